//! `hil-sim` command line.
//!
//! ```text
//! hil-sim list                                   built-in scenarios
//! hil-sim run <scenario.toml | builtin> [--out DIR]
//! hil-sim pil <scenario.toml | builtin> [--out DIR] [--elf PATH] [--no-pin]
//! ```
//! `pil` runs a closed-loop scenario with the drive on an emulated Cortex-M4F (QEMU,
//! processor in the loop) and writes the same outputs as `run`, plus link figures in the
//! summary; `--elf` names the target program (default: `qemu-target`'s release build),
//! `--no-pin` leaves QEMU and the simulator unpinned (slower).
//!
//! ```text
//! hil-sim link <DEVICE> <enable | disable | clear-fault | status | speed W | position TH | torque T | gains | set-gains KP TAU | telemetry [N]>
//! ```
//! talks to the board's command/telemetry link on a serial device (e.g. `/dev/ttyACM0`, the
//! NUCLEO's virtual COM port; set to 115200 baud raw with `stty`, 2 s read timeout) and
//! prints the reply, or N telemetry frames.
//! ```text
//! hil-sim bench [builtin] [--runs N]
//! ```
//! times the closed-loop simulation alone (no trace files): the built-in scenario
//! (default `speed-step`, the issue's scenario 2) run N times (default 20) after one
//! warm-up run; prints JSON with the median and best simulated-seconds-per-wall-second and
//! nanoseconds per PWM period.
//!
//! `run` writes `DIR/trace.csv`, `DIR/summary.json` and the plots `speed.svg`,
//! `currents.svg`, `torque.svg` (default `DIR` = `out/<name>`). A file
//! that fails to parse or validate is reported with file, key and reason, and nothing is
//! written; outputs appear only complete (written to a temporary name, then renamed).

use controller_core::link::{Command, Reply};
use hil_sim::pil::PilOptions;
use hil_sim::scenario::{self, Builtin};
use hil_sim::sim::{self, Row};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

const BASE_HEADER: &str =
    "t_s,i_alpha_a,i_beta_a,psi_alpha_wb,psi_beta_wb,omega_m_rad_s,theta_m_rad,torque_nm,v_alpha_v,v_beta_v";
const CLOSED_LOOP_HEADER: &str = ",i_alpha_ref_a,i_beta_ref_a,omega_ref_rad_s,load_nm";

fn usage() -> ExitCode {
    eprintln!(
        "usage: hil-sim list\n       hil-sim run <scenario.toml | builtin> [--out DIR]\n       \
         hil-sim pil <scenario.toml | builtin> [--out DIR] [--elf PATH] [--no-pin]\n       \
         hil-sim bench [builtin] [--runs N]\n       \
         hil-sim link <DEVICE> <enable | disable | clear-fault | status | speed W | position TH | torque T | gains | set-gains KP TAU | telemetry [N]>"
    );
    ExitCode::from(2)
}

/// Write `path` atomically: a temporary sibling, synced, then renamed.
fn write_atomic(
    path: &Path,
    fill: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> std::io::Result<()> {
    let tmp = path.with_extension("partial");
    let mut f = std::io::BufWriter::new(std::fs::File::create(&tmp)?);
    fill(&mut f)?;
    f.into_inner().map_err(|e| e.into_error())?.sync_all()?;
    std::fs::rename(&tmp, path)
}

fn write_trace(path: &Path, rows: &[Row], closed_loop: bool) -> std::io::Result<()> {
    write_atomic(path, |f| {
        writeln!(f, "{BASE_HEADER}{}", if closed_loop { CLOSED_LOOP_HEADER } else { "" })?;
        for r in rows {
            let x = &r.x;
            write!(
                f,
                "{:.7},{:.6},{:.6},{:.6},{:.6},{:.5},{:.5},{:.5},{:.4},{:.4}",
                r.t_s,
                x.i_alpha_a,
                x.i_beta_a,
                x.psi_alpha_wb,
                x.psi_beta_wb,
                x.omega_m_rad_s,
                x.theta_m_rad,
                r.torque_nm,
                r.v_ab_v[0],
                r.v_ab_v[1]
            )?;
            if closed_loop {
                write!(
                    f,
                    ",{:.6},{:.6},{:.4},{:.4}",
                    r.i_ref_ab_a[0], r.i_ref_ab_a[1], r.omega_ref_rad_s, r.load_nm
                )?;
            }
            writeln!(f)?;
        }
        Ok(())
    })
}

fn progress_bar(fraction: f64) {
    use std::io::IsTerminal;
    if !std::io::stderr().is_terminal() {
        return;
    }
    let width = 40;
    let filled = ((fraction.clamp(0.0, 1.0)) * width as f64) as usize;
    eprint!("\r[{}{}] {:3.0}%", "#".repeat(filled), " ".repeat(width - filled), fraction * 100.0);
    if fraction >= 1.0 {
        eprintln!();
    }
}

fn peak_current(rows: &[Row]) -> f64 {
    rows.iter().map(|r| r.x.i_alpha_a.hypot(r.x.i_beta_a)).fold(0.0, f64::max)
}

/// The main signals as SVG plots: speed, stator currents (with references in closed loop),
/// torque. Rows are thinned to at most ~4000 points per curve.
fn write_plots(out: &Path, rows: &[Row], closed_loop: bool) -> Result<Vec<PathBuf>, String> {
    use hil_sim::plot::{Series, line_plot};
    let every = (rows.len() / 4000).max(1);
    let pts = |f: &dyn Fn(&Row) -> f64| rows.iter().step_by(every).map(|r| (r.t_s, f(r))).collect::<Vec<_>>();
    let mut speed = vec![Series::line("ω_m (rad/s)", pts(&|r| r.x.omega_m_rad_s))];
    let mut currents = vec![
        Series::line("i_α (A)", pts(&|r| r.x.i_alpha_a)),
        Series::line("i_β (A)", pts(&|r| r.x.i_beta_a)),
    ];
    let mut torque = vec![Series::line("T_e (N·m)", pts(&|r| r.torque_nm))];
    if closed_loop {
        speed.push(Series::line("ω_ref (rad/s)", pts(&|r| r.omega_ref_rad_s)));
        currents.push(Series::line("i_α ref (A)", pts(&|r| r.i_ref_ab_a[0])));
        currents.push(Series::line("i_β ref (A)", pts(&|r| r.i_ref_ab_a[1])));
        torque.push(Series::line("T_L (N·m)", pts(&|r| r.load_nm)));
    }
    let mut written = Vec::new();
    for (name, title, series) in [
        ("speed.svg", "Rotor speed", speed),
        ("currents.svg", "Stator currents", currents),
        ("torque.svg", "Torque", torque),
    ] {
        let path = out.join(name);
        let svg = line_plot(title, "t (s)", &series);
        write_atomic(&path, |f| f.write_all(svg.as_bytes()))
            .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
        written.push(path);
    }
    Ok(written)
}

fn finish(out: &Path, rows: &[Row], closed_loop: bool, summary: serde_json::Value) -> Result<(), String> {
    std::fs::create_dir_all(out).map_err(|e| format!("cannot create {}: {e}", out.display()))?;
    let trace = out.join("trace.csv");
    write_trace(&trace, rows, closed_loop).map_err(|e| format!("cannot write {}: {e}", trace.display()))?;
    write_plots(out, rows, closed_loop)?;
    let path = out.join("summary.json");
    let text = serde_json::to_string_pretty(&summary).map_err(|e| e.to_string())?;
    write_atomic(&path, |f| writeln!(f, "{text}"))
        .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
    println!("{text}");
    eprintln!(
        "hil-sim: wrote trace.csv, summary.json, speed.svg, currents.svg, torque.svg in {}",
        out.display()
    );
    Ok(())
}

fn run_builtin(b: &Builtin, out: &Path, pil: Option<&PilOptions>) -> Result<(), String> {
    eprintln!("hil-sim: {} — {}", b.name, b.about);
    let wall = std::time::Instant::now();
    let (rows, mode, link) = match pil {
        None => {
            let (rows, mode) = b.run(progress_bar)?;
            (rows, format!("{mode:?}"), None)
        }
        Some(opts) => {
            let (rows, mut link) = b.run_pil(opts, progress_bar)?;
            let mode = match link.transact(&Command::GetStatus)? {
                Reply::Status { mode, .. } => format!("{mode:?}"),
                other => return Err(format!("unexpected reply to GetStatus: {other:?}")),
            };
            (rows, mode, Some(link))
        }
    };
    let secs = wall.elapsed().as_secs_f64();
    let last = rows.last().ok_or("empty run")?;
    let mut summary = serde_json::json!({
        "scenario": b.name,
        "kind": "closed_loop",
        "duration_s": b.scenario.duration_s,
        "final_omega_m_rad_s": last.x.omega_m_rad_s,
        "final_omega_ref_rad_s": last.omega_ref_rad_s,
        "peak_stator_current_a": peak_current(&rows),
        "drive_mode": mode,
        "rk4_substeps_per_pwm_period": b.scenario.substeps,
        "wall_time_s": secs,
        "real_time_factor": b.scenario.duration_s / secs,
    });
    if let (Some(link), Some(obj)) = (&link, summary.as_object_mut()) {
        obj.insert("controller".into(), "pil: QEMU mps2-an386 (Cortex-M4F)".into());
        obj.insert("link_round_trips".into(), link.round_trips().into());
        obj.insert("link_round_trips_per_s".into(), (link.round_trips() as f64 / secs).into());
        obj.insert("link_host_rx_errors".into(), link.stats().errors().into());
        obj.insert("pinned_to_one_cpu".into(), link.pinned().into());
    }
    drop(link);
    finish(out, &rows, true, summary)
}

fn run_file(path: &Path, out: &Path, pil: Option<&PilOptions>) -> Result<(), String> {
    use hil_sim::scenario_file::{self, ScenarioFileKind};
    let sc = match scenario_file::load(path).map_err(|e| e.to_string())? {
        ScenarioFileKind::ClosedLoop(b) => return run_builtin(&b, out, pil),
        ScenarioFileKind::OpenLoop(_) if pil.is_some() => {
            return Err(format!(
                "{}: an open-loop scenario has no controller to put in the loop",
                path.display()
            ));
        }
        ScenarioFileKind::OpenLoop(sc) => sc,
    };
    eprintln!("hil-sim: open-loop run of {}", path.display());
    let wall = std::time::Instant::now();
    let rows = sim::run_open_loop(&sc, sim::OPEN_LOOP_MAX_STEP_S, progress_bar);
    let secs = wall.elapsed().as_secs_f64();
    let last = rows.last().ok_or("empty run")?;
    let summary = serde_json::json!({
        "scenario": path.display().to_string(),
        "kind": "open_loop",
        "duration_s": sc.duration_s,
        "final_omega_m_rad_s": last.x.omega_m_rad_s,
        "final_torque_nm": last.torque_nm,
        "peak_stator_current_a": peak_current(&rows),
        "rk4_max_step_s": sim::OPEN_LOOP_MAX_STEP_S,
        "wall_time_s": secs,
    });
    finish(out, &rows, false, summary)
}

/// `hil-sim bench [builtin] [--runs N]`: wall time of the simulation loop alone.
fn bench(builtins: &[Builtin], args: &[String]) -> Result<(), String> {
    let mut name = "speed-step";
    let mut runs: u32 = 20;
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--runs" => {
                let v = it.next().ok_or("`--runs` needs a count")?;
                runs = v.parse().ok().filter(|&n| n > 0).ok_or(format!("`{v}` is not a positive count"))?;
            }
            flag if flag.starts_with("--") => return Err(format!("unknown flag `{flag}`")),
            n => name = n,
        }
    }
    let b = builtins
        .iter()
        .find(|b| b.name == name)
        .ok_or(format!("`{name}` is not a built-in scenario (`hil-sim list`)"))?;
    let periods = (b.scenario.duration_s * b.spec.pwm_frequency_hz).round();
    let mut secs = Vec::with_capacity(runs as usize);
    for k in 0..=runs {
        let wall = std::time::Instant::now();
        let (rows, _) = b.run(|_| {})?;
        let s = wall.elapsed().as_secs_f64();
        std::hint::black_box(rows);
        if k > 0 {
            secs.push(s);
        }
        progress_bar(f64::from(k) / f64::from(runs));
    }
    secs.sort_by(f64::total_cmp);
    let median = secs.get(secs.len() / 2).copied().ok_or("no runs")?;
    let best = secs.first().copied().ok_or("no runs")?;
    let summary = serde_json::json!({
        "scenario": b.name,
        "runs": runs,
        "duration_s": b.scenario.duration_s,
        "pwm_frequency_hz": b.spec.pwm_frequency_hz,
        "rk4_substeps_per_pwm_period": b.scenario.substeps,
        "median_wall_time_s": median,
        "median_real_time_factor": b.scenario.duration_s / median,
        "best_real_time_factor": b.scenario.duration_s / best,
        "median_ns_per_pwm_period": median * 1e9 / periods,
        "best_ns_per_pwm_period": best * 1e9 / periods,
    });
    println!("{}", serde_json::to_string_pretty(&summary).map_err(|e| e.to_string())?);
    Ok(())
}

/// `hil-sim link DEVICE …`: one command to the board, or N telemetry frames from it.
fn board_link(args: &[String]) -> Result<(), String> {
    use controller_core::drive::Reference;
    let (Some(dev), Some(what)) = (args.first(), args.get(1)) else {
        return Err("usage: hil-sim link <DEVICE> <command> (see `hil-sim` without arguments)".into());
    };
    let value = |name: &str| -> Result<f32, String> {
        let v = args.get(2).ok_or(format!("`{name}` needs a value"))?;
        v.parse::<f32>().map_err(|_| format!("`{v}` is not a number"))
    };
    let cmd = match what.as_str() {
        "enable" => Some(Command::Enable),
        "disable" => Some(Command::Disable),
        "clear-fault" => Some(Command::ClearFault),
        "status" => Some(Command::GetStatus),
        "speed" => Some(Command::SetReference(Reference::Speed(value("speed")?))),
        "position" => Some(Command::SetReference(Reference::Position(value("position")?))),
        "torque" => Some(Command::SetReference(Reference::Torque(value("torque")?))),
        "gains" => Some(Command::ReadSpeedGains),
        "set-gains" => {
            let kp = value("set-gains")?;
            let tau = args.get(3).ok_or("`set-gains` needs KP and TAU_MAX")?;
            let tau_max_nm = tau.parse::<f32>().map_err(|_| format!("`{tau}` is not a number"))?;
            Some(Command::WriteSpeedGains { kp, tau_max_nm })
        }
        "telemetry" => None,
        other => return Err(format!("unknown link command `{other}`")),
    };
    // 115200 baud, raw bytes, reads return after 2 s without data.
    let st = std::process::Command::new("stty")
        .args(["-F", dev, "115200", "raw", "-echo", "min", "0", "time", "20"])
        .status()
        .map_err(|e| format!("cannot run stty: {e}"))?;
    if !st.success() {
        return Err(format!("stty could not configure {dev}"));
    }
    let port =
        std::fs::OpenOptions::new().read(true).write(true).open(dev).map_err(|e| format!("{dev}: {e}"))?;
    let rx = port.try_clone().map_err(|e| format!("{dev}: {e}"))?;
    let mut link = hil_sim::link_client::LinkClient::new(rx, port);
    let no_answer = |e: String| format!("{e} (no answer from the board within 2 s?)");
    match cmd {
        Some(c) => println!("{:?}", link.transact(&c).map_err(no_answer)?),
        None => {
            let n = match args.get(2) {
                Some(v) => v.parse::<u32>().map_err(|_| format!("`{v}` is not a count"))?,
                None => 10,
            };
            for _ in 0..n {
                println!("{:?}", link.next_reply().map_err(no_answer)?);
            }
        }
    }
    Ok(())
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let builtins = match scenario::all() {
        Ok(b) => b,
        Err(e) => {
            eprintln!("hil-sim: built-in scenarios: {e}");
            return ExitCode::FAILURE;
        }
    };
    match args.first().map(String::as_str) {
        Some("link") => match board_link(args.get(1..).unwrap_or_default()) {
            Ok(()) => ExitCode::SUCCESS,
            Err(e) => {
                eprintln!("hil-sim: {e}");
                ExitCode::FAILURE
            }
        },
        Some("bench") => match bench(&builtins, args.get(1..).unwrap_or_default()) {
            Ok(()) => ExitCode::SUCCESS,
            Err(e) => {
                eprintln!("hil-sim: {e}");
                ExitCode::FAILURE
            }
        },
        Some("list") => {
            for b in &builtins {
                println!("{:<20} {}", b.name, b.about);
            }
            ExitCode::SUCCESS
        }
        Some(cmd @ ("run" | "pil")) => {
            let Some(name) = args.get(1) else { return usage() };
            let stem =
                Path::new(name).file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
            let mut out = PathBuf::from("out").join(&stem);
            let mut pil = (cmd == "pil").then(PilOptions::default);
            let mut rest = args.iter().skip(2);
            while let Some(flag) = rest.next() {
                match (flag.as_str(), &mut pil) {
                    ("--out", _) => match rest.next() {
                        Some(d) => out = PathBuf::from(d),
                        None => return usage(),
                    },
                    ("--elf", Some(p)) => match rest.next() {
                        Some(e) => p.elf = PathBuf::from(e),
                        None => return usage(),
                    },
                    ("--no-pin", Some(p)) => p.pin_cpu = None,
                    _ => return usage(),
                }
            }
            let result = if let Some(b) = builtins.iter().find(|b| &b.name == name) {
                run_builtin(b, &out, pil.as_ref())
            } else if name.ends_with(".toml") || Path::new(name).exists() {
                run_file(Path::new(name), &out, pil.as_ref())
            } else {
                Err(format!("`{name}` is neither a scenario file nor a built-in scenario (`hil-sim list`)"))
            };
            match result {
                Ok(()) => ExitCode::SUCCESS,
                Err(e) => {
                    eprintln!("hil-sim: {e}");
                    ExitCode::FAILURE
                }
            }
        }
        _ => usage(),
    }
}
