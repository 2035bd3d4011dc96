//! The control interrupt → link task hand-over, lock-free: a triple buffer.
//!
//! The interrupt (the only writer) publishes a copy of what the task needs — the last
//! output, the calibration's state, whether the bridge is on — after every step; the task
//! (the only reader) takes the newest without masking the interrupt. Three slots: the one
//! the writer fills, the one the reader holds, and the one in between; an atomic swap hands
//! a slot from one side to the other, so the two never touch the same slot and no read is
//! ever torn (unlike a sequence lock, there is no racing copy to retry).

use core::cell::UnsafeCell;
use core::sync::atomic::{AtomicU8, Ordering};

/// The middle slot's index in the low bits, and this bit when it holds a value the reader
/// has not taken yet.
const FRESH: u8 = 0b100;
const INDEX: u8 = 0b011;

/// A single-writer, single-reader triple buffer of `T`.
pub struct TripleBuffer<T: Copy> {
    slots: (UnsafeCell<T>, UnsafeCell<T>, UnsafeCell<T>),
    /// The middle slot (index | FRESH).
    middle: AtomicU8,
    /// The writer's slot (touched by the writer only).
    back: AtomicU8,
    /// The reader's slot (touched by the reader only).
    front: AtomicU8,
}

// SAFETY: the slots are shared between one writer and one reader that never access the
// same slot at once: each side only touches the slot whose index it owns (`back`,
// `front`), and ownership moves between them only through the atomic swap of `middle`
// (AcqRel: the writes to a slot happen-before the reader's reads of it). `T: Send` since
// values cross from the interrupt to the task.
unsafe impl<T: Copy + Send> Sync for TripleBuffer<T> {}

impl<T: Copy> TripleBuffer<T> {
    /// Every slot holds `init`; nothing fresh.
    pub const fn new(init: T) -> Self {
        Self {
            slots: (UnsafeCell::new(init), UnsafeCell::new(init), UnsafeCell::new(init)),
            middle: AtomicU8::new(1),
            back: AtomicU8::new(0),
            front: AtomicU8::new(2),
        }
    }

    /// Slot `i` (0, 1, 2: the indices are a permutation of these by construction).
    fn slot(&self, i: u8) -> &UnsafeCell<T> {
        match i {
            0 => &self.slots.0,
            1 => &self.slots.1,
            _ => &self.slots.2,
        }
    }

    /// Publish `value` (the writer: one context only, e.g. the control interrupt).
    pub fn write(&self, value: T) {
        let back = self.back.load(Ordering::Relaxed) & INDEX;
        // SAFETY: `back` is the writer's slot: the reader holds `front`, and the middle is
        // neither (the three indices are always a permutation of 0, 1, 2).
        unsafe { *self.slot(back).get() = value };
        let old = self.middle.swap(back | FRESH, Ordering::AcqRel);
        self.back.store(old & INDEX, Ordering::Relaxed);
    }

    /// The newest value published (the reader: one context only, e.g. the link task); the
    /// last one taken again if nothing new came.
    pub fn read(&self) -> T {
        let mut front = self.front.load(Ordering::Relaxed) & INDEX;
        if self.middle.load(Ordering::Relaxed) & FRESH != 0 {
            let old = self.middle.swap(front, Ordering::AcqRel);
            front = old & INDEX;
            self.front.store(front, Ordering::Relaxed);
        }
        // SAFETY: `front` is the reader's slot: the writer fills `back` only.
        unsafe { *self.slot(front).get() }
    }
}

impl<T: Copy + core::fmt::Debug> core::fmt::Debug for TripleBuffer<T> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("TripleBuffer").field("middle", &self.middle.load(Ordering::Relaxed)).finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_reader_gets_the_newest_value() {
        let b = TripleBuffer::new(0u32);
        assert_eq!(b.read(), 0);
        b.write(1);
        b.write(2);
        assert_eq!(b.read(), 2);
        // Nothing new: the same value again.
        assert_eq!(b.read(), 2);
        b.write(3);
        assert_eq!(b.read(), 3);
    }

    /// The reader's slot is never the writer's: whatever the writer does between two reads,
    /// the slots stay a permutation and the value the reader holds is not overwritten.
    #[test]
    fn writer_and_reader_never_share_a_slot() {
        let b = TripleBuffer::new(0u64);
        for k in 1..1000u64 {
            for j in 0..(k % 5) {
                b.write(k * 10 + j);
                let (m, bk, fr) = (
                    b.middle.load(Ordering::Relaxed) & INDEX,
                    b.back.load(Ordering::Relaxed),
                    b.front.load(Ordering::Relaxed),
                );
                let mut ix = [m, bk, fr];
                ix.sort_unstable();
                assert_eq!(ix, [0, 1, 2], "after write {k}/{j}");
                // The reader's slot still holds what it last read.
            }
            let v = b.read();
            if k % 5 != 0 {
                assert_eq!(v, k * 10 + k % 5 - 1);
            }
        }
    }
}
