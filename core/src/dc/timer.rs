//! The machine's deadlines in one table: each [`Timer`] is armed at a master time or stopped,
//! `Machine::poll_timeout` is the earliest armed one, and `Machine::handle_timeout` acts on
//! those that expired. (quinn-proto keeps a connection's timers the same way.)
//!
//! The table holds deadlines that make the machine act when they pass. The pause before the
//! last FRMW of a drift burst (REQ-DC-104) is not one of them: it only holds a transmission
//! back, so it is a send gate (`Machine::pace_until`), which `poll_timeout` also reports while
//! nothing is in flight.
//!
//! Times are [`SystemTime`]s compared on the wrapping circle (REQ-TIME-004), never with `<`
//! on raw integers: a deadline is expired when it is not after `now`.

use crate::time::SystemTime;

/// One deadline of the machine.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(crate) enum Timer {
    /// The replies to the frame in flight are due (`Config::response_timeout_ns`, in `Cyclic`
    /// at most one cycle). Armed exactly while a frame is awaited.
    Reply,
    /// The pause before the next re-initialisation ends (REQ-DC-130). Armed exactly in
    /// `RestartWait`.
    Restart,
    /// The next cyclic frame is due (`MonitorConfig::cycle_ns`). Armed exactly in `Cyclic`,
    /// first at the instant the bring-up ends (a fixed instant such as the epoch would be
    /// "after now" on the wrapping circle for half of all clock readings).
    Cycle,
}

impl Timer {
    const ALL: [Timer; 3] = [Timer::Reply, Timer::Restart, Timer::Cycle];

    const fn slot(self) -> usize {
        match self {
            Timer::Reply => 0,
            Timer::Restart => 1,
            Timer::Cycle => 2,
        }
    }
}

/// Each timer's deadline, if armed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(crate) struct TimerTable {
    at: [Option<SystemTime>; 3],
}

impl TimerTable {
    /// Nothing armed.
    pub(crate) const fn new() -> Self {
        TimerTable { at: [None; 3] }
    }

    /// Arms `t` at `at` (re-arms it if it was armed).
    pub(crate) fn set(&mut self, t: Timer, at: SystemTime) {
        if let Some(slot) = self.at.get_mut(t.slot()) {
            *slot = Some(at);
        }
    }

    /// Stops `t` (a no-op if it was not armed).
    pub(crate) fn stop(&mut self, t: Timer) {
        if let Some(slot) = self.at.get_mut(t.slot()) {
            *slot = None;
        }
    }

    /// The deadline of `t`, if armed.
    pub(crate) fn get(&self, t: Timer) -> Option<SystemTime> {
        self.at.get(t.slot()).copied().flatten()
    }

    /// Whether `t` is armed.
    pub(crate) fn is_set(&self, t: Timer) -> bool {
        self.get(t).is_some()
    }

    /// Whether `t` is armed and its deadline is not after `now`.
    pub(crate) fn expired(&self, t: Timer, now: SystemTime) -> bool {
        self.get(t).is_some_and(|at| !at.is_after(now))
    }

    /// The earliest armed deadline.
    pub(crate) fn next(&self) -> Option<SystemTime> {
        Timer::ALL
            .iter()
            .filter_map(|t| self.get(*t))
            .reduce(earliest)
    }
}

/// The earlier of two times on the wrapping circle.
pub(crate) fn earliest(a: SystemTime, b: SystemTime) -> SystemTime {
    if a.is_after(b) {
        b
    } else {
        a
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn next_is_the_earliest_armed_deadline() {
        let mut t = TimerTable::new();
        assert_eq!(t.next(), None);
        t.set(Timer::Cycle, SystemTime(300));
        t.set(Timer::Reply, SystemTime(200));
        assert_eq!(t.next(), Some(SystemTime(200)));
        t.stop(Timer::Reply);
        assert_eq!(t.next(), Some(SystemTime(300)));
        assert!(!t.is_set(Timer::Reply) && t.is_set(Timer::Cycle));
        // Across the wrap of the 64-bit circle: u64::MAX is before 5.
        t.set(Timer::Restart, SystemTime(u64::MAX));
        t.set(Timer::Cycle, SystemTime(5));
        assert_eq!(t.next(), Some(SystemTime(u64::MAX)));
    }

    #[test]
    fn a_deadline_expires_at_its_time_not_before() {
        let mut t = TimerTable::new();
        assert!(!t.expired(Timer::Reply, SystemTime(0)));
        t.set(Timer::Reply, SystemTime(1_000));
        assert!(!t.expired(Timer::Reply, SystemTime(999)));
        assert!(t.expired(Timer::Reply, SystemTime(1_000)));
        assert!(t.expired(Timer::Reply, SystemTime(5_000)));
        t.set(Timer::Reply, SystemTime(u64::MAX));
        assert!(
            t.expired(Timer::Reply, SystemTime(3)),
            "3 is after u64::MAX on the circle"
        );
    }
}
