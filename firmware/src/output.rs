//! The bridge's output stage: what the control interrupt does with TIM1's main output enable
//! (MOE), its break flag (BIF) and the compare registers, behind the [`OutputStage`] trait so
//! that the sequence is tested on the host against a model of the timer and its break input
//! (its unit tests). `main.rs` implements the trait on the registers.
//!
//! Rules (each a defect once — see docs/firmware.md):
//! - MOE is set only on an explicit enable (the drive asking for the bridge after it was
//!   off), never "whenever it reads 0": a comparator pulse that ended inside a step must not
//!   be undone by the next write.
//! - MOE found at 0 while the firmware expects it at 1 is a hardware break, whether or not
//!   the flag was seen.
//! - BIF is cleared by writing a mask (the status bits are `rc_w0`: a read-modify-write would
//!   clear flags set between the read and the write).
//! - After the explicit enable the flag is read once more: a break that fell between the
//!   first read and the write of MOE is in BIF, and the outputs go off again at once.
//! - MOE is set one period after the compare values that are to drive the bridge were
//!   written (issue 54): they are preloaded, and the update event that makes them active
//!   comes between this period's write and the next. Set in the same period, the bridge
//!   first switched the values left active — 50 % on every phase after reset, a stopped
//!   run's last duties after a re-enable — for the rest of that period (nearly all of its
//!   50 µs at 20 kHz) instead of the pre-charge's zero vector.

use crate::control::{Bridge, ControlLoop, Samples};
use controller_core::fault::Fault;

/// The control interrupt's register actions on the PWM timer.
pub trait OutputStage {
    /// The break flag: the hardware comparator fired since it was last cleared.
    fn break_flag(&mut self) -> bool;
    /// Clear the break flag (and only it).
    fn clear_break_flag(&mut self);
    /// The main output enable as the hardware has it now.
    fn outputs_enabled(&mut self) -> bool;
    /// Compare values for the next period.
    fn set_compare(&mut self, ccr: [u16; 3]);
    /// Set MOE.
    fn enable_outputs(&mut self);
    /// Clear MOE.
    fn disable_outputs(&mut self);
    /// The brake chopper's switch (a GPIO, not TIM1: it acts whether or not the bridge is).
    fn set_brake(&mut self, on: bool);
}

/// Where the output stage is on the way from off to switching.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
enum Stage {
    /// MOE 0, nothing written for the bridge.
    #[default]
    Off,
    /// The first compare values written (preloaded: active from the next update event);
    /// MOE still 0.
    Loaded,
    /// MOE set by the firmware, which so expects it at 1.
    Armed,
}

/// Whether the firmware has enabled the outputs (and so expects MOE = 1).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Outputs {
    stage: Stage,
}

impl Outputs {
    /// Outputs off, as after reset.
    pub const fn new() -> Self {
        Self { stage: Stage::Off }
    }

    /// One control period: break detection, the control step, the output stage. The break
    /// flag or a lost MOE is added to `samples.hardware_break` (by reference: the caller keeps
    /// the samples for a command's `Status`).
    pub fn period(
        &mut self,
        hw: &mut impl OutputStage,
        ctl: &mut ControlLoop,
        samples: &mut Samples,
    ) -> Bridge {
        let flagged = hw.break_flag();
        let lost = self.stage == Stage::Armed && !hw.outputs_enabled();
        if flagged {
            hw.clear_break_flag();
        }
        samples.hardware_break |= flagged || lost;
        let bridge = ctl.step(samples);
        hw.set_brake(ctl.brake());
        match bridge {
            Bridge::Compare(ccr) => {
                hw.set_compare(ccr);
                match self.stage {
                    Stage::Armed => {}
                    // The values active now are the ones written last period: MOE on.
                    Stage::Loaded => {
                        hw.enable_outputs();
                        self.stage = Stage::Armed;
                        if hw.break_flag() {
                            // The break fell between the first read and the enable: off
                            // again. The next period finds MOE = 0 while armed and latches
                            // the fault.
                            hw.disable_outputs();
                        }
                    }
                    Stage::Off => self.stage = Stage::Loaded,
                }
            }
            Bridge::Off => {
                hw.disable_outputs();
                self.stage = Stage::Off;
            }
        }
        bridge
    }
}

impl Outputs {
    /// Two periods running overran ([`crate::control::LoopTimer::record`]): the drive latches
    /// [`Fault::Overrun`] and the bridge goes off now, not at the next period's step (which
    /// then finds the fault latched and keeps it off). Out of line: a fault's path.
    #[cold]
    #[inline(never)]
    pub fn overrun(&mut self, hw: &mut impl OutputStage, ctl: &mut ControlLoop) {
        ctl.trip(Fault::Overrun);
        hw.disable_outputs();
        self.stage = Stage::Off;
    }
}

/// What the panic and HardFault handlers do, in this order: mask every interrupt (so no
/// control interrupt can run again and touch MOE), then clear MOE and switch the brake
/// chopper off (nothing regulates the bus any more: a resistor left across a rectifier-fed
/// link would burn; the over-voltage is the power board's own protection's). Nothing
/// re-enables the outputs afterwards; the watchdog resets the MCU.
pub fn stop_for_good(mask_interrupts: impl FnOnce(), hw: &mut impl OutputStage) {
    mask_interrupts();
    hw.disable_outputs();
    hw.set_brake(false);
}

#[cfg(test)]
mod tests {
    use crate::control::run_slow;
    use crate::control::tests::cell;
    extern crate std;
    use super::*;
    use crate::config::{BOARD, DRIVE_CONFIG};
    use controller_core::drive::Mode;
    use std::vec::Vec;

    /// TIM1's main output and break logic: a break pulse clears MOE and sets BIF in hardware;
    /// MOE cannot be set while the break input is active. `pulse_at` injects a one-operation
    /// break pulse before the register operation with that index.
    #[derive(Debug, Default)]
    struct ModelTimer {
        moe: bool,
        bif: bool,
        ops: usize,
        pulse_at: Option<usize>,
        fired: bool,
        interrupts_masked: bool,
        brake: bool,
    }

    impl ModelTimer {
        fn op(&mut self) {
            if self.pulse_at == Some(self.ops) {
                self.moe = false;
                self.bif = true;
                self.fired = true;
            }
            self.ops += 1;
        }
    }

    impl OutputStage for ModelTimer {
        fn break_flag(&mut self) -> bool {
            self.op();
            self.bif
        }
        fn clear_break_flag(&mut self) {
            self.op();
            self.bif = false;
        }
        fn outputs_enabled(&mut self) -> bool {
            self.op();
            self.moe
        }
        fn set_compare(&mut self, _: [u16; 3]) {
            self.op();
        }
        fn enable_outputs(&mut self) {
            self.op();
            self.moe = true;
        }
        fn disable_outputs(&mut self) {
            self.op();
            self.moe = false;
        }
        fn set_brake(&mut self, on: bool) {
            self.brake = on;
        }
    }

    fn at_rest() -> Samples {
        Samples { i_abc: [2048; 3], vdc: 3100, encoder: 0, hardware_break: false }
    }

    /// Issue 19: a break injected before any register operation of any of the first periods
    /// after enable never leaves MOE at 1 when that period ends, nor in any period after it,
    /// and the drive latches `HardwareBreak` by the end of the next period.
    #[test]
    fn a_break_at_any_point_of_a_step_never_ends_with_moe_set() {
        let mut cases = 0;
        // The first four periods after enable take ≤ 4 operations each: 16 injection points.
        for pulse_op in 0..16 {
            let mut ctl = ControlLoop::new(&DRIVE_CONFIG, &BOARD, cell(), run_slow).unwrap();
            ctl.calibrate_at_rest();
            ctl.drive_mut(|mut d| d.enable()).unwrap().unwrap();
            let (mut out, mut hw) =
                (Outputs::new(), ModelTimer { pulse_at: Some(pulse_op), ..Default::default() });
            let mut fired_in = None;
            for k in 0..8 {
                out.period(&mut hw, &mut ctl, &mut at_rest());
                if hw.fired && fired_in.is_none() {
                    fired_in = Some(k);
                }
                if let Some(f) = fired_in {
                    assert!(!hw.moe, "break at op {pulse_op} (period {f}): MOE = 1 after period {k}");
                    if k > f {
                        assert_eq!(ctl.fast().mode(), Mode::Fault(Fault::HardwareBreak), "op {pulse_op}");
                    }
                }
            }
            if fired_in.is_some() {
                cases += 1;
            }
        }
        assert_eq!(cases, 16);
    }

    /// The brake switch follows the drive's comparator on the bus code in every mode: on above
    /// the drive file's `on_v` (360 V = code 3600 at 0.1 V per count), held down to `off_v`
    /// (350 V), off below — with the bridge off, running, and after a fault.
    #[test]
    fn the_brake_follows_the_bus_in_every_mode() {
        let mut ctl = ControlLoop::new(&DRIVE_CONFIG, &BOARD, cell(), run_slow).unwrap();
        ctl.calibrate_at_rest();
        let (mut out, mut hw) = (Outputs::new(), ModelTimer::default());
        let bus = |out: &mut Outputs, hw: &mut ModelTimer, ctl: &mut ControlLoop, code: u16| {
            out.period(hw, ctl, &mut Samples { vdc: code, ..at_rest() });
            hw.brake
        };
        let sweep = [(3590, false), (3601, true), (3550, true), (3501, true), (3499, false), (3550, false)];
        for (code, on) in sweep {
            assert_eq!(bus(&mut out, &mut hw, &mut ctl, code), on, "idle, code {code}");
        }
        ctl.drive_mut(|mut d| d.enable()).unwrap().unwrap();
        for (code, on) in sweep {
            assert_eq!(bus(&mut out, &mut hw, &mut ctl, code), on, "enabled, code {code}");
        }
        // An over-voltage trips the drive; the chopper goes on regulating the bus.
        assert!(bus(&mut out, &mut hw, &mut ctl, 4010));
        assert!(matches!(ctl.fast().mode(), Mode::Fault(Fault::DcBusOvervoltage)));
        assert!(!hw.moe);
        assert!(bus(&mut out, &mut hw, &mut ctl, 3550));
        assert!(!bus(&mut out, &mut hw, &mut ctl, 3400));
    }

    /// TIM1's compare registers with preload: a write goes to the preload register, the
    /// update event between two control periods makes it active.
    #[derive(Debug, Default)]
    struct Preloaded {
        timer: ModelTimer,
        preload: [u16; 3],
        active: [u16; 3],
        /// The active values while MOE was 1, at any register operation.
        switched: Vec<[u16; 3]>,
    }

    impl Preloaded {
        /// After reset: the start-up's 50 % in both registers.
        fn after_reset() -> Self {
            let half = BOARD.pwm_period_counts / 2;
            Self { preload: [half; 3], active: [half; 3], ..Default::default() }
        }
        fn update_event(&mut self) {
            self.active = self.preload;
        }
        fn note(&mut self) {
            if self.timer.moe {
                self.switched.push(self.active);
            }
        }
    }

    impl OutputStage for Preloaded {
        fn break_flag(&mut self) -> bool {
            self.note();
            self.timer.break_flag()
        }
        fn clear_break_flag(&mut self) {
            self.timer.clear_break_flag();
        }
        fn outputs_enabled(&mut self) -> bool {
            self.timer.outputs_enabled()
        }
        fn set_compare(&mut self, c: [u16; 3]) {
            self.note();
            self.preload = c;
        }
        fn enable_outputs(&mut self) {
            self.timer.enable_outputs();
            self.note();
        }
        fn disable_outputs(&mut self) {
            self.timer.disable_outputs();
        }
        fn set_brake(&mut self, on: bool) {
            self.timer.set_brake(on);
        }
    }

    /// Issue 54: from the instant MOE is set until the drive's first own period is active,
    /// the bridge switches the pre-charge's zero vector (compare 0: all low sides on) — at
    /// the first enable after reset (the start-up's 50 % left active) and at a re-enable
    /// after a run (its last duties left active) alike. Set in the period that wrote the
    /// pre-charge's values, MOE switched the values left active for the rest of it.
    #[test]
    fn the_bridge_switches_the_precharge_pattern_from_the_first_instant() {
        let mut ctl = ControlLoop::at_rest_for_tests();
        let (mut out, mut hw) = (Outputs::new(), Preloaded::after_reset());
        let period = |out: &mut Outputs, hw: &mut Preloaded, ctl: &mut ControlLoop| {
            let b = out.period(hw, ctl, &mut at_rest());
            hw.update_event();
            hw.note();
            b
        };
        for run in 0..2 {
            ctl.drive_mut(|mut d| d.enable()).unwrap().unwrap();
            for _ in 0..BOARD.bootstrap_precharge_periods {
                assert_eq!(period(&mut out, &mut hw, &mut ctl), Bridge::Compare([0; 3]));
            }
            assert!(hw.timer.moe, "run {run}: the bridge is on by the pre-charge's end");
            assert!(!hw.switched.is_empty());
            assert!(
                hw.switched.iter().all(|&c| c == [0; 3]),
                "run {run}: the bridge switched {:?} during the pre-charge",
                hw.switched.iter().find(|&&c| c != [0; 3])
            );
            // The drive's own duties, then a stop: they stay in the registers.
            for _ in 0..20 {
                assert!(matches!(period(&mut out, &mut hw, &mut ctl), Bridge::Compare(_)));
            }
            assert_ne!(hw.active, [0; 3], "the drive switches its own duties");
            ctl.drive_mut(|mut d| d.disable()).unwrap();
            assert_eq!(period(&mut out, &mut hw, &mut ctl), Bridge::Off);
            assert!(!hw.timer.moe);
            hw.switched.clear();
        }
    }

    /// Issue 54: an overrun stops the bridge at once and for good — the drive latches
    /// `Overrun` (the first fault: the MOE the firmware finds cleared in the next period is
    /// no second one), no later period sets MOE, and only `ClearFault` and an enable start
    /// it again.
    #[test]
    fn an_overrun_turns_the_bridge_off_and_latches() {
        let mut ctl = ControlLoop::at_rest_for_tests();
        let (mut out, mut hw) = (Outputs::new(), ModelTimer::default());
        ctl.drive_mut(|mut d| d.enable()).unwrap().unwrap();
        for _ in 0..60 {
            out.period(&mut hw, &mut ctl, &mut at_rest());
        }
        assert!(hw.moe);
        out.overrun(&mut hw, &mut ctl);
        assert!(!hw.moe);
        for _ in 0..100 {
            assert_eq!(out.period(&mut hw, &mut ctl, &mut at_rest()), Bridge::Off);
            assert!(!hw.moe);
        }
        assert_eq!(ctl.fast().mode(), Mode::Fault(Fault::Overrun));
        ctl.drive_mut(|mut d| d.clear_fault()).unwrap();
        ctl.drive_mut(|mut d| d.enable()).unwrap().unwrap();
        for _ in 0..60 {
            out.period(&mut hw, &mut ctl, &mut at_rest());
        }
        assert!(hw.moe, "a new enable runs again");
    }

    /// The outputs are enabled once, on the drive's request, and not re-written while on.
    #[test]
    fn moe_is_written_only_on_an_explicit_enable() {
        #[derive(Default)]
        struct Count(ModelTimer, usize);
        impl OutputStage for Count {
            fn break_flag(&mut self) -> bool {
                self.0.break_flag()
            }
            fn clear_break_flag(&mut self) {
                self.0.clear_break_flag()
            }
            fn outputs_enabled(&mut self) -> bool {
                self.0.outputs_enabled()
            }
            fn set_compare(&mut self, c: [u16; 3]) {
                self.0.set_compare(c)
            }
            fn enable_outputs(&mut self) {
                self.1 += 1;
                self.0.enable_outputs()
            }
            fn disable_outputs(&mut self) {
                self.0.disable_outputs()
            }
            fn set_brake(&mut self, on: bool) {
                self.0.set_brake(on)
            }
        }
        let mut ctl = ControlLoop::at_rest_for_tests();
        let (mut out, mut hw) = (Outputs::new(), Count::default());
        for _ in 0..10 {
            assert_eq!(out.period(&mut hw, &mut ctl, &mut at_rest()), Bridge::Off);
        }
        ctl.drive_mut(|mut d| d.enable()).unwrap().unwrap();
        for _ in 0..100 {
            assert!(matches!(out.period(&mut hw, &mut ctl, &mut at_rest()), Bridge::Compare(_)));
        }
        assert_eq!(hw.1, 1);
        assert!(hw.0.moe);
        // MOE cleared behind the firmware's back (a break whose flag was lost): a fault.
        hw.0.moe = false;
        assert_eq!(out.period(&mut hw, &mut ctl, &mut at_rest()), Bridge::Off);
        assert_eq!(ctl.fast().mode(), Mode::Fault(Fault::HardwareBreak));
        assert_eq!(hw.1, 1);
    }

    /// Issue 19: after a panic or a HardFault the control interrupt never runs again, so MOE
    /// stays 0 for as long as one looks (here 1 000 periods of a scheduler that runs the
    /// interrupt only while interrupts are not masked).
    #[test]
    fn after_stop_for_good_moe_stays_off() {
        let mut ctl = ControlLoop::new(&DRIVE_CONFIG, &BOARD, cell(), run_slow).unwrap();
        ctl.calibrate_at_rest();
        ctl.drive_mut(|mut d| d.enable()).unwrap().unwrap();
        let (mut out, mut hw) = (Outputs::new(), ModelTimer::default());
        for _ in 0..10 {
            out.period(&mut hw, &mut ctl, &mut at_rest());
        }
        assert!(hw.moe);
        // The bus above the shipped chopper's 360 V: the brake is on when the stop comes.
        let mut high_bus = Samples { vdc: 3700, ..at_rest() };
        out.period(&mut hw, &mut ctl, &mut high_bus);
        assert!(hw.brake && hw.moe);
        let mut masked = false;
        stop_for_good(|| masked = true, &mut hw);
        assert!(!hw.brake);
        hw.interrupts_masked = masked;
        for _ in 0..1000 {
            if !hw.interrupts_masked {
                out.period(&mut hw, &mut ctl, &mut high_bus);
            }
            assert!(!hw.moe && !hw.brake);
        }
        // Had the mask been forgotten, the next period would have re-enabled the bridge only
        // through an explicit enable: the drive is still Running, so `armed` finds MOE = 0
        // and latches a fault instead — the defence in depth the rules above give.
        hw.interrupts_masked = false;
        out.period(&mut hw, &mut ctl, &mut at_rest());
        assert!(!hw.moe);
        assert_eq!(ctl.fast().mode(), Mode::Fault(Fault::HardwareBreak));
    }
}
