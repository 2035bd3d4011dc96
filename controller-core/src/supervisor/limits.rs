//! The instant limits of every fast step (non-finite inputs, overcurrent, the current sum,
//! the bus) and the brake chopper's comparator, any mode: a failing check latches its fault
//! and the bridge is off in the same step.

use crate::fault::Fault;
use crate::io::Measurements;
use crate::num::max_f32;

crate::raw::raw_struct! {
    /// The instant limits, as the fast step tests them (the drive configuration's).
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub(crate) struct Limits {
        /// Bus undervoltage level while the bridge is active, V (+0 for none: the bit test needs
        /// the sign bit clear).
        pub(crate) vdc_min_v: f32,
        /// Bus overvoltage level, V.
        pub(crate) vdc_max_v: f32,
        /// Bits of the phase-current trip level `i_trip_a` (finite, positive): see
        /// [`Limits::ok`]; [`Limits::fault`] reads the level back from them.
        pub(crate) i_trip_bits: u32,
        /// Bits of `current_sum_max_a` (compared like `i_trip_bits`).
        pub(crate) i_sum_bits: u32,
    }
}

impl Limits {
    /// All the checks pass: the common case, tested without working out which check
    /// fails. The phase currents are checked on their bit patterns: with the sign bit
    /// cleared, an IEEE 754 float orders like an unsigned integer, and ±∞ and NaN lie above
    /// every finite value. So `|i| > i_trip` (finite i) and "i not finite" are both
    /// `abs_bits(i) > abs_bits(i_trip)`: one integer comparison per phase, on the integer
    /// units, while the floating-point units run the control law. Equal to
    /// `self.fault(m, active).is_none()` for every input
    /// (`supervisor_bit_test_equals_float_test`).
    #[inline]
    pub(crate) fn ok(&self, m: &Measurements, active: bool) -> bool {
        let i = m.i_abc_a;
        let i_peak_bits = abs_bits(i.a).max(abs_bits(i.b)).max(abs_bits(i.c));
        // The bus on its bits too, sign included: a negative or NaN reading is above every
        // positive level, so `bits ≤ max` is "finite, not negative, not above the maximum"
        // (a negative reading is named undervoltage, in every mode); the minimum (validated
        // ≥ 0) only while the bridge is active.
        // `min ≤ bits ≤ max` as one unsigned comparison, `bits − min ≤ max − min` (H. S.
        // Warren, Hacker's Delight, 2nd ed., §4-1), which needs `min ≤ max` as integers: the
        // configuration has `+0 ≤ min < max` (`DriveConfig::new` stores a zero minimum as +0,
        // `from_raw` refuses −0), so both bit patterns have the sign bit clear.
        let vdc_bits = m.vdc_v.to_bits();
        let vdc_min_bits = if active { self.vdc_min_v.to_bits() } else { 0 };
        i_peak_bits <= self.i_trip_bits
            && abs_bits(i.a + i.b + i.c) <= self.i_sum_bits
            && vdc_bits.wrapping_sub(vdc_min_bits) <= self.vdc_max_v.to_bits().wrapping_sub(vdc_min_bits)
    }

    /// Which check fails, in order of precedence: non-finite current or bus voltage,
    /// overcurrent, current-sensor plausibility, bus overvoltage, bus undervoltage (while the
    /// bridge is `active`; a negative reading in every mode). The encoder's readings change
    /// only at the slow step, which checks them.
    pub(crate) fn fault(&self, m: &Measurements, active: bool) -> Option<Fault> {
        if !(m.i_abc_a.is_finite() && m.vdc_v.is_finite()) {
            return Some(Fault::NonFiniteInput);
        }
        let i = m.i_abc_a;
        let i_peak = max_f32(max_f32(i.a.abs(), i.b.abs()), i.c.abs()); // finite: checked above
        if i_peak > f32::from_bits(self.i_trip_bits) {
            return Some(Fault::Overcurrent);
        }
        if (i.a + i.b + i.c).abs() > f32::from_bits(self.i_sum_bits) {
            return Some(Fault::CurrentSensor);
        }
        if m.vdc_v > self.vdc_max_v {
            return Some(Fault::DcBusOvervoltage);
        }
        // Below zero is no bus at all (a sensor's sign or offset wrong): in every mode.
        if (active && m.vdc_v < self.vdc_min_v) || m.vdc_v.is_sign_negative() {
            return Some(Fault::DcBusUndervoltage);
        }
        None
    }
}

crate::raw::raw_struct! {
    /// The brake chopper's levels ([`super::BrakeChopper`], `f32::MAX` both without one).
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub(crate) struct BrakeLevels {
        /// On above this bus voltage, V.
        pub(crate) on_v: f32,
        /// … and off below this one, V.
        pub(crate) off_v: f32,
    }
}

impl BrakeLevels {
    /// The hysteresis comparator on the measured bus voltage, in every mode, from its state
    /// `on`: on above `on_v`, off below `off_v`, held between; off on a non-finite reading
    /// (the fast step trips on it; a resistor left on would drain a healthy bus).
    #[inline]
    pub(crate) fn switch(&self, on: bool, vdc_v: f32) -> bool {
        vdc_v > self.on_v || (on && vdc_v >= self.off_v)
    }
}

/// `x`'s bits with the sign bit cleared (the bits of |x|).
#[inline]
pub(crate) fn abs_bits(x: f32) -> u32 {
    x.to_bits() & 0x7fff_ffff
}
