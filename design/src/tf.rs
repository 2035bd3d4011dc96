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

impl Tf {
    /// Unit-step response at `n` + 1 instants `0, t_end/n, …, t_end`, exact at the samples:
    /// controllable canonical realisation, discretised with the matrix exponential of
    /// `[[A, B], [0, 0]]·Δt` (zero-order hold is exact for a step). Errors for an improper
    /// or zero-denominator transfer function, or a bad time grid.
    pub fn step_response(&self, t_end_s: f64, n: usize) -> Result<Vec<(f64, f64)>, String> {
        use nalgebra::DMatrix;
        let (den, num) = (self.den.coeffs(), self.num.coeffs());
        let order = self.den.degree();
        let lead = den.first().copied().unwrap_or(0.0);
        if lead == 0.0 || self.num.degree() > order {
            return Err("step response needs a proper transfer function with a non-zero denominator".into());
        }
        if !(t_end_s.is_finite() && t_end_s > 0.0 && n > 0) {
            return Err(format!("step response needs t_end > 0 and n > 0 (got {t_end_s}, {n})"));
        }
        // Ascending, monic: a_0 … a_{order−1}; numerator b_0 … b_order.
        let a: Vec<f64> = den.iter().rev().map(|c| c / lead).collect();
        let b: Vec<f64> = (0..=order)
            .map(|i| num.len().checked_sub(1 + i).and_then(|d| num.get(d)).map_or(0.0, |c| c / lead))
            .collect();
        let d = b.get(order).copied().unwrap_or(0.0);
        if order == 0 {
            return Ok((0..=n).map(|k| (t_end_s * k as f64 / n as f64, d)).collect());
        }
        let c: Vec<f64> = (0..order).map(|i| b[i] - d * a[i]).collect();
        let dt = t_end_s / n as f64;
        // Augmented [[A, B], [0, 0]]: A companion (last row −a), B = e_last.
        let mut m = DMatrix::<f64>::zeros(order + 1, order + 1);
        for i in 0..order - 1 {
            m[(i, i + 1)] = dt;
        }
        for (j, aj) in a.iter().take(order).enumerate() {
            m[(order - 1, j)] = -aj * dt;
        }
        m[(order - 1, order)] = dt;
        let e = m.exp();
        let phi = e.view((0, 0), (order, order)).into_owned();
        let gamma = e.view((0, order), (order, 1)).into_owned();
        let mut x = nalgebra::DVector::<f64>::zeros(order);
        let mut out = Vec::with_capacity(n + 1);
        for k in 0..=n {
            let y = c.iter().zip(x.iter()).map(|(ci, xi)| ci * xi).sum::<f64>() + d;
            out.push((dt * k as f64, y));
            x = &phi * &x + &gamma;
        }
        Ok(out)
    }
}

/// `n` log-spaced frequencies from `lo` to `hi` (rad/s), both included.
pub fn logspace(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    let (a, b) = (lo.ln(), hi.ln());
    (0..n).map(|k| (a + (b - a) * k as f64 / (n.max(2) - 1) as f64).exp()).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn step_responses_match_closed_forms() {
        // 1/(s + 1): 1 − e^{−t}
        let r = Tf::new(&[1.0], &[1.0, 1.0]).step_response(5.0, 50).unwrap();
        for (t, y) in &r {
            assert!((y - (1.0 - (-t).exp())).abs() < 1e-12, "{t} {y}");
        }
        // s/(s² + 2s + 5) (a derivative-type load response like seed 001's): e^{−t} sin(2t)/2
        let r = Tf::new(&[1.0, 0.0], &[1.0, 2.0, 5.0]).step_response(6.0, 600).unwrap();
        for (t, y) in &r {
            assert!((y - (-t).exp() * (2.0 * t).sin() / 2.0).abs() < 1e-12, "{t} {y}");
        }
        // biproper (s + 3)/(s + 1): 3 − 2e^{−t}, starts at the feedthrough 1
        let r = Tf::new(&[1.0, 3.0], &[1.0, 1.0]).step_response(2.0, 20).unwrap();
        for (t, y) in &r {
            assert!((y - (3.0 - 2.0 * (-t).exp())).abs() < 1e-12, "{t} {y}");
        }
        assert!(Tf::new(&[1.0, 0.0, 0.0], &[1.0, 1.0]).step_response(1.0, 10).is_err());
        assert!(Tf::new(&[1.0], &[1.0, 1.0]).step_response(0.0, 10).is_err());
    }
}
