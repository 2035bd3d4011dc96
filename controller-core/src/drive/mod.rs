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
//! phase currents → IFOC's fast part (the slow step's plan: current references in αβ at the
//! field angle, the field turned by one step, the measured current summed for the flux
//! model) → α/β current controllers (or d/q controllers between Park and
//! inverse Park, [`CurrentFrame::Synchronous`]) → their voltage request, advanced by the
//! delay from sampling to application ([`VOLTAGE_DELAY_PERIODS`]) → SVPWM duties. **One vector
//! limit**: the modulator scales a request beyond the inverter's hexagon onto it, keeping its
//! angle, and the loops' integrators then track the voltage applied. The step returns the
//! bridge command, the mode and the brake chopper's switch; its signals (currents,
//! references, voltage, field angle, flux) are made on demand by [`Drive::telemetry`] from
//! what it left — a logger, the capture or the link's stream asks, not every period.
//! **Slow step** (every N-th period, [`Drive::slow_step`]): the IFOC's period closed (flux
//! model, slip angle); the encoder's position anchors the field angle (rotor angle plus
//! integrated slip); the current trim (a slow integral of the
//! field-frame current error, [`DriveSpec::current_trim_bandwidth_rad_s`]); the voltage
//! regulator (the budget `voltage_margin·V_dc/√3`, cut when the loops ask for more); position
//! loop (if a position reference is active) → speed loop, limited to the torque the bus can
//! give at this speed → the **operating point** ([`crate::envelope`]: the d-axis current —
//! rated flux below base speed, weakened above — and the torque limited to the envelope and to
//! what the flux that is there can drive now) → the IFOC's plan for the fast steps (i_qs*,
//! slip, the field and its rotation per step); the stuck-switch check.
//! [`Drive::step`] runs the slow step on every N-th call, then the fast step — what the
//! firmware's control interrupt and the simulators call.
//!
//! **Supervisor**: [`crate::supervisor`], one module per family of checks; the drive runs them
//! at their rates and latches what they find (first thing in the fast step: the instant
//! limits). The fast step performs no indexing, no division by unchecked values that could
//! panic, and no `unwrap`: it cannot panic for any input (property-tested).
//!
//! The rooms: [`spec`](DriveSpec) (the specification and the drive's design constants),
//! `config` ([`DriveConfig`]: validated, discretised, its raw codec), `fast` (the fast step),
//! `slow` (the slow step's stages), this module (the state, the commands and the step).

mod config;
mod fast;
mod slow;
mod spec;
#[cfg(test)]
mod tests;
#[cfg(test)]
pub(crate) use tests::test_spec;

pub use crate::fault::{Fault, FaultSet, Mode};
pub use crate::io::{CommandError, FastOutput, Measurements, PhaseCommand, Reference, Telemetry};
pub use crate::supervisor::encoder::{ENCODER_RESIDUAL_FRACTION, PINNED_FIELD_TURN_RAD, PINNED_PHASE_COS};
pub use crate::supervisor::motion::{
    FOLLOWING_PROGRESS_FRACTION, STALL_REFERENCE_FACTOR, STALL_SPEED_FRACTION,
};
pub use crate::supervisor::phases::{
    CURRENT_SUM_MEAN_FRACTION, OPEN_PHASE_ABSENT_FRACTION, OPEN_PHASE_COMMANDED_FRACTION,
    OPEN_PHASE_OTHERS_FRACTION, OPEN_PHASE_REF_SHARE, OPEN_PHASE_WINDOWS, SWITCH_FLOOR_SHARE,
    SWITCH_FOLLOWING_SHARE, SWITCH_FOLLOWING_WINDOWS, SWITCH_LEVEL_SHARE, SWITCH_MISSING_SHARE, SWITCH_SEEN,
    SWITCH_SHORTFALL_MISSING, SWITCH_WINDOWS, UNDRIVEN_REFERENCE_SHARE, UNDRIVEN_SAMPLES,
};
pub use crate::supervisor::thermal::THERMAL_UPDATE_SLOW_STEPS;
pub use crate::supervisor::{BrakeChopper, Protection, ThermalLimit};
pub use config::DriveConfig;
pub use spec::*;

use crate::current::CurrentState;
use crate::envelope::{Envelope, EnvelopeConfig};
use crate::frames::{AlphaBeta, Dq, SinCos};
use crate::ifoc::{FluxCommand, IfocState, TorqueCommand};
#[cfg(doc)]
use crate::mras::MrasConfig;
use crate::mras::RotorFit;
use crate::num::Scalar;
use crate::speed::SpeedState;
use crate::supervisor::encoder::{EncoderTrack, VoltageCheck};
use crate::supervisor::motion::MotionChecks;
use crate::supervisor::phases::{OpenPhaseWindow, SwitchWatch};
use crate::supervisor::rest::RestWatch;
use crate::supervisor::thermal::ThermalState;

/// What [`Drive::telemetry`] reads of the last fast step (stationary frame): the measured
/// current, the current references, the voltage applied.
#[derive(Clone, Copy, Debug, Default)]
struct StepSignals {
    i_ab: AlphaBeta,
    i_ref_ab: AlphaBeta,
    v_ab: AlphaBeta,
}

/// A drive: its configuration and its state, grouped by lifetime and owner — the rule of
/// what survives what is written in these types:
///
/// | group | what | made afresh by |
/// |---|---|---|
/// | the commands (these fields) | mode, reference, a controlled stop under way | [`Drive::new`]; a reconfiguration keeps the mode (a fault stays latched) and starts the reference at rest |
/// | `machine`: `MachineState` | the motor's and the inverter's temperature (I²t), the shaft's position and turns, whether it is at rest, how long the rotor has been left, the brake chopper's comparator | [`Drive::new`] only (power-up): kept by [`Drive::enable`] and by [`Drive::reconfigure`] |
/// | `run`: `RunState` | one run of the bridge: the loops, the field, the plan, the checks' counts; and the estimates it runs on (R_r, the inductances) | [`Drive::enable`] and [`Drive::reconfigure`], which carry the estimates into the new run |
///
/// The board's own state (the current sensors' offsets, the encoder's speed window, the
/// capture) is the firmware's, beside the drive (`firmware::control::ControlLoop`).
#[derive(Clone, Copy, Debug)]
pub struct Drive {
    cfg: DriveConfig,
    mode: Mode,
    reference: Reference,
    /// Speed reference of the speed loop at the last slow step (telemetry), rad/s.
    omega_ref_rad_s: f32,
    /// A fault answered by a controlled stop ([`Protection::stop_on`]), latched when the stop
    /// ends.
    pending_fault: Option<Fault>,
    /// Slow steps left of a controlled stop (`None`: not stopping).
    stop_steps_left: Option<u32>,
    /// Fast steps until the next slow step (0: this one): the cadence whoever reads the
    /// encoder every N-th period keeps in step with.
    steps_to_slow: u16,
    machine: MachineState,
    run: RunState,
}

/// What belongs to the machine and the board, not to a run or a configuration: kept by
/// [`Drive::enable`] and [`Drive::reconfigure`] (a gain write must not cool a hot motor's
/// protection, nor lose the shaft's position).
#[derive(Clone, Copy, Debug)]
struct MachineState {
    /// The I²t models ([`crate::supervisor::thermal`]).
    thermal: ThermalState,
    /// The encoder's readings: the shaft's position and turns, the jump check's last change.
    encoder: EncoderTrack,
    /// The rotor at rest ([`crate::supervisor::rest`]).
    rest: RestWatch,
    /// Slow steps with the bridge off (saturating): whether the rotor has lost its flux
    /// ([`MrasConfig::demagnetized_after`]).
    idle_slow_steps: u32,
    /// The brake chopper's comparator state.
    brake: bool,
}

impl MachineState {
    /// At power-up: cold, nothing read, nothing has driven the rotor.
    const POWER_UP: Self = Self {
        thermal: ThermalState::COLD,
        encoder: EncoderTrack::NONE,
        rest: RestWatch::NONE,
        idle_slow_steps: u32::MAX,
        brake: false,
    };
}

/// One run of the bridge, from an enable: made afresh by [`Drive::enable`] and
/// [`Drive::reconfigure`] ([`RunState::new`]), on the estimates the last run left.
#[derive(Clone, Copy, Debug)]
struct RunState {
    torque_cmd: TorqueCommand,
    current: CurrentState<f32>,
    /// The field orientation's state; it holds the estimates the run is on (R_r, the
    /// inductances: [`IfocState::rotor_resistance_scale`], [`IfocState::inductance_scale`]).
    ifoc: IfocState,
    speed: SpeedState,
    test_angle_rad: f32,
    /// The stall and following-error checks ([`crate::supervisor::motion`]).
    motion: MotionChecks,
    /// Consecutive fast steps with the voltage request outside the hexagon.
    saturated_steps: u32,
    /// The encoder-against-the-model check ([`crate::supervisor::encoder`]).
    voltage_check: VoltageCheck,
    /// The open-phase check's window: Σ|i_ref| and Σ|i| per phase, and its steps so far.
    open_phase: OpenPhaseWindow,
    /// The stuck-switch check's half-waves.
    switches: SwitchWatch,
    /// The flux (d-axis current) command of the present operating point.
    flux: FluxCommand,
    /// The envelope's d-axis current of the last slow step, A: the flux reference's
    /// (`flux` holds it lowered while the flux falls: [`FLUX_FALL_TIME_S`]).
    i_d_target_a: f32,
    /// The flux is being forced down: its back-EMF went beyond the voltage target, and it
    /// has not yet fallen to the operating point's flux ([`EnvelopeConfig::d_current_within_voltage`]).
    flux_forced: bool,
    /// Largest steady torque of the envelope at the last slow step, N·m (the speed loop's
    /// limit).
    torque_max_nm: f32,
    /// The voltage regulator's cut of the budget, V (≤ 0).
    v_cut_v: f32,
    /// Sum of the current loops' |v_request|² since the last slow step, V².
    v_req2_sum: f32,
    /// Fast steps in `v_req2_sum`.
    v_req_steps: u16,
    /// Sum of the d-axis voltage since the last slow step while magnetizing — the loops'
    /// request, or the modulator's limit of it while it limits (the magnetizing fit's), V.
    v_d_sum: f32,
    /// The magnetizing fit of the rotor resistance ([`crate::mras`]).
    rotor_fit: RotorFit,
    /// The machine model on the inductance in use ([`EnvelopeConfig::with_inductance_scale`]):
    /// the envelope's, the encoder check's and the rotor-resistance law's.
    model: EnvelopeConfig,
    /// The d-axis current of the rated flux on the inductance in use, A.
    i_d_rated_a: f32,
    /// Slow steps spent magnetizing.
    magnetizing_steps: u32,
    /// The rotor's electrical angle from the encoder, rad, in `[-π, π)`.
    theta_r_rad: f32,
    /// The rotation that advances the output voltage over the delay
    /// ([`VOLTAGE_DELAY_PERIODS`]), from the field speed at the last slow step.
    delay_rotation: SinCos,
    /// The speed loop's output was at its limit at the last slow step.
    speed_saturated: bool,
    /// The envelope in use ([`EnvelopeConfig::envelope`]).
    envelope: Envelope,
    /// Slow steps until it is remade.
    envelope_age: u16,
    /// The current trim added to the loops' references (field frame), A.
    trim: Dq,
    /// The modulator limited the voltage since the last slow step (the trim holds).
    trim_hold: bool,
    /// The last fast step's signals.
    last: StepSignals,
    /// The rotating-current test's angle in the last fast step, rad.
    last_test_angle_rad: f32,
}

impl RunState {
    /// A run of `cfg` from rest (no flux, no torque, every count at zero) on the rotor
    /// resistance `rr_scale` and the inductances `l_scale` × the motor's, with the
    /// magnetizing fit `rotor_fit`. Out of line: one copy for power-up, an enable and a
    /// reconfiguration (inlined into each, the firmware took ≈ 1.2 KB more flash).
    #[inline(never)]
    fn new(cfg: &DriveConfig, rr_scale: f32, l_scale: f32, rotor_fit: RotorFit) -> Self {
        Self {
            torque_cmd: TorqueCommand::TorqueNm(0.0),
            current: CurrentState::default(),
            ifoc: {
                let mut s = cfg.ifoc.state(0.0, rr_scale);
                cfg.ifoc.set_inductance_scale(&mut s, l_scale);
                s
            },
            speed: SpeedState::default(),
            test_angle_rad: 0.0,
            motion: MotionChecks::default(),
            saturated_steps: 0,
            voltage_check: VoltageCheck::default(),
            open_phase: OpenPhaseWindow::default(),
            switches: SwitchWatch::default(),
            flux: FluxCommand::default(),
            i_d_target_a: 0.0,
            flux_forced: false,
            torque_max_nm: 0.0,
            v_cut_v: 0.0,
            v_req2_sum: 0.0,
            v_req_steps: 0,
            v_d_sum: 0.0,
            rotor_fit,
            model: cfg.envelope.with_inductance_scale(l_scale),
            i_d_rated_a: cfg.i_d_rated_a / l_scale,
            magnetizing_steps: 0,
            theta_r_rad: 0.0,
            delay_rotation: SinCos::default(),
            speed_saturated: false,
            envelope: Envelope::ZERO,
            envelope_age: 0,
            trim: Dq::default(),
            trim_hold: false,
            last: StepSignals::default(),
            last_test_angle_rad: 0.0,
        }
    }
}

impl Drive {
    /// A drive in `Idle` with a zero speed reference, at power-up: a cold machine, nothing
    /// read of the encoder, the estimates at the configuration's initial values.
    /// `#[inline]`: compiled in the caller's crate — in the firmware at its opt-level "z"
    /// (start-up; out of line at controller-core's 2, +72 B).
    #[inline]
    pub fn new(cfg: DriveConfig) -> Self {
        let run = RunState::new(
            &cfg,
            cfg.mras.initial_scale(),
            cfg.mras.initial_inductance_scale(),
            RotorFit::default(),
        );
        Self {
            cfg,
            mode: Mode::Idle,
            reference: Reference::Speed(0.0),
            omega_ref_rad_s: 0.0,
            pending_fault: None,
            stop_steps_left: None,
            steps_to_slow: 0,
            machine: MachineState::POWER_UP,
            run,
        }
    }

    /// Swap the configuration for `cfg` — new gains (the firmware's `WriteSpeedGains`), or a
    /// new drive file for the same machine — keeping the machine's state: the motor's and
    /// the inverter's I²t temperature (θ rescaled if the rated current changed,
    /// [`ThermalLimit`]), the encoder's position and turns, how long the rotor has been
    /// left, the brake chopper's state. The estimates (R_r, the inductances, × the motor
    /// file's) carry over, limited to `cfg`'s ranges — an estimate inside them is one `cfg`'s
    /// certificate covers. The run starts afresh, the reference at rest (`Speed(0)`), a
    /// latched fault stays latched, and the slow cadence keeps its phase unless the divider
    /// changed (then the encoder's jump check starts again at the new read period). As in
    /// stabilizer and idsp: the configuration is swapped, the state is kept. Another machine
    /// is another drive ([`Drive::new`]; the link's `Configure` tells them apart).
    ///
    /// Refused while the bridge is active ([`CommandError::Active`]): the drive is left as
    /// it was. `#[inline]`: compiled in the caller's crate — in the firmware at its
    /// opt-level "z" (a gain write).
    #[inline]
    pub fn reconfigure(&mut self, cfg: DriveConfig) -> Result<(), CommandError> {
        if self.mode.is_active() {
            return Err(CommandError::Active);
        }
        let old = &self.cfg;
        let [rr_min, rr_max] = cfg.mras.range();
        let [l_min, l_max] = cfg.mras.inductance_range();
        let rr = self.run.ifoc.rotor_resistance_scale().limit(rr_min, rr_max);
        let l = self.run.ifoc.inductance_scale().limit(l_min, l_max);
        let thermal = &mut self.machine.thermal;
        thermal.motor = old.motor_thermal.carry(thermal.motor, &cfg.motor_thermal);
        thermal.inverter = old.inverter_thermal.carry(thermal.inverter, &cfg.inverter_thermal);
        if cfg.slow_divider != old.slow_divider {
            self.steps_to_slow = 0;
            self.machine.encoder.restart_jump_check();
        }
        self.run = RunState::new(&cfg, rr, l, RotorFit::default());
        (self.reference, self.omega_ref_rad_s) = (Reference::Speed(0.0), 0.0);
        (self.pending_fault, self.stop_steps_left) = (None, None);
        self.cfg = cfg;
        Ok(())
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
        &self.run.current
    }

    /// Speed-loop state (PI `p_term`/`i_term` when a PI law is configured).
    pub fn speed_state(&self) -> &SpeedState {
        &self.run.speed
    }

    /// IFOC state: field angle and rotor-flux estimate.
    pub fn ifoc_state(&self) -> &IfocState {
        &self.run.ifoc
    }

    /// The next [`Drive::step`] runs the slow step, which reads the measurements' encoder
    /// values (the one cadence: a caller that reads the encoder every N-th period reads it
    /// for this step).
    pub fn slow_step_due(&self) -> bool {
        self.steps_to_slow == 0
    }

    /// The last [`Drive::step`] ran the slow step, and the cadence has periods without one
    /// (a slow divider above 1): the firmware leaves the link's requests to a period without
    /// it, so that the longest period is the slow step's or a request's, not both.
    pub fn slow_step_ran(&self) -> bool {
        let divider = self.cfg.slow_divider;
        divider > 1 && self.steps_to_slow == divider - 1
    }

    /// Slow steps since a bridge last drove the rotor (saturating; `u32::MAX` from power-up):
    /// what decides whether the next enable measures the inductances
    /// ([`MrasConfig::demagnetized_after`]).
    pub fn idle_slow_steps(&self) -> u32 {
        self.machine.idle_slow_steps
    }

    /// The rotor was driven by something else `idle_slow_steps` slow steps ago (0: now) — a
    /// commissioning sequence in the drive's place, or the drive this one replaces (a new
    /// configuration): its flux may still be there at the next enable.
    pub fn rotor_driven(&mut self, idle_slow_steps: u32) {
        self.machine.idle_slow_steps = idle_slow_steps;
    }

    /// Idle → Magnetizing with a fresh run (`RunState`: the loops, the field, the checks'
    /// counts), on the estimates the last run left: the rotor resistance's estimate is the
    /// rotor's temperature, the inductance's the machine's. The machine's state carries on
    /// (`MachineState`), and so does the slow cadence: whoever reads the encoder every
    /// N-th period (the firmware, the simulator) stays in step with the slow step. No effect
    /// when already active. `#[inline]`: compiled in the caller's crate — in the firmware,
    /// with its commands at opt-level "z" (−148 B of flash), not at controller-core's 2.
    #[inline]
    pub fn enable(&mut self) -> Result<(), CommandError> {
        match self.mode {
            Mode::Fault(_) => Err(CommandError::Faulted),
            Mode::Idle => {
                let fit = RotorFit::new(self.cfg.mras.demagnetized_after(self.machine.idle_slow_steps));
                let (rr, l) = (self.run.ifoc.rotor_resistance_scale(), self.run.ifoc.inductance_scale());
                self.run = RunState::new(&self.cfg, rr, l, fit);
                self.machine.idle_slow_steps = 0;
                self.mode = Mode::Magnetizing;
                Ok(())
            }
            Mode::Magnetizing | Mode::Running => Ok(()),
        }
    }

    /// Back to Idle (phases off). A latched fault stays latched.
    pub fn disable(&mut self) {
        if !matches!(self.mode, Mode::Fault(_)) {
            // A fault answered by a controlled stop latches when the bridge goes off.
            self.mode = match self.pending_fault.take() {
                Some(f) => Mode::Fault(f),
                None => Mode::Idle,
            };
        }
        self.stop_steps_left = None;
    }

    /// A fault answered by a controlled stop that is under way ([`Protection::stop_on`]): it
    /// latches when the bridge goes off.
    pub fn pending_fault(&self) -> Option<Fault> {
        self.pending_fault
    }

    /// The thermal models' states, motor and inverter (1 = the steady temperature rise at
    /// the rated current; the limit is `overload_factor²`; 0 without a limit).
    pub fn thermal_state(&self) -> (f32, f32) {
        (self.machine.thermal.motor, self.machine.thermal.inverter)
    }

    /// React to fault `f`: a controlled stop, the fault latched when it ends, if `f` is in
    /// `stop_on` and the drive is Running; otherwise the bridge off at once ([`Drive::trip`]).
    #[cold]
    #[inline(never)]
    pub(super) fn fault_reaction(&mut self, f: Fault) {
        if self.cfg.stop_on.contains(f) && self.mode == Mode::Running {
            if self.pending_fault.is_none() {
                self.pending_fault = Some(f);
                self.reference = Reference::Speed(0.0);
                if self.stop_steps_left.is_none() {
                    self.stop_steps_left = Some(self.cfg.stop_slow_steps);
                }
            }
        } else {
            self.trip(f);
        }
    }

    /// A controlled stop (stop category 1): Running, the speed loop brakes to standstill
    /// within its torque and regeneration limits, then the bridge goes off (Idle) — once the
    /// speed is below the stall check's "not moving" level, or after `stop_time_s` at the
    /// latest; Magnetizing, the bridge goes off at once. A new reference (the host is back)
    /// cancels the stop. What the firmware does when its link falls silent.
    pub fn controlled_stop(&mut self) {
        match self.mode {
            _ if self.pending_fault.is_some() => {}
            Mode::Running if self.stop_steps_left.is_none() => {
                self.reference = Reference::Speed(0.0);
                self.stop_steps_left = Some(self.cfg.stop_slow_steps);
            }
            Mode::Magnetizing => self.disable(),
            _ => {}
        }
    }

    /// A controlled stop is under way.
    pub fn is_stopping(&self) -> bool {
        self.stop_steps_left.is_some()
    }

    /// Fault → Idle (the encoder's jump check judges again from the second change after,
    /// [`Fault::EncoderLoss`]'s jump being no reference).
    pub fn clear_fault(&mut self) {
        if matches!(self.mode, Mode::Fault(_)) {
            self.mode = Mode::Idle;
            // The encoder's last change may be the jump that latched `EncoderLoss`: no
            // reference for the next one.
            self.machine.encoder.forget_last_change();
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
        if self.pending_fault.is_some() {
            // A stop for a fault is not cancelled by a new reference.
            return Err(CommandError::Faulted);
        }
        self.reference = r;
        self.stop_steps_left = None;
        Ok(())
    }

    /// One PWM period: the slow step on every N-th call, then the fast step.
    pub fn step(&mut self, m: &Measurements) -> FastOutput {
        let after_slow = self.steps_to_slow == 0;
        if after_slow {
            self.slow_step(m);
            self.steps_to_slow = self.cfg.slow_divider.saturating_sub(1);
        } else {
            self.steps_to_slow -= 1;
        }
        self.fast(m, after_slow)
    }

    /// Latch fault `f` (the first fault stays latched): phases off from the next fast step
    /// on. The supervisor calls it; the firmware calls it for faults only it can see. Out of
    /// line (a fault's path: inlined, its eight callers took 376 B of flash).
    #[inline(never)]
    pub fn trip(&mut self, f: Fault) {
        if !matches!(self.mode, Mode::Fault(_)) {
            // A fault whose controlled stop was under way came first.
            self.mode = Mode::Fault(self.pending_fault.take().unwrap_or(f));
            self.stop_steps_left = None;
        }
    }

    /// The rotor has been at rest over the rest check's last windows
    /// ([`crate::supervisor::rest`]: `p·|ω_m|·T_r` at most 0.05 over `rest_time_s`, twice in
    /// a row): what commissioning's standstill tests need before they start. Watched in every
    /// mode; `false` from power-up until the windows have passed.
    pub fn rotor_at_rest(&self) -> bool {
        self.machine.rest.at_rest()
    }

    /// Multi-turn mechanical position from the encoder, rad (the position loop's;
    /// `EncoderTrack::position_rad`).
    pub fn position_rad(&self) -> f32 {
        self.machine.encoder.position_rad()
    }

    /// The signals of the last fast step, for logs, traces and the capture: made on demand
    /// from what the step left (its measured current, current references and voltage) and
    /// the drive's state, not in every step. All zero unless the bridge is active
    /// (Magnetizing or Running) — as after a step that tripped. Out of line: its callers
    /// (the firmware's capture and link stream) take it rarely.
    #[inline(never)]
    pub fn telemetry(&self) -> Telemetry {
        if !self.mode.is_active() {
            return Telemetry::default();
        }
        let rotating =
            matches!(self.reference, Reference::RotatingCurrent { .. }) && self.mode == Mode::Running;
        let s = &self.run.ifoc;
        let (theta_e_rad, omega_sl_rad_s, i_q_ref_a) = if rotating {
            (self.run.last_test_angle_rad, 0.0, 0.0)
        } else {
            (s.last_theta_e_rad(), s.omega_sl_rad_s(), s.i_ref_dq().q)
        };
        Telemetry {
            i_ab_a: self.run.last.i_ab,
            i_ref_ab_a: self.run.last.i_ref_ab,
            v_ab_v: self.run.last.v_ab,
            theta_e_rad,
            omega_sl_rad_s,
            psi_r_wb: s.psi_r_wb(),
            psi_ref_wb: s.flux_of(self.run.i_d_target_a),
            i_q_ref_a,
            omega_ref_rad_s: self.omega_ref_rad_s,
            rr_scale: s.rotor_resistance_scale(),
            l_scale: s.inductance_scale(),
        }
    }
}
