//! The validated, discretised configuration ([`DriveConfig`]): made from a [`DriveSpec`] on
//! the host, carried to the target as plain numbers ([`crate::raw`]) and checked there
//! without design arithmetic.

use super::spec::*;
use crate::current::CurrentControllerConfig;
use crate::encoder::SPEED_WINDOW_READS;
use crate::envelope::EnvelopeConfig;
use crate::fault::FaultSet;
use crate::frames::{Dq, SinCos};
use crate::ifoc::IfocConfig;
use crate::magnetics::MagnetizingChord;
use crate::mras::{MrasConfig, MrasError};
use crate::observer::{CORRECTION_PER_SAMPLE_MAX, ObserverConfig, ObserverError};
use crate::raw;
use crate::speed::{PositionConfig, SpeedControllerConfig};
use crate::supervisor::encoder::{ENCODER_ACCEL_FACTOR, EncoderLimits};
use crate::supervisor::limits::{BrakeLevels, Limits, abs_bits};
use crate::supervisor::motion::MotionLimits;
use crate::supervisor::motion::{FOLLOWING_PROGRESS_FRACTION, STALL_SPEED_FRACTION};
use crate::supervisor::phases::PhaseLimits;
use crate::supervisor::rest::RestLimits;
use crate::supervisor::thermal::ThermalConfig;
use crate::svpwm;
use crate::vhz::{VhzConfig, VhzError};
use num_complex::Complex32;

crate::raw::raw_struct! {
    /// Validated, discretised drive configuration. Its fields' order is its raw layout
    /// ([`crate::raw`]: each field's numbers in turn, the floats and the integers on their own
    /// sequences): a new field is its one line here and its value in [`DriveConfig::new`].
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct DriveConfig {
        pub(super) current: CurrentControllerConfig<f32>,
        pub(super) current_frame: CurrentFrame,
        /// The q current the slip is turned on.
        pub(super) slip_current: SlipCurrent,
        /// The control law is V/Hz (`control`'s tag, within the fast step's load reach of
        /// the drive's address: read every period, where `control` at the end cost address
        /// arithmetic).
        pub(super) vhz_on: bool,
        pub(super) ifoc: IfocConfig,
        /// The rotor-resistance adaptation.
        pub(super) mras: MrasConfig,
        pub(super) speed: SpeedControllerConfig,
        pub(super) position: PositionConfig,
        pub(super) envelope: EnvelopeConfig,
        /// d-axis current of the rated flux ψ_r*/L_m (limited to the current limit), A.
        pub(super) i_d_rated_a: f32,
        /// Running when ψ̂_r reaches this fraction of L_m·i_d*.
        pub(super) magnetized_fraction: f32,
        /// The field-weakening voltage target as a fraction of V_dc/√3.
        pub(super) voltage_margin: f32,
        /// The current trim's integral gain per slow step, 1 (bandwidth·T_slow).
        pub(super) trim_gain: f32,
        /// The current loops' back-calculation rate at the voltage limit, per fast step: a PI
        /// without a lag moves its integrator by this share of what the modulator took off
        /// its request ([`CurrentControllerConfig::track`]), `1 − e^(−T_s/T_slow)` — a tracking
        /// time constant of one slow period, discretised exactly. The plan steps the
        /// references once per slow period, and the proportional kick `k_p·Δi` of a step
        /// lasts the few fast periods the current takes to catch up; tracking at once (`T_t = T_s`) handed the whole kick to the
        /// integrator, which then lay below the back-EMF by as much (member 010 of the
        /// population, 153 kW at twice its base speed: a 20 A step at 4.51 V/A, 90 V, and
        /// the current ran away into a false `SwitchOpen`). A limit that lasts many slow
        /// periods (the back-EMF outgrowing the bus through an acceleration) is followed
        /// within a few of them, as by tracking.
        pub(super) tracking_rate: f32,
        /// Dead time as a fraction of the PWM period (0: no compensation).
        pub(super) dead_time_duty: f32,
        /// The highest duty the modulator gives a phase ([`DriveSpec::duty_max`]): also the
        /// fraction of the measured bus the loops, the envelope and the checks count on.
        pub(super) duty_max: f32,
        /// The highest duty that leaves a phase its current sample, `1 − 2·window/T` less the
        /// dead-time compensation added after it (1: no sampling window): `duty_max` without
        /// overmodulation, below it with ([`DriveSpec::overmodulation`]).
        pub(super) duty_sampled: f32,
        /// Half-width of the dead-time compensation's ramp around zero current, A.
        pub(super) dead_time_band_a: f32,
        /// Bus voltage at which the regeneration limit starts ([`REGEN_LIMIT_START`]), V.
        pub(super) regen_start_v: f32,
        /// Reciprocal of the regeneration limit's span, 1/V.
        pub(super) inv_regen_span_v: f32,
        /// The voltage-margin regulator's integral gain per slow step, 1
        /// ([`DriveSpec::voltage_regulator_bandwidth_rad_s`]·T_slow).
        pub(super) voltage_gain: f32,
        /// … and the fastest regulator's ([`VOLTAGE_REGULATOR_BANDWIDTH_RAD_S`]·T_slow): the
        /// gain an acceleration at the envelope's torque needs, whatever the rotor.
        pub(super) voltage_gain_max: f32,
        /// The field angle is advanced by ω_e times this for the delay between sampling and the
        /// voltage's application, s ([`VOLTAGE_DELAY_PERIODS`]·T).
        pub(super) delay_s: f32,
        /// The stator's impedance at the field's frequency as the loops see it, the back-EMF
        /// fed forward: `R_s` (Ω) and `σL_s` (H), for the stationary-frame references'
        /// precompensation ([`DriveConfig::reference_gain`]) and the field-frame loops'
        /// decoupling ([`DriveConfig::decoupling_v`]).
        pub(super) stator_impedance: [f32; 2],
        /// The field-frame loops' decoupling inductance, H: `σL_s` with
        /// [`DriveSpec::current_decoupling`] in the synchronous frame, else 0
        /// ([`DriveConfig::decoupling_v`]).
        pub(super) decoupling_h: f32,
        pub(super) ts_s: f32,
        /// [`FLUX_LAG_FRACTION`] × the motor's inertia, kg·m²: the flux's fall time in field
        /// weakening is this × |ω| / the envelope's torque (`Drive::slow_loops`).
        pub(super) flux_lag_j_kgm2: f32,
        /// The shortest flux fall time, s: [`FLUX_FALL_SLOW_PERIODS`] slow periods.
        pub(super) flux_fall_time_min_s: f32,
        /// Half the encoder speed reading's resolution, rad/s
        /// ([`DriveSpec::speed_resolution_rad_s`]): the band within which the present-flux
        /// limit's speed holds (`SlowRun::omega_limit_rad_s`).
        pub(super) speed_hold_band_rad_s: f32,
        /// Slow steps of Magnetizing without reaching the running flux before
        /// [`Fault::NoMotorCurrent`].
        pub(super) magnetizing_steps_max: u32,
        pub(super) slow_divider: u16,
        /// The fast steps to the next slow tick at the period that adopts the slow step's
        /// plan: `slow_divider − 1 −` [`plan_delay_periods`] (`Drive::step`; stored so, the
        /// fast step compares it with its count as it is).
        pub(super) adopt_at: u16,
        /// The instant limits ([`crate::supervisor::limits`]).
        pub(super) limits: Limits,
        /// The motion checks' levels ([`crate::supervisor::motion`]).
        pub(super) motion: MotionLimits,
        /// The brake chopper's levels (`f32::MAX` without a chopper: never on).
        pub(super) brake: BrakeLevels,
        /// Thermal models: 1/I_rated² (per A² of |i_αβ|²/2, the RMS phase current squared), the
        /// update gain `1 − e^(−N·T_slow/τ)` and the trip level `overload_factor²` (`f32::MAX`
        /// without a limit) — motor, then inverter.
        pub(super) motor_thermal: ThermalConfig,
        pub(super) inverter_thermal: ThermalConfig,
        /// Fast steps with the voltage request outside the hexagon before the trip.
        pub(super) saturation_steps: u32,
        /// The encoder's checks ([`crate::supervisor::encoder`]).
        pub(super) encoder: EncoderLimits,
        /// Sensorless: the flying start's search, slow steps at the start of magnetizing
        /// (one `T_r`, at least [`SEARCH_WINDOWS_MIN`] windows; 0 with an encoder) and the
        /// slow steps of its window (the most that keep the field's turn per window within
        /// [`SEARCH_TURN_MAX_RAD`] at the overspeed level).
        pub(super) search_slow_steps: u32,
        pub(super) search_span: u32,
        /// Slow steps a controlled stop may take before the bridge goes off anyway.
        pub(super) stop_slow_steps: u32,
        /// The open-phase and stuck-switch checks ([`crate::supervisor::phases`]).
        pub(super) phases: PhaseLimits,
        /// The faults answered by a controlled stop.
        pub(super) stop_on: FaultSet,
        /// The rotor at rest ([`crate::supervisor::rest`]).
        pub(super) rest: RestLimits,
        /// The speed's source: the encoder, the observer, or the encoder with the observer
        /// beside it ([`SpeedFeedback`]).
        pub(super) source: SpeedSource,
        /// The control law: vector control, or V/Hz with its configuration. Last: the vector
        /// drive's fast step reaches the fields it reads from the drive's address without
        /// address arithmetic (placed before the field orientation, its 60 B cost the
        /// firmware's interrupt 10 instructions per period).
        pub(super) control: ControlLaw,
        /// The magnetizing curve the slow step follows (a linear motor's: off). After the
        /// control law: the slow step alone reads it.
        pub(super) magnetizing: MagnetizingChord,
    }
}

impl raw::Field for CurrentFrame {
    const NF: usize = 0;
    const NU: usize = 1;
    fn put(&self, w: &mut raw::Writer) {
        w.u(match self {
            CurrentFrame::Stationary => 0,
            CurrentFrame::Synchronous => 1,
        });
    }
    #[inline(always)]
    fn get(r: &mut raw::Reader<'_>) -> Self {
        match r.u() {
            0 => CurrentFrame::Stationary,
            1 => CurrentFrame::Synchronous,
            _ => {
                r.bad = true;
                CurrentFrame::Stationary
            }
        }
    }
}

impl raw::Field for SlipCurrent {
    const NF: usize = 0;
    const NU: usize = 1;
    fn put(&self, w: &mut raw::Writer) {
        w.u(match self {
            SlipCurrent::Reference => 0,
            SlipCurrent::Measured => 1,
        });
    }
    #[inline(always)]
    fn get(r: &mut raw::Reader<'_>) -> Self {
        match r.u() {
            0 => SlipCurrent::Reference,
            1 => SlipCurrent::Measured,
            _ => {
                r.bad = true;
                SlipCurrent::Reference
            }
        }
    }
}

/// The control law ([`Control`], with the V/Hz law's configuration where it has one).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum ControlLaw {
    /// Field-oriented vector control.
    Vector,
    /// V/Hz ([`crate::vhz`]).
    VHz(VhzConfig),
}

/// A tag (0: vector control, 1: V/Hz) and the V/Hz law's numbers (zeros without one: a
/// fixed layout).
impl raw::Field for ControlLaw {
    const NF: usize = <VhzConfig as raw::Field>::NF;
    const NU: usize = 1 + <VhzConfig as raw::Field>::NU;
    fn put(&self, w: &mut raw::Writer) {
        let (tag, cfg) = match self {
            ControlLaw::Vector => (0, VhzConfig::default()),
            ControlLaw::VHz(v) => (1, *v),
        };
        w.u(tag);
        cfg.put(w);
    }
    #[inline(always)]
    fn get(r: &mut raw::Reader<'_>) -> Self {
        let tag = r.u();
        let cfg = VhzConfig::get(r);
        match tag {
            0 => ControlLaw::Vector,
            1 if cfg!(feature = "vhz") && cfg.is_valid() => ControlLaw::VHz(cfg),
            _ => {
                r.bad = true;
                ControlLaw::Vector
            }
        }
    }
}

/// Where the drive's speed and field angle come from ([`SpeedFeedback`], with the observer's
/// configuration where it has one).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum SpeedSource {
    /// The encoder.
    Encoder,
    /// The observer ([`SpeedFeedback::Sensorless`]).
    Observer(ObserverConfig),
    /// The encoder, the observer beside it ([`SpeedFeedback::EncoderRideThrough`]).
    RideThrough(ObserverConfig),
}

impl SpeedSource {
    /// The observer, where the drive runs one.
    #[inline]
    pub(super) fn observer(&self) -> Option<&ObserverConfig> {
        if !cfg!(feature = "observer") {
            return None; // not in this build: none of its code is linked
        }
        match self {
            SpeedSource::Encoder => None,
            SpeedSource::Observer(o) | SpeedSource::RideThrough(o) => Some(o),
        }
    }

    /// No encoder at all.
    #[inline]
    pub(super) fn sensorless(&self) -> bool {
        cfg!(feature = "observer") && matches!(self, SpeedSource::Observer(_))
    }

    /// An encoder fault is ridden through on the observer.
    #[inline]
    pub(super) fn rides_through(&self) -> bool {
        cfg!(feature = "observer") && matches!(self, SpeedSource::RideThrough(_))
    }
}

/// A tag (0: the encoder, 1: the observer, 2: the encoder with the observer beside it) and
/// the observer's numbers (zeros without one: a fixed layout).
impl raw::Field for SpeedSource {
    const NF: usize = <ObserverConfig as raw::Field>::NF;
    const NU: usize = 1 + <ObserverConfig as raw::Field>::NU;
    fn put(&self, w: &mut raw::Writer) {
        w.u(match self {
            SpeedSource::Encoder => 0,
            SpeedSource::Observer(_) => 1,
            SpeedSource::RideThrough(_) => 2,
        });
        self.observer().copied().unwrap_or_default().put(w);
    }
    #[inline(always)]
    fn get(r: &mut raw::Reader<'_>) -> Self {
        let tag = r.u();
        let cfg = ObserverConfig::get(r);
        match tag {
            0 => SpeedSource::Encoder,
            1 if cfg!(feature = "observer") && cfg.is_valid() => SpeedSource::Observer(cfg),
            2 if cfg!(feature = "observer") && cfg.is_valid() => SpeedSource::RideThrough(cfg),
            _ => {
                r.bad = true;
                SpeedSource::Encoder
            }
        }
    }
}

impl raw::Field for FaultSet {
    const NF: usize = 0;
    const NU: usize = 1;
    fn put(&self, w: &mut raw::Writer) {
        w.u(self.0);
    }
    #[inline(always)]
    fn get(r: &mut raw::Reader<'_>) -> Self {
        FaultSet(r.u())
    }
}

/// The flying start's search spans at least this many windows (the fit needs three; more
/// average the sensors' noise on a motor whose `T_r` is a few slow periods).
pub const SEARCH_WINDOWS_MIN: u32 = 6;
/// The most the field may turn in one window of the flying start's search at the overspeed
/// level, rad: the fit's angle is told apart from its alias up to π; half of it leaves the
/// margin. Windows of several slow periods average the current sensors' noise, which on
/// windows of one slow period moved drive.toml's reading of a rotor at 1.8 × base speed by
/// several percent (found trying the flying start).
pub const SEARCH_TURN_MAX_RAD: f64 = core::f64::consts::FRAC_PI_2;

/// The flying start's search takes a rotor it reads turning ([`crate::speed_search`]: a turn
/// the windows' noise does not explain) as turning only from this much over the transient's
/// time constant `T_r` up, rad (`|ω_e|·T_r`). Slower than that the rotor is magnetized as at
/// rest: the field held still builds in it to `1/√(1 + (ω_e·T_r)²)` of the target at the
/// least (`1/√5` here), and the observer's adaptation takes the speed from there.
pub const SEARCH_RESOLVED_TURN_RAD: f32 = 2.0;

/// What a thermal limit needs ([`crate::supervisor::thermal::ThermalConfig::new`]).
const THERMAL_NEED: &str =
    "needs rated_current_a > 0, time_constant_s > 0 and 1 ≤ overload_factor ≤ 10, finite";

/// The sensorless speed estimate's bandwidth `α_o`, rad/s: `2/(N·T_slow)`, the bandwidth whose
/// first-order lag equals, at low frequency, the delay `N·T_slow/2` of the encoder's speed
/// window of N = [`SPEED_WINDOW_READS`] reads — the lag the speed loop was designed and certified
/// with — limited to [`CORRECTION_PER_SAMPLE_MAX`] per fast step (at 4 kHz with a 2 kHz slow
/// loop: 400 instead of 500 rad/s).
pub fn observer_speed_bandwidth_rad_s(ts_s: f64, t_slow_s: f64) -> f64 {
    (2.0 / (SPEED_WINDOW_READS as f64 * t_slow_s)).min(CORRECTION_PER_SAMPLE_MAX / ts_s)
}

/// The drive's peak acceleration, rad/s²: the torque of the largest current reference all
/// on the q axis at the flux reference, `τ_peak = 1.5·p·(L_m/L_r)·ψ_r*·i_ref_max`, on the
/// motor's inertia — the encoder jump check's mechanics ([`ENCODER_ACCEL_FACTOR`] times it).
pub fn peak_acceleration_rad_s2(
    motor: &crate::motor::MotorParams,
    flux_ref_wb: f64,
    i_ref_max_a: f64,
) -> f64 {
    motor.torque_factor() * flux_ref_wb * i_ref_max_a / motor.j_kgm2()
}

/// The encoder jump level's two shares, mechanical rad: `[quantisation, acceleration]`, the
/// acceleration's the mechanics' allowance over a read squared ([`ENCODER_ACCEL_FACTOR`] ×
/// [`peak_acceleration_rad_s2`] × T_slow², at most the level), the quantisation's the rest
/// (`drive_file::drive::default_encoder_jump_rad`'s two terms). At a spacing of `n` reads
/// the jump check allows the first plus `n²` times the second.
pub fn encoder_jump_shares(spec: &DriveSpec) -> [f64; 2] {
    let t_slow_s = f64::from(spec.slow_divider) / spec.pwm_frequency_hz;
    let jump = spec.protection.encoder_jump_rad;
    let allowance = ENCODER_ACCEL_FACTOR
        * peak_acceleration_rad_s2(&spec.motor, spec.flux_ref_wb, spec.i_ref_max_a)
        * t_slow_s
        * t_slow_s;
    let count = (jump - allowance).clamp(0.0, jump);
    [count, jump - count]
}

/// `x` finite and positive.
fn finite_positive_f64(x: f64) -> bool {
    x.is_finite() && x > 0.0
}

impl DriveConfig {
    /// The slow loop runs every `slow_divider()`-th fast step.
    pub fn slow_divider(&self) -> u16 {
        self.slow_divider
    }

    /// The stationary-frame loops' reference precompensation at the field turn `step_rad`
    /// per fast step (`step`: its sin/cos): `G = 1/T(e^{jθ}) = 1 + Z(jω_e)/k(e^{jθ})`, with
    /// `T = kZ⁻¹/(1 + kZ⁻¹)` the loops' closed-loop response to a reference turning at
    /// ω_e = θ/T_s, `k` the implemented controller ([`CurrentControllerConfig::inverse_response`])
    /// and `Z = R_s + jω_e·σL_s` the stator as the loops see it once the back-EMF is fed
    /// forward and the delay's rotation applied (`FastState::feedforward`, `delay_s`). A PI in
    /// the stationary frame has no integrator at ω_e: its current is `T·i*`, behind and
    /// short of the reference by `|1 − T| ≈ ω_e·σL_s/k_p` (the 153 kW population member
    /// at twice its base speed: 3.7°, 17 A of d current on 270 A of q). Asked for `G·i*`, the
    /// loops give `i*`; the error the model misses is the trim's. `G` is 1 at standstill
    /// (the integrator's gain is infinite there) and for a non-finite result.
    pub(super) fn reference_gain(&self, step_rad: f32, step: SinCos) -> Complex32 {
        let [rs_ohm, sigma_ls_h] = self.stator_impedance;
        let z = Complex32::new(rs_ohm, step_rad / self.ts_s * sigma_ls_h);
        let g = z * self.current.inverse_response(step) + 1.0;
        if g.re.is_finite() && g.im.is_finite() { g } else { Complex32::new(1.0, 0.0) }
    }

    /// The field-frame loops' decoupling at field speed `omega_e_rad_s` (electrical) for
    /// the current `i_a` they are asked for (the plan's reference and trim), V: `jω_e·σL_s·i*`
    /// — the stator equation in the field frame, `v = R_s·i + σL_s·di/dt + jω_e·σL_s·i +
    /// jω_e·(L_m/L_r)·ψ_r + (L_m/L_r)·dψ_r/dt`, couples each axis to the other's current
    /// through the field's rotation. A synchronous PI takes that coupling as a disturbance;
    /// one that moves with the torque reference (d: `−ω_e·σL_s·Δi_q`) is answered by the
    /// proportional path alone until the integrator, at the stator's corner `R/σL_s` (the
    /// tuner's zero), catches up: an error of `ω_e·σL_s·Δi_q/k_p = (ω_e/ω_c)·Δi_q` that decays
    /// with `σL_s/R`. The 18 kW population member at 4.5 kHz, its torque falling from 25 to
    /// 6 A of q current at its top speed (628 rad/s, ω_c 1 977 rad/s), held a d current 7 A
    /// below its reference for 20 ms, the currents 90° behind their references — which the
    /// stuck-switch check read as a dead switch (`SwitchOpen`, healthy). Fed forward from the
    /// reference, the coupling is the loops' only through their error: `jω_e·σL_s·(i − i*)`,
    /// gone as they settle at ω_c. The EMF term stays the integrators' (the flux model's error
    /// fed forward cost the Krause template's envelope: docs/envelope.md). A reference's
    /// feedforward, outside the loops: their characteristic polynomial, and with it the
    /// certificate's loop analysis, is unchanged.
    pub(super) fn decoupling_v(&self, omega_e_rad_s: f32, i_a: Dq) -> Dq {
        let x = omega_e_rad_s * self.decoupling_h;
        Dq { d: -x * i_a.q, q: x * i_a.d }
    }

    /// PWM periods from the slow tick to the period that adopts its plan
    /// ([`plan_delay_periods`] at this configuration's rate).
    pub fn plan_delay(&self) -> u16 {
        self.slow_divider - 1 - self.adopt_at
    }

    /// Validate and discretise.
    pub fn new(spec: &DriveSpec) -> Result<Self, DriveError> {
        let f = spec.pwm_frequency_hz;
        if !(f.is_finite() && f > 0.0) {
            return Err(DriveError::PwmFrequency);
        }
        let delay = plan_delay_periods(f).ok_or(DriveError::PwmFrequency)?;
        // The plan is adopted before the next tick: at the latest in the period before it.
        let Some(adopt_at) = spec.slow_divider.checked_sub(1 + delay) else {
            return Err(DriveError::SlowDivider { min: delay + 1 });
        };
        let ts = 1.0 / f;
        // Before the protection, whose defaults are derived from the flux's magnetizing
        // current: a bad flux is named as such. Its magnetizing current ψ*/L_m must leave
        // current for torque below the current limit — above it the references are clamped:
        // a flux the drive never reaches and no torque (`design certify` certified ψ* = 50 Wb
        // on a 4 A drive).
        let i_d_rated_a = spec.flux_ref_wb / spec.motor.lm_h();
        if !(spec.flux_ref_wb.is_finite()
            && spec.flux_ref_wb > 0.0
            && spec.flux_floor_wb < spec.flux_ref_wb
            && i_d_rated_a < spec.i_ref_max_a)
        {
            return Err(DriveError::FluxReference);
        }
        if let Some(t) = &spec.magnetizing {
            if !cfg!(feature = "curve") {
                return Err(DriveError::CurveNotBuilt);
            }
            t.validate().map_err(DriveError::Magnetizing)?;
        }
        let p = &spec.protection;
        // Each threshold with what it needs, in the order they are judged: the first that
        // fails is named.
        const POSITIVE: &str = "must be finite and > 0";
        let checks = [
            ("i_ref_max_a", spec.i_ref_max_a.is_finite() && spec.i_ref_max_a > 0.0, POSITIVE),
            (
                "protection.i_trip_a",
                p.i_trip_a.is_finite() && p.i_trip_a > spec.i_ref_max_a,
                "must be finite and above i_ref_max_a (the references' limit must not trip)",
            ),
            ("protection.vdc_max_v", p.vdc_max_v.is_finite(), "must be finite"),
            (
                "protection.vdc_min_v",
                // As stored: two limits that round to one f32 would be refused by `from_raw`.
                p.vdc_min_v.is_finite()
                    && p.vdc_min_v >= 0.0
                    && p.vdc_min_v < p.vdc_max_v
                    && (p.vdc_min_v as f32) < (p.vdc_max_v as f32),
                "must be finite, ≥ 0 and below protection.vdc_max_v (in f32 too)",
            ),
            ("protection.overspeed_rad_s", finite_positive_f64(p.overspeed_rad_s), POSITIVE),
            ("protection.stall_time_s", finite_positive_f64(p.stall_time_s), POSITIVE),
            ("protection.following_time_s", finite_positive_f64(p.following_time_s), POSITIVE),
            ("protection.current_sum_max_a", finite_positive_f64(p.current_sum_max_a), POSITIVE),
            ("protection.current_sum_mean_max_a", finite_positive_f64(p.current_sum_mean_max_a), POSITIVE),
            ("protection.saturation_time_s", finite_positive_f64(p.saturation_time_s), POSITIVE),
            ("protection.encoder_check_time_s", finite_positive_f64(p.encoder_check_time_s), POSITIVE),
            ("protection.encoder_jump_rad", finite_positive_f64(p.encoder_jump_rad), POSITIVE),
            ("protection.stop_time_s", finite_positive_f64(p.stop_time_s), POSITIVE),
            ("protection.open_phase_time_s", finite_positive_f64(p.open_phase_time_s), POSITIVE),
            ("protection.rest_time_s", finite_positive_f64(p.rest_time_s), POSITIVE),
        ];
        if let Some(&(field, _, need)) = checks.iter().find(|(_, ok, _)| !ok) {
            return Err(DriveError::Protection { field, need });
        }
        let (brake_on_v, brake_off_v) = match p.brake_chopper {
            None => (f32::MAX, f32::MAX),
            Some(b) if b.off_v > 0.0 && b.off_v < b.on_v && b.on_v < REGEN_LIMIT_START * p.vdc_max_v => {
                (b.on_v as f32, b.off_v as f32)
            }
            Some(_) => return Err(DriveError::BrakeChopper),
        };
        let mf = spec.magnetized_fraction;
        if !(mf > 0.0 && mf < 1.0) {
            return Err(DriveError::MagnetizedFraction);
        }
        // Up to the circle; overmodulating, up to six-step's fundamental.
        let margin_max = if spec.overmodulation { SIX_STEP_FUNDAMENTAL } else { 1.0 };
        if !(spec.voltage_margin > 0.0 && spec.voltage_margin <= margin_max) {
            return Err(DriveError::VoltageMargin);
        }
        let t_slow = ts * f64::from(spec.slow_divider);
        // The flying start's window: the most slow periods in which the field turns at most
        // SEARCH_TURN_MAX_RAD at the overspeed level (electrical), at least one.
        let w_e_max = f64::from(spec.motor.pole_pairs()) * spec.protection.overspeed_rad_s;
        let search_span = libm::floor(SEARCH_TURN_MAX_RAD / (w_e_max * t_slow)).clamp(1.0, 64.0) as u32;
        let trim_bw = spec.current_trim_bandwidth_rad_s;
        if !(trim_bw >= 0.0 && trim_bw * t_slow < 0.1) {
            return Err(DriveError::CurrentTrim);
        }
        let dead_duty = spec.dead_time_compensation_s / ts;
        if !(0.0..0.1).contains(&dead_duty) {
            return Err(DriveError::DeadTime);
        }
        if spec.overmodulation && !cfg!(feature = "overmodulation") {
            return Err(DriveError::OvermodulationNotBuilt);
        }
        // Finite in f32 too.
        if !(spec.speed_resolution_rad_s >= 0.0 && (spec.speed_resolution_rad_s as f32).is_finite()) {
            return Err(DriveError::SpeedResolution);
        }
        let (duty_max, duty_sampled) = (spec.duty_max(), spec.duty_sampled());
        if !(spec.sample_window_s >= 0.0 && duty_sampled >= DUTY_MAX_MIN) {
            return Err(DriveError::SampleWindow);
        }
        // The flux model reaches mf·ψ* in T_r·ln(1/(1 − mf)) on the reference current; twice
        // that, plus 20 ms for the current loops, is the most magnetizing may take. Counted
        // in slow steps of the model's decay (no logarithm on the target: 640 B of flash).
        let decay = libm::exp(-t_slow / spec.motor.tr_s());
        let (mut left, mut steps) = (1.0f64, 0u32);
        while left > 1.0 - mf && steps < 100_000_000 {
            left *= decay;
            steps += 1;
        }
        let magnetizing_s = 2.0 * f64::from(steps) * t_slow + 0.02;
        // Static limit of the current controllers: the largest bus voltage we run on.
        let current = CurrentControllerConfig::new(
            &spec.current_law,
            ts,
            spec.discretization,
            svpwm::linear_limit_v(p.vdc_max_v as f32) as f64,
        )
        .map_err(DriveError::Current)?;
        let ifoc = IfocConfig::new(&spec.motor, ts, spec.flux_floor_wb, spec.i_ref_max_a)
            .map_err(DriveError::Ifoc)?;
        let mras = MrasConfig::new(
            &spec.motor,
            ts,
            spec.slow_divider,
            spec.rotor_resistance_range,
            spec.inductance_range,
        )
        .map_err(|e| match e {
            MrasError::InductanceRange => DriveError::InductanceRange,
            MrasError::Range | MrasError::Rate => DriveError::RotorResistanceRange,
        })?;
        let speed = SpeedControllerConfig::new(&spec.speed_law, ts * f64::from(spec.slow_divider))
            .map_err(DriveError::Speed)?;
        let position = PositionConfig::new(spec.position.k_per_s, spec.position.omega_max_rad_s)
            .map_err(DriveError::Position)?;
        let i_d_rated_a = ifoc.flux_command(spec.flux_ref_wb as f32).i_d_a();
        let [count_rad, accel_rad] = encoder_jump_shares(spec);
        Ok(Self {
            current,
            current_frame: spec.current_frame,
            slip_current: spec.slip_current,
            vhz_on: matches!(spec.control, Control::VHz { .. }),
            ifoc,
            mras,
            speed,
            position,
            envelope: EnvelopeConfig::new(&spec.motor),
            i_d_rated_a,
            magnetized_fraction: mf as f32,
            // Or the magnetizing fit's longest and the current loops' 20 ms, when that is
            // longer (a saturating motor's slid windows on a low rotor-resistance range).
            magnetizing_steps_max: (libm::ceil(magnetizing_s / t_slow).clamp(1.0, 4e9) as u32).max(
                mras.fit_slow_steps_max(spec.magnetizing.is_some())
                    .saturating_add(libm::ceil(0.02 / t_slow) as u32),
            ),
            voltage_margin: spec.voltage_margin as f32,
            voltage_gain: (spec.voltage_regulator_bandwidth_rad_s() * t_slow) as f32,
            voltage_gain_max: (VOLTAGE_REGULATOR_BANDWIDTH_RAD_S * t_slow) as f32,
            trim_gain: (trim_bw * t_slow) as f32,
            tracking_rate: (-libm::expm1(-1.0 / f64::from(spec.slow_divider))) as f32,
            dead_time_duty: dead_duty as f32,
            duty_max: duty_max as f32,
            duty_sampled: duty_sampled as f32,
            regen_start_v: (REGEN_LIMIT_START * p.vdc_max_v) as f32,
            inv_regen_span_v: (1.0 / ((REGEN_LIMIT_END - REGEN_LIMIT_START) * p.vdc_max_v)) as f32,
            dead_time_band_a: (DEAD_TIME_BAND_FRACTION * spec.i_ref_max_a) as f32,
            delay_s: (VOLTAGE_DELAY_PERIODS * ts) as f32,
            stator_impedance: [spec.motor.rs_ohm() as f32, (spec.motor.sigma() * spec.motor.ls_h()) as f32],
            decoupling_h: match spec.current_frame {
                CurrentFrame::Synchronous if spec.current_decoupling => {
                    (spec.motor.sigma() * spec.motor.ls_h()) as f32
                }
                _ => 0.0,
            },
            ts_s: ts as f32,
            flux_lag_j_kgm2: (FLUX_LAG_FRACTION * spec.motor.j_kgm2()) as f32,
            flux_fall_time_min_s: (FLUX_FALL_SLOW_PERIODS * t_slow) as f32,
            speed_hold_band_rad_s: (0.5 * spec.speed_resolution_rad_s) as f32,
            slow_divider: spec.slow_divider,
            adopt_at,
            limits: Limits {
                // Finite in f32 too (a level beyond f32::MAX would let +∞ through).
                i_trip_bits: abs_bits((p.i_trip_a as f32).min(f32::MAX)),
                i_sum_bits: abs_bits((p.current_sum_max_a as f32).min(f32::MAX)),
                // −0 as +0 (the same limit): the supervisor's bit test needs the sign bit clear.
                vdc_min_v: if p.vdc_min_v == 0.0 { 0.0 } else { p.vdc_min_v as f32 },
                vdc_max_v: p.vdc_max_v as f32,
            },
            motion: MotionLimits {
                overspeed_rad_s: p.overspeed_rad_s as f32,
                stall_speed_rad_s: (STALL_SPEED_FRACTION * p.overspeed_rad_s) as f32,
                // At least one slow step; saturating for absurdly long times.
                stall_slow_steps: libm::ceil(p.stall_time_s * f / f64::from(spec.slow_divider))
                    .clamp(1.0, 4e9) as u32,
                following_slow_steps: libm::ceil(p.following_time_s * f / f64::from(spec.slow_divider))
                    .clamp(1.0, 4e9) as u32,
                following_gain: (FOLLOWING_PROGRESS_FRACTION * t_slow / spec.motor.j_kgm2()) as f32,
                speed_limit: speed.output_limit(),
            },
            saturation_steps: libm::ceil(p.saturation_time_s * f).clamp(1.0, 4e9) as u32,
            encoder: EncoderLimits {
                // Finite in f32 too.
                jump_levels_rad: core::array::from_fn(|k| {
                    let n = (k + 1) as f64;
                    ((count_rad + n * n * accel_rad) as f32).min(f32::MAX)
                }),
                check_steps: libm::ceil(p.encoder_check_time_s * f / f64::from(spec.slow_divider))
                    .clamp(1.0, 4e9) as u32,
            },
            search_span,
            search_slow_steps: match spec.speed_feedback {
                SpeedFeedback::Sensorless => libm::ceil(spec.motor.tr_s() / t_slow)
                    .max(f64::from((SEARCH_WINDOWS_MIN + 1) * search_span))
                    .min(4e9) as u32,
                SpeedFeedback::Encoder | SpeedFeedback::EncoderRideThrough => 0,
            },
            motor_thermal: ThermalConfig::new(p.motor_thermal.as_ref(), t_slow)
                .ok_or(DriveError::Protection { field: "protection.motor_thermal", need: THERMAL_NEED })?,
            inverter_thermal: ThermalConfig::new(p.inverter_thermal.as_ref(), t_slow)
                .ok_or(DriveError::Protection { field: "protection.inverter_thermal", need: THERMAL_NEED })?,
            stop_on: if p.stop_on.0 & !FaultSet::STOPPABLE.0 == 0 {
                p.stop_on
            } else {
                return Err(DriveError::Protection {
                    field: "protection.stop_on",
                    need: "only faults after which the drive still controls the motor (FaultSet::STOPPABLE: \
                           the thermal overloads and overspeed)",
                });
            },
            stop_slow_steps: libm::ceil(p.stop_time_s * f / f64::from(spec.slow_divider)).clamp(1.0, 4e9)
                as u32,
            phases: PhaseLimits::new(
                [spec.open_phase_steps(), spec.open_phase_slow_steps()],
                spec.slow_divider,
                i_d_rated_a,
                p.current_sum_mean_max_a as f32,
            ),
            brake: BrakeLevels { on_v: brake_on_v, off_v: brake_off_v },
            rest: RestLimits::new(p.rest_time_s, t_slow, spec.motor.pole_pairs(), spec.motor.tr_s()),
            source: {
                let observer = || {
                    ObserverConfig::new(
                        &spec.motor,
                        ts,
                        observer_speed_bandwidth_rad_s(ts, t_slow),
                        spec.flux_floor_wb,
                        f64::from(spec.motor.pole_pairs()) * p.overspeed_rad_s,
                    )
                    .map_err(DriveError::Observer)
                };
                match spec.speed_feedback {
                    SpeedFeedback::Encoder => SpeedSource::Encoder,
                    _ if !cfg!(feature = "observer") => {
                        return Err(DriveError::Observer(ObserverError::NotBuilt));
                    }
                    SpeedFeedback::Sensorless => SpeedSource::Observer(observer()?),
                    SpeedFeedback::EncoderRideThrough => SpeedSource::RideThrough(observer()?),
                }
            },
            control: match spec.control {
                Control::Vector => ControlLaw::Vector,
                Control::VHz { .. } if !cfg!(feature = "vhz") => {
                    return Err(DriveError::Vhz(VhzError::NotBuilt));
                }
                Control::VHz { ramp_rad_s2, k_u, k_w } => ControlLaw::VHz(
                    VhzConfig::new(&spec.motor, ts, t_slow, spec.flux_ref_wb, ramp_rad_s2, [k_u, k_w])
                        .map_err(DriveError::Vhz)?,
                ),
            },
            magnetizing: MagnetizingChord::new(
                spec.magnetizing.as_ref(),
                spec.flux_ref_wb / spec.motor.lm_h(),
                spec.flux_ref_wb,
            ),
        })
    }
}

/// Floats in a raw drive configuration: the compiler's count of [`DriveConfig`]'s
/// (`raw::Field::NF`, summed over its declaration).
pub const FLOATS: usize = <DriveConfig as raw::Field>::NF;
/// Integers in a raw drive configuration (`raw::Field::NU`).
pub const INTEGERS: usize = <DriveConfig as raw::Field>::NU;

/// A drive configuration as numbers ([`crate::raw`]). Its `Debug` form is a Rust
/// expression: what the firmware's build script writes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RawDriveConfig {
    /// The f32 fields, in writing order.
    pub f: [f32; FLOATS],
    /// The integer fields (counts, bit patterns, variant tags), in writing order.
    pub u: [u32; INTEGERS],
}

impl DriveConfig {
    /// The configuration as plain numbers ([`crate::raw`]): what a host computes and the
    /// firmware embeds.
    pub fn to_raw(&self) -> RawDriveConfig {
        self.write_raw().0
    }

    /// [`Self::to_raw`], with the numbers written — floats, integers — and whether a field
    /// did not fit (the tests' check that the arrays are exactly full).
    pub(super) fn write_raw(&self) -> (RawDriveConfig, (usize, usize), bool) {
        let mut raw = RawDriveConfig { f: [0.0; FLOATS], u: [0; INTEGERS] };
        let mut w = raw::Writer::new(&mut raw.f, &mut raw.u);
        raw::Field::put(self, &mut w);
        let (counts, overflow) = (w.counts(), w.overflow);
        (raw, counts, overflow)
    }

    /// The configuration from [`DriveConfig::to_raw`]'s numbers, checked without any design
    /// arithmetic: every float finite, the variant tags known, the divider and the step
    /// counts at least 1, the bus range `+0 ≤ min < max`, the rotor-resistance law's
    /// configuration valid, the controlled stop's faults stoppable. [`DriveError::Raw`]
    /// otherwise.
    pub fn from_raw(raw: &RawDriveConfig) -> Result<Self, DriveError> {
        let mut r = raw::Reader::new(&raw.f, &raw.u);
        let cfg = <Self as raw::Field>::get(&mut r);
        let counts = [
            u32::from(cfg.slow_divider),
            cfg.magnetizing_steps_max,
            cfg.motion.stall_slow_steps,
            cfg.motion.following_slow_steps,
            cfg.saturation_steps,
            cfg.encoder.check_steps,
            cfg.stop_slow_steps,
            cfg.phases.open_phase_slow_steps,
            cfg.rest.window_slow_steps,
        ];
        // The bus range as `new` makes it, +0 for a zero minimum (the fast step's supervisor
        // tests it as one unsigned range of the bits, `Limits::ok`).
        let bus = cfg.limits.vdc_min_v.is_sign_positive() && cfg.limits.vdc_min_v < cfg.limits.vdc_max_v;
        if r.ok() && !cfg.magnetizing.is_built() {
            return Err(DriveError::CurveNotBuilt);
        }
        if r.ok() && cfg.duty_sampled < cfg.duty_max && !cfg!(feature = "overmodulation") {
            return Err(DriveError::OvermodulationNotBuilt);
        }
        if !r.ok()
            || !bus
            || !cfg.mras.is_valid()
            || counts.contains(&0)
            // The plan adopted before the next tick (`adopt_at` < the divider).
            || cfg.adopt_at >= cfg.slow_divider
            || cfg.stop_on.0 & !FaultSet::STOPPABLE.0 != 0
            || cfg.vhz_on != matches!(cfg.control, ControlLaw::VHz(_))
            // The flying start's speed search is the observer's: with an encoder it would hold
            // the drive magnetizing until its timeout.
            || (cfg.search_slow_steps != 0 && !cfg.source.sensorless())
            || !cfg.magnetizing.is_valid()
            // The modulator's two limits ordered (`svpwm::overmodulate`).
            || !(DUTY_MAX_MIN as f32 <= cfg.duty_sampled && cfg.duty_sampled <= cfg.duty_max && cfg.duty_max <= 1.0)
        {
            return Err(DriveError::Raw);
        }
        Ok(cfg)
    }

    /// The same drive with new gains of its saturated-P speed law (seed 002 eq. (21)), in
    /// f32 — the firmware's `WriteSpeedGains` — the stall check's limit following τ_max.
    /// `None` for another law or bad gains ([`SpeedControllerConfig::with_saturated_p`]).
    pub fn with_saturated_p(&self, kp: f32, tau_max_nm: f32) -> Option<Self> {
        let speed = self.speed.with_saturated_p(kp, tau_max_nm)?;
        // Copied whole, then the two fields set: the struct update syntax (`..*self`) copied
        // it field by field, inlined into the firmware's `WriteSpeedGains` (388 B of flash).
        let mut cfg = *self;
        (cfg.speed, cfg.motion.speed_limit) = (speed, speed.output_limit());
        Some(cfg)
    }

    /// `other` drives the same motor: the same field orientation and machine model, both
    /// made from the motor's parameters (`Drive::reconfigure` keeps the machine's state for
    /// it; another motor is another drive).
    pub fn same_motor(&self, other: &DriveConfig) -> bool {
        self.ifoc == other.ifoc && self.envelope == other.envelope
    }

    /// The speed loop.
    pub fn speed(&self) -> &SpeedControllerConfig {
        &self.speed
    }

    /// The fast-loop period, s.
    pub fn ts_s(&self) -> f32 {
        self.ts_s
    }

    /// The highest duty that leaves a phase its current sample: in a build without
    /// overmodulation `duty_max` itself (the two are equal there: `new` and `from_raw` refuse
    /// a configuration that overmodulates), so that the fast step loads one number for both
    /// (two loads cost its common path ≈ 2 instructions per period, `cost fast_step`).
    #[inline(always)]
    pub(super) fn duty_sampled(&self) -> f32 {
        if cfg!(feature = "overmodulation") { self.duty_sampled } else { self.duty_max }
    }

    /// The modulator may overmodulate ([`DriveSpec::overmodulation`]): its highest duty
    /// above the sampled one.
    #[inline(always)]
    pub(super) fn overmodulating(&self) -> bool {
        cfg!(feature = "overmodulation") && self.duty_sampled < self.duty_max
    }

    /// The V/Hz law, when the drive runs one ([`Control::VHz`]).
    #[inline(always)]
    pub(super) fn vhz(&self) -> Option<&VhzConfig> {
        if !self.vhz_on() {
            return None; // the flag first: near the drive's address
        }
        match &self.control {
            ControlLaw::VHz(v) => Some(v),
            ControlLaw::Vector => None,
        }
    }

    /// The drive runs the V/Hz law (the flag alone: what the every-period paths test).
    #[inline(always)]
    pub(super) fn vhz_on(&self) -> bool {
        cfg!(feature = "vhz") && self.vhz_on
    }
}
