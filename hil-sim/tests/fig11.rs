//! Seed 002 Fig. 11 (locked rotor, 300 rad/s current references, ICAD eq. (20)) on the
//! nonlinear machine, against linear theory: the steady-state error of a sinusoidal
//! reference of amplitude A is |S(jω)|·A with S = 1/(1 + L), L(jω) = k_d(e^{jωT})·g(jω)·e^{−1.5jωT}
//! (discrete controller as implemented; locked-rotor per-axis plant; sampling + one period of
//! computation delay ≈ 1.5 T). At ω_r = 0 the α and β axes decouple, so the SISO loop is exact.
#![allow(clippy::unwrap_used, clippy::indexing_slicing)]

use controller_core::current::{CurrentControllerConfig, CurrentLaw};
use controller_core::discretize::{Complex, Discretization};
use hil_sim::scenario::{fig11_locked_rotor, fig23_perturbed};

/// Locked-rotor per-axis plant from eq. (1) with ω_r = 0 (states i, ψ):
/// g(s) = (s + R_r/L_r)/(σL_s) / ((s − a)(s + R_r/L_r) − b·(R_r/L_r)·(L_m R_r/L_r)).
fn plant(m: &controller_core::motor::MotorParams, w: f64) -> Complex {
    let s = Complex::new(0.0, w);
    let sl = m.sigma() * m.ls_h();
    let (lr, lm, rr) = (m.lr_h(), m.lm_h(), m.rr_ohm());
    let a = -(lr * lr * m.rs_ohm() + lm * lm * rr) / (sl * lr * lr);
    let b = lm / (sl * lr);
    let p = Complex::new(rr / lr, 0.0);
    let num = (s + p) * (1.0 / sl);
    let den = (s - Complex::new(a, 0.0)) * (s + p) - Complex::new(b * (rr / lr) * (lm * rr / lr), 0.0);
    num / den
}

/// Run `b` and return (simulated, predicted) error amplitudes for its 1 A, 300 rad/s test.
fn simulated_and_predicted(b: &hil_sim::scenario::Builtin) -> (f64, f64) {
    let (rows, _) = b.run(|_| {}).unwrap();
    assert!(rows.iter().all(|r| r.x.omega_m_rad_s == 0.0));

    // Steady-state error over the last 0.3 s: least-squares sinusoid at 300 rad/s.
    let w = 300.0;
    let (mut ss, mut cc, mut sc, mut es, mut ec) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for r in rows.iter().filter(|r| r.t_s >= 1.0) {
        let e = r.i_ref_ab_a[0] - r.x.i_alpha_a;
        let (sn, cs) = ((w * r.t_s).sin(), (w * r.t_s).cos());
        ss += sn * sn;
        cc += cs * cs;
        sc += sn * cs;
        es += e * sn;
        ec += e * cs;
    }
    let det = ss * cc - sc * sc;
    let (ea, eb) = ((es * cc - ec * sc) / det, (ec * ss - es * sc) / det);
    let simulated = ea.hypot(eb);

    let ts = 1.0 / b.spec.pwm_frequency_hz;
    let k =
        CurrentControllerConfig::<f32>::new(&CurrentLaw::ICAD_EQ20, ts, Discretization::Tustin, 1e3).unwrap();
    let delay = Complex::new((-1.5 * w * ts).cos(), (-1.5 * w * ts).sin());
    let l = k.response(w, ts) * plant(&b.plant, w) * delay;
    let predicted = (Complex::new(1.0, 0.0) / (Complex::new(1.0, 0.0) + l)).norm() * 1.0;
    eprintln!(
        "{}, 300 rad/s, A = 1 A: simulated error amplitude {:.5} A ({:.2} %), linear prediction {:.5} A",
        b.name,
        simulated,
        simulated * 100.0,
        predicted
    );
    (simulated, predicted)
}

#[test]
fn fig11_tracking_error_matches_linear_prediction() {
    let (simulated, predicted) = simulated_and_predicted(&fig11_locked_rotor().unwrap());
    assert!((simulated - predicted).abs() < 0.05 * predicted, "{simulated} vs {predicted}");
    assert!(simulated < 0.05, "ICAD tracking error at 300 rad/s should be a few percent");
}

/// Fig. 23: the perturbed plant (Sec. VIII) with the nominal controller still tracks with
/// a small error; the linear prediction holds for the perturbed plant too.
#[test]
fn fig23_perturbed_plant_tracking_error() {
    let (simulated, predicted) = simulated_and_predicted(&fig23_perturbed().unwrap());
    assert!((simulated - predicted).abs() < 0.05 * predicted, "{simulated} vs {predicted}");
    assert!(simulated < 0.05);
}
