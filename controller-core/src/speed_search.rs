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
//! rotor resistance: volts on a small motor (13 V for drive.toml), a fraction of a volt on a
//! large one (0.71 V for the population's 153 kW member, whose windows' noise is that size).
//!
//! **The estimate.** Over each window (`span` slow periods) the voltage model's change,
//! `d_k = ∫(u_s − R_s·i_s)dt`, is `c·z^k + b` and noise: the transient, `z =
//! e^((−α + jω_m)·T_window)`, and a constant `b` — the stator-resistance error's drop `ΔR_s·i`
//! and the inverter's dead-time error, both constant vectors with the current held. So
//! `d_{k+1} = z·d_k + (1 − z)·b`, and with the means removed the windows' lags are `c_L =
//! Σ(d_{k+L} − m_L)(d_k − m₀)* = z^L·S` (`S` the transient's variance): `z = c₃/c₂`, its
//! phase `ω_m·T_window` (one `atan2` at the end) and its length `e^(−α·T_window)`, the
//! rotor's `1/T_r`, which the drive takes its rotor resistance from (the magnetizing fit
//! needs the rotor at rest). The lags three and two, not one: the noise each window carries
//! (what the current did at its two ends, [`SpeedSearch`]) reaches lag one only. The current
//! is held after the first window (not used: it holds the current's rise), so `L_σ·Δi_s` is
//! left out: with it the noise is the current sensors' at the windows' ends, without it the
//! current's own departure — either way a difference at the ends. A rotor at rest gives a
//! transient that does not turn: zero, and a turn is read only where the noise does not
//! explain it ([`SpeedSearch`]'s tests). The angle per slow period must stay within ±π (the
//! drive's overspeed level keeps it within a tenth of that:
//! [`crate::observer::ObserverConfig::new`]'s correction bound); the search lasts one `T_r`
//! (`DriveConfig`'s `search_slow_steps`), the transient's own decay.

use crate::frames::{AlphaBeta, atan2};
use crate::num::Scalar;

/// The search's sums: the fit of `d_{k+1} = z·d_k + w` (complex; `w` takes the constant
/// bias) by the lags that the windows' own noise does not reach, `z = c₃/c₂` with `c_L =
/// Σ(d_{k+L} − m_L)(d_k − m₀)*` — made at the end from the raw sums.
///
/// **Why not least squares.** A window's `d_k` carries, beside the transient, what the
/// current did at its two ends: `L_σ` times the stator current's departure from the held
/// vector there (the current loop's answer to the sensors' noise), with or without the
/// measured `L_σ·Δi_s` — then its sensors' noise. That is a difference of one value per window
/// end, `e_{k+1} − e_k`: neighbouring windows share one with opposite signs (lag-one
/// correlation −½), windows two or more apart none. Least squares on lag one reads that
/// correlation as a transient that turns by π; on a motor whose `R_R·|i|·T_window` is not
/// well above `L_σ` times the current's noise (the population's 153 kW member: 1.1 mWb against
/// 0.55 mWb) it read a rotor at rest as turning beyond the overspeed level. `c₂` and `c₃` hold
/// the transient alone, `c_L = z^L·S` of it (`S` its variance), so their ratio is `z` — its angle and its length
/// — unbiased by that noise.
///
/// **Resolved.** The lags carry the noise too. Over `n` triples, with `V = Σ|d_k − m₀|²` the
/// windows' variance — the transient's `S = c₂/z²` (real: `c_L = z^L·S`) and the noise's `N =
/// V − S` — each `c_L` is off by the noise against itself, `1.5·N²/n` in variance (Bartlett's
/// `(1 + 2ρ₁²)/n` for a lag beyond the noise's lag-one correlation `ρ₁` = −½), and by the
/// noise against the transient, at most `2S·N/n` (less for the differenced part of the noise,
/// whose power where a slow transient turns is small; not for a white part — with that
/// reduction taken a campaign run of the population's 6.3 kW member read a rotor at rest as
/// turning). Both tests at `K` = [`SEARCH_TURN_SIGMAS`] of those: the transient is there,
/// `n·min(|c₂|², |c₃|²) ≥ K²·1.5·N²`, and its angle `θ` (a window's) is resolved, `n·θ²·|c₃|²
/// ≥ K²·N·(1.5·N + 2S)` (the angle of `c₃/c₂` is off by the lags' error over `|c₃|`, `|z| ≤
/// 1`). `S` is taken with `|z|` no less than the fastest decay the drive allows the rotor (its
/// rotor-resistance range's top): where the noise is comparable to the transient, `|c₃|/|c₂|`
/// reads anything, and a small `|z|` made `S` all of `V` and the test void. A rotor at rest,
/// whose transient does not turn and hardly changes over the search, is at rest where the
/// noise is comparable to it. The bound that noise sets: a turn of `θ ≈
/// K·√(N·(1.5·N + 2S)/n)/|c₃|` per window and less is not read (the rotor is magnetized as at
/// rest), and a turn above it is read only as well as the noise lets it — on that member within
/// 15 % at base speed (unit test `the_windows_own_noise_is_not_read_as_a_turn`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SpeedSearch {
    /// `Σ d_{k+3}·d*_k` and `Σ d_{k+2}·d*_k` over the triples.
    cross3: AlphaBeta,
    cross2: AlphaBeta,
    /// `Σ d_{k+3}`, `Σ d_{k+2}` and `Σ d_k` over the triples.
    sum3: AlphaBeta,
    sum2: AlphaBeta,
    sum0: AlphaBeta,
    /// `Σ |d_k|²` over the triples.
    sq0: f32,
    /// The last three windows' `d` from `origin`, the latest first, and how many windows
    /// there were (the triples summed: three fewer).
    recent: [AlphaBeta; 3],
    windows: u32,
    /// The first window summed: every `d_k` is summed from it (the sums then hold the
    /// transient, not the bias beside it — see [`SpeedSearch::window`]).
    origin: AlphaBeta,
    /// The first window is over (it holds the current's rise from zero: not used).
    started: bool,
    /// The voltage model's change over the window being summed, Wb, and its slow steps.
    pending: AlphaBeta,
    pending_steps: u32,
}

/// How many of their standard deviations the search's lags and angle must be from zero to
/// read the rotor as turning ([`SpeedSearch`]): the normal law's two-sided point of 7·10⁻⁶. The
/// angle of a ratio of two noisy lags has wider tails than the normal law: at the 10⁻⁴ point
/// (3.89) one of 2 000 seeded searches of a rotor at rest at the population's 153 kW member's
/// noise read a turn; at this level none does (unit test
/// `the_windows_own_noise_is_not_read_as_a_turn`).
pub const SEARCH_TURN_SIGMAS: f32 = 4.5;

/// A turn the search read ([`SpeedSearch::read`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Turn {
    /// The electrical speed the rotor flux turned at, rad/s: the fit's `arg z` over the window.
    pub electrical_speed_rad_s: f32,
    /// The rate the transient decayed at, `α = 1/T_r` (1/s): the fit's `|z| = |c₃|/|c₂| =
    /// e^(−α·T_window)` — the rotor's own time constant, read on the turning rotor, where the
    /// magnetizing fit, which needs it at rest, cannot run; `None` without a decay (`|z| ≥
    /// 1`).
    pub decay_rate_per_s: Option<f32>,
}

/// `a·b*`.
fn times_conj(a: AlphaBeta, b: AlphaBeta) -> AlphaBeta {
    AlphaBeta { alpha: a.alpha * b.alpha + a.beta * b.beta, beta: a.beta * b.alpha - a.alpha * b.beta }
}

/// `|a|²`.
fn len2(a: AlphaBeta) -> f32 {
    a.alpha * a.alpha + a.beta * a.beta
}

impl SpeedSearch {
    /// One slow step: `dpsi_s`, the voltage model's `∫(u_s − R_s·i_s)dt` over it (Wb); a
    /// window is `span` slow steps. The first window is not used — it holds the current's rise
    /// from zero, whose `L_σ·Δi` is as wrong as the leakage estimate (drive.toml's campaign
    /// corner with L × 0.6 read a rotor at rest as turning).
    pub fn step(&mut self, dpsi_s: AlphaBeta, span: u32) {
        self.pending = self.pending + dpsi_s;
        self.pending_steps += 1;
        if self.pending_steps >= span {
            let d = core::mem::take(&mut self.pending);
            self.pending_steps = 0;
            if core::mem::replace(&mut self.started, true) {
                self.window(d);
            }
        }
    }

    /// One window: `d`, the voltage model's change over it (Wb), summed from the first
    /// window's. The fit is the same from any origin (the means take the shift), and its raw
    /// sums in f32 lose what they hold to cancellation when a constant bias much larger than
    /// the transient sits in every window (the inverter's dead-time error beside a rotor
    /// resistance's drop `R_R·|i|` of a fraction of a volt).
    fn window(&mut self, d: AlphaBeta) {
        if self.windows == 0 {
            self.origin = d;
        }
        let d = d - self.origin;
        self.windows = self.windows.saturating_add(1);
        let [d1, d2, d3] = self.recent;
        if self.windows > 3 {
            self.cross3 = self.cross3 + times_conj(d, d3);
            self.cross2 = self.cross2 + times_conj(d1, d3);
            self.sum3 = self.sum3 + d;
            self.sum2 = self.sum2 + d1;
            self.sum0 = self.sum0 + d3;
            self.sq0 += len2(d3);
        }
        self.recent = [d, d1, d2];
    }

    /// What the search read over windows of `window_s`, its transient decaying at most at
    /// `alpha_max_per_s`: the turn, or `None` before two triples of windows, or when the
    /// transient or its angle is within the noise's ([`SpeedSearch`]).
    pub fn read(&self, window_s: f32, alpha_max_per_s: f32) -> Option<Turn> {
        let (c3, c2, v, n) = self.fit()?;
        let z = times_conj(c3, c2);
        let angle = atan2(z.beta, z.alpha);
        let (c3_len2, c2_len2) = (len2(c3), len2(c2));
        let z_len2 = c3_len2 / c2_len2;
        // The transient's variance S = |c₂|/|z|², |z| within [e^(−α_max·T), 1].
        let z_min = 1.0 - alpha_max_per_s * window_s; // ≤ e^(−α_max·T)
        let transient = crate::num::sqrt_f32(c2_len2) / z_len2.limit(z_min * z_min, 1.0);
        let k2 = SEARCH_TURN_SIGMAS * SEARCH_TURN_SIGMAS;
        let noise = (v - transient).max(0.0);
        let there = n * c2_len2.min(c3_len2) >= k2 * 1.5 * noise * noise;
        let resolved = n * angle * angle * c3_len2 >= k2 * noise * (1.5 * noise + 2.0 * transient);
        // The decay: |z| = e^(−α·T_window).
        let alpha = -ln_near_one(crate::num::sqrt_f32(z_len2)) / window_s;
        (there && resolved).then_some(Turn {
            electrical_speed_rad_s: angle / window_s,
            decay_rate_per_s: crate::num::finite_positive(alpha).then_some(alpha),
        })
    }

    /// The fit: the lags `c₃` and `c₂`, the variance `Σ|d_k − m₀|²` and the triples; `None`
    /// before two triples, or without a transient.
    fn fit(&self) -> Option<(AlphaBeta, AlphaBeta, f32, f32)> {
        let triples = self.windows.saturating_sub(3);
        if triples < 2 {
            return None;
        }
        let n = triples as f32;
        let lag = |cross: AlphaBeta, sum: AlphaBeta| {
            let m = times_conj(sum, self.sum0);
            AlphaBeta { alpha: cross.alpha - m.alpha / n, beta: cross.beta - m.beta / n }
        };
        let (c3, c2) = (lag(self.cross3, self.sum3), lag(self.cross2, self.sum2));
        let variance = self.sq0 - len2(self.sum0) / n;
        let c2_len2 = len2(c2);
        (c2_len2 > 0.0 && c2_len2.is_finite()).then_some((c3, c2, variance, n))
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

    /// A search over `windows` windows of `t` s of the rotor flux's transient under a held
    /// current from a rotor without flux (`ψ_R(t) − ψ_∞ = −ψ_∞·e^((−α + jω)t)`, `ψ_∞ =
    /// R_R·i/(α − jω)`, `drop_v` = `R_R·i`), plus a constant bias (`bias_v`: a stator
    /// resistance's error drop) and the windows' own noise: `e_{k+1} − e_k`, `e` normal with
    /// `noise_wb` per component (seeded).
    fn search_of(
        (drop_v, alpha, t, windows): (f64, f64, f64, usize),
        w_e: f64,
        bias_v: f64,
        (noise_wb, seed): (f64, u64),
    ) -> SpeedSearch {
        let n = alpha * alpha + w_e * w_e;
        let psi_inf = (drop_v * alpha / n, drop_v * w_e / n);
        let psi = |t: f64| {
            let (m, a) = ((-alpha * t).exp(), w_e * t);
            (
                psi_inf.0 * (1.0 - m * a.cos()) + psi_inf.1 * m * a.sin(),
                psi_inf.1 * (1.0 - m * a.cos()) - psi_inf.0 * m * a.sin(),
            )
        };
        let mut state = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
        let mut normal = || {
            // The sum of twelve uniforms less six: unit variance.
            (0..12)
                .map(|_| {
                    state =
                        state.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
                    (state >> 11) as f64 / (1u64 << 53) as f64
                })
                .sum::<f64>()
                - 6.0
        };
        let mut s = SpeedSearch::default();
        s.step(AlphaBeta::default(), 1);
        let mut e = (noise_wb * normal(), noise_wb * normal());
        for k in 0..windows {
            let (p0, p1) = (psi(k as f64 * t), psi((k + 1) as f64 * t));
            let next = (noise_wb * normal(), noise_wb * normal());
            let d = AlphaBeta {
                alpha: (p1.0 - p0.0 + bias_v * t + next.0 - e.0) as f32,
                beta: (p1.1 - p0.1 + next.1 - e.1) as f32,
            };
            e = next;
            s.step(d, 1);
        }
        s
    }

    /// The rotor flux's transient under a held current, exactly: windows of its change turn
    /// at the rotor's speed, both ways, and a rotor at rest is not read as turning — with a
    /// constant bias too (a stator resistance 10 % off, 1 V; 3 V at 20 rad/s), which the
    /// fit's means take; and they decay at the rotor's `α` (within 1 %).
    #[test]
    fn the_held_current_transient_turns_at_the_rotors_speed() {
        // drive.toml's motor in the inverse-Γ form: R_R 20.8 Ω, L_M 1.34 H (α 15.5 1/s),
        // its 0.63 A magnetizing current, the slow period 0.5 ms, one T_r of windows.
        let (alpha, t) = (15.5f64, 5e-4f64);
        let motor = (20.8 * 0.63, alpha, t, (1.0 / (alpha * t)).ceil() as usize);
        for (w_e, bias_v, tolerance) in [
            (392.0, 0.0, 1e-3),
            (-196.0, 0.0, 1e-3),
            (20.0, 0.0, 1e-3),
            (0.0, 0.0, 1e-6),
            (196.0, 1.0, 1e-3),
            (-20.0, 3.0, 1e-2),
        ] {
            let turn = search_of(motor, w_e, bias_v, (0.0, 0)).read(t as f32, 2.0 * alpha as f32);
            let got = f64::from(turn.map_or(0.0, |t| t.electrical_speed_rad_s));
            let error = (got - w_e).abs() / w_e.abs().max(1.0);
            assert!(error < tolerance, "{w_e} rad/s, bias {bias_v} V: {got}");
            if w_e != 0.0 {
                let decay = f64::from(turn.and_then(|t| t.decay_rate_per_s).unwrap());
                assert!(
                    (decay / alpha - 1.0).abs() < 1e-2,
                    "{w_e} rad/s, bias {bias_v} V: α {decay} of {alpha}"
                );
            }
        }
    }

    /// The windows' own noise (what the current does at their ends) is not a turning rotor:
    /// alone, and beside a rotor at rest whose transient is that noise's size — the
    /// population's 153 kW member (R_R·i 0.71 V, α 0.71 1/s, windows of 1.5 ms; 0.28 mWb of
    /// noise at each end, the windows' variance the drive's search measured on that member,
    /// 0.3 µWb² per window) — in none of 2 000 seeded searches each. The same rotor turning at
    /// base speed (314 rad/s electrical) both ways and at twice it is read in every one of 20
    /// searches, within 20 % (the noise's bound, [`SpeedSearch`]).
    #[test]
    fn the_windows_own_noise_is_not_read_as_a_turn() {
        let (alpha, t) = (0.707f64, 1.5e-3f64);
        let big = (0.71, alpha, t, (1.0 / (alpha * t)).ceil() as usize);
        let (noise_wb, a_max) = (2.75e-4, 2.0 * alpha as f32);
        for seed in 0..2000 {
            let noise = search_of((0.0, alpha, t, big.3), 0.0, 0.0, (noise_wb, seed));
            assert_eq!(noise.read(t as f32, a_max), None, "noise, seed {seed}");
            let rest = search_of(big, 0.0, 11.0, (noise_wb, seed));
            let read = rest.read(t as f32, a_max).map_or(0.0, |t| t.electrical_speed_rad_s);
            assert_eq!(read, 0.0, "at rest, seed {seed}");
        }
        for w_e in [314.0, -314.0, 628.0] {
            let mut worst = 0.0f64;
            for seed in 0..20 {
                let s = search_of(big, w_e, 11.0, (noise_wb, seed));
                let got = f64::from(s.read(t as f32, a_max).unwrap().electrical_speed_rad_s);
                worst = worst.max((got / w_e - 1.0).abs());
            }
            eprintln!("{w_e} rad/s: read within {:.1} %", 100.0 * worst);
            assert!(worst < 0.2, "{w_e} rad/s: speed off by {worst}");
        }
    }
}
