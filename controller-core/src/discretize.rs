//! Continuous → discrete design, done once at construction time in `f64`.
//!
//! **Method: Tustin** (bilinear) `s ← K·(z − 1)/(z + 1)` with `K = 2/T`, or with frequency
//! prewarping at ω₀: `K = ω₀ / tan(ω₀T/2)`, which makes the discrete response equal the
//! continuous one exactly at ω₀.
//!
//! **Realisation: δ-form.** Coefficients are expressed in the increment operator
//! `δ = z − 1` instead of `z`. At 20 kHz the ICAD lag poles (−50 ± j200 rad/s) sit at
//! |z| ≈ 0.9975, and the direct-form denominator `z² + a₁z + a₂` has `a₁ ≈ −1.995`,
//! `a₂ ≈ 0.995` whose sum `1 + a₁ + a₂ ≈ 1.06e-4` sets the DC gain: rounding `a₁, a₂` to
//! f32 (ulp ≈ 1.2e-7) moves it by ~0.1 %, and the direct form amplifies state round-off by
//! `1/(1 + a₁ + a₂)`. In δ-form the same denominator is `δ² + α₁δ + α₀` with `α₁ = 2 + a₁`,
//! `α₀ = 1 + a₁ + a₂` computed *analytically* (no cancellation) and stored with full
//! relative precision, and states are updated by small increments. The precision analysis
//! (tests in [`crate::filter`]) measures both realisations in f32.
//!
//! Substituting `z − 1 = δ`, `z + 1 = δ + 2` into `n₂s² + n₁s + n₀`:
//! `(n₂K² + n₁K + n₀)δ² + (2n₁K + 4n₀)δ + 4n₀` (and likewise for the denominator).

use core::f64::consts::PI;

/// How `s` is mapped to `z`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Discretization {
    /// Plain Tustin, `K = 2/T`.
    Tustin,
    /// Tustin prewarped to match the continuous response exactly at `omega_rad_s`.
    TustinPrewarped {
        /// Match frequency ω₀ in rad/s; must be in `(0, π/T)`.
        omega_rad_s: f64,
    },
}

/// tan x on [0, π/2) by Lambert's continued fraction
/// `tan x = x/(1 − x²/(3 − x²/(5 − …)))`, evaluated bottom-up from 30 terms: within a few
/// ulp of `libm::tan` there (test `tan_matches_libm`), and a few hundred bytes of soft-double
/// code on the target where `libm::tan` with its argument reduction is ≈ 5 KiB of flash.
fn tan_half_range(x: f64) -> f64 {
    let x2 = x * x;
    let mut d = 61.0; // 2·30 + 1
    let mut k = 59.0;
    while k > 0.0 {
        d = k - x2 / d;
        k -= 2.0;
    }
    x / d
}

/// Errors of the design step.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DesignError {
    /// Sample period not finite and positive.
    SamplePeriod,
    /// Prewarp frequency not in `(0, Nyquist)`.
    PrewarpFrequency,
    /// A coefficient is not finite, or the leading denominator coefficient is zero.
    Coefficient,
}

impl core::fmt::Display for DesignError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::SamplePeriod => "the sample period is not finite and positive",
            Self::PrewarpFrequency => "the prewarp frequency is not between 0 and the Nyquist frequency",
            Self::Coefficient => "a coefficient is not finite, or the leading denominator coefficient is 0",
        })
    }
}

impl Discretization {
    /// The Tustin constant `K` for sample period `ts_s`.
    pub fn k(self, ts_s: f64) -> Result<f64, DesignError> {
        if !(ts_s.is_finite() && ts_s > 0.0) {
            return Err(DesignError::SamplePeriod);
        }
        match self {
            Discretization::Tustin => Ok(2.0 / ts_s),
            Discretization::TustinPrewarped { omega_rad_s: w } => {
                if !(w.is_finite() && w > 0.0 && w * ts_s < PI) {
                    return Err(DesignError::PrewarpFrequency);
                }
                Ok(w / tan_half_range(w * ts_s / 2.0))
            }
        }
    }
}

/// Continuous second-order section `(n2·s² + n1·s + n0)/(d2·s² + d1·s + d0)`.
/// A first-order section has `n2 = d2 = 0`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContinuousSection {
    /// Numerator `[n2, n1, n0]`.
    pub num: [f64; 3],
    /// Denominator `[d2, d1, d0]`.
    pub den: [f64; 3],
}

impl ContinuousSection {
    /// `(s + z1)(s + z2)/(s² + d1 s + d0)` with unit high-frequency gain.
    pub const fn biquad(num: [f64; 3], den: [f64; 3]) -> Self {
        Self { num, den }
    }

    /// Evaluate at `s = jω`.
    pub fn response(&self, omega_rad_s: f64) -> Complex {
        let s = Complex::new(0.0, omega_rad_s);
        let [n2, n1, n0] = self.num;
        let [d2, d1, d0] = self.den;
        let n = s * s * n2 + s * n1 + Complex::new(n0, 0.0);
        let d = s * s * d2 + s * d1 + Complex::new(d0, 0.0);
        n / d
    }

    /// Second order (`d2 ≠ 0`) or first order.
    pub fn is_second_order(&self) -> bool {
        self.den[0] != 0.0 || self.num[0] != 0.0
    }

    /// Tustin → δ-form coefficients, normalised so the leading denominator coefficient is 1.
    pub fn to_delta(&self, ts_s: f64, method: Discretization) -> Result<DeltaCoefficients, DesignError> {
        let k = method.k(ts_s)?;
        if !self.num.iter().chain(self.den.iter()).all(|c| c.is_finite()) {
            return Err(DesignError::Coefficient);
        }
        let map = |[c2, c1, c0]: [f64; 3]| {
            if self.is_second_order() {
                // (c2K² + c1K + c0)δ² + (2c1K + 4c0)δ + 4c0
                [c2 * k * k + c1 * k + c0, 2.0 * c1 * k + 4.0 * c0, 4.0 * c0]
            } else {
                // first order: c1·K·δ + c0·(δ + 2) = (c1K + c0)δ + 2c0
                [0.0, c1 * k + c0, 2.0 * c0]
            }
        };
        let n = map(self.num);
        let d = map(self.den);
        let lead = if self.is_second_order() { d[0] } else { d[1] };
        if lead == 0.0 || !lead.is_finite() {
            return Err(DesignError::Coefficient);
        }
        Ok(DeltaCoefficients {
            second_order: self.is_second_order(),
            num: [n[0] / lead, n[1] / lead, n[2] / lead],
            den: [d[0] / lead, d[1] / lead, d[2] / lead],
        })
    }
}

/// Discrete section in δ = z − 1: `(β0 δ² + β1 δ + β2)/(δ² + α1 δ + α0)` for second order,
/// `(β1 δ + β2)/(δ + α0)` for first order (then `num[0] = den[0] = 0`, `den[1] = 1`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DeltaCoefficients {
    /// Second order?
    pub second_order: bool,
    /// `[β0, β1, β2]`.
    pub num: [f64; 3],
    /// `[1, α1, α0]` (second order) or `[0, 1, α0]` (first order).
    pub den: [f64; 3],
}

impl DeltaCoefficients {
    /// Frequency response at ω for sample period `ts_s`: evaluates at `δ = e^{jωT} − 1`,
    /// written as `2j·sin(ωT/2)·e^{jωT/2}` to keep full precision at low ω.
    pub fn response(&self, omega_rad_s: f64, ts_s: f64) -> Complex {
        let delta = delta_at(omega_rad_s, ts_s);
        let [n2, n1, n0] = self.num;
        let [d2, d1, d0] = self.den;
        let n = delta * delta * n2 + delta * n1 + Complex::new(n0, 0.0);
        let d = delta * delta * d2 + delta * d1 + Complex::new(d0, 0.0);
        n / d
    }

    /// The equivalent direct-form z-domain coefficients `([b0, b1, b2], [1, a1, a2])` of
    /// `(b0 + b1 z⁻¹ + b2 z⁻²)/(1 + a1 z⁻¹ + a2 z⁻²)` (second order only; used to compare
    /// realisations).
    pub fn to_z(&self) -> ([f64; 3], [f64; 3]) {
        // β0 δ² + β1 δ + β2 with δ = z − 1: β0 z² + (β1 − 2β0) z + (β0 − β1 + β2).
        let z = |[c2, c1, c0]: [f64; 3]| [c2, c1 - 2.0 * c2, c2 - c1 + c0];
        (z(self.num), z(self.den))
    }
}

/// `δ = e^{jωT} − 1`.
pub fn delta_at(omega_rad_s: f64, ts_s: f64) -> Complex {
    let half = omega_rad_s * ts_s / 2.0;
    let (s, c) = (libm::sin(half), libm::cos(half));
    // 2j·sin(h)·(cos h + j sin h) = −2 sin² h + j 2 sin h cos h
    Complex::new(-2.0 * s * s, 2.0 * s * c)
}

/// Complex number of the frequency responses: `num_complex::Complex64` (no_std, `libm`), the
/// same type the design toolkit computes with.
pub type Complex = num_complex::Complex64;

#[cfg(test)]
mod tests {
    use super::*;

    const TS: f64 = 1.0 / 20_000.0;
    const LAG: ContinuousSection = ContinuousSection::biquad([1.0, 800.0, 160_000.0], [1.0, 100.0, 42_500.0]);

    #[test]
    fn delta_coefficients_match_the_paper_pole_radius() {
        let d = LAG.to_delta(TS, Discretization::Tustin).unwrap();
        let (_, a) = d.to_z();
        // Poles of z² + a1 z + a2 are complex: |z|² = a2. Independent value: the bilinear
        // image of s = −50 ± j200, |(2/T + s)/(2/T − s)|.
        let s = Complex::new(-50.0, 200.0);
        let k = Complex::new(2.0 / TS, 0.0);
        let zp = (k + s) / (k - s);
        assert!((libm::sqrt(a[2]) - zp.norm()).abs() < 1e-12);
        assert!((zp.norm() - 0.9975).abs() < 1e-4);
        // α0 = 1 + a1 + a2 computed analytically equals the z-form sum.
        assert!((d.den[2] - (1.0 + a[1] + a[2])).abs() < 1e-15);
    }

    #[test]
    fn tustin_is_exact_at_dc_and_prewarp_is_exact_at_its_frequency() {
        let d = LAG.to_delta(TS, Discretization::Tustin).unwrap();
        let dc = d.response(1e-9, TS);
        assert!((dc.re - 160_000.0 / 42_500.0).abs() < 1e-9);
        let w0 = 3000.0;
        let p = LAG.to_delta(TS, Discretization::TustinPrewarped { omega_rad_s: w0 }).unwrap();
        let err = (p.response(w0, TS) - LAG.response(w0)).norm() / LAG.response(w0).norm();
        assert!(err < 1e-12, "prewarped error at ω0: {err}");
    }

    /// Against `libm::tan` on [0, π/2): relative error within 8 ulp times tan's condition
    /// number x·(tan x + cot x) (which grows without bound towards π/2, where any f64
    /// evaluation of tan loses digits); ≤ 2e-15 for x ≤ 1.4 (prewarp below 0.89 × Nyquist).
    #[test]
    fn tan_matches_libm() {
        let mut worst_low = 0.0f64;
        for i in 1..=10_000 {
            let x = (core::f64::consts::FRAC_PI_2 - 1e-4) * f64::from(i) / 10_000.0;
            let (a, b) = (tan_half_range(x), libm::tan(x));
            let rel = ((a - b) / b).abs();
            let cond = x * (b + 1.0 / b);
            assert!(rel <= 8.0 * f64::EPSILON * cond, "x = {x}: {rel:e} (cond {cond})");
            if x <= 1.4 {
                worst_low = worst_low.max(rel);
            }
        }
        assert!(worst_low <= 2e-15, "{worst_low:e}");
        assert_eq!(tan_half_range(0.0), 0.0);
    }

    #[test]
    fn first_order_section() {
        // Low-pass 100/(s + 100): DC gain 1, pole at z = (K − 100)/(K + 100).
        let lp = ContinuousSection { num: [0.0, 0.0, 100.0], den: [0.0, 1.0, 100.0] };
        let d = lp.to_delta(TS, Discretization::Tustin).unwrap();
        assert!(!d.second_order);
        assert!((d.response(1e-9, TS).re - 1.0).abs() < 1e-9);
        let k = 2.0 / TS;
        assert!((d.den[2] - (1.0 - (k - 100.0) / (k + 100.0))).abs() < 1e-15);
    }

    #[test]
    fn invalid_design_inputs_are_errors() {
        assert_eq!(LAG.to_delta(0.0, Discretization::Tustin), Err(DesignError::SamplePeriod));
        assert_eq!(
            LAG.to_delta(TS, Discretization::TustinPrewarped { omega_rad_s: 1e6 }),
            Err(DesignError::PrewarpFrequency)
        );
        let bad = ContinuousSection { num: [1.0, 0.0, f64::NAN], den: [1.0, 1.0, 1.0] };
        assert_eq!(bad.to_delta(TS, Discretization::Tustin), Err(DesignError::Coefficient));
    }
}
