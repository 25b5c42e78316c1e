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

/// Seconds from the Unix epoch (1970) to the EtherCAT epoch 2000-01-01 00:00 UTC.
pub const UNIX_TO_ECAT_EPOCH_S: u64 = 946_684_800;

/// The master's clock in the DC epoch: host `CLOCK_MONOTONIC` plus a fixed offset taken once
/// from `CLOCK_REALTIME`, so slaves get a wall-clock-meaningful system time at bring-up, while
/// the runtime never sees the wall clock jump (NTP steps do not move a monotonic base).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DcClock {
    offset_ns: u64,
}

impl DcClock {
    /// Anchors the DC epoch to the current wall clock.
    pub fn from_realtime() -> Self {
        let wall = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| u64::try_from(d.as_nanos()).unwrap_or(u64::MAX))
            .unwrap_or(0);
        let dc_wall = wall.saturating_sub(UNIX_TO_ECAT_EPOCH_S * NS_PER_S);
        DcClock {
            offset_ns: dc_wall.saturating_sub(now_ns()),
        }
    }

    /// A clock with a given offset (tests).
    pub const fn with_offset(offset_ns: u64) -> Self {
        DcClock { offset_ns }
    }

    /// DC time (ns since 2000-01-01) of a monotonic instant.
    pub fn at(&self, mono_ns: u64) -> u64 {
        mono_ns.saturating_add(self.offset_ns)
    }

    /// DC time now.
    pub fn now(&self) -> u64 {
        self.at(now_ns())
    }

    /// Monotonic instant of a DC time.
    pub fn to_mono(&self, dc_ns: u64) -> u64 {
        dc_ns.saturating_sub(self.offset_ns)
    }
}
