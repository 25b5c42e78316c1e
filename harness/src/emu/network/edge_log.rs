//! The SYNC edge log: each slave logs its SYNC0/SYNC1 edges in true-time order; the network
//! hands them out merged in (true time, slave, log position) order, by a radix sort for many
//! records and a bottom-up merge of the per-slave runs for few.

use super::Network;
use crate::emu::esc::SyncEdge;

/// Initial capacity of each slave's SYNC edge log (a 1 kHz SYNC0 drained every 100 ms
/// needs ≈ 100); reserved up front so a fresh network does not grow 100 logs step by step.
pub(super) const EDGE_LOG_CAPACITY: usize = 128;

/// Below this many due edges `take_sync_edges` merges instead of radix-sorting.
const RADIX_MIN: usize = 4096;

/// Takes the first `due[s]` records of every log `s` (each sorted by true time) into one
/// vector sorted stably by true time — ties in slave order, then log order — by an LSD radix
/// sort (11-bit digits, stable) of keys that hold the true time relative to the earliest in
/// the upper 32 bits and (slave, position) in the lower 32, then a gather straight from the
/// logs (no concatenated copy, no scratch records). The taken records are drained. Returns
/// `None` (touching nothing) if the times span 2^32 ns or more, or a slave index or a due
/// count does not fit 16 bits.
fn radix_take(
    logs: &mut [Vec<SyncEdge>],
    due: &[usize],
    total: usize,
    keys: &mut Vec<u64>,
    keys2: &mut Vec<u64>,
) -> Option<Vec<SyncEdge>> {
    const DIGIT: u32 = 11;
    const BUCKETS: usize = 1 << DIGIT;
    if logs.len() > 1 << 16 || due.iter().any(|&n| n > 1 << 16) {
        return None;
    }
    let (mut lo, mut hi) = (u64::MAX, 0);
    for (log, &n) in logs.iter().zip(due) {
        if let (Some(a), Some(b)) = (log.first(), log[..n].last()) {
            lo = lo.min(a.true_time);
            hi = hi.max(b.true_time);
        }
    }
    if total == 0 {
        return Some(Vec::new());
    }
    let span = u32::try_from(hi - lo).ok()?;
    keys.clear();
    for (s, (log, &n)) in logs.iter().zip(due).enumerate() {
        let tag = (s as u64) << 16;
        keys.extend(
            log[..n]
                .iter()
                .enumerate()
                .map(|(i, e)| ((e.true_time - lo) << 32) | tag | i as u64),
        );
    }
    let passes = (u32::BITS - span.leading_zeros()).div_ceil(DIGIT);
    keys2.clear();
    keys2.resize(total, 0);
    for p in 0..passes {
        let shift = 32 + p * DIGIT;
        let digit = |k: u64| ((k >> shift) as usize) & (BUCKETS - 1);
        let mut count = [0u32; BUCKETS];
        for &k in keys.iter() {
            count[digit(k)] += 1;
        }
        let mut sum = 0;
        for c in count.iter_mut() {
            let x = *c;
            *c = sum;
            sum += x;
        }
        for &k in keys.iter() {
            let d = digit(k);
            keys2[count[d] as usize] = k;
            count[d] += 1;
        }
        core::mem::swap(keys, keys2);
    }
    let mut out = Vec::with_capacity(total);
    out.extend(
        keys.iter()
            .map(|k| logs[((k >> 16) & 0xFFFF) as usize][(k & 0xFFFF) as usize]),
    );
    // Drain in place so each log keeps its capacity for the next interval.
    for (log, &n) in logs.iter_mut().zip(due) {
        log.drain(..n);
    }
    Some(out)
}

/// Stably merges the sorted runs `buf[bounds[i]..bounds[i + 1]]` (by true time; the earlier
/// run wins ties) into one sorted run, pairwise and bottom-up, ping-ponging with `scratch`.
fn merge_runs(buf: &mut Vec<SyncEdge>, scratch: &mut Vec<SyncEdge>, bounds: &mut Vec<usize>) {
    while bounds.len() > 2 {
        scratch.clear();
        scratch.reserve(buf.len());
        let runs = bounds.len() - 1;
        let mut w = 1;
        let mut i = 0;
        while i < runs {
            let lo = bounds[i];
            let mid = bounds[i + 1];
            if i + 1 < runs {
                let hi = bounds[i + 2];
                let (a, b) = (&buf[lo..mid], &buf[mid..hi]);
                let (mut x, mut y) = (0, 0);
                while x < a.len() && y < b.len() {
                    if b[y].true_time < a[x].true_time {
                        scratch.push(b[y]);
                        y += 1;
                    } else {
                        scratch.push(a[x]);
                        x += 1;
                    }
                }
                scratch.extend_from_slice(&a[x..]);
                scratch.extend_from_slice(&b[y..]);
            } else {
                scratch.extend_from_slice(&buf[lo..mid]);
            }
            bounds[w] = scratch.len();
            w += 1;
            i += 2;
        }
        bounds.truncate(w);
        core::mem::swap(buf, scratch);
    }
}

impl Network {
    /// All SYNC edges up to now, sorted by true time (then slave), removed from the log.
    pub fn take_sync_edges(&mut self) -> Vec<SyncEdge> {
        let now = self.now;
        // Each slave's log is put in (true time, signal) order — it almost always is already:
        // output jitter only reorders SYNC0/SYNC1 of one slave by a few ns. The due prefixes
        // are taken in (true time, slave, log position) order by a radix sort or a merge of
        // the per-slave runs: the same order as sorting everything by (true time, slave,
        // signal, log position).
        let mut due = core::mem::take(&mut self.due);
        due.clear();
        let mut total = 0;
        for (e, log) in self.escs.iter_mut().zip(self.edges.iter_mut()) {
            if e.anchor() <= now {
                e.advance_to(now, log);
            }
            let key = |x: &SyncEdge| (x.true_time, x.signal as u8);
            if !log.windows(2).all(|w| key(&w[0]) <= key(&w[1])) {
                log.sort_by_key(key);
            }
            let n = log.partition_point(|x| x.true_time <= now);
            due.push(n);
            total += n;
        }
        if total >= RADIX_MIN {
            let (k1, k2) = &mut self.sort_keys;
            if let Some(out) = radix_take(&mut self.edges, &due, total, k1, k2) {
                self.due = due;
                return out;
            }
        }
        // Few records (merging beats clearing the radix sort's bucket counts) or a wide span.
        let mut out = Vec::with_capacity(total);
        let mut bounds = core::mem::take(&mut self.bounds);
        bounds.clear();
        bounds.push(0);
        // Drain in place so each log keeps its capacity for the next interval.
        for (log, n) in self.edges.iter_mut().zip(&due) {
            if *n > 0 {
                out.extend(log.drain(..*n));
                bounds.push(out.len());
            }
        }
        let mut scratch = core::mem::take(&mut self.edge_scratch);
        merge_runs(&mut out, &mut scratch, &mut bounds);
        self.edge_scratch = scratch;
        self.bounds = bounds;
        self.due = due;
        out
    }
}

#[cfg(test)]
mod test {
    use super::*;
    use crate::emu::SyncSignal;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Random per-slave logs (sorted by time, with ties inside and across slaves), as
    /// `take_sync_edges` concatenates them, and their run bounds.
    fn logs(seed: u64, slaves: usize, span: u64) -> (Vec<SyncEdge>, Vec<usize>) {
        let mut r = ChaCha8Rng::seed_from_u64(seed);
        let mut out = Vec::new();
        let mut bounds = vec![0];
        for s in 0..slaves {
            let mut t = r.gen_range(0..span.min(1000) + 1);
            for k in 0..r.gen_range(0..40) {
                t += r.gen_range(0..=span / 20);
                out.push(SyncEdge {
                    slave: s,
                    signal: if k % 3 == 0 {
                        SyncSignal::Sync1
                    } else {
                        SyncSignal::Sync0
                    },
                    true_time: t,
                    system_time: r.gen(),
                });
            }
            if out.len() > *bounds.last().unwrap() {
                bounds.push(out.len());
            }
        }
        (out, bounds)
    }

    /// Both orderings of `take_sync_edges` equal a stable sort by true time of the
    /// slave-major concatenation; the radix path declines spans of 2^32 ns or more and
    /// leaves each log's not-due tail in place.
    #[test]
    fn edge_sorts_match_stable_sort() {
        for seed in 0..300 {
            let span = match seed % 3 {
                0 => 50,
                1 => 200_000_000,
                _ => 1 << 34,
            };
            let (buf, bounds) = logs(seed, 1 + seed as usize % 37, span);
            let mut want = buf.clone();
            want.sort_by_key(|e| e.true_time);
            // Per-slave logs with one record after the due prefix each.
            let mut per: Vec<Vec<SyncEdge>> = bounds
                .windows(2)
                .map(|w| buf[w[0]..w[1]].to_vec())
                .collect();
            let due: Vec<usize> = per.iter().map(Vec::len).collect();
            let tail = |s: usize| SyncEdge {
                slave: s,
                signal: SyncSignal::Sync0,
                true_time: u64::MAX - s as u64,
                system_time: 0,
            };
            for (s, log) in per.iter_mut().enumerate() {
                log.push(tail(s));
            }
            let (mut k1, mut k2) = (Vec::new(), Vec::new());
            let hi = buf.iter().map(|e| e.true_time).max().unwrap_or(0);
            let lo = buf.iter().map(|e| e.true_time).min().unwrap_or(0);
            let fits = hi - lo < 1 << 32;
            let got = radix_take(&mut per, &due, buf.len(), &mut k1, &mut k2);
            assert_eq!(got.is_some(), fits, "seed {seed}");
            if let Some(got) = got {
                assert_eq!(got, want, "radix, seed {seed}");
                for (s, log) in per.iter().enumerate() {
                    assert_eq!(log, &vec![tail(s)], "drained, seed {seed}");
                }
            } else {
                assert_eq!(
                    per.iter().map(Vec::len).sum::<usize>(),
                    buf.len() + per.len()
                );
            }
            let mut b = buf.clone();
            let mut bo = bounds.clone();
            let mut scratch = Vec::new();
            merge_runs(&mut b, &mut scratch, &mut bo);
            assert_eq!(b, want, "merge, seed {seed}");
        }
    }
}
