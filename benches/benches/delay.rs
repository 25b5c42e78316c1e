//! Propagation-delay computation for 64-, 256- and 1024-slave trees (REQ-DC-012..018).
//!
//! Input: the samples a master reads after one latch round (DL status, ESC features, the four
//! port receive times and the EPU time per slave), produced by the spec crate's network model
//! for a junction-backbone tree (`ecdc_benches::trees`: every 8th slave a 4-port junction,
//! branches of 7). Timed:
//! - `delay/topology/N`: `Topology::<N>::build` (tree reconstruction from DL status + latches);
//! - `delay/compute/N`: `delay::compute` on that topology (per-slave delays to the reference);
//! - `delay/total/N`: both, what the machine does once per latch round.
//!
//! Before timing, every computed delay is checked against the model's true one (within the
//! 10 ns latch quantisation), so the bench measures the real computation on a valid tree.
//!
//! Times are this thread's CPU time (`common::ThreadCpu`: the machine is shared).
//!
//! verifies: REQ-DC-012, REQ-DC-013, REQ-DC-014, REQ-DC-015, REQ-DC-016, REQ-DC-017, REQ-DC-018

use criterion::{black_box, criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};

mod common;
use common::ThreadCpu;
use ecdc_benches::trees::{junction_tree, samples};
use ecdc_core::dc::delay;
use ecdc_core::dc::topology::Topology;

fn bench_tree<const N: usize>(c: &mut Criterion<ThreadCpu>) {
    let net = junction_tree(N, 7);
    let s = samples(&net);
    assert_eq!(s.len(), N);
    let latch = net.latch().expect("tree");
    let topo = Topology::<N>::build(&s).expect("topology");
    let d = delay::compute(&s, &topo, 0).expect("delays");
    for i in 0..N {
        let got = d.ns(i).expect("latched") as i128;
        let want = latch.delay(0, i);
        assert!(
            (got - want).abs() <= 20,
            "slave {i}: computed {got} ns, model {want} ns"
        );
    }

    let mut g = c.benchmark_group("delay");
    g.throughput(Throughput::Elements(N as u64));
    g.bench_with_input(BenchmarkId::new("topology", N), &s, |b, s| {
        b.iter(|| black_box(Topology::<N>::build(black_box(s))))
    });
    g.bench_with_input(BenchmarkId::new("compute", N), &s, |b, s| {
        b.iter(|| black_box(delay::compute(black_box(s), &topo, 0)))
    });
    g.bench_with_input(BenchmarkId::new("total", N), &s, |b, s| {
        b.iter(|| {
            let t = Topology::<N>::build(black_box(s)).expect("topology");
            black_box(delay::compute(s, &t, 0))
        })
    });
    g.finish();
}

fn bench_delay(c: &mut Criterion<ThreadCpu>) {
    bench_tree::<64>(c);
    bench_tree::<256>(c);
    bench_tree::<1024>(c);
}

criterion_group! {
    name = benches;
    config = common::criterion();
    targets = bench_delay
}
criterion_main!(benches);
