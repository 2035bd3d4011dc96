//! PI stability regions in the k_p–k_i plane (seed 000 Sec. 3–5).
//!
//! **Boundary locus (derived here; the printed eqs. (14)–(16) have a quadrant slip).** With
//! `C(s) = (k_p s + k_i)/s` and plant `G = N/D`, the closed-loop polynomial is
//! `δ(s) = s·D(s) + (k_p s + k_i)·N(s)`. A root crosses the imaginary axis at `s = jω` when
//! `jω·D(jω) + (k_i + jω k_p)·N(jω) = 0`, i.e.
//!
//! ```text
//! k_i + jω·k_p = −jω / G(jω)   ⇒   k_p(ω) = −cos∠G(jω) / |G(jω)|,   k_i(ω) = −ω·sin∠G(jω) / |G(jω)|
//! ```
//!
//! plus the line `k_i = 0` (a root at s = 0). Seed 000 prints `k_i = ω cos∠G/|G|`,
//! `k_p = sin∠G/|G|` (eq. (16)): for G = 1/(s + 1) at ω = 2 rad/s that gives k_p = −2,
//! while the true boundary is the line k_p = −1 — see `paper_eq16_is_not_the_boundary`. Membership of a point is decided exactly (Routh test on
//! the 16 Kharitonov closed loops), and every region is cross-checked against brute force.

use crate::kharitonov::{IntervalPlant, pi_characteristic};
use crate::poly::Poly;
use crate::tf::Tf;

/// One point of a boundary locus.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LocusPoint {
    /// Frequency, rad/s.
    pub omega_rad_s: f64,
    /// Proportional gain on the boundary.
    pub kp: f64,
    /// Integral gain on the boundary.
    pub ki: f64,
}

/// The stability boundary locus of plant `g` over `omegas`.
pub fn stability_locus(g: &Tf, omegas: &[f64]) -> Vec<LocusPoint> {
    omegas
        .iter()
        .map(|&w| {
            let z = num_complex::Complex64::new(0.0, -w) / g.response(w);
            LocusPoint { omega_rad_s: w, kp: z.im / w, ki: z.re }
        })
        .collect()
}

/// Is `(kp, ki)` stabilising for the fixed plant `n/d`?
pub fn is_stabilising(n: &Poly, d: &Poly, kp: f64, ki: f64) -> bool {
    pi_characteristic(n, d, kp, ki).is_hurwitz_routh()
}

/// Robust membership grid: `grid[a][b]` for `kp = kps[a]`, `ki = kis[b]`, true when all 16
/// Kharitonov closed loops are Hurwitz.
pub fn robust_grid(plant: &IntervalPlant, kps: &[f64], kis: &[f64]) -> Vec<Vec<bool>> {
    let plants = plant.kharitonov_plants();
    kps.iter()
        .map(|&kp| {
            kis.iter().map(|&ki| plants.iter().all(|(_, _, n, d)| is_stabilising(n, d, kp, ki))).collect()
        })
        .collect()
}

/// `n` evenly spaced values from `lo` to `hi`.
pub fn linspace(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    (0..n).map(|k| lo + (hi - lo) * k as f64 / (n.max(2) - 1) as f64).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kharitonov::seed000_current_plant;
    use crate::tf::logspace;

    #[test]
    fn first_order_plant_boundary_is_kp_minus_one() {
        // G = 1/(s+1): δ = s² + (1 + k_p)s + k_i, stable iff k_p > −1 and k_i > 0.
        let g = Tf::new(&[1.0], &[1.0, 1.0]);
        for p in stability_locus(&g, &logspace(0.01, 100.0, 50)) {
            assert!((p.kp + 1.0).abs() < 1e-12);
            assert!((p.ki - p.omega_rad_s * p.omega_rad_s).abs() < 1e-9 * p.ki.max(1.0));
        }
    }

    #[test]
    fn paper_eq16_is_not_the_boundary() {
        // Eq. (16) as printed: k_p = sin∠G/|G|. For G = 1/(s+1) at ω = 2 rad/s,
        // ∠G = −63.4° and |G| = 0.447, so k_p = −2 — off the true boundary k_p = −1.
        let g = Tf::new(&[1.0], &[1.0, 1.0]);
        let w = 2.0;
        let r = g.response(w);
        let kp_paper = r.arg().sin() / r.norm();
        assert!((kp_paper + 2.0).abs() < 1e-9);
        let n = Poly::new(&[1.0]);
        let d = Poly::new(&[1.0, 1.0]);
        // The printed point (−2, ·) is not marginal: k_p = −2 < −1 is plainly unstable.
        assert!(!is_stabilising(&n, &d, kp_paper, 1.0));
        let true_locus = stability_locus(&g, &[w]);
        assert!((true_locus[0].kp + 1.0).abs() < 1e-12);
    }

    /// Brute force: on a dense grid around the seed 000 nominal plant, wherever two
    /// neighbouring points differ in stability, the derived locus (or k_i = 0) passes
    /// between them.
    #[test]
    fn locus_bounds_the_brute_force_region() {
        let plant = seed000_current_plant().unwrap();
        let (_, _, n, d) = plant.kharitonov_plants().into_iter().next().unwrap();
        let g = Tf { num: n.clone(), den: d.clone() };
        let locus = stability_locus(&g, &logspace(1e-2, 1e5, 20_000));
        let (kps, kis) = (linspace(-2.0, 2.0, 81), linspace(-50.0, 400.0, 91));
        let (dkp, dki) = (kps[1] - kps[0], kis[1] - kis[0]);
        let stable: Vec<Vec<bool>> =
            kps.iter().map(|&kp| kis.iter().map(|&ki| is_stabilising(&n, &d, kp, ki)).collect()).collect();
        let mut flips = 0;
        for a in 0..kps.len() {
            for b in 0..kis.len() {
                for (a2, b2) in [(a + 1, b), (a, b + 1)] {
                    if a2 >= kps.len() || b2 >= kis.len() || stable[a][b] == stable[a2][b2] {
                        continue;
                    }
                    flips += 1;
                    let (kp_mid, ki_mid) = (0.5 * (kps[a] + kps[a2]), 0.5 * (kis[b] + kis[b2]));
                    let near_axis = ki_mid.abs() <= dki;
                    let near_locus =
                        locus.iter().any(|p| (p.kp - kp_mid).abs() <= dkp && (p.ki - ki_mid).abs() <= dki);
                    assert!(
                        near_axis || near_locus,
                        "flip at kp {kp_mid}, ki {ki_mid} without a boundary nearby"
                    );
                }
            }
        }
        assert!(flips > 50, "{flips}");
    }

    #[test]
    fn pi1_is_inside_the_robust_region_and_the_grid_has_both_kinds() {
        let plant = seed000_current_plant().unwrap();
        let g = robust_grid(&plant, &[30.0, -10.0], &[50.0, -5.0]);
        assert!(g[0][0]); // PI1
        assert!(!g[0][1]); // negative k_i
        assert!(!g[1][0]); // negative k_p far beyond the boundary
    }
}
