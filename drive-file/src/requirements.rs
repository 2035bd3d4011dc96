//! `[requirements]` (issue 51): what the user asks of the drive, in the units a
//! motor-control engineer states them in — the nonlinear campaign judges every run against
//! them (`hil_sim::campaign`), not against the drive's own speed law.
//!
//! ```toml
//! [requirements]                   # optional; absent keys take these defaults
//! speed_error_fraction = 0.01      # steady |ω − ω*| under load, × the base speed
//! speed_overshoot_fraction = 0.1   # of a speed step
//! speed_rise_time_s = 0.2          # 10 → 90 % of a step, or RISE_TIME_FACTOR × the least if longer; default: that
//! speed_settling_time_s = 0.5      # into the settling band, or SETTLING_TIME_FACTOR × the least; default: that
//! load_dip_fraction = 0.1          # largest |ω − ω*| after a load step, × the base speed, or the board's least
//! load_recovery_time_s = 0.5       # back within the speed-error band, or SETTLING_TIME_FACTOR × the least; default: the settling time allowed
//! torque_accuracy_fraction = 0.05  # steady |τ − τ*| (the torque the drive commands), × τ_max
//! flux_accuracy_fraction = 0.05    # steady |ψ_r − ψ_r*|, × controller.flux_ref_wb
//! current_bandwidth_hz = 1000.0    # least current-loop crossover on every corner; default f_pwm/20
//! ```
//!
//! **Scales come from physics, not from a shipped motor.** Speeds are fractions of the
//! motor's *base speed* on the bus it runs on — the speed at which its rated flux with no
//! load needs the whole linear voltage V_dc/√3, the speed an engineer states regulation
//! against ("±1 % of base speed") — plus one count of the encoder's speed resolution, the
//! least error the board can see. Times the file does not state are multiples of the
//! *least*: the time the motor, accelerating at the most torque it can give at each speed on
//! that bus and current limit (its physical envelope, from the T-equivalent circuit alone)
//! and at most τ_max, takes for the same step — and, for the error left near the target, no
//! faster than the fastest speed loop the board's encoder allows
//! (`hil_sim::requirements::least_step_times`). A drive that needs twice that to rise
//! leaves half the motor's torque unused on average; the factors below are that policy,
//! stated once. A stated time holds for the steps neither the torque limit nor the board
//! binds: a step that needs longer is allowed the factor × its least. A stated dip likewise
//! gives way to the least a load step makes under that loop.

use crate::source::{FileError, Source, num};
use serde::Deserialize;

/// Default steady-state speed error under load, × the base speed: ±1 %, a closed-loop
/// vector drive's usual speed regulation (an encoder drive's is ±0.01–0.1 %).
pub const DEFAULT_SPEED_ERROR_FRACTION: f64 = 0.01;
/// Default speed-step overshoot, × the step.
pub const DEFAULT_SPEED_OVERSHOOT_FRACTION: f64 = 0.1;
/// Default largest speed deviation after a load step, × the base speed.
pub const DEFAULT_LOAD_DIP_FRACTION: f64 = 0.1;
/// Default steady-state torque error, × τ_max.
pub const DEFAULT_TORQUE_ACCURACY_FRACTION: f64 = 0.05;
/// Default steady-state rotor-flux error, × the rated flux.
pub const DEFAULT_FLUX_ACCURACY_FRACTION: f64 = 0.05;
/// Default least current-loop bandwidth: the PWM rate over this (a sampled current loop's
/// crossover lies a decade or more below the sampling rate; 1 kHz at 20 kHz).
pub const DEFAULT_CURRENT_BANDWIDTH_DIVISOR: f64 = 20.0;
/// A speed step's default rise time (10 → 90 %): this many times the least (motor and board).
pub const RISE_TIME_FACTOR: f64 = 2.0;
/// A speed step's default settling time: this many times the least time into the
/// settling band.
pub const SETTLING_TIME_FACTOR: f64 = 3.0;
/// The settling band, × the step (the control engineer's 2 % band), or the speed-error band
/// if that is wider: a drive asked to regulate to ±x has settled once within ±x.
pub const SETTLING_BAND_FRACTION: f64 = 0.02;

/// The longest time a requirement may state, s: ten minutes, beyond any speed step or load
/// recovery a drive is specified for (a fan's run-up takes a minute or two) — and the
/// campaign runs each half of a run at least as long as the times it judges
/// (`speed_rise_time_s = 1e300` ran forever: found by trying).
pub const MAX_TIME_S: f64 = 600.0;

/// `[requirements]` as written (every key optional).
#[derive(Debug, Clone, Copy, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RequirementsTable {
    /// Steady-state speed error under load, × the base speed.
    pub speed_error_fraction: Option<f64>,
    /// Speed-step overshoot, × the step.
    pub speed_overshoot_fraction: Option<f64>,
    /// Speed-step rise time, 10 → 90 %, s.
    pub speed_rise_time_s: Option<f64>,
    /// Speed-step settling time into the settling band, s.
    pub speed_settling_time_s: Option<f64>,
    /// Largest speed deviation after a load step, × the base speed.
    pub load_dip_fraction: Option<f64>,
    /// Time after a load step until the speed stays within the speed-error band, s.
    pub load_recovery_time_s: Option<f64>,
    /// Steady-state torque error against the torque commanded, × τ_max.
    pub torque_accuracy_fraction: Option<f64>,
    /// Steady-state rotor-flux error against its reference, × the rated flux.
    pub flux_accuracy_fraction: Option<f64>,
    /// Least current-loop bandwidth (crossover) on every corner, Hz.
    pub current_bandwidth_hz: Option<f64>,
}

/// One requirement, by the key that states it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Requirement {
    /// `speed_error_fraction`.
    SpeedError,
    /// `speed_overshoot_fraction`.
    SpeedOvershoot,
    /// `speed_rise_time_s`.
    SpeedRiseTime,
    /// `speed_settling_time_s`.
    SpeedSettlingTime,
    /// `load_dip_fraction`.
    LoadDip,
    /// `load_recovery_time_s`.
    LoadRecoveryTime,
    /// `torque_accuracy_fraction`.
    TorqueAccuracy,
    /// `flux_accuracy_fraction`.
    FluxAccuracy,
    /// `current_bandwidth_hz`.
    CurrentBandwidth,
}

impl Requirement {
    /// Every requirement, in the file's order (the campaign's are the first eight, the
    /// speed's the first six: `hil_sim::campaign` takes them so).
    pub const ALL: [Requirement; 9] = [
        Self::SpeedError,
        Self::SpeedOvershoot,
        Self::SpeedRiseTime,
        Self::SpeedSettlingTime,
        Self::LoadDip,
        Self::LoadRecoveryTime,
        Self::TorqueAccuracy,
        Self::FluxAccuracy,
        Self::CurrentBandwidth,
    ];

    /// Its key in `[requirements]`.
    pub fn key(self) -> &'static str {
        match self {
            Self::SpeedError => "speed_error_fraction",
            Self::SpeedOvershoot => "speed_overshoot_fraction",
            Self::SpeedRiseTime => "speed_rise_time_s",
            Self::SpeedSettlingTime => "speed_settling_time_s",
            Self::LoadDip => "load_dip_fraction",
            Self::LoadRecoveryTime => "load_recovery_time_s",
            Self::TorqueAccuracy => "torque_accuracy_fraction",
            Self::FluxAccuracy => "flux_accuracy_fraction",
            Self::CurrentBandwidth => "current_bandwidth_hz",
        }
    }
}

impl core::fmt::Display for Requirement {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "requirements.{}", self.key())
    }
}

/// Validated requirements, defaults filled in. A time is `None` where the file states
/// none: the judge derives it from the least ([`Requirements::rise_time_allowed_s`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Requirements {
    /// Steady-state speed error under load, × the base speed.
    pub speed_error_fraction: f64,
    /// Speed-step overshoot, × the step.
    pub speed_overshoot_fraction: f64,
    /// Speed-step rise time (10 → 90 %), s ([`Requirements::rise_time_allowed_s`]).
    pub speed_rise_time_s: Option<f64>,
    /// Settling time into the band, s ([`Requirements::settling_time_allowed_s`]).
    pub speed_settling_time_s: Option<f64>,
    /// Largest speed deviation after a load step, × the base speed.
    pub load_dip_fraction: f64,
    /// Recovery time after a load step, s; `None`: the settling time allowed.
    pub load_recovery_time_s: Option<f64>,
    /// Steady-state torque error, × τ_max.
    pub torque_accuracy_fraction: f64,
    /// Steady-state rotor-flux error, × the rated flux.
    pub flux_accuracy_fraction: f64,
    /// Least current-loop bandwidth, Hz.
    pub current_bandwidth_hz: f64,
}

impl Requirements {
    /// The defaults for a drive switching at `pwm_frequency_hz`.
    pub fn defaults(pwm_frequency_hz: f64) -> Self {
        Self {
            speed_error_fraction: DEFAULT_SPEED_ERROR_FRACTION,
            speed_overshoot_fraction: DEFAULT_SPEED_OVERSHOOT_FRACTION,
            speed_rise_time_s: None,
            speed_settling_time_s: None,
            load_dip_fraction: DEFAULT_LOAD_DIP_FRACTION,
            load_recovery_time_s: None,
            torque_accuracy_fraction: DEFAULT_TORQUE_ACCURACY_FRACTION,
            flux_accuracy_fraction: DEFAULT_FLUX_ACCURACY_FRACTION,
            current_bandwidth_hz: pwm_frequency_hz / DEFAULT_CURRENT_BANDWIDTH_DIVISOR,
        }
    }

    /// The rise time allowed for a step whose least rise time (motor and board) is `least_s`, s:
    /// [`RISE_TIME_FACTOR`] × it, or the stated time if longer — a stated time is for the
    /// steps the torque limit does not bind (no drive raises a large step faster than the
    /// motor's torque allows).
    pub fn rise_time_allowed_s(&self, least_s: f64) -> f64 {
        let physical = RISE_TIME_FACTOR * least_s;
        self.speed_rise_time_s.map_or(physical, |t| t.max(physical))
    }

    /// The settling time allowed for a step whose least time into the band is
    /// `least_s`, s: [`SETTLING_TIME_FACTOR`] × it, or the stated time if longer.
    pub fn settling_time_allowed_s(&self, least_s: f64) -> f64 {
        let physical = SETTLING_TIME_FACTOR * least_s;
        self.speed_settling_time_s.map_or(physical, |t| t.max(physical))
    }

    /// The recovery time allowed after a load step whose least recovery (motor and board) is
    /// `least_s`, where a speed step of the same run would be allowed `settling_allowed_s` to
    /// settle, s: the stated time, else that settling time — or [`SETTLING_TIME_FACTOR`] ×
    /// the least if longer.
    pub fn recovery_time_allowed_s(&self, settling_allowed_s: f64, least_s: f64) -> f64 {
        self.load_recovery_time_s.unwrap_or(settling_allowed_s).max(SETTLING_TIME_FACTOR * least_s)
    }
}

impl RequirementsTable {
    /// Validate for a drive switching at `pwm_frequency_hz`; errors point at the value.
    pub fn validate(&self, src: &Source<'_>, pwm_frequency_hz: f64) -> Result<Requirements, FileError> {
        let d = Requirements::defaults(pwm_frequency_hz);
        // Fractions: in (0, 1] — a requirement of zero no sampled drive meets; a speed error
        // or dip of the whole base speed (or more) asks nothing; an overshoot of the whole
        // step is a reversal of the error.
        let fraction = |r: Requirement, x: Option<f64>, default: f64| -> Result<f64, FileError> {
            let Some(x) = x else { return Ok(default) };
            src.check(
                x.is_finite() && x > 0.0 && x <= 1.0,
                &r.to_string(),
                &format!("is {}; must lie in (0, 1]", num(x)),
            )?;
            Ok(x)
        };
        let time = |r: Requirement, x: Option<f64>| -> Result<Option<f64>, FileError> {
            let Some(x) = x else { return Ok(None) };
            src.check(
                x.is_finite() && x > 0.0 && x <= MAX_TIME_S,
                &r.to_string(),
                &format!("is {}; must be a positive number of seconds, at most {MAX_TIME_S}", num(x)),
            )?;
            Ok(Some(x))
        };
        let bandwidth = match self.current_bandwidth_hz {
            None => d.current_bandwidth_hz,
            Some(x) => {
                // Above the Nyquist rate no sampled loop has a crossover.
                let most = 0.5 * pwm_frequency_hz;
                src.check(
                    x.is_finite() && x > 0.0 && x < most,
                    &Requirement::CurrentBandwidth.to_string(),
                    &format!(
                        "is {} Hz; must lie in (0, {}) Hz — below half the PWM rate (pwm.frequency_hz)",
                        num(x),
                        num(most)
                    ),
                )?;
                x
            }
        };
        use Requirement as R;
        Ok(Requirements {
            speed_error_fraction: fraction(R::SpeedError, self.speed_error_fraction, d.speed_error_fraction)?,
            speed_overshoot_fraction: fraction(
                R::SpeedOvershoot,
                self.speed_overshoot_fraction,
                d.speed_overshoot_fraction,
            )?,
            speed_rise_time_s: time(R::SpeedRiseTime, self.speed_rise_time_s)?,
            speed_settling_time_s: time(R::SpeedSettlingTime, self.speed_settling_time_s)?,
            load_dip_fraction: fraction(R::LoadDip, self.load_dip_fraction, d.load_dip_fraction)?,
            load_recovery_time_s: time(R::LoadRecoveryTime, self.load_recovery_time_s)?,
            torque_accuracy_fraction: fraction(
                R::TorqueAccuracy,
                self.torque_accuracy_fraction,
                d.torque_accuracy_fraction,
            )?,
            flux_accuracy_fraction: fraction(
                R::FluxAccuracy,
                self.flux_accuracy_fraction,
                d.flux_accuracy_fraction,
            )?,
            current_bandwidth_hz: bandwidth,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::DriveFile;
    use std::path::Path;

    fn parse(text: &str) -> Result<DriveFile, FileError> {
        DriveFile::parse(Path::new("d.toml"), text)
    }

    /// The shipped file states five requirements; the rest take the defaults. A file without
    /// the table takes every default (the current bandwidth from its 20 kHz PWM).
    #[test]
    fn stated_requirements_and_defaults() {
        let r = DriveFile::shipped().unwrap().requirements;
        assert_eq!(
            (r.speed_error_fraction, r.load_dip_fraction, r.speed_rise_time_s),
            (0.25, 0.25, Some(0.6))
        );
        assert_eq!(r.flux_accuracy_fraction, 0.1);
        assert_eq!(
            (r.torque_accuracy_fraction, r.speed_settling_time_s),
            (DEFAULT_TORQUE_ACCURACY_FRACTION, None)
        );
        assert_eq!(r.current_bandwidth_hz, 500.0);
        let start = crate::SHIPPED.find("[requirements]").unwrap();
        let end = crate::SHIPPED.find("[board]").unwrap();
        let bare = format!("{}{}", &crate::SHIPPED[..start], &crate::SHIPPED[end..]);
        assert_eq!(parse(&bare).unwrap().requirements, Requirements::defaults(20_000.0));
    }

    /// A stated time holds for small steps; a step the torque limit binds is allowed the
    /// factor × its least.
    #[test]
    fn allowed_times_are_the_stated_or_the_physical() {
        let r = DriveFile::shipped().unwrap().requirements;
        assert_eq!(r.rise_time_allowed_s(0.1), 0.6);
        assert_eq!(r.rise_time_allowed_s(1.0), RISE_TIME_FACTOR);
        assert_eq!(r.settling_time_allowed_s(0.1), SETTLING_TIME_FACTOR * 0.1);
        assert_eq!(r.recovery_time_allowed_s(0.7, 0.1), 0.7);
        assert_eq!(r.recovery_time_allowed_s(0.7, 1.0), SETTLING_TIME_FACTOR);
    }

    /// Bad values are refused at their key: a zero or negative fraction, a fraction above
    /// one, a time of zero, a bandwidth at or above half the PWM rate, an unknown key.
    #[test]
    fn bad_requirements_are_refused_at_their_key() {
        // The line in place of the shipped file's own for that key, if it states one.
        let with = |line: &str| {
            let key = line.split(' ').next().unwrap_or_default();
            let kept: String = crate::SHIPPED
                .lines()
                .filter(|l| !l.starts_with(&format!("{key} ")))
                .map(|l| format!("{l}\n"))
                .collect();
            kept.replace("[requirements]\n", &format!("[requirements]\n{line}\n"))
        };
        for (line, key, says) in [
            ("torque_accuracy_fraction = 0.0", "requirements.torque_accuracy_fraction", "must lie in (0, 1]"),
            ("overshoot = 0.1", "", "unknown field `overshoot`"),
            ("speed_overshoot_fraction = 1.5", "requirements.speed_overshoot_fraction", "must lie in (0, 1]"),
            ("load_recovery_time_s = 0.0", "requirements.load_recovery_time_s", "positive number of seconds"),
            ("speed_rise_time_s = 1e300", "requirements.speed_rise_time_s", "at most 600"),
            (
                "current_bandwidth_hz = 10000.0",
                "requirements.current_bandwidth_hz",
                "below half the PWM rate",
            ),
            ("current_bandwidth_hz = nan", "requirements.current_bandwidth_hz", "must lie in (0, 10000) Hz"),
        ] {
            let e = parse(&with(line)).unwrap_err();
            assert!(e.to_string().contains(says), "{line}: {e}");
            if !key.is_empty() {
                assert_eq!(e.key.as_deref(), Some(key), "{line}: {e}");
            }
        }
    }
}
