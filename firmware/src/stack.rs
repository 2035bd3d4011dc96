//! The main stack's high-water mark, measured on the board (issue 19).
//!
//! cortex-m-rt paints the whole stack region — flip-link puts it at the bottom of RAM, below
//! the statics: `_stack_end` (its lowest address, RAM's start) up to `_stack_start` — with
//! [`PAINT`] before `main` (its `paint-stack` feature). The stack grows down from
//! `_stack_start`; the words it ever reached no longer hold the paint. The high-water mark is
//! the region's size less the run of paint at its bottom. The link task counts it for
//! `Status` (thread mode; one scan of the region, 88 824 B with drive.toml — `_stack_start`
//! less `_stack_end` in `llvm-nm` of the image — up to the first overwritten word), so it covers the executor's polls and every
//! interrupt at its deepest, the control interrupt's command path included — what QEMU's
//! measurement of `Drive::step` alone cannot.
//!
//! A word the stack used that happens to hold the paint again reads as unused; a frame is
//! never all paint, so the mark can fall short by the words of the deepest frame below its
//! last written one, not more.

/// cortex-m-rt's `STACK_PAINT_VALUE` (its `paint-stack` feature).
pub const PAINT: u32 = 0xCCCC_CCCC;

/// Bytes of a stack region of `words` words ever used: `word(i)` reads its `i`-th word from
/// the bottom (lowest address). The region less its bottom run of [`PAINT`].
pub fn used_bytes(words: usize, word: impl Fn(usize) -> u32) -> usize {
    let unused = (0..words).find(|&i| word(i) != PAINT).unwrap_or(words);
    (words - unused) * 4
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_mark_is_the_region_less_its_bottom_run_of_paint() {
        let mut region = [PAINT; 64];
        assert_eq!(used_bytes(region.len(), |i| region[i]), 0, "untouched");
        // A stack that reached word 40 from the bottom (24 words from the top), with a word
        // that happens to hold the paint above it.
        for w in region.iter_mut().skip(40) {
            *w = 0x2000_1234;
        }
        region[50] = PAINT;
        assert_eq!(used_bytes(region.len(), |i| region[i]), 24 * 4);
        region[0] = 0;
        assert_eq!(used_bytes(region.len(), |i| region[i]), 64 * 4, "all of it: the next push overflows");
        assert_eq!(used_bytes(0, |_| 0), 0);
    }
}
