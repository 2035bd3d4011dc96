//! `design recycle`: seed 001's study (report as text or JSON, step-response and region
//! plots like the paper's Figs. 2–5).

use design::recycle::{Constraints, Pi, RecycleProcess, Report, constraint_values, report};
use report::plot::{Series, line_plot, plot_in};
use std::path::Path;

/// Seed 001's recycle-process study: ITAE nominal PI, where it loses stability, Table I
/// checked every way, and the NLP (18) solved under the printed constraints, lemma 2.2,
/// Kharitonov and the exact family. Exit 0 when every optimum but the printed one is
/// verified robust.
#[derive(clap::Args, Debug)]
pub struct RecycleArgs {
    /// Print JSON.
    #[arg(long)]
    json: bool,
    /// Required decay rate: roots left of −RATE (Kharitonov and exact-family optima), 1/s.
    #[arg(long, allow_hyphen_values = true, value_name = "RATE", default_value_t = 0.01, value_parser = non_negative)]
    decay: f64,
    /// Write the step responses of Figs. 2–5 and the k₁–k₂ region plot here.
    #[arg(long)]
    plot_dir: Option<String>,
}

fn non_negative(s: &str) -> Result<f64, String> {
    s.parse::<f64>()
        .ok()
        .filter(|x| x.is_finite() && *x >= 0.0)
        .ok_or(format!("`{s}` is not a non-negative number"))
}

/// Run; `Ok(true)` when every reported optimum except the printed one is verified robust
/// (the printed one is reported, not required).
pub fn run(a: &RecycleArgs) -> Result<bool, String> {
    let (json, decay, plot_dir) = (a.json, a.decay, a.plot_dir.clone());
    let p = RecycleProcess::seed001();
    let r = report(&p, decay)?;
    if let Some(dir) = plot_dir {
        plots(Path::new(&dir), &p, &r)?;
        eprintln!("design: wrote the recycle plots to {dir}");
    }
    if json {
        report::outln!("{}", serde_json::to_string_pretty(&r).map_err(|e| e.to_string())?);
    } else {
        print_text(&r);
    }
    Ok(r.optima
        .iter()
        .filter(|o| o.constraints != Constraints::PaperPrinted)
        .all(|o| o.verdict.family_stable))
}

fn yes(b: bool) -> &'static str {
    if b { "yes" } else { "NO" }
}

fn print_text(r: &Report) {
    report::outln!("Recycle process (seed 001): k ∈ [1, 3], τ = 1, k_R = 1.6, τ_R = 1");
    report::outln!("ITAE nominal PI: k1 = {:.4}, k2 = {:.4}; unit-1 poles:", r.itae.k1, r.itae.k2);
    for [re, im] in &r.itae_unit1_poles {
        report::outln!("  {re:.4} {im:+.4}j");
    }
    report::outln!("unit 1 alone stable for all k: {}", yes(r.itae_unit1_robust));
    match r.itae_recycle_loss_of_stability_k {
        Some(k) => report::outln!("with the recycle the ITAE PI loses stability at k = {k:.4}"),
        None => report::outln!("with the recycle the ITAE PI stays stable over the range"),
    }
    report::outln!(
        "\nTable I   k1      k2      cost    printed(16)  L2.1 L2.2 Kharitonov family  worst Re (at k)"
    );
    for row in &r.table_i {
        let v = &row.verdict;
        report::outln!(
            "set {}   {:.4}  {:.4}  {:.4}  {:<11}  {:<4} {:<4} {:<10} {:<6}  {:.4} ({:.3})",
            row.set,
            row.pi.k1,
            row.pi.k2,
            v.cost,
            if v.printed_interval_valid { "valid" } else { "inside out" },
            yes(v.lemma_21),
            yes(v.lemma_22),
            yes(v.kharitonov),
            yes(v.family_stable),
            v.worst_pole_re,
            v.worst_at_k
        );
    }
    report::outln!(
        "\nNLP (18) optima (decay margin {} 1/s for the Kharitonov and family sets)",
        r.decay_1_per_s
    );
    for o in &r.optima {
        report::outln!(
            "{:<14} k1 = {:.4}, k2 = {:.4}, cost {:.4}; Kharitonov {}, family stable {}, worst Re {:.4} at k = {:.3}",
            format!("{:?}", o.constraints),
            o.pi.k1,
            o.pi.k2,
            o.cost,
            yes(o.verdict.kharitonov),
            yes(o.verdict.family_stable),
            o.verdict.worst_pole_re,
            o.verdict.worst_at_k
        );
    }
}

/// Labelled curves `(label, [(t, y)])`.
type Curves = Vec<(String, Vec<(f64, f64)>)>;

fn responses(p: &RecycleProcess, pi: &Pi, recycle: bool, ks: &[f64], t_end: f64) -> Result<Curves, String> {
    ks.iter()
        .map(|&k| Ok((format!("k = {k}"), p.load_response(k, pi, recycle).step_response(t_end, 800)?)))
        .collect()
}

fn plot_responses(path: &Path, title: &str, curves: &Curves) -> Result<(), String> {
    let series: Vec<Series<'_>> = curves.iter().map(|(l, pts)| Series::line(l, pts.clone())).collect();
    super::write_atomic(path, &line_plot(title, "t (s)", &series))
}

/// Figs. 2–5 and the k₁–k₂ plane with every constraint set's region.
fn plots(dir: &Path, p: &RecycleProcess, r: &Report) -> Result<(), String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let ks = [1.0, 2.0, 3.0];
    let itae = r.itae;
    plot_responses(
        &dir.join("fig2-unit1-itae.svg"),
        "Fig. 2: unit 1 alone, ITAE PI, unit load step: y",
        &responses(p, &itae, false, &ks, 20.0)?,
    )?;
    plot_responses(
        &dir.join("fig3-recycle-itae-nominal.svg"),
        "Fig. 3: with recycle, ITAE PI, k = 2: y",
        &responses(p, &itae, true, &[2.0], 40.0)?,
    )?;
    plot_responses(
        &dir.join("fig4-recycle-itae-k1-k3.svg"),
        "Fig. 4: with recycle, ITAE PI, k = 1 and 3 (unstable): y",
        &responses(p, &itae, true, &[1.0, 3.0], 40.0)?,
    )?;
    let (_, _, k1, k2) = design::recycle::TABLE_I[2];
    let set3 = Pi { k1, k2 };
    plot_responses(
        &dir.join("fig5-recycle-set3.svg"),
        "Fig. 5: with recycle, Table I set 3: y",
        &responses(p, &set3, true, &ks, 40.0)?,
    )?;
    if let Some(o) = r.optima.iter().find(|o| o.constraints == Constraints::Family) {
        plot_responses(
            &dir.join("recycle-family-optimum.svg"),
            "With recycle, nearest robust PI (exact family constraint): y",
            &responses(p, &o.pi, true, &ks, 60.0)?,
        )?;
    }
    region_plot(&dir.join("recycle-region.svg"), p, r)
}

fn region_plot(path: &Path, p: &RecycleProcess, r: &Report) -> Result<(), String> {
    let (k1r, k2r) = ((0.0, 3.5), (0.0, 1.6));
    let n = 140;
    let (mut family, mut kharitonov, mut lemmas, mut printed_unstable) = (vec![], vec![], vec![], vec![]);
    for i in 0..=n {
        for j in 0..=n {
            let pi = Pi {
                k1: k1r.0 + (k1r.1 - k1r.0) * f64::from(i) / f64::from(n),
                k2: k2r.0 + (k2r.1 - k2r.0) * f64::from(j) / f64::from(n),
            };
            let pt = (pi.k1, pi.k2);
            let fam = p.family_is_stable(&pi, 0.0);
            if constraint_values(p, Constraints::Lemmas, 0.0, &pi).iter().all(|&c| c > 0.0) {
                lemmas.push(pt);
            } else if p.interval(&pi, 0.0).is_robustly_hurwitz() {
                kharitonov.push(pt);
            } else if fam {
                family.push(pt);
            }
            if !fam && constraint_values(p, Constraints::PaperPrinted, 0.0, &pi).iter().all(|&c| c >= 0.0) {
                printed_unstable.push(pt);
            }
        }
    }
    let table: Vec<(f64, f64)> = r.table_i.iter().map(|t| (t.pi.k1, t.pi.k2)).collect();
    let mut series = vec![
        Series::dots("stable for every k ∈ [1, 3] (exact)", family).colored("#d8f0d0"),
        Series::dots("+ Kharitonov on the interval hull", kharitonov).colored("#9bd88b"),
        Series::dots("+ lemma 2.2 (sufficient)", lemmas).colored("#3c9a3c"),
        Series::dots("printed NLP constraints hold, loop unstable", printed_unstable).colored("#f4a0a0"),
        Series::markers("Table I sets", table).colored("#1f4fb4"),
        Series::markers("ITAE nominal", vec![(r.itae.k1, r.itae.k2)]).colored("#000000"),
    ];
    let colors = ["#d62728", "#ff7f0e", "#9467bd", "#8c564b"];
    let labels: Vec<String> = r.optima.iter().map(|o| format!("optimum: {:?}", o.constraints)).collect();
    for ((o, c), l) in r.optima.iter().zip(colors).zip(&labels) {
        series.push(Series::markers(l, vec![(o.pi.k1, o.pi.k2)]).colored(c));
    }
    super::write_atomic(
        path,
        &plot_in("Seed 001 recycle loop: robust PI regions (k2 vs k1)", "k1", &series, (k1r, k2r)),
    )
}
