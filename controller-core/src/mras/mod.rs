//! Rotor-resistance adaptation: a reactive-power model-reference adaptive system (MRAS).
//!
//! The field orientation ([`crate::ifoc`]) slips the field by `ω_sl = L_m·R_r/(L_r·ψ̂_r)·i_qs*`
//! and runs its flux model with `T_r = L_r/R_r`. The rotor resistance grows with the rotor's
//! temperature (aluminium bars: ≈ +0.4 %/K, so ×1.5 at 120 K above the temperature it was
//! measured at); with the resistance the motor file states, a hot rotor under load gets too
//! little slip and its flux runs above the model's (×1.66 at R_r ×2 in the campaign, issue 21).
//! This module estimates the scale `r̂ = R̂_r/R_r` online; the drive runs the slip and flux
//! model on it ([`crate::ifoc::IfocConfig::set_rotor_resistance_scale`]).
//!
//! **Reference (the machine)**: the reactive power of the measured currents and the voltage
//! the current loops asked for, in the field frame, `q = v_q·i_d − v_d·i_q` (the
//! amplitude-invariant scaling's; a factor 3/2 apart from the watts on both sides).
//!
//! **Adjustable model**: the same in steady state, with the flux held,
//! `q̂ = ω_e·(σL_s·|i|² + (L_m/L_r)·ψ̂_r·i_d)` — `v_d = R_s·i_d − ω_e·σL_s·i_q`,
//! `v_q = R_s·i_q + ω_e·(σL_s·i_d + (L_m/L_r)·ψ̂_r)` ([`EnvelopeConfig::stator_voltage`]):
//! **the stator resistance cancels**, so a hot stator (R_s ×1.5 in the certified box) does not
//! bias the estimate, and neither does a voltage error in phase with the current (the
//! dead time's, to first order).
//!
//! **Why it converges.** With the currents imposed, the rotor flux in steady state is
//! `ψ_r = L_m·i/(1 + j·ω_sl·T_r)`, so `q = ω_e·|i|²·(σL_s + (L_m²/L_r)/(1 + (ω_sl·T_r)²))`. The
//! drive's own model has `ω_sl·T̂_r = i_q/i_d = a`. With the true scale ρ,
//! `ω_sl·T_r = (r̂/ρ)·a`, and the normalised error
//! `x = (q − q̂)/(ω_e·(L_m²/L_r)·|i|²) = 1/(1 + (r̂·a/ρ)²) − 1/(1 + a²)` is positive when
//! `r̂ < ρ`, negative when `r̂ > ρ`, zero at `r̂ = ρ` — in motoring and generating alike (the
//! slip enters squared). Its slope at the match, `∂x/∂ln r̂ = −2a²/(1 + a²)²`, is largest at
//! `a = 1` (0.5) and small at both ends: no information at no load (no slip to get wrong) and
//! little at full torque from a low flux (a = 6 at the shipped drive's limit). The update is
//! a gradient step on `ln r̂`, `r̂ ← r̂·(1 + g·x/max(s(a), 0.5/`[`AMPLIFICATION_MAX`]`))`,
//! `g = T_slow/(`[`LAW_TIME_CONSTANTS`]`·T_r)`, limited to the configured range: a
//! first-order response with three rotor time constants where the slope peaks (the flux
//! cannot follow a faster change of the slip), never faster elsewhere, the step amplified
//! where the slope is small so that a high load ratio still converges (4.7 T_r at a = 6).
//! Found by trying (docs/rotor-resistance.md): a Newton step — dividing by the slope
//! uncapped — oscillated generating at a = 6; one rotor time constant with a cap of 3 put
//! torque ripple into the 24 V walk-through motor's generating runs (T_r = 14 ms); no
//! amplification left a flying start in field weakening seconds from converged.
//!
//! **What it cannot tell apart.** The reactive power also carries the leakage: a machine
//! whose leakage is ΔL above the model's (a leakage that saturates, a motor file whose
//! leakage is not the running machine's) adds `ω_e·ΔL·|i|²` to `q`, `x` by
//! `ΔL/(L_m²/L_r)`, and the law settles where the resistance's share cancels it:
//! `r̂/ρ − 1 ≈ (ΔL/(L_m²/L_r))/s(a)` — the leakage read as resistance, amplified by
//! `1/s(a)` to first order: 2 at a = 1, 3.1 at a = 0.5 and 2, 19 at a = 6 (unit test
//! `a_leakage_error_is_read_as_resistance_amplified_by_the_slope`). The step's amplification
//! only sets how fast it gets there. Measured: a deep-bar plant whose zero-slip leakage was
//! 13 % above its file's walked the shipped drive's estimate to ×1.25 in field weakening;
//! listening only where `s(a)` is within 64 % of its peak on both sides (a ≤ 2) cured that
//! but left the flying starts the law corrects at a ≈ 4.5 (the 24 V drive braking at
//! 391 rad/s: the q-axis fit's ×1.089 held, −7.5 % of torque), and a linear drive on its
//! motor's saturating twin at 2× base speed fell from 0.849 to 0.528 of the physical limit.
//! A deep bar whose circuit is the file's at zero slip (plant::DeepBar) moves the leakage at
//! the running slips little, and the shipped drive meets its requirements on it
//! (docs/verification.md).
//!
//! **When it listens** ([`MrasConfig::update`] returns the scale unchanged otherwise):
//! Running on the field-oriented references — on the voltage the bridge was given, limited
//! by the modulator or not (listening to the unlimited samples only, it read a rotor
//! resistance 10 % low at the voltage limit: docs/rotor-resistance.md) —, `|i_q| ≥` [`LOAD_RATIO_MIN`]`·i_d` (the slope at least
//! 64 % of its peak) and the rotor-flux EMF `|ω_e|·(L_m/L_r)·ψ̂_r` at least
//! [`EMF_FRACTION_MIN`] of the linear voltage limit (so that the voltage's own errors —
//! dead time, sensor gain — stay small against it), on a plan that moved the current
//! references by at most [`PLAN_STEADY_FRACTION`] of i_d (the inductance law's gate, for the
//! same reason: the evidence is the first fast step on the plan, whose voltage carries the
//! loops' proportional reaction `k_p·Δi*`; where the speed loop's answers to the encoder's
//! counts swing the load ratio about [`LOAD_RATIO_MIN`], the gate picks the samples whose
//! `i_q` was just pushed up — the population's 182 kW member 052 at no load in field
//! weakening read its ×1.236 rotor as ×1.04 that way, docs/rotor-resistance.md). At rest and
//! at no load the estimate is held: it is the rotor's temperature, which changes over
//! minutes.
//!
//! **Where it starts: measured while magnetizing** ([`fit`]): the rotor time constant, the
//! inductances and the stator resistance from the flux build at the enable, on a rotor at
//! rest or turning, on a linear or a saturating curve — before the first torque.
//!
//! **Online, at no load: the inductances** ([`MrasConfig::update_inductance`]). The fit's ℓ̂
//! carries the current sensors' noise twice (it needs the decay's area): on small motors its
//! spread is of the order of a ±5 % flux requirement. Where the loaded law has no
//! information the inductances' is whole: at `a = i_q/i_d → 0` the same reactive power is
//! `q = ω_e·(σL_s·|i|² + (L_m/L_r)·ψ_r·i_d) = ℓ·ω_e·L_s·i_d²` (the flux settled at
//! `ℓ·L_m·i_d`), the model's `q̂` is the same with ℓ̂, so `q/q̂ = ℓ/ℓ̂` — again without the
//! stator resistance or a voltage error in phase with the current. The update
//! `ℓ̂ ← ℓ̂·(1 + g·(q − q̂)/q̂)` (slope one in ln ℓ̂, the same gain: three rotor time constants)
//! listens at `|a| ≤` [`INDUCTANCE_LOAD_RATIO_MAX`] (the slip's share of the bias, stated
//! there), at the loaded law's EMF, with the flux model within [`FLUX_SETTLED_FRACTION`] of
//! its steady state (the relation is the settled flux's) and on a plan that did not move the
//! references by more than [`PLAN_STEADY_FRACTION`] (the loops' reaction to a step is in the
//! voltage). The drive keeps the rotor time constant the fit and the loaded law found,
//! `T̂_r = (ℓ̂/r̂)·T_r`, by scaling r̂ with ℓ̂ (the slip does not move), and turns the rated
//! flux's `i_d*` with ℓ̂. The two laws listen in disjoint regions (`a ≤ 0.3`, `a ≥ 0.5`).
//!
//! What the loaded law cannot tell apart: an inductance error scales `q` as a whole, and it
//! reads it as a slip error — ℓ̂'s own error is what is left of it. Saturation that changes
//! with the flux level is not modelled: ℓ̂ is the flux in use's (the rated flux's, below base
//! speed).

use crate::envelope::EnvelopeConfig;
use crate::frames::Dq;
use crate::motor::MotorParams;
use crate::num::{Scalar, sqrt_f32};

pub mod fit;

pub use fit::{
    DEMAGNETIZED_TIME_CONSTANTS, FIT_CURVE_FLUX_FRACTION, FIT_FLUX_SAMPLES, FIT_I_D_TOLERANCE,
    FIT_SETTLED_SHARE, FIT_SKIP_S, FIT_SLIDE_WINDOWS_MAX, FIT_WINDOW_FRACTION, FitAxis, FitPeriod, Fitted,
    RotorFit, fit_time_max_s, fit_window_s,
};

/// The least load ratio `|i_q|/i_d` the law listens at: the slope `s(a) = 2a²/(1 + a²)²` is
/// 0.32 there, 64 % of its peak (0.5 at a = 1).
pub const LOAD_RATIO_MIN: f32 = 0.5;

/// The largest load ratio `|i_q|/i_d` the inductance law listens at
/// ([`MrasConfig::update_inductance`]). There a rotor time constant off by ρ_t (the machine's
/// `1/T_r` over the drive's) biases the reactive power by `(1 + a²)/(1 + (ρ_t·a)²) − 1 ≈
/// −(ρ_t² − 1)·a²` of the no-load figure: after the magnetizing fit, which reads `T_r` within
/// a few per cent (its ratio of decays; docs/rotor-resistance.md), 0.55 % at ρ_t = 1.03; on
/// the range's guess before any fit (a flying start, ρ_t up to 1.22 on the default range)
/// 4.5 % until the loaded law has corrected `r̂`. Not less: a small motor's friction alone
/// is a load ratio of 0.13–0.18 at half its base speed (the 24 V walk-through motor's), and
/// at 0.1 its law never listened there.
pub const INDUCTANCE_LOAD_RATIO_MAX: f32 = 0.3;

/// Both laws listen only at a slow step whose plan moved the current references by
/// at most this fraction of i_d. Its evidence is the first fast step on the new plan, whose
/// voltage carries the loops' proportional reaction to the step, `k_p·Δi*` — against the
/// no-load reactive voltage `ω_e·L_s·i_d` a large share where the loops are fast against
/// the field (k_p/(ω_e·L_s) ≈ 8 on the 24 V walk-through motor at half base speed). At no
/// load the steps are the speed loop's answer to the encoder's quantised speed, and the load
/// gate picks the small `i_q` after which the next step is upwards: the 24 V motor's ℓ̂ read
/// 10 % high that way (`population`'s campaign reversals). At 0.1 % the reaction's share
/// stays below 1 % where k_p/(ω_e·L_s) ≤ 10.
pub const PLAN_STEADY_FRACTION: f32 = 1e-3;

/// The inductance law listens only with the flux model within this fraction of its steady
/// state `L̂_m·i_d`: `q = ℓ·ω_e·L_s·i_d²` holds for a settled flux, and while the flux builds
/// (a flying start, a field-weakening step) the machine's and the model's differ by their
/// rotor time constants' difference, not by ℓ — a flying start at 300 rad/s on the shipped
/// drive read ℓ̂ 1.6 % low from its flux build (`hil-sim --test envelope`, the torque reversal).
pub const FLUX_SETTLED_FRACTION: f32 = 0.02;

/// The peak of the error's slope `s(a) = 2a²/(1 + a²)²` (at a = 1).
const SLOPE_PEAK: f32 = 0.5;

/// The law's time constant at the slope's peak, in rotor time constants (module docs).
pub const LAW_TIME_CONSTANTS: f64 = 3.0;

/// The most the gradient step is amplified where the slope is small: the slope's peak over
/// this is the least divisor, so no slope is followed faster than the peak's.
pub const AMPLIFICATION_MAX: f32 = 6.0;

/// The least rotor-flux EMF the law listens at, as a fraction of the linear voltage limit.
pub const EMF_FRACTION_MIN: f32 = 0.1;

/// The range a drive file gets by default, × the motor's R_r: a rotor resistance measured
/// cold (identification, a datasheet's ambient figure), up to ≈ 120 K hotter — aluminium
/// bars, ≈ +0.4 %/K: a class-F rotor at its limit.
pub const DEFAULT_RANGE: [f64; 2] = [1.0, 1.5];

/// The widest range either estimate accepts, max/min: a rotor resistance or an inductance
/// uncertain by more than this is a motor file to be measured again, not one to adapt to
/// (the estimate starts inside the range, and the fit's windows are sized for its middle).
pub const RANGE_RATIO_MAX: f64 = 10.0;

/// Why an adaptation range was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MrasError {
    /// The rotor-resistance range is not `0 < min ≤ max ≤ min·`[`RANGE_RATIO_MAX`], finite.
    Range,
    /// The inductance range is not `0 < min ≤ max ≤ min·`[`RANGE_RATIO_MAX`], finite.
    InductanceRange,
    /// A period or the rotor time constant is not finite and positive.
    Rate,
}

crate::raw::raw_struct! {
    /// The adaptation's constants (from the motor, the periods and the ranges).
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct MrasConfig {
        /// `T_slow/(LAW_TIME_CONSTANTS·T_r)`: the update's gain.
        gain: f32,
        /// The range of `r̂`, × the motor's R_r.
        min: f32,
        max: f32,
        /// The range of `ℓ̂`, × the motor's inductances.
        l_min: f32,
        l_max: f32,
        /// The magnetizing fit: slow steps skipped, slow steps per window, and
        /// `T_r,motor/W` (`r̂/ℓ̂ = (T_r/W)·ln((S₀ − S₁)/(S₁ − S₂))`).
        fit_skip_steps: u32,
        fit_window_steps: u32,
        tr_over_window: f32,
        /// Fast steps per slow step, and `T_fast/L_s` (the flux linkage's volt-seconds, summed
        /// per fast step, over the motor's stator inductance), s/H.
        slow_divider: f32,
        t_fast_over_ls: f32,
        /// Idle slow steps after which the rotor counts as demagnetized
        /// ([`DEMAGNETIZED_TIME_CONSTANTS`]).
        demagnetized_steps: u32,
        /// A saturating motor's flux samples: slow steps apart ([`FIT_FLUX_SAMPLES`]), the
        /// fast period (Wb per volt-step), the leakages and the rotor resistance of the motor
        /// file ([`Self::rotor_resistance_on_curve`]).
        fit_sample_steps: u32,
        t_fast_s: f32,
        l_ls_h: f32,
        l_lr_h: f32,
        rr_ohm: f32,
    }
}

/// What one slow period shows the online law ([`MrasConfig::update`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Evidence {
    /// The measured current in the field frame, A.
    pub i: Dq,
    /// The voltage the bridge was given for the current loops — their request, or the
    /// modulator's limit of it — same frame and instant, V.
    pub v: Dq,
    /// The field's speed, electrical rad/s.
    pub w_e_rad_s: f32,
    /// The drive's rotor-flux estimate, Wb.
    pub psi_r_wb: f32,
    /// The linear voltage limit of the usable bus, V.
    pub v_limit_v: f32,
    /// How far the plan made at this slow step moved the current references, `|Δi*|`, A:
    /// the loops' proportional reaction to it is in `v`.
    pub i_ref_step_a: f32,
}

impl Evidence {
    /// The rotor-flux EMF `|ω_e|·(L_m/L_r)·ψ̂_r` is at least [`EMF_FRACTION_MIN`] of the
    /// linear voltage limit: the voltage's own errors stay small against it (both laws).
    #[inline(always)]
    fn emf_heard(&self, model: &EnvelopeConfig) -> bool {
        (self.w_e_rad_s * model.lm_over_lr() * self.psi_r_wb).abs() >= EMF_FRACTION_MIN * self.v_limit_v
    }

    /// The reactive power of the measured current and the loops' voltage,
    /// `q = v_q·i_d − v_d·i_q`, and the model's steady state of it at the flux estimate, `q̂`
    /// (module docs; both laws compare them).
    #[inline(always)]
    fn reactive_powers(&self, model: &EnvelopeConfig) -> (f32, f32) {
        let Self { i, v, w_e_rad_s: w_e, psi_r_wb, .. } = *self;
        let (vd, vq) = model.stator_voltage(i.d, i.q, w_e, psi_r_wb);
        (v.q * i.d - v.d * i.q, vq * i.d - vd * i.q)
    }
}

/// `0 < min ≤ max ≤ min·RANGE_RATIO_MAX`, finite.
fn range_ok([min, max]: [f64; 2]) -> bool {
    min.is_finite() && max.is_finite() && min > 0.0 && min <= max && max <= RANGE_RATIO_MAX * min
}

impl MrasConfig {
    /// For `motor`, the fast period `t_fast_s`, `slow_divider` fast steps per slow step, and
    /// the ranges `[min, max]` of the rotor resistance and of the inductances, × the motor's
    /// (`[1, 1]`: not estimated).
    pub fn new(
        motor: &MotorParams,
        t_fast_s: f64,
        slow_divider: u16,
        range: [f64; 2],
        inductance_range: [f64; 2],
    ) -> Result<Self, MrasError> {
        if !range_ok(range) {
            return Err(MrasError::Range);
        }
        if !range_ok(inductance_range) {
            return Err(MrasError::InductanceRange);
        }
        let ([min, max], [l_min, l_max]) = (range, inductance_range);
        let t_slow_s = t_fast_s * f64::from(slow_divider);
        let gain = t_slow_s / (LAW_TIME_CONSTANTS * motor.tr_s());
        if !(gain.is_finite() && gain > 0.0) {
            return Err(MrasError::Rate);
        }
        let f = f32::from_f64;
        // The windows: at the middle of the rotor resistance's range, on the motor's
        // inductance (a saturated machine's shorter T_r gets windows longer against it: they
        // average more noise). The rotor time constant at its longest: for demagnetizing.
        let window_s = fit_window_s(motor, range);
        let fit_window_steps = libm::round(window_s / t_slow_s).clamp(1.0, 1e6) as u32;
        let tr_max_s = motor.tr_s() * l_max / min;
        let fit_skip_steps = libm::ceil(FIT_SKIP_S / t_slow_s).clamp(0.0, 1e6) as u32;
        // The samples span the skip, the first slow step's and the three windows.
        let build_steps = fit_skip_steps + 1 + 3 * fit_window_steps;
        Ok(Self {
            gain: f(gain.min(1.0)),
            min: f(min),
            max: f(max),
            l_min: f(l_min),
            l_max: f(l_max),
            fit_skip_steps,
            fit_window_steps,
            tr_over_window: f(motor.tr_s() / (f64::from(fit_window_steps) * t_slow_s)),
            slow_divider: f32::from(slow_divider),
            t_fast_over_ls: f(t_fast_s / motor.ls_h()),
            demagnetized_steps: libm::ceil(DEMAGNETIZED_TIME_CONSTANTS * tr_max_s / t_slow_s).clamp(0.0, 4e9)
                as u32,
            fit_sample_steps: (build_steps / FIT_FLUX_SAMPLES as u32).max(1),
            t_fast_s: f(t_fast_s),
            l_ls_h: f(motor.ls_h() - motor.lm_h()),
            l_lr_h: f(motor.lr_h() - motor.lm_h()),
            rr_ohm: f(motor.rr_ohm()),
        })
    }

    /// The online rotor-resistance law runs (its range is not a single value).
    pub fn active(&self) -> bool {
        self.max > self.min
    }

    /// A configuration [`MrasConfig::new`] could have made (a check on raw data).
    pub fn is_valid(&self) -> bool {
        self.min > 0.0
            && self.min <= self.max
            && self.l_min > 0.0
            && self.l_min <= self.l_max
            && self.fit_window_steps > 0
            && self.gain > 0.0
            && self.slow_divider >= 1.0
    }

    /// The rotor-resistance range, × the motor's R_r.
    pub fn range(&self) -> [f32; 2] {
        [self.min, self.max]
    }

    /// The inductance range, × the motor's.
    pub fn inductance_range(&self) -> [f32; 2] {
        [self.l_min, self.l_max]
    }

    /// The rotor-resistance estimate at power-up: the range's geometric middle `√(min·max)`.
    pub fn initial_scale(&self) -> f32 {
        sqrt_f32(self.min * self.max)
    }

    /// The inductance estimate at power-up: the motor file's, limited to the range (a
    /// saturating machine's inductance is at most its unsaturated one).
    pub fn initial_inductance_scale(&self) -> f32 {
        1.0f32.limit(self.l_min, self.l_max)
    }

    /// One slow period: the scale `r` (× the motor's R_r) after this period's `evidence` —
    /// or `r` unchanged when it is not informative (module docs). `model` is the drive's
    /// machine model, on the inductance in use ([`EnvelopeConfig::with_inductance_scale`]).
    #[inline(never)]
    pub fn update(&self, r: f32, model: &EnvelopeConfig, evidence: &Evidence) -> f32 {
        let Evidence { i, w_e_rad_s: w_e, i_ref_step_a, .. } = *evidence;
        let listening = self.active()
            && i.d > 0.0
            && i.q.abs() >= LOAD_RATIO_MIN * i.d
            && i_ref_step_a <= PLAN_STEADY_FRACTION * i.d
            && evidence.emf_heard(model);
        if !listening {
            return r;
        }
        let (q, q_model) = evidence.reactive_powers(model);
        let i2 = i.d * i.d + i.q * i.q;
        let x = (q - q_model) / (w_e * i2 * model.lm2_over_lr_h());
        let a2 = i.q * i.q / (i.d * i.d);
        let one_a2 = 1.0 + a2;
        let slope = 2.0 * a2 / (one_a2 * one_a2);
        let step = x / crate::num::max_f32(slope, SLOPE_PEAK / AMPLIFICATION_MAX);
        let next = r * (1.0 + self.gain * step);
        if next.is_finite() { next.limit(self.min, self.max) } else { r }
    }

    /// One slow period: the inductance scale `l` (× the motor's) after this period's
    /// `evidence` — or `l` unchanged when it is not informative. The no-load half of the same
    /// reactive power (module docs, "Online, at no load"): with `|i_q| ≤`
    /// [`INDUCTANCE_LOAD_RATIO_MAX`]`·i_d` the slip carries no information, and
    /// `q/q̂ = ℓ/ℓ̂`; `ℓ̂ ← ℓ̂·(1 + g·(q − q̂)/q̂)`, the rotor-resistance law's gain.
    #[inline(never)]
    pub fn update_inductance(&self, l: f32, model: &EnvelopeConfig, evidence: &Evidence) -> f32 {
        let Evidence { i, psi_r_wb, i_ref_step_a, .. } = *evidence;
        // The flux model at its steady state `L̂_m·i_d` (L̂_m = (L̂_m²/L̂_r)/(L_m/L_r)), on the
        // measured current the model filters: a reference the loops follow with a steady
        // error at speed (stationary frame) would keep the gate shut.
        let psi_steady_wb = model.lm2_over_lr_h() / model.lm_over_lr() * i.d;
        let listening = self.l_max > self.l_min
            && i.d > 0.0
            && i.q.abs() <= INDUCTANCE_LOAD_RATIO_MAX * i.d
            && (psi_r_wb - psi_steady_wb).abs() <= FLUX_SETTLED_FRACTION * psi_r_wb
            && i_ref_step_a <= PLAN_STEADY_FRACTION * i.d
            && evidence.emf_heard(model);
        if !listening {
            return l;
        }
        let (q, q_model) = evidence.reactive_powers(model);
        let next = l * (1.0 + self.gain * (q - q_model) / q_model);
        if next.is_finite() { next.limit(self.l_min, self.l_max) } else { l }
    }
}

#[cfg(test)]
mod tests;
