//! Allocation-free statistics for the cyclic loop: a per-second window (rms / max, in the
//! spirit of linuxptp's `rms 12 max 40` lines) and a run-long fixed-bucket histogram for
//! median / p99 / p99.9.
//!
//! WHY fixed buckets: the loop must not allocate, so the histogram's memory is taken once
//! before the loop starts; recording is an index increment. Resolution is 10 ns up to 1 ms,
//! which covers veth round trips (4..200 us) and wake lateness; slower samples land in an
//! overflow bucket and are still reflected in the exact maximum.

/// Width of one histogram bucket in ns.
pub const BUCKET_NS: u64 = 10;
/// Number of finite buckets (range 0..1 ms).
pub const BUCKETS: usize = 100_000;

/// Run-long distribution of non-negative durations in ns.
#[derive(Debug, Clone)]
pub struct Histogram {
    buckets: Box<[u32]>,
    overflow: u64,
    count: u64,
    sum: u128,
    min: u64,
    max: u64,
}

impl Default for Histogram {
    fn default() -> Self {
        Self::new()
    }
}

impl Histogram {
    /// Allocates the buckets (do this before the loop).
    pub fn new() -> Self {
        Histogram {
            buckets: vec![0u32; BUCKETS].into_boxed_slice(),
            overflow: 0,
            count: 0,
            sum: 0,
            min: u64::MAX,
            max: 0,
        }
    }

    /// Records one sample (ns). Never allocates.
    #[inline]
    pub fn record(&mut self, ns: u64) {
        let idx = (ns / BUCKET_NS) as usize;
        match self.buckets.get_mut(idx) {
            Some(b) => *b = b.saturating_add(1),
            None => self.overflow = self.overflow.saturating_add(1),
        }
        self.count = self.count.saturating_add(1);
        self.sum = self.sum.saturating_add(u128::from(ns));
        self.min = self.min.min(ns);
        self.max = self.max.max(ns);
    }

    /// Number of samples.
    pub fn count(&self) -> u64 {
        self.count
    }

    /// Largest sample (exact), 0 when empty.
    pub fn max(&self) -> u64 {
        self.max
    }

    /// Smallest sample (exact), 0 when empty.
    pub fn min(&self) -> u64 {
        if self.count == 0 {
            0
        } else {
            self.min
        }
    }

    /// Mean in ns, 0 when empty.
    pub fn mean(&self) -> f64 {
        if self.count == 0 {
            0.0
        } else {
            self.sum as f64 / self.count as f64
        }
    }

    /// The `q` quantile (0..=1) in ns: the upper edge of the bucket holding it (10 ns
    /// resolution), clamped to the exact min and max, which are returned exactly for the first
    /// and last rank. Ranks beyond the bucket range report the max. 0 when empty.
    pub fn quantile(&self, q: f64) -> u64 {
        if self.count == 0 {
            return 0;
        }
        let q = q.clamp(0.0, 1.0);
        // Rank of the sample we want, 1-based, at least 1.
        let rank = ((q * self.count as f64).ceil() as u64).max(1);
        // The extremes are known exactly.
        if rank == 1 {
            return self.min();
        }
        if rank >= self.count {
            return self.max;
        }
        let mut seen = 0u64;
        for (i, &c) in self.buckets.iter().enumerate() {
            seen += u64::from(c);
            if seen >= rank {
                return ((i as u64 + 1) * BUCKET_NS).min(self.max).max(self.min());
            }
        }
        self.max
    }

    /// A compact summary (all in ns).
    pub fn summary(&self) -> Summary {
        Summary {
            count: self.count,
            min: self.min(),
            median: self.quantile(0.5),
            p90: self.quantile(0.9),
            p99: self.quantile(0.99),
            p999: self.quantile(0.999),
            max: self.max,
            mean: self.mean(),
        }
    }
}

/// Quantiles of a [`Histogram`], in ns.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct Summary {
    /// Number of samples.
    pub count: u64,
    /// Smallest.
    pub min: u64,
    /// 50th percentile.
    pub median: u64,
    /// 90th percentile.
    pub p90: u64,
    /// 99th percentile.
    pub p99: u64,
    /// 99.9th percentile.
    pub p999: u64,
    /// Largest.
    pub max: u64,
    /// Mean.
    pub mean: f64,
}

impl std::fmt::Display for Summary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let us = |ns: u64| ns as f64 / 1000.0;
        write!(
            f,
            "n={} median {:.1} p90 {:.1} p99 {:.1} p99.9 {:.1} max {:.1} us",
            self.count,
            us(self.median),
            us(self.p90),
            us(self.p99),
            us(self.p999),
            us(self.max)
        )
    }
}

/// Signed samples over one reporting window: count, rms, mean, max |x|.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Window {
    count: u64,
    sum: i128,
    sum_sq: u128,
    max_abs: u64,
}

impl Window {
    /// Adds one sample.
    #[inline]
    pub fn record(&mut self, x: i64) {
        self.count = self.count.saturating_add(1);
        self.sum = self.sum.saturating_add(i128::from(x));
        let a = x.unsigned_abs();
        self.sum_sq = self.sum_sq.saturating_add(u128::from(a) * u128::from(a));
        self.max_abs = self.max_abs.max(a);
    }

    /// Samples so far.
    pub fn count(&self) -> u64 {
        self.count
    }

    /// Root mean square, 0 when empty.
    pub fn rms(&self) -> f64 {
        if self.count == 0 {
            0.0
        } else {
            (self.sum_sq as f64 / self.count as f64).sqrt()
        }
    }

    /// Mean, 0 when empty.
    pub fn mean(&self) -> f64 {
        if self.count == 0 {
            0.0
        } else {
            self.sum as f64 / self.count as f64
        }
    }

    /// Largest |x|.
    pub fn max_abs(&self) -> u64 {
        self.max_abs
    }

    /// Clears for the next window.
    pub fn reset(&mut self) {
        *self = Window::default();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_of_uniform_samples() {
        let mut h = Histogram::new();
        for i in 1..=1000u64 {
            h.record(i * 1000); // 1..1000 us
        }
        let s = h.summary();
        assert_eq!(s.count, 1000);
        assert_eq!(s.min, 1000);
        assert_eq!(s.max, 1_000_000);
        assert_eq!(s.median, 500_000 + BUCKET_NS);
        assert_eq!(s.p99, 990_000 + BUCKET_NS);
        assert!((s.mean - 500_500.0).abs() < 1e-6);
    }

    #[test]
    fn overflow_reports_exact_max() {
        let mut h = Histogram::new();
        h.record(5);
        h.record(5_000_000);
        assert_eq!(h.quantile(1.0), 5_000_000);
        assert_eq!(h.quantile(0.5), 5);
        assert_eq!(Histogram::new().quantile(0.5), 0);
    }

    #[test]
    fn window_rms_and_max() {
        let mut w = Window::default();
        for x in [3i64, -4, 3, -4] {
            w.record(x);
        }
        assert!((w.rms() - 12.5f64.sqrt()).abs() < 1e-9);
        assert_eq!(w.max_abs(), 4);
        assert!((w.mean() + 0.5).abs() < 1e-9);
        w.record(i64::MIN);
        assert_eq!(w.max_abs(), 1 << 63);
        w.reset();
        assert_eq!(w.count(), 0);
    }
}
