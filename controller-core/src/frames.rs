//! Reference frames and their transforms (f32).
//!
//! * [`Abc`] — phase quantities.
//! * [`AlphaBeta`] — stationary two-axis frame, **amplitude-invariant** Clarke transform: a
//!   balanced set of phase peak amplitude `A` maps to a vector of magnitude `A`.
//! * [`Dq`] — frame rotating with the electrical angle θe (d on the rotor flux in IFOC).
//!
//! Angle policy: electrical angles wrap into `[-π, π)` ([`wrap_angle`]); nothing else wraps.

use core::f32::consts::{PI, TAU};

const INV_SQRT3: f32 = 0.577_350_26;
const SQRT3_2: f32 = 0.866_025_4;

/// Three phase quantities (currents in A, voltages in V, or duty cycles).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Abc {
    /// Phase a.
    pub a: f32,
    /// Phase b.
    pub b: f32,
    /// Phase c.
    pub c: f32,
}

/// Stationary-frame vector.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AlphaBeta {
    /// α component (aligned with phase a).
    pub alpha: f32,
    /// β component (leads α by 90°).
    pub beta: f32,
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

impl SinCos {
    /// sin and cos of `theta_rad` (libm `sincosf`, the same routine on host and target).
    #[inline]
    pub fn new(theta_rad: f32) -> Self {
        let (sin, cos) = libm::sincosf(theta_rad);
        Self { sin, cos }
    }
}

impl Abc {
    /// All three elements finite.
    #[inline]
    pub fn is_finite(&self) -> bool {
        self.a.is_finite() && self.b.is_finite() && self.c.is_finite()
    }

    /// Amplitude-invariant Clarke transform using all three phases:
    /// α = (2a − b − c)/3, β = (b − c)/√3. A zero-sequence component is discarded.
    #[inline]
    pub fn clarke(self) -> AlphaBeta {
        AlphaBeta {
            alpha: (2.0 * self.a - self.b - self.c) * (1.0 / 3.0),
            beta: (self.b - self.c) * INV_SQRT3,
        }
    }
}

impl AlphaBeta {
    /// Inverse amplitude-invariant Clarke: a = α, b = −α/2 + (√3/2)β, c = −α/2 − (√3/2)β.
    #[inline]
    pub fn inverse_clarke(self) -> Abc {
        Abc {
            a: self.alpha,
            b: -0.5 * self.alpha + SQRT3_2 * self.beta,
            c: -0.5 * self.alpha - SQRT3_2 * self.beta,
        }
    }

    /// Park transform into the frame at angle θ: d = α cos θ + β sin θ, q = −α sin θ + β cos θ.
    #[inline]
    pub fn park(self, sc: SinCos) -> Dq {
        Dq { d: self.alpha * sc.cos + self.beta * sc.sin, q: -self.alpha * sc.sin + self.beta * sc.cos }
    }

    /// Euclidean magnitude.
    #[inline]
    pub fn magnitude(self) -> f32 {
        libm::sqrtf(self.alpha * self.alpha + self.beta * self.beta)
    }

    /// Multiply both components by `k`.
    #[inline]
    pub fn scale(self, k: f32) -> AlphaBeta {
        AlphaBeta { alpha: self.alpha * k, beta: self.beta * k }
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

impl Dq {
    /// Inverse Park: α = d cos θ − q sin θ, β = d sin θ + q cos θ.
    #[inline]
    pub fn inverse_park(self, sc: SinCos) -> AlphaBeta {
        AlphaBeta { alpha: self.d * sc.cos - self.q * sc.sin, beta: self.d * sc.sin + self.q * sc.cos }
    }
}

/// Wrap an angle into `[-π, π)`. Exact for |θ| < 3π (one add/subtract of 2π), which is
/// all that one control step can produce from a wrapped angle; larger inputs are reduced
/// with `remainderf`. Non-finite input gives NaN (the supervisor trips on it).
#[inline]
pub fn wrap_angle(theta_rad: f32) -> f32 {
    let t = if theta_rad >= PI {
        theta_rad - TAU
    } else if theta_rad < -PI {
        theta_rad + TAU
    } else {
        return theta_rad;
    };
    if (-PI..PI).contains(&t) {
        t
    } else {
        let r = libm::remainderf(theta_rad, TAU);
        if r >= PI { r - TAU } else { r }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

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
