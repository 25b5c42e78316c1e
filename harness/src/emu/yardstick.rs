//! The DC yardstick: SYNC0 skew, lock and clock error measured in true time from the
//! emulator's observers (SYNC edges, clocks, registers), whoever the master is.
//!
//! `ecdc simulate` (batch, over a finished run) and `ecdc emulate` (streaming, over an
//! open-ended run) both measure through this module, so the definitions are one piece of code:
//!
//! - [`clock_errors`]: slave system time minus the reference's at the same true instant, on the
//!   narrower width when a 32-bit slave is involved;
//! - [`PulseMatcher`]: a SYNC0 pulse is identified by its programmed system time; for every
//!   pulse the reference fired, each other slave's edge true time minus the reference's is one
//!   (slave, pulse) skew pair;
//! - [`SkewStats`]: mean |skew|, nearest-rank p99 |skew|, max |skew|, signed mean;
//! - [`LockTracker`]: lock is the first sample from which on every sample until the end of the
//!   run is within [`LOCK_NS`].
//!
//! [`Yardstick`] is the streaming form `ecdc emulate` uses; docs/emulator.md "DC yardstick"
//! defines its window and keys. Memory is bounded in time: the skew distribution is a
//! fixed-bin histogram (exact below 4096 ns), and the steady-state window is kept as at most
//! `2 × blocks` time blocks of the cyclic phase that merge pairwise as the run grows.

use std::collections::{BTreeMap, VecDeque};

use super::registers::addr;
use super::{EmuError, Network, SyncEdge, SyncSignal, TrueTime};

/// Lock threshold on the true clock error, ns: the "< 100 ns" synchronisation accuracy
/// Beckhoff states for DC (docs/background/esc-registers.md §6).
pub const LOCK_NS: u64 = 100;

/// Clock error `a − b` of two system times: wrapping on 64 bits when both slaves are 64-bit,
/// otherwise on the low 32 bits (the width a 32-bit slave and its loop work with).
pub fn clock_error(a: u64, b: u64, both_64bit: bool) -> i64 {
    if both_64bit {
        a.wrapping_sub(b) as i64
    } else {
        i64::from((a as u32).wrapping_sub(b as u32) as i32)
    }
}

/// Per slave: whether its system time is compared on 64 bits (64-bit DC, or no system time at
/// all, which never enters a comparison).
pub fn wide_slaves(net: &Network) -> Vec<bool> {
    (0..net.slave_count())
        .map(|i| {
            net.slave_info(i)
                .is_none_or(|x| !x.kind.has_system_time() || x.kind.is_64bit())
        })
        .collect()
}

/// Every slave's clock error against `reference` from their system times (`None` for a slave
/// without one, and for every slave while the reference has none).
pub fn clock_errors(sys: &[Option<u64>], wide: &[bool], reference: usize) -> Vec<Option<i64>> {
    let rsys = sys.get(reference).copied().flatten();
    let rwide = wide.get(reference).copied().unwrap_or(true);
    sys.iter()
        .zip(wide)
        .map(|(v, &w)| match (v, rsys) {
            (Some(a), Some(b)) => Some(clock_error(*a, b, w && rwide)),
            _ => None,
        })
        .collect()
}

/// Latest instant up to which some slave of `net` has been evaluated (frame effects land at
/// their true times, possibly after [`Network::now`]); clocks can be sampled from here on.
pub fn max_anchor(net: &Network) -> TrueTime {
    (0..net.slave_count())
        .filter_map(|i| net.esc(i).map(|e| e.anchor()))
        .max()
        .unwrap_or(0)
}

/// 1-based nearest rank of the `p` percentile (0..=100) among `n` values, `None` when empty.
pub fn nearest_rank(p: f64, n: u64) -> Option<u64> {
    if n == 0 {
        return None;
    }
    let rank = ((p / 100.0) * n as f64).ceil() as u64;
    Some(rank.clamp(1, n))
}

/// Nearest-rank percentile of sorted values (`p` in 0..=100).
pub fn percentile(sorted: &[u64], p: f64) -> Option<u64> {
    let rank = nearest_rank(p, sorted.len() as u64)?;
    sorted.get(usize::try_from(rank).ok()? - 1).copied()
}

/// The key a SYNC0 pulse is matched by: its programmed system time. With 32-bit slaves, the
/// low 32 bits (a 32-bit slave's copy of the 64-bit start time).
pub fn pulse_key(system_time: u64, narrow: bool) -> u64 {
    if narrow {
        system_time & u64::from(u32::MAX)
    } else {
        system_time
    }
}

/// One (slave, pulse) skew pair.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Pair {
    /// Emulator index of the slave (never the reference).
    pub slave: usize,
    /// True time of the reference's edge of this pulse (the window is decided on it).
    pub reference_time: TrueTime,
    /// Slave edge true time minus the reference's, ns.
    pub skew_ns: i64,
}

/// Pairs every slave's SYNC0 edge with the reference's edge of the same pulse, streaming.
///
/// Edges of one pulse arrive within the skew (ns to µs) of each other, so only the last
/// [`PulseMatcher::PENDING`] pulses are kept open; an older pulse whose reference edge never
/// came (the reference does not fire it) is dropped unpaired, as in a batch grouping.
#[derive(Debug, Clone)]
pub struct PulseMatcher {
    narrow: bool,
    pending: VecDeque<Pulse>,
}

#[derive(Debug, Clone)]
struct Pulse {
    key: u64,
    reference: Option<TrueTime>,
    early: Vec<(usize, TrueTime)>,
}

impl PulseMatcher {
    /// ecdc choice: 64 open pulses, because a pulse completes within one cycle and 64 cycles
    /// also cover slaves running a SYNC0 cycle other than the reference's.
    pub const PENDING: usize = 64;

    /// A matcher; `narrow` when some slave has a 32-bit system time.
    pub fn new(narrow: bool) -> Self {
        PulseMatcher {
            narrow,
            pending: VecDeque::new(),
        }
    }

    /// Takes one SYNC0 edge of `slave`; calls `out` for every pair it completes.
    pub fn push(
        &mut self,
        reference: usize,
        slave: usize,
        system_time: u64,
        true_time: TrueTime,
        out: &mut impl FnMut(Pair),
    ) {
        let key = pulse_key(system_time, self.narrow);
        let idx = match self.pending.iter().rposition(|p| p.key == key) {
            Some(i) => i,
            None => {
                if self.pending.len() >= Self::PENDING {
                    self.pending.pop_front();
                }
                self.pending.push_back(Pulse {
                    key,
                    reference: None,
                    early: Vec::new(),
                });
                self.pending.len() - 1
            }
        };
        let Some(p) = self.pending.get_mut(idx) else {
            return;
        };
        if slave == reference {
            if p.reference.is_none() {
                p.reference = Some(true_time);
                for (s, t) in p.early.drain(..) {
                    out(Pair {
                        slave: s,
                        reference_time: true_time,
                        skew_ns: t as i64 - true_time as i64,
                    });
                }
            }
        } else if let Some(tref) = p.reference {
            out(Pair {
                slave,
                reference_time: tref,
                skew_ns: true_time as i64 - tref as i64,
            });
        } else {
            p.early.push((slave, true_time));
        }
    }
}

/// Signed samples: count, sum, sum of |·|, max |·|.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Moments {
    count: u64,
    sum: i128,
    sum_abs: u128,
    max_abs: u64,
}

impl Moments {
    /// Adds one sample.
    pub fn record(&mut self, x: i64) {
        self.count = self.count.saturating_add(1);
        self.sum = self.sum.saturating_add(i128::from(x));
        self.sum_abs = self.sum_abs.saturating_add(u128::from(x.unsigned_abs()));
        self.max_abs = self.max_abs.max(x.unsigned_abs());
    }

    /// Adds every sample of `o`.
    pub fn merge(&mut self, o: &Moments) {
        self.count = self.count.saturating_add(o.count);
        self.sum = self.sum.saturating_add(o.sum);
        self.sum_abs = self.sum_abs.saturating_add(o.sum_abs);
        self.max_abs = self.max_abs.max(o.max_abs);
    }

    /// Number of samples.
    pub fn count(&self) -> u64 {
        self.count
    }

    /// Signed mean.
    pub fn mean(&self) -> Option<f64> {
        (self.count > 0).then(|| self.sum as f64 / self.count as f64)
    }

    /// Mean of |·|.
    pub fn mean_abs(&self) -> Option<f64> {
        (self.count > 0).then(|| self.sum_abs as f64 / self.count as f64)
    }

    /// Largest |·|.
    pub fn max_abs(&self) -> Option<u64> {
        (self.count > 0).then_some(self.max_abs)
    }
}

/// |skew| values below this many ns have a bin of their own (exact percentiles). ecdc choice:
/// 4096 ns, because a synchronised network's skews are tens of ns, so every percentile a DC
/// check compares with a threshold near the 100 ns lock criterion is exact.
pub const EXACT_BELOW_NS: u64 = 4096;
/// Sub-bins per power of two above [`EXACT_BELOW_NS`] (relative bin width 1/128). ecdc
/// choice: percentiles of large skews to better than 1 %, in 52 × 128 more bins at most.
const SUB_BINS: u64 = 128;
const SUB_BITS: u32 = 7;

/// Bin of |skew| `v`: `v` itself below 4096 ns, log-linear (128 bins per octave) above.
fn bin_of(v: u64) -> u32 {
    if v < EXACT_BELOW_NS {
        return v as u32;
    }
    let e = 63 - v.leading_zeros(); // >= 12
    let shift = e - SUB_BITS;
    let sub = (v >> shift) - SUB_BINS;
    (EXACT_BELOW_NS + u64::from(e - 12) * SUB_BINS + sub) as u32
}

/// Largest value of bin `b`.
fn bin_upper(b: u32) -> u64 {
    let b = u64::from(b);
    if b < EXACT_BELOW_NS {
        return b;
    }
    let rel = b - EXACT_BELOW_NS;
    let e = rel / SUB_BINS + 12;
    let sub = rel % SUB_BINS;
    let upper = (u128::from(SUB_BINS + sub + 1) << (e - u64::from(SUB_BITS))) - 1;
    u64::try_from(upper).unwrap_or(u64::MAX)
}

/// Streaming SYNC0 skew statistics over (slave, pulse) pairs.
///
/// WHY a fixed-bin histogram (kept sparse): p99 needs the distribution, and a run may be
/// endless. Bins are 1 ns wide below 4096 ns, so every percentile there equals the
/// nearest-rank value of the sorted samples exactly (skews of a working DC network are
/// nanoseconds); above, 128 bins per power of two bound the error of a percentile to 1/128 of
/// its value. At most 4096 + 52 × 128 bins exist whatever the run length; a map holds only the
/// bins that were hit.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct SkewStats {
    moments: Moments,
    bins: BTreeMap<u32, u64>,
}

impl SkewStats {
    /// Adds one signed skew, ns.
    pub fn record(&mut self, skew_ns: i64) {
        self.moments.record(skew_ns);
        let c = self.bins.entry(bin_of(skew_ns.unsigned_abs())).or_insert(0);
        *c = c.saturating_add(1);
    }

    /// Adds every sample of `o`.
    pub fn merge(&mut self, o: &SkewStats) {
        self.moments.merge(&o.moments);
        for (&b, &n) in &o.bins {
            let c = self.bins.entry(b).or_insert(0);
            *c = c.saturating_add(n);
        }
    }

    /// Number of pairs.
    pub fn count(&self) -> u64 {
        self.moments.count()
    }

    /// Mean |skew|.
    pub fn mean_abs(&self) -> Option<f64> {
        self.moments.mean_abs()
    }

    /// Signed mean skew (a constant bias shows here).
    pub fn signed_mean(&self) -> Option<f64> {
        self.moments.mean()
    }

    /// Max |skew|.
    pub fn max_abs(&self) -> Option<u64> {
        self.moments.max_abs()
    }

    /// Nearest-rank percentile of |skew| (`p` in 0..=100): exact below 4096 ns, else the top
    /// of its bin (at most 1/128 above the value), never above the exact maximum.
    pub fn percentile(&self, p: f64) -> Option<u64> {
        let rank = nearest_rank(p, self.count())?;
        let max = self.moments.max_abs;
        let mut seen = 0u64;
        for (&b, &n) in &self.bins {
            seen = seen.saturating_add(n);
            if seen >= rank {
                return Some(bin_upper(b).min(max));
            }
        }
        Some(max)
    }

    /// The numbers a report gives of these pairs.
    pub fn summary(&self) -> SkewSummary {
        SkewSummary {
            mean_ns: self.mean_abs(),
            p99_ns: self.percentile(99.0),
            max_ns: self.max_abs(),
            signed_mean_ns: self.signed_mean(),
        }
    }
}

/// SYNC0 skew over (slave, pulse) pairs as every report gives it (`ecdc emulate`, `simulate`,
/// `bench`): mean |·|, p99 |·| (nearest rank), max |·| and the signed mean, ns. Reports
/// flatten it, so its fields keep their `skew_` names in JSON.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct SkewSummary {
    #[serde(rename = "skew_mean_ns")]
    pub mean_ns: Option<f64>,
    #[serde(rename = "skew_p99_ns")]
    pub p99_ns: Option<u64>,
    #[serde(rename = "skew_max_ns")]
    pub max_ns: Option<u64>,
    /// Signed mean (a constant bias shows here).
    #[serde(rename = "skew_signed_mean_ns")]
    pub signed_mean_ns: Option<f64>,
}

/// Lock instant, streaming: the first sample after the last sample that was not locked.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LockTracker<T> {
    candidate: Option<T>,
}

impl<T> Default for LockTracker<T> {
    fn default() -> Self {
        LockTracker { candidate: None }
    }
}

impl<T: Copy> LockTracker<T> {
    /// Takes the next sample, `at` identifying it, `ok` whether it was within the threshold.
    pub fn sample(&mut self, ok: bool, at: T) {
        if !ok {
            self.candidate = None;
        } else if self.candidate.is_none() {
            self.candidate = Some(at);
        }
    }

    /// The lock sample so far (`None` while the latest sample is not locked).
    pub fn lock(&self) -> Option<T> {
        self.candidate
    }
}

/// Timing of a [`Yardstick`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct YardstickOpts {
    /// Clock sampling period (lock and clock error), ns.
    pub sample_ns: u64,
    /// Width of the first time blocks of the cyclic phase, ns.
    pub first_block_ns: u64,
    /// The window is kept in between `blocks` and `2 × blocks` time blocks.
    pub blocks: usize,
}

impl Default for YardstickOpts {
    /// ecdc choice: sample every 100 µs (simulate's `cycle/10` at its default 1 ms cycle),
    /// 1 ms first blocks, 16..32 blocks (the window start is at most 1/15 of the cyclic phase
    /// before its midpoint once blocks have merged).
    fn default() -> Self {
        YardstickOpts {
            sample_ns: 100_000,
            first_block_ns: 1_000_000,
            blocks: 16,
        }
    }
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
struct SlaveAcc {
    skew: Moments,
    clock_error: Moments,
    sync0_edges: u64,
}

#[derive(Debug, Clone, PartialEq, Eq)]
struct Block {
    skew: SkewStats,
    slaves: Vec<SlaveAcc>,
}

impl Block {
    fn new(n: usize) -> Self {
        Block {
            skew: SkewStats::default(),
            slaves: vec![SlaveAcc::default(); n],
        }
    }

    fn merge(&mut self, o: &Block) {
        self.skew.merge(&o.skew);
        for (a, b) in self.slaves.iter_mut().zip(&o.slaves) {
            a.skew.merge(&b.skew);
            a.clock_error.merge(&b.clock_error);
            a.sync0_edges = a.sync0_edges.saturating_add(b.sync0_edges);
        }
    }
}

/// The `sync` block of `ecdc emulate`'s report.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct SyncReport {
    /// Slaves with a SYNC0 edge in the window.
    pub slaves_firing: usize,
    /// (slave, pulse) skew pairs in the window.
    pub pairs: u64,
    #[serde(flatten)]
    pub skew: SkewSummary,
    /// Lock instant minus the first SYNC0 edge, ms.
    pub lock_ms: Option<f64>,
    /// Emulator index of the slave skews and clock errors are taken against.
    pub reference: Option<usize>,
    /// True time (ns since the emulator started) of the first SYNC0 edge of any slave.
    pub first_sync0_ns: Option<u64>,
    /// Steady-state window, true ns since the emulator started.
    pub window_start_ns: Option<u64>,
    pub window_end_ns: Option<u64>,
}

/// One slave of `ecdc emulate`'s report.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct SlaveReport {
    /// Emulator index (wire position, 0 = first slave).
    pub position: usize,
    /// Configured station address (0x0010).
    pub station: u16,
    /// Vendor / product / revision / serial, `null` where the emulator has none.
    pub identity: Option<super::sii::Identity>,
    /// AL status (0x0130): INIT, PREOP, BOOT, SAFEOP, OP, with `+ERR` when the error bit is set.
    pub al_state: String,
    /// 0x0981 has cyclic operation and SYNC0 enabled.
    pub sync0_active: bool,
    /// SYNC0 edges in the window.
    pub sync0_edges: u64,
    /// Whether this slave is the reference of the skews.
    pub reference: bool,
    /// This slave's skew in the window: mean |·|, max |·|, ns.
    pub skew_mean_ns: Option<f64>,
    pub skew_max_ns: Option<u64>,
    /// True clock error against the reference in the window: signed mean, max |·|, ns.
    pub clock_error_mean_ns: Option<f64>,
    pub clock_error_max_abs_ns: Option<u64>,
}

/// Streaming DC measurement of an emulated network, for an open-ended run.
#[derive(Debug, Clone)]
pub struct Yardstick {
    opts: YardstickOpts,
    wide: Vec<bool>,
    has_system_time: Vec<bool>,
    reference: Option<usize>,
    matcher: PulseMatcher,
    first_sync0: Option<TrueTime>,
    ever_fired: Vec<bool>,
    lock: LockTracker<TrueTime>,
    next_sample: TrueTime,
    end: Option<TrueTime>,
    block_ns: u64,
    blocks: Vec<Block>,
    sys: Vec<Option<u64>>,
    /// Scratch for the pairs one edge completes (kept to avoid an allocation per edge).
    pairs: Vec<Pair>,
}

impl Yardstick {
    /// A yardstick for the slaves of `net`.
    pub fn new(net: &Network, opts: YardstickOpts) -> Self {
        let has_system_time = (0..net.slave_count())
            .map(|i| net.slave_info(i).is_some_and(|x| x.kind.has_system_time()))
            .collect();
        Self::with_slaves(wide_slaves(net), has_system_time, opts)
    }

    /// A yardstick for slaves described by their width and whether they have a system time.
    pub fn with_slaves(wide: Vec<bool>, has_system_time: Vec<bool>, opts: YardstickOpts) -> Self {
        let n = wide.len();
        let opts = YardstickOpts {
            sample_ns: opts.sample_ns.max(1),
            first_block_ns: opts.first_block_ns.max(1),
            blocks: opts.blocks.max(1),
        };
        Yardstick {
            matcher: PulseMatcher::new(wide.iter().any(|w| !w)),
            wide,
            has_system_time,
            reference: None,
            first_sync0: None,
            ever_fired: vec![false; n],
            lock: LockTracker::default(),
            next_sample: 0,
            end: None,
            block_ns: opts.first_block_ns,
            blocks: Vec::new(),
            sys: vec![None; n],
            pairs: Vec::new(),
            opts,
        }
    }

    /// Fixes the reference instead of choosing it at the first SYNC0 edge.
    pub fn set_reference(&mut self, reference: usize) {
        self.reference = Some(reference);
    }

    /// The reference skews are taken against, once chosen.
    pub fn reference(&self) -> Option<usize> {
        self.reference
    }

    /// Block holding true time `t` of the cyclic phase, merging blocks when the phase outgrows
    /// them.
    fn block(&mut self, t: TrueTime) -> Option<&mut Block> {
        let c = self.first_sync0?;
        let mut k = t.saturating_sub(c) / self.block_ns;
        let cap = self.opts.blocks.saturating_mul(2) as u64;
        while k >= cap {
            let merged: Vec<Block> = self
                .blocks
                .chunks(2)
                .map(|pair| {
                    let mut it = pair.iter();
                    let mut b = it.next().cloned().unwrap_or_else(|| Block::new(0));
                    if let Some(o) = it.next() {
                        b.merge(o);
                    }
                    b
                })
                .collect();
            self.blocks = merged;
            self.block_ns = self.block_ns.saturating_mul(2);
            k = t.saturating_sub(c) / self.block_ns;
        }
        let k = usize::try_from(k).ok()?;
        let n = self.wide.len();
        if self.blocks.len() <= k {
            self.blocks.resize_with(k + 1, || Block::new(n));
        }
        self.blocks.get_mut(k)
    }

    /// Takes SYNC edges (SYNC1 is ignored). `net` chooses the reference at the first SYNC0
    /// edge: the first slave in wire order with a system time and SYNC0 activated in 0x0981
    /// (the default of every master we know: the first DC slave), else the edge's slave.
    pub fn on_edges(&mut self, net: Option<&Network>, edges: &[SyncEdge]) {
        for e in edges {
            if e.signal != SyncSignal::Sync0 {
                continue;
            }
            if self.first_sync0.is_none() {
                self.first_sync0 = Some(e.true_time);
            }
            let reference = match self.reference {
                Some(r) => r,
                None => {
                    let r = net
                        .and_then(|net| {
                            (0..self.wide.len()).find(|&i| {
                                self.has_system_time.get(i).copied().unwrap_or(false)
                                    && sync0_active(net, i)
                            })
                        })
                        .unwrap_or(e.slave);
                    self.reference = Some(r);
                    r
                }
            };
            if let Some(f) = self.ever_fired.get_mut(e.slave) {
                *f = true;
            }
            if let Some(acc) = self
                .block(e.true_time)
                .and_then(|b| b.slaves.get_mut(e.slave))
            {
                acc.sync0_edges = acc.sync0_edges.saturating_add(1);
            }
            let mut pairs = core::mem::take(&mut self.pairs);
            pairs.clear();
            self.matcher
                .push(reference, e.slave, e.system_time, e.true_time, &mut |p| {
                    pairs.push(p)
                });
            for &p in &pairs {
                if let Some(b) = self.block(p.reference_time) {
                    b.skew.record(p.skew_ns);
                    if let Some(acc) = b.slaves.get_mut(p.slave) {
                        acc.skew.record(p.skew_ns);
                    }
                }
            }
            self.pairs = pairs;
            self.end = Some(self.end.map_or(e.true_time, |x| x.max(e.true_time)));
        }
    }

    /// Takes one clock sample at `ts` if a sample is due: lock is judged over the *firing*
    /// slaves (SYNC0 fired at least once and still activated in 0x0981); the clock error of
    /// every slave with a system time goes into the window. Samples start with the first
    /// SYNC0 edge. Moves `net`'s time to `ts`.
    pub fn sample(&mut self, net: &mut Network, ts: TrueTime) -> Result<(), EmuError> {
        if ts < self.next_sample || self.first_sync0.is_none() {
            return Ok(());
        }
        let Some(reference) = self.reference else {
            return Ok(());
        };
        self.next_sample = (ts / self.opts.sample_ns)
            .saturating_add(1)
            .saturating_mul(self.opts.sample_ns);
        let mut sys = core::mem::take(&mut self.sys);
        for (i, v) in sys.iter_mut().enumerate() {
            *v = net.clock(i, ts)?.system_time;
        }
        let errs = clock_errors(&sys, &self.wide, reference);
        self.sys = sys;
        let reference_ok = errs.get(reference).is_some_and(Option::is_some);
        let firing_ok = errs.iter().enumerate().all(|(i, e)| {
            let firing = self.ever_fired.get(i).copied().unwrap_or(false) && sync0_active(net, i);
            !firing || e.is_some_and(|e| e.unsigned_abs() < LOCK_NS)
        });
        self.lock.sample(reference_ok && firing_ok, ts);
        if let Some(b) = self.block(ts) {
            for (acc, e) in b.slaves.iter_mut().zip(&errs) {
                if let Some(e) = e {
                    acc.clock_error.record(*e);
                }
            }
        }
        self.end = Some(self.end.map_or(ts, |x| x.max(ts)));
        Ok(())
    }

    /// Edges, then a clock sample at the latest instant the network can be sampled at.
    pub fn observe(&mut self, net: &mut Network, edges: &[SyncEdge]) -> Result<(), EmuError> {
        self.on_edges(Some(net), edges);
        let ts = net.now().max(max_anchor(net));
        self.sample(net, ts)
    }

    /// The steady-state window `[start, end]`: the last half of the cyclic phase (first SYNC0
    /// edge to the latest observation), its start moved back to the block boundary at or
    /// before the midpoint.
    pub fn window(&self) -> Option<(TrueTime, TrueTime)> {
        let c = self.first_sync0?;
        let end = self.end?;
        let mid = c.saturating_add(end.saturating_sub(c) / 2);
        let k = mid.saturating_sub(c) / self.block_ns;
        Some((c.saturating_add(k.saturating_mul(self.block_ns)), end))
    }

    fn window_blocks(&self) -> &[Block] {
        let Some((start, _)) = self.window() else {
            return &[];
        };
        let c = self.first_sync0.unwrap_or(0);
        let k = usize::try_from(start.saturating_sub(c) / self.block_ns).unwrap_or(usize::MAX);
        self.blocks.get(k..).unwrap_or(&[])
    }

    /// Skew statistics over the window.
    pub fn window_skew(&self) -> SkewStats {
        let mut s = SkewStats::default();
        for b in self.window_blocks() {
            s.merge(&b.skew);
        }
        s
    }

    fn window_slaves(&self) -> Vec<SlaveAcc> {
        let mut acc = vec![SlaveAcc::default(); self.wide.len()];
        for b in self.window_blocks() {
            for (a, s) in acc.iter_mut().zip(&b.slaves) {
                a.skew.merge(&s.skew);
                a.clock_error.merge(&s.clock_error);
                a.sync0_edges = a.sync0_edges.saturating_add(s.sync0_edges);
            }
        }
        acc
    }

    /// True time of the lock sample, if locked.
    pub fn lock_time(&self) -> Option<TrueTime> {
        self.lock.lock()
    }

    /// True time of the first SYNC0 edge.
    pub fn first_sync0(&self) -> Option<TrueTime> {
        self.first_sync0
    }

    /// The `sync` report.
    pub fn report(&self) -> SyncReport {
        let skew = self.window_skew();
        let firing = self
            .window_slaves()
            .iter()
            .filter(|a| a.sync0_edges > 0)
            .count();
        let window = self.window();
        SyncReport {
            slaves_firing: firing,
            pairs: skew.count(),
            skew: skew.summary(),
            lock_ms: self
                .lock
                .lock()
                .zip(self.first_sync0)
                .map(|(l, c)| l.saturating_sub(c) as f64 / 1e6),
            reference: self.reference,
            first_sync0_ns: self.first_sync0,
            window_start_ns: window.map(|w| w.0),
            window_end_ns: window.map(|w| w.1),
        }
    }

    /// The per-slave report, registers read from `net`.
    pub fn slaves(&self, net: &Network) -> Vec<SlaveReport> {
        self.window_slaves()
            .iter()
            .enumerate()
            .map(|(i, a)| {
                let regs = net.esc(i).map(|e| e.regs());
                SlaveReport {
                    position: i,
                    station: regs.map_or(0, |r| r.get_u16(addr::STATION_ADDRESS)),
                    identity: net.identity(i),
                    al_state: al_state_name(regs.map_or(0, |r| r.get_u8(addr::AL_STATUS))),
                    sync0_active: sync0_active(net, i),
                    sync0_edges: a.sync0_edges,
                    reference: self.reference == Some(i),
                    skew_mean_ns: a.skew.mean_abs(),
                    skew_max_ns: a.skew.max_abs(),
                    clock_error_mean_ns: a.clock_error.mean(),
                    clock_error_max_abs_ns: a.clock_error.max_abs(),
                }
            })
            .collect()
    }
}

/// 0x0981 has bit 0 (cyclic operation) and bit 1 (SYNC0) set
/// (docs/background/esc-registers.md §3.6).
pub fn sync0_active(net: &Network, i: usize) -> bool {
    net.esc(i)
        .is_some_and(|e| e.regs().get_u8(addr::SYNC_ACTIVATION) & 0x03 == 0x03)
}

/// Name of an AL status byte (state in bits 0..3, error indication in bit 4;
/// docs/background/esc-registers.md §3.6).
pub fn al_state_name(status: u8) -> String {
    let state = match status & 0x0F {
        1 => "INIT".to_string(),
        2 => "PREOP".to_string(),
        3 => "BOOT".to_string(),
        4 => "SAFEOP".to_string(),
        8 => "OP".to_string(),
        other => format!("0x{other:X}"),
    };
    if status & 0x10 != 0 {
        format!("{state}+ERR")
    } else {
        state
    }
}

#[cfg(test)]
mod tests {
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    use super::*;
    use crate::schemes::measure::{lock_index, window_skews_from};
    use crate::schemes::run::{Edge, Record};

    #[test]
    fn clock_error_is_taken_on_the_narrower_width() {
        assert_eq!(clock_error(5, 7, true), -2);
        assert_eq!(clock_error(1 << 40, 0, true), 1 << 40);
        // A 64-bit slave against a 32-bit reference: only the low halves count.
        assert_eq!(clock_error((7 << 32) | 10, 4, false), 6);
        // Across the 32-bit wrap.
        assert_eq!(clock_error(3, u64::from(u32::MAX) - 2, false), 6);
    }

    #[test]
    fn bins_are_exact_below_4096_and_within_1_128_above() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        for v in (0..5000u64).chain((0..20_000).map(|_| rng.gen::<u64>() >> rng.gen_range(0..60))) {
            let b = bin_of(v);
            let up = bin_upper(b);
            assert!(up >= v, "{v}: bin {b} tops at {up}");
            if v < EXACT_BELOW_NS {
                assert_eq!(up, v);
            } else {
                assert!(up - v <= v / 128, "{v}: bin top {up}");
            }
            assert_eq!(bin_of(up), b, "{v}");
            if let Some(next) = up.checked_add(1) {
                assert_eq!(bin_of(next), b + 1, "{v}: bins must be contiguous");
            }
        }
        assert_eq!(bin_upper(bin_of(u64::MAX)), u64::MAX);
    }

    fn batch(skews: &[i64]) -> (u64, f64, f64, Option<u64>, Option<u64>) {
        let mut abs: Vec<u64> = skews.iter().map(|d| d.unsigned_abs()).collect();
        abs.sort_unstable();
        let n = abs.len() as f64;
        let mean = abs.iter().map(|&x| x as f64).sum::<f64>() / n;
        let signed = skews.iter().map(|&x| x as f64).sum::<f64>() / n;
        (
            abs.len() as u64,
            mean,
            signed,
            percentile(&abs, 99.0),
            abs.last().copied(),
        )
    }

    #[test]
    fn streaming_skew_stats_match_the_sorted_batch() {
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        for spread in [0i64, 3, 40, 4095, 100_000] {
            for n in [1usize, 2, 99, 100, 101, 1000, 7919] {
                let skews: Vec<i64> = (0..n).map(|_| rng.gen_range(-spread..=spread)).collect();
                let mut s = SkewStats::default();
                // Merging halves must give the same as recording everything in one.
                let (a, b) = skews.split_at(n / 2);
                let mut h = SkewStats::default();
                for &d in a {
                    s.record(d);
                }
                for &d in b {
                    h.record(d);
                }
                s.merge(&h);
                let (count, mean, signed, p99, max) = batch(&skews);
                assert_eq!(s.count(), count);
                assert!((s.mean_abs().unwrap() - mean).abs() <= 1e-9 * mean.max(1.0));
                assert!((s.signed_mean().unwrap() - signed).abs() <= 1e-9 * mean.max(1.0));
                assert_eq!(s.max_abs(), max);
                let (got, want) = (s.percentile(99.0).unwrap(), p99.unwrap());
                if want < EXACT_BELOW_NS {
                    assert_eq!(got, want, "spread {spread} n {n}");
                } else {
                    assert!(got >= want && got - want <= want / 128, "{got} vs {want}");
                }
            }
        }
        assert_eq!(SkewStats::default().percentile(99.0), None);
        assert_eq!(SkewStats::default().mean_abs(), None);
    }

    #[test]
    fn lock_tracker_matches_the_batch_lock_index() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for _ in 0..200 {
            let len = rng.gen_range(0..50);
            let track: Vec<(u64, u64, Option<u64>)> = (0..len)
                .map(|k| {
                    let m = match rng.gen_range(0..10) {
                        0 => None,
                        1..=3 => Some(rng.gen_range(LOCK_NS..1000)),
                        _ => Some(rng.gen_range(0..LOCK_NS)),
                    };
                    (k, k, m)
                })
                .collect();
            let want = track
                .iter()
                .rposition(|(_, _, m)| m.is_none_or(|m| m >= LOCK_NS))
                .map_or(0, |b| b + 1);
            let want = (want < track.len()).then_some(want);
            assert_eq!(lock_index(&track), want, "{track:?}");
        }
    }

    /// SYNC0 edges of `n` slaves over `pulses` 1 ms pulses: skews of a few ns, some edges
    /// missing (the reference's too), every k-th pulse with a large outlier.
    fn synthetic_edges(seed: u64, n: usize, pulses: u64, start: u64) -> Vec<SyncEdge> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut out = Vec::new();
        for k in 0..pulses {
            let programmed = 1_000_000_000 + k * 1_000_000;
            let nominal = start + k * 1_000_000;
            for s in 0..n {
                if rng.gen_range(0..50) == 0 {
                    continue;
                }
                let dev: i64 = if k % 97 == 5 && s == n - 1 {
                    rng.gen_range(-9000..9000)
                } else {
                    rng.gen_range(-30..30)
                };
                out.push(SyncEdge {
                    slave: s,
                    signal: SyncSignal::Sync0,
                    true_time: nominal.wrapping_add_signed(dev),
                    system_time: programmed,
                });
                if rng.gen_range(0..4) == 0 {
                    out.push(SyncEdge {
                        slave: s,
                        signal: SyncSignal::Sync1,
                        true_time: nominal + 500_000,
                        system_time: programmed + 500_000,
                    });
                }
            }
        }
        out.sort_by_key(|e| (e.true_time, e.slave));
        out
    }

    fn record_of(edges: &[SyncEdge], n: usize, end: u64) -> Record {
        Record {
            slaves: n,
            reference: 0,
            end,
            sync0: edges
                .iter()
                .filter(|e| e.signal == SyncSignal::Sync0)
                .map(|e| Edge {
                    system_time: e.system_time,
                    slave: e.slave,
                    true_time: e.true_time,
                })
                .collect(),
            ..Record::default()
        }
    }

    #[test]
    fn windowed_yardstick_matches_the_batch_over_the_same_window() {
        let n = 5;
        for (seed, pulses) in [(4u64, 10u64), (5, 31), (6, 64), (7, 3000), (8, 12_345)] {
            let edges = synthetic_edges(seed, n, pulses, 50_000_000);
            let opts = YardstickOpts::default();
            let mut y = Yardstick::with_slaves(vec![true; n], vec![true; n], opts);
            y.set_reference(0);
            // Fed in drains of a few edges, as frames would drain them.
            for chunk in edges.chunks(7) {
                y.on_edges(None, chunk);
            }
            let (start, end) = y.window().unwrap();
            let c = y.first_sync0().unwrap();
            let mid = c + (end - c) / 2;
            assert!(start <= mid, "window starts after the midpoint");
            // The start lies on the block grid at or before the midpoint: at most one block
            // early, and a block is at most 1/(blocks - 1) of the cyclic phase once merged.
            let block = (opts.first_block_ns).max((end - c) / (opts.blocks as u64 - 1));
            assert!(mid - start <= block, "{seed}: start {start} mid {mid}");

            let r = record_of(&edges, n, end);
            let pairs = window_skews_from(&r, Some(start));
            // The pairs themselves, against an independent grouping of the edges by pulse.
            let mut by_pulse: BTreeMap<u64, Vec<(usize, u64)>> = BTreeMap::new();
            for e in &r.sync0 {
                by_pulse
                    .entry(e.system_time)
                    .or_default()
                    .push((e.slave, e.true_time));
            }
            let mut want: Vec<(usize, i64)> = by_pulse
                .values()
                .filter_map(|v| Some((v, v.iter().find(|x| x.0 == 0)?.1)))
                .filter(|(_, tref)| *tref >= start && *tref <= end)
                .flat_map(|(v, tref)| {
                    v.iter()
                        .filter(|x| x.0 != 0)
                        .map(move |&(s, t)| (s, t as i64 - tref as i64))
                })
                .collect();
            let mut got = pairs.clone();
            want.sort_unstable();
            got.sort_unstable();
            assert_eq!(got, want, "seed {seed}");
            let skews: Vec<i64> = pairs.iter().map(|p| p.1).collect();
            let w = y.window_skew();
            let (count, mean, signed, p99, max) = batch(&skews);
            assert_eq!(w.count(), count, "seed {seed}");
            assert!(count > 0);
            assert!((w.mean_abs().unwrap() - mean).abs() < 1e-9 * mean.max(1.0));
            assert!((w.signed_mean().unwrap() - signed).abs() < 1e-9 * mean.max(1.0));
            assert_eq!(w.max_abs(), max);
            assert_eq!(w.percentile(99.0), p99);
            // Per slave, the same pairs.
            let rep = y.report();
            assert_eq!(rep.pairs, count);
            assert_eq!(rep.slaves_firing, n);
            let per = y.window_slaves();
            for (s, acc) in per.iter().enumerate().skip(1) {
                let mine: Vec<i64> = pairs.iter().filter(|p| p.0 == s).map(|p| p.1).collect();
                assert_eq!(acc.skew.count(), mine.len() as u64);
                assert_eq!(
                    acc.skew.max_abs(),
                    mine.iter().map(|d| d.unsigned_abs()).max()
                );
            }
        }
    }

    #[test]
    fn memory_stays_bounded_over_a_long_run() {
        let n = 3;
        let mut y = Yardstick::with_slaves(vec![true; n], vec![true; n], YardstickOpts::default());
        y.set_reference(0);
        // 2^20 pulses at 1 ms: 17 minutes of edges.
        for k in 0..(1u64 << 20) {
            let edges: Vec<SyncEdge> = (0..n)
                .map(|s| SyncEdge {
                    slave: s,
                    signal: SyncSignal::Sync0,
                    true_time: k * 1_000_000 + s as u64,
                    system_time: k * 1_000_000,
                })
                .collect();
            y.on_edges(None, &edges);
            assert!(y.blocks.len() <= 2 * y.opts.blocks);
            assert!(y.matcher.pending.len() <= PulseMatcher::PENDING);
        }
        let w = y.window_skew();
        assert_eq!(w.max_abs(), Some(2));
        assert!(w.count() >= (1 << 20) - 2);
    }

    #[test]
    fn a_pulse_the_reference_never_fires_gives_no_pair() {
        let mut m = PulseMatcher::new(false);
        let mut pairs = Vec::new();
        m.push(0, 1, 10, 100, &mut |p| pairs.push(p));
        m.push(0, 2, 20, 200, &mut |p| pairs.push(p));
        m.push(0, 0, 20, 190, &mut |p| pairs.push(p));
        m.push(0, 1, 20, 205, &mut |p| pairs.push(p));
        assert_eq!(
            pairs,
            vec![
                Pair {
                    slave: 2,
                    reference_time: 190,
                    skew_ns: 10
                },
                Pair {
                    slave: 1,
                    reference_time: 190,
                    skew_ns: 15
                },
            ]
        );
        // 32-bit slaves: the high half of the programmed time is ignored.
        let mut m = PulseMatcher::new(true);
        let mut pairs = Vec::new();
        m.push(0, 0, (5 << 32) | 7, 1000, &mut |p| pairs.push(p));
        m.push(0, 1, 7, 990, &mut |p| pairs.push(p));
        assert_eq!(
            pairs,
            vec![Pair {
                slave: 1,
                reference_time: 1000,
                skew_ns: -10
            }]
        );
    }

    #[test]
    fn al_state_names() {
        assert_eq!(al_state_name(0x01), "INIT");
        assert_eq!(al_state_name(0x08), "OP");
        assert_eq!(al_state_name(0x14), "SAFEOP+ERR");
        assert_eq!(al_state_name(0x00), "0x0");
    }
}
