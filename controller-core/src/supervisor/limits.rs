//! The instant limits of every fast step (non-finite inputs, overcurrent, the current sum,
//! the bus) and the brake chopper's comparator.

/// `x`'s bits with the sign bit cleared (the bits of |x|).
#[inline]
pub(crate) fn abs_bits(x: f32) -> u32 {
    x.to_bits() & 0x7fff_ffff
}
