//! The motor's and the inverter's I²t thermal models ([`Fault::MotorOverload`],
//! [`Fault::InverterOverload`]).

use super::ThermalLimit;
#[cfg(doc)]
use crate::fault::Fault;

/// A thermal limit, discretised ([`ThermalLimit`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct ThermalConfig {
    /// 1/I_rated², 1/A².
    pub(crate) inv_rated2: f32,
    /// θ += (x − θ)·gain every [`THERMAL_UPDATE_SLOW_STEPS`].
    pub(crate) gain: f32,
    /// Trip at θ ≥ this (`f32::MAX`: no limit).
    pub(crate) limit: f32,
}

impl ThermalConfig {
    pub(crate) const NONE: Self = Self { inv_rated2: 0.0, gain: 0.0, limit: f32::MAX };

    /// The limit `t` (`None`: no limit) discretised for a slow period of `t_slow_s`; `None`
    /// for an invalid limit (not finite, not positive, an overload factor outside [1, 10]).
    pub(crate) fn new(t: Option<&ThermalLimit>, t_slow_s: f64) -> Option<Self> {
        let Some(t) = t else { return Some(Self::NONE) };
        let ok = [t.rated_current_a, t.time_constant_s, t.overload_factor].iter().all(|x| x.is_finite())
            && t.rated_current_a > 0.0
            && t.time_constant_s > 0.0
            && t.overload_factor >= 1.0
            && t.overload_factor <= 10.0;
        if !ok {
            return None;
        }
        let dt = f64::from(THERMAL_UPDATE_SLOW_STEPS) * t_slow_s;
        Some(Self {
            inv_rated2: (1.0 / (t.rated_current_a * t.rated_current_a)) as f32,
            gain: (1.0 - libm::exp(-dt / t.time_constant_s)) as f32,
            limit: (t.overload_factor * t.overload_factor) as f32,
        })
    }

    /// θ after a period of mean squared RMS current `i2_a2`; `true` at the limit.
    #[inline]
    pub(crate) fn update(&self, theta: &mut f32, i2_a2: f32) -> bool {
        *theta += (i2_a2 * self.inv_rated2 - *theta) * self.gain;
        *theta >= self.limit
    }
}

/// The thermal models are updated with the mean squared current of this many slow steps
/// (0.5 s at the shipped 2 kHz): in f32, an update every slow step would be smaller than the
/// rounding of θ for thermal time constants of minutes.
pub const THERMAL_UPDATE_SLOW_STEPS: u16 = 1000;
