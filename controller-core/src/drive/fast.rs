//! The fast step, every PWM period: the instant limits → Clarke → the IFOC's fast part →
//! the current loops → the delay advance → the modulator (the hexagon's rare path out of
//! line) → the dead-time compensation; once per slow period, the encoder against the
//! machine model and the rotor-resistance law.

use super::*;
use crate::frames::{Abc, wrap_angle};
use crate::ifoc::IfocOutput;
use crate::mras::Evidence;
use crate::num::{max_f32, sqrt_f32};
use crate::supervisor::encoder::pinned_axis;
use crate::supervisor::limits::abs_bits;
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
                let th = self.test_angle_rad;
                let (a, sc, i_ref_ab) = self.rotating_current(amplitude_a);
                self.test_angle_rad = wrap_angle(th + omega_rad_s * cfg.ts_s);
                self.last_test_angle_rad = th;
                IfocOutput {
                    i_ref_dq: Dq { d: a, q: 0.0 },
                    i_ref_ab,
                    field: sc,
                    i_meas_dq: i_ab.park(sc),
                    omega_sl_rad_s: 0.0,
                }
            }
            // The current references at the field angle of the slow step's plan.
            _ => cfg.ifoc.step(&mut self.ifoc, i_ab),
        };
        // What the telemetry reads of this step, stored now (not held to the step's end; the
        // voltage applied at the end). A step that trips leaves the bridge off, and the
        // telemetry reads nothing while it is off ([`Drive::telemetry`]); `enable` clears it.
        (self.last.i_ab, self.last.i_ref_ab) = (i_ab, field.i_ref_ab);
        // The hexagon's vertex: the most one axis can get (the integrators' clamp).
        let v_usable = m.vdc_v * cfg.duty_max;
        let v_clamp = v_usable * (2.0 / 3.0);
        // The loops' request, in the stationary frame.
        let v_req = match cfg.current_frame {
            CurrentFrame::Stationary => {
                let e = field.i_ref_ab - i_ab;
                let [alpha, beta] = cfg.current.request(&mut self.current, e.alpha, e.beta, v_clamp);
                AlphaBeta { alpha, beta }
            }
            CurrentFrame::Synchronous => {
                // The trimmed references, as in the stationary frame (there the trim is in
                // `i_ref_ab`); here the loops' own integrators leave it at zero.
                let r = Dq { d: field.i_ref_dq.d + self.trim.d, q: field.i_ref_dq.q + self.trim.q };
                let i = field.i_meas_dq;
                let [d, q] = cfg.current.request(&mut self.current, r.d - i.d, r.q - i.q, v_clamp);
                Dq { d, q }.inverse_park(field.field)
            }
        };
        self.v_req2_sum += v_req.alpha * v_req.alpha + v_req.beta * v_req.beta;
        self.v_req_steps = self.v_req_steps.saturating_add(1);
        // Advanced over the delay to the period it acts in, then the one vector limit: the
        // modulator's hexagon, beyond which the rare path takes over.
        let v_applied = v_req.rotate(self.delay_rotation);
        let Some(duty) = svpwm::duties_within(v_applied, m.vdc_v, cfg.duty_max) else {
            return self.fast_step_limited(m, field.field, i_ab, v_req, after_slow);
        };
        self.saturated_steps = 0;
        if after_slow
            && !self.after_slow_checks(m, field.field, field.i_meas_dq, v_applied, Some(v_req), v_usable)
        {
            return off(self.mode);
        }
        if !running {
            // The magnetizing fit's voltage, in the field frame of this step (at speed the
            // field turns within a slow period): what the machine gets, the request.
            self.v_d_sum += v_req.park(field.field).d;
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
        let (brake, running) = (self.brake, self.mode == Mode::Running);
        let i_meas_dq = i_ab.park(field);
        let off = |mode| FastOutput { phases: PhaseCommand::Off, mode, brake };
        let v_usable = m.vdc_v * self.cfg.duty_max;
        let v_clamp = v_usable * (2.0 / 3.0);
        let modulation =
            svpwm::modulate_limited(v_req.rotate(self.delay_rotation), m.vdc_v, self.cfg.duty_max);
        if !(v_req.alpha.is_finite() && v_req.beta.is_finite()) {
            self.trip(Fault::NonFiniteOutput);
            return off(self.mode);
        }
        self.track_applied(modulation.v_applied, field, v_clamp);
        self.trim_hold = true;
        self.saturated_steps = self.saturated_steps.saturating_add(1);
        if self.saturated_steps >= self.cfg.saturation_steps {
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
            let r = self.delay_rotation;
            let v = applied.rotate(SinCos { sin: -r.sin, cos: r.cos });
            self.v_d_sum += v.park(field).d;
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
        let w_e_rad_s = self.model.pole_pairs() * m.omega_m_rad_s + self.ifoc.omega_sl_rad_s();
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
                psi_r_wb: self.ifoc.psi_r_wb(),
                v_limit_v,
            };
            let r = self.cfg.mras.update(self.ifoc.rotor_resistance_scale(), &self.model, &evidence);
            self.cfg.ifoc.set_rotor_resistance_scale(&mut self.ifoc, r);
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
            let i_ref = self.last.i_ref_ab.inverse_clarke();
            let (dead, band) = (cfg.dead_time_duty, cfg.dead_time_band_a);
            if RARE {
                svpwm::compensate_dead_time_rare(duty, i_ref, dead, band)
            } else {
                svpwm::compensate_dead_time(duty, i_ref, dead, band)
            }
        } else {
            duty
        };
        self.last.v_ab = v_applied;
        FastOutput { phases: PhaseCommand::Duty(duty), mode: self.mode, brake }
    }

    /// The modulator limited the request to `applied` (stationary frame, after the delay
    /// advance): back into the loops' frame, and their integrators track it.
    #[cold]
    #[inline(never)]
    pub(super) fn track_applied(&mut self, applied: AlphaBeta, field: SinCos, v_clamp: f32) {
        let r = self.delay_rotation;
        let back = applied.rotate(SinCos { sin: -r.sin, cos: r.cos });
        let v = match self.cfg.current_frame {
            CurrentFrame::Stationary => [back.alpha, back.beta],
            CurrentFrame::Synchronous => {
                let dq = back.park(field);
                [dq.d, dq.q]
            }
        };
        self.cfg.current.track(&mut self.current, v, v_clamp);
    }

    /// The fast step's supervisor and brake chopper alone, for a period in which the
    /// firmware holds the bridge itself (the bootstrap pre-charge, all low sides on): a
    /// failing check latches its fault as in [`Drive::fast_step`]; the control state does not
    /// move. Returns the brake chopper's switch.
    pub fn supervise_only(&mut self, m: &Measurements) -> bool {
        if !self.measurements_ok(m) {
            self.trip_on(m);
        }
        self.brake_chopper(m.vdc_v)
    }

    /// All supervisor checks pass: the common case, tested without working out which check
    /// fails. The phase currents are checked on their bit patterns: with the sign bit
    /// cleared, an IEEE 754 float orders like an unsigned integer, and ±∞ and NaN lie above
    /// every finite value. So `|i| > i_trip` (finite i) and "i not finite" are both
    /// `abs_bits(i) > abs_bits(i_trip)`: one integer comparison per phase, on the integer
    /// units, while the floating-point units run the control law. Equal to
    /// `self.supervise(m).is_none()` for every input (`supervisor_bit_test_equals_float_test`).
    #[inline]
    pub(super) fn measurements_ok(&self, m: &Measurements) -> bool {
        let i = m.i_abc_a;
        let i_peak_bits = abs_bits(i.a).max(abs_bits(i.b)).max(abs_bits(i.c));
        // The bus on its bits too, sign included: a negative or NaN reading is above every
        // positive level, so `bits ≤ max` is "finite, not negative, not above the maximum"
        // (a negative reading is named undervoltage, in every mode); the minimum (validated
        // ≥ 0) only while the bridge is active.
        // `min ≤ bits ≤ max` as one unsigned comparison, `bits − min ≤ max − min` (H. S.
        // Warren, Hacker's Delight, 2nd ed., §4-1), which needs `min ≤ max` as integers: the
        // configuration has `+0 ≤ min < max` (`DriveConfig::new` stores a zero minimum as +0,
        // `from_raw` refuses −0), so both bit patterns have the sign bit clear.
        let vdc_bits = m.vdc_v.to_bits();
        let active = matches!(self.mode, Mode::Magnetizing | Mode::Running);
        let vdc_min_bits = if active { self.cfg.vdc_min_v.to_bits() } else { 0 };
        i_peak_bits <= self.cfg.i_trip_bits
            && abs_bits(i.a + i.b + i.c) <= self.cfg.i_sum_bits
            && vdc_bits.wrapping_sub(vdc_min_bits) <= self.cfg.vdc_max_v.to_bits().wrapping_sub(vdc_min_bits)
    }

    /// Which supervisor check of the fast step fails, in order of precedence: non-finite
    /// current or bus voltage, overcurrent, current-sensor plausibility, bus overvoltage, bus
    /// undervoltage (while the bridge is active; a negative reading in every mode). The encoder's
    /// readings change only at the slow step, which checks them ([`Drive::slow_step`]).
    pub(super) fn supervise(&self, m: &Measurements) -> Option<Fault> {
        if !(m.i_abc_a.is_finite() && m.vdc_v.is_finite()) {
            return Some(Fault::NonFiniteInput);
        }
        let i = m.i_abc_a;
        let i_peak = max_f32(max_f32(i.a.abs(), i.b.abs()), i.c.abs()); // finite: checked above
        if i_peak > f32::from_bits(self.cfg.i_trip_bits) {
            return Some(Fault::Overcurrent);
        }
        if (i.a + i.b + i.c).abs() > f32::from_bits(self.cfg.i_sum_bits) {
            return Some(Fault::CurrentSensor);
        }
        if m.vdc_v > self.cfg.vdc_max_v {
            return Some(Fault::DcBusOvervoltage);
        }
        // Below zero is no bus at all (a sensor's sign or offset wrong): in every mode.
        let active = matches!(self.mode, Mode::Magnetizing | Mode::Running);
        if (active && m.vdc_v < self.cfg.vdc_min_v) || m.vdc_v.is_sign_negative() {
            return Some(Fault::DcBusUndervoltage);
        }
        None
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

    /// The brake chopper's hysteresis comparator on the measured bus voltage, in every mode:
    /// on above `on_v`, off below `off_v`, held between; off on a non-finite reading (the
    /// fast step trips on it; a resistor left on would drain a healthy bus).
    #[inline]
    pub(super) fn brake_chopper(&mut self, vdc_v: f32) -> bool {
        self.brake = vdc_v > self.cfg.brake_on_v || (self.brake && vdc_v >= self.cfg.brake_off_v);
        self.brake
    }

    /// Encoder against the machine model: the magnitude of the applied voltage against that
    /// of the steady-state voltage ([`EnvelopeConfig::stator_voltage`]) of the measured
    /// currents at the encoder's speed. A frozen encoder at speed leaves the back-EMF in the applied voltage and takes
    /// it out of the model.
    #[inline(never)]
    pub(super) fn check_encoder(&mut self, i: Dq, v_ab: AlphaBeta, field: SinCos, w_e: f32, v_limit: f32) {
        let e = &self.model;
        let v = v_ab.park(field);
        let (vd, vq) = e.stator_voltage(i.d, i.q, w_e, self.ifoc.psi_r_wb());
        // Magnitudes, not vectors: a detuned field angle (rotor resistance off by the
        // certified 2×) turns the voltage vector but hardly changes its length, while a
        // frozen encoder at speed removes the back-EMF from the model's length.
        // Volts, far from overflow: √(x² + y²) with the FPU's square root (no libm::hypotf).
        let residual = (sqrt_f32(v.d * v.d + v.q * v.q) - sqrt_f32(vd * vd + vq * vq)).abs();
        // Consecutive implausible checks (a leaky count accumulated the detuned corner's
        // transients into a false trip).
        if residual > ENCODER_RESIDUAL_FRACTION * v_limit {
            self.encoder_bad_steps = self.encoder_bad_steps.saturating_add(1);
            let window_s =
                self.cfg.ts_s * f32::from(self.cfg.slow_divider) * self.cfg.encoder_check_steps as f32;
            let turning = w_e.abs() * window_s > PINNED_FIELD_TURN_RAD;
            let axis = pinned_axis(v_ab).filter(|_| !turning);
            self.pinned_steps = match axis {
                Some(a) if self.pinned_steps == 0 || a == self.pinned_axis => self.pinned_steps + 1,
                _ => 0,
            };
            self.pinned_axis = axis.unwrap_or(0);
            if self.encoder_bad_steps >= self.cfg.encoder_check_steps {
                // The last half of the implausible checks on one phase's axis: that phase
                // does not answer (its lead or a switch: the same currents until the
                // reference reverses).
                let pinned = 2 * self.pinned_steps >= self.encoder_bad_steps;
                // A phase's current that misses one way (or both) is the bridge's, not the
                // encoder's: a wrong field angle turns the references, the loops still
                // follow them.
                let bridge = pinned || self.switches.undriven(turning);
                self.trip(if bridge { Fault::OpenPhase } else { Fault::EncoderImplausible });
            }
        } else {
            (self.encoder_bad_steps, self.pinned_steps) = (0, 0);
        }
    }
}
