//! The encoder's checks: its jump between reads ([`Fault::EncoderLoss`], in the slow step)
//! and the encoder against the machine model ([`Fault::EncoderImplausible`], once per slow
//! period), whose verdict names a phase the loops do not drive ([`Fault::OpenPhase`]).

#[cfg(doc)]
use crate::fault::Fault;
use crate::frames::AlphaBeta;
use crate::num::{finite_positive, sqrt_f32};

/// The encoder check's threshold, as a fraction of the linear voltage limit V_dc/√3.
pub const ENCODER_RESIDUAL_FRACTION: f32 = 0.5;
/// A *pinned phase* for the encoder check: the applied voltage within ≈ 11.5° (cos⁻¹ 0.98)
/// of one phase's axis, the same axis and direction in every implausible check up to the
/// trip, while the drive's field turns less than that window's width
/// ([`PINNED_FIELD_TURN_RAD`]) over the checks. The loops then hold one phase at a rail
/// and its current does not answer — a switch stuck open (the opposite diode pins the
/// phase to the other rail) or an open lead, which the check names [`Fault::OpenPhase`],
/// not the encoder: until the reference reverses, the two give the same currents (named
/// [`Fault::SwitchOpen`] instead when the stuck-switch check saw one direction of a phase
/// go missing, `SwitchWatch::suspect`). Naming the switch here misnamed an open lead at
/// standstill, generating, on three of the fault matrix's seeds 0–11 (docs/protection.md).
/// Measured on the 36 stuck switches of `stuck_switches_at_every_point`: 0.992–0.998 at the
/// trip.
pub const PINNED_PHASE_COS: f32 = 0.98;
/// … the most the drive's field angle may turn over the encoder check's window for a held
/// voltage to be a pinned phase, rad: twice cos⁻¹ [`PINNED_PHASE_COS`]. With the field
/// turning faster the voltage on one axis can be the loops' (an integrator at its clamp
/// holds the α axis, phase a's): a frozen encoder at top speed, generating, with the jump
/// and speed checks off, held phase a's axis for 3 of its 20 checks
/// (`a_frozen_encoder_at_speed_stays_the_encoders_fault`).
pub const PINNED_FIELD_TURN_RAD: f32 = 0.4;

/// The phase axis `v` lies on ([`PINNED_PHASE_COS`]): its index (0, 1, 2 for a, b, c), 3
/// added when `v` points the negative way; `None` off every axis. The phase voltages of the
/// amplitude-invariant inverse Clarke transform are the projections of `v` on the axes.
pub(crate) fn pinned_axis(v: AlphaBeta) -> Option<u8> {
    let on = PINNED_PHASE_COS * sqrt_f32(v.alpha * v.alpha + v.beta * v.beta);
    if !finite_positive(on) {
        return None; // no voltage, or not finite: on no axis
    }
    let p = v.inverse_clarke();
    [p.a, p.b, p.c, -p.a, -p.b, -p.c].iter().position(|&x| x >= on).and_then(|k| u8::try_from(k).ok())
}
