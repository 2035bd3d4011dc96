//! Rational transfer functions `num(s)/den(s)`.

use crate::poly::Poly;
use num_complex::Complex64;

/// `num(s)/den(s)`.
#[derive(Clone, Debug, PartialEq)]
pub struct Tf {
    /// Numerator.
    pub num: Poly,
    /// Denominator.
    pub den: Poly,
}

impl Tf {
    /// From descending coefficients.
    pub fn new(num: &[f64], den: &[f64]) -> Self {
        Self { num: Poly::new(num), den: Poly::new(den) }
    }

    /// Frequency response at `s = jω`.
    pub fn response(&self, omega_rad_s: f64) -> Complex64 {
        let s = Complex64::new(0.0, omega_rad_s);
        self.num.eval(s) / self.den.eval(s)
    }
}

/// `n` log-spaced frequencies from `lo` to `hi` (rad/s), both included.
pub fn logspace(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    let (a, b) = (lo.ln(), hi.ln());
    (0..n).map(|k| (a + (b - a) * k as f64 / (n.max(2) - 1) as f64).exp()).collect()
}
