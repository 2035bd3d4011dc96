//! One member through what a user does with a new motor: `design tune` on its template,
//! then the tuned file's nonlinear campaign and fault matrix — judged as issue 49 asks:
//! tune refuses (with its reason), or the tuned file passes everything, or it fails (the
//! defect: tune passed a drive that does not work).

use crate::member::{Member, Origin};
use design::tune::{CurrentDesign, SpeedDesign, Structure};
use drive_file::DriveFile;
use hil_sim::campaign::Campaign;
use hil_sim::faults::Matrix;
use std::path::Path;
use std::sync::atomic::AtomicBool;

/// How a member ended.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "verdict", rename_all = "snake_case")]
pub enum Verdict {
    /// Tuned, and the tuned file passed the campaign and the fault matrix.
    Pass,
    /// `design tune` refused: why.
    Refuse {
        /// Tune's error.
        reason: String,
    },
    /// Tuned, then failed: the defect.
    Fail {
        /// What failed, in words (the first few failures).
        what: String,
    },
    /// Could not be judged (an input the tools refused after tune: a defect too).
    Error {
        /// The error.
        error: String,
    },
}

impl Verdict {
    /// "pass", "refuse", "FAIL", "ERROR".
    pub fn word(&self) -> &'static str {
        match self {
            Self::Pass => "pass",
            Self::Refuse { .. } => "refuse",
            Self::Fail { .. } => "FAIL",
            Self::Error { .. } => "ERROR",
        }
    }
}

/// What a member's run measured.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Report {
    /// The member's name.
    pub member: String,
    /// Rated power, W (`None` for a shipped motor without a nameplate).
    pub power_w: Option<f64>,
    /// The PWM rate it ran at, Hz.
    pub pwm_hz: f64,
    /// Bus voltage, V.
    pub vdc_v: f64,
    /// The tuned current loops' crossover, rad/s.
    pub omega_c_rad_s: Option<f64>,
    /// Campaign runs passed and run.
    pub campaign: Option<[u64; 2]>,
    /// Of those, the corner runs `design tune` had run and passed on the same campaign
    /// (`Tuned::passed_corner_runs_of`), not run again: 0 or the corner runs' number (0 in
    /// a report written before it was counted).
    #[serde(default)]
    pub campaign_runs_from_tune: u64,
    /// The campaign's failures, by kind, with their counts.
    pub campaign_failures: Vec<(String, u64)>,
    /// Fault-matrix rows passed (gaps included) and run.
    pub matrix: Option<[u64; 2]>,
    /// The failing rows' names and why.
    pub matrix_failures: Vec<String>,
    /// The verdict.
    pub verdict: Verdict,
    /// Wall time of the member, s.
    pub elapsed_s: f64,
    /// Wall time of its stages — tune, the campaign, the fault matrix — s (0 for a stage
    /// not run; 0 in a report written before they were timed). The drives run side by
    /// side, so a stage's time shares the machine with another drive's.
    #[serde(default)]
    pub stages_s: [f64; STAGES],
}

/// The stages [`Report::stages_s`] times, in order.
pub const STAGES: usize = 3;

/// Their names.
pub const STAGE_NAMES: [&str; STAGES] = ["tune", "campaign", "fault matrix"];

/// What a run of the population does per member.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plan {
    /// Campaign runs (the box's corners come first).
    pub campaign_runs: u64,
    /// Campaign seed.
    pub seed: u64,
    /// Run the fault matrix.
    pub matrix: bool,
    /// The speed law `design tune` is asked for (`auto`: the one the requirements choose).
    pub speed: SpeedDesign,
    /// Run the tuned drive without its encoder (`speed_feedback = "sensorless"`: the flux
    /// and speed observer); a rate the observer cannot run at is a refusal naming it.
    pub sensorless: bool,
    /// Tune and run the drive overmodulating (`overmodulation = true`: docs/envelope.md).
    pub overmodulation: bool,
}

/// The template text and its path (for errors), the motor and the bus of `member` at
/// `pwm_hz`; shipped members read their files under `root`.
pub fn inputs(member: &Member, pwm_hz: Option<f64>, root: &Path) -> Result<(String, String, f64), String> {
    match (&member.origin, member.template()) {
        (Origin::Shipped { template, .. }, _) => {
            let path = root.join(template);
            let text = std::fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))?;
            let text = match pwm_hz {
                Some(hz) => with_pwm(&text, hz)?,
                None => text,
            };
            let file = DriveFile::parse(&path, &text).map_err(|e| e.to_string())?;
            let vdc = hil_sim::commands::bus_voltage(None, &file, "the population")?;
            Ok((path.display().to_string(), text, vdc))
        }
        (Origin::Drawn { .. }, Some(text)) => {
            let board = member.board.ok_or("a drawn member without a board")?;
            let text = match pwm_hz {
                Some(hz) => {
                    Member { board: Some(board.at_pwm(hz)), ..member.clone() }.template().unwrap_or(text)
                }
                None => text,
            };
            Ok((format!("{}.toml", member.name), text, board.vdc_v))
        }
        (Origin::Drawn { .. }, None) => Err("a drawn member without a nameplate".into()),
    }
}

/// `text` with its `[pwm]` table's `frequency_hz` set to `hz` and `slow_divider` to keep the
/// slow loop near [`crate::member::SLOW_RATE_HZ`] (a template's own rates are its author's;
/// the population runs each at its sweep's).
pub fn with_pwm(text: &str, hz: f64) -> Result<String, String> {
    let divider = (hz / crate::member::SLOW_RATE_HZ).round().max(1.0);
    let mut out = String::new();
    let (mut in_pwm, mut set) = (false, [false; 2]);
    for line in text.lines() {
        let trimmed = line.trim_start();
        if trimmed.starts_with('[') {
            in_pwm = trimmed.starts_with("[pwm]");
        }
        let key = trimmed.split('=').next().unwrap_or("").trim();
        if in_pwm && key == "frequency_hz" {
            out.push_str(&format!("frequency_hz = {hz:?}\n"));
            set[0] = true;
        } else if in_pwm && key == "slow_divider" {
            out.push_str(&format!("slow_divider = {divider}\n"));
            set[1] = true;
        } else {
            out.push_str(line);
            out.push('\n');
        }
    }
    if set != [true, true] {
        return Err("the template's [pwm] table lacks frequency_hz or slow_divider".into());
    }
    Ok(out)
}

/// The campaign of a tuned drive file on a `vdc_v` bus: `runs` runs of 1 s from `seed`, the
/// file's `[certify]` box and `[requirements]` (the caller sets the duration it needs).
pub fn campaign_of(file: &DriveFile, vdc_v: f64, runs: u64, seed: u64) -> Result<Campaign, String> {
    Ok(Campaign {
        spec: file.spec,
        certify: file.certify.ok_or("the tuned file has no [certify]")?,
        vdc_v,
        duration_s: 1.0,
        runs,
        seed,
        shard: (0, 1),
        encoder_lines: file.encoder_lines(),
        plant: None,
        requirements: file.requirements,
    })
}

/// The campaign `run` gives a tuned `file` ([`campaign_of`]), its runs long enough to reach
/// the top speed ([`Campaign::full_range_duration_s`]), checked.
pub fn full_range_campaign_of(
    file: &DriveFile,
    vdc_v: f64,
    runs: u64,
    seed: u64,
) -> Result<Campaign, String> {
    let mut c = campaign_of(file, vdc_v, runs, seed)?;
    c.duration_s = c.duration_s.max(c.full_range_duration_s());
    c.check()?;
    Ok(c)
}

/// `text` with its `[controller]` table's `speed_feedback` set to `"sensorless"` (a drive run
/// without its encoder).
pub fn with_sensorless(text: &str) -> Result<String, String> {
    with_controller_key(text, "speed_feedback", "\"sensorless\"")
}

/// `text` with its `[controller]` table's `overmodulation` set to `true`.
pub fn with_overmodulation(text: &str) -> Result<String, String> {
    with_controller_key(text, "overmodulation", "true")
}

/// `text` with its `[controller]` table's `key` set to `value` (TOML), first in the table, in
/// place of the table's own line for it.
fn with_controller_key(text: &str, key: &str, value: &str) -> Result<String, String> {
    let mut out = String::new();
    let (mut in_controller, mut set) = (false, false);
    for line in text.lines() {
        let trimmed = line.trim_start();
        if trimmed.starts_with('[') {
            in_controller = trimmed.starts_with("[controller]");
            out.push_str(line);
            out.push('\n');
            if in_controller && !set {
                out.push_str(&format!("{key} = {value}\n"));
                set = true;
            }
            continue;
        }
        let this = trimmed.split('=').next().unwrap_or("").trim();
        if !(in_controller && this == key) {
            out.push_str(line);
            out.push('\n');
        }
    }
    if !set {
        return Err("the template has no [controller] table".into());
    }
    Ok(out)
}

/// Tunes, then runs the campaign and the matrix of `member` at `pwm_hz` (`None`: its own).
pub fn evaluate(
    member: &Member,
    pwm_hz: Option<f64>,
    root: &Path,
    plan: &Plan,
    cancel: &AtomicBool,
) -> Report {
    let start = std::time::Instant::now();
    let mut report = Report {
        member: member.name.clone(),
        power_w: member.nameplate.map(|n| n.power_w),
        pwm_hz: pwm_hz.or(member.board.map(|b| b.pwm_hz)).unwrap_or(f64::NAN),
        vdc_v: f64::NAN,
        omega_c_rad_s: None,
        campaign: None,
        campaign_runs_from_tune: 0,
        campaign_failures: Vec::new(),
        matrix: None,
        matrix_failures: Vec::new(),
        verdict: Verdict::Pass,
        elapsed_s: 0.0,
        stages_s: [0.0; STAGES],
    };
    report.verdict = match judge(member, pwm_hz, root, plan, cancel, &mut report) {
        Ok(v) => v,
        Err(error) => Verdict::Error { error },
    };
    report.elapsed_s = start.elapsed().as_secs_f64();
    report
}

fn judge(
    member: &Member,
    pwm_hz: Option<f64>,
    root: &Path,
    plan: &Plan,
    cancel: &AtomicBool,
    report: &mut Report,
) -> Result<Verdict, String> {
    // Ctrl-C: the members not yet started are not tuned (tune itself cannot be stopped).
    if cancel.load(std::sync::atomic::Ordering::Relaxed) {
        return Err("interrupted".into());
    }
    let (path, text, vdc) = inputs(member, pwm_hz, root)?;
    report.vdc_v = vdc;
    let path = Path::new(&path);
    // Without an encoder the template says so: `design tune` bounds the speed gain by the
    // observer's noise and confirms its choice on the observer.
    if let Ok(f) = DriveFile::parse(path, &text) {
        report.pwm_hz = f.spec.pwm_frequency_hz;
    }
    let text = if plan.sensorless { with_sensorless(&text)? } else { text };
    let text = if plan.overmodulation { with_overmodulation(&text)? } else { text };
    if plan.sensorless {
        // What the template parsed with an encoder and not without is the observer's.
        let observer = DriveFile::parse(path, &text).map_err(|e| e.to_string()).and_then(|f| {
            controller_core::drive::DriveConfig::new(&f.spec).map(|_| ()).map_err(|e| e.to_string())
        });
        if let Err(e) = observer {
            return Ok(Verdict::Refuse { reason: format!("sensorless: {e}") });
        }
    }
    // By default the speed law the requirements choose (issue 51): the saturated P where it
    // meets them, else the PI with its setpoint weight, else a refusal naming the requirement.
    let structure = Structure { current: CurrentDesign::Pi, speed: plan.speed };
    let clock = std::time::Instant::now();
    let tuned = design::tune::tune(path, &text, &member.motor, None, structure);
    report.stages_s[0] = clock.elapsed().as_secs_f64();
    let tuned = match tuned {
        Ok(t) => t,
        Err(reason) => return Ok(Verdict::Refuse { reason }),
    };
    let clock = std::time::Instant::now();
    report.omega_c_rad_s = Some(tuned.omega_c_rad_s);
    let file = DriveFile::parse(path, &tuned.text).map_err(|e| format!("the tuned file: {e}"))?;
    let c = full_range_campaign_of(&file, vdc, plan.campaign_runs, plan.seed)?;
    let certify = c.certify;
    // The corner runs tune ran and passed on this very campaign are not run twice.
    let from_tune = if tuned.passed_corner_runs_of(&c) { hil_sim::campaign::CORNER_RUNS } else { 0 };
    let verdicts = c.run_where(|k| k >= from_tune, |_| {}, cancel)?;
    let passed = from_tune + verdicts.iter().filter(|v| v.passed()).count() as u64;
    let runs = from_tune + verdicts.len() as u64;
    report.campaign = Some([passed, runs]);
    report.campaign_runs_from_tune = from_tune;
    let mut kinds: Vec<(String, u64)> = Vec::new();
    for v in verdicts.iter().filter(|v| !v.passed()) {
        let kind = format!("{} {}", v.manoeuvre.name(), v.failures.join("+"));
        match kinds.iter_mut().find(|(k, _)| *k == kind) {
            Some((_, n)) => *n += 1,
            None => kinds.push((kind, 1)),
        }
    }
    report.campaign_failures = kinds;
    report.stages_s[1] = clock.elapsed().as_secs_f64();
    if plan.matrix {
        let clock = std::time::Instant::now();
        let outcomes = Matrix::of_file(&file, certify.omega_r_max_rad_s, vdc).run(|_| {}, cancel)?;
        report.stages_s[2] = clock.elapsed().as_secs_f64();
        let ok = outcomes.iter().filter(|o| o.passed()).count() as u64;
        report.matrix = Some([ok, outcomes.len() as u64]);
        report.matrix_failures = outcomes
            .iter()
            .filter(|o| !o.passed())
            .map(|o| format!("{}: {}", hil_sim::faults::row_name(&o.case, &o.at), o.failures.join("; ")))
            .collect();
    }
    let campaign_ok = passed == runs;
    let matrix_ok = report.matrix_failures.is_empty();
    Ok(if campaign_ok && matrix_ok {
        Verdict::Pass
    } else {
        let mut what = Vec::new();
        if !campaign_ok {
            let kinds: Vec<String> =
                report.campaign_failures.iter().take(3).map(|(k, n)| format!("{n}× {k}")).collect();
            what.push(format!("campaign {passed}/{runs} ({})", kinds.join(", ")));
        }
        if !matrix_ok {
            what.push(format!(
                "matrix {} failing row(s) (first: {})",
                report.matrix_failures.len(),
                report.matrix_failures.first().map_or("", |s| s.as_str())
            ));
        }
        Verdict::Fail { what: what.join("; ") }
    })
}

/// One kind of failure over a population's drives: what failed, in how many matrix rows
/// or campaign runs, on how many drives.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Family {
    /// `matrix: <case>: <how>` or `campaign: <criterion>`.
    pub name: String,
    /// Failing matrix rows or campaign runs.
    pub count: u64,
    /// Drives (member × PWM rate) with at least one.
    pub drives: u64,
}

/// The failures of `reports` grouped by family, the largest first: a matrix row by its case
/// and how it failed (a healthy drive that tripped before the injection, or an operating
/// point not reached, is its own family whatever the case), a campaign run by each
/// criterion it failed.
pub fn families(reports: &[Report]) -> Vec<Family> {
    use std::collections::{BTreeMap, BTreeSet};
    let mut by_name: BTreeMap<String, (u64, BTreeSet<usize>)> = BTreeMap::new();
    let mut add = |name: String, n: u64, drive: usize| {
        let (count, drives) = by_name.entry(name).or_default();
        *count += n;
        drives.insert(drive);
    };
    for (d, r) in reports.iter().enumerate() {
        for f in &r.matrix_failures {
            add(matrix_family(f), 1, d);
        }
        for (kind, n) in &r.campaign_failures {
            // "<manoeuvre> <criterion>+<criterion>…"
            let criteria = kind.split_once(' ').map_or(kind.as_str(), |(_, c)| c);
            for c in criteria.split('+') {
                add(format!("campaign: {c}"), *n, d);
            }
        }
    }
    let mut families: Vec<Family> = by_name
        .into_iter()
        .map(|(name, (count, drives))| Family { name, count, drives: drives.len() as u64 })
        .collect();
    // Largest first; the map's order (by name) breaks ties.
    families.sort_by_key(|f| std::cmp::Reverse(f.count));
    families
}

/// A matrix failure's family (see [`families`]): `failure` is `<case> at <point>: <what>`.
fn matrix_family(failure: &str) -> String {
    let (row, what) = failure.split_once(": ").unwrap_or((failure, ""));
    if let Some(at) = what.find(") before the injection")
        && let Some(open) = what.get(..at).and_then(|w| w.rfind("Fault("))
    {
        let fault = what.get(open + "Fault(".len()..at).unwrap_or("?");
        return format!("matrix: a healthy drive tripped ({fault}) before the injection");
    }
    if what.contains("operating point was not reached") {
        return "matrix: the operating point not reached".into();
    }
    let case = row.split_once(" at ").map_or(row, |(c, _)| c);
    let how = if what.starts_with("not detected") {
        "missed"
    } else if what.starts_with("detected as") {
        "misnamed"
    } else if what.starts_with("tripped") {
        "tripped (a ride-through row)"
    } else if what.contains("bound") {
        "late"
    } else {
        "other"
    };
    format!("matrix: {case}: {how}")
}

/// [`families`] as a markdown table.
pub fn families_table(families: &[Family]) -> String {
    let mut s = String::from("| failure family | rows / runs | drives |\n|---|---|---|\n");
    for f in families {
        s.push_str(&format!("| {} | {} | {} |\n", f.name.replace('|', "/"), f.count, f.drives));
    }
    s
}

/// The rated-power bands of [`grid`], W: each decade from 100 W up (the population draws
/// 100 W … 200 kW; the shipped 17.6 W motor and anything below fall in the first, anything
/// above in the last).
const POWER_DECADES_W: [f64; 4] = [1e2, 1e3, 1e4, 1e5];

/// [`grid`]'s columns: one per PWM rate up to this many rates (`run --pwm`'s) …
const RATE_COLUMNS_MAX: usize = 6;
/// … else the rates in bands split here, Hz (`run --own-pwm`: each board's own, drawn from
/// 4–20 kHz — a column per drive made a table 200 columns wide).
const RATE_BAND_EDGES_HZ: [f64; 2] = [6e3, 12e3];

/// [`grid`]'s columns: each a label and the rates `lo ≤ f < hi` it holds (`lo = hi`: `f`
/// alone).
fn rate_columns(reports: &[Report]) -> Vec<(String, f64, f64)> {
    let mut rates: Vec<f64> = reports.iter().map(|r| r.pwm_hz).collect();
    rates.sort_by(f64::total_cmp);
    rates.dedup();
    if rates.len() <= RATE_COLUMNS_MAX {
        return rates.iter().map(|&f| (format!("{:.0} kHz", f / 1e3), f, f)).collect();
    }
    let edges: Vec<f64> =
        std::iter::once(f64::NEG_INFINITY).chain(RATE_BAND_EDGES_HZ).chain([f64::INFINITY]).collect();
    edges
        .windows(2)
        .filter_map(|w| {
            let (lo, hi) = (*w.first()?, *w.last()?);
            let inside: Vec<f64> = rates.iter().copied().filter(|f| (lo..hi).contains(f)).collect();
            let (first, last) = (inside.first()?, inside.last()?);
            Some((format!("{:.1}–{:.1} kHz", first / 1e3, last / 1e3), lo, hi))
        })
        .collect()
}

/// The verdicts over rated power × PWM rate as a markdown table: one row per power decade
/// (and one for the shipped motors without a nameplate), one column per PWM rate (or band of
/// rates where a run has more than six), each cell `pass / refuse / FAIL` (ERROR added when there is
/// one), and the totals.
pub fn grid(reports: &[Report]) -> String {
    let columns = rate_columns(reports);
    let holds = |(_, lo, hi): &(String, f64, f64), f: f64| f == *lo || (*lo..*hi).contains(&f);
    let band = |p: Option<f64>| -> Option<usize> {
        p.map(|p| POWER_DECADES_W.iter().rposition(|&lo| p >= lo).unwrap_or(0))
    };
    let label = |b: Option<usize>| match b {
        None => "shipped, no nameplate".to_string(),
        Some(i) => {
            let kw = |w: f64| if w < 1e3 { format!("{w:.0} W") } else { format!("{:.0} kW", w / 1e3) };
            match (POWER_DECADES_W.get(i), POWER_DECADES_W.get(i + 1)) {
                (Some(&lo), Some(&hi)) => format!("{} – {}", kw(lo), kw(hi)),
                (Some(&lo), None) => format!("≥ {}", kw(lo)),
                _ => String::new(),
            }
        }
    };
    let cell = |rs: &mut dyn Iterator<Item = &Report>| {
        let (mut n, mut e) = ([0usize; 3], 0usize);
        for r in rs {
            match r.verdict {
                Verdict::Pass => n[0] += 1,
                Verdict::Refuse { .. } => n[1] += 1,
                Verdict::Fail { .. } => n[2] += 1,
                Verdict::Error { .. } => e += 1,
            }
        }
        let mut c = format!("{} / {} / {}", n[0], n[1], n[2]);
        if e > 0 {
            c.push_str(&format!(" (+{e} ERROR)"));
        }
        c
    };
    let head: Vec<&str> = columns.iter().map(|(label, _, _)| label.as_str()).collect();
    let mut s =
        format!("| rated power | {} | all |\n|---|{}---|\n", head.join(" | "), "---|".repeat(columns.len()));
    let mut bands: Vec<Option<usize>> = reports.iter().map(|r| band(r.power_w)).collect();
    bands.sort();
    bands.dedup();
    // Each band's row, then the totals' (`None`: every report).
    let rows = bands.iter().map(|&b| (label(b), Some(b))).chain(std::iter::once(("all".to_string(), None)));
    for (name, row) in rows {
        let keep = |r: &&Report| row.is_none_or(|b| band(r.power_w) == b);
        let mut line = format!("| {name} |");
        for c in &columns {
            line.push_str(&format!(
                " {} |",
                cell(&mut reports.iter().filter(keep).filter(|r| holds(c, r.pwm_hz)))
            ));
        }
        line.push_str(&format!(" {} |\n", cell(&mut reports.iter().filter(keep))));
        s.push_str(&line);
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::member::draw;
    use controller_core::drive::DriveSpec;

    /// The grid counts each verdict in its power decade and PWM rate, the shipped motors
    /// without a nameplate on a row of their own, and the totals.
    #[test]
    fn the_grid_counts_verdicts_over_power_and_rate() {
        let report = |power_w: Option<f64>, pwm_hz: f64, verdict: Verdict| Report {
            member: String::new(),
            power_w,
            pwm_hz,
            vdc_v: 0.0,
            omega_c_rad_s: None,
            campaign: None,
            campaign_runs_from_tune: 0,
            campaign_failures: Vec::new(),
            matrix: None,
            matrix_failures: Vec::new(),
            verdict,
            elapsed_s: 0.0,
            stages_s: [0.0; STAGES],
        };
        let refuse = || Verdict::Refuse { reason: String::new() };
        let reports = [
            report(Some(500.0), 4e3, Verdict::Pass),
            report(Some(999.0), 20e3, refuse()),
            report(Some(1e3), 4e3, Verdict::Fail { what: String::new() }),
            report(Some(150e3), 20e3, Verdict::Pass),
            report(Some(17.6), 20e3, Verdict::Error { error: String::new() }),
            report(None, 4e3, Verdict::Pass),
        ];
        let g = grid(&reports);
        let lines: Vec<&str> = g.lines().collect();
        assert_eq!(lines.first(), Some(&"| rated power | 4 kHz | 20 kHz | all |"), "{g}");
        assert!(lines.contains(&"| shipped, no nameplate | 1 / 0 / 0 | 0 / 0 / 0 | 1 / 0 / 0 |"), "{g}");
        assert!(
            lines.contains(&"| 100 W – 1 kW | 1 / 0 / 0 | 0 / 1 / 0 (+1 ERROR) | 1 / 1 / 0 (+1 ERROR) |"),
            "{g}"
        );
        assert!(lines.contains(&"| 1 kW – 10 kW | 0 / 0 / 1 | 0 / 0 / 0 | 0 / 0 / 1 |"), "{g}");
        assert!(lines.contains(&"| ≥ 100 kW | 0 / 0 / 0 | 1 / 0 / 0 | 1 / 0 / 0 |"), "{g}");
        assert_eq!(
            *lines.last().unwrap(),
            "| all | 2 / 0 / 1 | 1 / 1 / 0 (+1 ERROR) | 3 / 1 / 1 (+1 ERROR) |",
            "{g}"
        );
        // Each board at its own rate: the rates in three bands, not a column each (200
        // columns for `run --members 200 --own-pwm`).
        let own: Vec<Report> =
            (0..10).map(|k| report(Some(500.0), 4e3 + 1.6e3 * f64::from(k), Verdict::Pass)).collect();
        let g = grid(&own);
        let lines: Vec<&str> = g.lines().collect();
        assert_eq!(
            lines.first(),
            Some(&"| rated power | 4.0–5.6 kHz | 7.2–10.4 kHz | 12.0–18.4 kHz | all |"),
            "{g}"
        );
        assert_eq!(*lines.last().unwrap(), "| all | 2 / 0 / 0 | 3 / 0 / 0 | 5 / 0 / 0 | 10 / 0 / 0 |", "{g}");
        // A report read back from the JSON `run` writes is the same report.
        let json = serde_json::to_string(&reports[1]).unwrap();
        assert_eq!(serde_json::from_str::<Report>(&json).unwrap(), reports[1]);
    }

    /// Member 21 of seed 1, a 116 W 34 V 8-pole motor at 4 kHz: its stationary-frame PI passes
    /// the certificate only down at 54 rad/s, where every phase current lags its reference at
    /// speed and the open-phase check tripped 46 of 64 campaign runs of a healthy drive; the
    /// field frame passes at 1 753 rad/s. Tune takes the faster frame, and no healthy run
    /// trips (tracking is judged elsewhere: issue 51's requirements).
    #[test]
    fn tune_takes_the_faster_frame_and_the_healthy_drive_does_not_trip() {
        let m = draw(1, 21, None).unwrap();
        assert!(m.name.starts_with("021-116W-34V-8p"), "{}", m.name);
        let plan = Plan {
            campaign_runs: 64,
            seed: 1,
            matrix: false,
            speed: SpeedDesign::SaturatedP,
            sensorless: false,
            overmodulation: false,
        };
        let r =
            evaluate(&m, Some(4000.0), Path::new(env!("CARGO_MANIFEST_DIR")), &plan, &AtomicBool::new(false));
        let omega_c = r.omega_c_rad_s.unwrap_or_else(|| panic!("{:?}", r.verdict));
        assert!(omega_c > 1000.0, "crossover {omega_c} rad/s");
        assert_eq!(r.campaign.map(|c| c[1]), Some(64), "{:?}", r.verdict);
        // Tune and the campaign timed, within the member's time; no matrix asked for.
        let [tune_s, campaign_s, matrix_s] = r.stages_s;
        assert!(tune_s > 0.0 && campaign_s > 0.0 && matrix_s == 0.0, "{:?}", r.stages_s);
        assert!(tune_s + campaign_s <= r.elapsed_s, "{:?} of {}", r.stages_s, r.elapsed_s);
        let tripped: Vec<_> = r.campaign_failures.iter().filter(|(k, _)| k.contains("fault")).collect();
        assert!(tripped.is_empty(), "healthy runs tripped: {tripped:?}");
    }

    /// `member` evaluated at `pwm_hz` as `run` does by default (seed 1, the speed law the
    /// requirements choose, no fault matrix) with `runs` campaign runs, on its encoder or not.
    fn evaluated(member: &Member, pwm_hz: f64, runs: u64, sensorless: bool) -> Report {
        let plan = Plan {
            campaign_runs: runs,
            seed: 1,
            matrix: false,
            speed: SpeedDesign::Auto,
            sensorless,
            overmodulation: false,
        };
        evaluate(member, Some(pwm_hz), Path::new(env!("CARGO_MANIFEST_DIR")), &plan, &AtomicBool::new(false))
    }

    /// Member `index` of seed 1 (its name starting with `name`) tuned at `pwm_hz` as `run`
    /// tunes it, its template first through `edit`: the result, its file and the bus it
    /// runs on.
    fn tuned_member(
        index: u64,
        name: &str,
        pwm_hz: f64,
        edit: fn(&str) -> Result<String, String>,
    ) -> (design::tune::Tuned, DriveFile, f64) {
        tuned_member_with(index, name, Some(pwm_hz), edit, SpeedDesign::Auto)
    }

    /// [`tuned_member`] with the speed law `speed` asked of tune, at `pwm_hz` or (`None`) at
    /// the member's own rate.
    fn tuned_member_with(
        index: u64,
        name: &str,
        pwm_hz: Option<f64>,
        edit: fn(&str) -> Result<String, String>,
        speed: SpeedDesign,
    ) -> (design::tune::Tuned, DriveFile, f64) {
        let m = draw(1, index, None).unwrap();
        assert!(m.name.starts_with(name), "{}", m.name);
        let (path, text, vdc) = inputs(&m, pwm_hz, Path::new(env!("CARGO_MANIFEST_DIR"))).unwrap();
        let text = edit(&text).unwrap();
        let structure = Structure { current: CurrentDesign::Pi, speed };
        let tuned = design::tune::tune(Path::new(&path), &text, &m.motor, None, structure).unwrap();
        let file = DriveFile::parse(Path::new(&path), &tuned.text).unwrap();
        (tuned, file, vdc)
    }

    /// The fault-matrix row `case` at `point` (`motoring` or generating) of member `index`
    /// tuned at `pwm_hz` (`None`: its own rate; [`tuned_member`], the template as written),
    /// run as the whole matrix runs it (its index seeds the sensors).
    fn member_row(
        index: u64,
        name: &str,
        pwm_hz: Option<f64>,
        case: &str,
        point: hil_sim::faults::Point,
        motoring: bool,
    ) -> hil_sim::faults::Outcome {
        let (tuned, file, vdc) = tuned_member_with(index, name, pwm_hz, |t| Ok(t.into()), SpeedDesign::Auto);
        matrix_row(&Matrix::of_file(&file, tuned.certify.omega_r_max_rad_s, vdc), case, point, motoring)
    }

    /// `matrix`'s row `case` at `point` (`motoring` or generating), run as the whole matrix
    /// runs it.
    fn matrix_row(
        matrix: &Matrix,
        case: &str,
        point: hil_sim::faults::Point,
        motoring: bool,
    ) -> hil_sim::faults::Outcome {
        let rows = matrix.rows().unwrap();
        let (k, c, at) = rows
            .iter()
            .find(|(_, c, at)| c.name == case && at.point == point && at.motoring == motoring)
            .unwrap();
        matrix.run_one(*k, c, at, matrix.expect(c, at), &AtomicBool::new(false)).unwrap()
    }

    /// `member` tuned at `pwm_hz` as `run` tunes it (the speed law the requirements choose):
    /// the result, the template's path and the bus it runs on.
    fn tune_member(member: &Member, pwm_hz: f64, root: &Path) -> (design::tune::Tuned, String, f64) {
        let (path, text, vdc) = inputs(member, Some(pwm_hz), root).unwrap();
        let structure = Structure { current: CurrentDesign::Pi, speed: SpeedDesign::Auto };
        (design::tune::tune(Path::new(&path), &text, &member.motor, None, structure).unwrap(), path, vdc)
    }

    /// Member 21 at 10 kHz on the default requirements: the P droops and seed 000's own PI
    /// (the region with the P's bandwidth, its deepest point) overshoots a torque-limited
    /// reversal by 13.9 % at its best setpoint weight, so tune refused it. The search of
    /// the region without the bandwidth floor finds a PI inside seed 000's margins that the
    /// prediction and the corner runs in SIL both say meets them, and the tuned drive passes
    /// its campaign.
    #[test]
    fn the_region_search_tunes_a_motor_seed_000s_own_pi_could_not() {
        let m = draw(1, 21, None).unwrap();
        let (tuned, _, _) = tune_member(&m, 10_000.0, Path::new(env!("CARGO_MANIFEST_DIR")));
        assert!(tuned.predicted_misses.is_empty(), "{:?}", tuned.predicted_misses);
        let controller_core::speed::SpeedLaw::PiTorque { kp, ki, .. } = tuned.spec.speed_law else {
            panic!("{:?}", tuned.spec.speed_law)
        };
        let c = tuned.certify;
        let j = m.motor.j_kgm2();
        let regions = design::pi_region::SpeedRegions::new(
            [j * c.j_factor[0], j * c.j_factor[1]],
            m.motor.b_nms(),
            f64::from(tuned.spec.slow_divider) / tuned.spec.pwm_frequency_hz,
            [c.phase_margin_deg_min, c.gain_margin_db_min],
        )
        .unwrap();
        assert!(regions.margins(kp, ki), "k_p {kp}, k_i {ki} outside seed 000's margins");
        let r = evaluated(&m, 10_000.0, 64, false);
        assert_eq!(r.verdict, Verdict::Pass, "{:?}", r.campaign_failures);
    }

    /// Every law tune writes is run in software in the loop before it is written, seed
    /// 000's own point too, and says so. Member 013 (162 W, 17 V, 2 poles) at 10 kHz: seed
    /// 000's point is predicted to meet the requirements and meets them on the corner runs
    /// of 1 s (which reach its top speed: tune's one campaign, `design::tune::TuneCampaigns`);
    /// the drive passes the population's 200 runs.
    #[test]
    fn the_law_tune_writes_is_met_in_sil_first() {
        let m = draw(1, 13, None).unwrap();
        let (tuned, _, _) = tune_member(&m, 10_000.0, Path::new(env!("CARGO_MANIFEST_DIR")));
        assert!(
            tuned.speed_origin.contains("met on the 64 corner runs of the 1.00 s campaign in SIL"),
            "{}",
            tuned.speed_origin
        );
        let r = evaluated(&m, 10_000.0, 200, false);
        assert_eq!(r.verdict, Verdict::Pass, "{:?}", r.campaign_failures);
        // Where no point's drive meets them, tune refuses and says what the corner runs
        // missed: the 24 V template (design's `the_requirements_choose_the_speed_law_or_refuse_naming_them`).
        // Member 013 at 20 kHz refused so until the references' precompensation; it passes since.
    }

    /// The population's campaign takes the corner runs `design tune` ran and passed as its
    /// own (`Tuned::passed_corner_runs_of`) only where they are the same runs. Member 013 at
    /// 10 kHz, whose tune campaign reaches its top speed: the tuned file's campaign is it but
    /// for its 200 runs, and run again its 64 corner runs all pass; another seed, run length
    /// or shard is another campaign.
    #[test]
    fn the_corner_runs_tune_passed_are_the_campaigns_own() {
        use hil_sim::campaign::CORNER_RUNS;
        let m = draw(1, 13, None).unwrap();
        let (tuned, path, vdc) = tune_member(&m, 10_000.0, Path::new(env!("CARGO_MANIFEST_DIR")));
        let file = DriveFile::parse(Path::new(&path), &tuned.text).unwrap();
        let c = full_range_campaign_of(&file, vdc, 200, 1).unwrap();
        assert!(tuned.passed_corner_runs_of(&c));
        let corners = c.run_where(|k| k < CORNER_RUNS, |_| {}, &AtomicBool::new(false)).unwrap();
        assert_eq!(corners.len() as u64, CORNER_RUNS);
        assert!(corners.iter().all(|v| v.passed()));
        for other in [
            Campaign { seed: 2, ..c },
            Campaign { duration_s: c.duration_s + 0.1, ..c },
            Campaign { shard: (0, 2), ..c },
        ] {
            assert!(!tuned.passed_corner_runs_of(&other), "{other:?}");
        }
    }

    /// Where tune lowers the speed loop's torque limit below the template's, the file's stall
    /// and following times (derived from that limit) move with it; tune confirmed its drive
    /// in software in the loop with the template's, 0.3–3 % off, so the population ran member
    /// 007's and 010's corner runs twice (at every rate). Member 007 at 20 kHz: its campaigns in
    /// SIL carry the written file's protection, and its corner runs are the campaign's own.
    #[test]
    fn tune_confirms_the_protection_its_file_derives() {
        let m = draw(1, 7, None).unwrap();
        let (tuned, path, vdc) = tune_member(&m, 20_000.0, Path::new(env!("CARGO_MANIFEST_DIR")));
        let file = DriveFile::parse(Path::new(&path), &tuned.text).unwrap();
        assert!(!tuned.sil_campaigns.is_empty());
        for sil in &tuned.sil_campaigns {
            assert_eq!(sil.spec.protection, file.spec.protection);
        }
        let c = full_range_campaign_of(&file, vdc, 200, 1).unwrap();
        assert!(tuned.passed_corner_runs_of(&c));
    }

    /// Tune runs up to `SIL_CONFIRMATIONS` (8) points of the region in software in the loop
    /// before it refuses, each at its setpoint weight stepped down while its drive misses only
    /// what the weight shapes. Member 022 (35 kW) at 20 kHz: with two points run in SIL tune
    /// refused it (the last, k_p 8.11, k_i 14.90 at weight 0.6, overshot in its corner runs of
    /// 1.21 s); the search now goes on and meets them at the 10th point tried.
    #[test]
    fn tune_searches_on_where_the_first_points_drive_overshoots_in_sil() {
        let m = draw(1, 22, None).unwrap();
        assert!(m.name.starts_with("022-35kW"), "{}", m.name);
        let (tuned, _, _) = tune_member(&m, 20_000.0, Path::new(env!("CARGO_MANIFEST_DIR")));
        assert!(tuned.predicted_misses.is_empty(), "{:?}", tuned.predicted_misses);
        let o = &tuned.speed_origin;
        let tried: usize = o
            .split(" tried")
            .next()
            .and_then(|head| head.rsplit(' ').next())
            .and_then(|n| n.parse().ok())
            .unwrap_or_else(|| panic!("{o}"));
        assert!(
            tried > 3 && o.contains("in SIL") && o.contains("was predicted to meet them and missed"),
            "{o}"
        );
    }

    /// The voltage check names a bridge fault by where the applied voltage departs from the
    /// model's, not by where the applied voltage lies. `drive.toml`'s perturbed motor, an
    /// upper switch stuck open: at rest (4 and 10 kHz) the other two legs wind up to push
    /// the current the dead leg does not, the applied voltage lies off every phase's axis,
    /// and the check named the encoder (`EncoderImplausible` 104 ms after the injection,
    /// motoring; 140.5 ms generating, at 4 kHz); at mid-speed generating (20 kHz) the field
    /// turned too fast for the applied voltage's axis to be judged (`EncoderImplausible`
    /// after 27.5 ms). What the bridge did not apply lies on phase a's axis in both. The
    /// rows at rest run at 10 kHz since the plan's delay: at 4 kHz tune refuses this motor
    /// (its top-speed generating corner run at R_s ×1.5 misses the torque accuracy, 0.056
    /// against 0.05, on a magnetizing fit that reads ℓ̂ 0.874 where the motor's is 1 —
    /// 0.897 with the plan adopted at its tick; docs/decisions.md).
    #[test]
    fn a_stuck_switch_at_rest_is_named_by_what_the_bridge_did_not_apply() {
        use hil_sim::faults::Point;
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let m = crate::member::shipped(&root)
            .unwrap()
            .into_iter()
            .find(|m| m.name.contains("perturbed"))
            .unwrap();
        let cancel = AtomicBool::new(false);
        // Tuned once per rate: the two rows at rest share their drive.
        let tuned_at = |pwm_hz: f64| {
            let (tuned, path, vdc) = tune_member(&m, pwm_hz, &root);
            let file = DriveFile::parse(Path::new(&path), &tuned.text).unwrap();
            Matrix::of_file(&file, tuned.certify.omega_r_max_rad_s, vdc)
        };
        let (at_10k, at_20k) = (tuned_at(10_000.0), tuned_at(20_000.0));
        for (pwm_hz, matrix, point, motoring) in [
            (10_000.0, &at_10k, Point::Standstill, true),
            (10_000.0, &at_10k, Point::Standstill, false),
            (20_000.0, &at_20k, Point::Mid, false),
        ] {
            // The row as the whole matrix runs it (its index seeds the sensors).
            let rows = matrix.rows().unwrap();
            let (k, c, at) = rows
                .iter()
                .find(|(_, c, at)| {
                    c.name == "switch a upper stuck open" && at.point == point && at.motoring == motoring
                })
                .unwrap();
            let o = matrix.run_one(*k, c, at, matrix.expect(c, at), &cancel).unwrap();
            let row = hil_sim::faults::row_name(c, at);
            assert_eq!(
                o.detected.map(|d| d.0),
                Some(controller_core::drive::Fault::OpenPhase),
                "{row} at {pwm_hz} Hz"
            );
            assert!(o.passed(), "{row} at {pwm_hz} Hz: {:?}", o.failures);
        }
    }

    /// The 8-pole member 018 (7.2 kW) at 10 kHz as tune tunes it: phase a's lead opens at
    /// rest, motoring, as its reference crosses zero — the field turns at the slip
    /// frequency, ≈ 3 rad/s, and phase a is asked for less than a fifth of the others'
    /// current for the first 50 ms; the open lead takes nothing the drive asks for until then.
    /// Judged from the first moment its phase is asked for half the reference vector's
    /// current (`hil_sim::faults::phase_asked_after_s`), the row passes, named `OpenPhase`
    /// 52.1 ms after the injection; from the injection it failed against 50 ms.
    #[test]
    fn an_open_lead_at_its_phases_zero_crossing_is_judged_from_its_need() {
        use hil_sim::faults::Point;
        let o = member_row(18, "018-7.2kW", Some(10_000.0), "open phase a", Point::Standstill, true);
        let (fault, after_s) = o.detected.unwrap();
        assert_eq!(fault, controller_core::drive::Fault::OpenPhase);
        assert!(
            after_s > hil_sim::faults::OPEN_PHASE_BOUND_S,
            "{after_s}: the injection is at the zero crossing"
        );
        assert!(o.passed(), "{:?} {:?}", o.detected, o.failures);
    }

    /// The 162 W, 17 V member (013) at 4 kHz as tune tunes it: phase a's lower switch stuck
    /// open at top speed, generating, with phase a's current negative and its leg at a duty
    /// of 0.985 — the dead switch moves the duty by 1.5 % of the period, less than where a
    /// stuck switch counts as mattering by its voltage (`hil_sim::sim::SWITCH_ACTING_DUTY`),
    /// but its current now flows through the upper diode, not the low-side shunt: the
    /// sensors read nothing in phase a, the current sum trips `CurrentSensor` in the next
    /// sample, and the matrix failed the row ("although the switch never mattered"). A dead
    /// lower switch that hides its phase from the shunts matters from that sample.
    #[test]
    fn a_dead_lower_switch_that_hides_its_phase_from_the_shunts_matters() {
        use hil_sim::faults::Point;
        let o = member_row(13, "013-162W", Some(4_000.0), "switch a lower stuck open", Point::Top, false);
        let (fault, after_s) = o.detected.unwrap();
        assert_eq!(fault, controller_core::drive::Fault::CurrentSensor);
        assert_eq!(o.acting_after_s, Some(0.0), "{:?}", o.failures);
        assert!(after_s <= 1e-3, "{after_s}");
        assert!(o.passed(), "{:?} {:?}", o.detected, o.failures);
    }

    /// The 153 kW member (010) at 4 kHz: phase a's upper switch stuck open at top speed,
    /// motoring. The back-EMF drives the phase's current the other way through the upper
    /// diode in its positive half-waves, while the speed loop, asking back the lost torque,
    /// grows the references beyond what the bus drives, so the live direction no longer
    /// *follows*; the check waited for it and named the switch after 150–184 ms against the
    /// row's bound of 52.6 ms (the sample's one failure at 4 kHz). Named on the dead
    /// direction's reversed current (`SWITCH_FOLLOWING_SHARE`), within 30 ms.
    #[test]
    fn a_dead_switch_at_top_speed_is_named_by_the_current_driven_the_other_way() {
        use hil_sim::faults::Point;
        let o = member_row(10, "010-153kW", Some(4_000.0), "switch a upper stuck open", Point::Top, true);
        let (fault, after_s) = o.detected.unwrap();
        assert_eq!(fault, controller_core::drive::Fault::SwitchOpen);
        assert!(after_s < 0.03, "{after_s}");
        assert!(o.passed(), "{:?} {:?}", o.detected, o.failures);
    }

    /// A switch stuck open at rest, where the field turns at the slip frequency, at the two
    /// ends of the dead direction's need, each at the member's own rate:
    /// - the 7.4 kW member 184 (7.9 kHz), phase a's reference at its positive peak: b and c
    ///   are asked for ≈ 1 A between them against a's 20 A, the dead phase holds them at zero
    ///   and the motor carries no current — `NoMotorCurrent` after 9.0 ms, the open lead's
    ///   name at rest (it failed as "detected as NoMotorCurrent");
    /// - the 478 W member 088 (7.4 kHz), injected at the waning end of phase a's positive
    ///   half-wave: the field measured before the injection (4.5 rad/s) puts the dead
    ///   direction's next need past the run's observation, but the field turns faster with
    ///   a phase's direction gone and `OpenPhase` comes after 563 ms, as phase a's reference
    ///   comes back its dead way — a name within the observation, judged as any; the bound
    ///   was capped at a fixed half second after the first need (550 ms) and failed it.
    #[test]
    fn a_stuck_switch_at_rest_is_judged_from_when_its_direction_is_needed() {
        use controller_core::drive::Fault;
        use hil_sim::faults::Point;
        for (index, name, fault, from_injection) in [
            (184, "184-7.4kW", Fault::NoMotorCurrent, 0.0..hil_sim::faults::OPEN_PHASE_BOUND_S),
            (88, "088-478W", Fault::OpenPhase, 0.5..hil_sim::faults::OBSERVE_S),
        ] {
            let o = member_row(index, name, None, "switch a upper stuck open", Point::Standstill, true);
            let (detected, after_s) = o.detected.unwrap();
            assert_eq!(detected, fault, "{name}");
            assert!(from_injection.contains(&after_s), "{name}: {after_s} s");
            assert!(o.passed(), "{name}: {:?} {:?}", o.detected, o.failures);
        }
    }

    /// The 24 kW member 181 at its own 7.2 kHz, phase a's upper switch stuck open at top
    /// speed, motoring: each time phase a's positive half-wave comes, the dead switch holds
    /// the phase at the lower rail, the voltage regulator shrinks the references (≈ 22 →
    /// 10 A) and phase a's current flows the other way (−18 A against +11 A asked). The
    /// stuck-switch check kept every sample out while the references fell, which was every
    /// dead visit: `SwitchOpen` after 86.8 ms against a bound of 52.9 ms. Judged with the
    /// fall allowed (controller-core's `SwitchWatch::add`), it is named within the bound.
    #[test]
    fn a_stuck_switch_that_shrinks_the_references_at_top_speed_is_named_in_time() {
        use hil_sim::faults::Point;
        let o = member_row(181, "181-24kW", None, "switch a upper stuck open", Point::Top, true);
        assert_eq!(o.detected.map(|d| d.0), Some(controller_core::drive::Fault::SwitchOpen));
        assert!(o.passed(), "{:?} {:?}", o.detected, o.failures);
    }

    /// The 52 kW 8-pole member 178 at its own 8 kHz: J = 10 kg·m² against a speed PI of
    /// k_p 25.6 N·m·s/rad — the law takes ≈ 0.3 s to reach its limit under the 1.5 × τ_max
    /// overload, and the following-error check counts only from there: named 525 ms after
    /// the overload at mid-speed, motoring, it failed issue 18's 0.5 s. Judged from the
    /// law's reach on the ideal loop plus the time the check needs there (and the rotor's
    /// pause through rest, which it crosses as the check would speak), it passes.
    #[test]
    fn an_overload_on_a_slow_speed_loop_is_judged_from_its_reach_to_the_limit() {
        use hil_sim::faults::{Expect, Point, STALL_BOUND_S};
        let o = member_row(178, "178-52kW", None, "overload (1.5 × τ_max)", Point::Mid, true);
        assert_eq!(o.detected.map(|d| d.0), Some(controller_core::drive::Fault::FollowingError));
        assert!(o.detected.is_some_and(|(_, t)| t > STALL_BOUND_S), "{:?}", o.detected);
        assert!(
            matches!(o.expect, Expect::Either { bound_s, .. } if bound_s > STALL_BOUND_S),
            "{:?}",
            o.expect
        );
        assert!(o.passed(), "{:?} {:?}", o.detected, o.failures);
    }

    /// Healthy drives arriving at top speed to generate, at their own PWM rates: the speed
    /// loop drops the torque from its limit to nearly nothing within a few milliseconds, and
    /// at the voltage limit the loops undershoot the fall — member 068 (34 kW, 690 V, 6.5 kHz):
    /// currents of 1.3–3 A against references of 6–8 A for 8 ms; member 020 (73 kW, 690 V,
    /// 5.7 kHz): 4–8 A against 18–20 A. The stuck-switch check read a dead direction in
    /// them and tripped `SwitchOpen` before the matrix's injection (068's encoder glitch,
    /// bus sag and surge and short rows, 020's load seizure). Samples taken while the
    /// references have just fallen do not count (`controller_core`'s `SwitchWatch::add`):
    /// each row names its own fault.
    #[test]
    fn loops_undershooting_a_torque_fall_at_top_speed_trip_nothing() {
        use controller_core::drive::Fault;
        use hil_sim::faults::Point;
        for (index, name, row) in
            [(68, "068-34kW", "encoder glitch 100 counts"), (20, "020-73kW", "load seizure (10 × τ_max)")]
        {
            let o = member_row(index, name, None, row, Point::Top, false);
            assert_ne!(o.detected.map(|d| d.0), Some(Fault::SwitchOpen), "{name}: {:?}", o.failures);
            assert!(o.passed(), "{name} {row}: {:?} {:?}", o.detected, o.failures);
        }
    }

    /// Sensor faults at standstill, where the field turns at the slip frequency and a phase's
    /// current can sit near zero for tens of milliseconds, judged as the check judges: the
    /// error all three channels sum to (the healthy ones' gain errors included), its mean over
    /// the check's window clear of the windowed level by the noise's resolution
    /// (`hil_sim::faults::SENSOR_VERDICT_SIGMAS`) for a whole window. Each row failed on a
    /// looser reading of "acting", and passes named `CurrentSensor`:
    /// - the 2.8 kW member 007 at 20 kHz, gain 0.5 generating, phase b held within ±0.8 A of
    ///   zero while the others carry 5 A: bound from a single sample at the level, named
    ///   51.95 ms late;
    /// - the 35 kW member 153 at its 16.7 kHz, gain 0.5 generating: the error 3.3 A within
    ///   0.4 A of its level for 13 ms (phase c's +0.5 % gain taking 0.15 A of it), named
    ///   3.4 ms late from the sliding mean's first touch of the bare level;
    /// - the 2.7 kW member 086 at its 7.8 kHz, sensor b dead motoring: the error touched the
    ///   level for a millisecond, fell back and came again 8 ms later, named 1.1 ms late from
    ///   the first touch.
    #[test]
    fn a_sensor_fault_near_its_phases_zero_is_judged_on_the_checks_window() {
        use hil_sim::faults::Point;
        for (index, name, pwm_hz, row, motoring) in [
            (7, "007-2.8kW", Some(20_000.0), "sensor b gain 0.5", false),
            (153, "153-35kW", None, "sensor b gain 0.5", false),
            (86, "086-2.7kW", None, "sensor b dead", true),
        ] {
            let o = member_row(index, name, pwm_hz, row, Point::Standstill, motoring);
            assert_eq!(o.detected.map(|d| d.0), Some(controller_core::drive::Fault::CurrentSensor), "{name}");
            assert!(o.passed(), "{name}: {:?} {:?}", o.detected, o.failures);
        }
    }

    /// An encoder fault is named where the readings can tell it from motion, and stated a gap
    /// where they cannot. Member 012 (6.7 kW, 8 poles, 1 024 lines) at 20 kHz: its encoder
    /// at half its lines at mid-speed (41 rad/s) changed two reads' increments by 0.0061 and
    /// 0.0046 rad against its jump level of 0.0063 rad and ran on (`FollowingError` after 28 ms
    /// motoring, undetected generating) — the second difference over two reads sees the
    /// change whole: `EncoderLoss`, within the three slow periods the matrix allows a change
    /// seen at that spacing. Member 001 (1.3 kW, 8 poles, 500 lines): a counter that stops at
    /// its mid-speed, 36 rad/s, changes the readings less than a seizure of ten times its
    /// torque would at any spacing (`Matrix::encoder_reach`), so the rows at mid-speed are
    /// stated gaps (they failed as `Stall` and `FollowingError`, and one ran on undetected).
    /// Member 013 (162 W, 2 poles, 2 048 lines) at 10 kHz: its encoder at half its lines at
    /// 150 rad/s is named within 0.6 ms where the fault falls on a read, as the matrix injects
    /// it — a gap by the worst alignment, a "gap closed" failure until the matrix judged the
    /// alignment it injects at.
    #[test]
    fn an_encoder_fault_is_named_where_the_readings_can_tell_it() {
        use hil_sim::faults::{Expect, Point};
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let cancel = AtomicBool::new(false);
        for (index, pwm_hz, named) in [(12, 20_000.0, true), (1, 20_000.0, false), (13, 10_000.0, true)] {
            let m = draw(1, index, None).unwrap();
            let (tuned, path, vdc) = tune_member(&m, pwm_hz, &root);
            let file = DriveFile::parse(Path::new(&path), &tuned.text).unwrap();
            let matrix = Matrix::of_file(&file, tuned.certify.omega_r_max_rad_s, vdc);
            let rows = matrix.rows().unwrap();
            let mid: Vec<_> = rows
                .iter()
                .filter(|(_, c, at)| {
                    matches!(c.name, "encoder stuck" | "encoder at half its lines") && at.point == Point::Mid
                })
                .collect();
            assert_eq!(mid.len(), 4, "{}", m.name);
            for (k, c, at) in mid {
                let row = hil_sim::faults::row_name(c, at);
                let expect = matrix.expect(c, at);
                if !named {
                    assert!(matches!(expect, Expect::Gap { .. }), "{}: {row}: {expect:?}", m.name);
                    continue;
                }
                let o = matrix.run_one(*k, c, at, expect, &cancel).unwrap();
                assert_eq!(
                    o.detected.map(|d| d.0),
                    Some(controller_core::drive::Fault::EncoderLoss),
                    "{}: {row}",
                    m.name
                );
                assert!(o.passed(), "{}: {row}: {:?}", m.name, o.failures);
            }
        }
    }

    /// Member 018 (7.2 kW, 8 poles, a coupled load) at 20 kHz holds its load at rest on a
    /// field that turns at the slip frequency, a fraction of a hertz: phase a's upper switch,
    /// stuck open as the matrix injects it, acts only on the waning tail of a positive
    /// half-wave, and its dead direction's next peak comes after the row's 0.6 s of
    /// observation. No check can see a direction nobody asks for: the row passes undetected
    /// (it failed "not detected" until the matrix judged a switch by a peak within the run),
    /// and the drive stays Running.
    #[test]
    fn a_stuck_switch_not_needed_again_within_the_run_is_no_miss() {
        use hil_sim::faults::Point;
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let m = draw(1, 18, None).unwrap();
        let (tuned, path, vdc) = tune_member(&m, 20_000.0, &root);
        let file = DriveFile::parse(Path::new(&path), &tuned.text).unwrap();
        let matrix = Matrix::of_file(&file, tuned.certify.omega_r_max_rad_s, vdc);
        let rows = matrix.rows().unwrap();
        let cancel = AtomicBool::new(false);
        for motoring in [true, false] {
            let (k, c, at) = rows
                .iter()
                .find(|(_, c, at)| {
                    c.name == "switch a upper stuck open"
                        && at.point == Point::Standstill
                        && at.motoring == motoring
                })
                .unwrap();
            let o = matrix.run_one(*k, c, at, matrix.expect(c, at), &cancel).unwrap();
            let row = hil_sim::faults::row_name(c, at);
            assert_eq!(o.detected, None, "{row}");
            assert!(o.passed(), "{row}: {:?}", o.failures);
        }
    }

    /// Failures group by family: a trip before the injection and an unreached point are
    /// families of their own, other rows by case and how, campaign runs per criterion.
    #[test]
    fn failures_group_by_family() {
        let report = |matrix: &[&str], campaign: &[(&str, u64)]| Report {
            member: "m".into(),
            power_w: None,
            pwm_hz: 4000.0,
            vdc_v: 310.0,
            omega_c_rad_s: None,
            campaign: None,
            campaign_runs_from_tune: 0,
            campaign_failures: campaign.iter().map(|(k, n)| ((*k).into(), *n)).collect(),
            matrix: None,
            matrix_failures: matrix.iter().map(|s| (*s).into()).collect(),
            verdict: Verdict::Pass,
            elapsed_s: 0.0,
            stages_s: [0.0; STAGES],
        };
        let reports = [
            report(
                &[
                    "open phase a at top speed generating: Fault(SwitchOpen) before the injection (at 0.7680 s); \
                     the operating point was not reached (283.6 rad/s, …)",
                    "switch a upper stuck open at mid-speed generating: SwitchOpen after 69.00 ms, bound 64.62 ms",
                ],
                &[("generating fault+tracking", 7), ("motoring tracking", 50)],
            ),
            report(
                &["switch a upper stuck open at standstill motoring: not detected (Running at the end)"],
                &[("reversal tracking", 3)],
            ),
        ];
        let f = families(&reports);
        let get = |name: &str| f.iter().find(|x| x.name == name).map(|x| (x.count, x.drives));
        assert_eq!(get("campaign: tracking"), Some((60, 2)));
        assert_eq!(get("campaign: fault"), Some((7, 1)));
        assert_eq!(get("matrix: a healthy drive tripped (SwitchOpen) before the injection"), Some((1, 1)));
        assert_eq!(get("matrix: switch a upper stuck open: late"), Some((1, 1)));
        assert_eq!(get("matrix: switch a upper stuck open: missed"), Some((1, 1)));
        assert_eq!(f.first().map(|x| x.count), Some(60));
        assert!(families_table(&f).contains("| campaign: tracking | 60 | 2 |"));
    }

    /// The 153 kW member (010) without its encoder at 20 kHz: every sensorless start runs the
    /// flying start's search, whose windows on this motor are as noisy as the transient they
    /// read; the campaign's corner runs (every corner, each manoeuvre) start at rest and run
    /// without a fault. The least-squares search read that rotor at rest as turning beyond
    /// the overspeed level: every run tripped `Overspeed`. Then, with the observer's
    /// correction switched at its flux floor, the estimate magnetized at the floor in some
    /// runs and the drive ran away at a zero speed reference (`FollowingError` in 1 of the
    /// 64; the mechanism, every time: `observer`'s test
    /// `the_observer_magnetizes_through_its_flux_floor_under_noise`). The start is judged on
    /// the shortest runs the campaign takes (`MIN_AFTER_STEP_S` after each event) of the
    /// saturated P, whose speed steps to what the heaviest corner reaches in them:
    /// at its top speed this member's drive does not yet hold its currents (issue 52,
    /// docs/population.md), and tune refuses it there.
    #[test]
    fn a_large_motors_sensorless_start_at_rest_is_not_read_as_turning() {
        let m = draw(1, 10, None).unwrap();
        assert!(m.name.starts_with("010-153kW"), "{}", m.name);
        let (path, text, vdc) = inputs(&m, Some(20_000.0), Path::new(env!("CARGO_MANIFEST_DIR"))).unwrap();
        let text = with_sensorless(&text).unwrap();
        let structure = Structure { current: CurrentDesign::Pi, speed: SpeedDesign::SaturatedP };
        let tuned = design::tune::tune(Path::new(&path), &text, &m.motor, None, structure).unwrap();
        let file = DriveFile::parse(Path::new(&path), &tuned.text).unwrap();
        let mut c = campaign_of(&file, vdc, 64, 1).unwrap();
        c.duration_s = c.step_s() + 2.0 * hil_sim::campaign::MIN_AFTER_STEP_S;
        let faults = faulted(&c);
        assert!(faults.is_empty(), "{faults:#?}");
    }

    /// The 1.3 kW two-pole member (003) at 20 kHz, tuned and run overmodulating: none of the
    /// 200 campaign runs faults. Found by `population run --overmodulation`: along the cut
    /// hexagon's edges the middle phase sits exactly on the sampled limit, the dead-time
    /// compensation puts it exactly on the window's, and the drive's f32 rounding of that
    /// limit read it as lost too — two phases lost in every such period, the current
    /// predicted from the last prediction, frozen for six periods while the loops drove phase
    /// b to −6.3 A at a torque reversal at top speed: `Overcurrent` in 4 of the 200 runs
    /// (`svpwm::WINDOW_ROUNDING_DUTY`).
    #[test]
    fn an_overmodulating_drive_reverses_at_top_speed_on_its_measured_currents() {
        let (_, file, vdc) = tuned_member(3, "003-1.3kW", 20_000.0, with_overmodulation);
        assert!(file.spec.overmodulation);
        let c = full_range_campaign_of(&file, vdc, 200, 1).unwrap();
        let faults = faulted(&c);
        assert!(faults.is_empty(), "{faults:#?}");
    }

    /// The 196 kW member (014) at 20 kHz as tune tunes it, run 109 of its 200-run campaign:
    /// motoring at its top speed of 375 rad/s under 0.8 × the load it holds there (load
    /// ratio ≈ 7, the voltage at its target), the speed loop's answers to the encoder's
    /// counts push the loops' request beyond the hexagon in ≈ 10 % of the slow periods.
    /// Heard on the unlimited samples only — those of the lowest voltage, so of the lowest
    /// reactive power —, the rotor-resistance law walked to ×1.19 against the rotor's
    /// ×1.297, the flux model ran 9 % under the machine's and the run missed its flux
    /// accuracy (0.0706 against 0.05). On the voltage the bridge was given, limited or not,
    /// the run meets its requirements: the flux within 0.0227 of the rated.
    /// The estimate itself is not the test's quantity: at that load ratio the law's evidence
    /// error is amplified by 1/s(a) ≈ 13 (docs/rotor-resistance.md); loaded it wandered
    /// between ×1.192 and ×1.246 while the law also heard the plans the speed loop had just
    /// moved, and holds ×1.293–1.309 on steady plans only (flux 0.0037;
    /// `hil-sim campaign FILE --trace 109`).
    /// The speed law is the one tune wrote when this was found (k_p 83.23, k_i 214.96,
    /// setpoint weight 0.6), fixed here: tune's search moves on as the drive does (it wrote
    /// k_i 179.14 at weight 0.7 for a while, and these gains again since).
    #[test]
    fn a_loaded_motor_at_the_voltage_limit_holds_its_flux_on_the_rotor_resistance_it_reads() {
        use drive_file::requirements::Requirement::FluxAccuracy;
        let (_, mut file, vdc) = tuned_member(14, "014-196kW", 20_000.0, |t| Ok(t.into()));
        let controller_core::speed::SpeedLaw::PiTorque { limit, .. } = file.spec.speed_law else {
            panic!("{:?}", file.spec.speed_law)
        };
        file.spec.speed_law = controller_core::speed::SpeedLaw::PiTorque {
            kp: 83.2342321116826,
            ki: 214.96444243719685,
            limit,
            setpoint_weight: 0.6,
        };
        let c = full_range_campaign_of(&file, vdc, 200, 1).unwrap();
        let mut rr_scale = f64::NAN;
        let v = c
            .run_one_into(109, &AtomicBool::new(false), &mut |r| {
                rr_scale = r.rr_scale;
                Ok(())
            })
            .unwrap();
        let flux = v.measures.iter().find(|m| m.requirement == FluxAccuracy).unwrap();
        assert!(flux.met(), "{flux:?}; the estimate ×{rr_scale:.4} against the rotor's ×{:.4}", v.sample.rr);
        assert!(v.passed(), "{}", v.csv());
    }

    /// The 65 kW 2-pole member (161) at its own 4.6 kHz as tune tunes it: its top speed in
    /// field weakening is 679 rad/s on the ideal actuator, which settles 2.26 s after the
    /// reference, and the drive is within half the tolerance of it 53 ms after the ideal
    /// wait (its flux follows the falling reference with T_r = 0.69 s, and the flux left above
    /// it takes the voltage the torque needs): at the ideal wait it was at 663 rad/s, 15.5
    /// short, and all 19 top-speed motoring rows failed "not reached". The matrix now
    /// injects once the drive, run healthy, has arrived, and the row judges the fault at the
    /// point it names.
    #[test]
    fn a_drive_slower_than_its_ideal_approach_takes_its_faults_once_it_has_arrived() {
        use hil_sim::faults::{Point, REACHED_TOLERANCE_RAD_S, SETTLE_EXTRA_S};
        let (tuned, file, vdc) =
            tuned_member_with(161, "161-65kW", None, |t| Ok(t.into()), SpeedDesign::Auto);
        let matrix = Matrix::of_file(&file, tuned.certify.omega_r_max_rad_s, vdc);
        let points = matrix.points();
        let settle_s =
            points.iter().filter_map(|p| matrix.approach(p).ok()).map(|a| a.settle_s).fold(0.0, f64::max);
        let ideal_s = matrix.reference_s() + settle_s + SETTLE_EXTRA_S;
        assert!(matrix.inject_s() > ideal_s + 0.02, "{} against the ideal wait {ideal_s}", matrix.inject_s());
        let o = matrix_row(&matrix, "encoder stuck", Point::Top, true);
        let target = matrix.approach(&o.at).unwrap().final_rad_s;
        assert!(
            (o.speed_at_injection_rad_s - target).abs() <= REACHED_TOLERANCE_RAD_S,
            "{} rad/s at the injection against {target}",
            o.speed_at_injection_rad_s
        );
        assert!(o.passed(), "{:?}", o.failures);
    }

    /// The 182 kW member (052) at its own 7.2 kHz as tune tunes it, run 68 of its 200-run
    /// campaign: a rotor ×1.236 hot, motoring to its top speed (314 rad/s, field weakening),
    /// 16 s at no load there, then 0.8 × the load it holds. At no load the speed loop's
    /// answers to the encoder's counts swing the load ratio |i_q|/i_d about the
    /// rotor-resistance law's gate (0.39–0.90, median 0.49): the law heard the samples whose
    /// i_q had just been pushed up — the loops' proportional reaction to that push in their
    /// voltage — and walked from the magnetizing fit's ×1.22 to ×1.04; loaded, the machine's
    /// flux ran 1.38 × the model's (the campaign's bound 1.3) and the field-weakening
    /// regulator hunted (torque 450–485 N·m). Heard only on a plan that held the references
    /// (as the inductance law is), the estimate stays with the rotor.
    #[test]
    fn a_hot_rotor_at_no_load_keeps_the_resistance_its_fit_read() {
        let (_, file, vdc) = tuned_member_with(52, "052-182kW", None, |t| Ok(t.into()), SpeedDesign::Auto);
        let c = full_range_campaign_of(&file, vdc, 200, 1).unwrap();
        // The estimate on the last period before the load step.
        let mut rr_unloaded = f64::NAN;
        let v = c
            .run_one_into(68, &AtomicBool::new(false), &mut |r| {
                if r.load_nm == 0.0 {
                    rr_unloaded = r.rr_scale;
                }
                Ok(())
            })
            .unwrap();
        // The magnetizing fit reads T_r within a few per cent (docs/rotor-resistance.md).
        let off = rr_unloaded / v.sample.rr - 1.0;
        assert!(off.abs() < 0.05, "×{rr_unloaded:.4} against the rotor's ×{:.4}", v.sample.rr);
        assert!(v.flux_ratio[1] <= hil_sim::campaign::FLUX_MODEL_BAND[1], "{}", v.csv());
        assert!(v.passed(), "{}", v.csv());
    }

    /// The 1.3 kW 8-pole member (001) at 20 kHz with the speed PI tune's search found for it
    /// (k_p 0.633, k_i 6.98, setpoint weight 0.8): on the 64 corner runs of 1 s — speed
    /// steps to ±145 rad/s at the torque limit, into field weakening — no healthy run trips.
    /// Loaded, its flux target falls from ≈ 58 rad/s, 20 % before the no-load base speed
    /// (71 rad/s) where the flux's fast fall was blended in: the flux left behind, forced
    /// there with the full gain, swung i_d* by 1.5 A per encoder count, the torque fell from
    /// 27 to 0 N·m for 5 ms and the stuck-switch check read the currents that could not
    /// follow as a dead switch (`SwitchOpen` in 7 of 64 runs; `hil-sim campaign --trace 24`
    /// shows it). Motoring, the fast fall now blends in where the target itself falls.
    #[test]
    fn a_loaded_motor_weakens_its_field_where_its_target_falls() {
        let c = pi_campaign(1, "001-1.3kW", [6.3328e-1, 6.9783, 0.8], 1.0);
        assert!(c.omega_s_rad_s() > 2.0 * 71.0, "steps to {} rad/s", c.omega_s_rad_s());
        let faults = faulted(&c);
        assert!(faults.is_empty(), "{faults:#?}");
    }

    /// The 7.3 kW member (002) at 4 kHz with the speed PI its refusal named while tune left
    /// the slip on the reference (k_p 6.6725, k_i 118.17): on the 64 corner runs to its top
    /// speed, braking an overhauling load there on the R_r × 1.5, L × 1.05 corners (runs 26
    /// and 58, J × 1 and × 2), the field turned at the slip of
    /// the reference leaves the rotor's flux, which swings until the speed runs away
    /// (`FollowingError`); turned at the slip of the measured q current
    /// (`slip_current = "measured"`, which tune now writes) no run faults (docs/envelope.md,
    /// docs/population.md). The swing was found on field-frame loops without their
    /// decoupling, which the reference's slip needs to fault: decoupled, the loops follow the
    /// reference's torque falls closely enough that it runs on (`current_decoupling`,
    /// docs/envelope.md).
    #[test]
    fn a_braking_drive_turns_its_field_at_the_slip_its_rotor_sees() {
        let mut c = pi_campaign_at(2, "002-7.3kW", [6.6725, 118.17, 1.0], 1.0, 4_000.0);
        c.duration_s = c.full_range_duration_s();
        assert_eq!(c.spec.current_frame, controller_core::drive::CurrentFrame::Synchronous);
        c.spec.slip_current = controller_core::drive::SlipCurrent::Reference;
        c.spec.current_decoupling = false;
        let on_reference = faulted(&c);
        assert!(!on_reference.is_empty());
        // k, R_s, R_r, L, J, manoeuvre: braking on the box's R_r × 1.5, L × 1.05 corners.
        let corner =
            |r: &String| r.split(',').nth(2) == Some("1.500000") && r.split(',').nth(3) == Some("1.050000");
        assert!(on_reference.iter().all(|r| corner(r) && r.contains(",generating,")), "{on_reference:#?}");
        assert!(on_reference.iter().all(|r| r.contains("Fault(FollowingError)")), "{on_reference:#?}");
        c.spec.slip_current = controller_core::drive::SlipCurrent::Measured;
        let on_measured = faulted(&c);
        assert!(on_measured.is_empty(), "{on_measured:#?}");
        c.spec.current_decoupling = true;
        let decoupled = faulted(&c);
        assert!(decoupled.is_empty(), "{decoupled:#?}");
    }

    /// The 33 kW 8-pole member (016) at 20 kHz with the speed PI tune's search found for it
    /// (k_p 68.8, k_i 710.9, setpoint weight 0.9): on the 64 corner runs to its top speed
    /// (2.96 s), the generating ones brake an overhauling load of 0.8 × what the motor holds
    /// there without a fault. With the torque the present flux allows worked out on the
    /// voltage regulator's trimmed budget, a 3 % trim cut it below the load, and the rotor
    /// ran away (`FollowingError` in runs 2 and 50).
    #[test]
    fn a_braking_drive_holds_its_load_at_top_speed() {
        let mut c = pi_campaign(16, "016-33kW", [6.8811e1, 7.1086e2, 0.9], 1.0);
        c.duration_s = c.full_range_duration_s();
        let faults = faulted(&c);
        assert!(faults.is_empty(), "{faults:#?}");
    }

    /// Member 022 at 4 kHz, its bus sagged below the protection's level at the top speed,
    /// generating: `DcBusUndervoltage` in the period of the sag, the bridge off — and then,
    /// with every switch open, the back-EMF of the flux the whole bus allowed drives the
    /// machine's own current through the diodes into the matrix's stiff, sagged bus, above
    /// 110 % of the trip level (201–211 A on sensor seeds 0–4 against 202 A). The criterion
    /// judges the current while the bridge is driven; the whole peak is reported beside it.
    /// The drive is tune's with the saturated P (the bus sag's current is the machine's, not
    /// the speed law's; tune's own choice at 4 kHz, a refusal since the present-flux limit's
    /// speed is held within half a count of the reading, docs/population.md).
    #[test]
    fn a_bus_sag_at_top_speed_is_judged_on_the_current_the_bridge_drove() {
        use hil_sim::faults::Point;
        let (tuned, file, vdc) =
            tuned_member_with(22, "022-35kW", Some(4_000.0), |t| Ok(t.into()), SpeedDesign::SaturatedP);
        let mut matrix = Matrix::of_file(&file, tuned.certify.omega_r_max_rad_s, vdc);
        // Sensor seed 1: 210 A through the diodes with the PI tune wrote when this was found
        // (seed 0's 201 A lay just under the limit).
        matrix.seed = 1;
        let o = matrix_row(&matrix, "bus sag", Point::Top, false);
        let limit = hil_sim::faults::PEAK_CURRENT_FRACTION * matrix.spec.protection.i_trip_a;
        assert_eq!(o.detected.map(|(f, _)| f), Some(controller_core::drive::Fault::DcBusUndervoltage));
        assert_eq!(o.off_after_periods, Some(0));
        assert!(o.peak_driven_a < 0.5 * limit, "{}", o.peak_driven_a);
        assert!(o.peak_current_a > limit, "{}", o.peak_current_a);
        assert!(o.passed(), "{:?}", o.failures);
    }

    /// Member 022 (35 kW, 500 lines: 0.785 rad/s per count of the speed window at 20 kHz) at
    /// 20 kHz, sensor seed 0: the healthy approach to its top speed, generating, reaches it.
    /// Accelerating through ≈ 140 rad/s at the voltage limit, its speed reading dithered one
    /// count each slow step and the present flux's torque limit, judged at the reading,
    /// jumped 53 ↔ 14 A: the references chattered, the currents fell 50 % short and the
    /// stuck-switch check tripped at ≈ 162 rad/s, before the injection, on the two rows
    /// below (on 10 top-speed rows over seeds 0–11). Judged at a speed held within half a
    /// count of the reading (`DriveSpec::speed_resolution_rad_s`), both pass. With no band
    /// (the reading itself) the chatter is back and the stuck-switch check trips on it before
    /// the injection (the first row's: `SwitchOpen` at 1.59 s, 162 rad/s; the second's sensor
    /// draw rides through): the currents do fall half short of
    /// the references there. (For a while both rows passed either way, the check keeping out
    /// the samples just after the references fell; since the rotor-resistance law listens only
    /// on plans that held the references, the estimate on the way differs, and the unbanded
    /// drive's chatter reaches the check again.)
    #[test]
    fn a_speed_read_between_two_counts_leaves_the_present_flux_limit_still() {
        use hil_sim::faults::Point;
        let (tuned, file, vdc) = tuned_member(22, "022-35kW", 20_000.0, |t| Ok(t.into()));
        let band = file.spec.speed_resolution_rad_s;
        // 500 lines, read every 0.5 ms (20 kHz, divider 10).
        assert!((band - controller_core::encoder::speed_resolution_rad_s(500, 5e-4)).abs() < 1e-9, "{band}");
        let unbanded = DriveFile { spec: DriveSpec { speed_resolution_rad_s: 0.0, ..file.spec }, ..file };
        for (f, banded) in [(&file, true), (&unbanded, false)] {
            let matrix = Matrix::of_file(f, tuned.certify.omega_r_max_rad_s, vdc);
            let mut tripped_on_the_way = Vec::new();
            for case in ["L_m step × 0.8 (saturation)", "overload (1.5 × τ_max)"] {
                let o = matrix_row(&matrix, case, Point::Top, false);
                if banded {
                    assert!(o.passed(), "band {banded}: {case}: {:?}", o.failures);
                }
                tripped_on_the_way.extend(o.tripped_before_s);
            }
            // Unbanded, the rows' sensor draws decide which of the two the chatter trips.
            assert_eq!(tripped_on_the_way.is_empty(), banded, "band {banded}: {tripped_on_the_way:?}");
        }
    }

    /// Member 020 (73 kW, 4 096 lines) at 20 kHz, run 112 of its 200-run campaign: motoring
    /// loaded at its top speed of 628 rad/s, the voltage at its limit. With the present
    /// flux's torque limit judged at the speed reading, its one-count dither moved the limit
    /// each slow step and the run missed the 5 % steady flux accuracy (0.0502): each step of
    /// the plan was also evidence the rotor-resistance law heard with the loops' reaction in
    /// it. Judged at a speed held within half a count of the reading, the run met it (0.0015);
    /// since the law listens only on plans that held the references, it meets it either way
    /// (`-- --nocapture` prints both).
    #[test]
    fn a_loaded_motor_at_top_speed_holds_its_flux_through_the_speed_readings_dither() {
        use drive_file::requirements::Requirement::FluxAccuracy;
        let (_, file, vdc) = tuned_member(20, "020-73kW", 20_000.0, |t| Ok(t.into()));
        let c = full_range_campaign_of(&file, vdc, 200, 1).unwrap();
        for band in [file.spec.speed_resolution_rad_s, 0.0] {
            let c = Campaign { spec: DriveSpec { speed_resolution_rad_s: band, ..c.spec }, ..c };
            let v = c.run_one(112, &AtomicBool::new(false)).unwrap();
            let flux = v.measures.iter().find(|m| m.requirement == FluxAccuracy).unwrap();
            eprintln!("band {band:.4} rad/s: flux accuracy {:.4}", flux.value);
            assert!(flux.met(), "band {band} rad/s: {flux:?}");
        }
    }

    /// Member 022 (35 kW, 500 lines) at 4 kHz with the speed PI tune wrote for it (k_p 9.19,
    /// k_i 18.6, setpoint weight 0.6), corner run 2 of its campaign: generating at its top
    /// speed of 309 rad/s under 0.8 × the load it holds there, the operating point on the
    /// voltage limit. Its envelope and point were made at the speed reading while the
    /// present flux's limit was judged at the speed held within half a count of it: with the
    /// held speed above the reading, the limit found the point's own current too much — at
    /// the voltage limit, near the braking current of least voltage, the current that fits
    /// is steep in the speed — and cut i_q from 92 to 77 A for a few slow periods: the
    /// braking torque dipped 16 %, 36 N·m peak to peak against the criterion's 34
    /// (`oscillation`; run 182 with the decoupling). Judged at one speed, the torque's
    /// ripple is the speed loop's answer to the reading's counts: within k_p × two counts.
    #[test]
    fn a_point_at_the_voltage_limit_is_judged_at_the_speed_it_was_made_for() {
        let kp = 9.19201223276931;
        let mut c = pi_campaign_at(22, "022-35kW", [kp, 18.619373344614548, 0.6], 1.0, 4_000.0);
        c.duration_s = c.full_range_duration_s();
        let counts = 2.0 * kp * c.spec.speed_resolution_rad_s;
        for decoupling in [false, true] {
            c.spec.current_decoupling = decoupling;
            c.check().unwrap();
            let v = c.run_one(2, &AtomicBool::new(false)).unwrap();
            assert_eq!(v.manoeuvre, hil_sim::campaign::Manoeuvre::Generating);
            assert!(v.ripple_nm < counts, "decoupling {decoupling}: {} N·m against {counts}", v.ripple_nm);
            assert!(v.passed(), "decoupling {decoupling}: {}", v.csv());
        }
    }

    /// The 153 kW member 010 (T_r 1.41 s) at 20 kHz, tuned and run as `population run` runs
    /// it: the campaign runs of seed 1 that missed the 5 % steady flux accuracy (5.4–6.9 %)
    /// with the voltage regulator at 10 rad/s — loaded at the top speed in field weakening,
    /// its budget and the envelope's flux cycled around the flux the machine held
    /// (`DriveSpec::voltage_regulator_bandwidth_rad_s`) — hold their flux.
    #[test]
    fn a_slow_rotors_voltage_regulator_holds_its_flux_at_top_speed() {
        use drive_file::requirements::Requirement::FluxAccuracy;
        let (_, file, vdc) = tuned_member(10, "010-153kW", 20_000.0, |t| Ok(t.into()));
        let c = full_range_campaign_of(&file, vdc, 200, 1).unwrap();
        for k in [77, 88, 97, 172, 177, 196] {
            let v = c.run_one(k, &AtomicBool::new(false)).unwrap();
            let flux = v.measures.iter().find(|m| m.requirement == FluxAccuracy).unwrap();
            assert!(flux.met(), "run {k}: {flux:?}");
        }
    }

    /// Member `index` at 20 kHz tuned as tune tunes it with the saturated P, its speed law
    /// then the PI `[k_p, k_i, setpoint weight]` at the P's torque limit: the 64 corner runs
    /// of `duration_s` (checked after the caller's changes, by [`faulted`]).
    fn pi_campaign(index: u64, name: &str, gains: [f64; 3], duration_s: f64) -> Campaign {
        pi_campaign_at(index, name, gains, duration_s, 20_000.0)
    }

    /// [`pi_campaign`] at `pwm_hz`.
    fn pi_campaign_at(
        index: u64,
        name: &str,
        [kp, ki, setpoint_weight]: [f64; 3],
        duration_s: f64,
        pwm_hz: f64,
    ) -> Campaign {
        let m = draw(1, index, None).unwrap();
        assert!(m.name.starts_with(name), "{}", m.name);
        let (path, text, vdc) = inputs(&m, Some(pwm_hz), Path::new(env!("CARGO_MANIFEST_DIR"))).unwrap();
        let structure = Structure { current: CurrentDesign::Pi, speed: SpeedDesign::SaturatedP };
        let tuned = design::tune::tune(Path::new(&path), &text, &m.motor, None, structure).unwrap();
        let file = DriveFile::parse(Path::new(&path), &tuned.text).unwrap();
        let mut c = campaign_of(&file, vdc, 64, 1).unwrap();
        let controller_core::speed::SpeedLaw::SaturatedP { tau_max_nm, .. } = c.spec.speed_law else {
            panic!("{:?}", c.spec.speed_law)
        };
        c.spec.speed_law =
            controller_core::speed::SpeedLaw::PiTorque { kp, ki, limit: tau_max_nm, setpoint_weight };
        c.duration_s = duration_s;
        c
    }

    /// `c` checked and run: the CSV lines of the runs that faulted.
    fn faulted(c: &Campaign) -> Vec<String> {
        c.check().unwrap();
        let verdicts = c.run(|_| {}, &AtomicBool::new(false)).unwrap();
        verdicts.iter().filter(|v| v.failures.contains(&"fault")).map(|v| v.csv()).collect()
    }

    /// The 73 kW 690 V member (020) without its encoder at 10 kHz: tuned on its encoder
    /// (k_p 93 N·m·s/rad) every sensorless campaign run oscillated (the observer's speed
    /// estimate carries the current sensors' noise; 58–93 N·m peak to peak against the
    /// criterion's 36). Tuned for the observer, the speed gain is bounded by that noise
    /// (`design::tune::observer_speed_peak_to_peak_rad_s`): on runs to the top speed (whose
    /// larger step allows a longer rise) a PI below the bound is predicted to meet the
    /// requirements, its drive misses them on the corner runs in SIL at the top speed, and
    /// tune refuses — a refusal naming the observer's bound or the corner runs, not a
    /// failure.
    #[test]
    fn a_drive_without_an_encoder_is_tuned_for_its_observers_noise() {
        let m = draw(1, 20, None).unwrap();
        assert!(m.name.starts_with("020-73kW"), "{}", m.name);
        let r = evaluated(&m, 10_000.0, 16, true);
        match r.verdict {
            Verdict::Refuse { reason } => assert!(
                reason.contains("the observer's")
                    || reason.contains("misses them in software in the loop on the 64 corner runs of the "),
                "{reason}"
            ),
            v => panic!("{v:?}"),
        }
    }

    /// A template's `[controller]` table gets `speed_feedback = "sensorless"`, in place of one
    /// it states; a template without the table is an error.
    #[test]
    fn with_sensorless_sets_the_speed_feedback() {
        let t =
            with_sensorless("[pwm]\nfrequency_hz = 1.0\n[controller]\nspeed_feedback = \"encoder\"\nx = 1\n")
                .unwrap();
        assert_eq!(t, "[pwm]\nfrequency_hz = 1.0\n[controller]\nspeed_feedback = \"sensorless\"\nx = 1\n");
        assert!(with_sensorless("[pwm]\n").is_err());
        let t = with_overmodulation("[controller]\novermodulation = false\nx = 1\n").unwrap();
        assert_eq!(t, "[controller]\novermodulation = true\nx = 1\n");
    }

    /// A tuned drive run without its encoder at a PWM rate its observer cannot run at up to
    /// the overspeed level is a refusal naming the observer, not a failure or an error
    /// (found trying `population run --sensorless --pwm 4000`: member 002, 7.3 kW, tunes at
    /// 4 kHz on its encoder; its observer's correction at the top speed exceeds 0.1 per
    /// sample).
    #[test]
    fn a_rate_the_observer_cannot_run_at_is_a_refusal_naming_it() {
        let m = draw(1, 2, None).unwrap();
        let r = evaluated(&m, 4_000.0, 16, true);
        match r.verdict {
            Verdict::Refuse { reason } => {
                assert!(reason.starts_with("sensorless: ") && reason.contains("per sample"), "{reason}")
            }
            v => panic!("{v:?}"),
        }
        assert!(r.campaign.is_none(), "no campaign on a refused drive");
    }
}
