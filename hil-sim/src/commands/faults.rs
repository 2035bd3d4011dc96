//! `hil-sim faults`: the fault-injection matrix of a drive file ([`crate::faults`]), its
//! table, and with `--trace` each selected row's trace.

use super::{INTERRUPTED, bus_voltage};
use crate::sim::Row;
use crate::trace::{make_out_dir, stream_trace, unmake_out_dir};
use controller_core::frames::{Abc, AlphaBeta};
use report::write::write_text;
use std::path::{Path, PathBuf};

/// What `faults` is asked.
#[derive(Debug, Clone, PartialEq)]
pub struct FaultsOptions {
    /// A drive file (its `[certify]` omega_r_max_rad_s sets the top speed, if it has one).
    pub drive: PathBuf,
    /// DC-bus voltage, V (`None`: [`bus_voltage`]'s choice).
    pub vdc: Option<f64>,
    /// Output directory (`None`: `out/faults`).
    pub out: Option<PathBuf>,
    /// Every fault injected this long after its time in the matrix, ms.
    pub inject_delay_ms: f64,
    /// Another draw of the sensors' noise and offsets (0: the matrix's own).
    pub seed: u64,
    /// Only the rows whose name contains this text (any case).
    pub only: Option<String>,
    /// Also write each row's trace into `OUT/rows/<row>/` ([`trace_fault_row`]).
    pub trace: bool,
    /// Simulate this motor (a shipped motor's name or a file with a `[motor]` table, its
    /// saturation included) instead of the drive's own.
    pub plant: Option<String>,
}

/// The most rows `hil-sim faults --trace` writes (each trace ≈ 3 MB of CSV).
pub const MAX_TRACED_ROWS: usize = 12;
/// `--trace` starts this long before the injection (or an earlier fault), s.
pub const TRACE_LEAD_S: f64 = 0.05;

/// A row's name as a directory name: lower case, every run of other characters one `-`.
fn slug(name: &str) -> String {
    let mut s = String::new();
    for c in name.chars() {
        if c.is_ascii_alphanumeric() {
            s.push(c.to_ascii_lowercase());
        } else if !s.ends_with('-') {
            s.push('-');
        }
    }
    s.trim_matches('-').to_string()
}

/// One fault row's run again, traced from [`TRACE_LEAD_S`] before its injection — or before
/// the fault its first run latched earlier (`tripped_before_s`: a failed row) — into
/// `out/trace.csv` (atomic, as `run`'s), with `phases.svg` (the three phase currents and
/// their references), `speed.svg` and `torque.svg`.
pub fn trace_fault_row(
    m: &crate::faults::Matrix,
    row: &crate::faults::RowSpec,
    tripped_before_s: Option<f64>,
    out: &Path,
) -> Result<(), String> {
    use report::plot::{Series, line_plot};
    let (k, case, at) = row;
    let b = m.scenario(*k, case, at);
    let from_s = tripped_before_s.unwrap_or(f64::INFINITY).min(m.inject_s()) - TRACE_LEAD_S;
    let expected = (b.scenario.duration_s - from_s) * b.spec.pwm_frequency_hz;
    let (_, trace) = stream_trace(out, true, expected, &INTERRUPTED, |sink| {
        b.run_into(|_| {}, |r| if r.t_s >= from_s { sink(r) } else { Ok(()) })
    })?;
    let rows = &trace.plot;
    let pts = |f: &dyn Fn(&Row) -> f64| rows.iter().map(|r| (r.t_s, f(r))).collect::<Vec<_>>();
    let abc = |r: &Row| AlphaBeta { alpha: r.x.i_alpha_a, beta: r.x.i_beta_a }.inverse_clarke();
    let abc_ref = |r: &Row| AlphaBeta { alpha: r.i_ref_ab_a[0], beta: r.i_ref_ab_a[1] }.inverse_clarke();
    let colors = ["#1f77b4", "#d62728", "#2ca02c"];
    let names = [("i_a (A)", "i_a ref (A)"), ("i_b (A)", "i_b ref (A)"), ("i_c (A)", "i_c ref (A)")];
    let mut phases = Vec::new();
    for (p, ((name, ref_name), color)) in names.iter().zip(colors).enumerate() {
        let pick = move |v: Abc<f64>| [v.a, v.b, v.c].get(p).copied().unwrap_or(f64::NAN);
        phases.push(Series::line(name, pts(&|r| pick(abc(r)))).colored(color));
        phases.push(Series::dots(ref_name, pts(&|r| pick(abc_ref(r)))).colored(color));
    }
    let title = format!("{}: phase currents (dots: references)", crate::faults::row_name(case, at));
    write_text(&out.join("phases.svg"), &line_plot(&title, "t (s)", &phases))?;
    let speed = [
        Series::line("ω_m (rad/s)", pts(&|r| r.x.omega_m_rad_s)),
        Series::line("ω_ref (rad/s)", pts(&|r| r.omega_ref_rad_s)),
    ];
    write_text(&out.join("speed.svg"), &line_plot("Rotor speed", "t (s)", &speed))?;
    let torque =
        [Series::line("T_e (N·m)", pts(&|r| r.torque_nm)), Series::line("T_L (N·m)", pts(&|r| r.load_nm))];
    write_text(&out.join("torque.svg"), &line_plot("Torque", "t (s)", &torque))?;
    Ok(())
}

/// `hil-sim faults`: the selected rows in parallel (Ctrl-C stops them and writes nothing),
/// the table printed, `faults.md`, `faults.json` and `faults.svg` written, then the rows'
/// traces if asked; `Err` if a row fails its criterion.
pub fn faults(a: &FaultsOptions) -> Result<(), String> {
    use crate::faults::Matrix;
    let file = drive_file::DriveFile::load(&a.drive).map_err(|e| e.to_string())?;
    let vdc = bus_voltage(a.vdc, &file, "the matrix")?;
    let out = a.out.clone().unwrap_or_else(|| PathBuf::from("out/faults"));
    // Without [certify], the top speed is twice the base speed (the field-weakening range).
    let omega_r_max = file.certify.map_or(f64::INFINITY, |c| c.omega_r_max_rad_s);
    let mut m = Matrix::of_file(&file, omega_r_max, vdc);
    m.inject_delay_s = 1e-3 * a.inject_delay_ms;
    m.seed = a.seed;
    if let Some(plant) = &a.plant {
        m.plant = Some(super::plant_model(plant, &file.spec)?);
    }
    let all = m.rows()?;
    let selected: Vec<_> = match &a.only {
        Some(text) => {
            let text = text.to_lowercase();
            let rows: Vec<_> = all
                .iter()
                .filter(|(_, c, p)| crate::faults::row_name(c, p).to_lowercase().contains(&text))
                .cloned()
                .collect();
            if rows.is_empty() {
                let mut names: Vec<String> = all.iter().map(|(_, c, _)| c.title()).collect();
                names.dedup();
                let points: Vec<String> = m.points().iter().map(|p| p.name()).collect();
                return Err(format!(
                    "--only {text:?} names no row (\"<fault> at <point>\"; faults: {}; points: {})",
                    names.join(", "),
                    points.join(", ")
                ));
            }
            rows
        }
        None => all,
    };
    if a.trace && selected.len() > MAX_TRACED_ROWS {
        return Err(format!(
            "--trace writes at most {MAX_TRACED_ROWS} rows' traces (≈ 3 MB of CSV each), and {} rows are selected: \
             narrow them with --only",
            selected.len()
        ));
    }
    // Made once the arguments are known to be good (a bad --only or --trace left an empty
    // directory: found by trying), and removed if the matrix is interrupted.
    let made = make_out_dir(&out)?;
    let total = selected.len();
    eprintln!(
        "hil-sim: fault matrix of {} on {} V: {total} rows (top speed {:.1} rad/s{}{})",
        a.drive.display(),
        super::volts(vdc),
        m.top_speed_rad_s,
        if a.inject_delay_ms > 0.0 {
            format!(", injected {} ms late", a.inject_delay_ms)
        } else {
            String::new()
        },
        if a.seed != 0 { format!(", noise seed {}", a.seed) } else { String::new() },
    );
    let start = std::time::Instant::now();
    let tty = std::io::IsTerminal::is_terminal(&std::io::stderr());
    let rows = m.run_rows(
        &selected,
        |done| {
            if tty {
                eprint!("\rhil-sim: {done}/{total} rows");
            } else if done % 10 == 0 || done == total {
                eprintln!("hil-sim: {done}/{total} rows");
            }
        },
        &INTERRUPTED,
    );
    if tty {
        eprintln!();
    }
    let rows = rows.inspect_err(|_| unmake_out_dir(&out, made))?;
    let elapsed = start.elapsed().as_secs_f64();
    let md = crate::faults::markdown(&m, &rows);
    write_text(&out.join("faults.md"), &md)?;
    let json = serde_json::to_string_pretty(&crate::faults::json(&m, &rows)).map_err(|e| e.to_string())?;
    write_text(&out.join("faults.json"), &format!("{json}\n"))?;
    write_text(&out.join("faults.svg"), &crate::faults::svg(&m, &rows))?;
    report::outln!(
        "{:<30} {:<22} {:>8} {:<40} {:<30} {:>4} {:>7} {:>7} {:>9} {:<22} verdict",
        "fault injected",
        "operating point",
        "ω rad/s",
        "asked",
        "detected as",
        "off",
        "peak A",
        "leg A",
        "E_bus J",
        "final"
    );
    for o in &rows {
        let (off, leg, failures) = o.cells();
        report::outln!(
            "{:<30} {:<22} {:>8.1} {:<40} {:<30} {off:>4} {:>7.2} {leg:>7} {:>9.3} {:<22} {}{failures}",
            o.case.title(),
            o.at.name(),
            o.speed_at_injection_rad_s,
            o.asked(),
            o.seen(),
            o.peak_current_a,
            o.energy_into_bus_j,
            format!("{:?}", o.final_mode),
            o.verdict(),
        );
    }
    let (failed, gaps) =
        (rows.iter().filter(|o| !o.passed()).count(), rows.iter().filter(|o| o.verdict() == "gap").count());
    report::outln!(
        "{} rows in {elapsed:.2} s: {} pass, {gaps} stated gaps, {failed} fail",
        rows.len(),
        rows.len() - failed - gaps
    );
    eprintln!("hil-sim: wrote faults.md, faults.json, faults.svg in {}", out.display());
    if a.trace {
        for (row, o) in selected.iter().zip(&rows) {
            let dir = out.join("rows").join(slug(&crate::faults::row_name(&row.1, &row.2)));
            trace_fault_row(&m, row, o.tripped_before_s, &dir)?;
            eprintln!("hil-sim: wrote trace.csv, phases.svg, speed.svg, torque.svg in {}", dir.display());
        }
    }
    if failed == 0 { Ok(()) } else { Err(format!("{failed} of {} rows failed their criterion", rows.len())) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_row_name_becomes_a_directory_name() {
        assert_eq!(slug("Open phase a at mid-speed, motoring"), "open-phase-a-at-mid-speed-motoring");
        assert_eq!(slug("  ω: 2× (top)  "), "2-top");
    }

    /// A selection that names no row, or too many rows to trace, is an error that says what
    /// to choose, before the output directory is made.
    #[test]
    fn bad_selections_are_errors_before_anything_is_made() {
        let out = std::env::temp_dir().join(format!("hil-sim-faults-{}", std::process::id()));
        let options = |only: &str, trace| FaultsOptions {
            plant: None,
            drive: PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../drive.toml")),
            vdc: None,
            out: Some(out.clone()),
            inject_delay_ms: 0.0,
            seed: 0,
            only: Some(only.into()),
            trace,
        };
        let e = faults(&options("no such fault", false)).unwrap_err();
        assert!(e.contains("names no row") && e.contains("points:"), "{e}");
        let e = faults(&options("at", true)).unwrap_err();
        assert!(e.contains(&format!("at most {MAX_TRACED_ROWS} rows")), "{e}");
        assert!(!out.exists());
    }
}
