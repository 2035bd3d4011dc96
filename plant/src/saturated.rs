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
//! the stator current would not be a state: refused there.
//!
//! **A deep-bar rotor** (inverse-Γ only, [`crate::Machine::with_deep_bar`]): a second cage
//! in parallel with the first at the magnetizing node, behind its own leakage L₂ — the
//! double-cage circuit, which with R_s, L_σ, L_M, R₁, R₂, L₂ is as general at the terminals
//! as any linear double-cage T model (its operational impedance has as many free
//! coefficients). Its flux `ψ₂ = ψ_R + L₂·i₂` obeys `dψ₂/dt = −R₂·i₂ + p·ω_m·J·ψ₂`, and
//! the first cage carries the rest, `i_r = f(|ψ_r|)·ψ_r/|ψ_r| − i_s − i₂`. The torque keeps
//! its formula (`ψ_k × i_k = ψ_R × i_k` for each cage). In the synchronous frame at slip
//! ω the rotor admits `1/R₁ + 1/(R₂ + jω·L₂)`: its resistance `1/Re(·)` rises from
//! `R₁‖R₂` at zero slip (the running machine's R_R) to R₁ at high slip — what a deep bar's
//! current crowding does (Boldea & Nasar, "The Induction Machine Handbook", ch. 9, where the
//! double cage is the bar's two-section approximation).
//!
//! **A linear T model** takes iron loss and a deep bar in its inverse-Γ equivalent (Slemon:
//! `L_M = L_m²/L_r`, `L_σ = L_s − L_M`, `R_R = R_r·(L_m/L_r)²`, the same machine at the
//! terminals), on the straight line of L_M; its state's rotor flux stays the T model's,
//! `ψ_r = (L_r/L_m)·ψ_R`, so the trace and the drive read the flux they know.
//!
//! The machine's state stays [`MachineState`]'s (stator
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
    /// A deep bar is modelled in the inverse-Γ form only (module docs), with its high-slip
    /// resistance factor finite and above 1 and its corner slip frequency finite and
    /// positive.
    DeepBar,
    /// A deep bar whose second cage's zero-slip leakage ([`DeepBar::zero_slip_leakage_h`])
    /// is not below the motor's L_σ.
    DeepBarLeakage,
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
            Self::DeepBar => {
                "a deep bar needs the inverse-Γ form (its rotor cages at the magnetizing branch), a high-slip \
                 resistance factor above 1 and a positive corner slip frequency"
            }
            Self::DeepBarLeakage => {
                "the deep bar's second cage leaks more at zero slip than the motor's whole leakage: its corner \
                 slip frequency is too low (or its factor too high) for this motor — L₂ = R₂/(2π·f) must leave \
                 L_σ > L₂·((k − 1)/k)²"
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
    /// The form's rotor resistance (Γ: R_r; inverse-Γ: R_R; with a deep bar, the first
    /// cage's R₁), Ω.
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
    /// A linear T model carried in its inverse-Γ equivalent (module docs): its state's
    /// rotor flux is `L_r/L_m` times the branch's (`None`: the state's is the branch's).
    linear_t: Option<f64>,
    /// A deep bar's second cage (module docs).
    cage: Option<Cage>,
}

/// A deep bar's second rotor cage, in parallel with the first at the magnetizing node.
#[derive(Clone, Copy, Debug)]
struct Cage {
    /// R₂, Ω.
    r_ohm: f64,
    /// L₂, H.
    l_h: f64,
    /// 1/L₂, 1/H.
    inv_l_per_h: f64,
    /// R₁ over the running resistance R₁‖R₂ (the bar's high-slip factor).
    high_slip_factor: f64,
    /// The leakage the second cage adds at zero slip, `L₂·(R₁/(R₁ + R₂))²`, H: taken from
    /// L_σ ([`DeepBar::zero_slip_leakage_h`]).
    zero_slip_leakage_h: f64,
}

/// A deep-bar rotor as its nameplate-level figures: the rotor resistance rises from the
/// running (zero-slip) R_R of the motor it is added to, to `high_slip_resistance_factor`
/// times it at high slip, the rise centred where the second cage's `R₂/L₂` is
/// `2π·corner_slip_hz` ([`crate::Machine::with_deep_bar`], module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DeepBar {
    /// R₁/R_R: the rotor resistance at high slip over the running one, > 1.
    pub high_slip_resistance_factor: f64,
    /// The inner cage's corner, `R₂/(2π·L₂)`, Hz of slip.
    pub corner_slip_hz: f64,
}

impl DeepBar {
    /// The circuit for a running rotor resistance `rr_ohm`: (R₁, R₂, L₂), with
    /// `R₁‖R₂ = rr_ohm`, `R₁ = k·rr_ohm`, so `R₂ = rr_ohm·k/(k − 1)`.
    pub fn circuit(&self, rr_ohm: f64) -> Result<(f64, f64, f64), SaturationError> {
        let (k, f) = (self.high_slip_resistance_factor, self.corner_slip_hz);
        if !(k.is_finite() && k > 1.0 && f.is_finite() && f > 0.0) {
            return Err(SaturationError::DeepBar);
        }
        let r2 = rr_ohm * k / (k - 1.0);
        Ok((k * rr_ohm, r2, r2 / (core::f64::consts::TAU * f)))
    }

    /// The leakage the second cage adds at zero slip for a running rotor resistance
    /// `rr_ohm`, H: at slip ω the rotor's impedance `R₁‖(R₂ + jω·L₂)` is `R₁‖R₂ +
    /// jω·L₂·(R₁/(R₁ + R₂))² + O(ω²)`, with `R₁/(R₁ + R₂) = (k − 1)/k`. The machine takes it
    /// from its L_σ, so that at zero slip — where a motor file's circuit is measured (a
    /// running machine; IEEE 112's locked-rotor test at reduced frequency for a deep bar) —
    /// both its resistance and its leakage are the file's; at high slip the resistance rises
    /// to k·R_R and the leakage falls by this much, as a deep bar's crowding does.
    pub fn zero_slip_leakage_h(&self, rr_ohm: f64) -> Result<f64, SaturationError> {
        let (_, _, l2) = self.circuit(rr_ohm)?;
        let share = (self.high_slip_resistance_factor - 1.0) / self.high_slip_resistance_factor;
        Ok(l2 * share * share)
    }

    /// Where a bar of height `height_m` and resistivity `resistivity_ohm_m` starts to crowd
    /// its current, Hz of slip: where the skin depth `δ = √(2ρ/(μ₀·ω))` equals the height,
    /// `f = ρ/(π·μ₀·h²)` — the physics a deep bar's corner stands for.
    pub fn corner_slip_hz_of_bar(height_m: f64, resistivity_ohm_m: f64) -> f64 {
        const MU_0_H_PER_M: f64 = 4e-7 * core::f64::consts::PI;
        resistivity_ohm_m / (core::f64::consts::PI * MU_0_H_PER_M * height_m * height_m)
    }

    /// The rotor's resistance at slip frequency `slip_hz` over the running one: `1/Re(Y)`
    /// with `Y = 1/R₁ + 1/(R₂ + jω·L₂)` (module docs), for a running R_R of 1.
    pub fn resistance_factor_at(&self, slip_hz: f64) -> Result<f64, SaturationError> {
        let (r1, r2, l2) = self.circuit(1.0)?;
        let x = core::f64::consts::TAU * slip_hz * l2;
        Ok(1.0 / (1.0 / r1 + r2 / (r2 * r2 + x * x)))
    }
}

/// The fluxes a step integrates, and the speed.
#[derive(Clone, Copy, Debug)]
struct Fluxes {
    psi_s: V2,
    psi_r: V2,
    /// The second cage's flux ψ₂ (a deep bar; zero and unused otherwise).
    psi_2: V2,
    w: f64,
}

/// The largest eigenvalue of the symmetric 3×3 `[[a, d, e], [d, b, f], [e, f, c]]`
/// (Smith's closed form, "Eigenvalues of a symmetric 3 × 3 matrix", CACM 1961).
fn largest_symmetric_eigenvalue(a: f64, b: f64, c: f64, d: f64, e: f64, f: f64) -> f64 {
    let q = (a + b + c) / 3.0;
    let off = d * d + e * e + f * f;
    let p2 = (a - q).powi(2) + (b - q).powi(2) + (c - q).powi(2) + 2.0 * off;
    if p2 == 0.0 {
        return q;
    }
    let p = (p2 / 6.0).sqrt();
    let (ba, bb, bc, bd, be, bf) = ((a - q) / p, (b - q) / p, (c - q) / p, d / p, e / p, f / p);
    let det = ba * (bb * bc - bf * bf) - bd * (bd * bc - bf * be) + be * (bd * bf - bb * be);
    let phi = (0.5 * det).clamp(-1.0, 1.0).acos() / 3.0;
    q + 2.0 * p * phi.cos()
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
        let mut s = Self {
            form: sat.form,
            curve: sat.curve,
            rs_ohm: m.rs_ohm(),
            rr_ohm: m.rr_ohm(),
            inv_leak_per_h: 1.0 / leak_h,
            leak_h,
            p: f64::from(m.pole_pairs()),
            lm_h: m.lm_h(),
            fastest_rate_per_s: f64::INFINITY,
            g_fe_s: 0.0,
            linear_t: None,
            cage: None,
        };
        s.fastest_rate_per_s = s.fastest_rate();
        Ok(s)
    }

    /// A linear T model `m` in its inverse-Γ equivalent on the straight line of L_M
    /// (module docs): the same machine at the terminals, to carry iron loss or a deep bar.
    pub(crate) fn linear_equivalent(m: &MotorParams) -> Result<Self, SaturationError> {
        let g = m.lm_h() / m.lr_h();
        let l_big_m = g * m.lm_h();
        let inv_gamma = MotorParams::new(
            m.rs_ohm(),
            m.rr_ohm() * g * g,
            m.ls_h(),
            l_big_m,
            l_big_m,
            m.pole_pairs(),
            m.j_kgm2(),
            m.b_nms(),
        )
        .map_err(|_| SaturationError::InverseGammaNeedsNoRotorLeakage)?;
        let psi = [1.0, 2.0];
        let curve = MagnetizingCurve::points(&psi, &psi.map(|x| x / l_big_m))
            .map_err(|_| SaturationError::InverseGammaNeedsNoRotorLeakage)?;
        let s = Self::new(&inv_gamma, &Saturation { form: Form::InverseGamma, curve })?;
        Ok(Self { linear_t: Some(1.0 / g), lm_h: m.lm_h(), ..s })
    }

    /// Whether the branch has a machine's curve (not the straight line of a linear machine
    /// carried for its iron loss or deep bar).
    pub(crate) fn is_curved(&self) -> bool {
        self.linear_t.is_none()
    }

    /// The fastest mode: the linear machine with the branch's incremental inductance deep
    /// in saturation, where it is smallest. With a deep bar, one axis at standstill is
    /// `dψ/dt = −R·C·ψ` over (ψ_s, ψ_R, ψ₂), R = diag(R_s, R₁, R₂) and C the inverse
    /// inductance matrix; its rates are the eigenvalues of the symmetric `R^½·C·R^½`.
    /// (Iron loss only slows the branch: left out; the mechanics do not enter.)
    fn fastest_rate(&self) -> f64 {
        let l_inc = 1.0 / self.curve.slope_per_h(self.curve.deep_flux_wb());
        if let Some(c) = &self.cage {
            let (a, g) = (self.inv_leak_per_h, 1.0 / l_inc);
            let (rs, r1, r2) = (self.rs_ohm, self.rr_ohm, c.r_ohm);
            return largest_symmetric_eigenvalue(
                rs * a,
                r1 * (g + a + c.inv_l_per_h),
                r2 * c.inv_l_per_h,
                -(rs * r1).sqrt() * a,
                0.0,
                -(r1 * r2).sqrt() * c.inv_l_per_h,
            );
        }
        let (ls, lr) = match self.form {
            Form::Gamma => (l_inc, l_inc + self.leak_h),
            Form::InverseGamma => (l_inc + self.leak_h, l_inc),
        };
        MotorParams::new(self.rs_ohm, self.rr_ohm, ls, lr, l_inc, 1, 1.0, 0.0)
            .map_or(f64::INFINITY, |deep| crate::Machine::new(&deep).fastest_rate_per_s())
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

    /// The same machine with its rotor a deep bar (module docs): inverse-Γ form only, the
    /// branch's R_R the running resistance. A second call replaces the first's bar.
    pub(crate) fn with_deep_bar(&self, bar: &DeepBar) -> Result<Self, SaturationError> {
        if self.form != Form::InverseGamma {
            return Err(SaturationError::DeepBar);
        }
        let running = self.running_rr_ohm();
        let (r1, r2, l2) = bar.circuit(running)?;
        let zero_slip_leakage_h = bar.zero_slip_leakage_h(running)?;
        // The file's L_σ is the zero-slip leakage: the main one is what the cage leaves of it.
        let leak_h = self.leak_h + self.cage.map_or(0.0, |c| c.zero_slip_leakage_h) - zero_slip_leakage_h;
        if !leak_h.is_finite() || leak_h <= 0.0 {
            return Err(SaturationError::DeepBarLeakage);
        }
        let cage = Cage {
            r_ohm: r2,
            l_h: l2,
            inv_l_per_h: 1.0 / l2,
            high_slip_factor: bar.high_slip_resistance_factor,
            zero_slip_leakage_h,
        };
        let mut s = Self { rr_ohm: r1, leak_h, inv_leak_per_h: 1.0 / leak_h, cage: Some(cage), ..*self };
        s.fastest_rate_per_s = s.fastest_rate();
        Ok(s)
    }

    /// The rotor's resistance at zero slip, Ω: R_R, or R₁‖R₂ with a deep bar.
    fn running_rr_ohm(&self) -> f64 {
        match &self.cage {
            Some(c) => self.rr_ohm / c.high_slip_factor,
            None => self.rr_ohm,
        }
    }

    /// The deep bar (`None`: one cage).
    pub(crate) fn deep_bar(&self) -> Option<DeepBar> {
        self.cage.map(|c| DeepBar {
            high_slip_resistance_factor: c.high_slip_factor,
            corner_slip_hz: c.r_ohm / (core::f64::consts::TAU * c.l_h),
        })
    }

    /// The same branch on the electrical parameters of `m` (a parameter step mid-run): the
    /// curve's inductances scaled as `m`'s L_m is to the one this was made with; a deep
    /// bar's resistances scaled with the running R_R (one temperature), its leakage kept.
    pub(crate) fn with_electrical(&self, m: &MotorParams) -> Result<Self, SaturationError> {
        let base = match self.linear_t {
            Some(_) => Self::linear_equivalent(m)?,
            None => {
                let curve = self.curve.with_inductance_scaled(m.lm_h() / self.lm_h);
                Self::new(m, &Saturation { form: self.form, curve })?
            }
        };
        let base = Self { g_fe_s: self.g_fe_s, ..base };
        match &self.cage {
            None => Ok(base),
            Some(c) => {
                let r2 = c.r_ohm * base.rr_ohm / self.running_rr_ohm();
                let corner_slip_hz = r2 / (core::f64::consts::TAU * c.l_h);
                base.with_deep_bar(&DeepBar {
                    high_slip_resistance_factor: c.high_slip_factor,
                    corner_slip_hz,
                })
            }
        }
    }

    /// The branch's rotor flux of a state, and back (module docs: a linear T model's state
    /// keeps the T model's ψ_r).
    #[inline]
    fn branch_flux(&self, x: &MachineState) -> V2 {
        let psi = [x.psi_alpha_wb, x.psi_beta_wb];
        match self.linear_t {
            Some(k) => scale(1.0 / k, psi),
            None => psi,
        }
    }
    #[inline]
    fn state_flux(&self, psi_r: V2) -> V2 {
        match self.linear_t {
            Some(k) => scale(k, psi_r),
            None => psi_r,
        }
    }

    /// The second cage's flux of a state, `ψ_R + L₂·i₂` (zero without a deep bar).
    #[inline]
    fn cage_flux(&self, x: &MachineState, psi_r: V2) -> V2 {
        match &self.cage {
            Some(c) => add(psi_r, scale(c.l_h, [x.i_cage_alpha_a, x.i_cage_beta_a])),
            None => [0.0; 2],
        }
    }

    /// The rotor flux's rate, `dψ_r/dt` — the air-gap voltage `u_m` of the inverse-Γ form —
    /// for the fluxes' rotor current `i_r` (without the iron's share), the rotor flux and
    /// the electrical speed `w`.
    #[inline]
    fn rotor_flux_rate(&self, i_r: V2, psi_r: V2, w: f64) -> V2 {
        let d = add(scale(-self.rr_ohm, i_r), scale(w, rot(psi_r)));
        if self.g_fe_s > 0.0 { scale(1.0 / (1.0 + self.rr_ohm * self.g_fe_s), d) } else { d }
    }

    /// `(3/2)·p·(ψ_s × i_s − G_fe·ψ_r × u_m)`: the rotor cages' torque (module docs).
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

    /// Stator, (first) rotor cage and second cage currents of the fluxes (the second zero
    /// without a deep bar).
    #[inline]
    fn currents(&self, psi_s: V2, psi_r: V2, psi_2: V2) -> (V2, V2, V2) {
        match self.form {
            Form::Gamma => {
                let i_r = scale(self.inv_leak_per_h, sub(psi_r, psi_s));
                (sub(self.magnetizing(psi_s), i_r), i_r, [0.0; 2])
            }
            Form::InverseGamma => {
                let i_s = scale(self.inv_leak_per_h, sub(psi_s, psi_r));
                let i_2 = match &self.cage {
                    Some(c) => scale(c.inv_l_per_h, sub(psi_2, psi_r)),
                    None => [0.0; 2],
                };
                (i_s, sub(sub(self.magnetizing(psi_r), i_s), i_2), i_2)
            }
        }
    }

    /// The stator flux of a state (its stator current and rotor flux). Γ: the branch and the
    /// leakage in parallel carry `i_s + ψ_r/L_ℓ`, so ψ_s lies along that vector with the
    /// magnitude that makes `f(|ψ_s|) + |ψ_s|/L_ℓ` equal its length; inverse-Γ: ψ_r + L_σ·i_s.
    pub(crate) fn stator_flux(&self, x: &MachineState) -> V2 {
        let (i_s, psi_r) = ([x.i_alpha_a, x.i_beta_a], self.branch_flux(x));
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
        let psi_r = self.branch_flux(x);
        let (i_s, i_r, _) = self.currents(psi_s, psi_r, self.cage_flux(x, psi_r));
        let u_m = self.rotor_flux_rate(i_r, psi_r, self.p * x.omega_m_rad_s);
        self.torque_of(psi_s, i_s, psi_r, u_m)
    }

    /// The terminal voltage at which the stator current stays zero (the open stator's), αβ:
    /// with i_s = 0 the stator flux is a function of the rotor flux alone and `v = dψ_s/dt`.
    /// Γ: ψ_s along ψ_r with `f(|ψ_s|) + |ψ_s|/L_ℓ = |ψ_r|/L_ℓ`; a change of ψ_r along
    /// itself moves |ψ_s| by `(1/L_ℓ)/(f′ + 1/L_ℓ)`, across it turns ψ_s by `|ψ_s|/|ψ_r|`.
    /// Inverse-Γ: ψ_s = ψ_r (a linear T model's terminals see the branch's rate).
    pub(crate) fn open_circuit_voltage(&self, x: &MachineState) -> V2 {
        let psi_r = self.branch_flux(x);
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
            Form::InverseGamma => {
                let (_, i_r, _) = self.currents(psi_r, psi_r, self.cage_flux(x, psi_r));
                self.rotor_flux_rate(i_r, psi_r, w)
            }
        }
    }

    /// The derivative of the fluxes and the speed; `t_l` the load and passive torque, held.
    #[inline]
    fn f(&self, inv_j: f64, b_nms: f64, x: &Fluxes, v: V2, t_l: f64) -> Fluxes {
        let (i_s, i_r, i_2) = self.currents(x.psi_s, x.psi_r, x.psi_2);
        let w = self.p * x.w;
        let d_psi_r = self.rotor_flux_rate(i_r, x.psi_r, w);
        let t_e = self.torque_of(x.psi_s, i_s, x.psi_r, d_psi_r);
        let psi_2 = match &self.cage {
            Some(c) => add(scale(-c.r_ohm, i_2), scale(w, rot(x.psi_2))),
            None => [0.0; 2],
        };
        Fluxes {
            psi_s: sub(v, scale(self.rs_ohm, i_s)),
            psi_r: d_psi_r,
            psi_2,
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
        let psi_r = self.branch_flux(x);
        let x0 = Fluxes { psi_s, psi_r, psi_2: self.cage_flux(x, psi_r), w: x.omega_m_rad_s };
        let at = |k: &Fluxes, s: f64| Fluxes {
            psi_s: add(x0.psi_s, scale(s, k.psi_s)),
            psi_r: add(x0.psi_r, scale(s, k.psi_r)),
            psi_2: add(x0.psi_2, scale(s, k.psi_2)),
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
        let psi_2 = match &self.cage {
            Some(_) => [0, 1].map(|n| x0.psi_2[n] + sum(k1.psi_2[n], k2.psi_2[n], k3.psi_2[n], k4.psi_2[n])),
            None => [0.0; 2],
        };
        let (i_s, _, i_2) = self.currents(psi_s, psi_r, psi_2);
        let state_psi = self.state_flux(psi_r);
        let x1 = MachineState {
            i_alpha_a: i_s[0],
            i_beta_a: i_s[1],
            psi_alpha_wb: state_psi[0],
            psi_beta_wb: state_psi[1],
            omega_m_rad_s: x0.w + sum(k1.w, k2.w, k3.w, k4.w),
            theta_m_rad: x.theta_m_rad + sum(x0.w, x2.w, x3.w, x4.w),
            i_cage_alpha_a: i_2[0],
            i_cage_beta_a: i_2[1],
        };
        (x1, psi_s)
    }

    /// The magnetic energy stored in the machine, J: the branch's (3/2)·∫f and the
    /// leakages' (3/2)·L·|i|²/2 (the second cage's with a deep bar).
    #[cfg(test)]
    pub(crate) fn magnetic_energy_j(&self, x: &MachineState) -> f64 {
        let psi_s = self.stator_flux(x);
        let psi_r = self.branch_flux(x);
        let (i_s, i_r, i_2) = self.currents(psi_s, psi_r, self.cage_flux(x, psi_r));
        let (psi_m, i_leak) = match self.form {
            Form::Gamma => (psi_s, i_r),
            Form::InverseGamma => (psi_r, i_s),
        };
        let sq = |a: V2| a[0] * a[0] + a[1] * a[1];
        let cage = self.cage.map_or(0.0, |c| 0.5 * c.l_h * sq(i_2));
        1.5 * (self.curve.energy(norm(psi_m)) + 0.5 * self.leak_h * sq(i_leak) + cage)
    }

    /// The power the resistances dissipate, W: the windings' (both cages' with a deep bar)
    /// and the iron's (the rotor's current less the iron's share, module docs).
    #[cfg(test)]
    pub(crate) fn copper_loss_w(&self, x: &MachineState) -> f64 {
        let psi_s = self.stator_flux(x);
        let psi_r = self.branch_flux(x);
        let (i_s, i_r, i_2) = self.currents(psi_s, psi_r, self.cage_flux(x, psi_r));
        let u_m = self.rotor_flux_rate(i_r, psi_r, self.p * x.omega_m_rad_s);
        let i_rotor = add(i_r, scale(self.g_fe_s, u_m));
        let sq = |a: V2| a[0] * a[0] + a[1] * a[1];
        let cage = self.cage.map_or(0.0, |c| c.r_ohm * sq(i_2));
        1.5 * (self.rs_ohm * sq(i_s) + self.rr_ohm * sq(i_rotor) + self.g_fe_s * sq(u_m) + cage)
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
    /// resistance too (its loss counted with the windings'), and with a deep bar besides
    /// (its second cage's loss and leakage energy counted).
    #[test]
    fn the_saturating_machine_conserves_energy() {
        let inv_gamma = MotorParams::new(3.7, 2.1, 0.245, 0.224, 0.224, 2, 0.015, 0.0).unwrap();
        let bar = DeepBar { high_slip_resistance_factor: 2.5, corner_slip_hz: 60.0 };
        for (m, form, iron, deep) in [
            (gamma_2kw(), Form::Gamma, false, false),
            (inv_gamma, Form::InverseGamma, false, false),
            (inv_gamma, Form::InverseGamma, true, false),
            (inv_gamma, Form::InverseGamma, true, true),
        ] {
            let machine = Machine::saturated(&m, &Saturation { form, curve: law() }).unwrap();
            let machine = if iron { machine.with_iron_loss(300.0).unwrap() } else { machine };
            let machine = if deep { machine.with_deep_bar(&bar).unwrap() } else { machine };
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
                ..Default::default()
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
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert_eq!(lossless.with_iron_loss(bad).map(|_| ()), Err(SaturationError::IronLoss), "{bad}");
        }
    }

    /// A deep bar (inverse-Γ): the analytic steady state in the synchronous frame, the
    /// rotor flux ψ on the real axis at slip ω — the first cage's current `−jω·ψ/R₁`, the
    /// second's `−jω·ψ/(R₂ + jω·L₂)`, `i_s = f(ψ)` less both, `v = R_s·i_s + jω_s·(ψ +
    /// L_σ·i_s)`, the torque `(3/2)·p·ψ²·ω/R(ω)` with `R(ω)` the bar's resistance at that
    /// slip ([`DeepBar::resistance_factor_at`] times the running R_R). Started in it at a
    /// held speed, the machine stays in it for 0.1 s to 1e-9 in both currents (and the
    /// torque to what that is in torque), from a slip far below the corner to one far above it, below and beyond the
    /// knee; the resistance there runs from R_R to near k·R_R.
    #[test]
    fn a_deep_bar_holds_its_analytic_steady_state() {
        let m = MotorParams::new(3.7, 2.1, 0.245, 0.224, 0.224, 2, 0.015, 0.0).unwrap();
        let c = law();
        let bar = DeepBar { high_slip_resistance_factor: 2.5, corner_slip_hz: 15.0 };
        let machine = Machine::saturated(&m, &Saturation { form: Form::InverseGamma, curve: c })
            .unwrap()
            .with_deep_bar(&bar)
            .unwrap()
            .speed_locked();
        let read = machine.deep_bar().unwrap();
        assert!((read.corner_slip_hz - 15.0).abs() < 1e-12 && read.high_slip_resistance_factor == 2.5);
        let (r1, r2, l2) = bar.circuit(2.1).unwrap();
        assert!((1.0 / (1.0 / r1 + 1.0 / r2) - 2.1).abs() < 1e-12);
        // The main leakage: the file's, less what the second cage adds at zero slip.
        let l_sigma = 0.245 - 0.224 - bar.zero_slip_leakage_h(2.1).unwrap();
        let (w_s, l, rs) = (2.0 * core::f64::consts::PI * 50.0, l_sigma, 3.7);
        let mut factors = Vec::new();
        for psi in [0.5, 1.2] {
            for w_sl in [1.0, 6.0, 60.0, 300.0] {
                // Complex arithmetic on (re, im) pairs: 1/(R₂ + jω·L₂).
                let den = r2 * r2 + (w_sl * l2).powi(2);
                let y2 = [r2 / den, -w_sl * l2 / den];
                let i_1 = [0.0, -w_sl * psi / r1];
                let i_2 = [w_sl * psi * y2[1], -w_sl * psi * y2[0]];
                let i_s = [c.current_a(psi) - i_1[0] - i_2[0], -i_1[1] - i_2[1]];
                let v = [rs * i_s[0] - w_s * l * i_s[1], rs * i_s[1] + w_s * (psi + l * i_s[0])];
                let factor = bar.resistance_factor_at(w_sl / core::f64::consts::TAU).unwrap();
                let torque = 1.5 * 2.0 * psi * psi * w_sl / (2.1 * factor);
                factors.push(factor);
                let turn = |a: [f64; 2], t: f64| {
                    let (co, si) = ((w_s * t).cos(), (w_s * t).sin());
                    [a[0] * co - a[1] * si, a[0] * si + a[1] * co]
                };
                let mut x = MachineState {
                    i_alpha_a: i_s[0],
                    i_beta_a: i_s[1],
                    psi_alpha_wb: psi,
                    omega_m_rad_s: (w_s - w_sl) / 2.0,
                    i_cage_alpha_a: i_2[0],
                    i_cage_beta_a: i_2[1],
                    ..Default::default()
                };
                assert!(
                    (machine.torque_nm(&x) - torque).abs() < 1e-9 * torque,
                    "ψ {psi}, ω {w_sl}: at the start"
                );
                let h = 1e-5;
                for n in 0..10_000 {
                    x = machine.rk4_source(&x, n as f64 * h, h, |t| turn(v, t), 0.0);
                }
                let (want, want_2) = (turn(i_s, 0.1), turn(i_2, 0.1));
                let scale_a = i_s[0].hypot(i_s[1]);
                let close = |a: f64, b: f64| (a - b).abs() < 1e-9 * scale_a;
                assert!(
                    close(x.i_alpha_a, want[0]) && close(x.i_beta_a, want[1]),
                    "ψ {psi}, ω {w_sl}: {x:?}"
                );
                assert!(
                    close(x.i_cage_alpha_a, want_2[0]) && close(x.i_cage_beta_a, want_2[1]),
                    "ψ {psi}, ω {w_sl}"
                );
                // The currents' tolerance in torque: (3/2)·p·ψ times 1e-9 of the current.
                let torque_tol = 1e-9 * 1.5 * 2.0 * psi * scale_a;
                let got = machine.torque_nm(&x);
                assert!((got - torque).abs() < torque_tol, "ψ {psi}, ω {w_sl}: {got} vs {torque}");
            }
        }
        // The corner's physics: an aluminium bar at 75 °C (3.4e-8 Ω·m), 10 and 40 mm high.
        let corner = |h: f64| DeepBar::corner_slip_hz_of_bar(h, 3.4e-8);
        assert!((corner(0.010) - 86.12).abs() < 0.01 && (corner(0.040) - 5.383).abs() < 1e-3);
        // From the running R_R (below the corner) to near k·R_R (far above it).
        assert!(factors[0] < 1.001 && factors[3] > 0.85 * 2.5, "{factors:?}");
    }

    /// A deep bar leaves the motor file's circuit whole at zero slip, where a file's circuit
    /// is measured: the rotor's impedance `R₁‖(R₂ + jω·L₂)` tends to R_R with a reactance
    /// `ω·`[`DeepBar::zero_slip_leakage_h`] (to 1e-6 at ω = 1e-3 rad/s), and the machine's
    /// main leakage is the file's L_σ less it — the sum the file's. A bar whose second cage
    /// alone leaks more than the file's L_σ (the shipped 300 W motor with a 1.8× bar cornering
    /// at 8 Hz: L₂·(0.8/1.8)² = 0.18 H against 0.096 H) is refused.
    #[test]
    fn a_deep_bars_circuit_is_the_files_at_zero_slip() {
        let m = MotorParams::new(3.7, 2.1, 0.245, 0.224, 0.224, 2, 0.015, 0.0).unwrap();
        let bar = DeepBar { high_slip_resistance_factor: 2.5, corner_slip_hz: 15.0 };
        let (r1, r2, l2) = bar.circuit(2.1).unwrap();
        let w = 1e-3;
        // Z = R₁·(R₂ + jωL₂)/(R₁ + R₂ + jωL₂), on (re, im) pairs.
        let (nr, ni) = (r1 * r2, r1 * w * l2);
        let (dr, di) = (r1 + r2, w * l2);
        let d2 = dr * dr + di * di;
        let (zr, zi) = ((nr * dr + ni * di) / d2, (ni * dr - nr * di) / d2);
        let extra = bar.zero_slip_leakage_h(2.1).unwrap();
        assert!((zr / 2.1 - 1.0).abs() < 1e-6 && (zi / w / extra - 1.0).abs() < 1e-6, "{zr} {}", zi / w);
        let machine = Machine::saturated(&m, &Saturation { form: Form::InverseGamma, curve: law() })
            .and_then(|x| x.with_deep_bar(&bar))
            .unwrap();
        let Some(sat) = machine.saturation else { panic!("saturating") };
        assert!((sat.leak_h + extra - (0.245 - 0.224)).abs() < 1e-15, "{}", sat.leak_h);
        // A second bar replaces the first, leakage included.
        let again = machine.with_deep_bar(&bar).unwrap();
        let Some(sat2) = again.saturation else { panic!("saturating") };
        assert!((sat2.leak_h - sat.leak_h).abs() < 1e-15);
        let shipped = Machine::new(&MotorParams::delorenzo_dl10115a1().unwrap());
        let low = DeepBar { high_slip_resistance_factor: 1.8, corner_slip_hz: 8.0 };
        assert_eq!(shipped.with_deep_bar(&low).map(|_| ()), Err(SaturationError::DeepBarLeakage));
    }

    /// A linear T model takes a deep bar and iron loss in its inverse-Γ equivalent (module
    /// docs): a 0.3 s direct-on-line start of the shipped T motor with both agrees with the
    /// same machine written in the inverse-Γ form by hand, to 1e-9 of the current's peak —
    /// its state's rotor flux the T model's, L_r/L_m times the branch's. Its fastest rate
    /// with the bar is an eigenvalue of the standstill 3×3 and the largest. A Γ machine or
    /// a bar that is not one is refused.
    #[test]
    fn a_linear_t_machine_takes_a_deep_bar_in_its_inverse_gamma_equivalent() {
        let t = MotorParams::delorenzo_dl10115a1().unwrap();
        let g = t.lm_h() / t.lr_h();
        let lm = g * t.lm_h();
        let inv_gamma = MotorParams::new(
            t.rs_ohm(),
            t.rr_ohm() * g * g,
            t.ls_h(),
            lm,
            lm,
            t.pole_pairs(),
            t.j_kgm2(),
            t.b_nms(),
        )
        .unwrap();
        let psi: [f64; 2] = [1.0, 2.0];
        let curve = MagnetizingCurve::points(&psi, &psi.map(|p| p / lm)).unwrap();
        let bar = DeepBar { high_slip_resistance_factor: 1.8, corner_slip_hz: 60.0 };
        let by_hand = Machine::saturated(&inv_gamma, &Saturation { form: Form::InverseGamma, curve })
            .and_then(|m| m.with_iron_loss(900.0))
            .and_then(|m| m.with_deep_bar(&bar))
            .unwrap();
        let from_t = Machine::new(&t).with_iron_loss(900.0).and_then(|m| m.with_deep_bar(&bar)).unwrap();
        assert!(!from_t.is_saturating() && by_hand.is_saturating());
        let (h, src) = (2e-5, sine(180.0, 2.0 * core::f64::consts::PI * 50.0));
        let (mut a, mut b) = (MachineState::default(), MachineState::default());
        let (mut worst, mut peak, mut flux) = (0.0f64, 0.0f64, 0.0f64);
        for n in 0..15_000 {
            let time = n as f64 * h;
            a = from_t.rk4_source(&a, time, h, &src, 0.5);
            b = by_hand.rk4_source(&b, time, h, &src, 0.5);
            peak = peak.max(b.i_alpha_a.abs());
            worst =
                worst.max((a.i_alpha_a - b.i_alpha_a).abs()).max((a.i_cage_beta_a - b.i_cage_beta_a).abs());
            flux = flux.max((a.psi_alpha_wb * g - b.psi_alpha_wb).abs());
        }
        assert!(worst < 1e-9 * peak && flux < 1e-9, "{worst} A of {peak} A, flux {flux}");
        assert!(b.omega_m_rad_s > 20.0, "the start ran: {b:?}");
        // The fastest rate: a root of det(λ − R·C), and no root above it.
        let Some(sat) = from_t.saturation else { panic!("carried in the inverse-Γ form") };
        let rate = from_t.fastest_rate_per_s();
        let (r1, r2, l2) = bar.circuit(t.rr_ohm() * g * g).unwrap();
        let l_sigma = t.ls_h() - lm - bar.zero_slip_leakage_h(t.rr_ohm() * g * g).unwrap();
        let (a_, g_, c_) = (1.0 / l_sigma, 1.0 / lm, 1.0 / l2);
        let rc = [
            [t.rs_ohm() * a_, -t.rs_ohm() * a_, 0.0],
            [-r1 * a_, r1 * (g_ + a_ + c_), -r1 * c_],
            [0.0, -r2 * c_, r2 * c_],
        ];
        let det = |l: f64| {
            let m = |i: usize, j: usize| if i == j { l - rc[i][j] } else { -rc[i][j] };
            m(0, 0) * (m(1, 1) * m(2, 2) - m(1, 2) * m(2, 1))
                - m(0, 1) * (m(1, 0) * m(2, 2) - m(1, 2) * m(2, 0))
                + m(0, 2) * (m(1, 0) * m(2, 1) - m(1, 1) * m(2, 0))
        };
        assert!(det(rate).abs() < 1e-9 * rate.powi(3), "{rate}: {}", det(rate));
        assert!(det(1.001 * rate) > 0.0 && rate > sat.rs_ohm / (t.ls_h() - lm));
        let gamma =
            Machine::saturated(&gamma_2kw(), &Saturation { form: Form::Gamma, curve: law() }).unwrap();
        assert_eq!(gamma.with_deep_bar(&bar).map(|_| ()), Err(SaturationError::DeepBar));
        for (k, f) in [(1.0, 8.0), (0.5, 8.0), (f64::NAN, 8.0), (2.0, 0.0), (2.0, f64::INFINITY)] {
            let bad = DeepBar { high_slip_resistance_factor: k, corner_slip_hz: f };
            assert_eq!(from_t.with_deep_bar(&bad).map(|_| ()), Err(SaturationError::DeepBar), "{k} {f}");
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
