//! Value shapes the TOML deserialiser does not check by itself.

use serde::{Deserialize, Deserializer, de::Error};

/// An array of exactly `N` numbers: `toml` reads `[1.0, 1.2, 1.5]` into `[f64; 2]` by
/// dropping the last element; this reads it as a list and refuses any other length.
pub fn exact<'de, D: Deserializer<'de>, const N: usize>(d: D) -> Result<[f64; N], D::Error> {
    let v = Vec::<f64>::deserialize(d)?;
    let n = v.len();
    v.try_into().map_err(|_| D::Error::invalid_length(n, &format!("exactly {N} numbers").as_str()))
}

/// [`exact`] for optional keys.
pub fn exact_opt<'de, D: Deserializer<'de>, const N: usize>(d: D) -> Result<Option<[f64; N]>, D::Error> {
    exact::<D, N>(d).map(Some)
}

/// A closed interval `[lo, hi]` written as a two-element array.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Interval {
    /// Lower end.
    pub lo: f64,
    /// Upper end.
    pub hi: f64,
}

impl Interval {
    /// Both ends finite and `lo ≤ hi`.
    pub fn is_ordered(&self) -> bool {
        self.lo.is_finite() && self.hi.is_finite() && self.lo <= self.hi
    }

    /// `lo ≤ x ≤ hi`.
    pub fn contains(&self, x: f64) -> bool {
        self.lo <= x && x <= self.hi
    }

    /// The two ends.
    pub fn ends(&self) -> [f64; 2] {
        [self.lo, self.hi]
    }
}

impl<'de> Deserialize<'de> for Interval {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let [lo, hi] = exact::<D, 2>(d)?;
        Ok(Self { lo, hi })
    }
}
