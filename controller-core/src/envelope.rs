//! The operating envelope: which torque the current limit and the bus allow at a speed, and
//! the current references (i_d*, i_q*) that deliver a torque with the most flux the voltage
//! allows — field weakening above base speed and the breakdown-torque (maximum torque per
//! volt) limit, from one steady-state model.
//!
//! **Model** (the standard dq model at steady state in the rotor-flux frame, seed 000 eqs.
//! (1)–(9) with `ψ_qr = 0`, `ψ_r = L_m·i_d`). With the *slip ratio* `r = i_q/i_d`:
//!
//! ```text
//! ω_sl = r/T_r                     (eq. (7))
//! ω_e  = p·ω_m + r/T_r
//! v_d  = i_d·(R_s − ω_e·σL_s·r)
//! v_q  = i_d·(R_s·r + ω_e·L_s)      so |v| = i_d·g(r),  g(r)² = v_d² + v_q² at i_d = 1
//! |i|  = i_d·√(1 + r²)
//! T    = K·i_d²·r,  K = (3/2)·p·L_m²/L_r
//! ```
//!
//! At a slip ratio r the d-axis current can be at most
//! `i_d,max(r)² = min(i_d,rated², V²/g(r)², I²/(1 + r²))` (rated flux, voltage budget V,
//! current limit I), so the largest torque at that ratio is `T(r) = K·r·i_d,max(r)²`. The
//! **envelope** `T_max = max_r T(r)` is found by a coarse scan of r (T(r) is not unimodal
//! when generating: towards zero stator frequency the voltage bound loosens and a second,
//! lower maximum appears) refined by a golden-section search; the **reference** for a
//! torque `|T*| < T_max` is the smallest r with `T(r) = |T*|` — first tried at the rated flux
//! (one evaluation), else by bisection on `[0, r_opt]`, the envelope's rising side (where
//! T(r) is assumed monotone: it is while the envelope's maximum is the first one, as on the
//! shipped motor) — with `i_d* = i_d,max(r)`, `i_q* = r·i_d*`: the smallest r allows the
//! largest `i_d = √(T*/(K·r))`, i.e.
//! the most flux, hence the least slip, that delivers T* within the limits (not the least
//! current: at light load below base speed it keeps the rated flux).
//! Below base speed that is the rated flux; above it the flux falls with speed (field
//! weakening, the voltage bound active); at high speed the optimum sits at the
//! breakdown ratio, the maximum of r/g(r)² (maximum torque per volt). Regeneration is the
//! mirror image: `(ω_m, r) → (−ω_m, −r)` leaves |v| unchanged.
//!
//! **Motoring: no more flux than no load allows.** The rated-flux bound is lowered to the
//! flux whose no-load voltage fits the budget, `i_d ≤ V/g(0)`; motoring never needs more (the
//! load only adds voltage: g(r) ≥ g(0)).
//!
//! **Generating: the most flux a reversal can still hold within the current limit.** Braking,
//! the stator resistance's drop subtracts from the back-EMF, so more flux fits the bus and
//! gives more braking torque — until the torque reverses or the bridge trips: the back-EMF
//! of that flux, `E = ω_r·(L_m/L_r)·ψ_r = ω_r·(L_m²/L_r)·i_d` (slip ≈ 0 at the reversal),
//! then meets the bus. Whatever the current loops then ask, the voltage `E + Z·i` with
//! `Z = R_s + jω_r·σL_s` fits `V` for some `|i| ≤ I` exactly when `E ≤ V + |Z|·I`: the loops
//! (or, the bridge off, the diodes clamping to at least `V`) hold the current within the
//! limit while the flux falls. So generating
//!
//! ```text
//! i_d ≤ (V + I·√(R_s² + (ω_r·σL_s)²)) / (|ω_r|·L_m²/L_r)
//! ```
//!
//! — from the motor, the bus and the current limit, not fitted (issue 52: the no-load cap
//! it replaces left up to 45 % of the shipped motor's braking torque unused above base
//! speed; `tests::a_braking_flux_can_always_be_held_within_the_current_limit`). The drive
//! forces that flux down at a reversal ([`crate::drive`]).
//!
//! R_s is kept: on a small motor (DeLorenzo: R_s·i_q ≈ 50 V of a 179 V limit) the R_s-free
//! ellipse and breakdown ratio `1/σ` are far off (`tests::breakdown_ratio_with_and_without_rs`).
//!
//! The voltage budget V is the caller's: the drive passes a margin below the linear limit
//! `V_dc/√3`, corrected by a slow regulator on the voltage the current loops actually ask
//! for ([`crate::drive`]), so that parameter error cannot push them into saturation.
//!
//! Cost: evaluations of `T(r)` (each ≈ 20 multiply–adds and one division). The envelope,
//! [`SCAN_POINTS`] + [`GOLDEN_STEPS`] + 2 of them, is remade every
//! [`ENVELOPE_REFRESH_SLOW_STEPS`] slow steps; the point for each slow step's torque is one
//! evaluation below the envelope's voltage and current limits, and [`BISECTION_STEPS`] + 3
//! where one of them binds.

use crate::motor::MotorParams;
use crate::num::{Scalar, finite_positive, min_f32};

/// Points of the coarse scan of T(r) over `(0, 2/σ]` that brackets the envelope's maximum.
/// T(r) is not unimodal when generating: towards zero stator frequency the voltage bound
/// loosens and a second, lower maximum appears (the current bound caps it); the scan finds
/// the global one, and the first ratio that reaches a torque.
pub const SCAN_POINTS: u32 = 16;
/// Golden-section steps for the envelope's slip ratio within the scan's bracket (2/16 of
/// the range): it shrinks to 0.618^16 ≈ 4.5e-4 of its width, 5.6e-5 of the range (T is flat
/// at its maximum: the torque error is far smaller).
pub const GOLDEN_STEPS: u32 = 16;
/// Bisection steps for a torque below the envelope: the ratio to 2^-18 ≈ 3.8e-6 of the
/// bracket.
pub const BISECTION_STEPS: u32 = 18;

crate::raw::raw_struct! {
    /// Steady-state machine constants of the envelope (f32, derived at construction).
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct EnvelopeConfig {
        rs_ohm: f32,
        ls_h: f32,
        sigma_ls_h: f32,
        inv_tr_per_s: f32,
        pole_pairs: f32,
        /// K = (3/2)·p·L_m²/L_r: torque per (i_d²·r), N·m/A².
        k_nm_per_a2: f32,
        /// L_m/L_r.
        lm_over_lr: f32,
        /// L_m·R_r/L_r: slip speed per (i_q/ψ_r), electrical rad/s·Wb/A.
        slip_gain: f32,
        /// Upper end of the slip-ratio search, 2/σ (the R_s-free breakdown ratio is 1/σ).
        r_max: f32,
    }
}

/// One operating point: the current references and the torque limit at this speed and bus.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct OperatingPoint {
    /// d-axis current reference, A (≥ 0).
    pub i_d_a: f32,
    /// q-axis current reference, A (the sign of the torque).
    pub i_q_a: f32,
    /// Largest torque magnitude in the torque's direction, N·m.
    pub torque_max_nm: f32,
}

impl EnvelopeConfig {
    /// The constants of `motor`.
    pub fn new(motor: &MotorParams) -> Self {
        let f = f32::from_f64;
        Self {
            rs_ohm: f(motor.rs_ohm()),
            ls_h: f(motor.ls_h()),
            sigma_ls_h: f(motor.sigma() * motor.ls_h()),
            inv_tr_per_s: f(1.0 / motor.tr_s()),
            pole_pairs: f32::from(motor.pole_pairs()),
            k_nm_per_a2: f(motor.torque_factor() * motor.lm_h()),
            lm_over_lr: f(motor.lm_h() / motor.lr_h()),
            slip_gain: f(motor.lm_h() * motor.rr_ohm() / motor.lr_h()),
            r_max: f(2.0 / motor.sigma()),
        }
    }

    /// The same machine with every inductance × `scale` (L_s, L_r, L_m alike, so σ and
    /// L_m/L_r stay; T_r = L_r/R_r and K ∝ L_m²/L_r scale with it): the drive's model once
    /// the magnetizing fit has measured the inductance ([`crate::mras`]). Exact at 1.
    pub fn with_inductance_scale(&self, scale: f32) -> Self {
        Self {
            ls_h: self.ls_h * scale,
            sigma_ls_h: self.sigma_ls_h * scale,
            inv_tr_per_s: self.inv_tr_per_s / scale,
            k_nm_per_a2: self.k_nm_per_a2 * scale,
            ..*self
        }
    }

    /// The machine as the drive has identified it: every inductance × `l_scale`
    /// ([`Self::with_inductance_scale`]) and the rotor resistance × `rr_scale` (T_r = L_r/R_r
    /// and the slip per `i_q/ψ_r`, `L_m·R_r/L_r`, with it) — the estimates the field
    /// orientation runs on (the magnetizing fit's, then the rotor-resistance law's,
    /// [`crate::mras`]), so that the envelope asks for no more voltage than the motor as it is
    /// now needs. On the motor file's rotor, the shipped drive's perturbed motor at 4 kHz, at
    /// its box's corner of a hot stator and rotor in saturated iron (R_s × 1.5, R_r × 2,
    /// L × 0.6), was given τ_max at standstill — its slip, and the voltage it takes, twice
    /// what the envelope counted —, more than that machine takes on a 310 V bus, and tripped
    /// `LossOfControl` 21 ms into the speed step (`hil-sim` test
    /// `a_hot_motor_accelerates_from_rest_on_the_torque_its_bus_gives`). The stator
    /// resistance stays the file's: the magnetizing fit's (`Fitted::stator_resistance_ohm`)
    /// carries the dead time's residual voltage at the magnetizing current, which taken as a
    /// resistance shrinks the envelope of a cold stator. Exact at 1, 1.
    pub fn identified(&self, l_scale: f32, rr_scale: f32) -> Self {
        let l = self.with_inductance_scale(l_scale);
        Self { inv_tr_per_s: l.inv_tr_per_s * rr_scale, slip_gain: l.slip_gain * rr_scale, ..l }
    }

    /// The same machine with its magnetizing inductance × `scale` and its leakages as they
    /// are (`L_s − L_m`, `L_r − L_m`: leakage flux runs in air and does not saturate; the
    /// rotor resistance kept): a saturating machine at a point of its curve (issue 50) — with
    /// [`Self::with_inductance_scale`] the stator's transient inductance σL_s would scale
    /// with the chord, 1.35× at the unsaturated end of the 300 W motor's twin. Exact at 1 (to
    /// rounding).
    pub fn with_magnetizing_scale(&self, scale: f32) -> Self {
        let lm2_over_lr = self.lm2_over_lr_h();
        let lm = lm2_over_lr / self.lm_over_lr;
        let lr = lm / self.lm_over_lr;
        let rr = self.slip_gain * lr / lm;
        let (lm_new, lr_new) = (lm * scale, lr - lm + lm * scale);
        let ls_new = self.ls_h - lm + lm_new;
        let lm2_over_lr_new = lm_new * lm_new / lr_new;
        let sigma_ls_h = ls_new - lm2_over_lr_new;
        Self {
            ls_h: ls_new,
            sigma_ls_h,
            inv_tr_per_s: rr / lr_new,
            k_nm_per_a2: 1.5 * self.pole_pairs * lm2_over_lr_new,
            lm_over_lr: lm_new / lr_new,
            slip_gain: lm_new * rr / lr_new,
            r_max: 2.0 * ls_new / sigma_ls_h,
            ..*self
        }
    }

    /// `L_m²/L_r`, H: the rotor-flux path's inductance seen from the stator.
    pub fn lm2_over_lr_h(&self) -> f32 {
        self.k_nm_per_a2 / (1.5 * self.pole_pairs)
    }

    /// Pole pairs p.
    pub fn pole_pairs(&self) -> f32 {
        self.pole_pairs
    }

    /// `L_m/L_r`.
    pub fn lm_over_lr(&self) -> f32 {
        self.lm_over_lr
    }

    /// The no-load base speed on the voltage `v_max_v`, mechanical rad/s: where the d-axis
    /// current `i_d_a` alone (the rated flux's, no torque) needs all of it,
    /// `R_s² + (p·ω·L_s)² = (V/i_d)²` — above it the flux the bus allows falls as 1/ω (field
    /// weakening); 0 where even standstill needs more (R_s·i_d > V).
    #[inline]
    pub fn no_load_base_speed_rad_s(&self, i_d_a: f32, v_max_v: f32) -> f32 {
        let z = v_max_v / crate::num::max_f32(i_d_a, 1e-9);
        crate::num::sqrt_f32(crate::num::max_f32(z * z - self.rs_ohm * self.rs_ohm, 0.0))
            / (self.pole_pairs * self.ls_h)
    }

    /// `g(0)²`: the stator voltage per A of i_d at no load (r = 0) and electrical rotor
    /// speed `w_r`, `R_s² + (w_r·L_s)²`.
    #[inline]
    fn no_load_g2(&self, w_r: f32) -> f32 {
        let x = w_r * self.ls_h;
        self.rs_ohm * self.rs_ohm + x * x
    }

    /// Generating at electrical rotor speed `w_r` (< 0, mirrored), the largest `i_d²` whose
    /// back-EMF a torque reversal or a trip holds within the current limit `i_max_a` on the
    /// voltage `v_max_v`: `((V + I·|Z|)/(|ω_r|·L_m²/L_r))²`, `|Z|² = R_s² + (ω_r·σL_s)²`
    /// (the module's doc). `L_m²/L_r = L_s − σL_s`. Infinite at standstill.
    #[inline]
    fn reversible_id2(&self, w_r: f32, v_max_v: f32, i_max_a: f32) -> f32 {
        let x = w_r * self.sigma_ls_h;
        let e_max = v_max_v + i_max_a * crate::num::sqrt_f32(self.rs_ohm * self.rs_ohm + x * x);
        let id = e_max / (w_r.abs() * (self.ls_h - self.sigma_ls_h));
        id * id
    }

    /// `i_d,max(r)²` at electrical rotor speed `w_r` (in the motoring direction), for rated
    /// `i_d²`, voltage budget `V²` and current limit `I²`.
    /// Out of line: the envelope's solver calls it in ten places (inlined, 748 B of flash).
    #[inline(never)]
    fn id2_max(&self, r: f32, w_r: f32, id2_rated: f32, v2: f32, i2: f32) -> f32 {
        let w_e = w_r + r * self.inv_tr_per_s;
        let vd = self.rs_ohm - w_e * self.sigma_ls_h * r;
        let vq = self.rs_ohm * r + w_e * self.ls_h;
        let g2 = vd * vd + vq * vq; // ≥ R_s²·(1 + r²) > 0
        min_f32(min_f32(id2_rated, v2 / g2), i2 / (1.0 + r * r))
    }

    /// `T(r)/K`.
    #[inline]
    fn torque_per_k(&self, r: f32, w_r: f32, id2_rated: f32, v2: f32, i2: f32) -> f32 {
        r * self.id2_max(r, w_r, id2_rated, v2, i2)
    }

    /// The limits of one slow step, checked: `None` for a non-finite or non-positive limit or
    /// a non-finite speed. Returns `(w_r, id2r, v2, i2)` for the torque direction `sign`:
    /// the electrical rotor speed mirrored onto motoring, the rated-flux bound capped at the
    /// no-load flux (motoring) or the reversible flux (generating: [`Self::reversible_id2`]),
    /// V², I².
    #[inline]
    fn limits(
        &self,
        sign: f32,
        omega_m_rad_s: f32,
        i_d_rated_a: f32,
        v_max_v: f32,
        i_max_a: f32,
    ) -> Option<(f32, f32, f32, f32)> {
        let ok = finite_positive; // false for NaN
        if !(ok(i_d_rated_a) && ok(v_max_v) && ok(i_max_a) && omega_m_rad_s.is_finite()) {
            return None;
        }
        // Mirror regeneration onto motoring: r ≥ 0 below.
        let w_r = sign * self.pole_pairs * omega_m_rad_s;
        let (v2, i2) = (v_max_v * v_max_v, i_max_a * i_max_a);
        let id2_cap =
            if w_r >= 0.0 { v2 / self.no_load_g2(w_r) } else { self.reversible_id2(w_r, v_max_v, i_max_a) };
        Some((w_r, min_f32(i_d_rated_a * i_d_rated_a, id2_cap), v2, i2))
    }

    /// The envelope at mechanical speed `omega_m_rad_s` in the torque direction `sign` (±1),
    /// with rated d-axis current `i_d_rated_a`, voltage budget `v_max_v` (peak phase voltage)
    /// and current limit `i_max_a`: the largest torque and the slip ratio that gives it. A
    /// coarse scan ([`SCAN_POINTS`]) refined by [`GOLDEN_STEPS`] of golden section — the
    /// expensive part, which the drive refreshes every [`ENVELOPE_REFRESH_SLOW_STEPS`] slow
    /// steps (and at once when the torque changes direction). Bad limits give a zero envelope.
    #[inline(never)]
    pub fn envelope(
        &self,
        sign: f32,
        omega_m_rad_s: f32,
        i_d_rated_a: f32,
        v_max_v: f32,
        i_max_a: f32,
    ) -> Envelope {
        let sign = if sign < 0.0 { -1.0 } else { 1.0 };
        let Some((w_r, id2r, v2, i2)) = self.limits(sign, omega_m_rad_s, i_d_rated_a, v_max_v, i_max_a)
        else {
            return Envelope { torque_max_nm: 0.0, r_opt: 0.0, sign };
        };
        let t = |r: f32| self.torque_per_k(r, w_r, id2r, v2, i2);
        let dr = self.r_max * (1.0 / SCAN_POINTS as f32);
        let (mut j_max, mut t_max) = (0u32, 0.0f32);
        for j in 1..=SCAN_POINTS {
            let tj = t(dr * j as f32);
            if tj > t_max {
                (j_max, t_max) = (j, tj);
            }
        }
        // Golden section for the maximum between the scan's neighbours of its best point.
        const INV_PHI: f32 = 0.618_034;
        let (mut a, mut b) = (dr * j_max.saturating_sub(1) as f32, dr * (j_max + 1) as f32);
        let mut c = b - INV_PHI * (b - a);
        let mut d = a + INV_PHI * (b - a);
        let (mut tc, mut td) = (t(c), t(d));
        for _ in 0..GOLDEN_STEPS {
            if tc > td {
                b = d;
                d = c;
                td = tc;
                c = b - INV_PHI * (b - a);
                tc = t(c);
            } else {
                a = c;
                c = d;
                tc = td;
                d = a + INV_PHI * (b - a);
                td = t(d);
            }
        }
        let (r_opt, t_opt) = if tc > td { (c, tc) } else { (d, td) };
        Envelope { torque_max_nm: self.k_nm_per_a2 * t_opt, r_opt, sign }
    }

    /// The operating point for torque `torque_nm` (in `env`'s direction) on the envelope
    /// `env` (made for about the same speed and bus): the smallest slip ratio that gives the
    /// torque, and the most flux with it. First the rated (capped) flux: if the torque needs
    /// no more voltage or current than the limits allow there, that is the point — one
    /// evaluation, the common case below base speed. Otherwise bisection ([`BISECTION_STEPS`])
    /// on `[0, env.r_opt]`, the envelope's rising side; a torque beyond the envelope gets
    /// `env.r_opt`. The point's `torque_max_nm` is `env`'s. Bad limits give a zero point.
    #[inline(never)]
    pub fn point(
        &self,
        env: &Envelope,
        torque_nm: f32,
        omega_m_rad_s: f32,
        i_d_rated_a: f32,
        v_max_v: f32,
        i_max_a: f32,
    ) -> OperatingPoint {
        let Some((w_r, id2r, v2, i2)) = self.limits(env.sign, omega_m_rad_s, i_d_rated_a, v_max_v, i_max_a)
        else {
            return OperatingPoint::default();
        };
        if !torque_nm.is_finite() {
            return OperatingPoint::default();
        }
        let wanted = torque_nm.abs() / self.k_nm_per_a2;
        let r_rated = wanted / id2r;
        let r = if self.id2_max(r_rated, w_r, id2r, v2, i2) >= id2r {
            r_rated
        } else if wanted >= self.torque_per_k(env.r_opt, w_r, id2r, v2, i2) {
            env.r_opt
        } else {
            let (mut lo, mut hi) = (0.0f32, env.r_opt);
            for _ in 0..BISECTION_STEPS {
                let mid = 0.5 * (lo + hi);
                if self.torque_per_k(mid, w_r, id2r, v2, i2) < wanted {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            hi
        };
        let i_d_a = crate::num::sqrt_f32(self.id2_max(r, w_r, id2r, v2, i2));
        OperatingPoint { i_d_a, i_q_a: env.sign * r * i_d_a, torque_max_nm: env.torque_max_nm }
    }

    /// [`Self::envelope`] and [`Self::point`] in one: the operating point for torque
    /// `torque_nm` at this speed and bus, limited to the envelope.
    pub fn operating_point(
        &self,
        torque_nm: f32,
        omega_m_rad_s: f32,
        i_d_rated_a: f32,
        v_max_v: f32,
        i_max_a: f32,
    ) -> OperatingPoint {
        let env = self.envelope(torque_nm, omega_m_rad_s, i_d_rated_a, v_max_v, i_max_a);
        self.point(&env, torque_nm, omega_m_rad_s, i_d_rated_a, v_max_v, i_max_a)
    }
}

/// The envelope at one speed, bus and torque direction ([`EnvelopeConfig::envelope`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Envelope {
    /// Largest torque magnitude, N·m.
    pub torque_max_nm: f32,
    /// The slip ratio i_q/i_d that gives it.
    r_opt: f32,
    /// Torque direction, ±1.
    sign: f32,
}

impl Envelope {
    /// No torque (before the first envelope is made).
    pub const ZERO: Envelope = Envelope { torque_max_nm: 0.0, r_opt: 0.0, sign: 1.0 };

    /// The torque direction it was made for, ±1.
    pub fn sign(&self) -> f32 {
        self.sign
    }
}

/// The drive remakes its envelope every this many slow steps (8 ms at the shipped 2 kHz):
/// speed and bus change little in that time (400 rad/s² of the shipped drive's acceleration is
/// 3.2 rad/s), and the point between refreshes needs one evaluation in the common case.
pub const ENVELOPE_REFRESH_SLOW_STEPS: u16 = 16;

impl EnvelopeConfig {
    /// The stator voltage (v_d, v_q) of the dq model at steady state in the rotor-flux frame,
    /// with the flux `psi_r_wb` held (not necessarily L_m·i_d): `v_d = R_s·i_d − ω_e·σL_s·i_q`,
    /// `v_q = R_s·i_q + ω_e·(σL_s·i_d + (L_m/L_r)·ψ_r)` at electrical frequency `w_e` (seed 000
    /// eqs. (1)–(4) at steady state). The one place of this equation: the present-flux limit
    /// ([`Self::i_q_max_at_flux`]) and the drive's encoder check use it; the envelope's g(r)
    /// is the same equation at ψ_r = L_m·i_d, written per A of i_d.
    #[inline]
    pub fn stator_voltage(&self, i_d_a: f32, i_q_a: f32, w_e: f32, psi_r_wb: f32) -> (f32, f32) {
        let vd = self.rs_ohm * i_d_a - w_e * self.sigma_ls_h * i_q_a;
        let vq = self.rs_ohm * i_q_a + w_e * (self.sigma_ls_h * i_d_a + self.lm_over_lr * psi_r_wb);
        (vd, vq)
    }

    /// The largest d-axis current (A), at most `i_d_a` and at least `−i_max_a`, whose voltage
    /// fits the budget `v_max_v` *now* with the q-axis current `i_q_a`, the rotor flux at
    /// `psi_r_wb` and mechanical speed `omega_m_rad_s`: where the back-EMF of a flux that has
    /// not yet fallen (a torque reversal from braking, a speed rising faster than the rotor
    /// lets its flux fall) leaves no voltage, a negative i_d holds the stator voltage within
    /// the bus and forces the flux down (`dψ_r/dt = (L_m·i_d − ψ_r)/T_r`) instead of leaving
    /// the loops saturated and the current uncontrolled. The stator voltage
    /// ([`Self::stator_voltage`]) at `ω_e = ω_r + (L_m·R_r/L_r)·i_q/ψ_r` is quadratic in i_d,
    /// `|v|² = a·i_d² + 2b·i_d + c` with `a = R_s² + (ω_e·σL_s)²`, `b = ω_e²·σL_s·(L_m/L_r)·ψ_r`
    /// and `c = (ω_e·σL_s·i_q)² + (R_s·i_q + ω_e·(L_m/L_r)·ψ_r)² − V²`: `i_d` itself when it
    /// fits, else the larger root, else (no root: more back-EMF than the current limit holds,
    /// which the generating envelope's flux bound excludes) the current of least voltage,
    /// `−b/a`.
    #[inline(never)]
    pub fn d_current_within_voltage(
        &self,
        psi_r_wb: f32,
        i_d_a: f32,
        i_q_a: f32,
        omega_m_rad_s: f32,
        v_max_v: f32,
        i_max_a: f32,
    ) -> f32 {
        let psi = if psi_r_wb > 1e-3 { psi_r_wb } else { 1e-3 };
        let w_r = self.pole_pairs * omega_m_rad_s;
        let w_e = w_r + self.slip_gain * i_q_a / psi;
        let v2 = v_max_v * v_max_v;
        if self.voltage2_at_flux(i_d_a, i_q_a, w_r, psi) <= v2 || !(v2.is_finite() && w_e.is_finite()) {
            return i_d_a;
        }
        let x = w_e * self.sigma_ls_h;
        let e = w_e * self.lm_over_lr * psi;
        let (xq, vq0) = (x * i_q_a, self.rs_ohm * i_q_a + e);
        let a = self.rs_ohm * self.rs_ohm + x * x;
        let b = x * e;
        let disc = b * b - a * (xq * xq + vq0 * vq0 - v2);
        let root = if disc > 0.0 { (crate::num::sqrt_f32(disc) - b) / a } else { -b / a };
        root.limit(-i_max_a, i_d_a)
    }

    /// `|v|²` of [`Self::stator_voltage`] with the flux `psi_r_wb` held, at electrical rotor
    /// speed `w_r` plus the slip of `i_q_a`, `(L_m·R_r/L_r)·i_q/ψ_r`. Out of line: the rare
    /// paths (the least voltage's search, the forcing's first test) call it.
    #[inline(never)]
    fn voltage2_at_flux(&self, i_d_a: f32, i_q_a: f32, w_r: f32, psi_r_wb: f32) -> f32 {
        let (vd, vq) = self.stator_voltage(i_d_a, i_q_a, w_r + self.slip_gain * i_q_a / psi_r_wb, psi_r_wb);
        vd * vd + vq * vq
    }

    /// The largest |i_q| (A) the voltage budget `v_max_v` allows *now*, with the rotor flux
    /// at `psi_r_wb` (not yet at its steady state: it changes with T_r) and the d-axis current
    /// at `i_d_a`, at mechanical speed `omega_m_rad_s`, in the direction `sign` of the torque
    /// (±1), at most `i_q_cap_a`. The stator voltage of the dq model with the flux held:
    /// `v_d = R_s·i_d − ω_e·σL_s·i_q`, `v_q = R_s·i_q + ω_e·(σL_s·i_d + (L_m/L_r)·ψ_r)`,
    /// `ω_e = p·ω_m + (L_m·R_r/L_r)·i_q/ψ_r`. While field weakening lowers the flux, the back-EMF
    /// of the flux that is still there leaves less voltage for i_q than the steady state
    /// would: the torque is held to what the bus can drive until the flux has fallen, so that
    /// the current loops are not pushed into the voltage limit. Bisection on i_q between the
    /// least current that fits and the cap: [`BISECTION_STEPS`] evaluations. Motoring |v|
    /// grows with i_q, and zero is that least current (returned when even it does not fit);
    /// generating on a flux whose back-EMF alone exceeds the budget, the braking current
    /// lowers |v| — the current of least voltage is found first ([`GOLDEN_STEPS`], twice
    /// each), and returned when nothing fits.
    #[inline(never)]
    pub fn i_q_max_at_flux(
        &self,
        psi_r_wb: f32,
        i_d_a: f32,
        omega_m_rad_s: f32,
        v_max_v: f32,
        i_q_cap_a: f32,
        sign: f32,
    ) -> f32 {
        let psi = if psi_r_wb > 1e-3 { psi_r_wb } else { 1e-3 };
        let w_r = self.pole_pairs * omega_m_rad_s;
        let v2 = v_max_v * v_max_v;
        // The bisection's test inline (the common path: 474 instructions per call, against
        // 798 with the evaluation out of line); the rare golden section's out of line.
        let fits = |i_q: f32| {
            let i_q = sign * i_q;
            let (vd, vq) = self.stator_voltage(i_d_a, i_q, w_r + self.slip_gain * i_q / psi, psi);
            vd * vd + vq * vq <= v2 // false for NaN
        };
        let v2_at = |i_q: f32| self.voltage2_at_flux(i_d_a, sign * i_q, w_r, psi);
        if fits(i_q_cap_a) {
            return i_q_cap_a;
        }
        let mut lo = 0.0f32;
        if !fits(0.0) {
            if sign * omega_m_rad_s >= 0.0 {
                // Motoring: |v| grows with i_q, nothing fits.
                return 0.0;
            }
            // Not even no torque fits: generating, the braking current lowers the voltage (the
            // stator resistance's drop, a lower stator frequency), so the currents that fit
            // start above zero. The current of least voltage (golden section: |v|² is convex
            // in i_q over the range): from there up, if it fits; else it, the nearest to fitting.
            const INV_PHI: f32 = 0.618_034;
            let (mut a, mut b) = (0.0f32, i_q_cap_a);
            for _ in 0..GOLDEN_STEPS {
                let (c, d) = (b - INV_PHI * (b - a), a + INV_PHI * (b - a));
                if v2_at(c) < v2_at(d) {
                    b = d;
                } else {
                    a = c;
                }
            }
            lo = 0.5 * (a + b);
            if !fits(lo) {
                return lo;
            }
        }
        let mut hi = i_q_cap_a;
        for _ in 0..BISECTION_STEPS {
            let mid = 0.5 * (lo + hi);
            if fits(mid) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        lo
    }
}

impl EnvelopeConfig {}

/// The same model in f64 on a dense grid of slip ratios: the reference the tests (and the
/// simulator's envelope check) hold [`EnvelopeConfig::operating_point`] against. Returns
/// `(T_max, i_d, i_q)` at the best of `n` ratios in `(0, 2/σ]`.
pub fn envelope_by_grid(
    motor: &MotorParams,
    omega_m_rad_s: f64,
    i_d_rated_a: f64,
    v_max_v: f64,
    i_max_a: f64,
    n: u32,
) -> (f64, f64, f64) {
    let (rs, ls, sls) = (motor.rs_ohm(), motor.ls_h(), motor.sigma() * motor.ls_h());
    let k = motor.torque_factor() * motor.lm_h();
    let w_r = f64::from(motor.pole_pairs()) * omega_m_rad_s;
    let r_max = 2.0 / motor.sigma();
    // Motoring, no more flux than no load allows; generating, no more than a reversal holds
    // within the current limit (see the module docs).
    let id2_cap = if w_r >= 0.0 {
        v_max_v * v_max_v / (rs * rs + (w_r * ls) * (w_r * ls))
    } else {
        let id = (v_max_v + i_max_a * libm::hypot(rs, w_r * sls)) / (w_r.abs() * (ls - sls));
        id * id
    };
    let id2_rated = (i_d_rated_a * i_d_rated_a).min(id2_cap);
    let mut best = (0.0, 0.0, 0.0);
    for j in 1..=n {
        let r = r_max * f64::from(j) / f64::from(n);
        let w_e = w_r + r / motor.tr_s();
        let (vd, vq) = (rs - w_e * sls * r, rs * r + w_e * ls);
        let g2 = vd * vd + vq * vq;
        let id2 = id2_rated.min(v_max_v * v_max_v / g2).min(i_max_a * i_max_a / (1.0 + r * r));
        let t = k * r * id2;
        if t > best.0 {
            let id = libm::sqrt(id2);
            best = (t, id, r * id);
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    fn motor() -> MotorParams {
        MotorParams::delorenzo_dl10115a1().unwrap()
    }

    const V: f32 = 178.979_5; // 310 V / √3
    const ID_RATED: f32 = 0.9 / 1.42;

    /// The solver's envelope against a 200 000-point f64 grid, from standstill to 2.2× the
    /// no-load base speed, both torque directions, on three buses: within 0.05 %.
    #[test]
    fn envelope_matches_a_dense_grid() {
        let c = EnvelopeConfig::new(&motor());
        let mut worst = 0.0f64;
        for v in [V, 0.7 * V, 1.3 * V] {
            for k in -22..=22 {
                let w = 20.0 * k as f32;
                for sign in [1.0f32, -1.0] {
                    let op = c.operating_point(sign * 1e3, w, ID_RATED, v, 4.0);
                    let (t_grid, _, _) = envelope_by_grid(
                        &motor(),
                        f64::from(sign * w),
                        f64::from(ID_RATED),
                        f64::from(v),
                        4.0,
                        200_000,
                    );
                    let e = (f64::from(op.torque_max_nm) - t_grid).abs() / t_grid;
                    worst = worst.max(e);
                    assert!(e < 5e-4, "ω {w} sign {sign} V {v}: {} vs {t_grid}", op.torque_max_nm);
                    // The point delivers the envelope's torque (K·i_d·i_q, sign included).
                    let k = motor().torque_factor() * motor().lm_h();
                    let t_pt = k * f64::from(op.i_d_a) * f64::from(op.i_q_a);
                    assert!((t_pt - f64::from(sign) * t_grid).abs() < 1e-3 * t_grid, "{t_pt} vs {t_grid}");
                }
            }
        }
        eprintln!("envelope: worst relative error against the grid {worst:.2e}");
    }

    /// Below the envelope the point delivers the torque asked, within every limit, and
    /// with the most flux: no grid ratio that can deliver it does so with a larger i_d.
    #[test]
    fn torque_below_the_envelope_with_the_most_flux() {
        let m = motor();
        let c = EnvelopeConfig::new(&m);
        let k = m.torque_factor() * m.lm_h();
        for w in [0.0f32, 100.0, 195.7, 300.0, 391.0, -250.0] {
            for frac in [0.0f32, 0.1, 0.5, 0.9, 0.99] {
                for sign in [1.0f32, -1.0] {
                    // The envelope in this torque direction (motoring and generating differ).
                    let t_max = c.operating_point(sign * 1e3, w, ID_RATED, V, 4.0).torque_max_nm;
                    let t = sign * frac * t_max;
                    let op = c.operating_point(t, w, ID_RATED, V, 4.0);
                    let t_pt = (k as f32) * op.i_d_a * op.i_q_a;
                    assert!((t_pt - t).abs() <= 1e-3 * t_max, "ω {w} T {t}: {t_pt}");
                    assert!(op.i_d_a <= ID_RATED * (1.0 + 1e-6));
                    assert!(libm::hypotf(op.i_d_a, op.i_q_a) <= 4.0 * (1.0 + 1e-5));
                    // Voltage at that point within the budget.
                    let (id, iq) = (f64::from(op.i_d_a), f64::from(op.i_q_a));
                    let w_e = f64::from(w) + if id > 0.0 { iq / (id * m.tr_s()) } else { 0.0 };
                    let vd = m.rs_ohm() * id - w_e * m.sigma() * m.ls_h() * iq;
                    let vq = m.rs_ohm() * iq + w_e * m.ls_h() * id;
                    assert!(vd.hypot(vq) <= f64::from(V) * (1.0 + 1e-4), "ω {w} T {t}: |v| {}", vd.hypot(vq));
                    // Most flux: on a fine grid of ratios, none delivering |T| has a larger i_d.
                    // A zero torque is motoring's (−0 too).
                    let mirror = if t < 0.0 { -1.0 } else { 1.0 };
                    let (sgn_w, tt): (f64, f64) = (mirror * f64::from(w), f64::from(t.abs()));
                    for j in 1..4000 {
                        let r = 30.0 * f64::from(j) / 4000.0;
                        let w_e = sgn_w + r / m.tr_s();
                        let g2 = (m.rs_ohm() - w_e * m.sigma() * m.ls_h() * r).powi(2)
                            + (m.rs_ohm() * r + w_e * m.ls_h()).powi(2);
                        let g0 = m.rs_ohm().powi(2) + (sgn_w * m.ls_h()).powi(2);
                        let id2 = f64::from(ID_RATED * ID_RATED)
                            .min(f64::from(V * V) / g0)
                            .min(f64::from(V * V) / g2)
                            .min(16.0 / (1.0 + r * r));
                        // Feasible at r: the i_d that gives |T| there, √(|T|/(K·r)), is
                        // within i_d,max(r). It must not exceed the point's i_d.
                        if k * r * id2 >= tt * (1.0 + 1e-3) {
                            let id_r = (tt / (k * r)).sqrt();
                            assert!(
                                id_r <= id * (1.0 + 2e-3) + 1e-6,
                                "ω {w} T {t}: r {r} gives it with i_d {id_r}"
                            );
                        }
                    }
                }
            }
        }
    }

    /// Field weakening: at rated flux below the no-load base speed (≈ 196 rad/s here), less
    /// above it, falling roughly as 1/ω; the breakdown ratio with R_s (the optimum's r at
    /// high speed) is far from the R_s-free 1/σ = 15 on this motor.
    #[test]
    fn breakdown_ratio_with_and_without_rs() {
        let m = motor();
        let c = EnvelopeConfig::new(&m);
        let no_load = |w: f32| c.operating_point(0.0, w, ID_RATED, V, 4.0).i_d_a;
        assert!((no_load(0.0) - ID_RATED).abs() < 1e-6);
        assert!((no_load(190.0) - ID_RATED).abs() < 1e-6);
        let (a, b) = (no_load(300.0), no_load(391.0));
        assert!(a < 0.7 * ID_RATED && b < a, "{a} {b}");
        assert!(((a * 300.0) / (b * 391.0) - 1.0).abs() < 0.05);
        let op = c.operating_point(1e3, 391.0, ID_RATED, V, 4.0);
        let r = op.i_q_a / op.i_d_a;
        eprintln!("breakdown ratio at 391 rad/s: {r:.2} (R_s-free: 1/σ = {:.2})", 1.0 / m.sigma());
        assert!((r - 7.96).abs() < 0.1, "{r}");
    }

    /// Generating above base speed the flux is the most whose back-EMF a reversal holds
    /// within the current limit: at the braking point's flux, some |i| ≤ I brings the
    /// stator voltage within the budget (min over |i| ≤ I of |E + Z·i| = E − |Z|·I, f64 from
    /// the motor's parameters), the bound binds where the rated flux does not fit, and the
    /// braking flux is well above the no-load cap's (issue 52: that cap gave 0.55 of the
    /// physical limit at 2× base speed on this motor).
    #[test]
    fn a_braking_flux_can_always_be_held_within_the_current_limit() {
        let m = motor();
        let c = EnvelopeConfig::new(&m);
        let (p, i_max) = (f64::from(m.pole_pairs()), 4.0f32);
        for w in [300.0f32, 391.6] {
            let braking = c.operating_point(-1e3, w, ID_RATED, V, i_max);
            let w_r = p * f64::from(w);
            let psi = m.lm_h() * f64::from(braking.i_d_a);
            let back_emf = w_r * m.lm_h() / m.lr_h() * psi;
            let z = m.rs_ohm().hypot(w_r * m.sigma() * m.ls_h());
            let v_held = back_emf - z * f64::from(i_max);
            eprintln!(
                "at {w} rad/s: braking i_d {:.4} A (ψ_r {psi:.4} Wb), {:.3} N·m; back-EMF {back_emf:.1} V, \
                 {v_held:.1} V held at |i| = I",
                braking.i_d_a, braking.torque_max_nm
            );
            assert!(v_held <= f64::from(V) * (1.0 + 1e-5), "{v_held}");
            assert!(braking.i_d_a <= ID_RATED * (1.0 + 1e-6));
            // More than the no-load cap it replaced allowed, `i_d ≤ V/√(R_s² + (ω_r·L_s)²)`.
            let no_load_cap = f64::from(V) / m.rs_ohm().hypot(w_r * m.ls_h());
            assert!(f64::from(braking.i_d_a) > 1.3 * no_load_cap, "{} vs {no_load_cap}", braking.i_d_a);
        }
        // Over speeds, buses and current limits: never more than a reversal holds, and held
        // exactly where the bound binds (below the rated flux and the point's own limits).
        let mut binding = 0;
        for w in [200.0f32, 300.0, 400.0, 600.0, 800.0] {
            for v in [V, 0.5 * V, 0.25 * V] {
                for i_max in [0.5f32, 1.0, 2.0, 4.0] {
                    let b = c.operating_point(-1e3, w, ID_RATED, v, i_max);
                    let w_r = p * f64::from(w);
                    let back_emf = w_r * m.lm_h() / m.lr_h() * m.lm_h() * f64::from(b.i_d_a);
                    let z = m.rs_ohm().hypot(w_r * m.sigma() * m.ls_h());
                    let held = (back_emf - z * f64::from(i_max)) / f64::from(v);
                    assert!(held <= 1.0 + 1e-5, "{w} rad/s, {v} V, {i_max} A: {held}");
                    binding += usize::from(held > 1.0 - 1e-4);
                }
            }
        }
        // On this motor the point's own voltage and current bounds bind first at most of them
        // (2 of 60 when written): the bound must be reached somewhere, or this checks nothing.
        eprintln!("the reversal bound binds at {binding} of 60 points");
        assert!(binding > 0, "{binding}");
    }

    /// The d-axis current within the voltage at no torque: unchanged where it fits; where
    /// the flux's back-EMF leaves no room, the largest current whose voltage is the budget
    /// (f64 from the stator voltage equation), negative, within the current limit.
    #[test]
    fn a_flux_beyond_the_bus_is_forced_down_within_the_voltage() {
        let m = motor();
        let c = EnvelopeConfig::new(&m);
        let w = 300.0f32;
        let v_at = |i_d: f32, psi: f32| {
            let w_r = f64::from(w) * f64::from(m.pole_pairs());
            let vd = m.rs_ohm() * f64::from(i_d);
            let vq = w_r * (m.sigma() * m.ls_h() * f64::from(i_d) + m.lm_h() / m.lr_h() * f64::from(psi));
            vd.hypot(vq)
        };
        // The no-load flux at this speed fits with its own current.
        let psi_fit = 0.45;
        assert_eq!(c.d_current_within_voltage(psi_fit, psi_fit / 1.42, 0.0, w, V, 4.0), psi_fit / 1.42);
        // The rated flux does not: i_d < 0 with |v| = V.
        let i_d = c.d_current_within_voltage(0.9, ID_RATED, 0.0, w, V, 4.0);
        assert!(i_d < 0.0 && i_d > -4.0, "{i_d}");
        assert!((v_at(i_d, 0.9) / f64::from(V) - 1.0).abs() < 1e-4, "{}", v_at(i_d, 0.9));
        // Braking current subtracts voltage (R_s's drop, a lower stator frequency): less
        // forcing, and |v| = V at the slip of that current.
        let i_q = -3.0f32;
        let i_d_braking = c.d_current_within_voltage(0.9, ID_RATED, i_q, w, V, 4.0);
        let w_e = f64::from(w) + m.rr_ohm() * m.lm_h() / m.lr_h() * f64::from(i_q) / 0.9;
        let (i_d64, i_q64) = (f64::from(i_d_braking), f64::from(i_q));
        let vd = m.rs_ohm() * i_d64 - w_e * m.sigma() * m.ls_h() * i_q64;
        let vq = m.rs_ohm() * i_q64 + w_e * (m.sigma() * m.ls_h() * i_d64 + m.lm_h() / m.lr_h() * 0.9);
        eprintln!(
            "at 300 rad/s and 0.9 Wb: i_d {i_d:.4} A at no torque, {i_d_braking:.4} A braking at {i_q} A"
        );
        assert!(i_d_braking > i_d, "{i_d_braking}");
        assert!(i_d_braking >= ID_RATED || (vd.hypot(vq) / f64::from(V) - 1.0).abs() < 1e-4);
        // A flux no current within the limit holds: the least voltage's current, clamped.
        assert_eq!(c.d_current_within_voltage(5.0, ID_RATED, 0.0, w, V, 1.0), -1.0);
        // Bad input leaves the current as it was.
        assert_eq!(c.d_current_within_voltage(f32::NAN, 0.5, 0.0, w, V, 4.0), 0.5);
    }

    #[test]
    fn bad_limits_give_zero() {
        let c = EnvelopeConfig::new(&motor());
        for (t, w, v) in [(f32::NAN, 0.0, V), (1.0, f32::INFINITY, V), (1.0, 0.0, 0.0), (1.0, 0.0, f32::NAN)]
        {
            assert_eq!(c.operating_point(t, w, ID_RATED, v, 4.0), OperatingPoint::default());
        }
    }
}
