//! The datagrams the machine sends and the table that matches replies to them by index.
//!
//! A request is an [`Op`]: command, address, length and a small payload. Reads carry zeros;
//! writes carry at most 8 bytes, always exactly the width of the register written
//! (REQ-CONV-003). A reply is accepted only if its index is one the machine has in flight *and*
//! its command, register (ADO), station (for FP commands) and length equal the request's
//! (REQ-DC-113); anything else in a frame is someone else's datagram and is counted, not used.

use crate::dc::error::Error;
#[cfg(test)]
use crate::wire::Datagram;
use crate::wire::{Address, Command, FrameBuilder, HeaderKey, HeaderPattern};

/// Most datagrams of the machine in one frame. Per-slave steps on bigger networks take several
/// frames. ecdc choice: 32 datagrams of up to 44 bytes fit one 1 498-byte EtherCAT payload.
pub const MAX_INFLIGHT: usize = 32;

/// Payload of a request: zeros (reads, the latch trigger) or the first `len` bytes of a
/// little-endian integer (writes of exactly the register's width).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Payload {
    /// `len` zero bytes.
    Zero,
    /// The low `len` bytes of the value, little-endian (`len` ≤ 8).
    Le(u64),
}

/// One datagram the machine wants to send.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Op {
    /// Command.
    pub command: Command,
    /// Address (position, configured or broadcast; ADO = register).
    pub address: Address,
    /// Data length in bytes.
    pub len: u16,
    /// Data.
    pub payload: Payload,
}

impl Op {
    /// A read of `len` bytes at `reg` of the slave with station address `station`.
    pub const fn fprd(station: u16, reg: u16, len: u16) -> Op {
        Op {
            command: Command::Fprd,
            address: Address::configured(station, reg),
            len,
            payload: Payload::Zero,
        }
    }
    /// A write of the low `len` bytes of `value` at `reg` of `station`.
    pub const fn fpwr(station: u16, reg: u16, len: u16, value: u64) -> Op {
        Op {
            command: Command::Fpwr,
            address: Address::configured(station, reg),
            len,
            payload: Payload::Le(value),
        }
    }
    /// A broadcast read of `len` bytes at `reg`.
    pub const fn brd(reg: u16, len: u16) -> Op {
        Op {
            command: Command::Brd,
            address: Address::broadcast(reg),
            len,
            payload: Payload::Zero,
        }
    }
    /// A broadcast write of `len` zero bytes at `reg`.
    pub const fn bwr_zero(reg: u16, len: u16) -> Op {
        Op {
            command: Command::Bwr,
            address: Address::broadcast(reg),
            len,
            payload: Payload::Zero,
        }
    }
    /// FRMW of `len` bytes at `reg` of the reference `station`, payload pre-filled with `value`
    /// (slaves in front of the reference compare with it, KickCAT `sendDriftCompensation`).
    pub const fn frmw(station: u16, reg: u16, len: u16, value: u64) -> Op {
        Op {
            command: Command::Frmw,
            address: Address::configured(station, reg),
            len,
            payload: Payload::Le(value),
        }
    }

    /// Station address for FP commands, else 0.
    pub const fn station(&self) -> u16 {
        match self.address {
            Address::Configured { station, .. } => station,
            _ => 0,
        }
    }

    /// Register (ADO), 0 for logical addresses.
    pub fn register(&self) -> u16 {
        self.address.ado().unwrap_or(0)
    }

    /// Writes the datagram into `b` with `index`. Fails (frame unchanged) if it does not fit.
    pub fn emit(&self, b: &mut FrameBuilder<'_>, index: u8) -> crate::wire::Result<()> {
        match self.payload {
            Payload::Zero => b
                .push_zeroed(self.command, index, self.address, self.len)
                .map(|_| ()),
            Payload::Le(v) => {
                let bytes = v.to_le_bytes();
                let n = usize::from(self.len).min(bytes.len());
                let data = bytes.get(..n).unwrap_or(&[]);
                b.push(self.command, index, self.address, data).map(|_| ())
            }
        }
    }
}

/// What a reply belongs to, inside the current step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Tag {
    /// Item number of the current request step.
    Item(u16),
    /// The FRMW that leads every cyclic frame and closes every drift-check frame but a
    /// check's last.
    Frmw,
    /// Cyclic BRD 0x092C (upper bound; WKC = slaves with a system time).
    CycBound,
    /// Cyclic BRD 0x0130 (AL status): its WKC counts every slave, the topology check.
    CycTopology,
    /// Cyclic FPRD 0x092C of the slave at this table position.
    CycDiff(u16),
    /// Cyclic delay re-measurement item.
    CycRemeasure(u16),
}

/// A datagram in flight: enough to match its reply and route it.
///
/// `repr(C)` in header order: the first 8 bytes are the datagram's first 8 header bytes
/// (command, index, ADP = station, ADO = register, length) as sent without the M bit, so
/// [`Pending::key`] is one load and a reply's header compares with it in one go.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(C)]
pub struct Pending {
    /// Command sent.
    pub command: Command,
    /// Index sent.
    pub index: u8,
    /// Station (FP commands) or 0.
    pub station: u16,
    /// Register (ADO) sent.
    pub register: u16,
    /// Data length sent.
    pub len: u16,
    /// Where the reply goes.
    pub tag: Tag,
}

impl Pending {
    /// REQ-DC-113: a reply matches only if index, command, register, length and (for FP
    /// commands) station are those sent. Position/broadcast ADP is changed by the slaves and is
    /// therefore not compared. Field by field: the tests' oracle for the one-load key match
    /// the machine uses ([`Pending::key`]).
    #[cfg(test)]
    pub fn matches<T: AsRef<[u8]>>(&self, d: &Datagram<T>) -> bool {
        // One read of the header bytes (the same fields as the accessors below).
        if let Some(h) = d.header_bytes() {
            return self.matches_header(h);
        }
        d.index() == self.index
            && d.command_raw() == self.command.code()
            && d.ado() == self.register
            && d.data_len() == self.len
            && (!matches!(
                self.command,
                Command::Fprd | Command::Fpwr | Command::Fprw | Command::Frmw
            ) || d.adp() == self.station)
    }
}

impl Pending {
    /// Command, index, station, register and length in the order and width of a datagram
    /// header's first 8 bytes read as a little-endian `u64` (M, C and reserved bits clear).
    #[inline]
    pub(crate) const fn key(&self) -> HeaderKey {
        HeaderKey::new(
            self.command,
            self.index,
            self.station,
            self.register,
            self.len,
        )
    }

    /// The reply header this entry accepts, for [`crate::wire::matches_pattern`]: command,
    /// index, register, length and, for FP commands, station — [`Pending::matches_header`]'s
    /// fields.
    #[inline]
    pub(crate) fn pattern(&self) -> HeaderPattern {
        HeaderPattern {
            want: self.key(),
            mask: self.compared(),
            len: self.len,
        }
    }

    /// The header bits a reply must share with the request: command, index, register and data
    /// length, and the station for FP commands (a position or broadcast address is changed by
    /// the slaves).
    #[inline(always)]
    const fn compared(&self) -> u64 {
        let fixed = HeaderKey::COMMAND_INDEX | HeaderKey::ADO | HeaderKey::LEN;
        if matches!(
            self.command,
            Command::Fprd | Command::Fpwr | Command::Fprw | Command::Frmw
        ) {
            fixed | HeaderKey::ADP
        } else {
            fixed
        }
    }

    /// [`Pending::matches`] on a datagram's 10 header bytes.
    #[inline]
    pub(crate) fn matches_header(&self, h: &[u8; 10]) -> bool {
        h.first_chunk::<8>()
            .is_some_and(|h| self.key().agrees(HeaderKey::of(h), self.compared()))
    }
}

/// The datagrams of one transmission still waiting for their reply.
///
/// Slots are filled in order (`0..used`) and a reply normally comes back in the order its
/// requests were sent, so matching first tries the slot after the previous match (`hint`) and
/// only then scans; counters make `is_empty`/`has_room` O(1). Indexes in flight are distinct
/// (`Config::index_count` ≥ 2 × [`MAX_INFLIGHT`]), so at most one entry matches a reply and
/// the order of the search never changes the result.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub(crate) struct Inflight {
    pub(crate) entries: [Option<Pending>; MAX_INFLIGHT],
    /// Slots `used..` are `None`.
    used: u8,
    /// Number of `Some` entries.
    live: u8,
    /// Slot tried first by the next `take_match`.
    hint: u8,
    /// The index the next datagram gets (`Config::index_first` + k, cycling through
    /// `Config::index_count` values); `clear` keeps it, so indexes keep cycling across frames.
    pub(crate) next_index: u8,
}

/// `MAX_INFLIGHT` as the counters' type.
const MAX_INFLIGHT_U8: u8 = 32;
const _: () = assert!(MAX_INFLIGHT_U8 as usize == MAX_INFLIGHT);

impl Inflight {
    /// An empty table whose first datagram gets index `first`.
    pub(crate) const fn new(first: u8) -> Self {
        Inflight {
            entries: [None; MAX_INFLIGHT],
            used: 0,
            live: 0,
            hint: 0,
            next_index: first,
        }
    }
    #[inline]
    pub(crate) fn is_empty(&self) -> bool {
        self.live == 0
    }
    #[inline]
    pub(crate) fn has_room(&self) -> bool {
        self.live < MAX_INFLIGHT_U8
    }
    #[inline]
    pub(crate) fn insert(&mut self, p: Pending) -> bool {
        if let Some(slot) = self.entries.get_mut(usize::from(self.used)) {
            *slot = Some(p);
            self.used = self.used.wrapping_add(1);
            self.live = self.live.wrapping_add(1);
            return true;
        }
        // Every slot was used since the last clear: reuse the first free one.
        match self.entries.iter_mut().find(|e| e.is_none()) {
            Some(slot) => {
                *slot = Some(p);
                self.live = self.live.saturating_add(1);
                true
            }
            None => false,
        }
    }
    /// No slot used since the last `clear`.
    #[inline]
    pub(crate) fn is_cleared(&self) -> bool {
        self.used == 0 && self.live == 0
    }
    /// After writing `Some` into slots `0..n` of a cleared table (through `entries`): counts
    /// them as used and live. False (nothing changed) if the table was not cleared or `n` is
    /// more than its size.
    #[inline]
    pub(crate) fn mark_filled(&mut self, n: usize) -> bool {
        match u8::try_from(n) {
            Ok(n) if n <= MAX_INFLIGHT_U8 && self.is_cleared() => {
                self.used = n;
                self.live = n;
                true
            }
            _ => false,
        }
    }
    #[inline]
    pub(crate) fn clear(&mut self) {
        // With no live entry every slot is already `None` (the usual case after a cycle).
        if self.live != 0 {
            for e in self.entries.iter_mut().take(usize::from(self.used)) {
                *e = None;
            }
        }
        self.used = 0;
        self.live = 0;
        self.hint = 0;
    }
    /// The number of entries when the table holds slots `0..n` (n > 0) exactly as filled,
    /// none taken yet and the hint at slot 0: then the reply datagram `i`, if it matches
    /// `entries[i]`, is the one `take_match` takes from slot `i` ([`Inflight::take_at`]).
    #[inline]
    pub(crate) fn fresh_len(&self) -> Option<usize> {
        (self.used > 0 && self.live == self.used && self.hint == 0)
            .then_some(usize::from(self.used))
    }
    /// Slot `i`'s entry, if any.
    #[inline]
    pub(crate) fn get(&self, i: usize) -> Option<&Pending> {
        self.entries.get(i)?.as_ref()
    }
    /// What `take_match` does once it has found slot `pos`: removes and returns its entry and
    /// moves the hint past it.
    #[inline]
    pub(crate) fn take_at(&mut self, pos: usize) -> Option<Pending> {
        let taken = self.entries.get_mut(pos)?.take()?;
        self.live = self.live.saturating_sub(1);
        self.hint = u8::try_from(pos.wrapping_add(1)).unwrap_or(0);
        Some(taken)
    }
    /// After the replies to all `n` entries of a table in the state [`Inflight::fresh_len`]
    /// describes were handled in slot order: the table `take_at(0..n)` leaves (every slot
    /// empty, the hint past the last).
    #[inline]
    pub(crate) fn took_all(&mut self, n: usize) {
        for e in self.entries.iter_mut().take(n) {
            *e = None;
        }
        self.live = 0;
        self.hint = u8::try_from(n).unwrap_or(0);
    }
    /// Removes and returns the pending entry matching the datagram with header bytes `d`, if
    /// any.
    #[inline]
    pub(crate) fn take_match(&mut self, d: &[u8; 10]) -> Option<Pending> {
        let h = usize::from(self.hint);
        let pos = match self.entries.get(h) {
            Some(Some(p)) if p.matches_header(d) => h,
            _ => self
                .entries
                .iter()
                .take(usize::from(self.used))
                .position(|e| e.is_some_and(|p| p.matches_header(d)))?,
        };
        self.take_at(pos)
    }
}

/// One matched reply to an item of a request step: the item's number, the datagram as sent,
/// and what came back.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Reply<'a> {
    pub(crate) item: u16,
    pub(crate) sent: Pending,
    pub(crate) wkc: u16,
    pub(crate) data: &'a [u8],
}

impl<'a> Reply<'a> {
    /// (item, datagram as sent, working counter, data).
    pub(crate) const fn parts(self) -> (u16, Pending, u16, &'a [u8]) {
        (self.item, self.sent, self.wkc, self.data)
    }
}

impl Pending {
    /// The error for a value read from (or meant for) this datagram's register that is out of
    /// range.
    pub(crate) const fn out_of_range(&self) -> Error {
        Error::OutOfRange {
            station: self.station,
            register: self.register,
        }
    }

    /// The working counter of a latching BWR (0x0900): every slave with latches must have seen
    /// the write; slaves without DC may or may not count it, so the count lies between
    /// `latching` and `all`.
    pub(crate) fn check_latch_wkc(&self, wkc: u16, latching: u16, all: u16) -> Result<(), Error> {
        if wkc < latching || wkc > all {
            return Err(Error::Wkc {
                command: self.command,
                station: 0,
                register: self.register,
                expected: latching,
                actual: wkc,
            });
        }
        Ok(())
    }
}

/// Reads a little-endian unsigned integer of up to 8 bytes; `None` if `data` is not exactly
/// `len` bytes long.
#[inline]
pub(crate) fn le(data: &[u8], len: usize) -> Option<u64> {
    if data.len() != len {
        return None;
    }
    // The widths the machine reads, without a variable-length copy (the last arm gives the
    // same values: these arms are for speed only). Longer than 8 bytes: `None` there.
    match *data {
        [a, b] => Some(u64::from(u16::from_le_bytes([a, b]))),
        [a, b, c, d] => Some(u64::from(u32::from_le_bytes([a, b, c, d]))),
        [a, b, c, d, e, f, g, h] => Some(u64::from_le_bytes([a, b, c, d, e, f, g, h])),
        _ => {
            let mut b = [0u8; 8];
            b.get_mut(..len)?.copy_from_slice(data);
            Some(u64::from_le_bytes(b))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::FrameBuilder;
    use std::vec::Vec;

    fn pending(index: u8, station: u16) -> Pending {
        Pending {
            index,
            command: Command::Fprd,
            register: 0x092C,
            station,
            len: 4,
            tag: Tag::CycDiff(station),
        }
    }

    /// The reply datagram (as bytes of a frame) for `p`.
    fn reply(p: &Pending) -> Vec<u8> {
        let mut buf = [0u8; 64];
        let mut b = FrameBuilder::new(&mut buf).unwrap();
        let s = b
            .push(
                p.command,
                p.index,
                Address::configured(p.station, p.register),
                &[0; 4],
            )
            .unwrap();
        buf[s.offset()..s.offset() + 16].to_vec()
    }

    /// REQ-DC-113: a reply header matches its request on command, index, register and data
    /// length, and on the station for FP commands only; M, C and IRQ do not matter.
    #[test]
    fn reply_header_fields_that_must_match() {
        let header = |cmd: u8, idx: u8, adp: u16, ado: u16, len_word: u16| {
            let mut h = [0u8; 10];
            h[0] = cmd;
            h[1] = idx;
            h[2..4].copy_from_slice(&adp.to_le_bytes());
            h[4..6].copy_from_slice(&ado.to_le_bytes());
            h[6..8].copy_from_slice(&len_word.to_le_bytes());
            h[8] = 0x55;
            h
        };
        let fp = pending(7, 0x1001);
        let fprd = Command::Fprd.code();
        assert!(fp.matches_header(&header(fprd, 7, 0x1001, 0x092C, 4)));
        assert!(fp.matches_header(&header(fprd, 7, 0x1001, 0x092C, 4 | 0xC000)));
        for h in [
            header(fprd, 7, 0x1001, 0x092C, 5),
            header(fprd, 7, 0x1001, 0x092C, 4 | 0x0100),
            header(fprd, 8, 0x1001, 0x092C, 4),
            header(fprd, 7, 0x1002, 0x092C, 4),
            header(fprd, 7, 0x1001, 0x092D, 4),
            header(Command::Fpwr.code(), 7, 0x1001, 0x092C, 4),
        ] {
            assert!(!fp.matches_header(&h), "{h:02x?}");
        }
        // A broadcast's ADP is the slaves' count of it: not compared.
        let brd = Pending {
            command: Command::Brd,
            station: 0,
            ..fp
        };
        let code = Command::Brd.code();
        assert!(brd.matches_header(&header(code, 7, 0x0003, 0x092C, 4)));
        assert!(!brd.matches_header(&header(code, 7, 0x0003, 0x092C, 2)));
    }

    /// The in-flight table: room and emptiness by counters, matching in send order and out of
    /// order, a reply matched once only, and reuse of freed slots once all 32 were used.
    #[test]
    fn inflight_table() {
        let mut t = Inflight::new(0x80);
        assert!(t.is_empty() && t.has_room());
        let ps: Vec<Pending> = (0..MAX_INFLIGHT as u16)
            .map(|i| pending(0x80 + i as u8, 0x1000 + i))
            .collect();
        for p in &ps {
            assert!(t.insert(*p));
        }
        assert!(!t.has_room() && !t.is_empty());
        assert!(!t.insert(pending(0x10, 1)), "full");
        // In order, then out of order (the hint misses and the scan finds it).
        for i in [0usize, 1, 2, 7, 3, 31, 4] {
            let r = reply(&ps[i]);
            let d = Datagram::new_checked(&r[..]).unwrap();
            assert!(ps[i].matches(&d));
            let h = d.header_bytes().unwrap();
            assert_eq!(t.take_match(h), Some(ps[i]));
            assert_eq!(t.take_match(h), None, "matched once");
        }
        // A wrong station does not match.
        let mut other = ps[5];
        other.station = 0x2000;
        let r = reply(&other);
        let d = Datagram::new_checked(&r[..]).unwrap();
        assert!(!ps[5].matches(&d));
        assert_eq!(t.take_match(d.header_bytes().unwrap()), None);
        assert!(t.has_room());
        // Freed slots are reused although all 32 were used since the clear.
        let q = pending(0x40, 0x3000);
        assert!(t.insert(q));
        let r = reply(&q);
        assert_eq!(
            t.take_match(
                Datagram::new_checked(&r[..])
                    .unwrap()
                    .header_bytes()
                    .unwrap()
            ),
            Some(q)
        );
        t.clear();
        assert!(t.is_empty() && t.has_room());
        assert!(t.entries.iter().all(Option::is_none));
    }

    /// A table is cleared until a slot is used, and stays used after its entry is taken,
    /// until `clear`. `mark_filled` counts slots written directly, only into a cleared table
    /// and only up to its size.
    #[test]
    fn cleared_and_filled() {
        let mut t = Inflight::new(0x80);
        assert!(t.is_cleared());
        assert_eq!(t.fresh_len(), None, "nothing filled");
        let p = pending(0x80, 0x1001);
        assert!(t.insert(p));
        assert!(!t.is_cleared());
        let r = reply(&p);
        let d = Datagram::new_checked(&r[..]).unwrap();
        assert_eq!(t.take_match(d.header_bytes().unwrap()), Some(p));
        assert!(t.is_empty() && !t.is_cleared(), "a slot was used");
        assert!(!t.mark_filled(1), "not cleared");
        t.clear();
        assert!(!t.mark_filled(MAX_INFLIGHT + 1), "more than its size");
        assert!(t.is_cleared());
        for (i, e) in t.entries.iter_mut().take(3).enumerate() {
            *e = Some(pending(0x80 + i as u8, 0x1001 + i as u16));
        }
        assert!(t.mark_filled(3));
        assert_eq!(t.fresh_len(), Some(3));
        assert!(!t.is_cleared());
        // Only as filled: not once an entry is taken, nor with the hint moved.
        let mut taken = t.clone();
        assert!(taken.take_at(0).is_some());
        assert_eq!(taken.fresh_len(), None);
        let mut moved = t.clone();
        moved.hint = 1;
        assert_eq!(moved.fresh_len(), None);
        t.clear();
        assert!(t.mark_filled(MAX_INFLIGHT));
    }

    /// `le` reads 2, 4 and 8 bytes and any other length up to 8, and refuses a length mismatch.
    #[test]
    fn le_widths() {
        assert_eq!(le(&[1, 2], 2), Some(0x0201));
        assert_eq!(le(&[1, 2, 3, 4], 4), Some(0x0403_0201));
        assert_eq!(
            le(&[1, 2, 3, 4, 5, 6, 7, 8], 8),
            Some(0x0807_0605_0403_0201)
        );
        assert_eq!(le(&[1, 2, 3], 3), Some(0x03_0201));
        assert_eq!(le(&[1, 2, 3], 4), None);
        assert_eq!(le(&[0; 9], 9), None);
    }
}
