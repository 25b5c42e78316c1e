//! The servo tests' pseudo-random source (xorshift64*): deterministic, seeded per test. Test
//! modules add the draws they need (ranges, distributions) in their own `impl Rng` blocks.

/// xorshift64* state; the seed must not be 0.
pub(crate) struct Rng(pub(crate) u64);

impl Rng {
    /// The next 64 pseudo-random bits.
    pub(crate) fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
}
