//! The sensorless observer's linearised stability (issue 53, deliverable 5): the drive's
//! flux and speed observer (`controller_core::observer`, Hinkkanen, Harnefors and Luomi 2010)
//! as it runs — its discrete update, ported to f64 line for line (the f32 step's rounding would
//! swamp the central differences; the port is held to the drive's step by a test) — fed by the
//! machine's sinusoidal steady state at an operating point, linearised about its equilibrium.
//!
//! **The map.** At stator frequency `ω_s` the machine's current and voltage are
//! `i(t) = I·e^{jω_s t}`, `u(t) = U·e^{jω_s t}` (the T model's steady state for the rotor's
//! electrical speed `ω_m` and the current phasor `I = i_d + j·i_q` in the rotor-flux frame).
//! One observer step covers an interval of `T` with the currents at both ends and the
//! voltage held at the interval's mean (`U·e^{jω_s T/2}·sinc`, here its phasor at the middle).
//! In coordinates turning with `ω_s` — the stator-flux estimate `ẑ = ψ̂_s·e^{−jω_s kT}` and the
//! speed estimate `ω̂` — the step is a time-invariant map `F(ẑ, ω̂)` of three real states. Its
//! fixed point is the observer's steady state (the true flux and speed when its parameters are
//! the machine's; off them where they are not), found by iterating `F`; the spectral radius
//! of `F`'s Jacobian there (central differences) below 1 is the observer's local stability at
//! that point. The same iteration is the time simulation the radius is checked against: a
//! radius above 1 leaves the iteration without a fixed point.
//!
//! **What it covers.** The observer's own error dynamics — the flux correction and the speed
//! adaptation, with the machine's currents given — over a grid of speeds (both directions) and
//! torque-producing currents (motoring and regenerating), with the machine's parameters off
//! the observer's by given factors. Not the loop the observer closes through the field
//! orientation and the speed controller (the current references are taken in the estimated
//! frame, which moves the currents the observer then sees): that coupling is left to the
//! simulated campaign.

use crate::sampled::spectral_radius;
use controller_core::motor::MotorParams;
use controller_core::observer::ZETA_INF;
use nalgebra::DMatrix;
use num_complex::Complex64 as C;

/// The observer's parameters as it runs them (inverse-Γ, from the motor it believes in).
#[derive(Clone, Copy, Debug)]
struct Params {
    ts_s: f64,
    rs_ohm: f64,
    r_sigma_ohm: f64,
    l_sigma_h: f64,
    alpha_per_s: f64,
    speed_bandwidth_rad_s: f64,
}

impl Params {
    fn of(m: &MotorParams, ts_s: f64, speed_bandwidth_rad_s: f64) -> Self {
        let k = m.lm_h() / m.lr_h();
        let (l_m, r_r) = (m.lm_h() * k, m.rr_ohm() * k * k);
        Self {
            ts_s,
            rs_ohm: m.rs_ohm(),
            r_sigma_ohm: m.rs_ohm() + r_r,
            l_sigma_h: m.ls_h() - l_m,
            alpha_per_s: r_r / l_m,
            speed_bandwidth_rad_s,
        }
    }
}

/// One step of `controller_core::observer::FluxObserver`'s update (its `advance`, above the
/// flux floor, adapting), in f64: the stator-flux estimate and the electrical speed estimate
/// after an interval with the currents `i0`, `i1` at its ends and the voltage `u` held.
fn advance(p: &Params, psi_s: C, w: f64, u: C, i0: C, i1: C) -> (C, f64) {
    let t = p.ts_s;
    let i_mid = (i0 + i1) * 0.5;
    let psi_s_mid = psi_s + (u - i0 * p.rs_ohm) * (0.5 * t);
    let psi_r_mid = psi_s_mid - i_mid * p.l_sigma_h;
    let alpha_jw = C::new(p.alpha_per_s, -w);
    let e_rate = i_mid * p.r_sigma_ohm - u - alpha_jw * psi_r_mid;
    let e_int = (i1 - i0) * p.l_sigma_h + e_rate * t;
    let sigma_o = 0.5 * p.alpha_per_s + f64::from(ZETA_INF) * w.abs();
    let k1 = alpha_jw.conj() * (sigma_o / alpha_jw.norm_sqr());
    let psi2 = psi_r_mid.norm_sqr();
    let p_e = psi_r_mid.conj() * e_int;
    let w = w - p.speed_bandwidth_rad_s * p_e.im / psi2;
    let correction = k1 * (e_int + psi_r_mid * p_e.conj() / psi2);
    (psi_s + (u - i_mid * p.rs_ohm) * t + correction, w)
}

/// The T model's sinusoidal steady state at stator frequency `w_s` and electrical rotor speed
/// `w_m` for the stator current phasor `i_s`: the voltage and the stator flux phasors.
fn steady_state(m: &MotorParams, w_s: f64, w_m: f64, i_s: C) -> (C, C) {
    let w_r = w_s - w_m;
    let i_r = C::new(0.0, -w_r * m.lm_h()) * i_s / C::new(m.rr_ohm(), w_r * m.lr_h());
    let psi_s = i_s * m.ls_h() + i_r * m.lm_h();
    (i_s * m.rs_ohm() + C::new(0.0, w_s) * psi_s, psi_s)
}

/// An operating point: the rotor's electrical speed, rad/s, and the stator current in the
/// rotor-flux frame (d: the flux's, q: the torque's; A).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Point {
    /// Electrical rotor speed, rad/s.
    pub omega_m_rad_s: f64,
    /// d-axis current, A.
    pub i_d_a: f64,
    /// q-axis current, A (its sign against the speed's: regenerating).
    pub i_q_a: f64,
}

/// The observer at one operating point ([`at`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointStability {
    /// The point.
    pub point: Point,
    /// The spectral radius of the linearised step at the observer's steady state (∞: no
    /// steady state found — the iteration diverged or wandered).
    pub radius: f64,
    /// The steady state's speed error, electrical rad/s (estimate − truth; NaN without one).
    pub speed_error_rad_s: f64,
}

/// Newton's steps to the fixed point at most, and the residual taken as converged (relative,
/// of the flux and of the speed).
const NEWTON_STEPS: usize = 60;
const CONVERGED: f64 = 1e-12;

/// The observer of `believed` (its parameters), stepped every `ts_s` with speed bandwidth
/// `speed_bandwidth_rad_s`, on the machine `truth` at `point`.
pub fn at(
    truth: &MotorParams,
    believed: &MotorParams,
    ts_s: f64,
    speed_bandwidth_rad_s: f64,
    point: Point,
) -> PointStability {
    let p = Params::of(believed, ts_s, speed_bandwidth_rad_s);
    let Point { omega_m_rad_s: w_m, i_d_a, i_q_a } = point;
    // The slip of the T model in rotor-flux orientation: ω_r = (R_r/L_r)·i_q/i_d.
    let w_s = w_m + truth.rr_ohm() / truth.lr_h() * i_q_a / i_d_a;
    let i = C::new(i_d_a, i_q_a);
    let (u, psi_s) = steady_state(truth, w_s, w_m, i);
    let turn = C::from_polar(1.0, w_s * ts_s);
    let half = C::from_polar(1.0, 0.5 * w_s * ts_s);
    // The map in the turning coordinates, the interval from θ = 0 to ω_s·T.
    let map = |z: C, w: f64| -> (C, f64) {
        let (psi, w) = advance(&p, z, w, u * half, i, i * turn);
        (psi / turn, w)
    };
    let unstable = PointStability { point, radius: f64::INFINITY, speed_error_rad_s: f64::NAN };
    let scale = psi_s.norm().max(1e-9);
    let f = |x: [f64; 3]| {
        let (z, w) = map(C::new(x[0], x[1]), x[2]);
        [z.re, z.im, w]
    };
    // The Jacobian by central differences.
    let h = [1e-6 * scale, 1e-6 * scale, 1e-6 * w_m.abs().max(1.0)];
    let jacobian = |x: [f64; 3]| {
        let mut jac = DMatrix::<f64>::zeros(3, 3);
        for j in 0..3 {
            let (mut up, mut down) = (x, x);
            up[j] += h[j];
            down[j] -= h[j];
            let (a, b) = (f(up), f(down));
            for r in 0..3 {
                jac[(r, j)] = (a[r] - b[r]) / (2.0 * h[j]);
            }
        }
        jac
    };
    // The fixed point by Newton's method on F(x) − x from the truth, each step halved until
    // the residual falls (the observer's slow modes near zero stator frequency would take
    // millions of iterations of F; full Newton steps overshot where the equilibrium is far
    // from the truth).
    let w_scale = w_m.abs().max(1.0);
    let residual = |x: [f64; 3]| {
        let fx = f(x);
        let g = [fx[0] - x[0], fx[1] - x[1], fx[2] - x[2]];
        (g, g[0].hypot(g[1]) / scale + g[2].abs() / w_scale)
    };
    let mut x = [psi_s.re, psi_s.im, w_m];
    let (mut g, mut r) = residual(x);
    let mut converged = false;
    for _ in 0..NEWTON_STEPS {
        if r < CONVERGED {
            converged = true;
            break;
        }
        let a = jacobian(x) - DMatrix::<f64>::identity(3, 3);
        let Some(dx) = a.lu().solve(&DMatrix::from_column_slice(3, 1, &g)) else { return unstable };
        let mut k = 1.0;
        loop {
            let next = [x[0] - k * dx[0], x[1] - k * dx[1], x[2] - k * dx[2]];
            let (g1, r1) = residual(next);
            if r1.is_finite() && r1 < r {
                (x, g, r) = (next, g1, r1);
                break;
            }
            k *= 0.5;
            if k < 1e-6 {
                return unstable;
            }
        }
    }
    if !converged {
        return unstable;
    }
    PointStability { point, radius: spectral_radius(&jacobian(x)), speed_error_rad_s: x[2] - w_m }
}

/// The grid of [`worst`]: the observer's sample period and speed bandwidth, and the operating
/// points — `speeds` electrical speeds evenly from `−omega_max_rad_s` to `omega_max_rad_s`
/// (zero among them when odd) × the q-axis currents `−i_q_max`, `−i_q_max/2`, 0, `i_q_max/2`,
/// `i_q_max` at the d-axis current `i_d_a`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Grid {
    /// The observer's sample period, s.
    pub ts_s: f64,
    /// Its speed estimate's bandwidth, rad/s.
    pub speed_bandwidth_rad_s: f64,
    /// The highest electrical speed, rad/s.
    pub omega_max_rad_s: f64,
    /// Speeds in the grid.
    pub speeds: usize,
    /// d-axis current, A.
    pub i_d_a: f64,
    /// The largest q-axis current, A.
    pub i_q_max_a: f64,
}

/// The worst of [`at`] over `grid`: the largest spectral radius (∞ where no steady state).
pub fn worst(truth: &MotorParams, believed: &MotorParams, grid: &Grid) -> PointStability {
    let n = grid.speeds.max(2);
    let w_max = grid.omega_max_rad_s;
    let mut worst: Option<PointStability> = None;
    for k in 0..n {
        let w = -w_max + 2.0 * w_max * k as f64 / (n - 1) as f64;
        for q in [-1.0, -0.5, 0.0, 0.5, 1.0] {
            let point = Point { omega_m_rad_s: w, i_d_a: grid.i_d_a, i_q_a: q * grid.i_q_max_a };
            let s = at(truth, believed, grid.ts_s, grid.speed_bandwidth_rad_s, point);
            if worst.is_none_or(|b| s.radius.total_cmp(&b.radius).is_gt()) {
                worst = Some(s);
            }
        }
    }
    worst.unwrap_or(PointStability {
        point: Point { omega_m_rad_s: 0.0, i_d_a: grid.i_d_a, i_q_a: 0.0 },
        radius: f64::INFINITY,
        speed_error_rad_s: f64::NAN,
    })
}

/// The stator resistances, × the observer's, at which [`worst`] (the same grid) stays below 1:
/// `[lo, hi]` by bisection from 1 (each within `1e-3`), the observer's parameters otherwise the
/// machine's — the accuracy the drive's measurement of `R_s` at every enable must reach for the
/// observer to hold everywhere on the grid. `None` when it does not hold even at ×1.
pub fn stator_resistance_margin(m: &MotorParams, grid: &Grid) -> Option<[f64; 2]> {
    let holds = |rs: f64| m.scaled(rs, 1.0, 1.0, 1.0).is_ok_and(|truth| worst(&truth, m, grid).radius < 1.0);
    if !holds(1.0) {
        return None;
    }
    let edge = |far: f64| {
        let (mut good, mut bad) = (1.0, far);
        if holds(far) {
            return far;
        }
        while (bad - good).abs() > 1e-3 {
            let mid = 0.5 * (good + bad);
            if holds(mid) { good = mid } else { bad = mid }
        }
        good
    };
    Some([edge(0.5), edge(2.0)])
}

/// Speeds in the certificate's grid: even, so that the grid leaves out zero speed at no load —
/// zero stator frequency, where the speed is unobservable (a pole at 1) whatever the gains.
pub const CERTIFY_SPEEDS: usize = 24;

/// The observer's part of a drive's certificate ([`check`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ObserverCheck {
    /// The worst point with the observer's parameters the machine's: over the speeds up to the
    /// overspeed level both ways and the torque currents the current limit leaves, motoring and
    /// regenerating ([`worst`] on [`CERTIFY_SPEEDS`] speeds).
    pub worst: PointStability,
    /// The stator resistances the observer holds at over the same grid, × the machine's
    /// ([`stator_resistance_margin`]): what the drive's measurement at every enable must reach.
    pub rs_margin: Option<[f64; 2]>,
    /// The worst radius below 1.
    pub pass: bool,
}

/// The observer of `spec`'s drive (sensorless, or beside the encoder), linearised over its
/// range on the drive's own motor; `None` for a drive without one.
pub fn check(spec: &controller_core::drive::DriveSpec) -> Option<ObserverCheck> {
    use controller_core::drive::SpeedFeedback;
    if spec.speed_feedback == SpeedFeedback::Encoder {
        return None;
    }
    let ts = 1.0 / spec.pwm_frequency_hz;
    let bw = controller_core::drive::observer_speed_bandwidth_rad_s(ts, ts * f64::from(spec.slow_divider));
    let m = &spec.motor;
    let w_max = f64::from(m.pole_pairs()) * spec.protection.overspeed_rad_s;
    let i_d = spec.flux_ref_wb / m.lm_h();
    let i_q = (spec.i_ref_max_a * spec.i_ref_max_a - i_d * i_d).max(0.0).sqrt();
    let grid = Grid {
        ts_s: ts,
        speed_bandwidth_rad_s: bw,
        omega_max_rad_s: w_max,
        speeds: CERTIFY_SPEEDS,
        i_d_a: i_d,
        i_q_max_a: i_q,
    };
    let worst = worst(m, m, &grid);
    Some(ObserverCheck { worst, rs_margin: stator_resistance_margin(m, &grid), pass: worst.radius < 1.0 })
}

#[cfg(test)]
mod tests {
    use super::*;
    use controller_core::frames::AlphaBeta;
    use controller_core::observer::{FluxObserver, ObserverConfig};

    fn motor() -> MotorParams {
        MotorParams::delorenzo_dl10115a1().unwrap()
    }

    /// drive.toml's range: 20 kHz, the observer's 500 rad/s, 600 rad/s both ways, 3.9 A of
    /// torque current beside the rated flux's 0.634 A.
    const GRID: Grid = Grid {
        ts_s: 5e-5,
        speed_bandwidth_rad_s: 500.0,
        omega_max_rad_s: 600.0,
        speeds: 24,
        i_d_a: 0.634,
        i_q_max_a: 3.9,
    };

    /// The port against the drive's own observer (f32): fed the same steady state, the
    /// controller-core observer settles where the f64 map's fixed point is — the flux within
    /// 0.1 % and the speed within 0.05 rad/s — so the linearisation is of the observer the
    /// drive runs.
    #[test]
    fn the_port_settles_where_the_drives_observer_does() {
        let m = motor();
        let (ts, bw) = (5e-5, 500.0);
        let cfg = ObserverConfig::new(&m, ts, bw, 0.05, 700.0).unwrap();
        for &(w_m, i_q) in &[(150.0, 2.0), (150.0, -2.0), (20.0, -2.0), (-80.0, 1.0)] {
            let point = Point { omega_m_rad_s: w_m, i_d_a: 0.634, i_q_a: i_q };
            let s = at(&m, &m, ts, bw, point);
            assert!(s.radius < 1.0, "{point:?}: {s:?}");
            // The drive's observer on the same samples.
            let w_s = w_m + m.rr_ohm() / m.lr_h() * i_q / 0.634;
            let i = C::new(0.634, i_q);
            let (u, _) = steady_state(&m, w_s, w_m, i);
            let ab = |c: C| AlphaBeta { alpha: c.re as f32, beta: c.im as f32 };
            // Magnetized with the speed known, then adapting.
            let mut obs = FluxObserver::new(ab(i));
            let mut e = obs.estimate(&cfg);
            for k in 0..200_000u32 {
                let th = w_s * ts * f64::from(k);
                let u_k = u * C::from_polar(1.0, th + 0.5 * w_s * ts);
                let i_k = i * C::from_polar(1.0, th + w_s * ts);
                e = if k < 40_000 {
                    obs.step_known_speed(&cfg, ab(u_k), ab(i_k), (w_m / f64::from(m.pole_pairs())) as f32)
                } else {
                    obs.step(&cfg, ab(u_k), ab(i_k))
                };
            }
            let w_est = f64::from(e.omega_m_rad_s) * f64::from(m.pole_pairs());
            eprintln!(
                "{point:?}: drive's observer {w_est:.3} rad/s, the map's {:.3}",
                w_m + s.speed_error_rad_s
            );
            assert!((w_est - (w_m + s.speed_error_rad_s)).abs() < 0.05, "{point:?}");
        }
    }

    /// With its parameters right the observer is stable at every point of drive.toml's range —
    /// both directions, motoring and regenerating, through zero stator frequency — its
    /// steady state the truth; the design of its gains (σ_o = α/2 + ζ∞·|ω̂|).
    #[test]
    fn with_its_parameters_right_it_is_stable_everywhere() {
        let m = motor();
        let s = worst(&m, &m, &GRID);
        eprintln!(
            "exact parameters: worst radius {:.8} (slowest decay {:.2} 1/s) at {:?}",
            s.radius,
            -s.radius.ln() / 5e-5,
            s.point
        );
        // The steady state the truth but for the interval's discretisation (the voltage read at
        // its middle): within a thousandth of a rad/s.
        assert!(s.radius < 1.0 && s.speed_error_rad_s.abs() < 1e-3, "{s:?}");
    }

    /// The linearisation against the time simulation of the same map: where it finds a stable
    /// steady state off the truth (the rotor resistance ×2, regenerating at −183 rad/s), the map
    /// iterated from the truth settles on it; where it finds none (a stator 20 % hotter than
    /// the observer believes, regenerating at −130 rad/s with 3.9 A: the stator frequency at
    /// −35 rad/s), the iteration's speed estimate runs away.
    #[test]
    fn the_linearisation_agrees_with_the_time_simulation() {
        let m = motor();
        let (ts, bw) = (5e-5, 500.0);
        let iterate = |truth: &MotorParams, point: Point| {
            let p = Params::of(&m, ts, bw);
            let w_s = point.omega_m_rad_s + truth.rr_ohm() / truth.lr_h() * point.i_q_a / point.i_d_a;
            let i = C::new(point.i_d_a, point.i_q_a);
            let (u, psi_s) = steady_state(truth, w_s, point.omega_m_rad_s, i);
            let (turn, half) = (C::from_polar(1.0, w_s * ts), C::from_polar(1.0, 0.5 * w_s * ts));
            let (mut z, mut w) = (psi_s, point.omega_m_rad_s);
            for _ in 0..2_000_000 {
                let (psi, w1) = advance(&p, z, w, u * half, i, i * turn);
                (z, w) = (psi / turn, w1);
            }
            w
        };
        let stable = Point { omega_m_rad_s: -182.6, i_d_a: 0.634, i_q_a: 3.9 };
        let rr2 = m.scaled(1.0, 2.0, 1.0, 1.0).unwrap();
        let s = at(&rr2, &m, ts, bw, stable);
        let w = iterate(&rr2, stable);
        eprintln!(
            "R_r ×2 at {stable:?}: radius {:.8}, steady speed {:.3}, iterated {w:.3}",
            s.radius,
            stable.omega_m_rad_s + s.speed_error_rad_s
        );
        assert!(s.radius < 1.0);
        assert!((w - (stable.omega_m_rad_s + s.speed_error_rad_s)).abs() < 0.01, "{w}");
        let lost = Point { omega_m_rad_s: -130.4, i_d_a: 0.634, i_q_a: 3.9 };
        let hot = m.scaled(1.2, 1.0, 1.0, 1.0).unwrap();
        let s = at(&hot, &m, ts, bw, lost);
        let w = iterate(&hot, lost);
        eprintln!("R_s ×1.2 at {lost:?}: radius {}, iterated {w:.1}", s.radius);
        assert!(s.radius.is_infinite());
        assert!(w.abs() > 10.0 * lost.omega_m_rad_s.abs(), "{w}");
    }

    /// How far the observer's stator resistance may be from the machine's on drive.toml's grid
    /// (600 rad/s, 3.9 A of torque current both ways): the margin the drive's measurement at
    /// every enable must keep — a stator 20 % hotter than believed loses the speed regenerating
    /// (above; `hil-sim/tests/observer.rs` shows its speed error at 3 % of base speed).
    #[test]
    fn the_stator_resistance_margin_of_drive_toml() {
        let m = motor();
        let [lo, hi] = stator_resistance_margin(&m, &GRID).unwrap();
        eprintln!("drive.toml's observer holds R_s × [{lo:.3}, {hi:.3}] of the machine's");
        assert!(lo < 1.0 && hi > 1.0 && hi < 1.2, "[{lo}, {hi}]");
    }

    /// `design certify`'s part: drive.toml without its encoder passes (its worst point
    /// regenerating near zero stator frequency), and states the stator-resistance margin its
    /// measurement must keep; the encoder drive has no observer to check.
    #[test]
    fn the_certificate_checks_the_observer_of_a_drive_that_runs_one() {
        let mut spec = drive_file::DriveFile::shipped().unwrap().spec;
        assert_eq!(check(&spec), None);
        spec.speed_feedback = controller_core::drive::SpeedFeedback::Sensorless;
        let c = check(&spec).unwrap();
        eprintln!("{c:?}");
        assert!(c.pass && c.worst.radius < 1.0);
        // Regenerating: the torque current against the speed.
        assert!(c.worst.point.omega_m_rad_s * c.worst.point.i_q_a < 0.0, "{:?}", c.worst.point);
        let [lo, hi] = c.rs_margin.unwrap();
        assert!(lo < 1.0 && 1.0 < hi, "[{lo}, {hi}]");
    }
}
