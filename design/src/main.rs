//! `design` command line (`design --help`, `design <command> --help`: the help text is the
//! doc comments of the argument structs). Exit status everywhere: 0 the checked property
//! holds, 1 it does not, 2 usage or input error (named in the message).

mod cli {
    pub mod bench;
    pub mod kharitonov;
    pub mod recycle;
    pub mod startup_fit;

    pub use report::write::write_text as write_atomic;
}

use clap::{Args, Parser, Subcommand};
use controller_core::current::CurrentLaw;
use std::process::ExitCode;

/// Robust design toolkit for the drive's controllers: Kharitonov regions (seed 000),
/// interval-polynomial PI design (seed 001), ICAD multivariable analysis (seed 002), and the
/// certification of a drive file.
#[derive(Parser, Debug)]
#[command(name = "design", version, propagate_version = true)]
struct Cli {
    #[command(subcommand)]
    command: Cmd,
}

#[derive(Subcommand, Debug)]
enum Cmd {
    /// PI on an interval plant: robust stability, gain–phase margin, bandwidth (seed 000).
    Kharitonov(cli::kharitonov::KharitonovArgs),
    /// Individual channel analysis of the stator-current loops at one rotor speed (seed 002).
    Icad(IcadArgs),
    /// Check every controller constant of a drive file against its [certify] intervals.
    Certify(CertifyArgs),
    /// Synthesise the current and speed gains for a motor on a template drive file (its
    /// board, PWM, protection and certificate), widen the box to the motor file's
    /// [identification] intervals, certify, and write the drive file — the template edited in
    /// place, its comments kept, every changed value printed (nothing if it fails).
    Tune(TuneArgs),
    /// Seed 001's recycle-process study.
    Recycle(cli::recycle::RecycleArgs),
    /// Interval plant fitted to a nonlinear start-up (seed 000 Sec. 6).
    StartupFit(cli::startup_fit::StartupFitArgs),
    /// Time the ICAD sweep and a k_p–k_i grid (JSON; tools/control_bench.py compares
    /// python-control on the same work).
    Bench,
}

/// Seed 002's individual channel analysis at electrical rotor speed `--omega-r`, and the
/// ω_r sweep (0…5000 rad/s, 5 rad/s steps) for the range where the full 2×2 loop stays
/// stable. Exit 0 when the loop is stable at `--omega-r`, continuous and sampled at
/// `--pwm-hz` (the loop as the drive runs it).
#[derive(Args, Debug)]
struct IcadArgs {
    /// A shipped motor (delorenzo-eq13, delorenzo-appendix, delorenzo-perturbed,
    /// krause-2300v-500hp, em-synergy-m800006) or any file with a [motor] table.
    #[arg(long)]
    motor: String,
    /// Electrical rotor speed, rad/s.
    #[arg(long, allow_negative_numbers = true, value_parser = finite_speed)]
    omega_r: f64,
    /// `icad20` (seed 002 eq. (20)), `pi:KP,KI`, or a drive file (`.toml`: its current law,
    /// e.g. one `design tune --current icad` wrote).
    #[arg(long, value_parser = parse_law)]
    controller: CurrentLaw,
    /// PWM rate of the sampled analysis (the loop as the drive runs it: zero-order hold, one
    /// period of delay; `design::sampled`), Hz.
    #[arg(long, default_value_t = 20_000.0, value_parser = positive_rate)]
    pwm_hz: f64,
    /// Print JSON.
    #[arg(long)]
    json: bool,
}

fn positive_rate(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(x) if x.is_finite() && (1.0..=1e6).contains(&x) => Ok(x),
        _ => Err(format!("`{s}` is not a rate in [1, 1e6] Hz")),
    }
}

/// `design certify`: on every corner of the parameter box (see `design::certify`).
#[derive(Args, Debug)]
struct CertifyArgs {
    /// Drive file with a [certify] table (e.g. the firmware's drive.toml).
    drive: String,
    /// Print JSON.
    #[arg(long)]
    json: bool,
    /// Also write the certificate's pictures (SVG) here: Nyquist plots of γ and γ·h₂ on
    /// every corner, Bode plots of c₁ and k·g₁₁, the stable-speed sweep.
    #[arg(long)]
    plot_dir: Option<std::path::PathBuf>,
    /// The nonlinear campaign's summary.json (`hil-sim campaign <this file>`, unsharded): it
    /// must be of this very file (its fingerprint) and box; the file is certified when both
    /// the linear checks and every campaign run pass.
    #[arg(long)]
    campaign: Option<std::path::PathBuf>,
    /// Write the certificate (JSON: the file's fingerprint, every linear check, the
    /// requirements with their worst corners and margins, the campaign's figures, the
    /// verdict) here, and its one-page summary beside it (`.svg`: the speed step over the box
    /// against the requirements, the torque–speed envelope against the physical limit).
    #[arg(long)]
    out: Option<std::path::PathBuf>,
}

/// The campaign's part of a certificate: its summary checked against the drive file.
struct Nonlinear {
    /// Every run passed.
    ok: bool,
    passed: u64,
    runs: u64,
    /// What the certificate keeps of the summary.
    record: serde_json::Value,
    /// The first speed step over the box (absent from an older hil-sim's summary).
    step_band: Option<hil_sim::campaign::StepBand>,
    /// The campaign's bus, V.
    vdc_v: Option<f64>,
}

fn campaign_result(
    summary_path: &std::path::Path,
    drive_text: &str,
    c: &design::certify::CertifySpec,
) -> Result<Nonlinear, String> {
    use serde_json::Value;
    let shown = summary_path.display();
    let text = std::fs::read_to_string(summary_path).map_err(|e| format!("{shown}: {e}"))?;
    let s: Value =
        serde_json::from_str(&text).map_err(|e| format!("{shown}: not a campaign summary: {e}"))?;
    let at = |pointer: &str| s.pointer(pointer).cloned().unwrap_or(Value::Null);
    let fp = drive_file::source::fingerprint(drive_text);
    let theirs = at("/drive/fingerprint");
    if theirs.as_str() != Some(fp.as_str()) {
        return Err(format!(
            "{shown}: the campaign ran another drive file (fingerprint {theirs} against this file's {fp}): run `hil-sim campaign` on this one"
        ));
    }
    if at("/shard").as_str() != Some("0/1") {
        return Err(format!("{shown}: one shard of a campaign ({}), not the whole", at("/shard")));
    }
    // Within 1e-12: serde_json's default float parsing is not always correctly rounded.
    let same = |key: &str, x: [f64; 2]| {
        let near = |i: usize, v: f64| {
            at(&format!("/box/{key}/{i}")).as_f64().is_some_and(|y| (y - v).abs() <= 1e-12 * v.abs().max(1.0))
        };
        near(0, x[0]) && near(1, x[1])
    };
    if !(same("rs_factor", c.rs_factor)
        && same("rr_factor", c.rr_factor)
        && same("inductance_factor", c.inductance_factor)
        && same("j_factor", c.j_factor))
    {
        return Err(format!("{shown}: the campaign's box differs from the file's [certify]"));
    }
    // Every corner of the box through every manoeuvre (the campaign's first runs): a
    // campaign of fewer runs certifies nothing about the corners it left out.
    let corner_runs = at("/corner_runs").as_u64().filter(|&n| n > 0).ok_or_else(|| {
        format!("{shown}: the summary does not say which runs take the box's corners (an older hil-sim): run `hil-sim campaign` again")
    })?;
    let campaign_runs = at("/campaign_runs").as_u64().unwrap_or(0);
    if campaign_runs < corner_runs {
        return Err(format!(
            "{shown}: a campaign of {campaign_runs} runs, fewer than the {corner_runs} that take every corner of the box through every manoeuvre: run `hil-sim campaign` with --runs {corner_runs} or more"
        ));
    }
    // A campaign whose speed steps went nowhere judged nothing (a drive that cannot
    // magnetize its motor on the bus stepped to ±0 rad/s and passed: found by trying).
    if !at("/omega_s_rad_s").as_f64().is_some_and(|w| w > 0.0) {
        return Err(format!(
            "{shown}: the campaign's speed step is {} rad/s: it judged no motion (the drive has no speed range on its bus)",
            at("/omega_s_rad_s")
        ));
    }
    let (runs, passed) = (at("/runs").as_u64().unwrap_or(0), at("/passed").as_u64().unwrap_or(0));
    let ok = runs > 0 && runs == passed && campaign_runs == runs;
    let mut record = serde_json::Map::new();
    for k in [
        "runs",
        "passed",
        "failed",
        "seed",
        "duration_s",
        "vdc_v",
        "omega_s_rad_s",
        "box",
        "criteria",
        "diagnostics",
        "per_manoeuvre",
        "requirements",
        "requirements_missed",
    ] {
        record.insert(k.into(), at(&format!("/{k}")));
    }
    record.insert("summary".into(), shown.to_string().into());
    record.insert("passed_all".into(), ok.into());
    let step_band = serde_json::from_value(at("/step_band")).ok();
    let vdc_v = at("/vdc_v").as_f64();
    Ok(Nonlinear { ok, passed, runs, record: Value::Object(record), step_band, vdc_v })
}

/// `design tune --motor M --out F [--template drive.toml]` (design::tune).
#[derive(Args, Debug)]
struct TuneArgs {
    /// A shipped motor or a motor file (e.g. `hil-sim identify`'s, with [identification]).
    #[arg(long)]
    motor: String,
    /// The template drive file: board, PWM, protection, flux reference, current limit, the
    /// certificate's minima and speed range.
    #[arg(long, default_value = "drive.toml")]
    template: std::path::PathBuf,
    /// The drive file to write.
    #[arg(long)]
    out: std::path::PathBuf,
    /// The current controller: `pi` (the fastest the certificate passes) or `icad` (seed
    /// 002 eq. (20)'s structure placed from `[certify] omega_r_max_rad_s`, the gain the most
    /// robust over the box).
    #[arg(long, default_value = "pi")]
    current: design::tune::CurrentDesign,
    /// The speed controller: `auto` (the first of p and pi whose predicted response meets
    /// the template's [requirements] over the box and whose drive then meets them on the
    /// 64 corner runs of its 1 s and full-range campaigns in SIL; refused, naming what each misses, when neither does), `p` (saturated P, seed 002 eq. (21); the link may rewrite its gains) or
    /// `pi` (PI → torque inside seed 000's stability and gain–phase-margin regions over the
    /// inertia interval: the deepest point with the P's bandwidth, or else the deepest that
    /// meets the requirements, predicted and on those corner runs).
    #[arg(long, default_value = "auto")]
    speed: design::tune::SpeedDesign,
}

/// An interval for the tune summary, to six significant digits (the file keeps every digit):
/// `[65.18986469044033, 260.7594587617613]` read as noise (found by a helper).
fn interval([lo, hi]: [f64; 2]) -> String {
    let sig = |x: f64| {
        if x == 0.0 || !x.is_finite() {
            return format!("{x}");
        }
        let decimals = (5 - x.abs().log10().floor() as i32).clamp(0, 15) as usize;
        let s = format!("{x:.decimals$}");
        if s.contains('.') { s.trim_end_matches('0').trim_end_matches('.').to_string() } else { s }
    };
    format!("[{}, {}]", sig(lo), sig(hi))
}

fn tune(a: &TuneArgs) -> Result<bool, String> {
    // The template is the engineer's own file (its comments, its sources): not rewritten.
    let same = |p: &std::path::Path| std::fs::canonicalize(p).ok();
    if same(&a.out).is_some() && same(&a.out) == same(&a.template) {
        return Err(format!(
            "--out {} is the template: tuning writes a new file (the template keeps its comments); choose another --out",
            a.out.display()
        ));
    }
    // The motor as written (a shipped one's text, or the file's): its [identification]
    // intervals widen the box, and a saturating one goes into the drive file with its curve.
    let (motor_path, motor_text) = drive_file::motor::text_of(&a.motor).map_err(|e| e.to_string())?;
    let intervals = design::tune::Intervals::parse(&motor_text).map_err(|e| format!("{}: {e}", a.motor))?;
    let template = drive_file::source::read(&a.template).map_err(|e| e.to_string())?;
    let t = design::tune::tune_file(
        &a.template,
        &template,
        design::tune::MotorFile { path: &motor_path, text: &motor_text },
        intervals.as_ref(),
        design::tune::Structure { current: a.current, speed: a.speed },
    )?;
    let law = &t.spec.current_law;
    let lag = law.lag.map_or(String::new(), |l| {
        format!(
            " × lag ({} s² + {} s + {})/({} s² + {} s + {})",
            l.num[0], l.num[1], l.num[2], l.den[0], l.den[1], l.den[2]
        )
    });
    let template_frame = drive_file::DriveFile::parse(&a.template, &template)
        .map(|f| f.spec.current_frame)
        .map_err(|e| e.to_string())?;
    let frame = |f: controller_core::drive::CurrentFrame| match f {
        controller_core::drive::CurrentFrame::Stationary => "stationary",
        controller_core::drive::CurrentFrame::Synchronous => "synchronous",
    };
    if t.spec.current_frame != template_frame {
        report::outln!(
            "current frame: {} (the template's {} frame passes no crossover of the search as fast)",
            frame(t.spec.current_frame),
            frame(template_frame)
        );
    }
    report::outln!(
        "current loops: {} {} kp {:.4} V/A, ki {:.1} V/(A·s){lag} — crossover {:.0} rad/s on the nominal motor, \
         smallest margin {:.3}× its minimum over the box",
        frame(t.spec.current_frame),
        if law.lag.is_some() { "ICAD" } else { "PI" },
        law.kp_v_per_a,
        law.ki_v_per_as,
        t.omega_c_rad_s,
        t.current_robustness
    );
    match t.spec.speed_law {
        controller_core::speed::SpeedLaw::SaturatedP { kp, tau_max_nm } => report::outln!(
            "speed loop: saturated P kp {kp:.5} N·m·s/rad, τ_max {tau_max_nm:.3} N·m — {}",
            t.speed_origin
        ),
        controller_core::speed::SpeedLaw::PiTorque { kp, ki, limit, setpoint_weight } => report::outln!(
            "speed loop: PI kp {kp:.5} N·m·s/rad, ki {ki:.5} N·m/rad, limit {limit:.3} N·m, setpoint weight \
             {setpoint_weight} — {}",
            t.speed_origin
        ),
        controller_core::speed::SpeedLaw::PiIq { .. } => {}
    }
    let quarter = design::tune::heaviest_speed_bandwidth(t.omega_s_rad_s, &t.certify)
        / design::tune::POSITION_BELOW_SPEED;
    report::outln!(
        "position loop: k {:.4} 1/s ({}the speed loop's {:.2} rad/s on the heaviest inertia / {}), ω_max {} rad/s",
        t.spec.position.k_per_s,
        if t.spec.position.k_per_s < quarter { "lowered for the sampled certificate from " } else { "" },
        quarter * design::tune::POSITION_BELOW_SPEED,
        design::tune::POSITION_BELOW_SPEED,
        t.spec.position.omega_max_rad_s
    );
    let c = &t.certify;
    // The link rewrites a saturated P's gains only: a PI's file keeps the template's ranges,
    // which nothing writes.
    let writable = match t.spec.speed_law {
        controller_core::speed::SpeedLaw::SaturatedP { .. } => {
            format!("; writable kp {}", interval(c.speed_kp_writable))
        }
        _ => String::new(),
    };
    report::outln!(
        "box: Rs×{} Rr×{} L×{} J×{}{writable}; certified: {} checks pass",
        interval(c.rs_factor),
        interval(c.rr_factor),
        interval(c.inductance_factor),
        interval(c.j_factor),
        t.checks.len()
    );
    let estimate = |[lo, hi]: [f64; 2]| if lo < hi { interval([lo, hi]) } else { format!("fixed at ×{lo}") };
    report::outln!(
        "estimates the drive runs on: R_r {}, L {} (rotor_resistance_range, inductance_range)",
        estimate(t.spec.rotor_resistance_range),
        estimate(t.spec.inductance_range)
    );
    if t.predicted_misses.is_empty() && t.met_in_sil {
        report::outln!(
            "requirements: met over the box by the speed law alone (predicted), and by the drive on {} in SIL \
             (`hil-sim campaign` judges it over the whole box)",
            t.sil_runs
        );
    } else if t.predicted_misses.is_empty() {
        report::outln!(
            "requirements: met over the box by the speed law alone (predicted; `hil-sim campaign` judges the drive)"
        );
    }
    for (k, m) in &t.predicted_misses {
        report::outln!(
            "requirements: {} predicted missed (worst {k}: {:.4} against {:.4}) — the speed law you chose; `--speed auto` chooses one that meets them",
            m.requirement,
            m.value,
            m.allowed
        );
    }
    if t.changes.is_empty() {
        report::outln!("changed: nothing (the template's values are the tuned ones)");
    }
    for c in &t.changes {
        report::outln!("changed: {c}");
    }
    cli::write_atomic(&a.out, &t.text)?;
    eprintln!("design: wrote {}", a.out.display());
    Ok(true)
}

fn finite_speed(s: &str) -> Result<f64, String> {
    let max = drive_file::certify::OMEGA_R_MAX_RAD_S;
    s.parse::<f64>()
        .ok()
        .filter(|x| x.is_finite() && x.abs() <= max)
        .ok_or(format!("`{s}` is not a speed within ±{max} rad/s"))
}

fn parse_law(s: &str) -> Result<CurrentLaw, String> {
    match s {
        "icad20" => Ok(CurrentLaw::ICAD_EQ20),
        file if file.ends_with(".toml") => {
            let path = std::path::Path::new(file);
            let text = drive_file::source::read(path).map_err(|e| e.to_string())?;
            Ok(drive_file::DriveFile::parse(path, &text).map_err(|e| e.to_string())?.spec.current_law)
        }
        other => match other.strip_prefix("pi:") {
            Some(g) => {
                let (kp, ki) = cli::kharitonov::parse_pi(g)?;
                Ok(CurrentLaw { kp_v_per_a: kp, ki_v_per_as: ki, lag: None })
            }
            None => Err(format!("`{other}` is neither icad20, pi:KP,KI nor a drive file (.toml)")),
        },
    }
}

fn icad(a: &IcadArgs) -> Result<bool, String> {
    let m = drive_file::motor::load(&a.motor).map_err(|e| e.to_string())?;
    let (omega_r, law, json) = (a.omega_r, a.controller, a.json);
    let r = design::icad::analyse(&m, &law, omega_r);
    let stable_here = design::icad::closed_loop_abscissa(&m, &law, omega_r) < 0.0;
    let range = design::icad::stable_omega_r_max(&m, &law, 5.0, 5000.0);
    let ts = 1.0 / a.pwm_hz;
    let ctrl = controller_core::current::CurrentControllerConfig::<f32>::new(
        &law,
        ts,
        controller_core::discretize::Discretization::Tustin,
        1.0,
    )
    .map_err(|e| format!("the law cannot be discretised at {} Hz: {e}", a.pwm_hz))?;
    let sampled = design::sampled::analyse(&m, &ctrl, ts, omega_r);
    let sampled_range = design::sampled::stable_omega_r_max(&m, &ctrl, ts, 5.0, 5000.0);
    // The loop as the drive runs it, at this speed: the exit status asks both (a 100 Hz loop
    // unstable at every speed exited 0 on the continuous verdict alone: found by trying).
    let radius =
        design::sampled::spectral_radius(&design::sampled::current_loop_matrix(&m, &ctrl, ts, omega_r));
    let sampled_here = radius < 1.0;
    let v = serde_json::json!({
        "omega_r_rad_s": omega_r,
        "crossover_rad_s": r.channel.crossover_rad_s,
        "phase_margin_deg": r.channel.phase_margin_deg,
        "gain_margin_increase_db": r.channel.gain_margin_increase_db,
        "gain_margin_reduction_db": r.channel.gain_margin_reduction_db,
        "bandwidth_rad_s": r.channel.bandwidth_rad_s,
        "diagonal_phase_margin_deg": r.diagonal.phase_margin_deg,
        "diagonal_gain_margin_reduction_db": r.diagonal.gain_margin_reduction_db,
        "kg_at_omega_r_db": r.kg_at_omega_r_db,
        "coupling_peak_db": r.coupling_peak_db,
        "gamma_margin_db": r.gamma_margin_db,
        "gamma_h_margin_db": r.gamma_h_margin_db,
        "gm_min": r.gm_min,
        "gm_min_db": 20.0 * r.gm_min.log10(),
        "stable_at_omega_r": stable_here,
        "stable_omega_r_max_rad_s": range,
        "stable_omega_r_search_limit_rad_s": 5000.0,
        "sampled_pwm_hz": a.pwm_hz,
        "sampled_phase_margin_deg": sampled.channel.phase_margin_deg,
        "sampled_gain_margin_increase_db": sampled.channel.gain_margin_increase_db,
        "sampled_gain_margin_reduction_db": sampled.channel.gain_margin_reduction_db,
        "sampled_gamma_h_margin_db": sampled.gamma_h_margin_db,
        "sampled_stable_omega_r_max_rad_s": sampled_range,
        "sampled_spectral_radius": radius,
        "sampled_stable_at_omega_r": sampled_here,
    });
    if json {
        report::outln!("{}", serde_json::to_string_pretty(&v).map_err(|e| e.to_string())?);
    } else if let Some(obj) = v.as_object() {
        for (k, val) in obj {
            report::outln!("{k:<36} {val}");
        }
    }
    if stable_here && !sampled_here {
        eprintln!(
            "design icad: stable as a continuous loop at ω_r = {omega_r} rad/s, but not sampled at {} Hz \
             (spectral radius {radius:.4} ≥ 1)",
            a.pwm_hz
        );
    }
    Ok(stable_here && sampled_here)
}

fn certify(a: &CertifyArgs) -> Result<bool, String> {
    let (path, json) = (a.drive.clone(), a.json);
    // The page goes beside the JSON, as `.svg`: an --out of that name would be overwritten.
    if let Some(out) = a.out.as_ref().filter(|o| o.extension().is_some_and(|e| e == "svg")) {
        return Err(format!(
            "--out {}: the certificate is JSON, and its page is written beside it as .svg — name it .json",
            out.display()
        ));
    }
    a.plot_dir.as_deref().map(report::write::check_dir).transpose()?;
    let drive_text = drive_file::source::read(std::path::Path::new(&path)).map_err(|e| e.to_string())?;
    let (spec, c) = design::certify::parse(std::path::Path::new(&path), &drive_text)?;
    let checks = design::certify::certify(&spec, &c)?;
    // The user's current-bandwidth requirement, on every corner (the sampled loops').
    let file =
        drive_file::DriveFile::parse(std::path::Path::new(&path), &drive_text).map_err(|e| e.to_string())?;
    let requirements = file.requirements;
    let (bw_rad_s, bw_corner) = design::certify::current_bandwidth_rad_s(&spec, &c)?;
    let bw_hz = bw_rad_s / std::f64::consts::TAU;
    let bw_ok = bw_hz >= requirements.current_bandwidth_hz;
    // The link's writable speed gains: the requirements at each corner of their ranges
    // (predicted on the ideal actuator, as `design tune` chooses the law).
    let writable = design::tune::writable_gain_misses(&spec, &c, &file)?;
    let writable_ok = writable.is_empty();
    let writable_json: Vec<_> = writable
        .iter()
        .flat_map(|([kp, tau], misses)| {
            misses.iter().map(move |(k, m)| {
                serde_json::json!({"kp": kp, "tau_max_nm": tau, "requirement": m.requirement.to_string(),
                    "worst_run": k.k, "worst_run_duration_s": k.duration_s, "value": m.value, "allowed": m.allowed})
            })
        })
        .collect();
    // The observer, for a drive that runs one (issue 53): linearised over its range.
    let observer = design::observer::check(&spec);
    let observer_ok = observer.is_none_or(|o| o.pass);
    let linear_ok = checks.iter().all(|c| c.pass) && bw_ok && writable_ok && observer_ok;
    let nonlinear = a.campaign.as_deref().map(|p| campaign_result(p, &drive_text, &c)).transpose()?;
    let ok = linear_ok && nonlinear.as_ref().is_none_or(|n| n.ok);
    if let Some(out) = &a.out {
        let v: Vec<_> = checks
            .iter()
            .map(|c| serde_json::json!({"check": c.name, "corner": c.corner, "value": c.value, "limit": c.limit, "pass": c.pass}))
            .collect();
        let cert = serde_json::json!({
            "file": path,
            "fingerprint": drive_file::source::fingerprint(&drive_text),
            "certified": ok,
            "linear": {"certified": linear_ok, "checks": v},
            "requirements": {
                "current_bandwidth_hz": {"least": bw_hz, "corner": bw_corner, "allowed_least": requirements.current_bandwidth_hz, "met": bw_ok},
                "writable_speed_gains": {"kp": c.speed_kp_writable, "tau_max_nm": c.speed_tau_max_nm_writable, "met": writable_ok, "missed": writable_json},
            },
            "nonlinear": nonlinear.as_ref().map(|n| n.record.clone()),
            "observer": observer.map(|o| serde_json::json!({
                "worst_radius": if o.worst.radius.is_finite() { serde_json::json!(o.worst.radius) } else { serde_json::Value::Null },
                "at_omega_e_rad_s": o.worst.point.omega_m_rad_s,
                "at_i_q_a": o.worst.point.i_q_a,
                "stator_resistance_margin": o.rs_margin,
                "pass": o.pass,
            })),
        });
        let text = serde_json::to_string_pretty(&cert).map_err(|e| e.to_string())?;
        cli::write_atomic(out, &format!("{text}\n"))?;
        eprintln!("design: wrote the certificate to {}", out.display());
        // Its page: the step response over the box against the requirements, the
        // torque–speed envelope against the physical limit.
        let vdc = nonlinear
            .as_ref()
            .and_then(|n| n.vdc_v)
            .unwrap_or_else(|| hil_sim::commands::default_bus_v(&file));
        let band = nonlinear.as_ref().and_then(|n| n.step_band.as_ref());
        let page = out.with_extension("svg");
        cli::write_atomic(&page, &design::certify::summary_page(&spec, band, vdc)?)?;
        eprintln!("design: wrote the certificate's page to {}", page.display());
    }
    if let Some(n) = &nonlinear {
        report::outln!(
            "campaign: {} of {} runs passed{}",
            n.passed,
            n.runs,
            if n.ok { "" } else { " — NOT certified nonlinearly" }
        );
    }
    if let Some(dir) = &a.plot_dir {
        std::fs::create_dir_all(dir).map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
        for (name, svg) in design::certify::pictures(&spec, &c)? {
            cli::write_atomic(&dir.join(name), &svg)?;
        }
        eprintln!("design: wrote the certificate's pictures to {}", dir.display());
    }
    if json {
        let v: Vec<_> = checks
            .iter()
            .map(|c| serde_json::json!({"check": c.name, "corner": c.corner, "value": c.value, "limit": c.limit, "pass": c.pass}))
            .collect();
        let out = serde_json::json!({"file": path, "certified": ok, "checks": v});
        report::outln!("{}", serde_json::to_string_pretty(&out).map_err(|e| e.to_string())?);
    } else {
        for ch in &checks {
            let value = ch.value.map_or_else(|| "none".to_string(), |v| format!("{v:.3}"));
            report::outln!(
                "{:<5} {:<56} {:<22} {:>10}  limit {}",
                if ch.pass { "ok" } else { "FAIL" },
                ch.name,
                ch.corner,
                value,
                ch.limit
            );
        }
        report::outln!(
            "{:<5} {:<56} {:<22} {:>10.1}  least {}",
            if bw_ok { "ok" } else { "FAIL" },
            "requirements.current_bandwidth_hz: sampled crossover (Hz)",
            bw_corner,
            bw_hz,
            requirements.current_bandwidth_hz
        );
        if matches!(spec.speed_law, controller_core::speed::SpeedLaw::SaturatedP { .. }) {
            report::outln!(
                "{:<5} {:<56} {:<22} {:>10}  of 4",
                if writable_ok { "ok" } else { "FAIL" },
                "requirements over the writable speed gains (predicted)",
                "k_p × τ_max corners",
                4 - writable.len(),
            );
        }
        if let Some(o) = observer {
            let w = o.worst;
            report::outln!(
                "{:<5} {:<56} {:<22} {:>10.6}  below 1",
                if o.pass { "ok" } else { "FAIL" },
                "observer: linearised, parameters right (spectral radius)",
                format!("{:.0} rad/s, {:+.2} A", w.point.omega_m_rad_s, w.point.i_q_a),
                w.radius
            );
            // What the drive's measurement of R_s at every enable must reach: said, not judged.
            match o.rs_margin {
                Some([lo, hi]) => report::outln!(
                    "{:<5} {:<56} {:<22} {:>10}  ×[{lo:.3}, {hi:.3}]",
                    "info",
                    "observer: stator resistance it holds at, × the motor's",
                    "whole grid",
                    ""
                ),
                None => report::outln!("{:<5} observer: no stator resistance margin", "info"),
            }
        }
        report::outln!("{path}: {}", if ok { "certified" } else { "NOT certified" });
        if matches!(spec.control, controller_core::drive::Control::VHz { .. }) {
            // Said, not hidden: what the certificate did not check (issue 53).
            eprintln!(
                "design certify: {path}: note: control = \"vhz\" — the certificate checks the current and speed \
                 loops vector control runs (the magnetizing runs on the current loops); the V/Hz law's own \
                 stability is not in it (docs/sensorless.md)"
            );
        }
    }
    if let Some(n) = nonlinear.as_ref().filter(|n| !n.ok) {
        eprintln!("design certify: {path}: the campaign passed {} of {} runs", n.passed, n.runs);
        // Each requirement missed, with its worst run: what the user asked and did not get.
        for r in n.record.get("requirements").and_then(|r| r.as_array()).into_iter().flatten() {
            let (met, runs) = (r["met"].as_u64().unwrap_or(0), r["runs"].as_u64().unwrap_or(0));
            if met < runs {
                let shown =
                    |v: &serde_json::Value| v.as_f64().map_or_else(|| "∞".to_string(), |x| format!("{x:.4}"));
                eprintln!(
                    "design certify: {path}: {} missed in {} of {runs} runs (worst: run {}, {} against {})",
                    r["requirement"].as_str().unwrap_or("?"),
                    runs - met,
                    r["worst_run"],
                    shown(&r["worst_value"]),
                    shown(&r["allowed"]),
                );
            }
        }
    }
    if !bw_ok {
        eprintln!(
            "design certify: {path}: requirements.current_bandwidth_hz missed: the current loops cross over at {bw_hz:.1} Hz at {bw_corner}, the file asks {} Hz",
            requirements.current_bandwidth_hz
        );
    }
    for ([kp, tau], misses) in &writable {
        let what: Vec<String> = misses
            .iter()
            .map(|(k, m)| {
                format!("{} (worst run {k}: {:.4} against {:.4})", m.requirement, m.value, m.allowed)
            })
            .collect();
        eprintln!(
            "design certify: {path}: at the writable k_p {kp}, τ_max {tau} N·m the speed law is predicted to miss {} — narrow certify.speed_kp_writable / speed_tau_max_nm_writable",
            what.join(", ")
        );
    }
    if !ok {
        for ch in checks.iter().filter(|c| !c.pass) {
            // The value as a number, or "none" (it printed "Some(44.17…)": found by trying).
            let value = ch.value.map_or_else(|| "none".to_string(), |v| format!("{v:.4}"));
            eprintln!("design certify: {path}: {} at {} is {value}, limit {}", ch.name, ch.corner, ch.limit);
        }
    }
    Ok(ok)
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match &cli.command {
        Cmd::Kharitonov(a) => cli::kharitonov::run(a),
        Cmd::Icad(a) => icad(a),
        Cmd::Certify(a) => certify(a),
        Cmd::Tune(a) => tune(a),
        Cmd::Recycle(a) => cli::recycle::run(a),
        Cmd::Bench => cli::bench::run(),
        Cmd::StartupFit(a) => cli::startup_fit::run(a),
    };
    match result {
        Ok(true) => ExitCode::SUCCESS,
        Ok(false) => ExitCode::from(1),
        Err(e) => {
            eprintln!("design: {e}");
            ExitCode::from(2)
        }
    }
}
