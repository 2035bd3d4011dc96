//! The induction machine's electrical subsystem as a 2×2 plant (seed 002 eqs. (1), (3), (4)).
//!
//! State space (stationary frame, electrical rotor speed ω_r as a parameter; the matrices
//! come from [`plant::Machine::electrical_matrices`]):
//! x = [i_sα, i_sβ, ψ_rα, ψ_rβ], u = [v_sα, v_sβ], y = [i_sα, i_sβ], with A(ω_r) and B of
//! eq. (1). `G(jω) = C (jωI − A)⁻¹ B` is evaluated by a complex linear solve; the structure
//! gives g₂₂ = g₁₁ and g₂₁ = −g₁₂.
//!
//! **Synchronous frame** ([`ImModel::in_frame`]): the same machine seen by loops that park
//! their currents at the field angle θ_e and turn their voltage back. With `x = R(θ_e)·x_dq`
//! (R the rotation of each (α, β) pair) and θ̇_e = ω_e, `ẋ_dq = (A − ω_e·J)·x_dq + B·u_dq`,
//! J = blockdiag([[0, −1], [1, 0]]) — A and B commute with R (the machine has no preferred
//! axis). At no load the field turns with the rotor, ω_e = ω_r.

use controller_core::drive::CurrentFrame;
use controller_core::motor::MotorParams;
use nalgebra::{Matrix4, Matrix4x2};
use num_complex::Complex64;

/// A(ω_r) and B of seed 002 eq. (1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImModel {
    /// System matrix.
    pub a: Matrix4<f64>,
    /// Input matrix.
    pub b: Matrix4x2<f64>,
}

/// The 2×2 frequency response at one frequency.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct G2 {
    /// g₁₁ (v_α → i_α).
    pub g11: Complex64,
    /// g₁₂ (v_β → i_α).
    pub g12: Complex64,
    /// g₂₁ (v_α → i_β).
    pub g21: Complex64,
    /// g₂₂ (v_β → i_β).
    pub g22: Complex64,
}

impl G2 {
    /// Multivariable structure function, eq. (8): γ = g₁₂g₂₁/(g₁₁g₂₂).
    pub fn gamma(&self) -> Complex64 {
        self.g12 * self.g21 / (self.g11 * self.g22)
    }
}

impl ImModel {
    /// Eq. (1) for `m` at electrical rotor speed `omega_r` (rad/s; = p·ω_m), from the
    /// simulator's plant so that analysis and simulation share one implementation.
    pub fn new(m: &MotorParams, omega_r: f64) -> Self {
        let (a, inv_sigma_ls) = plant::Machine::new(m).electrical_matrices(omega_r);
        let a = Matrix4::from_fn(|i, j| a[i][j]);
        let b = Matrix4x2::new(inv_sigma_ls, 0.0, 0.0, inv_sigma_ls, 0.0, 0.0, 0.0, 0.0);
        Self { a, b }
    }

    /// Eq. (1) as the current loops of `frame` see it (module docs): the stationary frame's
    /// [`ImModel::new`], or in the field frame turning at ω_e = ω_r.
    pub fn in_frame(m: &MotorParams, omega_r: f64, frame: CurrentFrame) -> Self {
        let mut model = Self::new(m, omega_r);
        if frame == CurrentFrame::Synchronous {
            for pair in [0, 2] {
                model.a[(pair, pair + 1)] += omega_r;
                model.a[(pair + 1, pair)] -= omega_r;
            }
        }
        model
    }

    /// G(jω) = C (jωI − A)⁻¹ B.
    pub fn response(&self, omega_rad_s: f64) -> G2 {
        let s = Complex64::new(0.0, omega_rad_s);
        let m = Matrix4::<Complex64>::identity() * s - self.a.map(|x| Complex64::new(x, 0.0));
        let b = self.b.map(|x| Complex64::new(x, 0.0));
        let x = m
            .lu()
            .solve(&b)
            .unwrap_or_else(|| nalgebra::Matrix4x2::from_element(Complex64::new(f64::NAN, f64::NAN)));
        G2 { g11: x[(0, 0)], g12: x[(0, 1)], g21: x[(1, 0)], g22: x[(1, 1)] }
    }
}

/// Seed 002 eq. (19): G_M,min = Lr²Lm⁴ / (Lr²Lm⁴ + 4σLr³LsLm² + 4σ²Lr⁴Ls²), the limit of
/// |γ(jω_r)| for ω_r → ∞.
pub fn gm_min(m: &MotorParams) -> f64 {
    let (ls, lr, lm, s) = (m.ls_h(), m.lr_h(), m.lm_h(), m.sigma());
    let n = lr * lr * lm.powi(4);
    n / (n + 4.0 * s * lr.powi(3) * ls * lm * lm + 4.0 * s * s * lr.powi(4) * ls * ls)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The DeLorenzo parameters solved from seed 002 eq. (13) (`motors/delorenzo-eq13.toml`).
    fn eq13_set() -> MotorParams {
        drive_file::motor::load("delorenzo-eq13").unwrap()
    }

    #[test]
    fn matrices_reproduce_eq13() {
        let m = ImModel::new(&eq13_set(), 100.0);
        for (got, want) in [
            (m.a[(0, 0)], -359.2),
            (m.a[(0, 2)], 141.8),
            (m.a[(0, 3)], 9.2 * 100.0),
            (m.a[(2, 0)], 21.9),
            (m.a[(2, 2)], -15.4),
            (m.a[(2, 3)], -100.0),
            (m.b[(0, 0)], 9.7),
        ] {
            assert!((got - want).abs() < 0.006 * want.abs(), "{got} vs {want}");
        }
    }

    #[test]
    fn structure_and_locked_rotor_siso() {
        let mp = MotorParams::delorenzo_dl10115a1().unwrap();
        let g = ImModel::new(&mp, 300.0).response(700.0);
        assert!((g.g22 - g.g11).norm() < 1e-12 * g.g11.norm());
        assert!((g.g21 + g.g12).norm() < 1e-12 * g.g12.norm());
        // ω_r = 0: the axes decouple and g₁₁ is the per-axis plant of the Fig. 11 test.
        let g0 = ImModel::new(&mp, 0.0).response(300.0);
        assert!(g0.g12.norm() < 1e-15);
        let s = Complex64::new(0.0, 300.0);
        let sl = mp.sigma() * mp.ls_h();
        let (lr, lm, rr) = (mp.lr_h(), mp.lm_h(), mp.rr_ohm());
        let a = -(lr * lr * mp.rs_ohm() + lm * lm * rr) / (sl * lr * lr);
        let p = rr / lr;
        let want = (s + p) / sl / ((s - a) * (s + p) - lm / (sl * lr) * p * (lm * rr / lr));
        assert!((g0.g11 - want).norm() < 1e-12 * want.norm());
    }

    /// Eq. (14): γ(jω_r) = L_r²L_m⁴ω_r⁴ / (re + j·im)², with re, im as printed — checked
    /// against the numeric MSF at s = jω_r.
    #[test]
    fn gamma_at_the_rotor_speed_matches_eq14() {
        let m = eq13_set();
        let (ls, lr, lm, rs, rr, sg) = (m.ls_h(), m.lr_h(), m.lm_h(), m.rs_ohm(), m.rr_ohm(), m.sigma());
        for wr in [50.0, 200.0, 375.0, 1000.0] {
            let num = ImModel::new(&m, wr).response(wr).gamma();
            let re = 2.0 * wr * wr * sg * ls * lr * lr + wr * wr * lr * lm * lm - lr * rs * rr;
            let im = -wr * sg * ls * lr * rr - 2.0 * wr * lr * lr * rs - wr * lm * lm * rr;
            let d = Complex64::new(re, im);
            let eq14 = Complex64::new(lr * lr * lm.powi(4) * wr.powi(4), 0.0) / (d * d);
            eprintln!("ω_r = {wr}: numeric γ(jω_r) = {num:.5}, eq. (14) = {eq14:.5}");
            assert!((num - eq14).norm() < 1e-9 * eq14.norm().max(1e-12), "{num} vs {eq14}");
        }
    }

    /// The shipped motor files: the eq. (13) set gives the paper's G_M,min ≈ 0.75
    /// (−2.47 dB), the appendix set does not (−2.31 dB).
    #[test]
    fn motor_files_gm_min() {
        let load = |n| drive_file::motor::load(n).unwrap();
        let (app, eq13) = (load("delorenzo-appendix"), load("delorenzo-eq13"));
        let db = |x: f64| 20.0 * x.log10();
        eprintln!(
            "G_M,min eq. (19): appendix {:.4} ({:.2} dB), eq. (13) set {:.4} ({:.2} dB); paper ≈ 0.75 (−2.47 dB)",
            gm_min(&app),
            db(gm_min(&app)),
            gm_min(&eq13),
            db(gm_min(&eq13))
        );
        assert!((db(gm_min(&eq13)) + 2.47).abs() < 0.02);
        assert!((db(gm_min(&app)) + 2.47).abs() > 0.1);
    }

    /// Eq. (19) is the high-speed limit of |γ(jω_r)|; the eq. (13) parameters give the
    /// paper's ≈ 0.75 (−2.47 dB).
    #[test]
    fn gm_min_is_the_high_speed_limit() {
        let m = eq13_set();
        let far = ImModel::new(&m, 1e6).response(1e6).gamma().norm();
        assert!((far - gm_min(&m)).abs() < 1e-6, "{far} vs {}", gm_min(&m));
        assert!((20.0 * gm_min(&m).log10() + 2.47).abs() < 0.02);
    }
}
