//! Sensor models: phase-current ADC (gain and offset error, seeded Gaussian noise,
//! quantisation), DC-bus measurement (quantisation) and an incremental encoder whose counts
//! go through the same estimator the firmware uses ([`controller_core::encoder`]).

use crate::rng::{Normals, Rng};
use controller_core::encoder::{EncoderConfig, EncoderError, EncoderReading, EncoderState};
use controller_core::frames::Abc;
use std::f64::consts::TAU;

/// Speed window of the encoder estimator, in slow-loop reads: the firmware's.
pub const ENCODER_WINDOW: usize = controller_core::encoder::SPEED_WINDOW_READS;

/// Sensor non-idealities. `Default` is ideal (exact values).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SensorModel {
    /// Current ADC resolution, A per count (0: no quantisation).
    pub current_lsb_a: f64,
    /// Offset error per phase, A.
    pub current_offset_a: [f64; 3],
    /// Gain per phase (1: exact).
    pub current_gain: [f64; 3],
    /// RMS of white Gaussian noise added to each sample, A.
    pub current_noise_rms_a: f64,
    /// Bus-voltage ADC resolution, V per count (0: exact).
    pub vdc_lsb_v: f64,
    /// Encoder lines per revolution (`None`: exact speed and angle).
    pub encoder_lines: Option<u32>,
    /// Low-side shunts: the conduction a phase's sample needs on either side of the top of
    /// the count, s; a phase whose duty leaves less (in the period before the sample or the
    /// one after) reads no current — its shunt carries none while the high side conducts.
    /// `None`: the drive's own (`DriveSpec::sample_window_s`, the drive file's board) in a
    /// [`crate::scenario::Builtin`] run, none in a bare [`crate::sim::run`]; `Some(0.0)`:
    /// sensors that need no window.
    pub low_side_window_s: Option<f64>,
    /// Noise seed: equal seeds give equal runs.
    pub seed: u64,
}

impl Default for SensorModel {
    fn default() -> Self {
        Self {
            current_lsb_a: 0.0,
            current_offset_a: [0.0; 3],
            current_gain: [1.0; 3],
            current_noise_rms_a: 0.0,
            vdc_lsb_v: 0.0,
            encoder_lines: None,
            low_side_window_s: None,
            seed: 1,
        }
    }
}

impl SensorModel {
    /// A NUCLEO-G474RE-like front end: 12-bit ADC, 8.06 mA/count (3.3 V, 10 mΩ shunt,
    /// gain 10), 20 mA offset on phase b, +0.5 % gain on phase c, 10 mA rms noise,
    /// 0.1 V/count bus measurement, 1024-line encoder.
    pub fn realistic(seed: u64) -> Self {
        Self {
            current_lsb_a: 3.3 / 4096.0 / 0.1,
            current_offset_a: [0.0, 0.02, 0.0],
            current_gain: [1.0, 1.0, 1.005],
            current_noise_rms_a: 0.01,
            vdc_lsb_v: 0.1,
            encoder_lines: Some(1024),
            low_side_window_s: None,
            seed,
        }
    }
}

/// The trip level [`SensorModel::realistic`]'s board is designed for, A (±16.5 A of full
/// scale: about twice it).
pub const REALISTIC_TRIP_A: f64 = 8.0;

impl SensorModel {
    /// [`SensorModel::realistic`] on a board designed for a drive tripping at `i_trip_a`:
    /// full scale, LSB, noise and offset scaled by `i_trip_a`/[`REALISTIC_TRIP_A`] (1 for the
    /// shipped drive). A fixed ±16.5 A front end is 37 times too fine for a 300 A machine and
    /// too coarse for a 2.4 A one: its noise and offset alone reached the current-sum check's
    /// level there (a random motor of `design`'s campaign test tripped `CurrentSensor`).
    pub fn realistic_for_trip(seed: u64, i_trip_a: f64) -> Self {
        let k = if i_trip_a.is_finite() && i_trip_a > 0.0 { i_trip_a / REALISTIC_TRIP_A } else { 1.0 };
        let r = Self::realistic(seed);
        Self {
            current_lsb_a: r.current_lsb_a * k,
            current_offset_a: r.current_offset_a.map(|o| o * k),
            current_noise_rms_a: r.current_noise_rms_a * k,
            ..r
        }
    }
}

/// `x` to the nearest multiple of `lsb` (an ADC reading; `lsb` 0: exact).
fn quantize(x: f64, lsb: f64) -> f64 {
    if lsb > 0.0 { round_half_away(x / lsb) * lsb } else { x }
}

/// `x.round()` — to the nearest integer, halves away from zero, the sign of a zero kept —
/// bit for bit, without the call to libm's `round` that x86-64's baseline instruction set
/// needs (3 % of a campaign's time: three readings every PWM period). Below 2⁵² the
/// integer part is the truncating conversion's, exact, and so is the fraction `x − t`;
/// from 2⁵² up every f64 is an integer, and NaN and ±∞ are returned as they are.
#[inline]
fn round_half_away(x: f64) -> f64 {
    if x.is_nan() || x.abs() >= 4_503_599_627_370_496.0 {
        return x;
    }
    let t = ((x as i64) as f64).copysign(x);
    let fraction = x - t;
    if fraction >= 0.5 {
        t + 1.0
    } else if fraction <= -0.5 {
        t - 1.0
    } else {
        t
    }
}

/// Quadrature counts (4 per line) of an encoder with `lines` over the angle `theta_m_rad`.
fn counts_at(theta_m_rad: f64, lines: u32) -> i64 {
    (theta_m_rad * 4.0 * f64::from(lines) / TAU).floor() as i64
}

/// Sensor state for one run.
#[derive(Clone, Debug)]
pub struct Sensors {
    model: SensorModel,
    /// The current sensors' noise, seeded by the model's seed.
    noise: Normals,
    encoder: Option<(EncoderConfig<ENCODER_WINDOW>, EncoderState<ENCODER_WINDOW>, u32)>,
    last: EncoderReading,
    /// The current ADC is exact (no gain/offset error, noise or quantisation).
    exact_currents: bool,
    /// The last 16-bit count read, and the count a frozen encoder keeps reporting.
    last_count: u16,
    frozen_count: Option<u16>,
    /// The counter: `count_base + ⌊(θ − theta_base)·4·lines/2π⌋`, so that a glitch (spurious
    /// counts) or a change of the line count carries on from the count reached.
    count_base: i64,
    theta_base_rad: f64,
    /// Spurious counts to add at the next read (a glitch).
    glitch_counts: i64,
    /// Two current channels wired to each other's phase (`swap_current_channels`).
    swapped: Option<(usize, usize)>,
    /// −1: the encoder counts backwards (`reverse_encoder`).
    encoder_sign: f64,
}

impl Sensors {
    /// Sensors for a slow loop read every `slow_period_s`.
    pub fn new(model: SensorModel, slow_period_s: f64) -> Result<Self, EncoderError> {
        let encoder = match model.encoder_lines {
            Some(lines) => {
                Some((EncoderConfig::new(lines, slow_period_s as f32)?, EncoderState::default(), lines))
            }
            None => None,
        };
        let ideal = SensorModel::default();
        let exact_currents = model.current_lsb_a == 0.0
            && model.current_offset_a == ideal.current_offset_a
            && model.current_gain == ideal.current_gain
            && model.current_noise_rms_a == 0.0;
        Ok(Self {
            model,
            noise: Normals::new(Rng(model.seed)),
            encoder,
            last: EncoderReading::default(),
            exact_currents,
            last_count: 0,
            frozen_count: None,
            count_base: 0,
            theta_base_rad: 0.0,
            glitch_counts: 0,
            swapped: None,
            encoder_sign: 1.0,
        })
    }

    /// Sampled phase currents from the true ones.
    #[inline(always)]
    pub fn currents(&mut self, true_abc: [f64; 3]) -> Abc {
        self.currents_sampled(true_abc, 0)
    }

    /// [`Sensors::currents`] with the phases in `unsampled` (bit 0 a, 1 b, 2 c) read while
    /// their shunts carry no current ([`SensorModel::low_side_window_s`]).
    pub fn currents_sampled(&mut self, true_abc: [f64; 3], unsampled: u8) -> Abc {
        let mut true_abc = true_abc;
        for (k, i) in true_abc.iter_mut().enumerate() {
            if unsampled & (1 << k) != 0 {
                *i = 0.0;
            }
        }
        if self.exact_currents {
            let [a, b, c] = true_abc.map(|i| i as f32);
            Abc { a, b, c }
        } else {
            self.adc_currents(true_abc)
        }
    }

    /// [`Sensors::currents`] through the ADC model.
    #[inline(never)]
    fn adc_currents(&mut self, true_abc: [f64; 3]) -> Abc {
        let m = self.model;
        let mut out = [0.0f32; 3];
        for (k, o) in out.iter_mut().enumerate() {
            let (g, off) = (
                m.current_gain.get(k).copied().unwrap_or(1.0),
                m.current_offset_a.get(k).copied().unwrap_or(0.0),
            );
            let noise =
                if m.current_noise_rms_a > 0.0 { m.current_noise_rms_a * self.noise.normal() } else { 0.0 };
            let i = true_abc.get(k).copied().unwrap_or(0.0);
            *o = quantize(g * i + off + noise, m.current_lsb_a) as f32;
        }
        if let Some((p, q)) = self.swapped {
            out.swap(p, q);
        }
        let [a, b, c] = out;
        Abc { a, b, c }
    }

    /// From now on the current channels of phases `p` and `q` read each other's phase (a
    /// wiring error between the shunts and the ADC inputs, or two motor leads swapped at
    /// the sensors). Indices above 2 are taken as 2.
    pub fn swap_current_channels(&mut self, p: usize, q: usize) {
        self.swapped = Some((p.min(2), q.min(2)));
        self.exact_currents = false;
    }

    /// From now on the current sensor of `phase` reads `gain·i + offset_a` (a fault).
    pub fn fail_current_channel(&mut self, phase: usize, gain: f64, offset_a: f64) {
        if let (Some(g), Some(o)) =
            (self.model.current_gain.get_mut(phase), self.model.current_offset_a.get_mut(phase))
        {
            *g = gain;
            *o = offset_a;
            self.exact_currents = false;
        }
    }

    /// From now on the encoder counter does not move (a lost or stuck encoder): the
    /// estimator sees a constant count.
    pub fn freeze_encoder(&mut self) {
        self.frozen_count = Some(self.last_count);
    }

    /// At the next read the counter jumps by `counts` spurious counts (noise on the encoder's
    /// lines, a missed index): the count is off by that much from then on.
    pub fn glitch_encoder(&mut self, counts: i64) {
        self.glitch_counts = self.glitch_counts.saturating_add(counts);
    }

    /// From now on the encoder counts `lines` per revolution, the estimator still decoding
    /// with the configured number (a wrong line count); the count carries on from where it is,
    /// at the new rate from the angle `theta_m_rad` on. No effect without an encoder model.
    pub fn change_encoder_lines(&mut self, lines: u32, theta_m_rad: f64) {
        if let Some((_, _, l)) = &mut self.encoder {
            self.count_base =
                self.count_base.saturating_add(counts_at(theta_m_rad - self.theta_base_rad, *l));
            self.theta_base_rad = theta_m_rad;
            *l = lines.max(1);
        }
    }

    /// From now on the encoder counts backwards (its A and B channels swapped); the count
    /// carries on from where it is, from the angle `theta_m_rad` on.
    pub fn reverse_encoder(&mut self, theta_m_rad: f64) {
        if let Some((_, _, l)) = &self.encoder {
            self.count_base = self
                .count_base
                .saturating_add(counts_at(self.encoder_sign * (theta_m_rad - self.theta_base_rad), *l));
            self.theta_base_rad = theta_m_rad;
        }
        self.encoder_sign = -self.encoder_sign;
    }

    /// Measured bus voltage.
    pub fn vdc(&self, vdc_v: f64) -> f32 {
        quantize(vdc_v, self.model.vdc_lsb_v) as f32
    }

    /// Encoder read (call once per slow period): counts of a 16-bit quadrature counter.
    /// Without an encoder model, the exact values are returned, the angle wrapped into
    /// `[-π, π)` like the estimator's (and a frozen encoder reports the angle and zero speed
    /// of the moment it froze; a glitch or a line-count change needs the encoder model).
    pub fn encoder_read(&mut self, theta_m_rad: f64, omega_m_rad_s: f64) -> EncoderReading {
        let frozen = self.frozen_count;
        self.last = match &mut self.encoder {
            Some((cfg, st, lines)) => {
                self.count_base = self.count_base.saturating_add(std::mem::take(&mut self.glitch_counts));
                let counts = self.count_base.saturating_add(counts_at(
                    self.encoder_sign * (theta_m_rad - self.theta_base_rad),
                    *lines,
                ));
                // The hardware counter keeps only the low 16 bits.
                let count = frozen.unwrap_or(counts.rem_euclid(65_536) as u16);
                self.last_count = count;
                cfg.update(st, count)
            }
            None if frozen.is_some() => {
                EncoderReading { theta_m_rad: self.last.theta_m_rad, omega_m_rad_s: 0.0 }
            }
            None => {
                let (theta, omega) = (self.encoder_sign * theta_m_rad, self.encoder_sign * omega_m_rad_s);
                EncoderReading {
                    theta_m_rad: (theta - TAU * (theta / TAU).round()) as f32,
                    omega_m_rad_s: omega as f32,
                }
            }
        };
        self.last
    }

    /// The reading of the last encoder read (held between slow periods).
    pub fn encoder_held(&self) -> EncoderReading {
        self.last
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The ADC's rounding is `f64::round`'s, bit for bit: halves, signed zeros, the ends of
    /// the exact range, non-finite values, and a seeded sweep of readings.
    #[test]
    fn the_adc_rounds_as_f64_round_does() {
        let mut rng = crate::rng::Rng(7);
        let edges = [
            0.0,
            -0.0,
            0.3,
            -0.3,
            0.5,
            -0.5,
            0.499_999_999_999_999_94,
            1.5,
            -1.5,
            2.5,
            -2.5,
            1e300,
            -1e300,
            4_503_599_627_370_495.5,
            -4_503_599_627_370_495.5,
            4_503_599_627_370_496.0,
            f64::MAX,
            f64::MIN_POSITIVE,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ];
        let sweep = (0..100_000).map(|_| (rng.uniform() - 0.5) * 10f64.powi((rng.uniform() * 12.0) as i32));
        for x in edges.into_iter().chain(sweep) {
            assert_eq!(round_half_away(x).to_bits(), x.round().to_bits(), "{x:e}");
        }
        assert!(round_half_away(f64::NAN).is_nan());
    }

    #[test]
    fn noise_is_seeded_and_has_the_requested_rms() {
        let m = SensorModel { current_noise_rms_a: 0.05, ..Default::default() };
        let (mut a, mut b) = (Sensors::new(m, 1e-3).unwrap(), Sensors::new(m, 1e-3).unwrap());
        let mut c = Sensors::new(SensorModel { seed: 2, ..m }, 1e-3).unwrap();
        let mut sum2 = 0.0;
        let n = 20_000;
        let mut differs = false;
        for _ in 0..n {
            let (x, y, z) = (a.currents([0.0; 3]), b.currents([0.0; 3]), c.currents([0.0; 3]));
            assert_eq!(x, y);
            differs |= x != z;
            sum2 += f64::from(x.a).powi(2);
        }
        let rms = (sum2 / f64::from(n)).sqrt();
        assert!(differs);
        // 20 000 samples: the RMS estimate has ≈ 0.5 % standard error; allow 3 %.
        assert!((rms - 0.05).abs() < 0.0015, "{rms}");
    }

    #[test]
    fn quantisation_offset_and_gain() {
        let m = SensorModel {
            current_lsb_a: 0.01,
            current_offset_a: [0.0, 0.1, 0.0],
            current_gain: [1.0, 1.0, 2.0],
            ..Default::default()
        };
        let mut s = Sensors::new(m, 1e-3).unwrap();
        let i = s.currents([0.123, 0.0, 0.5]);
        assert!((i.a - 0.12).abs() < 1e-6 && (i.b - 0.1).abs() < 1e-6 && (i.c - 1.0).abs() < 1e-6);
        assert_eq!(
            Sensors::new(SensorModel { vdc_lsb_v: 0.5, ..Default::default() }, 1e-3).unwrap().vdc(310.3),
            310.5
        );
    }
}
