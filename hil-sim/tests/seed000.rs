//! Seed 000 Figs. 11/12: 2300 V machine, speed step to 100 rad/s with PI1/PI3 (dq current
//! loops) and PI2 (speed), nominal and with R_r +100 %, R_s +50 % in the plant.
//! Asserted against the paper's design goals (Sec. 7.1): overshoot < 10 %, settling (2 %)
//! within 1.5 s of the start of the speed step; and zero steady-state error (integral action).
#![allow(clippy::unwrap_used)]

use controller_core::drive::Mode;
use hil_sim::scenario::{Builtin, seed000_fig11, seed000_fig12};

fn step_metrics(b: &Builtin) -> (f64, f64, f64) {
    let (rows, mode) = b.run(|_| {}).unwrap();
    assert_eq!(mode, Mode::Running);
    // The step starts when the drive enters Running: first row with a non-zero reference.
    let t0 = rows.iter().find(|r| r.omega_ref_rad_s > 0.0).unwrap().t_s;
    let peak = rows.iter().map(|r| r.x.omega_m_rad_s).fold(f64::MIN, f64::max);
    let last_out = rows.iter().rev().find(|r| (r.x.omega_m_rad_s - 100.0).abs() > 2.0).map_or(t0, |r| r.t_s);
    let final_w = rows.last().unwrap().x.omega_m_rad_s;
    ((peak - 100.0) / 100.0, last_out - t0, final_w)
}

#[test]
fn speed_step_meets_the_design_goals_nominal_and_perturbed() {
    for b in [seed000_fig11().unwrap(), seed000_fig12().unwrap()] {
        let (overshoot, settling, final_w) = step_metrics(&b);
        eprintln!(
            "{}: overshoot {:.2} %, 2 % settling {settling:.3} s after the step, final ω {final_w:.4} rad/s",
            b.name,
            overshoot * 100.0
        );
        assert!(overshoot < 0.10);
        assert!(settling < 1.5);
        assert!((final_w - 100.0).abs() < 0.05);
    }
}
