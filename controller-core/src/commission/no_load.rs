//! Stage 6 of the sequence: the no-load test at rated flux (issue 20: "L_m from a no-load
//! rotating test at rated flux"). It runs only if the motor may turn, and takes over the slow
//! rotating field at the end of its hold.
//!
//! The standstill levels measure the magnetizing inductance at the flux of their DC
//! currents; a real machine's L_m falls as its iron saturates, and control runs at rated
//! flux. So the field is brought to rated flux, with the rotor turning freely at nearly the
//! field's speed (no load: almost no rotor current), and the terminal impedance there gives
//! L_m (on the host: `hil_sim::identify`).
//!
//! 1. **Set-up** from what the sequence has measured so far (no model from the user):
//!    - R̂_s from the settled voltages of the first two DC levels (the inverter's error
//!      cancels);
//!    - L̂_s and T̂_r from the area of the second level's decay (I/2 → I): with
//!      `e(t) = v(t) − v(∞)`, the flux so far `A(t) = ∫₀ᵗ e dt + R̂_s·lag` is
//!      `L_σ·ΔI + L_M·ΔI·(1 − e^{−t/T_r})` (the leakage's share at the step, the rotor's
//!      after), so `L̂_s·ΔI = A(∞)` and T̂_r is the time A(t) covers 1 − e^{−1} of the rotor's
//!      share (with the pulses' L̂σ; interpolated between block ends). An area, not a moment:
//!      the long settled tail's noise barely moves it. Crude (± 10 %), and only used to set
//!      the test up: the slip bound and the settling;
//!    - the field's electrical turning per encoder radian `k_e` over the second half of the
//!      hold (p/(1 − s) whatever the encoder's lines or direction: the rotor's electrical
//!      speed is `k_e·ω_encoder` from here on). A rotor that did not turn skips the test.
//! 2. **Accelerate**: the field frequency rises by at most [`NO_LOAD_RAMP_RAD_S2`] and leads
//!    the rotor's electrical speed by at most `1/T̂_r` (the slip of the most torque per
//!    ampere for an impressed current), up to the test frequency; the amplitude ramps to
//!    `ψ_rated/L̂_s` (at most the test current). A rotor that does not follow within
//!    [`NO_LOAD_RAMP_MAX_S`] is [`Refusal::RotorStalled`].
//! 3. **Settle**: the stator flux is averaged over blocks of T̂_r (at least
//!    [`NO_LOAD_SETTLE_MIN_S`]); the settling ends when two blocks in a row agree within
//!    [`NO_LOAD_FLUX_STEADY`] after at least [`NO_LOAD_SETTLE_TR`] blocks (the rotor flux's
//!    and the rotor speed's transients both move it), or after [`NO_LOAD_SETTLE_MAX_BLOCKS`].
//!    The flux is `|V − R̂_s·I|/ω` (the commanded voltage turned back by the 1.5 periods
//!    by which it leads its effect): its component across the current (exact, the back-EMF
//!    of the flux along it) and along it (which a small error of R̂_s moves, but which adds
//!    only to second order while the slip is small). The inverter's error is not in V: each
//!    phase's `−sign(i_x)·V_e` is made up ahead of the loops, `+V̂_e·s(i_x*)` on the
//!    reference's phase currents (`s` the sign, ramped across ±[`DEAD_TIME_BAND_FRACTION`]
//!    of the amplitude, as the drive's compensation), `V̂_e = (3/4)·ê` from the first DC
//!    level's `ê = v − R̂_s·I` on the α axis. Subtracting its fundamental `(4/π)·V_e` along
//!    the measured current instead left a large motor's low levels far off: where the error
//!    is a third of the back-EMF (a 7.3 kW member's 0.3 level, 6.2 V against 18 V at 12.5 Hz)
//!    the uncompensated error clamps each phase current near its zero crossings, the
//!    error's fundamental turns off the current, and the level read its flux 8 % high,
//!    outside its interval (+1.1 % compensated; population test
//!    `saturating_members_are_identified_on_their_curve`). At low flux
//!    the friction's slip turns the current tens of degrees off the flux (45° at 0.3 of the
//!    rated flux on the shipped saturating motor): the component across alone then reads
//!    the flux 30 % low and the level lands at twice its target.
//!    Its last block corrects the amplitude toward rated flux in proportion (by at most
//!    [`NO_LOAD_CORRECTION_MAX`] either way), and it settles again; while the settled flux
//!    still misses by more than [`NO_LOAD_FLUX_TOLERANCE`] it corrects again by the secant
//!    through the last two settled (amplitude, flux) points, at most
//!    [`NO_LOAD_CORRECTIONS_MAX`] times in all, or until the test current caps the amplitude.
//!    A saturating branch needs this: its inductance falls as the current rises, and
//!    proportional steps only creep toward the target (on the shipped saturating motor one
//!    left the test at 107.9 % of the rated flux, which the host refuses).
//! 4. **Measure** [`NO_LOAD_WINDOWS`] windows of [`NO_LOAD_WINDOW_S`]: the mean commanded
//!    voltage and measured current in the frame of the current reference, and the encoder's
//!    turning (the slip).
//! 5. **The magnetizing curve** (issue 50, deliverable 4; [`CommissionSpec::curve`](super::CommissionSpec::curve)):
//!    the same settling, corrections and measurement at each fraction of the rated flux in
//!    [`CURVE_FLUX_FRACTIONS`] (0.3 to 1.2, [`CURVE_WINDOWS`] windows each), the amplitude's
//!    first guess the last level's scaled by the flux ratio, then at the test current itself
//!    if it lies above the last level's (uncorrected: so that the curve holds every current
//!    the DC levels used, whose decays the host reads through it): every level is a point of
//!    the branch's curve, whatever flux it settles at (the host reads the flux and the magnetizing current from the
//!    windows, `hil_sim::identify`). The field turns at the test frequency throughout — the
//!    back-EMF at the highest level takes at most 1.2 × [`NO_LOAD_VOLTAGE_FRACTION`] of the
//!    linear limit.
//! 6. **Decelerate**: the field frequency falls as it rose (the field lags the rotor by at
//!    most `1/T̂_r`) to zero, and the standing field brakes the rotor for at most
//!    [`NO_LOAD_BRAKE_S`]; then the sequence is done.

use super::{Commissioning, LEVELS, ROTATION_BLOCKS, ROTATION_HOLD_S, ROTATION_HZ, Refusal, Stage};
use crate::drive::DEAD_TIME_BAND_FRACTION;
use crate::drive::Measurements;
use crate::frames::{Abc, AlphaBeta, SinCos, wrap_angle};
use crate::svpwm;
use core::f32::consts::PI;

/// The test frequency is lowered, if need be, so that rated flux takes at most this fraction
/// of the linear voltage limit (the rest is the loops' room).
pub const NO_LOAD_VOLTAGE_FRACTION: f32 = 0.5;
/// Steepest rise (and fall) of the field's frequency, rad/s² (20 Hz/s electrical).
pub const NO_LOAD_RAMP_RAD_S2: f32 = 2.0 * PI * 20.0;
/// The rotor's speed for the slip bound is measured over this many periods (10 ms at 20 kHz).
pub const NO_LOAD_SPEED_PERIODS: u32 = 200;
/// The current amplitude moves to its target over this time, s.
pub const NO_LOAD_AMPLITUDE_RAMP_S: f32 = 0.2;
/// Settling at the test frequency: at least this many flux blocks of T̂_r…
pub const NO_LOAD_SETTLE_TR: u32 = 3;
/// …a block lasting at least this long, s…
pub const NO_LOAD_SETTLE_MIN_S: f32 = 0.05;
/// …until two blocks in a row agree within this fraction…
pub const NO_LOAD_FLUX_STEADY: f32 = 0.002;
/// …or this many blocks have passed.
pub const NO_LOAD_SETTLE_MAX_BLOCKS: u32 = 40;
/// T̂_r is taken within these bounds, s (it sets the slip bound and the settling time only).
pub const NO_LOAD_TR_RANGE_S: [f32; 2] = [1e-3, 2.0];
/// The flux correction changes the amplitude by at most this ratio either way.
pub const NO_LOAD_CORRECTION_MAX: f32 = 1.3;
/// After the first correction, another is made while the settled flux misses its target by
/// more than this fraction (a saturating branch; a linear one lands within it at once)…
pub const NO_LOAD_FLUX_TOLERANCE: f32 = 0.01;
/// …at most this many corrections in all, per level (six steps of at most
/// [`NO_LOAD_CORRECTION_MAX`] reach 4.8× or 0.21× the first guess's current).
pub const NO_LOAD_CORRECTIONS_MAX: u32 = 6;
/// The magnetizing curve's levels after the rated one, fractions of the rated stator flux:
/// the curve over 0.3–1.2 ψ_N (the saturation issue's deliverable 4), up from the lowest.
pub const CURVE_FLUX_FRACTIONS: [f32; 6] = [0.3, 0.5, 0.7, 0.9, 1.1, 1.2];
/// Measurement windows per curve level (repeats, for the point's interval), of
/// [`NO_LOAD_WINDOW_S`] each.
pub const CURVE_WINDOWS: usize = 2;
/// The curve's levels: [`CURVE_FLUX_FRACTIONS`], then the test current itself (if above the
/// last level's), so that the curve holds every current the DC levels used.
pub const CURVE_LEVELS: usize = CURVE_FLUX_FRACTIONS.len() + 1;
/// The test current's level keeps its flux below this multiple of the rated flux — its
/// back-EMF at most 0.8 of the linear limit, the rated flux's being at most
/// [`NO_LOAD_VOLTAGE_FRACTION`] of it — bounded by extrapolating the last level's chord
/// (saturation only lowers the flux): a motor that saturates little, or a large test current,
/// would otherwise run into the loops' voltage limit and lose the whole sequence.
pub const CURVE_FLUX_MAX: f32 = 0.8 / NO_LOAD_VOLTAGE_FRACTION;
/// Measurement windows (repeats, for the interval)…
pub const NO_LOAD_WINDOWS: usize = 4;
/// …of this length each, s.
pub const NO_LOAD_WINDOW_S: f32 = 0.125;
/// The field must reach the test frequency within this, s ([`Refusal::RotorStalled`]); the
/// deceleration ends after it at the latest.
pub const NO_LOAD_RAMP_MAX_S: f32 = 10.0;
/// Longest braking by the standing field at the end, s.
pub const NO_LOAD_BRAKE_S: f32 = 1.0;
/// The rotor counts as at rest below this electrical speed, a fraction of the slip bound.
pub const NO_LOAD_REST_FRACTION: f32 = 0.05;
/// Largest |k_e| accepted, electrical rad per encoder rad (64 pole pairs at a 4× slip or
/// line-count error): beyond it the rotor did not turn.
pub const NO_LOAD_KE_MAX: f32 = 256.0;

/// 1 − e^{−1}: the share of an exponential's area one time constant covers.
const ONE_MINUS_INV_E: f32 = 0.632_120_56;

/// One measurement window: means over [`NoLoadRecord::periods_per_window`] periods.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct NoLoadWindow {
    /// Commanded voltage in the frame of the current reference (d along it), V (the voltage
    /// commanded at period k against the reference's angle at period k).
    pub v_dq_v: [f32; 2],
    /// Measured current in that frame, A.
    pub i_dq_a: [f32; 2],
    /// The encoder's turning over the window, rad.
    pub theta_m_rad: f32,
}

/// The no-load test's record (all zero if it did not run).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct NoLoadRecord {
    /// The sequence's own R̂_s, Ω (set-up only).
    pub rs_ohm: f32,
    /// The sequence's own L̂_s, H (set-up only).
    pub ls_h: f32,
    /// The sequence's own T̂_r, s, within [`NO_LOAD_TR_RANGE_S`] (set-up only).
    pub tr_s: f32,
    /// Field electrical rad per encoder rad over the slow field's hold.
    pub k_e: f32,
    /// Stator flux after the first settling, before the correction, Wb.
    pub flux_first_wb: f32,
    /// Current amplitude during the measurement, A.
    pub amplitude_a: f32,
    /// Field frequency during the measurement, rad/s (electrical).
    pub omega_e_rad_s: f32,
    /// Periods per window.
    pub periods_per_window: u32,
    /// The windows.
    pub windows: [NoLoadWindow; NO_LOAD_WINDOWS],
    /// The magnetizing curve's windows: [`CURVE_WINDOWS`] per level of [`CURVE_LEVELS`], in
    /// order (all zero for a level not reached or skipped).
    pub curve: [NoLoadWindow; CURVE_LEVELS * CURVE_WINDOWS],
}

impl NoLoadRecord {
    /// 4-byte words of a serialised record.
    pub const WORDS: usize = 8 + 5 * (NO_LOAD_WINDOWS + CURVE_LEVELS * CURVE_WINDOWS);
}

/// Where the test stands.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) enum Phase {
    #[default]
    Accelerate,
    Settle {
        /// Corrections of the amplitude made so far at this level.
        corrections: u32,
    },
    Measure,
    Decelerate,
    Brake,
}

/// The test's working state.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct NoLoadState {
    phase: Phase,
    /// Periods into the phase (or window).
    k: u32,
    /// Field frequency, its target, rad/s.
    omega_e: f32,
    omega_target: f32,
    /// Rotor electrical speed from the last speed block, rad/s.
    omega_r_e: f32,
    /// Largest lead (or lag) of the field over the rotor, rad/s.
    slip_max: f32,
    /// Current amplitude, its target, A.
    amplitude: f32,
    amplitude_target: f32,
    /// Amplitude change per period while ramping, A.
    amplitude_step: f32,
    /// Periods of one flux block while settling, the blocks so far and the last one's flux.
    block_periods: u32,
    blocks: u32,
    flux_prev: f32,
    /// Encoder turning of the present speed block, rad, and its periods.
    speed_theta: f32,
    speed_n: u32,
    /// Σ stator flux over the present block, Wb.
    flux_sum: f32,
    /// Present window and its sums.
    window: usize,
    sums: NoLoadWindow,
    /// The level: 0 the rated flux, `k` ≥ 1 [`CURVE_FLUX_FRACTIONS`]`[k − 1]`.
    level: usize,
    /// The level's last settled (amplitude A, stator flux Wb), for the secant.
    settled: Option<(f32, f32)>,
    /// The inverter's error per phase V̂_e (each phase's `−sign(i_x)·V_e`), V.
    dead_time_v: f32,
    /// The commanded voltage's lead over its effect at the test frequency, as a rotation.
    lead: SinCos,
}

/// What a level aims at.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Target {
    /// A fraction of the rated flux (corrected toward it).
    Flux(f32),
    /// The test current (no correction).
    TestCurrent,
}

/// The target of `level` (`None` past the last level): 0 the rated flux, then the curve's.
fn level_target(level: usize) -> Option<Target> {
    match level {
        0 => Some(Target::Flux(1.0)),
        k if k <= CURVE_FLUX_FRACTIONS.len() => CURVE_FLUX_FRACTIONS.get(k - 1).map(|f| Target::Flux(*f)),
        k if k == CURVE_LEVELS => Some(Target::TestCurrent),
        _ => None,
    }
}

/// Upper bound of the test's periods (every wait to its timeout, T̂_r at its bound).
pub(super) fn max_periods(pwm_hz: f32) -> u64 {
    let settle = NO_LOAD_SETTLE_MAX_BLOCKS as f32 * NO_LOAD_TR_RANGE_S[1].max(NO_LOAD_SETTLE_MIN_S);
    let levels = 1 + CURVE_LEVELS;
    let s = 2.0 * NO_LOAD_RAMP_MAX_S
        + levels as f32 * (1 + NO_LOAD_CORRECTIONS_MAX) as f32 * (settle + NO_LOAD_AMPLITUDE_RAMP_S)
        + (NO_LOAD_WINDOWS + CURVE_LEVELS * CURVE_WINDOWS) as f32 * NO_LOAD_WINDOW_S
        + NO_LOAD_BRAKE_S;
    (s * pwm_hz) as u64 + 8
}

impl NoLoadState {
    /// After a level's windows: the next level of the curve, its amplitude's first guess the
    /// present one scaled by the flux ratio (within the test current); after the last, the
    /// deceleration — at once after the rated level unless `curve`
    /// ([`CommissionConfig::curve`](super::CommissionConfig::curve)).
    fn next_level(&mut self, curve: bool, test_current_a: f32, psi_rated_wb: f32, pwm_hz: f32) {
        let next = if curve { level_target(self.level + 1) } else { None };
        let target = match (level_target(self.level), next) {
            (Some(Target::Flux(from)), Some(Target::Flux(to))) => {
                (self.amplitude * to / from).min(test_current_a)
            }
            // The test current (within the flux bound), if the last level stayed clear of it.
            (_, Some(Target::TestCurrent)) => {
                let flux = self.settled.map_or(f32::INFINITY, |(_, f)| f);
                let cap = self.amplitude * CURVE_FLUX_MAX * psi_rated_wb / flux;
                let top = test_current_a.min(cap);
                // NaN (no settled flux) is not above either.
                let above = top.partial_cmp(&(self.amplitude * (1.0 + NO_LOAD_FLUX_TOLERANCE)));
                if above != Some(core::cmp::Ordering::Greater) {
                    self.phase = Phase::Decelerate;
                    return;
                }
                top
            }
            _ => {
                self.phase = Phase::Decelerate;
                return;
            }
        };
        self.level += 1;
        self.amplitude_target = target;
        self.amplitude_step = (self.amplitude_target - self.amplitude).abs().max(0.1 * self.amplitude_target)
            / (NO_LOAD_AMPLITUDE_RAMP_S * pwm_hz);
        (self.phase, self.k, self.blocks, self.flux_prev, self.flux_sum, self.settled) =
            (Phase::Settle { corrections: 0 }, 0, 0, 0.0, 0.0, None);
    }

    /// The inverter's error made up ahead of the loops: per phase `V̂_e·s(i_x)`, `i_x` the
    /// reference's phase current and `s` its sign ramped across ±[`DEAD_TIME_BAND_FRACTION`] of
    /// the amplitude (the drive's compensation, `svpwm::compensate_dead_time`, in volts).
    fn dead_time_compensation(&self, i_ref: AlphaBeta) -> AlphaBeta {
        let v_e = self.dead_time_v;
        let band = DEAD_TIME_BAND_FRACTION as f32 * self.amplitude;
        let k = v_e / band.max(f32::MIN_POSITIVE);
        // Comparisons, not `f32::clamp` (its panic path would be linked): a NaN gives −V̂_e.
        let s = |i: f32| (k * i).max(-v_e).min(v_e);
        let abc = i_ref.inverse_clarke();
        Abc { a: s(abc.a), b: s(abc.b), c: s(abc.c) }.clarke()
    }
}

/// Moves `x` toward `target` by at most `step`.
fn toward(x: f32, target: f32, step: f32) -> f32 {
    if x < target { (x + step).min(target) } else { (x - step).max(target) }
}

impl Commissioning {
    /// R̂_s, L̂_s and T̂_r from the DC levels (module docs, step 1); `None` if they make no
    /// sense (then the test does not run).
    pub(super) fn level_estimates(&self) -> Option<(f32, f32, f32)> {
        let [l0, l1, _] = &self.record.levels;
        let ts = self.cfg.ts_s;
        let (v0, v1) = (*l0.v_alpha_v.last()?, *l1.v_alpha_v.last()?);
        let di = l1.i_ref_a - l0.i_ref_a;
        let rs = (v1 - v0) / di;
        // (time at the block's end s, A there V·s), block by block.
        let areas = self.cfg.block_end.iter().zip(l1.v_alpha_v.iter()).scan(
            (0u32, rs * l1.lag_a_periods * ts),
            |(start, a), (&end, &v)| {
                *a += (v - v1) * (end - *start) as f32 * ts;
                *start = end;
                Some((end as f32 * ts, *a))
            },
        );
        let (_, total) = areas.clone().last()?;
        let ls = total / di;
        let l_sigma = self.record.l_sigma_pulse_h;
        let l_mm = ls - l_sigma;
        let threshold = (l_sigma + ONE_MINUS_INV_E * l_mm) * di;
        // The first block end past the threshold, interpolated from the one before.
        let mut before = (0.0, rs * l1.lag_a_periods * ts);
        let mut tr = f32::NAN;
        for (t, a) in areas {
            if a >= threshold {
                tr = before.0 + (t - before.0) * (threshold - before.1) / (a - before.1);
                break;
            }
            before = (t, a);
        }
        let [lo, hi] = NO_LOAD_TR_RANGE_S;
        (rs.is_finite() && rs > 0.0 && ls.is_finite() && l_mm > 0.0 && tr.is_finite() && tr > 0.0)
            .then_some((rs, ls, tr.clamp(lo, hi)))
    }

    /// At the slow field's hold end: sets the test up (module docs, step 1); `false` if it
    /// cannot run (the slow field then ramps down as without it).
    pub(super) fn start_no_load(&mut self, vdc_v: f32) -> bool {
        let Some((rs, ls, tr)) = self.level_estimates() else {
            return false;
        };
        let spec = self.cfg.spec;
        let rot = &self.record.rotation;
        // The second half of the hold: its blocks end at the record's end.
        let hold_blocks = (ROTATION_HOLD_S * spec.pwm_hz) as u32 / rot.periods_per_block.max(1);
        let half = (hold_blocks / 2) as usize;
        let (Some(&end), Some(&from)) =
            (rot.theta_m_rad.last(), rot.theta_m_rad.get(ROTATION_BLOCKS.saturating_sub(half + 1)))
        else {
            return false;
        };
        let w_rot = 2.0 * PI * ROTATION_HZ;
        let field = w_rot * (half as u32 * rot.periods_per_block) as f32 * self.cfg.ts_s;
        let k_e = field / (end - from);
        if !(k_e.is_finite() && k_e.abs() <= NO_LOAD_KE_MAX) {
            return false;
        }
        let psi = spec.rated_flux_wb;
        let w_bus = NO_LOAD_VOLTAGE_FRACTION * svpwm::linear_limit_v(vdc_v) / psi;
        let omega_target = (2.0 * PI * spec.no_load_hz).min(w_bus).max(w_rot);
        let amplitude_target = (psi / ls).min(spec.test_current_a);
        let amplitude = LEVELS[0] * spec.test_current_a;
        // The inverter's error on the α axis, ê = (4/3)·V_e; it opposes the current, so a
        // negative reading (noise on an inverter without dead time) is none.
        let e = self.record.levels.first().and_then(|l| Some(*l.v_alpha_v.last()? - rs * l.i_ref_a));
        self.no_load = NoLoadState {
            dead_time_v: (0.75 * e.filter(|e| e.is_finite()).unwrap_or(0.0)).max(0.0),
            lead: SinCos::new(1.5 * omega_target * self.cfg.ts_s),
            omega_e: w_rot,
            omega_target,
            omega_r_e: w_rot,
            slip_max: (1.0 / tr).min(omega_target),
            amplitude,
            amplitude_target,
            amplitude_step: (amplitude_target - amplitude).abs().max(0.1 * amplitude_target)
                / (NO_LOAD_AMPLITUDE_RAMP_S * spec.pwm_hz),
            block_periods: (tr.max(NO_LOAD_SETTLE_MIN_S) * spec.pwm_hz) as u32,
            ..NoLoadState::default()
        };
        let r = &mut self.record.no_load;
        (r.rs_ohm, r.ls_h, r.tr_s, r.k_e) = (rs, ls, tr, k_e);
        r.periods_per_window = (NO_LOAD_WINDOW_S * spec.pwm_hz) as u32;
        true
    }

    /// One period of the test (module docs).
    pub(super) fn no_load(&mut self, i: AlphaBeta, m: &Measurements) -> Option<(AlphaBeta, f32)> {
        let ts = self.cfg.ts_s;
        let pwm = self.cfg.spec.pwm_hz;
        let d_theta_m = wrap_angle(m.theta_m_rad - self.theta_m_prev_rad);
        self.theta_m_prev_rad = m.theta_m_rad;
        let k_e = self.record.no_load.k_e;
        let s = &mut self.no_load;
        s.speed_theta += d_theta_m;
        s.speed_n += 1;
        if s.speed_n >= NO_LOAD_SPEED_PERIODS {
            s.omega_r_e = k_e * s.speed_theta / (s.speed_n as f32 * ts);
            (s.speed_theta, s.speed_n) = (0.0, 0);
        }
        s.amplitude = toward(s.amplitude, s.amplitude_target, s.amplitude_step);
        let ramp = NO_LOAD_RAMP_RAD_S2 * ts;
        s.k += 1;
        match s.phase {
            Phase::Accelerate => {
                s.omega_e = (s.omega_e + ramp).min(s.omega_r_e + s.slip_max).min(s.omega_target).max(0.0);
                if s.omega_e >= s.omega_target && s.amplitude == s.amplitude_target {
                    (s.phase, s.k) = (Phase::Settle { corrections: 0 }, 0);
                } else if s.k as f32 > NO_LOAD_RAMP_MAX_S * pwm {
                    let hz = s.omega_e / (2.0 * PI);
                    self.refuse(Refusal::RotorStalled(hz));
                    return None;
                }
            }
            Phase::Settle { .. } | Phase::Measure => {}
            Phase::Decelerate => {
                s.omega_e = (s.omega_e - ramp).max(s.omega_r_e - s.slip_max).max(0.0);
                if s.omega_e <= 0.0 || s.k as f32 > NO_LOAD_RAMP_MAX_S * pwm {
                    (s.phase, s.k, s.omega_e) = (Phase::Brake, 0, 0.0);
                }
            }
            Phase::Brake => {
                let at_rest = s.speed_n == 0 && s.omega_r_e.abs() < NO_LOAD_REST_FRACTION * s.slip_max;
                if at_rest || s.k as f32 > NO_LOAD_BRAKE_S * pwm {
                    self.stage = Stage::Done;
                }
            }
        }
        let sc = SinCos::new(self.theta_e_rad);
        let amplitude = self.no_load.amplitude;
        let i_ref = AlphaBeta { alpha: amplitude * sc.cos, beta: amplitude * sc.sin };
        let v = self.regulate_ab(i_ref, i, m.vdc_v)?;
        self.measure(v, i, sc, d_theta_m);
        self.theta_e_rad = wrap_angle(self.theta_e_rad + self.no_load.omega_e * ts);
        Some((v + self.no_load.dead_time_compensation(i_ref), i_ref.alpha))
    }

    /// The settling's flux and its correction, and the measurement windows.
    fn measure(&mut self, v: AlphaBeta, i: AlphaBeta, sc: SinCos, d_theta_m: f32) {
        let psi_rated = self.cfg.spec.rated_flux_wb;
        let test_current = self.cfg.spec.test_current_a;
        let pwm_hz = self.cfg.spec.pwm_hz;
        let curve = self.cfg.curve();
        let rs = self.record.no_load.rs_ohm;
        let rec = &mut self.record.no_load;
        let s = &mut self.no_load;
        match s.phase {
            Phase::Settle { corrections } => {
                // The voltage turned back by its lead, across and along the current.
                let v = AlphaBeta {
                    alpha: s.lead.cos * v.alpha + s.lead.sin * v.beta,
                    beta: s.lead.cos * v.beta - s.lead.sin * v.alpha,
                };
                let i_a = i.magnitude().max(f32::MIN_POSITIVE);
                let across = (v.beta * i.alpha - v.alpha * i.beta) / i_a;
                let along = (v.alpha * i.alpha + v.beta * i.beta) / i_a - rs * i_a;
                let flux = AlphaBeta { alpha: across, beta: along }.magnitude();
                s.flux_sum += flux / s.omega_e.max(f32::MIN_POSITIVE);
                if s.k < s.block_periods {
                    return;
                }
                let flux = s.flux_sum / s.k as f32;
                let steady = (flux - s.flux_prev).abs() <= NO_LOAD_FLUX_STEADY * flux;
                (s.flux_sum, s.k, s.flux_prev) = (0.0, 0, flux);
                s.blocks += 1;
                if !((steady && s.blocks >= NO_LOAD_SETTLE_TR) || s.blocks >= NO_LOAD_SETTLE_MAX_BLOCKS) {
                    return;
                }
                (s.blocks, s.flux_prev) = (0, 0.0);
                let Some(Target::Flux(fraction)) = level_target(s.level) else {
                    // The test current's level: measured as it settles.
                    s.phase = Phase::Measure;
                    return;
                };
                let target = psi_rated * fraction;
                if s.level == 0 && corrections == 0 {
                    rec.flux_first_wb = flux;
                }
                let proportional = s.amplitude * target / flux;
                let secant = match s.settled {
                    Some((a0, f0)) => s.amplitude + (target - flux) * (s.amplitude - a0) / (flux - f0),
                    None => proportional,
                };
                let next = if secant.is_finite() { secant } else { proportional };
                let next = if next.is_finite() { next } else { s.amplitude };
                let amplitude = next
                    .clamp(s.amplitude / NO_LOAD_CORRECTION_MAX, s.amplitude * NO_LOAD_CORRECTION_MAX)
                    .min(test_current);
                s.settled = Some((s.amplitude, flux));
                let missed = (flux / target - 1.0).abs() > NO_LOAD_FLUX_TOLERANCE;
                let moves = amplitude != s.amplitude;
                if corrections == 0 || (missed && moves && corrections < NO_LOAD_CORRECTIONS_MAX) {
                    s.amplitude_target = amplitude;
                    s.phase = Phase::Settle { corrections: corrections + 1 };
                } else {
                    s.phase = Phase::Measure;
                    if s.level == 0 {
                        rec.amplitude_a = s.amplitude;
                        rec.omega_e_rad_s = s.omega_e;
                    }
                }
            }
            Phase::Measure => {
                let (vd, id) = (v.park(sc), i.park(sc));
                let w = &mut s.sums;
                w.v_dq_v[0] += vd.d;
                w.v_dq_v[1] += vd.q;
                w.i_dq_a[0] += id.d;
                w.i_dq_a[1] += id.q;
                w.theta_m_rad += d_theta_m;
                if s.k >= rec.periods_per_window {
                    let n = s.k as f32;
                    let (slots, windows) = match s.level {
                        0 => (&mut rec.windows[..], NO_LOAD_WINDOWS),
                        k => {
                            let from = (k - 1) * CURVE_WINDOWS;
                            (rec.curve.get_mut(from..from + CURVE_WINDOWS).unwrap_or_default(), CURVE_WINDOWS)
                        }
                    };
                    if let Some(out) = slots.get_mut(s.window) {
                        *out = NoLoadWindow {
                            v_dq_v: w.v_dq_v.map(|x| x / n),
                            i_dq_a: w.i_dq_a.map(|x| x / n),
                            theta_m_rad: w.theta_m_rad,
                        };
                    }
                    (s.sums, s.k) = (NoLoadWindow::default(), 0);
                    s.window += 1;
                    if s.window >= windows {
                        s.window = 0;
                        s.next_level(curve, test_current, psi_rated, pwm_hz);
                    }
                }
            }
            _ => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The compensation is the inverter's error turned round: on every phase whose reference
    /// current lies outside the ramp, `+V̂_e·sign(i_x)` against the error's `−V̂_e·sign(i_x)`
    /// (the simulator's switching inverter), so the two cancel in αβ; a phase at zero current
    /// gets none; its fundamental along a sinusoidal current is the error's, `(4/π)·V̂_e`.
    #[test]
    fn the_no_load_test_makes_up_the_inverters_error() {
        let s = NoLoadState { dead_time_v: 5.0, amplitude: 2.0, ..NoLoadState::default() };
        let band = DEAD_TIME_BAND_FRACTION as f32 * 2.0;
        let sign = |i: f32| if i > 0.0 { 1.0 } else { -1.0 };
        let n = 3600;
        let mut fundamental = 0.0;
        for k in 0..n {
            let theta = 2.0 * PI * k as f32 / n as f32;
            let sc = SinCos::new(theta);
            let i_ref = AlphaBeta { alpha: 2.0 * sc.cos, beta: 2.0 * sc.sin };
            let c = s.dead_time_compensation(i_ref);
            let abc = i_ref.inverse_clarke();
            let outside = [abc.a, abc.b, abc.c].iter().all(|i| i.abs() > band);
            if outside {
                let error =
                    Abc { a: -5.0 * sign(abc.a), b: -5.0 * sign(abc.b), c: -5.0 * sign(abc.c) }.clarke();
                assert!((c + error).magnitude() < 1e-5, "at {theta} rad: {c:?} against {error:?}");
            }
            fundamental += (c.alpha * sc.cos + c.beta * sc.sin) / n as f32;
        }
        assert!((fundamental / (4.0 / PI * 5.0) - 1.0).abs() < 2e-3, "{fundamental}");
        let zero = s.dead_time_compensation(AlphaBeta { alpha: 0.0, beta: 0.0 });
        assert_eq!(zero.magnitude(), 0.0);
    }
}
