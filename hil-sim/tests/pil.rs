//! Processor in the loop (QEMU): needs `qemu-system-arm` and the `pil` target program, so
//! these tests are `#[ignore]`d for plain `cargo test`; `cargo xtask qemu` (part of CI) builds
//! the program and runs them with `--ignored`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]

use hil_sim::pil::PilOptions;
use hil_sim::scenario;
use std::time::Instant;

#[test]
#[ignore = "needs QEMU and the pil target program: `cargo xtask qemu`"]
fn pil_trace_equals_sil_trace_bit_for_bit_for_every_builtin() {
    let opts = PilOptions::default();
    for b in scenario::all().unwrap() {
        let (sil, _) = b.run(|_| {}).unwrap();
        let wall = Instant::now();
        let (pil, link) = b.run_pil(&opts, |_| {}).unwrap();
        let trips = link.round_trips();
        drop(link);
        let secs = wall.elapsed().as_secs_f64();
        println!(
            "{:<22} {:>7} rows, {:>7} round trips, {:6.0} round trips/s, {:5.2}× real time",
            b.name,
            pil.len(),
            trips,
            trips as f64 / secs,
            b.scenario.duration_s / secs
        );
        assert_eq!(sil.len(), pil.len(), "{}", b.name);
        for (i, (s, p)) in sil.iter().zip(&pil).enumerate() {
            // The link does not carry the observer's estimate (`DriveUnderTest::observed_speed_rad_s`).
            let s = &hil_sim::sim::Row { omega_est_rad_s: None, ..*s };
            assert_eq!(s, p, "{}: first difference at row {i} (t = {} s)", b.name, s.t_s);
        }
    }
}

#[test]
#[ignore = "needs QEMU and the pil target program: `cargo xtask qemu`"]
fn target_counts_every_malformed_frame_and_keeps_serving() {
    use controller_core::drive::{Measurements, Mode};
    use controller_core::link::{self, Command, MAX_FRAME, Reply};
    let mut pil =
        hil_sim::pil::Pil::start(&PilOptions::default(), &drive_file::DriveFile::shipped().unwrap().spec)
            .unwrap();
    let good = {
        let mut f = [0u8; MAX_FRAME];
        let n = link::command_frame(&Command::Enable, &mut f).unwrap();
        f[..n].to_vec()
    };
    // 1: bad CRC; 2: invalid COBS (a code byte pointing past the end); 3: too long;
    // 4: too short (type byte only, no CRC); 5: unknown message type; 6: wrong length.
    let mut bad_crc = good.clone();
    bad_crc[1] ^= 0x40;
    let mut noise = vec![0u8];
    noise.extend(bad_crc);
    noise.extend([0x05, 0x11, 0x00]);
    noise.extend(vec![0x33; 2 * MAX_FRAME]);
    noise.push(0);
    noise.extend([0x02, 0x7E, 0x00]);
    for payload in [&[0x7Eu8][..], &[0x02, 0x01]] {
        let mut f = [0u8; MAX_FRAME];
        let n = link::encode_frame(payload, &mut f).unwrap();
        noise.extend(&f[..n]);
    }
    pil.send_raw(&noise).unwrap();
    // No reply to any of them; the next good command is answered.
    match pil.transact(&Command::GetStatus).unwrap() {
        Reply::Status { mode, frames_ok, frame_errors, .. } => {
            assert_eq!(mode, Mode::Idle);
            assert_eq!(frames_ok, 2, "Configure and GetStatus");
            assert_eq!(frame_errors, 6);
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(pil.transact(&Command::Enable).unwrap(), Reply::Ack);
    let m = Measurements { vdc_v: 310.0, ..Default::default() };
    assert!(
        matches!(pil.transact(&Command::Step(m)).unwrap(), Reply::Output(o, _) if o.mode == Mode::Magnetizing)
    );
    assert_eq!(pil.stats().errors(), 0);
}

#[test]
#[ignore = "needs QEMU and the pil target program: `cargo xtask qemu`"]
fn cli_pil_writes_the_same_trace_as_run() {
    let dir = std::env::temp_dir().join(format!("hil-sim-cli-pil-{}", std::process::id()));
    let exe = env!("CARGO_BIN_EXE_hil-sim");
    // `--elf` relative to the working directory (QEMU itself runs in a temporary one).
    let qemu_target = concat!(env!("CARGO_MANIFEST_DIR"), "/../qemu-target");
    for (cmd, sub, elf) in
        [("run", "sil", None), ("pil", "pil", Some("target/thumbv7em-none-eabihf/release/pil"))]
    {
        let mut c = std::process::Command::new(exe);
        c.args([cmd, "fig11-locked-rotor", "--out"]).arg(dir.join(sub)).current_dir(qemu_target);
        if let Some(e) = elf {
            c.args(["--elf", e]);
        }
        let st = c.stdout(std::process::Stdio::null()).status().unwrap();
        assert!(st.success(), "{cmd}");
    }
    let sil = std::fs::read(dir.join("sil/trace.csv")).unwrap();
    let pil = std::fs::read(dir.join("pil/trace.csv")).unwrap();
    assert!(sil == pil, "trace.csv differs between run and pil");
    let summary: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("pil/summary.json")).unwrap()).unwrap();
    assert_eq!(summary["link_host_rx_errors"], 0);
    assert_eq!(summary["drive_mode"], "Running");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Ctrl-C during a PIL run left its FIFO directory behind: now it is removed.
#[test]
#[ignore = "needs QEMU and the pil target program: `cargo xtask qemu`"]
fn interrupted_pil_run_removes_its_fifo_directory() {
    let out = std::env::temp_dir().join(format!("hil-sim-pil-sigint-{}", std::process::id()));
    let child = std::process::Command::new(env!("CARGO_BIN_EXE_hil-sim"))
        .args(["pil", "fig16-icad", "--out"])
        .arg(&out)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let fifo_dir = std::env::temp_dir().join(format!("hil-sim-pil-{}-0", child.id()));
    let t0 = Instant::now();
    while !out.join("trace.csv.partial").exists() && t0.elapsed().as_secs() < 30 {
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    std::thread::sleep(std::time::Duration::from_millis(300));
    assert!(fifo_dir.exists(), "the run's FIFO directory {}", fifo_dir.display());
    let st = std::process::Command::new("kill").args(["-INT", &child.id().to_string()]).status().unwrap();
    assert!(st.success());
    let done = child.wait_with_output().unwrap();
    assert_eq!(done.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&done.stderr).contains("interrupted"));
    assert!(!fifo_dir.exists() && !out.join("trace.csv.partial").exists());
    let _ = std::fs::remove_dir_all(&out);
}

/// The rotating commissioning of the DeLorenzo motor (1.24 A, 380 V 60 Hz on 310 V), with
/// the magnetizing curve or without.
fn delorenzo_spec(curve: bool) -> controller_core::commission::CommissionSpec {
    controller_core::commission::CommissionSpec {
        pwm_hz: 20_000.0,
        test_current_a: 1.24,
        current_limit_a: 2.48,
        vdc_min_v: 248.0,
        vdc_max_v: 372.0,
        level_time_s: 3.0,
        rotate: true,
        rated_flux_wb: 0.823,
        no_load_hz: 15.0,
        curve,
    }
}

/// Issue 20: the commissioning sequence on the emulated Cortex-M4F records exactly what it
/// records in process, so the motor file is the same, bit for bit; a refusal is the same too.
#[test]
#[ignore = "needs QEMU and the pil target program: `cargo xtask qemu`"]
fn pil_commissioning_writes_the_sil_motor_file_bit_for_bit() {
    use controller_core::commission::{CommissionConfig, Refusal};
    use hil_sim::identify::{self, RunError, Setup, Target};
    let m = drive_file::motor::load("delorenzo-appendix").unwrap();
    let spec = delorenzo_spec(false);
    let setup = Setup::realistic(m, CommissionConfig::new(spec).unwrap(), 310.0, 5);
    let file = |target: &Target| {
        let (rec, t) = identify::simulate_on(&setup, target, |_, _| {}, || false).unwrap();
        let id = identify::estimate(&setup.config, &rec, 1).unwrap();
        (rec, t, identify::motor_file(&id, 1.0, 1, 0.005, 0.0005, "pil = sil"))
    };
    let wall = Instant::now();
    let (pil_rec, pil_t, pil_file) = file(&Target::Pil(PilOptions::default()));
    println!("PIL commissioning: {pil_t:.1} s of motor time in {:.1} s", wall.elapsed().as_secs_f64());
    let (sil_rec, sil_t, sil_file) = file(&Target::InProcess);
    assert_eq!(pil_rec, sil_rec);
    assert_eq!(pil_t, sil_t);
    assert_eq!(pil_file, sil_file);
    let mut swapped = setup.clone();
    swapped.injections.push(hil_sim::sim::Injection::CurrentChannelsSwapped { first: 1, second: 2 });
    let r = identify::simulate_on(&swapped, &Target::Pil(PilOptions::default()), |_, _| {}, || false);
    assert_eq!(r.unwrap_err(), RunError::Refused(Refusal::PhaseOrder));
}

/// Issue 50: the magnetizing curve measured on the emulated Cortex-M4F (the link's
/// `Commission` carries the curve) is the one measured in process, record and motor file
/// bit for bit, on the 300 W motor's saturating twin. Found by trying: `hil-sim identify
/// --pil --curve` sent the spec without the curve, so the target ran the rated flux only
/// while the host looked for the curve in its record.
#[test]
#[ignore = "needs QEMU and the pil target program: `cargo xtask qemu`"]
fn pil_measures_the_magnetizing_curve_bit_for_bit() {
    use controller_core::commission::CommissionConfig;
    use hil_sim::identify::{self, Setup, Target};
    let (m, sat) = drive_file::motor::load_model("delorenzo-saturating").unwrap();
    let spec = delorenzo_spec(true);
    let mut setup = Setup::realistic(m, CommissionConfig::new(spec).unwrap(), 310.0, 7);
    setup.saturation = sat;
    let file = |target: &Target| {
        let (rec, t) = identify::simulate_on(&setup, target, |_, _| {}, || false).unwrap();
        let id = identify::estimate(&setup.config, &rec, m.pole_pairs()).unwrap();
        (rec, t, identify::motor_file(&id, 1.0, m.pole_pairs(), 0.005, 0.0005, "pil = sil"))
    };
    let wall = Instant::now();
    let (pil_rec, pil_t, pil_file) = file(&Target::Pil(PilOptions::default()));
    println!("PIL curve: {pil_t:.1} s of motor time in {:.1} s", wall.elapsed().as_secs_f64());
    let (sil_rec, sil_t, sil_file) = file(&Target::InProcess);
    assert!(sil_file.contains("[motor.saturation]"), "{sil_file}");
    assert_eq!(pil_rec, sil_rec);
    assert_eq!(pil_t, sil_t);
    assert_eq!(pil_file, sil_file);
}

/// Issue 19: the capture of a PIL `fig11` run equals the SIL trace. The emulated MCU records
/// into the firmware's capture (`controller_core::capture`, its depth) after every `Step`;
/// read out over the link, each sample equals the in-process run's trace row of the same
/// period, bit for bit: once armed immediately (every 100th period from the first), once on
/// a level trigger (the α current reference rising through 0.5 A, 32 samples before it,
/// every period).
#[test]
#[ignore = "needs QEMU and the pil target program: `cargo xtask qemu`"]
fn pil_capture_of_fig11_equals_the_sil_trace() {
    use controller_core::capture::{CaptureSpec, CaptureState, Edge, RECORD_SAMPLES, Signal, Trigger};
    use hil_sim::capture;
    let b = scenario::fig11_locked_rotor().unwrap();
    assert_eq!(b.scenario.trace_every, 1, "one row per period");
    let (sil, _) = b.run(|_| {}).unwrap();
    let ts = 1.0 / b.spec.pwm_frequency_hz;
    // The trace's values as the drive's f32 (the row holds them widened to f64, exactly).
    let value = |row: &hil_sim::sim::Row, s: Signal| -> f32 {
        match s {
            Signal::IRefAlpha => row.i_ref_ab_a[0] as f32,
            Signal::IRefBeta => row.i_ref_ab_a[1] as f32,
            Signal::PsiR => row.psi_est_wb as f32,
            Signal::DutyA => row.duty.map_or(f32::NAN, |d| d[0] as f32),
            _ => unreachable!(),
        }
    };
    let signals = [Signal::IRefAlpha, Signal::IRefBeta, Signal::PsiR, Signal::DutyA];
    let same = |a: f32, b: f32| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan());
    let level_trigger = Trigger::Level { signal: Signal::IRefAlpha, edge: Edge::Rising, level: 0.5 };
    for (trigger, pre, every) in [(Trigger::Immediate, 0u16, 100u16), (level_trigger, 32, 1)] {
        let spec = CaptureSpec { signals, trigger, pre_samples: pre, decimation: every };
        let mut pil = hil_sim::pil::Pil::start(&PilOptions::default(), &b.spec).unwrap();
        capture::arm(&mut |c| pil.transact(c), spec).unwrap();
        b.simulate(&mut pil, |_| {}, |_| Ok(())).unwrap();
        let req = capture::Request { spec, period_s: ts, shown: 4, then: None };
        let (state, record) = capture::read(&mut |c| pil.transact(c), &req).unwrap();
        assert_eq!(state, CaptureState::Done, "{trigger:?}");
        let record = record.unwrap();
        assert_eq!(record.samples.len(), RECORD_SAMPLES);
        // The trace's rows the record holds: sample j is period first + j·every.
        let first = match trigger {
            Trigger::Immediate => 0,
            Trigger::Level { level, .. } => {
                let x = |k: usize| value(&sil[k], Signal::IRefAlpha);
                let fired = (usize::from(pre).max(1)..sil.len())
                    .find(|&k| x(k - 1) < level && x(k) >= level)
                    .expect("the reference crosses 0.5 A");
                println!("level trigger at period {fired} (t = {:.5} s)", fired as f64 * ts);
                fired - usize::from(pre)
            }
        };
        for (j, sample) in record.samples.iter().enumerate() {
            let row = &sil[first + j * usize::from(every)];
            for (c, s) in signals.iter().enumerate() {
                assert!(
                    same(sample[c], value(row, *s)),
                    "{trigger:?}: sample {j} (t = {} s), {}: PIL {} vs SIL {}",
                    row.t_s,
                    s.name(),
                    sample[c],
                    value(row, *s)
                );
            }
        }
        println!("{trigger:?}: {} samples equal the SIL trace", record.samples.len());
    }
}
