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
//! **In** ([`Mailbox`]): the task posts one request (a command); an interrupt serves it — the
//! control interrupt or the drive's slow context, whichever the command is for: each claims
//! it first, so one serves it — and leaves the reply; the task takes it. Whose turn it is is
//! one atomic state, so the request and the reply are only ever touched by their owner.
//!
//! **Between the control interrupt and a slower context** ([`Handoff`]): a value the fast
//! context hands over and the slow one hands back after working on it, each side touching
//! it only while it owns it — the drive's slow step in a context of its own (issue 54).

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
const CLAIMED: u8 = 3;

/// A one-slot request/reply mailbox between one task (posts, takes) and the interrupts that
/// serve it (any number, of any priorities on one core: the first to claim a request serves
/// it, the others find it claimed).
pub struct Mailbox<Q: Copy, A: Copy> {
    state: AtomicU8,
    request: UnsafeCell<MaybeUninit<Q>>,
    reply: UnsafeCell<MaybeUninit<A>>,
}

// SAFETY: `state` says who owns the slots — the task in EMPTY (writes the request) and in
// REPLY (reads the reply); in REQUEST the request is read-only (any server may read it);
// in CLAIMED the one server whose compare-exchange moved REQUEST to CLAIMED owns the reply
// slot (and reads the request) — and changes hands only by Release stores (or the
// compare-exchange's Acquire) seen with Acquire loads, so a slot is never written while
// another side reads or writes it, and each side sees the other's writes. `Q`, `A: Send`:
// they cross.
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

    /// A server: claim a posted request and answer it with `f`'s reply, or give it back,
    /// posted, for a later call or another server when `f` gives none (nothing to do
    /// without a request: one atomic load). A request another server holds is left alone.
    pub fn serve(&self, f: impl FnOnce(&Q) -> Option<A>) {
        if self.state.load(Ordering::Relaxed) != REQUEST
            || self.state.compare_exchange(REQUEST, CLAIMED, Ordering::Acquire, Ordering::Relaxed).is_err()
        {
            return;
        }
        // SAFETY: CLAIMED by this call: this server owns both slots (the task writes the
        // request only in EMPTY, the other servers touch nothing in CLAIMED), and `post`
        // wrote the request; it is only read here, in place — not copied first: a request
        // given back costs no copy.
        let q = unsafe { (*self.request.get()).assume_init_ref() };
        match f(q) {
            Some(a) => {
                // SAFETY: as above.
                unsafe { (*self.reply.get()).write(a) };
                self.state.store(REPLY, Ordering::Release);
            }
            None => self.state.store(REQUEST, Ordering::Release),
        }
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

/// [`Handoff`] states: which context owns the value, and whether it is lent out.
const FAST: u8 = 0;
const FAST_LENT: u8 = 1;
const SLOW: u8 = 2;
const SLOW_LENT: u8 = 3;

/// A value two contexts take turns on, on one core: the fast context (the control interrupt,
/// the higher priority) owns it until it hands it over ([`Handoff::hand_over`]); the slow
/// context (a lower-priority interrupt) then works on it once ([`Handoff::run`]) and hands it
/// back. Neither side waits: the fast context asks whether the value is back
/// ([`Handoff::with`] gives `None` while the slow context has it) — the drive's slow step,
/// latched at its tick and adopted a fixed number of periods later, is the use (issue 54's
/// two contexts).
pub struct Handoff<T> {
    state: AtomicU8,
    value: UnsafeCell<T>,
}

// SAFETY: `state` says who owns the value — the fast context in FAST (and FAST_LENT while
// its closure runs), the slow context in SLOW (SLOW_LENT) — and each side changes it only
// from a state it owns, handing over with a Release store the other side reads with
// Acquire: the value is never reached from both sides at once, and each sees the other's
// writes. A lent state refuses a second borrow from the same side (a closure that calls
// back in). On one core the fast context, the higher priority, never runs inside the slow
// one's load-then-store of SLOW's states, and the slow context never runs inside the fast
// one's. `T: Send`: the value crosses between the contexts.
unsafe impl<T: Send> Sync for Handoff<T> {}

impl<T> Handoff<T> {
    /// `value`, the fast context's.
    pub const fn new(value: T) -> Self {
        Self { state: AtomicU8::new(FAST), value: UnsafeCell::new(value) }
    }

    /// The fast context: `f` on the value, `None` while the slow context has it (or from a
    /// closure already holding it).
    pub fn with<R>(&self, f: impl FnOnce(&mut T) -> R) -> Option<R> {
        self.lend(FAST, FAST_LENT, f)
    }

    /// The fast context: hand the value to the slow context. False if the fast context does
    /// not own it (already handed over, not yet back) or is inside [`Handoff::with`].
    pub fn hand_over(&self) -> bool {
        if self.state.load(Ordering::Relaxed) != FAST {
            return false;
        }
        self.state.store(SLOW, Ordering::Release);
        true
    }

    /// The slow context: `f` on the value handed over, then the value back to the fast
    /// context; `None` when nothing was handed over.
    pub fn run<R>(&self, f: impl FnOnce(&mut T) -> R) -> Option<R> {
        self.lend(SLOW, SLOW_LENT, f)
    }

    /// `f` on the value if the calling side owns it (`owner`), marked `lent` meanwhile, then
    /// the value the fast context's: [`Handoff::with`] keeps it, [`Handoff::run`] gives it
    /// back (Release: the slow side's writes before the fast side's next Acquire).
    fn lend<R>(&self, owner: u8, lent: u8, f: impl FnOnce(&mut T) -> R) -> Option<R> {
        if self.state.load(Ordering::Acquire) != owner {
            return None;
        }
        self.state.store(lent, Ordering::Relaxed);
        // SAFETY: the state was `owner`, now `lent`: the calling side owns the value (the
        // fast context touches it only in FAST, the slow one only in SLOW) and this is its
        // only borrow (a nested call sees `lent`).
        let r = f(unsafe { &mut *self.value.get() });
        self.state.store(FAST, Ordering::Release);
        Some(r)
    }

    /// The value is the fast context's (handed back, or never handed over).
    pub fn is_back(&self) -> bool {
        self.state.load(Ordering::Acquire) == FAST
    }
}

impl<T> core::fmt::Debug for Handoff<T> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Handoff").field("state", &self.state.load(Ordering::Relaxed)).finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    extern crate std;

    /// The fast context owns the value until it hands it over; then only the slow context
    /// reaches it, once, and hands it back; a nested borrow is refused.
    #[test]
    fn a_handoff_lends_the_value_to_one_side_at_a_time() {
        let h = Handoff::new(0u32);
        assert_eq!(h.run(|v| *v += 1), None, "nothing handed over");
        assert_eq!(
            h.with(|v| {
                *v += 1;
                *v
            }),
            Some(1)
        );
        assert_eq!(h.with(|_| h.with(|_| ())), Some(None), "a nested borrow is refused");
        assert_eq!(h.with(|_| h.hand_over()), Some(false), "not handed over from inside a borrow");
        assert!(h.hand_over());
        assert!(!h.is_back());
        assert_eq!(h.with(|v| *v), None, "the slow context's");
        assert!(!h.hand_over(), "not twice");
        assert_eq!(
            h.run(|v| {
                *v *= 10;
                h.run(|_| ())
            }),
            Some(None),
            "a nested run is refused"
        );
        assert!(h.is_back());
        assert_eq!(h.run(|_| ()), None, "run once per hand-over");
        assert_eq!(h.with(|v| *v), Some(10));
    }

    /// Two threads standing for the two contexts (on the board one core: the test is the
    /// stronger), each touching the value only through its side: every hand-over is run once,
    /// and no side ever sees the other's borrow.
    #[test]
    fn a_handoff_between_two_threads_never_shares_the_value() {
        use std::sync::Arc;
        let h = Arc::new(Handoff::new((0u64, false)));
        let slow = {
            let h = Arc::clone(&h);
            std::thread::spawn(move || {
                let mut runs = 0;
                while runs < 10_000 {
                    if h.run(|(n, busy)| {
                        assert!(!*busy);
                        *busy = true;
                        *n += 1;
                        *busy = false;
                    })
                    .is_some()
                    {
                        runs += 1;
                    }
                }
            })
        };
        let mut handed = 0;
        while handed < 10_000 {
            if h.with(|(n, busy)| {
                assert!(!*busy);
                assert_eq!(*n, handed, "each hand-over run once before it is back");
            })
            .is_some()
                && h.hand_over()
            {
                handed += 1;
            }
        }
        slow.join().unwrap();
        assert_eq!(h.with(|(n, _)| *n), Some(10_000));
    }

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

    /// Two servers (the slow context, preempted by the control interrupt): a request claimed
    /// by one is left alone by the other, whether the first answers it or gives it back;
    /// once given back, the other may serve it.
    #[test]
    fn a_claimed_request_is_served_by_its_claimer_alone() {
        let m: Mailbox<u32, u64> = Mailbox::new();
        assert!(m.post(3));
        m.serve(|q| {
            m.serve(|_| unreachable!("claimed by the preempted server"));
            Some(u64::from(*q))
        });
        assert_eq!(m.take(), Some(3));
        assert!(m.post(4));
        m.serve(|_| {
            m.serve(|_| unreachable!("claimed by the preempted server"));
            None
        });
        assert_eq!(m.take(), None, "given back, posted");
        m.serve(|q| Some(u64::from(*q) + 1));
        assert_eq!(m.take(), Some(5));
    }
}
