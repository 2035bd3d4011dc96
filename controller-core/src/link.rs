//! Command/telemetry link: the frames the firmware's UART link and the processor-in-the-loop
//! link (QEMU, semihosting FIFOs) exchange.
//!
//! **Frame** on the wire: `COBS(payload ‖ CRC-16) ‖ 0x00`.
//! - `payload` = one message: a type byte, then the fields in a fixed little-endian layout
//!   (`f32`/`f64` as their IEEE-754 bits, so values cross the link bit-exactly).
//! - CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection; check value of
//!   `"123456789"` is 0x29B1) over the payload, appended little-endian.
//! - COBS (consistent overhead byte stuffing) removes every 0x00 from the frame body, so a
//!   single 0x00 delimits frames and a receiver resynchronises at the next delimiter after
//!   any corruption or lost byte.
//!
//! **Receiving**: feed bytes to a [`FrameDecoder`]; at each delimiter it yields either a
//! CRC-checked payload or a [`FrameError`], counted in [`LinkStats`]. [`Command::decode`] and
//! [`Reply::decode`] then reject unknown types, wrong lengths and invalid values with a
//! [`DecodeError`] (counted too). Nothing in this module panics for any input (fuzzed:
//! `fuzz/fuzz_targets/frame_decoder.rs`, and property-tested below).
//!
//! Messages: host → drive [`Command`]s, drive → host [`Reply`]s. `Step` carries the
//! measurements of one PWM period (processor-in-the-loop only: on the board the ADC provides
//! them) and is answered by `Output`, the drive's [`FastOutput`].

use crate::current::CurrentLaw;
use crate::discretize::{ContinuousSection, Discretization};
use crate::drive::{
    CommandError, CurrentFrame, Drive, DriveConfig, DriveSpec, FastOutput, Fault, Measurements, Mode,
    PhaseCommand, PositionLaw, Protection, Reference, Telemetry,
};
use crate::frames::{Abc, AlphaBeta};
use crate::motor::MotorParams;
use crate::speed::SpeedLaw;

/// Largest payload (type byte + fields), bytes.
pub const MAX_PAYLOAD: usize = 240;
/// Largest frame on the wire, delimiter included: payload + CRC, one COBS overhead byte per
/// 254 bytes (plus one), and the 0x00.
pub const MAX_FRAME: usize = MAX_PAYLOAD + 2 + (MAX_PAYLOAD + 2) / 254 + 1 + 1;

/// CRC-16/CCITT-FALSE of `data`.
pub fn crc16(data: &[u8]) -> u16 {
    let mut crc: u16 = 0xFFFF;
    for &b in data {
        crc ^= u16::from(b) << 8;
        for _ in 0..8 {
            crc = if crc & 0x8000 != 0 { (crc << 1) ^ 0x1021 } else { crc << 1 };
        }
    }
    crc
}

/// Why a buffer was too small for an encoded message or frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BufferFull;

/// COBS-encode `src` into `dst` (no delimiter). Returns the encoded length.
pub fn cobs_encode(src: &[u8], dst: &mut [u8]) -> Result<usize, BufferFull> {
    // `code_at` is the index of the pending code byte, `n` the bytes written so far.
    let mut code_at = 0usize;
    let mut n = 1usize;
    let mut code: u8 = 1;
    let mut bytes = src.iter().peekable();
    while let Some(&b) = bytes.next() {
        if b != 0 {
            *dst.get_mut(n).ok_or(BufferFull)? = b;
            n += 1;
            code += 1;
        }
        // A zero, or a full block of 254 data bytes, closes the block; a new code byte is
        // opened only if input remains (the standard encoding of 254 bytes is 255 bytes).
        if b == 0 || code == 0xFF {
            *dst.get_mut(code_at).ok_or(BufferFull)? = code;
            code = 1;
            if b == 0 || bytes.peek().is_some() {
                code_at = n;
                n += 1;
            } else {
                return Ok(n);
            }
        }
    }
    *dst.get_mut(code_at).ok_or(BufferFull)? = code;
    Ok(n)
}

/// COBS-decode `buf` in place (no delimiter inside). Returns the decoded length, or `None` if
/// `buf` is not valid COBS (a zero byte, or a code running past the end).
pub fn cobs_decode_in_place(buf: &mut [u8]) -> Option<usize> {
    let mut read = 0usize;
    let mut write = 0usize;
    while read < buf.len() {
        let code = *buf.get(read)?;
        if code == 0 {
            return None;
        }
        read += 1;
        for _ in 1..code {
            let b = *buf.get(read)?;
            if b == 0 {
                return None;
            }
            *buf.get_mut(write)? = b;
            read += 1;
            write += 1;
        }
        if code != 0xFF && read < buf.len() {
            *buf.get_mut(write)? = 0;
            write += 1;
        }
    }
    Some(write)
}

/// Frame-level errors (reported at the delimiter that ends the bad frame).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameError {
    /// More bytes than [`MAX_FRAME`] before a delimiter; dropped up to the next delimiter.
    TooLong,
    /// Invalid COBS encoding.
    Cobs,
    /// Shorter than a type byte plus the CRC.
    TooShort,
    /// CRC mismatch.
    Crc,
}

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

/// Error counters of one link endpoint.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LinkStats {
    /// Frames accepted (CRC good, message decoded).
    pub frames_ok: u32,
    /// [`FrameError::TooLong`].
    pub too_long: u32,
    /// [`FrameError::Cobs`].
    pub cobs: u32,
    /// [`FrameError::TooShort`].
    pub too_short: u32,
    /// [`FrameError::Crc`].
    pub crc: u32,
    /// [`DecodeError::UnknownType`].
    pub unknown_type: u32,
    /// [`DecodeError::Length`].
    pub length: u32,
    /// [`DecodeError::Value`].
    pub value: u32,
}

impl LinkStats {
    /// Count a frame error.
    pub fn count_frame(&mut self, e: FrameError) {
        let c = match e {
            FrameError::TooLong => &mut self.too_long,
            FrameError::Cobs => &mut self.cobs,
            FrameError::TooShort => &mut self.too_short,
            FrameError::Crc => &mut self.crc,
        };
        *c = c.saturating_add(1);
    }

    /// Count a message error.
    pub fn count_decode(&mut self, e: DecodeError) {
        let c = match e {
            DecodeError::UnknownType(_) => &mut self.unknown_type,
            DecodeError::Length => &mut self.length,
            DecodeError::Value => &mut self.value,
        };
        *c = c.saturating_add(1);
    }

    /// All rejected frames.
    pub fn errors(&self) -> u32 {
        [self.too_long, self.cobs, self.too_short, self.crc, self.unknown_type, self.length, self.value]
            .iter()
            .fold(0u32, |a, &b| a.saturating_add(b))
    }
}

/// Streaming frame receiver with a fixed buffer of [`MAX_FRAME`] bytes.
#[derive(Clone, Debug)]
pub struct FrameDecoder {
    buf: [u8; MAX_FRAME],
    len: usize,
    overflow: bool,
}

impl Default for FrameDecoder {
    fn default() -> Self {
        Self::new()
    }
}

impl FrameDecoder {
    /// An empty receiver.
    pub const fn new() -> Self {
        Self { buf: [0; MAX_FRAME], len: 0, overflow: false }
    }

    /// Feed one byte. At a delimiter returns the frame's payload (CRC stripped) or its error;
    /// empty frames (two delimiters in a row) are skipped silently.
    pub fn push(&mut self, byte: u8) -> Option<Result<&[u8], FrameError>> {
        if byte != 0 {
            match self.buf.get_mut(self.len) {
                Some(slot) if !self.overflow => {
                    *slot = byte;
                    self.len += 1;
                }
                _ => self.overflow = true,
            }
            return None;
        }
        let (len, overflow) = (self.len, self.overflow);
        self.len = 0;
        self.overflow = false;
        if overflow {
            return Some(Err(FrameError::TooLong));
        }
        if len == 0 {
            return None;
        }
        let Some(body) = self.buf.get_mut(..len) else { return Some(Err(FrameError::TooLong)) };
        let Some(n) = cobs_decode_in_place(body) else { return Some(Err(FrameError::Cobs)) };
        let Some(decoded) = body.get(..n) else { return Some(Err(FrameError::Cobs)) };
        let Some((payload, crc)) =
            n.checked_sub(2).and_then(|k| Some((decoded.get(..k)?, decoded.get(k..)?)))
        else {
            return Some(Err(FrameError::TooShort));
        };
        if payload.is_empty() {
            return Some(Err(FrameError::TooShort));
        }
        let got = match crc {
            [lo, hi] => u16::from_le_bytes([*lo, *hi]),
            _ => return Some(Err(FrameError::TooShort)),
        };
        if got != crc16(payload) {
            return Some(Err(FrameError::Crc));
        }
        Some(Ok(payload))
    }
}

impl FrameDecoder {
    /// Feed one byte; at the end of a frame that is a valid command return it. Every frame
    /// is counted in `stats`: accepted, or by its error.
    pub fn push_command(&mut self, byte: u8, stats: &mut LinkStats) -> Option<Command> {
        self.push_message(byte, stats, Command::decode)
    }

    /// Feed one byte; at the end of a frame that is a valid reply return it (counted as
    /// [`FrameDecoder::push_command`]).
    pub fn push_reply(&mut self, byte: u8, stats: &mut LinkStats) -> Option<Reply> {
        self.push_message(byte, stats, Reply::decode)
    }

    fn push_message<M>(
        &mut self,
        byte: u8,
        stats: &mut LinkStats,
        decode: impl FnOnce(&[u8]) -> Result<M, DecodeError>,
    ) -> Option<M> {
        match self.push(byte)? {
            Err(e) => {
                stats.count_frame(e);
                None
            }
            Ok(payload) => match decode(payload) {
                Ok(m) => {
                    stats.frames_ok = stats.frames_ok.saturating_add(1);
                    Some(m)
                }
                Err(e) => {
                    stats.count_decode(e);
                    None
                }
            },
        }
    }
}

/// Encode `payload` as a complete frame (CRC, COBS, delimiter) into `out`.
pub fn encode_frame(payload: &[u8], out: &mut [u8]) -> Result<usize, BufferFull> {
    let mut raw = [0u8; MAX_PAYLOAD + 2];
    let body = raw.get_mut(..payload.len() + 2).ok_or(BufferFull)?;
    let (p, c) = body.split_at_mut(payload.len());
    p.copy_from_slice(payload);
    c.copy_from_slice(&crc16(payload).to_le_bytes());
    let n = cobs_encode(body, out)?;
    *out.get_mut(n).ok_or(BufferFull)? = 0;
    Ok(n + 1)
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
    fn f32(&mut self, v: f32) -> Result<(), BufferFull> {
        self.bytes(&v.to_le_bytes())
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
}

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
}

/// Drive → host.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Reply {
    /// Command accepted.
    Ack,
    /// Command refused.
    Nack(NackReason),
    /// Result of a `Step`, or streamed telemetry of the board.
    Output(FastOutput),
    /// The saturated-P speed-loop gains in use.
    SpeedGains {
        /// N·m per rad/s.
        kp: f32,
        /// Torque limit τ_max, N·m.
        tau_max_nm: f32,
    },
    /// Mode and the receiver's counters.
    Status {
        /// Drive mode.
        mode: Mode,
        /// Frames accepted by the drive.
        frames_ok: u32,
        /// Frames the drive rejected.
        frame_errors: u32,
    },
}

mod tag {
    pub const CONFIGURE: u8 = 0x01;
    pub const ENABLE: u8 = 0x02;
    pub const DISABLE: u8 = 0x03;
    pub const CLEAR_FAULT: u8 = 0x04;
    pub const SET_REFERENCE: u8 = 0x05;
    pub const STEP: u8 = 0x06;
    pub const GET_STATUS: u8 = 0x07;
    pub const WRITE_SPEED_GAINS: u8 = 0x08;
    pub const READ_SPEED_GAINS: u8 = 0x09;
    pub const ACK: u8 = 0x81;
    pub const NACK: u8 = 0x82;
    pub const OUTPUT: u8 = 0x83;
    pub const STATUS: u8 = 0x84;
    pub const SPEED_GAINS: u8 = 0x85;
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
    for v in [s.flux_ref_wb, s.flux_floor_wb, s.i_ref_max_a, s.magnetized_fraction] {
        w.f64(v)?;
    }
    let p = &s.protection;
    for v in [p.i_trip_a, p.vdc_min_v, p.vdc_max_v] {
        w.f64(v)?;
    }
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
    let protection = Protection { i_trip_a: r.f64()?, vdc_min_v: r.f64()?, vdc_max_v: r.f64()? };
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
        protection,
    })
}

fn mode_code(m: Mode) -> u8 {
    match m {
        Mode::Idle => 0,
        Mode::Magnetizing => 1,
        Mode::Running => 2,
        Mode::Fault(Fault::Overcurrent) => 10,
        Mode::Fault(Fault::DcBusOvervoltage) => 11,
        Mode::Fault(Fault::DcBusUndervoltage) => 12,
        Mode::Fault(Fault::NonFiniteInput) => 13,
        Mode::Fault(Fault::NonFiniteOutput) => 14,
        Mode::Fault(Fault::EncoderLoss) => 15,
        Mode::Fault(Fault::HardwareBreak) => 16,
    }
}

fn mode_from_code(c: u8) -> Result<Mode, DecodeError> {
    Ok(match c {
        0 => Mode::Idle,
        1 => Mode::Magnetizing,
        2 => Mode::Running,
        10 => Mode::Fault(Fault::Overcurrent),
        11 => Mode::Fault(Fault::DcBusOvervoltage),
        12 => Mode::Fault(Fault::DcBusUndervoltage),
        13 => Mode::Fault(Fault::NonFiniteInput),
        14 => Mode::Fault(Fault::NonFiniteOutput),
        15 => Mode::Fault(Fault::EncoderLoss),
        16 => Mode::Fault(Fault::HardwareBreak),
        _ => return Err(DecodeError::Value),
    })
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
        }
        Ok(w.n)
    }

    /// Parse a payload.
    pub fn decode(payload: &[u8]) -> Result<Self, DecodeError> {
        let (&t, rest) = payload.split_first().ok_or(DecodeError::Length)?;
        let mut r = Reader { rest };
        let c = match t {
            tag::CONFIGURE => Command::Configure(read_spec(&mut r)?),
            tag::ENABLE => Command::Enable,
            tag::DISABLE => Command::Disable,
            tag::CLEAR_FAULT => Command::ClearFault,
            tag::SET_REFERENCE => Command::SetReference(read_reference(&mut r)?),
            tag::STEP => Command::Step(Measurements {
                i_abc_a: r.abc()?,
                vdc_v: r.f32()?,
                omega_m_rad_s: r.f32()?,
                theta_m_rad: r.f32()?,
            }),
            tag::GET_STATUS => Command::GetStatus,
            tag::WRITE_SPEED_GAINS => Command::WriteSpeedGains { kp: r.f32()?, tau_max_nm: r.f32()? },
            tag::READ_SPEED_GAINS => Command::ReadSpeedGains,
            other => return Err(DecodeError::UnknownType(other)),
        };
        r.finish()?;
        Ok(c)
    }
}

impl Reply {
    /// Serialise into `buf`. Returns the payload length.
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
                })?;
            }
            Reply::Output(o) => {
                w.u8(tag::OUTPUT)?;
                w.u8(mode_code(o.mode))?;
                match o.phases {
                    PhaseCommand::Off => {
                        w.u8(0)?;
                        w.abc(Abc::default())?;
                    }
                    PhaseCommand::Duty(d) => {
                        w.u8(1)?;
                        w.abc(d)?;
                    }
                }
                let t = &o.telemetry;
                w.ab(t.i_ab_a)?;
                w.ab(t.i_ref_ab_a)?;
                w.ab(t.v_ab_v)?;
                for v in [t.theta_e_rad, t.omega_sl_rad_s, t.psi_r_wb, t.i_q_ref_a, t.omega_ref_rad_s] {
                    w.f32(v)?;
                }
            }
            Reply::SpeedGains { kp, tau_max_nm } => {
                w.u8(tag::SPEED_GAINS)?;
                w.f32(*kp)?;
                w.f32(*tau_max_nm)?;
            }
            Reply::Status { mode, frames_ok, frame_errors } => {
                w.u8(tag::STATUS)?;
                w.u8(mode_code(*mode))?;
                w.bytes(&frames_ok.to_le_bytes())?;
                w.bytes(&frame_errors.to_le_bytes())?;
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
                _ => return Err(DecodeError::Value),
            }),
            tag::OUTPUT => {
                let mode = mode_from_code(r.u8()?)?;
                let phases = match (r.u8()?, r.abc()?) {
                    (0, _) => PhaseCommand::Off,
                    (1, d) => PhaseCommand::Duty(d),
                    _ => return Err(DecodeError::Value),
                };
                let telemetry = Telemetry {
                    i_ab_a: r.ab()?,
                    i_ref_ab_a: r.ab()?,
                    v_ab_v: r.ab()?,
                    theta_e_rad: r.f32()?,
                    omega_sl_rad_s: r.f32()?,
                    psi_r_wb: r.f32()?,
                    i_q_ref_a: r.f32()?,
                    omega_ref_rad_s: r.f32()?,
                };
                Reply::Output(FastOutput { phases, mode, telemetry })
            }
            tag::SPEED_GAINS => Reply::SpeedGains { kp: r.f32()?, tau_max_nm: r.f32()? },
            tag::STATUS => Reply::Status {
                mode: mode_from_code(r.u8()?)?,
                frames_ok: u32::from_le_bytes(r.take()?),
                frame_errors: u32::from_le_bytes(r.take()?),
            },
            other => return Err(DecodeError::UnknownType(other)),
        };
        r.finish()?;
        Ok(reply)
    }
}

/// Carry out `cmd` on `drive` and say how it went — the command handling shared by the
/// processor-in-the-loop server and the firmware (which refuses `Step` itself: on the board
/// the measurements come from the ADC, and handles the speed-gain commands, which need the
/// specification and the certified ranges it keeps). `Configure` replaces the drive only while it is
/// Idle or faulted, with a configuration validated by [`DriveConfig::new`].
pub fn execute(drive: &mut Drive, cmd: &Command, stats: &LinkStats) -> Reply {
    match cmd {
        Command::Configure(spec) => {
            if matches!(drive.mode(), Mode::Magnetizing | Mode::Running) {
                return Reply::Nack(NackReason::NotIdle);
            }
            match DriveConfig::new(spec) {
                Ok(cfg) => {
                    *drive = Drive::new(cfg);
                    Reply::Ack
                }
                Err(_) => Reply::Nack(NackReason::Configuration),
            }
        }
        Command::Enable => command_result(drive.enable()),
        Command::Disable => {
            drive.disable();
            Reply::Ack
        }
        Command::ClearFault => {
            drive.clear_fault();
            Reply::Ack
        }
        Command::SetReference(r) => command_result(drive.set_reference(*r)),
        Command::Step(m) => Reply::Output(drive.step(m)),
        Command::GetStatus => {
            Reply::Status { mode: drive.mode(), frames_ok: stats.frames_ok, frame_errors: stats.errors() }
        }
        // Gains live in the specification, which the board keeps (firmware `server`).
        Command::WriteSpeedGains { .. } | Command::ReadSpeedGains => Reply::Nack(NackReason::Unsupported),
    }
}

fn command_result(r: Result<(), CommandError>) -> Reply {
    match r {
        Ok(()) => Reply::Ack,
        Err(CommandError::Faulted) => Reply::Nack(NackReason::Faulted),
        Err(CommandError::NonFinite) => Reply::Nack(NackReason::NonFinite),
    }
}

/// Encode a command as a complete frame into `out`.
pub fn command_frame(c: &Command, out: &mut [u8]) -> Result<usize, BufferFull> {
    let mut p = [0u8; MAX_PAYLOAD];
    let n = c.encode(&mut p)?;
    encode_frame(p.get(..n).ok_or(BufferFull)?, out)
}

/// Encode a reply as a complete frame into `out`.
pub fn reply_frame(r: &Reply, out: &mut [u8]) -> Result<usize, BufferFull> {
    let mut p = [0u8; MAX_PAYLOAD];
    let n = r.encode(&mut p)?;
    encode_frame(p.get(..n).ok_or(BufferFull)?, out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::drive::test_spec;
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
        let cmds = [
            Command::Configure(spec),
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
        ];
        let stream: Vec<u8> = cmds.iter().flat_map(frame_of).collect();
        let (got, stats) = decode_all(&stream);
        assert_eq!(got, cmds);
        assert_eq!(stats.errors(), 0);
        let mut p = [0u8; MAX_PAYLOAD];
        let n = Command::Configure(spec).encode(&mut p).unwrap();
        assert!(n <= MAX_PAYLOAD);
        assert!(frame_of(&Command::Configure(spec)).len() <= MAX_FRAME);
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
            Reply::Output(out),
            Reply::Output(FastOutput {
                phases: PhaseCommand::Off,
                mode: Mode::Fault(Fault::Overcurrent),
                telemetry: Telemetry::default(),
            }),
            Reply::Status { mode: Mode::Running, frames_ok: 7, frame_errors: u32::MAX },
            Reply::SpeedGains { kp: 0.05, tau_max_nm: 2.0 },
            Reply::Nack(NackReason::OutOfCertifiedRange),
        ];
        for r in replies {
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
                assert_eq!(
                    got.last(),
                    Some(&Command::SetReference(Reference::Speed(1.0))),
                    "byte {i} bit {bit}"
                );
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
}
