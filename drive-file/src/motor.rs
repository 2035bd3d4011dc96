//! The `[motor]` table: the T-equivalent circuit per phase, referred to the stator
//! (L_s, L_r self-inductances), and the mechanics.
//!
//! A *motor file* is any TOML file with a `[motor]` table — a motor file proper
//! (`motors/*.toml`), a drive file or a scenario file: every command that takes a motor
//! accepts each of them, and the shipped motors by name ([`BUILTIN`]).

use crate::source::{self, FileError, Source, num};
use controller_core::motor::{MotorError, MotorField, MotorParams};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// `[motor]` table as written.
#[derive(Debug, Clone, Copy, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct MotorTable {
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
    /// Rated (nameplate) RMS phase current, A (optional: with the thermal time constant,
    /// the default motor I²t limit, `drive::default_motor_thermal`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rated_current_a: Option<f64>,
    /// Thermal time constant of the winding, s (optional, see `rated_current_a`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub thermal_time_constant_s: Option<f64>,
}

/// Accepted magnitude of each value. The bounds are wide — from a 10 W servo motor to a
/// 10 MW machine with margin — and exist so that a typo (`1e300`, a value in mH written
/// as H × 1e6) is an input error instead of a simulation that never ends or a design that
/// divides by zero.
pub const RANGES: [(&str, f64, f64, &str); 7] = [
    ("rs_ohm", 1e-5, 1e4, "Ω"),
    ("rr_ohm", 1e-5, 1e4, "Ω"),
    ("ls_h", 1e-6, 1e3, "H"),
    ("lr_h", 1e-6, 1e3, "H"),
    ("lm_h", 1e-6, 1e3, "H"),
    ("j_kgm2", 1e-8, 1e5, "kg·m²"),
    ("b_nms", 0.0, 1e4, "N·m·s/rad"),
];

/// Largest accepted number of pole pairs.
pub const POLE_PAIRS_MAX: u8 = 64;

impl MotorTable {
    /// The table of validated parameters (for writing a motor file).
    pub fn from_params(m: &MotorParams) -> Self {
        Self {
            rs_ohm: m.rs_ohm(),
            rr_ohm: m.rr_ohm(),
            ls_h: m.ls_h(),
            lr_h: m.lr_h(),
            lm_h: m.lm_h(),
            pole_pairs: m.pole_pairs(),
            j_kgm2: m.j_kgm2(),
            b_nms: m.b_nms(),
            rated_current_a: None,
            thermal_time_constant_s: None,
        }
    }

    fn value(&self, key: &str) -> f64 {
        match key {
            "rs_ohm" => self.rs_ohm,
            "rr_ohm" => self.rr_ohm,
            "ls_h" => self.ls_h,
            "lr_h" => self.lr_h,
            "lm_h" => self.lm_h,
            "j_kgm2" => self.j_kgm2,
            _ => self.b_nms,
        }
    }

    /// Validate into [`MotorParams`]; errors point at `table.key` in `src`.
    pub fn validate(&self, src: &Source<'_>, table: &str) -> Result<MotorParams, FileError> {
        for (key, lo, hi, unit) in RANGES {
            let x = self.value(key);
            src.check(
                x.is_finite() && x >= lo && x <= hi && (lo > 0.0 || x >= 0.0),
                &format!("{table}.{key}"),
                &format!("is {}; must lie in [{}, {}] {unit}", num(x), num(lo), num(hi)),
            )?;
        }
        src.check(
            (1..=POLE_PAIRS_MAX).contains(&self.pole_pairs),
            &format!("{table}.pole_pairs"),
            &format!("must lie in 1…{POLE_PAIRS_MAX}"),
        )?;
        for (key, x) in [
            ("rated_current_a", self.rated_current_a),
            ("thermal_time_constant_s", self.thermal_time_constant_s),
        ] {
            if let Some(x) = x {
                src.check(
                    x.is_finite() && x > 0.0 && x <= 1e6,
                    &format!("{table}.{key}"),
                    "must lie in (0, 1e6]",
                )?;
            }
        }
        src.check(
            self.rated_current_a.is_some() == self.thermal_time_constant_s.is_some(),
            &format!("{table}.thermal_time_constant_s"),
            "give both rated_current_a and thermal_time_constant_s (the motor's I²t limit), or neither",
        )?;
        for (key, l) in [("ls_h", self.ls_h), ("lr_h", self.lr_h)] {
            src.check(
                self.lm_h < l,
                &format!("{table}.lm_h"),
                &format!("L_m = {} H must be below {key} = {l} H (leakage > 0)", self.lm_h),
            )?;
        }
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
        .map_err(|e| match e {
            MotorError::NotPositive(f) => src.error(&format!("{table}.{}", field_key(f)), "must be > 0"),
            MotorError::Leakage => src.error(
                &format!("{table}.lm_h"),
                "leakage coefficient σ = 1 − L_m²/(L_s·L_r) must lie in (0, 1): need L_m² < L_s·L_r",
            ),
        })
    }
}

fn field_key(f: MotorField) -> &'static str {
    match f {
        MotorField::RsOhm => "rs_ohm",
        MotorField::RrOhm => "rr_ohm",
        MotorField::LsH => "ls_h",
        MotorField::LrH => "lr_h",
        MotorField::LmH => "lm_h",
        MotorField::PolePairs => "pole_pairs",
        MotorField::JKgm2 => "j_kgm2",
        MotorField::BNms => "b_nms",
    }
}

/// `(name, TOML text)` of every shipped motor (`motors/*.toml`; the comments in each file
/// say where every number comes from).
pub const BUILTIN: [(&str, &str); 5] = [
    ("delorenzo-appendix", include_str!("../../motors/delorenzo-appendix.toml")),
    ("delorenzo-eq13", include_str!("../../motors/delorenzo-eq13.toml")),
    ("delorenzo-perturbed", include_str!("../../motors/delorenzo-perturbed.toml")),
    ("krause-2300v-500hp", include_str!("../../motors/krause-2300v-500hp.toml")),
    ("em-synergy-m800006", include_str!("../../motors/em-synergy-m800006.toml")),
];

/// Only the `[motor]` table of a file; other tables (a drive's, a scenario's) are ignored.
#[derive(Deserialize)]
struct MotorOnly {
    motor: MotorTable,
}

/// The `[motor]` table of a file's text.
pub fn parse(path: &Path, text: &str) -> Result<MotorParams, FileError> {
    let src = Source::parse(path, text)?;
    if !src.has("motor") {
        // A scenario that references its drive file: the motor is that file's.
        if let Some(drive) = src.string("drive") {
            let target = crate::relative_to(path, &drive);
            return load_path(&target);
        }
        return Err(FileError::file(path, "no [motor] table (a motor, drive or scenario file has one)"));
    }
    let raw: MotorOnly = src.deserialize()?;
    raw.motor.validate(&src, "motor")
}

fn load_path(path: &Path) -> Result<MotorParams, FileError> {
    let text = source::read(path)?;
    parse(path, &text)
}

/// A shipped motor by name ([`BUILTIN`]), or the `[motor]` table of a file.
pub fn load(name_or_path: &str) -> Result<MotorParams, FileError> {
    if let Some((name, text)) = BUILTIN.iter().find(|(n, _)| *n == name_or_path) {
        return parse(Path::new(&format!("<builtin {name}>")), text);
    }
    if name_or_path.is_empty() {
        return Err(FileError::file(Path::new(""), "empty motor name"));
    }
    load_path(Path::new(name_or_path)).map_err(|e| {
        if e.at.is_none() && !Path::new(name_or_path).exists() {
            let names: Vec<_> = BUILTIN.iter().map(|(n, _)| *n).collect();
            FileError::file(
                Path::new(name_or_path),
                format!("neither a file nor a shipped motor ({})", names.join(", ")),
            )
        } else {
            e
        }
    })
}

/// The text of a motor file holding `m`, headed by `comment` (each line prefixed `# `).
pub fn to_toml(m: &MotorParams, comment: &str) -> Result<String, String> {
    #[derive(Serialize)]
    struct File {
        motor: MotorTable,
    }
    let body = toml::to_string(&File { motor: MotorTable::from_params(m) }).map_err(|e| e.to_string())?;
    let head: String = comment.lines().map(|l| format!("# {l}\n")).collect();
    Ok(format!("{head}{body}"))
}

/// The no-load base speed on the bus `vdc_v`, electrical rad/s: where the motor's back-EMF
/// at the flux reference reaches the modulator's linear limit, `ω_e = (V_dc/√3) / ψ_s` with
/// the stator flux `ψ_s ≈ ψ_r*·L_s/L_m` at no load. Up to it the drive runs at full flux on
/// any bus it accepts when `vdc_v` is the lowest (`protection.vdc_min_v`).
pub fn no_load_base_speed_el_rad_s(
    motor: &controller_core::motor::MotorParams,
    flux_ref_wb: f64,
    vdc_v: f64,
) -> f64 {
    let psi_s_wb = flux_ref_wb * motor.ls_h() / motor.lm_h();
    (vdc_v / 3f64.sqrt()) / psi_s_wb
}

#[cfg(test)]
mod tests {
    use super::*;

    fn motor_err(text: &str) -> FileError {
        parse(Path::new("m.toml"), text).unwrap_err()
    }

    const GOOD: &str = "[motor]\nrs_ohm = 16.2\nrr_ohm = 23.2\nls_h = 1.44\nlr_h = 1.5\nlm_h = 1.42\n\
                        pole_pairs = 1\nj_kgm2 = 0.005\nb_nms = 0.0005\n";

    #[test]
    fn shipped_motors_load_and_round_trip() {
        for (name, _) in BUILTIN {
            let m = load(name).unwrap();
            let text = to_toml(&m, "round trip").unwrap();
            assert_eq!(parse(Path::new("rt.toml"), &text).unwrap(), m, "{name}");
        }
        assert_eq!(parse(Path::new("m.toml"), GOOD).unwrap(), load("delorenzo-appendix").unwrap());
    }

    /// Issue 16: range errors point at the value (file:line:column: key: reason).
    #[test]
    fn range_errors_point_at_the_value() {
        let e = motor_err(&GOOD.replace("rs_ohm = 16.2", "rs_ohm = -16.2"));
        assert_eq!(e.to_string(), "m.toml:2:10: motor.rs_ohm: is -16.2; must lie in [1e-5, 10000] Ω");
        // The value that made `design startup-fit` hang.
        let e = motor_err(&GOOD.replace("rs_ohm = 16.2", "rs_ohm = 1e300"));
        assert_eq!((e.at, e.key.as_deref()), (Some((2, 10)), Some("motor.rs_ohm")), "{e}");
        let e = motor_err(&GOOD.replace("lm_h = 1.42", "lm_h = 1.45"));
        assert_eq!((e.at, e.key.as_deref()), (Some((6, 8)), Some("motor.lm_h")), "{e}");
        assert!(e.reason.contains("ls_h"), "{e}");
        let e = motor_err(&GOOD.replace("lm_h = 1.42", "lm_h = nan"));
        assert_eq!(e.key.as_deref(), Some("motor.lm_h"), "{e}");
        let e = motor_err(&GOOD.replace("pole_pairs = 1", "pole_pairs = 0"));
        assert_eq!(e.key.as_deref(), Some("motor.pole_pairs"), "{e}");
        let e = motor_err(&GOOD.replace("pole_pairs = 1", "pole_pairs = 300"));
        assert_eq!(e.key.as_deref(), Some("motor.pole_pairs"), "{e}");
        let e = motor_err(&GOOD.replace("j_kgm2", "j_kg"));
        assert!(e.reason.contains("j_kg") && e.at == Some((8, 1)), "{e}");
        assert!(motor_err("x = 1").reason.contains("no [motor] table"));
        // σ < 1 is the last check: L_m² < L_s·L_r with L_m below both always holds.
        assert!(parse(Path::new("m.toml"), &GOOD.replace("lm_h = 1.42", "lm_h = 1.4399")).is_ok());
    }

    #[test]
    fn unknown_names_list_the_shipped_motors() {
        let e = load("no-such-motor").unwrap_err();
        assert!(e.to_string().contains("delorenzo-eq13"), "{e}");
        assert!(load("").is_err());
    }
}
