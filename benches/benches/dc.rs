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

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use ecdc_benches::cyclic::{fixture, Capture, Replay, Shape, CYCLE_NS};
use ecdc_core::servo::master::{MasterConfig, MasterInput, MasterServo};

fn servo() -> MasterServo {
    MasterServo::new(MasterConfig::for_period(CYCLE_NS as u32).expect("period"))
        .expect("servo config")
}

/// The master side of the loop, closed through the replay: the cycles are replayed on the 1 ms
/// grid, and a wake-up `shift` (the sum of the servo's deadline corrections) is added to the
/// reference time the machine returned, which is what waking `shift` ns later would read.
struct Master {
    servo: MasterServo,
    shift: i64,
    app_base: i64,
}

impl Master {
    fn new() -> Self {
        Master {
            servo: servo(),
            shift: 0,
            app_base: 0,
        }
    }

    #[inline]
    fn step(&mut self, now: u64, reference: Option<u64>) -> i64 {
        let input = match reference {
            Some(r) => MasterInput::Sample {
                local_ns: now.wrapping_add_signed(self.shift),
                app_ns: now.wrapping_add_signed(self.app_base),
                ref_ns: r.wrapping_add_signed(self.shift),
            },
            None => MasterInput::Lost,
        };
        let out = self.servo.update(input);
        self.shift = self.shift.wrapping_add(out.deadline_correction_ns);
        self.app_base = self.app_base.wrapping_add(out.app_time_step_ns);
        out.phase_error_ns
    }
}

fn bench_case<const N: usize>(c: &mut Criterion, n: usize) {
    let (cap, _): (Capture<N>, _) = fixture::<N>(Shape::Line, n).expect("bring-up and capture");
    let frame_len = cap.request.len();
    let mut g = c.benchmark_group("dc");
    let mut r = Replay::new(&cap);
    g.bench_function(format!("cycle/{n}"), |b| b.iter(|| black_box(r.cycle())));
    assert!(r.healthy(), "{n} slaves: replay left the locked path");

    let mut r = Replay::new(&cap);
    let mut s = Master::new();
    // Warm the servo up into tracking and lock (gear change after 32 good cycles).
    for _ in 0..5000 {
        let now = r.now();
        let t = r.cycle().map(|t| t.0);
        s.step(now, t);
    }
    assert!(
        s.servo.is_locked(),
        "{n} slaves: master servo did not lock on the replay"
    );
    g.bench_function(format!("cycle_servo/{n}"), |b| {
        b.iter(|| {
            let now = r.now();
            let t = r.cycle().map(|t| t.0);
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

fn bench_dc(c: &mut Criterion) {
    bench_case::<1>(c, 1);
    bench_case::<16>(c, 16);
    bench_case::<64>(c, 64);
    bench_case::<256>(c, 256);
}

criterion_group!(benches, bench_dc);
criterion_main!(benches);
