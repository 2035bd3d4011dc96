//! `design tune`'s tests.

use super::write::HEADER_START;
use super::*;

const TEMPLATE: &str = include_str!("../../../drive.toml");

/// Every shipped DeLorenzo motor on the shipped board: a drive file that the certificate
/// passes whole, with faster or equal current loops than the search's floor.
#[test]
fn shipped_motors_on_the_shipped_board_are_certified() {
    for name in ["delorenzo-appendix", "delorenzo-eq13", "delorenzo-perturbed"] {
        let m = drive_file::motor::load(name).unwrap();
        let t = tune(Path::new("drive.toml"), TEMPLATE, &m, None, Structure::default()).unwrap();
        assert!(t.checks.iter().all(|c| c.pass), "{name}");
        // The position loop: critically damped on the heaviest inertia, the sampled
        // cascade among the checks.
        let omega_b = t.omega_s_rad_s / t.certify.j_factor[1];
        assert!((t.spec.position.k_per_s - omega_b / POSITION_BELOW_SPEED).abs() < 1e-12);
        assert!(t.checks.iter().any(|c| c.name.starts_with("sampled position") && c.pass));
        assert!(
            t.omega_c_rad_s > 1000.0 && t.omega_s_rad_s > 1.0,
            "{name}: {} {}",
            t.omega_c_rad_s,
            t.omega_s_rad_s
        );
        println!(
            "{name}: ω_c {:.0} rad/s, ω_s {:.1} rad/s, {} checks",
            t.omega_c_rad_s,
            t.omega_s_rad_s,
            t.checks.len()
        );
    }
}

/// The ICAD placement at ω_h = 400 rad/s (the shipped drive's top speed) with eq. (20)'s
/// gain is eq. (20), coefficient for coefficient.
#[test]
fn icad_placement_at_the_shipped_top_speed_is_eq20() {
    assert_eq!(icad_law(326.5, 400.0), CurrentLaw::ICAD_EQ20);
}

/// Issue 21: on the DeLorenzo motor the tuned ICAD controller has margins at least as good
/// as eq. (20)'s at ω_r = 375 rad/s — every margin of the paper's continuous analysis, the
/// coupling and the stable speed range, and the sampled phase, gain-reduction and γh
/// margins. The sampled gain-*increase* margin is the one figure below eq. (20)'s (the
/// price of a faster crossover; docs/design-toolkit.md), asserted at twice the minimum.
/// The criterion itself: over the box, the tuned gain's smallest margin-to-minimum ratio
/// is at least eq. (20)'s.
#[test]
fn tuned_icad_is_at_least_as_robust_as_eq20() {
    let m = drive_file::motor::load("delorenzo-appendix").unwrap();
    let t = tune(
        Path::new("drive.toml"),
        TEMPLATE,
        &m,
        None,
        Structure { current: CurrentDesign::Icad, ..Default::default() },
    )
    .unwrap();
    assert!(t.checks.iter().all(|c| c.pass));
    let law = t.spec.current_law;
    assert_eq!(law.lag, CurrentLaw::ICAD_EQ20.lag);
    assert_eq!(law.ki_v_per_as / law.kp_v_per_a, 1000.0);
    // The criterion lands near the paper's hand design (Bode shaping, k_p = 326.5 V/A).
    assert!((law.kp_v_per_a / 326.5 - 1.0).abs() < 0.05, "{}", law.kp_v_per_a);
    let eq20 = CurrentLaw::ICAD_EQ20;
    let ts = 1.0 / t.spec.pwm_frequency_hz;
    let report = |l: &CurrentLaw| {
        let ctrl =
            controller_core::current::CurrentControllerConfig::<f32>::new(l, ts, t.spec.discretization, 1.0)
                .unwrap();
        (
            crate::icad::analyse(&m, l, 375.0),
            crate::sampled::analyse(&m, &ctrl, ts, 375.0),
            crate::icad::stable_omega_r_max(&m, l, 5.0, 5000.0).unwrap(),
            crate::sampled::stable_omega_r_max(&m, &ctrl, ts, 5.0, 5000.0).unwrap(),
        )
    };
    let (c, s, range, s_range) = report(&law);
    let (c0, s0, range0, s_range0) = report(&eq20);
    let f = |x: Option<f64>| x.unwrap();
    println!("at 375 rad/s        tuned ICAD   eq. (20)");
    for (what, a, b) in [
        ("crossover", f(c.channel.crossover_rad_s), f(c0.channel.crossover_rad_s)),
        ("phase margin", f(c.channel.phase_margin_deg), f(c0.channel.phase_margin_deg)),
        ("gain reduction", f(c.channel.gain_margin_reduction_db), f(c0.channel.gain_margin_reduction_db)),
        ("γh margin", f(c.gamma_h_margin_db), f(c0.gamma_h_margin_db)),
        ("sampled phase", f(s.channel.phase_margin_deg), f(s0.channel.phase_margin_deg)),
        ("sampled reduction", f(s.channel.gain_margin_reduction_db), f(s0.channel.gain_margin_reduction_db)),
        ("sampled γh", f(s.gamma_h_margin_db), f(s0.gamma_h_margin_db)),
        ("stable range", range, range0),
        ("sampled range", s_range, s_range0),
    ] {
        println!("{what:<20}{a:>10.2}{b:>10.2}");
        assert!(a >= b, "{what}: {a} < eq. (20)'s {b}");
    }
    assert!(c.coupling_peak_db <= c0.coupling_peak_db, "{} {}", c.coupling_peak_db, c0.coupling_peak_db);
    // No gain-increase margin exists continuously (the phase never crosses −180°).
    assert!(c.channel.gain_margin_increase_db.is_none() && c0.channel.gain_margin_increase_db.is_none());
    let (gi, gi0) = (f(s.channel.gain_margin_increase_db), f(s0.channel.gain_margin_increase_db));
    println!("sampled increase    {gi:>10.2}{gi0:>10.2}  (minimum 6)");
    assert!(gi >= 12.0, "{gi}");
    let (_, cert) = crate::certify::parse(Path::new("drive.toml"), TEMPLATE).unwrap();
    let mut shipped = t.spec;
    shipped.current_law = eq20;
    let r0 = robustness(&certify_current(&shipped, &cert).unwrap()).0;
    println!("robustness over the box: tuned {:.4}, eq. (20) {r0:.4}", t.current_robustness);
    assert!(t.current_robustness >= r0);
}

/// `--speed pi` on the DeLorenzo motor: a PI with integral action inside every region
/// of seed 000's design (margins and bandwidth on all 16 Kharitonov plants of the
/// inertia interval, k_p under the encoder-noise limit), away from their boundary (±5 %
/// in either gain stays inside), and certified — the exact sampled loop included.
#[test]
fn speed_pi_lies_inside_seed000s_regions() {
    let m = drive_file::motor::load("delorenzo-appendix").unwrap();
    let structure = Structure { speed: SpeedDesign::Pi, ..Default::default() };
    let t = tune(Path::new("drive.toml"), TEMPLATE, &m, None, structure).unwrap();
    assert!(t.checks.iter().all(|c| c.pass));
    let SpeedLaw::PiTorque { kp, ki, limit, .. } = t.spec.speed_law else { panic!("{:?}", t.spec.speed_law) };
    assert_eq!(limit, 2.0);
    let c = &t.certify;
    let t_slow = f64::from(t.spec.slow_divider) / t.spec.pwm_frequency_hz;
    let r = SpeedRegions::new(
        [m.j_kgm2() * c.j_factor[0], m.j_kgm2() * c.j_factor[1]],
        m.b_nms(),
        t_slow,
        [c.phase_margin_deg_min, c.gain_margin_db_min],
    )
    .unwrap();
    let omega_b = heaviest_speed_bandwidth(t.omega_s_rad_s, c);
    let kp_noise = encoder_kp_limit(2.0, 1024, t_slow);
    println!("speed PI: kp {kp:.5}, ki {ki:.5}, ω_B {omega_b:.2} rad/s, kp limit {kp_noise:.5}");
    assert!(ki > 0.0 && kp <= kp_noise);
    for (a, b) in [(1.0, 1.0), (0.95, 1.0), (1.05, 1.0), (1.0, 0.95), (1.0, 1.05)] {
        let (x, y) = (a * kp, b * ki);
        assert!(r.margins(x, y) && r.bandwidth(x, y, omega_b), "({x}, {y}) outside");
    }
}

/// The speed PI's drive in the nonlinear campaign of 1 s runs, on the narrow box (what
/// self-commissioning's intervals give): every run passes the campaign's criteria and meets
/// drive.toml's requirements — the 10 % overshoot among them, which tune's prediction and
/// SIL confirmation judge on these short runs' small steps as well as on the full-range ones
/// (`TuneCampaigns`). Judged on the full range alone, tune took setpoint weight 1 and every
/// reversal of this campaign overshot, worst 0.21 against 0.1. 256 runs: the 64 corner runs
/// tune confirmed on, and 192 random samples of the box it did not run.
#[test]
fn speed_pi_meets_the_requirements_on_the_short_campaign() {
    use hil_sim::campaign::Campaign;
    use std::sync::atomic::AtomicBool;
    let template = TEMPLATE
        .replace("rr_factor = [1.0, 2.0]", "rr_factor = [1.0, 1.2]")
        .replace("inductance_factor = [0.6, 1.0]", "inductance_factor = [0.95, 1.05]");
    let m = drive_file::motor::load("delorenzo-appendix").unwrap();
    let structure = Structure { speed: SpeedDesign::Pi, ..Default::default() };
    let t = tune(Path::new("narrow.toml"), &template, &m, None, structure).unwrap();
    let c = Campaign {
        spec: t.spec,
        certify: t.certify,
        vdc_v: 310.0,
        duration_s: SHORT_RUN_S,
        runs: 256,
        seed: 1,
        shard: (0, 1),
        encoder_lines: drive_file::drive::DEFAULT_ENCODER_LINES,
        plant: None,
        requirements: drive_file::DriveFile::parse(Path::new("t.toml"), &t.text).unwrap().requirements,
    };
    let v = c.run(|_| {}, &AtomicBool::new(false)).unwrap();
    let bad: Vec<String> = v.iter().filter(|v| !v.passed()).map(|v| v.csv()).collect();
    assert!(bad.is_empty(), "{} of {} fail ({}):\n{}", bad.len(), v.len(), missed_counts(&v), bad.join("\n"));
}

/// `requirement ×runs` for each requirement `verdicts` missed.
fn missed_counts(verdicts: &[hil_sim::campaign::Verdict]) -> String {
    let mut n = std::collections::BTreeMap::new();
    for r in verdicts.iter().flat_map(|v| v.requirements_missed()) {
        *n.entry(r.key()).or_insert(0) += 1;
    }
    n.iter().map(|(k, c)| format!("{k} ×{c}")).collect::<Vec<_>>().join(", ")
}

/// A PWM rate too slow for the ICAD loops at the top speed: refused, naming the check
/// that binds (at 5 kHz the sampled phase margin stays under 18° of 45°).
/// The tuned file is the template edited in place: every comment of `drive.toml` is
/// still there, and each value tune changed is named with its old and new value (the
/// speed gain, the writable range it certifies, the current law ICAD → PI); the values it
/// kept are not listed. (Until this, tune wrote the file anew from its parsed values:
/// every comment gone, the writable ranges rewritten silently.)
#[test]
fn the_tuned_file_keeps_the_templates_comments_and_names_each_change() {
    let path = Path::new("drive.toml");
    let m = drive_file::motor::load("delorenzo-appendix").unwrap();
    let t = tune(path, TEMPLATE, &m, None, Structure::default()).unwrap();
    // The ICAD law's comment goes with it (the law is now a PI); every other stays.
    for line in TEMPLATE.lines().filter(|l| l.contains('#') && !l.starts_with("current = ")) {
        let comment = &line[line.find('#').unwrap()..];
        assert!(t.text.contains(comment), "lost: {comment}");
    }
    assert!(!t.text.contains("# seed 002 eq. (20)"), "an ICAD comment on a PI law");
    let named = |prefix: &str| t.changes.iter().any(|c| c.starts_with(prefix));
    assert!(named("controller.speed.kp: 0.05 → "), "{:#?}", t.changes);
    assert!(named("certify.speed_kp_writable: [0.04, 0.1] → "), "{:#?}", t.changes);
    assert!(named("controller.current.kind: \"icad\" → \"pi\""), "{:#?}", t.changes);
    assert!(named("controller.slip_current: (absent) → \"measured\""), "{:#?}", t.changes);
    assert!(!named("motor."), "the template's motor is the one tuned: {:#?}", t.changes);
    // What it names is what differs.
    let back = drive_file::DriveFile::parse(path, &t.text).unwrap();
    assert_eq!(back.spec.speed_law, t.spec.speed_law);
    // Tuned again from its own output: one header (this tune's), nothing changed.
    let again = tune(path, &t.text, &m, None, Structure::default()).unwrap();
    assert_eq!(again.text.matches(HEADER_START).count(), 1, "{}", again.text);
    assert!(again.changes.is_empty(), "{:#?}", again.changes);
}

/// The field turns at the slip of the measured q current unless the template states its
/// choice: drive.toml (silent) is tuned to `"measured"`; the same template stating
/// `"reference"` keeps it, in the spec and in the file.
#[test]
fn tune_takes_the_measured_slip_unless_the_template_states_one() {
    let path = Path::new("drive.toml");
    let m = drive_file::motor::load("delorenzo-appendix").unwrap();
    let t = tune(path, TEMPLATE, &m, None, Structure::default()).unwrap();
    assert_eq!(t.spec.slip_current, SlipCurrent::Measured);
    let back = drive_file::DriveFile::parse(path, &t.text).unwrap();
    assert_eq!(back.spec.slip_current, SlipCurrent::Measured);
    let stated = TEMPLATE.replace("[controller]\n", "[controller]\nslip_current = \"reference\"\n");
    assert_ne!(stated, TEMPLATE);
    let t = tune(path, &stated, &m, None, Structure::default()).unwrap();
    assert_eq!(t.spec.slip_current, SlipCurrent::Reference);
    assert!(!t.changes.iter().any(|c| c.starts_with("controller.slip_current")), "{:#?}", t.changes);
    let back = drive_file::DriveFile::parse(path, &t.text).unwrap();
    assert_eq!(back.spec.slip_current, SlipCurrent::Reference);
}

/// A template whose motor is written in another form (Γ, with its saturation) is tuned
/// in the T form the tuned motor has: the other form's keys go, named. Found by trying:
/// tune wrote the T keys beside `form = "gamma"` and refused its own file ("tuned file:
/// motor.ls_h: belongs to the T form").
#[test]
fn a_template_in_another_motor_form_is_tuned_in_the_t_form() {
    let a = TEMPLATE.find("[motor]").unwrap();
    let b = a + TEMPLATE[a + 1..].find("\n[").unwrap() + 1;
    let gamma = "[motor]\nform = \"gamma\"\nrs_ohm = 16.2\nrr_ohm = 23.86\nlm_h = 1.998\nl_sigma_h = 0.1026\n\
                 pole_pairs = 1\nj_kgm2 = 0.005\nb_nms = 0.0005\nrated_current_a = 0.88\n\
                 thermal_time_constant_s = 900.0\n\n[motor.saturation]\nbeta_per_wb = 0.9\nexponent = 7.0\n";
    let template = format!("{}{gamma}{}", &TEMPLATE[..a], &TEMPLATE[b..]);
    drive_file::DriveFile::parse(Path::new("gamma.toml"), &template).unwrap();
    let m = drive_file::motor::load("delorenzo-appendix").unwrap();
    let t = tune(Path::new("gamma.toml"), &template, &m, None, Structure::default()).unwrap();
    for key in ["form", "l_sigma_h", "saturation"] {
        assert!(
            t.changes.iter().any(|c| c.starts_with(&format!("motor.{key}: ")) && c.ends_with("(removed)")),
            "{key}: {:#?}",
            t.changes
        );
    }
    assert_eq!(t.spec.motor, m);
}

/// A motor file whose branch saturates — `hil-sim identify --curve`'s Γ file, its curve as
/// points (here motulator's 2.2 kW law sampled at seven fluxes) — is tuned as the drive runs
/// it: its linear model at the curve's chord at the template's flux reference, and the drive
/// file carries its `[motor]` table as written, curve included, so the tuned drive runs on
/// the curve. Found by trying: tune wrote the linear model at the rated chord and removed
/// `[motor.saturation]` ("motor.saturation: a table → (removed)").
#[test]
fn a_saturating_motor_file_keeps_its_curve() {
    let template = include_str!("../../../drives/motulator-2kw-saturating.toml");
    let flux = [0.3, 0.5, 0.7, 0.9, 1.04, 1.14, 1.2];
    let current = flux.map(|p: f64| p * (1.0 + (0.84 * p).powi(7)) / 0.34);
    let list = |x: &[f64]| x.iter().map(|v| format!("{v}")).collect::<Vec<_>>().join(", ");
    let motor = format!(
        "[motor]\nform = \"gamma\"\nrs_ohm = 3.7\nrr_ohm = 2.5\nlm_h = 0.245\nl_sigma_h = 0.023\npole_pairs = 2\n\
         j_kgm2 = 0.015\nb_nms = 0.0\n\n[motor.saturation]\ncurrent_a = [{}]\nflux_wb = [{}]\n",
        list(&current),
        list(&flux)
    );
    let path = Path::new("identified.toml");
    let t = tune_file(
        Path::new("motulator.toml"),
        template,
        MotorFile { path, text: &motor },
        None,
        Structure::default(),
    )
    .unwrap();
    assert!(
        !t.changes.iter().any(|c| c.starts_with("motor.saturation") && c.ends_with("(removed)")),
        "{:#?}",
        t.changes
    );
    let back = drive_file::DriveFile::parse(Path::new("tuned.toml"), &t.text).unwrap();
    let flux_ref = back.spec.flux_ref_wb;
    let (chord, table, _) = drive_file::motor::drive_model_of(path, &motor, flux_ref).unwrap().unwrap();
    assert_eq!(back.spec.magnetizing, Some(table), "{}", t.text);
    assert_eq!(back.spec.motor, chord);
    assert_eq!(t.spec.motor, chord);
    let (_, sat) = drive_file::motor::parse_model(Path::new("tuned.toml"), &t.text).unwrap();
    let (_, want) = drive_file::motor::parse_model(path, &motor).unwrap();
    assert_eq!(sat, want);
    // A linear motor file is tuned as before.
    let m = drive_file::motor::load("delorenzo-appendix").unwrap();
    let linear = drive_file::motor::BUILTIN.iter().find(|(n, _)| *n == "delorenzo-appendix").unwrap().1;
    let a = tune(Path::new("t.toml"), TEMPLATE, &m, None, Structure::default()).unwrap();
    let b = tune_file(
        Path::new("t.toml"),
        TEMPLATE,
        MotorFile { path, text: linear },
        None,
        Structure::default(),
    )
    .unwrap();
    assert_eq!(a.text, b.text);
}

#[test]
fn an_icad_the_pwm_cannot_run_is_refused() {
    let template = TEMPLATE
        .replace("frequency_hz = 20000.0", "frequency_hz = 5000.0")
        .replace("slow_divider = 10", "slow_divider = 2");
    let m = drive_file::motor::load("delorenzo-appendix").unwrap();
    let e = tune(
        Path::new("slow.toml"),
        &template,
        &m,
        None,
        Structure { current: CurrentDesign::Icad, ..Default::default() },
    )
    .unwrap_err();
    assert!(e.contains("no ICAD gain") && e.contains("sampled current: phase margin"), "{e}");
}

/// The 500 hp Krause machine on its 3 300 V template: certified (linear), its box holding
/// the rotor resistances the drive's estimate may take — the template's R_r ×[1, 1.2]
/// widened to the default estimate range ×[1, 1.5] (the tuned file's flying starts ran on
/// the range's middle, ×1.22, outside what it certified: found by trying) and written so.
#[test]
fn the_krause_motor_tunes_on_its_template() {
    let template = include_str!("../../../drives/krause-3300v.toml");
    assert!(template.contains("rr_factor = [1.0, 1.2]") && !template.contains("rotor_resistance_range"));
    let m = drive_file::motor::load("krause-2300v-500hp").unwrap();
    let t = tune(Path::new("drives/krause-3300v.toml"), template, &m, None, Structure::default()).unwrap();
    assert!(t.checks.iter().all(|c| c.pass));
    assert_eq!(t.spec.rotor_resistance_range, controller_core::mras::DEFAULT_RANGE);
    assert_eq!(t.certify.rr_factor, controller_core::mras::DEFAULT_RANGE);
    let written = drive_file::DriveFile::parse(Path::new("t.toml"), &t.text).unwrap();
    assert_eq!(written.certify.unwrap().rr_factor, controller_core::mras::DEFAULT_RANGE);
    // A range of one value is the estimate switched off: it stays so (the box holds it).
    let off = template.replace("[controller]\n", "[controller]\nrotor_resistance_range = [1.0, 1.0]\n");
    assert_ne!(off, template);
    let t = tune(Path::new("off.toml"), &off, &m, None, Structure::default()).unwrap();
    assert_eq!(t.spec.rotor_resistance_range, [1.0, 1.0]);
    assert_eq!(t.certify.rr_factor, [1.0, 1.2]);
    let written = drive_file::DriveFile::parse(Path::new("t.toml"), &t.text).unwrap();
    assert_eq!(written.spec.rotor_resistance_range, [1.0, 1.0]);
}

/// A template sized for motor `m` on a 310 V bus: rated flux 0.9·(V_dc/√3)/(2π·50 Hz),
/// current limit three times the magnetizing current, τ_max half of what it gives,
/// trip at twice the limit; the narrow box self-commissioning supports. PWM at 10 kHz, the
/// industry's usual rate (issue 49), with the slow loop at 2 kHz as the shipped board's: at
/// 20 kHz tune's runs in SIL simulated twice the fast steps for the same requirements'
/// windows, and these motors' tests were a third of CI's test step.
fn template_for(m: &MotorParams) -> String {
    let psi = 0.9 * 310.0 / 3f64.sqrt() / (2.0 * std::f64::consts::PI * 50.0);
    let i_d = psi / m.lm_h();
    let i_max = 3.0 * i_d;
    let tau = 0.5 * m.torque_factor() * psi * (i_max * i_max - i_d * i_d).sqrt();
    format!(
        "[pwm]\nfrequency_hz = 10000.0\nslow_divider = 5\n\
         [motor]\nrs_ohm = {}\nrr_ohm = {}\nls_h = {}\nlr_h = {}\nlm_h = {}\npole_pairs = {}\nj_kgm2 = {}\nb_nms = {}\n\
         [controller]\ncurrent = {{ kind = \"pi\", kp = 1.0, ki = 1.0 }}\n\
         speed = {{ kind = \"saturated_p\", kp = 0.001, tau_max_nm = {tau} }}\n\
         flux_ref_wb = {psi}\ni_ref_max_a = {i_max}\n\
         [protection]\ni_trip_a = {}\nvdc_min_v = 250.0\nvdc_max_v = 370.0\n\
         [certify]\nomega_r_max_rad_s = 628.0\nrs_factor = [1.0, 1.5]\nrr_factor = [1.0, 1.2]\n\
         inductance_factor = [0.95, 1.05]\nj_factor = [1.0, 2.0]\nspeed_kp_writable = [0.0005, 0.002]\n\
         speed_tau_max_nm_writable = [{}, {tau}]\nphase_margin_deg_min = 45.0\ngain_margin_db_min = 6.0\n\
         gamma_h_margin_db_min = 1.0\n",
        m.rs_ohm(),
        m.rr_ohm(),
        m.ls_h(),
        m.lr_h(),
        m.lm_h(),
        m.pole_pairs(),
        m.j_kgm2(),
        m.b_nms(),
        2.0 * i_max,
        tau / 20.0,
    )
}

/// One test per seeded random motor, in a module named for the check (`…::motor_3`): the
/// harness spreads the motors over the cores (as one loop, one check held a core for
/// minutes while the other sat idle).
macro_rules! per_random_motor {
    ($module:ident, $check:ident) => {
        per_random_motor!($module, $check, [] [] [] [] [] []);
    };
    // Each motor's test with its own attributes (`#[ignore = "…"]`), in order 0 … 5.
    ($module:ident, $check:ident, [$(#[$a0:meta])*] [$(#[$a1:meta])*] [$(#[$a2:meta])*]
        [$(#[$a3:meta])*] [$(#[$a4:meta])*] [$(#[$a5:meta])*]) => {
        mod $module {
            $(#[$a0])*
            #[test]
            fn motor_0() {
                super::$check(0)
            }
            $(#[$a1])*
            #[test]
            fn motor_1() {
                super::$check(1)
            }
            $(#[$a2])*
            #[test]
            fn motor_2() {
                super::$check(2)
            }
            $(#[$a3])*
            #[test]
            fn motor_3() {
                super::$check(3)
            }
            $(#[$a4])*
            #[test]
            fn motor_4() {
                super::$check(4)
            }
            $(#[$a5])*
            #[test]
            fn motor_5() {
                super::$check(5)
            }
        }
    };
}

/// The `k`-th of the seeded random motors.
fn seeded_random_motor(k: usize) -> MotorParams {
    let motors = seeded_random_motors();
    assert!(k < motors.len(), "{k} is not one of the {} random motors", motors.len());
    motors.into_iter().nth(k).unwrap()
}

/// Six seeded random motors in the ranges of `hil-sim/tests/identify.rs`.
fn seeded_random_motors() -> Vec<MotorParams> {
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut uniform = |lo: f64, hi: f64| {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        lo + (hi - lo) * (state >> 11) as f64 / (1u64 << 53) as f64
    };
    (0..6)
        .map(|_| {
            let lm = (uniform(0.05f64.ln(), 2f64.ln())).exp();
            let (ls, lr) = (lm * (1.0 + uniform(0.02, 0.1)), lm * (1.0 + uniform(0.02, 0.1)));
            let rr = lr / uniform(0.02, 0.6);
            let rs = ls / uniform(0.01, 0.2);
            let j = uniform(1e-4, 1e-1);
            MotorParams::new(rs, rr, ls, lr, lm, 2, j, j * 0.01).unwrap()
        })
        .collect()
}

/// Issue 51's acceptance on the same random motors, each on its template's default
/// requirements: `--speed auto` writes a file predicted to meet them, or refuses naming
/// each requirement its laws miss — on the prediction (the P droops, seed 000's PI at its
/// best setpoint weight overshoots or rises too slowly) or on the corner runs in SIL, of 1 s
/// and to the box's top speed (`TuneCampaigns`, docs/population.md).
fn meets_the_requirements_or_is_refused_naming_them(k: usize) {
    let auto = Structure { speed: SpeedDesign::Auto, ..Default::default() };
    let m = seeded_random_motor(k);
    match tune(Path::new("template.toml"), &template_for(&m), &m, None, auto) {
        Ok(t) => {
            assert!(t.predicted_misses.is_empty(), "random {k}: {:?}", t.predicted_misses);
            println!("random {k}: {:?}", t.spec.speed_law);
        }
        Err(e) => {
            // Refused on the prediction, naming each law's misses, or on the corner runs
            // in SIL (to the box's top speed), naming what they missed and in how many.
            let predicted = e.starts_with("no speed law meets the requirements")
                && e.contains("misses requirements.")
                && e.contains("PI (seed 000's");
            let in_sil = e.contains("is predicted to meet the requirements over the box, but the drive misses them in software in the loop on the 64 corner runs of the ")
                && e.contains(" of 64 runs");
            assert!(predicted || in_sil, "random {k}: {e}");
            println!("random {k}: {e}");
        }
    }
}
// Motors 2, 4 and 5 take tune through every point of its region in SIL: 90, 95 and 185 s of
// the test step on 2 cores, more than CI's 20 minutes allow beside the rest; motor 3, 20 s.
// They run with `cargo test -p design -- --ignored`; the population's CI sample (a step of
// `cargo xtask ci`: 72 drives of physical motors, tune to the fault matrix,
// docs/population.md) is the breadth of this check.
per_random_motor!(
    seeded_random_motors_meet_the_requirements_or_are_refused_naming_them,
    meets_the_requirements_or_is_refused_naming_them,
    [] [] [#[ignore = "slow: cargo test -p design -- --ignored"]] [#[ignore = "slow: cargo test -p design -- --ignored"]]
    [#[ignore = "slow: cargo test -p design -- --ignored"]] [#[ignore = "slow: cargo test -p design -- --ignored"]]
);

/// Motors the toolkit has never seen (the ranges of `hil-sim/tests/identify.rs`: 2–10 %
/// leakage each side, L_m 0.05…2 H, T_r 20…600 ms, L_s/R_s 10…200 ms, p = 2), each on a
/// template sized for it: the tuned file passes every linear check, and then the nonlinear
/// campaign (issue 21: "passes both certificates"): 200 runs each over the tuned file's box (`hil_sim::campaign`: speed
/// steps, load steps to the torque limit and reversals, realistic sensors scaled to the
/// drive's trip level), long enough for each motor to magnetize first. Every run passes
/// (a stated gap — reversals at the R_r ×1.2 corners missing tracking by a little, the
/// fixed-T_r orientation detuned — closed with the drive's rotor-resistance estimate,
/// docs/rotor-resistance.md). The runs are judged on the campaign's own criteria (no
/// fault, no flux collapse, no oscillation); the default `[requirements]` — ±1 % speed
/// regulation, which the saturated P's droop τ_L/k_p misses by design — are printed, not
/// asserted: choosing a speed law that meets them is the tuner's next step (issue 51).
fn tunes_certifies_and_passes_the_campaign(k: usize) {
    use hil_sim::campaign::{Campaign, STEP_S};
    use std::sync::atomic::AtomicBool;
    let m = seeded_random_motor(k);
    let t = tune(Path::new("template.toml"), &template_for(&m), &m, None, Structure::default())
        .unwrap_or_else(|e| panic!("random {k} ({m:?}): {e}"));
    assert!(t.checks.iter().all(|c| c.pass), "random {k}");
    println!("random {k}: ω_c {:.0} rad/s, ω_s {:.1} rad/s", t.omega_c_rad_s, t.omega_s_rad_s);
    let mut c = Campaign {
        spec: t.spec,
        certify: t.certify,
        vdc_v: 310.0,
        duration_s: 1.0,
        runs: 200,
        seed: 1,
        shard: (0, 1),
        encoder_lines: drive_file::drive::DEFAULT_ENCODER_LINES,
        plant: None,
        requirements: drive_file::DriveFile::parse(Path::new("t.toml"), &t.text).unwrap().requirements,
    };
    // A long rotor time constant magnetizes later: 0.75 s after the step as at 1 s.
    c.duration_s = c.duration_s.max(c.step_s() + (1.0 - STEP_S));
    let v = c.run(|_| {}, &AtomicBool::new(false)).unwrap();
    let bad: Vec<String> = v.iter().filter(|v| !v.criteria_failed().is_empty()).map(|v| v.csv()).collect();
    println!(
        "random {k} (L_m {:.3} H, T_r {:.3} s, J {:.2e} kg·m², i_trip {:.2} A, runs of {:.2} s): {} of {} pass the criteria, {} meet the default requirements; missed: {}",
        m.lm_h(),
        m.lr_h() / m.rr_ohm(),
        m.j_kgm2(),
        t.spec.protection.i_trip_a,
        c.duration_s,
        v.len() - bad.len(),
        v.len(),
        v.iter().filter(|v| v.passed()).count(),
        missed_counts(&v),
    );
    for b in bad.iter().take(5) {
        println!("  {b}");
    }
    assert!(bad.is_empty(), "random motor {k} fails the campaign");
}
// Motors 2, 4 and 5: 13, 11 and 26 s of the test step; with `--ignored`, as above.
per_random_motor!(
    seeded_random_motors_tune_certify_and_pass_the_campaign,
    tunes_certifies_and_passes_the_campaign,
    [] [] [#[ignore = "slow: cargo test -p design -- --ignored"]] []
    [#[ignore = "slow: cargo test -p design -- --ignored"]] [#[ignore = "slow: cargo test -p design -- --ignored"]]
);

/// Issue 51: the template's `[requirements]` choose the speed law. The 24 V template asks
/// the defaults (±1 % regulation, 10 % overshoot), its runs stepping to the box's top speed
/// (where the motor's friction takes half the drive's torque: 178.6 rad/s). The saturated
/// P's droop misses the first, so `auto` takes the PI predicted to meet them all — and its
/// drive, run on the corner runs in SIL, meets them on the runs of 1 s but misses the torque
/// accuracy in a generating run at top speed on the full range's (1.99 s; the runs of 1 s
/// missed the flux accuracy in a few until the rotor-resistance law heard only plans that
/// held the references): refused, naming it. `--speed p` keeps
/// the P and reports the miss. Asked for 1 % overshoot, neither law is predicted to meet
/// the requirements, refused naming each law's misses. drive.toml's own requirements (its
/// P law's) keep the P; the 3 300 V template is tuned on the defaults at a point deeper in
/// the region than the first ones, whose drives missed them in SIL.
#[test]
fn the_requirements_choose_the_speed_law_or_refuse_naming_them() {
    let template = include_str!("../../../drives/em-synergy-24v.toml");
    let m = drive_file::motor::load("em-synergy-m800006").unwrap();
    let auto = Structure { speed: SpeedDesign::Auto, ..Default::default() };
    let e = tune(Path::new("24v.toml"), template, &m, None, auto).unwrap_err();
    assert!(
        e.contains("PI") && e.contains("is predicted to meet the requirements over the box, but the drive misses them in software in the loop")
            && e.contains("torque_accuracy_fraction")
            && e.contains("(runs of 1.99 s)"),
        "{e}"
    );
    let p = tune(Path::new("24v.toml"), template, &m, None, Structure::default()).unwrap();
    let missed: Vec<_> = p.predicted_misses.iter().map(|(_, m)| m.requirement.key()).collect();
    assert!(missed.contains(&"speed_error_fraction"), "{missed:?}");
    // 1 %: refused, named, with what bounds the region.
    let strict = template.replace("[requirements]\n", "[requirements]\nspeed_overshoot_fraction = 0.01\n");
    let e = tune(Path::new("strict.toml"), &strict, &m, None, auto).unwrap_err();
    assert!(
        e.contains("saturated P")
            && e.contains("misses requirements.speed_error_fraction")
            && e.contains("PI (seed 000's")
            && e.contains("requirements.speed_overshoot_fraction")
            && e.contains("the region: k_p ≤"),
        "{e}"
    );
    let d = drive_file::motor::load("delorenzo-appendix").unwrap();
    let t = tune(Path::new("drive.toml"), TEMPLATE, &d, None, auto).unwrap();
    assert!(matches!(t.spec.speed_law, SpeedLaw::SaturatedP { .. }) && t.predicted_misses.is_empty());
    // The 500 hp machine on its 3 300 V template (the default requirements): the P droops,
    // and the first PIs predicted to meet them miss the small steps of its short campaign
    // (at the least the campaign accepts, 2.83 s) in SIL; a deeper point of the region
    // meets them, and tune says which it ran before it.
    let k = drive_file::motor::load("krause-2300v-500hp").unwrap();
    let t = tune(Path::new("krause.toml"), include_str!("../../../drives/krause-3300v.toml"), &k, None, auto)
        .unwrap();
    assert!(matches!(t.spec.speed_law, SpeedLaw::PiTorque { .. }) && t.predicted_misses.is_empty());
    let o = &t.speed_origin;
    assert!(
        o.contains("met on the 64 corner runs of the 2.83 s")
            && o.contains("was predicted to meet them and missed")
            && o.contains("of 64 runs (runs of 2.83 s)"),
        "{o}"
    );
}

/// Issue 51, deliverable 3: the link's writable gains are the ranges over which the
/// requirements hold. drive.toml's, k_p × [0.04, 0.1], meet them at every corner
/// (predicted); widened down to 0.02, the corners there miss the load step's dip (0.38 of
/// base speed against the 0.25 asked) — `design certify` refuses it, naming them.
#[test]
fn the_writable_speed_gains_keep_the_requirements() {
    use drive_file::requirements::Requirement;
    let shipped = drive_file::DriveFile::shipped().unwrap();
    let cert = shipped.certify.unwrap();
    assert_eq!(cert.speed_kp_writable, [0.04, 0.1]);
    assert!(writable_gain_misses(&shipped.spec, &cert, &shipped).unwrap().is_empty());
    let wide = CertifySpec { speed_kp_writable: [0.02, 0.1], ..cert };
    let missed = writable_gain_misses(&shipped.spec, &wide, &shipped).unwrap();
    assert!(!missed.is_empty() && missed.iter().all(|([kp, _], _)| *kp == 0.02), "{missed:?}");
    let dip = missed
        .iter()
        .flat_map(|(_, m)| m)
        .find(|(_, m)| m.requirement == Requirement::LoadDip)
        .map(|(_, m)| (m.value, m.allowed));
    let (value, allowed) = dip.expect("the load dip is missed at k_p 0.02");
    assert!((value - 0.384).abs() < 0.01 && (allowed - 0.252).abs() < 0.001, "{value} against {allowed}");
}

/// The walk-through's motor on its 24 V template (docs/walkthrough.md).
#[test]
fn the_walkthrough_motor_tunes_on_its_template() {
    let template = include_str!("../../../drives/em-synergy-24v.toml");
    let m = drive_file::motor::load("em-synergy-m800006").unwrap();
    let t = tune(Path::new("drives/em-synergy-24v.toml"), template, &m, None, Structure::default()).unwrap();
    assert!(t.checks.iter().all(|c| c.pass));
    let SpeedLaw::SaturatedP { kp, tau_max_nm } = t.spec.speed_law else { panic!() };
    assert_eq!(tau_max_nm, 0.12);
    // The encoder rule binds: k_p·Δω_q = 2.5 % of τ_max (Δω_q = 0.383 rad/s).
    assert!((kp * 0.3835 / (0.025 * 0.12) - 1.0).abs() < 0.01, "{kp}");
}

/// The inductance estimate follows the box: a template that does not state
/// `inductance_range` gets its box's inductance interval as the range (the 24 V
/// template's ±5 %: estimated, so that the flux is not off by the box's spread); one that
/// states a single value keeps the estimate off; one that states a range gets the hull of
/// the two as both box and range, written into the file.
#[test]
fn the_inductance_estimate_covers_the_box() {
    let template = include_str!("../../../drives/em-synergy-24v.toml");
    assert!(template.contains("inductance_factor = [0.95, 1.05]") && !template.contains("inductance_range"));
    let m = drive_file::motor::load("em-synergy-m800006").unwrap();
    let tuned = |text: &str| {
        let t = tune(Path::new("t.toml"), text, &m, None, Structure::default()).unwrap();
        let written = drive_file::DriveFile::parse(Path::new("t.toml"), &t.text).unwrap();
        assert_eq!(written.spec.inductance_range, t.spec.inductance_range, "written as tuned");
        assert_eq!(written.certify.unwrap().inductance_factor, t.certify.inductance_factor);
        (t.spec.inductance_range, t.certify.inductance_factor)
    };
    assert_eq!(tuned(template), ([0.95, 1.05], [0.95, 1.05]));
    let state = |range: &str| {
        template.replace("[controller]\n", &format!("[controller]\ninductance_range = {range}\n"))
    };
    assert_eq!(tuned(&state("[1.0, 1.0]")), ([1.0, 1.0], [0.95, 1.05]), "stated off: kept off");
    assert_eq!(tuned(&state("[0.6, 1.0]")), ([0.6, 1.05], [0.6, 1.05]), "the hull");
}

/// A synchronous-frame template: the same PI rule (its zero on the stator's pole below the
/// rotor corner holds in the field frame too), searched against the certificate in that
/// frame, passes every check and keeps the frame; ICAD in it is refused by name.
#[test]
fn a_synchronous_template_tunes_a_pi() {
    let sync = TEMPLATE.replace("current_frame = \"stationary\"", "current_frame = \"synchronous\"");
    assert_ne!(sync, TEMPLATE);
    let m = drive_file::motor::load("delorenzo-appendix").unwrap();
    let t = tune(Path::new("sync.toml"), &sync, &m, None, Structure::default()).unwrap();
    assert_eq!(t.spec.current_frame, CurrentFrame::Synchronous);
    assert!(t.checks.iter().all(|c| c.pass));
    assert!(t.checks.iter().any(|c| c.name.starts_with("sampled current: worst")));
    let written = drive_file::DriveFile::parse(Path::new("t.toml"), &t.text).unwrap();
    assert_eq!(written.spec.current_frame, CurrentFrame::Synchronous);
    // The header names the frame (it said "stationary-frame" whatever the template's).
    assert!(t.text.starts_with("# Tuned by") && t.text.contains("synchronous-frame PI"), "{}", t.text);
    assert!(!t.text.contains("stationary"), "{}", t.text);
    println!("synchronous PI: ω_c {:.0} rad/s, {} checks", t.omega_c_rad_s, t.checks.len());
    let icad = Structure { current: CurrentDesign::Icad, ..Default::default() };
    let e = tune(Path::new("sync.toml"), &sync, &m, None, icad).unwrap_err();
    assert!(e.contains("synchronous") && e.contains("--current pi"), "{e}");
}

/// The strided search answers what the candidate-by-candidate one did wherever passing
/// is monotone (every threshold over a 44-candidate grid, and none passing), with at
/// most ⌈n/4⌉ + 3 certificates.
#[test]
fn the_strided_search_finds_the_first_passing_candidate() {
    let grid: Vec<f64> = candidates(5026.5, 50.0).collect();
    assert_eq!(grid.len(), 44);
    for threshold in grid.iter().copied().chain([0.0, 1e9]) {
        let mut calls = 0;
        let found = search_down(grid.iter().copied(), |w| {
            calls += 1;
            Ok(w <= threshold)
        })
        .unwrap();
        let linear = grid.iter().copied().find(|&w| w <= threshold);
        assert_eq!(found, linear, "threshold {threshold}");
        assert!(calls < grid.len().div_ceil(SEARCH_STRIDE) + SEARCH_STRIDE, "{calls} calls");
    }
    // An error stops it.
    assert!(search_down(grid.iter().copied(), |_| Err("no".into())).is_err());
}

/// The frame is tune's choice (issue 49: it never tried the other one): the shipped
/// board at 10 kHz passes no stationary-frame crossover of the search on the DeLorenzo
/// motor — the stationary PI's phase error at the top electrical speed — and the
/// field-frame PI passes; the file records the frame taken.
#[test]
fn tune_takes_the_field_frame_when_the_stationary_frame_fails() {
    let at_10k = TEMPLATE
        .replace("frequency_hz = 20000.0", "frequency_hz = 10000.0")
        .replace("slow_divider = 10", "slow_divider = 5");
    assert_ne!(at_10k, TEMPLATE);
    let m = drive_file::motor::load("delorenzo-appendix").unwrap();
    let t = tune(Path::new("10k.toml"), &at_10k, &m, None, Structure::default()).unwrap();
    assert_eq!(t.spec.current_frame, CurrentFrame::Synchronous);
    assert!(t.checks.iter().all(|c| c.pass));
    let written = drive_file::DriveFile::parse(Path::new("t.toml"), &t.text).unwrap();
    assert_eq!(written.spec.current_frame, CurrentFrame::Synchronous);
    // The same gains in the stationary frame fail the template's own box.
    let mut spec = drive_file::DriveFile::parse(Path::new("10k.toml"), &at_10k).unwrap().spec;
    spec.motor = m;
    let cert = drive_file::DriveFile::parse(Path::new("10k.toml"), &at_10k).unwrap().certify.unwrap();
    spec.current_law = t.spec.current_law;
    assert_eq!(spec.current_frame, CurrentFrame::Stationary);
    assert!(!certify_current(&spec, &cert).unwrap().iter().all(|c| c.pass));
}

/// A motor without rotor leakage (inverse-Γ, L_r = L_m) or without stator leakage (Γ,
/// L_s = L_m) is written back in its own form: in the T form the tuned file refused
/// itself ("L_m = 0.224 H must be below lr_h = 0.224 H") and tune wrote nothing — found
/// tuning motulator's 2.2-kW machine from motors/motulator-2kw.toml.
#[test]
fn a_motor_without_one_leakage_is_written_in_its_own_form() {
    let inverse_gamma = "[motor]\nform = \"inverse_gamma\"\nrs_ohm = 16.2\nrr_ohm = 22.0\nlm_h = 1.34\n\
                         l_sigma_h = 0.1\npole_pairs = 1\nj_kgm2 = 0.005\nb_nms = 0.0005\n";
    let gamma = "[motor]\nform = \"gamma\"\nrs_ohm = 16.2\nrr_ohm = 24.0\nlm_h = 1.44\nl_sigma_h = 0.1\n\
                 pole_pairs = 1\nj_kgm2 = 0.005\nb_nms = 0.0005\n";
    for (text, form) in [(inverse_gamma, "inverse_gamma"), (gamma, "gamma")] {
        let m = drive_file::motor::parse(Path::new("m.toml"), text).unwrap();
        let t = tune(Path::new("drive.toml"), TEMPLATE, &m, None, Structure::default()).unwrap();
        assert!(t.text.contains(&format!("form = \"{form}\"")), "{}", t.text);
        let written = drive_file::DriveFile::parse(Path::new("t.toml"), &t.text).unwrap().spec.motor;
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * b.abs();
        for (a, b) in [
            (written.ls_h(), m.ls_h()),
            (written.lr_h(), m.lr_h()),
            (written.lm_h(), m.lm_h()),
            (written.rr_ohm(), m.rr_ohm()),
            (written.rs_ohm(), m.rs_ohm()),
        ] {
            assert!(close(a, b), "{form}: {a} against {b}");
        }
    }
}

#[test]
fn identification_intervals_widen_the_box() {
    let text = "[motor]\nrs_ohm = 16.2\nrr_ohm = 23.2\nls_h = 1.44\nlr_h = 1.5\nlm_h = 1.42\npole_pairs = 1\n\
                j_kgm2 = 0.005\nb_nms = 0.0005\n[identification]\nrs_ohm = [15.0, 17.0]\nj_kgm2 = [0.004, 0.011]\n";
    let iv = Intervals::parse(text).unwrap().unwrap();
    assert_eq!(iv.rs_ohm, Some([15.0, 17.0]));
    let m = drive_file::motor::parse(Path::new("m.toml"), text).unwrap();
    let t = tune(Path::new("drive.toml"), TEMPLATE, &m, Some(&iv), Structure::default()).unwrap();
    assert!((t.certify.rs_factor[0] - 15.0 / 16.2).abs() < 1e-12, "{:?}", t.certify.rs_factor);
    assert_eq!(t.certify.j_factor[1], 0.011 / 0.005);
    assert!(Intervals::parse("[identification]\nrs_ohm = [2.0, 1.0]\n").is_err());
    assert_eq!(Intervals::parse("[motor]\n").unwrap(), None);
}

/// The stationary PI's steady error against closed forms: a proportional loop on a pure
/// inductance leaves `ωL/√((ωL)² + k_p²)`; on a pure resistance `r/(r + k_p)`.
#[test]
fn a_stationary_pis_steady_error_is_its_sensitivity_at_the_field_speed() {
    let p = |kp: f64| CurrentLaw { kp_v_per_a: kp, ki_v_per_as: 0.0, lag: None };
    let (w, l, kp) = (628.0, 0.0776, 136.0);
    let inductive = stationary_steady_error(p(kp), 0.0, l, w);
    assert!((inductive - w * l / (w * l).hypot(kp)).abs() < 1e-12, "{inductive}");
    let resistive = stationary_steady_error(p(kp), 12.3, 0.0, w);
    assert!((resistive - 12.3 / (12.3 + kp)).abs() < 1e-12, "{resistive}");
}

/// What the setpoint weight may take back: a drive that missed only the overshoot or the
/// settling time in software in the loop is run again at the next lower weight
/// (`speed::confirm`); a fault, or any requirement the weight does not shape, ends it.
#[test]
fn only_an_overshoot_or_a_settling_time_steps_the_setpoint_weight_down() {
    let misses = |counts: &[(&str, usize)]| {
        let counts: Vec<(String, usize)> = counts.iter().map(|(f, n)| ((*f).to_string(), *n)).collect();
        SilMiss::of(&counts, 64)
    };
    assert_eq!(misses(&[]), None);
    let overshoot = misses(&[("speed_overshoot_fraction", 1), ("speed_settling_time_s", 3)]).unwrap();
    assert!(overshoot.shaped_only);
    assert_eq!(
        overshoot.words,
        "speed_overshoot_fraction in 1 of 64 runs, speed_settling_time_s in 3 of 64 runs"
    );
    for other in [
        "fault",
        "oscillation",
        "speed_rise_time_s",
        "load_dip_fraction",
        "torque_accuracy_fraction",
        "flux_accuracy_fraction",
    ] {
        assert!(!misses(&[("speed_overshoot_fraction", 1), (other, 1)]).unwrap().shaped_only, "{other}");
    }
    // The weights step down one at a time, to 0 and no further; a P law has none.
    let pi = SpeedLaw::PiTorque { kp: 1.0, ki: 2.0, limit: 3.0, setpoint_weight: 0.7 };
    let lower = lower_setpoint_weight(&pi).unwrap();
    assert_eq!(lower, SpeedLaw::PiTorque { kp: 1.0, ki: 2.0, limit: 3.0, setpoint_weight: 0.6 });
    let mut law = pi;
    let mut steps = 0;
    while let Some(l) = lower_setpoint_weight(&law) {
        (law, steps) = (l, steps + 1);
    }
    assert_eq!((setpoint_weight(&law), steps), (0.0, 7));
    assert_eq!(lower_setpoint_weight(&SpeedLaw::SaturatedP { kp: 1.0, tau_max_nm: 3.0 }), None);
}
