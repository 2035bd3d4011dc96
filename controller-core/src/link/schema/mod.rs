//! Message schema: host → drive [`Command`]s and drive → host [`Reply`]s, each a type byte
//! and its fields in a fixed little-endian layout (`f32`/`f64` as IEEE-754 bits).
//!
//! Here: the messages, the field writer and reader, the type bytes and the frames; each
//! message's encoding and decoding in `codec`, the layouts of the compound fields (a drive
//! specification, a reference, a capture spec, a commissioning stage, a phase command) in
//! `fields`.

use super::framing::{BufferFull, MAX_PAYLOAD, encode_frame};
use crate::capture::{CHUNK_BYTES, CaptureSpec, CaptureState};
use crate::commission::{CommissionOutput, CommissionSpec, RECORD_BYTES, Record};
use crate::drive::{DriveSpec, FastOutput, FaultSet, Measurements, Mode, Reference, Telemetry};
use crate::frames::{Abc, AlphaBeta};

mod codec;
mod fields;

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
    /// `CommissionConfig::new` rejects. On the wire: six f32 (PWM, test current, current
    /// limit, bus min and max, level time), the motion byte (bit 0 `rotate`, bit 1 `curve`;
    /// another bit is a `DecodeError::Value`), rated flux and no-load frequency (f32).
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

/// Declares the refusals once, each with its byte on the wire: the [`NackReason`] enum,
/// [`NackReason::code`] and [`NackReason::from_code`]. A new reason is one line with the next
/// free byte; none moves (the golden test `nack_codes_are_the_wire_contract` pins them).
macro_rules! nack_reasons {
    ($($(#[$doc:meta])* $name:ident = $code:literal,)*) => {
        /// Why a command was refused.
        #[derive(Clone, Copy, Debug, PartialEq, Eq)]
        pub enum NackReason {
            $($(#[$doc])* $name,)*
        }

        impl NackReason {
            /// Every reason, in the order declared.
            pub const ALL: [NackReason; [$($code),*].len()] = [$(NackReason::$name),*];

            /// The reason's byte on the wire.
            pub const fn code(self) -> u8 {
                match self {
                    $(NackReason::$name => $code,)*
                }
            }

            /// The reason of a byte (`None`: no such reason).
            pub const fn from_code(c: u8) -> Option<NackReason> {
                match c {
                    $($code => Some(NackReason::$name),)*
                    _ => None,
                }
            }
        }
    };
}

nack_reasons! {
    /// A fault is latched.
    Faulted = 0,
    /// A value was not finite.
    NonFinite = 1,
    /// The drive specification was rejected by `DriveConfig::new`.
    Configuration = 2,
    /// The command needs the drive Idle.
    NotIdle = 3,
    /// The command is not supported by this endpoint.
    Unsupported = 4,
    /// No drive configuration yet: send `Configure` first.
    NotConfigured = 5,
    /// A gain outside the certified range.
    OutOfCertifiedRange = 6,
    /// No finished commissioning record (or no such part of it).
    NoRecord = 7,
    /// The rotor turns: commissioning's standstill tests need it at rest
    /// (`Drive::rotor_at_rest`).
    NotAtRest = 8,
    /// A position reference to a drive without an encoder (`speed_feedback = "sensorless"`).
    NoEncoder = 9,
    /// A torque or position reference to a V/Hz drive, which takes a speed reference only.
    SpeedOnly = 10,
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
        /// The encoder's faults the drive rode through on its observer since its last enable
        /// ([`Drive::ridden_through`](crate::drive::Drive::ridden_through)): it runs on,
        /// without the encoder.
        ridden_through: FaultSet,
        /// Frames accepted by the drive.
        frames_ok: u32,
        /// Frames the drive rejected.
        frame_errors: u32,
        /// The control interrupt's timing (zero where it is not measured: PIL).
        timing: LoopTiming,
        /// The board's raw readings of a recent control period — the slow step's tick that
        /// served the `GetStatus` (zero without a board).
        readings: BoardReadings,
    },
}

/// The board's raw readings at a control period, before any scaling: what bring-up
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
