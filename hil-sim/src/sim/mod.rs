//! Software-in-the-loop: a `controller-core` [`Drive`] against the [`Machine`] plant.
//!
//! Timing, as on the board: at the start of PWM period k the currents are sampled, the
//! drive computes duties, and those duties are applied during period k+1 (one period of
//! computation delay). Inverter: [`InverterModel`] — average-value (default) or switching
//! with dead time; the plant integrates the resulting piecewise-constant voltage exactly.
//! Sensors: [`SensorModel`] (ideal by default). Loads: a piecewise-constant torque set by
//! events, plus the [`LoadModel`] (eddy-current brake or locked rotor).
//!
//! This module holds what a run is made of: the controller it drives ([`DriveUnderTest`]),
//! the scenario ([`Scenario`], [`Event`], [`Injection`], [`LoadModel`]) and the trace's
//! [`Row`]. The rooms: `closed_loop` — the run itself ([`run`]); `open_loop` — the plant on
//! a sine source ([`run_open_loop`]); `integrate` — the plant over one period (a switching
//! inverter's segments, the bridge off) and the RK4 step's stability; `dc_link` — the
//! capacitor, its source and the brake chopper ([`DcLink`]).
//!
//! [`Machine`]: plant::Machine

use crate::bridge_fault::{Comparator, PhaseShort, SwitchShort};
use crate::inverter::InverterModel;
use crate::sensors::SensorModel;
use controller_core::drive::{Drive, FastOutput, FaultSet, Measurements, Mode, Reference, Telemetry};
use controller_core::motor::MotorParams;
use plant::MachineState;

mod closed_loop;
mod dc_link;
mod integrate;
mod open_loop;

pub(crate) use closed_loop::first_period_at;
pub use closed_loop::{run, run_collect};
pub use dc_link::{Chopper, DcLink, DcSource};
pub use integrate::{BRIDGE_OFF_SUBSTEPS, RK4_RATE_STEP_MAX};
pub use open_loop::{OPEN_LOOP_MAX_STEP_S, OPEN_LOOP_SUBSTEPS_MAX, run_open_loop};

/// The controller a run drives: the in-process [`Drive`] (software in the loop) or a drive
/// on an emulated MCU ([`crate::pil::Pil`], processor in the loop). Errors are broken links;
/// a drive refusing a command is not an error (the trace shows it).
///
/// [`DriveUnderTest::step`] returns the output itself, not a `Result`: wrapping it cost the
/// simulator ≈ 5 ns per period when this was changed (`hil-sim bench`: ≈ 58 against ≈ 53
/// ns), the output being copied through memory on its way to the plant. A step that fails
/// (a broken PIL link) returns phases off and leaves its error for
/// [`DriveUnderTest::take_failure`], which the simulator asks after every step.
pub trait DriveUnderTest {
    /// The slow loop runs every `slow_divider()`-th step.
    fn slow_divider(&self) -> u16;
    /// [`Drive::enable`].
    fn enable(&mut self) -> Result<(), String>;
    /// [`Drive::set_reference`].
    fn set_reference(&mut self, r: Reference) -> Result<(), String>;
    /// [`Drive::controlled_stop`].
    fn controlled_stop(&mut self) -> Result<(), String>;
    /// [`Drive::step`]; phases off if the step failed (see [`DriveUnderTest::take_failure`]).
    fn step(&mut self, m: &Measurements) -> FastOutput;
    /// [`Drive::telemetry`]: the signals of the last step (asked only for the trace's rows).
    fn telemetry(&self) -> Telemetry;
    /// Why the last [`DriveUnderTest::step`] failed, if it did (taken: asked again, `None`).
    /// The in-process drive cannot fail.
    fn take_failure(&mut self) -> Option<String> {
        None
    }
    /// The board's comparator broke the bridge ([`Drive::trip`] with `HardwareBreak`, what
    /// the firmware does when it finds the break flag).
    fn hardware_break(&mut self) -> Result<(), String> {
        Err("the hardware comparator's break is modelled for the in-process drive only".into())
    }
    /// The controller has nothing more to do: the run may end early (asked every 2 000
    /// periods). A drive never finishes.
    fn finished(&self) -> bool {
        false
    }
    /// [`Drive::ridden_through`]: the encoder's faults the drive carried on through (asked
    /// only for the trace's rows; empty where the drive does not say: over the link).
    fn ridden_through(&self) -> FaultSet {
        FaultSet::EMPTY
    }
    /// [`Drive::observed_speed_rad_s`]: the observer's speed estimate (asked only for the
    /// trace's rows; `None` without an observer, or where the drive does not say).
    fn observed_speed_rad_s(&self) -> Option<f32> {
        None
    }
}

impl DriveUnderTest for Drive {
    fn slow_divider(&self) -> u16 {
        self.config().slow_divider()
    }

    fn enable(&mut self) -> Result<(), String> {
        let _refused = Drive::enable(self);
        Ok(())
    }

    fn set_reference(&mut self, r: Reference) -> Result<(), String> {
        let _refused = Drive::set_reference(self, r);
        Ok(())
    }

    fn controlled_stop(&mut self) -> Result<(), String> {
        Drive::controlled_stop(self);
        Ok(())
    }

    fn step(&mut self, m: &Measurements) -> FastOutput {
        Drive::step(self, m)
    }

    fn telemetry(&self) -> Telemetry {
        Drive::telemetry(self)
    }

    fn ridden_through(&self) -> FaultSet {
        Drive::ridden_through(self)
    }

    fn observed_speed_rad_s(&self) -> Option<f32> {
        Drive::observed_speed_rad_s(self)
    }

    fn hardware_break(&mut self) -> Result<(), String> {
        self.trip(controller_core::drive::Fault::HardwareBreak);
        Ok(())
    }
}

/// A time-stamped event of a scenario.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Event {
    /// Enable the drive.
    Enable,
    /// New outer-loop reference.
    Reference(Reference),
    /// New load torque, N·m: an *active* load (a hoist's weight, a dynamometer's command),
    /// which drives the shaft whatever it does — a tripped rotor too.
    LoadNm(f64),
    /// A *passive* load coupled from now on, added to what is there: it only takes the
    /// energy the shaft gives it (or stores it), so a tripped rotor coasts to rest.
    Coupling(PassiveLoad),
    /// A controlled stop ([`Drive::controlled_stop`]).
    Stop,
    /// A fault of the plant, inverter or sensors from this time on.
    Fault(Injection),
}

/// A passive mechanical load ([`Event::Coupling`]), the kinds a driven machine presents.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PassiveLoad {
    /// Dry friction of `friction_nm` against the motion, holding up to it at rest (a
    /// conveyor's belt, a brake pad).
    Friction {
        /// N·m.
        friction_nm: f64,
    },
    /// A fan or a centrifugal pump: `k_nm_s2`·ω·|ω| against the motion.
    Fan {
        /// N·m·s²/rad².
        k_nm_s2: f64,
    },
    /// Inertia alone (a flywheel, a drum), kg·m².
    Inertia {
        /// kg·m².
        j_kgm2: f64,
    },
}

/// A fault injected into the simulated hardware (issue 18's campaign): what the drive must
/// detect.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Injection {
    /// Current sensor of `phase` (0 = a, 1 = b, 2 = c) reads `gain·i + offset_a` from now on:
    /// dead (0, 0), stuck at x (0, x), a gain error (g, 0), an offset drift (1, x).
    CurrentSensor {
        /// Phase index 0…2.
        phase: usize,
        /// New gain.
        gain: f64,
        /// New offset, A.
        offset_a: f64,
    },
    /// The current channels of phases `first` and `second` read each other's phase from
    /// now on (swapped wiring; a commissioning check must refuse it).
    CurrentChannelsSwapped {
        /// Phase index 0…2.
        first: usize,
        /// Phase index 0…2.
        second: usize,
    },
    /// The encoder counter stops counting (a lost or stuck encoder).
    EncoderStuck,
    /// The encoder counts backwards from now on (its A and B channels swapped: an
    /// installation error commissioning must refuse).
    EncoderReversed,
    /// The encoder counter jumps by `counts` spurious counts at the next read (noise on its
    /// lines); the count stays off by that much. Needs the encoder model.
    EncoderGlitch {
        /// Spurious counts (either sign).
        counts: i64,
    },
    /// The encoder counts `lines` per revolution from now on while the estimator decodes
    /// with the configured number (a wrong line count). Needs the encoder model.
    EncoderLines {
        /// The encoder's actual lines per revolution.
        lines: u32,
    },
    /// The DC bus becomes `vdc_v` (a sag or a surge).
    BusVoltage {
        /// New bus voltage, V.
        vdc_v: f64,
    },
    /// The machine's electrical parameters become those of `motor` (the rotor heating, the
    /// magnetizing inductance saturating); the mechanics and the state carry over.
    Plant {
        /// The new electrical parameters (its J and B are not used).
        motor: MotorParams,
    },
    /// The load seizes: a friction torque of `torque_nm` brakes the rotor to rest and holds
    /// it there (a jammed gearbox or bearing; the deceleration is finite, as in a real
    /// seizure).
    LoadSeizure {
        /// The seized load's friction torque, N·m.
        torque_nm: f64,
    },
    /// The load's torque steps to `torque_nm` (as [`Event::LoadNm`]: positive against
    /// positive speed) — an overload beyond what the drive can give, which does not lock the
    /// rotor but drags it away from its reference.
    LoadStep {
        /// The new load torque, N·m.
        torque_nm: f64,
    },
    /// Two motor terminals short ([`crate::bridge_fault`]): a current through the short's
    /// resistance and inductance from leg to leg, which the current sensors and the
    /// comparator see.
    PhaseShort(PhaseShort),
    /// A switch conducts for good ([`crate::bridge_fault`]): the bus shoots through its leg
    /// whenever the leg's other switch turns on.
    SwitchShort(SwitchShort),
    /// A switch of `phase`'s leg never conducts again (a dead gate driver, a bond wire off):
    /// its leg cannot drive the current in that switch's direction, which then flows
    /// through the opposite diode — with the upper switch open, a positive phase current
    /// puts the leg at −V_dc/2 for the whole period (decided on the current at the period's
    /// start).
    SwitchOpen {
        /// Phase index 0…2.
        phase: usize,
        /// The upper switch (else the lower one).
        upper: bool,
    },
    /// The lead of `phase` (0 = a, 1 = b, 2 = c) opens: no current flows in it from now on
    /// (a broken wire or connector; the motor runs single-phase on the other two).
    OpenPhase {
        /// Phase index 0…2.
        phase: usize,
    },
}

impl Injection {
    /// A fault of the encoder (none of a sensorless drive's).
    pub fn is_encoders(&self) -> bool {
        matches!(
            self,
            Injection::EncoderStuck
                | Injection::EncoderReversed
                | Injection::EncoderGlitch { .. }
                | Injection::EncoderLines { .. }
        )
    }
}

/// When the drive leaves Magnetizing for Running: its flux model's time to
/// `magnetized_fraction` of its target on its reference current, `T_r·ln(1/(1 − f))` (0.19 s
/// for the DeLorenzo machine, 2.3 s for the 500 hp Krause machine), or the magnetizing fit's
/// longest when that is later ([`controller_core::mras::fit_time_max_s`]: a saturating
/// motor's fit slides its windows until the flux settles). Runs ask for torque after it.
pub fn magnetizing_time_s(spec: &controller_core::drive::DriveSpec) -> f64 {
    let flux_s = spec.motor.tr_s() * (1.0 / (1.0 - spec.magnetized_fraction)).ln();
    let [range, inductance_range] = [spec.rotor_resistance_range, spec.inductance_range];
    let fitting = range[0] < range[1] || inductance_range[0] < inductance_range[1];
    if fitting {
        let saturating = spec.magnetizing.is_some();
        let fit_s = controller_core::mras::fit_time_max_s(&spec.motor, range, inductance_range, saturating);
        flux_s.max(fit_s)
    } else {
        flux_s
    }
}

/// `m` with its resistances scaled by `rs_factor` and `rr_factor` (heating) and its
/// magnetizing inductance by `lm_factor` (saturation: L_s and L_r change by the same
/// amount, the leakage inductances stay) — a [`Injection::Plant`] change. `None` if the
/// result is not a valid motor.
pub fn scaled_plant(m: &MotorParams, rs_factor: f64, rr_factor: f64, lm_factor: f64) -> Option<MotorParams> {
    let lm = lm_factor * m.lm_h();
    MotorParams::new(
        rs_factor * m.rs_ohm(),
        rr_factor * m.rr_ohm(),
        m.ls_h() - m.lm_h() + lm,
        m.lr_h() - m.lm_h() + lm,
        lm,
        m.pole_pairs(),
        m.j_kgm2(),
        m.b_nms(),
    )
    .ok()
}

/// Load beyond the event-driven constant torque.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum LoadModel {
    /// Only the constant torque set by [`Event::LoadNm`].
    #[default]
    Torque,
    /// Eddy-current brake: T_L = k·ω_m (plus the event torque).
    EddyBrake {
        /// N·m per rad/s.
        k_nm_s_rad: f64,
    },
    /// Rotor held at standstill.
    LockedRotor,
    /// Coulomb (dry) friction of magnitude `friction_nm` (plus the event torque).
    CoulombFriction {
        /// N·m.
        friction_nm: f64,
    },
    /// A dynamometer: the rotor turns at `omega_m_rad_s` from the start, whatever the torque
    /// (for torque–speed measurements).
    Dynamometer {
        /// Mechanical speed, rad/s.
        omega_m_rad_s: f64,
    },
}

/// A closed-loop run.
#[derive(Clone, Debug, PartialEq)]
pub struct Scenario {
    /// Events `(t_s, event)`, in time order.
    pub events: Vec<(f64, Event)>,
    /// Simulated time, s.
    pub duration_s: f64,
    /// DC-bus voltage, V.
    pub vdc_v: f64,
    /// RK4 sub-steps per PWM period.
    pub substeps: u32,
    /// Trace decimation: one row every `trace_every` PWM periods.
    pub trace_every: u32,
    /// Sensor non-idealities.
    pub sensors: SensorModel,
    /// Load model.
    pub load: LoadModel,
    /// Inverter model.
    pub inverter: InverterModel,
    /// DC link (`None`: a stiff bus at `vdc_v`).
    pub dc_link: Option<DcLink>,
    /// The power board's hardware overcurrent comparator (`None`: not modelled).
    pub comparator: Option<Comparator>,
    /// Windings that heat with their losses, from these temperatures (`None`: the
    /// resistances stay as stated; [`plant::thermal`]).
    pub heating: Option<HeatingRun>,
    /// What the simulated machine has beyond its motor file's circuit: iron loss, a deep-bar
    /// rotor (`plant::Extras`; none by default).
    pub extras: plant::Extras,
}

/// A heating machine and its windings' temperatures at the start of a run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeatingRun {
    /// The thermal model of the run's machine.
    pub model: plant::thermal::Heating,
    /// The temperatures it starts from.
    pub windings: plant::thermal::Windings,
}

/// A validated open-loop scenario.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OpenLoop {
    /// Simulated time, s.
    pub duration_s: f64,
    /// Trace sample period, s.
    pub sample_period_s: f64,
    /// Motor.
    pub motor: MotorParams,
    /// Its magnetizing branch's saturation, if it has one.
    pub saturation: Option<controller_core::magnetics::Saturation>,
    /// Phase peak voltage, V.
    pub amplitude_v: f64,
    /// Source frequency, Hz.
    pub frequency_hz: f64,
    /// Load torque, N·m.
    pub load_nm: f64,
}

/// One trace row.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Row {
    /// Time, s.
    pub t_s: f64,
    /// Plant state.
    pub x: MachineState,
    /// The windings' temperatures, when they heat ([`Scenario::heating`]).
    pub windings: Option<plant::thermal::Windings>,
    /// Electromagnetic torque, N·m.
    pub torque_nm: f64,
    /// Applied stator voltage, V.
    pub v_ab_v: [f64; 2],
    /// Current references, A.
    pub i_ref_ab_a: [f64; 2],
    /// Speed reference, rad/s.
    pub omega_ref_rad_s: f64,
    /// The drive's q-axis current reference, A (its torque command over its torque factor
    /// and flux model).
    pub i_q_ref_a: f64,
    /// Load torque, N·m.
    pub load_nm: f64,
    /// The drive's mode after this period's step (`None` in open-loop runs).
    pub mode: Option<Mode>,
    /// The encoder's faults the drive rode through on its observer since its enable
    /// ([`Drive::ridden_through`]: still reported, not tripped on; empty in open-loop runs).
    pub ridden_through: FaultSet,
    /// The drive's observer's speed estimate after this period's step, mechanical rad/s
    /// ([`Drive::observed_speed_rad_s`]; `None` without an observer, and in open-loop runs).
    pub omega_est_rad_s: Option<f64>,
    /// Duties the drive decided for the next period (`None`: bridge off).
    pub duty: Option<[f64; 3]>,
    /// DC-bus voltage, V.
    pub vdc_v: f64,
    /// The drive's rotor-flux estimate, Wb.
    pub psi_est_wb: f64,
    /// The drive's rotor-flux reference, Wb.
    pub psi_ref_wb: f64,
    /// The rotor resistance the drive's field orientation runs on, × the motor file's.
    pub rr_scale: f64,
    /// The inductances the drive's field orientation runs on, × the motor file's.
    pub l_scale: f64,
    /// Current the inverter draws from the DC link during this period, A (negative:
    /// regeneration into the link).
    pub i_dc_a: f64,
    /// Current from the source into the link, A.
    pub i_source_a: f64,
    /// Current through the brake chopper's resistor, A.
    pub i_chopper_a: f64,
    /// The drive's brake output after this period's step (it switches the chopper in the
    /// next period).
    pub brake: bool,
    /// Largest |leg current| in this period, A (0 unless the comparator or a short is
    /// modelled: then the legs are resolved within the period, [`crate::bridge_fault`]).
    pub i_leg_peak_a: f64,
    /// The hardware comparator has broken the bridge (MOE cleared, latched).
    pub hw_break: bool,
    /// Largest stator current magnitude |i_s| (αβ) at the periods' (the open loop: the RK4
    /// steps') boundaries since the previous row, this row's included, A: a trace thinned
    /// to every n-th period keeps its peak (the summary's peak was the thinned rows': 0.955
    /// against 0.984 A at 1 ms sampling — found by trying).
    pub i_peak_a: f64,
    /// Periods since the previous row, this row's included, whose current sample the
    /// simulated low-side shunts could not read in one phase (`[0]`: the drive rebuilds it
    /// from the other two when it overmodulates) and in two or more (`[1]`: no phase sum
    /// gives them) — [`crate::sensors::SensorModel::low_side_window_s`].
    pub unsampled_periods: [u32; 2],
    /// A switch stuck open mattered in this period: its direction of current was needed
    /// and the duty it would have switched (at least [`SWITCH_ACTING_DUTY`]) went through
    /// the opposite diode instead — or, a lower switch, any of it, and the low-side shunt of
    /// a phase the sensors could read at the duty the drive asked for then reads nothing
    /// (its current flows through the upper diode).
    pub switch_acting: bool,
}

/// The least part of a period a stuck-open switch must have been asked to conduct for the
/// period to count as one where it mattered ([`Row::switch_acting`]).
pub const SWITCH_ACTING_DUTY: f64 = 0.02;

/// What a user checks when `machine` is too stiff to integrate: its parameters, and a
/// saturating one's curve (its steepest part, deep in saturation, sets the step).
fn stiffness_culprits(machine: &plant::Machine) -> &'static str {
    if machine.is_saturating() {
        "the motor's R_s, R_r, leakage and its [motor.saturation] curve (its steepest part sets the step)"
    } else {
        "the motor's R_s, R_r and inductances"
    }
}

fn non_finite(t_s: f64, machine: &plant::Machine) -> String {
    let why = if machine.is_saturating() {
        ": a saturating machine driven far past its curve's knee is stiffer than the integration step \
         (check [motor.saturation]: beta_per_wb is the knee's inverse flux, 1/Wb)"
    } else {
        ""
    };
    format!("the simulated machine's state is no longer finite at t = {t_s} s (the run diverged){why}")
}
