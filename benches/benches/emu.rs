//! Emulator speed: a line of 100 (and of 6) slaves, one cyclic frame per 1 ms (FRMW 0x0910 +
//! LRW 200 bytes + BRD AL status), SYNC0 active on every slave with a 1 ms cycle, PHY jitter and
//! wander on. The target is ≥ 50× real time for 100 slaves (REQ-ESC-101; docs/emulator.md
//! §Speed); the 6-slave figure is the emulator's share of a default `ecdc simulate` run.
//!
//! Reading the output: criterion's benchmarks `emu_100_slaves_1khz/100ms_simulated` and
//! `emu_6_slaves_1khz/100ms_simulated` declare their throughput in simulated nanoseconds, so
//! `thrpt` in Gelem/s *is* the simulated/real-time ratio (50 Gelem/s = 50×). Before them, three
//! one-off runs of 1 s simulated per size print the ratio against wall time and against this
//! thread's CPU time (the CPU figure is the one that holds on a loaded machine).
//!
//! verifies: REQ-ESC-101

use criterion::{criterion_group, criterion_main, BatchSize, Criterion, Throughput};
use ecdc_benches::timed::thread_cpu_ns;
use ecdc_core::wire::{Address, Command, FrameBuilder};
use ecdc_harness::emu::{Network, Scenario, SlaveSpec};
use std::hint::black_box;
use std::time::Instant;

/// Line lengths measured: REQ-ESC-101's 100, and `ecdc simulate`'s default 6. The environment
/// variable `EMU_BENCH_SLAVES` (e.g. `100`) restricts the run to one size, which is how the
/// callgrind figure in docs/emulator.md is taken.
const SIZES: [usize; 2] = [100, 6];

fn sizes() -> Vec<usize> {
    match std::env::var("EMU_BENCH_SLAVES") {
        Ok(v) => v.split(',').filter_map(|x| x.trim().parse().ok()).collect(),
        Err(_) => SIZES.to_vec(),
    }
}
const CYCLE_NS: u64 = 1_000_000;

fn frame(dgs: &[(Command, Address, &[u8])]) -> Vec<u8> {
    let mut buf = vec![0u8; 1514];
    let mut b = FrameBuilder::new(&mut buf).expect("buffer");
    for (i, (c, a, d)) in dgs.iter().enumerate() {
        b.push(*c, i as u8, *a, d).expect("fits");
    }
    let n = b.finish().expect("finish");
    buf.truncate(n);
    buf
}

/// A line of `slaves`, addressed, SYNC0 running at 1 ms from t = 1 ms.
fn setup(slaves: usize) -> (Network, u64) {
    let mut sc = Scenario::default();
    sc.timing.power_on_spread_ns = 0;
    for i in 0..slaves {
        sc = sc.with_slave(SlaveSpec {
            station: 0x1000 + i as u16,
            ..SlaveSpec::default()
        });
    }
    let mut net = Network::new(&sc).expect("scenario");
    let mut t = 0;
    for (ado, data) in [
        (0x09A0u16, CYCLE_NS.to_le_bytes()[..4].to_vec()),
        (0x0990, 1_000_000u64.to_le_bytes().to_vec()),
        (0x0981, vec![0x03]),
        (0x0930, vec![0x00, 0x10]),
    ] {
        let f = frame(&[(Command::Bwr, Address::broadcast(ado), &data)]);
        let r = net
            .transact(&f, t)
            .expect("time")
            .returned()
            .expect("returned");
        t = r.arrival + 1_000;
    }
    (net, t)
}

/// `cycles` cyclic frames, one per ms; returns the time after the last.
fn run(net: &mut Network, mut t: u64, cycles: u64) -> u64 {
    let f = frame(&[
        (Command::Frmw, Address::configured(0x1000, 0x0910), &[0; 8]),
        (Command::Lrw, Address::Logical(0x10000), &[0; 200]),
        (Command::Brd, Address::broadcast(0x0130), &[0; 2]),
    ]);
    for _ in 0..cycles {
        let d = net.transact(&f, t).expect("time");
        black_box(d);
        t += CYCLE_NS;
    }
    net.advance_to(t).expect("time");
    black_box(net.take_sync_edges());
    t
}

fn bench(c: &mut Criterion) {
    let sizes = sizes();
    for &slaves in &sizes {
        // One-off: 1 s of true time (SYNC edges drained every 100 ms), three runs.
        for _ in 0..3 {
            let (mut net, t0) = setup(slaves);
            let cpu0 = thread_cpu_ns();
            let start = Instant::now();
            let mut t1 = t0;
            for _ in 0..10 {
                t1 = run(&mut net, t1, 100);
            }
            let wall = start.elapsed().as_nanos() as f64;
            let cpu = (thread_cpu_ns() - cpu0) as f64;
            let sim = (t1 - t0) as f64;
            eprintln!(
                "emu: {slaves} slaves @ 1 kHz: {:.3} s simulated in {:.1} ms wall = {:.0}x real \
                 time; {:.1} ms thread CPU = {:.0}x real time",
                sim / 1e9,
                wall / 1e6,
                sim / wall,
                cpu / 1e6,
                sim / cpu
            );
        }
    }
    for &slaves in &sizes {
        let mut g = c.benchmark_group(format!("emu_{slaves}_slaves_1khz"));
        // Elements = simulated ns: thrpt in Gelem/s reads directly as the real-time ratio.
        g.throughput(Throughput::Elements(100 * CYCLE_NS));
        g.bench_function("100ms_simulated", |b| {
            b.iter_batched(
                || setup(slaves),
                // The network is returned so that criterion drops it outside the timing: the
                // figure is simulation throughput, not tear-down.
                |(mut net, t)| {
                    run(&mut net, t, 100);
                    net
                },
                BatchSize::LargeInput,
            )
        });
        g.finish();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
