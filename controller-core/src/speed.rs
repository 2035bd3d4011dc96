//! Speed and position loops (slow rate).
//!
//! * Speed PI, e.g. seed 000 eq. (35) PI2 = (50s + 250)/s, whose output is `i_qs*` (A).
//! * Torque-limited saturated P, seed 002 eq. (21):
//!   `τ_ref = sat_{±τ_max}(k_p·(ω_ref − ω_r))` — no integral action, so a steady-state error
//!   remains under load (as the paper notes); during a large step the torque saturates and
//!   the machine accelerates on a constant-torque ramp.
//! * Position loop around the speed loop (seed 002 Fig. 12/14): P law
//!   `ω_ref = sat_{±ω_max}(k_θ·(θ_ref − θ))`.
//!
//! Speeds are *mechanical* rad/s.

use crate::discretize::Discretization;
use crate::ifoc::TorqueCommand;
use crate::num::Scalar;
use crate::pi::{PiConfig, PiError, PiState};

/// Continuous description of a speed law.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SpeedLaw {
    /// PI producing a torque reference (N·m), limited to ±`limit`.
    PiTorque {
        /// N·m per rad/s.
        kp: f64,
        /// N·m per rad.
        ki: f64,
        /// Torque limit, N·m.
        limit: f64,
    },
    /// PI producing an `i_qs*` reference (A), limited to ±`limit` (seed 000 PI2).
    PiIq {
        /// A per rad/s.
        kp: f64,
        /// A per rad.
        ki: f64,
        /// Current limit, A.
        limit: f64,
    },
    /// Seed 002 eq. (21).
    SaturatedP {
        /// N·m per rad/s.
        kp: f64,
        /// τ_max, N·m.
        tau_max_nm: f64,
    },
}

impl SpeedLaw {
    /// Seed 000 eq. (35): PI2 = (50s + 250)/s, output i_qs* limited to ±`iq_max_a`.
    pub const fn pi2_seed000(iq_max_a: f64) -> Self {
        SpeedLaw::PiIq { kp: 50.0, ki: 250.0, limit: iq_max_a }
    }
}

/// Why a speed or position law was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SpeedError {
    /// PI rejected.
    Pi(PiError),
    /// Gain negative or not finite.
    Gain,
    /// Limit not finite and positive.
    Limit,
}

impl core::fmt::Display for SpeedError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Pi(e) => write!(f, "{e}"),
            Self::Gain => f.write_str("the gain is negative or not finite"),
            Self::Limit => f.write_str("the limit is not finite and positive"),
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Law {
    Pi { pi: PiConfig<f32>, torque: bool },
    SaturatedP { kp: f32, tau_max: f32 },
}

/// Discrete speed controller configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpeedControllerConfig {
    law: Law,
}

/// Speed controller state (PI terms are telemetry; unused by the P law).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SpeedState {
    /// PI state.
    pub pi: PiState<f32>,
}

fn check_gain(x: f64) -> Result<(), SpeedError> {
    if x.is_finite() && x >= 0.0 { Ok(()) } else { Err(SpeedError::Gain) }
}
fn check_limit(x: f64) -> Result<(), SpeedError> {
    if x.is_finite() && x > 0.0 { Ok(()) } else { Err(SpeedError::Limit) }
}

impl SpeedControllerConfig {
    /// Discretise `law` for the slow-loop period `ts_s` (Tustin).
    pub fn new(law: &SpeedLaw, ts_s: f64) -> Result<Self, SpeedError> {
        let law = match *law {
            SpeedLaw::PiTorque { kp, ki, limit } | SpeedLaw::PiIq { kp, ki, limit } => {
                check_limit(limit)?;
                let pi = PiConfig::new(kp, ki, ts_s, Discretization::Tustin, -limit, limit)
                    .map_err(SpeedError::Pi)?;
                Law::Pi { pi, torque: matches!(law, SpeedLaw::PiTorque { .. }) }
            }
            SpeedLaw::SaturatedP { kp, tau_max_nm } => {
                check_gain(kp)?;
                check_limit(tau_max_nm)?;
                Law::SaturatedP { kp: kp as f32, tau_max: tau_max_nm as f32 }
            }
        };
        Ok(Self { law })
    }

    /// Magnitude limit of the output (N·m for torque laws, A for the i_q law).
    pub fn output_limit(&self) -> f32 {
        match &self.law {
            Law::Pi { pi, .. } => pi.limits().1,
            Law::SaturatedP { tau_max, .. } => *tau_max,
        }
    }

    /// One slow step: speed reference and measurement (mechanical rad/s) → torque command.
    #[inline]
    pub fn update(&self, s: &mut SpeedState, omega_ref_rad_s: f32, omega_m_rad_s: f32) -> TorqueCommand {
        self.update_limited(s, omega_ref_rad_s, omega_m_rad_s, self.output_limit())
    }

    /// [`Self::update`] with the output limited to `±limit` (the law's units; the drive
    /// passes the smaller of the law's own limit and what the bus can deliver at this speed),
    /// so that the PI's integrator stops where the torque does ([`crate::pi`]).
    #[inline]
    pub fn update_limited(
        &self,
        s: &mut SpeedState,
        omega_ref_rad_s: f32,
        omega_m_rad_s: f32,
        limit: f32,
    ) -> TorqueCommand {
        let e = omega_ref_rad_s - omega_m_rad_s;
        match &self.law {
            Law::Pi { pi, torque: true } => {
                TorqueCommand::TorqueNm(pi.update_limited(&mut s.pi, e, -limit, limit))
            }
            Law::Pi { pi, torque: false } => {
                TorqueCommand::IqA(pi.update_limited(&mut s.pi, e, -limit, limit))
            }
            Law::SaturatedP { kp, .. } => TorqueCommand::TorqueNm((kp * e).limit(-limit, limit)),
        }
    }

    /// The law's output is a torque (N·m), not an i_q (A).
    pub fn is_torque(&self) -> bool {
        !matches!(self.law, Law::Pi { torque: false, .. })
    }
}

/// Position loop configuration: P with speed-reference saturation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PositionConfig {
    k_per_s: f32,
    omega_max_rad_s: f32,
}

impl PositionConfig {
    /// `ω_ref = sat(k_per_s·(θ_ref − θ), ±omega_max_rad_s)`.
    pub fn new(k_per_s: f64, omega_max_rad_s: f64) -> Result<Self, SpeedError> {
        check_gain(k_per_s)?;
        check_limit(omega_max_rad_s)?;
        Ok(Self { k_per_s: k_per_s as f32, omega_max_rad_s: omega_max_rad_s as f32 })
    }

    /// Position reference and measurement (mechanical rad, not wrapped) → speed reference.
    #[inline]
    pub fn update(&self, theta_ref_rad: f32, theta_m_rad: f32) -> f32 {
        (self.k_per_s * (theta_ref_rad - theta_m_rad)).limit(-self.omega_max_rad_s, self.omega_max_rad_s)
    }
}

impl SpeedControllerConfig {
    pub(crate) fn put(&self, w: &mut crate::raw::Writer) {
        match &self.law {
            Law::Pi { pi, torque } => {
                w.u(if *torque { 0 } else { 1 });
                pi.put(w);
            }
            Law::SaturatedP { kp, tau_max } => {
                w.u(2);
                for x in [*kp, *tau_max, 0.0, 0.0] {
                    w.f(x);
                }
            }
        }
    }

    /// `None` for an unknown law tag.
    /// The law from [`Self::put`]'s numbers; an unknown tag sets the reader's `bad` (the
    /// configuration is refused).
    pub(crate) fn get(r: &mut crate::raw::Reader<'_>) -> Self {
        let tag = r.u();
        // The same four slots: a PI's (kp, ki/K, u_min, u_max), or the P law's (kp, τ_max, 0, 0).
        let pi = PiConfig::get(r);
        let law = match tag {
            0 => Law::Pi { pi, torque: true },
            1 => Law::Pi { pi, torque: false },
            2 => Law::SaturatedP { kp: pi.kp(), tau_max: pi.ki_over_k() },
            _ => {
                r.bad = true;
                Law::Pi { pi, torque: true }
            }
        };
        Self { law }
    }

    /// The saturated-P law (seed 002 eq. (21)) with new gains, checked in f32 (what the
    /// firmware's `WriteSpeedGains` does without the f64 design path). `None` for another
    /// law, or a gain that is negative or not finite (τ_max: not positive).
    pub fn with_saturated_p(&self, kp: f32, tau_max_nm: f32) -> Option<Self> {
        let ok = kp.is_finite() && kp >= 0.0 && tau_max_nm.is_finite() && tau_max_nm > 0.0;
        match self.law {
            Law::SaturatedP { .. } if ok => Some(Self { law: Law::SaturatedP { kp, tau_max: tau_max_nm } }),
            _ => None,
        }
    }

    /// `(k_p, τ_max)` of a saturated-P law.
    pub fn saturated_p(&self) -> Option<(f32, f32)> {
        match self.law {
            Law::SaturatedP { kp, tau_max } => Some((kp, tau_max)),
            Law::Pi { .. } => None,
        }
    }
}

impl PositionConfig {
    pub(crate) fn put(&self, w: &mut crate::raw::Writer) {
        w.f(self.k_per_s);
        w.f(self.omega_max_rad_s);
    }

    pub(crate) fn get(r: &mut crate::raw::Reader<'_>) -> Self {
        Self { k_per_s: r.f(), omega_max_rad_s: r.f() }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn saturated_p_eq21() {
        let c = SpeedControllerConfig::new(&SpeedLaw::SaturatedP { kp: 0.1, tau_max_nm: 2.0 }, 1e-3).unwrap();
        let mut s = SpeedState::default();
        assert_eq!(c.update(&mut s, 376.0, 0.0), TorqueCommand::TorqueNm(2.0));
        assert_eq!(c.update(&mut s, -376.0, 0.0), TorqueCommand::TorqueNm(-2.0));
        let TorqueCommand::TorqueNm(t) = c.update(&mut s, 110.0, 100.0) else { panic!() };
        assert!((t - 1.0).abs() < 1e-6);
    }

    /// Constant-torque ramp while saturated: J·dω/dt = τ_max on a frictionless rotor, so ω
    /// rises at τ_max/J until k_p·e < τ_max, then approaches ω_ref exponentially (time
    /// constant J/k_p) with no overshoot.
    #[test]
    fn saturated_p_gives_constant_torque_ramp() {
        let (j, tau_max, ts) = (0.01f32, 1.0f32, 1e-3f32);
        let c =
            SpeedControllerConfig::new(&SpeedLaw::SaturatedP { kp: 0.05, tau_max_nm: 1.0 }, 1e-3).unwrap();
        let mut s = SpeedState::default();
        let mut w = 0.0f32;
        for k in 0..400 {
            let TorqueCommand::TorqueNm(t) = c.update(&mut s, 100.0, w) else { panic!() };
            if k < 300 {
                // saturated while 0.05·(100 − ω) > 1, i.e. ω < 80 → first 80/(τ/J) = 0.8 s
                let expected = tau_max / j * (k as f32) * ts;
                if expected < 79.0 {
                    assert!((w - expected).abs() < 1e-3, "k={k} w={w}");
                }
            }
            w += t / j * ts;
            assert!(w <= 100.0);
        }
    }

    #[test]
    fn pi2_outputs_iq_and_respects_limit() {
        let c = SpeedControllerConfig::new(&SpeedLaw::pi2_seed000(20.0), 1e-3).unwrap();
        let mut s = SpeedState::default();
        // PI2 = 50 + 250/s: error 0.1 rad/s → 5 A + integral.
        let TorqueCommand::IqA(i) = c.update(&mut s, 0.1, 0.0) else { panic!() };
        assert!((i - (5.0 + 250.0 * 1e-3 * 0.5 * 0.1)).abs() < 1e-4);
        let TorqueCommand::IqA(i) = c.update(&mut s, 100.0, 0.0) else { panic!() };
        assert_eq!(i, 20.0);
    }

    #[test]
    fn position_p_saturates_speed() {
        let p = PositionConfig::new(20.0, 50.0).unwrap();
        // Seed 002 Fig. 14 step of 6.28 rad (one turn, 2π).
        let step = core::f32::consts::TAU;
        assert_eq!(p.update(step, 0.0), 50.0);
        assert!((p.update(step, 6.0) - 20.0 * (step - 6.0)).abs() < 1e-4);
        assert_eq!(p.update(-step, 0.0), -50.0);
    }

    #[test]
    fn rejects_bad_laws() {
        assert_eq!(
            SpeedControllerConfig::new(&SpeedLaw::SaturatedP { kp: -1.0, tau_max_nm: 1.0 }, 1e-3),
            Err(SpeedError::Gain)
        );
        assert_eq!(
            SpeedControllerConfig::new(&SpeedLaw::SaturatedP { kp: 1.0, tau_max_nm: 0.0 }, 1e-3),
            Err(SpeedError::Limit)
        );
        assert_eq!(PositionConfig::new(1.0, f64::NAN), Err(SpeedError::Limit));
    }
}
