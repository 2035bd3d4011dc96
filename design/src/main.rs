//! `design` command line.
//!
//! ```text
//! design kharitonov --plant <plant.toml> --pi KP,KI [--json]
//!                   [--plot FILE.svg [--kp-range LO,HI] [--ki-range LO,HI]]
//! ```
//! `--plot` draws the k_p–k_i plane like seed 000 Figs. 4–6: the stability boundary loci of
//! the 16 Kharitonov plants, the robust region sampled by exact Routh tests on a 120×120
//! grid (dots), and the PI point. Default ranges: −0.5…3 times the PI gains.
//! design icad --motor <motor.toml | builtin> --omega-r <rad/s> --controller <icad20 | pi:KP,KI> [--json]
//! ```
//! `icad` runs seed 002's individual channel analysis of the stator-current loops at one
//! electrical rotor speed (motors: `delorenzo-eq13`, `delorenzo-appendix`,
//! `delorenzo-perturbed`, `krause-2300v-500hp` or a motor file) and sweeps ω_r (0…5000 rad/s,
//! 5 rad/s steps) for the range where the full 2×2 loop stays stable. Exit 0 when the loop is
//! stable at the given ω_r, 1 when not, 2 on usage/input errors.
//!
//! design certify <gains.toml> [--json]
//! ```
//! `certify` checks every controller constant of a gains file against its declared
//! parameter intervals (see `design::certify`); exit 0 when all checks pass, 1 with the
//! failing checks listed, 2 on input errors.
//!
//! design recycle [--json] [--decay RATE] [--plot-dir DIR]
//! ```
//! `recycle` runs seed 001's study of the recycle process (`design::recycle`): ITAE
//! nominal PI, where it loses stability, Table I checked every way, and the NLP (18)
//! solved under the printed constraints, lemma 2.2, Kharitonov and the exact family
//! (the last two with roots left of −RATE, default 0.01 1/s). `--plot-dir` writes the
//! step responses of Figs. 2–5 and the k₁–k₂ region plot. Exit 0 when every optimum but
//! the printed one is verified robust.
//!
//! ```text
//! `kharitonov` checks a PI controller `(KP·s + KI)/s` on the 16 Kharitonov plants of an
//! interval plant file (`[numerator]`/`[denominator]` tables with `lo`/`hi` arrays of
//! descending coefficients). `--json` prints `robust_stable`, `worst_pole_re` and the
//! per-plant figures; otherwise a table. Exit status: 0 robustly stable, 1 not, 2 usage or
//! input error.

mod cli {
    pub mod recycle;
}

use design::kharitonov::{IntervalPlant, IntervalPoly};
use serde::Deserialize;
use std::process::ExitCode;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Bounds {
    lo: Vec<f64>,
    hi: Vec<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PlantFile {
    numerator: Bounds,
    denominator: Bounds,
}

fn load_plant(path: &str) -> Result<IntervalPlant, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{path}: cannot read: {e}"))?;
    let f: PlantFile = toml::from_str(&text).map_err(|e| format!("{path}: {e}"))?;
    let poly = |key: &str, b: &Bounds| {
        IntervalPoly::new(&b.lo, &b.hi)
            .map_err(|e| format!("{path}: key `{key}`: {e:?} (need equal lengths and finite lo ≤ hi)"))
    };
    Ok(IntervalPlant { num: poly("numerator", &f.numerator)?, den: poly("denominator", &f.denominator)? })
}

fn parse_pi(s: &str) -> Result<(f64, f64), String> {
    let mut it = s.split(',').map(str::trim).map(str::parse::<f64>);
    match (it.next(), it.next(), it.next()) {
        (Some(Ok(kp)), Some(Ok(ki)), None) if kp.is_finite() && ki.is_finite() => Ok((kp, ki)),
        _ => Err(format!("--pi expects KP,KI (two numbers), got `{s}`")),
    }
}

fn parse_range(flag: &str, s: &str) -> Result<(f64, f64), String> {
    parse_pi(s)
        .ok()
        .filter(|(a, b)| a < b)
        .ok_or_else(|| format!("{flag} expects LO,HI with LO < HI, got `{s}`"))
}

fn plot_region(
    path: &str,
    plant: &IntervalPlant,
    (kp, ki): (f64, f64),
    kp_range: (f64, f64),
    ki_range: (f64, f64),
) -> Result<(), String> {
    use design::pi_region::{linspace, robust_grid, stability_locus};
    use design::tf::{Tf, logspace};
    use hil_sim::plot::{Series, plot_in};
    let omegas = logspace(1e-3, 1e6, 4000);
    let mut series: Vec<Series<'_>> = Vec::new();
    for (n, (_, _, num, den)) in plant.kharitonov_plants().into_iter().enumerate() {
        let g = Tf { num, den };
        let pts = stability_locus(&g, &omegas).iter().map(|p| (p.kp, p.ki)).collect();
        let label = if n == 0 { "stability boundary loci, 16 plants" } else { "" };
        series.push(Series::line(label, pts).colored("#1f77b4"));
    }
    let (kps, kis) = (linspace(kp_range.0, kp_range.1, 120), linspace(ki_range.0, ki_range.1, 120));
    let grid = robust_grid(plant, &kps, &kis);
    let mut inside = Vec::new();
    for (&kp_g, row) in kps.iter().zip(&grid) {
        for (&ki_g, &ok) in kis.iter().zip(row) {
            if ok {
                inside.push((kp_g, ki_g));
            }
        }
    }
    series.push(Series::dots("robustly stable (Routh, 16 plants)", inside).colored("#9be39b"));
    series.push(Series::line("k_i = 0", vec![(kp_range.0, 0.0), (kp_range.1, 0.0)]).colored("#444444"));
    series.push(Series::markers("PI", vec![(kp, ki)]).colored("#d62728"));
    let svg = plot_in("Robust PI stability region (k_i vs k_p)", "k_p", &series, (kp_range, ki_range));
    let tmp = format!("{path}.partial");
    std::fs::write(&tmp, svg).and_then(|()| std::fs::rename(&tmp, path)).map_err(|e| format!("{path}: {e}"))
}

fn kharitonov(args: &[String]) -> Result<bool, String> {
    let (mut plant, mut pi, mut json, mut plot) = (None, None, false, None);
    let (mut kp_range, mut ki_range) = (None, None);
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--plant" => plant = Some(it.next().ok_or("--plant needs a file")?.clone()),
            "--pi" => pi = Some(parse_pi(it.next().ok_or("--pi needs KP,KI")?)?),
            "--json" => json = true,
            "--plot" => plot = Some(it.next().ok_or("--plot needs a file")?.clone()),
            "--kp-range" => kp_range = Some(parse_range(a, it.next().ok_or("--kp-range needs LO,HI")?)?),
            "--ki-range" => ki_range = Some(parse_range(a, it.next().ok_or("--ki-range needs LO,HI")?)?),
            other => return Err(format!("unknown argument `{other}`")),
        }
    }
    let plant = load_plant(&plant.ok_or("--plant <file> is required")?)?;
    let (kp, ki) = pi.ok_or("--pi KP,KI is required")?;
    let r = plant.check_pi(kp, ki);
    if let Some(path) = plot {
        let around = |x: f64| (-0.5 * x.abs() - 1.0, 3.0 * x.abs() + 1.0);
        plot_region(&path, &plant, (kp, ki), kp_range.unwrap_or(around(kp)), ki_range.unwrap_or(around(ki)))?;
        eprintln!("design: wrote {path}");
    }
    if json {
        let per: Vec<_> = r
            .per_plant
            .iter()
            .map(|(i, j, re)| serde_json::json!({"numerator": i, "denominator": j, "max_pole_re": re}))
            .collect();
        let v = serde_json::json!({
            "kp": kp, "ki": ki,
            "robust_stable": r.robust_stable,
            "worst_pole_re": r.worst_pole_re,
            "plants": per,
        });
        println!("{}", serde_json::to_string_pretty(&v).map_err(|e| e.to_string())?);
    } else {
        println!("PI ({kp}·s + {ki})/s on the 16 Kharitonov plants");
        for (i, j, re) in &r.per_plant {
            println!("  N{i}/D{j}: max Re(pole) = {re:.6}");
        }
        println!("robust_stable = {}, worst_pole_re = {:.6}", r.robust_stable, r.worst_pole_re);
    }
    Ok(r.robust_stable)
}

fn icad(args: &[String]) -> Result<bool, String> {
    use controller_core::current::CurrentLaw;
    let (mut motor, mut omega_r, mut law, mut json) = (None, None, None, false);
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--motor" => motor = Some(it.next().ok_or("--motor needs a file or builtin name")?.clone()),
            "--omega-r" => {
                let v = it.next().ok_or("--omega-r needs a value")?;
                omega_r = Some(
                    v.parse::<f64>()
                        .ok()
                        .filter(|x| x.is_finite())
                        .ok_or(format!("--omega-r: `{v}` is not a number"))?,
                );
            }
            "--controller" => {
                let c = it.next().ok_or("--controller needs icad20 or pi:KP,KI")?;
                law = Some(match c.as_str() {
                    "icad20" => CurrentLaw::ICAD_EQ20,
                    other => match other.strip_prefix("pi:") {
                        Some(g) => {
                            let (kp, ki) = parse_pi(g)?;
                            CurrentLaw { kp_v_per_a: kp, ki_v_per_as: ki, lag: None }
                        }
                        None => {
                            return Err(format!("--controller: `{other}` is neither icad20 nor pi:KP,KI"));
                        }
                    },
                });
            }
            "--json" => json = true,
            other => return Err(format!("unknown argument `{other}`")),
        }
    }
    let m = hil_sim::motors::load(&motor.ok_or("--motor is required")?).map_err(|e| e.to_string())?;
    let omega_r = omega_r.ok_or("--omega-r is required")?;
    let law = law.ok_or("--controller is required")?;
    let r = design::icad::analyse(&m, &law, omega_r);
    let stable_here = design::icad::closed_loop_abscissa(&m, &law, omega_r) < 0.0;
    let range = design::icad::stable_omega_r_max(&m, &law, 5.0, 5000.0);
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
    });
    if json {
        println!("{}", serde_json::to_string_pretty(&v).map_err(|e| e.to_string())?);
    } else if let Some(obj) = v.as_object() {
        for (k, val) in obj {
            println!("{k:<36} {val}");
        }
    }
    Ok(stable_here)
}

fn certify(args: &[String]) -> Result<bool, String> {
    let (mut path, mut json) = (None, false);
    for a in args {
        match a.as_str() {
            "--json" => json = true,
            p if path.is_none() && !p.starts_with("--") => path = Some(p.to_string()),
            other => return Err(format!("unknown argument `{other}`")),
        }
    }
    let path = path.ok_or("certify needs a gains file")?;
    let (spec, c) = design::certify::load(std::path::Path::new(&path))?;
    let checks = design::certify::certify(&spec, &c)?;
    let ok = checks.iter().all(|c| c.pass);
    if json {
        let v: Vec<_> = checks
            .iter()
            .map(|c| serde_json::json!({"check": c.name, "corner": c.corner, "value": c.value, "limit": c.limit, "pass": c.pass}))
            .collect();
        let out = serde_json::json!({"file": path, "certified": ok, "checks": v});
        println!("{}", serde_json::to_string_pretty(&out).map_err(|e| e.to_string())?);
    } else {
        for ch in &checks {
            let value = ch.value.map_or_else(|| "none".to_string(), |v| format!("{v:.3}"));
            println!(
                "{:<5} {:<56} {:<22} {:>10}  limit {}",
                if ch.pass { "ok" } else { "FAIL" },
                ch.name,
                ch.corner,
                value,
                ch.limit
            );
        }
        println!("{path}: {}", if ok { "certified" } else { "NOT certified" });
    }
    if !ok {
        for ch in checks.iter().filter(|c| !c.pass) {
            eprintln!(
                "design certify: {path}: {} at {} is {:?}, limit {}",
                ch.name, ch.corner, ch.value, ch.limit
            );
        }
    }
    Ok(ok)
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = match args.first().map(String::as_str) {
        Some("kharitonov") => kharitonov(args.get(1..).unwrap_or(&[])),
        Some("icad") => icad(args.get(1..).unwrap_or(&[])),
        Some("certify") => certify(args.get(1..).unwrap_or(&[])),
        Some("recycle") => cli::recycle::run(args.get(1..).unwrap_or(&[])),
        _ => Err("usage: design kharitonov --plant <plant.toml> --pi KP,KI [--json] [--plot FILE]\n       \
                  design icad --motor <toml|builtin> --omega-r <rad/s> --controller <icad20|pi:KP,KI> [--json]\n       \
                  design certify <gains.toml> [--json]\n       \
                  design recycle [--json] [--decay 1/s] [--plot-dir DIR]"
            .into()),
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
