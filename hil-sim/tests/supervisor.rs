//! The supervisor against the faults found by trying (issue 18), on the nonlinear machine with
//! the shipped drive: each ends in its own named fault, within a bounded time.
//!
//! Detection times are bracketed by two runs of the same scenario cut at different lengths:
//! the fault must be latched at the end of the longer one and not yet at the end of the
//! shorter one (so a trip at the first step, for a wrong reason, fails too).
#![allow(clippy::unwrap_used, clippy::indexing_slicing)]

use controller_core::drive::{Fault, Mode};
use hil_sim::scenario::{Builtin, speed_step};
use hil_sim::sim::{Event, Injection, LoadModel};

fn mode_after(b: &Builtin, duration_s: f64) -> (Mode, f64) {
    let mut b = b.clone();
    b.scenario.duration_s = duration_s;
    let (rows, mode) = b.run(|_| {}).unwrap();
    let peak = rows.iter().map(|r| r.x.omega_m_rad_s.abs()).fold(0.0, f64::max);
    (mode, peak)
}

/// A locked rotor under a speed command: `Stall` the stall time after the command (the
/// speed step at 0.3 s saturates the torque at once; the derived stall time, 0.152 s
/// shipped: `drive::default_stall_time_s`), within a slow period and the speed estimate's
/// settling — well inside issue 18's 0.5 s.
#[test]
fn locked_rotor_under_a_speed_command_is_a_stall() {
    let mut b = speed_step().unwrap();
    b.scenario.load = LoadModel::LockedRotor;
    b.scenario.events.retain(|(_, e)| !matches!(e, Event::LoadNm(_)));
    let stall_s = b.spec.protection.stall_time_s;
    assert!((0.1..0.2).contains(&stall_s), "{stall_s}");
    assert_eq!(mode_after(&b, 0.3 + stall_s - 0.005).0, Mode::Running, "no trip before the stall time");
    assert_eq!(mode_after(&b, 0.3 + stall_s + 0.005).0, Mode::Fault(Fault::Stall));
}

/// A 20 N·m load step (ten times the torque limit) at 150 rad/s drove the motor to
/// −6 974 rad/s while the drive reported Running. Now it ends in a named fault: the load
/// drags the motor at 3 600 rad/s² against the drive's 2 N·m, and the following check names
/// it `FollowingError` while it drags — beyond what the window owes plus a whole window's
/// owing at τ_max (0.096 s derived from the mechanics: 3.8 rad/s), a few milliseconds in,
/// the rotor still turning forwards. (Before issue 49's drag test it waited for the window's
/// end, near −235 rad/s.) With the following check's window out of reach and the overspeed
/// level at 200 rad/s, `Overspeed` is latched within one slow period (0.5 ms) of the speed
/// crossing it. (The load is active: with the bridge off it keeps accelerating the motor —
/// what the mechanics do then is the load's.)
#[test]
fn a_load_the_drive_cannot_hold_ends_in_a_named_fault() {
    let mut b = speed_step().unwrap();
    let mut step_s = f64::NAN;
    for (t, e) in &mut b.scenario.events {
        if let Event::LoadNm(l) = e
            && *l > 0.0
        {
            *l = 20.0;
            step_s = *t;
        }
    }
    b.scenario.events.retain(|(t, _)| *t < 2.0);
    b.scenario.trace_every = 1;
    let (rows, mode) = b.run(|_| {}).unwrap();
    assert_eq!(mode, Mode::Fault(Fault::FollowingError));
    let tripped = rows.iter().position(|r| r.mode == Some(Mode::Fault(Fault::FollowingError))).unwrap();
    let (at_trip, t_trip) = (rows[tripped].x.omega_m_rad_s, rows[tripped].t_s);
    eprintln!("FollowingError {:.1} ms after the load, at {at_trip:.1} rad/s", 1e3 * (t_trip - step_s));
    // The P law saturates 40 rad/s below its reference (τ_max/k_p = 2/0.05): 11 ms at
    // 3 600 rad/s²; then 3.8 rad/s of margin (≈ 1 ms) and a slow period (0.5 ms).
    assert!(t_trip - step_s < 0.015, "{t_trip} s");
    assert!(at_trip > 100.0, "{at_trip} rad/s");
    b.spec.protection.following_time_s = 100.0;
    b.spec.protection.overspeed_rad_s = 200.0;
    let (rows, mode) = b.run(|_| {}).unwrap();
    assert_eq!(mode, Mode::Fault(Fault::Overspeed));
    let cross = rows.iter().find(|r| r.x.omega_m_rad_s.abs() > 200.0).unwrap().t_s;
    assert_eq!(mode_after(&b, cross - 1e-4).0, Mode::Running, "tripped before crossing");
    assert_eq!(mode_after(&b, cross + 5e-4 + 1e-4).0, Mode::Fault(Fault::Overspeed));
}

/// A load beyond the torque limit that the drive cannot hold but that does not lock the
/// rotor (3 N·m against the shipped 2 N·m at 150 rad/s): the speed loop saturates, the motor
/// decelerates at 200 rad/s², reverses and would run away backwards to the overspeed level
/// (≈ 4 s). The following-error check names it instead, a window (0.096 s) after the speed loop
/// saturates (the saturated-P law at 40 rad/s of error, ≈ 60 ms after the step): within
/// issue 18's 0.5 s for a stall, not before the window, and not as `Stall` (the rotor
/// crosses zero without stopping).
#[test]
fn a_load_beyond_the_drive_is_a_following_error() {
    let mut b = speed_step().unwrap();
    for (_, e) in &mut b.scenario.events {
        if let Event::LoadNm(l) = e
            && *l > 0.0
        {
            *l = 3.0;
        }
    }
    let window = b.spec.protection.following_time_s;
    assert_eq!(mode_after(&b, 1.5 + window).0, Mode::Running, "no trip before the window");
    let (mode, peak) = mode_after(&b, 1.5 + 0.5);
    assert_eq!(mode, Mode::Fault(Fault::FollowingError));
    assert!(peak < 155.0, "{peak}");
}

/// All three current sensors reading zero (gain 0) from the start: the true current flows
/// but nothing is measured. The flux model would declare the motor magnetized after
/// ≈ 0.19 s; instead the open-phase check's first window (2.5 ms) finds every commanded
/// phase without current: `NoMotorCurrent` (before this check: `LossOfControl` after the
/// 20 ms saturation time; the magnetizing timeout is the last line: controller-core's unit
/// tests).
#[test]
fn dead_current_sensors_never_reach_running() {
    let mut b = speed_step().unwrap();
    b.scenario.sensors.current_gain = [0.0; 3];
    assert_eq!(mode_after(&b, 0.002).0, Mode::Magnetizing);
    assert_eq!(mode_after(&b, 0.006).0, Mode::Fault(Fault::NoMotorCurrent));
}

/// A dead phase-a sensor: the three measured currents no longer sum to zero. At standstill
/// the field is on phase a, whose magnetizing current (ψ_r*/L_m = 0.63 A) is above the
/// 0.4 A plausibility level: `CurrentSensor` within 10 ms of enable.
#[test]
fn a_dead_phase_sensor_is_a_current_sensor_fault() {
    let mut b = speed_step().unwrap();
    b.scenario.sensors.current_gain = [0.0, 1.0, 1.0];
    assert_eq!(mode_after(&b, 0.01).0, Mode::Fault(Fault::CurrentSensor));
    // And not with healthy sensors, noise and errors included (speed-step-sensors runs the
    // whole scenario Running: tests/speed_step.rs).
}

/// `speed_step` with `injection` at 1.0 s (steady 148.5 rad/s, no load yet).
fn injected(injection: Injection) -> Builtin {
    let mut b = speed_step().unwrap();
    b.scenario.events.push((1.0, Event::Fault(injection)));
    b.scenario.events.sort_by(|x, y| x.0.total_cmp(&y.0));
    b
}

/// A phase-b current sensor that dies while running: `CurrentSensor` within 10 ms (the
/// sum −i_b passes the 0.4 A level within ≈ 4.4 ms of any instant for a 0.65 A phase
/// current).
#[test]
fn a_sensor_dying_mid_run_is_caught_within_10_ms() {
    let b = injected(Injection::CurrentSensor { phase: 1, gain: 0.0, offset_a: 0.0 });
    assert_eq!(mode_after(&b, 0.999).0, Mode::Running);
    assert_eq!(mode_after(&b, 1.010).0, Mode::Fault(Fault::CurrentSensor));
    // An offset drift of 0.5 A: at once.
    let b = injected(Injection::CurrentSensor { phase: 0, gain: 1.0, offset_a: 0.5 });
    assert_eq!(mode_after(&b, 1.001).0, Mode::Fault(Fault::CurrentSensor));
}

/// Bus sag below `vdc_min_v` and surge above `vdc_max_v`: tripped in the next PWM period.
#[test]
fn bus_sag_and_surge() {
    let b = injected(Injection::BusVoltage { vdc_v: 150.0 });
    assert_eq!(mode_after(&b, 0.999).0, Mode::Running);
    assert_eq!(mode_after(&b, 1.0002).0, Mode::Fault(Fault::DcBusUndervoltage));
    let b = injected(Injection::BusVoltage { vdc_v: 450.0 });
    assert_eq!(mode_after(&b, 1.0002).0, Mode::Fault(Fault::DcBusOvervoltage));
}

/// The load seizes at speed: a 20 N·m friction (ten times the drive's torque limit) stops
/// the rotor from 148.5 rad/s in ≈ 40 ms and holds it. The following check names it while
/// it decelerates (a drag beyond a window's owing, once the P law has saturated 40 rad/s
/// below its reference: `FollowingError` within 15 ms); without
/// that check (its window out of reach), the speed loop saturates at rest, so `Stall` after
/// the stall time at rest (0.152 s), not before — and never `EncoderLoss`: the deceleration
/// (≈ 3 600 rad/s²) is within what the jump check allows.
#[test]
fn load_seizure_is_named_while_it_drags_else_a_stall() {
    let mut b = injected(Injection::LoadSeizure { torque_nm: 20.0 });
    assert_eq!(mode_after(&b, 0.999).0, Mode::Running);
    assert_eq!(mode_after(&b, 1.015).0, Mode::Fault(Fault::FollowingError));
    b.spec.protection.following_time_s = 100.0;
    let stall_s = b.spec.protection.stall_time_s;
    assert_eq!(mode_after(&b, 1.0 + stall_s).0, Mode::Running);
    assert_eq!(mode_after(&b, 1.1 + stall_s).0, Mode::Fault(Fault::Stall));
}

/// All three current sensors stuck at zero while running (the sum stays zero, so the
/// current-sum check cannot see it): within two open-phase windows (5 ms) every commanded
/// phase is found without current — `NoMotorCurrent`, inside issue 18's 10 ms for sensor
/// faults (before the open-phase check: `LossOfControl` after 15–25 ms).
#[test]
fn all_sensors_stuck_at_zero_is_no_motor_current() {
    let mut b = speed_step().unwrap();
    for phase in 0..3 {
        b.scenario
            .events
            .push((1.0, Event::Fault(Injection::CurrentSensor { phase, gain: 0.0, offset_a: 0.0 })));
    }
    b.scenario.events.sort_by(|x, y| x.0.total_cmp(&y.0));
    assert_eq!(mode_after(&b, 0.9999).0, Mode::Running);
    assert_eq!(mode_after(&b, 1.005).0, Mode::Fault(Fault::NoMotorCurrent));
}

/// Issue 18: no false trip in a 60 s run with realistic sensors (12-bit ADC with offset, gain
/// error and noise, 1024-line encoder): speed steps both ways, a reversal, load steps.
#[test]
fn no_false_trip_in_a_minute_with_realistic_sensors() {
    use controller_core::drive::Reference;
    let mut b = hil_sim::scenario::speed_step_sensors().unwrap();
    b.scenario.duration_s = 60.0;
    b.scenario.trace_every = 2000;
    b.scenario.events = vec![
        (0.0, Event::Enable),
        (0.3, Event::Reference(Reference::Speed(150.0))),
        (10.0, Event::LoadNm(1.0)),
        (20.0, Event::LoadNm(0.0)),
        (25.0, Event::Reference(Reference::Speed(-150.0))),
        (40.0, Event::Reference(Reference::Speed(20.0))),
        (50.0, Event::Reference(Reference::Position(100.0))),
    ];
    let (_, mode) = b.run(|_| {}).unwrap();
    assert_eq!(mode, Mode::Running);
}

/// A frozen encoder at speed (148.5 rad/s, 49 counts per read): the first read after the
/// freeze changes by 0 where the last changed by 49 counts — `EncoderLoss` within two slow
/// periods (issue 18's bound for encoder faults), with the 1024-line model and with the
/// exact encoder (before the jump check: `Stall` after 0.3 s).
#[test]
fn a_frozen_encoder_at_speed_is_an_encoder_loss() {
    for lines in [None, Some(1024)] {
        let mut b = speed_step().unwrap();
        b.scenario.sensors.encoder_lines = lines;
        b.scenario.events.retain(|(t, _)| *t < 1.0);
        b.scenario.events.push((1.0, Event::Fault(Injection::EncoderStuck)));
        assert_eq!(mode_after(&b, 1.0).0, Mode::Running, "{lines:?}");
        assert_eq!(mode_after(&b, 1.0 + 2.0 * 5e-4 + 1e-4).0, Mode::Fault(Fault::EncoderLoss), "{lines:?}");
    }
}

/// A glitch of 100 spurious counts (at speed and at standstill): `EncoderLoss` at the next
/// read (within two slow periods); a glitch of 2 counts (edge chatter) passes.
#[test]
fn an_encoder_glitch_is_an_encoder_loss() {
    for w in [150.0, 0.0] {
        let mut b = speed_step().unwrap();
        b.scenario.sensors = hil_sim::sensors::SensorModel::realistic(3);
        b.scenario.events = vec![
            (0.0, Event::Enable),
            (0.3, Event::Reference(controller_core::drive::Reference::Speed(w))),
            (1.0, Event::Fault(Injection::EncoderGlitch { counts: 100 })),
        ];
        assert_eq!(mode_after(&b, 1.0).0, Mode::Running, "{w}");
        assert_eq!(mode_after(&b, 1.0 + 2.0 * 5e-4 + 1e-4).0, Mode::Fault(Fault::EncoderLoss), "{w}");
        b.scenario.events[2].1 = Event::Fault(Injection::EncoderGlitch { counts: 2 });
        assert_eq!(mode_after(&b, 1.2).0, Mode::Running, "{w}");
    }
}

/// An open lead (issue 18: "open phase: 50 ms"): each phase opened at standstill (held at
/// 0 rad/s under ±0.5 N·m of load: both torque signs) and at 150 rad/s (motoring and
/// generating), with realistic sensors — `OpenPhase` every time, within 20 ms (the test
/// prints the slowest), never another fault first. Before this check the same runs ended in
/// `EncoderImplausible` after 10–50 ms.
#[test]
fn an_open_phase_is_caught_by_name() {
    let mut slowest: f64 = 0.0;
    for (w, load) in [(0.0, 0.5), (0.0, -0.5), (150.0, 0.5), (150.0, -0.5)] {
        for phase in 0..3 {
            let mut b = speed_step().unwrap();
            b.scenario.sensors = hil_sim::sensors::SensorModel::realistic(7 + phase as u64);
            b.scenario.events = vec![
                (0.0, Event::Enable),
                (0.3, Event::Reference(controller_core::drive::Reference::Speed(w))),
                (0.4, Event::LoadNm(load)),
                (1.2, Event::Fault(Injection::OpenPhase { phase })),
            ];
            b.scenario.trace_every = 1;
            b.scenario.duration_s = 1.3;
            let (rows, mode) = b.run(|_| {}).unwrap();
            let first = rows.iter().find(|r| matches!(r.mode, Some(Mode::Fault(_)))).unwrap();
            let dt = first.t_s - 1.2;
            assert_eq!(mode, Mode::Fault(Fault::OpenPhase), "ω {w} load {load} phase {phase}");
            assert!(dt > 0.0 && dt <= 0.02, "ω {w} load {load} phase {phase}: {dt} s");
            slowest = slowest.max(dt);
        }
    }
    eprintln!("open phase: caught within {:.2} ms at worst", 1e3 * slowest);
}

/// The motor's I²t limit (the shipped motor data with the time constant shortened to 20 s):
/// at 150 rad/s under a 1.9 N·m load (above the 0.88 A × 1.15 the limit allows for ever) the
/// model trips when `τ·ln(x/(x − 1.15²))` says for the run's mean x = (I_rms/I_rated)², to
/// within an update period (0.5 s) and 2 %; the reaction is the shipped one, a controlled
/// stop: the fault latches once the motor is at rest, not at the trip.
#[test]
fn a_motor_overload_stops_the_motor_then_latches() {
    let mut b = speed_step().unwrap();
    let mut thermal = b.spec.protection.motor_thermal.unwrap();
    thermal.time_constant_s = 20.0;
    b.spec.protection.motor_thermal = Some(thermal);
    b.scenario.events = vec![
        (0.0, Event::Enable),
        (0.3, Event::Reference(controller_core::drive::Reference::Speed(150.0))),
        (0.8, Event::LoadNm(1.9)),
    ];
    b.scenario.duration_s = 60.0;
    b.scenario.trace_every = 100;
    let (rows, mode) = b.run(|_| {}).unwrap();
    assert_eq!(mode, Mode::Fault(Fault::MotorOverload));
    let latched = rows.iter().position(|r| r.mode == Some(Mode::Fault(Fault::MotorOverload))).unwrap();
    // Where the stop began: the speed reference dropped to 0 while Running.
    let stop = rows.iter().position(|r| r.t_s > 1.0 && r.omega_ref_rad_s == 0.0).unwrap();
    assert!(stop < latched);
    assert!(
        rows[latched].x.omega_m_rad_s.abs() < 3.1,
        "at rest when latched: {}",
        rows[latched].x.omega_m_rad_s
    );
    let i2 = |r: &hil_sim::sim::Row| 0.5 * (r.x.i_alpha_a.powi(2) + r.x.i_beta_a.powi(2));
    let x = rows[..stop].iter().map(i2).sum::<f64>() / stop as f64 / (thermal.rated_current_a.powi(2));
    let predicted = 20.0 * (x / (x - thermal.overload_factor.powi(2))).ln();
    let t = rows[stop].t_s;
    eprintln!(
        "x = {x:.3} (I_rms/I_rated)², trip after {t:.2} s, predicted {predicted:.2} s; latched at {:.2} s",
        rows[latched].t_s
    );
    assert!((t - predicted).abs() <= 0.5 + 0.02 * predicted, "{t} vs {predicted}");
}
