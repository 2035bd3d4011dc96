//! Reference frames and their transforms (f32 on the control path; the Clarke pair is
//! generic over [`Scalar`], so the simulator's f64 plant side uses the same transform).
//!
//! * [`Abc`] — phase quantities.
//! * [`AlphaBeta`] — stationary two-axis frame, **amplitude-invariant** Clarke transform: a
//!   balanced set of phase peak amplitude `A` maps to a vector of magnitude `A`.
//! * [`Dq`] — frame rotating with the electrical angle θe (d on the rotor flux in IFOC).
//!
//! Angle policy: electrical angles wrap into `[-π, π)` ([`wrap_angle`]); nothing else wraps.

use crate::num::Scalar;
use core::f32::consts::{PI, TAU};

/// 1/√3 (rounds to 0.577_350_26 in f32).
pub(crate) const INV_SQRT3: f64 = 0.577_350_269_189_625_8;
/// √3/2 (rounds to 0.866_025_4 in f32).
const SQRT3_2: f64 = 0.866_025_403_784_438_6;

/// Three phase quantities (currents in A, voltages in V, or duty cycles); f32 unless the
/// simulator's f64.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Abc<T = f32> {
    /// Phase a.
    pub a: T,
    /// Phase b.
    pub b: T,
    /// Phase c.
    pub c: T,
}

/// Stationary-frame vector.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AlphaBeta<T = f32> {
    /// α component (aligned with phase a).
    pub alpha: T,
    /// β component (leads α by 90°).
    pub beta: T,
}

/// Rotating-frame vector.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Dq {
    /// Direct (flux) axis.
    pub d: f32,
    /// Quadrature (torque) axis.
    pub q: f32,
}

/// sin and cos of one angle, computed once and shared by Park and inverse Park.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SinCos {
    /// sin θ.
    pub sin: f32,
    /// cos θ.
    pub cos: f32,
}

impl Default for SinCos {
    /// θ = 0.
    fn default() -> Self {
        Self { sin: 0.0, cos: 1.0 }
    }
}

impl SinCos {
    /// sin and cos of `theta_rad`, in f32 arithmetic only (no f64, no table), for the
    /// control path: the field angle (the IFOC recomputes its field with it at every slow step and
    /// turns it in between, [`SinCos::then`]).
    ///
    /// `libm::sincosf` evaluates its kernels in f64, which a Cortex-M4F does in software:
    /// ≈ 2 800 instructions per call (measured, `qemu-target` `cost`). Here: quadrant
    /// reduction `r = θ − k·π/2` with π/2 split in two f32 parts (Cody–Waite, exact for
    /// |k| ≤ 2^7), then the Cephes single-precision minimax polynomials on |r| ≤ π/4
    /// (sin: degree 7, cos: degree 8; relative error ≲ 3e-8) — about 40 instructions.
    /// Absolute error ≤ 1.2e-7 for |θ| ≤ 100 rad (tests; `selftest::sincos_accuracy` on
    /// the target), which includes the f32 rounding of θ itself. Larger angles lose accuracy
    /// with the reduction: the drive always passes a wrapped angle. Non-finite θ gives NaN.
    /// Out of line: no fast step of the drive calls it, and its callers' copies took 580 B
    /// of flash.
    #[inline(never)]
    pub fn new(theta_rad: f32) -> Self {
        const FRAC_2_PI: f32 = core::f32::consts::FRAC_2_PI;
        // π/2 = PIO2_HI + PIO2_LO (to 1.7e-13); PIO2_HI has 7 trailing zero bits, so k·PIO2_HI
        // is exact for |k| ≤ 2^7.
        const PIO2_HI: f32 = 1.570_785_5;
        const PIO2_LO: f32 = 1.080_433_4e-5;
        // Adding 1.5·2^23 rounds |y| < 2^22 to the nearest integer k (ties to even), which
        // then sits in the low mantissa bits of the sum: k mod 4 is the quadrant. Two adds
        // instead of a float → int → float round trip; NaN and ±∞ stay NaN through r.
        const ROUND: f32 = 12_582_912.0;
        let y = theta_rad * FRAC_2_PI;
        let shifted = y + ROUND;
        let kf = shifted - ROUND;
        let quadrant = shifted.to_bits() & 3;
        let r = (theta_rad - kf * PIO2_HI) - kf * PIO2_LO;
        let z = r * r;
        let sin_r = r + r * z * ((-1.951_529_6e-4 * z + 8.332_161e-3) * z - 1.666_665_5e-1);
        let cos_r = 1.0 - 0.5 * z + z * z * ((2.443_315_7e-5 * z - 1.388_731_6e-3) * z + 4.166_664_6e-2);
        // Quadrant q: (sin, cos) = (sin r, cos r), (cos r, −sin r), (−sin r, −cos r),
        // (−cos r, sin r) for q = 0..3 — swap on odd q, sign bits from q's second bit.
        let (s, c) = if quadrant & 1 == 0 { (sin_r, cos_r) } else { (cos_r, sin_r) };
        let sin = f32::from_bits(s.to_bits() ^ ((quadrant & 2) << 30));
        let cos = f32::from_bits(c.to_bits() ^ (((quadrant + 1) & 2) << 30));
        Self { sin, cos }
    }
}

impl SinCos {
    /// Largest angle step `|δ|` for which [`SinCos::rotated`] keeps its accuracy, rad.
    pub const MAX_ROTATION_RAD: f32 = 0.1;

    /// sin and cos of θ + δ from those of θ, by rotating the unit vector through δ:
    /// `sin(θ+δ) = sin θ·cos δ + cos θ·sin δ`, `cos(θ+δ) = cos θ·cos δ − sin θ·sin δ`, with
    /// `sin δ ≈ δ(1 − δ²/6·(1 − δ²/20))` and `cos δ ≈ 1 − δ²/2·(1 − δ²/12)`. Truncation for
    /// `|δ| ≤` [`SinCos::MAX_ROTATION_RAD`]: ≤ δ⁷/5040 = 2e-11 (sin) and δ⁶/720 = 1.4e-9
    /// (cos), below the f32 rounding of each rotation (a few 1e-8). 16 operations, against
    /// ≈ 30 for [`SinCos::new`] (the drive's delay advance, turned from θ = 0).
    #[inline]
    pub fn rotated(self, delta_rad: f32) -> Self {
        let d2 = delta_rad * delta_rad;
        let sin_d = delta_rad - delta_rad * d2 * ((1.0 / 6.0) - d2 * (1.0 / 120.0));
        let cos_d = 1.0 - d2 * (0.5 - d2 * (1.0 / 24.0));
        Self { sin: self.sin * cos_d + self.cos * sin_d, cos: self.cos * cos_d - self.sin * sin_d }
    }
}

impl SinCos {
    /// sin and cos of the sum of the two angles (this one turned by `r`'s): four products.
    /// The rounding adds up from turn to turn (≈ 1e-7 each): a caller turning repeatedly
    /// recomputes with [`SinCos::new`] now and then (the IFOC at every slow step).
    #[inline]
    pub fn then(self, r: SinCos) -> Self {
        Self { sin: self.sin * r.cos + self.cos * r.sin, cos: self.cos * r.cos - self.sin * r.sin }
    }
}

impl Abc {
    /// All three elements finite.
    #[inline]
    pub fn is_finite(&self) -> bool {
        self.a.is_finite() && self.b.is_finite() && self.c.is_finite()
    }
}

impl<T: Scalar> Abc<T> {
    /// Amplitude-invariant Clarke transform using all three phases:
    /// α = (2a − b − c)/3, β = (b − c)/√3. A zero-sequence component is discarded.
    #[inline]
    pub fn clarke(self) -> AlphaBeta<T> {
        // k = 1 folds away: the same operations as the transform written out.
        self.clarke_scaled(T::from_f64(1.0))
    }

    /// [`Abc::clarke`] of `k`·(a, b, c), with `k` joining the constants: α = (2a − b − c)·(k/3),
    /// β = (b − c)·(k/√3). Multiplications, not divisions; the simulator's inverter takes
    /// `k = V_dc` for duties, one operation fewer on its critical path than scaling after.
    #[inline]
    pub fn clarke_scaled(self, k: T) -> AlphaBeta<T> {
        AlphaBeta {
            alpha: (T::from_f64(2.0) * self.a - self.b - self.c) * (k * T::from_f64(1.0 / 3.0)),
            beta: (self.b - self.c) * (k * T::from_f64(INV_SQRT3)),
        }
    }
}

impl<T: Scalar> AlphaBeta<T> {
    /// Inverse amplitude-invariant Clarke: a = α, b = −α/2 + (√3/2)β, c = −α/2 − (√3/2)β.
    #[inline]
    pub fn inverse_clarke(self) -> Abc<T> {
        let (half, s) = (T::from_f64(-0.5), T::from_f64(SQRT3_2));
        Abc { a: self.alpha, b: half * self.alpha + s * self.beta, c: half * self.alpha - s * self.beta }
    }
}

impl AlphaBeta {
    /// Park transform into the frame at angle θ: d = α cos θ + β sin θ, q = −α sin θ + β cos θ.
    #[inline]
    pub fn park(self, sc: SinCos) -> Dq {
        Dq { d: self.alpha * sc.cos + self.beta * sc.sin, q: -self.alpha * sc.sin + self.beta * sc.cos }
    }

    /// The vector turned by the angle whose sin and cos are `sc` (counter-clockwise).
    #[inline]
    pub fn rotate(self, sc: SinCos) -> AlphaBeta {
        AlphaBeta {
            alpha: self.alpha * sc.cos - self.beta * sc.sin,
            beta: self.alpha * sc.sin + self.beta * sc.cos,
        }
    }

    /// Euclidean magnitude.
    #[inline]
    pub fn magnitude(self) -> f32 {
        crate::num::sqrt_f32(self.alpha * self.alpha + self.beta * self.beta)
    }

    /// Multiply both components by `k`.
    #[inline]
    pub fn scale(self, k: f32) -> AlphaBeta {
        AlphaBeta { alpha: self.alpha * k, beta: self.beta * k }
    }
}

impl core::ops::Add for AlphaBeta {
    type Output = AlphaBeta;
    /// Component-wise sum.
    #[inline]
    fn add(self, other: AlphaBeta) -> AlphaBeta {
        AlphaBeta { alpha: self.alpha + other.alpha, beta: self.beta + other.beta }
    }
}

impl core::ops::Sub for AlphaBeta {
    type Output = AlphaBeta;
    /// Component-wise difference.
    #[inline]
    fn sub(self, other: AlphaBeta) -> AlphaBeta {
        AlphaBeta { alpha: self.alpha - other.alpha, beta: self.beta - other.beta }
    }
}

impl core::ops::AddAssign for Dq {
    /// Component-wise sum.
    #[inline]
    fn add_assign(&mut self, other: Dq) {
        (self.d, self.q) = (self.d + other.d, self.q + other.q);
    }
}

impl Dq {
    /// Inverse Park: α = d cos θ − q sin θ, β = d sin θ + q cos θ.
    #[inline]
    pub fn inverse_park(self, sc: SinCos) -> AlphaBeta {
        AlphaBeta { alpha: self.d * sc.cos - self.q * sc.sin, beta: self.d * sc.sin + self.q * sc.cos }
    }
}

/// Wrap an angle into `[-π, π)`. Exact for |θ| < 3π (one add/subtract of 2π), which is
/// all that one control step can produce from a wrapped angle; larger inputs take
/// [`wrap_far`] (out of line: the common case stays a compare or two where it is inlined).
/// Non-finite input gives NaN (the supervisor trips on it). Out of line: no fast step calls
/// it since the IFOC's fast step stopped carrying θ_e (issue 19; its slow-step callers'
/// copies took flash).
#[inline(never)]
pub fn wrap_angle(theta_rad: f32) -> f32 {
    let t = if theta_rad >= PI {
        theta_rad - TAU
    } else if theta_rad < -PI {
        theta_rad + TAU
    } else {
        return theta_rad;
    };
    if (-PI..PI).contains(&t) { t } else { wrap_far(theta_rad) }
}

/// 2π in two parts (Cody–Waite): 6.28125 has 8 significant bits, so its product with a turn
/// count below 2^16 is exact in f32; the rest, rounded to f32, carries the error.
const TAU_HI: f32 = 6.281_25;
const TAU_LO: f32 = (core::f64::consts::TAU - 6.281_25) as f32;
/// Above this many turns an f32 angle's spacing is a radian or more: no phase left.
const WRAP_TURNS_MAX: f32 = (1u32 << 22) as f32;

/// [`wrap_angle`] for |θ| ≥ 3π: θ less its nearest whole number of turns n (taken off as
/// n·`TAU_HI` + n·`TAU_LO`), within a few units in the last place of θ for |n| < 2^16
/// (|θ| < 4·10^5 rad; test `wrap_far_matches_f64_and_stays_in_range`). Beyond 2^22 turns
/// (2.6·10^7 rad) an f32 carries no phase: 0. Non-finite: NaN. Replaces `libm::remainderf`
/// (264 B of flash on the M4F, called from every inlined `wrap_angle`).
#[cold]
#[inline(never)]
pub fn wrap_far(theta_rad: f32) -> f32 {
    if !theta_rad.is_finite() {
        return f32::NAN;
    }
    let turns = theta_rad * (1.0 / TAU);
    if turns.abs() >= WRAP_TURNS_MAX {
        return 0.0;
    }
    // Nearest whole number (|turns| < 2^22: adding and taking off 1.5·2^23 rounds it).
    const ROUND: f32 = 12_582_912.0;
    let n = (turns + ROUND) - ROUND;
    let r = (theta_rad - n * TAU_HI) - n * TAU_LO;
    if r >= PI {
        r - TAU
    } else if r < -PI {
        r + TAU
    } else {
        r
    }
}

/// The angle of the vector `(x, y)`, rad in `[-π, π]`, in f32 arithmetic only (no libm: its
/// `atan2f` and `atanf` took 0.5 KiB of flash): the octant reduction to `z = min/max ∈ [0, 1]`
/// and Abramowitz & Stegun 4.4.49's polynomial, `atan z = z·(a₁ + a₃z² + a₅z⁴ + a₇z⁶ + a₉z⁸)`
/// with |error| ≤ 1e-5 rad (test: 1.17e-5 against f64 over every direction, with the f32
/// rounding; asserted ≤ 1.2e-5). `(0, 0)` gives
/// 0; a non-finite component NaN. Out of line: the sensorless field anchor calls it once per
/// slow step.
#[inline(never)]
pub fn atan2(y: f32, x: f32) -> f32 {
    const A: [f32; 5] = [0.999_866, -0.330_299_5, 0.180_141, -0.085_133, 0.020_835_1];
    if !(x.is_finite() && y.is_finite()) {
        return f32::NAN;
    }
    let (ax, ay) = (x.abs(), y.abs());
    let (lo, hi) = if ay > ax { (ax, ay) } else { (ay, ax) };
    if hi == 0.0 {
        return 0.0;
    }
    let z = lo / hi;
    let z2 = z * z;
    let t = z * (A[0] + z2 * (A[1] + z2 * (A[2] + z2 * (A[3] + z2 * A[4]))));
    // The octant back: beyond 45°, past 90°, below the axis.
    let t = if ay > ax { core::f32::consts::FRAC_PI_2 - t } else { t };
    let t = if x < 0.0 { PI - t } else { t };
    if y < 0.0 { -t } else { t }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn atan2_absolute_error_against_f64() {
        let mut worst = 0.0f64;
        for i in 0..200_000 {
            let th = f64::from(i) * (core::f64::consts::TAU / 200_000.0) - core::f64::consts::PI;
            for r in [1e-3, 1.0, 300.0] {
                let (x, y) = ((r * th.cos()) as f32, (r * th.sin()) as f32);
                let exact = libm::atan2(f64::from(y), f64::from(x));
                let mut e = (f64::from(atan2(y, x)) - exact).abs();
                // −π and π are the same direction.
                e = e.min((e - core::f64::consts::TAU).abs());
                worst = worst.max(e);
            }
        }
        eprintln!("atan2 worst abs. error {worst:.3e}");
        assert!(worst <= 1.2e-5, "{worst}");
        assert_eq!(atan2(0.0, 0.0), 0.0);
        assert!(atan2(f32::NAN, 1.0).is_nan() && atan2(1.0, f32::INFINITY).is_nan());
    }

    #[test]
    fn sincos_absolute_error_against_f64() {
        let mut worst = (0.0f64, 0.0f32);
        for i in -1_000_000..=1_000_000 {
            let th = i as f32 * 1e-4; // |θ| ≤ 100 rad, all quadrant boundaries crossed
            let sc = SinCos::new(th);
            let (s, c) = libm::sincos(f64::from(th));
            let e = (f64::from(sc.sin) - s).abs().max((f64::from(sc.cos) - c).abs());
            if e > worst.0 {
                worst = (e, th);
            }
        }
        eprintln!("SinCos worst abs. error {:.3e} at θ = {}", worst.0, worst.1);
        assert!(worst.0 <= 1.2e-7, "{worst:?}");
        assert!(SinCos::new(f32::NAN).sin.is_nan() && SinCos::new(f32::INFINITY).cos.is_nan());
    }

    /// One rotation of an exact start vector, over a grid of start angles and every angle
    /// step up to ±`MAX_ROTATION_RAD`: the error against f64 sin/cos of θ + δ stays at the
    /// level of `SinCos::new` itself (truncation ≤ 1.4e-9, the rest is f32 rounding).
    #[test]
    fn rotation_absolute_error_against_f64() {
        let mut worst = (0.0f64, 0.0f32, 0.0f32);
        for i in -1000..=1000 {
            let th = i as f32 * (PI / 1000.0);
            let start = SinCos::new(th);
            for j in -200..=200 {
                let d = j as f32 * (SinCos::MAX_ROTATION_RAD / 200.0);
                let r = start.rotated(d);
                let (s, c) = libm::sincos(f64::from(th) + f64::from(d));
                let e = (f64::from(r.sin) - s).abs().max((f64::from(r.cos) - c).abs());
                if e > worst.0 {
                    worst = (e, th, d);
                }
            }
        }
        eprintln!("SinCos::rotated worst abs. error {:.3e} at θ = {}, δ = {}", worst.0, worst.1, worst.2);
        assert!(worst.0 <= 2.5e-7, "{worst:?}");
    }

    fn close(a: f32, b: f32, tol: f32) -> bool {
        (a - b).abs() <= tol
    }

    #[test]
    fn balanced_set_maps_to_vector_of_same_amplitude() {
        // a = A cos φ, b = A cos(φ − 2π/3), c = A cos(φ + 2π/3)  →  α = A cos φ, β = A sin φ.
        let amp = 10.0f32;
        for k in 0..12 {
            let phi = k as f32 * TAU / 12.0;
            let abc = Abc {
                a: amp * libm::cosf(phi),
                b: amp * libm::cosf(phi - TAU / 3.0),
                c: amp * libm::cosf(phi + TAU / 3.0),
            };
            let ab = abc.clarke();
            assert!(close(ab.alpha, amp * libm::cosf(phi), 1e-5));
            assert!(close(ab.beta, amp * libm::sinf(phi), 1e-5));
            assert!(close(ab.magnitude(), amp, 1e-5));
        }
    }

    #[test]
    fn known_vectors() {
        // Phase a alone at +1 with b = c = −1/2 is the α axis.
        let ab = Abc { a: 1.0, b: -0.5, c: -0.5 }.clarke();
        assert!(close(ab.alpha, 1.0, 1e-7) && close(ab.beta, 0.0, 1e-7));
        // Zero sequence disappears.
        let z = Abc { a: 3.0, b: 3.0, c: 3.0 }.clarke();
        assert!(close(z.alpha, 0.0, 1e-7) && close(z.beta, 0.0, 1e-7));
        // Park at θ = π/2 maps β onto d.
        let dq = AlphaBeta { alpha: 0.0, beta: 2.0 }.park(SinCos::new(PI / 2.0));
        assert!(close(dq.d, 2.0, 1e-6) && close(dq.q, 0.0, 1e-6));
    }

    #[test]
    fn wrap_angle_range() {
        assert_eq!(wrap_angle(PI), -PI);
        assert!(close(wrap_angle(3.5 * PI), -0.5 * PI, 1e-5));
        assert!(close(wrap_angle(-7.0 * PI / 2.0), 0.5 * PI, 1e-5));
        assert!(wrap_angle(f32::NAN).is_nan());
    }

    /// The far wrap against f64 on a dense grid up to 4·10^5 rad (2^16 turns): within
    /// 2 units in the last place of the input (its own resolution) plus 1e-6 rad,
    /// compared around the circle; in range for every finite input; NaN for non-finite.
    #[test]
    fn wrap_far_matches_f64_and_stays_in_range() {
        let mut worst_ulps = 0.0f64;
        let mut k = 0u32;
        let mut theta = 3.0 * PI;
        while theta < 4.0e5 {
            for t in [theta, -theta] {
                let w = wrap_angle(t);
                assert!((-PI..PI).contains(&w), "{t} → {w}");
                let want =
                    f64::from(t) - core::f64::consts::TAU * (f64::from(t) / core::f64::consts::TAU).round();
                let mut d = f64::from(w) - want;
                if d > core::f64::consts::PI {
                    d -= core::f64::consts::TAU;
                } else if d < -core::f64::consts::PI {
                    d += core::f64::consts::TAU;
                }
                let ulp = f64::from(f32::from_bits(t.abs().to_bits() + 1) - t.abs());
                assert!(d.abs() <= 2.0 * ulp + 1e-6, "{t}: {w} vs {want} ({} ulp)", d.abs() / ulp);
                worst_ulps = worst_ulps.max(d.abs() / ulp);
            }
            k += 1;
            // Dense near 3π, then geometric with an irrational-ish stride.
            theta = if k < 20_000 { 3.0 * PI + k as f32 * 1.0e-3 } else { theta * 1.000_137 + 0.37 };
        }
        assert!(worst_ulps > 0.0);
        for t in [1.0e7f32, 2.6e7, 3.0e7, 1.0e30, f32::MAX, f32::MIN, -5.0e8] {
            assert!((-PI..PI).contains(&wrap_angle(t)), "{t}");
        }
        assert!(wrap_angle(f32::INFINITY).is_nan() && wrap_angle(f32::NEG_INFINITY).is_nan());
    }

    proptest! {
        #[test]
        fn clarke_round_trip(alpha in -1e3f32..1e3, beta in -1e3f32..1e3) {
            let ab = AlphaBeta { alpha, beta };
            let back = ab.inverse_clarke().clarke();
            prop_assert!(close(back.alpha, alpha, 1e-3) && close(back.beta, beta, 1e-3));
            // The inverse Clarke output has no zero sequence.
            let abc = ab.inverse_clarke();
            prop_assert!((abc.a + abc.b + abc.c).abs() < 1e-3);
        }

        #[test]
        fn park_round_trip_preserves_magnitude(alpha in -1e3f32..1e3, beta in -1e3f32..1e3,
                                               theta in -10.0f32..10.0) {
            let ab = AlphaBeta { alpha, beta };
            let sc = SinCos::new(theta);
            let dq = ab.park(sc);
            let back = dq.inverse_park(sc);
            prop_assert!(close(back.alpha, alpha, 1e-3) && close(back.beta, beta, 1e-3));
            prop_assert!(close(libm::hypotf(dq.d, dq.q), ab.magnitude(), 1e-3));
        }

        #[test]
        fn wrap_angle_is_in_range_and_equivalent(theta in -100.0f32..100.0) {
            let w = wrap_angle(theta);
            prop_assert!((-PI..PI).contains(&w));
            prop_assert!(close(libm::sinf(w), libm::sinf(theta), 1e-4));
            prop_assert!(close(libm::cosf(w), libm::cosf(theta), 1e-4));
        }
    }
}
