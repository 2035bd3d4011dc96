//! The motion checks of the slow step: overspeed, stall ([`Fault::Stall`]) and the
//! speed-following error ([`Fault::FollowingError`]).

#[cfg(doc)]
use crate::fault::Fault;

/// "Not moving" for the stall check: below this fraction of the overspeed level.
pub const STALL_SPEED_FRACTION: f64 = 0.005;

/// The stall check's "asked to move": the speed loop at its limit, or a speed reference at
/// least this multiple of the "not moving" level ([`STALL_SPEED_FRACTION`]: 5 % of the
/// overspeed level). The limit alone missed a seized rotor under a soft proportional law
/// (drives/em-synergy-24v.toml: 0.001 N·m per rad/s saturates only 120 rad/s from its
/// reference, and its mid-speed point is 109 rad/s) — found by its fault matrix. A speed
/// reference only: a position hold under a load asks its speed loop for the speed whose
/// torque holds the load (30 rad/s for that law under a quarter of its τ_max) with the rotor
/// rightly at rest — that tripped; a seized rotor under a position command saturates the
/// loop once the position loop's speed reference reaches its limit.
pub const STALL_REFERENCE_FACTOR: f32 = 10.0;

/// The following-error check's margin: over a window of `following_time_s` at the speed
/// loop's limit, the speed may move against the commanded torque by at most this fraction
/// of `Σ τ_cmd·T_slow / J` (the drive's inertia) — a load 10 % beyond the torque (5 % on
/// twice that J, the top of a certified box) before it trips. Against, not merely too
/// little: a load the envelope's torque just holds keeps the motor steady below its
/// reference with the loop at its limit (a hot motor in field weakening does, in the
/// campaign), which is no fault. The speed, not the speed error: a position loop may move
/// its speed reference faster than the torque limit lets the motor follow.
pub const FOLLOWING_PROGRESS_FRACTION: f64 = 0.1;

crate::raw::raw_struct! {
    /// The motion checks' levels (the drive configuration's).
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub(crate) struct MotionLimits {
        /// Overspeed: |ω_m| above this while the bridge is active, rad/s.
        pub(crate) overspeed_rad_s: f32,
        /// "Not moving": [`STALL_SPEED_FRACTION`] of the overspeed level, rad/s.
        pub(crate) stall_speed_rad_s: f32,
        /// Slow steps of stall before the trip.
        pub(crate) stall_slow_steps: u32,
        /// Slow steps of a following-error window.
        pub(crate) following_slow_steps: u32,
        /// [`FOLLOWING_PROGRESS_FRACTION`]·T_slow/J, rad/s per N·m: the least progress per slow
        /// step at the torque commanded.
        pub(crate) following_gain: f32,
        /// The speed loop's output limit (saturation test of the stall check; the following
        /// check's τ_max).
        pub(crate) speed_limit: f32,
    }
}

/// The stall and following-error checks' counts: one run's (an enable starts them afresh).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct MotionChecks {
    /// Consecutive slow steps with the stall condition.
    stall_steps: u32,
    /// Slow steps into the present following-error window, the speed at its start (rad/s)
    /// and the margin since, signed as the torque (rad/s).
    following_steps: u32,
    following_w0_rad_s: f32,
    following_owed_rad_s: f32,
}

impl MotionChecks {
    /// Both counts from zero (the drive starts Running: the speed loop starts afresh).
    pub(crate) fn restart(&mut self) {
        self.stall_steps = 0;
        self.following_steps = 0;
    }

    /// The stall check, one slow step: `asked` (commanded to move: a speed or position
    /// reference, the loop at its limit or a speed reference of at least
    /// [`STALL_REFERENCE_FACTOR`] × the "not moving" level) while the rotor is below that
    /// level, for `stall_slow_steps` in a row: `true`, [`Fault::Stall`].
    pub(crate) fn stall(&mut self, limits: &MotionLimits, asked: bool, omega_m_rad_s: f32) -> bool {
        if asked && omega_m_rad_s.abs() < limits.stall_speed_rad_s {
            self.stall_steps = self.stall_steps.saturating_add(1);
            self.stall_steps >= limits.stall_slow_steps
        } else {
            self.stall_steps = 0;
            false
        }
    }

    /// The speed-following check ([`Fault::FollowingError`], `true`), one slow step with the
    /// speed loop `at_limit` under a speed or position reference and the torque it commands,
    /// `torque_nm` (0 for an i_q command: it owes nothing); `torque_law`: the speed law's
    /// output is a torque. While the speed loop is at its limit (a rotor at rest pauses the
    /// window: that is the stall check's; one passing through zero, dragged backwards, keeps
    /// it), windows of `following_time_s`; a window in which the speed moved against the
    /// torque by more than it owes trips, any other starts the next — and within a window, a
    /// drag beyond what it owes so far plus a whole window's owing at the limit trips at
    /// once (a seizure at speed). Owed, with `f` =
    /// [`FOLLOWING_PROGRESS_FRACTION`] and J the drive's inertia: generating (a load driving
    /// the motor against the brake: a runaway), `f·Σ τ_cmd·T_slow/J` — a load beyond
    /// `(1 + f)·τ_cmd`; motoring, `Σ ((1 + f)·τ_max − |τ_cmd|)·T_slow/J` — a load beyond
    /// `(1 + f)` of the configured limit τ_max, which no speed can hold (at the limit the two
    /// agree). A motoring motor held below its reference by the envelope's smaller torque in
    /// field weakening slows to where the torque holds the load, which is no fault, unless
    /// the load is beyond what any speed gives: that is caught at once instead of once the
    /// motor has slowed to base speed. Speed laws with an i_q output (no torque limit to
    /// compare) count only while generating.
    pub(crate) fn following(
        &mut self,
        limits: &MotionLimits,
        at_limit: bool,
        omega_m_rad_s: f32,
        torque_nm: f32,
        torque_law: bool,
    ) -> bool {
        if !at_limit {
            self.following_steps = 0;
            return false;
        }
        if omega_m_rad_s.abs() < limits.stall_speed_rad_s {
            return false;
        }
        let generating = torque_nm * omega_m_rad_s < 0.0;
        // No torque owes nothing (a zero limit still reads as saturated).
        if torque_nm == 0.0 || !(generating || torque_law) {
            self.following_steps = 0;
            return false;
        }
        if self.following_steps == 0 {
            (self.following_w0_rad_s, self.following_owed_rad_s) = (omega_m_rad_s, 0.0);
        }
        let f = FOLLOWING_PROGRESS_FRACTION as f32;
        self.following_owed_rad_s += if generating {
            limits.following_gain * torque_nm
        } else {
            // following_gain = f·T_slow/J.
            let beyond = (1.0 + f) * limits.speed_limit - torque_nm.abs();
            limits.following_gain * (1.0 / f) * beyond * torque_nm.signum()
        };
        self.following_steps += 1;
        let owed = self.following_owed_rad_s;
        let moved = omega_m_rad_s - self.following_w0_rad_s;
        let against = -moved * owed.signum();
        // Dragged at once: against the torque by more than what is owed so far plus a whole
        // window's progress at the limit — the margin the window's length was chosen for
        // (`f·τ_max·T_window/J`: the encoder speed's quanta the default window holds), so a
        // seizure at speed (a load ten times the torque: the rotor stops within a window on a
        // heavy rotor, and the stall check then needed its own time on top) is named while it
        // drags, not a window later.
        let margin = limits.following_gain * limits.speed_limit * limits.following_slow_steps as f32;
        let mut dragged = owed != 0.0 && against > owed.abs() + margin;
        if self.following_steps >= limits.following_slow_steps {
            // Dragged against the torque by more than the margin.
            dragged |= owed != 0.0 && against > owed.abs();
            self.following_steps = 0;
        }
        dragged
    }
}
