//! [`HeaderKey`]: a datagram's first 8 header bytes (command, index, ADP, ADO, length word) as
//! one little-endian `u64`, so that a request and its reply compare in one load and one
//! masked compare (REQ-DC-113), and a datagram of the fixed cyclic set is written from it.
//!
//! ```text
//! bits  0..8   cmd      (datagram byte 0)
//! bits  8..16  idx      (byte 1)
//! bits 16..32  ADP      (bytes 2..4)
//! bits 32..48  ADO      (bytes 4..6)
//! bits 48..64  len | C << 14 | M << 15  (bytes 6..8)
//! ```

use super::datagram::field;
use super::frame::{field as ffield, FrameType};
use super::Command;

/// Bit positions of the fields in the little-endian key: 8 × their byte offsets (the
/// command is byte 0, bits 0..8).
const IDX_SHIFT: u32 = 8;
const ADP_SHIFT: u32 = 16;
const ADO_SHIFT: u32 = 32;
const LEN_SHIFT: u32 = 48;
const _: () = assert!(
    field::CMD == 0
        && field::IDX == 1
        && field::ADP.start == 2
        && field::ADO.start == 4
        && field::LEN_FLAGS.start == 6
        && field::LEN_FLAGS.end == 8
);

/// The first 8 header bytes of a datagram, little-endian.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(crate) struct HeaderKey(pub(crate) u64);

impl HeaderKey {
    /// The command and index bits.
    pub(crate) const COMMAND_INDEX: u64 = 0xFFFF;
    /// The ADP bits (station or position address).
    pub(crate) const ADP: u64 = 0xFFFF << ADP_SHIFT;
    /// The ADO bits (register offset).
    pub(crate) const ADO: u64 = 0xFFFF << ADO_SHIFT;
    /// The whole length word: length, reserved bits, C and M.
    pub(crate) const LEN_WORD: u64 = 0xFFFF << LEN_SHIFT;
    /// The M bit (more datagrams follow).
    pub(crate) const MORE: u64 = (field::MORE as u64) << LEN_SHIFT;
    /// The command bits.
    pub(crate) const COMMAND: u64 = 0xFF;
    /// The data length bits of the length word (C, M and the reserved bits left out).
    pub(crate) const LEN: u64 = (field::LEN_MASK as u64) << LEN_SHIFT;

    /// The key of a datagram sent with `command`, `index`, `adp`, `ado` and `len` ≤ 0x07FF
    /// data bytes, C and M clear.
    #[inline(always)]
    pub(crate) const fn new(command: Command, index: u8, adp: u16, ado: u16, len: u16) -> Self {
        HeaderKey(
            (command.code() as u64)
                | (index as u64) << IDX_SHIFT
                | (adp as u64) << ADP_SHIFT
                | (ado as u64) << ADO_SHIFT
                | (len as u64) << LEN_SHIFT,
        )
    }

    /// The same key with M set (`more`) or clear.
    #[inline(always)]
    pub(crate) const fn with_more(self, more: bool) -> Self {
        if more {
            HeaderKey(self.0 | Self::MORE)
        } else {
            HeaderKey(self.0 & !Self::MORE)
        }
    }

    /// The same key with the length word `len` (its C, M and reserved bits as `len` has them).
    #[inline(always)]
    pub(crate) const fn with_len(self, len: u16) -> Self {
        HeaderKey(self.0 & !Self::LEN_WORD | (len as u64) << LEN_SHIFT)
    }

    /// The key of the header bytes `h`.
    #[inline(always)]
    pub(crate) const fn of(h: &[u8; field::LEN_FLAGS.end]) -> Self {
        HeaderKey(u64::from_le_bytes(*h))
    }

    /// Whether `self` and `other` agree on the bits of `mask`.
    #[inline(always)]
    pub(crate) const fn agrees(self, other: HeaderKey, mask: u64) -> bool {
        (self.0 ^ other.0) & mask == 0
    }

    /// A whole datagram of `T` bytes (header, `T` − 12 data bytes, WKC) as the frame builder
    /// writes it: these 8 header bytes, IRQ 0, the data the low bytes of `value`
    /// little-endian (zero beyond 8), WKC 0.
    #[inline(always)]
    pub(crate) fn datagram<const T: usize>(self, value: u64) -> [u8; T] {
        let mut out = [0u8; T];
        if let Some(h) = out.first_chunk_mut::<{ field::LEN_FLAGS.end }>() {
            *h = self.0.to_le_bytes();
        }
        let len = T.saturating_sub(field::MIN_LEN).min(8);
        let data = out.get_mut(field::DATA..field::DATA.saturating_add(len));
        if let (Some(d), Some(v)) = (data, value.to_le_bytes().get(..len)) {
            d.copy_from_slice(v);
        }
        out
    }
}

/// The EtherCAT header of a DLPDU frame whose datagrams take `len` bytes (reserved bit
/// clear); `None` if `len` does not fit the length field.
#[inline(always)]
pub(crate) fn dlpdu_header(len: usize) -> Option<[u8; ffield::HEADER_LEN]> {
    let len = u16::try_from(len)
        .ok()
        .filter(|l| l & !ffield::LEN_MASK == 0)?;
    Some((len | u16::from(FrameType::Dlpdu.to_u8()) << ffield::TYPE_SHIFT).to_le_bytes())
}

/// A datagram's data (between the header and the WKC) and its working counter; empty data
/// and 0 if `d` is shorter than a datagram.
#[inline(always)]
pub(crate) fn data_and_wkc(d: &[u8]) -> (&[u8], u16) {
    let body = d.get(field::DATA..).unwrap_or(&[]);
    match body.split_last_chunk::<{ field::WKC_LEN }>() {
        Some((data, wkc)) => (data, u16::from_le_bytes(*wkc)),
        None => (&[], 0),
    }
}

/// Sets or clears the M bit of the datagram that starts at `d` (nothing if `d` is shorter
/// than a header).
#[inline(always)]
pub(crate) fn set_more(d: &mut [u8], more: bool) {
    let [_, m] = field::MORE.to_le_bytes();
    if let Some([_, hi]) = d
        .get_mut(field::LEN_FLAGS)
        .and_then(|w| w.first_chunk_mut::<2>())
    {
        *hi = if more { *hi | m } else { *hi & !m };
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::{Address, Datagram, FrameBuilder};

    /// The key's bytes are the header the builder writes, and `datagram` the whole datagram.
    #[test]
    fn key_is_the_header_the_builder_writes() {
        for (cmd, adp, ado, data) in [
            (Command::Fprd, 0x1001u16, 0x092Cu16, &[0u8; 4][..]),
            (Command::Brd, 0, 0x0130, &[0u8; 2][..]),
            (Command::Frmw, 0x1234, 0x0910, &[1, 2, 3, 4, 5, 6, 7, 8][..]),
        ] {
            let mut buf = [0u8; 64];
            let mut b = FrameBuilder::new(&mut buf).unwrap();
            let slot = b
                .push(
                    cmd,
                    0x5A,
                    Address::Raw(u32::from(adp) | u32::from(ado) << 16),
                    data,
                )
                .unwrap();
            let d = b.datagram_mut(slot).unwrap();
            let bytes = d.into_inner();
            let len = u16::try_from(data.len()).unwrap();
            let key = HeaderKey::new(cmd, 0x5A, adp, ado, len);
            assert_eq!(&bytes[..8], &key.0.to_le_bytes());
            let mut value = [0u8; 8];
            value[..data.len()].copy_from_slice(data);
            let v = u64::from_le_bytes(value);
            match data.len() {
                2 => assert_eq!(&key.datagram::<14>(v)[..], &bytes[..14]),
                4 => assert_eq!(&key.datagram::<16>(v)[..], &bytes[..16]),
                _ => assert_eq!(&key.datagram::<20>(v)[..], &bytes[..20]),
            }
            assert_eq!(HeaderKey::of(bytes[..8].try_into().unwrap()), key);
            let mut with_m = key.datagram::<16>(0);
            set_more(&mut with_m, true);
            assert!(Datagram::new_unchecked(&with_m[..]).more());
            set_more(&mut with_m, true);
            assert!(
                Datagram::new_unchecked(&with_m[..]).more(),
                "setting M twice keeps it"
            );
            assert_eq!(key.with_more(true).with_more(true), key.with_more(true));
            assert_eq!(
                HeaderKey::of(with_m[..8].try_into().unwrap()),
                key.with_more(true)
            );
            set_more(&mut with_m, false);
            assert_eq!(with_m, key.datagram::<16>(0));
        }
        assert_eq!(dlpdu_header(0x0123), Some(0x1123u16.to_le_bytes()));
        assert_eq!(dlpdu_header(0x0800), None);
        let d = HeaderKey::new(Command::Brd, 1, 0, 0x0130, 2).datagram::<14>(0xBEEF);
        let mut d = d;
        d[12..].copy_from_slice(&7u16.to_le_bytes());
        assert_eq!(data_and_wkc(&d), (&[0xEF, 0xBE][..], 7));
        assert_eq!(data_and_wkc(&d[..11]), (&[][..], 0));
    }
}
