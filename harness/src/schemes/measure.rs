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

use std::collections::BTreeMap;

use super::run::Record;

/// Lock threshold on the true clock error, ns.
pub const LOCK_NS: u64 = 100;

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
    pub skew_mean_ns: Option<f64>,
    pub skew_p99_ns: Option<u64>,
    pub skew_max_ns: Option<u64>,
    /// Signed mean of the skew (a constant bias shows here).
    pub skew_signed_mean_ns: Option<f64>,
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

/// Nearest-rank percentile of sorted values (`p` in 0..=100).
pub fn percentile(sorted: &[u64], p: f64) -> Option<u64> {
    if sorted.is_empty() {
        return None;
    }
    let rank = ((p / 100.0) * sorted.len() as f64).ceil() as usize;
    sorted.get(rank.clamp(1, sorted.len()) - 1).copied()
}

/// Lock sample index: first index after the last sample that was not within `LOCK_NS`.
pub fn lock_index(track: &[(u64, u64, Option<u64>)]) -> Option<usize> {
    let last_bad = track
        .iter()
        .rposition(|(_, _, m)| m.is_none_or(|m| m >= LOCK_NS));
    let idx = last_bad.map_or(0, |b| b + 1);
    (idx < track.len()).then_some(idx)
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

/// Every (slave, signed skew in ns) pair of the steady-state window, in pulse order (the pairs
/// the skew statistics are computed over).
pub fn window_skews(r: &Record) -> Vec<(usize, i64)> {
    let win_start = window_start(r);
    let in_win = |t: u64| win_start.is_some_and(|w| t >= w && t <= r.end);
    // With 32-bit slaves a pulse is identified by the low 32 bits of its programmed time
    // (unique for 2^32 / gcd(cycle, 2^32) cycles: 67 s at 1 ms).
    let key_mask = if r.has_32bit {
        u64::from(u32::MAX)
    } else {
        u64::MAX
    };
    let mut pulses: BTreeMap<u64, Vec<(usize, u64)>> = BTreeMap::new();
    for e in &r.sync0 {
        pulses
            .entry(e.system_time & key_mask)
            .or_default()
            .push((e.slave, e.true_time));
    }
    let mut out = Vec::new();
    for edges in pulses.values() {
        let Some(&(_, tref)) = edges.iter().find(|(s, _)| *s == r.reference) else {
            continue;
        };
        if !in_win(tref) {
            continue;
        }
        for &(s, t) in edges {
            if s == r.reference {
                continue;
            }
            out.push((s, t as i64 - tref as i64));
        }
    }
    out
}

/// Computes the summary of a record.
pub fn summarize(r: &Record) -> Summary {
    let cyclic_start = r.sync0.iter().map(|e| e.true_time).min();
    let win_start = window_start(r);
    let in_win = |t: u64| win_start.is_some_and(|w| t >= w && t <= r.end);

    // Skew per pulse.
    let mut all: Vec<u64> = Vec::new();
    let mut signed_sum = 0f64;
    let mut per_slave: Vec<Vec<u64>> = vec![Vec::new(); r.slaves];
    for (s, d) in window_skews(r) {
        signed_sum += d as f64;
        all.push(d.unsigned_abs());
        if let Some(v) = per_slave.get_mut(s) {
            v.push(d.unsigned_abs());
        }
    }
    let skew_mean = mean(all.iter().map(|&x| x as f64));
    let skew_signed = (!all.is_empty()).then(|| signed_sum / all.len() as f64);
    all.sort_unstable();

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
            let sk = per_slave.get(i).cloned().unwrap_or_default();
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
                skew_mean_ns: mean(sk.iter().map(|&x| x as f64)),
                skew_max_ns: sk.iter().copied().max(),
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
        skew_samples: all.len(),
        skew_mean_ns: skew_mean,
        skew_p99_ns: percentile(&all, 99.0),
        skew_max_ns: all.last().copied(),
        skew_signed_mean_ns: skew_signed,
        slaves,
        t_diff_ns: None,
    }
}
