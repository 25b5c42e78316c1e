//! Error-feedback quantiser: turns a Q32 command into whole units while carrying the fractional
//! remainder, so the long-run sum of the integers equals the sum of the commands to within one
//! unit (REQ-SERVO-040).
//!
//! q_k = ⌊x_k + r_k⌋, r_{k+1} = x_k + r_k − q_k ∈ [0, 1). Summing gives
//! Σq = Σx + r_0 − r_n, so |Σq − Σx| < 1 for every input sequence: flooring each period on its
//! own (seed 004 eq. 18) instead biases the rate by up to 1 LSB per period, always the same way.

use super::gains::FRAC_BITS;

/// Largest |x| accepted, in Q32 (2^62, i.e. 2^30 whole units per step). Larger inputs are
/// clamped; with |x| ≤ 2^62 and r < 2^32 the sum x + r never overflows an i64.
pub const CARRY_X_MAX: i64 = 1 << 62;

/// Fractional remainder in [0, 1), Q32. The type itself is the invariant: a `u32` cannot hold
/// anything outside [0, 2^32).
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::carry::Carry;
/// use ecdc_core::servo::gains::ONE;
///
/// // A command of 0.5 per period becomes 0, 1, 0, 1: the sum stays exact.
/// let mut c = Carry::new();
/// let out = [ONE / 2; 4].map(|x| c.quantize(x));
/// assert_eq!(out, [0, 1, 0, 1]);
/// ```
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Carry {
    r: u32,
}

impl Carry {
    /// A quantiser with zero remainder.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::carry::Carry;
    ///
    /// assert_eq!(Carry::new().remainder(), 0);
    /// ```
    pub const fn new() -> Self {
        Carry { r: 0 }
    }

    /// The remainder r in Q32, in [0, 2^32).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::carry::Carry;
    /// use ecdc_core::servo::gains::ONE;
    ///
    /// let mut c = Carry::new();
    /// assert_eq!(c.quantize(ONE + ONE / 4), 1);
    /// assert_eq!(c.remainder(), 1 << 30); // 0.25 carried
    /// ```
    pub const fn remainder(self) -> u32 {
        self.r
    }

    /// REQ-SERVO-040: emit ⌊x + r⌋ for a Q32 value `x`, keep the fraction.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::carry::Carry;
    /// use ecdc_core::servo::gains::ONE;
    ///
    /// let mut c = Carry::new();
    /// // −0.25 floors to −1 and carries +0.75; the next −0.25 then yields 0.
    /// assert_eq!(c.quantize(-ONE / 4), -1);
    /// assert_eq!(c.quantize(-ONE / 4), 0);
    /// ```
    pub fn quantize(&mut self, x_q32: i64) -> i64 {
        let x = x_q32.clamp(CARRY_X_MAX.wrapping_neg(), CARRY_X_MAX);
        // |x| ≤ 2^62, r < 2^32: the sum fits in i64.
        let s = x.wrapping_add(i64::from(self.r));
        // Arithmetic shift is floor division by 2^32 for negative values too.
        let q = s >> FRAC_BITS;
        // The low 32 bits are s − q·2^32 ∈ [0, 2^32).
        self.r = u32::try_from(s & 0xFFFF_FFFF).unwrap_or(0);
        q
    }

    /// Forget the remainder (after a step, so no stale fraction leaks into the new phase).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::carry::Carry;
    /// use ecdc_core::servo::gains::ONE;
    ///
    /// let mut c = Carry::new();
    /// c.quantize(ONE / 2);
    /// c.reset(); // after a clock step
    /// assert_eq!(c, Carry::new());
    /// ```
    pub fn reset(&mut self) {
        *self = Carry::new();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn long_run_sum_is_exact() {
        let mut c = Carry::new();
        // 0.3 units per step for 1000 steps: 300 units, never off by a whole unit on the way.
        let x = (3i64 << 32) / 10;
        let mut sum_q = 0i64;
        for k in 1..=1000i64 {
            sum_q += c.quantize(x);
            let exact = x * k;
            assert!((sum_q << 32) <= exact && exact - (sum_q << 32) < 1 << 32);
        }
        assert_eq!(sum_q, 299); // 1000·⌊0.3·2^32⌋/2^32 = 299.99…
        let mut c = Carry::new();
        assert_eq!(c.quantize(-1), -1);
        assert_eq!(c.remainder(), u32::MAX);
        assert_eq!(c.quantize(1), 1); // 2^-32 + (1 − 2^-32) carries into a whole unit
        assert_eq!(c.remainder(), 0);
        assert_eq!(c.quantize(i64::MIN), -(1 << 30));
        assert_eq!(c.quantize(i64::MAX), 1 << 30);
    }
}
