//! The EtherCAT header and the datagram walk. Works on the Ethernet payload or on the payload of
//! a UDP datagram to port 0x88A4 alike (REQ-WIRE-003).
//!
//! ```text
//! off size field
//!  0   2   LE u16: length (bits 0..10) | reserved (bit 11) | type (bits 12..15)
//!  2  len  datagrams, walked by their M bits
//! 2+len .. padding (ignored)
//! ```
//!
//! Wireshark finds the end of the datagram list by M bits only and merely displays the header
//! length. We walk the M bits *and* require the walk to end exactly at the header length
//! (REQ-WIRE-015), so a frame whose two descriptions disagree is rejected with a typed error.

use super::datagram::field as dfield;
use super::key::HeaderKey;
use super::{get_u16_le, put, Datagram, Error, Result, MAX_DATAGRAM_DATA, MAX_ECAT_PAYLOAD};

// implements: REQ-WIRE-005
/// Byte layout of the EtherCAT header.
pub(crate) mod field {
    use core::ops::Range;
    /// The length/reserved/type word.
    pub const HEADER: Range<usize> = 0..2;
    /// First datagram byte.
    pub const DATAGRAMS: usize = HEADER.end;
    /// Header length (2).
    pub const HEADER_LEN: usize = DATAGRAMS;
    /// Length bits.
    pub const LEN_MASK: u16 = 0x07FF;
    /// Reserved bit 11.
    pub const RESERVED: u16 = 0x0800;
    /// Type shift (bits 12..15).
    pub const TYPE_SHIFT: u32 = 12;
}

/// EtherCAT header length.
pub const ECAT_HEADER_LEN: usize = field::HEADER_LEN;

/// The 4-bit EtherCAT frame type (Wireshark `EthercatFrameTypes`). Only [`FrameType::Dlpdu`]
/// is processed by ESCs and by this codec; the others are reported by
/// [`Error::NotDlpdu`]. REQ-WIRE-014
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum FrameType {
    /// 1: EtherCAT commands (datagrams).
    Dlpdu,
    /// 2: ADS.
    Ads,
    /// 3: RAW-IO.
    RawIo,
    /// 4: network variables.
    Nv,
    /// 5: mailbox gateway.
    Mailbox,
    /// Any other value (0, 6..15).
    Other(u8),
}

impl FrameType {
    /// Decodes the 4-bit type.
    pub const fn from_u8(t: u8) -> FrameType {
        match t {
            1 => FrameType::Dlpdu,
            2 => FrameType::Ads,
            3 => FrameType::RawIo,
            4 => FrameType::Nv,
            5 => FrameType::Mailbox,
            other => FrameType::Other(other),
        }
    }
    /// The 4-bit value.
    pub const fn to_u8(self) -> u8 {
        match self {
            FrameType::Dlpdu => 1,
            FrameType::Ads => 2,
            FrameType::RawIo => 3,
            FrameType::Nv => 4,
            FrameType::Mailbox => 5,
            FrameType::Other(t) => t,
        }
    }
}

/// A zero-copy view of an EtherCAT header followed by its datagrams (and possibly padding).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EcatFrame<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> EcatFrame<T> {
    /// Wraps `buffer` without checks. Accessors and iterators stay panic-free, and the
    /// iterators still report every error `new_checked` would.
    pub const fn new_unchecked(buffer: T) -> EcatFrame<T> {
        EcatFrame { buffer }
    }

    /// Wraps `buffer` after [`EcatFrame::check_len`]: header checks plus a full datagram walk.
    /// After `Ok`, [`EcatFrame::iter`] yields only `Ok` items.
    pub fn new_checked(buffer: T) -> Result<EcatFrame<T>> {
        let f = EcatFrame::new_unchecked(buffer);
        f.check_len()?;
        Ok(f)
    }

    /// Validates the frame. In this order (first failure wins), REQ-WIRE-010..017:
    /// 1. 2 header bytes present, else [`Error::Truncated`];
    /// 2. type is 1, else [`Error::NotDlpdu`];
    /// 3. reserved bit 11 clear, else [`Error::HeaderReservedBit`];
    /// 4. length ≤ 1498 (so header + datagrams ≤ 1500), else [`Error::FrameTooLong`];
    /// 5. the buffer holds 2 + length bytes, else [`Error::Truncated`];
    /// 6. length > 0, else [`Error::NoDatagram`];
    /// 7. per datagram, in walk order: its 10-byte header lies inside the header length
    ///    ([`Error::LengthMismatch`]); data length ≤ 1486 ([`Error::DatagramTooLong`]); the whole
    ///    datagram lies inside the header length ([`Error::LengthMismatch`]); command ≤ 14
    ///    ([`Error::UnknownCommand`]); reserved bits clear ([`Error::DatagramReservedBits`]);
    /// 8. after a datagram with M set the header length must leave room for more
    ///    ([`Error::MoreBitOnLast`]); after one with M clear it must be used up
    ///    ([`Error::TrailingData`]).
    ///
    /// Invalidated by [`EcatFrame::set_header`] and by any datagram length/flag setter.
    pub fn check_len(&self) -> Result<()> {
        // Valid frames (the common case) in one tight pass; anything else goes through the
        // walk below, which reports the exact first error.
        if valid_fast(self.buffer.as_ref()).is_some() {
            return Ok(());
        }
        // The walk alone (spans, no views): the same checks, in the same order, as `iter`.
        let mut it = self.iter();
        while let Some(span) = it.next_span() {
            span?;
        }
        Ok(())
    }

    /// Unwraps the buffer.
    pub fn into_inner(self) -> T {
        self.buffer
    }

    /// The raw header word.
    #[inline]
    pub fn header(&self) -> u16 {
        get_u16_le(self.buffer.as_ref(), field::HEADER.start)
    }

    /// Length of all datagrams in bytes (11 bits; header and padding excluded).
    #[inline]
    pub fn length(&self) -> u16 {
        self.header() & field::LEN_MASK
    }

    /// Reserved bit 11.
    #[inline]
    pub fn reserved(&self) -> bool {
        self.header() & field::RESERVED != 0
    }

    /// The 4-bit type (1 = DLPDU).
    #[inline]
    pub fn frame_type(&self) -> u8 {
        let [_, hi] = self.header().to_le_bytes();
        hi >> 4
    }

    /// The type as an enum.
    #[inline]
    pub fn frame_type_kind(&self) -> FrameType {
        FrameType::from_u8(self.frame_type())
    }

    /// 2 + length: the EtherCAT bytes without padding.
    #[inline]
    pub fn ecat_len(&self) -> usize {
        usize::from(self.length()).wrapping_add(field::HEADER_LEN)
    }

    /// The datagram bytes as the header length delimits them (empty if the buffer is shorter).
    #[inline]
    pub fn datagrams_bytes(&self) -> &[u8] {
        self.buffer
            .as_ref()
            .get(field::DATAGRAMS..self.ecat_len())
            .unwrap_or(&[])
    }

    /// Bytes after the header length (Ethernet padding), empty if none.
    #[inline]
    pub fn padding(&self) -> &[u8] {
        self.buffer.as_ref().get(self.ecat_len()..).unwrap_or(&[])
    }

    // implements: REQ-WIRE-021, REQ-WIRE-022
    /// Iterates over the datagrams, validating as [`EcatFrame::check_len`] describes. After
    /// the first `Err` the iterator ends. Every yielded view spans exactly one datagram inside
    /// the buffer.
    pub fn iter(&self) -> Datagrams<'_> {
        Datagrams::new(self.buffer.as_ref())
    }

    /// The datagrams of a frame that passed [`EcatFrame::check_len`], each split into header,
    /// data and WKC, without validating again (crate-internal: one validating walk per
    /// received frame). On such a frame it yields exactly the datagrams of
    /// [`EcatFrame::iter`]; on any other buffer it stops at the first datagram that does not
    /// fit (never panics) and reports nothing.
    #[inline]
    pub(crate) fn iter_valid(&self) -> ValidDatagrams<'_> {
        ValidDatagrams {
            rest: self.datagrams_bytes(),
            done: false,
        }
    }

    /// Like [`EcatFrame::iter`] but yields `(start, len)` of each datagram, `start` counted
    /// from the first byte of this view's buffer (the EtherCAT header). With these a caller can
    /// build `Datagram<&mut [u8]>` over `buf[start..start + len]` itself.
    pub fn datagram_offsets(&self) -> DatagramOffsets<'_> {
        DatagramOffsets { inner: self.iter() }
    }

    /// Number of datagrams, or the first error.
    pub fn datagram_count(&self) -> Result<usize> {
        let mut n = 0usize;
        for d in self.iter() {
            d?;
            n = n.wrapping_add(1);
        }
        Ok(n)
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> EcatFrame<T> {
    /// Writes the header word: `length` (11 bits), reserved 0, `frame_type` (4 bits).
    pub fn set_header(&mut self, length: u16, frame_type: u8) {
        let v = (length & field::LEN_MASK) | (u16::from(frame_type & 0x0F) << field::TYPE_SHIFT);
        put(self.buffer.as_mut(), field::HEADER.start, &v.to_le_bytes());
    }

    /// Writes the raw header word (reserved bit included).
    pub fn set_header_raw(&mut self, v: u16) {
        put(self.buffer.as_mut(), field::HEADER.start, &v.to_le_bytes());
    }

    /// Mutable walk: yields `Datagram<&mut [u8]>` views, one per datagram, each spanning exactly
    /// that datagram, so a caller (an emulated ESC) can update ADP, WKC, data, IRQ and the C bit
    /// in place while walking. Validation is the same as [`EcatFrame::iter`]; the walk reads
    /// each datagram's length and M bit *before* yielding it, so changing them through the view
    /// does not derail the walk (but does invalidate the frame for later parses).
    ///
    /// ```
    /// use ecdc_core::wire::{Address, Command, EthernetFrame, FrameBuilder};
    /// let mut buf = [0u8; 64];
    /// let mut b = FrameBuilder::new(&mut buf).unwrap();
    /// b.push(Command::Brd, 7, Address::broadcast(0x0130), &[0, 0]).unwrap();
    /// let n = b.finish().unwrap();
    /// // What one emulated ESC does to a passing frame:
    /// let mut eth = EthernetFrame::new_checked(&mut buf[..n]).unwrap();
    /// eth.mark_processed_by_slave();
    /// let mut frame = eth.ecat_frame_mut().unwrap();
    /// for d in frame.iter_mut() {
    ///     let mut d = d.unwrap();
    ///     let cmd = d.command().unwrap();
    ///     if cmd.increments_adp() {
    ///         d.set_adp(d.adp().wrapping_add(1));
    ///     }
    ///     d.data_mut().copy_from_slice(&[0x08, 0x00]); // BRD: data_in OR register
    ///     d.add_wkc(cmd.wkc_increment(true, false));
    /// }
    /// let eth = EthernetFrame::new_checked(&buf[..n]).unwrap();
    /// assert!(eth.processed_by_slave());
    /// let d = eth.into_ecat_frame().unwrap().into_iter().next().unwrap().unwrap();
    /// assert_eq!((d.adp(), d.wkc(), d.data()), (1, 1, &[0x08, 0x00][..]));
    /// ```
    pub fn iter_mut(&mut self) -> DatagramsMut<'_> {
        let buf = self.buffer.as_mut();
        let end = usize::from(get_u16_le(buf, 0) & field::LEN_MASK).wrapping_add(field::HEADER_LEN);
        match Walk::start(buf) {
            Ok(walk) => DatagramsMut {
                rest: buf.get_mut(field::DATAGRAMS..end).unwrap_or(&mut []),
                walk,
                first_error: None,
            },
            Err(e) => DatagramsMut {
                rest: &mut [],
                walk: Walk::finished(),
                first_error: Some(e),
            },
        }
    }
}

/// Iterating a frame view over a borrowed slice yields datagrams borrowing that slice (not the
/// view), so they outlive a temporary view.
impl<'a> IntoIterator for EcatFrame<&'a [u8]> {
    type Item = Result<Datagram<&'a [u8]>>;
    type IntoIter = Datagrams<'a>;

    fn into_iter(self) -> Datagrams<'a> {
        Datagrams::new(self.buffer)
    }
}

/// Header line then one indented line per datagram; an invalid frame prints the datagrams
/// before the error and then `(error: …)`. Never panics.
impl<T: AsRef<[u8]>> core::fmt::Display for EcatFrame<T> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "EtherCAT len {} type {}{}",
            self.length(),
            self.frame_type(),
            if self.reserved() { " R" } else { "" }
        )?;
        for d in self.iter() {
            match d {
                Ok(d) => write!(f, "\n  {d}")?,
                Err(e) => write!(f, "\n  (error: {e})")?,
            }
        }
        Ok(())
    }
}

/// `Some(())` iff [`EcatFrame::check_len`]'s walk accepts `buf`: the header checks of
/// [`Walk::start`], then per datagram a complete 10-byte header, data length ≤ 1486, the whole
/// datagram inside the header length, a known command and clear reserved bits, and the last
/// datagram (M clear) ending exactly at the header length. `None` for any failure (the caller
/// then runs the full walk for the exact error).
#[inline]
fn valid_fast(buf: &[u8]) -> Option<()> {
    valid_fast_each(buf, |_| true)
}

/// [`valid_fast`] that also hands each datagram's 10 header bytes, in walk order, to `f`, and
/// fails as soon as `f` returns false. The checks are `valid_fast`'s (it is this function with
/// an `f` that always agrees), so `Some(())` means [`EcatFrame::check_len`] accepts `buf` and
/// `f` saw the headers of exactly the datagrams [`EcatFrame::iter_valid`] yields.
#[inline]
pub(crate) fn valid_fast_each(
    buf: &[u8],
    mut f: impl FnMut(&[u8; dfield::HEADER_LEN]) -> bool,
) -> Option<()> {
    let walk = Walk::start(buf).ok()?;
    let end = usize::from(walk.length).wrapping_add(field::HEADER_LEN);
    let mut rest = buf.get(field::DATAGRAMS..end)?;
    loop {
        let h = rest.first_chunk::<{ dfield::HEADER_LEN }>()?;
        let [cmd, .., l0, l1, _, _] = *h;
        let lf = u16::from_le_bytes([l0, l1]);
        let len = usize::from(lf & dfield::LEN_MASK);
        if len > MAX_DATAGRAM_DATA
            || usize::from(cmd) >= super::Command::ALL.len()
            || lf & dfield::RESERVED_MASK != 0
            || !f(h)
        {
            return None;
        }
        // `None` when the datagram runs past the header length.
        rest = rest.get(len.wrapping_add(dfield::MIN_LEN)..)?;
        if lf & dfield::MORE == 0 {
            return rest.is_empty().then_some(());
        }
    }
}

/// What one datagram of a frame must look like for [`matches_pattern`]: its first 8 header
/// bytes (command, index, ADP, ADO, length word) read as a little-endian `u64`, compared where
/// `mask` is set. The length word (bits 48..63) is always compared in full: `len` with C and
/// the reserved bits clear, and M set on every datagram but the last.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct HeaderPattern {
    /// Command, index, ADP and ADO; the length word is ignored (`len` and M replace it).
    pub want: HeaderKey,
    /// Which of bits 0..47 are compared (ADP is left out where slaves change it).
    pub mask: u64,
    /// Data length.
    pub len: u16,
}

impl HeaderPattern {
    /// Whether a datagram's first 8 header bytes `head` match: the masked fields equal, the
    /// length word exactly `len` with M as `more` (C and reserved bits clear), the length
    /// within [`MAX_DATAGRAM_DATA`] and the command a known one.
    #[inline]
    pub(crate) fn matches(&self, head: &[u8; dfield::LEN_FLAGS.end], more: bool) -> bool {
        let want = self.want.with_len(self.len).with_more(more);
        let [cmd, ..] = *head;
        HeaderKey::of(head).agrees(want, self.mask & !HeaderKey::LEN_WORD | HeaderKey::LEN_WORD)
            && usize::from(self.len) <= MAX_DATAGRAM_DATA
            && usize::from(cmd) < super::Command::ALL.len()
    }
}

/// True iff `buf` (EtherCAT header + datagrams) holds exactly `n` ≥ 1 datagrams, datagram `i`
/// matching `pattern(i)` ([`HeaderPattern`]), and [`EcatFrame::check_len`] accepts it: a
/// DLPDU header, reserved bit clear, length ≤ 1498 inside `buf`, every datagram a known
/// command with data ≤ 1486 bytes, and the last ending exactly at the header length. The
/// datagrams are then those [`EcatFrame::iter_valid`] yields, at the offsets their lengths give.
///
/// This is [`valid_fast_each`] for a caller who knows the layout it sent: one 8-byte compare
/// per datagram instead of a field-by-field walk. False also when `pattern` returns `None`.
#[inline]
pub(crate) fn matches_pattern(
    buf: &[u8],
    n: usize,
    mut pattern: impl FnMut(usize) -> Option<HeaderPattern>,
) -> bool {
    let Some(&[h0, h1]) = buf.first_chunk::<{ field::HEADER_LEN }>() else {
        return false;
    };
    let h = u16::from_le_bytes([h0, h1]);
    let length = usize::from(h & field::LEN_MASK);
    // DLPDU type, reserved bit clear (REQ-WIRE-012..014), the whole region present.
    if h & !field::LEN_MASK != u16::from(FrameType::Dlpdu.to_u8()) << field::TYPE_SHIFT
        || length > MAX_ECAT_PAYLOAD
        || n == 0
    {
        return false;
    }
    let Some(region) = buf.get(field::DATAGRAMS..length.wrapping_add(field::HEADER_LEN)) else {
        return false;
    };
    let mut at = 0usize;
    for i in 0..n {
        let Some(p) = pattern(i) else {
            return false;
        };
        let head = region
            .get(at..)
            .and_then(|r| r.first_chunk::<{ dfield::LEN_FLAGS.end }>());
        if !head.is_some_and(|h| p.matches(h, i.wrapping_add(1) < n)) {
            return false;
        }
        at = at
            .wrapping_add(usize::from(p.len))
            .wrapping_add(dfield::MIN_LEN);
    }
    at == region.len()
}

/// The state of an M-bit walk over a datagram region of exactly `length` bytes.
#[derive(Debug, Clone, Copy)]
struct Walk {
    length: u16,
    walked: u16,
    more: bool,
    done: bool,
}

impl Walk {
    /// Header checks 1..6 of [`EcatFrame::check_len`].
    fn start(buf: &[u8]) -> Result<Walk> {
        let Some(&[a, b]) = buf.get(field::HEADER) else {
            return Err(Error::Truncated);
        };
        let h = u16::from_le_bytes([a, b]);
        let frame_type = b >> 4;
        // REQ-WIRE-014: only DLPDU frames carry datagrams; others are reported as they are.
        if frame_type != FrameType::Dlpdu.to_u8() {
            return Err(Error::NotDlpdu { frame_type });
        }
        // REQ-WIRE-013: reserved bit set is an error (SOEM masks 0x0FFF and would misread it).
        if h & field::RESERVED != 0 {
            return Err(Error::HeaderReservedBit);
        }
        let length = h & field::LEN_MASK;
        let total = usize::from(length).wrapping_add(field::HEADER_LEN);
        // REQ-WIRE-012
        if usize::from(length) > MAX_ECAT_PAYLOAD {
            return Err(Error::FrameTooLong {
                len: usize::from(length),
            });
        }
        // REQ-WIRE-010: a cut capture.
        if buf.len() < total {
            return Err(Error::Truncated);
        }
        if length == 0 {
            return Err(Error::NoDatagram);
        }
        Ok(Walk {
            length,
            walked: 0,
            more: true,
            done: false,
        })
    }

    const fn finished() -> Walk {
        Walk {
            length: 0,
            walked: 0,
            more: false,
            done: true,
        }
    }

    /// One step over `rest` (the region from offset `walked`). Returns the datagram's offset in
    /// the region and its length; fuses after `None` or `Err`.
    fn step(&mut self, rest: &[u8]) -> Option<Result<(usize, usize)>> {
        if self.done {
            return None;
        }
        let r = self.step_inner(rest);
        if !matches!(r, Ok(Some(_))) {
            self.done = true;
        }
        r.transpose()
    }

    /// The common case of [`Walk::step`] in one pass: a datagram follows (M set), and it is
    /// complete and valid (every check of `step_inner` passes). Returns `None`, with the walk
    /// unchanged, for anything else, which `step` then handles (and reports) exactly.
    #[inline]
    fn step_valid(&mut self, rest: &[u8]) -> Option<(usize, usize)> {
        if self.done || !self.more {
            return None;
        }
        let h = rest.first_chunk::<{ dfield::HEADER_LEN }>()?;
        let lf = u16::from_le_bytes([h[6], h[7]]);
        let len = usize::from(lf & dfield::LEN_MASK);
        let total = len.wrapping_add(dfield::MIN_LEN);
        let ok = len <= MAX_DATAGRAM_DATA
            && total <= rest.len()
            && usize::from(h[0]) < super::Command::ALL.len()
            && lf & dfield::RESERVED_MASK == 0;
        if !ok {
            return None;
        }
        let start = usize::from(self.walked);
        // total ≤ rest.len() ≤ length − walked ≤ 1498.
        let total16 = u16::try_from(total).ok()?;
        self.walked = self.walked.checked_add(total16)?;
        self.more = lf & dfield::MORE != 0;
        Some((start, total))
    }

    fn step_inner(&mut self, rest: &[u8]) -> Result<Option<(usize, usize)>> {
        // REQ-WIRE-015: the walk must end exactly at the header length.
        if !self.more {
            return if self.walked < self.length {
                Err(Error::TrailingData)
            } else {
                Ok(None)
            };
        }
        if rest.is_empty() {
            return Err(if self.walked == 0 {
                Error::NoDatagram
            } else {
                Error::MoreBitOnLast
            });
        }
        let mismatch = |need: usize| Error::LengthMismatch {
            header: self.length,
            walked: u16::try_from(usize::from(self.walked).saturating_add(need))
                .unwrap_or(u16::MAX),
        };
        if rest.len() < dfield::HEADER_LEN {
            return Err(mismatch(dfield::MIN_LEN));
        }
        let d = Datagram::new_unchecked(rest);
        let len = d.data_len();
        // REQ-WIRE-011
        if usize::from(len) > MAX_DATAGRAM_DATA {
            return Err(Error::DatagramTooLong { len });
        }
        let total = d.total_len();
        if rest.len() < total {
            return Err(mismatch(total));
        }
        // REQ-WIRE-013, REQ-WIRE-017
        d.check_fields()?;
        let start = usize::from(self.walked);
        // total ≤ rest.len() ≤ length − walked, so this cannot exceed `length`.
        let total16 = u16::try_from(total).map_err(|_| mismatch(total))?;
        self.walked = self.walked.checked_add(total16).ok_or(mismatch(total))?;
        self.more = d.more();
        Ok(Some((start, total)))
    }
}

/// Iterator over a frame's datagrams; see [`EcatFrame::iter`].
#[derive(Debug, Clone)]
pub struct Datagrams<'a> {
    region: &'a [u8],
    walk: Walk,
    first_error: Option<Error>,
}

impl<'a> Datagrams<'a> {
    /// Walk over the EtherCAT payload `buf` (header first).
    fn new(buf: &'a [u8]) -> Datagrams<'a> {
        match Walk::start(buf) {
            Ok(walk) => {
                let end = usize::from(walk.length).wrapping_add(field::HEADER_LEN);
                Datagrams {
                    region: buf.get(field::DATAGRAMS..end).unwrap_or(&[]),
                    walk,
                    first_error: None,
                }
            }
            Err(e) => Datagrams {
                region: &[],
                walk: Walk::finished(),
                first_error: Some(e),
            },
        }
    }

    #[inline]
    fn next_span(&mut self) -> Option<Result<(usize, usize)>> {
        if let Some(e) = self.first_error.take() {
            return Some(Err(e));
        }
        let rest = self
            .region
            .get(usize::from(self.walk.walked)..)
            .unwrap_or(&[]);
        if let Some(span) = self.walk.step_valid(rest) {
            return Some(Ok(span));
        }
        self.walk.step(rest)
    }
}

impl<'a> Iterator for Datagrams<'a> {
    type Item = Result<Datagram<&'a [u8]>>;

    #[inline]
    fn next(&mut self) -> Option<Self::Item> {
        let region = self.region;
        Some(self.next_span()?.and_then(|(start, len)| {
            region
                .get(start..start.wrapping_add(len))
                .map(Datagram::new_unchecked)
                .ok_or(Error::Truncated)
        }))
    }
}

impl core::iter::FusedIterator for Datagrams<'_> {}

/// One datagram of a validated frame: its header bytes, data and WKC.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct RawDatagram<'a> {
    /// The 10 header bytes (command, index, address, length and flags, IRQ).
    pub(crate) header: &'a [u8; dfield::HEADER_LEN],
    /// The data bytes.
    pub(crate) data: &'a [u8],
    /// The working counter.
    pub(crate) wkc: u16,
}

impl RawDatagram<'_> {
    /// The C bit (circulating), as [`Datagram::circulating`].
    #[inline]
    pub(crate) fn circulating(&self) -> bool {
        header_circulating(self.header)
    }
}

/// The C bit (circulating) of a datagram's 10 header bytes, as [`Datagram::circulating`].
#[inline]
pub(crate) fn header_circulating(h: &[u8; dfield::HEADER_LEN]) -> bool {
    let [.., l1, _, _] = *h;
    u16::from_le_bytes([0, l1]) & dfield::CIRCULATING != 0
}

/// Iterator over a validated frame's datagrams; see [`EcatFrame::iter_valid`].
#[derive(Debug, Clone)]
pub(crate) struct ValidDatagrams<'a> {
    rest: &'a [u8],
    done: bool,
}

impl<'a> Iterator for ValidDatagrams<'a> {
    type Item = RawDatagram<'a>;

    #[inline]
    fn next(&mut self) -> Option<RawDatagram<'a>> {
        if self.done {
            return None;
        }
        let (header, tail) = self.rest.split_first_chunk::<{ dfield::HEADER_LEN }>()?;
        let [.., l0, l1, _, _] = *header;
        let lf = u16::from_le_bytes([l0, l1]);
        let (data, tail) = tail.split_at_checked(usize::from(lf & dfield::LEN_MASK))?;
        let (wkc, tail) = tail.split_first_chunk::<{ dfield::WKC_LEN }>()?;
        self.rest = tail;
        self.done = lf & dfield::MORE == 0;
        Some(RawDatagram {
            header,
            data,
            wkc: u16::from_le_bytes(*wkc),
        })
    }
}

/// Iterator over `(start, len)` of each datagram; see [`EcatFrame::datagram_offsets`].
#[derive(Debug, Clone)]
pub struct DatagramOffsets<'a> {
    inner: Datagrams<'a>,
}

impl Iterator for DatagramOffsets<'_> {
    type Item = Result<(usize, usize)>;

    fn next(&mut self) -> Option<Self::Item> {
        Some(
            self.inner
                .next_span()?
                .map(|(s, l)| (s.wrapping_add(field::DATAGRAMS), l)),
        )
    }
}

impl core::iter::FusedIterator for DatagramOffsets<'_> {}

/// Mutable iterator over a frame's datagrams; see [`EcatFrame::iter_mut`].
#[derive(Debug)]
pub struct DatagramsMut<'a> {
    rest: &'a mut [u8],
    walk: Walk,
    first_error: Option<Error>,
}

impl<'a> Iterator for DatagramsMut<'a> {
    type Item = Result<Datagram<&'a mut [u8]>>;

    fn next(&mut self) -> Option<Self::Item> {
        if let Some(e) = self.first_error.take() {
            return Some(Err(e));
        }
        let step = self.walk.step(self.rest)?;
        Some(step.and_then(|(_, len)| {
            let rest = core::mem::take(&mut self.rest);
            let (head, tail) = rest.split_at_mut_checked(len).ok_or(Error::Truncated)?;
            self.rest = tail;
            Ok(Datagram::new_unchecked(head))
        }))
    }
}

impl core::iter::FusedIterator for DatagramsMut<'_> {}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::Command;
    use std::vec;
    use std::vec::Vec;

    /// A DLPDU whose header length covers exactly one zeroed LRD of each data length of
    /// `lens`, M set on all but the last (no padding).
    fn lrd_frame(lens: &[u16]) -> Vec<u8> {
        let total: u16 = lens.iter().map(|l| l + 12).sum();
        let mut x = vec![0u8; 2 + usize::from(total)];
        x[..2].copy_from_slice(&(total | 0x1000).to_le_bytes());
        let mut at = 2;
        for (i, &len) in lens.iter().enumerate() {
            let more = if i + 1 < lens.len() { 0x8000 } else { 0 };
            x[at] = Command::Lrd.code();
            x[at + 6..at + 8].copy_from_slice(&(len | more).to_le_bytes());
            at += 12 + usize::from(len);
        }
        x
    }

    /// The base frame of docs/background/wire-format.md §2.3 (EtherCAT part), written by hand:
    /// header len 34 type 1; BRD idx 1 ADP 0 ADO 0 len 2 M=1; FRMW idx 2 ADP 0x1001 ADO 0x0910
    /// len 8 M=0; 10 bytes of padding.
    fn base() -> Vec<u8> {
        let mut f = Vec::new();
        f.extend_from_slice(&[0x22, 0x10]); // length 34, type 1
        f.extend_from_slice(&[0x07, 0x01, 0x00, 0x00, 0x00, 0x00, 0x02, 0x80, 0x00, 0x00]);
        f.extend_from_slice(&[0x00, 0x00]); // data
        f.extend_from_slice(&[0x00, 0x00]); // WKC
        f.extend_from_slice(&[0x0e, 0x02, 0x01, 0x10, 0x10, 0x09, 0x08, 0x00, 0x00, 0x00]);
        f.extend_from_slice(&[0; 8]); // data
        f.extend_from_slice(&[0x00, 0x00]); // WKC
        f.extend_from_slice(&[0; 10]); // padding
        f
    }

    /// REQ-WIRE-015: the base frame walks to exactly the header length.
    // verifies: REQ-WIRE-015
    #[test]
    fn deconstruct() {
        let b = base();
        let f = EcatFrame::new_checked(&b[..]).unwrap();
        assert_eq!(f.length(), 34);
        assert_eq!(f.frame_type(), 1);
        assert!(!f.reserved());
        assert_eq!(f.padding().len(), 10);
        let ds: Vec<_> = f.iter().map(|d| d.unwrap()).collect();
        assert_eq!(ds.len(), 2);
        assert_eq!(ds[0].command(), Ok(Command::Brd));
        assert!(ds[0].more());
        assert_eq!(ds[1].command(), Ok(Command::Frmw));
        assert_eq!(ds[1].adp(), 0x1001);
        assert_eq!(ds[1].ado(), 0x0910);
        let offs: Vec<_> = f.datagram_offsets().map(|o| o.unwrap()).collect();
        assert_eq!(offs, [(2, 14), (16, 20)]);
        assert_eq!(f.datagram_count(), Ok(2));
    }

    /// The patterns of a valid frame's own datagrams (ADP compared or not).
    fn patterns(b: &[u8], with_adp: bool) -> Vec<HeaderPattern> {
        EcatFrame::new_checked(b)
            .unwrap()
            .iter()
            .map(|d| {
                let d = d.unwrap();
                let h = u64::from_le_bytes(d.header_bytes().unwrap()[..8].try_into().unwrap());
                HeaderPattern {
                    want: HeaderKey(h),
                    mask: if with_adp {
                        0xFFFF_FFFF_FFFF
                    } else {
                        0xFFFF_0000_FFFF
                    },
                    len: d.data_len(),
                }
            })
            .collect()
    }

    /// `matches_pattern` is sound (it accepts only what `check_len` accepts, with exactly the
    /// datagrams patterned) and exact (it accepts a frame with its own patterns; it refuses a
    /// wrong count, a changed compared field, a circulating or reserved bit): over the base
    /// frame and every single-byte change of it, and over padding, truncation and count.
    #[test]
    fn matches_pattern_sound_and_exact() {
        let b = base();
        for with_adp in [false, true] {
            let pats = patterns(&b, with_adp);
            let by = |i: usize| pats.get(i).copied();
            assert!(matches_pattern(&b, 2, by));
            assert!(matches_pattern(&b[..36], 2, by), "padding is not required");
            assert!(!matches_pattern(&b[..35], 2, by), "truncated");
            assert!(!matches_pattern(&b, 1, by) && !matches_pattern(&b, 3, by));
            assert!(!matches_pattern(&b, 0, by));
            let mut accepted = 0;
            for at in 0..b.len() {
                for x in [0x01u8, 0x02, 0x08, 0x10, 0x40, 0x80, 0xFF] {
                    let mut v = b.clone();
                    v[at] ^= x;
                    if !matches_pattern(&v, 2, by) {
                        continue;
                    }
                    accepted += 1;
                    let f = EcatFrame::new_checked(&v[..]).expect("sound: check_len accepts");
                    let ds: Vec<_> = f.iter().map(|d| d.unwrap()).collect();
                    assert_eq!(ds.len(), 2);
                    for (d, p) in ds.iter().zip(&pats) {
                        let h = d.header_bytes().unwrap();
                        assert_eq!(h[0], p.want.0 as u8, "command");
                        assert_eq!(h[1], (p.want.0 >> 8) as u8, "index");
                        assert_eq!(d.ado(), (p.want.0 >> 32) as u16, "ADO");
                        assert_eq!(d.data_len(), p.len);
                        assert!(!d.circulating());
                        if with_adp {
                            assert_eq!(d.adp(), (p.want.0 >> 16) as u16, "ADP");
                        }
                    }
                    // Only data, WKC, IRQ, padding (and ADP where not compared) may differ.
                    let in_header =
                        |o: usize| [2usize, 16].iter().any(|&s| (s..s + 8).contains(&o));
                    let adp = |o: usize| [4usize, 5, 18, 19].contains(&o);
                    assert!(
                        !in_header(at) || (!with_adp && adp(at)),
                        "byte {at} ^ {x:#x}"
                    );
                }
            }
            assert!(accepted > 50, "{accepted}");
            // Where the ADP is not compared, any ADP is accepted (slaves change it).
            for at in [4usize, 5, 18, 19] {
                let mut v = b.clone();
                v[at] ^= 0x5A;
                assert_eq!(matches_pattern(&v, 2, by), !with_adp, "ADP byte {at}");
            }
        }
    }

    /// `matches_pattern` at the EtherCAT length limit: a frame of exactly 1498 datagram bytes
    /// matches its patterns, one of 1499 does not even where the buffer holds it all; and a
    /// pattern that leaves the command out still refuses an unknown command code.
    #[test]
    fn matches_pattern_limits() {
        let frame = |lens: &[u16]| {
            let mut x = lrd_frame(lens);
            x.extend_from_slice(&[0; 8]);
            x
        };
        let pattern = |lens: &[u16], i: usize| {
            Some(HeaderPattern {
                want: HeaderKey::new(Command::Lrd, 0, 0, 0, 0),
                mask: 0xFFFF_FFFF_FFFF,
                len: *lens.get(i)?,
            })
        };
        let fits = [1486u16];
        assert!(matches_pattern(&frame(&fits), 1, |i| pattern(&fits, i)));
        let over = [1475u16, 0];
        assert!(!matches_pattern(&frame(&over), 2, |i| pattern(&over, i)));

        let unknown = [15u8, 0, 0, 0, 0, 0, 2, 0];
        let any_command = HeaderPattern {
            want: HeaderKey::new(Command::Lrd, 0, 0, 0, 0),
            mask: 0xFFFF_FFFF_FF00,
            len: 2,
        };
        assert_eq!(Command::ALL.len(), 15);
        assert!(!any_command.matches(&unknown, false));
        let mut known = unknown;
        known[0] = 14;
        assert!(any_command.matches(&known, false));
    }

    /// The walk's one-pass step takes every valid datagram that has a successor announced
    /// (both datagrams of the base frame) and returns what the full step returns, leaving the
    /// walk as the full step leaves it; on anything else it declines without changing the
    /// walk. Checked on the base frame and every single-byte change of its first 26 bytes.
    #[test]
    fn step_valid_agrees_with_step() {
        let fast_steps = |buf: &[u8]| -> usize {
            let Ok(mut w) = Walk::start(buf) else {
                return 0;
            };
            let end = 2 + usize::from(w.length);
            let region = buf.get(2..end.min(buf.len())).unwrap_or(&[]);
            let mut taken = 0;
            loop {
                let rest = region.get(usize::from(w.walked)..).unwrap_or(&[]);
                let before = w;
                let mut slow = w;
                let want = slow.step(rest);
                match w.step_valid(rest) {
                    Some(span) => {
                        assert_eq!(want, Some(Ok(span)));
                        assert_eq!((w.walked, w.more), (slow.walked, slow.more));
                        taken += 1;
                    }
                    None => {
                        assert_eq!(
                            (w.walked, w.more, w.done),
                            (before.walked, before.more, before.done)
                        );
                        return taken;
                    }
                }
            }
        };
        let b = base();
        assert_eq!(fast_steps(&b), 2);
        for at in 0..26 {
            for v in 0..=255u8 {
                let mut x = b.clone();
                x[at] = v;
                fast_steps(&x);
            }
        }
    }

    /// A datagram cut off by the header length reports how far the walk would have needed to
    /// go: the whole datagram once its length word is inside the region (10 bytes left), the
    /// minimum datagram before (8 bytes left).
    #[test]
    fn cut_datagram_reports_the_length_needed() {
        for (left, walked) in [(10u16, 14 + 20), (8, 14 + 12)] {
            let mut b = base();
            b[..2].copy_from_slice(&((14 + left) | 0x1000).to_le_bytes());
            assert_eq!(
                EcatFrame::new_checked(&b[..]).err(),
                Some(Error::LengthMismatch {
                    header: 14 + left,
                    walked
                }),
                "{left} bytes left"
            );
        }
    }

    fn err(b: &[u8]) -> Error {
        let e = EcatFrame::new_checked(b).unwrap_err();
        // iter on the unchecked view reports the same first error
        let it = EcatFrame::new_unchecked(b).iter().find_map(|d| d.err());
        assert_eq!(it, Some(e));
        e
    }

    /// REQ-WIRE-010..017: one hand-made corruption per error.
    // verifies: REQ-WIRE-010, REQ-WIRE-011, REQ-WIRE-012, REQ-WIRE-013, REQ-WIRE-014, REQ-WIRE-015, REQ-WIRE-016, REQ-WIRE-017
    #[test]
    fn negative() {
        assert_eq!(err(&[]), Error::Truncated);
        assert_eq!(err(&[0x22]), Error::Truncated);
        let b = base();
        // cut inside the header length
        assert_eq!(err(&b[..35]), Error::Truncated);
        // length 1499
        let mut x = vec![0u8; 1600];
        x[0] = 0xDB;
        x[1] = 0x15;
        assert_eq!(err(&x), Error::FrameTooLong { len: 1499 });
        // length 0
        assert_eq!(err(&[0x00, 0x10, 0, 0]), Error::NoDatagram);
        // One byte of the valid frame changed: (byte, new value, the error).
        let lm = |header, walked| Error::LengthMismatch { header, walked };
        let corruptions = [
            // type 5 (mailbox gateway)
            (1, 0x50, Error::NotDlpdu { frame_type: 5 }),
            // reserved bit 11
            (1, 0x18, Error::HeaderReservedBit),
            // header length 36 (2 more than the walk): M clear on FRMW -> trailing data
            (0, 36, Error::TrailingData),
            // header length 32: FRMW ends past it
            (0, 32, lm(32, 34)),
            // header length 14: BRD has M set but the length ends after it
            (0, 14, Error::MoreBitOnLast),
            // header length 20: second datagram header incomplete
            (0, 20, lm(20, 26)),
            // M clear on BRD while the header covers FRMW too
            (9, 0x00, Error::TrailingData),
            // M set on FRMW (last) -> region exhausted
            (23, 0x80, Error::MoreBitOnLast),
            // command 15 in the second datagram
            (16, 15, Error::UnknownCommand { code: 15 }),
            // reserved bit 13 of the second datagram
            (23, 0x20, Error::DatagramReservedBits),
        ];
        for (at, value, want) in corruptions {
            let mut x = b.clone();
            x[at] = value;
            assert_eq!(err(&x), want, "byte {at} = {value:#04x}");
        }
        // data length 1487 in a 1500-byte payload
        let mut x = vec![0u8; 1500];
        x[0] = 0xDA;
        x[1] = 0x15; // length 1498
        x[2] = 0x07;
        x[8] = 0xCF;
        x[9] = 0x05; // len 1487
        assert_eq!(err(&x), Error::DatagramTooLong { len: 1487 });
        // ...and 1486 + 12 = 1498 exactly fits
        x[8] = 0xCE;
        assert!(EcatFrame::new_checked(&x[..]).is_ok());
    }

    /// The iterator fuses after an error.
    /// The header setters: `set_header` keeps 11 bits of length and 4 of type with the
    /// reserved bit clear, `set_header_raw` writes the word as given.
    #[test]
    fn header_setters() {
        let mut b = [0xffu8; 2];
        let mut f = EcatFrame::new_unchecked(&mut b[..]);
        f.set_header(0xFFFF, 0xFF);
        assert_eq!(f.header(), 0xF7FF);
        f.set_header(14, 1);
        assert_eq!((f.header(), f.length(), f.frame_type()), (0x100E, 14, 1));
        assert!(!f.reserved());
        f.set_header_raw(0x0800 | 0x100E);
        assert_eq!(b, [0x0E, 0x18]);
    }

    #[test]
    fn fuses() {
        let mut x = base();
        x[16] = 15;
        let f = EcatFrame::new_unchecked(&x[..]);
        let mut it = f.iter();
        assert!(it.next().unwrap().is_ok());
        assert!(it.next().unwrap().is_err());
        assert!(it.next().is_none());
        assert!(it.next().is_none());
    }

    /// iter_mut: an emulated ESC increments ADP and WKC of each datagram in place.
    #[test]
    fn iter_mut_in_place() {
        let mut x = base();
        let mut f = EcatFrame::new_checked(&mut x[..]).unwrap();
        for d in f.iter_mut() {
            let mut d = d.unwrap();
            d.set_adp(d.adp().wrapping_add(1));
            d.add_wkc(1);
            d.data_mut().fill(0xAB);
            // changing the M bit through the view does not derail the walk
            d.set_more(false);
        }
        assert_eq!(&x[4..6], &[0x01, 0x00]); // BRD ADP 1
        assert_eq!(&x[12..16], &[0xAB, 0xAB, 0x01, 0x00]); // data, WKC 1
        assert_eq!(&x[34..36], &[0x01, 0x00]); // FRMW WKC 1
        assert_eq!(&x[18..20], &[0x02, 0x10]); // FRMW ADP 0x1002
    }

    /// REQ-WIRE-003: the same view works on a UDP payload (no Ethernet header in front).
    // verifies: REQ-WIRE-003
    #[test]
    fn udp_payload() {
        let b = base();
        let f = EcatFrame::new_checked(&b[..36]).unwrap();
        assert_eq!(f.datagram_count(), Ok(2));
        assert!(f.padding().is_empty());
    }

    /// The one-pass validation in `check_len` accepts exactly what the datagram walk accepts
    /// and otherwise reports the walk's first error: every single-byte change of the base frame
    /// (each of its 46 bytes set to each of 256 values), and every truncation.
    #[test]
    fn check_len_fast_path_agrees_with_walk() {
        let walk = |b: &[u8]| -> Result<()> {
            for d in EcatFrame::new_unchecked(b).iter() {
                d?;
            }
            Ok(())
        };
        let b = base();
        let mut accepted = 0usize;
        for at in 0..b.len() {
            for v in 0..=255u8 {
                let mut x = b.clone();
                x[at] = v;
                let f = EcatFrame::new_unchecked(&x[..]);
                let got = f.check_len();
                assert_eq!(got, walk(&x), "byte {at} = {v:#04x}");
                // The fast path itself, not only its fallback, accepts what the walk accepts.
                assert_eq!(
                    valid_fast(&x).is_some(),
                    got.is_ok(),
                    "byte {at} = {v:#04x}"
                );
                accepted += usize::from(got.is_ok());
                if got.is_ok() {
                    // The unvalidated split walk yields the same datagrams.
                    let split: Vec<_> = f
                        .iter_valid()
                        .map(|r| (r.header.to_vec(), r.data.to_vec(), r.wkc, r.circulating()))
                        .collect();
                    let walked: Vec<_> = f
                        .iter()
                        .map(|d| {
                            let d = d.unwrap();
                            let h = d.header_bytes().unwrap().to_vec();
                            (h, d.data().to_vec(), d.wkc(), d.circulating())
                        })
                        .collect();
                    assert_eq!(split, walked, "byte {at} = {v:#04x}");
                }
            }
        }
        assert!(
            accepted > 46 * 200,
            "most changes (data, WKC, padding) stay valid"
        );
        for n in 0..=b.len() {
            assert_eq!(
                EcatFrame::new_unchecked(&b[..n]).check_len(),
                walk(&b[..n]),
                "truncated to {n}"
            );
        }
        // One datagram of the largest data length, and one byte more.
        for (len, ok) in [(1486u16, true), (1487, false)] {
            let x = lrd_frame(&[len]);
            assert_eq!(valid_fast(&x).is_some(), ok, "{len}");
            assert_eq!(walk(&x).is_ok(), ok, "{len}");
        }
    }

    #[test]
    fn frame_type_enum() {
        for t in 0..16u8 {
            assert_eq!(FrameType::from_u8(t).to_u8(), t);
        }
        assert_eq!(FrameType::from_u8(1), FrameType::Dlpdu);
    }
}
