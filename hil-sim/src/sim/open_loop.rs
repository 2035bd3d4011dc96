//! The open-loop run: the machine fed by an ideal balanced sine source, for validating the
//! plant alone.

use super::integrate::RK4_RATE_STEP_MAX;
use super::{OpenLoop, Row, non_finite};
use plant::{Machine, MachineState};

/// Largest RK4 step used for open-loop runs, s. The step-size study
/// (`open_loop_step_convergence` in the tests) shows the trace error at this step.
pub const OPEN_LOOP_MAX_STEP_S: f64 = 1e-5;

/// The most RK4 steps an open-loop run takes per trace sample: a machine stiffer than that
/// (a 0.2 ns stator time constant wanted millions) is refused rather than integrated for
/// minutes.
pub const OPEN_LOOP_SUBSTEPS_MAX: f64 = 10_000.0;

/// Open-loop run: the machine fed by an ideal balanced sine source, for validating the
/// plant alone. One row per `sample_period_s` to `sink` (as in [`run`](super::run)); the RK4 step
/// divides the sample period into equal steps of at most `max_step_s`, and small enough for
/// the machine's fastest mode ([`RK4_RATE_STEP_MAX`]). Returns the number of rows.
pub fn run_open_loop(
    sc: &OpenLoop,
    max_step_s: f64,
    mut progress: impl FnMut(f64),
    mut sink: impl FnMut(&Row) -> Result<(), String>,
) -> Result<u64, String> {
    let machine = match &sc.saturation {
        Some(sat) => Machine::saturated(&sc.motor, sat).map_err(|e| e.to_string())?,
        None => Machine::new(&sc.motor),
    };
    let w = 2.0 * std::f64::consts::PI * sc.frequency_hz;
    let amp = sc.amplitude_v;
    let source = move |t: f64| [amp * (w * t).cos(), amp * (w * t).sin()];
    // At most `max_step_s`, and stable on this machine's fastest mode (`RK4_RATE_STEP_MAX`).
    let stable_step_s = RK4_RATE_STEP_MAX / machine.fastest_rate_per_s();
    let substeps = (sc.sample_period_s / max_step_s.min(stable_step_s)).ceil().max(1.0);
    if substeps.is_nan() || substeps > OPEN_LOOP_SUBSTEPS_MAX {
        return Err(format!(
            "the simulated machine is too stiff to integrate: its fastest electrical mode decays at {:.4e} 1/s, \
             which needs {substeps:.3e} RK4 steps per sample (at most {OPEN_LOOP_SUBSTEPS_MAX}); check {}",
            machine.fastest_rate_per_s(),
            super::stiffness_culprits(&machine)
        ));
    }
    let h = sc.sample_period_s / substeps;
    let n = (sc.duration_s / sc.sample_period_s).round() as u64;
    let mut x = MachineState::default();
    let row = |t: f64, x: MachineState, peak2: f64| Row {
        t_s: t,
        x,
        torque_nm: machine.torque_nm(&x),
        v_ab_v: source(t),
        load_nm: sc.load_nm,
        i_peak_a: peak2.sqrt(),
        ..Row::default()
    };
    let magnitude2 = |x: &MachineState| x.i_alpha_a * x.i_alpha_a + x.i_beta_a * x.i_beta_a;
    let mut peak2 = 0.0f64;
    for k in 0..=n {
        let t0 = k as f64 * sc.sample_period_s;
        if !x.is_finite() {
            return Err(non_finite(t0, &machine));
        }
        sink(&row(t0, x, peak2.max(magnitude2(&x))))?;
        if k == n {
            break;
        }
        peak2 = 0.0;
        for j in 0..substeps as u64 {
            x = machine.rk4_source(&x, t0 + j as f64 * h, h, source, sc.load_nm);
            peak2 = peak2.max(magnitude2(&x));
        }
        if k % 1000 == 0 {
            progress(k as f64 / n as f64);
        }
    }
    progress(1.0);
    Ok(n + 1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use controller_core::motor::MotorParams;

    fn dol(max_step: f64) -> Vec<Row> {
        let sc = OpenLoop {
            duration_s: 0.5,
            sample_period_s: 1e-3,
            motor: MotorParams::delorenzo_dl10115a1().unwrap(),
            saturation: None,
            amplitude_v: 180.0,
            frequency_hz: 50.0,
            load_nm: 0.2,
        };
        let mut rows = Vec::new();
        run_open_loop(
            &sc,
            max_step,
            |_| {},
            |r| {
                rows.push(*r);
                Ok(())
            },
        )
        .unwrap();
        rows
    }

    /// Step-size study of the chosen open-loop step (10 µs) against a 16× finer step
    /// (0.625 µs) over a 0.5 s direct-on-line start: RK4 is 4th order, so the error of
    /// the 10 µs trace is ≈ 16/15 of the difference. Printed and asserted.
    #[test]
    fn open_loop_step_convergence() {
        let (coarse, fine) = (dol(OPEN_LOOP_MAX_STEP_S), dol(OPEN_LOOP_MAX_STEP_S / 16.0));
        let mut max_di: f64 = 0.0;
        let mut max_dw: f64 = 0.0;
        for (a, b) in coarse.iter().zip(&fine) {
            max_di =
                max_di.max((a.x.i_alpha_a - b.x.i_alpha_a).abs().max((a.x.i_beta_a - b.x.i_beta_a).abs()));
            max_dw = max_dw.max((a.x.omega_m_rad_s - b.x.omega_m_rad_s).abs());
        }
        let peak_i = fine.iter().map(|r| r.x.i_alpha_a.abs()).fold(0.0, f64::max);
        eprintln!(
            "RK4 10 µs vs 0.625 µs: max |Δi| {max_di:.2e} A (peak {peak_i:.2} A), max |Δω| {max_dw:.2e} rad/s"
        );
        assert!(max_di < 1e-8 * peak_i.max(1.0));
        assert!(max_dw < 1e-8);
    }
}
