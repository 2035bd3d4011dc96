//! Issue 20's acceptance in SIL: the standstill commissioning (`controller_core::commission`
//! measuring, `hil_sim::identify` estimating) on every shipped motor and on seeded random
//! motors, with realistic sensors (12-bit ADC with offset, gain error and noise) and a
//! switching inverter with 1 µs of dead time.
#![allow(clippy::unwrap_used, clippy::indexing_slicing, clippy::panic)]

use controller_core::commission::{CommissionConfig, CommissionSpec, Refusal};
use controller_core::magnetics::{Form, Saturation};
use controller_core::motor::MotorParams;
use hil_sim::identify::{self, Identified, RunError, Setup};
use hil_sim::sim::Injection;

const PWM_HZ: f32 = 20_000.0;
const DEAD_TIME_S: f64 = 1e-6;

/// The sequence's spec; the no-load test at a quarter of a 60 Hz rating and the DeLorenzo
/// machine's rated flux (380 V, 60 Hz) unless [`Nameplate`] says otherwise.
fn spec(test_current_a: f32, vdc_v: f32) -> CommissionSpec {
    CommissionSpec {
        pwm_hz: PWM_HZ,
        test_current_a,
        current_limit_a: 2.0 * test_current_a,
        vdc_min_v: 0.8 * vdc_v,
        vdc_max_v: 1.2 * vdc_v,
        level_time_s: 3.0,
        rotate: true,
        rated_flux_wb: identify::rated_flux_wb(380.0, 60.0) as f32,
        no_load_hz: 15.0,
        curve: false,
    }
}

/// A motor's rating for the no-load test: rated stator flux (Wb) and frequency (Hz).
#[derive(Clone, Copy)]
struct Nameplate {
    flux_wb: f64,
    hz: f64,
}

fn setup(m: MotorParams, i_test: f32, vdc: f64, seed: u64, plate: Nameplate) -> Setup {
    let mut spec = spec(i_test, vdc as f32);
    spec.rated_flux_wb = plate.flux_wb as f32;
    spec.no_load_hz = (plate.hz / 4.0) as f32;
    let cfg = CommissionConfig::new(spec).unwrap();
    Setup::realistic(m, cfg, vdc, seed)
}

const DELORENZO: Nameplate = Nameplate { flux_wb: 0.8230, hz: 60.0 };

fn identify(s: &Setup) -> (Identified, f64) {
    let (rec, t) = identify::simulate(s, |_, _| {}, || false).unwrap();
    (identify::estimate(&s.config, &rec, s.motor.pole_pairs()).unwrap(), t)
}

/// Issue 20's bounds: R_s and L_m within 3 %; σL_s, R_r and T_r within 5 %; offsets within
/// 1 LSB; the inverter's voltage error within 10 %; every interval holds the true value;
/// ≤ 30 s of motor time (the rotating field included). Beyond the bounds: J within
/// 10 % (`identify::rotation`'s docs: the torque of a small slip is sensitive to the speed
/// measured, more so the stiffer the machine), and the intervals of J and B hold the true
/// values. L_M and L_m are the no-load test's, at rated flux: it must have reached the rated
/// flux within 2 % (the sequence measures the flux by the voltage across the current; the
/// host by the full impedance; below 95 % the estimate refuses); the DC levels' L_M is
/// held to the same 3 %. L_m and R_r are compared under the motor's own leakage split (the
/// terminals cannot tell the split: `identify`'s module docs); the split-free L_M = L_m²/L_r
/// and R_R = R_r·(L_m/L_r)² are held to the same bounds.
fn check(name: &str, m: &MotorParams, s: &Setup) -> String {
    let (id, t) = identify(s);
    let (l_sigma, l_mm, r_rr, tr) = identify::inverse_gamma(m);
    let own_split = (m.lr_h() - m.lm_h()) / (m.ls_h() - m.lm_h());
    let tm = id.t_model(own_split);
    let intervals = id.t_intervals(own_split);
    let rel = |a: f64, b: f64| a / b - 1.0;
    let errors = [
        ("R_s", rel(id.rs_ohm.value, m.rs_ohm()), 0.03, id.rs_ohm.contains(m.rs_ohm())),
        ("σL_s", rel(id.l_sigma_h.value, l_sigma), 0.05, id.l_sigma_h.contains(l_sigma)),
        ("T_r", rel(id.tr_s.value, tr), 0.05, id.tr_s.contains(tr)),
        ("R_R", rel(id.r_rr_ohm.value, r_rr), 0.05, id.r_rr_ohm.contains(r_rr)),
        ("L_M", rel(id.l_mm_h.value, l_mm), 0.03, id.l_mm_h.contains(l_mm)),
        ("R_r", rel(tm.rr_ohm, m.rr_ohm()), 0.05, intervals[1].1.contains(m.rr_ohm())),
        ("L_m", rel(tm.lm_h, m.lm_h()), 0.03, intervals[4].1.contains(m.lm_h())),
        ("L_s", rel(tm.ls_h, m.ls_h()), 0.03, intervals[2].1.contains(m.ls_h())),
        ("L_r", rel(tm.lr_h, m.lr_h()), 0.03, intervals[3].1.contains(m.lr_h())),
    ];
    let mut line = format!("{name:<24}");
    for (what, e, bound, inside) in errors {
        assert!(e.abs() <= bound, "{name}: {what} off by {:+.2} % (bound {} %)", 100.0 * e, 100.0 * bound);
        assert!(inside, "{name}: the interval of {what} misses the true value");
        line += &format!(" {what} {:+.2} %", 100.0 * e);
    }
    let lsb = s.sensors.current_lsb_a;
    for (k, (got, truth)) in id.offsets_a.iter().zip(s.sensors.current_offset_a).enumerate() {
        assert!((got - truth).abs() <= lsb, "{name}: offset {k}: {got} A against {truth} A (LSB {lsb} A)");
    }
    let ve = s.vdc_v * DEAD_TIME_S * f64::from(PWM_HZ);
    let e_ve = rel(id.inverter_error_v.value, ve);
    assert!(e_ve.abs() <= 0.10, "{name}: inverter error {} V against {ve} V", id.inverter_error_v.value);
    assert!(t <= 30.0, "{name}: {t} s of motor time");
    let nl = id.no_load.unwrap();
    let e_flux = rel(nl.flux_wb, nl.rated_flux_wb);
    assert!(e_flux.abs() <= 0.02, "{name}: no-load flux {}", nl.flux_wb);
    let e_lmm_dc = rel(nl.standstill_l_mm_h.value, l_mm);
    assert!(e_lmm_dc.abs() <= 0.03, "{name}: the DC levels' L_M off by {:+.2} %", 100.0 * e_lmm_dc);
    let rot = id.rotation.unwrap();
    let e_j = rel(rot.j_kgm2.value, m.j_kgm2());
    assert!(e_j.abs() <= 0.10, "{name}: J off by {:+.2} %", 100.0 * e_j);
    assert!(rot.j_kgm2.contains(m.j_kgm2()) && rot.b_nms.contains(m.b_nms()), "{name}: {rot:?}");
    line + &format!(
        " V_e {:+.2} % J {:+.2} %, no-load flux {:+.2} % at {:.1} Hz (DC levels' L_M {:+.2} %), {t:.1} s",
        100.0 * e_ve,
        100.0 * e_j,
        100.0 * e_flux,
        nl.omega_e_rad_s / (2.0 * std::f64::consts::PI),
        100.0 * e_lmm_dc
    )
}

/// Every shipped linear motor, each on its bus: the DeLorenzo machines on 310 V at 1.24 A (rated
/// 380 V, 60 Hz), the 500 hp Krause machine on a 2300 V-class bus (3 250 V) at 100 A (2 300 V,
/// 60 Hz), the EM_Synergy motor on 24 V at 2.6 A, its rated peak current (14.85 V, 50 Hz).
#[test]
fn every_shipped_motor_is_identified_within_the_bounds() {
    for (name, _) in drive_file::motor::BUILTIN {
        let (m, saturation) = drive_file::motor::load_model(name).unwrap();
        // A saturating motor is a curve, not one L_m: identifying it is the saturation
        // issue's deliverable 4 (this sequence would meet its linear T model at the
        // unsaturated inductance, a machine that does not exist).
        if saturation.is_some() {
            continue;
        }
        let (i, vdc, (v, hz)) = match name {
            "krause-2300v-500hp" => (100.0, 3250.0, (2300.0, 60.0)),
            "em-synergy-m800006" => (2.6, 24.0, (14.85, 50.0)),
            _ => (1.24, 310.0, (380.0, 60.0)),
        };
        let plate = Nameplate { flux_wb: identify::rated_flux_wb(v, hz), hz };
        println!("{}", check(name, &m, &setup(m, i, vdc, 7, plate)));
    }
}

/// Motors the code has never seen: random parameters within a physical range (a 2 % to
/// 10 % leakage on each side, unequal; L_m 0.05…2 H; T_r 20…600 ms; L_s/R_s 10…200 ms;
/// R_s·I 10…40 V on a 310 V bus; rated flux that of 0.3…0.8 × the test current at no load,
/// rated frequency 40…60 Hz, spread over the motors).
#[test]
fn seeded_random_motors_meet_the_same_bounds() {
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut uniform = |lo: f64, hi: f64| {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        lo + (hi - lo) * (state >> 11) as f64 / (1u64 << 53) as f64
    };
    for k in 0..6 {
        let lm = (uniform(0.05f64.ln(), 2f64.ln())).exp();
        let (ls, lr) = (lm * (1.0 + uniform(0.02, 0.1)), lm * (1.0 + uniform(0.02, 0.1)));
        let rr = lr / uniform(0.02, 0.6);
        let rs = ls / uniform(0.01, 0.2);
        let i = (uniform(10.0, 40.0) / rs) as f32;
        let m = MotorParams::new(rs, rr, ls, lr, lm, 2, 0.01, uniform(0.0, 1e-3)).unwrap();
        // Not drawn from `uniform`: the motors stay those of the sequence before the no-load test.
        let plate =
            Nameplate { flux_wb: ls * f64::from(i) * (0.3 + 0.1 * k as f64), hz: 40.0 + 4.0 * k as f64 };
        println!("{}", check(&format!("random {k} (I = {i:.2} A)"), &m, &setup(m, i, 310.0, 100 + k, plate)));
    }
}

/// A swapped pair of current channels is refused before any DC test; so is an inverted
/// sensor set; a reversed encoder (or wrong line count, or pole pairs) by the rotating field.
#[test]
fn swapped_current_channels_are_refused() {
    let m = drive_file::motor::load("delorenzo-appendix").unwrap();
    let mut s = setup(m, 1.24, 310.0, 3, DELORENZO);
    s.injections.push(Injection::CurrentChannelsSwapped { first: 1, second: 2 });
    let r = identify::simulate(&s, |_, _| {}, || false).unwrap_err();
    assert_eq!(r, RunError::Refused(Refusal::PhaseOrder));
    let mut s = setup(m, 1.24, 310.0, 3, DELORENZO);
    s.sensors.current_gain = [-1.0; 3];
    let r = identify::simulate(&s, |_, _| {}, || false).unwrap_err();
    assert_eq!(r, RunError::Refused(Refusal::CurrentSign));
    // A reversed encoder, an encoder with twice the lines, a wrong pole-pair count: the
    // rotating field's ratio names each.
    let encoder = |injection: Option<Injection>, pole_pairs: u8| {
        let mut s = setup(m, 1.24, 310.0, 3, DELORENZO);
        s.injections.extend(injection);
        let (rec, _) = identify::simulate(&s, |_, _| {}, || false).unwrap();
        identify::estimate(&s.config, &rec, pole_pairs).unwrap_err()
    };
    let e = encoder(Some(Injection::EncoderReversed), 1);
    assert!(e.contains("counts against the rotating field"), "{e}");
    let e = encoder(Some(Injection::EncoderLines { lines: 2048 }), 1);
    assert!(e.contains("line count"), "{e}");
    let e = encoder(None, 2);
    assert!(e.contains("2 pole pairs is wrong"), "{e}");
    // A lead that is open: no current along a.
    let mut s = setup(m, 1.24, 310.0, 3, DELORENZO);
    s.injections.push(Injection::OpenPhase { phase: 0 });
    let r = identify::simulate(&s, |_, _| {}, || false).unwrap_err();
    assert_eq!(r, RunError::Refused(Refusal::NoCurrent));
}

/// The no-load test measures L_m where it runs, not a copy of the standstill value: the
/// simulated machine is linear, so saturation is mimicked by a step of its magnetizing
/// inductance (−12 %, the leakages kept) as the no-load test starts. The DC levels' L_M is
/// the unsaturated one, the no-load test's (and the file's) the saturated one, each within
/// 3 %; the stator flux reached is the rated one within 2 % all the same.
#[test]
fn the_no_load_test_measures_the_magnetizing_inductance_at_its_flux() {
    let m = drive_file::motor::load("delorenzo-appendix").unwrap();
    let k = 0.88;
    let (lls, llr) = (m.ls_h() - m.lm_h(), m.lr_h() - m.lm_h());
    let lm = k * m.lm_h();
    let sat =
        MotorParams::new(m.rs_ohm(), m.rr_ohm(), lm + lls, lm + llr, lm, 1, m.j_kgm2(), m.b_nms()).unwrap();
    let mut s = setup(m, 1.24, 310.0, 3, DELORENZO);
    s.later.push((12.6, Injection::Plant { motor: sat }));
    let (rec, _) = identify::simulate(&s, |_, _| {}, || false).unwrap();
    let id = identify::estimate(&s.config, &rec, 1).unwrap();
    let nl = id.no_load.unwrap();
    let (_, l_mm, _, _) = identify::inverse_gamma(&m);
    let (_, l_mm_sat, _, _) = identify::inverse_gamma(&sat);
    let rel = |a: f64, b: f64| a / b - 1.0;
    println!(
        "L_M: DC levels {:+.2} % of the unsaturated, no-load {:+.2} % of the saturated ({:.4} H vs {:.4} H); flux {:+.2} %",
        100.0 * rel(nl.standstill_l_mm_h.value, l_mm),
        100.0 * rel(nl.l_mm_h.value, l_mm_sat),
        l_mm_sat,
        l_mm,
        100.0 * rel(nl.flux_wb, nl.rated_flux_wb)
    );
    assert!(rel(nl.standstill_l_mm_h.value, l_mm).abs() <= 0.03, "{nl:?}");
    assert!(rel(nl.l_mm_h.value, l_mm_sat).abs() <= 0.03 && nl.l_mm_h.contains(l_mm_sat), "{nl:?}");
    assert_eq!(id.l_mm_h, nl.l_mm_h);
    assert!(rel(nl.flux_wb, nl.rated_flux_wb).abs() <= 0.02, "{nl:?}");
}

/// A nameplate that does not fit the motor: 5 000 V on the 380 V DeLorenzo machine asks for
/// 13 times its flux; the bus lowers the frequency and the test current caps the current,
/// the test reaches 16 % of it, and the estimate is refused, naming both (nothing written by
/// the CLI) — before, the file said "L_M at 16.4 % of the rated flux" and was written.
#[test]
fn a_nameplate_the_motor_cannot_reach_is_refused() {
    let m = drive_file::motor::load("delorenzo-appendix").unwrap();
    let plate = Nameplate { flux_wb: identify::rated_flux_wb(5000.0, 60.0), hz: 60.0 };
    let s = setup(m, 1.24, 310.0, 3, plate);
    let (rec, _) = identify::simulate(&s, |_, _| {}, || false).unwrap();
    let e = identify::estimate(&s.config, &rec, 1).unwrap_err();
    assert!(e.contains("of the rated flux") && e.contains("test current capped"), "{e}");
}

/// A load that seizes while the no-load test accelerates (a coupling the user forgot): the
/// field waits for the rotor, and after `NO_LOAD_RAMP_MAX_S` the sequence refuses with the
/// frequency it reached; the bridge is off.
#[test]
fn a_seized_load_stops_the_no_load_test_by_name() {
    let m = drive_file::motor::load("delorenzo-appendix").unwrap();
    let mut s = setup(m, 1.24, 310.0, 3, DELORENZO);
    // The no-load test starts at ≈ 12.4 s (the stage display of `hil-sim identify`).
    s.later.push((12.6, Injection::LoadSeizure { torque_nm: 5.0 }));
    let r = identify::simulate(&s, |_, _| {}, || false).unwrap_err();
    let RunError::Refused(Refusal::RotorStalled(hz)) = r else { panic!("{r:?}") };
    assert!(hz > 2.0 && hz < 15.0, "the field reached {hz} Hz");
}

/// `hil-sim link <dev> identify`'s protocol against an emulated board: a thread that runs
/// the sequence on its own clock (20 000 periods per stage poll) against an inverse-Γ motor
/// at standstill and answers the link as the firmware's `commissioning` feature does. The
/// host starts it, polls, fetches the record in parts and estimates; Ctrl-C's `Stop` aborts.
#[test]
fn a_board_is_commissioned_over_its_link() {
    use controller_core::commission::{Commissioning, Stage};
    use controller_core::drive::{Measurements, PhaseCommand};
    use controller_core::frames::AlphaBeta;
    use controller_core::link::{self, Command, FrameDecoder, LinkStats, MAX_FRAME, NackReason, Reply};
    use std::io::{Read, Write};
    use std::os::unix::net::UnixStream;
    let (rs, l_sigma, r_rr, tr) = (16.2, 0.0957, 20.8, 0.0647);
    let board = move |mut s: UnixStream| {
        let mut seq: Option<(Commissioning, Option<controller_core::commission::CommissionOutput>)> = None;
        let (mut i, mut psi, mut v) = ([0.0f64; 2], [0.0f64; 2], [0.0f64; 2]);
        let mut dec = FrameDecoder::new();
        let mut stats = LinkStats::default();
        let mut buf = [0u8; 256];
        let mut frame = [0u8; MAX_FRAME];
        loop {
            let Ok(n) = s.read(&mut buf) else { return };
            if n == 0 {
                return;
            }
            for &b in &buf[..n] {
                let Some(cmd) = dec.push_command(b, &mut stats) else { continue };
                let reply = match (&mut seq, cmd) {
                    (_, Command::Commission(spec)) => match CommissionConfig::new(spec) {
                        Ok(cfg) => {
                            seq = Some((Commissioning::new(cfg), None));
                            Reply::Ack
                        }
                        Err(_) => Reply::Nack(NackReason::Configuration),
                    },
                    (Some((c, last)), Command::GetCommissionStage) => {
                        let ts = 5e-5;
                        for _ in 0..20_000 {
                            let abc = AlphaBeta { alpha: i[0] as f32, beta: i[1] as f32 }.inverse_clarke();
                            let m = Measurements { i_abc_a: abc, vdc_v: 310.0, ..Default::default() };
                            let o = c.step(&m);
                            *last = Some(o);
                            let applied = v;
                            v = match o.phases {
                                PhaseCommand::Off => [0.0; 2],
                                PhaseCommand::Duty(_) => {
                                    [f64::from(o.v_ab_v.alpha), f64::from(o.v_ab_v.beta)]
                                }
                            };
                            for _ in 0..20 {
                                for ax in 0..2 {
                                    let dpsi = r_rr * i[ax] - psi[ax] / tr;
                                    let di = (applied[ax] - rs * i[ax] - dpsi) / l_sigma;
                                    psi[ax] += ts / 20.0 * dpsi;
                                    i[ax] += ts / 20.0 * di;
                                }
                            }
                        }
                        last.map_or(Reply::Nack(NackReason::NoRecord), Reply::Commission)
                    }
                    (Some((c, _)), Command::GetCommissionRecord { chunk }) => {
                        link::record_chunk(c.record(), chunk)
                    }
                    (Some((c, _)), Command::Stop) => {
                        c.abort();
                        Reply::Ack
                    }
                    _ => Reply::Nack(NackReason::Unsupported),
                };
                let n = link::reply_frame(&reply, &mut frame).unwrap();
                if s.write_all(&frame[..n]).is_err() {
                    return;
                }
            }
        }
    };
    let run = |interrupt_after: Option<usize>| {
        let (host, dev) = UnixStream::pair().unwrap();
        let t = std::thread::spawn(move || board(dev));
        let mut link = hil_sim::link_client::LinkClient::new(host.try_clone().unwrap(), host)
            .with_reply_timeout(std::time::Duration::from_secs(20));
        let mut spec = spec(1.24, 310.0);
        spec.rotate = false;
        let mut stages = Vec::new();
        let polls = std::cell::Cell::new(0usize);
        let r = identify::over_link(
            &mut link,
            spec,
            std::time::Duration::ZERO,
            |s| {
                polls.set(polls.get() + 1);
                stages.push(s)
            },
            || interrupt_after.is_some_and(|n| polls.get() >= n),
        );
        drop(link);
        t.join().unwrap();
        (r, stages, spec)
    };
    let (r, stages, spec) = run(None);
    let rec = r.unwrap();
    assert!(stages.contains(&Stage::Level(1)) && stages.last() == Some(&Stage::Done), "{stages:?}");
    let id = identify::estimate(&CommissionConfig::new(spec).unwrap(), &rec, 1).unwrap();
    assert!((id.rs_ohm.value / rs - 1.0).abs() < 0.03, "{:?}", id.rs_ohm);
    assert!((id.l_sigma_h.value / l_sigma - 1.0).abs() < 0.05, "{:?}", id.l_sigma_h);
    assert!((id.tr_s.value / tr - 1.0).abs() < 0.05, "{:?}", id.tr_s);
    // Interrupted after two polls: the board is told to stop and the run reports it.
    let (r, _, _) = run(Some(2));
    assert_eq!(r.unwrap_err(), RunError::Interrupted);
}

/// The no-load stator flux of a saturating motor at stator current `i_a` (peak): the Γ
/// branch carries the whole current at the terminals; the inverse-Γ one behind L_σ.
fn no_load_stator_flux_wb(m: &MotorParams, sat: &Saturation, i_a: f64) -> f64 {
    match sat.form {
        Form::Gamma => sat.curve.flux_at_total_current(i_a, 0.0),
        Form::InverseGamma => sat.curve.flux_at_total_current(i_a, 0.0) + (m.ls_h() - m.lm_h()) * i_a,
    }
}

/// The saturation issue's deliverable 4 on a Γ machine whose magnetizing branch saturates,
/// identified with `--curve` (`hil_sim::identify`'s `curve` module): the no-load test reaches
/// the rated flux (its amplitude corrected until the flux lies within 1 %), then measures the
/// curve at 0.3…1.2 of it; the host fits the Γ model on it. Asserted, against the machine's
/// own values at the flux the rated level reached: each curve point's stator flux within
/// 5 % of the machine's at that current and inside its interval, the points spanning
/// 0.3…1.1 of the rated flux at least; R_s within 3 %; L_σ, R_R and T_r = (L_s + L_σ)/R_R
/// within 5 %, each interval holding the truth; J within 10 %; the file carries the curve in
/// the Γ form, and a drive reads it back.
fn check_saturating(name: &str, s: &Setup, sat: &Saturation) -> String {
    assert_eq!(sat.form, Form::Gamma, "{name}: the check knows the Γ machine's values");
    let m = s.motor;
    let (id, t) = identify(s);
    let nl = id.no_load.as_ref().unwrap();
    let rated = nl.rated_flux_wb;
    assert!((nl.flux_wb / rated - 1.0).abs() <= 0.02, "{name}: no-load flux {} against {rated}", nl.flux_wb);
    let mut line = format!("{name}: curve");
    for p in &nl.curve {
        let i = p.current_a.value;
        let truth = no_load_stator_flux_wb(&m, sat, i);
        let e = p.flux_wb.value / truth - 1.0;
        assert!(e.abs() <= 0.05, "{name}: level {:?}: {:+.2} %", p.target_fraction, 100.0 * e);
        assert!(
            p.flux_wb.contains(truth),
            "{name}: level {:?}: the interval misses the truth",
            p.target_fraction
        );
        line += &format!(" {:.2}:{:+.2} %", p.flux_wb.value / rated, 100.0 * e);
    }
    let span = |f: fn(f64, f64) -> f64, init| nl.curve.iter().map(|p| p.flux_wb.value / rated).fold(init, f);
    let (lo, hi) = (span(f64::min, f64::INFINITY), span(f64::max, 0.0));
    assert!(lo <= 0.31 && hi >= 1.1, "{name}: the curve spans {lo:.3}…{hi:.3} of the rated flux");
    // The Γ machine at the flux the rated level reached: L_s its chord there.
    let g = id.gamma.unwrap();
    let truth = identify::gamma_truth(&m, &sat.curve, nl.flux_wb);
    let rel = |a: f64, b: f64| a / b - 1.0;
    let errors = [
        ("R_s", rel(id.rs_ohm.value, m.rs_ohm()), 0.03, id.rs_ohm.contains(m.rs_ohm())),
        ("L_σ", rel(g.l_sigma_h.value, truth.l_sigma_h), 0.05, g.l_sigma_h.contains(truth.l_sigma_h)),
        ("R_R", rel(g.r_r_ohm.value, truth.r_r_ohm), 0.05, g.r_r_ohm.contains(truth.r_r_ohm)),
        ("L_s", rel(g.l_s_h.value, truth.l_s_h), 0.05, g.l_s_h.contains(truth.l_s_h)),
        ("T_r", rel(g.tr_s.value, truth.tr_s), 0.05, g.tr_s.contains(truth.tr_s)),
    ];
    for (what, e, bound, inside) in errors {
        assert!(e.abs() <= bound, "{name}: {what} off by {:+.2} % (bound {} %)", 100.0 * e, 100.0 * bound);
        assert!(inside, "{name}: the interval of {what} misses the true value");
        line += &format!(" {what} {:+.2} %", 100.0 * e);
    }
    let rot = id.rotation.unwrap();
    let e_j = rel(rot.j_kgm2.value, m.j_kgm2());
    line += &format!(" J {:+.2} %", 100.0 * e_j);
    assert!(e_j.abs() <= 0.10, "{line}");
    // The file carries the curve in the Γ form, and reads back to it.
    assert!(identify::saturating_curve(&id).is_some());
    let text = identify::motor_file(&id, 1.0, m.pole_pairs(), m.j_kgm2(), m.b_nms(), "test");
    let (written, back) =
        drive_file::motor::parse_model(std::path::Path::new("identified.toml"), &text).unwrap();
    let back = back.unwrap();
    assert_eq!(back.form, Form::Gamma, "{text}");
    assert!((written.ls_h() / g.l_s_h.value - 1.0).abs() < 1e-9, "{text}");
    for p in &nl.curve {
        let i = back.curve.current_a(p.flux_wb.value);
        assert!((i / p.current_a.value - 1.0).abs() < 1e-6, "{text}");
    }
    assert!(text.contains("curve_flux_wb = [["), "{text}");
    line + &format!(", {} points over {lo:.3}…{hi:.3} of the rated flux, {t:.1} s", nl.curve.len())
}

/// `config` with the no-load test measuring the magnetizing curve.
fn with_curve(config: CommissionConfig) -> CommissionConfig {
    CommissionConfig::new(CommissionSpec { curve: true, ..*config.spec() }).unwrap()
}

/// [`check_saturating`] on the shipped saturating DeLorenzo motor (1.24 A, 380 V 60 Hz) and
/// on motulator's 2.2 kW machine (the saturation issue's reference: L_s(ψ) = 0.34/(1 +
/// (0.84·ψ)⁷), 400 V 50 Hz on 540 V, 7 A).
#[test]
fn a_saturating_motors_curve_is_measured() {
    let (m, sat) = drive_file::motor::load_model("delorenzo-saturating").unwrap();
    let sat = sat.unwrap();
    let mut s = setup(m, 1.24, 310.0, 7, DELORENZO);
    s.saturation = Some(sat);
    s.config = with_curve(s.config);
    println!("{}", check_saturating("delorenzo-saturating", &s, &sat));
    let (m, sat) = drive_file::motor::load_model("../drives/motulator-2kw-saturating.toml").unwrap();
    let sat = sat.unwrap();
    let plate = Nameplate { flux_wb: identify::rated_flux_wb(400.0, 50.0), hz: 50.0 };
    let mut s = setup(m, 7.0, 540.0, 7, plate);
    s.saturation = Some(sat);
    s.config = with_curve(s.config);
    println!("{}", check_saturating("motulator 2.2 kW", &s, &sat));
}

/// A test current deep in saturation (the 300 W twin at 5 A, ten times the current its rated
/// flux needs): the rotor follows the slow field, but the DC levels' step builds almost no
/// flux and the sequence cannot set its no-load test up — the refusal says so, with the
/// levels' currents, where it used to say the rotor had not followed.
#[test]
fn a_test_current_deep_in_saturation_is_named() {
    let (m, sat) = drive_file::motor::load_model("delorenzo-saturating").unwrap();
    let mut s = setup(m, 5.0, 310.0, 7, DELORENZO);
    s.saturation = sat;
    let (rec, _) = identify::simulate(&s, |_, _| {}, || false).unwrap();
    let e = identify::estimate(&s.config, &rec, 1).unwrap_err();
    assert!(e.contains("the rotor followed the slow field") && e.contains("2.500 A to 5.000 A"), "{e}");
}
