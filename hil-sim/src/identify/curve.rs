//! The estimates redone on the measured magnetizing curve (`--curve`; issue 50,
//! deliverable 4: "T_r and R_r at rated flux"), in the Γ model: the saturating branch at
//! the terminals (its flux the stator flux, which the no-load test measures without any
//! leakage estimate), the leakage L_σ and R_R on the rotor side — motulator's form.
//!
//! On a motor that saturates, the standstill estimates rest on a linear rotor branch the
//! motor does not have: a DC step's decay is not one exponential, so its fitted amplitude and
//! time constant are neither R_R nor the rated flux's T_r (motulator's 2.2 kW machine at a
//! 7 A test current without `--curve`: T_r 0.062 s and R_R 1.72 Ω in the inverse-Γ terms
//! against 0.107 s and 2.09 Ω at rated flux), and the injections' rotor branch, its
//! inductance the DC levels', misplaces the leakage. With the curve ψ_s(i_m) the host
//! redoes them:
//! - **L_σ from each injection**: around its bias (the last level's current, I/2) the
//!   machine is linear, its branch the curve's *incremental* inductance `L_inc = 1/f'(ψ_b)`;
//!   the impedance less R_s is `jωL_inc ∥ (R_R + jωL_σ)`, so `R_R + jωL_σ = 1/(1/(Z − R_s) −
//!   1/(jωL_inc))` and L_σ its imaginary part over ω (its real part rests on R_s's error; R_R
//!   comes from the decays).
//! - **R_R from each DC step, through the curve.** While the loop holds the current at I the
//!   rotor flux obeys `dψ_r/dt = R_R·(I − f(ψ_s))`, ψ_s given by `ψ_s + L_σ·f(ψ_s) = ψ_r +
//!   L_σ·I`: autonomous, so its solution for any R_R is the one for R_R = 1 on the time scale
//!   R_R·t, `ψ_r(t) = Ψ(R_R·t)`, Ψ integrated once (RK4) from the previous level's settled
//!   flux. The voltage above its settled value is dψ_s/dt, so a block's mean is the change of
//!   ψ_s over it over its length (t from the current's mean lag, as in the linear fit); R_R
//!   by least squares (the settled value by linear least squares for each R_R; R_R on a
//!   logarithmic grid, then golden section). Only steps whose currents lie on the measured
//!   curve (up to its top point's current) count: beyond it the curve is only extrapolated.
//! - **At rated flux**: L_s the chord ψ_s/i_m there, `T_r = (L_s + L_σ)/R_R`, and the
//!   inverse-Γ equivalent the reports and the design toolkit read (`γ = L_s/(L_s + L_σ)`:
//!   L_M = γ·L_s, σL_s = γ·L_σ, R_R = γ²·R_R(Γ)).
//! - **J and B** with the rotating field's torque through the Γ model on the curve.
//!
//! The no-load test cannot tell the Γ model from the inverse-Γ one (both give the same
//! terminal curve at no load); the standstill dynamics can, and the two forms are different
//! machines once saturated. The shipped saturating motors are Γ machines (motulator's form);
//! an inverse-Γ machine is identified here as the Γ machine nearest to it.

use super::estimation::{
    Branch, GammaRotor, Terminals, minimize_on_log_scale, no_load, rotation, skip_periods,
};
use super::{Estimate, GammaFit, Identified, MARGIN};
use controller_core::commission::{BLOCKS, CommissionConfig, Record};
use controller_core::magnetics::MagnetizingCurve;

/// The measured curve as the branch's curve (ψ_R against i_M); `None` below two points.
pub fn measured_curve(id: &Identified) -> Option<MagnetizingCurve> {
    let points = &id.no_load.as_ref()?.curve;
    let flux: Vec<f64> = points.iter().map(|p| p.flux_wb.value).collect();
    let current: Vec<f64> = points.iter().map(|p| p.current_a.value).collect();
    MagnetizingCurve::points(&flux, &current).ok()
}

/// `id` (the linear estimates, the no-load test's curve in it) redone on the curve (module
/// docs); `id` as it is if the no-load test measured no curve.
pub(super) fn refine(
    cfg: &CommissionConfig,
    rec: &Record,
    pole_pairs: u8,
    mut id: Identified,
) -> Result<Identified, String> {
    let (Some(mut curve), Some(standstill)) =
        (measured_curve(&id), id.no_load.as_ref().map(|n| n.standstill_l_mm_h))
    else {
        return Ok(id);
    };
    let rs = id.rs_ohm.value;
    let terminals = Terminals { rs, l_sigma: id.l_sigma_h.value };
    let mut fit = fit_rotor(cfg, rec, &id, &curve)?;
    // The curve's points again with the rotor's current taken out (the friction's slip), and
    // the rotor on that curve: twice (the second pass moves R_R by < 0.1 %).
    for _ in 0..2 {
        let rotor = GammaRotor { r_r_ohm: fit.1.value, l_sigma_h: fit.0.value };
        id.no_load = Some(no_load(cfg, rec, pole_pairs, terminals, standstill, Some(rotor))?);
        curve = measured_curve(&id).ok_or("the measured curve does not rise")?;
        fit = fit_rotor(cfg, rec, &id, &curve)?;
    }
    let (l_sigma, r_r) = fit;
    let l_s = id.no_load.as_ref().map(|n| n.l_s_h).ok_or("no no-load test")?;

    let tr = |l: f64, s: f64, r: f64| (l + s) / r;
    let tr_s = Estimate::derived(
        tr(l_s.value, l_sigma.value, r_r.value),
        tr(l_s.interval[0], l_sigma.interval[0], r_r.interval[1]),
        tr(l_s.interval[1], l_sigma.interval[1], r_r.interval[0]),
    );
    // The inverse-Γ equivalent at rated flux.
    let gamma = |l: f64, s: f64| l / (l + s);
    let g = gamma(l_s.value, l_sigma.value);
    let (g_lo, g_hi) =
        (gamma(l_s.interval[0], l_sigma.interval[1]), gamma(l_s.interval[1], l_sigma.interval[0]));
    id.l_mm_h = Estimate::derived(g * l_s.value, g_lo * l_s.interval[0], g_hi * l_s.interval[1]);
    id.l_sigma_h =
        Estimate::derived(g * l_sigma.value, g_lo * l_sigma.interval[0], g_hi * l_sigma.interval[1]);
    id.r_rr_ohm =
        Estimate::derived(g * g * r_r.value, g_lo * g_lo * r_r.interval[0], g_hi * g_hi * r_r.interval[1]);
    id.tr_s = tr_s;
    let branch = Branch::Gamma { curve: &curve, l_sigma_h: l_sigma.value };
    id.rotation = Some(rotation(cfg, rec, pole_pairs, branch, r_r.value)?);
    id.gamma = Some(GammaFit { l_s_h: l_s, l_sigma_h: l_sigma, r_r_ohm: r_r, tr_s });
    Ok(id)
}

/// The Γ rotor on `curve`: (L_σ, R_R), L_σ from the injections, R_R from the DC steps on the
/// curve (module docs).
fn fit_rotor(
    cfg: &CommissionConfig,
    rec: &Record,
    id: &Identified,
    curve: &MagnetizingCurve,
) -> Result<(Estimate, Estimate), String> {
    let top = id.no_load.as_ref().and_then(|n| n.curve.last()).map_or(0.0, |p| p.current_a.value);
    let rs = id.rs_ohm.value;
    // L_σ from each injection, the branch its incremental inductance at the bias.
    let [_, _, bias] = id.decays;
    let l_inc = incremental_inductance_h(id, bias.i_a).ok_or("the measured curve has no points")?;
    let l_sigma: Vec<f64> = id
        .impedance
        .iter()
        .map(|&(w, zr, zi)| {
            let j = num_complex::Complex64::i();
            let y = 1.0 / num_complex::Complex64::new(zr - rs, zi) - 1.0 / (j * w * l_inc);
            (1.0 / y).im / w
        })
        .collect();
    if l_sigma.iter().any(|x| !(x.is_finite() && *x > 0.0)) {
        return Err(format!(
            "on the measured curve the injections give no positive rotor leakage ({l_sigma:?} H)"
        ));
    }
    let l_sigma = Estimate::of(&l_sigma, MARGIN.l_sigma);
    let r_r: Vec<f64> =
        (0..3).filter_map(|level| step_r_r(cfg, rec, id, level, curve, l_sigma.value, top)).collect();
    if r_r.is_empty() {
        return Err(format!(
            "no DC step lies on the measured curve (its top point is at {top:.4} A): lower --test-current to \
             at most that, or run without --curve"
        ));
    }
    Ok((l_sigma, Estimate::of(&r_r, MARGIN.rr)))
}

/// The measured curve's incremental inductance dψ_s/di_m at current `i_a`, H: between the
/// derivatives at the points either side, each the harmonic mean of its two segments'
/// slopes (Fritsch and Carlson's monotone cubic, "Monotone piecewise cubic interpolation",
/// SIAM J. Numer. Anal. 1980) — a segment's own slope is the chord's over a span where the
/// curve bends most, which put L_σ 4.8 % high on the shipped saturating motor.
fn incremental_inductance_h(id: &Identified, i_a: f64) -> Option<f64> {
    let points = &id.no_load.as_ref()?.curve;
    let knots: Vec<(f64, f64)> = std::iter::once((0.0, 0.0))
        .chain(points.iter().map(|p| (p.current_a.value, p.flux_wb.value)))
        .collect();
    let slopes: Vec<f64> = knots.windows(2).map(|w| (w[1].1 - w[0].1) / (w[1].0 - w[0].0)).collect();
    let at_knot = |k: usize| -> f64 {
        match (k.checked_sub(1).and_then(|j| slopes.get(j)), slopes.get(k)) {
            (Some(a), Some(b)) if a * b > 0.0 => 2.0 / (1.0 / a + 1.0 / b),
            (Some(_), Some(_)) => 0.0,
            (Some(a), None) => *a,
            (None, Some(b)) => *b,
            (None, None) => f64::NAN,
        }
    };
    let k = knots.iter().rposition(|(i, _)| *i <= i_a)?.min(knots.len().checked_sub(2)?);
    let ((i0, _), (i1, _)) = (*knots.get(k)?, *knots.get(k + 1)?);
    let t = ((i_a - i0) / (i1 - i0)).clamp(0.0, 1.0);
    let l = (1.0 - t) * at_knot(k) + t * at_knot(k + 1);
    (l.is_finite() && l > 0.0).then_some(l)
}

/// R_R (Γ) from DC step `level` through `curve` with rotor leakage `l_sigma_h` (module
/// docs); `None` if its currents leave the curve (above `top_a`) or the fit finds nothing.
fn step_r_r(
    cfg: &CommissionConfig,
    rec: &Record,
    id: &Identified,
    level: usize,
    curve: &MagnetizingCurve,
    l_sigma_h: f64,
    top_a: f64,
) -> Option<f64> {
    let lv = rec.levels.get(level)?;
    let fit = id.decays.get(level)?;
    let before = level.checked_sub(1).and_then(|k| id.decays.get(k)).map_or(0.0, |d| d.i_a);
    let ref_before =
        level.checked_sub(1).and_then(|k| rec.levels.get(k)).map_or(0.0, |l| f64::from(l.i_ref_a));
    let (i_now, step) = (fit.i_a, fit.i_a - before);
    if before.max(i_now) > top_a * (1.0 + MARGIN.lm) || step.abs() <= 0.0 || before < 0.0 || i_now <= 0.0 {
        return None;
    }
    let step_ref = f64::from(lv.i_ref_a) - ref_before;
    let k0 = if step_ref.abs() > 0.0 { f64::from(lv.lag_a_periods) / step_ref } else { 0.0 } - 1.5;
    // Ψ(s) for R_R = 1: dψ_r/ds = I − f(ψ_s(ψ_r)), from the previous level's settled flux
    // (no rotor current: ψ_r = ψ_s); ψ_s tabulated along it.
    let l = l_sigma_h;
    let stator = |psi_r: f64| curve.flux_at_total_current((psi_r / l + i_now).max(0.0), 1.0 / l);
    let (psi0, psi_f) = (curve.flux_at_total_current(before, 0.0), curve.flux_at_total_current(i_now, 0.0));
    let span = (psi_f - psi0).abs();
    let h = l / 20.0;
    let rate = |psi_r: f64| i_now - curve.current_a(stator(psi_r));
    let mut psi_s = vec![stator(psi0)];
    let mut x = psi0;
    while (x - psi_f).abs() > 1e-9 * span && psi_s.len() < 2_000_000 {
        let k1 = rate(x);
        let k2 = rate(x + 0.5 * h * k1);
        let k3 = rate(x + 0.5 * h * k2);
        let k4 = rate(x + h * k3);
        x += h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
        psi_s.push(stator(x));
    }
    let settled = stator(psi_f);
    let at = |s: f64| -> f64 {
        let u = s.max(0.0) / h;
        let k = u.floor() as usize;
        match (psi_s.get(k), psi_s.get(k + 1)) {
            (Some(a), Some(b)) => a + (b - a) * (u - k as f64),
            _ => settled,
        }
    };
    let ts = f64::from(cfg.ts_s());
    let ends: Vec<f64> = cfg.block_end().iter().map(|&e| f64::from(e)).collect();
    let starts: Vec<f64> = std::iter::once(0.0).chain(ends.iter().copied()).take(BLOCKS).collect();
    let keep: Vec<(f64, f64, f64)> = starts
        .iter()
        .zip(&ends)
        .zip(&lv.v_alpha_v)
        .filter(|((a, _), _)| **a >= skip_periods())
        .map(|((a, e), v)| (*a, *e, f64::from(*v)))
        .collect();
    let ssr = |r: f64| {
        let g: Vec<f64> = keep
            .iter()
            .map(|(a, e, _)| {
                let (ta, te) = (((a - k0) * ts).max(0.0), ((e - k0) * ts).max(0.0));
                (at(r * te) - at(r * ta)) / ((e - a) * ts)
            })
            .collect();
        let wsum: f64 = keep.iter().map(|(a, e, _)| e - a).sum();
        let c = keep.iter().zip(&g).map(|((a, e, v), g)| (e - a) * (v - g)).sum::<f64>() / wsum;
        keep.iter().zip(&g).map(|((a, e, v), g)| (e - a) * (v - c - g).powi(2)).sum::<f64>()
    };
    // A logarithmic grid over 1/5…5× the linear fit's R_R, then golden section.
    let linear = fit.a_v / step;
    if !(linear.is_finite() && linear > 0.0) {
        return None;
    }
    let r = minimize_on_log_scale(ssr, [linear / 5.0, linear * 5.0], 100, 60);
    r.is_finite().then_some(r)
}
