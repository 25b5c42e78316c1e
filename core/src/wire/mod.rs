//! EtherCAT wire codec: zero-copy views, a frame builder and typed DC register codecs.
//!
//! # Layers (outermost first)
//!
//! ```text
//! Ethernet II  dst(6) src(6) [802.1Q tag(4)] type=0x88A4(2)      -> EthernetFrame<T>
//!   (or IPv4/UDP port 0x88A4: the UDP payload starts here)
//! EtherCAT header  LE u16: len(11) reserved(1) type(4)            -> EcatFrame<T>
//!   datagram*  cmd idx addr(4) len/R/C/M(2) irq(2) data(len) wkc(2) -> Datagram<T>
//! padding up to 60 bytes (without FCS)
//! ```
//!
//! # Files
//!
//! `ethernet.rs` (Ethernet II + one 802.1Q tag), `frame.rs` (EtherCAT header, the M-bit walk,
//! `iter`/`iter_mut`/`datagram_offsets`), `datagram.rs` (one datagram view + `DatagramRepr`),
//! `command.rs` (the 15 commands, addressing kinds, WKC rules), `address.rs` (typed 4 address
//! bytes), `builder.rs` (`FrameBuilder` into `&mut [u8]`), `register.rs` (DC register map and
//! codecs), `error.rs` (`wire::Error`).
//!
//! # Contract (each sentence is checked by tests or proofs, see `spec/req/wire.md`)
//!
//! - Views (`EthernetFrame`, `EcatFrame`, `Datagram`) wrap any `T: AsRef<[u8]>`; setters exist
//!   when `T: AsMut<[u8]>` too. `new_unchecked` never fails, `check_len`/`new_checked` validate.
//! - No accessor of any view panics, for any buffer, checked or not (REQ-WIRE-020): every read
//!   goes through `.get()`. On a buffer that failed `check_len` a getter returns zeros or an empty
//!   slice, which is meaningless but safe; after `check_len` returned `Ok` the values are the
//!   fields on the wire.
//! - `EcatFrame::new_checked` validates the header and walks every datagram by its M bit, and
//!   cross-checks the walk against the header length (REQ-WIRE-010..016). Afterwards `iter()`
//!   yields only `Ok` datagrams whose spans lie inside the buffer.
//! - Reserved bits set to 1 are an error, in the EtherCAT header ([`Error::HeaderReservedBit`])
//!   and in the datagram length word ([`Error::DatagramReservedBits`]) alike (REQ-WIRE-013).
//!   The raw bits stay readable through the unchecked views.
//! - `DatagramRepr::parse` + `DatagramRepr::emit` round-trip every valid datagram (REQ-WIRE-030).
//! - [`FrameBuilder`] writes into the caller's buffer and never writes past it: when a datagram
//!   does not fit it returns [`Error::BufferFull`] and leaves the frame as it was (REQ-WIRE-040).
//!
//! ```
//! use ecdc_core::wire::{Address, Command, EthernetFrame, FrameBuilder};
//! let mut buf = [0u8; 128];
//! let mut b = FrameBuilder::new(&mut buf).unwrap();
//! b.push(Command::Brd, 1, Address::broadcast(0x0130), &[0, 0]).unwrap();
//! b.push(Command::Frmw, 2, Address::configured(0x1001, 0x0910), &[0; 8]).unwrap();
//! let n = b.finish().unwrap();
//! assert_eq!(n, 60);
//! let eth = EthernetFrame::new_checked(&buf[..n]).unwrap();
//! let frame = eth.ecat_frame().unwrap();
//! let cmds: Vec<_> = frame.iter().map(|d| d.unwrap().command().unwrap()).collect();
//! assert_eq!(cmds, [Command::Brd, Command::Frmw]);
//! ```

mod address;
mod builder;
mod command;
mod datagram;
mod error;
mod ethernet;
mod frame;
mod key;
pub mod register;

pub use address::Address;
pub(crate) use builder::put_small;
pub use builder::{DatagramSlot, FrameBuilder};
pub use command::{Addressing, Command};
pub use datagram::{Datagram, DatagramRepr, DATAGRAM_HEADER_LEN, DATAGRAM_OVERHEAD};
pub use error::{Error, Result};
pub use ethernet::{EthernetFrame, HEADER_LEN as ETHERNET_HEADER_LEN};
pub(crate) use frame::{matches_pattern, HeaderPattern};
pub use frame::{DatagramOffsets, Datagrams, DatagramsMut, EcatFrame, FrameType, ECAT_HEADER_LEN};
pub(crate) use key::{data_and_wkc, dlpdu_header, set_more, HeaderKey};

/// EtherType of EtherCAT (big-endian on the wire like every EtherType). REQ-WIRE-001
pub const ETHERTYPE_ETHERCAT: u16 = 0x88A4;
/// EtherType of an IEEE 802.1Q VLAN tag; one tag is tolerated in front of 0x88A4. REQ-WIRE-002
pub const ETHERTYPE_VLAN: u16 = 0x8100;
/// UDP port (source or destination) of EtherCAT over UDP. REQ-WIRE-003
pub const UDP_PORT_ETHERCAT: u16 = 0x88A4;
/// Largest data length of one datagram: 1500 − 2 (EtherCAT header) − 10 − 2. REQ-WIRE-011
pub const MAX_DATAGRAM_DATA: usize = 1486;
/// Largest datagram byte count in one frame, i.e. the largest valid EtherCAT header length:
/// the 1500-byte Ethernet payload minus the 2-byte EtherCAT header (ESC datasheet: "44-1498
/// Byte" of datagrams; SOEM: 1518 = 14 + 2 + 10 + 1486 + 2 + 4). REQ-WIRE-012
pub const MAX_ECAT_PAYLOAD: usize = 1498;
/// Largest Ethernet payload: EtherCAT header + datagrams.
pub const MAX_ETHERNET_PAYLOAD: usize = 1500;
/// Smallest Ethernet frame without FCS; the builder pads to it. REQ-WIRE-041
pub const MIN_FRAME_LEN: usize = 60;
/// Largest untagged Ethernet frame without FCS (14 + 1500).
pub const MAX_FRAME_LEN: usize = 1514;
/// Fixed unicast source MAC of the MainDevice. Bit 0x02 of the first octet is clear (and so is the
/// multicast bit 0x01), so a frame that came back through an ESC, which sets bit 0x02, is
/// recognisable as processed. REQ-WIRE-060
pub const MASTER_MAC: [u8; 6] = [0x10, 0x10, 0x10, 0x10, 0x10, 0x10];
/// Destination MAC used by the builder: broadcast, as masters usually send. REQ-WIRE-060
pub const BROADCAST_MAC: [u8; 6] = [0xff; 6];
/// The bit an ESC sets in the first source-MAC octet of every frame it forwards. REQ-WIRE-061
pub const MAC_PROCESSED_BIT: u8 = 0x02;

/// Reads a little-endian `u16` at `at`; 0 when out of range (views only call it after
/// `check_len`, so the fallback is never observable on checked buffers).
#[inline]
pub(crate) fn get_u16_le(buf: &[u8], at: usize) -> u16 {
    match buf.get(at..at.wrapping_add(2)) {
        Some(&[a, b]) => u16::from_le_bytes([a, b]),
        _ => 0,
    }
}

/// Reads a little-endian `u32` at `at`; 0 when out of range.
#[inline]
pub(crate) fn get_u32_le(buf: &[u8], at: usize) -> u32 {
    match buf.get(at..at.wrapping_add(4)) {
        Some(&[a, b, c, d]) => u32::from_le_bytes([a, b, c, d]),
        _ => 0,
    }
}

/// Writes `bytes` at `at` if they fit; otherwise does nothing (setters are only meaningful after
/// `check_len`, and must never panic before it).
#[inline]
pub(crate) fn put(buf: &mut [u8], at: usize, bytes: &[u8]) {
    if let Some(dst) = buf.get_mut(at..at.wrapping_add(bytes.len())) {
        dst.copy_from_slice(bytes);
    }
}
