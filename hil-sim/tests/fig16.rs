//! Seed 002 Fig. 16: ICAD vs PI current loops under the saturated-P speed loop (21) to
//! 376 rad/s.
//!
//! Metric: RMS deviation of the simulated speed from the **ideal trajectory** — the same
//! speed law (21), sampled at the slow-loop rate, acting on the rotor with perfect torque
//! (J·dω/dt = τ_ref − B·ω), i.e. "assuming a perfect stator current control" as the paper's
//! dashed line. Also reported: the RMS α-current tracking error over the last second, near
//! 376 rad/s where the PI's open-loop gain has collapsed (paper Fig. 15).
#![allow(clippy::unwrap_used, clippy::indexing_slicing, clippy::panic)]

use controller_core::speed::SpeedLaw;
use hil_sim::scenario::{Builtin, fig16_icad, fig16_pi};

struct Metrics {
    speed_rms_dev: f64,
    current_rms_err: f64,
    final_speed: f64,
}

fn ideal_speed(b: &Builtin, t_end: f64) -> impl Fn(f64) -> f64 {
    let SpeedLaw::SaturatedP { kp, tau_max_nm } = b.spec.speed_law else { panic!("fig16 uses eq. (21)") };
    let (j, bf) = (b.spec.motor.j_kgm2(), b.spec.motor.b_nms());
    let t_slow = f64::from(b.spec.slow_divider) / b.spec.pwm_frequency_hz;
    let (t_ref, w_ref) = (0.3, 376.0);
    // Integrate finely; torque held per slow period.
    let h = t_slow / 100.0;
    let mut traj = vec![(0.0, 0.0)];
    let (mut t, mut w, mut tau) = (0.0f64, 0.0f64, 0.0f64);
    let mut k = 0u64;
    while t < t_end {
        if k.is_multiple_of(100) {
            let r = if t >= t_ref { w_ref } else { 0.0 };
            tau = (kp * (r - w)).clamp(-tau_max_nm, tau_max_nm);
        }
        w += h * (tau - bf * w) / j;
        t += h;
        k += 1;
        traj.push((t, w));
    }
    move |ts: f64| {
        let i = traj.partition_point(|p| p.0 < ts).min(traj.len() - 1);
        traj[i].1
    }
}

fn metrics(b: &Builtin) -> Metrics {
    let (rows, _) = b.run(|_| {}).unwrap();
    let ideal = ideal_speed(b, b.scenario.duration_s);
    let dev2: f64 = rows.iter().map(|r| (r.x.omega_m_rad_s - ideal(r.t_s)).powi(2)).sum();
    let tail: Vec<_> = rows.iter().filter(|r| r.t_s > b.scenario.duration_s - 1.0).collect();
    let e2: f64 = tail.iter().map(|r| (r.i_ref_ab_a[0] - r.x.i_alpha_a).powi(2)).sum();
    Metrics {
        speed_rms_dev: (dev2 / rows.len() as f64).sqrt(),
        current_rms_err: (e2 / tail.len() as f64).sqrt(),
        final_speed: rows.last().unwrap().x.omega_m_rad_s,
    }
}

#[test]
fn icad_tracks_the_ideal_ramp_better_than_pi() {
    let (icad, pi) = (metrics(&fig16_icad().unwrap()), metrics(&fig16_pi().unwrap()));
    for (name, m) in [("ICAD", &icad), ("PI", &pi)] {
        eprintln!(
            "Fig. 16 {name:>4}: RMS speed deviation from ideal {:.3} rad/s, RMS i_α error (last 1 s) {:.4} A, final ω {:.2} rad/s",
            m.speed_rms_dev, m.current_rms_err, m.final_speed
        );
    }
    assert!(icad.speed_rms_dev < 0.5 * pi.speed_rms_dev);
    assert!(icad.current_rms_err < 0.5 * pi.current_rms_err);
}
