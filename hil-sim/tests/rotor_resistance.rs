//! The rotor-resistance estimate (`controller_core::mras`) in software in the loop: the fit
//! while magnetizing, and the reactive-power adaptation following a rotor that heats up.
#![allow(clippy::unwrap_used, clippy::indexing_slicing)]

use controller_core::drive::{DriveSpec, Mode, Reference};
use controller_core::motor::MotorParams;
use hil_sim::inverter::InverterModel;
use hil_sim::scenario::Builtin;
use hil_sim::sensors::SensorModel;
use hil_sim::sim::{Event, Injection, LoadModel, Row, Scenario, scaled_plant};

fn shipped() -> DriveSpec {
    drive_file::DriveFile::shipped().unwrap().spec
}

/// The shipped motor with its resistances scaled: `rs`×R_s, `rr`×R_r.
fn motor(spec: &DriveSpec, rs: f64, rr: f64) -> MotorParams {
    scaled_plant(&spec.motor, rs, rr, 1.0).unwrap()
}

fn run(
    spec: DriveSpec,
    plant: MotorParams,
    events: Vec<(f64, Event)>,
    duration_s: f64,
    seed: u64,
) -> Vec<Row> {
    let b = Builtin {
        name: "rotor-resistance".into(),
        about: String::new(),
        spec,
        plant,
        scenario: Scenario {
            events,
            duration_s,
            vdc_v: 310.0,
            substeps: 1,
            trace_every: 10,
            sensors: SensorModel::realistic_for_trip(seed, spec.protection.i_trip_a),
            load: LoadModel::Torque,
            inverter: InverterModel::Average,
            dc_link: None,
            comparator: None,
        },
    };
    let (rows, mode) = b.run(|_| {}).unwrap();
    assert_eq!(mode, Mode::Running, "the drive ends running");
    rows
}

/// At rest, the three-window fit of the magnetizing d-axis voltage gives the rotor
/// resistance without the stator's: with realistic sensors (12-bit currents with offset,
/// gain error and noise; four noise seeds each), cold and hot rotors, cold and hot stators,
/// the estimate when the drive starts running is within 6 % of the truth, 3 % on average
/// (measured: 2.7 % and 0.9 %) — the detuning left for the online law. (Before the fit the drive ran on the range's middle, √2: up to 41 % off.)
#[test]
fn magnetizing_measures_the_rotor_resistance() {
    let spec = shipped();
    let (mut worst, mut sum, mut n) = (0.0f64, 0.0f64, 0.0f64);
    for (rs, rr) in [(1.0, 1.0), (1.5, 1.0), (1.0, 1.5), (1.5, 1.5), (1.0, 2.0), (1.5, 2.0)] {
        for seed in 0..4 {
            let rows = run(spec, motor(&spec, rs, rr), vec![(0.0, Event::Enable)], 0.3, 11 + seed);
            let first = rows.iter().find(|r| r.mode == Some(Mode::Running)).unwrap();
            let err = first.rr_scale / rr - 1.0;
            eprintln!(
                "R_s ×{rs}, R_r ×{rr}, seed {seed}: estimate ×{:.4}, running from {:.3} s ({:+.2} %)",
                first.rr_scale,
                first.t_s,
                100.0 * err
            );
            worst = worst.max(err.abs());
            sum += err.abs();
            n += 1.0;
        }
    }
    eprintln!("worst {:.2} %, mean |error| {:.2} %", 100.0 * worst, 100.0 * sum / n);
    assert!(worst <= 0.06 && sum / n <= 0.03, "worst {:.2} %, mean {:.2} %", 100.0 * worst, 100.0 * sum / n);
}

/// A rotor heating up mid-run (its resistance stepping ×1.5 at speed under load, faster than
/// any real rotor heats): the reactive-power law brings the estimate within 5 % of the new
/// value within 0.5 s, and the machine's flux back within 5 % of the drive's model —
/// without the adaptation (`rotor_resistance_range = [1, 1]`) the flux settles 32 % above it.
#[test]
fn the_online_law_follows_a_heating_rotor() {
    let spec = shipped();
    let cold = motor(&spec, 1.0, 1.0);
    let hot = motor(&spec, 1.0, 1.5);
    let events = vec![
        (0.0, Event::Enable),
        (0.3, Event::Reference(Reference::Speed(100.0))),
        (0.6, Event::LoadNm(1.6)),
        (1.0, Event::Fault(Injection::Plant { motor: hot })),
    ];
    let flux_ratio = |r: &Row| r.x.psi_alpha_wb.hypot(r.x.psi_beta_wb) / r.psi_est_wb;
    let adapted = run(spec, cold, events.clone(), 2.0, 5);
    let before = adapted.iter().rfind(|r| r.t_s < 1.0).unwrap();
    assert!((before.rr_scale - 1.0).abs() <= 0.05, "cold estimate {:.4}", before.rr_scale);
    let after = adapted.iter().find(|r| r.t_s >= 1.5).unwrap();
    let end = adapted.last().unwrap();
    eprintln!(
        "adapted: estimate ×{:.4} before, ×{:.4} 0.5 s after, ×{:.4} at {:.1} s; flux/model {:.3} at the end",
        before.rr_scale,
        after.rr_scale,
        end.rr_scale,
        end.t_s,
        flux_ratio(end)
    );
    assert!(
        (after.rr_scale / 1.5 - 1.0).abs() <= 0.05,
        "estimate 0.5 s after the step: {:.4}",
        after.rr_scale
    );
    assert!((flux_ratio(end) - 1.0).abs() <= 0.05, "flux/model {:.3}", flux_ratio(end));
    let fixed = DriveSpec { rotor_resistance_range: [1.0, 1.0], ..spec };
    let rows = run(fixed, cold, events, 2.0, 5);
    let end = rows.last().unwrap();
    eprintln!("fixed: flux/model {:.3} at the end", flux_ratio(end));
    assert!(
        flux_ratio(end) > 1.15,
        "without adaptation the hot rotor's flux runs high: {:.3}",
        flux_ratio(end)
    );
}
