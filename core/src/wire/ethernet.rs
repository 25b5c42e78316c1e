//! Ethernet II header with at most one IEEE 802.1Q tag (REQ-WIRE-001, REQ-WIRE-002).
//!
//! ```text
//! untagged: dst(0..6) src(6..12) type(12..14)                         payload at 14
//! tagged:   dst(0..6) src(6..12) 0x8100(12..14) TCI(14..16) type(16..18) payload at 18
//! ```
//! EtherTypes are big-endian, unlike every EtherCAT field. ESCs accept a VLAN tag but do not
//! evaluate it, so the codec only skips it.

use super::{put, EcatFrame, Error, Result, ETHERTYPE_ETHERCAT, ETHERTYPE_VLAN, MAC_PROCESSED_BIT};

mod field {
    use core::ops::Range;
    pub const DESTINATION: Range<usize> = 0..6;
    pub const SOURCE: Range<usize> = 6..12;
    pub const ETHERTYPE: Range<usize> = 12..14;
    pub const VLAN_TCI: Range<usize> = 14..16;
    pub const INNER_ETHERTYPE: Range<usize> = 16..18;
    pub const HEADER_LEN: usize = ETHERTYPE.end;
    pub const TAGGED_HEADER_LEN: usize = INNER_ETHERTYPE.end;
}

/// Untagged Ethernet header length.
pub const HEADER_LEN: usize = field::HEADER_LEN;

/// A zero-copy view of an Ethernet II frame (FCS not included).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EthernetFrame<T: AsRef<[u8]>> {
    buffer: T,
}

fn be16(buf: &[u8], at: core::ops::Range<usize>) -> u16 {
    match buf.get(at) {
        Some(&[a, b]) => u16::from_be_bytes([a, b]),
        _ => 0,
    }
}

fn mac(buf: &[u8], at: core::ops::Range<usize>) -> [u8; 6] {
    match buf.get(at) {
        Some(&[a, b, c, d, e, f]) => [a, b, c, d, e, f],
        _ => [0; 6],
    }
}

impl<T: AsRef<[u8]>> EthernetFrame<T> {
    /// Wraps `buffer` without checks (accessors stay panic-free).
    pub const fn new_unchecked(buffer: T) -> EthernetFrame<T> {
        EthernetFrame { buffer }
    }

    /// Wraps `buffer` after [`EthernetFrame::check_len`].
    pub fn new_checked(buffer: T) -> Result<EthernetFrame<T>> {
        let f = EthernetFrame::new_unchecked(buffer);
        f.check_len()?;
        Ok(f)
    }

    /// [`Error::Truncated`] unless the (possibly tagged) header is complete. Frames shorter
    /// than 60 bytes are accepted: captures on the sending host and veth links are unpadded.
    /// Invalidated by [`EthernetFrame::set_outer_ethertype`].
    pub fn check_len(&self) -> Result<()> {
        if self.buffer.as_ref().len() < self.header_len() {
            return Err(Error::Truncated);
        }
        Ok(())
    }

    /// Unwraps the buffer.
    pub fn into_inner(self) -> T {
        self.buffer
    }

    /// Destination MAC.
    pub fn dst(&self) -> [u8; 6] {
        mac(self.buffer.as_ref(), field::DESTINATION)
    }

    /// Source MAC.
    pub fn src(&self) -> [u8; 6] {
        mac(self.buffer.as_ref(), field::SOURCE)
    }

    /// The EtherType at offset 12 (0x8100 for a tagged frame).
    pub fn outer_ethertype(&self) -> u16 {
        be16(self.buffer.as_ref(), field::ETHERTYPE)
    }

    /// True if one 802.1Q tag follows the source MAC.
    pub fn is_tagged(&self) -> bool {
        self.outer_ethertype() == ETHERTYPE_VLAN
    }

    /// The EtherType after at most one 802.1Q tag. A second tag shows up as 0x8100 here.
    pub fn ethertype(&self) -> u16 {
        if self.is_tagged() {
            be16(self.buffer.as_ref(), field::INNER_ETHERTYPE)
        } else {
            self.outer_ethertype()
        }
    }

    /// The 16-bit tag control information (PCP, DEI, VID) of an 802.1Q tag.
    pub fn vlan(&self) -> Option<u16> {
        if self.is_tagged() {
            Some(be16(self.buffer.as_ref(), field::VLAN_TCI))
        } else {
            None
        }
    }

    /// 14, or 18 with a tag.
    pub fn header_len(&self) -> usize {
        if self.is_tagged() {
            field::TAGGED_HEADER_LEN
        } else {
            field::HEADER_LEN
        }
    }

    /// Everything after the header (EtherCAT header, datagrams, padding). Empty before
    /// `check_len`.
    pub fn payload(&self) -> &[u8] {
        self.buffer.as_ref().get(self.header_len()..).unwrap_or(&[])
    }

    /// True if an ESC has forwarded this frame: bit 0x02 of the first source octet is set
    /// (the master's own MAC has it clear). REQ-WIRE-061
    pub fn processed_by_slave(&self) -> bool {
        self.src()[0] & MAC_PROCESSED_BIT != 0
    }

    /// Checks the EtherType is 0x88A4 ([`Error::NotEtherCat`]) and returns a validated
    /// EtherCAT view of the payload ([`EcatFrame::new_checked`]). The view borrows this frame.
    pub fn ecat_frame(&self) -> Result<EcatFrame<&[u8]>> {
        self.check_len()?;
        let ethertype = self.ethertype();
        if ethertype != ETHERTYPE_ETHERCAT {
            return Err(Error::NotEtherCat { ethertype });
        }
        EcatFrame::new_checked(self.payload())
    }

    /// [`EthernetFrame::ecat_frame`]'s checks before the EtherCAT validation (length,
    /// EtherType), then the payload's view *unchecked*: `None` where those checks fail. For a
    /// caller that validates the datagram region itself (`wire::matches_pattern`). The tag is
    /// looked at once.
    #[inline]
    pub(crate) fn ecat_frame_unvalidated(&self) -> Option<EcatFrame<&[u8]>> {
        let b = self.buffer.as_ref();
        let (ethertype, at) = if self.is_tagged() {
            (be16(b, field::INNER_ETHERTYPE), field::TAGGED_HEADER_LEN)
        } else {
            (self.outer_ethertype(), field::HEADER_LEN)
        };
        let payload = b.get(at..)?;
        (ethertype == ETHERTYPE_ETHERCAT).then(|| EcatFrame::new_unchecked(payload))
    }
}

impl<'a> EthernetFrame<&'a [u8]> {
    /// The payload, borrowing the underlying buffer rather than the view.
    pub fn into_payload(self) -> &'a [u8] {
        let at = self.header_len();
        self.buffer.get(at..).unwrap_or(&[])
    }

    /// Like [`EthernetFrame::ecat_frame`], borrowing the underlying buffer.
    pub fn into_ecat_frame(self) -> Result<EcatFrame<&'a [u8]>> {
        self.check_len()?;
        let ethertype = self.ethertype();
        if ethertype != ETHERTYPE_ETHERCAT {
            return Err(Error::NotEtherCat { ethertype });
        }
        EcatFrame::new_checked(self.into_payload())
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> EthernetFrame<T> {
    /// Sets the destination MAC.
    pub fn set_dst(&mut self, m: [u8; 6]) {
        put(self.buffer.as_mut(), field::DESTINATION.start, &m);
    }

    /// Sets the source MAC.
    pub fn set_src(&mut self, m: [u8; 6]) {
        put(self.buffer.as_mut(), field::SOURCE.start, &m);
    }

    /// Sets bit 0x02 of the first source octet, as every ESC does on a frame it forwards.
    /// REQ-WIRE-061
    pub fn mark_processed_by_slave(&mut self) {
        let mut s = self.src();
        s[0] |= MAC_PROCESSED_BIT;
        self.set_src(s);
    }

    /// Sets the EtherType at offset 12 (use 0x8100 to make room for a tag).
    /// Invalidates `check_len`.
    pub fn set_outer_ethertype(&mut self, t: u16) {
        put(
            self.buffer.as_mut(),
            field::ETHERTYPE.start,
            &t.to_be_bytes(),
        );
    }

    /// Sets the EtherType after the tag if tagged, else at offset 12.
    pub fn set_ethertype(&mut self, t: u16) {
        let at = if self.is_tagged() {
            field::INNER_ETHERTYPE.start
        } else {
            field::ETHERTYPE.start
        };
        put(self.buffer.as_mut(), at, &t.to_be_bytes());
    }

    /// Everything after the header, mutable (empty before `check_len`).
    pub fn payload_mut(&mut self) -> &mut [u8] {
        let at = self.header_len();
        self.buffer.as_mut().get_mut(at..).unwrap_or(&mut [])
    }

    /// Like [`EthernetFrame::ecat_frame`], but over the mutable payload, for in-place
    /// processing (an emulated ESC walking the datagrams with
    /// [`EcatFrame::iter_mut`]).
    pub fn ecat_frame_mut(&mut self) -> Result<EcatFrame<&mut [u8]>> {
        self.check_len()?;
        let ethertype = self.ethertype();
        if ethertype != ETHERTYPE_ETHERCAT {
            return Err(Error::NotEtherCat { ethertype });
        }
        EcatFrame::new_checked(self.payload_mut())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec;
    use std::vec::Vec;

    /// BRD idx 1 ADO 0x0130 len 2, from a hand-written layout (docs/background/wire-format.md §2.3 base
    /// frame, first datagram only), padded to 60.
    fn frame(tagged: bool) -> Vec<u8> {
        let mut f = vec![0xff, 0xff, 0xff, 0xff, 0xff, 0xff]; // dst
        f.extend_from_slice(&[0x10, 0x10, 0x10, 0x10, 0x10, 0x10]); // src
        if tagged {
            f.extend_from_slice(&[0x81, 0x00, 0x20, 0x05]); // 802.1Q, PCP 1, VID 5
        }
        f.extend_from_slice(&[0x88, 0xa4]); // EtherType
        f.extend_from_slice(&[0x0e, 0x10]); // EtherCAT header: len 14, type 1
        f.extend_from_slice(&[0x07, 0x01, 0x00, 0x00, 0x30, 0x01, 0x02, 0x00, 0x00, 0x00]);
        f.extend_from_slice(&[0x00, 0x00, 0x05, 0x00]); // data, WKC 5
        f.resize(60, 0);
        f
    }

    /// REQ-WIRE-001/002: untagged and single-tagged frames decode alike.
    // verifies: REQ-WIRE-001
    #[test]
    fn deconstruct() {
        for tagged in [false, true] {
            let b = frame(tagged);
            let e = EthernetFrame::new_checked(&b[..]).unwrap();
            assert_eq!(e.dst(), [0xff; 6]);
            assert_eq!(e.src(), [0x10; 6]);
            assert_eq!(e.ethertype(), 0x88a4);
            assert_eq!(e.header_len(), if tagged { 18 } else { 14 });
            assert_eq!(e.vlan(), tagged.then_some(0x2005));
            assert!(!e.processed_by_slave());
            let f = e.ecat_frame().unwrap();
            assert_eq!(f.length(), 14);
            let d = f.iter().next().unwrap().unwrap();
            assert_eq!(d.ado(), 0x0130);
            assert_eq!(d.wkc(), 5);
        }
    }

    #[test]
    fn not_ethercat_and_truncated() {
        // IPv4 in an untagged frame; a double tag, whose inner type is 0x8100.
        for (tagged, at, ethertype) in [(false, 12, 0x0800u16), (true, 16, 0x8100)] {
            let mut b = frame(tagged);
            b[at..at + 2].copy_from_slice(&ethertype.to_be_bytes());
            let e = EthernetFrame::new_checked(&b[..]).unwrap();
            assert_eq!(e.ecat_frame().err(), Some(Error::NotEtherCat { ethertype }));
        }
        let b = frame(true);
        for n in 0..18 {
            assert!(EthernetFrame::new_checked(&b[..n]).is_err() || n >= 14 && b[12] != 0x81);
        }
        assert_eq!(
            EthernetFrame::new_checked(&b[..17]).err(),
            Some(Error::Truncated)
        );
        // A header and nothing else is a (useless but) complete header.
        assert!(EthernetFrame::new_checked(&b[..18]).is_ok());
        assert!(EthernetFrame::new_checked(&frame(false)[..14]).is_ok());
    }

    /// The borrowing walk refuses another EtherType as the view's does; the EtherType setter
    /// writes after the tag of a tagged frame.
    #[test]
    fn into_ecat_frame_and_ethertype() {
        for tagged in [false, true] {
            let mut b = frame(tagged);
            let e = EthernetFrame::new_checked(&b[..]).unwrap();
            assert_eq!(e.into_ecat_frame().map(|f| f.length()), Ok(14));
            let mut e = EthernetFrame::new_checked(&mut b[..]).unwrap();
            e.set_ethertype(0x0800);
            assert_eq!(e.ethertype(), 0x0800);
            assert_eq!(e.is_tagged(), tagged);
            let e = EthernetFrame::new_checked(&b[..]).unwrap();
            assert_eq!(
                e.into_ecat_frame().err(),
                Some(Error::NotEtherCat { ethertype: 0x0800 })
            );
        }
    }

    /// REQ-WIRE-061: the processed bit round trip.
    // verifies: REQ-WIRE-061
    #[test]
    fn processed_bit() {
        let mut b = frame(false);
        let mut e = EthernetFrame::new_checked(&mut b[..]).unwrap();
        e.mark_processed_by_slave();
        assert!(e.processed_by_slave());
        assert_eq!(e.src(), [0x12, 0x10, 0x10, 0x10, 0x10, 0x10]);
    }
}
