//! The slaves the cyclic round robin reads (REQ-DC-106): every position with a system time,
//! ascending, with its station address — derived from the slave table, so that a cycle takes
//! its per-slave FPRD 0x092C reads from a dense list instead of stepping over the table.
//!
//! A cache, not state: it is rebuilt from `slaves[..count]` whenever it is not known to match
//! them (after every entry into `Cyclic`, or if `count` changed), so it is not part of the
//! machine's control state (`dc/control.rs`).

use crate::dc::slave::SlaveInfo;

/// Positions (and stations) of the slaves with a system time among the first `count`.
#[derive(Clone)]
pub(crate) struct MonitorList<const N: usize> {
    /// (position, station), ascending by position; `len` entries are valid.
    entries: [(u16, u16); N],
    /// For each position p < count: the number of entries below p (the index of the first
    /// entry at or after p).
    rank: [u16; N],
    len: u16,
    /// The slave count the list was built for; `None`: to be rebuilt.
    built_for: Option<u16>,
}

impl<const N: usize> core::fmt::Debug for MonitorList<N> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("MonitorList")
            .field("len", &self.len)
            .field("built_for", &self.built_for)
            .finish_non_exhaustive()
    }
}

impl<const N: usize> MonitorList<N> {
    pub(crate) const fn new() -> Self {
        MonitorList {
            entries: [(0, 0); N],
            rank: [0; N],
            len: 0,
            built_for: None,
        }
    }

    /// Forget the list (the slave table may change).
    pub(crate) fn invalidate(&mut self) {
        self.built_for = None;
    }

    /// The list for `slaves` (the first `count`), rebuilt if it is not known to match them,
    /// and the index in it of the first entry at or after position `start` (< `count`, or 0).
    #[inline]
    pub(crate) fn get(
        &mut self,
        slaves: &[SlaveInfo; N],
        count: u16,
        start: u16,
    ) -> (&[(u16, u16)], usize) {
        if self.built_for != Some(count) {
            self.rebuild(slaves, count);
        }
        let list = self.entries.get(..usize::from(self.len)).unwrap_or(&[]);
        let j = self
            .rank
            .get(usize::from(start))
            .map_or(0, |&r| usize::from(r));
        (list, j)
    }

    #[cold]
    fn rebuild(&mut self, slaves: &[SlaveInfo; N], count: u16) {
        let mut len = 0u16;
        for ((pos, s), rank) in (0..count).zip(slaves.iter()).zip(self.rank.iter_mut()) {
            *rank = len;
            if s.dc.has_system_time() {
                if let Some(slot) = self.entries.get_mut(usize::from(len)) {
                    *slot = (pos, s.station);
                    len = len.wrapping_add(1);
                }
            }
        }
        self.len = len;
        self.built_for = Some(count);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dc::slave::DcKind;

    /// The list and the rank equal a plain scan of the table, for tables of every size up to
    /// 40 with pseudo-random DC kinds, every start position; a rebuild follows `invalidate`
    /// and a change of `count`, and the list is not in `Debug`.
    #[test]
    fn list_and_rank_match_a_scan() {
        let mut seed = 0x9E37_79B9_7F4A_7C15u64;
        let mut slaves = [SlaveInfo::default(); 40];
        for count in 0..=40u16 {
            for s in slaves.iter_mut() {
                seed ^= seed << 13;
                seed ^= seed >> 7;
                seed ^= seed << 17;
                s.dc = match seed % 4 {
                    0 => DcKind::None,
                    1 => DcKind::DelayOnly,
                    2 => DcKind::Bits32,
                    _ => DcKind::Bits64,
                };
                s.station = (seed >> 20) as u16;
            }
            let mut m = MonitorList::<40>::new();
            m.invalidate();
            let want: std::vec::Vec<(u16, u16)> = (0..count)
                .filter(|&p| slaves[usize::from(p)].dc.has_system_time())
                .map(|p| (p, slaves[usize::from(p)].station))
                .collect();
            for start in 0..count.max(1) {
                let (list, j) = m.get(&slaves, count, start);
                assert_eq!(list, &want[..]);
                assert_eq!(j, want.iter().filter(|&&(p, _)| p < start).count());
            }
            // Stale until invalidated (same count), rebuilt after.
            if count > 0 {
                slaves[0].dc = if slaves[0].dc.has_system_time() {
                    DcKind::None
                } else {
                    DcKind::Bits64
                };
                assert_eq!(m.get(&slaves, count, 0).0, &want[..]);
                m.invalidate();
                assert_ne!(m.get(&slaves, count, 0).0, &want[..]);
            }
            let shown = std::format!("{m:?}");
            assert!(shown.starts_with("MonitorList { len: "), "{shown}");
        }
    }
}
