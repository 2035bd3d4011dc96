//! Issue 21: the sampled position cascade `design certify` checks
//! (`design::sampled::SpeedLoop::position_matrix`) against the simulated drive. A 1 rad
//! position step — small enough that neither the speed limit nor the torque limit acts —
//! with the shipped drive's loops set to what `design tune` gives the DeLorenzo motor
//! (saturated P k_p = 0.13038 N·m·s/rad, position k = 3.2595 1/s): the simulated angle
//! follows the linear sampled model's to within 1 % of the step over 2 s, and settles
//! without overshoot, as the damping rule intends.
#![allow(clippy::unwrap_used, clippy::indexing_slicing)]

use controller_core::drive::{Mode, PositionLaw, Reference};
use controller_core::speed::SpeedLaw;
use hil_sim::sim::Event;

#[test]
fn the_sampled_position_cascade_agrees_with_the_simulated_drive() {
    let (kp, k, t_step) = (0.13038, 3.2595, 0.5);
    let mut b = hil_sim::scenario::speed_step().unwrap();
    b.spec.speed_law = SpeedLaw::SaturatedP { kp, tau_max_nm: 2.0 };
    b.spec.position = PositionLaw { k_per_s: k, omega_max_rad_s: 150.0 };
    b.scenario.events = vec![(0.0, Event::Enable), (t_step, Event::Reference(Reference::Position(1.0)))];
    b.scenario.duration_s = t_step + 2.0;
    b.scenario.trace_every = 1;
    let m = b.spec.motor;
    let t_slow = f64::from(b.spec.slow_divider) / b.spec.pwm_frequency_hz;
    let (rows, mode) = b.run(|_| {}).unwrap();
    assert_eq!(mode, Mode::Running);
    let l =
        design::sampled::SpeedLoop { j_kgm2: m.j_kgm2(), b_nms: m.b_nms(), ts_s: t_slow, kp, ki_over_k: 0.0 };
    let mm = l.position_matrix(k);
    let n = mm.nrows();
    let mut x = nalgebra::DVector::<f64>::zeros(n);
    x[n - 1] = -1.0;
    let model: Vec<f64> = (0..4000)
        .map(|_| {
            let th = 1.0 + x[n - 1];
            x = &mm * &x;
            th
        })
        .collect();
    let (mut worst, mut peak) = (0.0f64, 0.0f64);
    for r in rows.iter().filter(|r| r.t_s >= t_step) {
        let kf = (r.t_s - t_step) / t_slow;
        let i = kf.floor() as usize;
        let Some((a, c)) = model.get(i).zip(model.get(i + 1)) else { break };
        let th_model = a + (c - a) * (kf - kf.floor());
        worst = worst.max((r.x.theta_m_rad - th_model).abs());
        peak = peak.max(r.x.theta_m_rad);
    }
    println!("largest difference from the sampled model: {worst:.5} rad of a 1 rad step; peak {peak:.5} rad");
    assert!(worst < 0.01, "{worst}");
    assert!(peak <= 1.0 + 1e-3, "overshoot: {peak}");
}
