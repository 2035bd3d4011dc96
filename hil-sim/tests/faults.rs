//! Issue 18's fault-injection matrix (`hil_sim::faults`, `hil-sim faults`): single rows with
//! their measured quantities, and the judge failing what it must fail. The whole matrix runs
//! in `cargo xtask ci` (release: 114 rows in ≈ 0.9 s).
#![allow(clippy::unwrap_used, clippy::indexing_slicing, clippy::panic)]

use controller_core::drive::{Fault, Mode};
use hil_sim::faults::{Case, Expect, Matrix, OperatingPoint, Point};
use hil_sim::scenario::Builtin;
use hil_sim::sim::{Event, Injection};
use std::sync::atomic::AtomicBool;

fn shipped() -> Matrix {
    let d = drive_file::DriveFile::shipped().unwrap();
    let mut m = Matrix::new(d.spec, d.certify.unwrap().omega_r_max_rad_s, 310.0);
    let c = d.board.unwrap().table.comparator.unwrap();
    m.comparator = Some(hil_sim::bridge_fault::Comparator { trip_a: c.trip_a, filter_s: c.filter_s });
    m
}

fn case(m: &Matrix, name: &str) -> Case {
    m.cases().unwrap().into_iter().find(|c| c.name.starts_with(name)).unwrap()
}

fn point(m: &Matrix, p: Point, motoring: bool) -> OperatingPoint {
    m.points().into_iter().find(|o| o.point == p && o.motoring == motoring).unwrap()
}

/// An open lead at mid-speed: `OpenPhase` within the issue's 50 ms (two 2.5 ms windows),
/// the bridge off from the next period, the phase current far below the trip level.
#[test]
fn an_open_phase_row_measures_what_the_issue_names() {
    let m = shipped();
    let (c, at) = (case(&m, "open phase"), point(&m, Point::Mid, true));
    let o = m.run_one(1, &c, &at, m.expect(&c, &at), &AtomicBool::new(false)).unwrap();
    assert!(o.passed(), "{:?}", o.failures);
    let (f, t) = o.detected.unwrap();
    assert_eq!(f, Fault::OpenPhase);
    assert!((0.004..=0.010).contains(&t), "{t}");
    assert_eq!(o.off_after_periods, Some(0));
    assert!(o.peak_current_a < 0.5 * 8.0, "{}", o.peak_current_a);
    assert_eq!(o.final_mode, Mode::Fault(Fault::OpenPhase));
    assert!((o.speed_at_injection_rad_s - at.speed_rad_s).abs() < 15.0);
}

/// An open lead wherever its injection falls on the check's 2.5 ms windows (the matrix
/// injects on their grid), with three noise seeds, at all six points: `OpenPhase` within the
/// issue's 50 ms. Found by trying: at top speed, motoring, the reference shrinks below the
/// commanded level ≈ 5 ms after the lead opens; 0.6 ms off the grid two windows no longer
/// closed before that, and the check took 66.85 ms (seed 2). A phase whose reference is at
/// least half the others' (`OPEN_PHASE_REF_SHARE`) now stays judged (its current still below
/// 10 % of that reference).
#[test]
fn an_open_phase_is_caught_wherever_the_injection_falls_on_the_windows() {
    let mut m = shipped();
    let c = case(&m, "open phase");
    for delay_s in [0.6e-3, 1.3e-3] {
        m.inject_delay_s = delay_s;
        for at in m.points() {
            for seed in 0..3 {
                let o = m.run_one(seed, &c, &at, m.expect(&c, &at), &AtomicBool::new(false)).unwrap();
                assert!(o.passed(), "{} +{delay_s} s seed {seed}: {:?}", at.name(), o.failures);
                assert_eq!(o.detected.map(|(f, _)| f), Some(Fault::OpenPhase), "{} seed {seed}", at.name());
            }
        }
    }
}

/// The judge fails a drive that misses a fault: with the current-sum levels at the trip level
/// (so high that a dead sensor's error never reaches them), the dead-sensor row is not
/// detected as `CurrentSensor` within 10 ms.
#[test]
fn a_drive_that_misses_a_fault_fails_its_row() {
    let mut m = shipped();
    m.spec.protection.current_sum_max_a = 7.9;
    m.spec.protection.current_sum_mean_max_a = 7.9;
    let (c, at) = (case(&m, "sensor b dead"), point(&m, Point::Mid, true));
    let o = m.run_one(2, &c, &at, m.expect(&c, &at), &AtomicBool::new(false)).unwrap();
    assert!(!o.passed());
    assert_eq!(o.verdict(), "FAIL");
    assert!(o.detected.is_none_or(|(f, t)| f != Fault::CurrentSensor || t > 0.010), "{:?}", o.detected);
}

/// A stated gap that no longer holds fails the matrix (the list of gaps stays true): an
/// encoder glitch, which the drive catches, declared a gap.
#[test]
fn a_gap_that_closes_fails_its_row() {
    let m = shipped();
    let (c, at) = (case(&m, "encoder glitch"), point(&m, Point::Mid, false));
    let gap = Expect::Gap { fault: Fault::EncoderLoss, bound_s: 1e-3, why: "test", may_close: false };
    let o = m.run_one(3, &c, &at, gap, &AtomicBool::new(false)).unwrap();
    assert_eq!(o.detected.map(|(f, _)| f), Some(Fault::EncoderLoss));
    assert!(o.failures.iter().any(|f| f.contains("gap closed")), "{:?}", o.failures);
    // … and a ride-through that trips fails too.
    let o = m.run_one(3, &c, &at, Expect::RideThrough, &AtomicBool::new(false)).unwrap();
    assert!(o.failures.iter().any(|f| f.contains("tripped")), "{:?}", o.failures);
}

/// The stuck upper switch at mid-speed, motoring — a stated gap until the check weighed each
/// direction over its recent samples (`drive::SWITCH_WINDOWS`; two missed half-waves took a
/// whole electrical period, ≈ 77 ms there, and the voltage check named it
/// `EncoderImplausible`) — is `SwitchOpen` within the issue's 50 ms on the matrix's seeds
/// 0–11 (docs/protection.md: 10.5–46.0 ms, `OpenPhase` first on three of them), and the row
/// fails when nothing catches it (the stuck-switch and open-phase windows and the voltage
/// check out of the way): the bridge would keep switching.
#[test]
fn a_stuck_upper_switch_at_mid_speed_motoring_is_named_and_fails_uncaught() {
    let mut m = shipped();
    let (c, at) = (case(&m, "switch a upper stuck open"), point(&m, Point::Mid, true));
    let expect = m.expect(&c, &at);
    assert!(matches!(expect, Expect::Either { faults, .. } if faults.contains(&Fault::SwitchOpen)));
    for seed in [0, 3] {
        let o = m.run_one(seed, &c, &at, expect, &AtomicBool::new(false)).unwrap();
        assert!(o.passed(), "seed {seed}: {:?} {:?}", o.detected, o.failures);
        // The stuck-switch check's own `SwitchOpen`, or the voltage check's verdict first:
        // `OpenPhase` (a dead direction not yet answered is also an open lead's).
        let named = o.detected.map(|(f, _)| f);
        assert!(matches!(named, Some(Fault::SwitchOpen | Fault::OpenPhase)), "seed {seed}: {named:?}");
    }
    m.spec.protection.encoder_check_time_s = 1e6;
    m.spec.protection.open_phase_time_s = 1e6;
    m.spec.protection.saturation_time_s = 1e6;
    m.spec.protection.current_sum_max_a = 7.9;
    m.spec.protection.current_sum_mean_max_a = 7.9;
    let o = m.run_one(3, &c, &at, expect, &AtomicBool::new(false)).unwrap();
    assert_eq!(o.verdict(), "FAIL", "{:?} {:?}", o.detected, o.failures);
}

/// A switch stuck open at rest: the loops hold the voltage on the dead phase's axis, and
/// the voltage check names the phase (`drive::PINNED_PHASE_COS`), not the encoder — the
/// upper switch at rest both ways and the lower one at rest, motoring (before the rule:
/// `EncoderImplausible` 10–14 ms after the switch was first needed), each within the open
/// phase's 50 ms of its first use, the bridge off from the next period. Before the
/// reference reverses a dead switch and an open lead give the same currents: the rule
/// names `OpenPhase` (it named `SwitchOpen`, which misnamed an open lead at standstill,
/// generating, on seeds 6, 8 and 10), `SwitchOpen` when the stuck-switch check saw one
/// direction go missing first. With this test's sensor noise the lower switch's shunt may
/// read zero first (`CurrentSensor`, accepted by the row too).
#[test]
fn a_pinned_phase_is_named_a_bridge_fault_not_the_encoder() {
    let m = shipped();
    for (name, motoring) in [
        ("switch a upper stuck open", true),
        ("switch a upper stuck open", false),
        ("switch a lower stuck open", true),
    ] {
        let (c, at) = (case(&m, name), point(&m, Point::Standstill, motoring));
        let o = m.run_one(5, &c, &at, m.expect(&c, &at), &AtomicBool::new(false)).unwrap();
        assert!(o.passed(), "{name} {motoring}: {:?}", o.failures);
        let (f, t) = o.detected.unwrap();
        // The lower switch's shunt may read zero first (the sensors' noise decides): the
        // current-sum check's name, which the row accepts too.
        let named = if name.contains("upper") {
            &[Fault::SwitchOpen, Fault::OpenPhase][..]
        } else {
            &[Fault::SwitchOpen, Fault::OpenPhase, Fault::CurrentSensor]
        };
        assert!(named.contains(&f), "{name} {motoring}: {f:?}");
        let needed = o.acting_after_s.unwrap();
        assert!(t - needed <= 0.050, "{name} {motoring}: {t} s, needed from {needed} s");
        assert_eq!(o.off_after_periods, Some(0));
    }
}

/// An open lead at rest, generating: the loops pin the dead phase's axis and the voltage
/// check's rule trips first on some seeds — named `SwitchOpen` on seeds 6, 8 and 10 of the
/// matrix until the rule named the phase (`drive::PINNED_PHASE_COS`): an open lead is
/// `OpenPhase` on every one of the seeds 0–11, within the 50 ms.
#[test]
fn an_open_lead_at_rest_generating_is_an_open_phase_on_every_seed() {
    open_lead_on_seeds_0_to_11(Point::Standstill, false);
}

/// An open lead at top speed, motoring: the voltage regulator shrinks the references with
/// the fault (|i*| ≈ 0.09 A) and a tenth of the dead phase's own reference lay under its
/// sensor's noise: `OpenPhase` after 77 ms on seed 4 until the absent test took the
/// commanded level as its floor (`drive::OPEN_PHASE_ABSENT_FRACTION`); within the 50 ms on
/// every one of the seeds 0–11.
#[test]
fn an_open_lead_at_top_speed_motoring_is_an_open_phase_on_every_seed() {
    open_lead_on_seeds_0_to_11(Point::Top, true);
}

/// The matrix's open-lead row at `p` on seeds 0–11 (`hil-sim faults --seed`): `OpenPhase`
/// within its bound on each.
fn open_lead_on_seeds_0_to_11(p: Point, motoring: bool) {
    let mut m = shipped();
    let rows = m.rows().unwrap();
    let (k, c, at) = rows
        .into_iter()
        .find(|(_, c, at)| c.name.starts_with("open phase a") && at.point == p && at.motoring == motoring)
        .unwrap();
    for seed in 0..12 {
        m.seed = seed; // the row's sensors as in the matrix's run on that seed
        let o = m.run_one(k, &c, &at, m.expect(&c, &at), &AtomicBool::new(false)).unwrap();
        assert_eq!(o.detected.map(|(f, _)| f), Some(Fault::OpenPhase), "seed {seed}");
        assert!(o.passed(), "seed {seed}: {:?}", o.failures);
    }
}

/// A frozen encoder at top speed, generating, with the jump, speed and loss-of-control checks
/// out of the way (at mid-speed and motoring nothing then catches it within the row; since
/// the voltage regulator takes at most its target's worth of excess per period,
/// `drive::VOLTAGE_REGULATOR_EXCESS_MAX`, `LossOfControl` comes first here): the voltage check
/// catches it after its 10 ms, by the encoder's name: the applied voltage departs from the
/// model's along a vector that turns with the field, on no phase's axis for long (the
/// pinned-phase rule, `drive::PINNED_PHASE_COS`, must not rename it). The open-phase window
/// is out of the way too: its verdict on the currents the loops no longer hold at the
/// voltage limit, `OpenPhase` after 25.1 ms, comes a slow period before the voltage check's
/// twentieth implausible check in a row (its residual hovers at the level: one check at
/// 84.04 V against 84.12 V restarts the count about 10 ms before) — before the plan's delay
/// (issue 54) the voltage check's verdict came at 24.0 ms: a race, not a rule.
#[test]
fn a_frozen_encoder_at_speed_stays_the_encoders_fault() {
    let mut m = shipped();
    m.spec.protection.encoder_jump_rad = 1e6;
    m.spec.protection.stall_time_s = 1e6;
    m.spec.protection.following_time_s = 1e6;
    m.spec.protection.saturation_time_s = 1e6;
    m.spec.protection.open_phase_time_s = 1e3;
    let (c, at) = (case(&m, "encoder stuck"), point(&m, Point::Top, false));
    let o = m.run_one(6, &c, &at, Expect::RideThrough, &AtomicBool::new(false)).unwrap();
    let (f, t) = o.detected.unwrap();
    assert_eq!(f, Fault::EncoderImplausible);
    assert!((0.010..=0.030).contains(&t), "{t}");
}

/// An interrupt stops a row with an error (the CLI then writes nothing).
#[test]
fn an_interrupt_stops_the_matrix() {
    let m = shipped();
    let e = m.run(|_| {}, &AtomicBool::new(true)).unwrap_err();
    assert!(e.contains("interrupted"), "{e}");
}

/// A short between terminals a and b (20 µH, 0.05 Ω) at top speed: the leg current rises at
/// the pole-voltage difference over 20 µH, the board's comparator (12 A, 1 µs) breaks the
/// bridge within the period — the drive learns it at its next interrupt, `HardwareBreak`
/// one period after the injection — and the short's current dies through the diodes; the
/// motor's own phase currents do not move (the stiff legs feed it).
#[test]
fn a_terminal_short_breaks_the_bridge_through_the_comparator() {
    let m = shipped();
    let (c, at) = (case(&m, "short a–b"), point(&m, Point::Top, true));
    let o = m.run_one(4, &c, &at, m.expect(&c, &at), &AtomicBool::new(false)).unwrap();
    assert!(o.passed(), "{:?}", o.failures);
    let (f, t) = o.detected.unwrap();
    assert_eq!(f, Fault::HardwareBreak);
    assert!((t - 5e-5).abs() < 1e-9, "one PWM period: {t}");
    // Above the comparator's level, by at most the rise at the whole bus over 20 µH during
    // 1.5 filter time constants (the first-order filter lags a ramp by one).
    let rise_a = 310.0 / 20e-6 * 1.5e-6;
    assert!(o.peak_leg_a > 12.0 && o.peak_leg_a < 12.0 + rise_a, "{}", o.peak_leg_a);
    assert!(o.peak_current_a < 1.0, "{}", o.peak_current_a);
}

/// A switch stuck open (phase a's upper one) at top speed, motoring and generating, on the
/// sensors' noise seeds 0–11: the phase follows its reference in one direction only, and
/// each run is named a bridge fault within four turns of the rotor, the bridge off from the
/// next period. Until the reference reverses, an open lead and a switch stuck open in the
/// direction needed carry the same currents: the open-phase window's two-window verdict
/// (`OpenPhase`, which the matrix accepts for a stuck switch) and the stuck-switch check's
/// (`SwitchOpen`) race, and at top speed two windows are half an electrical period. The
/// stuck switch's dead half-wave carries a little through the opposite diode, so the
/// window seldom holds it absent for two windows: the stuck-switch check names most of
/// them (main, the plan adopted at its tick: 24 of 24; with the plan adopted a plan's
/// delay after its tick: 21 of 24). A `SwitchOpen` comes no sooner than the dead direction
/// can be judged: more than three quarters of its weighted samples missed
/// (`drive::SWITCH_MISSING_SHARE`), at least ln 0.25 / ln(1 − g) ≈ 6.2 slow periods (3.1 ms)
/// after the switch was first needed, g the weight of a sample at a 2.5 ms window. (Before
/// the check: `OpenPhase` after 407–492 ms or nothing; with two missed half-waves, 29–46 ms.)
/// Waiting for the reversal before the window's verdict names all 24 `SwitchOpen` but an
/// open lead 14.5–37 ms after it opens instead of 7–12 ms: the branch that tried it is in
/// docs/decisions.md.
#[test]
fn a_switch_stuck_open_at_top_speed_is_named() {
    let m = shipped();
    let case = Case {
        name: "switch a upper open",
        injection: hil_sim::sim::Injection::SwitchOpen { phase: 0, upper: true },
    };
    let (mut runs, mut switch_open) = (0, 0);
    for motoring in [true, false] {
        let at = point(&m, Point::Top, motoring);
        let period_s = std::f64::consts::TAU / at.speed_rad_s;
        for seed in 0..12 {
            let expect = Expect::Fault { fault: Fault::SwitchOpen, bound_s: 4.0 * period_s };
            let o = m.run_one(seed, &case, &at, expect, &AtomicBool::new(false)).unwrap();
            eprintln!("{} seed {seed}: {} (bound {:.1} ms)", at.name(), o.seen(), 4e3 * period_s);
            let needed = o.acting_after_s.unwrap();
            let named = o.detected.filter(|(f, _)| matches!(f, Fault::SwitchOpen | Fault::OpenPhase));
            let Some((fault, t)) = named else { panic!("{} seed {seed}: {}", at.name(), o.seen()) };
            assert!(t - needed <= 4.0 * period_s, "{} seed {seed}: {}", at.name(), o.seen());
            assert_eq!(o.off_after_periods, Some(0), "{} seed {seed}", at.name());
            if fault == Fault::SwitchOpen {
                assert!(t - needed >= 3.0e-3, "{} seed {seed}: {t} s, needed from {needed} s", at.name());
                switch_open += 1;
            }
            runs += 1;
        }
    }
    assert!(2 * switch_open > runs, "SwitchOpen in {switch_open} of {runs} runs");
}

/// Each of the six switches stuck open at the matrix's six points: what the drive names it
/// and when (docs/protection.md's list; not yet matrix rows). Run with `cargo test --release
/// -p hil-sim --test faults -- --ignored --nocapture stuck_switches`; the sensors' noise seed
/// is 7, or `SURVEY_SEED`'s.
#[test]
#[ignore = "prints a table for the docs (36 runs)"]
fn stuck_switches_at_every_point() {
    let m = shipped();
    let seed = std::env::var("SURVEY_SEED").map_or(7, |s| s.parse().unwrap());
    for phase in 0..3 {
        for upper in [true, false] {
            let case =
                Case { name: "switch open", injection: hil_sim::sim::Injection::SwitchOpen { phase, upper } };
            for at in m.points() {
                let o = m.run_one(seed, &case, &at, Expect::RideThrough, &AtomicBool::new(false)).unwrap();
                println!(
                    "phase {} {} switch, {:22}: {:36} peak {:.2} A",
                    ["a", "b", "c"][phase],
                    if upper { "upper" } else { "lower" },
                    at.name(),
                    o.seen(),
                    o.peak_current_a
                );
            }
        }
    }
}

/// The markdown's list of gaps names the operating points each holds at (it said "at
/// standstill" for every gap, the top-speed overload's included — a gap since closed, by
/// the following check's motoring rule: found by reading it).
#[test]
fn the_gap_list_names_its_operating_points() {
    let m = shipped();
    let (c, at) = (case(&m, "encoder stuck"), point(&m, Point::Standstill, true));
    let o = m.run_one(6, &c, &at, m.expect(&c, &at), &AtomicBool::new(false)).unwrap();
    assert_eq!(o.verdict(), "gap");
    let md = hil_sim::faults::markdown(&m, &[o]);
    assert!(md.contains("- **encoder stuck** (standstill motoring): "), "{md}");
    assert!(!md.contains("at standstill:"), "{md}");
}

fn drive_file(name: &str, vdc_v: f64) -> Matrix {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(name);
    let d = drive_file::DriveFile::load(&path).unwrap();
    Matrix::new(d.spec, d.certify.unwrap().omega_r_max_rad_s, vdc_v)
}

/// The matrix's times come from the drive: the shipped drive keeps 0.25 s and 2.5 s (its
/// rotor magnetizes in 1.25 × T_r·ln 20 = 0.24 s, its slowest point settles within 1.72 s
/// on the ideal loop); the 3 300 V drive's rotor (T_r 0.78 s) would still be magnetizing
/// at 0.25 s — its standstill hold drifted to 58 rad/s under a load that came with the
/// torque held at zero —, so its reference waits 1.25 × T_r·ln 20 and its injection the
/// slowest point's settling time more, plus half a second.
#[test]
fn the_matrix_times_each_drive_from_its_rotor_and_its_speed_law() {
    let m = shipped();
    assert_eq!((m.reference_s(), m.inject_s()), (0.25, 2.5));
    let k = drive_file("drives/krause-3300v.toml", 3300.0);
    let magnetizing_s = 1.25 * k.spec.motor.tr_s() * 20f64.ln();
    assert!(magnetizing_s > 1.0, "{magnetizing_s}");
    assert!((k.reference_s() - magnetizing_s).abs() < 1e-12, "{}", k.reference_s());
    let settle_s = k.points().iter().map(|p| k.approach(p).unwrap().settle_s).fold(0.0, f64::max);
    assert!(settle_s > 1.0, "{settle_s}");
    assert!((k.inject_s() - (magnetizing_s + settle_s + 0.5)).abs() < 1e-12, "{}", k.inject_s());
}

/// A point the drive has not reached at the injection is a failed row with its reason —
/// the whole matrix used to stop at it. Here the shipped drive's mid-speed fault comes
/// 0.1 s after its reference, while it still accelerates.
#[test]
fn a_point_not_reached_is_a_failed_row() {
    let mut m = shipped();
    m.inject_delay_s = 0.35 - m.inject_s();
    let (c, at) = (case(&m, "encoder glitch"), point(&m, Point::Mid, true));
    let o = m.run_one(1, &c, &at, m.expect(&c, &at), &AtomicBool::new(false)).unwrap();
    assert_eq!(o.verdict(), "FAIL");
    assert!(o.failures[0].starts_with("the operating point was not reached"), "{:?}", o.failures);
    assert!(o.speed_at_injection_rad_s < 0.5 * at.speed_rad_s, "{}", o.speed_at_injection_rad_s);
}

/// The bus and sensor cases are the drive's levels: the shipped drive's (sag to 150 V,
/// surge to 450 V from its 200/400 V limits, a sensor stuck at 1 A or drifting by 0.5 A of
/// its 8 A trip level) and the 24 V drive's, which "sag to 150 V" would have overvolted.
#[test]
fn the_bus_and_sensor_cases_scale_with_the_drive() {
    let titles = |m: &Matrix| -> Vec<String> { m.cases().unwrap().iter().map(Case::title).collect() };
    let shipped = titles(&shipped());
    for t in ["bus sag to 150 V", "bus surge to 450 V", "sensor b stuck at 1 A", "sensor b offset +0.5 A"] {
        assert!(shipped.iter().any(|s| s == t), "{t} in {shipped:?}");
    }
    let small = titles(&drive_file("drives/em-synergy-24v.toml", 24.0));
    for t in ["bus sag to 14 V", "bus surge to 34 V"] {
        assert!(small.iter().any(|s| s == t), "{t} in {small:?}");
    }
}

/// A rotor seized at mid-speed under the 24 V drive's soft speed law (0.001 N·m per rad/s,
/// τ_max 0.12 N·m: saturated only 120 rad/s below its reference) ran on, Running, with no
/// trip: the stall check asked for the loop at its limit. Now a speed reference well above
/// "not moving" counts: `Stall` within the issue's 0.5 s (`drive::STALL_REFERENCE_FACTOR`).
#[test]
fn a_seized_rotor_under_a_soft_speed_law_is_a_stall() {
    let m = drive_file("drives/em-synergy-24v.toml", 24.0);
    let (c, at) = (case(&m, "load seizure"), point(&m, Point::Mid, true));
    let o = m.run_one(1, &c, &at, m.expect(&c, &at), &AtomicBool::new(false)).unwrap();
    assert!(o.passed(), "{:?}", o.failures);
    // The point is where that law settles under the quarter load on the ideal loop (65.3
    // of 108.6 rad/s): within 1 rad/s of it, 43 rad/s below the reference the matrix once
    // judged it against.
    let settles = m.approach(&at).unwrap().final_rad_s;
    assert!(
        (o.speed_at_injection_rad_s - settles).abs() < 1.0,
        "{} vs {settles}",
        o.speed_at_injection_rad_s
    );
    assert!(at.speed_rad_s - o.speed_at_injection_rad_s > 40.0, "{}", o.speed_at_injection_rad_s);
    let (f, t) = o.detected.unwrap();
    assert_eq!(f, Fault::Stall);
    assert!(t <= 0.5, "{t}");
    // A position hold under its load asks that law for 30 rad/s with the rotor rightly at
    // rest: no stall (the speed reference of a position hold does not count).
    let (c, at) = (case(&m, "R_r step"), point(&m, Point::Standstill, true));
    let o = m.run_one(2, &c, &at, m.expect(&c, &at), &AtomicBool::new(false)).unwrap();
    assert!(o.passed(), "{:?}", o.failures);
}

/// The 24 V drive's 1.5 × τ_max overload while generating at top speed was "not detected":
/// the drive braked with 0.098 of its 0.12 N·m and the motor's friction took the rest, so
/// the motor settled 35 % over its reference — a droop, not a runaway. The matrix's
/// generating overload now carries the friction at the overspeed level too (b·ω_overspeed):
/// no speed below overspeed holds it, and the following check names it within issue 18's
/// 0.5 s.
#[test]
fn a_generating_overload_is_a_runaway_beyond_the_motors_friction() {
    let m = drive_file("drives/em-synergy-24v.toml", 24.0);
    let c = case(&m, "overload");
    let at = point(&m, Point::Top, false);
    let Builtin { scenario, .. } = m.scenario(5, &c, &at);
    let tau_max = hil_sim::campaign::torque_limit_nm(&m.spec);
    let friction = m.spec.motor.b_nms() * m.spec.protection.overspeed_rad_s;
    let load = scenario.events.iter().find_map(|(_, e)| match e {
        Event::Fault(Injection::LoadStep { torque_nm }) => Some(*torque_nm),
        _ => None,
    });
    let expected = (1.5 * tau_max + friction).copysign(at.load_nm);
    assert!(load.is_some_and(|l| (l - expected).abs() < 1e-12), "{load:?} vs {expected}");
    let o = m.run_one(5, &c, &at, m.expect(&c, &at), &AtomicBool::new(false)).unwrap();
    assert!(o.passed(), "{:?}", o.failures);
    let (f, t) = o.detected.unwrap();
    assert!(matches!(f, Fault::FollowingError | Fault::Overspeed), "{f:?}");
    assert!(t <= 0.5, "{t}");
}

/// An overload's bound runs past issue 18's 0.5 s only for a speed law slower than that to
/// reach its limit (`Matrix::overload_reach_s`, on the ideal loop; `-- --nocapture` prints
/// it): the shipped drive's law reaches its limit within 0.13 s at every point (15 ms at top speed motoring, 124.5 ms
/// generating there), and its six overload rows keep 0.5 s; the law reaches its limit
/// sooner under twice the overload.
#[test]
fn an_overloads_bound_is_the_issues_unless_the_law_is_slower_to_its_limit() {
    let m = shipped();
    let c = case(&m, "overload");
    let tau_max = hil_sim::campaign::torque_limit_nm(&m.spec);
    for p in [Point::Standstill, Point::Mid, Point::Top] {
        for motoring in [true, false] {
            let at = point(&m, p, motoring);
            match m.expect(&c, &at) {
                Expect::Either { bound_s, .. } => assert_eq!(bound_s, 0.5, "{p:?} {motoring}"),
                e => panic!("{e:?}"),
            }
            let load = |k: f64| k * tau_max * at.load_nm.signum();
            let (reach_s, _) = m.overload_reach_s(&at, load(1.5)).unwrap();
            let (sooner_s, _) = m.overload_reach_s(&at, load(3.0)).unwrap();
            eprintln!(
                "overload at {p:?}, motoring {motoring}: the law at its limit after {reach_s:.4} s ({sooner_s:.4} s at 3 × τ_max)"
            );
            assert!(reach_s < 0.25 && sooner_s <= reach_s, "{p:?} {motoring}: {reach_s} {sooner_s}");
        }
    }
}

/// The 24 V drive's upper switch of phase a stuck open at standstill: the loops pin phase a
/// at its duty limit (and b at 0) while its reference still rises through 38 % of the
/// magnitude, below the stuck-switch check's level, and the voltage check's verdict came
/// first — `EncoderImplausible` 16 ms after the switch was first needed. The verdict now
/// asks whether the loops drive every phase (`drive::UNDRIVEN_REFERENCE_SHARE`): `OpenPhase`
/// (no current in a commanded phase; an open lead gives the same currents until the
/// reference reverses), at the same time, within the issue's 50 ms. (A frozen encoder keeps
/// its name: `a_frozen_encoder_at_speed_stays_the_encoders_fault`.)
#[test]
fn a_stuck_switch_at_standstill_is_named_by_the_phase_the_loops_cannot_drive() {
    let m = drive_file("drives/em-synergy-24v.toml", 24.0);
    let (k, c, at) = m
        .rows()
        .unwrap()
        .into_iter()
        .find(|(_, c, at)| {
            c.title() == "switch a upper stuck open" && at.point == Point::Standstill && at.motoring
        })
        .unwrap();
    let o = m.run_one(k, &c, &at, m.expect(&c, &at), &AtomicBool::new(false)).unwrap();
    assert!(o.passed(), "{:?}", o.failures);
    let (f, t) = o.detected.unwrap();
    assert_eq!(f, Fault::OpenPhase);
    assert!(t - o.acting_after_s.unwrap() <= 0.05, "{t} {:?}", o.acting_after_s);
}

/// A gain error on a phase near its zero crossing makes no error until its current grows:
/// on seed 4 the matrix's sensor-b gain of 0.5 at standstill struck with phase b's current
/// crossing zero, and `CurrentSensor` came 24.6 ms after the injection — a failure against
/// the issue's 10 ms from the injection. The bound runs, as a stuck switch's does from its
/// first use, from when the sensors' error — all three channels' sum on the true currents —
/// came clear of the current-sum check's windowed level by the check's resolution and
/// stayed so for a whole window (`hil_sim::faults::SENSOR_VERDICT_SIGMAS`); this one never
/// did before the check named it, which passes by its name. A sensor fault of constant
/// error (an offset, stuck at a value the current is not at) acts as soon as it lifts the
/// window's mean clear of the level.
#[test]
fn a_sensor_gain_error_is_judged_from_when_its_error_comes_clear_of_the_checks_level() {
    let mut m = shipped();
    m.seed = 4;
    let (k, c, at) = m
        .rows()
        .unwrap()
        .into_iter()
        .find(|(_, c, at)| c.name == "sensor b gain 0.5" && at.point == Point::Standstill && at.motoring)
        .unwrap();
    let o = m.run_one(k, &c, &at, m.expect(&c, &at), &AtomicBool::new(false)).unwrap();
    let (f, t) = o.detected.unwrap();
    assert_eq!(f, Fault::CurrentSensor);
    // Later than the issue's 10 ms from the injection: a bound from there fails the row.
    assert!(t > 0.010, "{t}");
    if let Some(acting) = o.acting_after_s {
        assert!(t - acting <= 0.010, "{t} - {acting}");
    }
    assert!(o.passed(), "{:?}", o.failures);
    // An offset acts from the injection.
    let (k, c, at) = m
        .rows()
        .unwrap()
        .into_iter()
        .find(|(_, c, at)| c.name == "sensor b offset" && at.point == Point::Standstill && at.motoring)
        .unwrap();
    let o = m.run_one(k, &c, &at, m.expect(&c, &at), &AtomicBool::new(false)).unwrap();
    // … as soon as it lifts the window's mean clear of the level: its 0.5 A against 0.1 A,
    // the currents' share and the 24 mA resolution (≈ 0.15 A), within 30 % of the window
    // (0.65 ms of 2.5).
    let acting = o.acting_after_s.unwrap();
    assert!(acting <= 0.3 * m.spec.protection.open_phase_time_s, "{acting}");
    assert!(o.passed(), "{:?}", o.failures);
}

/// The matrix's encoder is the board's too, and its wrong-line-count row injects half the
/// board's lines: on a 512-line board "encoder 512 lines (1024 set)" injected no change
/// and passed (found by trying).
#[test]
fn the_wrong_line_count_row_halves_the_boards_lines() {
    let mut m = shipped();
    m.encoder_lines = 512;
    let c = case(&m, "encoder at half its lines");
    assert_eq!(c.title(), "encoder 256 lines (512 set)");
    let at = point(&m, Point::Mid, true);
    let o = m.run_one(3, &c, &at, m.expect(&c, &at), &AtomicBool::new(false)).unwrap();
    assert!(o.passed(), "{:?}", o.failures);
    assert_eq!(o.detected.map(|(f, _)| f), Some(Fault::EncoderLoss));
}

/// The 500 hp machine tuned by `design tune` on its 3 300 V template with stationary-frame
/// loops (PI, kp 55.5 V/A) rides to its top-speed points, motoring and generating, and names the frozen
/// encoder there. Until this stop all 38 of its top-speed rows tripped a false `SwitchOpen`
/// before their injection (at 3.9–4.2 s, ≈ 160–195 rad/s): its flux fell with T_r = 0.78 s
/// behind the envelope's (fixed by `drive::FLUX_FALL_TIME_S`), and the stuck-switch check
/// judged the currents against the *trimmed* references — the intended ones plus the
/// current trim, which makes up a stationary-frame PI's steady error (≈ E/kp: 27 A of a
/// ≈ 1 500 V back-EMF at top speed) and so exceeds what the currents, rightly, carry. The
/// check now reads the intended references (its undriven count, the voltage check's verdict,
/// and the open-phase window keep the trimmed ones: what the loops push for).
#[test]
fn the_tuned_3300_v_drive_reaches_its_top_speed_points() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let template = root.join("drives/krause-3300v.toml");
    let motor =
        drive_file::motor::load(root.join("motors/krause-2300v-500hp.toml").to_str().unwrap()).unwrap();
    // Stationary-frame loops (the template's are synchronous, as seed 000's: there the trim
    // is zero and the intended and trimmed references are one).
    let text = std::fs::read_to_string(&template)
        .unwrap()
        .replace("current_frame = \"synchronous\"", "current_frame = \"stationary\"");
    let tuned =
        design::tune::tune(&template, &text, &motor, None, design::tune::Structure::default()).unwrap();
    assert_eq!(tuned.spec.current_frame, controller_core::drive::CurrentFrame::Stationary);
    let file = drive_file::DriveFile::parse(&template, &tuned.text).unwrap();
    let m = Matrix::of_file(&file, tuned.certify.omega_r_max_rad_s, 3300.0);
    let c = case(&m, "encoder stuck");
    for motoring in [true, false] {
        let at = point(&m, Point::Top, motoring);
        let o = m.run_one(0, &c, &at, m.expect(&c, &at), &AtomicBool::new(false)).unwrap();
        eprintln!("{}: {} at {:.1} rad/s", at.name(), o.seen(), o.speed_at_injection_rad_s);
        assert!(o.passed(), "{}: {:?}", at.name(), o.failures);
    }
}

/// An open lead at rest may be named `NoMotorCurrent`: the vector stands where the hold left
/// it, and along the open phase's axis the other two phases are asked equal currents, which
/// the open lead holds at zero between them (a 270 W 34 V member of the population, issue
/// 49). At speed the vector turns through every phase: `OpenPhase` only.
#[test]
fn an_open_lead_at_rest_may_be_named_no_motor_current() {
    let m = shipped();
    let c = case(&m, "open phase");
    for motoring in [true, false] {
        let rest = m.expect(&c, &point(&m, Point::Standstill, motoring));
        assert!(
            matches!(rest, Expect::Either { faults, .. } if faults == [Fault::OpenPhase, Fault::NoMotorCurrent]),
            "{rest:?}"
        );
        for p in [Point::Mid, Point::Top] {
            let e = m.expect(&c, &point(&m, p, motoring));
            assert!(matches!(e, Expect::Fault { fault: Fault::OpenPhase, .. }), "{e:?}");
        }
    }
}

/// A stuck switch's bound runs from the first peak of its dead direction after the
/// injection (`dead_peak_after_s`): the reference vector's angle at the injection and the
/// field's turn, measured on the references before it. At mid-speed (81 rad/s, one pole
/// pair: ω_e ≈ 81 rad/s plus the slip) that adds at most one turn; at rest, where the field
/// turns at the slip frequency only, at most the observation (`OBSERVE_S`).
#[test]
fn a_stuck_switchs_bound_runs_from_its_directions_peak() {
    use hil_sim::faults::{OBSERVE_S, OPEN_PHASE_BOUND_S, dead_peak_after_s};
    use std::f64::consts::{FRAC_PI_2, PI, TAU};
    let close = |a: f64, b: f64| (a - b).abs() < 1e-12;
    // Phase a's upper switch: its peak at θ = 0, a quarter turn ahead of −π/2.
    assert!(close(dead_peak_after_s(0, true, -FRAC_PI_2, 100.0), FRAC_PI_2 / 100.0));
    // Just past the peak: the next one is (almost) a whole turn away.
    assert!(close(dead_peak_after_s(0, true, 0.1, 100.0), (TAU - 0.1) / 100.0));
    // The field turning the other way reaches it from the other side.
    assert!(close(dead_peak_after_s(0, true, -FRAC_PI_2, -100.0), 1.5 * PI / 100.0));
    // The lower switch's peak is at π; phase b's upper at 2π/3.
    assert!(close(dead_peak_after_s(0, false, 0.0, 100.0), PI / 100.0));
    assert!(close(dead_peak_after_s(1, true, 0.0, 100.0), TAU / 3.0 / 100.0));
    assert!(dead_peak_after_s(0, true, 0.0, 0.0).is_infinite());
    assert!(dead_peak_after_s(0, true, f64::NAN, 100.0).is_infinite());
    let m = shipped();
    let c = case(&m, "switch a upper stuck open");
    let bound = |p: Point| {
        let at = point(&m, p, true);
        let o = m.run_one(1, &c, &at, m.expect(&c, &at), &AtomicBool::new(false)).unwrap();
        match o.expect {
            Expect::Either { bound_s, .. } => bound_s - OPEN_PHASE_BOUND_S,
            e => panic!("{e:?}"),
        }
    };
    let mid = bound(Point::Mid);
    assert!((0.0..=TAU / 81.0).contains(&mid), "{mid} s");
    let rest = bound(Point::Standstill);
    assert!(rest > 0.1 && rest <= OBSERVE_S, "{rest} s");
}

/// An open lead's bound runs from the first moment after the injection that its phase is
/// asked for half the reference vector's magnitude, either way (`phase_asked_after_s`, the
/// level from which the phase checks count a sample): at once within 60° of a peak; from a
/// zero crossing, 30° of the field's turn later, in either direction of turning.
#[test]
fn an_open_leads_bound_runs_from_when_its_phase_is_asked() {
    use hil_sim::faults::phase_asked_after_s;
    use std::f64::consts::{FRAC_PI_2, FRAC_PI_6, PI, TAU};
    let close = |a: f64, b: f64| (a - b).abs() < 1e-12;
    // Phase a at its positive peak, at its negative one, 59° past: asked at once.
    for theta in [0.0, PI, 59f64.to_radians(), -2.2] {
        assert_eq!(phase_asked_after_s(0, theta, 100.0), 0.0, "{theta}");
    }
    // At its zero crossing (θ = π/2): 30° of turn to −½ (forward) or to +½ (backward).
    assert!(close(phase_asked_after_s(0, FRAC_PI_2, 100.0), FRAC_PI_6 / 100.0));
    assert!(close(phase_asked_after_s(0, FRAC_PI_2, -100.0), FRAC_PI_6 / 100.0));
    // 70° past phase a's peak, turning forward: 50° to go; backward: 10°.
    let seventy = 70f64.to_radians();
    assert!(close(phase_asked_after_s(0, seventy, 10.0), 50f64.to_radians() / 10.0));
    assert!(close(phase_asked_after_s(0, seventy, -10.0), 10f64.to_radians() / 10.0));
    // Phase b's zero crossing is a third of a turn on.
    assert!(close(phase_asked_after_s(1, FRAC_PI_2 + TAU / 3.0, 100.0), FRAC_PI_6 / 100.0));
    assert!(phase_asked_after_s(0, FRAC_PI_2, 0.0).is_infinite());
    assert!(phase_asked_after_s(0, f64::NAN, 100.0).is_infinite());
}

/// Found on the population: the shipped DeLorenzo motor tuned at 4 kHz, its phase a's upper
/// switch stuck open at mid-speed generating, injected at the end of the positive half-wave.
/// The bound ran from that first need plus a quarter turn — the peak the switch had carried
/// while healthy — and the row failed at 69 ms against 64 ms; the check names the switch 15
/// ms after the first peak the switch misses, and the row passes.
#[test]
fn a_stuck_switch_injected_past_its_peak_is_judged_from_the_next_one() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let text = std::fs::read_to_string(root.join("drive.toml")).unwrap();
    let text = text
        .replace("frequency_hz = 20000.0", "frequency_hz = 4000.0")
        .replace("slow_divider = 10", "slow_divider = 2");
    let motor = drive_file::motor::load("delorenzo-appendix").unwrap();
    let structure = design::tune::Structure {
        current: design::tune::CurrentDesign::Pi,
        speed: design::tune::SpeedDesign::Auto,
    };
    let tuned =
        design::tune::tune(std::path::Path::new("drive-4khz.toml"), &text, &motor, None, structure).unwrap();
    let d = drive_file::DriveFile::parse(std::path::Path::new("drive-4khz.toml"), &tuned.text).unwrap();
    let mut m = Matrix::new(d.spec, d.certify.unwrap().omega_r_max_rad_s, 310.0);
    let c = d.board.unwrap().table.comparator.unwrap();
    m.comparator = Some(hil_sim::bridge_fault::Comparator { trip_a: c.trip_a, filter_s: c.filter_s });
    let (c, at) = (case(&m, "switch a upper stuck open"), point(&m, Point::Mid, false));
    let o = m.run_one(1, &c, &at, m.expect(&c, &at), &AtomicBool::new(false)).unwrap();
    assert!(o.passed(), "{:?}", o.failures);
    let (f, t) = o.detected.unwrap();
    // Either name, as the matrix's row expects: until the reference reverses, the dead switch
    // and an open lead give the same currents, and which of the two checks concludes first is
    // decided within a slow period here — the current loops' anti-windup moves it (tracking:
    // `SwitchOpen` at 69.5 ms; back-calculation: `OpenPhase` at 61 ms).
    assert!(matches!(f, Fault::SwitchOpen | Fault::OpenPhase), "{f:?}");
    // The row's bound runs from the next peak: past the old one, the first need plus a
    // quarter turn at the field's speed (one pole pair, the slip on top only makes the
    // quarter shorter) plus 50 ms — which the switch's name at 69.5 ms overran.
    let quarter = std::f64::consts::FRAC_PI_2 / o.speed_at_injection_rad_s.abs();
    let acting = o.acting_after_s.unwrap();
    let Expect::Either { bound_s, .. } = o.expect else { panic!("{:?}", o.expect) };
    let old = acting + quarter + hil_sim::faults::OPEN_PHASE_BOUND_S;
    assert!(bound_s > old + 0.015, "bound {bound_s} s, old {old} s");
    assert!(t <= bound_s, "{t} s");
}

/// The shipped drive on a plant richer than its model (`hil-sim faults --plant
/// delorenzo-saturating`: the same motor with a magnetizing branch that saturates, the
/// drive's model linear): the rows where the model's error acts — the plant's parameter
/// steps and the overloads, at top speed in field weakening, where the branch runs far
/// below its knee at 1.38× its rated inductance — pass as on the linear plant. The whole
/// matrix passes there too (110 pass, 4 stated gaps: `hil-sim faults drive.toml --plant
/// delorenzo-saturating`, docs/verification.md).
#[test]
fn the_shipped_drive_passes_its_matrix_rows_on_a_saturating_plant() {
    let mut m = shipped();
    let (motor, saturation) = drive_file::motor::load_model("delorenzo-saturating").unwrap();
    assert!(saturation.is_some());
    m.plant = Some(hil_sim::scenario::SimulatedMotor { motor, saturation, extras: plant::Extras::default() });
    for name in ["R_r step", "L_m step", "overload"] {
        for motoring in [true, false] {
            let (c, at) = (case(&m, name), point(&m, Point::Top, motoring));
            let o = m.run_one(7, &c, &at, m.expect(&c, &at), &AtomicBool::new(false)).unwrap();
            assert!(o.passed(), "{name} motoring {motoring}: {:?}", o.failures);
        }
    }
    // The run is on the saturating plant: the same row on the drive's own model differs.
    let (c, at) = (case(&m, "R_r step"), point(&m, Point::Top, true));
    let sat = m.run_one(7, &c, &at, m.expect(&c, &at), &AtomicBool::new(false)).unwrap();
    m.plant = None;
    let lin = m.run_one(7, &c, &at, m.expect(&c, &at), &AtomicBool::new(false)).unwrap();
    assert!(
        (sat.peak_current_a - lin.peak_current_a).abs() > 1e-3,
        "{} vs {}",
        sat.peak_current_a,
        lin.peak_current_a
    );
}

/// A sensorless drive (drive.toml with `speed_feedback = "sensorless"`) has no encoder: its
/// matrix has no encoder rows, and no row ends in an encoder fault — the observer's estimate
/// is not judged as an encoder (an open phase was named `EncoderLoss` when it was: its
/// estimate jumped). Found by running the matrix sensorless (issue 53).
#[test]
fn a_sensorless_drive_has_no_encoder_to_fail() {
    let mut m = shipped();
    m.spec.speed_feedback = controller_core::drive::SpeedFeedback::Sensorless;
    assert!(m.cases().unwrap().iter().all(|c| !c.injection.is_encoders()));
    assert!(shipped().cases().unwrap().iter().any(|c| c.injection.is_encoders()));
    let outcomes = m.run(|_| {}, &AtomicBool::new(false)).unwrap();
    for o in &outcomes {
        assert!(
            !matches!(o.final_mode, Mode::Fault(Fault::EncoderLoss | Fault::EncoderImplausible)),
            "{} at {:?}: {:?}",
            o.case.name,
            o.at.point,
            o.final_mode
        );
    }
}

/// Encoder-loss ride-through (issue 53): drive.toml with the observer beside its encoder
/// (`speed_feedback = "encoder_ride_through"`). Every encoder row at speed — stuck, a
/// 100-count glitch, half the lines; mid and top speed, motoring and generating — carries on
/// on the observer: no trip, the fault reported within the encoder bound (two slow periods),
/// the speed held to the end of the run ([`Expect::Reported`]). At standstill (a position
/// hold, which needs the shaft's angle) they are what they are without the observer.
#[test]
fn the_frozen_encoder_rows_at_speed_carry_on_on_the_observer() {
    let mut m = shipped();
    m.spec.speed_feedback = controller_core::drive::SpeedFeedback::EncoderRideThrough;
    let encoders: Vec<_> = m.cases().unwrap().into_iter().filter(|c| c.injection.is_encoders()).collect();
    assert_eq!(encoders.len(), 3);
    let mut reported = 0;
    for c in &encoders {
        for at in m.points() {
            let expect = m.expect(c, &at);
            let o = m.run_one(0, c, &at, expect, &AtomicBool::new(false)).unwrap();
            eprintln!("{} at {}: {} — {}", c.name, at.name(), o.seen(), o.verdict());
            assert!(o.passed(), "{} at {}: {:?}", c.name, at.name(), o.failures);
            if at.point != Point::Standstill {
                assert!(matches!(expect, Expect::Reported { .. }), "{expect:?}");
                assert_eq!(o.final_mode, Mode::Running);
                reported += 1;
            }
        }
    }
    assert_eq!(reported, 12);
}

/// Overmodulation (issue 52): a current sensor stuck at 1 A at top speed is named
/// `CurrentSensor` within the row's 10 ms, motoring and generating, noise seeds 0–3, on the
/// shipped drive with `overmodulation = true` at voltage targets 0.98 and 1 (its default).
/// Found by the whole matrix: with every period free to give up a window, the stuck phase
/// was rebuilt into the other two, the loops ran the bridge at its limit so that every
/// sample stayed rebuilt, the current-sum checks never saw three measured phases, and the
/// rows were named `SwitchOpen` after 10.1 and 7.6 ms. The two periods around each slow
/// tick keep every window (`FastState::modulation`) — without them this test fails (0.98,
/// motoring, seed 1).
#[test]
fn a_stuck_current_sensor_is_named_while_overmodulating() {
    let mut m = shipped();
    m.spec.overmodulation = true;
    let c = m.cases().unwrap().into_iter().find(|c| c.title() == "sensor b stuck at 1 A").unwrap();
    for margin in [0.98, drive_file::drive::DEFAULT_VOLTAGE_MARGIN_OVERMODULATING] {
        m.spec.voltage_margin = margin;
        for motoring in [true, false] {
            let at = point(&m, Point::Top, motoring);
            for seed in 0..4 {
                let o = m.run_one(seed, &c, &at, m.expect(&c, &at), &AtomicBool::new(false)).unwrap();
                eprintln!(
                    "margin {margin} motoring {motoring} seed {seed}: {} {:?}",
                    o.verdict(),
                    o.failures
                );
                assert_eq!(o.verdict(), "pass", "{:?}", o.failures);
            }
        }
    }
}

/// The sensor rows' resolution (`SENSOR_VERDICT_SIGMAS` standard deviations of a window's
/// mean of the channels' noise and quantisation): the shipped board's three channels of
/// 10 mA RMS on 8.06 mA counts, over its five samples a window (2.5 ms at the 2 kHz slow
/// rate), leave σ = 7.95 mA — 24 mA at three, a quarter of its 0.1 A windowed level
/// (docs/protection.md).
#[test]
fn the_sensor_rows_resolution_is_the_noise_of_the_checks_window() {
    let m = shipped();
    let p = &m.spec.protection;
    let samples = m.spec.open_phase_slow_steps();
    assert_eq!(samples, 5);
    let sigma = hil_sim::faults::sensor_window_sigma_a(&hil_sim::sensors::SensorModel::realistic(0), samples);
    assert!((sigma - 7.95e-3).abs() < 0.01e-3, "{sigma}");
    assert!((hil_sim::faults::SENSOR_VERDICT_SIGMAS * sigma - 0.024).abs() < 0.5e-3);
    assert!((p.current_sum_mean_max_a - 0.1).abs() < 1e-12, "{}", p.current_sum_mean_max_a);
}

/// A sensor row's level is a fraction of the trip level, whose binary tail printed as
/// "sensor b stuck at 16.516000000000002 A" on a population member's matrix: ten
/// significant digits, and the shipped drive's levels as they were.
#[test]
fn a_sensor_rows_level_prints_without_its_binary_tail() {
    let case = |gain, offset_a| Case {
        name: "sensor b",
        injection: Injection::CurrentSensor { phase: 1, gain, offset_a },
    };
    assert_eq!(case(0.0, 16.516000000000002).title(), "sensor b at 16.516 A");
    assert_eq!(case(1.0, 8.258000000000001).title(), "sensor b +8.258 A");
    assert_eq!(case(1.0, -0.5).title(), "sensor b -0.5 A");
    assert_eq!(case(0.0, 1.0).title(), "sensor b at 1 A");
}
