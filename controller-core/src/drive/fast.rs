//! The fast step, every PWM period: the instant limits → Clarke → the IFOC's fast part →
//! the current loops → the delay advance → the modulator (the hexagon's rare path out of
//! line) → the dead-time compensation; once per slow period, the encoder against the
//! machine model and the rotor-resistance law.

use super::*;
use crate::frames::{Abc, wrap_angle};
use crate::ifoc::IfocOutput;
use crate::mras::Evidence;
use crate::num::sqrt_f32;
#[cfg(doc)]
use crate::supervisor::limits::{BrakeLevels, Limits};
use crate::svpwm;

impl Drive {
    /// Current loop. See the module docs for the signal flow.
    pub fn fast_step(&mut self, m: &Measurements) -> FastOutput {
        // The fast step right after the slow step (the phase checks are the slow step's own:
        // `Drive::check_phases`).
        let after_slow = self.steps_to_slow == self.cfg.slow_divider.saturating_sub(1);
        self.fast(m, after_slow)
    }

    /// [`Drive::fast_step`], told whether it follows the slow step ([`Drive::step`] knows).
    #[inline(always)]
    pub(super) fn fast(&mut self, m: &Measurements, after_slow: bool) -> FastOutput {
        if !self.measurements_ok(m) {
            self.trip_on(m);
        }
        let brake = self.brake_chopper(m.vdc_v);
        let off = |mode| FastOutput { phases: PhaseCommand::Off, mode, brake };
        let running = self.mode == Mode::Running;
        if !running && self.mode != Mode::Magnetizing {
            return off(self.mode); // Idle or Fault
        }
        let cfg = &self.cfg;
        let i_ab = m.i_abc_a.clarke();
        let field = match self.reference {
            Reference::RotatingCurrent { amplitude_a, omega_rad_s } if running => {
                let th = self.run.test_angle_rad;
                let (a, sc, i_ref_ab) = self.rotating_current(amplitude_a);
                self.run.test_angle_rad = wrap_angle(th + omega_rad_s * cfg.ts_s);
                self.run.last_test_angle_rad = th;
                IfocOutput {
                    i_ref_dq: Dq { d: a, q: 0.0 },
                    i_ref_ab,
                    field: sc,
                    i_meas_dq: i_ab.park(sc),
                    omega_sl_rad_s: 0.0,
                }
            }
            // The current references at the field angle of the slow step's plan.
            _ => cfg.ifoc.step(&mut self.run.ifoc, i_ab),
        };
        // What the telemetry reads of this step, stored now (not held to the step's end; the
        // voltage applied at the end). A step that trips leaves the bridge off, and the
        // telemetry reads nothing while it is off ([`Drive::telemetry`]); `enable` clears it.
        (self.run.last.i_ab, self.run.last.i_ref_ab) = (i_ab, field.i_ref_ab);
        // The hexagon's vertex: the most one axis can get (the integrators' clamp).
        let v_usable = m.vdc_v * cfg.duty_max;
        let v_clamp = v_usable * (2.0 / 3.0);
        // The loops' request, in the stationary frame.
        let v_req = match cfg.current_frame {
            CurrentFrame::Stationary => {
                let e = field.i_ref_ab - i_ab;
                let [alpha, beta] = cfg.current.request(&mut self.run.current, e.alpha, e.beta, v_clamp);
                AlphaBeta { alpha, beta }
            }
            CurrentFrame::Synchronous => {
                // The trimmed references, as in the stationary frame (there the trim is in
                // `i_ref_ab`); here the loops' own integrators leave it at zero.
                let r = Dq { d: field.i_ref_dq.d + self.run.trim.d, q: field.i_ref_dq.q + self.run.trim.q };
                let i = field.i_meas_dq;
                let [d, q] = cfg.current.request(&mut self.run.current, r.d - i.d, r.q - i.q, v_clamp);
                Dq { d, q }.inverse_park(field.field)
            }
        };
        self.run.v_req2_sum += v_req.alpha * v_req.alpha + v_req.beta * v_req.beta;
        self.run.v_req_steps = self.run.v_req_steps.saturating_add(1);
        // Advanced over the delay to the period it acts in, then the one vector limit: the
        // modulator's hexagon, beyond which the rare path takes over.
        let v_applied = v_req.rotate(self.run.delay_rotation);
        let Some(duty) = svpwm::duties_within(v_applied, m.vdc_v, cfg.duty_max) else {
            return self.fast_step_limited(m, field.field, i_ab, v_req, after_slow);
        };
        self.run.saturated_steps = 0;
        if after_slow
            && !self.after_slow_checks(m, field.field, field.i_meas_dq, v_applied, Some(v_req), v_usable)
        {
            return off(self.mode);
        }
        if !running {
            // The magnetizing fit's voltage, in the field frame of this step (at speed the
            // field turns within a slow period): what the machine gets, the request.
            self.run.v_d_sum += v_req.park(field.field).d;
        }
        self.finish_fast_step::<false>(duty, v_applied, brake)
    }

    /// The rare path of the fast step: the modulator limited the request (beyond the hexagon,
    /// not finite, or a bad bus). The loops' integrators track what it applied; a request
    /// that is not finite trips [`Fault::NonFiniteOutput`], one held at the limit for
    /// `saturation_time_s` [`Fault::LossOfControl`]; the rotor-resistance law does not listen
    /// (its evidence is the loops' unlimited request).
    #[cold]
    #[inline(never)]
    pub(super) fn fast_step_limited(
        &mut self,
        m: &Measurements,
        field: SinCos,
        i_ab: AlphaBeta,
        v_req: AlphaBeta,
        after_slow: bool,
    ) -> FastOutput {
        // The common path's values, made again (the same operations): few of them held
        // across its body, none through memory.
        let (brake, running) = (self.machine.brake, self.mode == Mode::Running);
        let i_meas_dq = i_ab.park(field);
        let off = |mode| FastOutput { phases: PhaseCommand::Off, mode, brake };
        let v_usable = m.vdc_v * self.cfg.duty_max;
        let v_clamp = v_usable * (2.0 / 3.0);
        let modulation =
            svpwm::modulate_limited(v_req.rotate(self.run.delay_rotation), m.vdc_v, self.cfg.duty_max);
        if !(v_req.alpha.is_finite() && v_req.beta.is_finite()) {
            self.trip(Fault::NonFiniteOutput);
            return off(self.mode);
        }
        self.track_applied(modulation.v_applied, field, v_clamp);
        self.run.trim_hold = true;
        self.run.saturated_steps = self.run.saturated_steps.saturating_add(1);
        if self.run.saturated_steps >= self.cfg.saturation_steps {
            self.trip(Fault::LossOfControl);
            return off(self.mode);
        }
        let applied = modulation.v_applied;
        if after_slow && !self.after_slow_checks(m, field, i_meas_dq, applied, None, v_usable) {
            return off(self.mode);
        }
        if !running {
            // The magnetizing fit's voltage: the modulator's limit of the request at the
            // current's step, back in the request's frame (the flux linkage the fit reads is
            // the volt-seconds applied).
            let r = self.run.delay_rotation;
            let v = applied.rotate(SinCos { sin: -r.sin, cos: r.cos });
            self.run.v_d_sum += v.park(field).d;
        }
        self.finish_fast_step::<true>(modulation.duty, applied, brake)
    }

    /// The once-per-slow-period work, on the fast step right after the slow step (out of
    /// line: one test per fast step), while Running on the field-oriented references: the
    /// encoder against the machine model on the voltage applied, `v_applied`, then the
    /// rotor-resistance law on the loops' request `v_req` — `None` when the modulator limited
    /// it (the law listens to the unlimited request only). False when the encoder check
    /// tripped (the bridge off).
    #[inline(never)]
    pub(super) fn after_slow_checks(
        &mut self,
        m: &Measurements,
        field: SinCos,
        i_meas_dq: Dq,
        v_applied: AlphaBeta,
        v_req: Option<AlphaBeta>,
        v_usable_v: f32,
    ) -> bool {
        let field_oriented = !matches!(self.reference, Reference::RotatingCurrent { .. });
        if !(self.mode == Mode::Running && field_oriented) {
            return true;
        }
        let w_e_rad_s = self.run.model.pole_pairs() * m.omega_m_rad_s + self.run.ifoc.omega_sl_rad_s();
        let v_limit_v = svpwm::linear_limit_v(v_usable_v);
        self.check_encoder(i_meas_dq, v_applied, field, w_e_rad_s, v_limit_v);
        if self.mode != Mode::Running {
            return false;
        }
        if let Some(v_req) = v_req {
            // The rotor resistance from the reactive power (the loops' own request).
            let evidence = Evidence {
                i: i_meas_dq,
                v: v_req.park(field),
                w_e_rad_s,
                psi_r_wb: self.run.ifoc.psi_r_wb(),
                v_limit_v,
            };
            let r = self.cfg.mras.update(self.run.ifoc.rotor_resistance_scale(), &self.run.model, &evidence);
            self.cfg.ifoc.set_rotor_resistance_scale(&mut self.run.ifoc, r);
        }
        true
    }

    /// The fast step's end on either path: the dead-time compensation of the duties, what
    /// the telemetry reads of this step, the output.
    /// `RARE`: on the rare path, whose dead-time compensation is made out of line
    /// ([`svpwm::compensate_dead_time_rare`], the same values).
    #[inline(always)]
    pub(super) fn finish_fast_step<const RARE: bool>(
        &mut self,
        duty: Abc,
        v_applied: AlphaBeta,
        brake: bool,
    ) -> FastOutput {
        let cfg = &self.cfg;
        let duty = if cfg.dead_time_duty > 0.0 {
            // This step's references (stored by the step).
            let i_ref = self.run.last.i_ref_ab.inverse_clarke();
            let (dead, band) = (cfg.dead_time_duty, cfg.dead_time_band_a);
            if RARE {
                svpwm::compensate_dead_time_rare(duty, i_ref, dead, band)
            } else {
                svpwm::compensate_dead_time(duty, i_ref, dead, band)
            }
        } else {
            duty
        };
        self.run.last.v_ab = v_applied;
        FastOutput { phases: PhaseCommand::Duty(duty), mode: self.mode, brake }
    }

    /// The modulator limited the request to `applied` (stationary frame, after the delay
    /// advance): back into the loops' frame, and their integrators track it.
    #[cold]
    #[inline(never)]
    pub(super) fn track_applied(&mut self, applied: AlphaBeta, field: SinCos, v_clamp: f32) {
        let r = self.run.delay_rotation;
        let back = applied.rotate(SinCos { sin: -r.sin, cos: r.cos });
        let v = match self.cfg.current_frame {
            CurrentFrame::Stationary => [back.alpha, back.beta],
            CurrentFrame::Synchronous => {
                let dq = back.park(field);
                [dq.d, dq.q]
            }
        };
        self.cfg.current.track(&mut self.run.current, v, v_clamp);
    }

    /// A period in which the firmware holds the bridge itself (the bootstrap pre-charge, all
    /// low sides on): the fast step's supervisor and brake chopper — a failing check latches
    /// its fault as in [`Drive::fast_step`] — and the cadence with the shaft's stage of its
    /// slow periods (`Drive::track_shaft`: the encoder read and its jump check, the rest
    /// detector, the thermal models; the rotor angle follows the shaft). The control state
    /// (loops, flux model, plan, the magnetizing time) does not move. Returns the brake
    /// chopper's switch.
    ///
    /// The cadence runs on (issue 54): frozen, with the encoder unread, the first read after
    /// a 40-period pre-charge spanned five slow periods against the one before it, and an
    /// enable on a rotor turning at 5 rad/s or more tripped [`Fault::EncoderLoss`] (the
    /// firmware's `an_enable_on_a_turning_rotor_keeps_the_encoder`).
    pub fn hold_step(&mut self, m: &Measurements) -> bool {
        if self.steps_to_slow == 0 {
            let step_rad = self.track_shaft(m);
            self.anchor_field(step_rad);
            self.steps_to_slow = self.cfg.slow_divider.saturating_sub(1);
        } else {
            self.steps_to_slow -= 1;
        }
        if !self.measurements_ok(m) {
            self.trip_on(m);
        }
        self.brake_chopper(m.vdc_v)
    }

    /// All supervisor checks of the fast step pass ([`Limits::ok`]).
    #[inline]
    pub(super) fn measurements_ok(&self, m: &Measurements) -> bool {
        self.cfg.limits.ok(m, self.mode.is_active())
    }

    /// Which supervisor check of the fast step fails ([`Limits::fault`]).
    pub(super) fn supervise(&self, m: &Measurements) -> Option<Fault> {
        self.cfg.limits.fault(m, self.mode.is_active())
    }

    /// The rare path of the fast step: a supervisor check failed; latch its fault.
    #[cold]
    #[inline(never)]
    pub(super) fn trip_on(&mut self, m: &Measurements) {
        // `measurements_ok` and `supervise` agree, so this is always Some.
        if let Some(f) = self.supervise(m) {
            self.trip(f);
        }
    }

    /// The brake chopper's comparator on the measured bus voltage ([`BrakeLevels::switch`]),
    /// in every mode.
    #[inline]
    pub(super) fn brake_chopper(&mut self, vdc_v: f32) -> bool {
        self.machine.brake = self.cfg.brake.switch(self.machine.brake, vdc_v);
        self.machine.brake
    }

    /// Encoder against the machine model: the magnitude of the applied voltage against that
    /// of the steady-state voltage ([`EnvelopeConfig::stator_voltage`]) of the measured
    /// currents at the encoder's speed. A frozen encoder at speed leaves the back-EMF in the applied voltage and takes
    /// it out of the model.
    #[inline(never)]
    pub(super) fn check_encoder(&mut self, i: Dq, v_ab: AlphaBeta, field: SinCos, w_e: f32, v_limit: f32) {
        let e = &self.run.model;
        let v = v_ab.park(field);
        let (vd, vq) = e.stator_voltage(i.d, i.q, w_e, self.run.ifoc.psi_r_wb());
        // Magnitudes, not vectors: a detuned field angle (rotor resistance off by the
        // certified 2×) turns the voltage vector but hardly changes its length, while a
        // frozen encoder at speed removes the back-EMF from the model's length.
        // Volts, far from overflow: √(x² + y²) with the FPU's square root (no libm::hypotf).
        let residual = (sqrt_f32(v.d * v.d + v.q * v.q) - sqrt_f32(vd * vd + vq * vq)).abs();
        // Consecutive implausible checks (a leaky count accumulated the detuned corner's
        // transients into a false trip).
        if residual > ENCODER_RESIDUAL_FRACTION * v_limit {
            let cfg = &self.cfg;
            let window_s = cfg.ts_s * f32::from(cfg.slow_divider) * cfg.encoder_check_steps as f32;
            let turning = w_e.abs() * window_s > PINNED_FIELD_TURN_RAD;
            let switches = &self.run.switches;
            let verdict = self
                .run
                .voltage_check
                .implausible(v_ab, turning, cfg.encoder_check_steps, || switches.undriven(turning));
            if let Some(f) = verdict {
                self.trip(f);
            }
        } else {
            self.run.voltage_check.plausible();
        }
    }
}
