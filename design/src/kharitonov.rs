//! Kharitonov analysis of interval polynomials and interval plants (seed 000 Sec. 5,
//! eqs. (23)–(30)).
//!
//! An interval polynomial has each coefficient in `[lo, hi]`. With ascending coefficients
//! `a_0, a_1, a_2, …` its four Kharitonov polynomials follow the patterns (period 4)
//!
//! ```text
//! K1: lo lo hi hi …    K2: hi hi lo lo …    K3: lo hi hi lo …    K4: hi lo lo hi …
//! ```
//!
//! and the interval polynomial is Hurwitz iff all four are (Kharitonov's theorem). For an
//! interval plant N(s)/D(s) the 16 Kharitonov plants are N_i/D_j; a PI (indeed PID)
//! controller stabilises the whole family iff it stabilises these 16 (the result seed 000
//! builds on; cross-checked here by sampling plants inside the coefficient box).

use crate::poly::Poly;

/// A polynomial with interval coefficients, **descending** powers like [`Poly`].
#[derive(Clone, Debug, PartialEq)]
pub struct IntervalPoly {
    lo: Vec<f64>,
    hi: Vec<f64>,
}

/// Why an interval polynomial was rejected.
#[derive(Clone, Debug, PartialEq)]
pub enum IntervalError {
    /// `lo` and `hi` have different lengths or are empty.
    Length,
    /// Coefficient `index` (descending) has `lo > hi` or is not finite.
    Bounds {
        /// Index in descending order.
        index: usize,
    },
}

impl IntervalPoly {
    /// From descending lower and upper bounds.
    pub fn new(lo: &[f64], hi: &[f64]) -> Result<Self, IntervalError> {
        if lo.len() != hi.len() || lo.is_empty() {
            return Err(IntervalError::Length);
        }
        if let Some(index) = lo.iter().zip(hi).position(|(l, h)| !(l.is_finite() && h.is_finite() && l <= h))
        {
            return Err(IntervalError::Bounds { index });
        }
        Ok(Self { lo: lo.to_vec(), hi: hi.to_vec() })
    }

    /// A fixed polynomial as a degenerate interval.
    pub fn point(desc: &[f64]) -> Self {
        Self { lo: desc.to_vec(), hi: desc.to_vec() }
    }

    /// The four Kharitonov polynomials K1..K4.
    pub fn kharitonov(&self) -> [Poly; 4] {
        // Patterns on ascending powers k = 0, 1, 2, …: true = upper bound.
        const PATTERNS: [[bool; 4]; 4] = [
            [false, false, true, true],
            [true, true, false, false],
            [false, true, true, false],
            [true, false, false, true],
        ];
        let n = self.lo.len();
        PATTERNS.map(|pat| {
            let desc: Vec<f64> = (0..n)
                .map(|i| {
                    let k = n - 1 - i; // power of s for descending index i
                    if pat[k % 4] { self.hi[i] } else { self.lo[i] }
                })
                .collect();
            Poly::new(&desc)
        })
    }

    /// Lower bounds, descending.
    pub fn lo(&self) -> &[f64] {
        &self.lo
    }

    /// Upper bounds, descending.
    pub fn hi(&self) -> &[f64] {
        &self.hi
    }

    /// The smallest box holding every polynomial of `polys` (descending, padded to the
    /// largest degree; the zero polynomial for an empty set). For a family affine in one parameter,
    /// `p0 + k·p1` with `k ∈ [k_lo, k_hi]`, the hull of its two end members is the family's
    /// interval polynomial — each coefficient's range comes from the loop's algebra,
    /// orientation included; for fitted models it is their coefficient ranges.
    pub fn hull(polys: &[Poly]) -> Self {
        let Some(n) = polys.iter().map(|p| p.coeffs().len()).max() else {
            return Self::point(&[0.0]);
        };
        let padded: Vec<Vec<f64>> = polys.iter().map(|p| p.padded(n)).collect();
        let fold = |i: usize, f: fn(f64, f64) -> f64, init: f64| padded.iter().map(|p| p[i]).fold(init, f);
        Self {
            lo: (0..n).map(|i| fold(i, f64::min, f64::INFINITY)).collect(),
            hi: (0..n).map(|i| fold(i, f64::max, f64::NEG_INFINITY)).collect(),
        }
    }

    /// Kharitonov's exact test: all four Kharitonov polynomials Hurwitz (Routh).
    pub fn is_robustly_hurwitz(&self) -> bool {
        self.kharitonov().iter().all(Poly::is_hurwitz_routh)
    }

    /// Largest real part of any root of the four Kharitonov polynomials. Its sign decides
    /// robust stability; the value is a continuous margin an optimiser can use. (It bounds
    /// the family's roots only at the imaginary axis: Kharitonov's theorem is about
    /// crossing it, not about decay rates — use [`Poly::shifted`] members for those.)
    pub fn kharitonov_abscissa(&self) -> f64 {
        self.kharitonov().iter().map(Poly::max_real_root).fold(f64::NEG_INFINITY, f64::max)
    }

    /// Seed 001 lemmas 2.1 and 2.2 (eqs. (2), (3); Nie's conditions applied to the worst
    /// member): with ascending bounds `x_i ≤ δ_i ≤ y_i`, all `x_i > 0` and
    /// `factor·x_i·x_{i+1} > y_{i−1}·y_{i+2}` for `i = 1 … n−2`.
    ///
    /// `factor = 1` is lemma 2.1, a **necessary** condition (the member taking `x_i`,
    /// `x_{i+1}`, `y_{i−1}`, `y_{i+2}` exists because coefficients vary independently, and
    /// every Hurwitz polynomial satisfies `a_i a_{i+1} > a_{i−1} a_{i+2}`); the paper's
    /// wording "is Hurwitz … if the following necessary conditions are satisfied" reads it
    /// as sufficient, which it is not (e.g. s⁴ + s³ + 2s² + 1.9s + 0.5 passes and is not Hurwitz).
    /// [`NIE_SUFFICIENT`] is lemma 2.2, **sufficient**. Both are cross-checked against
    /// Kharitonov's exact test in the tests.
    pub fn nie_conditions(&self, factor: f64) -> NieReport {
        let n = self.lo.len() - 1;
        // ascending access: x(i) = lo[n − i]
        let x = |i: usize| n.checked_sub(i).and_then(|d| self.lo.get(d)).copied().unwrap_or(0.0);
        let y = |i: usize| n.checked_sub(i).and_then(|d| self.hi.get(d)).copied().unwrap_or(0.0);
        let min_coefficient = self.lo.iter().copied().fold(f64::INFINITY, f64::min);
        let margins: Vec<f64> =
            (1..n.saturating_sub(1)).map(|i| factor * x(i) * x(i + 1) - y(i - 1) * y(i + 2)).collect();
        let holds = min_coefficient > 0.0 && margins.iter().all(|&m| m > 0.0);
        NieReport { min_coefficient, margins, holds }
    }

    /// A member with coefficients `lo + t·(hi − lo)`, `t` in [0, 1] per coefficient.
    pub fn member(&self, t: &[f64]) -> Poly {
        let desc: Vec<f64> = self
            .lo
            .iter()
            .zip(&self.hi)
            .enumerate()
            .map(|(i, (l, h))| l + t.get(i).copied().unwrap_or(0.0) * (h - l))
            .collect();
        Poly::new(&desc)
    }
}

/// Lemma 2.2's constant (seed 001 eq. (3)).
pub const NIE_SUFFICIENT: f64 = 0.4655;

/// Outcome of [`IntervalPoly::nie_conditions`].
#[derive(Clone, Debug, PartialEq)]
pub struct NieReport {
    /// Smallest lower bound `min x_i` (must be > 0).
    pub min_coefficient: f64,
    /// `factor·x_i·x_{i+1} − y_{i−1}·y_{i+2}` for `i = 1 … n−2` (each must be > 0).
    pub margins: Vec<f64>,
    /// Every condition holds.
    pub holds: bool,
}

/// An interval plant N(s)/D(s).
#[derive(Clone, Debug, PartialEq)]
pub struct IntervalPlant {
    /// Numerator.
    pub num: IntervalPoly,
    /// Denominator.
    pub den: IntervalPoly,
}

/// Result of checking a PI controller against the 16 Kharitonov plants.
#[derive(Clone, Debug, PartialEq)]
pub struct PiCheck {
    /// All 16 closed loops Hurwitz.
    pub robust_stable: bool,
    /// Largest real part of any closed-loop pole over the 16 plants.
    pub worst_pole_re: f64,
    /// `(i, j, max real part)` per plant N_i/D_j (1-based as in the paper).
    pub per_plant: Vec<(usize, usize, f64)>,
}

/// Closed-loop characteristic polynomial of PI `(k_p s + k_i)/s` with plant `n/d`:
/// `s·d(s) + (k_p s + k_i)·n(s)`.
pub fn pi_characteristic(n: &Poly, d: &Poly, kp: f64, ki: f64) -> Poly {
    d.mul(&Poly::new(&[1.0, 0.0])).add(&n.mul(&Poly::new(&[kp, ki])))
}

impl IntervalPlant {
    /// The 16 plants `(i, j, N_i, D_j)`.
    pub fn kharitonov_plants(&self) -> Vec<(usize, usize, Poly, Poly)> {
        let (ns, ds) = (self.num.kharitonov(), self.den.kharitonov());
        let mut v = Vec::with_capacity(16);
        for (i, n) in ns.iter().enumerate() {
            for (j, d) in ds.iter().enumerate() {
                v.push((i + 1, j + 1, n.clone(), d.clone()));
            }
        }
        v
    }

    /// Check PI `(k_p s + k_i)/s` on the 16 plants.
    pub fn check_pi(&self, kp: f64, ki: f64) -> PiCheck {
        let per_plant: Vec<(usize, usize, f64)> = self
            .kharitonov_plants()
            .iter()
            .map(|(i, j, n, d)| (*i, *j, pi_characteristic(n, d, kp, ki).max_real_root()))
            .collect();
        let worst_pole_re = per_plant.iter().map(|p| p.2).fold(f64::NEG_INFINITY, f64::max);
        let robust_stable = self
            .kharitonov_plants()
            .iter()
            .all(|(_, _, n, d)| pi_characteristic(n, d, kp, ki).is_hurwitz_routh());
        PiCheck { robust_stable, worst_pole_re, per_plant }
    }
}

/// Seed 000 eqs. (32)–(33): the interval q-axis current-loop plant of the 2300 V machine.
pub fn seed000_current_plant() -> Result<IntervalPlant, IntervalError> {
    Ok(IntervalPlant {
        num: IntervalPoly::new(
            &[375_660.0, 27_133_000.0, 20_911_000_000.0, 330_660_000_000.0, 373_220_000_000.0],
            &[375_660.0, 27_133_000.0, 20_966_000_000.0, 1_499_900_000_000.0, 1_845_500_000_000.0],
        )?,
        den: IntervalPoly::new(
            &[1.0, 141.9, 203_110.0, 12_366_000.0, 8_035_500_000.0, 233_990_000_000.0],
            &[1.0, 141.9, 204_990.0, 12_500_000.0, 8_316_600_000.0, 242_110_000_000.0],
        )?,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kharitonov_patterns() {
        // a0 + a1 s + a2 s² + a3 s³ with a_k ∈ [k, k + 10]: K1 = (lo, lo, hi, hi) ascending.
        let p = IntervalPoly::new(&[3.0, 2.0, 1.0, 0.0], &[13.0, 12.0, 11.0, 10.0]).unwrap();
        let k = p.kharitonov();
        // ascending a0 ∈ [0, 10], a1 ∈ [1, 11], a2 ∈ [2, 12], a3 ∈ [3, 13]
        assert_eq!(k[0].coeffs(), &[13.0, 12.0, 1.0, 0.0]);
        assert_eq!(k[1].coeffs(), &[3.0, 2.0, 11.0, 10.0]);
        assert_eq!(k[2].coeffs(), &[3.0, 12.0, 11.0, 0.0]);
        assert_eq!(k[3].coeffs(), &[13.0, 2.0, 1.0, 10.0]);
    }

    #[test]
    fn rejects_bad_intervals() {
        assert_eq!(IntervalPoly::new(&[1.0], &[1.0, 2.0]), Err(IntervalError::Length));
        assert_eq!(IntervalPoly::new(&[1.0, 3.0], &[2.0, 2.0]), Err(IntervalError::Bounds { index: 1 }));
    }

    /// Kharitonov's theorem cross-checked on random interval cubics: the four polynomials
    /// decide the same as 400 sampled members plus all 16 vertices (a sampled unstable
    /// member proves "not robust"; agreement is required whenever the sampling finds one).
    #[test]
    fn theorem_agrees_with_sampling() {
        let mut rnd = crate::testutil::uniform(12345u64);
        let (mut robust_cases, mut fragile_cases) = (0, 0);
        for _ in 0..300 {
            let lo: Vec<f64> = (0..4).map(|i| if i == 0 { 1.0 } else { 0.2 + 3.0 * rnd() }).collect();
            let hi: Vec<f64> =
                lo.iter().enumerate().map(|(i, l)| if i == 0 { 1.0 } else { l + 1.5 * rnd() }).collect();
            let ip = IntervalPoly::new(&lo, &hi).unwrap();
            let kh = ip.kharitonov().iter().all(Poly::is_hurwitz_routh);
            let mut sampled_unstable = false;
            for v in 0..16u32 {
                let t: Vec<f64> = (0..4).map(|b| f64::from((v >> b) & 1)).collect();
                sampled_unstable |= !ip.member(&t).is_hurwitz_routh();
            }
            for _ in 0..400 {
                let t: Vec<f64> = (0..4).map(|_| rnd()).collect();
                sampled_unstable |= !ip.member(&t).is_hurwitz_routh();
            }
            if kh {
                robust_cases += 1;
                assert!(!sampled_unstable, "Kharitonov says robust but a member is unstable: {lo:?} {hi:?}");
            } else {
                fragile_cases += 1;
            }
        }
        assert!(robust_cases > 20 && fragile_cases > 20, "{robust_cases} {fragile_cases}");
    }

    /// Seed 000: PI1 = (30s + 50)/s on the interval plant (32)–(33).
    #[test]
    fn seed000_pi1_on_the_interval_current_plant() {
        let plant = seed000_current_plant().unwrap();
        let r = plant.check_pi(30.0, 50.0);
        eprintln!(
            "seed 000 PI1 on (32)–(33): robust_stable = {}, worst pole Re = {:.4}",
            r.robust_stable, r.worst_pole_re
        );
        for (i, j, re) in &r.per_plant {
            eprintln!("  N{i}/D{j}: max Re(pole) = {re:.4}");
        }
        // Brute force inside the box: 2000 random members of numerator and denominator.
        let mut rnd = crate::testutil::uniform(99u64);
        let mut worst_sampled = f64::NEG_INFINITY;
        for _ in 0..2000 {
            let tn: Vec<f64> = (0..5).map(|_| rnd()).collect();
            let td: Vec<f64> = (0..6).map(|_| rnd()).collect();
            let p = pi_characteristic(&plant.num.member(&tn), &plant.den.member(&td), 30.0, 50.0);
            worst_sampled = worst_sampled.max(p.max_real_root());
        }
        eprintln!("  2000 sampled members: worst pole Re = {worst_sampled:.4}");
        assert_eq!(r.robust_stable, r.worst_pole_re < 0.0);
        if r.robust_stable {
            assert!(worst_sampled < 0.0);
        }
    }
    /// Lemmas 2.1/2.2 against Kharitonov's exact test on random interval quartics and
    /// quintics: 2.2 holding must imply robust stability, robust stability must imply 2.1;
    /// each implication is exercised (counts asserted), and the gaps between them exist.
    #[test]
    fn nie_lemmas_bracket_the_exact_test() {
        let mut rnd = crate::testutil::uniform(4242u64);
        let (mut suff, mut robust, mut nec, mut cases) = (0, 0, 0, 0);
        for degree in [4usize, 5] {
            for _ in 0..3000 {
                let lo: Vec<f64> =
                    (0..=degree).map(|i| if i == 0 { 1.0 } else { 0.1 + 6.0 * rnd() }).collect();
                let hi: Vec<f64> = lo
                    .iter()
                    .enumerate()
                    .map(|(i, l)| if i == 0 { 1.0 } else { l * (1.0 + 0.3 * rnd()) })
                    .collect();
                let ip = IntervalPoly::new(&lo, &hi).unwrap();
                let (s22, k, s21) = (
                    ip.nie_conditions(NIE_SUFFICIENT).holds,
                    ip.is_robustly_hurwitz(),
                    ip.nie_conditions(1.0).holds,
                );
                assert!(!s22 || k, "lemma 2.2 holds but Kharitonov fails: {lo:?} {hi:?}");
                assert!(!k || s21, "robustly Hurwitz but lemma 2.1 fails: {lo:?} {hi:?}");
                cases += 1;
                suff += usize::from(s22);
                robust += usize::from(k);
                nec += usize::from(s21);
            }
        }
        eprintln!("{cases} interval polynomials: lemma 2.2 {suff}, Kharitonov {robust}, lemma 2.1 {nec}");
        assert!(suff > 50 && robust > suff && nec > robust, "{suff} {robust} {nec}");
    }

    #[test]
    fn lemma_21_is_not_sufficient() {
        // The counterexample quoted in `nie_conditions`: passes 2.1, has RHP roots.
        let p = IntervalPoly::point(&[1.0, 1.0, 2.0, 1.9, 0.5]);
        assert!(p.nie_conditions(1.0).holds);
        assert!(!p.is_robustly_hurwitz());
    }

    #[test]
    fn hull_orients_each_coefficient() {
        let h = IntervalPoly::hull(&[Poly::new(&[1.0, 3.0, -2.0]), Poly::new(&[1.0, 1.0, 4.0])]);
        assert_eq!(h.lo(), &[1.0, 1.0, -2.0]);
        assert_eq!(h.hi(), &[1.0, 3.0, 4.0]);
        // Different degrees are padded; an empty set has no hull.
        let h = IntervalPoly::hull(&[Poly::new(&[2.0]), Poly::new(&[1.0, -1.0])]);
        assert_eq!((h.lo(), h.hi()), (&[0.0, -1.0][..], &[1.0, 2.0][..]));
        assert_eq!(IntervalPoly::hull(&[]), IntervalPoly::point(&[0.0]));
    }
}
