//! Discrete PI controller `C(s) = Kp + Ki/s` with output limits and anti-windup.
//!
//! Discretisation: the integral term by Tustin (optionally prewarped), the proportional term
//! is exact:
//!
//! ```text
//! p[k] = Kp·e[k]
//! i[k] = i[k−1] + Ki/K·(e[k] + e[k−1])          K = 2/T (or the prewarped constant)
//! u[k] = limit(p[k] + i[k], u_min, u_max)
//! ```
//!
//! **Anti-windup: conditional integration with a clamped integrator.** The increment is
//! skipped when the unsaturated output is beyond a limit and the increment would push it
//! further, and the integrator itself is kept inside `[u_min, u_max]`. Chosen over
//! back-calculation because it has no extra tracking gain to tune and stays correct when the
//! limits change every sample (the current loops' voltage limit follows the DC bus), and
//! because the integrator state can never exceed the actuator range, which bounds the
//! recovery overshoot (see `recovery_after_long_saturation_is_bounded`).
//!
//! **Vector limit.** Where two channels share one limit on the magnitude of their outputs
//! (the α/β or d/q current loops and the inverter's voltage circle), each channel runs
//! [`PiConfig::update_unlimited`], the caller scales the output vector onto the limit and
//! then each integrator *tracks the applied output* ([`PiConfig::track`]), or moves towards
//! it at a rate ([`PiConfig::back_calculate`]).
//!
//! **Bumpless gain change.** `Ki` sits inside the sum, so changing it never bumps the output.
//! Changing `Kp` is made bumpless by [`PiState::retune`], which moves `(Kp_old − Kp_new)·e`
//! into the integrator.

use crate::discretize::{DesignError, Discretization};
use crate::num::Scalar;

/// PI configuration (`Copy`; one config can drive several channels).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PiConfig<T> {
    kp: T,
    ki_over_k: T,
    u_min: T,
    u_max: T,
}

/// Why a PI configuration was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PiError {
    /// `Kp` or `Ki` negative or not finite.
    Gain,
    /// Limits not finite or `u_min ≥ u_max`.
    Limits,
    /// Discretisation rejected (sample period or prewarp frequency).
    Design(DesignError),
}

impl core::fmt::Display for PiError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Gain => f.write_str("a PI gain is negative or not finite"),
            Self::Limits => f.write_str("the PI's output limits are not finite, or not min < max"),
            Self::Design(e) => write!(f, "the PI's discretisation: {e}"),
        }
    }
}

/// PI state. `p_term` and `i_term` of the last update are exposed for telemetry.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PiState<T> {
    /// Proportional term of the last update.
    pub p_term: T,
    /// Integral term (the integrator state).
    pub i_term: T,
    e_prev: T,
}

impl<T: Scalar> PiConfig<T> {
    /// PI `kp + ki/s` (output units per error unit, and per error-unit·second), sampled every
    /// `ts_s`, output limited to `[u_min, u_max]`.
    pub fn new(
        kp: f64,
        ki: f64,
        ts_s: f64,
        method: Discretization,
        u_min: f64,
        u_max: f64,
    ) -> Result<Self, PiError> {
        if !(kp.is_finite() && ki.is_finite() && kp >= 0.0 && ki >= 0.0) {
            return Err(PiError::Gain);
        }
        if !(u_min.is_finite() && u_max.is_finite() && u_min < u_max) {
            return Err(PiError::Limits);
        }
        let k = method.k(ts_s).map_err(PiError::Design)?;
        Ok(Self {
            kp: T::from_f64(kp),
            ki_over_k: T::from_f64(ki / k),
            u_min: T::from_f64(u_min),
            u_max: T::from_f64(u_max),
        })
    }

    /// The configured output limits `(u_min, u_max)`.
    pub fn limits(&self) -> (T, T) {
        (self.u_min, self.u_max)
    }

    /// Proportional gain as stored.
    pub fn kp(&self) -> T {
        self.kp
    }

    /// The discrete integral gain `Ki/K` as stored.
    pub fn ki_over_k(&self) -> T {
        self.ki_over_k
    }

    /// One update with the configured limits.
    #[inline]
    pub fn update(&self, s: &mut PiState<T>, e: T) -> T {
        self.update_limited(s, e, self.u_min, self.u_max)
    }

    /// One update with run-time limits `[lo, hi]` (e.g. a voltage limit following the DC
    /// bus). Never panics; for `lo > hi` the output is `hi`.
    #[inline]
    pub fn update_limited(&self, s: &mut PiState<T>, e: T, lo: T, hi: T) -> T {
        let p = self.kp * e;
        let di = self.ki_over_k * (e + s.e_prev);
        let unsat = p + s.i_term + di;
        let winding_up = (unsat > hi && di > T::ZERO) || (unsat < lo && di < T::ZERO);
        let i = if winding_up { s.i_term } else { s.i_term + di };
        s.i_term = i.limit(lo, hi);
        s.p_term = p;
        s.e_prev = e;
        (p + s.i_term).limit(lo, hi)
    }
}

impl<T: Scalar> PiConfig<T> {
    /// First half of an update whose output a caller limits together with other channels
    /// (the current loops' one vector limit): the output `p + i` with the integral
    /// increment taken and the integrator kept within `±limit`, before any output limit.
    /// The caller limits the outputs jointly and, if it did, calls [`PiConfig::track`] or
    /// [`PiConfig::back_calculate`].
    #[inline]
    pub fn update_unlimited(&self, s: &mut PiState<T>, e: T, limit: T) -> T {
        let p = self.kp * e;
        s.i_term = (s.i_term + self.ki_over_k * (e + s.e_prev)).limit_symmetric(limit);
        s.p_term = p;
        s.e_prev = e;
        p + s.i_term
    }

    /// Second half, when the output was limited to `applied`: the integrator tracks the
    /// output actually applied, `i = applied − p` (kept within `±limit`), so that the next
    /// step starts from what the actuator did, not from what was asked (anti-windup by
    /// tracking the limited output).
    #[inline]
    pub fn track(&self, s: &mut PiState<T>, applied: T, limit: T) {
        s.i_term = (applied - s.p_term).limit(-limit, limit);
    }

    /// Second half, when the output was limited to `applied`, by **back-calculation**
    /// (Åström & Hägglund): the integrator moves by `rate` of what the limit took off the
    /// request, `i ← i + rate·(applied − (p + i))` (kept within `±limit`) — a tracking time
    /// constant `T_t = T_s/rate`. `rate = 1` is [`Self::track`]; below it, a limit that lasts
    /// a few samples (a reference step's proportional kick) moves the integrator by that
    /// share of it only, while one that lasts many `T_t` is followed as by tracking.
    #[inline]
    pub fn back_calculate(&self, s: &mut PiState<T>, applied: T, rate: T, limit: T) {
        let excess = applied - (s.p_term + s.i_term);
        s.i_term = (s.i_term + rate * excess).limit(-limit, limit);
    }
}

impl<T: Scalar> PiState<T> {
    /// Bumpless change from `old` to `new` gains: afterwards, the same error gives the same
    /// output as before the change (up to the next integral increment).
    pub fn retune(&mut self, old: &PiConfig<T>, new: &PiConfig<T>) {
        self.i_term = (self.i_term + (old.kp - new.kp) * self.e_prev).limit(new.u_min, new.u_max);
    }
}

impl PiConfig<f32> {
    /// [`PiConfig::new`] with Tustin's integral, designed at run time in f32 (a gain found by
    /// a measurement on the target, without soft-float f64): `kp`, `ki` as there, output
    /// within `±u_max`. `None` unless the gains are finite and non-negative and `ts_s` and
    /// `u_max` finite and positive.
    pub fn tustin_f32(kp: f32, ki: f32, ts_s: f32, u_max: f32) -> Option<Self> {
        let ok = |x: f32| x.is_finite() && x >= 0.0;
        (ok(kp) && ok(ki) && ok(ts_s) && ts_s > 0.0 && ok(u_max) && u_max > 0.0).then_some(Self {
            kp,
            ki_over_k: ki * ts_s * 0.5,
            u_min: -u_max,
            u_max,
        })
    }
}

/// `k_p`, `K_i/K`, `u_min`, `u_max`.
impl crate::raw::Field for PiConfig<f32> {
    const NF: usize = <[f32; 4] as crate::raw::Field>::NF;
    const NU: usize = 0;

    fn put(&self, w: &mut crate::raw::Writer) {
        [self.kp, self.ki_over_k, self.u_min, self.u_max].put(w);
    }

    #[inline(always)]
    fn get(r: &mut crate::raw::Reader<'_>) -> Self {
        let [kp, ki_over_k, u_min, u_max] = <[f32; 4]>::get(r);
        Self { kp, ki_over_k, u_min, u_max }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TS: f64 = 1e-4;

    fn pi(kp: f64, ki: f64, lim: f64) -> PiConfig<f32> {
        PiConfig::new(kp, ki, TS, Discretization::Tustin, -lim, lim).unwrap()
    }

    #[test]
    fn step_response_is_kp_plus_ki_t() {
        // Continuous: u(t) = Kp + Ki·t for a unit error step. Tustin integrates the step
        // with a half-sample at k = 0: i[k] = Ki·T·(k + 1/2).
        let c = pi(2.0, 50.0, 1e6);
        let mut s = PiState::default();
        for k in 0..1000 {
            let u = c.update(&mut s, 1.0);
            let expected = 2.0 + 50.0 * TS * (k as f64 + 0.5);
            assert!((f64::from(u) - expected).abs() < 1e-4, "k={k}: {u} vs {expected}");
        }
        assert_eq!(s.p_term, 2.0);
    }

    #[test]
    fn ramp_response_matches_kp_t_plus_ki_t2_over_2() {
        // e(t) = t → u(t) = Kp·t + Ki·t²/2; Tustin integrates a ramp exactly.
        let c = pi(3.0, 40.0, 1e6);
        let mut s = PiState::default();
        for k in 0..2000 {
            let t = k as f64 * TS;
            let u = c.update(&mut s, t as f32);
            let expected = 3.0 * t + 40.0 * t * t / 2.0;
            assert!((f64::from(u) - expected).abs() < 1e-5, "k={k}");
        }
    }

    /// Integrating plant y' = 10·u (a speed loop with a torque limit), Euler-exact, closed
    /// by `c` (or by the same PI whose integrator is not protected: only the output clamps).
    /// Returns the peak of y over the run.
    fn peak_of_step(c: &PiConfig<f32>, naive: bool, r: f32, n: usize) -> f32 {
        let (mut y, mut peak) = (0.0f32, 0.0f32);
        let mut s = PiState::default();
        let (mut i_naive, mut e_prev) = (0.0f32, 0.0f32);
        let (lo, hi) = c.limits();
        for _ in 0..n {
            let e = r - y;
            let u = if naive {
                i_naive += c.ki_over_k() * (e + e_prev);
                e_prev = e;
                (c.kp() * e + i_naive).clamp(lo, hi)
            } else {
                c.update(&mut s, e)
            };
            y += 10.0 * u * TS as f32;
            peak = peak.max(y);
        }
        peak
    }

    /// Loop 20(s + 10)/s² (ζ = 0.71). A small step (no saturation) gives the linear overshoot
    /// OS_lin. A step of r = 10 saturates u = 1 for ≈ 1 s. Bound: the overshoot after the
    /// saturation is no larger than that of the same step in an unsaturated loop, OS_lin·r
    /// (measured: ≈ 0.05·OS_lin·r); the unprotected integrator must overshoot by more than
    /// 3·OS_lin·r, so the test detects windup.
    #[test]
    fn recovery_after_long_saturation_is_bounded() {
        let c = pi(2.0, 20.0, 1.0);
        let os_lin = peak_of_step(&c, false, 0.01, 30_000) / 0.01 - 1.0;
        let r = 10.0;
        let os_aw = peak_of_step(&c, false, r, 30_000) - r;
        let os_naive = peak_of_step(&c, true, r, 30_000) - r;
        eprintln!(
            "linear overshoot {:.1} %; after 1 s saturation: anti-windup {os_aw:.3}, naive {os_naive:.3} (bound {:.3})",
            os_lin * 100.0,
            os_lin * r
        );
        assert!(os_aw <= os_lin * r, "anti-windup overshoot {os_aw}");
        assert!(os_naive > 3.0 * os_lin * r, "naive overshoot {os_naive}: the test would not detect windup");
    }

    #[test]
    fn outputs_and_integrator_stay_within_limits() {
        let c = pi(10.0, 1e4, 3.0);
        let mut s = PiState::default();
        for k in 0..10_000 {
            let e = if (k / 100) % 2 == 0 { 100.0 } else { -100.0 };
            let u = c.update(&mut s, e);
            assert!((-3.0..=3.0).contains(&u) && (-3.0..=3.0).contains(&s.i_term));
        }
    }

    #[test]
    fn bumpless_gain_change() {
        let old = pi(2.0, 100.0, 1e3);
        let new = pi(8.0, 400.0, 1e3);
        let mut s = PiState::default();
        let mut u = 0.0;
        for _ in 0..100 {
            u = old.update(&mut s, 0.7);
        }
        s.retune(&old, &new);
        let u_after = new.update(&mut s, 0.7);
        // Only the regular integral increment of the new gains separates the two.
        let increment = f64::from(new.ki_over_k()) * 1.4;
        assert!((f64::from(u_after - u) - increment).abs() < 1e-4, "bump {}", u_after - u);
        // Without retune the output would jump by (8 − 2)·0.7 = 4.2.
        let mut s2 = PiState::default();
        for _ in 0..100 {
            old.update(&mut s2, 0.7);
        }
        let jump = f64::from(new.update(&mut s2, 0.7) - u) - increment;
        assert!((jump - 4.2).abs() < 1e-3, "{jump}");
    }

    /// One axis at the voltage limit and a reference step of 80 → 100 A — member 010's
    /// current loop at twice its base speed (k_p 4.51 V/A, k_i 216.8 V/(A·s), σL_s 0.515 mH,
    /// R_s 15.6 mΩ, a back-EMF of 312 V against a 333 V limit, 20 kHz): the step's kick of
    /// ≈ 90 V saturates the loop. Tracking at once (rate 1) hands the kick's excess to the
    /// integrator, which then lies below the back-EMF and wins it back at k_i·e: the current
    /// falls short by 12.5 A on average over the next 10 ms. Back-calculation at one slow
    /// period of 10 samples (rate 1 − e^(−0.1), as the drive's) charges it a share: 3.9 A. (The drive steps its
    /// references every slow period; with tracking, member 010's kicks, one per encoder
    /// count of speed noise, added up into a runaway and a false `SwitchOpen`.)
    #[test]
    fn a_reference_steps_kick_at_the_limit_is_not_charged_to_the_integrator() {
        let (l, r, emf, v_lim, ts) = (0.000515f64, 0.0156f64, 312.0f64, 333.0f64, 50e-6f64);
        let c = PiConfig::<f32>::new(4.51, 216.8, ts, Discretization::Tustin, -384.0, 384.0).unwrap();
        let a = (-r * ts / l).exp();
        let mean_shortfall = |rate: f32| {
            let mut s = PiState { i_term: (emf + r * 80.0) as f32, ..PiState::default() };
            let (mut i, mut sum) = (80.0f64, 0.0);
            for k in 0..210 {
                let i_ref = if k >= 10 { 100.0 } else { 80.0 };
                let request = c.update_unlimited(&mut s, (i_ref - i) as f32, 384.0);
                let applied = request.clamp(-v_lim as f32, v_lim as f32);
                if applied != request {
                    c.back_calculate(&mut s, applied, rate, 384.0);
                }
                i = a * i + (1.0 - a) * (f64::from(applied) - emf) / r;
                if k >= 10 {
                    sum += i_ref - i;
                }
            }
            sum / 200.0
        };
        let (slow, at_once) = (mean_shortfall(-(-0.1f32).exp_m1()), mean_shortfall(1.0));
        eprintln!("mean shortfall over 10 ms: {slow:.2} A at one slow period, {at_once:.2} A at rate 1");
        assert!(slow < 0.25 * 20.0, "{slow}");
        assert!(at_once > 2.0 * slow, "{at_once} {slow}");
    }

    /// Back-calculation at rate 1 is tracking; at rate ρ a limit held for n samples leaves
    /// `(1 − ρ)ⁿ` of the integrator's distance from `applied − p` (the error held still).
    #[test]
    fn back_calculation_follows_a_lasting_limit_at_its_rate() {
        let c = pi(2.0, 100.0, 50.0);
        let (e, applied) = (10.0f32, 30.0f32);
        let mut tracked = PiState::default();
        let mut back = PiState::default();
        c.update_unlimited(&mut tracked, e, 50.0);
        c.update_unlimited(&mut back, e, 50.0);
        c.track(&mut tracked, applied, 50.0);
        c.back_calculate(&mut back, applied, 1.0, 50.0);
        assert!((tracked.i_term - back.i_term).abs() < 1e-5, "{} {}", tracked.i_term, back.i_term);
        let mut s = PiState { i_term: 0.0, e_prev: e, ..PiState::default() };
        let target = applied - 2.0 * e;
        for _ in 0..20 {
            c.update_unlimited(&mut s, e, 50.0);
            s.i_term -= c.ki_over_k() * 2.0 * e; // hold the integral: the limit's share alone
            c.back_calculate(&mut s, applied, 0.1, 50.0);
        }
        let left = (s.i_term - target) / (0.0 - target);
        assert!((left - 0.9f32.powi(20)).abs() < 1e-4, "{left}");
    }

    #[test]
    fn rejects_bad_configs() {
        let t = Discretization::Tustin;
        assert_eq!(PiConfig::<f32>::new(-1.0, 1.0, TS, t, -1.0, 1.0), Err(PiError::Gain));
        assert_eq!(PiConfig::<f32>::new(1.0, f64::NAN, TS, t, -1.0, 1.0), Err(PiError::Gain));
        assert_eq!(PiConfig::<f32>::new(1.0, 1.0, TS, t, 1.0, 1.0), Err(PiError::Limits));
        assert_eq!(
            PiConfig::<f32>::new(1.0, 1.0, -TS, t, -1.0, 1.0),
            Err(PiError::Design(DesignError::SamplePeriod))
        );
    }
}
