//! Classic pcap files (not pcapng): a 24-byte global header, then one 16-byte record header
//! plus the captured bytes per frame. Written in host-independent little-endian order; the
//! reader accepts both byte orders and both timestamp resolutions.
//!
//! Format: <https://www.ietf.org/archive/id/draft-gharris-opsawg-pcap-01.html>
//! (magic 0xA1B2C3D4 = µs, 0xA1B23C4D = ns; version 2.4; LINKTYPE_ETHERNET = 1).

use std::fmt;
use std::fs::File;
use std::io::{self, BufReader, BufWriter, Read, Write};
use std::path::Path;

/// LINKTYPE_ETHERNET.
pub const LINKTYPE_ETHERNET: u32 = 1;
/// Magic of a microsecond-resolution file.
pub const MAGIC_MICROS: u32 = 0xA1B2_C3D4;
/// Magic of a nanosecond-resolution file.
pub const MAGIC_NANOS: u32 = 0xA1B2_3C4D;
/// First word of a pcapng file (Section Header Block), recognised to give a clear error.
const PCAPNG_MAGIC: u32 = 0x0A0D_0D0A;
/// Snapshot length we write: larger than any Ethernet frame.
pub const SNAPLEN: u32 = 65_535;
/// Largest record the reader accepts (guards against allocating on a corrupt length).
pub const MAX_RECORD: u32 = 262_144;

/// Timestamp resolution of a file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TimeResolution {
    /// Microseconds (the classic default, magic 0xA1B2C3D4).
    Micro,
    /// Nanoseconds (magic 0xA1B23C4D).
    Nano,
}

impl TimeResolution {
    fn units_per_second(self) -> u64 {
        match self {
            TimeResolution::Micro => 1_000_000,
            TimeResolution::Nano => 1_000_000_000,
        }
    }
}

/// Why a pcap file could not be read or written.
#[derive(Debug)]
pub enum PcapError {
    /// Underlying I/O error.
    Io(io::Error),
    /// The input is empty (0 bytes).
    Empty,
    /// The input ends inside the 24-byte global header.
    ShortHeader {
        /// Bytes present.
        len: usize,
        /// Whether the bytes present start with a pcap magic number.
        pcap_magic: bool,
    },
    /// The file does not start with a pcap magic number.
    BadMagic(u32),
    /// The file is pcapng, which this reader does not handle (convert with
    /// `editcap -F pcap in.pcapng out.pcap`).
    Pcapng,
    /// Link type other than Ethernet.
    UnsupportedLinktype(u32),
    /// A record header says more bytes than [`MAX_RECORD`] or more than the original length.
    BadRecord {
        /// 0-based record number.
        index: u64,
        /// Captured length found.
        incl_len: u32,
    },
    /// The file ends inside a record.
    TruncatedRecord {
        /// 0-based record number.
        index: u64,
    },
    /// A frame longer than the snapshot length was given to the writer.
    FrameTooLong(usize),
}

impl fmt::Display for PcapError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PcapError::Io(e) => write!(f, "pcap I/O: {e}"),
            PcapError::Empty => f.write_str(
                "empty file: not a pcap capture (a classic pcap starts with a 24-byte header)",
            ),
            PcapError::ShortHeader {
                len,
                pcap_magic: true,
            } => write!(
                f,
                "truncated pcap capture: {len} bytes, the global header alone is 24"
            ),
            PcapError::ShortHeader { len, .. } => write!(
                f,
                "not a pcap capture: {len} bytes, shorter than the 24-byte pcap header"
            ),
            PcapError::BadMagic(m) => write!(
                f,
                "not a pcap capture (magic {m:#010x}; a classic pcap starts with {MAGIC_MICROS:#010x} \
                 or {MAGIC_NANOS:#010x} in either byte order)"
            ),
            PcapError::Pcapng => f.write_str(
                "pcapng is not supported; convert with `editcap -F pcap in.pcapng out.pcap`",
            ),
            PcapError::UnsupportedLinktype(l) => {
                write!(
                    f,
                    "pcap link type {l} is not Ethernet (1): only Ethernet captures are read; \
                     capture on the Ethernet interface itself (`tcpdump -i any` writes link \
                     type 113, Linux cooked capture)"
                )
            }
            PcapError::BadRecord { index, incl_len } => {
                write!(
                    f,
                    "pcap record {index}: implausible captured length {incl_len}"
                )
            }
            PcapError::TruncatedRecord { index } => {
                write!(
                    f,
                    "pcap record {index}: file ends inside the record (the capture was cut \
                     short after {index} complete record(s))"
                )
            }
            PcapError::FrameTooLong(n) => write!(f, "frame of {n} bytes exceeds snaplen"),
        }
    }
}

impl std::error::Error for PcapError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            PcapError::Io(e) => Some(e),
            _ => None,
        }
    }
}

impl From<io::Error> for PcapError {
    fn from(e: io::Error) -> Self {
        PcapError::Io(e)
    }
}

/// Writes a classic pcap stream.
#[derive(Debug)]
pub struct PcapWriter<W: Write> {
    out: W,
    resolution: TimeResolution,
}

impl PcapWriter<BufWriter<File>> {
    /// Creates (truncates) `path` and writes the global header.
    pub fn create(path: impl AsRef<Path>, resolution: TimeResolution) -> Result<Self, PcapError> {
        PcapWriter::new(BufWriter::new(File::create(path)?), resolution)
    }
}

impl<W: Write> PcapWriter<W> {
    /// Writes the global header (version 2.4, snaplen 65535, linktype Ethernet) to `out`.
    pub fn new(mut out: W, resolution: TimeResolution) -> Result<Self, PcapError> {
        let magic = match resolution {
            TimeResolution::Micro => MAGIC_MICROS,
            TimeResolution::Nano => MAGIC_NANOS,
        };
        let mut h = Vec::with_capacity(24);
        h.extend_from_slice(&magic.to_le_bytes());
        h.extend_from_slice(&2u16.to_le_bytes());
        h.extend_from_slice(&4u16.to_le_bytes());
        h.extend_from_slice(&0i32.to_le_bytes()); // thiszone
        h.extend_from_slice(&0u32.to_le_bytes()); // sigfigs
        h.extend_from_slice(&SNAPLEN.to_le_bytes());
        h.extend_from_slice(&LINKTYPE_ETHERNET.to_le_bytes());
        out.write_all(&h)?;
        Ok(PcapWriter { out, resolution })
    }

    /// Appends one frame (without FCS) with a timestamp in ns since the Unix epoch (or any
    /// epoch: simulated runs start at 0). µs files round down.
    pub fn write_frame(&mut self, ts_ns: u64, frame: &[u8]) -> Result<(), PcapError> {
        let len = u32::try_from(frame.len())
            .ok()
            .filter(|l| *l <= SNAPLEN)
            .ok_or(PcapError::FrameTooLong(frame.len()))?;
        let secs = ts_ns / 1_000_000_000;
        let frac_ns = ts_ns % 1_000_000_000;
        let frac = match self.resolution {
            TimeResolution::Micro => frac_ns / 1_000,
            TimeResolution::Nano => frac_ns,
        };
        // pcap seconds are 32-bit; saturate rather than wrap for far-future simulated times.
        let secs = u32::try_from(secs).unwrap_or(u32::MAX);
        let frac = u32::try_from(frac).unwrap_or(0);
        let mut h = [0u8; 16];
        h[0..4].copy_from_slice(&secs.to_le_bytes());
        h[4..8].copy_from_slice(&frac.to_le_bytes());
        h[8..12].copy_from_slice(&len.to_le_bytes());
        h[12..16].copy_from_slice(&len.to_le_bytes());
        self.out.write_all(&h)?;
        self.out.write_all(frame)?;
        Ok(())
    }

    /// Flushes and returns the inner writer.
    pub fn finish(mut self) -> Result<W, PcapError> {
        self.out.flush()?;
        Ok(self.out)
    }
}

/// One captured frame.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Record {
    /// Timestamp in ns (µs files are scaled).
    pub ts_ns: u64,
    /// Original frame length on the wire (≥ `data.len()` when the capture was cut).
    pub orig_len: u32,
    /// Captured bytes.
    pub data: Vec<u8>,
}

/// Reads a classic pcap stream record by record (an `Iterator` of `Result<Record>`).
#[derive(Debug)]
pub struct PcapReader<R: Read> {
    input: R,
    big_endian: bool,
    resolution: TimeResolution,
    index: u64,
    done: bool,
}

impl PcapReader<BufReader<File>> {
    /// Opens `path` and reads the global header.
    pub fn open(path: impl AsRef<Path>) -> Result<Self, PcapError> {
        PcapReader::new(BufReader::new(File::open(path)?))
    }
}

impl<R: Read> PcapReader<R> {
    /// Reads and checks the global header.
    pub fn new(mut input: R) -> Result<Self, PcapError> {
        let mut h = [0u8; 24];
        let mut got = 0;
        while got < h.len() {
            match input.read(&mut h[got..]) {
                Ok(0) => break,
                Ok(n) => got += n,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(PcapError::Io(e)),
            }
        }
        if got == 0 {
            return Err(PcapError::Empty);
        }
        if got < 4 {
            return Err(PcapError::ShortHeader {
                len: got,
                pcap_magic: false,
            });
        }
        let magic_le = u32::from_le_bytes([h[0], h[1], h[2], h[3]]);
        let (big_endian, resolution) = match magic_le {
            MAGIC_MICROS => (false, TimeResolution::Micro),
            MAGIC_NANOS => (false, TimeResolution::Nano),
            m if m.swap_bytes() == MAGIC_MICROS => (true, TimeResolution::Micro),
            m if m.swap_bytes() == MAGIC_NANOS => (true, TimeResolution::Nano),
            PCAPNG_MAGIC => return Err(PcapError::Pcapng),
            m => return Err(PcapError::BadMagic(m)),
        };
        if got < h.len() {
            return Err(PcapError::ShortHeader {
                len: got,
                pcap_magic: true,
            });
        }
        let r = PcapReader {
            input,
            big_endian,
            resolution,
            index: 0,
            done: false,
        };
        let linktype = r.u32_at(&h, 20);
        if linktype != LINKTYPE_ETHERNET {
            return Err(PcapError::UnsupportedLinktype(linktype));
        }
        Ok(r)
    }

    /// Timestamp resolution of the file.
    pub fn resolution(&self) -> TimeResolution {
        self.resolution
    }

    fn u32_at(&self, b: &[u8], at: usize) -> u32 {
        let w = [b[at], b[at + 1], b[at + 2], b[at + 3]];
        if self.big_endian {
            u32::from_be_bytes(w)
        } else {
            u32::from_le_bytes(w)
        }
    }

    fn read_record(&mut self) -> Result<Option<Record>, PcapError> {
        let mut h = [0u8; 16];
        // A clean end of file is allowed only before a record header.
        let mut got = 0;
        while got < h.len() {
            let n = self.input.read(&mut h[got..])?;
            if n == 0 {
                return if got == 0 {
                    Ok(None)
                } else {
                    Err(PcapError::TruncatedRecord { index: self.index })
                };
            }
            got += n;
        }
        let secs = u64::from(self.u32_at(&h, 0));
        let frac = u64::from(self.u32_at(&h, 4));
        let incl_len = self.u32_at(&h, 8);
        let orig_len = self.u32_at(&h, 12);
        if incl_len > MAX_RECORD {
            return Err(PcapError::BadRecord {
                index: self.index,
                incl_len,
            });
        }
        let mut data = vec![0u8; incl_len as usize];
        self.input.read_exact(&mut data).map_err(|e| {
            if e.kind() == io::ErrorKind::UnexpectedEof {
                PcapError::TruncatedRecord { index: self.index }
            } else {
                PcapError::Io(e)
            }
        })?;
        let per_unit = 1_000_000_000 / self.resolution.units_per_second();
        let ts_ns = secs
            .saturating_mul(1_000_000_000)
            .saturating_add(frac.saturating_mul(per_unit));
        self.index += 1;
        Ok(Some(Record {
            ts_ns,
            orig_len,
            data,
        }))
    }
}

impl<R: Read> Iterator for PcapReader<R> {
    type Item = Result<Record, PcapError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        let r = self.read_record().transpose();
        if !matches!(r, Some(Ok(_))) {
            self.done = true;
        }
        r
    }
}

/// Writes `frames` (timestamp ns, bytes) to `path` as a nanosecond pcap.
pub fn write_file<'a>(
    path: impl AsRef<Path>,
    frames: impl IntoIterator<Item = (u64, &'a [u8])>,
) -> Result<(), PcapError> {
    let mut w = PcapWriter::create(path, TimeResolution::Nano)?;
    for (ts, f) in frames {
        w.write_frame(ts, f)?;
    }
    w.finish()?;
    Ok(())
}

/// Reads every record of `path`.
pub fn read_file(path: impl AsRef<Path>) -> Result<Vec<Record>, PcapError> {
    PcapReader::open(path)?.collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A µs file written by hand (global header + one 2-byte record) reads back.
    #[test]
    fn reads_hand_written_micro_file() {
        let mut f = Vec::new();
        f.extend_from_slice(&[0xd4, 0xc3, 0xb2, 0xa1, 2, 0, 4, 0]);
        f.extend_from_slice(&[0; 8]);
        f.extend_from_slice(&[0xff, 0xff, 0, 0, 1, 0, 0, 0]);
        f.extend_from_slice(&[5, 0, 0, 0, 7, 0, 0, 0, 2, 0, 0, 0, 60, 0, 0, 0]);
        f.extend_from_slice(&[0xab, 0xcd]);
        let recs: Vec<_> = PcapReader::new(&f[..]).unwrap().collect();
        assert_eq!(
            recs[0].as_ref().unwrap(),
            &Record {
                ts_ns: 5_000_007_000,
                orig_len: 60,
                data: vec![0xab, 0xcd]
            }
        );
        assert_eq!(recs.len(), 1);
        // cut inside the record
        let r: Vec<_> = PcapReader::new(&f[..f.len() - 1]).unwrap().collect();
        assert!(matches!(r[0], Err(PcapError::TruncatedRecord { index: 0 })));
    }

    #[test]
    fn write_read_roundtrip_both_resolutions() {
        for res in [TimeResolution::Micro, TimeResolution::Nano] {
            let mut w = PcapWriter::new(Vec::new(), res).unwrap();
            w.write_frame(1_500_000_123, &[1, 2, 3]).unwrap();
            w.write_frame(0, &[]).unwrap();
            let bytes = w.finish().unwrap();
            let r = PcapReader::new(&bytes[..]).unwrap();
            assert_eq!(r.resolution(), res);
            let recs: Vec<_> = r.map(|x| x.unwrap()).collect();
            let ts = if res == TimeResolution::Nano {
                1_500_000_123
            } else {
                1_500_000_000
            };
            assert_eq!(recs[0].ts_ns, ts);
            assert_eq!(recs[0].data, [1, 2, 3]);
            assert_eq!(recs[1].data, [0u8; 0]);
        }
    }

    #[test]
    fn short_inputs_say_what_they_are() {
        assert!(matches!(PcapReader::new(&[][..]), Err(PcapError::Empty)));
        assert!(matches!(
            PcapReader::new(&b"ab"[..]),
            Err(PcapError::ShortHeader {
                len: 2,
                pcap_magic: false
            })
        ));
        let text = b"myhost\n";
        match PcapReader::new(&text[..]) {
            Err(e @ PcapError::BadMagic(_)) => {
                assert!(
                    e.to_string()
                        .contains("not a pcap capture (magic 0x6f68796d"),
                    "{e}"
                )
            }
            other => panic!("{other:?}"),
        }
        let cut = MAGIC_MICROS.to_le_bytes();
        let e = PcapReader::new(&cut[..]).unwrap_err();
        assert!(matches!(
            e,
            PcapError::ShortHeader {
                len: 4,
                pcap_magic: true
            }
        ));
        assert!(e.to_string().contains("truncated pcap capture"), "{e}");
    }

    #[test]
    fn rejects_non_pcap() {
        let mut ng = vec![0x0a, 0x0d, 0x0d, 0x0a];
        ng.resize(24, 0);
        assert!(matches!(PcapReader::new(&ng[..]), Err(PcapError::Pcapng)));
        let junk = [0u8; 24];
        assert!(matches!(
            PcapReader::new(&junk[..]),
            Err(PcapError::BadMagic(0))
        ));
        let mut raw_ip = Vec::new();
        raw_ip.extend_from_slice(&MAGIC_MICROS.to_le_bytes());
        raw_ip.resize(20, 0);
        raw_ip.extend_from_slice(&101u32.to_le_bytes());
        assert!(matches!(
            PcapReader::new(&raw_ip[..]),
            Err(PcapError::UnsupportedLinktype(101))
        ));
        // big-endian header is accepted
        let mut be = Vec::new();
        be.extend_from_slice(&MAGIC_NANOS.to_be_bytes());
        be.resize(20, 0);
        be.extend_from_slice(&1u32.to_be_bytes());
        assert_eq!(
            PcapReader::new(&be[..]).unwrap().resolution(),
            TimeResolution::Nano
        );
        // implausible record length
        let mut w = PcapWriter::new(Vec::new(), TimeResolution::Nano)
            .unwrap()
            .finish()
            .unwrap();
        w.extend_from_slice(&[0, 0, 0, 0, 0, 0, 0, 0, 0xff, 0xff, 0xff, 0x7f, 0, 0, 0, 0]);
        let r: Vec<_> = PcapReader::new(&w[..]).unwrap().collect();
        assert!(matches!(r[0], Err(PcapError::BadRecord { index: 0, .. })));
    }
}
