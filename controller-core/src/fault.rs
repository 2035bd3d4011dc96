//! Faults and modes: what the supervisor latches ([`Fault`]), sets of them ([`FaultSet`]) and
//! the drive's state machine ([`Mode`]). A fault's bit ([`Fault::bit`]) and a mode's byte
//! ([`Mode::code`]) are wire contracts (the link, the capture, the firmware's generated
//! configuration): pinned by golden tests below.

/// Declares the faults once, in bit order, each with its mode byte: the [`Fault`] enum (a
/// fault's bit is its place here), [`Fault::ALL`], [`Mode::code`] and [`Mode::from_code`].
/// A new fault is one line at the end, with the next free byte; none moves (the golden test
/// `fault_bits_and_mode_codes_are_the_wire_contract` pins them).
macro_rules! faults {
    ($($(#[$doc:meta])* $name:ident = $code:literal,)*) => {
        /// Latched fault causes.
        #[derive(Clone, Copy, Debug, PartialEq, Eq)]
        pub enum Fault {
            $($(#[$doc])* $name,)*
        }

        impl Fault {
            /// Every fault, in bit order.
            pub const ALL: [Fault; [$($code),*].len()] = [$(Fault::$name),*];

            /// The fault's byte as a [`Mode::Fault`] ([`Mode::code`]).
            const fn code(self) -> u8 {
                match self {
                    $(Fault::$name => $code,)*
                }
            }

            /// The fault of a mode byte.
            const fn of_code(c: u8) -> Option<Fault> {
                match c {
                    $($code => Some(Fault::$name),)*
                    _ => None,
                }
            }
        }
    };
}

faults! {
    /// A phase current exceeded `i_trip_a`.
    Overcurrent = 10,
    /// DC bus above `vdc_max_v`.
    DcBusOvervoltage = 11,
    /// DC bus below `vdc_min_v` while the bridge was active.
    DcBusUndervoltage = 12,
    /// A measurement was NaN or infinite.
    NonFiniteInput = 13,
    /// A controller output was not finite.
    NonFiniteOutput = 14,
    /// The encoder's position jumped: its change over a read departs from the previous
    /// read's by more than `encoder_jump_rad` (a glitch, a counter that stopped at speed, lost
    /// counts, a line count that changed).
    EncoderLoss = 15,
    /// The inverter's hardware break input fired (the timer already turned the bridge off;
    /// reported by the firmware through `Drive::trip`).
    HardwareBreak = 16,
    /// |ω_m| above `overspeed_rad_s` (a runaway: the load overpowers the drive, or the
    /// speed loop lost control).
    Overspeed = 17,
    /// The speed loop's output at its limit while the rotor does not turn, for
    /// `stall_time_s` (a locked rotor under a speed or position command).
    Stall = 18,
    /// The current loops asked for more voltage than the bridge has for
    /// `saturation_time_s`: they no longer control the current (dead sensors, a voltage
    /// limit reached at speed, an open phase).
    LossOfControl = 21,
    /// The applied voltage does not fit the motor at the encoder's speed for
    /// `encoder_check_time_s` (a frozen or lost encoder, a wrong line count).
    EncoderImplausible = 22,
    /// The three measured phase currents do not sum to zero (a dead, stuck or drifting
    /// current sensor).
    CurrentSensor = 19,
    /// No phase carries the current it is commanded over `open_phase_time_s`, or
    /// magnetizing takes more than twice the time the reference current needs (the flux
    /// model, on the measured current, does not build): no motor current flows (open leads,
    /// a motor that is not there, dead current sensors).
    NoMotorCurrent = 20,
    /// A phase is commanded a current but carries none, over `open_phase_time_s` (a broken
    /// lead or connector). Also the encoder check's verdict when the loops held the voltage
    /// on one phase's axis throughout (`PINNED_PHASE_COS`): that phase's current does not
    /// answer its voltage — an open lead, or a switch stuck open before the reference has
    /// reversed (until then the two are the same currents).
    OpenPhase = 23,
    /// The motor's I²t thermal model reached its limit (`Protection::motor_thermal`).
    MotorOverload = 24,
    /// The inverter's I²t thermal model reached its limit (`Protection::inverter_thermal`).
    InverterOverload = 25,
    /// The speed loop at its limit with the rotor turning, for `following_time_s`, while the
    /// speed error did not shrink as the commanded torque would make it (a load beyond the
    /// drive's torque: the motor is dragged away from its reference).
    FollowingError = 26,
    /// A phase follows its reference in one direction of current and not in the other: a
    /// bridge switch (or its gate drive) stuck open — its direction of current can only
    /// flow through the opposite diode, which pins the phase to the other rail.
    SwitchOpen = 27,
    /// The control interrupt finished past the next update event in two periods running:
    /// the duties it computed missed the period they were for (the firmware's loop timer;
    /// reported through `Drive::trip`, the bridge already off); or the slow step's job not
    /// back at its plan's adoption or at the next tick (`FastSide::step`: a slow context
    /// that cannot keep up), the bridge off in that period.
    Overrun = 28,
}

impl Fault {
    /// The fault's bit in a [`FaultSet`].
    pub const fn bit(self) -> u32 {
        1 << (self as u32)
    }
}

/// Drive state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// Bridge off, waiting for `enable`.
    Idle,
    /// Building rotor flux with zero torque.
    Magnetizing,
    /// Speed/position/torque control.
    Running,
    /// Latched fault, bridge off.
    Fault(Fault),
}

impl Mode {
    /// The bridge is the drive's: Magnetizing or Running.
    #[inline]
    pub fn is_active(self) -> bool {
        matches!(self, Mode::Magnetizing | Mode::Running)
    }
}

impl Mode {
    /// The mode as one byte: the link's, the capture's (0 Idle, 1 Magnetizing, 2 Running,
    /// a fault from 10 up: its byte in the `faults!` table).
    pub fn code(self) -> u8 {
        match self {
            Mode::Idle => 0,
            Mode::Magnetizing => 1,
            Mode::Running => 2,
            Mode::Fault(f) => f.code(),
        }
    }

    /// The mode of a [`Mode::code`] (`None` for a byte no mode has).
    pub fn from_code(c: u8) -> Option<Mode> {
        match c {
            0 => Some(Mode::Idle),
            1 => Some(Mode::Magnetizing),
            2 => Some(Mode::Running),
            c => Fault::of_code(c).map(Mode::Fault),
        }
    }
}

/// A set of [`Fault`]s (a bit per fault, [`Fault::bit`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FaultSet(pub u32);

impl FaultSet {
    /// No fault.
    pub const EMPTY: Self = Self(0);
    /// The faults a controlled stop may answer: the drive still measures, senses and
    /// controls the motor after them (thermal overloads; an overspeed, if the load does not
    /// overpower the drive — otherwise the stop time ends it).
    pub const STOPPABLE: Self =
        Self(Fault::MotorOverload.bit() | Fault::InverterOverload.bit() | Fault::Overspeed.bit());

    /// `f` is in the set.
    pub const fn contains(self, f: Fault) -> bool {
        self.0 & f.bit() != 0
    }

    /// The set with `f`.
    pub const fn with(self, f: Fault) -> Self {
        Self(self.0 | f.bit())
    }

    /// The faults in the set, in bit order.
    pub fn faults(self) -> impl Iterator<Item = Fault> {
        Fault::ALL.into_iter().filter(move |f| self.contains(*f))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The wire contracts, pinned: a fault's bit in a [`FaultSet`] (the drive file's
    /// `stop_on`, the firmware's generated configuration) and a mode's byte (the link, the
    /// capture). A new fault takes the next bit and the next code; none moves.
    #[test]
    fn fault_bits_and_mode_codes_are_the_wire_contract() {
        let golden: [(Fault, u32, u8); 19] = [
            (Fault::Overcurrent, 1 << 0, 10),
            (Fault::DcBusOvervoltage, 1 << 1, 11),
            (Fault::DcBusUndervoltage, 1 << 2, 12),
            (Fault::NonFiniteInput, 1 << 3, 13),
            (Fault::NonFiniteOutput, 1 << 4, 14),
            (Fault::EncoderLoss, 1 << 5, 15),
            (Fault::HardwareBreak, 1 << 6, 16),
            (Fault::Overspeed, 1 << 7, 17),
            (Fault::Stall, 1 << 8, 18),
            (Fault::LossOfControl, 1 << 9, 21),
            (Fault::EncoderImplausible, 1 << 10, 22),
            (Fault::CurrentSensor, 1 << 11, 19),
            (Fault::NoMotorCurrent, 1 << 12, 20),
            (Fault::OpenPhase, 1 << 13, 23),
            (Fault::MotorOverload, 1 << 14, 24),
            (Fault::InverterOverload, 1 << 15, 25),
            (Fault::FollowingError, 1 << 16, 26),
            (Fault::SwitchOpen, 1 << 17, 27),
            (Fault::Overrun, 1 << 18, 28),
        ];
        assert_eq!(golden.map(|(f, ..)| f), Fault::ALL, "Fault::ALL in bit order");
        for (f, bit, code) in golden {
            assert_eq!(f.bit(), bit, "{f:?}");
            assert_eq!(Mode::Fault(f).code(), code, "{f:?}");
            assert_eq!(Mode::from_code(code), Some(Mode::Fault(f)), "{f:?}");
        }
        for (m, code) in [(Mode::Idle, 0), (Mode::Magnetizing, 1), (Mode::Running, 2)] {
            assert_eq!((m.code(), Mode::from_code(code)), (code, Some(m)));
        }
        let used = (0..=u8::MAX).filter(|&c| Mode::from_code(c).is_some()).count();
        assert_eq!(used, 3 + Fault::ALL.len(), "no other byte is a mode");
        assert_eq!(FaultSet::STOPPABLE.0, (1 << 14) | (1 << 15) | (1 << 7));
    }
}
