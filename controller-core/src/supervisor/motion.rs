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
