//! The slow step, every N-th period, as named stages: the encoder read (its jump check) and
//! the thermal models → the IFOC's period closed and the field anchored → the current trim →
//! the voltage regulator → the position and speed loops → the operating point (the envelope)
//! → magnetizing or the motion checks → the fast steps' plan → the phase checks.

use super::*;
use crate::envelope::ENVELOPE_REFRESH_SLOW_STEPS;
use crate::frames::{Abc, wrap_angle};
#[cfg(doc)]
use crate::ifoc::IfocConfig;
use crate::mras::{Evidence, FitPeriod};
use crate::num::{Scalar, finite_positive, max_f32, min_f32, sqrt_f32};
use crate::supervisor::phases::leg_sides;
use crate::svpwm;
use crate::vhz::{VhzConfig, VhzReport};

/// A saturating motor's machine model moves this fraction of the way to the chord at its
/// operating point at each refresh while Running (`SlowState::remodel_on_curve`).
const MODEL_CHORD_RELAXATION: f32 = 0.5;

/// Iterations of a saturating motor's inductance from its magnetizing fit
/// (`SlowState::set_inductance_on_curve`): the error shrinks by `1 − L_diff/L_chord` each,
/// 0.66 at the rated flux of motulator's curve — 0.04 of it left after eight.
const FIT_CURVE_ITERATIONS: u32 = 8;

impl SlowState {
    /// The slow step on its inputs: see [`SlowSide::run`].
    /// `vhz`: the V/Hz law's state at the tick, once it runs.
    pub(super) fn step(&mut self, cfg: &DriveConfig, inputs: &SlowInputs, vhz: Option<&VhzReport>) {
        self.mode = inputs.mode;
        if let Mode::Fault(_) = self.mode {
            // A fault of the fast step ended a controlled stop (its pending fault is what
            // latched).
            (self.pending_fault, self.stop_steps_left) = (None, None);
        }
        // On the state the plan they ran on was made in (nothing moves it in between).
        if let Some(a) = inputs.after_slow.as_ref().filter(|_| self.mode == Mode::Running) {
            self.after_slow_checks(cfg, a);
        }
        self.slow_loops(cfg, inputs);
        let m = &inputs.m;
        if self.mode.is_active() && m.is_finite() {
            // V/Hz follows no current reference: the phase window judges the currents against
            // themselves, which leaves its current-sum check (against the law's operating
            // point, the low-pass-filtered current, a slowly turning current read as an open
            // phase: a seized rotor tripped `OpenPhase`). One call of the checks (two, and
            // they went out of line: +40 instructions per slow step, `cost slow_step`).
            let unreferenced = match self.vhz_running(cfg) {
                Some(v) => {
                    self.plan_vhz(cfg, v, inputs, vhz);
                    true
                }
                None => {
                    self.plan(cfg, m.omega_m_rad_s);
                    false
                }
            };
            self.check_phases(cfg, m.i_abc_a, unreferenced, inputs);
        }
    }

    /// V/Hz: no field orientation and no speed loop (the ramp and its limits are the plan's,
    /// `plan_vhz`); of the motion checks, the stall check on the ramp's reference at the speed
    /// `omega_m_rad_s` (the following-error check judges a torque command, which V/Hz has
    /// not). Out of line: in the vector drive's slow step, +44 instructions.
    #[cold]
    #[inline(never)]
    fn vhz_motion_checks(&mut self, cfg: &DriveConfig, omega_m_rad_s: f32) {
        let asked = self.run.vhz_ramp_rad_s.abs() >= STALL_REFERENCE_FACTOR * cfg.motion.stall_speed_rad_s;
        if self.run.motion.stall(&cfg.motion, asked, omega_m_rad_s) {
            self.trip(Fault::Stall);
        }
    }

    /// The V/Hz law, Running on a speed reference (the rotating-current test runs on the
    /// current loops).
    #[inline]
    fn vhz_running<'c>(&self, cfg: &'c DriveConfig) -> Option<&'c VhzConfig> {
        let test = matches!(self.reference, Reference::RotatingCurrent { .. });
        cfg.vhz().filter(|_| self.mode == Mode::Running && !test)
    }

    /// V/Hz, the slow step's plan ([`crate::vhz`]): the ramp of the frequency reference
    /// towards the speed reference at the configured rate, limited — the **current limit and
    /// stall prevention**: while the operating point's current is beyond the references' limit,
    /// or its slip beyond the breakdown's margin ([`VhzConfig::beyond_breakdown`]: a load
    /// beyond the breakdown torque — in field weakening it comes before the current limit, and
    /// the rotor fell out while the ramp ran on to base speed), the ramp turns towards the
    /// rotor's speed (against the slip: a motoring overload slows the field, a braking one
    /// slows the deceleration), and the **bus limit**: generating with the link above the
    /// regeneration limit's start, the ramp holds; then the **field weakening**: the stator
    /// flux the modulator's linear limit at `duty_max` holds at the frequency with the
    /// operating point's resistive drop ([`VhzConfig::flux_within_voltage`]) — the whole
    /// circle: `voltage_margin` is the current loops' headroom, and V/Hz has none.
    #[cold]
    #[inline(never)]
    fn plan_vhz(&mut self, cfg: &DriveConfig, v: &VhzConfig, inputs: &SlowInputs, vhz: Option<&VhzReport>) {
        let m = &inputs.m;
        let (i0, slip, w_s) =
            vhz.map_or((Dq::default(), 0.0, 0.0), |s| (s.i0, s.slip_rad_s, s.omega_s_rad_s));
        let target = match self.reference {
            Reference::Speed(w) => w,
            _ => 0.0,
        };
        let (ramp, step) = (self.run.vhz_ramp_rad_s, v.ramp_step_rad_s());
        let i_max = cfg.ifoc.i_max_a();
        let w_r_e = v.pole_pairs() * ramp;
        let generating = slip * (w_r_e + slip) < 0.0;
        // In field weakening the breakdown is judged on the rotor's measured speed (the
        // observer's without an encoder) and the slip the field turns at against it: while
        // the ramp accelerates into a load, the frequency feedback keeps the field ahead of
        // the ramp's speed by up to (1 + k_w) × the slip filter's lag, and the ramp's speed
        // and the filtered slip both read the rotor ahead of where it is.
        let weakened = self.run.vhz_plan.psi_s_wb < v.psi_s_nom_wb();
        let w_m_e = v.pole_pairs() * m.omega_m_rad_s;
        let overloaded = i0.d * i0.d + i0.q * i0.q > i_max * i_max
            || v.beyond_breakdown(slip, w_r_e, false)
            || (weakened && v.beyond_breakdown(w_s - w_m_e, w_m_e, true));
        let ramp = if overloaded {
            ramp - if slip > 0.0 { step } else { -step }
        } else if generating && m.vdc_v > cfg.regen_start_v {
            ramp
        } else {
            ramp + (target - ramp).limit(-step, step)
        };
        self.run.vhz_ramp_rad_s = ramp;
        self.omega_ref_rad_s = ramp;
        let w_e = v.pole_pairs() * ramp + slip;
        // Weakened for the faster of the plan's frequency and the one the law turned the field
        // at (its frequency feedback moves it away from the plan's in a transient: braking
        // from base speed, the plan's alone left the voltage beyond the hexagon).
        let u_max = svpwm::linear_limit_v(m.vdc_v * cfg.duty_max);
        let psi_s = v.flux_within_voltage(u_max, if w_s.abs() > w_e.abs() { w_s } else { w_e }, i0);
        self.run.vhz_plan = v.plan(ramp, psi_s, self.run.ifoc.inductance_scale());
        self.run.delay_rotation = SinCos::default().rotated((w_e * cfg.delay_s).limit(-0.5, 0.5));
    }

    /// The slow step's first stage, the shaft's and the machine's, which runs whatever the
    /// bridge does (a slow period of [`Drive::hold_step`] too): the encoder read (its
    /// non-finite and jump checks), the rest detector, the thermal models. Returns the
    /// encoder's change, mechanical rad.
    #[inline]
    pub(super) fn track_shaft(&mut self, cfg: &DriveConfig, m: &Measurements) -> f32 {
        // The encoder's readings change only here (the fast step checks the currents and
        // the bus): not finite, in any mode, is the supervisor's non-finite input.
        if !(m.omega_m_rad_s.is_finite() && m.theta_m_rad.is_finite()) {
            self.trip(Fault::NonFiniteInput);
        }
        let step_rad = self.read_encoder(cfg, m.theta_m_rad);
        self.machine.rest.update(&cfg.rest, step_rad);
        self.update_thermal(cfg, m.i_abc_a);
        step_rad
    }

    /// The slow step up to the plan: see [`Drive::slow_step`].
    fn slow_loops(&mut self, cfg: &DriveConfig, inputs: &SlowInputs) {
        let m = &inputs.m;
        let step_rad = self.track_shaft(cfg, m);
        let active = self.mode.is_active();
        if active && m.omega_m_rad_s.abs() > cfg.motion.overspeed_rad_s {
            self.trip(Fault::Overspeed);
        }
        let active = self.mode.is_active();
        if !active {
            self.machine.idle_slow_steps = self.machine.idle_slow_steps.saturating_add(1);
        }
        if !active || !m.is_finite() {
            self.run.torque_cmd = TorqueCommand::TorqueNm(0.0);
            return;
        }
        if let Some(left) = self.stop_steps_left {
            if left == 0 || m.omega_m_rad_s.abs() < cfg.motion.stall_speed_rad_s {
                self.disable();
                self.run.torque_cmd = TorqueCommand::TorqueNm(0.0);
                return;
            }
            self.stop_steps_left = Some(left - 1);
        }
        if self.vhz_running(cfg).is_some() {
            return self.vhz_motion_checks(cfg, m.omega_m_rad_s);
        }
        // The fast steps since the last slow step: the slip angle and the flux model advance
        // over them (before the field is anchored, on the slip angle).
        self.run.ifoc.add_sums(inputs.sums);
        let measured_slip = cfg.slip_current == SlipCurrent::Measured && self.mode == Mode::Running;
        let (i_mean, n) = cfg.ifoc.close_period(&mut self.run.ifoc, measured_slip, cfg.plan_delay());
        if cfg.magnetizing.on() {
            self.follow_curve(cfg);
        }
        self.anchor_field(cfg, step_rad);
        if let Some(theta_e) = inputs.field_rad {
            // Sensorless: the field where the observer finds the rotor flux.
            self.run.theta_r_rad = cfg.ifoc.anchor_field(&mut self.run.ifoc, theta_e);
            self.observe_field_rate(cfg, theta_e);
        }
        // The plan this step makes starts at its adoption: the field there.
        cfg.ifoc.advance(&mut self.run.ifoc, cfg.plan_delay());
        // The modulator limited the loops' request since the last slow step.
        let limited = inputs.limited;
        if n > 0 && (self.mode == Mode::Running || !cfg.mras.fit_pending(&self.run.rotor_fit)) {
            // The period's mean error of the intended references (those of the plan in force).
            let r = self.run.ifoc.i_ref_dq();
            self.update_trim(cfg, Dq { d: r.d - i_mean.d, q: r.q - i_mean.q }, limited);
        }
        // The loops' request over the slow period while magnetizing.
        let (v_fit_sum, v_fit_steps) = (inputs.v_fit_sum, inputs.v_req_steps);
        let (v_target, v_budget) = self.voltage_budget(cfg, inputs, m.vdc_v * cfg.duty_max, limited);
        let running = self.mode == Mode::Running;
        let limit = self.run.torque_max_nm;
        let torque_nm = if !running {
            0.0
        } else {
            match self.reference {
                Reference::Torque(t) => t,
                Reference::RotatingCurrent { .. } => 0.0,
                Reference::Speed(w) => {
                    self.omega_ref_rad_s = w;
                    // The user's reference through the speed law's setpoint-weight prefilter.
                    let w_f = cfg.speed.reference(&mut self.run.speed, w);
                    self.speed_torque(cfg, w_f, m.omega_m_rad_s, limit)
                }
                Reference::Position(th) => {
                    let w = cfg.position.update(th, self.machine.encoder.position_rad());
                    self.omega_ref_rad_s = w;
                    // The position loop's, unfiltered: its design ends at the speed loop.
                    let w = cfg.speed.pass_reference(&mut self.run.speed, w);
                    self.speed_torque(cfg, w, m.omega_m_rad_s, limit)
                }
            }
        };
        // At its limit, the speed rises as fast as the drive makes it (`voltage_budget`).
        self.run.torque_at_limit = running
            && match self.reference {
                Reference::Torque(t) => t.abs() >= 0.999 * limit,
                Reference::Speed(_) | Reference::Position(_) => self.run.speed_saturated,
                Reference::RotatingCurrent { .. } => false,
            };
        let (w, i_max) = (m.omega_m_rad_s, cfg.ifoc.i_max_a());
        // One speed for the voltage: the envelope, its point, the forcing and the present
        // flux's limit (`SlowRun::omega_limit_rad_s`).
        let band = if self.on_observer(cfg) { 0.0 } else { cfg.speed_hold_band_rad_s };
        let held = self.run.omega_limit_rad_s.limit(w - band, w + band);
        let w_v = if running { held } else { w };
        self.run.omega_limit_rad_s = w_v;
        let sign = if torque_nm < 0.0 { -1.0 } else { 1.0 };
        // The envelope is remade every ENVELOPE_REFRESH_SLOW_STEPS, and at once when the
        // torque changes direction.
        if self.run.envelope_age == 0 || self.run.envelope.sign() != sign {
            // On the estimates as they are now (the rotor-resistance law moves them).
            self.remodel(cfg);
            self.run.envelope = self.run.model.envelope(sign, w_v, self.run.i_d_rated_a, v_budget, i_max);
            self.run.envelope_age = ENVELOPE_REFRESH_SLOW_STEPS;
        }
        self.run.envelope_age -= 1;
        // Generating: no more than the DC link can take (REGEN_LIMIT_START/END) — the point's
        // flux too: a braking flux held for a torque the link refuses would leave its
        // back-EMF beyond the bus.
        let room = if torque_nm * m.omega_m_rad_s < 0.0 {
            (1.0 - (m.vdc_v - cfg.regen_start_v) * cfg.inv_regen_span_v).limit(0.0, 1.0)
        } else {
            1.0
        };
        let torque_nm = torque_nm * room;
        let op =
            self.run.model.point(&self.run.envelope, torque_nm, w_v, self.run.i_d_rated_a, v_budget, i_max);
        // Running, a flux above the envelope's falls within FLUX_FALL_TIME_S — sooner while the
        // speed rises (FLUX_LAG_FRACTION) —, however slow the rotor (magnetizing, the rotor
        // fit reads the flux building at its own T_r); where
        // its back-EMF leaves no voltage for the current asked, it is forced down by a
        // negative i_d the bus can drive.
        self.run.i_d_target_a = op.i_d_a;
        let psi = self.run.ifoc.psi_r_wb();
        let i_d_a = if running {
            // The flux the bus allows falls as 1/ω above the base speed: a rising speed asks
            // it to fall as fast (FLUX_LAG_FRACTION), the current reversed if need be. Where
            // the target holds, a flux above it (a rescaled model, an overshoot, the current
            // limit's point) falls within FLUX_FALL_TIME_S on no less than no current. Between
            // them the fall rate and the floor blend in over the lag allowed — where the target
            // has fallen by less, a speed held there does not switch them each slow step —
            // from the no-load base speed ω_b, or, motoring (the speed rises with the torque
            // asked), from where the target itself has begun to fall (as far as the speed
            // makes it fall: weighed by |ω|/ω_b, below): under load the voltage binds below
            // ω_b (the 1.3 kW member 001's target had fallen 20 % at ω_b, and the flux left
            // behind, forced there with the full gain, swung i_d* by 1.5 A per encoder count:
            // the torque fell from 27 to 0 N·m). Braking, the speed falls and the braking
            // point's lower flux is its own choice, not the speed's: ω_b's blend.
            // ω_b is the bus's (the voltage target's), not the regulator's budget: a budget cut
            // for a fault (an open lead) would have the flux driven down into the fault. The
            // target's fall is the budget's, but motoring only and weighed by |ω|/ω_b: the
            // fault matrix's open leads (mid and top speed, both ways) are named as before.
            let w_b = self.run.model.no_load_base_speed_rad_s(self.run.i_d_rated_a, v_target);
            let lag = FLUX_LAG_FRACTION as f32;
            let above_base = (w.abs() - w_b) / max_f32(lag * w_b, 1e-3);
            let fallen = if torque_nm * w > 0.0 {
                // The part of the fall the speed makes: weighed by |ω|/ω_b, how much of the
                // bus the rated flux's back-EMF takes (a stator whose resistance takes it at
                // standstill has its target down with no speed to weaken the field for).
                let speed_share = min_f32(w.abs() / max_f32(w_b, 1e-3), 1.0);
                speed_share * (1.0 - op.i_d_a / max_f32(self.run.i_d_rated_a, 1e-6)) / lag
            } else {
                0.0
            };
            let blend = max_f32(above_base, fallen).limit(0.0, 1.0);
            let tau_fast = (cfg.flux_lag_j_kgm2 * w.abs() / max_f32(op.torque_max_nm, 1e-6))
                .limit(cfg.flux_fall_time_min_s, FLUX_FALL_TIME_S as f32);
            let slow_rate = (1.0 / FLUX_FALL_TIME_S) as f32;
            let fall_rate = cfg.ts_s * (slow_rate + blend * (1.0 / tau_fast - slow_rate));
            let floor_a = -blend * i_max;
            let falling = cfg.ifoc.falling_flux_current(&self.run.ifoc, op.i_d_a, fall_rate, floor_a);
            // Motoring current only adds voltage: the flux is forced where even none fits.
            // Braking current subtracts it: judged at the point's braking current (within the
            // envelope: the torque asked, converted at the present flux, overstated the slip of
            // a torque beyond it and forced the 24 V drive's flux down while braking at
            // 43 rad/s).
            let i_q_a = if torque_nm * w < 0.0 { op.i_q_a } else { 0.0 };
            // Only a flux above its target is forced: one below it (rising, or a saturated
            // estimate) is not what leaves no voltage, and forcing it would feed on itself
            // (less flux, more slip, more voltage). It starts where the flux is beyond the
            // voltage target itself — a budget the regulator cut for a fault (an open lead at
            // top speed) would otherwise have it drive amperes into the fault — and goes on,
            // against the budget (whose cut is the loops' headroom in the transient), until
            // the flux is down to the point's: stopped where it fits the target, the loops
            // sat at the modulator's limit on the flux left.
            let model = &self.run.model;
            let above = psi > self.run.ifoc.flux_of(op.i_d_a);
            self.run.flux_forced = above
                && (self.run.flux_forced
                    || model.d_current_within_voltage(psi, falling, i_q_a, w_v, v_target, i_max) < falling);
            let i_d_a = if self.run.flux_forced {
                model.d_current_within_voltage(psi, falling, i_q_a, w_v, v_budget, i_max)
            } else {
                falling
            };
            // How far the forcing moved the d reference from where the flux would fall of
            // itself: the step the loops follow at the voltage limit (the stuck-switch check's).
            self.run.forcing_a = max_f32(falling - i_d_a, 0.0);
            i_d_a
        } else {
            self.run.forcing_a = 0.0;
            op.i_d_a
        };
        self.run.flux = cfg.ifoc.d_current_command(i_d_a);
        // What the bus drives now, with the flux that is there (it follows i_d* with T_r):
        // only worked out when the torque asked for needs more than fits.
        let per_a = cfg.ifoc.torque_factor() * max_f32(psi, 1e-3);
        let needed = min_f32(self.run.flux.i_q_max_a(), torque_nm.abs() / per_a);
        // Braking, on the bus's voltage target, not the regulator's budget: the budget's trim is
        // the loops' headroom in a transient, and an overhauling load the steady envelope holds
        // must stay held — cut 3 % (321 → 312 V), member 016's present-flux limit fell from
        // ≥ 320 to 275 N·m under a 319 N·m load at its top speed, and the rotor ran away
        // (`FollowingError` in 30 of 512 generating runs; population test
        // `a_braking_drive_holds_its_load_at_top_speed`).
        let v_now = if torque_nm * w < 0.0 { v_target } else { v_budget };
        let i_q_now = self.run.model.i_q_max_at_flux(psi, i_d_a, w_v, v_now, needed, sign);
        let torque_now_nm = room * min_f32(op.torque_max_nm, per_a * i_q_now);
        // The speed loop's limit is the steady envelope: limited by the present flux too, it
        // would ask for a torque the rated flux can give, and the flux would never fall.
        self.run.torque_max_nm = op.torque_max_nm;
        self.run.torque_cmd = TorqueCommand::TorqueNm(torque_nm.limit(-torque_now_nm, torque_now_nm));
        if !running {
            if self.run.search_left > 0 {
                self.search(cfg, inputs);
            }
            // The rotor resistance and the inductance from the building flux
            // ([`MrasConfig::fit`]).
            let l_now = self.run.ifoc.inductance_scale();
            if m.omega_m_rad_s.abs() >= cfg.motion.stall_speed_rad_s {
                self.run.rotor_fit.turning();
            }
            let i_d_a = self.run.flux.i_d_a();
            let built_inductance_scale =
                if cfg.magnetizing.on() { self.built_inductance_scale(cfg, i_d_a) } else { l_now };
            let period = FitPeriod {
                v_sum: v_fit_sum,
                steps: v_fit_steps,
                i_d_a,
                i_d_mean_a: i_mean.d,
                // The field's angle over the period at the shaft's speed.
                field_step_rad: cfg.envelope.pole_pairs()
                    * m.omega_m_rad_s
                    * cfg.ts_s
                    * f32::from(cfg.slow_divider),
                built_inductance_scale,
                saturating: cfg.magnetizing.on(),
                delay_steps: cfg.plan_delay(),
            };
            if let Some(fit) = cfg.mras.fit(&mut self.run.rotor_fit, &period, l_now) {
                cfg.ifoc.set_rotor_resistance_scale(&mut self.run.ifoc, fit.rr_scale);
                if cfg.magnetizing.on() {
                    // A measured linkage is the settled build's at the fit's current; the
                    // scale in use is the model's, at its flux.
                    let i_m = if fit.inductance_measured {
                        self.run.flux.i_d_a()
                    } else {
                        self.model_magnetizing_current_a()
                    };
                    self.set_inductance_on_curve(cfg, fit.inductance_scale, i_m);
                    self.rotor_resistance_on_curve(cfg);
                } else {
                    self.set_inductance_scale(cfg, fit.inductance_scale);
                }
                self.remodel(cfg);
                // Sensorless: the observer's voltage model on the stator as it is now.
                if let (Some(o), Some(r_s)) = (cfg.source.observer(), fit.stator_resistance_ohm) {
                    self.machine.rs_scale = o.stator_resistance_scale(r_s).unwrap_or(self.machine.rs_scale);
                }
            }
            self.run.magnetizing_steps = self.run.magnetizing_steps.saturating_add(1);
            if self.run.magnetizing_steps > cfg.magnetizing_steps_max {
                // The flux model runs on the measured current: none flows.
                self.trip(Fault::NoMotorCurrent);
            } else if self.run.ifoc.psi_r_wb()
                >= cfg.magnetized_fraction * self.run.ifoc.flux_of(self.run.flux.i_d_a())
                && !cfg.mras.fit_pending(&self.run.rotor_fit)
                && self.run.search_left == 0
            {
                // The flux model runs on the measured current: the motor is magnetized.
                self.mode = Mode::Running;
                // V/Hz: the ramp starts at the rotor's speed (a flying start's too).
                self.run.vhz_ramp_rad_s = m.omega_m_rad_s;
                self.run.speed = SpeedState::default();
                self.run.motion.restart();
            }
            return;
        }
        let commanding_motion = matches!(self.reference, Reference::Speed(_) | Reference::Position(_));
        // Asked to move: the loop at its limit, or a speed reference well above "not moving"
        // (a proportional law too soft to saturate still commands a seized rotor to turn).
        let asked = self.run.speed_saturated
            || matches!(self.reference, Reference::Speed(w)
                if w.abs() >= STALL_REFERENCE_FACTOR * cfg.motion.stall_speed_rad_s);
        if self.run.motion.stall(&cfg.motion, commanding_motion && asked, m.omega_m_rad_s) {
            self.trip(Fault::Stall);
            self.run.torque_cmd = TorqueCommand::TorqueNm(0.0);
        }
        self.check_following(cfg, commanding_motion, m.omega_m_rad_s);
    }

    /// One encoder reading, in every mode (the turn count must not miss a turn made while
    /// the bridge is off): the change since the last reading, mechanical rad; a jump
    /// ([`EncoderTrack::read`]) trips [`Fault::EncoderLoss`] unless a fault is latched.
    fn read_encoder(&mut self, cfg: &DriveConfig, theta_m_rad: f32) -> f32 {
        // On the observer, the reading is its estimate, not an encoder: nothing to judge (a
        // jump of the estimate is the machine's fault, which its own checks name — an open
        // phase read as `EncoderLoss` in the fault matrix otherwise).
        let judge = !matches!(self.mode, Mode::Fault(_)) && !self.on_observer(cfg);
        let (step, jumped) = self.machine.encoder.read(theta_m_rad, &cfg.encoder, judge);
        if jumped {
            self.encoder_fault(cfg, Fault::EncoderLoss);
        }
        step
    }

    /// Sensorless, the first slow steps of magnetizing: the flying start's search
    /// ([`crate::speed_search`]) — the voltage model's change per slow step while the field
    /// stands still; at its end, a rotor found turning by [`SEARCH_RESOLVED_TURN_RAD`] or
    /// more per `T_r` is magnetized on its speed (the field turns with it, the observer
    /// starts again on it), the flux model starting again from zero (what it built on the
    /// standing field is not the turning rotor's flux); slower, it is taken at rest, as
    /// before the search.
    #[cold]
    #[inline(never)]
    fn search(&mut self, cfg: &DriveConfig, inputs: &SlowInputs) {
        let Some(o) = cfg.source.observer() else { return };
        self.run.search.step(inputs.search_psi, cfg.search_span);
        self.run.search_left -= 1;
        if self.run.search_left > 0 {
            return;
        }
        let window_s = cfg.ts_s * f32::from(cfg.slow_divider) * cfg.search_span as f32;
        let alpha_max = o.alpha_per_s() * cfg.mras.range()[1];
        let turn = self.run.search.read(window_s, alpha_max);
        let w_e = turn.map_or(0.0, |t| t.electrical_speed_rad_s);
        let w_m = w_e / cfg.envelope.pole_pairs();
        if w_e.abs() >= SEARCH_RESOLVED_TURN_RAD * o.alpha_per_s() {
            self.run.known_speed_rad_s = w_m;
            self.run.ifoc.forget_flux();
            self.run.magnetizing_steps = 0;
            // The rotor resistance from the transient's decay, `α = R_r/L_r`: the magnetizing
            // fit needs the rotor at rest, and held at its range's middle (× √2 of the motor
            // file's for drive.toml) the speed estimate under a braking current was off by its
            // error times the slip — a catch then braking tripped `FollowingError`.
            if let Some(a) = turn.and_then(|t| t.decay_rate_per_s) {
                let [lo, hi] = cfg.mras.range();
                let scale = (self.run.ifoc.inductance_scale() * a / o.alpha_per_s()).limit(lo, hi);
                cfg.ifoc.set_rotor_resistance_scale(&mut self.run.ifoc, scale);
            }
        }
    }

    /// The encoder's fault `f`: ridden through on the observer where the drive has one beside
    /// the encoder ([`SpeedFeedback::EncoderRideThrough`]), Running under a speed or torque
    /// reference — from the next slow step on, the speed and the field are the observer's,
    /// and `f` is reported ([`Drive::ridden_through`]); tripped otherwise.
    #[cold]
    #[inline(never)]
    fn encoder_fault(&mut self, cfg: &DriveConfig, f: Fault) {
        let needs_shaft = matches!(self.reference, Reference::Position(_));
        if cfg.source.rides_through() && self.mode == Mode::Running && !needs_shaft {
            self.ridden_through = self.ridden_through.with(f);
        } else {
            self.trip(f);
        }
    }

    /// Sensorless: the field's speed over the last slow period from the observer's flux
    /// angle at its two ends — the stator frequency. The reactive-power law
    /// ([`crate::mras`]) needs the frequency of the voltage and current it reads: taken as
    /// `p·ω̂_m + ω_sl`, the speed estimate's own error (which the inductance estimate makes)
    /// read as an inductance error, and the two ran away together (the 24 V walk-through
    /// motor's inductance to its range's floor and the speed 4 % short at no load).
    fn observe_field_rate(&mut self, cfg: &DriveConfig, theta_e_rad: f32) {
        if let (Some(last), Some(o)) = (self.run.field_last_rad, cfg.source.observer()) {
            let t_slow_s = o.ts_s() * f32::from(cfg.slow_divider);
            self.run.field_rate_rad_s = Some(wrap_angle(theta_e_rad - last) / t_slow_s);
        }
        self.run.field_last_rad = Some(theta_e_rad);
    }

    /// The rotor's electrical angle advances by p·Δθ_m (the encoder's change over the read),
    /// and the field angle is re-anchored on it.
    pub(super) fn anchor_field(&mut self, cfg: &DriveConfig, step_rad: f32) {
        self.run.theta_r_rad =
            wrap_angle(self.run.theta_r_rad + wrap_angle(cfg.envelope.pole_pairs() * step_rad));
        cfg.ifoc.anchor(&mut self.run.ifoc, self.run.theta_r_rad);
    }

    /// The current trim integrates `error`, the mean field-frame error (intended − measured)
    /// of the last slow period, unless the modulator limited the voltage in it: then the
    /// currents cannot follow and the trim holds.
    fn update_trim(&mut self, cfg: &DriveConfig, error: Dq, limited: bool) {
        if !limited {
            let k = cfg.trim_gain;
            let lim = CURRENT_TRIM_RANGE * cfg.ifoc.i_max_a();
            self.run.trim.d = (self.run.trim.d + k * error.d).limit(-lim, lim);
            self.run.trim.q = (self.run.trim.q + k * error.q).limit(-lim, lim);
        }
    }

    /// The voltage budget of the current references: the target `voltage_margin·V_dc/√3`
    /// less the regulator's cut, which integrates the target's excess over the RMS of the
    /// voltage the loops asked for since the last slow step (only downwards from zero, and
    /// at most [`VOLTAGE_REGULATOR_RANGE`] of the limit). A steady model error is corrected
    /// through the flux, at the drive's own bandwidth
    /// ([`DriveSpec::voltage_regulator_bandwidth_rad_s`], at most 1/T_r) —
    /// [`VOLTAGE_REGULATOR_LIMITED_GAIN`] times faster while the modulator limits. Limited
    /// while the torque asked is at its limit (the speed loop's output saturated, a torque
    /// reference at the envelope's), the speed rises as fast as the drive makes it and the
    /// voltage the machine needs with it: an integrator follows a ramp of relative slope α/ω
    /// only (α/ω)/K behind, and the loops have the 2 % the voltage margin leaves, so the
    /// regulator then cuts at that many times [`VOLTAGE_REGULATOR_BANDWIDTH_RAD_S`] however
    /// slow the rotor (≈ 2/s for the 500 hp machine at 90 rad/s; at ten times its rotor's
    /// 1/T_r, seed 000 Fig. 12's detuned plant tripped `LossOfControl` at 93.6 rad/s). A
    /// drive whose slowest rotor is faster than 1/[`VOLTAGE_REGULATOR_BANDWIDTH_RAD_S`] has
    /// the same gain in both.
    ///
    /// Returns the target and the budget.
    fn voltage_budget(
        &mut self,
        cfg: &DriveConfig,
        inputs: &SlowInputs,
        vdc_v: f32,
        limited: bool,
    ) -> (f32, f32) {
        let target = cfg.voltage_margin * svpwm::linear_limit_v(vdc_v);
        if inputs.v_req_steps > 0 {
            let v_req = sqrt_f32(inputs.v_req2_sum / f32::from(inputs.v_req_steps));
            let floor = -VOLTAGE_REGULATOR_RANGE * svpwm::linear_limit_v(vdc_v);
            let gain = match (limited, self.run.torque_at_limit) {
                (false, _) => cfg.voltage_gain,
                (true, false) => VOLTAGE_REGULATOR_LIMITED_GAIN * cfg.voltage_gain,
                (true, true) => VOLTAGE_REGULATOR_LIMITED_GAIN * cfg.voltage_gain_max,
            };
            let error = max_f32(target - v_req, -VOLTAGE_REGULATOR_EXCESS_MAX * target);
            self.run.v_cut_v = (self.run.v_cut_v + gain * error).limit(floor, 0.0);
        }
        (target, target + self.run.v_cut_v)
    }

    /// The speed loop's torque for speed reference `w_ref` (shaped: `SpeedControllerConfig::reference`) at speed `w`, its output limited
    /// to the envelope's torque `limit` (so that a PI speed law does not wind up against a
    /// torque the bus cannot give). An i_q-output law (seed 000 PI2) is converted to torque
    /// with the flux estimate.
    fn speed_torque(&mut self, cfg: &DriveConfig, w_ref: f32, w: f32, limit_nm: f32) -> f32 {
        let per_a = cfg.ifoc.torque_factor() * self.run.ifoc.psi_r_wb();
        let limit = if cfg.speed.is_torque() { limit_nm } else { limit_nm / max_f32(per_a, 1e-6) };
        let limit = min_f32(limit, cfg.motion.speed_limit);
        let cmd = cfg.speed.update_limited(&mut self.run.speed, w_ref, w, limit);
        let (TorqueCommand::TorqueNm(u) | TorqueCommand::IqA(u)) = cmd;
        self.run.speed_saturated = u.abs() >= 0.999 * limit;
        match cmd {
            TorqueCommand::TorqueNm(t) => t,
            TorqueCommand::IqA(i) => i * per_a,
        }
    }

    /// The fast steps' plan up to the next slow step ([`IfocConfig::plan`]: the current
    /// references, the slip and the field's rotation per step), and the rotation that
    /// advances the output voltage over the delay, from the field speed of that plan.
    fn plan(&mut self, cfg: &DriveConfig, omega_m_rad_s: f32) {
        let running = self.mode == Mode::Running;
        let cmd = if running { self.run.torque_cmd } else { TorqueCommand::TorqueNm(0.0) };
        let before = self.run.ifoc.i_ref_dq();
        cfg.ifoc.plan(&mut self.run.ifoc, &self.run.flux, cmd, omega_m_rad_s, self.run.trim);
        if matches!(cfg.current_frame, CurrentFrame::Stationary) {
            // What the loops must be asked for their current to be the plan's.
            let (step_rad, step) = self.run.ifoc.plan_step();
            self.run.ifoc.precompensate(cfg.reference_gain(step_rad, step));
        }
        let after = self.run.ifoc.i_ref_dq();
        let (dd, dq) = (after.d - before.d, after.q - before.q);
        self.run.i_ref_step_a = sqrt_f32(dd * dd + dq * dq);
        let (omega_e, v_ff) = match self.reference {
            // The test's current turns in a field of its own: no flux of the model's.
            Reference::RotatingCurrent { omega_rad_s, .. } if running => (omega_rad_s, Dq { d: 0.0, q: 0.0 }),
            _ => {
                let w_e = cfg.envelope.pole_pairs() * omega_m_rad_s + self.run.ifoc.omega_sl_rad_s();
                // The stationary-frame loops get the back-EMF, the field-frame loops the
                // decoupling (`FastState::feedforward`).
                let v_ff = match cfg.current_frame {
                    CurrentFrame::Stationary => Dq { d: 0.0, q: cfg.ifoc.back_emf_v(&self.run.ifoc, w_e) },
                    CurrentFrame::Synchronous => {
                        let (i, trim) = (self.run.ifoc.i_ref_dq(), self.run.trim);
                        cfg.decoupling_v(w_e, Dq { d: i.d + trim.d, q: i.q + trim.q })
                    }
                };
                (w_e, v_ff)
            }
        };
        self.run.delay_rotation = SinCos::default().rotated((omega_e * cfg.delay_s).limit(-0.5, 0.5));
        self.run.v_ff = v_ff;
    }

    /// Run on the inductances `l` × the motor's (the magnetizing fit's): the flux model, the
    /// machine model and the rated flux's d-axis current `ψ*/(l·L_m)` — the drive keeps
    /// magnetizing until the flux model reaches it. The envelope is remade at the next slow
    /// step.
    pub(super) fn set_inductance_scale(&mut self, cfg: &DriveConfig, l: f32) {
        if !finite_positive(l) || l == self.run.ifoc.inductance_scale() {
            return;
        }
        cfg.ifoc.set_inductance_scale(&mut self.run.ifoc, l);
        self.remodel(cfg);
        self.run.i_d_rated_a = cfg.i_d_rated_a / l;
        self.run.envelope_age = 0;
    }

    /// A saturating motor (issue 50): the inductances in use follow the magnetizing curve —
    /// the identified scale ℓ × the chord `c(ℓ·i_m)` at the flux model's magnetizing current
    /// `i_m = ψ̂_r/L̂_m` (the curve of a machine whose inductances are ℓ × the file's carries
    /// the flux `ψ(ℓ·i)` at current i, as the simulated plant scales it), every slow step
    /// after the flux model's. The model is then the chord model `ψ̂_r = L(i_m)·i_m`: the
    /// flux estimate is rescaled with the inductance ([`IfocConfig::set_inductance_scale`]:
    /// `i_m` is unchanged); the rated flux's current is the curve's own, and every other
    /// operating point's (field weakening's, through the machine model at its refresh) is
    /// taken on the present chord: it settles on the curve's `i(ψ*)` as the flux does,
    /// geometrically while `0 < L_diff < 2·L_chord`
    /// ([`crate::magnetics::MagnetizingTable::validate`]). Where
    /// leakage and magnetizing inductance are scaled alike the chord is an approximation of
    /// the machine's dynamics; at no load in steady state it is the curve itself.
    #[inline(never)]
    fn follow_curve(&mut self, cfg: &DriveConfig) {
        let s = &self.run.ifoc;
        let l_id = self.run.identified_inductance_scale();
        let i_m = self.model_magnetizing_current_a();
        let chord = cfg.magnetizing.ratio(l_id * i_m);
        let l = l_id * chord;
        if finite_positive(l) && l != s.inductance_scale() {
            cfg.ifoc.set_inductance_scale(&mut self.run.ifoc, l);
            self.run.chord = chord;
        }
        // The rated flux's current on the curve itself, `ψ(ℓ·i) = ψ*` at `i = i_N/ℓ`: held
        // while the flux builds (the magnetizing fit gives up on a moving reference).
        self.run.i_d_rated_a = cfg.i_d_rated_a / l_id;
    }

    /// The flux model's magnetizing current `i_m = ψ̂_r/L̂_m`, A.
    fn model_magnetizing_current_a(&self) -> f32 {
        let s = &self.run.ifoc;
        s.psi_r_wb() / s.flux_of(1.0)
    }

    /// A saturating motor's inductance scale at the flux the d-axis current `i_d_a` builds:
    /// the identified ℓ × the curve's chord at `ℓ·i_d` ([`Self::follow_curve`] in steady
    /// state).
    #[cold]
    #[inline(never)]
    fn built_inductance_scale(&self, cfg: &DriveConfig, i_d_a: f32) -> f32 {
        let l_id = self.run.identified_inductance_scale();
        l_id * cfg.magnetizing.ratio(l_id * i_d_a)
    }

    /// A saturating motor's magnetizing fit: the flux linkage it measured is the chord, × the
    /// rated one, of the machine at the flux built — `ℓ·c(ℓ·i_m)` for a machine whose
    /// inductances are ℓ × the file's ([`Self::follow_curve`]), not ℓ × the chord the drive
    /// had assumed there. `i_m`, A: for a measured linkage the fit's current (the build it
    /// extrapolates is settled: all of the current magnetizes) — the flux model's `ψ̂_r/L̂_m`,
    /// still building where the machine's rotor is faster than the model's, read the 300 W
    /// twin at R_r ×1.5 as ℓ 0.96 with exact sensors; for the scale in use (a fit that did
    /// not measure it) the model's. ℓ is the fixed point of `ℓ ← l/c(ℓ·i_m)`, which converges while
    /// the table rises no more steeply than its chord allows
    /// ([`crate::magnetics::MagnetizingTable::validate`]: the map's slope is
    /// `1 − L_diff/L_chord`), within [`FIT_CURVE_ITERATIONS`]; kept within the inductance
    /// range. Read as ℓ × the assumed chord, the 300 W twin at 0.6 × its file's inductances
    /// was taken for a less saturated machine: its rotor flux ended 13.1 % below its
    /// reference (hil-sim test
    /// `a_saturating_machine_is_identified_on_its_curve_at_any_inductance_scale`).
    #[cold]
    #[inline(never)]
    fn set_inductance_on_curve(&mut self, cfg: &DriveConfig, l_measured: f32, i_m: f32) {
        let [lo, hi] = cfg.mras.inductance_range();
        let mut l = self.run.identified_inductance_scale();
        // A loop, not eight copies (unrolled, the firmware took 280 B more flash for a step
        // that runs once per enable).
        for _ in 0..core::hint::black_box(FIT_CURVE_ITERATIONS) {
            l = (l_measured / cfg.magnetizing.ratio(l * i_m)).limit(lo, hi);
        }
        let chord = cfg.magnetizing.ratio(l * i_m);
        self.run.chord = chord;
        self.set_inductance_scale(cfg, l * chord);
        self.run.i_d_rated_a = cfg.i_d_rated_a / l;
    }

    /// A saturating motor's rotor resistance, read on its curve from the build the
    /// magnetizing fit sampled ([`crate::mras::MrasConfig::rotor_resistance_on_curve`]), on
    /// the inductance scale ℓ just identified; the first windows' (what the fit returned)
    /// where it cannot be read (hil-sim test
    /// `a_saturating_machines_rotor_resistance_is_read_at_rest_on_its_curve`; read from the
    /// first windows, a tenth of motulator's 2.2 kW machine's campaign, every run above R_r
    /// ×1.16, missed its flux).
    #[cold]
    #[inline(never)]
    fn rotor_resistance_on_curve(&mut self, cfg: &DriveConfig) {
        let l = self.run.identified_inductance_scale();
        let chord = &cfg.magnetizing;
        let fit = &self.run.rotor_fit;
        if let Some(r) = cfg.mras.rotor_resistance_on_curve(fit, l, |psi| chord.current_at_flux(psi)) {
            cfg.ifoc.set_rotor_resistance_scale(&mut self.run.ifoc, r);
        }
    }

    /// The envelope's machine model on the drive's estimates now: the inductance and the
    /// rotor resistance its field orientation runs on ([`EnvelopeConfig::identified`]).
    fn remodel(&mut self, cfg: &DriveConfig) {
        if cfg.magnetizing.on() {
            return self.remodel_on_curve(cfg);
        }
        let s = &self.run.ifoc;
        self.run.model = cfg.envelope.identified(s.inductance_scale(), s.rotor_resistance_scale());
    }

    /// A saturating motor's machine model: the identified machine (ℓ × the file's
    /// inductances) with its magnetizing inductance the curve's chord at the operating point
    /// it plans for and its leakages as identified
    /// ([`EnvelopeConfig::with_magnetizing_scale`]) — the chord at the flux of the last
    /// operating point, `L̂_m·i_d` on the model that planned it (the rated flux before the
    /// first). The flux model's chord, where the flux is now, planned a magnetizing machine's
    /// voltage on the unsaturated inductance and lowered its rated flux below base speed: a
    /// flying start near base speed gave up its rotor fit on the moving reference (the 300 W
    /// motor's saturating twin at 149 rad/s, a tenth of its envelope: 37.5 % too much torque,
    /// `hil-sim envelope drives/delorenzo-saturating.toml --torque-fraction 0.1`). Read at
    /// the flux, not at the current: in field weakening the voltage sets the flux whatever
    /// the chord, so the model is the curve's from the next refresh on — read at the current,
    /// it settled by a fraction of its error per refresh, and the fit gave up there too.
    /// Running, it moves [`MODEL_CHORD_RELAXATION`] of the way each refresh: at the current
    /// limit the point's flux depends on the chord more than one for one, and the full step
    /// made a limit cycle of the refreshes (the twin's whole envelope at 37 rad/s: 43 % short).
    /// A machine whose inductances are ℓ × the file's has ℓ × the file's chord at the same
    /// flux.
    #[cold]
    #[inline(never)]
    fn remodel_on_curve(&mut self, cfg: &DriveConfig) {
        let l_id = self.run.identified_inductance_scale();
        let model = &self.run.model;
        let psi = if self.run.i_d_target_a > 0.0 {
            model.lm2_over_lr_h() / model.lm_over_lr() * self.run.i_d_target_a
        } else {
            cfg.ifoc.flux_of(cfg.i_d_rated_a)
        };
        let target = cfg.magnetizing.ratio_at_flux(psi);
        let now = self.run.model_chord;
        let chord =
            if self.mode == Mode::Running { now + MODEL_CHORD_RELAXATION * (target - now) } else { target };
        self.run.model_chord = chord;
        let rr = self.run.ifoc.rotor_resistance_scale();
        self.run.model = cfg.envelope.identified(l_id, rr).with_magnetizing_scale(chord);
    }

    /// Run on the inductances `l` × the motor's as [`Self::set_inductance_scale`], keeping the
    /// rotor time constant `T̂_r = (ℓ̂/r̂)·T_r` the fit and the loaded law found (the rotor
    /// resistance scaled with ℓ̂, within its range: the slip `(r̂/ℓ̂)·i_q/(T_r·i_d)` does not
    /// move), and leave the envelope to its periodic refresh: the online law moves `l` a
    /// little every slow step (a remade envelope each of them would triple the slow step).
    fn adapt_inductance_scale(&mut self, cfg: &DriveConfig, l: f32) {
        let l_now = self.run.ifoc.inductance_scale();
        if !finite_positive(l) || l == l_now {
            return;
        }
        let [r_min, r_max] = cfg.mras.range();
        let r = (self.run.ifoc.rotor_resistance_scale() * (l / l_now)).limit(r_min, r_max);
        cfg.ifoc.set_rotor_resistance_scale(&mut self.run.ifoc, r);
        cfg.ifoc.set_inductance_scale(&mut self.run.ifoc, l);
        self.remodel(cfg);
        self.run.i_d_rated_a = cfg.i_d_rated_a / l;
    }

    /// The phase checks once per slow period: the open-phase window ([`Fault::OpenPhase`],
    /// [`Fault::NoMotorCurrent`], the windowed current sum's [`Fault::CurrentSensor`];
    /// Magnetizing and Running) and the stuck-switch check ([`Fault::SwitchOpen`]; Running),
    /// on the phase currents `i_abc_a` of the tick against the references its fast step ran
    /// on (latched with them, `SlowInputs::i_refs_ab`) — enough samples of a half-wave up to
    /// the top speed (≈ 18 per electrical period at 700 rad/s), at a tenth of the
    /// instructions of every step, and none of them in the fast step (the window sampled
    /// every fast step cost 49 instructions per fast step, `cost interrupt_fast_step`).
    /// A fault latched here turns the bridge off with the plan's adoption. `unreferenced`:
    /// no references (V/Hz follows none): the currents are their own, and no stuck-switch
    /// check.
    fn check_phases(&mut self, cfg: &DriveConfig, i_abc_a: Abc, unreferenced: bool, inputs: &SlowInputs) {
        let running = self.mode == Mode::Running;
        let [i_ref_ab, i_track_ab] = if unreferenced {
            [i_abc_a.clarke(); 2]
        } else {
            match self.reference {
                Reference::RotatingCurrent { amplitude_a, .. } if running => {
                    [super::fast::rotating_current(cfg, amplitude_a, inputs.test_angle_rad).2; 2]
                }
                _ => inputs.i_refs_ab,
            }
        };
        let (i_ref_abc, i_track_abc) = (i_ref_ab.inverse_clarke(), i_track_ab.inverse_clarke());
        let window = self.run.open_phase.add(
            i_track_abc,
            i_abc_a,
            cfg.phases.open_phase_slow_steps,
            // The motor file's magnetizing current, as the window's level: a saturated
            // machine's (×1/ℓ̂) is larger, so its phases would pass the level sooner.
            cfg.i_d_rated_a,
            cfg.phases.sum_mean_max_a,
        );
        // The stuck-switch check judges the half-waves of the current against references it
        // follows; V/Hz has none. Forcing the flux down steps the d reference, which the
        // loops follow at the voltage limit: `forcing_a`, the step, for the check to weigh.
        let fault = window.or_else(|| {
            if running && !unreferenced {
                self.run.switches.add(
                    [i_ref_abc, i_track_abc],
                    [i_abc_a, leg_sides(inputs.v_ab)],
                    [cfg.phases.switch_level_a, self.run.forcing_a],
                    cfg.phases.switch_gains,
                )
            } else {
                None
            }
        });
        if let Some(f) = fault {
            self.trip(f);
        }
    }

    /// The speed-following check ([`MotionChecks::following`]): [`Fault::FollowingError`]
    /// with the torque command at zero.
    pub(super) fn check_following(&mut self, cfg: &DriveConfig, commanding_motion: bool, omega_m_rad_s: f32) {
        // The slow step commands a torque (an i_q command owes nothing: no trip from it).
        let torque_nm = match self.run.torque_cmd {
            TorqueCommand::TorqueNm(t) => t,
            TorqueCommand::IqA(_) => 0.0,
        };
        let at_limit = commanding_motion && self.run.speed_saturated;
        let torque_law = cfg.speed.is_torque();
        if self.run.motion.following(&cfg.motion, at_limit, omega_m_rad_s, torque_nm, torque_law) {
            self.trip(Fault::FollowingError);
            self.run.torque_cmd = TorqueCommand::TorqueNm(0.0);
        }
    }

    /// The thermal models (every slow step, every mode): the RMS phase current squared
    /// (|i_αβ|²/2, the Clarke transform being amplitude-invariant) averaged over
    /// [`THERMAL_UPDATE_SLOW_STEPS`], then one step of each model; at its limit,
    /// [`Fault::MotorOverload`] or [`Fault::InverterOverload`] ([`Drive::fault_reaction`]).
    #[inline(never)]
    fn update_thermal(&mut self, cfg: &DriveConfig, i_abc: Abc) {
        let [motor, inverter] = self.machine.thermal.update(&cfg.motor_thermal, &cfg.inverter_thermal, i_abc);
        if motor {
            self.fault_reaction(cfg, Fault::MotorOverload);
        }
        if inverter {
            self.fault_reaction(cfg, Fault::InverterOverload);
        }
    }

    /// The once-per-slow-period checks on the fast step after the slow step (`a`: Running on
    /// the field-oriented references): the encoder against the machine model on the voltage
    /// applied, then — unless it tripped — the rotor-resistance and inductance laws on the
    /// voltage the bridge was given, limited by the modulator or not (`AfterSlow::v_given`).
    /// Listening to the unlimited samples only, the law heard a biased sample wherever the
    /// modulator limits now and then: at the voltage limit in field weakening under load,
    /// the speed loop's kicks push the request beyond the hexagon in ≈ 10 % of the slow
    /// periods, and leaving those out keeps the samples of the lowest voltage, so the lowest
    /// reactive power — read as a rotor resistance below the rotor's. The 196 kW population
    /// member 014 at 20 kHz settled 10 % low (×1.16–1.20 against its rotor's ×1.297) and its
    /// flux swung ±15 % at the top speed under load (docs/rotor-resistance.md).
    pub(super) fn after_slow_checks(&mut self, cfg: &DriveConfig, a: &AfterSlow) {
        let w_e_rad_s = self.run.model.pole_pairs() * a.omega_m_rad_s + self.run.ifoc.omega_sl_rad_s();
        let v_limit_v = svpwm::linear_limit_v(a.v_usable_v);
        let sensorless = self.on_observer(cfg);
        self.check_encoder(cfg, a.i_meas_dq, a.v_applied, a.field, w_e_rad_s, v_limit_v);
        if self.mode != Mode::Running {
            return;
        }
        // Sensorless, the laws read the stator frequency the field turns at (none before it
        // has turned one slow period).
        let w_e_rad_s = match (sensorless, self.run.field_rate_rad_s) {
            (false, _) => Some(w_e_rad_s),
            (true, rate) => rate,
        };
        if let Some(w_e_rad_s) = w_e_rad_s {
            // The rotor resistance from the reactive power (the voltage the machine got).
            let evidence = Evidence {
                i: a.i_meas_dq,
                v: a.v_given.park(a.field),
                w_e_rad_s,
                psi_r_wb: self.run.ifoc.psi_r_wb(),
                v_limit_v,
                i_ref_step_a: self.run.i_ref_step_a,
            };
            // Sensorless, the rotor resistance is held at the magnetizing fit's: the
            // observer's field angle does not depend on it in steady state (the voltage
            // model fixes the flux; R_r only divides the frequency into speed and slip),
            // so the reactive power holds no information on it — the well-known
            // unobservability of R_r without a speed measurement.
            if !sensorless {
                let r = cfg.mras.update(self.run.ifoc.rotor_resistance_scale(), &self.run.model, &evidence);
                cfg.ifoc.set_rotor_resistance_scale(&mut self.run.ifoc, r);
            }
            // The inductances from the same reactive power at no load.
            // (Judged on the identified inductance: the curve's chord is not the machine's error.)
            let chord = self.run.chord;
            let l = cfg.mras.update_inductance(
                self.run.identified_inductance_scale(),
                &self.run.model,
                &evidence,
            );
            self.adapt_inductance_scale(cfg, l * chord);
        }
    }

    /// Encoder against the machine model: the magnitude of the applied voltage against that
    /// of the steady-state voltage ([`EnvelopeConfig::stator_voltage`]) of the measured
    /// currents at the encoder's speed. A frozen encoder at speed leaves the back-EMF in the applied voltage and takes
    /// it out of the model.
    #[inline(never)]
    fn check_encoder(
        &mut self,
        cfg: &DriveConfig,
        i: Dq,
        v_ab: AlphaBeta,
        field: SinCos,
        w_e: f32,
        v_limit: f32,
    ) {
        let e = &self.run.model;
        let v = v_ab.park(field);
        let (vd, vq) = e.stator_voltage(i.d, i.q, w_e, self.run.ifoc.psi_r_wb());
        // Magnitudes, not vectors: a detuned field angle (rotor resistance off by the
        // certified 2×) turns the voltage vector but hardly changes its length, while a
        // frozen encoder at speed removes the back-EMF from the model's length.
        // Volts, far from overflow: √(x² + y²) with the FPU's square root (no libm::hypotf).
        let residual = (sqrt_f32(v.d * v.d + v.q * v.q) - sqrt_f32(vd * vd + vq * vq)).abs();
        // The vector the applied voltage departs from the model's by: a leg held at a rail
        // leaves it on that phase's axis — for the stuck-switch check's next samples too.
        let departure = v_ab - Dq { d: vd, q: vq }.inverse_park(field);
        self.run.switches.note_departure(departure, v_limit);
        // Consecutive implausible checks (a leaky count accumulated the detuned corner's
        // transients into a false trip).
        if residual > ENCODER_RESIDUAL_FRACTION * v_limit {
            let window_s = cfg.ts_s * f32::from(cfg.slow_divider) * cfg.encoder.check_steps as f32;
            let turning = w_e.abs() * window_s > PINNED_FIELD_TURN_RAD;
            let switches = &self.run.switches;
            let verdict = self
                .run
                .voltage_check
                .implausible(departure, cfg.encoder.check_steps, || switches.undriven(turning));
            match verdict {
                // On the observer, the speed is its estimate, which the voltage model fixes: a
                // departure that no phase explains names no encoder — nothing to trip on.
                Some(Fault::EncoderImplausible) if self.on_observer(cfg) => {
                    self.run.voltage_check.plausible()
                }
                Some(Fault::EncoderImplausible) => {
                    self.run.voltage_check.plausible();
                    self.encoder_fault(cfg, Fault::EncoderImplausible);
                }
                Some(f) => self.trip(f),
                None => {}
            }
        } else {
            self.run.voltage_check.plausible();
        }
    }
}
