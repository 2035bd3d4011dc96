//! The encoder's checks: its jump between reads ([`Fault::EncoderLoss`], in the slow step)
//! and the encoder against the machine model ([`Fault::EncoderImplausible`], once per slow
//! period), whose verdict names a phase the loops do not drive ([`Fault::OpenPhase`]).

use crate::fault::Fault;
use crate::frames::{AlphaBeta, wrap_angle};
use crate::num::{finite_positive, sqrt_f32};
use core::f32::consts::{PI, TAU};

/// The acceleration the jump check allows, in multiples of the drive's peak
/// (`drive::peak_acceleration_rad_s2`): a load ten times the drive's torque — the fault
/// matrix's seizure (10 × τ_max) and the supervisor's 20 N·m test — is motion, not a jump
/// (`drive_file::drive::default_encoder_jump_rad`).
pub const ENCODER_ACCEL_FACTOR: f64 = 10.0;

/// The encoder check's threshold, as a fraction of the linear voltage limit V_dc/√3.
pub const ENCODER_RESIDUAL_FRACTION: f32 = 0.5;
/// A *pinned phase* for the encoder check: the applied voltage's *departure* from the
/// model's (the vector difference, in the stationary frame) within ≈ 11.5° (cos⁻¹ 0.98) of
/// one phase's axis, the same axis and direction in the last half of the implausible checks
/// up to the trip. A leg held at the wrong rail removes `d·V_dc` from its own phase only,
/// and the common mode drops out of the stationary frame: what the loops ask and the motor
/// does not get lies on that phase's axis, whatever the other two legs do and however fast
/// the field turns, while a wrong encoder angle turns the model's voltage, and the
/// departure, with the field (a frozen encoder at top speed, generating, stays
/// `EncoderImplausible`: `a_frozen_encoder_at_speed_stays_the_encoders_fault`). Judged on
/// the applied voltage itself (until this was found), a stuck switch at rest, whose other
/// two legs wind up to push the current the dead one does not, lay off every axis and was
/// named the encoder's (`drive.toml`'s perturbed motor at 4, 10 and 20 kHz; population test
/// `a_stuck_switch_at_rest_is_named_by_what_the_bridge_did_not_apply`), and a turning field
/// had to be excluded. A switch stuck open (the opposite diode pins the phase to the other
/// rail) or an open lead, which the check names [`Fault::OpenPhase`],
/// not the encoder: until the reference reverses, the two give the same currents (named
/// [`Fault::SwitchOpen`] instead when the stuck-switch check saw one direction of a phase
/// go missing, `SwitchWatch::suspect`). Naming the switch here misnamed an open lead at
/// standstill, generating, on three of the fault matrix's seeds 0–11 (docs/protection.md).
pub const PINNED_PHASE_COS: f32 = 0.98;
/// The most the drive's field angle may turn over the encoder check's window for a phase's
/// short samples to say the loops do not drive it (`SwitchWatch::undriven`), rad: twice
/// cos⁻¹ [`PINNED_PHASE_COS`], the width of a pinned axis's window. With the field turning
/// faster a current that lags its reference falls short near every zero crossing.
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

crate::raw::raw_struct! {
    /// The encoder checks' levels (the drive configuration's).
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub(crate) struct EncoderLimits {
        /// The jump check's level at each spacing `n` = 1 … [`JUMP_SPACING_MAX`] reads,
        /// mechanical rad: its quantisation share — the second difference of three readings
        /// of motion the mechanics allow errs by less — plus `n²` times its acceleration share
        /// (`encoder_jump_rad` at `n` = 1; [`EncoderTrack::read`]).
        pub(crate) jump_levels_rad: [f32; JUMP_SPACING_MAX],
        /// Slow periods of implausible encoder before the trip ([`VoltageCheck::implausible`]).
        pub(crate) check_steps: u32,
    }
}

/// The longest spacing of the jump check, in reads: its second differences span twice it,
/// the speed estimate's window ([`crate::encoder::SPEED_WINDOW_READS`]).
pub const JUMP_SPACING_MAX: usize = crate::encoder::SPEED_WINDOW_READS / 2;
// `EncoderTrack::read` writes its four second differences out.
const _: () = assert!(JUMP_SPACING_MAX == 4);

/// The encoder's readings as the slow step takes them: the last angle, the whole turns
/// counted and the last changes. The shaft's, so they carry on through every mode, an enable
/// and a reconfiguration (a turn made while the bridge is off is still a turn).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct EncoderTrack {
    /// Encoder angle at the last read, mechanical rad, within a revolution.
    theta_m_prev_rad: f32,
    /// Whole turns counted from the readings.
    turns: i32,
    /// The last changes, one per read, mechanical rad, the newest first.
    steps_rad: [f32; 2 * JUMP_SPACING_MAX],
    /// How many of them, from the newest back, are references for the jump check (counted
    /// on beyond).
    changes: u8,
    /// A reading was taken (the next one makes a change).
    read_once: bool,
    /// The read period changed: the next change is the last across it, not a reference.
    rebase: bool,
}

impl EncoderTrack {
    /// Nothing read yet.
    pub(crate) const NONE: Self = Self {
        theta_m_prev_rad: 0.0,
        turns: 0,
        steps_rad: [0.0; 2 * JUMP_SPACING_MAX],
        changes: 0,
        read_once: false,
        rebase: false,
    };

    /// One reading `theta_m_rad`: the change since the last reading, mechanical rad (the
    /// wrapped difference of two angles within a revolution: exact in f32 however far the
    /// motor has turned; 0 for the first reading or a non-finite one), and whether it
    /// *jumped* (judged when `judge`).
    ///
    /// **Jump check** ([`Fault::EncoderLoss`]): the second difference of the readings at a
    /// spacing of `n` reads, `D_n = (θ_k − θ_{k−n}) − (θ_{k−n} − θ_{k−2n})`, for n = 1 …
    /// [`JUMP_SPACING_MAX`], beyond the level's quantisation share plus `n²` times its
    /// acceleration share (`encoder_jump_rad` at n = 1). For motion the mechanics allow, `D_n`
    /// is at most `α·(nT)²` plus the quantisation of its three readings, whatever `n`; a
    /// change `c` of the per-read increment (a glitch, a counter that stops at speed, a
    /// line count that changes) makes it `n·c` once `n` reads have passed: a change made
    /// between two reads, split between two one-read differences that each pass, is whole in
    /// the wider ones (found on a population member: an encoder losing half its lines at
    /// 41 rad/s changed two reads by 0.0061 and 0.0046 rad against a level of 0.0063, and
    /// ran on undetected). Below the speed at which a stopped counter's `D_n` exceeds the
    /// levels at every spacing, a stopped counter reads as a rotor that a seizure stopped
    /// (the mechanics' allowance, [`ENCODER_ACCEL_FACTOR`]): only the electrical quantities
    /// tell them apart.
    #[inline]
    pub(crate) fn read(&mut self, theta_m_rad: f32, limits: &EncoderLimits, judge: bool) -> (f32, bool) {
        if !theta_m_rad.is_finite() {
            return (0.0, false);
        }
        let step = if self.read_once { wrap_angle(theta_m_rad - self.theta_m_prev_rad) } else { 0.0 };
        // The angle wrapped past ±π: a turn.
        let raw = theta_m_rad - self.theta_m_prev_rad;
        if self.read_once && (raw - step).abs() > PI {
            self.turns = self.turns.saturating_add(if raw < step { 1 } else { -1 });
        }
        self.theta_m_prev_rad = theta_m_rad;
        // The newest first (element by element: `copy_within` is a `memmove` call).
        let s = self.steps_rad;
        self.steps_rad = [step, s[0], s[1], s[2], s[3], s[4], s[5], s[6]];
        // After a change of the read period, the change across it counts turns but is no
        // reference: the check judges from the second change at the new period.
        self.changes = if !self.read_once || self.rebase { 0 } else { self.changes.saturating_add(1) };
        (self.read_once, self.rebase) = (true, false);
        // D_n = 2·P_n − P_2n, P_m the newest m changes' sum (in-bounds constant indices).
        let s = &self.steps_rad;
        let p2 = s[0] + s[1];
        let (p3, p4) = (p2 + s[2], p2 + s[2] + s[3]);
        let p6 = p4 + s[4] + s[5];
        let p8 = p6 + s[6] + s[7];
        let d = [2.0 * s[0] - p2, 2.0 * p2 - p4, 2.0 * p3 - p6, 2.0 * p4 - p8];
        // Each spacing once its 2n changes are known.
        let known = usize::from(self.changes) / 2;
        let l = &limits.jump_levels_rad;
        let jumped = judge
            && ((known > 0 && d[0].abs() > l[0])
                || (known > 1 && d[1].abs() > l[1])
                || (known > 2 && d[2].abs() > l[2])
                || (known > 3 && d[3].abs() > l[3]));
        (step, jumped)
    }

    /// The last change is no reference (a cleared fault's: it may be the jump that latched
    /// it): the jump check judges again from the second change after this.
    #[inline]
    pub(crate) fn forget_last_change(&mut self) {
        self.changes = 0;
    }

    /// A track `turns` whole turns out (tests of what a long travel does to the checks).
    #[cfg(test)]
    pub(crate) fn with_turns(turns: i32) -> Self {
        Self { turns, ..Self::NONE }
    }

    /// The read period changes (a new slow divider): the jump check, a second difference of
    /// the readings, judges again from the second change at the new period; the angle and
    /// the turns carry on.
    pub(crate) fn restart_jump_check(&mut self) {
        self.changes = 0;
        self.rebase = true;
    }

    /// Multi-turn mechanical position, rad: the turns counted since the first reading plus
    /// the angle within the turn. In f32, its resolution is that of a position of this size
    /// (1e-3 rad at ±4 000 turns); the field angle does not use it.
    pub(crate) fn position_rad(&self) -> f32 {
        self.turns as f32 * TAU + self.theta_m_prev_rad
    }
}

/// The encoder-against-the-model check's counts: one run's (an enable starts them afresh).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct VoltageCheck {
    /// Consecutive slow periods with an implausible encoder.
    bad_steps: u32,
    /// … and of those, the last consecutive ones whose voltage held one phase's axis
    /// ([`PINNED_PHASE_COS`]), and which axis (phase index, and 3 added when negative).
    pinned_steps: u32,
    pinned_axis: u8,
}

impl VoltageCheck {
    /// A plausible check: the counts start again.
    #[inline]
    pub(crate) fn plausible(&mut self) {
        (self.bad_steps, self.pinned_steps) = (0, 0);
    }

    /// An implausible check (the applied voltage's magnitude off the model's by more than
    /// [`ENCODER_RESIDUAL_FRACTION`] of the linear limit; `departure` the applied voltage
    /// less the model's, stationary frame, V). After `steps` in a row
    /// the verdict: [`Fault::OpenPhase`] when the last half of them held one phase's axis
    /// (that phase does not answer: its lead or a switch, the same currents until the
    /// reference reverses) or `undriven` says a phase misses (the stuck-switch check's
    /// [`super::phases::SwitchWatch::undriven`]: a phase's current that misses is the
    /// bridge's, not the encoder's — a wrong field angle turns the references, the loops
    /// still follow them); [`Fault::EncoderImplausible`] otherwise.
    #[inline]
    pub(crate) fn implausible(
        &mut self,
        departure: AlphaBeta,
        steps: u32,
        undriven: impl FnOnce() -> bool,
    ) -> Option<Fault> {
        self.bad_steps = self.bad_steps.saturating_add(1);
        let axis = pinned_axis(departure);
        self.pinned_steps = match axis {
            Some(a) if self.pinned_steps == 0 || a == self.pinned_axis => self.pinned_steps + 1,
            _ => 0,
        };
        self.pinned_axis = axis.unwrap_or(0);
        if self.bad_steps < steps {
            return None;
        }
        let pinned = 2 * self.pinned_steps >= self.bad_steps;
        Some(if pinned || undriven() { Fault::OpenPhase } else { Fault::EncoderImplausible })
    }
}
