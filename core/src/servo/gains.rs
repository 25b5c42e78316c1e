//! PI gains in Q32 fixed point, derived from closed-loop pole positions and refused outside the
//! stable region.
//!
//! Why poles: a raw (kp, ki) pair says nothing a user can check against the application, and a
//! pair that looks harmless can be unstable. A pole radius is one physically meaningful knob: the error decays as
//! p^k, so p = 0.99 at 1 kHz is a ~100 ms time constant. For the per-sample PI of
//! [`super::pi`] the closed-loop characteristic polynomial is z² + (Kp + Ki − 2)·z + (1 − Kp)
//! (\[DERIVED\] for the plant θₖ₊₁ = θₖ + δ − uₖ, REQ-SERVO-001); placing real poles p₁, p₂ gives Kp = 1 − p₁p₂ and
//! Ki = (1 − p₁)(1 − p₂) (REQ-SERVO-001).
//!
//! Q-format: a gain g is stored as the integer round(g · 2^32) in an `i64` ([`ONE`] = 1.0).
//! Admissible gains satisfy 0 < Kp < 2 and 0 < Ki, 2·Kp + Ki < 4, so Kp < 2^33, Ki < 2^34 and
//! Kp + Ki < 2^34: these are the bounds the overflow argument of [`super::pi`] uses.

/// Fractional bits of every gain, integrator and command value in the servo (Q32).
pub const FRAC_BITS: u32 = 32;

/// 1.0 in Q32.
pub const ONE: i64 = 1 << FRAC_BITS;

/// Stability margin (REQ-SERVO-002): Kp ∈ [M, 2 − M] and 2·Kp + Ki ≤ 4 − M, M = 2^-10. Keeps
/// both poles a visible distance inside the unit circle, which excludes linuxptp's marginal
/// corner Kp = 1, Ki = 2 (a pole at z = −1: z² + z + 0 = z(z + 1)).
pub const MARGIN: i64 = ONE >> 10;

/// The corners of the admitted (Kp, Ki) region in Q32: Kp at M and at 2 − M with the least
/// Ki, and the points on 2·Kp + Ki = 4 − M (feature `verification`): the gains every kernel
/// test and proof of the PI step runs with.
#[cfg(any(test, feature = "verification"))]
pub const EDGE_GAINS: [(i64, i64); 5] = [
    (MARGIN, 1),
    (ONE, ONE / 2),
    (2 * ONE - MARGIN, 1),
    (MARGIN, 4 * ONE - 3 * MARGIN),
    (ONE, 2 * ONE - MARGIN),
];

/// A closed-loop pole on the real axis in [0, 1), as a Q32 fraction (`u32`, so p < 1 holds by
/// construction). p = 0 is dead-beat; p → 1 is an ever slower, quieter loop.
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::gains::{PiGains, Pole, ONE};
///
/// // The error decays as 0.5^k: a dead-beat-ish, fast loop.
/// let p = Pole::from_micro(500_000)?;
/// assert_eq!(p.q32(), 1 << 31);
/// let g = PiGains::double_pole(p)?;
/// assert_eq!((g.kp(), g.ki()), (3 * ONE / 4, ONE / 4));
/// # Ok::<(), ecdc_core::servo::GainError>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Pole(u32);

impl Pole {
    /// The pole at `micro` / 1 000 000 (e.g. 990 000 = 0.99). Refuses ≥ 1.0: a pole on or
    /// outside the unit circle never converges.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::{GainError, Pole};
    ///
    /// // 0.99 at a 1 kHz cycle: a ~100 ms time constant.
    /// assert_eq!(Pole::from_micro(990_000)?.q32(), 4_252_017_623);
    /// assert_eq!(
    ///     Pole::from_micro(1_000_000),
    ///     Err(GainError::PoleOutsideUnitInterval)
    /// );
    /// # Ok::<(), GainError>(())
    /// ```
    pub fn from_micro(micro: u32) -> Result<Self, GainError> {
        if micro >= 1_000_000 {
            return Err(GainError::PoleOutsideUnitInterval);
        }
        // micro < 10^6 < 2^20, so micro · 2^32 < 2^52 and the quotient is < 2^32.
        let q = (u64::from(micro) << FRAC_BITS) / 1_000_000;
        u32::try_from(q)
            .map(Pole)
            .map_err(|_| GainError::PoleOutsideUnitInterval)
    }

    /// The pole with raw Q32 value `raw` (p = raw / 2^32).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::Pole;
    ///
    /// assert_eq!(Pole::from_q32(1 << 31), Pole::from_micro(500_000)?);
    /// # Ok::<(), ecdc_core::servo::GainError>(())
    /// ```
    pub const fn from_q32(raw: u32) -> Self {
        Pole(raw)
    }

    /// Raw Q32 value.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::Pole;
    ///
    /// assert_eq!(Pole::from_micro(250_000)?.q32(), 1 << 30);
    /// # Ok::<(), ecdc_core::servo::GainError>(())
    /// ```
    pub const fn q32(self) -> u32 {
        self.0
    }
}

/// Why a gain set was refused.
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::gains::{GainError, PiGains, ONE};
///
/// // Kp = 1, Ki = 2: linuxptp's corner with a pole at z = −1, refused.
/// assert_eq!(
///     PiGains::from_q32(ONE, 2 * ONE),
///     Err(GainError::JuryViolated)
/// );
/// assert_eq!(PiGains::from_q32(ONE, 0), Err(GainError::KiNotPositive));
/// assert_eq!(PiGains::from_q32(0, ONE), Err(GainError::KpOutOfRange));
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum GainError {
    /// A pole was given at or beyond 1.0.
    PoleOutsideUnitInterval,
    /// Kp outside [MARGIN, 2 − MARGIN]: a pole at or beyond ±1.
    KpOutOfRange,
    /// Ki ≤ 0: no integral action, or a pole at z = 1 (no convergence to a frequency error).
    KiNotPositive,
    /// 2·Kp + Ki > 4 − MARGIN: a pole at or beyond z = −1 (Nyquist-rate oscillation).
    JuryViolated,
}

/// Admissible per-sample PI gains (normalised: the P and I gains per sample, dimensionless).
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::gains::{PiGains, Pole, ONE};
///
/// // Critically damped, pole 0.9: Kp = 1 − 0.81 = 0.19, Ki = 0.1² = 0.01.
/// let g = PiGains::double_pole(Pole::from_micro(900_000)?)?;
/// assert_eq!((g.kp() * 100 + ONE / 2) / ONE, 19); // Kp ≈ 0.19 (Q32, rounded)
/// assert_eq!((g.ki() * 100 + ONE / 2) / ONE, 1); // Ki ≈ 0.01
/// # Ok::<(), ecdc_core::servo::GainError>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct PiGains {
    kp: i64,
    ki: i64,
}

impl PiGains {
    /// REQ-SERVO-001: Kp = 1 − p₁p₂, Ki = (1 − p₁)(1 − p₂), then the REQ-SERVO-002 check
    /// (which real poles in [0, 1) pass unless Ki rounds to zero, i.e. a pole within 2^-32 of
    /// 1, or both poles are so near 1 that Kp < MARGIN).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::gains::{PiGains, Pole, ONE};
    ///
    /// // Both poles at 0: dead-beat, Kp = Ki = 1.
    /// let g = PiGains::from_poles(Pole::from_q32(0), Pole::from_q32(0))?;
    /// assert_eq!((g.kp(), g.ki()), (ONE, ONE));
    /// // Poles 0.5 and 0: Kp = 1, Ki = 0.5.
    /// let g = PiGains::from_poles(Pole::from_q32(1 << 31), Pole::from_q32(0))?;
    /// assert_eq!((g.kp(), g.ki()), (ONE, ONE / 2));
    /// # Ok::<(), ecdc_core::servo::GainError>(())
    /// ```
    pub fn from_poles(p1: Pole, p2: Pole) -> Result<Self, GainError> {
        let (a, b) = (u128::from(p1.0), u128::from(p2.0));
        let one = 1u128 << FRAC_BITS;
        // All products < 2^64 and quotients ≤ 2^32; u128 cannot overflow here.
        let prod = a.wrapping_mul(b) >> FRAC_BITS;
        let kp = one.wrapping_sub(prod);
        let ki = one.wrapping_sub(a).wrapping_mul(one.wrapping_sub(b)) >> FRAC_BITS;
        let kp = i64::try_from(kp).map_err(|_| GainError::KpOutOfRange)?;
        let ki = i64::try_from(ki).map_err(|_| GainError::KiNotPositive)?;
        Self::from_q32(kp, ki)
    }

    /// Critically damped design: a double pole at `p` (Kp = 1 − p², Ki = (1 − p)²).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::gains::{PiGains, Pole};
    ///
    /// let p = Pole::from_micro(990_000)?;
    /// assert_eq!(PiGains::double_pole(p)?, PiGains::from_poles(p, p)?);
    /// # Ok::<(), ecdc_core::servo::GainError>(())
    /// ```
    pub fn double_pole(p: Pole) -> Result<Self, GainError> {
        Self::from_poles(p, p)
    }

    /// REQ-SERVO-002: raw Q32 gains, accepted only inside the Jury stability region with margin:
    /// MARGIN ≤ Kp ≤ 2 − MARGIN, Ki ≥ 1 LSB, 2·Kp + Ki ≤ 4 − MARGIN.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::gains::{PiGains, ONE};
    ///
    /// // Kp = 0.5, Ki = 0.125, given directly.
    /// let g = PiGains::from_q32(ONE / 2, ONE / 8)?;
    /// assert_eq!(g.kp(), ONE / 2);
    /// # Ok::<(), ecdc_core::servo::GainError>(())
    /// ```
    pub fn from_q32(kp: i64, ki: i64) -> Result<Self, GainError> {
        const KP_MAX: i64 = 2 * ONE - MARGIN;
        const SUM_MAX: i64 = 4 * ONE - MARGIN;
        if !(MARGIN..=KP_MAX).contains(&kp) {
            return Err(GainError::KpOutOfRange);
        }
        if ki <= 0 {
            return Err(GainError::KiNotPositive);
        }
        // Saturating: a ki near i64::MAX gives i64::MAX, above the bound like the true sum.
        let two_kp_ki = kp.saturating_mul(2).saturating_add(ki);
        if two_kp_ki > SUM_MAX {
            return Err(GainError::JuryViolated);
        }
        Ok(PiGains { kp, ki })
    }

    /// Kp in Q32; always in [MARGIN, 2 − MARGIN].
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::gains::{PiGains, ONE};
    ///
    /// assert_eq!(PiGains::from_q32(ONE / 2, ONE / 8)?.kp(), ONE / 2);
    /// # Ok::<(), ecdc_core::servo::GainError>(())
    /// ```
    pub const fn kp(self) -> i64 {
        self.kp
    }

    /// Ki in Q32; always in [1, 4 − MARGIN).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::gains::{PiGains, ONE};
    ///
    /// assert_eq!(PiGains::from_q32(ONE / 2, ONE / 8)?.ki(), ONE / 8);
    /// # Ok::<(), ecdc_core::servo::GainError>(())
    /// ```
    pub const fn ki(self) -> i64 {
        self.ki
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A pole's raw Q32 value is its fraction of one: 0.25 is 2^30.
    #[test]
    fn pole_q32_is_its_fraction() {
        assert_eq!(Pole::from_micro(250_000).unwrap().q32(), 1 << 30);
        assert_eq!(Pole::from_micro(500_000).unwrap().q32(), 1 << 31);
    }

    /// A huge Ki is refused as a Jury violation, the saturated sum included.
    #[test]
    fn huge_ki_violates_jury() {
        for ki in [4 * ONE, i64::MAX / 2, i64::MAX] {
            assert_eq!(
                PiGains::from_q32(ONE, ki),
                Err(GainError::JuryViolated),
                "{ki}"
            );
        }
    }

    fn f(q: i64) -> f64 {
        q as f64 / ONE as f64
    }

    #[test]
    fn poles_map_to_expected_gains() {
        // Poles 1/2 and 1/3: Kp = 1 − 1/6, Ki = (1/2)(2/3).
        let g = PiGains::from_poles(Pole::from_q32(1 << 31), Pole::from_q32(0x5555_5555)).unwrap();
        assert!((f(g.kp()) - 5.0 / 6.0).abs() < 1e-9);
        assert!((f(g.ki()) - 1.0 / 3.0).abs() < 1e-9);
        let p = Pole::from_micro(990_000).unwrap();
        let g = PiGains::double_pole(p).unwrap();
        assert!((f(g.kp()) - (1.0 - 0.99f64 * 0.99)).abs() < 1e-8);
        assert!((f(g.ki()) - 0.01f64 * 0.01).abs() < 1e-8);
        // Dead-beat: both poles at 0.
        let g = PiGains::double_pole(Pole::from_q32(0)).unwrap();
        assert_eq!((g.kp(), g.ki()), (ONE, ONE));
    }

    #[test]
    fn refuses_outside_stability_region() {
        assert_eq!(
            Pole::from_micro(1_000_000),
            Err(GainError::PoleOutsideUnitInterval)
        );
        // linuxptp's marginal corner Kp = 1, Ki = 2 (pole at −1).
        assert_eq!(
            PiGains::from_q32(ONE, 2 * ONE),
            Err(GainError::JuryViolated)
        );
        assert_eq!(PiGains::from_q32(0, ONE), Err(GainError::KpOutOfRange));
        assert_eq!(PiGains::from_q32(2 * ONE, 1), Err(GainError::KpOutOfRange));
        assert_eq!(PiGains::from_q32(ONE, 0), Err(GainError::KiNotPositive));
        assert_eq!(
            PiGains::from_q32(ONE, i64::MAX),
            Err(GainError::JuryViolated)
        );
        // Both poles within 2^-32 of 1: Kp rounds below the margin.
        assert!(PiGains::from_poles(Pole::from_q32(u32::MAX), Pole::from_q32(u32::MAX)).is_err());
        // linuxptp defaults at 1 s are inside.
        assert!(PiGains::from_q32(3_006_477_107, 1_288_490_189).is_ok());
    }
}
