//! splitmix64 (Steele, Lea, Flood, "Fast splittable pseudorandom number generators", OOPSLA
//! 2014): small, seeded and reproducible — the sensors' noise, the campaign's samples and the
//! motor population draw from it, so a seed names a run on any machine.

/// One splitmix64 output for the state `x` (a hash of `x`).
pub fn mix(mut x: u64) -> u64 {
    x = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    x ^ (x >> 31)
}

/// A splitmix64 stream.
#[derive(Clone, Copy, Debug)]
pub struct Rng(pub u64);

impl Rng {
    /// The next 64 bits.
    pub fn next_u64(&mut self) -> u64 {
        let out = mix(self.0);
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        out
    }
    /// Uniform in (0, 1].
    pub fn uniform(&mut self) -> f64 {
        ((self.next_u64() >> 11) as f64 + 1.0) / (1u64 << 53) as f64
    }
    /// Standard normal (Box–Muller).
    pub fn normal(&mut self) -> f64 {
        let (u1, u2) = (self.uniform(), self.uniform());
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
}

/// [`Rng::normal`]'s deviates, the same stream, made [`NORMALS_BATCH`] at a time: the
/// sensors draw three every PWM period and feed them straight to the drive, which, drawn one
/// by one, waited on each one's logarithm and cosine; in a batch the processor overlaps them.
#[derive(Clone, Debug)]
pub struct Normals {
    rng: Rng,
    batch: [f64; NORMALS_BATCH],
    /// The next deviate's index in `batch` (`NORMALS_BATCH`: none left).
    next: usize,
}

/// The deviates [`Normals`] makes at a time.
pub const NORMALS_BATCH: usize = 64;

impl Normals {
    /// The deviates of the stream `rng`.
    pub fn new(rng: Rng) -> Self {
        Self { rng, batch: [0.0; NORMALS_BATCH], next: NORMALS_BATCH }
    }

    /// The next standard normal deviate: `rng.normal()`'s next.
    pub fn normal(&mut self) -> f64 {
        if self.next >= NORMALS_BATCH {
            for z in &mut self.batch {
                *z = self.rng.normal();
            }
            self.next = 0;
        }
        let z = self.batch.get(self.next).copied().unwrap_or(0.0);
        self.next += 1;
        z
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The stream is splitmix64's: its reference outputs for seed 1234567 (the published
    /// test vector of the algorithm's C reference).
    #[test]
    fn the_stream_is_splitmix64() {
        let mut r = Rng(1234567);
        let got: Vec<u64> = (0..3).map(|_| r.next_u64()).collect();
        assert_eq!(got, [6457827717110365317, 3203168211198807973, 9817491932198370423]);
    }

    /// The batches are `Rng::normal`'s stream, bit for bit, across batch boundaries.
    #[test]
    fn the_batches_are_the_streams_deviates() {
        let mut rng = Rng(3);
        let one_by_one: Vec<u64> = (0..3 * NORMALS_BATCH + 1).map(|_| rng.normal().to_bits()).collect();
        let mut g = Normals::new(Rng(3));
        let batched: Vec<u64> = (0..one_by_one.len()).map(|_| g.normal().to_bits()).collect();
        assert_eq!(batched, one_by_one);
    }
}
