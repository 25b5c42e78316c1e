//! The one error type of the wire layer. Fieldful where the value helps a human or a test
//! decide *which* check fired (REQ-WIRE-016).

use core::fmt;

/// Why a buffer is not a valid EtherCAT frame, or why the builder refused a datagram.
#[non_exhaustive]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Error {
    /// The buffer is shorter than a header or a field needs, or shorter than the EtherCAT
    /// header length says (a cut capture). REQ-WIRE-010
    Truncated,
    /// The EtherType (after at most one 802.1Q tag) is not 0x88A4. REQ-WIRE-001
    NotEtherCat {
        /// The EtherType found.
        ethertype: u16,
    },
    /// Bit 11 of the EtherCAT header is set. Policy: error (REQ-WIRE-013).
    HeaderReservedBit,
    /// The EtherCAT header type is not 1 (DLPDU). Reported, not guessed at. REQ-WIRE-014
    NotDlpdu {
        /// The 4-bit type found (2 ADS, 3 RAW-IO, 4 NV, 5 mailbox gateway, ...).
        frame_type: u8,
    },
    /// A datagram declares more than 1486 data bytes. REQ-WIRE-011
    DatagramTooLong {
        /// The 11-bit length found.
        len: u16,
    },
    /// The datagrams would exceed 1498 bytes (EtherCAT header + datagrams > 1500, the Ethernet
    /// payload limit). REQ-WIRE-012
    FrameTooLong {
        /// The datagram byte count declared by the EtherCAT header length.
        len: usize,
    },
    /// A datagram has its M bit set, but the EtherCAT header length ends right after it.
    /// REQ-WIRE-015
    MoreBitOnLast,
    /// The M bit of a datagram is clear, but the EtherCAT header length covers further bytes.
    /// REQ-WIRE-015
    TrailingData,
    /// A datagram would end past the EtherCAT header length. `walked` is the datagram byte count
    /// the M-bit walk needed up to and including that datagram (at least its 10-byte header
    /// plus the WKC). REQ-WIRE-015
    LengthMismatch {
        /// Length from the EtherCAT header (datagram bytes, header excluded).
        header: u16,
        /// Bytes the M-bit walk needed.
        walked: u16,
    },
    /// Command code above 14 (FRMW). REQ-WIRE-017
    UnknownCommand {
        /// The command byte found.
        code: u8,
    },
    /// One of bits 11..13 of a datagram's length word is set. Policy: error, same as the header
    /// reserved bit (REQ-WIRE-013).
    DatagramReservedBits,
    /// The EtherCAT header length is 0: a DLPDU frame carries at least one datagram. REQ-WIRE-015
    NoDatagram,
    /// The builder's buffer (or the 1498-byte datagram limit of one frame) has no room for the
    /// datagram, or the buffer cannot hold a padded 60-byte frame. REQ-WIRE-040
    BufferFull,
    /// The [`crate::wire::Address`] kind does not match the command's addressing kind (e.g. a
    /// position address on FPRD). REQ-WIRE-031
    AddressMismatch,
    /// A [`crate::wire::DatagramSlot`] that does not belong to this builder's frame.
    InvalidSlot,
}

/// Result of every fallible wire operation.
pub type Result<T> = core::result::Result<T, Error>;

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Error::Truncated => f.write_str("buffer truncated"),
            Error::NotEtherCat { ethertype } => {
                write!(f, "EtherType {ethertype:#06x} is not EtherCAT (0x88a4)")
            }
            Error::HeaderReservedBit => f.write_str("EtherCAT header reserved bit 11 is set"),
            Error::NotDlpdu { frame_type } => {
                write!(f, "EtherCAT frame type {frame_type} is not 1 (DLPDU)")
            }
            Error::DatagramTooLong { len } => {
                write!(f, "datagram data length {len} exceeds 1486")
            }
            Error::FrameTooLong { len } => {
                write!(f, "EtherCAT datagram length {len} exceeds 1498")
            }
            Error::MoreBitOnLast => {
                f.write_str("M bit set on the datagram that ends the header length")
            }
            Error::TrailingData => {
                f.write_str("header length covers bytes after the last datagram (M clear)")
            }
            Error::LengthMismatch { header, walked } => write!(
                f,
                "EtherCAT header length {header} but the M-bit walk needs {walked} bytes"
            ),
            Error::UnknownCommand { code } => write!(f, "unknown command code {code}"),
            Error::DatagramReservedBits => f.write_str("datagram reserved bits 11..13 are set"),
            Error::NoDatagram => f.write_str("EtherCAT header length is 0 (no datagram)"),
            Error::BufferFull => f.write_str("frame buffer full"),
            Error::AddressMismatch => f.write_str("address kind does not match the command"),
            Error::InvalidSlot => f.write_str("datagram slot does not belong to this frame"),
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for Error {}

#[cfg(test)]
mod tests {
    use super::*;

    /// Errors say which field is wrong, with its value.
    #[test]
    fn error_messages() {
        assert_eq!(
            std::format!("{}", Error::NotEtherCat { ethertype: 0x0800 }),
            "EtherType 0x0800 is not EtherCAT (0x88a4)"
        );
        assert_eq!(std::format!("{}", Error::Truncated), "buffer truncated");
    }
}
