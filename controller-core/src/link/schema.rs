//! Message schema: host → drive [`Command`]s and drive → host [`Reply`]s, each a type byte
//! and its fields in a fixed little-endian layout (`f32`/`f64` as IEEE-754 bits).

use super::framing::{BufferFull, MAX_PAYLOAD, encode_frame};
use crate::capture::{CHANNELS, CHUNK_BYTES, CaptureSpec, CaptureState, Edge, Signal, Trigger};
use crate::commission::{CommissionOutput, CommissionSpec, RECORD_BYTES, Record, Refusal, Stage};
use crate::current::CurrentLaw;
use crate::discretize::{ContinuousSection, Discretization};
use crate::drive::{
    BrakeChopper, CurrentFrame, DriveSpec, FastOutput, FaultSet, Measurements, Mode, PhaseCommand,
    PositionLaw, Protection, Reference, Telemetry, ThermalLimit,
};
use crate::frames::{Abc, AlphaBeta};
use crate::motor::MotorParams;
use crate::speed::SpeedLaw;
use crate::supervisor::THRESHOLD_COUNT;

/// Message-level errors.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DecodeError {
    /// Unknown message type byte.
    UnknownType(u8),
    /// Payload shorter or longer than the type requires.
    Length,
    /// An enum tag or value out of range (e.g. a motor parameter that is not positive).
    Value,
}

/// Little-endian field writer.
#[derive(Debug)]
struct Writer<'a> {
    buf: &'a mut [u8],
    n: usize,
}

impl<'a> Writer<'a> {
    fn new(buf: &'a mut [u8]) -> Self {
        Self { buf, n: 0 }
    }
    fn bytes(&mut self, b: &[u8]) -> Result<(), BufferFull> {
        let end = self.n + b.len();
        self.buf.get_mut(self.n..end).ok_or(BufferFull)?.copy_from_slice(b);
        self.n = end;
        Ok(())
    }
    fn u8(&mut self, v: u8) -> Result<(), BufferFull> {
        self.bytes(&[v])
    }
    fn u16(&mut self, v: u16) -> Result<(), BufferFull> {
        self.bytes(&v.to_le_bytes())
    }
    /// Out of line, and `f32` through it: the replies' dozens of 4-byte fields share one
    /// bounds check and copy in the firmware's flash (−120 B).
    #[inline(never)]
    fn u32(&mut self, v: u32) -> Result<(), BufferFull> {
        self.bytes(&v.to_le_bytes())
    }
    fn f32(&mut self, v: f32) -> Result<(), BufferFull> {
        self.u32(v.to_bits())
    }
    fn f64(&mut self, v: f64) -> Result<(), BufferFull> {
        self.bytes(&v.to_le_bytes())
    }
    fn abc(&mut self, v: Abc) -> Result<(), BufferFull> {
        self.f32(v.a)?;
        self.f32(v.b)?;
        self.f32(v.c)
    }
    fn ab(&mut self, v: AlphaBeta) -> Result<(), BufferFull> {
        self.f32(v.alpha)?;
        self.f32(v.beta)
    }
}

/// Little-endian field reader.
#[derive(Debug)]
struct Reader<'a> {
    rest: &'a [u8],
}

impl<'a> Reader<'a> {
    fn take<const N: usize>(&mut self) -> Result<[u8; N], DecodeError> {
        let (head, tail) = self.rest.split_first_chunk::<N>().ok_or(DecodeError::Length)?;
        self.rest = tail;
        Ok(*head)
    }
    fn u8(&mut self) -> Result<u8, DecodeError> {
        Ok(u8::from_le_bytes(self.take()?))
    }
    fn u16(&mut self) -> Result<u16, DecodeError> {
        Ok(u16::from_le_bytes(self.take()?))
    }
    fn u32(&mut self) -> Result<u32, DecodeError> {
        Ok(u32::from_le_bytes(self.take()?))
    }
    fn f32(&mut self) -> Result<f32, DecodeError> {
        Ok(f32::from_le_bytes(self.take()?))
    }
    fn f64(&mut self) -> Result<f64, DecodeError> {
        Ok(f64::from_le_bytes(self.take()?))
    }
    fn abc(&mut self) -> Result<Abc, DecodeError> {
        Ok(Abc { a: self.f32()?, b: self.f32()?, c: self.f32()? })
    }
    fn ab(&mut self) -> Result<AlphaBeta, DecodeError> {
        Ok(AlphaBeta { alpha: self.f32()?, beta: self.f32()? })
    }
    fn f64x3(&mut self) -> Result<[f64; 3], DecodeError> {
        Ok([self.f64()?, self.f64()?, self.f64()?])
    }
    fn finish(self) -> Result<(), DecodeError> {
        if self.rest.is_empty() { Ok(()) } else { Err(DecodeError::Length) }
    }
}

/// Host → drive.
// `Configure` is ~200 bytes, the others ≤ 25; no heap to box it in, and a command lives only
// between decoding and handling.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Command {
    /// Replace the drive configuration (only while Idle); answered by `Ack` or
    /// `Nack(Configuration)`.
    Configure(DriveSpec),
    /// [`crate::drive::Drive::enable`].
    Enable,
    /// [`crate::drive::Drive::disable`].
    Disable,
    /// [`crate::drive::Drive::clear_fault`].
    ClearFault,
    /// [`crate::drive::Drive::set_reference`].
    SetReference(Reference),
    /// One PWM period's measurements (processor in the loop); answered by `Output`.
    Step(Measurements),
    /// Ask for the drive's status and link counters; answered by `Status`.
    GetStatus,
    /// Replace the saturated-P speed-loop gains (seed 002 eq. (21)) while Idle; the board
    /// accepts only values inside the certified ranges of `drive.toml`.
    WriteSpeedGains {
        /// N·m per rad/s.
        kp: f32,
        /// Torque limit τ_max, N·m.
        tau_max_nm: f32,
    },
    /// Ask for the speed-loop gains; answered by `SpeedGains`.
    ReadSpeedGains,
    /// A controlled stop ([`crate::drive::Drive::controlled_stop`]): brake to standstill,
    /// then the bridge off.
    Stop,
    /// Start a commissioning sequence ([`crate::commission`]) in place of the drive; `Step`
    /// is then answered by `Commission`. `Ack`, or `Nack(Configuration)` for a spec that
    /// `CommissionConfig::new` rejects.
    Commission(CommissionSpec),
    /// Ask for part `chunk` of the finished sequence's record ([`RECORD_CHUNK_BYTES`] each);
    /// answered by `CommissionRecord`, or `Nack(NoRecord)`.
    GetCommissionRecord {
        /// 0 … [`RECORD_CHUNKS`] − 1.
        chunk: u8,
    },
    /// Ask where the commissioning sequence stands; answered by `Commission` (its last
    /// step's output), or `Nack(NoRecord)` when none was started.
    GetCommissionStage,
    /// Arm the capture ([`crate::capture`]) with this spec, dropping any record; `Ack`, or
    /// `Nack(Configuration)` for a spec [`Capture::arm`](crate::capture::Capture::arm)
    /// refuses.
    ArmCapture(CaptureSpec),
    /// Ask where the capture stands and, once it is done, for part `chunk` of its record;
    /// answered by `Capture`, or `Nack(NoRecord)` past the record's end.
    ReadCapture {
        /// 0 … samples/8 − 1.
        chunk: u8,
    },
}

/// The reply to `GetCommissionRecord { chunk }` for `record` (`None`: not finished).
pub fn record_chunk(record: Option<&Record>, chunk: u8) -> Reply {
    let mut all = [0u8; RECORD_BYTES];
    let Some(_) = record.and_then(|r| r.write_bytes(&mut all)) else {
        return Reply::Nack(NackReason::NoRecord);
    };
    let start = usize::from(chunk) * RECORD_CHUNK_BYTES;
    match all.get(start..) {
        Some(part) if !part.is_empty() => {
            let mut bytes = [0u8; RECORD_CHUNK_BYTES];
            for (b, x) in bytes.iter_mut().zip(part) {
                *b = *x;
            }
            Reply::CommissionRecord { chunk, bytes }
        }
        _ => Reply::Nack(NackReason::NoRecord),
    }
}

/// Bytes of a record per `CommissionRecord` reply.
pub const RECORD_CHUNK_BYTES: usize = 128;
/// `CommissionRecord` replies that carry a whole record.
pub const RECORD_CHUNKS: u8 = RECORD_BYTES.div_ceil(RECORD_CHUNK_BYTES) as u8;

/// Why a command was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NackReason {
    /// A fault is latched.
    Faulted,
    /// A value was not finite.
    NonFinite,
    /// The drive specification was rejected by `DriveConfig::new`.
    Configuration,
    /// The command needs the drive Idle.
    NotIdle,
    /// The command is not supported by this endpoint.
    Unsupported,
    /// No drive configuration yet: send `Configure` first.
    NotConfigured,
    /// A gain outside the certified range.
    OutOfCertifiedRange,
    /// No finished commissioning record (or no such part of it).
    NoRecord,
}

/// Drive → host.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Reply {
    /// Command accepted.
    Ack,
    /// Command refused.
    Nack(NackReason),
    /// Result of a `Step` and its signals ([`Drive::telemetry`](crate::drive::Drive::telemetry)),
    /// or streamed telemetry of the board.
    Output(FastOutput, Telemetry),
    /// The saturated-P speed-loop gains in use.
    SpeedGains {
        /// N·m per rad/s.
        kp: f32,
        /// Torque limit τ_max, N·m.
        tau_max_nm: f32,
    },
    /// Result of a `Step` during commissioning.
    Commission(CommissionOutput),
    /// Part of a commissioning record: bytes `chunk·RECORD_CHUNK_BYTES …` of
    /// `Record::write_bytes`, zero-padded after the end.
    CommissionRecord {
        /// Which part.
        chunk: u8,
        /// Its bytes.
        bytes: [u8; RECORD_CHUNK_BYTES],
    },
    /// The capture's state and, once done, part `chunk` of its record
    /// ([`Capture::chunk`](crate::capture::Capture::chunk); zeros before).
    Capture {
        /// Where it stands.
        state: CaptureState,
        /// Samples in a record (the buffer's depth).
        samples: u16,
        /// Which part.
        chunk: u8,
        /// Its bytes.
        bytes: [u8; CHUNK_BYTES],
    },
    /// Mode and the receiver's counters.
    Status {
        /// Drive mode.
        mode: Mode,
        /// Frames accepted by the drive.
        frames_ok: u32,
        /// Frames the drive rejected.
        frame_errors: u32,
        /// The control interrupt's timing (zero where it is not measured: PIL).
        timing: LoopTiming,
        /// The board's raw readings of the last control period (zero without a board).
        readings: BoardReadings,
    },
}

/// The board's raw readings at the last control period, before any scaling: what bring-up
/// checks against the drive file's scalings (docs/firmware.md's checklist).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BoardReadings {
    /// Phase-current ADC codes a, b, c.
    pub i_abc_counts: [u16; 3],
    /// DC-bus ADC code.
    pub vdc_counts: u16,
    /// Quadrature counter (the encoder timer's count).
    pub encoder_counts: u16,
}

/// The control loop's resources on a board: the control interrupt's timing (DWT cycle
/// counter) — the longest step seen and the steps that took a whole PWM period or more — and
/// the deepest the stack it and the tasks run on has been (zero where not measured: PIL).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LoopTiming {
    /// Most CPU cycles one control interrupt took.
    pub cycles_max: u32,
    /// Control interrupts that took at least a PWM period (their compare values came late).
    pub overruns: u32,
    /// The main stack's high-water mark since reset, bytes (its painted words overwritten).
    pub stack_bytes: u32,
}

pub(crate) mod tag {
    pub const CONFIGURE: u8 = 0x01;
    pub const ENABLE: u8 = 0x02;
    pub const DISABLE: u8 = 0x03;
    pub const CLEAR_FAULT: u8 = 0x04;
    pub const SET_REFERENCE: u8 = 0x05;
    pub const STEP: u8 = 0x06;
    pub const GET_STATUS: u8 = 0x07;
    pub const WRITE_SPEED_GAINS: u8 = 0x08;
    pub const READ_SPEED_GAINS: u8 = 0x09;
    pub const STOP: u8 = 0x0A;
    pub const COMMISSION: u8 = 0x0B;
    pub const GET_COMMISSION_RECORD: u8 = 0x0C;
    pub const GET_COMMISSION_STAGE: u8 = 0x0D;
    pub const ARM_CAPTURE: u8 = 0x0E;
    pub const READ_CAPTURE: u8 = 0x0F;
    pub const ACK: u8 = 0x81;
    pub const NACK: u8 = 0x82;
    pub const OUTPUT: u8 = 0x83;
    pub const STATUS: u8 = 0x84;
    pub const SPEED_GAINS: u8 = 0x85;
    pub const COMMISSION_OUTPUT: u8 = 0x86;
    pub const COMMISSION_RECORD: u8 = 0x87;
    pub const CAPTURE: u8 = 0x88;
}

fn write_reference(w: &mut Writer<'_>, r: Reference) -> Result<(), BufferFull> {
    match r {
        Reference::Speed(x) => {
            w.u8(0)?;
            w.f32(x)?;
            w.f32(0.0)
        }
        Reference::Position(x) => {
            w.u8(1)?;
            w.f32(x)?;
            w.f32(0.0)
        }
        Reference::Torque(x) => {
            w.u8(2)?;
            w.f32(x)?;
            w.f32(0.0)
        }
        Reference::RotatingCurrent { amplitude_a, omega_rad_s } => {
            w.u8(3)?;
            w.f32(amplitude_a)?;
            w.f32(omega_rad_s)
        }
    }
}

/// A capture spec: the four signal codes, the trigger (kind 0 immediate, 1 rising,
/// 2 falling, 3 either; its signal's code; its level), pre-trigger samples, decimation.
fn write_capture_spec(w: &mut Writer<'_>, c: &CaptureSpec) -> Result<(), BufferFull> {
    for s in c.signals {
        w.u8(s.code())?;
    }
    let (kind, signal, level) = match c.trigger {
        Trigger::Immediate => (0, Signal::IA, 0.0),
        Trigger::Level { signal, edge: Edge::Rising, level } => (1, signal, level),
        Trigger::Level { signal, edge: Edge::Falling, level } => (2, signal, level),
        Trigger::Level { signal, edge: Edge::Either, level } => (3, signal, level),
    };
    w.u8(kind)?;
    w.u8(signal.code())?;
    w.f32(level)?;
    w.u16(c.pre_samples)?;
    w.u16(c.decimation)
}

fn read_capture_spec(r: &mut Reader<'_>) -> Result<CaptureSpec, DecodeError> {
    let mut signal = || r.u8().and_then(|c| Signal::from_code(c).ok_or(DecodeError::Value));
    let mut signals = [Signal::IA; CHANNELS];
    for s in &mut signals {
        *s = signal()?;
    }
    let (kind, signal, level) = (r.u8()?, Signal::from_code(r.u8()?).ok_or(DecodeError::Value)?, r.f32()?);
    let trigger = match kind {
        0 => Trigger::Immediate,
        1 => Trigger::Level { signal, edge: Edge::Rising, level },
        2 => Trigger::Level { signal, edge: Edge::Falling, level },
        3 => Trigger::Level { signal, edge: Edge::Either, level },
        _ => return Err(DecodeError::Value),
    };
    Ok(CaptureSpec { signals, trigger, pre_samples: r.u16()?, decimation: r.u16()? })
}

fn read_reference(r: &mut Reader<'_>) -> Result<Reference, DecodeError> {
    let (t, x, y) = (r.u8()?, r.f32()?, r.f32()?);
    Ok(match t {
        0 => Reference::Speed(x),
        1 => Reference::Position(x),
        2 => Reference::Torque(x),
        3 => Reference::RotatingCurrent { amplitude_a: x, omega_rad_s: y },
        _ => return Err(DecodeError::Value),
    })
}

fn write_spec(w: &mut Writer<'_>, s: &DriveSpec) -> Result<(), BufferFull> {
    let m = &s.motor;
    for v in [m.rs_ohm(), m.rr_ohm(), m.ls_h(), m.lr_h(), m.lm_h()] {
        w.f64(v)?;
    }
    w.u8(m.pole_pairs())?;
    w.f64(m.j_kgm2())?;
    w.f64(m.b_nms())?;
    w.f64(s.pwm_frequency_hz)?;
    w.u16(s.slow_divider)?;
    w.f64(s.current_law.kp_v_per_a)?;
    w.f64(s.current_law.ki_v_per_as)?;
    match s.current_law.lag {
        None => w.u8(0)?,
        Some(sec) => {
            w.u8(1)?;
            for v in sec.num.iter().chain(sec.den.iter()) {
                w.f64(*v)?;
            }
        }
    }
    match s.discretization {
        Discretization::Tustin => {
            w.u8(0)?;
            w.f64(0.0)?;
        }
        Discretization::TustinPrewarped { omega_rad_s } => {
            w.u8(1)?;
            w.f64(omega_rad_s)?;
        }
    }
    w.u8(match s.current_frame {
        CurrentFrame::Stationary => 0,
        CurrentFrame::Synchronous => 1,
    })?;
    let (t, a, b, c) = match s.speed_law {
        SpeedLaw::PiTorque { kp, ki, limit } => (0, kp, ki, limit),
        SpeedLaw::PiIq { kp, ki, limit } => (1, kp, ki, limit),
        SpeedLaw::SaturatedP { kp, tau_max_nm } => (2, kp, tau_max_nm, 0.0),
    };
    w.u8(t)?;
    for v in [a, b, c, s.position.k_per_s, s.position.omega_max_rad_s] {
        w.f64(v)?;
    }
    for v in [
        s.flux_ref_wb,
        s.flux_floor_wb,
        s.i_ref_max_a,
        s.magnetized_fraction,
        s.voltage_margin,
        s.current_trim_bandwidth_rad_s,
        s.dead_time_compensation_s,
        s.sample_window_s,
        s.rotor_resistance_range[0],
        s.rotor_resistance_range[1],
        s.inductance_range[0],
        s.inductance_range[1],
    ] {
        w.f64(v)?;
    }
    let p = &s.protection;
    for v in p.thresholds() {
        w.f64(v)?;
    }
    match p.brake_chopper {
        None => w.u8(0)?,
        Some(b) => {
            w.u8(1)?;
            w.f64(b.on_v)?;
            w.f64(b.off_v)?;
        }
    }
    for t in [p.motor_thermal, p.inverter_thermal] {
        match t {
            None => w.u8(0)?,
            Some(t) => {
                w.u8(1)?;
                w.f64(t.rated_current_a)?;
                w.f64(t.time_constant_s)?;
                w.f64(t.overload_factor)?;
            }
        }
    }
    w.u32(p.stop_on.0)?;
    Ok(())
}

fn read_spec(r: &mut Reader<'_>) -> Result<DriveSpec, DecodeError> {
    let (rs, rr, ls, lr, lm) = (r.f64()?, r.f64()?, r.f64()?, r.f64()?, r.f64()?);
    let pole_pairs = r.u8()?;
    let (j, b) = (r.f64()?, r.f64()?);
    let motor = MotorParams::new(rs, rr, ls, lr, lm, pole_pairs, j, b).map_err(|_| DecodeError::Value)?;
    let pwm_frequency_hz = r.f64()?;
    let slow_divider = r.u16()?;
    let (kp_v_per_a, ki_v_per_as) = (r.f64()?, r.f64()?);
    let lag = match r.u8()? {
        0 => None,
        1 => Some(ContinuousSection { num: r.f64x3()?, den: r.f64x3()? }),
        _ => return Err(DecodeError::Value),
    };
    let discretization = match (r.u8()?, r.f64()?) {
        (0, _) => Discretization::Tustin,
        (1, omega_rad_s) => Discretization::TustinPrewarped { omega_rad_s },
        _ => return Err(DecodeError::Value),
    };
    let current_frame = match r.u8()? {
        0 => CurrentFrame::Stationary,
        1 => CurrentFrame::Synchronous,
        _ => return Err(DecodeError::Value),
    };
    let t = r.u8()?;
    let (a, b2, c) = (r.f64()?, r.f64()?, r.f64()?);
    let speed_law = match t {
        0 => SpeedLaw::PiTorque { kp: a, ki: b2, limit: c },
        1 => SpeedLaw::PiIq { kp: a, ki: b2, limit: c },
        2 => SpeedLaw::SaturatedP { kp: a, tau_max_nm: b2 },
        _ => return Err(DecodeError::Value),
    };
    let position = PositionLaw { k_per_s: r.f64()?, omega_max_rad_s: r.f64()? };
    let (flux_ref_wb, flux_floor_wb, i_ref_max_a, magnetized_fraction) =
        (r.f64()?, r.f64()?, r.f64()?, r.f64()?);
    let (voltage_margin, current_trim_bandwidth_rad_s, dead_time_compensation_s, sample_window_s) =
        (r.f64()?, r.f64()?, r.f64()?, r.f64()?);
    let rotor_resistance_range = [r.f64()?, r.f64()?];
    let inductance_range = [r.f64()?, r.f64()?];
    let mut thresholds = [0.0; THRESHOLD_COUNT];
    for t in &mut thresholds {
        *t = r.f64()?;
    }
    let brake_chopper = match r.u8()? {
        0 => None,
        1 => Some(BrakeChopper { on_v: r.f64()?, off_v: r.f64()? }),
        _ => return Err(DecodeError::Value),
    };
    let (motor_thermal, inverter_thermal) = (read_thermal(r)?, read_thermal(r)?);
    let protection = Protection::with_thresholds(
        thresholds,
        brake_chopper,
        motor_thermal,
        inverter_thermal,
        FaultSet(r.u32()?),
    );
    Ok(DriveSpec {
        motor,
        pwm_frequency_hz,
        slow_divider,
        current_law: CurrentLaw { kp_v_per_a, ki_v_per_as, lag },
        discretization,
        current_frame,
        speed_law,
        position,
        flux_ref_wb,
        flux_floor_wb,
        i_ref_max_a,
        magnetized_fraction,
        voltage_margin,
        current_trim_bandwidth_rad_s,
        dead_time_compensation_s,
        sample_window_s,
        rotor_resistance_range,
        inductance_range,
        protection,
    })
}

fn read_thermal(r: &mut Reader<'_>) -> Result<Option<ThermalLimit>, DecodeError> {
    Ok(match r.u8()? {
        0 => None,
        1 => Some(ThermalLimit {
            rated_current_a: r.f64()?,
            time_constant_s: r.f64()?,
            overload_factor: r.f64()?,
        }),
        _ => return Err(DecodeError::Value),
    })
}

/// A stage as (code, refusal code, refusal value, refusal index).
fn stage_code(s: Stage) -> (u8, u8, f32, u8) {
    let (r, v, i) = match s {
        Stage::Refused(r) => match r {
            Refusal::BusOutOfRange(v) => (0, v, 0),
            Refusal::BusUnsteady(v) => (1, v, 0),
            Refusal::OffsetTooLarge { channel, offset_a } => (2, offset_a, channel),
            Refusal::NoCurrent => (3, 0.0, 0),
            Refusal::PhaseOrder => (4, 0.0, 0),
            Refusal::CurrentSign => (5, 0.0, 0),
            Refusal::CurrentDirection { phase } => (6, 0.0, phase),
            Refusal::NoDecay => (7, 0.0, 0),
            Refusal::Overcurrent(i) => (8, i, 0),
            Refusal::VoltageLimit => (9, 0.0, 0),
            Refusal::NonFinite => (10, 0.0, 0),
            Refusal::Aborted => (11, 0.0, 0),
            Refusal::RotorStalled(hz) => (12, hz, 0),
        },
        _ => (0, 0.0, 0),
    };
    let code = match s {
        Stage::Offsets => 0,
        Stage::Pulse(p) => 1 + p.min(2),
        Stage::Level(l) => 4 + l.min(2),
        Stage::Injection(j) => 7 + j.min(1),
        Stage::Done => 9,
        Stage::Refused(_) => 10,
        Stage::Rotate => 11,
        Stage::NoLoad => 12,
    };
    (code, r, v, i)
}

fn stage_from_code(code: u8, r: u8, v: f32, i: u8) -> Result<Stage, DecodeError> {
    Ok(match code {
        0 => Stage::Offsets,
        1..=3 => Stage::Pulse(code - 1),
        4..=6 => Stage::Level(code - 4),
        7..=8 => Stage::Injection(code - 7),
        9 => Stage::Done,
        11 => Stage::Rotate,
        12 => Stage::NoLoad,
        10 => Stage::Refused(match (r, i) {
            (0, _) => Refusal::BusOutOfRange(v),
            (1, _) => Refusal::BusUnsteady(v),
            (2, 0..=2) => Refusal::OffsetTooLarge { channel: i, offset_a: v },
            (3, _) => Refusal::NoCurrent,
            (4, _) => Refusal::PhaseOrder,
            (5, _) => Refusal::CurrentSign,
            (6, 0..=2) => Refusal::CurrentDirection { phase: i },
            (7, _) => Refusal::NoDecay,
            (8, _) => Refusal::Overcurrent(v),
            (9, _) => Refusal::VoltageLimit,
            (10, _) => Refusal::NonFinite,
            (11, _) => Refusal::Aborted,
            (12, _) => Refusal::RotorStalled(v),
            _ => return Err(DecodeError::Value),
        }),
        _ => return Err(DecodeError::Value),
    })
}

fn write_phases(w: &mut Writer<'_>, p: PhaseCommand) -> Result<(), BufferFull> {
    match p {
        PhaseCommand::Off => {
            w.u8(0)?;
            w.abc(Abc::default())
        }
        PhaseCommand::Duty(d) => {
            w.u8(1)?;
            w.abc(d)
        }
    }
}

fn read_phases(r: &mut Reader<'_>) -> Result<PhaseCommand, DecodeError> {
    match (r.u8()?, r.abc()?) {
        (0, _) => Ok(PhaseCommand::Off),
        (1, d) => Ok(PhaseCommand::Duty(d)),
        _ => Err(DecodeError::Value),
    }
}

impl Command {
    /// Serialise into `buf` (at most [`MAX_PAYLOAD`] bytes). Returns the payload length.
    pub fn encode(&self, buf: &mut [u8]) -> Result<usize, BufferFull> {
        let mut w = Writer::new(buf);
        match self {
            Command::Configure(s) => {
                w.u8(tag::CONFIGURE)?;
                write_spec(&mut w, s)?;
            }
            Command::Enable => w.u8(tag::ENABLE)?,
            Command::Disable => w.u8(tag::DISABLE)?,
            Command::ClearFault => w.u8(tag::CLEAR_FAULT)?,
            Command::SetReference(r) => {
                w.u8(tag::SET_REFERENCE)?;
                write_reference(&mut w, *r)?;
            }
            Command::Step(m) => {
                w.u8(tag::STEP)?;
                w.abc(m.i_abc_a)?;
                w.f32(m.vdc_v)?;
                w.f32(m.omega_m_rad_s)?;
                w.f32(m.theta_m_rad)?;
            }
            Command::GetStatus => w.u8(tag::GET_STATUS)?,
            Command::WriteSpeedGains { kp, tau_max_nm } => {
                w.u8(tag::WRITE_SPEED_GAINS)?;
                w.f32(*kp)?;
                w.f32(*tau_max_nm)?;
            }
            Command::ReadSpeedGains => w.u8(tag::READ_SPEED_GAINS)?,
            Command::Stop => w.u8(tag::STOP)?,
            Command::Commission(c) => {
                w.u8(tag::COMMISSION)?;
                for v in
                    [c.pwm_hz, c.test_current_a, c.current_limit_a, c.vdc_min_v, c.vdc_max_v, c.level_time_s]
                {
                    w.f32(v)?;
                }
                w.u8(u8::from(c.rotate))?;
                w.f32(c.rated_flux_wb)?;
                w.f32(c.no_load_hz)?;
            }
            Command::GetCommissionRecord { chunk } => {
                w.u8(tag::GET_COMMISSION_RECORD)?;
                w.u8(*chunk)?;
            }
            Command::GetCommissionStage => w.u8(tag::GET_COMMISSION_STAGE)?,
            Command::ArmCapture(c) => {
                w.u8(tag::ARM_CAPTURE)?;
                write_capture_spec(&mut w, c)?;
            }
            Command::ReadCapture { chunk } => {
                w.u8(tag::READ_CAPTURE)?;
                w.u8(*chunk)?;
            }
        }
        Ok(w.n)
    }

    /// Parse a payload.
    pub fn decode(payload: &[u8]) -> Result<Self, DecodeError> {
        let (&t, rest) = payload.split_first().ok_or(DecodeError::Length)?;
        let mut r = Reader { rest };
        let c = match t {
            tag::CONFIGURE => Command::Configure(read_spec(&mut r)?),
            tag::STEP => Command::Step(Measurements {
                i_abc_a: r.abc()?,
                vdc_v: r.f32()?,
                omega_m_rad_s: r.f32()?,
                theta_m_rad: r.f32()?,
            }),
            other => decode_board_tag(other, &mut r)?.command().ok_or(DecodeError::UnknownType(other))?,
        };
        r.finish()?;
        Ok(c)
    }

    /// Parse a payload as the board does ([`BoardCommand`]): `Configure` and `Step` are
    /// recognised by their type byte and not parsed — the board takes neither, and parsing
    /// `Configure` would validate a motor in f64 on a target without double-precision
    /// hardware (42 000 → 36 280 B of flash on the firmware, with the smaller [`BoardCommand`]).
    pub fn decode_board(payload: &[u8]) -> Result<BoardCommand, DecodeError> {
        let (&t, rest) = payload.split_first().ok_or(DecodeError::Length)?;
        if matches!(t, tag::CONFIGURE | tag::STEP) {
            return Ok(BoardCommand::Refused);
        }
        let mut r = Reader { rest };
        let c = decode_board_tag(t, &mut r)?;
        r.finish()?;
        Ok(c)
    }
}

/// The commands every endpoint parses.
fn decode_board_tag(t: u8, r: &mut Reader<'_>) -> Result<BoardCommand, DecodeError> {
    Ok(match t {
        tag::ENABLE => BoardCommand::Enable,
        tag::DISABLE => BoardCommand::Disable,
        tag::CLEAR_FAULT => BoardCommand::ClearFault,
        tag::SET_REFERENCE => BoardCommand::SetReference(read_reference(r)?),
        tag::GET_STATUS => BoardCommand::GetStatus,
        tag::WRITE_SPEED_GAINS => BoardCommand::WriteSpeedGains { kp: r.f32()?, tau_max_nm: r.f32()? },
        tag::READ_SPEED_GAINS => BoardCommand::ReadSpeedGains,
        tag::STOP => BoardCommand::Stop,
        tag::COMMISSION => BoardCommand::Commission(CommissionSpec {
            pwm_hz: r.f32()?,
            test_current_a: r.f32()?,
            current_limit_a: r.f32()?,
            vdc_min_v: r.f32()?,
            vdc_max_v: r.f32()?,
            level_time_s: r.f32()?,
            rotate: match r.u8()? {
                0 => false,
                1 => true,
                _ => return Err(DecodeError::Value),
            },
            rated_flux_wb: r.f32()?,
            no_load_hz: r.f32()?,
        }),
        tag::GET_COMMISSION_RECORD => BoardCommand::GetCommissionRecord { chunk: r.u8()? },
        tag::GET_COMMISSION_STAGE => BoardCommand::GetCommissionStage,
        tag::ARM_CAPTURE => BoardCommand::ArmCapture(read_capture_spec(r)?),
        tag::READ_CAPTURE => BoardCommand::ReadCapture { chunk: r.u8()? },
        other => return Err(DecodeError::UnknownType(other)),
    })
}

/// A command as the board decodes it ([`Command::decode_board`]): the [`Command`]s it takes,
/// and `Refused` for the two it does not.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BoardCommand {
    /// [`Command::Enable`].
    Enable,
    /// [`Command::Disable`].
    Disable,
    /// [`Command::ClearFault`].
    ClearFault,
    /// [`Command::SetReference`].
    SetReference(Reference),
    /// [`Command::GetStatus`].
    GetStatus,
    /// [`Command::WriteSpeedGains`].
    WriteSpeedGains {
        /// N·m per rad/s.
        kp: f32,
        /// N·m.
        tau_max_nm: f32,
    },
    /// [`Command::ReadSpeedGains`].
    ReadSpeedGains,
    /// [`Command::Stop`].
    Stop,
    /// [`Command::Commission`].
    Commission(CommissionSpec),
    /// [`Command::GetCommissionRecord`].
    GetCommissionRecord {
        /// Part.
        chunk: u8,
    },
    /// [`Command::GetCommissionStage`].
    GetCommissionStage,
    /// [`Command::ArmCapture`].
    ArmCapture(CaptureSpec),
    /// [`Command::ReadCapture`].
    ReadCapture {
        /// Part.
        chunk: u8,
    },
    /// `Configure` or `Step`: answered with `Nack(Unsupported)`, payload not parsed.
    Refused,
}

impl BoardCommand {
    /// The board's form of `cmd`: `Configure` and `Step` are `Refused`.
    pub fn of(cmd: &Command) -> Self {
        match *cmd {
            Command::Configure(_) | Command::Step(_) => BoardCommand::Refused,
            Command::Enable => BoardCommand::Enable,
            Command::Disable => BoardCommand::Disable,
            Command::ClearFault => BoardCommand::ClearFault,
            Command::SetReference(r) => BoardCommand::SetReference(r),
            Command::GetStatus => BoardCommand::GetStatus,
            Command::WriteSpeedGains { kp, tau_max_nm } => BoardCommand::WriteSpeedGains { kp, tau_max_nm },
            Command::ReadSpeedGains => BoardCommand::ReadSpeedGains,
            Command::Stop => BoardCommand::Stop,
            Command::Commission(s) => BoardCommand::Commission(s),
            Command::GetCommissionRecord { chunk } => BoardCommand::GetCommissionRecord { chunk },
            Command::GetCommissionStage => BoardCommand::GetCommissionStage,
            Command::ArmCapture(c) => BoardCommand::ArmCapture(c),
            Command::ReadCapture { chunk } => BoardCommand::ReadCapture { chunk },
        }
    }

    /// The command (`None` for `Refused`).
    pub fn command(self) -> Option<Command> {
        Some(match self {
            BoardCommand::Enable => Command::Enable,
            BoardCommand::Disable => Command::Disable,
            BoardCommand::ClearFault => Command::ClearFault,
            BoardCommand::SetReference(r) => Command::SetReference(r),
            BoardCommand::GetStatus => Command::GetStatus,
            BoardCommand::WriteSpeedGains { kp, tau_max_nm } => Command::WriteSpeedGains { kp, tau_max_nm },
            BoardCommand::ReadSpeedGains => Command::ReadSpeedGains,
            BoardCommand::Stop => Command::Stop,
            BoardCommand::Commission(s) => Command::Commission(s),
            BoardCommand::GetCommissionRecord { chunk } => Command::GetCommissionRecord { chunk },
            BoardCommand::GetCommissionStage => Command::GetCommissionStage,
            BoardCommand::ArmCapture(c) => Command::ArmCapture(c),
            BoardCommand::ReadCapture { chunk } => Command::ReadCapture { chunk },
            BoardCommand::Refused => return None,
        })
    }
}

impl Reply {
    /// Serialise into `buf`. Returns the payload length. `#[inline]`, as [`reply_frame`].
    #[inline]
    pub fn encode(&self, buf: &mut [u8]) -> Result<usize, BufferFull> {
        let mut w = Writer::new(buf);
        match self {
            Reply::Ack => w.u8(tag::ACK)?,
            Reply::Nack(r) => {
                w.u8(tag::NACK)?;
                w.u8(match r {
                    NackReason::Faulted => 0,
                    NackReason::NonFinite => 1,
                    NackReason::Configuration => 2,
                    NackReason::NotIdle => 3,
                    NackReason::Unsupported => 4,
                    NackReason::NotConfigured => 5,
                    NackReason::OutOfCertifiedRange => 6,
                    NackReason::NoRecord => 7,
                })?;
            }
            Reply::Output(o, t) => {
                w.u8(tag::OUTPUT)?;
                w.u8(o.mode.code())?;
                w.u8(u8::from(o.brake))?;
                write_phases(&mut w, o.phases)?;
                w.ab(t.i_ab_a)?;
                w.ab(t.i_ref_ab_a)?;
                w.ab(t.v_ab_v)?;
                for v in [
                    t.theta_e_rad,
                    t.omega_sl_rad_s,
                    t.psi_r_wb,
                    t.psi_ref_wb,
                    t.i_q_ref_a,
                    t.omega_ref_rad_s,
                    t.rr_scale,
                    t.l_scale,
                ] {
                    w.f32(v)?;
                }
            }
            Reply::SpeedGains { kp, tau_max_nm } => {
                w.u8(tag::SPEED_GAINS)?;
                w.f32(*kp)?;
                w.f32(*tau_max_nm)?;
            }
            Reply::Commission(o) => {
                w.u8(tag::COMMISSION_OUTPUT)?;
                let (code, r, v, i) = stage_code(o.stage);
                w.u8(code)?;
                w.u8(r)?;
                w.f32(v)?;
                w.u8(i)?;
                write_phases(&mut w, o.phases)?;
                w.ab(o.v_ab_v)?;
                w.f32(o.i_ref_alpha_a)?;
            }
            Reply::CommissionRecord { chunk, bytes } => {
                w.u8(tag::COMMISSION_RECORD)?;
                w.u8(*chunk)?;
                w.bytes(bytes)?;
            }
            Reply::Capture { state, samples, chunk, bytes } => {
                w.u8(tag::CAPTURE)?;
                w.u8(state.code())?;
                w.u16(*samples)?;
                w.u8(*chunk)?;
                w.bytes(bytes)?;
            }
            Reply::Status { mode, frames_ok, frame_errors, timing, readings } => {
                w.u8(tag::STATUS)?;
                w.u8(mode.code())?;
                w.bytes(&frames_ok.to_le_bytes())?;
                w.bytes(&frame_errors.to_le_bytes())?;
                w.u32(timing.cycles_max)?;
                w.u32(timing.overruns)?;
                w.u32(timing.stack_bytes)?;
                let [a, b, c] = readings.i_abc_counts;
                for x in [a, b, c, readings.vdc_counts, readings.encoder_counts] {
                    w.bytes(&x.to_le_bytes())?;
                }
            }
        }
        Ok(w.n)
    }

    /// Parse a payload.
    pub fn decode(payload: &[u8]) -> Result<Self, DecodeError> {
        let (&t, rest) = payload.split_first().ok_or(DecodeError::Length)?;
        let mut r = Reader { rest };
        let reply = match t {
            tag::ACK => Reply::Ack,
            tag::NACK => Reply::Nack(match r.u8()? {
                0 => NackReason::Faulted,
                1 => NackReason::NonFinite,
                2 => NackReason::Configuration,
                3 => NackReason::NotIdle,
                4 => NackReason::Unsupported,
                5 => NackReason::NotConfigured,
                6 => NackReason::OutOfCertifiedRange,
                7 => NackReason::NoRecord,
                _ => return Err(DecodeError::Value),
            }),
            tag::OUTPUT => {
                let mode = Mode::from_code(r.u8()?).ok_or(DecodeError::Value)?;
                let brake = match r.u8()? {
                    0 => false,
                    1 => true,
                    _ => return Err(DecodeError::Value),
                };
                let phases = read_phases(&mut r)?;
                let telemetry = Telemetry {
                    i_ab_a: r.ab()?,
                    i_ref_ab_a: r.ab()?,
                    v_ab_v: r.ab()?,
                    theta_e_rad: r.f32()?,
                    omega_sl_rad_s: r.f32()?,
                    psi_r_wb: r.f32()?,
                    psi_ref_wb: r.f32()?,
                    i_q_ref_a: r.f32()?,
                    omega_ref_rad_s: r.f32()?,
                    rr_scale: r.f32()?,
                    l_scale: r.f32()?,
                };
                Reply::Output(FastOutput { phases, mode, brake }, telemetry)
            }
            tag::SPEED_GAINS => Reply::SpeedGains { kp: r.f32()?, tau_max_nm: r.f32()? },
            tag::COMMISSION_OUTPUT => {
                let (code, refusal, v, i) = (r.u8()?, r.u8()?, r.f32()?, r.u8()?);
                Reply::Commission(CommissionOutput {
                    stage: stage_from_code(code, refusal, v, i)?,
                    phases: read_phases(&mut r)?,
                    v_ab_v: r.ab()?,
                    i_ref_alpha_a: r.f32()?,
                })
            }
            tag::COMMISSION_RECORD => Reply::CommissionRecord { chunk: r.u8()?, bytes: r.take()? },
            tag::CAPTURE => Reply::Capture {
                state: CaptureState::from_code(r.u8()?).ok_or(DecodeError::Value)?,
                samples: r.u16()?,
                chunk: r.u8()?,
                bytes: r.take()?,
            },
            tag::STATUS => Reply::Status {
                mode: Mode::from_code(r.u8()?).ok_or(DecodeError::Value)?,
                frames_ok: u32::from_le_bytes(r.take()?),
                frame_errors: u32::from_le_bytes(r.take()?),
                timing: LoopTiming { cycles_max: r.u32()?, overruns: r.u32()?, stack_bytes: r.u32()? },
                readings: {
                    let mut u = || r.take().map(u16::from_le_bytes);
                    BoardReadings { i_abc_counts: [u()?, u()?, u()?], vdc_counts: u()?, encoder_counts: u()? }
                },
            },
            other => return Err(DecodeError::UnknownType(other)),
        };
        r.finish()?;
        Ok(reply)
    }
}

/// Encode a command as a complete frame into `out`.
pub fn command_frame(c: &Command, out: &mut [u8]) -> Result<usize, BufferFull> {
    let mut p = [0u8; MAX_PAYLOAD];
    let n = c.encode(&mut p)?;
    encode_frame(p.get(..n).ok_or(BufferFull)?, out)
}

/// Encode a reply as a complete frame into `out`.
///
/// `#[inline]` (and [`Reply::encode`]): compiled in the caller's crate — in the firmware at
/// its opt-level "z" rather than controller-core's 2, for the link task's replies, where
/// speed does not matter (−136 B of flash).
#[inline]
pub fn reply_frame(r: &Reply, out: &mut [u8]) -> Result<usize, BufferFull> {
    let mut p = [0u8; MAX_PAYLOAD];
    let n = r.encode(&mut p)?;
    encode_frame(p.get(..n).ok_or(BufferFull)?, out)
}
