//! Lock and loss of lock with hysteresis on the BRD 0x092C bound (REQ-DC-106): locked after
//! `lock_cycles` cycles in a row with the bound ≤ `lock_ns`, unlocked after `unlock_cycles` in
//! a row above `unlock_ns`; "not locked" is due once per unlocked run, after
//! `lock_timeout_cycles` cycles.

use crate::dc::config::MonitorConfig;

/// The lock state of cyclic operation and its streaks; its `Default` is unlocked, nothing
/// counted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub(crate) struct LockHysteresis {
    pub(crate) locked: bool,
    /// Cycles in a row with the bound ≤ `lock_ns`.
    good_streak: u16,
    /// Cycles in a row with the bound > `unlock_ns`.
    bad_streak: u16,
    /// "Not locked" was reported in this unlocked run.
    not_locked_reported: bool,
}

/// A change of the lock state.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum LockChange {
    Locked,
    Lost,
}

impl LockHysteresis {
    /// Counts one cycle's bound into the streaks; the change it makes, if any.
    pub(crate) fn judge(&mut self, bound_ns: u32, m: &MonitorConfig) -> Option<LockChange> {
        self.good_streak = if bound_ns <= m.lock_ns {
            self.good_streak.saturating_add(1)
        } else {
            0
        };
        self.bad_streak = if bound_ns > m.unlock_ns {
            self.bad_streak.saturating_add(1)
        } else {
            0
        };
        if !self.locked && self.good_streak >= m.lock_cycles {
            self.locked = true;
            Some(LockChange::Locked)
        } else if self.locked && self.bad_streak >= m.unlock_cycles {
            self.locked = false;
            self.not_locked_reported = false;
            Some(LockChange::Lost)
        } else {
            None
        }
    }

    /// Whether "not locked" is due now, after `cycles` cycles unlocked against a limit of
    /// `timeout`; true once per unlocked run.
    pub(crate) fn not_locked_due(&mut self, cycles: u32, timeout: u32) -> bool {
        let due = !self.locked && !self.not_locked_reported && cycles >= timeout;
        if due {
            self.not_locked_reported = true;
        }
        due
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Ten good cycles lock (the tenth), three bad ones unlock (the third); a bound between the
    /// two thresholds breaks both streaks.
    #[test]
    fn hysteresis() {
        let m = MonitorConfig::DEFAULT;
        let mut h = LockHysteresis::default();
        for _ in 0..9 {
            assert_eq!(h.judge(m.lock_ns, &m), None);
        }
        assert_eq!(h.judge(500, &m), None, "between the thresholds");
        for _ in 0..9 {
            assert_eq!(h.judge(0, &m), None);
        }
        assert_eq!(h.judge(0, &m), Some(LockChange::Locked));
        assert_eq!(h.judge(0, &m), None);
        let bad = m.unlock_ns + 1;
        assert_eq!((h.judge(bad, &m), h.judge(bad, &m)), (None, None));
        assert_eq!(
            h.judge(m.unlock_ns, &m),
            None,
            "at the threshold is not bad"
        );
        assert_eq!((h.judge(bad, &m), h.judge(bad, &m)), (None, None));
        assert_eq!(h.judge(bad, &m), Some(LockChange::Lost));
        assert!(!h.locked);
    }

    /// "Not locked" is due once at the timeout, again only after a lock was lost, never while
    /// locked.
    #[test]
    fn not_locked_once_per_unlocked_run() {
        let m = MonitorConfig::DEFAULT;
        let mut h = LockHysteresis::default();
        assert!(!h.not_locked_due(99, 100));
        assert!(h.not_locked_due(100, 100));
        assert!(!h.not_locked_due(101, 100));
        h.locked = true;
        h.not_locked_reported = false;
        assert!(!h.not_locked_due(200, 100));
        for _ in 0..m.unlock_cycles {
            h.judge(u32::MAX, &m);
        }
        assert!(!h.locked);
        assert!(h.not_locked_due(100, 100));
    }
}
