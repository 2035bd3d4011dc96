//! Converter scaling: ADC counts → physical units, duty cycle → PWM compare counts.
//!
//! Two paths with the same configuration:
//! * f32 (reference, Cortex-M4F),
//! * fixed point with the [`fixed`] crate for FPU-less cores: currents as `I16F16`
//!   (±32 768 A, 15 µA resolution — far below one ADC count of any practical shunt
//!   front end) and duties as `U1F15` (0 … 1.99997, so 100 % is exact; 1/32 768 resolution,
//!   finer than one compare count for periods up to 32 768 counts).
//!
//! Saturation, never wrap-around: a compare value is always in `[0, period]`, whatever the
//! duty (NaN → 0, i.e. the low switch on; the supervisor turns the bridge off first).

use fixed::types::{I16F16, U1F15};

/// Raw ADC conversion result.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AdcCode(pub u16);

/// Why a scaling was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ScalingError {
    /// Gain not finite or zero, or not representable in the fixed-point format.
    Gain,
    /// Offset above the ADC full scale.
    Offset,
    /// PWM period of zero counts.
    Period,
}

/// Linear ADC channel: `x = (code − offset)·gain`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AdcScaling {
    offset_counts: i32,
    gain_f32: f32,
    gain_fixed: I16F16,
}

impl AdcScaling {
    /// `gain` in physical units per count (e.g. A/count, may be negative for an inverting
    /// amplifier), `offset_counts` the code at zero (≤ `full_scale_counts`). In f32: the
    /// firmware builds it at start-up, and f64 there is software arithmetic (flash).
    pub fn new(gain: f32, offset_counts: u16, full_scale_counts: u16) -> Result<Self, ScalingError> {
        if !(gain.is_finite() && gain != 0.0 && gain.abs() < 32_767.0) {
            return Err(ScalingError::Gain);
        }
        if offset_counts > full_scale_counts {
            return Err(ScalingError::Offset);
        }
        // Rounded to the nearest 2⁻¹⁶ (|gain| < 32 767: in range), without the `fixed`
        // crate's generic float conversion (≈ 0.3 KB of the firmware's flash).
        let gain_fixed = I16F16::from_bits(libm::roundf(gain * 65_536.0) as i32);
        if gain_fixed == I16F16::ZERO {
            return Err(ScalingError::Gain);
        }
        Ok(Self { offset_counts: i32::from(offset_counts), gain_f32: gain, gain_fixed })
    }

    /// The same channel with its zero at `offset_counts` (a measured offset: the caller keeps
    /// it within the ADC range).
    pub fn with_offset(self, offset_counts: u16) -> Self {
        Self { offset_counts: i32::from(offset_counts), ..self }
    }

    /// Physical value in f32.
    #[inline]
    pub fn to_f32(&self, code: AdcCode) -> f32 {
        // |code − offset| ≤ 65 535: exact in f32.
        (i32::from(code.0) - self.offset_counts) as f32 * self.gain_f32
    }

    /// Physical value in `I16F16` (saturating).
    #[inline]
    pub fn to_fixed(&self, code: AdcCode) -> I16F16 {
        self.gain_fixed.saturating_mul_int(i32::from(code.0) - self.offset_counts)
    }
}

/// The dead-time generator's setting (STM32 advanced timers' BDTR.DTG, RM0440 §28.6.20) for
/// at least `ticks` timer clocks with CKD = 00 (t_DTS = t_CK_INT), the least such:
/// `DTG[7:5]` = 0xx gives DTG·1 (0 … 127), 10x (64 + `DTG[5:0]`)·2 (128 … 254), 110
/// (32 + `DTG[4:0]`)·8 (256 … 504), 111 (32 + `DTG[4:0]`)·16 (512 … 1 008). `None` above
/// 1 008 ticks (5.9 µs at 170 MHz). The firmware evaluates it at compile time for the drive
/// file's dead time; the drive file compensates what it gives ([`dead_time_dtg_ticks`]).
pub const fn dead_time_dtg(ticks: u16) -> Option<u8> {
    let t = ticks as u32;
    if t <= 127 {
        Some(t as u8)
    } else if t <= 254 {
        Some(0b1000_0000 | (t.div_ceil(2) - 64) as u8)
    } else if t <= 504 {
        Some(0b1100_0000 | (t.div_ceil(8) - 32) as u8)
    } else if t <= 1008 {
        Some(0b1110_0000 | (t.div_ceil(16) - 32) as u8)
    } else {
        None
    }
}

/// The dead time a [`dead_time_dtg`] code gives, timer clocks (CKD = 00): above 127 ticks
/// the generator's steps are 2, 8 and 16 ticks, so the dead time the bridge gets — the one
/// to compensate — can be up to 15 ticks longer than asked.
pub const fn dead_time_dtg_ticks(dtg: u8) -> u16 {
    let d = dtg as u16;
    match dtg >> 5 {
        0..=3 => d,
        4 | 5 => (64 + (d & 0x3F)) * 2,
        6 => (32 + (d & 0x1F)) * 8,
        _ => (32 + (d & 0x1F)) * 16,
    }
}

/// Centre-aligned PWM compare scaling: compare = duty·period.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PwmScaling {
    period_counts: u16,
}

impl PwmScaling {
    /// `period_counts` = the auto-reload value (compare = period → 100 % duty).
    pub fn new(period_counts: u16) -> Result<Self, ScalingError> {
        if period_counts == 0 { Err(ScalingError::Period) } else { Ok(Self { period_counts }) }
    }

    /// Compare value for an f32 duty, rounded to nearest, saturated to `[0, period]`.
    #[inline]
    pub fn compare(&self, duty: f32) -> u16 {
        self.compare_with(f32::from(self.period_counts), duty)
    }

    /// The three phases' compare values ([`PwmScaling::compare`] each): the period converted
    /// to f32 once.
    #[inline]
    pub fn compare3(&self, duty: crate::frames::Abc) -> [u16; 3] {
        let p = f32::from(self.period_counts);
        [self.compare_with(p, duty.a), self.compare_with(p, duty.b), self.compare_with(p, duty.c)]
    }

    /// `period_f32` is the period in f32. Converted through u32: `as u32` saturates and maps
    /// NaN to 0 (the intended behaviour here) in the Cortex-M4F's one `vcvt`, where `as u16`
    /// adds a saturation to 16 bits; the period's bound brings it into u16 range.
    #[inline]
    fn compare_with(&self, period_f32: f32, duty: f32) -> u16 {
        let c = (duty * period_f32 + 0.5) as u32;
        c.min(u32::from(self.period_counts)) as u16
    }

    /// Compare value for a fixed-point duty, rounded to nearest, saturated to `[0, period]`.
    #[inline]
    pub fn compare_fixed(&self, duty: U1F15) -> u16 {
        let c = (u32::from(duty.to_bits()) * u32::from(self.period_counts) + (1 << 14)) >> 15;
        // ≤ period·65 535/32 768 < 2^17; the min brings it into u16 range.
        c.min(u32::from(self.period_counts)) as u16
    }

    /// f32 duty → `U1F15` (saturating; NaN → 0).
    #[inline]
    pub fn duty_to_fixed(duty: f32) -> U1F15 {
        U1F15::saturating_from_num(if duty.is_nan() { 0.0 } else { duty })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// RM0440's ends of each DTG range decode to the manual's dead times; every dead time up
    /// to 1 008 ticks gets the least code that gives at least as much, and that code gives less
    /// than one of its range's steps more; the shipped 85 ticks are code 85.
    #[test]
    fn dead_time_codes_round_up_to_the_next_setting() {
        for (code, ticks) in [(0, 0), (127, 127), (0b1000_0000, 128), (0b1011_1111, 254), (0b1100_0000, 256)]
            .into_iter()
            .chain([(0b1101_1111, 504), (0b1110_0000, 512), (0b1111_1111, 1008)])
        {
            assert_eq!(dead_time_dtg_ticks(code), ticks, "{code:#010b}");
        }
        assert_eq!(dead_time_dtg(85), Some(85));
        assert_eq!(dead_time_dtg(1009), None);
        for t in 0..=1008u16 {
            let code = dead_time_dtg(t).unwrap();
            let got = dead_time_dtg_ticks(code);
            let step = match t {
                0..=127 => 1,
                128..=254 => 2,
                255..=504 => 8,
                _ => 16,
            };
            assert!(got >= t && got < t + step, "{t} ticks: code {code:#010b} gives {got}");
            // No smaller code gives enough.
            assert!((0..code).all(|c| dead_time_dtg_ticks(c) < t || dead_time_dtg_ticks(c) > got), "{t}");
        }
    }

    /// NUCLEO-style front end: 12-bit ADC at 3.3 V, 0.01 Ω shunt, gain 10 amplifier with
    /// mid-scale offset: 3.3/4096/(0.01·10) = 8.057e-3 A/count.
    fn shunt() -> AdcScaling {
        AdcScaling::new(3.3 / 4096.0 / 0.1, 2048, 4095).unwrap()
    }

    #[test]
    fn adc_known_codes() {
        let s = shunt();
        assert_eq!(s.to_f32(AdcCode(2048)), 0.0);
        assert!((s.to_f32(AdcCode(4095)) - 2047.0 * 3.3 / 409.6).abs() < 1e-4);
        assert!((s.to_f32(AdcCode(0)) + 2048.0 * 3.3 / 409.6).abs() < 1e-4);
    }

    #[test]
    fn rejects_bad_scalings() {
        assert_eq!(AdcScaling::new(0.0, 0, 4095), Err(ScalingError::Gain));
        assert_eq!(AdcScaling::new(f32::NAN, 0, 4095), Err(ScalingError::Gain));
        assert_eq!(AdcScaling::new(1e-7, 0, 4095), Err(ScalingError::Gain)); // below I16F16 resolution
        assert_eq!(AdcScaling::new(1.0, 5000, 4095), Err(ScalingError::Offset));
        assert_eq!(PwmScaling::new(0), Err(ScalingError::Period));
    }

    /// The fixed-point gain is the nearest multiple of 2⁻¹⁶ (what `fixed`'s conversion gives,
    /// off ties), over gains from the smallest accepted to the largest, both signs; a gain
    /// that rounds to zero is refused.
    #[test]
    fn the_fixed_gain_is_the_nearest() {
        let mut g = 1.6e-5f32;
        while g < 32_000.0 {
            for gain in [g, -g] {
                let s = AdcScaling::new(gain, 0, 4095).unwrap();
                let err = (f64::from(s.gain_fixed.to_num::<f32>()) - f64::from(gain)).abs();
                assert!(err <= 0.5 / 65_536.0, "{gain}: {err:e}");
                assert_eq!(s.gain_fixed, I16F16::from_num(gain), "{gain}");
            }
            g *= 1.37;
        }
        assert_eq!(AdcScaling::new(7.0e-6, 0, 4095), Err(ScalingError::Gain));
    }

    #[test]
    fn compare_limits_and_rounding() {
        let p = PwmScaling::new(4250).unwrap(); // 170 MHz, 20 kHz centre-aligned
        assert_eq!(p.compare(0.0), 0);
        assert_eq!(p.compare(1.0), 4250);
        assert_eq!(p.compare(0.5), 2125);
        assert_eq!(p.compare(2.0), 4250);
        assert_eq!(p.compare(-1.0), 0);
        assert_eq!(p.compare(f32::NAN), 0);
        assert_eq!(p.compare_fixed(U1F15::ONE), 4250);
        assert_eq!(p.compare_fixed(U1F15::MAX), 4250);
    }

    /// The three-phase form equals the one-phase form, and both saturate to `[0, period]`
    /// whatever the duty: beyond u32's range, infinite, NaN, negative.
    #[test]
    fn compare3_equals_compare_and_saturates() {
        let p = PwmScaling::new(4250).unwrap();
        let duties =
            [0.0, 0.25, 0.5, 0.999_9, 1.0, 1.000_2, 2.0, 1e9, 1e30, f32::INFINITY, -0.0, -1e-9, -1.0, -1e30];
        for &d in duties.iter().chain([f32::NEG_INFINITY, f32::NAN].iter()) {
            let [a, b, c] = p.compare3(crate::frames::Abc { a: d, b: 1.0 - d, c: 0.5 * d });
            assert_eq!([a, b, c], [p.compare(d), p.compare(1.0 - d), p.compare(0.5 * d)], "{d}");
            assert!(a <= 4250, "{d}: {a}");
        }
        assert_eq!((p.compare(1e30), p.compare(f32::INFINITY), p.compare(-1e30)), (4250, 4250, 0));
    }

    proptest! {
        /// Fixed and f32 ADC paths agree within one I16F16 LSB plus gain rounding:
        /// |Δ| ≤ 2^-16 · (1 + |code − offset|).
        #[test]
        fn adc_fixed_agrees_with_f32(code in 0u16..4096) {
            let s = shunt();
            let f = s.to_f32(AdcCode(code));
            let q = s.to_fixed(AdcCode(code)).to_num::<f32>();
            let bound = (1.0 + (f32::from(code) - 2048.0).abs()) / 65536.0;
            prop_assert!((f - q).abs() <= bound, "{} vs {}", f, q);
        }

        /// Fixed and f32 compare values differ by at most one count.
        #[test]
        fn compare_fixed_agrees_with_f32(duty in 0.0f32..=1.0, period in 1u16..=u16::MAX) {
            let p = PwmScaling::new(period).unwrap();
            let a = p.compare(duty);
            let b = p.compare_fixed(PwmScaling::duty_to_fixed(duty));
            prop_assert!(a.abs_diff(b) <= 1 + period / 32768, "{} vs {}", a, b);
            prop_assert!(a <= period && b <= period);
        }
    }
}
