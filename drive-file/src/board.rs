//! `[board]`: the power board's sensing scale factors, the PWM timer and the encoder — what
//! the firmware needs beyond the drive. The pin map stays in the firmware's `main.rs`.

use crate::source::{FileError, Source};
use controller_core::drive::DriveSpec;
use controller_core::scaling::{dead_time_dtg, dead_time_dtg_ticks};
use serde::Deserialize;

/// `[board]` as written.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct BoardTable {
    /// Clock of the PWM timer, Hz.
    pub tim_clock_hz: u32,
    /// Dead time between complementary switches, s (the timer gives it rounded up to its
    /// ticks and its dead-time generator's steps: [`BoardTable::realised_dead_time_s`]).
    pub dead_time_s: f64,
    /// ADC full-scale code (4095 for 12 bits).
    pub adc_full_scale: u16,
    /// Amperes per ADC count of the phase-current channels.
    pub current_a_per_count: f64,
    /// Current-channel code at zero current (nominal: the firmware measures each channel's
    /// at start-up).
    pub current_offset_counts: u16,
    /// Offset calibration: the largest departure of a channel's measured zero from
    /// `current_offset_counts`, counts (default [`DEFAULT_OFFSET_ERROR_FRACTION`] of the ADC
    /// full scale).
    pub current_offset_max_error_counts: Option<f64>,
    /// Offset calibration: the largest RMS noise of a channel with the bridge off, counts
    /// (default [`DEFAULT_NOISE_MAX_COUNTS`]).
    pub current_noise_max_counts: Option<f64>,
    /// Volts per ADC count of the bus channel.
    pub vdc_v_per_count: f64,
    /// The bus the drive is built for, V (optional): what every command runs on without
    /// `--vdc` (`hil-sim campaign`, `faults`, `envelope`; the population). Strictly between
    /// `protection.vdc_min_v` and `vdc_max_v`.
    pub vdc_rated_v: Option<f64>,
    /// Encoder lines per revolution.
    pub encoder_lines: u32,
    /// Link watchdog: no valid frame for this long while the bridge is on → a controlled
    /// stop, s (optional: without it the firmware runs on without its host).
    pub link_timeout_s: Option<f64>,
    /// The inverter's rated continuous RMS phase current, A (optional: with
    /// `inverter_overload`, the default inverter I²t limit, `drive::default_inverter_thermal`).
    pub inverter_rated_current_a: Option<f64>,
    /// The inverter's overload rating: `{ factor, time_s }`, e.g. 150 % for 60 s.
    pub inverter_overload: Option<OverloadTable>,
    /// The power board's hardware overcurrent comparator on the leg currents (BKIN):
    /// `{ trip_a, filter_s }` — what the simulator models (`hil_sim::bridge_fault`); the
    /// firmware only sees its break.
    pub comparator: Option<ComparatorTable>,
    /// How long the firmware holds all three low sides on before the bridge's first period
    /// after it was off, charging the high-side gate drivers' bootstrap capacitors, s
    /// (default [`DEFAULT_BOOTSTRAP_PRECHARGE_S`]; 0: none, for isolated gate supplies).
    pub bootstrap_precharge_s: Option<f64>,
    /// The low-side conduction a phase-current sample needs on either side of the top of the
    /// count, s: the dead time, then the shunt amplifier's settling and the ADC's sampling
    /// (default `dead_time_s` + [`DEFAULT_SAMPLE_SETTLE_S`]). The modulator keeps every duty
    /// short enough to leave it (`controller_core::drive::DriveSpec::sample_window_s`).
    pub sample_window_s: Option<f64>,
}

/// `[board] comparator = { trip_a = 12.0, filter_s = 1e-6 }`.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ComparatorTable {
    /// Trip level of the filtered |leg current|, A.
    pub trip_a: f64,
    /// Filter time constant (RC and comparator delay), s.
    pub filter_s: f64,
}

/// `[board] inverter_overload = { factor = 1.5, time_s = 60.0 }`: `factor` × the rated
/// current for `time_s` from cold.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct OverloadTable {
    /// Overload current over the rated one (> 1).
    pub factor: f64,
    /// How long it may flow from cold, s.
    pub time_s: f64,
}

/// Default offset tolerance as a fraction of the ADC full scale: 5 % (205 counts of 4095) —
/// a shunt amplifier's zero drifts by a few counts, a broken one (stuck at a rail, without
/// its reference) by hundreds.
pub const DEFAULT_OFFSET_ERROR_FRACTION: f64 = 0.05;
/// Default noise limit, counts RMS: a healthy 12-bit shunt channel shows one to three counts
/// with the bridge off; eight is a floating input or switching noise coupled in.
pub const DEFAULT_NOISE_MAX_COUNTS: f64 = 8.0;

/// Default bootstrap pre-charge, s: five time constants of a 1 µF bootstrap capacitor
/// charged through 400 Ω — a placeholder for the gate driver's datasheet values.
pub const DEFAULT_BOOTSTRAP_PRECHARGE_S: f64 = 2e-3;

/// The shunt amplifier's settling after the low side turns on and the ADC's sampling of
/// the three phases, s, added to the dead time for [`BoardTable::sample_window_s`]'s
/// default: 1 µs, a placeholder for the power board's measurement (an amplifier settling to
/// 12 bits in ≈ 0.5 µs, three conversions' sampling phases of 6.5 ADC cycles each).
pub const DEFAULT_SAMPLE_SETTLE_S: f64 = 1e-6;

/// The longest bootstrap pre-charge accepted, s.
pub const BOOTSTRAP_PRECHARGE_MAX_S: f64 = 0.1;

/// The encoder's input filter may last at most this fraction of the shortest interval
/// between two quadrature edges at the overspeed level.
pub const ENCODER_FILTER_FRACTION: f64 = 0.15;

/// The STM32 timers' sixteen input-filter settings (TIMx_CCMRx ICxF, with CKD = 0 so that
/// f_DTS = f_CK_INT): (f_CK_INT divider, samples N) by code. An edge passes once N samples
/// at f_CK_INT/divider agree.
pub const TIMER_INPUT_FILTERS: [(u32, u32); 16] = [
    (1, 1),
    (1, 2),
    (1, 4),
    (1, 8),
    (2, 6),
    (2, 8),
    (4, 6),
    (4, 8),
    (8, 6),
    (8, 8),
    (16, 5),
    (16, 6),
    (16, 8),
    (32, 5),
    (32, 6),
    (32, 8),
];

/// The encoder timer's input filter: the longest of [`TIMER_INPUT_FILTERS`] that lasts at most
/// [`ENCODER_FILTER_FRACTION`] of the shortest interval between two quadrature edges at
/// `overspeed_rad_s` (`1/(4·lines·ω/2π)`): it rejects the glitches shorter than it (ringing
/// of a long encoder cable as the bridge switches) and delays a real edge by it. (code, its
/// duration s). The timer's clock is `tim_clock_hz` (TIM4 on APB1 at the same 170 MHz as
/// TIM1 on the G474).
pub fn encoder_filter(tim_clock_hz: u32, encoder_lines: u32, overspeed_rad_s: f64) -> (u8, f64) {
    let edge_s = std::f64::consts::TAU / (4.0 * f64::from(encoder_lines) * overspeed_rad_s);
    let duration = |(div, n): (u32, u32)| f64::from(div * n) / f64::from(tim_clock_hz);
    TIMER_INPUT_FILTERS
        .iter()
        .enumerate()
        .filter(|&(_, &f)| duration(f) <= ENCODER_FILTER_FRACTION * edge_s)
        .max_by(|a, b| duration(*a.1).total_cmp(&duration(*b.1)))
        .map_or((0, 0.0), |(code, &f)| (code as u8, duration(f)))
}

/// Validated board data, with the timer values derived from the drive's PWM frequency.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Board {
    /// `[board]` as written (validated).
    pub table: BoardTable,
    /// Centre-aligned PWM (the counter up to ARR and down, a period of 2·ARR ticks):
    /// ARR = f_tim/(2·f_pwm).
    pub pwm_period_counts: u16,
    /// Dead time in timer ticks: what the dead-time generator gives
    /// ([`BoardTable::realised_dead_time_s`]).
    pub dead_time_ticks: u16,
    /// Offset calibration limits (defaults applied), counts: largest zero error, largest
    /// RMS noise.
    pub calibration_limits_counts: (f64, f64),
    /// The bootstrap pre-charge in PWM periods (default applied).
    pub bootstrap_precharge_periods: u16,
}

impl BoardTable {
    /// [`BoardTable::sample_window_s`] or its default (the dead time the timer gives, then the
    /// settling).
    pub fn sample_window_s(&self) -> f64 {
        self.sample_window_s.unwrap_or(self.realised_dead_time_s() + DEFAULT_SAMPLE_SETTLE_S)
    }

    /// The dead time in whole timer ticks, never fewer than asked (a part-per-million of a
    /// tick forgiven: 500 ns at 170 MHz is 85 ticks, not 86 for a rounding error), and the
    /// ticks the dead-time generator gives for it (`controller_core::scaling::dead_time_dtg`:
    /// above 127 ticks its steps are 2, 8 and 16 ticks). `None` when it cannot (validated
    /// in [`BoardTable::validate`]).
    fn dead_time_ticks(&self) -> Option<(f64, u16)> {
        let ticks = (self.dead_time_s * f64::from(self.tim_clock_hz) - 1e-6).ceil();
        if !(ticks >= 0.0 && ticks <= f64::from(u16::MAX)) {
            return None;
        }
        let code = dead_time_dtg(ticks as u16)?;
        Some((ticks, dead_time_dtg_ticks(code)))
    }

    /// The dead time the bridge gets, s: `dead_time_s` rounded up to the timer's ticks and to
    /// the dead-time generator's steps — what the modulator compensates and the sampling
    /// window waits out (1.19 µs at 170 MHz is 203 ticks, which the generator gives as 204:
    /// 1.2 µs). `dead_time_s` itself when the board cannot give it (an error of
    /// [`BoardTable::validate`]).
    pub fn realised_dead_time_s(&self) -> f64 {
        match self.dead_time_ticks() {
            Some((_, ticks)) if self.tim_clock_hz > 0 => f64::from(ticks) / f64::from(self.tim_clock_hz),
            _ => self.dead_time_s,
        }
    }

    /// The inverter's rating (the drive's I²t default is built from it before the rest of
    /// the board is checked).
    pub fn validate_overload(&self, src: &Source<'_>) -> Result<(), FileError> {
        if let Some(i) = self.inverter_rated_current_a {
            src.check(i.is_finite() && i > 0.0, "board.inverter_rated_current_a", "must be finite and > 0")?;
        }
        if let Some(o) = self.inverter_overload {
            src.check(
                o.factor.is_finite()
                    && o.factor > 1.0
                    && o.factor <= 10.0
                    && o.time_s.is_finite()
                    && o.time_s > 0.0,
                "board.inverter_overload",
                "needs 1 < factor ≤ 10 and time_s > 0",
            )?;
        }
        src.check(
            self.inverter_rated_current_a.is_some() == self.inverter_overload.is_some(),
            "board.inverter_overload",
            "give both inverter_rated_current_a and inverter_overload, or neither",
        )
    }

    /// The board's ratings against the rest of the file (each accepted silently until issue
    /// 49): a level the drive trips at must be one its channel can read, the comparator must
    /// leave the current limit's torque, and the inverter must carry the motor's rated
    /// current. The error names both keys.
    fn validate_against_drive(&self, src: &Source<'_>, spec: &DriveSpec) -> Result<(), FileError> {
        let p = &spec.protection;
        let full_scale = f64::from(self.adc_full_scale);
        let vdc_read_v = full_scale * self.vdc_v_per_count;
        src.check(
            vdc_read_v > p.vdc_max_v,
            "board.vdc_v_per_count",
            &format!(
                "the bus channel reads at most {vdc_read_v} V (adc_full_scale × vdc_v_per_count), not above \
                 protection.vdc_max_v = {} V: the overvoltage trip could never see its level",
                p.vdc_max_v
            ),
        )?;
        if let Some(v) = self.vdc_rated_v {
            src.check(
                v.is_finite() && v > p.vdc_min_v && v < p.vdc_max_v,
                "board.vdc_rated_v",
                &format!(
                    "{v} V must lie strictly between protection.vdc_min_v = {} V and protection.vdc_max_v = {} V: \
                     on or beyond a trip level the drive trips at its own rated bus",
                    p.vdc_min_v, p.vdc_max_v
                ),
            )?;
        }
        let offset = f64::from(self.current_offset_counts);
        let current_read_a = offset.min(full_scale - offset) * self.current_a_per_count;
        src.check(
            current_read_a > p.i_trip_a,
            "board.current_a_per_count",
            &format!(
                "the current channels read ±{current_read_a} A (the offset's distance to the ADC's ends × \
                 current_a_per_count), not above protection.i_trip_a = {} A: the trip could never see its level",
                p.i_trip_a
            ),
        )?;
        if let Some(c) = self.comparator {
            src.check(
                c.trip_a > spec.i_ref_max_a,
                "board.comparator",
                &format!(
                    "trip_a = {} A is not above controller.i_ref_max_a = {} A: the hardware comparator would trip \
                     on the drive's own current limit",
                    c.trip_a, spec.i_ref_max_a
                ),
            )?;
        }
        if let (Some(inverter), Some(motor)) = (self.inverter_rated_current_a, p.motor_thermal) {
            src.check(
                inverter >= motor.rated_current_a,
                "board.inverter_rated_current_a",
                &format!(
                    "{inverter} A is below motor.rated_current_a = {} A: the inverter's I²t would trip at the \
                     motor's continuous duty (a smaller motor, or a larger inverter)",
                    motor.rated_current_a
                ),
            )?;
        }
        Ok(())
    }

    /// Validate against the drive; errors point at the value.
    pub fn validate(&self, src: &Source<'_>, spec: &DriveSpec) -> Result<Board, FileError> {
        // The firmware clocks the core and TIM1 (on APB2, undivided) at one frequency, and
        // the slow step's schedule — the plan's delay, the highest PWM rate — is timed on the
        // core's (`controller_core::drive::plan_delay_periods`): a board file at another clock
        // would build a firmware whose timer and schedule disagree with the file.
        let core_hz = controller_core::drive::CORE_CLOCK_HZ;
        src.check(
            f64::from(self.tim_clock_hz) == core_hz,
            "board.tim_clock_hz",
            &format!(
                "must be the core's clock, {:.0} MHz (controller_core::drive::CORE_CLOCK_HZ): the firmware \
                 runs TIM1 on it, and the slow step's schedule is timed on it",
                core_hz / 1e6
            ),
        )?;
        let f_tim = f64::from(self.tim_clock_hz);
        // Centre-aligned: the counter runs 0 → ARR → 0, a period of 2·ARR ticks (not
        // 2·(ARR + 1): with ARR = f_tim/(2·f) − 1 the PWM ran at 20 004.7 Hz, issue 19).
        let arr = f_tim / (2.0 * spec.pwm_frequency_hz);
        src.check(
            (arr - arr.round()).abs() < 1e-9 && (100.0..=65_535.0).contains(&arr),
            "pwm.frequency_hz",
            &format!(
                "board.tim_clock_hz/(2·f_pwm) = {arr} must be a whole number of timer ticks in 100…65535"
            ),
        )?;
        // (Not finite, negative or beyond the generator's 1 008 ticks: `None` already.)
        let ticks = self
            .dead_time_ticks()
            .filter(|&(asked, given)| asked >= 1.0 && f64::from(given) <= 0.05 * (arr + 1.0));
        let Some((_, ticks)) = ticks else {
            return Err(src.error(
                "board.dead_time_s",
                "must be > 0 (a leg without dead time shoots through at every edge), at most 1008 timer \
                 ticks and 5 % of the PWM half-period",
            ));
        };
        for (key, x) in
            [("current_a_per_count", self.current_a_per_count), ("vdc_v_per_count", self.vdc_v_per_count)]
        {
            src.check(x.is_finite() && x > 0.0, &format!("board.{key}"), "must be finite and > 0")?;
        }
        src.check(self.adc_full_scale > 0, "board.adc_full_scale", "must be > 0")?;
        src.check(
            self.current_offset_counts <= self.adc_full_scale,
            "board.current_offset_counts",
            "must lie within the ADC range",
        )?;
        src.check(self.encoder_lines > 0, "board.encoder_lines", "must be ≥ 1")?;
        let offset_max = self
            .current_offset_max_error_counts
            .unwrap_or(DEFAULT_OFFSET_ERROR_FRACTION * f64::from(self.adc_full_scale));
        let noise_max = self.current_noise_max_counts.unwrap_or(DEFAULT_NOISE_MAX_COUNTS);
        for (key, x) in
            [("current_offset_max_error_counts", offset_max), ("current_noise_max_counts", noise_max)]
        {
            src.check(x.is_finite() && x > 0.0, &format!("board.{key}"), "must be finite and > 0")?;
        }
        self.validate_overload(src)?;
        if let Some(c) = self.comparator {
            src.check(
                c.trip_a.is_finite()
                    && c.trip_a > 0.0
                    && c.filter_s.is_finite()
                    && c.filter_s > 0.0
                    && c.filter_s * spec.pwm_frequency_hz <= 0.1,
                "board.comparator",
                "needs trip_a > 0 and 0 < filter_s ≤ a tenth of the PWM period",
            )?;
        }
        if let Some(t) = self.link_timeout_s {
            src.check(
                t.is_finite() && (0.02..=3600.0).contains(&t),
                "board.link_timeout_s",
                "must lie in [0.02, 3600] s (the link task wakes every 10 ms)",
            )?;
        }
        self.validate_against_drive(src, spec)?;
        let precharge = self.bootstrap_precharge_s.unwrap_or(DEFAULT_BOOTSTRAP_PRECHARGE_S);
        src.check(
            precharge.is_finite() && (0.0..=BOOTSTRAP_PRECHARGE_MAX_S).contains(&precharge),
            "board.bootstrap_precharge_s",
            &format!("must lie in [0, {BOOTSTRAP_PRECHARGE_MAX_S}] s"),
        )?;
        Ok(Board {
            table: *self,
            pwm_period_counts: arr.round() as u16,
            dead_time_ticks: ticks,
            calibration_limits_counts: (offset_max, noise_max),
            // Saturates at 65 535 periods (0.1 s only above a 655 kHz PWM).
            bootstrap_precharge_periods: (precharge * spec.pwm_frequency_hz).round().min(f64::from(u16::MAX))
                as u16,
        })
    }
}
