//! Counter self-compensation (seed 004 §2.3.2, eq. 15–18) with the fractional remainder carried.
//!
//! The slave clock is a counter of crystal pulses, multiplied by a PLL (Npll) for finer
//! correction. Over one sync period the slave drifts Δ ns from the master (Δ > 0: slave fast,
//! REQ-CONV-007). The seed corrects N' = ⌊−Δ·Npll/T_slave⌋ fine counts per period (eq. 16–18
//! read as one floor at the fine resolution; the reading is argued at
//! `ecdc_spec::servo::seed_counter_compensation`). Flooring each period on its own drops up to
//! one fine count every period, always in the same direction: a rate bias of up to T_slave/Npll
//! per period that accumulates without bound in phase. Here the exact correction
//! x = −Δ·f_slave·Npll / 10^9 fine counts is computed in Q32 and quantised by [`Carry`], so the
//! long-run correction rate is exact and the phase error stays under one fine count
//! (REQ-SERVO-041).

use super::carry::{Carry, CARRY_X_MAX};
use super::gains::FRAC_BITS;

/// Largest |Δ| per period accepted, in ns (2^40 ns ≈ 18 min). Larger values are clamped.
pub const DELTA_MAX_NS: i64 = 1 << 40;

/// Largest fine-count rate f_slave·Npll, in Hz (2^34 ≈ 17 GHz).
pub const COUNT_HZ_MAX: u64 = 1 << 34;

/// Why a compensator configuration was refused.
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::counter::{CounterCompensator, CounterError};
///
/// assert_eq!(CounterCompensator::new(0, 1), Err(CounterError::CountRate));
/// // 25 MHz × 1000 = 25 GHz is above the supported 2^34 Hz.
/// assert_eq!(
///     CounterCompensator::new(25_000_000, 1_000),
///     Err(CounterError::CountRate)
/// );
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum CounterError {
    /// f_slave·Npll must be in [1, COUNT_HZ_MAX].
    CountRate,
}

/// Per-period counter compensation with carried remainder.
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::counter::CounterCompensator;
///
/// // 25 MHz crystal, no PLL: one count is 40 ns. The slave gains 100 ns per period, i.e. 2.5
/// // counts to drop; the carried half count makes the periods alternate −3, −2.
/// let mut comp = CounterCompensator::new(25_000_000, 1)?;
/// assert_eq!([comp.per_period(100), comp.per_period(100)], [-3, -2]);
/// # Ok::<(), ecdc_core::servo::counter::CounterError>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct CounterCompensator {
    count_hz: u64,
    carry: Carry,
}

impl CounterCompensator {
    /// A compensator for a crystal of `crystal_hz` multiplied by `npll` (eq. 18's Npll).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::counter::CounterCompensator;
    ///
    /// let comp = CounterCompensator::new(25_000_000, 4)?; // 100 MHz fine counts
    /// assert_eq!(comp.remainder(), 0);
    /// # Ok::<(), ecdc_core::servo::counter::CounterError>(())
    /// ```
    pub fn new(crystal_hz: u64, npll: u32) -> Result<Self, CounterError> {
        let count_hz = crystal_hz
            .checked_mul(u64::from(npll))
            .filter(|&c| (1..=COUNT_HZ_MAX).contains(&c))
            .ok_or(CounterError::CountRate)?;
        Ok(CounterCompensator {
            count_hz,
            carry: Carry::new(),
        })
    }

    /// Exact correction −Δ·count_hz/10^9 in Q32 fine counts (rounded toward −∞), clamped to
    /// the carry input range. |Δ|·count_hz·2^32 ≤ 2^40·2^34·2^32 = 2^106 fits in i128.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::counter::CounterCompensator;
    /// use ecdc_core::servo::gains::ONE;
    ///
    /// let comp = CounterCompensator::new(25_000_000, 1)?;
    /// assert_eq!(comp.exact_q32(100), -5 * ONE / 2); // −2.5 counts
    /// # Ok::<(), ecdc_core::servo::counter::CounterError>(())
    /// ```
    pub fn exact_q32(&self, delta_ns: i64) -> i64 {
        let d = i128::from(delta_ns.clamp(-DELTA_MAX_NS, DELTA_MAX_NS));
        let num = d
            .wrapping_neg()
            .wrapping_mul(i128::from(self.count_hz))
            .wrapping_shl(FRAC_BITS);
        let x = num.div_euclid(1_000_000_000);
        let lim = i128::from(CARRY_X_MAX);
        i64::try_from(x.clamp(lim.wrapping_neg(), lim)).unwrap_or(0)
    }

    /// REQ-SERVO-041: the fine counts N' to add to the slave counter this period (negative:
    /// drop counts) for a measured drift of `delta_ns` over the period.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::counter::CounterCompensator;
    ///
    /// let mut comp = CounterCompensator::new(25_000_000, 1)?;
    /// // Slave 40 ns slow per period: add one count.
    /// assert_eq!(comp.per_period(-40), 1);
    /// # Ok::<(), ecdc_core::servo::counter::CounterError>(())
    /// ```
    pub fn per_period(&mut self, delta_ns: i64) -> i64 {
        let x = self.exact_q32(delta_ns);
        self.carry.quantize(x)
    }

    /// As [`Self::per_period`] for a drift given in Q32 ns (a servo command), so the servo's
    /// fractional ns are not floored away before the conversion. |Δ| is clamped to 2^60.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::counter::CounterCompensator;
    /// use ecdc_core::servo::gains::ONE;
    ///
    /// let mut a = CounterCompensator::new(25_000_000, 1)?;
    /// let mut b = a;
    /// assert_eq!(a.per_period_q32(100 * ONE), b.per_period(100));
    /// # Ok::<(), ecdc_core::servo::counter::CounterError>(())
    /// ```
    pub fn per_period_q32(&mut self, delta_q32: i64) -> i64 {
        let d = i128::from(delta_q32.clamp(-(1 << 60), 1 << 60));
        // |Δ|·count_hz ≤ 2^60·2^34 = 2^94: fits in i128.
        let x = d
            .wrapping_neg()
            .wrapping_mul(i128::from(self.count_hz))
            .div_euclid(1_000_000_000);
        let lim = i128::from(CARRY_X_MAX);
        let x = i64::try_from(x.clamp(lim.wrapping_neg(), lim)).unwrap_or(0);
        self.carry.quantize(x)
    }

    /// The carried remainder, Q32 fine counts in [0, 2^32).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::counter::CounterCompensator;
    ///
    /// let mut comp = CounterCompensator::new(25_000_000, 1)?;
    /// comp.per_period(100); // −2.5 counts: −3 emitted, +0.5 carried
    /// assert_eq!(comp.remainder(), 1 << 31);
    /// # Ok::<(), ecdc_core::servo::counter::CounterError>(())
    /// ```
    pub const fn remainder(&self) -> u32 {
        self.carry.remainder()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_rate_where_a_per_period_floor_drifts() {
        // 25 MHz crystal, PLL ×4 = 100 MHz fine counts (10 ns). Slave 25 ns fast per period:
        // the exact correction is −2.5 fine counts per period. Flooring each period gives −3,
        // 5 ns too much every period; the carry alternates −2 and −3.
        let mut c = CounterCompensator::new(25_000_000, 4).unwrap();
        let mut sum = 0i64;
        for k in 1..=10_000i64 {
            sum += c.per_period(25);
            // Running phase error below one fine count at every period.
            assert!((2 * sum + 5 * k).abs() < 2, "k={k} sum={sum}");
        }
        assert_eq!(sum, -25_000);
        // A non-representable rate (−3.3 counts): the sum stays within one count of exact.
        let mut c = CounterCompensator::new(25_000_000, 4).unwrap();
        let sum: i64 = (0..10_000).map(|_| c.per_period(33)).sum();
        assert!((-33_001..=-33_000).contains(&sum), "{sum}");
        assert!(CounterCompensator::new(0, 4).is_err());
        assert!(CounterCompensator::new(u64::MAX, 2).is_err());
    }

    /// REQ-SERVO-041 on a Q32 drift: the same correction as `per_period` for whole ns, both
    /// signs, with the fraction carried and visible in `remainder`.
    // verifies: REQ-SERVO-041
    #[test]
    fn per_period_q32_matches_whole_ns_and_carries() {
        // 100 MHz fine counts: 25 ns fast is −2.5 counts per period.
        let mut c = CounterCompensator::new(25_000_000, 4).unwrap();
        assert_eq!(c.remainder(), 0);
        assert_eq!(c.per_period_q32(25 << 32), -3);
        assert_eq!(c.remainder(), 1 << 31);
        assert_eq!(c.per_period_q32(25 << 32), -2);
        assert_eq!(c.remainder(), 0);
        // Slave slow: +2.5 counts per period.
        assert_eq!(c.per_period_q32(-25 << 32), 2);
        assert_eq!(c.remainder(), 1 << 31);
        assert_eq!(c.per_period_q32(-25 << 32), 3);
        // Whole-ns input: identical to `per_period`, step by step, for both signs.
        let mut a = CounterCompensator::new(25_000_000, 4).unwrap();
        let mut b = a;
        for d in [33i64, -33, 7, -1_000_000, 12_345, 0, -7] {
            assert_eq!(a.per_period_q32(d << 32), b.per_period(d), "{d}");
            assert_eq!(a.remainder(), b.remainder(), "{d}");
        }
    }

    /// REQ-SERVO-041: a fraction of a ns per period is not floored away: 0.5 ns at 1 GHz fine
    /// counts is −0.5 count, i.e. −1 every second period.
    // verifies: REQ-SERVO-041
    #[test]
    fn per_period_q32_keeps_fractional_ns() {
        let mut c = CounterCompensator::new(1_000_000_000, 1).unwrap();
        let out: [i64; 4] = core::array::from_fn(|_| c.per_period_q32(1 << 31));
        assert_eq!(out, [-1, 0, -1, 0]);
        let mut c = CounterCompensator::new(1_000_000_000, 1).unwrap();
        let out: [i64; 4] = core::array::from_fn(|_| c.per_period_q32(-(1 << 31)));
        assert_eq!(out, [0, 1, 0, 1]);
    }

    /// |Δ| is clamped to 2^60 Q32 ns on both sides, and only outside that range.
    #[test]
    fn per_period_q32_clamps_symmetrically() {
        let fresh = || CounterCompensator::new(25_000_000, 4).unwrap();
        let lim: i64 = 1 << 60;
        // 2^60 Q32 ns at 100 MHz: −2^28/10 counts = −26 843 545.6 → floor −26 843 546.
        assert_eq!(fresh().per_period_q32(lim), -26_843_546);
        assert_eq!(fresh().per_period_q32(i64::MAX), -26_843_546);
        assert_eq!(fresh().per_period_q32(-lim), 26_843_545);
        assert_eq!(fresh().per_period_q32(i64::MIN), 26_843_545);
        // Just inside the limit the input is used as is.
        assert_eq!(fresh().per_period_q32(lim - (10 << 32)), -26_843_546 + 1);
    }
}
