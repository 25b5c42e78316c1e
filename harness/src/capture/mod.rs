//! Frame capture files and encapsulations.
//!
//! - [`pcap`]: classic pcap (linktype Ethernet, µs or ns timestamps) writer and reader, so any
//!   sequence of frames the emulator, the simulation or the runtime sees can be opened in
//!   Wireshark and fed back to `ecdc decode`.
//! - [`udp`]: EtherCAT over UDP (port 0x88A4) inside Ethernet/IPv4, to build and to unwrap.

pub mod pcap;
pub mod udp;

pub use pcap::{PcapError, PcapReader, PcapWriter, Record, TimeResolution};
