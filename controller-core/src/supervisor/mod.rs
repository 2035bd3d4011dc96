//! The supervisor: the drive's protection, one room per family of checks, each with its
//! thresholds beside it and their reasoning.
//!
//! | module | checks | rate |
//! |---|---|---|
//! | [`limits`] | non-finite current or bus, overcurrent, current sum, bus over/undervoltage; the brake chopper | every fast step |
//! | [`phases`] | open phase, no motor current, the windowed current sum, a stuck switch | once per slow period |
//! | [`encoder`] | the encoder's jump, the encoder against the machine model (a pinned phase) | slow step / once per slow period |
//! | [`motion`] | overspeed, stall, speed-following error | slow step |
//! | [`thermal`] | the motor's and the inverter's I²t | every [`thermal::THERMAL_UPDATE_SLOW_STEPS`] slow steps |
//! | [`rest`] | the rotor at rest (what commissioning needs before it starts; no fault) | slow step |
//!
//! Loss of control (the loops at their voltage limit), a non-finite controller output and
//! the magnetizing time are the drive's own (the drive module): they read the loops.
//!
//! **Instant limits** (first thing in the fast step, any mode): a non-finite current or bus
//! voltage (the encoder's readings: in the slow step, where they change), a phase current
//! beyond `i_trip_a`, three phase currents that do not sum to zero within
//! `current_sum_max_a` (a dead or drifting sensor), a bus voltage above `vdc_max_v`, or —
//! when the bridge is active — below `vdc_min_v`, latches a [`Fault`] and turns all phases
//! off in the same step. In the slow step: overspeed (|ω_m| above `overspeed_rad_s` while
//! active) and stall (the speed loop's output at its limit, or a speed reference above 5 %
//! of the overspeed level, with the rotor below 0.5 % of it for `stall_time_s`),
//! speed-following error (the speed loop at its limit for `following_time_s` while the
//! speed moved *against* the commanded torque by more than a tenth of what that torque would
//! do to the drive's inertia: a load beyond the drive drags the motor away from its
//! reference); after the modulator, loss of control (the current loops at their voltage
//! limit for `saturation_time_s`), and once per slow period the encoder against the machine
//! model ([`Fault::EncoderImplausible`]). Magnetizing ends when the flux model — on the
//! measured current — reaches the running flux; if it has not within twice the time the
//! reference current needs, [`Fault::NoMotorCurrent`]. A non-finite controller output
//! (impossible for finite inputs, checked anyway) trips too.
//!
//! The checks' states are the drive's (the `Drive`'s), grouped by lifetime there;
//! their thresholds are [`Protection`] (the drive file's `[protection]`) and the constants of
//! each module.

pub mod encoder;
pub mod limits;
pub mod motion;
pub mod phases;
pub mod rest;
pub mod thermal;

#[cfg(doc)]
use crate::fault::Fault;
use crate::fault::FaultSet;
#[cfg(doc)]
use {
    encoder::ENCODER_RESIDUAL_FRACTION,
    motion::{FOLLOWING_PROGRESS_FRACTION, STALL_REFERENCE_FACTOR, STALL_SPEED_FRACTION},
};

/// Declares the protection's scalar thresholds once: each line is a field of [`Protection`]
/// (f64, in design units), its place on the link's wire (`Configure`, in this order) and its
/// line in the firmware's generated configuration ([`Protection::THRESHOLDS`],
/// [`Protection::thresholds`], [`Protection::with_thresholds`]). A new timed check's
/// threshold is one line here.
macro_rules! protection {
    ($($(#[$doc:meta])* $name:ident,)*) => {
        /// Protection thresholds. The drive file derives defaults for most of them from the
        /// motor and the other limits (`drive_file::drive`, where the reasoning is written
        /// down).
        #[derive(Clone, Copy, Debug, PartialEq)]
        pub struct Protection {
            $($(#[$doc])* pub $name: f64,)*
            /// The board's brake chopper (a resistor switched across the DC link), if it has one:
            /// the drive switches it with a hysteresis comparator on the measured bus voltage, in
            /// every mode (it protects the link whether or not the bridge is active).
            pub brake_chopper: Option<BrakeChopper>,
            /// The motor's I²t thermal limit ([`Fault::MotorOverload`]), if the motor's rated current
            /// and thermal time constant are known.
            pub motor_thermal: Option<ThermalLimit>,
            /// The inverter's I²t thermal limit ([`Fault::InverterOverload`]), from the board data.
            pub inverter_thermal: Option<ThermalLimit>,
            /// The faults answered by a controlled stop and then the bridge off (the fault latched
            /// once the stop ends), instead of the bridge off at once; only those after which the
            /// drive still controls the motor ([`FaultSet::STOPPABLE`]).
            pub stop_on: FaultSet,
        }

        impl Protection {
            /// The scalar thresholds' names, in their order (the wire's, the generated
            /// code's): the fields of the drive file's `[protection]` table of those names.
            pub const THRESHOLDS: [&'static str; THRESHOLD_COUNT] = [$(stringify!($name)),*];

            /// The scalar thresholds' values, in the order of [`Protection::THRESHOLDS`].
            pub fn thresholds(&self) -> [f64; THRESHOLD_COUNT] {
                [$(self.$name),*]
            }

            /// The protection of the scalar thresholds `t` (in the order of
            /// [`Protection::THRESHOLDS`]) and the structured rest.
            pub fn with_thresholds(
                t: [f64; THRESHOLD_COUNT],
                brake_chopper: Option<BrakeChopper>,
                motor_thermal: Option<ThermalLimit>,
                inverter_thermal: Option<ThermalLimit>,
                stop_on: FaultSet,
            ) -> Self {
                let [$($name),*] = t;
                Self { $($name,)* brake_chopper, motor_thermal, inverter_thermal, stop_on }
            }
        }

        /// How many scalar thresholds [`Protection`] has.
        pub const THRESHOLD_COUNT: usize = [$(stringify!($name)),*].len();
    };
}

protection! {
    /// Phase-current trip level (absolute instantaneous value), A.
    i_trip_a,
    /// DC-bus undervoltage trip (checked while the bridge is active), V.
    vdc_min_v,
    /// DC-bus overvoltage trip, V.
    vdc_max_v,
    /// Overspeed trip: |ω_m| above this while the bridge is active, mechanical rad/s.
    overspeed_rad_s,
    /// Stall trip: the speed loop's output at its limit, or a speed reference at least
    /// [`STALL_REFERENCE_FACTOR`] × the "not moving" level, while |ω_m| stays below
    /// [`STALL_SPEED_FRACTION`] of `overspeed_rad_s` for this long, s.
    stall_time_s,
    /// Speed-following error ([`Fault::FollowingError`]): the speed loop at its limit, the
    /// rotor turning (steps below the stall check's "not moving" level not counted), for this
    /// long while the speed moved against the commanded torque by more than
    /// [`FOLLOWING_PROGRESS_FRACTION`] of what that torque alone would have done to the drive's
    /// inertia, s.
    following_time_s,
    /// Current-sensor plausibility: |i_a + i_b + i_c| of the three measured phase currents
    /// (zero for any star-connected motor) above this trips, A.
    current_sum_max_a,
    /// Loss of control: the current loops at their voltage limit (an axis clamped, or the
    /// request outside the bridge's hexagon) for this long without a break, s.
    saturation_time_s,
    /// Encoder against the machine model: the applied voltage departs from the voltage the
    /// motor needs at the encoder's speed by more than [`ENCODER_RESIDUAL_FRACTION`] of the
    /// linear voltage limit, at every slow-step check for this long, s.
    encoder_check_time_s,
    /// Encoder jump: the position's change between two slow-loop reads may differ from the
    /// previous read's change by at most this, mechanical rad — the count quantisation plus
    /// the largest acceleration the mechanics allow over a read period squared. More is a
    /// glitch, a counter that stopped at speed, or an encoder that lost counts
    /// ([`Fault::EncoderLoss`], within two reads).
    encoder_jump_rad,
    /// A controlled stop (`Drive::controlled_stop`: the speed loop brakes to standstill,
    /// then the bridge goes off) takes at most this long before the bridge goes off anyway, s.
    stop_time_s,
    /// Open phase: the window, s, of the open-phase and no-motor-current check (a phase
    /// commanded a current but carrying none while the others do, for two windows in a row:
    /// [`Fault::OpenPhase`]; no phase carrying its current: [`Fault::NoMotorCurrent`]),
    /// sampled once per slow period; at least one slow period.
    open_phase_time_s,
    /// The rotor at rest ([`rest`]): the window, s, over which the shaft's displacement is
    /// judged (at least one slow period).
    rest_time_s,
    /// Current-sensor plausibility over one open-phase window: the mean
    /// |i_a + i_b + i_c| above this plus [`phases::CURRENT_SENSOR_GAIN_TOLERANCE`] of the window's
    /// mean |i_a| + |i_b| + |i_c| trips ([`Fault::CurrentSensor`]) — a sensor whose error
    /// stays below `current_sum_max_a` (a gain fault at a light load). The healthy sensors'
    /// own residual: their noise, quantisation and calibrated offsets (this level; the drive
    /// file's default, `drive_file::drive::default_current_sum_mean_a`) and their gain
    /// errors (the share), A.
    current_sum_mean_max_a,
}

/// An I²t thermal limit: a first-order thermal model, `dθ/dt = (I²/I_rated² − θ)/τ` with
/// I the RMS phase current, θ = 1 the steady temperature rise at the rated current; the
/// limit trips when θ reaches `overload_factor²` (so `overload_factor × I_rated` may flow
/// for ever, and `k × I_rated` trips after `τ·ln(k²/(k² − overload_factor²))` from cold).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ThermalLimit {
    /// Rated (continuous) RMS phase current, A.
    pub rated_current_a: f64,
    /// Thermal time constant, s.
    pub time_constant_s: f64,
    /// The continuous current allowed, as a multiple of the rated one (≥ 1: a motor's
    /// service factor; 1 for an inverter rated for its continuous current).
    pub overload_factor: f64,
}

/// Brake-chopper thresholds: on above `on_v`, off again below `off_v`
/// (0 < `off_v` < `on_v` < `REGEN_LIMIT_START`·`vdc_max_v`). With `on_v` below the
/// regeneration limit's start the chopper takes the braking energy and the limit acts only if
/// the chopper cannot (a resistor too large for the power, or none connected). At or above it
/// is refused (`DriveError::BrakeChopper`): the drive would cut its braking torque before
/// the chopper switched on, and the chopper take little — found by trying the 3 300 V template (on at 3 700 V, the cut from 3 515 V), which
/// braked from 320 rad/s at 50–460 of its 2 000 N·m, still at 160 rad/s 8 s later.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BrakeChopper {
    /// Switch on above this bus voltage, V.
    pub on_v: f64,
    /// Switch off below this bus voltage, V.
    pub off_v: f64,
}
