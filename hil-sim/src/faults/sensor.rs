//! When a current sensor's fault counts as acting: the matrix's bound for a sensor row runs
//! from there, as a stuck switch's does from its first use.
//!
//! The error is the sum all three channels read on the true currents,
//! Σ(g_k − 1)·i_k + (b − b₀) — the fault's gain and its offset against the healthy channel's
//! (calibrated away at power-up) with the healthy channels' gain errors, which the check
//! cannot tell from it and which may cancel part of it. The level is the current-sum check's
//! windowed one as the check takes it (means over an open-phase window: its level plus its
//! share of Σ|i| for the healthy channels' gain errors), raised by the check's resolution,
//! [`SENSOR_VERDICT_SIGMAS`] standard deviations of a window's mean of the channels' noise
//! and quantisation ([`sensor_window_sigma_a`]). The fault acts from when the error's mean
//! over a window came clear of that level and stayed so for a whole window, which puts the
//! end of one of the check's own windows inside the stretch (a window's mean is the sliding
//! mean at its end).
//!
//! A gain error on a phase carrying no current makes no error, and at standstill, where the
//! field turns at the slip frequency, a phase may carry little for tens of milliseconds.
//! Each looser reading failed a healthy check on the population: from a single reading
//! above the level, a gain of 0.5 on a phase held near its zero crossing (the 2.8 kW member
//! 007 at standstill generating, i_b within ±0.8 A of zero against 5 A in the others) failed
//! its row by 42 ms; from the sliding mean's first touch of the level, a dead sensor on a
//! phase crossing zero (member 086: the error rose to its level for a millisecond, fell
//! back, came again 8 ms later) by 1 ms, and a gain of 0.5 whose error sat at the level
//! (member 153, 35 kW, generating: 3.3 A within 0.4 A of it for 13 ms, phase c's +0.5 %
//! gain taking 0.15 A of it) by 3.4 ms.

use crate::sensors::SensorModel;
use crate::sim::Injection;
use std::collections::VecDeque;

/// A current sensor's fault counts as acting once the channels' sum error, averaged over an
/// open-phase window, exceeds the windowed current-sum check's level by this many standard
/// deviations of the window's mean of their noise ([`sensor_window_sigma_a`]): a verdict the
/// noise turns once in 740 windows. At the level itself the check's verdict is the noise's.
pub const SENSOR_VERDICT_SIGMAS: f64 = 3.0;

/// The standard deviation of the current sum's mean over `samples` readings of the three
/// channels of `sensors`: each channel's noise and its quantisation (uniform over one count:
/// `lsb/√12`), independent, A.
pub fn sensor_window_sigma_a(sensors: &SensorModel, samples: u32) -> f64 {
    let per_channel = sensors.current_noise_rms_a.powi(2) + sensors.current_lsb_a.powi(2) / 12.0;
    (3.0 * per_channel / f64::from(samples.max(1))).sqrt()
}

/// A sensor fault's error against the check's level, period by period after the injection
/// (the module's rule).
pub(super) struct SensorActing {
    /// The three channels' gains after the fault.
    gains: [f64; 3],
    /// The faulty channel's offset against the healthy one's, A.
    offset_error_a: f64,
    /// The windowed level with the check's resolution, A.
    level_a: f64,
    /// The check's window in PWM periods (its samples are slow steps).
    window: usize,
    /// The last window's [error, level] per period, and their sums, A.
    rows: VecDeque<[f64; 2]>,
    sums: [f64; 2],
    /// The time from which the window's mean error has been clear of the level, and for how
    /// many periods.
    clear: Option<(f64, usize)>,
}

impl SensorActing {
    /// For `injection` on `sensors` (None unless it is a current sensor's fault), against the
    /// windowed level `current_sum_mean_max_a` over the drive's open-phase window of
    /// `samples` slow steps, a slow step every `slow_divider` PWM periods.
    pub(super) fn new(
        injection: &Injection,
        sensors: &SensorModel,
        current_sum_mean_max_a: f64,
        samples: u32,
        slow_divider: u16,
    ) -> Option<Self> {
        let Injection::CurrentSensor { phase, gain, offset_a } = *injection else {
            return None;
        };
        let mut gains = sensors.current_gain;
        if let Some(g) = gains.get_mut(phase) {
            *g = gain;
        }
        let healthy_offset = sensors.current_offset_a.get(phase).copied().unwrap_or(0.0);
        Some(Self {
            gains,
            offset_error_a: offset_a - healthy_offset,
            level_a: current_sum_mean_max_a + SENSOR_VERDICT_SIGMAS * sensor_window_sigma_a(sensors, samples),
            window: (samples as usize * usize::from(slow_divider)).max(1),
            rows: VecDeque::new(),
            sums: [0.0; 2],
            clear: None,
        })
    }

    /// One PWM period, `t_s` after the injection, of the true phase currents `i_abc_a`: the
    /// time the error came clear of the level, once it has stayed so for a whole window.
    pub(super) fn add(&mut self, t_s: f64, i_abc_a: [f64; 3]) -> Option<f64> {
        let share = f64::from(controller_core::drive::CURRENT_SENSOR_GAIN_TOLERANCE);
        let [ga, gb, gc] = self.gains;
        let [a, b, c] = i_abc_a;
        let row = [
            ((ga - 1.0) * a + (gb - 1.0) * b + (gc - 1.0) * c + self.offset_error_a).abs(),
            self.level_a + share * (a.abs() + b.abs() + c.abs()),
        ];
        self.rows.push_back(row);
        self.sums = [self.sums[0] + row[0], self.sums[1] + row[1]];
        if self.rows.len() > self.window
            && let Some([e, l]) = self.rows.pop_front()
        {
            self.sums = [self.sums[0] - e, self.sums[1] - l];
        }
        // The periods before the injection in the window carry no error.
        let level = self.sums[1] / self.rows.len() as f64 * self.window as f64;
        self.clear = (self.sums[0] >= level).then(|| self.clear.map_or((t_s, 1), |(from, n)| (from, n + 1)));
        self.clear.and_then(|(from, n)| (n >= self.window).then_some(from))
    }
}
