//! Current-sensor offset calibration with the bridge off (issue 19; issue 20's first check).
//!
//! With no current flowing, each phase-current channel reads its offset plus noise. Over
//! `samples` conversions the mean is the offset and the standard deviation the noise; a
//! channel whose offset lies further than `max_offset_error_counts` from the nominal code
//! (a broken amplifier, a missing reference voltage) or whose noise exceeds
//! `max_noise_counts` RMS (a floating input, a switching-noise coupling) is refused by name.
//! Sums of the codes' departures d from the nominal one: Σd in i32 (exact: at most
//! [`MAX_SAMPLES`] departures below 2^16 each), Σd² in f32 (each d² exact; the departures of
//! a healthy channel are small, so the sum is too, and the variance `E[d²] − E[d]²` loses
//! nothing that matters; a broken channel is refused anyway). Cheap on a Cortex-M4: no
//! 64-bit arithmetic (a soft conversion, `__aeabi_l2f`, on the M4F).

/// At least this many samples (issue 19: ≥ 1 024).
pub const MIN_SAMPLES: u32 = 1024;
/// At most this many (1.6 s of a 20 kHz loop): 2^15 departures below 2^16 each keep Σd
/// inside i32 (test `extreme_codes_at_most_samples_sum_exactly`).
pub const MAX_SAMPLES: u32 = 1 << 15;

/// Why a calibration configuration was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CalibrationConfigError {
    /// Samples outside [`MIN_SAMPLES`]…[`MAX_SAMPLES`].
    Samples,
    /// A limit that is not finite and positive.
    Limit,
}

/// Why a calibration failed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CalibrationError {
    /// The channel's offset is too far from the nominal code.
    Offset {
        /// Channel (0 = a).
        channel: u8,
        /// Its mean code.
        mean_counts: f32,
    },
    /// The channel is too noisy.
    Noise {
        /// Channel (0 = a).
        channel: u8,
        /// Its RMS noise, counts.
        rms_counts: f32,
    },
}

/// Offsets found: the rounded mean code of each channel, the mean and the RMS noise.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Offsets {
    /// Rounded mean code of each channel (the zero of its scaling).
    pub counts: [u16; 3],
    /// Mean code of each channel.
    pub mean_counts: [f32; 3],
    /// RMS noise of each channel, counts.
    pub rms_counts: [f32; 3],
}

/// Calibration limits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CalibrationConfig {
    samples: u32,
    nominal_counts: u16,
    max_offset_error_counts: f32,
    max_noise_counts: f32,
}

impl CalibrationConfig {
    /// `samples` conversions per channel; the offset must lie within
    /// `max_offset_error_counts` of `nominal_counts`, the RMS noise below `max_noise_counts`.
    pub fn new(
        samples: u32,
        nominal_counts: u16,
        max_offset_error_counts: f32,
        max_noise_counts: f32,
    ) -> Result<Self, CalibrationConfigError> {
        if !(MIN_SAMPLES..=MAX_SAMPLES).contains(&samples) {
            return Err(CalibrationConfigError::Samples);
        }
        let ok = |x: f32| x.is_finite() && x > 0.0;
        if !(ok(max_offset_error_counts) && ok(max_noise_counts)) {
            return Err(CalibrationConfigError::Limit);
        }
        Ok(Self { samples, nominal_counts, max_offset_error_counts, max_noise_counts })
    }

    /// Samples per channel.
    pub fn samples(&self) -> u32 {
        self.samples
    }
}

/// A calibration under way.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OffsetCalibration {
    /// Σd and Σd² of d = code − nominal.
    sum: [i32; 3],
    sum2: [f32; 3],
    n: u32,
}

impl Default for OffsetCalibration {
    fn default() -> Self {
        Self { sum: [0; 3], sum2: [0.0; 3], n: 0 }
    }
}

impl OffsetCalibration {
    /// One conversion of the three channels (bridge off). `None` until `cfg.samples()`
    /// have been taken, then the verdict (and again for every further call: start a new
    /// calibration with `OffsetCalibration::default()`).
    ///
    /// `#[inline]` (and the verdict's): compiled in the caller's crate, so at the firmware's
    /// opt-level "z" — the calibration runs once at start-up, and at controller-core's
    /// opt-level 2 its verdict was unrolled over the three channels (−116 B of flash).
    #[inline]
    pub fn add(
        &mut self,
        cfg: &CalibrationConfig,
        codes: [u16; 3],
    ) -> Option<Result<Offsets, CalibrationError>> {
        if self.n < cfg.samples {
            for ((s, s2), c) in self.sum.iter_mut().zip(self.sum2.iter_mut()).zip(codes) {
                let d = i32::from(c) - i32::from(cfg.nominal_counts);
                // |Σd| ≤ MAX_SAMPLES·(2^16 − 1) < 2^31: no overflow.
                *s += d;
                // |d| < 2^16, exact in f32; d² exact up to 2^24, rounded beyond (a broken
                // channel). Squared in f32: in i32 it overflows above 46 340.
                let df = d as f32;
                *s2 += df * df;
            }
            self.n += 1;
        }
        (self.n >= cfg.samples).then(|| self.verdict(cfg))
    }

    #[inline]
    fn verdict(&self, cfg: &CalibrationConfig) -> Result<Offsets, CalibrationError> {
        let n = self.n.max(1) as f32;
        let nominal = f32::from(cfg.nominal_counts);
        let mut out = Offsets { counts: [0; 3], mean_counts: [0.0; 3], rms_counts: [0.0; 3] };
        for channel in 0..3u8 {
            let k = usize::from(channel);
            let (s, s2) = (self.sum.get(k).copied().unwrap_or(0), self.sum2.get(k).copied().unwrap_or(0.0));
            let mean_d = s as f32 / n;
            let mean = nominal + mean_d;
            let rms = crate::num::sqrt_f32(crate::num::max_f32(s2 / n - mean_d * mean_d, 0.0));
            // Both finite: sums of finite codes.
            if mean_d.abs() > cfg.max_offset_error_counts {
                return Err(CalibrationError::Offset { channel, mean_counts: mean });
            }
            if rms > cfg.max_noise_counts {
                return Err(CalibrationError::Noise { channel, rms_counts: rms });
            }
            if let (Some(c), Some(m), Some(r)) =
                (out.counts.get_mut(k), out.mean_counts.get_mut(k), out.rms_counts.get_mut(k))
            {
                // Rounded to the nearest code (within the ADC range: checked above).
                (*c, *m, *r) = ((mean + 0.5) as u16, mean, rms);
            }
        }
        Ok(out)
    }
}

/// The current sensors' residual offsets, tracked while the bridge is off (a sensorless
/// drive's, [`crate::observer`]): the power-up calibration zeroes each channel's code, but
/// an amplifier's offset drifts with its temperature, and near zero stator frequency the
/// observer's voltage model integrates `R_s·Δi` (docs/sensorless.md: 20 mA, 2.5 LSB, moved
/// the plugging window's speed by several percent of base). With the bridge off no current
/// flows — the three phases' means are the offsets — so the mean of each block of
/// [`MIN_SAMPLES`] samples (the power-up calibration's least) is the residual, the first
/// block after the bridge turns off discarded (the current's decay through the diodes,
/// well within its 51 ms at 20 kHz). The estimate in use is the last complete block's,
/// kept while the bridge is on. Non-finite samples are skipped (the measurement checks
/// trip on them).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct IdleZero {
    sum_a: [f32; 3],
    samples: u32,
    /// Blocks completed since the bridge turned off (saturating).
    blocks: u8,
    offset_a: [f32; 3],
}

impl IdleZero {
    /// One sample `i_a` (phases a, b, c, A) with the bridge off.
    pub fn idle(&mut self, i_a: [f32; 3]) {
        if !i_a.iter().all(|x| x.is_finite()) {
            return;
        }
        for (s, x) in self.sum_a.iter_mut().zip(i_a) {
            *s += x;
        }
        self.samples += 1;
        if self.samples >= MIN_SAMPLES {
            if self.blocks > 0 {
                let n = self.samples as f32;
                self.offset_a = self.sum_a.map(|s| s / n);
            }
            (self.sum_a, self.samples, self.blocks) = ([0.0; 3], 0, self.blocks.saturating_add(1));
        }
    }

    /// The bridge is on: the next idle stretch starts a new first block.
    pub fn active(&mut self) {
        (self.sum_a, self.samples, self.blocks) = ([0.0; 3], 0, 0);
    }

    /// The sensors' zero moved (a calibration of their codes): what was read is of the old
    /// zero — forgotten, the next idle stretch starts a new first block.
    pub fn forget(&mut self) {
        *self = Self::default();
    }

    /// The residual offsets, A (zero before a block has completed).
    pub fn offset_a(&self) -> [f32; 3] {
        self.offset_a
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg() -> CalibrationConfig {
        CalibrationConfig::new(1024, 2048, 200.0, 8.0).unwrap()
    }

    /// The i32 sum's bound: the most samples, every code as far from the nominal one as a
    /// u16 can be, sums exactly (overflow checks are on in tests) and reads back the mean.
    #[test]
    fn extreme_codes_at_most_samples_sum_exactly() {
        for (nominal, code) in [(0u16, u16::MAX), (u16::MAX, 0u16)] {
            let c = CalibrationConfig::new(MAX_SAMPLES, nominal, 1e6, 1e6).unwrap();
            let mut cal = OffsetCalibration::default();
            let mut verdict = None;
            for _ in 0..MAX_SAMPLES {
                verdict = cal.add(&c, [code; 3]);
            }
            let o = verdict.unwrap().unwrap();
            assert_eq!(o.counts, [code; 3]);
            assert_eq!(o.mean_counts, [f32::from(code); 3]);
        }
    }

    /// A seeded noise source: uniform in ±`half` counts (RMS half/√3).
    fn noise(seed: &mut u64, half: i32) -> i32 {
        *seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
        ((*seed >> 33) % (2 * half as u64 + 1)) as i32 - half
    }

    #[test]
    fn finds_the_offsets_to_half_a_count() {
        let c = cfg();
        let mut cal = OffsetCalibration::default();
        let mut seed = 7;
        let offsets = [2060, 2011, 2048];
        let mut verdict = None;
        for k in 0..1024 {
            let codes = offsets.map(|o| (o + noise(&mut seed, 6)) as u16);
            verdict = cal.add(&c, codes);
            assert_eq!(verdict.is_some(), k == 1023);
        }
        let o = verdict.unwrap().unwrap();
        assert_eq!(o.counts, [2060, 2011, 2048]);
        for (m, want) in o.mean_counts.iter().zip(offsets) {
            assert!((m - want as f32).abs() < 0.5, "{m}");
        }
        // Uniform ±6: RMS √(((13² − 1)/12)) = 3.74.
        for r in o.rms_counts {
            assert!((r - 3.74).abs() < 0.3, "{r}");
        }
    }

    #[test]
    fn refuses_a_channel_out_of_range_or_noisy_by_name() {
        let c = cfg();
        let run = |codes: &dyn Fn(&mut u64) -> [u16; 3]| {
            let mut cal = OffsetCalibration::default();
            let mut seed = 3;
            let mut v = None;
            for _ in 0..1024 {
                v = cal.add(&c, codes(&mut seed));
            }
            v.unwrap()
        };
        // Phase b's amplifier stuck at the rail.
        let e = run(&|_| [2048, 4095, 2048]).unwrap_err();
        assert_eq!(e, CalibrationError::Offset { channel: 1, mean_counts: 4095.0 });
        // Phase c floating: ±40 counts of noise (RMS 23).
        let e = run(&|s| [2048, 2048, (2048 + noise(s, 40)) as u16]).unwrap_err();
        assert!(
            matches!(e, CalibrationError::Noise { channel: 2, rms_counts } if rms_counts > 20.0),
            "{e:?}"
        );
        assert_eq!(CalibrationConfig::new(100, 2048, 200.0, 8.0), Err(CalibrationConfigError::Samples));
        assert_eq!(CalibrationConfig::new(1024, 2048, f32::NAN, 8.0), Err(CalibrationConfigError::Limit));
    }

    /// With the bridge off the tracker reads each phase's offset through noise and
    /// quantisation (a 12-bit step of 8 mA, 10 mA RMS of noise: the realistic sensors') to a
    /// fraction of a step; the first block after the bridge turns off is discarded (a current
    /// still decaying there does not reach the estimate), and the estimate is kept while the
    /// bridge is on.
    #[test]
    fn the_idle_tracker_reads_the_residual_offsets() {
        let lsb = 3.3 / 4096.0 / 0.1;
        let offset = [0.0, 0.02, -0.013];
        let mut z = IdleZero::default();
        let mut seed = 7u64;
        let mut noise = || {
            // Irwin–Hall: the sum of 12 uniforms less 6, unit variance.
            (0..12)
                .map(|_| {
                    seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                    (seed >> 11) as f64 / (1u64 << 53) as f64
                })
                .sum::<f64>()
                - 6.0
        };
        let mut sample = |decay: f64| {
            offset.map(|o| {
                let x = o + decay + 0.01 * noise();
                ((x / lsb).round() * lsb) as f32
            })
        };
        // The first block: a current decaying from 2 A, discarded.
        for k in 0..MIN_SAMPLES {
            z.idle(sample(2.0 * (-f64::from(k) / 20.0).exp()));
        }
        assert_eq!(z.offset_a(), [0.0; 3]);
        for _ in 0..MIN_SAMPLES {
            z.idle(sample(0.0));
        }
        for (got, want) in z.offset_a().iter().zip(offset) {
            assert!((f64::from(*got) - want).abs() < 0.25 * lsb, "{got} against {want}");
        }
        let kept = z.offset_a();
        z.active();
        z.idle([f32::NAN; 3]);
        assert_eq!(z.offset_a(), kept);
        z.forget();
        assert_eq!(z.offset_a(), [0.0; 3]);
    }
}
