//! The sensorless observer (`controller_core::observer`, Hinkkanen et al. 2010) riding beside
//! the shipped encoder drive on the simulated machine: it sees only what a sensorless drive
//! would — the voltage the drive asked for (before its dead-time compensation, which the
//! switching inverter's 1 µs dead time then departs from), the currents through realistic
//! sensors (12-bit ADC with offset, gain error and noise), never the encoder — and its
//! speed and flux are compared with the plant's. The acceptance figure for a
//! sensorless drive is the speed within 2 % of base speed; the estimate the drive would run
//! on is held to that here, in every quadrant the shipped drive's P law visits under
//! ±0.8·τ_max loads at half base speed and at 3 % of it (where the negative load turns the
//! rotor backwards: plugging, the stator frequency near zero).
#![allow(clippy::unwrap_used, clippy::indexing_slicing)]

use controller_core::drive::{
    Drive, DriveConfig, DriveSpec, FastOutput, Measurements, Mode, PhaseCommand, Reference, SpeedFeedback,
    Telemetry,
};
use controller_core::frames::AlphaBeta;
use controller_core::motor::MotorParams;
use controller_core::observer::{Estimate, FluxObserver, ObserverConfig};
use drive_file::DriveFile;
use hil_sim::inverter::InverterModel;
use hil_sim::scenario::Builtin;
use hil_sim::sensors::SensorModel;
use hil_sim::sim::{DriveUnderTest, Event, LoadModel, Row, Scenario};

/// The shipped drive with the observer beside it, fed what the drive measured and asked for.
struct Riding {
    drive: Drive,
    cfg: ObserverConfig,
    obs: FluxObserver,
    /// The voltage the drive asked for in its last two steps (newest first): the one asked
    /// two steps ago was applied over the interval that ends at this step's sample.
    asked: [AlphaBeta; 2],
    log: Vec<Estimate>,
}

impl DriveUnderTest for Riding {
    fn slow_divider(&self) -> u16 {
        self.drive.config().slow_divider()
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
        let i = m.i_abc_a.clarke();
        let u = self.asked[1];
        // Magnetising at rest the speed is known (zero); running, it is estimated.
        let est = match self.drive.mode() {
            Mode::Running => self.obs.step(&self.cfg, u, i),
            _ => self.obs.step_known_speed(&self.cfg, u, i, 0.0),
        };
        let out = self.drive.step(m);
        let asked = match out.phases {
            PhaseCommand::Duty(_) => self.drive.telemetry().v_ab_v,
            PhaseCommand::Off => AlphaBeta::default(),
        };
        self.asked = [asked, self.asked[0]];
        assert!(!matches!(out.mode, Mode::Fault(_)), "the encoder drive tripped: {:?}", out.mode);
        self.log.push(est);
        out
    }
    fn telemetry(&self) -> Telemetry {
        self.drive.telemetry()
    }
}

/// Base speed of drive.toml on its 310 V bus, rad/s (its `[requirements]` comment, printed by
/// `design certify drive.toml`).
const BASE_RAD_S: f64 = 196.0;

/// The drive idles this long before its enable, s, as after its power-up: a sensorless
/// drive reads its current sensors' residual offsets then (`IdleZero`: the first 51.2 ms
/// block after the bridge is off discarded, the second kept).
const IDLE_S: f64 = 0.12;

/// drive.toml's drive `spec` on `plant` with `sensors`: enabled at [`IDLE_S`], the speed
/// reference at 0.3 s, the load steps of `loads` (time, N·m), until the last window's end; the switching
/// inverter with the board's dead time, which the drive compensates (the voltage the observer
/// is given is then the one the bridge applied but for the current's ripple around its zero
/// crossings).
fn scenario(
    spec: DriveSpec,
    plant: MotorParams,
    sensors: SensorModel,
    reference_rad_s: f64,
    loads: &[(f64, f64)],
    windows: &[(f64, f64)],
) -> Builtin {
    let mut events =
        vec![(IDLE_S, Event::Enable), (0.3, Event::Reference(Reference::Speed(reference_rad_s as f32)))];
    events.extend(loads.iter().map(|&(t, l)| (t, Event::LoadNm(l))));
    Builtin {
        name: "observer".into(),
        about: "drive.toml with the observer".into(),
        plant,
        plant_saturation: None,
        expect_fault: None,
        spec,
        scenario: Scenario {
            events,
            duration_s: windows.iter().map(|w| w.1).fold(0.0, f64::max),
            vdc_v: 310.0,
            substeps: 1,
            trace_every: 1,
            sensors,
            load: LoadModel::Torque,
            inverter: InverterModel::Switching { dead_time_s: spec.dead_time_compensation_s },
            dc_link: None,
            comparator: None,
            heating: None,
            extras: plant::Extras::default(),
        },
    }
}

/// The estimate against the plant in each window of `windows`, after
/// running `reference` with the load steps of `loads` (time, N·m) on drive.toml, the plant's
/// stator resistance `rs_scale` × the drive's.
fn ride(reference_rad_s: f64, loads: &[(f64, f64)], windows: &[(f64, f64)], rs_scale: f64) -> Vec<Figures> {
    let file = DriveFile::shipped().unwrap();
    let spec = file.spec;
    let ts = 1.0 / spec.pwm_frequency_hz;
    let p = f64::from(spec.motor.pole_pairs());
    let cfg = ObserverConfig::new(
        &spec.motor,
        ts,
        2.0 * core::f64::consts::PI * 40.0,
        0.1 * spec.flux_ref_wb,
        spec.protection.overspeed_rad_s * p,
    )
    .unwrap();
    let b = scenario(
        spec,
        spec.motor.scaled(rs_scale, 1.0, 1.0, 1.0).unwrap(),
        SensorModel::realistic(11),
        reference_rad_s,
        loads,
        windows,
    );
    let mut dut = Riding {
        drive: Drive::new(DriveConfig::new(&b.spec).unwrap()),
        cfg,
        obs: FluxObserver::new(AlphaBeta::default()),
        asked: [AlphaBeta::default(); 2],
        log: Vec::new(),
    };
    let mut rows: Vec<Row> = Vec::new();
    b.simulate(
        &mut dut,
        |_| {},
        |r| {
            rows.push(*r);
            Ok(())
        },
    )
    .unwrap();
    assert_eq!(rows.len(), dut.log.len());
    windows
        .iter()
        .map(|&(t0, t1)| {
            let mut f = Figures::default();
            let mut n = 0.0;
            // The estimate of step k is at its sample, the start of period k: row k's state.
            for (r, e) in rows.iter().zip(&dut.log).filter(|(r, _)| r.t_s >= t0 && r.t_s < t1) {
                let x = r.x;
                let w = f64::from(e.omega_m_rad_s) - x.omega_m_rad_s;
                let (pa, pb) = (f64::from(e.psi_r_alpha_wb), f64::from(e.psi_r_beta_wb));
                let angle = (pa * x.psi_beta_wb - pb * x.psi_alpha_wb)
                    .atan2(pa * x.psi_alpha_wb + pb * x.psi_beta_wb);
                f.speed_rad_s += x.omega_m_rad_s;
                f.mean_speed_error_rad_s += w;
                f.worst_speed_error_rad_s = f.worst_speed_error_rad_s.max(w.abs());
                f.worst_angle_rad = f.worst_angle_rad.max(angle.abs());
                n += 1.0;
            }
            f.speed_rad_s /= n;
            f.mean_speed_error_rad_s /= n;
            f
        })
        .collect()
}

/// The estimate against the plant over a window.
#[derive(Default)]
struct Figures {
    /// The rotor's mean speed, rad/s.
    speed_rad_s: f64,
    /// Mean of ω̂ − ω, rad/s: what a speed loop closed on ω̂ would leave in steady state.
    mean_speed_error_rad_s: f64,
    /// Largest |ω̂ − ω|, rad/s.
    worst_speed_error_rad_s: f64,
    /// Largest |∠ψ̂_r − ∠ψ_r|, rad.
    worst_angle_rad: f64,
}

#[test]
fn the_observer_finds_the_speed_and_the_field_in_every_quadrant() {
    let tau = 1.6; // 0.8 × the shipped speed law's 2 N·m
    for (name, reference) in [("half base speed", 0.5 * BASE_RAD_S), ("3 % of base speed", 0.03 * BASE_RAD_S)]
    {
        let windows = [(1.0, 1.5), (2.0, 2.5), (3.0, 3.5)];
        let got = ride(reference, &[(1.5, tau), (2.5, -tau)], &windows, 1.0);
        for ((t0, t1), f) in windows.iter().zip(&got) {
            eprintln!(
                "{name}, {t0}–{t1} s (ω {:.1} rad/s): speed error mean {:+.3}, worst {:.3} rad/s ({:.2} %, {:.2} % of base); flux angle worst {:.2}°",
                f.speed_rad_s,
                f.mean_speed_error_rad_s,
                f.worst_speed_error_rad_s,
                100.0 * f.mean_speed_error_rad_s.abs() / BASE_RAD_S,
                100.0 * f.worst_speed_error_rad_s / BASE_RAD_S,
                f.worst_angle_rad.to_degrees()
            );
        }
        for f in &got {
            // The figure (2 % of base speed, mean over 0.5 s) for the estimate a
            // sensorless speed loop would close on; the worst single sample (the sensors'
            // noise through the speed adaptation) within twice that; the field angle within
            // 5° (the torque current's share leaking into the flux axis below 9 %).
            assert!(f.mean_speed_error_rad_s.abs() < 0.02 * BASE_RAD_S);
            assert!(f.worst_speed_error_rad_s < 0.04 * BASE_RAD_S);
            assert!(f.worst_angle_rad < 5f64.to_radians());
        }
    }
}

/// Why the drive measures the stator resistance: at low speed the voltage model's `R_s·i`
/// outweighs the back-EMF (≈ 25 V against a few volts at 3 % of base speed under load), so
/// an observer on the file's R_s, riding beside a stator 20 % hotter — inside the certified
/// box's R_s × [1, 1.5] — is moved in the low-speed regenerating (plugging) window beyond
/// the 2 % of base speed. The drive itself runs its observer on the R_s its
/// magnetizing fit measured (`the_drive_runs_on_the_observer_as_on_its_encoder`).
#[test]
fn a_hotter_stator_than_the_drive_believes_defeats_it_at_low_speed_regenerating() {
    let windows = [(1.0, 1.5), (2.0, 2.5)];
    let got = ride(0.03 * BASE_RAD_S, &[(1.5, 1.6), (2.5, -1.6)], &windows, 1.2);
    for ((t0, t1), f) in windows.iter().zip(&got) {
        eprintln!(
            "R_s × 1.2, 3 % of base, {t0}–{t1} s (ω {:.1} rad/s): speed error mean {:+.3} rad/s ({:.2} % of base); flux angle worst {:.2}°",
            f.speed_rad_s,
            f.mean_speed_error_rad_s,
            100.0 * f.mean_speed_error_rad_s.abs() / BASE_RAD_S,
            f.worst_angle_rad.to_degrees()
        );
    }
    // Motoring at 3 % of base it holds; plugging it does not.
    assert!(got[0].mean_speed_error_rad_s.abs() < 0.02 * BASE_RAD_S);
    assert!(got[1].mean_speed_error_rad_s.abs() > 0.02 * BASE_RAD_S);
}

/// drive.toml's scenario of [`ride`] run by the drive itself on `feedback` (a plain drive, no
/// rider), on a plant whose stator resistance is `rs_scale` × the drive's: the speed
/// reference `references` (time, rad/s; the first at 0.3 s as [`scenario`] has it, each later
/// one at its time), the load steps `loads`; the plant's mean speed in each window and the
/// mode it ends in.
fn run_on(
    feedback: SpeedFeedback,
    sensors: SensorModel,
    rs_scale: f64,
    references: &[(f64, f64)],
    loads: &[(f64, f64)],
    windows: &[(f64, f64)],
) -> (Vec<f64>, Mode) {
    let mut spec = DriveFile::shipped().unwrap().spec;
    spec.speed_feedback = feedback;
    let plant = spec.motor.scaled(rs_scale, 1.0, 1.0, 1.0).unwrap();
    let (first, later) = references.split_first().unwrap();
    let mut b = scenario(spec, plant, sensors, first.1, loads, windows);
    let steps = later.iter().map(|&(t, w)| (t, Event::Reference(Reference::Speed(w as f32))));
    b.scenario.events.extend(steps);
    b.scenario.events.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (rows, mode) = b.run(|_| {}).unwrap();
    let means = windows
        .iter()
        .map(|&(t0, t1)| {
            let w: Vec<f64> =
                rows.iter().filter(|r| r.t_s >= t0 && r.t_s < t1).map(|r| r.x.omega_m_rad_s).collect();
            w.iter().sum::<f64>() / w.len() as f64
        })
        .collect();
    (means, mode)
}

/// The drive on the observer instead of the encoder (issue 53's acceptance: speed steps and
/// 0.8·τ_max load steps at half base speed and at 3 % of it, no fault, the true shaft speed
/// within 2 % of base speed — here of the same drive's on its encoder, whose P law droops
/// by design under load, seed 002 eq. (21), so that the positive load pushes the 3 % run
/// backwards: plugging, the stator frequency near zero).
///
/// At 3 % of base speed the stator's resistance decides: the drive measures it at every
/// enable (the magnetizing fit's constant voltage over the current) and its observer runs on
/// it, so a stator hotter than the file (R_s ×1.2, ×1.5: the certified box) is held like a
/// cold one — on the file's R_s the plugging window ran away (−68 % and −83 % of base).
///
/// The realistic sensors' 20 mA offset on phase b (2.3 % of this motor's rated current,
/// 2.5 LSB: a residual after the firmware's power-up offset calibration as temperature drift
/// leaves one) would move the voltage model by `R_s·Δi` ≈ 0.3 V against a back-EMF of a few
/// volts near zero stator frequency, and the fit's R_s by its projection on the d axis: the
/// drive reads it while idle before the enable ([`IDLE_S`]) and takes it off. Every case is
/// held to 2 % of base speed.
#[test]
fn the_drive_runs_on_the_observer_as_on_its_encoder() {
    let tau = 1.6;
    let windows = [(1.0, 1.5), (2.0, 2.5), (3.0, 3.5)];
    let offset_free = SensorModel { current_offset_a: [0.0; 3], ..SensorModel::realistic(11) };
    let cases = [
        ("half base speed", 0.5, SensorModel::realistic(11), 1.0),
        ("3 % of base speed", 0.03, SensorModel::realistic(11), 1.0),
        ("3 % of base speed, no current offset", 0.03, offset_free, 1.0),
        ("3 % of base speed, R_s ×1.2", 0.03, SensorModel::realistic(11), 1.2),
        ("3 % of base speed, R_s ×1.5", 0.03, SensorModel::realistic(11), 1.5),
        ("3 % of base speed, R_s ×1.5, no current offset", 0.03, offset_free, 1.5),
    ];
    for (name, of_base, sensors, rs) in cases {
        let (reference, loads) = (of_base * BASE_RAD_S, [(1.5, tau), (2.5, -tau)]);
        let (enc, enc_mode) =
            run_on(SpeedFeedback::Encoder, sensors, rs, &[(0.3, reference)], &loads, &windows);
        let (obs, obs_mode) =
            run_on(SpeedFeedback::Sensorless, sensors, rs, &[(0.3, reference)], &loads, &windows);
        let mut worst = 0.0f64;
        for ((t0, t1), (e, o)) in windows.iter().zip(enc.iter().zip(&obs)) {
            eprintln!(
                "{name}, {t0}–{t1} s: mean speed on the encoder {e:.2} rad/s, sensorless {o:.2} rad/s ({:+.2} % of base)",
                100.0 * (o - e) / BASE_RAD_S
            );
            worst = worst.max((o - e).abs() / BASE_RAD_S);
        }
        assert_eq!(enc_mode, Mode::Running);
        assert_eq!(obs_mode, Mode::Running, "{name}: sensorless ended in {obs_mode:?}");
        assert!(worst < 0.02, "{name}: {worst}");
    }
}

/// Issue 53's second acceptance on drive.toml: through zero speed under 0.5·τ_max, and
/// regenerating at 10 % of base speed with 0.5·τ_max. The P law droops τ_L/k_p = 1 N·m/0.05 =
/// 20 rad/s, so under +1 N·m a reference ramped from +40 to −20 rad/s in 0.5 rad/s steps every
/// 20 ms (a reversal over 2.4 s) takes the rotor from ≈ +20 through zero — the stator frequency
/// crosses zero on the way, at the rotor's −ω_sl — to ≈ −40 rad/s; then the load reverses
/// (−1 N·m drives the rotor forward) with the reference at 0, the rotor at ≈ +20 rad/s
/// regenerating (10 % of base speed). Each window's mean against the same drive's on its
/// encoder.
#[test]
fn through_zero_speed_under_load_and_regenerating_at_a_tenth_of_base_speed() {
    let steps = 120;
    let mut references: Vec<(f64, f64)> = vec![(0.3, 40.0)];
    references.extend((0..=steps).map(|k| (1.0 + 0.02 * f64::from(k), 40.0 - 0.5 * f64::from(k))));
    references.push((4.0, 0.0));
    let loads = [(0.6, 1.0), (4.0, -1.0)];
    let windows = [(0.8, 1.0), (1.6, 1.8), (2.0, 2.2), (2.4, 2.6), (3.2, 3.6), (4.8, 5.3)];
    let offset_free = SensorModel { current_offset_a: [0.0; 3], ..SensorModel::realistic(11) };
    for (name, sensors) in [("no current offset", offset_free), ("20 mA offset", SensorModel::realistic(11))]
    {
        let (enc, enc_mode) = run_on(SpeedFeedback::Encoder, sensors, 1.0, &references, &loads, &windows);
        let (obs, obs_mode) = run_on(SpeedFeedback::Sensorless, sensors, 1.0, &references, &loads, &windows);
        assert_eq!(enc_mode, Mode::Running);
        assert_eq!(obs_mode, Mode::Running, "{name}: sensorless ended in {obs_mode:?}");
        for ((t0, t1), (e, o)) in windows.iter().zip(enc.iter().zip(&obs)) {
            let error = (o - e) / BASE_RAD_S;
            eprintln!(
                "{name}, {t0}–{t1} s: mean speed on the encoder {e:.2} rad/s, sensorless {o:.2} rad/s ({:+.2} % of base)",
                100.0 * error
            );
            assert!(error.abs() < 0.02, "{name}, {t0}–{t1} s: {error}");
        }
    }
}

/// drive.toml's `spec` on its motor, realistic sensors: an active load of `load_nm` spins the
/// rotor up with the bridge off until `end_s` and lets it coast; the drive is enabled at 0.6 s
/// with the speed reference `reference_rad_s`; the run ends at `duration_s`.
fn coasting_then_enabled(
    spec: DriveSpec,
    load_nm: f64,
    end_s: f64,
    reference_rad_s: f64,
    duration_s: f64,
) -> Builtin {
    let loads = [(0.0, load_nm), (end_s, 0.0)];
    let mut b =
        scenario(spec, spec.motor, SensorModel::realistic(11), reference_rad_s, &loads, &[(0.0, duration_s)]);
    for (t, e) in &mut b.scenario.events {
        if matches!(e, Event::Enable | Event::Reference(_)) {
            *t = 0.6;
        }
    }
    b.scenario.events.sort_by(|a, b| a.0.total_cmp(&b.0));
    b
}

/// A flying start then braking at once (issue 53): an active load spins the rotor up with
/// the bridge off, then lets it coast; the sensorless drive enabled on it finds the rotor
/// turning (the search of `a_flying_start_catches_the_rotor_both_ways`), reads its rotor
/// resistance from the same search's decay (`Turn::decay_rate_per_s`: the magnetizing
/// fit needs the rotor at rest), magnetizes on its speed and brakes at once — at ≈ 1.75 ×
/// base speed to 150 rad/s in field weakening, and at −base speed to rest — on plants whose
/// rotor is × 1, × 1.5 and × 1.9 of the motor file's (the certified range's span). Each run
/// ends Running, the shaft nearer its reference than at the enable, the current below half
/// the trip level, and the rotor resistance read within 5 % of the plant's (the range's floor
/// clamps × 1; the least-squares fit of lag one, which took the windows' noise for part of the
/// transient, read it up to ≈ 10 % low). Held at the range's middle instead (× √2),
/// the speed estimate under the braking current was off by its error times the slip, ran
/// against the torque, and the following check tripped 2 ms after the drive started running.
#[test]
fn a_flying_start_then_braking_at_once_holds() {
    let mut spec = DriveFile::shipped().unwrap().spec;
    spec.speed_feedback = SpeedFeedback::Sensorless;
    for rr in [1.0, 1.5, 1.9] {
        // (the load and its end, s; the reference, rad/s; the least |speed| at the enable)
        for (load, end_s, reference, at_least) in [(-4.0, 0.45, 150.0, 300.0), (4.0, 0.26, 0.0, 190.0)] {
            let mut b = coasting_then_enabled(spec, load, end_s, reference, 1.2);
            b.plant = spec.motor.scaled(1.0, rr, 1.0, 1.0).unwrap();
            let (rows, mode) = b.run(|_| {}).unwrap();
            let at_enable = rows.iter().find(|r| r.t_s >= 0.6).unwrap().x.omega_m_rad_s;
            let at_end = rows.last().unwrap().x.omega_m_rad_s;
            let running = rows.iter().find(|r| r.mode == Some(Mode::Running)).unwrap();
            let read = running.rr_scale / rr;
            let peak = rows.iter().map(|r| r.x.i_alpha_a.hypot(r.x.i_beta_a)).fold(0.0, f64::max);
            eprintln!(
                "R_r × {rr}: enabled at {at_enable:.1} rad/s, reference {reference} rad/s: read R_r × {:.4} ({:+.1} %), \
                 Running at {:.4} s, {at_end:.1} rad/s at the end, {mode:?}, peak current {peak:.2} A",
                running.rr_scale,
                100.0 * (read - 1.0),
                running.t_s
            );
            assert!(at_enable.abs() > at_least, "{at_enable}");
            assert_eq!(mode, Mode::Running);
            assert!((at_end - reference).abs() < (at_enable - reference).abs(), "{at_end}");
            assert!(peak < 0.5 * spec.protection.i_trip_a, "{peak}");
            assert!((read - 1.0).abs() <= 0.05, "R_r read × {} on × {rr}", running.rr_scale);
        }
    }
}

/// The speed loop samples the observer's speed once per slow period: it reads the mean of
/// the period's estimates. Sampled alone, the estimate's noise up to the observer's
/// bandwidth aliased into the speed loop — on the current loops and the speed gain
/// `design tune` gives this motor at 20 kHz (a stationary PI of 550 V/A, whose gain carries
/// the current sensors' noise into the voltage the observer reads; k_p 0.13) the torque's
/// ripple at 100 rad/s was 3.8 × the encoder drive's (0.325 against 0.086 N·m peak to peak);
/// on the mean, 1.5 × (0.126). Held to 2 ×.
#[test]
fn the_speed_loop_reads_the_observers_mean_over_its_period() {
    let ripple = |feedback: SpeedFeedback| {
        let mut spec = DriveFile::shipped().unwrap().spec;
        spec.speed_feedback = feedback;
        spec.current_law =
            controller_core::current::CurrentLaw { kp_v_per_a: 550.425, ki_v_per_as: 212_684.0, lag: None };
        spec.speed_law = controller_core::speed::SpeedLaw::SaturatedP { kp: 0.13038, tau_max_nm: 2.0 };
        let sensors =
            SensorModel { current_offset_a: [0.0; 3], current_gain: [1.0; 3], ..SensorModel::realistic(11) };
        let b = scenario(spec, spec.motor, sensors, 100.0, &[], &[(0.0, 1.5)]);
        let (rows, mode) = b.run(|_| {}).unwrap();
        assert_eq!(mode, Mode::Running, "{feedback:?}");
        let torque: Vec<f64> = rows.iter().filter(|r| r.t_s > 1.2).map(|r| r.torque_nm).collect();
        torque.iter().copied().fold(f64::MIN, f64::max) - torque.iter().copied().fold(f64::MAX, f64::min)
    };
    let (encoder, sensorless) = (ripple(SpeedFeedback::Encoder), ripple(SpeedFeedback::Sensorless));
    eprintln!("torque peak to peak at 100 rad/s: encoder {encoder:.3} N·m, sensorless {sensorless:.3} N·m");
    assert!(sensorless < 2.0 * encoder, "{sensorless} against {encoder}");
}

/// Encoder-loss ride-through (issue 53, deliverable 3): drive.toml with the observer beside
/// its encoder (`speed_feedback = "encoder_ride_through"`) at half base speed under
/// +0.8·τ_max; its encoder freezes at 1.5 s (the counter stops: the fault matrix's "encoder
/// stuck"), and the load reverses to −0.8·τ_max at 2.5 s. The drive does not trip: it reports
/// the fault within the matrix's encoder bound (two slow periods) and carries on on its
/// observer — the true shaft speed in each window within 2 % of base speed of the same drive
/// on a healthy encoder (the sensorless figure), the current below the trip level.
#[test]
fn a_frozen_encoder_at_speed_is_ridden_through_on_the_observer() {
    use controller_core::drive::{Fault, FaultSet};
    use hil_sim::sim::Injection;
    let (tau, reference) = (1.6, 0.5 * BASE_RAD_S);
    let (loads, freeze_s) = ([(1.0, tau), (2.5, -tau)], 1.5);
    let windows = [(1.9, 2.4), (3.0, 3.5)];
    let sensors = SensorModel::realistic(11);
    let (healthy, healthy_mode) =
        run_on(SpeedFeedback::Encoder, sensors, 1.0, &[(0.3, reference)], &loads, &windows);
    assert_eq!(healthy_mode, Mode::Running);
    let mut spec = DriveFile::shipped().unwrap().spec;
    spec.speed_feedback = SpeedFeedback::EncoderRideThrough;
    let mut b = scenario(spec, spec.motor, sensors, reference, &loads, &windows);
    b.scenario.events.push((freeze_s, Event::Fault(Injection::EncoderStuck)));
    b.scenario.events.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (rows, mode) = b.run(|_| {}).unwrap();
    assert_eq!(mode, Mode::Running, "the ride-through drive ended in {mode:?}");
    let reported = rows.iter().find(|r| r.ridden_through != FaultSet::EMPTY).unwrap();
    let slow_s = f64::from(spec.slow_divider) / spec.pwm_frequency_hz;
    let after_s = reported.t_s - freeze_s;
    eprintln!("reported {:?} {:.2} ms after the freeze", reported.ridden_through, 1e3 * after_s);
    assert!(reported.ridden_through.contains(Fault::EncoderLoss), "{:?}", reported.ridden_through);
    assert!(after_s <= 2.0 * slow_s + 1e-9, "{after_s}");
    for ((t0, t1), h) in windows.iter().zip(&healthy) {
        let w: Vec<f64> =
            rows.iter().filter(|r| r.t_s >= *t0 && r.t_s < *t1).map(|r| r.x.omega_m_rad_s).collect();
        let mean = w.iter().sum::<f64>() / w.len() as f64;
        let error = (mean - h) / BASE_RAD_S;
        eprintln!(
            "{t0}–{t1} s: mean speed on the healthy encoder {h:.2} rad/s, ridden through {mean:.2} rad/s ({:+.2} % of base)",
            100.0 * error
        );
        assert!(error.abs() < 0.02, "{t0}–{t1} s: {error}");
    }
    let peak = rows
        .iter()
        .filter(|r| r.t_s >= freeze_s)
        .map(|r| r.x.i_alpha_a.hypot(r.x.i_beta_a))
        .fold(0.0, f64::max);
    eprintln!("peak current after the freeze {peak:.2} A (trip {} A)", spec.protection.i_trip_a);
    assert!(peak < spec.protection.i_trip_a, "{peak}");
}

/// The flying start (issue 53, deliverable 4): the sensorless drive enabled on a rotor
/// coasting at ±base speed (an active load spun it up, ∓4 N·m until 0.26 s, and let it go;
/// no flux left in it), its reference the speed the rotor turns at (a fan restarted at its set
/// speed). The search reads the rotor's speed from its own flux under the held magnetizing
/// current (`controller_core::speed_search`), the drive magnetizes on it and runs on: the
/// issue asks it caught within 0.5 s below the trip current — Running within 0.5 s of the
/// enable and no fault to the end, the peak current below the 8 A trip, the speed in the last
/// 0.3 s within 2 % of base speed of the reference.
#[test]
fn a_flying_start_catches_the_rotor_both_ways() {
    let mut spec = DriveFile::shipped().unwrap().spec;
    spec.speed_feedback = SpeedFeedback::Sensorless;
    for sign in [1.0, -1.0] {
        let reference = sign * BASE_RAD_S;
        let (rows, mode) =
            coasting_then_enabled(spec, -4.0 * sign, 0.26, reference, 1.6).run(|_| {}).unwrap();
        let at_enable = rows.iter().find(|r| r.t_s >= 0.6).unwrap().x.omega_m_rad_s;
        let running_s =
            rows.iter().find(|r| r.t_s >= 0.6 && r.mode == Some(Mode::Running)).unwrap().t_s - 0.6;
        let peak = rows.iter().map(|r| r.x.i_alpha_a.hypot(r.x.i_beta_a)).fold(0.0, f64::max);
        let end: Vec<f64> = rows.iter().filter(|r| r.t_s >= 1.3).map(|r| r.x.omega_m_rad_s).collect();
        let mean = end.iter().sum::<f64>() / end.len() as f64;
        eprintln!(
            "enabled at {at_enable:.1} rad/s: Running after {:.1} ms, {mode:?} at the end, peak current {peak:.2} A, \
             mean speed {mean:.1} rad/s for {reference:.1} ({:+.2} % of base)",
            1e3 * running_s,
            100.0 * (mean - reference) / BASE_RAD_S
        );
        assert!(at_enable.abs() > 0.98 * BASE_RAD_S, "{at_enable}");
        assert_eq!(mode, Mode::Running);
        assert!(rows.iter().filter(|r| r.t_s >= 0.6).all(|r| r.mode.is_some_and(|m| m.is_active())));
        assert!(running_s < 0.5, "{running_s}");
        assert!(peak < spec.protection.i_trip_a, "{peak}");
        assert!((mean - reference).abs() < 0.02 * BASE_RAD_S, "{mean} for {reference}");
    }
}

/// A stated gap (docs/sensorless.md): an encoder that freezes at a low speed is not seen,
/// with or without the observer beside it. drive.toml at 10 % of base speed under +1.6 N·m
/// (the P law's droop has the rotor at ≈ −12 rad/s); frozen there at 1.5 s, the encoder's
/// change per read is below the jump check's level, the field freezes with it (the machine
/// a DC brake the voltage check cannot tell from a rotor at rest), and the load drives the
/// rotor backwards far beyond the reference without a fault or a report, until it reverses
/// at 2.5 s. Pinned so that the check that closes it flips it.
#[test]
fn an_encoder_frozen_at_a_low_speed_is_not_seen() {
    use controller_core::drive::FaultSet;
    use hil_sim::sim::Injection;
    for feedback in [SpeedFeedback::Encoder, SpeedFeedback::EncoderRideThrough] {
        let mut spec = DriveFile::shipped().unwrap().spec;
        spec.speed_feedback = feedback;
        let loads = [(1.0, 1.6), (2.5, -1.6)];
        let mut b =
            scenario(spec, spec.motor, SensorModel::realistic(11), 0.1 * BASE_RAD_S, &loads, &[(0.0, 2.5)]);
        b.scenario.events.push((1.5, Event::Fault(Injection::EncoderStuck)));
        b.scenario.events.sort_by(|a, b| a.0.total_cmp(&b.0));
        let (rows, mode) = b.run(|_| {}).unwrap();
        let at = |t: f64| rows.iter().find(|r| r.t_s >= t).unwrap().x.omega_m_rad_s;
        let slowest = rows.iter().map(|r| r.x.omega_m_rad_s).fold(f64::MAX, f64::min);
        eprintln!(
            "{feedback:?}: frozen at {:.1} rad/s, the rotor driven to {slowest:.1} rad/s, {mode:?} at the end",
            at(1.5)
        );
        assert!(at(1.5) < -5.0 && at(1.5) > -20.0, "{}", at(1.5));
        assert_eq!(mode, Mode::Running);
        assert!(rows.iter().all(|r| r.ridden_through == FaultSet::EMPTY));
        assert!(slowest < -100.0, "{slowest}");
    }
}

/// The stator resistance the sensorless drive measures at its enable (the magnetizing fit's
/// constant voltage over the current, realistic sensors, the switching inverter with the
/// board's dead time compensated) against the winding's, on plants whose R_s is × 1, 1.2 and
/// 1.5 the file's — against the margin the observer's certificate states for drive.toml
/// (`design certify`: the observer holds R_s errors within ×[0.986, 1.092] over its whole
/// grid). Each within 1 % of the winding's — inside the margin's tighter, −1.4 % side — so
/// the margin left is the winding's warming after the enable (docs/sensorless.md).
#[test]
fn the_measured_stator_resistance_against_the_certificates_margin() {
    let mut spec = DriveFile::shipped().unwrap().spec;
    spec.speed_feedback = SpeedFeedback::Sensorless;
    for rs in [1.0, 1.2, 1.5] {
        let plant = spec.motor.scaled(rs, 1.0, 1.0, 1.0).unwrap();
        let b = scenario(spec, plant, SensorModel::realistic(11), 0.0, &[], &[(0.0, 0.6)]);
        let mut drive = Drive::new(DriveConfig::new(&spec).unwrap());
        b.simulate(&mut drive, |_| {}, |_| Ok(())).unwrap();
        assert_eq!(drive.mode(), Mode::Running);
        let measured = f64::from(drive.stator_resistance_scale());
        let error = measured / rs - 1.0;
        eprintln!("plant R_s × {rs}: measured × {measured:.5} ({:+.3} % of the winding's)", 100.0 * error);
        assert!(error.abs() < 0.01, "{rs}: {measured}");
    }
}
