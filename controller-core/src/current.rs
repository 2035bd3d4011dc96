//! Stationary-frame stator current controllers, one per α/β axis.
//!
//! Two laws behind one interface ([`CurrentControllerConfig`]), chosen by configuration,
//! run on the α/β axes (stationary frame, seed 002) or on d/q (synchronous frame, seed 000's
//! PI1/PI3; the drive runs [`CurrentControllerConfig::request`] on the d/q errors):
//!
//! * **ICAD lag-compensated controller**, seed 002 eq. (20), implemented in the factored
//!   form of eq. (22):
//!   `k(s) = 326.5(s+400)²(s+1000) / (s(s²+100s+42500))
//!         = [326.5 + 326 500/s] · [(s+400)²/(s²+100s+42500)]`,
//!   i.e. a PI section (Kp = 326.5 V/A, Ki = 326 500 V/(A·s)) cascaded with a lag biquad
//!   (poles −50 ± j200 rad/s, double zero at −400 rad/s, DC gain 160 000/42 500 ≈ 3.76).
//! * **Stationary PI**, seed 002 Sec. VI-D (Kp = 360, Ki = 9000) or seed 000 PI1 = (30s+50)/s.
//!
//! Cascade order: error → lag biquad → PI → limit. Putting the only unstable mode (the
//! integrator) next to the output limit makes the PI's conditional integration
//! ([`crate::pi`]) an anti-windup for the *whole* cascade: the lag section is stable
//! (|z| ≈ 0.9975 at 20 kHz) with bounded input, so its state cannot wind up. In the drive the
//! two axes share **one vector limit**, the inverter's hexagon: the loops' request
//! ([`CurrentControllerConfig::request`]) goes to the modulator, which scales a request
//! beyond the hexagon onto it keeping its angle ([`crate::svpwm`]), and the integrators then
//! track the voltage applied ([`CurrentControllerConfig::track`]). The single-axis
//! [`CurrentControllerConfig::update_axis`] keeps the PI's conditional integration.

use crate::discretize::{ContinuousSection, DesignError, Discretization};
use crate::filter::{Biquad, BiquadState};
use crate::frames::{AlphaBeta, SinCos};
use crate::num::Scalar;
use crate::pi::{PiConfig, PiError, PiState};
use crate::raw::Field;
use num_complex::Complex32;

/// Continuous-time description of a current law: `(kp + ki/s) · lag(s)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CurrentLaw {
    /// Proportional gain of the PI section, V/A.
    pub kp_v_per_a: f64,
    /// Integral gain of the PI section, V/(A·s).
    pub ki_v_per_as: f64,
    /// Optional second-order lag section.
    pub lag: Option<ContinuousSection>,
}

impl CurrentLaw {
    /// Seed 002 eq. (20)/(22): 326.5(s+1000)/s · (s+400)²/(s²+100s+42500).
    pub const ICAD_EQ20: CurrentLaw = CurrentLaw {
        kp_v_per_a: 326.5,
        ki_v_per_as: 326.5 * 1000.0,
        lag: Some(ContinuousSection::biquad([1.0, 800.0, 160_000.0], [1.0, 100.0, 42_500.0])),
    };
    /// Seed 002 Sec. VI-D comparison PI: Kp = 360, Ki = 9000.
    pub const PI_SEED002: CurrentLaw = CurrentLaw { kp_v_per_a: 360.0, ki_v_per_as: 9000.0, lag: None };
    /// Seed 000 eq. (34): PI1 = (30s + 50)/s.
    pub const PI1_SEED000: CurrentLaw = CurrentLaw { kp_v_per_a: 30.0, ki_v_per_as: 50.0, lag: None };

    /// Continuous frequency response k(jω).
    pub fn response(&self, omega_rad_s: f64) -> crate::discretize::Complex {
        use crate::discretize::Complex;
        let s = Complex::new(0.0, omega_rad_s);
        let pi = (Complex::new(self.ki_v_per_as, 0.0) + s * self.kp_v_per_a) / s;
        match &self.lag {
            Some(l) => pi * l.response(omega_rad_s),
            None => pi,
        }
    }
}

/// Why a current controller could not be built.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CurrentError {
    /// PI section rejected.
    Pi(PiError),
    /// Lag section rejected.
    Lag(DesignError),
}

impl core::fmt::Display for CurrentError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Pi(e) => write!(f, "PI section: {e}"),
            Self::Lag(e) => write!(f, "lag section: {e}"),
        }
    }
}

/// Discrete current controller configuration for one axis (shared by α and β).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CurrentControllerConfig<T> {
    lag: Option<Biquad<T>>,
    pi: PiConfig<T>,
}

/// State of one axis.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CurrentAxisState<T> {
    lag: BiquadState<T>,
    /// PI section state (its `p_term`/`i_term` are telemetry).
    pub pi: PiState<T>,
}

/// State of both axes: α/β in the stationary frame, d/q in the synchronous frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CurrentState<T> {
    /// α (stationary) or d (synchronous) axis.
    pub axis1: CurrentAxisState<T>,
    /// β (stationary) or q (synchronous) axis.
    pub axis2: CurrentAxisState<T>,
}

impl<T: Scalar> CurrentControllerConfig<T> {
    /// Discretise `law` for sample period `ts_s`. The PI section's static limits are
    /// `±v_max_v`; [`Self::update_axis`] and [`Self::request`] take the run-time limit.
    pub fn new(
        law: &CurrentLaw,
        ts_s: f64,
        method: Discretization,
        v_max_v: f64,
    ) -> Result<Self, CurrentError> {
        let pi = PiConfig::new(law.kp_v_per_a, law.ki_v_per_as, ts_s, method, -v_max_v, v_max_v)
            .map_err(CurrentError::Pi)?;
        let lag = match &law.lag {
            Some(l) => Some(Biquad::design(l, ts_s, method).map_err(CurrentError::Lag)?),
            None => None,
        };
        Ok(Self { lag, pi })
    }

    /// The PI section.
    pub fn pi(&self) -> &PiConfig<T> {
        &self.pi
    }

    /// The lag section, if any.
    pub fn lag(&self) -> Option<&Biquad<T>> {
        self.lag.as_ref()
    }

    /// One axis: current error (A) → voltage (V), limited to `±v_limit`.
    #[inline]
    pub fn update_axis(&self, s: &mut CurrentAxisState<T>, error_a: T, v_limit: T) -> T {
        let e = match &self.lag {
            Some(lag) => lag.update(&mut s.lag, error_a),
            None => error_a,
        };
        self.pi.update_limited(&mut s.pi, e, -v_limit, v_limit)
    }
}

impl CurrentControllerConfig<f32> {
    /// One axis up to the PI's output, before the vector limit: the lag section, then
    /// [`PiConfig::update_unlimited`].
    #[inline(always)]
    fn update_axis_unlimited(&self, s: &mut CurrentAxisState<f32>, error_a: f32, v_max_v: f32) -> f32 {
        let e = match &self.lag {
            Some(lag) => lag.update(&mut s.lag, error_a),
            None => error_a,
        };
        self.pi.update_unlimited(&mut s.pi, e, v_max_v)
    }

    /// Both axes up to the PI's outputs, **not limited**: the current errors of the two axes
    /// (A) → the voltage request (V). Each integrator is kept within `±v_clamp_v` (in the
    /// drive the hexagon's vertex `2V_dc/3`, the most one axis can ever get). The caller
    /// limits the request as one vector — the inverter's hexagon in the drive — and, if it
    /// did, calls [`Self::track`].
    /// Always inlined: called from the drive's two frames, the compiler kept it out of line
    /// (`hil-sim bench`: ≈ 6 % of the loop in the call).
    #[inline(always)]
    pub fn request(&self, s: &mut CurrentState<f32>, e1_a: f32, e2_a: f32, v_clamp_v: f32) -> [f32; 2] {
        [
            self.update_axis_unlimited(&mut s.axis1, e1_a, v_clamp_v),
            self.update_axis_unlimited(&mut s.axis2, e2_a, v_clamp_v),
        ]
    }

    /// The request was limited to `applied` (V, same frame): the integrators follow the
    /// voltage applied, so neither winds up beyond what the inverter delivered, and the
    /// loops leave the limit as soon as their request falls inside it.
    ///
    /// - **A PI on its own** moves by back-calculation at `rate` per sample
    ///   ([`PiConfig::back_calculate`]); the drive's is `1 − e^(−T_s/T_slow)`, a tracking
    ///   time constant of one period of the plan that steps its references
    ///   (`DriveConfig::tracking_rate`). Back-calculation is a first-order follower, and a
    ///   steady limit is steady in the field frame only: in the stationary frame, where the
    ///   applied voltage turns by the field's step δ = ω_e·T_s each sample, the integrators
    ///   are first turned by `turn` (the field's step; no turn in the synchronous frame),
    ///   so that they follow a lasting limit as a synchronous integrator would. Unturned, a
    ///   follower at rate ρ settles at ρ/(1 − (1−ρ)·e^{−jδ}) of a phasor turning by δ per
    ///   sample — 15° behind at ρ = 0.095 and δ = 0.029 (an 8-pole motor at 145 rad/s,
    ///   20 kHz), and that drive, braking at its current limit, fell short of its load
    ///   (population member 001).
    /// - **A PI behind a lag (ICAD)** tracks the applied voltage at once ([`PiConfig::track`],
    ///   `rate` unused): its lag section carries the error's history, and its step responses
    ///   at the limit were measured with tracking (conditional integration instead raised the
    ///   shipped drive's 0 → 300 rad/s torque peak from 2.49 to 2.63 N·m).
    #[cold]
    #[inline(never)]
    pub fn track(
        &self,
        s: &mut CurrentState<f32>,
        applied: [f32; 2],
        rate: f32,
        turn: SinCos,
        v_clamp_v: f32,
    ) {
        let [a1, a2] = applied;
        if self.lag.is_some() {
            self.pi.track(&mut s.axis1.pi, a1, v_clamp_v);
            self.pi.track(&mut s.axis2.pi, a2, v_clamp_v);
        } else {
            let i = AlphaBeta { alpha: s.axis1.pi.i_term, beta: s.axis2.pi.i_term }.rotate(turn);
            (s.axis1.pi.i_term, s.axis2.pi.i_term) = (i.alpha, i.beta);
            self.pi.back_calculate(&mut s.axis1.pi, a1, rate, v_clamp_v);
            self.pi.back_calculate(&mut s.axis2.pi, a2, rate, v_clamp_v);
        }
    }

    /// Frequency response of the *implemented* discrete controller (coefficients as stored
    /// in f32) at ω, for sample period `ts_s` and the Tustin constant of `method`.
    pub fn response(&self, omega_rad_s: f64, ts_s: f64) -> crate::discretize::Complex {
        use crate::discretize::{Complex, delta_at};
        let delta = delta_at(omega_rad_s, ts_s);
        // PI: kp + (Ki/K)(z + 1)/(z − 1) = kp + (Ki/K)(δ + 2)/δ
        let ki_k = f64::from(self.pi.ki_over_k());
        let pi = Complex::new(f64::from(self.pi.kp()), 0.0) + (delta + Complex::new(2.0, 0.0)) * ki_k / delta;
        match &self.lag {
            Some(l) => pi * l.coefficients().response(omega_rad_s, ts_s),
            None => pi,
        }
    }
}

impl CurrentControllerConfig<f32> {
    /// `1/k(z)` of the implemented controller at `z = e^{jθ}`, `step` = (sin θ, cos θ) with
    /// |θ| < π/2 (the field's turn per fast step), in f32 for the drive's slow step
    /// ([`CurrentControllerConfig::response`] is its f64 counterpart). With δ = z − 1 the PI
    /// is `k_p + κ(δ + 2)/δ` (κ = `Ki/K`), so `1/k_PI = δ / (k_p·δ + κ(δ + 2))`: zero at
    /// θ = 0, where the integrator's gain is infinite. δ's real part, cos θ − 1, is taken as
    /// `−sin²θ / (1 + cos θ)`, without cancellation at small θ.
    pub fn inverse_response(&self, step: SinCos) -> Complex32 {
        let SinCos { sin, cos } = step;
        let delta = Complex32::new(-sin * sin / (1.0 + cos), sin);
        let (kp, kappa) = (self.pi.kp(), self.pi.ki_over_k());
        let den = delta * kp + (delta + 2.0) * kappa;
        // Zero only without an integrator at θ = 0: a P alone, 1/k_p there.
        let pi = if den.norm_sqr() > 0.0 { delta / den } else { Complex32::new(1.0 / kp, 0.0) };
        match &self.lag {
            Some(l) => pi * l.inverse_response(delta),
            None => pi,
        }
    }
}

/// Whether there is a lag (1) or not (0), the lag's coefficients (zeros without one: a
/// fixed layout) and the PI's.
impl Field for CurrentControllerConfig<f32> {
    const NF: usize = <Biquad<f32> as Field>::NF + <PiConfig<f32> as Field>::NF;
    const NU: usize = 1;

    fn put(&self, w: &mut crate::raw::Writer) {
        w.u(u32::from(self.lag.is_some()));
        self.lag.unwrap_or(Biquad::zero()).put(w);
        self.pi.put(w);
    }

    #[inline(always)]
    fn get(r: &mut crate::raw::Reader<'_>) -> Self {
        let has_lag = r.u() == 1;
        let lag = Biquad::get(r);
        Self { lag: if has_lag { Some(lag) } else { None }, pi: PiConfig::get(r) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::discretize::Complex;
    use crate::frames::AlphaBeta;
    use crate::num::Q32;

    /// Max relative error |k_d(e^{jωT}) − k(jω)| / |k(jω)| on a log grid over [1, 3000] rad/s.
    fn max_rel_error(law: &CurrentLaw, fs_hz: f64) -> (f64, f64) {
        let ts = 1.0 / fs_hz;
        let c = CurrentControllerConfig::<f32>::new(law, ts, Discretization::Tustin, 1e3).unwrap();
        let mut worst = (0.0, 0.0);
        for i in 0..=2000 {
            let w = libm::pow(10.0, 3.0 * libm::log10(3000.0) * (i as f64) / 2000.0 / 3.0);
            let kc = law.response(w);
            let err = (c.response(w, ts) - kc).norm() / kc.norm();
            if err > worst.0 {
                worst = (err, w);
            }
        }
        worst
    }

    /// The slow step's f32 `1/k(e^{jθ})` against the f64 response of the same stored
    /// coefficients, for the ICAD (PI and lag) and a PI, at field turns per step from
    /// standstill to 0.3 rad (4 kHz PWM at 950 rad/s electrical): within 1e-4 of |1/k|
    /// (f32 arithmetic on ≈ 10 operations), and zero at θ = 0.
    #[test]
    fn the_inverse_response_in_f32_is_the_responses_reciprocal() {
        let ts = 5e-5;
        for law in [CurrentLaw::ICAD_EQ20, CurrentLaw::PI_SEED002, CurrentLaw::PI1_SEED000] {
            let c = CurrentControllerConfig::<f32>::new(&law, ts, Discretization::Tustin, 1e3).unwrap();
            assert_eq!(c.inverse_response(SinCos::new(0.0)).norm(), 0.0);
            for i in 1..=300 {
                let theta = 0.3 * f64::from(i) / 300.0;
                for th in [theta, -theta] {
                    let expected = Complex::new(1.0, 0.0) / c.response(th / ts, ts);
                    let got = c.inverse_response(SinCos::new(th as f32));
                    let err = Complex::new(f64::from(got.re) - expected.re, f64::from(got.im) - expected.im);
                    assert!(err.norm() <= 1e-4 * expected.norm(), "{law:?} at θ = {th}: {got} vs {expected}");
                }
            }
        }
    }

    #[test]
    fn continuous_eq20_equals_its_factored_form_eq22() {
        // Evaluate eq. (20) directly from its printed polynomial form.
        use crate::discretize::Complex;
        for w in [1.0, 50.0, 205.0, 375.0, 1000.0, 3350.0] {
            let s = Complex::new(0.0, w);
            let p400 = s + Complex::new(400.0, 0.0);
            let num = p400 * p400 * (s + Complex::new(1000.0, 0.0)) * 326.5;
            let den = s * (s * s + s * 100.0 + Complex::new(42_500.0, 0.0));
            let k20 = num / den;
            let k22 = CurrentLaw::ICAD_EQ20.response(w);
            assert!((k20 - k22).norm() / k20.norm() < 1e-12);
        }
    }

    /// Issue requirement: discretised (20) at 20 kHz within 0.2 % of k(jω) on 1–3000 rad/s,
    /// with the f32 coefficients actually stored. 10 and 50 kHz are reported.
    #[test]
    fn icad_discretisation_error_at_20khz_below_0_2_percent() {
        for fs in [10_000.0, 20_000.0, 50_000.0] {
            let (e, w) = max_rel_error(&CurrentLaw::ICAD_EQ20, fs);
            eprintln!(
                "ICAD eq. (20) Tustin at {fs:>6} Hz: max rel. error {:.4} % at {w:.0} rad/s",
                e * 100.0
            );
            if fs == 20_000.0 {
                assert!(e <= 2e-3, "{e}");
            }
        }
    }

    #[test]
    fn pi_discretisation_error_at_20khz_below_0_2_percent() {
        for (name, law) in
            [("PI Kp=360 Ki=9000", CurrentLaw::PI_SEED002), ("PI1 (30s+50)/s", CurrentLaw::PI1_SEED000)]
        {
            for fs in [10_000.0, 20_000.0, 50_000.0] {
                let (e, w) = max_rel_error(&law, fs);
                eprintln!("{name} at {fs:>6} Hz: max rel. error {:.5} % at {w:.0} rad/s", e * 100.0);
                if fs == 20_000.0 {
                    assert!(e <= 2e-3);
                }
            }
        }
    }

    /// Time-domain check of the frequency response: drive the f32 controller with a sine
    /// at ω and fit the steady-state output's amplitude and phase.
    #[test]
    fn icad_sine_response_in_time_matches_k_jw() {
        let ts = 1.0 / 20_000.0;
        let c = CurrentControllerConfig::<f32>::new(&CurrentLaw::ICAD_EQ20, ts, Discretization::Tustin, 1e9)
            .unwrap();
        for w in [300.0f64, 1000.0, 3000.0] {
            let mut s = CurrentAxisState::default();
            // 2 s settles the lag poles (time constant 20 ms); fit over whole periods after.
            let n_settle = 40_000usize;
            let n_fit = 20_000usize;
            // Least squares y ≈ a·sin ωt + b·cos ωt + c (c absorbs the integrator's offset).
            let mut m = [[0.0f64; 3]; 3];
            let mut v = [0.0f64; 3];
            for k in 0..(n_settle + n_fit) {
                let t = k as f64 * ts;
                let x = libm::sin(w * t);
                let y = f64::from(c.update_axis(&mut s, x as f32, 1e9));
                if k >= n_settle {
                    let basis = [libm::sin(w * t), libm::cos(w * t), 1.0];
                    for i in 0..3 {
                        v[i] += basis[i] * y;
                        for j in 0..3 {
                            m[i][j] += basis[i] * basis[j];
                        }
                    }
                }
            }
            let det3 = |m: &[[f64; 3]; 3]| {
                m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
                    - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
                    + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
            };
            let cramer = |col: usize| {
                let mut mc = m;
                for (row, vi) in mc.iter_mut().zip(v.iter()) {
                    row[col] = *vi;
                }
                det3(&mc) / det3(&m)
            };
            let (a, b) = (cramer(0), cramer(1));
            let measured = crate::discretize::Complex::new(a, b);
            let expected = CurrentLaw::ICAD_EQ20.response(w);
            let err = (measured - expected).norm() / expected.norm();
            eprintln!("ICAD f32 time-domain response at {w} rad/s: rel. error {:.4} %", err * 100.0);
            assert!(err < 3e-3, "{w}: {err}");
        }
    }

    /// Samples until the output leaves the +limit after the error reverses from +5 A (held
    /// for 1 s in saturation) to −1 A; `naive` disables the integrator protection.
    fn samples_to_leave_limit(naive: bool) -> Option<usize> {
        let ts = 1.0 / 20_000.0;
        let c =
            CurrentControllerConfig::<f32>::new(&CurrentLaw::ICAD_EQ20, ts, Discretization::Tustin, 200.0)
                .unwrap();
        let mut s = CurrentAxisState::default();
        let lim = if naive { 1e30 } else { 100.0 };
        for _ in 0..20_000 {
            let u = c.update_axis(&mut s, 5.0, lim);
            assert!(naive || (u <= 100.0 && s.pi.i_term <= 100.0));
        }
        (0..200_000).find(|_| c.update_axis(&mut s, -1.0, lim).min(100.0) < 99.0)
    }

    /// The lag section alone, fed the same error sequence: samples until its output turns
    /// negative — before that, even a perfect anti-windup must keep the output at +limit.
    fn samples_until_lag_output_negative() -> Option<usize> {
        let ts = 1.0 / 20_000.0;
        let c =
            CurrentControllerConfig::<f32>::new(&CurrentLaw::ICAD_EQ20, ts, Discretization::Tustin, 200.0)
                .unwrap();
        let lag = c.lag().unwrap();
        let mut s = BiquadState::default();
        for _ in 0..20_000 {
            lag.update(&mut s, 5.0);
        }
        (0..200_000).find(|_| lag.update(&mut s, -1.0) < 0.0)
    }

    /// Anti-windup through the cascade: after 1 s at the limit, the output leaves it within
    /// 0.5 ms (10 samples) of the moment the lag section's own (linear) response lets it;
    /// an unprotected integrator would keep it there for more than 100× longer.
    #[test]
    fn anti_windup_through_the_cascade() {
        let lag_zero = samples_until_lag_output_negative().unwrap();
        let aw = samples_to_leave_limit(false).unwrap();
        let naive = samples_to_leave_limit(true).unwrap_or(usize::MAX);
        eprintln!(
            "leaving saturation: lag output < 0 after {lag_zero} samples, anti-windup {aw}, naive {naive}"
        );
        assert!(aw <= lag_zero + 10, "aw {aw} vs lag {lag_zero}");
        assert!(naive > 100 * aw.max(1));
    }

    #[test]
    fn q32_icad_agrees_with_f32() {
        let ts = 1.0 / 20_000.0;
        let law = CurrentLaw::ICAD_EQ20;
        let cf = CurrentControllerConfig::<f32>::new(&law, ts, Discretization::Tustin, 200.0).unwrap();
        let cq = CurrentControllerConfig::<Q32>::new(&law, ts, Discretization::Tustin, 200.0).unwrap();
        let c64 = CurrentControllerConfig::<f64>::new(&law, ts, Discretization::Tustin, 200.0).unwrap();
        let (mut sf, mut sq, mut s64) =
            (CurrentAxisState::default(), CurrentAxisState::default(), CurrentAxisState::default());
        let (mut max_err, mut q_err, mut f_err) = (0.0f32, 0.0f64, 0.0f64);
        for k in 0..40_000 {
            let t = k as f64 * ts;
            // 300 rad/s current error of 0.5 A with a step, including saturating stretches.
            let e = (0.5 * libm::sin(300.0 * t) + if k > 20_000 { 2.0 } else { 0.0 }) as f32;
            let uf = cf.update_axis(&mut sf, e, 150.0);
            let uq = cq.update_axis(&mut sq, Q32::from_f32(e), Q32::from_f32(150.0)).to_f32();
            let u64 = c64.update_axis(&mut s64, f64::from(e), 150.0);
            max_err = max_err.max((uf - uq).abs());
            q_err = q_err.max((f64::from(uq) - u64).abs());
            f_err = f_err.max((f64::from(uf) - u64).abs());
        }
        eprintln!(
            "ICAD max |Δu| over 2 s: Q32−f32 {max_err:.2e} V, Q32−f64 {q_err:.2e} V, f32−f64 {f_err:.2e} V"
        );
        // Both stay within 3.3e-5 of the 150 V range of the f64 reference: Q32 through the
        // 2^-32 quantisation of α0 ≈ 1.06e-4 (2e-6 relative on the lag's DC gain), f32
        // through integrator round-off (ulp 1.5e-5 V near 150 V over 4e4 steps).
        // Bound on the Q32–f32 agreement: 1e-2 V = 0.007 % of the range.
        assert!(q_err < 5e-3 && f_err < 5e-3, "{q_err} {f_err}");
        assert!(max_err < 1e-2, "{max_err}");
    }

    /// One step of both axes through the drive's vector limit, the modulator's hexagon
    /// (stationary frame): the applied voltage and whether it was limited.
    fn step_hexagon(
        c: &CurrentControllerConfig<f32>,
        s: &mut CurrentState<f32>,
        e: [f32; 2],
        vdc: f32,
    ) -> ([f32; 2], bool) {
        let clamp = 2.0 * vdc / 3.0;
        let [r1, r2] = c.request(s, e[0], e[1], clamp);
        let m = crate::svpwm::modulate(AlphaBeta { alpha: r1, beta: r2 }, vdc);
        let applied = [m.v_applied.alpha, m.v_applied.beta];
        if m.saturated {
            c.track(s, applied, 1.0, SinCos::default(), clamp);
        }
        (applied, m.saturated)
    }

    /// The vector limit: whatever the errors (angles all round, magnitudes from inside the
    /// hexagon to far beyond), the output stays in the hexagon; when it was limited, each
    /// integrator is the applied voltage less its own p-term (within its clamp).
    #[test]
    fn integrators_track_the_applied_voltage() {
        let ts = 1.0 / 20_000.0;
        let c =
            CurrentControllerConfig::<f32>::new(&CurrentLaw::ICAD_EQ20, ts, Discretization::Tustin, 400.0)
                .unwrap();
        let vdc = 310.0f32;
        let clamp = 2.0 * vdc / 3.0;
        let mut limited_steps = 0;
        for k in 0..72 {
            let th = k as f32 * core::f32::consts::TAU / 72.0;
            for e_mag in [1e-3f32, 0.05, 0.5, 5.0, 500.0] {
                let mut s = CurrentState::default();
                let e = [e_mag * libm::cosf(th), e_mag * libm::sinf(th)];
                for _ in 0..2_000 {
                    let ([u1, u2], limited) = step_hexagon(&c, &mut s, e, vdc);
                    // Inside the hexagon: |v| ≤ its vertex radius 2V_dc/3.
                    assert!(libm::hypotf(u1, u2) <= clamp * (1.0 + 1e-6));
                    if limited {
                        limited_steps += 1;
                        for (u, axis) in [(u1, &s.axis1), (u2, &s.axis2)] {
                            let tracked = (u - axis.pi.p_term).limit(-clamp, clamp);
                            assert!(
                                (axis.pi.i_term - tracked).abs() <= 1e-6 * axis.pi.p_term.abs().max(clamp)
                            );
                        }
                    }
                }
            }
        }
        assert!(limited_steps > 10_000, "the test must exercise the limit: {limited_steps}");
    }

    /// Leaving the limit: after 1 s of a large error vector, the error reverses; the output
    /// leaves the hexagon no later than the lag section's own linear response lets it (plus
    /// 10 samples).
    #[test]
    fn vector_anti_windup_through_the_cascade() {
        let ts = 1.0 / 20_000.0;
        let c =
            CurrentControllerConfig::<f32>::new(&CurrentLaw::ICAD_EQ20, ts, Discretization::Tustin, 400.0)
                .unwrap();
        let mut s = CurrentState::default();
        for _ in 0..20_000 {
            step_hexagon(&c, &mut s, [5.0, 5.0], 310.0);
        }
        let lag_zero = samples_until_lag_output_negative().unwrap();
        let left = (0..200_000).find(|_| !step_hexagon(&c, &mut s, [-1.0, -1.0], 310.0).1).unwrap();
        eprintln!("vector limit: left the hexagon after {left} samples (lag output < 0 after {lag_zero})");
        assert!(left <= lag_zero + 10, "{left} vs {lag_zero}");
    }

    /// A lag-less PI held at a limit that turns with the field — the stationary frame at the
    /// voltage limit, the applied voltage a phasor of 300 V turning by δ = 0.029 rad a sample
    /// (an 8-pole motor at 145 rad/s, 20 kHz), the error held at zero so that the limit alone
    /// moves the integrators — back-calculated at the drive's rate ρ = 1 − e^(−1/10): turned
    /// by δ first, the integrators sit on the applied voltage (as tracking puts them); not
    /// turned, the first-order follower settles at ρ/(1 − (1−ρ)·e^{−jδ}) of it: 0.96 of its
    /// magnitude, 15° behind.
    #[test]
    fn a_lasting_limit_turning_with_the_field_is_followed_as_by_tracking() {
        let ts = 1.0 / 20_000.0;
        let c =
            CurrentControllerConfig::<f32>::new(&CurrentLaw::PI_SEED002, ts, Discretization::Tustin, 400.0)
                .unwrap();
        let (v, delta, rate) = (300.0f32, 0.029f32, -libm::expm1f(-0.1));
        let follow = |turn: SinCos| {
            let mut s = CurrentState::default();
            let mut applied = [v, 0.0];
            for k in 1..=2_000 {
                let th = k as f32 * delta;
                c.request(&mut s, 0.0, 0.0, 400.0);
                applied = [v * libm::cosf(th), v * libm::sinf(th)];
                c.track(&mut s, applied, rate, turn, 400.0);
            }
            let i = Complex::new(f64::from(s.axis1.pi.i_term), f64::from(s.axis2.pi.i_term));
            i / Complex::new(f64::from(applied[0]), f64::from(applied[1]))
        };
        let turned = follow(SinCos::default().rotated(delta));
        assert!((turned - Complex::new(1.0, 0.0)).norm() < 1e-4, "{turned:?}");
        let unturned = follow(SinCos::default());
        let (rho, d) = (f64::from(rate), f64::from(delta));
        let expected = Complex::new(rho, 0.0) / (Complex::new(1.0, 0.0) - Complex::from_polar(1.0 - rho, -d));
        assert!((unturned - expected).norm() < 1e-3, "{unturned:?} {expected:?}");
        let lag_deg = -unturned.arg().to_degrees();
        assert!((15.0..16.0).contains(&lag_deg), "{lag_deg}°");
    }

    #[test]
    fn bad_law_is_rejected() {
        let bad = CurrentLaw { kp_v_per_a: -1.0, ..CurrentLaw::PI_SEED002 };
        assert!(matches!(
            CurrentControllerConfig::<f32>::new(&bad, 5e-5, Discretization::Tustin, 100.0),
            Err(CurrentError::Pi(PiError::Gain))
        ));
    }
}
