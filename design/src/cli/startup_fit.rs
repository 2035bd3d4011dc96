//! `design startup-fit`: seed 000 Sec. 6 — an interval plant fitted to a nonlinear start-up.

use design::startup_fit::{Experiment, fit_segments, interval_plant, replay, simulate};
use report::plot::{Series, line_plot};
use std::fmt::Write as _;
use std::path::Path;

/// Seed 000 Sec. 6: fit linear models to segments of a direct-on-line start of the
/// nonlinear machine and write their coefficient ranges as an interval plant file
/// (`design kharitonov --plant`). Exit 0 when every fitted model replays its segment's i_sα
/// within 5 % RMS.
#[derive(clap::Args, Debug)]
pub struct StartupFitArgs {
    /// A shipped motor name or any file with a [motor] table.
    #[arg(long, default_value = "krause-2300v-500hp")]
    motor: String,
    /// Number of segments.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=200))]
    segments: Option<u32>,
    /// Print JSON.
    #[arg(long)]
    json: bool,
    /// Write the start-up and fitted-model plots here.
    #[arg(long)]
    plot_dir: Option<String>,
    /// Write the interval plant file here.
    #[arg(long)]
    plant_out: Option<String>,
}

/// Run; `Ok(true)` when every segment's replay error is below 5 %.
pub fn run(a: &StartupFitArgs) -> Result<bool, String> {
    let (motor, json, plot_dir, plant_out) =
        (a.motor.clone(), a.json, a.plot_dir.clone(), a.plant_out.clone());
    let mut e = Experiment::krause_2300v();
    if let Some(n) = a.segments {
        e.segments = n as usize;
    }
    let m = drive_file::motor::load(&motor).map_err(|er| er.to_string())?;
    let trace = simulate(&m, &e)?;
    let segs = fit_segments(&m, &trace, &e)?;
    let plant = interval_plant(&segs);
    if let Some(path) = &plant_out {
        if let Some(parent) = Path::new(path).parent().filter(|p| !p.as_os_str().is_empty()) {
            std::fs::create_dir_all(parent).map_err(|er| format!("{}: {er}", parent.display()))?;
        }
        let mut t = String::new();
        let _ = writeln!(
            t,
            "# Interval plant g11 = i_sα/v_sα fitted to a start-up of `{motor}` (design startup-fit,"
        );
        let _ = writeln!(t, "# {} segments); descending coefficients, monic denominator.", segs.len());
        let _ = writeln!(t, "[numerator]\nlo = {:?}\nhi = {:?}\n", plant.num.lo(), plant.num.hi());
        let _ = writeln!(t, "[denominator]\nlo = {:?}\nhi = {:?}", plant.den.lo(), plant.den.hi());
        super::write_atomic(Path::new(path), &t)?;
        eprintln!("design: wrote {path}");
    }
    if let Some(dir) = &plot_dir {
        let dir = Path::new(dir);
        std::fs::create_dir_all(dir).map_err(|er| format!("{}: {er}", dir.display()))?;
        let every = (trace.x.len() / 20_000).max(1);
        let nonlinear: Vec<(f64, f64)> =
            trace.t_s.iter().zip(&trace.x).step_by(every).map(|(t, x)| (*t, x.i_alpha_a)).collect();
        let mut fitted = Vec::new();
        for s in &segs {
            let sim = replay(&trace, s.range, &s.a, &s.b, e.h_s);
            fitted.extend(
                trace
                    .t_s
                    .get(s.range.0..s.range.1)
                    .unwrap_or(&[])
                    .iter()
                    .zip(sim)
                    .step_by(every)
                    .map(|(t, i)| (*t, i)),
            );
        }
        let svg = line_plot(
            "Start-up: nonlinear i_sα (A) and the fitted linear models, each replayed over its segment",
            "t (s)",
            &[Series::line("nonlinear plant", nonlinear), Series::line("fitted models (piecewise)", fitted)],
        );
        super::write_atomic(&dir.join("startup-fit.svg"), &svg)?;
        let speed: Vec<(f64, f64)> = trace
            .t_s
            .iter()
            .zip(&trace.x)
            .step_by(every)
            .map(|(t, x)| (*t, x.omega_m_rad_s * f64::from(m.pole_pairs())))
            .collect();
        let bounds: Vec<(f64, f64)> = segs.iter().map(|s| (s.t_s.0, s.omega_r_mean_rad_s)).collect();
        let svg = line_plot(
            "Start-up: electrical rotor speed (rad/s) and the segments' mean speeds",
            "t (s)",
            &[Series::line("ω_r", speed), Series::markers("segment start, mean ω_r", bounds)],
        );
        super::write_atomic(&dir.join("startup-speed.svg"), &svg)?;
        eprintln!("design: wrote the start-up plots to {}", dir.display());
    }
    let ok = segs.iter().all(|s| s.replay_rel_rms < 0.05);
    let per: Vec<_> = segs
        .iter()
        .map(|s| {
            serde_json::json!({
                "t_s": [s.t_s.0, s.t_s.1], "omega_r_mean_rad_s": s.omega_r_mean_rad_s,
                "replay_rel_rms": s.replay_rel_rms,
                "g11_num": s.g11.num.coeffs(), "g11_den": s.g11.den.coeffs(),
            })
        })
        .collect();
    let v = serde_json::json!({
        "motor": motor, "experiment": e, "segments": per,
        "interval_plant": {
            "numerator": {"lo": plant.num.lo(), "hi": plant.num.hi()},
            "denominator": {"lo": plant.den.lo(), "hi": plant.den.hi()},
        },
    });
    if json {
        report::outln!("{}", serde_json::to_string_pretty(&v).map_err(|er| er.to_string())?);
    } else {
        report::outln!("start-up of {motor}: {} segments", segs.len());
        for s in &segs {
            report::outln!(
                "  {:.3}–{:.3} s  mean ω_r {:7.1} rad/s  replay error {:5.2} %",
                s.t_s.0,
                s.t_s.1,
                s.omega_r_mean_rad_s,
                100.0 * s.replay_rel_rms
            );
        }
        let fmt = |v: &[f64]| v.iter().map(|x| format!("{x:.4e}")).collect::<Vec<_>>().join(", ");
        report::outln!(
            "interval g11 numerator   lo [{}]\n                         hi [{}]",
            fmt(plant.num.lo()),
            fmt(plant.num.hi())
        );
        report::outln!(
            "interval g11 denominator lo [{}]\n                         hi [{}]",
            fmt(plant.den.lo()),
            fmt(plant.den.hi())
        );
    }
    Ok(ok)
}
