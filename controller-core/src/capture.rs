//! A triggered capture — a scope in the drive (issue 19).
//!
//! Four chosen signals of every `decimation`-th control period go into a ring buffer of
//! `DEPTH` samples in RAM. Armed, the capture records continuously and watches its trigger;
//! when it fires, it takes the samples that complete the record and stops: the record holds
//! `pre_samples` samples before the trigger's sample, the trigger's sample, and the rest
//! after it. The link reads the finished record out in chunks ([`Capture::chunk`], the
//! `ArmCapture` / `ReadCapture` commands) and `hil-sim link … capture` writes it as CSV and
//! SVG.
//!
//! The signals are what the control step had and decided: its [`Measurements`] and its
//! [`FastOutput`] ([`Signal`]), and the drive's signals ([`Telemetry`]), read from a
//! [`Source`] only for a recorded sample. The firmware records after every step in the
//! control interrupt, the drive's signals one by one with the slow part of the plan in force
//! ([`FastPeriod`]); the processor-in-the-loop server after every `Step`, the whole drive's
//! telemetry ([`Period`]), so a PIL run's capture is the simulation's trace, bit for bit
//! (`hil-sim/tests/pil.rs`). Recording costs a compare while nothing is armed or the record
//! is finished (`cargo xtask qemu`: `cost part:capture_idle`, `part:capture_sample` for a
//! recorded sample; docs/performance.md).
//!
//! A level trigger fires on the first recorded sample that reaches the level from the other
//! side — a signal resting exactly on it fires when it leaves (a reference at 0 stepping
//! up fires `rising` through 0) — and only once the pre-trigger samples are in: a crossing
//! within the first `pre_samples` samples after arming is not the trigger.
//!
//! Configuration apart from state: [`Capture::arm`] validates a [`CaptureSpec`] against the
//! buffer's depth once; [`Capture::record`] never checks anything.

use crate::drive::{FastOutput, FastSide, Measurements, PhaseCommand, Telemetry, TelemetryField};

/// Signals per sample.
pub const CHANNELS: usize = 4;
/// The depth the firmware and the processor-in-the-loop server record (one source): 256
/// samples of 4 signals, 4 KiB of RAM; 12.8 ms of the 20 kHz loop at full rate, longer
/// decimated.
pub const RECORD_SAMPLES: usize = 256;
/// Samples per chunk of the read-out: 8 samples × 4 channels × 4 bytes = 128 bytes, one
/// link reply ([`crate::link::RECORD_CHUNK_BYTES`]).
pub const CHUNK_SAMPLES: usize = 8;
/// The deepest record the link can read out: its chunk index is a byte.
pub const MAX_DEPTH: usize = 256 * CHUNK_SAMPLES;
/// Bytes per chunk: the samples in order, each its channels in order, each an `f32`
/// little-endian.
pub const CHUNK_BYTES: usize = CHUNK_SAMPLES * CHANNELS * 4;

/// What a channel or the trigger watches. The code ([`Signal::code`]) is the link's.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Signal {
    /// Measured phase current a, A.
    IA,
    /// Measured phase current b, A.
    IB,
    /// Measured phase current c, A.
    IC,
    /// Measured DC-bus voltage, V.
    Vdc,
    /// Measured mechanical speed, rad/s.
    OmegaM,
    /// Measured mechanical angle within a revolution, rad.
    ThetaM,
    /// Stator current α, A.
    IAlpha,
    /// Stator current β, A.
    IBeta,
    /// Current reference α, A.
    IRefAlpha,
    /// Current reference β, A.
    IRefBeta,
    /// Applied voltage α, V.
    VAlpha,
    /// Applied voltage β, V.
    VBeta,
    /// Field angle, electrical rad.
    ThetaE,
    /// Slip frequency, electrical rad/s.
    OmegaSl,
    /// Rotor-flux estimate, Wb.
    PsiR,
    /// Rotor-flux reference, Wb.
    PsiRef,
    /// q-axis current reference, A.
    IqRef,
    /// Speed reference, rad/s.
    OmegaRef,
    /// Rotor resistance in use, × the motor file's.
    RrScale,
    /// Inductances in use, × the motor file's.
    LScale,
    /// Duty of phase a for the next period (NaN while the bridge is off).
    DutyA,
    /// Duty of phase b (NaN while the bridge is off).
    DutyB,
    /// Duty of phase c (NaN while the bridge is off).
    DutyC,
    /// The drive's mode after the step, as the link's mode code (0 Idle, 1 Magnetizing,
    /// 2 Running, ≥ 10 a fault).
    Mode,
}

impl Signal {
    /// Every signal, in code order.
    pub const ALL: [Signal; 24] = [
        Signal::IA,
        Signal::IB,
        Signal::IC,
        Signal::Vdc,
        Signal::OmegaM,
        Signal::ThetaM,
        Signal::IAlpha,
        Signal::IBeta,
        Signal::IRefAlpha,
        Signal::IRefBeta,
        Signal::VAlpha,
        Signal::VBeta,
        Signal::ThetaE,
        Signal::OmegaSl,
        Signal::PsiR,
        Signal::PsiRef,
        Signal::IqRef,
        Signal::OmegaRef,
        Signal::RrScale,
        Signal::LScale,
        Signal::DutyA,
        Signal::DutyB,
        Signal::DutyC,
        Signal::Mode,
    ];

    /// The link's code: the position in [`Signal::ALL`].
    pub fn code(self) -> u8 {
        self as u8
    }

    /// The signal of a link code.
    pub fn from_code(code: u8) -> Option<Self> {
        Self::ALL.get(usize::from(code)).copied()
    }

    /// Name (a CSV column's, a command line's).
    pub fn name(self) -> &'static str {
        match self {
            Signal::IA => "i_a",
            Signal::IB => "i_b",
            Signal::IC => "i_c",
            Signal::Vdc => "vdc",
            Signal::OmegaM => "omega_m",
            Signal::ThetaM => "theta_m",
            Signal::IAlpha => "i_alpha",
            Signal::IBeta => "i_beta",
            Signal::IRefAlpha => "i_ref_alpha",
            Signal::IRefBeta => "i_ref_beta",
            Signal::VAlpha => "v_alpha",
            Signal::VBeta => "v_beta",
            Signal::ThetaE => "theta_e",
            Signal::OmegaSl => "omega_sl",
            Signal::PsiR => "psi_r",
            Signal::PsiRef => "psi_ref",
            Signal::IqRef => "i_q_ref",
            Signal::OmegaRef => "omega_ref",
            Signal::RrScale => "rr_scale",
            Signal::LScale => "l_scale",
            Signal::DutyA => "duty_a",
            Signal::DutyB => "duty_b",
            Signal::DutyC => "duty_c",
            Signal::Mode => "mode",
        }
    }

    /// Unit ("1" for a ratio or a code).
    pub fn unit(self) -> &'static str {
        match self {
            Signal::IA
            | Signal::IB
            | Signal::IC
            | Signal::IAlpha
            | Signal::IBeta
            | Signal::IRefAlpha
            | Signal::IRefBeta
            | Signal::IqRef => "A",
            Signal::Vdc | Signal::VAlpha | Signal::VBeta => "V",
            Signal::OmegaM | Signal::OmegaSl | Signal::OmegaRef => "rad/s",
            Signal::ThetaM | Signal::ThetaE => "rad",
            Signal::PsiR | Signal::PsiRef => "Wb",
            Signal::RrScale
            | Signal::LScale
            | Signal::DutyA
            | Signal::DutyB
            | Signal::DutyC
            | Signal::Mode => "1",
        }
    }

    /// The signal's value in one control period.
    #[inline]
    pub fn value(self, m: &Measurements, out: &FastOutput, t: &Telemetry) -> f32 {
        match self.field() {
            Some(k) => t.get(k),
            None => self.measured(m, out),
        }
    }

    /// The drive's signal ([`Telemetry`]'s field) this one is, if it is one; `None` for what
    /// the period's measurements and output carry ([`Signal::measured`]).
    #[inline]
    pub fn field(self) -> Option<TelemetryField> {
        use TelemetryField as F;
        Some(match self {
            Signal::IAlpha => F::IAlpha,
            Signal::IBeta => F::IBeta,
            Signal::IRefAlpha => F::IRefAlpha,
            Signal::IRefBeta => F::IRefBeta,
            Signal::VAlpha => F::VAlpha,
            Signal::VBeta => F::VBeta,
            Signal::ThetaE => F::ThetaE,
            Signal::OmegaSl => F::OmegaSl,
            Signal::PsiR => F::PsiR,
            Signal::PsiRef => F::PsiRef,
            Signal::IqRef => F::IqRef,
            Signal::OmegaRef => F::OmegaRef,
            Signal::RrScale => F::RrScale,
            Signal::LScale => F::LScale,
            Signal::IA
            | Signal::IB
            | Signal::IC
            | Signal::Vdc
            | Signal::OmegaM
            | Signal::ThetaM
            | Signal::DutyA
            | Signal::DutyB
            | Signal::DutyC
            | Signal::Mode => return None,
        })
    }

    /// The value of a signal that is not the drive's ([`Signal::field`] `None`) in one
    /// control period: a measurement, a duty or the mode. NaN for a drive's signal.
    #[inline]
    pub fn measured(self, m: &Measurements, out: &FastOutput) -> f32 {
        let duty = |k: usize| match out.phases {
            PhaseCommand::Duty(d) => [d.a, d.b, d.c].get(k).copied().unwrap_or(f32::NAN),
            PhaseCommand::Off => f32::NAN,
        };
        match self {
            Signal::IA => m.i_abc_a.a,
            Signal::IB => m.i_abc_a.b,
            Signal::IC => m.i_abc_a.c,
            Signal::Vdc => m.vdc_v,
            Signal::OmegaM => m.omega_m_rad_s,
            Signal::ThetaM => m.theta_m_rad,
            Signal::DutyA => duty(0),
            Signal::DutyB => duty(1),
            Signal::DutyC => duty(2),
            Signal::Mode => f32::from(out.mode.code()),
            _ => f32::NAN,
        }
    }
}

/// Where a recorded sample's signals come from: one control period's, each made when a
/// channel or the trigger asks for it ([`Capture::record_from`]).
pub trait Source {
    /// Signal `s` in this period.
    fn value(&self, s: Signal) -> f32;
}

/// A period's measurements, output and telemetry, made whole (the simulators', the
/// processor-in-the-loop server's; [`Capture::record`]).
#[derive(Clone, Copy, Debug)]
pub struct Period<'a> {
    /// The step's measurements.
    pub m: &'a Measurements,
    /// Its output.
    pub out: &'a FastOutput,
    /// The drive's signals after it.
    pub t: &'a Telemetry,
}

impl Source for Period<'_> {
    #[inline]
    fn value(&self, s: Signal) -> f32 {
        s.value(self.m, self.out, self.t)
    }
}

/// A period of the drive's fast side: its measurements and output, and the drive's signals
/// one by one ([`FastSide::signal`], the slow side's part that of the plan in force) — only
/// those a channel or the trigger asks for. The firmware's capture, in the control
/// interrupt: made whole for each sample, the telemetry cost the period ≈ 110 instructions,
/// and the slow side is not the interrupt's to read while its job runs.
#[derive(Clone, Copy, Debug)]
pub struct FastPeriod<'a> {
    /// The step's measurements.
    pub m: &'a Measurements,
    /// Its output.
    pub out: &'a FastOutput,
    /// The fast side after it.
    pub fast: &'a FastSide,
}

impl Source for FastPeriod<'_> {
    #[inline]
    fn value(&self, s: Signal) -> f32 {
        match s.field() {
            Some(k) => self.fast.signal(k),
            None => s.measured(self.m, self.out),
        }
    }
}

/// Which crossing of the trigger level fires.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Edge {
    /// From below the level to at or above it, or from on it to above it.
    Rising,
    /// From above the level to at or below it, or from on it to below it.
    Falling,
    /// Either.
    Either,
}

/// When the record is taken.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Trigger {
    /// As soon as the pre-trigger samples are in.
    Immediate,
    /// When `signal` crosses `level` (between two recorded samples) the way `edge` says.
    Level {
        /// The watched signal (it need not be one of the channels).
        signal: Signal,
        /// Rising, falling or either.
        edge: Edge,
        /// In the signal's unit.
        level: f32,
    },
}

/// What to capture: the link's `ArmCapture`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CaptureSpec {
    /// The four channels.
    pub signals: [Signal; CHANNELS],
    /// When.
    pub trigger: Trigger,
    /// Samples kept before the trigger's sample (less than the depth).
    pub pre_samples: u16,
    /// One sample every this many control periods (≥ 1).
    pub decimation: u16,
}

/// Why a [`CaptureSpec`] was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CaptureSpecError {
    /// `pre_samples` not below the depth.
    PreSamples,
    /// `decimation` zero.
    Decimation,
    /// The trigger level not finite.
    Level,
}

/// Where a capture stands.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CaptureState {
    /// Nothing armed.
    Idle,
    /// Recording, waiting for the trigger.
    Armed,
    /// The trigger fired; completing the record.
    Triggered,
    /// The record is complete and frozen until the next arm.
    Done,
}

impl CaptureState {
    /// The link's code.
    pub fn code(self) -> u8 {
        match self {
            CaptureState::Idle => 0,
            CaptureState::Armed => 1,
            CaptureState::Triggered => 2,
            CaptureState::Done => 3,
        }
    }

    /// The state of a link code.
    pub fn from_code(code: u8) -> Option<Self> {
        [CaptureState::Idle, CaptureState::Armed, CaptureState::Triggered, CaptureState::Done]
            .get(usize::from(code))
            .copied()
    }
}

/// The capture: its spec (validated when armed), its state and a ring of `DEPTH` samples
/// (`DEPTH` a multiple of [`CHUNK_SAMPLES`], at most 2 048: the link's chunk index is a
/// byte). `DEPTH · 16` bytes of RAM.
#[derive(Clone, Debug)]
pub struct Capture<const DEPTH: usize> {
    spec: CaptureSpec,
    state: CaptureState,
    ring: [[f32; CHANNELS]; DEPTH],
    /// The next sample's slot.
    head: usize,
    /// Samples since arming, up to `DEPTH`.
    filled: usize,
    /// Samples still to take after the trigger's.
    left: usize,
    /// Control periods to skip before the next sample.
    skip: u16,
    /// The trigger signal at the last recorded sample (NaN: none yet).
    last: f32,
}

impl<const DEPTH: usize> Default for Capture<DEPTH> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const DEPTH: usize> Capture<DEPTH> {
    /// Chunks in a record.
    pub const CHUNKS: usize = DEPTH / CHUNK_SAMPLES;

    /// Idle, the ring zeroed.
    pub const fn new() -> Self {
        const {
            assert!(DEPTH >= CHUNK_SAMPLES && DEPTH.is_multiple_of(CHUNK_SAMPLES) && DEPTH <= MAX_DEPTH);
        }
        Self {
            spec: CaptureSpec {
                signals: [Signal::IA; CHANNELS],
                trigger: Trigger::Immediate,
                pre_samples: 0,
                decimation: 1,
            },
            state: CaptureState::Idle,
            ring: [[0.0; CHANNELS]; DEPTH],
            head: 0,
            filled: 0,
            left: 0,
            skip: 0,
            last: f32::NAN,
        }
    }

    /// Arm with `spec` (checked against the depth), dropping any record under way or done.
    pub fn arm(&mut self, spec: CaptureSpec) -> Result<(), CaptureSpecError> {
        if usize::from(spec.pre_samples) >= DEPTH {
            return Err(CaptureSpecError::PreSamples);
        }
        if spec.decimation == 0 {
            return Err(CaptureSpecError::Decimation);
        }
        if let Trigger::Level { level, .. } = spec.trigger
            && !level.is_finite()
        {
            return Err(CaptureSpecError::Level);
        }
        // Field by field: no temporary of the ring's size (the firmware arms in the control
        // interrupt, whose stack is small).
        self.spec = spec;
        self.state = CaptureState::Armed;
        (self.head, self.filled, self.left, self.skip, self.last) = (0, 0, 0, 0, f32::NAN);
        Ok(())
    }

    /// Where it stands.
    pub fn state(&self) -> CaptureState {
        self.state
    }

    /// The spec it was last armed with.
    pub fn spec(&self) -> CaptureSpec {
        self.spec
    }

    /// One control period's measurements and output (call after every step), and its
    /// signals ([`Drive::telemetry`](crate::drive::Drive::telemetry)), made only for a sample
    /// that is recorded.
    #[inline]
    pub fn record(&mut self, m: &Measurements, out: &FastOutput, telemetry: impl FnOnce() -> Telemetry) {
        if self.due() {
            self.take(&Period { m, out, t: &telemetry() });
        }
    }

    /// One control period (call after every step), its signals read from `src` — each only
    /// if a channel or the trigger of a recorded sample asks for it (the firmware's capture:
    /// the drive's signals one by one, `FastSide::signal`).
    #[inline]
    pub fn record_from(&mut self, src: &impl Source) {
        if self.due() {
            self.take(src);
        }
    }

    /// This period's sample is recorded: armed or triggered, and not one the decimation skips.
    #[inline(always)]
    fn due(&mut self) -> bool {
        if matches!(self.state, CaptureState::Idle | CaptureState::Done) {
            return false;
        }
        if self.skip > 0 {
            self.skip -= 1;
            return false;
        }
        true
    }

    /// A recorded sample: into the ring, then the trigger or the countdown.
    #[inline(never)]
    fn take(&mut self, src: &impl Source) {
        let s = &self.spec;
        self.skip = s.decimation.saturating_sub(1);
        if let Some(slot) = self.ring.get_mut(self.head) {
            *slot = s.signals.map(|x| src.value(x));
        }
        self.head = if self.head + 1 >= DEPTH { 0 } else { self.head + 1 };
        self.filled = (self.filled + 1).min(DEPTH);
        match self.state {
            CaptureState::Armed => {
                let fired = match s.trigger {
                    Trigger::Immediate => true,
                    Trigger::Level { signal, edge, level } => {
                        let (was, now) = (self.last, src.value(signal));
                        self.last = now;
                        let rising = (was < level && now >= level) || (was == level && now > level);
                        let falling = (was > level && now <= level) || (was == level && now < level);
                        match edge {
                            Edge::Rising => rising,
                            Edge::Falling => falling,
                            Edge::Either => rising || falling,
                        }
                    }
                };
                // The trigger's sample needs its pre-trigger samples before it.
                if fired && self.filled > usize::from(s.pre_samples) {
                    self.left = DEPTH - 1 - usize::from(s.pre_samples);
                    self.state = if self.left == 0 { CaptureState::Done } else { CaptureState::Triggered };
                }
            }
            CaptureState::Triggered => {
                self.left = self.left.saturating_sub(1);
                if self.left == 0 {
                    self.state = CaptureState::Done;
                }
            }
            CaptureState::Idle | CaptureState::Done => {}
        }
    }

    /// Part `chunk` of the finished record: samples `chunk·8 …` from the oldest (sample
    /// `pre_samples` is the trigger's), as [`CHUNK_BYTES`] bytes. `None` until the record
    /// is done, or past its end.
    pub fn chunk(&self, chunk: usize) -> Option<[u8; CHUNK_BYTES]> {
        if self.state != CaptureState::Done || chunk >= Self::CHUNKS {
            return None;
        }
        // Done: the ring is full and its oldest sample is the next slot.
        let mut bytes = [0u8; CHUNK_BYTES];
        for (j, out) in bytes.chunks_exact_mut(CHANNELS * 4).enumerate() {
            let k = (self.head + chunk * CHUNK_SAMPLES + j) % DEPTH;
            let sample = self.ring.get(k).copied().unwrap_or_default();
            for (v, b) in sample.iter().zip(out.chunks_exact_mut(4)) {
                b.copy_from_slice(&v.to_le_bytes());
            }
        }
        Some(bytes)
    }
}

impl Capture<RECORD_SAMPLES> {
    /// [`Capture::record_from`] a period of the drive's fast side ([`FastPeriod`]) at the
    /// firmware's depth, compiled here — at controller-core's opt-level, where the firmware
    /// builds the control law — not in the caller's crate (generic, the firmware compiled it
    /// at its own opt-level "z": `cost part:capture_sample`).
    #[inline(never)]
    pub fn record_fast(&mut self, p: &FastPeriod<'_>) {
        self.record_from(p);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::drive::Mode;
    use crate::frames::Abc;

    /// A period whose measured current a is `k` and whose speed reference is `w`.
    fn period(k: f32, w: f32) -> (Measurements, FastOutput, Telemetry) {
        let m = Measurements {
            i_abc_a: Abc { a: k, b: -k, c: 0.0 },
            vdc_v: 300.0,
            omega_m_rad_s: 0.0,
            theta_m_rad: 0.0,
        };
        let out = FastOutput { phases: PhaseCommand::Off, mode: Mode::Running, brake: false };
        (m, out, Telemetry { omega_ref_rad_s: w, ..Telemetry::default() })
    }

    /// The firmware's source (each signal alone from the fast side, the plan's slow part)
    /// reads every signal as the whole telemetry on the plan's slow part does, bit for bit:
    /// a drive magnetizing and Running under a torque reference, every period.
    #[test]
    fn a_fast_period_reads_every_signal_as_the_whole_telemetry() {
        use crate::drive::{Drive, DriveConfig, Reference};
        let mut d = Drive::new(DriveConfig::new(&crate::drive::test_spec()).unwrap());
        d.enable().unwrap();
        let (mut running, mut i) = (0, Abc::default());
        for k in 0..6_000u32 {
            if d.mode() == Mode::Running && running == 0 {
                d.set_reference(Reference::Torque(1.0)).unwrap();
            }
            let m = Measurements { i_abc_a: i, vdc_v: 310.0, omega_m_rad_s: 2.0, theta_m_rad: 0.1 };
            let out = d.step(&m);
            if let PhaseCommand::Duty(duty) = out.phases {
                i = crate::drive::rl_step(i, duty, 310.0, 16.2, 0.1, 5e-5);
            }
            running += u32::from(d.mode() == Mode::Running);
            let (fast, _) = d.into_parts();
            let t = fast.telemetry_with(&fast.plan_signals());
            let (whole, alone) =
                (Period { m: &m, out: &out, t: &t }, FastPeriod { m: &m, out: &out, fast: &fast });
            for s in Signal::ALL {
                assert_eq!(alone.value(s).to_bits(), whole.value(s).to_bits(), "{s:?}, period {k}");
            }
        }
        assert!(running > 1_000, "Running for {running} periods");
    }

    fn spec(trigger: Trigger, pre: u16, decimation: u16) -> CaptureSpec {
        CaptureSpec {
            signals: [Signal::IA, Signal::IB, Signal::OmegaRef, Signal::Mode],
            trigger,
            pre_samples: pre,
            decimation,
        }
    }

    fn read<const D: usize>(c: &Capture<D>) -> std::vec::Vec<[f32; CHANNELS]> {
        let mut v = std::vec::Vec::new();
        for k in 0..Capture::<D>::CHUNKS {
            let b = c.chunk(k).unwrap();
            for s in b.chunks_exact(16) {
                let f = |i: usize| f32::from_le_bytes(s[4 * i..4 * i + 4].try_into().unwrap());
                v.push([f(0), f(1), f(2), f(3)]);
            }
        }
        v
    }

    #[test]
    fn immediate_records_the_next_depth_samples_decimated() {
        let mut c = Capture::<16>::new();
        assert_eq!(c.state(), CaptureState::Idle);
        c.arm(spec(Trigger::Immediate, 0, 3)).unwrap();
        for k in 0..100 {
            let (m, o, t) = period(k as f32, 0.0);
            c.record(&m, &o, || t);
        }
        assert_eq!(c.state(), CaptureState::Done);
        let r = read(&c);
        assert_eq!(r.len(), 16);
        for (j, s) in r.iter().enumerate() {
            assert_eq!(*s, [3.0 * j as f32, -3.0 * j as f32, 0.0, 2.0], "sample {j}");
        }
        assert_eq!(c.chunk(2), None, "past the end");
    }

    #[test]
    fn a_rising_level_puts_the_trigger_after_its_pre_samples() {
        let mut c = Capture::<32>::new();
        let trigger = Trigger::Level { signal: Signal::OmegaRef, edge: Edge::Rising, level: 100.0 };
        c.arm(spec(trigger, 10, 1)).unwrap();
        // The speed reference steps to 150 at period 500 (and falls back at 700, which a
        // rising trigger ignores); an arm long before it, so the ring wraps many times.
        for k in 0..1000 {
            let w = if (500..700).contains(&k) { 150.0 } else { 0.0 };
            let (m, o, t) = period(k as f32, w);
            c.record(&m, &o, || t);
            if k < 500 {
                assert_eq!(c.state(), CaptureState::Armed, "{k}");
            }
        }
        assert_eq!(c.state(), CaptureState::Done);
        let r = read(&c);
        for (j, s) in r.iter().enumerate() {
            assert_eq!(s[0], (490 + j) as f32, "sample {j}");
        }
        assert_eq!(r[9][2], 0.0);
        assert_eq!(r[10][2], 150.0, "the trigger's sample is sample pre_samples");
    }

    #[test]
    fn falling_and_either_edges_and_a_trigger_too_early_for_its_pre_samples() {
        for edge in [Edge::Falling, Edge::Either] {
            let mut c = Capture::<8>::new();
            let trigger = Trigger::Level { signal: Signal::IA, edge, level: 2.5 };
            // 5 pre-samples: the rising crossing at period 3 (2 → 3) has only 3 before it.
            c.arm(spec(trigger, 5, 1)).unwrap();
            for k in 0..60 {
                // Rises 0, 1, …, 39, then falls to 2.
                let x = if k < 40 { k as f32 } else { 2.0 };
                let (m, o, t) = period(x, 0.0);
                c.record(&m, &o, || t);
            }
            // Either: too early at the rise, so the fall (39 → 2) fires, as for Falling.
            let r = read(&c);
            assert_eq!(r[5][0], 2.0, "{edge:?}: {r:?}");
            assert_eq!(r[4][0], 39.0, "{edge:?}");
            assert_eq!(r[0][0], 35.0, "{edge:?}");
        }
    }

    /// A reference resting exactly on the level (0 while idle) fires when it leaves it.
    #[test]
    fn a_signal_resting_on_the_level_fires_when_it_leaves() {
        for (edge, step) in [(Edge::Rising, 100.0), (Edge::Falling, -100.0), (Edge::Either, 100.0)] {
            let mut c = Capture::<8>::new();
            c.arm(spec(Trigger::Level { signal: Signal::OmegaRef, edge, level: 0.0 }, 2, 1)).unwrap();
            for k in 0..20 {
                let (m, o, t) = period(k as f32, if k >= 10 { step } else { 0.0 });
                c.record(&m, &o, || t);
            }
            assert_eq!(c.state(), CaptureState::Done, "{edge:?}");
            let r = read(&c);
            assert_eq!((r[2][0], r[2][2]), (10.0, step), "{edge:?}");
            assert_eq!(r[1][2], 0.0);
        }
    }

    #[test]
    fn no_trigger_stays_armed_and_rearming_restarts() {
        let mut c = Capture::<8>::new();
        let trigger = Trigger::Level { signal: Signal::OmegaRef, edge: Edge::Either, level: 1.0 };
        c.arm(spec(trigger, 0, 1)).unwrap();
        for k in 0..50 {
            let (m, o, t) = period(k as f32, 0.0);
            c.record(&m, &o, || t);
        }
        assert_eq!(c.state(), CaptureState::Armed);
        assert_eq!(c.chunk(0), None, "nothing to read before the record is done");
        c.arm(spec(Trigger::Immediate, 7, 1)).unwrap();
        for k in 0..8 {
            let (m, o, t) = period(100.0 + k as f32, 0.0);
            c.record(&m, &o, || t);
        }
        assert_eq!(c.state(), CaptureState::Done);
        assert_eq!(read(&c)[0][0], 100.0);
        // Frozen once done.
        let (m, o, t) = period(-1.0, 0.0);
        c.record(&m, &o, || t);
        assert_eq!(read(&c)[7][0], 107.0);
    }

    #[test]
    fn bad_specs_are_refused() {
        let mut c = Capture::<8>::new();
        assert_eq!(c.arm(spec(Trigger::Immediate, 8, 1)), Err(CaptureSpecError::PreSamples));
        assert_eq!(c.arm(spec(Trigger::Immediate, 0, 0)), Err(CaptureSpecError::Decimation));
        for level in [f32::NAN, f32::INFINITY] {
            let t = Trigger::Level { signal: Signal::IA, edge: Edge::Rising, level };
            assert_eq!(c.arm(spec(t, 0, 1)), Err(CaptureSpecError::Level));
        }
        assert_eq!(c.state(), CaptureState::Idle);
    }

    #[test]
    fn codes_round_trip_and_names_are_unique() {
        for (k, s) in Signal::ALL.iter().enumerate() {
            assert_eq!(usize::from(s.code()), k);
            assert_eq!(Signal::from_code(s.code()), Some(*s));
            assert_eq!(Signal::ALL.iter().filter(|t| t.name() == s.name()).count(), 1);
        }
        assert_eq!(Signal::from_code(24), None);
        for c in 0..4 {
            assert_eq!(CaptureState::from_code(c).map(CaptureState::code), Some(c));
        }
        assert_eq!(CaptureState::from_code(4), None);
    }
}
