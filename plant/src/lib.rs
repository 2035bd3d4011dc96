//! Induction machine in the stationary frame, seed 002 eqs. (1)–(2).
//!
//! States `x = [i_sα, i_sβ, ψ_rα, ψ_rβ, ω_m, θ_m]`. The electrical speed inside the
//! matrix `A` of eq. (1) is `ω_r = p·ω_m` (p pole pairs; the paper's `P/2`):
//!
//! ```text
//! di_sα/dt = a·i_sα + b·R_r/L_r·ψ_rα + b·ω_r·ψ_rβ + v_sα/(σL_s)
//! di_sβ/dt = a·i_sβ − b·ω_r·ψ_rα + b·R_r/L_r·ψ_rβ + v_sβ/(σL_s)
//! dψ_rα/dt = L_m·R_r/L_r·i_sα − R_r/L_r·ψ_rα − ω_r·ψ_rβ
//! dψ_rβ/dt = L_m·R_r/L_r·i_sβ + ω_r·ψ_rα − R_r/L_r·ψ_rβ
//! T_e      = (3/2)·p·L_m/L_r·(ψ_rα·i_sβ − ψ_rβ·i_sα)
//! J·dω_m/dt = T_e − B·ω_m − T_L,   dθ_m/dt = ω_m
//! ```
//! with `a = −(L_r²R_s + L_m²R_r)/(σL_sL_r²)`, `b = L_m/(σL_sL_r)`. Integrated with classical
//! RK4 at a fixed step (voltage and load held constant over the step).

#![forbid(unsafe_code)]
// Fixed-size state arrays are indexed inside `array::from_fn` with indices bounded by the
// array length.
#![allow(clippy::indexing_slicing)]
#![cfg_attr(test, allow(clippy::unwrap_used, clippy::expect_used, clippy::panic))]

use controller_core::magnetics::Saturation;
use controller_core::motor::MotorParams;
use core::cell::Cell;

pub mod saturated;
pub mod thermal;
pub use saturated::DeepBar;
use saturated::{Saturated, SaturationError};

/// What a simulated machine has beyond its equivalent circuit's form, each optional: iron
/// loss and a deep-bar rotor ([`crate::saturated`]). A linear machine takes them in its
/// inverse-Γ equivalent, a saturating one in the inverse-Γ form only.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Extras {
    /// An iron-loss resistance across the magnetizing branch, Ω.
    pub iron_loss_ohm: Option<f64>,
    /// A deep-bar rotor.
    pub deep_bar: Option<DeepBar>,
}

/// Plant state.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MachineState {
    /// Stator current α, A.
    pub i_alpha_a: f64,
    /// Stator current β, A.
    pub i_beta_a: f64,
    /// Rotor flux α, Wb.
    pub psi_alpha_wb: f64,
    /// Rotor flux β, Wb.
    pub psi_beta_wb: f64,
    /// Mechanical speed, rad/s.
    pub omega_m_rad_s: f64,
    /// Mechanical angle, rad (not wrapped).
    pub theta_m_rad: f64,
    /// The second rotor cage's current α, A: a deep-bar rotor's inner cage
    /// ([`Machine::with_deep_bar`]); 0 on a machine with one cage.
    pub i_cage_alpha_a: f64,
    /// The second rotor cage's current β, A.
    pub i_cage_beta_a: f64,
}

impl MachineState {
    /// Every component finite (a diverged run is not).
    pub fn is_finite(&self) -> bool {
        (self.i_alpha_a
            + self.i_beta_a
            + self.psi_alpha_wb
            + self.psi_beta_wb
            + self.omega_m_rad_s
            + self.theta_m_rad
            + self.i_cage_alpha_a
            + self.i_cage_beta_a)
            .is_finite()
    }
}

/// Two lanes (α, β) of a space vector, combined lane by lane: eq. (1) is the same
/// equation on both lanes up to the rotation terms, so the compiler keeps each pair in one
/// SIMD register.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Pair(f64, f64);

impl Pair {
    #[inline(always)]
    fn splat(x: f64) -> Self {
        Pair(x, x)
    }
    /// (β, α).
    #[inline(always)]
    fn swap(self) -> Self {
        Pair(self.1, self.0)
    }
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Pair(self.0 + o.0, self.1 + o.1)
    }
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        Pair(self.0 - o.0, self.1 - o.1)
    }
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        Pair(self.0 * o.0, self.1 * o.1)
    }
}

/// The RK4 state: stator current and rotor flux vectors, mechanical speed (θ_m enters no
/// derivative). ω_m is carried on both lanes: it multiplies both lanes of the rotation
/// terms, and the torque term below comes out on both lanes too, so no stage moves a value
/// between lanes.
#[derive(Clone, Copy, Debug)]
struct Coupled {
    i: Pair,
    psi: Pair,
    w: Pair,
}

/// Coefficients of eq. (1)–(2) multiplied by a step length `s` (h/2 or h for the RK4
/// stages), so that a stage yields its increment `s·f(x)` without a further product.
#[derive(Clone, Copy, Debug)]
struct Scaled {
    /// s·(a, a).
    a: Pair,
    /// s·b·R_r/L_r on both lanes.
    b_rr_lr: Pair,
    /// s·L_m·R_r/L_r on both lanes.
    lm_rr_lr: Pair,
    /// s·R_r/L_r on both lanes.
    rr_lr: Pair,
    /// s·(b·p, −b·p): the rotation term of di/dt is ω_m·(b·p·ψ_β, −b·p·ψ_α).
    b_p_rot: Pair,
    /// s·(−p, p): the rotation term of dψ/dt is ω_m·(−p·ψ_β, p·ψ_α).
    p_rot: Pair,
    /// s·(3/2)·p·L_m/L_r / J·(1, −1): applied to (ψ_α·i_β − ψ_β·i_α, ψ_β·i_α − ψ_α·i_β).
    torque_per_j: Pair,
    /// s·B/J on both lanes.
    b_per_j: Pair,
    /// s/(σL_s): stator voltage → current increment.
    inv_sigma_ls: Pair,
    /// s/J on both lanes: load torque → speed increment.
    inv_j: Pair,
}

impl Scaled {
    fn new(m: &Machine, s: f64) -> Self {
        Self {
            a: Pair::splat(s * m.a),
            b_rr_lr: Pair::splat(s * m.b * m.rr_lr),
            lm_rr_lr: Pair::splat(s * m.lm_rr_lr),
            rr_lr: Pair::splat(s * m.rr_lr),
            b_p_rot: Pair(s * m.b * m.p, -s * m.b * m.p),
            p_rot: Pair(-s * m.p, s * m.p),
            torque_per_j: Pair(s * m.torque_factor * m.inv_j, -s * m.torque_factor * m.inv_j),
            b_per_j: Pair::splat(s * m.b_nms * m.inv_j),
            inv_sigma_ls: Pair::splat(s * m.inv_sigma_ls),
            inv_j: Pair::splat(s * m.inv_j),
        }
    }

    /// One RK4 stage at `x` from the step's start `x0`: the increment `k = s·f(x)` of
    /// eq. (1)–(2) and the next stage's point `x0 + k`, with the stator voltage `v` and the
    /// load (plus friction) torque `t_l` held. Lane by lane, before the factor s:
    /// `di/dt = a·i + b·R_r/L_r·ψ + b·p·ω_m·(ψ_β, −ψ_α) + v/(σL_s)`,
    /// `dψ/dt = L_m·R_r/L_r·i − R_r/L_r·ψ + p·ω_m·(−ψ_β, ψ_α)`,
    /// `dω_m/dt = (3/2)·p·L_m/L_r·(ψ_α·i_β − ψ_β·i_α)/J − B·ω_m/J − T_L/J`.
    /// Branch-free, and grouped so that the terms waiting on the longest products (the
    /// rotation and torque terms, which need ω_m or both vectors) are added last: the
    /// four stages run in sequence, and their chain of dependent operations is the
    /// simulator's latency.
    #[inline(always)]
    fn stage(&self, x0: &Coupled, x: Coupled, v: Pair, t_l: Pair) -> (Coupled, Coupled) {
        let (i, psi, w) = (x.i, x.psi, x.w);
        let psi_rot = psi.swap();
        let i_early = self.a.mul(i).add(self.inv_sigma_ls.mul(v));
        let i_late = self.b_rr_lr.mul(psi).add(w.mul(self.b_p_rot).mul(psi_rot));
        let psi_early = self.lm_rr_lr.mul(i).sub(self.rr_lr.mul(psi));
        let psi_late = w.mul(self.p_rot).mul(psi_rot);
        let cross = psi.mul(i.swap()); // (ψ_α·i_β, ψ_β·i_α)
        let w_late = self.torque_per_j.mul(cross.sub(cross.swap()));
        let w_early = self.b_per_j.mul(w).add(self.inv_j.mul(t_l));
        let k = Coupled { i: i_early.add(i_late), psi: psi_early.add(psi_late), w: w_late.sub(w_early) };
        let next = Coupled {
            i: x0.i.add(i_early).add(i_late),
            psi: x0.psi.add(psi_early).add(psi_late),
            w: x0.w.sub(w_early).add(w_late),
        };
        (k, next)
    }
}

/// Classical RK4 of eq. (1)–(2) at a fixed step, with the coefficients pre-scaled for its
/// half and full stages ([`Machine::rk4_stepper`]). Made once per run: the closed-loop
/// simulator takes one step per PWM period.
#[derive(Clone, Debug)]
pub struct Rk4 {
    machine: Machine,
    half: Scaled,
    full: Scaled,
    h_s: f64,
    /// A saturating machine's last step: its result's stator current and rotor flux, and
    /// the stator flux it integrated to. A step from exactly that state takes the flux
    /// instead of recovering it by Newton ([`Machine::saturated`]); any other state (the
    /// diodes' projection of the current, a new run) recovers it.
    last_stator_flux: Cell<Option<([f64; 4], [f64; 2])>>,
}

impl Rk4 {
    /// One step with stator voltage `v_ab_v` and load torque held (an inverter output is
    /// constant over a PWM period in the average model).
    #[inline]
    pub fn step(&self, x: &MachineState, v_ab_v: [f64; 2], load_nm: f64) -> MachineState {
        self.step_source(x, 0.0, |_| v_ab_v, load_nm)
    }

    /// One step from time `t_s` with a time-varying stator voltage `v(t)` (an ideal source,
    /// evaluated at the RK4 nodes t, t + h/2, t + h).
    ///
    /// In increment form: `K₁ = (h/2)·f(x₀)`, `K₂ = (h/2)·f(x₀ + K₁)`, `K₃ = h·f(x₀ + K₂)`,
    /// `K₄ = (h/2)·f(x₀ + K₃)`, `x₁ = x₀ + (K₁ + 2K₂ + K₃ + K₄)/3` — the classical
    /// `x₀ + h/6·(f₁ + 2f₂ + 2f₃ + f₄)` with the step folded into the coefficients.
    #[inline]
    pub fn step_source(
        &self,
        x: &MachineState,
        t_s: f64,
        v: impl Fn(f64) -> [f64; 2],
        load_nm: f64,
    ) -> MachineState {
        let v_at = |t: f64| {
            let [va, vb] = v(t);
            Pair(va, vb)
        };
        let h_s = self.h_s;
        let (v0, v_mid, v1) = (v_at(t_s), v_at(t_s + h_s / 2.0), v_at(t_s + h_s));
        self.begin(x, v0, v_mid, v1, load_nm).finish(self)
    }

    /// The fan's torque for this step, from its start ([`Machine::with_fan`]), at most the
    /// torque that stops the rotor within the step, J·|ω_m|/h: held over the step, a stiffer
    /// fan's would reverse the rotor, and the stages' speeds (and with them the back-EMF)
    /// would grow without bound — a 1e6 N·m-at-1 rad/s fan in a scenario file ended "the
    /// run diverged". A fan a step can integrate (2k·|ω|·h/J ≪ 1) is far below the cap.
    #[inline]
    fn fan_torque_nm(&self, x: &MachineState) -> f64 {
        let t = self.machine.fan_torque_nm(x);
        if self.machine.inv_j > 0.0 {
            let stop_nm = x.omega_m_rad_s.abs() / (self.machine.inv_j * self.h_s);
            // (Not `clamp`: a state gone non-finite reaches the run's own check, not a panic.)
            t.max(-stop_nm).min(stop_nm)
        } else {
            t
        }
    }

    /// The first half of [`Rk4::step`] (stages 1 and 2); [`Rk4Midway::finish`] does the
    /// rest. `step` is `begin_step` then `finish`, so the results are identical. The split
    /// lets a caller put independent work between the halves (the simulator: the drive's
    /// step), which the processor then runs beside the plant's chain of dependent
    /// operations. Splitting after stage 1 measured the same, after stage 3 no gain.
    #[inline]
    pub fn begin_step(&self, x: &MachineState, v_ab_v: [f64; 2], load_nm: f64) -> Rk4Midway {
        let v = Pair(v_ab_v[0], v_ab_v[1]);
        self.begin(x, v, v, v, load_nm)
    }

    #[inline(always)]
    fn begin(&self, x: &MachineState, v0: Pair, v_mid: Pair, v1: Pair, load_nm: f64) -> Rk4Midway {
        let x0 = Coupled {
            i: Pair(x.i_alpha_a, x.i_beta_a),
            psi: Pair(x.psi_alpha_wb, x.psi_beta_wb),
            w: Pair::splat(x.omega_m_rad_s),
        };
        let passive = self.machine.coulomb_torque_nm(x, load_nm) + self.fan_torque_nm(x);
        if let Some(sat) = &self.machine.saturation {
            let m = &self.machine;
            let v = [[v0.0, v0.1], [v_mid.0, v_mid.1], [v1.0, v1.1]];
            let key = |x: &MachineState| [x.i_alpha_a, x.i_beta_a, x.psi_alpha_wb, x.psi_beta_wb];
            let psi_s = match self.last_stator_flux.get() {
                Some((k, psi_s)) if k == key(x) => psi_s,
                _ => sat.stator_flux(x),
            };
            let (mut x1, psi_s1) = sat.step(m.inv_j, m.b_nms, x, psi_s, v, load_nm + passive, self.h_s);
            self.last_stator_flux.set(Some((key(&x1), psi_s1)));
            m.stop_a_reversing_passive_load(x.omega_m_rad_s, &mut x1);
            return Rk4Midway(Midway::Whole(x1));
        }
        let t_l = Pair::splat(load_nm + passive);
        let (k1, x2) = self.half.stage(&x0, x0, v0, t_l);
        let (k2, x3) = self.half.stage(&x0, x2, v_mid, t_l);
        let sum2 = |a: Pair, b: Pair| a.add(b.add(b));
        Rk4Midway(Midway::Split(Split {
            theta0: x.theta_m_rad,
            x0,
            x3,
            t_l,
            v_mid,
            v1,
            k12: Coupled { i: sum2(k1.i, k2.i), psi: sum2(k1.psi, k2.psi), w: sum2(k1.w, k2.w) },
            w2: x2.w.0,
        }))
    }
}

/// An RK4 step after its first two stages ([`Rk4::begin_step`]), or a saturating
/// machine's step done whole (its stages are not split).
#[derive(Clone, Copy, Debug)]
pub struct Rk4Midway(Midway);

#[derive(Clone, Copy, Debug)]
enum Midway {
    /// The linear machine's step after stages 1 and 2.
    Split(Split),
    /// A saturating machine's step, done.
    Whole(MachineState),
}

/// The linear step's values after stages 1 and 2.
#[derive(Clone, Copy, Debug)]
struct Split {
    /// θ_m at the step's start (ω_m, i and ψ are in `x0`).
    theta0: f64,
    x0: Coupled,
    x3: Coupled,
    t_l: Pair,
    v_mid: Pair,
    v1: Pair,
    /// K₁ + 2K₂.
    k12: Coupled,
    /// ω_m at stage 2.
    w2: f64,
}

impl Rk4Midway {
    /// Stages 3 and 4 and the step's result (`rk4` is the stepper that began it).
    #[inline]
    pub fn finish(&self, rk4: &Rk4) -> MachineState {
        match &self.0 {
            Midway::Split(split) => split.finish(rk4),
            Midway::Whole(x1) => *x1,
        }
    }
}

impl Split {
    #[inline(always)]
    fn finish(&self, rk4: &Rk4) -> MachineState {
        let (x0, x3, t_l) = (&self.x0, self.x3, self.t_l);
        let (k3, x4) = rk4.full.stage(x0, x3, self.v_mid, t_l);
        // What stage 4 does not change is summed while it runs.
        let third = Pair::splat(1.0 / 3.0);
        let i_part = x0.i.add(third.mul(self.k12.i.add(k3.i)));
        let psi_part = x0.psi.add(third.mul(self.k12.psi.add(k3.psi)));
        let w_part = x0.w.add(third.mul(self.k12.w.add(k3.w)));
        let (k4, _) = rk4.half.stage(x0, x4, self.v1, t_l);
        let i = i_part.add(third.mul(k4.i));
        let psi = psi_part.add(third.mul(k4.psi));
        let w = w_part.add(third.mul(k4.w)).0;
        // dθ_m/dt = ω_m: its stages are the stage speeds.
        let theta = self.theta0 + rk4.h_s / 6.0 * (x0.w.0 + 2.0 * (self.w2 + x3.w.0) + x4.w.0);
        let mut x1 = MachineState {
            i_alpha_a: i.0,
            i_beta_a: i.1,
            psi_alpha_wb: psi.0,
            psi_beta_wb: psi.1,
            omega_m_rad_s: w,
            theta_m_rad: theta,
            i_cage_alpha_a: 0.0,
            i_cage_beta_a: 0.0,
        };
        rk4.machine.stop_a_reversing_passive_load(x0.w.0, &mut x1);
        x1
    }
}

/// The machine model with its precomputed coefficients.
#[derive(Clone, Copy, Debug)]
pub struct Machine {
    a: f64,
    b: f64,
    rr_lr: f64,
    lm_rr_lr: f64,
    inv_sigma_ls: f64,
    torque_factor: f64,
    p: f64,
    inv_j: f64,
    b_nms: f64,
    /// Coulomb (dry) friction torque magnitude, N·m.
    coulomb_nm: f64,
    /// A saturating magnetizing branch ([`Machine::saturated`]); the coefficients above are
    /// then the unsaturated machine's, for [`Machine::electrical_matrices`].
    saturation: Option<Saturated>,
    /// A fan's (or pump's) torque per speed squared, N·m·s²/rad²: k·ω_m·|ω_m| against the
    /// motion.
    fan_nm_s2: f64,
    /// The parameters it was made with (a linear machine takes iron loss or a deep bar in
    /// their inverse-Γ equivalent).
    motor: MotorParams,
}

impl Machine {
    /// Coefficients of eq. (1) for `m`.
    pub fn new(m: &MotorParams) -> Self {
        let sigma_ls = m.sigma() * m.ls_h();
        let (lr, lm) = (m.lr_h(), m.lm_h());
        Self {
            a: -(lr * lr * m.rs_ohm() + lm * lm * m.rr_ohm()) / (sigma_ls * lr * lr),
            b: lm / (sigma_ls * lr),
            rr_lr: m.rr_ohm() / lr,
            lm_rr_lr: lm * m.rr_ohm() / lr,
            inv_sigma_ls: 1.0 / sigma_ls,
            torque_factor: m.torque_factor(),
            p: f64::from(m.pole_pairs()),
            inv_j: 1.0 / m.j_kgm2(),
            b_nms: m.b_nms(),
            coulomb_nm: 0.0,
            fan_nm_s2: 0.0,
            saturation: None,
            motor: *m,
        }
    }

    /// The machine `m` with the saturating magnetizing branch `sat` ([`crate::saturated`]): `m`
    /// is the form written as a T model (Γ: L_s = L_m; inverse-Γ: L_r = L_m), its L_m
    /// replaced by the curve.
    pub fn saturated(m: &MotorParams, sat: &Saturation) -> Result<Self, SaturationError> {
        Ok(Self { saturation: Some(Saturated::new(m, sat)?), ..Self::new(m) })
    }

    /// Whether the magnetizing branch saturates (has a machine's curve; a linear machine
    /// carried in its inverse-Γ equivalent for its iron loss or deep bar does not).
    pub fn is_saturating(&self) -> bool {
        self.saturation.as_ref().is_some_and(Saturated::is_curved)
    }

    /// The branch a loss or a deep bar is added to: a saturating machine's, or a linear
    /// one's in its inverse-Γ equivalent ([`crate::saturated`]).
    fn branch(&self) -> Result<Saturated, SaturationError> {
        match &self.saturation {
            Some(s) => Ok(*s),
            None => Saturated::linear_equivalent(&self.motor),
        }
    }

    /// The same machine with an iron-loss resistance `r_fe_ohm` across its magnetizing branch
    /// ([`crate::saturated`]): a saturating machine in the inverse-Γ form, or a linear
    /// machine in its inverse-Γ equivalent; an error otherwise.
    pub fn with_iron_loss(&self, r_fe_ohm: f64) -> Result<Self, SaturationError> {
        Ok(Self { saturation: Some(self.branch()?.with_iron_loss(r_fe_ohm)?), ..*self })
    }

    /// The iron-loss resistance across the magnetizing branch, Ω (`None`: none).
    pub fn iron_loss_ohm(&self) -> Option<f64> {
        self.saturation.as_ref().and_then(Saturated::iron_loss_ohm)
    }

    /// The same machine with a deep-bar rotor ([`crate::saturated`]): a second cage that
    /// keeps the running rotor resistance and raises it `bar.high_slip_resistance_factor`
    /// times at high slip. A saturating machine in the inverse-Γ form, or a linear machine
    /// in its inverse-Γ equivalent; an error otherwise.
    pub fn with_deep_bar(&self, bar: &DeepBar) -> Result<Self, SaturationError> {
        Ok(Self { saturation: Some(self.branch()?.with_deep_bar(bar)?), ..*self })
    }

    /// The same machine with `extras` ([`Machine::with_iron_loss`], [`Machine::with_deep_bar`]);
    /// none leaves it as it is.
    pub fn with_extras(&self, extras: &Extras) -> Result<Self, SaturationError> {
        let m = match extras.iron_loss_ohm {
            Some(r) => self.with_iron_loss(r)?,
            None => *self,
        };
        match &extras.deep_bar {
            Some(bar) => m.with_deep_bar(bar),
            None => Ok(m),
        }
    }

    /// The deep bar (`None`: a rotor with one cage).
    pub fn deep_bar(&self) -> Option<DeepBar> {
        self.saturation.as_ref().and_then(Saturated::deep_bar)
    }

    /// A passive load (dry friction, a fan: held over the step from its start) would have
    /// reversed the rotor within the step that began at `w0_rad_s`: it stops instead.
    #[inline(always)]
    fn stop_a_reversing_passive_load(&self, w0_rad_s: f64, x1: &mut MachineState) {
        let passive = self.coulomb_nm > 0.0 || self.fan_nm_s2 > 0.0;
        if passive && w0_rad_s * x1.omega_m_rad_s < 0.0 {
            x1.omega_m_rad_s = 0.0;
        }
    }

    /// The linear electrical subsystem of eq. (1) at electrical rotor speed `omega_r`:
    /// A(ω_r) (row-major, states i_sα, i_sβ, ψ_rα, ψ_rβ) and the input gain 1/(σL_s)
    /// (B = diag(1/(σL_s), 1/(σL_s)) on the current rows). The same coefficients drive
    /// [`Machine::rk4`], so the analysis in `design` and the simulation share one eq. (1).
    /// A saturating machine's are those of its T model at the unsaturated L_m.
    pub fn electrical_matrices(&self, omega_r: f64) -> ([[f64; 4]; 4], f64) {
        let (k1, k2) = (self.b * self.rr_lr, self.b * omega_r);
        (
            [
                [self.a, 0.0, k1, k2],
                [0.0, self.a, -k2, k1],
                [self.lm_rr_lr, 0.0, -self.rr_lr, -omega_r],
                [0.0, self.lm_rr_lr, omega_r, -self.rr_lr],
            ],
            self.inv_sigma_ls,
        )
    }

    /// The fastest electrical mode's rate, 1/s: the magnitude of the most negative eigenvalue
    /// of [`Machine::electrical_matrices`] at standstill (there one axis decouples into a
    /// real 2×2 — trace `a − R_r/L_r`, determinant `−a·R_r/L_r − b·(R_r/L_r)·L_m·R_r/L_r`;
    /// turning adds ±jω_r, which RK4's region covers far beyond any speed run). An explicit
    /// RK4 step `h` is stable for `rate·h` up to ≈ 2.785 on the negative real axis.
    /// A saturating machine's: that of the linear machine with the branch's incremental
    /// inductance deep in saturation (`MagnetizingCurve::deep_flux_wb`), where it is
    /// fastest.
    pub fn fastest_rate_per_s(&self) -> f64 {
        if let Some(s) = &self.saturation {
            return s.fastest_rate_per_s();
        }
        let (m, _) = self.electrical_matrices(0.0);
        let [[a11, _, a13, _], _, [a31, _, a33, _], _] = m;
        let half_trace = 0.5 * (a11 + a33);
        let det = a11 * a33 - a13 * a31;
        -half_trace + (half_trace * half_trace - det).max(0.0).sqrt()
    }

    /// The stator voltage at which the stator current would neither flow nor change: the
    /// back-EMF of the rotor flux, `(L_m/L_r)·dψ_r/dt` with `i_s = 0`, i.e.
    /// `−(L_m/L_r)·((R_r/L_r)·ψ_r − ω_r·J·ψ_r)` (eq. (1)'s current rows solved for `v` at
    /// `i = 0`, `di/dt = 0`; J the 90° rotation). What an open stator's terminals show, αβ, V.
    pub fn open_circuit_voltage(&self, x: &MachineState) -> [f64; 2] {
        if let Some(s) = &self.saturation {
            return s.open_circuit_voltage(x);
        }
        let k = self.b / self.inv_sigma_ls; // L_m/L_r
        let w = self.p * x.omega_m_rad_s;
        let (pa, pb) = (x.psi_alpha_wb, x.psi_beta_wb);
        [-k * (self.rr_lr * pa + w * pb), -k * (self.rr_lr * pb - w * pa)]
    }

    /// Electromagnetic torque, N·m.
    pub fn torque_nm(&self, x: &MachineState) -> f64 {
        if let Some(s) = &self.saturation {
            return s.torque_nm(x);
        }
        self.torque_factor * (x.psi_alpha_wb * x.i_beta_a - x.psi_beta_wb * x.i_alpha_a)
    }

    /// The same machine with its speed held (infinite inertia, no friction): for
    /// locked-rotor and fixed-slip tests.
    pub fn speed_locked(&self) -> Self {
        Self { inv_j: 0.0, b_nms: 0.0, coulomb_nm: 0.0, fan_nm_s2: 0.0, ..*self }
    }

    /// The same mechanics (inertia, friction, a locked rotor) with the electrical
    /// parameters of `m` (a parameter change mid-run: the rotor heating, the magnetizing
    /// inductance saturating); the state carries over as it is (currents and rotor flux).
    /// A saturating branch keeps its curve, its inductances scaled as `m`'s L_m changed;
    /// `m` must keep the form (an error otherwise).
    pub fn with_electrical(&self, m: &MotorParams) -> Result<Self, SaturationError> {
        let saturation = match &self.saturation {
            Some(s) => Some(s.with_electrical(m)?),
            None => None,
        };
        let e = Self { saturation, ..Self::new(m) };
        Ok(Self {
            inv_j: self.inv_j,
            b_nms: self.b_nms,
            coulomb_nm: self.coulomb_nm,
            fan_nm_s2: self.fan_nm_s2,
            ..e
        })
    }

    /// The same machine with Coulomb friction of magnitude `t_c_nm`: −T_c·sign(ω_m) while
    /// turning; at rest it holds up to T_c of driving torque (stiction = Coulomb level).
    /// The friction torque is fixed at each RK4 step's start, and a step in which ω_m would
    /// change sign ends at rest, so the fixed-step integration cannot chatter around zero.
    pub fn with_coulomb_friction(&self, t_c_nm: f64) -> Self {
        Self { coulomb_nm: t_c_nm.abs(), ..*self }
    }

    /// The same machine with an extra viscous load `k_nm_s_rad` (an eddy-current brake,
    /// T_L = k·ω_m).
    pub fn with_eddy_brake(&self, k_nm_s_rad: f64) -> Self {
        Self { b_nms: self.b_nms + k_nm_s_rad, ..*self }
    }

    /// The same machine driving a fan or a centrifugal pump: T_L = k·ω_m·|ω_m| against the
    /// motion, `k_nm_s2` N·m·s²/rad² (the torque at a speed ω over ω²), added to any fan
    /// already coupled. Evaluated at each RK4 step's start, as the Coulomb friction is (a
    /// step h changes it by a fraction 2k·|ω|·h/J), and like it, a step in which it would
    /// reverse the rotor ends at rest: a fan too stiff for the step stops the rotor instead
    /// of driving it backwards without bound.
    pub fn with_fan(&self, k_nm_s2: f64) -> Self {
        Self { fan_nm_s2: self.fan_nm_s2 + k_nm_s2.abs(), ..*self }
    }

    /// The same machine with `j_kgm2` more inertia coupled to its shaft (a flywheel, a
    /// conveyor's drum: a load that stores energy and drives no torque); a held rotor stays
    /// held.
    pub fn with_added_inertia(&self, j_kgm2: f64) -> Self {
        if self.inv_j == 0.0 {
            return *self;
        }
        Self { inv_j: 1.0 / (1.0 / self.inv_j + j_kgm2.abs()), ..*self }
    }

    /// The fan's torque for a step starting at `x`, N·m (against the motion).
    #[inline]
    fn fan_torque_nm(&self, x: &MachineState) -> f64 {
        let w = x.omega_m_rad_s;
        self.fan_nm_s2 * w * w.abs()
    }

    /// The Coulomb friction's magnitude, N·m.
    pub fn coulomb_nm(&self) -> f64 {
        self.coulomb_nm
    }

    /// Coulomb friction for a step starting at `x`: kinetic (±T_c against the motion) while
    /// turning; at rest, static friction balancing the driving torque at the step's start,
    /// up to T_c.
    fn coulomb_torque_nm(&self, x: &MachineState, load_nm: f64) -> f64 {
        let w = x.omega_m_rad_s;
        if self.coulomb_nm == 0.0 {
            0.0
        } else if w > 0.0 {
            self.coulomb_nm
        } else if w < 0.0 {
            -self.coulomb_nm
        } else {
            let drive_nm = self.torque_nm(x) - load_nm;
            drive_nm.max(-self.coulomb_nm).min(self.coulomb_nm)
        }
    }

    /// RK4 at the fixed step `h_s` (coefficients scaled once; see [`Rk4`]).
    pub fn rk4_stepper(&self, h_s: f64) -> Rk4 {
        Rk4 {
            machine: *self,
            half: Scaled::new(self, h_s / 2.0),
            full: Scaled::new(self, h_s),
            h_s,
            last_stator_flux: Cell::new(None),
        }
    }

    /// One RK4 step of `h_s` seconds with stator voltage `v_ab_v` and load torque held
    /// ([`Rk4::step`]; a run at a fixed step makes the [`Rk4`] once instead).
    pub fn rk4(&self, x: &MachineState, v_ab_v: [f64; 2], load_nm: f64, h_s: f64) -> MachineState {
        self.rk4_stepper(h_s).step(x, v_ab_v, load_nm)
    }

    /// One RK4 step from time `t_s` with a time-varying stator voltage `v(t)`
    /// ([`Rk4::step_source`]).
    pub fn rk4_source(
        &self,
        x: &MachineState,
        t_s: f64,
        h_s: f64,
        v: impl Fn(f64) -> [f64; 2],
        load_nm: f64,
    ) -> MachineState {
        self.rk4_stepper(h_s).step_source(x, t_s, v, load_nm)
    }
}

#[cfg(test)]
mod tests {

    /// The fastest electrical rate is an eigenvalue of the standstill matrix (the full 4×4's
    /// characteristic polynomial vanishes there) and the largest in magnitude; the DeLorenzo
    /// motor's is 395 1/s (rate·50 µs = 0.02, far inside RK4's region), R_s = 10 kΩ's
    /// 1.05·10⁵ 1/s (5.2: outside).
    #[test]
    fn fastest_rate_is_the_standstill_matrixs_largest_eigenvalue() {
        let char_poly = |m: &Machine, l: f64| {
            let (a, _) = m.electrical_matrices(0.0);
            // One decoupled axis: (a11 − λ)(a33 − λ) − a13·a31.
            let [[a11, _, a13, _], _, [a31, _, a33, _], _] = a;
            ((a11 - l) * (a33 - l) - a13 * a31, a11 + a33, a11 * a33 - a13 * a31)
        };
        for (rs, expect) in [(16.2, (390.0, 400.0)), (1e4, (1.0e5, 1.1e5))] {
            let m = Machine::new(&MotorParams::new(rs, 23.2, 1.44, 1.5, 1.42, 1, 0.005, 0.0).unwrap());
            let rate = m.fastest_rate_per_s();
            let (at_root, trace, det) = char_poly(&m, -rate);
            assert!(at_root.abs() <= 1e-9 * det.abs().max(rate * rate), "{at_root} at −{rate}");
            // The other root, trace − λ, is the slower one.
            assert!((trace + rate).abs() <= rate, "{trace}");
            assert!((expect.0..expect.1).contains(&rate), "{rate}");
        }
    }

    use super::*;

    /// The open-circuit voltage holds a zero stator current at zero: one 1 µs RK4 step from
    /// i = 0 with it applied leaves a current ω_r·h/2 = 1.5e-4 of what 0 V gives (the EMF
    /// turns by ω_r·h within the step while the applied voltage is held; asserted with a
    /// factor 1.5 of slack), and its magnitude is
    /// (L_m/L_r)·|ψ_r|·√((R_r/L_r)² + ω_r²).
    #[test]
    fn open_circuit_voltage_keeps_the_current_at_zero() {
        let mp = MotorParams::new(16.2, 23.2, 1.44, 1.5, 1.42, 2, 0.005, 0.0).unwrap();
        let m = Machine::new(&mp);
        let x =
            MachineState { psi_alpha_wb: 0.3, psi_beta_wb: -0.4, omega_m_rad_s: 150.0, ..Default::default() };
        let v = m.open_circuit_voltage(&x);
        let mag = |y: &MachineState| y.i_alpha_a.hypot(y.i_beta_a);
        let held = mag(&m.rk4(&x, v, 0.0, 1e-6));
        let shorted = mag(&m.rk4(&x, [0.0, 0.0], 0.0, 1e-6));
        assert!(held < 1.5 * 300.0 * 1e-6 / 2.0 * shorted, "{held} vs {shorted}");
        let expected = (1.42 / 1.5) * 0.5 * ((23.2f64 / 1.5).powi(2) + 300f64.powi(2)).sqrt();
        assert!((v[0].hypot(v[1]) / expected - 1.0).abs() < 1e-12);
    }

    /// A fan k = 1e-5 N·m·s²/rad², J = 0.005, no friction: coast-down from 300 rad/s with no
    /// torque follows J·dω/dt = −k·ω², ω(t) = ω₀/(1 + k·ω₀·t/J) — 150 rad/s at 1.667 s —
    /// within 1e-4 relative (the fan torque is held over each 50 µs step); backwards the
    /// same, mirrored. An added inertia of J halves the acceleration a load gives.
    #[test]
    fn a_fan_coasts_down_as_its_square_law_says_and_a_coupling_adds_inertia() {
        let mp = MotorParams::new(16.2, 23.2, 1.44, 1.5, 1.42, 1, 0.005, 0.0).unwrap();
        let (k, j, h) = (1e-5, 0.005, 5e-5);
        let m = Machine::new(&mp).with_fan(k);
        for w0 in [300.0, -300.0] {
            let mut x = MachineState { omega_m_rad_s: w0, ..Default::default() };
            for n in 1..=40_000 {
                x = m.rk4(&x, [0.0, 0.0], 0.0, h);
                if n % 10_000 == 0 {
                    let t = n as f64 * h;
                    let w = w0 / (1.0 + k * w0.abs() * t / j);
                    assert!(
                        (x.omega_m_rad_s / w - 1.0).abs() < 1e-4,
                        "{w0}: {} at {t} s, {w}",
                        x.omega_m_rad_s
                    );
                }
            }
        }
        let coupled = Machine::new(&mp).with_added_inertia(0.005);
        let accel = |m: &Machine| m.rk4(&MachineState::default(), [0.0, 0.0], -0.1, h).omega_m_rad_s / h;
        let (alone, doubled) = (accel(&Machine::new(&mp)), accel(&coupled));
        assert!((alone / doubled - 2.0).abs() < 1e-9, "{alone} {doubled}");
        assert_eq!(Machine::new(&mp).speed_locked().with_added_inertia(1.0).inv_j, 0.0);
    }

    /// A fan far stiffer than a step can integrate (1e6 N·m at 1 rad/s on J = 0.005: held
    /// over a 50 µs step its torque would reverse the rotor and grow without bound — found
    /// trying a scenario file, the run "diverged"): the rotor stops within the step instead
    /// (to rounding), never reversing, and stays at rest, finite.
    #[test]
    fn a_fan_too_stiff_for_the_step_stops_the_rotor_instead_of_reversing_it() {
        let mp = MotorParams::new(16.2, 23.2, 1.44, 1.5, 1.42, 1, 0.005, 0.0).unwrap();
        let m = Machine::new(&mp).with_fan(1e6);
        for w0 in [100.0, -100.0] {
            let mut x = MachineState { omega_m_rad_s: w0, ..Default::default() };
            for _ in 0..100 {
                x = m.rk4(&x, [0.0, 0.0], 0.0, 5e-5);
                assert!(
                    x.omega_m_rad_s.is_finite() && x.omega_m_rad_s * w0 >= 0.0,
                    "{w0}: {}",
                    x.omega_m_rad_s
                );
            }
            assert!(x.omega_m_rad_s.abs() < 1e-9, "{w0}: {}", x.omega_m_rad_s);
        }
    }

    /// Coulomb friction T_c = 0.1 N·m, no viscous friction, J = 0.005: coast-down from
    /// 10 rad/s with no torque stops at t = J·ω₀/T_c = 0.5 s and stays at rest (no chatter);
    /// at rest, a load of 0.08 N·m (< T_c) does not move it, 0.15 N·m accelerates it at
    /// (0.15 − 0.1)/J = 10 rad/s².
    #[test]
    fn coulomb_friction_coast_down_stiction_and_breakaway() {
        let mp = MotorParams::new(16.2, 23.2, 1.44, 1.5, 1.42, 1, 0.005, 0.0).unwrap();
        let m = Machine::new(&mp).with_coulomb_friction(0.1);
        let h = 5e-5;
        let mut x = MachineState { omega_m_rad_s: 10.0, ..Default::default() };
        let mut t_stop = None;
        for k in 0..20_000 {
            x = m.rk4(&x, [0.0, 0.0], 0.0, h);
            if t_stop.is_none() && x.omega_m_rad_s == 0.0 {
                t_stop = Some((k + 1) as f64 * h);
            }
            if t_stop.is_some() {
                assert_eq!(x.omega_m_rad_s, 0.0, "chatter at step {k}");
            }
        }
        let t_stop = t_stop.expect("stops");
        assert!((t_stop - 0.5).abs() <= h, "stopped at {t_stop} s");
        // Stiction.
        let rest = MachineState::default();
        let mut y = rest;
        for _ in 0..1000 {
            y = m.rk4(&y, [0.0, 0.0], -0.08, h);
        }
        assert_eq!(y.omega_m_rad_s, 0.0);
        // Breakaway: load −0.15 N·m drives it (the sign convention: T_L opposes T_e).
        let mut z = rest;
        for _ in 0..2000 {
            z = m.rk4(&z, [0.0, 0.0], -0.15, h);
        }
        let a = z.omega_m_rad_s / (2000.0 * h);
        assert!((a - 10.0).abs() < 1e-6, "acceleration {a}");
    }

    /// The textbook RK4 `x + h/6·(f₁ + 2f₂ + 2f₃ + f₄)` of eq. (1)–(2), with the derivative
    /// formed from [`Machine::electrical_matrices`] and the torque: a reference for the
    /// increment form of [`Rk4`] (no Coulomb friction).
    fn textbook_rk4(m: &Machine, x: &MachineState, v: [f64; 2], load_nm: f64, h: f64) -> [f64; 6] {
        let f = |y: [f64; 6]| {
            let (a, b) = m.electrical_matrices(m.p * y[4]);
            let mut d = [0.0; 6];
            for (r, row) in a.iter().enumerate() {
                d[r] = (0..4).map(|c| row[c] * y[c]).sum::<f64>() + if r < 2 { b * v[r] } else { 0.0 };
            }
            let te = m.torque_factor * (y[2] * y[1] - y[3] * y[0]);
            d[4] = (te - m.b_nms * y[4] - load_nm) * m.inv_j;
            d[5] = y[4];
            d
        };
        let add = |y: [f64; 6], k: [f64; 6], s: f64| std::array::from_fn(|n| y[n] + s * k[n]);
        let y0 = [x.i_alpha_a, x.i_beta_a, x.psi_alpha_wb, x.psi_beta_wb, x.omega_m_rad_s, x.theta_m_rad];
        let k1 = f(y0);
        let k2 = f(add(y0, k1, h / 2.0));
        let k3 = f(add(y0, k2, h / 2.0));
        let k4 = f(add(y0, k3, h));
        std::array::from_fn(|n| y0[n] + h / 6.0 * (k1[n] + 2.0 * k2[n] + 2.0 * k3[n] + k4[n]))
    }

    /// The step in increment form agrees with the textbook RK4 up to rounding (1e-12
    /// relative to each state's size; one step at h = 200 µs moves the state by up to
    /// ≈ 1e-1 of it, so a wrong coefficient or stage weight shows at ≥ 1e-3), and the split
    /// step (begun before the drive's step in the simulator) is the step bit for bit, with
    /// and without friction, at a state with every term of eq. (1)–(2) non-zero.
    #[test]
    fn step_is_textbook_rk4_and_split_step_equals_step() {
        let m = Machine::new(&delorenzo());
        let x = MachineState {
            i_alpha_a: 1.3,
            i_beta_a: -0.7,
            psi_alpha_wb: 0.4,
            psi_beta_wb: 0.9,
            omega_m_rad_s: 120.0,
            theta_m_rad: 2.0,
            ..Default::default()
        };
        let (v, load, h) = ([150.0, -80.0], 0.6, 2e-4);
        let got = m.rk4_stepper(h).step(&x, v, load);
        let want = textbook_rk4(&m, &x, v, load, h);
        let got_arr = [
            got.i_alpha_a,
            got.i_beta_a,
            got.psi_alpha_wb,
            got.psi_beta_wb,
            got.omega_m_rad_s,
            got.theta_m_rad,
        ];
        for (n, (g, w)) in got_arr.iter().zip(want).enumerate() {
            assert!((g - w).abs() <= 1e-12 * w.abs().max(1.0), "state {n}: {g} vs {w}");
        }
        for machine in [m, m.with_coulomb_friction(0.05)] {
            let rk4 = machine.rk4_stepper(5e-5);
            assert_eq!(rk4.begin_step(&x, v, load).finish(&rk4), rk4.step(&x, v, load));
            assert_ne!(rk4.step(&x, v, load), x);
        }
    }

    fn delorenzo() -> MotorParams {
        MotorParams::delorenzo_dl10115a1().unwrap()
    }

    /// Locked rotor, constant voltage: the currents settle at v/R_s and the flux at L_m·i.
    /// Slowest mode: root of σL_sL_r s² + (L_sR_r + L_rR_s)s + R_sR_r, τ ≈ 0.15 s; 10 s of
    /// simulation leaves e^-66 of the transient.
    #[test]
    fn dc_steady_state_at_standstill() {
        let m = Machine::new(&delorenzo());
        let mut x = MachineState::default();
        let w = m.speed_locked();
        for _ in 0..100_000 {
            x = w.rk4(&x, [16.2, 0.0], 0.0, 1e-4);
        }
        assert!((x.i_alpha_a - 1.0).abs() < 1e-9);
        assert!((x.psi_alpha_wb - 1.42).abs() < 1e-9);
        assert_eq!(x.omega_m_rad_s, 0.0);
    }

    /// Steady-state torque of the classical per-phase T-equivalent circuit (a reference
    /// derived independently of the state-space model): `L_ls = L_s − L_m`, `L_lr = L_r − L_m`,
    /// `Z_r = R_r/s + jω_e L_lr`, `I_r = I_s·jω_e L_m/(Z_r + jω_e L_m)`,
    /// `T = 3·p·|I_r,rms|²·R_r/(s·ω_e)`.
    fn equivalent_circuit_torque(m: &MotorParams, v_peak: f64, f_hz: f64, slip: f64) -> f64 {
        let we = 2.0 * std::f64::consts::PI * f_hz;
        let (lls, llr) = (m.ls_h() - m.lm_h(), m.lr_h() - m.lm_h());
        // complex arithmetic on (re, im) pairs
        let mul = |a: (f64, f64), b: (f64, f64)| (a.0 * b.0 - a.1 * b.1, a.0 * b.1 + a.1 * b.0);
        let div = |a: (f64, f64), b: (f64, f64)| {
            let d = b.0 * b.0 + b.1 * b.1;
            ((a.0 * b.0 + a.1 * b.1) / d, (a.1 * b.0 - a.0 * b.1) / d)
        };
        let zm = (0.0, we * m.lm_h());
        let zr = (m.rr_ohm() / slip, we * llr);
        let zp = div(mul(zm, zr), (zm.0 + zr.0, zm.1 + zr.1));
        let z = (m.rs_ohm() + zp.0, we * lls + zp.1);
        let is = div((v_peak / std::f64::consts::SQRT_2, 0.0), z);
        let ir = div(mul(is, zm), (zm.0 + zr.0, zm.1 + zr.1));
        let ir2 = ir.0 * ir.0 + ir.1 * ir.1;
        3.0 * f64::from(m.pole_pairs()) * ir2 * m.rr_ohm() / (slip * we)
    }

    /// Torque–slip curve: the simulated machine held at ω_m = (1 − s)·ω_e/p and fed by the
    /// balanced source settles to the equivalent-circuit torque within 1e-5 relative. The
    /// slowest electrical mode (τ ≈ 0.15 s at standstill) leaves e^-16 after 2.4 s.
    #[test]
    fn torque_slip_curve_matches_equivalent_circuit() {
        let mp = delorenzo();
        let m = Machine::new(&mp).speed_locked();
        let (v, f) = (180.0, 50.0);
        let we = 2.0 * std::f64::consts::PI * f;
        for slip in [-0.1, 0.02, 0.05, 0.1, 0.3, 0.6, 1.0] {
            let mut x = MachineState {
                omega_m_rad_s: (1.0 - slip) * we / f64::from(mp.pole_pairs()),
                ..Default::default()
            };
            let h = 1e-5;
            let n = 240_000;
            let source = |t: f64| [v * (we * t).cos(), v * (we * t).sin()];
            for k in 0..n {
                x = m.rk4_source(&x, k as f64 * h, h, source, 0.0);
            }
            let t_sim = m.torque_nm(&x);
            let t_ec = equivalent_circuit_torque(&mp, v, f, slip);
            eprintln!("slip {slip:5.2}: simulated {t_sim:.6} N·m, equivalent circuit {t_ec:.6} N·m");
            assert!((t_sim - t_ec).abs() < 1e-5 * t_ec.abs(), "slip {slip}: {t_sim} vs {t_ec}");
        }
    }

    /// Energy balance over a free acceleration: electrical input power = copper losses +
    /// d/dt(magnetic energy) + mechanical power. Checked as integrals (trapezoid), RK4 at
    /// 10 µs; the residual bounds the integration error.
    #[test]
    fn power_balance_during_a_direct_on_line_start() {
        let mp = delorenzo();
        let m = Machine::new(&mp);
        let h = 1e-5;
        let (amp, we) = (180.0, 2.0 * std::f64::consts::PI * 50.0);
        let mut x = MachineState::default();
        let (mut e_in, mut e_cu, mut e_mech) = (0.0, 0.0, 0.0);
        let power = |x: &MachineState, t: f64| {
            let v = [amp * (we * t).cos(), amp * (we * t).sin()];
            // Amplitude-invariant frame: p = 3/2·(v·i).
            let p_in = 1.5 * (v[0] * x.i_alpha_a + v[1] * x.i_beta_a);
            // Rotor current from ψ = L_r i_r + L_m i_s.
            let ir = [
                (x.psi_alpha_wb - mp.lm_h() * x.i_alpha_a) / mp.lr_h(),
                (x.psi_beta_wb - mp.lm_h() * x.i_beta_a) / mp.lr_h(),
            ];
            let p_cu = 1.5
                * (mp.rs_ohm() * (x.i_alpha_a.powi(2) + x.i_beta_a.powi(2))
                    + mp.rr_ohm() * (ir[0].powi(2) + ir[1].powi(2)));
            let p_mech = m.torque_nm(x) * x.omega_m_rad_s;
            (v, p_in, p_cu, p_mech)
        };
        let stored = |x: &MachineState| {
            let ir = [
                (x.psi_alpha_wb - mp.lm_h() * x.i_alpha_a) / mp.lr_h(),
                (x.psi_beta_wb - mp.lm_h() * x.i_beta_a) / mp.lr_h(),
            ];
            let is = [x.i_alpha_a, x.i_beta_a];
            let mut w = 0.0;
            for k in 0..2 {
                w += 0.75
                    * (mp.ls_h() * is[k] * is[k]
                        + mp.lr_h() * ir[k] * ir[k]
                        + 2.0 * mp.lm_h() * is[k] * ir[k]);
            }
            w
        };
        let steps = 50_000;
        for n in 0..steps {
            let t = n as f64 * h;
            let (v, p0, c0, m0) = power(&x, t);
            x = m.rk4(&x, v, 0.0, h);
            // voltage held over the step: evaluate end power with the same v
            let (_, p1, c1, m1) = {
                let (_, _, c, mm) = power(&x, t + h);
                let p_in = 1.5 * (v[0] * x.i_alpha_a + v[1] * x.i_beta_a);
                ((), p_in, c, mm)
            };
            e_in += 0.5 * h * (p0 + p1);
            e_cu += 0.5 * h * (c0 + c1);
            e_mech += 0.5 * h * (m0 + m1);
        }
        let residual = e_in - e_cu - e_mech - stored(&x);
        assert!(e_in > 1.0);
        assert!(residual.abs() / e_in < 1e-3, "residual {residual} of {e_in} J");
    }
}
