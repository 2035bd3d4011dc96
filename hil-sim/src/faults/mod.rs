//! The fault-injection matrix (issue 18): every fault the simulator can inject, at
//! standstill, mid-speed and top speed, motoring and generating, each run judged against
//! the detection the issue asks for.
//!
//! **Runs.** The drive file on its nominal motor with realistic sensors
//! ([`SensorModel::realistic_for_trip`], seeded by the row), a stiff bus: enable at 0, the operating
//! point's reference at [`REFERENCE_S`] with its load, the fault injected at [`INJECT_S`]
//! (the point reached: checked, the row fails otherwise), observed for [`OBSERVE_S`]; the
//! reference and the injection come later for a drive whose rotor magnetizes or whose speed
//! settles more slowly ([`Matrix::reference_s`], [`Matrix::inject_s`]).
//! Operating points ([`Point`]): standstill is a position hold (a speed law with
//! proportional action alone would turn under the load), mid-speed is half the base speed
//! on the bus, top speed 90 % of the drive's top (its certified ω_r,max/p, at most twice the
//! base speed: field weakening); the load is ±[`LOAD_FRACTION`] of the torque limit
//! (motoring: against the motion, or positive at standstill; generating: with it), at top
//! speed a quarter of that (the envelope's torque there is small).
//!
//! **Measured** (every PWM period from the injection): the fault latched first and when,
//! the PWM periods from the detection to the bridge off (the drive's output of the detecting
//! step: 0 means the bridge is off for the next period), the peak true phase current against
//! the trip level, the energy the motor returned to the bus
//! (`−∫ 1.5·(v_α i_α + v_β i_β) dt`, the average inverter being lossless) and the final mode.
//!
//! **Criteria** ([`Expect`]): a fault detected with its code within its bound (sensor faults
//! 10 ms, encoder faults two slow periods, open phase 50 ms, stall 0.5 s, bus one PWM
//! period), the bridge off within one PWM period of the detection, the peak phase current
//! ≤ 110 % of the trip level while the drive drives its bridge (and in the period its last
//! duties set up: with every switch open the inverter is a diode bridge, and a back-EMF
//! above the matrix's stiff, sagged bus drives the machine's own current through it — the
//! 35 kW member 022 at 4 kHz, top speed generating, its bus sagged to 299 V: 201–211 A
//! through the diodes over sensor seeds 0–4, its bridge off in the period of the sag,
//! against 110 % of its 184 A trip level); or — for a change the drive must tolerate — no
//! trip at all.
//! A row the bound cannot or does not yet hold for is a stated **gap** with its
//! reason: printed as such, and a failure of the matrix if it starts passing (so the list
//! stays true).

use crate::bridge_fault::{Comparator, PhaseShort, SwitchShort};
use crate::inverter::InverterModel;
use crate::scenario::Builtin;
use crate::sensors::SensorModel;
use crate::sim::{Event, Injection, LoadModel, Row, Scenario, scaled_plant};
use controller_core::drive::{DriveSpec, Fault, FaultSet, Mode, Reference, SpeedFeedback};
use controller_core::frames::AlphaBeta;
use rayon::prelude::*;

mod arrival;
mod expect;
mod field;
mod report;
mod sensor;
pub use arrival::{ARRIVAL_BAND_FRACTION, ARRIVAL_HORIZON};
pub use field::{dead_peak_after_s, phase_asked_after_s};
use report::ms;
pub use report::{Outcome, json, markdown, svg};
use sensor::SensorActing;
pub use sensor::{SENSOR_VERDICT_SIGMAS, sensor_window_sigma_a};
use std::sync::atomic::{AtomicBool, Ordering};

/// The operating point's reference (and load) come at this time at the earliest, s (the
/// drive magnetized; later for a slower rotor: [`Matrix::reference_s`]).
pub const REFERENCE_S: f64 = 0.25;
/// The fault is injected at this time at the earliest, s (every operating point reached;
/// later for a slower drive: [`Matrix::inject_s`]).
pub const INJECT_S: f64 = 2.5;
/// The reference waits this multiple of the flux model's magnetizing time
/// `T_r·ln(1/(1 − f))` (the current's rise on top of it).
pub const MAGNETIZING_MARGIN: f64 = 1.25;
/// The injection waits the slowest point's settling time on the ideal loop
/// ([`Matrix::approach`]) after the reference, and this much more, s (the drive's own
/// torque lags the ideal actuator's by its flux and current loops).
pub const SETTLE_EXTRA_S: f64 = 0.5;
/// The ideal loop has settled once it stays within this fraction of its final speed (plus
/// [`SETTLED_RAD_S`]).
pub const SETTLED_FRACTION: f64 = 0.02;
/// … rad/s.
pub const SETTLED_RAD_S: f64 = 1.0;
/// The ideal loop runs at most this long to find its final speed, s.
pub const APPROACH_MAX_S: f64 = 60.0;
/// Each run is observed this long after the injection, s (the stall bound and margin).
pub const OBSERVE_S: f64 = 0.6;
/// The bus sags to this fraction of the drive's undervoltage level (`[protection]`
/// vdc_min_v: 150 V for the shipped drive's 200 V) …
pub const BUS_SAG_FRACTION: f64 = 0.75;
/// … and surges to this fraction of its overvoltage level (450 V for its 400 V).
pub const BUS_SURGE_FRACTION: f64 = 1.125;
/// A current sensor sticks at this fraction of the trip level (1 A of the shipped drive's
/// 8 A), and drifts by half of it.
pub const SENSOR_STUCK_FRACTION: f64 = 0.125;
/// Load as a fraction of the torque limit (a quarter of it at top speed).
pub const LOAD_FRACTION: f64 = 0.25;
/// Peak phase current allowed, as a fraction of the trip level.
pub const PEAK_CURRENT_FRACTION: f64 = 1.1;
/// The operating point counts as reached when the speed at the injection is within this
/// of the speed the drive's law settles at on an ideal torque actuator ([`Matrix::approach`]:
/// a proportional law's droop under the load, the envelope's torque limit included), rad/s.
pub const REACHED_TOLERANCE_RAD_S: f64 = 15.0;
/// Detection bounds (issue 18's acceptance): sensor faults, s.
pub const SENSOR_BOUND_S: f64 = 0.010;
/// … open phase, s.
pub const OPEN_PHASE_BOUND_S: f64 = 0.050;
/// … stall, s.
pub const STALL_BOUND_S: f64 = 0.5;
/// The field's speed ω_e at the injection is measured on the reference current vector over
/// this long before it, s.
pub const FIELD_TURN_WINDOW_S: f64 = 0.02;

/// The overload case's load, a multiple of the torque limit (with the operating point's
/// load direction).
pub const OVERLOAD_FACTOR: f64 = 1.5;
/// … encoder faults, slow periods.
pub const ENCODER_BOUND_SLOW_PERIODS: f64 = 2.0;

/// Where the fault strikes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Point {
    /// Position hold at rest.
    Standstill,
    /// Half the base speed.
    Mid,
    /// 90 % of the top speed (field weakening).
    Top,
}

impl Point {
    /// Name in tables.
    pub fn name(self) -> &'static str {
        match self {
            Point::Standstill => "standstill",
            Point::Mid => "mid-speed",
            Point::Top => "top speed",
        }
    }
}

/// An operating point: where, and which way the torque flows.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OperatingPoint {
    /// Where.
    pub point: Point,
    /// Motoring (the load against the motion) or generating (the load driving).
    pub motoring: bool,
    /// Mechanical speed, rad/s.
    pub speed_rad_s: f64,
    /// Load torque, N·m (positive against positive speed).
    pub load_nm: f64,
}

impl OperatingPoint {
    /// "mid-speed motoring" and the like.
    pub fn name(&self) -> String {
        format!("{} {}", self.point.name(), if self.motoring { "motoring" } else { "generating" })
    }
}

/// A fault to inject.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Case {
    /// Short name (the bus cases' without their voltage: [`Case::title`]).
    pub name: &'static str,
    /// What is injected.
    pub injection: Injection,
}

impl Case {
    /// The name in tables: [`Case::name`], with its level where that is the drive's
    /// ("bus sag to 150 V", "sensor b stuck at 1 A", "sensor b offset +0.5 A").
    pub fn title(&self) -> String {
        match self.injection {
            Injection::BusVoltage { vdc_v } => format!("{} to {vdc_v:.0} V", self.name),
            Injection::CurrentSensor { gain, offset_a, .. } if gain == 0.0 && offset_a != 0.0 => {
                format!("{} at {} A", self.name, ten_digits(offset_a))
            }
            Injection::CurrentSensor { gain: 1.0, offset_a, .. } => {
                format!("{} {:+} A", self.name, ten_digits(offset_a))
            }
            // Half the board's lines ([`Matrix::encoder_lines`]).
            Injection::EncoderLines { lines } => format!("encoder {lines} lines ({} set)", 2 * lines),
            _ => self.name.into(),
        }
    }
}

/// `x` rounded to ten significant digits, which prints without the binary fraction's
/// tail: a level worked out as a fraction of the trip level printed "stuck at
/// 16.516000000000002 A" (found by trying a population member's matrix).
fn ten_digits(x: f64) -> f64 {
    format!("{x:.9e}").parse().unwrap_or(x)
}

/// What a row must show.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Expect {
    /// This fault, latched first, within `bound_s` of the injection.
    Fault {
        /// The code.
        fault: Fault,
        /// Detection bound, s.
        bound_s: f64,
    },
    /// Any of these faults (whichever protection acts first), within `bound_s`.
    Either {
        /// The codes.
        faults: &'static [Fault],
        /// Detection bound, s.
        bound_s: f64,
    },
    /// No trip: the drive must ride through it.
    RideThrough,
    /// No trip: the drive carries on on its observer (`speed_feedback =
    /// "encoder_ride_through"`), reports one of these faults within `bound_s`, and holds the
    /// operating point's speed to the end of the run (within [`REACHED_TOLERANCE_RAD_S`] of
    /// its speed at the injection).
    Reported {
        /// The codes.
        faults: &'static [Fault],
        /// Report bound, s.
        bound_s: f64,
    },
    /// A stated gap: what the issue asks (`fault` within `bound_s`) does not hold here, for
    /// the reason given. The row fails if it starts to hold, unless `may_close`.
    Gap {
        /// The code the issue asks for.
        fault: Fault,
        /// Its bound, s.
        bound_s: f64,
        /// Why it does not hold.
        why: &'static str,
        /// It may hold, as chance falls (an encoder fault whose change the readings'
        /// quantisation puts over the jump check's level or not: [`EncoderReach::Unsure`]).
        may_close: bool,
    },
}

impl Expect {
    /// The same expectation with its detection bound `lead_s` later (a fault the drive
    /// cannot see before the motor asks for what it took away: a stuck switch's dead
    /// direction, an open lead's phase); no bound, no change.
    fn later_by(self, lead_s: f64) -> Self {
        match self {
            Self::Fault { fault, bound_s } => Self::Fault { fault, bound_s: bound_s + lead_s },
            Self::Either { faults, bound_s } => Self::Either { faults, bound_s: bound_s + lead_s },
            other => other,
        }
    }
}

/// What the drive's jump check can make of an encoder fault at a row
/// ([`Matrix::encoder_reach`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EncoderReach {
    /// Seen at this spacing, in reads, however the readings' quantisation falls.
    Seen(usize),
    /// Seen at this spacing or not, as the readings' quantisation falls.
    Unsure(usize),
    /// The readings of a rotor that a seizure slowed, at every spacing.
    Unseen,
}

/// The matrix of one drive.
#[derive(Clone, Debug)]
pub struct Matrix {
    /// The drive.
    pub spec: DriveSpec,
    /// Its top speed (certified ω_r,max/p, at most twice the base speed), rad/s.
    pub top_speed_rad_s: f64,
    /// Bus voltage, V.
    pub vdc_v: f64,
    /// The board's hardware comparator, if the drive file gives one.
    pub comparator: Option<Comparator>,
    /// The board's encoder lines, which the simulated encoder has (the matrix's own
    /// 1 024 whatever the file said, until found by trying: a 13 000-line board's drive then
    /// tripped `EncoderLoss` in its campaign, and a 512-line board's "half the lines" row
    /// injected no change). [`drive_file::drive::DEFAULT_ENCODER_LINES`] from
    /// [`Matrix::new`]; the CLI sets the file's.
    pub encoder_lines: u32,
    /// The injection this long after [`INJECT_S`], s (0 in the matrix: its time on the fast
    /// steps' grid — tests move it off the open-phase check's windows; `hil-sim faults
    /// --inject-delay-ms`).
    pub inject_delay_s: f64,
    /// Another draw of the sensors' noise (0 in the matrix: [`Matrix::sensor_seed`];
    /// `hil-sim faults --seed`).
    pub seed: u64,
    /// The simulated machine when it is not the drive's own motor (`hil-sim faults
    /// --plant`): its T model, its magnetizing branch's saturation and its extras.
    pub plant: Option<crate::scenario::SimulatedMotor>,
    /// The reference's time and the injection's (before its delay), s: made once by
    /// [`Matrix::new`] from the drive ([`Matrix::reference_s`], [`Matrix::inject_s`]).
    times_s: (f64, f64),
    /// The six points' [`Approach`]es, made once by [`Matrix::new`] (the times and every
    /// row's "reached" read them).
    approaches: Vec<(OperatingPoint, Result<Approach, String>)>,
    /// When the drive itself, run healthy, has arrived at every point it reaches, s
    /// (`Matrix::arrival_s`): measured once, at the first use of [`Matrix::inject_s`], on
    /// the matrix as configured then (its plant, comparator and encoder).
    arrival_s: std::sync::OnceLock<f64>,
}

/// What the drive's speed law does on an ideal torque actuator from rest under an operating
/// point's reference and load ([`crate::campaign::IdealLoop`]: the law's own code, the
/// plant's mechanics, the envelope's torque at each speed).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Approach {
    /// The speed it settles at, rad/s (a proportional law's droop under the load included).
    pub final_rad_s: f64,
    /// When it has settled, from the reference: the last time it was farther than
    /// [`SETTLED_FRACTION`] of the final speed plus [`SETTLED_RAD_S`] from it, s.
    pub settle_s: f64,
}

/// One row of the matrix: its index (which seeds its sensors), the fault and the point.
pub type RowSpec = (u64, Case, OperatingPoint);

/// A row's name, `"<fault> at <operating point>"` (what `hil-sim faults --only` matches).
pub fn row_name(case: &Case, at: &OperatingPoint) -> String {
    format!("{} at {}", case.title(), at.name())
}

/// The short injected: two terminals through 0.05 Ω and 20 µH (a few metres of cable).
pub const SHORT: PhaseShort = PhaseShort { phases: [0, 1], resistance_ohm: 0.05, inductance_h: 20e-6 };

/// A shorted switch's shoot-through loop: the DC-link capacitor, the leg's two switches and
/// its shunt, 0.05 Ω and 100 nH (a compact power stage). On 310 V that is 3.1 A/ns: within
/// the comparator's 1 µs filter the leg's current reaches kiloamperes — the row shows it; a
/// real stage needs its gate driver's desaturation detection (sub-µs), which the board
/// model does not have. The matrix judges the detection and the motor's currents. The legs
/// are resolved in 1 µs sub-steps ([`crate::bridge_fault::SUBSTEPS`]) and the trip falls on
/// the first one past the level, so the printed peak leg current (≈ 2.4 kA) is an upper
/// bound: a continuous 1 µs RC filter on a 3.1 A/ns ramp crosses 12 A after ≈ 90 ns, near
/// 270 A.
pub const SHOOT_THROUGH: (f64, f64) = (0.05, 100e-9);

/// Phase a's `upper` switch shorted, through [`SHOOT_THROUGH`].
pub const fn switch_short(upper: bool) -> SwitchShort {
    SwitchShort { phase: 0, upper, resistance_ohm: SHOOT_THROUGH.0, inductance_h: SHOOT_THROUGH.1 }
}

impl Matrix {
    /// The matrix of the drive file `file` on `vdc_v` up to `omega_r_max_rad_s`: its spec,
    /// its encoder's lines and its board's comparator.
    pub fn of_file(file: &drive_file::DriveFile, omega_r_max_rad_s: f64, vdc_v: f64) -> Self {
        let mut m = Self::new(file.spec, omega_r_max_rad_s, vdc_v);
        m.encoder_lines = file.encoder_lines();
        m.comparator = file
            .board
            .and_then(|b| b.table.comparator)
            .map(|c| crate::bridge_fault::Comparator { trip_a: c.trip_a, filter_s: c.filter_s });
        // A drive on its magnetizing curve against the file's saturating machine.
        m.plant = file.saturating_motor.map(|(motor, sat)| crate::scenario::SimulatedMotor {
            motor,
            saturation: Some(sat),
            extras: plant::Extras::default(),
        });
        m
    }

    /// The matrix of `spec` on `vdc_v`, up to the electrical speed `omega_r_max_rad_s`
    /// (without the board's comparator: [`Matrix::comparator`]).
    pub fn new(spec: DriveSpec, omega_r_max_rad_s: f64, vdc_v: f64) -> Self {
        let m = &spec.motor;
        let base = crate::envelope::drive_base_speed_rad_s(&spec, vdc_v);
        let top = (omega_r_max_rad_s / f64::from(m.pole_pairs()))
            .min(drive_file::drive::FIELD_WEAKENING_RANGE * base);
        let mut m = Self {
            spec,
            top_speed_rad_s: top,
            vdc_v,
            comparator: None,
            encoder_lines: drive_file::drive::DEFAULT_ENCODER_LINES,
            inject_delay_s: 0.0,
            seed: 0,
            plant: None,
            times_s: (REFERENCE_S, INJECT_S),
            approaches: Vec::new(),
            arrival_s: std::sync::OnceLock::new(),
        };
        let magnetizing_s = MAGNETIZING_MARGIN * crate::sim::magnetizing_time_s(&m.spec);
        let reference_s = REFERENCE_S.max(magnetizing_s);
        m.approaches = m.points().into_iter().map(|p| (p, m.ideal_approach(&p))).collect();
        // A law that does not run on the ideal loop: the rows say so (`Matrix::run_one`).
        let settle_s =
            m.approaches.iter().filter_map(|(_, a)| a.as_ref().ok()).map(|a| a.settle_s).fold(0.0, f64::max);
        m.times_s = (reference_s, INJECT_S.max(reference_s + settle_s + SETTLE_EXTRA_S));
        m
    }

    /// When the operating point's reference and load come, s: [`REFERENCE_S`], or
    /// [`MAGNETIZING_MARGIN`] × the flux model's magnetizing time `T_r·ln(1/(1 − f))` when
    /// that is later (a large motor's rotor: a load that came while the drive magnetizes,
    /// its torque held at zero, would turn the rotor away from the point before the drive
    /// runs).
    pub fn reference_s(&self) -> f64 {
        self.times_s.0
    }

    /// `at`'s [`Approach`] (standstill, a position hold: at rest at once): one of the six
    /// points' made by [`Matrix::new`], another point's worked out now.
    pub fn approach(&self, at: &OperatingPoint) -> Result<Approach, String> {
        match self.approaches.iter().find(|(p, _)| p == at) {
            Some((_, a)) => a.clone(),
            None => self.ideal_approach(at),
        }
    }

    /// [`Matrix::approach`] worked out: the drive's speed law on the ideal loop from rest.
    fn ideal_approach(&self, at: &OperatingPoint) -> Result<Approach, String> {
        if at.point == Point::Standstill {
            return Ok(Approach { final_rad_s: 0.0, settle_s: 0.0 });
        }
        let (ideal, speeds, t_slow) = self.settled_ideal(at)?;
        let final_rad_s = ideal.omega_m_rad_s;
        if !final_rad_s.is_finite() {
            return Err(format!("the speed law's ideal loop does not settle at {}", at.name()));
        }
        let band = SETTLED_FRACTION * final_rad_s.abs() + SETTLED_RAD_S;
        let outside = speeds.iter().rposition(|w| (w - final_rad_s).abs() > band);
        Ok(Approach { final_rad_s, settle_s: outside.map_or(0.0, |k| (k + 1) as f64 * t_slow) })
    }

    /// The drive's speed law on the ideal loop from rest to `at` (its speed reference —
    /// at standstill 0, the position loop left out — and load), until the speed moves less
    /// than 1e-4 rad/s in a second (or [`APPROACH_MAX_S`]): the loop, the speeds on the way
    /// (one a slow period) and the slow period, s.
    fn settled_ideal(
        &self,
        at: &OperatingPoint,
    ) -> Result<(crate::campaign::IdealLoop, Vec<f64>, f64), String> {
        let t_slow = f64::from(self.spec.slow_divider) / self.spec.pwm_frequency_hz;
        let mut ideal = crate::campaign::IdealLoop::new(&self.spec, &self.spec.motor, self.vdc_v, t_slow)?;
        let per_s = (1.0 / t_slow).round().max(1.0) as usize;
        let mut speeds = Vec::new();
        while speeds.len() < per_s * APPROACH_MAX_S as usize {
            for _ in 0..per_s {
                ideal.step(at.speed_rad_s, at.load_nm);
                speeds.push(ideal.omega_m_rad_s);
            }
            let second_ago = speeds.len().checked_sub(per_s + 1).and_then(|k| speeds.get(k));
            if second_ago.is_some_and(|w| (ideal.omega_m_rad_s - w).abs() < 1e-4) {
                break;
            }
        }
        Ok((ideal, speeds, t_slow))
    }

    /// How long after an overload of `load_nm` the drive's speed law, settled at `at` on the
    /// ideal loop (as for [`Matrix::approach`]), takes to reach its torque limit, s (`None`
    /// past [`OBSERVE_S`], or no ideal loop). Below its limit the law answers the load by
    /// its own dynamics — a slow speed loop on a heavy rotor droops for hundreds of
    /// milliseconds first (the population's 52 kW 8-pole member 178: J = 10 kg·m², a PI of
    /// k_p 25.6 N·m·s/rad, J/k_p ≈ 0.39 s) — and the following-error check counts only at
    /// the limit. At standstill the position loop is left out: it adds to the speed error,
    /// so the law reaches its limit no later with it.
    /// Also the ideal loop's speed then, rad/s.
    pub fn overload_reach_s(&self, at: &OperatingPoint, load_nm: f64) -> Option<(f64, f64)> {
        let (ideal, _, t_slow) = self.settled_ideal(at).ok()?;
        let mut ideal = ideal.measured();
        let steps = (OBSERVE_S / t_slow).ceil() as usize;
        let k = (1..=steps).find(|_| ideal.step(at.speed_rad_s, load_nm))?;
        Some((k as f64 * t_slow, ideal.omega_m_rad_s))
    }

    /// The load an overload of `torque_nm` puts on the rotor at `at` (see [`Matrix::scenario`]).
    fn overload_nm(&self, torque_nm: f64, at: &OperatingPoint) -> f64 {
        let runaway = if at.motoring || at.point == Point::Standstill {
            0.0
        } else {
            self.spec.motor.b_nms() * self.spec.protection.overspeed_rad_s
        };
        (torque_nm + runaway).copysign(at.load_nm)
    }

    /// The six operating points.
    pub fn points(&self) -> Vec<OperatingPoint> {
        let tau = crate::campaign::torque_limit_nm(&self.spec);
        let base = crate::envelope::drive_base_speed_rad_s(&self.spec, self.vdc_v);
        let mut v = Vec::new();
        for (point, speed, load) in [
            (Point::Standstill, 0.0, LOAD_FRACTION * tau),
            (Point::Mid, 0.5 * base, LOAD_FRACTION * tau),
            (Point::Top, 0.9 * self.top_speed_rad_s, 0.25 * LOAD_FRACTION * tau),
        ] {
            for motoring in [true, false] {
                v.push(OperatingPoint {
                    point,
                    motoring,
                    speed_rad_s: speed,
                    load_nm: if motoring { load } else { -load },
                });
            }
        }
        v
    }

    /// The faults injected (the plant's parameter changes act on the simulated motor:
    /// [`Matrix::plant`]'s, else `spec.motor`). A sensorless drive has no encoder to fail:
    /// its matrix has no encoder rows.
    pub fn cases(&self) -> Result<Vec<Case>, String> {
        let mut cases = self.all_cases()?;
        if self.spec.speed_feedback == SpeedFeedback::Sensorless {
            cases.retain(|c| !c.injection.is_encoders());
        }
        Ok(cases)
    }

    /// Every fault the simulator injects, encoder's included.
    fn all_cases(&self) -> Result<Vec<Case>, String> {
        let m = self.plant.as_ref().map_or(&self.spec.motor, |p| &p.motor);
        let hot = scaled_plant(m, 1.0, 1.5, 1.0).ok_or("R_r × 1.5 is not a valid motor")?;
        let saturated = scaled_plant(m, 1.0, 1.0, 0.8).ok_or("L_m × 0.8 is not a valid motor")?;
        // Rounded to the milliampere: the names print it.
        let stuck_a = (1e3 * SENSOR_STUCK_FRACTION * self.spec.protection.i_trip_a).round() * 1e-3;
        Ok(vec![
            Case { name: "open phase a", injection: Injection::OpenPhase { phase: 0 } },
            Case { name: "short a–b (20 µH, 0.05 Ω)", injection: Injection::PhaseShort(SHORT) },
            Case {
                name: "switch a upper stuck open",
                injection: Injection::SwitchOpen { phase: 0, upper: true },
            },
            Case {
                name: "switch a lower stuck open",
                injection: Injection::SwitchOpen { phase: 0, upper: false },
            },
            Case { name: "switch a upper shorted", injection: Injection::SwitchShort(switch_short(true)) },
            Case { name: "switch a lower shorted", injection: Injection::SwitchShort(switch_short(false)) },
            Case { name: "encoder stuck", injection: Injection::EncoderStuck },
            Case { name: "encoder glitch 100 counts", injection: Injection::EncoderGlitch { counts: 100 } },
            Case {
                name: "encoder at half its lines",
                injection: Injection::EncoderLines { lines: (self.encoder_lines / 2).max(1) },
            },
            Case {
                name: "sensor b dead",
                injection: Injection::CurrentSensor { phase: 1, gain: 0.0, offset_a: 0.0 },
            },
            Case {
                name: "sensor b stuck",
                injection: Injection::CurrentSensor { phase: 1, gain: 0.0, offset_a: stuck_a },
            },
            Case {
                name: "sensor b gain 0.5",
                injection: Injection::CurrentSensor { phase: 1, gain: 0.5, offset_a: 0.0 },
            },
            Case {
                name: "sensor b offset",
                injection: Injection::CurrentSensor { phase: 1, gain: 1.0, offset_a: 0.5 * stuck_a },
            },
            Case {
                name: "bus sag",
                injection: Injection::BusVoltage { vdc_v: BUS_SAG_FRACTION * self.spec.protection.vdc_min_v },
            },
            Case {
                name: "bus surge",
                injection: Injection::BusVoltage {
                    vdc_v: BUS_SURGE_FRACTION * self.spec.protection.vdc_max_v,
                },
            },
            Case { name: "R_r step × 1.5 (heating)", injection: Injection::Plant { motor: hot } },
            Case { name: "L_m step × 0.8 (saturation)", injection: Injection::Plant { motor: saturated } },
            Case {
                name: "overload (1.5 × τ_max)",
                injection: Injection::LoadStep {
                    torque_nm: OVERLOAD_FACTOR * crate::campaign::torque_limit_nm(&self.spec),
                },
            },
            Case {
                name: "load seizure (10 × τ_max)",
                injection: Injection::LoadSeizure {
                    torque_nm: 10.0 * crate::campaign::torque_limit_nm(&self.spec),
                },
            },
        ])
    }

    /// Every row (case × point) in matrix order, each with its index.
    pub fn rows(&self) -> Result<Vec<RowSpec>, String> {
        let points = self.points();
        Ok(self
            .cases()?
            .into_iter()
            .flat_map(|c| points.clone().into_iter().map(move |p| (c, p)))
            .zip(0u64..)
            .map(|((c, p), k)| (k, c, p))
            .collect())
    }

    /// Every row, in parallel on all cores (rayon), in matrix order; `progress(done)`
    /// after each; `cancel` stops them at the next period.
    pub fn run(&self, progress: impl Fn(usize) + Sync, cancel: &AtomicBool) -> Result<Vec<Outcome>, String> {
        self.run_rows(&self.rows()?, progress, cancel)
    }

    /// The rows given (a selection of [`Matrix::rows`], their indices kept: each runs as in
    /// the whole matrix), in parallel, in the order given.
    pub fn run_rows(
        &self,
        rows: &[RowSpec],
        progress: impl Fn(usize) + Sync,
        cancel: &AtomicBool,
    ) -> Result<Vec<Outcome>, String> {
        // The drive's arrival measured before the rows (each reads it) start in parallel.
        self.inject_s();
        let done = std::sync::atomic::AtomicUsize::new(0);
        rows.par_iter()
            .map(|(k, case, at)| {
                let o = self.run_one(*k, case, at, self.expect(case, at), cancel);
                progress(done.fetch_add(1, Ordering::Relaxed) + 1);
                o
            })
            .collect()
    }

    /// The seed of row `k`'s sensors (noise, quantisation offsets): the matrix's own for
    /// [`Matrix::seed`] 0, another draw for each other seed.
    pub fn sensor_seed(&self, k: u64) -> u64 {
        (0xFA17 + k).wrapping_add(self.seed << 32)
    }

    /// The time of the injection, s: [`INJECT_S`], or — for a drive slower to reach its
    /// points — the slowest point's settling time after [`Matrix::reference_s`] plus
    /// [`SETTLE_EXTRA_S`], or when the drive itself, run healthy, has arrived at every point
    /// it reaches (see [`ARRIVAL_BAND_FRACTION`]) if that is later still; then the delay
    /// ([`Matrix::inject_delay_s`]).
    pub fn inject_s(&self) -> f64 {
        self.times_s.1.max(self.arrival_s()) + self.inject_delay_s
    }

    /// Row `k`'s run, `case` at `at`, as a scenario: what [`Matrix::run_one`] judges, and
    /// what `hil-sim faults --trace` writes out.
    pub fn scenario(&self, k: u64, case: &Case, at: &OperatingPoint) -> Builtin {
        // An overload acts the way the operating point's load does (against the motion when
        // motoring, with it when generating). Generating at speed, it also carries the
        // motor's friction at the overspeed level: a load the drive's brake and the friction
        // b·ω hold below overspeed is not a runaway but a droop (found on the 24 V drive,
        // whose 1.5 × τ_max settled at 383 rad/s, 35 % over its reference, with the
        // saturated-P loop short of its limit — a row the matrix failed as "not detected").
        let injection = match case.injection {
            Injection::LoadStep { torque_nm } => {
                Injection::LoadStep { torque_nm: self.overload_nm(torque_nm, at) }
            }
            other => other,
        };
        let inject_s = self.inject_s();
        self.point_run(k, row_name(case, at), at, Some((inject_s, injection)), inject_s + OBSERVE_S)
    }

    /// Row `k`'s run at `at` (its sensors seeded by `k`), named `about`: the reference and
    /// the load at [`Matrix::reference_s`], then `fault` (its time and injection) if any,
    /// for `duration_s`.
    fn point_run(
        &self,
        k: u64,
        about: String,
        at: &OperatingPoint,
        fault: Option<(f64, Injection)>,
        duration_s: f64,
    ) -> Builtin {
        let reference = if at.point == Point::Standstill {
            Reference::Position(0.0)
        } else {
            Reference::Speed(at.speed_rad_s as f32)
        };
        let mut events = vec![
            (0.0, Event::Enable),
            (self.reference_s(), Event::Reference(reference)),
            (self.reference_s(), Event::LoadNm(at.load_nm)),
        ];
        events.extend(fault.map(|(t_s, injection)| (t_s, Event::Fault(injection))));
        Builtin {
            name: format!("faults-{k}"),
            about,
            spec: self.spec,
            plant: self.plant.map_or(self.spec.motor, |p| p.motor),
            plant_saturation: self.plant.and_then(|p| p.saturation),
            expect_fault: None,
            scenario: Scenario {
                events,
                duration_s,
                vdc_v: self.vdc_v,
                substeps: 1,
                trace_every: 1,
                sensors: SensorModel {
                    encoder_lines: Some(self.encoder_lines),
                    ..SensorModel::realistic_for_trip(self.sensor_seed(k), self.spec.protection.i_trip_a)
                },
                load: LoadModel::Torque,
                inverter: InverterModel::Average,
                dc_link: None,
                comparator: self.comparator,
                heating: None,
                extras: self.plant.map_or(plant::Extras::default(), |p| p.extras),
            },
        }
    }

    /// One row (`k` seeds its sensors), judged against `expect` (the matrix's own:
    /// [`Matrix::expect`]).
    pub fn run_one(
        &self,
        k: u64,
        case: &Case,
        at: &OperatingPoint,
        expect: Expect,
        cancel: &AtomicBool,
    ) -> Result<Outcome, String> {
        let b = self.scenario(k, case, at);
        let pwm_s = 1.0 / self.spec.pwm_frequency_hz;
        let i_trip = self.spec.protection.i_trip_a;
        let mut speed_at_injection = f64::NAN;
        let mut detected: Option<(Fault, f64)> = None;
        let mut reported: Option<(FaultSet, f64)> = None;
        let mut final_speed = f64::NAN;
        let mut off_after: Option<u64> = None;
        let (mut peak, mut peak_leg, mut energy) = (0.0f64, 0.0f64, 0.0f64);
        // The peak while the bridge is driven and in the period after (`Outcome::peak_driven_a`),
        // and whether the last row's bridge was driven.
        let (mut peak_driven, mut was_driven) = (0.0f64, true);
        let mut before_injection_fault: Option<(Mode, f64)> = None;
        let mut mode_at_reference: Option<Mode> = None;
        let mut acting_at: Option<f64> = None;
        // A current sensor's fault acts once the sensors' error comes clear of the windowed
        // current-sum check's level for a window ([`SensorActing`]).
        let mut sensor_fault = SensorActing::new(
            &case.injection,
            &b.scenario.sensors,
            self.spec.protection.current_sum_mean_max_a,
            self.spec.open_phase_slow_steps(),
            self.spec.slow_divider,
        );
        // The first period a phase's or a leg's current was above the trip level.
        let mut over_trip_at: Option<f64> = None;
        // The first row at or after the injection (the event loop's own comparison).
        let mut injected_at: Option<f64> = None;
        // The reference vector's turn over the last FIELD_TURN_WINDOW_S before the injection:
        // [its angle at the last row, the time, the angle turned (signed)], rad and s.
        let mut turn: Option<[f64; 3]> = None;
        // The reference vector's angle at the injection, rad.
        let mut theta_at_injection = f64::NAN;
        let final_mode = b.run_into(
            |_| {},
            |r: &Row| {
                if cancel.load(Ordering::Relaxed) {
                    return Err("interrupted".into());
                }
                if r.t_s >= self.reference_s() && mode_at_reference.is_none() {
                    mode_at_reference = r.mode;
                }
                if r.t_s < self.inject_s() {
                    if r.t_s >= self.inject_s() - FIELD_TURN_WINDOW_S {
                        let angle = r.i_ref_ab_a[1].atan2(r.i_ref_ab_a[0]);
                        let [last, time, turned] = turn.unwrap_or([angle, 0.0, 0.0]);
                        let step = (angle - last + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
                            - std::f64::consts::PI;
                        turn = Some([angle, time + pwm_s, turned + step]);
                    }
                    if before_injection_fault.is_none()
                        && let Some(mode @ Mode::Fault(_)) = r.mode
                    {
                        before_injection_fault = Some((mode, r.t_s));
                    }
                    return Ok(());
                }
                let t0 = *injected_at.get_or_insert(r.t_s);
                if r.t_s == t0 {
                    speed_at_injection = r.x.omega_m_rad_s;
                    theta_at_injection = r.i_ref_ab_a[1].atan2(r.i_ref_ab_a[0]);
                }
                let i = AlphaBeta { alpha: r.x.i_alpha_a, beta: r.x.i_beta_a }.inverse_clarke();
                let phase_peak = i.a.abs().max(i.b.abs()).max(i.c.abs());
                peak = peak.max(phase_peak);
                if was_driven || r.duty.is_some() {
                    peak_driven = peak_driven.max(phase_peak);
                }
                was_driven = r.duty.is_some();
                peak_leg = peak_leg.max(r.i_leg_peak_a);
                if over_trip_at.is_none() && phase_peak.max(r.i_leg_peak_a) > i_trip {
                    over_trip_at = Some(r.t_s - t0);
                }
                if acting_at.is_none() && r.switch_acting {
                    acting_at = Some(r.t_s - t0);
                }
                if let Some(sensor) = &mut sensor_fault
                    && acting_at.is_none()
                {
                    acting_at = sensor.add(r.t_s - t0, [i.a, i.b, i.c]);
                }
                energy -= 1.5 * (r.v_ab_v[0] * r.x.i_alpha_a + r.v_ab_v[1] * r.x.i_beta_a) * pwm_s;
                if detected.is_none()
                    && let Some(Mode::Fault(f)) = r.mode
                {
                    detected = Some((f, r.t_s - t0));
                }
                if reported.is_none() && r.ridden_through != FaultSet::EMPTY {
                    reported = Some((r.ridden_through, r.t_s - t0));
                }
                final_speed = r.x.omega_m_rad_s;
                if let Some((_, t)) = detected
                    && off_after.is_none()
                    && r.duty.is_none()
                {
                    off_after = Some(((r.t_s - t0 - t) / pwm_s).round() as u64);
                }
                Ok(())
            },
        )?;
        // A row whose point the drive did not reach is a failed row with its reason (the
        // judgement below still runs: what it shows is stated, not trusted).
        let mut failures = Vec::new();
        if let Some((mode, t)) = before_injection_fault {
            failures.push(format!("{mode:?} before the injection (at {t:.4} s)"));
        }
        if let Some(mode) = mode_at_reference.filter(|m| *m != Mode::Running) {
            failures.push(format!("{mode:?}, not Running, when the reference came"));
        }
        match self.approach(at) {
            Ok(a) => {
                let off = (speed_at_injection - a.final_rad_s).abs();
                // A NaN (no row at the injection) fails too.
                if off.is_nan() || off > REACHED_TOLERANCE_RAD_S {
                    failures.push(format!(
                        "the operating point was not reached ({speed_at_injection:.1} rad/s, the law settles at \
                         {:.1} on an ideal actuator)",
                        a.final_rad_s
                    ));
                }
            }
            Err(e) => failures.push(e),
        }
        // The bound's origin: the injection, a stuck switch's first use, or the period a
        // short's current crossed the trip level (issue 18: "1 PWM period after the current
        // crosses the trip level"; on a low bus, or with the legs' voltages alike at rest, a
        // short's current takes periods to get there).
        let acting_after_s = match case.injection {
            Injection::SwitchOpen { .. } | Injection::CurrentSensor { .. } => acting_at,
            Injection::PhaseShort(_) | Injection::SwitchShort(_) => Some(over_trip_at.unwrap_or(0.0)),
            _ => Some(0.0),
        };
        let latent = acting_after_s.is_none();
        // A stuck switch's bound runs from the first peak of the reference in its dead
        // direction after the injection ([`dead_peak_after_s`]), or the first period it
        // mattered if later, at most the observation later.
        // Its dead direction needed only after the end of the observation: the switch acted on
        // the waning tail of a half-wave only (at rest, where the field turns at a slip of a
        // fraction of a hertz, the 8-pole population member 018's) and is not needed again
        // within the run — no check can see a direction nobody asks for: undetected is no
        // failure, a detection is judged as any.
        let mut unneeded = false;
        let omega_e = turn.map_or(f64::NAN, |[_, time, turned]| turned / time);
        let expect = match (case.injection, expect, acting_after_s) {
            (Injection::SwitchOpen { phase, upper }, e @ Expect::Either { .. }, Some(acting)) => {
                let peak = dead_peak_after_s(phase, upper, theta_at_injection, omega_e);
                unneeded = peak > OBSERVE_S;
                e.later_by((peak - acting).clamp(0.0, OBSERVE_S))
            }
            // An open lead takes both directions: its bound runs from the first period after
            // the injection where the phase is asked for a current the checks count
            // ([`phase_asked_after_s`]) — injected at the phase's zero crossing at rest,
            // where the field turns at the slip frequency, it takes nothing the drive asks for
            // until the reference grows (the 8-pole member 018 at 10 kHz: phase a's reference
            // under a fifth of the others' for the first 50 ms, `OpenPhase` 52.1 ms after the
            // injection).
            (Injection::OpenPhase { phase }, e, Some(_)) => {
                let asked = phase_asked_after_s(phase, theta_at_injection, omega_e);
                e.later_by(if asked.is_finite() { asked.min(OBSERVE_S) } else { 0.0 })
            }
            (_, e, _) => e,
        };
        // A sensor's error below the check's level is still its fault: named early, it is
        // judged by its name (a switch that never mattered must not trip anything).
        let sensor = sensor_fault.is_some();
        let from_origin = detected.map(|(f, t)| (f, t - acting_after_s.unwrap_or(t)));
        let judge = |accept: &[Fault], bound_s: f64, failures: &mut Vec<String>| match from_origin {
            None if latent || unneeded => {}
            Some((f, t)) if latent && !sensor => {
                failures.push(format!("{f:?} after {} although the switch never mattered", ms(t)))
            }
            Some((f, t)) if accept.contains(&f) && t <= bound_s + 0.5 * pwm_s => {
                if off_after.is_none_or(|n| n > 1) {
                    failures.push(format!("bridge off after {off_after:?} periods"));
                }
            }
            Some((f, t)) if accept.contains(&f) => {
                failures.push(format!("{f:?} after {}, bound {}", ms(t), ms(bound_s)))
            }
            Some((f, _)) => failures.push(format!("detected as {f:?}, not {accept:?}")),
            None => failures.push(format!("not detected ({final_mode:?} at the end)")),
        };
        match expect {
            Expect::Fault { fault, bound_s } => judge(&[fault], bound_s, &mut failures),
            Expect::Either { faults, bound_s } => judge(faults, bound_s, &mut failures),
            Expect::RideThrough => {
                if let Some((f, t)) = detected {
                    failures.push(format!("tripped: {f:?} after {}", ms(t)));
                }
            }
            Expect::Reported { faults, bound_s } => {
                if let Some((f, t)) = detected {
                    failures.push(format!("tripped: {f:?} after {}", ms(t)));
                }
                match reported {
                    Some((set, t))
                        if faults.iter().any(|f| set.contains(*f)) && t <= bound_s + 0.5 * pwm_s => {}
                    Some((set, t)) => failures.push(format!(
                        "reported {} after {}, bound {}",
                        report::names(set),
                        ms(t),
                        ms(bound_s)
                    )),
                    None => failures.push("not reported".into()),
                }
                let drift = (final_speed - speed_at_injection).abs();
                if drift.is_nan() || drift > REACHED_TOLERANCE_RAD_S {
                    failures.push(format!(
                        "the speed was not held: {final_speed:.1} rad/s at the end, {speed_at_injection:.1} at the injection"
                    ));
                }
            }
            Expect::Gap { fault, bound_s, may_close, .. } => {
                let mut would = Vec::new();
                judge(&[fault], bound_s, &mut would);
                if !may_close && would.is_empty() && peak_driven <= PEAK_CURRENT_FRACTION * i_trip {
                    failures
                        .push("gap closed: the row now meets the issue's bound (update the matrix)".into());
                }
            }
        }
        if !matches!(expect, Expect::Gap { .. })
            && (peak_driven.is_nan() || peak_driven > PEAK_CURRENT_FRACTION * i_trip)
        {
            failures.push(format!(
                "peak current {peak_driven:.2} A > {:.0} % of {i_trip} A while the bridge was driven",
                100.0 * PEAK_CURRENT_FRACTION
            ));
        }
        Ok(Outcome {
            case: *case,
            at: *at,
            expect,
            speed_at_injection_rad_s: speed_at_injection,
            detected,
            reported,
            final_speed_rad_s: final_speed,
            acting_after_s,
            tripped_before_s: before_injection_fault.map(|(_, t)| t),
            off_after_periods: off_after,
            peak_current_a: peak,
            peak_driven_a: peak_driven,
            peak_leg_a: peak_leg,
            energy_into_bus_j: energy,
            final_mode,
            failures,
        })
    }
}
