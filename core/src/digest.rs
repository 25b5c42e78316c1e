//! FNV-1a digests for golden-output tests: a test folds every output of a seeded run into one
//! 64-bit value and compares it with the committed one. That pins a behaviour without keeping a
//! second copy of the code; a change that alters any output fails the test, and if the change
//! is intended its commit says why and records the new digest (the assertion prints it).

/// FNV-1a over 64-bit words.
pub(crate) struct Digest(u64);

impl Digest {
    pub(crate) fn new() -> Self {
        Digest(0xcbf2_9ce4_8422_2325)
    }

    pub(crate) fn word(&mut self, w: u64) {
        for b in w.to_le_bytes() {
            self.0 ^= u64::from(b);
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01B3);
        }
    }

    pub(crate) fn int(&mut self, v: i64) {
        self.word(v as u64);
    }

    /// Asserts that the digest is the committed `expected` one; the message names what
    /// changed and prints the digest to record if the change is intended.
    pub(crate) fn assert_golden(&self, what: &str, expected: u64) {
        assert_eq!(self.0, expected, "{what} changed: digest {:#018x}", self.0);
    }
}
