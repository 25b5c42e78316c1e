//! Issue #15 regression guard (not timing-based): a `Machine<1024>` replays a whole recorded
//! bring-up to lock and the cyclic cycles up to it on a thread whose stack is what an idle
//! thread needs plus 64 KiB; if the core's stack need regresses, the thread overflows its stack
//! and the test process dies. `benches/src/bin/stack.rs` measures the actual need.
//!
//! Also: a machine that went through that bring-up and is then `configure`d in place is the
//! machine `Machine::new` returns.

use ecdc_benches::cyclic::{self, config_with_cycle, Shape};
use ecdc_benches::timed::{self, CallLog};
use ecdc_core::dc::Machine;

const N: usize = 1024;

/// What an idle thread needs on this platform, rounded up (the stack bench measured 27 KiB on
/// x86_64 Linux with glibc).
const IDLE_THREAD: usize = 32 * 1024;

/// The budget of issue #15.
const BUDGET: usize = 64 * 1024;

#[test]
fn bring_up_of_1024_slaves_fits_64_kib_of_stack() {
    // Recording the run (with the emulator) and comparing machines by value need a large stack:
    // that thread's use is not what is guarded.
    let big = std::thread::Builder::new()
        .stack_size(256 * 1024 * 1024)
        .spawn(|| {
            let sc = cyclic::scenario(Shape::Line, N, 0);
            let cfg = config_with_cycle(&sc, 2_000_000);
            let fresh: Box<Machine<N>> = Box::new(Machine::new(cfg).unwrap());
            let mut log = CallLog::default();
            let outcome =
                timed::try_bring_up(&sc, (*fresh).clone(), 300_000_000_000, Some(&mut log))
                    .unwrap();
            let Ok((locked, _, b)) = outcome else {
                panic!("{N} slaves did not lock");
            };
            let mut locked = Box::new(locked);
            locked.configure(cfg).unwrap();
            assert_eq!(
                format!("{locked:?}"),
                format!("{fresh:?}"),
                "configure after a bring-up gives the machine of new"
            );
            (fresh, log, b.frames_sent)
        })
        .unwrap();
    let (fresh, log, frames) = big.join().unwrap();
    // Unoptimised test builds have much larger frames: the budget holds for optimised ones.
    let stack = if cfg!(debug_assertions) {
        4 * 1024 * 1024
    } else {
        IDLE_THREAD + BUDGET
    };
    let small = std::thread::Builder::new()
        .stack_size(stack)
        .spawn(move || timed::replay_boxed(fresh, &log).2)
        .unwrap();
    assert_eq!(
        small.join().unwrap(),
        frames,
        "the replay sent what the run sent"
    );
}
