//! The PI kernel: one update step with output clamp, integrator clamp and conditional
//! integration. This is the function the P5 proofs cover (REQ-SERVO-010..013).
//!
//! Units: the error θ is in ns (REQ-CONV-007: measured − target, positive = the controlled clock
//! is ahead). The command y and the integrator I are "ns of retard per nominal interval" in Q32
//! (ns · 2^32): positive y slows the controlled clock / delays the next wake-up by y ns.
//! Adapters convert y into a deadline correction ([`super::master`]) or ppb (`servo::ptp`,
//! feature `ptp`).
//!
//! Position form (REQ-SERVO-010):
//!   v = Kp·θ + I + Ki·θ,   y = clamp(v, ±y_max),
//!   I' = clamp(I + Ki·θ, ±I_max) if |v| ≤ y_max or Ki·θ pulls v back toward the range,
//!   I' = I otherwise (conditional integration: no windup while saturated).
//!
//! Overflow argument (every bound used, REQ-SERVO-013):
//! - θ is clamped to ±[`THETA_MAX`] = 2^28 ns before use;
//! - admissible gains have Kp + Ki < 2^34 (see [`super::gains`]), so |(Kp + Ki)·θ| < 2^62 and
//!   |Ki·θ| < 2^62;
//! - limits are validated to 0 < I_max ≤ y_max ≤ [`LIMIT_MAX_NS`]·2^32 = 2^60, and I is clamped
//!   to ±I_max on entry, so |v| < 2^62 + 2^60 < 2^63 and |I + Ki·θ| < 2^62 + 2^60 < 2^63.
//!
//! Hence plain i64 arithmetic never overflows; the code still uses `wrapping_*` so the lint
//! set stays quiet, and the proofs check that no wrap can happen.
//!
//! The whole step is [`pi_step_word`], written once against [`crate::num::Word`]: θ clamp
//! ([`clamp_theta`]), the two products ([`pi_products`]), then everything after them (entry
//! clamp of I, sum, output clamp, conditional integration: [`pi_update`]). `pi_step` runs it on
//! `u64` (two's complement bit patterns of the i64 values), and `ecdc-proofs` runs the very same
//! functions on z3 bit-vectors to prove the bounds above at 64 bits (P5, `smt::props`).

use super::gains::{PiGains, FRAC_BITS};
use crate::num::{clamp, wrapping_neg, Logic, Word};

/// log2 of [`THETA_MAX`].
pub const THETA_BITS: u32 = 28;

/// Largest |θ| the kernel uses, in ns (2^28 ns ≈ 268 ms). Larger errors are clamped: they
/// belong to the step path, and the master loop's folded error never exceeds P/2 for periods up
/// to 536 ms.
pub const THETA_MAX: i64 = 1 << THETA_BITS;

/// Largest admissible y_max / I_max in ns per interval (2^28 ns ≈ 268 ms per interval).
pub const LIMIT_MAX_NS: i64 = 1 << 28;

/// Edges of the admitted (y_max, I_max) limits in Q32 (feature `verification`): the least,
/// both at 2^60, an integrator limit far below the output limit, and a typical pair.
#[cfg(any(test, feature = "verification"))]
pub const EDGE_LIMITS: [(i64, i64); 4] = [
    (1, 1),
    (1 << 60, 1 << 60),
    (1 << 60, 1),
    (1000 * super::gains::ONE, 10 * super::gains::ONE),
];

/// Output and integrator clamps, in Q32 ns per interval.
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::gains::{PiGains, Pole, ONE};
/// use ecdc_core::servo::pi::{pi_step, PiLimits};
/// use ecdc_core::servo::ConfigError;
///
/// // At most 1 µs of correction per interval, integrator at most 500 ns.
/// let lim = PiLimits::from_ns(1_000, 500).map_err(ConfigError::Limits)?;
/// let g = PiGains::double_pole(Pole::from_q32(1 << 31)).map_err(ConfigError::Gains)?;
/// // A 2 µs error saturates the output at the limit.
/// let step = pi_step(g, lim, 0, 2_000);
/// assert_eq!((step.y, step.saturated), (1_000 * ONE, true));
/// # Ok::<(), ConfigError>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct PiLimits {
    y_max: i64,
    i_max: i64,
}

/// Why a limit pair was refused.
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::pi::{LimitError, PiLimits};
///
/// assert_eq!(PiLimits::from_ns(0, 0), Err(LimitError::OutputLimit));
/// // The integrator limit may not exceed the output limit.
/// assert_eq!(
///     PiLimits::from_ns(100, 200),
///     Err(LimitError::IntegratorLimit)
/// );
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum LimitError {
    /// y_max must be in (0, LIMIT_MAX_NS·2^32].
    OutputLimit,
    /// I_max must be in (0, y_max] (REQ-SERVO-011: then saturation ends at the first
    /// sample whose P term opposes it).
    IntegratorLimit,
}

impl PiLimits {
    /// REQ-SERVO-011: limits in Q32 ns per interval, 0 < I_max ≤ y_max ≤ 2^60.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::gains::ONE;
    /// use ecdc_core::servo::pi::PiLimits;
    ///
    /// // 2.5 ns per interval: not expressible in whole ns.
    /// let lim = PiLimits::from_q32(5 * ONE / 2, ONE)?;
    /// assert_eq!(lim.y_max(), 5 * ONE / 2);
    /// # Ok::<(), ecdc_core::servo::pi::LimitError>(())
    /// ```
    pub fn from_q32(y_max: i64, i_max: i64) -> Result<Self, LimitError> {
        if y_max <= 0 || y_max > LIMIT_MAX_NS << FRAC_BITS {
            return Err(LimitError::OutputLimit);
        }
        if i_max <= 0 || i_max > y_max {
            return Err(LimitError::IntegratorLimit);
        }
        Ok(PiLimits { y_max, i_max })
    }

    /// Limits in whole ns per interval.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::gains::ONE;
    /// use ecdc_core::servo::pi::PiLimits;
    ///
    /// // IgH's ±0.1 % of a 1 ms cycle.
    /// let lim = PiLimits::from_ns(1_000, 1_000)?;
    /// assert_eq!(lim, PiLimits::from_q32(1_000 * ONE, 1_000 * ONE)?);
    /// # Ok::<(), ecdc_core::servo::pi::LimitError>(())
    /// ```
    pub fn from_ns(y_max_ns: i64, i_max_ns: i64) -> Result<Self, LimitError> {
        if !(1..=LIMIT_MAX_NS).contains(&y_max_ns) {
            return Err(LimitError::OutputLimit);
        }
        if !(1..=y_max_ns).contains(&i_max_ns) {
            return Err(LimitError::IntegratorLimit);
        }
        // Both ≤ 2^28, so the shifts stay below 2^60.
        Self::from_q32(y_max_ns << FRAC_BITS, i_max_ns << FRAC_BITS)
    }

    /// y_max in Q32.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::gains::ONE;
    /// use ecdc_core::servo::pi::PiLimits;
    ///
    /// assert_eq!(PiLimits::from_ns(1_000, 500)?.y_max(), 1_000 * ONE);
    /// # Ok::<(), ecdc_core::servo::pi::LimitError>(())
    /// ```
    pub const fn y_max(self) -> i64 {
        self.y_max
    }

    /// I_max in Q32.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::gains::ONE;
    /// use ecdc_core::servo::pi::PiLimits;
    ///
    /// assert_eq!(PiLimits::from_ns(1_000, 500)?.i_max(), 500 * ONE);
    /// # Ok::<(), ecdc_core::servo::pi::LimitError>(())
    /// ```
    pub const fn i_max(self) -> i64 {
        self.i_max
    }
}

/// Result of one PI step.
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::gains::{PiGains, Pole, ONE};
/// use ecdc_core::servo::pi::{pi_step, PiLimits, PiStep};
/// use ecdc_core::servo::ConfigError;
///
/// // Kp = 0.75, Ki = 0.25: a 100 ns error commands 75 + 25 = 100 ns of retard.
/// let g = PiGains::double_pole(Pole::from_q32(1 << 31)).map_err(ConfigError::Gains)?;
/// let lim = PiLimits::from_ns(1_000, 500).map_err(ConfigError::Limits)?;
/// let step = pi_step(g, lim, 0, 100);
/// assert_eq!(
///     step,
///     PiStep {
///         y: 100 * ONE,
///         integrator: 25 * ONE,
///         saturated: false
///     }
/// );
/// # Ok::<(), ConfigError>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct PiStep {
    /// Command y in Q32 ns per interval; |y| ≤ y_max.
    pub y: i64,
    /// Next integrator I' in Q32; |I'| ≤ I_max.
    pub integrator: i64,
    /// The unclamped command v exceeded ±y_max.
    pub saturated: bool,
}

/// Clamp `x` to ±`limit` (limit ≥ 0).
#[inline]
fn clamp_mag(x: i64, limit: i64) -> i64 {
    x.clamp(limit.wrapping_neg(), limit)
}

/// The add/compare/clamp part of one PI step, as N-bit two's complement words (see
/// [`pi_update`]).
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::pi::pi_update;
///
/// // On plain u64 words: P term 75, I term 25, limits 1000 / 500.
/// let u = pi_update::<u64>(0, 75, 25, 1_000, 500);
/// assert_eq!((u.y, u.integrator, u.v, u.saturated), (100, 25, 100, false));
/// ```
pub struct PiUpdate<W: Word> {
    /// Command y = clamp(v, ±y_max).
    pub y: W,
    /// Next integrator I'.
    pub integrator: W,
    /// v ≠ y (the unclamped command exceeded ±y_max).
    pub saturated: W::Bool,
    /// The unclamped command v = Kp·θ + I + Ki·θ (I after its entry clamp), mod 2^N.
    pub v: W,
}

/// Signed clamp of `x` to [−limit, limit] on words (limit ≥ 0 as a signed value).
#[inline]
fn clamp_word<W: Word>(x: W, limit: W) -> W {
    W::from_signed(clamp::<W>(
        x.to_signed(),
        wrapping_neg(limit).to_signed(),
        limit.to_signed(),
    ))
}

/// REQ-SERVO-010..013: the PI update after its two products `p_term` = Kp·θ and `i_term` =
/// Ki·θ, for integrator `i` and limits `y_max`, `i_max` (all two's complement N-bit words):
/// I is clamped to ±I_max on entry, v = p_term + I + i_term, y = clamp(v, ±y_max), and
/// I' = clamp(I + i_term, ±I_max) if v was not clamped or i_term points back toward the range,
/// else I' = I. Branch-free (comparisons and [`Word::select`]), so the same code is proved
/// symbolically. All sums wrap modulo 2^N; the module doc's bounds (and the SMT proof) show
/// that they never wrap for admissible inputs.
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::pi::pi_update;
///
/// // Saturated and the I term pushes further out: the integrator is held (no windup).
/// let u = pi_update::<u64>(0, 1_500, 500, 1_000, 500);
/// assert_eq!((u.y, u.integrator, u.saturated), (1_000, 0, true));
/// // Saturated, but the I term pulls back towards the range: integrate.
/// let u = pi_update::<u64>(0, 1_500, (-100i64) as u64, 1_000, 500);
/// assert_eq!((u.y, u.integrator as i64), (1_000, -100));
/// ```
#[inline]
pub fn pi_update<W: Word>(i: W, p_term: W, i_term: W, y_max: W, i_max: W) -> PiUpdate<W> {
    let i = clamp_word(i, i_max);
    let v = p_term.wrapping_add(i).wrapping_add(i_term);
    let y = clamp_word(v, y_max);
    let saturated = v.eq(y).not();
    // Integrate when unsaturated, or when the increment points back toward the range.
    let zero = W::lit(0);
    let above = y_max.slt(v).and(i_term.slt(zero));
    let below = v.slt(wrapping_neg(y_max)).and(zero.slt(i_term));
    let integrator = W::select(
        saturated.not().or(above.or(below)),
        clamp_word(i.wrapping_add(i_term), i_max),
        i,
    );
    PiUpdate {
        y,
        integrator,
        saturated,
        v,
    }
}

/// REQ-SERVO-010..013: one PI update for error `theta` (ns) from integrator `i` (Q32).
///
/// Total for every input: `i` outside ±I_max is first clamped to it (a corrupted state cannot
/// leak into the output), `theta` is clamped to ±THETA_MAX.
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::gains::{PiGains, Pole, ONE};
/// use ecdc_core::servo::pi::{pi_step, PiLimits};
/// use ecdc_core::servo::ConfigError;
///
/// let g = PiGains::double_pole(Pole::from_q32(1 << 31)).map_err(ConfigError::Gains)?;
/// let lim = PiLimits::from_ns(1_000, 500).map_err(ConfigError::Limits)?;
/// // Two intervals with the error 100 ns each: the integrator grows by Ki · θ = 25 ns.
/// let s1 = pi_step(g, lim, 0, 100);
/// let s2 = pi_step(g, lim, s1.integrator, 100);
/// assert_eq!((s2.integrator, s2.y), (50 * ONE, 125 * ONE));
/// # Ok::<(), ConfigError>(())
/// ```
pub fn pi_step(g: PiGains, lim: PiLimits, i: i64, theta: i64) -> PiStep {
    let w = u64::from_signed;
    let r = pi_step_word::<u64>(
        w(g.kp()),
        w(g.ki()),
        w(i),
        w(theta),
        w(lim.y_max),
        w(lim.i_max),
    );
    PiStep {
        y: r.y.to_signed(),
        integrator: r.integrator.to_signed(),
        saturated: r.saturated,
    }
}

/// θ clamped to ±[`THETA_MAX`] on N-bit words (N ≥ 32), as two's complement.
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::pi::{clamp_theta, THETA_MAX};
///
/// assert_eq!(clamp_theta::<u64>(1 << 40), THETA_MAX as u64);
/// assert_eq!(clamp_theta::<u64>((-5i64) as u64) as i64, -5);
/// ```
#[inline]
pub fn clamp_theta<W: Word>(theta: W) -> W {
    clamp_word(theta, W::lit(1).shl(THETA_BITS))
}

/// The two products of one PI step, Kp·θ and Ki·θ, for θ already clamped by [`clamp_theta`].
/// They wrap modulo 2^N; at N = 64 with admissible gains (Kp < 2^33, Ki < 2^34, see
/// [`super::gains`]) and |θ| ≤ 2^28 they never do: |Kp·θ| ≤ 2^61 and |Ki·θ| ≤ 2^62 (module doc;
/// proved on z3 through this function, `smt::props::pi_products_exact` in `ecdc-proofs`).
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::gains::ONE;
/// use ecdc_core::servo::pi::pi_products;
///
/// let (kp, ki) = ((3 * ONE / 4) as u64, (ONE / 4) as u64);
/// let (p, i) = pi_products::<u64>(kp, ki, 100);
/// assert_eq!((p, i), (75 * ONE as u64, 25 * ONE as u64));
/// ```
#[inline]
pub fn pi_products<W: Word>(kp: W, ki: W, theta: W) -> (W, W) {
    (kp.wrapping_mul(theta), ki.wrapping_mul(theta))
}

/// One whole PI step on N-bit two's complement words: θ clamp, the two products, then
/// [`pi_update`]. [`pi_step`] runs it on `u64`; the SMT proofs run each of the three stages on
/// z3 words, so every line of the step is covered at 64 bits.
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::gains::{PiGains, Pole};
/// use ecdc_core::servo::pi::{pi_step, pi_step_word, PiLimits};
/// use ecdc_core::servo::ConfigError;
///
/// let g = PiGains::double_pole(Pole::from_q32(1 << 31)).map_err(ConfigError::Gains)?;
/// let lim = PiLimits::from_ns(1_000, 500).map_err(ConfigError::Limits)?;
/// let w = |x: i64| x as u64;
/// let u = pi_step_word::<u64>(
///     w(g.kp()),
///     w(g.ki()),
///     0,
///     w(-300),
///     w(lim.y_max()),
///     w(lim.i_max()),
/// );
/// assert_eq!(u.y as i64, pi_step(g, lim, 0, -300).y);
/// # Ok::<(), ConfigError>(())
/// ```
#[inline]
pub fn pi_step_word<W: Word>(kp: W, ki: W, i: W, theta: W, y_max: W, i_max: W) -> PiUpdate<W> {
    let (p_term, i_term) = pi_products(kp, ki, clamp_theta(theta));
    pi_update(i, p_term, i_term, y_max, i_max)
}

/// Hold: the command used when a sample is missing, blanked or rejected — the integrator alone
/// (the learned frequency), no P term, no integration (REQ-SERVO-071).
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::gains::ONE;
/// use ecdc_core::servo::pi::{hold, PiLimits};
///
/// let lim = PiLimits::from_ns(1_000, 500)?;
/// assert_eq!(hold(lim, 40 * ONE), 40 * ONE); // keep the learned rate
/// assert_eq!(hold(lim, 900 * ONE), 500 * ONE); // never beyond I_max
/// # Ok::<(), ecdc_core::servo::pi::LimitError>(())
/// ```
#[inline]
pub fn hold(lim: PiLimits, i: i64) -> i64 {
    clamp_mag(i, lim.i_max)
}

#[cfg(test)]
mod tests {
    use super::super::gains::{Pole, EDGE_GAINS, ONE};
    use super::*;

    #[test]
    fn linear_region_matches_formula() {
        // Fast gains (poles 1/2 and 1/3, Kp = 5/6, Ki = 1/3): a test choice with Kp, Ki < 1.
        let g = PiGains::from_poles(Pole::from_q32(1 << 31), Pole::from_q32(0x5555_5555)).unwrap();
        let lim = PiLimits::from_ns(1000, 500).unwrap();
        let s = pi_step(g, lim, 10 * ONE, 60);
        let v = g.kp() * 60 + 10 * ONE + g.ki() * 60;
        assert_eq!(s.y, v);
        assert_eq!(s.integrator, 10 * ONE + g.ki() * 60);
        assert!(!s.saturated);
    }

    #[test]
    fn saturates_and_does_not_wind_up() {
        let g = PiGains::double_pole(Pole::from_micro(500_000).unwrap()).unwrap();
        let lim = PiLimits::from_ns(100, 50).unwrap();
        let mut i = 0;
        for _ in 0..1000 {
            let s = pi_step(g, lim, i, 1_000_000);
            assert_eq!(s.y, 100 * ONE);
            assert!(s.saturated);
            i = s.integrator;
        }
        // The integrator never integrates while the output is pinned by a same-sign error.
        assert_eq!(i, 0);
        // An opposing error leaves saturation at once and integrates back.
        let s = pi_step(g, lim, 50 * ONE, -10);
        assert!(!s.saturated);
        assert!(s.integrator < 50 * ONE);
    }

    /// `pi_step` written as a plain-i64 body: the oracle that the Word-generic [`pi_step_word`]
    /// (θ clamp, products and [`pi_update`], which SMT runs on bit-vectors) gives the same
    /// result.
    fn pi_step_i64(g: PiGains, lim: PiLimits, i: i64, theta: i64) -> PiStep {
        let i = clamp_mag(i, lim.i_max);
        let th = clamp_mag(theta, THETA_MAX);
        let p_term = g.kp().wrapping_mul(th);
        let i_term = g.ki().wrapping_mul(th);
        let v = p_term.wrapping_add(i).wrapping_add(i_term);
        let y = clamp_mag(v, lim.y_max);
        let saturated = v != y;
        let pulls_back =
            (v > lim.y_max && i_term < 0) || (v < lim.y_max.wrapping_neg() && i_term > 0);
        let integrator = if !saturated || pulls_back {
            clamp_mag(i.wrapping_add(i_term), lim.i_max)
        } else {
            i
        };
        PiStep {
            y,
            integrator,
            saturated,
        }
    }

    #[test]
    fn word_kernel_equals_i64_body() {
        let mut n = 0u32;
        let mut seed = 0x9E37_79B9_7F4A_7C15u64;
        for (kp, ki) in EDGE_GAINS {
            let g = PiGains::from_q32(kp, ki).unwrap();
            for (y_max, i_max) in EDGE_LIMITS {
                let lim = PiLimits::from_q32(y_max, i_max).unwrap();
                let mut is = std::vec![0, 1, -1, i_max, -i_max, i_max + 1, -i_max - 1, y_max];
                is.extend([i64::MIN, i64::MAX, -y_max, i_max / 2, -(i_max / 3)]);
                let mut ths = std::vec![
                    0,
                    1,
                    -1,
                    THETA_MAX,
                    -THETA_MAX,
                    THETA_MAX + 1,
                    -THETA_MAX - 1
                ];
                ths.extend([i64::MIN, i64::MAX, 12_345, -98_765]);
                // Pseudo-random values (xorshift) on top of the boundaries.
                for _ in 0..40 {
                    seed ^= seed << 13;
                    seed ^= seed >> 7;
                    seed ^= seed << 17;
                    let r = i64::from_ne_bytes(seed.to_ne_bytes());
                    is.push(r % (2 * i_max));
                    ths.push(r >> (seed % 40));
                }
                for &i in &is {
                    for &th in &ths {
                        assert_eq!(
                            pi_step(g, lim, i, th),
                            pi_step_i64(g, lim, i, th),
                            "kp {kp} ki {ki} y_max {y_max} i_max {i_max} i {i} theta {th}"
                        );
                        n += 1;
                    }
                }
            }
        }
        assert_eq!(n, 5 * 4 * 53 * 51);
    }

    #[test]
    fn extreme_inputs_stay_bounded() {
        let g = PiGains::from_q32(2 * ONE - super::super::gains::MARGIN, 1).unwrap();
        let lim = PiLimits::from_ns(LIMIT_MAX_NS, LIMIT_MAX_NS).unwrap();
        for &th in &[i64::MIN, i64::MAX, 0, -1, 1] {
            for &i in &[i64::MIN, i64::MAX, 0] {
                let s = pi_step(g, lim, i, th);
                assert!(s.y.abs() <= lim.y_max());
                assert!(s.integrator.abs() <= lim.i_max());
            }
        }
        assert_eq!(PiLimits::from_ns(0, 0), Err(LimitError::OutputLimit));
        assert_eq!(PiLimits::from_ns(10, 11), Err(LimitError::IntegratorLimit));
    }
}

#[cfg(test)]
mod limit_tests {
    use super::*;

    /// REQ-SERVO-011: 0 < I_max ≤ y_max ≤ LIMIT_MAX_NS · 2^32, each bound on its own.
    #[test]
    fn q32_limits_refused_outside_their_ranges() {
        let top = LIMIT_MAX_NS << FRAC_BITS;
        assert!(PiLimits::from_q32(top, top).is_ok());
        assert!(PiLimits::from_q32(1, 1).is_ok());
        for y in [0, -1, i64::MIN, top + 1, i64::MAX] {
            assert_eq!(
                PiLimits::from_q32(y, 1),
                Err(LimitError::OutputLimit),
                "y_max {y}"
            );
        }
        for i in [0, -1, i64::MIN, 2 << 32, i64::MAX] {
            assert_eq!(
                PiLimits::from_q32(1 << 32, i),
                Err(LimitError::IntegratorLimit),
                "i_max {i}"
            );
        }
    }
}
