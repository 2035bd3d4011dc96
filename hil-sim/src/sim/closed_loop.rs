//! The closed-loop run: a [`DriveUnderTest`] against the plant, period by period, with the
//! scenario's events, the sensors, the inverter, the DC link and the legs (module docs of
//! `sim`: the timing).

use super::dc_link::LinkState;
use super::integrate::{
    BRIDGE_OFF_SUBSTEPS, PHASE_AXES, check_rk4_step, integrate_bridge_off, integrate_segments,
};
use super::{
    DriveUnderTest, Event, HeatingRun, Injection, LoadModel, PassiveLoad, Row, SWITCH_ACTING_DUTY, Scenario,
    non_finite,
};
use crate::bridge_fault::{Legs, SwitchShort};
use crate::inverter::InverterModel;
use crate::sensors::Sensors;
use controller_core::drive::{Measurements, PhaseCommand};
use controller_core::frames::AlphaBeta;
use controller_core::motor::MotorParams;
use plant::thermal::Heating;
use plant::{Machine, MachineState, Rk4Midway};

/// The plant's side of one period in [`run`].
// One on the stack per period, never stored: boxing the large variant would allocate in
// the simulator's hot loop.
#[allow(clippy::large_enum_variant)]
enum Period {
    /// Average inverter: the held stator voltage and the step begun with it.
    Average([f64; 2], Rk4Midway),
    /// Switching inverter: the duties whose segments the plant integrates.
    Switching([f64; 3]),
    /// All six switches off: the freewheeling diodes ([`integrate_bridge_off`]).
    Off,
}

/// Run `scenario` with `drive` (already configured) on `machine`; `pwm_hz` is the drive's
/// fast rate. Each trace row goes to `sink` as it is made (a long run streams to disk; an
/// error from the sink — a full disk, an interrupt — stops the run with that error). Calls
/// `progress(fraction)` now and then. A plant state that is no longer finite (a diverging
/// run) stops the run with an error at the first trace row that shows it. Returns the
/// number of rows.
///
/// Never inlined: on its own, the loop keeps more of its state in registers than inlined
/// into the CLI's `main` (measured with `hil-sim bench`).
#[inline(never)]
pub fn run(
    drive: &mut impl DriveUnderTest,
    machine: &Machine,
    pwm_hz: f64,
    sc: &Scenario,
    mut progress: impl FnMut(f64),
    mut sink: impl FnMut(&Row) -> Result<(), String>,
) -> Result<u64, String> {
    let ts = 1.0 / pwm_hz;
    let divider = u64::from(drive.slow_divider());
    let mut sensors =
        Sensors::new(sc.sensors, ts * divider as f64).map_err(|e| format!("encoder model: {e:?}"))?;
    let loaded = match sc.load {
        LoadModel::Torque => *machine,
        LoadModel::EddyBrake { k_nm_s_rad } => machine.with_eddy_brake(k_nm_s_rad),
        LoadModel::LockedRotor | LoadModel::Dynamometer { .. } => machine.speed_locked(),
        LoadModel::CoulombFriction { friction_nm } => machine.with_coulomb_friction(friction_nm),
    };
    // The machine as it is now (a load seizure or a parameter change rebuilds it).
    let mut machine = loaded;
    // Heating windings: the machine on their resistances, rebuilt every
    // `HEATING_UPDATE_S` with the mean copper losses since the last update.
    let mut heating = sc.heating.map(|run| Heated::new(run, ts));
    if let Some(w) = &heating {
        machine = machine.with_electrical(&w.motor).map_err(|e| e.to_string())?;
    }
    let substeps = sc.substeps.max(1);
    let h = ts / f64::from(substeps);
    check_rk4_step(&machine, sc, h)?;
    let mut rk4 = machine.rk4_stepper(h);
    let mut rk4_off = machine.rk4_stepper(ts / f64::from(BRIDGE_OFF_SUBSTEPS));
    let n = (sc.duration_s / ts).round() as u64;
    let trace_every = sc.trace_every.max(1);
    let mut x = MachineState::default();
    if let LoadModel::Dynamometer { omega_m_rad_s } = sc.load {
        x.omega_m_rad_s = omega_m_rad_s;
    }
    let mut load = 0.0;
    // Duties applied during the present period (computed in the previous one). A bridge
    // that is off applies ≈ 0 V in the average model: the same as duties of ½.
    let (mut duty_applied, mut bridge_on, mut brake_applied) = ([0.5; 3], false, false);
    // The legs within the period (a short, the comparator): resolved only when modelled.
    let mut legs = Legs::default();
    let mut legs_modelled = sc.comparator.is_some();
    // A switch stuck open: (phase, upper).
    let mut switch_open: Option<(usize, bool)> = None;
    // Low-side shunts: the highest duty that leaves a phase its sampling window (above 1:
    // none needed), and the duties of the period before the present one (bridge off: none).
    let sensed_duty_max = 1.0 - 2.0 * sc.sensors.low_side_window_s.unwrap_or(0.0) * pwm_hz;
    // The drive's limit is the same number in f32: its rounding is no lost window.
    const DUTY_TOLERANCE: f64 = controller_core::svpwm::WINDOW_ROUNDING_DUTY as f64;
    // A duty that leaves its phase's shunt no window: the sample reads no current there.
    let unreadable = |d: f64| sensed_duty_max < 1.0 && d > sensed_duty_max + DUTY_TOLERANCE;
    let mut duty_before: Option<[f64; 3]> = None;
    let mut events = sc.events.iter().peekable();
    let first_period_of = |e: Option<&&(f64, Event)>| e.map_or(u64::MAX, |(te, _)| first_period_at(*te, ts));
    let mut next_event_k = first_period_of(events.peek());
    let mut rows = 0u64;
    // The largest |i_s|² since the last row ([`Row::i_peak_a`]), and the periods with a phase
    // (two or more) unread ([`Row::unsampled_periods`]).
    let mut unsampled_since_row = [0u32; 2];
    let mut peak2_since_row = 0.0f64;
    // Countdowns instead of `k % m`: the loop body is a few tens of nanoseconds.
    let (mut to_slow, mut to_trace, mut to_progress) = (0, 0, 0);
    // A stiff bus (no DC link model) is measured once, until a bus fault; with a link model
    // the bus follows the link every period, and a bus fault changes the source.
    let mut vdc_v = sc.vdc_v;
    let mut vdc_measured_v = sensors.vdc(vdc_v);
    let mut source_v = sc.vdc_v;
    let mut link_state = LinkState { vdc_v: sc.vdc_v };
    // An open lead's axis: its current is held at zero after every plant step.
    let mut open_phase: Option<(f64, f64)> = None;
    for k in 0..n {
        if k >= next_event_k {
            let t = k as f64 * ts;
            while let Some((_, e)) = events.next_if(|(te, _)| *te <= t) {
                match *e {
                    Event::Enable => drive.enable()?,
                    Event::Reference(r) => drive.set_reference(r)?,
                    Event::Stop => drive.controlled_stop()?,
                    Event::LoadNm(l) => load = l,
                    Event::Coupling(c) => {
                        machine = match c {
                            PassiveLoad::Friction { friction_nm } => {
                                machine.with_coulomb_friction(machine.coulomb_nm() + friction_nm.abs())
                            }
                            PassiveLoad::Fan { k_nm_s2 } => machine.with_fan(k_nm_s2),
                            PassiveLoad::Inertia { j_kgm2 } => machine.with_added_inertia(j_kgm2),
                        };
                        rk4 = machine.rk4_stepper(h);
                        rk4_off = machine.rk4_stepper(ts / f64::from(BRIDGE_OFF_SUBSTEPS));
                    }
                    Event::Fault(Injection::CurrentSensor { phase, gain, offset_a }) => {
                        sensors.fail_current_channel(phase, gain, offset_a);
                    }
                    Event::Fault(Injection::CurrentChannelsSwapped { first, second }) => {
                        sensors.swap_current_channels(first, second)
                    }
                    Event::Fault(Injection::EncoderStuck) => sensors.freeze_encoder(),
                    Event::Fault(Injection::EncoderReversed) => sensors.reverse_encoder(x.theta_m_rad),
                    Event::Fault(Injection::EncoderGlitch { counts }) => sensors.glitch_encoder(counts),
                    Event::Fault(Injection::EncoderLines { lines }) => {
                        sensors.change_encoder_lines(lines, x.theta_m_rad)
                    }
                    Event::Fault(Injection::BusVoltage { vdc_v: v }) => {
                        if sc.dc_link.is_some() {
                            source_v = v;
                        } else {
                            vdc_v = v;
                            vdc_measured_v = sensors.vdc(v);
                        }
                    }
                    Event::Fault(Injection::SwitchOpen { phase, upper }) => {
                        switch_open = Some((phase.min(2), upper));
                    }
                    Event::Fault(Injection::PhaseShort(short)) => {
                        legs.short = Some((short, 0.0));
                        legs_modelled = true;
                    }
                    Event::Fault(Injection::SwitchShort(s)) => {
                        legs.shoot = Some((SwitchShort { phase: s.phase.min(2), ..s }, 0.0));
                        legs_modelled = true;
                    }
                    Event::Fault(Injection::OpenPhase { phase }) => {
                        open_phase = PHASE_AXES.get(phase).copied()
                    }
                    Event::Fault(Injection::LoadStep { torque_nm }) => load = torque_nm,
                    Event::Fault(Injection::LoadSeizure { torque_nm }) => {
                        machine = machine.with_coulomb_friction(torque_nm);
                        rk4 = machine.rk4_stepper(h);
                        rk4_off = machine.rk4_stepper(ts / f64::from(BRIDGE_OFF_SUBSTEPS));
                    }
                    Event::Fault(Injection::Plant { motor }) => {
                        // Checked before the run (`check_rk4_step`); a heating machine's
                        // windings stay as hot as they are.
                        let motor = match heating.as_mut() {
                            Some(w) => w.rebase(&motor),
                            None => motor,
                        };
                        machine = machine.with_electrical(&motor).map_err(|e| e.to_string())?;
                        rk4 = machine.rk4_stepper(h);
                        rk4_off = machine.rk4_stepper(ts / f64::from(BRIDGE_OFF_SUBSTEPS));
                    }
                }
            }
            next_event_k = first_period_of(events.peek());
        }
        // True phase currents (controller-core's inverse Clarke, in f64).
        let i = AlphaBeta { alpha: x.i_alpha_a, beta: x.i_beta_a }.inverse_clarke();
        let i_true = [i.a, i.b, i.c];
        // A phase without a window in the period before the sample or the one after it reads
        // no current.
        let mask =
            |d: &[f64; 3]| d.iter().enumerate().fold(0u8, |m, (k, &x)| m | (u8::from(unreadable(x)) << k));
        let unsampled = if sensed_duty_max < 1.0 {
            duty_before.as_ref().map_or(0, mask) | if bridge_on { mask(&duty_applied) } else { 0 }
        } else {
            0
        };
        match unsampled.count_ones() {
            0 => {}
            1 => unsampled_since_row[0] += 1,
            _ => unsampled_since_row[1] += 1,
        }
        let i_abc =
            sensors.currents_sampled(if legs_modelled { legs.currents(i_true) } else { i_true }, unsampled);
        if legs.broken {
            // The firmware finds the break flag in its next interrupt; the bridge is off.
            drive.hardware_break()?;
            bridge_on = false;
        }
        let enc = if to_slow == 0 {
            to_slow = divider.saturating_sub(1);
            sensors.encoder_read(x.theta_m_rad, x.omega_m_rad_s)
        } else {
            to_slow -= 1;
            sensors.encoder_held()
        };
        let m = Measurements {
            i_abc_a: i_abc,
            vdc_v: vdc_measured_v,
            omega_m_rad_s: enc.omega_m_rad_s,
            theta_m_rad: enc.theta_m_rad,
        };
        // The plant's period k sees the duties decided one period ago (bridge off: all ½,
        // ≈ 0 V); the drive's step k acts in period k + 1. The two do not wait on each other,
        // so with the average inverter the plant's first RK4 stages are issued before the
        // drive's step: the processor then runs both dependent chains side by side.
        let x_at_start = x;
        peak2_since_row = peak2_since_row.max(x.i_alpha_a * x.i_alpha_a + x.i_beta_a * x.i_beta_a);
        let mut switch_acting = false;
        if let Some((p, upper)) = switch_open
            && bridge_on
        {
            // The dead switch's direction of current flows through the opposite diode.
            let before = duty_applied[p];
            match (upper, i_true[p] > 0.0) {
                (true, true) => duty_applied[p] = 0.0,
                (false, false) => duty_applied[p] = 1.0,
                _ => {}
            }
            // It matters where it moves the leg's duty by a share of the period, or where a
            // dead lower switch takes the current from the low-side shunt (it flows through
            // the upper diode): the sensors then read nothing in a phase they could read at
            // the duty the drive asked for (in the next sample's mask).
            let hidden = unreadable(duty_applied[p]) && !unreadable(before);
            switch_acting = (duty_applied[p] - before).abs() >= SWITCH_ACTING_DUTY || hidden;
        }
        let period = match sc.inverter {
            _ if !bridge_on => Period::Off,
            InverterModel::Switching { .. } => Period::Switching(duty_applied),
            InverterModel::Average => {
                let v = InverterModel::average_voltage(duty_applied, vdc_v);
                Period::Average(v, rk4.begin_step(&x, v, load))
            }
        };
        let out = drive.step(&m);
        if let Some(e) = drive.take_failure() {
            return Err(e);
        }
        let v_avg = match period {
            Period::Average(v, midway) => {
                x = midway.finish(&rk4);
                for _ in 1..substeps {
                    x = rk4.step(&x, v, load);
                }
                v
            }
            Period::Off => {
                let (next, v) = integrate_bridge_off(&machine, &rk4_off, &x, vdc_v, load);
                x = next;
                v
            }
            Period::Switching(d) => {
                let segments = sc.inverter.segments(d, i_true, vdc_v, ts);
                x = integrate_segments(&machine, &x, &segments, h, load);
                segments.average()
            }
        };
        if let Some((ux, uy)) = open_phase {
            let along = x.i_alpha_a * ux + x.i_beta_a * uy;
            x.i_alpha_a -= along * ux;
            x.i_beta_a -= along * uy;
        }
        if let Some(w) = heating.as_mut()
            && let Some(motor) = w.period(&x)
        {
            machine = machine.with_electrical(&motor).map_err(|e| e.to_string())?;
            rk4 = machine.rk4_stepper(h);
            rk4_off = machine.rk4_stepper(ts / f64::from(BRIDGE_OFF_SUBSTEPS));
        }
        let mut leg_period = crate::bridge_fault::LegPeriod::default();
        if legs_modelled {
            let end = AlphaBeta { alpha: x.i_alpha_a, beta: x.i_beta_a }.inverse_clarke();
            let pole = bridge_on.then(|| duty_applied.map(|d| (d - 0.5) * vdc_v));
            leg_period = legs.period(sc.comparator.as_ref(), i_true, [end.a, end.b, end.c], pole, vdc_v, ts);
        }
        let vdc_period_v = vdc_v;
        let (mut i_dc, mut i_src, mut i_ch) = (0.0, 0.0, 0.0);
        if let Some(link) = &sc.dc_link {
            i_dc = if bridge_on {
                duty_applied.iter().zip(i_true).map(|(d, i)| d * i).sum()
            } else {
                i_true.iter().map(|i| i.min(0.0)).sum()
            };
            (i_src, i_ch) = link_state.step(link, source_v, i_dc, brake_applied, ts);
            vdc_v = link_state.vdc_v;
            vdc_measured_v = sensors.vdc(vdc_v);
        }
        if to_trace == 0 {
            to_trace = trace_every - 1;
            if !x_at_start.is_finite() {
                return Err(non_finite(k as f64 * ts, &machine));
            }
            rows += 1;
            let telemetry = drive.telemetry();
            sink(&Row {
                t_s: k as f64 * ts,
                x: x_at_start,
                windings: heating.as_ref().map(|w| w.run.windings),
                torque_nm: machine.torque_nm(&x_at_start),
                v_ab_v: v_avg,
                i_ref_ab_a: [f64::from(telemetry.i_ref_ab_a.alpha), f64::from(telemetry.i_ref_ab_a.beta)],
                omega_ref_rad_s: f64::from(telemetry.omega_ref_rad_s),
                i_q_ref_a: f64::from(telemetry.i_q_ref_a),
                load_nm: load,
                mode: Some(out.mode),
                ridden_through: drive.ridden_through(),
                omega_est_rad_s: drive.observed_speed_rad_s().map(f64::from),
                duty: match out.phases {
                    PhaseCommand::Off => None,
                    PhaseCommand::Duty(d) => Some([f64::from(d.a), f64::from(d.b), f64::from(d.c)]),
                },
                vdc_v: vdc_period_v,
                i_dc_a: i_dc,
                i_source_a: i_src,
                i_chopper_a: i_ch,
                brake: out.brake,
                i_leg_peak_a: leg_period.peak_a,
                hw_break: legs.broken,
                i_peak_a: core::mem::take(&mut peak2_since_row).sqrt(),
                unsampled_periods: core::mem::take(&mut unsampled_since_row),
                switch_acting,
                psi_est_wb: f64::from(telemetry.psi_r_wb),
                psi_ref_wb: f64::from(telemetry.psi_ref_wb),
                rr_scale: f64::from(telemetry.rr_scale),
                l_scale: f64::from(telemetry.l_scale),
            })?;
        } else {
            to_trace -= 1;
        }
        // Duties (and the brake) computed now act during the next period.
        duty_before = bridge_on.then_some(duty_applied);
        brake_applied = out.brake;
        (duty_applied, bridge_on) = match out.phases {
            PhaseCommand::Off => ([0.5; 3], false),
            PhaseCommand::Duty(d) => ([f64::from(d.a), f64::from(d.b), f64::from(d.c)], true),
        };
        if to_progress == 0 {
            to_progress = 1999;
            progress(k as f64 / n as f64);
            if drive.finished() {
                break;
            }
        } else {
            to_progress -= 1;
        }
    }
    progress(1.0);
    Ok(rows)
}

/// How often heating windings are stepped and the machine rebuilt on their resistances, s:
/// a thousandth of a second against thermal time constants of minutes.
const HEATING_UPDATE_S: f64 = 1e-3;

/// Heating windings during a run ([`Scenario::heating`]).
struct Heated {
    run: HeatingRun,
    /// The motor at the windings' present temperatures.
    motor: MotorParams,
    /// The copper losses summed over the periods since the last update, W, and their count.
    losses_w: [f64; 2],
    periods: u32,
    /// Periods per update, and the PWM period, s.
    every: u32,
    ts: f64,
}

impl Heated {
    fn new(run: HeatingRun, ts: f64) -> Self {
        let every = (HEATING_UPDATE_S / ts).round().clamp(1.0, 1e6) as u32;
        Self { motor: run.model.motor_at(&run.windings), run, losses_w: [0.0; 2], periods: 0, every, ts }
    }

    /// One PWM period ending in the state `x`: its losses counted; the motor on the new
    /// resistances when the windings were stepped.
    fn period(&mut self, x: &MachineState) -> Option<MotorParams> {
        let [s, r] = Heating::losses_w(&self.motor, x);
        self.losses_w = [self.losses_w[0] + s, self.losses_w[1] + r];
        self.periods += 1;
        if self.periods < self.every {
            return None;
        }
        let n = f64::from(self.periods);
        let mean = self.losses_w.map(|p| p / n);
        self.run.windings = self.run.model.advance(&self.run.windings, mean, n * self.ts);
        (self.losses_w, self.periods) = ([0.0; 2], 0);
        self.motor = self.run.model.motor_at(&self.run.windings);
        Some(self.motor)
    }

    /// The motor stepped to `motor` (stated at the reference temperature): the same windings
    /// on its resistances.
    fn rebase(&mut self, motor: &MotorParams) -> MotorParams {
        self.run.model = self.run.model.with_motor(motor);
        self.motor = self.run.model.motor_at(&self.run.windings);
        self.motor
    }
}

/// [`run`] keeping every row in memory (tests, short runs).
pub fn run_collect(
    drive: &mut impl DriveUnderTest,
    machine: &Machine,
    pwm_hz: f64,
    sc: &Scenario,
    progress: impl FnMut(f64),
) -> Result<Vec<Row>, String> {
    let mut rows = Vec::new();
    run(drive, machine, pwm_hz, sc, progress, |r| {
        rows.push(*r);
        Ok(())
    })?;
    Ok(rows)
}

/// The first period k whose start `k·ts_s` is at or after `t_s` (the same floating-point
/// comparison the event loop makes); `u64::MAX` when there is none in range. Lets [`run`]
/// compare period indices instead of converting every k to a time.
pub(crate) fn first_period_at(t_s: f64, ts_s: f64) -> u64 {
    let at = |k: u64| k as f64 * ts_s;
    let periods = t_s / ts_s;
    if periods.is_nan() || periods >= 1e15 {
        return u64::MAX;
    }
    // The quotient is within a few units of the answer; settle it with the comparison itself.
    let mut k = periods.floor().max(0.0) as u64;
    while k > 0 && at(k - 1) >= t_s {
        k -= 1;
    }
    while at(k) < t_s {
        k += 1;
    }
    k
}

#[cfg(test)]
mod tests {
    use super::*;
    use controller_core::drive::{Drive, FastOutput, Reference, Telemetry};

    /// `first_period_at` is the smallest k with `k·ts ≥ t` in floating point — checked against
    /// that definition by search, at event times on, just beside and between period starts.
    #[test]
    fn first_period_at_matches_the_event_comparison() {
        let ts = 1.0 / 20_000.0;
        let brute = |t: f64| (0u64..).find(|&k| k as f64 * ts >= t).unwrap();
        let mut times = vec![0.0, -1.0, 0.3, 1.5, 2.5, 3.5, 1e-9, ts, 2.0 * ts];
        for k in [1u64, 7, 6000, 29_999, 30_000, 70_000] {
            let t = k as f64 * ts;
            times.extend([t, t.next_up(), t.next_down(), t + 0.5 * ts]);
        }
        for t in times {
            assert_eq!(first_period_at(t, ts), brute(t), "t = {t:e}");
        }
        assert_eq!(first_period_at(f64::INFINITY, ts), u64::MAX);
        assert_eq!(first_period_at(f64::NAN, ts), u64::MAX);
    }

    /// The in-process drive, whose link breaks at its `fail_at`-th step (a PIL target dying).
    struct Breaks {
        drive: Drive,
        steps: u64,
        fail_at: u64,
        failure: Option<String>,
    }

    impl DriveUnderTest for Breaks {
        fn slow_divider(&self) -> u16 {
            self.drive.slow_divider()
        }
        fn enable(&mut self) -> Result<(), String> {
            DriveUnderTest::enable(&mut self.drive)
        }
        fn set_reference(&mut self, r: Reference) -> Result<(), String> {
            DriveUnderTest::set_reference(&mut self.drive, r)
        }
        fn controlled_stop(&mut self) -> Result<(), String> {
            DriveUnderTest::controlled_stop(&mut self.drive)
        }
        fn step(&mut self, m: &Measurements) -> FastOutput {
            self.steps += 1;
            let out = DriveUnderTest::step(&mut self.drive, m);
            if self.steps == self.fail_at {
                self.failure = Some(format!("link broken at step {}", self.steps));
            }
            out
        }
        fn telemetry(&self) -> Telemetry {
            self.drive.telemetry()
        }
        fn take_failure(&mut self) -> Option<String> {
            self.failure.take()
        }
    }

    /// A failed step ends the run with its error at that step: no further step, no trace.
    #[test]
    fn failed_step_stops_the_run() {
        let b = crate::scenario::speed_step().unwrap();
        let drive = Drive::new(controller_core::drive::DriveConfig::new(&b.spec).unwrap());
        let mut dut = Breaks { drive, steps: 0, fail_at: 1000, failure: None };
        let r = run_collect(&mut dut, &Machine::new(&b.plant), b.spec.pwm_frequency_hz, &b.scenario, |_| {});
        assert_eq!(r, Err("link broken at step 1000".to_string()));
        assert_eq!(dut.steps, 1000);
    }
}
