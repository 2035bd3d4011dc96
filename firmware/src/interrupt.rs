//! The control interrupt's body once its samples are read, and what it shares with the link
//! task — free of the registers (those are behind [`OutputStage`]), so that the code the
//! board runs every period is the code QEMU counts (`qemu-target`'s `cost
//! interrupt_period`) and the host tests.
//!
//! ```text
//!  Samples ─▶ Outputs::period (break flag → ControlLoop::step → compare values, MOE)
//!          ─▶ the link watchdog's stop, a posted command (Mailbox)
//!          ─▶ the snapshot for the link task (TripleBuffer), when it asks for one
//! ```

use crate::boundary::{Mailbox, TripleBuffer};
use crate::control::{Bridge, ControlLoop, Samples, Snapshot};
use crate::output::{OutputStage, Outputs};
use crate::server::{self, Prepared};
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
    /// step ([`Outputs::period`]), then the link's requests — the watchdog's stop and a
    /// posted command take effect from the next period — and the snapshot, if the link task
    /// asked for one. A command and the snapshot wait while the drive's slow step is in
    /// flight ([`ControlLoop::slow_busy`]: from its tick to its plan's adoption, a plan's
    /// delay at most) — they act on, and read, its state — so that the longest period is
    /// the slow step's or theirs, not the sum (`cost interrupt_worst_period`, `cost
    /// interrupt_worst_command_period`); the watchdog's stop waits too (the controlled stop
    /// acts on the slow side's reference: a plan's delay at most, 100 µs at 20 kHz), its
    /// abort of a commissioning sequence does not.
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
        // Only this side clears the flags and the task only sets them (on one core: the
        // task cannot run between the load and the store), so a load and a store do what
        // a swap's exclusive-access loop would.
        if self.watchdog_stop.load(Ordering::Relaxed) && server::LinkWatchdog::stop(ctl) {
            self.watchdog_stop.store(false, Ordering::Relaxed);
        }
        // (`slow_busy` is asked only with a request: nothing added to a period without.)
        self.commands.serve(|(cmd, prepared, stats)| {
            if ctl.slow_busy() {
                return None;
            }
            ctl.note_readings(&samples);
            server::handle_board(ctl, cmd, *prepared, stats)
        });
        if self.snapshot_wanted.load(Ordering::Relaxed) && !ctl.slow_busy() {
            self.snapshot_wanted.store(false, Ordering::Relaxed);
            self.snapshot.write(ctl.snapshot());
        }
        bridge
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
    /// at rest).
    struct Rig {
        shared: Shared,
        outputs: Outputs,
        tim: Timer,
        ctl: ControlLoop<'static>,
    }

    impl Rig {
        fn new() -> Self {
            let (outputs, tim) = (Outputs::new(), Timer::default());
            Self { shared: Shared::new(), outputs, tim, ctl: ControlLoop::at_rest_for_tests() }
        }

        /// One control period on samples `s`.
        fn period(&mut self, s: Samples) {
            self.shared.control_period(&mut self.outputs, &mut self.tim, &mut self.ctl, s);
        }

        /// Periods at rest until the next one ends with no slow step of the drive in flight
        /// (in which the link's requests are served: `Shared::control_period`).
        fn step_to_a_period_without_the_slow_step(&mut self) {
            while self.ctl.slow_busy() || self.ctl.fast().slow_step_due() {
                self.period(at_rest());
            }
        }

        fn post(&self, cmd: BoardCommand) -> bool {
            self.shared.commands.post((cmd, Prepared::Nothing, LinkStats::default()))
        }
    }

    #[test]
    fn a_snapshot_is_published_after_the_period_that_follows_a_request_only() {
        let mut r = Rig::new();
        for _ in 0..3 {
            r.period(at_rest());
        }
        assert_eq!(r.shared.snapshot.read(), None, "nothing asked, nothing published");
        r.step_to_a_period_without_the_slow_step();
        r.shared.request_snapshot();
        r.period(at_rest());
        assert_eq!(r.shared.snapshot.read(), Some(r.ctl.snapshot()));
        // The request is spent: the drive moves on, the snapshot read stays the one taken.
        r.ctl.drive_mut(|mut d| d.enable()).unwrap().unwrap();
        r.period(at_rest());
        let held = r.shared.snapshot.read().unwrap();
        assert!(!held.bridge_on && r.ctl.snapshot().bridge_on);
        r.step_to_a_period_without_the_slow_step();
        r.shared.request_snapshot();
        r.period(at_rest());
        assert!(r.shared.snapshot.read().unwrap().bridge_on);
    }

    /// A command, a snapshot request and the watchdog's stop that find the drive's slow step
    /// in flight wait for the period that adopts its plan.
    #[test]
    fn the_links_requests_wait_while_the_slow_step_is_in_flight() {
        let mut r = Rig::new();
        r.ctl.drive_mut(|mut d| d.enable()).unwrap().unwrap();
        let mut guard = 0;
        while !(r.ctl.fast().slow_step_due() && r.ctl.fast().mode() == Mode::Magnetizing) && guard < 100 {
            r.period(at_rest());
            guard += 1;
        }
        assert!(guard < 100, "the pre-charge ends and a slow step comes");
        assert!(r.post(BoardCommand::GetStatus));
        r.shared.request_snapshot();
        // From the slow step's tick up to its plan's adoption: a plan's delay.
        for _ in 0..r.ctl.config().plan_delay() {
            r.period(at_rest());
            assert!(r.ctl.slow_busy());
            assert_eq!(r.shared.commands.take(), None, "not served while the slow step is in flight");
            assert_eq!(r.shared.snapshot.read(), None, "nor published");
        }
        r.period(at_rest());
        assert!(!r.ctl.slow_busy());
        assert!(matches!(r.shared.commands.take(), Some(Reply::Status { .. })));
        assert!(r.shared.snapshot.read().is_some());
        // The watchdog's stop in a slow step's period waits too (it acts on the slow side),
        // and is carried out in the period that adopts the plan.
        while !r.ctl.fast().slow_step_due() {
            r.period(at_rest());
        }
        r.shared.watchdog_stop.store(true, Ordering::Relaxed);
        for _ in 0..r.ctl.config().plan_delay() {
            r.period(at_rest());
            assert!(r.ctl.slow_busy());
            assert_eq!(r.ctl.fast().mode(), Mode::Magnetizing, "waits");
            assert!(r.shared.watchdog_stop.load(Ordering::Relaxed));
        }
        r.period(at_rest());
        assert_eq!(r.ctl.fast().mode(), Mode::Idle, "Magnetizing: the controlled stop is the bridge off");
        assert!(!r.shared.watchdog_stop.load(Ordering::Relaxed), "carried out once");
    }

    /// `Status` reports the raw samples of the period that serves it (noted then, not in
    /// every period).
    #[test]
    fn status_reports_the_samples_of_the_period_that_serves_it() {
        let mut r = Rig::new();
        r.step_to_a_period_without_the_slow_step();
        assert!(r.post(BoardCommand::GetStatus));
        let s = Samples { i_abc: [2050, 2047, 2046], vdc: 3105, encoder: 12, hardware_break: false };
        r.period(s);
        let Some(Reply::Status { readings, .. }) = r.shared.commands.take() else { panic!("a status") };
        assert_eq!(
            (readings.i_abc_counts, readings.vdc_counts, readings.encoder_counts),
            (s.i_abc, s.vdc, s.encoder)
        );
    }

    #[test]
    fn the_watchdogs_stop_and_a_posted_command_act_in_the_next_period() {
        let mut r = Rig::new();
        r.step_to_a_period_without_the_slow_step();
        assert!(r.post(BoardCommand::Enable));
        assert_eq!(r.shared.commands.take(), None, "not served before a period");
        r.period(at_rest());
        assert_eq!(r.shared.commands.take(), Some(Reply::Ack));
        assert_eq!(r.ctl.fast().mode(), Mode::Magnetizing);
        // Magnetizing, the watchdog's controlled stop is the bridge off at once.
        r.shared.watchdog_stop.store(true, Ordering::Relaxed);
        r.period(at_rest());
        assert_eq!(r.ctl.fast().mode(), Mode::Idle);
        assert!(!r.shared.watchdog_stop.load(Ordering::Relaxed), "the stop is carried out once");
    }
}
