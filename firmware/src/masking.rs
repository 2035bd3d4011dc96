//! The critical section the board's runtime takes (embassy's executor and time driver, the
//! link task's queues): BASEPRI raised to [`SECTION_LEVEL`], which masks every interrupt but
//! those at priority 0 — the control interrupt's — instead of PRIMASK, which delayed the
//! control interrupt by each section's length (issue 54).
//!
//! | context | NVIC priority | inside a section |
//! | --- | --- | --- |
//! | `ADC1_2`, the control interrupt | 0 | runs |
//! | `TIM3`, embassy's time driver | 4 (0x40) | waits |
//! | `LPUART1`, the link | 5 (0x50) | waits |
//!
//! BASEPRI compares the group priority; embassy leaves PRIGROUP at 0, so all four of the
//! STM32G4's priority bits are group bits ([`PRIORITY_BITS`]).
//!
//! **Sound only if no context left running takes a section**: a section does not exclude
//! the control interrupt, so the control interrupt must share its data without one (it does:
//! `firmware::boundary`'s lock-free hand-over, `firmware::interrupt`). A section entered from
//! such a context ([`may_enter`] false) is refused with an undefined instruction — a
//! HardFault, whose handler turns the bridge off for good — instead of being left
//! unprotected.

/// The NVIC's implemented priority bits on the STM32G4 (PM0214 §4.3.7: the upper four bits
/// of each priority byte).
pub const PRIORITY_BITS: u32 = 4;

/// BASEPRI of a section: the priority one step below the control interrupt's 0, the least
/// implemented step `1 << (8 − PRIORITY_BITS)` (embassy's `Priority::P1`, 0x10). It masks
/// every priority value at or above it.
pub const SECTION_LEVEL: u8 = 1 << (8 - PRIORITY_BITS);

/// The least priority step that BASEPRI can mask apart from priority 0 on an NVIC that
/// reads `implemented` back from a priority register written with 0xFF (its implemented
/// bits), with the group-priority split `prigroup` (SCB_AIRCR.PRIGROUP: the group priority
/// is bits `[7 : prigroup + 1]`, and BASEPRI compares the group priority only): the BASEPRI
/// of a section on that NVIC. `None` when no group bit is implemented. On the STM32G4 (four
/// bits, PRIGROUP 0 from reset, which the firmware keeps) it is [`SECTION_LEVEL`].
pub const fn least_step(implemented: u8, prigroup: u8) -> Option<u8> {
    let group = if prigroup >= 7 { 0 } else { implemented & (0xFF << (prigroup + 1)) };
    match group & group.wrapping_neg() {
        0 => None,
        step => Some(step),
    }
}

// The board's level is the least group step of its four bits under PRIGROUP 0.
const _: () = assert!(matches!(least_step(0xF0, 0), Some(SECTION_LEVEL)));

/// A context may take a section of BASEPRI `level` when the section excludes it: thread mode
/// (`active` `None`), or an exception whose priority value `Some(p)` the level masks
/// (`p ≥ level`). NMI and HardFault (fixed priorities above every configurable one) pass as
/// `Some(0)`: never.
pub const fn may_enter(active: Option<u8>, level: u8) -> bool {
    match active {
        None => true,
        Some(p) => p >= level,
    }
}

/// The section on the Cortex-M's registers.
#[cfg(target_os = "none")]
pub mod cortex {
    use core::sync::atomic::{Ordering, compiler_fence};
    use cortex_m::interrupt::InterruptNumber;
    use cortex_m::peripheral::scb::{Exception, SystemHandler, VectActive};
    use cortex_m::peripheral::{NVIC, SCB};

    /// An external interrupt by number, for the NVIC's priority register.
    #[derive(Clone, Copy)]
    struct Irq(u16);

    // SAFETY: `number` returns the number the active vector names (IPSR − 16, < 240): an
    // interrupt the NVIC has.
    unsafe impl InterruptNumber for Irq {
        fn number(self) -> u16 {
            self.0
        }
    }

    /// The priority value of the context running now: `None` in thread mode, `Some(0)` for
    /// the NMI and the HardFault (fixed, above every configurable priority).
    pub fn active_priority() -> Option<u8> {
        let handler = match SCB::vect_active() {
            VectActive::ThreadMode => return None,
            VectActive::Interrupt { irqn } => return Some(NVIC::get_priority(Irq(u16::from(irqn)))),
            VectActive::Exception(e) => match e {
                Exception::MemoryManagement => SystemHandler::MemoryManagement,
                Exception::BusFault => SystemHandler::BusFault,
                Exception::UsageFault => SystemHandler::UsageFault,
                Exception::SVCall => SystemHandler::SVCall,
                Exception::DebugMonitor => SystemHandler::DebugMonitor,
                Exception::PendSV => SystemHandler::PendSV,
                Exception::SysTick => SystemHandler::SysTick,
                _ => return Some(0),
            },
        };
        Some(SCB::get_priority(handler))
    }

    /// Enter a section of BASEPRI `level`: returns the BASEPRI before, raises it to `level`
    /// (BASEPRI_MAX: a nested section never lowers it).
    #[inline]
    pub fn enter(level: u8) -> u8 {
        let before = cortex_m::register::basepri::read();
        cortex_m::register::basepri_max::write(level);
        compiler_fence(Ordering::SeqCst);
        before
    }

    /// Leave a section: BASEPRI back to `before` ([`enter`]'s).
    ///
    /// # Safety
    /// `before` is what the matching [`enter`] returned, and the sections nest (the
    /// critical-section crate's contract).
    #[inline]
    pub unsafe fn leave(before: u8) {
        compiler_fence(Ordering::SeqCst);
        // SAFETY: restores the masking of the matching `enter` (the caller's contract); a
        // lower BASEPRI only lets interrupts run that the enclosing context allowed.
        unsafe { cortex_m::register::basepri::write(before) }
    }
}

/// The board's critical section ([`SECTION_LEVEL`]).
#[cfg(all(target_os = "none", feature = "board"))]
mod board {
    use super::{SECTION_LEVEL, cortex, may_enter};

    struct Section;
    critical_section::set_impl!(Section);

    // SAFETY: a section masks every context that may take one ([`may_enter`]; the others
    // are refused), on one core, and restores the BASEPRI it found.
    unsafe impl critical_section::Impl for Section {
        unsafe fn acquire() -> u8 {
            if !may_enter(cortex::active_priority(), SECTION_LEVEL) {
                // Not excluded by the section: a HardFault (the bridge off for good) rather
                // than data left unprotected.
                cortex_m::asm::udf();
            }
            cortex::enter(SECTION_LEVEL)
        }

        unsafe fn release(before: u8) {
            // SAFETY: `before` is the matching acquire's (the crate's contract).
            unsafe { cortex::leave(before) }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The section's level is embassy's P1 on the STM32G4, and the least step of what an
    /// NVIC implements.
    #[test]
    fn the_section_masks_all_but_priority_zero() {
        assert_eq!(SECTION_LEVEL, 0x10);
        assert_eq!(least_step(0xF0, 0), Some(SECTION_LEVEL));
        // Eight bits: bit 0 is a subpriority under PRIGROUP 0, which BASEPRI ignores.
        assert_eq!((least_step(0xFF, 0), least_step(0xE0, 0), least_step(0, 0)), (Some(2), Some(0x20), None));
        assert_eq!((least_step(0xF0, 4), least_step(0xF0, 7)), (Some(0x20), None));
        // The control interrupt (0) and the fixed-priority faults may not take one; the
        // time driver (0x40), the link (0x50) and thread mode may.
        assert!(!may_enter(Some(0), SECTION_LEVEL));
        assert!(may_enter(Some(0x40), SECTION_LEVEL) && may_enter(Some(0x50), SECTION_LEVEL));
        assert!(may_enter(Some(SECTION_LEVEL), SECTION_LEVEL) && may_enter(None, SECTION_LEVEL));
    }
}
