//! Issue 21's nonlinear campaign (`hil_sim::campaign`, `hil-sim campaign`): the drive in
//! software in the loop over its parameter box, each run judged by the module's criteria.
#![allow(clippy::unwrap_used, clippy::indexing_slicing)]

use drive_file::requirements::Requirement;
use hil_sim::campaign::{Campaign, Manoeuvre, Verdict};
use std::sync::atomic::AtomicBool;

fn shipped(runs: u64) -> Campaign {
    let f = drive_file::DriveFile::shipped().unwrap();
    Campaign {
        spec: f.spec,
        certify: f.certify.unwrap(),
        vdc_v: 310.0,
        duration_s: 1.0,
        runs,
        seed: 1,
        shard: (0, 1),
        encoder_lines: f.encoder_lines(),
        plant: None,
        requirements: f.requirements,
    }
}

fn run(c: &Campaign) -> Vec<Verdict> {
    c.run(|_| {}, &AtomicBool::new(false)).unwrap()
}

/// The shipped drive passes the linear certificates (continuous and sampled) over its
/// `[certify]` box, and the nonlinear campaign's corners over the same box. What the linear
/// analyses cannot see, the campaign found: at the low-inductance corners (L ×0.6, a
/// saturated machine) a drive on the motor file's inductances builds 0.6× the flux it
/// believes and its torque falls short of its command — every such corner under load misses
/// `requirements.torque_accuracy_fraction` with `inductance_range = [1, 1]` below (the
/// torque 23 % short of τ* at the first corner). With the inductances measured at the enable (`controller_core::mras`) they pass, as
/// the hot-rotor corners (R_r ×2: flux up to 1.66× its model before the rotor resistance was
/// measured and adapted) do. The test prints each corner's verdict (docs/design-toolkit.md).
#[test]
fn the_shipped_box_passes_the_campaign_with_the_inductance_measured() {
    let (spec, c) = design::certify::parse(std::path::Path::new("drive.toml"), drive_file::SHIPPED).unwrap();
    assert!(design::certify::certify(&spec, &c).unwrap().iter().all(|ch| ch.pass));
    let mut campaign = shipped(64);
    let verdicts = run(&campaign);
    for v in &verdicts {
        eprintln!("{}", v.csv());
    }
    let failed: Vec<String> = verdicts.iter().filter(|v| !v.passed()).map(Verdict::csv).collect();
    assert!(failed.is_empty(), "{failed:#?}");
    campaign.spec.inductance_range = [1.0, 1.0];
    let small_l = campaign.certify.inductance_factor[0];
    for v in run(&campaign) {
        if v.sample.l == small_l && v.manoeuvre != Manoeuvre::Reversal {
            let torque = v.requirements_missed().contains(&Requirement::TorqueAccuracy);
            assert!(torque, "the motor file's inductances: {}", v.csv());
        }
    }
}

/// What a commissioned drive faces: inductances within ±5 % (identification, issue 20),
/// both resistances over the shipped box's whole temperature range (R_s ×[1, 1.5], R_r
/// ×[1, 2], the rotor's measured and adapted by the drive), inertia ×[1, 2] — every run
/// passes, the corners and seeded samples. Before the adaptation the same box held only with
/// R_r within +20 % (`rotor_resistance_range = [1, 1]` below: at the hot corners the flux
/// leaves the drive's model — the diagnostic — and, loaded, misses its reference — the
/// verdict).
#[test]
fn a_commissioned_box_passes_every_run() {
    let mut c = shipped(96);
    c.certify.inductance_factor = [0.95, 1.05];
    let verdicts = run(&c);
    let failed: Vec<String> = verdicts.iter().filter(|v| !v.passed()).map(Verdict::csv).collect();
    assert!(failed.is_empty(), "{failed:#?}");
    assert_eq!(verdicts.len(), 96);
    let worst = verdicts.iter().map(|v| v.flux_ratio[1]).fold(0.0, f64::max);
    eprintln!("commissioned box: 96 of 96 pass; flux at most {worst:.3} of the model's");
    c.spec.rotor_resistance_range = [1.0, 1.0];
    let fixed = run(&c);
    for v in fixed.iter().filter(|v| v.sample.rr == 2.0) {
        let band = hil_sim::campaign::FLUX_MODEL_BAND;
        assert!(v.flux_ratio[1] > band[1], "without the adaptation the flux leaves the model: {}", v.csv());
        // Loaded, the slip the drive computes with the cold rotor's time constant turns the
        // field away: the steady flux misses its reference. The reversal ends at no load,
        // where the slip is nil and the flux is right again (its excess was transient).
        let loaded = v.manoeuvre != Manoeuvre::Reversal;
        if !loaded {
            eprintln!("R_r ×2 without the estimate, the reversal: {}", v.csv());
        }
        assert_eq!(v.requirements_missed().contains(&Requirement::FluxAccuracy), loaded, "{}", v.csv());
    }
}

/// Shards make the same runs as the whole campaign, bit for bit (each run's parameters,
/// manoeuvre and sensor noise come from the seed and its index alone).
#[test]
fn shards_concatenate_into_the_whole_campaign() {
    let mut c = shipped(70);
    c.duration_s = 0.5;
    let whole: Vec<String> = run(&Campaign { ..c }).iter().filter(|v| v.k >= 62).map(Verdict::csv).collect();
    let mut parts: Vec<(u64, String)> = (0..3)
        .flat_map(|i| run(&Campaign { shard: (i, 3), ..c }))
        .filter(|v| v.k >= 62)
        .map(|v| (v.k, v.csv()))
        .collect();
    parts.sort();
    assert_eq!(parts.into_iter().map(|(_, s)| s).collect::<Vec<_>>(), whole);
}

/// Into field weakening with a hot stator and rotor (R_s ×1.5, R_r ×1.2, L ×1.05: runs 28–31
/// of a 6 s campaign over the narrow box, speed steps to 345 rad/s): every manoeuvre ended in
/// `LossOfControl` at ≈ 111 rad/s while the voltage regulator cut at its 10 rad/s; cutting ten
/// times faster while the modulator limits (`VOLTAGE_REGULATOR_LIMITED_GAIN`), none faults,
/// and the three that are not reversals track the sampled machine's envelope within the
/// bound (the reversal misses it: the detuned field orientation, docs/design-toolkit.md).
#[test]
fn a_hot_motor_into_field_weakening_keeps_control() {
    let mut c = shipped(64);
    c.certify.rr_factor = [1.0, 1.2];
    c.certify.inductance_factor = [0.95, 1.05];
    c.duration_s = 6.0;
    let cancel = AtomicBool::new(false);
    for k in 28..32 {
        let v = c.run_one(k, &cancel).unwrap();
        let s = v.sample;
        assert_eq!((s.rs, s.rr, s.l), (1.5, 1.2, 1.05), "{}", v.csv());
        eprintln!("{}", v.csv());
        assert!(!v.failures.contains(&"fault"), "{}", v.csv());
        if k != 31 {
            assert!(v.passed(), "{}", v.csv());
        }
    }
}

/// A rotor ten times slower (T_r 0.65 s): the drive magnetizes it in 1.94 s, so the speed
/// step waits until 2.13 s, and 1 s runs are refused with the duration needed instead of
/// ending, every one, in Magnetizing.
#[test]
fn runs_too_short_to_magnetize_are_refused() {
    let mut c = shipped(4);
    let m = c.spec.motor;
    c.spec.motor = controller_core::motor::MotorParams::new(
        m.rs_ohm(),
        m.rr_ohm() / 10.0,
        m.ls_h(),
        m.lr_h(),
        m.lm_h(),
        m.pole_pairs(),
        m.j_kgm2(),
        m.b_nms(),
    )
    .unwrap();
    assert!((c.step_s() - 2.131).abs() < 1e-3, "{}", c.step_s());
    let e = c.run(|_| {}, &AtomicBool::new(false)).unwrap_err();
    assert!(e.contains("take a duration of at least 2.38 s"), "{e}");
    c.duration_s = 2.4;
    assert!(c.check().is_ok());
}

/// A drive whose rated flux needs more voltage than its bus gives even at standstill has no
/// speed range: its campaign stepped the speed to ±0 rad/s and passed every run, and
/// `design certify --campaign` certified it (found by trying, on the 24 V motor with
/// R_s = 19.9 Ω). Now refused, naming the bus and the flux.
#[test]
fn a_drive_without_a_speed_range_on_its_bus_is_refused() {
    let mut c = shipped(4);
    // The shipped motor's magnetizing current, 0.63 A, through 10 kΩ: 6.3 kV at standstill.
    c.spec.motor = c.spec.motor.scaled(1e4 / c.spec.motor.rs_ohm(), 1.0, 1.0, 1.0).unwrap();
    assert!(c.omega_s_rad_s() <= 0.0, "{}", c.omega_s_rad_s());
    let e = c.run(|_| {}, &AtomicBool::new(false)).unwrap_err();
    assert!(e.contains("no speed range on the") && e.contains("controller.flux_ref_wb"), "{e}");
}

/// The simulated encoder is the board's: the campaign's sensors had 1 024 lines whatever
/// `[board] encoder_lines` said, so a 13 000-line board's drive — its encoder-jump limit
/// derived from 13 000 lines — tripped `EncoderLoss` at standstill in 16 of 64 runs (found by
/// trying). On the board's own encoder every run passes.
#[test]
fn the_campaign_simulates_the_boards_encoder() {
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../drive.toml"))
        .unwrap()
        .replace("encoder_lines = 1024", "encoder_lines = 13000");
    let f = drive_file::DriveFile::parse(std::path::Path::new("fine.toml"), &text).unwrap();
    assert_eq!(f.encoder_lines(), 13000);
    let c = Campaign {
        spec: f.spec,
        certify: f.certify.unwrap(),
        encoder_lines: f.encoder_lines(),
        plant: None,
        duration_s: 0.5,
        runs: 64,
        ..shipped(64)
    };
    let bad: Vec<String> = run(&c).iter().filter(|v| !v.passed()).map(Verdict::csv).collect();
    assert!(bad.is_empty(), "{}", bad.join("\n"));
    // The 1 024-line encoder under that drive: what the campaign ran before.
    let old = Campaign { encoder_lines: 1024, ..c };
    assert!(run(&old).iter().any(|v| !v.passed()));
}

/// `hil-sim campaign --plant`: the runs simulate another machine at the box's samples — here
/// the shipped motor's saturating twin (`motors/delorenzo-saturating.toml`). The corners at
/// the nominal inductance pass as on the linear plant; the low-inductance corners (the whole
/// curve scaled by 0.6) miss the torque accuracy their requirements ask (13.7 % short at
/// worst), which docs/verification.md states: the drive's one measured inductance scale does
/// not follow a curve (the saturation issue's deliverable 5).
#[test]
fn the_campaign_runs_on_a_saturating_plant_when_asked() {
    let linear = shipped(64);
    let mut saturating = shipped(64);
    let (motor, saturation) = drive_file::motor::load_model("delorenzo-saturating").unwrap();
    saturating.plant =
        Some(hil_sim::scenario::SimulatedMotor { motor, saturation, extras: plant::Extras::default() });
    let (lin, sat) = (run(&linear), run(&saturating));
    let small_l = linear.certify.inductance_factor[0];
    for (a, b) in lin.iter().zip(&sat) {
        assert_eq!(a.k, b.k);
        assert_ne!(a.csv(), b.csv(), "run {} did not change with the plant", a.k);
        if b.sample.l == 1.0 {
            assert!(b.passed(), "{}", b.csv());
        }
    }
    assert!(sat.iter().any(|v| v.sample.l == small_l
        && v.criteria_failed().is_empty()
        && v.requirements_missed().contains(&Requirement::TorqueAccuracy)));
}

/// The shipped drive's 16 corner runs through to its top speed, on its own motor and on the
/// motor file `name` (a plant the drive does not model): the runs on the file's motor, each
/// checked to differ from its run on the drive's own; the file's extras checked by `has`.
fn on_plant(name: &str, has: impl Fn(&plant::Extras) -> bool) -> Vec<Verdict> {
    let path = format!("{}/../motors/{name}", env!("CARGO_MANIFEST_DIR"));
    let (motor, saturation) = drive_file::motor::load_model(&path).unwrap();
    let extras = hil_sim::scenario::extras_of(&drive_file::motor::load_plant_extras(&path).unwrap());
    assert!(has(&extras) && saturation.is_none(), "{name}");
    let mut c = shipped(16);
    c.duration_s = c.full_range_duration_s();
    let plain = run(&c);
    c.plant = Some(hil_sim::scenario::SimulatedMotor { motor, saturation, extras });
    let on = run(&c);
    for (a, b) in plain.iter().zip(&on) {
        assert_ne!(a.csv(), b.csv(), "run {} did not change with the plant", a.k);
    }
    on
}

/// Issue 50, deliverable 3: `hil-sim campaign --plant motors/delorenzo-deep-bar.toml` runs the
/// shipped drive on a deep-bar rotor (a second cage: at zero slip the file's circuit, its
/// resistance ×1.5 above an 86 Hz corner and its leakage lower — a plant the drive does not
/// model), over the box's corners through to its top speed: every run changes with the
/// plant and every run meets the file's requirements (docs/verification.md states the
/// figures).
#[test]
fn the_campaign_passes_on_a_deep_bar_plant() {
    for b in on_plant("delorenzo-deep-bar.toml", |e| e.deep_bar.is_some()) {
        assert!(b.passed(), "{}", b.csv());
    }
}

/// Issue 50's acceptance on a lossy plant: `hil-sim campaign --plant
/// motors/delorenzo-iron-loss.toml` runs the shipped drive on the appendix motor with 30 W
/// of core loss at its rated voltage (a resistance across the magnetizing branch, which the
/// drive does not model), over the box's corners through to its top speed: every run changes
/// with the plant and every run meets the file's requirements. The iron-loss current lies
/// along the air-gap voltage — the q axis at speed — so the rotor carries `i_q − i_fe`: the
/// torque's worst error (printed) is the requirement's margin; docs/verification.md states
/// where the loss starts to trip the drive.
#[test]
fn the_campaign_passes_on_an_iron_loss_plant() {
    let mut worst = 0.0f64;
    for b in on_plant("delorenzo-iron-loss.toml", |e| e.iron_loss_ohm.is_some()) {
        assert!(b.passed(), "{}", b.csv());
        worst = b
            .measures
            .iter()
            .filter(|m| m.requirement == Requirement::TorqueAccuracy)
            .fold(worst, |w, m| w.max(m.value));
    }
    println!("iron loss: worst torque error {worst:.4} of τ_max");
}

/// Issue 51's acceptance: the shipped drive meets the requirements its file states (the
/// campaign over the box, every corner through every manoeuvre), and the same file with the
/// speed gain at 0.02 — below the link's writable range, which starts at 0.04 for this reason
/// (`design certify`'s prediction over the writable gains) — is refused, naming the load-step
/// requirement. A saturated P droops τ_L/k_p under a load τ_L: the campaign's load step is
/// 0.8·τ_max = 1.6 N·m, so the dip is 1.6/0.02 = 80 rad/s, 0.41 of the 196 rad/s base speed,
/// against the 0.25 the file allows (the rotor reverses under a 45 rad/s reference). Each
/// load run's dip (the quantity the requirement names) lies within the first-order loop's
/// bounds: at most the droop `(τ_L ± B·ω*)/(k_p + B)` (+2 %: no overshoot), at least what
/// it reaches by the run's end — each half of a run lasts ≥ 1.2 × the 0.6 s rise time the
/// file allows, 1.48 time constants `J/(k_p + B)` on twice the inertia: 1 − e^−1.48 = 0.77 of
/// the droop, less what the speed estimate's window delays (0.75 measured): ≥ 0.7.
#[test]
fn the_shipped_requirements_hold_and_the_least_writable_gain_misses_the_load_step() {
    let ok = run(&shipped(64));
    let missed: Vec<String> = ok.iter().filter(|v| !v.passed()).map(Verdict::csv).collect();
    assert!(missed.is_empty(), "{missed:#?}");
    let text = drive_file::SHIPPED
        .replace("kp = 0.05, tau_max_nm = 2.0", "kp = 0.02, tau_max_nm = 2.0")
        .replace("speed_kp_writable = [0.04, 0.1]", "speed_kp_writable = [0.02, 0.1]");
    let f = drive_file::DriveFile::parse(std::path::Path::new("kp002.toml"), &text).unwrap();
    let c = Campaign { spec: f.spec, ..shipped(64) };
    let base = c.scales().base_speed_rad_s;
    let v = run(&c);
    for r in v.iter().filter(|v| v.manoeuvre != Manoeuvre::Reversal) {
        let dip = r.measures.iter().find(|m| m.requirement == Requirement::LoadDip).unwrap();
        let (kp, b, w) = (0.02, f.spec.motor.b_nms(), c.omega_s_rad_s());
        let droop = |sign: f64| (0.8 * 2.0 + sign * b * w) / (kp + b) / base;
        let (least, most) = (0.7 * droop(-1.0), 1.02 * droop(1.0));
        assert!(
            !dip.met() && dip.value >= least && dip.value <= most,
            "dip {} not in [{least}, {most}]: {}",
            dip.value,
            r.csv()
        );
        assert!(r.criteria_failed().is_empty(), "{}", r.csv());
    }
}

/// The speed law alone (`Campaign::predict`, the ideal actuator) predicts the campaign's
/// speed requirements: the P law's droop and dip within 10 % of what the whole drive does,
/// and the same verdict on drive.toml (met) and at k_p = 0.02 (the load dip missed).
#[test]
fn the_prediction_agrees_with_the_campaign_on_the_speed_requirements() {
    let c = shipped(64);
    let text = drive_file::SHIPPED
        .replace("kp = 0.05, tau_max_nm = 2.0", "kp = 0.02, tau_max_nm = 2.0")
        .replace("speed_kp_writable = [0.04, 0.1]", "speed_kp_writable = [0.02, 0.1]");
    let f = drive_file::DriveFile::parse(std::path::Path::new("kp002.toml"), &text).unwrap();
    let low = Campaign { spec: f.spec, ..shipped(64) };
    for c in [c, low] {
        let runs = run(&c);
        for v in runs.iter().filter(|v| v.manoeuvre != Manoeuvre::Reversal) {
            let p = c.predict(v.k).unwrap();
            for r in [Requirement::SpeedError, Requirement::LoadDip] {
                let (a, b) = (
                    v.measures.iter().find(|m| m.requirement == r).unwrap(),
                    p.iter().find(|m| m.requirement == r).unwrap(),
                );
                assert!(
                    (b.value / a.value - 1.0).abs() < 0.1,
                    "{r}: predicted {} measured {}: {}",
                    b.value,
                    a.value,
                    v.csv()
                );
                assert_eq!(a.met(), b.met(), "{r}: {}", v.csv());
            }
        }
    }
}

/// The sensorless drive's flying-start search at rest (issue 53): the campaign's corner run
/// 4 — a hot stator (R_s × 1.5) and a small inductance (L × 0.6), the rotor at rest — was
/// read as turning when the search used the window of the current's rise from zero (its
/// `L_σ·Δi` 40 % off), magnetized on that speed and tripped `FollowingError` at the start.
/// The search now leaves that window out; the run ends Running and passes.
#[test]
fn the_sensorless_search_does_not_read_a_rotor_at_rest_as_turning() {
    let mut c = shipped(1000);
    c.spec.speed_feedback = controller_core::drive::SpeedFeedback::Sensorless;
    let v = c.run_one(4, &AtomicBool::new(false)).unwrap();
    eprintln!("run 4 ({:?}): {:?}, failures {:?}", v.sample, v.mode, v.failures);
    assert_eq!(v.mode, controller_core::drive::Mode::Running);
    assert!(v.passed(), "{:?}", v.failures);
}

/// A hot motor accelerated from rest on the torque its bus gives (issue 49): the shipped
/// drive on its perturbed motor (`motors/delorenzo-perturbed.toml`) at 4 kHz, as `design
/// tune` writes it (synchronous-frame PI, saturated P), run to its top speed at the box's
/// corner of a hot stator and rotor in saturated iron (R_s × 1.5, R_r × 2, L × 0.6): on
/// the motor file's resistances the envelope gave the speed step τ_max = 2 N·m at
/// standstill, more than that machine takes on a 310 V bus, and the loops sat at the
/// modulator's limit until `LossOfControl` tripped 21 ms into the step (every manoeuvre of
/// the corner). On the resistances and inductance the magnetizing fit measured
/// (`EnvelopeConfig::identified`) it accelerates, and the run meets the requirements.
#[test]
fn a_hot_motor_accelerates_from_rest_on_the_torque_its_bus_gives() {
    let text = drive_file::SHIPPED
        .replace("frequency_hz = 20000.0", "frequency_hz = 4000.0")
        .replace("slow_divider = 10", "slow_divider = 2")
        .replace("rs_ohm = 16.2", "rs_ohm = 32.4")
        .replace("rr_ohm = 23.2", "rr_ohm = 46.4")
        .replace("ls_h = 1.44", "ls_h = 0.864")
        .replace("lr_h = 1.5", "lr_h = 0.9")
        .replace("lm_h = 1.42", "lm_h = 0.8378")
        .replace(
            "current = { kind = \"icad\" }",
            "current = { kind = \"pi\", kp = 107.45462915174929, ki = 92770.01315056415 }",
        )
        .replace("current_frame = \"stationary\"", "current_frame = \"synchronous\"")
        .replace("kp = 0.05, tau_max_nm = 2.0", "kp = 0.1303797293808807, tau_max_nm = 2.0")
        .replace(
            "speed_kp_writable = [0.04, 0.1]",
            "speed_kp_writable = [0.06518986469044034, 0.2607594587617614]",
        );
    let f = drive_file::DriveFile::parse(std::path::Path::new("perturbed-4k.toml"), &text).unwrap();
    assert_eq!(f.spec.pwm_frequency_hz, 4000.0);
    let mut c = Campaign {
        spec: f.spec,
        certify: f.certify.unwrap(),
        vdc_v: 310.0,
        duration_s: 1.0,
        runs: 64,
        seed: 1,
        shard: (0, 1),
        encoder_lines: f.encoder_lines(),
        plant: None,
        requirements: f.requirements,
    };
    c.duration_s = c.full_range_duration_s();
    let cancel = AtomicBool::new(false);
    for k in 12..16 {
        let v = c.run_one(k, &cancel).unwrap();
        let s = v.sample;
        assert_eq!((s.rs, s.rr, s.l), (1.5, 2.0, 0.6), "{}", v.csv());
        eprintln!("{}", v.csv());
        assert!(v.passed(), "{}", v.csv());
    }
}
