//! Link tests: known vectors, round trips, corruption (property-tested).

use super::schema::tag;
use super::*;
use crate::capture::{CaptureSpec, Edge, Signal, Trigger};
use crate::drive::test_spec;
use crate::drive::{FastOutput, Fault, Measurements, Mode, PhaseCommand, Reference, Telemetry};
use crate::frames::Abc;
use proptest::prelude::*;
use std::vec::Vec;

fn frame_of(c: &Command) -> Vec<u8> {
    let mut out = [0u8; MAX_FRAME];
    let n = command_frame(c, &mut out).unwrap();
    out[..n].to_vec()
}

fn decode_all(bytes: &[u8]) -> (Vec<Command>, LinkStats) {
    let mut d = FrameDecoder::new();
    let mut stats = LinkStats::default();
    let mut got = Vec::new();
    for &b in bytes {
        got.extend(d.push_command(b, &mut stats));
    }
    (got, stats)
}

/// A refusal's byte is a wire contract (a host's decoder, the board's replies): pinned, and
/// every byte beyond them refused.
#[test]
fn nack_codes_are_the_wire_contract() {
    use super::schema::NackReason as N;
    let golden = [
        (N::Faulted, 0),
        (N::NonFinite, 1),
        (N::Configuration, 2),
        (N::NotIdle, 3),
        (N::Unsupported, 4),
        (N::NotConfigured, 5),
        (N::OutOfCertifiedRange, 6),
        (N::NoRecord, 7),
        (N::NotAtRest, 8),
        (N::NoEncoder, 9),
        (N::SpeedOnly, 10),
    ];
    assert_eq!(golden.map(|(r, _)| r), N::ALL);
    for (r, code) in golden {
        assert_eq!((r.code(), N::from_code(code)), (code, Some(r)), "{r:?}");
        let mut buf = [0u8; 8];
        let n = Reply::Nack(r).encode(&mut buf).unwrap();
        assert_eq!(buf.get(..n), Some(&[tag::NACK, code][..]), "{r:?}");
        assert_eq!(Reply::decode(&buf[..n]), Ok(Reply::Nack(r)));
    }
    for code in 11..=u8::MAX {
        assert_eq!(N::from_code(code), None);
        assert!(Reply::decode(&[tag::NACK, code]).is_err(), "{code}");
    }
}

#[test]
fn crc_check_value() {
    assert_eq!(crc16(b"123456789"), 0x29B1);
}

#[test]
fn cobs_known_vectors() {
    // Vectors from the COBS paper / Wikipedia table.
    let cases: [(&[u8], &[u8]); 4] = [
        (&[0x00], &[0x01, 0x01]),
        (&[0x00, 0x00], &[0x01, 0x01, 0x01]),
        (&[0x11, 0x22, 0x00, 0x33], &[0x03, 0x11, 0x22, 0x02, 0x33]),
        (&[0x11, 0x00, 0x00, 0x00], &[0x02, 0x11, 0x01, 0x01, 0x01]),
    ];
    for (raw, enc) in cases {
        let mut out = [0u8; 16];
        let n = cobs_encode(raw, &mut out).unwrap();
        assert_eq!(&out[..n], enc);
        let mut b = enc.to_vec();
        let m = cobs_decode_in_place(&mut b).unwrap();
        assert_eq!(&b[..m], raw);
    }
    // 254 non-zero bytes: one 0xFF block.
    let raw: Vec<u8> = (1..=254).collect();
    let mut out = [0u8; 300];
    let n = cobs_encode(&raw, &mut out).unwrap();
    assert_eq!(n, 255);
    assert_eq!(out[0], 0xFF);
    let mut b = out[..n].to_vec();
    let m = cobs_decode_in_place(&mut b).unwrap();
    assert_eq!(&b[..m], &raw[..]);
}

#[test]
fn every_command_round_trips() {
    let spec = test_spec();
    // The largest Configure: every optional part present.
    let mut largest = spec;
    largest.protection.brake_chopper = Some(crate::drive::BrakeChopper { on_v: 360.0, off_v: 350.0 });
    let thermal =
        crate::drive::ThermalLimit { rated_current_a: 1.0, time_constant_s: 600.0, overload_factor: 1.15 };
    largest.protection.motor_thermal = Some(thermal);
    largest.protection.inverter_thermal = Some(thermal);
    largest.protection.stop_on = crate::drive::FaultSet::STOPPABLE;
    largest.control = crate::drive::Control::VHz { ramp_rad_s2: 200.0, k_u: 1.0, k_w: 4.0 };
    // A straight curve's table: each point exact in f32, the wire's precision.
    largest.magnetizing = Some(crate::magnetics::MagnetizingTable {
        flux_ratio: core::array::from_fn(|k| (k + 1) as f64 * crate::magnetics::TABLE_STEP),
    });
    // The frame, the slip's current and overmodulation share one byte (bits 0, 1, 2): each
    // set alone and all three.
    largest.current_frame = crate::drive::CurrentFrame::Synchronous;
    largest.slip_current = crate::drive::SlipCurrent::Measured;
    largest.overmodulation = true;
    let slip_alone = crate::drive::DriveSpec { slip_current: crate::drive::SlipCurrent::Measured, ..spec };
    let frame_alone =
        crate::drive::DriveSpec { current_frame: crate::drive::CurrentFrame::Synchronous, ..spec };
    let overmodulation_alone = crate::drive::DriveSpec { overmodulation: true, ..spec };
    let cmds = [
        Command::Configure(spec),
        Command::Configure(largest),
        Command::Configure(slip_alone),
        Command::Configure(frame_alone),
        Command::Configure(overmodulation_alone),
        Command::Enable,
        Command::Disable,
        Command::ClearFault,
        Command::SetReference(Reference::Speed(150.0)),
        Command::SetReference(Reference::Position(-3.5)),
        Command::SetReference(Reference::Torque(-0.3)),
        Command::SetReference(Reference::RotatingCurrent { amplitude_a: 1.0, omega_rad_s: 300.0 }),
        Command::Step(Measurements {
            i_abc_a: Abc { a: 1.0, b: -0.5, c: -0.5 },
            vdc_v: 310.0,
            omega_m_rad_s: f32::MIN_POSITIVE,
            theta_m_rad: -1e-30,
        }),
        Command::GetStatus,
        Command::WriteSpeedGains { kp: 0.05, tau_max_nm: 2.0 },
        Command::ReadSpeedGains,
        Command::Stop,
        Command::Commission(crate::commission::CommissionSpec {
            pwm_hz: 20_000.0,
            test_current_a: 1.24,
            current_limit_a: 2.48,
            vdc_min_v: 248.0,
            vdc_max_v: 372.0,
            level_time_s: 3.0,
            rotate: true,
            rated_flux_wb: 0.823,
            no_load_hz: 15.0,
            curve: true,
        }),
        Command::GetCommissionRecord { chunk: 10 },
        Command::GetCommissionStage,
        Command::ArmCapture(CaptureSpec {
            signals: [Signal::Mode, Signal::DutyC, Signal::IA, Signal::OmegaRef],
            trigger: Trigger::Immediate,
            pre_samples: 0,
            decimation: 1,
        }),
        Command::ReadCapture { chunk: 31 },
    ];
    let captures = [Edge::Rising, Edge::Falling, Edge::Either].map(|edge| {
        Command::ArmCapture(CaptureSpec {
            signals: [Signal::IAlpha, Signal::IRefAlpha, Signal::VAlpha, Signal::PsiR],
            trigger: Trigger::Level { signal: Signal::ThetaM, edge, level: -1.5e-3 },
            pre_samples: 255,
            decimation: u16::MAX,
        })
    });
    let cmds: Vec<Command> = cmds.into_iter().chain(captures).collect();
    let stream: Vec<u8> = cmds.iter().flat_map(frame_of).collect();
    let (got, stats) = decode_all(&stream);
    assert_eq!(got, cmds);
    assert_eq!(stats.errors(), 0);
    let mut p = [0u8; MAX_PAYLOAD];
    let n = Command::Configure(largest).encode(&mut p).unwrap();
    assert_eq!(n, MAX_PAYLOAD, "MAX_PAYLOAD is the largest Configure");
    assert!(frame_of(&Command::Configure(largest)).len() <= MAX_FRAME);
    // The board's form: what it decodes is `BoardCommand::of` the command, and back.
    for c in &cmds {
        let mut p = [0u8; MAX_PAYLOAD];
        let n = c.encode(&mut p).unwrap();
        let board = Command::decode_board(&p[..n]).unwrap();
        assert_eq!(board, BoardCommand::of(c), "{c:?}");
        let refused = matches!(c, Command::Configure(_) | Command::Step(_));
        assert_eq!(board.command(), if refused { None } else { Some(*c) }, "{c:?}");
    }
}

#[test]
fn replies_round_trip_bit_exact() {
    let mut drive = crate::drive::Drive::new(crate::drive::DriveConfig::new(&test_spec()).unwrap());
    drive.enable().unwrap();
    let m = Measurements { i_abc_a: Abc { a: 0.1, b: 0.2, c: -0.3 }, vdc_v: 310.0, ..Default::default() };
    let out = drive.step(&m);
    let replies = [
        Reply::Ack,
        Reply::Nack(NackReason::Configuration),
        Reply::Output(out, drive.telemetry()),
        Reply::Output(
            FastOutput { phases: PhaseCommand::Off, mode: Mode::Fault(Fault::Overcurrent), brake: true },
            Telemetry::default(),
        ),
        Reply::Status {
            mode: Mode::Running,
            ridden_through: crate::fault::FaultSet::EMPTY.with(Fault::EncoderImplausible),
            frames_ok: 7,
            frame_errors: u32::MAX,
            timing: super::LoopTiming { cycles_max: 1234, overruns: 2, stack_bytes: 1480 },
            readings: super::BoardReadings {
                i_abc_counts: [2048, 1, u16::MAX],
                vdc_counts: 3100,
                encoder_counts: 7,
            },
        },
        Reply::SpeedGains { kp: 0.05, tau_max_nm: 2.0 },
        Reply::Nack(NackReason::OutOfCertifiedRange),
        Reply::Nack(NackReason::NoRecord),
        Reply::Nack(NackReason::NotAtRest),
        Reply::Nack(NackReason::NoEncoder),
        Reply::Nack(NackReason::SpeedOnly),
        Reply::CommissionRecord { chunk: 3, bytes: core::array::from_fn(|k| k as u8) },
        Reply::Capture {
            state: crate::capture::CaptureState::Triggered,
            samples: 256,
            chunk: 7,
            bytes: core::array::from_fn(|k| (3 * k) as u8),
        },
        Reply::Capture {
            state: crate::capture::CaptureState::Done,
            samples: 8,
            chunk: 0,
            bytes: [0xA5; 128],
        },
    ];
    use crate::commission::{CommissionOutput, Refusal, Stage};
    let stages = [
        Stage::Offsets,
        Stage::Pulse(2),
        Stage::Level(1),
        Stage::Injection(1),
        Stage::Rotate,
        Stage::NoLoad,
        Stage::Done,
        Stage::Refused(Refusal::BusOutOfRange(150.5)),
        Stage::Refused(Refusal::OffsetTooLarge { channel: 2, offset_a: -0.4 }),
        Stage::Refused(Refusal::CurrentDirection { phase: 1 }),
        Stage::Refused(Refusal::Overcurrent(9.5)),
        Stage::Refused(Refusal::Aborted),
        Stage::Refused(Refusal::RotorStalled(7.25)),
    ];
    let commissioning = stages.map(|stage| {
        Reply::Commission(CommissionOutput {
            phases: PhaseCommand::Duty(Abc { a: 0.25, b: 0.5, c: 0.75 }),
            stage,
            v_ab_v: crate::frames::AlphaBeta { alpha: 12.5, beta: -1e-7 },
            i_ref_alpha_a: 0.62,
        })
    });
    for r in replies.into_iter().chain(commissioning) {
        let mut f = [0u8; MAX_FRAME];
        let n = reply_frame(&r, &mut f).unwrap();
        let mut d = FrameDecoder::new();
        let mut got = None;
        for &b in &f[..n] {
            if let Some(p) = d.push(b) {
                got = Some(Reply::decode(p.unwrap()).unwrap());
            }
        }
        assert_eq!(got, Some(r));
    }
}

#[test]
fn corrupted_frames_are_counted_and_the_next_frame_survives() {
    let good = frame_of(&Command::SetReference(Reference::Speed(1.0)));
    // Flip one bit in the body: a CRC (or COBS) error, then the good frame again.
    for i in 0..good.len() - 1 {
        for bit in 0..8 {
            let mut bad = good.clone();
            bad[i] ^= 1 << bit;
            let stream: Vec<u8> = bad.iter().chain(good.iter()).copied().collect();
            let (got, stats) = decode_all(&stream);
            assert_eq!(got.last(), Some(&Command::SetReference(Reference::Speed(1.0))), "byte {i} bit {bit}");
            // A flipped byte may become 0x00 (splitting the frame in two): every piece is
            // rejected, none accepted.
            assert!(stats.errors() >= 1, "byte {i} bit {bit}: {stats:?}");
            assert_eq!(stats.frames_ok, 1);
        }
    }
}

#[test]
fn malformed_payloads_are_rejected_with_their_reason() {
    assert_eq!(Command::decode(&[]), Err(DecodeError::Length));
    assert_eq!(Command::decode(&[0x7E]), Err(DecodeError::UnknownType(0x7E)));
    assert_eq!(Command::decode(&[tag::ENABLE, 0]), Err(DecodeError::Length));
    assert_eq!(Command::decode(&[tag::STEP, 1, 2, 3]), Err(DecodeError::Length));
    let mut p = [0u8; MAX_PAYLOAD];
    let n = Command::SetReference(Reference::Speed(1.0)).encode(&mut p).unwrap();
    p[1] = 9; // reference tag
    assert_eq!(Command::decode(&p[..n]), Err(DecodeError::Value));
    // A motor with a negative resistance is refused at decode.
    let n = Command::Configure(test_spec()).encode(&mut p).unwrap();
    p[1..9].copy_from_slice(&(-1.0f64).to_le_bytes());
    assert_eq!(Command::decode(&p[..n]), Err(DecodeError::Value));
    // Oversized garbage without a delimiter, then a good frame.
    let mut stream = vec![0x55u8; 3 * MAX_FRAME];
    stream.push(0);
    stream.extend(frame_of(&Command::Enable));
    let (got, stats) = decode_all(&stream);
    assert_eq!(got, [Command::Enable]);
    assert_eq!(stats.too_long, 1);
}

proptest! {
    #[test]
    fn cobs_round_trips_and_never_emits_zero(raw in proptest::collection::vec(prop_oneof![Just(0u8), any::<u8>()], 0..700)) {
        let mut enc = vec![0u8; raw.len() + raw.len() / 254 + 2];
        let n = cobs_encode(&raw, &mut enc).unwrap();
        prop_assert!(n <= raw.len() + raw.len() / 254 + 1);
        prop_assert!(enc[..n].iter().all(|&b| b != 0));
        let m = cobs_decode_in_place(&mut enc[..n]).unwrap();
        prop_assert_eq!(&enc[..m], &raw[..]);
    }

    #[test]
    fn arbitrary_bytes_never_panic_and_resync(bytes in proptest::collection::vec(any::<u8>(), 0..600)) {
        let mut stream = bytes.clone();
        stream.push(0);
        stream.extend(frame_of(&Command::GetStatus));
        let (got, _) = decode_all(&stream);
        prop_assert_eq!(got.last(), Some(&Command::GetStatus));
    }

    #[test]
    fn step_round_trips_any_bits(bits in proptest::array::uniform6(any::<u32>())) {
        let f = |i: usize| f32::from_bits(bits[i]);
        let m = Measurements { i_abc_a: Abc { a: f(0), b: f(1), c: f(2) }, vdc_v: f(3), omega_m_rad_s: f(4), theta_m_rad: f(5) };
        let (got, _) = decode_all(&frame_of(&Command::Step(m)));
        let Some(Command::Step(back)) = got.first().copied() else { panic!("no frame") };
        let out = [back.i_abc_a.a, back.i_abc_a.b, back.i_abc_a.c, back.vdc_v, back.omega_m_rad_s, back.theta_m_rad];
        for (i, v) in out.iter().enumerate() { prop_assert_eq!(v.to_bits(), bits[i]); }
    }
}

/// A capture spec with an unknown signal or trigger kind is refused as a value; the
/// capture's replies: `Ack`, `Nack(Configuration)` for a spec the depth refuses, the state
/// with zeros before the record is done, `Nack(NoRecord)` past its end.
#[test]
fn capture_specs_and_replies() {
    use crate::capture::{Capture, CaptureState};
    let spec = CaptureSpec {
        signals: [Signal::IA; 4],
        trigger: Trigger::Level { signal: Signal::IB, edge: Edge::Rising, level: 1.0 },
        pre_samples: 2,
        decimation: 1,
    };
    let mut p = [0u8; MAX_PAYLOAD];
    let n = Command::ArmCapture(spec).encode(&mut p).unwrap();
    assert_eq!(n, 15, "type, 4 signals, kind, signal, level, pre-samples, decimation");
    for (at, bad) in [(1, 24u8), (5, 4), (6, 200)] {
        let mut q = p;
        q[at] = bad;
        assert_eq!(Command::decode(&q[..n]), Err(DecodeError::Value), "byte {at} = {bad}");
        assert_eq!(Command::decode_board(&q[..n]), Err(DecodeError::Value));
    }
    let mut c = Capture::<16>::new();
    assert_eq!(
        arm_capture(&mut c, CaptureSpec { pre_samples: 16, ..spec }),
        Reply::Nack(NackReason::Configuration)
    );
    assert_eq!(arm_capture(&mut c, spec), Reply::Ack);
    assert_eq!(
        read_capture(&c, 1),
        Reply::Capture { state: CaptureState::Armed, samples: 16, chunk: 1, bytes: [0; 128] }
    );
    assert_eq!(read_capture(&c, 2), Reply::Nack(NackReason::NoRecord));
    // A drive alone has no capture.
    let mut drive = crate::drive::Drive::new(crate::drive::DriveConfig::new(&test_spec()).unwrap());
    assert_eq!(
        execute(&mut drive, &Command::ArmCapture(spec), &LinkStats::default()),
        Reply::Nack(NackReason::Unsupported)
    );
}

/// Every mode's byte decodes back to it, and no other byte decodes (3 modes and the 19
/// faults).
#[test]
fn mode_codes_round_trip() {
    let mut modes = 0;
    for c in 0..=u8::MAX {
        if let Some(m) = Mode::from_code(c) {
            assert_eq!(m.code(), c);
            modes += 1;
        }
    }
    assert_eq!(modes, 3 + 19);
}

/// `Configure` on the same motor keeps the machine's state and a latched fault (the drive
/// swaps its configuration: `Drive::reconfigure`); on another motor it makes another drive,
/// Idle and cold. Refused while the bridge is active.
#[test]
fn configure_keeps_the_same_motors_state_and_not_anothers() {
    use crate::drive::{Drive, DriveConfig, Fault, Mode, ThermalLimit};
    let stats = LinkStats::default();
    let mut spec = test_spec();
    spec.protection.motor_thermal =
        Some(ThermalLimit { rated_current_a: 1.0, time_constant_s: 100.0, overload_factor: 1.15 });
    let mut drive = Drive::new(DriveConfig::new(&spec).unwrap());
    let hot = Measurements { i_abc_a: Abc { a: 1.0, b: -1.0, c: 0.0 }, vdc_v: 310.0, ..Default::default() };
    for _ in 0..2 * 1000 * u32::from(spec.slow_divider) {
        drive.step(&hot);
    }
    let theta = drive.thermal_state();
    assert!(theta.0 > 0.0);
    drive.trip(Fault::HardwareBreak);
    let gains = crate::drive::DriveSpec {
        speed_law: crate::speed::SpeedLaw::SaturatedP { kp: 0.08, tau_max_nm: 1.5 },
        ..spec
    };
    assert_eq!(execute(&mut drive, &Command::Configure(gains), &stats), Reply::Ack);
    assert_eq!((drive.thermal_state(), drive.mode()), (theta, Mode::Fault(Fault::HardwareBreak)));
    let mut other = gains;
    other.motor = crate::motor::MotorParams::new(8.0, 12.0, 0.7, 0.75, 0.7, 2, 0.01, 0.001).unwrap();
    other.flux_ref_wb = 0.5;
    assert_eq!(execute(&mut drive, &Command::Configure(other), &stats), Reply::Ack);
    assert_eq!((drive.thermal_state(), drive.mode()), ((0.0, 0.0), Mode::Idle));
    drive.enable().unwrap();
    assert_eq!(execute(&mut drive, &Command::Configure(gains), &stats), Reply::Nack(NackReason::NotIdle));
}

/// `Commission`'s motion byte carries the rotation and the curve as two bits (a spec
/// asking the curve without the rotation goes through, for the board's validation to
/// refuse by name); any other bit is refused as a value. A board older than the curve
/// read 0 and 1 alone, as today.
#[test]
fn the_commission_motion_byte_carries_the_curve() {
    use crate::commission::{CommissionConfig, CommissionSpec, CommissionSpecError};
    let spec = CommissionSpec {
        pwm_hz: 20_000.0,
        test_current_a: 1.0,
        current_limit_a: 2.0,
        vdc_min_v: 250.0,
        vdc_max_v: 370.0,
        level_time_s: 1.0,
        rotate: true,
        rated_flux_wb: 0.823,
        no_load_hz: 15.0,
        curve: true,
    };
    let at = 1 + 6 * 4;
    let mut p = [0u8; MAX_PAYLOAD];
    for (rotate, curve, byte) in [(false, false, 0u8), (true, false, 1), (false, true, 2), (true, true, 3)] {
        let s = CommissionSpec { rotate, curve, ..spec };
        let n = Command::Commission(s).encode(&mut p).unwrap();
        assert_eq!(p.get(at), Some(&byte), "rotate {rotate}, curve {curve}");
        assert_eq!(Command::decode_board(&p[..n]), Ok(BoardCommand::Commission(s)));
        assert_eq!(CommissionConfig::new(s).map(|c| c.curve()).ok(), (rotate || !curve).then_some(curve));
    }
    assert_eq!(
        CommissionConfig::new(CommissionSpec { rotate: false, ..spec }),
        Err(CommissionSpecError::CurveWithoutRotation)
    );
    let n = Command::Commission(spec).encode(&mut p).unwrap();
    for bad in [4u8, 8, 255] {
        let mut q = p;
        if let Some(b) = q.get_mut(at) {
            *b = bad;
        }
        assert_eq!(Command::decode_board(&q[..n]), Err(DecodeError::Value), "motion byte {bad}");
    }
}
