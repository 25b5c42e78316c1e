//! The seed 004 two-pole offset filter (§2.2, eq. 7–9), in fixed point.
//!
//! The paper's equations survive only as the pole choice e^−aT = 1/2, e^−bT = 1/3 (the equation
//! images are missing from the seed text). The unity-DC-gain two-pole low-pass with those poles
//! is \[DERIVED\]:
//!   Y(k) = (5/6)·Y(k−1) − (1/6)·Y(k−2) + (1/3)·X(k)          (eq. 9 as reconstructed)
//! which factors into two first-order sections, each a convex combination:
//!   U(k) = (1/2)·U(k−1) + (1/2)·X(k),   Y(k) = (1/3)·Y(k−1) + (2/3)·U(k).
//! The cascade is what runs here, because convexity gives the bound by a one-step induction:
//! if |U|, |Y|, |X| ≤ M then |U'|, |Y'| ≤ M (REQ-SERVO-031). The impulse response is positive,
//! so the filter never overshoots a step. The spec model (`ecdc_spec::servo`) runs the direct
//! form in exact rationals; the model test bounds the difference.
//!
//! State is Q16 ns (fractional bits keep the floor bias below 2^-15 ns). Input is clamped to
//! ±[`FILTER_X_MAX`] = 2^45 ns; then |X·2^16| ≤ 2^61 and every sum stays below 3·2^61 < 2^63.

/// Fractional bits of the filter state.
pub const FILTER_FRAC: u32 = 16;

/// Largest |input| in ns (2^45 ns ≈ 9.8 h); larger offsets are clamped.
pub const FILTER_X_MAX: i64 = 1 << 45;

const M_Q16: i64 = FILTER_X_MAX << FILTER_FRAC;

/// Two-pole offset filter state (REQ-SERVO-030). Primes on the first sample so a large initial
/// offset does not ring through as a start-up transient from zero.
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::filter::OffsetFilter;
///
/// // The first sample primes the filter; a drop to 0 then comes through smoothly.
/// let mut f = OffsetFilter::new();
/// assert_eq!(f.update(100), 100);
/// assert_eq!(f.update(0), 67);
/// assert_eq!(f.update(0), 39);
/// ```
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct OffsetFilter {
    u: i64,
    y: i64,
    primed: bool,
}

impl OffsetFilter {
    /// An unprimed filter.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::filter::OffsetFilter;
    ///
    /// let f = OffsetFilter::new();
    /// assert_eq!((f.output(), f.state_q16()), (0, (0, 0)));
    /// ```
    pub const fn new() -> Self {
        OffsetFilter {
            u: 0,
            y: 0,
            primed: false,
        }
    }

    /// Raw state (U, Y) in Q16 ns, for proofs and diagnostics.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::filter::OffsetFilter;
    ///
    /// let mut f = OffsetFilter::new();
    /// f.update(100);
    /// assert_eq!(f.state_q16(), (100 << 16, 100 << 16));
    /// ```
    pub const fn state_q16(&self) -> (i64, i64) {
        (self.u, self.y)
    }

    /// Rebuild from raw Q16 state (clamped to the invariant range), for proofs.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::filter::OffsetFilter;
    ///
    /// let mut f = OffsetFilter::new();
    /// f.update(100);
    /// let (u, y) = f.state_q16();
    /// assert_eq!(OffsetFilter::from_state_q16(u, y), f);
    /// ```
    pub fn from_state_q16(u: i64, y: i64) -> Self {
        OffsetFilter {
            u: u.clamp(-M_Q16, M_Q16),
            y: y.clamp(-M_Q16, M_Q16),
            primed: true,
        }
    }

    /// REQ-SERVO-030: filter one offset sample (ns); returns YOffset(k), rounded to ns.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::filter::OffsetFilter;
    ///
    /// let mut f = OffsetFilter::new();
    /// f.update(0);
    /// // A step input never overshoots: the output climbs towards 90.
    /// let out = [90; 6].map(|x| f.update(x));
    /// assert!(out.windows(2).all(|w| w[0] <= w[1] && w[1] <= 90));
    /// ```
    pub fn update(&mut self, offset_ns: i64) -> i64 {
        let x = offset_ns.clamp(-FILTER_X_MAX, FILTER_X_MAX) << FILTER_FRAC;
        if !self.primed {
            self.u = x;
            self.y = x;
            self.primed = true;
        } else {
            // Convex combinations with floor rounding stay inside [−M, M] (module doc).
            self.u = self.u.wrapping_add(x) >> 1;
            let num = self.y.wrapping_add(self.u.wrapping_mul(2));
            self.y = num.div_euclid(3);
        }
        self.output()
    }

    /// Current output rounded to the nearest ns (ties toward +∞).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::filter::OffsetFilter;
    ///
    /// let mut f = OffsetFilter::new();
    /// f.update(-25);
    /// assert_eq!(f.output(), -25);
    /// ```
    pub fn output(&self) -> i64 {
        self.y.wrapping_add(1 << (FILTER_FRAC - 1)) >> FILTER_FRAC
    }

    /// Forget all history (after a clock step).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::filter::OffsetFilter;
    ///
    /// let mut f = OffsetFilter::new();
    /// f.update(1_000);
    /// f.reset(); // the clock was stepped: old offsets mean nothing now
    /// assert_eq!(f.update(-40), -40);
    /// ```
    pub fn reset(&mut self) {
        *self = Self::new();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `reset` forgets every sample: the next one passes through as into a new filter.
    #[test]
    fn reset_is_new() {
        let mut f = OffsetFilter::new();
        f.update(1_000);
        f.update(900);
        f.reset();
        assert_eq!(f, OffsetFilter::new());
        assert_eq!(f.update(-40), -40);
    }

    /// The raw state round-trips (a rebuilt filter continues exactly as the original), and a
    /// state outside the invariant range is clamped into it.
    #[test]
    fn state_round_trip_and_clamp() {
        let mut f = OffsetFilter::new();
        for x in [100, -40, 7_000] {
            f.update(x);
        }
        let (u, y) = f.state_q16();
        let mut g = OffsetFilter::from_state_q16(u, y);
        assert_eq!(g, f);
        assert_eq!(g.update(55), f.update(55));
        let h = OffsetFilter::from_state_q16(i64::MAX, i64::MIN);
        assert_eq!(h.state_q16(), (M_Q16, -M_Q16));
    }

    #[test]
    fn unity_dc_gain_and_no_overshoot() {
        let mut f = OffsetFilter::new();
        f.update(0);
        let mut last = 0;
        for _ in 0..60 {
            let y = f.update(1000);
            assert!(y >= last && y <= 1000);
            last = y;
        }
        assert_eq!(last, 1000);
        // Direct form check of the reconstructed eq. 9 on the first steps after a unit step.
        let mut f = OffsetFilter::new();
        f.update(0);
        assert_eq!(f.update(6000), 2000); // (1/3)·6000
        assert_eq!(f.update(6000), 3667); // (5/6)·2000 + 2000 = 3666.7
    }

    #[test]
    fn extremes_clamped() {
        let mut f = OffsetFilter::new();
        for &x in &[i64::MAX, i64::MIN, i64::MAX, 0, i64::MIN] {
            let y = f.update(x);
            assert!(y.abs() <= FILTER_X_MAX);
        }
    }
}
