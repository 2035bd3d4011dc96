//! The controlled stop (`Drive::controlled_stop`, link `Stop`, scenario event `stop`; the
//! firmware's link watchdog issues it): the speed loop brakes to standstill, then the bridge
//! goes off; a stop that cannot finish (a load driving the motor) ends with the bridge off
//! after `protection.stop_time_s`.
#![allow(clippy::unwrap_used, clippy::indexing_slicing)]

use controller_core::drive::{Fault, Mode, Reference};
use hil_sim::sim::Event;

/// From 148 rad/s: braked at the torque limit (the shipped drive's 2 N·m on J = 0.005:
/// 400 rad/s², ≈ 0.37 s), the bridge off (Idle, no fault) within a slow period of the speed
/// falling below the stall check's "not moving" level (0.5 % of the overspeed level).
#[test]
fn a_controlled_stop_brakes_to_rest_then_turns_the_bridge_off() {
    let mut b = hil_sim::scenario::speed_step().unwrap();
    b.scenario.events =
        vec![(0.0, Event::Enable), (0.3, Event::Reference(Reference::Speed(150.0))), (1.2, Event::Stop)];
    b.scenario.duration_s = 2.0;
    b.scenario.trace_every = 1;
    let (rows, mode) = b.run(|_| {}).unwrap();
    assert_eq!(mode, Mode::Idle);
    assert!(rows.iter().all(|r| !matches!(r.mode, Some(Mode::Fault(_)))));
    let off = rows.iter().find(|r| r.t_s > 1.2 && r.mode == Some(Mode::Idle)).unwrap();
    let level = controller_core::drive::STALL_SPEED_FRACTION * b.spec.protection.overspeed_rad_s;
    let w_at_stop = rows.iter().find(|r| r.t_s >= 1.2).unwrap().x.omega_m_rad_s;
    let min_torque =
        rows.iter().filter(|r| r.t_s > 1.2 && r.t_s < off.t_s).map(|r| r.torque_nm).fold(0.0, f64::min);
    eprintln!(
        "stop from {w_at_stop:.1} rad/s: bridge off after {:.3} s at {:.2} rad/s (level {level:.2}), braking torque down to {min_torque:.2} N·m",
        off.t_s - 1.2,
        off.x.omega_m_rad_s
    );
    assert!(off.x.omega_m_rad_s.abs() < level + 0.2, "{}", off.x.omega_m_rad_s);
    assert!(off.t_s - 1.2 < 0.6, "{}", off.t_s);
    assert!(min_torque < -1.9, "braked at the torque limit: {min_torque}");
    // Off means off: no more duties after it.
    assert!(rows.iter().filter(|r| r.t_s >= off.t_s).all(|r| r.duty.is_none()));
}

/// A load of 1.9 N·m drives the motor, all but the drive's 2 N·m: the brake slows it at
/// 20 rad/s² only, the stop cannot finish, and the bridge goes off at `stop_time_s` (0.5 s
/// here), within a slow period. A load beyond the brake (3 N·m) drags the motor against it:
/// `FollowingError` latched before the stop time, the bridge off.
#[test]
fn a_stop_that_cannot_finish_ends_with_the_bridge_off_after_stop_time() {
    let run = |load_nm: f64| {
        let mut b = hil_sim::scenario::speed_step().unwrap();
        b.spec.protection.stop_time_s = 0.5;
        b.scenario.events = vec![
            (0.0, Event::Enable),
            (0.3, Event::Reference(Reference::Speed(50.0))),
            (1.0, Event::LoadNm(-load_nm)),
            (1.0, Event::Stop),
        ];
        b.scenario.duration_s = 1.8;
        b.scenario.trace_every = 1;
        let (rows, mode) = b.run(|_| {}).unwrap();
        (b, rows, mode)
    };
    let (b, rows, mode) = run(1.9);
    assert_eq!(mode, Mode::Idle);
    let off = rows.iter().find(|r| r.t_s > 1.0 && r.mode == Some(Mode::Idle)).unwrap();
    let slow = f64::from(b.spec.slow_divider) / b.spec.pwm_frequency_hz;
    eprintln!(
        "stop against a driving load: bridge off after {:.4} s at {:.1} rad/s",
        off.t_s - 1.0,
        off.x.omega_m_rad_s
    );
    assert!((off.t_s - 1.0 - 0.5).abs() <= 2.0 * slow, "{}", off.t_s);
    assert!(off.x.omega_m_rad_s > 30.0, "still driven: {}", off.x.omega_m_rad_s);
    let (_, rows, mode) = run(3.0);
    assert_eq!(mode, Mode::Fault(Fault::FollowingError));
    let tripped = rows.iter().find(|r| matches!(r.mode, Some(Mode::Fault(_)))).unwrap();
    assert!(tripped.t_s - 1.0 < 0.5, "{}", tripped.t_s);
}
