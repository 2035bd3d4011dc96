//! Nyquist encirclements of an arbitrary point.
//!
//! For `L = N/D` and a point `p`, the number of **clockwise** encirclements of `p` by the
//! Nyquist plot of `L` (the image of the Nyquist D-contour: up the imaginary axis with small
//! right-hand detours around imaginary-axis poles, back along a large right half circle) is
//! `Z − P`: `Z` the right-half-plane roots of `N − p·D`, `P` those of `D` (poles on the axis
//! count as outside, because the detours leave them on the left).
//!
//! [`encirclements`] counts it **graphically**: the winding of `L(s) − p` along the
//! contour, with adaptive steps so that no step turns the argument by more than 0.2 rad.
//! [`encirclements_by_roots`] is the algebraic count above; the tests require both to agree
//! on random loops and points. With `p = −1` this is the Nyquist stability test; with
//! `p = 1` it is seed 002's structural-robustness test on `γ·h` (Sec. IV).

use crate::poly::Poly;
use crate::tf::Tf;
use num_complex::Complex64;

/// Why a count is not defined.
#[derive(Clone, Debug, PartialEq)]
pub enum NyquistError {
    /// The plot passes through the point (within `1e-9` relative): the count is not defined.
    ThroughPoint {
        /// Where on the contour, `s`.
        at: Complex64,
    },
    /// Improper or zero-denominator loop.
    Improper,
    /// The loop's poles, zeros or closed-loop roots are unknown (the eigenvalue iterations
    /// did not converge: [`crate::eig::eigenvalues`]).
    Roots,
}

/// Clockwise encirclements of `point` by the Nyquist plot of `l` (graphical winding).
pub fn encirclements(l: &Tf, point: Complex64) -> Result<i64, NyquistError> {
    if l.den.coeffs().iter().all(|&c| c == 0.0) || l.num.degree() > l.den.degree() {
        return Err(NyquistError::Improper);
    }
    let poles = l.den.roots().ok_or(NyquistError::Roots)?;
    let zeros = l.num.roots().ok_or(NyquistError::Roots)?;
    // Scale of the problem: radius beyond every root; detour radius below every gap.
    let big = poles.iter().chain(&zeros).map(|z| z.norm()).fold(1.0, f64::max) * 1e3;
    let mut axis_poles: Vec<f64> = poles.iter().filter(|z| z.re.abs() <= 1e-9 * big).map(|z| z.im).collect();
    axis_poles.sort_by(f64::total_cmp);
    axis_poles.dedup_by(|a, b| (*a - *b).abs() <= 1e-9 * big);
    // The detours must be small enough to leave every other pole, zero and root of
    // L = p (those near an axis pole are the ones a detour could swallow) outside.
    let closed = complex_poly_roots(&l.num, &l.den, point).ok_or(NyquistError::Roots)?;
    let min_gap = poles
        .iter()
        .chain(&zeros)
        .chain(&closed)
        .flat_map(|a| axis_poles.iter().map(move |&w| (a - Complex64::new(0.0, w)).norm()))
        .filter(|&d| d > 1e-9 * big)
        .fold(big, f64::min);
    let eps = (min_gap * 1e-3).max(1e-12 * big);
    // Axis pieces are sampled uniformly in u = asinh(ω/S): linear near 0, logarithmic
    // beyond the smallest root scale S, so no resonance or low-frequency turn is skipped.
    let small = poles.iter().chain(&zeros).map(|z| z.norm()).filter(|&r| r > 1e-9 * big).fold(big, f64::min);
    let sc = (small * 1e-2).min(eps.max(1e-12 * big) * 1e2).max(1e-12 * big);
    let axis = move |a: f64, b: f64| {
        let (ua, ub) = ((a / sc).asinh(), (b / sc).asinh());
        move |t: f64| Complex64::new(0.0, sc * (ua + (ub - ua) * t).sinh())
    };
    // The contour as pieces s(t), t ∈ [0, 1], traversed clockwise.
    let mut pieces: Vec<Box<dyn Fn(f64) -> Complex64>> = Vec::new();
    let mut from = -big;
    for &w in &axis_poles {
        pieces.push(Box::new(axis(from, w - eps)));
        // right-hand detour: θ from −π/2 to π/2
        pieces.push(Box::new(move |t| {
            Complex64::new(0.0, w)
                + Complex64::from_polar(eps, -std::f64::consts::FRAC_PI_2 + std::f64::consts::PI * t)
        }));
        from = w + eps;
    }
    pieces.push(Box::new(axis(from, big)));
    // large half circle: θ from π/2 down to −π/2 (clockwise)
    pieces.push(Box::new(move |t| {
        Complex64::from_polar(big, std::f64::consts::FRAC_PI_2 - std::f64::consts::PI * t)
    }));
    let f = |s: Complex64| l.num.eval(s) / l.den.eval(s) - point;
    let scale = point.norm().max(1.0);
    let mut total = 0.0;
    for piece in &pieces {
        total += winding_along(&f, piece.as_ref(), scale)?;
    }
    // The argument of f decreases by 2π per clockwise encirclement.
    Ok((-total / std::f64::consts::TAU).round() as i64)
}

/// Argument change of `f(s(t))` for t from 0 to 1, with steps refined until each turns the
/// argument by < 0.2 rad (and never more than 2²⁰ steps per piece).
fn winding_along(
    f: &dyn Fn(Complex64) -> Complex64,
    s: &dyn Fn(f64) -> Complex64,
    scale: f64,
) -> Result<f64, NyquistError> {
    let value = |t: f64| {
        let v = f(s(t));
        if v.norm() <= 1e-9 * scale || !v.is_finite() {
            Err(NyquistError::ThroughPoint { at: s(t) })
        } else {
            Ok(v)
        }
    };
    // 2048 initial steps; a step is bisected while it turns the argument by more than
    // 0.2 rad or its two halves disagree with it (an aliased turn).
    let mut total = 0.0;
    let n0 = 2048;
    let min_step = 1.0 / (n0 as f64 * f64::from(1u32 << 20));
    let mut prev = value(0.0)?;
    for k in 0..n0 {
        let (t0, t1) = (k as f64 / n0 as f64, (k + 1) as f64 / n0 as f64);
        let mut stack = vec![(t0, t1)];
        // depth-first, left to right: the leftmost interval is on top
        while let Some((a, b)) = stack.pop() {
            let (vm, vb) = (value(0.5 * (a + b))?, value(b)?);
            let d = (vb / prev).arg();
            let (d1, d2) = ((vm / prev).arg(), (vb / vm).arg());
            let aliased = (d1 + d2 - d).abs() > 1e-6;
            if (d.abs() > 0.2 || aliased) && b - a > min_step {
                let m = 0.5 * (a + b);
                stack.push((m, b));
                stack.push((a, m));
                continue;
            }
            total += d;
            prev = vb;
        }
    }
    Ok(total)
}

/// Clockwise encirclements from root counts: `Z − P` (right-half-plane roots of `N − p·D`
/// and of `D`; roots within `1e-9` relative of the axis count as left); `None` if the roots
/// are unknown.
pub fn encirclements_by_roots(l: &Tf, point: Complex64) -> Option<i64> {
    let rhp = |roots: &[Complex64], scale: f64| roots.iter().filter(|z| z.re > 1e-9 * scale).count() as i64;
    let poles = l.den.roots()?;
    let scale = poles.iter().chain(&l.num.roots()?).map(|z| z.norm()).fold(1.0, f64::max);
    Some(rhp(&complex_poly_roots(&l.num, &l.den, point)?, scale) - rhp(&poles, scale))
}

/// Roots of `N(s) − p·D(s)` for complex `p`: with `a = N − Re(p)·D`, `b = −Im(p)·D`, the
/// real polynomial `a² + b² = (a + jb)(a − jb)` has the wanted roots and their conjugates;
/// the half where `a + jb` vanishes is kept (`None`: unknown roots).
fn complex_poly_roots(n: &Poly, d: &Poly, p: Complex64) -> Option<Vec<Complex64>> {
    // q(s) = (N − pD)(s)·(N − p̄D)(s) is real with roots {r} ∪ {r̄}.
    let a = n.add(&d.scale(-p.re));
    if p.im == 0.0 {
        return a.roots();
    }
    let b = d.scale(-p.im);
    // (a + j b)(a − j b) = a² + b²
    let q = a.mul(&a).add(&b.mul(&b));
    let cand = q.roots()?;
    // Keep the half that are roots of a + j·b: |a(r) + j b(r)| small.
    let mut scored: Vec<(f64, Complex64)> = cand
        .iter()
        .map(|&r| {
            let v = a.eval(r) + Complex64::new(0.0, 1.0) * b.eval(r);
            (v.norm(), r)
        })
        .collect();
    scored.sort_by(|x, y| x.0.total_cmp(&y.0));
    let deg = a.degree().max(b.degree());
    Some(scored.into_iter().take(deg).map(|(_, r)| r).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn c(re: f64, im: f64) -> Complex64 {
        Complex64::new(re, im)
    }

    #[test]
    fn textbook_cases() {
        // L = 4/(s+1)³ (stable, GM 6 dB): no encirclement of −1. It crosses the negative
        // real axis at −0.5 (ω = ±√3) and spirals into 0 through −270°: −0.2 is encircled
        // twice clockwise (4 + 0.2(s+1)³ has two right-half-plane roots).
        let l = Tf::new(&[4.0], &[1.0, 3.0, 3.0, 1.0]);
        assert_eq!(encirclements(&l, c(-1.0, 0.0)), Ok(0));
        assert_eq!(encirclements(&l, c(-0.2, 0.0)), Ok(2));
        assert_eq!(encirclements_by_roots(&l, c(-0.2, 0.0)), Some(2));
        // K = 16: GM negative, unstable, two clockwise encirclements of −1.
        let l = Tf::new(&[16.0], &[1.0, 3.0, 3.0, 1.0]);
        assert_eq!(encirclements(&l, c(-1.0, 0.0)), Ok(2));
        // Unstable open loop 2/(s − 1): one counter-clockwise encirclement of −1 (stable CL).
        let l = Tf::new(&[2.0], &[1.0, -1.0]);
        assert_eq!(encirclements(&l, c(-1.0, 0.0)), Ok(-1));
        // Integrator with lag (pole on the axis): 1/(s(s+1)) has no encirclement of −1.
        let l = Tf::new(&[1.0], &[1.0, 1.0, 0.0]);
        assert_eq!(encirclements(&l, c(-1.0, 0.0)), Ok(0));
        // Through the point: undefined.
        let l = Tf::new(&[1.0], &[1.0, 1.0]);
        assert!(matches!(encirclements(&l, c(0.5, -0.5)), Err(NyquistError::ThroughPoint { .. })));
    }

    /// Graphical winding against root counting on random loops (including integrators and
    /// lightly damped modes) and random complex points.
    #[test]
    fn winding_agrees_with_root_count() {
        let mut rnd = crate::testutil::uniform(31u64);
        let mut nonzero = 0;
        for case in 0..200 {
            let mut den = Poly::new(&[1.0]);
            for _ in 0..(1 + case % 3) {
                let (w, z) = (0.1 + 10.0 * rnd(), -0.3 + 1.0 * rnd());
                den = den.mul(&Poly::new(&[1.0, 2.0 * z * w, w * w]));
            }
            if case % 4 == 0 {
                den = den.mul(&Poly::new(&[1.0, 0.0])); // integrator
            }
            let num = Poly::new(&[rnd() * 5.0, 1.0 + 20.0 * rnd()]);
            let l = Tf { num, den };
            let p = c(-3.0 + 6.0 * rnd(), -2.0 + 4.0 * rnd());
            let Ok(g) = encirclements(&l, p) else { continue };
            let r = encirclements_by_roots(&l, p);
            assert_eq!(Some(g), r, "case {case}: {l:?} around {p}");
            nonzero += usize::from(g != 0);
        }
        assert!(nonzero > 20, "{nonzero}");
    }
}
