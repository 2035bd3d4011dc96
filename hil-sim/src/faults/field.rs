//! When the field's turn lets the drive see a fault that takes one phase away: a switch stuck
//! open ([`Injection::SwitchOpen`]: one direction of its phase's current) or an open lead
//! ([`Injection::OpenPhase`]: both). Phase k's reference is `|i|·cos(θ − k·2π/3)`, the
//! reference vector at angle θ (αβ) at the injection turning at the field's measured speed
//! ω_e (signed; `Matrix::run_one` measures both on the references before the injection). The
//! phase checks count a phase's sample only where its reference reaches
//! [`SWITCH_LEVEL_SHARE`] of the vector's magnitude — within 60° of a peak: before that the
//! missing current is a fraction of the amplitude (at rest, where the field turns at the slip
//! frequency, a few per cent of it for tens of milliseconds), below what the checks resolve.
//! Each function returns a time from the injection, s: infinite for a field that does not
//! turn (or was not measured) and never brings what the check needs.

#[cfg(doc)]
use crate::sim::Injection;
use controller_core::supervisor::phases::SWITCH_LEVEL_SHARE;
use std::f64::consts::{PI, TAU};

/// The angle of phase `phase`'s peak in the direction a switch stuck open takes away
/// (`upper`: the positive current), rad.
fn dead_peak_rad(phase: usize, upper: bool) -> f64 {
    phase as f64 * TAU / 3.0 + if upper { 0.0 } else { PI }
}

/// The first peak, after the injection, of phase `phase`'s reference in the dead direction
/// (`upper`: the positive current), the reference vector at `theta0_rad` turning at
/// `omega_e_rad_s`. Injected past that direction's peak, the switch still acts on the
/// half-wave's waning rest, but its first whole half-wave — the first peak the dead switch
/// misses — comes a turn later: from the first need plus a quarter turn, as the bound was
/// first written, it ran from the peak the switch had carried while healthy (the shipped
/// DeLorenzo motor at 4 kHz, injected at the end of the positive half-wave: detected 69 ms
/// after, 15 ms after the next peak, against a bound of 64 ms).
pub fn dead_peak_after_s(phase: usize, upper: bool, theta0_rad: f64, omega_e_rad_s: f64) -> f64 {
    let ahead = ((dead_peak_rad(phase, upper) - theta0_rad) * omega_e_rad_s.signum()).rem_euclid(TAU);
    let t = ahead / omega_e_rad_s.abs();
    if t.is_nan() { f64::INFINITY } else { t }
}

/// The first moment phase `phase`'s reference reaches [`SWITCH_LEVEL_SHARE`] of the
/// reference vector's magnitude (either direction: within 60° of a peak) — 0 if it is there
/// at the injection — the vector at `theta0_rad` turning at `omega_e_rad_s`.
pub fn phase_asked_after_s(phase: usize, theta0_rad: f64, omega_e_rad_s: f64) -> f64 {
    let half_width = f64::from(SWITCH_LEVEL_SHARE).acos();
    // The phase's angle from its nearest positive or negative peak, in [0, π).
    let from_peak = (theta0_rad - phase as f64 * TAU / 3.0).rem_euclid(PI);
    if from_peak <= half_width || from_peak >= PI - half_width {
        return 0.0;
    }
    // Turning forward the phase nears the next peak (at π), backward the last one (at 0).
    let ahead = if omega_e_rad_s >= 0.0 { PI - half_width - from_peak } else { from_peak - half_width };
    let t = ahead / omega_e_rad_s.abs();
    if t.is_nan() { f64::INFINITY } else { t }
}
