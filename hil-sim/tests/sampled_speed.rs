//! Issue 21: the sampled speed-loop model of `design certify` against the simulated drive.
//! The model (`design::sampled::SpeedLoop`: zero-order hold at the slow period, the encoder's
//! 8-read speed window, one slow period of torque delay) puts the saturated P law's stability
//! limit at a k_p it prints; in software in the loop, a small speed step (inside the torque
//! limit) with k_p at 0.8× that limit settles, at 1.25× it does not — the speed oscillation
//! grows until the torque limit holds it in a limit cycle.
#![allow(clippy::unwrap_used, clippy::indexing_slicing)]

use controller_core::drive::{Mode, Reference};
use controller_core::speed::SpeedLaw;
use hil_sim::sensors::SensorModel;
use hil_sim::sim::Event;

/// Peak-to-peak speed over the last 0.1 s of a 0.2 rad/s step at 10 rad/s with gain `kp`.
fn ripple_after_step(kp: f64) -> f64 {
    let mut b = hil_sim::scenario::speed_step().unwrap();
    b.spec.speed_law = SpeedLaw::SaturatedP { kp, tau_max_nm: 2.0 };
    // A fine encoder (2^18 lines: the window's speed quantum is 1.5e-3 rad/s), so that the
    // estimator's window and not its resolution is what the loop sees.
    b.scenario.sensors = SensorModel { encoder_lines: Some(1 << 18), ..SensorModel::default() };
    b.scenario.events = vec![
        (0.0, Event::Enable),
        (0.3, Event::Reference(Reference::Speed(10.0))),
        (0.8, Event::Reference(Reference::Speed(10.2))),
    ];
    b.scenario.duration_s = 1.2;
    b.scenario.trace_every = 1;
    let (rows, mode) = b.run(|_| {}).unwrap();
    assert_eq!(mode, Mode::Running);
    let tail: Vec<f64> = rows.iter().filter(|r| r.t_s >= 1.1).map(|r| r.x.omega_m_rad_s).collect();
    let (lo, hi) = tail.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &w| (l.min(w), h.max(w)));
    hi - lo
}

#[test]
fn the_sampled_speed_limit_agrees_with_the_simulated_drive() {
    let b = hil_sim::scenario::speed_step().unwrap();
    let m = b.spec.motor;
    let t_slow = f64::from(b.spec.slow_divider) / b.spec.pwm_frequency_hz;
    let stable = |kp: f64| {
        design::sampled::SpeedLoop { j_kgm2: m.j_kgm2(), b_nms: m.b_nms(), ts_s: t_slow, kp, ki_over_k: 0.0 }
            .radius()
            < 1.0
    };
    let (mut lo, mut hi) = (0.05f64, 50.0f64);
    for _ in 0..60 {
        let mid = (lo * hi).sqrt();
        if stable(mid) { lo = mid } else { hi = mid }
    }
    let (below, above) = (ripple_after_step(0.8 * lo), ripple_after_step(1.25 * lo));
    eprintln!(
        "sampled model's limit k_p = {lo:.3}; SIL speed ripple 0.3 s after a 0.2 rad/s step: {below:.2e} rad/s at 0.8×, {above:.2e} rad/s at 1.25×"
    );
    assert!(below < 0.01, "{below}");
    assert!(above > 0.1, "{above}");
}
