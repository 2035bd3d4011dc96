//! The `[motor]` table: the T-equivalent circuit per phase, referred to the stator
//! (L_s, L_r self-inductances), and the mechanics.
//!
//! A *motor file* is any TOML file with a `[motor]` table — a motor file proper
//! (`motors/*.toml`), a drive file or a scenario file: every command that takes a motor
//! accepts each of them, and the shipped motors by name ([`BUILTIN`]).

use crate::source::{self, FileError, Source, num};
use controller_core::magnetics::{
    CURVE_POINTS_MAX, CurveError, Form, MagnetizingCurve, MagnetizingTable, Saturation,
};
use controller_core::motor::{MotorError, MotorField, MotorParams};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The equivalent circuit a `[motor]` table is written in (`form`).
#[derive(Debug, Clone, Copy, Deserialize, Serialize, PartialEq, Eq, Default)]
#[serde(rename_all = "snake_case")]
pub enum MotorForm {
    /// The T model: `ls_h`, `lr_h`, `lm_h` (self-inductances and the magnetizing one).
    #[default]
    T,
    /// The Γ model (textbooks, motulator's `InductionMachinePars`): `lm_h` the magnetizing
    /// inductance at the stator terminals (= L_s), `l_sigma_h` the leakage on the rotor
    /// side, `rr_ohm` the Γ rotor resistance.
    Gamma,
    /// The inverse-Γ model (drive vendors, motulator's `InductionMachineInvGammaPars`):
    /// `lm_h` = L_M at the rotor, `l_sigma_h` = L_σ on the stator side, `rr_ohm` = R_R.
    InverseGamma,
}

/// `[motor.saturation]`: the magnetizing branch's curve, either motulator's law
/// `L(ψ) = lm_h/(1 + (beta_per_wb·ψ)^exponent)` or points of the curve (`flux_wb`, the
/// branch's flux, against `current_a`, its current; space-vector peaks, as a no-load test
/// gives them: √2·the phase RMS values).
#[derive(Debug, Clone, Default, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SaturationTable {
    /// β of the law, 1/Wb.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub beta_per_wb: Option<f64>,
    /// S of the law.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub exponent: Option<f64>,
    /// The curve's currents, A (peak).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub current_a: Option<Vec<f64>>,
    /// The curve's fluxes, Wb (peak).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub flux_wb: Option<Vec<f64>>,
}

/// `[motor]` table as written.
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct MotorTable {
    /// The equivalent circuit the values are written in ([`MotorForm`]; T when absent).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub form: Option<MotorForm>,
    /// Stator resistance, Ω.
    pub rs_ohm: f64,
    /// Rotor resistance referred to the stator (in the form's referral), Ω.
    pub rr_ohm: f64,
    /// Stator self-inductance, H (T form).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ls_h: Option<f64>,
    /// Rotor self-inductance, H (T form).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lr_h: Option<f64>,
    /// Magnetising inductance, H (the unsaturated L_u of a saturating branch's law).
    pub lm_h: f64,
    /// The leakage inductance of the Γ and inverse-Γ forms, H.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub l_sigma_h: Option<f64>,
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
    /// The magnetizing branch's saturation (Γ and inverse-Γ forms): the simulated plant's;
    /// the drive's model stays linear at `lm_h`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub saturation: Option<SaturationTable>,
    /// `[motor.iron_loss]`: a resistance across the magnetizing branch — the simulated
    /// plant's only (`plant::saturated`); the drive does not model it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub iron_loss: Option<IronLossTable>,
    /// `[motor.deep_bar]`: a deep-bar rotor — the simulated plant's only
    /// (`plant::DeepBar`); the drive does not model it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub deep_bar: Option<DeepBarTable>,
}

/// `[motor.iron_loss]`.
#[derive(Debug, Clone, Copy, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct IronLossTable {
    /// The resistance across the magnetizing branch, Ω (per phase, in the form's referral).
    pub resistance_ohm: f64,
}

/// `[motor.deep_bar]`: the rotor resistance rises from `rr_ohm` at zero slip to
/// `high_slip_resistance_factor` times it at high slip, centred at `corner_slip_hz`.
#[derive(Debug, Clone, Copy, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct DeepBarTable {
    /// The rotor resistance at high slip over `rr_ohm`, > 1.
    pub high_slip_resistance_factor: f64,
    /// The slip frequency the rise is centred at, Hz.
    pub corner_slip_hz: f64,
}

/// What a `[motor]` table gives the simulated plant beyond its circuit and curve (each
/// optional; [`MotorTable::plant_extras`]).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PlantExtras {
    /// `[motor.iron_loss]`'s resistance, Ω.
    pub iron_loss_ohm: Option<f64>,
    /// `[motor.deep_bar]`.
    pub deep_bar: Option<DeepBarTable>,
}

/// Accepted magnitude of each value. The bounds are wide — from a 10 W servo motor to a
/// 10 MW machine with margin — and exist so that a typo (`1e300`, a value in mH written
/// as H × 1e6) is an input error instead of a simulation that never ends or a design that
/// divides by zero.
pub const RANGES: [(&str, f64, f64, &str); 8] = [
    ("rs_ohm", 1e-5, 1e4, "Ω"),
    ("rr_ohm", 1e-5, 1e4, "Ω"),
    ("ls_h", 1e-6, 1e3, "H"),
    ("lr_h", 1e-6, 1e3, "H"),
    ("lm_h", 1e-6, 1e3, "H"),
    ("l_sigma_h", 1e-7, 1e3, "H"),
    ("j_kgm2", 1e-8, 1e5, "kg·m²"),
    ("b_nms", 0.0, 1e4, "N·m·s/rad"),
];

/// Accepted β of a saturation law, 1/Wb: a knee 1/β from 1 mWb (a 10 W motor's rated flux
/// is ≈ 5 mWb) to 1 kWb (beyond any machine's ≈ 30 Wb: in effect, no saturation).
pub const BETA_PER_WB: [f64; 2] = [1e-3, 1e3];
/// Accepted exponent S of a saturation law: from 1 to 32 (motulator's measured 2.2-kW
/// machine: 7; beyond 32 the law is a hard limit no RK4 step integrates).
pub const EXPONENT: [f64; 2] = [1.0, 32.0];

/// The largest flux a measured curve's point may give, Wb (30 times the largest machine's
/// rated flux), and its largest current, A: beyond them a typo, not a machine.
pub const CURVE_FLUX_MAX_WB: f64 = 1e3;
/// See [`CURVE_FLUX_MAX_WB`].
pub const CURVE_CURRENT_MAX_A: f64 = 1e6;

/// Largest accepted number of pole pairs.
pub const POLE_PAIRS_MAX: u8 = 64;

impl MotorTable {
    /// The table of validated parameters (for writing a motor file): the T form, or the Γ
    /// (inverse-Γ) form when the stator (rotor) leakage is zero — the form that holds them.
    pub fn from_params(m: &MotorParams) -> Self {
        let (form, ls_h, lr_h, l_sigma_h) = if m.ls_h() == m.lm_h() {
            (Some(MotorForm::Gamma), None, None, Some(m.lr_h() - m.lm_h()))
        } else if m.lr_h() == m.lm_h() {
            (Some(MotorForm::InverseGamma), None, None, Some(m.ls_h() - m.lm_h()))
        } else {
            (None, Some(m.ls_h()), Some(m.lr_h()), None)
        };
        Self {
            form,
            rs_ohm: m.rs_ohm(),
            rr_ohm: m.rr_ohm(),
            ls_h,
            lr_h,
            lm_h: m.lm_h(),
            l_sigma_h,
            pole_pairs: m.pole_pairs(),
            j_kgm2: m.j_kgm2(),
            b_nms: m.b_nms(),
            rated_current_a: None,
            thermal_time_constant_s: None,
            saturation: None,
            iron_loss: None,
            deep_bar: None,
        }
    }

    /// The simulated plant's `[motor.iron_loss]` and `[motor.deep_bar]`, each value checked
    /// (errors point at `table.iron_loss.resistance_ohm`, …); whether the form can take them
    /// is the plant's to say.
    pub fn plant_extras(&self, src: &Source<'_>, table: &str) -> Result<PlantExtras, FileError> {
        let check = |ok: bool, key: &str, need: &str| {
            if ok { Ok(()) } else { Err(src.error(&format!("{table}.{key}"), need)) }
        };
        if let Some(t) = &self.iron_loss {
            let r = t.resistance_ohm;
            check(r.is_finite() && r > 0.0, "iron_loss.resistance_ohm", "must be finite and > 0")?;
        }
        if let Some(t) = &self.deep_bar {
            let k = t.high_slip_resistance_factor;
            check(
                k.is_finite() && k > 1.0,
                "deep_bar.high_slip_resistance_factor",
                "must be finite and > 1",
            )?;
            let f = t.corner_slip_hz;
            check(f.is_finite() && f > 0.0, "deep_bar.corner_slip_hz", "must be finite and > 0")?;
        }
        Ok(PlantExtras { iron_loss_ohm: self.iron_loss.map(|t| t.resistance_ohm), deep_bar: self.deep_bar })
    }

    fn value(&self, key: &str) -> Option<f64> {
        match key {
            "rs_ohm" => Some(self.rs_ohm),
            "rr_ohm" => Some(self.rr_ohm),
            "ls_h" => self.ls_h,
            "lr_h" => self.lr_h,
            "lm_h" => Some(self.lm_h),
            "l_sigma_h" => self.l_sigma_h,
            "j_kgm2" => Some(self.j_kgm2),
            _ => Some(self.b_nms),
        }
    }

    /// Validate into [`MotorParams`]; errors point at `table.key` in `src`. A saturating
    /// motor's are its linear T model at `lm_h` (see [`MotorTable::validate_model`]).
    pub fn validate(&self, src: &Source<'_>, table: &str) -> Result<MotorParams, FileError> {
        self.validate_model(src, table).map(|(m, _)| m)
    }

    /// Validate into [`MotorParams`] — the form written as a T model (Γ: L_s = L_m =
    /// `lm_h`, L_r = L_m + `l_sigma_h`; inverse-Γ: L_r = L_m = `lm_h`, L_s = L_m +
    /// `l_sigma_h`), exactly the same machine while linear — and the magnetizing branch's
    /// saturation when the table has one.
    pub fn validate_model(
        &self,
        src: &Source<'_>,
        table: &str,
    ) -> Result<(MotorParams, Option<Saturation>), FileError> {
        let key = |k: &str| format!("{table}.{k}");
        for (k, lo, hi, unit) in RANGES {
            if let Some(x) = self.value(k) {
                src.check(
                    x.is_finite() && x >= lo && x <= hi && (lo > 0.0 || x >= 0.0),
                    &key(k),
                    &format!("is {}; must lie in [{}, {}] {unit}", num(x), num(lo), num(hi)),
                )?;
            }
        }
        src.check(
            (1..=POLE_PAIRS_MAX).contains(&self.pole_pairs),
            &key("pole_pairs"),
            &format!("must lie in 1…{POLE_PAIRS_MAX}"),
        )?;
        for (k, x) in [
            ("rated_current_a", self.rated_current_a),
            ("thermal_time_constant_s", self.thermal_time_constant_s),
        ] {
            if let Some(x) = x {
                src.check(x.is_finite() && x > 0.0 && x <= 1e6, &key(k), "must lie in (0, 1e6]")?;
            }
        }
        src.check(
            self.rated_current_a.is_some() == self.thermal_time_constant_s.is_some(),
            &key("thermal_time_constant_s"),
            "give both rated_current_a and thermal_time_constant_s (the motor's I²t limit), or neither",
        )?;
        let form = self.form.unwrap_or_default();
        let (ls, lr) = match (form, self.ls_h, self.lr_h, self.l_sigma_h) {
            (MotorForm::T, Some(ls), Some(lr), None) => {
                for (k, l) in [("ls_h", ls), ("lr_h", lr)] {
                    src.check(
                        self.lm_h < l,
                        &key("lm_h"),
                        &format!(
                            "L_m = {} H must be below {k} = {l} H (leakage > 0); a motor without stator or rotor \
                             leakage is written in the gamma or inverse_gamma form (form = \"gamma\", lm_h, l_sigma_h)",
                            self.lm_h
                        ),
                    )?;
                }
                (ls, lr)
            }
            (MotorForm::T, ls, _, None) => {
                let missing = if ls.is_none() { "ls_h" } else { "lr_h" };
                return Err(src.error(
                    table,
                    format!("the T form needs {missing} (or write form = \"gamma\" with l_sigma_h)"),
                ));
            }
            (MotorForm::T, _, _, Some(_)) => {
                return Err(src.error(
                    &key("l_sigma_h"),
                    "belongs to the gamma and inverse_gamma forms: write form = \"gamma\" or \"inverse_gamma\", \
                     or give the T form's ls_h and lr_h instead",
                ));
            }
            (_, Some(_), _, _) | (_, _, Some(_), _) => {
                let k = if self.ls_h.is_some() { "ls_h" } else { "lr_h" };
                return Err(src.error(
                    &key(k),
                    format!("belongs to the T form; the {} form takes lm_h and l_sigma_h", form_name(form)),
                ));
            }
            (_, None, None, None) => {
                return Err(src.error(
                    table,
                    format!("the {} form needs l_sigma_h (its leakage inductance)", form_name(form)),
                ));
            }
            (MotorForm::Gamma, None, None, Some(l)) => (self.lm_h, self.lm_h + l),
            (MotorForm::InverseGamma, None, None, Some(l)) => (self.lm_h + l, self.lm_h),
        };
        let params = MotorParams::new(
            self.rs_ohm,
            self.rr_ohm,
            ls,
            lr,
            self.lm_h,
            self.pole_pairs,
            self.j_kgm2,
            self.b_nms,
        )
        .map_err(|e| match e {
            MotorError::NotPositive(f) => src.error(&key(field_key(f)), "must be > 0"),
            MotorError::Leakage => src.error(
                &key("lm_h"),
                "leakage coefficient σ = 1 − L_m²/(L_s·L_r) must lie in (0, 1): need L_m² < L_s·L_r",
            ),
        })?;
        let saturation = match &self.saturation {
            None => None,
            Some(t) => Some(self.saturation_of(t, form, src, table)?),
        };
        Ok((params, saturation))
    }

    /// The motor as a drive runs it at the rotor flux `flux_ref_wb` (issue 50): a linear
    /// motor's T model ([`MotorTable::validate`]) and no table; a saturating motor's T model
    /// with its magnetizing inductance the curve's chord at that flux at no load (where the
    /// branch's flux is the rotor's, in either form) — `L_m`, and `L_s`, `L_r` with it, so
    /// the leakage is the file's — and the curve as the drive's table
    /// ([`MagnetizingTable::of_curve`]). A table the drive cannot run on names
    /// `[motor.saturation]`.
    pub fn drive_model(
        &self,
        src: &Source<'_>,
        table: &str,
        flux_ref_wb: f64,
    ) -> Result<(MotorParams, Option<MagnetizingTable>), FileError> {
        let (m, saturation) = self.validate_model(src, table)?;
        let Some(sat) = saturation else { return Ok((m, None)) };
        let key = format!("{table}.saturation");
        let rated = MagnetizingTable::of_curve(&sat.curve, flux_ref_wb)
            .filter(|(t, i)| t.validate().is_ok() && i.is_finite() && *i > 0.0);
        let Some((t, i_rated_a)) = rated else {
            return Err(src.error(
                &key,
                format!(
                    "the drive cannot run on this curve at controller.flux_ref_wb = {} Wb: its flux must rise \
                     with the current, and no step of it more than twice as steeply as the chord to it, from 0 to \
                     twice the rated flux's magnetizing current",
                    num(flux_ref_wb)
                ),
            ));
        };
        let shift = flux_ref_wb / i_rated_a - m.lm_h();
        let at_rated = MotorParams::new(
            m.rs_ohm(),
            m.rr_ohm(),
            m.ls_h() + shift,
            m.lr_h() + shift,
            m.lm_h() + shift,
            m.pole_pairs(),
            m.j_kgm2(),
            m.b_nms(),
        )
        .map_err(|_| src.error(&key, "its chord at controller.flux_ref_wb leaves no valid T model"))?;
        Ok((at_rated, Some(t)))
    }

    /// The `[motor.saturation]` table as the branch's curve.
    fn saturation_of(
        &self,
        t: &SaturationTable,
        form: MotorForm,
        src: &Source<'_>,
        table: &str,
    ) -> Result<Saturation, FileError> {
        let key = |k: &str| format!("{table}.saturation.{k}");
        let form = match form {
            MotorForm::Gamma => Form::Gamma,
            MotorForm::InverseGamma => Form::InverseGamma,
            MotorForm::T => {
                return Err(src.error(
                    &format!("{table}.saturation"),
                    "needs the gamma or inverse_gamma form: with both leakages the T model does not say which \
                     flux saturates the branch; write the motor in the form its curve was measured in \
                     (form = \"gamma\" for a no-load test at the terminals)",
                ));
            }
        };
        let curve = match (t.beta_per_wb, t.exponent, &t.current_a, &t.flux_wb) {
            (Some(beta), Some(s), None, None) => {
                for (k, x, [lo, hi]) in [("beta_per_wb", beta, BETA_PER_WB), ("exponent", s, EXPONENT)] {
                    src.check(
                        x.is_finite() && (lo..=hi).contains(&x),
                        &key(k),
                        &format!("is {}; must lie in [{}, {}]", num(x), num(lo), num(hi)),
                    )?;
                }
                MagnetizingCurve::law(self.lm_h, beta, s)
                    .map_err(|_| src.error(&key("exponent"), "not a saturation law"))?
            }
            (None, None, Some(i), Some(psi)) => {
                for (k, values, max) in
                    [("flux_wb", psi, CURVE_FLUX_MAX_WB), ("current_a", i, CURVE_CURRENT_MAX_A)]
                {
                    if let Some((n, x)) =
                        values.iter().enumerate().find(|(_, x)| !x.is_finite() || x.abs() > max)
                    {
                        return Err(src.error(
                            &format!("{table}.saturation.{k}[{n}]"),
                            format!("is {}; must lie within ±{}", num(*x), num(max)),
                        ));
                    }
                }
                MagnetizingCurve::points(psi, i).map_err(|e| {
                    match e {
                CurveError::NotRising(k) => src.error(
                    &format!("{table}.saturation.flux_wb[{k}]"),
                    "flux_wb and current_a must both rise strictly from the origin (point 0 after (0, 0))",
                ),
                _ => src.error(
                    &key("flux_wb"),
                    format!("flux_wb and current_a must have the same length, 2…{CURVE_POINTS_MAX} points"),
                ),
                }
                })?
            }
            _ => {
                return Err(src.error(
                    &format!("{table}.saturation"),
                    "give either beta_per_wb and exponent (L = lm_h/(1 + (β·ψ)^S)) or current_a and flux_wb \
                     (points of the curve), not a mix",
                ));
            }
        };
        Ok(Saturation { form, curve })
    }
}

fn form_name(f: MotorForm) -> &'static str {
    match f {
        MotorForm::T => "t",
        MotorForm::Gamma => "gamma",
        MotorForm::InverseGamma => "inverse_gamma",
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
pub const BUILTIN: [(&str, &str); 6] = [
    ("delorenzo-appendix", include_str!("../../motors/delorenzo-appendix.toml")),
    ("delorenzo-eq13", include_str!("../../motors/delorenzo-eq13.toml")),
    ("delorenzo-perturbed", include_str!("../../motors/delorenzo-perturbed.toml")),
    ("krause-2300v-500hp", include_str!("../../motors/krause-2300v-500hp.toml")),
    ("em-synergy-m800006", include_str!("../../motors/em-synergy-m800006.toml")),
    ("delorenzo-saturating", include_str!("../../motors/delorenzo-saturating.toml")),
];

/// Only the `[motor]` table of a file; other tables (a drive's, a scenario's) are ignored.
#[derive(Deserialize)]
struct MotorOnly {
    motor: MotorTable,
}

/// The `[motor]` table of a file's text.
pub fn parse(path: &Path, text: &str) -> Result<MotorParams, FileError> {
    parse_model(path, text).map(|(m, _)| m)
}

/// The `[motor]` table of a file's text, with its magnetizing branch's saturation
/// ([`MotorTable::validate_model`]).
pub fn parse_model(path: &Path, text: &str) -> Result<(MotorParams, Option<Saturation>), FileError> {
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
    raw.motor.validate_model(&src, "motor")
}

/// The `[motor]` table of a file's text as a drive at rotor flux `flux_ref_wb` runs it, if
/// its branch saturates: the chord model there and the curve as the drive's table
/// ([`MotorTable::drive_model`]), with the table as written; `None` for a linear motor.
pub fn drive_model_of(
    path: &Path,
    text: &str,
    flux_ref_wb: f64,
) -> Result<Option<(MotorParams, MagnetizingTable, MotorTable)>, FileError> {
    let src = Source::parse(path, text)?;
    if !src.has("motor") {
        // A scenario that references its drive file, as in `parse_model`.
        return match src.string("drive") {
            Some(drive) => {
                let target = crate::relative_to(path, &drive);
                drive_model_of(&target, &source::read(&target)?, flux_ref_wb)
            }
            None => Ok(None),
        };
    }
    let raw: MotorOnly = src.deserialize()?;
    if raw.motor.saturation.is_none() {
        return Ok(None);
    }
    let (m, table) = raw.motor.drive_model(&src, "motor", flux_ref_wb)?;
    Ok(table.map(|t| (m, t, raw.motor)))
}

fn load_path(path: &Path) -> Result<(MotorParams, Option<Saturation>), FileError> {
    let text = source::read(path)?;
    parse_model(path, &text)
}

/// The text of a shipped motor by name ([`BUILTIN`]), under the path `<builtin name>`, or
/// of a file.
pub fn text_of(name_or_path: &str) -> Result<(std::path::PathBuf, String), FileError> {
    match BUILTIN.iter().find(|(n, _)| *n == name_or_path) {
        Some((name, text)) => Ok((format!("<builtin {name}>").into(), (*text).to_string())),
        None => {
            load(name_or_path)?;
            Ok((name_or_path.into(), source::read(Path::new(name_or_path))?))
        }
    }
}

/// A shipped motor by name ([`BUILTIN`]), or the `[motor]` table of a file.
pub fn load(name_or_path: &str) -> Result<MotorParams, FileError> {
    load_model(name_or_path).map(|(m, _)| m)
}

/// A shipped motor's or a file's `[motor]` table's plant extras ([`MotorTable::plant_extras`];
/// a scenario's, its drive file's motor's). Call after [`load_model`] has read the same name.
pub fn load_plant_extras(name_or_path: &str) -> Result<PlantExtras, FileError> {
    let (path, text) = match BUILTIN.iter().find(|(n, _)| *n == name_or_path) {
        Some((name, text)) => (std::path::PathBuf::from(format!("<builtin {name}>")), (*text).to_string()),
        None => (std::path::PathBuf::from(name_or_path), source::read(Path::new(name_or_path))?),
    };
    plant_extras_of(&path, &text)
}

fn plant_extras_of(path: &Path, text: &str) -> Result<PlantExtras, FileError> {
    let src = Source::parse(path, text)?;
    if !src.has("motor") {
        return match src.string("drive") {
            Some(drive) => {
                let target = crate::relative_to(path, &drive);
                plant_extras_of(&target, &source::read(&target)?)
            }
            None => Ok(PlantExtras::default()),
        };
    }
    let raw: MotorOnly = src.deserialize()?;
    raw.motor.plant_extras(&src, "motor")
}

/// [`load`], with the magnetizing branch's saturation ([`MotorTable::validate_model`]).
pub fn load_model(name_or_path: &str) -> Result<(MotorParams, Option<Saturation>), FileError> {
    if let Some((name, text)) = BUILTIN.iter().find(|(n, _)| *n == name_or_path) {
        return parse_model(Path::new(&format!("<builtin {name}>")), text);
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

    const GAMMA: &str = "[motor]\nform = \"gamma\"\nrs_ohm = 3.7\nrr_ohm = 2.5\nlm_h = 0.34\nl_sigma_h = 0.023\n\
                         pole_pairs = 2\nj_kgm2 = 0.015\nb_nms = 0.0\n";

    fn model(text: &str) -> Result<(MotorParams, Option<Saturation>), FileError> {
        parse_model(Path::new("m.toml"), text)
    }

    /// The Γ and inverse-Γ forms are their T models with the stator (Γ) or the rotor
    /// (inverse-Γ) leakage zero; the law and the points become the branch's curve.
    #[test]
    fn the_gamma_and_inverse_gamma_forms_are_their_t_models() {
        let (m, sat) = model(GAMMA).unwrap();
        assert_eq!((m.ls_h(), m.lr_h(), m.lm_h(), m.rr_ohm()), (0.34, 0.34 + 0.023, 0.34, 2.5));
        assert_eq!(sat, None);
        let inv = GAMMA
            .replace("\"gamma\"", "\"inverse_gamma\"")
            .replace("0.34", "0.224")
            .replace("0.023", "0.021");
        let (m, _) = model(&inv).unwrap();
        assert_eq!((m.ls_h(), m.lr_h(), m.lm_h()), (0.224 + 0.021, 0.224, 0.224));
        let law = format!("{GAMMA}[motor.saturation]\nbeta_per_wb = 0.84\nexponent = 7.0\n");
        let (_, sat) = model(&law).unwrap();
        let want = MagnetizingCurve::law(0.34, 0.84, 7.0).unwrap();
        assert_eq!(sat, Some(Saturation { form: Form::Gamma, curve: want }));
        let points =
            format!("{GAMMA}[motor.saturation]\nflux_wb = [0.5, 1.0, 1.2]\ncurrent_a = [1.6, 3.8, 7.0]\n");
        let (_, sat) = model(&points).unwrap();
        let want = MagnetizingCurve::points(&[0.5, 1.0, 1.2], &[1.6, 3.8, 7.0]).unwrap();
        assert_eq!(sat, Some(Saturation { form: Form::Gamma, curve: want }));
    }

    /// Each contradiction names its key and says what to write instead.
    #[test]
    fn a_form_and_its_keys_must_agree() {
        let err = |text: &str| model(text).unwrap_err();
        // An inverse-Γ machine written as a T (L_r = L_m): the error names the form to use.
        let e = err(&GOOD.replace("lr_h = 1.5", "lr_h = 1.42"));
        assert!(e.key.as_deref() == Some("motor.lm_h") && e.reason.contains("inverse_gamma"), "{e}");
        let e = err(&GOOD.replace("b_nms", "l_sigma_h = 0.01\nb_nms"));
        assert!(e.key.as_deref() == Some("motor.l_sigma_h") && e.reason.contains("form"), "{e}");
        let e = err(&GAMMA.replace("l_sigma_h = 0.023", "l_sigma_h = 0.023\nls_h = 0.36"));
        assert!(e.key.as_deref() == Some("motor.ls_h") && e.reason.contains("gamma"), "{e}");
        let e = err(&GAMMA.replace("l_sigma_h = 0.023\n", ""));
        assert!(e.reason.contains("l_sigma_h"), "{e}");
        let e = err(&GAMMA.replace("l_sigma_h = 0.023", "l_sigma_h = -0.023"));
        assert_eq!(e.key.as_deref(), Some("motor.l_sigma_h"), "{e}");
        let e = err(&GAMMA.replace("\"gamma\"", "\"pi\""));
        assert!(e.to_string().contains("form"), "{e}");
        let sat = |t: &str| format!("{GAMMA}[motor.saturation]\n{t}\n");
        let e = err(&format!("{GOOD}[motor.saturation]\nbeta_per_wb = 0.84\nexponent = 7.0\n"));
        assert!(e.key.as_deref() == Some("motor.saturation") && e.reason.contains("gamma"), "{e}");
        let e = err(&sat("beta_per_wb = 0.84"));
        assert!(e.key.as_deref() == Some("motor.saturation") && e.reason.contains("exponent"), "{e}");
        let e = err(&sat("beta_per_wb = 0.84\nexponent = 7.0\nflux_wb = [1.0, 2.0]"));
        assert!(e.reason.contains("not a mix"), "{e}");
        let e = err(&sat("beta_per_wb = 0.84\nexponent = 0.5"));
        assert_eq!(e.key.as_deref(), Some("motor.saturation.exponent"), "{e}");
        let e = err(&sat("beta_per_wb = -1\nexponent = 7"));
        assert_eq!(e.key.as_deref(), Some("motor.saturation.beta_per_wb"), "{e}");
        // Found by trying: a knee at 1 µWb diverged the run, S = 33.5 refused it as "too
        // stiff" — both now refused by their range, naming the key.
        let e = err(&sat("beta_per_wb = 1e6\nexponent = 7"));
        assert!(
            e.to_string().ends_with("motor.saturation.beta_per_wb: is 1e6; must lie in [0.001, 1000]"),
            "{e}"
        );
        let e = err(&sat("beta_per_wb = 0.84\nexponent = 33.5"));
        assert!(e.to_string().ends_with("motor.saturation.exponent: is 33.5; must lie in [1, 32]"), "{e}");
        let e = err(&sat("flux_wb = [0.5, 1.0, 0.9]\ncurrent_a = [1.0, 2.0, 3.0]"));
        assert_eq!(e.key.as_deref(), Some("motor.saturation.flux_wb[2]"), "{e}");
        let e = err(&sat("flux_wb = [0.5, 1.0]\ncurrent_a = [1.0, 1e308]"));
        assert!(
            e.to_string().ends_with("motor.saturation.current_a[1]: is 1e308; must lie within ±1e6"),
            "{e}"
        );
        let e = err(&sat("flux_wb = [0.5, 1.0]\ncurrent_a = [1.0, 2.0, 3.0]"));
        assert!(e.key.as_deref() == Some("motor.saturation.flux_wb") && e.reason.contains("length"), "{e}");
        let e = err(&sat("beta = 0.84"));
        assert!(e.to_string().contains("beta"), "{e}");
    }

    #[test]
    fn unknown_names_list_the_shipped_motors() {
        let e = load("no-such-motor").unwrap_err();
        assert!(e.to_string().contains("delorenzo-eq13"), "{e}");
        assert!(load("").is_err());
    }
}
