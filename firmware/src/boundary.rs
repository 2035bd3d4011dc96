//! The link task ↔ control interrupt boundary, lock-free: a triple buffer out of the
//! interrupt, a one-slot mailbox into it.
//!
//! **Out** ([`TripleBuffer`]): the interrupt (the only writer) publishes a copy of what the task needs — the last
//! output, the calibration's state, whether the bridge is on — after every step; the task
//! (the only reader) takes the newest without masking the interrupt. Three slots: the one
//! the writer fills, the one the reader holds, and the one in between; an atomic swap hands
//! a slot from one side to the other, so the two never touch the same slot and no read is
//! ever torn (unlike a sequence lock, there is no racing copy to retry).
//!
//! **In** ([`Mailbox`]): the task posts one request (a command); the interrupt serves it at
//! the end of a period and leaves the reply; the task takes it. Whose turn it is is one
//! atomic state, so the request and the reply are only ever touched by their owner.

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

/// [`Mailbox`] states: who owns the slots.
const EMPTY: u8 = 0;
const REQUEST: u8 = 1;
const REPLY: u8 = 2;

/// A one-slot request/reply mailbox between one task (posts, takes) and one interrupt
/// (serves).
pub struct Mailbox<Q: Copy, A: Copy> {
    state: AtomicU8,
    request: UnsafeCell<Option<Q>>,
    reply: UnsafeCell<Option<A>>,
}

// SAFETY: `state` says who owns the slots — the task in EMPTY (writes the request) and in
// REPLY (reads the reply), the interrupt in REQUEST (reads the request, writes the reply)
// — and changes hands only by Release stores seen with Acquire loads, so a slot is never
// accessed by both sides and each side sees the other's writes. `Q`, `A: Send`: they cross.
unsafe impl<Q: Copy + Send, A: Copy + Send> Sync for Mailbox<Q, A> {}

impl<Q: Copy, A: Copy> Mailbox<Q, A> {
    /// Empty.
    pub const fn new() -> Self {
        Self { state: AtomicU8::new(EMPTY), request: UnsafeCell::new(None), reply: UnsafeCell::new(None) }
    }

    /// The task: post `q`. False while a request or an untaken reply is in the box.
    pub fn post(&self, q: Q) -> bool {
        if self.state.load(Ordering::Acquire) != EMPTY {
            return false;
        }
        // SAFETY: EMPTY: the task owns the request slot.
        unsafe { *self.request.get() = Some(q) };
        self.state.store(REQUEST, Ordering::Release);
        true
    }

    /// The interrupt: answer a posted request with `f` (nothing to do otherwise: one
    /// atomic load).
    pub fn serve(&self, f: impl FnOnce(&Q) -> A) {
        if self.state.load(Ordering::Acquire) != REQUEST {
            return;
        }
        // SAFETY: REQUEST: the interrupt owns both slots.
        let a = unsafe { (*self.request.get()).as_ref().map(f) };
        // SAFETY: as above.
        unsafe { *self.reply.get() = a };
        self.state.store(REPLY, Ordering::Release);
    }

    /// The task: the reply, once served (the box is empty again after it).
    pub fn take(&self) -> Option<A> {
        if self.state.load(Ordering::Acquire) != REPLY {
            return None;
        }
        // SAFETY: REPLY: the task owns the reply slot.
        let a = unsafe { (*self.reply.get()).take() };
        self.state.store(EMPTY, Ordering::Release);
        a
    }
}

impl<Q: Copy, A: Copy> Default for Mailbox<Q, A> {
    fn default() -> Self {
        Self::new()
    }
}

impl<Q: Copy, A: Copy> core::fmt::Debug for Mailbox<Q, A> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Mailbox").field("state", &self.state.load(Ordering::Relaxed)).finish()
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

    /// Post → serve → take; a second post waits for the reply to be taken; serving with
    /// nothing posted does nothing.
    #[test]
    fn the_mailbox_answers_one_request_at_a_time() {
        let m: Mailbox<u32, u64> = Mailbox::new();
        let mut served = 0;
        m.serve(|_| {
            served += 1;
            0
        });
        assert_eq!((served, m.take()), (0, None));
        assert!(m.post(7));
        assert!(!m.post(8), "busy until served and taken");
        assert_eq!(m.take(), None, "not served yet");
        m.serve(|q| u64::from(*q) * 10);
        assert!(!m.post(9), "a reply waits");
        m.serve(|_| unreachable!("served once"));
        assert_eq!(m.take(), Some(70));
        assert_eq!(m.take(), None);
        assert!(m.post(9));
        m.serve(|q| u64::from(*q));
        assert_eq!(m.take(), Some(9));
    }
}
