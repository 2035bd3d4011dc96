//! Space-vector modulation by min–max zero-sequence injection.
//!
//! For a requested stationary-frame voltage `v` and measured DC-bus voltage `V_dc`, the phase
//! references `v_abc = inverse_clarke(v)` receive the common-mode offset
//! `v_0 = −(max(v_abc) + min(v_abc))/2`, and each phase duty is
//! `d_x = 1/2 + (v_x + v_0)/V_dc` (duty = fraction of the period the upper switch conducts,
//! average phase-to-midpoint voltage `(d_x − 1/2)·V_dc`). This is equivalent to classical
//! SVPWM with equal zero-vector sharing.
//!
//! **Linear-range limit.** Duties stay in `[0, 1]` exactly when the phase-reference span
//! `max(v_abc) − min(v_abc)` is ≤ `V_dc`, i.e. inside the voltage hexagon (radius `V_dc/√3`
//! on its inscribed circle, `2V_dc/3` at its vertices). A request outside the hexagon is
//! scaled down by `V_dc/span` — the **voltage angle is preserved** and the result lies on the
//! hexagon boundary. The returned [`Modulation::saturated`] flag reports it. A non-positive or
//! non-finite bus voltage, or a non-finite request, yields 50 % duty on all phases
//! (zero voltage); the drive supervisor trips on such inputs before they get here.
//!
//! **Low-side shunt sampling** ([`modulate_sampled`]). A phase's current is measured in its
//! low-side shunt, which carries it only while the low-side switch conducts: around the top
//! of the count, `(1 − d)·T` per period. With `d_s` the highest duty that still leaves the
//! board's window, the span is limited to `d_s·V_dc` (the hexagon scaled by `d_s`: the
//! drive's usable bus) and the common mode is moved down (less of the top zero vector) by
//! as much as the highest centred duty exceeds `d_s`: every phase keeps its window, so all
//! three currents are measured in every period — the supervisor's current-sum checks need
//! the third — at the cost of `1 − d_s` of the voltage. (Rebuilding the highest phase from
//! the other two in every period keeps that voltage, but was measured to blind those checks
//! at top speed: docs/firmware.md; overmodulation, below, rebuilds it only where it must.)
//!
//! **Overmodulation** ([`overmodulate`], the drive file's `[controller] overmodulation`,
//! issue 52). Beyond the sampled hexagon one phase at a time may give up its window: the
//! lowest phase is held at duty 0, the highest may rise to `d_f` (1 less the dead-time
//! compensation's room), and the middle one stays at most `d_s`, so that two phases — the
//! lowest and the middle — are always measured and the third is their negative sum (the
//! drive rebuilds it only in the periods that lost it, and its current-sum checks skip those
//! samples). The region is the hexagon of `d_f` with its six vertices cut where the middle
//! phase would lose its window too: `span ≤ d_f·V_dc` and `mid − min ≤ d_s·V_dc`. A request
//! beyond it is scaled down onto it, the angle kept — the minimum-phase-error method of
//! S. Bolognani and M. Zigliotto ("Novel digital continuous control of SVM inverters in the
//! overmodulation range", IEEE Trans. Ind. Appl. 33(2), 1997), on this drive's cut hexagon.

use crate::frames::{Abc, AlphaBeta};
use crate::num::{finite_positive, max_f32, min_f32};

/// Result of one modulation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Modulation {
    /// Duty cycles of phases a, b, c, each in `[0, 1]`.
    pub duty: Abc,
    /// Stationary-frame voltage actually applied (after the hexagon limit), in V.
    pub v_applied: AlphaBeta,
    /// The request was outside the hexagon and has been scaled down.
    pub saturated: bool,
}

/// Radius of the circle inscribed in the hexagon: the largest sinusoidal phase-voltage peak
/// in the linear range, `V_dc/√3`.
#[inline]
pub fn linear_limit_v(vdc_v: f32) -> f32 {
    vdc_v * 0.577_350_26
}

/// Duty cycles for voltage `v` on a bus of `vdc_v` volts (see the module docs); every duty
/// up to 1 allowed ([`modulate_sampled`] with 1: no sampling window).
#[inline]
pub fn modulate(v: AlphaBeta, vdc_v: f32) -> Modulation {
    modulate_sampled(v, vdc_v, 1.0)
}

/// Duty cycles for voltage `v` on a bus of `vdc_v` volts with every duty at most
/// `duty_max` (the highest duty whose low-side window still holds a current sample; 1: no
/// window needed): the span limited to `duty_max·V_dc`, the common mode moved down (module
/// docs). `duty_max` in `(½, 1]` (the drive's configuration validates it).
///
/// Written as `d_x = d_max − (max − v_x)/V_dc` with `d_max = min(½ + ½·span/V_dc, duty_max)`
/// — the centred duties `½ + (v_x + v_0)/V_dc` of the module docs, less their excess over
/// `duty_max` — so that no duty needs a clamp: with `s = span/V_dc ≤ duty_max` (as rounded),
/// `(max − v_x)/V_dc ≤ s` by the monotony of rounding, and `d_max − s ≥ 0` exactly (`d_max ≥ s`
/// in both of its cases), so every duty lies in `[0, d_max]` (test
/// `sampled_duties_stay_within_the_window`). Three comparisons find the largest and smallest
/// phase; a NaN in `v` reaches `span` through them (α NaN: a NaN phase a becomes `lo`, then
/// `min`; β NaN: phases b and c are NaN, b becomes `hi`, then `max`), an infinite one makes
/// it infinite. A request beyond the hexagon, a non-finite one and a bad bus take the
/// out-of-line `modulate_limited` (with `saturated` set).
#[inline]
pub fn modulate_sampled(v: AlphaBeta, vdc_v: f32, duty_max: f32) -> Modulation {
    match duties_within(v, vdc_v, duty_max) {
        Some(duty) => Modulation { duty, v_applied: v, saturated: false },
        None => modulate_limited(v, vdc_v, duty_max),
    }
}

/// [`modulate_sampled`]'s duties when `v` lies inside the hexagon on a positive, finite
/// bus (then the voltage applied is `v`); `None` otherwise — a request beyond the hexagon,
/// a non-finite one or a bad bus, for the caller's out-of-line path
/// ([`modulate_sampled`]'s `modulate_limited`). The drive's fast step calls it directly, so
/// that its common path keeps the duties in registers (merged with the limited path's
/// result, they went through the stack: 11 instructions per fast step).
#[inline]
pub(crate) fn duties_within(v: AlphaBeta, vdc_v: f32, duty_max: f32) -> Option<Abc> {
    let abc = v.inverse_clarke();
    let (max, min) = extremes(abc);
    let span = max - min;
    let k = 1.0 / vdc_v;
    let s = span * k;
    // Inside the (scaled) hexagon on a positive, finite bus: false for a NaN span or bus, a
    // zero bus (s = ∞ or NaN), a negative one (k < 0) and an infinite one (k = 0).
    if !(s <= duty_max && k > 0.0) {
        return None;
    }
    let d_max = min_f32(0.5 + 0.5 * s, duty_max);
    let duty = |x: f32| d_max - (max - x) * k;
    Some(Abc { a: duty(abc.a), b: duty(abc.b), c: duty(abc.c) })
}

/// The largest and the smallest phase of `abc`, by three comparisons (a NaN reaches the
/// span `max − min`: see [`modulate_sampled`]).
#[inline(always)]
fn extremes(abc: Abc) -> (f32, f32) {
    let (hi, lo) = if abc.a > abc.b { (abc.a, abc.b) } else { (abc.b, abc.a) };
    let max = if abc.c > hi { abc.c } else { hi };
    let min = if abc.c < lo { abc.c } else { lo };
    (max, min)
}

/// [`modulate_sampled`] beyond the hexagon: the request scaled down to its boundary by
/// `duty_max·V_dc/span` (the angle kept), the largest duty at `duty_max`, the smallest at 0
/// (clamped: `duty_max − span·(duty_max/span)` may round below it); for a bus that is not
/// positive and finite or a request that is not finite, ½ on every phase (zero voltage).
/// Only for a request [`duties_within`] refused: one inside the hexagon it would scale *up*
/// to the boundary.
#[cold]
#[inline(never)]
pub(crate) fn modulate_limited(v: AlphaBeta, vdc_v: f32, duty_max: f32) -> Modulation {
    // The same operations as `duties_within`'s, so the same values.
    let abc = v.inverse_clarke();
    let (max, min) = extremes(abc);
    let span = max - min;
    let zero =
        Modulation { duty: Abc { a: 0.5, b: 0.5, c: 0.5 }, v_applied: AlphaBeta::default(), saturated: true };
    if !(finite_positive(vdc_v) && finite_positive(span)) {
        return zero;
    }
    let k = duty_max / span;
    // Comparisons, not `f32::clamp`: with a limit that is not a constant its panic path (and
    // core::fmt's float printing, ≈ 15 KB of flash) would be linked.
    let duty = |x: f32| max_f32(duty_max - (max - x) * k, 0.0);
    Modulation {
        duty: Abc { a: duty(abc.a), b: duty(abc.b), c: duty(abc.c) },
        v_applied: v.scale(duty_max * vdc_v / span),
        saturated: true,
    }
}

/// Duties for `v` beyond the sampled hexagon (module docs, "Overmodulation"): the lowest
/// phase at 0, the request applied as asked while its span is at most `duty_full·V_dc` and
/// its middle phase at most `duty_sampled·V_dc` above its lowest, scaled down onto that cut
/// hexagon beyond it (the angle kept, `saturated` set). Every duty in `[0, duty_full]`, the
/// middle one in `[0, duty_sampled]` up to rounding (the drive finds the phases without a
/// window from the duties themselves: [`unsampled_phases`]); for a bus that is not positive
/// and finite or a request that is not finite, ½ on every phase (zero voltage). For a request
/// `duties_within` refused at `duty_sampled` (inside the sampled hexagon it would not
/// centre the duties), with `½ < duty_sampled ≤ duty_full ≤ 1` (the configuration's).
#[cold]
#[inline(never)]
pub fn overmodulate(v: AlphaBeta, vdc_v: f32, duty_sampled: f32, duty_full: f32) -> Modulation {
    let abc = v.inverse_clarke();
    let (max, min) = extremes(abc);
    // The middle phase: the largest of the three pairwise minima.
    let mid = max_f32(max_f32(min_f32(abc.a, abc.b), min_f32(abc.b, abc.c)), min_f32(abc.a, abc.c));
    let span = max - min;
    if !(finite_positive(vdc_v) && finite_positive(span)) {
        return modulate_limited(v, vdc_v, duty_sampled);
    }
    // The request's share that fits: 1 inside the cut hexagon, else the binding side's
    // (a zero middle span divides to +∞, which `min_f32` passes over).
    let k = min_f32(min_f32(1.0, duty_full * vdc_v / span), duty_sampled * vdc_v / (mid - min));
    let scale = k / vdc_v;
    let duty = |x: f32| min_f32(max_f32((x - min) * scale, 0.0), duty_full);
    Modulation {
        duty: Abc { a: duty(abc.a), b: duty(abc.b), c: duty(abc.c) },
        v_applied: if k < 1.0 { v.scale(k) } else { v },
        saturated: k < 1.0,
    }
}

/// A duty this little above a window's limit is rounding, not a lost window (10⁻⁶ of a period,
/// 50 ps at 20 kHz; a timer count is ≈ 10⁻⁴): [`overmodulate`] puts the middle phase exactly
/// on the sampled limit along its cut edges, and the dead-time compensation added after it
/// reaches the window's limit exactly, each rounded. The simulator's shunts lose a window
/// beyond the limit by more than this; [`unsampled_phases`] counts half of it, so that its
/// own rounding of the limit never reads a phase the shunts lost. (Counted without it, the
/// drive took every sample along a cut edge for two phases lost and ran on predicted
/// currents: a torque reversal at top speed drove a healthy motor into `Overcurrent`.)
pub const WINDOW_ROUNDING_DUTY: f32 = 1e-6;

/// The phases whose duty leaves no low-side sampling window, as bits (a = 1, b = 2, c = 4):
/// above `window_duty`, the highest duty whose low side still conducts for the window (the
/// duties after the dead-time compensation: `duty_sampled` plus the compensation's room), by
/// more than half of [`WINDOW_ROUNDING_DUTY`].
#[inline]
pub fn unsampled_phases(duty: Abc, window_duty: f32) -> u8 {
    let limit = window_duty + 0.5 * WINDOW_ROUNDING_DUTY;
    u8::from(duty.a > limit) | u8::from(duty.b > limit) << 1 | u8::from(duty.c > limit) << 2
}

/// Dead-time compensation, per phase. During the dead time `t_d` after each commanded
/// switching both switches are off and the freewheeling diode chosen by the current's sign
/// sets the phase: a current out of the inverter (`i_x > 0`) pulls it to the lower rail, one
/// into it to the upper rail — on average a voltage error `−sign(i_x)·(t_d/T)·V_dc` per phase
/// (the simulator's switching inverter, `hil-sim/src/inverter.rs`, models exactly that). The
/// duty is raised by `(t_d/T)·s(i_x)`, where `s` is the sign made smooth by a linear ramp of
/// half-width `band_a` around zero, so that a current crossing zero — or the noise on it —
/// does not toggle the full correction. `i_abc_a` are the *reference* phase currents (smooth,
/// and ahead of the measured ones by the loops' lag); `dead_duty` = `t_d/T`. Duties stay in
/// `[0, 1]`.
#[inline]
pub fn compensate_dead_time(duty: Abc, i_abc_a: Abc, dead_duty: f32, band_a: f32) -> Abc {
    let k = dead_duty / band_a;
    let d = |d: f32, i: f32| compensate_phase(d, i, k, dead_duty);
    Abc { a: d(duty.a, i_abc_a.a), b: d(duty.b, i_abc_a.b), c: d(duty.c, i_abc_a.c) }
}

/// [`compensate_dead_time`] for the fast step's rare path (`Drive::fast_step_limited`): the
/// same operations, one phase at a time out of line: its own copy of the three phases
/// inlined took 288 B of the firmware's flash for a path that runs rarely (now 204 B).
/// The common path keeps [`compensate_dead_time`] inlined.
pub(crate) fn compensate_dead_time_rare(duty: Abc, i_abc_a: Abc, dead_duty: f32, band_a: f32) -> Abc {
    let k = dead_duty / band_a;
    let d = |d: f32, i: f32| compensate_phase_out_of_line(d, i, k, dead_duty);
    Abc { a: d(duty.a, i_abc_a.a), b: d(duty.b, i_abc_a.b), c: d(duty.c, i_abc_a.c) }
}

#[inline(never)]
fn compensate_phase_out_of_line(d: f32, i: f32, k: f32, dead_duty: f32) -> f32 {
    compensate_phase(d, i, k, dead_duty)
}

/// One phase's duty `d` compensated for the current `i`, `k` = `dead_duty/band_a`.
#[inline(always)]
fn compensate_phase(d: f32, i: f32, k: f32, dead_duty: f32) -> f32 {
    // Comparisons, not `f32::clamp` (a library call on the Cortex-M4F); a NaN current gives
    // −t_d/T, a finite duty.
    let s = min_f32(max_f32(k * i, -dead_duty), dead_duty);
    min_f32(max_f32(d + s, 0.0), 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frames::SinCos;
    use core::f32::consts::{PI, TAU};
    use proptest::prelude::*;

    /// Average phase-to-midpoint voltages reconstructed from duties, back to αβ.
    fn applied(m: &Modulation, vdc: f32) -> AlphaBeta {
        Abc { a: (m.duty.a - 0.5) * vdc, b: (m.duty.b - 0.5) * vdc, c: (m.duty.c - 0.5) * vdc }.clarke()
    }

    #[test]
    fn the_rare_paths_dead_time_compensation_is_the_common_paths() {
        let xs = [-1e30, -3.0, -0.004, -0.0, 0.0, 1e-9, 0.002, 0.5, 0.999, 7.0, f32::INFINITY, f32::NAN];
        for (k, &d) in xs.iter().enumerate() {
            for &i in &xs {
                let duty = Abc { a: d, b: xs[(k + 3) % xs.len()], c: 0.5 };
                let i_abc = Abc { a: i, b: -i, c: 0.5 * i };
                for (dead, band) in [(0.01, 0.004), (0.02, 1e-6), (0.0, 0.004)] {
                    let common = compensate_dead_time(duty, i_abc, dead, band);
                    let rare = compensate_dead_time_rare(duty, i_abc, dead, band);
                    let bits = |x: Abc| [x.a.to_bits(), x.b.to_bits(), x.c.to_bits()];
                    assert_eq!(bits(rare), bits(common), "{duty:?} {i_abc:?} {dead} {band}");
                }
            }
        }
    }

    #[test]
    fn zero_request_is_half_duty() {
        let m = modulate(AlphaBeta::default(), 300.0);
        assert_eq!(m.duty, Abc { a: 0.5, b: 0.5, c: 0.5 });
        assert!(!m.saturated);
    }

    #[test]
    fn inscribed_circle_is_linear_and_reaches_duty_limits() {
        let vdc = 310.0;
        let r = linear_limit_v(vdc);
        for k in 0..360 {
            let th = k as f32 * TAU / 360.0;
            let sc = SinCos::new(th);
            let v = AlphaBeta { alpha: r * 0.9999 * sc.cos, beta: r * 0.9999 * sc.sin };
            let m = modulate(v, vdc);
            assert!(!m.saturated, "inside the circle at {th}");
            let back = applied(&m, vdc);
            assert!((back.alpha - v.alpha).abs() < 1e-3 && (back.beta - v.beta).abs() < 1e-3);
        }
        // On the circle at a sector middle (30°), the span equals V_dc: duties touch 0 and 1.
        let v = AlphaBeta { alpha: r * libm::cosf(PI / 6.0), beta: r * libm::sinf(PI / 6.0) };
        let m = modulate(v, vdc);
        let dmax = m.duty.a.max(m.duty.b).max(m.duty.c);
        let dmin = m.duty.a.min(m.duty.b).min(m.duty.c);
        assert!((dmax - 1.0).abs() < 1e-5 && dmin.abs() < 1e-5);
    }

    #[test]
    fn hexagon_vertex_reaches_two_thirds_vdc() {
        let vdc = 100.0;
        let m = modulate(AlphaBeta { alpha: 2.0 * vdc / 3.0, beta: 0.0 }, vdc);
        assert!(!m.saturated);
        assert!((m.duty.a - 1.0).abs() < 1e-6 && m.duty.b.abs() < 1e-6 && m.duty.c.abs() < 1e-6);
    }

    #[test]
    fn beyond_the_hexagon_the_angle_is_preserved() {
        let vdc = 100.0;
        let req = AlphaBeta { alpha: 300.0, beta: 120.0 };
        let m = modulate(req, vdc);
        assert!(m.saturated);
        let back = applied(&m, vdc);
        let ang_req = libm::atan2f(req.beta, req.alpha);
        let ang_out = libm::atan2f(back.beta, back.alpha);
        assert!((ang_req - ang_out).abs() < 1e-5);
        // On the hexagon boundary: the duty span is exactly 1.
        let dmax = m.duty.a.max(m.duty.b).max(m.duty.c);
        let dmin = m.duty.a.min(m.duty.b).min(m.duty.c);
        assert!((dmax - dmin - 1.0).abs() < 1e-5);
        assert!((back.alpha - m.v_applied.alpha).abs() < 1e-3);
    }

    #[test]
    fn bad_bus_gives_zero_voltage() {
        for vdc in [0.0, -5.0, f32::NAN, f32::INFINITY] {
            let m = modulate(AlphaBeta { alpha: 10.0, beta: 0.0 }, vdc);
            assert_eq!(m.duty, Abc { a: 0.5, b: 0.5, c: 0.5 });
        }
        let m = modulate(AlphaBeta { alpha: f32::NAN, beta: 0.0 }, 300.0);
        assert_eq!(m.duty, Abc { a: 0.5, b: 0.5, c: 0.5 });
    }

    /// The compensation adds ±t_d/T beyond the band, a linear ramp inside it, and stays in
    /// [0, 1].
    #[test]
    fn dead_time_compensation_follows_the_current_sign() {
        let d = Abc { a: 0.5, b: 0.5, c: 0.999 };
        let c = compensate_dead_time(d, Abc { a: 2.0, b: -0.05, c: 3.0 }, 0.02, 0.1);
        assert!((c.a - 0.52).abs() < 1e-7 && (c.b - 0.49).abs() < 1e-7 && c.c == 1.0, "{c:?}");
        let c = compensate_dead_time(d, Abc { a: -2.0, b: 0.0, c: f32::NAN }, 0.02, 0.1);
        assert!((c.a - 0.48).abs() < 1e-7 && c.b == 0.5 && c.c.is_finite(), "{c:?}");
    }

    /// With a sampling limit: every duty at most the limit, the circle of the scaled
    /// hexagon applied as requested (only the common mode moves, and only down), beyond it the
    /// angle kept, the applied voltage the duties'.
    #[test]
    fn a_sampling_limit_keeps_every_phase_measured() {
        let (vdc, d_s) = (310.0, 0.94);
        let r0 = linear_limit_v(vdc);
        for k in 0..720 {
            let th = k as f32 * TAU / 720.0;
            let sc = SinCos::new(th);
            for r in [0.5, 0.88, 0.9399, 0.95, 1.0, 1.3, 2.0] {
                let v = AlphaBeta { alpha: r * r0 * sc.cos, beta: r * r0 * sc.sin };
                let m = modulate_sampled(v, vdc, d_s);
                for d in [m.duty.a, m.duty.b, m.duty.c] {
                    assert!((0.0..=d_s).contains(&d), "duty {d} at {th} rad, {r}");
                }
                let back = applied(&m, vdc);
                assert!(
                    (back.alpha - m.v_applied.alpha).abs() < 2e-3
                        && (back.beta - m.v_applied.beta).abs() < 2e-3
                );
                if r < d_s {
                    assert!(!m.saturated && m.v_applied == v, "{th} {r}");
                    let p = modulate(v, vdc);
                    let s = p.duty.a - m.duty.a;
                    assert!(
                        s >= -1e-6
                            && (s - (p.duty.b - m.duty.b)).abs() < 1e-5
                            && (s - (p.duty.c - m.duty.c)).abs() < 1e-5
                    );
                } else if m.saturated {
                    let (a0, a1) =
                        (libm::atan2f(v.beta, v.alpha), libm::atan2f(m.v_applied.beta, m.v_applied.alpha));
                    assert!((a0 - a1).abs() < 1e-4, "angle {a0} → {a1}");
                }
            }
        }
        // A vertex: d_s of the hexagon's, one phase at d_s, two at 0.
        let m = modulate_sampled(AlphaBeta { alpha: vdc, beta: 0.0 }, vdc, d_s);
        assert!((m.duty.a - d_s).abs() < 1e-6 && m.duty.b < 1e-6 && m.duty.c < 1e-6, "{m:?}");
        assert!((m.v_applied.alpha - d_s * 2.0 * vdc / 3.0).abs() < 1e-3);
        // No limit: exactly `modulate`.
        let v = AlphaBeta { alpha: 150.0, beta: 90.0 };
        assert_eq!(modulate_sampled(v, vdc, 1.0), modulate(v, vdc));
    }

    /// Overmodulation: inside the sampled hexagon nothing to do (the caller's common path);
    /// beyond it the request applied exactly up to the cut hexagon, the angle kept beyond
    /// it; the lowest phase at 0, the highest at most `d_f`, the middle at most `d_s` — so at
    /// most one phase loses its window — and the duties' voltage the one reported applied.
    #[test]
    fn overmodulation_gives_up_one_window_at_a_time() {
        let (vdc, d_s, d_f) = (310.0f32, 0.94f32, 0.98f32);
        let r0 = linear_limit_v(vdc);
        let mut fundamental = [0.0f32; 2];
        for k in 0..3600 {
            let th = k as f32 * TAU / 3600.0;
            let sc = SinCos::new(th);
            for (n, r) in [0.95f32, 0.98, 1.0, 1.05, 1.1, 1.2, 3.0, 100.0].into_iter().enumerate() {
                let v = AlphaBeta { alpha: r * r0 * sc.cos, beta: r * r0 * sc.sin };
                if duties_within(v, vdc, d_s).is_some() {
                    continue;
                }
                let m = overmodulate(v, vdc, d_s, d_f);
                let d = [m.duty.a, m.duty.b, m.duty.c];
                let lo = d.iter().copied().fold(f32::MAX, f32::min);
                assert!(lo == 0.0, "{th} {r}: {m:?}");
                assert!(d.iter().all(|&x| (0.0..=d_f).contains(&x)), "{th} {r}: {m:?}");
                assert!(unsampled_phases(m.duty, d_s).count_ones() <= 1, "{th} {r}: {m:?}");
                let back = applied(&m, vdc);
                assert!(
                    (back.alpha - m.v_applied.alpha).abs() < 2e-3
                        && (back.beta - m.v_applied.beta).abs() < 2e-3
                );
                let (a0, a1) =
                    (libm::atan2f(v.beta, v.alpha), libm::atan2f(m.v_applied.beta, m.v_applied.alpha));
                assert!((a0 - a1).abs() < 1e-4, "angle {a0} → {a1}");
                if !m.saturated {
                    assert_eq!(m.v_applied, v);
                }
                if n == 7 {
                    // Far beyond: the boundary's fundamental over a turn (accumulated below).
                    fundamental[0] += m.v_applied.alpha * sc.cos + m.v_applied.beta * sc.sin;
                    fundamental[1] += 1.0;
                }
            }
        }
        // A request of 1.05 × the circle at a side's middle (30°) is applied whole: beyond
        // the sampled hexagon, within the full one.
        let v = AlphaBeta { alpha: 1.0 * r0 * libm::cosf(PI / 6.0), beta: 1.0 * r0 * libm::sinf(PI / 6.0) };
        let m = overmodulate(v.scale(0.97), vdc, d_s, d_f);
        assert!(!m.saturated && unsampled_phases(m.duty, d_s) == 1, "{m:?}");
        // At a vertex of one phase high (0°) the span binds: that phase at d_f, the other two
        // at 0 and measured; at one of two phases high (180°) the middle phase binds: both at
        // d_s.
        let m = overmodulate(AlphaBeta { alpha: vdc, beta: 0.0 }, vdc, d_s, d_f);
        assert!(
            m.saturated && (m.duty.a - d_f).abs() < 1e-6 && m.duty.b.abs() < 1e-6 && m.duty.c.abs() < 1e-6,
            "{m:?}"
        );
        let m = overmodulate(AlphaBeta { alpha: -vdc, beta: 0.0 }, vdc, d_s, d_f);
        assert!(
            m.saturated && (m.duty.b - d_s).abs() < 1e-6 && (m.duty.c - d_s).abs() < 1e-6 && m.duty.a == 0.0,
            "{m:?}"
        );
        // The cut hexagon's boundary, followed at an even angle, has a fundamental between
        // the sampled hexagon's circle and six-step's 2/π·V_dc.
        let f = fundamental[0] / fundamental[1];
        assert!(f > d_s * r0 && f < 2.0 / PI * vdc, "fundamental {} of the circle", f / r0);
        // Bad inputs: zero voltage.
        for (v, vdc) in
            [(AlphaBeta { alpha: f32::NAN, beta: 0.0 }, 300.0), (AlphaBeta { alpha: 10.0, beta: 0.0 }, 0.0)]
        {
            assert_eq!(overmodulate(v, vdc, d_s, d_f).duty, Abc { a: 0.5, b: 0.5, c: 0.5 });
        }
    }

    proptest! {
        #[test]
        fn duties_always_in_unit_interval(alpha in -1e6f32..1e6, beta in -1e6f32..1e6,
                                          vdc in 1e-3f32..1e4) {
            let m = modulate(AlphaBeta { alpha, beta }, vdc);
            for d in [m.duty.a, m.duty.b, m.duty.c] {
                prop_assert!((0.0..=1.0).contains(&d));
            }
        }

        /// The unclamped duties of `modulate_sampled`: every duty in `[0, duty_max]` exactly
        /// (no tolerance: the limit is the low-side sampling window), inside the hexagon and
        /// beyond it, for any window, bus and request — requests near the hexagon's scaled
        /// boundary, where rounding decides which path runs, included (the radius drawn
        /// around it), and tiny ones; and the voltage applied the request itself inside.
        #[test]
        fn sampled_duties_stay_within_the_window(
            angle in -4.0f32..4.0,
            radius in prop_oneof![0.0f32..2.0, 0.999f32..1.001, 0.0f32..1e-6],
            duty_max in prop_oneof![0.5001f32..1.0, Just(1.0f32), Just(0.9f32)],
            vdc in prop_oneof![1e-3f32..1e4, Just(310.0f32)],
        ) {
            // radius 1: the scaled hexagon's inscribed circle at the worst angle is at
            // duty_max·V_dc/√3; its vertices at duty_max·2V_dc/3.
            let sc = crate::frames::SinCos::new(angle);
            let r = radius * duty_max * vdc * (2.0 / 3.0);
            let v = AlphaBeta { alpha: r * sc.cos, beta: r * sc.sin };
            let m = modulate_sampled(v, vdc, duty_max);
            for d in [m.duty.a, m.duty.b, m.duty.c] {
                prop_assert!((0.0..=duty_max).contains(&d), "duty {} of {} ({:?})", d, duty_max, m);
            }
            if !m.saturated {
                prop_assert_eq!(m.v_applied, v);
            }
        }
    }
}
