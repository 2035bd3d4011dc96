//! Each message's encoding and decoding: [`Command`]s (in full, and as the board parses
//! them) and [`Reply`]s, a type byte ([`tag`]) and the fields in order.

use super::super::framing::BufferFull;
use super::fields::{
    read_capture_spec, read_phases, read_reference, read_spec, stage_code, stage_from_code,
    write_capture_spec, write_phases, write_reference, write_spec,
};
use super::{
    BoardCommand, BoardReadings, Command, DecodeError, LoopTiming, NackReason, Reader, Reply, Writer, tag,
};
use crate::capture::CaptureState;
use crate::commission::{CommissionOutput, CommissionSpec};
use crate::drive::{FastOutput, FaultSet, Measurements, Mode, Telemetry};

impl Command {
    /// Serialise into `buf` (at most [`MAX_PAYLOAD`](crate::link::MAX_PAYLOAD) bytes). Returns the
    /// payload length.
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
                w.u8(if c.rotate { ROTATE } else { 0 } | if c.curve { CURVE } else { 0 })?;
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

/// `Commission`'s motion byte: the rotor may turn (the rotating field and the no-load test)…
const ROTATE: u8 = 1;
/// …and the no-load test measures the magnetizing curve. Any other bit is refused.
const CURVE: u8 = 2;

/// `Commission`'s fields in their order on the wire.
fn read_commission_spec(r: &mut Reader<'_>) -> Result<CommissionSpec, DecodeError> {
    let [pwm_hz, test_current_a, current_limit_a, vdc_min_v, vdc_max_v, level_time_s] =
        [r.f32()?, r.f32()?, r.f32()?, r.f32()?, r.f32()?, r.f32()?];
    let motion = r.u8()?;
    if motion & !(ROTATE | CURVE) != 0 {
        return Err(DecodeError::Value);
    }
    Ok(CommissionSpec {
        pwm_hz,
        test_current_a,
        current_limit_a,
        vdc_min_v,
        vdc_max_v,
        level_time_s,
        rotate: motion & ROTATE != 0,
        rated_flux_wb: r.f32()?,
        no_load_hz: r.f32()?,
        curve: motion & CURVE != 0,
    })
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
        tag::COMMISSION => BoardCommand::Commission(read_commission_spec(r)?),
        tag::GET_COMMISSION_RECORD => BoardCommand::GetCommissionRecord { chunk: r.u8()? },
        tag::GET_COMMISSION_STAGE => BoardCommand::GetCommissionStage,
        tag::ARM_CAPTURE => BoardCommand::ArmCapture(read_capture_spec(r)?),
        tag::READ_CAPTURE => BoardCommand::ReadCapture { chunk: r.u8()? },
        other => return Err(DecodeError::UnknownType(other)),
    })
}

impl Reply {
    /// Serialise into `buf`. Returns the payload length. `#[inline]`, as [`reply_frame`](super::reply_frame).
    #[inline]
    pub fn encode(&self, buf: &mut [u8]) -> Result<usize, BufferFull> {
        let mut w = Writer::new(buf);
        match self {
            Reply::Ack => w.u8(tag::ACK)?,
            Reply::Nack(r) => {
                w.u8(tag::NACK)?;
                w.u8(r.code())?;
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
            Reply::Status { mode, ridden_through, frames_ok, frame_errors, timing, readings } => {
                w.u8(tag::STATUS)?;
                w.u8(mode.code())?;
                w.u32(ridden_through.0)?;
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
            tag::NACK => Reply::Nack(NackReason::from_code(r.u8()?).ok_or(DecodeError::Value)?),
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
                ridden_through: FaultSet(r.u32()?),
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
