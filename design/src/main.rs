//! `design` command line.
//!
//! ```text
//! design kharitonov --plant <plant.toml> --pi KP,KI [--json]
//!                   [--plot FILE.svg [--kp-range LO,HI] [--ki-range LO,HI]]
//! ```
//! `--plot` draws the k_p–k_i plane like seed 000 Figs. 4–6: the stability boundary loci of
//! the 16 Kharitonov plants, the robust region sampled by exact Routh tests on a 120×120
//! grid (dots), and the PI point. Default ranges: −0.5…3 times the PI gains.
//! `kharitonov` checks a PI controller `(KP·s + KI)/s` on the 16 Kharitonov plants of an
//! interval plant file (`[numerator]`/`[denominator]` tables with `lo`/`hi` arrays of
//! descending coefficients). `--json` prints `robust_stable`, `worst_pole_re` and the
//! per-plant figures; otherwise a table. Exit status: 0 robustly stable, 1 not, 2 usage or
//! input error.

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
    series.push(Series::dots("PI", vec![(kp, ki)]).colored("#d62728"));
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

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = match args.first().map(String::as_str) {
        Some("kharitonov") => kharitonov(args.get(1..).unwrap_or(&[])),
        _ => Err("usage: design kharitonov --plant <plant.toml> --pi KP,KI [--json]".into()),
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
