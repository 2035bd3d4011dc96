//! Incremental-encoder position and speed.
//!
//! Input: the quadrature counter of a timer in encoder mode (4 counts per line), read every
//! slow step as a wrapping `u16`. Position accumulates the *wrapping* difference of
//! successive reads, so the 16-bit hardware counter may overflow freely (as long as fewer
//! than 32 768 counts pass between two reads: at 1024 lines and a 1 kHz slow loop that is
//! 48 000 rad/s). Speed is the count difference over a window of `N` reads (M-method):
//! `ω = Δcounts·2π/(4·lines) / (N·T)`; resolution `2π/(4·lines·N·T)` rad/s, delay `N·T/2`.
//!
//! The angle is reported within one revolution, `[-π, π)`: the count modulo `4·lines`, exact
//! in f32. A multi-turn angle in f32 would lose the count after 2^24 counts (4 096
//! revolutions at 1024 lines, under a minute and a half at 3 000 rpm); the drive counts the
//! turns itself from successive readings (`controller_core::drive`).

use core::f32::consts::TAU;

/// The drive's speed window, in slow-loop reads: the firmware's estimator and the simulator's
/// encoder model both use it (one source). 8 reads at the shipped 2 kHz slow loop: 4 ms of
/// window, 2 ms of delay, 0.38 rad/s of resolution with a 1024-line encoder.
pub const SPEED_WINDOW_READS: usize = 8;

/// The speed reading's resolution, rad/s: one count of an encoder of `lines` over the speed
/// window of [`SPEED_WINDOW_READS`] reads every `read_period_s`, `2π/(4·lines·N·T)` (the one
/// place of this formula for a design in f64; [`EncoderConfig::speed_resolution_rad_s`] is the
/// estimator's own, in f32). Zero lines count as one.
pub fn speed_resolution_rad_s(lines: u32, read_period_s: f64) -> f64 {
    core::f64::consts::TAU / (4.0 * f64::from(lines.max(1))) / (SPEED_WINDOW_READS as f64 * read_period_s)
}

/// Why an encoder configuration was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EncoderError {
    /// Zero lines, or more than [`MAX_LINES`].
    Lines,
    /// Read period not finite and positive.
    Period,
}

/// The most lines per revolution: 4·lines = 2^24 counts, the most an f32 angle within a
/// revolution resolves count by count (and far inside the i32 the count is kept in).
pub const MAX_LINES: u32 = 1 << 22;

/// Encoder configuration. `N` is the speed window in reads.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EncoderConfig<const N: usize> {
    counts_per_rev: i32,
    rad_per_count: f32,
    rad_s_per_count: f32,
}

/// Encoder state: the count within a revolution, the accumulated count (wrapping, for the
/// speed window's differences) and its last `N` values. 32-bit only: 64-bit division and
/// conversions are library calls on the Cortex-M4F.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EncoderState<const N: usize> {
    last_raw: u16,
    /// In `[0, 4·lines)`.
    in_turn: i32,
    counts: u32,
    history: [u32; N],
    head: usize,
    primed: bool,
}

impl<const N: usize> Default for EncoderState<N> {
    fn default() -> Self {
        Self { last_raw: 0, in_turn: 0, counts: 0, history: [0; N], head: 0, primed: false }
    }
}

impl<const N: usize> EncoderState<N> {
    /// Start the speed window again (a new read period: the window's displacement is
    /// counted in reads) and keep the angle: the position stays continuous, the speed reads
    /// 0 until the window has filled again.
    pub fn restart_window(&mut self) {
        self.history = [self.counts; N];
        self.head = 0;
    }
}

/// Position (rad, within a revolution) and speed (rad/s).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct EncoderReading {
    /// Mechanical angle since the first read, rad, wrapped into `[-π, π)`.
    pub theta_m_rad: f32,
    /// Mechanical speed over the window, rad/s.
    pub omega_m_rad_s: f32,
}

impl<const N: usize> EncoderConfig<N> {
    /// `lines` per revolution, read every `read_period_s`. In f32: the firmware builds it at
    /// start-up, and f64 there is software arithmetic (flash).
    pub fn new(lines: u32, read_period_s: f32) -> Result<Self, EncoderError> {
        if lines == 0 || lines > MAX_LINES || N == 0 {
            return Err(EncoderError::Lines);
        }
        if !crate::num::finite_positive(read_period_s) {
            return Err(EncoderError::Period);
        }
        // 4·lines ≤ 2^24 is exact in f32.
        let rad_per_count = TAU / (4.0 * lines as f32);
        Ok(Self {
            // ≤ 2^24: no overflow.
            counts_per_rev: 4 * lines as i32,
            rad_per_count,
            rad_s_per_count: rad_per_count / (N as f32 * read_period_s),
        })
    }

    /// Speed resolution (one count over the window), rad/s.
    pub fn speed_resolution_rad_s(&self) -> f32 {
        self.rad_s_per_count
    }

    /// One read of the hardware counter.
    #[inline]
    pub fn update(&self, s: &mut EncoderState<N>, raw: u16) -> EncoderReading {
        if !s.primed {
            s.last_raw = raw;
            s.primed = true;
        }
        // Two's-complement difference of a wrapping 16-bit counter.
        let delta = i32::from(raw.wrapping_sub(s.last_raw) as i16);
        s.counts = s.counts.wrapping_add_signed(delta);
        s.last_raw = raw;
        let oldest = s.history.get(s.head).copied().unwrap_or(s.counts);
        if let Some(slot) = s.history.get_mut(s.head) {
            *slot = s.counts;
        }
        s.head = if s.head + 1 >= N { 0 } else { s.head + 1 };
        // Within a revolution: the count modulo 4·lines (|in_turn + delta| < 2^25 and
        // 4·lines ≥ 4: the checked remainder is never `None`), exact in f32 (≤ 2^24);
        // shifted into [-π, π).
        s.in_turn = (s.in_turn + delta).checked_rem_euclid(self.counts_per_rev).unwrap_or(0);
        let in_turn =
            if 2 * s.in_turn >= self.counts_per_rev { s.in_turn - self.counts_per_rev } else { s.in_turn };
        // The window's displacement: a wrapping difference, exact below 2^31 counts.
        let moved = s.counts.wrapping_sub(oldest) as i32;
        EncoderReading {
            theta_m_rad: in_turn as f32 * self.rad_per_count,
            omega_m_rad_s: moved as f32 * self.rad_s_per_count,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constant_speed_through_counter_overflow() {
        // 1024 lines, 1 kHz reads, 10-read window; 100 rad/s = 65.19 counts per read.
        let cfg = EncoderConfig::<10>::new(1024, 1e-3).unwrap();
        let mut s = EncoderState::default();
        let counts_per_rad = 4096.0 / f64::from(TAU);
        let mut r = EncoderReading::default();
        for k in 0..5000u32 {
            let theta = 100.0 * f64::from(k) * 1e-3;
            let raw = ((theta * counts_per_rad).floor() as i64).rem_euclid(65_536) as u16;
            r = cfg.update(&mut s, raw);
        }
        // 5 s at 100 rad/s = 499.9 rad (79.56 turns) = −2.7875 rad within the turn; the
        // counter wrapped ~5 times.
        let within = 499.9 - 80.0 * f64::from(TAU);
        assert!(
            (f64::from(r.theta_m_rad) - within).abs() < 2.0 * f64::from(TAU) / 4096.0 + 1e-3,
            "{}",
            r.theta_m_rad
        );
        assert!(
            (r.omega_m_rad_s - 100.0).abs() <= cfg.speed_resolution_rad_s() + 1e-3,
            "{}",
            r.omega_m_rad_s
        );
        assert!((cfg.speed_resolution_rad_s() - 0.1534).abs() < 1e-3);
    }

    #[test]
    fn reverse_rotation_and_rejects() {
        let cfg = EncoderConfig::<4>::new(500, 1e-3).unwrap();
        let mut s = EncoderState::default();
        let mut r = EncoderReading::default();
        for k in 0..20u16 {
            r = cfg.update(&mut s, 0u16.wrapping_sub(k * 10));
        }
        assert!(r.theta_m_rad < 0.0 && r.omega_m_rad_s < 0.0);
        // 10 counts/read at 2000 counts/rev, 1 kHz: −31.4 rad/s
        assert!((r.omega_m_rad_s + 10.0 * TAU / 2000.0 / 1e-3).abs() < 1e-3);
        assert_eq!(EncoderConfig::<4>::new(0, 1e-3), Err(EncoderError::Lines));
        assert_eq!(EncoderConfig::<4>::new(MAX_LINES + 1, 1e-3), Err(EncoderError::Lines));
        assert!(EncoderConfig::<4>::new(MAX_LINES, 1e-3).is_ok());
        assert_eq!(EncoderConfig::<4>::new(10, 0.0), Err(EncoderError::Period));
    }
    /// The 32-bit count gives what a 64-bit multi-turn count modulo 4·lines gives, for any
    /// line count (1 … MAX_LINES) and any steps the 16-bit counter can make between reads.
    #[test]
    fn in_turn_count_matches_a_64_bit_reference() {
        for lines in [1u32, 3, 1024, 2500, MAX_LINES] {
            let cfg = EncoderConfig::<8>::new(lines, 5e-4).unwrap();
            let cpr = 4 * i64::from(lines);
            let mut s = EncoderState::default();
            cfg.update(&mut s, 0); // primes: the count starts here
            let (mut raw, mut total) = (0u16, 0i64);
            let mut seed = 0x2545_f491_4f6c_dd1du64;
            // Every accumulated count, the primer's first; before the window fills, 0.
            let mut totals = vec![0i64];
            for k in 0..20_000usize {
                seed ^= seed << 13;
                seed ^= seed >> 7;
                seed ^= seed << 17;
                let step = (seed >> 48) as u16 as i16;
                let step = if k % 3 == 0 { step / 256 } else { step };
                raw = raw.wrapping_add(step as u16);
                total += i64::from(step);
                let r = cfg.update(&mut s, raw);
                let mut want = total.rem_euclid(cpr);
                if 2 * want >= cpr {
                    want -= cpr;
                }
                assert_eq!(
                    r.theta_m_rad,
                    want as f32 * (TAU / (4.0 * lines as f32)),
                    "lines {lines}, read {k}"
                );
                totals.push(total);
                let oldest = totals.len().checked_sub(9).map_or(0, |j| totals[j]);
                assert_eq!(r.omega_m_rad_s, (total - oldest) as f32 * cfg.speed_resolution_rad_s());
            }
        }
    }

    /// Hours at speed: 2^26 counts (16 384 revolutions at 1024 lines, 5.5 min at 50 rev/s).
    /// A multi-turn angle in f32 has an ulp of 2 counts there, so two readings a count
    /// apart could not be told apart; the reading within one revolution stays exact.
    #[test]
    fn readings_stay_exact_after_many_revolutions() {
        let cfg = EncoderConfig::<8>::new(1024, 5e-4).unwrap();
        let mut s = EncoderState::default();
        let count = TAU / 4096.0;
        // 49 counts per read (150 rad/s at 2 kHz), counter wrapping every 1 337 reads.
        let mut raw = 0u16;
        let mut prev = cfg.update(&mut s, raw).theta_m_rad;
        for k in 1..1_400_000u32 {
            raw = raw.wrapping_add(49);
            let r = cfg.update(&mut s, raw);
            if k > 1_369_000 {
                let mut d = r.theta_m_rad - prev;
                if d < -core::f32::consts::PI {
                    d += TAU;
                }
                assert!(
                    (d - 49.0 * count).abs() < 1e-4,
                    "read {k}: increment {d} rad, 49 counts = {}",
                    49.0 * count
                );
                assert!((-core::f32::consts::PI..core::f32::consts::PI).contains(&r.theta_m_rad));
            }
            prev = r.theta_m_rad;
        }
    }
}
