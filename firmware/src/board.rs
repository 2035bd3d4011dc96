//! Board constants: NUCLEO-G474RE with a three-phase inverter power board. Another board is a
//! change of this file (and of the pin map in `main.rs`).

use crate::control::BoardConfig;

/// Timer clock of TIM1 (APB2 at SYSCLK), Hz.
pub const TIM_CLOCK_HZ: u32 = 170_000_000;

/// Dead time inserted by TIM1 between complementary switches, timer ticks (5.88 ns each):
/// 85 ticks = 500 ns.
pub const DEAD_TIME_TICKS: u16 = 85;

/// Centre-aligned PWM at the drive's 20 kHz: ARR = f_tim/(2·f_pwm) − 1.
pub const PWM_PERIOD_COUNTS: u16 = 4249;

/// Sensing and encoder of the power board: shunt amplifiers ±16.5 A over the 12-bit range
/// around mid-scale; bus divider 0.1 V per count (409.5 V full scale); 1024-line encoder.
/// The encoder plausibility limit is 1000 counts per 0.5 ms read, 3 068 rad/s: about 8× the
/// 376 rad/s top speed of the scenarios (test below).
pub const BOARD: BoardConfig = BoardConfig {
    current_a_per_count: 16.5 / 2048.0,
    current_offset_counts: 2048,
    vdc_v_per_count: 0.1,
    adc_full_scale: 4095,
    pwm_period_counts: PWM_PERIOD_COUNTS,
    encoder_lines: 1024,
    encoder_max_counts_per_read: 1000,
};

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pwm_period_gives_the_drive_frequency() {
        let spec = controller_core::drive::example_spec().unwrap();
        // Centre-aligned: one period = 2·(ARR + 1) timer ticks.
        let f = f64::from(TIM_CLOCK_HZ) / (2.0 * (f64::from(PWM_PERIOD_COUNTS) + 1.0));
        assert!((f - spec.pwm_frequency_hz).abs() < 1e-9, "{f}");
        // Encoder plausibility limit: 1000 counts per slow-loop read → rad/s, well above the
        // 376 rad/s top speed (seed 002 Fig. 16) and below the 16-bit wrap (32 768 counts).
        let read_s = f64::from(spec.slow_divider) / spec.pwm_frequency_hz;
        let counts_per_rad = 4.0 * f64::from(BOARD.encoder_lines) / core::f64::consts::TAU;
        let limit_rad_s = f64::from(BOARD.encoder_max_counts_per_read) / counts_per_rad / read_s;
        assert!((limit_rad_s - 3068.0).abs() < 1.0, "{limit_rad_s}");
        assert!(limit_rad_s > 2.0 * 376.0 && BOARD.encoder_max_counts_per_read < 32_768);
        // Dead time 500 ns.
        assert!((f64::from(DEAD_TIME_TICKS) / f64::from(TIM_CLOCK_HZ) - 500e-9).abs() < 1e-9);
    }
}
