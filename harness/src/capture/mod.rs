//! Frame capture files and encapsulations.
//!
//! - [`pcap`]: classic pcap and pcapng (linktype Ethernet) writer and streaming reader, so any
//!   sequence of frames the emulator, the simulation or the runtime sees can be opened in
//!   Wireshark, and Wireshark's captures fed back to `ecdc decode`.
//! - [`udp`]: EtherCAT over UDP (port 0x88A4) inside Ethernet/IPv4, to build and to unwrap.

pub mod pcap;
pub mod udp;

pub use pcap::{Format, PcapError, PcapReader, PcapWriter, Record, TimeResolution};
