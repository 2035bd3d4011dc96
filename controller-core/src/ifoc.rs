//! Indirect field-oriented control (seed 000 eqs. (6)–(9), seed 002 Fig. 12).
//!
//! With the d axis on the rotor flux (`ψ_qr = 0`, `ψ_dr = ψ_r`, eq. (6)):
//!
//! * flux reference → `i_ds* = ψ_r*/L_m` (eq. (9), steady state of eq. (8); the drive divides
//!   by the inductance scale in use, [`IfocConfig::set_inductance_scale`]);
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
//!   `θ_e[k+1] = wrap(θ_e[k] + (p·ω_m + ω_sl)·T)` between reads, in `[-π, π)`;
//! * current references returned in αβ (inverse Park at θ_e) for the stationary-frame loops;
//!   sin/cos of θ_e[k+1] are evaluated at the end of step k, so that step k+1 starts with them:
//!   by rotating those of θ_e\[k\] through the angle step ([`SinCos::rotated`]), and afresh
//!   from θ_e[k+1] ([`SinCos::new`]) every [`FIELD_RESYNC_STEPS`] steps, so that rounding
//!   cannot accumulate (field error ≤ 2.5e-6 against sin/cos of θ_e, `field_tracks_the_angle`).
//!
//! **Guard while the flux builds up:** ψ̂ is floored at `psi_min_wb` in the torque and slip
//! divisions, so neither can blow up at start; `i_qs*` is further limited so that the current
//! reference vector stays within `i_max_a`.

use crate::frames::{AlphaBeta, Dq, SinCos, wrap_angle};
use crate::motor::MotorParams;
use crate::num::{Scalar, max_f32, sqrt_f32};

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

/// IFOC configuration (derived from the motor at construction).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IfocConfig {
    inv_lm: f32,
    lm_h: f32,
    slip_gain: f32,
    inv_torque_factor: f32,
    pole_pairs: f32,
    flux_model_gain: f32,
    /// `T/T_r`, the flux model's rate per step at the motor's rotor resistance.
    flux_rate: f32,
    psi_min_wb: f32,
    i_max_a: f32,
    ts_s: f32,
}

/// The field's sin/cos are recomputed from the angle every this many steps and rotated in
/// between (see the module docs).
pub const FIELD_RESYNC_STEPS: u8 = 16;

/// IFOC state, made by [`IfocConfig::state`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IfocState {
    /// Field (rotor-flux) angle θ_e, rad, in `[-π, π)`.
    theta_e_rad: f32,
    /// Slip angle θ_sl = ∫ω_sl dt, rad, in `[-π, π)`: θ_e less the rotor's electrical angle.
    theta_sl_rad: f32,
    /// sin and cos of `theta_e_rad`, computed when the angle advances — one step before
    /// they are used, so that the next step's current references do not wait for them.
    field: SinCos,
    /// Steps left until `field` is recomputed from `theta_e_rad` (0: at the next step).
    steps_to_resync: u8,
    /// Rotor-flux model estimate ψ̂_r, Wb.
    psi_r_wb: f32,
    /// The slip gain `L_m·R̂_r/L_r` and the flux model's gain `1 − e^{−T·R̂_r/L_r}` of the
    /// rotor resistance in use, R̂_r = the motor's × [`IfocState::rotor_resistance_scale`]
    /// (set by [`IfocConfig::set_rotor_resistance_scale`]).
    slip_gain: f32,
    flux_model_gain: f32,
    rr_scale: f32,
    /// The magnetizing inductance in use, `L̂_m = L_m·`[`IfocState::inductance_scale`] (the
    /// flux model's `ψ̂_r → L̂_m·i_ds`; set by [`IfocConfig::set_inductance_scale`]), H.
    lm_h: f32,
    l_scale: f32,
    /// 1/max(ψ̂_r, ψ_min): the one division of the step (for i_qs* and ω_sl), made when ψ̂_r
    /// is updated, at the end of the step before — off the head of the next step's chain
    /// of dependent operations (`hil-sim bench`: ≈ 1 ns per period).
    inv_psi_floored: f32,
}

impl IfocState {
    /// Field (rotor-flux) angle θ_e for the next step, rad, in `[-π, π)`.
    pub fn theta_e_rad(&self) -> f32 {
        self.theta_e_rad
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

    /// sin and cos of the field angle afresh; restarts the resync countdown. Kept out of
    /// line: inlined in [`IfocConfig::update`], the rarely taken branch slowed the fast step.
    #[cold]
    #[inline(never)]
    fn resync_field(&mut self) {
        self.field = SinCos::new(self.theta_e_rad);
        self.steps_to_resync = FIELD_RESYNC_STEPS - 1;
    }
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

/// Result of one IFOC step.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct IfocOutput {
    /// Current references in the field frame, A.
    pub i_ref_dq: Dq,
    /// Current references in the stationary frame, A.
    pub i_ref_ab: AlphaBeta,
    /// Field angle used for this step, rad.
    pub theta_e_rad: f32,
    /// sin and cos of `theta_e_rad` (for Park and inverse Park in the synchronous frame).
    pub field: SinCos,
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
            flux_model_gain: f(1.0 - libm::exp(-ts_s / motor.tr_s())),
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
        let i_q_max_a = sqrt_f32((self.i_max_a * self.i_max_a - i_d_a * i_d_a).max(0.0));
        FluxCommand { i_d_a, i_q_max_a }
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

    /// The encoder's reading: the rotor's electrical angle `theta_r_rad` (rad, any range
    /// a single wrap brings into `[-π, π)`). The field angle becomes `θ_r + θ_sl`, and its
    /// sin/cos are computed afresh for the next step.
    pub fn anchor(&self, s: &mut IfocState, theta_r_rad: f32) {
        s.theta_e_rad = wrap_angle(wrap_angle(theta_r_rad) + s.theta_sl_rad);
        s.resync_field();
    }

    /// A state with θ_e = 0, the flux estimate `psi_r_wb` (0: an unmagnetized machine) and
    /// the rotor resistance `rr_scale` × the motor's ([`IfocConfig::set_rotor_resistance_scale`]).
    pub fn state(&self, psi_r_wb: f32, rr_scale: f32) -> IfocState {
        let mut s = IfocState {
            theta_e_rad: 0.0,
            theta_sl_rad: 0.0,
            field: SinCos::default(),
            steps_to_resync: 0,
            slip_gain: self.slip_gain,
            flux_model_gain: self.flux_model_gain,
            rr_scale: 1.0,
            lm_h: self.lm_h,
            l_scale: 1.0,
            psi_r_wb,
            inv_psi_floored: self.inv_psi_floored(psi_r_wb),
        };
        self.set_rotor_resistance_scale(&mut s, rr_scale);
        s
    }

    /// Run the slip and the flux model on the rotor resistance `scale` × the motor's (a
    /// finite, positive scale; anything else is ignored): `ω_sl = scale·L_m·R_r/(L_r·ψ̂)·i_qs*`
    /// (ψ̂ on the inductance in use: the slip `R_r·i_q/(L_r·i_d)` does not depend on it), and
    /// the flux model's rate `1/T̂_r = (R̂_r/R_r)/(L̂/L)/T_r` ([`Self::set_inductance_scale`]).
    pub fn set_rotor_resistance_scale(&self, s: &mut IfocState, scale: f32) {
        if !(scale.is_finite() && scale > 0.0) {
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
        if !(scale.is_finite() && scale > 0.0) {
            return;
        }
        s.psi_r_wb *= scale / s.l_scale;
        s.inv_psi_floored = self.inv_psi_floored(s.psi_r_wb);
        s.l_scale = scale;
        s.lm_h = scale * self.lm_h;
        self.set_flux_model_rate(s);
    }

    /// The flux model's gain `1 − e^{−c·x}` (`x = T/T_r`, `c = (R̂_r/R_r)/(L̂/L)`) as
    /// `g·c·(1 − (c − 1)·x/2)` from the motor's exact `g = 1 − e^{−x}`: exact at c = 1, its
    /// error `O((c·x)³)` — 1.5e-7 of the gain at the shipped `x = 7.7e-4` and c = 2, about
    /// f32's rounding (test `the_rotor_resistance_scales_slip_and_flux_model`).
    fn set_flux_model_rate(&self, s: &mut IfocState) {
        let c = s.rr_scale / s.l_scale;
        s.flux_model_gain = self.flux_model_gain * c * (1.0 - 0.5 * (c - 1.0) * self.flux_rate);
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

    /// One step: flux command ([`IfocConfig::flux_command`]), torque command, mechanical
    /// speed (rad/s), the measured stator current (A) and a trim of the references (A, field
    /// frame) → current references at the present field angle; then the angle and the flux
    /// model (on the measured d-axis current) advance by one sample. The trim is added to
    /// the references the current loops track (`i_ref_ab`) but not to the intended ones
    /// (`i_ref_dq`), which set the slip.
    #[inline]
    pub fn update(
        &self,
        s: &mut IfocState,
        flux: &FluxCommand,
        cmd: TorqueCommand,
        omega_m_rad_s: f32,
        i_meas: AlphaBeta,
        trim: Dq,
    ) -> IfocOutput {
        let i_d = flux.i_d_a;
        let inv_psi = s.inv_psi_floored;
        let i_q_wanted = match cmd {
            TorqueCommand::TorqueNm(t) => t * self.inv_torque_factor * inv_psi,
            TorqueCommand::IqA(i) => i,
        };
        let i_q = i_q_wanted.limit(-flux.i_q_max_a, flux.i_q_max_a);
        let omega_sl = s.slip_gain * i_q * inv_psi;
        let theta = s.theta_e_rad;
        let i_ref_dq = Dq { d: i_d, q: i_q };
        let s_field = s.field;
        let i_ref_ab = Dq { d: i_d + trim.d, q: i_q + trim.q }.inverse_park(s_field);
        let slip_step = omega_sl * self.ts_s;
        let delta = self.pole_pairs * omega_m_rad_s * self.ts_s + slip_step;
        s.theta_e_rad = wrap_angle(theta + delta);
        s.theta_sl_rad = wrap_angle(s.theta_sl_rad + slip_step);
        // Rotated with the angle; afresh every FIELD_RESYNC_STEPS steps, and after a step
        // too large to rotate accurately (or not finite).
        let rotatable = delta.abs() <= SinCos::MAX_ROTATION_RAD; // false for NaN
        let resync = (s.steps_to_resync == 0) | !rotatable;
        s.field = s_field.rotated(delta);
        s.steps_to_resync = s.steps_to_resync.wrapping_sub(1);
        if resync {
            s.resync_field();
        }
        // Only the d part: the drive parks the measured current itself where it needs q
        // (kept apart, the Cortex-M4F runs ≈ 7 fewer instructions per fast step).
        let i_d_meas = i_meas.alpha * s_field.cos + i_meas.beta * s_field.sin;
        s.psi_r_wb += s.flux_model_gain * (s.lm_h * i_d_meas - s.psi_r_wb);
        s.inv_psi_floored = self.inv_psi_floored(s.psi_r_wb);
        IfocOutput { i_ref_dq, i_ref_ab, theta_e_rad: theta, field: s_field, omega_sl_rad_s: omega_sl }
    }
}

impl IfocConfig {
    pub(crate) fn put(&self, w: &mut crate::raw::Writer) {
        for x in [
            self.inv_lm,
            self.lm_h,
            self.slip_gain,
            self.inv_torque_factor,
            self.pole_pairs,
            self.flux_model_gain,
            self.flux_rate,
            self.psi_min_wb,
            self.i_max_a,
            self.ts_s,
        ] {
            w.f(x);
        }
    }

    pub(crate) fn get(r: &mut crate::raw::Reader<'_>) -> Self {
        Self {
            inv_lm: r.f(),
            lm_h: r.f(),
            slip_gain: r.f(),
            inv_torque_factor: r.f(),
            pole_pairs: r.f(),
            flux_model_gain: r.f(),
            flux_rate: r.f(),
            psi_min_wb: r.f(),
            i_max_a: r.f(),
            ts_s: r.f(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg() -> IfocConfig {
        let m = MotorParams::delorenzo_dl10115a1().unwrap();
        IfocConfig::new(&m, 5e-5, 0.05, 10.0).unwrap()
    }

    /// `n` steps with ideal current control one step late: the measured current is the
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
        for _ in 0..n {
            out = c.update(s, &c.flux_command(psi), cmd, omega_m, out.i_ref_ab, Dq::default());
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

    #[test]
    fn flux_model_is_first_order_with_tr() {
        let c = cfg();
        let mut s = c.state(0.0, 1.0);
        let tr = 1.5f64 / 23.2;
        let n = (tr / 5e-5).round() as usize;
        run(&c, &mut s, 1.0, TorqueCommand::TorqueNm(0.0), 0.0, n);
        // The first step measures no current yet (the reference is one step late).
        let expected = 1.0 - libm::exp(-((n - 1) as f64) * 5e-5 / tr);
        assert!((f64::from(s.psi_r_wb()) - expected).abs() < 1e-4);
    }

    #[test]
    fn field_angle_advances_at_synchronous_speed_and_wraps() {
        let c = cfg();
        let mut s = c.state(1.0, 1.0);
        // p = 1, ω_m = 100 rad/s, no torque: θ advances 100·T per step.
        let mut prev = 0.0f32;
        let mut wraps = 0;
        for _ in 0..20_000 {
            let out = c.update(
                &mut s,
                &c.flux_command(1.0),
                TorqueCommand::IqA(0.0),
                100.0,
                AlphaBeta::default(),
                Dq::default(),
            );
            assert!((-core::f32::consts::PI..core::f32::consts::PI).contains(&out.theta_e_rad));
            if out.theta_e_rad < prev {
                wraps += 1;
            }
            prev = out.theta_e_rad;
        }
        // 1 s at 100 rad/s = 15.9 turns.
        assert_eq!(wraps, 16);
    }

    /// The field vector the current references are turned with stays within 2.5e-6 of
    /// sin/cos of the field angle, step after step: rotated between resyncs, recomputed when the
    /// angle step is beyond `SinCos::MAX_ROTATION_RAD` (ω_e > 2 000 rad/s here, p = 1), from
    /// standstill to beyond that speed, both directions, through flux build-up (where
    /// the slip is largest) — 40 000 steps (2 s) per speed, 2 500 field-angle wraps at the
    /// highest speed. The bound: the angle θ_e itself is an f32 sum, rounded by up to
    /// ulp(π)/2 = 1.2e-7 at each step, which the rotated vector (turned by the unrounded
    /// steps) does not follow until the next resync: 16·1.2e-7 ≈ 1.9e-6, plus the 2.5e-7 of
    /// one rotation. Without the resyncs the gap grows without bound (≈ 2e-5 with a resync every
    /// 256 steps instead of 16, ≈ 1e-3 without the range check: both fail here).
    #[test]
    fn field_tracks_the_angle() {
        let c = cfg();
        let mut worst = (0.0f64, 0.0f32);
        for omega_m in [0.0f32, 37.3, 150.0, -376.0, 1_500.0, -1_900.0, 2_500.0, 8_000.0] {
            let mut s = c.state(0.0, 1.0);
            let mut measured = AlphaBeta::default();
            for k in 0..40_000 {
                let torque = if k < 20_000 { 1.0 } else { -3.0 };
                let out = c.update(
                    &mut s,
                    &c.flux_command(0.9),
                    TorqueCommand::TorqueNm(torque),
                    omega_m,
                    measured,
                    Dq::default(),
                );
                measured = out.i_ref_ab;
                let (sin, cos) = libm::sincos(f64::from(out.theta_e_rad));
                let e = (f64::from(out.field.sin) - sin).abs().max((f64::from(out.field.cos) - cos).abs());
                if e > worst.0 {
                    worst = (e, omega_m);
                }
            }
        }
        eprintln!("IFOC field vs sin/cos(θ_e): worst abs. error {:.3e} at ω_m = {} rad/s", worst.0, worst.1);
        assert!(worst.0 <= 2.5e-6, "{worst:?}");
    }

    #[test]
    fn guard_bounds_slip_and_current_while_flux_is_zero() {
        let c = cfg();
        let mut s = c.state(0.0, 1.0);
        let out = c.update(
            &mut s,
            &c.flux_command(1.0),
            TorqueCommand::TorqueNm(1e6),
            0.0,
            AlphaBeta::default(),
            Dq::default(),
        );
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
            let exact = 1.0 - (-f64::from(scale) * x).exp();
            let rel = f64::from(s.flux_model_gain) / exact - 1.0;
            assert!(rel.abs() <= 1e-6, "{scale}: flux model gain off by {rel:e}");
        }
        // At scale 1 the motor's own numbers, bit for bit.
        let s = c.state(0.0, 1.0);
        assert_eq!((s.slip_gain, s.flux_model_gain), (c.slip_gain, c.flux_model_gain));
        // Anything but a finite positive scale is ignored.
        let mut s = c.state(0.0, 2.0);
        for bad in [0.0, -1.0, f32::NAN, f32::INFINITY] {
            c.set_rotor_resistance_scale(&mut s, bad);
            assert_eq!(s.rotor_resistance_scale(), 2.0);
        }
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
            let exact = 1.0 - (-f64::from(r / l) * x).exp();
            let rel = f64::from(s.flux_model_gain) / exact - 1.0;
            assert!(rel.abs() <= 1e-6, "ℓ {l}, r {r}: flux model gain off by {rel:e}");
            // Slip at i_d = 1 A, i_q = 1 A on the flux ℓ·L_m: the machine's r·R_r/(ℓ·L_r).
            let slip = f64::from(s.slip_gain) / (f64::from(l) * m.lm_h());
            let truth = f64::from(r) * m.rr_ohm() / (f64::from(l) * m.lr_h());
            assert!((slip / truth - 1.0).abs() <= 1e-6, "ℓ {l}, r {r}: slip {slip} of {truth}");
        }
        // At ℓ = 1 the motor's own numbers, bit for bit.
        let mut s = c.state(0.0, 1.0);
        c.set_inductance_scale(&mut s, 1.0);
        assert_eq!((s.slip_gain, s.flux_model_gain, s.lm_h), (c.slip_gain, c.flux_model_gain, c.lm_h));
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
