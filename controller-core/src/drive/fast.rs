//! The fast step, every PWM period: the instant limits → Clarke → the IFOC's fast part →
//! the current loops → the delay advance → the modulator (the hexagon's rare path out of
//! line) → the dead-time compensation. The fast step of the period that adopts the slow
//! step's plan keeps its signals for the once-per-slow-period checks (`AfterSlow`), which
//! the next slow step runs on its state first (`SlowState::after_slow_checks`).

use super::*;
use crate::frames::{Abc, wrap_angle};
use crate::ifoc::IfocOutput;
use crate::observer::ObserverConfig;
#[cfg(doc)]
use crate::supervisor::limits::{BrakeLevels, Limits};
use crate::svpwm;

/// The rotating-current test reference at the test angle `angle_rad`: its amplitude
/// (limited to the IFOC's current limit), the angle's sin/cos and the αβ reference.
pub(super) fn rotating_current(
    cfg: &DriveConfig,
    amplitude_a: f32,
    angle_rad: f32,
) -> (f32, SinCos, AlphaBeta) {
    let a = amplitude_a.limit(0.0, cfg.ifoc.i_max_a());
    let sc = SinCos::new(angle_rad);
    (a, sc, AlphaBeta { alpha: a * sc.cos, beta: a * sc.sin })
}

impl FastSide {
    /// Current loop. See the module docs for the signal flow.
    pub fn fast_step(&mut self, m: &Measurements) -> FastOutput {
        // The period that adopts the slow step's plan keeps its signals for the next slow
        // step's checks (`FastSide::cadence`).
        let keep = self.state.steps_to_slow == self.cfg.adopt_at;
        self.fast(m, keep)
    }

    /// [`FastSide::fast_step`], told whether its period adopted the slow step's plan
    /// ([`FastSide::step`] knows): then its signals are kept for the next slow step's
    /// once-per-slow-period checks (`SlowInputs::after_slow`).
    #[inline(always)]
    pub(super) fn fast(&mut self, m: &Measurements, keep: bool) -> FastOutput {
        self.state.step(&self.cfg, &mut self.vhz, m, keep)
    }

    /// A period in which the firmware holds the bridge itself (the bootstrap pre-charge, all
    /// low sides on): the fast step's supervisor and brake chopper — a failing check latches
    /// its fault as in [`FastSide::fast_step`] — and the cadence with the shaft's stage of its
    /// slow periods (`SlowState::track_shaft`: the encoder read and its jump check, the rest
    /// detector, the thermal models; the rotor angle follows the shaft), run in this context
    /// on the slow side `slow` holds ([`Fault::Overrun`] if it is not back). The control
    /// state (loops, flux model, plan, the magnetizing time) does not move. Returns the brake
    /// chopper's switch.
    ///
    /// The cadence runs on (issue 54): frozen, with the encoder unread, the first read after
    /// a 40-period pre-charge spanned five slow periods against the one before it, and an
    /// enable on a rotor turning at 5 rad/s or more tripped [`Fault::EncoderLoss`] (the
    /// firmware's `an_enable_on_a_turning_rotor_keeps_the_encoder`).
    pub fn hold_step(&mut self, m: &Measurements, slow: &mut dyn SlowContext) -> bool {
        let held;
        let m = if self.cfg.source.sensorless() {
            held = self.state.held_shaft(m);
            &held
        } else {
            m
        };
        let back = if self.state.steps_to_slow == 0 {
            self.state.steps_to_slow = self.cfg.slow_divider.saturating_sub(1);
            slow.with(&mut |s| self.hold_tick(s, m))
        } else {
            self.state.steps_to_slow -= 1;
            // The adoption of a job latched before the hold (none on the board, whose link
            // commands an enable after it): its mode and faults.
            self.state.steps_to_slow != self.cfg.adopt_at || slow.with(&mut |s| self.hold_adopt(s))
        };
        if !back {
            self.state.trip(Fault::Overrun);
        }
        let cfg = &self.cfg;
        if !self.state.measurements_ok(cfg, m) {
            self.state.trip_on(cfg, m);
        }
        self.state.brake_chopper(cfg, m.vdc_v)
    }
}

impl FastSide {
    /// [`FastSide::hold_step`]'s tick on the slow side `s`: the shaft's stage of the slow
    /// step, the field turned with the rotor.
    fn hold_tick(&mut self, s: &mut SlowSide, m: &Measurements) {
        DriveMut::new(self, s).sync();
        let step_rad = s.state.track_shaft(&s.cfg, m);
        s.state.anchor_field(&s.cfg, step_rad);
        self.state.run.field.adopt_angle(s.state.run.ifoc.field_steps());
        self.state.trip_from(s.state.mode);
        DriveMut::new(self, s).sync();
    }

    /// [`FastSide::hold_step`]'s adoption: a command's order, the slow side's mode and
    /// faults.
    fn hold_adopt(&mut self, s: &mut SlowSide) {
        if s.order != Order::default() {
            self.obey(s);
        }
        self.state.trip_from(s.state.mode);
        self.plan_signals = s.plan_signals;
        DriveMut::new(self, s).sync();
    }
}

impl FastState {
    /// Sensorless, the bridge held by the firmware: no encoder to read; the shaft as the
    /// observer last left it, at rest. Out of line (measured: inlined into the firmware's
    /// interrupt it cost 4 instructions per Running period through the code around it,
    /// `cost interrupt_period` 719.0 against 715.0).
    #[cold]
    #[inline(never)]
    fn held_shaft(&self, m: &Measurements) -> Measurements {
        Measurements { omega_m_rad_s: 0.0, theta_m_rad: self.theta_est_rad, ..*m }
    }

    /// Overmodulating ([`DriveSpec::overmodulation`]): this period's sample with the phase
    /// that had no low-side window — in the period before the sample or the one after it,
    /// whose duties the last two steps gave — rebuilt as the negative sum of the other two
    /// (the modulator leaves at most one phase of a period without its window:
    /// [`svpwm::overmodulate`]). Where the highest phase changes between those two periods
    /// (the field passing a hexagon vertex) two phases lost theirs and one is not enough: the
    /// last period's current turned by the field's step stands in. The slow tick's sample is
    /// never rebuilt (the two periods around it keep every window: [`FastState::modulation`]),
    /// so the slow step's checks read three measured phases as without overmodulation. The
    /// masks move on a period (this step's own is noted by [`FastState::finished_beyond`]).
    /// Out of line: only an overmodulating drive calls it.
    #[inline(never)]
    pub(super) fn rebuild(&mut self, m: &Measurements) -> Measurements {
        let [last, before] = self.unsampled;
        self.unsampled = [0, last];
        let i = m.i_abc_a;
        let i_abc_a = match last | before {
            0 => return *m,
            1 => Abc { a: -(i.b + i.c), ..i },
            2 => Abc { b: -(i.a + i.c), ..i },
            4 => Abc { c: -(i.a + i.b), ..i },
            _ => self.run.last.i_ab.rotate(self.run.field.rotation()).inverse_clarke(),
        };
        Measurements { i_abc_a, ..*m }
    }

    /// The observer's step on this period's sample (the voltage asked two steps ago was
    /// applied over the period that ends at it), with the currents less the sensors' residual
    /// offsets ([`IdleZero`], read with the bridge off). Returns `m` with those currents and,
    /// on the observer ([`FastState::on_observer`]), its estimate as the encoder reading
    /// (the speed, and the shaft's angle it turns); beside a healthy encoder
    /// ([`SpeedFeedback::EncoderRideThrough`]), the encoder's reading.
    ///
    /// The speed is known while magnetizing: zero without an encoder (a rotor at rest), the
    /// encoder's beside one; running, it is estimated — beside the encoder too, which the
    /// observer never hears then, so that its estimate is still right when the encoder fails.
    /// With the bridge off nothing is known: a speed of zero, the angle held (the encoder's
    /// beside one). Out of line: an encoder drive's interrupt does not carry it (inlined,
    /// 1.1 KiB of the firmware's flash).
    #[inline(never)]
    pub(super) fn observe(&mut self, o: &ObserverConfig, sensorless: bool, m: &Measurements) -> Measurements {
        let on_observer = sensorless || self.run.on_observer;
        if !self.mode.is_active() {
            let i = m.i_abc_a;
            self.zero.idle([i.a, i.b, i.c]);
            if !on_observer {
                self.theta_est_rad = m.theta_m_rad;
                return *m;
            }
            return Measurements { omega_m_rad_s: 0.0, theta_m_rad: self.theta_est_rad, ..*m };
        }
        self.zero.active();
        let [za, zb, zc] = self.zero.offset_a();
        let i = m.i_abc_a;
        let m = &Measurements { i_abc_a: Abc { a: i.a - za, b: i.b - zb, c: i.c - zc }, ..*m };
        let (i, u) = (m.i_abc_a.clarke(), self.run.v_interval);
        self.run.v_interval = self.run.last.v_ab;
        let e = if self.mode == Mode::Running {
            self.run.observer.step(o, u, i)
        } else if on_observer {
            // The flying start's search sums the voltage model while the field stands still.
            let d = self.run.observer.voltage_model_step(o, u, i);
            self.run.search_psi = AlphaBeta {
                alpha: self.run.search_psi.alpha + d.alpha,
                beta: self.run.search_psi.beta + d.beta,
            };
            self.run.observer.step_known_speed(o, u, i, self.run.known_speed_rad_s)
        } else {
            self.run.observer.step_known_speed(o, u, i, m.omega_m_rad_s)
        };
        self.run.estimate = e;
        // The slow step samples the speed once per slow period: it reads the mean of the
        // period's estimates (the estimate's noise up to the observer's bandwidth, aliased
        // into the speed loop when sampled alone, put 4× the torque ripple of the encoder's
        // into a tuned drive).
        let r = &mut self.run;
        r.omega_sum_rad_s += e.omega_m_rad_s;
        r.omega_steps = r.omega_steps.saturating_add(1);
        let omega_m_rad_s = if self.steps_to_slow == 0 {
            let mean = r.omega_sum_rad_s / f32::from(r.omega_steps);
            (r.omega_sum_rad_s, r.omega_steps) = (0.0, 0);
            mean
        } else {
            e.omega_m_rad_s
        };
        if !on_observer {
            // Beside the encoder: its angle is where the observer's turning starts from.
            self.theta_est_rad = m.theta_m_rad;
            return *m;
        }
        self.theta_est_rad = wrap_angle(self.theta_est_rad + e.omega_m_rad_s * o.ts_s());
        Measurements { omega_m_rad_s, theta_m_rad: self.theta_est_rad, ..*m }
    }

    /// The speed and the field are the observer's: no encoder, or the encoder's fault ridden
    /// through (adopted from the slow side's plan).
    #[inline(always)]
    pub(super) fn on_observer(&self, cfg: &DriveConfig) -> bool {
        cfg.source.sensorless() || self.run.on_observer
    }

    /// The fast step; `keep`: its period adopted the slow step's plan (its signals kept for
    /// the next slow step's once-per-slow-period checks); `vhz`: the V/Hz law's run, which a
    /// V/Hz drive's steps take while Running.
    #[inline(always)]
    fn step(&mut self, cfg: &DriveConfig, vhz: &mut VhzRun, m: &Measurements, keep: bool) -> FastOutput {
        if !self.measurements_ok(cfg, m) {
            self.trip_on(cfg, m);
        }
        let brake = self.brake_chopper(cfg, m.vdc_v);
        let off = |mode| FastOutput { phases: PhaseCommand::Off, mode, brake };
        let running = self.mode == Mode::Running;
        if !running && self.mode != Mode::Magnetizing {
            return off(self.mode); // Idle or Fault
        }
        // V/Hz (the flag beside the mode already read: two instructions per period for a
        // vector drive, which tested it before the step's own checks for five).
        if running
            && cfg.vhz_on()
            && let Some(out) = self.step_vhz(cfg, vhz, m, brake)
        {
            return out;
        }
        let i_ab = m.i_abc_a.clarke();
        let field = match self.reference {
            Reference::RotatingCurrent { amplitude_a, omega_rad_s } if running => {
                let th = self.run.test_angle_rad;
                let (a, sc, i_ref_ab) = rotating_current(cfg, amplitude_a, th);
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
            _ => cfg.ifoc.step_field(&mut self.run.field, i_ab),
        };
        // What the telemetry reads of this step, stored now (not held to the step's end; the
        // voltage applied at the end). A step that trips leaves the bridge off, and the
        // telemetry reads nothing while it is off ([`Drive::telemetry`]); `enable` clears it.
        (self.run.last.i_ab, self.run.last.i_ref_ab) = (i_ab, field.i_ref_ab);
        // The hexagon's vertex: the most one axis can get (the integrators' clamp).
        let v_usable = m.vdc_v * cfg.duty_max;
        let v_clamp = v_usable * (2.0 / 3.0);
        // The loops' request, in the stationary frame, with the plan's feedforward
        // (`FastState::feedforward`), added in the loops' own frame.
        let ff = self.run.v_ff;
        let v_req = match cfg.current_frame {
            CurrentFrame::Stationary => {
                let e = field.i_ref_ab - i_ab;
                let [alpha, beta] = cfg.current.request(&mut self.run.current, e.alpha, e.beta, v_clamp);
                // The back-EMF, on the field's q axis (the plan's d part is 0 here).
                let sc = field.field;
                AlphaBeta { alpha: alpha - ff.q * sc.sin, beta: beta + ff.q * sc.cos }
            }
            CurrentFrame::Synchronous => {
                // The trimmed references, as in the stationary frame (there the trim is in
                // `i_ref_ab`); here the loops' own integrators leave it at zero.
                let r = Dq { d: field.i_ref_dq.d + self.run.trim.d, q: field.i_ref_dq.q + self.run.trim.q };
                let i = field.i_meas_dq;
                let [d, q] = cfg.current.request(&mut self.run.current, r.d - i.d, r.q - i.q, v_clamp);
                Dq { d: d + ff.d, q: q + ff.q }.inverse_park(field.field)
            }
        };
        self.run.v_req2_sum += v_req.alpha * v_req.alpha + v_req.beta * v_req.beta;
        self.run.v_req_steps = self.run.v_req_steps.saturating_add(1);
        // Advanced over the delay to the period it acts in, then the one vector limit: the
        // modulator's hexagon, beyond which the rare path takes over.
        let v_applied = v_req.rotate(self.run.delay_rotation);
        let Some(duty) = svpwm::duties_within(v_applied, m.vdc_v, cfg.duty_sampled()) else {
            return self.step_limited(cfg, m, field.field, i_ab, v_req, keep);
        };
        self.run.saturated_steps = 0;
        if keep {
            self.keep_after_slow(m, field.field, field.i_meas_dq, v_applied, v_req, v_usable);
        }
        if !running {
            // The magnetizing fit's voltage, in the field frame of this step (at speed the
            // field turns within a slow period): what the machine gets, the request.
            self.run.v_fit_sum += v_req.park(field.field);
        }
        self.finish::<false>(cfg, duty, v_applied, brake)
    }

    /// V/Hz, Running ([`crate::vhz`]), after the supervisor's instant limits and the brake
    /// chopper: the law's voltage for the measured current, advanced over the delay,
    /// modulated — the hexagon's limit as in vector control (a request that is not finite
    /// trips [`Fault::NonFiniteOutput`], one held at the limit for `saturation_time_s`
    /// [`Fault::LossOfControl`]). The first step takes over the magnetized machine at the
    /// field angle the magnetizing current was held at. `None` under the rotating-current test
    /// (the current loops run it). Out of line: a vector drive's interrupt does not carry it.
    #[cold]
    #[inline(never)]
    fn step_vhz(
        &mut self,
        cfg: &DriveConfig,
        run: &mut VhzRun,
        m: &Measurements,
        brake: bool,
    ) -> Option<FastOutput> {
        let v = cfg.vhz()?;
        if matches!(self.reference, Reference::RotatingCurrent { .. }) {
            return None;
        }
        let i_ab = m.i_abc_a.clarke();
        if !run.on {
            run.state = v.start(self.run.field.last_theta_e_rad(), i_ab);
            run.on = true;
        }
        let v_ab = v.step(&mut run.state, &run.plan, i_ab);
        // The telemetry's and the dead-time compensation's reference: the operating point.
        (self.run.last.i_ab, self.run.last.i_ref_ab) = (i_ab, run.state.i0_ab());
        let v_applied = v_ab.rotate(self.run.delay_rotation);
        if !(v_applied.alpha.is_finite() && v_applied.beta.is_finite()) {
            self.trip(Fault::NonFiniteOutput);
            return Some(FastOutput { phases: PhaseCommand::Off, mode: self.mode, brake });
        }
        let (modulation, limit) = match svpwm::duties_within(v_applied, m.vdc_v, cfg.duty_sampled()) {
            Some(duty) => (svpwm::Modulation { duty, v_applied, saturated: false }, None),
            None => self.modulation(cfg, v_applied, m.vdc_v),
        };
        self.run.saturated_steps =
            if limit.is_some() { self.run.saturated_steps.saturating_add(1) } else { 0 };
        if self.run.saturated_steps >= cfg.saturation_steps {
            self.trip(Fault::LossOfControl);
            return Some(FastOutput { phases: PhaseCommand::Off, mode: self.mode, brake });
        }
        // The dead-time compensation out of line (the rare path's): inlined, this step took
        // 1.4 KB of the firmware's flash.
        Some(self.finished_beyond(cfg, modulation.duty, modulation.v_applied, brake))
    }

    /// The modulator beyond the sampled hexagon: what the bridge gets, and the loops' limit
    /// (`Some`: the voltage the modulator can give them, the request being beyond it; `None`:
    /// the request is applied as asked). Overmodulating, [`svpwm::overmodulate`] — except in
    /// the two periods around the slow tick's sample (the steps before the tick), which keep
    /// every phase's window ([`svpwm::modulate_limited`] on the sampled hexagon), so that the
    /// sample the slow step's checks read, and at least one in each slow period the fast
    /// step's current-sum check reads, is three measured phases: a sensor that fails while
    /// overmodulating is still seen (rebuilt from a phase stuck at 1 A the loops ran the
    /// bridge at its limit, every phase rebuilt, until a stuck-switch verdict — found by the
    /// fault matrix). That dip is the modulator's own and the loops do not track it: their
    /// limit stays the overmodulated one. Otherwise the sampled hexagon, the loops' limit.
    #[inline(always)]
    fn modulation(
        &self,
        cfg: &DriveConfig,
        v: AlphaBeta,
        vdc_v: f32,
    ) -> (svpwm::Modulation, Option<AlphaBeta>) {
        if cfg.overmodulating() {
            let over = svpwm::overmodulate(v, vdc_v, cfg.duty_sampled, cfg.duty_max);
            let limit = over.saturated.then_some(over.v_applied);
            if self.steps_to_slow > 1 {
                (over, limit)
            } else {
                (svpwm::modulate_limited(v, vdc_v, cfg.duty_sampled), limit)
            }
        } else {
            let m = svpwm::modulate_limited(v, vdc_v, cfg.duty_sampled());
            (m, Some(m.v_applied))
        }
    }

    /// [`FastState::finish`] on a path beyond the sampled hexagon: overmodulating, the phases
    /// its duties leave without a window noted for the next two samples
    /// ([`FastState::rebuild`]).
    #[inline(always)]
    fn finished_beyond(
        &mut self,
        cfg: &DriveConfig,
        duty: Abc,
        v_applied: AlphaBeta,
        brake: bool,
    ) -> FastOutput {
        let out = self.finish::<true>(cfg, duty, v_applied, brake);
        if cfg.overmodulating()
            && let PhaseCommand::Duty(d) = out.phases
        {
            self.unsampled[0] = svpwm::unsampled_phases(d, cfg.duty_sampled + cfg.dead_time_duty);
        }
        out
    }

    /// The rare path of the fast step: the modulator limited the request (beyond the hexagon,
    /// not finite, or a bad bus). The loops' integrators track what it applied; a request
    /// that is not finite trips [`Fault::NonFiniteOutput`], one held at the limit for
    /// `saturation_time_s` [`Fault::LossOfControl`]; the rotor-resistance law's evidence is
    /// what it applied (`AfterSlow::v_given`).
    #[cold]
    #[inline(never)]
    fn step_limited(
        &mut self,
        cfg: &DriveConfig,
        m: &Measurements,
        field: SinCos,
        i_ab: AlphaBeta,
        v_req: AlphaBeta,
        keep: bool,
    ) -> FastOutput {
        // The common path's values, made again (the same operations): few of them held
        // across its body, none through memory.
        let (brake, running) = (self.brake, self.mode == Mode::Running);
        let i_meas_dq = i_ab.park(field);
        let off = |mode| FastOutput { phases: PhaseCommand::Off, mode, brake };
        let v_usable = m.vdc_v * cfg.duty_max;
        let v_clamp = v_usable * (2.0 / 3.0);
        let (modulation, limit) = self.modulation(cfg, v_req.rotate(self.run.delay_rotation), m.vdc_v);
        if !(v_req.alpha.is_finite() && v_req.beta.is_finite()) {
            self.trip(Fault::NonFiniteOutput);
            return off(self.mode);
        }
        let applied = modulation.v_applied;
        // The voltage applied, back in the request's frame (the flux linkage the magnetizing
        // fit reads is the volt-seconds applied; the rotor-resistance law, the voltage the
        // machine got).
        let r = self.run.delay_rotation;
        let given = applied.rotate(SinCos { sin: -r.sin, cos: r.cos });
        let Some(limit) = limit else {
            // Overmodulating, within the modulator's reach: the common path's bookkeeping
            // (the request is the loops' voltage; the bridge's, the request or — around the
            // tick's sample — less).
            self.run.saturated_steps = 0;
            if keep {
                self.keep_after_slow(m, field, i_meas_dq, applied, given, v_usable);
            }
            if !running {
                self.run.v_fit_sum += given.park(field);
            }
            return self.finished_beyond(cfg, modulation.duty, applied, brake);
        };
        self.track_applied(cfg, limit, field, v_clamp);
        self.run.trim_hold = true;
        self.run.saturated_steps = self.run.saturated_steps.saturating_add(1);
        if self.run.saturated_steps >= cfg.saturation_steps {
            self.trip(Fault::LossOfControl);
            return off(self.mode);
        }
        if keep {
            self.keep_after_slow(m, field, i_meas_dq, applied, given, v_usable);
        }
        if !running {
            // The magnetizing fit's voltage: the modulator's limit of the request at the
            // current's step.
            self.run.v_fit_sum += given.park(field);
        }
        self.finished_beyond(cfg, modulation.duty, applied, brake)
    }

    /// The signals of the fast step after the slow step for the once-per-slow-period checks,
    /// kept while Running on the field-oriented references (out of line: once per slow
    /// period).
    #[inline(never)]
    fn keep_after_slow(
        &mut self,
        m: &Measurements,
        field: SinCos,
        i_meas_dq: Dq,
        v_applied: AlphaBeta,
        v_given: AlphaBeta,
        v_usable_v: f32,
    ) {
        let field_oriented = !matches!(self.reference, Reference::RotatingCurrent { .. });
        if self.mode == Mode::Running && field_oriented {
            let omega_m_rad_s = m.omega_m_rad_s;
            self.run.after_slow =
                Some(AfterSlow { omega_m_rad_s, field, i_meas_dq, v_applied, v_given, v_usable_v });
        }
    }

    /// The fast step's end on either path: the dead-time compensation of the duties, what
    /// the telemetry reads of this step, the output.
    /// `RARE`: on the rare path, whose dead-time compensation is made out of line
    /// ([`svpwm::compensate_dead_time_rare`], the same values).
    #[inline(always)]
    fn finish<const RARE: bool>(
        &mut self,
        cfg: &DriveConfig,
        duty: Abc,
        v_applied: AlphaBeta,
        brake: bool,
    ) -> FastOutput {
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
    /// advance): back into the loops' frame, and their integrators follow it
    /// (`CurrentControllerConfig::track`, turned with the field in the stationary frame).
    #[cold]
    #[inline(never)]
    fn track_applied(&mut self, cfg: &DriveConfig, applied: AlphaBeta, field: SinCos, v_clamp: f32) {
        let r = self.run.delay_rotation;
        let (back, emf) = (applied.rotate(SinCos { sin: -r.sin, cos: r.cos }), self.feedforward(field));
        // The loops' share of it: the feedforward is not theirs to track.
        let back = AlphaBeta { alpha: back.alpha - emf.alpha, beta: back.beta - emf.beta };
        // The loops' frame's turn against the field since the last sample.
        let (v, turn) = match cfg.current_frame {
            CurrentFrame::Stationary => ([back.alpha, back.beta], self.run.field.rotation()),
            CurrentFrame::Synchronous => {
                let dq = back.park(field);
                ([dq.d, dq.q], SinCos::default())
            }
        };
        cfg.current.track(&mut self.run.current, v, cfg.tracking_rate, turn, v_clamp);
    }

    /// The plan's feedforward at the field angle `field`, in the stationary frame. Added to
    /// the loops' request, it leaves them the stator's own impedance. Stationary frame: the
    /// back-EMF `ω_e·(L_m/L_r)·ψ̂_r` on the field's q axis ([`IfocConfig::back_emf_v`]) — a
    /// stationary-frame PI otherwise makes the EMF out of its error (≈ E/k_p: 70 A of a
    /// 153 kW motor's 180 A at twice its base speed, where the modulator's limit then left
    /// the trim no room and the current fell to half its reference). Synchronous frame: the
    /// decoupling `jω_e·σL_s·i*` ([`DriveConfig::decoupling_v`]) and no EMF, which its
    /// integrators hold as the constant it is there (fed forward on the model's flux and the
    /// plan's speed, the Krause template's envelope fell from −8.2 % to −12 % at 35.7 rad/s).
    /// A disturbance's feedforward, outside the loops: their characteristic polynomial, and
    /// so the certificate's analysis, do not change. The slow step plans it in the field
    /// frame; the fast step adds it in the loops' frame (the common path inlines its two
    /// cases: one rotation of a whole vector here cost the fast step 6.6 instructions per
    /// period, `cost fast_step`), this on the rare path.
    #[inline(always)]
    fn feedforward(&self, field: SinCos) -> AlphaBeta {
        self.run.v_ff.inverse_park(field)
    }

    /// The slow side's mode `mode` taken, unless a fault of the fast step came first.
    #[inline(always)]
    pub(super) fn trip_from(&mut self, mode: Mode) {
        if !matches!(self.mode, Mode::Fault(_)) {
            self.mode = mode;
        }
    }

    /// All supervisor checks of the fast step pass ([`Limits::ok`]).
    #[inline]
    pub(super) fn measurements_ok(&self, cfg: &DriveConfig, m: &Measurements) -> bool {
        cfg.limits.ok(m, self.mode.is_active())
    }

    /// The rare path of the fast step: a supervisor check failed; latch its fault
    /// ([`Limits::fault`]).
    #[cold]
    #[inline(never)]
    fn trip_on(&mut self, cfg: &DriveConfig, m: &Measurements) {
        // `measurements_ok` and `fault` agree, so this is always Some.
        if let Some(f) = cfg.limits.fault(m, self.mode.is_active()) {
            self.trip(f);
        }
    }

    /// The brake chopper's comparator on the measured bus voltage ([`BrakeLevels::switch`]),
    /// in every mode.
    #[inline]
    fn brake_chopper(&mut self, cfg: &DriveConfig, vdc_v: f32) -> bool {
        self.brake = cfg.brake.switch(self.brake, vdc_v);
        self.brake
    }
}
