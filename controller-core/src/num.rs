//! Numeric policy.
//!
//! * **Design in f64, run in `T`.** Every coefficient is computed once, at construction, in
//!   `f64` (see [`crate::discretize`]) and then rounded to the run-time type `T: Scalar`.
//! * **f32 is the reference** run-time type (single-precision FPU of the Cortex-M4F).
//! * **[`Q32`]** (signed 64-bit fixed point, 32 integer and 32 fractional bits, *saturating*
//!   arithmetic) is the configuration for FPU-less cores. Its formats come from the precision
//!   analysis in the tests of [`crate::filter`]: the δ-form lag section of the ICAD controller
//!   has per-step state increments of order 1e-4 of the signal, so the state needs ≳ 30
//!   fractional bits to keep the increment's quantisation below 1e-5 relative; coefficients
//!   as small as 1.06e-4 need ≥ 30 fractional bits to keep 1e-5 relative precision. A 16.16
//!   format fails both (see `q16_16_is_too_coarse_for_the_lag_section`).
//! * Saturation, not wrap-around, everywhere a physical quantity is represented; the only
//!   wrapping quantity is the electrical angle (see [`crate::frames::wrap_angle`]).
//! * Arithmetic in `T` never panics: f32 arithmetic cannot, and `Q32` saturates.

/// The larger of `a` and `b` by comparison. Equal to `f32::max` for non-NaN inputs (up to
/// the sign of a zero tie), but `f32::max` (IEEE maxNum) is a library call on the
/// Cortex-M4F, whose FPU has no `vmaxnm`: ≈ 15 instructions against 2. For the fast path,
/// where inputs are known finite; a NaN `b` is returned as is.
#[inline]
pub fn max_f32(a: f32, b: f32) -> f32 {
    if a > b { a } else { b }
}

/// The smaller of `a` and `b` by comparison (see [`max_f32`]).
#[inline]
pub fn min_f32(a: f32, b: f32) -> f32 {
    if a < b { a } else { b }
}

/// `x` finite and above zero: `x.is_finite() && x > 0.0` for every `x` (NaN: `false`), on
/// its bits — the positive finite floats are the patterns `1 ..= 0x7f7f_ffff` (sign clear,
/// exponent below all ones, not zero). LLVM folds the two comparisons (or `x > 0.0 &&
/// x < f32::INFINITY`) into a class test that it lowers to ≈ 20 instructions on the
/// Cortex-M4F; this is three (852 B of flash less over the firmware's tests).
#[inline]
pub fn finite_positive(x: f32) -> bool {
    x.to_bits().wrapping_sub(1) < 0x7f7f_ffff
}

/// ln x for a finite x > 0 (NaN otherwise), within 2e-6 (relative above 1): the exponent's
/// `e·ln 2` and `ln m = 2·atanh(s)`, `s = (m − 1)/(m + 1)`, of the mantissa
/// `m ∈ [√½, √2)` by its series to s⁷ (|s| ≤ 0.172: the first term left out, 2·s⁹/9, is
/// below 3e-8). Not libm's `logf`: ≈ 30 instructions, without a library routine in the
/// image.
pub fn ln_f32(x: f32) -> f32 {
    if !finite_positive(x) {
        return f32::NAN;
    }
    // Subnormals scaled into the normal range first.
    let (x, e0) = if x < f32::MIN_POSITIVE { (x * 8_388_608.0, -23) } else { (x, 0) };
    let bits = x.to_bits();
    let mut e = ((bits >> 23) & 0xff) as i32 - 127 + e0;
    let mut m = f32::from_bits((bits & 0x007f_ffff) | 0x3f80_0000);
    if m > core::f32::consts::SQRT_2 {
        m *= 0.5;
        e += 1;
    }
    let s = (m - 1.0) / (m + 1.0);
    let s2 = s * s;
    let ln_m = 2.0 * s * (1.0 + s2 * (1.0 / 3.0 + s2 * (0.2 + s2 * (1.0 / 7.0))));
    e as f32 * core::f32::consts::LN_2 + ln_m
}

/// √x, correctly rounded (IEEE 754), NaN for x < 0. On the Cortex-M4F it is the FPU's
/// `vsqrt.f32` (14 cycles, in a two-instruction leaf routine: the register classes of
/// `asm!` need the double-precision `vfp2` feature this FPU does not have); elsewhere
/// libm's `sqrtf` (a software routine of ≈ 150 instructions on the Cortex-M, where no
/// hardware square root is available). Both round correctly, so the emulated MCU (PIL) and
/// the host (SIL) agree bit for bit.
#[inline]
pub fn sqrt_f32(x: f32) -> f32 {
    #[cfg(all(target_arch = "arm", target_abi = "eabihf"))]
    {
        vsqrt::sqrt(x)
    }
    #[cfg(not(all(target_arch = "arm", target_abi = "eabihf")))]
    {
        libm::sqrtf(x)
    }
}

/// The FPU's square root, the crate's one use of `unsafe`.
#[cfg(all(target_arch = "arm", target_abi = "eabihf"))]
#[allow(unsafe_code)]
mod vsqrt {
    core::arch::global_asm!(
        ".section .text.controller_core_vsqrt_f32,\"ax\",%progbits",
        ".global controller_core_vsqrt_f32",
        ".type controller_core_vsqrt_f32,%function",
        ".thumb_func",
        ".fpu fpv4-sp-d16",
        "controller_core_vsqrt_f32:",
        "vsqrt.f32 s0, s0",
        "bx lr",
        ".size controller_core_vsqrt_f32, . - controller_core_vsqrt_f32",
    );

    unsafe extern "C" {
        fn controller_core_vsqrt_f32(x: f32) -> f32;
    }

    #[inline]
    pub fn sqrt(x: f32) -> f32 {
        // SAFETY: `controller_core_vsqrt_f32` (above) is a leaf routine of the hard-float
        // procedure call standard: argument and result in s0, `vsqrt.f32 s0, s0`, return; it
        // touches no memory, no stack and no other register. Every eabihf Arm target has
        // the single-precision FPU that executes it.
        unsafe { controller_core_vsqrt_f32(x) }
    }
}

use core::fmt::Debug;
use core::ops::{Add, Mul, Neg, Sub};
use fixed::types::I32F32;

/// A run-time scalar for the control loops: f32, f64 or [`Q32`].
pub trait Scalar:
    Copy + Debug + PartialOrd + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + Neg<Output = Self>
{
    /// Zero.
    const ZERO: Self;
    /// Round a design-time `f64` to this type (saturating for fixed point, NaN → 0).
    fn from_f64(x: f64) -> Self;
    /// Widen to `f64` (exact for f32 and `Q32`).
    fn to_f64(self) -> f64;

    /// `self` limited to `[lo, hi]`. Unlike `f32::clamp` this never panics (for `lo > hi`
    /// the result is `hi`); a NaN `self` is returned unchanged so that the supervisor sees it.
    #[inline]
    fn limit(self, lo: Self, hi: Self) -> Self {
        let x = if self < lo { lo } else { self };
        if x > hi { hi } else { x }
    }

    /// `self.limit(-l, l)`, the same value for every input: f32 tests `|self| ≤ l` first
    /// and limits only when it fails (out of line — an integrator at its clamp is the rare
    /// case): 4 instructions instead of 8 on the Cortex-M4F, whose FPU has no min/max.
    #[inline]
    fn limit_symmetric(self, l: Self) -> Self {
        self.limit(-l, l)
    }
}

impl Scalar for f32 {
    const ZERO: Self = 0.0;
    #[inline]
    fn from_f64(x: f64) -> Self {
        // Rounding to nearest: the one intended narrowing of design values.
        x as f32
    }
    #[inline]
    fn to_f64(self) -> f64 {
        f64::from(self)
    }
    #[inline]
    fn limit_symmetric(self, l: Self) -> Self {
        // |x| ≤ l leaves `limit(−l, l)` nothing to do (l ≥ |x| ≥ 0); its failure — beyond the
        // limit, a NaN x or l, a negative l — takes the general limit.
        if self.abs() <= l { self } else { limit_symmetric_rare(self, l) }
    }
}

/// [`Scalar::limit_symmetric`]'s rare path for f32.
#[cold]
#[inline(never)]
fn limit_symmetric_rare(x: f32, l: f32) -> f32 {
    x.limit(-l, l)
}

impl Scalar for f64 {
    const ZERO: Self = 0.0;
    #[inline]
    fn from_f64(x: f64) -> Self {
        x
    }
    #[inline]
    fn to_f64(self) -> f64 {
        self
    }
}

/// Saturating 32.32 fixed point (a [`fixed::types::I32F32`] whose `+ − × −x` saturate
/// instead of panicking or wrapping). Range ±2.1e9, resolution 2.3e-10.
#[derive(Clone, Copy, Debug, Default, PartialEq, PartialOrd)]
pub struct Q32(pub I32F32);

impl Q32 {
    /// Convert from f32 (saturating, NaN → 0).
    #[inline]
    pub fn from_f32(x: f32) -> Self {
        Q32(I32F32::saturating_from_num(if x.is_nan() { 0.0 } else { x }))
    }
    /// Convert to f32 (rounds to nearest).
    #[inline]
    pub fn to_f32(self) -> f32 {
        self.0.to_num::<f32>()
    }
}

impl Add for Q32 {
    type Output = Self;
    #[inline]
    fn add(self, o: Self) -> Self {
        Q32(self.0.saturating_add(o.0))
    }
}
impl Sub for Q32 {
    type Output = Self;
    #[inline]
    fn sub(self, o: Self) -> Self {
        Q32(self.0.saturating_sub(o.0))
    }
}
impl Mul for Q32 {
    type Output = Self;
    #[inline]
    fn mul(self, o: Self) -> Self {
        Q32(self.0.saturating_mul(o.0))
    }
}
impl Neg for Q32 {
    type Output = Self;
    #[inline]
    fn neg(self) -> Self {
        Q32(self.0.saturating_neg())
    }
}

impl Scalar for Q32 {
    const ZERO: Self = Q32(I32F32::ZERO);
    #[inline]
    fn from_f64(x: f64) -> Self {
        Q32(I32F32::saturating_from_num(if x.is_nan() { 0.0 } else { x }))
    }
    #[inline]
    fn to_f64(self) -> f64 {
        self.0.to_num::<f64>()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn q32_saturates_instead_of_overflowing() {
        let big = Q32::from_f64(2.0e9);
        assert_eq!((big + big).0, I32F32::MAX);
        assert_eq!((big * big).0, I32F32::MAX);
        assert_eq!((-big - big).0, I32F32::MIN);
        assert_eq!(Q32::from_f64(f64::NAN), Q32::ZERO);
        assert_eq!(Q32::from_f64(f64::INFINITY).0, I32F32::MAX);
    }

    #[test]
    fn ln_agrees_with_the_library() {
        for k in -380..=380 {
            let x = 10f32.powf(k as f32 / 10.0);
            let (a, b) = (ln_f32(x), f64::from(x).ln());
            assert!((f64::from(a) - b).abs() <= 2e-6 * b.abs().max(1.0), "ln {x}: {a} vs {b}");
        }
        for x in [1.0f32, 2.0, 1.5, core::f32::consts::E, f32::MIN_POSITIVE, 1e-40, f32::MAX] {
            let (a, b) = (ln_f32(x), f64::from(x).ln());
            assert!((f64::from(a) - b).abs() <= 2e-6 * b.abs().max(1.0), "ln {x}: {a} vs {b}");
        }
        for x in [0.0f32, -1.0, f32::NAN, f32::INFINITY] {
            assert!(ln_f32(x).is_nan());
        }
    }

    #[test]
    fn finite_positive_is_the_float_test() {
        let special = [0.0f32, -0.0, 1e-45, -1e-45, f32::MIN_POSITIVE, 1.0, -1.0, f32::MAX, f32::MIN];
        let special = special.into_iter().chain([f32::INFINITY, f32::NEG_INFINITY, f32::NAN, -f32::NAN]);
        let bits = (0..=u32::MAX).step_by(65_521).map(f32::from_bits);
        for x in special.chain(bits) {
            assert_eq!(finite_positive(x), x.is_finite() && x > 0.0, "{x:e} ({:#x})", x.to_bits());
        }
    }

    #[test]
    fn limit_symmetric_is_limit_for_every_input() {
        let values = [
            0.0f32,
            -0.0,
            1.0,
            -1.0,
            0.5,
            -0.5,
            2.0,
            -2.0,
            1e-45,
            -1e-45,
            3.4e38,
            -3.4e38,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            -f32::NAN,
            1.0000001,
            -1.0000001,
        ];
        for x in values {
            for l in values {
                let (fast, slow) = (x.limit_symmetric(l), x.limit(-l, l));
                assert_eq!(fast.to_bits(), slow.to_bits(), "x {x:e}, l {l:e}");
            }
        }
    }

    #[test]
    fn limit_never_panics_and_keeps_nan() {
        assert_eq!(5.0f32.limit(-1.0, 1.0), 1.0);
        assert_eq!((-5.0f32).limit(-1.0, 1.0), -1.0);
        assert_eq!(0.5f32.limit(1.0, -1.0), -1.0);
        assert!(f32::NAN.limit(-1.0, 1.0).is_nan());
    }
}
