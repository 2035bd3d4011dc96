//! The microcontroller's own failures routed to the bridge's break: what `main.rs` writes to
//! SYSCFG_CFGR2 and PWR_CR2 at start-up, and the read-back check it applies, kept here so
//! that the words are host-tested (RM0440 §9.1.6 SYSCFG_CFGR2, §6.4.2 PWR_CR2).
//!
//! TIM1's break input takes, besides the power board's comparator on BKIN, a *system break*
//! from four sources once each is linked (its lock bit set; write-once until reset):
//!
//! | bit | source | what it catches |
//! | --- | --- | --- |
//! | CLL (0) | Cortex-M4 lockup | a fault inside the HardFault handler |
//! | SPL (1) | SRAM parity error | a flipped bit in SRAM (with the SRAM_PE option byte set; without it the link stays inactive) |
//! | PVDL (2) | programmable voltage detector | V_DD below [`PVD_LEVEL_CODE`]'s ≈ 2.8 V |
//! | ECCL (3) | flash ECC double error | an uncorrectable bit pair in the code (also the NMI, which the default handler turns into a stop for good) |
//!
//! A system break clears MOE in hardware like the comparator; the control interrupt finds
//! MOE at 0 while armed and latches `HardwareBreak` (`firmware::output`). Until issue 54 only
//! CLL was set.

/// SYSCFG_CFGR2.CLL: the core's lockup output to TIM1's break.
pub const CFGR2_CLL: u32 = 1 << 0;
/// SYSCFG_CFGR2.SPL: SRAM parity errors to TIM1's break.
pub const CFGR2_SPL: u32 = 1 << 1;
/// SYSCFG_CFGR2.PVDL: the PVD's output to TIM1's break (and PWR_CR2's PVDE and PLS locked).
pub const CFGR2_PVDL: u32 = 1 << 2;
/// SYSCFG_CFGR2.ECCL: flash ECC double errors to TIM1's break.
pub const CFGR2_ECCL: u32 = 1 << 3;
/// SYSCFG_CFGR2.SPF: the SRAM parity error flag (`rc_w1`: writing 1 clears it; the word
/// written leaves it 0, untouched).
pub const CFGR2_SPF: u32 = 1 << 8;

/// The word written to SYSCFG_CFGR2: every system-break source linked.
pub const BREAK_LINKS: u32 = CFGR2_CLL | CFGR2_SPL | CFGR2_PVDL | CFGR2_ECCL;

/// PWR_CR2.PLS for the PVD's falling threshold: 0b101, V_PVD5 ≈ 2.8 V (the data sheet's
/// table gives the range). The NUCLEO supplies 3.3 V; the ADC's references and the gate
/// drivers' logic levels are off well before the 1.71 V the core runs down to, and the
/// 2.8 V level stops the bridge while they still hold.
pub const PVD_LEVEL_CODE: u8 = 0b101;
// PLS is a 3-bit field, and 0b111 selects the external PVD_IN pin, not a level.
const _: () = assert!(PVD_LEVEL_CODE < 0b111);

/// The read-back of SYSCFG_CFGR2 after [`BREAK_LINKS`] was written: a link that did not take
/// (a register written elsewhere first cannot clear a lock bit, but a wrong word could
/// leave one out) keeps the bridge off.
pub fn check_break_links(read: u32) -> Result<(), BreakLinksError> {
    if read & BREAK_LINKS == BREAK_LINKS { Ok(()) } else { Err(BreakLinksError { read }) }
}

/// SYSCFG_CFGR2 read back without every system-break link.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BreakLinksError {
    /// The register as read.
    pub read: u32,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// RM0440 §9.1.6: CLL, SPL, PVDL, ECCL are bits 0–3; SPF (bit 8, `rc_w1`) stays 0 in the
    /// word written.
    #[test]
    fn every_system_break_source_is_linked() {
        assert_eq!(BREAK_LINKS, 0b1111);
        assert_eq!(BREAK_LINKS & CFGR2_SPF, 0);
        assert_eq!(check_break_links(BREAK_LINKS), Ok(()));
        // A parity flag set meanwhile does not matter.
        assert_eq!(check_break_links(BREAK_LINKS | CFGR2_SPF), Ok(()));
        // Any link missing keeps the bridge off (CLL alone was the state before issue 54).
        for bit in [CFGR2_CLL, CFGR2_SPL, CFGR2_PVDL, CFGR2_ECCL] {
            let read = BREAK_LINKS & !bit;
            assert_eq!(check_break_links(read), Err(BreakLinksError { read }));
        }
        assert!(check_break_links(CFGR2_CLL).is_err());
    }
}
