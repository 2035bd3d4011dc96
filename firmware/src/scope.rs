//! The capture (`controller_core::capture`) between the control interrupt, which records into
//! it while it is armed, and the link task, which arms it and reads the record out — in
//! thread mode: no part of the read-out (a 128-byte chunk per `ReadCapture`) or of the arming
//! runs in the control interrupt (issue 54: its longest period).
//!
//! ```text
//!            ArmCapture (the link task)
//!   LINK ─────────────────────────────────▶ RECORDING   (the interrupt records every period)
//!    ▲  ◀──── the record done, or the link asks for it back (a re-arm) ────┘
//! ```
//!
//! One atomic says who holds the capture; the other side does not touch it. While the
//! interrupt records, the link reads the capture's state from a mirror the interrupt keeps
//! (`ReadCapture` then answers with the state and no samples, as before the record is done).

use controller_core::capture::{Capture, CaptureState, FastPeriod};
use controller_core::link::{self, BoardCommand, Reply};
use core::cell::UnsafeCell;
use core::sync::atomic::{AtomicBool, AtomicU8, Ordering};

/// Samples in a capture's record (`controller_core::capture`).
pub const CAPTURE_DEPTH: usize = controller_core::capture::RECORD_SAMPLES;

/// [`Scope`]'s holders: the link task (and while one of its calls has it, lent), the
/// control interrupt.
const LINK: u8 = 0;
const LINK_LENT: u8 = 1;
const RECORDING: u8 = 2;

/// The capture and who holds it: zero-initialised, the link's and idle.
pub struct Scope {
    owner: AtomicU8,
    /// The link task wants the capture back while the interrupt records (a re-arm).
    recall: AtomicBool,
    /// The capture's state while the interrupt records ([`CaptureState::code`]).
    state: AtomicU8,
    capture: UnsafeCell<Capture<CAPTURE_DEPTH>>,
}

// SAFETY: `owner` says who holds the capture — the link's side in LINK, one of its calls in
// LINK_LENT (taken by a compare-exchange from LINK: a second caller finds it lent), the
// control interrupt in RECORDING — and only the holder touches it; each side hands it over
// with a Release store the other side's Acquire load sees, so the capture is never reached
// from two places at once and each sees the other's writes. The link's side moves it to
// RECORDING only from LINK_LENT, the interrupt back only from RECORDING. `recall` and
// `state` are plain flags.
unsafe impl Sync for Scope {}

impl Scope {
    /// Idle, the link's.
    pub const fn new() -> Self {
        Self {
            owner: AtomicU8::new(LINK),
            recall: AtomicBool::new(false),
            state: AtomicU8::new(0),
            capture: UnsafeCell::new(Capture::new()),
        }
    }

    /// The control interrupt holds the capture: it records ([`Scope::record`]). One load.
    #[inline(always)]
    pub fn recording(&self) -> bool {
        self.owner.load(Ordering::Acquire) == RECORDING
    }

    /// The control interrupt, after each step: one period's signals, read from `src` only
    /// for a recorded sample, into the capture if it holds it ([`Scope::recording`]: the
    /// caller asks first, and makes `src` only then); the capture back to the link once the
    /// record is done or the link asks for it.
    pub fn record(&self, src: &FastPeriod<'_>) {
        if !self.recording() {
            return;
        }
        // SAFETY: RECORDING: the interrupt holds the capture (the link task does not touch
        // it until the Release store below), and this is the only borrow.
        let c = unsafe { &mut *self.capture.get() };
        c.record_fast(src);
        let state = c.state();
        self.state.store(state.code(), Ordering::Relaxed);
        if state == CaptureState::Done || self.recall.load(Ordering::Relaxed) {
            self.owner.store(LINK, Ordering::Release);
        }
    }

    /// The link task: `ArmCapture` or `ReadCapture` answered (any other command: `None`).
    /// `None` too for an `ArmCapture` while the interrupt records: the capture is asked back
    /// (it comes back within a period) — call again. While it records, `ReadCapture` answers
    /// with its state and no samples. Out of line (inlined into the link task's async body,
    /// 252 B more flash).
    #[inline(never)]
    pub fn serve(&self, cmd: &BoardCommand) -> Option<Reply> {
        match cmd {
            BoardCommand::ArmCapture(spec) => {
                let reply = self.lend(|c| {
                    let reply = link::arm_capture(c, *spec);
                    let armed = c.state() == CaptureState::Armed;
                    if armed {
                        self.recall.store(false, Ordering::Relaxed);
                        self.state.store(CaptureState::Armed.code(), Ordering::Relaxed);
                    }
                    (reply, armed)
                });
                if reply.is_none() {
                    self.recall.store(true, Ordering::Relaxed);
                }
                reply
            }
            BoardCommand::ReadCapture { chunk } => {
                Some(self.lend(|c| (link::read_capture(c, *chunk), false)).unwrap_or_else(|| {
                    link::capture_reply::<CAPTURE_DEPTH>(self.recording_state(), *chunk, None)
                }))
            }
            _ => None,
        }
    }

    /// The capture, if the link's side holds it (host tests and benchmarks: the record
    /// once done).
    pub fn with_capture<R>(&self, f: impl FnOnce(&Capture<CAPTURE_DEPTH>) -> R) -> Option<R> {
        self.lend(|c| (f(c), false))
    }

    /// The capture's state as the link's side sees it.
    pub fn state(&self) -> CaptureState {
        self.with_capture(Capture::state).unwrap_or_else(|| self.recording_state())
    }

    /// The state the interrupt last left while it records.
    fn recording_state(&self) -> CaptureState {
        CaptureState::from_code(self.state.load(Ordering::Relaxed)).unwrap_or(CaptureState::Armed)
    }

    /// `f` on the capture if the link's side holds it (lent meanwhile), then the interrupt's
    /// if `f` says so (armed), else back to the link's side.
    fn lend<R>(&self, f: impl FnOnce(&mut Capture<CAPTURE_DEPTH>) -> (R, bool)) -> Option<R> {
        self.owner.compare_exchange(LINK, LINK_LENT, Ordering::Acquire, Ordering::Relaxed).ok()?;
        // SAFETY: LINK_LENT, taken from LINK by this call: the capture is this call's alone
        // (the interrupt touches it only in RECORDING, the link's other calls find it lent).
        let (r, record) = f(unsafe { &mut *self.capture.get() });
        self.owner.store(if record { RECORDING } else { LINK }, Ordering::Release);
        Some(r)
    }
}

impl Default for Scope {
    fn default() -> Self {
        Self::new()
    }
}

impl core::fmt::Debug for Scope {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Scope").field("owner", &self.owner.load(Ordering::Relaxed)).finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use controller_core::capture::{CHUNK_BYTES, CaptureSpec, Edge, Signal, Trigger};
    use controller_core::drive::{Drive, FastOutput, Measurements, Mode, PhaseCommand};

    fn spec(trigger: Trigger) -> CaptureSpec {
        CaptureSpec { signals: [Signal::IA; 4], trigger, pre_samples: 0, decimation: 1 }
    }

    /// One period whose measured current a is `k`.
    fn record(s: &Scope, k: f32) {
        let m = Measurements {
            i_abc_a: controller_core::frames::Abc { a: k, b: 0.0, c: 0.0 },
            ..Default::default()
        };
        let out = FastOutput { phases: PhaseCommand::Off, mode: Mode::Idle, brake: false };
        let cfg = controller_core::drive::DriveConfig::from_raw(&crate::config::DRIVE_CONFIG).unwrap();
        let (fast, _) = Drive::new(cfg).into_parts();
        s.record(&FastPeriod { m: &m, out: &out, fast: &fast });
    }

    /// Armed by the link, the capture is the interrupt's: it records every period, the link
    /// reads only its state (no samples) and cannot reach it; once the record is done it is
    /// the link's again, whose read-out is the record's.
    #[test]
    fn the_capture_is_the_link_tasks_but_while_the_interrupt_records() {
        let s = Scope::new();
        record(&s, 1.0);
        assert_eq!(s.state(), CaptureState::Idle, "nothing armed: nothing recorded");
        assert_eq!(s.serve(&BoardCommand::ArmCapture(spec(Trigger::Immediate))), Some(Reply::Ack));
        assert_eq!(s.with_capture(|_| ()), None, "the interrupt's while it records");
        for k in 0..CAPTURE_DEPTH - 1 {
            record(&s, k as f32);
            let Some(Reply::Capture { state, bytes, .. }) = s.serve(&BoardCommand::ReadCapture { chunk: 0 })
            else {
                panic!("a capture reply")
            };
            assert_eq!((state, bytes), (CaptureState::Triggered, [0; CHUNK_BYTES]), "period {k}");
        }
        record(&s, 255.0);
        assert_eq!(s.state(), CaptureState::Done);
        let chunk = s.with_capture(|c| c.chunk(31)).flatten();
        assert!(chunk.is_some());
        let Some(Reply::Capture { state, bytes, .. }) = s.serve(&BoardCommand::ReadCapture { chunk: 31 })
        else {
            panic!("a capture reply")
        };
        assert_eq!((state, Some(bytes)), (CaptureState::Done, chunk));
        let last = f32::from_le_bytes(bytes[CHUNK_BYTES - 16..CHUNK_BYTES - 12].try_into().unwrap());
        assert_eq!(last, 255.0, "the last period's sample closes the record");
        assert_eq!(
            s.serve(&BoardCommand::ReadCapture { chunk: 32 }),
            Some(Reply::Nack(link::NackReason::NoRecord))
        );
        assert_eq!(s.serve(&BoardCommand::GetStatus), None, "not the scope's");
    }

    /// A re-arm while the interrupt records (waiting for a trigger that does not come): the
    /// capture is asked back, comes back at the interrupt's next period, and the second try
    /// arms it — recording again, not handed back at once.
    #[test]
    fn a_re_arm_while_recording_asks_the_capture_back() {
        let s = Scope::new();
        let never = spec(Trigger::Level { signal: Signal::IA, edge: Edge::Rising, level: 1e9 });
        let arm = BoardCommand::ArmCapture(never);
        assert_eq!(s.serve(&arm), Some(Reply::Ack));
        record(&s, 0.0);
        assert_eq!(s.serve(&arm), None, "the interrupt records: asked back");
        assert_eq!(s.state(), CaptureState::Armed);
        record(&s, 0.0);
        assert_eq!(s.with_capture(|c| c.state()), Some(CaptureState::Armed), "back to the link");
        assert_eq!(s.serve(&arm), Some(Reply::Ack));
        for _ in 0..3 {
            record(&s, 0.0);
            assert_eq!(s.with_capture(|_| ()), None, "recording on");
        }
        // A spec refused leaves the capture the link's.
        let s = Scope::new();
        let bad = BoardCommand::ArmCapture(CaptureSpec { decimation: 0, ..never });
        assert_eq!(s.serve(&bad), Some(Reply::Nack(link::NackReason::Configuration)));
        assert_eq!(s.with_capture(|c| c.state()), Some(CaptureState::Idle));
    }
}
