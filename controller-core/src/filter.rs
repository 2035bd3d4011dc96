//! Run-time linear sections in δ-form (see [`crate::discretize`] for the design and why).
//!
//! Second order, observer-canonical in δ = z − 1. With
//! `H(δ) = β0 + (c1 δ + c2)/(δ² + α1 δ + α0)`, `c1 = β1 − β0α1`, `c2 = β2 − β0α0`:
//!
//! ```text
//! y[k]    = w1[k] + β0·x[k]
//! w1[k+1] = w1[k] + (w2[k] − α1·w1[k] + c1·x[k])
//! w2[k+1] = w2[k] + (c2·x[k] − α0·w1[k])
//! ```
//!
//! First order: `H(δ) = β1 + c/(δ + α0)`, `c = β2 − β1α0`: `y = w + β1·x`,
//! `w[k+1] = w[k] + (c·x − α0·w)`.
//!
//! Config (`Copy`, shared by the α and β channels) is apart from state.

use crate::discretize::{ContinuousSection, DeltaCoefficients, DesignError, Discretization};
use crate::num::Scalar;
use num_complex::Complex32;

/// Second-order section configuration in δ-form.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Biquad<T> {
    b0: T,
    c1: T,
    c2: T,
    a1: T,
    a0: T,
}

/// State of a [`Biquad`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BiquadState<T> {
    w1: T,
    w2: T,
}

impl Biquad<f32> {
    /// `1/H(δ)` of the stored coefficients at `delta` = z − 1 (f32, for the drive's slow
    /// step): `(δ² + α1δ + α0) / (β0(δ² + α1δ + α0) + c1δ + c2)`. Its poles are the
    /// section's zeros — ICAD's lag has a double zero at −400 rad/s, inside the unit circle —
    /// so it is finite on the circle unless a zero lies on it (then not finite, which the
    /// drive's caller, `DriveConfig::reference_gain`, replaces by 1).
    pub fn inverse_response(&self, delta: Complex32) -> Complex32 {
        let d = delta * delta + delta * self.a1 + self.a0;
        d / (d * self.b0 + delta * self.c1 + self.c2)
    }
}

impl<T: Scalar> Biquad<T> {
    /// Design from a continuous second-order section.
    pub fn design(
        section: &ContinuousSection,
        ts_s: f64,
        method: Discretization,
    ) -> Result<Self, DesignError> {
        let d = section.to_delta(ts_s, method)?;
        if !d.second_order {
            return Err(DesignError::Coefficient);
        }
        Ok(Self::from_delta(&d))
    }

    /// Round δ-form coefficients (computed in f64) to `T`.
    pub fn from_delta(d: &DeltaCoefficients) -> Self {
        let [b0, b1, b2] = d.num;
        let [_, a1, a0] = d.den;
        Self {
            b0: T::from_f64(b0),
            c1: T::from_f64(b1 - b0 * a1),
            c2: T::from_f64(b2 - b0 * a0),
            a1: T::from_f64(a1),
            a0: T::from_f64(a0),
        }
    }

    /// The δ-form coefficients actually stored (after rounding to `T`), for analysis.
    pub fn coefficients(&self) -> DeltaCoefficients {
        let (b0, c1, c2, a1, a0) =
            (self.b0.to_f64(), self.c1.to_f64(), self.c2.to_f64(), self.a1.to_f64(), self.a0.to_f64());
        DeltaCoefficients { second_order: true, num: [b0, c1 + b0 * a1, c2 + b0 * a0], den: [1.0, a1, a0] }
    }

    /// One sample: returns `y[k]` and advances the state.
    #[inline]
    pub fn update(&self, s: &mut BiquadState<T>, x: T) -> T {
        let y = s.w1 + self.b0 * x;
        let w1 = s.w1;
        s.w1 = w1 + (s.w2 - self.a1 * w1 + self.c1 * x);
        s.w2 = s.w2 + (self.c2 * x - self.a0 * w1);
        y
    }
}

/// First-order section configuration in δ-form.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FirstOrder<T> {
    b1: T,
    c: T,
    a0: T,
}

/// State of a [`FirstOrder`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FirstOrderState<T> {
    w: T,
}

impl<T: Scalar> FirstOrder<T> {
    /// Design from a continuous first-order section.
    pub fn design(
        section: &ContinuousSection,
        ts_s: f64,
        method: Discretization,
    ) -> Result<Self, DesignError> {
        let d = section.to_delta(ts_s, method)?;
        if d.second_order {
            return Err(DesignError::Coefficient);
        }
        let [_, b1, b2] = d.num;
        let a0 = d.den[2];
        Ok(Self { b1: T::from_f64(b1), c: T::from_f64(b2 - b1 * a0), a0: T::from_f64(a0) })
    }

    /// Unity-DC-gain low-pass `ω_c/(s + ω_c)`.
    pub fn low_pass(corner_rad_s: f64, ts_s: f64) -> Result<Self, DesignError> {
        if !(corner_rad_s.is_finite() && corner_rad_s > 0.0) {
            return Err(DesignError::Coefficient);
        }
        let lp = ContinuousSection { num: [0.0, 0.0, corner_rad_s], den: [0.0, 1.0, corner_rad_s] };
        Self::design(&lp, ts_s, Discretization::Tustin)
    }

    /// One sample.
    #[inline]
    pub fn update(&self, s: &mut FirstOrderState<T>, x: T) -> T {
        let y = s.w + self.b1 * x;
        s.w = s.w + (self.c * x - self.a0 * s.w);
        y
    }
}

/// `b0`, `c1`, `c2`, `a1`, `a0`.
impl crate::raw::Field for Biquad<f32> {
    const NF: usize = <[f32; 5] as crate::raw::Field>::NF;
    const NU: usize = 0;

    fn put(&self, w: &mut crate::raw::Writer) {
        [self.b0, self.c1, self.c2, self.a1, self.a0].put(w);
    }

    #[inline(always)]
    fn get(r: &mut crate::raw::Reader<'_>) -> Self {
        let [b0, c1, c2, a1, a0] = <[f32; 5]>::get(r);
        Self { b0, c1, c2, a1, a0 }
    }
}

impl Biquad<f32> {
    /// All-zero coefficients (the raw form's filler for a missing section).
    pub(crate) fn zero() -> Self {
        Self { b0: 0.0, c1: 0.0, c2: 0.0, a1: 0.0, a0: 0.0 }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::discretize::Complex;
    use crate::num::Q32;

    pub const TS: f64 = 1.0 / 20_000.0;
    pub const LAG: ContinuousSection =
        ContinuousSection::biquad([1.0, 800.0, 160_000.0], [1.0, 100.0, 42_500.0]);

    /// Direct form II transposed in z, the textbook realisation, kept here only as the
    /// baseline of the precision analysis.
    struct Df2t {
        b: [f32; 3],
        a: [f32; 3],
        s1: f32,
        s2: f32,
    }
    impl Df2t {
        fn update(&mut self, x: f32) -> f32 {
            let [b0, b1, b2] = self.b;
            let [_, a1, a2] = self.a;
            let y = b0 * x + self.s1;
            self.s1 = b1 * x - a1 * y + self.s2;
            self.s2 = b2 * x - a2 * y;
            y
        }
    }

    fn df_response(b: [f64; 3], a: [f64; 3], w: f64) -> Complex {
        let zi = Complex::new(libm::cos(w * TS), -libm::sin(w * TS));
        let n = Complex::new(b[0], 0.0) + zi * b[1] + zi * zi * b[2];
        let d = Complex::new(a[0], 0.0) + zi * a[1] + zi * zi * a[2];
        n / d
    }

    /// Steady-state gain of a filter driven by a constant, measured in time.
    fn dc_gain_in_time(mut step: impl FnMut(f32) -> f32) -> f64 {
        let mut y = 0.0;
        for _ in 0..80_000 {
            y = step(1.0);
        }
        f64::from(y)
    }

    /// Coefficient precision: f32 rounding of the δ-form keeps the DC gain within 1e-6
    /// relative; the same rounding applied to direct-form z coefficients errs by ≥ 1e-4.
    #[test]
    fn coefficient_precision_delta_vs_direct_form() {
        let ideal = 160_000.0 / 42_500.0;
        let d = LAG.to_delta(TS, Discretization::Tustin).unwrap();
        let bq = Biquad::<f32>::from_delta(&d);
        let delta_err = (bq.coefficients().response(1e-6, TS).re - ideal).abs() / ideal;
        let (b, a) = d.to_z();
        let r = |x: [f64; 3]| x.map(|c| f64::from(c as f32));
        let df_err = (df_response(r(b), r(a), 1e-6).norm() - ideal).abs() / ideal;
        eprintln!("DC gain error with f32 coefficients: δ-form {delta_err:.2e}, direct form {df_err:.2e}");
        assert!(delta_err < 1e-6);
        assert!(df_err > 1e-4, "direct-form rounding error unexpectedly small: {df_err}");
    }

    /// State precision in time: run both realisations in f32 to steady state.
    #[test]
    fn state_precision_delta_vs_direct_form_in_time() {
        let ideal = 160_000.0 / 42_500.0;
        let d = LAG.to_delta(TS, Discretization::Tustin).unwrap();
        let bq = Biquad::<f32>::from_delta(&d);
        let mut s = BiquadState::default();
        let delta = dc_gain_in_time(|x| bq.update(&mut s, x));
        let (b, a) = d.to_z();
        let mut df = Df2t { b: b.map(|c| c as f32), a: a.map(|c| c as f32), s1: 0.0, s2: 0.0 };
        let direct = dc_gain_in_time(|x| df.update(x));
        let (e_delta, e_direct) = ((delta - ideal).abs() / ideal, (direct - ideal).abs() / ideal);
        eprintln!("steady-state gain error in f32 time run: δ-form {e_delta:.2e}, DF-IIt {e_direct:.2e}");
        assert!(e_delta < 2e-5, "δ-form {e_delta}");
        assert!(e_direct > 5.0 * e_delta, "DF-IIt {e_direct} not worse than δ-form {e_delta}");
    }

    /// The Q32 configuration tracks f64 within 1e-6 relative on a long random-ish input.
    #[test]
    fn q32_lag_section_agrees_with_f64() {
        let d = LAG.to_delta(TS, Discretization::Tustin).unwrap();
        let (b64, bq) = (Biquad::<f64>::from_delta(&d), Biquad::<Q32>::from_delta(&d));
        let (mut s64, mut sq) = (BiquadState::default(), BiquadState::default());
        let mut max_err = 0.0f64;
        let mut x = 0.3f64;
        for k in 0..100_000 {
            // deterministic pseudo-random piecewise-constant input in [-10, 10]
            if k % 97 == 0 {
                x = libm::sin(k as f64 * 12.9898) * 10.0;
            }
            let y64 = b64.update(&mut s64, x);
            let yq = bq.update(&mut sq, Q32::from_f64(x)).to_f64();
            max_err = max_err.max((y64 - yq).abs());
        }
        eprintln!("Q32 lag section max |error| vs f64: {max_err:.2e} (input ±10)");
        assert!(max_err < 1e-5);
    }

    /// A 16.16 format is not enough for this section: its DC gain error exceeds 1 %.
    #[test]
    fn q16_16_is_too_coarse_for_the_lag_section() {
        let d = LAG.to_delta(TS, Discretization::Tustin).unwrap();
        let q16 = |c: f64| (c * 65536.0).round() / 65536.0;
        let rounded = DeltaCoefficients { second_order: true, num: d.num.map(q16), den: d.den.map(q16) };
        let ideal = 160_000.0 / 42_500.0;
        let err = (rounded.response(1e-6, TS).norm() - ideal).abs() / ideal;
        eprintln!("DC gain error with 16 fractional bits: {err:.2e}");
        assert!(err > 1e-2);
    }

    #[test]
    fn first_order_low_pass_step() {
        // 100 rad/s low-pass: after 10 ms (one time constant) y ≈ 1 − e⁻¹.
        let lp = FirstOrder::<f32>::low_pass(100.0, TS).unwrap();
        let mut s = FirstOrderState::default();
        let mut y = 0.0;
        for _ in 0..200 {
            y = lp.update(&mut s, 1.0);
        }
        assert!((f64::from(y) - (1.0 - libm::exp(-1.0))).abs() < 2e-3, "{y}");
    }
}
