//! The rotor at rest: what the standstill tests of commissioning need before they start
//! (`Drive::rotor_at_rest`). Watched in every mode from the encoder's track, so that the
//! answer is there when commissioning is asked for.
//!
//! The standstill tests (DC levels, decays, injections: `crate::commission`) read the
//! rotor's answer to a stator field that does not turn. A rotor turning at the electrical
//! speed ω_r = p·ω_m sees that field turn at ω_r, and its impedance is `R_r(1 + j·ω_r·T_r)`
//! instead of `R_r`: the time constant a decay test fits is off by ≈ (ω_r·T_r)²/2. "At
//! rest" is therefore the rotor's own time constant's, not a fixed speed: `ω_r·T_r` at most
//! [`REST_SPEED_TR`] (0.05: 0.1 % on T_r), measured over a window long enough for the
//! encoder to resolve that speed (the drive file's `protection.rest_time_s`, derived from
//! the line count: `drive_file::drive::default_rest_time_s`).

use crate::raw::raw_struct;

/// The largest `p·|ω_m|·T_r` that counts as at rest (the module docs).
pub const REST_SPEED_TR: f64 = 0.05;

/// Consecutive windows the rotor must have been at rest in: one window's displacement can
/// cancel in a swing.
pub const REST_WINDOWS: u8 = 2;

raw_struct! {
    /// The rest check's levels (the drive configuration's).
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub(crate) struct RestLimits {
        /// The window, slow steps (`rest_time_s`, at least one).
        pub(crate) window_slow_steps: u32,
        /// The most the shaft may turn over a window and be at rest, mechanical rad:
        /// [`REST_SPEED_TR`]/(p·T_r) over the window.
        pub(crate) angle_rad: f32,
    }
}

impl RestLimits {
    /// The levels of a window of `rest_time_s` (finite and positive: `DriveConfig::new`
    /// checks it first) on a slow period of `t_slow_s`, for a motor of `pole_pairs` and rotor
    /// time constant `tr_s`.
    pub(crate) fn new(rest_time_s: f64, t_slow_s: f64, pole_pairs: u8, tr_s: f64) -> Self {
        let steps = libm::ceil(rest_time_s / t_slow_s).clamp(1.0, 4e9);
        let rest_rad_s = REST_SPEED_TR / (f64::from(pole_pairs) * tr_s);
        Self { window_slow_steps: steps as u32, angle_rad: (rest_rad_s * steps * t_slow_s) as f32 }
    }
}

/// The rest check's state: the shaft's (kept by an enable and a reconfiguration).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct RestWatch {
    /// The shaft's displacement since the window's start, mechanical rad: the sum of the
    /// encoder's wrapped changes per read (exact however far the shaft has turned, which a
    /// difference of multi-turn positions in f32 is not: above 65 536 rad its step exceeds
    /// the shipped window's 6.2e-3 rad).
    moved_rad: f32,
    /// Slow steps into the window.
    steps: u32,
    /// Consecutive windows at rest (saturating).
    quiet: u8,
}

impl RestWatch {
    /// Nothing watched yet.
    pub(crate) const NONE: Self = Self { moved_rad: 0.0, steps: 0, quiet: 0 };

    /// One slow step in which the shaft turned by `step_rad` (the encoder's change over the
    /// read): at the window's end, at rest if it turned at most `angle_rad` over it.
    #[inline]
    pub(crate) fn update(&mut self, limits: &RestLimits, step_rad: f32) {
        self.moved_rad += step_rad;
        self.steps += 1;
        if self.steps < limits.window_slow_steps {
            return;
        }
        let still = self.moved_rad.abs() <= limits.angle_rad;
        self.quiet = if still { self.quiet.saturating_add(1) } else { 0 };
        (self.moved_rad, self.steps) = (0.0, 0);
    }

    /// At rest over the last [`REST_WINDOWS`] windows.
    pub(crate) fn at_rest(&self) -> bool {
        self.quiet >= REST_WINDOWS
    }
}
