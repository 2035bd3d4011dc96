//! Self-commissioning at standstill (issue 20): the measurements a drive makes on a motor it
//! knows nothing about, run from the fast step — the same code on a board, in SIL and in
//! QEMU PIL. The sequence only *measures*; the parameters are estimated from its
//! [`Record`] off the control path (`hil-sim`'s `identify`, in f64), so a PIL run and a SIL
//! run that produce the same record write the same motor file.
//!
//! Sequence ([`Stage`]), bridge off until the bus and offsets pass:
//! 1. **Offsets and bus** ([`OFFSET_PERIODS`] periods, bridge off): the mean of each
//!    phase-current channel is its offset (subtracted from then on); the bus must lie in the
//!    configured range and vary by less than [`BUS_RIPPLE_MAX`] of its mean.
//! 2. **Voltage pulses** along phase a, b and c (then the same pulse reversed, then zero
//!    voltage until the current has decayed): the current must rise along the voltage (a
//!    swapped pair of current channels, an inverted sensor, a phase that carries no current
//!    are refused by name), and the rise gives a first estimate of the transient
//!    inductance L̂σ for the current loop: `V/(di/dt)` with the initial slope from the rise
//!    at half and at the whole pulse, `(4·Δi(t/2) − Δi(t))/t` (Richardson: exact for a rise
//!    that bends quadratically). The pulse starts at [`PULSE_PERIODS`] periods and
//!    [`PULSE_START_FRACTION`] of the linear limit; its voltage doubles up to
//!    [`PULSE_MAX_FRACTION`], then its length up to [`PULSE_MAX_PERIODS`], until the current
//!    rises by a quarter of the test current.
//! 3. **Three DC levels** on the α axis (phase a against b and c), current-controlled:
//!    0 → I/2 → I → I/2, each held for `level_time_s`. At a standstill a current along one
//!    axis makes no torque. The commanded voltage is recorded in [`BLOCKS`] blocks of
//!    geometrically growing length (the first two periods, the last ≈ a sixth of the level),
//!    which resolve a rotor time constant from a few milliseconds to a second. The steady
//!    voltages give R_s and the inverter's voltage error (two levels: the error, constant
//!    while the currents keep their sign, cancels); each step's decay gives the rotor
//!    time constant and the referred rotor resistance (the DC-decay test).
//! 4. **Two sinusoidal injections** around I/2 (100 and 200 periods per cycle, amplitude
//!    [`INJECTION_FRACTION`]·I): lock-in sums of the voltage and the current over whole
//!    cycles give the impedance at those frequencies, hence the transient inductance σL_s.
//! 5. **A slow rotating field**, only if the motor may turn ([`CommissionSpec::rotate`]):
//!    the current vector I/2 turns, its frequency ramped to [`ROTATION_HZ`] over
//!    [`ROTATION_RAMP_S`], held for [`ROTATION_HOLD_S`] and ramped back to zero over
//!    [`ROTATION_STOP_S`]. The rotor follows with a small slip. The encoder's turning is
//!    recorded at the end of each of [`ROTATION_BLOCKS`] equal blocks of the ramp and the
//!    hold: against the field's, it tells the encoder's direction and line count (with the
//!    motor's pole pairs, on the host), and the speed it gives, with the torque the
//!    identified model gives for the impressed current, the inertia and friction. It
//!    ramps back to zero only if the no-load test cannot start (a rotor that did not turn).
//! 6. **The no-load test at rated flux** ([`Stage::NoLoad`], whenever the field turns; module
//!    [`no_load`]): from the slow field's hold the field accelerates, its lead over the
//!    rotor bounded, to the test frequency, with the current amplitude that gives the rated
//!    stator flux; there the loops' voltage and current are recorded in the field's frame,
//!    whence the magnetizing inductance *at rated flux* (on the host); then the field brings
//!    the rotor back to rest.
//!
//! The current loops (α and β, the latter held at zero) are PI loops designed from L̂σ:
//! crossover `ω_c` = 2π·f_pwm/[`LOOP_BANDWIDTH_DIVIDER`], the integral's zero a decade
//! below. Guard rails: the phase currents stay below the configured limit (else
//! [`Refusal::Overcurrent`]), the loops' voltage below [`VOLTAGE_LIMIT_FRACTION`] of the
//! linear limit (else [`Refusal::VoltageLimit`] after [`SATURATION_PERIODS`] in a row), the bus within its range, every
//! measurement finite, and every wait has a timeout; any refusal turns the bridge off for
//! good (a new [`Commissioning`] starts over).
//!
//! The code, by stage: `pulses` (1–2: offsets, bus, pulses, the current loops' design),
//! `levels` (3–4: the DC levels and the injections), `rotation` (5), [`no_load`] (6); the
//! sequence's state and its step here; what it measured and its bytes in `record`
//! ([`Record`]).

use crate::drive::{Measurements, PhaseCommand};
use crate::frames::{Abc, AlphaBeta};
use crate::pi::{PiConfig, PiState};
use crate::svpwm;

mod levels;
pub mod no_load;
mod pulses;
mod record;
mod rotation;

pub use no_load::{
    CURVE_FLUX_FRACTIONS, CURVE_LEVELS, CURVE_WINDOWS, NO_LOAD_WINDOWS, NoLoadRecord, NoLoadWindow,
};
pub use record::{InjectionRecord, LevelRecord, PulseRecord, RECORD_BYTES, Record, RotationRecord};

/// Periods of the offset and bus measurement (≥ 1 024, issue 19's calibration).
pub const OFFSET_PERIODS: u32 = 2048;
/// The bus may vary by this fraction of its mean during the offset measurement.
pub const BUS_RIPPLE_MAX: f32 = 0.05;
/// Periods of one voltage pulse (and of its reversal).
pub const PULSE_PERIODS: u32 = 16;
/// Longest pulse, periods (25.6 ms at 20 kHz).
pub const PULSE_MAX_PERIODS: u32 = 512;
/// First pulse voltage, a fraction of the linear limit V_dc/√3; doubled up to
/// [`PULSE_MAX_FRACTION`].
pub const PULSE_START_FRACTION: f32 = 0.01;
/// Largest pulse voltage tried: above it, a motor that carries no current is refused.
pub const PULSE_MAX_FRACTION: f32 = 0.64;
/// The current after a pulse must have decayed below this fraction of the test current…
pub const REST_CURRENT_FRACTION: f32 = 0.02;
/// …within this many periods (one second at 20 kHz).
pub const REST_MAX_PERIODS: u32 = 20_000;
/// The measured current must point within this angle of the pulse (cosine of 30°).
pub const DIRECTION_COS_MIN: f32 = 0.866;
/// Current-loop crossover: 2π·f_pwm divided by this (1 kHz at 20 kHz: 27° of phase for the
/// 1.5 periods of delay, and a margin for L̂σ's error).
pub const LOOP_BANDWIDTH_DIVIDER: f32 = 20.0;
/// The loops' voltage must stay below this fraction of the linear limit.
pub const VOLTAGE_LIMIT_FRACTION: f32 = 0.9;
/// A step of the reference saturates the loops for a few periods; this many in a row is
/// [`Refusal::VoltageLimit`] (10 ms at 20 kHz).
pub const SATURATION_PERIODS: u32 = 200;
/// Recorded blocks per DC level.
pub const BLOCKS: usize = 48;
/// Length of the first block, periods.
pub const FIRST_BLOCK_PERIODS: f32 = 2.0;
/// Periods over which the current's lag after a level step is summed.
pub const LAG_PERIODS: u32 = 64;
/// Injection amplitude, a fraction of the test current.
pub const INJECTION_FRACTION: f32 = 0.2;
/// Periods per cycle of each injection.
pub const INJECTION_PERIODS: [u32; 2] = [100, 200];
/// Whole cycles before the lock-in sums start…
pub const INJECTION_SETTLE_CYCLES: u32 = 4;
/// …and the cycles summed.
pub const INJECTION_CYCLES: u32 = 16;
/// DC levels: multiples of the test current.
pub const LEVELS: [f32; 3] = [0.5, 1.0, 0.5];
/// Electrical frequency of the rotating field's hold, Hz (slow: the back-EMF stays small and
/// the rotor, unloaded, keeps up with a small slip).
pub const ROTATION_HZ: f32 = 2.0;
/// Time the field's frequency ramps up, s…
pub const ROTATION_RAMP_S: f32 = 1.0;
/// …is held, s…
pub const ROTATION_HOLD_S: f32 = 2.0;
/// …and ramps back to zero, braking the rotor, s.
pub const ROTATION_STOP_S: f32 = 1.0;
/// Recorded blocks over the ramp and the hold.
pub const ROTATION_BLOCKS: usize = 60;

/// What the user states about the test (validated by [`CommissionConfig::new`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CommissionSpec {
    /// PWM frequency, Hz.
    pub pwm_hz: f32,
    /// Test current I: the higher DC level, A (the motor's rated peak current is a good
    /// choice: large against the inverter's dead-time error, safe for the winding).
    pub test_current_a: f32,
    /// Any phase current above this refuses, A (≥ 1.5·I: the injection and one period of
    /// a pulse's overshoot fit below it).
    pub current_limit_a: f32,
    /// Accepted DC bus, V.
    pub vdc_min_v: f32,
    /// Accepted DC bus, V.
    pub vdc_max_v: f32,
    /// Time each DC level is held, s (≥ 4 rotor time constants for a good decay fit).
    pub level_time_s: f32,
    /// The motor may turn (nothing coupled that must not move): end with the rotating
    /// field (stage 5) and the no-load test at rated flux (stage 6).
    pub rotate: bool,
    /// Rated stator flux linkage, Wb (peak, per phase: `√2·V_LL/(√3·2π·f)` from the nameplate's
    /// rated line voltage V_LL and frequency f), the no-load test's flux. Used only with
    /// [`CommissionSpec::rotate`].
    pub rated_flux_wb: f32,
    /// The no-load test's field frequency, Hz (electrical; lowered if the bus cannot give
    /// rated flux there, [`no_load::NO_LOAD_VOLTAGE_FRACTION`]). A quarter of the rated
    /// frequency keeps the test short and the rotor slow. Used only with
    /// [`CommissionSpec::rotate`].
    pub no_load_hz: f32,
    /// With [`CommissionSpec::rotate`]: after the rated flux, the no-load test measures the
    /// magnetizing curve at 0.3…1.2 of it ([`no_load::CURVE_FLUX_FRACTIONS`]; a motor that
    /// saturates). It costs 10…25 s more of rotation.
    pub curve: bool,
}

/// Why a [`CommissionSpec`] was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CommissionSpecError {
    /// PWM frequency not finite or outside 1…100 kHz.
    PwmFrequency,
    /// Test current not finite and positive.
    TestCurrent,
    /// Current limit below 1.5× the test current (or not finite).
    CurrentLimit,
    /// Bus range empty, negative or not finite.
    BusRange,
    /// Level time shorter than [`BLOCKS`]·[`FIRST_BLOCK_PERIODS`]·2 periods or over 60 s.
    LevelTime,
    /// With [`CommissionSpec::rotate`]: a rated flux that is not finite and positive, or a
    /// no-load frequency outside [`ROTATION_HZ`] … 400 Hz.
    NoLoad,
    /// [`CommissionSpec::curve`] without [`CommissionSpec::rotate`]: the curve is measured
    /// on the turning rotor's no-load test.
    CurveWithoutRotation,
}

/// A validated commissioning configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CommissionConfig {
    spec: CommissionSpec,
    ts_s: f32,
    level_periods: u32,
    block_end: [u32; BLOCKS],
}

impl CommissionConfig {
    /// Validates `spec` and lays out the record's blocks: `BLOCKS` blocks whose lengths grow
    /// by a common ratio from [`FIRST_BLOCK_PERIODS`] and add up to the level.
    pub fn new(spec: CommissionSpec) -> Result<Self, CommissionSpecError> {
        let finite_pos = |x: f32| x.is_finite() && x > 0.0;
        if !(spec.pwm_hz.is_finite() && (1e3..=1e5).contains(&spec.pwm_hz)) {
            return Err(CommissionSpecError::PwmFrequency);
        }
        if !finite_pos(spec.test_current_a) {
            return Err(CommissionSpecError::TestCurrent);
        }
        if !(spec.current_limit_a.is_finite() && spec.current_limit_a >= 1.5 * spec.test_current_a) {
            return Err(CommissionSpecError::CurrentLimit);
        }
        if !(finite_pos(spec.vdc_min_v) && spec.vdc_max_v.is_finite() && spec.vdc_min_v < spec.vdc_max_v) {
            return Err(CommissionSpecError::BusRange);
        }
        let ts_s = 1.0 / spec.pwm_hz;
        let periods = spec.level_time_s * spec.pwm_hz;
        let least = 2.0 * FIRST_BLOCK_PERIODS * BLOCKS as f32;
        if !(periods.is_finite() && periods >= least && spec.level_time_s <= 60.0) {
            return Err(CommissionSpecError::LevelTime);
        }
        if spec.rotate
            && !(finite_pos(spec.rated_flux_wb)
                && spec.no_load_hz.is_finite()
                && (ROTATION_HZ..=400.0).contains(&spec.no_load_hz))
        {
            return Err(CommissionSpecError::NoLoad);
        }
        if spec.curve && !spec.rotate {
            return Err(CommissionSpecError::CurveWithoutRotation);
        }
        let level_periods = periods as u32;
        // The ratio r with FIRST·(r^B − 1)/(r − 1) = level: bisection (the sum grows with r).
        let total = |r: f32| {
            let mut s = 0.0f32;
            for _ in 0..BLOCKS {
                s = s * r + FIRST_BLOCK_PERIODS;
            }
            s
        };
        let (mut lo, mut hi) = (1.0f32, 2.0f32);
        for _ in 0..40 {
            let mid = 0.5 * (lo + hi);
            if total(mid) < level_periods as f32 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let mut block_end = [0u32; BLOCKS];
        let mut s = 0.0f32;
        let mut prev = 0u32;
        for end in block_end.iter_mut() {
            s = s * hi + FIRST_BLOCK_PERIODS;
            let e = ((s + 0.5) as u32).max(prev + 1).min(level_periods);
            *end = e;
            prev = e;
        }
        if let Some(last) = block_end.last_mut() {
            *last = level_periods;
        }
        Ok(Self { spec, ts_s, level_periods, block_end })
    }

    /// The no-load test measures the magnetizing curve ([`CommissionSpec::curve`]).
    pub fn curve(&self) -> bool {
        self.spec.curve
    }

    /// The spec.
    pub fn spec(&self) -> &CommissionSpec {
        &self.spec
    }

    /// PWM period, s.
    pub fn ts_s(&self) -> f32 {
        self.ts_s
    }

    /// Periods of each DC level.
    pub fn level_periods(&self) -> u32 {
        self.level_periods
    }

    /// End of each block (exclusive), periods from the level's step.
    pub fn block_end(&self) -> &[u32; BLOCKS] {
        &self.block_end
    }

    /// An upper bound of the whole sequence, periods (every pulse retried, every rest to its
    /// timeout) — what a simulation of it must allow.
    pub fn max_periods(&self) -> u64 {
        let doublings = 7 + 5; // voltage 0.01 · 2^6 = 0.64, then length 16 · 2^5 = 512
        let pulses = 3 * doublings * (2 * PULSE_MAX_PERIODS + REST_MAX_PERIODS);
        let injections: u32 =
            INJECTION_PERIODS.iter().map(|n| n * (INJECTION_SETTLE_CYCLES + INJECTION_CYCLES)).sum();
        let rotation = if self.spec.rotate {
            ((ROTATION_RAMP_S + ROTATION_HOLD_S + ROTATION_STOP_S) * self.spec.pwm_hz) as u64
                + 1
                + no_load::max_periods(self.spec.pwm_hz)
        } else {
            0
        };
        u64::from(OFFSET_PERIODS)
            + u64::from(pulses)
            + 3 * u64::from(self.level_periods)
            + u64::from(injections)
            + rotation
    }
}

/// The largest offset a current channel may read with the bridge off, as a share of the
/// test current: beyond it the sequence's small currents would be the offset's.
pub const OFFSET_SHARE_MAX: f32 = 0.1;

/// Why the sequence stopped (the bridge is off).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Refusal {
    /// The bus is outside the configured range, V.
    BusOutOfRange(f32),
    /// The bus varied by more than [`BUS_RIPPLE_MAX`] of its mean, V (max − min).
    BusUnsteady(f32),
    /// A current channel read more than [`OFFSET_SHARE_MAX`] of the test current with the
    /// bridge off, A.
    OffsetTooLarge {
        /// Channel (0 = a).
        channel: u8,
        /// Its mean, A.
        offset_a: f32,
    },
    /// No current after the largest pulse: an open lead, no motor, or dead sensors.
    NoCurrent,
    /// The currents answer phase b's pulse along phase c and the reverse: two current
    /// channels (or the sensors' wiring to the legs) are swapped.
    PhaseOrder,
    /// Every current points against its pulse: the current sensors' sign is inverted.
    CurrentSign,
    /// The current after the pulse along `phase` pointed elsewhere (one inverted or dead
    /// sensor, a broken lead).
    CurrentDirection {
        /// Phase of the pulse (0 = a).
        phase: u8,
    },
    /// The current did not decay after a pulse within [`REST_MAX_PERIODS`].
    NoDecay,
    /// A phase current above the limit, A.
    Overcurrent(f32),
    /// The current loop needed more voltage than [`VOLTAGE_LIMIT_FRACTION`] of the linear
    /// limit for [`SATURATION_PERIODS`] in a row (a test current too high for this motor's resistance on this bus).
    VoltageLimit,
    /// A measurement or a computed voltage was not finite.
    NonFinite,
    /// Stopped by the caller.
    Aborted,
    /// In the no-load test, the rotor did not follow the field to the test frequency within
    /// [`no_load::NO_LOAD_RAMP_MAX_S`] (a load coupled, a brake on): the field's frequency
    /// reached, Hz.
    RotorStalled(f32),
}

/// The sequence's stage (for progress displays: [`Stage::index`] of [`Stage::COUNT`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Stage {
    /// Offsets and bus, bridge off.
    Offsets,
    /// Voltage pulse along a phase (0 = a), direction and L̂σ.
    Pulse(u8),
    /// DC level 0…2.
    Level(u8),
    /// Sinusoidal injection 0…1.
    Injection(u8),
    /// The slow rotating field.
    Rotate,
    /// The no-load test at rated flux.
    NoLoad,
    /// Finished: [`Commissioning::record`] holds the measurements.
    Done,
    /// Refused: the bridge is off.
    Refused(Refusal),
}

impl Stage {
    /// Stages of a full sequence.
    pub const COUNT: u8 = 11;

    /// 0-based position of the stage in the sequence ([`Stage::COUNT`] when finished or
    /// refused).
    pub fn index(self) -> u8 {
        match self {
            Stage::Offsets => 0,
            Stage::Pulse(p) => 1 + p,
            Stage::Level(l) => 4 + l,
            Stage::Injection(j) => 7 + j,
            Stage::Rotate => 9,
            Stage::NoLoad => 10,
            Stage::Done | Stage::Refused(_) => Self::COUNT,
        }
    }

    /// The sequence is over: finished or refused (the bridge stays off).
    pub fn is_over(self) -> bool {
        matches!(self, Stage::Done | Stage::Refused(_))
    }
}

/// Output of one step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CommissionOutput {
    /// Bridge command for the next period.
    pub phases: PhaseCommand,
    /// Stage after this step.
    pub stage: Stage,
    /// The stationary-frame voltage commanded, V (zero with the bridge off).
    pub v_ab_v: AlphaBeta,
    /// The α-current reference, A.
    pub i_ref_alpha_a: f32,
}

/// Pulse sub-phase.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum PulsePhase {
    Rise,
    Reverse,
    Rest,
}

/// The sequence's state.
#[derive(Clone, Debug)]
pub struct Commissioning {
    cfg: CommissionConfig,
    stage: Stage,
    /// Periods into the present stage (or sub-phase).
    k: u32,
    record: Record,
    // Offsets and bus.
    sum_a: [f32; 3],
    sum2_a: [f32; 3],
    vdc_sum_v: f32,
    vdc_min_v: f32,
    vdc_max_v: f32,
    // Pulses.
    pulse_phase: PulsePhase,
    v_pulse_v: f32,
    pulse_periods: u32,
    i_start: AlphaBeta,
    i_half: AlphaBeta,
    // Levels and injections.
    loops: Option<PiConfig<f32>>,
    pi_alpha: PiState<f32>,
    pi_beta: PiState<f32>,
    block: usize,
    block_v: f32,
    block_i: f32,
    block_n: u32,
    i_ref_prev_a: f32,
    /// Consecutive periods at the voltage limit.
    saturated: u32,
    /// The rotating field's angle, rad, and the last encoder reading, rad.
    theta_e_rad: f32,
    theta_m_prev_rad: f32,
    /// The no-load test's state.
    no_load: no_load::NoLoadState,
}

impl Commissioning {
    /// A sequence about to start (bridge off).
    pub fn new(cfg: CommissionConfig) -> Self {
        Self {
            cfg,
            stage: Stage::Offsets,
            k: 0,
            record: Record::default(),
            sum_a: [0.0; 3],
            sum2_a: [0.0; 3],
            vdc_sum_v: 0.0,
            vdc_min_v: f32::INFINITY,
            vdc_max_v: f32::NEG_INFINITY,
            pulse_phase: PulsePhase::Rise,
            v_pulse_v: 0.0,
            pulse_periods: PULSE_PERIODS,
            i_start: AlphaBeta::default(),
            i_half: AlphaBeta::default(),
            loops: None,
            pi_alpha: PiState::default(),
            pi_beta: PiState::default(),
            block: 0,
            block_v: 0.0,
            block_i: 0.0,
            block_n: 0,
            i_ref_prev_a: 0.0,
            saturated: 0,
            theta_e_rad: 0.0,
            theta_m_prev_rad: 0.0,
            no_load: no_load::NoLoadState::default(),
        }
    }

    /// The configuration.
    pub fn config(&self) -> &CommissionConfig {
        &self.cfg
    }

    /// The present stage.
    pub fn stage(&self) -> Stage {
        self.stage
    }

    /// The measurements, once the sequence is [`Stage::Done`].
    pub fn record(&self) -> Option<&Record> {
        (self.stage == Stage::Done).then_some(&self.record)
    }

    /// Stop now: the bridge goes off and stays off ([`Refusal::Aborted`]).
    pub fn abort(&mut self) {
        if self.stage != Stage::Done {
            self.refuse(Refusal::Aborted);
        }
    }

    fn refuse(&mut self, r: Refusal) {
        if !matches!(self.stage, Stage::Refused(_)) {
            self.stage = Stage::Refused(r);
        }
    }

    fn off(&self) -> CommissionOutput {
        CommissionOutput {
            phases: PhaseCommand::Off,
            stage: self.stage,
            v_ab_v: AlphaBeta::default(),
            i_ref_alpha_a: 0.0,
        }
    }

    /// One PWM period.
    pub fn step(&mut self, m: &Measurements) -> CommissionOutput {
        if self.stage.is_over() {
            return self.off();
        }
        if !(m.i_abc_a.is_finite() && m.vdc_v.is_finite()) {
            self.refuse(Refusal::NonFinite);
            return self.off();
        }
        let spec = self.cfg.spec;
        if self.stage != Stage::Offsets {
            if !(spec.vdc_min_v..=spec.vdc_max_v).contains(&m.vdc_v) {
                self.refuse(Refusal::BusOutOfRange(m.vdc_v));
                return self.off();
            }
            let peak = m.i_abc_a.a.abs().max(m.i_abc_a.b.abs()).max(m.i_abc_a.c.abs());
            if peak > spec.current_limit_a {
                self.refuse(Refusal::Overcurrent(peak));
                return self.off();
            }
        }
        let o = self.record.offsets_a;
        let [oa, ob, oc] = o;
        let i = Abc { a: m.i_abc_a.a - oa, b: m.i_abc_a.b - ob, c: m.i_abc_a.c - oc }.clarke();
        let v = match self.stage {
            Stage::Offsets => {
                self.offsets(m);
                return self.off();
            }
            Stage::Pulse(p) => self.pulse(p, i, m.vdc_v),
            Stage::Level(l) => self.level(l, i, m.vdc_v),
            Stage::Injection(j) => self.injection(j, i, m.vdc_v),
            Stage::Rotate => self.rotate(i, m),
            Stage::NoLoad => self.no_load(i, m),
            Stage::Done | Stage::Refused(_) => None,
        };
        let Some((v, i_ref)) = v else {
            return self.off();
        };
        if !(v.alpha.is_finite() && v.beta.is_finite()) {
            self.refuse(Refusal::NonFinite);
            return self.off();
        }
        let modulation = svpwm::modulate(v, m.vdc_v);
        if self.stage.is_over() {
            return self.off();
        }
        CommissionOutput {
            phases: PhaseCommand::Duty(modulation.duty),
            stage: self.stage,
            v_ab_v: modulation.v_applied,
            i_ref_alpha_a: i_ref,
        }
    }

    fn next(&mut self, stage: Stage) {
        self.stage = stage;
        self.k = 0;
        self.pulse_phase = PulsePhase::Rise;
    }

    /// The current loops on `i_ref` along α (β at zero); `None` (refused) when they need
    /// more than the voltage limit.
    fn regulate(&mut self, i_ref: f32, i: AlphaBeta, vdc_v: f32) -> Option<AlphaBeta> {
        self.regulate_ab(AlphaBeta { alpha: i_ref, beta: 0.0 }, i, vdc_v)
    }

    /// The current loops on the vector `i_ref`.
    fn regulate_ab(&mut self, i_ref: AlphaBeta, i: AlphaBeta, vdc_v: f32) -> Option<AlphaBeta> {
        let loops = self.loops?;
        let limit = VOLTAGE_LIMIT_FRACTION * svpwm::linear_limit_v(vdc_v);
        let alpha = loops.update_limited(&mut self.pi_alpha, i_ref.alpha - i.alpha, -limit, limit);
        let beta = loops.update_limited(&mut self.pi_beta, i_ref.beta - i.beta, -limit, limit);
        if alpha.abs() >= limit || beta.abs() >= limit {
            self.saturated += 1;
            if self.saturated > SATURATION_PERIODS {
                self.refuse(Refusal::VoltageLimit);
                return None;
            }
        } else {
            self.saturated = 0;
        }
        Some(AlphaBeta { alpha, beta })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The inverse-Γ model at standstill along one axis (the T-model's terminal behaviour):
    /// `v = R_s·i + L_σ·di/dt + dψ/dt`, `dψ/dt = R_R·i − ψ/T_r`, integrated exactly enough
    /// (Euler with 20 substeps) for the sequence's logic; accuracy is `hil-sim`'s job.
    #[derive(Clone, Copy)]
    struct Motor {
        rs: f64,
        l_sigma: f64,
        rr: f64,
        tr: f64,
    }

    fn spec() -> CommissionSpec {
        CommissionSpec {
            pwm_hz: 20_000.0,
            test_current_a: 1.0,
            current_limit_a: 2.0,
            vdc_min_v: 200.0,
            vdc_max_v: 400.0,
            level_time_s: 0.5,
            rotate: false,
            rated_flux_wb: 0.823,
            no_load_hz: 15.0,
            curve: false,
        }
    }

    /// Runs the sequence; `swap` exchanges the b and c current channels, `sign` multiplies
    /// every reading.
    fn run(motor: Motor, swap: bool, sign: f32) -> Commissioning {
        run_spec(spec(), motor, swap, sign)
    }

    fn run_spec(spec: CommissionSpec, motor: Motor, swap: bool, sign: f32) -> Commissioning {
        let cfg = CommissionConfig::new(spec).unwrap();
        let mut c = Commissioning::new(cfg);
        let ts = 1.0 / 20_000.0;
        let (mut i, mut psi) = ([0.0f64; 2], [0.0f64; 2]);
        let mut v_next = [0.0f64; 2];
        for _ in 0..cfg.max_periods() {
            let abc = AlphaBeta { alpha: i[0] as f32, beta: i[1] as f32 }.inverse_clarke();
            let abc = if swap { Abc { a: abc.a, b: abc.c, c: abc.b } } else { abc };
            let m = Measurements {
                i_abc_a: Abc { a: sign * abc.a, b: sign * abc.b, c: sign * abc.c },
                vdc_v: 310.0,
                ..Default::default()
            };
            let out = c.step(&m);
            let v = v_next;
            v_next = match out.phases {
                PhaseCommand::Off => [0.0; 2],
                PhaseCommand::Duty(_) => [f64::from(out.v_ab_v.alpha), f64::from(out.v_ab_v.beta)],
            };
            let h = ts / 20.0;
            for _ in 0..20 {
                for ax in 0..2 {
                    let dpsi = motor.rr * i[ax] - psi[ax] / motor.tr;
                    let di = (v[ax] - motor.rs * i[ax] - dpsi) / motor.l_sigma;
                    psi[ax] += h * dpsi;
                    i[ax] += h * di;
                }
            }
            if c.stage().is_over() {
                break;
            }
        }
        c
    }

    const MOTOR: Motor = Motor { rs: 16.2, l_sigma: 0.1, rr: 20.8, tr: 0.065 };

    #[test]
    fn blocks_grow_geometrically_and_cover_the_level() {
        let cfg = CommissionConfig::new(spec()).unwrap();
        let e = cfg.block_end();
        assert_eq!(e[0], 2);
        assert_eq!(e[BLOCKS - 1], cfg.level_periods());
        assert!(e.windows(2).all(|w| w[0] < w[1]), "{e:?}");
        let last = e[BLOCKS - 1] - e[BLOCKS - 2];
        assert!(last > 100 && last < cfg.level_periods() / 4, "{last}");
    }

    #[test]
    fn a_healthy_motor_completes_with_a_plausible_record() {
        let c = run(MOTOR, false, 1.0);
        assert_eq!(c.stage(), Stage::Done);
        let r = c.record().unwrap();
        // L̂σ from the pulses' initial slope: within 10 % of σL.
        assert!((r.l_sigma_pulse_h - 0.1).abs() < 0.01, "{}", r.l_sigma_pulse_h);
        // The levels settle to R_s·I (no inverter error in this model): last block.
        for lv in &r.levels {
            let v = lv.v_alpha_v[BLOCKS - 1];
            assert!((v - 16.2 * lv.i_ref_a).abs() < 0.05 * 16.2 * lv.i_ref_a, "{v} at {}", lv.i_ref_a);
        }
        // The first block of the up-step carries R_s·I + R_R·ΔI (the decay's start).
        let up = &r.levels[1];
        let expected = 16.2 + 20.8 * 0.5;
        assert!((up.v_alpha_v[8] - expected).abs() < 0.2 * 20.8 * 0.5, "{}", up.v_alpha_v[8]);
        assert!(r.injections.iter().all(|j| j.i_sin_cos[0] > 0.0), "{:?}", r.injections);
    }

    #[test]
    fn swapped_channels_inverted_sensors_and_no_motor_are_refused_by_name() {
        assert_eq!(run(MOTOR, true, 1.0).stage(), Stage::Refused(Refusal::PhaseOrder));
        assert_eq!(run(MOTOR, false, -1.0).stage(), Stage::Refused(Refusal::CurrentSign));
        // No motor: an enormous inductance and resistance carry no current.
        let open = Motor { rs: 1e6, l_sigma: 1e3, rr: 1.0, tr: 1.0 };
        assert_eq!(run(open, false, 1.0).stage(), Stage::Refused(Refusal::NoCurrent));
        // A test current this motor cannot carry on 310 V: the voltage limit.
        let hot = Motor { rs: 250.0, ..MOTOR };
        assert_eq!(run(hot, false, 1.0).stage(), Stage::Refused(Refusal::VoltageLimit));
    }

    #[test]
    fn a_record_crosses_as_bytes_bit_for_bit() {
        let c = run(MOTOR, false, 1.0);
        let r = c.record().unwrap();
        let mut buf = [0u8; RECORD_BYTES];
        assert_eq!(r.write_bytes(&mut buf), Some(RECORD_BYTES));
        assert_eq!(Record::read_bytes(&buf).as_ref(), Some(r));
        assert_eq!(r.write_bytes(&mut buf[..RECORD_BYTES - 1]), None);
        assert_eq!(Record::read_bytes(&buf[1..]), None);
        // Every word is a field: a record of distinct values round-trips too.
        let mut k = 0u32;
        let mut distinct = Record::default();
        distinct.visit_mut(&mut |x: &mut f32| {
            k += 1;
            *x = k as f32;
        });
        assert_eq!(4 * k as usize, RECORD_BYTES);
        distinct.write_bytes(&mut buf).unwrap();
        assert_eq!(Record::read_bytes(&buf), Some(distinct));
    }

    #[test]
    fn bad_specs_are_refused() {
        let bad = |f: fn(&mut CommissionSpec)| {
            let mut s = spec();
            f(&mut s);
            CommissionConfig::new(s).unwrap_err()
        };
        assert_eq!(bad(|s| s.pwm_hz = f32::NAN), CommissionSpecError::PwmFrequency);
        assert_eq!(bad(|s| s.test_current_a = 0.0), CommissionSpecError::TestCurrent);
        assert_eq!(bad(|s| s.current_limit_a = 1.2), CommissionSpecError::CurrentLimit);
        assert_eq!(bad(|s| s.vdc_max_v = 100.0), CommissionSpecError::BusRange);
        assert_eq!(bad(|s| s.level_time_s = 1e-3), CommissionSpecError::LevelTime);
        assert_eq!(bad(|s| s.level_time_s = 1e9), CommissionSpecError::LevelTime);
        // The no-load test's nameplate matters only if the motor may turn.
        let mut s = spec();
        s.rated_flux_wb = f32::NAN;
        assert!(CommissionConfig::new(s).is_ok());
        s.rotate = true;
        assert_eq!(CommissionConfig::new(s).unwrap_err(), CommissionSpecError::NoLoad);
        s.rated_flux_wb = 0.8;
        s.no_load_hz = 1.0;
        assert_eq!(CommissionConfig::new(s).unwrap_err(), CommissionSpecError::NoLoad);
    }

    /// A rotor that does not turn (this model's encoder reads 0): the slow field ramps down
    /// and the sequence ends without the no-load test, whose record stays empty (the host
    /// names the encoder). The sequence's own set-up estimates from the DC levels are what
    /// the no-load test would use: L̂_s within 5 % and T̂_r within 10 % of the model's.
    #[test]
    fn a_rotor_that_does_not_turn_skips_the_no_load_test() {
        let c = run_spec(CommissionSpec { rotate: true, ..spec() }, MOTOR, false, 1.0);
        assert_eq!(c.stage(), Stage::Done);
        let r = c.record().unwrap();
        assert_eq!(r.no_load, NoLoadRecord::default());
        assert!(r.rotation.theta_m_rad.iter().all(|&x| x == 0.0));
        let (rs, ls, tr) = c.level_estimates().unwrap();
        let l_s = MOTOR.l_sigma + MOTOR.rr * MOTOR.tr;
        assert!((f64::from(rs) / MOTOR.rs - 1.0).abs() < 0.01, "R̂_s {rs}");
        assert!((f64::from(ls) / l_s - 1.0).abs() < 0.05, "L̂_s {ls} against {l_s}");
        assert!((f64::from(tr) / MOTOR.tr - 1.0).abs() < 0.10, "T̂_r {tr}");
    }

    #[test]
    fn a_bus_out_of_range_is_refused_with_the_bridge_off() {
        let mut c = Commissioning::new(CommissionConfig::new(spec()).unwrap());
        let m = Measurements { vdc_v: 150.0, ..Default::default() };
        for _ in 0..OFFSET_PERIODS {
            assert_eq!(c.step(&m).phases, PhaseCommand::Off);
        }
        assert_eq!(c.stage(), Stage::Refused(Refusal::BusOutOfRange(150.0)));
        assert_eq!(c.step(&m).phases, PhaseCommand::Off);
    }
}
