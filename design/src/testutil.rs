//! Test helpers.

/// A seeded uniform generator on [0, 1) (64-bit LCG, top 53 bits): reproducible random
/// cases without a dependency.
pub fn uniform(mut seed: u64) -> impl FnMut() -> f64 {
    move || {
        seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64
    }
}
