//! `design kharitonov`: robust stability, gain–phase margin and bandwidth of a PI on an
//! interval plant (seed 000 Secs. 3–5), with the k_p–k_i plane plots.

use design::kharitonov::{IntervalPlant, IntervalPoly};
use design::pi_region::{
    Tester, bandwidth_boundary, bandwidth_ellipse, linspace, meets_bandwidth, robust_performance,
    stability_locus, tester_is_stable, tester_locus,
};
use design::poly::Poly;
use design::tf::{Tf, logspace};
use hil_sim::plot::{Series, plot_in};
use serde::Deserialize;
use std::path::Path;

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

fn two_numbers(flag: &str, s: &str) -> Result<(f64, f64), String> {
    let mut it = s.split(',').map(str::trim).map(str::parse::<f64>);
    match (it.next(), it.next(), it.next()) {
        (Some(Ok(a)), Some(Ok(b)), None) if a.is_finite() && b.is_finite() => Ok((a, b)),
        _ => Err(format!("{flag} expects two numbers A,B, got `{s}`")),
    }
}

/// `KP,KI`.
pub fn parse_pi(s: &str) -> Result<(f64, f64), String> {
    two_numbers("--pi", s).map_err(|_| format!("--pi expects KP,KI (two numbers), got `{s}`"))
}

fn parse_range(flag: &str, s: &str) -> Result<(f64, f64), String> {
    two_numbers(flag, s)
        .ok()
        .filter(|(a, b)| a < b)
        .ok_or_else(|| format!("{flag} expects LO,HI with LO < HI, got `{s}`"))
}

/// What to draw besides the plane.
enum Region {
    Stability,
    Gpm(Tester),
    Bandwidth(f64),
}

fn plot_region(
    path: &Path,
    plant: &IntervalPlant,
    (kp, ki): (f64, f64),
    (kp_range, ki_range): ((f64, f64), (f64, f64)),
    region: &Region,
) -> Result<(), String> {
    let omegas = logspace(1e-3, 1e6, 4000);
    let plants = plant.kharitonov_plants();
    let mut curves: Vec<Series<'_>> = Vec::new();
    let (title, boundary_label, member_label) = match region {
        Region::Stability => (
            "Robust PI stability region (k_i vs k_p), 16 Kharitonov plants",
            "stability boundary loci (derived), 16 plants",
            "robustly stable (Routh, 16 plants)",
        ),
        Region::Gpm(_) => (
            "Gain-phase margin region, tester A·exp(-jφ) (k_i vs k_p)",
            "tester boundary loci (derived), 16 plants",
            "stable with the tester, 16 plants",
        ),
        Region::Bandwidth(_) => (
            "Bandwidth region |T(jω_B)| ≥ 1/√2 (k_i vs k_p)",
            "exact boundaries |T(jω_B)| = 1/√2, 16 plants",
            "meets ω_B, 16 plants",
        ),
    };
    for (n, (_, _, num, den)) in plants.iter().enumerate() {
        let g = Tf { num: num.clone(), den: den.clone() };
        let pts: Vec<(f64, f64)> = match region {
            Region::Stability => stability_locus(&g, &omegas).iter().map(|p| (p.kp, p.ki)).collect(),
            Region::Gpm(t) => tester_locus(&g, *t, &omegas).iter().map(|p| (p.kp, p.ki)).collect(),
            Region::Bandwidth(wb) => bandwidth_boundary(&g, *wb, 400),
        };
        curves.push(Series::line(if n == 0 { boundary_label } else { "" }, pts).colored("#1f77b4"));
        if let (Region::Bandwidth(wb), 0) = (region, n) {
            // The printed (22) ellipse |L(jω_B)| = √2 + 1 (sufficient once its inequality is reversed).
            curves.push(
                Series::line(
                    "eq. (22): |L(jω_B)| = √2+1, plant 1",
                    bandwidth_ellipse(&g, *wb, 2f64.sqrt() + 1.0, 400),
                )
                .colored("#ff7f0e"),
            );
        }
    }
    let member = |n: &Poly, d: &Poly, kp: f64, ki: f64| match region {
        Region::Stability => design::pi_region::is_stabilising(n, d, kp, ki),
        Region::Gpm(t) => tester_is_stable(n, d, kp, ki, *t),
        Region::Bandwidth(wb) => meets_bandwidth(n, d, kp, ki, *wb),
    };
    let (kps, kis) = (linspace(kp_range.0, kp_range.1, 120), linspace(ki_range.0, ki_range.1, 120));
    let mut inside = Vec::new();
    for &kp_g in &kps {
        for &ki_g in &kis {
            if plants.iter().all(|(_, _, n, d)| member(n, d, kp_g, ki_g)) {
                inside.push((kp_g, ki_g));
            }
        }
    }
    let mut series = vec![Series::dots(member_label, inside).colored("#9be39b")];
    series.extend(curves);
    series.push(Series::line("k_i = 0", vec![(kp_range.0, 0.0), (kp_range.1, 0.0)]).colored("#444444"));
    series.push(Series::markers("PI", vec![(kp, ki)]).colored("#d62728"));
    super::write_atomic(path, &plot_in(title, "k_p", &series, (kp_range, ki_range)))
}

/// Parse and run; `Ok(true)` when every requested property holds robustly.
pub fn run(args: &[String]) -> Result<bool, String> {
    let (mut plant, mut pi, mut json, mut plot, mut plot_dir) = (None, None, false, None, None);
    let (mut kp_range, mut ki_range, mut gpm, mut bandwidth) = (None, None, None, None);
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--plant" => plant = Some(it.next().ok_or("--plant needs a file")?.clone()),
            "--pi" => pi = Some(parse_pi(it.next().ok_or("--pi needs KP,KI")?)?),
            "--json" => json = true,
            "--plot" => plot = Some(it.next().ok_or("--plot needs a file")?.clone()),
            "--plot-dir" => plot_dir = Some(it.next().ok_or("--plot-dir needs a directory")?.clone()),
            "--kp-range" => kp_range = Some(parse_range(a, it.next().ok_or("--kp-range needs LO,HI")?)?),
            "--ki-range" => ki_range = Some(parse_range(a, it.next().ok_or("--ki-range needs LO,HI")?)?),
            "--gpm" => {
                let (g, phi) = two_numbers(a, it.next().ok_or("--gpm needs A,PHI_DEG")?)?;
                if g <= 0.0 {
                    return Err(format!("--gpm: the gain A must be positive, got {g}"));
                }
                gpm = Some(Tester { gain: g, phase_rad: phi.to_radians() });
            }
            "--bandwidth" => {
                let v = it.next().ok_or("--bandwidth needs ω_B in rad/s")?;
                bandwidth = Some(
                    v.parse::<f64>()
                        .ok()
                        .filter(|x| x.is_finite() && *x > 0.0)
                        .ok_or(format!("--bandwidth: `{v}` is not a positive number"))?,
                );
            }
            other => return Err(format!("unknown argument `{other}`")),
        }
    }
    let plant = load_plant(&plant.ok_or("--plant <file> is required")?)?;
    let (kp, ki) = pi.ok_or("--pi KP,KI is required")?;
    let r = plant.check_pi(kp, ki);
    let around = |x: f64| (-0.5 * x.abs() - 1.0, 3.0 * x.abs() + 1.0);
    let window = (kp_range.unwrap_or(around(kp)), ki_range.unwrap_or(around(ki)));
    if let Some(path) = &plot {
        plot_region(Path::new(path), &plant, (kp, ki), window, &Region::Stability)?;
        eprintln!("design: wrote {path}");
    }
    if let Some(dir) = &plot_dir {
        let dir = Path::new(dir);
        std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
        plot_region(&dir.join("stability.svg"), &plant, (kp, ki), window, &Region::Stability)?;
        if let Some(t) = gpm {
            plot_region(&dir.join("gpm.svg"), &plant, (kp, ki), window, &Region::Gpm(t))?;
        }
        if let Some(wb) = bandwidth {
            plot_region(&dir.join("bandwidth.svg"), &plant, (kp, ki), window, &Region::Bandwidth(wb))?;
        }
        eprintln!("design: wrote the region plots to {}", dir.display());
    }
    // Loop margins per Kharitonov plant (dense log grid, crossings interpolated).
    let w = logspace(1e-3, 1e10, 26_000);
    let margins: Vec<design::margins::Margins> = plant
        .kharitonov_plants()
        .iter()
        .map(|(_, _, n, d)| {
            let g = Tf { num: n.clone(), den: d.clone() };
            let l: Vec<_> =
                w.iter().map(|&x| num_complex::Complex64::new(kp, -ki / x) * g.response(x)).collect();
            design::margins::margins(&w, &l)
        })
        .collect();
    let perf = |t: Tester, wb: f64| robust_performance(&plant, kp, ki, t, wb);
    let gpm_r = gpm.map(|t| perf(t, bandwidth.unwrap_or(1.0)));
    let bw_r = bandwidth.map(|wb| perf(gpm.unwrap_or(Tester { gain: 1.0, phase_rad: 0.0 }), wb));
    let ok = r.robust_stable
        && gpm_r.as_ref().is_none_or(|g| g.gpm_member)
        && bw_r.as_ref().is_none_or(|b| b.bandwidth_member);
    if json {
        let per: Vec<_> = r
            .per_plant
            .iter()
            .zip(&margins)
            .map(|((i, j, re), m)| {
                serde_json::json!({
                    "numerator": i, "denominator": j, "max_pole_re": re,
                    "crossover_rad_s": m.crossover_rad_s, "phase_margin_deg": m.phase_margin_deg,
                    "gain_margin_increase_db": m.gain_margin_increase_db,
                    "gain_margin_reduction_db": m.gain_margin_reduction_db,
                    "bandwidth_rad_s": m.bandwidth_rad_s,
                })
            })
            .collect();
        let mut v = serde_json::json!({
            "kp": kp, "ki": ki,
            "robust_stable": r.robust_stable,
            "worst_pole_re": r.worst_pole_re,
            "plants": per,
        });
        if let (Some(t), Some(g)) = (gpm, &gpm_r) {
            let gpm_v = serde_json::json!({
                "gain": t.gain, "phase_deg": t.phase_rad.to_degrees(),
                "robust_member": g.gpm_member, "failing_plants": g.gpm_failing,
            });
            if let Some(o) = v.as_object_mut() {
                o.insert("gpm".into(), gpm_v);
            }
        }
        if let (Some(wb), Some(b)) = (bandwidth, &bw_r) {
            let bw_v = serde_json::json!({
                "omega_b_rad_s": wb, "robust_member": b.bandwidth_member,
                "min_closed_loop_gain_at_omega_b": b.min_closed_loop_gain_at_omega_b,
            });
            if let Some(o) = v.as_object_mut() {
                o.insert("bandwidth".into(), bw_v);
            }
        }
        println!("{}", serde_json::to_string_pretty(&v).map_err(|e| e.to_string())?);
    } else {
        println!("PI ({kp}·s + {ki})/s on the 16 Kharitonov plants");
        let opt = |x: Option<f64>| x.map_or_else(|| "none".to_string(), |v| format!("{v:.2}"));
        for ((i, j, re), m) in r.per_plant.iter().zip(&margins) {
            println!(
                "  N{i}/D{j}: max Re(pole) = {re:.6}  crossover {} rad/s  PM {}°  GM +{} / −{} dB",
                opt(m.crossover_rad_s),
                opt(m.phase_margin_deg),
                opt(m.gain_margin_increase_db),
                opt(m.gain_margin_reduction_db)
            );
        }
        println!("robust_stable = {}, worst_pole_re = {:.6}", r.robust_stable, r.worst_pole_re);
        if let (Some(t), Some(g)) = (gpm, &gpm_r) {
            println!(
                "gain-phase tester A = {}, φ = {:.1}°: robust member = {} (failing plants {:?})",
                t.gain,
                t.phase_rad.to_degrees(),
                g.gpm_member,
                g.gpm_failing
            );
        }
        if let (Some(wb), Some(b)) = (bandwidth, &bw_r) {
            println!(
                "bandwidth ω_B = {wb} rad/s: robust member = {} (min |T(jω_B)| = {:.4}, need ≥ 0.7071)",
                b.bandwidth_member, b.min_closed_loop_gain_at_omega_b
            );
        }
    }
    Ok(ok)
}
