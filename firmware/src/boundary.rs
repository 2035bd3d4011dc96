//! The link task ↔ control interrupt boundary, lock-free: a triple buffer out of the
//! interrupt, a one-slot mailbox into it.
//!
//! **Out** ([`TripleBuffer`]): the interrupt (the only writer) publishes a copy of what the
//! task needs — the last output, the calibration's state, whether the bridge is on — after
//! a step when the task has asked for one (`crate::interrupt::Shared`); the task
//! (the only reader) takes the newest without masking the interrupt. Three slots: the one
//! the writer fills, the one the reader holds, and the one in between; an atomic swap hands
//! a slot from one side to the other, so the two never touch the same slot and no read is
//! ever torn (unlike a sequence lock, there is no racing copy to retry).
//!
//! **In** ([`Mailbox`]): the task posts one request (a command); the interrupt serves it at
//! the end of a period and leaves the reply; the task takes it. Whose turn it is is one
//! atomic state, so the request and the reply are only ever touched by their owner.

use core::cell::UnsafeCell;
use core::mem::MaybeUninit;
use core::sync::atomic::{AtomicBool, AtomicU8, Ordering};

/// The middle slot's index in the low bits, and this bit when it holds a value the reader
/// has not taken yet.
const FRESH: u8 = 0b100;
const INDEX: u8 = 0b011;
/// The indices are stored XOR these, so that the all-zero state — the one a zero-initialised
/// static starts in (`.bss`: no flash for an initial image) — is back 0, middle 1, front 2.
const MIDDLE_XOR: u8 = 1;
const FRONT_XOR: u8 = 2;

/// One slot of a [`TripleBuffer`].
type Slot<T> = UnsafeCell<MaybeUninit<T>>;

/// A single-writer, single-reader triple buffer of `T`. Zero-initialised: nothing is
/// published until the first [`TripleBuffer::write`].
pub struct TripleBuffer<T: Copy> {
    slots: (Slot<T>, Slot<T>, Slot<T>),
    /// The middle slot (index ^ MIDDLE_XOR | FRESH).
    middle: AtomicU8,
    /// The writer's slot (touched by the writer only).
    back: AtomicU8,
    /// The reader's slot ^ FRONT_XOR (touched by the reader only).
    front: AtomicU8,
    /// The reader's slot holds a value (touched by the reader only).
    taken: AtomicBool,
}

// SAFETY: the slots are shared between one writer and one reader that never access the
// same slot at once: each side only touches the slot whose index it owns (`back`,
// `front`), and ownership moves between them only through the atomic swap of `middle`
// (AcqRel: the writes to a slot happen-before the reader's reads of it). A slot is read
// only after a write handed it over (`FRESH`, then `taken`). `T: Send` since values cross
// from the interrupt to the task.
unsafe impl<T: Copy + Send> Sync for TripleBuffer<T> {}

impl<T: Copy> TripleBuffer<T> {
    /// Nothing published.
    pub const fn new() -> Self {
        Self {
            slots: (
                UnsafeCell::new(MaybeUninit::uninit()),
                UnsafeCell::new(MaybeUninit::uninit()),
                UnsafeCell::new(MaybeUninit::uninit()),
            ),
            middle: AtomicU8::new(0),
            back: AtomicU8::new(0),
            front: AtomicU8::new(0),
            taken: AtomicBool::new(false),
        }
    }

    /// Slot `i` (0, 1, 2: the indices are a permutation of these by construction).
    fn slot(&self, i: u8) -> &Slot<T> {
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
        unsafe { (*self.slot(back).get()).write(value) };
        let old = self.middle.swap((back ^ MIDDLE_XOR) | FRESH, Ordering::AcqRel);
        self.back.store((old ^ MIDDLE_XOR) & INDEX, Ordering::Relaxed);
    }

    /// The newest value published (the reader: one context only, e.g. the link task); the
    /// last one taken again if nothing new came; `None` before the first write.
    pub fn read(&self) -> Option<T> {
        let mut front = (self.front.load(Ordering::Relaxed) ^ FRONT_XOR) & INDEX;
        if self.middle.load(Ordering::Relaxed) & FRESH != 0 {
            let old = self.middle.swap(front ^ MIDDLE_XOR, Ordering::AcqRel);
            front = (old ^ MIDDLE_XOR) & INDEX;
            self.front.store(front ^ FRONT_XOR, Ordering::Relaxed);
            self.taken.store(true, Ordering::Relaxed);
        }
        if !self.taken.load(Ordering::Relaxed) {
            return None;
        }
        // SAFETY: `front` is the reader's slot (the writer fills `back` only), written before
        // it was handed over (`taken`).
        Some(unsafe { (*self.slot(front).get()).assume_init_read() })
    }
}

impl<T: Copy> Default for TripleBuffer<T> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T: Copy> core::fmt::Debug for TripleBuffer<T> {
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
    request: UnsafeCell<MaybeUninit<Q>>,
    reply: UnsafeCell<MaybeUninit<A>>,
}

// SAFETY: `state` says who owns the slots — the task in EMPTY (writes the request) and in
// REPLY (reads the reply), the interrupt in REQUEST (reads the request, writes the reply)
// — and changes hands only by Release stores seen with Acquire loads, so a slot is never
// accessed by both sides and each side sees the other's writes. `Q`, `A: Send`: they cross.
unsafe impl<Q: Copy + Send, A: Copy + Send> Sync for Mailbox<Q, A> {}

impl<Q: Copy, A: Copy> Mailbox<Q, A> {
    /// Empty (zero-initialised: a static of it takes no flash).
    pub const fn new() -> Self {
        Self {
            state: AtomicU8::new(EMPTY),
            request: UnsafeCell::new(MaybeUninit::uninit()),
            reply: UnsafeCell::new(MaybeUninit::uninit()),
        }
    }

    /// The task: post `q`. False while a request or an untaken reply is in the box.
    pub fn post(&self, q: Q) -> bool {
        if self.state.load(Ordering::Acquire) != EMPTY {
            return false;
        }
        // SAFETY: EMPTY: the task owns the request slot.
        unsafe { (*self.request.get()).write(q) };
        self.state.store(REQUEST, Ordering::Release);
        true
    }

    /// The interrupt: answer a posted request with `f`'s reply, or leave it posted for a
    /// later call when `f` gives none (nothing to do without a request: one atomic load).
    pub fn serve(&self, f: impl FnOnce(&Q) -> Option<A>) {
        if self.state.load(Ordering::Acquire) != REQUEST {
            return;
        }
        // SAFETY: REQUEST: the interrupt owns both slots (the task writes the request only
        // in EMPTY), and `post` wrote the request; it is only read here, in place — not
        // copied first: a request left posted costs no copy.
        let q = unsafe { (*self.request.get()).assume_init_ref() };
        let Some(a) = f(q) else { return };
        // SAFETY: as above.
        unsafe { (*self.reply.get()).write(a) };
        self.state.store(REPLY, Ordering::Release);
    }

    /// The task: the reply, once served (the box is empty again after it).
    pub fn take(&self) -> Option<A> {
        if self.state.load(Ordering::Acquire) != REPLY {
            return None;
        }
        // SAFETY: REPLY: the task owns the reply slot, and `serve` wrote it.
        let a = unsafe { (*self.reply.get()).assume_init_read() };
        self.state.store(EMPTY, Ordering::Release);
        Some(a)
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
        let b = TripleBuffer::<u32>::new();
        assert_eq!(b.read(), None, "nothing published yet");
        b.write(1);
        b.write(2);
        assert_eq!(b.read(), Some(2));
        // Nothing new: the same value again.
        assert_eq!(b.read(), Some(2));
        b.write(3);
        assert_eq!(b.read(), Some(3));
    }

    /// The reader's slot is never the writer's: whatever the writer does between two reads,
    /// the slots stay a permutation and the value the reader holds is not overwritten.
    #[test]
    fn writer_and_reader_never_share_a_slot() {
        let b = TripleBuffer::<u64>::new();
        for k in 1..1000u64 {
            for j in 0..(k % 5) {
                b.write(k * 10 + j);
                let (m, bk, fr) = (
                    (b.middle.load(Ordering::Relaxed) ^ MIDDLE_XOR) & INDEX,
                    b.back.load(Ordering::Relaxed),
                    b.front.load(Ordering::Relaxed) ^ FRONT_XOR,
                );
                let mut ix = [m, bk, fr];
                ix.sort_unstable();
                assert_eq!(ix, [0, 1, 2], "after write {k}/{j}");
                // The reader's slot still holds what it last read.
            }
            let v = b.read();
            if k % 5 != 0 {
                assert_eq!(v, Some(k * 10 + k % 5 - 1));
            }
        }
    }

    /// Post → serve → take; a second post waits for the reply to be taken; serving with
    /// nothing posted does nothing; a request the interrupt leaves stays posted.
    #[test]
    fn the_mailbox_answers_one_request_at_a_time() {
        let m: Mailbox<u32, u64> = Mailbox::new();
        let mut served = 0;
        m.serve(|_| {
            served += 1;
            Some(0)
        });
        assert_eq!((served, m.take()), (0, None));
        assert!(m.post(7));
        assert!(!m.post(8), "busy until served and taken");
        assert_eq!(m.take(), None, "not served yet");
        m.serve(|_| None);
        assert_eq!(m.take(), None, "left posted");
        assert!(!m.post(8), "still busy");
        m.serve(|q| Some(u64::from(*q) * 10));
        assert!(!m.post(9), "a reply waits");
        m.serve(|_| unreachable!("served once"));
        assert_eq!(m.take(), Some(70));
        assert_eq!(m.take(), None);
        assert!(m.post(9));
        m.serve(|q| Some(u64::from(*q)));
        assert_eq!(m.take(), Some(9));
    }
}
