//! Per-cycle DC cost of the core, for 1, 16, 64 and 256 slaves (emulated line, seed 0).
//!
//! Setup (not timed): the machine is brought up on the emulator until `Locked`, then one period
//! of its cyclic frame pattern is captured with the emulator's real responses
//! (`ecdc_benches::cyclic`). Timed, per iteration = one 1 ms cycle:
//! - `dc/cycle/N`: `poll_transmit` (FRMW 0x0910 + BRD 0x092C + BRD 0x0130 + up to 8 round-robin
//!   FPRD 0x092C, into an Ethernet frame) + `handle_frame` on the response (validate, match every
//!   datagram by index/command/register/station/length, extract the reference time, the bound,
//!   per-slave Δt, WKC/topology checks, lock hysteresis) + draining `poll_event`;
//! - `dc/cycle_servo/N`: the same plus the master-follows-reference servo step on the
//!   extracted reference time (`MasterServo::update`), i.e. the whole per-cycle DC cost;
//! - `dc/replay_overhead`: the bench's own work per iteration (moving the canned FRMW
//!   reference time forward), to subtract.
//!
//! After timing, each case checks the machine is still locked with no lost cycle and no
//! unmatched datagram, so the replay exercised the normal path throughout.
//!
//! Times are this thread's CPU time (`common::ThreadCpu`: the machine is shared).

use criterion::{black_box, criterion_group, criterion_main, Criterion};

mod common;
use common::ThreadCpu;
use ecdc_benches::cyclic::{fixture, Capture, MasterLoop, Replay, Shape};

fn bench_case<const N: usize>(c: &mut Criterion<ThreadCpu>, n: usize) {
    let (cap, _): (Capture<N>, _) = fixture::<N>(Shape::Line, n).expect("bring-up and capture");
    let frame_len = cap.request.len();
    let mut g = c.benchmark_group("dc");
    let mut r = Replay::new(&cap);
    g.bench_function(format!("cycle/{n}"), |b| b.iter(|| black_box(r.cycle())));
    assert!(r.healthy(), "{n} slaves: replay left the locked path");

    let mut r = Replay::new(&cap);
    let mut s = MasterLoop::new(cap.cycle_ns).expect("servo");
    // Warm the servo up into tracking and lock (gear change after 32 good cycles).
    for _ in 0..5000 {
        let now = r.now();
        let t = r.cycle();
        s.step(now, t);
    }
    assert!(
        s.servo.is_locked(),
        "{n} slaves: master servo did not lock on the replay"
    );
    g.bench_function(format!("cycle_servo/{n}"), |b| {
        b.iter(|| {
            let now = r.now();
            let t = r.cycle();
            black_box(s.step(now, t))
        })
    });
    assert!(r.healthy(), "{n} slaves: replay left the locked path");
    assert!(s.servo.is_locked(), "{n} slaves: master servo lost lock");
    if n == 64 {
        let mut r = Replay::new(&cap);
        g.bench_function("replay_overhead", |b| b.iter(|| black_box(r.prepare())));
    }
    g.finish();
    eprintln!(
        "dc/{n}: cyclic request {frame_len} bytes, ring of {} captured cycles",
        cap.ring.len()
    );
}

fn bench_dc(c: &mut Criterion<ThreadCpu>) {
    bench_case::<1>(c, 1);
    bench_case::<16>(c, 16);
    bench_case::<64>(c, 64);
    bench_case::<256>(c, 256);
}

criterion_group! {
    name = benches;
    config = common::criterion();
    targets = bench_dc
}
criterion_main!(benches);
