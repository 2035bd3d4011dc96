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
//! **The estimate.** Over each slow period the change of `ψ_R`, `d_k = ∫(u_s − R_s·i_s)dt −
//! L_σ·Δi_s`, is `c·z^k + b`: the transient, `z = e^((−α + jω_m)·T_slow)`, and a constant `b`
//! — the stator-resistance error's drop `ΔR_s·i` and the inverter's dead-time error, both
//! constant vectors with the current held. So `d_{k+1} = z·d_k + (1 − z)·b` exactly, and the
//! least-squares fit of that line over the search (its intercept takes `b`) gives `z`, whose
//! phase is `ω_m·T_slow`: `Σ(d_{k+1} − m₁)(d_k − m₀)*`, `m` the means, one `atan2` at the end.
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
    /// Pairs summed.
    pairs: u32,
    /// The last window's `d_k`, if there was one.
    last: Option<AlphaBeta>,
    /// The current at the last window's end, A (`None` before the first: the window from
    /// the enable to the first slow step is partial and is not used).
    i_last: Option<AlphaBeta>,
    /// The voltage model's change over the window being summed, Wb, and its slow steps.
    pending: AlphaBeta,
    pending_steps: u32,
}

/// `a·b*`.
fn times_conj(a: AlphaBeta, b: AlphaBeta) -> AlphaBeta {
    AlphaBeta { alpha: a.alpha * b.alpha + a.beta * b.beta, beta: a.beta * b.alpha - a.alpha * b.beta }
}

impl SpeedSearch {
    /// One slow step: `dpsi_s`, the voltage model's `∫(u_s − R_s·i_s)dt` over it (Wb), the
    /// current `i_now` at its end (A), the leakage `l_sigma_h` (H); a window is `span` slow
    /// steps. The first window is not used — it holds the current's rise from zero, whose
    /// `L_σ·Δi` is as wrong as the leakage estimate (drive.toml's campaign corner with
    /// L × 0.6 read a rotor at rest as turning) — it sets the current the next starts from.
    pub fn step(&mut self, dpsi_s: AlphaBeta, i_now: AlphaBeta, l_sigma_h: f32, span: u32) {
        if self.i_last.is_none() {
            self.pending_steps += 1;
            if self.pending_steps >= span {
                self.pending_steps = 0;
                self.i_last = Some(i_now);
            }
            return;
        }
        self.pending =
            AlphaBeta { alpha: self.pending.alpha + dpsi_s.alpha, beta: self.pending.beta + dpsi_s.beta };
        self.pending_steps += 1;
        if self.pending_steps >= span {
            let dpsi_s = core::mem::take(&mut self.pending);
            self.pending_steps = 0;
            self.window(dpsi_s, i_now, l_sigma_h);
        }
    }

    /// One window: `dpsi_s`, the voltage model's change over it (Wb), the current `i_now`
    /// at its end (A), the leakage `l_sigma_h` (H).
    fn window(&mut self, dpsi_s: AlphaBeta, i_now: AlphaBeta, l_sigma_h: f32) {
        let Some(i_last) = self.i_last.replace(i_now) else { return };
        let d = AlphaBeta {
            alpha: dpsi_s.alpha - l_sigma_h * (i_now.alpha - i_last.alpha),
            beta: dpsi_s.beta - l_sigma_h * (i_now.beta - i_last.beta),
        };
        if let Some(p) = self.last {
            let c = times_conj(d, p);
            self.cross = AlphaBeta { alpha: self.cross.alpha + c.alpha, beta: self.cross.beta + c.beta };
            self.next_sum =
                AlphaBeta { alpha: self.next_sum.alpha + d.alpha, beta: self.next_sum.beta + d.beta };
            self.this_sum =
                AlphaBeta { alpha: self.this_sum.alpha + p.alpha, beta: self.this_sum.beta + p.beta };
            self.pairs = self.pairs.saturating_add(1);
        }
        self.last = Some(d);
    }

    /// The electrical speed the rotor flux turned at, rad/s, over windows of `window_s`;
    /// `None` before two pairs of windows, or without a change.
    pub fn electrical_speed_rad_s(&self, window_s: f32) -> Option<f32> {
        if self.pairs < 2 {
            return None;
        }
        let n = self.pairs as f32;
        let means = times_conj(self.next_sum, self.this_sum);
        let c =
            AlphaBeta { alpha: self.cross.alpha - means.alpha / n, beta: self.cross.beta - means.beta / n };
        let len2 = c.alpha * c.alpha + c.beta * c.beta;
        (len2 > 0.0 && len2.is_finite()).then(|| atan2(c.beta, c.alpha) / window_s)
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    /// The rotor flux's transient under a held current, exactly: windows of its change turn
    /// at the rotor's speed, both ways, and stand still at rest — with a constant bias too
    /// (a stator resistance 10 % off, 1 V; 3 V at 20 rad/s), which the fit's intercept takes.
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
            let held = AlphaBeta { alpha: i as f32, beta: 0.0 };
            let mut s = SpeedSearch::default();
            s.step(AlphaBeta::default(), held, 0.1, 1);
            for k in 0..windows {
                let (p0, p1) = (psi(k as f64 * t), psi((k + 1) as f64 * t));
                // The voltage model's change: the flux's, plus the resistance error's drop.
                let d = AlphaBeta { alpha: (p1.0 - p0.0 + bias_v * t) as f32, beta: (p1.1 - p0.1) as f32 };
                s.step(d, held, 0.1, 1);
            }
            let got = f64::from(s.electrical_speed_rad_s(t as f32).unwrap());
            let error = (got - w_m).abs() / w_m.abs().max(1.0);
            assert!(error < tolerance, "{w_m} rad/s, bias {bias_v} V: {got}");
        }
    }
}
