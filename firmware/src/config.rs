//! The firmware's configuration, generated at build time from the workspace's `drive.toml`
//! (`build.rs`, `drive_file::codegen`): the drive specification ([`drive_spec`]) and its
//! discretised configuration, computed on the build host ([`DRIVE_CONFIG`]: the firmware
//! runs no f64 design arithmetic), the board's constants ([`BOARD`], [`TIM_CLOCK_HZ`], [`PWM_PERIOD_COUNTS`],
//! [`DEAD_TIME_TICKS`]) and the gain ranges `design certify drive.toml` certified
//! ([`SPEED_KP`], [`SPEED_TAU_MAX_NM`]), which the firmware enforces on gains written over
//! its link. Another motor or board is a change of `drive.toml` (and of the pin map in
//! `main.rs`).

use crate::control::BoardConfig;

include!(concat!(env!("OUT_DIR"), "/config.rs"));

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;

    /// The generated constants are the drive file's values, bit for bit.
    #[test]
    fn generated_configuration_equals_the_drive_file() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../drive.toml");
        let d = drive_file::DriveFile::load(std::path::Path::new(path)).unwrap();
        assert_eq!(drive_spec().unwrap(), d.spec);
        // The embedded configuration is the one the design path builds from the file.
        let built = controller_core::drive::DriveConfig::new(&d.spec).unwrap();
        assert_eq!(DRIVE_CONFIG, built.to_raw());
        assert_eq!(controller_core::drive::DriveConfig::from_raw(&DRIVE_CONFIG), Ok(built));
        let (b, c) = (d.board.unwrap(), d.certify.unwrap());
        assert_eq!(BOARD.current_a_per_count, b.table.current_a_per_count as f32);
        assert_eq!(BOARD.vdc_v_per_count, b.table.vdc_v_per_count as f32);
        assert_eq!(BOARD.current_offset_counts, b.table.current_offset_counts);
        assert_eq!(BOARD.encoder_lines, b.table.encoder_lines);
        // The default bootstrap pre-charge, 2 ms, at 20 kHz.
        assert_eq!(BOARD.bootstrap_precharge_periods, b.bootstrap_precharge_periods);
        assert_eq!(BOARD.bootstrap_precharge_periods, 40);
        assert_eq!(
            (PWM_PERIOD_COUNTS, DEAD_TIME_TICKS, TIM_CLOCK_HZ),
            (b.pwm_period_counts, b.dead_time_ticks, b.table.tim_clock_hz)
        );
        assert_eq!(SPEED_KP, (c.speed_kp_writable[0] as f32, c.speed_kp_writable[1] as f32));
        assert_eq!(
            SPEED_TAU_MAX_NM,
            (c.speed_tau_max_nm_writable[0] as f32, c.speed_tau_max_nm_writable[1] as f32)
        );
    }

    /// The encoder's input filter for drive.toml (170 MHz, 1 024 lines, overspeed 607.3 rad/s:
    /// quadrature edges 2.53 µs apart at the overspeed level, 15 % of it 0.379 µs): code 9,
    /// f_CK_INT/8 and N = 8, 0.376 µs — the longest setting within the bound.
    #[test]
    fn encoder_filter_fits_the_overspeed_edges() {
        let spec = drive_spec().unwrap();
        let (code, d) = drive_file::board::encoder_filter(
            TIM_CLOCK_HZ,
            BOARD.encoder_lines,
            spec.protection.overspeed_rad_s,
        );
        assert_eq!((ENCODER_FILTER, code), (9, 9));
        assert!((d - 64.0 / 170e6).abs() < 1e-15, "{d}");
        let edge = core::f64::consts::TAU / (4.0 * 1024.0 * spec.protection.overspeed_rad_s);
        assert!(d <= drive_file::board::ENCODER_FILTER_FRACTION * edge);
        // The next longer setting (f/16, N = 5: 0.47 µs) would not fit.
        assert!(80.0 / 170e6 > drive_file::board::ENCODER_FILTER_FRACTION * edge);
        // A very fast encoder gets no filter rather than one that eats its edges.
        assert_eq!(drive_file::board::encoder_filter(170_000_000, 1 << 20, 1e4).0, 0);
    }

    #[test]
    fn pwm_period_gives_the_drive_frequency() {
        let spec = drive_spec().unwrap();
        // Centre-aligned: the counter runs 0 → ARR → 0, one period = 2·ARR timer ticks
        // (with 2·(ARR + 1) the board formula made the PWM run at 20 004.7 Hz, issue 19).
        let f = f64::from(TIM_CLOCK_HZ) / (2.0 * f64::from(PWM_PERIOD_COUNTS));
        assert!((f - spec.pwm_frequency_hz).abs() < 1e-9, "{f}");
        // The 16-bit counter must not wrap by half its range between two reads below the
        // overspeed level (the estimator takes the wrapping difference as a signed step).
        let read_s = f64::from(spec.slow_divider) / spec.pwm_frequency_hz;
        let counts_per_rad = 4.0 * f64::from(BOARD.encoder_lines) / core::f64::consts::TAU;
        let counts = spec.protection.overspeed_rad_s * read_s * counts_per_rad;
        assert!(counts < 32_768.0 / 2.0, "{counts}");
    }
}
