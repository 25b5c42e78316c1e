//! Median/MAD outlier gate over the last [`GATE_WINDOW`] accepted errors (REQ-SERVO-050).
//!
//! Why: OS wake-up and NIC timestamp noise is heavy-tailed (a few samples 10–100× the typical
//! jitter); a PI integrates every one of them. The median and the
//! median absolute deviation are unaffected by a minority of outliers, so the gate rejects a
//! sample whose distance from the window median exceeds max(κ·1.4826·MAD, floor). A run of
//! `confirm` rejections on the same side is a real change, not noise: the caller then re-acquires
//! or steps (REQ-SERVO-050).

use super::run::SignRun;

/// Window length (power of two; the median of 16 is cheap to sort on the stack).
pub const GATE_WINDOW: usize = 16;

/// Gate configuration.
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::gate::GateConfig;
///
/// // κ = 5 (5 · 1.4826 in Q8), 8 samples before arming, 3 same-side rejections confirm.
/// let cfg = GateConfig {
///     kappa_q8: 1898,
///     floor_ns: 100,
///     min_samples: 8,
///     confirm: 3,
/// };
/// assert_eq!(cfg, GateConfig::with_floor(100));
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
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
    /// κ = 5, floor as given, 8 samples before arming, confirm after 3 (ecdc choices).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::gate::GateConfig;
    ///
    /// // For a 1 ms cycle the master servo uses a floor of P/100 = 10 µs.
    /// let cfg = GateConfig::with_floor(10_000);
    /// assert_eq!((cfg.floor_ns, cfg.confirm), (10_000, 3));
    /// ```
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
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::gate::{Gate, GateConfig, GateVerdict};
///
/// let cfg = GateConfig::with_floor(100);
/// let mut gate = Gate::new();
/// for theta in [10, -10, 5, -5, 0, 8, -8, 2] {
///     gate.push(theta);
/// }
/// // A 5 µs spike is rejected; three on the same side are a real change.
/// let v = [5_000, 5_000, 5_000].map(|theta| gate.judge(&cfg, theta));
/// assert_eq!(
///     v,
///     [
///         GateVerdict::Reject,
///         GateVerdict::Reject,
///         GateVerdict::Confirmed
///     ]
/// );
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum GateVerdict {
    /// Inside the threshold (or the gate is not armed): use it.
    Accept,
    /// Outside the threshold: do not integrate, hold.
    Reject,
    /// The `confirm`-th consecutive rejection on the same side: a real change.
    Confirmed,
}

/// Gate state: a ring of recent accepted errors plus the current rejection run.
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::gate::{Gate, GateConfig, GateVerdict};
///
/// let cfg = GateConfig::with_floor(100);
/// let mut gate = Gate::new();
/// for theta in [10, -10, 5, -5, 0, 8, -8, 2] {
///     // Judge first, record only what was accepted.
///     if gate.judge(&cfg, theta) == GateVerdict::Accept {
///         gate.push(theta);
///     }
/// }
/// assert_eq!(gate.judge(&cfg, 50), GateVerdict::Accept);
/// assert_eq!(gate.judge(&cfg, -5_000), GateVerdict::Reject);
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Gate {
    buf: [i64; GATE_WINDOW],
    /// The same `len` entries as `buf`, kept in ascending order by [`Gate::push`] (entries
    /// past `len` are unspecified), so the median and MAD need no sort per judgement.
    sorted: [i64; GATE_WINDOW],
    len: u8,
    head: u8,
    run: SignRun,
}

impl Default for Gate {
    fn default() -> Self {
        Self::new()
    }
}

/// Replace one entry equal to `old` in the full ascending window by `new` (if `old` is present),
/// keeping it ascending: `old` and the rank of `new` are found by bisection, then the entries
/// between the two positions move by one slot in a single block copy.
#[inline]
fn replace_full(s: &mut [i64; GATE_WINDOW], old: i64, new: i64) {
    let p = count_below(s, old);
    if s.get(p) != Some(&old) {
        return;
    }
    // l entries are below `new`: l > p when new > old, l ≤ p otherwise.
    let l = count_below(s, new);
    let slot = if l > p {
        // s[p+1..l] move left into s[p..l-1]; `new` goes to l − 1.
        s.copy_within(p.wrapping_add(1)..l, p);
        l.wrapping_sub(1)
    } else {
        // s[l..p] move right into s[l+1..=p]; `new` goes to l.
        s.copy_within(l..p, l.wrapping_add(1));
        l
    };
    if let Some(v) = s.get_mut(slot) {
        *v = new;
    }
}

/// Insert `x` into the ascending prefix `s[..n]` (n < GATE_WINDOW), keeping it ascending.
pub(super) fn sorted_insert(s: &mut [i64; GATE_WINDOW], n: usize, x: i64) {
    let Some(v) = s.get_mut(..=n) else {
        return;
    };
    let i = v.get(..n).map_or(0, |p| p.partition_point(|&y| y < x));
    // i ≤ n < v.len(): the ranges are in bounds.
    v.copy_within(i..n, i.wrapping_add(1));
    if let Some(slot) = v.get_mut(i) {
        *slot = x;
    }
}

/// Median (lower middle for even n) and MAD (the same median of |x − median|) of an ascending
/// slice, without sorting. With k = (n − 1)/2 and m = s[k], the deviations below the median
/// (m − s[k], m − s[k−1], …, m − s[0]: k + 1 of them) and above it (s[k+1] − m, …) are two
/// ascending runs; the MAD is the (k+1)-th smallest of their union. Taking t from the upper run
/// and k + 1 − t from the lower one, the largest taken, max(m − s[t], s[k+t] − m), is at least
/// that element for every t and equal to it for the merge's own split, so the MAD is the
/// minimum over t (t = k + 1 is never needed: the lower run starts with m − s[k] = 0, so the
/// split t = k already has max = s[2k] − m ≤ s[2k+1] − m): k + 1 branch-free steps. Equal,
/// value for value, to sorting a copy and the deviations (`median_mad_equals_sorting` in the
/// tests).
pub(super) fn median_mad_sorted(s: &[i64]) -> (i64, i64) {
    let k = s.len().wrapping_sub(1) / 2;
    let (Some(&med), Some(&first)) = (s.get(k), s.first()) else {
        return (0, 0);
    };
    // t = 0: the whole lower run.
    let mut mad = med.wrapping_sub(first);
    // t = 1..=k.
    if let (Some(lower), Some(upper)) = (s.get(1..=k), s.get(k.wrapping_add(1)..)) {
        for (&x, &y) in lower.iter().zip(upper) {
            mad = mad.min(med.wrapping_sub(x).max(y.wrapping_sub(med)));
        }
    }
    (med, mad)
}

/// `s[i]` for an index the caller keeps below [`GATE_WINDOW`] (masked, so no bounds check).
#[inline(always)]
fn at(s: &[i64; GATE_WINDOW], i: usize) -> i64 {
    s.get(i & (GATE_WINDOW - 1)).copied().unwrap_or(0)
}

/// Median and MAD of a full ascending window: [`median_mad_sorted`] for n = 16 (k = 7), with
/// the minimum over the split t found by bisection instead of a scan. With a_t = m − s[t]
/// (non-increasing in t) and b_t = s[7+t] − m (non-decreasing), the predicate b_t ≥ a_t is
/// monotone in t and true at t = 7 (a_7 = 0); for its first true t*, max(a_t, b_t) is a_t
/// (non-increasing) below t* and b_t (non-decreasing) from t* on, so the minimum over t is
/// min(b_{t*}, a_{t*−1}) (only b_{t*} when t* = 0). Three branch-free halvings find t*.
#[inline]
fn median_mad_full(s: &[i64; GATE_WINDOW]) -> (i64, i64) {
    const K: usize = (GATE_WINDOW - 1) / 2;
    let med = s[K];
    // b_t ≥ a_t ⇔ s[7+t] + s[t] ≥ 2m; entries are clamped to ±2^40, so nothing overflows.
    let twice = med.wrapping_mul(2);
    let upper = |t: usize| at(s, K.wrapping_add(t)).wrapping_add(at(s, t)) >= twice;
    let mut t: usize = if upper(3) { 0 } else { 4 };
    if !upper(t.wrapping_add(1)) {
        t = t.wrapping_add(2);
    }
    if !upper(t) {
        t = t.wrapping_add(1);
    }
    let b = at(s, K.wrapping_add(t)).wrapping_sub(med);
    let a = match t.checked_sub(1) {
        Some(u) => med.wrapping_sub(at(s, u)),
        None => i64::MAX,
    };
    (med, a.min(b))
}

/// Number of entries of the full ascending window below `x`, in [0, 16] (branch-free bisection).
#[inline(always)]
fn count_below(s: &[i64; GATE_WINDOW], x: i64) -> usize {
    let mut i = 0usize;
    for half in [8usize, 4, 2, 1] {
        if at(s, i.wrapping_add(half).wrapping_sub(1)) < x {
            i = i.wrapping_add(half);
        }
    }
    i.wrapping_add(usize::from(at(s, i) < x))
}

impl Gate {
    /// An empty, unarmed gate.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::gate::{Gate, GateConfig};
    ///
    /// let gate = Gate::new();
    /// assert!(gate.is_empty());
    /// assert_eq!(gate.threshold(&GateConfig::with_floor(100)), None); // not armed
    /// ```
    pub const fn new() -> Self {
        Gate {
            buf: [0; GATE_WINDOW],
            sorted: [0; GATE_WINDOW],
            len: 0,
            head: 0,
            run: SignRun::new(),
        }
    }

    /// Number of samples in the window.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::gate::{Gate, GATE_WINDOW};
    ///
    /// let mut gate = Gate::new();
    /// for theta in 0..20 {
    ///     gate.push(theta);
    /// }
    /// assert_eq!(gate.len(), GATE_WINDOW); // the window keeps the last 16
    /// ```
    pub const fn len(&self) -> usize {
        self.len as usize
    }

    /// True when the window is empty.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::gate::Gate;
    ///
    /// let mut gate = Gate::new();
    /// assert!(gate.is_empty());
    /// gate.push(3);
    /// assert!(!gate.is_empty());
    /// ```
    pub const fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// (median, threshold) of the current window, or `None` while not armed.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::gate::{Gate, GateConfig};
    ///
    /// let cfg = GateConfig::with_floor(100);
    /// let mut gate = Gate::new();
    /// for theta in [10, -10, 5, -5, 0, 8, -8, 2] {
    ///     gate.push(theta);
    /// }
    /// // Median 0; κ·MAD of this quiet window is below the floor, so the floor rules.
    /// assert_eq!(gate.threshold(&cfg), Some((0, 100)));
    /// ```
    #[inline]
    pub fn threshold(&self, cfg: &GateConfig) -> Option<(i64, i64)> {
        let n = self.len();
        if cfg.kappa_q8 == 0 || n < usize::from(cfg.min_samples.max(3)) {
            return None;
        }
        let med = *self.sorted.get(..n)?.get(n.wrapping_sub(1) / 2)?;
        Some((med, self.spread(cfg, n).max(i64::from(cfg.floor_ns))))
    }

    /// κ·MAD (Q8 product shifted back, saturating) of the first `n` sorted entries, n ≤ 16.
    #[inline]
    fn spread(&self, cfg: &GateConfig, n: usize) -> i64 {
        // Window entries are clamped to ±2^40 on entry: the deviations cannot overflow.
        let mad = if n == GATE_WINDOW {
            median_mad_full(&self.sorted).1
        } else {
            self.sorted.get(..n).map_or(0, |s| median_mad_sorted(s).1)
        };
        mad.saturating_mul(i64::from(cfg.kappa_q8)) >> 8
    }

    /// REQ-SERVO-050: judge `theta`. Does not record it; call [`Gate::push`] for accepted ones.
    ///
    /// The same decision as comparing |θ − median| with [`Gate::threshold`]'s max(κ·MAD, floor),
    /// but the MAD is only computed when the distance exceeds the floor (below it the sample is
    /// inside the threshold whatever the MAD is).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::gate::{Gate, GateConfig, GateVerdict};
    ///
    /// let cfg = GateConfig::with_floor(100);
    /// let mut gate = Gate::new();
    /// // Not armed yet: everything is accepted.
    /// assert_eq!(gate.judge(&cfg, 1_000_000), GateVerdict::Accept);
    /// for theta in [0; 8] {
    ///     gate.push(theta);
    /// }
    /// assert_eq!(gate.judge(&cfg, 99), GateVerdict::Accept);
    /// assert_eq!(gate.judge(&cfg, 101), GateVerdict::Reject);
    /// ```
    #[inline(always)]
    pub fn judge(&mut self, cfg: &GateConfig, theta: i64) -> GateVerdict {
        let n = self.len();
        // Not armed: exactly when `threshold` is None (n ≤ GATE_WINDOW always holds).
        if cfg.kappa_q8 == 0 || n < usize::from(cfg.min_samples.max(3)) || n > GATE_WINDOW {
            self.run.clear();
            return GateVerdict::Accept;
        }
        // n in [3, 16]: the median index (n − 1)/2 is in bounds.
        let med = at(&self.sorted, n.wrapping_sub(1) / 2);
        let e = theta.clamp(-WINDOW_CLAMP, WINDOW_CLAMP).wrapping_sub(med);
        let dist = e.wrapping_abs();
        if dist <= i64::from(cfg.floor_ns) || dist <= self.spread(cfg, n) {
            self.run.clear();
            return GateVerdict::Accept;
        }
        if self.run.push(e > 0) >= cfg.confirm.max(1) {
            self.run.clear();
            GateVerdict::Confirmed
        } else {
            GateVerdict::Reject
        }
    }

    /// Record an accepted error.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::gate::{Gate, GateConfig};
    ///
    /// let mut gate = Gate::new();
    /// for theta in [30, 10, 20] {
    ///     gate.push(theta);
    /// }
    /// let cfg = GateConfig {
    ///     min_samples: 3,
    ///     ..GateConfig::with_floor(100)
    /// };
    /// assert_eq!(gate.threshold(&cfg).map(|(median, _)| median), Some(20));
    /// ```
    #[inline(always)]
    pub fn push(&mut self, theta: i64) {
        let h = usize::from(self.head) % GATE_WINDOW;
        let x = theta.clamp(-WINDOW_CLAMP, WINDOW_CLAMP);
        let n = self.len().min(GATE_WINDOW);
        if let Some(slot) = self.buf.get_mut(h) {
            if n == GATE_WINDOW {
                // Full: slot h holds the oldest entry, which leaves the window.
                replace_full(&mut self.sorted, *slot, x);
            } else {
                sorted_insert(&mut self.sorted, n, x);
            }
            *slot = x;
        }
        self.head = u8::try_from(h.wrapping_add(1) % GATE_WINDOW).unwrap_or(0);
        if self.len() < GATE_WINDOW {
            self.len = self.len.saturating_add(1);
        }
    }

    /// Forget the window (after a step or a confirmed change).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::gate::Gate;
    ///
    /// let mut gate = Gate::new();
    /// gate.push(5);
    /// gate.clear(); // after a step, old errors predict nothing
    /// assert!(gate.is_empty());
    /// ```
    pub fn clear(&mut self) {
        *self = Self::new();
    }
}

/// Window entries are clamped to ±2^40 ns so median/MAD arithmetic cannot overflow.
const WINDOW_CLAMP: i64 = 1 << 40;

#[cfg(test)]
mod tests {
    use super::*;

    /// Empty until the first sample, and its length counts the samples.
    #[test]
    fn empty_and_len() {
        let mut g = Gate::new();
        assert!(g.is_empty());
        assert_eq!(g.len(), 0);
        g.push(3);
        assert!(!g.is_empty());
        assert_eq!(g.len(), 1);
    }

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

    /// The oracle for the incremental window: median of a sorted copy of the window,
    /// then the median of the sorted absolute deviations.
    fn median_by_sorting(v: &mut [i64; GATE_WINDOW], n: usize) -> i64 {
        let s = &mut v[..n];
        s.sort_unstable();
        s[(n - 1) / 2]
    }

    fn threshold_by_sorting(g: &Gate, cfg: &GateConfig) -> Option<(i64, i64)> {
        let n = g.len();
        if cfg.kappa_q8 == 0 || n < usize::from(cfg.min_samples.max(3)) {
            return None;
        }
        let mut v = g.buf;
        let med = median_by_sorting(&mut v, n);
        let mut dev = [0i64; GATE_WINDOW];
        for (d, x) in dev.iter_mut().zip(g.buf.iter()).take(n) {
            *d = x.wrapping_sub(med).wrapping_abs();
        }
        let mad = median_by_sorting(&mut dev, n);
        let t = mad.saturating_mul(i64::from(cfg.kappa_q8)) >> 8;
        Some((med, t.max(i64::from(cfg.floor_ns))))
    }

    use crate::servo::test_rng::Rng;
    impl Rng {
        fn value(&mut self, kind: u64) -> i64 {
            let r = self.next();
            match kind {
                // Few distinct values: many ties.
                0 => (r % 5) as i64 - 2,
                // Typical jitter.
                1 => (r % 2001) as i64 - 1000,
                // Around and beyond the ±2^40 clamp, and the i64 extremes.
                2 => match r % 6 {
                    0 => i64::MIN,
                    1 => i64::MAX,
                    2 => WINDOW_CLAMP + (r >> 60) as i64 - 8,
                    3 => -WINDOW_CLAMP - (r >> 60) as i64 + 8,
                    4 => 0,
                    _ => (r >> 20) as i64 - (1 << 43),
                },
                // Anything.
                _ => r as i64,
            }
        }
    }

    #[test]
    fn median_mad_equals_sorting() {
        let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
        for case in 0..20_000u64 {
            let n = 1 + (case % GATE_WINDOW as u64) as usize;
            let mut v = [0i64; GATE_WINDOW];
            for x in v.iter_mut().take(n) {
                *x = rng.value(case % 4).clamp(-WINDOW_CLAMP, WINDOW_CLAMP);
            }
            let mut s = v;
            s[..n].sort_unstable();
            let mut a = v;
            let med = median_by_sorting(&mut a, n);
            let mut dev = [0i64; GATE_WINDOW];
            for (d, x) in dev.iter_mut().zip(v.iter()).take(n) {
                *d = x.wrapping_sub(med).wrapping_abs();
            }
            let mad = median_by_sorting(&mut dev, n);
            assert_eq!(median_mad_sorted(&s[..n]), (med, mad), "{:?}", &v[..n]);
            if n == GATE_WINDOW {
                assert_eq!(median_mad_full(&s), (med, mad), "{v:?}");
            }
        }
    }

    #[test]
    fn incremental_window_equals_sorting_gate() {
        let cfgs = [
            GateConfig::with_floor(0),
            GateConfig::with_floor(10_000),
            GateConfig {
                kappa_q8: u32::MAX,
                floor_ns: 1,
                min_samples: 0,
                confirm: 1,
            },
            GateConfig {
                kappa_q8: 0,
                floor_ns: 5,
                min_samples: 16,
                confirm: 0,
            },
            GateConfig {
                kappa_q8: 1,
                floor_ns: 0,
                min_samples: 200,
                confirm: 3,
            },
        ];
        let mut rng = Rng(12345);
        for seq in 0..400u64 {
            let mut g = Gate::new();
            let kind = seq % 4;
            for step in 0..200u64 {
                let theta = rng.value(if step % 17 == 0 { 2 } else { kind });
                let cfg = &cfgs[(rng.next() % cfgs.len() as u64) as usize];
                assert_eq!(g.threshold(cfg), threshold_by_sorting(&g, cfg));
                let mut sorted = g.buf;
                sorted[..g.len()].sort_unstable();
                assert_eq!(g.sorted[..g.len()], sorted[..g.len()]);
                let _ = g.judge(cfg, theta);
                if rng.next() % 64 == 0 {
                    g.clear();
                } else {
                    g.push(theta);
                }
            }
        }
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
