//! The machine the identification describes: the inverse-Γ circuit the terminals tell
//! (R_s, L_σ, L_M, R_R), the T-model under a leakage split (the `identify` module's docs,
//! "The model identified, and the leakage split"), and the rated flux of a nameplate.

use super::{Estimate, Identified};
use controller_core::motor::MotorParams;

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

/// Rated stator flux linkage (peak, per phase), Wb, from the nameplate's rated line voltage
/// (RMS) and frequency: `√2·V_LL/(√3·2π·f)` (the stator resistance's drop neglected).
pub fn rated_flux_wb(rated_voltage_v: f64, rated_frequency_hz: f64) -> f64 {
    std::f64::consts::SQRT_2 * rated_voltage_v
        / (3f64.sqrt() * 2.0 * std::f64::consts::PI * rated_frequency_hz)
}

/// A saturating Γ machine's own values at no load at stator flux `flux_wb`: what
/// [`GammaFit`](super::GammaFit) should find there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GammaTruth {
    /// The branch's chord ψ/f(ψ) at that flux, H.
    pub l_s_h: f64,
    /// The rotor-side leakage, H.
    pub l_sigma_h: f64,
    /// The rotor resistance, Ω.
    pub r_r_ohm: f64,
    /// (L_s + L_σ)/R_R, s.
    pub tr_s: f64,
}

/// [`GammaTruth`] of the Γ machine `m` (its T model: L_s = L_m, L_r = L_m + L_σ) whose branch
/// follows `curve`, at stator flux `flux_wb`.
pub fn gamma_truth(
    m: &MotorParams,
    curve: &controller_core::magnetics::MagnetizingCurve,
    flux_wb: f64,
) -> GammaTruth {
    let l_s_h = flux_wb / curve.current_a(flux_wb);
    let l_sigma_h = m.lr_h() - m.lm_h();
    GammaTruth { l_s_h, l_sigma_h, r_r_ohm: m.rr_ohm(), tr_s: (l_s_h + l_sigma_h) / m.rr_ohm() }
}

/// The true values the identification should find for `m`: (L_σ, L_M, R_R, T_r).
pub fn inverse_gamma(m: &MotorParams) -> (f64, f64, f64, f64) {
    let k = m.lm_h() / m.lr_h();
    let l_sigma = m.ls_h() - m.lm_h() * k;
    let l_mm = m.lm_h() * k;
    let r_rr = m.rr_ohm() * k * k;
    (l_sigma, l_mm, r_rr, m.lr_h() / m.rr_ohm())
}

#[cfg(test)]
mod tests {
    use super::*;

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
