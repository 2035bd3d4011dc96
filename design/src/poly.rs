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

    /// Sum.
    pub fn add(&self, o: &Poly) -> Poly {
        let n = self.c.len().max(o.c.len());
        let pad = |p: &Poly| -> Vec<f64> {
            let mut v = vec![0.0; n - p.c.len()];
            v.extend_from_slice(&p.c);
            v
        };
        let (a, b) = (pad(self), pad(o));
        Poly::new(&a.iter().zip(&b).map(|(x, y)| x + y).collect::<Vec<_>>())
    }

    /// Multiply by a scalar.
    pub fn scale(&self, k: f64) -> Poly {
        Poly::new(&self.c.iter().map(|x| x * k).collect::<Vec<_>>())
    }

    /// Roots (eigenvalues of the companion matrix). A degree-0 polynomial has none.
    pub fn roots(&self) -> Vec<Complex64> {
        let n = self.degree();
        if n == 0 {
            return Vec::new();
        }
        let lead = self.c.first().copied().unwrap_or(1.0);
        let mut m = DMatrix::<f64>::zeros(n, n);
        for j in 0..n {
            m[(0, j)] = -self.c.get(j + 1).copied().unwrap_or(0.0) / lead;
        }
        for i in 1..n {
            m[(i, i - 1)] = 1.0;
        }
        m.complex_eigenvalues().iter().copied().collect()
    }

    /// Largest real part of the roots (−∞ for constants): the stability abscissa.
    pub fn max_real_root(&self) -> f64 {
        self.roots().iter().map(|r| r.re).fold(f64::NEG_INFINITY, f64::max)
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn roots_of_known_polynomials() {
        // (s + 1)(s + 2)(s² + 2s + 5): roots −1, −2, −1 ± 2j
        let p = Poly::new(&[1.0, 1.0]).mul(&Poly::new(&[1.0, 2.0])).mul(&Poly::new(&[1.0, 2.0, 5.0]));
        let r = p.roots();
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
        let r = p.roots();
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
}
