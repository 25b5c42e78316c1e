//! Servo specification: plain reference versions of the servo maths (REQ-SERVO in
//! `spec/req/servo.md`), written for obviousness over wide integers (i128) or f64, with no
//! clamping tricks and no fixed-point shortcuts. Model tests in `proofs/tests/servo.rs` compare
//! `ecdc_core::servo` against these functions.
//!
//! Seed 004 (SERCOS-III / IEEE 1588 paper) equations used here: eq. 1 (offset), eq. 2 (mean path
//! delay; the image is missing, the standard two-way form is used), eq. 6 (rate ratio over n
//! periods), eq. 7–9 (two-pole offset filter with e^−aT = 1/2, e^−bT = 1/3; reconstructed from the
//! pole choice, see [`seed_filter_direct`]), eq. 15–18 (counter self-compensation).

/// Q32 one.
pub const ONE: i128 = 1 << 32;

/// Closed-loop poles of the per-sample PI (REQ-SERVO-001): the roots of
/// z² + (Kp + Ki − 2)·z + (1 − Kp). Returns the larger root modulus.
pub fn pi_pole_radius(kp: f64, ki: f64) -> f64 {
    let b = kp + ki - 2.0;
    let c = 1.0 - kp;
    let disc = b * b - 4.0 * c;
    if disc >= 0.0 {
        let s = disc.sqrt();
        ((-b + s) / 2.0).abs().max(((-b - s) / 2.0).abs())
    } else {
        // Complex pair: |z|² = c.
        c.sqrt()
    }
}

/// REQ-SERVO-002 in its plain form: both closed-loop poles strictly inside the unit circle.
/// (The core additionally demands the margin 2^-10; see `ecdc_core::servo::gains::MARGIN`.)
pub fn pi_stable(kp: f64, ki: f64) -> bool {
    ki > 0.0 && pi_pole_radius(kp, ki) < 1.0
}

/// REQ-SERVO-001: Kp = 1 − p₁p₂, Ki = (1 − p₁)(1 − p₂).
pub fn gains_from_poles(p1: f64, p2: f64) -> (f64, f64) {
    (1.0 - p1 * p2, (1.0 - p1) * (1.0 - p2))
}

/// REQ-SERVO-010..012: one PI step over i128, the rule written literally. Inputs in Q32 except
/// `theta` (ns). Returns (y, I', saturated).
///
/// θ is first clamped to ±2^28 ns and I to ±I_max (the kernel's documented input contract);
/// then v = Kp·θ + I + Ki·θ, y = clamp(v, ±y_max); I' = clamp(I + Ki·θ, ±I_max) when |v| ≤ y_max
/// or Ki·θ points back toward the range, else I' = I.
pub fn pi_step(
    kp: i128,
    ki: i128,
    y_max: i128,
    i_max: i128,
    i: i128,
    theta: i128,
) -> (i128, i128, bool) {
    let i = i.clamp(-i_max, i_max);
    let th = theta.clamp(-(1 << 28), 1 << 28);
    let inc = ki * th;
    let v = kp * th + i + inc;
    let y = v.clamp(-y_max, y_max);
    let saturated = v != y;
    let back = (v > y_max && inc < 0) || (v < -y_max && inc > 0);
    let i_next = if !saturated || back {
        (i + inc).clamp(-i_max, i_max)
    } else {
        i
    };
    (y, i_next, saturated)
}

/// Seed 004 eq. 9 as reconstructed in direct form, in f64:
/// Y(k) = (e^−aT + e^−bT)·Y(k−1) − e^−aT·e^−bT·Y(k−2) + (1 − e^−aT)(1 − e^−bT)·X(k), with
/// e^−aT = 1/2 and e^−bT = 1/3, i.e. Y(k) = 5/6·Y(k−1) − 1/6·Y(k−2) + 1/3·X(k) (unity DC gain).
/// History is primed with the first input (as the core does).
pub fn seed_filter_direct(xs: &[f64]) -> Vec<f64> {
    let (a, b) = (0.5f64, 1.0f64 / 3.0);
    let mut out = Vec::with_capacity(xs.len());
    let (mut y1, mut y2) = match xs.first() {
        Some(&x0) => (x0, x0),
        None => return out,
    };
    for (k, &x) in xs.iter().enumerate() {
        let y = if k == 0 {
            x
        } else {
            (a + b) * y1 - a * b * y2 + (1.0 - a) * (1.0 - b) * x
        };
        out.push(y);
        y2 = y1;
        y1 = y;
    }
    out
}

/// Seed 004 eq. 15–18, the seed's counter compensation per sync period: N' = ⌊−Δ·Npll/T_slave⌋
/// fine (PLL-multiplied) counts for a drift of Δ ns, with `t_slave_ps` the crystal period in ps
/// (the paper's T_slave).
///
/// Reading: eq. 16 defines N = ⌊Δ/T_slave⌋ (whole crystal counts) and eq. 18 prints
/// N' = floor(−N·Npll). Taken with eq. 16's floored N, the outer floor acts on an integer and does
/// nothing, the result is a multiple of Npll (the PLL would add no resolution, contradicting the
/// sentence after eq. 18, which says the multiplication is there to make the compensation finer)
/// and any −T_slave ≤ Δ < 0 yields +Npll counts, a whole crystal count of over-correction. The
/// reading that fits the text is that eq. 18 floors once, at the fine resolution: N is Δ/T_slave
/// before rounding, so N' = ⌊−(Δ/T_slave)·Npll⌋. That is what is implemented; with Npll = 1 it is
/// eq. 16–17 with the floor applied to −Δ/T_slave.
pub fn seed_counter_compensation(delta_ns: i128, t_slave_ps: i128, npll: i128) -> i128 {
    (-delta_ns * 1000 * npll).div_euclid(t_slave_ps)
}

/// REQ-SERVO-041: the exact cumulative correction after periods with drifts `deltas` (ns), in
/// fine counts, as an exact rational num/10^9: Σ −Δ·count_hz / 10^9. Returns the floor.
pub fn exact_counter_total(deltas: &[i128], count_hz: i128) -> i128 {
    let num: i128 = deltas.iter().map(|d| -d * count_hz).sum();
    num.div_euclid(1_000_000_000)
}

/// REQ-SERVO-020: mean path delay ((t2 − t1) + (t4 − t3)) / 2, floor, over unwrapped times.
pub fn mean_path_delay(t1: i128, t2: i128, t3: i128, t4: i128) -> i128 {
    ((t2 - t1) + (t4 - t3)).div_euclid(2)
}

/// REQ-SERVO-021: offset = Ts1 − Tm1 − Delay (eq. 1).
pub fn offset_from_master(t1: i128, t2: i128, delay: i128) -> i128 {
    t2 - t1 - delay
}

/// REQ-SERVO-022: rate correction (ppb, f64) from eq. 6: master elapsed / slave elapsed − 1.
pub fn rate_ratio_ppb(m0: i128, m_n: i128, s0: i128, s_n: i128) -> f64 {
    let dm = (m_n - m0) as f64;
    let ds = (s_n - s0) as f64;
    (dm / ds - 1.0) * 1e9
}

/// The master-follows-reference plant: the phase error of the master's
/// wake-up against the reference, in exact ns·10^9 units so drift in ppb accumulates without
/// rounding. θₖ₊₁ = θₖ + P·drift_ppb/10^9 − cₖ + (jitter handled by the caller).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MasterPlant {
    /// Cycle period, ns.
    pub period_ns: i128,
    /// Master timer rate error, ppb (positive: the master's timer runs fast, wakes early).
    pub drift_ppb: i128,
    /// True (app − ref) error in ns·10^9.
    pub theta_e9: i128,
}

impl MasterPlant {
    /// True error in ns (floor).
    pub fn theta_ns(&self) -> i128 {
        self.theta_e9.div_euclid(1_000_000_000)
    }

    /// Advance one cycle with deadline correction `c_ns` (wake later by c) and an app-time step
    /// (whole periods) `app_step_ns`.
    pub fn advance(&mut self, c_ns: i128, app_step_ns: i128) {
        self.theta_e9 += (app_step_ns - c_ns) * 1_000_000_000 + self.period_ns * self.drift_ppb;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pole_placement_and_jury() {
        let (kp, ki) = gains_from_poles(0.5, 1.0 / 3.0);
        assert!((kp - 5.0 / 6.0).abs() < 1e-12 && (ki - 1.0 / 3.0).abs() < 1e-12);
        assert!((pi_pole_radius(kp, ki) - 0.5).abs() < 1e-9);
        assert!(!pi_stable(1.0, 2.0)); // linuxptp's user-constant corner: pole at −1
        assert!(pi_stable(0.7, 0.3));
    }

    #[test]
    fn filter_unity_dc_gain() {
        let ys = seed_filter_direct(&[0.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0]);
        assert!((ys[1] - 1.0 / 3.0).abs() < 1e-12);
        assert!((ys[10] - 1.0).abs() < 1e-2);
    }

    #[test]
    fn seed_counter_floors_once_at_the_fine_resolution() {
        // 25 MHz crystal (40 000 ps), ×4 (10 ns fine counts). 25 ns of drift is 2.5 fine counts:
        // the seed corrects ⌊−2.5⌋ = −3, one crystal-count floor (⌊25/40⌋ = 0) would give 0.
        assert_eq!(seed_counter_compensation(25, 40_000, 4), -3);
        // A slave 1 ns slow: ⌊0.1⌋ = 0 fine counts, not the +4 (one crystal count) of flooring Δ
        // to crystal counts first.
        assert_eq!(seed_counter_compensation(-1, 40_000, 4), 0);
        // The PLL matters: without it (Npll = 1) the same 25 ns is corrected by a whole count.
        assert_eq!(seed_counter_compensation(25, 40_000, 1), -1);
        assert_eq!(seed_counter_compensation(-40, 40_000, 4), 4);
        assert_eq!(exact_counter_total(&[25; 1000], 100_000_000), -2500);
    }
}
