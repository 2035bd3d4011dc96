//! The saturating plant against motulator (an independent simulator): its 2.2-kW example
//! machine with main-flux saturation, started direct on line from 400 V 50 Hz against its
//! nominal 14.6 N·m from rest, 1 s. The reference trace is motulator 0.18's own machine and
//! mechanics integrated by scipy's DOP853 at rtol 1e-10, written by
//! `python3.12 tools/motulator_dol.py --write` (which also runs `hil-sim` on the same
//! scenario file, `hil-sim/scenarios/dol-motulator-2kw-sat.toml`).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]

use controller_core::magnetics::{Form, MagnetizingCurve, Saturation};
use controller_core::motor::MotorParams;
use plant::{Machine, MachineState};

const REFERENCE: &str = include_str!("data/motulator_dol_2kw_sat.csv");

/// The saturation issue's acceptance: the RMS difference of i_α, i_β, speed and torque
/// within 0.5 % of each signal's peak.
const ACCEPTANCE: f64 = 5e-3;

/// The plant's RK4 at 10 µs (the open-loop run's step) against motulator, signal by
/// signal, as RMS difference over peak; asserted against the acceptance and against the
/// figure this plant reaches (printed), so that a regression far inside the acceptance
/// still shows.
#[test]
fn the_saturating_plant_starts_as_motulators_machine_does() {
    let rows: Vec<[f64; 5]> = REFERENCE
        .lines()
        .filter(|l| !l.starts_with('#') && !l.starts_with('t'))
        .map(|l| {
            let v: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
            [v[0], v[1], v[2], v[3], v[4]]
        })
        .collect();
    assert_eq!(rows.len(), 2001);
    // Γ form as a T model: L_s = L_m = L_u, L_r = L_u + L_ℓ.
    let m = MotorParams::new(3.7, 2.5, 0.34, 0.34 + 0.023, 0.34, 2, 0.015, 0.0).unwrap();
    let curve = MagnetizingCurve::law(0.34, 0.84, 7.0).unwrap();
    let machine = Machine::saturated(&m, &Saturation { form: Form::Gamma, curve }).unwrap();
    let (amp, w) = (2f64.sqrt() * 400.0 / 3f64.sqrt(), 2.0 * std::f64::consts::PI * 50.0);
    let source = |t: f64| [amp * (w * t).cos(), amp * (w * t).sin()];
    let (h, per_sample) = (1e-5, 50);
    let mut x = MachineState::default();
    let mut sums = [0.0f64; 4];
    let mut peaks = [0.0f64; 4];
    for (k, r) in rows.iter().enumerate() {
        let ours = [x.i_alpha_a, x.i_beta_a, x.omega_m_rad_s, machine.torque_nm(&x)];
        for s in 0..4 {
            sums[s] += (ours[s] - r[s + 1]).powi(2);
            peaks[s] = peaks[s].max(r[s + 1].abs());
        }
        for j in 0..per_sample {
            x = machine.rk4_source(&x, (k * per_sample + j) as f64 * h, h, source, 14.6);
        }
    }
    let names = ["i_alpha_a", "i_beta_a", "omega_m_rad_s", "torque_nm"];
    for s in 0..4 {
        let rel = (sums[s] / rows.len() as f64).sqrt() / peaks[s];
        eprintln!("{:>14}: RMS difference {:.3e} of peak {:.3}", names[s], rel, peaks[s]);
        assert!(rel < ACCEPTANCE, "{}: {rel} of peak", names[s]);
        assert!(
            rel < 1e-8,
            "{}: {rel} of peak (this plant agrees to the reference file's 10 digits)",
            names[s]
        );
    }
}
