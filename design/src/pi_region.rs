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
    tester_locus(g, Tester { gain: 1.0, phase_rad: 0.0 }, omegas)
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

/// The gain–phase-margin tester `A·e^{−jφ}` inserted in the loop (seed 000 Sec. 4).
///
/// **Derived here** (the printed eqs. (18) and (29) are rotated by a quarter turn and (29)
/// also flips the sign of ∠G): the tester loop `1 + A e^{−jφ}·(k_p + k_i/(jω))·G(jω)`
/// vanishes on the imaginary axis when
///
/// ```text
/// k_i + jω·k_p = −jω·e^{jφ} / (A·G(jω))
///   ⇒ k_p = −cos(φ − ∠G)/(A|G|),   k_i = ω·sin(φ − ∠G)/(A|G|)
/// ```
///
/// (A = 1, φ = 0 gives [`stability_locus`]). Seed 000 prints `k_i = ω cos(φ − ∠G)/(A|G|)`,
/// `k_p = sin(φ − ∠G)/(A|G|)` (18) and `k_i = ω sin(∠G + φ)/(A|G|)`, `k_p = cos(∠G + φ)/(A|G|)` (29).
/// The region is where the loop stays stable with the tester in it: `A` > 1 asks for a
/// gain-increase margin of `A`, `A` < 1 a reduction margin (seed 000 uses `A = √2/2`), `φ` a
/// phase margin. Membership is decided exactly by [`tester_is_stable`].
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Tester {
    /// Gain factor A.
    pub gain: f64,
    /// Phase lag φ, rad.
    pub phase_rad: f64,
}

/// The boundary locus of `tester` for plant `g` over `omegas` (derivation on [`Tester`]).
pub fn tester_locus(g: &Tf, tester: Tester, omegas: &[f64]) -> Vec<LocusPoint> {
    let rot = num_complex::Complex64::from_polar(1.0 / tester.gain, tester.phase_rad);
    omegas
        .iter()
        .map(|&w| {
            let z = num_complex::Complex64::new(0.0, -w) * rot / g.response(w);
            LocusPoint { omega_rad_s: w, kp: z.im / w, ki: z.re }
        })
        .collect()
}

/// Is the loop PI·`n/d` stable with `tester` inserted? The tester's characteristic
/// polynomial `p(s) = s·d(s) + A e^{−jφ}(k_p s + k_i)·n(s)` has complex coefficients;
/// `p(s)·p̄(s)` (p̄: conjugated coefficients, roots mirrored about the real axis, same real
/// parts) is real, so the exact Routh test decides.
pub fn tester_is_stable(n: &Poly, d: &Poly, kp: f64, ki: f64, tester: Tester) -> bool {
    use num_complex::Complex64 as C;
    let t = C::from_polar(tester.gain, -tester.phase_rad);
    let sd = d.mul(&Poly::new(&[1.0, 0.0]));
    let cn = n.mul(&Poly::new(&[kp, ki]));
    let len = sd.coeffs().len().max(cn.coeffs().len());
    let p: Vec<C> = sd.padded(len).iter().zip(cn.padded(len)).map(|(a, b)| C::new(*a, 0.0) + t * b).collect();
    let mut q = vec![0.0; 2 * len - 1];
    for (i, a) in p.iter().enumerate() {
        for (j, b) in p.iter().enumerate() {
            if let Some(x) = q.get_mut(i + j) {
                *x += (a * b.conj()).re;
            }
        }
    }
    Poly::new(&q).is_hurwitz_routh()
}

/// Closed-loop `|T(jω)| = |L/(1 + L)|` of PI·`g` at `omega_rad_s`.
pub fn closed_loop_gain(g: &Tf, kp: f64, ki: f64, omega_rad_s: f64) -> f64 {
    let c = num_complex::Complex64::new(kp, -ki / omega_rad_s);
    let l = c * g.response(omega_rad_s);
    (l / (1.0 + l)).norm()
}

/// Bandwidth condition at `ω_B` (seed 000 eqs. (19)–(22), derived): with integral action
/// `T(0) = 1`, so (19) asks `|T(jω_B)| ≥ 1/√2`, i.e. `L(jω_B)` outside the circle
/// `|L − 1| = √2` — exact, decided here with closed-loop stability. The printed (21)/(30)
/// bound `|jω_B k_p + k_i| ≤ ω_B/((√2 − 1)|G|)` has the inequality reversed (and (30)
/// squares |G|): `|L(jω_B)| ≥ √2 + 1` is **sufficient** for (19), `|L(jω_B)| ≥ √2 − 1`
/// **necessary** — the ellipses [`bandwidth_ellipse`] draws around the exact boundary.
pub fn meets_bandwidth(n: &Poly, d: &Poly, kp: f64, ki: f64, omega_b_rad_s: f64) -> bool {
    let g = Tf { num: n.clone(), den: d.clone() };
    is_stabilising(n, d, kp, ki)
        && closed_loop_gain(&g, kp, ki, omega_b_rad_s) >= std::f64::consts::FRAC_1_SQRT_2
}

/// The exact bandwidth boundary at `ω_B`: `k_i + jω_B k_p = jω_B(1 + √2 e^{jθ})/G(jω_B)`,
/// θ over `n` points of a full turn (an ellipse in the k_p–k_i plane).
pub fn bandwidth_boundary(g: &Tf, omega_b_rad_s: f64, n: usize) -> Vec<(f64, f64)> {
    use num_complex::Complex64 as C;
    let u = C::new(0.0, omega_b_rad_s) / g.response(omega_b_rad_s);
    (0..=n)
        .map(|k| {
            let th = std::f64::consts::TAU * k as f64 / n as f64;
            let z = u * (1.0 + C::from_polar(std::f64::consts::SQRT_2, th));
            (z.im / omega_b_rad_s, z.re)
        })
        .collect()
}

/// The ellipse `ω_B² k_p² + k_i² = (r·ω_B/|G(jω_B)|)²`, i.e. `|L(jω_B)| = r` (eq. (22) with
/// r = √2 + 1; r = √2 − 1 is the necessary counterpart).
pub fn bandwidth_ellipse(g: &Tf, omega_b_rad_s: f64, r: f64, n: usize) -> Vec<(f64, f64)> {
    let rho = r * omega_b_rad_s / g.response(omega_b_rad_s).norm();
    (0..=n)
        .map(|k| {
            let th = std::f64::consts::TAU * k as f64 / n as f64;
            (rho * th.cos() / omega_b_rad_s, rho * th.sin())
        })
        .collect()
}

/// Performance membership of one PI against an interval plant's 16 Kharitonov plants.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct RobustPerformance {
    /// Stable with the tester in the loop for all 16 plants.
    pub gpm_member: bool,
    /// Plants `(i, j)` failing the tester.
    pub gpm_failing: Vec<(usize, usize)>,
    /// `|T(jω_B)| ≥ 1/√2` and stable for all 16 plants.
    pub bandwidth_member: bool,
    /// Smallest `|T(jω_B)|` over the 16 plants.
    pub min_closed_loop_gain_at_omega_b: f64,
}

/// Check `(kp, ki)` for the GPM tester and the bandwidth `ω_B` over the 16 plants (the
/// vertex result the paper relies on; a sampled-member cross-check is in the tests).
pub fn robust_performance(
    plant: &IntervalPlant,
    kp: f64,
    ki: f64,
    tester: Tester,
    omega_b_rad_s: f64,
) -> RobustPerformance {
    let plants = plant.kharitonov_plants();
    let gpm_failing: Vec<(usize, usize)> = plants
        .iter()
        .filter(|(_, _, n, d)| !tester_is_stable(n, d, kp, ki, tester))
        .map(|(i, j, _, _)| (*i, *j))
        .collect();
    let min_t = plants
        .iter()
        .map(|(_, _, n, d)| closed_loop_gain(&Tf { num: n.clone(), den: d.clone() }, kp, ki, omega_b_rad_s))
        .fold(f64::INFINITY, f64::min);
    RobustPerformance {
        gpm_member: gpm_failing.is_empty(),
        gpm_failing,
        bandwidth_member: plants.iter().all(|(_, _, n, d)| meets_bandwidth(n, d, kp, ki, omega_b_rad_s)),
        min_closed_loop_gain_at_omega_b: min_t,
    }
}

/// `n` evenly spaced values from `lo` to `hi`.
pub fn linspace(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    (0..n).map(|k| lo + (hi - lo) * k as f64 / (n.max(2) - 1) as f64).collect()
}

/// The speed loop's dead time as the region design models it, in slow periods: the speed
/// estimate's window (its centre lies `SPEED_WINDOW_READS/2` periods back), the torque
/// applied one slow period after the sample, and the hold's half period.
pub fn speed_dead_time_periods() -> f64 {
    controller_core::encoder::SPEED_WINDOW_READS as f64 / 2.0 + 1.5
}

/// Seed 000's regions (Sec. 3–5) for the speed loop's PI → torque: the plant
/// `e^{−sτ}/(J s + B)` with J over an interval and the dead time τ
/// ([`speed_dead_time_periods`]·T_slow) as a first-order Padé `(1 − sτ/2)/(1 + sτ/2)`, so
/// `N = 1 − sτ/2` and `D = (Jτ/2)s² + (J + Bτ/2)s + B` form an interval plant, decided on
/// its 16 Kharitonov plants.
#[derive(Clone, Debug)]
pub struct SpeedRegions {
    plants: Vec<(usize, usize, crate::poly::Poly, crate::poly::Poly)>,
    gm: Tester,
    pm: Tester,
    /// The inertia interval, kg·m².
    pub j_kgm2: [f64; 2],
    /// The modelled dead time, s.
    pub tau_s: f64,
    /// The phase margin asked, degrees, and the gain margin, dB.
    pub minima: [f64; 2],
}

impl SpeedRegions {
    /// The regions for J ∈ `j_kgm2`, friction `b_nms`, slow period `t_slow_s`, and the
    /// phase and gain margins asked (degrees, dB).
    pub fn new(j_kgm2: [f64; 2], b_nms: f64, t_slow_s: f64, minima: [f64; 2]) -> Result<Self, String> {
        use crate::kharitonov::IntervalPoly;
        use Tester;
        let tau = speed_dead_time_periods() * t_slow_s;
        let [jl, jh] = j_kgm2;
        let plant = IntervalPlant {
            num: IntervalPoly::point(&[-tau / 2.0, 1.0]),
            den: IntervalPoly::new(
                &[jl * tau / 2.0, jl + b_nms * tau / 2.0, b_nms],
                &[jh * tau / 2.0, jh + b_nms * tau / 2.0, b_nms],
            )
            .map_err(|e| format!("speed plant: {e:?}"))?,
        };
        Ok(Self {
            plants: plant.kharitonov_plants(),
            gm: Tester { gain: 10f64.powf(minima[1] / 20.0), phase_rad: 0.0 },
            pm: Tester { gain: 1.0, phase_rad: minima[0].to_radians() },
            j_kgm2,
            tau_s: tau,
            minima,
        })
    }

    /// Robustly stable.
    pub fn stable(&self, kp: f64, ki: f64) -> bool {
        self.plants.iter().all(|(_, _, n, d)| is_stabilising(n, d, kp, ki))
    }

    /// Stable with each gain–phase tester in the loop (the margins) on every plant.
    pub fn margins(&self, kp: f64, ki: f64) -> bool {
        self.plants.iter().all(|(_, _, n, d)| {
            tester_is_stable(n, d, kp, ki, self.gm) && tester_is_stable(n, d, kp, ki, self.pm)
        })
    }

    /// Closed-loop bandwidth at least `omega_b_rad_s` on every plant (seed 000 eq. (19)).
    pub fn bandwidth(&self, kp: f64, ki: f64, omega_b_rad_s: f64) -> bool {
        self.plants.iter().all(|(_, _, n, d)| meets_bandwidth(n, d, kp, ki, omega_b_rad_s))
    }
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
    /// The tester loci bound the brute-force tester region (stability of the complex
    /// tester polynomial on a dense grid only changes across the derived locus or k_i = 0),
    /// and the printed eq. (18) point is not on it.
    #[test]
    fn gpm_locus_bounds_the_brute_force_region() {
        let plant = seed000_current_plant().unwrap();
        let (_, _, n, d) = plant.kharitonov_plants().into_iter().next().unwrap();
        let g = Tf { num: n.clone(), den: d.clone() };
        for tester in [
            Tester { gain: 2.0, phase_rad: 0.0 },
            Tester { gain: 1.0, phase_rad: 1.0 },
            Tester { gain: 0.5_f64.sqrt(), phase_rad: std::f64::consts::FRAC_PI_3 },
        ] {
            let locus = tester_locus(&g, tester, &logspace(1e-2, 1e5, 20_000));
            let (kps, kis) = (linspace(-2.0, 2.0, 81), linspace(-50.0, 400.0, 91));
            let (dkp, dki) = (kps[1] - kps[0], kis[1] - kis[0]);
            let stable: Vec<Vec<bool>> = kps
                .iter()
                .map(|&kp| kis.iter().map(|&ki| tester_is_stable(&n, &d, kp, ki, tester)).collect())
                .collect();
            let (mut flips, mut inside) = (0, 0);
            for a in 0..kps.len() {
                for b in 0..kis.len() {
                    inside += usize::from(stable[a][b]);
                    for (a2, b2) in [(a + 1, b), (a, b + 1)] {
                        if a2 >= kps.len() || b2 >= kis.len() || stable[a][b] == stable[a2][b2] {
                            continue;
                        }
                        flips += 1;
                        let (kp_mid, ki_mid) = (0.5 * (kps[a] + kps[a2]), 0.5 * (kis[b] + kis[b2]));
                        let near = ki_mid.abs() <= dki
                            || locus
                                .iter()
                                .any(|p| (p.kp - kp_mid).abs() <= dkp && (p.ki - ki_mid).abs() <= dki);
                        assert!(
                            near,
                            "{tester:?}: flip at kp {kp_mid}, ki {ki_mid} without a boundary nearby"
                        );
                    }
                }
            }
            assert!(flips > 20 && inside > 50, "{tester:?}: {flips} {inside}");
        }
        // The tester with A = 1, φ = 0 is plain stability.
        assert!(tester_is_stable(&n, &d, 30.0, 50.0, Tester { gain: 1.0, phase_rad: 0.0 }));
        assert!(!tester_is_stable(&n, &d, 30.0, -50.0, Tester { gain: 1.0, phase_rad: 0.0 }));
    }

    /// A phase tester φ is passed iff the measured phase margin exceeds φ (single-crossover
    /// loop G = 1/(s + 1)², PI gains swept).
    #[test]
    fn phase_tester_agrees_with_measured_phase_margin() {
        let (n, d) = (Poly::new(&[1.0]), Poly::new(&[1.0, 2.0, 1.0]));
        let g = Tf { num: n.clone(), den: d.clone() };
        let w = logspace(1e-3, 1e3, 20_000);
        let tester = Tester { gain: 1.0, phase_rad: 45f64.to_radians() };
        let (mut pass, mut fail) = (0, 0);
        for kp in linspace(0.2, 6.0, 15) {
            for ki in linspace(0.05, 3.0, 15) {
                let l: Vec<_> =
                    w.iter().map(|&x| num_complex::Complex64::new(kp, -ki / x) * g.response(x)).collect();
                let m = crate::margins::margins(&w, &l);
                let pm = m.phase_margin_deg.unwrap();
                if (pm - 45.0).abs() < 0.5 || !is_stabilising(&n, &d, kp, ki) {
                    continue; // too close to call on the grid / unstable anyway
                }
                let t = tester_is_stable(&n, &d, kp, ki, tester);
                assert_eq!(t, pm > 45.0, "kp {kp} ki {ki}: PM {pm}");
                if t { pass += 1 } else { fail += 1 }
            }
        }
        assert!(pass > 10 && fail > 10, "{pass} {fail}");
    }

    /// Bandwidth: the exact condition lies between the necessary and the sufficient
    /// ellipses; where the measured −3 dB bandwidth exceeds ω_B the exact single-frequency
    /// condition holds; and the printed (21) direction is wrong (a PI inside it misses ω_B).
    #[test]
    fn bandwidth_condition_is_bracketed_and_matches_measurement() {
        let (n, d) = (Poly::new(&[1.0]), Poly::new(&[1.0, 2.0, 1.0]));
        let g = Tf { num: n.clone(), den: d.clone() };
        let wb = 1.5;
        let w = logspace(1e-3, 1e3, 20_000);
        let gmag = g.response(wb).norm();
        let (mut exact_n, mut suff_n, mut nec_n) = (0, 0, 0);
        for kp in linspace(0.1, 8.0, 40) {
            for ki in linspace(0.05, 6.0, 40) {
                if !is_stabilising(&n, &d, kp, ki) {
                    continue;
                }
                let l_mag = gmag * (ki * ki + wb * wb * kp * kp).sqrt() / wb;
                let exact = meets_bandwidth(&n, &d, kp, ki, wb);
                let (suff, nec) = (l_mag >= 2f64.sqrt() + 1.0, l_mag >= 2f64.sqrt() - 1.0);
                assert!(!suff || exact, "sufficient but not exact at {kp} {ki}");
                assert!(!exact || nec, "exact but not necessary at {kp} {ki}");
                let l: Vec<_> =
                    w.iter().map(|&x| num_complex::Complex64::new(kp, -ki / x) * g.response(x)).collect();
                if let Some(bw) = crate::margins::margins(&w, &l).bandwidth_rad_s
                    && bw > wb * 1.01
                {
                    assert!(exact, "measured bandwidth {bw} > {wb} but |T(jω_B)| < 1/√2 at {kp} {ki}");
                }
                exact_n += usize::from(exact);
                suff_n += usize::from(suff);
                nec_n += usize::from(nec);
            }
        }
        assert!(suff_n < exact_n && exact_n < nec_n && suff_n > 10, "{suff_n} {exact_n} {nec_n}");
        // The printed (21) keeps |L(jω_B)| ≤ √2 + 1; a small PI satisfies it and is far too slow.
        let (kp, ki) = (0.1, 0.05);
        let l_mag = gmag * (ki * ki + wb * wb * kp * kp).sqrt() / wb;
        assert!(l_mag <= 2f64.sqrt() + 1.0 && !meets_bandwidth(&n, &d, kp, ki, wb));
        // The exact boundary points give |T(jω_B)| = 1/√2.
        for (kp, ki) in bandwidth_boundary(&g, wb, 16) {
            assert!((closed_loop_gain(&g, kp, ki, wb) - std::f64::consts::FRAC_1_SQRT_2).abs() < 1e-9);
        }
    }
}
