//! Motor files shipped with hil-sim (`hil-sim/motors/*.toml`, a bare `[motor]` table each;
//! the comments in each file say where every number comes from).

use crate::config::{ConfigError, MotorFile};
use controller_core::motor::MotorParams;
use std::path::Path;

/// `(name, TOML text)` of every shipped motor.
pub const BUILTIN: [(&str, &str); 4] = [
    ("delorenzo-appendix", include_str!("../motors/delorenzo-appendix.toml")),
    ("delorenzo-eq13", include_str!("../motors/delorenzo-eq13.toml")),
    ("delorenzo-perturbed", include_str!("../motors/delorenzo-perturbed.toml")),
    ("krause-2300v-500hp", include_str!("../motors/krause-2300v-500hp.toml")),
];

/// Parse a motor table; errors name `file` and the key.
pub fn parse(file: &Path, text: &str) -> Result<MotorParams, ConfigError> {
    let raw: MotorFile = crate::config::from_toml(file, text)?;
    raw.to_params(file, "motor")
}

/// A shipped motor by name, or a motor file by path.
pub fn load(name_or_path: &str) -> Result<MotorParams, ConfigError> {
    if let Some((name, text)) = BUILTIN.iter().find(|(n, _)| *n == name_or_path) {
        return parse(Path::new(&format!("<builtin {name}>")), text);
    }
    let path = Path::new(name_or_path);
    let text = std::fs::read_to_string(path).map_err(|e| ConfigError {
        file: path.to_path_buf(),
        key: None,
        reason: format!("cannot read: {e}"),
    })?;
    parse(path, &text)
}

#[cfg(test)]
mod tests {
    use super::*;
    use controller_core::motor::MotorError;

    /// Every shipped file loads; the eq. (13) set reproduces the printed matrix entries (its
    /// G_M,min is checked in `design`, next to eq. (19)).
    #[test]
    fn motor_files_load_and_eq13_entries() {
        for (name, _) in BUILTIN {
            load(name).unwrap();
        }
        let (app, eq13) = (load("delorenzo-appendix").unwrap(), load("delorenzo-eq13").unwrap());
        let s_ls = eq13.sigma() * eq13.ls_h();
        let a11 = -(eq13.lr_h().powi(2) * eq13.rs_ohm() + eq13.lm_h().powi(2) * eq13.rr_ohm())
            / (s_ls * eq13.lr_h().powi(2));
        for (got, printed) in [
            (1.0 / s_ls, 9.7),
            (a11, -359.2),
            (eq13.lm_h() * eq13.rr_ohm() / (s_ls * eq13.lr_h().powi(2)), 141.8),
            (eq13.lm_h() / (s_ls * eq13.lr_h()), 9.2),
            (eq13.lm_h() * eq13.rr_ohm() / eq13.lr_h(), 21.9),
            (eq13.rr_ohm() / eq13.lr_h(), 15.4),
        ] {
            assert!((got - printed).abs() < 0.006 * printed.abs(), "{got} vs {printed}");
        }
        // The appendix set misses σLs by ≈ 7 %.
        let s_ls_app = app.sigma() * app.ls_h();
        assert!(((1.0 / s_ls_app) / 9.7 - 1.0 - 0.076).abs() < 0.01);
    }

    /// The hand-typed files equal their definitions: the appendix set is the core's
    /// `MotorParams::delorenzo_dl10115a1()`, the perturbed set is Sec. VIII's factors on it.
    #[test]
    fn files_match_their_definitions() {
        let app = MotorParams::delorenzo_dl10115a1().unwrap();
        assert_eq!(load("delorenzo-appendix").unwrap(), app);
        let p = load("delorenzo-perturbed").unwrap();
        for (got, want) in [
            (p.rs_ohm(), 2.0 * app.rs_ohm()),
            (p.rr_ohm(), 2.0 * app.rr_ohm()),
            (p.ls_h(), 0.6 * app.ls_h()),
            (p.lr_h(), 0.6 * app.lr_h()),
            (p.lm_h(), 0.59 * app.lm_h()),
        ] {
            assert!((got - want).abs() < 1e-12 * want, "{got} vs {want}");
        }
        assert_eq!((p.pole_pairs(), p.j_kgm2(), p.b_nms()), (app.pole_pairs(), app.j_kgm2(), app.b_nms()));
    }

    #[test]
    fn table2_read_literally_is_not_a_machine() {
        // Seed 000 Table 2 as printed: Ls = Lr = 0.0032 H < Lm = 0.143 H.
        assert_eq!(
            MotorParams::new(0.262, 0.187, 0.0032, 0.0032, 0.143, 4, 11.06, 0.0),
            Err(MotorError::Leakage)
        );
        let k = load("krause-2300v-500hp").unwrap();
        assert!((k.ls_h() - k.lm_h() - 0.0032).abs() < 1e-12);
    }
}
