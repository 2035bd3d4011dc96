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
    /// The direct-on-line supply's line voltage (rms), V: seed 000's 2 300 V for its Krause
    /// motor; required for any other motor (its rated voltage).
    #[arg(long)]
    line_voltage_v: Option<f64>,
    /// The supply's frequency, Hz: seed 000's 60 Hz for its Krause motor; required for any
    /// other motor (its rated frequency).
    #[arg(long)]
    frequency_hz: Option<f64>,
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

/// The seed's motor, whose supply the experiment is ([`Experiment::krause_2300v`]).
const SEED000_MOTOR: &str = "krause-2300v-500hp";

/// The highest supply `--line-voltage-v` and `--frequency-hz` accept: beyond any
/// induction motor's.
const LINE_VOLTAGE_MAX_V: f64 = 100e3;
const FREQUENCY_MAX_HZ: f64 = 10e3;

/// A fitted model holds when it replays its segment's i_sα within this RMS fraction.
const REPLAY_ERROR_MAX: f64 = 0.05;

/// Run; `Ok(true)` when every segment's replay error is below [`REPLAY_ERROR_MAX`] (else
/// the interval plant is not written, and the segments that miss are named).
pub fn run(a: &StartupFitArgs) -> Result<bool, String> {
    let (motor, json, plot_dir, plant_out) =
        (a.motor.clone(), a.json, a.plot_dir.clone(), a.plant_out.clone());
    let mut e = Experiment::krause_2300v();
    if let Some(n) = a.segments {
        e.segments = n as usize;
    }
    let m = drive_file::motor::load(&motor).map_err(|er| er.to_string())?;
    // The experiment is seed 000's start of its Krause motor on 2 300 V, 60 Hz: any other
    // motor names its own supply (a 24 V motor was started on 2 300 V, and the failed fit's
    // plant was written all the same — found by trying).
    match (a.line_voltage_v, a.frequency_hz) {
        (Some(v), Some(f)) => {
            // A supply beyond any motor's (1e300 V overflowed the machine's state and read as
            // "time constants too short": found by trying).
            if !((0.0..=LINE_VOLTAGE_MAX_V).contains(&v)
                && v > 0.0
                && (0.0..=FREQUENCY_MAX_HZ).contains(&f)
                && f > 0.0)
            {
                return Err(format!(
                    "--line-voltage-v {v} and --frequency-hz {f} must lie in (0, {LINE_VOLTAGE_MAX_V}] V and \
                     (0, {FREQUENCY_MAX_HZ}] Hz"
                ));
            }
            (e.v_peak_v, e.f_hz) = (v * std::f64::consts::SQRT_2 / 3f64.sqrt(), f);
        }
        (None, None) if motor == SEED000_MOTOR => {}
        _ => {
            return Err(format!(
                "the start-up runs the motor direct on line: give its supply, --line-voltage-v (rms, line) and \
                 --frequency-hz, for `{motor}` (seed 000's 2 300 V, 60 Hz are its Krause motor's)"
            ));
        }
    }
    let trace = simulate(&m, &e)?;
    let segs = fit_segments(&m, &trace, &e)?;
    let plant = interval_plant(&segs);
    let ok = segs.iter().all(|s| s.replay_rel_rms < REPLAY_ERROR_MAX);
    if let Some(path) = plant_out.as_ref().filter(|_| ok) {
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
    if !ok {
        let missed: Vec<String> = segs
            .iter()
            .filter(|s| s.replay_rel_rms >= REPLAY_ERROR_MAX)
            .map(|s| format!("{:.3}–{:.3} s ({:.1} %)", s.t_s.0, s.t_s.1, 100.0 * s.replay_rel_rms))
            .collect();
        eprintln!(
            "design: {} of {} fitted models replay their segment's i_sα worse than {} % RMS: {}{}",
            missed.len(),
            segs.len(),
            100.0 * REPLAY_ERROR_MAX,
            missed.join(", "),
            if plant_out.is_some() { "; the interval plant is not written" } else { "" }
        );
    }
    Ok(ok)
}
