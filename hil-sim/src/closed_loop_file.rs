//! Closed-loop scenario files (TOML): a drive (controller choice and gains), the motor the
//! controller is configured for, optionally a different simulated plant, sensors, load and
//! timed events. A file is closed-loop when it has a `[controller]` table.
//!
//! ```toml
//! duration_s = 3.5
//! sample_period_s = 1e-3          # trace sample period (a multiple of the PWM period)
//! pwm_frequency_hz = 20000        # default 20 kHz
//! slow_divider = 10               # speed/position loop every 10th PWM period (default)
//! vdc_v = 310.0
//! rk4_substeps = 1                # default 1 (see tests/substeps.rs)
//!
//! [motor]                          # what the controller is configured for
//! rs_ohm = 16.2                    # … same keys as the open-loop [motor] table
//!
//! # [plant]                        # optional: the simulated machine, if different
//!
//! [controller]
//! current = { kind = "icad" }      # or { kind = "pi", kp = 360.0, ki = 9000.0 }
//! current_frame = "stationary"     # or "synchronous" (d/q loops)
//! speed = { kind = "saturated_p", kp = 0.05, tau_max_nm = 2.0 }
//! #  or { kind = "pi_torque", kp, ki, limit }  |  { kind = "pi_iq", kp, ki, limit }
//! position = { k_per_s = 10.0, omega_max_rad_s = 150.0 }
//! flux_ref_wb = 0.9
//! i_ref_max_a = 4.0
//!
//! [protection]
//! i_trip_a = 8.0
//! vdc_min_v = 200.0
//! vdc_max_v = 400.0
//!
//! [load]                           # optional: "torque" (events only, default),
//! kind = "eddy_brake"              # "eddy_brake" with k_nm_s_rad, "locked_rotor", or
//! k_nm_s_rad = 0.002               # "coulomb_friction" with friction_nm
//!
//! [inverter]                       # optional: "average" (default) or
//! kind = "switching"               # carrier comparison with dead time
//! dead_time_s = 1e-6
//!
//! [sensors]                        # optional, every key defaults to ideal
//! current_lsb_a = 0.00806
//! encoder_lines = 1024
//!
//! [[events]]
//! t_s = 0.0
//! kind = "enable"
//! [[events]]
//! t_s = 0.3
//! kind = "speed"                   # speed (rad/s), position (rad), torque (N·m), load (N·m)
//! value = 150.0                    # or kind = "rotating_current", amplitude_a, omega_rad_s
//! ```

use crate::config::{ConfigError, MotorFile};
use crate::inverter::InverterModel;
use crate::scenario::Builtin;
use crate::sensors::SensorModel;
use crate::sim::{Event, LoadModel, Scenario};
use controller_core::current::CurrentLaw;
use controller_core::discretize::Discretization;
use controller_core::drive::{
    CurrentFrame, DriveConfig, DriveError, DriveSpec, PositionLaw, Protection, Reference,
};
use controller_core::speed::SpeedLaw;
use serde::Deserialize;
use std::path::Path;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    duration_s: f64,
    sample_period_s: f64,
    #[serde(default = "default_pwm")]
    pwm_frequency_hz: f64,
    #[serde(default = "default_divider")]
    slow_divider: u16,
    vdc_v: f64,
    #[serde(default = "default_substeps")]
    rk4_substeps: u32,
    motor: MotorFile,
    plant: Option<MotorFile>,
    controller: ControllerFile,
    protection: ProtectionFile,
    load: Option<LoadFile>,
    inverter: Option<InverterFile>,
    #[serde(default)]
    sensors: SensorsFile,
    events: Vec<EventFile>,
}

/// Default PWM frequency, Hz.
pub fn default_pwm() -> f64 {
    20_000.0
}
/// Default slow-loop divider.
pub fn default_divider() -> u16 {
    10
}
fn default_substeps() -> u32 {
    1
}
fn default_magnetized() -> f64 {
    0.95
}
fn default_position() -> PositionFile {
    PositionFile { k_per_s: 10.0, omega_max_rad_s: 100.0 }
}

/// `[controller]` table.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ControllerFile {
    current: CurrentFile,
    #[serde(default)]
    current_frame: FrameFile,
    speed: SpeedFile,
    #[serde(default = "default_position")]
    position: PositionFile,
    flux_ref_wb: f64,
    flux_floor_wb: Option<f64>,
    i_ref_max_a: f64,
    #[serde(default = "default_magnetized")]
    magnetized_fraction: f64,
}

#[derive(Debug, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
enum CurrentFile {
    Icad,
    Pi { kp: f64, ki: f64 },
}

#[derive(Debug, Default, Deserialize)]
#[serde(rename_all = "snake_case")]
enum FrameFile {
    #[default]
    Stationary,
    Synchronous,
}

#[derive(Debug, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
enum SpeedFile {
    SaturatedP { kp: f64, tau_max_nm: f64 },
    PiTorque { kp: f64, ki: f64, limit: f64 },
    PiIq { kp: f64, ki: f64, limit: f64 },
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct PositionFile {
    k_per_s: f64,
    omega_max_rad_s: f64,
}

/// `[protection]` table.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProtectionFile {
    i_trip_a: f64,
    vdc_min_v: f64,
    vdc_max_v: f64,
}

#[derive(Debug, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
enum LoadFile {
    Torque,
    EddyBrake { k_nm_s_rad: f64 },
    LockedRotor,
    CoulombFriction { friction_nm: f64 },
}

#[derive(Debug, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
enum InverterFile {
    Average,
    Switching { dead_time_s: f64 },
}

#[derive(Debug, Deserialize)]
#[serde(default, deny_unknown_fields)]
struct SensorsFile {
    current_lsb_a: f64,
    current_offset_a: [f64; 3],
    current_gain: [f64; 3],
    current_noise_rms_a: f64,
    vdc_lsb_v: f64,
    encoder_lines: Option<u32>,
    seed: u64,
}

impl Default for SensorsFile {
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
    Speed,
    Position,
    Torque,
    Load,
    RotatingCurrent,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct EventFile {
    t_s: f64,
    kind: EventKind,
    value: Option<f64>,
    amplitude_a: Option<f64>,
    omega_rad_s: Option<f64>,
}

/// Build and validate the drive of a file from its `pwm_frequency_hz`, `slow_divider`,
/// `[motor]`, `[controller]` and `[protection]` tables (shared with the gains file of
/// `design certify`). Errors name the key.
pub fn drive_spec(
    file: &Path,
    pwm_frequency_hz: f64,
    slow_divider: u16,
    motor: &MotorFile,
    c: &ControllerFile,
    protection: &ProtectionFile,
) -> Result<DriveSpec, ConfigError> {
    let err =
        |key: &str, reason: String| ConfigError { file: file.to_path_buf(), key: Some(key.into()), reason };
    let motor = motor.to_params(file, "motor")?;
    let current_law = match c.current {
        CurrentFile::Icad => CurrentLaw::ICAD_EQ20,
        CurrentFile::Pi { kp, ki } => CurrentLaw { kp_v_per_a: kp, ki_v_per_as: ki, lag: None },
    };
    let speed_law = match c.speed {
        SpeedFile::SaturatedP { kp, tau_max_nm } => SpeedLaw::SaturatedP { kp, tau_max_nm },
        SpeedFile::PiTorque { kp, ki, limit } => SpeedLaw::PiTorque { kp, ki, limit },
        SpeedFile::PiIq { kp, ki, limit } => SpeedLaw::PiIq { kp, ki, limit },
    };
    let spec = DriveSpec {
        motor,
        pwm_frequency_hz,
        slow_divider,
        current_law,
        discretization: Discretization::Tustin,
        current_frame: match c.current_frame {
            FrameFile::Stationary => CurrentFrame::Stationary,
            FrameFile::Synchronous => CurrentFrame::Synchronous,
        },
        speed_law,
        position: PositionLaw { k_per_s: c.position.k_per_s, omega_max_rad_s: c.position.omega_max_rad_s },
        flux_ref_wb: c.flux_ref_wb,
        flux_floor_wb: c.flux_floor_wb.unwrap_or(0.05 * c.flux_ref_wb),
        i_ref_max_a: c.i_ref_max_a,
        magnetized_fraction: c.magnetized_fraction,
        protection: Protection {
            i_trip_a: protection.i_trip_a,
            vdc_min_v: protection.vdc_min_v,
            vdc_max_v: protection.vdc_max_v,
        },
    };
    DriveConfig::new(&spec).map_err(|e| {
        let (key, reason) = match e {
            DriveError::PwmFrequency => ("pwm_frequency_hz", "must be finite and > 0".into()),
            DriveError::SlowDivider => ("slow_divider", "must be ≥ 1".into()),
            DriveError::Current(e) => ("controller.current", format!("rejected: {e:?}")),
            DriveError::Speed(e) => ("controller.speed", format!("rejected: {e:?}")),
            DriveError::Position(e) => ("controller.position", format!("rejected: {e:?}")),
            DriveError::Ifoc(e) => ("controller", format!("IFOC parameters rejected: {e:?}")),
            DriveError::FluxReference => {
                ("controller.flux_ref_wb", "must be finite, > 0 and above flux_floor_wb".into())
            }
            DriveError::MagnetizedFraction => ("controller.magnetized_fraction", "must lie in (0, 1)".into()),
            DriveError::Protection => (
                "protection",
                "need 0 ≤ vdc_min_v < vdc_max_v and i_trip_a > controller.i_ref_max_a > 0".into(),
            ),
        };
        err(key, reason)
    })?;
    Ok(spec)
}

/// Is `text` a closed-loop scenario (has a `[controller]` table)?
pub fn is_closed_loop(text: &str) -> bool {
    text.parse::<toml::Table>().map(|t| t.contains_key("controller")).unwrap_or(false)
}

/// Parse and validate a closed-loop scenario read from `file`.
pub fn parse(file: &Path, text: &str) -> Result<Builtin, ConfigError> {
    let err =
        |key: &str, reason: String| ConfigError { file: file.to_path_buf(), key: Some(key.into()), reason };
    let f: File = crate::config::from_toml(file, text)?;
    let positive = |key: &str, x: f64| {
        if x.is_finite() && x > 0.0 { Ok(()) } else { Err(err(key, "must be finite and > 0".into())) }
    };
    positive("duration_s", f.duration_s)?;
    positive("pwm_frequency_hz", f.pwm_frequency_hz)?;
    positive("vdc_v", f.vdc_v)?;
    positive("sample_period_s", f.sample_period_s)?;
    let periods = f.sample_period_s * f.pwm_frequency_hz;
    if periods < 0.999 || (periods - periods.round()).abs() > 1e-6 * periods {
        return Err(err(
            "sample_period_s",
            format!("must be a whole number of PWM periods (is {periods:.4})"),
        ));
    }
    if f.rk4_substeps == 0 {
        return Err(err("rk4_substeps", "must be ≥ 1".into()));
    }
    let spec = drive_spec(file, f.pwm_frequency_hz, f.slow_divider, &f.motor, &f.controller, &f.protection)?;
    let plant = match &f.plant {
        Some(p) => p.to_params(file, "plant")?,
        None => spec.motor,
    };
    let mut events = Vec::with_capacity(f.events.len());
    for (n, e) in f.events.iter().enumerate() {
        let key = |k: &str| format!("events[{n}].{k}");
        if !(e.t_s.is_finite() && e.t_s >= 0.0) {
            return Err(err(&key("t_s"), "must be finite and ≥ 0".into()));
        }
        let value = || match e.value {
            Some(v) if v.is_finite() => Ok(v as f32),
            _ => {
                Err(err(&key("value"), format!("kind `{:?}` needs a finite `value`", e.kind).to_lowercase()))
            }
        };
        let ev = match e.kind {
            EventKind::Enable => Event::Enable,
            EventKind::Speed => Event::Reference(Reference::Speed(value()?)),
            EventKind::Position => Event::Reference(Reference::Position(value()?)),
            EventKind::Torque => Event::Reference(Reference::Torque(value()?)),
            EventKind::Load => Event::LoadNm(f64::from(value()?)),
            EventKind::RotatingCurrent => match (e.amplitude_a, e.omega_rad_s) {
                (Some(a), Some(w)) if a.is_finite() && w.is_finite() => {
                    Event::Reference(Reference::RotatingCurrent {
                        amplitude_a: a as f32,
                        omega_rad_s: w as f32,
                    })
                }
                _ => {
                    return Err(err(
                        &key("kind"),
                        "`rotating_current` needs finite `amplitude_a` and `omega_rad_s`".into(),
                    ));
                }
            },
        };
        events.push((e.t_s, ev));
    }
    if events.windows(2).any(|w| w.first().map(|a| a.0) > w.get(1).map(|b| b.0)) {
        return Err(err("events", "must be in time order".into()));
    }
    let load = match f.load {
        None | Some(LoadFile::Torque) => LoadModel::Torque,
        Some(LoadFile::EddyBrake { k_nm_s_rad }) => {
            if !(k_nm_s_rad.is_finite() && k_nm_s_rad >= 0.0) {
                return Err(err("load.k_nm_s_rad", "must be finite and ≥ 0".into()));
            }
            LoadModel::EddyBrake { k_nm_s_rad }
        }
        Some(LoadFile::LockedRotor) => LoadModel::LockedRotor,
        Some(LoadFile::CoulombFriction { friction_nm }) => {
            if !(friction_nm.is_finite() && friction_nm >= 0.0) {
                return Err(err("load.friction_nm", "must be finite and ≥ 0".into()));
            }
            LoadModel::CoulombFriction { friction_nm }
        }
    };
    let s = &f.sensors;
    let finite = s.current_lsb_a.is_finite() && s.current_noise_rms_a.is_finite() && s.vdc_lsb_v.is_finite();
    if !(finite && s.current_lsb_a >= 0.0 && s.current_noise_rms_a >= 0.0 && s.vdc_lsb_v >= 0.0) {
        return Err(err("sensors", "resolutions and noise must be finite and ≥ 0".into()));
    }
    if s.encoder_lines == Some(0) {
        return Err(err("sensors.encoder_lines", "must be ≥ 1".into()));
    }
    let sensors = SensorModel {
        current_lsb_a: s.current_lsb_a,
        current_offset_a: s.current_offset_a,
        current_gain: s.current_gain,
        current_noise_rms_a: s.current_noise_rms_a,
        vdc_lsb_v: s.vdc_lsb_v,
        encoder_lines: s.encoder_lines,
        seed: s.seed,
    };
    let inverter = match f.inverter {
        None | Some(InverterFile::Average) => InverterModel::Average,
        Some(InverterFile::Switching { dead_time_s }) => {
            if !(dead_time_s.is_finite() && dead_time_s >= 0.0 && dead_time_s < 0.5 / f.pwm_frequency_hz) {
                return Err(err(
                    "inverter.dead_time_s",
                    "must be finite, ≥ 0 and below half the PWM period".into(),
                ));
            }
            InverterModel::Switching { dead_time_s }
        }
    };
    let stem = file.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    Ok(Builtin {
        name: stem,
        about: format!("closed-loop scenario file {}", file.display()),
        spec,
        plant,
        scenario: Scenario {
            events,
            duration_s: f.duration_s,
            vdc_v: f.vdc_v,
            substeps: f.rk4_substeps,
            trace_every: periods.round() as u32,
            sensors,
            load,
            inverter,
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const FIG16: &str = include_str!("../scenarios/fig16-icad.toml");

    fn err(text: &str) -> ConfigError {
        parse(Path::new("c.toml"), text).unwrap_err()
    }

    #[test]
    fn shipped_file_equals_builtin() {
        assert!(is_closed_loop(FIG16));
        let f = parse(Path::new("fig16-icad.toml"), FIG16).unwrap();
        let b = crate::scenario::fig16_icad().unwrap();
        assert_eq!(f.spec, b.spec);
        assert_eq!(f.plant, b.plant);
        assert_eq!(f.scenario, b.scenario);
    }

    #[test]
    fn errors_name_file_key_and_reason() {
        let e = err(&FIG16.replace("flux_ref_wb = 0.35", "flux_ref_wb = 0.35\nflux_gain = 2"));
        assert!(e.to_string().starts_with("c.toml:") && e.to_string().contains("flux_gain"), "{e}");
        let e = err(&FIG16.replace("i_trip_a = 8.0", "i_trip_a = 3.0"));
        assert_eq!(e.key.as_deref(), Some("protection"));
        let e = err(&FIG16.replace("kind = \"speed\"\nvalue = 376.0", "kind = \"speed\""));
        assert_eq!(e.key.as_deref(), Some("events[1].value"));
        let e = err(&FIG16.replace("sample_period_s = 1e-3", "sample_period_s = 1.23e-4"));
        assert_eq!(e.key.as_deref(), Some("sample_period_s"));
        let e = err(&FIG16.replace("tau_max_nm = 0.4", "tau_max_nm = -0.4"));
        assert_eq!(e.key.as_deref(), Some("controller.speed"));
        let e = err(&FIG16.replace("kind = \"icad\"", "kind = \"lqr\""));
        assert!(e.to_string().contains("lqr"), "{e}");
        let e = err(&FIG16.replace("t_s = 0.3", "t_s = -1.0"));
        assert_eq!(e.key.as_deref(), Some("events[1].t_s"));
    }

    #[test]
    fn coulomb_friction_load() {
        let with = |load: &str| format!("{FIG16}\n[load]\n{load}\n");
        let f = parse(Path::new("c.toml"), &with("kind = \"coulomb_friction\"\nfriction_nm = 0.05")).unwrap();
        assert_eq!(f.scenario.load, LoadModel::CoulombFriction { friction_nm: 0.05 });
        let e = err(&with("kind = \"coulomb_friction\"\nfriction_nm = -0.05"));
        assert_eq!(e.key.as_deref(), Some("load.friction_nm"));
        let e = err(&with("kind = \"coulomb_friction\""));
        assert!(e.to_string().contains("friction_nm"), "{e}");
    }
}
