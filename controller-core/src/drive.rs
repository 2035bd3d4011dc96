//! Drive composition: supervisor, state machine, fast and slow steps.
//!
//! ```text
//!            enable()               ψ̂_r ≥ magnetized_fraction·ψ_r*
//!   Idle ───────────────▶ Magnetizing ─────────────────────────────▶ Running
//!    ▲  ◀──── disable() ───────┴──────────────── disable() ────────────┘
//!    │                 any mode ── supervisor trip ──▶ Fault(f)  (latched, phases off)
//!    └──────────────────── clear_fault() ──────────────────┘
//! ```
//!
//! **Fast step** (every PWM period, [`Drive::fast_step`]): supervisor → Clarke of the measured
//! phase currents → IFOC (field angle, current references in αβ) → α/β current controllers
//! (or d/q controllers between Park and inverse Park, [`CurrentFrame::Synchronous`]) with the
//! voltage limit `V_dc/√3` → SVPWM duties.
//! **Slow step** (every N-th period, [`Drive::slow_step`]): position loop (if a position
//! reference is active) → speed loop → torque command held for the fast steps.
//! [`Drive::step`] runs the slow step on every N-th call, then the fast step — what the
//! firmware's control interrupt and the simulators call.
//!
//! **Supervisor** (first thing in the fast step, any mode): any non-finite measurement,
//! a phase current beyond `i_trip_a`, three phase currents that do not sum to zero within
//! `current_sum_max_a` (a dead or drifting sensor), a bus voltage above `vdc_max_v`, or —
//! when the bridge is active — below `vdc_min_v`, latches a [`Fault`] and turns all phases
//! off in the same step. In the slow step: overspeed (|ω_m| above `overspeed_rad_s` while
//! active) and stall (the speed loop's output at its limit with the rotor below 1 % of the
//! overspeed level for `stall_time_s`); after the modulator, loss of control (the current
//! loops at their voltage limit for `saturation_time_s`), and once per slow period the
//! encoder against the machine model ([`Fault::EncoderImplausible`]). Magnetizing → Running also needs the measured
//! d-axis current to have followed its reference ([`Fault::NoMotorCurrent`] otherwise). A non-finite controller output (impossible for finite inputs, checked anyway)
//! trips too. The fast step performs no indexing, no division by unchecked values that could
//! panic, and no `unwrap`: it cannot panic for any input (property-tested).

use crate::current::{CurrentControllerConfig, CurrentError, CurrentLaw, CurrentState};
use crate::discretize::Discretization;
use crate::frames::{Abc, AlphaBeta, Dq, SinCos, wrap_angle};
use crate::ifoc::{FluxCommand, IfocConfig, IfocError, IfocOutput, IfocState, TorqueCommand};
use crate::motor::MotorParams;
use crate::num::{Scalar, max_f32};
use crate::speed::{PositionConfig, SpeedControllerConfig, SpeedError, SpeedLaw, SpeedState};
use crate::svpwm;

/// Protection thresholds. The drive file derives defaults for the last three from the motor
/// and the other limits (`drive_file::drive`, where the reasoning is written down).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Protection {
    /// Phase-current trip level (absolute instantaneous value), A.
    pub i_trip_a: f64,
    /// DC-bus undervoltage trip (checked while the bridge is active), V.
    pub vdc_min_v: f64,
    /// DC-bus overvoltage trip, V.
    pub vdc_max_v: f64,
    /// Overspeed trip: |ω_m| above this while the bridge is active, mechanical rad/s.
    pub overspeed_rad_s: f64,
    /// Stall trip: the speed loop's output at its limit while |ω_m| stays below
    /// [`STALL_SPEED_FRACTION`] of `overspeed_rad_s` for this long, s.
    pub stall_time_s: f64,
    /// Current-sensor plausibility: |i_a + i_b + i_c| of the three measured phase currents
    /// (zero for any star-connected motor) above this trips, A.
    pub current_sum_max_a: f64,
    /// Loss of control: the current loops at their voltage limit (an axis clamped, or the
    /// request outside the bridge's hexagon) for this long without a break, s.
    pub saturation_time_s: f64,
    /// Encoder against the machine model: the applied voltage departs from the voltage the
    /// motor needs at the encoder's speed by more than [`ENCODER_RESIDUAL_FRACTION`] of the
    /// linear voltage limit, at every slow-step check for this long, s.
    pub encoder_check_time_s: f64,
}

/// The encoder check's threshold, as a fraction of the linear voltage limit V_dc/√3.
pub const ENCODER_RESIDUAL_FRACTION: f32 = 0.5;

/// "Not moving" for the stall check: below this fraction of the overspeed level.
pub const STALL_SPEED_FRACTION: f64 = 0.01;

/// Magnetizing → Running needs the measured d-axis current to reach this fraction of its
/// reference: a motor that is not there (open leads, dead current sensors) never does.
pub const MAGNETIZING_CURRENT_FRACTION: f32 = 0.5;

/// Position loop parameters (P law with speed saturation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PositionLaw {
    /// Speed reference per rad of position error, 1/s.
    pub k_per_s: f64,
    /// Speed-reference limit, mechanical rad/s.
    pub omega_max_rad_s: f64,
}

/// Reference frame of the current loops.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum CurrentFrame {
    /// α/β loops on sinusoidal references (seed 002; ICAD eq. (20)).
    #[default]
    Stationary,
    /// d/q loops on the field-oriented frame (seed 000 PI1/PI3): Park of the measured
    /// currents at θ_e, the controllers on d and q errors, inverse Park of the voltage.
    Synchronous,
}

/// Everything a drive needs, in design units (f64). [`DriveConfig::new`] validates it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriveSpec {
    /// Motor.
    pub motor: MotorParams,
    /// Fast-loop (PWM) frequency, Hz.
    pub pwm_frequency_hz: f64,
    /// The slow loop runs every `slow_divider`-th fast step (≥ 1).
    pub slow_divider: u16,
    /// Current law (ICAD or PI).
    pub current_law: CurrentLaw,
    /// Discretisation of the current law.
    pub discretization: Discretization,
    /// Frame of the current loops.
    pub current_frame: CurrentFrame,
    /// Speed law.
    pub speed_law: SpeedLaw,
    /// Position loop.
    pub position: PositionLaw,
    /// Rotor-flux reference ψ_r*, Wb.
    pub flux_ref_wb: f64,
    /// Flux floor of the IFOC guard, Wb.
    pub flux_floor_wb: f64,
    /// Magnitude limit of the current reference vector, A.
    pub i_ref_max_a: f64,
    /// Magnetizing → Running when ψ̂_r ≥ this fraction of ψ_r* (in (0, 1)).
    pub magnetized_fraction: f64,
    /// Trip thresholds.
    pub protection: Protection,
}

/// Why a drive specification was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DriveError {
    /// PWM frequency not finite and positive.
    PwmFrequency,
    /// `slow_divider` is 0.
    SlowDivider,
    /// Current law rejected.
    Current(CurrentError),
    /// Speed law rejected.
    Speed(SpeedError),
    /// Position law rejected.
    Position(SpeedError),
    /// IFOC parameters rejected.
    Ifoc(IfocError),
    /// Flux reference not finite and positive, or `flux_floor_wb` not below it.
    FluxReference,
    /// `magnetized_fraction` not in (0, 1).
    MagnetizedFraction,
    /// Protection thresholds inconsistent: need 0 ≤ vdc_min < vdc_max,
    /// i_trip > i_ref_max > 0, and positive finite overspeed, stall time and current sum.
    Protection,
}

/// Validated, discretised drive configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriveConfig {
    current: CurrentControllerConfig<f32>,
    current_frame: CurrentFrame,
    ifoc: IfocConfig,
    speed: SpeedControllerConfig,
    position: PositionConfig,
    flux: FluxCommand,
    psi_running_wb: f32,
    ts_s: f32,
    slow_divider: u16,
    /// Bits of the phase-current trip level (finite, positive): see
    /// [`Drive::measurements_ok`]; [`Drive::supervise`] reads the level back from them.
    i_trip_bits: u32,
    /// Bits of `current_sum_max_a` (compared like `i_trip_bits`).
    i_sum_bits: u32,
    vdc_min_v: f32,
    vdc_max_v: f32,
    overspeed_rad_s: f32,
    stall_speed_rad_s: f32,
    /// Slow steps of stall before the trip.
    stall_slow_steps: u32,
    /// The speed loop's output limit (saturation test of the stall check).
    speed_limit: f32,
    /// Fast steps with the voltage request outside the hexagon before the trip.
    saturation_steps: u32,
    /// Slow periods of implausible encoder before the trip.
    encoder_check_steps: u32,
    /// Steady-state stator voltage model in the field frame (the encoder check).
    emf: EmfModel,
}

/// Steady-state stator voltage of the induction machine in the rotor-flux frame:
/// v_d = R_s i_d − ω_e σL_s i_q, v_q = R_s i_q + ω_e (σL_s i_d + (L_m/L_r) ψ_r), with
/// ω_e = p ω_m + ω_sl (the standard dq model, seed 000 eqs. (1)–(4) at steady state).
#[derive(Clone, Copy, Debug, PartialEq)]
struct EmfModel {
    rs_ohm: f32,
    sigma_ls_h: f32,
    lm_over_lr: f32,
    pole_pairs: f32,
}

impl DriveConfig {
    /// The slow loop runs every `slow_divider()`-th fast step.
    pub fn slow_divider(&self) -> u16 {
        self.slow_divider
    }

    /// Validate and discretise.
    pub fn new(spec: &DriveSpec) -> Result<Self, DriveError> {
        let f = spec.pwm_frequency_hz;
        if !(f.is_finite() && f > 0.0) {
            return Err(DriveError::PwmFrequency);
        }
        if spec.slow_divider == 0 {
            return Err(DriveError::SlowDivider);
        }
        let ts = 1.0 / f;
        let p = &spec.protection;
        let finite = [
            p.i_trip_a,
            p.vdc_min_v,
            p.vdc_max_v,
            spec.i_ref_max_a,
            p.overspeed_rad_s,
            p.stall_time_s,
            p.current_sum_max_a,
            p.saturation_time_s,
            p.encoder_check_time_s,
        ]
        .iter()
        .all(|x| x.is_finite());
        if !(finite
            && p.vdc_min_v >= 0.0
            && p.vdc_min_v < p.vdc_max_v
            && spec.i_ref_max_a > 0.0
            && p.i_trip_a > spec.i_ref_max_a
            && p.overspeed_rad_s > 0.0
            && p.stall_time_s > 0.0
            && p.current_sum_max_a > 0.0
            && p.saturation_time_s > 0.0
            && p.encoder_check_time_s > 0.0)
        {
            return Err(DriveError::Protection);
        }
        if !(spec.flux_ref_wb.is_finite() && spec.flux_ref_wb > 0.0 && spec.flux_floor_wb < spec.flux_ref_wb)
        {
            return Err(DriveError::FluxReference);
        }
        let mf = spec.magnetized_fraction;
        if !(mf > 0.0 && mf < 1.0) {
            return Err(DriveError::MagnetizedFraction);
        }
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
        let speed = SpeedControllerConfig::new(&spec.speed_law, ts * f64::from(spec.slow_divider))
            .map_err(DriveError::Speed)?;
        let position = PositionConfig::new(spec.position.k_per_s, spec.position.omega_max_rad_s)
            .map_err(DriveError::Position)?;
        Ok(Self {
            current,
            current_frame: spec.current_frame,
            ifoc,
            speed,
            position,
            flux: ifoc.flux_command(spec.flux_ref_wb as f32),
            ts_s: ts as f32,
            psi_running_wb: (spec.flux_ref_wb * mf) as f32,
            slow_divider: spec.slow_divider,
            // Finite in f32 too (a level beyond f32::MAX would let +∞ through).
            i_trip_bits: abs_bits((p.i_trip_a as f32).min(f32::MAX)),
            i_sum_bits: abs_bits((p.current_sum_max_a as f32).min(f32::MAX)),
            vdc_min_v: p.vdc_min_v as f32,
            vdc_max_v: p.vdc_max_v as f32,
            overspeed_rad_s: p.overspeed_rad_s as f32,
            stall_speed_rad_s: (STALL_SPEED_FRACTION * p.overspeed_rad_s) as f32,
            // At least one slow step; saturating for absurdly long times.
            stall_slow_steps: libm::ceil(p.stall_time_s * f / f64::from(spec.slow_divider)).clamp(1.0, 4e9)
                as u32,
            speed_limit: speed.output_limit(),
            saturation_steps: libm::ceil(p.saturation_time_s * f).clamp(1.0, 4e9) as u32,
            encoder_check_steps: libm::ceil(p.encoder_check_time_s * f / f64::from(spec.slow_divider))
                .clamp(1.0, 4e9) as u32,
            emf: EmfModel {
                rs_ohm: spec.motor.rs_ohm() as f32,
                sigma_ls_h: (spec.motor.sigma() * spec.motor.ls_h()) as f32,
                lm_over_lr: (spec.motor.lm_h() / spec.motor.lr_h()) as f32,
                pole_pairs: f32::from(spec.motor.pole_pairs()),
            },
        })
    }
}

/// Latched fault causes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fault {
    /// A phase current exceeded `i_trip_a`.
    Overcurrent,
    /// DC bus above `vdc_max_v`.
    DcBusOvervoltage,
    /// DC bus below `vdc_min_v` while the bridge was active.
    DcBusUndervoltage,
    /// A measurement was NaN or infinite.
    NonFiniteInput,
    /// A controller output was not finite.
    NonFiniteOutput,
    /// The position sensor stopped making sense (reported by the firmware through
    /// [`Drive::trip`]).
    EncoderLoss,
    /// The inverter's hardware break input fired (the timer already turned the bridge off;
    /// reported by the firmware through [`Drive::trip`]).
    HardwareBreak,
    /// |ω_m| above `overspeed_rad_s` (a runaway: the load overpowers the drive, or the
    /// speed loop lost control).
    Overspeed,
    /// The speed loop's output at its limit while the rotor does not turn, for
    /// `stall_time_s` (a locked rotor under a speed or position command).
    Stall,
    /// The current loops asked for more voltage than the bridge has for
    /// `saturation_time_s`: they no longer control the current (dead sensors, a voltage
    /// limit reached at speed, an open phase).
    LossOfControl,
    /// The applied voltage does not fit the motor at the encoder's speed for
    /// `encoder_check_time_s` (a frozen or lost encoder, a wrong line count).
    EncoderImplausible,
    /// The three measured phase currents do not sum to zero (a dead, stuck or drifting
    /// current sensor).
    CurrentSensor,
    /// At the end of magnetizing the measured d-axis current is below
    /// [`MAGNETIZING_CURRENT_FRACTION`] of its reference: no motor current flows (open
    /// leads, a motor that is not there, dead current sensors).
    NoMotorCurrent,
}

/// Drive state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// Bridge off, waiting for `enable`.
    Idle,
    /// Building rotor flux with zero torque.
    Magnetizing,
    /// Speed/position/torque control.
    Running,
    /// Latched fault, bridge off.
    Fault(Fault),
}

/// Outer-loop reference.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Reference {
    /// Mechanical speed, rad/s.
    Speed(f32),
    /// Mechanical position, rad (not wrapped).
    Position(f32),
    /// Electromagnetic torque, N·m (speed loop bypassed).
    Torque(f32),
    /// Current-loop test (commissioning; seed 002 Fig. 11/23): IFOC and the outer loops are
    /// bypassed and the stator current reference is the rotating vector
    /// `A·(cos θ, sin θ)`, `θ += ω·T` — a sinusoid of `omega_rad_s` on each axis, β lagging
    /// α by 90°. The amplitude is limited to `i_ref_max_a`.
    RotatingCurrent {
        /// Amplitude A, A.
        amplitude_a: f32,
        /// Electrical frequency ω, rad/s.
        omega_rad_s: f32,
    },
}

/// Commands that are refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CommandError {
    /// A fault is latched: clear it first.
    Faulted,
    /// The reference value is NaN or infinite.
    NonFinite,
}

/// Sampled inputs of one PWM period.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Measurements {
    /// Phase currents, A.
    pub i_abc_a: Abc,
    /// DC-bus voltage, V.
    pub vdc_v: f32,
    /// Mechanical speed, rad/s.
    pub omega_m_rad_s: f32,
    /// Mechanical position, rad (not wrapped).
    pub theta_m_rad: f32,
}

impl Measurements {
    fn is_finite(&self) -> bool {
        self.i_abc_a.is_finite()
            && self.vdc_v.is_finite()
            && self.omega_m_rad_s.is_finite()
            && self.theta_m_rad.is_finite()
    }
}

/// What the bridge should do for the next PWM period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PhaseCommand {
    /// All six switches off.
    Off,
    /// Upper-switch duty cycles in [0, 1].
    Duty(Abc),
}

/// Signals of one fast step, for logs and traces.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Telemetry {
    /// Measured stator current, A.
    pub i_ab_a: AlphaBeta,
    /// Stator current reference, A.
    pub i_ref_ab_a: AlphaBeta,
    /// Applied stator voltage (after the hexagon limit), V.
    pub v_ab_v: AlphaBeta,
    /// Field angle, rad.
    pub theta_e_rad: f32,
    /// Slip speed, electrical rad/s.
    pub omega_sl_rad_s: f32,
    /// Rotor-flux model estimate, Wb.
    pub psi_r_wb: f32,
    /// q-axis current reference, A.
    pub i_q_ref_a: f32,
    /// Speed reference of the speed loop, mechanical rad/s.
    pub omega_ref_rad_s: f32,
}

/// Output of one fast step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FastOutput {
    /// Bridge command.
    pub phases: PhaseCommand,
    /// Mode after this step.
    pub mode: Mode,
    /// Signals.
    pub telemetry: Telemetry,
}

/// A drive: configuration plus all loop states.
#[derive(Clone, Copy, Debug)]
pub struct Drive {
    cfg: DriveConfig,
    mode: Mode,
    reference: Reference,
    torque_cmd: TorqueCommand,
    omega_ref_rad_s: f32,
    /// Fast steps until the next slow step (0: this one).
    steps_to_slow: u16,
    current: CurrentState<f32>,
    ifoc: IfocState,
    speed: SpeedState,
    test_angle_rad: f32,
    /// Consecutive slow steps with the stall condition.
    stall_steps: u32,
    /// Consecutive fast steps with the voltage request outside the hexagon.
    saturated_steps: u32,
    /// Consecutive slow periods with an implausible encoder.
    encoder_bad_steps: u32,
}

impl Drive {
    /// A drive in `Idle` with a zero speed reference.
    pub fn new(cfg: DriveConfig) -> Self {
        Self {
            cfg,
            mode: Mode::Idle,
            reference: Reference::Speed(0.0),
            torque_cmd: TorqueCommand::TorqueNm(0.0),
            omega_ref_rad_s: 0.0,
            steps_to_slow: 0,
            current: CurrentState::default(),
            ifoc: cfg.ifoc.state(0.0),
            speed: SpeedState::default(),
            test_angle_rad: 0.0,
            stall_steps: 0,
            saturated_steps: 0,
            encoder_bad_steps: 0,
        }
    }

    /// Present mode.
    pub fn mode(&self) -> Mode {
        self.mode
    }

    /// The configuration.
    pub fn config(&self) -> &DriveConfig {
        &self.cfg
    }

    /// Current-loop states (their PI `p_term`/`i_term` are telemetry).
    pub fn current_state(&self) -> &CurrentState<f32> {
        &self.current
    }

    /// Speed-loop state (PI `p_term`/`i_term` when a PI law is configured).
    pub fn speed_state(&self) -> &SpeedState {
        &self.speed
    }

    /// IFOC state: field angle and rotor-flux estimate.
    pub fn ifoc_state(&self) -> &IfocState {
        &self.ifoc
    }

    /// Idle → Magnetizing with fresh loop states. No effect when already active.
    pub fn enable(&mut self) -> Result<(), CommandError> {
        match self.mode {
            Mode::Fault(_) => Err(CommandError::Faulted),
            Mode::Idle => {
                self.current = CurrentState::default();
                self.ifoc = self.cfg.ifoc.state(0.0);
                self.speed = SpeedState::default();
                self.torque_cmd = TorqueCommand::TorqueNm(0.0);
                self.steps_to_slow = 0;
                self.test_angle_rad = 0.0;
                self.stall_steps = 0;
                self.saturated_steps = 0;
                self.encoder_bad_steps = 0;
                self.mode = Mode::Magnetizing;
                Ok(())
            }
            Mode::Magnetizing | Mode::Running => Ok(()),
        }
    }

    /// Back to Idle (phases off). A latched fault stays latched.
    pub fn disable(&mut self) {
        if !matches!(self.mode, Mode::Fault(_)) {
            self.mode = Mode::Idle;
        }
    }

    /// Fault → Idle.
    pub fn clear_fault(&mut self) {
        if matches!(self.mode, Mode::Fault(_)) {
            self.mode = Mode::Idle;
        }
    }

    /// Set the outer-loop reference (takes effect at the next slow step).
    pub fn set_reference(&mut self, r: Reference) -> Result<(), CommandError> {
        let finite = match r {
            Reference::Speed(x) | Reference::Position(x) | Reference::Torque(x) => x.is_finite(),
            Reference::RotatingCurrent { amplitude_a, omega_rad_s } => {
                amplitude_a.is_finite() && omega_rad_s.is_finite()
            }
        };
        if !finite {
            return Err(CommandError::NonFinite);
        }
        self.reference = r;
        Ok(())
    }

    /// One PWM period: the slow step on every N-th call, then the fast step.
    #[inline]
    pub fn step(&mut self, m: &Measurements) -> FastOutput {
        if self.steps_to_slow == 0 {
            self.slow_step(m);
            self.steps_to_slow = self.cfg.slow_divider.saturating_sub(1);
        } else {
            self.steps_to_slow -= 1;
        }
        self.fast_step(m)
    }

    /// Speed/position loop, and the slow supervisor: overspeed (while the bridge is active)
    /// and stall (while Running under a speed or position reference). Holds a zero torque
    /// command unless Running; ignores non-finite measurements (the fast step trips on them).
    pub fn slow_step(&mut self, m: &Measurements) {
        let active = matches!(self.mode, Mode::Magnetizing | Mode::Running);
        if active && m.omega_m_rad_s.abs() > self.cfg.overspeed_rad_s {
            self.trip(Fault::Overspeed);
        }
        if self.mode != Mode::Running || !m.is_finite() {
            self.torque_cmd = TorqueCommand::TorqueNm(0.0);
            return;
        }
        self.torque_cmd = match self.reference {
            Reference::Torque(t) => TorqueCommand::TorqueNm(t),
            Reference::RotatingCurrent { .. } => TorqueCommand::TorqueNm(0.0),
            Reference::Speed(w) => {
                self.omega_ref_rad_s = w;
                self.cfg.speed.update(&mut self.speed, w, m.omega_m_rad_s)
            }
            Reference::Position(th) => {
                let w = self.cfg.position.update(th, m.theta_m_rad);
                self.omega_ref_rad_s = w;
                self.cfg.speed.update(&mut self.speed, w, m.omega_m_rad_s)
            }
        };
        let commanding_motion = matches!(self.reference, Reference::Speed(_) | Reference::Position(_));
        let (TorqueCommand::TorqueNm(u) | TorqueCommand::IqA(u)) = self.torque_cmd;
        let saturated = u.abs() >= 0.999 * self.cfg.speed_limit;
        if commanding_motion && saturated && m.omega_m_rad_s.abs() < self.cfg.stall_speed_rad_s {
            self.stall_steps = self.stall_steps.saturating_add(1);
            if self.stall_steps >= self.cfg.stall_slow_steps {
                self.trip(Fault::Stall);
                self.torque_cmd = TorqueCommand::TorqueNm(0.0);
            }
        } else {
            self.stall_steps = 0;
        }
    }

    /// All supervisor checks pass: the common case, tested without working out which check
    /// fails. The phase currents are checked on their bit patterns: with the sign bit
    /// cleared, an IEEE 754 float orders like an unsigned integer, and ±∞ and NaN lie above
    /// every finite value. So `|i| > i_trip` (finite i) and "i not finite" are both
    /// `abs_bits(i) > abs_bits(i_trip)`: one integer comparison per phase, on the integer
    /// units, while the floating-point units run the control law. Equal to
    /// `self.supervise(m).is_none()` for every input (`supervisor_bit_test_equals_float_test`).
    #[inline]
    fn measurements_ok(&self, m: &Measurements) -> bool {
        let i = m.i_abc_a;
        let i_peak_bits = abs_bits(i.a).max(abs_bits(i.b)).max(abs_bits(i.c));
        let rest_finite = m.vdc_v.is_finite() && m.omega_m_rad_s.is_finite() && m.theta_m_rad.is_finite();
        let active = matches!(self.mode, Mode::Magnetizing | Mode::Running);
        i_peak_bits <= self.cfg.i_trip_bits
            && abs_bits(i.a + i.b + i.c) <= self.cfg.i_sum_bits
            && rest_finite
            && m.vdc_v <= self.cfg.vdc_max_v
            && !(active && m.vdc_v < self.cfg.vdc_min_v)
    }

    /// Which supervisor check fails, in order of precedence: non-finite input, overcurrent,
    /// current-sensor plausibility, bus overvoltage, bus undervoltage (only while the bridge
    /// is active).
    fn supervise(&self, m: &Measurements) -> Option<Fault> {
        if !m.is_finite() {
            return Some(Fault::NonFiniteInput);
        }
        let i = m.i_abc_a;
        let i_peak = max_f32(max_f32(i.a.abs(), i.b.abs()), i.c.abs()); // finite: checked above
        if i_peak > f32::from_bits(self.cfg.i_trip_bits) {
            return Some(Fault::Overcurrent);
        }
        if (i.a + i.b + i.c).abs() > f32::from_bits(self.cfg.i_sum_bits) {
            return Some(Fault::CurrentSensor);
        }
        if m.vdc_v > self.cfg.vdc_max_v {
            return Some(Fault::DcBusOvervoltage);
        }
        let active = matches!(self.mode, Mode::Magnetizing | Mode::Running);
        if active && m.vdc_v < self.cfg.vdc_min_v {
            return Some(Fault::DcBusUndervoltage);
        }
        None
    }

    /// The rare path of the fast step: a supervisor check failed; latch its fault.
    #[cold]
    #[inline(never)]
    fn trip_on(&mut self, m: &Measurements) {
        // `measurements_ok` and `supervise` agree, so this is always Some.
        if let Some(f) = self.supervise(m) {
            self.trip(f);
        }
    }

    /// Latch fault `f` (the first fault stays latched): phases off from the next fast step
    /// on. The supervisor calls it; the firmware calls it for faults only it can see.
    pub fn trip(&mut self, f: Fault) {
        if !matches!(self.mode, Mode::Fault(_)) {
            self.mode = Mode::Fault(f);
        }
    }

    /// Encoder against the machine model: the magnitude of the applied voltage against that
    /// of the steady-state voltage [`EmfModel`] of the measured currents at the encoder's
    /// speed. A frozen encoder at speed leaves the back-EMF in the applied voltage and takes
    /// it out of the model.
    #[inline(never)]
    fn check_encoder(
        &mut self,
        i_ab: AlphaBeta,
        v_ab: AlphaBeta,
        field: &IfocOutput,
        omega_m: f32,
        v_limit: f32,
    ) {
        let e = &self.cfg.emf;
        let (i, v) = (i_ab.park(field.field), v_ab.park(field.field));
        let w_e = e.pole_pairs * omega_m + field.omega_sl_rad_s;
        let vd = e.rs_ohm * i.d - w_e * e.sigma_ls_h * i.q;
        let vq = e.rs_ohm * i.q + w_e * (e.sigma_ls_h * i.d + e.lm_over_lr * self.ifoc.psi_r_wb());
        // Magnitudes, not vectors: a detuned field angle (rotor resistance off by the
        // certified 2×) turns the voltage vector but hardly changes its length, while a
        // frozen encoder at speed removes the back-EMF from the model's length.
        let residual = (libm::hypotf(v.d, v.q) - libm::hypotf(vd, vq)).abs();
        // Consecutive implausible checks (a leaky count accumulated the detuned corner's
        // transients into a false trip).
        if residual > ENCODER_RESIDUAL_FRACTION * v_limit {
            self.encoder_bad_steps = self.encoder_bad_steps.saturating_add(1);
            if self.encoder_bad_steps >= self.cfg.encoder_check_steps {
                self.trip(Fault::EncoderImplausible);
            }
        } else {
            self.encoder_bad_steps = 0;
        }
    }

    /// Current loop. See the module docs for the signal flow.
    #[inline]
    pub fn fast_step(&mut self, m: &Measurements) -> FastOutput {
        if !self.measurements_ok(m) {
            self.trip_on(m);
        }
        let off = |mode| FastOutput { phases: PhaseCommand::Off, mode, telemetry: Telemetry::default() };
        let running = self.mode == Mode::Running;
        if !running && self.mode != Mode::Magnetizing {
            return off(self.mode); // Idle or Fault
        }
        let cfg = &self.cfg;
        let i_ab = m.i_abc_a.clarke();
        let cmd = if running { self.torque_cmd } else { TorqueCommand::TorqueNm(0.0) };
        let field = match self.reference {
            Reference::RotatingCurrent { amplitude_a, omega_rad_s } if running => {
                let a = amplitude_a.limit(0.0, cfg.ifoc.i_max_a());
                let th = self.test_angle_rad;
                self.test_angle_rad = wrap_angle(th + omega_rad_s * cfg.ts_s);
                let sc = SinCos::new(th);
                IfocOutput {
                    i_ref_dq: Dq { d: a, q: 0.0 },
                    i_ref_ab: AlphaBeta { alpha: a * sc.cos, beta: a * sc.sin },
                    theta_e_rad: th,
                    field: sc,
                    omega_sl_rad_s: 0.0,
                }
            }
            _ => cfg.ifoc.update(&mut self.ifoc, &cfg.flux, cmd, m.omega_m_rad_s),
        };
        let v_limit = svpwm::linear_limit_v(m.vdc_v);
        // The loops' outputs, and whether either axis sits on its limit (the loop no longer
        // controls that axis's current).
        let (v_ab, clamped) = match cfg.current_frame {
            CurrentFrame::Stationary => {
                let v = cfg.current.update(&mut self.current, field.i_ref_ab, i_ab, v_limit);
                (v, max_f32(v.alpha.abs(), v.beta.abs()) >= v_limit)
            }
            CurrentFrame::Synchronous => {
                let sc = field.field;
                let v = cfg.current.update_dq(&mut self.current, field.i_ref_dq, i_ab.park(sc), v_limit);
                (v.inverse_park(sc), max_f32(v.d.abs(), v.q.abs()) >= v_limit)
            }
        };
        if !(v_ab.alpha.is_finite() && v_ab.beta.is_finite()) {
            self.trip(Fault::NonFiniteOutput);
            return off(self.mode);
        }
        let modulation = svpwm::modulate(v_ab, m.vdc_v);
        if clamped || modulation.saturated {
            self.saturated_steps = self.saturated_steps.saturating_add(1);
            if self.saturated_steps >= cfg.saturation_steps {
                self.trip(Fault::LossOfControl);
                return off(self.mode);
            }
        } else {
            self.saturated_steps = 0;
        }
        // Once per slow period (the fast step right after the slow step), while Running on
        // the field-oriented references: the encoder against the machine model.
        let field_oriented = !matches!(self.reference, Reference::RotatingCurrent { .. });
        if running && field_oriented && self.steps_to_slow == cfg.slow_divider.saturating_sub(1) {
            self.check_encoder(i_ab, modulation.v_applied, &field, m.omega_m_rad_s, v_limit);
            if self.mode != Mode::Running {
                return off(self.mode);
            }
        }
        if !running && self.ifoc.psi_r_wb() >= self.cfg.psi_running_wb {
            // The flux model says magnetized; the motor must agree: the measured d-axis
            // current has followed its reference (the model runs on the reference).
            let i_d = i_ab.park(field.field).d;
            if i_d >= MAGNETIZING_CURRENT_FRACTION * field.i_ref_dq.d {
                self.mode = Mode::Running;
                self.speed = SpeedState::default();
                self.stall_steps = 0;
            } else {
                self.trip(Fault::NoMotorCurrent);
                return off(self.mode);
            }
        }
        FastOutput {
            phases: PhaseCommand::Duty(modulation.duty),
            mode: self.mode,
            telemetry: Telemetry {
                i_ab_a: i_ab,
                i_ref_ab_a: field.i_ref_ab,
                v_ab_v: modulation.v_applied,
                theta_e_rad: field.theta_e_rad,
                omega_sl_rad_s: field.omega_sl_rad_s,
                psi_r_wb: self.ifoc.psi_r_wb(),
                i_q_ref_a: field.i_ref_dq.q,
                omega_ref_rad_s: self.omega_ref_rad_s,
            },
        }
    }
}

/// `x`'s bits with the sign bit cleared (the bits of |x|).
#[inline]
fn abs_bits(x: f32) -> u32 {
    x.to_bits() & 0x7fff_ffff
}

/// Test data: the DeLorenzo DL10115A1 drive of seed 002 (ICAD eq. (20), saturated-P speed
/// loop eq. (21), 20 kHz, ψ_r* = 0.9 Wb). Not the shipped configuration — that is the
/// workspace's `drive.toml`, read by the `drive-file` crate; nothing keeps the two equal.
#[cfg(test)]
pub(crate) fn test_spec() -> DriveSpec {
    DriveSpec {
        motor: MotorParams::new(16.2, 23.2, 1.44, 1.5, 1.42, 1, 0.005, 0.0005).unwrap(),
        pwm_frequency_hz: 20_000.0,
        slow_divider: 10,
        current_law: CurrentLaw::ICAD_EQ20,
        discretization: Discretization::Tustin,
        current_frame: CurrentFrame::Stationary,
        speed_law: SpeedLaw::SaturatedP { kp: 0.05, tau_max_nm: 2.0 },
        position: PositionLaw { k_per_s: 10.0, omega_max_rad_s: 150.0 },
        flux_ref_wb: 0.9,
        flux_floor_wb: 0.05,
        i_ref_max_a: 4.0,
        magnetized_fraction: 0.95,
        protection: Protection {
            i_trip_a: 8.0,
            vdc_min_v: 200.0,
            vdc_max_v: 400.0,
            overspeed_rad_s: 450.0,
            stall_time_s: 0.3,
            current_sum_max_a: 0.4,
            saturation_time_s: 0.02,
            encoder_check_time_s: 0.01,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn drive() -> Drive {
        Drive::new(DriveConfig::new(&test_spec()).unwrap())
    }

    fn meas(vdc: f32) -> Measurements {
        Measurements { vdc_v: vdc, ..Default::default() }
    }

    /// Per-phase R-L load standing in for a locked-rotor machine (seen from the stator at
    /// high frequency: R_s and σL_s). Returns the current after applying `duty` for one
    /// period on `vdc` (exact ZOH of di/dt = (v − R i)/L per phase, star point floating:
    /// the common-mode voltage is removed).
    fn rl_step(i: Abc, duty: Abc, vdc: f32, r: f32, l: f32, ts: f32) -> Abc {
        let v = Abc { a: (duty.a - 0.5) * vdc, b: (duty.b - 0.5) * vdc, c: (duty.c - 0.5) * vdc };
        let v0 = (v.a + v.b + v.c) / 3.0;
        let a = libm::expf(-r / l * ts);
        let step = |i: f32, v: f32| a * i + (1.0 - a) * (v - v0) / r;
        Abc { a: step(i.a, v.a), b: step(i.b, v.b), c: step(i.c, v.c) }
    }

    #[test]
    fn rejects_inconsistent_specs() {
        let ok = test_spec();
        let bad = |f: &dyn Fn(&mut DriveSpec)| {
            let mut s = ok;
            f(&mut s);
            DriveConfig::new(&s).err()
        };
        assert_eq!(bad(&|s| s.pwm_frequency_hz = 0.0), Some(DriveError::PwmFrequency));
        assert_eq!(bad(&|s| s.slow_divider = 0), Some(DriveError::SlowDivider));
        assert_eq!(bad(&|s| s.protection.i_trip_a = 3.0), Some(DriveError::Protection));
        assert_eq!(bad(&|s| s.protection.vdc_min_v = 500.0), Some(DriveError::Protection));
        assert_eq!(bad(&|s| s.flux_ref_wb = f64::NAN), Some(DriveError::FluxReference));
        assert_eq!(bad(&|s| s.magnetized_fraction = 1.0), Some(DriveError::MagnetizedFraction));
        assert_eq!(
            bad(&|s| s.speed_law = SpeedLaw::SaturatedP { kp: 1.0, tau_max_nm: -1.0 }),
            Some(DriveError::Speed(SpeedError::Limit))
        );
        assert!(bad(&|_| ()).is_none());
    }

    #[test]
    fn state_machine_and_fault_latching() {
        let mut d = drive();
        assert_eq!(d.fast_step(&meas(310.0)).phases, PhaseCommand::Off);
        d.enable().unwrap();
        assert_eq!(d.mode(), Mode::Magnetizing);
        assert!(matches!(d.fast_step(&meas(310.0)).phases, PhaseCommand::Duty(_)));
        // Undervoltage while active trips; phases off in the same step.
        let out = d.fast_step(&meas(100.0));
        assert_eq!(out.mode, Mode::Fault(Fault::DcBusUndervoltage));
        assert_eq!(out.phases, PhaseCommand::Off);
        // Latched: enable refused, a later overcurrent does not overwrite the first cause.
        assert_eq!(d.enable(), Err(CommandError::Faulted));
        let over = Measurements { i_abc_a: Abc { a: 9.0, b: -4.5, c: -4.5 }, ..meas(310.0) };
        assert_eq!(d.fast_step(&over).mode, Mode::Fault(Fault::DcBusUndervoltage));
        d.disable();
        assert!(matches!(d.mode(), Mode::Fault(_)));
        d.clear_fault();
        assert_eq!(d.mode(), Mode::Idle);
        // Undervoltage is not a fault while idle (bus not yet charged); overvoltage is.
        assert_eq!(d.fast_step(&meas(0.0)).mode, Mode::Idle);
        assert_eq!(d.fast_step(&meas(450.0)).mode, Mode::Fault(Fault::DcBusOvervoltage));
        assert_eq!(d.set_reference(Reference::Speed(f32::NAN)), Err(CommandError::NonFinite));
    }

    /// A drive brought to Running on the R-L load (computed once, then copied).
    /// Overspeed trips while the bridge is active (in the slow step), never while Idle.
    #[test]
    fn overspeed_trips_only_while_active() {
        let limit = test_spec().protection.overspeed_rad_s as f32;
        let fast = Measurements { vdc_v: 310.0, omega_m_rad_s: 1.01 * limit, ..Default::default() };
        let mut d = drive();
        d.step(&fast);
        assert_eq!(d.mode(), Mode::Idle);
        let mut d = running_drive();
        let ok = Measurements { omega_m_rad_s: 0.99 * limit, ..fast };
        for _ in 0..20 {
            d.step(&ok);
        }
        assert_eq!(d.mode(), Mode::Running);
        let mut d = running_drive();
        d.slow_step(&Measurements { omega_m_rad_s: -1.01 * limit, ..fast });
        assert_eq!(d.mode(), Mode::Fault(Fault::Overspeed));
    }

    /// With no measured current the flux model alone cannot take the drive to Running (the
    /// second line of defence: with the default saturation time, `LossOfControl` comes
    /// first, so it is set long here).
    #[test]
    fn magnetizing_without_current_is_no_motor_current() {
        let mut spec = test_spec();
        spec.protection.saturation_time_s = 10.0;
        let mut d = Drive::new(DriveConfig::new(&spec).unwrap());
        d.enable().unwrap();
        let m = Measurements { vdc_v: 310.0, ..Default::default() };
        let mut k = 0;
        while d.mode() == Mode::Magnetizing && k < 100_000 {
            d.step(&m);
            k += 1;
        }
        assert_eq!(d.mode(), Mode::Fault(Fault::NoMotorCurrent));
        // T_r·ln(1/(1 − 0.95)) = 0.194 s: the check happens where Running would have begun.
        assert!((k as f64 / 20_000.0 - 0.194).abs() < 0.01, "{k}");
    }

    fn running_drive() -> Drive {
        static RUNNING: std::sync::OnceLock<Drive> = std::sync::OnceLock::new();
        *RUNNING.get_or_init(|| {
            let mut d = drive();
            d.enable().unwrap();
            let mut i = Abc::default();
            while d.mode() != Mode::Running {
                if let PhaseCommand::Duty(duty) =
                    d.step(&Measurements { i_abc_a: i, vdc_v: 310.0, ..Default::default() }).phases
                {
                    i = rl_step(i, duty, 310.0, 16.2, 0.1, 5e-5);
                }
            }
            d
        })
    }

    /// Wiring check of the whole fast path (Clarke → IFOC → current loops → SVPWM → duty →
    /// volts), in both current-loop frames: on an R-L load the d-current settles at
    /// ψ_r*/L_m, the flux model reaches the running threshold, and the drive moves to
    /// Running by itself.
    #[test]
    fn magnetizes_an_rl_load_and_enters_running() {
        for frame in [CurrentFrame::Stationary, CurrentFrame::Synchronous] {
            let spec = DriveSpec { current_frame: frame, ..test_spec() };
            let mut d = Drive::new(DriveConfig::new(&spec).unwrap());
            d.enable().unwrap();
            let (r, l, ts, vdc) = (16.2f32, 0.1f32, 5e-5f32, 310.0f32);
            let mut i = Abc::default();
            let mut out = d.step(&Measurements { i_abc_a: i, vdc_v: vdc, ..Default::default() });
            for _ in 0..20_000 {
                if let PhaseCommand::Duty(duty) = out.phases {
                    i = rl_step(i, duty, vdc, r, l, ts);
                }
                out = d.step(&Measurements { i_abc_a: i, vdc_v: vdc, ..Default::default() });
            }
            assert_eq!(d.mode(), Mode::Running, "{frame:?}");
            // i_ds* = 0.9/1.42 = 0.6338 A; at standstill with zero torque, θ_e stays 0, so the
            // reference is on α: i_α → 0.6338 A, i_β → 0.
            let t = out.telemetry;
            assert!((t.i_ref_ab_a.alpha - 0.9 / 1.42).abs() < 1e-4);
            assert!((t.i_ab_a.alpha - t.i_ref_ab_a.alpha).abs() < 1e-3, "{frame:?} {t:?}");
            assert!(t.i_ab_a.beta.abs() < 1e-3);
            // In steady state the d (= α here) voltage R·i comes from the integrator.
            let pi = d.current_state().axis1.pi;
            assert!((pi.i_term - 16.2 * t.i_ab_a.alpha).abs() < 0.05, "{frame:?} {pi:?}");
            assert!(pi.p_term.abs() < 0.5);
        }
    }

    #[test]
    fn rotating_current_reference() {
        let mut d = running_drive();
        d.set_reference(Reference::RotatingCurrent { amplitude_a: 100.0, omega_rad_s: 300.0 }).unwrap();
        let mut refs = std::vec::Vec::new();
        // Ideal current tracking (the measured current is the previous reference): with no
        // current at all the loops would sit at their limit and trip `LossOfControl`.
        let mut i = AlphaBeta::default();
        for _ in 0..2000 {
            let m = Measurements { i_abc_a: i.inverse_clarke(), ..meas(310.0) };
            i = d.step(&m).telemetry.i_ref_ab_a;
            refs.push(i);
        }
        // Amplitude limited to i_ref_max = 4 A; β lags α by 90°: α = 4 cos θ, β = 4 sin θ.
        for r in &refs {
            assert!((r.magnitude() - 4.0).abs() < 1e-4);
        }
        // 2000 steps at 300 rad/s · 50 µs: the angle advanced by 30 rad.
        let (a, b) = (refs.first().unwrap(), refs.last().unwrap());
        let turned = libm::atan2f(b.beta, b.alpha) - libm::atan2f(a.beta, a.alpha);
        let expected = crate::frames::wrap_angle(1999.0 * 300.0 * 5e-5);
        assert!((crate::frames::wrap_angle(turned - expected)).abs() < 1e-3);
        assert_eq!(
            d.set_reference(Reference::RotatingCurrent { amplitude_a: 1.0, omega_rad_s: f32::INFINITY }),
            Err(CommandError::NonFinite)
        );
    }

    fn finite_meas() -> impl Strategy<Value = Measurements> {
        (-20.0f32..20.0, -20.0f32..20.0, -20.0f32..20.0, 0.0f32..600.0, -1e4f32..1e4, -1e6f32..1e6).prop_map(
            |(a, b, c, vdc_v, w, th)| Measurements {
                i_abc_a: Abc { a, b, c },
                vdc_v,
                omega_m_rad_s: w,
                theta_m_rad: th,
            },
        )
    }

    /// Any float, weighted towards the trip levels (±8 A; 200 and 400 V) and the specials.
    fn any_measured() -> impl Strategy<Value = f32> {
        prop_oneof![
            any::<u32>().prop_map(f32::from_bits),
            -20.0f32..20.0,
            150.0f32..450.0,
            proptest::sample::select(vec![
                8.0f32,
                -8.0,
                200.0,
                400.0,
                0.0,
                -0.0,
                f32::MAX,
                f32::MIN_POSITIVE
            ]),
            proptest::sample::select(vec![8.0f32.next_up(), (-8.0f32).next_down(), 8.0f32.next_down()]),
            non_finite(),
        ]
    }

    fn non_finite() -> impl Strategy<Value = f32> {
        prop_oneof![Just(f32::NAN), Just(f32::INFINITY), Just(f32::NEG_INFINITY)]
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        /// Any finite inputs: outputs finite and inside their limits, whatever the mode.
        #[test]
        fn finite_inputs_give_bounded_outputs(seq in proptest::collection::vec(finite_meas(), 1..200),
                                              r in -1e3f32..1e3, which in 0u8..4, start_running: bool) {
            let mut d = if start_running { running_drive() } else { drive() };
            let reference = match which {
                0 => Reference::Speed(r),
                1 => Reference::Position(r),
                2 => Reference::Torque(r),
                _ => Reference::RotatingCurrent { amplitude_a: r, omega_rad_s: r },
            };
            d.set_reference(reference).unwrap();
            d.enable().unwrap();
            for m in &seq {
                let out = d.step(m);
                match out.phases {
                    PhaseCommand::Off => prop_assert!(!matches!(out.mode, Mode::Magnetizing | Mode::Running)),
                    PhaseCommand::Duty(duty) => {
                        for x in [duty.a, duty.b, duty.c] {
                            prop_assert!((0.0..=1.0).contains(&x));
                        }
                        let t = out.telemetry;
                        let lim = svpwm::linear_limit_v(m.vdc_v) * 2.0 / 1.732_050_8 + 1e-3;
                        prop_assert!(t.v_ab_v.magnitude() <= lim);
                        prop_assert!(t.i_ref_ab_a.magnitude() <= 4.0 + 1e-3);
                        prop_assert!(t.theta_e_rad.is_finite() && t.psi_r_wb.is_finite());
                    }
                }
            }
        }

        /// Any NaN/inf in any input field: Fault within one fast step, phases off.
        #[test]
        fn non_finite_input_trips_in_one_step(warm in proptest::collection::vec(finite_meas(), 0..50),
                                              mut bad in finite_meas(), field in 0u8..6, x in non_finite()) {
            let mut d = running_drive();
            for m in &warm {
                d.step(m);
            }
            match field {
                0 => bad.i_abc_a.a = x,
                1 => bad.i_abc_a.b = x,
                2 => bad.i_abc_a.c = x,
                3 => bad.vdc_v = x,
                4 => bad.omega_m_rad_s = x,
                _ => bad.theta_m_rad = x,
            }
            let out = d.step(&bad);
            prop_assert_eq!(out.phases, PhaseCommand::Off);
            prop_assert!(matches!(out.mode, Mode::Fault(_)));
        }
    }

    proptest! {
        // Cheap cases; many, so that the exact trip levels come up.
        #![proptest_config(ProptestConfig::with_cases(4096))]

        /// `Drive::measurements_ok` (bit patterns) passes exactly when `Drive::supervise` and
        /// the float comparisons written out here find no fault, in every mode.
        #[test]
        fn supervisor_bit_test_equals_float_test(
            base in (-4.0f32..=4.0, -4.0f32..=4.0, -0.6f32..=0.6, 200.0f32..=400.0, -1e4f32..1e4, -1e6f32..1e6),
            changes in proptest::collection::vec((0usize..6, any_measured()), 0..3),
            mode in 0u8..3,
        ) {
            let mut d = drive();
            match mode {
                0 => {}
                1 => d.enable().unwrap(),
                _ => d = running_drive(),
            }
            // A measurement whose currents sum to about zero (the third phase closes the sum to
            // within ±0.6 A, across the 0.4 A plausibility level), with up to two fields
            // replaced by anything.
            let mut x = [base.0, base.1, -(base.0 + base.1) + base.2, base.3, base.4, base.5];
            for (field, value) in changes {
                if let Some(v) = x.get_mut(field) {
                    *v = value;
                }
            }
            let m = Measurements {
                i_abc_a: Abc { a: x[0], b: x[1], c: x[2] },
                vdc_v: x[3],
                omega_m_rad_s: x[4],
                theta_m_rad: x[5],
            };
            let spec = test_spec();
            let p = spec.protection;
            let float_test = if ![x[0], x[1], x[2], x[3], x[4], x[5]].iter().all(|v| v.is_finite()) {
                Some(Fault::NonFiniteInput)
            } else if x[0].abs().max(x[1].abs()).max(x[2].abs()) > p.i_trip_a as f32 {
                Some(Fault::Overcurrent)
            } else if (x[0] + x[1] + x[2]).abs() > p.current_sum_max_a as f32 {
                Some(Fault::CurrentSensor)
            } else if x[3] > p.vdc_max_v as f32 {
                Some(Fault::DcBusOvervoltage)
            } else if d.mode() != Mode::Idle && x[3] < p.vdc_min_v as f32 {
                Some(Fault::DcBusUndervoltage)
            } else {
                None
            };
            prop_assert_eq!(d.supervise(&m), float_test);
            prop_assert_eq!(d.measurements_ok(&m), float_test.is_none());
        }
    }
}
