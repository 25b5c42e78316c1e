//! Shared by the criterion benches of this crate: a measurement of this thread's CPU time.
//!
//! The benches run on a shared 2-core machine where other builds and tests compete for the
//! cores; wall-clock samples then include time-slices given to other processes. Thread CPU
//! time (`CLOCK_THREAD_CPUTIME_ID`) counts only the time this thread ran. Criterion reads it
//! once before and once after each sample's batch of iterations, so the clock call's own cost
//! (a system call, ~0.1-0.5 µs) is spread over the batch. Values are nanoseconds and are
//! printed as times.

#![allow(dead_code)]

use criterion::measurement::{Measurement, ValueFormatter, WallTime};
use criterion::Criterion;

pub use ecdc_benches::timed::thread_cpu_ns;

/// Criterion measurement: thread CPU time in ns.
pub struct ThreadCpu;

static WALL: WallTime = WallTime;

impl Measurement for ThreadCpu {
    type Intermediate = u64;
    type Value = u64;

    fn start(&self) -> u64 {
        thread_cpu_ns()
    }
    fn end(&self, i: u64) -> u64 {
        thread_cpu_ns().saturating_sub(i)
    }
    fn add(&self, a: &u64, b: &u64) -> u64 {
        a + b
    }
    fn zero(&self) -> u64 {
        0
    }
    fn to_f64(&self, v: &u64) -> f64 {
        *v as f64
    }
    fn formatter(&self) -> &dyn ValueFormatter {
        WALL.formatter()
    }
}

/// Criterion configured with [`ThreadCpu`].
pub fn criterion() -> Criterion<ThreadCpu> {
    Criterion::default().with_measurement(ThreadCpu)
}
