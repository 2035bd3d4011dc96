//! Indirect field-oriented control (seed 000 eqs. (6)–(9), seed 002 Fig. 12).
//!
//! With the d axis on the rotor flux (`ψ_qr = 0`, `ψ_dr = ψ_r`, eq. (6)):
//!
//! * flux reference → `i_ds* = ψ_r*/L_m` (eq. (9), steady state of eq. (8); the drive divides
//!   by the inductance scale in use, [`IfocConfig::set_inductance_scale`], and lowers it while
//!   Running and a slow rotor's flux falls, [`IfocConfig::falling_flux_current`]);
//! * rotor-flux model, eq. (8) `ψ_r = L_m/(1 + s·T_r)·i_ds`, discretised exactly (ZOH) — on
//!   the estimated `L̂_m` and `T̂_r` ([`IfocConfig::set_inductance_scale`],
//!   [`IfocConfig::set_rotor_resistance_scale`]; the motor's when not estimated), driven
//!   by the **measured** d-axis current (Park of the measured currents at the field angle):
//!   `ψ̂[k+1] = ψ̂[k] + (1 − e^{−T/T_r})·(L_m·i_ds − ψ̂[k])` — so the estimate cannot run ahead
//!   of a motor that is not there, and slip and torque stay consistent while the flux
//!   reference changes (field weakening);
//! * torque → `i_qs* = T*/((3/2)·p·(L_m/L_r)·ψ̂)` (from eq. (5) with `ψ_qr = 0`);
//! * slip, eq. (7): `ω_sl = L_m·R_r/(L_r·ψ̂)·i_qs*`;
//! * field angle `θ_e = p·θ_m + θ_sl`: the slip angle `θ_sl[k+1] = wrap(θ_sl[k] + ω_sl·T)`
//!   is integrated here; the rotor angle comes from the encoder's position at each read
//!   ([`IfocConfig::anchor`]) and is extrapolated with `p·ω_m·T` per step between reads, so
//!   `θ_e[k+1] = θ_e[k] + (p·ω_m + ω_sl)·T` between reads, in `[-π, π)`;
//! * current references returned in αβ (inverse Park at θ_e) for the stationary-frame loops.
//!
//! **Two rates** (the split of ST's MCSDK into a high- and a medium-frequency task): what
//! changes only with the slow step's inputs — the torque command, the encoder's speed, the
//! trim, and through 1/ψ̂ the flux model — is worked out once per slow period
//! ([`IfocConfig::plan`]: i_qs*, ω_sl, the field vector afresh from θ_e with [`SinCos::new`],
//! and the rotation `(cos δ, sin δ)` of its angle step δ = (p·ω_m + ω_sl)·T). Each fast step
//! ([`IfocConfig::step`]) only turns the references with the field vector, turns the field by
//! that rotation, and adds the measured current's field-frame components to a sum. At the
//! next slow step ([`IfocConfig::close_period`]) the flux model takes the period's mean
//! measured d-axis current in one step of its exact discretisation over the period's n fast
//! steps — `ψ̂ ← ψ̂ + (1 − e^{−n·T/T_r})·(L_m·ī_ds − ψ̂)`, equal to n per-step updates with a
//! constant current — and the slip angle advances by `n·ω_sl·T`. Within a slow period the
//! field angle was already a straight-line extrapolation (ω_m is read once per period and ω_sl
//! changed only through ψ̂, by ≤ n·T/T_r = 0.8 % of its distance to its target per period in
//! the shipped drive); the rotated field vector stays within 1e-6 of sin/cos θ_e
//! (`field_tracks_the_angle`), recomputed at every plan.
//!
//! **Guard while the flux builds up:** ψ̂ is floored at `psi_min_wb` in the torque and slip
//! divisions, so neither can blow up at start; `i_qs*` is further limited so that the current
//! reference vector stays within `i_max_a`.

use crate::frames::{AlphaBeta, Dq, SinCos, wrap_angle};
use crate::motor::MotorParams;
use crate::num::{Scalar, finite_positive, max_f32, sqrt_f32};
use num_complex::Complex32;

/// Torque-producing command from the speed loop.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TorqueCommand {
    /// Electromagnetic torque reference, N·m (converted with the flux estimate).
    TorqueNm(f32),
    /// q-axis current reference, A (e.g. seed 000 PI2, whose output is i_qs*).
    IqA(f32),
}

/// Why an IFOC configuration was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum IfocError {
    /// Sample period not finite and positive.
    SamplePeriod,
    /// Flux floor not finite and positive.
    FluxFloor,
    /// Current limit not finite and positive.
    CurrentLimit,
}

impl core::fmt::Display for IfocError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::SamplePeriod => "the sample period is not finite and positive",
            Self::FluxFloor => "the flux floor is not finite and positive",
            Self::CurrentLimit => "the current limit is not finite and positive",
        })
    }
}

crate::raw::raw_struct! {
    /// IFOC configuration (derived from the motor at construction).
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct IfocConfig {
        inv_lm: f32,
        lm_h: f32,
        slip_gain: f32,
        inv_torque_factor: f32,
        pole_pairs: f32,
        /// `T/T_r`, the flux model's rate per fast step at the motor's rotor resistance.
        flux_rate: f32,
        psi_min_wb: f32,
        i_max_a: f32,
        ts_s: f32,
    }
}

/// The plan of the fast steps up to the next slow step ([`IfocConfig::plan`]): what the fast
/// steps turn into current references.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FieldPlan {
    /// The field's turn per fast step, δ = (p·ω_m + ω_sl)·T, and its sin/cos.
    step_rad: f32,
    rotation: SinCos,
    /// The intended current references (they set the slip), those the loops track (the
    /// trim added), A, field frame; the slip speed, electrical rad/s.
    i_ref_dq: Dq,
    i_track_dq: Dq,
    omega_sl_rad_s: f32,
}

/// The fast steps' part of the field orientation: the plan in force, the field angle of its
/// first step and the field turned since, and the measured current summed for the flux
/// model. The fast context owns one ([`IfocConfig::step_field`]); the slow context's
/// [`IfocState`] holds another, in which it makes the next plan ([`FieldSteps::adopt`]
/// hands that over).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FieldSteps {
    /// Field (rotor-flux) angle θ_e, rad, in `[-π, π)`, from which the next fast step's is
    /// θ_e + n·δ, n the fast steps counted in the sums: in the slow context's, that of the
    /// plan's first fast step (set by [`IfocConfig::anchor`]); in the fast context's,
    /// rebased where the count starts again ([`FieldSteps::take_sums`],
    /// [`FieldSteps::adopt`]).
    theta_e_rad: f32,
    /// sin and cos of the present field angle: afresh at each plan, turned by the plan's
    /// rotation each step.
    field: SinCos,
    plan: FieldPlan,
    /// Σ of the measured current in the field frame over the fast steps since the last
    /// [`IfocConfig::close_period`], A, and their count.
    i_sum_dq: Dq,
    steps: u16,
}

impl FieldSteps {
    /// Field (rotor-flux) angle θ_e for the next fast step, rad, in `[-π, π)`: the plan's
    /// first step's advanced by its step δ per fast step since (the fast step does not carry
    /// the angle — it turns the field vector; made here, on demand).
    pub fn theta_e_rad(&self) -> f32 {
        wrap_angle(self.theta_e_rad + f32::from(self.steps) * self.plan.step_rad)
    }

    /// The field's turn per fast step, δ = (p·ω_m + ω_sl)·T: sin δ and cos δ.
    pub fn rotation(&self) -> SinCos {
        self.plan.rotation
    }

    /// θ_e of the last fast step (before any: of the next one), rad, in `[-π, π)`.
    pub fn last_theta_e_rad(&self) -> f32 {
        wrap_angle(self.theta_e_rad + f32::from(self.steps.saturating_sub(1)) * self.plan.step_rad)
    }

    /// The current references the next fast step returns (the plan's trimmed references at
    /// the present field angle), A, stationary frame: what [`IfocConfig::step`] computes.
    pub fn i_ref_ab(&self) -> AlphaBeta {
        self.plan.i_track_dq.inverse_park(self.field)
    }

    /// The intended current references of the plan at the present field angle (without the
    /// trim: what the plan asks of the machine), A, stationary frame.
    pub fn i_intended_ab(&self) -> AlphaBeta {
        self.plan.i_ref_dq.inverse_park(self.field)
    }

    /// The sums of the measured current since the last take, field frame, A, and their
    /// count; cleared (the slow step's inputs, latched by the fast context), the angle
    /// rebased on the next step's.
    pub fn take_sums(&mut self) -> (Dq, u16) {
        let sums = (self.i_sum_dq, self.steps);
        self.theta_e_rad = self.theta_e_rad();
        (self.i_sum_dq, self.steps) = (Dq::default(), 0);
        sums
    }

    /// Take the plan, the field angle of its first step — the next fast step — and its field
    /// from `made` (the slow context's), keeping this one's sums (the angle rebased on
    /// their count).
    pub fn adopt(&mut self, made: &FieldSteps) {
        (self.field, self.plan) = (made.field, made.plan);
        self.theta_e_rad = self.rebased(made.theta_e_rad);
    }

    /// Take the field angle of `made` alone as the next fast step's (an anchor without a
    /// plan: the pre-charge's).
    pub fn adopt_angle(&mut self, made: &FieldSteps) {
        self.theta_e_rad = self.rebased(made.theta_e_rad);
    }

    /// The angle from which `next_rad` is the next fast step's, this plan's step δ per fast
    /// step counted in the sums.
    fn rebased(&self, next_rad: f32) -> f32 {
        wrap_angle(next_rad - f32::from(self.steps) * self.plan.step_rad)
    }
}

/// IFOC state, made by [`IfocConfig::state`]: the flux model and the slip angle on the
/// estimates in use, and the fast steps' part ([`FieldSteps`]) — the plan made last.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IfocState {
    f: FieldSteps,
    /// Slip angle θ_sl = ∫ω_sl dt, rad, in `[-π, π)`: θ_e less the rotor's electrical angle
    /// (at the last [`IfocConfig::close_period`]).
    theta_sl_rad: f32,
    /// The slip of the plan in force at the last [`IfocConfig::close_period`], rad/s: the
    /// fast steps ran it up to the adoption of the next one, the plan's delay into the
    /// period the next close closes.
    omega_sl_before_rad_s: f32,
    /// Rotor-flux model estimate ψ̂_r, Wb.
    psi_r_wb: f32,
    /// The slip gain `L_m·R̂_r/L_r` and the flux model's rate per fast step `T·R̂_r/L̂_r` of
    /// the rotor resistance in use, R̂_r = the motor's × [`IfocState::rotor_resistance_scale`]
    /// (set by [`IfocConfig::set_rotor_resistance_scale`]).
    slip_gain: f32,
    flux_rate: f32,
    rr_scale: f32,
    /// The magnetizing inductance in use, `L̂_m = L_m·`[`IfocState::inductance_scale`] (the
    /// flux model's `ψ̂_r → L̂_m·i_ds`; set by [`IfocConfig::set_inductance_scale`]), H.
    lm_h: f32,
    l_scale: f32,
}

impl IfocState {
    /// The flux model starts again from an unmagnetized rotor (a flying start: the flux it
    /// built on a field that stood still is not the turning rotor's).
    pub fn forget_flux(&mut self) {
        self.psi_r_wb = 0.0;
    }

    /// Field (rotor-flux) angle θ_e for the next fast step ([`FieldSteps::theta_e_rad`]).
    pub fn theta_e_rad(&self) -> f32 {
        self.f.theta_e_rad()
    }

    /// θ_e of the last fast step ([`FieldSteps::last_theta_e_rad`]).
    pub fn last_theta_e_rad(&self) -> f32 {
        self.f.last_theta_e_rad()
    }

    /// The fast steps' part: the plan made last.
    pub fn field_steps(&self) -> &FieldSteps {
        &self.f
    }

    /// The fast steps' sums `(Σ i_dq, n)` (those of another [`FieldSteps`], taken by
    /// [`FieldSteps::take_sums`]) added to this state's, for [`IfocConfig::close_period`].
    pub fn add_sums(&mut self, (sum, n): (Dq, u16)) {
        let s = &mut self.f;
        s.i_sum_dq = Dq { d: s.i_sum_dq.d + sum.d, q: s.i_sum_dq.q + sum.q };
        s.steps = s.steps.saturating_add(n);
    }

    /// Rotor-flux model estimate ψ̂_r, Wb.
    pub fn psi_r_wb(&self) -> f32 {
        self.psi_r_wb
    }

    /// Slip angle θ_sl, rad, in `[-π, π)`.
    pub fn theta_sl_rad(&self) -> f32 {
        self.theta_sl_rad
    }

    /// The rotor resistance in use over the motor's, R̂_r/R_r.
    pub fn rotor_resistance_scale(&self) -> f32 {
        self.rr_scale
    }

    /// The inductances in use over the motor's, L̂/L (L_s, L_r, L_m alike).
    pub fn inductance_scale(&self) -> f32 {
        self.l_scale
    }

    /// The steady-state rotor flux of d-axis current `i_d_a` on the inductance in use,
    /// `L̂_m·i_d`, Wb.
    pub fn flux_of(&self, i_d_a: f32) -> f32 {
        self.lm_h * i_d_a
    }

    /// The slip speed of the present plan, electrical rad/s.
    pub fn omega_sl_rad_s(&self) -> f32 {
        self.f.plan.omega_sl_rad_s
    }

    /// The current references the next fast step returns ([`FieldSteps::i_ref_ab`]).
    pub fn i_ref_ab(&self) -> AlphaBeta {
        self.f.i_ref_ab()
    }

    /// The intended current references of the present plan at the present field angle
    /// ([`FieldSteps::i_intended_ab`]).
    pub fn i_intended_ab(&self) -> AlphaBeta {
        self.f.i_intended_ab()
    }

    /// The intended current references of the present plan (without the trim), A.
    pub fn i_ref_dq(&self) -> Dq {
        self.f.plan.i_ref_dq
    }

    /// The present plan's field turn per fast step, rad, and its sin/cos.
    pub fn plan_step(&self) -> (f32, SinCos) {
        (self.f.plan.step_rad, self.f.plan.rotation)
    }

    /// The tracked references of the present plan made `gain·i_ref + trim` (field frame, the
    /// complex `gain` on d + jq): what the loops must be asked for their current to be the
    /// intended `i_ref` where they do not follow a turning reference exactly
    /// (`DriveConfig::reference_gain`). The trim (tracked − intended) is kept.
    pub fn precompensate(&mut self, gain: Complex32) {
        let p = &mut self.f.plan;
        let (r, trim) =
            (p.i_ref_dq, Dq { d: p.i_track_dq.d - p.i_ref_dq.d, q: p.i_track_dq.q - p.i_ref_dq.q });
        p.i_track_dq =
            Dq { d: gain.re * r.d - gain.im * r.q + trim.d, q: gain.re * r.q + gain.im * r.d + trim.q };
    }
}

/// `1 − e^{−y}` for `y ≥ 0` in f32 arithmetic, without cancellation: the Taylor series to
/// degree 6 for `y ≤ ⅛` (relative truncation ≤ y⁶/5040 = 7.6e-10 at ⅛; the shipped drive's
/// `y` per slow period is 7.7e-3), and above ⅛ by halving `y` until it is and doubling back
/// with `1 − e^{−2y} = g·(2 − g)` (no subtraction of near-equal numbers; test
/// `one_minus_exp_neg_is_accurate`: within 1e-6 of f64 from 1e-9 to 100). Non-finite or
/// negative `y`: 0 (the flux model holds).
fn one_minus_exp_neg(y: f32) -> f32 {
    if !finite_positive(y) {
        return 0.0;
    }
    let (mut y, mut halvings) = (y, 0u8);
    while y > 0.125 && halvings < 64 {
        y *= 0.5;
        halvings += 1;
    }
    let mut g = y
        * (1.0
            - y * (1.0 / 2.0)
                * (1.0
                    - y * (1.0 / 3.0)
                        * (1.0 - y * (1.0 / 4.0) * (1.0 - y * (1.0 / 5.0) * (1.0 - y * (1.0 / 6.0))))));
    for _ in 0..halvings {
        g *= 2.0 - g;
    }
    g
}

/// What a rotor-flux reference ψ_r* asks of the current references: `i_ds* = ψ_r*/L_m`
/// (eq. (9)) limited to `±i_max`, and the room left for `i_qs*`, `√(i_max² − i_ds*²)`.
/// Made by [`IfocConfig::flux_command`] when the flux reference is set, not in the fast
/// step (the square root is a software routine of ≈ 150 instructions on the Cortex-M).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FluxCommand {
    i_d_a: f32,
    i_q_max_a: f32,
}

impl FluxCommand {
    /// d-axis current reference, A.
    pub fn i_d_a(&self) -> f32 {
        self.i_d_a
    }

    /// Limit of |i_qs*|, A.
    pub fn i_q_max_a(&self) -> f32 {
        self.i_q_max_a
    }
}

/// Result of one fast IFOC step ([`IfocConfig::step`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct IfocOutput {
    /// Current references in the field frame, A.
    pub i_ref_dq: Dq,
    /// Current references in the stationary frame, A.
    pub i_ref_ab: AlphaBeta,
    /// sin and cos of the field angle of this step ([`IfocState::last_theta_e_rad`] after it;
    /// for Park and inverse Park in the synchronous frame).
    pub field: SinCos,
    /// The measured current in the field frame (the Park transform at `field`), A.
    pub i_meas_dq: Dq,
    /// Slip speed, electrical rad/s.
    pub omega_sl_rad_s: f32,
}

impl IfocConfig {
    /// Build for `motor`, step `ts_s`, flux floor `psi_min_wb` and current limit `i_max_a`.
    pub fn new(motor: &MotorParams, ts_s: f64, psi_min_wb: f64, i_max_a: f64) -> Result<Self, IfocError> {
        if !(ts_s.is_finite() && ts_s > 0.0) {
            return Err(IfocError::SamplePeriod);
        }
        if !(psi_min_wb.is_finite() && psi_min_wb > 0.0) {
            return Err(IfocError::FluxFloor);
        }
        if !(i_max_a.is_finite() && i_max_a > 0.0) {
            return Err(IfocError::CurrentLimit);
        }
        let f = f32::from_f64;
        Ok(Self {
            inv_lm: f(1.0 / motor.lm_h()),
            lm_h: f(motor.lm_h()),
            slip_gain: f(motor.lm_h() * motor.rr_ohm() / motor.lr_h()),
            inv_torque_factor: f(1.0 / motor.torque_factor()),
            pole_pairs: f32::from(motor.pole_pairs()),
            flux_rate: f(ts_s / motor.tr_s()),
            psi_min_wb: f(psi_min_wb),
            i_max_a: f(i_max_a),
            ts_s: f(ts_s),
        })
    }

    /// The current references that flux reference `psi_ref_wb` (Wb) asks for. A non-finite
    /// reference gives a zero command (no flux, no torque).
    pub fn flux_command(&self, psi_ref_wb: f32) -> FluxCommand {
        self.d_current_command(psi_ref_wb * self.inv_lm)
    }

    /// The command for d-axis current reference `i_d_a` (A), limited to `±i_max`, with the
    /// room it leaves for `i_qs*`. A non-finite reference gives a zero command.
    pub fn d_current_command(&self, i_d_a: f32) -> FluxCommand {
        let i_d_a = i_d_a.limit(-self.i_max_a, self.i_max_a);
        if !i_d_a.is_finite() {
            return FluxCommand::default();
        }
        let i_q_max_a = sqrt_f32(max_f32(self.i_max_a * self.i_max_a - i_d_a * i_d_a, 0.0));
        FluxCommand { i_d_a, i_q_max_a }
    }

    /// The d-axis current reference that brings the rotor flux down to the steady flux of
    /// `i_d_a` (A, ≥ 0) with time constant τ_f = T_s/`fall_rate` (`fall_rate`: per fast step)
    /// where the rotor's own T̂_r is slower — the flux model ([`IfocConfig::close_period`],
    /// `dψ_r/dt = (L̂_m·i_ds − ψ_r)/T̂_r`) solved for the `i_ds` that gives
    /// `dψ_r/dt = (L̂_m·i_d − ψ̂_r)/τ_f`:
    ///
    /// ```text
    /// i_ds* = i_ψ + (T̂_r/τ_f)·(i_d − i_ψ),   i_ψ = ψ̂_r/L̂_m,   T̂_r/τ_f at least 1
    /// ```
    ///
    /// limited to `[floor_a, i_d]`: down to no current (`floor_a` 0: the flux then falls with
    /// T̂_r, the fastest without reversing the current) or reversed (`floor_a` < 0: a speed
    /// rising through field weakening asks the flux to fall faster than the rotor lets it
    /// with no current, `FLUX_LAG_FRACTION`), within the current limit, and never above
    /// `i_d` — a flux forced
    /// upwards asks for voltage that a machine in field weakening does not have (forced both
    /// ways, the 3 300 V drive's loops sat at the modulator's limit at top speed, the flux
    /// model below its target on the current they could not drive). A flux at or below its
    /// target gets `i_d` itself. Both speeds are the model's: with `fall_rate` ≥
    /// `flux_rate` nothing is forced.
    pub fn falling_flux_current(&self, s: &IfocState, i_d_a: f32, fall_rate: f32, floor_a: f32) -> f32 {
        let i_psi = s.psi_r_wb / s.lm_h;
        let k = max_f32(fall_rate / s.flux_rate, 1.0);
        (i_psi + k * (i_d_a - i_psi)).limit(max_f32(floor_a, -self.i_max_a), i_d_a)
    }

    /// The steady-state rotor flux of d-axis current `i_d_a` on the motor's inductance,
    /// `L_m·i_d`, Wb ([`IfocState::flux_of`]: on the inductance in use).
    pub fn flux_of(&self, i_d_a: f32) -> f32 {
        self.lm_h * i_d_a
    }

    /// Torque per rotor flux and q-axis current, `(3/2)·p·L_m/L_r`, N·m/(Wb·A).
    pub fn torque_factor(&self) -> f32 {
        1.0 / self.inv_torque_factor
    }

    /// The rotor flux's back-EMF in the stator at field speed `omega_e_rad_s` (electrical),
    /// V, on the field's q axis: `ω_e·(L_m/L_r)·ψ̂_r` — the T model's stator equation
    /// `v_s = R_s·i_s + σL_s·di_s/dt + (L_m/L_r)·dψ_r/dt` with the rotor flux turning at
    /// ω_e (its magnitude's change is the slow flux model's). `L_m/L_r` is the torque
    /// factor's (the same on any inductance scale); ψ̂_r the flux model's.
    pub fn back_emf_v(&self, s: &IfocState, omega_e_rad_s: f32) -> f32 {
        omega_e_rad_s * s.psi_r_wb() / (1.5 * self.pole_pairs * self.inv_torque_factor)
    }

    /// The encoder's reading: the rotor's electrical angle `theta_r_rad` (rad, any range
    /// a single wrap brings into `[-π, π)`). The field angle becomes `θ_r + θ_sl`; the next
    /// [`IfocConfig::plan`] computes its sin/cos.
    pub fn anchor(&self, s: &mut IfocState, theta_r_rad: f32) {
        s.f.theta_e_rad = wrap_angle(wrap_angle(theta_r_rad) + s.theta_sl_rad);
    }

    /// Anchor the field at `theta_e_rad` itself (a sensorless drive's observed rotor-flux
    /// angle) instead of on the rotor's angle: returns the rotor angle `θ_e − θ_sl` this
    /// makes, rad in `[-π, π)`.
    pub fn anchor_field(&self, s: &mut IfocState, theta_e_rad: f32) -> f32 {
        s.f.theta_e_rad = wrap_angle(theta_e_rad);
        wrap_angle(s.f.theta_e_rad - s.theta_sl_rad)
    }

    /// A state with θ_e = 0, the flux estimate `psi_r_wb` (0: an unmagnetized machine) and
    /// the rotor resistance `rr_scale` × the motor's ([`IfocConfig::set_rotor_resistance_scale`]).
    pub fn state(&self, psi_r_wb: f32, rr_scale: f32) -> IfocState {
        let mut s = IfocState {
            f: FieldSteps::default(),
            theta_sl_rad: 0.0,
            omega_sl_before_rad_s: 0.0,
            slip_gain: self.slip_gain,
            flux_rate: self.flux_rate,
            rr_scale: 1.0,
            lm_h: self.lm_h,
            l_scale: 1.0,
            psi_r_wb,
        };
        self.set_rotor_resistance_scale(&mut s, rr_scale);
        s
    }

    /// Run the slip and the flux model on the rotor resistance `scale` × the motor's (a
    /// finite, positive scale; anything else is ignored): `ω_sl = scale·L_m·R_r/(L_r·ψ̂)·i_qs*`
    /// (ψ̂ on the inductance in use: the slip `R_r·i_q/(L_r·i_d)` does not depend on it), and
    /// the flux model's rate `1/T̂_r = (R̂_r/R_r)/(L̂/L)/T_r` ([`Self::set_inductance_scale`]).
    #[inline(never)]
    pub fn set_rotor_resistance_scale(&self, s: &mut IfocState, scale: f32) {
        if !finite_positive(scale) {
            return;
        }
        s.rr_scale = scale;
        s.slip_gain = scale * self.slip_gain;
        self.set_flux_model_rate(s);
    }

    /// Run the flux model on the inductances `scale` × the motor's (L_s, L_r, L_m alike —
    /// a finite, positive scale; anything else is ignored): its target `L̂_m·i_ds` and its
    /// time constant `T̂_r = L̂_r/R̂_r`. The estimate ψ̂_r is rescaled with it (it is `L̂_m` times
    /// the filtered current), so that a flux measured with the old inductance is not lost.
    pub fn set_inductance_scale(&self, s: &mut IfocState, scale: f32) {
        if !finite_positive(scale) {
            return;
        }
        s.psi_r_wb *= scale / s.l_scale;
        s.l_scale = scale;
        s.lm_h = scale * self.lm_h;
        self.set_flux_model_rate(s);
    }

    /// The flux model's rate per fast step `c·T/T_r`, `c = (R̂_r/R_r)/(L̂/L)`.
    fn set_flux_model_rate(&self, s: &mut IfocState) {
        s.flux_rate = s.rr_scale / s.l_scale * self.flux_rate;
    }

    /// 1/ψ̂_r with ψ̂_r floored at `psi_min_wb` (the guard of the module docs).
    #[inline]
    fn inv_psi_floored(&self, psi_r_wb: f32) -> f32 {
        1.0 / max_f32(psi_r_wb, self.psi_min_wb)
    }

    /// The current-reference limit, A.
    pub fn i_max_a(&self) -> f32 {
        self.i_max_a
    }

    /// Slow rate, first: the fast steps since the last call close — the field angle advances
    /// by their `n·δ` (the plan's prediction), and the rotor's model by what the measured
    /// current did over them: the flux model (eq. (8), exact ZOH over the n steps) takes
    /// the mean of the measured d-axis current, and with `measured_slip` the slip angle
    /// advances by `n·T·(L_m·R_r/L_r)·ī_q/ψ̂_r` on the mean measured q-axis current (eq. (7)
    /// on the current the rotor saw), without it by the slip of the plans the fast steps ran
    /// (`SlipCurrent`). The two differ where the loops do not follow — at the voltage limit,
    /// braking at the top speed — and the slip of the reference then turned the field away
    /// from the rotor's flux, a detuning that grew into a swing of the flux and a trip
    /// (`FollowingError` on healthy motors of the population at 4 kHz).
    ///
    /// `delay`: the plan's delay ([`crate::drive::plan_delay_periods`]) — the first `delay`
    /// of the n steps ran the plan before this state's last one (its adoption comes that
    /// many periods after the tick that made it): their slip is that plan's, and the field
    /// angle of the last plan's first step advances over the rest alone. Returns the mean
    /// measured current, field frame, A, and n (0: no fast step ran; nothing changes).
    pub fn close_period(&self, s: &mut IfocState, measured_slip: bool, delay: u16) -> (Dq, u16) {
        let n = s.f.steps;
        if n == 0 {
            return (Dq::default(), 0);
        }
        let nf = f32::from(n);
        let (before, after) = (f32::from(delay.min(n)), f32::from(n.saturating_sub(delay)));
        let mean = Dq { d: s.f.i_sum_dq.d / nf, q: s.f.i_sum_dq.q / nf };
        let slip_angle_rad = if measured_slip {
            nf * s.slip_gain * mean.q * self.inv_psi_floored(s.psi_r_wb)
        } else {
            before * s.omega_sl_before_rad_s + after * s.f.plan.omega_sl_rad_s
        };
        s.theta_sl_rad = wrap_angle(s.theta_sl_rad + slip_angle_rad * self.ts_s);
        s.omega_sl_before_rad_s = s.f.plan.omega_sl_rad_s;
        // The next period's first step's angle (the drive's slow step then anchors it to
        // the encoder's reading).
        s.f.theta_e_rad = wrap_angle(s.f.theta_e_rad + after * s.f.plan.step_rad);
        s.psi_r_wb += one_minus_exp_neg(nf * s.flux_rate) * (s.lm_h * mean.d - s.psi_r_wb);
        (s.f.i_sum_dq, s.f.steps) = (Dq::default(), 0);
        (mean, n)
    }

    /// The field angle of the next plan's first step `delay` fast steps on (the plan's delay
    /// from the anchor's tick to its adoption), over which the plan in force turns it.
    pub fn advance(&self, s: &mut IfocState, delay: u16) {
        s.f.theta_e_rad = wrap_angle(s.f.theta_e_rad + f32::from(delay) * s.f.plan.step_rad);
    }

    /// Slow rate, last: the plan for the fast steps up to the next slow step, from the flux
    /// command ([`IfocConfig::flux_command`]), the torque command, the mechanical speed
    /// (rad/s) and a trim of the references (A, field frame) — i_qs* on the flux estimate,
    /// the slip, the field vector afresh from θ_e and its rotation per fast step. The trim is
    /// added to the references the current loops track but not to the intended ones, which
    /// set the slip.
    pub fn plan(
        &self,
        s: &mut IfocState,
        flux: &FluxCommand,
        cmd: TorqueCommand,
        omega_m_rad_s: f32,
        trim: Dq,
    ) {
        let i_d = flux.i_d_a;
        let inv_psi = self.inv_psi_floored(s.psi_r_wb);
        let i_q_wanted = match cmd {
            TorqueCommand::TorqueNm(t) => t * self.inv_torque_factor * inv_psi,
            TorqueCommand::IqA(i) => i,
        };
        let i_q = i_q_wanted.limit(-flux.i_q_max_a, flux.i_q_max_a);
        let omega_sl_rad_s = s.slip_gain * i_q * inv_psi;
        let step_rad = (self.pole_pairs * omega_m_rad_s + omega_sl_rad_s) * self.ts_s;
        s.f.plan = FieldPlan {
            step_rad,
            rotation: SinCos::new(step_rad),
            i_ref_dq: Dq { d: i_d, q: i_q },
            i_track_dq: Dq { d: i_d + trim.d, q: i_q + trim.q },
            omega_sl_rad_s,
        };
        s.f.field = SinCos::new(s.f.theta_e_rad);
    }

    /// One fast step, with the measured stator current (A): the current references at the
    /// present field angle, then the field turned by the plan's rotation and the measured
    /// current's field-frame components added to the flux model's sum.
    #[inline]
    pub fn step(&self, s: &mut IfocState, i_meas: AlphaBeta) -> IfocOutput {
        self.step_field(&mut s.f, i_meas)
    }

    /// [`IfocConfig::step`] on the fast steps' part alone (the fast context's).
    #[inline(always)]
    pub fn step_field(&self, s: &mut FieldSteps, i_meas: AlphaBeta) -> IfocOutput {
        let field = s.field;
        let i_ref_ab = s.i_ref_ab();
        let i = i_meas.park(field);
        s.i_sum_dq = Dq { d: s.i_sum_dq.d + i.d, q: s.i_sum_dq.q + i.q };
        s.steps = s.steps.saturating_add(1);
        s.field = field.then(s.plan.rotation);
        let p = &s.plan;
        IfocOutput { i_ref_dq: p.i_ref_dq, i_ref_ab, i_meas_dq: i, field, omega_sl_rad_s: p.omega_sl_rad_s }
    }
}

impl IfocConfig {}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg() -> IfocConfig {
        let m = MotorParams::delorenzo_dl10115a1().unwrap();
        IfocConfig::new(&m, 5e-5, 0.05, 10.0).unwrap()
    }

    /// Fast steps per plan in these tests (the shipped drive's slow divider).
    const N: usize = 10;

    /// `n` fast steps with a plan every `N`th (closing the period before it, as the drive's
    /// slow step) and ideal current control one step late: the measured current is the
    /// previous step's reference. Returns the last output.
    fn run(
        c: &IfocConfig,
        s: &mut IfocState,
        psi: f32,
        cmd: TorqueCommand,
        omega_m: f32,
        n: usize,
    ) -> IfocOutput {
        let mut out = IfocOutput::default();
        for k in 0..n {
            if k % N == 0 {
                c.close_period(s, false, 0);
                c.plan(s, &c.flux_command(psi), cmd, omega_m, Dq::default());
            }
            out = c.step(s, out.i_ref_ab);
        }
        out
    }

    /// Hand-computed operating point, DeLorenzo motor, ψr* = 1 Wb, T* = 1 N·m:
    /// i_ds* = 1/1.42 = 0.704225 A; i_qs* = 1·1.5/(1.5·1·1.42·1) = 0.704225 A;
    /// ω_sl = 1.42·23.2/(1.5·1)·0.704225 = 15.4667 rad/s
    /// (cross-check: ω_sl = i_qs/(T_r·i_ds) = 23.2/1.5 = 15.4667).
    #[test]
    fn steady_state_operating_point() {
        let c = cfg();
        let mut s = c.state(0.0, 1.0);
        // Flux builds with T_r = 64.7 ms; 1 s is > 15 T_r.
        let out = run(&c, &mut s, 1.0, TorqueCommand::TorqueNm(1.0), 0.0, 20_000);
        c.close_period(&mut s, false, 0);
        // The measured current is the reference one step late, in a field that has turned by
        // ω_sl·T = 7.7e-4 rad since: its d part is i_d + i_q·ω_sl·T, 7.7e-4 too high here.
        assert!((s.psi_r_wb() - 1.000_773).abs() < 1e-4, "flux {}", s.psi_r_wb());
        let psi = s.psi_r_wb();
        assert!((out.i_ref_dq.d - 0.704_225).abs() < 1e-5);
        // i_q* and ω_sl* follow the flux estimate: T*/(K'·ψ̂) and L_m·R_r/L_r·i_q*/ψ̂.
        assert!((out.i_ref_dq.q * psi - 0.704_225).abs() < 1e-4);
        assert!((out.omega_sl_rad_s * psi * psi - 15.466_67).abs() < 2e-3, "{}", out.omega_sl_rad_s);
        // The αβ reference has the dq magnitude.
        assert!((out.i_ref_ab.magnitude() - libm::hypotf(out.i_ref_dq.d, out.i_ref_dq.q)).abs() < 1e-5);
    }

    /// The flux model over whole periods equals the per-step ZOH model of eq. (8) with the
    /// same current: ψ̂ after `n` steps of a constant i_d is `L_m·i_d·(1 − e^{−n·T/T_r})`.
    #[test]
    fn flux_model_is_first_order_with_tr() {
        let c = cfg();
        let mut s = c.state(0.0, 1.0);
        let tr = 1.5f64 / 23.2;
        let n = (tr / 5e-5 / N as f64).round() as usize * N;
        let i_d = 1.0 / 1.42;
        for k in 0..n {
            if k % N == 0 {
                c.close_period(&mut s, false, 0);
                c.plan(&mut s, &c.flux_command(1.0), TorqueCommand::TorqueNm(0.0), 0.0, Dq::default());
            }
            // The measured current on the d axis of this step's field.
            let f = s.f.field;
            c.step(&mut s, Dq { d: i_d, q: 0.0 }.inverse_park(f));
        }
        c.close_period(&mut s, false, 0);
        let expected = 1.0 - libm::exp(-(n as f64) * 5e-5 / tr);
        let e = (f64::from(s.psi_r_wb()) - expected).abs();
        assert!(e < 1e-5, "ψ̂ {} against {expected}: {e:e}", s.psi_r_wb());
    }

    /// `1 − e^{−y}` against f64 from 1e-9 to 100 (the series, the halvings), relative error
    /// within a few f32 roundings; 0 for non-finite and non-positive `y`.
    #[test]
    fn one_minus_exp_neg_is_accurate() {
        let mut worst = 0.0f64;
        let mut y = 1e-9f64;
        while y < 100.0 {
            let g = f64::from(one_minus_exp_neg(y as f32));
            let exact = -libm::expm1(-f64::from(y as f32));
            worst = worst.max((g / exact - 1.0).abs());
            y *= 1.07;
        }
        assert!(worst < 1e-6, "worst relative error {worst:e}");
        for bad in [0.0, -1.0, f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            assert_eq!(one_minus_exp_neg(bad), 0.0, "{bad}");
        }
    }

    /// The slip angle is the rotor's: over a plan asking i_q* = 2 A, a measured q-axis
    /// current of 1 A (loops that cannot follow, at the voltage limit) advances it by half
    /// the plan's slip, and the reference's 2 A by all of it.
    #[test]
    fn the_slip_angle_follows_the_measured_q_current() {
        let c = cfg();
        for (i_q_meas, share) in [(1.0f32, 0.5f32), (2.0, 1.0)] {
            let mut s = c.state(1.0, 1.0);
            c.plan(&mut s, &c.flux_command(1.0), TorqueCommand::IqA(2.0), 0.0, Dq::default());
            let mut omega_sl = 0.0;
            for _ in 0..N {
                let f = s.f.field;
                omega_sl = c.step(&mut s, Dq { d: 0.5, q: i_q_meas }.inverse_park(f)).omega_sl_rad_s;
            }
            assert!(omega_sl > 0.0);
            c.close_period(&mut s, true, 0);
            let expected = share * omega_sl * N as f32 * 5e-5;
            let got = s.theta_sl_rad();
            assert!((got - expected).abs() <= 1e-5 * expected, "{got} against {expected}");
        }
    }

    #[test]
    fn field_angle_advances_at_synchronous_speed_and_wraps() {
        let c = cfg();
        let mut s = c.state(1.0, 1.0);
        // p = 1, ω_m = 100 rad/s, no torque: θ advances 100·T per step.
        let mut prev = 0.0f32;
        let mut wraps = 0;
        for k in 0..20_000 {
            if k % N == 0 {
                c.close_period(&mut s, false, 0);
                c.plan(&mut s, &c.flux_command(1.0), TorqueCommand::IqA(0.0), 100.0, Dq::default());
            }
            let theta = s.theta_e_rad();
            c.step(&mut s, AlphaBeta::default());
            assert_eq!(s.last_theta_e_rad(), theta);
            assert!((-core::f32::consts::PI..core::f32::consts::PI).contains(&theta));
            if theta < prev {
                wraps += 1;
            }
            prev = theta;
        }
        // 1 s at 100 rad/s = 15.9 turns.
        assert_eq!(wraps, 16);
    }

    /// The field vector the current references are turned with stays within 1.5e-6 of
    /// sin/cos of the field angle, step after step: turned by the plan's rotation between
    /// plans, recomputed at each — from standstill to a field step of 0.4 rad, both
    /// directions, through flux build-up (where the slip is largest) — 40 000 steps (2 s) per
    /// speed, 2 500 field-angle wraps at the highest speed. The bound: the angle θ_e itself
    /// is the f32 θ_e,0 + k·δ ([`IfocState::theta_e_rad`]), rounded by up to ulp(π)/2 =
    /// 1.2e-7 (twice, and once more in the wrap), plus the rotation's own error (≤ 1.2e-7
    /// per turn, `SinCos::new`, up to 9 turns before the next plan) and rounding. Without the
    /// recompute at each plan the gap grows without bound (test
    /// `the_field_drifts_without_the_plans_recompute`).
    #[test]
    fn field_tracks_the_angle() {
        let c = cfg();
        let mut worst = (0.0f64, 0.0f32);
        for omega_m in [0.0f32, 37.3, 150.0, -376.0, 1_500.0, -1_900.0, 2_500.0, 8_000.0] {
            let mut s = c.state(0.0, 1.0);
            let mut measured = AlphaBeta::default();
            for k in 0..40_000 {
                let torque = if k < 20_000 { 1.0 } else { -3.0 };
                if k % N == 0 {
                    c.close_period(&mut s, false, 0);
                    c.plan(
                        &mut s,
                        &c.flux_command(0.9),
                        TorqueCommand::TorqueNm(torque),
                        omega_m,
                        Dq::default(),
                    );
                }
                let theta = s.theta_e_rad();
                let out = c.step(&mut s, measured);
                measured = out.i_ref_ab;
                let (sin, cos) = libm::sincos(f64::from(theta));
                let e = (f64::from(out.field.sin) - sin).abs().max((f64::from(out.field.cos) - cos).abs());
                if e > worst.0 {
                    worst = (e, omega_m);
                }
            }
        }
        eprintln!("IFOC field vs sin/cos(θ_e): worst abs. error {:.3e} at ω_m = {} rad/s", worst.0, worst.1);
        assert!(worst.0 <= 1.5e-6, "{worst:?}");
    }

    /// The recompute at each plan is what holds the field to its angle: planned once and
    /// turned for 40 000 steps at 8 000 rad/s, the vector drifts far beyond the bound above.
    #[test]
    fn the_field_drifts_without_the_plans_recompute() {
        let c = cfg();
        let mut s = c.state(0.9, 1.0);
        c.plan(&mut s, &c.flux_command(0.9), TorqueCommand::TorqueNm(1.0), 8_000.0, Dq::default());
        let mut worst = 0.0f64;
        for _ in 0..40_000 {
            let theta = s.theta_e_rad();
            let out = c.step(&mut s, AlphaBeta::default());
            let (sin, cos) = libm::sincos(f64::from(theta));
            worst =
                worst.max((f64::from(out.field.sin) - sin).abs().max((f64::from(out.field.cos) - cos).abs()));
        }
        assert!(worst > 1e-5, "{worst:e}");
    }

    #[test]
    fn guard_bounds_slip_and_current_while_flux_is_zero() {
        let c = cfg();
        let mut s = c.state(0.0, 1.0);
        c.plan(&mut s, &c.flux_command(1.0), TorqueCommand::TorqueNm(1e6), 0.0, Dq::default());
        let out = c.step(&mut s, AlphaBeta::default());
        assert!(libm::hypotf(out.i_ref_dq.d, out.i_ref_dq.q) <= 10.0 + 1e-4);
        // ω_sl ≤ slip_gain·i_max/ψ_min = 21.96·10/0.05
        assert!(out.omega_sl_rad_s.is_finite() && out.omega_sl_rad_s <= 21.97 * 10.0 / 0.05);
    }

    #[test]
    fn flux_command_splits_the_current_limit() {
        let c = cfg(); // i_max = 10 A, L_m = 1.42 H
        let f = c.flux_command(1.0);
        assert!((f.i_d_a() - 1.0 / 1.42).abs() < 1e-6);
        assert!((f.i_q_max_a() - libm::sqrtf(100.0 - f.i_d_a() * f.i_d_a())).abs() < 1e-5);
        // A flux reference beyond the limit: all of it on d, nothing left for q.
        let f = c.flux_command(100.0);
        assert_eq!((f.i_d_a(), f.i_q_max_a()), (10.0, 0.0));
        assert_eq!(c.flux_command(f32::NAN), FluxCommand::default());
    }

    #[test]
    fn the_rotor_resistance_scales_slip_and_flux_model() {
        let m = MotorParams::delorenzo_dl10115a1().unwrap();
        let c = cfg();
        let x = 1.0 / (20e3 * m.tr_s());
        for scale in [0.5f32, 1.0, 1.5, 2.0, 3.0] {
            let s = c.state(0.0, scale);
            assert_eq!(s.rotor_resistance_scale(), scale);
            let slip = f64::from(s.slip_gain) / (m.lm_h() * m.rr_ohm() / m.lr_h());
            assert!((slip - f64::from(scale)).abs() <= 1e-6, "{scale}: slip gain ×{slip}");
            let rel = f64::from(s.flux_rate) / (f64::from(scale) * x) - 1.0;
            assert!(rel.abs() <= 1e-6, "{scale}: flux model rate off by {rel:e}");
        }
        // At scale 1 the motor's own numbers, bit for bit.
        let s = c.state(0.0, 1.0);
        assert_eq!((s.slip_gain, s.flux_rate), (c.slip_gain, c.flux_rate));
        // Anything but a finite positive scale is ignored.
        let mut s = c.state(0.0, 2.0);
        for bad in [0.0, -1.0, f32::NAN, f32::INFINITY] {
            c.set_rotor_resistance_scale(&mut s, bad);
            assert_eq!(s.rotor_resistance_scale(), 2.0);
        }
    }

    /// [`IfocConfig::falling_flux_current`]: a flux at or below its target gets the target's
    /// current, and so does any flux when the fall time is no faster than the rotor's T_r;
    /// a flux well above it no current, or a reversed one within the current limit on a
    /// negative floor; and a flux a little
    /// above it (no limit reached) falls to 1/e of its excess in the fall time — 10 ms here,
    /// where the DeLorenzo rotor's own T_r is 64.7 ms — on the flux model's exact update.
    #[test]
    fn a_flux_above_its_target_falls_within_the_fall_time() {
        let c = cfg();
        let (ts, fall_s) = (5e-5f32, 0.01f32);
        let fall_rate = ts / fall_s;
        let target = 0.5 * 0.9 / 1.42; // half the rated flux's current, A
        let psi_target = c.flux_of(target);
        let at = |psi: f32| c.state(psi, 1.0);
        assert_eq!(c.falling_flux_current(&at(psi_target), target, fall_rate, 0.0), target);
        assert_eq!(c.falling_flux_current(&at(0.5 * psi_target), target, fall_rate, 0.0), target);
        assert_eq!(c.falling_flux_current(&at(2.0 * psi_target), target, ts / 0.1, 0.0), target);
        // Twice the target: i_ψ + (T_r/τ_f)·(i_d − i_ψ) = i_d·(2 − 6.47) — no current on a
        // floor of 0, reversed on a negative one, never beyond the current limit.
        assert_eq!(c.falling_flux_current(&at(2.0 * psi_target), target, fall_rate, 0.0), 0.0);
        let k = fall_rate / c.state(psi_target, 1.0).flux_rate;
        let i_max = c.i_max_a();
        let reversed = c.falling_flux_current(&at(2.0 * psi_target), target, fall_rate, -i_max);
        assert!((reversed - target * (2.0 - k)).abs() < 1e-5 && reversed < 0.0, "{reversed}, k {k}");
        assert_eq!(c.falling_flux_current(&at(100.0 * psi_target), target, fall_rate, -2.0 * i_max), -i_max);
        let mut s = at(1.05 * psi_target);
        let (mut t_s, t_slow) = (0.0f32, N as f32 * ts);
        let excess0 = s.psi_r_wb() - psi_target;
        while s.psi_r_wb() - psi_target > excess0 / core::f32::consts::E {
            let i_d = c.falling_flux_current(&s, target, fall_rate, 0.0);
            assert!(i_d > 0.0 && i_d < target, "{i_d}");
            s.add_sums((Dq { d: N as f32 * i_d, q: 0.0 }, N as u16));
            c.close_period(&mut s, false, 0);
            t_s += t_slow;
        }
        assert!((t_s - fall_s).abs() <= t_slow, "{t_s}");
    }

    /// On the inductances ×ℓ (L_s, L_r, L_m alike) with the rotor resistance ×r, the flux
    /// model is the scaled machine's — target ℓ·L_m·i_d, time constant ℓ·T_r/r — and the slip
    /// is the machine's `r·R_r·i_q/(ℓ·L_r·i_d)` at the flux it builds; the estimate is
    /// rescaled with ℓ; bad scales are ignored.
    #[test]
    fn the_inductance_scales_the_flux_model() {
        let m = MotorParams::delorenzo_dl10115a1().unwrap();
        let c = cfg();
        let x = 1.0 / (20e3 * m.tr_s());
        for (l, r) in [(0.6f32, 1.0f32), (0.6, 2.0), (0.8, 1.3), (1.0, 1.0)] {
            let mut s = c.state(0.5, r);
            c.set_inductance_scale(&mut s, l);
            assert_eq!(s.inductance_scale(), l);
            assert!((s.psi_r_wb() - 0.5 * l).abs() <= 1e-7, "ψ̂ rescaled: {}", s.psi_r_wb());
            assert!((f64::from(s.flux_of(1.0)) / (f64::from(l) * m.lm_h()) - 1.0).abs() <= 1e-6);
            let rel = f64::from(s.flux_rate) / (f64::from(r / l) * x) - 1.0;
            assert!(rel.abs() <= 1e-6, "ℓ {l}, r {r}: flux model rate off by {rel:e}");
            // Slip at i_d = 1 A, i_q = 1 A on the flux ℓ·L_m: the machine's r·R_r/(ℓ·L_r).
            let slip = f64::from(s.slip_gain) / (f64::from(l) * m.lm_h());
            let truth = f64::from(r) * m.rr_ohm() / (f64::from(l) * m.lr_h());
            assert!((slip / truth - 1.0).abs() <= 1e-6, "ℓ {l}, r {r}: slip {slip} of {truth}");
        }
        // At ℓ = 1 the motor's own numbers, bit for bit.
        let mut s = c.state(0.0, 1.0);
        c.set_inductance_scale(&mut s, 1.0);
        assert_eq!((s.slip_gain, s.flux_rate, s.lm_h), (c.slip_gain, c.flux_rate, c.lm_h));
        for bad in [0.0, -1.0, f32::NAN, f32::INFINITY] {
            c.set_inductance_scale(&mut s, bad);
            assert_eq!(s.inductance_scale(), 1.0);
        }
    }

    #[test]
    fn rejects_bad_config() {
        let m = MotorParams::delorenzo_dl10115a1().unwrap();
        assert_eq!(IfocConfig::new(&m, 0.0, 0.05, 10.0), Err(IfocError::SamplePeriod));
        assert_eq!(IfocConfig::new(&m, 5e-5, 0.0, 10.0), Err(IfocError::FluxFloor));
        assert_eq!(IfocConfig::new(&m, 5e-5, 0.05, f64::NAN), Err(IfocError::CurrentLimit));
    }
}
