//! Speed and position loops (slow rate).
//!
//! * Speed PI, e.g. seed 000 eq. (35) PI2 = (50s + 250)/s, whose output is `i_qs*` (A),
//!   with two degrees of freedom: the user's speed reference reaches it through the
//!   **setpoint-weight prefilter** `F(s) = (b·s + z)/(s + z)`, `z = k_i/k_p` — the response
//!   to a reference of the PI whose proportional term sees `b·ω_ref − ω` (Åström & Hägglund,
//!   *PID Controllers: Theory, Design and Tuning*, 1995, §4.5 "set-point weighting"), while
//!   the response to a load is the PI's own. `b = 1` is the one-degree PI; a smaller `b`
//!   takes out the zero's overshoot of a reference step, not the load's dip. A prefilter,
//!   not the weight inside the PI: there the integrator would hold `(1 − b)·k_p·ω_ref`
//!   beside the load — on the 24 V walk-through drive k_p·ω_ref alone is ≈ 4 × its torque
//!   limit (0.00636 N·m·s/rad × 75.5 rad/s against 0.12 N·m) — and its clamp to that limit
//!   leaves a steady error under load.
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
        /// Setpoint weight `b` in [0, 1] (the module docs; 1: the one-degree PI).
        setpoint_weight: f64,
    },
    /// PI producing an `i_qs*` reference (A), limited to ±`limit` (seed 000 PI2).
    PiIq {
        /// A per rad/s.
        kp: f64,
        /// A per rad.
        ki: f64,
        /// Current limit, A.
        limit: f64,
        /// Setpoint weight `b` in [0, 1] (the module docs; 1: the one-degree PI).
        setpoint_weight: f64,
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
        SpeedLaw::PiIq { kp: 50.0, ki: 250.0, limit: iq_max_a, setpoint_weight: 1.0 }
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
    /// Setpoint weight not in [0, 1].
    SetpointWeight,
}

impl core::fmt::Display for SpeedError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Pi(e) => write!(f, "{e}"),
            Self::Gain => f.write_str("the gain is negative or not finite"),
            Self::Limit => f.write_str("the limit is not finite and positive"),
            Self::SetpointWeight => f.write_str("the setpoint weight is not within [0, 1]"),
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Law {
    Pi { pi: PiConfig<f32>, torque: bool, prefilter: Prefilter },
    SaturatedP { kp: f32, tau_max: f32 },
}

/// The setpoint-weight prefilter `F(s) = (b·s + z)/(s + z)` (the module docs), discretised:
/// `r_lp ← r_lp + α·(ω_ref − r_lp)`, `ω_ref,f = b·ω_ref + (1 − b)·r_lp`, with
/// `α = 1 − e^{−z·T}` (the first-order lag exact for a reference held over the period).
/// `F = b + (1 − b)·z/(s + z)`: the weight passes at once, the rest through the lag.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Prefilter {
    weight: f32,
    alpha: f32,
}

impl Prefilter {
    /// For weight `b` of a PI `k_p + k_i/s` sampled every `ts_s`. The lag passes at once
    /// (α = 1, F = 1) where the PI has no zero to take out: `k_p = 0` (an integral law, z
    /// infinite) and `k_i = 0` (a P law, z = 0, where F would be the constant b). α is at
    /// least the least normal f32, so that a very slow lag stays one `from_raw` accepts.
    fn new(b: f64, kp: f64, ki: f64, ts_s: f64) -> Result<Self, SpeedError> {
        if !(b.is_finite() && (0.0..=1.0).contains(&b)) {
            return Err(SpeedError::SetpointWeight);
        }
        let alpha = if kp > 0.0 && ki > 0.0 {
            (1.0 - libm::exp(-ki / kp * ts_s)).max(f64::from(f32::MIN_POSITIVE))
        } else {
            1.0
        };
        Ok(Self { weight: b as f32, alpha: alpha as f32 })
    }
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
    /// The prefilter's lag, rad/s ([`SpeedControllerConfig::reference`]).
    reference_lag_rad_s: f32,
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
            SpeedLaw::PiTorque { kp, ki, limit, setpoint_weight }
            | SpeedLaw::PiIq { kp, ki, limit, setpoint_weight } => {
                check_limit(limit)?;
                let pi = PiConfig::new(kp, ki, ts_s, Discretization::Tustin, -limit, limit)
                    .map_err(SpeedError::Pi)?;
                let prefilter = Prefilter::new(setpoint_weight, kp, ki, ts_s)?;
                Law::Pi { pi, torque: matches!(law, SpeedLaw::PiTorque { .. }), prefilter }
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

    /// One slow step: the user's speed reference (through [`Self::reference`]) and the
    /// measurement (mechanical rad/s) → torque command.
    #[inline]
    pub fn update(&self, s: &mut SpeedState, omega_ref_rad_s: f32, omega_m_rad_s: f32) -> TorqueCommand {
        let w = self.reference(s, omega_ref_rad_s);
        self.update_limited(s, w, omega_m_rad_s, self.output_limit())
    }

    /// The speed reference the loop follows for the user's `omega_ref_rad_s`: through the
    /// setpoint-weight prefilter of a PI law (the module docs), one slow step of it; the
    /// reference itself for `b = 1` (bit for bit) and for the P law.
    #[inline]
    pub fn reference(&self, s: &mut SpeedState, omega_ref_rad_s: f32) -> f32 {
        let Law::Pi { prefilter: p, .. } = &self.law else { return omega_ref_rad_s };
        let lag = &mut s.reference_lag_rad_s;
        *lag += p.alpha * (omega_ref_rad_s - *lag);
        p.weight * omega_ref_rad_s + (1.0 - p.weight) * *lag
    }

    /// A reference that must reach the loop as it is — the position loop's, whose design
    /// ends at the speed loop: passed unfiltered, and the prefilter's lag follows it, so that
    /// a speed reference after it starts from there.
    #[inline]
    pub fn pass_reference(&self, s: &mut SpeedState, omega_ref_rad_s: f32) -> f32 {
        s.reference_lag_rad_s = omega_ref_rad_s;
        omega_ref_rad_s
    }

    /// The PI or P on a speed reference already shaped ([`Self::reference`] or
    /// [`Self::pass_reference`]), its output limited to `±limit` (the law's units; the drive
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
            Law::Pi { pi, torque: true, .. } => {
                TorqueCommand::TorqueNm(pi.update_limited(&mut s.pi, e, -limit, limit))
            }
            Law::Pi { pi, torque: false, .. } => {
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

crate::raw::raw_struct! {
    /// Position loop configuration: P with speed-reference saturation.
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct PositionConfig {
        k_per_s: f32,
        omega_max_rad_s: f32,
    }
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

/// A tag (0: PI to torque, 1: PI to i_q, 2: saturated P) and six floats: the PI's and its
/// prefilter's, or the P law's in the same slots.
impl crate::raw::Field for SpeedControllerConfig {
    const NF: usize = <PiConfig<f32> as crate::raw::Field>::NF + 2;
    const NU: usize = 1;

    fn put(&self, w: &mut crate::raw::Writer) {
        match &self.law {
            Law::Pi { pi, torque, prefilter } => {
                w.u(if *torque { 0 } else { 1 });
                crate::raw::Field::put(pi, w);
                w.f(prefilter.weight);
                w.f(prefilter.alpha);
            }
            Law::SaturatedP { kp, tau_max } => {
                w.u(2);
                for x in [*kp, *tau_max, 0.0, 0.0, 1.0, 1.0] {
                    w.f(x);
                }
            }
        }
    }

    /// The law from `put`'s numbers; an unknown tag sets the reader's `bad` (the
    /// configuration is refused).
    #[inline(always)]
    fn get(r: &mut crate::raw::Reader<'_>) -> Self {
        let tag = r.u();
        // The same six slots: a PI's (kp, ki/K, u_min, u_max, b, α), or the P law's
        // (kp, τ_max, 0, 0, 1, 1).
        let pi = <PiConfig<f32> as crate::raw::Field>::get(r);
        let prefilter = Prefilter { weight: r.f(), alpha: r.f() };
        // A weight within [0, 1] and a lag that moves and does not overshoot, as `new` makes.
        if !((0.0..=1.0).contains(&prefilter.weight) && prefilter.alpha > 0.0 && prefilter.alpha <= 1.0) {
            r.bad = true;
        }
        let law = match tag {
            0 => Law::Pi { pi, torque: true, prefilter },
            1 => Law::Pi { pi, torque: false, prefilter },
            2 => Law::SaturatedP { kp: pi.kp(), tau_max: pi.ki_over_k() },
            _ => {
                r.bad = true;
                Law::Pi { pi, torque: true, prefilter }
            }
        };
        Self { law }
    }
}

impl SpeedControllerConfig {
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

    /// A PI `k_p + k_i/s` on `J dω/dt = τ − τ_L` (J 0.01 kg·m², ζ ≈ 0.5 with a zero near its
    /// poles: the linear step overshoots), sampled at 2 kHz: the speed after `n` slow steps of
    /// reference `w_ref` and a load `load_nm` from step `load_at` on.
    fn pi_run(b: f64, w_ref: f32, load_nm: f32, load_at: usize, n: usize) -> std::vec::Vec<f32> {
        let (j, ts) = (0.01f32, 5e-4f32);
        let law = SpeedLaw::PiTorque { kp: 0.2, ki: 4.0, limit: 100.0, setpoint_weight: b };
        let c = SpeedControllerConfig::new(&law, f64::from(ts)).unwrap();
        let mut s = SpeedState::default();
        let mut w = 0.0f32;
        (0..n)
            .map(|k| {
                let TorqueCommand::TorqueNm(t) = c.update(&mut s, w_ref, w) else { panic!() };
                let load = if k >= load_at { load_nm } else { 0.0 };
                w += (t - load) / j * ts;
                w
            })
            .collect()
    }

    /// The setpoint weight (Åström & Hägglund's set-point weighting, as the prefilter
    /// `F(s) = (b·s + z)/(s + z)`): b = 1 is the one-degree PI, bit for bit; a smaller b
    /// lowers the linear step's overshoot — b = 0 leaves the second-order poles alone — and
    /// leaves the load's response as it was.
    #[test]
    fn the_setpoint_weight_shapes_the_reference_response_not_the_loads() {
        let law = SpeedLaw::PiTorque { kp: 0.2, ki: 4.0, limit: 100.0, setpoint_weight: 1.0 };
        let c = SpeedControllerConfig::new(&law, 5e-4).unwrap();
        let mut s = SpeedState::default();
        for w in [3.0f32, -7.25, 1e-3, 0.0] {
            assert_eq!(c.reference(&mut s, w).to_bits(), w.to_bits());
        }
        // One step of the prefilter: b at once, the lag's α = 1 − e^{−z·T} of the rest.
        let half = SpeedLaw::PiTorque { kp: 0.2, ki: 4.0, limit: 100.0, setpoint_weight: 0.5 };
        let c = SpeedControllerConfig::new(&half, 5e-4).unwrap();
        let mut s = SpeedState::default();
        let alpha = 1.0 - (-20.0f64 * 5e-4).exp();
        assert!((f64::from(c.reference(&mut s, 10.0)) - (5.0 + 5.0 * alpha)).abs() < 1e-5);
        // The position loop's reference passes, and the lag follows it (no bump after).
        assert_eq!(c.pass_reference(&mut s, 4.0), 4.0);
        assert_eq!(c.reference(&mut s, 4.0), 4.0);
        // Without integral action there is no zero to take out: the reference passes.
        let p_only = SpeedLaw::PiTorque { kp: 0.2, ki: 0.0, limit: 100.0, setpoint_weight: 0.5 };
        let c = SpeedControllerConfig::new(&p_only, 5e-4).unwrap();
        assert_eq!(c.reference(&mut SpeedState::default(), 10.0), 10.0);
        // Overshoot of a linear step (1 rad/s: k_p·e well inside the limit).
        let overshoot = |b: f64| {
            let w = pi_run(b, 1.0, 0.0, usize::MAX, 4000);
            w.iter().fold(0.0f32, |m, &x| m.max(x)) - 1.0
        };
        // ζ = k_p/(2√(k_i·J)) = 0.5: 16 % from the poles alone; the zero at z = 20 rad/s,
        // beside them, makes it 30 %.
        let (one, none) = (overshoot(1.0), overshoot(0.0));
        assert!((0.27..0.33).contains(&one), "b = 1: {one}");
        assert!((0.14..0.18).contains(&none), "b = 0: {none}");
        assert!(overshoot(0.5) < one && overshoot(0.5) > none);
        // The load's response: the reference long settled, the same for every weight.
        let [a, b] = [1.0, 0.0].map(|b| pi_run(b, 1.0, 0.5, 3000, 6000));
        let dip = |w: &[f32]| w.iter().skip(3000).fold(f32::MAX, |m, &x| m.min(x));
        assert!((dip(&a) - dip(&b)).abs() < 1e-4, "{} {}", dip(&a), dip(&b));
        assert!((a[5999] - 1.0).abs() < 1e-3 && (b[5999] - 1.0).abs() < 1e-3, "no droop: integral action");
    }

    #[test]
    fn a_setpoint_weight_outside_0_1_is_refused() {
        for b in [-0.1, 1.5, f64::NAN] {
            let law = SpeedLaw::PiTorque { kp: 0.2, ki: 4.0, limit: 1.0, setpoint_weight: b };
            assert_eq!(SpeedControllerConfig::new(&law, 5e-4), Err(SpeedError::SetpointWeight));
        }
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
