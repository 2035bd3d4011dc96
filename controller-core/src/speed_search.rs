//! Flying start without an encoder: the rotor's speed read from its own flux before the
//! drive magnetizes it.
//!
//! **The physics.** With the stator current held at a constant vector `i` (the magnetizing
//! current of a field that does not turn, which is what the drive applies when it starts
//! magnetizing on a rotor it takes to be at rest), the rotor flux of the inverse-Γ model obeys
//! `dψ_R/dt = R_R·i − (α − j·ω_m)·ψ_R` (`α = 1/T_r`, `ω_m` the electrical rotor speed): its
//! departure from the steady state `ψ_∞ = R_R·i/(α − j·ω_m)` decays at `α` and turns at
//! `ω_m`, whatever the flux left in the rotor. Its rate `dψ_R/dt = (−α + j·ω_m)·(ψ_R − ψ_∞)`
//! turns at `ω_m` too, and it is what the stator's voltage model gives with the current held:
//! `dψ_R/dt = u_s − R_s·i_s − L_σ·di_s/dt`. From a rotor that carries no flux, its length is
//! `|(−α + jω_m)·ψ_∞| = R_R·|i|` at any speed — the drive's rated magnetizing current on the
//! rotor resistance: volts, well above the sensors' noise.
//!
//! **The estimate.** Over each window (`span` slow periods) the change of `ψ_R`, `d_k =
//! ∫(u_s − R_s·i_s)dt − L_σ·Δi_s`, is `c·z^k + b`: the transient, `z = e^((−α + jω_m)·T_window)`,
//! and a constant `b` — the stator-resistance error's drop `ΔR_s·i` and the inverter's
//! dead-time error, both constant vectors with the current held. So `d_{k+1} = z·d_k + (1 −
//! z)·b` exactly, and the least-squares fit of that line over the search (its intercept takes
//! `b`) gives `z`: its phase is `ω_m·T_window` — `Σ(d_{k+1} − m₁)(d_k − m₀)*`, `m` the means,
//! one `atan2` at the end — and its length `e^(−α·T_window)`, over the variance
//! `Σ|d_k − m₀|²`: the rotor's `1/T_r`, which the drive takes its rotor resistance from (the
//! magnetizing fit needs the rotor at rest). The current is held after the first window (not
//! used: it holds the current's rise), so `L_σ·Δi_s` is left out: its only part then is the
//! current sensors' noise at the windows' ends, which neighbouring windows share with opposite
//! signs — with it, the fit read the rotor resistance high on drive.toml's realistic sensors
//! (measured when the term was dropped; the commit's message holds the figures).
//! Without the intercept (the plain lag-one correlation) `|b|²`, real and positive, pulls the
//! angle towards zero as the transient decays. A rotor at rest gives a transient
//! that does not turn: zero. The angle per slow period must stay within ±π (the drive's
//! overspeed level keeps it within a tenth of that: [`crate::observer::ObserverConfig::new`]'s
//! correction bound); the search lasts one `T_r` (`DriveConfig`'s `search_slow_steps`), the
//! transient's own decay.

use crate::frames::{AlphaBeta, atan2};

/// The search's sums: the least-squares fit of `d_{k+1} = z·d_k + w` (complex; `w` takes the
/// constant bias), whose `arg z` is the angle per window — `Σ(d_{k+1} − m₁)(d_k − m₀)*` with
/// the means `m` of the pairs, made at the end from the raw sums.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SpeedSearch {
    /// `Σ d_{k+1}·d*_k`.
    cross: AlphaBeta,
    /// `Σ d_{k+1}` and `Σ d_k` over the pairs.
    next_sum: AlphaBeta,
    this_sum: AlphaBeta,
    /// `Σ |d_k|²` over the pairs.
    this_sq_sum: f32,
    /// Pairs summed.
    pairs: u32,
    /// The last window's `d_k`, if there was one.
    last: Option<AlphaBeta>,
    /// The first window is over (it holds the current's rise from zero: not used).
    started: bool,
    /// The voltage model's change over the window being summed, Wb, and its slow steps.
    pending: AlphaBeta,
    pending_steps: u32,
}

/// `a·b*`.
fn times_conj(a: AlphaBeta, b: AlphaBeta) -> AlphaBeta {
    AlphaBeta { alpha: a.alpha * b.alpha + a.beta * b.beta, beta: a.beta * b.alpha - a.alpha * b.beta }
}

impl SpeedSearch {
    /// One slow step: `dpsi_s`, the voltage model's `∫(u_s − R_s·i_s)dt` over it (Wb); a
    /// window is `span` slow steps. The first window is not used — it holds the current's rise
    /// from zero, whose `L_σ·Δi` is as wrong as the leakage estimate (drive.toml's campaign
    /// corner with L × 0.6 read a rotor at rest as turning).
    pub fn step(&mut self, dpsi_s: AlphaBeta, span: u32) {
        self.pending =
            AlphaBeta { alpha: self.pending.alpha + dpsi_s.alpha, beta: self.pending.beta + dpsi_s.beta };
        self.pending_steps += 1;
        if self.pending_steps >= span {
            let d = core::mem::take(&mut self.pending);
            self.pending_steps = 0;
            if core::mem::replace(&mut self.started, true) {
                self.window(d);
            }
        }
    }

    /// One window: `d`, the voltage model's change over it (Wb).
    fn window(&mut self, d: AlphaBeta) {
        if let Some(p) = self.last {
            let c = times_conj(d, p);
            self.cross = AlphaBeta { alpha: self.cross.alpha + c.alpha, beta: self.cross.beta + c.beta };
            self.next_sum =
                AlphaBeta { alpha: self.next_sum.alpha + d.alpha, beta: self.next_sum.beta + d.beta };
            self.this_sum =
                AlphaBeta { alpha: self.this_sum.alpha + p.alpha, beta: self.this_sum.beta + p.beta };
            self.this_sq_sum += p.alpha * p.alpha + p.beta * p.beta;
            self.pairs = self.pairs.saturating_add(1);
        }
        self.last = Some(d);
    }

    /// The electrical speed the rotor flux turned at, rad/s, over windows of `window_s`;
    /// `None` before two pairs of windows, or without a change.
    pub fn electrical_speed_rad_s(&self, window_s: f32) -> Option<f32> {
        self.fit().map(|(c, _)| atan2(c.beta, c.alpha) / window_s)
    }

    /// The rate the transient decays at, `α = 1/T_r` (1/s), over windows of `window_s`: the
    /// fit's `|z| = e^(−α·T_window)` — the cross-covariance over the variance of `d_k`,
    /// `|Σ(d_{k+1} − m₁)(d_k − m₀)*| / Σ|d_k − m₀|²`: the rotor's own time constant, read
    /// on the turning rotor, where the magnetizing fit, which needs it at rest, cannot run.
    /// `None` as [`SpeedSearch::electrical_speed_rad_s`], or without a decay (`|z| ≥ 1`).
    pub fn decay_rate_per_s(&self, window_s: f32) -> Option<f32> {
        let (c, variance) = self.fit()?;
        let z = crate::num::sqrt_f32(c.alpha * c.alpha + c.beta * c.beta) / variance;
        let alpha = -ln_near_one(z) / window_s;
        crate::num::finite_positive(alpha).then_some(alpha)
    }

    /// The fit: the cross-covariance `c = Σ(d_{k+1} − m₁)(d_k − m₀)*` and the variance
    /// `Σ|d_k − m₀|²`; `None` before two pairs, or without a change.
    fn fit(&self) -> Option<(AlphaBeta, f32)> {
        if self.pairs < 2 {
            return None;
        }
        let n = self.pairs as f32;
        let means = times_conj(self.next_sum, self.this_sum);
        let c =
            AlphaBeta { alpha: self.cross.alpha - means.alpha / n, beta: self.cross.beta - means.beta / n };
        let m0 = self.this_sum;
        let variance = self.this_sq_sum - (m0.alpha * m0.alpha + m0.beta * m0.beta) / n;
        let len2 = c.alpha * c.alpha + c.beta * c.beta;
        (len2 > 0.0 && len2.is_finite()).then_some((c, variance))
    }
}

/// `ln x` for `x` in (0, 1], to 0.5 % down to `x` = 0.3: `2·atanh(y)`, `y = (x − 1)/(x + 1)`,
/// to `y⁵` — a window's decay `e^(−α·T_window)` is near one (libm's table-driven `logf` is
/// larger than the firmware's flash has left).
fn ln_near_one(x: f32) -> f32 {
    let y = (x - 1.0) / (x + 1.0);
    let y2 = y * y;
    2.0 * y * (1.0 + y2 * (1.0 / 3.0 + y2 / 5.0))
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn the_logarithm_near_one() {
        for k in 0..=700 {
            let x = 1.0 - 0.001 * k as f32;
            let (got, exact) = (f64::from(ln_near_one(x)), f64::from(x).ln());
            assert!((got - exact).abs() <= 5e-3 * exact.abs() + 1e-7, "{x}: {got} against {exact}");
        }
    }

    /// The rotor flux's transient under a held current, exactly: windows of its change turn
    /// at the rotor's speed, both ways, and stand still at rest — with a constant bias too
    /// (a stator resistance 10 % off, 1 V; 3 V at 20 rad/s), which the fit's intercept takes;
    /// and they decay at the rotor's `α` (within 1 %).
    #[test]
    fn the_held_current_transient_turns_at_the_rotors_speed() {
        // drive.toml's motor in the inverse-Γ form: R_R 20.8 Ω, L_M 1.34 H (α 15.5 1/s),
        // its 0.63 A magnetizing current, the slow period 0.5 ms, one T_r of windows.
        let (r_rr, alpha, i, t) = (20.8f64, 15.5f64, 0.63f64, 5e-4f64);
        let windows = (1.0 / (alpha * t)).ceil() as usize;
        for (w_m, bias_v, tolerance) in [
            (392.0, 0.0, 1e-3),
            (-196.0, 0.0, 1e-3),
            (20.0, 0.0, 1e-3),
            (0.0, 0.0, 1e-6),
            (196.0, 1.0, 1e-3),
            (-20.0, 3.0, 1e-2),
        ] {
            // ψ_R(t) − ψ_∞ = −ψ_∞·e^((−α + jω)t) from a rotor without flux; ψ_∞ = R_R·i/(α − jω).
            let (den_re, den_im) = (alpha, -w_m);
            let n = den_re * den_re + den_im * den_im;
            let psi_inf = (r_rr * i * den_re / n, -r_rr * i * den_im / n);
            let psi = |t: f64| {
                let (m, a) = ((-alpha * t).exp(), w_m * t);
                (
                    psi_inf.0 * (1.0 - m * a.cos()) + psi_inf.1 * m * a.sin(),
                    psi_inf.1 * (1.0 - m * a.cos()) - psi_inf.0 * m * a.sin(),
                )
            };
            let mut s = SpeedSearch::default();
            s.step(AlphaBeta::default(), 1);
            for k in 0..windows {
                let (p0, p1) = (psi(k as f64 * t), psi((k + 1) as f64 * t));
                // The voltage model's change: the flux's, plus the resistance error's drop.
                let d = AlphaBeta { alpha: (p1.0 - p0.0 + bias_v * t) as f32, beta: (p1.1 - p0.1) as f32 };
                s.step(d, 1);
            }
            let got = f64::from(s.electrical_speed_rad_s(t as f32).unwrap());
            let error = (got - w_m).abs() / w_m.abs().max(1.0);
            assert!(error < tolerance, "{w_m} rad/s, bias {bias_v} V: {got}");
            let decay = f64::from(s.decay_rate_per_s(t as f32).unwrap());
            assert!((decay / alpha - 1.0).abs() < 1e-2, "{w_m} rad/s, bias {bias_v} V: α {decay} of {alpha}");
        }
    }
}
