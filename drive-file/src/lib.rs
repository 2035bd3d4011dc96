//! The drive file: one TOML format for everything that configures a drive, read by the
//! simulator (`hil-sim`), the design toolkit (`design`) and the firmware's build script
//! (`firmware/build.rs`, through [`codegen`]).
//!
//! ```toml
//! [pwm]                       # optional; these are the defaults
//! frequency_hz = 20000.0      # fast loop = PWM rate
//! slow_divider = 10           # speed/position loops every 10th period
//!
//! [motor]                     # T-equivalent circuit referred to the stator (motor::RANGES)
//! rs_ohm = 16.2
//! rr_ohm = 23.2
//! ls_h = 1.44                 # self-inductances; need lm_h < ls_h, lr_h
//! lr_h = 1.5
//! lm_h = 1.42
//! pole_pairs = 1
//! j_kgm2 = 0.005
//! b_nms = 0.0005
//!
//! [controller]
//! current = { kind = "icad" }            # eq. (20); or { kind = "icad", kp, ki, lag_num, lag_den }
//!                                        # or { kind = "pi", kp = 360.0, ki = 9000.0 }
//! current_frame = "stationary"           # or "synchronous" (d/q loops)
//! current_decoupling = true              # default: d/q loops get jω_e·σL_s·i* fed forward; false: not
//! slip_current = "reference"             # default: the slip on i_q*, as seed 000's eq. (7);
//!                                        # "measured": on the measured q current while Running
//! speed_feedback = "encoder"             # default; "sensorless": the flux and speed observer;
//!                                        # "encoder_ride_through": the observer beside the encoder
//! control = "vector"                     # default; "vhz" or { kind = "vhz", … }: V/Hz (speed references only),
//!                                        # optional ramp_rad_s2 (default: 0.1·τ_max/J), k_u = 1.0, k_w = 4.0
//! speed = { kind = "saturated_p", kp = 0.05, tau_max_nm = 2.0 }
//! #  or { kind = "pi_torque", kp, ki, limit }  |  { kind = "pi_iq", kp, ki, limit }
//! position = { k_per_s = 10.0, omega_max_rad_s = 150.0 }   # default 10 1/s, 100 rad/s
//! flux_ref_wb = 0.9
//! flux_floor_wb = 0.05                   # default 5 % of flux_ref_wb
//! i_ref_max_a = 4.0
//! magnetized_fraction = 0.95             # default
//! voltage_margin = 0.98                  # default (1.0 overmodulating): steady voltage target, fraction of V_dc/√3
//! current_trim_bandwidth_rad_s = 20.0    # default: field-frame current trim; 0 turns it off
//! dead_time_compensation = false         # default; true compensates [board] dead_time_s
//! overmodulation = false                 # default; true: beyond the sampling window's hexagon,
//!                                        # one phase rebuilt (voltage_margin then 1.0 by default, up to 1.1027)
//! rotor_resistance_range = [1.0, 1.5]   # default: R_r adapted within × rr_ohm; [1, 1] fixes it
//! inductance_range = [1.0, 1.0]         # default: fixed; [0.6, 1.0] measures L within × the motor's
//!
//! [protection]
//! i_trip_a = 8.0
//! vdc_min_v = 200.0
//! vdc_max_v = 400.0
//! # overspeed_rad_s, stall_time_s, following_time_s, current_sum_max_a, saturation_time_s,
//! # encoder_check_time_s, encoder_jump_rad, stop_time_s, open_phase_time_s, rest_time_s,
//! # current_sum_mean_max_a: derived
//! # defaults (drive::protection_with_defaults; the encoder's from [board] encoder_lines)
//! brake_chopper = { on_v = 360.0, off_v = 350.0 }   # optional: the board's brake chopper
//!
//! [certify]                   # optional: what `design certify` checks (certify::CertifyTable)
//! [board]                     # optional: the firmware's board scaling (board::BoardTable)
//! [requirements]              # optional: what the campaign judges (requirements::RequirementsTable)
//! ```
//!
//! A *motor file* is any file with a `[motor]` table ([`motor::load`]); scenario files
//! (`hil-sim`) embed the drive tables or name a drive file with `drive = "path"` (relative to
//! the scenario file). Every error is reported as `file:line:column: key: reason`
//! ([`FileError`]), range errors included.
#![forbid(unsafe_code)]
#![cfg_attr(test, allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing))]

pub mod board;
pub mod certify;
pub mod codegen;
pub mod drive;
pub mod motor;
pub mod requirements;
pub mod source;
pub mod values;

pub use drive::{DriveFile, DriveTables};
pub use source::{FileError, Source};

use std::path::{Path, PathBuf};

/// The firmware's drive file, shipped at the workspace root: the DeLorenzo DL10115A1 on
/// the NUCLEO-G474RE power board, certified by CI.
pub const SHIPPED: &str = include_str!("../../drive.toml");

/// `reference` (as written in `from`) relative to `from`'s directory.
pub fn relative_to(from: &Path, reference: &str) -> PathBuf {
    let r = Path::new(reference);
    if r.is_absolute() {
        r.to_path_buf()
    } else {
        from.parent().map_or_else(|| r.to_path_buf(), |d| d.join(r))
    }
}

impl DriveFile {
    /// Parse and validate drive-file text read from `path`.
    pub fn parse(path: &Path, text: &str) -> Result<Self, FileError> {
        let src = Source::parse(path, text)?;
        // A scenario file given for a drive file: said as such (it read "duration_s: unknown
        // field", found by trying).
        if src.has("duration_s") {
            return Err(FileError::file(
                path,
                "this is a scenario file (it has duration_s): this command takes a drive file ([pwm], [motor], \
                 [controller], [protection], [certify]) — `hil-sim run` takes scenario files",
            ));
        }
        src.deserialize::<DriveTables>()?.validate(&src)
    }

    /// Read, parse and validate a drive file.
    pub fn load(path: &Path) -> Result<Self, FileError> {
        let text = source::read(path)?;
        Self::parse(path, &text)
    }

    /// The shipped drive file ([`SHIPPED`]).
    pub fn shipped() -> Result<Self, FileError> {
        Self::parse(Path::new("<builtin drive.toml>"), SHIPPED)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shipped drive's default controlled-stop time (`drive::default_stop_time_s` quotes
    /// it): 0.005 kg·m² · 607.3 rad/s / (0.5 · 1.5 · 0.9² / 1.5 N·m) = 7.50 s.
    #[test]
    fn default_stop_time_of_the_shipped_drive() {
        let f = DriveFile::shipped().unwrap();
        let t = f.spec.protection.stop_time_s;
        eprintln!("default stop_time_s = {t:.4} s");
        assert!((t - 0.005 * f.spec.protection.overspeed_rad_s / 0.405).abs() < 1e-9);
        assert!((t - 7.4974).abs() < 1e-3, "{t}");
    }

    fn err(text: &str) -> FileError {
        DriveFile::parse(Path::new("d.toml"), text).unwrap_err()
    }

    /// `line:column` of the first occurrence of `needle` in the shipped file.
    fn pos(text: &str, needle: &str) -> (usize, usize) {
        let off = text.find(needle).unwrap();
        let line = text[..off].matches('\n').count() + 1;
        let col = text[..off].rsplit('\n').next().unwrap().chars().count() + 1;
        (line, col)
    }

    /// `overmodulation`: the drive counts on the full hexagon's circle (the board's window
    /// still the sampled limit), and its voltage target may reach beyond the circle up to
    /// six-step's fundamental — beyond 1 without overmodulation, and beyond six-step with it,
    /// an error that names `voltage_margin` and the bound.
    #[test]
    fn overmodulation_counts_on_the_full_hexagon_and_widens_the_voltage_target() {
        let s = SHIPPED;
        let with = |lines: &str| s.replacen("[controller]\n", &format!("[controller]\n{lines}\n"), 1);
        let shipped = DriveFile::shipped().unwrap().spec;
        assert!(!shipped.overmodulation);
        let d = DriveFile::parse(Path::new("d.toml"), &with("overmodulation = true")).unwrap().spec;
        assert!(d.overmodulation);
        assert_eq!(d.voltage_margin, drive::DEFAULT_VOLTAGE_MARGIN_OVERMODULATING);
        assert_eq!(shipped.voltage_margin, drive::DEFAULT_VOLTAGE_MARGIN);
        assert_eq!(d.duty_sampled(), shipped.duty_max());
        assert_eq!(d.duty_max(), 1.0 - d.dead_time_compensation_s * d.pwm_frequency_hz);
        assert!(d.duty_max() > d.duty_sampled());
        let d = DriveFile::parse(Path::new("d.toml"), &with("overmodulation = true\nvoltage_margin = 1.05"))
            .unwrap();
        assert_eq!(d.spec.voltage_margin, 1.05);
        let e = err(&with("voltage_margin = 1.05"));
        assert_eq!(e.key.as_deref(), Some("controller.voltage_margin"), "{e}");
        assert!(e.to_string().contains("up to 1.1027 with controller.overmodulation"), "{e}");
        let e = err(&with("overmodulation = true\nvoltage_margin = 1.2"));
        assert_eq!(e.key.as_deref(), Some("controller.voltage_margin"), "{e}");
        assert!(e.to_string().contains("(0, 1.1027] (six-step"), "{e}");
        let e = err(&with("overmodulation = \"yes\""));
        assert_eq!(e.key.as_deref(), Some("controller.overmodulation"), "{e}");
    }

    /// `speed_feedback`: the drive runs on the observer; a rate too slow for it up to the
    /// overspeed level and an unknown value are errors that name the key.
    #[test]
    fn the_speed_feedback_key_chooses_the_observer_and_names_itself_when_wrong() {
        let s = SHIPPED;
        let with = |line: &str| s.replacen("[controller]\n", &format!("[controller]\n{line}\n"), 1);
        let d = DriveFile::parse(Path::new("d.toml"), &with("speed_feedback = \"sensorless\"")).unwrap();
        assert_eq!(d.spec.speed_feedback, controller_core::drive::SpeedFeedback::Sensorless);
        assert_eq!(
            DriveFile::shipped().unwrap().spec.speed_feedback,
            controller_core::drive::SpeedFeedback::Encoder
        );
        let e = err(&with("speed_feedback = \"hall\""));
        assert_eq!(e.key.as_deref(), Some("controller.speed_feedback"), "{e}");
        // 2 kHz PWM with a 1 kHz slow loop: (α/2 + 0.7·p·ω_max)·T = 0.22 per sample.
        let slow = with("speed_feedback = \"sensorless\"")
            .replacen("frequency_hz = 20000.0", "frequency_hz = 2000.0", 1)
            .replacen("slow_divider = 10", "slow_divider = 2", 1);
        let e = err(&slow);
        assert_eq!(e.key.as_deref(), Some("controller.speed_feedback"), "{e}");
        assert!(e.to_string().contains("sample faster or lower the top speed"), "{e}");
        // The observer beside the encoder: the same observer, the same refusal, named.
        let d = DriveFile::parse(Path::new("d.toml"), &with("speed_feedback = \"encoder_ride_through\""))
            .unwrap();
        assert_eq!(d.spec.speed_feedback, controller_core::drive::SpeedFeedback::EncoderRideThrough);
        let e = err(&slow.replacen("\"sensorless\"", "\"encoder_ride_through\"", 1));
        assert_eq!(e.key.as_deref(), Some("controller.speed_feedback"), "{e}");
        assert!(e.to_string().contains("encoder_ride_through"), "{e}");
    }

    /// `control`: V/Hz with its ramp, or its default (a tenth of the drive's torque on the
    /// motor's inertia: drive.toml's 1.5·1·(1.42²/1.5)·0.634·√(4² − 0.634²) N·m × 0.1 over
    /// 0.005 kg·m²); an unknown kind and a bad ramp name the key.
    #[test]
    fn the_control_key_chooses_vhz_and_names_itself_when_wrong() {
        use controller_core::drive::Control;
        let s = SHIPPED;
        let with = |line: &str| s.replacen("[controller]\n", &format!("[controller]\n{line}\n"), 1);
        assert_eq!(DriveFile::shipped().unwrap().spec.control, Control::Vector);
        let d =
            DriveFile::parse(Path::new("d.toml"), &with("control = { kind = \"vhz\", ramp_rad_s2 = 50.0 }"))
                .unwrap();
        assert_eq!(d.spec.control, Control::VHz { ramp_rad_s2: 50.0, k_u: 1.0, k_w: 4.0 });
        let d = DriveFile::parse(Path::new("d.toml"), &with("control = { kind = \"vhz\" }")).unwrap();
        let Control::VHz { ramp_rad_s2, .. } = d.spec.control else { panic!("{:?}", d.spec.control) };
        let (i_d, lm) = (0.9 / 1.42, 1.42f64);
        let torque = 1.5 * lm * lm / 1.5 * i_d * (16.0 - i_d * i_d).sqrt();
        eprintln!("drive.toml's default V/Hz ramp: {ramp_rad_s2:.1} rad/s²");
        assert!((ramp_rad_s2 - 0.1 * torque / 0.005).abs() < 1e-9, "{ramp_rad_s2}");
        // The name alone: the defaults (a user's first try).
        let named = DriveFile::parse(Path::new("d.toml"), &with("control = \"vhz\"")).unwrap();
        assert_eq!(named.spec.control, d.spec.control);
        let plain = with("control = { kind = \"vhz\", k_u = 0.0, k_w = 0.0 }");
        let d = DriveFile::parse(Path::new("d.toml"), &plain).unwrap();
        assert!(matches!(d.spec.control, Control::VHz { k_u: 0.0, k_w: 0.0, .. }));
        for bad in [
            "control = { kind = \"scalar\" }",
            "control = \"scalar\"",
            "control = 3",
            "control = { kind = \"vhz\", ramp_rad_s2 = -1.0 }",
            "control = { kind = \"vhz\", ramp_rad_s2 = 1e300 }",
            "control = { kind = \"vhz\", k_w = -4.0 }",
            "control = { kind = \"vhz\", gain = 1.0 }",
        ] {
            let e = err(&with(bad));
            assert!(e.key.as_deref().is_some_and(|k| k.starts_with("controller.control")), "{bad}: {e}");
        }
    }

    #[test]
    fn shipped_file_is_complete() {
        let d = DriveFile::shipped().unwrap();
        assert!(d.certify.is_some() && d.board.is_some());
        let b = d.board.unwrap();
        // 170 MHz / (2 · 4250) = 20 000 Hz exactly.
        assert_eq!((b.pwm_period_counts, b.dead_time_ticks), (4250, 85));
    }

    /// Issue 16, item 2: each value found by trying is an input error that points at it.
    #[test]
    fn bad_values_point_at_file_line_column_and_key() {
        let s = SHIPPED;
        let replace = |from: &str, to: &str| {
            assert!(s.contains(from), "{from}");
            s.replacen(from, to, 1)
        };
        // A three-element interval (was silently read as its first two).
        let e = err(&replace("rs_factor = [1.0, 1.5]", "rs_factor = [1.0, 1.2, 1.5]"));
        assert_eq!(e.key.as_deref(), Some("certify.rs_factor"), "{e}");
        assert!(e.reason.contains("exactly 2"), "{e}");
        let (line, _) = pos(s, "rs_factor");
        assert_eq!(e.at.map(|a| a.0), Some(line), "{e}");
        // A NaN requirement (was "limit NaN" failures at run time).
        let e = err(&replace("phase_margin_deg_min = 45.0", "phase_margin_deg_min = nan"));
        let (line, col) = pos(s, "phase_margin_deg_min");
        assert_eq!(
            e.to_string(),
            format!(
                "d.toml:{line}:{}: certify.phase_margin_deg_min: is NaN; must be a finite number",
                col + 23
            )
        );
        // A speed range the sweep could not finish (was a hang).
        let e = err(&replace("omega_r_max_rad_s = 400.0", "omega_r_max_rad_s = 1e9"));
        assert_eq!(e.key.as_deref(), Some("certify.omega_r_max_rad_s"), "{e}");
        // A certificate at standstill only (was accepted: the fault matrix and the campaign
        // then ran their "top speed" at rest), or short of base speed on the lowest bus.
        for short in ["0.0", "100.0"] {
            let e = err(&replace("omega_r_max_rad_s = 400.0", &format!("omega_r_max_rad_s = {short}")));
            assert_eq!(e.key.as_deref(), Some("certify.omega_r_max_rad_s"), "{e}");
            assert!(e.reason.contains("below the drive's no-load base speed"), "{e}");
        }
        // A brake chopper above where the drive cuts its braking torque (0.925 × 400 V): the
        // cut came first (the 3 300 V template's, found by trying, braked at 50–460 N·m of
        // 2 000).
        let e = err(&replace(
            "brake_chopper = { on_v = 360.0, off_v = 350.0 }",
            "brake_chopper = { on_v = 380.0, off_v = 350.0 }",
        ));
        assert_eq!(e.key.as_deref(), Some("protection.brake_chopper"), "{e}");
        assert!(
            e.reason.contains(
                "on_v = 380, off_v = 350: need 0 < off_v < on_v < 370 V, where the drive starts cutting"
            ),
            "{e}"
        );
        // Reversed interval.
        let e = err(&replace("rr_factor = [1.0, 2.0]", "rr_factor = [2.0, 1.0]"));
        assert_eq!(e.key.as_deref(), Some("certify.rr_factor"), "{e}");
        // A box of another motor (`[1.0, 1e300]` was accepted and printed with 300 digits:
        // found by trying).
        let e = err(&replace("rs_factor = [1.0, 1.5]", "rs_factor = [1.0, 1e300]"));
        assert_eq!(e.key.as_deref(), Some("certify.rs_factor"), "{e}");
        assert!(
            e.reason.contains("is [1, 1e300]; a factor of the motor file's value must lie in [0.1, 10]"),
            "{e}"
        );
        // Configured gain outside the writable range.
        let e = err(&replace("speed_kp_writable = [0.04, 0.1]", "speed_kp_writable = [0.06, 0.1]"));
        assert_eq!(e.key.as_deref(), Some("certify.speed_kp_writable"), "{e}");
        // No dead time (every edge a shoot-through), or more than TIM1's dead-time generator
        // gives: refused at the key. A dead time between ticks rounds up, never down.
        for bad in ["0.0", "-1e-9", "7e-6"] {
            let e = err(&replace("dead_time_s = 5e-7", &format!("dead_time_s = {bad}")));
            assert_eq!(e.key.as_deref(), Some("board.dead_time_s"), "{bad}: {e}");
        }
        let f =
            DriveFile::parse(Path::new("x.toml"), &replace("dead_time_s = 5e-7", "dead_time_s = 4.97e-7"))
                .unwrap();
        assert_eq!(f.board.map(|b| b.dead_time_ticks), Some(85), "84.49 ticks → 85");
        // A bootstrap pre-charge that would hold the low sides on for minutes.
        let e = err(&replace("bootstrap_precharge_s = 2e-3", "bootstrap_precharge_s = 60.0"));
        assert_eq!(e.key.as_deref(), Some("board.bootstrap_precharge_s"), "{e}");
        // A sampling window that leaves the phases less than DUTY_MAX_MIN, a negative one, a
        // NaN: named at the key.
        for bad in ["5.5e-6", "-1e-6", "nan"] {
            let e = err(&replace("sample_window_s = 1.5e-6", &format!("sample_window_s = {bad}")));
            assert_eq!(e.key.as_deref(), Some("board.sample_window_s"), "{bad}: {e}");
        }
        // A rotor-resistance or inductance range reversed, through zero, NaN, or wider than
        // RANGE_RATIO_MAX (an estimate that would start at ×1e15): named at its key, with
        // what it needs.
        for key in ["rotor_resistance_range", "inductance_range"] {
            let line = if key == "inductance_range" {
                "inductance_range = [0.6, 1.0]"
            } else {
                "rotor_resistance_range = [1.0, 2.0]"
            };
            for bad in ["[2.0, 1.0]", "[0.0, 2.0]", "[1.0, nan]", "[1.0, inf]", "[1.0, 1e30]", "[0.05, 1.0]"]
            {
                let e = err(&replace(line, &format!("{key} = {bad}")));
                assert_eq!(e.key.as_deref(), Some(format!("controller.{key}").as_str()), "{bad}: {e}");
                assert!(e.reason.contains("0 < min ≤ max ≤ 10·min"), "{bad}: {e}");
            }
        }
        // Trip level below the current limit.
        let e = err(&replace("i_trip_a = 8.0", "i_trip_a = 3.0"));
        assert_eq!((e.key.as_deref(), e.at), (Some("protection.i_trip_a"), Some(pos(s, "8.0"))), "{e}");
        // A flux reference whose magnetizing current ψ*/L_m the current limit cannot give
        // (found by trying: `design certify` certified 50 Wb on the 4 A drive), and one of
        // zero: named at the flux, not at the protection derived from it (0 named i_trip_a).
        for bad in ["50.0", "1e300", "0.0", "-0.9"] {
            let e = err(&replace("flux_ref_wb = 0.9", &format!("flux_ref_wb = {bad}")));
            assert_eq!(e.key.as_deref(), Some("controller.flux_ref_wb"), "{bad}: {e}");
        }
        let e = err(&replace("flux_ref_wb = 0.9", "flux_ref_wb = 50.0"));
        assert!(e.reason.contains("ψ*/L_m below controller.i_ref_max_a = 4 A"), "{e}");
        // Negative resistance, in the motor table.
        let e = err(&replace("rs_ohm = 16.2", "rs_ohm = -16.2"));
        assert_eq!(e.key.as_deref(), Some("motor.rs_ohm"), "{e}");
        // Unknown key and wrong kind.
        let e = err(&replace("flux_ref_wb = 0.9", "flux_ref_wb = 0.9\nflux_gain = 2"));
        assert!(e.reason.contains("flux_gain") && e.at.is_some(), "{e}");
        let e = err(&replace("kind = \"icad\"", "kind = \"lqr\""));
        assert!(e.reason.contains("lqr") && e.key.as_deref() == Some("controller.current.kind"), "{e}");
        // A PWM rate of zero, a NaN gain.
        let e = err(&replace("frequency_hz = 20000.0", "frequency_hz = 0.0"));
        assert_eq!(e.key.as_deref(), Some("pwm.frequency_hz"), "{e}");
        let e = err(&replace("kp = 0.05", "kp = nan"));
        assert!(
            e.key.as_deref().is_some_and(|k| k.starts_with("controller.speed") || k.starts_with("certify")),
            "{e}"
        );
        // A speed PI's setpoint weight outside [0, 1]; absent, the one-degree PI.
        let pi = |b: &str| {
            replace(
                "speed = { kind = \"saturated_p\", kp = 0.05, tau_max_nm = 2.0 }",
                &format!("speed = {{ kind = \"pi_torque\", kp = 0.05, ki = 0.5, limit = 2.0{b} }}"),
            )
        };
        for b in [", setpoint_weight = 1.5", ", setpoint_weight = -0.1", ", setpoint_weight = nan"] {
            let e = err(&pi(b));
            assert_eq!(e.key.as_deref(), Some("controller.speed.setpoint_weight"), "{b}: {e}");
            assert!(e.reason.contains("within [0, 1]"), "{e}");
        }
        let one = DriveFile::parse(Path::new("pi.toml"), &pi("")).unwrap();
        assert!(matches!(
            one.spec.speed_law,
            controller_core::speed::SpeedLaw::PiTorque { setpoint_weight: 1.0, .. }
        ));
        // A half-given ICAD law.
        let e = err(&replace("current = { kind = \"icad\" }", "current = { kind = \"icad\", kp = 300.0 }"));
        assert_eq!(e.key.as_deref(), Some("controller.current"), "{e}");
        // A timer that cannot make the PWM rate.
        let e = err(&replace("frequency_hz = 20000.0", "frequency_hz = 19999.0"));
        assert_eq!(e.key.as_deref(), Some("pwm.frequency_hz"), "{e}");
        // Found by trying: a 1 Hz PWM was blamed on the current trim without a number (and,
        // issue 49, on a trim the file does not set: the PWM rate is what it sets), a bus
        // the core's f32 cannot hold on `controller.current` as "rejected: Pi(Limits)", a
        // negative speed gain as "rejected: Gain".
        let slow_pwm = replace("frequency_hz = 20000.0", "frequency_hz = 1.0");
        assert!(!slow_pwm.contains("current_trim_bandwidth_rad_s ="));
        let e = err(&slow_pwm);
        assert_eq!(e.key.as_deref(), Some("pwm.frequency_hz"), "{e}");
        assert!(
            e.reason.contains("below 0.1/T_slow = 0.01 rad/s")
                && e.reason.contains("10/1 Hz = 10 s")
                && e.reason.contains("not set"),
            "{e}"
        );
        // A default sample window (dead time + settling) that leaves too little duty at
        // 68 kHz blames the dead time the file sets, not the window it does not (with a slow
        // divider that leaves the slow step's 10 periods of plan delay at that rate).
        let fast = replace("frequency_hz = 20000.0", "frequency_hz = 68000.0")
            .replace("slow_divider = 10", "slow_divider = 40");
        let e = err(&replace("frequency_hz = 20000.0", "frequency_hz = 68000.0"));
        assert_eq!(e.key.as_deref(), Some("pwm.slow_divider"), "{e}");
        assert!(e.reason.contains("≥ 11") && e.reason.contains("10 period(s)"), "{e}");
        let window_line = fast.lines().find(|l| l.starts_with("sample_window_s")).unwrap().to_string();
        let e = err(&fast.replace(&format!("{window_line}\n"), ""));
        assert_eq!(e.key.as_deref(), Some("board.dead_time_s"), "{e}");
        assert!(e.reason.contains("not set") && e.reason.contains("68000 Hz"), "{e}");
        let e = err(&fast);
        assert_eq!(e.key.as_deref(), Some("board.sample_window_s"), "{e}");
        // Set in the file, the trim is the key blamed.
        let e =
            err(&slow_pwm.replace("[controller]\n", "[controller]\ncurrent_trim_bandwidth_rad_s = 20.0\n"));
        assert_eq!(e.key.as_deref(), Some("controller.current_trim_bandwidth_rad_s"), "{e}");
        let e = err(&replace("vdc_max_v = 400.0", "vdc_max_v = 1e300"));
        assert_eq!(e.key.as_deref(), Some("protection.vdc_max_v"), "{e}");
        assert!(e.reason.contains("beyond the controller's f32 range"), "{e}");
        let e = err(&replace("kind = \"saturated_p\", kp = 0.05", "kind = \"saturated_p\", kp = -0.05"));
        assert!(!e.reason.contains("Gain") && !e.reason.contains('('), "{e}");
    }

    /// The derived protection defaults of the shipped drive, and the stall time's condition
    /// (a start at the torque limit leaves the "not moving" band well before it, at the
    /// largest certified inertia).
    #[test]
    fn derived_protection_defaults() {
        let d = DriveFile::shipped().unwrap();
        let p = d.spec.protection;
        // 1.2 · 2 · (400 V/√3) / (0.9 Wb · 1.44/1.42) / 1: 20 % beyond a 2:1 field-weakening
        // range above the no-load base speed on the highest bus.
        assert!((p.overspeed_rad_s - 607.286).abs() < 1e-3, "{}", p.overspeed_rad_s);
        // The stall time (drive::default_stall_time_s): 20 × J·ω_band/τ_max, the band 0.5 %
        // of the overspeed level: 20·0.005·(0.005·607.286)/2 = 0.1518 s.
        assert!((p.stall_time_s - 0.151_82).abs() < 1e-5, "{}", p.stall_time_s);
        assert_eq!(p.current_sum_max_a, 0.4);
        // The sample-counted windows: the open-phase window 5 slow periods, the encoder check
        // 20 (2.5 and 10 ms at the shipped 0.5 ms); a slower slow loop, longer windows.
        assert!(
            (p.open_phase_time_s - 0.0025).abs() < 1e-12 && (p.encoder_check_time_s - 0.01).abs() < 1e-12
        );
        let slow = SHIPPED.replace("slow_divider = 10", "slow_divider = 20");
        assert_ne!(slow, SHIPPED);
        let q = DriveFile::parse(Path::new("d.toml"), &slow).unwrap().spec.protection;
        assert!((q.open_phase_time_s - 0.005).abs() < 1e-12 && (q.encoder_check_time_s - 0.02).abs() < 1e-12);
        // The following window (drive::default_following_time_s): 10 counts of the encoder
        // speed's resolution (2π/4096 over 8 reads of 0.5 ms: 0.3835 rad/s) owed at a tenth
        // of τ_max/J = 2/0.005: 10·0.3835·0.005/(0.1·2) = 0.0959 s — and a lighter rotor, a
        // shorter window, down to the estimate's own 4 ms.
        assert!((p.following_time_s - 0.09587).abs() < 1e-4, "{}", p.following_time_s);
        let light = SHIPPED.replace("j_kgm2 = 0.005", "j_kgm2 = 0.0001");
        assert_ne!(light, SHIPPED);
        let t = DriveFile::parse(Path::new("d.toml"), &light).unwrap().spec.protection.following_time_s;
        assert!((t - 0.004).abs() < 1e-12, "{t}");
        // The current-sum limit: 5 % of the 8 A trip level on the shipped board (20 of its
        // 8.06 mA counts are 0.16 A); on a 100 A front end (48.8 mA counts) 20 counts, 0.98 A.
        let coarse =
            SHIPPED.replace("current_a_per_count = 0.008056640625", "current_a_per_count = 0.048828125");
        assert_ne!(coarse, SHIPPED);
        let p_coarse = DriveFile::parse(Path::new("d.toml"), &coarse).unwrap().spec.protection;
        assert_eq!(p_coarse.current_sum_max_a, 20.0 * 0.048828125);
        // The windowed level: a quarter of the instantaneous one, 0.1 A on the shipped board,
        // 0.24 A on the coarse one.
        assert_eq!(p.current_sum_mean_max_a, 0.25 * 0.4);
        assert_eq!(p_coarse.current_sum_mean_max_a, 0.25 * 20.0 * 0.048828125);
        let j_max = d.spec.motor.j_kgm2() * d.certify.unwrap().j_factor[1];
        let band = controller_core::drive::STALL_SPEED_FRACTION * p.overspeed_rad_s;
        let leave_s = j_max * band / 2.0; // τ_max = 2 N·m
        assert!(leave_s <= 0.1 * p.stall_time_s, "{leave_s}");
        // Encoder jump: 4 counts of 1024 lines + 10 × (1.5·1·(1.42/1.5)·0.9·4 N·m)/0.005 kg·m²
        // × (0.5 ms)² = 6.136e-3 + 2.556e-3 rad; the board's line count is used (a 512-line
        // board doubles the counts' share).
        assert!((p.encoder_jump_rad - 8.692e-3).abs() < 1e-6, "{}", p.encoder_jump_rad);
        let t = SHIPPED.replace("encoder_lines = 1024", "encoder_lines = 512");
        let p512 = DriveFile::parse(Path::new("d.toml"), &t).unwrap().spec.protection.encoder_jump_rad;
        assert!((p512 - 2.0 * 6.136e-3 - 2.556e-3).abs() < 1e-6, "{p512}");
        // I²t: the motor's from [motor] with the 1.15 service factor; the inverter's from
        // [board]: 150 % for 60 s → τ = 60/ln(2.25/1.25) = 102.07 s; overloads stop the motor
        // under control by default, an overspeed turns the bridge off.
        let m = p.motor_thermal.unwrap();
        assert_eq!((m.rated_current_a, m.time_constant_s, m.overload_factor), (0.88, 900.0, 1.15));
        let i = p.inverter_thermal.unwrap();
        assert_eq!((i.rated_current_a, i.overload_factor), (4.0, 1.0));
        assert!((i.time_constant_s - 102.07).abs() < 0.01, "{}", i.time_constant_s);
        use controller_core::drive::{Fault, FaultSet};
        assert_eq!(p.stop_on, FaultSet::EMPTY.with(Fault::MotorOverload).with(Fault::InverterOverload));
        let t = SHIPPED.replace(
            "vdc_max_v = 400.0",
            "vdc_max_v = 400.0\nreaction = { motor_overload = \"off\", overspeed = \"stop\" }",
        );
        let p2 = DriveFile::parse(Path::new("d.toml"), &t).unwrap().spec.protection;
        assert_eq!(p2.stop_on, FaultSet::EMPTY.with(Fault::InverterOverload).with(Fault::Overspeed));
        let e = err(&SHIPPED
            .replace("vdc_max_v = 400.0", "vdc_max_v = 400.0\nreaction = { encoder_loss = \"stop\" }"));
        assert_eq!(e.key.as_deref(), Some("protection.reaction.encoder_loss"), "{e}");
        let e = err(&SHIPPED.replace("thermal_time_constant_s = 900.0", ""));
        assert_eq!(e.key.as_deref(), Some("motor.thermal_time_constant_s"), "{e}");
        let e = err(&SHIPPED.replace("{ factor = 1.5,", "{ factor = 0.9,"));
        assert_eq!(e.key.as_deref(), Some("board.inverter_overload"), "{e}");
        let e = err(&SHIPPED.replace(
            "vdc_max_v = 400.0",
            "vdc_max_v = 400.0\nmotor_thermal = { rated_current_a = -1.0, time_constant_s = 9.0, overload_factor = 1.1 }",
        ));
        assert_eq!(e.key.as_deref(), Some("protection.motor_thermal"), "{e}");
        // Explicit values win; a bad one points at its key.
        let t = SHIPPED.replace("vdc_max_v = 400.0", "vdc_max_v = 400.0\noverspeed_rad_s = 500.0");
        assert_eq!(DriveFile::parse(Path::new("d.toml"), &t).unwrap().spec.protection.overspeed_rad_s, 500.0);
        let e = err(&SHIPPED.replace("vdc_max_v = 400.0", "vdc_max_v = 400.0\nstall_time_s = -1.0"));
        assert_eq!(e.key.as_deref(), Some("protection.stall_time_s"), "{e}");
    }

    /// `[protection]`'s scalar keys are controller-core's declaration
    /// (`Protection::THRESHOLDS`): each one the file sets wins over its derived default, the
    /// others keep theirs; an unknown key names itself at its own line, with the known ones;
    /// a required one missing is named.
    #[test]
    fn protection_keys_are_the_cores_thresholds() {
        use controller_core::drive::Protection;
        let shipped = DriveFile::parse(Path::new("d.toml"), SHIPPED).unwrap().spec.protection;
        for (k, name) in Protection::THRESHOLDS.iter().enumerate() {
            let mut expected = shipped.thresholds();
            // × 1.5, but the bus trip × 1.02: the board's bus channel reads 409.5 V at most.
            let v = expected[k] * if *name == "vdc_max_v" { 1.02 } else { 1.5 };
            expected[k] = v;
            // The stall time's default follows the overspeed level (its "not moving" band).
            if *name == "overspeed_rad_s"
                && let Some(stall) = Protection::THRESHOLDS.iter().position(|n| *n == "stall_time_s")
            {
                expected[stall] *= 1.5;
            }
            let t = if SHIPPED.contains(&format!("\n{name} = ")) {
                SHIPPED.replace(&format!("\n{name} = "), &format!("\n{name} = {v:?}\n# was: "))
            } else {
                SHIPPED.replace("vdc_max_v = 400.0", &format!("vdc_max_v = 400.0\n{name} = {v:?}"))
            };
            match DriveFile::parse(Path::new("d.toml"), &t) {
                // The three required ones are the others' basis (the current sum's default
                // follows i_trip_a): only the one set is compared for them.
                Ok(f) if k < 3 => assert_eq!(f.spec.protection.thresholds()[k], v, "{name}"),
                Ok(f) => assert_eq!(f.spec.protection.thresholds(), expected, "{name}"),
                // Some are judged against the others (i_trip_a × 1.5 is within the current
                // channels' ±16.5 A; a bus minimum × 1.5 = 300 V is still below 400 V): none
                // here is refused.
                Err(e) => panic!("{name} = {v}: {e}"),
            }
        }
        let t = SHIPPED.replace("vdc_max_v = 400.0", "vdc_max_v = 400.0\nstal_time_s = 0.3");
        let e = err(&t);
        assert_eq!(
            (e.key.as_deref(), e.at),
            (Some("protection.stal_time_s"), Some(pos(&t, "stal_time_s"))),
            "{e}"
        );
        assert!(e.to_string().contains("`stall_time_s`"), "{e}");
        let e = err(&SHIPPED.replace("i_trip_a = 8.0", ""));
        assert!(e.to_string().contains("missing field `i_trip_a`"), "{e}");
    }

    /// The board against the rest of the file (issue 49: each was accepted silently): the
    /// error names the board's key and the one it contradicts, at the board's line.
    #[test]
    fn board_ratings_that_contradict_the_drive_are_refused_naming_both_keys() {
        let cases = [
            // 4095 × 0.09 = 368.6 V read, against a 400 V trip.
            (
                "vdc_v_per_count = 0.1 ",
                "vdc_v_per_count = 0.09 ",
                "board.vdc_v_per_count",
                "protection.vdc_max_v",
            ),
            // A rated bus on the overvoltage trip level: the drive trips at its own bus.
            ("vdc_rated_v = 310.0", "vdc_rated_v = 400.0", "board.vdc_rated_v", "protection.vdc_max_v"),
            ("vdc_rated_v = 310.0", "vdc_rated_v = 150.0", "board.vdc_rated_v", "protection.vdc_min_v"),
            // ±2048 × 0.0039 = ±7.99 A read, against an 8 A trip.
            (
                "current_a_per_count = 0.008056640625",
                "current_a_per_count = 0.0039",
                "board.current_a_per_count",
                "protection.i_trip_a",
            ),
            // A comparator at the current limit.
            ("trip_a = 12.0", "trip_a = 4.0", "board.comparator", "controller.i_ref_max_a"),
            // An inverter rated below the motor's 0.88 A.
            (
                "inverter_rated_current_a = 4.0",
                "inverter_rated_current_a = 0.8",
                "board.inverter_rated_current_a",
                "motor.rated_current_a",
            ),
        ];
        for (from, to, key, other) in cases {
            let text = SHIPPED.replace(from, to);
            assert_ne!(text, SHIPPED, "{from}");
            let e = err(&text);
            assert_eq!(e.key.as_deref(), Some(key), "{e}");
            assert!(e.to_string().contains(other), "{e}");
            assert_eq!(e.at.map(|(line, _)| line), Some(pos(&text, to).0), "{e}");
        }
    }

    /// A board clock that is not the core's (the firmware's TIM1 clock and the schedule's) is
    /// refused at its key, naming the core's.
    #[test]
    fn a_board_clock_other_than_the_cores_is_refused() {
        let text = SHIPPED.replace("tim_clock_hz = 170000000", "tim_clock_hz = 150000000");
        assert_ne!(text, SHIPPED);
        let e = err(&text);
        assert_eq!(e.key.as_deref(), Some("board.tim_clock_hz"), "{e}");
        assert!(e.to_string().contains("170 MHz"), "{e}");
        assert_eq!(e.at.map(|(line, _)| line), Some(pos(&text, "tim_clock_hz = 150000000").0), "{e}");
    }

    /// Dead-time compensation takes the board's dead time, and needs a board.
    #[test]
    fn dead_time_compensation_takes_the_boards_dead_time() {
        assert_eq!(DriveFile::shipped().unwrap().spec.dead_time_compensation_s, 0.0);
        let on = SHIPPED.replace(
            "magnetized_fraction = 0.95",
            "magnetized_fraction = 0.95\ndead_time_compensation = true",
        );
        let d = DriveFile::parse(Path::new("d.toml"), &on).unwrap();
        assert_eq!(d.spec.dead_time_compensation_s, d.board.unwrap().table.dead_time_s);
        // What the timer gives: 1.19 µs at 170 MHz is 203 ticks (202.3 rounded up), which the
        // dead-time generator gives in steps of 2 above 127 ticks: 204 ticks, 1.2 µs —
        // compensated, and waited out by the default sampling window; the firmware's ticks
        // are those.
        let slow = on.replace("dead_time_s = 5e-7", "dead_time_s = 1.19e-6");
        let d = DriveFile::parse(Path::new("d.toml"), &slow).unwrap();
        let b = d.board.unwrap();
        assert_eq!(b.dead_time_ticks, 204);
        assert_eq!(d.spec.dead_time_compensation_s, 204.0 / 170e6);
        let default_window = board::BoardTable { sample_window_s: None, ..b.table };
        assert_eq!(default_window.sample_window_s(), 204.0 / 170e6 + board::DEFAULT_SAMPLE_SETTLE_S);
        // Beyond 5 % of the half-period (212 ticks at 20 kHz) as given, not only as asked:
        // 211.7 ticks asked are 212, given as 212 — accepted; 213 asked are given as 214.
        let edge = |s: f64| {
            DriveFile::parse(
                Path::new("d.toml"),
                &on.replace("dead_time_s = 5e-7", &format!("dead_time_s = {s:e}")),
            )
        };
        assert_eq!(edge(212.0 / 170e6).map(|d| d.board.map(|b| b.dead_time_ticks)), Ok(Some(212)));
        assert_eq!(edge(213.0 / 170e6).map_err(|e| e.key), Err(Some("board.dead_time_s".into())));
        let no_board = on.split("[board]").next().unwrap().to_string();
        let e = err(&no_board);
        assert_eq!(e.key.as_deref(), Some("controller.dead_time_compensation"), "{e}");
    }

    #[test]
    fn icad_with_explicit_gains_equals_eq20() {
        let t = SHIPPED.replace(
            "current = { kind = \"icad\" }",
            "current = { kind = \"icad\", kp = 326.5, ki = 326500.0, lag_num = [1.0, 800.0, 160000.0], lag_den = [1.0, 100.0, 42500.0] }",
        );
        let a = DriveFile::parse(Path::new("d.toml"), &t).unwrap();
        assert_eq!(a.spec, DriveFile::shipped().unwrap().spec);
        let e = err(&t.replace("lag_den = [1.0, 100.0, 42500.0]", "lag_den = [1.0, 100.0]"));
        assert!(e.key.as_deref() == Some("controller.current") && e.reason.contains("exactly 3"), "{e}");
    }

    #[test]
    fn relative_references() {
        assert_eq!(relative_to(Path::new("a/b/s.toml"), "../d.toml"), PathBuf::from("a/b/../d.toml"));
        assert_eq!(relative_to(Path::new("s.toml"), "d.toml"), PathBuf::from("d.toml"));
        assert_eq!(relative_to(Path::new("a/s.toml"), "/x/d.toml"), PathBuf::from("/x/d.toml"));
    }

    /// A drive whose `[motor]` saturates runs on its curve (issue 50). Before, the file's
    /// `[motor.saturation]` was read and dropped: the drive ran a linear model on the
    /// unsaturated `lm_h` (1.998 H for a machine whose rated-flux inductance is 1.44 H), its
    /// magnetizing current 28 % short. Now its `L_m` is the curve's chord at
    /// `controller.flux_ref_wb`, the leakage as written, the curve its table; the simulator's
    /// machine is the file's own ([`DriveFile::saturating_motor`]); a curve the drive cannot
    /// run on names `motor.saturation`.
    #[test]
    fn a_saturating_motor_runs_on_its_curve() {
        let (start, end) = (SHIPPED.find("\n[motor]").unwrap(), SHIPPED.find("\nrs_ohm = 16.2").unwrap());
        let twin = "\n[motor]\nform = \"gamma\"\nlm_h = 1.99765926\nl_sigma_h = 0.102551081\n";
        let text = format!("{}{twin}{}", &SHIPPED[..start], &SHIPPED[end..])
            .replacen("ls_h = 1.44\nlr_h = 1.5\nlm_h = 1.42\n", "", 1)
            .replacen(
                "\n[controller]",
                "\n[motor.saturation]\nbeta_per_wb = 0.956813\nexponent = 7.0\n\n[controller]",
                1,
            );
        let d = DriveFile::parse(Path::new("d.toml"), &text).unwrap();
        let (plant, sat) = d.saturating_motor.unwrap();
        assert_eq!(plant.lm_h(), 1.99765926);
        let psi = d.spec.flux_ref_wb;
        let m = &d.spec.motor;
        assert!((m.lm_h() - psi / sat.curve.current_a(psi)).abs() < 1e-12, "{}", m.lm_h());
        // At the drive's 0.9 Wb, a little below the 0.913 Wb at which the file places 1.44 H.
        assert!((1.44..1.5).contains(&m.lm_h()), "{}", m.lm_h());
        assert!(((m.lr_h() - m.lm_h()) - 0.102551081).abs() < 1e-12 && m.ls_h() == m.lm_h());
        let t = d.spec.magnetizing.unwrap();
        assert_eq!(t.chord_ratio(1.0), 1.0);
        assert!(t.chord_ratio(0.5) > 1.2, "{}", t.chord_ratio(0.5));
        // Linear files have none.
        assert!(DriveFile::shipped().unwrap().spec.magnetizing.is_none());
        assert!(DriveFile::shipped().unwrap().saturating_motor.is_none());
        // A curve whose flux jumps past a low knee (8 H between 0.5 and 0.6 A, 1.5 H of chord
        // at the rated 0.6 A): the drive's chord model would not settle on it.
        let steep = text.replace(
            "beta_per_wb = 0.956813\nexponent = 7.0",
            "flux_wb = [0.1, 0.9, 1.0]\ncurrent_a = [0.5, 0.6, 0.7]",
        );
        assert_ne!(steep, text);
        let e = DriveFile::parse(Path::new("d.toml"), &steep).unwrap_err();
        assert_eq!(e.key.as_deref(), Some("motor.saturation"), "{e}");
        assert!(e.reason.contains("twice as steeply"), "{e}");
    }
}
