//! V/Hz control with stator-current feedback: the open-loop drive of fans and pumps, made
//! stable at light load — Hinkkanen, Tiitinen, Mölsä, Harnefors, "On the stability of
//! volts-per-hertz control for induction motors", IEEE J. Emerg. Sel. Topics Power
//! Electron. 10(2), 2022 (the method of motulator's `VHzCtrl` up to its 0.3 releases).
//!
//! Plain V/Hz turns a stator-flux vector at the reference frequency; at light load an
//! induction machine fed so has a poorly damped (often unstable) electromechanical mode
//! between 10 and 40 % of its base speed — the well-known light-load oscillation. The
//! method adds to the plain law, in the frame of the stator-flux reference ψ_s* (angle θ_s):
//!
//! * the **operating point**, the measured current low-pass filtered (`i_s0`, bandwidth
//!   [`ALPHA_I_RAD_S`]), and the slip it implies: the rotor flux `ψ_R0 = ψ_s* − L_σ·i_s0`
//!   and the slip of a current `i`, `ω_r(i) = R_R·Im{i·ψ_R0*}/|ψ_R0|²` (inverse-Γ
//!   parameters);
//! * **slip compensation and frequency damping**: `ω_s = ω_ref + ω_r0 + k_w·(ω_r0 − ω_r(i_s))`
//!   with `ω_r0` the slip low-pass filtered (bandwidth [`ALPHA_F_RAD_S`]) — the frequency moves
//!   against the dynamic part of the slip ([`K_W`]);
//! * **IR compensation (the voltage boost) and current feedback**:
//!   `u_s = R_s·(i_sd,nom + j·i_sq0) + j·ω_s·ψ_s* + k·(i_s0 − i_s)` with
//!   `k = k_u·L_σ·(α + j·ω_s)`, `α = R_R/L_M` ([`K_U`]) — a virtual impedance against the
//!   dynamic part of the current, which moves the oscillating mode's poles left.
//!
//! `k_u` and `k_w` are the configuration's ([`K_U`], [`K_W`] by default: the paper's); 0 and 0
//! is plain V/Hz with slip and IR compensation.
//!
//! The boost is no number to fit: it is `R_s` times the magnetizing current (and the load's
//! operating-point current), both from the motor file. The drive ([`crate::drive`]) runs the
//! law in its fast step (every PWM period) and, in its slow step, the frequency reference's
//! ramp, the current limit (the ramp turned back towards the rotor's speed while the
//! operating-point current exceeds the limit, stall prevention), the bus limit (a
//! decelerating ramp held while the link is above the regeneration limit) and the field
//! weakening (`ψ_s* = min(ψ_s,nom, u_max/|ω_s|)`).

use crate::frames::{AlphaBeta, Dq, SinCos};
use crate::motor::MotorParams;

/// The current feedback's default gain `k_u` (the paper's choice: the virtual impedance
/// `L_σ·(α + jω_s)` whole, which damps the oscillating mode over the whole speed range at
/// light load in the paper's analysis).
pub const K_U: f64 = 1.0;
/// The frequency feedback's default gain `k_w` (the paper's choice).
pub const K_W: f64 = 4.0;
/// The largest feedback gain accepted (the paper's analysis spans a few units).
pub const K_MAX: f64 = 20.0;
/// The operating-point current's low-pass bandwidth `α_i`, rad/s: well below the
/// electromechanical mode it must not follow (the paper's 2π·1 Hz).
pub const ALPHA_I_RAD_S: f64 = core::f64::consts::TAU;
/// The slip compensation's low-pass bandwidth `α_f`, rad/s (the paper's 2π·1 Hz).
pub const ALPHA_F_RAD_S: f64 = core::f64::consts::TAU;

/// The default ramp's share of the drive's torque: the frequency reference ramps at the
/// acceleration this share of the torque at the current limit gives the motor file's
/// inertia, leaving the rest for the load and the slip's transient.
pub const RAMP_TORQUE_SHARE: f64 = 0.1;

/// The default ramp of a drive on `motor` with rotor-flux reference `flux_ref_wb` and current
/// limit `i_max_a`, mechanical rad/s²: [`RAMP_TORQUE_SHARE`] of the torque at the current
/// limit (`1.5·p·(L_m²/L_r)·i_d·i_q`, i_d the flux's magnetizing current and i_q the rest of
/// the limit) on the motor file's inertia. Not finite (a flux beyond the limit): the
/// configuration refuses it.
pub fn default_ramp_rad_s2(motor: &MotorParams, flux_ref_wb: f64, i_max_a: f64) -> f64 {
    let i_d = flux_ref_wb / motor.lm_h();
    let i_q = libm::sqrt(i_max_a * i_max_a - i_d * i_d);
    let torque = 1.5 * f64::from(motor.pole_pairs()) * motor.lm_h() * motor.lm_h() / motor.lr_h() * i_d * i_q;
    RAMP_TORQUE_SHARE * torque / motor.j_kgm2()
}

/// The share of the pull-out slip the ramp's stall prevention allows ([`VhzConfig::pull_out_slip_rad_s`]):
/// the margin motulator's reference generator keeps to the breakdown torque (its `k_b`).
pub const PULL_OUT_MARGIN: f32 = 0.9;

/// The relative step in slip by which [`VhzConfig::beyond_breakdown`] tells, in field
/// weakening, the rising side of the torque from the falling: the check fires within half of
/// it of the breakdown's margin (the test measures where).
pub const BREAKDOWN_STEP: f32 = 0.01;

/// Why a V/Hz configuration was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VhzError {
    /// The sample period is not finite and positive, or the filters' bandwidths are not well
    /// below its rate.
    SamplePeriod,
    /// The ramp is not finite and positive.
    Ramp,
    /// A feedback gain (`k_u`, `k_w`) is not finite and within `[0, K_MAX]`.
    Gain,
    /// The stator-flux reference is not finite and positive.
    Flux,
    /// This build of the crate has no V/Hz law (its feature `vhz` is off: an image carries
    /// only the control law its drive runs).
    NotBuilt,
}

impl core::fmt::Display for VhzError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::SamplePeriod => {
                f.write_str("the V/Hz law's sample period must be finite, > 0 and below 0.1 s")
            }
            Self::Ramp => f.write_str("ramp_rad_s2 must be finite and > 0 (in f32 too, once per slow step)"),
            Self::Gain => write!(f, "k_u and k_w must be finite, ≥ 0 and at most {K_MAX}"),
            Self::Flux => f.write_str("the V/Hz law's stator flux (from flux_ref_wb) must be finite and > 0"),
            Self::NotBuilt => f.write_str(
                "this build has no V/Hz law (controller-core's feature `vhz`, the firmware's `vhz`)",
            ),
        }
    }
}

/// The law's configuration: the motor in the inverse-Γ form and the discretised gains,
/// validated at construction.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct VhzConfig {
    ts_s: f32,
    rs_ohm: f32,
    /// Inverse-Γ `R_R`, Ω.
    r_r_ohm: f32,
    /// Inverse-Γ `L_σ`, H.
    l_sigma_h: f32,
    /// `α = R_R/L_M`, 1/s.
    alpha_per_s: f32,
    /// `L_s = L_M + L_σ`, H: the no-load stator inductance (the magnetizing current of ψ_s*).
    ls_h: f32,
    /// The rated stator flux, Wb: at no load, the drive's rotor-flux reference ψ_r* × `L_s/L_m`.
    psi_s_nom_wb: f32,
    /// `α_i·T`, `α_f·T`: the filters' gains per sample.
    i_gain: f32,
    f_gain: f32,
    /// The ramp's change per slow step, mechanical rad/s.
    ramp_step_rad_s: f32,
    pole_pairs: f32,
    /// `L_r/L_m`: the T model's rotor flux is `ψ_R·L_r/L_m`.
    lr_over_lm: f32,
    /// The current feedback's and the frequency feedback's gains.
    k_u: f32,
    k_w: f32,
}

/// The raw layout ([`crate::raw`]): the fields in their order of declaration, as one array.
impl crate::raw::Field for VhzConfig {
    const NF: usize = <[f32; 14] as crate::raw::Field>::NF;
    const NU: usize = 0;
    fn put(&self, w: &mut crate::raw::Writer) {
        self.numbers().put(w);
    }
    #[inline(always)]
    fn get(r: &mut crate::raw::Reader<'_>) -> Self {
        let [
            ts_s,
            rs_ohm,
            r_r_ohm,
            l_sigma_h,
            alpha_per_s,
            ls_h,
            psi_s_nom_wb,
            i_gain,
            f_gain,
            ramp_step_rad_s,
            pole_pairs,
            lr_over_lm,
            k_u,
            k_w,
        ] = <[f32; 14]>::get(r);
        Self {
            ts_s,
            rs_ohm,
            r_r_ohm,
            l_sigma_h,
            alpha_per_s,
            ls_h,
            psi_s_nom_wb,
            i_gain,
            f_gain,
            ramp_step_rad_s,
            pole_pairs,
            lr_over_lm,
            k_u,
            k_w,
        }
    }
}

/// The slow step's plan for the fast steps: the ramp's frequency reference and the flux.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct VhzPlan {
    /// The ramp's speed reference in electrical rad/s (`p·ω_ref`).
    pub omega_ref_e_rad_s: f32,
    /// The stator-flux reference ψ_s*, Wb (weakened above base speed).
    pub psi_s_wb: f32,
    /// The magnetizing current of ψ_s* on the inductances in use, A (the IR compensation's
    /// d-axis current).
    pub i_sd_a: f32,
}

/// The law's state: the stator-flux reference's angle, the operating point.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct VhzState {
    /// The stator-flux reference's angle θ_s (sin, cos), turned every step.
    field: SinCos,
    /// θ_s, rad in `[-π, π)` (the field is made afresh from it at every slow step: the
    /// turning's rounding does not add up).
    theta_s_rad: f32,
    /// The operating-point current `i_s0` in the stator-flux frame, A.
    i0: Dq,
    /// The operating-point slip `ω_r0`, electrical rad/s.
    omega_r0_rad_s: f32,
    /// The stator frequency of the last step, electrical rad/s.
    omega_s_rad_s: f32,
}

/// What the slow step reads of the law's state ([`VhzState::report`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct VhzReport {
    /// The operating-point current in the stator-flux reference's frame, A.
    pub i0: Dq,
    /// The operating-point slip `ω_r0`, electrical rad/s.
    pub slip_rad_s: f32,
    /// The stator frequency of the last step, electrical rad/s.
    pub omega_s_rad_s: f32,
}

impl VhzConfig {
    /// The law for `motor`, stepped every `ts_s`, holding the rated rotor flux `flux_ref_wb`
    /// (T form, the drive's ψ_r*) at no load, its frequency reference ramped by `ramp_rad_s2`
    /// (mechanical) in slow steps of `t_slow_s`, with the feedback gains `[k_u, k_w]`.
    pub fn new(
        motor: &MotorParams,
        ts_s: f64,
        t_slow_s: f64,
        flux_ref_wb: f64,
        ramp_rad_s2: f64,
        [k_u, k_w]: [f64; 2],
    ) -> Result<Self, VhzError> {
        let ok = |x: f64| x.is_finite() && x > 0.0;
        if !(ok(ts_s) && ok(t_slow_s) && ts_s < 0.1 && ALPHA_I_RAD_S.max(ALPHA_F_RAD_S) * ts_s < 0.1) {
            return Err(VhzError::SamplePeriod);
        }
        if !ok(ramp_rad_s2) {
            return Err(VhzError::Ramp);
        }
        if !ok(flux_ref_wb) {
            return Err(VhzError::Flux);
        }
        if ![k_u, k_w].iter().all(|k| (0.0..=K_MAX).contains(k)) {
            return Err(VhzError::Gain);
        }
        let k = motor.lm_h() / motor.lr_h();
        let l_m = motor.lm_h() * k;
        let r_r = motor.rr_ohm() * k * k;
        let f = |x: f64| x as f32;
        let cfg = Self {
            ts_s: f(ts_s),
            rs_ohm: f(motor.rs_ohm()),
            r_r_ohm: f(r_r),
            l_sigma_h: f(motor.ls_h() - l_m),
            alpha_per_s: f(r_r / l_m),
            ls_h: f(motor.ls_h()),
            psi_s_nom_wb: f(flux_ref_wb * motor.ls_h() / motor.lm_h()),
            i_gain: f(ALPHA_I_RAD_S * ts_s),
            f_gain: f(ALPHA_F_RAD_S * ts_s),
            ramp_step_rad_s: f(ramp_rad_s2 * t_slow_s),
            pole_pairs: f32::from(motor.pole_pairs()),
            lr_over_lm: f(1.0 / k),
            k_u: f(k_u),
            k_w: f(k_w),
        };
        // Finite in f32 too: a ramp of 1e300 rad/s² was accepted, ramped at once on the host,
        // and refused by `DriveConfig::from_raw` in the firmware's build (found trying it).
        if !cfg.ramp_step_rad_s.is_finite() {
            return Err(VhzError::Ramp);
        }
        if !cfg.is_valid() {
            return Err(VhzError::Flux);
        }
        Ok(cfg)
    }

    /// Every value finite and positive, the gains within `[0, K_MAX]` (what
    /// [`VhzConfig::new`] made; a raw configuration is checked with it).
    pub fn is_valid(&self) -> bool {
        let [model @ .., k_u, k_w] = self.numbers();
        let gain = |k: f32| (0.0..=K_MAX as f32).contains(&k);
        model.iter().all(|&x| crate::num::finite_positive(x)) && gain(k_u) && gain(k_w)
    }

    fn numbers(&self) -> [f32; 14] {
        [
            self.ts_s,
            self.rs_ohm,
            self.r_r_ohm,
            self.l_sigma_h,
            self.alpha_per_s,
            self.ls_h,
            self.psi_s_nom_wb,
            self.i_gain,
            self.f_gain,
            self.ramp_step_rad_s,
            self.pole_pairs,
            self.lr_over_lm,
            self.k_u,
            self.k_w,
        ]
    }

    /// The rated stator flux, Wb.
    pub fn psi_s_nom_wb(&self) -> f32 {
        self.psi_s_nom_wb
    }

    /// The pull-out (breakdown) slip of the stator-flux-fed machine, electrical rad/s:
    /// `R_R/L_σ` (inverse-Γ), where the torque at constant ψ_s, `∝ ω_r/(1 + (ω_r·L_σ/R_R)²)`,
    /// peaks. Beyond it more slip gives less torque: the rotor falls out and the slip runs away.
    pub fn pull_out_slip_rad_s(&self) -> f32 {
        self.r_r_ohm / self.l_sigma_h
    }

    /// Whether the operating point's slip `slip_rad_s` at the rotor's electrical speed
    /// `omega_r_e_rad_s` is beyond [`PULL_OUT_MARGIN`] of the breakdown — where more slip
    /// (a higher stator frequency) gives less torque, and the rotor falls behind a ramp that
    /// runs on:
    ///
    /// * at the rated flux (`weakened` false: the law holds ψ_s), the pull-out slip `R_R/L_σ`
    ///   (inverse-Γ): the torque at constant ψ_s, `∝ x/(1 + x²)` with `x = ω_r·L_σ/R_R`,
    ///   peaks at `x = 1`;
    /// * in field weakening, motoring, the law holds the voltage instead
    ///   ([`VhzConfig::flux_within_voltage`]): the flux falls as the frequency rises, and the
    ///   torque at a given rotor speed peaks far below the pull-out slip — with no resistance,
    ///   where `ω_s·(1 − x²) = 2·ω_r·(1 + x²)`, a stator frequency about twice the rotor's.
    ///   The machine's steady state at a fixed voltage, resistance and leakage in
    ///   (`voltage_fed_torque`), judged by a step of [`BREAKDOWN_STEP`] in slip:
    ///   beyond where the torque stops rising. Without it, a fan overloading in field
    ///   weakening was held by none of the limits, and its rotor fell to rest behind a ramp
    ///   at base speed. Generating, the flux rises as the slip lowers the stator frequency:
    ///   the pull-out slip alone.
    ///
    /// The margin: the slip judged as `ω_r/PULL_OUT_MARGIN` (beyond the margin's share of the
    /// breakdown slip).
    pub fn beyond_breakdown(&self, slip_rad_s: f32, omega_r_e_rad_s: f32, weakened: bool) -> bool {
        let w_r = slip_rad_s.abs() / PULL_OUT_MARGIN;
        let motoring = slip_rad_s * omega_r_e_rad_s >= 0.0;
        let w_re = omega_r_e_rad_s.abs();
        w_r >= self.pull_out_slip_rad_s()
            || (weakened
                && motoring
                && self.voltage_fed_torque(w_re, w_r * (1.0 + BREAKDOWN_STEP))
                    <= self.voltage_fed_torque(w_re, w_r))
    }

    /// The machine's torque at the rotor's electrical speed `w_re` and the slip `w_r`
    /// (electrical rad/s, motoring) fed a fixed stator voltage, over `1.5·p·u²` (a shape, not a
    /// torque): the inverse-Γ circuit at steady state per ampere of stator current — the rotor
    /// flux `ψ_R = R_R/(α + jω_r)`, the stator flux `ψ_s = L_σ + ψ_R`, the voltage
    /// `v = R_s + jω_s·ψ_s` — the torque `−Im ψ_R` per ampere squared, over `|v|²`. Out of
    /// line: one copy for its two calls (the firmware's flash).
    #[inline(never)]
    fn voltage_fed_torque(&self, w_re: f32, w_r: f32) -> f32 {
        let (a, b) = (self.alpha_per_s, w_r);
        let d = a * a + b * b;
        let (psi_d, psi_q) = (self.r_r_ohm * a / d, -self.r_r_ohm * b / d);
        let w_s = w_re + w_r;
        let (v_d, v_q) = (self.rs_ohm - w_s * psi_q, w_s * (self.l_sigma_h + psi_d));
        -psi_q / (v_d * v_d + v_q * v_q)
    }

    /// The stator flux the voltage `u_max_v` holds at the stator frequency `omega_s_rad_s` with
    /// the operating point's current `i0` (the stator-flux reference's frame), Wb, at most the
    /// rated flux: the steady state `u = R_s·i_s0 + j·ω_s·ψ_s` within `|u| ≤ u_max` — the
    /// field weakening. Without the resistance's drop (`ψ_s = u_max/ω_s`) the law asked more
    /// voltage than the modulator has where `R_s·i` is a sizeable share of it (a small
    /// motor's), its flux fell short of the reference and its slip estimate with it. Zero
    /// where the drop alone takes the voltage.
    pub fn flux_within_voltage(&self, u_max_v: f32, omega_s_rad_s: f32, i0: Dq) -> f32 {
        let (u_d, u_q) = (self.rs_ohm * i0.d, self.rs_ohm * i0.q);
        let room = crate::num::sqrt_f32((u_max_v * u_max_v - u_d * u_d).max(0.0));
        // The q-axis drop adds to the back-EMF when the current turns with the field (motoring).
        let drop = if omega_s_rad_s < 0.0 { -u_q } else { u_q };
        let psi = (room - drop).max(0.0) / omega_s_rad_s.abs().max(1e-3);
        psi.min(self.psi_s_nom_wb)
    }

    /// The ramp's change per slow step, mechanical rad/s.
    pub fn ramp_step_rad_s(&self) -> f32 {
        self.ramp_step_rad_s
    }

    /// Pole pairs.
    pub fn pole_pairs(&self) -> f32 {
        self.pole_pairs
    }

    /// The plan for speed reference `omega_ref_rad_s` (the ramp's, mechanical) with stator
    /// flux `psi_s_wb`, on the inductances `l_scale` × the motor's.
    pub fn plan(&self, omega_ref_rad_s: f32, psi_s_wb: f32, l_scale: f32) -> VhzPlan {
        VhzPlan {
            omega_ref_e_rad_s: self.pole_pairs * omega_ref_rad_s,
            psi_s_wb,
            i_sd_a: psi_s_wb / (self.ls_h * l_scale),
        }
    }

    /// The state taking over a magnetized machine: the stator-flux frame at the field angle
    /// `theta_rad` the magnetizing current was held at, the operating point the current
    /// `i_ab` measured there, with no slip.
    pub fn start(&self, theta_rad: f32, i_ab: AlphaBeta) -> VhzState {
        let field = SinCos::new(theta_rad);
        VhzState { field, theta_s_rad: theta_rad, i0: i_ab.park(field), ..VhzState::default() }
    }

    /// One sample: `i_ab` the measured stator current. Returns the stator voltage reference
    /// (stationary frame, V); the state moves on to the next step (θ_s turned by `ω_s·T`, the
    /// operating point's filters). The equations of the module docs.
    #[inline]
    pub fn step(&self, s: &mut VhzState, plan: &VhzPlan, i_ab: AlphaBeta) -> AlphaBeta {
        let field = s.field;
        let i = i_ab.park(field);
        let (l_sigma, psi_s, i0) = (self.l_sigma_h, plan.psi_s_wb, s.i0);
        // The operating point's rotor flux ψ_R0 = ψ_s* − L_σ·i_s0 and the slip of the
        // measured current.
        let psi_r = Dq { d: psi_s - l_sigma * i0.d, q: -l_sigma * i0.q };
        let psi_r2 = (psi_r.d * psi_r.d + psi_r.q * psi_r.q).max(1e-6);
        let omega_r = self.r_r_ohm * (i.q * psi_r.d - i.d * psi_r.q) / psi_r2;
        // Slip compensation and the frequency's damping.
        let w0 = s.omega_r0_rad_s;
        let omega_s = plan.omega_ref_e_rad_s + w0 + self.k_w * (w0 - omega_r);
        // IR compensation and the current feedback k·(i_s0 − i_s), k = k_u·L_σ·(α + jω_s).
        let e = Dq { d: i0.d - i.d, q: i0.q - i.q };
        let (kr, ki) = (self.k_u * l_sigma * self.alpha_per_s, self.k_u * l_sigma * omega_s);
        let u = Dq {
            d: self.rs_ohm * plan.i_sd_a + kr * e.d - ki * e.q,
            q: self.rs_ohm * i0.q + omega_s * psi_s + kr * e.q + ki * e.d,
        };
        // The state: the filters, the frame turned (within the rotation's accurate range).
        s.i0 = Dq { d: i0.d + self.i_gain * (i.d - i0.d), q: i0.q + self.i_gain * (i.q - i0.q) };
        s.omega_r0_rad_s = w0 + self.f_gain * (omega_r - w0);
        let delta = (omega_s * self.ts_s).clamp(-SinCos::MAX_ROTATION_RAD, SinCos::MAX_ROTATION_RAD);
        s.field = field.rotated(delta);
        s.theta_s_rad += delta;
        s.omega_s_rad_s = omega_s;
        u.inverse_park(field)
    }
}

impl VhzState {
    /// The frame made afresh from its angle (once per slow period: the rounding of the
    /// turns does not add up), the angle wrapped.
    pub fn renew_field(&mut self) {
        self.theta_s_rad = crate::frames::wrap_angle(self.theta_s_rad);
        self.field = SinCos::new(self.theta_s_rad);
    }

    /// The operating-point current in the stationary frame, A.
    pub fn i0_ab(&self) -> AlphaBeta {
        self.i0.inverse_park(self.field)
    }

    /// What the slow step reads: the operating point, the slip, the stator frequency.
    pub fn report(&self) -> VhzReport {
        VhzReport { i0: self.i0, slip_rad_s: self.omega_r0_rad_s, omega_s_rad_s: self.omega_s_rad_s }
    }

    /// The operating-point slip `ω_r0`, electrical rad/s.
    pub fn slip_rad_s(&self) -> f32 {
        self.omega_r0_rad_s
    }

    /// θ_s, rad.
    pub fn theta_s_rad(&self) -> f32 {
        self.theta_s_rad
    }

    /// The rotor flux of the operating point in the T model's terms (`|ψ_s* − L_σ·i_s0|`,
    /// inverse-Γ, × `L_r/L_m`), Wb: the drive's ψ_r.
    pub fn psi_r_wb(&self, cfg: &VhzConfig, plan: &VhzPlan) -> f32 {
        let d = plan.psi_s_wb - cfg.l_sigma_h * self.i0.d;
        let q = cfg.l_sigma_h * self.i0.q;
        crate::num::sqrt_f32(d * d + q * q) * cfg.lr_over_lm
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn motor() -> MotorParams {
        MotorParams::delorenzo_dl10115a1().unwrap()
    }

    /// The state equations of the inverse-Γ machine in the stator-flux reference's frame at
    /// constant speed: the law's steady state at no load holds the rated flux and turns at
    /// the reference (no slip), and with load it compensates the slip — the rotor turns at
    /// the reference within the filters' settling.
    #[test]
    fn the_law_holds_the_flux_and_compensates_the_slip() {
        let m = motor();
        let ts = 1e-4;
        let cfg = VhzConfig::new(&m, ts, 1e-3, 0.9, 100.0, [K_U, K_W]).unwrap();
        let k = m.lm_h() / m.lr_h();
        let (l_m, r_r, l_s, r_s) = (m.lm_h() * k, m.rr_ohm() * k * k, m.ls_h(), m.rs_ohm());
        let l_sigma = l_s - l_m;
        for &(w_ref_m, load_nm) in &[(100.0f64, 0.0f64), (100.0, 0.5), (-150.0, -0.5)] {
            let plan = cfg.plan(w_ref_m as f32, cfg.psi_s_nom_wb(), 1.0);
            let mut s = cfg.start(0.0, AlphaBeta::default());
            // Stator flux ψ_s and rotor flux ψ_R (stationary frame), the rotor speed set so
            // that the machine's torque carries `load_nm` (a stiff shaft: a speed loop of the
            // test's own holding the torque).
            let (mut psi_s, mut psi_rr) = ([0.0f64; 2], [0.0f64; 2]);
            let mut w_m = w_ref_m;
            let p = f64::from(m.pole_pairs());
            for _ in 0..60_000 {
                let i = [(psi_s[0] - psi_rr[0]) / l_sigma, (psi_s[1] - psi_rr[1]) / l_sigma];
                let v = cfg.step(&mut s, &plan, AlphaBeta { alpha: i[0] as f32, beta: i[1] as f32 });
                let u = [f64::from(v.alpha), f64::from(v.beta)];
                let w = p * w_m;
                for _ in 0..10 {
                    let i = [(psi_s[0] - psi_rr[0]) / l_sigma, (psi_s[1] - psi_rr[1]) / l_sigma];
                    let h = ts / 10.0;
                    let ds = [u[0] - r_s * i[0], u[1] - r_s * i[1]];
                    let dr = [
                        r_r * i[0] - (r_r / l_m) * psi_rr[0] - w * psi_rr[1],
                        r_r * i[1] - (r_r / l_m) * psi_rr[1] + w * psi_rr[0],
                    ];
                    psi_s = [psi_s[0] + h * ds[0], psi_s[1] + h * ds[1]];
                    psi_rr = [psi_rr[0] + h * dr[0], psi_rr[1] + h * dr[1]];
                }
                let i = [(psi_s[0] - psi_rr[0]) / l_sigma, (psi_s[1] - psi_rr[1]) / l_sigma];
                let torque = 1.5 * p * (psi_rr[0] * i[1] - psi_rr[1] * i[0]);
                // The shaft: slowly to the speed where the torque is the load's.
                w_m += 1e-4 * (torque - load_nm) / 0.05 * 10.0;
            }
            let psi = (psi_s[0].powi(2) + psi_s[1].powi(2)).sqrt();
            assert!(
                (psi / f64::from(cfg.psi_s_nom_wb()) - 1.0).abs() < 0.03,
                "ψ_s {psi} at {w_ref_m}, {load_nm}"
            );
            assert!(
                (w_m - w_ref_m).abs() < 0.01 * w_ref_m.abs(),
                "ω_m {w_m} for {w_ref_m} under {load_nm} N·m"
            );
        }
    }

    /// The torque of `m` fed a stator voltage of magnitude `u_v` at the rotor's electrical
    /// speed `w_re` and the slip `w_r` (electrical rad/s), N·m: the T-equivalent circuit at
    /// steady state (the resistance, the leakages and the magnetizing branch all in), as
    /// `hil_sim::envelope::physical_limit_nm` takes it — per ampere of stator current, scaled
    /// to the voltage.
    fn voltage_fed_torque_nm(m: &MotorParams, u_v: f64, w_re: f64, w_r: f64) -> f64 {
        let (rs, rr, ls, lr, lm) = (m.rs_ohm(), m.rr_ohm(), m.ls_h(), m.lr_h(), m.lm_h());
        // ψ_s and V per ampere of stator current along the real axis, complex as (re, im).
        let den = (rr, w_r * lr);
        let d2 = den.0 * den.0 + den.1 * den.1;
        // I_r = −jω_r·L_m/(R_r + jω_r·L_r).
        let i_r = (-w_r * lm * den.1 / d2, -w_r * lm * den.0 / d2);
        let psi_s = (ls + lm * i_r.0, lm * i_r.1);
        let w_s = w_re + w_r;
        let v = (rs - w_s * psi_s.1, w_s * psi_s.0);
        let t1 = -1.5 * f64::from(m.pole_pairs()) * psi_s.1;
        t1 * u_v * u_v / (v.0 * v.0 + v.1 * v.1)
    }

    /// The field weakening's breakdown check against the breakdown of the whole machine: on
    /// three motors (drive.toml's 300 W with its 16 Ω stator, motulator's 2.2 kW, Krause's
    /// 3 300 V machine), a fixed voltage and rotor speeds where it weakens the flux to 1/1.2 …
    /// 1/3 of the rated, the check first fires at [`PULL_OUT_MARGIN`] of the slip of the
    /// machine's largest torque, within the [`BREAKDOWN_STEP`] it judges by (it never lets the
    /// ramp past the breakdown), where the machine gives at least 99 % of that torque (the
    /// margin costs little: the torque is flat at its peak).
    #[test]
    fn the_weakened_breakdown_check_fires_just_before_the_machines_breakdown() {
        let motors = [
            (motor(), 0.9),
            (MotorParams::new(3.7, 2.1, 0.245, 0.224, 0.224, 2, 0.015, 0.0).unwrap(), 0.77),
            (MotorParams::new(0.262, 0.187, 0.1462, 0.1462, 0.143, 2, 11.06, 0.0).unwrap(), 7.0),
        ];
        for (m, flux) in motors {
            let cfg = VhzConfig::new(&m, 1e-4, 1e-3, flux, 100.0, [K_U, K_W]).unwrap();
            let psi_nom = f64::from(cfg.psi_s_nom_wb());
            let w_pull = f64::from(cfg.pull_out_slip_rad_s());
            let u_v = 100.0;
            for k in [1.2, 1.5, 2.0, 3.0] {
                let w_re = k * u_v / psi_nom;
                let slips = (1..=20_000).map(|n| f64::from(n) * 1e-4 * w_pull);
                let (w_pk, t_pk) = slips
                    .clone()
                    .map(|w| (w, voltage_fed_torque_nm(&m, u_v, w_re, w)))
                    .fold((0.0, f64::MIN), |a, b| if b.1 > a.1 { b } else { a });
                let w_c = slips.clone().find(|&w| cfg.beyond_breakdown(w as f32, w_re as f32, true)).unwrap();
                let t_c = voltage_fed_torque_nm(&m, u_v, w_re, w_c);
                eprintln!(
                    "R_s {} Ω, flux 1/{k}: fires at slip {w_c:.2} rad/s, {:.4} of the breakdown's \
                     {w_pk:.2}, torque {:.4} of the largest",
                    m.rs_ohm(),
                    w_c / w_pk,
                    t_c / t_pk
                );
                let margin = f64::from(PULL_OUT_MARGIN);
                let share = w_c / w_pk;
                assert!(share <= margin && share >= margin * (1.0 - f64::from(BREAKDOWN_STEP)), "{share}");
                assert!(t_c >= 0.99 * t_pk, "{t_c} of {t_pk}");
                // Generating, the flux rises as the frequency falls: the pull-out slip alone.
                assert!(!cfg.beyond_breakdown(-(w_c as f32), w_re as f32, true));
            }
        }
    }

    /// The field weakening's flux asks the law's steady-state voltage `R_s·i_s0 + jω_s·ψ_s`
    /// of exactly the voltage there is, motoring and generating, in both directions — and
    /// the rated flux where there is room.
    #[test]
    fn the_weakened_flux_asks_the_voltage_there_is() {
        let cfg = VhzConfig::new(&motor(), 1e-4, 1e-3, 0.9, 100.0, [K_U, K_W]).unwrap();
        let (rs, u_max) = (cfg.rs_ohm, 160.0f32);
        for (w, i0) in [
            (400.0f32, Dq { d: 0.7, q: 1.5 }),
            (400.0, Dq { d: 0.7, q: -1.5 }),
            (-400.0, Dq { d: 0.7, q: -1.5 }),
            (-300.0, Dq { d: 0.6, q: 2.0 }),
        ] {
            let psi = cfg.flux_within_voltage(u_max, w, i0);
            assert!(psi < cfg.psi_s_nom_wb(), "{psi}");
            let u = (rs * i0.d).hypot(rs * i0.q + w * psi);
            assert!((u / u_max - 1.0).abs() < 1e-5, "{u} V at {w} rad/s, {i0:?}");
        }
        assert_eq!(cfg.flux_within_voltage(u_max, 50.0, Dq { d: 0.7, q: 1.5 }), cfg.psi_s_nom_wb());
        // The drop alone beyond the voltage: no flux.
        assert_eq!(cfg.flux_within_voltage(10.0, 400.0, Dq { d: 0.7, q: 1.5 }), 0.0);
    }

    #[test]
    fn bad_inputs_are_named() {
        let m = motor();
        let k = [K_U, K_W];
        assert_eq!(VhzConfig::new(&m, 0.0, 1e-3, 0.9, 100.0, k), Err(VhzError::SamplePeriod));
        assert_eq!(VhzConfig::new(&m, 1e-4, 1e-3, 0.9, f64::NAN, k), Err(VhzError::Ramp));
        assert_eq!(VhzConfig::new(&m, 1e-4, 1e-3, 0.9, 1e300, k), Err(VhzError::Ramp));
        assert_eq!(VhzConfig::new(&m, 1e-4, 1e-3, 1e300, 100.0, k), Err(VhzError::Flux));
        assert_eq!(VhzConfig::new(&m, 1e-4, 1e-3, 0.0, 100.0, k), Err(VhzError::Flux));
        for bad in [[-1.0, 4.0], [1.0, f64::NAN], [1.0, K_MAX + 1.0]] {
            assert_eq!(VhzConfig::new(&m, 1e-4, 1e-3, 0.9, 100.0, bad), Err(VhzError::Gain), "{bad:?}");
        }
        assert!(VhzConfig::new(&m, 1e-4, 1e-3, 0.9, 100.0, k).unwrap().is_valid());
        // Plain V/Hz (no feedback) is a valid law.
        assert!(VhzConfig::new(&m, 1e-4, 1e-3, 0.9, 100.0, [0.0, 0.0]).unwrap().is_valid());
        assert!(!VhzConfig::default().is_valid());
    }
}
