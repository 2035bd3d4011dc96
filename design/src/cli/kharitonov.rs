//! `design kharitonov`: robust stability, gain–phase margin and bandwidth of a PI on an
//! interval plant (seed 000 Secs. 3–5), with the k_p–k_i plane plots.

use design::kharitonov::{IntervalPlant, IntervalPoly};
use design::pi_region::{
    Tester, bandwidth_boundary, bandwidth_ellipse, linspace, meets_bandwidth, robust_performance,
    stability_locus, tester_is_stable, tester_locus,
};
use design::poly::Poly;
use design::tf::{Tf, logspace};
use report::plot::{Series, plot_in};
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

/// Read an interval plant file. Besides the shape (equal lengths, finite `lo ≤ hi`), the
/// denominator's leading coefficient must keep one sign over its interval — a degree that
/// can drop is not a plant of that order (a denominator `[0, 0]` was once "robustly
/// stable") — and the plant must be proper.
fn load_plant(path: &str) -> Result<IntervalPlant, String> {
    let file = Path::new(path);
    let text = drive_file::source::read(file).map_err(|e| e.to_string())?;
    let src = drive_file::Source::parse(file, &text).map_err(|e| e.to_string())?;
    let f: PlantFile = src.deserialize().map_err(|e| e.to_string())?;
    let poly = |key: &str, b: &Bounds| {
        IntervalPoly::new(&b.lo, &b.hi).map_err(|e| {
            src.error(key, format!("{e:?}: need lo and hi of equal, non-zero length, finite, lo ≤ hi"))
                .to_string()
        })
    };
    let (num, den) = (poly("numerator", &f.numerator)?, poly("denominator", &f.denominator)?);
    let lead = |b: &Bounds| (b.lo.first().copied().unwrap_or(0.0), b.hi.first().copied().unwrap_or(0.0));
    let (dl, dh) = lead(&f.denominator);
    if !(dl > 0.0 || dh < 0.0) {
        return Err(src
            .error("denominator.lo", format!("the leading coefficient's interval [{dl}, {dh}] contains 0"))
            .to_string());
    }
    if f.numerator.lo.len() > f.denominator.lo.len() {
        return Err(src
            .error("numerator", "more coefficients than the denominator: not a proper plant")
            .to_string());
    }
    Ok(IntervalPlant { num, den })
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
    two_numbers("--pi", s).map_err(|_| format!("expects KP,KI (two numbers), got `{s}`"))
}

fn parse_range(s: &str) -> Result<(f64, f64), String> {
    two_numbers("range", s)
        .ok()
        .filter(|(a, b)| a < b)
        .ok_or_else(|| format!("expects LO,HI with LO < HI, got `{s}`"))
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

/// Robust stability of a PI `(KP·s + KI)/s` on the 16 Kharitonov plants of an interval plant
/// file; with `--gpm` the gain–phase-margin tester `A·e^{−jφ}`, with `--bandwidth` the
/// closed-loop `|T(jω_B)| ≥ 1/√2` condition (seed 000 Secs. 3–5). Exit 0 when every requested
/// property holds robustly, 1 when one does not.
#[derive(clap::Args, Debug)]
pub struct KharitonovArgs {
    /// Interval plant file: `[numerator]`/`[denominator]` tables with `lo`/`hi` arrays of
    /// descending coefficients (e.g. design/plants/seed000-current.toml).
    #[arg(long)]
    plant: String,
    /// The PI gains KP,KI.
    #[arg(long, allow_hyphen_values = true, value_name = "KP,KI", value_parser = parse_pi)]
    pi: (f64, f64),
    /// Gain–phase margin tester A,PHI_DEG (A > 0).
    #[arg(long, allow_hyphen_values = true, value_name = "A,PHI_DEG", value_parser = parse_gpm)]
    gpm: Option<(f64, f64)>,
    /// Closed-loop bandwidth requirement ω_B, rad/s.
    #[arg(long, value_name = "RAD_S", value_parser = positive)]
    bandwidth: Option<f64>,
    /// Print JSON.
    #[arg(long)]
    json: bool,
    /// Draw the stability plane (Figs. 4/8) to this SVG file.
    #[arg(long)]
    plot: Option<String>,
    /// Write stability.svg, and gpm.svg / bandwidth.svg when asked for (Figs. 5–6, 9–10).
    #[arg(long)]
    plot_dir: Option<String>,
    /// k_p window of the plots [default: −0.5…3 times the PI gain].
    #[arg(long, allow_hyphen_values = true, value_name = "LO,HI", value_parser = parse_range)]
    kp_range: Option<(f64, f64)>,
    /// k_i window of the plots [default: −0.5…3 times the PI gain].
    #[arg(long, allow_hyphen_values = true, value_name = "LO,HI", value_parser = parse_range)]
    ki_range: Option<(f64, f64)>,
}

fn parse_gpm(s: &str) -> Result<(f64, f64), String> {
    let (g, phi) = two_numbers("--gpm", s)?;
    if g > 0.0 { Ok((g, phi)) } else { Err(format!("the gain A must be positive, got {g}")) }
}

fn positive(s: &str) -> Result<f64, String> {
    s.parse::<f64>()
        .ok()
        .filter(|x| x.is_finite() && *x > 0.0)
        .ok_or(format!("`{s}` is not a positive number"))
}

/// Run; `Ok(true)` when every requested property holds robustly.
pub fn run(a: &KharitonovArgs) -> Result<bool, String> {
    let (json, plot, plot_dir, kp_range, ki_range, bandwidth) =
        (a.json, a.plot.clone(), a.plot_dir.clone(), a.kp_range, a.ki_range, a.bandwidth);
    let gpm = a.gpm.map(|(g, phi)| Tester { gain: g, phase_rad: phi.to_radians() });
    let plant = load_plant(&a.plant)?;
    let (kp, ki) = a.pi;
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
        report::outln!("{}", serde_json::to_string_pretty(&v).map_err(|e| e.to_string())?);
    } else {
        report::outln!("PI ({kp}·s + {ki})/s on the 16 Kharitonov plants");
        let opt = |x: Option<f64>| x.map_or_else(|| "none".to_string(), |v| format!("{v:.2}"));
        for ((i, j, re), m) in r.per_plant.iter().zip(&margins) {
            report::outln!(
                "  N{i}/D{j}: max Re(pole) = {re:.6}  crossover {} rad/s  PM {}°  GM +{} / −{} dB",
                opt(m.crossover_rad_s),
                opt(m.phase_margin_deg),
                opt(m.gain_margin_increase_db),
                opt(m.gain_margin_reduction_db)
            );
        }
        report::outln!("robust_stable = {}, worst_pole_re = {:.6}", r.robust_stable, r.worst_pole_re);
        if let (Some(t), Some(g)) = (gpm, &gpm_r) {
            report::outln!(
                "gain-phase tester A = {}, φ = {:.1}°: robust member = {} (failing plants {:?})",
                t.gain,
                t.phase_rad.to_degrees(),
                g.gpm_member,
                g.gpm_failing
            );
        }
        if let (Some(wb), Some(b)) = (bandwidth, &bw_r) {
            report::outln!(
                "bandwidth ω_B = {wb} rad/s: robust member = {} (min |T(jω_B)| = {:.4}, need ≥ 0.7071)",
                b.bandwidth_member,
                b.min_closed_loop_gain_at_omega_b
            );
        }
    }
    Ok(ok)
}
