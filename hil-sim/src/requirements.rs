//! The campaign's judge against the user's `[requirements]` (issue 51): each run's speed
//! steps, load step and steady state measured on the simulated machine (its speed, its
//! electromagnetic torque, its rotor flux — not the drive's estimates), each against what the
//! file asks, and the step times against the *physical least*: the run's motor accelerating
//! at the most torque its T-equivalent circuit gives on the bus and the current limit
//! ([`crate::envelope::physical_limit_nm`]), at most τ_max — computed from the motor alone,
//! not from the drive's model of it nor from its speed law.
//!
//! Scales (module docs of `drive_file::requirements`): speeds are fractions of the drive's
//! motor's base speed on the campaign's bus ([`crate::envelope::base_speed_rad_s`], the
//! whole linear voltage), plus one count of the encoder's speed resolution — the least speed
//! error the board can see (the speed loop closes on it).
//!
//! **The board bounds a step and a load step too**, not only the motor's torque. The speed
//! loop closes on the encoder's estimate, whose one count toggles the torque by `k_p·Δω_q`:
//! no speed loop on this board may have a gain above [`Scales::speed_gain_limit_nm_s`]
//! ([`ENCODER_NOISE_FRACTION`]`·τ_max/Δω_q`), so none answers a speed error `e` with more
//! than `k_max·e` of torque. The least times are those of a step under
//! `min(T_phys(ω) − B·ω, k_max·|ω* − ω|)` ([`least_step_times`]): the motor's torque limit
//! for a large step, the fastest loop the board allows for a small one (its exponential
//! tail, `J/k_max` a time constant). A load step `ΔT` may move the speed by `ΔT/k_max`
//! ([`Scales::least_dip_rad_s`]): a proportional loop at `k_max` settles there, a critically
//! damped PI of that `k_p` peaks at `2/e` ≈ 0.74 of it — and that PI, the fastest integral
//! action the board allows, sets the least recovery ([`Scales::least_recovery_s`]).

use drive_file::requirements::{Requirement, Requirements, SETTLING_BAND_FRACTION};

/// The campaign's torque-ripple limit (peak to peak about the trend over
/// [`STEADY_WINDOW_S`]), × τ_max (`campaign::RIPPLE_FRACTION`).
pub const RIPPLE_FRACTION: f64 = 0.1;

/// One count of speed resolution may move the torque by at most this fraction of τ_max:
/// a quarter of the ripple the campaign allows ([`RIPPLE_FRACTION`], peak to peak). The
/// estimate toggles between neighbouring counts, so the speed law's torque toggles by
/// `k_p·Δω_q` — a square wave the loop carries round and the current loops add their own
/// noise to; the quarter leaves the rest of the allowance to them. `design tune`
/// bounds its speed gains by it; the judge derives from it the fastest speed loop a board
/// allows ([`Scales::speed_gain_limit_nm_s`]). Measured over the population (`population
/// run --members 24 --shipped --pwm 4000,10000,20000`): at a quarter, one drive of 87
/// oscillates in 2 of its 200 runs; at half, 12 drives in 60 runs, the shipped DeLorenzo and
/// EM_Synergy drives among them.
pub const ENCODER_NOISE_FRACTION: f64 = RIPPLE_FRACTION / 4.0;

/// The last this long of a run is its steady state (speed error, torque and flux accuracy),
/// s — also the campaign's oscillation window (`campaign::RIPPLE_WINDOW_S`).
pub const STEADY_WINDOW_S: f64 = 0.05;
/// Speed points of the physical least time's integral over a step ([`least_step_times`]):
/// 100, so that 10 % and 90 % of the step are grid points.
pub const LEAST_TIME_POINTS: u32 = 100;
/// Speeds at which [`least_step_times`] asks for the torque, evenly over the step (its ends
/// included); between them the torque is interpolated linearly. Each ask is a search over
/// slips (4 000 of them, a bisection each on a saturating machine): asked at every
/// integration point, a campaign of 10 000 runs spent 4.6× longer per period.
pub const LEAST_TIME_TORQUE_NODES: u32 = 11;

/// Fixed-point steps of [`Scales::least_recovery_s`]'s `x = ln(2R) + ln x`: each shrinks the
/// error by `1/x` (< 1/2 where it starts, `x ≥ 2`), so 40 leave none a `f64` holds.
const RECOVERY_ITERATIONS: u32 = 40;

/// What the judge reads of one row (one slow period) of a run.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Sample {
    /// Time, s.
    pub t_s: f64,
    /// The machine's speed, mechanical rad/s.
    pub omega_m_rad_s: f64,
    /// The speed reference, mechanical rad/s.
    pub omega_ref_rad_s: f64,
    /// The machine's electromagnetic torque, N·m.
    pub torque_nm: f64,
    /// The torque the drive commands, N·m.
    pub torque_ref_nm: f64,
    /// The machine's rotor-flux magnitude, Wb.
    pub psi_r_wb: f64,
    /// The drive's rotor-flux reference, Wb.
    pub psi_ref_wb: f64,
}

/// The scales the requirements are stated in, for one campaign.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scales {
    /// The motor's base speed on the bus, mechanical rad/s.
    pub base_speed_rad_s: f64,
    /// One count of the encoder's speed resolution, rad/s.
    pub speed_quantum_rad_s: f64,
    /// The drive's torque limit τ_max, N·m.
    pub tau_max_nm: f64,
    /// The rated rotor flux (`controller.flux_ref_wb`), Wb.
    pub flux_rated_wb: f64,
}

impl Scales {
    /// The speed error allowed at steady state, rad/s.
    pub fn speed_error_allowed_rad_s(&self, r: &Requirements) -> f64 {
        r.speed_error_fraction * self.base_speed_rad_s + self.speed_quantum_rad_s
    }

    /// The deviation allowed after a load step of `load_step_nm`, rad/s: the stated fraction
    /// of the base speed, or the least the board allows ([`Scales::least_dip_rad_s`]) if
    /// that is more — plus one count.
    pub fn dip_allowed_rad_s(&self, r: &Requirements, load_step_nm: f64) -> f64 {
        (r.load_dip_fraction * self.base_speed_rad_s).max(self.least_dip_rad_s(load_step_nm))
            + self.speed_quantum_rad_s
    }

    /// The most speed gain a loop closing on this board's encoder may have, N·m per rad/s:
    /// one count moves the torque by [`ENCODER_NOISE_FRACTION`]`·τ_max` (∞ without a count).
    pub fn speed_gain_limit_nm_s(&self) -> f64 {
        speed_gain_limit_nm_s(self.tau_max_nm, self.speed_quantum_rad_s)
    }

    /// The least speed deviation a load step of `load_step_nm` makes under a loop of at most
    /// [`Scales::speed_gain_limit_nm_s`]: `|ΔT|/k_max`, rad/s.
    pub fn least_dip_rad_s(&self, load_step_nm: f64) -> f64 {
        load_step_nm.abs() / self.speed_gain_limit_nm_s()
    }

    /// The least time after a load step of `load_step_nm` on inertia `j_kgm2` until the speed
    /// is back within the speed-error band `r` allows, s. No loop knows the load before its
    /// integral has learnt it: the reference is the fastest PI the board allows, `k_p =
    /// k_max` and `k_i = k_max²/(4J)` (a double pole at `ω_0 = k_max/(2J)`, critically
    /// damped), whose deviation is `(ΔT/J)·t·e^{−ω_0·t}` — at most `2/e·ΔT/k_max`, then back
    /// within the band `b` where `x·e^{−x} = k_max·b/(2ΔT)`, `x = ω_0·t > 1`; 0 for a
    /// deviation that never leaves the band.
    pub fn least_recovery_s(&self, r: &Requirements, load_step_nm: f64, j_kgm2: f64) -> f64 {
        let k = self.speed_gain_limit_nm_s();
        // ln(1/(x·e^{−x})) = x − ln x: solve x = ln(2R) + ln x from above (a contraction
        // for x > 1), R the least dip over the band.
        let log_2r = (2.0 * self.least_dip_rad_s(load_step_nm) / self.speed_error_allowed_rad_s(r)).ln();
        // (No count, k = ∞: no least dip, ln 0 = −∞.)
        if log_2r.is_nan() || log_2r <= 1.0 {
            return 0.0;
        }
        let mut x = 2.0 * log_2r;
        for _ in 0..RECOVERY_ITERATIONS {
            x = log_2r + x.ln();
        }
        x * 2.0 * j_kgm2 / k
    }

    /// A step of `step_rad_s`'s settling band, × the step: [`SETTLING_BAND_FRACTION`], or the
    /// speed-error band the requirements allow if that is wider (a drive asked to regulate
    /// to ±x has settled once within ±x).
    pub fn settling_band_fraction(&self, r: &Requirements, step_rad_s: f64) -> f64 {
        SETTLING_BAND_FRACTION
            .max(self.speed_error_allowed_rad_s(r) / step_rad_s.abs().max(f64::MIN_POSITIVE))
    }
}

/// The most speed gain a loop may have when one count of its speed estimate is
/// `speed_quantum_rad_s` and its torque limit `tau_max_nm`, N·m per rad/s:
/// [`ENCODER_NOISE_FRACTION`]`·τ_max/Δω_q` (∞ for a zero count).
pub fn speed_gain_limit_nm_s(tau_max_nm: f64, speed_quantum_rad_s: f64) -> f64 {
    if speed_quantum_rad_s > 0.0 {
        ENCODER_NOISE_FRACTION * tau_max_nm / speed_quantum_rad_s
    } else {
        f64::INFINITY
    }
}

/// A speed step's response.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepResponse {
    /// 10 → 90 % of the step, s (∞: not reached before the step's window ended).
    pub rise_s: f64,
    /// Largest excursion beyond the target, × the step (0: none).
    pub overshoot_fraction: f64,
    /// From the step until the speed stays within the band, s (∞: outside at the window's
    /// end).
    pub settling_s: f64,
}

/// The step from `from` to `to` (rad/s) at `t0_s`, measured on `samples` up to `t_end_s`
/// (exclusive), with a settling band of `band_fraction` × the step.
pub fn step_response(
    samples: &[Sample],
    t0_s: f64,
    t_end_s: f64,
    from: f64,
    to: f64,
    band_fraction: f64,
) -> StepResponse {
    let step = to - from;
    let rows: Vec<&Sample> = samples.iter().filter(|s| s.t_s >= t0_s && s.t_s < t_end_s).collect();
    let progress = |s: &Sample| (s.omega_m_rad_s - from) / step;
    let first = |fraction: f64| rows.iter().find(|s| progress(s) >= fraction).map(|s| s.t_s);
    let rise_s = match (first(0.1), first(0.9)) {
        (Some(a), Some(b)) => b - a,
        _ => f64::INFINITY,
    };
    let overshoot_fraction = rows.iter().map(|s| progress(s) - 1.0).fold(0.0, f64::max);
    let settling_s = settled_after(&rows, t0_s, |s| beyond((progress(s) - 1.0).abs(), band_fraction));
    StepResponse { rise_s, overshoot_fraction, settling_s }
}

/// From `t0_s` until the first of `rows` after the last one `outside` (0: none outside; ∞:
/// the last row is outside, or there are none).
fn settled_after(rows: &[&Sample], t0_s: f64, outside: impl Fn(&Sample) -> bool) -> f64 {
    match rows.iter().rposition(|s| outside(s)) {
        None if rows.is_empty() => f64::INFINITY,
        None => 0.0,
        Some(k) => rows.get(k + 1).map_or(f64::INFINITY, |s| s.t_s - t0_s),
    }
}

/// `x` above `limit`, or NaN.
fn beyond(x: f64, limit: f64) -> bool {
    x.is_nan() || x > limit
}

/// A load step's response.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LoadResponse {
    /// Largest |ω − ω*| after the step, rad/s.
    pub dip_rad_s: f64,
    /// From the step until |ω − ω*| stays within the band, s (∞: outside at the end).
    pub recovery_s: f64,
}

/// The load step at `t0_s`, measured on `samples` from then on, with a band of `band_rad_s`.
pub fn load_response(samples: &[Sample], t0_s: f64, band_rad_s: f64) -> LoadResponse {
    let rows: Vec<&Sample> = samples.iter().filter(|s| s.t_s >= t0_s).collect();
    let error = |s: &Sample| (s.omega_m_rad_s - s.omega_ref_rad_s).abs();
    // A NaN speed is the largest dip of all.
    let dip_rad_s = rows
        .iter()
        .map(|s| error(s))
        .fold(0.0, |a: f64, e| if a.is_nan() || e.is_nan() { f64::NAN } else { a.max(e) });
    let recovery_s = settled_after(&rows, t0_s, |s| beyond(error(s), band_rad_s));
    LoadResponse { dip_rad_s, recovery_s }
}

/// The steady state: means over the last [`STEADY_WINDOW_S`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Steady {
    /// |mean(ω − ω*)|, rad/s.
    pub speed_error_rad_s: f64,
    /// |mean(τ − τ*)|, N·m.
    pub torque_error_nm: f64,
    /// |mean(|ψ_r| − ψ_r*)|, Wb.
    pub flux_error_wb: f64,
}

/// [`Steady`] of `samples` (NaN where the window is empty).
pub fn steady(samples: &[Sample]) -> Steady {
    let end = samples.last().map_or(f64::NAN, |s| s.t_s);
    let w: Vec<&Sample> = samples.iter().filter(|s| s.t_s > end - STEADY_WINDOW_S).collect();
    let n = w.len() as f64;
    let mean = |f: &dyn Fn(&Sample) -> f64| (w.iter().map(|s| f(s)).sum::<f64>() / n).abs();
    Steady {
        speed_error_rad_s: mean(&|s| s.omega_m_rad_s - s.omega_ref_rad_s),
        torque_error_nm: mean(&|s| s.torque_nm - s.torque_ref_nm),
        flux_error_wb: mean(&|s| s.psi_r_wb - s.psi_ref_wb),
    }
}

/// The least times of a step from `from` to `to` (mechanical rad/s) with no load on inertia
/// `j_kgm2` and friction `b_nms`, by a speed loop of at most `gain_nm_s` (N·m per rad/s;
/// [`Scales::speed_gain_limit_nm_s`], ∞ for none): (10 → 90 % rise, time into the band of
/// `band_fraction` × the step), s. `torque_nm(ω, motoring)` is the most torque the motor
/// gives at ω (its physical limit, at most τ_max), motoring or braking. The net torque is
/// `min(T(ω) − B·ω·sign, k·|to − ω|)` — the torque limit, or the loop's answer to the error
/// left, friction compensated — and `t = ∫ J dω/(that)` by the midpoint rule over
/// [`LEAST_TIME_POINTS`] speeds; ∞ where the motor cannot go on.
pub fn least_step_times(
    torque_nm: impl Fn(f64, bool) -> f64,
    j_kgm2: f64,
    b_nms: f64,
    gain_nm_s: f64,
    from: f64,
    to: f64,
    band_fraction: f64,
) -> (f64, f64) {
    let n = LEAST_TIME_POINTS;
    let d = (to - from) / f64::from(n);
    let dir = d.signum();
    // The torque at the nodes, each side of zero speed where the step crosses it (motoring
    // and braking differ there).
    let m = LEAST_TIME_TORQUE_NODES - 1;
    let node_speed = |i: u32| from + (to - from) * f64::from(i) / f64::from(m);
    let nodes: Vec<(f64, f64)> = (0..=m)
        .map(|i| {
            let w = node_speed(i);
            (torque_nm(w.abs(), w * dir >= 0.0), torque_nm(w.abs(), w * dir > 0.0))
        })
        .collect();
    let torque_at = |w: f64| {
        let x = ((w - from) / (to - from) * f64::from(m)).clamp(0.0, f64::from(m));
        let i = (x.floor() as usize).min(m as usize - 1);
        let f = x - i as f64;
        let motoring = w * dir >= 0.0;
        let pick = |k: usize| {
            nodes.get(k).map_or(0.0, |&(at_or_past, past)| if motoring { at_or_past } else { past })
        };
        // Across zero speed the two sides are not interpolated into each other.
        let (a, b) = (pick(i), pick(i + 1));
        let (wa, wb) = (node_speed(i as u32), node_speed(i as u32 + 1));
        if wa * dir < 0.0 && wb * dir > 0.0 { torque_nm(w.abs(), motoring) } else { a + f * (b - a) }
    };
    let mut t = vec![0.0f64; n as usize + 1];
    for k in 0..n as usize {
        let w = from + (k as f64 + 0.5) * d;
        let accel = (torque_at(w) - dir * b_nms * w).min(gain_nm_s * (to - w).abs());
        let dt = if accel > 0.0 { j_kgm2 * d.abs() / accel } else { f64::INFINITY };
        t[k + 1] = t[k] + dt;
    }
    let at = |fraction: f64| {
        let x = fraction * f64::from(n);
        let k = (x.floor() as usize).min(n as usize - 1);
        let f = x - k as f64;
        // ∞ beyond a speed the motor cannot pass (and no ∞ − ∞ on a grid point).
        if f == 0.0 || t[k + 1].is_infinite() {
            if f == 0.0 { t[k] } else { f64::INFINITY }
        } else {
            t[k] + f * (t[k + 1] - t[k])
        }
    };
    let rise = at(0.9) - at(0.1);
    (rise, at((1.0 - band_fraction).max(0.0)))
}

/// One requirement judged on one run: its worst measured value and what was allowed there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Measure {
    /// The requirement.
    pub requirement: Requirement,
    /// Measured, in the requirement's unit (a fraction, or s).
    pub value: f64,
    /// Allowed, in the same unit.
    pub allowed: f64,
}

impl Measure {
    /// Met (a NaN is not).
    pub fn met(&self) -> bool {
        self.value <= self.allowed
    }

    /// `allowed/value`: above 1 met, with that margin; below 1 missed.
    pub fn margin(&self) -> f64 {
        if self.value.is_nan() {
            f64::NAN
        } else if self.value > 0.0 {
            self.allowed / self.value
        } else {
            f64::INFINITY
        }
    }
}

/// The worst of `measures` for each requirement — the least margin, a NaN worst of all —
/// each with its tag (a run index, or nothing), in [`Requirement::ALL`]'s order.
pub fn worst_each_tagged<K>(measures: impl IntoIterator<Item = (K, Measure)>) -> Vec<(K, Measure)> {
    let mut worst: Vec<(K, Measure)> = Vec::new();
    for (k, m) in measures {
        match worst.iter_mut().find(|(_, w)| w.requirement == m.requirement) {
            Some(w) if m.margin().is_nan() || m.margin() < w.1.margin() => *w = (k, m),
            Some(_) => {}
            None => worst.push((k, m)),
        }
    }
    worst.sort_by_key(|(_, m)| m.requirement);
    worst
}

/// [`worst_each_tagged`] without tags.
pub fn worst_each(measures: impl IntoIterator<Item = Measure>) -> Vec<Measure> {
    worst_each_tagged(measures.into_iter().map(|m| ((), m))).into_iter().map(|(_, m)| m).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(t0: f64, rise_s: f64, to: f64, overshoot: f64) -> Vec<Sample> {
        (0..2000)
            .map(|k| {
                let t = k as f64 * 1e-3;
                let x = ((t - t0) / rise_s).clamp(0.0, 1.0);
                // A bump of `overshoot` after the ramp, decaying in 50 ms.
                let bump = if t > t0 + rise_s { overshoot * (-(t - t0 - rise_s) / 0.05).exp() } else { 0.0 };
                Sample { t_s: t, omega_m_rad_s: to * (x + bump), omega_ref_rad_s: to, ..Sample::default() }
            })
            .collect()
    }

    /// A linear ramp over 0.5 s: 10 → 90 % in 0.4 s; its overshoot and settling measured.
    #[test]
    fn a_ramp_step_is_measured() {
        let s = ramp(0.1, 0.5, 100.0, 0.1);
        let r = step_response(&s, 0.1, 2.0, 0.0, 100.0, 0.02);
        assert!((r.rise_s - 0.4).abs() < 2e-3, "{r:?}");
        assert!((r.overshoot_fraction - 0.1).abs() < 2e-3, "{r:?}");
        // The bump falls below 2 % after 0.05·ln(5) = 80 ms.
        assert!((r.settling_s - (0.5 + 0.05 * 5f64.ln())).abs() < 2e-3, "{r:?}");
        // A window that ends before the ramp does: neither risen nor settled.
        let short = step_response(&s, 0.1, 0.4, 0.0, 100.0, 0.02);
        assert!(short.rise_s.is_infinite() && short.settling_s.is_infinite(), "{short:?}");
    }

    /// A dip of 10 rad/s recovering with a 0.1 s time constant: back within 1 rad/s after
    /// 0.1·ln 10 s.
    #[test]
    fn a_load_dip_is_measured() {
        let s: Vec<Sample> = (0..1000)
            .map(|k| {
                let t = k as f64 * 1e-3;
                let e = if t >= 0.5 { 10.0 * (-(t - 0.5) / 0.1).exp() } else { 0.0 };
                Sample { t_s: t, omega_m_rad_s: 50.0 - e, omega_ref_rad_s: 50.0, ..Sample::default() }
            })
            .collect();
        let r = load_response(&s, 0.5, 1.0);
        assert!((r.dip_rad_s - 10.0).abs() < 1e-9, "{r:?}");
        assert!((r.recovery_s - 0.1 * 10f64.ln()).abs() < 2e-3, "{r:?}");
        // A droop that stays: never recovered.
        let droop: Vec<Sample> = s.iter().map(|x| Sample { omega_m_rad_s: 45.0, ..*x }).collect();
        assert!(load_response(&droop, 0.5, 1.0).recovery_s.is_infinite());
        let nan: Vec<Sample> = s.iter().map(|x| Sample { omega_m_rad_s: f64::NAN, ..*x }).collect();
        assert!(load_response(&nan, 0.5, 1.0).dip_rad_s.is_nan());
    }

    /// A constant torque T on J from rest: ω = T·t/J, so 10 → 90 % of a step Δ takes
    /// 0.8·J·Δ/T and the 2 % band 0.98·J·Δ/T; a torque that vanishes never gets there.
    #[test]
    fn least_times_of_a_constant_torque() {
        let (rise, settle) = least_step_times(|_, _| 2.0, 0.01, 0.0, f64::INFINITY, 0.0, 100.0, 0.02);
        assert!((rise - 0.8 * 0.01 * 100.0 / 2.0).abs() < 1e-12, "{rise}");
        assert!((settle - 0.98 * 0.01 * 100.0 / 2.0).abs() < 1e-12, "{settle}");
        // A reversal: braking torque to 0, motoring beyond, the same magnitude both ways.
        let (r, _) = least_step_times(
            |_, motoring| if motoring { 2.0 } else { 1.0 },
            0.01,
            0.0,
            f64::INFINITY,
            50.0,
            -50.0,
            0.02,
        );
        // 10 → 50 % at 1 N·m (braking), 50 → 90 % at 2 N·m.
        assert!((r - (0.01 * 40.0 / 1.0 + 0.01 * 40.0 / 2.0)).abs() < 1e-12, "{r}");
        let (r, s) = least_step_times(
            |w, _| if w < 50.0 { 2.0 } else { 0.0 },
            0.01,
            0.0,
            f64::INFINITY,
            0.0,
            100.0,
            0.02,
        );
        assert!(r.is_infinite() && s.is_infinite());
    }

    /// Under a gain-limited loop: a small step is the first-order `k/J` response (10 → 90 % in
    /// `ln 9·J/k`, into a 2 % band in `ln 50·J/k`); a large one runs at the torque limit until
    /// the error falls to `T/k`, then takes the same tail. A load step's least dip is `ΔT/k`.
    #[test]
    fn least_times_of_a_gain_limited_loop() {
        let (j, k) = (0.01, 0.5);
        let (rise, settle) = least_step_times(|_, _| 1e9, j, 0.0, k, 0.0, 10.0, 0.02);
        assert!((rise / (9f64.ln() * j / k) - 1.0).abs() < 2e-3, "{rise}");
        // The midpoint rule under-reads the log's integral near the band by ≈ 0.3 % at 100 points.
        assert!((settle / (50f64.ln() * j / k) - 1.0).abs() < 5e-3, "{settle}");
        // 100 rad/s at 2 N·m: the torque binds down to an error of 4 rad/s (2/0.5), 96 rad/s
        // in 0.48 s, then the exponential from 4 rad/s to the band's 2 rad/s, (J/k)·ln 2.
        let (_, settle) = least_step_times(|_, _| 2.0, j, 0.0, k, 0.0, 100.0, 0.02);
        assert!((settle - (j * 96.0 / 2.0 + j / k * 2f64.ln())).abs() < 1e-3, "{settle}");
        // Friction does not leave a gain-limited loop short of the target (it is compensated).
        let (rise_b, _) = least_step_times(|_, _| 1e9, j, 0.05, k, 0.0, 10.0, 0.02);
        assert!((rise_b - rise).abs() < 1e-12);
        let sc =
            Scales { base_speed_rad_s: 100.0, speed_quantum_rad_s: 0.4, tau_max_nm: 8.0, flux_rated_wb: 1.0 };
        assert!((sc.speed_gain_limit_nm_s() - ENCODER_NOISE_FRACTION * 8.0 / 0.4).abs() < 1e-12);
        assert!((sc.least_dip_rad_s(-4.0) - 4.0 / sc.speed_gain_limit_nm_s()).abs() < 1e-12);
        // The stated dip, or the board's least if more, plus one count.
        let r = Requirements::defaults(20e3);
        assert!((sc.dip_allowed_rad_s(&r, 0.0) - (r.load_dip_fraction * 100.0 + 0.4)).abs() < 1e-12);
        assert!((sc.dip_allowed_rad_s(&r, 6.4) - (6.4 / 0.5 + 0.4)).abs() < 1e-12);
        // The critically damped PI at k = 0.5 on J = 0.01 (ω_0 = 25 1/s) after 6.4 N·m: its
        // deviation (ΔT/J)·t·e^{−ω_0·t}, sampled densely, last above the 1.4 rad/s band at
        // the time returned.
        let band = r.speed_error_fraction * 100.0 + 0.4;
        let t = sc.least_recovery_s(&r, 6.4, j);
        let e = |t: f64| 6.4 / j * t * (-25.0 * t).exp();
        let last_out = (1..100_000).map(|i| i as f64 * 1e-5).filter(|&t| e(t) > band).fold(0.0, f64::max);
        assert!((t - last_out).abs() < 2e-5, "{t} {last_out}");
        // A load whose PI deviation (at most 2/e·ΔT/k) stays within the band: none.
        assert_eq!(sc.least_recovery_s(&r, 0.9 * band * 0.5 * std::f64::consts::E / 2.0, j), 0.0);
    }

    /// Each requirement's worst is its least margin; a NaN is the worst of all.
    #[test]
    fn the_worst_of_each_requirement() {
        let m = |requirement, value, allowed| Measure { requirement, value, allowed };
        let w = worst_each([
            m(Requirement::LoadDip, 1.0, 2.0),
            m(Requirement::SpeedError, 0.5, 1.0),
            m(Requirement::LoadDip, 3.0, 2.0),
            m(Requirement::LoadDip, 2.5, 2.0),
        ]);
        assert_eq!(
            w.iter().map(|x| x.requirement).collect::<Vec<_>>(),
            [Requirement::SpeedError, Requirement::LoadDip]
        );
        assert_eq!(w[1].value, 3.0);
        assert!(!w[1].met() && w[0].met());
        let nan = worst_each([m(Requirement::LoadDip, 1.0, 2.0), m(Requirement::LoadDip, f64::NAN, 2.0)]);
        assert!(nan[0].value.is_nan() && !nan[0].met());
    }
}
