//! The tuned values written into the template, in place, with what changed.

use super::*;

/// The template's tables with `[motor]`, the gains and `[certify]`'s box and writable
/// ranges replaced (comments are not kept: the header says where the file came from).
/// The template `template_text` with the tuned values written into it, and what changed.
///
/// Edited in place (`toml_edit`): the template's comments, order and layout stay; a value
/// tune sets keeps the comment after it, unless it is a law table whose `kind` changed (the
/// comment described the template's law). Each value that differs from the template's —
/// compared as numbers, not as text — is listed as `key: old → new` (`(absent)` where the
/// template did not state it), and each key a new law drops as `key: old → (removed)`.
pub(super) fn write(
    template_text: &str,
    template_path: &Path,
    spec: &DriveSpec,
    saturating: Option<&drive_file::motor::MotorTable>,
    cert: &CertifySpec,
    omega_c: f64,
    speed_origin: &str,
) -> Result<(String, Vec<String>), String> {
    use toml_edit::{Array, DocumentMut, Value};
    // A tuned file used as the template: its header described the last tune, not this one.
    let body = match template_text.strip_prefix(HEADER_START) {
        Some(rest) => {
            rest.split_once(HEADER_END).map_or(template_text, |(_, after)| after.trim_start_matches('\n'))
        }
        None => template_text,
    };
    let mut doc: DocumentMut = body.parse().map_err(|e| format!("{}: {e}", template_path.display()))?;
    let mut changes = Vec::new();
    let float = |x: f64| Value::from(x);
    let pair = |p: [f64; 2]| Value::Array(p.into_iter().map(float).collect::<Array>());
    let m = &spec.motor;
    match saturating {
        Some(t) => write_saturating(&mut doc, t, &mut changes)?,
        None => write_linear(&mut doc, m, &mut changes)?,
    }
    let law = &spec.current_law;
    let mut current = vec![
        ("kind", Value::from(if law.lag.is_some() { "icad" } else { "pi" })),
        ("kp", float(law.kp_v_per_a)),
        ("ki", float(law.ki_v_per_as)),
    ];
    let triple = |p: [f64; 3]| Value::Array(p.into_iter().map(float).collect::<Array>());
    if let Some(lag) = &law.lag {
        current.push(("lag_num", triple(lag.num)));
        current.push(("lag_den", triple(lag.den)));
    }
    let speed = match spec.speed_law {
        SpeedLaw::SaturatedP { kp, tau_max_nm } => {
            vec![("kind", Value::from("saturated_p")), ("kp", float(kp)), ("tau_max_nm", float(tau_max_nm))]
        }
        SpeedLaw::PiTorque { kp, ki, limit, setpoint_weight } => vec![
            ("kind", Value::from("pi_torque")),
            ("kp", float(kp)),
            ("ki", float(ki)),
            ("limit", float(limit)),
            ("setpoint_weight", float(setpoint_weight)),
        ],
        SpeedLaw::PiIq { .. } => return Err("internal: tune does not write an i_q speed law".into()),
    };
    let position = [
        ("k_per_s", float(spec.position.k_per_s)),
        ("omega_max_rad_s", float(spec.position.omega_max_rad_s)),
    ];
    let controller =
        doc.get_mut("controller").and_then(|c| c.as_table_like_mut()).ok_or("no [controller] table")?;
    let frame = match spec.current_frame {
        CurrentFrame::Stationary => "stationary",
        CurrentFrame::Synchronous => "synchronous",
    };
    set_law(controller, "controller.current", &current, &mut changes)?;
    set_value(controller, "controller", "current_frame", Value::from(frame), &mut changes);
    let slip = match spec.slip_current {
        SlipCurrent::Reference => "reference",
        SlipCurrent::Measured => "measured",
    };
    set_value(controller, "controller", "slip_current", Value::from(slip), &mut changes);
    set_law(controller, "controller.speed", &speed, &mut changes)?;
    set_value(
        controller,
        "controller",
        "rotor_resistance_range",
        pair(spec.rotor_resistance_range),
        &mut changes,
    );
    set_value(controller, "controller", "inductance_range", pair(spec.inductance_range), &mut changes);
    set_law(controller, "controller.position", &position, &mut changes)?;
    let certify = [
        ("rs_factor", pair(cert.rs_factor)),
        ("rr_factor", pair(cert.rr_factor)),
        ("inductance_factor", pair(cert.inductance_factor)),
        ("j_factor", pair(cert.j_factor)),
        ("speed_kp_writable", pair(cert.speed_kp_writable)),
        ("speed_tau_max_nm_writable", pair(cert.speed_tau_max_nm_writable)),
    ];
    set_keys(&mut doc, "certify", &certify, &mut changes)?;
    let speed_loop = match spec.speed_law {
        SpeedLaw::SaturatedP { .. } => format!("saturated-P speed loop,\n# {speed_origin}"),
        _ => format!("PI speed loop,\n# {speed_origin}"),
    };
    let current = if law.lag.is_some() {
        "ICAD current loops (seed 002\n# eq. (20)'s placement scaled to the top rotor speed, the gain the most robust over the box)"
    } else {
        "PI current loops with their zero\n# on the stator's pole (the fastest the certificate passes on every corner)"
    };
    Ok((
        format!(
            "{HEADER_START} from the template {} (design::tune): {frame}-frame {current},\n\
             # crossover {omega_c:.0} rad/s on the nominal motor; {speed_loop}{HEADER_END}{doc}",
            template_path.display()
        ),
        changes,
    ))
}

/// `[motor]` as the tuned linear motor `m`: the T form unless it has no rotor leakage (the
/// inverse-Γ form: L_r = L_m) or no stator leakage (the Γ form: L_s = L_m), which the T form
/// refuses; the keys of the other forms, and a saturation the linear model does not take, go.
fn write_linear(
    doc: &mut toml_edit::DocumentMut,
    m: &MotorParams,
    changes: &mut Vec<String>,
) -> Result<(), String> {
    use toml_edit::Value;
    let float = |x: f64| Value::from(x);
    // The tuned motor is linear (`MotorParams`), written in the T form unless it has no
    // rotor leakage (the inverse-Γ form: L_r = L_m) or no stator leakage (the Γ form:
    // L_s = L_m), which the T form refuses; the keys of the other forms, and the saturation
    // the linear model does not take, go.
    let (form, leakage_h, gone) = if m.lr_h() == m.lm_h() {
        (Some("inverse_gamma"), m.ls_h() - m.lm_h(), ["ls_h", "lr_h", "saturation"])
    } else if m.ls_h() == m.lm_h() {
        (Some("gamma"), m.lr_h() - m.lm_h(), ["ls_h", "lr_h", "saturation"])
    } else {
        (None, 0.0, ["form", "l_sigma_h", "saturation"])
    };
    let mut motor = vec![("rs_ohm", float(m.rs_ohm())), ("rr_ohm", float(m.rr_ohm()))];
    match form {
        Some(f) => motor.extend([("form", Value::from(f)), ("l_sigma_h", float(leakage_h))]),
        None => motor.extend([("ls_h", float(m.ls_h())), ("lr_h", float(m.lr_h()))]),
    }
    motor.extend([("lm_h", float(m.lm_h())), ("j_kgm2", float(m.j_kgm2())), ("b_nms", float(m.b_nms()))]);
    motor.push(("pole_pairs", Value::from(i64::from(m.pole_pairs()))));
    if let Some(t) = doc.get_mut("motor").and_then(|t| t.as_table_like_mut()) {
        for key in gone {
            if let Some(old) = t.remove(key) {
                let old = old.as_value().map_or_else(|| "a table".to_string(), bare);
                changes.push(format!("motor.{key}: {old} → (removed)"));
            }
        }
    }
    set_keys(doc, "motor", &motor, changes)
}

/// `[motor]` as the saturating motor file's table `t` has it — form, values and
/// `[motor.saturation]` — the keys of the other forms gone.
fn write_saturating(
    doc: &mut toml_edit::DocumentMut,
    t: &drive_file::motor::MotorTable,
    changes: &mut Vec<String>,
) -> Result<(), String> {
    let written: toml_edit::DocumentMut = toml::to_string(t)
        .map_err(|e| format!("internal: the motor table: {e}"))?
        .parse()
        .map_err(|e| format!("internal: the motor table: {e}"))?;
    let motor = doc
        .entry("motor")
        .or_insert_with(toml_edit::table)
        .as_table_like_mut()
        .ok_or("[motor] is not a table")?;
    let keys: Vec<String> = motor.iter().map(|(k, _)| k.to_string()).collect();
    for key in keys {
        // Tune sets what the motor file states; the template's thermal keys stay unless the
        // motor file states them too.
        let thermal = matches!(key.as_str(), "rated_current_a" | "thermal_time_constant_s");
        if !written.contains_key(&key)
            && !thermal
            && let Some(old) = motor.remove(&key)
        {
            let old = old.as_value().map_or_else(|| "a table".to_string(), bare);
            changes.push(format!("motor.{key}: {old} → (removed)"));
        }
    }
    for (key, item) in written.iter() {
        match item.as_value() {
            Some(v) => set_value(motor, "motor", key, v.clone(), changes),
            None => {
                let new = item.clone();
                let differs = motor.get(key).is_none_or(|old| old.to_string() != new.to_string());
                if differs {
                    changes.push(format!("motor.{key}: the motor file's"));
                    motor.insert(key, new);
                }
            }
        }
    }
    Ok(())
}

/// The first words of the header `design tune` writes …
pub(super) const HEADER_START: &str = "# Tuned by `design tune`";
/// … and its last.
pub(super) const HEADER_END: &str = ". `design certify` this file.\n";

/// The value's text without its decoration (the comment and spaces around it).
pub(super) fn bare(v: &toml_edit::Value) -> String {
    let mut v = v.clone();
    v.decor_mut().clear();
    if let Some(t) = v.as_inline_table_mut() {
        t.fmt();
    }
    v.to_string()
}

/// The same value: numbers compared as numbers (a template's `2` is the tuned `2.0`),
/// arrays element by element, anything else by its text.
pub(super) fn same(a: &toml_edit::Value, b: &toml_edit::Value) -> bool {
    let number = |v: &toml_edit::Value| v.as_float().or_else(|| v.as_integer().map(|i| i as f64));
    match (a, b) {
        (toml_edit::Value::Array(x), toml_edit::Value::Array(y)) => {
            x.len() == y.len() && x.iter().zip(y.iter()).all(|(p, q)| same(p, q))
        }
        _ => match (number(a), number(b)) {
            (Some(x), Some(y)) => x == y,
            _ => bare(a) == bare(b),
        },
    }
}

/// `table.key = new`, the old value's comment kept; a change listed as `path.key: old → new`.
pub(super) fn set_value(
    table: &mut dyn toml_edit::TableLike,
    path: &str,
    key: &str,
    new: toml_edit::Value,
    changes: &mut Vec<String>,
) {
    match table.get_mut(key).and_then(|i| i.as_value_mut()) {
        Some(old) if same(old, &new) => {}
        Some(old) => {
            changes.push(format!("{path}.{key}: {} → {}", bare(old), bare(&new)));
            let decor = old.decor().clone();
            *old = new;
            *old.decor_mut() = decor;
        }
        None => {
            changes.push(format!("{path}.{key}: (absent) → {}", bare(&new)));
            table.insert(key, toml_edit::Item::Value(new));
        }
    }
}

/// The keys `values` of the top-level table `name` (made if the template has none).
pub(super) fn set_keys(
    doc: &mut toml_edit::DocumentMut,
    name: &str,
    values: &[(&str, toml_edit::Value)],
    changes: &mut Vec<String>,
) -> Result<(), String> {
    let table = doc
        .entry(name)
        .or_insert_with(toml_edit::table)
        .as_table_like_mut()
        .ok_or_else(|| format!("[{name}] is not a table"))?;
    for (key, v) in values {
        set_value(table, name, key, v.clone(), changes);
    }
    Ok(())
}

/// A law's table `path` (`controller.speed`: its last part the key in `parent`) with
/// exactly the keys `values`: an inline table stays inline, a table stays a table; the
/// keys another law had are removed; the comment after an inline table is kept unless the
/// law's `kind` changed.
pub(super) fn set_law(
    parent: &mut dyn toml_edit::TableLike,
    path: &str,
    values: &[(&str, toml_edit::Value)],
    changes: &mut Vec<String>,
) -> Result<(), String> {
    let key = path.rsplit('.').next().unwrap_or(path);
    let item = parent.entry(key).or_insert(toml_edit::Item::None);
    if item.is_none() {
        *item = toml_edit::Item::Value(toml_edit::Value::InlineTable(toml_edit::InlineTable::new()));
    }
    let kind_changed =
        match (item.get("kind").and_then(|k| k.as_str()), values.iter().find(|(k, _)| *k == "kind")) {
            (Some(old), Some((_, new))) => new.as_str() != Some(old),
            _ => false,
        };
    if kind_changed && let Some(v) = item.as_value_mut() {
        v.decor_mut().clear();
    }
    let table = item.as_table_like_mut().ok_or_else(|| format!("`{path}` is not a table"))?;
    let stale: Vec<String> =
        table.iter().map(|(k, _)| k.to_string()).filter(|k| !values.iter().any(|(v, _)| v == k)).collect();
    for k in stale {
        if let Some(old) = table.remove(&k) {
            let old = old.as_value().map_or_else(|| "a table".to_string(), bare);
            changes.push(format!("{path}.{k}: {old} → (removed)"));
        }
    }
    for (k, v) in values {
        set_value(table, path, k, v.clone(), changes);
    }
    if let Some(t) = item.as_inline_table_mut() {
        t.fmt();
    }
    Ok(())
}
