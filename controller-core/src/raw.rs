//! The discretised configuration as plain numbers, so that a host can build it and an image
//! embed it: the firmware's build script runs [`crate::drive::DriveConfig::new`] (f64 design
//! arithmetic, libm) on the host and writes [`crate::drive::DriveConfig::to_raw`]'s numbers
//! into the firmware, which only checks and copies them
//! ([`crate::drive::DriveConfig::from_raw`]): no f64 code, no libm on the target. IEEE 754
//! arithmetic is the same in software on the Cortex-M and in hardware on the host, so the
//! embedded configuration equals the one the target would have computed, bit for bit.
//!
//! Each configuration type writes its fields in a fixed order and reads them back in the
//! same order; the round trip is tested (`drive` tests, and the firmware's against its drive
//! file).

/// Writes fields in order into a configuration's numbers (the drive's raw form,
/// [`crate::drive::RawDriveConfig`], owns the arrays).
pub(crate) struct Writer<'a> {
    f: &'a mut [f32],
    u: &'a mut [u32],
    nf: usize,
    nu: usize,
    /// A field did not fit (the arrays are too small): caught by the tests.
    pub(crate) overflow: bool,
}

impl<'a> Writer<'a> {
    pub(crate) fn new(f: &'a mut [f32], u: &'a mut [u32]) -> Self {
        Self { f, u, nf: 0, nu: 0, overflow: false }
    }

    pub(crate) fn f(&mut self, x: f32) {
        match self.f.get_mut(self.nf) {
            Some(slot) => *slot = x,
            None => self.overflow = true,
        }
        self.nf += 1;
    }

    pub(crate) fn u(&mut self, x: u32) {
        match self.u.get_mut(self.nu) {
            Some(slot) => *slot = x,
            None => self.overflow = true,
        }
        self.nu += 1;
    }

    /// How many floats and integers were written.
    pub(crate) fn counts(&self) -> (usize, usize) {
        (self.nf, self.nu)
    }
}

/// Reads fields in the order they were written. Reading beyond the end gives zeros (and
/// sets `overrun`), never a panic.
pub(crate) struct Reader<'a> {
    f: &'a [f32],
    u: &'a [u32],
    nf: usize,
    nu: usize,
    /// A read went beyond the end, or an integer did not fit its field (a float's finiteness:
    /// [`Reader::ok`]).
    pub(crate) bad: bool,
}

impl<'a> Reader<'a> {
    pub(crate) fn new(f: &'a [f32], u: &'a [u32]) -> Self {
        Self { f, u, nf: 0, nu: 0, bad: false }
    }

    /// The next float (0 beyond the end: `bad`). Not checked here: [`Reader::ok`] checks
    /// every float read at once. Inlined (with every [`Field::get`]), a read is one load at a
    /// constant offset: out of line, with its finiteness check, the firmware's start-up
    /// read the configuration through ≈ 100 calls and kept each value on the stack.
    #[inline(always)]
    pub(crate) fn f(&mut self) -> f32 {
        let x = self.f.get(self.nf).copied();
        self.nf += 1;
        x.unwrap_or_else(|| {
            self.bad = true;
            0.0
        })
    }

    /// The next integer (0 beyond the end: `bad`), inlined as [`Reader::f`].
    #[inline(always)]
    pub(crate) fn u(&mut self) -> u32 {
        let x = self.u.get(self.nu).copied();
        self.nu += 1;
        x.unwrap_or_else(|| {
            self.bad = true;
            0
        })
    }

    /// Every read was in range, every integer fitted, and every float read is finite.
    pub(crate) fn ok(&self) -> bool {
        !self.bad && self.f.get(..self.nf).is_some_and(|f| f.iter().all(|x| x.is_finite()))
    }
}

/// A value of the raw configuration: its numbers, in order, on the floats' and the
/// integers' sequences (each has its own cursor). A struct declared with [`raw_struct!`]
/// is one: its fields in their order of declaration — the struct is the one source of its
/// place on the raw wire.
pub(crate) trait Field: Sized {
    /// The floats `put` writes (a count the compiler sums: the raw arrays' sizes are the
    /// configuration's, [`crate::drive::FLOATS`]).
    const NF: usize;
    /// The integers `put` writes ([`crate::drive::INTEGERS`]).
    const NU: usize;
    /// Write the value's numbers.
    fn put(&self, w: &mut Writer);
    /// Read them back; a number that does not fit sets [`Reader::bad`] (the value is then a
    /// placeholder: the caller refuses the configuration); a float is checked finite only at
    /// the end ([`Reader::ok`]). Every `get` is `#[inline(always)]`: a configuration is read
    /// once, at start-up, and inlined whole its reads are loads at constant offsets, stored
    /// where the value is built (out of line, each value was kept on the stack and copied).
    fn get(r: &mut Reader<'_>) -> Self;
}

impl Field for f32 {
    const NF: usize = 1;
    const NU: usize = 0;
    fn put(&self, w: &mut Writer) {
        w.f(*self);
    }
    #[inline(always)]
    fn get(r: &mut Reader<'_>) -> Self {
        r.f()
    }
}

impl Field for u32 {
    const NF: usize = 0;
    const NU: usize = 1;
    fn put(&self, w: &mut Writer) {
        w.u(*self);
    }
    #[inline(always)]
    fn get(r: &mut Reader<'_>) -> Self {
        r.u()
    }
}

/// 0 or 1; anything else marks the configuration bad.
impl Field for bool {
    const NF: usize = 0;
    const NU: usize = 1;
    fn put(&self, w: &mut Writer) {
        w.u(u32::from(*self));
    }
    #[inline(always)]
    fn get(r: &mut Reader<'_>) -> Self {
        match r.u() {
            0 => false,
            1 => true,
            _ => {
                r.bad = true;
                false
            }
        }
    }
}

impl Field for u16 {
    const NF: usize = 0;
    const NU: usize = 1;
    fn put(&self, w: &mut Writer) {
        w.u(u32::from(*self));
    }
    #[inline(always)]
    fn get(r: &mut Reader<'_>) -> Self {
        let x = r.u();
        u16::try_from(x).unwrap_or_else(|_| {
            r.bad = true;
            0
        })
    }
}

impl<T: Field, const N: usize> Field for [T; N] {
    const NF: usize = N * T::NF;
    const NU: usize = N * T::NU;
    fn put(&self, w: &mut Writer) {
        for x in self {
            x.put(w);
        }
    }
    #[inline(always)]
    fn get(r: &mut Reader<'_>) -> Self {
        core::array::from_fn(|_| T::get(r))
    }
}

/// Declares a struct whose fields are [`Field`]s and makes it one: `put` writes its fields
/// in their order of declaration, `get` reads them back in the same order. The struct
/// declaration is then the one source of its raw layout — a new field is its one line.
macro_rules! raw_struct {
    (
        $(#[$meta:meta])*
        $vis:vis struct $name:ident {
            $($(#[$fmeta:meta])* $fvis:vis $field:ident: $ty:ty,)*
        }
    ) => {
        $(#[$meta])*
        $vis struct $name {
            $($(#[$fmeta])* $fvis $field: $ty,)*
        }

        impl $crate::raw::Field for $name {
            const NF: usize = 0 $(+ <$ty as $crate::raw::Field>::NF)*;
            const NU: usize = 0 $(+ <$ty as $crate::raw::Field>::NU)*;
            fn put(&self, w: &mut $crate::raw::Writer) {
                $($crate::raw::Field::put(&self.$field, w);)*
            }
            #[inline(always)]
            fn get(r: &mut $crate::raw::Reader<'_>) -> Self {
                Self { $($field: $crate::raw::Field::get(r),)* }
            }
        }
    };
}
pub(crate) use raw_struct;
