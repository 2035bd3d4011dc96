//! Scenario files (TOML).
//!
//! Open-loop voltage-source runs validate the plant alone:
//!
//! ```toml
//! duration_s = 1.0
//! sample_period_s = 1e-4
//!
//! [motor]          # per-phase values referred to the stator; L_s, L_r are self-inductances
//! rs_ohm = 16.2
//! rr_ohm = 23.2
//! ls_h = 1.44
//! lr_h = 1.5
//! lm_h = 1.42
//! pole_pairs = 1
//! j_kgm2 = 0.005
//! b_nms = 0.0005
//!
//! [source]
//! kind = "sine"
//! amplitude_v = 180.0   # phase peak
//! frequency_hz = 50.0
//!
//! [load]
//! kind = "constant"
//! torque_nm = 0.0
//! ```
//!
//! Closed-loop files (with a `[controller]` table) are described in
//! [`crate::closed_loop_file`]. Unknown keys and bad values are errors naming the file, the key
//! and the reason.

use controller_core::motor::{MotorError, MotorField, MotorParams};
use serde::Deserialize;
use std::fmt;
use std::path::{Path, PathBuf};

/// A scenario-file error: file, key and reason.
#[derive(Debug, Clone, PartialEq)]
pub struct ConfigError {
    /// The file.
    pub file: PathBuf,
    /// The offending key (dotted path), if known.
    pub key: Option<String>,
    /// What is wrong.
    pub reason: String,
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.key {
            Some(k) => write!(f, "{}: key `{k}`: {}", self.file.display(), self.reason),
            None => write!(f, "{}: {}", self.file.display(), self.reason),
        }
    }
}

impl std::error::Error for ConfigError {}

/// `[motor]` table.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct MotorFile {
    /// Stator resistance, Ω.
    pub rs_ohm: f64,
    /// Rotor resistance referred to the stator, Ω.
    pub rr_ohm: f64,
    /// Stator self-inductance, H.
    pub ls_h: f64,
    /// Rotor self-inductance, H.
    pub lr_h: f64,
    /// Magnetising inductance, H.
    pub lm_h: f64,
    /// Pole pairs.
    pub pole_pairs: u8,
    /// Inertia, kg·m².
    pub j_kgm2: f64,
    /// Viscous friction, N·m·s/rad.
    pub b_nms: f64,
}

impl MotorFile {
    /// Validate into [`MotorParams`]; errors name the key under `prefix`.
    pub fn to_params(&self, file: &Path, prefix: &str) -> Result<MotorParams, ConfigError> {
        MotorParams::new(
            self.rs_ohm,
            self.rr_ohm,
            self.ls_h,
            self.lr_h,
            self.lm_h,
            self.pole_pairs,
            self.j_kgm2,
            self.b_nms,
        )
        .map_err(|e| {
            let (key, reason) = match e {
                MotorError::NotPositive(f) => {
                    let key = match f {
                        MotorField::RsOhm => "rs_ohm",
                        MotorField::RrOhm => "rr_ohm",
                        MotorField::LsH => "ls_h",
                        MotorField::LrH => "lr_h",
                        MotorField::LmH => "lm_h",
                        MotorField::PolePairs => "pole_pairs",
                        MotorField::JKgm2 => "j_kgm2",
                        MotorField::BNms => "b_nms",
                    };
                    let why =
                        if key == "b_nms" { "must be finite and ≥ 0" } else { "must be finite and > 0" };
                    (key, why.to_string())
                }
                MotorError::Leakage => (
                    "lm_h",
                    "leakage coefficient σ = 1 − Lm²/(Ls·Lr) must lie in (0, 1): need Lm² < Ls·Lr"
                        .to_string(),
                ),
            };
            ConfigError { file: file.to_path_buf(), key: Some(format!("{prefix}.{key}")), reason }
        })
    }
}

/// `[source]` table: an ideal voltage source (open-loop runs).
#[derive(Debug, Clone, Copy, Deserialize, PartialEq)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum SourceFile {
    /// Balanced sine: v_α = A cos 2πft, v_β = A sin 2πft (A = phase peak).
    Sine {
        /// Phase peak voltage, V.
        amplitude_v: f64,
        /// Frequency, Hz.
        frequency_hz: f64,
    },
}

/// `[load]` table.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum LoadFile {
    /// Constant load torque, N·m (positive opposes positive rotation).
    Constant {
        /// Load torque, N·m.
        torque_nm: f64,
    },
}

/// A scenario file.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ScenarioFile {
    /// Simulated time, s.
    pub duration_s: f64,
    /// Trace sample period, s.
    pub sample_period_s: f64,
    /// Motor.
    pub motor: MotorFile,
    /// Voltage source (open loop).
    pub source: SourceFile,
    /// Load (default: none).
    #[serde(default)]
    pub load: Option<LoadFile>,
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
    /// Phase peak voltage, V.
    pub amplitude_v: f64,
    /// Source frequency, Hz.
    pub frequency_hz: f64,
    /// Load torque, N·m.
    pub load_nm: f64,
}

/// Deserialize TOML `text` read from `file`; syntax errors, unknown keys and type errors
/// become a [`ConfigError`] that carries toml's line/column excerpt.
pub fn from_toml<T: serde::de::DeserializeOwned>(file: &Path, text: &str) -> Result<T, ConfigError> {
    toml::from_str(text).map_err(|e| ConfigError {
        file: file.to_path_buf(),
        key: None,
        reason: e.to_string().trim_end().replace('\n', "\n    "),
    })
}

fn check(file: &Path, key: &str, ok: bool, reason: &str) -> Result<(), ConfigError> {
    if ok {
        Ok(())
    } else {
        Err(ConfigError { file: file.to_path_buf(), key: Some(key.to_string()), reason: reason.to_string() })
    }
}

/// Parse and validate scenario text read from `file`.
pub fn parse(file: &Path, text: &str) -> Result<OpenLoop, ConfigError> {
    let raw: ScenarioFile = from_toml(file, text)?;
    check(file, "duration_s", raw.duration_s.is_finite() && raw.duration_s > 0.0, "must be finite and > 0")?;
    check(
        file,
        "sample_period_s",
        raw.sample_period_s.is_finite() && raw.sample_period_s > 0.0 && raw.sample_period_s <= raw.duration_s,
        "must be finite, > 0 and ≤ duration_s",
    )?;
    let motor = raw.motor.to_params(file, "motor")?;
    let SourceFile::Sine { amplitude_v, frequency_hz } = raw.source;
    check(
        file,
        "source.amplitude_v",
        amplitude_v.is_finite() && amplitude_v >= 0.0,
        "must be finite and ≥ 0",
    )?;
    check(file, "source.frequency_hz", frequency_hz.is_finite(), "must be finite")?;
    let load_nm = match raw.load {
        Some(LoadFile::Constant { torque_nm }) => {
            check(file, "load.torque_nm", torque_nm.is_finite(), "must be finite")?;
            torque_nm
        }
        None => 0.0,
    };
    Ok(OpenLoop {
        duration_s: raw.duration_s,
        sample_period_s: raw.sample_period_s,
        motor,
        amplitude_v,
        frequency_hz,
        load_nm,
    })
}

/// A scenario file of either kind.
#[derive(Debug, Clone)]
pub enum ScenarioFileKind {
    /// Plant fed by an ideal source (`[source]`).
    OpenLoop(OpenLoop),
    /// Drive against the plant (`[controller]`, see [`crate::closed_loop_file`]).
    ClosedLoop(Box<crate::scenario::Builtin>),
}

/// Read, parse and validate a scenario file of either kind.
pub fn load(file: &Path) -> Result<ScenarioFileKind, ConfigError> {
    let text = std::fs::read_to_string(file).map_err(|e| ConfigError {
        file: file.to_path_buf(),
        key: None,
        reason: format!("cannot read: {e}"),
    })?;
    if crate::closed_loop_file::is_closed_loop(&text) {
        crate::closed_loop_file::parse(file, &text).map(|b| ScenarioFileKind::ClosedLoop(Box::new(b)))
    } else {
        parse(file, &text).map(ScenarioFileKind::OpenLoop)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r#"
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

    fn err(text: &str) -> ConfigError {
        parse(Path::new("s.toml"), text).unwrap_err()
    }

    #[test]
    fn good_file_parses() {
        let s = parse(Path::new("s.toml"), GOOD).unwrap();
        assert_eq!(s.load_nm, 0.5);
        assert_eq!(s.motor.pole_pairs(), 1);
    }

    #[test]
    fn unknown_key_is_named() {
        let e = err(&GOOD.replace("rs_ohm = 16.2", "rs_ohm = 16.2\nrs_ohms = 1.0"));
        let msg = e.to_string();
        assert!(msg.starts_with("s.toml:") && msg.contains("rs_ohms"), "{msg}");
        let e = err(&GOOD.replace("frequency_hz = 50.0", "frequency_hz = 50.0\nphase_deg = 3"));
        assert!(e.to_string().contains("phase_deg"), "{e}");
    }

    #[test]
    fn bad_values_name_the_key_and_reason() {
        let e = err(&GOOD.replace("rr_ohm = 23.2", "rr_ohm = -1.0"));
        assert_eq!(e.key.as_deref(), Some("motor.rr_ohm"));
        assert!(e.to_string().contains("must be finite and > 0"));
        let e = err(&GOOD.replace("lm_h = 1.42", "lm_h = 1.6"));
        assert_eq!(e.key.as_deref(), Some("motor.lm_h"));
        let e = err(&GOOD.replace("duration_s = 0.5", "duration_s = 0.0"));
        assert_eq!(e.key.as_deref(), Some("duration_s"));
        let e = err(&GOOD.replace("kind = \"sine\"", "kind = \"square\""));
        assert!(e.to_string().contains("square"), "{e}");
        let e = err(&GOOD.replace("sample_period_s = 1e-3", "sample_period_s = 2.0"));
        assert_eq!(e.key.as_deref(), Some("sample_period_s"));
        let e = err(&GOOD.replace("torque_nm = 0.5", "torque_nm = nan"));
        assert_eq!(e.key.as_deref(), Some("load.torque_nm"));
    }
}
