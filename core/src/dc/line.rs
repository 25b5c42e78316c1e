//! [`Line`]: what the machine knows of the line of slaves, shared by every phase of the
//! bring-up and of cyclic operation: the slave table, the reference clock, the running domain
//! the line joins, and the SYNC start the slaves were programmed with.
//!
//! Discovery fills the table and picks the reference; each later phase adds its results to the
//! slaves' entries (delays, offsets, t_Diff). A new bring-up (`CountSlaves`) forgets all of it
//! ([`Line::forget_found`]) except the per-slave t_Diff overrides, which are configuration and
//! go only with [`crate::dc::Machine::configure`].

use crate::dc::slave::SlaveInfo;
use crate::time::SystemTime;

/// The slave table and the facts of the line every phase reads.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub(crate) struct Line<const N: usize> {
    /// By auto-increment position; the first `count` entries are the slaves found.
    pub(crate) slaves: [SlaveInfo; N],
    /// Slaves found (BRD working counter), ≤ N.
    pub(crate) count: u16,
    /// Position of the reference clock (first slave with a system time).
    pub(crate) reference: u16,
    /// Slaves with a system time: the expected FRMW working counter.
    pub(crate) sys_count: u16,
    /// Per-slave `t_Diff` overrides by auto-increment position (REQ-DC-015); `None` uses
    /// `Config::t_diff_ns`.
    pub(crate) t_diff: [Option<i32>; N],
    /// Running DC domain's time minus the master's clock at the latch, ns (REQ-DC-131); 0 when
    /// no slave was found running.
    pub(crate) domain_shift: i64,
    /// System time of the first SYNC0 pulse programmed (`None`: none yet).
    pub(crate) sync_start: Option<SystemTime>,
}

impl<const N: usize> Line<N> {
    /// Nothing found and no override.
    pub(crate) const fn new() -> Self {
        Line {
            slaves: [SlaveInfo::EMPTY; N],
            count: 0,
            reference: 0,
            sys_count: 0,
            t_diff: [None; N],
            domain_shift: 0,
            sync_start: None,
        }
    }

    /// The slaves found, in position order.
    pub(crate) fn found(&self) -> &[SlaveInfo] {
        self.slaves.get(..usize::from(self.count)).unwrap_or(&[])
    }

    /// The slave found at position `pos`.
    pub(crate) fn slave(&self, pos: u16) -> Option<&SlaveInfo> {
        self.slaves
            .get(usize::from(pos))
            .filter(|_| pos < self.count)
    }

    /// The slave found at position `pos`.
    pub(crate) fn slave_mut(&mut self, pos: u16) -> Option<&mut SlaveInfo> {
        let count = self.count;
        self.slaves
            .get_mut(usize::from(pos))
            .filter(|_| pos < count)
    }

    /// Slaves found with receive-time latches: the working counter of a latching BWR.
    pub(crate) fn latching_count(&self) -> u16 {
        let n = self.found().iter().filter(|s| s.dc.has_latches()).count();
        u16::try_from(n).unwrap_or(u16::MAX)
    }

    /// Back to [`new`](Self::new) in place (nothing of size `N` on the stack).
    pub(crate) fn clear(&mut self) {
        self.slaves.fill(SlaveInfo::EMPTY);
        self.t_diff.fill(None);
        self.forget_found();
    }

    /// A new bring-up starts: what the last one found no longer holds. The slave entries are
    /// overwritten by discovery before anything reads them.
    pub(crate) fn forget_found(&mut self) {
        self.count = 0;
        self.sys_count = 0;
        self.reference = 0;
        self.sync_start = None;
        self.domain_shift = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dc::slave::DcKind;

    fn line_of(kinds: &[DcKind]) -> Line<4> {
        let mut l = Line::new();
        for (s, k) in l.slaves.iter_mut().zip(kinds) {
            s.dc = *k;
        }
        l.count = u16::try_from(kinds.len()).unwrap();
        l
    }

    /// Only the slaves found are reachable, by position.
    #[test]
    fn slaves_beyond_the_count_are_not_found() {
        let mut l = line_of(&[DcKind::Bits64, DcKind::None]);
        assert_eq!(l.found().len(), 2);
        assert!(l.slave(1).is_some() && l.slave_mut(1).is_some());
        assert!(l.slave(2).is_none() && l.slave_mut(2).is_none());
        assert!(l.slave(u16::MAX).is_none() && l.slave_mut(u16::MAX).is_none());
        l.count = 0;
        assert!(l.slave(0).is_none() && l.slave_mut(0).is_none());
    }

    /// The latching BWR's working counter counts every slave with latches, and only those.
    #[test]
    fn latching_count_is_the_slaves_with_latches() {
        let l = line_of(&[
            DcKind::Bits64,
            DcKind::None,
            DcKind::DelayOnly,
            DcKind::Bits32,
        ]);
        assert_eq!(l.latching_count(), 3);
        assert_eq!(line_of(&[DcKind::None]).latching_count(), 0);
        // A slave beyond the count does not latch for this line.
        let mut l = line_of(&[DcKind::Bits64, DcKind::Bits64]);
        l.count = 1;
        assert_eq!(l.latching_count(), 1);
    }

    /// A new bring-up forgets what was found but keeps the t_Diff overrides; `clear` both.
    #[test]
    fn forget_found_keeps_overrides_clear_does_not() {
        let mut l = line_of(&[DcKind::Bits64]);
        l.reference = 1;
        l.sys_count = 1;
        l.domain_shift = 7;
        l.sync_start = Some(SystemTime(9));
        l.t_diff[0] = Some(80);
        l.forget_found();
        assert_eq!((l.count, l.reference, l.sys_count), (0, 0, 0));
        assert_eq!((l.domain_shift, l.sync_start), (0, None));
        assert_eq!(l.t_diff[0], Some(80));
        l.clear();
        assert_eq!(l, Line::new());
    }
}
