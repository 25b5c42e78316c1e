//! Building a frame datagram by datagram in the caller's buffer (REQ-WIRE-040..042).
//!
//! The builder keeps the frame valid after every successful push: the previous datagram's M
//! bit is set, the EtherCAT header length covers exactly the datagrams, the new datagram has
//! M clear, IRQ 0 and WKC 0. A push that does not fit returns [`Error::BufferFull`] and changes
//! nothing, so a state machine handed `&mut FrameBuilder` can try to append its datagrams to a
//! frame the embedding master is also filling, and leave the rest for the next frame.

use super::datagram::field as dfield;
use super::frame::field as ffield;
use super::{
    Address, Command, Datagram, DatagramRepr, Error, Result, BROADCAST_MAC, ETHERTYPE_ETHERCAT,
    MASTER_MAC, MAX_DATAGRAM_DATA, MAX_ECAT_PAYLOAD, MIN_FRAME_LEN,
};
use crate::wire::ethernet::{EthernetFrame, HEADER_LEN as ETH_HEADER_LEN};

/// A handle to a datagram pushed into a [`FrameBuilder`], used to fill its data later and to
/// match its reply (by index, or by offset in the frame).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct DatagramSlot {
    offset: usize,
    len: u16,
    index: u8,
}

impl DatagramSlot {
    /// Offset of the datagram's first byte in the builder's buffer (Ethernet frame or UDP
    /// payload, as the builder was created).
    pub const fn offset(&self) -> usize {
        self.offset
    }
    /// Offset of the first data byte in the builder's buffer.
    pub const fn data_offset(&self) -> usize {
        self.offset.wrapping_add(dfield::DATA)
    }
    /// Data length.
    pub const fn len(&self) -> u16 {
        self.len
    }
    /// True if the datagram carries no data.
    pub const fn is_empty(&self) -> bool {
        self.len == 0
    }
    /// The index written into the datagram.
    pub const fn index(&self) -> u8 {
        self.index
    }
}

/// Writes an Ethernet header (or nothing, for a UDP payload), the EtherCAT header and datagrams
/// into `&'a mut [u8]`.
#[derive(Debug)]
pub struct FrameBuilder<'a> {
    buf: &'a mut [u8],
    /// Offset of the EtherCAT header in `buf` (14, or 0 for a UDP payload).
    ecat_start: usize,
    /// End of the last datagram in `buf`.
    end: usize,
    /// Offset of the last datagram, whose M bit the next push sets.
    last: Option<usize>,
    count: usize,
    next_index: u8,
    /// Ethernet frames are padded to 60 bytes by `finish`.
    pad: bool,
}

impl<'a> FrameBuilder<'a> {
    /// Starts an Ethernet frame: dst ff:ff:ff:ff:ff:ff, src [`MASTER_MAC`], EtherType 0x88A4,
    /// EtherCAT header with length 0 and type 1. Needs at least 60 bytes (the padded minimum),
    /// else [`Error::BufferFull`]. REQ-WIRE-041, REQ-WIRE-060
    pub fn new(buf: &'a mut [u8]) -> Result<FrameBuilder<'a>> {
        if buf.len() < MIN_FRAME_LEN {
            return Err(Error::BufferFull);
        }
        let mut eth = EthernetFrame::new_unchecked(&mut *buf);
        eth.set_dst(BROADCAST_MAC);
        eth.set_src(MASTER_MAC);
        eth.set_outer_ethertype(ETHERTYPE_ETHERCAT);
        Ok(FrameBuilder::start(buf, ETH_HEADER_LEN, true))
    }

    /// Starts an EtherCAT-over-UDP payload (EtherCAT header + datagrams, no padding).
    /// Needs at least the 2 header bytes, else [`Error::BufferFull`]. REQ-WIRE-003
    pub fn new_udp_payload(buf: &'a mut [u8]) -> Result<FrameBuilder<'a>> {
        if buf.len() < ffield::HEADER_LEN {
            return Err(Error::BufferFull);
        }
        Ok(FrameBuilder::start(buf, 0, false))
    }

    fn start(buf: &'a mut [u8], ecat_start: usize, pad: bool) -> FrameBuilder<'a> {
        let mut b = FrameBuilder {
            buf,
            ecat_start,
            end: ecat_start.wrapping_add(ffield::HEADER_LEN),
            last: None,
            count: 0,
            next_index: 0,
            pad,
        };
        b.write_header_len();
        b
    }

    /// Re-opens a valid untagged Ethernet EtherCAT frame already in `buf` (e.g. built earlier
    /// and kept) to append further datagrams. Padding after the datagrams is overwritten.
    pub fn resume(buf: &'a mut [u8]) -> Result<FrameBuilder<'a>> {
        if buf.len() < MIN_FRAME_LEN {
            return Err(Error::BufferFull);
        }
        let (end, last, count) = {
            let eth = EthernetFrame::new_checked(&*buf)?;
            if eth.is_tagged() {
                return Err(Error::NotEtherCat {
                    ethertype: eth.outer_ethertype(),
                });
            }
            let frame = eth.ecat_frame()?;
            let mut last = None;
            let mut count = 0usize;
            for off in frame.datagram_offsets() {
                let (s, _) = off?;
                last = Some(s.wrapping_add(ETH_HEADER_LEN));
                count = count.wrapping_add(1);
            }
            (frame.ecat_len().wrapping_add(ETH_HEADER_LEN), last, count)
        };
        Ok(FrameBuilder {
            buf,
            ecat_start: ETH_HEADER_LEN,
            end,
            last,
            count,
            next_index: 0,
            pad: true,
        })
    }

    /// Sets the source MAC (default [`MASTER_MAC`]; keep bit 0x02 of the first octet clear so
    /// processed frames stay recognisable). No effect on a UDP payload.
    pub fn set_source(&mut self, mac: [u8; 6]) {
        if self.pad {
            EthernetFrame::new_unchecked(&mut *self.buf).set_src(mac);
        }
    }

    /// Sets the destination MAC. No effect on a UDP payload.
    pub fn set_destination(&mut self, mac: [u8; 6]) {
        if self.pad {
            EthernetFrame::new_unchecked(&mut *self.buf).set_dst(mac);
        }
    }

    /// The index [`FrameBuilder::push_auto`] uses next.
    pub fn next_index(&self) -> u8 {
        self.next_index
    }

    /// Sets the index [`FrameBuilder::push_auto`] uses next (it then counts up, wrapping).
    pub fn set_next_index(&mut self, idx: u8) {
        self.next_index = idx;
    }

    /// Datagrams pushed so far.
    pub fn datagram_count(&self) -> usize {
        self.count
    }

    /// Current frame length without padding.
    pub fn len(&self) -> usize {
        self.end
    }

    /// True if no datagram was pushed.
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// Largest data length one more datagram can carry: limited by the buffer, the 1498
    /// datagram bytes of one frame and 1486 bytes per datagram; 0 also when not even an empty datagram
    /// fits (check with [`FrameBuilder::fits`]).
    pub fn remaining_data_capacity(&self) -> usize {
        self.room()
            .saturating_sub(dfield::MIN_LEN)
            .min(MAX_DATAGRAM_DATA)
    }

    /// True if a datagram with `len` data bytes fits.
    pub fn fits(&self, len: usize) -> bool {
        len <= MAX_DATAGRAM_DATA && len.saturating_add(dfield::MIN_LEN) <= self.room()
    }

    /// Bytes left for datagrams.
    fn room(&self) -> usize {
        let limit = self.buf.len().min(
            self.ecat_start
                .saturating_add(ffield::HEADER_LEN)
                .saturating_add(MAX_ECAT_PAYLOAD),
        );
        limit.saturating_sub(self.end)
    }

    /// Appends a datagram with `data`, M clear, IRQ 0, WKC 0, and sets the previous datagram's
    /// M bit. Errors (nothing written): [`Error::AddressMismatch`], [`Error::DatagramTooLong`],
    /// [`Error::BufferFull`]. REQ-WIRE-040
    pub fn push(
        &mut self,
        command: Command,
        index: u8,
        address: Address,
        data: &[u8],
    ) -> Result<DatagramSlot> {
        let len = u16::try_from(data.len())
            .ok()
            .filter(|l| usize::from(*l) <= MAX_DATAGRAM_DATA)
            .ok_or(Error::DatagramTooLong {
                len: u16::try_from(data.len()).unwrap_or(u16::MAX),
            })?;
        self.reserve(command, index, address, len, Some(data))
    }

    /// Like [`FrameBuilder::push`] with `len` zero bytes of data (fill them later through
    /// [`FrameBuilder::data_mut`]).
    pub fn push_zeroed(
        &mut self,
        command: Command,
        index: u8,
        address: Address,
        len: u16,
    ) -> Result<DatagramSlot> {
        self.reserve(command, index, address, len, None)
    }

    /// Like [`FrameBuilder::push`] with the next automatic index (see
    /// [`FrameBuilder::set_next_index`]); the counter advances only on success.
    pub fn push_auto(
        &mut self,
        command: Command,
        address: Address,
        data: &[u8],
    ) -> Result<DatagramSlot> {
        let slot = self.push(command, self.next_index, address, data)?;
        self.next_index = self.next_index.wrapping_add(1);
        Ok(slot)
    }

    /// Appends a datagram described by `repr` (its C bit, IRQ and WKC included, so an emulator
    /// or a test can build replies) with `data`; `data.len()` must equal `repr.len`, else
    /// [`Error::Truncated`].
    pub fn push_repr(&mut self, repr: &DatagramRepr, data: &[u8]) -> Result<DatagramSlot> {
        if data.len() != usize::from(repr.len) {
            return Err(Error::Truncated);
        }
        let slot = self.push(repr.command, repr.index, repr.address, data)?;
        let mut d = self.datagram_mut(slot)?;
        d.set_circulating(repr.circulating);
        d.set_irq(repr.irq);
        d.set_wkc(repr.wkc);
        Ok(slot)
    }

    /// Appends one datagram: header (M clear, IRQ 0), `data` (exactly `len` bytes) or `len`
    /// zeros, WKC 0; sets the previous datagram's M bit and the EtherCAT header length. Writes
    /// the same bytes as `DatagramRepr::emit` on a zeroed region, in one pass.
    #[inline]
    fn reserve(
        &mut self,
        command: Command,
        index: u8,
        address: Address,
        len: u16,
        data: Option<&[u8]>,
    ) -> Result<DatagramSlot> {
        address.check_for(command)?;
        if usize::from(len) > MAX_DATAGRAM_DATA {
            return Err(Error::DatagramTooLong { len });
        }
        if !self.fits(usize::from(len)) {
            return Err(Error::BufferFull);
        }
        let total = usize::from(len).wrapping_add(dfield::MIN_LEN);
        let start = self.end;
        let end = start.checked_add(total).ok_or(Error::BufferFull)?;
        let region = self.buf.get_mut(start..end).ok_or(Error::BufferFull)?;
        let (header, rest) = region
            .split_first_chunk_mut::<{ dfield::HEADER_LEN }>()
            .ok_or(Error::BufferFull)?;
        let [a0, a1, a2, a3] = address.to_raw().to_le_bytes();
        let [l0, l1] = (len & dfield::LEN_MASK).to_le_bytes();
        *header = [command.code(), index, a0, a1, a2, a3, l0, l1, 0, 0];
        let (body, wkc) = rest
            .split_at_mut_checked(usize::from(len))
            .ok_or(Error::BufferFull)?;
        match data {
            Some(d) if d.len() == body.len() => copy_small(body, d),
            _ => zero_small(body),
        }
        zero_small(wkc);
        // Only now that the new datagram is written does the previous one get its M bit.
        self.commit(start, end, start, 1);
        Ok(DatagramSlot {
            offset: start,
            len,
            index,
        })
    }

    /// Appends a block of `n` datagrams that the caller writes into the returned `total` bytes
    /// (crate-internal fast path for fixed datagram sets, e.g. the DC cycle). The caller must
    /// write `n` complete datagrams, M set on all but the last, the last one starting at
    /// `last_at` in the block (see [`put_small`]). Like `n` successful pushes of those
    /// datagrams, this sets the previous datagram's M bit, the EtherCAT header length, the
    /// datagram count and the datagram a later push chains to. `None`, with nothing changed,
    /// if the block does not fit (the same room check as [`FrameBuilder::fits`] per datagram:
    /// the sum of their sizes within the room) or `last_at` is not inside it.
    #[inline(always)]
    pub(crate) fn append_block(
        &mut self,
        total: usize,
        n: usize,
        last_at: usize,
    ) -> Option<&mut [u8]> {
        if total > self.room() || last_at >= total || n == 0 {
            return None;
        }
        let start = self.end;
        let end = start.checked_add(total)?;
        if end > self.buf.len() {
            return None;
        }
        self.commit(start, end, start.wrapping_add(last_at), n);
        self.buf.get_mut(start..end)
    }

    /// Takes `n` datagrams written at `start..end` (the last one at `last`) into the frame: the
    /// previous last datagram gets its M bit (bit 15 of its little-endian length word, i.e. the
    /// high byte's top bit), then the end, count, chain and EtherCAT header length follow.
    #[inline(always)]
    fn commit(&mut self, start: usize, end: usize, last: usize, n: usize) {
        if let Some(prev) = self.last {
            let at = prev.wrapping_add(dfield::LEN_FLAGS.end.wrapping_sub(1));
            if at < start {
                if let Some(b) = self.buf.get_mut(at) {
                    *b |= 0x80;
                }
            }
        }
        self.last = Some(last);
        self.end = end;
        self.count = self.count.wrapping_add(n);
        self.write_header_len();
    }

    #[inline(always)]
    fn write_header_len(&mut self) {
        let len = self
            .end
            .saturating_sub(self.ecat_start.wrapping_add(ffield::HEADER_LEN));
        // len ≤ 1498 by the capacity check in `fits`; type 1 (DLPDU), reserved bit 0 — what
        // `EcatFrame::set_header(len, 1)` writes.
        let len = u16::try_from(len).unwrap_or(0);
        let v = (len & ffield::LEN_MASK) | (1u16 << ffield::TYPE_SHIFT);
        if let Some(h) = self
            .buf
            .get_mut(self.ecat_start..)
            .and_then(|b| b.first_chunk_mut::<2>())
        {
            *h = v.to_le_bytes();
        }
    }

    fn check_slot(&self, slot: DatagramSlot) -> Result<core::ops::Range<usize>> {
        let first = self.ecat_start.wrapping_add(ffield::HEADER_LEN);
        let data = slot.data_offset()..slot.data_offset().wrapping_add(usize::from(slot.len));
        let dg_end = data.end.wrapping_add(dfield::WKC_LEN);
        let ok = slot.offset >= first
            && dg_end <= self.end
            && data.start <= data.end
            && self
                .buf
                .get(slot.offset..dg_end)
                .is_some_and(|b| Datagram::new_unchecked(b).data_len() == slot.len);
        if ok {
            Ok(slot.offset..dg_end)
        } else {
            Err(Error::InvalidSlot)
        }
    }

    /// The data bytes of a pushed datagram. [`Error::InvalidSlot`] if the slot is not from this
    /// frame.
    pub fn data_mut(&mut self, slot: DatagramSlot) -> Result<&mut [u8]> {
        let r = self.check_slot(slot)?;
        let dg = self.buf.get_mut(r).ok_or(Error::InvalidSlot)?;
        Ok(Datagram::new_unchecked(dg).data_mut_owned())
    }

    /// A mutable view of a pushed datagram (to set IRQ, WKC, C bit, address after the fact).
    pub fn datagram_mut(&mut self, slot: DatagramSlot) -> Result<Datagram<&mut [u8]>> {
        let r = self.check_slot(slot)?;
        self.buf
            .get_mut(r)
            .map(Datagram::new_unchecked)
            .ok_or(Error::InvalidSlot)
    }

    /// Ends the frame: Ethernet frames are zero-padded to 60 bytes. Returns the frame length
    /// (the bytes to send are `buf[..len]`). [`Error::NoDatagram`] if nothing was pushed.
    /// REQ-WIRE-041
    pub fn finish(self) -> Result<usize> {
        if self.count == 0 {
            return Err(Error::NoDatagram);
        }
        if !self.pad {
            return Ok(self.end);
        }
        if self.end >= MIN_FRAME_LEN {
            return Ok(self.end);
        }
        if let Some(p) = self.buf.get_mut(self.end..MIN_FRAME_LEN) {
            p.fill(0);
        }
        Ok(MIN_FRAME_LEN)
    }
}

/// Writes one datagram at the start of `*dst` and moves `*dst` past it: header (`command`,
/// `index`, `address`, data length `len`, M = `more`, C clear, IRQ 0), the low `len` bytes of
/// `value` little-endian as data (`len` ≤ 8), WKC 0 — the bytes [`FrameBuilder::push`] writes
/// for that datagram (plus the M bit a following push would set). False, with `*dst`
/// unchanged, if `len` > 8 or the datagram does not fit.
#[inline]
pub(crate) fn put_small(
    dst: &mut &mut [u8],
    command: Command,
    index: u8,
    address: Address,
    len: u16,
    more: bool,
    value: u64,
) -> bool {
    if len > 8 {
        return false;
    }
    let [a0, a1, a2, a3] = address.to_raw().to_le_bytes();
    let flags = if more { dfield::MORE } else { 0 };
    let [l0, l1] = ((len & dfield::LEN_MASK) | flags).to_le_bytes();
    let c = command.code();
    let [v0, v1, v2, v3, v4, v5, v6, v7] = value.to_le_bytes();
    let total = usize::from(len).wrapping_add(dfield::MIN_LEN);
    if dst.len() < total {
        return false;
    }
    let taken = core::mem::take(dst);
    let Some((d, tail)) = taken.split_at_mut_checked(total) else {
        return false;
    };
    match len {
        2 => put_array(d, [c, index, a0, a1, a2, a3, l0, l1, 0, 0, v0, v1, 0, 0]),
        4 => put_array(
            d,
            [c, index, a0, a1, a2, a3, l0, l1, 0, 0, v0, v1, v2, v3, 0, 0],
        ),
        8 => put_array(
            d,
            [
                c, index, a0, a1, a2, a3, l0, l1, 0, 0, v0, v1, v2, v3, v4, v5, v6, v7, 0, 0,
            ],
        ),
        _ => {
            let v = value.to_le_bytes();
            let data = v.get(..usize::from(len)).unwrap_or(&[]);
            if let Some((h, rest)) = d.split_first_chunk_mut::<{ dfield::HEADER_LEN }>() {
                *h = [c, index, a0, a1, a2, a3, l0, l1, 0, 0];
                if let Some((body, wkc)) = rest.split_at_mut_checked(data.len()) {
                    body.copy_from_slice(data);
                    wkc.fill(0);
                }
            }
        }
    }
    *dst = tail;
    true
}

/// `dst.fill(0)`, with the short lengths of DC datagrams written as fixed-size stores (no
/// call into `memset`).
#[inline]
fn zero_small(dst: &mut [u8]) {
    match dst.len() {
        0 => {}
        2 => put_array(dst, [0u8; 2]),
        4 => put_array(dst, [0u8; 4]),
        8 => put_array(dst, [0u8; 8]),
        _ => dst.fill(0),
    }
}

/// `dst.copy_from_slice(src)` for `dst.len() == src.len()`, fixed-size for 2, 4 and 8 bytes.
#[inline]
fn copy_small(dst: &mut [u8], src: &[u8]) {
    match (src.len(), dst.len()) {
        (2, 2) => copy_array::<2>(dst, src),
        (4, 4) => copy_array::<4>(dst, src),
        (8, 8) => copy_array::<8>(dst, src),
        (a, b) if a == b => dst.copy_from_slice(src),
        _ => {}
    }
}

#[inline]
fn put_array<const K: usize>(dst: &mut [u8], v: [u8; K]) {
    if let Some(d) = dst.first_chunk_mut::<K>() {
        *d = v;
    }
}

#[inline]
fn copy_array<const K: usize>(dst: &mut [u8], src: &[u8]) {
    if let (Some(d), Some(s)) = (dst.first_chunk_mut::<K>(), src.first_chunk::<K>()) {
        *d = *s;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::{EcatFrame, MAX_FRAME_LEN};

    /// REQ-WIRE-040/041/060: the builder reproduces the hand-written base frame of
    /// docs/background/wire-format.md §2.3 byte for byte (into a 0xa5-filled buffer).
    // verifies: REQ-WIRE-040
    #[test]
    fn builds_base_frame() {
        let mut buf = [0xa5u8; 100];
        let mut b = FrameBuilder::new(&mut buf).unwrap();
        b.push(Command::Brd, 1, Address::broadcast(0), &[0, 0])
            .unwrap();
        let s = b
            .push_zeroed(Command::Frmw, 2, Address::configured(0x1001, 0x0910), 8)
            .unwrap();
        assert_eq!(s.offset(), 30);
        assert_eq!(b.datagram_count(), 2);
        let n = b.finish().unwrap();
        assert_eq!(n, 60);
        let expected: [u8; 60] = [
            0xff, 0xff, 0xff, 0xff, 0xff, 0xff, // dst
            0x10, 0x10, 0x10, 0x10, 0x10, 0x10, // src
            0x88, 0xa4, // EtherType
            0x22, 0x10, // len 34, type 1
            0x07, 0x01, 0x00, 0x00, 0x00, 0x00, 0x02, 0x80, 0x00, 0x00, // BRD, M=1
            0x00, 0x00, 0x00, 0x00, // data, WKC
            0x0e, 0x02, 0x01, 0x10, 0x10, 0x09, 0x08, 0x00, 0x00, 0x00, // FRMW
            0, 0, 0, 0, 0, 0, 0, 0, 0x00, 0x00, // data, WKC
            0, 0, 0, 0, 0, 0, 0, 0, 0, 0, // padding
        ];
        assert_eq!(buf[..60], expected);
        assert_eq!(buf[60], 0xa5, "nothing written past the frame");
    }

    /// REQ-WIRE-040: a push that does not fit changes nothing; capacity is the buffer and
    /// 1498 EtherCAT bytes.
    // verifies: REQ-WIRE-040
    #[test]
    fn capacity() {
        let mut buf = [0u8; 64];
        let mut b = FrameBuilder::new(&mut buf).unwrap();
        // 64 - 14 - 2 = 48 bytes of room -> 36 data bytes
        assert_eq!(b.remaining_data_capacity(), 36);
        assert_eq!(
            b.push_zeroed(Command::Lrw, 0, Address::logical(0), 37),
            Err(Error::BufferFull)
        );
        assert!(b.is_empty());
        b.push_zeroed(Command::Lrw, 0, Address::logical(0), 36)
            .unwrap();
        assert_eq!(b.remaining_data_capacity(), 0);
        assert!(!b.fits(0));
        assert_eq!(
            b.push(Command::Nop, 0, Address::Raw(0), &[]),
            Err(Error::BufferFull)
        );
        assert_eq!(b.finish(), Ok(64));

        let mut big = [0u8; 2000];
        let mut b = FrameBuilder::new(&mut big).unwrap();
        assert_eq!(b.remaining_data_capacity(), 1486);
        b.push_zeroed(Command::Lrw, 0, Address::logical(0), 1486)
            .unwrap();
        assert_eq!(b.finish(), Ok(MAX_FRAME_LEN));

        let mut big = [0u8; 2000];
        let mut b = FrameBuilder::new(&mut big).unwrap();
        b.push_zeroed(Command::Lrw, 0, Address::logical(0), 1000)
            .unwrap();
        // 1498 - 1012 = 486 left -> 474 data
        assert_eq!(b.remaining_data_capacity(), 474);
        assert_eq!(
            b.push_zeroed(Command::Lrw, 0, Address::logical(0), 475),
            Err(Error::BufferFull)
        );
        let mut small = [0u8; 59];
        assert_eq!(FrameBuilder::new(&mut small).err(), Some(Error::BufferFull));
    }

    /// Each constructor's minimum buffer is accepted and one byte less refused: 60 bytes for
    /// an Ethernet frame (new and resume), the 2-byte header for a UDP payload.
    #[test]
    fn minimum_buffers() {
        let mut buf = [0u8; 60];
        let mut b = FrameBuilder::new(&mut buf).unwrap();
        b.push(Command::Nop, 0, Address::Raw(0), &[]).unwrap();
        assert_eq!(b.finish(), Ok(60));
        let mut again = buf;
        let b = FrameBuilder::resume(&mut again).unwrap();
        assert_eq!(b.datagram_count(), 1);
        assert_eq!(
            FrameBuilder::resume(&mut buf[..59]).err(),
            Some(Error::BufferFull)
        );
        let mut udp = [0u8; 2];
        assert!(FrameBuilder::new_udp_payload(&mut udp).is_ok());
        assert_eq!(
            FrameBuilder::new_udp_payload(&mut udp[..1]).err(),
            Some(Error::BufferFull)
        );
    }

    /// The MAC setters write the Ethernet header and leave a UDP payload alone; lengths and
    /// emptiness of the frame and of each slot follow the pushes.
    #[test]
    fn addresses_and_lengths() {
        let mut buf = [0u8; 100];
        let mut b = FrameBuilder::new(&mut buf).unwrap();
        assert!(b.is_empty());
        assert_eq!(b.len(), 16);
        b.set_destination([0x02, 1, 2, 3, 4, 5]);
        b.set_source([0x00, 9, 8, 7, 6, 5]);
        let full = b
            .push_zeroed(Command::Fprd, 0, Address::configured(1, 0x0900), 8)
            .unwrap();
        let empty = b.push(Command::Nop, 1, Address::Raw(0), &[]).unwrap();
        assert_eq!((full.len(), full.is_empty()), (8, false));
        assert_eq!((empty.len(), empty.is_empty()), (0, true));
        assert!(!b.is_empty());
        assert_eq!(b.len(), 16 + 20 + 12);
        b.finish().unwrap();
        assert_eq!(buf[..12], [0x02, 1, 2, 3, 4, 5, 0x00, 9, 8, 7, 6, 5]);

        let mut udp = [0x5au8; 20];
        let mut b = FrameBuilder::new_udp_payload(&mut udp).unwrap();
        b.set_destination([0; 6]);
        b.set_source([0; 6]);
        assert_eq!(b.len(), 2);
        assert_eq!(udp[2..], [0x5a; 18]);
    }

    /// The block fast path takes a block exactly as large as the room left (the buffer or the
    /// 1498 EtherCAT bytes, whichever is less) and refuses one byte more, a last datagram
    /// outside the block and an empty block, changing nothing then.
    #[test]
    fn append_block_limits() {
        let mut buf = [0u8; 60];
        let mut b = FrameBuilder::new(&mut buf).unwrap();
        let room = 60 - 16;
        assert_eq!(b.append_block(room + 1, 1, 0), None);
        assert_eq!(b.append_block(room, 1, room), None);
        assert_eq!(b.append_block(room, 0, 0), None);
        assert_eq!((b.len(), b.datagram_count()), (16, 0));
        assert_eq!(b.append_block(room, 2, 10).map(|blk| blk.len()), Some(room));
        assert_eq!((b.len(), b.datagram_count()), (60, 2));

        let mut big = [0u8; 2000];
        let mut b = FrameBuilder::new(&mut big).unwrap();
        assert_eq!(b.append_block(1499, 1, 0), None, "over 1498 EtherCAT bytes");
        assert_eq!(b.append_block(1498, 1, 0).map(|blk| blk.len()), Some(1498));
    }

    /// `put_small` writes the bytes `push` writes for the same datagram (every data length up
    /// to 8, with and without the M bit a following push would set) into a slice of exactly
    /// that size, and refuses a slice one byte short or more than 8 data bytes, leaving the
    /// slice as it was.
    #[test]
    fn put_small_equals_push() {
        let value = 0x0807_0605_0403_0201u64;
        let address = Address::configured(0x1001, 0x0910);
        for len in 0..=8u16 {
            for more in [false, true] {
                let mut frame = [0u8; 100];
                let mut b = FrameBuilder::new(&mut frame).unwrap();
                let data = &value.to_le_bytes()[..usize::from(len)];
                let s = b.push(Command::Frmw, 7, address, data).unwrap();
                let mut d = b.datagram_mut(s).unwrap();
                if more {
                    d.set_len_flags(d.len_flags() | dfield::MORE);
                }
                let want = &frame[16..16 + 12 + usize::from(len)];
                let mut out = [0xeeu8; 22];
                let total = 12 + usize::from(len);
                let put = |dst: &mut &mut [u8]| {
                    put_small(dst, Command::Frmw, 7, address, len, more, value)
                };
                let mut dst = &mut out[..total];
                assert!(put(&mut dst));
                assert!(dst.is_empty());
                assert_eq!(&out[..total], want, "len {len} more {more}");

                let mut short = [0xeeu8; 22];
                let mut dst = &mut short[..total - 1];
                assert!(!put(&mut dst));
                assert_eq!(dst.len(), total - 1);
                assert_eq!(short, [0xee; 22]);
            }
        }
        let mut out = [0u8; 40];
        let mut dst = &mut out[..];
        assert!(!put_small(
            &mut dst,
            Command::Frmw,
            7,
            address,
            9,
            false,
            value
        ));
        assert_eq!(dst.len(), 40);
    }

    #[test]
    fn rejects_bad_input() {
        let mut buf = [0u8; 1600];
        let mut b = FrameBuilder::new(&mut buf).unwrap();
        assert_eq!(
            b.push(Command::Fprd, 0, Address::position(0, 0), &[0; 2]),
            Err(Error::AddressMismatch)
        );
        assert_eq!(
            b.push(Command::Lwr, 0, Address::logical(0), &[0; 1487]),
            Err(Error::DatagramTooLong { len: 1487 })
        );
        assert!(b.is_empty());
        assert_eq!(b.finish(), Err(Error::NoDatagram));
    }

    /// Slots, auto index, push_repr, resume, UDP payload.
    #[test]
    fn slots_and_resume() {
        let mut buf = [0u8; 200];
        {
            let mut b = FrameBuilder::new(&mut buf).unwrap();
            b.set_next_index(250);
            let s1 = b
                .push_auto(Command::Fprd, Address::configured(0x1001, 0x0900), &[0; 4])
                .unwrap();
            let s2 = b
                .push_auto(Command::Brd, Address::broadcast(0x0130), &[0; 2])
                .unwrap();
            assert_eq!((s1.index(), s2.index(), b.next_index()), (250, 251, 252));
            b.data_mut(s1).unwrap().copy_from_slice(&[1, 2, 3, 4]);
            b.datagram_mut(s2).unwrap().set_wkc(7);
            let foreign = DatagramSlot {
                offset: 17,
                len: 4,
                index: 0,
            };
            assert_eq!(b.data_mut(foreign).err(), Some(Error::InvalidSlot));
            assert_eq!(b.finish(), Ok(60));
        }
        {
            let mut b = FrameBuilder::resume(&mut buf[..]).unwrap();
            assert_eq!(b.datagram_count(), 2);
            let repr = DatagramRepr {
                command: Command::Lrw,
                index: 9,
                address: Address::logical(0x0001_0000),
                len: 3,
                circulating: true,
                irq: 0x55,
                wkc: 3,
            };
            b.push_repr(&repr, &[9, 8, 7]).unwrap();
            b.finish().unwrap();
        }
        let eth = EthernetFrame::new_checked(&buf[..]).unwrap();
        let f = eth.ecat_frame().unwrap();
        let ds: std::vec::Vec<_> = f.iter().map(|d| d.unwrap()).collect();
        assert_eq!(ds.len(), 3);
        assert_eq!(ds[0].data(), &[1, 2, 3, 4]);
        assert_eq!(ds[1].wkc(), 7);
        assert!(ds[0].more() && ds[1].more() && !ds[2].more());
        let r = DatagramRepr::parse(&ds[2]).unwrap();
        assert_eq!((r.index, r.circulating, r.irq, r.wkc), (9, true, 0x55, 3));

        let mut udp = [0u8; 40];
        let mut b = FrameBuilder::new_udp_payload(&mut udp).unwrap();
        b.push(Command::Aprd, 0, Address::position(1, 0x10), &[0; 2])
            .unwrap();
        let n = b.finish().unwrap();
        assert_eq!(n, 16);
        let f = EcatFrame::new_checked(&udp[..n]).unwrap();
        assert_eq!(f.datagram_count(), Ok(1));
    }
}
