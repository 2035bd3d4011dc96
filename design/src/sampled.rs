//! The loops as the drive runs them: sampled, delayed, with the controllers discretised
//! exactly as `controller-core` stores them (issue 21's discrete-time certificate).
//!
//! **Current loops** (stationary frame). The plant of seed 002 eq. (1) at electrical rotor
//! speed ω_r ([`crate::im::ImModel`]) under a zero-order hold of one PWM period T:
//! `Φ = e^{AT}`, `Γ = ∫₀ᵀ e^{As} ds·B` (one matrix exponential of `[[A, B], [0, 0]]·T`). The
//! currents sampled at the start of period k give, through the controller, the voltage applied
//! during period k + 1 (the firmware's preload, the simulator's duty delay): one period of
//! computational delay, and the drive turns that voltage ahead by `1.5·T·ω_e`
//! ([`controller_core::drive::VOLTAGE_DELAY_PERIODS`]; here ω_e = ω_r, the no-load slip). The
//! controller on each axis is [`CurrentControllerConfig`]'s f32 coefficients: the PI
//! `k_p + (K_i/K)(z + 1)/(z − 1)` in series with the lag biquad. The closed loop is the
//! linear state-space system `X(k+1) = M·X(k)`, states = plant (4), delayed voltage (2),
//! controller (2·n_k); stable iff M's spectral radius is below 1. Its frequency response on
//! the unit circle, `G(e^{jωT}) = C(e^{jωT}I − Φ)⁻¹Γ·R(θ)·e^{−jωT}`, gives the ICAD margins of
//! the sampled loop (seed 002's quantities, [`crate::icad::report`]) up to the Nyquist
//! frequency π/T.
//!
//! **Synchronous-frame current loops** ([`current_loop_matrix_in`]): the drive parks the
//! currents sampled at period k at the field angle θ_k, runs the same controller on d and q,
//! turns its output back at θ_k and ahead over the delay. In the field's coordinates
//! `x_dq(k) = R(−θ_k)·x(k)` (θ_{k+1} = θ_k + ω_e·T; ω_e = ω_r at no load), with Φ and Γ
//! commuting with R: `x_dq(k+1) = Φ·R(−ω_e·T)·x_dq(k) + Γ·R(1.5·ω_e·T − 2·ω_e·T)·d(k)`, d the
//! controller's output of the period before (applied during period k, turned at θ_{k−1}
//! and ahead by the delay's 1.5·ω_e·T: the middle of period k, seen from θ_{k+1}). The
//! same state-space matrix and frequency response follow, with those Φ and Γ.
//!
//! **Speed loop**. The mechanical plant `J dω/dt = τ − Bω` under a zero-order hold of the
//! slow period T_s = N_div·T; the speed measured as the firmware's and the simulator's
//! encoder estimator does, the angle advanced over the last
//! [`SPEED_WINDOW_READS`] slow reads divided by their span (an FIR of the per-period angle
//! increments `Δθ = c₁ω + c₂τ`, exact under the hold); the torque commanded at slow step k
//! applied during slow period k + 1 (one slow period for the current loops to build it up:
//! an assumption, checked against the simulated drive by `hil-sim/tests/sampled_speed.rs`). The saturated P law is
//! checked in its linear region (|τ| < τ_max); a PI law with its integrator
//! `K_i/K·(z + 1)/(z − 1)`. Stability over a grid of J (and of k_p over the writable range):
//! Kharitonov's theorem does not carry over to the unit circle, so the sampled speed check
//! is a grid, stated as such.

use crate::icad::{IcadReport, realise, report};
use crate::im::{G2, ImModel};
use crate::poly::Poly;
use controller_core::current::CurrentControllerConfig;
use controller_core::discretize::Discretization;
use controller_core::drive::CurrentFrame;
use controller_core::drive::VOLTAGE_DELAY_PERIODS;
use controller_core::encoder::SPEED_WINDOW_READS;
use controller_core::motor::MotorParams;
use controller_core::pi::PiConfig;
use nalgebra::{DMatrix, Matrix2, Matrix4, Matrix4x2};
use num_complex::Complex64;

/// The plant of one PWM period: `x(k+1) = Φ x(k) + Γ u(k)` (u held over the period).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SampledPlant {
    /// e^{AT}.
    pub phi: Matrix4<f64>,
    /// ∫₀ᵀ e^{As} ds·B.
    pub gamma: Matrix4x2<f64>,
}

impl SampledPlant {
    /// Zero-order hold of eq. (1) at `omega_r` over `ts_s`.
    pub fn new(m: &MotorParams, omega_r: f64, ts_s: f64) -> Self {
        let c = ImModel::new(m, omega_r);
        let mut aug = DMatrix::<f64>::zeros(6, 6);
        for i in 0..4 {
            for j in 0..4 {
                aug[(i, j)] = c.a[(i, j)] * ts_s;
            }
            for j in 0..2 {
                aug[(i, 4 + j)] = c.b[(i, j)] * ts_s;
            }
        }
        let e = aug.exp();
        Self { phi: Matrix4::from_fn(|i, j| e[(i, j)]), gamma: Matrix4x2::from_fn(|i, j| e[(i, 4 + j)]) }
    }
}

/// The rotation `R(θ)`.
fn rotation(theta: f64) -> Matrix2<f64> {
    let (s, c) = theta.sin_cos();
    Matrix2::new(c, -s, s, c)
}

/// The voltage's rotation ahead over the delay, `R(θ)` with `θ = 1.5·T·ω_e`.
fn advance(omega_e: f64, ts_s: f64) -> Matrix2<f64> {
    rotation(VOLTAGE_DELAY_PERIODS * ts_s * omega_e)
}

/// One period of the plant in the loops' coordinates: `(Φ, Γ·R)` with the voltage's
/// rotation R (module docs) — the stationary frame's Φ and Γ·R(1.5·ω_e·T), or in the field's
/// coordinates Φ·R(−ω_e·T) and Γ·R(−0.5·ω_e·T).
fn loop_plant(
    m: &MotorParams,
    omega_r: f64,
    ts_s: f64,
    frame: CurrentFrame,
) -> (Matrix4<f64>, Matrix4x2<f64>) {
    let p = SampledPlant::new(m, omega_r, ts_s);
    match frame {
        CurrentFrame::Stationary => (p.phi, p.gamma * advance(omega_r, ts_s)),
        CurrentFrame::Synchronous => {
            let step = rotation(-omega_r * ts_s);
            let mut turn = Matrix4::<f64>::zeros();
            turn.fixed_view_mut::<2, 2>(0, 0).copy_from(&step);
            turn.fixed_view_mut::<2, 2>(2, 2).copy_from(&step);
            let back = rotation((VOLTAGE_DELAY_PERIODS - 2.0) * ts_s * omega_r);
            (p.phi * turn, p.gamma * back)
        }
    }
}

/// One axis of the implemented current controller as z-domain `(num, den)` polynomials.
fn controller_z(ctrl: &CurrentControllerConfig<f32>) -> (Poly, Poly) {
    let (kp, kik) = (f64::from(ctrl.pi().kp()), f64::from(ctrl.pi().ki_over_k()));
    // kp + kik (z + 1)/(z − 1) = (kp(z − 1) + kik(z + 1)) / (z − 1)
    let pi_num = Poly::new(&[kp + kik, kik - kp]);
    let pi_den = Poly::new(&[1.0, -1.0]);
    match ctrl.lag() {
        Some(l) => {
            let (b, a) = l.coefficients().to_z();
            (pi_num.mul(&Poly::new(&b)), pi_den.mul(&Poly::new(&a)))
        }
        None => (pi_num, pi_den),
    }
}

/// The closed current loop's state matrix M at `omega_r` (see the module docs).
pub fn current_loop_matrix(
    m: &MotorParams,
    ctrl: &CurrentControllerConfig<f32>,
    ts_s: f64,
    omega_r: f64,
) -> DMatrix<f64> {
    current_loop_matrix_in(m, ctrl, ts_s, omega_r, CurrentFrame::Stationary)
}

/// [`current_loop_matrix`] for loops in `frame` (module docs).
pub fn current_loop_matrix_in(
    m: &MotorParams,
    ctrl: &CurrentControllerConfig<f32>,
    ts_s: f64,
    omega_r: f64,
    frame: CurrentFrame,
) -> DMatrix<f64> {
    let (phi, gr) = loop_plant(m, omega_r, ts_s, frame);
    let (num, den) = controller_z(ctrl);
    let (ak, bk, ck, dk) = realise(&num, &den);
    let nk = ak.nrows();
    let n = 6 + 2 * nk;
    let mut mm = DMatrix::<f64>::zeros(n, n);
    for i in 0..4 {
        for j in 0..4 {
            mm[(i, j)] = phi[(i, j)];
        }
        for j in 0..2 {
            mm[(i, 4 + j)] = gr[(i, j)];
        }
    }
    for axis in 0..2 {
        let off = 6 + axis * nk;
        // d(k+1) = u(k) = C_k x_k − D_k i_axis
        mm[(4 + axis, axis)] = -dk;
        for j in 0..nk {
            mm[(4 + axis, off + j)] = ck[(0, j)];
        }
        // x_k(k+1) = A_k x_k − B_k i_axis
        for i in 0..nk {
            for j in 0..nk {
                mm[(off + i, off + j)] = ak[(i, j)];
            }
            mm[(off + i, axis)] = -bk[(i, 0)];
        }
    }
    mm
}

/// Largest eigenvalue magnitude of `m` (∞ if not finite or unknown: not proven stable).
pub fn spectral_radius(m: &DMatrix<f64>) -> f64 {
    if !m.iter().all(|x| x.is_finite()) {
        return f64::INFINITY;
    }
    crate::eig::eigenvalues(m).map_or(f64::INFINITY, |e| e.iter().map(|z| z.norm()).fold(0.0, f64::max))
}

/// The worst spectral radius of the sampled current loop over `0…omega_r_max` in steps of
/// `step` (and at `omega_r_max`), with the ω_r where it occurs.
pub fn current_loop_worst_radius(
    m: &MotorParams,
    ctrl: &CurrentControllerConfig<f32>,
    ts_s: f64,
    omega_r_max: f64,
    step: f64,
) -> (f64, f64) {
    current_loop_worst_radius_in(m, ctrl, ts_s, omega_r_max, step, CurrentFrame::Stationary)
}

/// [`current_loop_worst_radius`] for loops in `frame`.
pub fn current_loop_worst_radius_in(
    m: &MotorParams,
    ctrl: &CurrentControllerConfig<f32>,
    ts_s: f64,
    omega_r_max: f64,
    step: f64,
    frame: CurrentFrame,
) -> (f64, f64) {
    let mut worst = (f64::NEG_INFINITY, 0.0);
    let mut w = 0.0f64;
    loop {
        let w_here = w.min(omega_r_max);
        let r = spectral_radius(&current_loop_matrix_in(m, ctrl, ts_s, w_here, frame));
        if r > worst.0 || r.is_nan() {
            worst = (r, w_here);
        }
        if w >= omega_r_max {
            break;
        }
        w += step;
    }
    worst
}

/// Largest ω_r (searched up to `limit` in steps of `step`) such that the sampled loop is
/// stable for every electrical rotor speed in [0, ω_r] — [`crate::icad::stable_omega_r_max`]
/// for the loop as the drive runs it; `None` if unstable already at 0.
pub fn stable_omega_r_max(
    m: &MotorParams,
    ctrl: &CurrentControllerConfig<f32>,
    ts_s: f64,
    step: f64,
    limit: f64,
) -> Option<f64> {
    let mut last = None;
    let mut w = 0.0;
    while w <= limit {
        if spectral_radius(&current_loop_matrix(m, ctrl, ts_s, w)) >= 1.0 {
            return last;
        }
        last = Some(w);
        w += step;
    }
    last
}

/// The sampled loop's 2×2 frequency response at ω (0 < ω < π/T), delay and advance included.
pub fn sampled_response(p: &SampledPlant, omega_r: f64, ts_s: f64, omega_rad_s: f64) -> G2 {
    response_of(&p.phi, &(p.gamma * advance(omega_r, ts_s)), ts_s, omega_rad_s)
}

/// `C(zI − Φ)⁻¹Γ·z⁻¹` at `z = e^{jωT}`.
fn response_of(phi: &Matrix4<f64>, gamma: &Matrix4x2<f64>, ts_s: f64, omega_rad_s: f64) -> G2 {
    let z = Complex64::from_polar(1.0, omega_rad_s * ts_s);
    let a = Matrix4::<Complex64>::identity() * z - phi.map(|x| Complex64::new(x, 0.0));
    let b = gamma.map(|x| Complex64::new(x, 0.0));
    let x = a.lu().solve(&b).unwrap_or_else(|| Matrix4x2::from_element(Complex64::new(f64::NAN, f64::NAN)));
    let d = z.inv();
    G2 { g11: x[(0, 0)] * d, g12: x[(0, 1)] * d, g21: x[(1, 0)] * d, g22: x[(1, 1)] * d }
}

/// ICAD analysis of the sampled current loop at `omega_r` (frequencies up to 0.999·π/T).
pub fn analyse(m: &MotorParams, ctrl: &CurrentControllerConfig<f32>, ts_s: f64, omega_r: f64) -> IcadReport {
    analyse_in(m, ctrl, ts_s, omega_r, CurrentFrame::Stationary)
}

/// [`analyse`] for loops in `frame` (module docs).
pub fn analyse_in(
    m: &MotorParams,
    ctrl: &CurrentControllerConfig<f32>,
    ts_s: f64,
    omega_r: f64,
    frame: CurrentFrame,
) -> IcadReport {
    let (phi, gamma) = loop_plant(m, omega_r, ts_s, frame);
    let nyquist = 0.999 * std::f64::consts::PI / ts_s;
    let w = crate::tf::logspace(1e-1, nyquist, 20_000);
    report(m, omega_r, &w, |x| (response_of(&phi, &gamma, ts_s, x), ctrl.response(x, ts_s)))
}

/// The sampled speed loop (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpeedLoop {
    /// Inertia, kg·m².
    pub j_kgm2: f64,
    /// Viscous friction, N·m·s/rad.
    pub b_nms: f64,
    /// Slow period, s.
    pub ts_s: f64,
    /// The law's proportional gain, N·m per rad/s (torque laws; for an i_q law, k_p·K_t).
    pub kp: f64,
    /// The discrete integrator's gain K_i/K per step (0: a P law), in the same units.
    pub ki_over_k: f64,
}

impl SpeedLoop {
    /// A PI law discretised as the drive does (Tustin, `PiConfig`, f32 coefficients),
    /// times `scale` (K_t for an i_q law, 1 for a torque law).
    pub fn pi(j_kgm2: f64, b_nms: f64, ts_s: f64, kp: f64, ki: f64, scale: f64) -> Result<Self, String> {
        let pi = PiConfig::<f32>::new(kp, ki, ts_s, Discretization::Tustin, -1.0, 1.0)
            .map_err(|e| format!("speed PI rejected: {e:?}"))?;
        Ok(Self {
            j_kgm2,
            b_nms,
            ts_s,
            kp: scale * f64::from(pi.kp()),
            ki_over_k: scale * f64::from(pi.ki_over_k()),
        })
    }

    /// The closed loop's state matrix: ω, the last `SPEED_WINDOW_READS` angle increments,
    /// the torque being applied, and (PI) the integrator and the previous error.
    pub fn matrix(&self) -> DMatrix<f64> {
        let (j, b, t) = (self.j_kgm2, self.b_nms, self.ts_s);
        // ZOH of J ω' = τ − B ω: ω(k+1) = a ω + g τ; Δθ = c1 ω + c2 τ.
        let (a, g, c1, c2) = if b * t / j > 1e-9 {
            let a = (-b * t / j).exp();
            let tau_m = j / b;
            (a, (1.0 - a) / b, tau_m * (1.0 - a), (t - tau_m * (1.0 - a)) / b)
        } else {
            (1.0, t / j, t, t * t / (2.0 * j))
        };
        let nw = SPEED_WINDOW_READS;
        let pi = self.ki_over_k != 0.0;
        // States: 0 ω, 1..=nw Δθ(k−1)…Δθ(k−nw), nw+1 τ applied, then (PI) i-term, e_prev.
        let n = nw + 2 + if pi { 2 } else { 0 };
        let (w, tau) = (0, nw + 1);
        let mut m = DMatrix::<f64>::zeros(n, n);
        m[(w, w)] = a;
        m[(w, tau)] = g;
        // Newest increment: Δθ(k) = c1 ω(k) + c2 τ(k); the rest shift.
        m[(1, w)] = c1;
        m[(1, tau)] = c2;
        for i in 2..=nw {
            m[(i, i - 1)] = 1.0;
        }
        // The measured speed at step k: Σ Δθ(k−1…k−nw) / (nw·T); error e = −ω_meas.
        let e_row: Vec<(usize, f64)> = (1..=nw).map(|i| (i, -1.0 / (nw as f64 * t))).collect();
        // τ(k+1) = kp e + i(k+1), i(k+1) = i + kik (e + e_prev).
        for &(i, c) in &e_row {
            m[(tau, i)] += (self.kp + self.ki_over_k) * c;
        }
        if pi {
            let (it, ep) = (nw + 2, nw + 3);
            m[(tau, it)] += 1.0;
            m[(tau, ep)] += self.ki_over_k;
            m[(it, it)] = 1.0;
            m[(it, ep)] = self.ki_over_k;
            for &(i, c) in &e_row {
                m[(it, i)] += self.ki_over_k * c;
                m[(ep, i)] = c;
            }
        }
        m
    }

    /// Spectral radius of [`Self::matrix`].
    pub fn radius(&self) -> f64 {
        spectral_radius(&self.matrix())
    }

    /// The position loop closed around this speed loop (the drive's cascade, seed 002 Fig.
    /// 14): `ω_ref = k·(θ_ref − θ)` at the slow rate from the encoder's reading, θ the sum
    /// of the angle increments. States: [`Self::matrix`]'s, then θ − θ_ref.
    pub fn position_matrix(&self, k_per_s: f64) -> DMatrix<f64> {
        let m = self.matrix();
        let n = m.nrows();
        let nw = SPEED_WINDOW_READS;
        let mut p = DMatrix::<f64>::zeros(n + 1, n + 1);
        p.view_mut((0, 0), (n, n)).copy_from(&m);
        // θ(k+1) = θ(k) + Δθ(k): the newest increment's row (state 1).
        for c in 0..n {
            p[(n, c)] = m[(1, c)];
        }
        p[(n, n)] = 1.0;
        // The speed error gains −k·θ. Every row that reads the error — the torque, and a
        // PI's integrator and previous error (states nw+1 …) — reads the newest increment
        // only through it, with weight −1/(nw·T): −k is that weight times k·nw·T.
        let per_error = k_per_s * nw as f64 * self.ts_s;
        for r in (nw + 1)..n {
            p[(r, n)] = m[(r, 1)] * per_error;
        }
        p
    }

    /// Spectral radius of [`Self::position_matrix`].
    pub fn position_radius(&self, k_per_s: f64) -> f64 {
        spectral_radius(&self.position_matrix(k_per_s))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use controller_core::current::CurrentLaw;

    fn delorenzo() -> MotorParams {
        MotorParams::new(16.2, 23.2, 1.44, 1.5, 1.42, 1, 0.005, 0.0005).unwrap()
    }

    fn icad(ts: f64) -> CurrentControllerConfig<f32> {
        CurrentControllerConfig::new(&CurrentLaw::ICAD_EQ20, ts, Discretization::Tustin, 179.0).unwrap()
    }

    /// The zero-order hold against a fine RK4 of the same plant over one period.
    #[test]
    fn zoh_matches_a_fine_simulation() {
        let m = delorenzo();
        let (ts, wr) = (5e-5, 300.0);
        let p = SampledPlant::new(&m, wr, ts);
        let machine = plant::Machine::new(&m).speed_locked();
        let x0 = plant::MachineState {
            i_alpha_a: 1.0,
            i_beta_a: -0.5,
            psi_alpha_wb: 0.3,
            psi_beta_wb: 0.1,
            omega_m_rad_s: wr,
            ..Default::default()
        };
        let u = [40.0, -25.0];
        let mut x = x0;
        for _ in 0..1000 {
            x = machine.rk4(&x, u, 0.0, ts / 1000.0);
        }
        let v = nalgebra::Vector4::new(x0.i_alpha_a, x0.i_beta_a, x0.psi_alpha_wb, x0.psi_beta_wb);
        let z = p.phi * v + p.gamma * nalgebra::Vector2::new(u[0], u[1]);
        for (a, b) in [x.i_alpha_a, x.i_beta_a, x.psi_alpha_wb, x.psi_beta_wb].iter().zip(z.iter()) {
            assert!((a - b).abs() < 1e-10, "{a} vs {b}");
        }
    }

    /// The closed-loop matrix against a time simulation of the same difference equations
    /// run through controller-core's own controller (f32): the impulse responses' decay
    /// rate matches the spectral radius.
    #[test]
    fn closed_loop_matrix_matches_the_controller_code() {
        let m = delorenzo();
        let (ts, wr) = (5e-5, 300.0);
        let ctrl = icad(ts);
        let p = SampledPlant::new(&m, wr, ts);
        let rot = advance(wr, ts);
        // Simulate: measure, controller (f64 state through the f32 code is close enough
        // here: the comparison is on the decay rate), voltage applied next period.
        let mut state = controller_core::current::CurrentState::<f32>::default();
        let mut x = nalgebra::Vector4::new(0.0, 0.0, 0.0, 0.0);
        let mut d = nalgebra::Vector2::new(0.0, 0.0);
        let mut peak_late: f64 = 0.0;
        let mut peak_early: f64 = 0.0;
        let n = 4000;
        for k in 0..n {
            let r = if k == 0 { 1.0 } else { 0.0 };
            let [u1, u2] = ctrl.request(&mut state, (r - x[0]) as f32, (-x[1]) as f32, 1e6);
            x = p.phi * x + p.gamma * (rot * d);
            d = nalgebra::Vector2::new(f64::from(u1), f64::from(u2));
            let mag = x[0].hypot(x[1]);
            if k >= n / 4 && k < n / 2 {
                peak_early = peak_early.max(mag);
            }
            if k >= 3 * n / 4 {
                peak_late = peak_late.max(mag);
            }
        }
        let rho = spectral_radius(&current_loop_matrix(&m, &ctrl, ts, wr));
        // Over n/2 periods the envelope decays as ρ^(n/2), within the ratio of the peaks.
        let measured = (peak_late / peak_early).powf(1.0 / (n as f64 / 2.0));
        assert!(rho < 1.0, "{rho}");
        assert!((measured - rho).abs() < 2e-4, "decay per period {measured} vs ρ = {rho}");
    }

    /// The synchronous-frame matrix against a time simulation of the drive's synchronous
    /// loops in the stationary frame — currents parked at θ_k, controller-core's controller
    /// on d and q, its output turned back at θ_k and ahead by 1.5·ω_e·T, applied the next
    /// period: the impulse response decays at the synchronous matrix's spectral radius, not
    /// at the stationary one's (seed 002's PI 360/9 000 at 300 rad/s).
    #[test]
    fn synchronous_matrix_matches_the_controller_code() {
        let m = delorenzo();
        let (ts, wr) = (5e-5, 300.0);
        let law = CurrentLaw::PI_SEED002;
        let ctrl = CurrentControllerConfig::new(&law, ts, Discretization::Tustin, 179.0).unwrap();
        let p = SampledPlant::new(&m, wr, ts);
        let ahead = advance(wr, ts);
        let mut state = controller_core::current::CurrentState::<f32>::default();
        let mut x = nalgebra::Vector4::new(0.0, 0.0, 0.0, 0.0);
        let mut d = nalgebra::Vector2::new(0.0, 0.0);
        let (mut peak_early, mut peak_late) = (0.0f64, 0.0f64);
        let n = 20000;
        for k in 0..n {
            let theta = wr * ts * k as f64;
            let i_dq = rotation(-theta) * nalgebra::Vector2::new(x[0], x[1]);
            let r = if k == 0 { 0.01 } else { 0.0 };
            let [ud, uq] = ctrl.request(&mut state, (r - i_dq[0]) as f32, (-i_dq[1]) as f32, 1e6);
            x = p.phi * x + p.gamma * (ahead * d);
            d = rotation(theta) * nalgebra::Vector2::new(f64::from(ud), f64::from(uq));
            let mag = x[0].hypot(x[1]);
            if (n / 4..n / 2).contains(&k) {
                peak_early = peak_early.max(mag);
            }
            if k >= 3 * n / 4 {
                peak_late = peak_late.max(mag);
            }
        }
        let measured = (peak_late / peak_early).powf(1.0 / (n as f64 / 2.0));
        let sync = spectral_radius(&current_loop_matrix_in(&m, &ctrl, ts, wr, CurrentFrame::Synchronous));
        let stat = spectral_radius(&current_loop_matrix(&m, &ctrl, ts, wr));
        eprintln!("decay per period {measured:.7}: synchronous ρ {sync:.7}, stationary ρ {stat:.7}");
        assert!(sync < 1.0 && (measured - sync).abs() < 2e-5, "{measured} vs {sync}");
        assert!((measured - stat).abs() > 10.0 * (measured - sync).abs(), "{measured}: {stat} as close");
    }

    /// The two synchronous-frame models, derived apart — the continuous `A − ω_e·J` and the
    /// sampled `Φ·R(−ω_e·T)`, `Γ·R(−0.5·ω_e·T)` — agree where the sampling hardly matters:
    /// at 1 MHz the sampled loop's slowest mode, `ln|z|/T`, is the continuous loop's within
    /// 1 % over 0…400 rad/s (seed 002's PI 360/9 000).
    #[test]
    fn synchronous_sampled_and_continuous_agree_at_a_fast_rate() {
        let m = delorenzo();
        let law = CurrentLaw::PI_SEED002;
        let ts = 1e-6;
        let ctrl = CurrentControllerConfig::new(&law, ts, Discretization::Tustin, 179.0).unwrap();
        for wr in [0.0, 150.0, 400.0] {
            let cont = crate::icad::closed_loop_abscissa_in(&m, &law, wr, CurrentFrame::Synchronous);
            let samp = spectral_radius(&current_loop_matrix_in(&m, &ctrl, ts, wr, CurrentFrame::Synchronous))
                .ln()
                / ts;
            eprintln!("ω_r {wr}: continuous {cont:.4} 1/s, sampled at 1 MHz {samp:.4} 1/s");
            assert!((samp / cont - 1.0).abs() < 0.01, "ω_r {wr}: {samp} vs {cont}");
        }
    }

    /// 20 kHz: stable over the certified speeds; 100 Hz: the same law is unstable (its
    /// crossover is beyond the Nyquist frequency).
    #[test]
    fn the_sampling_rate_decides() {
        let m = delorenzo();
        let (r20k, _) = current_loop_worst_radius(&m, &icad(5e-5), 5e-5, 400.0, 5.0);
        let (r100, _) = current_loop_worst_radius(&m, &icad(1e-2), 1e-2, 400.0, 5.0);
        eprintln!("spectral radius: 20 kHz {r20k:.6}, 100 Hz {r100:.3}");
        assert!(r20k < 1.0 && r100 > 1.0);
    }

    /// The stable rotor-speed range of the sampled ICAD loop at 20 kHz against the continuous
    /// analysis's 645 rad/s (seed 002 eq. (13) motor): the test prints both — the same 645:
    /// the limit is the structure's (γh at low frequency, where the delay hardly acts), the
    /// delay costs margin, not range.
    #[test]
    fn sampled_stable_speed_range() {
        let m = drive_file::motor::load("delorenzo-eq13").unwrap();
        let cont = crate::icad::stable_omega_r_max(&m, &CurrentLaw::ICAD_EQ20, 5.0, 5000.0);
        let samp = stable_omega_r_max(&m, &icad(5e-5), 5e-5, 5.0, 5000.0);
        eprintln!("ICAD (20) stable for ω_r ∈ [0, {cont:?}] continuous, [0, {samp:?}] sampled at 20 kHz");
        assert_eq!(cont, Some(645.0));
        assert!(samp.is_some_and(|w| w > 400.0 && w <= 645.0 + 5.0), "{samp:?}");
    }

    /// The speed loop: the shipped k_p = 0.05 is stable, k_p = 50 and 1e9 are not; for the
    /// P law without window or delay the limit would be k_p·T/J < 2 — the window and the
    /// delay lower it (the test prints the largest stable k_p found by bisection).
    #[test]
    fn speed_gain_limits() {
        let loop_ = |kp: f64| SpeedLoop { j_kgm2: 0.005, b_nms: 0.0005, ts_s: 5e-4, kp, ki_over_k: 0.0 };
        assert!(loop_(0.05).radius() < 1.0);
        assert!(loop_(50.0).radius() > 1.0);
        assert!(loop_(1e9).radius() > 1.0);
        let (mut lo, mut hi) = (0.05f64, 50.0f64);
        for _ in 0..60 {
            let mid = (lo * hi).sqrt();
            if loop_(mid).radius() < 1.0 { lo = mid } else { hi = mid }
        }
        eprintln!("largest stable k_p: {lo:.4} N·m·s/rad (k_p·T/J = {:.4})", lo * 5e-4 / 0.005);
        assert!(lo * 5e-4 / 0.005 < 2.0);
        // A PI law: seed 000's PI2 on its own 500 hp machine is stable.
        let pi = SpeedLoop::pi(11.06, 0.0, 5e-4, 50.0, 250.0, 1.0).unwrap();
        assert!(pi.radius() < 1.0, "{}", pi.radius());
    }

    /// The position cascade's matrix against a direct simulation of the same sampled loop
    /// built from the physics (the rotor integrated in 1 000 steps per slow period, the
    /// window of increments, the torque one period late, ω_ref = k·(θ_ref − θ)): the angle
    /// after a 1 rad step agrees to 1e-6 rad over 2 000 periods (1 s) and settles; a large enough
    /// gain is unstable; k = 0 leaves the angle uncontrolled (radius 1).
    #[test]
    fn position_cascade_matches_a_direct_simulation() {
        let (j, b, t, kp, k) = (0.005, 0.0005, 5e-4, 0.05, 10.0);
        let l = SpeedLoop { j_kgm2: j, b_nms: b, ts_s: t, kp, ki_over_k: 0.0 };
        let m = l.position_matrix(k);
        let n = m.nrows();
        let mut x = nalgebra::DVector::<f64>::zeros(n);
        x[n - 1] = -1.0;
        let nw = SPEED_WINDOW_READS;
        let (mut w, mut th, mut tau) = (0.0f64, 0.0f64, 0.0f64);
        let mut window = std::collections::VecDeque::from(vec![0.0; nw]);
        let mut worst: f64 = 0.0;
        for _ in 0..2000 {
            worst = worst.max((th - (1.0 + x[n - 1])).abs());
            let meas: f64 = window.iter().sum::<f64>() / (nw as f64 * t);
            let next = kp * (k * (1.0 - th) - meas);
            let th0 = th;
            let h = t / 1000.0;
            for _ in 0..1000 {
                // Midpoint step of J ω' = τ − B ω, θ' = ω.
                let wm = w + 0.5 * h * (tau - b * w) / j;
                th += h * wm;
                w += h * (tau - b * wm) / j;
            }
            window.pop_back();
            window.push_front(th - th0);
            tau = next;
            x = &m * &x;
        }
        assert!(worst < 1e-6, "{worst}");
        assert!((th - 1.0).abs() < 0.05, "settles: {th}");
        assert!(l.position_radius(k) < 1.0);
        let (mut lo, mut hi) = (k, 1e6);
        for _ in 0..60 {
            let mid = (lo * hi).sqrt();
            if l.position_radius(mid) < 1.0 { lo = mid } else { hi = mid }
        }
        // Continuous, this cascade is stable for every k (a second-order loop); the delays
        // bound it — far above any well-damped gain, so the certificate's stability check
        // is necessary, not sufficient, and `design tune` places k by damping.
        eprintln!("largest stable position gain: {lo:.3} 1/s (speed loop k_p/J = {} 1/s)", kp / j);
        assert!(lo > 100.0 * k && l.position_radius(1e6) > 1.0, "{lo}");
        assert!((l.position_radius(0.0) - 1.0).abs() < 1e-9);
    }
}
