//! The induction machine with a saturating magnetizing branch, in the Γ or the inverse-Γ
//! form (`controller_core::magnetics`), with the fluxes as its states — the formulation of
//! motulator's `InductionMachine` (Γ, saturating `L_s(|ψ_s|)`), extended to the inverse-Γ
//! form. Stationary frame, peak-valued space vectors, p pole pairs, J the 90° rotation:
//!
//! ```text
//! dψ_s/dt = v_s − R_s·i_s
//! dψ_r/dt = −R_r·i_r + p·ω_m·J·ψ_r
//! Γ:         i_r = (ψ_r − ψ_s)/L_ℓ,  i_s = f(|ψ_s|)·ψ_s/|ψ_s| − i_r
//! inverse-Γ: i_s = (ψ_s − ψ_r)/L_σ,  i_r = f(|ψ_r|)·ψ_r/|ψ_r| − i_s
//! T_e = (3/2)·p·(ψ_sα·i_sβ − ψ_sβ·i_sα)
//! ```
//! with f the magnetizing curve.
//!
//! **Iron loss** (inverse-Γ only, [`crate::Machine::with_iron_loss`]): a resistance R_fe across
//! the magnetizing branch, which in the inverse-Γ form sits behind the stator leakage and
//! carries the air-gap voltage `u_m = dψ_R/dt` (stator frame). Its current `u_m/R_fe` is
//! taken from the rotor's, `i_r = f(|ψ_r|)·ψ_r/|ψ_r| − i_s + u_m/R_fe`, so
//! `dψ_r/dt = (−R_r·(f − i_s) + p·ω_m·J·ψ_r)/(1 + R_r/R_fe)`, and the torque is the rotor
//! branch's, `T_e = (3/2)·p·(ψ_s × i_s − ψ_r × u_m/R_fe)` — the iron-loss current makes no
//! torque. The loss `(3/2)·|u_m|²/R_fe` grows with the square of the frequency and of the
//! flux (eddy currents; a constant R_fe). In the Γ form the branch is behind R_s alone and
//! the stator current would not be a state: refused there. The machine's state stays [`MachineState`]'s (stator
//! current, rotor flux — what the rest of the simulator reads and what the bridge's diodes
//! act on); a step recovers the stator flux from it
//! ([`MagnetizingCurve::flux_at_total_current`]), integrates the fluxes by classical RK4
//! and returns the current. Written as a T model with its stator leakage (Γ) or its rotor
//! leakage (inverse-Γ) zero, the linear machine's `MotorParams` are the same machine at
//! `f(ψ) = ψ/L_m`: the two models then agree to rounding (test
//! `an_unsaturated_curve_is_the_linear_machine`).

use crate::MachineState;
use controller_core::magnetics::{Form, MagnetizingCurve, Saturation};
use controller_core::motor::MotorParams;

/// A space vector (α, β).
type V2 = [f64; 2];

#[inline(always)]
fn add(a: V2, b: V2) -> V2 {
    [a[0] + b[0], a[1] + b[1]]
}
#[inline(always)]
fn sub(a: V2, b: V2) -> V2 {
    [a[0] - b[0], a[1] - b[1]]
}
#[inline(always)]
fn scale(k: f64, a: V2) -> V2 {
    [k * a[0], k * a[1]]
}
#[inline(always)]
fn norm(a: V2) -> f64 {
    // Not `hypot`: its care for overflow costs a quarter of a step, and a flux or a current
    // near 1e154 is not a machine.
    (a[0] * a[0] + a[1] * a[1]).sqrt()
}
/// J·a, the vector turned by 90°.
#[inline(always)]
fn rot(a: V2) -> V2 {
    [-a[1], a[0]]
}

/// Why a saturating machine was refused.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SaturationError {
    /// The Γ form has no stator leakage: its `MotorParams` need L_s = L_m.
    GammaNeedsNoStatorLeakage,
    /// The inverse-Γ form has no rotor leakage: its `MotorParams` need L_r = L_m.
    InverseGammaNeedsNoRotorLeakage,
    /// Iron loss is modelled in the inverse-Γ form only (module docs), with R_fe finite
    /// and positive.
    IronLoss,
}

impl core::fmt::Display for SaturationError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::GammaNeedsNoStatorLeakage => "a Γ-form machine has no stator leakage: L_s must equal L_m",
            Self::InverseGammaNeedsNoRotorLeakage => {
                "an inverse-Γ-form machine has no rotor leakage: L_r must equal L_m"
            }
            Self::IronLoss => {
                "iron loss needs the inverse-Γ form (its magnetizing branch behind the stator leakage) and a \
                 finite, positive resistance"
            }
        })
    }
}

/// The electrical part of a saturating machine (the mechanics stay in [`crate::Machine`]).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Saturated {
    form: Form,
    curve: MagnetizingCurve,
    rs_ohm: f64,
    /// The form's rotor resistance (Γ: R_r; inverse-Γ: R_R), Ω.
    rr_ohm: f64,
    /// 1/L of the form's leakage (Γ: L_ℓ, rotor side; inverse-Γ: L_σ, stator side), 1/H.
    inv_leak_per_h: f64,
    /// The form's leakage, H.
    leak_h: f64,
    p: f64,
    /// The T model's L_m it was made with, H (a parameter step scales the curve by its
    /// change).
    lm_h: f64,
    /// The fastest electrical rate over the fluxes a run reaches, 1/s.
    fastest_rate_per_s: f64,
    /// The iron-loss conductance across the magnetizing branch, S (0: none).
    g_fe_s: f64,
}

/// The fluxes a step integrates, and the speed.
#[derive(Clone, Copy, Debug)]
struct Fluxes {
    psi_s: V2,
    psi_r: V2,
    w: f64,
}

impl Saturated {
    /// `m` is the form written as a T model (Γ: L_s = L_m; inverse-Γ: L_r = L_m, each to
    /// 1e-9 relative); `sat.curve` replaces its magnetizing inductance.
    pub(crate) fn new(m: &MotorParams, sat: &Saturation) -> Result<Self, SaturationError> {
        let same = |a: f64, b: f64| (a - b).abs() <= 1e-9 * a.abs().max(b.abs());
        let leak_h = match sat.form {
            Form::Gamma if same(m.ls_h(), m.lm_h()) => m.lr_h() - m.lm_h(),
            Form::Gamma => return Err(SaturationError::GammaNeedsNoStatorLeakage),
            Form::InverseGamma if same(m.lr_h(), m.lm_h()) => m.ls_h() - m.lm_h(),
            Form::InverseGamma => return Err(SaturationError::InverseGammaNeedsNoRotorLeakage),
        };
        // The fastest mode: the linear machine with the branch's incremental inductance
        // deep in saturation, where it is smallest.
        let l_inc = 1.0 / sat.curve.slope_per_h(sat.curve.deep_flux_wb());
        let (ls, lr) = match sat.form {
            Form::Gamma => (l_inc, l_inc + leak_h),
            Form::InverseGamma => (l_inc + leak_h, l_inc),
        };
        let fastest_rate_per_s =
            MotorParams::new(m.rs_ohm(), m.rr_ohm(), ls, lr, l_inc, m.pole_pairs(), m.j_kgm2(), m.b_nms())
                .map_or(f64::INFINITY, |deep| crate::Machine::new(&deep).fastest_rate_per_s());
        Ok(Self {
            form: sat.form,
            curve: sat.curve,
            rs_ohm: m.rs_ohm(),
            rr_ohm: m.rr_ohm(),
            inv_leak_per_h: 1.0 / leak_h,
            leak_h,
            p: f64::from(m.pole_pairs()),
            lm_h: m.lm_h(),
            fastest_rate_per_s,
            g_fe_s: 0.0,
        })
    }

    /// The same machine with an iron-loss resistance `r_fe_ohm` across its magnetizing
    /// branch (module docs): inverse-Γ form only.
    pub(crate) fn with_iron_loss(&self, r_fe_ohm: f64) -> Result<Self, SaturationError> {
        if self.form != Form::InverseGamma || !(r_fe_ohm.is_finite() && r_fe_ohm > 0.0) {
            return Err(SaturationError::IronLoss);
        }
        Ok(Self { g_fe_s: 1.0 / r_fe_ohm, ..*self })
    }

    /// The iron-loss resistance, Ω (`None`: no iron loss).
    pub(crate) fn iron_loss_ohm(&self) -> Option<f64> {
        (self.g_fe_s > 0.0).then(|| 1.0 / self.g_fe_s)
    }

    /// The same branch on the electrical parameters of `m` (a parameter step mid-run): the
    /// curve's inductances scaled as `m`'s L_m is to the one this was made with.
    pub(crate) fn with_electrical(&self, m: &MotorParams) -> Result<Self, SaturationError> {
        let curve = self.curve.with_inductance_scaled(m.lm_h() / self.lm_h);
        Ok(Self { g_fe_s: self.g_fe_s, ..Self::new(m, &Saturation { form: self.form, curve })? })
    }

    /// The rotor flux's rate, `dψ_r/dt` — the air-gap voltage `u_m` of the inverse-Γ form —
    /// for the fluxes' rotor current `i_r` (without the iron's share), the rotor flux and
    /// the electrical speed `w`.
    #[inline]
    fn rotor_flux_rate(&self, i_r: V2, psi_r: V2, w: f64) -> V2 {
        let d = add(scale(-self.rr_ohm, i_r), scale(w, rot(psi_r)));
        if self.g_fe_s > 0.0 { scale(1.0 / (1.0 + self.rr_ohm * self.g_fe_s), d) } else { d }
    }

    /// `(3/2)·p·(ψ_s × i_s − G_fe·ψ_r × u_m)`: the rotor branch's torque (module docs).
    #[inline]
    fn torque_of(&self, psi_s: V2, i_s: V2, psi_r: V2, u_m: V2) -> f64 {
        let cross = |a: V2, b: V2| a[0] * b[1] - a[1] * b[0];
        1.5 * self.p * (cross(psi_s, i_s) - self.g_fe_s * cross(psi_r, u_m))
    }

    pub(crate) fn fastest_rate_per_s(&self) -> f64 {
        self.fastest_rate_per_s
    }

    /// The magnetizing branch's current for its flux vector.
    #[inline]
    fn magnetizing(&self, psi_m: V2) -> V2 {
        scale(self.curve.inverse_inductance_per_h(norm(psi_m)), psi_m)
    }

    /// Stator and rotor currents of the fluxes.
    #[inline]
    fn currents(&self, psi_s: V2, psi_r: V2) -> (V2, V2) {
        match self.form {
            Form::Gamma => {
                let i_r = scale(self.inv_leak_per_h, sub(psi_r, psi_s));
                (sub(self.magnetizing(psi_s), i_r), i_r)
            }
            Form::InverseGamma => {
                let i_s = scale(self.inv_leak_per_h, sub(psi_s, psi_r));
                (i_s, sub(self.magnetizing(psi_r), i_s))
            }
        }
    }

    /// The stator flux of a state (its stator current and rotor flux). Γ: the branch and the
    /// leakage in parallel carry `i_s + ψ_r/L_ℓ`, so ψ_s lies along that vector with the
    /// magnitude that makes `f(|ψ_s|) + |ψ_s|/L_ℓ` equal its length; inverse-Γ: ψ_r + L_σ·i_s.
    pub(crate) fn stator_flux(&self, x: &MachineState) -> V2 {
        let (i_s, psi_r) = ([x.i_alpha_a, x.i_beta_a], [x.psi_alpha_wb, x.psi_beta_wb]);
        match self.form {
            Form::Gamma => {
                let w = add(i_s, scale(self.inv_leak_per_h, psi_r));
                let a = norm(w);
                if a > 0.0 {
                    scale(self.curve.flux_at_total_current(a, self.inv_leak_per_h) / a, w)
                } else {
                    [0.0; 2]
                }
            }
            Form::InverseGamma => add(psi_r, scale(self.leak_h, i_s)),
        }
    }

    /// Electromagnetic torque, N·m.
    pub(crate) fn torque_nm(&self, x: &MachineState) -> f64 {
        let psi_s = self.stator_flux(x);
        let psi_r = [x.psi_alpha_wb, x.psi_beta_wb];
        let (i_s, i_r) = self.currents(psi_s, psi_r);
        let u_m = self.rotor_flux_rate(i_r, psi_r, self.p * x.omega_m_rad_s);
        self.torque_of(psi_s, i_s, psi_r, u_m)
    }

    /// The terminal voltage at which the stator current stays zero (the open stator's), αβ:
    /// with i_s = 0 the stator flux is a function of the rotor flux alone and `v = dψ_s/dt`.
    /// Γ: ψ_s along ψ_r with `f(|ψ_s|) + |ψ_s|/L_ℓ = |ψ_r|/L_ℓ`; a change of ψ_r along
    /// itself moves |ψ_s| by `(1/L_ℓ)/(f′ + 1/L_ℓ)`, across it turns ψ_s by `|ψ_s|/|ψ_r|`.
    /// Inverse-Γ: ψ_s = ψ_r.
    pub(crate) fn open_circuit_voltage(&self, x: &MachineState) -> V2 {
        let psi_r = [x.psi_alpha_wb, x.psi_beta_wb];
        let r = norm(psi_r);
        if r == 0.0 {
            return [0.0; 2];
        }
        let w = self.p * x.omega_m_rad_s;
        match self.form {
            Form::Gamma => {
                let r_s = self.curve.flux_at_total_current(r * self.inv_leak_per_h, self.inv_leak_per_h);
                let u = scale(1.0 / r, psi_r);
                let i_r = scale(self.curve.current_a(r_s), u);
                let d_psi_r = add(scale(-self.rr_ohm, i_r), scale(w, rot(psi_r)));
                let along = d_psi_r[0] * u[0] + d_psi_r[1] * u[1];
                let across = sub(d_psi_r, scale(along, u));
                let k_along = self.inv_leak_per_h / (self.curve.slope_per_h(r_s) + self.inv_leak_per_h);
                add(scale(along * k_along, u), scale(r_s / r, across))
            }
            Form::InverseGamma => self.rotor_flux_rate(self.magnetizing(psi_r), psi_r, w),
        }
    }

    /// The derivative of the fluxes and the speed; `t_l` the load and passive torque, held.
    #[inline]
    fn f(&self, inv_j: f64, b_nms: f64, x: &Fluxes, v: V2, t_l: f64) -> Fluxes {
        let (i_s, i_r) = self.currents(x.psi_s, x.psi_r);
        let d_psi_r = self.rotor_flux_rate(i_r, x.psi_r, self.p * x.w);
        let t_e = self.torque_of(x.psi_s, i_s, x.psi_r, d_psi_r);
        Fluxes {
            psi_s: sub(v, scale(self.rs_ohm, i_s)),
            psi_r: d_psi_r,
            w: (t_e - b_nms * x.w - t_l) * inv_j,
        }
    }

    /// One classical RK4 step of `h_s` from `x` and its stator flux `psi_s`
    /// ([`Saturated::stator_flux`]) with the voltage at the step's start, middle and end
    /// and the load (with the passive torques) held; the state's angle by the stages'
    /// speeds, as the linear step does. Returns the state and its stator flux.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn step(
        &self,
        inv_j: f64,
        b_nms: f64,
        x: &MachineState,
        psi_s: V2,
        v: [V2; 3],
        t_l: f64,
        h_s: f64,
    ) -> (MachineState, V2) {
        let x0 = Fluxes { psi_s, psi_r: [x.psi_alpha_wb, x.psi_beta_wb], w: x.omega_m_rad_s };
        let at = |k: &Fluxes, s: f64| Fluxes {
            psi_s: add(x0.psi_s, scale(s, k.psi_s)),
            psi_r: add(x0.psi_r, scale(s, k.psi_r)),
            w: x0.w + s * k.w,
        };
        let [v0, v_mid, v1] = v;
        let k1 = self.f(inv_j, b_nms, &x0, v0, t_l);
        let x2 = at(&k1, 0.5 * h_s);
        let k2 = self.f(inv_j, b_nms, &x2, v_mid, t_l);
        let x3 = at(&k2, 0.5 * h_s);
        let k3 = self.f(inv_j, b_nms, &x3, v_mid, t_l);
        let x4 = at(&k3, h_s);
        let k4 = self.f(inv_j, b_nms, &x4, v1, t_l);
        let sum = |a: f64, b: f64, c: f64, d: f64| h_s / 6.0 * (a + 2.0 * (b + c) + d);
        let psi_s = [0, 1].map(|n| x0.psi_s[n] + sum(k1.psi_s[n], k2.psi_s[n], k3.psi_s[n], k4.psi_s[n]));
        let psi_r = [0, 1].map(|n| x0.psi_r[n] + sum(k1.psi_r[n], k2.psi_r[n], k3.psi_r[n], k4.psi_r[n]));
        let (i_s, _) = self.currents(psi_s, psi_r);
        let x1 = MachineState {
            i_alpha_a: i_s[0],
            i_beta_a: i_s[1],
            psi_alpha_wb: psi_r[0],
            psi_beta_wb: psi_r[1],
            omega_m_rad_s: x0.w + sum(k1.w, k2.w, k3.w, k4.w),
            theta_m_rad: x.theta_m_rad + sum(x0.w, x2.w, x3.w, x4.w),
        };
        (x1, psi_s)
    }

    /// The magnetic energy stored in the machine, J: the branch's (3/2)·∫f and the
    /// leakage's (3/2)·L·|i|²/2.
    #[cfg(test)]
    pub(crate) fn magnetic_energy_j(&self, x: &MachineState) -> f64 {
        let psi_s = self.stator_flux(x);
        let psi_r = [x.psi_alpha_wb, x.psi_beta_wb];
        let (i_s, i_r) = self.currents(psi_s, psi_r);
        let (psi_m, i_leak) = match self.form {
            Form::Gamma => (psi_s, i_r),
            Form::InverseGamma => (psi_r, i_s),
        };
        1.5 * (self.curve.energy(norm(psi_m))
            + 0.5 * self.leak_h * (i_leak[0] * i_leak[0] + i_leak[1] * i_leak[1]))
    }

    /// The power the resistances dissipate, W: the windings' and the iron's (the rotor's
    /// current less the iron's share, module docs).
    #[cfg(test)]
    pub(crate) fn copper_loss_w(&self, x: &MachineState) -> f64 {
        let psi_s = self.stator_flux(x);
        let psi_r = [x.psi_alpha_wb, x.psi_beta_wb];
        let (i_s, i_r) = self.currents(psi_s, psi_r);
        let u_m = self.rotor_flux_rate(i_r, psi_r, self.p * x.omega_m_rad_s);
        let i_rotor = add(i_r, scale(self.g_fe_s, u_m));
        let sq = |a: V2| a[0] * a[0] + a[1] * a[1];
        1.5 * (self.rs_ohm * sq(i_s) + self.rr_ohm * sq(i_rotor) + self.g_fe_s * sq(u_m))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Machine;

    /// motulator's 2.2 kW example machine, Γ form, as a T model (L_s = L_m = L_u).
    fn gamma_2kw() -> MotorParams {
        MotorParams::new(3.7, 2.5, 0.34, 0.34 + 0.023, 0.34, 2, 0.015, 0.0).unwrap()
    }

    fn law() -> MagnetizingCurve {
        MagnetizingCurve::law(0.34, 0.84, 7.0).unwrap()
    }

    fn sine(amp: f64, w: f64) -> impl Fn(f64) -> [f64; 2] {
        move |t: f64| [amp * (w * t).cos(), amp * (w * t).sin()]
    }

    /// A curve that is a straight line (points on ψ/L_m) is the linear machine: a 0.3 s
    /// direct-on-line start of the Γ and of the inverse-Γ form agrees with the linear
    /// plant (its own state and equations, seed 002 eq. (1)) to 1e-9 of the current's
    /// peak — rounding, accumulated over 30 000 steps.
    #[test]
    fn an_unsaturated_curve_is_the_linear_machine() {
        let inv_gamma = MotorParams::new(3.7, 2.1, 0.224 + 0.021, 0.224, 0.224, 2, 0.015, 0.0).unwrap();
        for (m, form) in [(gamma_2kw(), Form::Gamma), (inv_gamma, Form::InverseGamma)] {
            let psi: [f64; 3] = [0.5, 1.0, 3.0];
            let curve = MagnetizingCurve::points(&psi, &psi.map(|p| p / m.lm_h())).unwrap();
            let sat = Machine::saturated(&m, &Saturation { form, curve }).unwrap();
            let lin = Machine::new(&m);
            let (h, src) = (1e-5, sine(326.6, 2.0 * core::f64::consts::PI * 50.0));
            let (mut a, mut b) = (MachineState::default(), MachineState::default());
            let (mut worst, mut peak) = (0.0f64, 0.0f64);
            for n in 0..30_000 {
                let t = n as f64 * h;
                a = sat.rk4_source(&a, t, h, &src, 5.0);
                b = lin.rk4_source(&b, t, h, &src, 5.0);
                peak = peak.max(b.i_alpha_a.abs());
                worst = worst.max((a.i_alpha_a - b.i_alpha_a).abs()).max((a.i_beta_a - b.i_beta_a).abs());
                assert!((a.omega_m_rad_s - b.omega_m_rad_s).abs() < 1e-9 * (1.0 + b.omega_m_rad_s.abs()));
                assert!((sat.torque_nm(&a) - lin.torque_nm(&b)).abs() < 1e-8 * 30.0);
            }
            assert!(worst < 1e-9 * peak, "{form:?}: {worst} A of {peak} A");
        }
    }

    /// The nonlinearity neither makes nor loses energy: over a 0.4 s direct-on-line start
    /// of the saturating Γ machine (the flux well past the knee), the energy the source
    /// delivers equals the copper losses, the shaft's work and the change of the stored
    /// magnetic energy (the branch's ∫f plus the leakage's) to 1e-7 of the input — the
    /// trapezoid rule's error on a 2 µs grid; the inverse-Γ form with an iron-loss
    /// resistance too (its loss counted with the windings').
    #[test]
    fn the_saturating_machine_conserves_energy() {
        let inv_gamma = MotorParams::new(3.7, 2.1, 0.245, 0.224, 0.224, 2, 0.015, 0.0).unwrap();
        for (m, form, iron) in [
            (gamma_2kw(), Form::Gamma, false),
            (inv_gamma, Form::InverseGamma, false),
            (inv_gamma, Form::InverseGamma, true),
        ] {
            let machine = Machine::saturated(&m, &Saturation { form, curve: law() }).unwrap();
            let machine = if iron { machine.with_iron_loss(300.0).unwrap() } else { machine };
            let Some(sat) = machine.saturation else { panic!("saturating") };
            let (h, src) = (2e-6, sine(326.6, 2.0 * core::f64::consts::PI * 50.0));
            let mut x = MachineState::default();
            let power = |x: &MachineState, t: f64| {
                let v = src(t);
                let p_in = 1.5 * (v[0] * x.i_alpha_a + v[1] * x.i_beta_a);
                (p_in, sat.copper_loss_w(x), machine.torque_nm(x) * x.omega_m_rad_s)
            };
            let (mut e_in, mut e_cu, mut e_mech) = (0.0, 0.0, 0.0);
            let mut peak_flux = 0.0f64;
            for n in 0..200_000 {
                let t = n as f64 * h;
                let (p0, c0, m0) = power(&x, t);
                x = machine.rk4_source(&x, t, h, &src, 5.0);
                let (p1, c1, m1) = power(&x, t + h);
                e_in += 0.5 * h * (p0 + p1);
                e_cu += 0.5 * h * (c0 + c1);
                e_mech += 0.5 * h * (m0 + m1);
                peak_flux = peak_flux.max(norm(sat.stator_flux(&x)));
            }
            let residual = e_in - e_cu - e_mech - sat.magnetic_energy_j(&x);
            assert!(peak_flux > 1.0 / 0.84, "{form:?}: the run stayed below the knee ({peak_flux} Wb)");
            assert!(residual.abs() < 1e-7 * e_in, "{form:?}: {residual} J of {e_in} J");
        }
    }

    /// The analytic steady state in the synchronous frame (stator flux ψ on the real axis,
    /// slip ω_sl): ψ_r = ψ/(1 + jω_sl·L_ℓ/R_r), i_r = (ψ_r − ψ)/L_ℓ, i_s = f(ψ) − i_r,
    /// v = R_s·i_s + jω_s·ψ, T = (3/2)·p·Im(ψ·conj(i_s))·(−1). Started in it at a held
    /// speed, the machine stays in it for 0.1 s to 1e-9 in current and torque, at a flux
    /// below, at and beyond the knee.
    #[test]
    fn the_saturated_steady_state_is_the_analytic_one() {
        let m = gamma_2kw();
        let c = law();
        let machine =
            Machine::saturated(&m, &Saturation { form: Form::Gamma, curve: c }).unwrap().speed_locked();
        let (w_s, w_sl, l, rr, rs) = (2.0 * core::f64::consts::PI * 50.0, 6.0, 0.023, 2.5, 3.7);
        for psi in [0.4, 0.9, 1.2, 1.5] {
            // Complex arithmetic on (re, im) pairs.
            let k = w_sl * l / rr;
            let psi_r = [psi / (1.0 + k * k), -psi * k / (1.0 + k * k)];
            let i_r = [(psi_r[0] - psi) / l, psi_r[1] / l];
            let i_s = [c.current_a(psi) - i_r[0], -i_r[1]];
            let v = [rs * i_s[0], rs * i_s[1] + w_s * psi];
            let torque = 1.5 * 2.0 * (psi * i_s[1]);
            let w_m = (w_s - w_sl) / 2.0;
            let turn = |a: [f64; 2], t: f64| {
                let (co, si) = ((w_s * t).cos(), (w_s * t).sin());
                [a[0] * co - a[1] * si, a[0] * si + a[1] * co]
            };
            let mut x = MachineState {
                i_alpha_a: i_s[0],
                i_beta_a: i_s[1],
                psi_alpha_wb: psi_r[0],
                psi_beta_wb: psi_r[1],
                omega_m_rad_s: w_m,
                theta_m_rad: 0.0,
            };
            let h = 1e-5;
            for n in 0..10_000 {
                x = machine.rk4_source(&x, n as f64 * h, h, |t| turn(v, t), 0.0);
            }
            let want = turn(i_s, 0.1);
            let scale_a = i_s[0].hypot(i_s[1]);
            assert!((x.i_alpha_a - want[0]).abs() < 1e-9 * scale_a, "ψ {psi}: {x:?} vs {want:?}");
            assert!((x.i_beta_a - want[1]).abs() < 1e-9 * scale_a, "ψ {psi}");
            assert!((machine.torque_nm(&x) - torque).abs() < 1e-9 * torque.abs(), "ψ {psi}");
        }
    }

    /// Iron loss (inverse-Γ): the analytic steady state in the synchronous frame, the rotor
    /// flux ψ on the real axis at slip ω_sl — `u_m = jω_s·ψ`, the rotor's current
    /// `jω_sl·ψ/R_R`, the iron's `u_m/R_fe`, `i_s = f(ψ) + u_m/R_fe + jω_sl·ψ/R_R`,
    /// `v = R_s·i_s + jω_s·(ψ + L_σ·i_s)`, the torque the rotor's alone,
    /// `(3/2)·p·ψ²·ω_sl/R_R`. Started in it at a held speed, the machine stays in it for
    /// 0.1 s to 1e-9, below and beyond the knee; the iron loss there is
    /// `(3/2)·ω_s²·ψ²/R_fe`. Without R_fe the same voltage gives another current. And a Γ
    /// machine, a linear one or a resistance that is not one are refused.
    #[test]
    fn iron_loss_holds_its_analytic_steady_state() {
        let m = MotorParams::new(3.7, 2.1, 0.245, 0.224, 0.224, 2, 0.015, 0.0).unwrap();
        let c = law();
        let r_fe = 400.0;
        let lossless = Machine::saturated(&m, &Saturation { form: Form::InverseGamma, curve: c }).unwrap();
        let machine = lossless.with_iron_loss(r_fe).unwrap().speed_locked();
        assert_eq!(machine.iron_loss_ohm(), Some(r_fe));
        let (w_s, w_sl, l, rr, rs) = (2.0 * core::f64::consts::PI * 50.0, 6.0, 0.245 - 0.224, 2.1, 3.7);
        for psi in [0.5, 0.9, 1.2] {
            let i_s = [c.current_a(psi), w_s * psi / r_fe + w_sl * psi / rr];
            let v = [rs * i_s[0] - w_s * l * i_s[1], rs * i_s[1] + w_s * (psi + l * i_s[0])];
            let torque = 1.5 * 2.0 * psi * psi * w_sl / rr;
            let turn = |a: [f64; 2], t: f64| {
                let (co, si) = ((w_s * t).cos(), (w_s * t).sin());
                [a[0] * co - a[1] * si, a[0] * si + a[1] * co]
            };
            let start = MachineState {
                i_alpha_a: i_s[0],
                i_beta_a: i_s[1],
                psi_alpha_wb: psi,
                omega_m_rad_s: (w_s - w_sl) / 2.0,
                ..Default::default()
            };
            let run = |mach: &Machine| {
                let (mut x, h) = (start, 1e-5);
                for n in 0..10_000 {
                    x = mach.rk4_source(&x, n as f64 * h, h, |t| turn(v, t), 0.0);
                }
                x
            };
            let x = run(&machine);
            let want = turn(i_s, 0.1);
            let scale_a = i_s[0].hypot(i_s[1]);
            assert!((x.i_alpha_a - want[0]).abs() < 1e-9 * scale_a, "ψ {psi}: {x:?} vs {want:?}");
            assert!((x.i_beta_a - want[1]).abs() < 1e-9 * scale_a, "ψ {psi}");
            assert!((machine.torque_nm(&x) - torque).abs() < 1e-9 * torque, "ψ {psi}");
            let Some(sat) = machine.saturation else { panic!("saturating") };
            let copper = 1.5 * (rs * scale_a * scale_a + rr * (w_sl * psi / rr).powi(2));
            let iron = 1.5 * (w_s * psi).powi(2) / r_fe;
            assert!((sat.copper_loss_w(&x) - copper - iron).abs() < 1e-8 * (copper + iron), "ψ {psi}");
            let y = run(&lossless.speed_locked());
            assert!((y.i_beta_a - x.i_beta_a).hypot(y.i_alpha_a - x.i_alpha_a) > 0.05 * scale_a, "ψ {psi}");
        }
        let gamma = Machine::saturated(&gamma_2kw(), &Saturation { form: Form::Gamma, curve: c }).unwrap();
        assert_eq!(gamma.with_iron_loss(r_fe).map(|_| ()), Err(SaturationError::IronLoss));
        assert_eq!(Machine::new(&m).with_iron_loss(r_fe).map(|_| ()), Err(SaturationError::IronLoss));
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert_eq!(lossless.with_iron_loss(bad).map(|_| ()), Err(SaturationError::IronLoss), "{bad}");
        }
    }

    /// The open stator's voltage keeps the saturated machine's current at zero: one 1 µs
    /// step with it leaves a current three orders below the shorted stator's, at a
    /// saturated rotor flux, in both forms; unsaturated it is the linear formula.
    #[test]
    fn the_open_circuit_voltage_keeps_the_saturated_current_at_zero() {
        let inv_gamma = MotorParams::new(3.7, 2.1, 0.245, 0.224, 0.224, 2, 0.015, 0.0).unwrap();
        for (m, form) in [(gamma_2kw(), Form::Gamma), (inv_gamma, Form::InverseGamma)] {
            let machine = Machine::saturated(&m, &Saturation { form, curve: law() }).unwrap();
            let x = MachineState {
                psi_alpha_wb: 0.9,
                psi_beta_wb: -1.0,
                omega_m_rad_s: 150.0,
                ..Default::default()
            };
            let v = machine.open_circuit_voltage(&x);
            let mag = |y: &MachineState| y.i_alpha_a.hypot(y.i_beta_a);
            let held = mag(&machine.rk4(&x, v, 0.0, 1e-6));
            let shorted = mag(&machine.rk4(&x, [0.0, 0.0], 0.0, 1e-6));
            assert!(held < 1e-3 * shorted, "{form:?}: {held} vs {shorted}");
        }
    }

    /// A stepper takes its last step's stator flux only for exactly that step's result: a
    /// chained run equals fresh steppers' (which recover the flux by Newton) to rounding,
    /// and a state changed between steps (the diodes' projection of the current) is
    /// recovered, not taken from the cache.
    #[test]
    fn a_stepper_reuses_its_stator_flux_only_for_its_own_result() {
        let machine =
            Machine::saturated(&gamma_2kw(), &Saturation { form: Form::Gamma, curve: law() }).unwrap();
        let rk4 = machine.rk4_stepper(5e-5);
        let mut x = MachineState { psi_alpha_wb: 1.0, omega_m_rad_s: 140.0, ..Default::default() };
        for _ in 0..200 {
            let fresh = machine.rk4_stepper(5e-5).step(&x, [300.0, 100.0], 5.0);
            x = rk4.step(&x, [300.0, 100.0], 5.0);
            assert!(
                (x.i_alpha_a - fresh.i_alpha_a).abs() < 1e-9 * (1.0 + fresh.i_alpha_a.abs()),
                "{x:?} {fresh:?}"
            );
        }
        let changed = MachineState { i_alpha_a: x.i_alpha_a + 3.0, ..x };
        let fresh = machine.rk4_stepper(5e-5).step(&changed, [300.0, 100.0], 5.0);
        assert_eq!(rk4.step(&changed, [300.0, 100.0], 5.0), fresh);
    }

    #[test]
    fn a_form_its_parameters_contradict_is_refused() {
        let t = MotorParams::new(3.7, 2.5, 0.36, 0.36, 0.34, 2, 0.015, 0.0).unwrap();
        let sat = |form| Saturation { form, curve: law() };
        assert_eq!(
            Machine::saturated(&t, &sat(Form::Gamma)).err(),
            Some(SaturationError::GammaNeedsNoStatorLeakage)
        );
        assert_eq!(
            Machine::saturated(&gamma_2kw(), &sat(Form::InverseGamma)).err(),
            Some(SaturationError::InverseGammaNeedsNoRotorLeakage)
        );
    }
}
