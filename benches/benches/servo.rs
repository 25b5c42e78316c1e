//! One servo update: the per-cycle cost of the master-follows-reference loop (engine + fold +
//! carry) and of the bare PI kernel, in the tracking state with gate armed (the common path).
//!
//! Times are this thread's CPU time (`common::ThreadCpu`: the machine is shared).

use criterion::{black_box, criterion_group, criterion_main, Criterion};

mod common;
use common::ThreadCpu;
use ecdc_core::servo::gains::{PiGains, Pole};
use ecdc_core::servo::master::{MasterConfig, MasterInput, MasterServo};
use ecdc_core::servo::pi::{pi_step, PiLimits};

fn bench_servo(c: &mut Criterion<ThreadCpu>) {
    let period = 1_000_000u64;
    let mut m = MasterServo::new(MasterConfig::for_period(1_000_000).expect("valid period"))
        .expect("valid config");
    // Warm up into Tracking with a full gate window.
    let (mut app, mut local) = (1u64 << 45, 0u64);
    for k in 0..200u64 {
        let _ = m.update(MasterInput::Sample {
            local_ns: local,
            app_ns: app,
            ref_ns: app.wrapping_sub(k % 7),
        });
        app = app.wrapping_add(period);
        local = local.wrapping_add(period);
    }
    c.bench_function("servo/master_update_tracking", |b| {
        b.iter(|| {
            app = app.wrapping_add(period);
            local = local.wrapping_add(period);
            black_box(m.update(black_box(MasterInput::Sample {
                local_ns: local,
                app_ns: app,
                ref_ns: app.wrapping_sub(3),
            })))
        })
    });
    let g = PiGains::double_pole(Pole::from_micro(990_000).expect("pole")).expect("gains");
    let lim = PiLimits::from_ns(1000, 1000).expect("limits");
    let mut i = 0i64;
    c.bench_function("servo/pi_step", |b| {
        b.iter(|| {
            let s = pi_step(g, lim, i, black_box(123));
            i = s.integrator;
            black_box(s)
        })
    });
}

criterion_group! {
    name = benches;
    config = common::criterion();
    targets = bench_servo
}
criterion_main!(benches);
