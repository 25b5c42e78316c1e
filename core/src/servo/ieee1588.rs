//! IEEE 1588 measurement math (seed 004 §1, eq. 1–3 and §2.1, eq. 6).
//!
//! Timestamps are u64 ns on wrapping clocks (master domain for t1/t4, slave domain for t2/t3);
//! only differences are used, through the wrap-safe [`crate::num::wrapping_diff`], so they are
//! correct whenever the true differences are below 2^63 ns.
//!
//! Two-way exchange (IEEE 1588 delay request-response): t1 = Sync egress at the master (Tm1), t2 = its ingress at
//! the slave (Ts1), t3 = Delay_Req egress at the slave, t4 = its ingress at the master.
//! - mean path delay = ((t2 − t1) + (t4 − t3)) / 2 (eq. 2, symmetric path assumed);
//! - offset = t2 − t1 − delay (eq. 1), positive = slave ahead (REQ-CONV-007).

use crate::num::wrapping_diff;

/// Why a measurement was refused. A refused measurement is a lost sample for the servo
/// (holdover), never a wrong value.
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::ieee1588::{mean_path_delay, Exchange, PtpError};
///
/// // The Delay_Req "arrived" before it was sent: the timestamps cannot be right.
/// let e = Exchange {
///     t1: 1_000,
///     t2: 1_100,
///     t3: 2_000,
///     t4: 1_500,
/// };
/// assert_eq!(mean_path_delay(&e), Err(PtpError::NegativeDelay));
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PtpError {
    /// (t2 − t1) + (t4 − t3) < 0: timestamps inconsistent (a path cannot be negative).
    NegativeDelay,
    /// A sum left the i64 range: timestamps garbage or from different epochs.
    Overflow,
    /// An elapsed interval for the rate ratio was not positive.
    NonPositiveInterval,
    /// The rate ratio deviates from 1 by more than [`RATE_PPB_MAX`].
    RateOutOfRange,
}

/// One two-way timestamp exchange, ns.
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::ieee1588::{offset_and_delay, Exchange};
///
/// // Sync: sent at master 1 000, received at slave 1 600; Delay_Req: sent at slave 2 000,
/// // received at master 2 400. Path 500 ns each way, slave 100 ns ahead.
/// let e = Exchange {
///     t1: 1_000,
///     t2: 1_600,
///     t3: 2_000,
///     t4: 2_400,
/// };
/// assert_eq!(offset_and_delay(&e)?, (100, 500));
/// # Ok::<(), ecdc_core::servo::ieee1588::PtpError>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Exchange {
    /// Sync egress at the master (Tm1).
    pub t1: u64,
    /// Sync ingress at the slave (Ts1).
    pub t2: u64,
    /// Delay_Req egress at the slave.
    pub t3: u64,
    /// Delay_Req ingress at the master.
    pub t4: u64,
}

/// REQ-SERVO-020: mean path delay ((t2 − t1) + (t4 − t3)) / 2, rounded toward −∞, ≥ 0.
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::ieee1588::{mean_path_delay, Exchange};
///
/// let e = Exchange { t1: 1_000, t2: 1_600, t3: 2_000, t4: 2_400 };
/// assert_eq!(mean_path_delay(&e)?, 500); // (600 + 400) / 2
/// # Ok::<(), ecdc_core::servo::ieee1588::PtpError>(())
/// ```
pub fn mean_path_delay(e: &Exchange) -> Result<i64, PtpError> {
    let ms = wrapping_diff::<u64>(e.t2, e.t1);
    let sm = wrapping_diff::<u64>(e.t4, e.t3);
    let sum = ms.checked_add(sm).ok_or(PtpError::Overflow)?;
    if sum < 0 {
        return Err(PtpError::NegativeDelay);
    }
    Ok(sum >> 1)
}

/// REQ-SERVO-021: offset from master Ts1 − Tm1 − Delay (eq. 1); positive = slave ahead.
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::ieee1588::offset_from_master;
///
/// // Received 600 ns after it was sent, 500 of which are the path: slave 100 ns ahead.
/// assert_eq!(offset_from_master(1_000, 1_600, 500)?, 100);
/// # Ok::<(), ecdc_core::servo::ieee1588::PtpError>(())
/// ```
pub fn offset_from_master(t1: u64, t2: u64, delay: i64) -> Result<i64, PtpError> {
    wrapping_diff::<u64>(t2, t1)
        .checked_sub(delay)
        .ok_or(PtpError::Overflow)
}

/// Offset and mean path delay of one exchange.
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::ieee1588::{offset_and_delay, Exchange};
///
/// // The slave is 300 ns behind: its stamps read 300 less than the master's would.
/// let e = Exchange {
///     t1: 1_000,
///     t2: 1_200,
///     t3: 2_000,
///     t4: 2_800,
/// };
/// assert_eq!(offset_and_delay(&e)?, (-300, 500));
/// # Ok::<(), ecdc_core::servo::ieee1588::PtpError>(())
/// ```
pub fn offset_and_delay(e: &Exchange) -> Result<(i64, i64), PtpError> {
    let d = mean_path_delay(e)?;
    Ok((offset_from_master(e.t1, e.t2, d)?, d))
}

/// Largest accepted rate deviation, ppb (10 %: any real crystal is within ±1000 ppm).
pub const RATE_PPB_MAX: i64 = 100_000_000;

/// REQ-SERVO-022: crystal rate ratio over an interval (eq. 6), as the ppb correction r such
/// that slave_rate · (1 + r·10^-9) = master rate: r = (Δm − Δs)·10^9 / Δs, rounded to nearest.
/// Δm = master elapsed, Δs = slave elapsed (both > 0). Negative r: the slave is fast.
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::ieee1588::{rate_ratio_ppb, PtpError};
///
/// // Over one master second the slave counted 1 µs more: it runs 1 000 ppb fast.
/// assert_eq!(rate_ratio_ppb(0, 1_000_000_000, 0, 1_000_001_000)?, -1_000);
/// assert_eq!(
///     rate_ratio_ppb(5, 5, 0, 10),
///     Err(PtpError::NonPositiveInterval)
/// );
/// # Ok::<(), PtpError>(())
/// ```
pub fn rate_ratio_ppb(m0: u64, m_n: u64, s0: u64, s_n: u64) -> Result<i64, PtpError> {
    let dm = i128::from(wrapping_diff::<u64>(m_n, m0));
    let ds = i128::from(wrapping_diff::<u64>(s_n, s0));
    if dm <= 0 || ds <= 0 {
        return Err(PtpError::NonPositiveInterval);
    }
    // |dm − ds| < 2^64 and ×10^9 < 2^94: no overflow in i128. Round half away from zero.
    let num = dm.wrapping_sub(ds).wrapping_mul(1_000_000_000);
    let half = ds >> 1;
    let r = if num >= 0 {
        num.wrapping_add(half).checked_div(ds).unwrap_or(0)
    } else {
        num.wrapping_sub(half).checked_div(ds).unwrap_or(0)
    };
    let lim = i128::from(RATE_PPB_MAX);
    if r.abs() > lim {
        return Err(PtpError::RateOutOfRange);
    }
    i64::try_from(r).map_err(|_| PtpError::RateOutOfRange)
}

/// REQ-SERVO-023: compose two rate corrections (eq. 6's Rs = RsΔ · ratio):
/// (1 + a)(1 + b) − 1 = a + b + a·b/10^9 ppb, rounded toward zero, saturating.
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::ieee1588::compound_ppb;
///
/// // (1 + 10^-3)(1 + 10^-3) − 1 = 2.001 · 10^-3.
/// assert_eq!(compound_ppb(1_000_000, 1_000_000), 2_001_000);
/// assert_eq!(compound_ppb(500, -500), 0);
/// ```
pub fn compound_ppb(a: i64, b: i64) -> i64 {
    let (a, b) = (i128::from(a), i128::from(b));
    let c = a
        .saturating_add(b)
        .saturating_add(a.saturating_mul(b) / 1_000_000_000);
    i64::try_from(c.clamp(i128::from(i64::MIN), i128::from(i64::MAX))).unwrap_or(0)
}

/// Rate-ratio estimator over `n` sync periods (seed eq. 6: the numerator and denominator are
/// master and slave elapsed time over n adjustment periods). A timestamp error of e ns at
/// either end of the baseline moves the ratio by about e/(n·h₀), so longer baselines shrink it
/// as 1/n. The PTP servo runs it before its offset loop (`servo::ptp`, feature `ptp`;
/// REQ-SERVO-124).
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::ieee1588::RateEstimator;
///
/// // One (master, slave) pair per 1 ms period; the slave runs 100 ppm fast.
/// let mut est = RateEstimator::new(4);
/// let mut last = None;
/// for k in 0..5u64 {
///     last = est.push(k * 1_000_000, k * 1_000_100);
/// }
/// assert_eq!(last, Some(Ok(-99_990)));
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct RateEstimator {
    periods: u32,
    anchor: Option<(u64, u64)>,
    count: u32,
}

impl RateEstimator {
    /// Estimate over `periods` periods (0 is treated as 1).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::ieee1588::RateEstimator;
    ///
    /// assert_eq!(RateEstimator::new(0), RateEstimator::new(1));
    /// ```
    pub const fn new(periods: u32) -> Self {
        RateEstimator {
            periods: if periods == 0 { 1 } else { periods },
            anchor: None,
            count: 0,
        }
    }

    /// Feed one (master, slave) timestamp pair per period. Every `periods` pairs, returns the
    /// ratio over that baseline and re-anchors at the current pair.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::ieee1588::RateEstimator;
    ///
    /// let mut est = RateEstimator::new(2);
    /// assert_eq!(est.push(0, 0), None); // anchor
    /// assert_eq!(est.push(1_000_000, 1_000_000), None);
    /// assert_eq!(est.push(2_000_000, 1_999_998), Some(Ok(1_000))); // slave 1 000 ppb slow
    /// ```
    pub fn push(&mut self, master: u64, slave: u64) -> Option<Result<i64, PtpError>> {
        let Some((m0, s0)) = self.anchor else {
            self.anchor = Some((master, slave));
            self.count = 0;
            return None;
        };
        self.count = self.count.saturating_add(1);
        if self.count < self.periods {
            return None;
        }
        self.anchor = Some((master, slave));
        self.count = 0;
        Some(rate_ratio_ppb(m0, master, s0, slave))
    }

    /// Drop the anchor (after a step of either clock).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::ieee1588::RateEstimator;
    ///
    /// let mut est = RateEstimator::new(1);
    /// est.push(0, 0);
    /// est.reset(); // the slave clock was stepped: the old anchor is meaningless
    /// assert_eq!(est.push(5_000_000, 9_000_000), None); // a new anchor, no ratio
    /// ```
    pub fn reset(&mut self) {
        self.anchor = None;
        self.count = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A rate of exactly `RATE_PPB_MAX` is accepted, one ppb more is out of range.
    #[test]
    fn rate_limit_is_inclusive() {
        let ds = 1_000_000_000u64;
        let at = ds + RATE_PPB_MAX as u64;
        assert_eq!(rate_ratio_ppb(0, at, 0, ds), Ok(RATE_PPB_MAX));
        assert_eq!(
            rate_ratio_ppb(0, at + 1, 0, ds),
            Err(PtpError::RateOutOfRange)
        );
    }

    /// `reset` drops the anchor: the next pair starts a new interval and gives no ratio.
    #[test]
    fn rate_estimator_reset_drops_the_anchor() {
        let mut est = RateEstimator::new(1);
        assert_eq!(est.push(0, 0), None);
        est.reset();
        assert_eq!(est.push(5_000_000, 9_000_000), None);
        assert!(est.push(10_000_000, 14_000_000).is_some());
    }

    /// A zero path delay (both legs 0 ns, e.g. timestamps taken at one point) is a delay, not
    /// a negative one; one nanosecond below is refused.
    #[test]
    fn zero_delay_is_valid() {
        let legs = |t4| Exchange {
            t1: 5,
            t2: 5,
            t3: 9,
            t4,
        };
        assert_eq!(mean_path_delay(&legs(9)), Ok(0));
        assert_eq!(mean_path_delay(&legs(8)), Err(PtpError::NegativeDelay));
    }

    #[test]
    fn offset_delay_textbook() {
        // Slave 500 ns ahead, 1000 ns one-way delay.
        let e = Exchange {
            t1: 10_000,
            t2: 11_500,
            t3: 20_000,
            t4: 20_500,
        };
        assert_eq!(offset_and_delay(&e), Ok((500, 1000)));
        // Across the u64 wrap.
        let b = u64::MAX - 200;
        let e = Exchange {
            t1: b,
            t2: b.wrapping_add(1500),
            t3: b.wrapping_add(5000),
            t4: b.wrapping_add(5500),
        };
        assert_eq!(offset_and_delay(&e), Ok((500, 1000)));
        let bad = Exchange {
            t1: 1000,
            t2: 0,
            t3: 1000,
            t4: 0,
        };
        assert_eq!(mean_path_delay(&bad), Err(PtpError::NegativeDelay));
    }

    // verifies: REQ-SERVO-023
    #[test]
    fn rate_ratio_eq6() {
        // Slave runs 100 ppm fast: over 1 s of master time it counts 1.0001 s.
        assert_eq!(
            rate_ratio_ppb(0, 1_000_000_000, 0, 1_000_100_000),
            Ok(-99_990)
        );
        assert_eq!(
            rate_ratio_ppb(5, 5, 0, 1),
            Err(PtpError::NonPositiveInterval)
        );
        assert_eq!(rate_ratio_ppb(0, 2, 0, 1), Err(PtpError::RateOutOfRange));
        assert_eq!(compound_ppb(1_000_000, -1_000_000), -1000);
        assert_eq!(compound_ppb(1000, -1000), 0); // −0.001 ppb rounds toward zero
        let mut est = RateEstimator::new(4);
        let mut out = None;
        for k in 0..=4u64 {
            out = est.push(k * 1_000_000, k * 1_000_050);
        }
        assert_eq!(out, Some(Ok(-49_998)));
    }
}
