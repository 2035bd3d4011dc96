//! The estimates from a finished sequence's [`Record`] (the equations: the `identify`
//! module's docs, "Estimation"), and the thresholds that refuse a record: the DC levels'
//! decays, the injections' impedance, the rotating field's mechanics and the no-load test.

use super::{CurvePoint, DecayFit, Estimate, Identified, MARGIN, NoLoad, Rotation};
use controller_core::commission::{
    BLOCKS, CURVE_FLUX_FRACTIONS, CURVE_WINDOWS, CommissionConfig, NoLoadWindow, Record,
};

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
pub(super) fn rotation(
    cfg: &CommissionConfig,
    rec: &Record,
    pole_pairs: u8,
    branch: Branch<'_>,
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
    // The branch's chord at the field's current: its rotor time constant there.
    let (l_mm, tr) = branch.at_current(amp, r_rr);
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
    let psi0 = branch.flux_wb(amp + step_a * (-since_s / tr).exp());
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
        // dψ/dt = R_R·(i − i_M(ψ)) + j·p·ω·ψ, i_M(ψ) = ψ/L(|ψ|) the branch's current.
        // dψ/dt = R_R·(i − i_M) + j·p·ω·ψ, i_M = ψ/L_M (linear) or the Γ branch's current.
        let f = |psi: [f64; 2]| {
            let d = match branch {
                Branch::Linear(_) => [psi[0] / tr, psi[1] / tr],
                Branch::Gamma { .. } => {
                    let (_, i_m) = branch.gamma_stator(psi, i);
                    [r_rr * i_m[0], r_rr * i_m[1]]
                }
            };
            [r_rr * i[0] - d[0] - wr * psi[1], r_rr * i[1] - d[1] + wr * psi[0]]
        };
        let k1 = f(psi);
        let k2 = f([psi[0] + 0.5 * ts * k1[0], psi[1] + 0.5 * ts * k1[1]]);
        // τ = 1.5·p·ψ_s × i (the rotor flux's in the inverse-Γ form: the leakage's is along i).
        let flux = match branch {
            Branch::Linear(_) => psi,
            Branch::Gamma { .. } => branch.gamma_stator(psi, i).0,
        };
        torque_int += 1.5 * p * (flux[0] * i[1] - flux[1] * i[0]) * ts;
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

/// The Γ model's rotor (`curve` module), to take its current out of a no-load window's.
#[derive(Clone, Copy, Debug)]
pub(super) struct GammaRotor {
    /// R_R, Ω.
    pub(super) r_r_ohm: f64,
    /// L_σ, H.
    pub(super) l_sigma_h: f64,
}

/// The rotor's magnetizing, for the rotating field's torque: the inverse-Γ branch with one
/// L_M, or the Γ model on the measured curve (`curve`: the stator flux against the branch's
/// current; `l_sigma_h` the rotor-side leakage).
#[derive(Clone, Copy, Debug)]
pub(super) enum Branch<'a> {
    /// L_M, H.
    Linear(f64),
    /// The Γ model on its curve.
    Gamma { curve: &'a controller_core::magnetics::MagnetizingCurve, l_sigma_h: f64 },
}

impl Branch<'_> {
    /// The settled flux at current `i_a` ≥ 0, Wb (the rotor's; in the Γ form, with no rotor
    /// current, the stator's).
    pub(super) fn flux_wb(&self, i_a: f64) -> f64 {
        match self {
            Branch::Linear(l) => l * i_a,
            Branch::Gamma { curve, .. } => curve.flux_at_total_current(i_a, 0.0),
        }
    }

    /// (L_M, T_r) at current `i_a` > 0 and rotor resistance `r_ohm` (the form's): the
    /// magnetizing inductance of the inverse-Γ equivalent and the rotor time constant — in
    /// the Γ form `γ·L_s` and `(L_s + L_σ)/R_R` with L_s the chord there, `γ = L_s/(L_s + L_σ)`.
    pub(super) fn at_current(&self, i_a: f64, r_ohm: f64) -> (f64, f64) {
        match self {
            Branch::Linear(l) => (*l, l / r_ohm),
            Branch::Gamma { l_sigma_h, .. } => {
                let l_s = self.flux_wb(i_a) / i_a;
                (l_s * l_s / (l_s + l_sigma_h), (l_s + l_sigma_h) / r_ohm)
            }
        }
    }

    /// The Γ model's stator flux and branch current (vectors) for rotor flux `psi_r` and
    /// stator current `i`: `ψ_s + L_σ·i_m(ψ_s) = ψ_r + L_σ·i`, the branch's current radial
    /// in its flux ([`MagnetizingCurve::flux_at_total_current`]). Zeros for the linear branch.
    ///
    /// [`MagnetizingCurve::flux_at_total_current`]: controller_core::magnetics::MagnetizingCurve::flux_at_total_current
    pub(super) fn gamma_stator(&self, psi_r: [f64; 2], i: [f64; 2]) -> ([f64; 2], [f64; 2]) {
        let Branch::Gamma { curve, l_sigma_h: l } = self else { return ([0.0; 2], [0.0; 2]) };
        let a = [psi_r[0] / l + i[0], psi_r[1] / l + i[1]];
        let a_norm = a[0].hypot(a[1]);
        if a_norm <= 0.0 {
            return ([0.0; 2], [0.0; 2]);
        }
        let m = curve.flux_at_total_current(a_norm, 1.0 / l);
        let u = [a[0] / a_norm, a[1] / a_norm];
        let i_m = curve.current_a(m);
        ([m * u[0], m * u[1]], [i_m * u[0], i_m * u[1]])
    }
}

/// The minimiser of `f` over `[lo, hi]` (> 0): `grid` + 1 points evenly spaced in ln x, then
/// `iterations` of golden-section search on ln x between the best point's neighbours (the
/// decay fits' one-parameter searches: T_r here, R_R on the curve).
pub(super) fn minimize_on_log_scale(
    f: impl Fn(f64) -> f64,
    [lo, hi]: [f64; 2],
    grid: usize,
    iterations: u32,
) -> f64 {
    let (lo, hi) = (lo.ln(), hi.ln());
    let x_at = |j: usize| lo + (hi - lo) * j as f64 / grid as f64;
    let best = (0..=grid)
        .map(|j| (j, f(x_at(j).exp())))
        .fold((0, f64::INFINITY), |acc, (j, s)| if s < acc.1 { (j, s) } else { acc })
        .0;
    let (mut a, mut b) = (x_at(best.saturating_sub(1)), x_at((best + 1).min(grid)));
    let g = 0.5 * (5f64.sqrt() - 1.0);
    for _ in 0..iterations {
        let (x1, x2) = (b - g * (b - a), a + g * (b - a));
        if f(x1.exp()) < f(x2.exp()) {
            b = x2;
        } else {
            a = x1;
        }
    }
    (0.5 * (a + b)).exp()
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
pub(super) fn skip_periods() -> f64 {
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
    // From 2 periods to 10 levels.
    let level_s = f64::from(cfg.level_periods()) * ts;
    let tau = minimize_on_log_scale(|tau| ssr_at(tau).0, [2.0 * ts, 10.0 * level_s], 200, 80);
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
    let mut l_sigma: Vec<f64> = Vec::new();
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
        l_sigma.push(l_sigma_of(*slot, lmm_est.value, rr_est.value));
    }
    if l_sigma.iter().any(|x| !(x.is_finite() && *x > 0.0)) {
        return Err(format!("the injections give no positive transient inductance ({l_sigma:?} H)"));
    }
    let offsets_a = rec.offsets_a.map(f64::from);
    let l_sigma_est = Estimate::of(&l_sigma, MARGIN.l_sigma);
    let e_est = Estimate::of(&e, 0.0);
    let (rotation, no_load) = if cfg.spec().rotate {
        let rot = rotation(cfg, rec, pole_pairs, Branch::Linear(lmm_est.value), rr_est.value)?;
        let terminals = Terminals { rs: rs_est.value, l_sigma: l_sigma_est.value };
        (Some(rot), Some(no_load(cfg, rec, pole_pairs, terminals, lmm_est, None)?))
    } else {
        (None, None)
    };
    let id = Identified {
        rs_ohm: rs_est,
        l_sigma_h: l_sigma_est,
        tr_s: tr_est,
        r_rr_ohm: rr_est,
        l_mm_h: no_load.as_ref().map_or(lmm_est, |n| n.l_mm_h),
        inverter_error_v: e_est,
        offsets_a,
        vdc_v: f64::from(rec.vdc_v),
        decays,
        impedance,
        rotation,
        no_load,
        gamma: None,
    };
    if cfg.curve() { super::curve::refine(cfg, rec, pole_pairs, id) } else { Ok(id) }
}

/// L_σ from an injection's impedance `(ω, Re Z, Im Z)` less the rotor branch
/// `jωL·R_R/(jωL + R_R)` (imaginary part `ω·L·R_R²/(R_R² + ω²L²)`), L the branch's
/// inductance to a small signal.
pub(super) fn l_sigma_of((w, _, zi): (f64, f64, f64), l_h: f64, r_rr: f64) -> f64 {
    let zb_im = w * l_h * r_rr * r_rr / (r_rr * r_rr + w * w * l_h * l_h);
    (zi - zb_im) / w
}

/// The standstill estimates the no-load test's impedance is corrected with.
#[derive(Clone, Copy, Debug)]
pub(super) struct Terminals {
    /// R_s, Ω.
    pub(super) rs: f64,
    /// L_σ, H.
    pub(super) l_sigma: f64,
}

/// Why the sequence skipped its no-load test (`Commissioning::start_no_load` refuses to set
/// it up): the rotor did not follow the slow field over its hold's second half (its turning,
/// mechanical, below 1/`NO_LOAD_KE_MAX` of the field's, electrical — the sequence's own
/// test), or else the DC levels gave no inductance and rotor time constant to set it up
/// from — a step deep in saturation builds almost no flux (the 300 W twin at 5 A, ten times
/// its magnetizing current, was told its rotor had not followed; test
/// `a_test_current_deep_in_saturation_is_named`).
fn why_no_load_did_not_start(cfg: &CommissionConfig, rec: &Record) -> String {
    use controller_core::commission::{
        ROTATION_BLOCKS, ROTATION_HOLD_S, ROTATION_HZ, no_load::NO_LOAD_KE_MAX,
    };
    let r = &rec.rotation;
    let hold_blocks = (ROTATION_HOLD_S * cfg.spec().pwm_hz) as u32 / r.periods_per_block.max(1);
    let half = (hold_blocks / 2) as usize;
    let turned = match (r.theta_m_rad.last(), r.theta_m_rad.get(ROTATION_BLOCKS.saturating_sub(half + 1))) {
        (Some(end), Some(from)) => f64::from(end - from),
        _ => 0.0,
    };
    let field =
        2.0 * std::f64::consts::PI * f64::from(ROTATION_HZ) * f64::from(half as u32 * r.periods_per_block)
            / f64::from(cfg.spec().pwm_hz);
    let followed = turned.abs() * f64::from(NO_LOAD_KE_MAX) >= field;
    if !followed {
        return "the no-load test did not run (the rotor did not follow the slow field)".into();
    }
    let [i0, i1] = [0, 1].map(|k| rec.levels.get(k).map_or(f32::NAN, |l| l.i_ref_a));
    format!(
        "the no-load test did not run: the rotor followed the slow field, but the DC levels' step from \
         {i0:.3} A to {i1:.3} A gave no stator inductance and rotor time constant to set the test up \
         from — a step deep in saturation builds almost no flux: run with a test current near the \
         current the motor's rated flux needs"
    )
}

/// The no-load test's estimates (`controller_core::commission::no_load`).
///
/// Per window, in the frame of the current reference: the commanded voltage acts 1.5
/// periods later and held (`V = V̂·e^{−j1.5ωT}·sinc(ωT/2)`, as for the injections); the
/// inverter's error is made up ahead of the loops by the sequence
/// (`controller_core::commission::no_load`), so the commanded voltage is the motor's.
/// Then `Z = V/I`, the rotor branch `Z_R = Z − R_s − jωL_σ` and its admittance `Y_R = 1/(jωL_M) + s/R_R` (s the slip):
/// `L_M = −1/(ω·Im Y_R)`, whatever the slip (it only adds a real part). The stator flux
/// reached is `|V − R_s·I|/ω`.
pub(super) fn no_load(
    cfg: &CommissionConfig,
    rec: &Record,
    pole_pairs: u8,
    t: Terminals,
    standstill: Estimate,
    rotor: Option<GammaRotor>,
) -> Result<NoLoad, String> {
    let n = &rec.no_load;
    let ts = f64::from(cfg.ts_s());
    let w = f64::from(n.omega_e_rad_s);
    let periods = f64::from(n.periods_per_window);
    if !(w > 0.0 && w.is_finite() && periods > 0.0) {
        return Err(why_no_load_did_not_start(cfg, rec));
    }
    let half = 0.5 * w * ts;
    let delay = num_complex::Complex64::from_polar(half.sin() / half, -3.0 * half);
    let slip_of =
        |win: &NoLoadWindow| w - f64::from(pole_pairs) * f64::from(win.theta_m_rad) / (periods * ts);
    let level_slip =
        |windows: &[NoLoadWindow]| windows.iter().map(slip_of).sum::<f64>() / windows.len().max(1) as f64;
    let rated_slip = level_slip(&n.windows);
    let branch = |win: &NoLoadWindow| branch_of(win, w, delay, t, rotor.map(|r| (r, rated_slip)));
    let mut l_mm = Vec::new();
    let (mut flux, mut slip) = (0.0, 0.0);
    let mut rated_point = Vec::new();
    let mut chord = Vec::new();
    for win in &n.windows {
        let b = branch(win)?;
        l_mm.push(b.l_mm_h);
        rated_point.push(b);
        flux += b.stator_flux_wb;
        chord.push(b.stator_flux_wb / b.branch_current_a);
        slip += slip_of(win);
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
    if flux / k > NO_LOAD_FLUX_MAX * rated {
        return Err(format!(
            "the no-load test overshot the rated flux {rated:.4} Wb: it ran at {:.1} % of it, where the magnetizing \
             inductance is not the rated flux's (its current was set from the DC levels' inductance: a motor that \
             saturates needs less current for its rated flux than they predict); nothing measured at rated flux",
            100.0 * flux / k / rated
        ));
    }
    let mut levels = vec![(Some(1.0), rated_point)];
    for (k, windows) in n.curve.chunks_exact(CURVE_WINDOWS).enumerate() {
        // A level not reached (the sequence stopped before it, or skipped it) is all zero.
        if windows.iter().all(|win| *win == NoLoadWindow::default()) {
            continue;
        }
        // The fractions' levels, then the test current's.
        let target = CURVE_FLUX_FRACTIONS.get(k).map(|f| f64::from(*f));
        let sl = level_slip(windows);
        let points = windows.iter().map(|win| branch_of(win, w, delay, t, rotor.map(|r| (r, sl))));
        levels.push((target, points.collect::<Result<_, _>>()?));
    }
    Ok(NoLoad {
        curve: curve_points(levels),
        l_s_h: Estimate::of(&chord, MARGIN.lm),
        l_mm_h: Estimate::of(&l_mm, MARGIN.lm),
        standstill_l_mm_h: standstill,
        flux_wb: flux / k,
        rated_flux_wb: f64::from(cfg.spec().rated_flux_wb),
        omega_e_rad_s: w,
        amplitude_a: f64::from(n.amplitude_a),
        slip_rad_s: slip / k,
    })
}

/// The rotor branch in one no-load window (see [`no_load`]).
#[derive(Clone, Copy, Debug)]
pub(super) struct Window {
    /// L_M, H.
    l_mm_h: f64,
    /// The stator flux ψ_s = |V − R_s·I|/ω, Wb: the Γ branch's.
    stator_flux_wb: f64,
    /// The current's component along ψ_s: the Γ branch's current, A.
    branch_current_a: f64,
}

/// [`Window`] of window `win` at field frequency `w`, the voltage's `delay`, the
/// standstill `t`erminals.
fn branch_of(
    win: &NoLoadWindow,
    w: f64,
    delay: num_complex::Complex64,
    t: Terminals,
    rotor: Option<(GammaRotor, f64)>,
) -> Result<Window, String> {
    let v = num_complex::Complex64::new(f64::from(win.v_dq_v[0]), f64::from(win.v_dq_v[1])) * delay;
    let i = num_complex::Complex64::new(f64::from(win.i_dq_a[0]), f64::from(win.i_dq_a[1]));
    if i.norm().is_nan() || i.norm() <= 0.0 {
        return Err("no current in the no-load test's record".into());
    }
    let z_r = v / i - t.rs - num_complex::Complex64::new(0.0, w * t.l_sigma);
    let l = -1.0 / (w * (1.0 / z_r).im);
    if !(l.is_finite() && l > 0.0) {
        return Err(format!("the no-load test gives no positive magnetizing inductance ({l} H)"));
    }
    // The stator flux, and the Γ branch's current: the current's component along the flux,
    // less the rotor's, `i_r = j·ψ_s·ω_sl/(R_R + j·ω_sl·L_σ)` when the Γ rotor is known (ω_sl
    // the level's mean slip: a window's swings by ±0.4 rad/s as the rotor hunts; without the
    // rotor, its current is taken at right angles to the flux: first order in the slip; its
    // part along the flux, ψ_s·ω_sl²·L_σ/R_R², left the shipped saturating motor's 0.3 level
    // 6.4 % low in flux at its current, the friction's slip growing as the flux falls).
    let j = num_complex::Complex64::i();
    let psi_s = (v - i * t.rs) / (j * w);
    let i_r = |psi: num_complex::Complex64| {
        rotor.map_or(num_complex::Complex64::new(0.0, 0.0), |(r, sl)| {
            j * psi * sl / (r.r_r_ohm + j * sl * r.l_sigma_h)
        })
    };
    let branch = |psi: num_complex::Complex64| ((i - i_r(psi)) * psi.conj()).re / psi.norm();
    Ok(Window { l_mm_h: l, stator_flux_wb: psi_s.norm(), branch_current_a: branch(psi_s) })
}

/// The curve's points (the Γ branch's: the stator flux against the current's component
/// along it) from each level's windows (`(target fraction, windows)`): by rising
/// current, each point's flux and current the windows' span widened by the L_M margin
/// ([`MARGIN`]`.lm`: the current sensor's gain error and the model's approximations scale
/// them as they scale L_M). A point whose current does not exceed the one below it by more
/// than its own interval (the test current capped two levels at one current) is left out:
/// the curve must rise.
fn curve_points(levels: Vec<(Option<f64>, Vec<Window>)>) -> Vec<CurvePoint> {
    let mut points: Vec<CurvePoint> = levels
        .into_iter()
        .filter(|(_, b)| !b.is_empty())
        .map(|(target_fraction, b)| {
            let flux: Vec<f64> = b.iter().map(|x| x.stator_flux_wb).collect();
            let current: Vec<f64> = b.iter().map(|x| x.branch_current_a).collect();
            CurvePoint {
                target_fraction,
                flux_wb: Estimate::of(&flux, MARGIN.lm),
                current_a: Estimate::of(&current, MARGIN.lm),
            }
        })
        .collect();
    points.sort_by(|a, b| a.current_a.value.total_cmp(&b.current_a.value));
    let mut rising: Vec<CurvePoint> = Vec::with_capacity(points.len());
    for p in points {
        let above = rising.last().is_none_or(|q| {
            p.current_a.value > q.current_a.value * (1.0 + MARGIN.lm) && p.flux_wb.value > q.flux_wb.value
        });
        if above {
            rising.push(p);
        }
    }
    rising
}

/// The no-load test must reach this fraction of the rated flux, or the estimate is refused
/// (its L_m would not be the rated flux's; a wrong nameplate, or a test current too small).
pub const NO_LOAD_FLUX_MIN: f64 = 0.95;
/// … and at most this fraction: beyond it a saturating branch's inductance is far from the
/// rated flux's (1.38× the rated value at half flux, 0.8× at 1.1× on the shipped saturating
/// motor's curve), and the file would carry it as the rated one. Found by trying `hil-sim
/// identify delorenzo-saturating`: the test ran at 124.8 % and the file was written with
/// L_M 49 % below the curve's unsaturated value and T_r 64 % short.
pub const NO_LOAD_FLUX_MAX: f64 = 1.05;

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
                curve: false,
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
            curve: false,
        };
        let cfg = CommissionConfig::new(spec).unwrap();
        let mut rec = Record::default();
        for periods in [0, 1, 999, 1001, u32::MAX] {
            rec.rotation.periods_per_block = periods;
            let e = rotation(&cfg, &rec, 1, Branch::Linear(1.34), 20.8).unwrap_err();
            assert!(e.contains("empty or not this sequence's"), "{periods}: {e}");
        }
        rec.rotation.periods_per_block = 1000;
        assert!(rotation(&cfg, &rec, 1, Branch::Linear(1.34), 20.8).is_err(), "a rotor that never turned");
    }
}
