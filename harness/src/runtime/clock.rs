//! Host monotonic time in nanoseconds, and absolute-deadline sleeping.
//!
//! WHY raw nanoseconds rather than `std::time::Instant`: the DC core takes time as plain
//! integers (no clock reads in `core`), the emulator uses the same clock as "true time", and
//! `clock_nanosleep(TIMER_ABSTIME)` wants an absolute `CLOCK_MONOTONIC` value. Sleeping to an
//! absolute deadline means a late wake-up never shifts later cycles (no accumulated drift).

use std::sync::atomic::AtomicBool;

use super::sys;

/// Nanoseconds per second.
pub const NS_PER_S: u64 = 1_000_000_000;

/// Current `CLOCK_MONOTONIC` time in ns.
#[inline]
pub fn now_ns() -> u64 {
    sys::monotonic_ns()
}

/// Sleeps until the absolute monotonic time `deadline_ns`, then returns the wake-up time.
/// With `spin_ns > 0` it sleeps until `deadline - spin_ns` and busy-waits the rest, trading a
/// CPU for lower wake-up lateness. Returns `None` if `stop` was raised by a signal meanwhile.
pub fn sleep_until(deadline_ns: u64, spin_ns: u64, stop: &AtomicBool) -> Option<u64> {
    let coarse = deadline_ns.saturating_sub(spin_ns);
    if now_ns() < coarse && !sys::sleep_until(coarse, stop) {
        return None;
    }
    let mut now = now_ns();
    while now < deadline_ns {
        std::hint::spin_loop();
        now = now_ns();
    }
    Some(now)
}
