//! `hil-sim envelope`: the drive file's torque–speed envelope measured in software in the
//! loop ([`crate::envelope`]) against the analytic one.

use super::bus_voltage;
use controller_core::drive::Mode;
use report::write::write_text;
use std::path::PathBuf;

/// What `envelope` is asked.
#[derive(Debug, Clone, PartialEq)]
pub struct EnvelopeOptions {
    /// The drive file.
    pub drive: PathBuf,
    /// DC-bus voltage, V (`None`: [`bus_voltage`]'s choice).
    pub vdc: Option<f64>,
    /// Speeds measured, at least 2, evenly from 0.2× to 2× the no-load base speed.
    pub points: u32,
    /// Braking (generating) torque instead of motoring.
    pub generating: bool,
    /// Output directory (`None`: `out/envelope`).
    pub out: Option<PathBuf>,
    /// Simulate this motor (a shipped motor's name or a file with a `[motor]` table, its
    /// saturation included) instead of the drive's own.
    pub plant: Option<String>,
    /// Ask this fraction of the envelope on the drive's voltage target and judge the torque
    /// and flux accuracy ([`crate::envelope::Ask::Fraction`]); `None`: the envelope itself.
    pub torque_fraction: Option<f64>,
}

/// The envelope's acceptance: measured within this fraction of the analytic envelope.
pub const ENVELOPE_TOLERANCE: f64 = 0.05;
/// The accuracy's acceptance (`--torque-fraction`): the torque within this fraction of the
/// torque asked, the rotor flux within it of the drive's reference (issue 50's 5 %).
pub const ACCURACY_TOLERANCE: f64 = 0.05;

/// `hil-sim envelope`: prints the table, writes `envelope.csv`, `envelope.svg` and
/// `summary.json`; `Err` if a point is more than [`ENVELOPE_TOLERANCE`] off or the drive
/// faulted.
pub fn envelope(a: &EnvelopeOptions) -> Result<(), String> {
    if a.points < 2 {
        return Err(format!("{} points: the envelope needs at least 2", a.points));
    }
    let file = drive_file::DriveFile::load(&a.drive).map_err(|e| e.to_string())?;
    let spec = file.spec;
    let vdc = bus_voltage(a.vdc, &file, "the envelope")?;
    let out = a.out.clone().unwrap_or_else(|| PathBuf::from("out/envelope"));
    let base = crate::envelope::drive_base_speed_rad_s(&spec, vdc);
    if base <= 0.0 {
        return Err(format!("the rated flux needs more than the {} V bus has even at standstill", vdc));
    }
    let simulated = super::simulated_motor(a.plant.as_deref(), &file, &a.drive)?;
    // Its physical limit is the circuit's and curve's: a plant with more is refused, not
    // simulated without it.
    if simulated.is_some_and(|p| p.extras != plant::Extras::default()) {
        return Err(format!(
            "{}: the envelope simulates a motor's circuit and curve only; [motor.iron_loss] and [motor.deep_bar] \
             are run by `campaign` and `faults`",
            a.plant.as_deref().map_or_else(|| a.drive.display().to_string(), str::to_string)
        ));
    }
    std::fs::create_dir_all(&out).map_err(|e| format!("cannot create {}: {e}", out.display()))?;
    let n = f64::from(a.points - 1);
    let speeds: Vec<f64> = (0..a.points).map(|k| base * (0.2 + 1.8 * f64::from(k) / n)).collect();
    let sign = if a.generating { -1.0 } else { 1.0 };
    eprintln!(
        "hil-sim: envelope of {} on {} V, {} speeds from {:.1} to {:.1} rad/s (no-load base speed {base:.1} rad/s)",
        a.drive.display(),
        super::volts(vdc),
        speeds.len(),
        speeds.first().copied().unwrap_or(0.0),
        speeds.last().copied().unwrap_or(0.0)
    );
    let (plant, saturation) = simulated.map_or((spec.motor, None), |p| (p.motor, p.saturation));
    let ask = a.torque_fraction.map_or(crate::envelope::Ask::Beyond, crate::envelope::Ask::Fraction);
    let points =
        crate::envelope::measure_asking(&spec, &plant, saturation.as_ref(), vdc, &speeds, sign, ask)?;
    if let Some(f) = a.torque_fraction {
        return accuracy(a, f, &points, vdc, base, &out);
    }
    let mut csv = String::from(
        "omega_m_rad_s,measured_nm,analytic_nm,relative_error,physical_nm,of_physical,ripple_nm,flux_wb,mode,\
         one_phase_unread,phases_unread\n",
    );
    report::outln!(
        "{:>10} {:>12} {:>12} {:>8} {:>12} {:>8} {:>10} {:>8}  {:<22} unread (1 / 2+ phases)",
        "ω (rad/s)",
        "measured",
        "analytic",
        "error",
        "physical",
        "of it",
        "ripple",
        "ψ_r",
        "mode"
    );
    let mut failed = Vec::new();
    for p in &points {
        let e = p.relative_error();
        let of_physical = p.measured_nm / p.physical_nm;
        report::outln!(
            "{:>10.1} {:>10.4} Nm {:>9.4} Nm {:>+7.2}% {:>9.4} Nm {:>8.3} {:>7.4} Nm {:>7.3}  {:<22} {:>5.1} % / {:.2} %",
            p.omega_m_rad_s,
            p.measured_nm,
            p.analytic_nm,
            100.0 * e,
            p.physical_nm,
            of_physical,
            p.ripple_nm,
            p.flux_wb,
            format!("{:?}", p.mode),
            100.0 * p.unsampled_share[0],
            100.0 * p.unsampled_share[1],
        );
        csv.push_str(&format!(
            "{:.4},{:.6},{:.6},{:.6},{:.6},{:.5},{:.6},{:.5},{:?},{:.5},{:.5}\n",
            p.omega_m_rad_s,
            p.measured_nm,
            p.analytic_nm,
            e,
            p.physical_nm,
            of_physical,
            p.ripple_nm,
            p.flux_wb,
            p.mode,
            p.unsampled_share[0],
            p.unsampled_share[1],
        ));
        if e.abs() > ENVELOPE_TOLERANCE || p.mode != Mode::Running {
            failed.push(p.omega_m_rad_s);
        }
    }
    write_text(&out.join("envelope.csv"), &csv)?;
    write_text(
        &out.join("envelope.svg"),
        &crate::envelope::plot(&spec, &plant, saturation.as_ref(), vdc, &points, sign),
    )?;
    let summary = serde_json::json!({
        "drive": a.drive.display().to_string(),
        "vdc_v": vdc,
        "base_speed_rad_s": base,
        "direction": if a.generating { "generating" } else { "motoring" },
        "tolerance": ENVELOPE_TOLERANCE,
        "worst_relative_error": points.iter().map(|p| p.relative_error().abs()).fold(0.0, f64::max),
        "least_of_physical_limit": points.iter().map(|p| p.measured_nm / p.physical_nm).fold(f64::INFINITY, f64::min),
        "points_outside": failed.len(),
    });
    let text = serde_json::to_string_pretty(&summary).map_err(|e| e.to_string())?;
    write_text(&out.join("summary.json"), &format!("{text}\n"))?;
    eprintln!("hil-sim: wrote envelope.csv, envelope.svg, summary.json in {}", out.display());
    if failed.is_empty() {
        Ok(())
    } else {
        Err(format!(
            "{} point(s) more than {:.0} % off the envelope or faulted, at {failed:.1?} rad/s",
            failed.len(),
            100.0 * ENVELOPE_TOLERANCE
        ))
    }
}

/// `--torque-fraction F`: each point's torque against the torque asked and the machine's
/// rotor flux against the drive's reference; `accuracy.csv`, `summary.json` (the worst
/// errors over the points that did not fault, and how many faulted); `Err` if one is more
/// than [`ACCURACY_TOLERANCE`] off or the drive faulted.
fn accuracy(
    a: &EnvelopeOptions,
    fraction: f64,
    points: &[crate::envelope::Point],
    vdc: f64,
    base: f64,
    out: &std::path::Path,
) -> Result<(), String> {
    let mut csv =
        String::from("omega_m_rad_s,asked_nm,measured_nm,torque_error,flux_wb,flux_ref_wb,flux_error,mode\n");
    report::outln!(
        "{:>10} {:>12} {:>12} {:>8} {:>8} {:>8} {:>8}  mode",
        "ω (rad/s)",
        "asked",
        "measured",
        "error",
        "ψ_r",
        "ψ_r*",
        "error"
    );
    let mut failed = Vec::new();
    for p in points {
        let (te, fe) = (p.torque_error(), p.flux_error());
        report::outln!(
            "{:>10.1} {:>9.4} Nm {:>9.4} Nm {:>+7.2}% {:>8.4} {:>8.4} {:>+7.2}%  {:?}",
            p.omega_m_rad_s,
            p.asked_nm,
            p.measured_nm,
            100.0 * te,
            p.flux_wb,
            p.flux_ref_wb,
            100.0 * fe,
            p.mode
        );
        csv.push_str(&format!(
            "{:.4},{:.6},{:.6},{:.6},{:.5},{:.5},{:.6},{:?}\n",
            p.omega_m_rad_s, p.asked_nm, p.measured_nm, te, p.flux_wb, p.flux_ref_wb, fe, p.mode
        ));
        if !(te.abs() <= ACCURACY_TOLERANCE && fe.abs() <= ACCURACY_TOLERANCE) || p.mode != Mode::Running {
            failed.push(p.omega_m_rad_s);
        }
    }
    write_text(&out.join("accuracy.csv"), &csv)?;
    // Over the points that ran: a faulted point has no torque or flux to judge (its
    // errors are −100 % and a division by a zero reference), and is counted apart.
    let running = || points.iter().filter(|p| p.mode == Mode::Running);
    let worst = |f: fn(&crate::envelope::Point) -> f64| running().map(|p| f(p).abs()).fold(0.0, f64::max);
    let summary = serde_json::json!({
        "drive": a.drive.display().to_string(),
        "vdc_v": vdc,
        "base_speed_rad_s": base,
        "direction": if a.generating { "generating" } else { "motoring" },
        "torque_fraction": fraction,
        "tolerance": ACCURACY_TOLERANCE,
        "worst_torque_error": worst(crate::envelope::Point::torque_error),
        "worst_flux_error": worst(crate::envelope::Point::flux_error),
        "faulted": points.len() - running().count(),
        "points_outside": failed.len(),
    });
    let text = serde_json::to_string_pretty(&summary).map_err(|e| e.to_string())?;
    write_text(&out.join("summary.json"), &format!("{text}\n"))?;
    eprintln!("hil-sim: wrote accuracy.csv, summary.json in {}", out.display());
    if failed.is_empty() {
        Ok(())
    } else {
        Err(format!(
            "{} point(s) with the torque or the flux more than {:.0} % off, or faulted, at {failed:.1?} rad/s",
            failed.len(),
            100.0 * ACCURACY_TOLERANCE
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Refused before anything is written: too few points, a drive file that is not there.
    #[test]
    fn bad_options_are_errors() {
        let out = std::env::temp_dir().join(format!("hil-sim-envelope-{}", std::process::id()));
        let options = |points, drive: &str| EnvelopeOptions {
            drive: PathBuf::from(drive),
            vdc: None,
            points,
            generating: false,
            out: Some(out.clone()),
            plant: None,
            torque_fraction: None,
        };
        let e = envelope(&options(1, "drive.toml")).unwrap_err();
        assert!(e.contains("at least 2"), "{e}");
        let e = envelope(&options(3, "no-such-drive.toml")).unwrap_err();
        assert!(e.contains("no-such-drive.toml"), "{e}");
        assert!(!out.exists());
    }

    /// `--torque-fraction`: the shipped drive at half its envelope, two speeds, writes its
    /// accuracy table and summary and passes (its own linear machine: within 0.1 %).
    #[test]
    fn the_accuracy_is_measured_and_judged() {
        let out = std::env::temp_dir().join(format!("hil-sim-accuracy-{}", std::process::id()));
        let a = EnvelopeOptions {
            drive: PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../drive.toml")),
            vdc: None,
            points: 2,
            generating: false,
            out: Some(out.clone()),
            plant: None,
            torque_fraction: Some(0.5),
        };
        envelope(&a).unwrap();
        let csv = std::fs::read_to_string(out.join("accuracy.csv")).unwrap();
        assert_eq!(csv.lines().count(), 3, "{csv}");
        let summary: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
        assert!(summary["worst_torque_error"].as_f64().unwrap() < 1e-3, "{summary}");
        assert!(summary["worst_flux_error"].as_f64().unwrap() < 1e-3, "{summary}");
        assert_eq!(summary["faulted"], 0, "{summary}");
        std::fs::remove_dir_all(&out).unwrap();
    }
}
