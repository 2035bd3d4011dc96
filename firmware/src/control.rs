//! The control interrupt's body, free of hardware: raw ADC codes and the encoder counter in,
//! compare values (or "bridge off") out. The interrupt handler in `main.rs` only moves
//! registers into [`Samples`] and the result into TIM1; everything here is tested on the
//! host.
//!
//! ```text
//!  ADC codes ─▶ AdcScaling ─▶ i_abc, V_dc ─┐
//!  TIM4 count ─▶ Encoder (every N-th) ─▶ θ_m, ω_m ─┼─▶ Drive::step ─▶ duties ─▶ PwmScaling ─▶ CCR1..3
//!  TIM1 break flag ─▶ Drive::trip(HardwareBreak) ─┘                    └─ Off ─▶ MOE = 0
//! ```
//!
//! Encoder loss: the drive's own jump check (`controller_core::drive`, `Fault::EncoderLoss`)
//! on the angle the estimator reports — the same code in the simulator.

use controller_core::drive::{Drive, DriveConfig, DriveError, FastOutput, Fault, Measurements, PhaseCommand};
use controller_core::encoder::{EncoderConfig, EncoderError, EncoderState};
use controller_core::frames::Abc;
use controller_core::raw::RawDriveConfig;
use controller_core::scaling::{AdcCode, AdcScaling, PwmScaling, ScalingError};

/// Speed window of the encoder estimator, in slow-loop reads (the simulator's too).
pub const ENCODER_WINDOW: usize = controller_core::encoder::SPEED_WINDOW_READS;

/// Raw conversions of one PWM period.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Samples {
    /// Phase-current ADC codes a, b, c.
    pub i_abc: [u16; 3],
    /// DC-bus ADC code.
    pub vdc: u16,
    /// Quadrature counter (TIM4 CNT).
    pub encoder: u16,
    /// TIM1 break flag: the hardware overcurrent comparator fired.
    pub hardware_break: bool,
}

/// What the interrupt writes to TIM1.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Bridge {
    /// Main output enable off: all six switches off.
    Off,
    /// Compare values CCR1..CCR3, outputs on.
    Compare([u16; 3]),
}

/// Board-level constants: sensing front end, PWM timer, encoder.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoardConfig {
    /// Amperes per ADC count of the phase-current channels.
    pub current_a_per_count: f32,
    /// Code at zero current.
    pub current_offset_counts: u16,
    /// Volts per ADC count of the bus channel.
    pub vdc_v_per_count: f32,
    /// ADC full scale (4095 for 12 bits).
    pub adc_full_scale: u16,
    /// TIM1 auto-reload (compare = this → 100 % duty).
    pub pwm_period_counts: u16,
    /// Encoder lines per revolution.
    pub encoder_lines: u32,
}

/// Why the control loop could not be built.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ControlError {
    /// Drive specification rejected.
    Drive(DriveError),
    /// ADC or PWM scaling rejected.
    Scaling(ScalingError),
    /// Encoder configuration rejected.
    Encoder(EncoderError),
}

/// Control loop state: the drive plus the converter scalings and the encoder estimator.
#[derive(Clone, Debug)]
pub struct ControlLoop {
    board: BoardConfig,
    drive: Drive,
    current: AdcScaling,
    vdc: AdcScaling,
    pwm: PwmScaling,
    encoder_cfg: EncoderConfig<ENCODER_WINDOW>,
    encoder: EncoderState<ENCODER_WINDOW>,
    theta_m_rad: f32,
    omega_m_rad_s: f32,
    divider: u16,
    count: u16,
    last: Option<FastOutput>,
}

impl ControlLoop {
    /// Validate everything once, at start-up: the drive configuration built at compile time
    /// (`config::DRIVE_CONFIG`, checked by [`DriveConfig::from_raw`]) and the board's scalings.
    pub fn new(raw: &RawDriveConfig, board: &BoardConfig) -> Result<Self, ControlError> {
        let cfg = DriveConfig::from_raw(raw).map_err(ControlError::Drive)?;
        Self::with_config(cfg, board)
    }

    /// The shipped configuration without the checks that compare the measured currents with
    /// the drive's references (open phase, loss of control), for tests that step an enabled
    /// drive on samples at rest.
    #[cfg(test)]
    pub(crate) fn at_rest_for_tests() -> Self {
        let mut spec = crate::config::drive_spec().unwrap();
        spec.protection.open_phase_time_s = 1e6;
        spec.protection.saturation_time_s = 1e6;
        Self::with_config(DriveConfig::new(&spec).unwrap(), &crate::config::BOARD).unwrap()
    }

    fn with_config(cfg: DriveConfig, board: &BoardConfig) -> Result<Self, ControlError> {
        let divider = cfg.slow_divider();
        let current =
            AdcScaling::new(board.current_a_per_count, board.current_offset_counts, board.adc_full_scale)
                .map_err(ControlError::Scaling)?;
        let vdc =
            AdcScaling::new(board.vdc_v_per_count, 0, board.adc_full_scale).map_err(ControlError::Scaling)?;
        let pwm = PwmScaling::new(board.pwm_period_counts).map_err(ControlError::Scaling)?;
        let read_period_s = f32::from(divider) * cfg.ts_s();
        let encoder_cfg =
            EncoderConfig::new(board.encoder_lines, read_period_s).map_err(ControlError::Encoder)?;
        Ok(Self {
            board: *board,
            drive: Drive::new(cfg),
            current,
            vdc,
            pwm,
            encoder_cfg,
            encoder: EncoderState::default(),
            theta_m_rad: 0.0,
            omega_m_rad_s: 0.0,
            divider,
            count: 0,
            last: None,
        })
    }

    /// The drive configuration in use.
    pub fn config(&self) -> &DriveConfig {
        self.drive.config()
    }

    /// Start again from configuration `cfg` (a fresh drive, Idle); on error nothing changes.
    pub fn reconfigure(&mut self, cfg: DriveConfig) -> Result<(), ControlError> {
        *self = Self::with_config(cfg, &self.board)?;
        Ok(())
    }

    /// The drive (mode, telemetry, commands).
    pub fn drive(&self) -> &Drive {
        &self.drive
    }

    /// The drive, for commands from the link.
    pub fn drive_mut(&mut self) -> &mut Drive {
        &mut self.drive
    }

    /// The brake chopper's switch after the last step.
    pub fn brake(&self) -> bool {
        self.last.is_some_and(|o| o.brake)
    }

    /// Output of the last step (telemetry).
    pub fn last_output(&self) -> Option<FastOutput> {
        self.last
    }

    /// One PWM period: the control interrupt.
    pub fn step(&mut self, s: &Samples) -> Bridge {
        if s.hardware_break {
            self.drive.trip(Fault::HardwareBreak);
        }
        if self.count == 0 {
            self.read_encoder(s.encoder);
        }
        self.count = if self.count + 1 >= self.divider { 0 } else { self.count + 1 };
        let [a, b, c] = s.i_abc;
        let m = Measurements {
            i_abc_a: Abc {
                a: self.current.to_f32(AdcCode(a)),
                b: self.current.to_f32(AdcCode(b)),
                c: self.current.to_f32(AdcCode(c)),
            },
            vdc_v: self.vdc.to_f32(AdcCode(s.vdc)),
            omega_m_rad_s: self.omega_m_rad_s,
            theta_m_rad: self.theta_m_rad,
        };
        let out = self.drive.step(&m);
        self.last = Some(out);
        match out.phases {
            PhaseCommand::Off => Bridge::Off,
            PhaseCommand::Duty(d) => {
                Bridge::Compare([self.pwm.compare(d.a), self.pwm.compare(d.b), self.pwm.compare(d.c)])
            }
        }
    }

    fn read_encoder(&mut self, raw: u16) {
        let r = self.encoder_cfg.update(&mut self.encoder, raw);
        self.theta_m_rad = r.theta_m_rad;
        self.omega_m_rad_s = r.omega_m_rad_s;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::{DRIVE_CONFIG, drive_spec};
    use controller_core::drive::{Mode, Reference};
    use controller_core::link::{self, Command, LinkStats, NackReason, Reply};

    pub(crate) fn board() -> BoardConfig {
        BoardConfig {
            current_a_per_count: 16.5 / 2048.0,
            current_offset_counts: 2048,
            vdc_v_per_count: 0.1,
            adc_full_scale: 4095,
            pwm_period_counts: 4249,
            encoder_lines: 1024,
        }
    }

    fn at_rest(enc: u16) -> Samples {
        Samples { i_abc: [2048; 3], vdc: 3100, encoder: enc, hardware_break: false }
    }

    #[test]
    fn adc_codes_to_amperes_and_duty_to_compare() {
        let mut c = ControlLoop::new(&DRIVE_CONFIG, &board()).unwrap();
        // Idle: bridge off whatever the inputs.
        assert_eq!(c.step(&at_rest(0)), Bridge::Off);
        c.drive_mut().enable().unwrap();
        // Zero current at the offset code, 310 V: magnetizing starts. Min–max SVPWM centres
        // the three compare values on half the period.
        match c.step(&at_rest(0)) {
            Bridge::Compare(ccr) => {
                let (max, min) = (ccr.iter().max().unwrap(), ccr.iter().min().unwrap());
                assert!(*max <= 4249, "{ccr:?}");
                assert!(
                    ((u32::from(*max) + u32::from(*min)) as f64 / 2.0 - 4249.0 / 2.0).abs() <= 1.0,
                    "{ccr:?}"
                );
                assert!(max > min, "a voltage is applied: {ccr:?}");
            }
            Bridge::Off => panic!("bridge off while magnetizing"),
        }
        // 2048 + 1241 counts = +10 A on phase a: above i_trip (8 A) → Overcurrent, off.
        let s = Samples { i_abc: [2048 + 1241, 2048 - 620, 2048 - 621], ..at_rest(0) };
        assert_eq!(c.step(&s), Bridge::Off);
        assert_eq!(c.drive().mode(), Mode::Fault(Fault::Overcurrent));
    }

    #[test]
    fn hardware_break_latches_until_cleared_by_command() {
        let mut c = ControlLoop::new(&DRIVE_CONFIG, &board()).unwrap();
        c.drive_mut().enable().unwrap();
        assert!(matches!(c.step(&at_rest(0)), Bridge::Compare(_)));
        let brk = Samples { hardware_break: true, ..at_rest(0) };
        assert_eq!(c.step(&brk), Bridge::Off);
        // The break line released: still latched.
        for _ in 0..100 {
            assert_eq!(c.step(&at_rest(0)), Bridge::Off);
        }
        assert_eq!(c.drive().mode(), Mode::Fault(Fault::HardwareBreak));
        // Enable is refused while faulted; ClearFault then Enable works.
        let stats = LinkStats::default();
        assert_eq!(link::execute(c.drive_mut(), &Command::Enable, &stats), Reply::Nack(NackReason::Faulted));
        assert_eq!(link::execute(c.drive_mut(), &Command::ClearFault, &stats), Reply::Ack);
        assert_eq!(link::execute(c.drive_mut(), &Command::Enable, &stats), Reply::Ack);
        assert!(matches!(c.step(&at_rest(0)), Bridge::Compare(_)));
    }

    #[test]
    fn encoder_jump_is_encoder_loss_and_wrap_is_not() {
        let mut c = ControlLoop::at_rest_for_tests();
        c.drive_mut().enable().unwrap();
        c.drive_mut().set_reference(Reference::Speed(0.0)).unwrap();
        let div = u32::from(drive_spec().unwrap().slow_divider);
        // Counter running backwards through the 16-bit wrap, speeding up by one count per read
        // (6 100 rad/s², within the jump check's allowance) to 40 counts per read
        // (≈ 123 rad/s, below the overspeed level): fine.
        let mut enc = 600u16;
        for k in 0..(60 * div) {
            if k % div == 0 {
                enc = enc.wrapping_sub((k / div).min(40) as u16);
            }
            assert!(matches!(c.step(&at_rest(enc)), Bridge::Compare(_)), "step {k}");
        }
        assert!(enc > 60_000, "wrapped: {enc}");
        // A jump of 5000 counts between two reads.
        for _ in 0..div {
            let _ = c.step(&at_rest(enc.wrapping_add(5000)));
        }
        assert_eq!(c.drive().mode(), Mode::Fault(Fault::EncoderLoss));
    }

    #[test]
    fn invalid_board_constants_are_rejected_at_construction() {
        let spec = DRIVE_CONFIG;
        let bad = BoardConfig { pwm_period_counts: 0, ..board() };
        assert_eq!(ControlLoop::new(&spec, &bad).unwrap_err(), ControlError::Scaling(ScalingError::Period));
        let bad = BoardConfig { current_offset_counts: 5000, ..board() };
        assert_eq!(ControlLoop::new(&spec, &bad).unwrap_err(), ControlError::Scaling(ScalingError::Offset));
        let bad = BoardConfig { encoder_lines: 0, ..board() };
        assert_eq!(ControlLoop::new(&spec, &bad).unwrap_err(), ControlError::Encoder(EncoderError::Lines));
    }
}
