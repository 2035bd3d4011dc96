//! Independent time-domain check of the ω_r stability limit found by the eigenvalue sweep:
//! hil-sim's nonlinear machine held at a fixed speed, the firmware's discrete ICAD current
//! loops (controller-core, f32, 20 kHz, one period of computation delay) regulating to zero
//! current from a small initial perturbation; no voltage limit. The envelope's exponential
//! rate 100 rad/s below and above the limit must match the continuous closed-loop
//! eigenvalue abscissa in sign and within 30 % (the discrete loop and its delay differ
//! slightly from the continuous analysis).
#![allow(clippy::unwrap_used)]

use controller_core::current::{CurrentControllerConfig, CurrentLaw, CurrentState};
use controller_core::discretize::Discretization;
use controller_core::frames::AlphaBeta;
use plant::{Machine, MachineState};

fn envelope_ratio(omega_m: f64) -> f64 {
    let m = drive_file::motor::load("delorenzo-eq13").unwrap();
    let machine = Machine::new(&m).speed_locked();
    let ts = 5e-5;
    let k =
        CurrentControllerConfig::<f32>::new(&CurrentLaw::ICAD_EQ20, ts, Discretization::Tustin, 1e6).unwrap();
    let mut st = CurrentState::default();
    let mut x = MachineState { i_alpha_a: 0.01, omega_m_rad_s: omega_m, ..Default::default() };
    let mut v = [0.0f64; 2];
    let (mut early, mut late) = (0.0f64, 0.0f64);
    for n in 0..10_000 {
        let i = AlphaBeta { alpha: x.i_alpha_a as f32, beta: x.i_beta_a as f32 };
        let [ua, ub] = k.request(&mut st, -i.alpha, -i.beta, 1e6);
        x = machine.rk4(&x, v, 0.0, ts);
        v = [f64::from(ua), f64::from(ub)];
        let mag = x.i_alpha_a.hypot(x.i_beta_a);
        if (1000..2000).contains(&n) {
            early = early.max(mag);
        }
        if n >= 9000 {
            late = late.max(mag);
        }
    }
    late / early
}

#[test]
fn eigenvalue_speed_limit_is_confirmed_in_time() {
    let limit = design::icad::stable_omega_r_max(
        &drive_file::motor::load("delorenzo-eq13").unwrap(),
        &CurrentLaw::ICAD_EQ20,
        5.0,
        2000.0,
    )
    .unwrap();
    let m = drive_file::motor::load("delorenzo-eq13").unwrap();
    for w in [limit - 100.0, limit + 100.0] {
        // envelope ratio over 0.4 s → exponential rate; compare with the eigenvalue abscissa
        let rate = envelope_ratio(w).ln() / 0.4;
        let abscissa = design::icad::closed_loop_abscissa(&m, &CurrentLaw::ICAD_EQ20, w);
        eprintln!(
            "ω_r = {w}: time-domain rate {rate:+.2} 1/s, continuous eigenvalue abscissa {abscissa:+.2} 1/s"
        );
        assert_eq!(rate > 0.0, abscissa > 0.0);
        assert!((rate - abscissa).abs() < 0.3 * abscissa.abs(), "{rate} vs {abscissa}");
    }
    eprintln!("eigenvalue limit ω_r = {limit} rad/s");
}
