//! Median/MAD outlier gate over the last [`GATE_WINDOW`] accepted errors (servo.md §7 rule 3).
//!
//! Why: OS wake-up and NIC timestamp noise is heavy-tailed (a few samples 10–100× the typical
//! jitter, wire-and-runtime.md §4.4); a PI integrates every one of them. The median and the
//! median absolute deviation are unaffected by a minority of outliers, so the gate rejects a
//! sample whose distance from the window median exceeds max(κ·1.4826·MAD, floor). A run of
//! `confirm` rejections on the same side is a real change, not noise: the caller then re-acquires
//! or steps (REQ-SERVO-050).

/// Window length (power of two; the median of 16 is cheap to sort on the stack).
pub const GATE_WINDOW: usize = 16;

/// Gate configuration.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GateConfig {
    /// κ·1.4826 in Q8 (κ = 5 → 1898). 0 disables the gate.
    pub kappa_q8: u32,
    /// Smallest rejection threshold, ns: quantised or very quiet inputs have MAD = 0.
    pub floor_ns: u32,
    /// Samples the window must hold before the gate may reject anything (≥ 3).
    pub min_samples: u8,
    /// Consecutive same-side rejections that count as a real change (N_c).
    pub confirm: u8,
}

impl GateConfig {
    /// κ = 5, floor as given, 8 samples before arming, confirm after 3 (servo.md §7 defaults).
    pub const fn with_floor(floor_ns: u32) -> Self {
        GateConfig {
            kappa_q8: 1898,
            floor_ns,
            min_samples: 8,
            confirm: 3,
        }
    }
}

/// What the gate decided about one sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GateVerdict {
    /// Inside the threshold (or the gate is not armed): use it.
    Accept,
    /// Outside the threshold: do not integrate, hold.
    Reject,
    /// The `confirm`-th consecutive rejection on the same side: a real change.
    Confirmed,
}

/// Gate state: a ring of recent accepted errors plus the current rejection run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Gate {
    buf: [i64; GATE_WINDOW],
    len: u8,
    head: u8,
    run: u8,
    run_positive: bool,
}

impl Default for Gate {
    fn default() -> Self {
        Self::new()
    }
}

/// Median of the first `n` entries of `v` (sorted in place); lower middle for even `n`.
fn median(v: &mut [i64; GATE_WINDOW], n: usize) -> i64 {
    let Some(s) = v.get_mut(..n) else {
        return 0;
    };
    s.sort_unstable();
    s.get(n.wrapping_sub(1) / 2).copied().unwrap_or(0)
}

impl Gate {
    /// An empty, unarmed gate.
    pub const fn new() -> Self {
        Gate {
            buf: [0; GATE_WINDOW],
            len: 0,
            head: 0,
            run: 0,
            run_positive: false,
        }
    }

    /// Number of samples in the window.
    pub const fn len(&self) -> usize {
        self.len as usize
    }

    /// True when the window is empty.
    pub const fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// (median, threshold) of the current window, or `None` while not armed.
    pub fn threshold(&self, cfg: &GateConfig) -> Option<(i64, i64)> {
        let n = self.len();
        if cfg.kappa_q8 == 0 || n < usize::from(cfg.min_samples.max(3)) {
            return None;
        }
        let mut v = self.buf;
        let med = median(&mut v, n);
        let mut dev = [0i64; GATE_WINDOW];
        for (d, x) in dev.iter_mut().zip(self.buf.iter()).take(n) {
            // Window entries are clamped to ±2^40 on entry: no overflow.
            *d = x.wrapping_sub(med).wrapping_abs();
        }
        let mad = median(&mut dev, n);
        // MAD ≤ 2^41, κ_q8 < 2^32: the product fits in i64 before the shift.
        let t = mad.saturating_mul(i64::from(cfg.kappa_q8)) >> 8;
        Some((med, t.max(i64::from(cfg.floor_ns))))
    }

    /// REQ-SERVO-050: judge `theta`. Does not record it; call [`Gate::push`] for accepted ones.
    pub fn judge(&mut self, cfg: &GateConfig, theta: i64) -> GateVerdict {
        let Some((med, thr)) = self.threshold(cfg) else {
            self.run = 0;
            return GateVerdict::Accept;
        };
        let e = theta.clamp(-WINDOW_CLAMP, WINDOW_CLAMP).wrapping_sub(med);
        if e.wrapping_abs() <= thr {
            self.run = 0;
            return GateVerdict::Accept;
        }
        let positive = e > 0;
        if self.run == 0 || positive != self.run_positive {
            self.run = 1;
            self.run_positive = positive;
        } else {
            self.run = self.run.saturating_add(1);
        }
        if self.run >= cfg.confirm.max(1) {
            self.run = 0;
            GateVerdict::Confirmed
        } else {
            GateVerdict::Reject
        }
    }

    /// Record an accepted error.
    pub fn push(&mut self, theta: i64) {
        let h = usize::from(self.head) % GATE_WINDOW;
        if let Some(slot) = self.buf.get_mut(h) {
            *slot = theta.clamp(-WINDOW_CLAMP, WINDOW_CLAMP);
        }
        self.head = u8::try_from(h.wrapping_add(1) % GATE_WINDOW).unwrap_or(0);
        if self.len() < GATE_WINDOW {
            self.len = self.len.saturating_add(1);
        }
    }

    /// Forget the window (after a step or a confirmed change).
    pub fn clear(&mut self) {
        *self = Self::new();
    }
}

/// Window entries are clamped to ±2^40 ns so median/MAD arithmetic cannot overflow.
const WINDOW_CLAMP: i64 = 1 << 40;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_outlier_confirms_real_change() {
        let cfg = GateConfig::with_floor(50);
        let mut g = Gate::new();
        for k in 0..16 {
            assert_eq!(g.judge(&cfg, (k % 5) * 10 - 20), GateVerdict::Accept);
            g.push((k % 5) * 10 - 20);
        }
        // Median 0, MAD 10 → threshold max(74, 50) = 74.
        assert_eq!(g.threshold(&cfg), Some((0, 74)));
        assert_eq!(g.judge(&cfg, 70), GateVerdict::Accept);
        assert_eq!(g.judge(&cfg, 10_000), GateVerdict::Reject);
        assert_eq!(g.judge(&cfg, -10_000), GateVerdict::Reject); // side change restarts run
        assert_eq!(g.judge(&cfg, 5_000), GateVerdict::Reject);
        assert_eq!(g.judge(&cfg, 5_000), GateVerdict::Reject);
        assert_eq!(g.judge(&cfg, 5_000), GateVerdict::Confirmed);
        assert_eq!(g.judge(&cfg, i64::MIN), GateVerdict::Reject);
    }

    #[test]
    fn unarmed_until_min_samples() {
        let cfg = GateConfig::with_floor(1);
        let mut g = Gate::new();
        for _ in 0..7 {
            assert_eq!(g.judge(&cfg, i64::MAX), GateVerdict::Accept);
            g.push(0);
        }
        g.push(0);
        assert_eq!(g.judge(&cfg, 2), GateVerdict::Reject);
    }
}
