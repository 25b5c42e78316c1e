//! Profiling driver for the per-cycle DC path (callgrind, perf): brings 64 slaves up on the
//! emulator, captures the cyclic ring, then replays `CYCLES` cycles (default 100 000; first
//! argument overrides), with the master servo step when the second argument is `servo`.
//!
//! Instructions per cycle (what benches/results/criterion.md quotes): the difference of two
//! runs, which cancels the bring-up and the capture:
//!
//! ```sh
//! cargo build --release -p ecdc-benches --bin cycle_profile
//! valgrind --tool=callgrind --callgrind-out-file=c0.out target/release/cycle_profile 0
//! valgrind --tool=callgrind --callgrind-out-file=c1.out target/release/cycle_profile 50000
//! # (I refs of c1 - I refs of c0) / 50000; callgrind_annotate --inclusive=yes on both for
//! # the per-function split
//! ```

use ecdc_benches::cyclic::{fixture, Replay, Shape, CYCLE_NS};
use ecdc_core::servo::master::{MasterConfig, MasterInput, MasterServo};

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let cycles: u64 = args.next().map_or(Ok(100_000), |a| a.parse())?;
    let with_servo = args.next().is_some_and(|a| a == "servo");
    let (cap, _) = fixture::<64>(Shape::Line, 64)?;
    let mut r = Replay::new(&cap);
    let mut servo = MasterServo::new(
        MasterConfig::for_period(CYCLE_NS as u32).map_err(|e| anyhow::anyhow!("{e:?}"))?,
    )
    .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let started = std::time::Instant::now();
    let mut acc = 0i64;
    for _ in 0..cycles {
        let now = r.now();
        let t = r.cycle();
        if with_servo {
            let out = servo.update(t.map_or(MasterInput::Lost, |t| MasterInput::Sample {
                local_ns: now,
                app_ns: now,
                ref_ns: t.0,
            }));
            acc = acc.wrapping_add(out.deadline_correction_ns);
        }
    }
    let el = started.elapsed();
    anyhow::ensure!(r.healthy(), "replay left the locked path");
    println!(
        "{cycles} cycles in {:.3} s: {:.1} ns/cycle (acc {acc})",
        el.as_secs_f64(),
        el.as_nanos() as f64 / cycles as f64
    );
    Ok(())
}
