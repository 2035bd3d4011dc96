//! The control interrupt's body once its samples are read, the drive's slow context's part
//! of the link, and what they share with the link task — free of the registers (those are
//! behind [`OutputStage`]), so that the code the board runs every period is the code QEMU
//! counts (`qemu-target`'s `cost interrupt_period`) and the host tests.
//!
//! ```text
//!  control interrupt:  Samples ─▶ Outputs::period (break flag → ControlLoop::step → compare
//!                      values, MOE) ─▶ the watchdog's abort of a sequence, a posted
//!                      commissioning command (Mailbox)
//!  slow context:       the snapshot (TripleBuffer) ─▶ the slow step's job ─▶ the watchdog's
//!                      controlled stop, a posted drive command (Mailbox)
//! ```

use crate::boundary::{Mailbox, TripleBuffer};
use crate::control::{Bridge, ControlLoop, Samples, SlowLink, SlowPart, Snapshot};
use crate::output::{OutputStage, Outputs};
use crate::server::{self, Prepared};
use controller_core::drive::DriveMut;
use controller_core::link::{BoardCommand, LinkStats, Reply};
use core::sync::atomic::{AtomicBool, Ordering};

/// A command for the control interrupt: the command, its preparation (made by the link
/// task: nothing heavy runs in the interrupt) and the link's counters for `Status`.
pub type Request = (BoardCommand, Prepared, LinkStats);

/// What the control interrupt and the link task share, lock-free: neither side ever masks
/// the other.
#[derive(Debug, Default)]
pub struct Shared {
    /// The control loop's state for the link task (telemetry, calibration, bridge on).
    pub snapshot: TripleBuffer<Snapshot>,
    /// Commands in; the interrupt executes one after its step — the first step without the
    /// drive's slow step — and leaves the reply.
    pub commands: Mailbox<Request, Reply>,
    /// The link watchdog's stop, for the interrupt to carry out.
    pub watchdog_stop: AtomicBool,
    /// The link task wants a fresh snapshot: the interrupt publishes one after its next
    /// step without the drive's slow step (a snapshot of every period, ≈ 200 B copied
    /// twice, cost the interrupt more than its control step did; the task reads one every
    /// 10 ms at most).
    snapshot_wanted: AtomicBool,
}

impl Shared {
    /// Nothing published, nothing posted (zero-initialised: a static of it takes no flash).
    pub const fn new() -> Self {
        Self {
            snapshot: TripleBuffer::new(),
            commands: Mailbox::new(),
            watchdog_stop: AtomicBool::new(false),
            snapshot_wanted: AtomicBool::new(false),
        }
    }

    /// The link task: have the interrupt publish a snapshot after its next step without the
    /// slow step (read it from [`Shared::snapshot`] a period or two later).
    pub fn request_snapshot(&self) {
        self.snapshot_wanted.store(true, Ordering::Relaxed);
    }

    /// One control period after the samples are read: the output stage around the control
    /// step ([`Outputs::period`]), then the link's requests that are the fast context's —
    /// the watchdog's abort of a commissioning sequence, and a posted command the slow
    /// context does not serve ([`server::slow_context_serves`]: the commissioning's; a drive
    /// command only while a sequence runs, which it aborts or is refused by; the capture's,
    /// never posted, are refused). Those wait while the drive's slow step is in flight
    /// ([`ControlLoop::slow_busy`]: from its tick to its plan's adoption, a plan's delay at
    /// most), so that the longest period is not the slow step's and theirs. The drive's
    /// commands, the watchdog's controlled stop and the snapshot are the slow context's
    /// ([`SlowLink`]): nothing of theirs runs here but a load and a test.
    pub fn control_period(
        &self,
        outputs: &mut Outputs,
        hw: &mut impl OutputStage,
        ctl: &mut ControlLoop,
        mut samples: Samples,
    ) -> Bridge {
        // By reference: kept for a command's `Status` below (moved in, at opt-level "z" its
        // copy was a `memcpy` call in every period).
        let bridge = outputs.period(hw, ctl, &mut samples);
        // The slow context stops the drive and clears the flag, after the period of its tick
        // — whose control interrupt came here first.
        if self.watchdog_stop.load(Ordering::Relaxed) {
            ctl.abort_commissioning();
        }
        self.commands.serve(|(cmd, prepared, stats)| {
            if (server::slow_context_serves(cmd) && !ctl.commissioning()) || ctl.slow_busy() {
                return None;
            }
            ctl.note_readings(&samples);
            server::handle_board(ctl, cmd, *prepared, stats)
        });
        bridge
    }
}

/// The slow context's part of the link (`crate::control::run_slow`, the slow side held).
impl SlowLink for Shared {
    fn snapshot_wanted(&self) -> &AtomicBool {
        &self.snapshot_wanted
    }

    /// The snapshot the link task asked for, made of the fast context's note and the slow
    /// side's signals before the job (the same period's), published. Out of line: every
    /// 10 ms at most.
    #[inline(never)]
    fn publish(&self, p: &mut SlowPart) {
        if core::mem::take(&mut p.tick.snapshot) {
            self.snapshot.write(p.tick.fast.snapshot(&p.side.signals()));
            self.snapshot_wanted.store(false, Ordering::Relaxed);
        }
    }

    /// The watchdog's controlled stop, and a posted drive command (unless a commissioning sequence ran at
    /// the tick: then the fast context's). A command's fast part — the mode, a new run, a
    /// new configuration — is the fast side's at the plan's adoption
    /// ([`DriveMut::slow_only`]); its reply is sent now.
    fn serve(&self, p: &mut SlowPart) {
        if self.watchdog_stop.load(Ordering::Relaxed) {
            DriveMut::slow_only(&mut p.side).controlled_stop();
            self.watchdog_stop.store(false, Ordering::Relaxed);
        }
        if !p.tick.commissioning {
            let readings = p.tick.readings;
            self.commands.serve(|(cmd, _, stats)| {
                server::slow_context_serves(cmd)
                    .then(|| server::drive_command(DriveMut::slow_only(&mut p.side), cmd, stats, readings))
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use controller_core::drive::Mode;

    /// TIM1 and the brake pin as the interrupt sees them when nothing breaks.
    #[derive(Debug, Default)]
    struct Timer {
        moe: bool,
        ccr: [u16; 3],
    }

    impl OutputStage for Timer {
        fn break_flag(&mut self) -> bool {
            false
        }
        fn clear_break_flag(&mut self) {}
        fn outputs_enabled(&mut self) -> bool {
            self.moe
        }
        fn set_compare(&mut self, ccr: [u16; 3]) {
            self.ccr = ccr;
        }
        fn enable_outputs(&mut self) {
            self.moe = true;
        }
        fn disable_outputs(&mut self) {
            self.moe = false;
        }
        fn set_brake(&mut self, _: bool) {}
    }

    fn at_rest() -> Samples {
        Samples { i_abc: [2048; 3], vdc: 3100, encoder: 0, hardware_break: false }
    }

    /// The interrupt's body with its shared state, a timer and the control loop (calibrated
    /// at rest, connected to the shared state: its slow context, run at the tick by the
    /// tests' pend, serves the drive's commands).
    struct Rig {
        shared: &'static Shared,
        outputs: Outputs,
        tim: Timer,
        ctl: ControlLoop<'static>,
    }

    impl Rig {
        fn new() -> Self {
            extern crate std;
            let (outputs, tim) = (Outputs::new(), Timer::default());
            let shared = std::boxed::Box::leak(std::boxed::Box::new(Shared::new()));
            let mut ctl = ControlLoop::at_rest_for_tests();
            assert!(ctl.connect(shared));
            Self { shared, outputs, tim, ctl }
        }

        /// One control period on samples `s` (the slow context's turn after it, if it is a
        /// tick's: the tests' pend runs it at once).
        fn period(&mut self, s: Samples) {
            self.shared.control_period(&mut self.outputs, &mut self.tim, &mut self.ctl, s);
        }

        /// Periods at rest until the next one is a tick's (the slow context's turn).
        fn step_to_before_a_tick(&mut self) {
            while !self.ctl.fast().slow_step_due() {
                self.period(at_rest());
            }
        }

        /// An enable from the fast context, and periods at rest past its bootstrap pre-charge
        /// (all low sides on: compare 0; no slow job meanwhile, `FastSide::hold_step`).
        fn enable_past_the_precharge(&mut self) {
            while self.ctl.slow_busy() {
                self.period(at_rest());
            }
            self.ctl.drive_mut(|mut d| d.enable()).unwrap().unwrap();
            for _ in 0..100 {
                self.period(at_rest());
                if self.tim.ccr != [0; 3] {
                    return;
                }
            }
            panic!("the pre-charge ends");
        }

        fn post(&self, cmd: BoardCommand) -> bool {
            self.shared.commands.post((cmd, Prepared::Nothing, LinkStats::default()))
        }
    }

    /// The snapshot: its fast part noted by the control interrupt in the period before a
    /// tick once the link task asks (`FastSide::note_due`: neither a tick's nor an
    /// adoption's period), published by the slow context at that tick — the loop as it was
    /// before the noting period (its last output and signals; the slow side does not move in
    /// between). Nothing without a request, one per request.
    #[test]
    fn a_snapshot_is_noted_before_a_tick_and_published_at_it() {
        let mut r = Rig::new();
        for _ in 0..3 * r.ctl.config().slow_divider() {
            r.period(at_rest());
        }
        assert_eq!(r.shared.snapshot.read(), None, "nothing asked, nothing published");
        r.shared.request_snapshot();
        let published_at = |r: &mut Rig| {
            while !r.ctl.fast().note_due() {
                r.period(at_rest());
            }
            assert!(!r.ctl.fast().slow_step_due() && !r.ctl.slow_busy(), "a quiet period");
            let before = r.ctl.snapshot();
            r.period(at_rest());
            while !r.ctl.fast().slow_step_due() {
                r.period(at_rest());
                assert_ne!(r.shared.snapshot.read(), Some(before), "not before the tick");
            }
            r.period(at_rest());
            before
        };
        let before = published_at(&mut r);
        assert_eq!(r.shared.snapshot.read(), Some(before));
        // The request is spent: the drive moves on, the snapshot read stays the one taken.
        r.enable_past_the_precharge();
        for _ in 0..2 * r.ctl.config().slow_divider() {
            r.period(at_rest());
        }
        let held = r.shared.snapshot.read().unwrap();
        assert!(!held.bridge_on && r.ctl.snapshot().bridge_on, "one snapshot per request");
        r.shared.request_snapshot();
        let before = published_at(&mut r);
        assert_eq!(r.shared.snapshot.read(), Some(before));
        assert!(before.bridge_on);
    }

    /// A drive command is the slow context's: served after the job of the next tick — not
    /// by the control interrupt in the periods before, whatever their number — its reply
    /// then, its effect on the bridge at the plan's adoption (a plan's delay later);
    /// `Status` reports the raw samples of the tick's period.
    #[test]
    fn a_drive_command_is_served_at_a_tick_and_acts_at_the_adoption() {
        let mut r = Rig::new();
        r.step_to_before_a_tick();
        r.period(at_rest());
        assert!(r.post(BoardCommand::GetStatus));
        while !r.ctl.fast().slow_step_due() {
            r.period(at_rest());
            assert_eq!(r.shared.commands.take(), None, "not served between ticks");
        }
        let s = Samples { i_abc: [2050, 2047, 2046], vdc: 3105, encoder: 0, hardware_break: false };
        r.period(s);
        let Some(Reply::Status { readings, mode, .. }) = r.shared.commands.take() else { panic!("a status") };
        assert_eq!(
            (readings.i_abc_counts, readings.vdc_counts, readings.encoder_counts, mode),
            (s.i_abc, s.vdc, s.encoder, Mode::Idle)
        );
        assert!(r.post(BoardCommand::Enable));
        r.step_to_before_a_tick();
        r.period(at_rest());
        assert_eq!(r.shared.commands.take(), Some(Reply::Ack));
        for _ in 1..r.ctl.config().plan_delay() {
            assert_eq!(r.ctl.fast().mode(), Mode::Idle, "the bridge's mode changes at the adoption");
            r.period(at_rest());
        }
        r.period(at_rest());
        assert_eq!(r.ctl.fast().mode(), Mode::Magnetizing);
    }

    /// The watchdog's stop: the slow context's controlled stop at the next tick (Magnetizing:
    /// the bridge off at the adoption), carried out once.
    #[test]
    fn the_watchdogs_stop_acts_at_the_next_ticks_adoption() {
        let mut r = Rig::new();
        r.enable_past_the_precharge();
        r.shared.watchdog_stop.store(true, Ordering::Relaxed);
        while !r.ctl.fast().slow_step_due() {
            r.period(at_rest());
            assert!(r.shared.watchdog_stop.load(Ordering::Relaxed), "waits for the tick");
        }
        r.period(at_rest());
        assert!(!r.shared.watchdog_stop.load(Ordering::Relaxed), "carried out once");
        for _ in 0..r.ctl.config().plan_delay() {
            assert_eq!(r.ctl.fast().mode(), Mode::Magnetizing, "until the adoption");
            r.period(at_rest());
        }
        assert_eq!(r.ctl.fast().mode(), Mode::Idle, "Magnetizing: the controlled stop is the bridge off");
    }

    /// The capture's commands are the link task's (`crate::scope`), never posted: one posted
    /// anyway is refused by the control interrupt in the next period without the slow step
    /// in flight — nothing of the capture's read-out runs there.
    #[test]
    fn a_posted_capture_command_is_refused_by_the_control_interrupt() {
        let mut r = Rig::new();
        r.step_to_before_a_tick();
        r.period(at_rest());
        while r.ctl.slow_busy() {
            r.period(at_rest());
        }
        assert!(server::link_task_serves(&BoardCommand::ReadCapture { chunk: 0 }));
        assert!(r.post(BoardCommand::ReadCapture { chunk: 0 }));
        r.period(at_rest());
        assert_eq!(
            r.shared.commands.take(),
            Some(Reply::Nack(controller_core::link::NackReason::Unsupported))
        );
    }

    /// While a commissioning sequence runs, the drive's commands are the control interrupt's:
    /// an `Enable` is refused and a `Stop` aborts the sequence — never a slow context's
    /// enable or controlled stop of the drive beside the running sequence.
    #[cfg(feature = "commissioning")]
    #[test]
    fn a_sequences_stop_is_the_control_interrupts() {
        use controller_core::commission::CommissionSpec;
        use controller_core::link::NackReason;
        let mut r = Rig::new();
        let spec = CommissionSpec {
            pwm_hz: 20_000.0,
            test_current_a: 1.0,
            current_limit_a: 2.0,
            vdc_min_v: 250.0,
            vdc_max_v: 370.0,
            level_time_s: 1.0,
            rotate: false,
            rated_flux_wb: 0.823,
            no_load_hz: 15.0,
            curve: false,
        };
        let cmd = BoardCommand::Commission(spec);
        // Served by the control interrupt once the rest check has passed (its windows).
        let mut reply = None;
        for _ in 0..4_000 {
            if reply.is_none() {
                let _ = r.shared.commands.post((cmd, server::prepare(&cmd), LinkStats::default()));
            }
            r.period(at_rest());
            reply = r.shared.commands.take();
            if reply == Some(Reply::Ack) {
                break;
            }
            reply = None;
        }
        assert_eq!(reply, Some(Reply::Ack));
        assert!(r.ctl.commissioning());
        for (cmd, want) in
            [(BoardCommand::Enable, Reply::Nack(NackReason::NotIdle)), (BoardCommand::Stop, Reply::Ack)]
        {
            // Posted for a tick's period: the slow context has its turn first.
            r.step_to_before_a_tick();
            assert!(r.post(cmd));
            let mut got = None;
            for _ in 0..2 * r.ctl.config().slow_divider() {
                r.period(at_rest());
                got = r.shared.commands.take();
                if got.is_some() {
                    break;
                }
            }
            assert_eq!(got, Some(want), "{cmd:?}");
        }
        assert!(!r.ctl.commissioning(), "aborted");
        assert_eq!(r.ctl.fast().mode(), Mode::Idle);
    }
}
