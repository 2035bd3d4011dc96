//! Self-commissioning, host side (issue 20): run `controller_core::commission` against a
//! simulated motor (software in the loop), estimate the motor from its [`Record`], and write
//! a motor file with nominal values and intervals.
//!
//! # The model identified, and the leakage split
//! Seen from its terminals, an induction machine at standstill is the *inverse-Γ* circuit:
//! R_s, then L_σ = σL_s in series, then L_M = L_m²/L_r in parallel with R_R = R_r·(L_m/L_r)².
//! Its rotor time constant is T_r = L_M/R_R = L_r/R_r and L_s = L_σ + L_M. These four values
//! are all the terminals can tell; the T-model's five (R_s, R_r, L_s, L_r, L_m) need one
//! more: how the leakage divides between stator and rotor, `k = L_lr/L_ls` (default 1, the
//! usual equal split; IEEE Std 112 suggests 1.5 for NEMA design B, 1 for A and D). Control
//! does not depend on it: the current loops see R_s, σL_s and the rotor branch; IFOC's slip
//! gain needs T_r; the torque constant is 1.5·p·L_m²/L_r = 1.5·p·L_M; the rotor flux
//! referred to the stator, (L_m/L_r)·ψ_r, and every transfer function from stator voltage
//! to stator current are the same for every k (`split_leaves_the_terminals_unchanged`).
//!
//! # Estimation
//! - **R_s and the inverter's voltage error**: the DC levels' settled voltages `c` against
//!   their currents: `c = R_s·I + e` (two levels: the error e, constant while the phase
//!   currents keep their sign, cancels). Along phase a, each phase's dead-time error
//!   `−sign(i_x)·V_e` adds up to `−(4/3)·V_e` on the α axis, which the loop makes up:
//!   e = (4/3)·V_e, so V_e = ¾·e; its dead-time equivalent is `V_e/V_dc` of the period.
//! - **T_r and R_R** from each level step (the DC-decay test): with the current held by the
//!   loop at the new level, the rotor flux settles with T_r, and the voltage carries
//!   `dψ/dt = R_R·ΔI·e^{−t/T_r}` above its settled value. Each block mean is fitted by
//!   `c + A·(mean of e^{−(t − t₀)/τ} over the block)`, weighted by the block's length, with
//!   c and A by least squares for each τ and τ by a search on a logarithmic grid refined by
//!   golden section (variable projection). t₀ is the current's mean lag behind its step
//!   (from the record) less the 1.5 periods by which a commanded voltage precedes its
//!   effect. R_R = A/ΔI, L_M = R_R·T_r.
//! - **σL_s** from the injections: `Z(jω) = V̂·e^{−j1.5ωT}·sinc(ωT/2)/Î` (the voltage acts
//!   one period late and is held for a period), and
//!   `L_σ = (Im Z − Im Z_R)/ω` with the rotor branch `Z_R = jωL_M·R_R/(jωL_M + R_R)`.
//!
//! Every estimate is made once per repeat (two level pairs for R_s, three steps for T_r and
//! R_R, two frequencies for L_σ); the nominal value is their mean, the interval spans them,
//! widened by the stated margins ([`MARGIN`]).

use crate::inverter::InverterModel;
use crate::pil::{Pil, PilOptions};
use crate::sensors::SensorModel;
use crate::sim::{self, DriveUnderTest, Event, LoadModel, Scenario};
use controller_core::commission::{
    BLOCKS, CommissionConfig, CommissionOutput, Commissioning, LEVELS, RECORD_BYTES, Record, Refusal, Stage,
};
use controller_core::drive::{FastOutput, Measurements, Mode, PhaseCommand, Reference, Telemetry};
use controller_core::frames::AlphaBeta;
use controller_core::link::{Command, RECORD_CHUNK_BYTES, RECORD_CHUNKS, Reply};
use controller_core::motor::MotorParams;
use plant::Machine;
use std::cell::Cell;
use std::rc::Rc;

/// Relative margin added on each side of the repeats' span, per parameter: the accuracy the
/// identification is tested to on every shipped motor and on seeded random motors
/// (`tests/identify.rs`) — what the repeats cannot show (a current sensor's gain error
/// scales every impedance alike; the model's approximations).
pub const MARGIN: Margins = Margins { rs: 0.03, l_sigma: 0.05, tr: 0.05, rr: 0.05, lm: 0.03 };

/// Relative margins ([`MARGIN`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Margins {
    /// R_s.
    pub rs: f64,
    /// σL_s.
    pub l_sigma: f64,
    /// T_r.
    pub tr: f64,
    /// R_r (and R_R).
    pub rr: f64,
    /// L_m, L_s, L_r (and L_M).
    pub lm: f64,
}

/// A value and its interval.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Estimate {
    /// Mean of the repeats.
    pub value: f64,
    /// Smallest and largest repeat, widened by the margin.
    pub interval: [f64; 2],
    /// Largest repeat over the smallest, minus one (the repeatability).
    pub spread: f64,
}

impl Estimate {
    fn of(repeats: &[f64], margin: f64) -> Self {
        let n = repeats.len().max(1) as f64;
        let value = repeats.iter().sum::<f64>() / n;
        let lo = repeats.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = repeats.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        Self { value, interval: [lo * (1.0 - margin), hi * (1.0 + margin)], spread: hi / lo - 1.0 }
    }

    /// A derived value: `f` of the nominal values, its interval from `f` at the ends
    /// (`f` monotonic in each argument: the caller passes the ends that bound it).
    fn derived(value: f64, lo: f64, hi: f64) -> Self {
        Self { value, interval: [lo.min(hi), hi.max(lo)], spread: f64::NAN }
    }

    /// `x` lies in the interval.
    pub fn contains(&self, x: f64) -> bool {
        self.interval[0] <= x && x <= self.interval[1]
    }
}

/// One exponential fit of a level step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DecayFit {
    /// Settled voltage, V.
    pub c_v: f64,
    /// Amplitude at the current's step, V.
    pub a_v: f64,
    /// Time constant, s.
    pub tau_s: f64,
    /// RMS of the weighted residual, V.
    pub rms_v: f64,
    /// Settled current of the level, A.
    pub i_a: f64,
}

/// What the standstill sequence identified.
#[derive(Clone, Debug, PartialEq)]
pub struct Identified {
    /// Stator resistance, Ω.
    pub rs_ohm: Estimate,
    /// Transient inductance σL_s = L_σ, H.
    pub l_sigma_h: Estimate,
    /// Rotor time constant, s.
    pub tr_s: Estimate,
    /// Referred rotor resistance R_R = R_r·(L_m/L_r)², Ω.
    pub r_rr_ohm: Estimate,
    /// L_M = L_m²/L_r, H: at rated flux by the no-load test if it ran, else from the DC
    /// levels.
    pub l_mm_h: Estimate,
    /// The inverter's voltage error per phase V_e, V.
    pub inverter_error_v: Estimate,
    /// Current-channel offsets, A.
    pub offsets_a: [f64; 3],
    /// Mean bus voltage, V.
    pub vdc_v: f64,
    /// The decay fits of the three level steps.
    pub decays: [DecayFit; 3],
    /// Impedance measured at each injection: (ω rad/s, Re Z, Im Z).
    pub impedance: [(f64, f64, f64); 2],
    /// The rotating field's results (if the motor was allowed to turn).
    pub rotation: Option<Rotation>,
    /// The no-load test's results (if the motor was allowed to turn).
    pub no_load: Option<NoLoad>,
}

/// What the no-load test at rated flux found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NoLoad {
    /// L_M at the test's flux, H (one repeat per window).
    pub l_mm_h: Estimate,
    /// L_M from the DC levels (the standstill test's flux), H.
    pub standstill_l_mm_h: Estimate,
    /// Stator flux reached, Wb (peak), against the rated flux asked for.
    pub flux_wb: f64,
    /// The rated stator flux asked for, Wb.
    pub rated_flux_wb: f64,
    /// Field frequency, rad/s (electrical).
    pub omega_e_rad_s: f64,
    /// Current amplitude, A.
    pub amplitude_a: f64,
    /// Mean slip, rad/s (electrical; from the encoder and the pole pairs).
    pub slip_rad_s: f64,
}

/// What the slow rotating field found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rotation {
    /// The rotor's turning over the field's mechanical turning during the hold (1 − slip):
    /// the encoder's direction and line count, with the pole pairs given.
    pub ratio: f64,
    /// Mean speed during the hold, rad/s.
    pub omega_hold_rad_s: f64,
    /// Inertia, kg·m².
    pub j_kgm2: Estimate,
    /// Viscous friction, N·m·s/rad.
    pub b_nms: Estimate,
}

/// Relative margin on J and B, beyond three standard errors of their fit.
pub const MECHANICS_MARGIN: f64 = 0.10;

/// How well the slip during the hold is known, as a fraction of the field's frequency (the
/// hold's speed ratio scatters by ≈ 0.2 % between runs: the encoder's sampling at the hold's
/// ends and its speed estimate's lag). B rests on the small torque of that slip: the error
/// `k_τ·δω_sl/ω` it allows (k_τ = 1.5·p·L_M·I²·T_r, the torque per slip of an impressed
/// current) widens B's interval — for a large machine with little friction, B is then
/// hardly known, and its interval says so.
pub const SLIP_RESOLUTION: f64 = 0.002;

/// The rotor may turn this much slower than the field's mechanical speed (slip), or this
/// little faster (the encoder's and the fit's resolution), before the encoder's line count
/// or the pole pairs are taken to be wrong.
pub const ROTATION_RATIO_RANGE: [f64; 2] = [0.7, 1.05];

/// The rotating field's estimates (module docs; `Err` names a wrong encoder).
///
/// The field's angle is recomputed as the sequence made it; the rotor's from the recorded
/// encoder turning at each block's end (exact to a count). The direction and line count:
/// the rotor's turning over the field's mechanical turning during the second half of the
/// hold. The mechanics: the flux of the impressed current through the identified rotor
/// (`dψ/dt = R_R·i − ψ/T_r + j·p·ω·ψ`, ω from the encoder) gives the torque
/// `τ = 1.5·p·(ψ × i)`; from rest, `J·ω(t) + B·θ(t) = ∫₀ᵗ τ` at every block's middle (ω the
/// block's mean speed, θ the turning so far), solved for J and B by least squares.
///
/// The torque is that of a small slip, and a speed error δω moves it by `k_τ·p·δω`: the
/// stiffer the machine (large k_τ, long T_r), the more J rests on the encoder's resolution
/// — within 10 % on every motor of `tests/identify.rs` (0.1 % on the DeLorenzo machine,
/// 4 % on the 500 hp Krause machine).
fn rotation(
    cfg: &CommissionConfig,
    rec: &Record,
    pole_pairs: u8,
    l_mm: f64,
    r_rr: f64,
) -> Result<Rotation, String> {
    use controller_core::commission::{ROTATION_HOLD_S, ROTATION_HZ, ROTATION_RAMP_S};
    let r = &rec.rotation;
    let p = f64::from(pole_pairs);
    let pwm = f64::from(cfg.spec().pwm_hz);
    let ts = 1.0 / pwm;
    let ramp = (f64::from(ROTATION_RAMP_S) * pwm).floor();
    let w_max = 2.0 * std::f64::consts::PI * f64::from(ROTATION_HZ);
    let per_block = f64::from(r.periods_per_block);
    let blocks = r.theta_m_rad.len();
    let dt_block = per_block * ts;
    let theta_m: Vec<f64> = std::iter::once(0.0).chain(r.theta_m_rad.iter().map(|x| f64::from(*x))).collect();
    // A record from elsewhere (a board's) is checked before it is used: no blocks, or blocks
    // that do not fit the ramp and the hold, are an empty record, not a panic.
    let pwm_f32 = cfg.spec().pwm_hz;
    // As the sequence computes it (controller_core::commission, in f32 and u32).
    let expected =
        f64::from(((ROTATION_RAMP_S * pwm_f32) as u32 + (ROTATION_HOLD_S * pwm_f32) as u32) / blocks as u32);
    if per_block <= 0.0 || per_block != expected {
        return Err(format!(
            "the rotating field's record is empty or not this sequence's ({per_block} periods per block, expected {expected})"
        ));
    }
    // The second half of the hold: the field turns at w_max there.
    let hold_blocks = (f64::from(ROTATION_HOLD_S) / dt_block).round() as usize;
    let from = blocks.saturating_sub(hold_blocks / 2).min(blocks - 1);
    let ratio = p * (theta_m[blocks] - theta_m[from]) / (w_max * (blocks - from) as f64 * dt_block);
    if !ratio.is_finite() {
        return Err("the rotating field's record is empty".into());
    }
    if ratio < 0.0 {
        return Err(format!(
            "the encoder counts against the rotating field (the rotor turned {ratio:.3}× the field): its A and B \
             channels, or two motor leads, are swapped"
        ));
    }
    let [lo, hi] = ROTATION_RATIO_RANGE;
    if !(lo..=hi).contains(&ratio) {
        return Err(format!(
            "the encoder saw the rotor turn {ratio:.3}× the field's mechanical speed (expected {lo} … {hi}): \
             a wrong encoder line count, or {pole_pairs} pole pairs is wrong"
        ));
    }
    // Mean speed of each block, and its middle's turning so far.
    let omega: Vec<f64> = (0..blocks).map(|b| (theta_m[b + 1] - theta_m[b]) / dt_block).collect();
    let theta_mid: Vec<f64> = (0..blocks).map(|b| 0.5 * (theta_m[b] + theta_m[b + 1])).collect();
    let omega_at = |k: f64| {
        // Piecewise linear through the block means at the block middles, from rest.
        let x = k / per_block - 0.5;
        if x <= 0.0 {
            return omega[0] * (k / (0.5 * per_block)).clamp(0.0, 1.0);
        }
        let b = (x.floor() as usize).min(blocks - 2);
        omega[b] + (omega[b + 1] - omega[b]) * (x - b as f64).clamp(0.0, 1.0)
    };
    let amp = f64::from(r.amplitude_a);
    let tr = l_mm / r_rr;
    // The flux the rotation starts from: the last level's step down from I to I/2 still
    // decaying (the injections ride on I/2 and average out).
    let injections: u32 = controller_core::commission::INJECTION_PERIODS
        .iter()
        .map(|n| {
            n * (controller_core::commission::INJECTION_SETTLE_CYCLES
                + controller_core::commission::INJECTION_CYCLES)
        })
        .sum();
    let since_s = (f64::from(cfg.level_periods()) + f64::from(injections)) * ts;
    let step_a = f64::from(rec.levels[1].i_ref_a - rec.levels[2].i_ref_a);
    let psi0 = l_mm * (amp + step_a * (-since_s / tr).exp());
    let (mut psi, mut theta_e) = ([psi0, 0.0], 0.0f64);
    let n = blocks * r.periods_per_block as usize;
    let mut torque_int = 0.0;
    let mut torque_at_mid = vec![0.0; blocks];
    let half = r.periods_per_block as usize / 2;
    for k in 0..n {
        let kf = k as f64;
        let w = if kf < ramp { w_max * kf / ramp } else { w_max };
        let i = [amp * theta_e.cos(), amp * theta_e.sin()];
        let wr = p * omega_at(kf);
        let f = |psi: [f64; 2]| {
            [r_rr * i[0] - psi[0] / tr - wr * psi[1], r_rr * i[1] - psi[1] / tr + wr * psi[0]]
        };
        let k1 = f(psi);
        let k2 = f([psi[0] + 0.5 * ts * k1[0], psi[1] + 0.5 * ts * k1[1]]);
        torque_int += 1.5 * p * (psi[0] * i[1] - psi[1] * i[0]) * ts;
        psi = [psi[0] + ts * k2[0], psi[1] + ts * k2[1]];
        theta_e += w * ts;
        if k % r.periods_per_block as usize == half
            && let Some(t) = torque_at_mid.get_mut(k / r.periods_per_block as usize)
        {
            *t = torque_int;
        }
    }
    let (mut a11, mut a12, mut a22, mut y1, mut y2) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for b in 0..blocks {
        let (x1, x2, y) = (omega[b], theta_mid[b], torque_at_mid[b]);
        a11 += x1 * x1;
        a12 += x1 * x2;
        a22 += x2 * x2;
        y1 += x1 * y;
        y2 += x2 * y;
    }
    let det = a11 * a22 - a12 * a12;
    if det.abs() <= 1e-300 {
        return Err("the rotor did not accelerate: no inertia to fit".into());
    }
    let j = (a22 * y1 - a12 * y2) / det;
    let b = (a11 * y2 - a12 * y1) / det;
    let ssr: f64 = (0..blocks).map(|k| (torque_at_mid[k] - j * omega[k] - b * theta_mid[k]).powi(2)).sum();
    let s2 = ssr / (blocks as f64 - 2.0);
    let (sj, sb) = ((s2 * a22 / det).sqrt(), (s2 * a11 / det).sqrt());
    if !(j.is_finite() && j > 0.0) {
        return Err(format!("the rotating field gives no positive inertia ({j} kg·m²)"));
    }
    let widen = |x: f64, s: f64| {
        let m = MECHANICS_MARGIN * x.abs();
        Estimate { value: x, interval: [(x - 3.0 * s - m).max(0.0), x + 3.0 * s + m], spread: s / x.abs() }
    };
    let omega_hold = (theta_m[blocks] - theta_m[from]) / ((blocks - from) as f64 * dt_block);
    let k_tau = 1.5 * p * l_mm * amp * amp * tr;
    let b_slip = k_tau * SLIP_RESOLUTION * w_max / omega_hold.abs().max(1e-9);
    let mut b_est = widen(b.max(0.0), sb);
    b_est.interval = [(b_est.interval[0] - b_slip).max(0.0), b_est.interval[1] + b_slip];
    Ok(Rotation { ratio, omega_hold_rad_s: omega_hold, j_kgm2: widen(j, sj), b_nms: b_est })
}

/// The T-model under a leakage split.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TModel {
    /// Stator resistance, Ω.
    pub rs_ohm: f64,
    /// Rotor resistance, Ω.
    pub rr_ohm: f64,
    /// Stator self-inductance, H.
    pub ls_h: f64,
    /// Rotor self-inductance, H.
    pub lr_h: f64,
    /// Magnetizing inductance, H.
    pub lm_h: f64,
}

/// The T-model with `L_lr/L_ls = ratio` whose terminals are R_s, L_σ, L_M, R_R.
pub fn t_model(rs: f64, l_sigma: f64, l_mm: f64, r_rr: f64, ratio: f64) -> TModel {
    let ls = l_sigma + l_mm;
    // L_M·(L_m + k·(L_s − L_m)) = L_m²: the positive root.
    let b = l_mm * (1.0 - ratio);
    let lm = 0.5 * (b + (b * b + 4.0 * ratio * l_mm * ls).sqrt());
    let lr = lm * lm / l_mm;
    TModel { rs_ohm: rs, rr_ohm: r_rr * (lr / lm).powi(2), ls_h: ls, lr_h: lr, lm_h: lm }
}

impl Identified {
    /// The T-model at the nominal values, with leakage ratio `ratio`.
    pub fn t_model(&self, ratio: f64) -> TModel {
        t_model(self.rs_ohm.value, self.l_sigma_h.value, self.l_mm_h.value, self.r_rr_ohm.value, ratio)
    }

    /// Intervals of the T-model's parameters under `ratio`: each from the inverse-Γ
    /// intervals' ends (R_r grows with R_R; L_m, L_s, L_r with L_σ and L_M).
    pub fn t_intervals(&self, ratio: f64) -> [(&'static str, Estimate); 5] {
        let n = self.t_model(ratio);
        let [sl, sh] = self.l_sigma_h.interval;
        let [ml, mh] = self.l_mm_h.interval;
        let [rl, rh] = self.r_rr_ohm.interval;
        let lo = t_model(self.rs_ohm.value, sl, ml, rl, ratio);
        let hi = t_model(self.rs_ohm.value, sh, mh, rh, ratio);
        // R_r = R_R·(L_r/L_m)²; (L_r/L_m)² depends on L_σ and L_M in opposite senses: its
        // bounds from the cross ends.
        let ratio2 = |s: f64, m: f64| {
            let t = t_model(1.0, s, m, 1.0, ratio);
            t.rr_ohm
        };
        let q = [ratio2(sl, ml), ratio2(sl, mh), ratio2(sh, ml), ratio2(sh, mh)];
        let (qmin, qmax) =
            q.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| (a.min(x), b.max(x)));
        [
            ("rs_ohm", self.rs_ohm),
            ("rr_ohm", Estimate::derived(n.rr_ohm, rl * qmin, rh * qmax)),
            ("ls_h", Estimate::derived(n.ls_h, lo.ls_h, hi.ls_h)),
            ("lr_h", Estimate::derived(n.lr_h, lo.lr_h, hi.lr_h)),
            ("lm_h", Estimate::derived(n.lm_h, lo.lm_h, hi.lm_h)),
        ]
    }
}

/// Mean over periods `a..e` of `q^(k − k0)`.
fn block_mean(q: f64, a: f64, e: f64, k0: f64) -> f64 {
    let n = e - a;
    if (1.0 - q).abs() < 1e-12 {
        return q.powf(a - k0);
    }
    q.powf(a - k0) * (1.0 - q.powf(n)) / (n * (1.0 - q))
}

/// Weighted least squares of `y ≈ c + A·g` for fixed g: (c, A, Σw·r²).
fn fit_linear(w: &[f64], g: &[f64], y: &[f64]) -> (f64, f64, f64) {
    let (mut s, mut sg, mut sgg, mut sy, mut sgy) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for ((w, g), y) in w.iter().zip(g).zip(y) {
        s += w;
        sg += w * g;
        sgg += w * g * g;
        sy += w * y;
        sgy += w * g * y;
    }
    let det = s * sgg - sg * sg;
    if det.abs() < 1e-300 {
        let c = sy / s;
        return (c, 0.0, w.iter().zip(y).map(|(w, y)| w * (y - c).powi(2)).sum());
    }
    let c = (sgg * sy - sg * sgy) / det;
    let a = (s * sgy - sg * sy) / det;
    let ssr = w.iter().zip(g).zip(y).map(|((w, g), y)| w * (y - c - a * g).powi(2)).sum();
    (c, a, ssr)
}

/// Periods of the loop's transient after a step left out of the decay fit: ten time
/// constants of the current loop (`1/ω_c` is `LOOP_BANDWIDTH_DIVIDER/2π` periods).
fn skip_periods() -> f64 {
    10.0 * f64::from(controller_core::commission::LOOP_BANDWIDTH_DIVIDER) / (2.0 * std::f64::consts::PI)
}

/// Fits one level's record (see the module docs).
fn fit_decay(cfg: &CommissionConfig, rec: &Record, level: usize) -> Result<DecayFit, String> {
    let lv = rec.levels.get(level).ok_or("no such level")?;
    let ts = f64::from(cfg.ts_s());
    let ends: Vec<f64> = cfg.block_end().iter().map(|&e| f64::from(e)).collect();
    let starts: Vec<f64> = std::iter::once(0.0).chain(ends.iter().copied()).take(BLOCKS).collect();
    let settled = |x: &[f32; BLOCKS]| -> f64 {
        // The last three blocks, weighted by length.
        let (mut s, mut n) = (0.0, 0.0);
        for b in BLOCKS - 3..BLOCKS {
            let len = ends[b] - starts[b];
            s += f64::from(x[b]) * len;
            n += len;
        }
        s / n
    };
    let i_now = settled(&lv.i_alpha_a);
    let i_before = if level == 0 { 0.0 } else { settled(&rec.levels[level - 1].i_alpha_a) };
    let ref_before = if level == 0 { 0.0 } else { f64::from(rec.levels[level - 1].i_ref_a) };
    let step_ref = f64::from(lv.i_ref_a) - ref_before;
    let lag = if step_ref.abs() > 0.0 { f64::from(lv.lag_a_periods) / step_ref } else { 0.0 };
    let k0 = lag - 1.5;
    let skip = skip_periods();
    let keep: Vec<usize> = (0..BLOCKS).filter(|&b| starts[b] >= skip).collect();
    let w: Vec<f64> = keep.iter().map(|&b| ends[b] - starts[b]).collect();
    let y: Vec<f64> = keep.iter().map(|&b| f64::from(lv.v_alpha_v[b])).collect();
    let ssr_at = |tau: f64| {
        let q = (-1.0 / (tau / ts)).exp();
        let g: Vec<f64> = keep.iter().map(|&b| block_mean(q, starts[b], ends[b], k0)).collect();
        let (c, a, ssr) = fit_linear(&w, &g, &y);
        (ssr, c, a)
    };
    // Logarithmic grid from 2 periods to 10 levels, then golden section on ln τ.
    let level_s = f64::from(cfg.level_periods()) * ts;
    let (lo, hi) = ((2.0 * ts).ln(), (10.0 * level_s).ln());
    let grid = 200;
    let x_at = |j: usize| lo + (hi - lo) * j as f64 / grid as f64;
    let best = (0..=grid)
        .map(|j| (j, ssr_at(x_at(j).exp()).0))
        .fold((0, f64::INFINITY), |acc, (j, s)| if s < acc.1 { (j, s) } else { acc })
        .0;
    let (mut a, mut b) = (x_at(best.saturating_sub(1)), x_at((best + 1).min(grid)));
    let g = 0.5 * (5f64.sqrt() - 1.0);
    for _ in 0..80 {
        let (x1, x2) = (b - g * (b - a), a + g * (b - a));
        if ssr_at(x1.exp()).0 < ssr_at(x2.exp()).0 {
            b = x2;
        } else {
            a = x1;
        }
    }
    let tau = (0.5 * (a + b)).exp();
    let (ssr, c, amp) = ssr_at(tau);
    let wsum: f64 = w.iter().sum();
    if tau > 0.5 * level_s {
        return Err(format!(
            "level {level}: the rotor time constant ({tau:.3} s) is longer than half a level ({:.3} s): \
             hold the levels longer (--level-time ≥ {:.1} s)",
            0.5 * level_s,
            4.0 * tau
        ));
    }
    if !(i_now - i_before).is_finite() || (i_now - i_before).abs() < 1e-9 {
        return Err(format!("level {level}: the current did not step"));
    }
    Ok(DecayFit { c_v: c, a_v: amp, tau_s: tau, rms_v: (ssr / wsum).sqrt(), i_a: i_now })
}

/// Estimates the motor from a finished sequence's record (see the module docs);
/// `pole_pairs` (the nameplate's) checks the encoder against the rotating field.
pub fn estimate(cfg: &CommissionConfig, rec: &Record, pole_pairs: u8) -> Result<Identified, String> {
    let ts = f64::from(cfg.ts_s());
    let decays = [fit_decay(cfg, rec, 0)?, fit_decay(cfg, rec, 1)?, fit_decay(cfg, rec, 2)?];
    let [d0, d1, d2] = decays;
    // R_s from the two level pairs; the voltage error from each level's line.
    let rs = [(d1.c_v - d0.c_v) / (d1.i_a - d0.i_a), (d1.c_v - d2.c_v) / (d1.i_a - d2.i_a)];
    let rs_mean = 0.5 * (rs[0] + rs[1]);
    let e: Vec<f64> = decays.iter().map(|d| 0.75 * (d.c_v - rs_mean * d.i_a)).collect();
    // Each step: R_R = A/ΔI, T_r = τ.
    let steps = [(d0, 0.0), (d1, d0.i_a), (d2, d1.i_a)];
    let r_rr: Vec<f64> = steps.iter().map(|(d, before)| d.a_v / (d.i_a - before)).collect();
    let tr: Vec<f64> = decays.iter().map(|d| d.tau_s).collect();
    if r_rr.iter().chain(&tr).chain(&rs).any(|x| !(x.is_finite() && *x > 0.0)) {
        return Err(format!(
            "the DC levels do not fit an induction machine (R_s {rs:?} Ω, R_R {r_rr:?} Ω, T_r {tr:?} s)"
        ));
    }
    let rs_est = Estimate::of(&rs, MARGIN.rs);
    let rr_est = Estimate::of(&r_rr, MARGIN.rr);
    let tr_est = Estimate::of(&tr, MARGIN.tr);
    let l_mm: Vec<f64> = r_rr.iter().zip(&tr).map(|(r, t)| r * t).collect();
    let lmm_est = Estimate::of(&l_mm, MARGIN.lm);
    // σL_s from each injection.
    let mut impedance = [(0.0, 0.0, 0.0); 2];
    let mut l_sigma = Vec::new();
    for (slot, j) in impedance.iter_mut().zip(&rec.injections) {
        let n = f64::from(j.periods_per_cycle);
        let w = 2.0 * std::f64::consts::PI / (n * ts);
        // x = X_s·sin φ + X_c·cos φ = Re((X_c − jX_s)·e^{jφ}).
        let phasor = |sc: [f32; 2]| (f64::from(sc[1]), -f64::from(sc[0]));
        let (vr, vi) = phasor(j.v_sin_cos);
        let (ir, ii) = phasor(j.i_sin_cos);
        let half = 0.5 * w * ts;
        let (dr, di) = ((-3.0 * half).cos(), (-3.0 * half).sin());
        let sinc = half.sin() / half;
        let (var, vai) = ((vr * dr - vi * di) * sinc, (vr * di + vi * dr) * sinc);
        let den = ir * ir + ii * ii;
        if den.is_nan() || den <= 0.0 {
            return Err("no current answered the injection".into());
        }
        let (zr, zi) = ((var * ir + vai * ii) / den, (vai * ir - var * ii) / den);
        *slot = (w, zr, zi);
        // Rotor branch jωL_M·R_R/(jωL_M + R_R): imaginary part ω·L_M·R_R²/(R_R² + ω²L_M²).
        let (lm, rr) = (lmm_est.value, rr_est.value);
        let zb_im = w * lm * rr * rr / (rr * rr + w * w * lm * lm);
        l_sigma.push((zi - zb_im) / w);
    }
    if l_sigma.iter().any(|x| !(x.is_finite() && *x > 0.0)) {
        return Err(format!("the injections give no positive transient inductance ({l_sigma:?} H)"));
    }
    let offsets_a = rec.offsets_a.map(f64::from);
    let l_sigma_est = Estimate::of(&l_sigma, MARGIN.l_sigma);
    let e_est = Estimate::of(&e, 0.0);
    let (rotation, no_load) = if cfg.spec().rotate {
        let rot = rotation(cfg, rec, pole_pairs, lmm_est.value, rr_est.value)?;
        let terminals = Terminals { rs: rs_est.value, l_sigma: l_sigma_est.value, v_e: e_est.value };
        (Some(rot), Some(no_load(cfg, rec, pole_pairs, terminals, lmm_est)?))
    } else {
        (None, None)
    };
    Ok(Identified {
        rs_ohm: rs_est,
        l_sigma_h: l_sigma_est,
        tr_s: tr_est,
        r_rr_ohm: rr_est,
        l_mm_h: no_load.map_or(lmm_est, |n| n.l_mm_h),
        inverter_error_v: e_est,
        offsets_a,
        vdc_v: f64::from(rec.vdc_v),
        decays,
        impedance,
        rotation,
        no_load,
    })
}

/// The standstill estimates the no-load test's impedance is corrected with.
#[derive(Clone, Copy, Debug)]
struct Terminals {
    /// R_s, Ω.
    rs: f64,
    /// L_σ, H.
    l_sigma: f64,
    /// The inverter's voltage error per phase, V.
    v_e: f64,
}

/// The no-load test's estimates (`controller_core::commission::no_load`).
///
/// Per window, in the frame of the current reference: the commanded voltage acts 1.5
/// periods later and held (`V = V̂·e^{−j1.5ωT}·sinc(ωT/2)`, as for the injections), less the
/// inverter's error — each phase's `−sign(i)·V_e` square wave has the fundamental
/// `(4/π)·V_e` along the current, which the loops make up. Then `Z = V/I`, the rotor branch
/// `Z_R = Z − R_s − jωL_σ` and its admittance `Y_R = 1/(jωL_M) + s/R_R` (s the slip):
/// `L_M = −1/(ω·Im Y_R)`, whatever the slip (it only adds a real part). The stator flux
/// reached is `|V − R_s·I|/ω`.
fn no_load(
    cfg: &CommissionConfig,
    rec: &Record,
    pole_pairs: u8,
    t: Terminals,
    standstill: Estimate,
) -> Result<NoLoad, String> {
    let n = &rec.no_load;
    let ts = f64::from(cfg.ts_s());
    let w = f64::from(n.omega_e_rad_s);
    let periods = f64::from(n.periods_per_window);
    if !(w > 0.0 && w.is_finite() && periods > 0.0) {
        return Err("the no-load test did not run (the rotor did not follow the slow field)".into());
    }
    let half = 0.5 * w * ts;
    let delay = num_complex::Complex64::from_polar(half.sin() / half, -3.0 * half);
    let mut l_mm = Vec::new();
    let (mut flux, mut slip) = (0.0, 0.0);
    for win in &n.windows {
        let v = num_complex::Complex64::new(f64::from(win.v_dq_v[0]), f64::from(win.v_dq_v[1])) * delay;
        let i = num_complex::Complex64::new(f64::from(win.i_dq_a[0]), f64::from(win.i_dq_a[1]));
        if i.norm().is_nan() || i.norm() <= 0.0 {
            return Err("no current in the no-load test's record".into());
        }
        let v = v - i / i.norm() * (4.0 / std::f64::consts::PI * t.v_e);
        let z_r = v / i - t.rs - num_complex::Complex64::new(0.0, w * t.l_sigma);
        let l = -1.0 / (w * (1.0 / z_r).im);
        if !(l.is_finite() && l > 0.0) {
            return Err(format!("the no-load test gives no positive magnetizing inductance ({l} H)"));
        }
        l_mm.push(l);
        flux += (v - i * t.rs).norm() / w;
        slip += w - f64::from(pole_pairs) * f64::from(win.theta_m_rad) / (periods * ts);
    }
    let k = n.windows.len() as f64;
    let rated = f64::from(cfg.spec().rated_flux_wb);
    if flux / k < NO_LOAD_FLUX_MIN * rated {
        let spec = cfg.spec();
        let capped = f64::from(n.amplitude_a) >= 0.999 * f64::from(spec.test_current_a);
        let lowered = w < 0.999 * 2.0 * std::f64::consts::PI * f64::from(spec.no_load_hz);
        let why = match (capped, lowered) {
            (true, true) => "the test current capped the current and the bus the frequency",
            (true, false) => "the test current capped the current (raise --test-current)",
            (false, true) => "the bus could not give it at the test frequency, lowered to its floor",
            (false, false) => "the flux correction reached its limit (a strongly saturating motor?)",
        };
        return Err(format!(
            "the no-load test reached only {:.1} % of the rated flux {rated:.4} Wb ({why}): check the nameplate \
             (--rated-voltage, --rated-frequency); nothing measured at rated flux",
            100.0 * flux / k / rated
        ));
    }
    Ok(NoLoad {
        l_mm_h: Estimate::of(&l_mm, MARGIN.lm),
        standstill_l_mm_h: standstill,
        flux_wb: flux / k,
        rated_flux_wb: f64::from(cfg.spec().rated_flux_wb),
        omega_e_rad_s: w,
        amplitude_a: f64::from(n.amplitude_a),
        slip_rad_s: slip / k,
    })
}

/// One line on the no-load test's result.
pub fn describe_no_load(n: &NoLoad) -> String {
    format!(
        "no-load test: stator flux {:.4} Wb ({:.1} % of rated {:.4} Wb) at {:.2} Hz with {:.4} A, slip {:.3} rad/s; \
         L_M {:.5} H [{:.5}, {:.5}] (DC levels: {:.5} H)",
        n.flux_wb,
        100.0 * n.flux_wb / n.rated_flux_wb,
        n.rated_flux_wb,
        n.omega_e_rad_s / (2.0 * std::f64::consts::PI),
        n.amplitude_a,
        n.slip_rad_s,
        n.l_mm_h.value,
        n.l_mm_h.interval[0],
        n.l_mm_h.interval[1],
        n.standstill_l_mm_h.value,
    )
}

/// The no-load test must reach this fraction of the rated flux, or the estimate is refused
/// (its L_m would not be the rated flux's; a wrong nameplate, or a test current too small).
pub const NO_LOAD_FLUX_MIN: f64 = 0.95;

/// Rated stator flux linkage (peak, per phase), Wb, from the nameplate's rated line voltage
/// (RMS) and frequency: `√2·V_LL/(√3·2π·f)` (the stator resistance's drop neglected).
pub fn rated_flux_wb(rated_voltage_v: f64, rated_frequency_hz: f64) -> f64 {
    std::f64::consts::SQRT_2 * rated_voltage_v
        / (3f64.sqrt() * 2.0 * std::f64::consts::PI * rated_frequency_hz)
}

/// The pictures of a run: `decays.svg` — each DC level's recorded voltage above its settled
/// value, over its fitted amplitude, against time over its fitted T_r: all three on
/// `e^{−t/T_r}` when the model holds; and, with the rotating field, `rotation.svg` — the
/// encoder's speed against the field's mechanical speed. (name, SVG) pairs.
pub fn plots(
    cfg: &CommissionConfig,
    rec: &Record,
    id: &Identified,
    pole_pairs: u8,
) -> Vec<(&'static str, String)> {
    use report::plot::{Series, line_plot};
    let ts = f64::from(cfg.ts_s());
    let ends = cfg.block_end();
    let mut series = Vec::new();
    let labels = ["0 → I/2", "I/2 → I", "I → I/2"];
    for ((level, fit), label) in rec.levels.iter().zip(&id.decays).zip(labels) {
        let pts = (0..BLOCKS)
            .filter_map(|b| {
                let start = if b == 0 { 0.0 } else { f64::from(ends[b - 1]) };
                let mid = 0.5 * (start + f64::from(ends[b])) * ts;
                let x = mid / fit.tau_s;
                let y = (f64::from(level.v_alpha_v[b]) - fit.c_v) / fit.a_v;
                (x <= 5.0 && start >= skip_periods()).then_some((x, y))
            })
            .collect();
        series.push(Series::dots(label, pts));
    }
    let model = (0..=200).map(|k| k as f64 * 5.0 / 200.0).map(|x| (x, (-x).exp())).collect();
    series.push(Series::line("e^(−t/T_r)", model));
    let mut out = vec![(
        "decays.svg",
        line_plot("DC levels: (v − v_settled)/A against t/T_r", "t / T_r (each step's fitted T_r)", &series),
    )];
    if let Some(rot) = &id.rotation {
        let r = &rec.rotation;
        let dt = f64::from(r.periods_per_block) * ts;
        let mut prev = 0.0;
        let speed: Vec<(f64, f64)> = r
            .theta_m_rad
            .iter()
            .enumerate()
            .map(|(b, th)| {
                let w = (f64::from(*th) - prev) / dt;
                prev = f64::from(*th);
                ((b as f64 + 0.5) * dt, w)
            })
            .collect();
        let ramp = f64::from(controller_core::commission::ROTATION_RAMP_S);
        let w_max = 2.0 * std::f64::consts::PI * f64::from(controller_core::commission::ROTATION_HZ)
            / f64::from(pole_pairs);
        let t_end = speed.last().map_or(0.0, |p| p.0 + 0.5 * dt);
        let field = vec![(0.0, 0.0), (ramp, w_max), (t_end, w_max)];
        let title = format!(
            "Rotating field: J = {:.4} kg·m², B = {:.4} N·m·s/rad, rotor/field {:.4}",
            rot.j_kgm2.value, rot.b_nms.value, rot.ratio
        );
        out.push((
            "rotation.svg",
            line_plot(
                &title,
                "t, s (from the field's start)",
                &[Series::line("field / p, rad/s", field), Series::dots("encoder, rad/s", speed)],
            ),
        ));
    }
    out
}

/// The true values the identification should find for `m`: (L_σ, L_M, R_R, T_r).
pub fn inverse_gamma(m: &MotorParams) -> (f64, f64, f64, f64) {
    let k = m.lm_h() / m.lr_h();
    let l_sigma = m.ls_h() - m.lm_h() * k;
    let l_mm = m.lm_h() * k;
    let r_rr = m.rr_ohm() * k * k;
    (l_sigma, l_mm, r_rr, m.lr_h() / m.rr_ohm())
}

/// A simulated commissioning: the motor, the board and what the user states.
#[derive(Clone, Debug, PartialEq)]
pub struct Setup {
    /// The motor the simulator runs (unknown to the sequence).
    pub motor: MotorParams,
    /// The sequence's configuration.
    pub config: CommissionConfig,
    /// Bus voltage, V.
    pub vdc_v: f64,
    /// Sensors.
    pub sensors: SensorModel,
    /// Inverter.
    pub inverter: InverterModel,
    /// Things done to the hardware at t = 0 (a swapped pair of current channels…).
    pub injections: Vec<sim::Injection>,
    /// Things that happen during the run: (time s, what).
    pub later: Vec<(f64, sim::Injection)>,
}

impl Setup {
    /// The acceptance's setup: a switching inverter with 1 µs of dead time, and the realistic
    /// front end of `SensorModel::realistic` with its current range (and so its LSB, noise
    /// and offset) widened to 8× the test current when that exceeds its ±16.5 A.
    pub fn realistic(motor: MotorParams, config: CommissionConfig, vdc_v: f64, seed: u64) -> Self {
        let mut sensors = SensorModel::realistic(seed);
        let range_a = 3.3 / 2.0 / 0.1;
        let scale = (8.0 * f64::from(config.spec().test_current_a) / range_a).max(1.0);
        sensors.current_lsb_a *= scale;
        sensors.current_noise_rms_a *= scale;
        sensors.current_offset_a = sensors.current_offset_a.map(|o| o * scale);
        Self {
            motor,
            config,
            vdc_v,
            sensors,
            inverter: InverterModel::Switching { dead_time_s: 1e-6 },
            injections: Vec::new(),
            later: Vec::new(),
        }
    }
}

/// Where the sequence runs.
#[derive(Clone, Debug, PartialEq)]
pub enum Target {
    /// In this process (software in the loop).
    InProcess,
    /// On the emulated Cortex-M4F (processor in the loop).
    Pil(PilOptions),
}

/// A sequence the simulator drives: in process, or on the emulated MCU.
enum Runner {
    InProcess(Box<Commissioning>),
    Pil { pil: Box<Pil>, stage: Stage, failure: Option<String> },
}

/// [`Runner`] as the simulator's controller; the stage is shared with the progress display.
struct Sequence {
    runner: Runner,
    stage: Rc<Cell<Stage>>,
    /// The signals of the last step (its voltage and current reference).
    telemetry: Telemetry,
}

impl Sequence {
    /// The finished sequence's record (from the target, in chunks, over PIL).
    fn record(&mut self) -> Result<Option<Record>, String> {
        match &mut self.runner {
            Runner::InProcess(c) => Ok(c.record().copied()),
            Runner::Pil { pil, stage, .. } => {
                if *stage != Stage::Done {
                    return Ok(None);
                }
                fetch_record(|c| pil.transact(c)).map(Some)
            }
        }
    }
}

impl DriveUnderTest for Sequence {
    fn slow_divider(&self) -> u16 {
        10
    }
    fn enable(&mut self) -> Result<(), String> {
        Ok(())
    }
    fn set_reference(&mut self, _: Reference) -> Result<(), String> {
        Err("a commissioning sequence takes no reference".into())
    }
    fn controlled_stop(&mut self) -> Result<(), String> {
        match &mut self.runner {
            Runner::InProcess(c) => c.abort(),
            Runner::Pil { pil, .. } => {
                pil.transact(&Command::Stop)?;
            }
        }
        Ok(())
    }
    fn step(&mut self, m: &Measurements) -> FastOutput {
        let out = match &mut self.runner {
            Runner::InProcess(c) => c.step(m),
            Runner::Pil { pil, stage, failure } => match pil.transact(&Command::Step(*m)) {
                Ok(Reply::Commission(o)) => {
                    *stage = o.stage;
                    o
                }
                other => {
                    *failure = Some(match other {
                        Ok(r) => format!("unexpected reply {r:?} to a step"),
                        Err(e) => e,
                    });
                    CommissionOutput {
                        phases: PhaseCommand::Off,
                        stage: *stage,
                        v_ab_v: AlphaBeta::default(),
                        i_ref_alpha_a: 0.0,
                    }
                }
            },
        };
        let CommissionOutput { phases, stage, v_ab_v, i_ref_alpha_a } = out;
        self.stage.set(stage);
        self.telemetry = Telemetry {
            v_ab_v,
            i_ref_ab_a: AlphaBeta { alpha: i_ref_alpha_a, beta: 0.0 },
            ..Telemetry::default()
        };
        FastOutput { phases, mode: if stage.is_over() { Mode::Idle } else { Mode::Running }, brake: false }
    }
    fn telemetry(&self) -> Telemetry {
        self.telemetry
    }
    fn take_failure(&mut self) -> Option<String> {
        match &mut self.runner {
            Runner::InProcess(_) => None,
            Runner::Pil { failure, .. } => failure.take(),
        }
    }
    fn finished(&self) -> bool {
        self.stage.get().is_over()
    }
}

/// Why a simulated commissioning did not give a record.
#[derive(Clone, Debug, PartialEq)]
pub enum RunError {
    /// The sequence refused (the bridge went off).
    Refused(Refusal),
    /// The simulation failed.
    Simulation(String),
    /// The link to the board failed, or the board refused to start.
    Link(String),
    /// Stopped by the caller.
    Interrupted,
}

impl std::fmt::Display for RunError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            RunError::Refused(r) => write!(f, "commissioning refused: {}", describe(r)),
            RunError::Simulation(e) => write!(f, "simulation: {e}"),
            RunError::Link(e) => write!(f, "link: {e}"),
            RunError::Interrupted => write!(f, "interrupted"),
        }
    }
}

/// A refusal in words.
pub fn describe(r: &Refusal) -> String {
    match r {
        Refusal::BusOutOfRange(v) => format!("the bus reads {v} V, outside the accepted range"),
        Refusal::BusUnsteady(v) => format!("the bus varied by {v} V with the bridge off"),
        Refusal::OffsetTooLarge { channel, offset_a } => {
            // The limit and the way out (it read as a sensor fault at a small test current:
            // found by trying).
            let share = controller_core::commission::OFFSET_SHARE_MAX;
            format!(
                "current channel {} reads {offset_a} A with the bridge off, more than {:.0} % of the test current: \
                 an offset the calibration cannot trust — or a test current too small for this board's sensors \
                 (take a test current above {:.3} A, {:.0}× that reading)",
                phase_name(*channel),
                100.0 * share,
                offset_a.abs() / share,
                1.0 / share
            )
        }
        Refusal::NoCurrent => {
            "the current rose by less than a quarter of the test current after the largest voltage pulse \
             (an open lead, no motor, dead sensors — or a test current too large for this bus)"
                .into()
        }
        Refusal::PhaseOrder => {
            "phase order: phase b's pulse answered along c and c's along b (current channels swapped)".into()
        }
        Refusal::CurrentSign => {
            "every current answered against its pulse (current sensors' sign inverted)".into()
        }
        Refusal::CurrentDirection { phase } => {
            format!("the current answered phase {}'s pulse in another direction", phase_name(*phase))
        }
        Refusal::NoDecay => "the current did not decay after a pulse".into(),
        Refusal::Overcurrent(i) => format!("a phase current of {i} A exceeded the limit"),
        Refusal::VoltageLimit => "the test current needs more voltage than the bus gives (lower it)".into(),
        Refusal::NonFinite => "a measurement was not finite".into(),
        Refusal::Aborted => "aborted".into(),
        Refusal::RotorStalled(hz) => format!(
            "in the no-load test the rotor did not follow the field (the field reached {hz:.2} Hz): is a load \
             coupled or a brake on — or is the rated voltage given far below the motor's (a field too weak to turn it)?"
        ),
    }
}

fn phase_name(p: u8) -> char {
    match p {
        0 => 'a',
        1 => 'b',
        _ => 'c',
    }
}

/// A stage in words, for progress displays.
pub fn stage_name(s: Stage) -> String {
    match s {
        Stage::Offsets => "offsets and bus (bridge off)".into(),
        Stage::Pulse(p) => format!("voltage pulse along phase {}", phase_name(p)),
        Stage::Level(l) => format!(
            "DC level {} of 3 ({} × the test current)",
            l + 1,
            LEVELS.get(usize::from(l)).copied().unwrap_or(0.0)
        ),
        Stage::Injection(j) => format!("sinusoidal injection {} of 2", j + 1),
        Stage::Rotate => "slow rotating field (encoder, inertia)".into(),
        Stage::NoLoad => "no-load test at rated flux (magnetizing inductance)".into(),
        Stage::Done => "done".into(),
        Stage::Refused(_) => "refused".into(),
    }
}

/// The finished sequence's record from a target, part by part.
fn fetch_record(mut transact: impl FnMut(&Command) -> Result<Reply, String>) -> Result<Record, String> {
    let mut bytes = Vec::with_capacity(usize::from(RECORD_CHUNKS) * RECORD_CHUNK_BYTES);
    for chunk in 0..RECORD_CHUNKS {
        match transact(&Command::GetCommissionRecord { chunk })? {
            Reply::CommissionRecord { chunk: got, bytes: b } if got == chunk => bytes.extend(b),
            other => return Err(format!("unexpected reply {other:?} to record part {chunk}")),
        }
    }
    bytes.truncate(RECORD_BYTES);
    Record::read_bytes(&bytes).ok_or_else(|| "the target's record did not decode".into())
}

/// Runs the sequence on a board over its link (firmware built with the `commissioning`
/// feature): starts it, polls its stage every `poll` (each poll also keeps the board's link
/// watchdog from aborting it), and fetches the record. `progress` sees every stage polled;
/// `interrupted()` sends `Stop` (the board aborts: bridge off) and returns.
pub fn over_link<R: std::io::Read, W: std::io::Write>(
    link: &mut crate::link_client::LinkClient<R, W>,
    spec: controller_core::commission::CommissionSpec,
    poll: std::time::Duration,
    mut progress: impl FnMut(Stage),
    interrupted: impl Fn() -> bool,
) -> Result<Record, RunError> {
    let broken = RunError::Link;
    match link.transact(&Command::Commission(spec)).map_err(broken)? {
        Reply::Ack => {}
        Reply::Nack(r) => {
            return Err(RunError::Link(format!(
                "the board did not start the sequence: {r:?} (NotConfigured: offsets not calibrated; \
                 Unsupported: firmware built without the `commissioning` feature)"
            )));
        }
        other => return Err(RunError::Link(format!("unexpected reply {other:?} to Commission"))),
    }
    loop {
        if interrupted() {
            let _ = link.transact(&Command::Stop);
            return Err(RunError::Interrupted);
        }
        match link.transact(&Command::GetCommissionStage).map_err(broken)? {
            Reply::Commission(o) => {
                progress(o.stage);
                match o.stage {
                    Stage::Done => break,
                    Stage::Refused(r) => return Err(RunError::Refused(r)),
                    _ => {}
                }
            }
            // Started, not stepped yet.
            Reply::Nack(controller_core::link::NackReason::NoRecord) => {}
            other => return Err(RunError::Link(format!("unexpected reply {other:?} to GetCommissionStage"))),
        }
        std::thread::sleep(poll);
    }
    fetch_record(|c| link.transact(c)).map_err(RunError::Link)
}

/// Runs the sequence in SIL: the record, and the motor time it took (s).
/// `progress(stage, t_s)` is called every 2 000 periods; `interrupted()` stops the run.
pub fn simulate(
    setup: &Setup,
    progress: impl FnMut(Stage, f64),
    interrupted: impl Fn() -> bool,
) -> Result<(Record, f64), RunError> {
    simulate_on(setup, &Target::InProcess, progress, interrupted)
}

/// [`simulate`] with the sequence on `target`: in process or on the emulated MCU, against
/// the same simulated motor — equal records, bit for bit (`tests/pil.rs`).
pub fn simulate_on(
    setup: &Setup,
    target: &Target,
    mut progress: impl FnMut(Stage, f64),
    interrupted: impl Fn() -> bool,
) -> Result<(Record, f64), RunError> {
    let cfg = setup.config;
    let ts = f64::from(cfg.ts_s());
    let stage = Rc::new(Cell::new(Stage::Offsets));
    let runner = match target {
        Target::InProcess => Runner::InProcess(Box::new(Commissioning::new(cfg))),
        Target::Pil(opts) => {
            let mut pil = Pil::launch(opts).map_err(RunError::Simulation)?;
            match pil.transact(&Command::Commission(*cfg.spec())).map_err(RunError::Simulation)? {
                Reply::Ack => {}
                other => {
                    return Err(RunError::Simulation(format!(
                        "the target refused the sequence's spec: {other:?}"
                    )));
                }
            }
            Runner::Pil { pil: Box::new(pil), stage: Stage::Offsets, failure: None }
        }
    };
    let mut seq = Sequence { runner, stage: Rc::clone(&stage), telemetry: Telemetry::default() };
    let scenario = Scenario {
        events: setup
            .injections
            .iter()
            .map(|&i| (0.0, i))
            .chain(setup.later.iter().copied())
            .map(|(t, i)| (t, Event::Fault(i)))
            .collect(),
        duration_s: cfg.max_periods() as f64 * ts,
        vdc_v: setup.vdc_v,
        substeps: 4,
        trace_every: 2000,
        sensors: setup.sensors,
        load: LoadModel::Torque,
        inverter: setup.inverter,
        dc_link: None,
        comparator: None,
    };
    let machine = Machine::new(&setup.motor);
    let mut last_t = 0.0;
    let result = sim::run(
        &mut seq,
        &machine,
        1.0 / ts,
        &scenario,
        |f| progress(stage.get(), f * scenario.duration_s),
        |row| {
            last_t = row.t_s;
            if interrupted() { Err("interrupted".into()) } else { Ok(()) }
        },
    );
    match result {
        Err(_) if interrupted() => return Err(RunError::Interrupted),
        Err(e) => return Err(RunError::Simulation(e)),
        Ok(_) => {}
    }
    match stage.get() {
        Stage::Refused(r) => Err(RunError::Refused(r)),
        _ => match seq.record().map_err(RunError::Simulation)? {
            Some(r) => Ok((r, last_t)),
            None => Err(RunError::Simulation("the sequence did not finish in the time allowed".into())),
        },
    }
}

/// The motor file: `[motor]` at the nominal values under `ratio`, with `pole_pairs` as given,
/// J and B identified by the rotating field if it ran (else `j_kgm2`, `b_nms` as given), and
/// `[identification]` with the intervals and the inverter's error.
pub fn motor_file(
    id: &Identified,
    ratio: f64,
    pole_pairs: u8,
    j_kgm2: f64,
    b_nms: f64,
    about: &str,
) -> String {
    let t = id.t_model(ratio);
    let (j_kgm2, b_nms, mechanics) = match &id.rotation {
        Some(r) => (r.j_kgm2.value, r.b_nms.value, "j_kgm2 and b_nms by the slow rotating field"),
        None => (j_kgm2, b_nms, "j_kgm2 and b_nms are as given (the motor was not allowed to turn)"),
    };
    let n = drive_file::source::num;
    let iv = |e: &Estimate| format!("[{}, {}]", n(e.interval[0]), n(e.interval[1]));
    let magnetizing = match &id.no_load {
        Some(nl) => format!(
            "L_M (so L_m, L_s, L_r) by the no-load test at {:.4} Wb stator flux ({:.1} % of the rated\n\
             # {:.4} Wb), {:.2} Hz, {:.4} A; the DC levels gave L_M = {:.5} H",
            nl.flux_wb,
            100.0 * nl.flux_wb / nl.rated_flux_wb,
            nl.rated_flux_wb,
            nl.omega_e_rad_s / (2.0 * std::f64::consts::PI),
            nl.amplitude_a,
            nl.standstill_l_mm_h.value
        ),
        None => "L_M (so L_m, L_s, L_r) by the DC levels (the motor was not allowed to turn)".into(),
    };
    let mut s = String::new();
    for line in about.lines() {
        s.push_str(&format!("# {line}\n"));
    }
    s.push_str(&format!(
        "# Identified by controller-core's commissioning sequence (hil_sim::identify).\n\
         # The leakage split L_lr/L_ls = {} is assumed (the terminals cannot tell it; control does not\n\
         # depend on it). pole_pairs is as given; {mechanics}.\n\
         # {magnetizing}.\n\
         [motor]\n\
         rs_ohm = {}\nrr_ohm = {}\nls_h = {}\nlr_h = {}\nlm_h = {}\npole_pairs = {pole_pairs}\nj_kgm2 = {}\nb_nms = {}\n\n",
        n(ratio),
        n(t.rs_ohm),
        n(t.rr_ohm),
        n(t.ls_h),
        n(t.lr_h),
        n(t.lm_h),
        n(j_kgm2),
        n(b_nms),
    ));
    s.push_str(
        "# Intervals: the repeats' span widened by the stated margins (hil_sim::identify::MARGIN).\n\
         [identification]\n",
    );
    s.push_str(&format!("leakage_ratio = {}\n", n(ratio)));
    for (key, e) in id.t_intervals(ratio) {
        s.push_str(&format!("{key} = {}\n", iv(&e)));
    }
    s.push_str(&format!(
        "sigma_ls_h = {}\ntr_s = {}\nl_mm_h = {}\nr_rr_ohm = {}\n",
        iv(&id.l_sigma_h),
        iv(&id.tr_s),
        iv(&id.l_mm_h),
        iv(&id.r_rr_ohm)
    ));
    if let Some(r) = &id.rotation {
        s.push_str(&format!(
            "j_kgm2 = {}\nb_nms = {}\n# The rotor turned {}× the field's mechanical speed (1 − slip) at {} rad/s.\n",
            iv(&r.j_kgm2),
            iv(&r.b_nms),
            n(r.ratio),
            n(r.omega_hold_rad_s)
        ));
    }
    s.push_str(&format!(
        "# Inverter voltage error per phase (dead time and switch drops) at {} V, and its share of the bus:\n\
         inverter_error_v = {}\ndead_time_duty = {}\ncurrent_offsets_a = [{}, {}, {}]\n",
        n(id.vdc_v),
        n(id.inverter_error_v.value),
        n(id.inverter_error_v.value / id.vdc_v),
        n(id.offsets_a[0]),
        n(id.offsets_a[1]),
        n(id.offsets_a[2]),
    ));
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Any record — every word random bits, as a broken link or board could deliver — is
    /// estimated or refused, never a panic.
    #[test]
    fn random_records_never_panic() {
        use controller_core::commission::{CommissionSpec, RECORD_BYTES};
        let mut x = 0x9e37_79b9_7f4a_7c15u64;
        for rotate in [false, true] {
            let spec = CommissionSpec {
                pwm_hz: 20_000.0,
                test_current_a: 1.0,
                current_limit_a: 2.0,
                vdc_min_v: 250.0,
                vdc_max_v: 370.0,
                level_time_s: 1.0,
                rotate,
                rated_flux_wb: 0.823,
                no_load_hz: 15.0,
            };
            let cfg = CommissionConfig::new(spec).unwrap();
            for _ in 0..100 {
                let bytes: Vec<u8> = (0..RECORD_BYTES)
                    .map(|_| {
                        x ^= x << 13;
                        x ^= x >> 7;
                        x ^= x << 17;
                        x as u8
                    })
                    .collect();
                let rec = Record::read_bytes(&bytes).unwrap();
                let _ = estimate(&cfg, &rec, 1);
            }
        }
    }

    /// A record that did not come from this sequence (a board's, corrupted) is refused, not
    /// a panic: the rotating field's blocks empty or of another length.
    #[test]
    fn a_foreign_rotation_record_is_refused() {
        use controller_core::commission::CommissionSpec;
        let spec = CommissionSpec {
            pwm_hz: 20_000.0,
            test_current_a: 1.0,
            current_limit_a: 2.0,
            vdc_min_v: 250.0,
            vdc_max_v: 370.0,
            level_time_s: 1.0,
            rotate: true,
            rated_flux_wb: 0.823,
            no_load_hz: 15.0,
        };
        let cfg = CommissionConfig::new(spec).unwrap();
        let mut rec = Record::default();
        for periods in [0, 1, 999, 1001, u32::MAX] {
            rec.rotation.periods_per_block = periods;
            let e = rotation(&cfg, &rec, 1, 1.34, 20.8).unwrap_err();
            assert!(e.contains("empty or not this sequence's"), "{periods}: {e}");
        }
        rec.rotation.periods_per_block = 1000;
        assert!(rotation(&cfg, &rec, 1, 1.34, 20.8).is_err(), "a rotor that never turned");
    }

    /// The T-models of one set of terminals under different splits have the same standstill
    /// impedance at every frequency.
    #[test]
    fn split_leaves_the_terminals_unchanged() {
        let z = |t: &TModel, w: f64| {
            // R_s + jωL_ls + (jωL_m ∥ (R_r + jωL_lr)).
            let (lls, llr) = (t.ls_h - t.lm_h, t.lr_h - t.lm_h);
            let (ar, ai) = (0.0, w * t.lm_h);
            let (br, bi) = (t.rr_ohm, w * llr);
            let (nr, ni) = (ar * br - ai * bi, ar * bi + ai * br);
            let (dr, di) = (ar + br, ai + bi);
            let d = dr * dr + di * di;
            (t.rs_ohm + (nr * dr + ni * di) / d, w * lls + (ni * dr - nr * di) / d)
        };
        let m = MotorParams::new(16.2, 23.2, 1.44, 1.5, 1.42, 1, 0.005, 0.0005).unwrap();
        let (ls, lmm, rrr, _) = inverse_gamma(&m);
        let truth = TModel { rs_ohm: 16.2, rr_ohm: 23.2, ls_h: 1.44, lr_h: 1.5, lm_h: 1.42 };
        for ratio in [0.2, 1.0, 1.5, 4.0] {
            let t = t_model(16.2, ls, lmm, rrr, ratio);
            assert!(((t.lr_h - t.lm_h) / (t.ls_h - t.lm_h) - ratio).abs() < 1e-9);
            for w in [1.0, 30.0, 1e3] {
                let (a, b) = (z(&t, w), z(&truth, w));
                assert!((a.0 - b.0).abs() < 1e-9 * b.0.abs() + 1e-9 && (a.1 - b.1).abs() < 1e-9 * b.1.abs());
            }
        }
        // The motor's own split gives the motor back.
        let own = t_model(16.2, ls, lmm, rrr, (1.5 - 1.42) / (1.44 - 1.42));
        assert!((own.lm_h - 1.42).abs() < 1e-9 && (own.rr_ohm - 23.2).abs() < 1e-9, "{own:?}");
    }
}
