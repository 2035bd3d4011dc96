//! The control interrupt's body, free of hardware: raw ADC codes and the encoder counter in,
//! compare values (or "bridge off") out. The interrupt handler in `main.rs` only moves
//! registers into [`Samples`] and the result into TIM1; everything here is tested on the
//! host.
//!
//! ```text
//!  ADC codes ─▶ AdcScaling ─▶ i_abc, V_dc ─┐
//!  TIM4 count ─▶ Encoder (every N-th) ─▶ θ_m, ω_m ─┼─▶ FastSide::step ─▶ duties ─▶ PwmScaling ─▶ CCR1..3
//!  TIM1 break flag ─▶ FastSide::trip(HardwareBreak) ─┘   │  └─ Off ─▶ MOE = 0
//!                     tick: the slow side handed over ─▶ SlowCell ─▶ the slow context (run_slow)
//!                     a plan's delay later: its plan adopted ◀─┘
//! ```
//!
//! **Two contexts** (issue 54): the loop owns the drive's fast side; its slow side lives in a
//! [`SlowCell`] of its own ([`Cells`], beside the capture's [`Scope`]), lent to the slow
//! context from the slow step's tick until its job — and the link's work that needs the slow
//! side: the drive's commands, the watchdog's stop, the snapshot — is done ([`run_slow`],
//! pended by [`Pend`]); a command's part on the fast side is an order taken with the plan
//! (`controller_core::drive::DriveMut::slow_only`). [`ControlLoop::drive_mut`] commands both
//! halves at once from the fast context (the tests', the calibration's disable), in a period
//! with the slow side back.
//!
//! **Offset calibration** (first thing after start-up; a new configuration keeps its result):
//! [`CALIBRATION_SAMPLES`] periods with the bridge held off, the three current channels'
//! mean codes become their zeros (`controller_core::calibration`); a channel too far from
//! its nominal zero or too noisy latches `Fault::CurrentSensor` and the drive cannot be
//! enabled until the board is reset ([`ControlLoop::calibration`] says which channel and
//! why). Until it is done, the bridge stays off whatever the link asks.
//!
//! **Commissioning** (feature `commissioning`; `controller_core::commission`, issue 20):
//! started from the link while
//! the drive is Idle and calibrated (`ControlLoop::start_commissioning`), the sequence takes
//! the drive's place in the interrupt until it finishes or refuses; the drive still steps
//! (Idle: its brake chopper and its hardware-break latch), and a latched fault, a `Stop` or a
//! `Disable` aborts the sequence — the bridge off for good.
//!
//! **Capture** (`controller_core::capture`): after every drive step, and in the bootstrap
//! pre-charge's periods with the drive's last telemetry and the duties it applies (0: the
//! low sides on), so that the record's samples stay evenly spaced. During commissioning
//! it records the drive, which is then Idle, not the sequence.
//!
//! Encoder loss: the drive's own jump check (`controller_core::drive`, `Fault::EncoderLoss`)
//! on the angle the estimator reports — the same code in the simulator.

use crate::boundary::Handoff;
use crate::scope::Scope;
use controller_core::calibration::{
    CalibrationConfig, CalibrationConfigError, CalibrationError, OffsetCalibration, Offsets,
};
use controller_core::capture::FastPeriod;
#[cfg(feature = "commissioning")]
use controller_core::commission::{CommissionConfig, CommissionOutput, Commissioning, Record, Stage};
use controller_core::drive::RawDriveConfig;
use controller_core::drive::{
    Drive, DriveConfig, DriveError, DriveMut, DriveRef, FastOutput, FastSide, FastSignals, Fault,
    Measurements, Mode, PhaseCommand, SlowContext, SlowSide, SlowSignals, Telemetry,
};
use controller_core::encoder::{EncoderConfig, EncoderError, EncoderState};
use controller_core::frames::Abc;
use controller_core::link::BoardReadings;
use controller_core::scaling::{AdcCode, AdcScaling, PwmScaling, ScalingError};
use core::mem::MaybeUninit;
use core::sync::atomic::{AtomicBool, Ordering};

/// Samples of the offset calibration (51 ms at 20 kHz; issue 19: at least 1 024).
pub const CALIBRATION_SAMPLES: u32 = controller_core::calibration::MIN_SAMPLES;

/// Speed window of the encoder estimator, in slow-loop reads (the simulator's too).
pub const ENCODER_WINDOW: usize = controller_core::encoder::SPEED_WINDOW_READS;

pub use crate::scope::CAPTURE_DEPTH;

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
    /// Offset calibration: the largest departure of a channel's zero from
    /// `current_offset_counts`, counts …
    pub current_offset_max_error_counts: f32,
    /// … and the largest RMS noise of a channel with the bridge off, counts.
    pub current_noise_max_counts: f32,
    /// PWM periods with all low sides on before the bridge's first period after it was off
    /// (the bootstrap pre-charge, `[board] bootstrap_precharge_s`; 0: none).
    pub bootstrap_precharge_periods: u16,
}

/// Why the control loop could not be built.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ControlError {
    /// Drive specification rejected.
    Drive(DriveError),
    /// A new configuration while the bridge is the drive's (Magnetizing or Running).
    BridgeActive,
    /// A new configuration while the drive's slow step is in flight (a command waits for its
    /// plan's adoption: [`ControlLoop::slow_busy`]).
    SlowBusy,
    /// ADC or PWM scaling rejected.
    Scaling(ScalingError),
    /// Encoder configuration rejected.
    Encoder(EncoderError),
    /// Offset-calibration limits rejected.
    Calibration(CalibrationConfigError),
    /// The timer's ARR read back at start is not the board's period: the PWM would not run
    /// at the rate the drive's constants were discretised for.
    PwmPeriod {
        /// ARR read from TIM1.
        read: u16,
        /// `BoardConfig::pwm_period_counts`.
        expected: u16,
    },
    /// TIM1's update event, read back at start, is not once per period at the top of the
    /// count (where the currents are sampled): the duties would not take effect one period
    /// after their sample, the delay the simulator and the certificate analyse.
    UpdateTiming {
        /// RCR read from TIM1.
        rcr: u16,
        /// The counter's direction just after the first update event (`true`: counting
        /// down, i.e. the event was at the top); `None`: no update event came.
        down_after_update: Option<bool>,
    },
}

/// The control interrupt's timing (issue 19): the longest period's work in CPU cycles, from
/// the update event that started the period (the sampling instant) to the end of the
/// handler — the time the compare values must be written in — and the periods whose work
/// took a whole PWM period or more: their compare values missed the update they were for.
/// Two such periods running are [`Fault::Overrun`] (issue 54: overruns were only counted).
/// Atomics: the interrupt writes, the link task reads.
#[derive(Debug, Default)]
pub struct LoopTimer {
    max: core::sync::atomic::AtomicU32,
    overruns: core::sync::atomic::AtomicU32,
    /// The last period overran.
    overran: core::sync::atomic::AtomicBool,
}

impl LoopTimer {
    /// Nothing recorded.
    pub const fn new() -> Self {
        Self {
            max: core::sync::atomic::AtomicU32::new(0),
            overruns: core::sync::atomic::AtomicU32::new(0),
            overran: core::sync::atomic::AtomicBool::new(false),
        }
    }

    /// One period's work took `cycles` from its update event; a PWM period is
    /// `period_cycles`. `true`: this period and the one before it overran — the drive must
    /// stop ([`crate::output::Outputs::overrun`]).
    pub fn record(&self, cycles: u32, period_cycles: u32) -> bool {
        use core::sync::atomic::Ordering::Relaxed;
        self.max.fetch_max(cycles, Relaxed);
        let overran = cycles >= period_cycles;
        if overran {
            self.overruns.fetch_add(1, Relaxed);
        }
        // Only the interrupt writes it: a load and a store, no read-modify-write needed.
        let twice = overran && self.overran.load(Relaxed);
        self.overran.store(overran, Relaxed);
        twice
    }

    /// What the link's `Status` reports.
    pub fn read(&self) -> controller_core::link::LoopTiming {
        use core::sync::atomic::Ordering::Relaxed;
        controller_core::link::LoopTiming {
            cycles_max: self.max.load(Relaxed),
            overruns: self.overruns.load(Relaxed),
            // The stack is the task's to measure (`stack::used_bytes`).
            stack_bytes: 0,
        }
    }
}

/// CPU cycles of one PWM period: TIM1 runs on the CPU clock (the board's `tim_clock_hz`),
/// centre-aligned, 2·ARR ticks a period.
pub fn period_cycles(board: &BoardConfig) -> u32 {
    2 * u32::from(board.pwm_period_counts)
}

/// The ticks since the period's update event (the top of the centre-aligned count, where
/// the currents were sampled), from TIM1's counter `cnt` and direction read at the control
/// interrupt's entry: counting down, `ARR − CNT`; up again (past the bottom), `ARR + CNT`.
/// TIM1 runs on the CPU clock, so the ticks are cycles: added to the handler's own DWT count
/// they time the period's work from its sample — the ADC's conversions, the interrupt's
/// latency and its prologue included, which a count started in the handler missed.
pub fn ticks_since_update(cnt: u16, counting_down: bool, arr: u16) -> u32 {
    let (cnt, arr) = (u32::from(cnt.min(arr)), u32::from(arr));
    if counting_down { arr - cnt } else { arr + cnt }
}

/// The PWM period check at start: TIM1's ARR, read back after its configuration, must be the
/// board's (centre-aligned, a period of 2·ARR ticks; `drive-file`'s board validation).
pub fn check_pwm_period(read: u16, board: &BoardConfig) -> Result<(), ControlError> {
    if read == board.pwm_period_counts {
        Ok(())
    } else {
        Err(ControlError::PwmPeriod { read, expected: board.pwm_period_counts })
    }
}

/// TIM1's repetition counter: in centre-aligned mode it counts both the overflow (top) and
/// the underflow (bottom), so 1 gives one update event per period. Written while the
/// counter is stopped, before its start, the event falls on the overflow (RM0440, the
/// repetition counter's description: "if the RCR was written before starting the counter,
/// the UEV occurs on the overflow") — the top of the count, where the ADC samples. The
/// compare values the control interrupt writes after a sample are therefore loaded at the
/// next sample's instant: **one PWM period of delay**, whatever the interrupt's duration up
/// to a period. With 0 (two events a period) they were loaded at the bottom, half a period
/// after the sample — or a whole one when the step (a slow step with a link command) ran
/// past it: a delay that depended on the code's timing.
pub const UPDATE_REPETITION: u16 = 1;

/// The update-timing check at start: TIM1's RCR read back, and the direction the counter
/// runs right after the first update event (down: the event was at the top).
pub fn check_update_timing(rcr: u16, down_after_update: Option<bool>) -> Result<(), ControlError> {
    if rcr == UPDATE_REPETITION && down_after_update == Some(true) {
        Ok(())
    } else {
        Err(ControlError::UpdateTiming { rcr, down_after_update })
    }
}

/// Where the offset calibration stands.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Calibration {
    /// Under way, bridge held off.
    Running(OffsetCalibration),
    /// Done: the channels' zeros.
    Done(Offsets),
    /// Refused (`Fault::CurrentSensor` latched).
    Failed(CalibrationError),
}

/// What the slow context works on (issue 54's two contexts): the drive's slow side, what the
/// fast context noted for it at the tick, and the link it serves — lent to it from the slow
/// step's tick until its job and the link's work are done ([`run_slow`]).
pub struct SlowPart {
    pub(crate) side: SlowSide,
    pub(crate) tick: TickNote,
    /// The link whose drive commands, watchdog stop and snapshots the slow context serves
    /// ([`ControlLoop::connect`]; none: the link's requests are the fast context's alone).
    pub(crate) link: Option<&'static dyn SlowLink>,
}

/// What the fast context notes for the slow context at a tick, beside the job.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct TickNote {
    /// The raw samples of the tick's period: what a `Status` served then reports.
    pub(crate) readings: BoardReadings,
    /// A commissioning sequence runs: the link's drive commands are the fast context's (a
    /// `Stop` or `Disable` aborts it, the rest is refused).
    pub(crate) commissioning: bool,
    /// The link task asked for a snapshot: `fast` is noted for it.
    pub(crate) snapshot: bool,
    /// The fast context's part of the snapshot (written in place: no copy of it made on the
    /// way, which cost the tick's period ≈ 200 instructions).
    pub(crate) fast: FastNote,
}

/// The fast context's part of a [`Snapshot`], noted in the period [`FastSide::note_due`] names.
#[derive(Clone, Copy, Debug)]
pub(crate) struct FastNote {
    output: Option<FastOutput>,
    signals: FastSignals,
    calibration: Calibration,
    bridge_on: bool,
}

impl Default for FastNote {
    fn default() -> Self {
        Self {
            output: None,
            signals: FastSignals::default(),
            calibration: Calibration::Running(OffsetCalibration::default()),
            bridge_on: false,
        }
    }
}

impl FastNote {
    /// The snapshot, with the slow side's part of the signals `s`.
    pub(crate) fn snapshot(&self, s: &SlowSignals) -> Snapshot {
        Snapshot {
            output: self.output.map(|o| (o, self.signals.join(s))),
            calibration: Some(self.calibration),
            bridge_on: self.bridge_on,
        }
    }
}

/// The link as the drive's slow context serves it — `crate::interrupt::Shared`, which also
/// holds what the control interrupt and the link task share: what the slow context does with
/// it around the slow step's job ([`run_slow`]), and the link task's snapshot request, which
/// the control interrupt reads to note its part of one.
pub trait SlowLink: Sync {
    /// The link task asks for a snapshot ([`FastSide::note_due`]'s period notes its fast part).
    fn snapshot_wanted(&self) -> &AtomicBool;
    /// Before the job, the slow side held: the snapshot noted, published.
    fn publish(&self, p: &mut SlowPart);
    /// After the job: the link's work that needs the slow side (the watchdog's stop, a
    /// drive command).
    fn serve(&self, p: &mut SlowPart);
}

impl core::fmt::Debug for SlowPart {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        // The link is a trait object without `Debug`: a `Debug` bound on it put `core::fmt`
        // in the image through its vtable (2.4 KB of flash).
        f.debug_struct("SlowPart")
            .field("side", &self.side)
            .field("tick", &self.tick)
            .field("linked", &self.link.is_some())
            .finish()
    }
}

/// The cell of [`SlowPart`]: the fast context's but for the slow context's turns.
pub type SlowCell = Handoff<SlowPart>;

/// What the control loop shares with the other contexts, each behind its own hand-off: the
/// drive's slow side (the slow context's turns, [`SlowCell`]) and the capture (the link
/// task's but while it records, [`Scope`]). Where the firmware keeps it: a static.
#[derive(Debug)]
pub struct Cells {
    slow: SlowCell,
    scope: Scope,
}

impl Cells {
    /// The cells written into `slot`: the slow side `side` (no link yet), the capture idle.
    fn new(slot: &mut MaybeUninit<Self>, side: SlowSide) -> &mut Self {
        slot.write(Self {
            slow: Handoff::new(SlowPart { side, tick: TickNote::default(), link: None }),
            scope: Scope::new(),
        })
    }
}

/// How the slow step's job is started once its cell is handed over: the board pends its
/// slow interrupt, whose body is [`run_slow`]; the host tests and QEMU's benchmarks run it
/// themselves.
pub type Pend = fn(&SlowCell);

/// The slow context's body: the snapshot the link asked for published (the fast context's
/// note and the slow side's signals before the job: the same period's), the job handed
/// over, if any, run, then the link's work that needs the slow side (the watchdog's stop, a
/// drive command: [`SlowLink::serve`]), and the slow side handed back (the board's slow
/// interrupt; the host tests' and QEMU's [`Pend`]).
pub fn run_slow(cell: &SlowCell) {
    cell.run(|p| {
        p.publish();
        p.side.run();
        p.serve();
    });
}

impl SlowPart {
    /// [`SlowLink::publish`] on the link, if any. Out of line, as [`SlowPart::serve`]: the
    /// slow context's body one path with one call of the job (two, one per link or none,
    /// and the job went out of line with the magnetizing fit out of it: +1 KB of flash).
    #[inline(never)]
    fn publish(&mut self) {
        if let Some(l) = self.link {
            l.publish(self);
        }
    }

    /// [`SlowLink::serve`] on the link, if any.
    #[inline(never)]
    fn serve(&mut self) {
        if let Some(l) = self.link {
            l.serve(self);
        }
    }
}

/// The drive's slow side as the fast side's step reaches it ([`SlowContext`]): its cell
/// and how its job is started.
#[derive(Clone, Copy, Debug)]
struct SlowHome<'s> {
    cell: &'s SlowCell,
    pend: Pend,
    /// The snapshot request of the link the cell's slow context serves
    /// ([`ControlLoop::connect`]), for the fast context's check without the cell.
    snapshot_wanted: Option<&'static AtomicBool>,
    /// What the tick's period notes for the slow context beside the job ([`TickNote`]'s
    /// readings and whether a sequence runs), set before the step and written with the job
    /// (in a borrow of the cell of its own, it cost the tick's period ≈ 20 instructions).
    readings: BoardReadings,
    commissioning: bool,
}

impl SlowContext for SlowHome<'_> {
    fn with(&mut self, f: &mut dyn FnMut(&mut SlowSide)) -> bool {
        self.cell.with(|p| f(&mut p.side)).is_some()
    }

    fn start(&mut self, latch: &mut dyn FnMut(&mut SlowSide)) -> bool {
        let (readings, commissioning) = (self.readings, self.commissioning);
        let latched = self.cell.with(|p| {
            latch(&mut p.side);
            (p.tick.readings, p.tick.commissioning) = (readings, commissioning);
        });
        let handed = latched.is_some() && self.cell.hand_over();
        if handed {
            (self.pend)(self.cell);
        }
        handed
    }
}

/// Control loop state: the drive's fast side (its slow side in a [`SlowCell`] of its own, for
/// the slow context) plus the converter scalings and the encoder estimator.
#[derive(Debug)]
pub struct ControlLoop<'s> {
    board: BoardConfig,
    fast: FastSide,
    slow: SlowHome<'s>,
    /// Phase-current channels a, b, c (their zeros from the calibration).
    current: [AdcScaling; 3],
    calibration_cfg: CalibrationConfig,
    calibration: Calibration,
    vdc: AdcScaling,
    pwm: PwmScaling,
    encoder_cfg: EncoderConfig<ENCODER_WINDOW>,
    encoder: EncoderState<ENCODER_WINDOW>,
    theta_m_rad: f32,
    omega_m_rad_s: f32,
    /// The drive's slow divider, the encoder's read period: what `reconfigure` compares
    /// (the drive's configuration has it too; read from there, the build took 328 B more
    /// flash, over issue 19's budget).
    divider: u16,
    last: Option<FastOutput>,
    /// The last period's bridge output was not `Off`.
    bridge_on: bool,
    /// Pre-charge periods left (0: none under way).
    precharge_left: u16,
    /// The raw samples of the period that served the last command the control interrupt
    /// served (a `Status` during commissioning reports them; the slow context's `Status`
    /// the tick's, `TickNote`): noted when it serves one, not in every period.
    readings: BoardReadings,
    /// The scope: the drive's measurements and output of chosen periods (recorded here,
    /// armed and read out by the link task).
    scope: &'s Scope,
    /// A commissioning sequence in the drive's place, and its last output.
    #[cfg(feature = "commissioning")]
    commission: Option<(Commissioning, Option<CommissionOutput>)>,
    /// The commissioning sequence's pre-charge periods left, before its first pulse.
    #[cfg(feature = "commissioning")]
    commission_precharge_left: u16,
}

/// What the link task needs from the control interrupt, published after a step through a
/// [`crate::boundary::TripleBuffer`] (no critical section) when the task asks for it
/// ([`crate::interrupt::Shared::request_snapshot`]): the last output, the offset
/// calibration's state, and whether the bridge is on (the link watchdog's concern).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Snapshot {
    /// The last step's output, and the drive's signals ([`Drive::telemetry`]) after it:
    /// the link's telemetry stream.
    pub output: Option<(FastOutput, Telemetry)>,
    /// The offset calibration (`None` before the first step).
    pub calibration: Option<Calibration>,
    /// The drive (or a commissioning sequence) has the bridge.
    pub bridge_on: bool,
}

/// What [`ControlLoop`] validates of the board and the drive's cadence before it is made.
struct Parts {
    divider: u16,
    current: AdcScaling,
    calibration_cfg: CalibrationConfig,
    vdc: AdcScaling,
    pwm: PwmScaling,
    encoder_cfg: EncoderConfig<ENCODER_WINDOW>,
}

impl Parts {
    fn new(cfg: &DriveConfig, board: &BoardConfig) -> Result<Self, ControlError> {
        let divider = cfg.slow_divider();
        let current =
            AdcScaling::new(board.current_a_per_count, board.current_offset_counts, board.adc_full_scale)
                .map_err(ControlError::Scaling)?;
        let calibration_cfg = CalibrationConfig::new(
            CALIBRATION_SAMPLES,
            board.current_offset_counts,
            board.current_offset_max_error_counts,
            board.current_noise_max_counts,
        )
        .map_err(ControlError::Calibration)?;
        let vdc =
            AdcScaling::new(board.vdc_v_per_count, 0, board.adc_full_scale).map_err(ControlError::Scaling)?;
        let pwm = PwmScaling::new(board.pwm_period_counts).map_err(ControlError::Scaling)?;
        let read_period_s = f32::from(divider) * cfg.ts_s();
        let encoder_cfg =
            EncoderConfig::new(board.encoder_lines, read_period_s).map_err(ControlError::Encoder)?;
        Ok(Self { divider, current, calibration_cfg, vdc, pwm, encoder_cfg })
    }
}

/// Why a commissioning sequence was not started.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CommissionRefused {
    /// The drive is not Idle (running, or a fault latched).
    NotIdle,
    /// The offset calibration has not finished (or failed).
    NotCalibrated,
    /// The rotor turns ([`Drive::rotor_at_rest`]): the standstill tests would misread it.
    RotorTurning,
}

impl<'s> ControlLoop<'s> {
    /// Validate everything once, at start-up: the drive configuration built at compile time
    /// (`config::DRIVE_CONFIG`, checked by [`DriveConfig::from_raw`]) and the board's scalings.
    /// The drive's slow side is written into `cell`, its jobs started with `pend`.
    pub fn new(
        raw: &RawDriveConfig,
        board: &BoardConfig,
        cells: &'s mut MaybeUninit<Cells>,
        pend: Pend,
    ) -> Result<Self, ControlError> {
        let cfg = DriveConfig::from_raw(raw).map_err(ControlError::Drive)?;
        Self::with_config(cfg, board, cells, pend)
    }

    /// [`ControlLoop::new`] written into `slot` (the firmware's static cell): everything
    /// validated first, then the loop written into the slot — no `Result` of the loop's
    /// 5.2 KiB moved on the way (built by value and moved, its 4 KiB capture ring was copied
    /// three times through a 10 KiB stack frame at start-up; written, twice through 9.3 KiB).
    /// On error `slot` and `cell` are left as they were.
    pub fn init<'a>(
        slot: &'a mut MaybeUninit<Self>,
        cells: &'s mut MaybeUninit<Cells>,
        pend: Pend,
        raw: &RawDriveConfig,
        board: &BoardConfig,
    ) -> Result<&'a mut Self, ControlError> {
        let cfg = DriveConfig::from_raw(raw).map_err(ControlError::Drive)?;
        let parts = Parts::new(&cfg, board)?;
        Ok(slot.write(Self::assemble(cfg, board, parts, cells, pend)))
    }

    /// The shipped configuration without the checks that compare the measured currents with
    /// the drive's references or the machine model (open phase, loss of control, encoder
    /// against the model), calibrated, for tests that step an enabled drive on samples at
    /// rest.
    #[cfg(test)]
    pub(crate) fn at_rest_for_tests() -> ControlLoop<'static> {
        let mut spec = crate::config::drive_spec().unwrap();
        spec.protection.open_phase_time_s = 1e6;
        spec.protection.saturation_time_s = 1e6;
        spec.protection.encoder_check_time_s = 1e6;
        let cfg = DriveConfig::new(&spec).unwrap();
        let mut c = ControlLoop::with_config(cfg, &crate::config::BOARD, tests::cell(), run_slow).unwrap();
        c.calibrate_at_rest();
        c
    }

    /// The offset calibration on samples at the nominal zero (tests).
    #[cfg(test)]
    pub(crate) fn calibrate_at_rest(&mut self) {
        let zero = self.board.current_offset_counts;
        for _ in 0..CALIBRATION_SAMPLES {
            let _ = self.step(&Samples { i_abc: [zero; 3], vdc: 3100, encoder: 0, hardware_break: false });
        }
        assert!(matches!(self.calibration, Calibration::Done(_)), "{:?}", self.calibration);
    }

    fn with_config(
        cfg: DriveConfig,
        board: &BoardConfig,
        cells: &'s mut MaybeUninit<Cells>,
        pend: Pend,
    ) -> Result<Self, ControlError> {
        let parts = Parts::new(&cfg, board)?;
        Ok(Self::assemble(cfg, board, parts, cells, pend))
    }

    /// The loop from validated parts, at rest: calibration under way, the capture idle.
    #[inline(always)]
    fn assemble(
        cfg: DriveConfig,
        board: &BoardConfig,
        p: Parts,
        cells: &'s mut MaybeUninit<Cells>,
        pend: Pend,
    ) -> Self {
        let (fast, slow) = Drive::new(cfg).into_parts();
        let cells: &'s Cells = Cells::new(cells, slow);
        Self {
            board: *board,
            fast,
            slow: SlowHome {
                cell: &cells.slow,
                pend,
                snapshot_wanted: None,
                readings: BoardReadings::default(),
                commissioning: false,
            },
            scope: &cells.scope,
            current: [p.current; 3],
            calibration_cfg: p.calibration_cfg,
            calibration: Calibration::Running(OffsetCalibration::default()),
            vdc: p.vdc,
            pwm: p.pwm,
            encoder_cfg: p.encoder_cfg,
            encoder: EncoderState::default(),
            theta_m_rad: 0.0,
            omega_m_rad_s: 0.0,
            divider: p.divider,
            last: None,
            bridge_on: false,
            precharge_left: 0,
            readings: BoardReadings::default(),
            #[cfg(feature = "commissioning")]
            commission: None,
            #[cfg(feature = "commissioning")]
            commission_precharge_left: 0,
        }
    }

    /// The drive configuration in use.
    pub fn config(&self) -> &DriveConfig {
        self.fast.config()
    }

    /// Swap the configuration for `cfg` while the bridge is off and the slow side is back
    /// ([`ControlError::SlowBusy`] otherwise); on error nothing changes.
    ///
    /// The drive swaps its configuration and keeps the machine's state ([`Drive::reconfigure`]:
    /// the motor's and the inverter's I²t temperature, the shaft's position, how long ago the
    /// rotor was driven, the estimates), so a gain write cannot cool a hot motor's
    /// protection. What belongs to the board is kept: the measured current offsets, the
    /// capture and the encoder's angle; its speed window too when its period is the same (a
    /// gain write: a coasting rotor's speed stays known), and it starts again at a new one.
    /// The fast context's, at once (a drive file for the same motor; the link's gain write is
    /// the slow context's, `server::drive_command`, which keeps the slow divider).
    pub fn reconfigure(&mut self, cfg: DriveConfig) -> Result<(), ControlError> {
        let divider = cfg.slow_divider();
        let read_period_s = f32::from(divider) * cfg.ts_s();
        let encoder_cfg =
            EncoderConfig::new(self.board.encoder_lines, read_period_s).map_err(ControlError::Encoder)?;
        self.drive_mut(|mut d| d.reconfigure(cfg))
            .ok_or(ControlError::SlowBusy)?
            .map_err(|_| ControlError::BridgeActive)?;
        if encoder_cfg != self.encoder_cfg || divider != self.divider {
            // The speed window restarts at the new period; the angle carries on (the drive's
            // position and turns with it).
            (self.encoder_cfg, self.omega_m_rad_s) = (encoder_cfg, 0.0);
            self.encoder.restart_window();
            self.divider = divider;
        }
        (self.last, self.precharge_left) = (None, 0);
        Ok(())
    }

    /// The scope: the capture, armed and read out by the link task ([`Scope::serve`]).
    pub fn scope(&self) -> &'s Scope {
        self.scope
    }

    /// Latch fault `f` (the first stays latched): the bridge off from this period on; the
    /// slow side learns it at its next tick ([`FastSide::trip`]).
    pub fn trip(&mut self, f: Fault) {
        self.fast.trip(f);
    }

    /// A copy of this loop whose slow side is a copy of this one's, in `cells` of its own
    /// (benchmarks: the same periods again from the same state; two loops on one cell
    /// would share one slow side): connected to no link, its capture idle. `None` while the
    /// slow side is at its job.
    pub fn fork<'t>(&self, cells: &'t mut MaybeUninit<Cells>) -> Option<ControlLoop<'t>> {
        let side = self.slow.cell.with(|p| p.side)?;
        let cells: &'t Cells = Cells::new(cells, side);
        Some(ControlLoop {
            board: self.board,
            fast: self.fast,
            slow: SlowHome { cell: &cells.slow, snapshot_wanted: None, ..self.slow },
            scope: &cells.scope,
            current: self.current,
            calibration_cfg: self.calibration_cfg,
            calibration: self.calibration,
            vdc: self.vdc,
            pwm: self.pwm,
            encoder_cfg: self.encoder_cfg,
            encoder: self.encoder,
            theta_m_rad: self.theta_m_rad,
            omega_m_rad_s: self.omega_m_rad_s,
            divider: self.divider,
            last: self.last,
            bridge_on: self.bridge_on,
            precharge_left: self.precharge_left,
            readings: self.readings,
            #[cfg(feature = "commissioning")]
            commission: self.commission.clone(),
            #[cfg(feature = "commissioning")]
            commission_precharge_left: self.commission_precharge_left,
        })
    }

    /// The cell of the drive's slow side, for the slow context ([`run_slow`]).
    pub fn slow_cell(&self) -> &'s SlowCell {
        self.slow.cell
    }

    /// Connect the link `link`: the slow context serves its drive commands, the watchdog's
    /// stop and the snapshots ([`SlowLink`]), the control interrupt the rest
    /// (`crate::interrupt::Shared::control_period`, called with the same link). False
    /// (nothing changes) while the slow side is at its job.
    pub fn connect(&mut self, link: &'static dyn SlowLink) -> bool {
        let connected = self.slow.cell.with(|p| p.link = Some(link)).is_some();
        if connected {
            self.slow.snapshot_wanted = Some(link.snapshot_wanted());
        }
        connected
    }

    /// The drive's fast side: its mode, configuration and cadence, in every period.
    pub fn fast(&self) -> &FastSide {
        &self.fast
    }

    /// `f` on the whole drive, to read it; `None` while the slow step is in flight — from its
    /// tick to its plan's adoption ([`ControlLoop::slow_busy`]) — or its slow side is not
    /// back from its job. The loop's methods are the control interrupt's (the fast context:
    /// the slow cell's owner); the slow context reaches the cell only through [`run_slow`].
    pub fn drive<R>(&self, f: impl FnOnce(DriveRef<'_>) -> R) -> Option<R> {
        if self.slow_busy() {
            return None;
        }
        self.slow.cell.with(|p| f(DriveRef::new(&self.fast, &p.side)))
    }

    /// `f` on the whole drive, for commands from the link; `None` as [`ControlLoop::drive`]
    /// (the command waits for a later period).
    pub fn drive_mut<R>(&mut self, f: impl FnOnce(DriveMut<'_>) -> R) -> Option<R> {
        if self.slow_busy() {
            return None;
        }
        let fast = &mut self.fast;
        self.slow.cell.with(|p| f(DriveMut::new(fast, &mut p.side)))
    }

    /// The drive's signals after the last step ([`DriveRef::telemetry`]), the slow side's
    /// part that of the plan in force ([`FastSide::plan_signals`]) while it is at its job.
    pub fn telemetry(&self) -> Telemetry {
        let s = self.slow.cell.with(|p| p.side.signals()).unwrap_or(self.fast.plan_signals());
        self.fast.telemetry_with(&s)
    }

    /// What the link task reads ([`Snapshot`]), made on demand: the drive's telemetry too.
    pub fn snapshot(&self) -> Snapshot {
        Snapshot {
            output: self.last.map(|o| (o, self.telemetry())),
            calibration: Some(self.calibration),
            bridge_on: self.fast.mode().is_active() || self.commissioning(),
        }
    }

    /// The raw samples of the period that served the last command ([`Self::note_readings`]).
    pub fn readings(&self) -> BoardReadings {
        self.readings
    }

    /// Note this period's raw samples for the command about to be served (`Status` reports
    /// them). Called by the interrupt only when it serves a command: stored in every period,
    /// they cost 10 instructions of each.
    pub fn note_readings(&mut self, s: &Samples) {
        self.readings = BoardReadings { i_abc_counts: s.i_abc, vdc_counts: s.vdc, encoder_counts: s.encoder };
    }

    /// Where the offset calibration stands.
    pub fn calibration(&self) -> Calibration {
        self.calibration
    }

    /// One period of the calibration: the bridge held off (an enable from the link is
    /// undone), the three codes added; at the end, the channels' zeros or the fault.
    #[cold]
    #[inline(never)]
    fn calibrate(&mut self, codes: [u16; 3]) {
        let Calibration::Running(mut cal) = self.calibration else { return };
        if self.fast.mode().is_active() {
            // Undone in a period with the slow side back (the bridge stays off meanwhile:
            // `control`).
            self.drive_mut(|mut d| d.disable());
        }
        self.calibration = match cal.add(&self.calibration_cfg, codes) {
            None => Calibration::Running(cal),
            Some(Ok(offsets)) => {
                // Each zero lies within the tolerance of the nominal code.
                let [a, b, c] = offsets.counts;
                let [sa, sb, sc] = self.current;
                self.current = [sa.with_offset(a), sb.with_offset(b), sc.with_offset(c)];
                self.fast.current_zero_moved();
                Calibration::Done(offsets)
            }
            Some(Err(e)) => {
                self.fast.trip(Fault::CurrentSensor);
                Calibration::Failed(e)
            }
        };
    }

    /// Start commissioning with `cfg` (built outside the interrupt): only while Idle and
    /// calibrated. A finished or refused sequence is replaced.
    #[cfg(feature = "commissioning")]
    pub fn start_commissioning(&mut self, cfg: CommissionConfig) -> Result<(), CommissionRefused> {
        if self.fast.mode() != Mode::Idle || self.commissioning() {
            return Err(CommissionRefused::NotIdle);
        }
        if !matches!(self.calibration, Calibration::Done(_)) {
            return Err(CommissionRefused::NotCalibrated);
        }
        if self.drive(|d| d.rotor_at_rest()) != Some(true) {
            return Err(CommissionRefused::RotorTurning);
        }
        self.commission = Some((Commissioning::new(cfg), None));
        // The sequence's first stage measures the offsets with the bridge off; its pulses
        // then get the bootstrap pre-charge first ([`ControlLoop::control`]).
        self.commission_precharge_left = self.board.bootstrap_precharge_periods;
        Ok(())
    }

    /// A sequence is running (not finished, not refused).
    pub fn commissioning(&self) -> bool {
        #[cfg(feature = "commissioning")]
        return self.commission.as_ref().is_some_and(|(c, _)| !c.stage().is_over());
        #[cfg(not(feature = "commissioning"))]
        false
    }

    /// Stop the sequence: the bridge off for good (`Refusal::Aborted`).
    pub fn abort_commissioning(&mut self) {
        #[cfg(feature = "commissioning")]
        if let Some((c, _)) = &mut self.commission {
            c.abort();
        }
    }

    /// The last step's output of the sequence (`None`: none started).
    #[cfg(feature = "commissioning")]
    pub fn commission_output(&self) -> Option<CommissionOutput> {
        self.commission.as_ref().and_then(|(_, o)| *o)
    }

    /// The finished sequence's record.
    #[cfg(feature = "commissioning")]
    pub fn commission_record(&self) -> Option<&Record> {
        self.commission.as_ref().and_then(|(c, _)| c.record())
    }

    /// The drive's slow step is in flight after the period just stepped — from its tick (or
    /// during the bootstrap pre-charge its shaft's stage, [`FastSide::hold_step`]) up to the
    /// adoption of its plan ([`FastSide::slow_busy`]): the control interrupt serves its own
    /// share of the link's requests (`crate::interrupt::Shared::control_period`) in a period
    /// after it.
    pub fn slow_busy(&self) -> bool {
        self.fast.slow_busy()
    }

    /// The brake chopper's switch after the last step.
    pub fn brake(&self) -> bool {
        self.last.is_some_and(|o| o.brake)
    }

    /// One PWM period: the control interrupt.
    pub fn step(&mut self, s: &Samples) -> Bridge {
        if s.hardware_break {
            self.fast.trip(Fault::HardwareBreak);
        }
        // Running with the bridge on (the common case) needs no pre-charge check.
        let precharge = if self.bridge_on && self.precharge_left == 0 { None } else { self.precharge(s) };
        let bridge = match precharge {
            Some(b) => b,
            None => self.control(s),
        };
        self.bridge_on = bridge != Bridge::Off;
        bridge
    }

    /// The bootstrap pre-charge: a drive that asks for the bridge (enabled from the link)
    /// while the bridge was off first gets `bootstrap_precharge_periods` with all three low
    /// sides on (compare 0: the zero vector, no voltage on the motor), so that the high-side
    /// gate drivers' bootstrap capacitors are charged before its first period. Meanwhile the
    /// drive's supervisor runs on every sample and its cadence runs on, the encoder read in
    /// its slow periods ([`Drive::hold_step`]: a fault ends the pre-charge with the bridge
    /// off; a rotor that turns keeps its speed and its jump check's reference), and its
    /// control state does not move, so its first period afterwards is the one it would have
    /// had without. A disable meanwhile ends it. A
    /// commissioning sequence gets its own, after its offsets and before its first pulse
    /// ([`ControlLoop::start_commissioning`]).
    fn precharge(&mut self, s: &Samples) -> Option<Bridge> {
        let wants_bridge = self.fast.mode().is_active();
        if !wants_bridge {
            self.precharge_left = 0;
            return None;
        }
        // (Running with the bridge on, the common case, does not come here: `step`.)
        if matches!(self.calibration, Calibration::Running(_)) {
            return None; // the calibration undoes the enable
        }
        if !self.bridge_on {
            self.precharge_left = self.board.bootstrap_precharge_periods;
        }
        if self.precharge_left == 0 {
            return None;
        }
        self.precharge_left -= 1;
        if self.fast.slow_step_due() {
            self.read_encoder(s.encoder);
        }
        let m = self.measurements(s);
        let brake = self.fast.hold_step(&m, &mut self.slow);
        if let Some(o) = self.last.as_mut() {
            o.brake = brake;
            o.mode = self.fast.mode();
            // The capture's sample of this period: the drive's last telemetry, the duties
            // applied (the low sides on).
            let applied = FastOutput { phases: PhaseCommand::Duty(Abc { a: 0.0, b: 0.0, c: 0.0 }), ..*o };
            if self.scope.recording() {
                self.record(&m, &applied);
            }
        }
        if matches!(self.fast.mode(), Mode::Fault(_)) {
            self.precharge_left = 0;
            return Some(Bridge::Off);
        }
        let low = self.pwm.compare(0.0);
        Some(Bridge::Compare([low; 3]))
    }

    /// The samples in SI units, with the encoder's last reading.
    #[inline(always)]
    fn measurements(&self, s: &Samples) -> Measurements {
        let [a, b, c] = s.i_abc;
        let [sa, sb, sc] = &self.current;
        Measurements {
            i_abc_a: Abc { a: sa.to_f32(AdcCode(a)), b: sb.to_f32(AdcCode(b)), c: sc.to_f32(AdcCode(c)) },
            vdc_v: self.vdc.to_f32(AdcCode(s.vdc)),
            omega_m_rad_s: self.omega_m_rad_s,
            theta_m_rad: self.theta_m_rad,
        }
    }

    /// The control step proper: encoder, calibration, drive (or commissioning) → bridge.
    fn control(&mut self, s: &Samples) -> Bridge {
        // The encoder for the drive's slow step, in its period: the drive's cadence is the
        // one cadence (a new configuration restarts it).
        if self.fast.slow_step_due() {
            self.read_encoder(s.encoder);
            self.note_tick(s);
        }
        if self.slow.snapshot_wanted.is_some_and(|w| w.load(Ordering::Relaxed)) && self.fast.note_due() {
            self.note_snapshot();
        }
        let calibrating = matches!(self.calibration, Calibration::Running(_));
        if calibrating {
            self.calibrate(s.i_abc);
        }
        let m = self.measurements(s);
        let out = self.fast.step(&m, &mut self.slow);
        self.last = Some(out);
        if self.scope.recording() {
            self.record(&m, &out);
        }
        #[cfg(feature = "commissioning")]
        if let Some((c, last)) = self.commission.as_mut().filter(|(c, _)| !c.stage().is_over()) {
            if matches!(out.mode, Mode::Fault(_)) {
                c.abort();
            }
            // The bootstrap pre-charge before the sequence's first pulse: once its offsets
            // are measured (bridge off), it pauses with all low sides on — the zero vector,
            // no voltage on the motor — while the drive's supervisor above runs (a fault
            // aborts the sequence: its stage is then over). Its own timing is untouched: it
            // resumes where it paused.
            let paused = !matches!(c.stage(), Stage::Offsets) && !c.stage().is_over();
            if self.commission_precharge_left > 0 && paused {
                self.commission_precharge_left -= 1;
                let low = self.pwm.compare(0.0);
                return Bridge::Compare([low; 3]);
            }
            let o = c.step(&m);
            *last = Some(o);
            if o.phases != PhaseCommand::Off {
                // The sequence magnetizes the rotor: the drive's next enable must not read
                // the flux it leaves as a smaller inductance.
                // (In a period with the slow side back: the sequence's pulses last many.)
                self.drive_mut(|mut d| d.rotor_driven(0));
            }
            return match o.phases {
                PhaseCommand::Off => Bridge::Off,
                PhaseCommand::Duty(d) => Bridge::Compare(self.pwm.compare3(d)),
            };
        }
        match out.phases {
            PhaseCommand::Off => Bridge::Off,
            // The calibration's last period: the bridge stays off until the next one.
            PhaseCommand::Duty(_) if calibrating => Bridge::Off,
            PhaseCommand::Duty(d) => Bridge::Compare(self.pwm.compare3(d)),
        }
    }

    /// What the slow context needs beside the job of this period's tick ([`TickNote`]): the
    /// period's raw samples and whether a sequence runs, written with the job
    /// ([`SlowContext::start`]; nothing if the slow side is not back: the tick latches
    /// `Overrun`).
    #[inline(always)]
    fn note_tick(&mut self, s: &Samples) {
        self.slow.commissioning = self.commissioning();
        self.slow.readings =
            BoardReadings { i_abc_counts: s.i_abc, vdc_counts: s.vdc, encoder_counts: s.encoder };
    }

    /// The fast part of the snapshot the link task asked for, noted for the next job's slow
    /// context ([`TickNote`]) in the period [`FastSide::note_due`] names (the last period's:
    /// before this one's step), once per request. Out of line: every 10 ms at most.
    #[inline(never)]
    fn note_snapshot(&self) {
        let commissioning = self.commissioning();
        self.slow.cell.with(|p| {
            if !p.tick.snapshot {
                self.note_fast(&mut p.tick.fast, commissioning);
                p.tick.snapshot = true;
            }
        });
    }

    /// The fast context's part of a snapshot written into `n` ([`FastNote`]).
    #[inline(always)]
    fn note_fast(&self, n: &mut FastNote, commissioning: bool) {
        n.output = self.last;
        n.signals = self.fast.signals();
        n.calibration = self.calibration;
        n.bridge_on = self.fast.mode().is_active() || commissioning;
    }

    /// The capture's sample of this period ([`Scope::record`]), while it records: out of
    /// line, so that a period without it keeps its values in registers (inlined, the
    /// sample's source cost every period ≈ 10 instructions).
    #[inline(never)]
    fn record(&self, m: &Measurements, out: &FastOutput) {
        self.scope.record(&FastPeriod { m, out, fast: &self.fast });
    }

    fn read_encoder(&mut self, raw: u16) {
        let r = self.encoder_cfg.update(&mut self.encoder, raw);
        self.theta_m_rad = r.theta_m_rad;
        self.omega_m_rad_s = r.omega_m_rad_s;
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::config::{DRIVE_CONFIG, drive_spec};
    use controller_core::drive::{Mode, Reference};
    use controller_core::link::{self, BoardCommand, LinkStats, NackReason, Reply};

    extern crate std;

    /// A slow cell for a test's loop, its job run at once ([`run_slow`] as the pend): leaked,
    /// as the board's is a static.
    pub(crate) fn cell() -> &'static mut MaybeUninit<Cells> {
        std::boxed::Box::leak(std::boxed::Box::new(MaybeUninit::uninit()))
    }

    pub(crate) fn board() -> BoardConfig {
        BoardConfig {
            current_a_per_count: 16.5 / 2048.0,
            current_offset_counts: 2048,
            vdc_v_per_count: 0.1,
            adc_full_scale: 4095,
            pwm_period_counts: 4250,
            encoder_lines: 1024,
            current_offset_max_error_counts: 204.75,
            current_noise_max_counts: 8.0,
            bootstrap_precharge_periods: 40,
        }
    }

    /// Enable, then the bootstrap pre-charge on samples at rest: all low sides on (compare
    /// 0), for exactly the board's periods.
    fn enable_through_precharge(c: &mut ControlLoop) {
        c.drive_mut(|mut d| d.enable()).unwrap().unwrap();
        for k in 0..c.board.bootstrap_precharge_periods {
            assert_eq!(c.step(&at_rest(0)), Bridge::Compare([0; 3]), "pre-charge period {k}");
        }
    }

    /// The slow step's job in a context of its own that never runs it (a slow interrupt
    /// that is not serviced): the plan is not there when it is due, the drive latches
    /// `Overrun` and the bridge goes off in that period.
    #[test]
    fn a_slow_job_never_run_turns_the_bridge_off() {
        use core::sync::atomic::{AtomicBool, Ordering};
        static SERVICED: AtomicBool = AtomicBool::new(true);
        let pend: Pend = |cell| {
            if SERVICED.load(Ordering::Relaxed) {
                run_slow(cell);
            }
        };
        let mut c = ControlLoop::new(&DRIVE_CONFIG, &board(), cell(), pend).unwrap();
        c.calibrate_at_rest();
        enable_through_precharge(&mut c);
        SERVICED.store(false, Ordering::Relaxed);
        let mut periods = 0;
        while c.step(&at_rest(0)) != Bridge::Off {
            periods += 1;
            assert!(periods <= c.config().slow_divider(), "off within a slow period");
        }
        assert_eq!(c.fast().mode(), Mode::Fault(Fault::Overrun));
        assert!(!c.slow_cell().is_back(), "the job is still the slow context's");
        // Run at last: the slow side is back, the fault stays latched, the bridge off.
        run_slow(c.slow_cell());
        assert_eq!(c.step(&at_rest(0)), Bridge::Off);
        assert_eq!(c.drive(|d| d.mode()), Some(Mode::Fault(Fault::Overrun)));
    }

    fn at_rest(enc: u16) -> Samples {
        Samples { i_abc: [2048; 3], vdc: 3100, encoder: enc, hardware_break: false }
    }

    #[test]
    fn adc_codes_to_amperes_and_duty_to_compare() {
        let mut c = ControlLoop::new(&DRIVE_CONFIG, &board(), cell(), run_slow).unwrap();
        c.calibrate_at_rest();
        // Idle: bridge off whatever the inputs.
        assert_eq!(c.step(&at_rest(0)), Bridge::Off);
        enable_through_precharge(&mut c);
        // Zero current at the offset code, 310 V: magnetizing starts (with the flux command
        // of the next slow step: within one slow period). Min–max SVPWM centres the three
        // compare values on half the period, unless the highest would leave its phase no
        // low-side sampling window: then they move down, the highest at the limit
        // (`DriveSpec::duty_max`, 0.94 with drive.toml's 1.5 µs at 20 kHz).
        let spec = drive_spec().unwrap();
        let top = (spec.duty_max() * 4250.0).ceil() as u16;
        for _ in 1..spec.slow_divider {
            let _ = c.step(&at_rest(0));
        }
        match c.step(&at_rest(0)) {
            Bridge::Compare(ccr) => {
                let (max, min) = (ccr.iter().max().unwrap(), ccr.iter().min().unwrap());
                assert!(*max <= top, "{ccr:?} above {top}");
                let centred = ((u32::from(*max) + u32::from(*min)) as f64 / 2.0 - 4250.0 / 2.0).abs() <= 1.0;
                assert!(centred || *max + 1 >= top, "{ccr:?}");
                assert!(max > min, "a voltage is applied: {ccr:?}");
            }
            Bridge::Off => panic!("bridge off while magnetizing"),
        }
        // 2048 + 1241 counts = +10 A on phase a: above i_trip (8 A) → Overcurrent, off.
        let s = Samples { i_abc: [2048 + 1241, 2048 - 620, 2048 - 621], ..at_rest(0) };
        assert_eq!(c.step(&s), Bridge::Off);
        assert_eq!(c.fast().mode(), Mode::Fault(Fault::Overcurrent));
    }

    /// The bootstrap pre-charge leaves the drive exactly where an enable without it would:
    /// after it, each period's compare values equal those of a loop with no pre-charge,
    /// period for period (the drive was not stepped, its slow cadence did not move).
    #[test]
    fn the_precharge_does_not_disturb_the_drive() {
        let mut with = ControlLoop::new(&DRIVE_CONFIG, &board(), cell(), run_slow).unwrap();
        let mut without = ControlLoop::new(
            &DRIVE_CONFIG,
            &BoardConfig { bootstrap_precharge_periods: 0, ..board() },
            cell(),
            run_slow,
        )
        .unwrap();
        for c in [&mut with, &mut without] {
            c.calibrate_at_rest();
        }
        enable_through_precharge(&mut with);
        without.drive_mut(|mut d| d.enable()).unwrap().unwrap();
        let mut switching = 0;
        for k in 0..200u16 {
            // A current that moves, so that the loops' outputs move too (it does not follow
            // the references: the open-phase check ends the run, in both alike, after ≈ 100
            // periods of switching).
            let s = Samples { i_abc: [2048 + k % 50, 2048 - k % 50, 2048], ..at_rest(k / 10) };
            let (a, b) = (with.step(&s), without.step(&s));
            assert_eq!(a, b, "period {k}");
            switching += usize::from(matches!(a, Bridge::Compare(_)));
        }
        assert!(switching > 90, "{switching} {:?}", with.fast().mode());
        assert_eq!(with.fast().mode(), without.fast().mode());
    }

    /// A fault during the pre-charge ends it with the bridge off (the supervisor runs on
    /// every sample); a disable ends it too; the next enable pre-charges again.
    #[test]
    fn the_precharge_ends_on_a_fault_or_a_disable() {
        let mut c = ControlLoop::new(&DRIVE_CONFIG, &board(), cell(), run_slow).unwrap();
        c.calibrate_at_rest();
        c.drive_mut(|mut d| d.enable()).unwrap().unwrap();
        assert_eq!(c.step(&at_rest(0)), Bridge::Compare([0; 3]));
        // +10 A on phase a, above the 8 A trip level.
        let s = Samples { i_abc: [2048 + 1241, 2048 - 620, 2048 - 621], ..at_rest(0) };
        assert_eq!(c.step(&s), Bridge::Off);
        assert_eq!(c.fast().mode(), Mode::Fault(Fault::Overcurrent));
        assert_eq!(c.step(&at_rest(0)), Bridge::Off);
        c.drive_mut(|mut d| d.clear_fault()).unwrap();
        c.drive_mut(|mut d| d.enable()).unwrap().unwrap();
        assert_eq!(c.step(&at_rest(0)), Bridge::Compare([0; 3]));
        c.drive_mut(|mut d| d.disable()).unwrap();
        assert_eq!(c.step(&at_rest(0)), Bridge::Off);
        // A fresh enable: the whole pre-charge again.
        enable_through_precharge(&mut c);
        assert!(matches!(c.step(&at_rest(0)), Bridge::Compare(ccr) if ccr != [0; 3]));
    }

    /// A commissioning sequence's first pulse gets the bootstrap pre-charge: its offsets are
    /// measured with the bridge off, then it pauses for `bootstrap_precharge_periods` with all
    /// low sides on (compare 0) and resumes where it paused — from then on its outputs are
    /// those of a loop without the pre-charge, period for period, 40 periods later. A fault
    /// during the pre-charge aborts the sequence with the bridge off.
    #[cfg(feature = "commissioning")]
    #[test]
    fn a_commissioning_sequence_pre_charges_before_its_first_pulse() {
        use controller_core::commission::{CommissionSpec, OFFSET_PERIODS};
        let spec = CommissionSpec {
            pwm_hz: 20_000.0,
            test_current_a: 1.0,
            current_limit_a: 2.0,
            vdc_min_v: 200.0,
            vdc_max_v: 400.0,
            level_time_s: 0.5,
            rotate: false,
            rated_flux_wb: 0.9,
            no_load_hz: 15.0,
            curve: false,
        };
        let start = |periods: u16| {
            let mut c = ControlLoop::new(
                &DRIVE_CONFIG,
                &BoardConfig { bootstrap_precharge_periods: periods, ..board() },
                cell(),
                run_slow,
            )
            .unwrap();
            c.calibrate_at_rest();
            c.start_commissioning(CommissionConfig::new(spec).unwrap()).unwrap();
            for k in 0..OFFSET_PERIODS {
                assert_eq!(c.step(&at_rest(0)), Bridge::Off, "offsets, period {k}");
            }
            c
        };
        let (mut with, mut without) = (start(40), start(0));
        assert!(matches!(with.commission_output().map(|o| o.stage), Some(Stage::Pulse(0))));
        for k in 0..40 {
            assert_eq!(with.step(&at_rest(0)), Bridge::Compare([0; 3]), "pre-charge period {k}");
        }
        let mut pulsing = 0;
        for k in 0..400 {
            let (a, b) = (with.step(&at_rest(0)), without.step(&at_rest(0)));
            assert_eq!(a, b, "period {k} after the pre-charge");
            pulsing += usize::from(matches!(a, Bridge::Compare(ccr) if ccr != [0; 3]));
        }
        assert!(pulsing > 0, "the sequence pulsed");
        // The rotor it drove is not demagnetized for the drive's next enable (read, as the
        // link would, in a period without the slow step in flight).
        while with.slow_busy() {
            with.step(&at_rest(0));
        }
        assert!(
            with.drive(|d| d.idle_slow_steps()).unwrap() < 10,
            "{}",
            with.drive(|d| d.idle_slow_steps()).unwrap()
        );
        // A new configuration keeps how long ago the rotor was driven (its flux).
        let idle = with.drive(|d| d.idle_slow_steps()).unwrap();
        with.reconfigure(DriveConfig::new(&drive_spec().unwrap()).unwrap()).unwrap();
        assert_eq!(with.drive(|d| d.idle_slow_steps()).unwrap(), idle);
        // A fault during the pre-charge: +10 A on phase a, above the 8 A trip level.
        let mut c = start(40);
        assert_eq!(c.step(&at_rest(0)), Bridge::Compare([0; 3]));
        let s = Samples { i_abc: [2048 + 1241, 2048 - 620, 2048 - 621], ..at_rest(0) };
        assert_eq!(c.step(&s), Bridge::Off);
        assert!(!c.commissioning());
        for _ in 0..100 {
            assert_eq!(c.step(&at_rest(0)), Bridge::Off);
        }
    }

    /// The encoder is read in the period of the drive's slow step — after a new
    /// configuration made in the middle of a slow period too (a gain write from the link):
    /// read some periods earlier, the slow step would anchor the field on an angle k periods
    /// old, p·ω_m·k·T behind (17° at the shipped top speed for k = 9).
    #[test]
    fn the_encoder_is_read_for_the_drives_slow_step_after_a_reconfiguration() {
        let div = usize::from(drive_spec().unwrap().slow_divider);
        for reconfigure_at in 0..2 * div {
            let mut c = ControlLoop::new(&DRIVE_CONFIG, &board(), cell(), run_slow).unwrap();
            let mut encoder = 0u16;
            let mut done = false;
            for k in 0..reconfigure_at + 3 * div {
                // As the link's gain write is served: the first period from `reconfigure_at`
                // without the slow step in flight.
                if k >= reconfigure_at && !done && !c.slow_busy() {
                    c.reconfigure(DriveConfig::new(&drive_spec().unwrap()).unwrap()).unwrap();
                    done = true;
                }
                // One count a period: every read finds the rotor moved.
                encoder = encoder.wrapping_add(1);
                let (due, theta) = (c.fast().slow_step_due(), c.theta_m_rad);
                let _ = c.step(&at_rest(encoder));
                // The first read is the angle's zero (the encoder's priming read).
                let read = c.theta_m_rad != theta || k == 0;
                assert_eq!(read, due, "reconfigured at period {reconfigure_at}: period {k}");
            }
        }
    }

    /// A new slow divider while the encoder turns (found by a review: the drive's jump
    /// check compared a change read at the old period with one at the new, and the loop's
    /// estimator restarted its angle at 0 — a false `EncoderLoss`, and the position lost
    /// 0.76 of 1.53 rad): no fault, and the drive's position follows the counter.
    #[test]
    fn a_new_slow_divider_keeps_the_encoder_and_the_position() {
        let spec = drive_spec().unwrap();
        let counts_per_rad = 4.0 * f64::from(board().encoder_lines) / core::f64::consts::TAU;
        for w_rad_s in [7.7, 50.0, 150.0] {
            let mut c = ControlLoop::new(&DRIVE_CONFIG, &board(), cell(), run_slow).unwrap();
            let mut counts = 0.0f64;
            let mut run = |c: &mut ControlLoop, periods: u32| {
                for _ in 0..periods {
                    counts += w_rad_s * counts_per_rad / spec.pwm_frequency_hz;
                    let _ = c.step(&at_rest((counts.rem_euclid(65_536.0)) as u16));
                }
            };
            run(&mut c, 3000);
            let halved = controller_core::drive::DriveSpec { slow_divider: spec.slow_divider / 2, ..spec };
            c.reconfigure(DriveConfig::new(&halved).unwrap()).unwrap();
            run(&mut c, 3000);
            assert_eq!(c.fast().mode(), Mode::Idle, "{w_rad_s} rad/s");
            let turned = counts / counts_per_rad;
            // The first read is the angle's zero; then within a read's turning.
            let read_rad = w_rad_s * f64::from(spec.slow_divider) / spec.pwm_frequency_hz;
            let error = f64::from(c.drive(|d| d.position_rad()).unwrap()) - turned;
            assert!(
                error.abs() < 2.0 * read_rad,
                "{w_rad_s}: {} against {turned}",
                c.drive(|d| d.position_rad()).unwrap()
            );
        }
    }

    /// Issue 54: an enable on a rotor that turns (coasting, or driven by its load). The
    /// pre-charge froze the drive's cadence and skipped the encoder, so the first read after
    /// it spanned the pre-charge's 40 periods plus a slow period against the one period
    /// before: `EncoderLoss` at every speed here, from 5 rad/s. Now the encoder is read on the drive's
    /// cadence through the pre-charge: no fault, and the speed the drive reads at the end of
    /// the pre-charge is the shaft's within one count per read.
    #[test]
    fn an_enable_on_a_turning_rotor_keeps_the_encoder() {
        let spec = drive_spec().unwrap();
        let counts_per_rad = 4.0 * f64::from(crate::config::BOARD.encoder_lines) / core::f64::consts::TAU;
        let read_s = f64::from(spec.slow_divider) / spec.pwm_frequency_hz;
        for w_rad_s in [-100.0f64, -20.0, 5.0, 20.0, 100.0] {
            // Every start phase of the drive's cadence against the enable, the rotor brought
            // to speed at 1 000 rad/s² first (a plausible motion for the jump check).
            let ramp = (w_rad_s.abs() / 1000.0 * spec.pwm_frequency_hz) as u32;
            for enable_at in ramp + 100..ramp + 100 + u32::from(spec.slow_divider) {
                // (The samples carry no current: the checks that expect one are off.)
                let mut c = ControlLoop::at_rest_for_tests();
                let (mut counts, mut k) = (0.0f64, 0);
                let mut step = |c: &mut ControlLoop| {
                    k += 1;
                    let w = w_rad_s * f64::from(k.min(ramp)) / f64::from(ramp);
                    counts += w * counts_per_rad / spec.pwm_frequency_hz;
                    c.step(&at_rest(counts.rem_euclid(65_536.0) as u16))
                };
                for _ in 0..enable_at {
                    let _ = step(&mut c);
                }
                assert_eq!(c.fast().mode(), Mode::Idle, "{w_rad_s} rad/s before the enable");
                // As the link's command is served: in a period without the slow step in flight.
                while c.slow_busy() {
                    let _ = step(&mut c);
                }
                c.drive_mut(|mut d| d.enable()).unwrap().unwrap();
                for k in 0..c.board.bootstrap_precharge_periods {
                    assert_eq!(
                        step(&mut c),
                        Bridge::Compare([0; 3]),
                        "{w_rad_s} rad/s: pre-charge period {k}"
                    );
                }
                let error_rad_s = f64::from(c.omega_m_rad_s) - w_rad_s;
                assert!(
                    error_rad_s.abs() <= 1.0 / (counts_per_rad * read_s),
                    "{w_rad_s}: read {}",
                    c.omega_m_rad_s
                );
                for k in 0..10 * u32::from(spec.slow_divider) {
                    let _ = step(&mut c);
                    assert!(
                        !matches!(c.fast().mode(), Mode::Fault(_)),
                        "{w_rad_s} rad/s, enabled at {enable_at}: {:?} {k} periods after the pre-charge",
                        c.fast().mode()
                    );
                }
            }
        }
    }

    /// The capture samples every period, the bootstrap pre-charge's too (with the duties
    /// it applies, 0): an enable inside a record leaves no gap in its time axis.
    #[test]
    fn the_capture_records_the_precharge_periods() {
        use controller_core::capture::{CaptureSpec, CaptureState, Signal, Trigger};
        let mut c = ControlLoop::new(&DRIVE_CONFIG, &board(), cell(), run_slow).unwrap();
        c.calibrate_at_rest();
        let spec = CaptureSpec {
            signals: [Signal::DutyA, Signal::Mode, Signal::Vdc, Signal::IA],
            trigger: Trigger::Immediate,
            pre_samples: 0,
            decimation: 1,
        };
        assert_eq!(c.scope().serve(&BoardCommand::ArmCapture(spec)), Some(Reply::Ack));
        for _ in 0..10 {
            assert_eq!(c.step(&at_rest(0)), Bridge::Off);
        }
        enable_through_precharge(&mut c);
        for _ in 0..(CAPTURE_DEPTH - 10 - 40) {
            let _ = c.step(&at_rest(0));
        }
        assert_eq!(c.scope().state(), CaptureState::Done);
        let duty = |k: usize| {
            let b = c.scope().with_capture(|cap| cap.chunk(k / 8)).unwrap().unwrap();
            let at = (k % 8) * 16;
            f32::from_le_bytes(b[at..at + 4].try_into().unwrap())
        };
        assert!((0..10).all(|k| duty(k).is_nan()), "bridge off: no duty");
        assert!((10..50).all(|k| duty(k) == 0.0), "the pre-charge: low sides on");
        assert!(duty(50) > 0.0 && duty(50) < 1.0, "then the drive's own duty: {}", duty(50));
    }

    /// The capture in a slow step's periods, its job run by a slow context of its own after
    /// the period (the board's order) or at once at its tick: the same record bit for bit —
    /// the drive's outputs, and the signals' slow part (here the rotor-flux estimate, which
    /// the slow step's flux model moves) that of the plan in force, which changes at the
    /// plan's adoptions only, whenever the job ran.
    #[test]
    fn the_capture_reads_the_slow_part_of_the_plan_in_force() {
        use controller_core::capture::{CaptureSpec, CaptureState, Signal, Trigger};
        use core::sync::atomic::{AtomicBool, Ordering};
        static PENDING: AtomicBool = AtomicBool::new(false);
        let deferred: Pend = |_| PENDING.store(true, Ordering::Relaxed);
        let capture = CaptureSpec {
            signals: [Signal::DutyA, Signal::PsiR, Signal::IAlpha, Signal::Mode],
            trigger: Trigger::Immediate,
            pre_samples: 0,
            decimation: 1,
        };
        let run = |pend: Pend| {
            // The checks that compare the currents with a machine off (none stands behind
            // the samples: each period's current is the reference of the period before).
            let mut spec = drive_spec().unwrap();
            spec.protection.open_phase_time_s = 1e6;
            spec.protection.saturation_time_s = 1e6;
            spec.protection.encoder_check_time_s = 1e6;
            let cfg = DriveConfig::new(&spec).unwrap();
            let mut c = ControlLoop::with_config(cfg, &board(), cell(), pend).unwrap();
            let (zero, a_per_count) = (f32::from(c.board.current_offset_counts), c.board.current_a_per_count);
            let step = |c: &mut ControlLoop| {
                let i = c.telemetry().i_ref_ab_a.inverse_clarke();
                let code = |x: f32| (zero + x / a_per_count) as u16;
                let b = c.step(&Samples { i_abc: [code(i.a), code(i.b), code(i.c)], ..at_rest(0) });
                if PENDING.swap(false, Ordering::Relaxed) {
                    run_slow(c.slow_cell());
                }
                b
            };
            for _ in 0..CALIBRATION_SAMPLES {
                step(&mut c);
            }
            while c.slow_busy() {
                step(&mut c);
            }
            c.drive_mut(|mut d| d.enable()).unwrap().unwrap();
            // Running at a speed reference that the speed loop's reference ramps to.
            let mut k = 0;
            while c.fast().mode() != Mode::Running || c.slow_busy() {
                step(&mut c);
                k += 1;
                assert!(k < 20_000, "magnetized");
            }
            c.drive_mut(|mut d| d.set_reference(controller_core::drive::Reference::Speed(100.0)))
                .unwrap()
                .unwrap();
            assert_eq!(c.scope().serve(&BoardCommand::ArmCapture(capture)), Some(Reply::Ack));
            let mut adoptions = std::vec::Vec::new();
            for k in 0..CAPTURE_DEPTH {
                let busy = c.slow_busy();
                assert!(!matches!(step(&mut c), Bridge::Off), "period {k}");
                adoptions.push(busy && !c.slow_busy());
            }
            assert_eq!(c.scope().state(), CaptureState::Done);
            let chunks: std::vec::Vec<_> = (0..controller_core::capture::Capture::<CAPTURE_DEPTH>::CHUNKS)
                .map(|i| c.scope().with_capture(|cap| cap.chunk(i)).unwrap().unwrap())
                .collect();
            let signal = move |k: usize, s: usize| {
                let at = (k % 8) * 16 + 4 * s;
                f32::from_le_bytes(chunks[k / 8][at..at + 4].try_into().unwrap())
            };
            (adoptions, signal)
        };
        let (adoptions, at_once) = run(run_slow);
        let (_, apart) = run(deferred);
        let mut moved = 0;
        for (k, &adoption) in adoptions.iter().enumerate() {
            for (s, name) in [(0, "duty"), (1, "the flux estimate"), (2, "i_alpha"), (3, "mode")] {
                assert_eq!(at_once(k, s).to_bits(), apart(k, s).to_bits(), "{name}, sample {k}");
            }
            if k > 0 && at_once(k, 1) != at_once(k - 1, 1) {
                assert!(adoption, "the flux estimate moved at sample {k}, not an adoption");
                moved += 1;
            }
        }
        assert!(moved > 5, "the flux estimate moves at the adoptions: {moved}");
    }

    /// A fork (the benchmarks' copy of a loop) steps as its original, on a slow side of its
    /// own: the original's slow steps do not move the fork's.
    #[test]
    fn a_fork_steps_as_its_original_on_a_slow_side_of_its_own() {
        let mut c = ControlLoop::at_rest_for_tests();
        enable_through_precharge(&mut c);
        let mut fork = c.fork(cell()).unwrap();
        assert!(!core::ptr::eq(c.slow_cell(), fork.slow_cell()));
        for k in 0..200 {
            assert_eq!(c.step(&at_rest(0)), fork.step(&at_rest(0)), "period {k}");
        }
        // The original disabled and stepped alone for three slow periods: its slow side counts
        // them with the bridge off, the fork's (still magnetizing) does not move.
        while c.slow_busy() || fork.slow_busy() {
            let _ = (c.step(&at_rest(0)), fork.step(&at_rest(0)));
        }
        c.drive_mut(|mut d| d.disable()).unwrap();
        for _ in 0..c.config().slow_divider() * 3 {
            let _ = c.step(&at_rest(0));
        }
        while c.slow_busy() {
            let _ = c.step(&at_rest(0));
        }
        assert_eq!(c.drive(|d| d.idle_slow_steps()), Some(3));
        assert_eq!(fork.drive(|d| (d.mode(), d.idle_slow_steps())), Some((Mode::Magnetizing, 0)));
    }

    #[test]
    fn hardware_break_latches_until_cleared_by_command() {
        let mut c = ControlLoop::new(&DRIVE_CONFIG, &board(), cell(), run_slow).unwrap();
        c.calibrate_at_rest();
        c.drive_mut(|mut d| d.enable()).unwrap().unwrap();
        assert!(matches!(c.step(&at_rest(0)), Bridge::Compare(_)));
        let brk = Samples { hardware_break: true, ..at_rest(0) };
        assert_eq!(c.step(&brk), Bridge::Off);
        // The break line released: still latched.
        for _ in 0..100 {
            assert_eq!(c.step(&at_rest(0)), Bridge::Off);
        }
        assert_eq!(c.fast().mode(), Mode::Fault(Fault::HardwareBreak));
        // Enable is refused while faulted; ClearFault then Enable works.
        let stats = LinkStats::default();
        assert_eq!(
            c.drive_mut(|d| link::execute_board(d, &BoardCommand::Enable, &stats)).unwrap(),
            Reply::Nack(NackReason::Faulted)
        );
        assert_eq!(
            c.drive_mut(|d| link::execute_board(d, &BoardCommand::ClearFault, &stats)).unwrap(),
            Reply::Ack
        );
        assert_eq!(
            c.drive_mut(|d| link::execute_board(d, &BoardCommand::Enable, &stats)).unwrap(),
            Reply::Ack
        );
        assert!(matches!(c.step(&at_rest(0)), Bridge::Compare(_)));
    }

    #[test]
    fn encoder_jump_is_encoder_loss_and_wrap_is_not() {
        let mut c = ControlLoop::at_rest_for_tests();
        enable_through_precharge(&mut c);
        c.drive_mut(|mut d| d.set_reference(Reference::Speed(0.0))).unwrap().unwrap();
        let div = u32::from(drive_spec().unwrap().slow_divider);
        // Counter running backwards through the 16-bit wrap, speeding up by one count per read
        // (6 100 rad/s², within the jump check's allowance) to 40 counts per read
        // (≈ 123 rad/s, below the overspeed level): fine.
        let mut enc = 0u16; // where the calibration left the counter
        for k in 0..(60 * div) {
            if k % div == 0 {
                enc = enc.wrapping_sub((k / div).min(40) as u16);
            }
            assert!(matches!(c.step(&at_rest(enc)), Bridge::Compare(_)), "step {k}: {:?}", c.fast().mode());
        }
        assert!(enc > 60_000, "wrapped: {enc}");
        // A jump of 5000 counts between two reads.
        for _ in 0..div {
            let _ = c.step(&at_rest(enc.wrapping_add(5000)));
        }
        assert_eq!(c.fast().mode(), Mode::Fault(Fault::EncoderLoss));
    }

    /// The offset calibration at start-up: the bridge stays off for its 1 024 periods (an
    /// enable from the link is undone), then each channel's mean code is its zero — a
    /// sample at those codes reads 0 A — and the drive runs.
    #[test]
    fn offsets_are_calibrated_with_the_bridge_off() {
        let mut c = ControlLoop::new(&DRIVE_CONFIG, &board(), cell(), run_slow).unwrap();
        let zeros = [2060u16, 2040, 2048];
        // ±1 count of noise, alternating.
        let sample = |k: u32| Samples {
            i_abc: zeros.map(|z| if k.is_multiple_of(2) { z + 1 } else { z - 1 }),
            ..at_rest(0)
        };
        c.drive_mut(|mut d| d.enable()).unwrap().unwrap();
        for k in 0..CALIBRATION_SAMPLES {
            assert_eq!(c.step(&sample(k)), Bridge::Off, "period {k}");
            assert!(matches!(c.fast().mode(), Mode::Idle), "the enable is undone");
        }
        match c.calibration() {
            Calibration::Done(o) => {
                assert_eq!(o.counts, zeros);
                assert!(o.rms_counts.iter().all(|r| (r - 1.0).abs() < 1e-3), "{:?}", o.rms_counts);
            }
            other => panic!("{other:?}"),
        }
        c.drive_mut(|mut d| d.enable()).unwrap().unwrap();
        let div = drive_spec().unwrap().slow_divider;
        let mut out = Bridge::Off;
        for _ in 0..div {
            out = c.step(&Samples { i_abc: zeros, ..at_rest(0) });
        }
        assert!(matches!(out, Bridge::Compare(_)));
        let i = c.telemetry().i_ab_a;
        assert_eq!((i.alpha, i.beta), (0.0, 0.0));
    }

    /// A channel stuck at the rail, or a floating (noisy) one: a fault latched, the channel
    /// named by the calibration, the drive cannot be enabled.
    #[test]
    fn a_bad_channel_fails_the_calibration() {
        let stuck: fn(u32) -> [u16; 3] = |_| [2048, 4095, 2048];
        let floating: fn(u32) -> [u16; 3] = |k| [2048, 2048, if k.is_multiple_of(2) { 2078 } else { 2018 }];
        for (codes, channel) in [(stuck, 1u8), (floating, 2)] {
            let mut c = ControlLoop::new(&DRIVE_CONFIG, &board(), cell(), run_slow).unwrap();
            for k in 0..CALIBRATION_SAMPLES {
                assert_eq!(c.step(&Samples { i_abc: codes(k), ..at_rest(0) }), Bridge::Off);
            }
            match c.calibration() {
                Calibration::Failed(
                    CalibrationError::Offset { channel: ch, .. }
                    | CalibrationError::Noise { channel: ch, .. },
                ) => {
                    assert_eq!(ch, channel)
                }
                other => panic!("{other:?}"),
            }
            // A channel at the rail reads 16.5 A: the supervisor's Overcurrent (it runs in
            // every mode) latches first; a noisy one, the calibration's CurrentSensor.
            let want = if channel == 1 { Fault::Overcurrent } else { Fault::CurrentSensor };
            assert_eq!(c.fast().mode(), Mode::Fault(want));
            assert!(c.drive_mut(|mut d| d.enable()).unwrap().is_err());
            assert_eq!(c.step(&at_rest(0)), Bridge::Off);
        }
    }

    /// The firmware's construction in its static cell ([`ControlLoop::init`]) refuses what
    /// [`ControlLoop::new`] refuses, and otherwise makes the same loop: calibrating at rest,
    /// then stepping as `new`'s does, period for period.
    #[test]
    fn the_loop_made_in_place_is_the_loop_made_by_value() {
        let bad = BoardConfig { pwm_period_counts: 0, ..board() };
        let mut slot = MaybeUninit::uninit();
        assert_eq!(
            ControlLoop::init(&mut slot, cell(), run_slow, &DRIVE_CONFIG, &bad).err(),
            Some(ControlError::Scaling(ScalingError::Period))
        );
        let mut by_value = ControlLoop::new(&DRIVE_CONFIG, &board(), cell(), run_slow).unwrap();
        let in_place = ControlLoop::init(&mut slot, cell(), run_slow, &DRIVE_CONFIG, &board()).unwrap();
        assert!(matches!(in_place.calibration(), Calibration::Running(_)));
        assert_eq!(in_place.snapshot(), by_value.snapshot());
        for k in 0..(CALIBRATION_SAMPLES + 200) {
            let s = Samples { i_abc: [2048 + (k % 5) as u16, 2047, 2049], ..at_rest(k as u16) };
            assert_eq!(in_place.step(&s), by_value.step(&s), "period {k}");
            if k == CALIBRATION_SAMPLES + 10 {
                in_place.drive_mut(|mut d| d.enable()).unwrap().unwrap();
                by_value.drive_mut(|mut d| d.enable()).unwrap().unwrap();
            }
        }
        assert_eq!(in_place.snapshot(), by_value.snapshot());
        assert_eq!(in_place.fast().mode(), by_value.fast().mode());
    }

    #[test]
    fn invalid_board_constants_are_rejected_at_construction() {
        let spec = DRIVE_CONFIG;
        let bad = BoardConfig { pwm_period_counts: 0, ..board() };
        assert_eq!(
            ControlLoop::new(&spec, &bad, cell(), run_slow).unwrap_err(),
            ControlError::Scaling(ScalingError::Period)
        );
        let bad = BoardConfig { current_offset_counts: 5000, ..board() };
        assert_eq!(
            ControlLoop::new(&spec, &bad, cell(), run_slow).unwrap_err(),
            ControlError::Scaling(ScalingError::Offset)
        );
        let bad = BoardConfig { encoder_lines: 0, ..board() };
        assert_eq!(
            ControlLoop::new(&spec, &bad, cell(), run_slow).unwrap_err(),
            ControlError::Encoder(EncoderError::Lines)
        );
        // Issue 19: the timer's period read back must be the board's (embassy's
        // `ComplementaryPwm` with `khz(20)` programmed ARR = 4249, a 20 004.7 Hz PWM; the
        // board's is 4250, 20 000 Hz).
        let b = crate::config::BOARD;
        assert_eq!(b.pwm_period_counts, 4250);
        assert_eq!(check_pwm_period(4250, &b), Ok(()));
        assert_eq!(check_pwm_period(4249, &b), Err(ControlError::PwmPeriod { read: 4249, expected: 4250 }));
    }

    /// The update event must come once per period at the top of the count: RCR 1 read back
    /// and the counter running down after the first event; an event at the bottom, a
    /// repetition counter at 0 (the event twice a period) or no event at all refuse to run.
    #[test]
    fn the_update_event_must_be_at_the_top_once_per_period() {
        assert_eq!(check_update_timing(1, Some(true)), Ok(()));
        for (rcr, down) in [(1, Some(false)), (0, Some(true)), (3, Some(true)), (1, None)] {
            assert_eq!(
                check_update_timing(rcr, down),
                Err(ControlError::UpdateTiming { rcr, down_after_update: down })
            );
        }
    }

    /// Issue 54: two periods running that overran are an overrun fault; one alone, or two
    /// apart, only counted.
    #[test]
    fn two_overruns_running_stop_the_drive_and_one_does_not() {
        let t = LoopTimer::new();
        let p = 8500;
        assert!(!t.record(9000, p), "one overrun");
        assert!(!t.record(1000, p));
        assert!(!t.record(8500, p), "one again, not running");
        assert!(t.record(8600, p), "the second running");
        assert_eq!(t.read().overruns, 3);
    }

    /// The period's work is timed from its update event: at the top the counter turns down
    /// (0 ticks), at the bottom half a period has passed (ARR), counting up again beyond.
    #[test]
    fn the_period_is_timed_from_its_update_event() {
        let arr = 4250;
        assert_eq!(ticks_since_update(arr, true, arr), 0);
        assert_eq!(ticks_since_update(arr - 200, true, arr), 200);
        assert_eq!(ticks_since_update(0, true, arr), u32::from(arr));
        assert_eq!(ticks_since_update(0, false, arr), u32::from(arr));
        assert_eq!(ticks_since_update(300, false, arr), u32::from(arr) + 300);
        // A counter read above ARR (not possible with the preload) reads as the top.
        assert_eq!(ticks_since_update(u16::MAX, true, arr), 0);
    }

    /// The interrupt's timing: the longest step kept, a step of a whole period or more an
    /// overrun (8 500 cycles at 170 MHz and 20 kHz).
    #[test]
    fn the_loop_timer_keeps_the_longest_step_and_counts_overruns() {
        let period = period_cycles(&crate::config::BOARD);
        assert_eq!(period, 8500);
        let t = LoopTimer::new();
        for c in [900, 1200, 800, 8499] {
            assert!(!t.record(c, period));
        }
        assert_eq!(
            t.read(),
            controller_core::link::LoopTiming { cycles_max: 8499, overruns: 0, stack_bytes: 0 }
        );
        assert!(!t.record(8500, period));
        assert!(t.record(20_000, period));
        assert!(!t.record(1000, period));
        assert_eq!(
            t.read(),
            controller_core::link::LoopTiming { cycles_max: 20_000, overruns: 2, stack_bytes: 0 }
        );
    }
}
