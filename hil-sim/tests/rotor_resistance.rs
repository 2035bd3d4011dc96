//! The rotor-resistance estimate (`controller_core::mras`) in software in the loop: the fit
//! while magnetizing, and the reactive-power adaptation following a rotor that heats up.
#![allow(clippy::unwrap_used, clippy::indexing_slicing, clippy::panic)]

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

/// A run of `spec` on `plant` at 310 V with realistic sensors (noise seed `seed`), an active
/// load, the average inverter; a test changes what it needs.
fn builtin(
    spec: DriveSpec,
    plant: MotorParams,
    events: Vec<(f64, Event)>,
    duration_s: f64,
    seed: u64,
) -> Builtin {
    Builtin {
        name: "rotor-resistance".into(),
        about: String::new(),
        spec,
        plant,
        plant_saturation: None,
        expect_fault: None,
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
            heating: None,
            extras: plant::Extras::default(),
        },
    }
}

fn run(
    spec: DriveSpec,
    plant: MotorParams,
    events: Vec<(f64, Event)>,
    duration_s: f64,
    seed: u64,
) -> Vec<Row> {
    let (rows, mode) = builtin(spec, plant, events, duration_s, seed).run(|_| {}).unwrap();
    assert_eq!(mode, Mode::Running, "the drive ends running");
    rows
}

/// The shipped motor with its resistances and inductances scaled — `rs`×R_s, `rr`×R_r, and
/// `l`× L_s, L_r, L_m alike (the campaign's box).
fn box_motor(spec: &DriveSpec, rs: f64, rr: f64, l: f64) -> MotorParams {
    spec.motor.scaled(rs, rr, l, 1.0).unwrap()
}

/// At rest, the magnetizing fit gives the rotor resistance without the stator's, and the
/// inductances from the flux linkage the enable builds: with realistic sensors (12-bit
/// currents with offset, gain error and noise; two noise seeds each) over the shipped
/// box's corners — cold and hot rotors and stators, unsaturated and saturated (L ×0.6) —
/// the estimates when the drive starts running are within 6 % of the truth, 3 % on
/// average (the figures it prints are in docs/rotor-resistance.md); the flux the drive
/// then runs on is the machine's, within the same. (Before the fit the drive ran on the
/// range's middle, √2: up to 41 % off; before the inductance was measured, a machine at
/// L ×0.6 ran on 60 % of its flux.)
#[test]
fn magnetizing_measures_the_rotor_resistance_and_the_inductance() {
    let spec = shipped();
    let mut worst = [0.0f64; 3];
    let (mut sum, mut n) = ([0.0f64; 3], 0.0f64);
    for l in [1.0, 0.8, 0.6] {
        for (rs, rr) in [(1.0, 1.0), (1.5, 1.0), (1.0, 2.0), (1.5, 2.0)] {
            for seed in 0..2 {
                let rows = run(spec, box_motor(&spec, rs, rr, l), vec![(0.0, Event::Enable)], 0.6, 11 + seed);
                let first = rows.iter().find(|r| r.mode == Some(Mode::Running)).unwrap();
                let last = rows.last().unwrap();
                let flux = last.x.psi_alpha_wb.hypot(last.x.psi_beta_wb) / spec.flux_ref_wb - 1.0;
                let err = [first.rr_scale / rr - 1.0, first.l_scale / l - 1.0, flux];
                eprintln!(
                    "L ×{l}, R_s ×{rs}, R_r ×{rr}, seed {seed}: R_r ×{:.4} ({:+.2} %), L ×{:.4} ({:+.2} %), running from {:.3} s; flux at {:.1} s {:+.2} % off ψ*",
                    first.rr_scale,
                    100.0 * err[0],
                    first.l_scale,
                    100.0 * err[1],
                    first.t_s,
                    last.t_s,
                    100.0 * flux,
                );
                for k in 0..3 {
                    worst[k] = worst[k].max(err[k].abs());
                    sum[k] += err[k].abs();
                }
                n += 1.0;
            }
        }
    }
    for (k, what) in ["R_r", "L", "flux"].iter().enumerate() {
        eprintln!("{what}: worst {:.2} %, mean |error| {:.2} %", 100.0 * worst[k], 100.0 * sum[k] / n);
        assert!(
            worst[k] <= 0.06 && sum[k] / n <= 0.03,
            "{what}: worst {:.2} %, mean {:.2} %",
            100.0 * worst[k],
            100.0 * sum[k] / n
        );
    }
}

/// A rotor heating up mid-run (its resistance stepping ×1.5 at speed under load, faster than
/// any real rotor heats): the reactive-power law brings the estimate within 5 % of the new
/// value within 1 s (ten rotor time constants: the law's own is three, and it listens only
/// on the slow periods whose plan held the references, `mras::PLAN_STEADY_FRACTION`), and
/// the machine's flux back within 5 % of the drive's model — without the adaptation
/// (`rotor_resistance_range = [1, 1]`) the flux settles 32 % above it.
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
    let adapted = run(spec, cold, events.clone(), 2.5, 5);
    let before = adapted.iter().rfind(|r| r.t_s < 1.0).unwrap();
    assert!((before.rr_scale - 1.0).abs() <= 0.05, "cold estimate {:.4}", before.rr_scale);
    let half = adapted.iter().find(|r| r.t_s >= 1.5).unwrap();
    let after = adapted.iter().find(|r| r.t_s >= 2.0).unwrap();
    let end = adapted.last().unwrap();
    eprintln!(
        "adapted: estimate ×{:.4} before, ×{:.4} 0.5 s after, ×{:.4} 1 s after, ×{:.4} at {:.1} s; flux/model {:.3} at the end",
        before.rr_scale,
        half.rr_scale,
        after.rr_scale,
        end.rr_scale,
        end.t_s,
        flux_ratio(end)
    );
    assert!((after.rr_scale / 1.5 - 1.0).abs() <= 0.05, "estimate 1 s after the step: {:.4}", after.rr_scale);
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

/// The inductance is read from the whole flux linkage an enable builds, so only on a rotor
/// idle long enough to have lost its flux (`controller_core::mras::DEMAGNETIZED_TIME_CONSTANTS`,
/// 0.32 s on the shipped motor): re-enabled 50 ms after a stop, the drive keeps the
/// estimate it had, bit for bit (the rotor still holds most of its flux, which would read as
/// a smaller inductance); re-enabled 0.5 s after one it measures again, within 6 %. The
/// rotor resistance is read every time (the decay's ratio does not depend on the flux left).
#[test]
fn the_inductance_is_measured_only_on_a_demagnetized_rotor() {
    let spec = shipped();
    let events = vec![
        (0.0, Event::Enable),
        (0.5, Event::Stop),
        (0.55, Event::Enable),
        (1.1, Event::Stop),
        (1.6, Event::Enable),
    ];
    let rows = run(spec, box_motor(&spec, 1.0, 1.5, 0.6), events, 2.2, 11);
    let at = |t: f64| rows.iter().rfind(|r| r.t_s < t).unwrap();
    let (first, second, third) = (at(0.5), at(1.1), at(2.2));
    for r in [first, second, third] {
        assert_eq!(r.mode, Some(Mode::Running), "at {:.2} s", r.t_s);
        eprintln!("{:.2} s: L ×{:.4}, R_r ×{:.4}", r.t_s, r.l_scale, r.rr_scale);
        assert!((r.rr_scale / 1.5 - 1.0).abs() <= 0.06, "R_r ×{:.4} at {:.2} s", r.rr_scale, r.t_s);
    }
    assert_eq!(second.l_scale, first.l_scale, "not demagnetized: kept");
    assert!((first.l_scale / 0.6 - 1.0).abs() <= 0.06, "first: L ×{:.4}", first.l_scale);
    assert!((third.l_scale / 0.6 - 1.0).abs() <= 0.06, "third: L ×{:.4}", third.l_scale);
    assert_ne!(third.l_scale, first.l_scale, "measured again");
}

/// At no load and speed the reactive power gives the inductance without the stator
/// resistance (`controller_core::mras::MrasConfig::update_inductance`): over the shipped
/// box's corners (cold and hot rotors and stators, L ×1, ×0.8, ×0.6) with realistic sensors,
/// the estimate the magnetizing fit starts the run on (within 6 %, the test above) is within
/// 1.5 % of the machine's 1.5 s of no-load running at 100 rad/s later, and the machine's flux
/// within 1.5 % of its reference — the flux accuracy the fit alone leaves at its own error.
#[test]
fn no_load_running_corrects_the_inductance_the_fit_read() {
    let spec = shipped();
    let events = vec![(0.0, Event::Enable), (0.3, Event::Reference(Reference::Speed(100.0)))];
    let (mut fit_worst, mut law_worst, mut flux_worst) = (0.0f64, 0.0f64, 0.0f64);
    for l in [1.0, 0.8, 0.6] {
        for (rs, rr) in [(1.0, 1.0), (1.5, 2.0)] {
            for seed in 0..2 {
                let rows = run(spec, box_motor(&spec, rs, rr, l), events.clone(), 2.0, 21 + seed);
                let first = rows.iter().find(|r| r.mode == Some(Mode::Running)).unwrap();
                let last = rows.last().unwrap();
                let flux = last.x.psi_alpha_wb.hypot(last.x.psi_beta_wb) / spec.flux_ref_wb - 1.0;
                let (fit, law) = (first.l_scale / l - 1.0, last.l_scale / l - 1.0);
                eprintln!(
                    "L ×{l}, R_s ×{rs}, R_r ×{rr}, seed {seed}: fit L ×{:.4} ({:+.2} %), at {:.1} s L ×{:.4} ({:+.2} %), R_r ×{:.4}; flux {:+.2} % off ψ*",
                    first.l_scale,
                    100.0 * fit,
                    last.t_s,
                    last.l_scale,
                    100.0 * law,
                    last.rr_scale,
                    100.0 * flux
                );
                fit_worst = fit_worst.max(fit.abs());
                law_worst = law_worst.max(law.abs());
                flux_worst = flux_worst.max(flux.abs());
            }
        }
    }
    eprintln!(
        "worst: fit {:.2} %, after no-load running {:.2} %, flux {:.2} %",
        100.0 * fit_worst,
        100.0 * law_worst,
        100.0 * flux_worst
    );
    assert!(law_worst <= 0.015 && flux_worst <= 0.015, "L {law_worst:.4}, flux {flux_worst:.4}");
}

/// Issue 50: a flying start at twice base speed (the 300 W motor on 310 V, a dynamometer
/// holding 373.2 rad/s from the enable, the rotor-resistance range widened to [0.7, 2] so
/// that no end of it hides a misreading; realistic sensors): the magnetizing fit reads the
/// rotor resistance on the q axis, where the building flux is the back-EMF (`mras::FitAxis`),
/// within 2 % of the truth when the drive starts running — on the linear motor, and on its
/// saturating twin read on its curve (`MrasConfig::rotor_resistance_on_curve`: ×1.0185, the
/// encoder's speed at the enable; ×0.9994 with an exact one). Read on the d axis, where a
/// field angle drifting by a milliradian moves the voltage by a quarter of the decay, it
/// was ×0.88 on the linear motor and ×2.4 (the range's end) on the twin, whose detuned field
/// then tripped a false `EncoderImplausible` at a half of its envelope.
#[test]
fn a_flying_start_at_top_speed_reads_its_rotor_resistance() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    for name in ["drive.toml", "drives/delorenzo-saturating.toml"] {
        let file = drive_file::DriveFile::load(&root.join(name)).unwrap();
        let spec = DriveSpec { rotor_resistance_range: [0.7, 2.0], ..file.spec };
        let (plant, plant_saturation) = match file.saturating_motor {
            Some((m, s)) => (m, Some(s)),
            None => (spec.motor, None),
        };
        let events = vec![(0.0, Event::Enable), (0.0, Event::Reference(Reference::Torque(0.0)))];
        let mut b = builtin(spec, plant, events, 0.4, 3);
        b.plant_saturation = plant_saturation;
        b.scenario.load = LoadModel::Dynamometer { omega_m_rad_s: 373.2 };
        let (rows, mode) = b.run(|_| {}).unwrap();
        assert_eq!(mode, Mode::Running, "{name}");
        let first = rows.iter().find(|r| r.mode == Some(Mode::Running)).unwrap();
        eprintln!("{name}: R_r ×{:.4} when running from {:.3} s", first.rr_scale, first.t_s);
        assert!((first.rr_scale - 1.0).abs() < 0.02, "{name}: ×{}", first.rr_scale);
    }
}

/// Issue 50: a machine that heats with its own losses (`plant::thermal`: the stator winding
/// and the rotor cage as first-order nodes on the nameplate's rated rise, 80 K at 0.88 A; the
/// time constant compressed from minutes to 2 s so that a run shows it), driven at 100 rad/s
/// under 1.6 N·m from cold: the rotor warms by tens of kelvin and its resistance with it, and
/// the reactive-power law keeps the drive's estimate within 3 % of the machine's resistance
/// at every row of the last second, the flux within 3 % of the drive's model.
#[test]
fn the_online_law_follows_a_rotor_heating_with_its_losses() {
    use hil_sim::sim::HeatingRun;
    use plant::thermal::ThermalSpec;
    let spec = shipped();
    let plant = spec.motor;
    let thermal = ThermalSpec {
        rated_current_a: 0.88,
        no_load_current_a: spec.flux_ref_wb / (plant.lm_h() * 2f64.sqrt()),
        rated_rise_k: 80.0,
        time_constant_s: 2.0,
        ambient_c: 40.0,
        reference_c: 40.0,
    };
    let model = thermal.heating(&plant).unwrap();
    let events = vec![
        (0.0, Event::Enable),
        (0.3, Event::Reference(Reference::Speed(100.0))),
        (0.6, Event::LoadNm(1.6)),
    ];
    let mut b = builtin(spec, plant, events, 5.0, 7);
    b.scenario.trace_every = 100;
    b.scenario.heating = Some(HeatingRun { model, windings: model.cold() });
    let (rows, mode) = b.run(|_| {}).unwrap();
    assert_eq!(mode, Mode::Running);
    let truth = |r: &Row| model.motor_at(&r.windings.unwrap()).rr_ohm() / plant.rr_ohm();
    let end = rows.last().unwrap();
    let w = end.windings.unwrap();
    eprintln!(
        "at {:.1} s: stator {:.1} °C, rotor {:.1} °C, R_r ×{:.4}, estimate ×{:.4}",
        end.t_s,
        w.stator_c,
        w.rotor_c,
        truth(end),
        end.rr_scale
    );
    assert!(w.rotor_c - thermal.ambient_c > 20.0, "the rotor heated by {} K", w.rotor_c - thermal.ambient_c);
    for r in rows.iter().filter(|r| r.t_s >= end.t_s - 1.0) {
        let (err, flux) =
            (r.rr_scale / truth(r) - 1.0, r.x.psi_alpha_wb.hypot(r.x.psi_beta_wb) / r.psi_est_wb - 1.0);
        assert!(err.abs() < 0.03 && flux.abs() < 0.03, "{:.2} s: estimate {err:+.4}, flux {flux:+.4}", r.t_s);
    }
}

/// Issue 50: `scenarios/restart-hot.toml` — the shipped drive restarted on a motor stopped
/// at its rated rise (120 °C, the file's resistances stated at 20 °C: R_r ×1.403): the
/// magnetizing fit reads the hot rotor within 1 % before the first torque, and the windings'
/// temperatures are in the trace.
#[test]
fn a_motor_restarted_hot_is_read_hot() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/restart-hot.toml");
    let hil_sim::scenario_file::ScenarioFileKind::ClosedLoop(b) =
        hil_sim::scenario_file::load(&path).unwrap()
    else {
        panic!("a closed-loop scenario")
    };
    let model = b.scenario.heating.unwrap().model;
    let (rows, mode) = b.run(|_| {}).unwrap();
    assert_eq!(mode, Mode::Running);
    let first = rows.iter().find(|r| r.mode == Some(Mode::Running)).unwrap();
    let w = first.windings.unwrap();
    let truth = model.motor_at(&w).rr_ohm() / b.plant.rr_ohm();
    eprintln!("rotor at {:.2} °C: R_r ×{truth:.4}, read ×{:.4}", w.rotor_c, first.rr_scale);
    assert!((w.rotor_c - 120.0).abs() < 0.1 && (truth - 1.403).abs() < 1e-3, "{w:?}, ×{truth}");
    assert!((first.rr_scale / truth - 1.0).abs() < 0.01, "×{}", first.rr_scale);
}
