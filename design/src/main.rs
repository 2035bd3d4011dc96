//! `design` command line.
//!
//! ```text
//! design kharitonov --plant <plant.toml> --pi KP,KI [--json]
//! ```
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

fn kharitonov(args: &[String]) -> Result<bool, String> {
    let (mut plant, mut pi, mut json) = (None, None, false);
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--plant" => plant = Some(it.next().ok_or("--plant needs a file")?.clone()),
            "--pi" => pi = Some(parse_pi(it.next().ok_or("--pi needs KP,KI")?)?),
            "--json" => json = true,
            other => return Err(format!("unknown argument `{other}`")),
        }
    }
    let plant = load_plant(&plant.ok_or("--plant <file> is required")?)?;
    let (kp, ki) = pi.ok_or("--pi KP,KI is required")?;
    let r = plant.check_pi(kp, ki);
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
