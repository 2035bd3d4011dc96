//! Issue 17's acceptance: the whole operating envelope of the shipped drive on a 310 V bus —
//! field weakening to twice the base speed, a torque reversal at speed, the torque ripple at
//! the top, and the torque–speed envelope against the analytic one. On the nonlinear machine
//! model, in software in the loop, with the scenario files of `hil-sim/scenarios/`.
#![allow(clippy::unwrap_used, clippy::indexing_slicing, clippy::panic)]

use controller_core::drive::{Mode, Reference};
use hil_sim::envelope::{drive_base_speed_rad_s, measure};
use hil_sim::scenario::Builtin;
use hil_sim::scenario_file::{ScenarioFileKind, load};
use hil_sim::sim::{Event, Row};
use std::path::Path;

fn scenario(name: &str) -> Builtin {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios").join(name);
    match load(&path).unwrap() {
        ScenarioFileKind::ClosedLoop(b) => *b,
        ScenarioFileKind::OpenLoop(_) => panic!("{name} is a closed-loop scenario"),
    }
}

fn window(rows: &[Row], from_s: f64, to_s: f64) -> Vec<Row> {
    rows.iter().filter(|r| r.t_s >= from_s && r.t_s < to_s).copied().collect()
}

fn mean(rows: &[Row], f: impl Fn(&Row) -> f64) -> f64 {
    rows.iter().map(&f).sum::<f64>() / rows.len() as f64
}

fn span(rows: &[Row], f: impl Fn(&Row) -> f64) -> f64 {
    let (lo, hi) =
        rows.iter().map(f).fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), x| (l.min(x), h.max(x)));
    hi - lo
}

fn flux(r: &Row) -> f64 {
    r.x.psi_alpha_wb.hypot(r.x.psi_beta_wb)
}

fn volts(r: &Row) -> f64 {
    r.v_ab_v[0].hypot(r.v_ab_v[1])
}

/// 0 → 300 rad/s → twice the no-load base speed (184.0 rad/s on 310 V: the speed at which
/// the rated 0.9 Wb alone needs the modulator's 94 % of V_dc/√3, the rest being the low-side
/// shunts' sampling window), then a 0.2 N·m load step at top speed and its removal, with the
/// shipped drive. Before field weakening the same drive hung at ≈ 226 rad/s on the voltage
/// limit (on the whole bus). At the end of each plateau: the speed where the saturated-P law
/// eq. (21) puts it (no integral: ω = (k_p·ω_ref − T_L)/(k_p + B)) within 1 rad/s and steady
/// (peak to peak < 0.5 rad/s over 0.5 s: no sustained oscillation), the rotor flux within 5 %
/// of its weakened reference, |v| within the modulator's 94 % of V_dc/√3; no fault; the torque within τ_max except for
/// the current loops' step response to the 0 → τ_max speed step (ICAD eq. (20) overshoots:
/// ≤ 26 % for ≤ 5 ms). At 300 rad/s the torque ripple is below 0.1 N·m peak to peak.
#[test]
fn field_weakening_to_twice_base_speed_with_a_load_step_at_the_top() {
    let mut b = scenario("field-weakening.toml");
    b.scenario.trace_every = 1; // every PWM period: the ripple
    let base = drive_base_speed_rad_s(&b.spec, b.scenario.vdc_v);
    assert!((base - 184.0).abs() < 0.05, "{base}");
    assert!(b.scenario.events.iter().any(|(_, e)| matches!(
        e,
        hil_sim::sim::Event::Reference(Reference::Speed(w)) if (f64::from(*w) - 2.0 * base).abs() < 0.1
    )));
    let (rows, mode) = b.run(|_| {}).unwrap();
    assert_eq!(mode, Mode::Running);
    assert!(rows.iter().all(|r| !matches!(r.mode, Some(Mode::Fault(_)))));
    // The back-EMF feedforward does what the current trim did: without the trim, the
    // stationary loops' tracking error at ω_e (≈ E/k_p without the feedforward) left the
    // flux 35 % above its reference at the top; with it, the flux holds.
    let mut untrimmed = b.clone();
    untrimmed.spec.current_trim_bandwidth_rad_s = 0.0;
    untrimmed.scenario.trace_every = 200;
    let (u, _) = untrimmed.run(|_| {}).unwrap();
    let top = window(&u, 4.5, 5.0);
    let (psi_u, ref_u) = (mean(&top, flux), mean(&top, |r| r.psi_ref_wb));
    eprintln!(
        "without the current trim: ψ_r {psi_u:.4} Wb against its reference {ref_u:.4} at the top ({:+.1} %)",
        100.0 * (psi_u / ref_u - 1.0)
    );
    assert!((psi_u / ref_u - 1.0).abs() < 0.05);
    let (kp, bf) = (0.05, b.spec.motor.b_nms());
    let v_lin = b.spec.duty_max() * b.scenario.vdc_v / 3f64.sqrt();
    let peak_torque = rows.iter().map(|r| r.torque_nm.abs()).fold(0.0, f64::max);
    let over: Vec<f64> = rows.iter().filter(|r| r.torque_nm.abs() > 2.0 * 1.02).map(|r| r.t_s).collect();
    let overshoot_s = over.last().zip(over.first()).map_or(0.0, |(l, f)| l - f);
    eprintln!(
        "no-load base speed {base:.1} rad/s; peak torque {peak_torque:.3} N·m, beyond τ_max for {:.2} ms from {:?} s",
        1e3 * overshoot_s,
        over.first()
    );
    // 25 % is ICAD eq. (20)'s step overshoot; the voltage limit during the step adds 0.05 %.
    assert!(peak_torque <= 2.0 * 1.26 && overshoot_s <= 5e-3, "torque {peak_torque} N·m beyond τ_max");
    assert!(over.iter().all(|t| (0.3..0.31).contains(t)), "beyond τ_max other than at the speed step");
    let w_top = 368.0; // the scenario's reference, 2 × the base speed to 0.1 rad/s (checked above)
    for (end_s, w_ref, load) in [(3.0, 300.0, 0.0), (5.0, w_top, 0.0), (6.5, w_top, 0.2), (8.0, w_top, 0.0)] {
        let w = window(&rows, end_s - 0.5, end_s);
        let expected = (kp * w_ref - load) / (kp + bf);
        let (speed, wobble) = (mean(&w, |r| r.x.omega_m_rad_s), span(&w, |r| r.x.omega_m_rad_s));
        let (psi, psi_ref) = (mean(&w, flux), mean(&w, |r| r.psi_ref_wb));
        let v_max = w.iter().map(volts).fold(0.0, f64::max);
        let ripple = span(&w, |r| r.torque_nm);
        eprintln!(
            "until {end_s} s: ω {speed:.2} rad/s (eq. (21): {expected:.2}), ±{:.3}; ψ_r {psi:.4} Wb vs reference {psi_ref:.4}; |v| ≤ {v_max:.1} V of {v_lin:.1}; torque ripple {ripple:.4} N·m p-p",
            wobble / 2.0
        );
        assert!((speed - expected).abs() < 1.0, "{end_s}: {speed} vs {expected}");
        assert!(wobble < 0.5, "{end_s}: speed wobbles {wobble} rad/s");
        assert!((psi / psi_ref - 1.0).abs() < 0.05, "{end_s}: flux {psi} vs {psi_ref}");
        assert!(v_max <= v_lin, "{end_s}: |v| {v_max}");
        if end_s == 3.0 {
            assert!(ripple < 0.1, "torque ripple {ripple} N·m at {speed} rad/s");
        }
        if w_ref > base {
            assert!(psi_ref < 0.75 * b.spec.flux_ref_wb, "{end_s}: the field is not weakened: {psi_ref}");
        }
    }
}

/// The analytic motoring envelope of `b`'s drive at `omega_m_rad_s` on its scenario's bus and
/// the modulator's `duty_max` (`envelope_by_grid`, 20 000 slip ratios), N·m — on the motor as
/// the drive has identified it at `row` (its inductance and rotor-resistance estimates, which
/// its envelope runs on: `EnvelopeConfig::identified`).
fn motoring_envelope_nm(b: &Builtin, omega_m_rad_s: f64, row: &Row) -> f64 {
    let motor = b.spec.motor.scaled(1.0, row.rr_scale, row.l_scale, 1.0).unwrap();
    let i_d_rated = b.spec.flux_ref_wb / motor.lm_h();
    let v = b.spec.duty_max() * b.scenario.vdc_v / 3f64.sqrt();
    controller_core::envelope::envelope_by_grid(
        &motor,
        omega_m_rad_s,
        i_d_rated,
        v,
        b.spec.i_ref_max_a,
        20_000,
    )
    .0
}

/// At 300 rad/s (a dynamometer holds it), +τ_max then −τ_max: the drive stays in control.
/// Motoring it delivers its envelope (≈ 0.7 N·m: the bus cannot drive 2 N·m at this speed),
/// within 5 % of the analytic one on its estimates; generating, the full −2 N·m within 2 %, reached within
/// 0.3 s of the reversal. The reversal steps the current reference by ≈ 5.6 A (from +1.6 A
/// of q-axis current to the 4 A limit the other way): the current loops' step response
/// (ICAD eq. (20) overshoots ≈ 25 %) peaks above the 4 A reference limit, but the current
/// stays below 75 % of the 8 A trip level.
#[test]
fn torque_reversal_at_300_rad_s_without_loss_of_control() {
    let b = scenario("torque-reversal.toml");
    let (rows, mode) = b.run(|_| {}).unwrap();
    assert_eq!(mode, Mode::Running);
    assert!(rows.iter().all(|r| !matches!(r.mode, Some(Mode::Fault(_)))));
    let i_peak = rows.iter().map(|r| r.x.i_alpha_a.hypot(r.x.i_beta_a)).fold(0.0, f64::max);
    assert!(i_peak <= 0.75 * b.spec.protection.i_trip_a, "{i_peak} A");
    let motoring = mean(&window(&rows, 1.0, 1.2), |r| r.torque_nm);
    let analytic = motoring_envelope_nm(&b, 300.0, &window(&rows, 1.0, 1.2)[0]);
    let generating = mean(&window(&rows, 1.7, 2.0), |r| r.torque_nm);
    let reached = rows.iter().find(|r| r.t_s > 1.2 && r.torque_nm < -1.96).map(|r| r.t_s - 1.2);
    eprintln!(
        "300 rad/s: motoring {motoring:.3} N·m (envelope {analytic:.3}), generating {generating:.3} N·m, −2 N·m within {reached:?} s of the reversal; peak current {i_peak:.2} A"
    );
    assert!((motoring / analytic - 1.0).abs() < 0.05, "{motoring} vs {analytic}");
    assert!((generating + 2.0).abs() < 0.04, "{generating}");
    assert!(reached.is_some_and(|t| t < 0.3), "{reached:?}");
}

/// Found by trying (issue 52): at 300 rad/s the speed loop's reference 0 brakes at −τ_max on
/// the braking flux; a torque reference of +0.2 N·m then reverses the torque. The flux's
/// back-EMF is beyond the bus at no torque: the drive forces it down with a negative i_d the
/// bus can drive and delivers the torque. Before, the loops saturated with the current
/// uncontrolled and `LossOfControl` tripped 20 ms after the reversal. Asserted: no fault, the
/// flux below its braking value within 50 ms (the rotor's own T_r is 65 ms), 0.2 N·m within
/// 2 % over the last 0.1 s (the motoring envelope at this speed is 0.7 N·m), the current
/// within the 4 A reference limit throughout (the forcing current is bounded by it).
#[test]
fn a_reversal_from_braking_in_field_weakening_forces_the_flux_down() {
    let mut b = scenario("torque-reversal.toml");
    b.scenario.events = vec![(0.0, Event::Enable), (0.5, Event::Reference(Reference::Torque(0.2)))];
    b.scenario.duration_s = 1.0;
    b.scenario.trace_every = 1;
    let (rows, mode) = b.run(|_| {}).unwrap();
    assert_eq!(mode, Mode::Running);
    let braking = mean(&window(&rows, 0.4, 0.5), |r| r.torque_nm);
    let flux = |r: &Row| r.x.psi_alpha_wb.hypot(r.x.psi_beta_wb);
    let psi_braking = mean(&window(&rows, 0.4, 0.5), flux);
    let forced = rows.iter().find(|r| r.t_s > 0.5 && flux(r) < 0.5 * psi_braking).map(|r| r.t_s - 0.5);
    let motoring = mean(&window(&rows, 0.9, 1.0), |r| r.torque_nm);
    let i_peak = rows.iter().map(|r| r.x.i_alpha_a.hypot(r.x.i_beta_a)).fold(0.0, f64::max);
    eprintln!(
        "braking {braking:.3} N·m on {psi_braking:.3} Wb; after the reversal the flux is halved in {forced:?} s, \
         {motoring:.4} N·m at the end; peak current {i_peak:.2} A"
    );
    assert!(braking < -1.9, "{braking}");
    assert!(forced.is_some_and(|t| t < 0.05), "{forced:?}");
    assert!((motoring / 0.2 - 1.0).abs() < 0.02, "{motoring}");
    assert!(i_peak <= b.spec.i_ref_max_a * 1.02, "{i_peak} A");
}

/// A full torque reversal at 2× base speed (368 rad/s on a dynamometer): braking at the
/// envelope (−5 N·m asked, ≈ 4.2 N·m given on the braking flux), then +5 N·m. The flux is
/// forced from ≈ 0.75 Wb to the motoring point's ≈ 0.26 Wb; the loops follow the forcing
/// references at the voltage limit for a few milliseconds, which the stuck-switch check read
/// as a dead direction (`SwitchOpen` 14 ms after the reversal — before the forcing too, when
/// the real flux rose uncontrolled while the model's fell) until it was kept out of the
/// forcing (now out of a forcing step large enough to make a miss: the stuck-switch check's
/// `forcing_a`). Asserted: no fault, the motoring envelope within 5 % over the last 0.2 s,
/// the current below 75 % of the trip level throughout.
#[test]
fn a_full_reversal_from_braking_at_twice_base_speed_stays_in_control() {
    let mut b = scenario("torque-reversal.toml");
    b.scenario.load = hil_sim::sim::LoadModel::Dynamometer { omega_m_rad_s: 368.0 };
    b.scenario.events = vec![
        (0.0, Event::Enable),
        (0.0, Event::Reference(Reference::Torque(-5.0))),
        (0.8, Event::Reference(Reference::Torque(5.0))),
    ];
    b.scenario.duration_s = 1.6;
    b.scenario.trace_every = 1;
    let (rows, mode) = b.run(|_| {}).unwrap();
    assert_eq!(mode, Mode::Running);
    let braking = mean(&window(&rows, 0.7, 0.8), |r| r.torque_nm);
    let motoring = mean(&window(&rows, 1.4, 1.6), |r| r.torque_nm);
    let analytic = motoring_envelope_nm(&b, 368.0, &window(&rows, 1.4, 1.6)[0]);
    let i_peak = rows.iter().map(|r| r.x.i_alpha_a.hypot(r.x.i_beta_a)).fold(0.0, f64::max);
    eprintln!(
        "368 rad/s: braking {braking:.3} N·m, then motoring {motoring:.4} N·m (envelope {analytic:.4}); peak current {i_peak:.2} A"
    );
    assert!(braking < -4.0, "{braking}");
    assert!((motoring / analytic - 1.0).abs() < 0.05, "{motoring} vs {analytic}");
    assert!(i_peak <= 0.75 * b.spec.protection.i_trip_a, "{i_peak} A");
}

/// The 24 V drive braking on its envelope, below base speed and above it (issue 52): within
/// 5 % of its analytic envelope and without ripple (< 2 % of it, peak to peak). Found by
/// trying: the flux forcing judged a braking torque beyond the envelope at the present flux,
/// overstated its slip, and forced the flux down while braking at 43.5 and 86.9 rad/s —
/// −27.7 % and −13.5 % with 0.08–0.10 N·m of ripple, where the drive had given −1.7 % and
/// −1.4 % before the braking envelope.
#[test]
fn the_24_v_drive_brakes_on_its_envelope() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../drives/em-synergy-24v.toml");
    let spec = drive_file::DriveFile::load(&path).unwrap().spec;
    let points = measure(&spec, &spec.motor, 24.0, &[43.5, 86.9, 304.2, 391.1], -1.0).unwrap();
    for p in &points {
        eprintln!(
            "{:>6.1} rad/s: {:.4} N·m vs {:.4} ({:+.2} %), ripple {:.4} N·m, {:.3} of the physical limit",
            p.omega_m_rad_s,
            p.measured_nm,
            p.analytic_nm,
            100.0 * (p.measured_nm / p.analytic_nm - 1.0),
            p.ripple_nm,
            p.measured_nm / p.physical_nm
        );
        assert!((p.measured_nm / p.analytic_nm - 1.0).abs() < 0.05, "{} rad/s", p.omega_m_rad_s);
        assert!(p.ripple_nm < 0.02 * p.analytic_nm, "{} rad/s: ripple {}", p.omega_m_rad_s, p.ripple_nm);
    }
}

/// The torque–speed envelope: at ten speeds from 0.2× to 2× the no-load base speed the
/// steady torque measured in SIL lies within 5 % of the analytic current- and
/// voltage-limited envelope of the same machine (`hil-sim envelope` prints the table and
/// writes envelope.svg). The drive aims at `voltage_margin` = 0.98 of V_dc/√3, so where the
/// voltage limits it the torque is ≈ 0.98² = 96 % of the envelope.
#[test]
fn torque_speed_envelope_within_5_percent_of_the_analytic_one() {
    let spec = drive_file::DriveFile::shipped().unwrap().spec;
    let base = drive_base_speed_rad_s(&spec, 310.0);
    let speeds: Vec<f64> = (0..10).map(|k| base * (0.2 + 0.2 * f64::from(k))).collect();
    for sign in [1.0, -1.0] {
        let points = measure(&spec, &spec.motor, 310.0, &speeds, sign).unwrap();
        for p in &points {
            eprintln!(
                "{} {:>6.1} rad/s: {:.4} N·m vs {:.4} ({:+.2} %)",
                if sign > 0.0 { "motoring  " } else { "generating" },
                p.omega_m_rad_s,
                p.measured_nm,
                p.analytic_nm,
                100.0 * p.relative_error()
            );
            assert_eq!(p.mode, Mode::Running);
            assert!(p.relative_error().abs() < 0.05, "{p:?}");
        }
    }
}

/// Overmodulation (issue 52): the shipped drive with `overmodulation = true` — beyond the
/// board's sampling window one phase at a time gives up its sample, rebuilt from the other two
/// — reaches at least 0.95 of the motor's physical limit (`physical_limit_nm`: |v| ≤ V_dc/√3,
/// |i| ≤ i_ref_max, ψ_r ≤ flux_ref, from the motor alone) at ten speeds from 0.2× to 2× its
/// base speed, motoring and generating, on its default voltage target (the circle; without
/// overmodulation 0.85 motoring above base, the window's 94 % of the bus — `hil-sim envelope
/// drive.toml`). Every point Running: the simulated shunts read zero in a phase without its
/// window, and a sample not rebuilt trips `CurrentSensor` (the same runs with the rebuild
/// taken out: every point faulted); samples with two phases unread, which no sum rebuilds
/// (the drive predicts them), stay below 1 % of the periods. With the voltage target at 1.03 of the circle the steady
/// voltage itself reaches into the hexagon's corners: at least the circle's limit above base
/// speed, its ripple (the corners' sixth harmonic) printed and below 5 % of the torque.
#[test]
fn overmodulation_reaches_the_physical_limit() {
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../drive.toml")).unwrap();
    let text = text.replacen("[controller]\n", "[controller]\novermodulation = true\n", 1);
    let spec = drive_file::DriveFile::parse(std::path::Path::new("drive.toml"), &text).unwrap().spec;
    assert_eq!(spec.voltage_margin, drive_file::drive::DEFAULT_VOLTAGE_MARGIN_OVERMODULATING);
    let base = drive_base_speed_rad_s(&spec, 310.0);
    let speeds: Vec<f64> = (0..10).map(|k| base * (0.2 + 0.2 * f64::from(k))).collect();
    for (margin, sign) in [(spec.voltage_margin, 1.0), (spec.voltage_margin, -1.0), (1.03, 1.0)] {
        let spec = controller_core::drive::DriveSpec { voltage_margin: margin, ..spec };
        for p in measure(&spec, &spec.motor, 310.0, &speeds, sign).unwrap() {
            let of_limit = p.measured_nm / p.physical_nm;
            eprintln!(
                "margin {margin} {} {:>6.1} rad/s: {:.4} N·m, {of_limit:.3} of the physical limit, ripple {:.4} N·m, \
                 a phase rebuilt in {:.1} % of the periods, two unread in {:.2} %",
                if sign > 0.0 { "motoring  " } else { "generating" },
                p.omega_m_rad_s,
                p.measured_nm,
                p.ripple_nm,
                100.0 * p.unsampled_share[0],
                100.0 * p.unsampled_share[1],
            );
            assert_eq!(p.mode, Mode::Running, "{p:?}");
            assert!(of_limit >= 0.95, "{p:?}");
            // Two phases unread (the field passing a vertex between the two periods around a
            // sample, the current predicted): rare.
            assert!(p.unsampled_share[1] < 0.01, "{p:?}");
            if margin > 1.0 && p.omega_m_rad_s >= base {
                assert!(of_limit >= 1.0 && p.ripple_nm < 0.05 * p.measured_nm, "{p:?}");
            }
        }
    }
}

/// The envelope of a large, slow rotor is measured where the drive runs, at the torque it
/// can give: found by trying `hil-sim envelope` on the 500 hp Krause drive, its points were
/// still magnetizing at the end of their 2 s runs (T_r·ln 20 = 2.3 s) and asked for 1 kN·m,
/// below its 2.8 kN·m envelope, so it "measured" 3–33 % of it. At 35.7 rad/s, below base
/// speed on its template's placeholder current gains: Running, within 10 % of the envelope
/// (−8.2 % since the template's loops are synchronous, −7.4 % stationary: those gains hold
/// the flux at 4.40 Wb of 4.8; the 5 % acceptance is the shipped drive's, above) and not
/// above it.
#[test]
fn a_slow_rotors_envelope_is_measured_magnetized_at_its_own_torque() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../drives/krause-3300v.toml");
    let spec = drive_file::DriveFile::load(&path).unwrap().spec;
    assert!(hil_sim::envelope::run_s(&spec) > hil_sim::sim::magnetizing_time_s(&spec) + 1.0);
    let p = measure(&spec, &spec.motor, 3300.0, &[35.7], 1.0).unwrap()[0];
    eprintln!("{p:?}");
    assert_eq!(p.mode, Mode::Running);
    assert!(p.analytic_nm > 1e3, "{p:?}");
    assert!(p.relative_error() > -0.1 && p.relative_error() < 0.01, "{p:?}");
}

/// Dead-time compensation: the switching inverter with 1 µs dead time at 10 rad/s, where the
/// dead time's voltage error (V_dc·t_d/T = 6.2 V per phase) is large against the ≈ 12 V the
/// motor needs. The current's distortion — the RMS of its deviation from its mean in the
/// machine's rotor-flux frame (the fundamental is the mean there), over the last 0.5 s of a
/// 1.5 s run, relative to that mean — is at least 2× smaller with the compensation
/// (`controller_core::svpwm::compensate_dead_time`) than without. (ICAD eq. (20) already
/// rejects most of the dead time's effect: the test prints the distortion without and with
/// compensation, and with no dead time at all.)
#[test]
fn dead_time_compensation_reduces_the_current_distortion() {
    let distortion = |compensate: bool, dead_time_s: f64| {
        let mut b = hil_sim::scenario::speed_step_switching().unwrap();
        b.scenario.inverter = hil_sim::inverter::InverterModel::Switching { dead_time_s };
        b.spec.dead_time_compensation_s = if compensate { dead_time_s } else { 0.0 };
        b.scenario.events = vec![
            (0.0, hil_sim::sim::Event::Enable),
            (0.3, hil_sim::sim::Event::Reference(Reference::Speed(10.0))),
        ];
        b.scenario.duration_s = 1.5;
        b.scenario.trace_every = 1;
        let (rows, mode) = b.run(|_| {}).unwrap();
        assert_eq!(mode, Mode::Running);
        let w = window(&rows, 1.0, 1.5);
        let dq = |r: &Row| {
            let (s, c) = r.x.psi_beta_wb.atan2(r.x.psi_alpha_wb).sin_cos();
            (r.x.i_alpha_a * c + r.x.i_beta_a * s, -r.x.i_alpha_a * s + r.x.i_beta_a * c)
        };
        let (md, mq) = (mean(&w, |r| dq(r).0), mean(&w, |r| dq(r).1));
        let ripple2 = mean(&w, |r| {
            let (d, q) = dq(r);
            (d - md).powi(2) + (q - mq).powi(2)
        });
        ripple2.sqrt() / md.hypot(mq)
    };
    let (without, with, ideal) = (distortion(false, 1e-6), distortion(true, 1e-6), distortion(false, 0.0));
    eprintln!(
        "1 µs dead time at 10 rad/s: current distortion {:.4} % without compensation, {:.4} % with ({:.1}×); no dead time {:.4} %",
        100.0 * without,
        100.0 * with,
        without / with,
        100.0 * ideal
    );
    assert!(without >= 2.0 * with, "{without} vs {with}");
}

/// The bridge off is the diode bridge it is, not a short: after a trip at 148 rad/s (a 1 A
/// offset appears on phase a's sensor: `CurrentSensor`) the phase currents commutate through
/// the freewheeling diodes against the 310 V bus and are below 50 mA within 2 ms; from then
/// on no torque, and the motor coasts — its speed decays as friction alone makes it,
/// ω(t) = ω₀·e^(−B·t/J), within 0.1 %. (Modelled as 0 V, the off bridge shorted the motor:
/// a trip at 150 rad/s braked it at −3.6 N·m with 3 A flowing.)
#[test]
fn a_trip_at_speed_lets_the_motor_coast() {
    let mut b = hil_sim::scenario::speed_step().unwrap();
    b.scenario.events = vec![
        (0.0, hil_sim::sim::Event::Enable),
        (0.3, hil_sim::sim::Event::Reference(Reference::Speed(150.0))),
        (
            1.0,
            hil_sim::sim::Event::Fault(hil_sim::sim::Injection::CurrentSensor {
                phase: 0,
                gain: 1.0,
                offset_a: 1.0,
            }),
        ),
    ];
    b.scenario.duration_s = 1.6;
    b.scenario.trace_every = 1;
    let (rows, mode) = b.run(|_| {}).unwrap();
    assert!(matches!(mode, Mode::Fault(_)), "{mode:?}");
    let t_trip = rows.iter().find(|r| matches!(r.mode, Some(Mode::Fault(_)))).unwrap().t_s;
    let after: Vec<Row> = rows.iter().filter(|r| r.t_s >= t_trip + 2e-3).copied().collect();
    let i_max = after
        .iter()
        .map(|r| {
            let i = controller_core::frames::AlphaBeta { alpha: r.x.i_alpha_a, beta: r.x.i_beta_a }
                .inverse_clarke();
            i.a.abs().max(i.b.abs()).max(i.c.abs())
        })
        .fold(0.0, f64::max);
    let t_max = after.iter().map(|r| r.torque_nm.abs()).fold(0.0, f64::max);
    let (first, last) = (after.first().unwrap(), after.last().unwrap());
    let (j, bf) = (b.plant.j_kgm2(), b.plant.b_nms());
    let coast = first.x.omega_m_rad_s * (-bf / j * (last.t_s - first.t_s)).exp();
    eprintln!(
        "trip at {t_trip:.4} s, {:.2} rad/s: from 2 ms on, phase currents ≤ {:.2e} A, |torque| ≤ {t_max:.2e} N·m; speed {:.3} rad/s after {:.3} s (friction alone: {coast:.3})",
        first.x.omega_m_rad_s,
        i_max,
        last.x.omega_m_rad_s,
        last.t_s - first.t_s
    );
    assert!(i_max < 0.05, "{i_max} A");
    assert!(t_max < 1e-3, "{t_max} N·m");
    assert!((last.x.omega_m_rad_s / coast - 1.0).abs() < 1e-3, "{} vs {coast}", last.x.omega_m_rad_s);
}

/// Bridge off while the motor's line back-EMF is above the bus: the diodes conduct and the
/// motor regenerates. At 387.7 rad/s in field weakening (line EMF ≈ the 310 V bus) the bus
/// sags to 150 V (`DcBusUndervoltage` trips the bridge off): the rotor flux drives current
/// through the diodes into the bus, braking the motor, until its decaying flux has brought the
/// line EMF down to the bus; then the phases open and the motor coasts. The test prints the
/// peak current, the braking torque and the line EMF when the last phase opens, and asserts
/// that EMF is within 2 % of the bus or above it, and below it by the next line-voltage peak
/// (the current dies at its zero crossing after the last EMF peak above the bus; the flux
/// decays ≈ 1 %/ms here).
/// (Before, an open phase never conducted again, whatever its EMF.)
#[test]
fn a_trip_above_the_bus_regenerates_until_the_emf_is_down() {
    let mut b = scenario("field-weakening.toml");
    b.scenario.events.retain(|(t, _)| *t < 4.0);
    b.scenario
        .events
        .push((4.0, hil_sim::sim::Event::Fault(hil_sim::sim::Injection::BusVoltage { vdc_v: 150.0 })));
    b.scenario.duration_s = 4.3;
    b.scenario.trace_every = 1;
    let (rows, mode) = b.run(|_| {}).unwrap();
    assert_eq!(mode, Mode::Fault(controller_core::drive::Fault::DcBusUndervoltage));
    let machine = plant::Machine::new(&b.plant);
    let line_emf = |r: &Row| {
        3f64.sqrt() * {
            let [a, b] = machine.open_circuit_voltage(&r.x);
            a.hypot(b)
        }
    };
    let phase_peak = |r: &Row| {
        let i =
            controller_core::frames::AlphaBeta { alpha: r.x.i_alpha_a, beta: r.x.i_beta_a }.inverse_clarke();
        i.a.abs().max(i.b.abs()).max(i.c.abs())
    };
    let trip = rows.iter().position(|r| matches!(r.mode, Some(Mode::Fault(_)))).unwrap();
    let at_trip = &rows[trip];
    let last_conducting = rows.iter().rposition(|r| phase_peak(r) > 1e-6).unwrap();
    let after = &rows[trip + 1..];
    let i_peak = after.iter().map(phase_peak).fold(0.0, f64::max);
    let braking = after.iter().map(|r| r.torque_nm).fold(0.0, f64::min);
    let end = &rows[last_conducting + 1];
    eprintln!(
        "bus 310 → 150 V at {:.1} rad/s, line EMF {:.1} V: diodes conduct for {:.1} ms after the trip, peak {:.2} A, torque down to {:.3} N·m; \
         the last phase opens at {:.1} rad/s with line EMF {:.1} V against the 150 V bus",
        at_trip.x.omega_m_rad_s,
        line_emf(at_trip),
        1e3 * (end.t_s - at_trip.t_s),
        i_peak,
        braking,
        end.x.omega_m_rad_s,
        line_emf(end)
    );
    assert!(line_emf(at_trip) > 1.5 * 150.0, "the motor's EMF was well above the sagged bus");
    assert!(end.t_s - at_trip.t_s > 5e-3, "the diodes conducted beyond the currents' own decay");
    assert!(braking < -0.1, "regeneration brakes the motor: {braking}");
    // The last current dies near an EMF peak; the line voltage peaks again a sixth of the
    // electrical period later (2.9 ms at 362 rad/s), so the envelope may still be above the
    // bus at the end, but must be below it by that next peak (the flux decays ≈ 1 %/ms).
    let sixth = std::f64::consts::PI / 3.0 / end.x.omega_m_rad_s.abs();
    let next_peak = rows.iter().find(|r| r.t_s >= end.t_s + sixth).unwrap();
    assert!(line_emf(end) > 0.98 * 150.0, "{}", line_emf(end));
    assert!(line_emf(next_peak) < 150.0, "{}", line_emf(next_peak));
    assert!(rows[last_conducting + 1..].iter().all(|r| r.torque_nm.abs() < 1e-9));
}

/// Energy stored in the machine's magnetic field, J: (3/4)·(i_s·ψ_s + i_r·ψ_r) with the rotor
/// current `i_r = (ψ_r − L_m·i_s)/L_r` and `ψ_s = σL_s·i_s + (L_m/L_r)·ψ_r` (amplitude-invariant
/// αβ: three-phase power and energy carry 3/2).
fn magnetic_energy_j(m: &controller_core::motor::MotorParams, r: &Row) -> f64 {
    let (is, psir) = ([r.x.i_alpha_a, r.x.i_beta_a], [r.x.psi_alpha_wb, r.x.psi_beta_wb]);
    let ir = [0, 1].map(|k| (psir[k] - m.lm_h() * is[k]) / m.lr_h());
    let psis = [0, 1].map(|k| m.sigma() * m.ls_h() * is[k] + m.lm_h() / m.lr_h() * psir[k]);
    0.75 * (is[0] * psis[0] + is[1] * psis[1] + ir[0] * psir[0] + ir[1] * psir[1])
}

/// Copper losses of the machine, W: (3/2)·(R_s·|i_s|² + R_r·|i_r|²).
fn copper_loss_w(m: &controller_core::motor::MotorParams, r: &Row) -> f64 {
    let (is, psir) = ([r.x.i_alpha_a, r.x.i_beta_a], [r.x.psi_alpha_wb, r.x.psi_beta_wb]);
    let ir = [0, 1].map(|k| (psir[k] - m.lm_h() * is[k]) / m.lr_h());
    1.5 * (m.rs_ohm() * (is[0] * is[0] + is[1] * is[1]) + m.rr_ohm() * (ir[0] * ir[0] + ir[1] * ir[1]))
}

/// Stopping from twice the base speed at full torque (−τ_max from the speed loop) on a 470 µF
/// DC link fed by a diode rectifier. Returns the rows from the stop command on and the time
/// to below 1 rad/s.
fn brake(file: &str) -> (Builtin, Vec<Row>, f64) {
    let mut b = scenario(file);
    b.scenario.trace_every = 1;
    let (rows, mode) = b.run(|_| {}).unwrap();
    assert_eq!(mode, Mode::Running, "{file}");
    assert!(rows.iter().all(|r| !matches!(r.mode, Some(Mode::Fault(_)))), "{file}");
    let from: Vec<Row> = rows.into_iter().filter(|r| r.t_s >= 3.5).collect();
    let stopped = from.iter().find(|r| r.x.omega_m_rad_s.abs() < 1.0).map(|r| r.t_s - 3.5).unwrap();
    (b, from, stopped)
}

/// With a brake chopper (100 Ω, which the drive switches on at 360 V and off at 350 V: the
/// shipped drive file's `[protection] brake_chopper`) the motor stops at −2 N·m, the bus
/// stays below its 400 V trip, and the energy balance closes within 2 %: the kinetic energy
/// released, less friction, equals the machine's copper losses, the change of its magnetic
/// energy, the link capacitor's and the chopper's energy, less what the rectifier supplied.
/// Without a resistor (the drive's brake output switching nothing) the drive limits its
/// generating torque as the bus nears the trip
/// (`REGEN_LIMIT_START/END`, 370…390 V): the bus stays below the trip and the drive stops
/// without a fault — several times more slowly, on the machine's own losses (the test prints
/// both times).
#[test]
fn braking_with_and_without_a_chopper() {
    let (b, rows, t_chopper) = brake("brake-chopper.toml");
    let m = b.plant;
    let link = b.scenario.dc_link.unwrap();
    let ts = 1.0 / b.spec.pwm_frequency_hz;
    let (first, last) = (rows.first().unwrap(), rows.last().unwrap());
    let kinetic = 0.5 * m.j_kgm2() * (first.x.omega_m_rad_s.powi(2) - last.x.omega_m_rad_s.powi(2));
    let friction: f64 = rows.iter().map(|r| m.b_nms() * r.x.omega_m_rad_s.powi(2) * ts).sum();
    let copper: f64 = rows.iter().map(|r| copper_loss_w(&m, r) * ts).sum();
    let magnetic = magnetic_energy_j(&m, last) - magnetic_energy_j(&m, first);
    let capacitor = 0.5 * link.capacitance_f * (last.vdc_v.powi(2) - first.vdc_v.powi(2));
    let chopper: f64 = rows.iter().map(|r| r.vdc_v * r.i_chopper_a * ts).sum();
    let source: f64 = rows.iter().map(|r| r.vdc_v * r.i_source_a * ts).sum();
    let released = kinetic - friction;
    let accounted = copper + magnetic + capacitor + chopper - source;
    let v_peak = rows.iter().map(|r| r.vdc_v).fold(0.0, f64::max);
    eprintln!(
        "chopper: stopped in {t_chopper:.3} s, bus ≤ {v_peak:.1} V; {kinetic:.1} J kinetic − {friction:.1} J friction = {released:.1} J \
         against copper {copper:.1} + magnetic {magnetic:.2} + capacitor {capacitor:.2} + chopper {chopper:.1} − source {source:.1} = {accounted:.1} J ({:+.2} %)",
        100.0 * (accounted / released - 1.0)
    );
    assert!(v_peak < b.spec.protection.vdc_max_v, "{v_peak}");
    assert!((accounted / released - 1.0).abs() < 0.02, "{accounted} vs {released}");
    // The chopper takes what the machine's losses do not (≈ 40 % here: R_s = 16.2 Ω makes
    // this small motor's copper losses large).
    assert!(chopper > 0.25 * released, "the chopper took {chopper} J of {released}");
    // The drive switched it: current flows exactly in the periods after the drive's brake
    // output was on (rows are consecutive periods), and the output followed its hysteresis.
    let b_cfg = b.spec.protection.brake_chopper.unwrap();
    for w in rows.windows(2) {
        assert_eq!(w[1].i_chopper_a > 0.0, w[0].brake, "t = {}", w[1].t_s);
        if w[1].brake && !w[0].brake {
            assert!(w[1].vdc_v > b_cfg.on_v - 1.0, "on at {} V", w[1].vdc_v);
        }
        if w[0].brake && !w[1].brake {
            assert!(w[1].vdc_v < b_cfg.off_v + 1.0, "off at {} V", w[1].vdc_v);
        }
    }
    let (b, rows, t_limited) = brake("brake-no-chopper.toml");
    // The drive asked for the brake, but no resistor was there to take the energy.
    assert!(rows.iter().any(|r| r.brake) && rows.iter().all(|r| r.i_chopper_a == 0.0));
    let v_peak = rows.iter().map(|r| r.vdc_v).fold(0.0, f64::max);
    eprintln!(
        "no chopper: stopped in {t_limited:.3} s ({:.1}× longer), bus ≤ {v_peak:.1} V",
        t_limited / t_chopper
    );
    assert!(v_peak < b.spec.protection.vdc_max_v, "{v_peak}");
    assert!(t_limited > t_chopper);
}

/// Low-side shunts (issue 19): the simulator's sensors read no current in a phase whose duty
/// leaves less than the board's 1.5 µs on either side of the sample (`[board]
/// sample_window_s`). The shipped drive keeps every duty at most 0.94 and runs the
/// field-weakening scenario to twice its base speed without a fault, every phase measured
/// in every period; the same drive unaware of the window (duties up to 1) reads zero in the
/// phase nearest its top duty and trips on the current sum as soon as it reaches the hexagon.
#[test]
fn the_low_side_sampling_window_is_kept() {
    let b = scenario("field-weakening.toml");
    assert_eq!(b.spec.sample_window_s, 1.5e-6);
    assert!((b.spec.duty_max() - 0.94).abs() < 1e-12);
    let mut aware = b.clone();
    aware.scenario.trace_every = 1;
    let (rows, mode) = aware.run(|_| {}).unwrap();
    assert_eq!(mode, Mode::Running);
    let top = rows.iter().filter_map(|r| r.duty).flatten().fold(0.0, f64::max);
    eprintln!("aware of the window: highest duty {top:.6}");
    assert!(top <= 0.94 + 1e-6 && top > 0.93, "{top}");
    let mut unaware = b.clone();
    unaware.spec.sample_window_s = 0.0;
    unaware.scenario.sensors.low_side_window_s = Some(1.5e-6);
    let (rows, mode) = unaware.run(|_| {}).unwrap();
    let first = rows.iter().find(|r| matches!(r.mode, Some(Mode::Fault(_)))).map(|r| r.t_s);
    eprintln!("unaware: {mode:?} at {first:?} s");
    assert_eq!(mode, Mode::Fault(controller_core::drive::Fault::CurrentSensor));
}

/// A motoring load at the top of field weakening (368 rad/s, where the envelope gives
/// ≈ 0.53 N·m): one the configured τ_max (2 N·m) could hold at a lower speed only slows the
/// motor toward where the envelope's torque holds it — no fault, as a hot motor under load
/// does in the campaign; one beyond 1.1·τ_max (3 N·m: no speed holds it) is a
/// `FollowingError` within issue 18's 0.5 s, named while the motor is still in field
/// weakening (before: only once it had slowed below base speed, after more than 0.5 s).
#[test]
fn an_overload_in_field_weakening_is_named_at_once() {
    let run = |load_nm: f64| {
        let mut b = scenario("field-weakening.toml");
        b.scenario.trace_every = 20;
        b.scenario.duration_s = 6.5;
        for (t, e) in &mut b.scenario.events {
            if let hil_sim::sim::Event::LoadNm(l) = e
                && *t == 5.0
            {
                *l = load_nm;
            }
        }
        b.run(|_| {}).unwrap().0
    };
    let held = run(1.6);
    let end = held.last().unwrap();
    eprintln!("1.6 N·m at the top: {:?}, ω {:.1} rad/s at {:.1} s", end.mode, end.x.omega_m_rad_s, end.t_s);
    assert!(held.iter().all(|r| !matches!(r.mode, Some(Mode::Fault(_)))), "a load τ_max holds: no fault");
    assert!(end.x.omega_m_rad_s < 300.0, "the motor slowed: {}", end.x.omega_m_rad_s);
    let over = run(3.0);
    let trip = over.iter().find(|r| matches!(r.mode, Some(Mode::Fault(_)))).unwrap();
    eprintln!(
        "3 N·m at the top: {:?} after {:.1} ms, at {:.1} rad/s",
        trip.mode,
        1e3 * (trip.t_s - 5.0),
        trip.x.omega_m_rad_s
    );
    assert_eq!(trip.mode, Some(Mode::Fault(controller_core::drive::Fault::FollowingError)));
    assert!(
        trip.t_s - 5.0 <= 0.5 && trip.x.omega_m_rad_s > 184.0,
        "{:.3} s, {:.1} rad/s",
        trip.t_s,
        trip.x.omega_m_rad_s
    );
}

/// A stiff supply on the link (0.05 Ω, 470 µF: R·C = 23.5 µs, under half the 50 µs period):
/// the link's explicit Euler step went unstable, and the run "diverged" at 13 ms blaming the
/// machine (found by trying). Solved exactly over each period, the braking stop runs: the
/// supply holds the bus within a few volts of its 310 V (the drive's braking current, a few
/// amperes, drops 0.05 Ω·i), and the supply takes the energy back.
#[test]
fn a_stiff_supply_holds_the_bus() {
    let mut b = scenario("brake-no-chopper.toml");
    let link = b.scenario.dc_link.as_mut().unwrap();
    (link.source, link.resistance_ohm) = (hil_sim::sim::DcSource::Supply, 0.05);
    assert!(link.resistance_ohm * link.capacitance_f < 0.5 / b.spec.pwm_frequency_hz);
    let (rows, mode) = b.run(|_| {}).unwrap();
    assert_eq!(mode, Mode::Running);
    let (lo, hi) =
        rows.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), r| (lo.min(r.vdc_v), hi.max(r.vdc_v)));
    assert!(lo > 305.0 && hi < 315.0, "bus {lo} … {hi} V");
    assert!(rows.iter().any(|r| r.i_source_a < -0.1), "the supply sinks the braking current");
}

/// The 500 hp Krause machine tuned by `design tune` on its 3 300 V template (what
/// `design tune --template drives/krause-3300v.toml --motor krause-2300v-500hp` writes).
fn tuned_krause() -> design::tune::Tuned {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let template = root.join("drives/krause-3300v.toml");
    let motor =
        drive_file::motor::load(root.join("motors/krause-2300v-500hp.toml").to_str().unwrap()).unwrap();
    let text = std::fs::read_to_string(&template).unwrap();
    design::tune::tune(&template, &text, &motor, None, design::tune::Structure::default()).unwrap()
}

/// A rotor slower than the field-weakening voltage regulator has its flux brought down
/// (`controller_core::drive::FLUX_FALL_TIME_S`): the 500 hp Krause machine (T_r 0.78 s)
/// tuned by `design tune` on its 3 300 V template, magnetized at rest, then 0 → 320 rad/s
/// (1.7 × its no-load base speed) with a 125 N·m load from the same moment. Accelerating at
/// its 2 000 N·m (≈ 180 rad/s²) it enters field weakening faster than its rotor flux falls by
/// itself: with the d-axis current at the envelope's the flux stayed above the falling
/// reference, the voltage left for torque dropped to a quarter (≈ 330 of 1 470 N·m near
/// 175 rad/s), and it had not come within 1 % of the 319.0 rad/s its saturated-P law settles
/// at within 3.5 s of the step (this test with FLUX_FALL_TIME_S = 1e9: 219 rad/s at the end;
/// 5 s were not enough with the stationary loops either). With the flux forced down: within
/// 3 s (2.34 s with the template's synchronous loops, 2.37 s stationary), no fault, and
/// through field weakening (200–300 rad/s) the machine's rotor flux within 10 % of the
/// drive's reference (7.5 % at worst, printed: it lags by about FLUX_FALL_TIME_S times the
/// reference's rate).
#[test]
fn a_slow_rotor_weakens_its_field_in_time() {
    let tuned = tuned_krause();
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("a_slow_rotor_weakens_its_field_in_time");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("tuned.toml"), &tuned.text).unwrap();
    let (step_s, load_nm, omega_ref) = (3.0, 125.0, 320.0);
    let scenario = format!(
        "drive = \"tuned.toml\"\nduration_s = 6.5\nsample_period_s = 1e-3\nvdc_v = 3300.0\n\
         [[events]]\nt_s = 0.0\nkind = \"enable\"\n\
         [[events]]\nt_s = {step_s:.1}\nkind = \"load\"\nvalue = {load_nm:.1}\n\
         [[events]]\nt_s = {step_s:.1}\nkind = \"speed\"\nvalue = {omega_ref:.1}\n"
    );
    let path = dir.join("scenario.toml");
    let b = hil_sim::scenario_file::parse_closed_loop(&path, &scenario).unwrap();
    let kp = match b.spec.speed_law {
        controller_core::speed::SpeedLaw::SaturatedP { kp, .. } => kp,
        ref l => panic!("{l:?}"),
    };
    // eq. (21) without integral: ω = k_p·ω_ref/(k_p + B) − T_L/(k_p + B), B = 0 here.
    let settles = omega_ref - load_nm / kp;
    let (rows, mode) = b.run(|_| {}).unwrap();
    assert_eq!(mode, Mode::Running);
    let reached_s = rows.iter().find(|r| r.x.omega_m_rad_s >= 0.99 * settles).map(|r| r.t_s - step_s);
    eprintln!("settles at {settles:.1} rad/s, reached within 1 % after {reached_s:?} s");
    assert!(
        reached_s.is_some_and(|t| t < 3.0),
        "{reached_s:?}; final {:?}",
        rows.last().map(|r| r.x.omega_m_rad_s)
    );
    let fw: Vec<Row> = rows.iter().filter(|r| (200.0..300.0).contains(&r.x.omega_m_rad_s)).copied().collect();
    assert!(!fw.is_empty());
    let worst = fw.iter().map(|r| (flux(r) / r.psi_ref_wb - 1.0).abs()).fold(0.0, f64::max);
    eprintln!("rotor flux against its reference through field weakening: worst {:.1} %", 100.0 * worst);
    assert!(worst < 0.1, "{worst}");
}

/// The tuned 500 hp drive brakes at its envelope at base speed (178.6 rad/s on 3 300 V):
/// `hil-sim envelope krause-tuned.toml --generating` tripped a false `SwitchOpen` there
/// (found by a helper trying the tools). Its first period Running asks the loops for 197 A
/// of i_q at once; the proportional path's kick saturates the modulator for a period or two,
/// and the voltage regulator, taking that request's excess (≈ 3 700 V) whole at its limited
/// gain, cut the budget by half in 2 ms: the present flux's back-EMF then left no voltage
/// for any torque, until the flux fell and the cycle began again, a torque swinging
/// −313 … +120 N·m at ≈ 30 Hz with the currents far from their references. Now the excess
/// it takes per period is capped (`drive::VOLTAGE_REGULATOR_EXCESS_MAX`): Running, within
/// 15 % of the analytic envelope (−10.1 %, this machine: the regulator's margin and the
/// flying start's rotor-resistance guess), a ripple below 1 % of it.
#[test]
fn the_tuned_3300_v_drive_brakes_at_its_base_speed() {
    let tuned = tuned_krause();
    let spec = tuned.spec;
    let base = drive_base_speed_rad_s(&spec, 3300.0);
    assert!((base - 178.6).abs() < 0.05, "{base}");
    let p = measure(&spec, &spec.motor, 3300.0, &[base], -1.0).unwrap()[0];
    eprintln!("{p:?}: {:+.2} %", 100.0 * p.relative_error());
    assert_eq!(p.mode, Mode::Running);
    assert!(p.relative_error() > -0.15 && p.relative_error() < 0.01, "{p:?}");
    assert!(p.ripple_nm < 0.01 * p.analytic_nm, "{p:?}");
}

/// `hil-sim envelope --plant delorenzo-saturating`: the shipped drive on its motor's
/// saturating twin at 2× base speed, motoring. The run simulates the curve and the physical
/// limit follows it (0.6222 N·m against the linear motor's 0.6217); the drive reaches 0.849
/// of it, as on its own model (0.847): at the voltage limit the shortfall is the modulator's
/// 0.94-duty circle, not the saturation.
#[test]
fn the_envelope_on_a_saturating_plant_is_judged_against_its_own_limit() {
    let spec = drive_file::DriveFile::shipped().unwrap().spec;
    let (plant, saturation) = drive_file::motor::load_model("delorenzo-saturating").unwrap();
    let sat =
        hil_sim::envelope::measure_on(&spec, &plant, saturation.as_ref(), 310.0, &[368.0], 1.0).unwrap()[0];
    let lin = measure(&spec, &spec.motor, 310.0, &[368.0], 1.0).unwrap()[0];
    assert_eq!(sat.mode, Mode::Running);
    assert_ne!(sat.physical_nm, lin.physical_nm);
    assert_ne!(sat.measured_nm, lin.measured_nm);
    let of = sat.measured_nm / sat.physical_nm;
    assert!((0.82..0.88).contains(&of), "{of}");
}

/// Issue 50, the drive on the curve: a drive file whose motor saturates
/// (`drives/delorenzo-saturating.toml`, the shipped drive on its motor's saturating twin)
/// runs its field orientation and machine model on the curve's chord
/// (`drive::DriveSpec::magnetizing`), on its own saturating machine
/// (`DriveFile::saturating_motor`). At half its envelope on 310 V (`hil-sim envelope
/// drives/delorenzo-saturating.toml --torque-fraction 0.5 [--generating]`), at half and
/// 1.25 × base speed (in field weakening), motoring and braking: the torque within 5 % of the
/// torque asked and the rotor flux within 5 % of the drive's reference, no fault — measured
/// within 1.3 %; at a tenth of it, at half and 1.4 × base speed, within 2 %. The same drive
/// without its table (a linear model at the rated chord) on the
/// same machine trips `LossOfControl` at a tenth of its envelope at 1.5 × base speed. The
/// whole sweep, 0.2 … 2 × base speed at 0.1, 0.5 and 1: docs/verification.md.
#[test]
fn a_saturating_drive_runs_on_its_curve() {
    use hil_sim::envelope::{Ask, measure_asking};
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let file = drive_file::DriveFile::load(&root.join("drives/delorenzo-saturating.toml")).unwrap();
    let (spec, (plant, sat)) = (file.spec, file.saturating_motor.unwrap());
    assert!(spec.magnetizing.is_some());
    let base = drive_base_speed_rad_s(&spec, 310.0);
    let speeds = [0.5 * base, 1.25 * base];
    for sign in [1.0, -1.0] {
        let points =
            measure_asking(&spec, &plant, Some(&sat), 310.0, &speeds, sign, Ask::Fraction(0.5)).unwrap();
        for p in points {
            eprintln!(
                "{sign:+} {:.1} rad/s: torque {:+.2} %, flux {:+.2} %",
                p.omega_m_rad_s,
                100.0 * p.torque_error(),
                100.0 * p.flux_error()
            );
            assert_eq!(p.mode, Mode::Running, "{p:?}");
            assert!(p.torque_error().abs() < 0.05 && p.flux_error().abs() < 0.05, "{p:?}");
        }
    }
    // A tenth of the envelope: the torque's error is the slip's, read by the flying start's
    // fit on the curve (`MrasConfig::rotor_resistance_on_curve`; from the q axis's decay it
    // ran 5.3 % over at half base speed).
    for p in
        measure_asking(&spec, &plant, Some(&sat), 310.0, &[0.5 * base, 1.4 * base], 1.0, Ask::Fraction(0.1))
            .unwrap()
    {
        eprintln!("a tenth, {:.1} rad/s: torque {:+.2} %", p.omega_m_rad_s, 100.0 * p.torque_error());
        assert_eq!(p.mode, Mode::Running, "{p:?}");
        assert!(p.torque_error().abs() < 0.02 && p.flux_error().abs() < 0.02, "{p:?}");
    }
    let linear = controller_core::drive::DriveSpec { magnetizing: None, ..spec };
    let p = measure_asking(&linear, &plant, Some(&sat), 310.0, &[1.5 * base], 1.0, Ask::Fraction(0.1))
        .unwrap()[0];
    eprintln!("without the table: {p:?}");
    assert_eq!(p.mode, Mode::Fault(controller_core::fault::Fault::LossOfControl), "{p:?}");
}

/// Issue 50: a saturating machine whose inductances are ℓ × its file's (1, 0.8 and the
/// certified box's corner 0.6, as the campaign scales a curve), magnetized at rest: the
/// magnetizing fit measures the flux linkage built, which is that machine's chord at that
/// flux — `ℓ·c(ℓ·i)` — and the drive solves for ℓ on its curve
/// (`SlowState::set_inductance_on_curve`). On the curve's flat part an error in the linkage
/// is an error in ℓ magnified by `L_chord/L_diff`, so the linkage must not be extrapolated
/// across the knee: the windows slide on until the flux has settled (`MrasConfig::fit`).
/// With the first three windows only, the linkage read far off and clamped to the range's
/// top, and ℓ read 0.846 at ℓ = 1 and at ℓ = 0.8 alike: the rotor flux settled 5.6 % over its
/// reference at ℓ = 1 (the campaign's generating runs at top speed then missed their torque
/// by 5.4–5.9 %). Asserted: ℓ within 3 % and the rotor flux within 2 % of its reference
/// (issue 50 asks 5 %).
#[test]
fn a_saturating_machine_is_identified_on_its_curve_at_any_inductance_scale() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let drive = root.join("drives/delorenzo-saturating.toml");
    for l in [1.0, 0.8, 0.6] {
        let text = format!(
            "drive = {:?}\nduration_s = 0.6\nsample_period_s = 1e-3\nvdc_v = 310.0\n\n\
             [plant]\nform = \"gamma\"\nrs_ohm = 16.2\nrr_ohm = 23.8581234\nlm_h = {:?}\nl_sigma_h = {:?}\n\
             pole_pairs = 1\nj_kgm2 = 0.005\nb_nms = 0.0005\n\n\
             [plant.saturation]\nbeta_per_wb = 0.956813\nexponent = 7.0\n\n\
             [[events]]\nt_s = 0.0\nkind = \"enable\"\n\n[[events]]\nt_s = 0.0\nkind = \"speed\"\nvalue = 0.0\n",
            drive.display().to_string(),
            l * 1.99765926,
            l * 0.102551081
        );
        let b = hil_sim::scenario_file::parse_closed_loop(Path::new("l.toml"), &text).unwrap();
        let (rows, mode) = b.run(|_| {}).unwrap();
        assert_eq!(mode, Mode::Running);
        let last = rows.last().unwrap();
        let error = flux(last) / last.psi_ref_wb - 1.0;
        // The scale in use is ℓ̂ × the chord at the flux model's current; at the reference
        // flux that chord is the rated one, 1.
        let l_error = last.l_scale / l - 1.0;
        eprintln!(
            "ℓ = {l}: ℓ̂·c {:.4} ({:+.2} %), rotor flux {:.4} Wb against {:.4}: {:+.2} %",
            last.l_scale,
            100.0 * l_error,
            flux(last),
            last.psi_ref_wb,
            100.0 * error
        );
        assert!(error.abs() < 0.02, "ℓ = {l}: flux {error}");
        assert!(l_error.abs() < 0.03, "ℓ = {l}: ℓ̂ {l_error}");
    }
}

/// Issue 50: a saturating machine's rotor resistance read at rest on its curve
/// (`MrasConfig::rotor_resistance_on_curve`), with realistic sensors and a switching
/// inverter with dead time — motulator's 2.2 kW machine (`drives/motulator-2kw-saturating.toml`,
/// 8 kHz) at R_r ×1.25 and ℓ 0.9 and 1.1, the 300 W motor's twin (`drives/delorenzo-saturating.toml`,
/// 20 kHz) at R_r ×1.5 and ℓ 0.6 and 1: within 2.5 % (measured within 1.9 %, the realistic
/// sensors' share; the bound is 5 %). The twin at ℓ = 1 read +4.3 % while the fit's
/// linkage was limited to ℓ's range, and +3.0 % while ℓ was solved at the flux model's
/// still-building current (`SlowState::set_inductance_on_curve`). Read from the first
/// windows' decay, a tenth of motulator's machine's campaign, every run above R_r ×1.16,
/// missed its flux. The scale in use at the end (ℓ̂ × the chord at the model's flux) is printed.
#[test]
fn a_saturating_machines_rotor_resistance_is_read_at_rest_on_its_curve() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    // The drive file, its Γ machine (R_s, R_R, unsaturated L_M, L_σ), pole pairs, J, β, the bus.
    let motulator = ("drives/motulator-2kw-saturating.toml", [3.7, 2.5, 0.34, 0.023], 2, 0.015, 0.84, 540.0);
    let twin = (
        "drives/delorenzo-saturating.toml",
        [16.2, 23.8581234, 1.99765926, 0.102551081],
        1,
        0.005,
        0.956813,
        310.0,
    );
    for ((file, [rs, rr, lm, ls], p, j, beta, vdc), r, l) in
        [(motulator, 1.25, 0.9), (motulator, 1.25, 1.1), (twin, 1.5, 0.6), (twin, 1.5, 1.0)]
    {
        let text = format!(
            "drive = {:?}\nduration_s = 0.6\nsample_period_s = 1e-3\nvdc_v = {vdc:?}\n\n\
             [plant]\nform = \"gamma\"\nrs_ohm = {rs:?}\nrr_ohm = {:?}\nlm_h = {:?}\nl_sigma_h = {:?}\n\
             pole_pairs = {p}\nj_kgm2 = {j:?}\nb_nms = 0.0\n\n\
             [plant.saturation]\nbeta_per_wb = {beta:?}\nexponent = 7.0\n\n\
             [inverter]\nkind = \"switching\"\ndead_time_s = 1e-6\n\n\
             [sensors]\ncurrent_lsb_a = 0.00806\ncurrent_noise_rms_a = 0.01\n\
             current_offset_a = [0.0, 0.02, 0.0]\ncurrent_gain = [1.0, 1.0, 1.005]\nencoder_lines = 1024\n\n\
             [[events]]\nt_s = 0.0\nkind = \"enable\"\n\n[[events]]\nt_s = 0.0\nkind = \"speed\"\nvalue = 0.0\n",
            root.join(file).display().to_string(),
            r * rr,
            l * lm,
            l * ls
        );
        let b = hil_sim::scenario_file::parse_closed_loop(Path::new("r.toml"), &text).unwrap();
        let (rows, mode) = b.run(|_| {}).unwrap();
        assert_eq!(mode, Mode::Running, "{file}");
        let last = rows.last().unwrap();
        let error = last.rr_scale / r - 1.0;
        eprintln!(
            "{file}, R_r ×{r}, ℓ {l}: R̂_r ×{:.4} ({:+.2} %); the scale in use ℓ̂·c {:.4}, the flux {:.4} Wb for {:.4}",
            last.rr_scale,
            100.0 * error,
            last.l_scale,
            last.psi_est_wb,
            last.psi_ref_wb
        );
        assert!(error.abs() < 0.025, "{file}, R_r ×{r}, ℓ {l}: ×{}", last.rr_scale);
    }
}

/// The q current the machine carries, A: the stator current's component across the rotor's
/// true flux.
fn q_current(r: &Row) -> f64 {
    let (pa, pb) = (r.x.psi_alpha_wb, r.x.psi_beta_wb);
    (pa * r.x.i_beta_a - pb * r.x.i_alpha_a) / pa.hypot(pb)
}

/// A stationary-frame PI has no integrator at the field's frequency: asked for `i*` it gives
/// `T(jω_e)·i*`, behind by ≈ ω_e·σL_s/k_p — at twice the base speed some of the d current
/// turned into the q axis. The slow step asks the loops for `i*/T` instead
/// (`DriveConfig::reference_gain`), so without the current trim the machine carries the
/// intended q current. The shipped drive at twice its base speed under a 0.2 N·m load (the
/// field-weakening scenario) on seed 002's Sec. VI-D PI (360, 9000) with the trim off: over
/// the load's last 0.5 s the q current across the rotor's true flux is within 1 % of the
/// drive's i_q* (0.01 % here; asked for `i*` alone, 4.5 % short: 0.7495 A of 0.7851 A). The
/// 1 % is the motor model's own error at the top (the drive's R_s against the plant's).
#[test]
fn a_stationary_pi_at_speed_carries_the_intended_q_current_without_the_trim() {
    let mut b = scenario("field-weakening.toml");
    b.spec.current_law = controller_core::current::CurrentLaw::PI_SEED002;
    b.spec.current_trim_bandwidth_rad_s = 0.0;
    b.scenario.trace_every = 20;
    let (rows, mode) = b.run(|_| {}).unwrap();
    assert_eq!(mode, Mode::Running);
    let w = window(&rows, 6.0, 6.5);
    let (i_q, i_q_ref) = (mean(&w, q_current), mean(&w, |r| r.i_q_ref_a));
    let speed = mean(&w, |r| r.x.omega_m_rad_s);
    eprintln!("at {speed:.1} rad/s: i_q {i_q:.4} A carried, {i_q_ref:.4} A intended");
    assert!((i_q / i_q_ref - 1.0).abs() < 0.01, "i_q {i_q} A against {i_q_ref} A");
}

/// A field-frame PI takes the axes' coupling through the field's rotation, `jω_e·σL_s·i`, as
/// a disturbance: a torque that falls by Δi_q puts `ω_e·σL_s·Δi_q` on the d axis, which the
/// proportional path answers with an error `ω_e·σL_s·Δi_q/k_p` until the integrator, at the
/// stator's corner, catches up with `σL_s/R`. Fed forward from the references
/// (`DriveConfig::decoupling_v`, `current_decoupling = true`), the coupling is left to the
/// loops only through their own error. Motulator's 2.2 kW machine (its saturating plant, the
/// synchronous-frame drive of drives/motulator-2kw-saturating.toml) held at 150 rad/s, its torque reference falling from
/// 12 N·m to nothing: from 5/ω_c after the fall (the q loop's own step gone) to σL_s/R, the
/// current misses its reference by at most a fifth of that prediction (0.057 A of 0.433 A;
/// without the decoupling 0.443 A, the prediction's within 2 %).
#[test]
fn a_torque_fall_at_speed_leaves_the_field_frame_loops_on_their_references() {
    use hil_sim::inverter::InverterModel;
    use hil_sim::sensors::SensorModel;
    use hil_sim::sim::{LoadModel, Scenario};
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let file = drive_file::DriveFile::load(&root.join("drives/motulator-2kw-saturating.toml")).unwrap();
    let spec = controller_core::drive::DriveSpec { current_decoupling: true, ..file.spec };
    assert_eq!(spec.current_frame, controller_core::drive::CurrentFrame::Synchronous);
    let (plant, plant_saturation) = file.saturating_motor.map_or((spec.motor, None), |(m, s)| (m, Some(s)));
    let m = spec.motor;
    let sigma_ls_h = m.sigma() * m.ls_h();
    let kp = spec.current_law.kp_v_per_a;
    let omega_c = kp / sigma_ls_h;
    let tau_sigma_s = sigma_ls_h / (m.rs_ohm() + m.rr_ohm() * (m.lm_h() / m.lr_h()).powi(2));
    let (omega_m, fall_s) = (150.0, 0.5);
    let omega_e = f64::from(m.pole_pairs()) * omega_m;
    let b = Builtin {
        name: "decoupling".into(),
        about: String::new(),
        spec,
        plant,
        plant_saturation,
        expect_fault: None,
        scenario: Scenario {
            events: vec![
                (0.0, Event::Enable),
                (0.0, Event::Reference(Reference::Torque(12.0))),
                (fall_s, Event::Reference(Reference::Torque(0.0))),
            ],
            duration_s: fall_s + 0.02,
            vdc_v: file.rated_bus_v().unwrap(),
            substeps: 1,
            trace_every: 1,
            sensors: SensorModel::default(),
            load: LoadModel::Dynamometer { omega_m_rad_s: omega_m },
            inverter: InverterModel::Average,
            dc_link: None,
            comparator: None,
            heating: None,
            extras: plant::Extras::default(),
        },
    };
    let (rows, mode) = b.run(|_| {}).unwrap();
    assert_eq!(mode, Mode::Running);
    let i_q = rows.iter().rev().find(|r| r.t_s < fall_s).unwrap().i_q_ref_a;
    let predicted = omega_e * sigma_ls_h * i_q.abs() / kp;
    let error = window(&rows, fall_s + 5.0 / omega_c, fall_s + tau_sigma_s)
        .iter()
        .map(|r| (r.x.i_alpha_a - r.i_ref_ab_a[0]).hypot(r.x.i_beta_a - r.i_ref_ab_a[1]))
        .fold(0.0, f64::max);
    eprintln!(
        "ω_c {omega_c:.0} rad/s, σL_s/R {:.2} ms, i_q* {i_q:.2} A: the coupling's error {predicted:.3} A, {error:.3} A left",
        tau_sigma_s * 1e3
    );
    assert!(error <= 0.2 * predicted, "{error} A against {predicted} A");
}
