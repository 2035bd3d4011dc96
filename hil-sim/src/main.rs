//! `hil-sim` command line.
//!
//! ```text
//! hil-sim list                      built-in scenarios
//! hil-sim run <name> [--out DIR]    run one; writes DIR/trace.csv and prints a summary
//! ```

use controller_core::drive::{Drive, DriveConfig};
use hil_sim::plant::Machine;
use hil_sim::scenario::{self, Builtin};
use hil_sim::sim::{self, Row};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

fn usage() -> ExitCode {
    eprintln!("usage: hil-sim list | hil-sim run <scenario> [--out DIR]");
    ExitCode::from(2)
}

fn write_trace(dir: &Path, rows: &[Row]) -> std::io::Result<PathBuf> {
    std::fs::create_dir_all(dir)?;
    let path = dir.join("trace.csv");
    let tmp = dir.join(".trace.csv.partial");
    let mut f = std::io::BufWriter::new(std::fs::File::create(&tmp)?);
    writeln!(
        f,
        "t_s,i_alpha_a,i_beta_a,psi_alpha_wb,psi_beta_wb,omega_m_rad_s,theta_m_rad,torque_nm,v_alpha_v,v_beta_v,i_alpha_ref_a,i_beta_ref_a,omega_ref_rad_s,load_nm"
    )?;
    for r in rows {
        let x = &r.x;
        writeln!(
            f,
            "{:.6},{:.6},{:.6},{:.6},{:.6},{:.5},{:.5},{:.5},{:.4},{:.4},{:.6},{:.6},{:.4},{:.4}",
            r.t_s,
            x.i_alpha_a,
            x.i_beta_a,
            x.psi_alpha_wb,
            x.psi_beta_wb,
            x.omega_m_rad_s,
            x.theta_m_rad,
            r.torque_nm,
            r.v_ab_v[0],
            r.v_ab_v[1],
            r.i_ref_ab_a[0],
            r.i_ref_ab_a[1],
            r.omega_ref_rad_s,
            r.load_nm
        )?;
    }
    f.into_inner().map_err(|e| e.into_error())?.sync_all()?;
    // Nothing half-written: the trace appears only when complete.
    std::fs::rename(&tmp, &path)?;
    Ok(path)
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

fn run(b: &Builtin, out: &Path) -> Result<(), String> {
    let cfg = DriveConfig::new(&b.spec).map_err(|e| format!("invalid drive specification: {e:?}"))?;
    let mut drive = Drive::new(cfg);
    let machine = Machine::new(&b.spec.motor);
    eprintln!("hil-sim: {} — {}", b.name, b.about);
    let wall = std::time::Instant::now();
    let rows = sim::run(&mut drive, &machine, b.spec.pwm_frequency_hz, &b.scenario, progress_bar);
    let secs = wall.elapsed().as_secs_f64();
    let path =
        write_trace(out, &rows).map_err(|e| format!("cannot write trace to {}: {e}", out.display()))?;
    let last = rows.last().ok_or("empty run")?;
    let peak_i = rows.iter().map(|r| r.x.i_alpha_a.hypot(r.x.i_beta_a)).fold(0.0, f64::max);
    println!("trace            {}", path.display());
    println!(
        "simulated        {:.3} s in {:.1} ms wall ({:.0}x real time, {} RK4 sub-steps per PWM period)",
        b.scenario.duration_s,
        secs * 1e3,
        b.scenario.duration_s / secs,
        b.scenario.substeps
    );
    println!("final speed      {:.3} rad/s (reference {:.1})", last.x.omega_m_rad_s, last.omega_ref_rad_s);
    println!("peak |i_s|       {peak_i:.3} A");
    println!("drive mode       {:?}", drive.mode());
    Ok(())
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let builtins = match scenario::all() {
        Ok(b) => b,
        Err(e) => {
            eprintln!("hil-sim: built-in motor parameters rejected: {e:?}");
            return ExitCode::FAILURE;
        }
    };
    match args.first().map(String::as_str) {
        Some("list") => {
            for b in &builtins {
                println!("{:<14} {}", b.name, b.about);
            }
            ExitCode::SUCCESS
        }
        Some("run") => {
            let Some(name) = args.get(1) else { return usage() };
            let out = match (args.get(2).map(String::as_str), args.get(3)) {
                (None, _) => PathBuf::from("out").join(name),
                (Some("--out"), Some(d)) => PathBuf::from(d),
                _ => return usage(),
            };
            let Some(b) = builtins.iter().find(|b| b.name == name) else {
                eprintln!("hil-sim: unknown scenario `{name}`; `hil-sim list` shows the built-in ones");
                return ExitCode::from(2);
            };
            match run(b, &out) {
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
