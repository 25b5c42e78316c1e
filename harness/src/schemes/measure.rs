//! From a [`Record`] to the reported numbers. Definitions (also in docs/simulate.md):
//!
//! - **cyclic phase**: from the first SYNC0 edge of any slave to the end of the run;
//!   **steady-state window**: its last half.
//! - **skew**: for every SYNC0 pulse (identified by its programmed system time) whose reference
//!   edge lies in the window, and every other slave that fired that pulse: the slave's edge
//!   true time minus the reference's. Statistics over all (slave, pulse) pairs: mean |skew|,
//!   p99 |skew| (nearest rank), max |skew|.
//! - **lock**: the first lock-detection sample from which on *every* sample until the end of
//!   the run has every slave within 100 ns (true time) of the reference; `lock_frames` are
//!   the reference-time frames sent up to that sample, `lock_ms` its true time since the
//!   master started.
//! - per slave, over the cycle samples inside the window: 0x092C mean/max/min and the signed
//!   mean (and max |·|) of the true clock error.
//!
//! Pulse matching, the skew statistics and the lock rule are [`crate::emu::yardstick`]'s, the
//! same code `ecdc emulate` measures any master with; this module applies them to a finished
//! run, whose end (and so the exact window) is known.

use super::run::Record;
use crate::emu::yardstick::{LockTracker, Moments, PulseMatcher, SkewStats};

pub use crate::emu::yardstick::{percentile, SkewSummary, LOCK_NS};

/// One row of the per-slave table (seed 000 Table 2 layout, one row per slave here).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct SlaveRow {
    /// 1-based position as in seed 000 (slave 1 = the first slave).
    pub slave: usize,
    /// Whether this slave is the reference clock.
    pub reference: bool,
    /// 0x0920 written (signed), ns.
    pub offset_ns: Option<i64>,
    /// 0x0928 written, ns.
    pub delay_ns: Option<u32>,
    /// Signed 0x092C in the window: mean, max, min (ns); `None` when the scheme never
    /// distributes the reference time (the register is never updated).
    pub drift_mean_ns: Option<f64>,
    pub drift_max_ns: Option<i32>,
    pub drift_min_ns: Option<i32>,
    /// True clock error (slave − reference) in the window: signed mean and max |·|, ns.
    pub clock_error_mean_ns: Option<f64>,
    pub clock_error_max_abs_ns: Option<u64>,
    /// This slave's SYNC0 skew in the window: mean |·| and max |·|, ns.
    pub skew_mean_ns: Option<f64>,
    pub skew_max_ns: Option<u64>,
}

/// The numbers of one scheme.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Summary {
    pub name: String,
    /// What the scheme was told beyond what it measured (`{}` = nothing), e.g. `t_diff_ns`.
    pub given: super::Given,
    /// Why the scheme stopped early, if it did.
    pub error: Option<String>,
    pub lock_frames: Option<u64>,
    pub lock_ms: Option<f64>,
    /// Frames of the static drift compensation (burst), as the scheme reports it.
    pub static_drift_frames: Option<u64>,
    /// Reference-time frames over the whole run.
    pub dist_frames: u64,
    pub cyclic_start_ns: Option<u64>,
    pub window_start_ns: Option<u64>,
    pub window_end_ns: u64,
    pub skew_samples: usize,
    #[serde(flatten)]
    pub skew: SkewSummary,
    pub slaves: Vec<SlaveRow>,
    /// Per slave, the t_DIFF the scheme used against the emulator's truth (schemes that
    /// determine it themselves; set by the caller, `None` otherwise).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub t_diff_ns: Option<Vec<TdiffRow>>,
}

/// One slave's t_DIFF in a report: what the scheme used, the truth, and where the value came
/// from.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct TdiffRow {
    /// Slave number as in the per-slave tables (1 = first slave).
    pub slave: usize,
    /// The value the scheme used, ns.
    pub measured: i64,
    /// t_P − t_F of the emulated ESC, ns.
    #[serde(rename = "true")]
    pub truth: i64,
    /// `measured`, `same-type (slave k)`, `configured`, `fallback (…)` or `default`.
    pub source: String,
}

/// Lock sample index: first index after the last sample that was not within `LOCK_NS`.
pub fn lock_index(track: &[(u64, u64, Option<u64>)]) -> Option<usize> {
    let mut lock = LockTracker::default();
    for (i, (_, _, m)) in track.iter().enumerate() {
        lock.sample(m.is_some_and(|m| m < LOCK_NS), i);
    }
    lock.lock()
}

fn mean(v: impl Iterator<Item = f64>) -> Option<f64> {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x, n + 1));
    (n > 0).then(|| s / n as f64)
}

/// Start of the steady-state window (last half of the cyclic phase), if SYNC0 ever fired.
pub fn window_start(r: &Record) -> Option<u64> {
    let cyclic_start = r.sync0.iter().map(|e| e.true_time).min();
    cyclic_start.map(|c| c + (r.end.saturating_sub(c)) / 2)
}

/// Every (slave, signed skew in ns) pair of the steady-state window, in the order the pairs
/// complete (the pairs the skew statistics are computed over).
pub fn window_skews(r: &Record) -> Vec<(usize, i64)> {
    window_skews_from(r, window_start(r))
}

/// The skew pairs whose reference edge lies in `[win_start, end]` (none without a start).
pub fn window_skews_from(r: &Record, win_start: Option<u64>) -> Vec<(usize, i64)> {
    let in_win = |t: u64| win_start.is_some_and(|w| t >= w && t <= r.end);
    let mut matcher = PulseMatcher::new(r.has_32bit);
    let mut out = Vec::new();
    for e in &r.sync0 {
        matcher.push(r.reference, e.slave, e.system_time, e.true_time, &mut |p| {
            if in_win(p.reference_time) {
                out.push((p.slave, p.skew_ns));
            }
        });
    }
    out
}

/// Computes the summary of a record.
pub fn summarize(r: &Record) -> Summary {
    let cyclic_start = r.sync0.iter().map(|e| e.true_time).min();
    let win_start = window_start(r);
    let in_win = |t: u64| win_start.is_some_and(|w| t >= w && t <= r.end);

    // Skew per pulse.
    let mut all = SkewStats::default();
    let mut per_slave = vec![Moments::default(); r.slaves];
    for (s, d) in window_skews(r) {
        all.record(d);
        if let Some(v) = per_slave.get_mut(s) {
            v.record(d);
        }
    }

    let lock = lock_index(&r.track).and_then(|i| r.track.get(i));
    let distributes = r.dist_frames > 0;
    let slaves = (0..r.slaves)
        .map(|i| {
            let w = r.written.get(i).copied().unwrap_or_default();
            let win = |k: &usize| r.cyc_t.get(*k).is_some_and(|&t| in_win(t));
            let idx: Vec<usize> = (0..r.cyc_t.len()).filter(win).collect();
            let diffs: Vec<i32> = if distributes && i != r.reference {
                idx.iter()
                    .filter_map(|&k| r.cyc_diff.get(i).and_then(|v| v.get(k)).copied().flatten())
                    .collect()
            } else {
                Vec::new()
            };
            let errs: Vec<i64> = idx
                .iter()
                .filter_map(|&k| r.cyc_err.get(i).and_then(|v| v.get(k)).copied().flatten())
                .collect();
            let sk = per_slave.get(i).copied().unwrap_or_default();
            SlaveRow {
                slave: i + 1,
                reference: i == r.reference,
                offset_ns: w.offset,
                delay_ns: w.delay,
                drift_mean_ns: mean(diffs.iter().map(|&d| f64::from(d))),
                drift_max_ns: diffs.iter().copied().max(),
                drift_min_ns: diffs.iter().copied().min(),
                clock_error_mean_ns: mean(errs.iter().map(|&e| e as f64)),
                clock_error_max_abs_ns: errs.iter().map(|e| e.unsigned_abs()).max(),
                skew_mean_ns: sk.mean_abs(),
                skew_max_ns: sk.max_abs(),
            }
        })
        .collect();
    Summary {
        name: r.name.to_string(),
        given: r.given.clone(),
        error: r.error.clone(),
        lock_frames: lock.map(|l| l.1),
        lock_ms: lock.map(|l| l.0 as f64 / 1e6),
        static_drift_frames: r.static_drift_frames,
        dist_frames: r.dist_frames,
        cyclic_start_ns: cyclic_start,
        window_start_ns: win_start,
        window_end_ns: r.end,
        skew_samples: usize::try_from(all.count()).unwrap_or(usize::MAX),
        skew: all.summary(),
        slaves,
        t_diff_ns: None,
    }
}
