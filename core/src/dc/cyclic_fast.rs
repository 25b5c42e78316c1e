//! The cyclic exchange's fast paths (REQ-DC-106). Each does exactly what the general code
//! does with the frame it applies to, and declines (changing nothing) on anything else:
//! - transmit: the cycle's fixed datagrams written as one block (general: `push_op` each);
//! - receive: a reply laid out exactly as the cycle was sent, validated and matched in one
//!   8-byte compare per datagram, then routed by slot (general: `ecat_frame` + `take_match`).
//!   When the table holds just the cycle's own datagrams (FRMW, BRD 0x092C, BRD 0x0130, the
//!   round robin's FPRD 0x092C) the fixed sizes of the FPRD replies are used directly.
//!
//! Oracle tests compare each path with the general one (`cyclic.rs` tests).

use crate::dc::cyclic::{diff_reply, rr_after, CyclicCx};
use crate::dc::error::Error;
use crate::dc::event::Event;
use crate::dc::request::{Op, Payload, Pending, Tag};
use crate::dc::shared::index_after;
use crate::time::SystemTime;
use crate::wire::register::reg;
use crate::wire::{
    data_and_wkc, dlpdu_header, matches_pattern, put_small, set_more, Command, FrameBuilder,
    HeaderKey, DATAGRAM_OVERHEAD, ECAT_HEADER_LEN,
};

/// Size of one round-robin FPRD 0x092C datagram.
const FPRD_LEN: usize = 4 + DATAGRAM_OVERHEAD;

impl<const N: usize> CyclicCx<'_, N> {
    /// The cycle's fixed datagrams (FRMW, BRD 0x092C, BRD 0x0130, the round robin's FPRD
    /// 0x092C) written as one block: the same bytes, indexes, in-flight entries and
    /// round-robin cursor as pushing them one by one with `push_op` (the fallback in
    /// `fill_cyclic`), without the per-datagram checks. Applies only when every datagram fits
    /// the frame and the in-flight table (else returns false having changed nothing, and the
    /// caller pushes one by one, which also handles a partial fit).
    pub(crate) fn push_cycle_block(&mut self, b: &mut FrameBuilder<'_>, frmw: Op) -> bool {
        let frmw_value = match frmw.payload {
            Payload::Le(v) => v,
            Payload::Zero => 0,
        };
        if frmw.len > 8
            || frmw.address.check_for(frmw.command).is_err()
            || !self.sh.inflight.is_cleared()
        {
            return false;
        }
        // Indexes as `alloc_index` hands them out, one per datagram in send order.
        let (first, range) = (self.sh.cfg.index_first, self.sh.cfg.index_count);
        let mut next = self.sh.inflight.next_index;
        let mut alloc = || {
            let i = next;
            next = index_after(i, first, range);
            i
        };
        let (i0, i1, i2) = (alloc(), alloc(), alloc());
        // The round robin of `rr_next_monitored` over the list of slaves with a system time:
        // from the first at or after the cursor, `k` of them, wrapping; the cursor then stands
        // after the last read once `budget` were found, or where it started when fewer than
        // `budget` exist (the scan went all the way round).
        let count = self.sh.line.count;
        let start = self.rr_start();
        let Some((fixed_slots, rr_slots)) = self.sh.inflight.entries.split_at_mut_checked(3) else {
            return false;
        };
        let (list, j) = self
            .sh
            .scratch
            .monitor
            .get(&self.sh.line.slaves, count, start);
        let budget = usize::from(self.sh.cfg.monitor.slaves_per_cycle);
        let (before, after) = list.split_at(j.min(list.len()));
        let k = budget.min(list.len());
        if k > rr_slots.len() {
            // More reads than the table holds next to the fixed three.
            return false;
        }
        let new_rr = if count == 0 || budget == 0 {
            self.c.rr
        } else if budget <= list.len() {
            // The budget-th read: list[j + budget − 1], wrapped.
            let at = j.wrapping_add(budget).wrapping_sub(1);
            let at = if at >= list.len() {
                at.wrapping_sub(list.len())
            } else {
                at
            };
            list.get(at).map_or(start, |&(p, _)| rr_after(p, count))
        } else {
            start
        };
        // FRMW, BRD 4 bytes, BRD 2 bytes, k FPRD 4 bytes.
        let head = usize::from(frmw.len)
            .wrapping_add(DATAGRAM_OVERHEAD)
            .wrapping_add(4 + DATAGRAM_OVERHEAD)
            .wrapping_add(2 + DATAGRAM_OVERHEAD);
        let total = head.wrapping_add(k.wrapping_mul(FPRD_LEN));
        let last_at = if k == 0 {
            head.wrapping_sub(2 + DATAGRAM_OVERHEAD)
        } else {
            total.wrapping_sub(FPRD_LEN)
        };
        let n = k.wrapping_add(3);
        let Some(mut rest) = b.append_block(total, n, last_at) else {
            return false;
        };
        let fixed = [
            Pending {
                command: frmw.command,
                index: i0,
                station: frmw.station(),
                register: frmw.register(),
                len: frmw.len,
                tag: Tag::Frmw,
            },
            Pending {
                command: Command::Brd,
                index: i1,
                station: 0,
                register: reg::SYSTEM_TIME_DIFFERENCE,
                len: 4,
                tag: Tag::CycBound,
            },
            Pending {
                command: Command::Brd,
                index: i2,
                station: 0,
                register: reg::AL_STATUS,
                len: 2,
                tag: Tag::CycTopology,
            },
        ];
        // The FRMW of a 64-bit reference: `put_small`'s bytes (its key is its header: FP).
        let mut ok = if frmw.command == Command::Frmw && frmw.len == 8 {
            let bytes = fixed[0].key().with_more(true).datagram(frmw_value);
            match core::mem::take(&mut rest).split_first_chunk_mut::<{ 8 + DATAGRAM_OVERHEAD }>() {
                Some((d, tail)) => {
                    *d = bytes;
                    rest = tail;
                    true
                }
                None => false,
            }
        } else {
            put_small(
                &mut rest,
                frmw.command,
                i0,
                frmw.address,
                frmw.len,
                true,
                frmw_value,
            )
        };
        // The BRDs: `put_small`'s bytes (header with ADP 0, zero data, WKC 0).
        match core::mem::take(&mut rest).split_first_chunk_mut::<{ 4 + DATAGRAM_OVERHEAD }>() {
            Some((d, tail)) => {
                *d = fixed[1].key().with_more(true).datagram(0);
                rest = tail;
            }
            None => ok = false,
        }
        match core::mem::take(&mut rest).split_first_chunk_mut::<{ 2 + DATAGRAM_OVERHEAD }>() {
            Some((d, tail)) => {
                *d = fixed[2].key().with_more(k > 0).datagram(0);
                rest = tail;
            }
            None => ok = false,
        }
        for (slot, p) in fixed_slots.iter_mut().zip(fixed) {
            *slot = Some(p);
        }
        // The reads, their indexes in send order: entries into slots 3.., headers (their keys:
        // FP) into the block, M set on all but the last.
        let reads_len = k.wrapping_mul(FPRD_LEN);
        match core::mem::take(&mut rest).split_at_mut_checked(reads_len) {
            Some((reads, tail)) => {
                rest = tail;
                let targets = rr_slots.iter_mut().zip(reads.chunks_exact_mut(FPRD_LEN));
                for ((slot, d), &(pos, station)) in targets.zip(after.iter().chain(before)) {
                    let p = Pending {
                        command: Command::Fprd,
                        index: alloc(),
                        station,
                        register: reg::SYSTEM_TIME_DIFFERENCE,
                        len: 4,
                        tag: Tag::CycDiff(pos),
                    };
                    d.copy_from_slice(&p.key().with_more(true).datagram::<FPRD_LEN>(0));
                    *slot = Some(p);
                }
                if let Some(last) = reads.get_mut(reads_len.wrapping_sub(FPRD_LEN)..) {
                    set_more(last, false);
                }
            }
            None => ok = false,
        }
        self.c.rr = new_rr;
        self.sh.inflight.next_index = next;
        ok &= self.sh.inflight.mark_filled(n);
        // Unreachable by construction: `rest` was exactly `total` bytes, the sum of the pieces
        // written above, and `n` fits the table (checked before `append_block`). Should the
        // sums ever disagree, the block is already in the frame, so the cycle goes out with
        // nothing in flight: its replies count as foreign, the cycle is lost the ordinary way,
        // and the fault is reported instead of a panic (REQ-CONV-008).
        if !ok || !rest.is_empty() {
            self.sh.inflight.clear();
            self.sh.push_event(Event::Error(Error::Internal {
                state: crate::dc::State::Cyclic,
            }));
        }
        true
    }

    /// The receive fast path on `ecat` (EtherCAT header + datagrams, trailing padding
    /// allowed): [`Machine::cyclic_block_reply`] when the table holds the cycle's own
    /// datagrams, else the per-datagram pattern walk. True if the frame was handled.
    #[inline]
    pub(crate) fn cyclic_fast(&mut self, now: SystemTime, ecat: &[u8]) -> bool {
        let Some(n) = self.sh.inflight.fresh_len() else {
            return false;
        };
        match self.cyclic_block_reply(now, ecat, n) {
            Some(handled) => handled,
            None => self.cyclic_pattern_reply(now, ecat, n),
        }
    }

    /// The reply to a cycle whose table holds exactly FRMW (or ARMW), BRD 0x092C, BRD 0x0130
    /// and FPRD 0x092C × k, fresh (`n` entries): `None` if the table is not of that shape;
    /// else whether the frame is that cycle's reply, exactly as sent (header length, every
    /// datagram's command, index, address, length, M and C bits), in which case every reply
    /// went to `on_cyclic_reply` in slot order, as `cyclic_pattern_reply` would have done.
    #[inline]
    pub(crate) fn cyclic_block_reply(
        &mut self,
        now: SystemTime,
        ecat: &[u8],
        n: usize,
    ) -> Option<bool> {
        let [Some(p0), Some(p1), Some(p2), fprds @ ..] = self.sh.inflight.entries.get(..n)? else {
            return None;
        };
        // Anything else in flight (re-measurement steps) is pushed after the cycle's reads.
        let only_reads = match fprds.last() {
            None => true,
            Some(p) => p.is_some_and(|p| matches!(p.tag, Tag::CycDiff(_))),
        };
        if !only_reads
            || p0.tag != Tag::Frmw
            || p1.tag != Tag::CycBound
            || p2.tag != Tag::CycTopology
            || p1.len != 4
            || p2.len != 2
        {
            return None;
        }
        let k = fprds.len();
        let l0 = usize::from(p0.len).wrapping_add(DATAGRAM_OVERHEAD);
        let l1 = 4 + DATAGRAM_OVERHEAD;
        let l2 = 2 + DATAGRAM_OVERHEAD;
        let head = l0.wrapping_add(l1).wrapping_add(l2);
        let total = head.wrapping_add(k.wrapping_mul(FPRD_LEN));
        // Type DLPDU, reserved bit clear, exactly the length sent (≤ 32 × 20 bytes).
        let header = dlpdu_header(total)?;
        let Some(region) = ecat
            .get(..ECAT_HEADER_LEN.wrapping_add(total))
            .filter(|r| r.first_chunk() == Some(&header))
            .and_then(|r| r.get(ECAT_HEADER_LEN..))
        else {
            return Some(false);
        };
        let split = || {
            let (fixed, rr) = region.split_at_checked(head)?;
            let (d0, rest) = fixed.split_at_checked(l0)?;
            let (d1, d2) = rest.split_at_checked(l1)?;
            Some((d0, d1, d2, rr))
        };
        let Some((d0, d1, d2, rr)) = split() else {
            return Some(false);
        };
        let is = |d: &[u8], p: &Pending, more: bool| {
            d.first_chunk::<8>()
                .is_some_and(|h| p.pattern().matches(h, more))
        };
        if !is(d0, p0, true) || !is(d1, p1, true) || !is(d2, p2, k > 0) {
            return Some(false);
        }
        if !fprds_match(rr, fprds) {
            return Some(false);
        }
        // Matched: route every reply in slot order (`on_cyclic_reply` for these tags).
        let len0 = p0.len;
        let (data, wkc) = data_and_wkc(d0);
        self.on_frmw_reply(now, len0, wkc, data);
        let (data, wkc) = data_and_wkc(d1);
        self.on_bound_reply(wkc, data);
        let (data, wkc) = data_and_wkc(d2);
        self.on_topology_reply(wkc, data);
        let crate::dc::shared::Shared { inflight, line, .. } = &mut *self.sh;
        let cyc = &mut *self.c;
        let reads = inflight.entries.get(3..n).unwrap_or(&[]);
        for (p, d) in reads.iter().zip(rr.chunks_exact(FPRD_LEN)) {
            let (data, wkc) = data_and_wkc(d);
            if let (Some(p), Some(raw)) = (p, data.first_chunk::<4>()) {
                if let Tag::CycDiff(pos) = p.tag {
                    diff_reply(&mut line.slaves, line.count, cyc, pos, p.station, wkc, *raw);
                }
            }
        }
        self.sh.inflight.took_all(n);
        Some(true)
    }

    /// The reply to the `n` fresh entries of the table, validated and matched in one pattern
    /// walk (one 8-byte compare per datagram): the frame must hold exactly those datagrams in
    /// send order, none circulating, each matching its slot — then `handle_frame`'s general
    /// path would take slot `i` for datagram `i` (its in-order hint), and `on_cyclic_reply`
    /// changes neither the state nor the table. Routes every reply and returns true; else
    /// returns false having changed nothing.
    pub(crate) fn cyclic_pattern_reply(&mut self, now: SystemTime, ecat: &[u8], n: usize) -> bool {
        let inflight = &self.sh.inflight;
        if !matches_pattern(ecat, n, |i| inflight.get(i).map(Pending::pattern)) {
            return false;
        }
        // Validated: `n` datagrams at the offsets their lengths give, slot `i` for datagram `i`.
        let mut rest = ecat.get(ECAT_HEADER_LEN..).unwrap_or(&[]);
        for i in 0..n {
            let Some(p) = self.sh.inflight.get(i).copied() else {
                break;
            };
            let size = usize::from(p.len).wrapping_add(DATAGRAM_OVERHEAD);
            let Some((d, tail)) = rest.split_at_checked(size) else {
                break;
            };
            rest = tail;
            let (data, wkc) = data_and_wkc(d);
            self.on_cyclic_reply(now, p, wkc, data);
        }
        self.sh.inflight.took_all(n);
        true
    }
}

/// Whether `rr` is exactly the replies to the round-robin reads `fprds`, in order: each slot a
/// `CycDiff` entry for FPRD 0x092C of 4 bytes, each reply's first 8 header bytes its key with
/// M on all but the last (every bit compared: FP commands keep their station).
#[inline]
fn fprds_match(rr: &[u8], fprds: &[Option<Pending>]) -> bool {
    const FIXED: u64 = HeaderKey::COMMAND | HeaderKey::ADO | HeaderKey::LEN_WORD;
    const FPRD: HeaderKey = HeaderKey::new(Command::Fprd, 0, 0, reg::SYSTEM_TIME_DIFFERENCE, 4);
    let mut rest = rr;
    let mut left = fprds.len();
    let mut ok = true;
    for p in fprds {
        let (Some(p), Some((d, tail))) = (p, rest.split_first_chunk::<FPRD_LEN>()) else {
            return false;
        };
        rest = tail;
        left = left.wrapping_sub(1);
        let Some(h) = d.first_chunk() else {
            return false;
        };
        let key = p.key();
        ok &= key.agrees(FPRD, FIXED)
            && matches!(p.tag, Tag::CycDiff(_))
            && HeaderKey::of(h) == key.with_more(left > 0);
    }
    ok && rest.is_empty()
}
