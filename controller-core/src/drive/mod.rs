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
//! [`Drive::step`] latches the slow step's inputs and runs it on every N-th call, adopts its
//! plan [`DriveConfig::plan_delay`] calls later, and runs the fast step on every call — what
//! the firmware's control interrupt and the simulators call.
//!
//! **Supervisor**: [`crate::supervisor`], one module per family of checks; the drive runs them
//! at their rates and latches what they find (first thing in the fast step: the instant
//! limits). The fast step performs no indexing, no division by unchecked values that could
//! panic, and no `unwrap`: it cannot panic for any input (property-tested).
//!
//! **Two contexts** (issue 54): a [`Drive`] is two halves that never share a byte — the
//! [`FastSide`] (`FastState`: the mode, the current loops, the plan in force, the fast
//! step's sums; its own copy of the configuration) and the [`SlowSide`] (`SlowState`: the
//! reference, the machine's state, the flux model, the loops of the outer rates, the checks;
//! its copy of the configuration; the job latched at the tick). The slow step reads the fast
//! side only through what is latched for it (`SlowInputs`, taken at its tick) and acts on it
//! only through its plan, which the fast side adopts at a fixed period,
//! [`plan_delay_periods`] after the tick ([`FastSide::step`]) — so that it can run in a
//! context of its own, preempted by the fast interrupt ([`SlowContext`]: the fast side
//! reaches the slow side only at the tick and the adoption, and a slow side not back then is
//! [`Fault::Overrun`]), and the drive still steps alike on the board, in QEMU and in the
//! simulator (which keeps the halves together: [`Drive::step`]). The plan is made for the
//! period that adopts it: the field anchored on the encoder at the tick and turned over the
//! delay by the plan in force, the slip angle closed over the plans the fast steps ran. The
//! once-per-slow-period checks on the adopting period's fast step (the encoder against the
//! machine model, the rotor-resistance law) run on its signals (`AfterSlow`, latched with the
//! next tick's inputs) at the start of the next slow step. The commands act on both halves
//! ([`DriveMut`]); the firmware serves them while no slow step is in flight
//! ([`Drive::slow_busy`]).
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
pub(crate) use tests::{rl_step, test_spec};

pub use crate::fault::{Fault, FaultSet, Mode};
pub use crate::io::{
    CommandError, FastOutput, Measurements, PhaseCommand, Reference, Telemetry, TelemetryField,
};
pub use crate::supervisor::encoder::{
    ENCODER_ACCEL_FACTOR, ENCODER_RESIDUAL_FRACTION, JUMP_SPACING_MAX, PINNED_FIELD_TURN_RAD,
    PINNED_PHASE_COS,
};
pub use crate::supervisor::motion::{
    FOLLOWING_PROGRESS_FRACTION, STALL_REFERENCE_FACTOR, STALL_SPEED_FRACTION,
};
pub use crate::supervisor::phases::{
    CURRENT_SENSOR_GAIN_TOLERANCE, CURRENT_SUM_MEAN_FRACTION, OPEN_PHASE_ABSENT_FRACTION,
    OPEN_PHASE_COMMANDED_FRACTION, OPEN_PHASE_OTHERS_FRACTION, OPEN_PHASE_REF_SHARE, OPEN_PHASE_WINDOWS,
    SWITCH_FLOOR_SHARE, SWITCH_FOLLOWING_SHARE, SWITCH_FOLLOWING_WINDOWS, SWITCH_LEVEL_SHARE,
    SWITCH_MISSING_SHARE, SWITCH_SEEN, SWITCH_SHORTFALL_MISSING, SWITCH_WINDOWS, UNDRIVEN_REFERENCE_SHARE,
    UNDRIVEN_SAMPLES,
};
pub use crate::supervisor::thermal::THERMAL_UPDATE_SLOW_STEPS;
pub use crate::supervisor::{BrakeChopper, Protection, ThermalLimit};
pub use config::{
    DriveConfig, FLOATS, INTEGERS, RawDriveConfig, SEARCH_RESOLVED_TURN_RAD, SEARCH_TURN_MAX_RAD,
    SEARCH_WINDOWS_MIN, encoder_jump_shares, observer_speed_bandwidth_rad_s, peak_acceleration_rad_s2,
};
pub use spec::*;

use crate::calibration::IdleZero;
use crate::current::CurrentState;
use crate::envelope::{Envelope, EnvelopeConfig};
use crate::frames::{AlphaBeta, Dq, SinCos};
use crate::ifoc::FieldSteps;
use crate::ifoc::{FluxCommand, IfocState, TorqueCommand};
#[cfg(doc)]
use crate::mras::MrasConfig;
use crate::mras::RotorFit;
use crate::num::Scalar;
use crate::observer::{Estimate, FluxObserver};
use crate::speed::SpeedState;
use crate::speed_search::SpeedSearch;
use crate::supervisor::encoder::{EncoderTrack, VoltageCheck};
use crate::supervisor::motion::MotionChecks;
use crate::supervisor::phases::{OpenPhaseWindow, SwitchWatch};
use crate::supervisor::rest::RestWatch;
use crate::supervisor::thermal::ThermalState;
use crate::vhz::{VhzPlan, VhzReport, VhzState};

/// What [`Drive::telemetry`] reads of the last fast step (stationary frame): the measured
/// current, the current references, the voltage applied.
#[derive(Clone, Copy, Debug, Default)]
struct StepSignals {
    i_ab: AlphaBeta,
    i_ref_ab: AlphaBeta,
    v_ab: AlphaBeta,
}

/// A drive: its configuration and its state, in two halves — the fast context's
/// ([`FastSide`]) and the slow context's ([`SlowSide`]), each with its own copy of the
/// configuration — grouped within them by lifetime and owner; the rule of what survives what
/// is written in these types:
///
/// | group | what | made afresh by |
/// |---|---|---|
/// | `FastState`'s own fields, `SlowState`'s | mode, reference, a controlled stop under way, the slow cadence | [`Drive::new`]; a reconfiguration keeps the mode (a fault stays latched) and starts the reference at rest |
/// | `MachineState` (slow), the brake comparator (fast) | the motor's and the inverter's temperature (I²t), the shaft's position and turns, whether it is at rest, how long the rotor has been left, the brake chopper's comparator | [`Drive::new`] only (power-up): kept by [`Drive::enable`] and by [`Drive::reconfigure`] |
/// | `FastRun`, `SlowRun` | one run of the bridge: the loops, the field, the plan, the checks' counts; and the estimates it runs on (R_r, the inductances) | [`Drive::enable`] and [`Drive::reconfigure`], which carry the estimates into the new run |
///
/// The simulators own a `Drive` and step it whole ([`Drive::step`]: the slow step's job runs
/// at its tick, in the same call). The firmware owns the halves apart
/// ([`Drive::into_parts`]): the fast interrupt the [`FastSide`], a slower interrupt the
/// [`SlowSide`] while its job runs — the two never share a byte — and it commands the drive
/// through a [`DriveMut`] made of both while the slow side is back.
///
/// The board's own state (the current sensors' offsets, the encoder's speed window, the
/// capture) is the firmware's, beside the drive (`firmware::control::ControlLoop`).
///
/// `repr(C)`, the fast side first: the fast step's loads within the Cortex-M4F's reach
/// from the drive's address ([`FastSide`]).
#[derive(Clone, Copy, Debug)]
#[repr(C)]
pub struct Drive {
    fast: FastSide,
    slow: SlowSide,
}

/// The fast context's half of a [`Drive`]: the bridge's state every period, the
/// configuration, V/Hz's fast run. Steps with [`FastSide::step`].
///
/// `repr(C)`, the fast step's state first and its configuration next: within the
/// Cortex-M4F's ±1 020 B reach of a floating-point load from the half's address (laid out
/// by the compiler, the slow state came first and the fast step paid address arithmetic).
#[derive(Clone, Copy, Debug)]
#[repr(C)]
pub struct FastSide {
    state: FastState,
    cfg: DriveConfig,
    vhz: VhzRun,
    /// The slow side's signals of the plan in force, adopted with it
    /// ([`SlowSide`]'s `plan_signals`): the slow part of [`FastSide::signal`].
    plan_signals: SlowSignals,
}

/// The slow context's half of a [`Drive`]: the loops of the outer rates, the machine's
/// state, the checks, a copy of the configuration, and the job latched at the last tick
/// ([`SlowSide::run`]).
#[derive(Clone, Copy, Debug)]
pub struct SlowSide {
    state: SlowState,
    cfg: DriveConfig,
    /// The job latched at the last tick, written in place by the fast side's latch (built
    /// by value and moved into an `Option`, it was copied twice in the tick's period) …
    job: SlowJob,
    /// … and not run yet.
    job_due: bool,
    order: Order,
    /// Its signals as its last job left them ([`SlowSide::signals`]): the plan's, which the
    /// fast side adopts with it.
    plan_signals: SlowSignals,
}

/// What a command on the slow side asks of the fast side ([`DriveMut`]): taken at once when
/// the command has the fast side too, or with the next plan the fast side adopts when the
/// slow context commands the slow side alone ([`DriveMut::slow_only`], the board's link).
/// The mode and the reference travel as every plan's do.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Order {
    /// A new run: the fast step's (`FastRun`) and V/Hz's afresh (an enable, a
    /// reconfiguration).
    restart: bool,
    /// The slow side's configuration taken (a reconfiguration).
    reconfigured: bool,
    /// Its speed law and the stall check's limit alone (a gain write,
    /// [`DriveMut::write_speed_gains`]) — the fast side reads neither, so its copy stays the
    /// slow side's at two fields' cost (the whole configuration's, 584 B, cost the adopting
    /// period ≈ 500 instructions, `cost interrupt_worst_command_period`).
    speed_law: bool,
    /// The slow cadence starts again at this period (a new divider).
    cadence: bool,
    /// The slow side's mode taken, unless a fault of the fast step stands (an enable, a
    /// disable, a stop while magnetizing; the adoption takes it anyway).
    mode: bool,
    /// The fault cleared: the slow side's mode taken over the fast side's fault.
    cleared: bool,
}

/// The slow step's job: its inputs, latched from the fast side at the tick, and the V/Hz
/// law's state then (once it runs).
#[derive(Clone, Copy, Debug)]
struct SlowJob {
    inputs: SlowInputs,
    vhz: Option<VhzReport>,
}

/// Where the slow side is while the fast side steps ([`FastSide::step`]): beside it, its job
/// run at the tick (the simulator: [`SlowSide`] itself), or in a context of its own (the
/// board: the firmware's hand-off to a lower-priority interrupt).
pub trait SlowContext {
    /// `f` on the slow side if the fast context holds it now; false while it is lent to its
    /// job.
    fn with(&mut self, f: &mut dyn FnMut(&mut SlowSide)) -> bool;
    /// The tick: `latch` writes the job into the slow side, which is then started
    /// ([`SlowSide::run`]): run now, or the slow side handed to its context — in one borrow
    /// of it (the board's context notes there what its slow context serves beside the job).
    /// False if the slow side is not back or could not be handed over.
    fn start(&mut self, latch: &mut dyn FnMut(&mut SlowSide)) -> bool;
}

/// The simulator's: the slow side beside the fast one, its job run at its tick.
impl SlowContext for SlowSide {
    fn with(&mut self, f: &mut dyn FnMut(&mut SlowSide)) -> bool {
        f(self);
        true
    }

    fn start(&mut self, latch: &mut dyn FnMut(&mut SlowSide)) -> bool {
        latch(self);
        self.run();
        true
    }
}

/// The slow side's part of the drive's signals ([`DriveRef::telemetry`]), read from its
/// state: what the fast context reads of it while it holds it — the firmware's capture keeps
/// the last one read for the periods in which the slow side is at its job.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SlowSignals {
    omega_sl_rad_s: f32,
    i_q_ref_a: f32,
    psi_r_wb: f32,
    psi_ref_wb: f32,
    omega_ref_rad_s: f32,
    rr_scale: f32,
    l_scale: f32,
}

/// The fast side's part of the drive's signals ([`FastSide::signals`]): the last fast
/// step's currents and voltage, and the field angle of whichever law ran it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FastSignals {
    active: bool,
    i_ab: AlphaBeta,
    i_ref_ab: AlphaBeta,
    v_ab: AlphaBeta,
    theta_e_rad: f32,
    field: FieldOf,
}

/// Whose field [`FastSignals`] carries the angle of.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
enum FieldOf {
    /// The field orientation's (its slip, flux and q reference are the slow side's).
    #[default]
    Vector,
    /// The rotating-current test's: no slip, no q reference.
    Test,
    /// V/Hz's stator-flux frame, its operating point's slip and rotor flux.
    Vhz { omega_sl_rad_s: f32, psi_r_wb: f32 },
}

impl FastSignals {
    /// The drive's signals, with the slow side's part `s` ([`DriveRef::telemetry`]): all zero
    /// unless the bridge was active.
    pub fn join(&self, s: &SlowSignals) -> Telemetry {
        if !self.active {
            return Telemetry::default();
        }
        let (omega_sl_rad_s, i_q_ref_a, psi_r_wb) = match self.field {
            FieldOf::Vector => (s.omega_sl_rad_s, s.i_q_ref_a, s.psi_r_wb),
            FieldOf::Test => (0.0, 0.0, s.psi_r_wb),
            FieldOf::Vhz { omega_sl_rad_s, psi_r_wb } => (omega_sl_rad_s, 0.0, psi_r_wb),
        };
        Telemetry {
            i_ab_a: self.i_ab,
            i_ref_ab_a: self.i_ref_ab,
            v_ab_v: self.v_ab,
            theta_e_rad: self.theta_e_rad,
            omega_sl_rad_s,
            psi_r_wb,
            psi_ref_wb: s.psi_ref_wb,
            i_q_ref_a,
            omega_ref_rad_s: s.omega_ref_rad_s,
            rr_scale: s.rr_scale,
            l_scale: s.l_scale,
        }
    }
}

impl SlowSide {
    /// Its part of the drive's signals now.
    pub fn signals(&self) -> SlowSignals {
        let (s, ifoc) = (&self.state, &self.state.run.ifoc);
        SlowSignals {
            omega_sl_rad_s: ifoc.omega_sl_rad_s(),
            i_q_ref_a: ifoc.i_ref_dq().q,
            psi_r_wb: ifoc.psi_r_wb(),
            psi_ref_wb: ifoc.flux_of(s.run.i_d_target_a),
            omega_ref_rad_s: s.omega_ref_rad_s,
            rr_scale: ifoc.rotor_resistance_scale(),
            l_scale: ifoc.inductance_scale(),
        }
    }

    /// The job latched at the last tick, if it has not run (nothing otherwise): the slow
    /// step on its inputs (latched from the fast side, `FastState::latch`) and the slow
    /// side's state alone (`SlowState::step`) — what the board's slow context runs. Its plan
    /// is the fast side's [`DriveConfig::plan_delay`] periods after the tick
    /// ([`FastSide::step`]).
    ///
    /// First the once-per-slow-period checks on the fast step that adopted the last plan
    /// (latched with the inputs; `SlowState::after_slow_checks`): the encoder against the
    /// machine model, the rotor-resistance law.
    /// Speed/position loop, the operating point, and the slow supervisor: a non-finite
    /// encoder reading (in every mode), overspeed (while the bridge is active), stall (while
    /// Running under a speed or position reference) and the magnetizing time. Holds a zero
    /// torque command unless Running; otherwise ignores non-finite measurements (the fast
    /// step trips on the currents and the bus).
    ///
    /// Order: encoder → the IFOC's period closed ([`crate::ifoc::IfocConfig::close_period`]: flux model,
    /// slip angle) → field angle ([`crate::ifoc::IfocConfig::anchor`]); current trim; voltage regulator;
    /// speed loop limited to the envelope's torque at the last slow step; operating point
    /// ([`EnvelopeConfig::point`] on the envelope remade every [`crate::envelope::ENVELOPE_REFRESH_SLOW_STEPS`]:
    /// i_d*, and the torque limited to the envelope); magnetized → Running; the fast steps'
    /// plan ([`crate::ifoc::IfocConfig::plan`]); the phase checks (open phase, no motor current, the
    /// windowed current sum; a stuck switch while Running).
    pub fn run(&mut self) {
        if self.job_due {
            self.state.step(&self.cfg, &self.job.inputs, self.job.vhz.as_ref());
            self.job_due = false;
            self.plan_signals = self.signals();
        }
    }
}

/// The whole drive to command, made of its two halves while the fast context holds both
/// ([`DriveMut::new`]; [`Drive`]'s methods are these): the link's commands, a
/// reconfiguration.
#[derive(Debug)]
pub struct DriveMut<'a> {
    /// `None`: the slow context's, its commands' fast part ordered for the next adoption.
    fast: Option<&'a mut FastSide>,
    slow: &'a mut SlowSide,
}

/// The whole drive to read ([`DriveRef::new`]; [`Drive`]'s reading methods are these).
#[derive(Clone, Copy, Debug)]
pub struct DriveRef<'a> {
    fast: &'a FastSide,
    slow: &'a SlowSide,
}

impl<'a> DriveMut<'a> {
    /// The drive made of its halves: a command acts on both at once.
    pub fn new(fast: &'a mut FastSide, slow: &'a mut SlowSide) -> Self {
        Self { fast: Some(fast), slow }
    }

    /// The drive as the slow context commands it, holding the slow side alone (the board's
    /// link, served after the slow step's job): a command decides on the slow side's state
    /// — the mode latched at the tick, moved on by the job — acts on it, and leaves its
    /// fast part (a new run, the new configuration, the mode) to the plan the fast side
    /// adopts [`DriveConfig::plan_delay`] periods after the tick. A fault of the fast step
    /// in between stays latched (only a cleared fault's mode is taken over one).
    pub fn slow_only(slow: &'a mut SlowSide) -> Self {
        Self { fast: None, slow }
    }
}

impl<'a> DriveRef<'a> {
    /// The drive made of its halves.
    pub fn new(fast: &'a FastSide, slow: &'a SlowSide) -> Self {
        Self { fast, slow }
    }
}

/// The fast step's state: what the bridge runs on every period.
#[derive(Clone, Copy, Debug)]
struct FastState {
    /// The mode: the fast side's word is final (it switches the bridge); the slow side's
    /// changes reach it with the plan.
    mode: Mode,
    /// The slow side's fault answered by a controlled stop, if one is under way: a fault of
    /// the fast step latches it instead (the first fault stays latched).
    pending_fault: Option<Fault>,
    /// The reference as the fast step needs it (the rotating-current test's).
    reference: Reference,
    /// Fast steps until the next slow step (0: this one): the cadence whoever reads the
    /// encoder every N-th period keeps in step with.
    steps_to_slow: u16,
    /// The brake chopper's comparator state (the machine's: kept by enable and reconfigure).
    brake: bool,
    /// Sensorless: the shaft's angle as the estimated speed turns it, mechanical rad in
    /// `[-π, π)` — the encoder reading the drive gets instead of an encoder's (the machine's:
    /// kept by enable, so that the turn count does not jump).
    theta_est_rad: f32,
    /// Sensorless: the current sensors' residual offsets, tracked with the bridge off and
    /// taken off the measured currents with it on ([`IdleZero`]; the machine's: kept by
    /// enable).
    zero: IdleZero,
    /// Overmodulating: the phases without a sampling window in the last two periods' duties
    /// (this step's sample lies between them), as [`crate::svpwm::unsampled_phases`]' bits — the
    /// last period's first.
    unsampled: [u8; 2],
    run: FastRun,
}

/// One run of the bridge, the fast step's part: made afresh by [`Drive::enable`] and
/// [`Drive::reconfigure`].
#[derive(Clone, Copy, Debug, Default)]
struct FastRun {
    current: CurrentState<f32>,
    /// The plan in force, the field turned since its first step, the measured current's sums.
    field: FieldSteps,
    /// The rotation that advances the output voltage over the delay
    /// ([`VOLTAGE_DELAY_PERIODS`]), from the field speed of the plan in force.
    delay_rotation: SinCos,
    /// The current trim of the plan in force (field frame), A.
    trim: Dq,
    /// The voltage fed forward by the plan in force (field frame), V.
    v_ff: Dq,
    test_angle_rad: f32,
    /// Consecutive fast steps with the voltage request outside the hexagon.
    saturated_steps: u32,
    /// Sum of the current loops' |v_request|² since the last slow step, V².
    v_req2_sum: f32,
    /// Fast steps in `v_req2_sum`.
    v_req_steps: u16,
    /// Sum of the field-frame voltage since the last slow step while magnetizing — the
    /// loops' request, or the modulator's limit of it while it limits (the magnetizing
    /// fit's, [`crate::mras::FitPeriod`]), V.
    v_fit_sum: Dq,
    /// The modulator limited the voltage since the last slow step (the trim holds).
    trim_hold: bool,
    /// The last fast step's signals.
    last: StepSignals,
    /// The rotating-current test's angle in the last fast step, rad.
    last_test_angle_rad: f32,
    /// The signals of the fast step after the slow step for the once-per-slow-period checks.
    after_slow: Option<AfterSlow>,
    /// Sensorless: the flux and speed observer, the voltage applied over the period that
    /// ends at this step's sample (asked two steps ago), and its last estimate.
    observer: FluxObserver,
    v_interval: AlphaBeta,
    /// Sensorless: the sum of the speed estimates since the last slow step, rad/s, and their
    /// count — the slow step reads their mean ([`FastState::observe`]).
    omega_sum_rad_s: f32,
    omega_steps: u16,
    estimate: Estimate,
    /// Ride-through: the encoder's fault was ridden through, the speed and the field are the
    /// observer's (the slow side's [`SlowState::ridden_through`], adopted with its plan).
    on_observer: bool,
    /// Sensorless, magnetizing: the voltage model's `∫(u − R_s·i)dt` since the last slow
    /// step (the flying start's search, [`crate::speed_search`]), Wb.
    search_psi: AlphaBeta,
    /// Sensorless, magnetizing: the rotor's speed the search found, mechanical rad/s (0: at
    /// rest, or not yet known) — adopted from the slow side's plan.
    known_speed_rad_s: f32,
}

impl FastRun {
    /// Afresh, as [`Default`] makes it, field by field (the pattern names every field, so a
    /// new one cannot be left out): assigned whole, the run's zeroing was a `memclr` call of
    /// ≈ 190 instructions in the period that adopts an enable (`tools/qemu_profile.py
    /// --longest … FastSide::obey`).
    #[inline(always)]
    fn restart(&mut self) {
        let FastRun {
            current,
            field,
            delay_rotation,
            trim,
            v_ff,
            test_angle_rad,
            saturated_steps,
            v_req2_sum,
            v_req_steps,
            v_fit_sum,
            trim_hold,
            last,
            last_test_angle_rad,
            after_slow,
            observer,
            v_interval,
            omega_sum_rad_s,
            omega_steps,
            estimate,
            on_observer,
            search_psi,
            known_speed_rad_s,
        } = self;
        *current = Default::default();
        *field = Default::default();
        *delay_rotation = Default::default();
        *trim = Default::default();
        *v_ff = Default::default();
        *test_angle_rad = Default::default();
        *saturated_steps = Default::default();
        *v_req2_sum = Default::default();
        *v_req_steps = Default::default();
        *v_fit_sum = Default::default();
        *trim_hold = Default::default();
        *last = Default::default();
        *last_test_angle_rad = Default::default();
        *after_slow = Default::default();
        *observer = Default::default();
        *v_interval = Default::default();
        *omega_sum_rad_s = Default::default();
        *omega_steps = Default::default();
        *estimate = Default::default();
        *on_observer = Default::default();
        *search_psi = Default::default();
        *known_speed_rad_s = Default::default();
    }
}

/// V/Hz's fast-side run ([`crate::vhz`]): the law's state, the slow step's plan in force, and
/// whether the law has taken over the magnetized machine in this run — made afresh with
/// `FastRun`. Kept after the slow state, not in `FastRun`: there it moved the configuration
/// beyond the M4F's reach from the drive's address, and the vector drive's interrupt paid
/// for a law it does not run.
#[derive(Clone, Copy, Debug, Default)]
struct VhzRun {
    state: VhzState,
    plan: VhzPlan,
    on: bool,
}

impl VhzRun {
    /// What the slow step reads at its tick: the law's state, once it runs. Out of line: a
    /// vector drive does not carry it.
    #[cold]
    #[inline(never)]
    fn report(&self) -> Option<VhzReport> {
        self.on.then(|| self.state.report())
    }

    /// The slow step's plan for the law (the one it starts on, from the step that found the
    /// machine magnetized), and its frame made afresh from its angle.
    #[cold]
    #[inline(never)]
    fn adopt(&mut self, plan: &VhzPlan) {
        self.plan = *plan;
        if self.on {
            self.state.renew_field();
        }
    }
}

/// What the slow step reads of the fast side, latched at its tick ([`FastState::latch`]).
#[derive(Clone, Copy, Debug)]
struct SlowInputs {
    m: Measurements,
    /// The fast side's mode at the tick.
    mode: Mode,
    /// The measured current's sums since the last tick (field frame, A) and their count.
    sums: (Dq, u16),
    v_req2_sum: f32,
    v_req_steps: u16,
    v_fit_sum: Dq,
    /// The modulator limited the voltage since the last tick.
    limited: bool,
    /// The rotating-current test's angle at the tick, rad.
    test_angle_rad: f32,
    /// Sensorless and Running: the observer's rotor-flux angle at the tick, rad (the field
    /// is anchored on it).
    field_rad: Option<f32>,
    /// Sensorless, magnetizing: the voltage model's change since the last tick, Wb.
    search_psi: AlphaBeta,
    /// The fast step's current references at the tick, intended and tracked (the trim
    /// added), stationary frame, A: the phase checks judge the tick's sample against them.
    i_refs_ab: [AlphaBeta; 2],
    /// The voltage the fast step before the tick gave the bridge (stationary frame, the
    /// delay's advance included), V: which rail each leg held the phase at for most of the
    /// period around the tick's sample, for the stuck-switch check.
    v_ab: AlphaBeta,
    /// The signals of the fast step that adopted the last plan, for the once-per-slow-period
    /// checks (`None`: it was not Running on the field-oriented references).
    after_slow: Option<AfterSlow>,
}

impl SlowInputs {
    /// Nothing latched: the job before the first tick (never run: `SlowSide::job_due`).
    fn at_rest() -> Self {
        Self {
            m: Measurements::default(),
            mode: Mode::Idle,
            sums: (Dq::default(), 0),
            v_req2_sum: 0.0,
            v_req_steps: 0,
            v_fit_sum: Dq::default(),
            limited: false,
            test_angle_rad: 0.0,
            field_rad: None,
            search_psi: AlphaBeta::default(),
            i_refs_ab: [AlphaBeta::default(); 2],
            v_ab: AlphaBeta::default(),
            after_slow: None,
        }
    }
}

/// The fast step right after the slow step, as the once-per-slow-period checks read it
/// ([`Drive::after_slow_checks`]): Running on the field-oriented references.
#[derive(Clone, Copy, Debug)]
struct AfterSlow {
    omega_m_rad_s: f32,
    field: SinCos,
    i_meas_dq: Dq,
    v_applied: AlphaBeta,
    /// The voltage the bridge was given, back in the loops' frame (undone the delay's
    /// advance): their request, or the modulator's limit of it — what the machine got.
    v_given: AlphaBeta,
    v_usable_v: f32,
}

/// The slow step's state.
#[derive(Clone, Copy, Debug)]
struct SlowState {
    /// The mode as the slow side knows it: the fast side's at the tick, then its own
    /// changes (handed over with the plan).
    mode: Mode,
    reference: Reference,
    /// Speed reference of the speed loop at the last slow step (telemetry), rad/s.
    omega_ref_rad_s: f32,
    /// A fault answered by a controlled stop ([`Protection::stop_on`]), latched when the stop
    /// ends.
    pending_fault: Option<Fault>,
    /// Slow steps left of a controlled stop (`None`: not stopping).
    stop_steps_left: Option<u32>,
    /// Ride-through: the encoder's faults ridden through on the observer since the last
    /// enable ([`SpeedFeedback::EncoderRideThrough`]; reported, [`Drive::ridden_through`]).
    ridden_through: FaultSet,
    machine: MachineState,
    run: SlowRun,
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
    /// Sensorless: the stator resistance the last magnetizing fit measured, × the motor
    /// file's (the winding's temperature: it carries on); the observer runs on it.
    rs_scale: f32,
}

impl MachineState {
    /// At power-up: cold, nothing read, nothing has driven the rotor.
    const POWER_UP: Self = Self {
        thermal: ThermalState::COLD,
        encoder: EncoderTrack::NONE,
        rest: RestWatch::NONE,
        idle_slow_steps: u32::MAX,
        rs_scale: 1.0,
    };
}

/// One run of the bridge, the slow step's part: made afresh by [`Drive::enable`] and
/// [`Drive::reconfigure`] ([`SlowRun::new`]), on the estimates the last run left.
#[derive(Clone, Copy, Debug)]
struct SlowRun {
    torque_cmd: TorqueCommand,
    /// The field orientation's state; it holds the estimates the run is on (R_r, the
    /// inductances: [`IfocState::rotor_resistance_scale`], [`IfocState::inductance_scale`]),
    /// and the plan made last.
    ifoc: IfocState,
    speed: SpeedState,
    /// The stall and following-error checks ([`crate::supervisor::motion`]).
    motion: MotionChecks,
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
    /// The torque asked was at its limit at the last slow step (the speed loop's output
    /// saturated, or a torque reference at the envelope's): the speed rises as fast as the
    /// drive makes it (the voltage regulator's gain at the modulator's limit).
    torque_at_limit: bool,
    /// How far below the d current on which the flux falls of itself the forcing holds its
    /// reference, A (0 unforced): the stuck-switch check does not judge references the
    /// loops follow by that step at the voltage limit ([`SwitchWatch::add`]).
    forcing_a: f32,
    /// The speed the plan's voltage is judged at — the envelope, its operating point, the
    /// flux's forcing and the present flux's torque limit —, mechanical rad/s: the reading,
    /// held while the reading stays within half a count of the encoder's speed
    /// window of it (`DriveConfig::speed_hold_band_rad_s`; the observer's reading itself).
    /// At the voltage limit that limit is steep in the speed (the back-EMF takes nearly all
    /// of the voltage), and a speed held between two counts reads one or the other: judged
    /// at the reading, the population's member 022 (35 kW, 500 lines, 0.785 rad/s per count
    /// at 20 kHz) had its limit jump 53 ↔ 14 A each slow step accelerating through 140 rad/s,
    /// the references chattered by tens of A per 0.5 ms, the currents fell 50 % short and
    /// the stuck-switch check tripped a healthy drive (`SwitchOpen` on 10 of the fault
    /// matrix's top-speed rows over seeds 0–11). Held so, a reading alternating between two
    /// counts holds it between them, and a change of speed moves it at once, half a count
    /// behind — a whole count's band lagged a load's dip by a count, and member 001 at 4 kHz
    /// (8 poles, 500 lines) then dipped 0.16972 of its base speed against the 0.16967 its
    /// requirements allowed on a corner run (load on at its top speed) and tune refused it.
    /// One speed for all four: the point is made at the voltage limit, and a limit judged
    /// half a count above the speed the point was made at found the point's own current too
    /// much (member 022 at 4 kHz generating at 309 rad/s: i_q's limit fell from 92 to 77 A
    /// whenever the held speed sat above the reading, its braking torque dipping 16 % for a
    /// few slow periods; population test
    /// `a_point_at_the_voltage_limit_is_judged_at_the_speed_it_was_made_for`).
    omega_limit_rad_s: f32,
    /// The magnetizing fit of the rotor resistance ([`crate::mras`]).
    rotor_fit: RotorFit,
    /// The machine model on the inductance in use ([`EnvelopeConfig::with_inductance_scale`]):
    /// the envelope's, the encoder check's and the rotor-resistance law's.
    model: EnvelopeConfig,
    /// The d-axis current of the rated flux on the inductance in use, A.
    i_d_rated_a: f32,
    /// The magnetizing curve's chord at the flux model's current, × the rated one (1 for a
    /// linear motor): the inductance in use is the identified one × this
    /// ([`SlowRun::identified_inductance_scale`]; `SlowState::follow_curve`).
    chord: f32,
    /// A saturating motor's machine model: the chord of its magnetizing inductance at the
    /// operating point, × the rated one (1 for a linear motor; `SlowState::remodel`).
    model_chord: f32,
    /// Slow steps spent magnetizing.
    magnetizing_steps: u32,
    /// The rotor's electrical angle from the encoder, rad, in `[-π, π)`.
    theta_r_rad: f32,
    /// Sensorless: the observer's rotor-flux angle at the last slow step, rad (`None` before
    /// the first Running one).
    field_last_rad: Option<f32>,
    /// Sensorless: the field's speed over the last slow period, electrical rad/s — the
    /// stator frequency, which the current loops impose whatever the speed estimate's error
    /// (`None` until two Running slow steps).
    field_rate_rad_s: Option<f32>,
    /// The rotation that advances the output voltage over the delay
    /// ([`VOLTAGE_DELAY_PERIODS`]), from the field speed of the plan made last.
    delay_rotation: SinCos,
    /// The voltage fed forward by the plan made last (field frame), V.
    v_ff: Dq,
    /// The speed loop's output was at its limit at the last slow step.
    speed_saturated: bool,
    /// The envelope in use ([`EnvelopeConfig::envelope`]).
    envelope: Envelope,
    /// Slow steps until it is remade.
    envelope_age: u16,
    /// The current trim added to the loops' references (field frame), A.
    trim: Dq,
    /// How far the plan made last moved the current references, `|Δi*|`, A (the loops'
    /// reaction to it is in the voltage the after-slow checks read).
    i_ref_step_a: f32,
    /// Sensorless: the flying start's search ([`crate::speed_search`]), its slow steps left
    /// (0: done), and the rotor's speed it found, mechanical rad/s (0: at rest).
    search: SpeedSearch,
    search_left: u32,
    known_speed_rad_s: f32,
    /// V/Hz: the ramp's speed reference, mechanical rad/s (from the rotor's speed when the
    /// machine is magnetized), and the plan for the fast steps.
    vhz_ramp_rad_s: f32,
    vhz_plan: VhzPlan,
}

impl SlowRun {
    /// The inductances identified, × the motor's: those in use over the magnetizing curve's
    /// chord where the flux model is (the same for a linear motor) — what a new run starts
    /// from, and what the identification's laws and ranges judge.
    #[inline]
    fn identified_inductance_scale(&self) -> f32 {
        self.ifoc.inductance_scale() / self.chord
    }

    /// A run of `cfg` from rest (no flux, no torque, every count at zero) on the rotor
    /// resistance `rr_scale` and the inductances `l_scale` × the motor's, with the
    /// magnetizing fit `rotor_fit`. Out of line: one copy for power-up, an enable and a
    /// reconfiguration (inlined into each, the firmware took ≈ 1.2 KB more flash).
    #[inline(never)]
    fn new(cfg: &DriveConfig, rr_scale: f32, l_scale: f32, rotor_fit: RotorFit) -> Self {
        Self {
            torque_cmd: TorqueCommand::TorqueNm(0.0),
            ifoc: {
                let mut s = cfg.ifoc.state(0.0, rr_scale);
                cfg.ifoc.set_inductance_scale(&mut s, l_scale);
                s
            },
            speed: SpeedState::default(),
            motion: MotionChecks::default(),
            voltage_check: VoltageCheck::default(),
            open_phase: OpenPhaseWindow::default(),
            switches: SwitchWatch::default(),
            flux: FluxCommand::default(),
            i_d_target_a: 0.0,
            flux_forced: false,
            torque_max_nm: 0.0,
            v_cut_v: 0.0,
            torque_at_limit: false,
            forcing_a: 0.0,
            omega_limit_rad_s: 0.0,
            rotor_fit,
            model: cfg.envelope.with_inductance_scale(l_scale),
            i_d_rated_a: cfg.i_d_rated_a / l_scale,
            chord: 1.0,
            model_chord: 1.0,
            magnetizing_steps: 0,
            theta_r_rad: 0.0,
            field_last_rad: None,
            field_rate_rad_s: None,
            delay_rotation: SinCos::default(),
            v_ff: Dq { d: 0.0, q: 0.0 },
            speed_saturated: false,
            envelope: Envelope::ZERO,
            envelope_age: 0,
            i_ref_step_a: 0.0,
            trim: Dq::default(),
            search: SpeedSearch::default(),
            search_left: cfg.search_slow_steps,
            known_speed_rad_s: 0.0,
            vhz_ramp_rad_s: 0.0,
            vhz_plan: VhzPlan::default(),
        }
    }
}

impl FastState {
    /// The slow step's inputs at its tick, written into `into` field by field: the
    /// measurements, the mode, and the sums since the last tick, which start again.
    #[inline(always)]
    fn latch(&mut self, m: &Measurements, sensorless: bool, into: &mut SlowInputs) {
        into.field_rad = (sensorless && self.mode == Mode::Running).then(|| {
            let e = &self.run.estimate;
            crate::frames::atan2(e.psi_r_beta_wb, e.psi_r_alpha_wb)
        });
        into.i_refs_ab = [self.run.field.i_intended_ab(), self.run.field.i_ref_ab()];
        into.v_ab = self.run.last.v_ab;
        let r = &mut self.run;
        into.search_psi = r.search_psi;
        into.m = *m;
        into.mode = self.mode;
        into.sums = r.field.take_sums();
        into.v_req2_sum = r.v_req2_sum;
        into.v_req_steps = r.v_req_steps;
        into.v_fit_sum = r.v_fit_sum;
        into.limited = r.trim_hold;
        into.test_angle_rad = r.test_angle_rad;
        // Copied, then cleared (`take` went through a copy of its own on the stack).
        into.after_slow = r.after_slow;
        r.after_slow = None;
        (r.v_req2_sum, r.v_req_steps, r.v_fit_sum, r.trim_hold) = (0.0, 0, Dq::default(), false);
        r.search_psi = AlphaBeta::default();
    }

    /// Take the slow step's plan (`s`, the slow side's state after its step): its mode
    /// (unless a fault of the fast step came first), the reference, the fast steps' plan,
    /// the delay's rotation and the trim.
    #[inline(always)]
    fn adopt(&mut self, s: &SlowState) {
        self.trip_from(s.mode);
        (self.pending_fault, self.reference) = (s.pending_fault, s.reference);
        self.run.field.adopt(s.run.ifoc.field_steps());
        // Sensorless: the observer on the field orientation's estimates of the machine (a
        // build without it has none to feed).
        if cfg!(feature = "observer") {
            let ifoc = &s.run.ifoc;
            self.run.observer.set_scales(
                ifoc.inductance_scale(),
                ifoc.rotor_resistance_scale(),
                s.machine.rs_scale,
            );
        }
        (self.run.delay_rotation, self.run.trim, self.run.v_ff) =
            (s.run.delay_rotation, s.run.trim, s.run.v_ff);
        self.run.on_observer = s.ridden_through != FaultSet::EMPTY;
        if s.run.known_speed_rad_s != self.run.known_speed_rad_s {
            // The search found the rotor turning: the observer starts again on its speed.
            self.run.known_speed_rad_s = s.run.known_speed_rad_s;
            self.run.observer.restart();
        }
    }

    /// Latch fault `f` (the first fault stays latched: a controlled stop's, if one is under
    /// way): phases off from this step on.
    #[inline(never)]
    fn trip(&mut self, f: Fault) {
        if !matches!(self.mode, Mode::Fault(_)) {
            self.mode = Mode::Fault(self.pending_fault.take().unwrap_or(f));
        }
    }
}

impl SlowState {
    /// The speed and the field are the observer's: no encoder, or the encoder's fault
    /// ridden through.
    #[inline]
    fn on_observer(&self, cfg: &DriveConfig) -> bool {
        cfg.source.sensorless() || self.ridden_through != FaultSet::EMPTY
    }

    /// Latch fault `f` (the first fault stays latched): handed to the fast step with the plan.
    /// Out of line (a fault's path: inlined, its callers took flash).
    #[inline(never)]
    fn trip(&mut self, f: Fault) {
        if !matches!(self.mode, Mode::Fault(_)) {
            // A fault whose controlled stop was under way came first.
            self.mode = Mode::Fault(self.pending_fault.take().unwrap_or(f));
            self.stop_steps_left = None;
        }
    }

    /// Back to Idle (phases off) — a fault answered by a controlled stop latches now. A
    /// latched fault stays latched.
    fn disable(&mut self) {
        if !matches!(self.mode, Mode::Fault(_)) {
            self.mode = match self.pending_fault.take() {
                Some(f) => Mode::Fault(f),
                None => Mode::Idle,
            };
        }
        self.stop_steps_left = None;
    }

    /// React to fault `f`: a controlled stop, the fault latched when it ends, if `f` is in
    /// `stop_on` and the drive is Running; otherwise the bridge off at once.
    #[cold]
    #[inline(never)]
    pub(super) fn fault_reaction(&mut self, cfg: &DriveConfig, f: Fault) {
        if cfg.stop_on.contains(f) && self.mode == Mode::Running {
            if self.pending_fault.is_none() {
                self.pending_fault = Some(f);
                self.reference = Reference::Speed(0.0);
                if self.stop_steps_left.is_none() {
                    self.stop_steps_left = Some(cfg.stop_slow_steps);
                }
            }
        } else {
            self.trip(f);
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
        let run = SlowRun::new(
            &cfg,
            cfg.mras.initial_scale(),
            cfg.mras.initial_inductance_scale(),
            RotorFit::default(),
        );
        let fast = FastSide {
            state: FastState {
                mode: Mode::Idle,
                pending_fault: None,
                reference: Reference::Speed(0.0),
                steps_to_slow: 0,
                brake: false,
                theta_est_rad: 0.0,
                zero: IdleZero::default(),
                unsampled: [0; 2],
                run: FastRun::default(),
            },
            cfg,
            vhz: VhzRun::default(),
            plan_signals: SlowSignals::default(),
        };
        let slow = SlowSide {
            state: SlowState {
                mode: Mode::Idle,
                reference: Reference::Speed(0.0),
                omega_ref_rad_s: 0.0,
                pending_fault: None,
                stop_steps_left: None,
                ridden_through: FaultSet::EMPTY,
                machine: MachineState::POWER_UP,
                run,
            },
            cfg,
            job: SlowJob { inputs: SlowInputs::at_rest(), vhz: None },
            job_due: false,
            order: Order::default(),
            plan_signals: SlowSignals::default(),
        };
        Self { fast, slow }
    }

    /// The two halves, for two contexts (the firmware's: [`Drive`]).
    pub fn into_parts(self) -> (FastSide, SlowSide) {
        (self.fast, self.slow)
    }

    /// To command it ([`DriveMut`]).
    pub fn as_mut(&mut self) -> DriveMut<'_> {
        DriveMut::new(&mut self.fast, &mut self.slow)
    }

    /// To read it ([`DriveRef`]).
    pub fn as_ref(&self) -> DriveRef<'_> {
        DriveRef { fast: &self.fast, slow: &self.slow }
    }

    /// One PWM period, the slow step's job run at its tick: [`FastSide::step`] with the slow
    /// side beside it.
    pub fn step(&mut self, m: &Measurements) -> FastOutput {
        self.fast.step(m, &mut self.slow)
    }

    /// A period in which the firmware holds the bridge: [`FastSide::hold_step`] with the slow
    /// side beside it.
    pub fn hold_step(&mut self, m: &Measurements) -> bool {
        self.fast.hold_step(m, &mut self.slow)
    }

    /// The slow step alone, its plan not adopted (benchmarks and tests): its inputs latched
    /// from the fast side, then its job ([`SlowSide::run`]).
    pub fn slow_step(&mut self, m: &Measurements) {
        self.fast.latch(m, &mut self.slow);
        self.slow.run();
    }

    /// The fast step alone, without the cadence (benchmarks and tests):
    /// [`FastSide::fast_step`].
    pub fn fast_step(&mut self, m: &Measurements) -> FastOutput {
        self.fast.fast_step(m)
    }

    /// Another machine: a new drive on `cfg` ([`Drive::new`]) in this one's place, which only
    /// knows how long the rotor was left ([`DriveMut::rotor_driven`]).
    pub fn replace(&mut self, cfg: DriveConfig) {
        let idle = self.slow.state.machine.idle_slow_steps;
        *self = Drive::new(cfg);
        self.rotor_driven(idle);
    }

    /// [`DriveMut::reconfigure`].
    #[inline]
    pub fn reconfigure(&mut self, cfg: DriveConfig) -> Result<(), CommandError> {
        self.as_mut().reconfigure(cfg)
    }

    /// [`DriveMut::rotor_driven`].
    #[inline]
    pub fn rotor_driven(&mut self, idle_slow_steps: u32) {
        self.as_mut().rotor_driven(idle_slow_steps)
    }

    /// [`DriveMut::enable`].
    #[inline]
    pub fn enable(&mut self) -> Result<(), CommandError> {
        self.as_mut().enable()
    }

    /// [`FastSide::current_zero_moved`].
    #[inline]
    pub fn current_zero_moved(&mut self) {
        self.fast.current_zero_moved()
    }

    /// [`DriveMut::disable`].
    #[inline]
    pub fn disable(&mut self) {
        self.as_mut().disable()
    }

    /// [`DriveMut::controlled_stop`].
    #[inline]
    pub fn controlled_stop(&mut self) {
        self.as_mut().controlled_stop()
    }

    /// [`DriveMut::clear_fault`].
    #[inline]
    pub fn clear_fault(&mut self) {
        self.as_mut().clear_fault()
    }

    /// [`DriveMut::set_reference`].
    #[inline]
    pub fn set_reference(&mut self, r: Reference) -> Result<(), CommandError> {
        self.as_mut().set_reference(r)
    }

    /// [`DriveMut::trip`].
    #[inline]
    pub fn trip(&mut self, f: Fault) {
        self.as_mut().trip(f)
    }

    /// [`DriveRef::speed_state`].
    #[inline]
    pub fn speed_state(&self) -> &SpeedState {
        self.as_ref().speed_state()
    }

    /// [`DriveRef::ifoc_state`].
    #[inline]
    pub fn ifoc_state(&self) -> &IfocState {
        self.as_ref().ifoc_state()
    }

    /// [`DriveRef::idle_slow_steps`].
    #[inline]
    pub fn idle_slow_steps(&self) -> u32 {
        self.as_ref().idle_slow_steps()
    }

    /// [`DriveRef::pending_fault`].
    #[inline]
    pub fn pending_fault(&self) -> Option<Fault> {
        self.as_ref().pending_fault()
    }

    /// [`DriveRef::thermal_state`].
    #[inline]
    pub fn thermal_state(&self) -> (f32, f32) {
        self.as_ref().thermal_state()
    }

    /// [`DriveRef::stator_resistance_scale`].
    #[inline]
    pub fn stator_resistance_scale(&self) -> f32 {
        self.as_ref().stator_resistance_scale()
    }

    /// [`DriveRef::ridden_through`].
    #[inline]
    pub fn ridden_through(&self) -> FaultSet {
        self.as_ref().ridden_through()
    }

    /// [`DriveRef::is_stopping`].
    #[inline]
    pub fn is_stopping(&self) -> bool {
        self.as_ref().is_stopping()
    }

    /// [`DriveRef::rotor_at_rest`].
    #[inline]
    pub fn rotor_at_rest(&self) -> bool {
        self.as_ref().rotor_at_rest()
    }

    /// [`DriveRef::position_rad`].
    #[inline]
    pub fn position_rad(&self) -> f32 {
        self.as_ref().position_rad()
    }

    /// [`DriveRef::telemetry`].
    #[inline]
    pub fn telemetry(&self) -> Telemetry {
        self.as_ref().telemetry()
    }

    /// [`FastSide::mode`].
    #[inline]
    pub fn mode(&self) -> Mode {
        self.fast.mode()
    }

    /// [`FastSide::config`].
    #[inline]
    pub fn config(&self) -> &DriveConfig {
        self.fast.config()
    }

    /// [`FastSide::current_state`].
    #[inline]
    pub fn current_state(&self) -> &CurrentState<f32> {
        self.fast.current_state()
    }

    /// [`FastSide::slow_step_due`].
    #[inline]
    pub fn slow_step_due(&self) -> bool {
        self.fast.slow_step_due()
    }

    /// [`FastSide::slow_busy`].
    #[inline]
    pub fn slow_busy(&self) -> bool {
        self.fast.slow_busy()
    }

    /// [`FastSide::observed_speed_rad_s`].
    #[inline]
    pub fn observed_speed_rad_s(&self) -> Option<f32> {
        self.fast.observed_speed_rad_s()
    }
}

impl DriveMut<'_> {
    /// The slow side learns the fast side's fault (a fault of the fast step ends a
    /// controlled stop: its pending fault is what latched), and the fast side the slow
    /// side's reference and pending fault: after a command, and at the slow step's tick.
    /// Without the fast side (the slow context's) the slow step's job did the first half
    /// from the mode latched at the tick, and the adoption does the second. Out of line:
    /// one copy for its dozen callers.
    #[inline(never)]
    fn sync(&mut self) {
        let Some(fast) = self.fast.as_deref_mut() else { return };
        if let Mode::Fault(_) = fast.state.mode {
            self.slow.state.mode = fast.state.mode;
            (self.slow.state.pending_fault, self.slow.state.stop_steps_left) = (None, None);
        }
        fast.state.pending_fault = self.slow.state.pending_fault;
        fast.state.reference = self.slow.state.reference;
    }

    /// The command's fast part: at once with the fast side here ([`FastSide::obey`], then
    /// [`DriveMut::sync`]); left in the slow side's order otherwise, for the next adoption.
    fn done(&mut self) {
        if let Some(fast) = self.fast.as_deref_mut() {
            fast.obey(self.slow);
        }
        self.sync();
    }

    /// The mode a command decides on: the fast side's (its word is final), or without it the
    /// slow side's — the mode latched at the tick as the job left it, the one the next
    /// adoption takes unless the fast step faults first.
    pub fn mode(&self) -> Mode {
        self.fast.as_deref().map_or(self.slow.state.mode, |f| f.state.mode)
    }

    /// [`DriveRef::ridden_through`].
    pub fn ridden_through(&self) -> FaultSet {
        self.slow.state.ridden_through
    }

    /// The configuration (the same on both sides).
    pub fn config(&self) -> &DriveConfig {
        &self.slow.cfg
    }

    /// The rotor was driven by something else `idle_slow_steps` slow steps ago (0: now) — a
    /// commissioning sequence in the drive's place, or the drive this one replaces (a new
    /// configuration): its flux may still be there at the next enable.
    pub fn rotor_driven(&mut self, idle_slow_steps: u32) {
        self.slow.state.machine.idle_slow_steps = idle_slow_steps;
    }

    /// Idle → Magnetizing with a fresh run (`FastRun`, `SlowRun`: the loops, the field, the
    /// checks' counts), on the estimates the last run left: the rotor resistance's estimate
    /// is the rotor's temperature, the inductance's the machine's. The machine's state
    /// carries on (`MachineState`), and so does the slow cadence: whoever reads the encoder
    /// every N-th period (the firmware, the simulator) stays in step with the slow step. No
    /// effect when already active. `#[inline]`: compiled in the caller's crate — in the
    /// firmware, with its commands at opt-level "z" (−148 B of flash), not at
    /// controller-core's 2.
    #[inline]
    pub fn enable(&mut self) -> Result<(), CommandError> {
        self.sync();
        let r = match self.mode() {
            Mode::Fault(_) => Err(CommandError::Faulted),
            Mode::Idle => {
                let s = &mut *self.slow;
                let fit = RotorFit::new(s.cfg.mras.demagnetized_after(s.state.machine.idle_slow_steps));
                let run = &s.state.run;
                let (rr, l) = (run.ifoc.rotor_resistance_scale(), run.identified_inductance_scale());
                s.state.run = SlowRun::new(&s.cfg, rr, l, fit);
                s.order.restart = true;
                s.state.ridden_through = FaultSet::EMPTY;
                s.state.machine.idle_slow_steps = 0;
                s.state.mode = Mode::Magnetizing;
                s.order.mode = true;
                Ok(())
            }
            Mode::Magnetizing | Mode::Running => Ok(()),
        };
        self.done();
        r
    }

    /// Back to Idle (phases off). A latched fault stays latched.
    pub fn disable(&mut self) {
        self.sync();
        self.slow.state.disable();
        self.slow.order.mode = true;
        self.done();
    }

    /// A controlled stop (stop category 1): Running, the speed loop brakes to standstill
    /// within its torque and regeneration limits, then the bridge goes off (Idle) — once the
    /// speed is below the stall check's "not moving" level, or after `stop_time_s` at the
    /// latest; Magnetizing, the bridge goes off at once. A new reference (the host is back)
    /// cancels the stop. What the firmware does when its link falls silent.
    pub fn controlled_stop(&mut self) {
        self.sync();
        let mode = self.mode();
        let s = &mut self.slow.state;
        match mode {
            _ if s.pending_fault.is_some() => {}
            Mode::Running if s.stop_steps_left.is_none() => {
                s.reference = Reference::Speed(0.0);
                s.stop_steps_left = Some(self.slow.cfg.stop_slow_steps);
            }
            Mode::Magnetizing => {
                s.disable();
                self.slow.order.mode = true;
            }
            _ => {}
        }
        self.done();
    }

    /// Fault → Idle (the encoder's jump check judges again from the second change after,
    /// [`Fault::EncoderLoss`]'s jump being no reference).
    pub fn clear_fault(&mut self) {
        self.sync();
        if matches!(self.mode(), Mode::Fault(_)) {
            let s = &mut *self.slow;
            s.state.mode = Mode::Idle;
            s.order.cleared = true;
            // The encoder's last change may be the jump that latched `EncoderLoss`: no
            // reference for the next one.
            s.state.machine.encoder.forget_last_change();
        }
        self.done();
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
        let cfg = &self.slow.cfg;
        if cfg.vhz().is_some() && matches!(r, Reference::Position(_) | Reference::Torque(_)) {
            return Err(CommandError::SpeedOnly);
        }
        if self.slow.state.on_observer(cfg) && matches!(r, Reference::Position(_)) {
            return Err(CommandError::NoEncoder);
        }
        self.sync();
        if self.slow.state.pending_fault.is_some() {
            // A stop for a fault is not cancelled by a new reference.
            return Err(CommandError::Faulted);
        }
        self.slow.state.reference = r;
        self.slow.state.stop_steps_left = None;
        self.done();
        Ok(())
    }

    /// Latch fault `f` (the first fault stays latched): phases off from the next fast step
    /// on (without the fast side: from the next adoption, unless the fast step faults
    /// first). The supervisor calls it; the firmware calls it for faults only it can see.
    /// Out of line (a fault's path: inlined, its eight callers took 376 B of flash).
    #[inline(never)]
    pub fn trip(&mut self, f: Fault) {
        match self.fast.as_deref_mut() {
            Some(fast) => fast.state.trip(f),
            None => self.slow.state.trip(f),
        }
        self.sync();
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
    /// is another drive ([`Drive::replace`]; the link's `Configure` tells them apart).
    ///
    /// Refused while the bridge is active ([`CommandError::Active`]): the drive is left as
    /// it was. `#[inline]`: compiled in the caller's crate — in the firmware at its
    /// opt-level "z" (a gain write).
    #[inline]
    pub fn reconfigure(&mut self, cfg: DriveConfig) -> Result<(), CommandError> {
        self.swap(cfg, false)
    }

    /// New gains of the saturated-P speed law (seed 002 eq. (21)) — the firmware's
    /// `WriteSpeedGains`: [`DriveMut::reconfigure`] with
    /// [`DriveConfig::with_saturated_p`], the speed law and the stall check's limit, which
    /// the fast side never reads (its order copies these two alone). `None` for another law
    /// or bad gains. `#[inline]`: compiled in the caller's crate.
    #[inline]
    pub fn write_speed_gains(&mut self, kp: f32, tau_max_nm: f32) -> Option<Result<(), CommandError>> {
        let cfg = self.slow.cfg.with_saturated_p(kp, tau_max_nm)?;
        Some(self.swap(cfg, true))
    }

    /// [`DriveMut::reconfigure`]'s body; `speed_law`: `cfg` differs from the configuration
    /// in use in the speed law and the stall check's limit alone.
    #[inline]
    fn swap(&mut self, cfg: DriveConfig, speed_law: bool) -> Result<(), CommandError> {
        if self.mode().is_active() {
            return Err(CommandError::Active);
        }
        self.sync();
        let s = &mut *self.slow;
        let old = &s.cfg;
        let [rr_min, rr_max] = cfg.mras.range();
        let [l_min, l_max] = cfg.mras.inductance_range();
        let rr = s.state.run.ifoc.rotor_resistance_scale().limit(rr_min, rr_max);
        let l = s.state.run.identified_inductance_scale().limit(l_min, l_max);
        let thermal = &mut s.state.machine.thermal;
        thermal.motor = old.motor_thermal.carry(thermal.motor, &cfg.motor_thermal);
        thermal.inverter = old.inverter_thermal.carry(thermal.inverter, &cfg.inverter_thermal);
        if cfg.slow_divider != old.slow_divider {
            s.order.cadence = true;
            s.state.machine.encoder.restart_jump_check();
        }
        s.state.run = SlowRun::new(&cfg, rr, l, RotorFit::default());
        (s.state.reference, s.state.omega_ref_rad_s) = (Reference::Speed(0.0), 0.0);
        (s.state.pending_fault, s.state.stop_steps_left) = (None, None);
        (s.cfg, s.job_due) = (cfg, false);
        (s.order.restart, s.order.reconfigured, s.order.speed_law) = (true, !speed_law, speed_law);
        self.done();
        Ok(())
    }
}

impl<'a> DriveRef<'a> {
    /// Speed-loop state (PI `p_term`/`i_term` when a PI law is configured).
    pub fn speed_state(self) -> &'a SpeedState {
        &self.slow.state.run.speed
    }

    /// IFOC state: the rotor-flux estimate, the estimates in use and the plan made last.
    pub fn ifoc_state(self) -> &'a IfocState {
        &self.slow.state.run.ifoc
    }

    /// Slow steps since a bridge last drove the rotor (saturating; `u32::MAX` from power-up):
    /// what decides whether the next enable measures the inductances
    /// ([`MrasConfig::demagnetized_after`]).
    pub fn idle_slow_steps(self) -> u32 {
        self.slow.state.machine.idle_slow_steps
    }

    /// A fault answered by a controlled stop that is under way ([`Protection::stop_on`]): it
    /// latches when the bridge goes off.
    pub fn pending_fault(self) -> Option<Fault> {
        if matches!(self.fast.state.mode, Mode::Fault(_)) { None } else { self.slow.state.pending_fault }
    }

    /// The thermal models' states, motor and inverter (1 = the steady temperature rise at
    /// the rated current; the limit is `overload_factor²`; 0 without a limit).
    pub fn thermal_state(self) -> (f32, f32) {
        (self.slow.state.machine.thermal.motor, self.slow.state.machine.thermal.inverter)
    }

    /// The stator resistance the observer runs on, × the motor file's: what the magnetizing
    /// fit measured at the last enable of a demagnetized rotor at rest (1 before any, and
    /// for a drive without an observer). Its error against the winding's is what the
    /// observer's certificate bounds (`design certify`'s stator-resistance margin).
    pub fn stator_resistance_scale(self) -> f32 {
        self.slow.state.machine.rs_scale
    }

    /// The encoder's faults the drive rode through on the observer since the last enable
    /// ([`SpeedFeedback::EncoderRideThrough`]): the faults it would have tripped on, which
    /// the user must still hear of — the encoder is broken, the drive runs without it.
    /// Empty for the other speed sources.
    pub fn ridden_through(self) -> FaultSet {
        self.slow.state.ridden_through
    }

    /// A controlled stop is under way.
    pub fn is_stopping(self) -> bool {
        self.slow.state.stop_steps_left.is_some() && !matches!(self.fast.state.mode, Mode::Fault(_))
    }

    /// The rotor has been at rest over the rest check's last windows
    /// ([`crate::supervisor::rest`]: `p·|ω_m|·T_r` at most 0.05 over `rest_time_s`, twice in
    /// a row): what commissioning's standstill tests need before they start. Watched in every
    /// mode; `false` from power-up until the windows have passed.
    pub fn rotor_at_rest(self) -> bool {
        self.slow.state.machine.rest.at_rest()
    }

    /// Multi-turn mechanical position from the encoder, rad (the position loop's;
    /// `EncoderTrack::position_rad`).
    pub fn position_rad(self) -> f32 {
        self.slow.state.machine.encoder.position_rad()
    }

    /// The signals of the last fast step, for logs, traces and the capture: made on demand
    /// from what the step left (its measured current, current references and voltage) and
    /// the drive's state ([`FastSide::telemetry_with`] on [`SlowSide::signals`]), not in
    /// every step. All zero unless the bridge is active (Magnetizing or Running) — as after a
    /// step that tripped.
    pub fn telemetry(self) -> Telemetry {
        self.fast.telemetry_with(&self.slow.signals())
    }

    /// [`FastSide::mode`].
    pub fn mode(self) -> Mode {
        self.fast.mode()
    }

    /// [`FastSide::config`].
    pub fn config(self) -> &'a DriveConfig {
        self.fast.config()
    }
}

impl FastSide {
    /// Present mode.
    pub fn mode(&self) -> Mode {
        self.state.mode
    }

    /// The configuration.
    pub fn config(&self) -> &DriveConfig {
        &self.cfg
    }

    /// Current-loop states (their PI `p_term`/`i_term` are telemetry).
    pub fn current_state(&self) -> &CurrentState<f32> {
        &self.state.run.current
    }

    /// The next [`Drive::step`] runs the slow step, which reads the measurements' encoder
    /// values (the one cadence: a caller that reads the encoder every N-th period reads it
    /// for this step).
    pub fn slow_step_due(&self) -> bool {
        self.state.steps_to_slow == 0
    }

    /// The next [`FastSide::step`] is the one period of each slow period in which the fast
    /// context notes what the slow context reads beside the next job (the firmware's part of
    /// a snapshot for the link): the last before the tick — neither a tick nor an adoption,
    /// the slow side back, and a plain period (the first after an adoption takes ≈ 240
    /// instructions more, measured in `cost`) — or the tick itself when the adoption is the
    /// last period before it. So the tick's and the adoption's periods, the longest, carry
    /// none of it.
    pub fn note_due(&self) -> bool {
        let s = self.state.steps_to_slow;
        if self.cfg.adopt_at == 0 { s == 0 } else { s == 1 }
    }

    /// The slow step's job is in flight after the last [`Drive::step`]: from its tick up to
    /// the period that adopts its plan ([`DriveConfig::plan_delay`]). The board's slow
    /// context may be running it, so the firmware leaves the link's requests — which act on
    /// the slow side's state — to a period after the adoption (the tick's period is among
    /// these: the longest period is never the job's and a request's).
    pub fn slow_busy(&self) -> bool {
        self.state.steps_to_slow > self.cfg.adopt_at
    }

    /// The observer's speed estimate at the last step, mechanical rad/s (`None` without an
    /// observer: an encoder drive). With the bridge off, the last one before it went off.
    pub fn observed_speed_rad_s(&self) -> Option<f32> {
        self.cfg.source.observer().map(|_| self.state.run.estimate.omega_m_rad_s)
    }

    /// One PWM period, the two contexts' schedule (issue 54): the observer on the period's
    /// sample (sensorless: its estimate is the encoder reading both steps get); at the tick
    /// (every `slow_divider`-th period) the slow step's inputs latched into the slow side and
    /// its job started (`slow`: run at once beside the fast side, or handed to the board's
    /// slow context, which runs it while the fast interrupt goes on);
    /// [`DriveConfig::plan_delay`] periods after the tick its plan adopted — the mode, the
    /// reference, the field plan — at that fixed period whatever context made it and however
    /// long it took, so that the simulator, QEMU and the board step alike; then the fast
    /// step. A slow side not back at the tick or at the adoption (its job late: a slow
    /// context that cannot keep up) latches [`Fault::Overrun`], the bridge off in that
    /// period.
    pub fn step(&mut self, m: &Measurements, slow: &mut dyn SlowContext) -> FastOutput {
        let (rebuilt, observed);
        let m = if self.cfg.overmodulating() {
            rebuilt = self.state.rebuild(m);
            &rebuilt
        } else {
            m
        };
        let m = match self.cfg.source.observer() {
            Some(o) => {
                observed = self.state.observe(o, self.cfg.source.sensorless(), m);
                &observed
            }
            None => m,
        };
        let keep = self.cadence(m, slow);
        self.fast(m, keep)
    }

    /// The slow cadence of one period ([`FastSide::step`]). True in the adopting period: its
    /// fast step, the plan's first, keeps its signals for the once-per-slow-period checks,
    /// which the next slow step runs (latched with its inputs).
    #[inline(always)]
    fn cadence(&mut self, m: &Measurements, slow: &mut dyn SlowContext) -> bool {
        if self.state.steps_to_slow == 0 {
            self.tick(m, slow);
            self.state.steps_to_slow = self.cfg.slow_divider.saturating_sub(1);
        } else {
            self.state.steps_to_slow -= 1;
        }
        let adopting = self.state.steps_to_slow == self.cfg.adopt_at;
        if adopting && !slow.with(&mut |s| self.adopt(s)) {
            self.state.trip(Fault::Overrun);
        }
        adopting
    }

    /// The tick: the slow step's job latched and started, or [`Fault::Overrun`] if the slow
    /// side is not back. Out of line: once per slow period.
    #[inline(never)]
    fn tick(&mut self, m: &Measurements, slow: &mut dyn SlowContext) {
        if !slow.start(&mut |s| self.latch(m, s)) {
            self.state.trip(Fault::Overrun);
        }
    }

    /// The slow step's job latched into `s` (`FastState::latch`: the measurements, the mode,
    /// the sums since the last tick), with the V/Hz law's state.
    #[inline(always)]
    fn latch(&mut self, m: &Measurements, s: &mut SlowSide) {
        self.state.latch(m, self.state.on_observer(&self.cfg), &mut s.job.inputs);
        // One call of the step (two, one of them for V/Hz, and it went out of line: +80
        // instructions per slow step of a vector drive, `cost slow_step`).
        s.job.vhz = if self.cfg.vhz_on() { self.vhz.report() } else { None };
        s.job_due = true;
    }

    /// The fast side takes the slow step's plan: its mode (unless a fault of the fast step
    /// came first), the reference, the field plan; V/Hz's. Out of line: once per slow
    /// period.
    #[inline(never)]
    fn adopt(&mut self, s: &mut SlowSide) {
        if s.order != Order::default() {
            self.obey(s);
        }
        self.state.adopt(&s.state);
        self.plan_signals = s.plan_signals;
        if self.cfg.vhz_on() {
            self.vhz.adopt(&s.state.run.vhz_plan);
        }
    }

    /// A command's fast part, ordered by the slow side ([`DriveMut`]), taken (and the order
    /// spent): the new configuration, the cadence from this period, a new run, the mode —
    /// unless a fault of the fast step stands, which only a clear takes over. Before the
    /// plan at an adoption: the new run takes it. Out of line: rare, and the adoption's
    /// path stays short.
    #[cold]
    #[inline(never)]
    fn obey(&mut self, s: &mut SlowSide) {
        let o = core::mem::take(&mut s.order);
        if o.reconfigured {
            self.cfg = s.cfg;
        } else if o.speed_law {
            (self.cfg.speed, self.cfg.motion) = (s.cfg.speed, s.cfg.motion);
        }
        if o.cadence {
            self.state.steps_to_slow = 0;
        }
        if o.restart {
            self.state.run.restart();
            // V/Hz's run is untouched by a drive that does not run the law (its step, its
            // report and its adoption are all behind the flag).
            if self.cfg.vhz_on() {
                self.vhz = VhzRun::default();
            }
        }
        if o.cleared {
            self.state.mode = s.state.mode;
        } else if o.mode {
            self.state.trip_from(s.state.mode);
        }
    }

    /// The signals of the last fast step ([`DriveRef::telemetry`]) with the slow side's part
    /// `s`. Out of line: its callers (the link's stream, the snapshot) take it rarely.
    #[inline(never)]
    pub fn telemetry_with(&self, s: &SlowSignals) -> Telemetry {
        self.signals().join(s)
    }

    /// The slow side's signals of the plan in force: as the job that made the plan left them,
    /// adopted with it (the slow side's own, [`SlowSide::signals`], move at the job's end and
    /// with a command).
    pub fn plan_signals(&self) -> SlowSignals {
        self.plan_signals
    }

    /// One field `k` of the last step's signals with the plan's slow part — of
    /// [`FastSide::telemetry_with`] on [`FastSide::plan_signals`], bit for bit — made alone:
    /// what the firmware's capture records (the whole telemetry made for a sample, and the
    /// slow side's part read through its hand-off, cost the capture's period ≈ 110
    /// instructions). The currents, the voltage and the slow part's own fields are read; the
    /// field's angle, slip, flux and q reference, which depend on the law that ran the step,
    /// are the whole join's (out of line).
    #[inline]
    pub fn signal(&self, k: TelemetryField) -> f32 {
        use TelemetryField as F;
        let s = &self.plan_signals;
        if !self.state.mode.is_active() {
            // `FastSignals::join`'s: every field of `Telemetry::default()` (made and read,
            // it was a 56-byte memclr at the firmware's opt-level "z").
            return 0.0;
        }
        let last = &self.state.run.last;
        match k {
            F::IAlpha => last.i_ab.alpha,
            F::IBeta => last.i_ab.beta,
            F::IRefAlpha => last.i_ref_ab.alpha,
            F::IRefBeta => last.i_ref_ab.beta,
            F::VAlpha => last.v_ab.alpha,
            F::VBeta => last.v_ab.beta,
            F::PsiRef => s.psi_ref_wb,
            F::OmegaRef => s.omega_ref_rad_s,
            F::RrScale => s.rr_scale,
            F::LScale => s.l_scale,
            F::ThetaE | F::OmegaSl | F::PsiR | F::IqRef => self.telemetry_with(s).get(k),
        }
    }

    /// Its part of the drive's signals after the last step: what the board's fast context
    /// latches for the slow context, which joins it with its own ([`FastSignals::join`]).
    #[inline(always)]
    pub fn signals(&self) -> FastSignals {
        let f = &self.state.run;
        let rotating = matches!(self.state.reference, Reference::RotatingCurrent { .. })
            && self.state.mode == Mode::Running;
        let (theta_e_rad, field) = match (self.cfg.vhz(), self.vhz.on, rotating) {
            (_, _, true) => (f.last_test_angle_rad, FieldOf::Test),
            // V/Hz: the stator-flux frame, the operating point's slip and rotor flux.
            (Some(v), true, false) => {
                let law = &self.vhz.state;
                (
                    crate::frames::wrap_angle(law.theta_s_rad()),
                    FieldOf::Vhz {
                        omega_sl_rad_s: law.slip_rad_s(),
                        psi_r_wb: law.psi_r_wb(v, &self.vhz.plan),
                    },
                )
            }
            _ => (f.field.last_theta_e_rad(), FieldOf::Vector),
        };
        FastSignals {
            active: self.state.mode.is_active(),
            i_ab: f.last.i_ab,
            i_ref_ab: f.last.i_ref_ab,
            v_ab: f.last.v_ab,
            theta_e_rad,
            field,
        }
    }

    /// The current sensors' zero moved (the firmware's power-up calibration of their codes,
    /// which steps the drive on the old zero meanwhile): a sensorless drive forgets the
    /// residual offsets it read with the bridge off ([`IdleZero::forget`]) — they are of the
    /// old zero, up to the calibration's tolerance, where the residual is a few LSB.
    pub fn current_zero_moved(&mut self) {
        self.state.zero.forget();
    }

    /// Latch fault `f` on the fast side alone (the first fault stays latched): phases off
    /// from the next fast step on; the slow side learns it at its next tick (the mode is
    /// among its inputs) or command. What the fast interrupt calls for the faults only the
    /// firmware sees ([`DriveMut::trip`] with the slow side back).
    #[inline(never)]
    pub fn trip(&mut self, f: Fault) {
        self.state.trip(f);
    }
}
