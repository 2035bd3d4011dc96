//! The motor's and the inverter's I²t thermal models ([`Fault::MotorOverload`],
//! [`Fault::InverterOverload`]).

use super::ThermalLimit;
#[cfg(doc)]
use crate::fault::Fault;
use crate::frames::Abc;

crate::raw::raw_struct! {
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

impl ThermalConfig {
    /// θ of this model carried over to `to`, another discretisation of the same machine's
    /// model (a reconfiguration): the temperature rise is the machine's, θ is relative to the
    /// rise at the rated current (∝ I_rated²), so it scales with `I_old²/I_new²`. Kept as it
    /// is when either has no limit (no rated current to scale by).
    pub(crate) fn carry(&self, theta: f32, to: &ThermalConfig) -> f32 {
        if self.inv_rated2 > 0.0 && to.inv_rated2 > 0.0 {
            theta * (to.inv_rated2 / self.inv_rated2)
        } else {
            theta
        }
    }
}

/// The thermal models' states and the mean square current gathering for their next update:
/// the machine's and the inverter's temperature, so they carry on through every mode (the
/// motor cools while the bridge is off), an enable and a reconfiguration.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct ThermalState {
    /// Σ of the RMS phase current squared, A², over the slow steps since the last update,
    /// and their count.
    sum_a2: f32,
    steps: u16,
    /// θ of the motor's and the inverter's model (1 = the steady rise at the rated current).
    pub(crate) motor: f32,
    pub(crate) inverter: f32,
}

impl ThermalState {
    /// At the ambient temperature, nothing gathered.
    pub(crate) const COLD: Self = Self { sum_a2: 0.0, steps: 0, motor: 0.0, inverter: 0.0 };

    /// One slow step of the phase currents `i_abc`: the RMS phase current squared
    /// (|i_αβ|²/2, the Clarke transform being amplitude-invariant) averaged over
    /// [`THERMAL_UPDATE_SLOW_STEPS`], then one step of each model. `[motor, inverter]` at
    /// their limits ([`Fault::MotorOverload`], [`Fault::InverterOverload`]).
    #[inline]
    pub(crate) fn update(
        &mut self,
        motor: &ThermalConfig,
        inverter: &ThermalConfig,
        i_abc: Abc,
    ) -> [bool; 2] {
        let i = i_abc.clarke();
        let i2 = 0.5 * (i.alpha * i.alpha + i.beta * i.beta);
        if i2.is_finite() {
            self.sum_a2 += i2;
        }
        self.steps += 1;
        if self.steps < THERMAL_UPDATE_SLOW_STEPS {
            return [false; 2];
        }
        let mean = self.sum_a2 * (1.0 / THERMAL_UPDATE_SLOW_STEPS as f32);
        (self.sum_a2, self.steps) = (0.0, 0);
        [motor.update(&mut self.motor, mean), inverter.update(&mut self.inverter, mean)]
    }
}
