//! Real-coefficient polynomials.
//!
//! Coefficients are stored in **descending** powers, as printed in the papers:
//! `[a_n, …, a_1, a_0]` is `a_n sⁿ + … + a_1 s + a_0`. Leading zeros are trimmed.
//! Roots come from the eigenvalues of the companion matrix (nalgebra's real Schur
//! decomposition), robust for the degrees met here (≤ ~15); Hurwitz stability has an
//! independent exact test (Routh array) used to cross-check.

use nalgebra::DMatrix;
use num_complex::Complex64;

/// A real polynomial in descending powers.
#[derive(Clone, Debug, PartialEq)]
pub struct Poly {
    c: Vec<f64>,
}

impl Poly {
    /// From descending coefficients; leading zeros are removed (the zero polynomial is `[0]`).
    pub fn new(desc: &[f64]) -> Self {
        let first = desc.iter().position(|&x| x != 0.0).unwrap_or(desc.len().saturating_sub(1));
        let c = desc.get(first..).map(<[f64]>::to_vec).filter(|v| !v.is_empty()).unwrap_or_else(|| vec![0.0]);
        Self { c }
    }

    /// Descending coefficients.
    pub fn coeffs(&self) -> &[f64] {
        &self.c
    }

    /// Degree (0 for constants, including zero).
    pub fn degree(&self) -> usize {
        self.c.len() - 1
    }

    /// Evaluate at complex `s` (Horner).
    pub fn eval(&self, s: Complex64) -> Complex64 {
        self.c.iter().fold(Complex64::new(0.0, 0.0), |acc, &a| acc * s + a)
    }

    /// Product.
    pub fn mul(&self, o: &Poly) -> Poly {
        let mut r = vec![0.0; self.c.len() + o.c.len() - 1];
        for (i, a) in self.c.iter().enumerate() {
            for (j, b) in o.c.iter().enumerate() {
                if let Some(x) = r.get_mut(i + j) {
                    *x += a * b;
                }
            }
        }
        Poly::new(&r)
    }

    /// Descending coefficients left-padded with zeros to `len` (at least the own length).
    pub fn padded(&self, len: usize) -> Vec<f64> {
        let mut v = vec![0.0; len.saturating_sub(self.c.len())];
        v.extend_from_slice(&self.c);
        v
    }

    /// Sum.
    pub fn add(&self, o: &Poly) -> Poly {
        let n = self.c.len().max(o.c.len());
        let (a, b) = (self.padded(n), o.padded(n));
        Poly::new(&a.iter().zip(&b).map(|(x, y)| x + y).collect::<Vec<_>>())
    }

    /// Multiply by a scalar.
    pub fn scale(&self, k: f64) -> Poly {
        Poly::new(&self.c.iter().map(|x| x * k).collect::<Vec<_>>())
    }

    /// Roots (eigenvalues of the companion matrix, [`crate::eig::eigenvalues`]). A degree-0
    /// polynomial has none; `None` if the eigenvalue iterations do not converge.
    pub fn roots(&self) -> Option<Vec<Complex64>> {
        let n = self.degree();
        if n == 0 {
            return Some(Vec::new());
        }
        let lead = self.c.first().copied().unwrap_or(1.0);
        let mut m = DMatrix::<f64>::zeros(n, n);
        for j in 0..n {
            m[(0, j)] = -self.c.get(j + 1).copied().unwrap_or(0.0) / lead;
        }
        for i in 1..n {
            m[(i, i - 1)] = 1.0;
        }
        crate::eig::eigenvalues(&m)
    }

    /// Largest real part of the roots (−∞ for constants): the stability abscissa (+∞ when
    /// the roots are unknown: not proven stable).
    pub fn max_real_root(&self) -> f64 {
        self.roots().map_or(f64::INFINITY, |r| r.iter().map(|r| r.re).fold(f64::NEG_INFINITY, f64::max))
    }

    /// `q(s) = p(s − σ)`: the roots move right by `σ`, so `q` is Hurwitz iff every root
    /// of `p` has real part below `−σ` (a decay-rate test with the exact Routh/segment tools).
    pub fn shifted(&self, sigma: f64) -> Poly {
        // Horner in the shifted variable: q = (…(a_n·(s − σ) + a_{n−1})·(s − σ) + …) + a_0.
        let x = Poly::new(&[1.0, -sigma]);
        self.c.iter().fold(Poly::new(&[0.0]), |acc, &a| acc.mul(&x).add(&Poly::new(&[a])))
    }

    /// The n×n Hurwitz matrix `H[i][j] = c[2j − i]` (1-based, `c` descending, zero outside
    /// `0..=n`). It is linear in the coefficients; all leading minors positive ⇔ Hurwitz
    /// (for a positive leading coefficient), and `det H = a_0·det H_{n−1}`.
    pub fn hurwitz_matrix(&self) -> DMatrix<f64> {
        let n = self.degree();
        DMatrix::from_fn(n, n, |i, j| {
            let m = 2 * (j + 1) as i64 - (i + 1) as i64;
            usize::try_from(m).ok().and_then(|m| self.c.get(m)).copied().unwrap_or(0.0)
        })
    }

    /// Hurwitz stability by the Routh array (exact for positive leading coefficient; a zero
    /// in the first column counts as not Hurwitz).
    pub fn is_hurwitz_routh(&self) -> bool {
        let sign = if self.c.first().copied().unwrap_or(0.0) < 0.0 { -1.0 } else { 1.0 };
        let c: Vec<f64> = self.c.iter().map(|x| x * sign).collect();
        if c.iter().any(|&x| x <= 0.0) {
            return false; // necessary condition: all coefficients positive
        }
        let mut r0: Vec<f64> = c.iter().step_by(2).copied().collect();
        let mut r1: Vec<f64> = c.iter().skip(1).step_by(2).copied().collect();
        for _ in 0..self.degree() {
            let (Some(&a0), Some(&b0)) = (r0.first(), r1.first()) else { break };
            if b0 <= 0.0 {
                return r1.is_empty() && a0 > 0.0;
            }
            let next: Vec<f64> = (0..r0.len().saturating_sub(1))
                .map(|k| {
                    let a = r0.get(k + 1).copied().unwrap_or(0.0);
                    let b = r1.get(k + 1).copied().unwrap_or(0.0);
                    (b0 * a - a0 * b) / b0
                })
                .collect();
            r0 = r1;
            r1 = next;
            if r1.is_empty() || r1.iter().all(|&x| x == 0.0) {
                return r0.len() == 1 && r0.first().is_some_and(|&x| x > 0.0);
            }
        }
        true
    }
}

/// Is every polynomial of the segment `λ·a + (1 − λ)·b`, λ ∈ [0, 1], Hurwitz?
///
/// Exact test (Bialas 1985): with `a`, `b` Hurwitz of the same degree and positive
/// leading coefficients, the Hurwitz matrix of a member is `λH_a + (1 − λ)H_b`; a root can
/// only leave the left half plane through the imaginary axis, where that matrix is
/// singular, i.e. where `H_a⁻¹H_b` has the eigenvalue `−λ/(1 − λ)` ≤ 0. So the segment is
/// Hurwitz iff the endpoints are and `H_a⁻¹H_b` has no real eigenvalue ≤ 0. A
/// one-parameter family affine in its parameter (a gain `k ∈ [k_lo, k_hi]`) is exactly such
/// a segment. Cross-checked against dense sweeps in the tests.
pub fn segment_is_hurwitz(a: &Poly, b: &Poly) -> bool {
    let same_degree = a.degree() == b.degree() && a.degree() > 0;
    let positive_lead = a.c.first().is_some_and(|&x| x > 0.0) && b.c.first().is_some_and(|&x| x > 0.0);
    if !(same_degree && positive_lead && a.is_hurwitz_routh() && b.is_hurwitz_routh()) {
        return false;
    }
    let Some(m) = a.hurwitz_matrix().lu().solve(&b.hurwitz_matrix()) else {
        return false; // a Hurwitz polynomial has a non-singular Hurwitz matrix
    };
    let scale = m.iter().fold(1.0_f64, |acc, x| acc.max(x.abs()));
    crate::eig::eigenvalues(&m).is_some_and(|e| !e.iter().any(|z| z.im.abs() <= 1e-9 * scale && z.re <= 0.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn roots_of_known_polynomials() {
        // (s + 1)(s + 2)(s² + 2s + 5): roots −1, −2, −1 ± 2j
        let p = Poly::new(&[1.0, 1.0]).mul(&Poly::new(&[1.0, 2.0])).mul(&Poly::new(&[1.0, 2.0, 5.0]));
        let r = p.roots().unwrap();
        assert_eq!(r.len(), 4);
        let want = [
            Complex64::new(-2.0, 0.0),
            Complex64::new(-1.0, -2.0),
            Complex64::new(-1.0, 0.0),
            Complex64::new(-1.0, 2.0),
        ];
        for w in want {
            let nearest = r.iter().map(|z| (z - w).norm()).fold(f64::INFINITY, f64::min);
            assert!(nearest < 1e-9, "{w}: {nearest}");
        }
        assert!(p.is_hurwitz_routh());
        assert!((p.max_real_root() + 1.0).abs() < 1e-9);
    }

    #[test]
    fn routh_agrees_with_roots_on_a_grid() {
        // s³ + a s² + b s + 1 is Hurwitz iff a > 0, b > 0, a·b > 1.
        for a in [-1.0, 0.3, 0.9, 1.1, 2.0] {
            for b in [-0.5, 0.5, 0.95, 1.05, 3.0] {
                let p = Poly::new(&[1.0, a, b, 1.0]);
                let exact = a > 0.0 && b > 0.0 && a * b > 1.0;
                assert_eq!(p.is_hurwitz_routh(), exact, "a={a} b={b}");
                assert_eq!(p.max_real_root() < 0.0, exact, "a={a} b={b}");
            }
        }
    }

    #[test]
    fn degree_15_roots_are_accurate() {
        // ∏ (s + k), k = 1..15: well separated real roots; residual check.
        let mut p = Poly::new(&[1.0]);
        for k in 1..=15 {
            p = p.mul(&Poly::new(&[1.0, f64::from(k)]));
        }
        let r = p.roots().unwrap();
        assert_eq!(r.len(), 15);
        for z in &r {
            // relative residual through the factored form
            let d = (1..=15).map(|k| (z + f64::from(k)).norm()).fold(f64::INFINITY, f64::min);
            assert!(d < 1e-3, "{z}");
        }
    }

    #[test]
    fn trims_and_arithmetic() {
        assert_eq!(Poly::new(&[0.0, 0.0, 1.0, 2.0]).coeffs(), &[1.0, 2.0]);
        assert_eq!(Poly::new(&[0.0]).degree(), 0);
        assert_eq!(Poly::new(&[1.0, 2.0]).add(&Poly::new(&[3.0, 4.0, 5.0])).coeffs(), &[3.0, 5.0, 7.0]);
        assert_eq!(Poly::new(&[1.0, 2.0]).scale(2.0).coeffs(), &[2.0, 4.0]);
    }
    #[test]
    fn shifted_moves_roots_right() {
        // (s + 1)(s + 3) shifted by 2 → (s − 1)(s + 1) = s² − 1
        let q = Poly::new(&[1.0, 4.0, 3.0]).shifted(2.0);
        assert_eq!(q.coeffs(), &[1.0, 0.0, -1.0]);
        assert!(Poly::new(&[1.0, 4.0, 3.0]).shifted(0.9).is_hurwitz_routh());
        assert!(!Poly::new(&[1.0, 4.0, 3.0]).shifted(1.1).is_hurwitz_routh());
    }

    #[test]
    fn hurwitz_matrix_of_a_quartic() {
        // a4 s⁴ + a3 s³ + a2 s² + a1 s + a0 → [[a3, a1, 0, 0], [a4, a2, a0, 0], [0, a3, a1, 0], [0, a4, a2, a0]]
        let h = Poly::new(&[1.0, 2.0, 3.0, 4.0, 5.0]).hurwitz_matrix();
        let want = [[2.0, 4.0, 0.0, 0.0], [1.0, 3.0, 5.0, 0.0], [0.0, 2.0, 4.0, 0.0], [0.0, 1.0, 3.0, 5.0]];
        for (i, row) in want.iter().enumerate() {
            for (j, w) in row.iter().enumerate() {
                assert_eq!(h[(i, j)], *w, "({i}, {j})");
            }
        }
    }

    /// Bialas' segment test against a dense sweep of the segment: random quartic segments
    /// with Hurwitz endpoints, both verdicts must occur and always agree with 2001 members.
    #[test]
    fn segment_test_agrees_with_dense_sweep() {
        let mut rnd = crate::testutil::uniform(7u64);
        // Two lightly damped modes at random frequencies: mixing such endpoints often
        // crosses the imaginary axis, so both verdicts occur.
        let random_hurwitz = |rnd: &mut dyn FnMut() -> f64| {
            let mode = |rnd: &mut dyn FnMut() -> f64| {
                let (w, z) = (0.2 + 5.0 * rnd(), 0.01 + 0.4 * rnd());
                Poly::new(&[1.0, 2.0 * z * w, w * w])
            };
            mode(rnd).mul(&mode(rnd))
        };
        let (mut robust, mut fragile) = (0, 0);
        for _ in 0..300 {
            let (a, b) = (random_hurwitz(&mut rnd), random_hurwitz(&mut rnd));
            let exact = segment_is_hurwitz(&a, &b);
            let swept = (0..=2000).all(|i| {
                let l = f64::from(i) / 2000.0;
                a.scale(l).add(&b.scale(1.0 - l)).is_hurwitz_routh()
            });
            // A sweep can miss an unstable sliver narrower than its step; never the reverse.
            if swept != exact {
                assert!(swept && !exact, "sweep found instability the exact test missed");
                let fine = (0..=200_000).all(|i| {
                    let l = f64::from(i) / 200_000.0;
                    a.scale(l).add(&b.scale(1.0 - l)).is_hurwitz_routh()
                });
                assert!(!fine, "exact test says unstable, 200 001-point sweep finds nothing: {a:?} {b:?}");
            }
            if exact { robust += 1 } else { fragile += 1 }
        }
        assert!(robust > 30 && fragile > 30, "{robust} {fragile}");
    }
}
