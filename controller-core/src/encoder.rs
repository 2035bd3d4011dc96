//! Incremental-encoder position and speed.
//!
//! Input: the quadrature counter of a timer in encoder mode (4 counts per line), read every
//! slow step as a wrapping `u16`. Position accumulates the *wrapping* difference of
//! successive reads, so the 16-bit hardware counter may overflow freely (as long as fewer
//! than 32 768 counts pass between two reads: at 1024 lines and a 1 kHz slow loop that is
//! 48 000 rad/s). Speed is the count difference over a window of `N` reads (M-method):
//! `ω = Δcounts·2π/(4·lines) / (N·T)`; resolution `2π/(4·lines·N·T)` rad/s, delay `N·T/2`.

use core::f32::consts::TAU;

/// The drive's speed window, in slow-loop reads: the firmware's estimator and the simulator's
/// encoder model both use it (one source). 8 reads at the shipped 2 kHz slow loop: 4 ms of
/// window, 2 ms of delay, 0.38 rad/s of resolution with a 1024-line encoder.
pub const SPEED_WINDOW_READS: usize = 8;

/// Why an encoder configuration was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EncoderError {
    /// Zero lines.
    Lines,
    /// Read period not finite and positive.
    Period,
}

/// Encoder configuration. `N` is the speed window in reads.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EncoderConfig<const N: usize> {
    rad_per_count: f32,
    rad_s_per_count: f32,
}

/// Encoder state: accumulated counts and the last `N` accumulated values.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EncoderState<const N: usize> {
    last_raw: u16,
    counts: i64,
    history: [i64; N],
    head: usize,
    primed: bool,
}

impl<const N: usize> Default for EncoderState<N> {
    fn default() -> Self {
        Self { last_raw: 0, counts: 0, history: [0; N], head: 0, primed: false }
    }
}

/// Position (rad, not wrapped) and speed (rad/s).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct EncoderReading {
    /// Mechanical angle since the first read, rad.
    pub theta_m_rad: f32,
    /// Mechanical speed over the window, rad/s.
    pub omega_m_rad_s: f32,
}

impl<const N: usize> EncoderConfig<N> {
    /// `lines` per revolution, read every `read_period_s`. In f32: the firmware builds it at
    /// start-up, and f64 there is software arithmetic (flash).
    pub fn new(lines: u32, read_period_s: f32) -> Result<Self, EncoderError> {
        if lines == 0 || N == 0 {
            return Err(EncoderError::Lines);
        }
        if !(read_period_s.is_finite() && read_period_s > 0.0) {
            return Err(EncoderError::Period);
        }
        // 4·lines ≤ 2^34 rounds to f32 by at most half an ulp: the count's angle to 6e-8.
        let rad_per_count = TAU / (4.0 * lines as f32);
        Ok(Self { rad_per_count, rad_s_per_count: rad_per_count / (N as f32 * read_period_s) })
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
        s.counts += i64::from(raw.wrapping_sub(s.last_raw) as i16);
        s.last_raw = raw;
        let oldest = s.history.get(s.head).copied().unwrap_or(s.counts);
        if let Some(slot) = s.history.get_mut(s.head) {
            *slot = s.counts;
        }
        s.head = if s.head + 1 >= N { 0 } else { s.head + 1 };
        EncoderReading {
            // i64 → f32: exact below 2^24 counts (4096 revolutions at 1024 lines), then
            // relative precision 6e-8 — the position loop works on differences.
            theta_m_rad: s.counts as f32 * self.rad_per_count,
            omega_m_rad_s: (s.counts - oldest) as f32 * self.rad_s_per_count,
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
        // 5 s at 100 rad/s = 500 rad; the counter wrapped ~5 times.
        assert!(
            (f64::from(r.theta_m_rad) - 499.9).abs() < 2.0 * f64::from(TAU) / 4096.0 + 1e-3,
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
        assert_eq!(EncoderConfig::<4>::new(10, 0.0), Err(EncoderError::Period));
    }
}
