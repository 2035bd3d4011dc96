//! The layouts of the compound fields the messages carry: a reference, a capture spec, a
//! drive specification (with its protection), a commissioning stage and a phase command.

use super::super::framing::BufferFull;
use super::{DecodeError, Reader, Writer};
use crate::capture::{CHANNELS, CaptureSpec, Edge, Signal, Trigger};
use crate::commission::{Refusal, Stage};
use crate::current::CurrentLaw;
use crate::discretize::{ContinuousSection, Discretization};
use crate::drive::{
    BrakeChopper, Control, CurrentFrame, DriveSpec, FaultSet, PhaseCommand, PositionLaw, Protection,
    Reference, SlipCurrent, SpeedFeedback, ThermalLimit,
};
use crate::frames::Abc;
use crate::magnetics::{MagnetizingTable, TABLE_POINTS};
use crate::motor::MotorParams;
use crate::speed::SpeedLaw;
use crate::supervisor::THRESHOLD_COUNT;

pub(super) fn write_reference(w: &mut Writer<'_>, r: Reference) -> Result<(), BufferFull> {
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
pub(super) fn write_capture_spec(w: &mut Writer<'_>, c: &CaptureSpec) -> Result<(), BufferFull> {
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

pub(super) fn read_capture_spec(r: &mut Reader<'_>) -> Result<CaptureSpec, DecodeError> {
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

pub(super) fn read_reference(r: &mut Reader<'_>) -> Result<Reference, DecodeError> {
    let (t, x, y) = (r.u8()?, r.f32()?, r.f32()?);
    Ok(match t {
        0 => Reference::Speed(x),
        1 => Reference::Position(x),
        2 => Reference::Torque(x),
        3 => Reference::RotatingCurrent { amplitude_a: x, omega_rad_s: y },
        _ => return Err(DecodeError::Value),
    })
}

pub(super) fn write_spec(w: &mut Writer<'_>, s: &DriveSpec) -> Result<(), BufferFull> {
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
    // The frame in bit 0, the slip's current in bit 1, overmodulation in bit 2, the field-frame
    // loops' decoupling in bit 3 (one byte: the spec fills the frame).
    let frame = match s.current_frame {
        CurrentFrame::Stationary => 0,
        CurrentFrame::Synchronous => 1,
    };
    let slip = match s.slip_current {
        SlipCurrent::Reference => 0,
        SlipCurrent::Measured => 2,
    };
    w.u8(frame | slip | u8::from(s.overmodulation) << 2 | u8::from(s.current_decoupling) << 3)?;
    let (t, a, b, c, d) = match s.speed_law {
        SpeedLaw::PiTorque { kp, ki, limit, setpoint_weight } => (0, kp, ki, limit, setpoint_weight),
        SpeedLaw::PiIq { kp, ki, limit, setpoint_weight } => (1, kp, ki, limit, setpoint_weight),
        SpeedLaw::SaturatedP { kp, tau_max_nm } => (2, kp, tau_max_nm, 0.0, 1.0),
    };
    w.u8(t)?;
    for v in [a, b, c, d, s.position.k_per_s, s.position.omega_max_rad_s] {
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
    w.u8(match s.speed_feedback {
        SpeedFeedback::Encoder => 0,
        SpeedFeedback::Sensorless => 1,
        SpeedFeedback::EncoderRideThrough => 2,
    })?;
    w.f64(s.speed_resolution_rad_s)?;
    // The control law: a tag, and V/Hz's ramp.
    match s.control {
        Control::Vector => w.u8(0)?,
        Control::VHz { ramp_rad_s2, k_u, k_w } => {
            w.u8(1)?;
            w.f64(ramp_rad_s2)?;
            w.f64(k_u)?;
            w.f64(k_w)?;
        }
    }
    // The magnetizing table: a tag, and its points in f32 — the precision the drive runs it
    // in (`DriveConfig::new` rounds them to f32 and nothing else reads them).
    match &s.magnetizing {
        None => w.u8(0),
        Some(t) => {
            w.u8(1)?;
            t.flux_ratio.iter().try_for_each(|&y| w.f32(y as f32))
        }
    }
}

pub(super) fn read_spec(r: &mut Reader<'_>) -> Result<DriveSpec, DecodeError> {
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
    let byte = r.u8()?;
    if byte > 15 {
        return Err(DecodeError::Value);
    }
    let current_frame = if byte & 1 == 0 { CurrentFrame::Stationary } else { CurrentFrame::Synchronous };
    let slip_current = if byte & 2 == 0 { SlipCurrent::Reference } else { SlipCurrent::Measured };
    let overmodulation = byte & 4 != 0;
    let current_decoupling = byte & 8 != 0;
    let t = r.u8()?;
    let (a, b2, c, d) = (r.f64()?, r.f64()?, r.f64()?, r.f64()?);
    let speed_law = match t {
        0 => SpeedLaw::PiTorque { kp: a, ki: b2, limit: c, setpoint_weight: d },
        1 => SpeedLaw::PiIq { kp: a, ki: b2, limit: c, setpoint_weight: d },
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
    let speed_feedback = match r.u8()? {
        0 => SpeedFeedback::Encoder,
        1 => SpeedFeedback::Sensorless,
        2 => SpeedFeedback::EncoderRideThrough,
        _ => return Err(DecodeError::Value),
    };
    let speed_resolution_rad_s = r.f64()?;
    let control = match r.u8()? {
        0 => Control::Vector,
        1 => Control::VHz { ramp_rad_s2: r.f64()?, k_u: r.f64()?, k_w: r.f64()? },
        _ => return Err(DecodeError::Value),
    };
    let magnetizing = match r.u8()? {
        0 => None,
        1 => {
            let mut t = MagnetizingTable { flux_ratio: [0.0; TABLE_POINTS] };
            for y in t.flux_ratio.iter_mut() {
                *y = f64::from(r.f32()?);
            }
            Some(t)
        }
        _ => return Err(DecodeError::Value),
    };
    Ok(DriveSpec {
        motor,
        pwm_frequency_hz,
        slow_divider,
        current_law: CurrentLaw { kp_v_per_a, ki_v_per_as, lag },
        discretization,
        current_frame,
        slip_current,
        current_decoupling,
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
        overmodulation,
        rotor_resistance_range,
        inductance_range,
        protection,
        speed_feedback,
        speed_resolution_rad_s,
        control,
        magnetizing,
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
pub(super) fn stage_code(s: Stage) -> (u8, u8, f32, u8) {
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

pub(super) fn stage_from_code(code: u8, r: u8, v: f32, i: u8) -> Result<Stage, DecodeError> {
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

pub(super) fn write_phases(w: &mut Writer<'_>, p: PhaseCommand) -> Result<(), BufferFull> {
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

pub(super) fn read_phases(r: &mut Reader<'_>) -> Result<PhaseCommand, DecodeError> {
    match (r.u8()?, r.abc()?) {
        (0, _) => Ok(PhaseCommand::Off),
        (1, d) => Ok(PhaseCommand::Duty(d)),
        _ => Err(DecodeError::Value),
    }
}
