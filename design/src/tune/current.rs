//! The current loops' gains: seed 002 eq. (20)'s ICAD placed for the top speed, and the geometric searches for the fastest crossover the certificate passes.

use super::*;

/// ICAD lag: double zero at `−ω_h` (seed 002 eq. (20): −400 rad/s at ω_h = 400 rad/s).
pub const ICAD_LAG_ZERO: f64 = 1.0;
/// ICAD lag: poles at `ω_h·(−1/8 ± j/2)` (eq. (20): −50 ± j200 rad/s).
pub const ICAD_LAG_POLE: [f64; 2] = [-0.125, 0.5];
/// ICAD PI zero, the phase lead: `−2.5·ω_h` (eq. (20): −1 000 rad/s).
pub const ICAD_LEAD_ZERO: f64 = 2.5;
/// The ICAD gain search's coarse grid: each candidate k_p is this fraction of the last.
pub const ICAD_GRID_RATIO: f64 = 0.8;
/// Golden-section steps refining the best grid point (the bracket shrinks to 0.618^n).
pub const ICAD_REFINE_STEPS: usize = 12;

/// Seed 002 eq. (20)'s structure placed for a top electrical rotor speed `omega_h_rad_s`:
/// `(k_p + k_i/s)·(s + z·ω_h)²/(s² − 2a·ω_h s + (a² + b²)ω_h²)` with `z` =
/// [`ICAD_LAG_ZERO`], `(a, b)` = [`ICAD_LAG_POLE`], `k_i = `[`ICAD_LEAD_ZERO`]`·ω_h·k_p`.
///
/// The reasoning generalised from Sec. VI-D (Amézquita-Brooks et al.): h_i's resonance —
/// the rotor-speed dip that makes γh approach (1, 0) — sits at the rotor speed, worst at the
/// top speed; the lag pair raises the open-loop gain there (its resonance just below ω_h,
/// 8.2 dB at ω_h, 11.5 dB at DC) without a drastic loss of phase at crossover, and the PI
/// zero adds the lead that keeps the loop stable, all slower than the closed-loop bandwidth.
/// Scaled by ω_h every placement is the paper's at ω_h = 400 rad/s (the shipped drive's
/// `[certify] omega_r_max_rad_s`): `icad_law(326.5, 400.0)` is eq. (20) exactly.
pub fn icad_law(kp_v_per_a: f64, omega_h_rad_s: f64) -> CurrentLaw {
    let w = omega_h_rad_s;
    let [a, b] = ICAD_LAG_POLE;
    let z = ICAD_LAG_ZERO * w;
    CurrentLaw {
        kp_v_per_a,
        ki_v_per_as: ICAD_LEAD_ZERO * w * kp_v_per_a,
        lag: Some(ContinuousSection::biquad(
            [1.0, 2.0 * z, z * z],
            [1.0, -2.0 * a * w, (a * a + b * b) * w * w],
        )),
    }
}

/// The smallest ratio of a margin to its minimum over every margin check (phase, gain, γh;
/// continuous and sampled; every corner) — the distance to the certificate's boundary, in
/// units of the minima — and the check that sets it; −∞ when a stability check fails. A
/// margin that does not exist (no phase crossover for a gain margin) does not bind.
pub fn robustness(checks: &[Check]) -> (f64, Option<&Check>) {
    let mut worst = (f64::INFINITY, None);
    for c in checks {
        let r = if c.name.contains("margin") {
            match c.value {
                Some(v) if c.limit > 0.0 => v / c.limit,
                Some(v) => v - c.limit + 1.0,
                None if c.pass => continue,
                None => f64::NEG_INFINITY,
            }
        } else if c.pass {
            continue;
        } else {
            f64::NEG_INFINITY
        };
        if r < worst.0 {
            worst = (r, Some(c));
        }
    }
    worst
}

/// Each candidate crossover is this fraction of the last.
pub const SEARCH_RATIO: f64 = 0.9;
/// The searches first try every this many candidates (`search_down`).
pub const SEARCH_STRIDE: usize = 4;

/// The candidates of a geometric search: `top`, then each [`SEARCH_RATIO`] of the last
/// (by repeated multiplication: the values the written gains come from), while at least
/// `bottom`.
pub(super) fn candidates(top: f64, bottom: f64) -> impl Iterator<Item = f64> {
    std::iter::successors(Some(top), |w| Some(w * SEARCH_RATIO)).take_while(move |&w| w >= bottom)
}

/// The first of `grid` (largest first) that `pass`es: every [`SEARCH_STRIDE`]-th candidate
/// first, then those between the last that failed and the first that passed, largest
/// first. Where passing is monotone in the gain (the sampled delay and the dead time bound
/// the loops from above), that is the candidate-by-candidate search's answer in about a
/// quarter of its certificates — `design tune` spent 10 s on a 116 W motor whose
/// stationary-frame PI passes 43 candidates down.
pub(super) fn search_down(
    grid: impl Iterator<Item = f64>,
    mut pass: impl FnMut(f64) -> Result<bool, String>,
) -> Result<Option<f64>, String> {
    let grid: Vec<f64> = grid.collect();
    let mut failed_below = 0; // candidates before this index failed (or were skipped)
    let mut hit = None;
    for (i, &w) in grid.iter().enumerate().step_by(SEARCH_STRIDE) {
        if pass(w)? {
            hit = Some((i, w));
            break;
        }
        failed_below = i + 1;
    }
    let end = hit.map_or(grid.len(), |(i, _)| i);
    for &w in grid.get(failed_below..end).unwrap_or_default() {
        if pass(w)? {
            return Ok(Some(w));
        }
    }
    Ok(hit.map(|(_, w)| w))
}

/// `spec` with the current law `law`.
pub(super) fn with_law(spec: &DriveSpec, law: CurrentLaw) -> DriveSpec {
    DriveSpec { current_law: law, ..*spec }
}
/// The ICAD gain (V/A) of [`icad_law`] at `omega_h` with the largest [`robustness`] of the
/// current checks over the box: a geometric grid from `kp_range[1]` down (ratio
/// [`ICAD_GRID_RATIO`]), then a golden-section search between the best point's neighbours.
/// Refused when even the best does not pass every current check.
pub(super) fn icad_gain(
    spec: &mut DriveSpec,
    cert: &CertifySpec,
    omega_h: f64,
    kp_range: [f64; 2],
) -> Result<f64, String> {
    let mut score = |kp: f64| -> Result<f64, String> {
        spec.current_law = icad_law(kp, omega_h);
        Ok(robustness(&certify_current(spec, cert)?).0)
    };
    let mut grid = Vec::new();
    let mut kp = kp_range[1];
    while kp >= kp_range[0] {
        grid.push((kp, score(kp)?));
        kp *= ICAD_GRID_RATIO;
    }
    let best = (0..grid.len())
        .max_by(|&a, &b| grid[a].1.total_cmp(&grid[b].1))
        .ok_or("internal: an empty ICAD gain grid")?;
    let (kp_best, s_best) = grid[best];
    // Golden section on ln k_p between the neighbours (or the grid's end).
    let (mut lo, mut hi) = ((kp_best * ICAD_GRID_RATIO).ln(), (kp_best / ICAD_GRID_RATIO).ln());
    let g = (5f64.sqrt() - 1.0) / 2.0;
    let (mut x1, mut x2) = (hi - g * (hi - lo), lo + g * (hi - lo));
    let (mut f1, mut f2) = (score(x1.exp())?, score(x2.exp())?);
    for _ in 0..ICAD_REFINE_STEPS {
        if f1 >= f2 {
            hi = x2;
            (x2, f2) = (x1, f1);
            x1 = hi - g * (hi - lo);
            f1 = score(x1.exp())?;
        } else {
            lo = x1;
            (x1, f1) = (x2, f2);
            x2 = lo + g * (hi - lo);
            f2 = score(x2.exp())?;
        }
    }
    let (kp, s) = [(kp_best, s_best), (x1.exp(), f1), (x2.exp(), f2)]
        .into_iter()
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap_or((kp_best, s_best));
    if s < 1.0 {
        spec.current_law = icad_law(kp, omega_h);
        let checks = certify_current(spec, cert)?;
        let why = robustness(&checks).1.map_or(String::new(), |c| match c.value {
            Some(v) => format!(": `{}` at {} is {v:.3} of {}", c.name, c.corner, c.limit),
            None => format!(": `{}` at {} fails", c.name, c.corner),
        });
        return Err(format!(
            "no ICAD gain from {:.4} to {:.4} V/A passes every current check on every corner at ω_h = {omega_h} rad/s \
             — the most robust, k_p = {kp:.4} V/A, falls short{why} (the box, the top speed or the PWM rate asks \
             too much)",
            kp_range[0], kp_range[1]
        ));
    }
    Ok(kp)
}

/// The current loops' other frame.
pub(super) fn other_frame(f: CurrentFrame) -> CurrentFrame {
    match f {
        CurrentFrame::Stationary => CurrentFrame::Synchronous,
        CurrentFrame::Synchronous => CurrentFrame::Stationary,
    }
}
