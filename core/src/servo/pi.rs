//! The PI kernel: one update step with output clamp, integrator clamp and conditional
//! integration. This is the function the P5 proofs cover (REQ-SERVO-010..013).
//!
//! Units: the error θ is in ns (REQ-CONV-007: measured − target, positive = the controlled clock
//! is ahead). The command y and the integrator I are "ns of retard per nominal interval" in Q32
//! (ns · 2^32): positive y slows the controlled clock / delays the next wake-up by y ns.
//! Adapters convert y into a deadline correction ([`super::master`]) or ppb ([`super::ptp`]).
//!
//! Position form (servo.md §7 rule 5):
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

use super::gains::{PiGains, FRAC_BITS};

/// Largest |θ| the kernel uses, in ns (2^28 ns ≈ 268 ms). Larger errors are clamped: they
/// belong to the step path, and the master loop's folded error never exceeds P/2 for periods up
/// to 536 ms.
pub const THETA_MAX: i64 = 1 << 28;

/// Largest admissible y_max / I_max in ns per interval (2^28 ns ≈ 268 ms per interval).
pub const LIMIT_MAX_NS: i64 = 1 << 28;

/// Output and integrator clamps, in Q32 ns per interval.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PiLimits {
    y_max: i64,
    i_max: i64,
}

/// Why a limit pair was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LimitError {
    /// y_max must be in (0, LIMIT_MAX_NS·2^32].
    OutputLimit,
    /// I_max must be in (0, y_max] (servo.md §7 invariant 2: then saturation ends at the first
    /// sample whose P term opposes it).
    IntegratorLimit,
}

impl PiLimits {
    /// REQ-SERVO-011: limits in Q32 ns per interval, 0 < I_max ≤ y_max ≤ 2^60.
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
    pub const fn y_max(self) -> i64 {
        self.y_max
    }

    /// I_max in Q32.
    pub const fn i_max(self) -> i64 {
        self.i_max
    }
}

/// Result of one PI step.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
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

/// REQ-SERVO-010..013: one PI update for error `theta` (ns) from integrator `i` (Q32).
///
/// Total for every input: `i` outside ±I_max is first clamped to it (a corrupted state cannot
/// leak into the output), `theta` is clamped to ±THETA_MAX.
pub fn pi_step(g: PiGains, lim: PiLimits, i: i64, theta: i64) -> PiStep {
    let i = clamp_mag(i, lim.i_max);
    let th = clamp_mag(theta, THETA_MAX);
    // |Kp·θ| ≤ 2^33·2^28, |Ki·θ| < 2^34·2^28 (module doc).
    let p_term = g.kp().wrapping_mul(th);
    let i_term = g.ki().wrapping_mul(th);
    let v = p_term.wrapping_add(i).wrapping_add(i_term);
    let y = clamp_mag(v, lim.y_max);
    let saturated = v != y;
    // Integrate when unsaturated, or when the increment points back toward the range.
    let pulls_back = (v > lim.y_max && i_term < 0) || (v < lim.y_max.wrapping_neg() && i_term > 0);
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

/// Hold: the command used when a sample is missing, blanked or rejected — the integrator alone
/// (the learned frequency), no P term, no integration (servo.md §7 rule 1).
#[inline]
pub fn hold(lim: PiLimits, i: i64) -> i64 {
    clamp_mag(i, lim.i_max)
}

#[cfg(test)]
mod tests {
    use super::super::gains::{Pole, ONE};
    use super::*;

    #[test]
    fn linear_region_matches_formula() {
        let g = PiGains::seed004();
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
