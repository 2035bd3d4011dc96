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

/// Floats in a raw drive configuration.
pub const FLOATS: usize = 71;
/// Integers in a raw drive configuration.
pub const INTEGERS: usize = 17;

/// A drive configuration as numbers (see the module docs). Its `Debug` form is a Rust
/// expression: what the firmware's build script writes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RawDriveConfig {
    /// The f32 fields, in writing order.
    pub f: [f32; FLOATS],
    /// The integer fields (counts, bit patterns, variant tags), in writing order.
    pub u: [u32; INTEGERS],
}

/// Writes fields in order.
pub(crate) struct Writer {
    raw: RawDriveConfig,
    nf: usize,
    nu: usize,
    /// A field did not fit (a size constant is too small): caught by the tests.
    pub(crate) overflow: bool,
}

impl Writer {
    pub(crate) fn new() -> Self {
        Self { raw: RawDriveConfig { f: [0.0; FLOATS], u: [0; INTEGERS] }, nf: 0, nu: 0, overflow: false }
    }

    pub(crate) fn f(&mut self, x: f32) {
        match self.raw.f.get_mut(self.nf) {
            Some(slot) => *slot = x,
            None => self.overflow = true,
        }
        self.nf += 1;
    }

    pub(crate) fn u(&mut self, x: u32) {
        match self.raw.u.get_mut(self.nu) {
            Some(slot) => *slot = x,
            None => self.overflow = true,
        }
        self.nu += 1;
    }

    /// The numbers, and how many of each were written.
    pub(crate) fn finish(self) -> (RawDriveConfig, usize, usize) {
        (self.raw, self.nf, self.nu)
    }
}

/// Reads fields in the order they were written. Reading beyond the end gives zeros (and
/// sets `overrun`), never a panic.
pub(crate) struct Reader<'a> {
    raw: &'a RawDriveConfig,
    nf: usize,
    nu: usize,
    /// A read went beyond the end, or a float was not finite.
    pub(crate) bad: bool,
}

impl<'a> Reader<'a> {
    pub(crate) fn new(raw: &'a RawDriveConfig) -> Self {
        Self { raw, nf: 0, nu: 0, bad: false }
    }

    /// The next float; a non-finite one marks the configuration bad.
    pub(crate) fn f(&mut self) -> f32 {
        let x = self.raw.f.get(self.nf).copied();
        self.nf += 1;
        match x {
            Some(x) if x.is_finite() => x,
            _ => {
                self.bad = true;
                0.0
            }
        }
    }

    pub(crate) fn u(&mut self) -> u32 {
        let x = self.raw.u.get(self.nu).copied();
        self.nu += 1;
        x.unwrap_or_else(|| {
            self.bad = true;
            0
        })
    }
}
