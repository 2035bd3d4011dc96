//! The drive tables: `[pwm]`, `[motor]`, `[controller]`, `[protection]`, and the optional
//! `[certify]` and `[board]`. Format and defaults are described in the crate docs.

use crate::motor::MotorTable;
use crate::source::{FileError, Source, num};
use crate::values::exact_opt;
use controller_core::current::CurrentLaw;
use controller_core::discretize::{ContinuousSection, Discretization};
use controller_core::drive::{
    BrakeChopper, Control, CurrentFrame, DriveConfig, DriveError, DriveSpec, Fault, FaultSet, PositionLaw,
    Protection, SpeedFeedback, ThermalLimit,
};
use controller_core::mras::RANGE_RATIO_MAX;
use controller_core::speed::SpeedLaw;
use controller_core::supervisor::THRESHOLD_COUNT;
use serde::Deserialize;

/// `[pwm]`: the fast loop runs once per PWM period, the slow loops every `slow_divider`-th.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct PwmTable {
    /// PWM (and fast-loop) frequency, Hz. Default 20 kHz.
    pub frequency_hz: f64,
    /// Speed/position loops every this many PWM periods. Default 10.
    pub slow_divider: u16,
}

impl Default for PwmTable {
    fn default() -> Self {
        Self { frequency_hz: 20_000.0, slow_divider: 10 }
    }
}

/// Accepted PWM frequencies, Hz: wide on purpose — whether a rate *works* is the
/// certificate's question, not the file's.
pub const PWM_FREQUENCY_HZ: (f64, f64) = (1.0, 1e6);
/// Largest slow-loop divider.
pub const SLOW_DIVIDER_MAX: u16 = 1000;

/// `[controller]` table.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ControllerTable {
    /// Current law.
    pub current: CurrentTable,
    /// Frame of the current loops (default stationary).
    #[serde(default)]
    pub current_frame: FrameTable,
    /// The field-frame loops' decoupling, `jω_e·σL_s·i*` fed forward (default on; the
    /// synchronous frame only: `DriveSpec::current_decoupling`).
    #[serde(default = "default_current_decoupling")]
    pub current_decoupling: bool,
    /// The q current the field's slip is turned on (default `"reference"`: i_q*, as seed 000
    /// prints eq. (7); `"measured"`: the measured q current while Running).
    #[serde(default)]
    pub slip_current: SlipTable,
    /// Where the speed and the field angle come from (default the encoder; `"sensorless"`:
    /// the flux and speed observer; `"encoder_ride_through"`: the encoder, the observer
    /// beside it carrying the drive on when the encoder fails — docs/sensorless.md).
    #[serde(default)]
    pub speed_feedback: FeedbackTable,
    /// The control law (default vector control; `"vhz"` or `{ kind = "vhz", … }`: V/Hz —
    /// docs/sensorless.md).
    #[serde(default, deserialize_with = "control_table")]
    pub control: ControlTable,
    /// Speed law.
    pub speed: SpeedTable,
    /// Position loop (default 10 1/s, 100 rad/s).
    #[serde(default)]
    pub position: PositionTable,
    /// Rotor-flux reference ψ_r*, Wb.
    pub flux_ref_wb: f64,
    /// IFOC flux floor, Wb (default 5 % of `flux_ref_wb`).
    pub flux_floor_wb: Option<f64>,
    /// Current-reference magnitude limit, A.
    pub i_ref_max_a: f64,
    /// Magnetizing → Running at this fraction of ψ_r* (default 0.95).
    #[serde(default = "default_magnetized")]
    pub magnetized_fraction: f64,
    /// Field weakening: the steady-state voltage target as a fraction of V_dc/√3 (default
    /// [`DEFAULT_VOLTAGE_MARGIN`], or [`DEFAULT_VOLTAGE_MARGIN_OVERMODULATING`] with
    /// `overmodulation`: [`ControllerTable::voltage_margin`]).
    pub voltage_margin: Option<f64>,
    /// Bandwidth of the field-frame current trim, rad/s; 0 turns it off (default
    /// [`DEFAULT_CURRENT_TRIM_BANDWIDTH_RAD_S`]).
    #[serde(default = "default_current_trim")]
    pub current_trim_bandwidth_rad_s: f64,
    /// Compensate the board's dead time (`[board] dead_time_s` as its timer gives it:
    /// `BoardTable::realised_dead_time_s`) in the modulator (default
    /// false: the simulator's average inverter has no dead time to compensate; turn it on
    /// for a board, and for the switching inverter model).
    #[serde(default)]
    pub dead_time_compensation: bool,
    /// Overmodulation (default false): beyond the hexagon the board's sampling window
    /// leaves, one phase at a time gives up its current sample, up to the full hexagon, its
    /// current rebuilt from the other two; the drive counts on the full hexagon's circle
    /// (`controller_core::drive::DriveSpec::overmodulation`, docs/envelope.md).
    #[serde(default)]
    pub overmodulation: bool,
    /// The rotor resistance's range, × `[motor] rr_ohm` (default
    /// [`controller_core::mras::DEFAULT_RANGE`]; `[1.0, 1.0]` turns the adaptation off).
    #[serde(default = "default_rotor_resistance_range")]
    pub rotor_resistance_range: [f64; 2],
    /// The inductances' range, × `[motor] ls_h`, `lr_h`, `lm_h` alike (default `[1.0, 1.0]`:
    /// the motor file's, fixed); within it the drive measures them at every enable of a
    /// demagnetized rotor at rest ([`controller_core::mras`]).
    #[serde(default = "default_inductance_range")]
    pub inductance_range: [f64; 2],
}

fn default_inductance_range() -> [f64; 2] {
    [1.0, 1.0]
}

fn default_rotor_resistance_range() -> [f64; 2] {
    controller_core::mras::DEFAULT_RANGE
}

/// Default bandwidth of the current trim, rad/s: slow against the current loops (their
/// crossover ≈ 1 000 rad/s), so their dynamics and the certificate's margins are those of
/// the loops alone. It is of the order of the flux's 1/T_r (≈ 15 rad/s on the DeLorenzo
/// motor) and of the voltage regulator's 10 rad/s; the field-weakening acceptance run
/// (`hil-sim/tests/envelope.rs`) shows the three settle together without sustained
/// oscillation (speed within ±0.08 rad/s, flux within 0.15 % of its reference).
pub const DEFAULT_CURRENT_TRIM_BANDWIDTH_RAD_S: f64 = 20.0;

fn default_current_trim() -> f64 {
    DEFAULT_CURRENT_TRIM_BANDWIDTH_RAD_S
}

/// The field-frame loops' decoupling is on unless the file turns it off: `design tune`'s
/// current PI is designed on the decoupled stator `R + s·σL_s`.
fn default_current_decoupling() -> bool {
    true
}

fn default_magnetized() -> f64 {
    0.95
}

/// Default field-weakening voltage target, as a fraction of the linear limit V_dc/√3: 2 %
/// of headroom for the current loops' transients (a torque step at top speed asks for
/// σL_s·di/dt on top of the steady voltage; the vector limit and the loss-of-control time
/// absorb short excursions), while the steady torque at the voltage limit — which scales
/// with the voltage squared — stays within 0.98² = 96 % of the machine's envelope.
pub const DEFAULT_VOLTAGE_MARGIN: f64 = 0.98;

/// Default field-weakening voltage target with overmodulation: the whole circle of the full
/// hexagon. The current loops' transient headroom is then the hexagon beyond the circle (the
/// modulator gives it, one phase rebuilt); the two periods around each slow tick keep every
/// window (`controller_core::drive`'s tick sample), which costs about 1 % of the voltage — at
/// 0.98 the shipped motor got 0.943–0.964 of its physical limit motoring (`hil-sim envelope`
/// on drive.toml with both lines), at 1 it gets 0.970–0.982 (`cargo test --release -p
/// hil-sim --test envelope overmodulation -- --nocapture`; docs/envelope.md).
pub const DEFAULT_VOLTAGE_MARGIN_OVERMODULATING: f64 = 1.0;

impl ControllerTable {
    /// The voltage target: the file's, or the default for its modulator.
    pub fn voltage_margin(&self) -> f64 {
        self.voltage_margin.unwrap_or(if self.overmodulation {
            DEFAULT_VOLTAGE_MARGIN_OVERMODULATING
        } else {
            DEFAULT_VOLTAGE_MARGIN
        })
    }
}

/// `controller.current`.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum CurrentTable {
    /// PI × second-order lag (seed 002). Without keys: eq. (20); otherwise all four of
    /// `kp`, `ki`, `lag_num`, `lag_den` (descending powers of s).
    Icad {
        /// V/A.
        kp: Option<f64>,
        /// V/(A·s).
        ki: Option<f64>,
        /// Lag numerator `[n2, n1, n0]`.
        #[serde(default, deserialize_with = "exact_opt")]
        lag_num: Option<[f64; 3]>,
        /// Lag denominator `[d2, d1, d0]`.
        #[serde(default, deserialize_with = "exact_opt")]
        lag_den: Option<[f64; 3]>,
    },
    /// PI `kp + ki/s`.
    Pi {
        /// V/A.
        kp: f64,
        /// V/(A·s).
        ki: f64,
    },
}

/// `controller.control`.
#[derive(Debug, Clone, Copy, Default, Deserialize, PartialEq)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum ControlTable {
    /// Field-oriented vector control.
    #[default]
    Vector,
    /// V/Hz with stator-current feedback.
    Vhz {
        /// The frequency reference's ramp, mechanical rad/s² (default
        /// [`controller_core::vhz::default_ramp_rad_s2`]: a tenth of the drive's torque at its
        /// current limit on the motor file's inertia).
        ramp_rad_s2: Option<f64>,
        /// The current feedback's gain (default [`controller_core::vhz::K_U`], the paper's).
        #[serde(default = "default_k_u")]
        k_u: f64,
        /// The frequency feedback's gain (default [`controller_core::vhz::K_W`], the paper's).
        #[serde(default = "default_k_w")]
        k_w: f64,
    },
}

/// `controller.control` as a name (`"vector"`, `"vhz"`: the defaults) or as a table
/// (`{ kind = "vhz", ramp_rad_s2, k_u, k_w }`): a user's `control = "vhz"` read as "invalid
/// type: string, expected internally tagged enum" (found trying it).
fn control_table<'de, D: serde::Deserializer<'de>>(d: D) -> Result<ControlTable, D::Error> {
    struct Either;
    impl<'de> serde::de::Visitor<'de> for Either {
        type Value = ControlTable;
        fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            f.write_str("\"vector\", \"vhz\" or a table { kind = \"vhz\", ramp_rad_s2, k_u, k_w }")
        }
        fn visit_str<E: serde::de::Error>(self, name: &str) -> Result<ControlTable, E> {
            match name {
                "vector" => Ok(ControlTable::Vector),
                "vhz" => Ok(ControlTable::Vhz { ramp_rad_s2: None, k_u: default_k_u(), k_w: default_k_w() }),
                _ => Err(E::unknown_variant(name, &["vector", "vhz"])),
            }
        }
        fn visit_map<A: serde::de::MapAccess<'de>>(self, map: A) -> Result<ControlTable, A::Error> {
            ControlTable::deserialize(serde::de::value::MapAccessDeserializer::new(map))
        }
    }
    d.deserialize_any(Either)
}

fn default_k_u() -> f64 {
    controller_core::vhz::K_U
}

fn default_k_w() -> f64 {
    controller_core::vhz::K_W
}

/// `controller.speed_feedback`.
#[derive(Debug, Clone, Copy, Default, Deserialize, PartialEq)]
#[serde(rename_all = "snake_case")]
pub enum FeedbackTable {
    /// The encoder.
    #[default]
    Encoder,
    /// The observer, no encoder.
    Sensorless,
    /// The encoder, the observer beside it: the drive carries on on the observer when the
    /// encoder fails, and reports the fault.
    EncoderRideThrough,
}

/// `controller.current_frame`.
#[derive(Debug, Clone, Copy, Default, Deserialize, PartialEq)]
#[serde(rename_all = "snake_case")]
pub enum FrameTable {
    /// α/β loops.
    #[default]
    Stationary,
    /// d/q loops.
    Synchronous,
}

/// `controller.slip_current`.
#[derive(Debug, Clone, Copy, Default, Deserialize, PartialEq)]
#[serde(rename_all = "snake_case")]
pub enum SlipTable {
    /// The reference i_q*.
    #[default]
    Reference,
    /// The measured q current while Running.
    Measured,
}

/// `controller.speed`.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum SpeedTable {
    /// Seed 002 eq. (21).
    SaturatedP {
        /// N·m per rad/s.
        kp: f64,
        /// N·m.
        tau_max_nm: f64,
    },
    /// PI → torque.
    PiTorque {
        /// N·m per rad/s.
        kp: f64,
        /// N·m per rad.
        ki: f64,
        /// N·m.
        limit: f64,
        /// The setpoint weight b in [0, 1] (`controller_core::speed`: the reference's
        /// prefilter; default 1, the one-degree PI).
        #[serde(default = "one")]
        setpoint_weight: f64,
    },
    /// PI → i_q* (seed 000 PI2).
    PiIq {
        /// A per rad/s.
        kp: f64,
        /// A per rad.
        ki: f64,
        /// A.
        limit: f64,
        /// As for `pi_torque`.
        #[serde(default = "one")]
        setpoint_weight: f64,
    },
}

/// The default setpoint weight: the one-degree PI.
fn one() -> f64 {
    1.0
}

/// `controller.position`.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct PositionTable {
    /// 1/s.
    pub k_per_s: f64,
    /// Mechanical rad/s.
    pub omega_max_rad_s: f64,
}

impl Default for PositionTable {
    fn default() -> Self {
        Self { k_per_s: 10.0, omega_max_rad_s: 100.0 }
    }
}

/// `[protection]` table. `i_trip_a`, `vdc_min_v` and `vdc_max_v` are required; every other
/// scalar threshold of [`Protection::THRESHOLDS`] may be set by its name and otherwise takes
/// the value derived from the drive ([`protection_with_defaults`]: [`default_overspeed_rad_s`],
/// [`default_stall_time_s`], …). The thresholds' keys are controller-core's declaration
/// (`Protection::THRESHOLDS`), not a list of this crate's: a new threshold is a key here
/// without a line of this crate, but its default.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProtectionTable {
    /// Phase-current trip level, A.
    pub i_trip_a: f64,
    /// Bus under-voltage trip, V.
    pub vdc_min_v: f64,
    /// Bus over-voltage trip, V.
    pub vdc_max_v: f64,
    /// The thresholds the file sets, by their place in [`Protection::THRESHOLDS`] (`None`:
    /// the derived default; the three above are never here).
    pub thresholds: [Option<f64>; THRESHOLD_COUNT],
    /// The board's brake chopper, if it has one: `{ on_v, off_v }`, the bus voltages at
    /// which the drive switches its resistor in and out (0 < off_v < on_v < vdc_max_v).
    pub brake_chopper: Option<BrakeChopperTable>,
    /// The motor's I²t limit (default: [`default_motor_thermal`] from `[motor]`).
    pub motor_thermal: Option<ThermalTable>,
    /// The inverter's I²t limit (default: [`default_inverter_thermal`] from `[board]`).
    pub inverter_thermal: Option<ThermalTable>,
    /// The reaction to each fault that allows a choice (default: [`DEFAULT_REACTION`]).
    pub reaction: Option<ReactionTable>,
}

impl ProtectionTable {
    /// The protection of `defaults` (the derived one) with what the file sets; the three
    /// required thresholds are this table's own fields (a value in their slots of
    /// `thresholds` is ignored).
    fn over(&self, defaults: &Protection) -> Protection {
        let mut t = defaults.thresholds();
        for ((v, set), name) in t.iter_mut().zip(self.thresholds).zip(Protection::THRESHOLDS) {
            *v = match name {
                "i_trip_a" => self.i_trip_a,
                "vdc_min_v" => self.vdc_min_v,
                "vdc_max_v" => self.vdc_max_v,
                _ => set.unwrap_or(*v),
            };
        }
        Protection::with_thresholds(
            t,
            self.brake_chopper.map(|b| BrakeChopper { on_v: b.on_v, off_v: b.off_v }),
            self.motor_thermal.map(ThermalTable::limit).or(defaults.motor_thermal),
            self.inverter_thermal.map(ThermalTable::limit).or(defaults.inverter_thermal),
            self.reaction.map_or(defaults.stop_on, |r| r.stop_on()),
        )
    }
}

/// Read as a map: the structured keys by name, the scalar thresholds by
/// [`Protection::THRESHOLDS`], anything else an unknown key (serde's error, with the key's
/// span: `deny_unknown_fields` as a derived table has it).
impl<'de> Deserialize<'de> for ProtectionTable {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        use serde::de::{Error, MapAccess, Visitor};
        const STRUCTURED: [&str; 4] = ["brake_chopper", "motor_thermal", "inverter_thermal", "reaction"];
        /// A key of the table, judged as it is read (an unknown one's error then carries the
        /// key's span, as a derived table's does).
        enum Key {
            Threshold(usize),
            BrakeChopper,
            MotorThermal,
            InverterThermal,
            Reaction,
        }
        impl<'de> Deserialize<'de> for Key {
            fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
                struct Name;
                impl Visitor<'_> for Name {
                    type Value = Key;
                    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                        f.write_str("a [protection] key")
                    }
                    fn visit_str<E: Error>(self, name: &str) -> Result<Key, E> {
                        if let Some(k) = Protection::THRESHOLDS.iter().position(|t| *t == name) {
                            return Ok(Key::Threshold(k));
                        }
                        match name {
                            "brake_chopper" => return Ok(Key::BrakeChopper),
                            "motor_thermal" => return Ok(Key::MotorThermal),
                            "inverter_thermal" => return Ok(Key::InverterThermal),
                            "reaction" => return Ok(Key::Reaction),
                            _ => {}
                        }
                        let known: Vec<String> = Protection::THRESHOLDS
                            .iter()
                            .chain(&STRUCTURED)
                            .map(|k| format!("`{k}`"))
                            .collect();
                        Err(E::custom(format!(
                            "unknown field `{name}`, expected one of {}",
                            known.join(", ")
                        )))
                    }
                }
                d.deserialize_str(Name)
            }
        }
        struct Table;
        impl<'de> Visitor<'de> for Table {
            type Value = ProtectionTable;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("the [protection] table")
            }
            fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<ProtectionTable, A::Error> {
                let (mut brake_chopper, mut motor_thermal, mut inverter_thermal, mut reaction) =
                    (None, None, None, None);
                let mut thresholds = [None; THRESHOLD_COUNT];
                while let Some(key) = map.next_key::<Key>()? {
                    match key {
                        Key::BrakeChopper => brake_chopper = Some(map.next_value()?),
                        Key::MotorThermal => motor_thermal = Some(map.next_value()?),
                        Key::InverterThermal => inverter_thermal = Some(map.next_value()?),
                        Key::Reaction => reaction = Some(map.next_value()?),
                        Key::Threshold(k) => {
                            let x = map.next_value::<f64>()?;
                            if let Some(slot) = thresholds.get_mut(k) {
                                *slot = Some(x);
                            }
                        }
                    }
                }
                let mut take = |name: &'static str| {
                    Protection::THRESHOLDS
                        .iter()
                        .position(|t| *t == name)
                        .and_then(|k| thresholds.get_mut(k))
                        .and_then(Option::take)
                        .ok_or_else(|| A::Error::missing_field(name))
                };
                let (i_trip_a, vdc_min_v, vdc_max_v) =
                    (take("i_trip_a")?, take("vdc_min_v")?, take("vdc_max_v")?);
                Ok(ProtectionTable {
                    i_trip_a,
                    vdc_min_v,
                    vdc_max_v,
                    thresholds,
                    brake_chopper,
                    motor_thermal,
                    inverter_thermal,
                    reaction,
                })
            }
        }
        d.deserialize_map(Table)
    }
}

/// `motor_thermal = { rated_current_a = 0.9, time_constant_s = 900.0, overload_factor = 1.15 }`.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ThermalTable {
    /// Rated RMS phase current, A.
    pub rated_current_a: f64,
    /// Thermal time constant, s.
    pub time_constant_s: f64,
    /// Continuous current allowed over the rated one (≥ 1).
    pub overload_factor: f64,
}

/// What the drive does on a fault: turn the bridge off at once, or stop the motor under
/// control and then turn it off (the fault latched when the stop ends).
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum Reaction {
    /// The bridge off at once (the motor coasts).
    Off,
    /// A controlled stop, then the bridge off.
    Stop,
}

/// `reaction = { motor_overload = "stop", inverter_overload = "stop", overspeed = "off" }`:
/// the faults after which the drive still controls the motor may be answered by a
/// controlled stop; every other fault turns the bridge off at once (a current, voltage or
/// encoder fault leaves nothing to control with).
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct ReactionTable {
    /// The motor's I²t limit.
    pub motor_overload: Option<Reaction>,
    /// The inverter's I²t limit.
    pub inverter_overload: Option<Reaction>,
    /// Overspeed (a stop only helps if the load does not overpower the drive; the stop time
    /// ends it otherwise).
    pub overspeed: Option<Reaction>,
}

/// Default reactions: the thermal overloads stop the motor under control (it is hot, not
/// out of control: a loaded machine should not coast), an overspeed turns the bridge off
/// (a load driving the motor past the limit would run on through a stop).
pub const DEFAULT_REACTION: ReactionTable = ReactionTable {
    motor_overload: Some(Reaction::Stop),
    inverter_overload: Some(Reaction::Stop),
    overspeed: Some(Reaction::Off),
};

impl ReactionTable {
    /// The faults answered by a controlled stop (unset entries take [`DEFAULT_REACTION`]'s).
    pub fn stop_on(&self) -> FaultSet {
        let d = DEFAULT_REACTION;
        [
            (self.motor_overload.or(d.motor_overload), Fault::MotorOverload),
            (self.inverter_overload.or(d.inverter_overload), Fault::InverterOverload),
            (self.overspeed.or(d.overspeed), Fault::Overspeed),
        ]
        .iter()
        .fold(FaultSet::EMPTY, |s, (r, f)| if *r == Some(Reaction::Stop) { s.with(*f) } else { s })
    }
}

impl ThermalTable {
    fn limit(self) -> ThermalLimit {
        ThermalLimit {
            rated_current_a: self.rated_current_a,
            time_constant_s: self.time_constant_s,
            overload_factor: self.overload_factor,
        }
    }
}

/// Default motor service factor: the continuous current the motor I²t limit allows, over the
/// rated current (IEC/NEMA general-purpose motors: 1.15).
pub const DEFAULT_MOTOR_SERVICE_FACTOR: f64 = 1.15;

/// Default motor I²t limit: the nameplate current and thermal time constant of `[motor]`
/// (both or neither), continuous current up to [`DEFAULT_MOTOR_SERVICE_FACTOR`] × rated.
pub fn default_motor_thermal(
    rated_current_a: Option<f64>,
    time_constant_s: Option<f64>,
) -> Option<ThermalLimit> {
    Some(ThermalLimit {
        rated_current_a: rated_current_a?,
        time_constant_s: time_constant_s?,
        overload_factor: DEFAULT_MOTOR_SERVICE_FACTOR,
    })
}

/// Default inverter I²t limit from the board's rating: continuous current up to the rated
/// one, and `factor` × rated for `time_s` from cold — the time constant that makes it so,
/// `τ = time_s / ln(factor²/(factor² − 1))` (150 % for 60 s: τ = 102 s).
pub fn default_inverter_thermal(rated_current_a: f64, factor: f64, time_s: f64) -> ThermalLimit {
    let k2 = factor * factor;
    ThermalLimit { rated_current_a, time_constant_s: time_s / (k2 / (k2 - 1.0)).ln(), overload_factor: 1.0 }
}

/// `[protection] brake_chopper = { on_v = 360.0, off_v = 350.0 }`.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct BrakeChopperTable {
    /// Switch the resistor in above this bus voltage, V.
    pub on_v: f64,
    /// Switch it out below this one, V.
    pub off_v: f64,
}

/// Default overspeed trip: 1.2 × [`FIELD_WEAKENING_RANGE`] × the no-load base speed on the
/// highest bus the drive accepts — the speed at which the motor's no-load back-EMF at the
/// flux reference reaches the largest voltage the bridge can apply,
/// `ω_m = (V_dc,max/√3) / (ψ_r*·L_s/L_m) / p` (stator flux ≈ ψ_r*·L_s/L_m at no load;
/// V_dc/√3 is the modulator's linear limit). The drive weakens the field above base speed;
/// beyond the field-weakening range by 20 % the load is driving the motor (or the speed
/// loop lost control).
pub fn default_overspeed_rad_s(
    motor: &controller_core::motor::MotorParams,
    flux_ref_wb: f64,
    vdc_max_v: f64,
) -> f64 {
    1.2 * FIELD_WEAKENING_RANGE * crate::motor::no_load_base_speed_el_rad_s(motor, flux_ref_wb, vdc_max_v)
        / f64::from(motor.pole_pairs())
}

/// The speed range above base speed a drive is expected to run in (the default overspeed
/// trip's basis): 2:1, the constant-power range of a general-purpose induction-motor drive.
/// Set `protection.overspeed_rad_s` for a wider one.
pub const FIELD_WEAKENING_RANGE: f64 = 2.0;

/// Default stall time, s: a locked rotor under a speed command is caught within this. A
/// healthy start at the torque limit must leave the "not moving" band (ω_band =
/// `controller_core::supervisor::motion::STALL_SPEED_FRACTION` of the overspeed level) well
/// before it: it takes `J·ω_band/(τ_max − τ_L)` against a load τ_L. The stall time is
/// [`STALL_LEAVE_FACTOR`] times the unloaded `J·ω_band/τ_max` — a start against a load of
/// 0.9·τ_max on twice the inertia (the top of a certified box) still leaves the band within
/// it — and at least the speed estimate's window (`SPEED_WINDOW_READS` slow periods). It was
/// a fixed 0.3 s, fitted to the shipped motor. Shipped drive:
/// 20·0.005·(0.005·607.3)/2 = 0.152 s.
pub fn default_stall_time_s(
    motor: &controller_core::motor::MotorParams,
    speed_limit_nm: f64,
    overspeed_rad_s: f64,
    slow_period_s: f64,
) -> f64 {
    let band_rad_s = controller_core::supervisor::motion::STALL_SPEED_FRACTION * overspeed_rad_s;
    at_least_the_speed_window(
        STALL_LEAVE_FACTOR * motor.j_kgm2() * band_rad_s / speed_limit_nm,
        slow_period_s,
    )
}

/// `t_s`, at least the speed estimate's window (`SPEED_WINDOW_READS` slow periods), and that
/// window for a `t_s` that is not finite: the motion checks judge nothing shorter.
fn at_least_the_speed_window(t_s: f64, slow_period_s: f64) -> f64 {
    let window_s = speed_window_s(slow_period_s);
    if t_s.is_finite() { t_s.max(window_s) } else { window_s }
}

/// The encoder speed estimate's window, `SPEED_WINDOW_READS` slow periods, s.
fn speed_window_s(slow_period_s: f64) -> f64 {
    controller_core::encoder::SPEED_WINDOW_READS as f64 * slow_period_s
}

/// See [`default_stall_time_s`]: 1/(1 − 0.9) for a load of 0.9·τ_max, × 2 for twice the
/// inertia.
pub const STALL_LEAVE_FACTOR: f64 = 20.0;

/// Default speed-following-error window, s: the shortest in which the check can judge —
/// the progress it owes at the speed loop's torque limit, `f·τ_max·T/J` (f =
/// `controller_core::drive::FOLLOWING_PROGRESS_FRACTION`), reaches
/// [`FOLLOWING_SPEED_QUANTA`] of the encoder speed's resolution `Δω_q = 2π/(4·lines)/(n·T_slow)`
/// (one count over the estimate's window of n = `SPEED_WINDOW_READS` reads), and at least
/// that window: `T = max(Q·Δω_q·J/(f·τ_max), n·T_slow)`.
///
/// Short, because the check must speak before the load drags the rotor to the bridge's
/// voltage limit, where the currents collapse and other checks (loss of control, a switch,
/// the encoder against the model) would name the wrong fault: a 1.5 × τ_max overload drags
/// a rotor at `0.5·τ_max/J`, through its base speed in `2·J·ω_b/τ_max`. It was a fixed 0.2 s,
/// fitted to the shipped motor (J·ω_b/τ_max ≈ 1.5 s there); an 895 W 4-pole motor of the
/// population (issue 49) has 0.08 s and its overload rows named `SwitchOpen`. Shipped drive:
/// 10·0.3835·0.005/(0.1·2) = 0.096 s.
pub fn default_following_time_s(
    motor: &controller_core::motor::MotorParams,
    speed_limit_nm: f64,
    encoder_lines: u32,
    slow_period_s: f64,
) -> f64 {
    let quantum_rad_s = controller_core::encoder::speed_resolution_rad_s(encoder_lines, slow_period_s);
    let owed_rad_s2 =
        controller_core::supervisor::motion::FOLLOWING_PROGRESS_FRACTION * speed_limit_nm / motor.j_kgm2();
    at_least_the_speed_window(FOLLOWING_SPEED_QUANTA * quantum_rad_s / owed_rad_s2, slow_period_s)
}

/// See [`default_following_time_s`]: the progress owed over the window, in counts of the
/// encoder speed's resolution — far above the estimate's ±1-count quantisation and the
/// sensors' edge chatter.
pub const FOLLOWING_SPEED_QUANTA: f64 = 10.0;

/// Default loss-of-control time, s: long against the current loops' settling, so a transient
/// at the voltage limit (a large current step at speed) passes, and short enough that a loop
/// that has lost its current (dead sensors, a voltage limit it cannot leave) trips quickly
/// (`hil-sim/tests/supervisor.rs`).
pub const DEFAULT_SATURATION_TIME_S: f64 = 0.02;

/// Default encoder-check time, s: [`ENCODER_CHECK_SLOW_PERIODS`] slow periods — the check
/// runs once per slow period, on the encoder estimate's 8-read window —, several times the
/// current loops' settling and that window, so a current step (whose σL_s·di/dt the
/// steady-state model leaves out) or a speed transient passes. 10 ms shipped (0.5 ms slow
/// period); a fixed 10 ms before issue 49, whatever the slow rate.
pub fn default_encoder_check_time_s(slow_period_s: f64) -> f64 {
    ENCODER_CHECK_SLOW_PERIODS * slow_period_s
}

/// See [`default_encoder_check_time_s`].
pub const ENCODER_CHECK_SLOW_PERIODS: f64 = 20.0;

/// Default encoder jump level, mechanical rad: [`ENCODER_JUMP_COUNTS`] counts of the
/// encoder plus the position change that [`ENCODER_ACCEL_FACTOR`] times the drive's peak
/// acceleration makes over a read period squared, `α·T²` with
/// `α = ENCODER_ACCEL_FACTOR·τ_peak/J` and `τ_peak = 1.5·p·(L_m/L_r)·ψ_r*·i_ref_max` (the
/// torque of the largest current reference all on the q axis at the rated flux). For the
/// shipped drive: 4·2π/4096 + 10·5.11/0.005·(0.5 ms)² = 6.14e-3 + 2.56e-3 = 8.69e-3 rad. A
/// motion the mechanics allow — the drive's torque and a load ten times it, a seizing load
/// included — stays below; a glitch of more than ≈ 6 counts, or a counter that stops at
/// more than 17 rad/s (8.69e-3 rad per 0.5 ms read), does not.
pub fn default_encoder_jump_rad(
    motor: &controller_core::motor::MotorParams,
    flux_ref_wb: f64,
    i_ref_max_a: f64,
    encoder_lines: u32,
    read_period_s: f64,
) -> f64 {
    let count_rad = core::f64::consts::TAU / (4.0 * f64::from(encoder_lines.max(1)));
    let accel_rad_s2 = ENCODER_ACCEL_FACTOR
        * controller_core::drive::peak_acceleration_rad_s2(motor, flux_ref_wb, i_ref_max_a);
    ENCODER_JUMP_COUNTS * count_rad + accel_rad_s2 * read_period_s * read_period_s
}

/// Default window of the rotor-at-rest check, s (`controller_core::supervisor::rest`): long
/// enough for the encoder to resolve the rest speed `ω_rest = REST_SPEED_TR/(p·T_r)` to a
/// quarter — [`REST_COUNTS`] counts at that speed — and at least two slow periods. Shipped
/// drive (1 024 lines, T_r = 64.7 ms): ω_rest = 0.773 rad/s, 4·1.53e-3/0.773 = 7.9 ms.
pub fn default_rest_time_s(
    motor: &controller_core::motor::MotorParams,
    encoder_lines: u32,
    slow_period_s: f64,
) -> f64 {
    let count_rad = core::f64::consts::TAU / (4.0 * f64::from(encoder_lines.max(1)));
    let rest_rad_s =
        controller_core::supervisor::rest::REST_SPEED_TR / (f64::from(motor.pole_pairs()) * motor.tr_s());
    (REST_COUNTS * count_rad / rest_rad_s).max(2.0 * slow_period_s)
}

/// See [`default_rest_time_s`]: the window holds this many counts at the rest speed, so
/// that a count of quantisation is a quarter of it.
pub const REST_COUNTS: f64 = 4.0;

/// See [`default_encoder_jump_rad`]: the floor quantisation of the three readings a second
/// difference takes makes it err by less than 2 counts; 2 more allow one count of edge
/// chatter on two of them.
pub const ENCODER_JUMP_COUNTS: f64 = 4.0;

/// See [`default_encoder_jump_rad`]: the acceleration allowed, in multiples of the drive's
/// own peak (the check splits the level into its two shares with it).
pub use controller_core::drive::ENCODER_ACCEL_FACTOR;

/// The encoder resolution the derived [`default_encoder_jump_rad`] assumes without a
/// `[board]` table (the simulator's realistic encoder, and the shipped board's).
pub const DEFAULT_ENCODER_LINES: u32 = 1024;

/// What the derived defaults are computed from, beyond the motor and the three required
/// protection keys.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DefaultsBasis {
    /// Rotor-flux reference ψ_r*, Wb.
    pub flux_ref_wb: f64,
    /// Largest current reference, A.
    pub i_ref_max_a: f64,
    /// The speed loop's torque limit, N·m (an i_q law's limit as torque at the flux
    /// reference).
    pub speed_limit_nm: f64,
    /// Encoder lines per revolution.
    pub encoder_lines: u32,
    /// Slow-loop (encoder read) period, s.
    pub slow_period_s: f64,
    /// The motor's I²t limit ([`default_motor_thermal`]), if known.
    pub motor_thermal: Option<ThermalLimit>,
    /// The inverter's I²t limit ([`default_inverter_thermal`]), if known.
    pub inverter_thermal: Option<ThermalLimit>,
    /// The current ADC's resolution, A per count ([`default_current_sum_a`]), if known.
    pub current_lsb_a: Option<f64>,
}

/// What a drive's defaults take from its `[board]` table (or the stated defaults without
/// one).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoardDefaults {
    /// Dead time to compensate, s (0: off).
    pub dead_time_compensation_s: f64,
    /// The low-side window a current sample needs, s (0 without a board: sensors that need
    /// none).
    pub sample_window_s: f64,
    /// Encoder lines per revolution ([`DEFAULT_ENCODER_LINES`] without a board).
    pub encoder_lines: u32,
    /// The inverter's I²t limit from its rating, if the board states one.
    pub inverter_thermal: Option<ThermalLimit>,
    /// The current ADC's resolution, A per count, if the board states it.
    pub current_lsb_a: Option<f64>,
}

/// The protection of a drive with the derived defaults for every optional key (what a
/// `[protection]` table with only its three required keys gives).
pub fn protection_with_defaults(
    motor: &controller_core::motor::MotorParams,
    basis: &DefaultsBasis,
    i_trip_a: f64,
    vdc_min_v: f64,
    vdc_max_v: f64,
) -> Protection {
    let flux_ref_wb = basis.flux_ref_wb;
    Protection {
        i_trip_a,
        vdc_min_v,
        vdc_max_v,
        overspeed_rad_s: default_overspeed_rad_s(motor, flux_ref_wb, vdc_max_v),
        stall_time_s: default_stall_time_s(
            motor,
            basis.speed_limit_nm,
            default_overspeed_rad_s(motor, flux_ref_wb, vdc_max_v),
            basis.slow_period_s,
        ),
        following_time_s: default_following_time_s(
            motor,
            basis.speed_limit_nm,
            basis.encoder_lines,
            basis.slow_period_s,
        ),
        current_sum_max_a: default_current_sum_a(i_trip_a, basis.current_lsb_a),
        saturation_time_s: DEFAULT_SATURATION_TIME_S,
        encoder_check_time_s: default_encoder_check_time_s(basis.slow_period_s),
        encoder_jump_rad: default_encoder_jump_rad(
            motor,
            flux_ref_wb,
            basis.i_ref_max_a,
            basis.encoder_lines,
            basis.slow_period_s,
        ),
        stop_time_s: default_stop_time_s(motor, flux_ref_wb, vdc_max_v),
        open_phase_time_s: default_open_phase_time_s(basis.slow_period_s),
        rest_time_s: default_rest_time_s(motor, basis.encoder_lines, basis.slow_period_s),
        current_sum_mean_max_a: default_current_sum_mean_a(i_trip_a, basis.current_lsb_a),
        brake_chopper: None,
        motor_thermal: basis.motor_thermal,
        inverter_thermal: basis.inverter_thermal,
        stop_on: DEFAULT_REACTION.stop_on(),
    }
}

/// Default longest controlled stop, s: the time to brake from the default overspeed level to
/// rest, `J·ω_over/τ_stop`, at least 1 s, with `τ_stop` = [`STOP_TORQUE_FRACTION`] of the
/// torque the rated flux gives with i_q = i_d, `1.5·p·ψ_r*²/L_r` — a light braking torque
/// any drive of this motor has, whatever its speed law. A stop the speed loop cannot finish
/// in that time (a load driving the motor, a bus that cannot take the energy) ends with the
/// bridge off and the motor coasting. Shipped drive: τ_stop = 0.5·1.5·0.9²/1.5 = 0.405 N·m,
/// 0.005·607.3/0.405 = 7.5 s.
pub fn default_stop_time_s(
    motor: &controller_core::motor::MotorParams,
    flux_ref_wb: f64,
    vdc_max_v: f64,
) -> f64 {
    let tau_stop_nm =
        STOP_TORQUE_FRACTION * 1.5 * f64::from(motor.pole_pairs()) * flux_ref_wb * flux_ref_wb / motor.lr_h();
    (motor.j_kgm2() * default_overspeed_rad_s(motor, flux_ref_wb, vdc_max_v) / tau_stop_nm).max(1.0)
}

/// Default open-phase window, s: [`OPEN_PHASE_WINDOW_SLOW_PERIODS`] slow periods — the check
/// takes one sample per slow period. Short enough that a phase whose reference sits near a
/// zero crossing for a window (|cos| < 0.19 for 0.375 rad of the field's turn at
/// ω_e = 150 rad/s and a 0.5 ms slow period) is judged again within a few samples, and that
/// its verdict (two windows) comes before the encoder check's (four times as many
/// samples, [`ENCODER_CHECK_SLOW_PERIODS`]), which an open lead's saturated loops also
/// upset; long enough to average the sensors' noise (0.01 A RMS) far below the 10 % level
/// (5 samples: σ/√5). 2.5 ms shipped; a fixed 2.5 ms before issue 49, whatever the slow rate.
pub fn default_open_phase_time_s(slow_period_s: f64) -> f64 {
    OPEN_PHASE_WINDOW_SLOW_PERIODS * slow_period_s
}

/// See [`default_open_phase_time_s`].
pub const OPEN_PHASE_WINDOW_SLOW_PERIODS: f64 = 5.0;

/// See [`default_stop_time_s`].
pub const STOP_TORQUE_FRACTION: f64 = 0.5;

/// Default current-sum limit as a fraction of `i_trip_a`: far above the noise of three
/// 12-bit channels and their gain errors at working currents, below the sum a dead phase
/// sensor leaves at the magnetizing current.
pub const DEFAULT_CURRENT_SUM_FRACTION: f64 = 0.05;

/// The least default current-sum limit in the current ADC's counts: the check trips on one
/// sample, so the sum of three channels must stay below it with their quantisation (±½
/// count each), the offsets the calibration leaves (±½ count each: 3 counts together) and
/// six standard deviations of their noise — three channels of ≈ 1.2 counts RMS (the
/// simulator's realistic front end, 10 mA on 8.06 mA counts): 6·√3·1.2 ≈ 12.5 counts; 20
/// with the margin. On the shipped board 20 counts are 0.16 A, under the 5 % of the trip
/// level; on a coarse one (a 100 A front end on an 8 A drive: 49 mA counts) the fraction
/// alone would trip on the noise.
pub const CURRENT_SUM_COUNTS: f64 = 20.0;

/// The default current-sum limit: [`DEFAULT_CURRENT_SUM_FRACTION`] of `i_trip_a`, at least
/// [`CURRENT_SUM_COUNTS`] of the board's current resolution `lsb_a` (A per count) when it is
/// known.
pub fn default_current_sum_a(i_trip_a: f64, lsb_a: Option<f64>) -> f64 {
    (DEFAULT_CURRENT_SUM_FRACTION * i_trip_a).max(CURRENT_SUM_COUNTS * lsb_a.unwrap_or(0.0))
}

/// The default windowed current-sum level (`current_sum_mean_max_a`):
/// `controller_core::drive::CURRENT_SUM_MEAN_FRACTION` of the default instantaneous level
/// ([`default_current_sum_a`]). Not a number of the board's counts: what healthy channels
/// leave in the window's mean besides their gain errors is mostly their noise, which the
/// file does not state — 8 counts (quantisation, calibrated offsets, the summed noise's mean
/// and 4σ of its window mean for 1.2 counts RMS per channel) tripped `CurrentSensor` on a
/// healthy 153 kW population member at 10 kHz whose front end's noise, 0.125 % of its trip
/// level as the simulator's realistic sensors scale it, is 2.4 of its counts (member 010,
/// run 134 of its 200-run campaign, generating at 314 rad/s). A board that knows its noise
/// sets the key.
pub fn default_current_sum_mean_a(i_trip_a: f64, lsb_a: Option<f64>) -> f64 {
    controller_core::drive::CURRENT_SUM_MEAN_FRACTION * default_current_sum_a(i_trip_a, lsb_a)
}

/// The tables that make a drive, as written.
#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct DriveTables {
    /// `[pwm]` (optional: defaults).
    #[serde(default)]
    pub pwm: PwmTable,
    /// `[motor]`.
    pub motor: MotorTable,
    /// `[controller]`.
    pub controller: ControllerTable,
    /// `[protection]`.
    pub protection: ProtectionTable,
    /// `[certify]`.
    pub certify: Option<crate::certify::CertifyTable>,
    /// `[board]`.
    pub board: Option<crate::board::BoardTable>,
    /// `[requirements]` (optional: defaults).
    #[serde(default)]
    pub requirements: crate::requirements::RequirementsTable,
}

/// A validated drive file.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DriveFile {
    /// The drive (what `controller-core` builds its configuration from).
    pub spec: DriveSpec,
    /// Certification intervals and requirements, if the file has them.
    pub certify: Option<crate::certify::Certify>,
    /// Board scaling, if the file has it.
    pub board: Option<crate::board::Board>,
    /// What the user asks of the drive (the defaults where the file is silent).
    pub requirements: crate::requirements::Requirements,
    /// A saturating motor as its file writes it — its form's T model at `lm_h` and its
    /// magnetizing branch — the machine the simulator runs for this drive (`spec.motor` is
    /// the drive's linear model at the rated flux, `spec.magnetizing` its table); `None` for
    /// a linear motor.
    pub saturating_motor:
        Option<(controller_core::motor::MotorParams, controller_core::magnetics::Saturation)>,
}

impl DriveFile {
    /// The encoder's lines per revolution: the board's, [`DEFAULT_ENCODER_LINES`] without one
    /// (what the drive's defaults are derived from, and what the simulator's encoder has).
    pub fn encoder_lines(&self) -> u32 {
        self.board.map_or(DEFAULT_ENCODER_LINES, |b| b.table.encoder_lines)
    }

    /// The bus the drive is built for, V: the board's `vdc_rated_v`, if the file states it.
    pub fn rated_bus_v(&self) -> Option<f64> {
        self.board.and_then(|b| b.table.vdc_rated_v)
    }
}

impl DriveTables {
    /// Validate everything; errors point at the offending value in `src`.
    pub fn validate(&self, src: &Source<'_>) -> Result<DriveFile, FileError> {
        let dead_time_s = match (self.controller.dead_time_compensation, &self.board) {
            (false, _) => 0.0,
            (true, Some(b)) => b.realised_dead_time_s(),
            (true, None) => {
                return Err(src.error(
                    "controller.dead_time_compensation",
                    "needs the board's dead time: a [board] table with dead_time_s",
                ));
            }
        };
        if let Some(b) = &self.board {
            b.validate_overload(src)?;
        }
        let board = BoardDefaults {
            dead_time_compensation_s: dead_time_s,
            sample_window_s: self.board.map_or(0.0, |b| b.sample_window_s()),
            encoder_lines: self.board.map_or(DEFAULT_ENCODER_LINES, |b| b.encoder_lines),
            inverter_thermal: self.board.and_then(|b| {
                let o = b.inverter_overload?;
                Some(default_inverter_thermal(b.inverter_rated_current_a?, o.factor, o.time_s))
            }),
            current_lsb_a: self.board.map(|b| b.current_a_per_count),
        };
        let spec = drive_spec(src, &self.pwm, &self.motor, &self.controller, &self.protection, &board)?;
        let certify = self.certify.as_ref().map(|c| c.validate(src, &spec)).transpose()?;
        let board = self.board.as_ref().map(|b| b.validate(src, &spec)).transpose()?;
        let requirements = self.requirements.validate(src, spec.pwm_frequency_hz)?;
        // The plant-only tables are checked here too: a bad value is the file's error.
        self.motor.plant_extras(src, "motor")?;
        let saturating_motor = match self.motor.validate_model(src, "motor")? {
            (m, Some(sat)) => Some((m, sat)),
            (_, None) => None,
        };
        Ok(DriveFile { spec, certify, board, requirements, saturating_motor })
    }
}

/// `x` is finite, also in the controller's `f32` (`vdc_max_v = 1e300` was "finite", then
/// infinite in the core and blamed on `controller.current`: found by trying).
fn finite(src: &Source<'_>, key: &str, x: f64) -> Result<(), FileError> {
    src.check(x.is_finite(), key, &format!("is {}; must be a finite number", num(x)))?;
    #[allow(clippy::cast_possible_truncation)] // the question asked: does f32 hold it?
    let in_f32 = (x as f32).is_finite();
    src.check(in_f32, key, &format!("is {}; beyond the controller's f32 range (±{:e})", num(x), f32::MAX))
}

/// Build and validate a [`DriveSpec`] from its tables (a drive file's, or those a scenario
/// file embeds). Errors point at the value.
pub fn drive_spec(
    src: &Source<'_>,
    pwm: &PwmTable,
    motor: &MotorTable,
    c: &ControllerTable,
    protection: &ProtectionTable,
    board: &BoardDefaults,
) -> Result<DriveSpec, FileError> {
    let dead_time_compensation_s = board.dead_time_compensation_s;
    let sample_window_s = board.sample_window_s;
    let (lo, hi) = PWM_FREQUENCY_HZ;
    src.check(
        pwm.frequency_hz.is_finite() && (lo..=hi).contains(&pwm.frequency_hz),
        "pwm.frequency_hz",
        &format!("is {}; must lie in [{lo}, {hi:e}] Hz", num(pwm.frequency_hz)),
    )?;
    src.check(
        (1..=SLOW_DIVIDER_MAX).contains(&pwm.slow_divider),
        "pwm.slow_divider",
        &format!("must lie in 1…{SLOW_DIVIDER_MAX}"),
    )?;
    let motor_table = motor;
    finite(src, "controller.flux_ref_wb", c.flux_ref_wb)?;
    src.check(c.flux_ref_wb > 0.0, "controller.flux_ref_wb", "must be > 0")?;
    let (motor, magnetizing) = motor.drive_model(src, "motor", c.flux_ref_wb)?;
    let current_law = match c.current {
        CurrentTable::Icad { kp: None, ki: None, lag_num: None, lag_den: None } => CurrentLaw::ICAD_EQ20,
        CurrentTable::Icad { kp: Some(kp), ki: Some(ki), lag_num: Some(n), lag_den: Some(d) } => {
            for (i, x) in n.iter().chain(&d).enumerate() {
                let key = if i < 3 { "controller.current.lag_num" } else { "controller.current.lag_den" };
                finite(src, key, *x)?;
            }
            CurrentLaw { kp_v_per_a: kp, ki_v_per_as: ki, lag: Some(ContinuousSection::biquad(n, d)) }
        }
        CurrentTable::Icad { .. } => {
            return Err(src.error(
                "controller.current",
                "`icad` takes either no gains (eq. (20)) or all of kp, ki, lag_num, lag_den",
            ));
        }
        CurrentTable::Pi { kp, ki } => CurrentLaw { kp_v_per_a: kp, ki_v_per_as: ki, lag: None },
    };
    finite(src, "controller.current.kp", current_law.kp_v_per_a)?;
    finite(src, "controller.current.ki", current_law.ki_v_per_as)?;
    let speed_law = match c.speed {
        SpeedTable::SaturatedP { kp, tau_max_nm } => SpeedLaw::SaturatedP { kp, tau_max_nm },
        SpeedTable::PiTorque { kp, ki, limit, setpoint_weight } => {
            SpeedLaw::PiTorque { kp, ki, limit, setpoint_weight }
        }
        SpeedTable::PiIq { kp, ki, limit, setpoint_weight } => {
            SpeedLaw::PiIq { kp, ki, limit, setpoint_weight }
        }
    };
    if let SpeedTable::PiTorque { setpoint_weight: b, .. } | SpeedTable::PiIq { setpoint_weight: b, .. } =
        c.speed
    {
        src.check(
            b.is_finite() && (0.0..=1.0).contains(&b),
            "controller.speed.setpoint_weight",
            &format!("is {}; must be within [0, 1] (1: the one-degree PI)", num(b)),
        )?;
    }
    for (key, x) in [
        ("controller.flux_ref_wb", c.flux_ref_wb),
        ("controller.i_ref_max_a", c.i_ref_max_a),
        ("controller.magnetized_fraction", c.magnetized_fraction),
        ("controller.voltage_margin", c.voltage_margin()),
        ("controller.current_trim_bandwidth_rad_s", c.current_trim_bandwidth_rad_s),
        ("controller.position.k_per_s", c.position.k_per_s),
        ("controller.position.omega_max_rad_s", c.position.omega_max_rad_s),
        ("protection.i_trip_a", protection.i_trip_a),
        ("protection.vdc_min_v", protection.vdc_min_v),
        ("protection.vdc_max_v", protection.vdc_max_v),
    ] {
        finite(src, key, x)?;
    }
    for (key, [min, max], of) in [
        ("controller.rotor_resistance_range", c.rotor_resistance_range, "rr_ohm"),
        ("controller.inductance_range", c.inductance_range, "ls_h, lr_h, lm_h"),
    ] {
        src.check(
            min.is_finite() && max.is_finite() && 0.0 < min && min <= max && max <= RANGE_RATIO_MAX * min,
            key,
            &format!("is [{}, {}]; {}", num(min), num(max), range_need(of)),
        )?;
    }
    if let Some(f) = c.flux_floor_wb {
        finite(src, "controller.flux_floor_wb", f)?;
        src.check(f > 0.0, "controller.flux_floor_wb", "must be > 0")?;
    }
    // The thresholds' ranges are controller-core's (`DriveConfig::new`, which names the
    // field it refuses: mapped to its key below).
    if let Some(b) = protection.brake_chopper {
        // Below where the drive starts cutting its braking torque, or the cut comes first and
        // the chopper takes little (the 3 300 V template's 3 700 V, found by trying).
        let cut_v = controller_core::drive::REGEN_LIMIT_START * protection.vdc_max_v;
        src.check(
            b.off_v.is_finite() && b.on_v.is_finite() && 0.0 < b.off_v && b.off_v < b.on_v && b.on_v < cut_v,
            "protection.brake_chopper",
            &format!(
                "on_v = {}, off_v = {}: need 0 < off_v < on_v < {} V, where the drive starts cutting its \
                 braking torque ({} × protection.vdc_max_v; a chopper switching on at or above it would \
                 take little of the energy)",
                num(b.on_v),
                num(b.off_v),
                num(cut_v),
                controller_core::drive::REGEN_LIMIT_START
            ),
        )?;
    }
    let spec = DriveSpec {
        motor,
        pwm_frequency_hz: pwm.frequency_hz,
        slow_divider: pwm.slow_divider,
        current_law,
        discretization: Discretization::Tustin,
        current_frame: match c.current_frame {
            FrameTable::Stationary => CurrentFrame::Stationary,
            FrameTable::Synchronous => CurrentFrame::Synchronous,
        },
        slip_current: match c.slip_current {
            SlipTable::Measured => controller_core::drive::SlipCurrent::Measured,
            SlipTable::Reference => controller_core::drive::SlipCurrent::Reference,
        },
        current_decoupling: c.current_decoupling,
        speed_law,
        speed_feedback: match c.speed_feedback {
            FeedbackTable::Encoder => SpeedFeedback::Encoder,
            FeedbackTable::Sensorless => SpeedFeedback::Sensorless,
            FeedbackTable::EncoderRideThrough => SpeedFeedback::EncoderRideThrough,
        },
        speed_resolution_rad_s: controller_core::encoder::speed_resolution_rad_s(
            board.encoder_lines,
            f64::from(pwm.slow_divider) / pwm.frequency_hz,
        ),
        control: match c.control {
            ControlTable::Vector => Control::Vector,
            ControlTable::Vhz { ramp_rad_s2, k_u, k_w } => Control::VHz {
                ramp_rad_s2: ramp_rad_s2.unwrap_or_else(|| {
                    controller_core::vhz::default_ramp_rad_s2(&motor, c.flux_ref_wb, c.i_ref_max_a)
                }),
                k_u,
                k_w,
            },
        },
        position: PositionLaw { k_per_s: c.position.k_per_s, omega_max_rad_s: c.position.omega_max_rad_s },
        flux_ref_wb: c.flux_ref_wb,
        flux_floor_wb: c.flux_floor_wb.unwrap_or(0.05 * c.flux_ref_wb),
        i_ref_max_a: c.i_ref_max_a,
        magnetized_fraction: c.magnetized_fraction,
        voltage_margin: c.voltage_margin(),
        current_trim_bandwidth_rad_s: c.current_trim_bandwidth_rad_s,
        dead_time_compensation_s,
        sample_window_s,
        overmodulation: c.overmodulation,
        rotor_resistance_range: c.rotor_resistance_range,
        inductance_range: c.inductance_range,
        magnetizing,
        protection: {
            let basis = DefaultsBasis {
                flux_ref_wb: c.flux_ref_wb,
                i_ref_max_a: c.i_ref_max_a,
                speed_limit_nm: match speed_law {
                    SpeedLaw::SaturatedP { tau_max_nm, .. } => tau_max_nm,
                    SpeedLaw::PiTorque { limit, .. } => limit,
                    SpeedLaw::PiIq { limit, .. } => motor.torque_factor() * c.flux_ref_wb * limit,
                },
                encoder_lines: board.encoder_lines,
                slow_period_s: f64::from(pwm.slow_divider) / pwm.frequency_hz,
                motor_thermal: default_motor_thermal(
                    motor_table.rated_current_a,
                    motor_table.thermal_time_constant_s,
                ),
                inverter_thermal: board.inverter_thermal,
                current_lsb_a: board.current_lsb_a,
            };
            let mut d = protection_with_defaults(
                &motor,
                &basis,
                protection.i_trip_a,
                protection.vdc_min_v,
                protection.vdc_max_v,
            );
            // The stall time's band is the overspeed level's: the file's, if it sets one.
            let overspeed = protection.over(&d).overspeed_rad_s;
            d.stall_time_s =
                default_stall_time_s(&motor, basis.speed_limit_nm, overspeed, basis.slow_period_s);
            protection.over(&d)
        },
    };
    DriveConfig::new(&spec).map_err(|e| match e {
        DriveError::PwmFrequency => src.error(
            "pwm.frequency_hz",
            format!(
                "must be finite, > 0 and leave each period room for the fast interrupt's longest \
                 (below {:.1} kHz on the {:.0} MHz core)",
                controller_core::drive::PWM_FREQUENCY_MAX_HZ / 1e3,
                controller_core::drive::CORE_CLOCK_HZ / 1e6
            ),
        ),
        DriveError::SlowDivider { min } => src.error(
            "pwm.slow_divider",
            format!(
                "must be ≥ {min} at this PWM rate: the slow step's plan is adopted {} period(s) after \
                 its tick (the slow context's time), before the next tick",
                min.saturating_sub(1)
            ),
        ),
        DriveError::Current(e) => src.error("controller.current", format!("rejected: {e}")),
        DriveError::Speed(e) => src.error("controller.speed", format!("rejected: {e}")),
        DriveError::Position(e) => src.error("controller.position", format!("rejected: {e}")),
        DriveError::Ifoc(e) => src.error("controller", format!("IFOC parameters rejected: {e}")),
        DriveError::FluxReference => src.error(
            "controller.flux_ref_wb",
            format!(
                "must be > 0, above controller.flux_floor_wb, and need a magnetizing current ψ*/L_m \
                     below controller.i_ref_max_a = {} A (L_m = {} H)",
                c.i_ref_max_a,
                spec.motor.lm_h()
            ),
        ),
        DriveError::MagnetizedFraction => src.error("controller.magnetized_fraction", "must lie in (0, 1)"),
        DriveError::Magnetizing(_) | DriveError::CurveNotBuilt => src.error("motor.saturation", e.to_string()),
        DriveError::OvermodulationNotBuilt => src.error("controller.overmodulation", e.to_string()),
        DriveError::VoltageMargin => src.error(
            "controller.voltage_margin",
            {
                let six_step = controller_core::drive::SIX_STEP_FUNDAMENTAL;
                if c.overmodulation {
                    format!("must lie in (0, {six_step:.4}] (six-step's fundamental, with controller.overmodulation)")
                } else {
                    format!("must lie in (0, 1] (up to {six_step:.4} with controller.overmodulation = true)")
                }
            },
        ),
        DriveError::RotorResistanceRange => {
            src.error("controller.rotor_resistance_range", range_need("rr_ohm"))
        }
        DriveError::InductanceRange => {
            src.error("controller.inductance_range", range_need("ls_h, lr_h, lm_h"))
        }
        DriveError::DeadTime => {
            src.error("board.dead_time_s", "must be ≥ 0 and below a tenth of the PWM period to compensate it")
        }
        DriveError::SampleWindow if !src.contains("board.sample_window_s") => src.error(
            "board.dead_time_s",
            format!(
                "with pwm.frequency_hz = {} Hz the default sample window (board.sample_window_s is not set: \
                 the dead time + {} s of settling = {} s) leaves the phases a duty below {} \
                 (1 − 2·window·f_pwm − dead time·f_pwm): a shorter dead time, a lower PWM rate, or \
                 board.sample_window_s",
                num(pwm.frequency_hz),
                num(crate::board::DEFAULT_SAMPLE_SETTLE_S),
                num(sample_window_s),
                controller_core::drive::DUTY_MAX_MIN
            ),
        ),
        DriveError::SampleWindow => src.error(
            "board.sample_window_s",
            format!(
                "must be ≥ 0 and leave the phases a duty of at least {} with the dead time's compensation \
                 (1 − 2·window·f_pwm − dead time·f_pwm)",
                controller_core::drive::DUTY_MAX_MIN
            ),
        ),
        // Derived from the board's encoder (lines ≥ 1, the slow period positive).
        DriveError::SpeedResolution => src.error("board.encoder_lines", e.to_string()),
        // Only `DriveConfig::from_raw` returns it.
        DriveError::Raw => src.error("controller", "configuration rejected"),
        DriveError::Observer(e) => src.error(
            "controller.speed_feedback",
            format!(
                "the observer of {:?} at pwm.frequency_hz = {} Hz up to protection.overspeed_rad_s = {:.0} rad/s: {e}",
                match c.speed_feedback {
                    FeedbackTable::EncoderRideThrough => "encoder_ride_through",
                    _ => "sensorless",
                },
                num(pwm.frequency_hz),
                spec.protection.overspeed_rad_s
            ),
        ),
        DriveError::Vhz(e) => src.error("controller.control", e.to_string()),
        DriveError::CurrentTrim => {
            // With its numbers: a slow PWM (`frequency_hz = 1`) reads as a trim too fast.
            let t_slow_s = f64::from(pwm.slow_divider) / pwm.frequency_hz;
            // A default the file does not hold is not the file's error: the slow period is.
            let (trim, limit, d, f, t) = (
                num(c.current_trim_bandwidth_rad_s),
                num(0.1 / t_slow_s),
                pwm.slow_divider,
                num(pwm.frequency_hz),
                num(t_slow_s),
            );
            if src.contains("controller.current_trim_bandwidth_rad_s") {
                src.error(
                    "controller.current_trim_bandwidth_rad_s",
                    format!(
                        "is {trim} rad/s; must be ≥ 0 and below 0.1/T_slow = {limit} rad/s, the slow period \
                         T_slow = pwm.slow_divider/pwm.frequency_hz = {d}/{f} Hz = {t} s"
                    ),
                )
            } else {
                src.error(
                    "pwm.frequency_hz",
                    format!(
                        "the slow period T_slow = pwm.slow_divider/pwm.frequency_hz = {d}/{f} Hz = {t} s is too long \
                         for the default current trim of {trim} rad/s (controller.current_trim_bandwidth_rad_s, not \
                         set, must lie below 0.1/T_slow = {limit} rad/s): a faster slow loop, or a slower trim set \
                         in the file"
                    ),
                )
            }
        }
        // The specification's path is the file's key, but for the current limit.
        DriveError::Protection { field, need } => {
            src.error(if field == "i_ref_max_a" { "controller.i_ref_max_a" } else { field }, need)
        }
        // Checked above, with the file's own words.
        DriveError::BrakeChopper => src.error(
            "protection.brake_chopper",
            format!("need 0 < off_v < on_v < {} × vdc_max_v", controller_core::drive::REGEN_LIMIT_START),
        ),
    })?;
    Ok(spec)
}

/// What an estimate's range needs, × the motor's `of`.
fn range_need(of: &str) -> String {
    format!("needs 0 < min ≤ max ≤ {}·min (× [motor] {of})", num(RANGE_RATIO_MAX))
}
