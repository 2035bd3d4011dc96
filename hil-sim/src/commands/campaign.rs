//! `hil-sim campaign`: the nonlinear campaign over a drive file's `[certify]` box
//! ([`crate::campaign`]), its table, plot and summary.

use super::{INTERRUPTED, bus_voltage};
use crate::trace::{make_out_dir, unmake_out_dir};
use report::write::write_text;
use std::path::PathBuf;

/// What `campaign` is asked.
#[derive(Debug, Clone, PartialEq)]
pub struct CampaignOptions {
    /// A drive file with a `[certify]` table.
    pub drive: PathBuf,
    /// Runs in the whole campaign (the corners' come first).
    pub runs: u64,
    /// Length of each run, s (`None`: 1 s, or the least that steps the speed to the box's
    /// top speed if longer: `Campaign::full_range_duration_s`).
    pub duration: Option<f64>,
    /// Seed of the random samples (and of the sensors' noise).
    pub seed: u64,
    /// Run only the shard i of N (`(i, N)`: runs with k mod N = i).
    pub shard: (u64, u64),
    /// DC-bus voltage, V (`None`: [`bus_voltage`]'s choice).
    pub vdc: Option<f64>,
    /// Output directory (`None`: `out/campaign`).
    pub out: Option<PathBuf>,
    /// Simulate this motor (a shipped motor's name or a file with a `[motor]` table, its
    /// saturation included) at the box's points instead of the drive's own.
    pub plant: Option<String>,
    /// Run only this run, writing its trace (`hil-sim campaign --trace K`) instead of the
    /// campaign's table.
    pub trace: Option<u64>,
}

/// `hil-sim campaign`: runs the shard in parallel (Ctrl-C stops it and writes nothing),
/// prints the per-manoeuvre and per-requirement tables, writes `campaign.csv`, `campaign.svg`,
/// `requirements.svg` ([`crate::campaign::requirements_plot`]) and `summary.json`
/// (with the drive file's fingerprint); `Err` if any run fails.
pub fn campaign(a: &CampaignOptions) -> Result<(), String> {
    let (i, n) = a.shard;
    if n == 0 || i >= n {
        return Err(format!("shard {i}/{n}: a shard i/N needs 0 ≤ i < N"));
    }
    use crate::campaign::{Campaign, Verdict};
    let file = drive_file::DriveFile::load(&a.drive).map_err(|e| e.to_string())?;
    let certify = file.certify.ok_or_else(|| {
        format!("{}: no [certify] table: the campaign samples its parameter box", a.drive.display())
    })?;
    let vdc = bus_voltage(a.vdc, &file, "the campaign")?;
    let out = a.out.clone().unwrap_or_else(|| PathBuf::from("out/campaign"));
    let mut c = Campaign {
        spec: file.spec,
        certify,
        vdc_v: vdc,
        duration_s: a.duration.unwrap_or(1.0),
        runs: a.runs,
        seed: a.seed,
        shard: a.shard,
        encoder_lines: file.encoder_lines(),
        plant: super::simulated_motor(a.plant.as_deref(), &file, &a.drive)?,
        requirements: file.requirements,
    };
    if a.duration.is_none() {
        c.duration_s = c.duration_s.max(c.full_range_duration_s());
    }
    c.check()?;
    if let Some(k) = a.trace {
        return trace_run(&c, k, a.out.clone());
    }
    match a.duration {
        Some(_) if c.omega_s_rad_s() < c.top_speed_rad_s() => eprintln!(
            "hil-sim: runs of {:.2} s step the speed to {:.1} rad/s, below the box's top speed {:.1} rad/s: its field \
             weakening is not run (--duration {:.2}, or none, reaches it)",
            c.duration_s,
            c.omega_s_rad_s(),
            c.top_speed_rad_s(),
            c.full_range_duration_s()
        ),
        _ => {}
    }
    let total = c.indices().count() as u64;
    if total == 0 {
        return Err(format!(
            "shard {}/{} of a {}-run campaign has no runs (its runs are those with k mod {} = {}): take fewer shards",
            a.shard.0, a.shard.1, a.runs, a.shard.1, a.shard.0
        ));
    }
    if a.runs < crate::campaign::CORNER_RUNS {
        eprintln!(
            "hil-sim: {} runs leave corners of the box without every manoeuvre: `design certify --campaign` asks for {} or more",
            a.runs,
            crate::campaign::CORNER_RUNS
        );
    }
    let made = make_out_dir(&out)?;
    eprintln!(
        "hil-sim: campaign of {} on {} V: {total} run(s) of {:.2} s (shard {}/{} of {}), speed steps to ±{:.1} rad/s",
        a.drive.display(),
        super::volts(vdc),
        c.duration_s,
        a.shard.0,
        a.shard.1,
        a.runs,
        c.omega_s_rad_s()
    );
    let start = std::time::Instant::now();
    // Progress: one line rewritten on a terminal, a line per 10 % otherwise (a CI log).
    let tty = std::io::IsTerminal::is_terminal(&std::io::stderr());
    let step = (total / if tty { 100 } else { 10 }).max(1);
    let verdicts = c.run(
        |done| {
            if done % step == 0 || done == total {
                if tty {
                    eprint!("\rhil-sim: {done}/{total} runs");
                } else {
                    eprintln!("hil-sim: {done}/{total} runs");
                }
            }
        },
        &INTERRUPTED,
    );
    if tty {
        eprintln!();
    }
    // Interrupted (Ctrl-C): nothing written, nor the directory this made.
    let verdicts = verdicts.inspect_err(|_| unmake_out_dir(&out, made))?;
    let elapsed = start.elapsed().as_secs_f64();
    let mut csv = Verdict::csv_header();
    csv.push('\n');
    for v in &verdicts {
        csv.push_str(&v.csv());
        csv.push('\n');
    }
    write_text(&out.join("campaign.csv"), &csv)?;
    write_text(&out.join("campaign.svg"), &crate::campaign::plot(&c, &verdicts))?;
    write_text(&out.join("requirements.svg"), &crate::campaign::requirements_plot(&c, &verdicts))?;
    let mut summary = crate::campaign::summary(&c, &verdicts, elapsed);
    // Which file exactly: `design certify --campaign` refuses a summary of another one.
    let drive_text = drive_file::source::read(&a.drive).map_err(|e| e.to_string())?;
    if let Some(o) = summary.as_object_mut() {
        o.insert(
            "drive".into(),
            serde_json::json!({
                "file": a.drive.display().to_string(),
                "fingerprint": drive_file::source::fingerprint(&drive_text),
            }),
        );
    }
    let text = serde_json::to_string_pretty(&summary).map_err(|e| e.to_string())?;
    write_text(&out.join("summary.json"), &format!("{text}\n"))?;
    report::outln!(
        "{:<12} {:>6} {:>7} {:>17} {:>13} {:>16}",
        "manoeuvre",
        "runs",
        "passed",
        "worst tracking",
        "worst ripple",
        "flux / model"
    );
    for m in crate::campaign::per_manoeuvre(&verdicts) {
        match (m.worst_tracking_error_rad_s, m.worst_ripple_nm, m.flux_ratio) {
            (Some(tracking), Some(ripple), Some([lo, hi])) => report::outln!(
                "{:<12} {:>6} {:>7} {tracking:>11.3} rad/s {ripple:>10.4} Nm {lo:>8.3} … {hi:.3}",
                m.manoeuvre.name(),
                m.runs,
                m.passed,
            ),
            _ => report::outln!(
                "{:<12} {:>6} {:>7} {:>17} {:>13} {:>16}",
                m.manoeuvre.name(),
                m.runs,
                m.passed,
                "—",
                "—",
                "—"
            ),
        }
    }
    let outside = crate::campaign::flux_outside_model(&verdicts);
    if !outside.is_empty() {
        let [lo, hi] = crate::campaign::FLUX_MODEL_BAND;
        let shown: Vec<String> = outside.iter().take(12).map(u64::to_string).collect();
        let more = if outside.len() > shown.len() { ", …" } else { "" };
        report::outln!(
            "flux outside {lo}…{hi} of the drive's model (a diagnostic, not a verdict) in {} run(s): {}{more}",
            outside.len(),
            shown.join(", ")
        );
    }
    report::outln!(
        "{:<36} {:>6} {:>6} {:>12} {:>12} {:>9}",
        "requirement",
        "runs",
        "met",
        "worst",
        "allowed",
        "worst run"
    );
    for r in crate::campaign::per_requirement(&verdicts) {
        match r.worst {
            Some((k, m)) => report::outln!(
                "{:<36} {:>6} {:>6} {:>12.4} {:>12.4} {:>9}",
                r.requirement.to_string(),
                r.runs,
                r.met,
                m.value,
                m.allowed,
                k
            ),
            None => report::outln!(
                "{:<36} {:>6} {:>6} {:>12} {:>12} {:>9}",
                r.requirement.to_string(),
                0,
                0,
                "—",
                "—",
                "—"
            ),
        }
    }
    let failed: Vec<&Verdict> = verdicts.iter().filter(|v| !v.passed()).collect();
    for v in failed.iter().take(20) {
        report::outln!("FAIL run {}: {} ({})", v.k, v.failures.join(", "), v.csv());
    }
    report::outln!(
        "{} runs in {elapsed:.2} s ({:.1} ns per simulated PWM period, {:.0} runs/s)",
        verdicts.len(),
        crate::campaign::ns_per_period(&c, &verdicts, elapsed),
        verdicts.len() as f64 / elapsed
    );
    eprintln!(
        "hil-sim: wrote campaign.csv, campaign.svg, requirements.svg, summary.json in {}",
        out.display()
    );
    if failed.is_empty() {
        Ok(())
    } else {
        Err(format!("{} of {} runs failed their criteria", failed.len(), verdicts.len()))
    }
}

/// `hil-sim campaign --trace K`: run `k` alone, its trace (one row per slow period) streamed
/// to `trace.csv` in `out` (default `out/campaign/run-K`) with its plots, and its verdict —
/// each requirement measured and allowed, the failures — in `summary.json` and on stdout.
/// `Err` if the run failed, as the campaign would.
fn trace_run(c: &crate::campaign::Campaign, k: u64, out: Option<PathBuf>) -> Result<(), String> {
    if k >= c.runs {
        return Err(format!(
            "run {k} is not in a {}-run campaign (runs 0 … {})",
            c.runs,
            c.runs.saturating_sub(1)
        ));
    }
    let out = out.unwrap_or_else(|| PathBuf::from(format!("out/campaign/run-{k}")));
    let rows = c.duration_s * c.spec.pwm_frequency_hz / f64::from(c.spec.slow_divider);
    let (verdict, stats) = crate::trace::stream_trace(&out, true, rows, &INTERRUPTED, |sink| {
        c.run_one_into(k, &INTERRUPTED, sink)
    })?;
    let failures = verdict.failures.clone();
    crate::trace::finish(&out, stats, |_, peak_a| {
        serde_json::json!({
            "run": verdict.k,
            "manoeuvre": verdict.manoeuvre.name(),
            "factors": {
                "rs": verdict.sample.rs, "rr": verdict.sample.rr, "l": verdict.sample.l, "j": verdict.sample.j,
            },
            "speed_step_rad_s": verdict.omega_s_rad_s,
            "duration_s": verdict.duration_s,
            "mode": format!("{:?}", verdict.mode),
            "peak_current_a": peak_a,
            "requirements": verdict.measures.iter().map(|m| serde_json::json!({
                "key": m.requirement.key(), "value": m.value, "allowed": m.allowed, "met": m.met(),
            })).collect::<Vec<_>>(),
            "failures": failures,
        })
    })?;
    if verdict.passed() { Ok(()) } else { Err(format!("run {k} failed: {}", verdict.failures.join(", "))) }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn options(shard: (u64, u64), out: &std::path::Path) -> CampaignOptions {
        CampaignOptions {
            drive: PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../drive.toml")),
            runs: 4,
            duration: Some(1.0),
            seed: 1,
            shard,
            vdc: None,
            out: Some(out.to_path_buf()),
            plant: None,
            trace: None,
        }
    }

    /// A shard that is not one (N = 0 divided by zero), or one with no runs, is an error
    /// before the output directory is made.
    #[test]
    fn bad_shards_are_errors() {
        let out = std::env::temp_dir().join(format!("hil-sim-campaign-{}", std::process::id()));
        for shard in [(0, 0), (3, 3)] {
            let e = campaign(&options(shard, &out)).unwrap_err();
            assert!(e.contains("0 ≤ i < N"), "{shard:?}: {e}");
        }
        let e = campaign(&options((5, 6), &out)).unwrap_err();
        assert!(e.contains("has no runs"), "{e}");
        assert!(!out.exists());
    }
}
