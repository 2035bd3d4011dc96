//! Scenario files (TOML): a drive plus a run.
//!
//! **Closed loop** — the drive's tables (`[pwm]`, `[motor]`, `[controller]`,
//! `[protection]`, the drive-file format of `drive_file`) embedded, or a drive file named
//! by `drive = "path"` (relative to the scenario file); then the run:
//!
//! ```toml
//! drive = "../../drive.toml"      # or embed [pwm], [motor], [controller], [protection]
//! duration_s = 3.5                # ≤ MAX_DURATION_S
//! sample_period_s = 1e-3          # trace sample period (a multiple of the PWM period)
//! vdc_v = 310.0
//! rk4_substeps = 1                # default 1 (see tests/substeps.rs)
//! expect_fault = "DcBusUndervoltage"   # optional: the run tests a protection — it passes
//!                                  # only if the drive latches this fault (`hil-sim run`
//!                                  # otherwise fails when the drive ends in any fault)
//!
//! # [plant]                        # optional: the simulated machine, if not [motor]
//!
//! [load]                           # optional: "torque" (events only, default),
//! kind = "eddy_brake"              # "eddy_brake" with k_nm_s_rad, "locked_rotor",
//! k_nm_s_rad = 0.002               # "coulomb_friction" with friction_nm, or "dynamometer"
//!                                  # with omega_m_rad_s (the rotor held at that speed)
//!
//! [inverter]                       # optional: "average" (default) or
//! kind = "switching"               # carrier comparison with dead time
//! dead_time_s = 1e-6
//!
//! [dc_link]                        # optional: without it the bus is stiff at vdc_v
//! capacitance_f = 470e-6
//! source = "rectifier"             # or "supply" (sinks current too); open-circuit vdc_v
//! resistance_ohm = 0.5             # the source's internal resistance
//! chopper = { resistance_ohm = 100.0 }   # optional: the brake resistor, switched by the
//!                                  # drive ([protection] brake_chopper)
//!
//! [sensors]                        # optional, every key defaults to ideal
//! current_lsb_a = 0.00806
//! current_offset_a = [0.0, 0.0, 0.0]
//! encoder_lines = 1024
//!
//! [[events]]
//! t_s = 0.0
//! kind = "enable"
//! [[events]]
//! t_s = 0.3
//! kind = "speed"                   # speed (rad/s), position (rad), torque (N·m), load (N·m:
//!                                  # an active load, which drives a tripped rotor too);
//!                                  # a passive load coupled from then on, added to what is
//!                                  # there: "friction" (N·m, dry), "fan" (N·m at
//!                                  # omega_rad_s, square law), "inertia" (kg·m²);
//!                                  # "stop": a controlled stop (brake to rest, bridge off)
//! value = 150.0                    # or kind = "rotating_current", amplitude_a, omega_rad_s
//! [[events]]                       # a fault injected into the simulated hardware:
//! t_s = 1.0
//! kind = "fault"
//! fault = "current_sensor"         # phase = "a"|"b"|"c", gain, offset_a (dead: 0, 0)
//! phase = "b"                      # or "encoder_stuck", "encoder_glitch" (counts),
//!                                  # "encoder_lines" (lines: the encoder's actual count),
//!                                  # "bus_voltage" (vdc_v), "load_seizure" (torque_nm: its
//!                                  # friction), "open_phase" (phase), "plant" (rs_factor,
//!                                  # rr_factor, lm_factor: the plant's R_s, R_r, L_m
//!                                  # scaled — heating, saturation; each default 1),
//!                                  # "phase_short" (phases = "ab", resistance_ohm,
//!                                  # inductance_h: two motor terminals shorted),
//!                                  # "switch_open" (phase, switch = "upper"|"lower"),
//!                                  # "switch_short" (phase, switch, resistance_ohm,
//!                                  # inductance_h: the leg's shoot-through loop)
//! gain = 0.0
//! offset_a = 0.0
//!
//! [comparator]                     # optional: the board's hardware overcurrent comparator
//! trip_a = 12.0                    # on the leg currents (hil_sim::bridge_fault)
//! filter_s = 1e-6
//!
//! [iron_loss]                      # optional: a resistance across the machine's magnetizing
//! resistance_ohm = 400.0           # branch (plant::saturated; a saturating machine in the
//!                                  # inverse-Γ form, a linear one in its inverse-Γ equivalent)
//!
//! [deep_bar]                       # optional: a deep-bar rotor (plant::saturated: a second
//! high_slip_resistance_factor = 2.0  # cage): the rotor resistance rises from [motor]'s at zero
//! corner_slip_hz = 10.0            # slip to this factor times it at high slip, the rise
//!                                  # centred at this slip frequency (same forms as iron_loss)
//!
//! [heating]                        # optional: windings that heat with their copper losses,
//! rated_rise_k = 80.0              # R_s and R_r following them (plant::thermal): the rise
//! ambient_c = 40.0                 # at the rated current (IEC 60034-1 class B: 80 K);
//! reference_c = 20.0               # where [motor]'s resistances are stated;
//! start = "cold"                   # "cold" (ambient), "hot" (rated rise) or start_c = 90.0;
//! # rated_current_a, time_constant_s: default [motor]'s; no_load_current_a: default the
//! # rated flux's magnetizing current, flux_ref_wb/(√2·L_m)
//! ```
//!
//! **Open loop** (plant alone, validation) — a `[motor]` table (or `drive = "path"` for
//! its motor) and an ideal source:
//!
//! ```toml
//! duration_s = 1.0
//! sample_period_s = 1e-4
//! [motor]
//! # …
//! [source]
//! kind = "sine"
//! amplitude_v = 180.0   # phase peak
//! frequency_hz = 50.0
//! [load]
//! kind = "constant"
//! torque_nm = 0.0
//! ```
//!
//! A file is closed-loop when it has a `[controller]` table or a `drive` key. Every bad
//! value is an error `file:line:column: key: reason`.

use crate::inverter::InverterModel;
use crate::scenario::Builtin;
use crate::sensors::SensorModel;
use crate::sim::{Event, Injection, LoadModel, OpenLoop, PassiveLoad, Scenario};
use controller_core::drive::Reference;
use controller_core::fault::Fault;
use drive_file::board::BoardTable;
use drive_file::certify::CertifyTable;
use drive_file::drive::{ControllerTable, ProtectionTable, PwmTable};
use drive_file::motor::MotorTable;
use drive_file::source::num;
use drive_file::values::exact;
use drive_file::{DriveFile, FileError, Source};
use serde::Deserialize;
use std::path::Path;

/// Longest simulated time a scenario may ask for, s (an hour of motor time: 72 million
/// PWM periods at 20 kHz).
pub const MAX_DURATION_S: f64 = 3600.0;
/// Most trace rows a run may write (≈ 0.7 GB of CSV).
pub const MAX_TRACE_ROWS: f64 = 5e6;
/// Largest magnitude of an event value (speed in rad/s, position in rad, torque or load in
/// N·m, current in A): far beyond any machine, and finite in the drive's f32.
pub const MAX_EVENT_VALUE: f64 = 1e6;

/// A scenario file of either kind.
#[derive(Debug, Clone)]
pub enum ScenarioFileKind {
    /// Plant fed by an ideal source (`[source]`).
    OpenLoop(Box<OpenLoop>),
    /// Drive against the plant.
    ClosedLoop(Box<Builtin>),
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct OpenLoopFile {
    duration_s: f64,
    sample_period_s: f64,
    drive: Option<String>,
    motor: Option<MotorTable>,
    source: SourceTable,
    load: Option<ConstantLoad>,
}

#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
enum SourceTable {
    /// v_α = A cos 2πft, v_β = A sin 2πft (A = phase peak).
    Sine { amplitude_v: f64, frequency_hz: f64 },
}

#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
enum ConstantLoad {
    Constant { torque_nm: f64 },
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ClosedLoopFile {
    duration_s: f64,
    sample_period_s: f64,
    vdc_v: f64,
    #[serde(default = "one")]
    rk4_substeps: u32,
    drive: Option<String>,
    pwm: Option<PwmTable>,
    motor: Option<MotorTable>,
    controller: Option<ControllerTable>,
    protection: Option<ProtectionTable>,
    certify: Option<CertifyTable>,
    board: Option<BoardTable>,
    plant: Option<MotorTable>,
    load: Option<LoadTable>,
    inverter: Option<InverterTable>,
    dc_link: Option<DcLinkTable>,
    comparator: Option<ComparatorTable>,
    heating: Option<HeatingTable>,
    iron_loss: Option<IronLossTable>,
    deep_bar: Option<DeepBarTable>,
    #[serde(default)]
    sensors: SensorsTable,
    /// The fault the run is meant to end in, by its name (`"DcBusUndervoltage"`).
    expect_fault: Option<String>,
    events: Vec<EventTable>,
}

/// `[iron_loss]`: a resistance across the simulated machine's magnetizing branch.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct IronLossTable {
    resistance_ohm: f64,
}

/// `[deep_bar]`: a deep-bar rotor ([`plant::DeepBar`]).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct DeepBarTable {
    high_slip_resistance_factor: f64,
    corner_slip_hz: f64,
}

/// `[heating]`: windings that heat with their losses ([`plant::thermal`]).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct HeatingTable {
    rated_rise_k: f64,
    ambient_c: f64,
    reference_c: f64,
    rated_current_a: Option<f64>,
    time_constant_s: Option<f64>,
    no_load_current_a: Option<f64>,
    start: Option<HeatingStart>,
    start_c: Option<f64>,
}

#[derive(Debug, Deserialize, Clone, Copy)]
#[serde(rename_all = "snake_case")]
enum HeatingStart {
    Cold,
    Hot,
}

/// `[comparator]`: the power board's hardware overcurrent comparator.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ComparatorTable {
    trip_a: f64,
    filter_s: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct DcLinkTable {
    capacitance_f: f64,
    source: LinkSourceTable,
    resistance_ohm: f64,
    chopper: Option<ChopperTable>,
}

#[derive(Debug, Deserialize, Clone, Copy)]
#[serde(rename_all = "snake_case")]
enum LinkSourceTable {
    Supply,
    Rectifier,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ChopperTable {
    resistance_ohm: f64,
}

/// The fastest a dynamometer load may turn the rotor, mechanical rad/s (the design
/// toolkit's largest certified speed).
pub const MAX_DYNAMOMETER_RAD_S: f64 = 20_000.0;

fn one() -> u32 {
    1
}

#[derive(Debug, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
enum LoadTable {
    Torque,
    EddyBrake { k_nm_s_rad: f64 },
    LockedRotor,
    CoulombFriction { friction_nm: f64 },
    Dynamometer { omega_m_rad_s: f64 },
}

#[derive(Debug, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
enum InverterTable {
    Average,
    Switching { dead_time_s: f64 },
}

#[derive(Debug, Deserialize)]
#[serde(default, deny_unknown_fields)]
struct SensorsTable {
    current_lsb_a: f64,
    #[serde(deserialize_with = "exact")]
    current_offset_a: [f64; 3],
    #[serde(deserialize_with = "exact")]
    current_gain: [f64; 3],
    current_noise_rms_a: f64,
    vdc_lsb_v: f64,
    encoder_lines: Option<u32>,
    seed: u64,
}

impl Default for SensorsTable {
    fn default() -> Self {
        let m = SensorModel::default();
        Self {
            current_lsb_a: m.current_lsb_a,
            current_offset_a: m.current_offset_a,
            current_gain: m.current_gain,
            current_noise_rms_a: m.current_noise_rms_a,
            vdc_lsb_v: m.vdc_lsb_v,
            encoder_lines: m.encoder_lines,
            seed: m.seed,
        }
    }
}

#[derive(Debug, Deserialize)]
#[serde(rename_all = "snake_case")]
enum EventKind {
    Enable,
    Stop,
    Speed,
    Position,
    Torque,
    Load,
    Friction,
    Fan,
    Inertia,
    RotatingCurrent,
    Fault,
}

#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(rename_all = "snake_case")]
enum FaultKind {
    CurrentSensor,
    OpenPhase,
    EncoderStuck,
    EncoderGlitch,
    EncoderLines,
    Plant,
    PhaseShort,
    SwitchOpen,
    SwitchShort,
    BusVoltage,
    LoadSeizure,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct EventTable {
    t_s: f64,
    kind: EventKind,
    value: Option<f64>,
    amplitude_a: Option<f64>,
    omega_rad_s: Option<f64>,
    fault: Option<FaultKind>,
    phase: Option<String>,
    gain: Option<f64>,
    offset_a: Option<f64>,
    vdc_v: Option<f64>,
    torque_nm: Option<f64>,
    counts: Option<i64>,
    lines: Option<u32>,
    phases: Option<String>,
    switch: Option<String>,
    resistance_ohm: Option<f64>,
    inductance_h: Option<f64>,
    rs_factor: Option<f64>,
    rr_factor: Option<f64>,
    lm_factor: Option<f64>,
}

/// `duration_s` and `sample_period_s` within their stated maxima; returns the row count.
fn check_timing(src: &Source<'_>, duration_s: f64, sample_period_s: f64) -> Result<f64, FileError> {
    src.check(
        duration_s.is_finite() && duration_s > 0.0 && duration_s <= MAX_DURATION_S,
        "duration_s",
        &format!("is {}; must lie in (0, {MAX_DURATION_S}] s", num(duration_s)),
    )?;
    src.check(
        sample_period_s.is_finite() && sample_period_s > 0.0 && sample_period_s <= duration_s,
        "sample_period_s",
        "must be finite, > 0 and ≤ duration_s",
    )?;
    let rows = duration_s / sample_period_s;
    src.check(
        rows <= MAX_TRACE_ROWS,
        "sample_period_s",
        &format!("gives {rows:.3e} trace rows; at most {MAX_TRACE_ROWS:e}"),
    )?;
    Ok(rows)
}

/// The drive a closed-loop file names or embeds.
/// The `[heating]` table on the plant `plant` of the drive `spec`: the rated current and the
/// time constant default to the drive's motor protection's, the no-load current to the rated
/// flux's magnetizing current.
fn heating_of(
    src: &Source<'_>,
    h: &HeatingTable,
    spec: &controller_core::drive::DriveSpec,
    plant: &controller_core::motor::MotorParams,
) -> Result<crate::sim::HeatingRun, FileError> {
    use plant::thermal::{ThermalError, ThermalSpec, Windings};
    let limit = spec.protection.motor_thermal;
    let rated_current_a = h.rated_current_a.or(limit.map(|l| l.rated_current_a)).ok_or_else(|| {
        src.error("heating.rated_current_a", "is needed: the drive's [motor] states no rated_current_a")
    })?;
    let time_constant_s = h.time_constant_s.or(limit.map(|l| l.time_constant_s)).ok_or_else(|| {
        src.error(
            "heating.time_constant_s",
            "is needed: the drive's [motor] states no thermal_time_constant_s",
        )
    })?;
    let thermal = ThermalSpec {
        rated_current_a,
        no_load_current_a: h.no_load_current_a.unwrap_or(spec.flux_ref_wb / (plant.lm_h() * 2f64.sqrt())),
        rated_rise_k: h.rated_rise_k,
        time_constant_s,
        ambient_c: h.ambient_c,
        reference_c: h.reference_c,
    };
    let model = thermal.heating(plant).map_err(|e| {
        let key = match e {
            ThermalError::Nameplate => "heating",
            ThermalError::Temperature => "heating.ambient_c",
        };
        src.error(key, e.to_string())
    })?;
    let windings = match (h.start, h.start_c) {
        (Some(_), Some(_)) => return Err(src.error("heating.start_c", "give start or start_c, not both")),
        (None | Some(HeatingStart::Cold), None) => model.cold(),
        (Some(HeatingStart::Hot), None) => model.rated_hot(),
        (None, Some(t)) => {
            src.check(
                t.is_finite() && t >= h.ambient_c && t < plant::thermal::COPPER_MELTING_C,
                "heating.start_c",
                "must lie between ambient_c and copper's melting point",
            )?;
            Windings { stator_c: t, rotor_c: t }
        }
    };
    Ok(crate::sim::HeatingRun { model, windings })
}

fn drive_of(src: &Source<'_>, f: &ClosedLoopFile) -> Result<DriveFile, FileError> {
    if let Some(reference) = &f.drive {
        let embedded = [
            ("pwm", f.pwm.is_some()),
            ("motor", f.motor.is_some()),
            ("controller", f.controller.is_some()),
            ("protection", f.protection.is_some()),
            ("certify", f.certify.is_some()),
            ("board", f.board.is_some()),
        ];
        if let Some((table, _)) = embedded.iter().find(|(_, given)| *given) {
            return Err(
                src.error(table, format!("`drive = \"{reference}\"` and a [{table}] table: give one"))
            );
        }
        let path = drive_file::relative_to(src.path(), reference);
        return DriveFile::load(&path)
            .map_err(|e| if e.at.is_none() { src.error("drive", e.to_string()) } else { e });
    }
    let missing =
        |t: &str| src.error(t, format!("a closed-loop scenario needs `drive = \"file\"` or a [{t}] table"));
    let tables = drive_file::DriveTables {
        pwm: f.pwm.unwrap_or_default(),
        motor: f.motor.clone().ok_or_else(|| missing("motor"))?,
        controller: f.controller.ok_or_else(|| missing("controller"))?,
        protection: f.protection.ok_or_else(|| missing("protection"))?,
        certify: f.certify,
        board: f.board,
        // A scenario runs the drive; what the user asks of it is judged by the campaign.
        requirements: Default::default(),
    };
    tables.validate(src)
}

/// Parse and validate a closed-loop scenario read from `file`.
pub fn parse_closed_loop(file: &Path, text: &str) -> Result<Builtin, FileError> {
    let src = Source::parse(file, text)?;
    let f: ClosedLoopFile = src.deserialize()?;
    check_timing(&src, f.duration_s, f.sample_period_s)?;
    src.check(f.vdc_v.is_finite() && f.vdc_v > 0.0, "vdc_v", "must be finite and > 0")?;
    let drive = drive_of(&src, &f)?;
    let spec = drive.spec;
    let periods = f.sample_period_s * spec.pwm_frequency_hz;
    src.check(
        periods >= 0.999 && (periods - periods.round()).abs() <= 1e-6 * periods,
        "sample_period_s",
        &format!("must be a whole number of PWM periods (is {periods:.4})"),
    )?;
    src.check((1..=1000).contains(&f.rk4_substeps), "rk4_substeps", "must lie in 1…1000")?;
    // The simulated machine: [plant] when given, else the drive's motor as its file writes
    // it — saturating when its table has a [*.saturation] (the drive then runs on the curve
    // too: `DriveFile::saturating_motor`).
    let (plant, plant_saturation) = match (&f.plant, drive.saturating_motor) {
        (Some(p), _) => p.validate_model(&src, "plant")?,
        (None, Some((m, sat))) => (m, Some(sat)),
        (None, None) => (spec.motor, None),
    };
    let mut events = Vec::with_capacity(f.events.len());
    for (n, e) in f.events.iter().enumerate() {
        let key = |k: &str| format!("events[{n}].{k}");
        src.check(
            e.t_s.is_finite() && e.t_s >= 0.0 && e.t_s <= f.duration_s,
            &key("t_s"),
            "must lie in [0, duration_s]",
        )?;
        // Bounded, so that the drive's f32 references are finite (the narrowing is then exact
        // up to rounding); the plant-side values stay f64.
        let bounded = |name: &str, v: Option<f64>| -> Result<f64, FileError> {
            match v {
                Some(x) if x.is_finite() && x.abs() <= MAX_EVENT_VALUE => Ok(x),
                Some(x) => Err(src
                    .error(&key(name), format!("is {}; must be finite, |x| ≤ {MAX_EVENT_VALUE:e}", num(x)))),
                None => {
                    Err(src.error(&key(name), format!("event `{:?}` needs `{name}`", e.kind).to_lowercase()))
                }
            }
        };
        let ev = match e.kind {
            EventKind::Enable => Event::Enable,
            EventKind::Stop => Event::Stop,
            EventKind::Speed => Event::Reference(Reference::Speed(bounded("value", e.value)? as f32)),
            EventKind::Position => Event::Reference(Reference::Position(bounded("value", e.value)? as f32)),
            EventKind::Torque => Event::Reference(Reference::Torque(bounded("value", e.value)? as f32)),
            // The load is the plant's: f64, as written (it was rounded to f32 before).
            EventKind::Load => Event::LoadNm(bounded("value", e.value)?),
            // Passive loads, coupled from then on (a tripped rotor coasts to rest under them).
            EventKind::Friction | EventKind::Fan | EventKind::Inertia => {
                let value = bounded("value", e.value)?;
                src.check(value >= 0.0, &key("value"), &format!("is {}; a passive load is ≥ 0", num(value)))?;
                Event::Coupling(match e.kind {
                    EventKind::Friction => PassiveLoad::Friction { friction_nm: value },
                    EventKind::Inertia => PassiveLoad::Inertia { j_kgm2: value },
                    _ => {
                        // The fan's torque `value` at speed `omega_rad_s`: k = T/ω².
                        let w = bounded("omega_rad_s", e.omega_rad_s)?;
                        src.check(
                            w.abs() > 0.0,
                            &key("omega_rad_s"),
                            "is 0; the speed at which the fan takes `value` N·m must not be",
                        )?;
                        PassiveLoad::Fan { k_nm_s2: value / (w * w) }
                    }
                })
            }
            EventKind::RotatingCurrent => Event::Reference(Reference::RotatingCurrent {
                amplitude_a: bounded("amplitude_a", e.amplitude_a)? as f32,
                omega_rad_s: bounded("omega_rad_s", e.omega_rad_s)? as f32,
            }),
            EventKind::Fault => Event::Fault({
                let phase_of = || match e.phase.as_deref() {
                    Some("a") => Ok(0),
                    Some("b") => Ok(1),
                    Some("c") => Ok(2),
                    _ => Err(src.error(&key("phase"), "needs phase = \"a\", \"b\" or \"c\"")),
                };
                // A short's loop (a terminal short's, a shorted switch's): R ≥ 0, L > 0.
                let loop_of = || -> Result<(f64, f64), FileError> {
                    let r = bounded("resistance_ohm", e.resistance_ohm)?;
                    let l = bounded("inductance_h", e.inductance_h)?;
                    src.check(r >= 0.0, &key("resistance_ohm"), "must be ≥ 0")?;
                    src.check(l > 0.0, &key("inductance_h"), "must be > 0")?;
                    Ok((r, l))
                };
                match e.fault {
                    None => return Err(src.error(&key("kind"), "a `fault` event needs `fault = \"…\"`")),
                    Some(FaultKind::CurrentSensor) => Injection::CurrentSensor {
                        phase: phase_of()?,
                        gain: bounded("gain", e.gain)?,
                        offset_a: bounded("offset_a", e.offset_a)?,
                    },
                    Some(FaultKind::OpenPhase) => Injection::OpenPhase { phase: phase_of()? },
                    Some(FaultKind::EncoderStuck) => Injection::EncoderStuck,
                    Some(FaultKind::EncoderGlitch) => {
                        let counts = bounded("counts", e.counts.map(|c| c as f64))?;
                        Injection::EncoderGlitch { counts: counts as i64 }
                    }
                    Some(FaultKind::EncoderLines) => match e.lines {
                        Some(lines) if lines >= 1 => Injection::EncoderLines { lines },
                        _ => {
                            return Err(
                                src.error(&key("lines"), "needs lines ≥ 1 (the encoder's actual count)")
                            );
                        }
                    },
                    Some(FaultKind::BusVoltage) => {
                        let v = bounded("vdc_v", e.vdc_v)?;
                        src.check(v > 0.0, &key("vdc_v"), "must be > 0")?;
                        Injection::BusVoltage { vdc_v: v }
                    }
                    Some(kind @ (FaultKind::SwitchOpen | FaultKind::SwitchShort)) => {
                        let phase = phase_of()?;
                        let upper = match e.switch.as_deref() {
                            Some("upper") => true,
                            Some("lower") => false,
                            _ => {
                                return Err(
                                    src.error(&key("switch"), "needs switch = \"upper\" or \"lower\"")
                                );
                            }
                        };
                        if matches!(kind, FaultKind::SwitchOpen) {
                            Injection::SwitchOpen { phase, upper }
                        } else {
                            let (r, l) = loop_of()?;
                            Injection::SwitchShort(crate::bridge_fault::SwitchShort {
                                phase,
                                upper,
                                resistance_ohm: r,
                                inductance_h: l,
                            })
                        }
                    }
                    Some(FaultKind::PhaseShort) => {
                        let phases = match e.phases.as_deref() {
                            Some("ab" | "ba") => [0, 1],
                            Some("bc" | "cb") => [1, 2],
                            Some("ca" | "ac") => [2, 0],
                            _ => {
                                return Err(
                                    src.error(&key("phases"), "needs phases = \"ab\", \"bc\" or \"ca\"")
                                );
                            }
                        };
                        let (r, l) = loop_of()?;
                        Injection::PhaseShort(crate::bridge_fault::PhaseShort {
                            phases,
                            resistance_ohm: r,
                            inductance_h: l,
                        })
                    }
                    Some(FaultKind::Plant) => {
                        let f = |name: &str, v: Option<f64>| -> Result<f64, FileError> {
                            let x = v.unwrap_or(1.0);
                            src.check(
                                x.is_finite() && (0.1..=10.0).contains(&x),
                                &key(name),
                                "must lie in [0.1, 10] (a factor on the plant's value)",
                            )?;
                            Ok(x)
                        };
                        let (rs, rr, lm) = (
                            f("rs_factor", e.rs_factor)?,
                            f("rr_factor", e.rr_factor)?,
                            f("lm_factor", e.lm_factor)?,
                        );
                        match crate::sim::scaled_plant(&plant, rs, rr, lm) {
                            Some(motor) => Injection::Plant { motor },
                            None => return Err(src.error(&key("lm_factor"), "gives an invalid motor")),
                        }
                    }
                    Some(FaultKind::LoadSeizure) => {
                        let torque_nm = bounded("torque_nm", e.torque_nm)?;
                        src.check(torque_nm > 0.0, &key("torque_nm"), "must be > 0")?;
                        Injection::LoadSeizure { torque_nm }
                    }
                }
            }),
        };
        events.push((e.t_s, ev));
    }
    if let Some(n) = events.windows(2).position(|w| w.first().map(|a| a.0) > w.get(1).map(|b| b.0)) {
        return Err(src.error(&format!("events[{}].t_s", n + 1), "events must be in time order"));
    }
    let nonneg = |key: &str, x: f64| src.check(x.is_finite() && x >= 0.0, key, "must be finite and ≥ 0");
    let load = match f.load {
        None | Some(LoadTable::Torque) => LoadModel::Torque,
        Some(LoadTable::EddyBrake { k_nm_s_rad }) => {
            nonneg("load.k_nm_s_rad", k_nm_s_rad)?;
            LoadModel::EddyBrake { k_nm_s_rad }
        }
        Some(LoadTable::LockedRotor) => LoadModel::LockedRotor,
        Some(LoadTable::CoulombFriction { friction_nm }) => {
            nonneg("load.friction_nm", friction_nm)?;
            LoadModel::CoulombFriction { friction_nm }
        }
        Some(LoadTable::Dynamometer { omega_m_rad_s }) => {
            src.check(
                omega_m_rad_s.is_finite() && omega_m_rad_s.abs() <= MAX_DYNAMOMETER_RAD_S,
                "load.omega_m_rad_s",
                &format!("must be finite, |ω| ≤ {MAX_DYNAMOMETER_RAD_S}"),
            )?;
            LoadModel::Dynamometer { omega_m_rad_s }
        }
    };
    let s = &f.sensors;
    nonneg("sensors.current_lsb_a", s.current_lsb_a)?;
    nonneg("sensors.current_noise_rms_a", s.current_noise_rms_a)?;
    nonneg("sensors.vdc_lsb_v", s.vdc_lsb_v)?;
    for x in s.current_offset_a {
        src.check(x.is_finite(), "sensors.current_offset_a", "must be finite")?;
    }
    for x in s.current_gain {
        src.check(x.is_finite(), "sensors.current_gain", "must be finite")?;
    }
    src.check(s.encoder_lines != Some(0), "sensors.encoder_lines", "must be ≥ 1")?;
    let sensors = SensorModel {
        current_lsb_a: s.current_lsb_a,
        current_offset_a: s.current_offset_a,
        current_gain: s.current_gain,
        current_noise_rms_a: s.current_noise_rms_a,
        vdc_lsb_v: s.vdc_lsb_v,
        encoder_lines: s.encoder_lines,
        low_side_window_s: None,
        seed: s.seed,
    };
    let inverter = match f.inverter {
        None | Some(InverterTable::Average) => InverterModel::Average,
        Some(InverterTable::Switching { dead_time_s }) => {
            src.check(
                dead_time_s.is_finite() && dead_time_s >= 0.0 && dead_time_s < 0.5 / spec.pwm_frequency_hz,
                "inverter.dead_time_s",
                "must be finite, ≥ 0 and below half the PWM period",
            )?;
            InverterModel::Switching { dead_time_s }
        }
    };
    let dc_link = match &f.dc_link {
        None => None,
        Some(l) => {
            let positive =
                |key: &str, x: f64| src.check(x.is_finite() && x > 0.0, key, "must be finite and > 0");
            positive("dc_link.capacitance_f", l.capacitance_f)?;
            positive("dc_link.resistance_ohm", l.resistance_ohm)?;
            // The inverter model averages over a PWM period on a bus that holds: at the trip
            // current for one period the capacitor must not swing by the whole bus (a 1 pF
            // link read 1.3·10¹⁰ V: found by trying).
            let least_f = spec.protection.i_trip_a / (spec.pwm_frequency_hz * f.vdc_v);
            src.check(
                l.capacitance_f >= least_f,
                "dc_link.capacitance_f",
                &format!(
                    "is {:e} F: below {least_f:.3e} F, which the trip current (protection.i_trip_a = {} A) \
                     would swing by the whole {} V bus within one PWM period",
                    l.capacitance_f, spec.protection.i_trip_a, f.vdc_v
                ),
            )?;
            let chopper = match &l.chopper {
                None => None,
                Some(c) => {
                    positive("dc_link.chopper.resistance_ohm", c.resistance_ohm)?;
                    src.check(
                        spec.protection.brake_chopper.is_some(),
                        "dc_link.chopper",
                        "the drive has no [protection] brake_chopper to switch this resistor",
                    )?;
                    Some(crate::sim::Chopper { resistance_ohm: c.resistance_ohm })
                }
            };
            Some(crate::sim::DcLink {
                capacitance_f: l.capacitance_f,
                source: match l.source {
                    LinkSourceTable::Supply => crate::sim::DcSource::Supply,
                    LinkSourceTable::Rectifier => crate::sim::DcSource::Rectifier,
                },
                resistance_ohm: l.resistance_ohm,
                chopper,
            })
        }
    };
    let comparator = match f.comparator {
        None => None,
        Some(c) => {
            src.check(c.trip_a.is_finite() && c.trip_a > 0.0, "comparator.trip_a", "must be finite and > 0")?;
            src.check(
                c.filter_s.is_finite() && c.filter_s > 0.0 && c.filter_s * spec.pwm_frequency_hz <= 0.1,
                "comparator.filter_s",
                "must be > 0 and at most a tenth of the PWM period",
            )?;
            Some(crate::bridge_fault::Comparator { trip_a: c.trip_a, filter_s: c.filter_s })
        }
    };
    // Iron loss and a deep bar: a saturating machine in the inverse-Γ form, a linear one in
    // its inverse-Γ equivalent.
    let iron_loss_ohm = match &f.iron_loss {
        None => None,
        Some(t) => {
            let r = t.resistance_ohm;
            src.check(r.is_finite() && r > 0.0, "iron_loss.resistance_ohm", "must be finite and > 0")?;
            Some(r)
        }
    };
    let deep_bar = match &f.deep_bar {
        None => None,
        Some(t) => {
            let k = t.high_slip_resistance_factor;
            src.check(
                k.is_finite() && k > 1.0,
                "deep_bar.high_slip_resistance_factor",
                "must be finite and > 1",
            )?;
            let hz = t.corner_slip_hz;
            src.check(hz.is_finite() && hz > 0.0, "deep_bar.corner_slip_hz", "must be finite and > 0")?;
            Some(plant::DeepBar { high_slip_resistance_factor: k, corner_slip_hz: hz })
        }
    };
    // The motor's own [*.iron_loss] / [*.deep_bar] ([plant], the embedded [motor] or the
    // drive file's), each unless the scenario's table says otherwise.
    let written = match (&f.plant, &f.motor, &f.drive) {
        (Some(p), _, _) => p.plant_extras(&src, "plant")?,
        (None, Some(m), _) => m.plant_extras(&src, "motor")?,
        (None, None, Some(d)) => {
            let path = drive_file::relative_to(src.path(), d);
            drive_file::motor::load_plant_extras(&path.to_string_lossy())
                .map_err(|e| if e.at.is_none() { src.error("drive", e.to_string()) } else { e })?
        }
        (None, None, None) => drive_file::motor::PlantExtras::default(),
    };
    let written = crate::scenario::extras_of(&written);
    let extras = plant::Extras {
        iron_loss_ohm: iron_loss_ohm.or(written.iron_loss_ohm),
        deep_bar: deep_bar.or(written.deep_bar),
    };
    // The machine the run builds, built now: a form that cannot take them is named here.
    crate::scenario::plant_machine(&plant, plant_saturation.as_ref(), &extras).map_err(|e| {
        let key = match (f.iron_loss.is_some(), f.deep_bar.is_some(), f.plant.is_some()) {
            (true, _, _) => "iron_loss",
            (false, true, _) => "deep_bar",
            (false, false, true) => "plant",
            (false, false, false) if f.motor.is_some() => "motor",
            (false, false, false) => "drive",
        };
        src.error(key, format!("{e} (form = \"inverse_gamma\")"))
    })?;
    let heating = match &f.heating {
        None => None,
        Some(h) => Some(heating_of(&src, h, &spec, &plant)?),
    };
    let stem = file.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let expect_fault = match f.expect_fault.as_deref() {
        None => None,
        Some(name) => Some(Fault::ALL.into_iter().find(|x| format!("{x:?}") == name).ok_or_else(|| {
            let names: Vec<String> = Fault::ALL.iter().map(|x| format!("{x:?}")).collect();
            src.error("expect_fault", format!("is \"{name}\"; a fault is one of {}", names.join(", ")))
        })?),
    };
    Ok(Builtin {
        name: stem,
        about: format!("closed-loop scenario file {}", file.display()),
        spec,
        plant,
        plant_saturation,
        expect_fault,
        scenario: Scenario {
            events,
            duration_s: f.duration_s,
            vdc_v: f.vdc_v,
            substeps: f.rk4_substeps,
            trace_every: periods.round() as u32,
            sensors,
            load,
            inverter,
            dc_link,
            comparator,
            heating,
            extras,
        },
    })
}

/// Parse and validate an open-loop scenario read from `file`.
pub fn parse_open_loop(file: &Path, text: &str) -> Result<OpenLoop, FileError> {
    let src = Source::parse(file, text)?;
    let raw: OpenLoopFile = src.deserialize()?;
    check_timing(&src, raw.duration_s, raw.sample_period_s)?;
    let (motor, saturation) = match (&raw.motor, &raw.drive) {
        (Some(m), None) => m.validate_model(&src, "motor")?,
        (None, Some(d)) => {
            drive_file::motor::load_model(&drive_file::relative_to(file, d).to_string_lossy())?
        }
        (Some(_), Some(_)) => return Err(src.error("motor", "`drive = …` and a [motor] table: give one")),
        (None, None) => return Err(src.error("motor", "needs a [motor] table or `drive = \"file\"`")),
    };
    let SourceTable::Sine { amplitude_v, frequency_hz } = raw.source;
    src.check(
        amplitude_v.is_finite() && (0.0..=1e6).contains(&amplitude_v),
        "source.amplitude_v",
        "must lie in [0, 1e6] V",
    )?;
    src.check(
        frequency_hz.is_finite() && frequency_hz.abs() <= 1e5,
        "source.frequency_hz",
        "must be finite, |f| ≤ 1e5 Hz",
    )?;
    let load_nm = match raw.load {
        Some(ConstantLoad::Constant { torque_nm }) => {
            src.check(torque_nm.is_finite(), "load.torque_nm", "must be finite")?;
            torque_nm
        }
        None => 0.0,
    };
    Ok(OpenLoop {
        duration_s: raw.duration_s,
        sample_period_s: raw.sample_period_s,
        motor,
        saturation,
        amplitude_v,
        frequency_hz,
        load_nm,
    })
}

/// Read, parse and validate a scenario file of either kind.
pub fn load(file: &Path) -> Result<ScenarioFileKind, FileError> {
    let text = drive_file::source::read(file)?;
    let src = Source::parse(file, &text)?;
    // A drive file given for a scenario: said as such (it read "missing field `duration_s`",
    // found by trying).
    if !src.has("duration_s") && (src.has("certify") || src.has("board") || src.has("protection")) {
        return Err(FileError::file(
            file,
            "this is a drive file: `hil-sim run` takes a scenario file — `drive = \"path/to/drive.toml\"`, \
             duration_s, sample_period_s, vdc_v and [[events]] (e.g. hil-sim/scenarios/fig16-icad.toml) — or a \
             built-in scenario's name (hil-sim list)",
        ));
    }
    if src.has("controller") || (src.has("drive") && !src.has("source")) {
        parse_closed_loop(file, &text).map(|b| ScenarioFileKind::ClosedLoop(Box::new(b)))
    } else {
        parse_open_loop(file, &text).map(|o| ScenarioFileKind::OpenLoop(Box::new(o)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const FIG16: &str = include_str!("../scenarios/fig16-icad.toml");
    const OPEN: &str = r#"
duration_s = 0.5
sample_period_s = 1e-3
[motor]
rs_ohm = 16.2
rr_ohm = 23.2
ls_h = 1.44
lr_h = 1.5
lm_h = 1.42
pole_pairs = 1
j_kgm2 = 0.005
b_nms = 0.0005
[source]
kind = "sine"
amplitude_v = 180.0
frequency_hz = 50.0
[load]
kind = "constant"
torque_nm = 0.5
"#;

    fn err(text: &str) -> FileError {
        parse_closed_loop(Path::new("c.toml"), text).unwrap_err()
    }
    fn open_err(text: &str) -> FileError {
        parse_open_loop(Path::new("s.toml"), text).unwrap_err()
    }
    fn replace(text: &str, from: &str, to: &str) -> String {
        assert!(text.contains(from), "{from}");
        text.replacen(from, to, 1)
    }

    #[test]
    fn shipped_file_equals_builtin() {
        let f = parse_closed_loop(Path::new("fig16-icad.toml"), FIG16).unwrap();
        let b = crate::scenario::fig16_icad().unwrap();
        assert_eq!(f.spec, b.spec);
        assert_eq!(f.plant, b.plant);
        assert_eq!(f.scenario, b.scenario);
    }

    #[test]
    fn a_scenario_may_name_its_drive_file() {
        let dir = std::env::temp_dir().join(format!("hil-sim-drive-ref-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("sub")).unwrap();
        std::fs::write(dir.join("drive.toml"), drive_file::SHIPPED).unwrap();
        let run = "drive = \"../drive.toml\"\nduration_s = 1.0\nsample_period_s = 1e-3\nvdc_v = 310.0\n\
                   [[events]]\nt_s = 0.0\nkind = \"enable\"\n";
        let path = dir.join("sub/s.toml");
        std::fs::write(&path, run).unwrap();
        let ScenarioFileKind::ClosedLoop(b) = load(&path).unwrap() else { panic!("closed loop") };
        assert_eq!(b.spec, DriveFile::shipped().unwrap().spec);
        // Both a reference and a table: refused, pointing at the table.
        let e = parse_closed_loop(
            &path,
            &format!("{run}[protection]\ni_trip_a = 8.0\nvdc_min_v = 1.0\nvdc_max_v = 2.0\n"),
        )
        .unwrap_err();
        assert_eq!(e.key.as_deref(), Some("protection"), "{e}");
        // A missing drive file is named.
        let e = parse_closed_loop(&path, &run.replace("../drive.toml", "../nope.toml")).unwrap_err();
        assert!(e.to_string().contains("nope.toml") && e.key.as_deref() == Some("drive"), "{e}");
        // The open-loop runner takes the drive's motor.
        let open = OPEN.replace("[motor]", "drive = \"../drive.toml\"\n[unused]");
        let open = open.replace("[unused]\nrs_ohm = 16.2\nrr_ohm = 23.2\nls_h = 1.44\nlr_h = 1.5\nlm_h = 1.42\npole_pairs = 1\nj_kgm2 = 0.005\nb_nms = 0.0005\n", "");
        let o = parse_open_loop(&path, &open).unwrap();
        assert_eq!(o.motor, DriveFile::shipped().unwrap().spec.motor);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// Issue 50: `[heating]` — the windings start cold, hot or at a temperature; a motor
    /// without a rated current needs one stated; a bad nameplate or start is named.
    #[test]
    fn heating_windings_are_read_and_checked() {
        let heated =
            |table: &str| parse_closed_loop(Path::new("h.toml"), &format!("{FIG16}\n[heating]\n{table}"));
        let base = "rated_rise_k = 80.0\nambient_c = 40.0\nreference_c = 20.0\nrated_current_a = 0.88\ntime_constant_s = 900.0\n";
        let run = heated(base).unwrap().scenario.heating.unwrap();
        assert_eq!(run.windings, run.model.cold());
        assert_eq!(run.windings.stator_c, 40.0);
        let hot = heated(&format!("{base}start = \"hot\"\n")).unwrap().scenario.heating.unwrap();
        assert_eq!(hot.windings.rotor_c, 120.0);
        let at = heated(&format!("{base}start_c = 90.0\n")).unwrap().scenario.heating.unwrap();
        assert_eq!(at.windings.stator_c, 90.0);
        let key = |table: &str| heated(table).unwrap_err().key;
        assert_eq!(
            key("rated_rise_k = 80.0\nambient_c = 40.0\nreference_c = 20.0\n").as_deref(),
            Some("heating.rated_current_a")
        );
        assert_eq!(key(&base.replace("80.0", "-1.0")).as_deref(), Some("heating"));
        assert_eq!(key(&format!("{base}start_c = 10.0\n")).as_deref(), Some("heating.start_c"));
        assert_eq!(key(&format!("{base}start_c = 1e300\n")).as_deref(), Some("heating.start_c"));
        assert_eq!(key(&base.replace("80.0", "1e300")).as_deref(), Some("heating.ambient_c"));
        assert_eq!(
            key(&format!("{base}start = \"hot\"\nstart_c = 90.0\n")).as_deref(),
            Some("heating.start_c")
        );
        assert_eq!(
            key(&base.replace("ambient_c = 40.0", "ambient_c = -400.0")).as_deref(),
            Some("heating.ambient_c")
        );
    }

    /// Issue 50: `[iron_loss]` on a machine in the inverse-Γ form (motulator's 2.2 kW drive,
    /// its motor file's form) is read and runs: the drive magnetizes and holds its speed. A
    /// linear T-form machine (FIG16's) takes it and `[deep_bar]` in its inverse-Γ
    /// equivalent; a saturating Γ-form one (delorenzo-saturating's) is refused naming the
    /// table; a value that is not one is refused naming its key. A `[plant]`'s own
    /// `[plant.deep_bar]` is the run's unless the scenario's `[deep_bar]` says otherwise.
    #[test]
    fn iron_loss_and_a_deep_bar_need_the_inverse_gamma_form() {
        let drive = Path::new(env!("CARGO_MANIFEST_DIR")).join("../drives/motulator-2kw.toml");
        let text = format!(
            "drive = {:?}\nduration_s = 1.0\nsample_period_s = 1e-3\nvdc_v = 540.0\n[iron_loss]\nresistance_ohm = 1000.0\n\
             [[events]]\nt_s = 0.0\nkind = \"enable\"\n[[events]]\nt_s = 0.2\nkind = \"speed\"\nvalue = 100.0\n",
            drive.display().to_string()
        );
        let b = parse_closed_loop(Path::new("iron.toml"), &text).unwrap();
        assert_eq!(b.scenario.extras.iron_loss_ohm, Some(1000.0));
        let (rows, mode) = b.run(|_| {}).unwrap();
        assert_eq!(mode, controller_core::drive::Mode::Running);
        let end = rows.last().unwrap();
        assert!((end.x.omega_m_rad_s - 100.0).abs() < 5.0, "{}", end.x.omega_m_rad_s);
        let bad = replace(&text, "resistance_ohm = 1000.0", "resistance_ohm = -1.0");
        assert_eq!(err(&bad).key.as_deref(), Some("iron_loss.resistance_ohm"));
        let bar = "[deep_bar]\nhigh_slip_resistance_factor = 2.0\ncorner_slip_hz = 60.0\n";
        let t_form = format!("{FIG16}\n[iron_loss]\nresistance_ohm = 1000.0\n{bar}");
        let extras = parse_closed_loop(Path::new("t.toml"), &t_form).unwrap().scenario.extras;
        let want = plant::DeepBar { high_slip_resistance_factor: 2.0, corner_slip_hz: 60.0 };
        assert_eq!((extras.iron_loss_ohm, extras.deep_bar), (Some(1000.0), Some(want)));
        let gamma = Path::new(env!("CARGO_MANIFEST_DIR")).join("../drives/delorenzo-saturating.toml");
        let gamma = text.replace(
            &format!("{:?}", drive.display().to_string()),
            &format!("{:?}", gamma.display().to_string()),
        );
        assert_eq!(err(&gamma).key.as_deref(), Some("iron_loss"));
        let gamma_bar = gamma.replace("[iron_loss]\nresistance_ohm = 1000.0\n", bar);
        assert_eq!(err(&gamma_bar).key.as_deref(), Some("deep_bar"));
        // The [plant]'s own deep bar, unless the scenario's [deep_bar] says otherwise.
        let plant = "[plant]\nrs_ohm = 16.2\nrr_ohm = 23.2\nls_h = 1.44\nlr_h = 1.5\nlm_h = 1.42\npole_pairs = 1\n\
                     j_kgm2 = 0.005\nb_nms = 0.0005\n[plant.deep_bar]\nhigh_slip_resistance_factor = 3.0\n\
                     corner_slip_hz = 60.0\n";
        let own = parse_closed_loop(Path::new("p.toml"), &format!("{FIG16}\n{plant}")).unwrap();
        let three = plant::DeepBar { high_slip_resistance_factor: 3.0, corner_slip_hz: 60.0 };
        assert_eq!(own.scenario.extras.deep_bar, Some(three));
        let told = parse_closed_loop(Path::new("p.toml"), &format!("{FIG16}\n{plant}{bar}")).unwrap();
        assert_eq!(told.scenario.extras.deep_bar, Some(want));
        for (from, to, key) in [
            ("= 2.0", "= 1.0", "deep_bar.high_slip_resistance_factor"),
            ("= 2.0", "= nan", "deep_bar.high_slip_resistance_factor"),
            ("= 60.0", "= 0.0", "deep_bar.corner_slip_hz"),
        ] {
            let bad = format!("{FIG16}\n{}", bar.replace(from, to));
            assert_eq!(err(&bad).key.as_deref(), Some(key), "{to}");
        }
        // A corner so low that the second cage alone leaks more than the motor does.
        let low = err(&format!("{FIG16}\n{}", bar.replace("= 60.0", "= 10.0")));
        assert_eq!(low.key.as_deref(), Some("deep_bar"), "{low}");
        assert!(low.to_string().contains("leaks more at zero slip"), "{low}");
    }

    /// Issue 16, item 2: the inputs found by trying are errors that point at the value.
    #[test]
    fn bad_values_are_located_errors() {
        // Durations past the stated maximum (1e300 panicked, 1e9 aborted on allocation).
        for d in ["1e300", "1e9", "inf", "-1.0"] {
            let e = err(&replace(FIG16, "duration_s = 6.5", &format!("duration_s = {d}")));
            assert_eq!((e.key.as_deref(), e.at), (Some("duration_s"), Some((4, 14))), "{e}");
            let e = open_err(&replace(OPEN, "duration_s = 0.5", &format!("duration_s = {d}")));
            assert_eq!(e.key.as_deref(), Some("duration_s"), "{e}");
        }
        // Too many trace rows.
        let e = err(&replace(FIG16, "duration_s = 6.5", "duration_s = 3600.0")
            .replace("sample_period_s = 1e-3", "sample_period_s = 5e-5"));
        assert!(e.key.as_deref() == Some("sample_period_s") && e.reason.contains("rows"), "{e}");
        // An event value beyond f32 (was silently dropped as +∞).
        let e = err(&replace(FIG16, "value = 376.0", "value = 1e300"));
        assert_eq!(e.key.as_deref(), Some("events[1].value"), "{e}");
        assert!(e.at.is_some_and(|(l, _)| l > 30), "{e}");
        // A 4-element offset (its last element was lost).
        let e = err(&format!("{FIG16}\n[sensors]\ncurrent_offset_a = [0.0, 0.0, 0.0, 0.1]\n"));
        assert!(
            e.key.as_deref() == Some("sensors.current_offset_a") && e.reason.contains("exactly 3"),
            "{e}"
        );
        let e = err(&replace(FIG16, "tau_max_nm = 0.4", "tau_max_nm = -0.4"));
        assert_eq!(e.key.as_deref(), Some("controller.speed"), "{e}");
        let e = err(&replace(FIG16, "t_s = 0.3", "t_s = -1.0"));
        assert_eq!(e.key.as_deref(), Some("events[1].t_s"), "{e}");
        let e = err(&replace(FIG16, "kind = \"speed\"\nvalue = 376.0", "kind = \"speed\""));
        assert_eq!(e.key.as_deref(), Some("events[1].value"), "{e}");
        let e = err(&replace(FIG16, "sample_period_s = 1e-3", "sample_period_s = 1.23e-4"));
        assert_eq!(e.key.as_deref(), Some("sample_period_s"), "{e}");
        let e = err(&replace(FIG16, "flux_ref_wb = 0.35", "flux_ref_wb = 0.35\nflux_gain = 2"));
        assert!(e.to_string().starts_with("c.toml:") && e.to_string().contains("flux_gain"), "{e}");
        let e = err(&replace(FIG16, "i_trip_a = 8.0", "i_trip_a = 3.0"));
        assert_eq!(e.key.as_deref(), Some("protection.i_trip_a"), "{e}");
        let e = open_err(&replace(OPEN, "torque_nm = 0.5", "torque_nm = nan"));
        assert_eq!(e.key.as_deref(), Some("load.torque_nm"), "{e}");
        let e = open_err(&replace(OPEN, "rr_ohm = 23.2", "rr_ohm = -1.0"));
        assert_eq!(e.key.as_deref(), Some("motor.rr_ohm"), "{e}");
        let e = open_err(&replace(OPEN, "kind = \"sine\"", "kind = \"square\""));
        assert!(e.to_string().contains("square"), "{e}");
    }

    #[test]
    fn fault_events() {
        let with = |ev: &str| format!("{FIG16}\n[[events]]\nt_s = 1.0\nkind = \"fault\"\n{ev}\n");
        let f = parse_closed_loop(
            Path::new("c.toml"),
            &with("fault = \"current_sensor\"\nphase = \"c\"\ngain = 0.0\noffset_a = 0.2"),
        )
        .unwrap();
        assert_eq!(
            f.scenario.events.last(),
            Some(&(1.0, Event::Fault(Injection::CurrentSensor { phase: 2, gain: 0.0, offset_a: 0.2 })))
        );
        let f =
            parse_closed_loop(Path::new("c.toml"), &with("fault = \"bus_voltage\"\nvdc_v = 150.0")).unwrap();
        assert_eq!(
            f.scenario.events.last(),
            Some(&(1.0, Event::Fault(Injection::BusVoltage { vdc_v: 150.0 })))
        );
        let e = err(&with("fault = \"current_sensor\"\ngain = 0.0\noffset_a = 0.0"));
        assert_eq!(e.key.as_deref(), Some("events[2].phase"), "{e}");
        let e = err(&with("fault = \"bus_voltage\""));
        assert_eq!(e.key.as_deref(), Some("events[2].vdc_v"), "{e}");
        let e = err(&with("fault = \"meteor\""));
        assert!(e.reason.contains("meteor"), "{e}");
        let last =
            |ev: &str| parse_closed_loop(Path::new("c.toml"), &with(ev)).unwrap().scenario.events.pop();
        assert_eq!(
            last("fault = \"encoder_glitch\"\ncounts = -40"),
            Some((1.0, Event::Fault(Injection::EncoderGlitch { counts: -40 })))
        );
        assert_eq!(
            last("fault = \"encoder_lines\"\nlines = 512"),
            Some((1.0, Event::Fault(Injection::EncoderLines { lines: 512 })))
        );
        assert_eq!(
            last("fault = \"load_seizure\"\ntorque_nm = 20.0"),
            Some((1.0, Event::Fault(Injection::LoadSeizure { torque_nm: 20.0 })))
        );
        match last("fault = \"plant\"\nrr_factor = 1.5\nlm_factor = 0.8") {
            Some((1.0, Event::Fault(Injection::Plant { motor }))) => {
                assert!((motor.rr_ohm() - 1.5 * 23.2).abs() < 1e-12);
                assert!((motor.lm_h() - 0.8 * 1.42).abs() < 1e-12);
                // The leakage stays: L_s − L_m as before.
                assert!((motor.ls_h() - motor.lm_h() - (1.44 - 1.42)).abs() < 1e-12);
                assert_eq!(motor.rs_ohm(), 16.2);
            }
            other => panic!("{other:?}"),
        }
        assert_eq!(
            last("fault = \"phase_short\"\nphases = \"bc\"\nresistance_ohm = 0.1\ninductance_h = 1e-5"),
            Some((
                1.0,
                Event::Fault(Injection::PhaseShort(crate::bridge_fault::PhaseShort {
                    phases: [1, 2],
                    resistance_ohm: 0.1,
                    inductance_h: 1e-5
                }))
            ))
        );
        let with_comparator = |c: &str| format!("{FIG16}\n[comparator]\n{c}\n");
        let f = parse_closed_loop(Path::new("c.toml"), &with_comparator("trip_a = 12.0\nfilter_s = 1e-6"))
            .unwrap();
        assert_eq!(
            f.scenario.comparator,
            Some(crate::bridge_fault::Comparator { trip_a: 12.0, filter_s: 1e-6 })
        );
        let e = err(&with_comparator("trip_a = 12.0\nfilter_s = 1e-3"));
        assert_eq!(e.key.as_deref(), Some("comparator.filter_s"), "{e}");
        assert_eq!(
            last("fault = \"switch_open\"\nphase = \"c\"\nswitch = \"lower\""),
            Some((1.0, Event::Fault(Injection::SwitchOpen { phase: 2, upper: false })))
        );
        assert_eq!(
            last(
                "fault = \"switch_short\"\nphase = \"b\"\nswitch = \"upper\"\nresistance_ohm = 0.05\ninductance_h = 1e-7"
            ),
            Some((
                1.0,
                Event::Fault(Injection::SwitchShort(crate::bridge_fault::SwitchShort {
                    phase: 1,
                    upper: true,
                    resistance_ohm: 0.05,
                    inductance_h: 1e-7
                }))
            ))
        );
        for (ev, k) in [
            ("fault = \"switch_short\"\nphase = \"a\"\nswitch = \"lower\"", "resistance_ohm"),
            (
                "fault = \"switch_short\"\nphase = \"a\"\nswitch = \"lower\"\nresistance_ohm = 0.1\ninductance_h = -1.0",
                "inductance_h",
            ),
            ("fault = \"switch_open\"\nphase = \"a\"\nswitch = \"middle\"", "switch"),
            ("fault = \"phase_short\"\nphases = \"aa\"", "phases"),
            (
                "fault = \"phase_short\"\nphases = \"ab\"\nresistance_ohm = 0.1\ninductance_h = 0.0",
                "inductance_h",
            ),
            ("fault = \"plant\"\nrs_factor = 0.0", "rs_factor"),
            ("fault = \"plant\"\nlm_factor = nan", "lm_factor"),
            ("fault = \"encoder_glitch\"", "counts"),
            ("fault = \"encoder_lines\"\nlines = 0", "lines"),
            ("fault = \"load_seizure\"", "torque_nm"),
            ("fault = \"load_seizure\"\ntorque_nm = -1.0", "torque_nm"),
        ] {
            let e = err(&with(ev));
            assert_eq!(e.key.as_deref(), Some(format!("events[2].{k}").as_str()), "{e}");
        }
    }

    /// Issue 49: a passive load — here a fan taking 0.2 N·m at 100 rad/s — lets a tripped
    /// rotor coast down (its speed falls, never reverses), where an active load of the same
    /// torque drives it backwards; a coupled inertia slows the coast-down. A negative
    /// passive load and a fan without its speed are refused by key.
    #[test]
    fn a_passive_load_lets_a_tripped_rotor_coast_to_rest() {
        let run = |load: &str| {
            let text = format!(
                "drive = \"../../drive.toml\"\nduration_s = 3.0\nsample_period_s = 1e-3\nvdc_v = 310.0\n\
                 [[events]]\nt_s = 0.0\nkind = \"enable\"\n\
                 [[events]]\nt_s = 0.3\nkind = \"speed\"\nvalue = 100.0\n\
                 {load}\n\
                 [[events]]\nt_s = 0.8\nkind = \"fault\"\nfault = \"bus_voltage\"\nvdc_v = 100.0\n"
            );
            let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/passive.toml");
            let b = parse_closed_loop(&path, &text).unwrap();
            let mut rows = Vec::new();
            let mode = b
                .run_into(
                    |_| {},
                    |r| {
                        rows.push((r.t_s, r.x.omega_m_rad_s));
                        Ok(())
                    },
                )
                .unwrap();
            assert_eq!(
                mode,
                controller_core::drive::Mode::Fault(controller_core::fault::Fault::DcBusUndervoltage)
            );
            rows
        };
        let after =
            |rows: &[(f64, f64)]| rows.iter().filter(|(t, _)| *t >= 0.8).map(|&(_, w)| w).collect::<Vec<_>>();
        let fan = "[[events]]\nt_s = 0.5\nkind = \"fan\"\nvalue = 0.2\nomega_rad_s = 100.0";
        let coasting = after(&run(fan));
        let first = coasting.first().copied().unwrap();
        assert!(first > 80.0, "at speed when it trips: {first}");
        assert!(coasting.windows(2).all(|w| w[1] <= w[0] + 1e-9), "a coast-down only falls");
        let last = coasting.last().copied().unwrap();
        assert!(last > 0.0 && last < 0.8 * first, "{first} → {last} rad/s");
        // The same torque as an active load drives the tripped rotor backwards.
        let active = after(&run("[[events]]\nt_s = 0.5\nkind = \"load\"\nvalue = 0.2"));
        assert!(active.last().copied().unwrap() < 0.0, "{:?}", active.last());
        // More inertia on the shaft: the same fan slows it less in the same time.
        let heavy = after(&run(&format!("{fan}\n[[events]]\nt_s = 0.5\nkind = \"inertia\"\nvalue = 0.01")));
        assert!(heavy.last().copied().unwrap() > last, "{heavy:?}");
        let e = err(&format!("{FIG16}\n[[events]]\nt_s = 0.5\nkind = \"friction\"\nvalue = -1.0\n"));
        assert_eq!(e.key.as_deref(), Some("events[2].value"), "{e}");
        let e = err(&format!("{FIG16}\n[[events]]\nt_s = 0.5\nkind = \"fan\"\nvalue = 1.0\n"));
        assert_eq!(e.key.as_deref(), Some("events[2].omega_rad_s"), "{e}");
    }

    /// `expect_fault` names a fault by its name; an unknown one is refused by key, listing
    /// the names.
    #[test]
    fn a_scenario_may_expect_a_fault_by_name() {
        let f = parse_closed_loop(Path::new("c.toml"), &format!("expect_fault = \"Overspeed\"\n{FIG16}"))
            .unwrap();
        assert_eq!(f.expect_fault, Some(Fault::Overspeed));
        assert_eq!(parse_closed_loop(Path::new("c.toml"), FIG16).unwrap().expect_fault, None);
        let e = err(&format!("expect_fault = \"overspeed\"\n{FIG16}"));
        assert_eq!(e.key.as_deref(), Some("expect_fault"));
        assert!(e.to_string().contains("Overspeed") && e.to_string().contains("SwitchOpen"), "{e}");
    }

    #[test]
    fn coulomb_friction_load() {
        let with = |load: &str| format!("{FIG16}\n[load]\n{load}\n");
        let f =
            parse_closed_loop(Path::new("c.toml"), &with("kind = \"coulomb_friction\"\nfriction_nm = 0.05"))
                .unwrap();
        assert_eq!(f.scenario.load, LoadModel::CoulombFriction { friction_nm: 0.05 });
        let e = err(&with("kind = \"coulomb_friction\"\nfriction_nm = -0.05"));
        assert_eq!(e.key.as_deref(), Some("load.friction_nm"));
        let e = err(&with("kind = \"coulomb_friction\""));
        assert!(e.to_string().contains("friction_nm"), "{e}");
    }

    #[test]
    fn dc_link_and_dynamometer() {
        let with = |table: &str| format!("{FIG16}\n{table}\n");
        let link = "[dc_link]\ncapacitance_f = 470e-6\nsource = \"rectifier\"\nresistance_ohm = 0.5\n";
        let chopper = format!("{link}chopper = {{ resistance_ohm = 100.0 }}");
        // The resistor needs a drive that switches it.
        let thresholds = "brake_chopper = { on_v = 360.0, off_v = 350.0 }";
        let no_brake = replace(FIG16, thresholds, "");
        let e = err(&format!("{no_brake}\n{chopper}\n"));
        assert_eq!(e.key.as_deref(), Some("dc_link.chopper"), "{e}");
        assert!(e.to_string().contains("brake_chopper"), "{e}");
        let f = parse_closed_loop(Path::new("c.toml"), &with(&chopper)).unwrap();
        let l = f.scenario.dc_link.unwrap();
        assert_eq!(
            (l.capacitance_f, l.source, l.resistance_ohm),
            (470e-6, crate::sim::DcSource::Rectifier, 0.5)
        );
        assert_eq!(l.chopper.unwrap().resistance_ohm, 100.0);
        let b = f.spec.protection.brake_chopper.unwrap();
        assert_eq!((b.on_v, b.off_v), (360.0, 350.0));
        let e = err(&with(&link.replace("470e-6", "0.0")));
        assert_eq!(e.key.as_deref(), Some("dc_link.capacitance_f"), "{e}");
        // A link the trip current would swing by the whole bus within a period (a 1 pF link
        // read 1.3·10¹⁰ V: found by trying): 8 A · 50 µs / 310 V = 1.29 µF at least.
        let e = err(&with(&link.replace("470e-6", "1e-12")));
        assert!(e.to_string().contains("below 1.290e-6 F"), "{e}");
        assert!(parse_closed_loop(Path::new("c.toml"), &with(&link.replace("470e-6", "1.3e-6"))).is_ok());
        // Thresholds the wrong way round, or above the over-voltage trip, point at the drive's key.
        for bad in ["{ on_v = 350.0, off_v = 360.0 }", "{ on_v = 450.0, off_v = 360.0 }"] {
            let e = err(&replace(FIG16, thresholds, &format!("brake_chopper = {bad}")));
            assert_eq!(e.key.as_deref(), Some("protection.brake_chopper"), "{e}");
        }
        let e = err(&with(&link.replace("rectifier", "battery")));
        assert!(e.to_string().contains("source"), "{e}");
        let f = parse_closed_loop(
            Path::new("c.toml"),
            &with("[load]\nkind = \"dynamometer\"\nomega_m_rad_s = -300.0"),
        )
        .unwrap();
        assert_eq!(f.scenario.load, LoadModel::Dynamometer { omega_m_rad_s: -300.0 });
        let e = err(&with("[load]\nkind = \"dynamometer\"\nomega_m_rad_s = 1e9"));
        assert_eq!(e.key.as_deref(), Some("load.omega_m_rad_s"), "{e}");
    }

    #[test]
    fn open_loop_file_parses() {
        let s = parse_open_loop(Path::new("s.toml"), OPEN).unwrap();
        assert_eq!(s.load_nm, 0.5);
        assert_eq!(s.motor.pole_pairs(), 1);
    }

    /// The shipped saturating scenario file is motulator's machine: run open loop, its
    /// trace matches motulator's own simulation (the plant's reference file, written by
    /// `tools/motulator_dol.py --write`) to 1e-8 of each signal's peak — rounding and RK4's
    /// 10 µs step — where the saturation issue asks 0.5 %.
    #[test]
    fn the_shipped_saturating_dol_is_motulators() {
        const FILE: &str = include_str!("../scenarios/dol-motulator-2kw-sat.toml");
        const REFERENCE: &str = include_str!("../../plant/tests/data/motulator_dol_2kw_sat.csv");
        let sc = parse_open_loop(Path::new("dol-motulator-2kw-sat.toml"), FILE).unwrap();
        assert!(sc.saturation.is_some());
        let mut rows = Vec::new();
        crate::sim::run_open_loop(
            &sc,
            crate::sim::OPEN_LOOP_MAX_STEP_S,
            |_| {},
            |r| {
                rows.push([r.x.i_alpha_a, r.x.i_beta_a, r.x.omega_m_rad_s, r.torque_nm]);
                Ok(())
            },
        )
        .unwrap();
        let reference: Vec<Vec<f64>> = REFERENCE
            .lines()
            .filter(|l| !l.starts_with('#') && !l.starts_with('t'))
            .map(|l| l.split(',').skip(1).map(|x| x.parse().unwrap()).collect())
            .collect();
        assert_eq!(rows.len(), reference.len());
        for s in 0..4 {
            let peak = reference.iter().map(|r| r[s].abs()).fold(0.0, f64::max);
            let ms = rows.iter().zip(&reference).map(|(a, b)| (a[s] - b[s]).powi(2)).sum::<f64>()
                / rows.len() as f64;
            assert!(ms.sqrt() < 1e-8 * peak, "signal {s}: {} of {peak}", ms.sqrt());
        }
    }

    /// A saturating machine driven far past its knee (β = 1000 1/Wb, the largest accepted:
    /// a knee at 1 mWb under 400 V) diverges, and a curve too steep for any step is refused
    /// before the run: both errors say where to look.
    #[test]
    fn a_diverging_saturating_run_names_its_curve() {
        const FILE: &str = include_str!("../scenarios/dol-motulator-2kw-sat.toml");
        let text = FILE.replace("beta_per_wb = 0.84", "beta_per_wb = 1000");
        let sc = parse_open_loop(Path::new("s.toml"), &text).unwrap();
        let e =
            crate::sim::run_open_loop(&sc, crate::sim::OPEN_LOOP_MAX_STEP_S, |_| {}, |_| Ok(())).unwrap_err();
        assert!(e.contains("diverged") && e.contains("[motor.saturation]"), "{e}");
        // A measured curve whose last segment no step can integrate: refused before the run,
        // naming the curve (it named only R_s, R_r and the inductances).
        let steep = FILE.replace(
            "beta_per_wb = 0.84\nexponent = 7.0",
            "flux_wb = [0.5, 1.0, 1.0000001]\ncurrent_a = [1.5, 3.5, 1e6]",
        );
        let sc = parse_open_loop(Path::new("s.toml"), &steep).unwrap();
        let e =
            crate::sim::run_open_loop(&sc, crate::sim::OPEN_LOOP_MAX_STEP_S, |_| {}, |_| Ok(())).unwrap_err();
        assert!(e.contains("too stiff") && e.contains("[motor.saturation] curve"), "{e}");
    }
}
