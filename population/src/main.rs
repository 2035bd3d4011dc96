//! `population`: the motor and board population of issue 49 — list it, write its files, run
//! a sample through tune, campaign and fault matrix.

use clap::{Parser, Subcommand};
use population::member::{self, Member};
use population::run::{Plan, Report, Verdict, evaluate};
use rayon::prelude::*;
use report::outln;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

/// A seeded, physical population of induction motors and inverter boards (scaling laws of
/// real machines: population/src/laws.rs), and the judge every release passes on it.
#[derive(Parser, Debug)]
#[command(version)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand, Debug)]
enum Cmd {
    /// Print the members: nameplate, model and board.
    List(Select),
    /// Print the anchors (published machines) in per unit beside the scaling laws.
    Anchors,
    /// Write each drawn member's template drive file (`design tune --template`) into DIR.
    Write {
        #[command(flatten)]
        select: Select,
        /// The PWM rate to write them at, Hz (1 000 … 40 000), as `run --pwm` runs them (the
        /// slow divider kept near the population's slow rate, the dead time within its share
        /// of the period); none: each board's own.
        #[arg(long)]
        pwm: Option<f64>,
        /// Also each drawn member's saturating machine, NAME-saturating.toml: a motor file
        /// (the Γ form with its magnetizing curve) to simulate (`--plant`) and to commission
        /// (`hil-sim identify … --curve`, the command in its first lines).
        #[arg(long)]
        saturating: bool,
        /// Output directory.
        dir: PathBuf,
    },
    /// Tune every member of the sample at each PWM rate, run the tuned file's campaign and
    /// fault matrix, and judge it: pass, refuse (tune said why) or FAIL (tune passed a
    /// drive that does not work). Writes population.json, population.md and population.svg;
    /// exits 1 if a member fails or more than 10 % refuse.
    Run(RunArgs),
    /// Print a run's verdicts over rated power × PWM rate and its totals, from the
    /// population.json it wrote (without running anything again).
    Summary {
        /// A population.json written by `run`.
        file: PathBuf,
    },
}

#[derive(clap::Args, Debug, Clone)]
struct Select {
    /// Seed of the population.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Drawn members (indices 0 … N−1), at most 100 000.
    #[arg(long, default_value_t = 24, value_parser = clap::value_parser!(u64).range(0..=100_000))]
    members: u64,
    /// Also the shipped motors on their shipped templates.
    #[arg(long)]
    shipped: bool,
}

#[derive(clap::Args, Debug)]
struct RunArgs {
    #[command(flatten)]
    select: Select,
    /// PWM rates to run every member at, Hz, comma separated (each 1 000 … 40 000).
    #[arg(long, value_delimiter = ',', default_value = "4000,10000,20000", conflicts_with = "own_pwm")]
    pwm: Vec<f64>,
    /// Run each member at its board's own PWM rate (drawn from 4–20 kHz) instead of `--pwm`'s.
    #[arg(long)]
    own_pwm: bool,
    /// Run member i at the (i mod n)-th of `--pwm`'s n rates instead of at every one: one drive
    /// per member, the rates taken in turn (the CI's sample: `cargo xtask population`).
    #[arg(long, conflicts_with = "own_pwm")]
    pwm_in_turn: bool,
    /// Campaign runs per member (the box's 64 corner runs first).
    #[arg(long, default_value_t = 200, value_parser = clap::value_parser!(u64).range(1..=100_000))]
    campaign_runs: u64,
    /// Skip the fault matrix.
    #[arg(long)]
    no_matrix: bool,
    /// The speed law `design tune` is asked for: `auto` (the one the template's
    /// [requirements] choose, or a refusal naming them), `p` or `pi`.
    #[arg(long, default_value = "auto")]
    speed: design::tune::SpeedDesign,
    /// Run the tuned drives without their encoders (`speed_feedback = "sensorless"`, the flux
    /// and speed observer: docs/sensorless.md).
    #[arg(long)]
    sensorless: bool,
    /// Tune and run the drives overmodulating (`overmodulation = true`: beyond the sampling
    /// window one phase rebuilt from the other two, docs/envelope.md).
    #[arg(long)]
    overmodulation: bool,
    /// Output directory.
    #[arg(long, default_value = "out/population")]
    out: PathBuf,
}

/// The selection's members: the shipped ones (`--shipped`), then the drawn ones. None is an
/// error: `run --members 0` ran no drive and passed.
fn members(s: &Select) -> Result<Vec<Member>, String> {
    if s.members == 0 && !s.shipped {
        return Err("no members: --members 0 without --shipped selects nothing".into());
    }
    let mut all = Vec::new();
    if s.shipped {
        all.extend(member::shipped(Path::new("."))?);
    }
    for i in 0..s.members {
        all.push(member::draw(s.seed, i, None)?);
    }
    Ok(all)
}

fn list(s: &Select) -> Result<bool, String> {
    outln!(
        "{:<28} {:>8} {:>7} {:>7} {:>6} {:>6} {:>6} {:>9} {:>8} {:>8} {:>7} {:>6}",
        "member",
        "I_N A",
        "r/min",
        "T_N N·m",
        "slip",
        "cos φ",
        "η",
        "J kg·m²",
        "V_dc V",
        "PWM kHz",
        "dt µs",
        "lines"
    );
    for m in members(s)? {
        match (m.nameplate, m.board) {
            (Some(n), Some(b)) => outln!(
                "{:<28} {:>8.3} {:>7.0} {:>7.3} {:>6.3} {:>6.3} {:>6.3} {:>9.3e} {:>8.0} {:>8.2} {:>7.2} {:>6}",
                m.name,
                n.current_a,
                n.speed_rpm,
                n.torque_nm,
                n.slip,
                n.power_factor,
                n.efficiency,
                m.motor.j_kgm2(),
                b.vdc_v,
                b.pwm_hz / 1e3,
                b.dead_time_s * 1e6,
                b.encoder_lines
            ),
            _ => outln!("{:<28} (its files' own nameplate and board)", m.name),
        }
    }
    Ok(true)
}

fn anchors() -> Result<bool, String> {
    outln!(
        "{:<52} {:>15} {:>15} {:>15} {:>15} {:>13}",
        "anchor",
        "r_s pu (law)",
        "r_r pu (law)",
        "x_l pu (law)",
        "x_m pu (law)",
        "H s (law)"
    );
    for a in population::laws::ANCHORS {
        let pu = population::laws::per_unit(&a);
        let cell = |i: usize| {
            let (x, l) = (pu.circuit_pu.get(i).copied(), pu.laws_pu.get(i).copied());
            format!("{:.4} ({:.4})", x.unwrap_or(f64::NAN), l.unwrap_or(f64::NAN))
        };
        outln!(
            "{:<52} {:>15} {:>15} {:>15} {:>15} {:>13}",
            a.name,
            cell(0),
            cell(1),
            cell(2),
            cell(3),
            format!("{:.3} ({:.3})", pu.h_s[0], pu.h_s[1])
        );
    }
    Ok(true)
}

/// `--pwm`'s rate, Hz, within what a run or a written template may ask for (1 000 … 40 000).
fn check_pwm(hz: f64) -> Result<(), String> {
    if (1_000.0..=40_000.0).contains(&hz) {
        return Ok(());
    }
    // A huge number in exponent form (1e300 printed in full is 301 digits).
    let shown = if hz.abs() < 1e9 { format!("{hz}") } else { format!("{hz:e}") };
    Err(format!("--pwm {shown}: a PWM rate of 1 000 … 40 000 Hz"))
}

fn write(s: &Select, pwm_hz: Option<f64>, saturating: bool, dir: &Path) -> Result<bool, String> {
    pwm_hz.map_or(Ok(()), check_pwm)?;
    std::fs::create_dir_all(dir).map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
    let (mut n, mut n_sat) = (0, 0);
    for m in members(s)? {
        // Each member's template as `run` tunes it at this rate: a failing member of a run,
        // reproduced by hand (`design tune --motor FILE --template FILE`; a shipped motor's
        // command is printed, its motor not being its template's `[motor]`).
        let (_, t, _) = population::run::inputs(&m, pwm_hz, Path::new("."))?;
        let file = dir.join(format!("{}.toml", m.name));
        report::write::write_text(&file, &t)?;
        n += 1;
        if let Some(hint) = shipped_hint(&m, &file) {
            eprintln!("{hint}");
        }
    }
    if saturating {
        // The drawn members only: a shipped motor's saturation is its own file's.
        for index in 0..s.members {
            let m = member::draw(s.seed, index, None)?;
            match population::saturation::saturating_motor_file(s.seed, index, &m) {
                Some(text) => {
                    report::write::write_text(&dir.join(format!("{}-saturating.toml", m.name)), &text)?;
                    n_sat += 1;
                }
                None => eprintln!("population: {}: no saturating machine (its Γ form is refused)", m.name),
            }
        }
    }
    eprintln!("population: wrote {n} template(s) and {n_sat} saturating motor file(s) in {}", dir.display());
    Ok(true)
}

/// For a shipped member written to `file`: the command that tunes it as `run` does — its
/// motor is a motor file of its own, not the template's `[motor]` (`write --shipped` wrote
/// nothing for them, and said nothing).
fn shipped_hint(m: &Member, file: &Path) -> Option<String> {
    match m.origin {
        member::Origin::Shipped { motor, .. } => Some(format!(
            "population: {}: a shipped motor on its template, whose [motor] is not this motor's: \
             design tune --motor {motor} --template {}",
            m.name,
            file.display()
        )),
        member::Origin::Drawn { .. } => None,
    }
}

/// The drives of a run: every member at every rate, or (`in_turn`) member i at rate i mod n.
fn drives<'a>(all: &'a [Member], rates: &[Option<f64>], in_turn: bool) -> Vec<(&'a Member, Option<f64>)> {
    if in_turn {
        all.iter().zip(rates.iter().cycle()).map(|(m, r)| (m, *r)).collect()
    } else {
        all.iter().flat_map(|m| rates.iter().map(move |r| (m, *r))).collect()
    }
}

/// Largest share of refusals a sample may have (issue 49's acceptance).
const REFUSE_MAX_SHARE: f64 = 0.10;

fn run(a: &RunArgs, cancel: &AtomicBool) -> Result<bool, String> {
    a.pwm.iter().try_for_each(|&f| check_pwm(f))?;
    let all = members(&a.select)?;
    let rates: Vec<Option<f64>> =
        if a.own_pwm { vec![None] } else { a.pwm.iter().map(|f| Some(*f)).collect() };
    let jobs = drives(&all, &rates, a.pwm_in_turn);
    let plan = Plan {
        campaign_runs: a.campaign_runs,
        seed: a.select.seed,
        matrix: !a.no_matrix,
        speed: a.speed,
        sensorless: a.sensorless,
        overmodulation: a.overmodulation,
    };
    report::write::check_dir(&a.out)?;
    eprintln!(
        "population: {} member(s) {} {} rate(s){} = {} drive(s): tune, campaign of {} runs{}",
        all.len(),
        if a.pwm_in_turn { "each at one of" } else { "×" },
        rates.len(),
        if a.pwm_in_turn { " in turn" } else { "" },
        jobs.len(),
        plan.campaign_runs,
        if plan.matrix { ", fault matrix" } else { "" }
    );
    let start = std::time::Instant::now();
    let done = AtomicUsize::new(0);
    let reports: Vec<Report> = jobs
        .par_iter()
        .map(|(m, r)| {
            let rep = evaluate(m, *r, Path::new("."), &plan, cancel);
            let k = done.fetch_add(1, Ordering::Relaxed) + 1;
            // Ctrl-C: the drives cut short are no verdict (they read `ERROR` before).
            let word = if cancel.load(Ordering::Relaxed) { "interrupted" } else { rep.verdict.word() };
            eprintln!(
                "population: [{k}/{}] {} at {:.1} kHz: {word} ({:.1} s)",
                jobs.len(),
                rep.member,
                rep.pwm_hz / 1e3,
                rep.elapsed_s
            );
            rep
        })
        .collect();
    if cancel.load(Ordering::Relaxed) {
        return Err("interrupted: nothing written".into());
    }
    let elapsed = start.elapsed().as_secs_f64();
    let count = |w: &str| reports.iter().filter(|r| r.verdict.word() == w).count();
    let (pass, refuse, fail, error) = (count("pass"), count("refuse"), count("FAIL"), count("ERROR"));
    let families = population::run::families(&reports);
    let md = format!(
        "{}\n{}\n{}",
        population::run::grid(&reports),
        table(&reports),
        population::run::families_table(&families)
    );
    outln!("{md}");
    // Where the time went: each stage's wall time summed over the drives (which run side by
    // side, so the sums exceed the run's).
    let stages_s: Vec<f64> = (0..population::run::STAGES)
        .map(|k| reports.iter().filter_map(|r| r.stages_s.get(k)).sum())
        .collect();
    let stages: Vec<String> = population::run::STAGE_NAMES
        .iter()
        .zip(&stages_s)
        .map(|(name, t)| format!("{name} {t:.1} s"))
        .collect();
    outln!("stages, summed over the drives: {}", stages.join(", "));
    outln!(
        "{} drive(s) in {elapsed:.1} s on {} thread(s): {pass} pass, {refuse} refuse, {fail} FAIL, {error} ERROR",
        reports.len(),
        rayon::current_num_threads()
    );
    std::fs::create_dir_all(&a.out).map_err(|e| format!("cannot create {}: {e}", a.out.display()))?;
    let json = serde_json::json!({
        "seed": a.select.seed,
        "members": a.select.members,
        "shipped": a.select.shipped,
        // null: each board's own.
        "pwm_hz": if a.own_pwm { None } else { Some(&a.pwm) },
        "pwm_in_turn": a.pwm_in_turn,
        "campaign_runs": a.campaign_runs,
        "matrix": !a.no_matrix,
        "speed": format!("{:?}", a.speed),
        "elapsed_s": elapsed,
        "stages_s": stages_s,
        "counts": { "pass": pass, "refuse": refuse, "fail": fail, "error": error },
        "families": families,
        "reports": reports,
    });
    let text = serde_json::to_string_pretty(&json).map_err(|e| e.to_string())?;
    report::write::write_text(&a.out.join("population.json"), &text)?;
    report::write::write_text(&a.out.join("population.md"), &md)?;
    report::write::write_text(&a.out.join("population.svg"), &plot(&reports))?;
    eprintln!("population: wrote population.json, population.md, population.svg in {}", a.out.display());
    let refuse_share = refuse as f64 / reports.len().max(1) as f64;
    if refuse_share > REFUSE_MAX_SHARE {
        eprintln!(
            "population: {:.0} % refused, more than {:.0} %",
            100.0 * refuse_share,
            100.0 * REFUSE_MAX_SHARE
        );
    }
    Ok(fail == 0 && error == 0 && refuse_share <= REFUSE_MAX_SHARE)
}

/// `summary FILE`: the grid and the totals of a run's population.json.
fn summary(file: &Path) -> Result<bool, String> {
    let text = std::fs::read_to_string(file).map_err(|e| format!("cannot read {}: {e}", file.display()))?;
    let json: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| format!("{}: not JSON: {e}", file.display()))?;
    let reports: Vec<Report> = json
        .get("reports")
        .cloned()
        .map(serde_json::from_value)
        .transpose()
        .map_err(|e| format!("{}: its reports are not a population run's: {e}", file.display()))?
        .ok_or_else(|| {
            format!("{}: no \"reports\" (not a population.json written by `run`)", file.display())
        })?;
    outln!("{}", population::run::grid(&reports));
    let elapsed = json.get("elapsed_s").and_then(serde_json::Value::as_f64);
    outln!(
        "{} drive(s){}: pass / refuse / FAIL over rated power and PWM rate (campaign of {} runs, fault matrix {})",
        reports.len(),
        elapsed.map_or(String::new(), |t| format!(" in {t:.1} s")),
        json.get("campaign_runs").map_or("?".into(), ToString::to_string),
        if json.get("matrix").and_then(serde_json::Value::as_bool) == Some(true) { "on" } else { "off" }
    );
    Ok(true)
}

fn table(reports: &[Report]) -> String {
    let mut s = String::from(
        "| member | PWM kHz | V_dc V | ω_c rad/s | campaign | matrix | verdict | why |\n|---|---|---|---|---|---|---|---|\n",
    );
    for r in reports {
        let pair = |p: Option<[u64; 2]>| p.map_or("—".into(), |[a, b]| format!("{a}/{b}"));
        let why = match &r.verdict {
            Verdict::Pass => String::new(),
            Verdict::Refuse { reason } => reason.clone(),
            Verdict::Fail { what } => what.clone(),
            Verdict::Error { error } => error.clone(),
        };
        s.push_str(&format!(
            "| {} | {:.1} | {:.0} | {} | {} | {} | {} | {} |\n",
            r.member,
            r.pwm_hz / 1e3,
            r.vdc_v,
            r.omega_c_rad_s.map_or("—".into(), |w| format!("{w:.0}")),
            pair(r.campaign),
            pair(r.matrix),
            r.verdict.word(),
            why.replace('|', "/")
        ));
    }
    s
}

/// Pass / refuse / fail over rated power × PWM rate.
fn plot(reports: &[Report]) -> String {
    use report::plot::{Series, line_plot};
    let pts = |w: &str| -> Vec<(f64, f64)> {
        reports
            .iter()
            .filter(|r| r.verdict.word() == w)
            .filter_map(|r| r.power_w.map(|p| (p.log10(), r.pwm_hz / 1e3)))
            .collect()
    };
    let series = [
        Series::markers("pass", pts("pass")).colored("#2a9d4b"),
        Series::markers("refuse", pts("refuse")).colored("#e0a000"),
        Series::markers("FAIL", pts("FAIL")).colored("#d62728"),
        Series::markers("ERROR", pts("ERROR")).colored("#7030a0"),
    ];
    line_plot(
        "Population: verdict over rated power and PWM rate (PWM kHz)",
        "log10(rated power / W)",
        &series,
    )
}

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    static CANCEL: AtomicBool = AtomicBool::new(false);
    let _ = ctrlc::set_handler(|| CANCEL.store(true, Ordering::Relaxed));
    let result = match &cli.cmd {
        Cmd::List(s) => list(s),
        Cmd::Anchors => anchors(),
        Cmd::Write { select, pwm, saturating, dir } => write(select, *pwm, *saturating, dir),
        Cmd::Run(a) => run(a, &CANCEL),
        Cmd::Summary { file } => summary(file),
    };
    match result {
        Ok(true) => std::process::ExitCode::SUCCESS,
        Ok(false) => std::process::ExitCode::FAILURE,
        Err(e) => {
            eprintln!("population: {e}");
            std::process::ExitCode::from(2)
        }
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    fn select(members: u64) -> Select {
        Select { seed: 1, members, shipped: false }
    }

    /// `write --pwm` writes the text `run` tunes at that rate (a failing member reproduced by
    /// hand), and a rate out of the range is refused before anything is written (a huge one
    /// named in exponent form: 1e300 was printed as 301 digits).
    #[test]
    fn written_templates_are_the_runs_at_its_rate() {
        let dir = std::env::temp_dir().join(format!("population-write-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let e = write(&select(2), Some(50.0), false, &dir).unwrap_err();
        assert!(e.contains("1 000 … 40 000 Hz"), "{e}");
        let huge = write(&select(2), Some(1e300), false, &dir).unwrap_err();
        assert_eq!(huge, "--pwm 1e300: a PWM rate of 1 000 … 40 000 Hz");
        assert!(!dir.exists());
        assert!(write(&select(2), Some(10_000.0), true, &dir).unwrap());
        for m in members(&select(2)).unwrap() {
            let text = std::fs::read_to_string(dir.join(format!("{}.toml", m.name))).unwrap();
            let (_, want, _) = population::run::inputs(&m, Some(10_000.0), Path::new(".")).unwrap();
            assert_eq!(text, want);
            assert!(text.contains("frequency_hz = 10000"), "{text}");
            // `--saturating`: each drawn member's machine beside its template, a motor file
            // drive-file reads as a saturating Γ machine.
            let path = dir.join(format!("{}-saturating.toml", m.name));
            let (_, sat) = drive_file::motor::load_model(&path.to_string_lossy()).unwrap();
            assert!(sat.is_some(), "{}", path.display());
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// An empty selection is refused, naming it (`run --members 0` ran no drive, wrote an
    /// empty report and exited 0).
    #[test]
    fn an_empty_selection_is_refused() {
        let e = members(&select(0)).unwrap_err();
        assert!(e.contains("--members 0") && e.contains("--shipped"), "{e}");
        let cancel = AtomicBool::new(false);
        let dir = std::env::temp_dir().join(format!("population-empty-{}", std::process::id()));
        let args = RunArgs {
            select: select(0),
            pwm: vec![20_000.0],
            own_pwm: false,
            pwm_in_turn: false,
            campaign_runs: 200,
            no_matrix: false,
            speed: design::tune::SpeedDesign::Auto,
            sensorless: false,
            overmodulation: false,
            out: dir.clone(),
        };
        assert_eq!(run(&args, &cancel).unwrap_err(), e);
        assert!(!dir.exists());
    }

    /// `run --own-pwm` runs each member at its board's own rate, and cannot be asked with
    /// `--pwm` (the help promised each board's own rate for no `--pwm`, which no command
    /// line could give: an empty `--pwm` is no number, and without it the default's three
    /// rates ran).
    #[test]
    fn each_boards_own_rate_is_asked_by_name() {
        let args = |line: &[&str]| {
            Cli::try_parse_from(line)
                .map(|c| match c.cmd {
                    Cmd::Run(a) => Some((a.own_pwm, a.pwm)),
                    _ => None,
                })
                .map_err(|e| e.kind())
        };
        let three = vec![4_000.0, 10_000.0, 20_000.0];
        assert_eq!(args(&["population", "run", "--own-pwm"]), Ok(Some((true, three.clone()))));
        assert_eq!(args(&["population", "run"]), Ok(Some((false, three))));
        assert_eq!(
            args(&["population", "run", "--own-pwm", "--pwm", "4000"]),
            Err(clap::error::ErrorKind::ArgumentConflict)
        );
        assert_eq!(
            args(&["population", "run", "--own-pwm", "--pwm-in-turn"]),
            Err(clap::error::ErrorKind::ArgumentConflict)
        );
    }

    /// `--pwm-in-turn` runs each member once, the rates in turn; without it every member at
    /// every rate.
    #[test]
    fn the_rates_in_turn_give_one_drive_per_member() {
        let all: Vec<Member> = (0..5).map(|i| member::draw(1, i, None).unwrap()).collect();
        let (r4, r10, r20) = (Some(4_000.0), Some(10_000.0), Some(20_000.0));
        let rates = [r4, r10, r20];
        let turn: Vec<(String, Option<f64>)> =
            drives(&all, &rates, true).into_iter().map(|(m, r)| (m.name.clone(), r)).collect();
        let want: Vec<(String, Option<f64>)> =
            all.iter().zip([r4, r10, r20, r4, r10]).map(|(m, r)| (m.name.clone(), r)).collect();
        assert_eq!(turn, want);
        assert_eq!(drives(&all, &rates, false).len(), 15);
    }

    /// A shipped member is written too, as `run` tunes it, with the command that tunes it on
    /// its own motor file (`write --members 0 --shipped` wrote 0 files and said nothing).
    #[test]
    fn a_shipped_member_is_written_with_the_command_that_tunes_it() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let shipped = member::shipped(&root).unwrap();
        let m = shipped.iter().find(|m| m.name.contains("perturbed")).unwrap();
        let hint = shipped_hint(m, Path::new("out/t.toml")).unwrap();
        assert!(
            hint.ends_with("design tune --motor motors/delorenzo-perturbed.toml --template out/t.toml"),
            "{hint}"
        );
        let (_, text, _) = population::run::inputs(m, Some(10_000.0), &root).unwrap();
        assert!(text.contains("frequency_hz = 10000"), "{text}");
        let drawn = member::draw(1, 0, None).unwrap();
        assert_eq!(shipped_hint(&drawn, Path::new("x")), None);
    }

    /// `summary` reads back what `run` wrote, and names what it cannot read: a missing file,
    /// text that is not JSON, JSON without a run's reports, reports of another shape.
    #[test]
    fn a_summary_reads_a_runs_json_and_names_what_it_cannot() {
        let dir = std::env::temp_dir().join(format!("population-summary-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = |name: &str, text: &str| {
            let p = dir.join(name);
            std::fs::write(&p, text).unwrap();
            p
        };
        let report = serde_json::json!({
            "member": "x", "power_w": 500.0, "pwm_hz": 4000.0, "vdc_v": 310.0, "omega_c_rad_s": null,
            "campaign": [64, 64], "campaign_failures": [], "matrix": null, "matrix_failures": [],
            "verdict": { "verdict": "pass" }, "elapsed_s": 1.0
        });
        let good =
            file("good.json", &serde_json::json!({ "reports": [report], "campaign_runs": 64 }).to_string());
        assert_eq!(summary(&good), Ok(true));
        let e = summary(&dir.join("missing.json")).unwrap_err();
        assert!(e.starts_with("cannot read"), "{e}");
        let e = summary(&file("text.json", "not json")).unwrap_err();
        assert!(e.contains("not JSON"), "{e}");
        let e = summary(&file("other.json", "{\"a\": 1}")).unwrap_err();
        assert!(e.contains("no \"reports\""), "{e}");
        let e = summary(&file("shape.json", "{\"reports\": [1]}")).unwrap_err();
        assert!(e.contains("not a population run's"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
