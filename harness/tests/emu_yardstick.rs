//! The DC yardstick of `ecdc emulate` watching a master in simulated time: on the same run it
//! must agree with `ecdc simulate`'s measurement (same pulses, same skews, same lock rule),
//! whoever the master is. Masters: ecdc's machine, the seed 000 reproduction, and the
//! uncompensated baseline that never locks.

use ecdc_harness::emu::yardstick::{Yardstick, YardstickOpts};
use ecdc_harness::emu::{Network, Scenario};
use ecdc_harness::schemes::ecdc::{self, Ecdc};
use ecdc_harness::schemes::measure::{lock_index, summarize, window_skews_from};
use ecdc_harness::schemes::run::{run_scheme_observed, RunOpts};
use ecdc_harness::schemes::seed000::Seed000;
use ecdc_harness::schemes::Scheme;

const CYCLE: u32 = 1_000_000;

fn opts(duration_ms: u64) -> RunOpts {
    RunOpts {
        duration_ns: duration_ms * 1_000_000,
        sample_ns: u64::from(CYCLE) / 10,
        cycle_ns: u64::from(CYCLE),
    }
}

/// Runs `s` with a yardstick watching the same network; returns what both measured.
fn watch(s: &mut dyn Scheme, run: RunOpts) -> (Yardstick, ecdc_harness::schemes::run::Record) {
    let mut y = Yardstick::new(
        s.net(),
        YardstickOpts {
            sample_ns: run.sample_ns,
            ..YardstickOpts::default()
        },
    );
    let rec = run_scheme_observed(s, run, &mut |_| {}, &mut |net, edges| {
        y.observe(net, edges).map_err(|e| anyhow::anyhow!("{e}"))
    })
    .expect("run");
    assert!(rec.error.is_none(), "{}: {:?}", rec.name, rec.error);
    (y, rec)
}

/// |skew| of every pair simulate's grouping gives over the yardstick's window, sorted.
fn sorted_window_skews(y: &Yardstick, rec: &ecdc_harness::schemes::run::Record) -> Vec<u64> {
    let (start, _) = y.window().expect("window");
    let mut sorted: Vec<u64> = window_skews_from(rec, Some(start))
        .iter()
        .map(|p| p.1.unsigned_abs())
        .collect();
    sorted.sort_unstable();
    sorted
}

fn agree(s: &mut dyn Scheme, run: RunOpts) {
    let n = s.net().slave_count();
    let (y, rec) = watch(s, run);
    let sum = summarize(&rec);
    let rep = y.report();
    let name = rec.name;
    eprintln!("{name}: yardstick {rep:?}");
    eprintln!(
        "{name}: simulate lock_ms {:?} skew mean {:?} p99 {:?} max {:?} pairs {} window {:?}..{}",
        sum.lock_ms,
        sum.skew.mean_ns,
        sum.skew.p99_ns,
        sum.skew.max_ns,
        sum.skew_samples,
        sum.window_start_ns,
        sum.window_end_ns
    );

    // The reference it chose (first DC slave with SYNC0 on) is the master's.
    assert_eq!(y.reference(), Some(rec.reference), "{name}");
    assert_eq!(y.first_sync0(), sum.cyclic_start_ns, "{name}");
    assert_eq!(rep.slaves_firing, n, "{name}");

    // Same pairs over the same window: identical statistics.
    let (start, end) = y.window().expect("window");
    assert_eq!(end, rec.end, "{name}");
    let exact_start = sum.window_start_ns.expect("simulate window");
    assert!(start <= exact_start, "{name}");
    let c = sum.cyclic_start_ns.expect("first SYNC0");
    assert!(
        exact_start - start <= (end - c) / 15,
        "{name}: window start {start} vs {exact_start}"
    );
    let skews: Vec<u64> = window_skews_from(&rec, Some(start))
        .iter()
        .map(|p| p.1.unsigned_abs())
        .collect();
    let mut sorted = skews.clone();
    sorted.sort_unstable();
    assert_eq!(rep.pairs, skews.len() as u64, "{name}");
    assert_eq!(rep.skew.max_ns, sorted.last().copied(), "{name}");
    assert_eq!(
        rep.skew.p99_ns,
        ecdc_harness::emu::yardstick::percentile(&sorted, 99.0),
        "{name}"
    );
    let mean = skews.iter().sum::<u64>() as f64 / skews.len() as f64;
    assert!(
        (rep.skew.mean_ns.expect("mean") - mean).abs() < 1e-9,
        "{name}"
    );
    // Against simulate's own (exact last-half) window: the same steady state.
    let d_mean = (rep.skew.mean_ns.unwrap() - sum.skew.mean_ns.unwrap()).abs();
    assert!(d_mean <= 0.5, "{name}: mean differs by {d_mean}");
    assert!(rep.skew.max_ns >= sum.skew.max_ns, "{name}");
    let d_p99 = rep.skew.p99_ns.unwrap().abs_diff(sum.skew.p99_ns.unwrap());
    assert!(d_p99 <= 2, "{name}: p99 differs by {d_p99}");

    // Lock: simulate's rule over the same samples, timed from the first SYNC0 edge. Before
    // SYNC0 fires no slave is firing, so a master that locks earlier is locked at the first
    // sample after the first edge.
    let lock_sim = lock_index(&rec.track)
        .map(|i| rec.track[i].0)
        .expect("simulate lock");
    let lock_y = y.lock_time().expect("yardstick lock");
    if lock_sim > c {
        assert_eq!(lock_y, lock_sim, "{name}");
    } else {
        assert!(
            lock_y >= c && lock_y <= c + run.sample_ns,
            "{name}: {lock_y} vs {c}"
        );
    }
    let lock_ms = rep.lock_ms.expect("lock_ms");
    assert!((lock_ms - (lock_y - c) as f64 / 1e6).abs() < 1e-9, "{name}");

    // Per slave: the clock error over the window agrees with simulate's per-cycle samples.
    let slaves = y.slaves(s.net());
    assert_eq!(slaves.len(), n);
    for (row, mine) in sum.slaves.iter().zip(&slaves) {
        assert!(mine.sync0_active, "{name}: slave {}", mine.position);
        assert!(mine.sync0_edges > 0, "{name}: slave {}", mine.position);
        assert_eq!(mine.reference, row.reference);
        let (a, b) = (
            mine.clock_error_mean_ns.expect("error mean"),
            row.clock_error_mean_ns.expect("sim error mean"),
        );
        assert!(
            (a - b).abs() <= 2.0,
            "{name}: slave {}: {a} vs {b}",
            row.slave
        );
        let (a, b) = (
            mine.clock_error_max_abs_ns.expect("error max"),
            row.clock_error_max_abs_ns.expect("sim error max"),
        );
        assert!(
            a >= b && a <= b + 30,
            "{name}: slave {}: {a} vs {b}",
            row.slave
        );
        // The station address the master configured is reported.
        assert_ne!(mine.station, 0, "{name}: slave {}", row.slave);
        // The identity is the one the slave's SII image holds.
        let id = mine.identity.as_ref().expect("identity from the SII image");
        assert_eq!(
            Some(id),
            s.net().identity(mine.position).as_ref(),
            "{name}: slave {}",
            row.slave
        );
    }
}

#[test]
fn yardstick_agrees_with_simulate_on_ecdc() {
    let sc = Scenario::seed000_line();
    let net = Network::new(&sc).unwrap();
    let mut s = Ecdc::new(net, ecdc::config(10, CYCLE)).unwrap();
    agree(&mut s, opts(2000));
}

#[test]
fn yardstick_agrees_with_simulate_on_the_seed000_master() {
    let sc = Scenario::seed000_line();
    let net = Network::new(&sc).unwrap();
    let mut s = Seed000::new(net, 10, CYCLE);
    agree(&mut s, opts(2000));
}

/// A master that never distributes time: clocks drift apart, neither measurement locks, and
/// the microsecond skews go through the histogram's log bins (p99 within 1/128).
#[test]
fn yardstick_agrees_with_simulate_on_a_master_that_never_locks() {
    let sc = Scenario::seed000_line();
    let net = Network::new(&sc).unwrap();
    let mut s = ecdc_harness::schemes::uncompensated::Uncompensated::new(net, CYCLE);
    let n = s.net().slave_count();
    let (y, rec) = watch(&mut s, opts(1500));
    let sum = summarize(&rec);
    let rep = y.report();
    assert_eq!(rep.slaves_firing, n);
    assert_eq!(sum.lock_ms, None);
    assert_eq!(rep.lock_ms, None);
    assert_eq!(y.lock_time(), None);
    let sorted = sorted_window_skews(&y, &rec);
    let exact = ecdc_harness::emu::yardstick::percentile(&sorted, 99.0).unwrap();
    let p99 = rep.skew.p99_ns.unwrap();
    assert!(
        exact > 4096,
        "the skews should be microseconds, p99 {exact}"
    );
    assert!(
        p99 >= exact && p99 - exact <= exact / 128,
        "{p99} vs {exact}"
    );
    assert_eq!(rep.skew.max_ns, sorted.last().copied());
    assert_eq!(rep.pairs, sorted.len() as u64);
}

/// A tree with a 32-bit DC slave, a slave without DC and one with receive times only: pulses
/// are matched on the low 32 bits, only the slaves with a system time fire, and the yardstick
/// still measures exactly the pairs simulate's grouping gives over its window.
#[test]
fn yardstick_on_a_mixed_tree_counts_only_the_slaves_that_fire() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/scenarios/tree_mixed.toml");
    let sc = Scenario::load(path.as_ref()).unwrap();
    let net = Network::new(&sc).unwrap();
    let with_system_time = (0..net.slave_count())
        .filter(|&i| net.slave_info(i).unwrap().kind.has_system_time())
        .count();
    let mut s = Ecdc::new(net, ecdc::config(0, CYCLE)).unwrap();
    let (y, rec) = watch(&mut s, opts(3000));
    assert!(rec.has_32bit);
    let rep = y.report();
    eprintln!("tree_mixed: yardstick {rep:?}");
    let fired: std::collections::BTreeSet<usize> = rec.sync0.iter().map(|e| e.slave).collect();
    assert_eq!(rep.slaves_firing, fired.len());
    assert_eq!(rep.slaves_firing, with_system_time);
    let sorted = sorted_window_skews(&y, &rec);
    assert!(!sorted.is_empty());
    assert_eq!(rep.pairs, sorted.len() as u64);
    assert_eq!(rep.skew.max_ns, sorted.last().copied());
    assert_eq!(
        rep.skew.p99_ns,
        ecdc_harness::emu::yardstick::percentile(&sorted, 99.0)
    );
    let slaves = y.slaves(s.net());
    for (i, sl) in slaves.iter().enumerate() {
        assert_eq!(sl.sync0_edges > 0, fired.contains(&i), "slave {i}");
    }
}
