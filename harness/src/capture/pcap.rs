//! Capture files, classic pcap and pcapng, read and written through the `pcap-file` crate.
//!
//! - Classic pcap: a 24-byte global header, then a 16-byte record header plus the captured
//!   bytes per frame (magic 0xA1B2C3D4 = µs, 0xA1B23C4D = ns; either byte order; version 2.4).
//!   <https://www.ietf.org/archive/id/draft-gharris-opsawg-pcap-01.html>
//! - pcapng (Wireshark's default): blocks, each with its total length at both ends; packets in
//!   Enhanced or Simple Packet Blocks, their link type and timestamp unit in the Interface
//!   Description Block they name (`if_tsresol`, default µs).
//!   <https://www.ietf.org/archive/id/draft-ietf-opsawg-pcapng-01.html>
//!
//! Only Ethernet (LINKTYPE_ETHERNET = 1) is read. The reader streams: the crate's parsers run
//! on a fixed window of [`MAX_RECORD`] + 64 KiB, one record at a time, so memory does not grow
//! with the file and no length field becomes an allocation.
//!
//! The first bytes are inspected here before the crate sees them, so that an empty file,
//! a text file or a cut header gets a message a user can act on.

use std::borrow::Cow;
use std::fmt;
use std::fs::File;
use std::io::{self, BufReader, BufWriter, Read, Write};
use std::path::Path;
use std::time::Duration;

use pcap_file::pcap::{PcapHeader, PcapPacket};
use pcap_file::pcapng::blocks::enhanced_packet::EnhancedPacketBlock;
use pcap_file::pcapng::blocks::interface_description::{
    InterfaceDescriptionBlock, InterfaceDescriptionOption,
};
use pcap_file::pcapng::Block;
use pcap_file::{DataLink, Endianness, TsResolution};

/// LINKTYPE_ETHERNET.
pub const LINKTYPE_ETHERNET: u32 = 1;
/// Magic of a microsecond-resolution classic pcap.
pub const MAGIC_MICROS: u32 = 0xA1B2_C3D4;
/// Magic of a nanosecond-resolution classic pcap.
pub const MAGIC_NANOS: u32 = 0xA1B2_3C4D;
/// First word of a pcapng file (its Section Header Block's type).
pub const PCAPNG_MAGIC: u32 = 0x0A0D_0D0A;
/// Snapshot length we write: larger than any Ethernet frame.
pub const SNAPLEN: u32 = 65_535;
/// Largest captured frame the reader hands out; a larger record is refused, whatever the
/// file's snapshot length says (the largest jumbo frame is about 9 KiB).
pub const MAX_RECORD: u32 = 262_144;

/// The two capture formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// Classic pcap.
    Pcap,
    /// pcapng.
    PcapNg,
}

impl Format {
    /// The format a file name asks for: `.pcapng` (any case) is pcapng, anything else pcap.
    pub fn from_path(path: &Path) -> Format {
        match path.extension().and_then(|e| e.to_str()) {
            Some(e) if e.eq_ignore_ascii_case("pcapng") => Format::PcapNg,
            _ => Format::Pcap,
        }
    }

    fn unit(self) -> &'static str {
        match self {
            Format::Pcap => "pcap record",
            Format::PcapNg => "pcapng block",
        }
    }
}

/// Timestamp resolution of a classic pcap file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TimeResolution {
    /// Microseconds (the classic default, magic 0xA1B2C3D4).
    Micro,
    /// Nanoseconds (magic 0xA1B23C4D).
    Nano,
}

impl From<TimeResolution> for TsResolution {
    fn from(r: TimeResolution) -> Self {
        match r {
            TimeResolution::Micro => TsResolution::MicroSecond,
            TimeResolution::Nano => TsResolution::NanoSecond,
        }
    }
}

/// Why a capture file could not be read or written.
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
    /// The file starts with neither a pcap nor a pcapng magic number.
    BadMagic(u32),
    /// Link type other than Ethernet.
    UnsupportedLinktype(u32),
    /// A record (pcap) or block (pcapng) that the format does not allow, or a captured frame
    /// larger than [`MAX_RECORD`].
    BadRecord {
        /// Which format.
        format: Format,
        /// 0-based record or block number.
        index: u64,
        /// What is wrong with it.
        reason: String,
    },
    /// The file ends inside a record or block.
    TruncatedRecord {
        /// Which format.
        format: Format,
        /// 0-based record or block number.
        index: u64,
    },
    /// A frame longer than the snapshot length was given to the writer.
    FrameTooLong(usize),
}

impl fmt::Display for PcapError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PcapError::Io(e) => write!(f, "capture I/O: {e}"),
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
                 or {MAGIC_NANOS:#010x} in either byte order, a pcapng with {PCAPNG_MAGIC:#010x})"
            ),
            PcapError::UnsupportedLinktype(l) => {
                write!(
                    f,
                    "capture link type {l} is not Ethernet (1): only Ethernet captures are read; \
                     capture on the Ethernet interface itself (`tcpdump -i any` writes link \
                     type 113, Linux cooked capture)"
                )
            }
            PcapError::BadRecord {
                format,
                index,
                reason,
            } => write!(f, "{} {index}: {reason}", format.unit()),
            PcapError::TruncatedRecord { format, index } => {
                let what = match format {
                    Format::Pcap => "record",
                    Format::PcapNg => "block",
                };
                write!(
                    f,
                    "{} {index}: file ends inside the {what} (the capture was cut short after \
                     {index} complete {what}(s))",
                    format.unit()
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

/// Maps the crate's error for record or block `index` onto ours.
fn from_crate(e: pcap_file::PcapError, format: Format, index: u64) -> PcapError {
    match e {
        pcap_file::PcapError::IoError(e) if e.kind() == io::ErrorKind::UnexpectedEof => {
            PcapError::TruncatedRecord { format, index }
        }
        pcap_file::PcapError::IncompleteBuffer => PcapError::TruncatedRecord { format, index },
        pcap_file::PcapError::IoError(e) => PcapError::Io(e),
        other => PcapError::BadRecord {
            format,
            index,
            reason: other.to_string(),
        },
    }
}

/// Writes a capture stream, classic pcap or pcapng.
pub struct PcapWriter<W: Write> {
    inner: WriterInner<W>,
}

enum WriterInner<W: Write> {
    Pcap(pcap_file::pcap::PcapWriter<W>),
    PcapNg(pcap_file::pcapng::PcapNgWriter<W>),
}

impl<W: Write> fmt::Debug for PcapWriter<W> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let format = match self.inner {
            WriterInner::Pcap(_) => Format::Pcap,
            WriterInner::PcapNg(_) => Format::PcapNg,
        };
        f.debug_struct("PcapWriter")
            .field("format", &format)
            .finish()
    }
}

impl PcapWriter<BufWriter<File>> {
    /// Creates (truncates) `path` and writes the file header: pcapng when the name ends in
    /// `.pcapng` (nanosecond timestamps), classic pcap with `resolution` otherwise.
    pub fn create(path: impl AsRef<Path>, resolution: TimeResolution) -> Result<Self, PcapError> {
        let path = path.as_ref();
        let out = BufWriter::new(File::create(path)?);
        match Format::from_path(path) {
            Format::Pcap => PcapWriter::new(out, resolution),
            Format::PcapNg => PcapWriter::new_pcapng(out),
        }
    }
}

impl<W: Write> PcapWriter<W> {
    /// Writes a classic pcap global header (version 2.4, little-endian, snaplen 65535,
    /// linktype Ethernet) to `out`.
    pub fn new(out: W, resolution: TimeResolution) -> Result<Self, PcapError> {
        let header = PcapHeader {
            version_major: 2,
            version_minor: 4,
            ts_correction: 0,
            ts_accuracy: 0,
            snaplen: SNAPLEN,
            datalink: DataLink::ETHERNET,
            ts_resolution: resolution.into(),
            endianness: Endianness::Little,
        };
        let w = pcap_file::pcap::PcapWriter::with_header(out, header)
            .map_err(|e| from_crate(e, Format::Pcap, 0))?;
        Ok(PcapWriter {
            inner: WriterInner::Pcap(w),
        })
    }

    /// Writes a pcapng Section Header Block (little-endian) and one Ethernet interface with
    /// nanosecond timestamps (`if_tsresol` = 9) to `out`.
    pub fn new_pcapng(out: W) -> Result<Self, PcapError> {
        let mut w = pcap_file::pcapng::PcapNgWriter::with_endianness(out, Endianness::Little)
            .map_err(|e| from_crate(e, Format::PcapNg, 0))?;
        let interface = InterfaceDescriptionBlock {
            linktype: DataLink::ETHERNET,
            snaplen: SNAPLEN,
            options: vec![InterfaceDescriptionOption::IfTsResol(9)],
        };
        w.write_pcapng_block(interface)
            .map_err(|e| from_crate(e, Format::PcapNg, 1))?;
        Ok(PcapWriter {
            inner: WriterInner::PcapNg(w),
        })
    }

    /// Appends one frame (without FCS) with a timestamp in ns since the Unix epoch (or any
    /// epoch: simulated runs start at 0). µs files round down; classic pcap seconds are
    /// 32-bit, so a time past 2106 is written as the last representable second.
    pub fn write_frame(&mut self, ts_ns: u64, frame: &[u8]) -> Result<(), PcapError> {
        let len = u32::try_from(frame.len())
            .ok()
            .filter(|l| *l <= SNAPLEN)
            .ok_or(PcapError::FrameTooLong(frame.len()))?;
        match &mut self.inner {
            WriterInner::Pcap(w) => {
                let secs = (ts_ns / 1_000_000_000).min(u64::from(u32::MAX));
                let frac = u32::try_from(ts_ns % 1_000_000_000).unwrap_or(0);
                let ts = Duration::new(secs, frac);
                w.write_packet(&PcapPacket::new(ts, len, frame))
                    .map_err(|e| from_crate(e, Format::Pcap, 0))?;
            }
            WriterInner::PcapNg(w) => {
                // With if_tsresol = 9 the block's 64-bit timestamp is in ns, which is what
                // the crate writes for a Duration.
                let block = EnhancedPacketBlock {
                    interface_id: 0,
                    timestamp: Duration::from_nanos(ts_ns),
                    original_len: len,
                    data: Cow::Borrowed(frame),
                    options: Vec::new(),
                };
                w.write_pcapng_block(block)
                    .map_err(|e| from_crate(e, Format::PcapNg, 0))?;
            }
        }
        Ok(())
    }

    /// Flushes and returns the inner writer.
    pub fn finish(self) -> Result<W, PcapError> {
        let mut out = match self.inner {
            WriterInner::Pcap(w) => w.into_writer(),
            WriterInner::PcapNg(w) => w.into_inner(),
        };
        out.flush()?;
        Ok(out)
    }
}

/// One captured frame.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Record {
    /// Timestamp in ns (scaled from the file's unit); `None` for a pcapng Simple Packet
    /// Block, which has none.
    pub ts_ns: Option<u64>,
    /// Original frame length on the wire (≥ `data.len()` when the capture was cut).
    pub orig_len: u32,
    /// Captured bytes.
    pub data: Vec<u8>,
}

/// A bounded read window over the input: the crate's parsers work on byte slices, and this
/// keeps at most one record (plus what one `read` brought) in memory.
struct Window<R: Read> {
    input: R,
    buf: Vec<u8>,
    /// Start of the unparsed bytes.
    pos: usize,
    /// End of the bytes read.
    len: usize,
}

/// Window size: the largest record the reader accepts plus its header and some slack, so a
/// record at the limit always fits.
const WINDOW: usize = MAX_RECORD as usize + 64 * 1024;

impl<R: Read> Window<R> {
    fn new(input: R, first: &[u8]) -> Self {
        let mut buf = vec![0u8; WINDOW];
        let len = first.len().min(WINDOW);
        buf[..len].copy_from_slice(&first[..len]);
        Window {
            input,
            buf,
            pos: 0,
            len,
        }
    }

    fn bytes(&self) -> &[u8] {
        &self.buf[self.pos..self.len]
    }

    /// Moves the unparsed bytes to the front and reads more; `Ok(false)` at the end of the
    /// input or when the window is full.
    fn fill(&mut self) -> Result<bool, PcapError> {
        self.buf.copy_within(self.pos..self.len, 0);
        self.len -= self.pos;
        self.pos = 0;
        if self.len == self.buf.len() {
            return Ok(false);
        }
        loop {
            match self.input.read(&mut self.buf[self.len..]) {
                Ok(0) => return Ok(false),
                Ok(n) => {
                    self.len += n;
                    return Ok(true);
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(PcapError::Io(e)),
            }
        }
    }

    fn consume(&mut self, n: usize) {
        self.pos = (self.pos + n).min(self.len);
    }

    /// True when every byte of the input has been parsed.
    fn at_end(&mut self) -> Result<bool, PcapError> {
        Ok(self.pos == self.len && !self.fill()?)
    }
}

enum Parser {
    Pcap(pcap_file::pcap::PcapParser),
    PcapNg(Box<pcap_file::pcapng::PcapNgParser>),
}

/// Reads a classic pcap or a pcapng stream record by record (an `Iterator` of
/// `Result<Record>`); stops after the first error. Memory is one fixed window of
/// [`MAX_RECORD`] plus 64 KiB, whatever the file or its length fields say.
pub struct PcapReader<R: Read> {
    window: Window<R>,
    parser: Parser,
    resolution: Option<TimeResolution>,
    /// Records (pcap) or blocks (pcapng) read so far.
    index: u64,
    done: bool,
}

impl<R: Read> fmt::Debug for PcapReader<R> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("PcapReader")
            .field("format", &self.format())
            .field("index", &self.index)
            .finish()
    }
}

impl PcapReader<BufReader<File>> {
    /// Opens `path` and reads the file header.
    pub fn open(path: impl AsRef<Path>) -> Result<Self, PcapError> {
        PcapReader::new(BufReader::new(File::open(path)?))
    }
}

/// Reads up to `buf.len()` bytes, fewer only at the end of the input.
fn read_up_to(input: &mut impl Read, buf: &mut [u8]) -> Result<usize, PcapError> {
    let mut got = 0;
    while let Some(rest) = buf.get_mut(got..).filter(|r| !r.is_empty()) {
        match input.read(rest) {
            Ok(0) => break,
            Ok(n) => got += n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(PcapError::Io(e)),
        }
    }
    Ok(got)
}

/// The length field of the record or block at the start of `bytes`, when it is there:
/// pcap's captured length (bytes 8..12), pcapng's block total length (bytes 4..8).
fn declared_len(bytes: &[u8], format: Format, big_endian: bool) -> Option<u32> {
    let at = match format {
        Format::Pcap => 8,
        Format::PcapNg => 4,
    };
    let w: [u8; 4] = bytes.get(at..at + 4)?.try_into().ok()?;
    Some(if big_endian {
        u32::from_be_bytes(w)
    } else {
        u32::from_le_bytes(w)
    })
}

impl<R: Read> PcapReader<R> {
    /// Reads and checks the file header (pcap: global header; pcapng: the first Section
    /// Header Block).
    pub fn new(mut input: R) -> Result<Self, PcapError> {
        let mut h = [0u8; 24];
        let got = read_up_to(&mut input, &mut h)?;
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
        let resolution = match magic_le {
            MAGIC_MICROS => Some(TimeResolution::Micro),
            MAGIC_NANOS => Some(TimeResolution::Nano),
            m if m.swap_bytes() == MAGIC_MICROS => Some(TimeResolution::Micro),
            m if m.swap_bytes() == MAGIC_NANOS => Some(TimeResolution::Nano),
            PCAPNG_MAGIC => None,
            m => return Err(PcapError::BadMagic(m)),
        };
        if resolution.is_some() && got < h.len() {
            return Err(PcapError::ShortHeader {
                len: got,
                pcap_magic: true,
            });
        }
        let mut window = Window::new(input, &h[..got]);
        let format = if resolution.is_some() {
            Format::Pcap
        } else {
            Format::PcapNg
        };
        let parser = loop {
            let parsed = match format {
                Format::Pcap => pcap_file::pcap::PcapParser::new(window.bytes())
                    .map(|(rest, p)| (rest.len(), Parser::Pcap(p))),
                Format::PcapNg => pcap_file::pcapng::PcapNgParser::new(window.bytes())
                    .map(|(rest, p)| (rest.len(), Parser::PcapNg(Box::new(p)))),
            };
            match parsed {
                Ok((rest, p)) => {
                    let used = window.bytes().len() - rest;
                    window.consume(used);
                    break p;
                }
                Err(pcap_file::PcapError::IncompleteBuffer) if window.fill()? => {}
                Err(e) => return Err(from_crate(e, format, 0)),
            }
        };
        if let Parser::Pcap(p) = &parser {
            let linktype = u32::from(p.header().datalink);
            if linktype != LINKTYPE_ETHERNET {
                return Err(PcapError::UnsupportedLinktype(linktype));
            }
        }
        Ok(PcapReader {
            window,
            parser,
            resolution,
            // pcapng: the Section Header Block was block 0.
            index: u64::from(resolution.is_none()),
            done: false,
        })
    }

    /// The file's format.
    pub fn format(&self) -> Format {
        match self.parser {
            Parser::Pcap(_) => Format::Pcap,
            Parser::PcapNg(_) => Format::PcapNg,
        }
    }

    /// Timestamp resolution of a classic pcap file (`None` for pcapng, where each interface
    /// has its own).
    pub fn resolution(&self) -> Option<TimeResolution> {
        self.resolution
    }

    fn big_endian(&self) -> bool {
        match &self.parser {
            Parser::Pcap(p) => p.header().endianness == Endianness::Big,
            Parser::PcapNg(p) => p.section().endianness == Endianness::Big,
        }
    }

    /// Parses the next record or block out of the window: `Ok(None)` at a clean end.
    fn next_item(&mut self) -> Result<Option<Item>, PcapError> {
        let (format, index, big_endian) = (self.format(), self.index, self.big_endian());
        if self.window.at_end()? {
            return Ok(None);
        }
        loop {
            let bytes = self.window.bytes();
            let parsed = match &mut self.parser {
                Parser::Pcap(p) => p.next_packet(bytes).map(|(rest, pkt)| {
                    let ts = u64::try_from(pkt.timestamp.as_nanos()).unwrap_or(u64::MAX);
                    let item = copy_out(format, index, &pkt.data).map(|data| {
                        Item::Frame(Record {
                            ts_ns: Some(ts),
                            orig_len: pkt.orig_len,
                            data,
                        })
                    });
                    (rest.len(), item)
                }),
                Parser::PcapNg(p) => p.next_block(bytes).map(|(rest, block)| {
                    let item = match block {
                        Block::EnhancedPacket(b) => {
                            copy_out(format, index, &b.data).map(|data| Item::NgFrame {
                                interface: b.interface_id,
                                raw_ts: Some(b.timestamp),
                                orig_len: b.original_len,
                                data,
                            })
                        }
                        Block::SimplePacket(b) => {
                            copy_out(format, index, &b.data).map(|data| Item::NgFrame {
                                interface: 0,
                                raw_ts: None,
                                orig_len: b.original_len,
                                data,
                            })
                        }
                        // Section and interface blocks are kept by the parser; statistics,
                        // name resolution and unknown blocks carry no frame.
                        _ => Ok(Item::Other),
                    };
                    (rest.len(), item)
                }),
            };
            match parsed {
                Ok((rest, item)) => {
                    let used = self.window.bytes().len() - rest;
                    self.window.consume(used);
                    self.index += 1;
                    return item.map(Some);
                }
                Err(pcap_file::PcapError::IncompleteBuffer) => {
                    // pcap: the captured length; pcapng: the whole block (headers, options).
                    let limit = match format {
                        Format::Pcap => MAX_RECORD as usize,
                        Format::PcapNg => WINDOW,
                    };
                    if let Some(n) = declared_len(self.window.bytes(), format, big_endian)
                        .filter(|n| *n as usize > limit)
                    {
                        return Err(PcapError::BadRecord {
                            format,
                            index,
                            reason: format!(
                                "length field {n} above the reader's limit ({limit} bytes)"
                            ),
                        });
                    }
                    if !self.window.fill()? {
                        return Err(PcapError::TruncatedRecord { format, index });
                    }
                }
                Err(e) => return Err(from_crate(e, format, index)),
            }
        }
    }

    fn read_record(&mut self) -> Result<Option<Record>, PcapError> {
        loop {
            let index = self.index;
            let (interface, raw_ts, orig_len, data) = match self.next_item()? {
                None => return Ok(None),
                Some(Item::Frame(r)) => return Ok(Some(r)),
                Some(Item::Other) => continue,
                Some(Item::NgFrame {
                    interface,
                    raw_ts,
                    orig_len,
                    data,
                }) => (interface, raw_ts, orig_len, data),
            };
            let Parser::PcapNg(p) = &self.parser else {
                return Ok(None);
            };
            let Some(idb) = p.interfaces().get(interface as usize) else {
                return Err(PcapError::BadRecord {
                    format: Format::PcapNg,
                    index,
                    reason: format!("packet of interface {interface}, which is not described"),
                });
            };
            let linktype = u32::from(idb.linktype);
            if linktype != LINKTYPE_ETHERNET {
                return Err(PcapError::UnsupportedLinktype(linktype));
            }
            return Ok(Some(Record {
                ts_ns: raw_ts.map(|t| ng_timestamp_ns(t, idb)),
                orig_len,
                data,
            }));
        }
    }
}

/// What one record or block held.
enum Item {
    /// A classic pcap record.
    Frame(Record),
    /// A pcapng packet; its interface gives the link type and the timestamp's unit.
    NgFrame {
        interface: u32,
        raw_ts: Option<Duration>,
        orig_len: u32,
        data: Vec<u8>,
    },
    /// A pcapng block without a frame.
    Other,
}

/// The captured bytes of record or block `index`, refused above [`MAX_RECORD`].
fn copy_out(format: Format, index: u64, data: &[u8]) -> Result<Vec<u8>, PcapError> {
    if data.len() > MAX_RECORD as usize {
        return Err(PcapError::BadRecord {
            format,
            index,
            reason: format!(
                "captured length {} above the reader's limit of {MAX_RECORD} bytes",
                data.len()
            ),
        });
    }
    Ok(data.to_vec())
}

/// An Enhanced Packet Block's timestamp in ns. The crate (2.0) hands out the block's raw
/// 64-bit count as if it were ns; its unit is the interface's `if_tsresol`: 10^-v s when the
/// top bit is clear, 2^-v s when it is set, 10^-6 s when the option is absent.
fn ng_timestamp_ns(raw_as_ns: Duration, idb: &InterfaceDescriptionBlock<'_>) -> u64 {
    let raw = raw_as_ns.as_nanos();
    let tsresol = idb
        .options
        .iter()
        .find_map(|o| match o {
            InterfaceDescriptionOption::IfTsResol(v) => Some(*v),
            _ => None,
        })
        .unwrap_or(6);
    let v = u32::from(tsresol & 0x7F);
    let ns = if tsresol & 0x80 == 0 {
        if v <= 9 {
            raw.saturating_mul(10u128.pow(9 - v))
        } else {
            // 10^38 is the largest power of ten a u128 holds; beyond, every count is 0 ns.
            10u128.checked_pow(v - 9).map_or(0, |d| raw / d)
        }
    } else {
        // raw < 2^64 and 10^9 < 2^30: the product fits in u128.
        raw.saturating_mul(1_000_000_000)
            .checked_shr(v)
            .unwrap_or(0)
    };
    u64::try_from(ns).unwrap_or(u64::MAX)
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

/// Writes `frames` (timestamp ns, bytes) to `path`: a nanosecond classic pcap, or pcapng
/// when the name ends in `.pcapng`.
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

/// Reads every record of `path` (for small files and tests; `ecdc decode` streams).
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
                ts_ns: Some(5_000_007_000),
                orig_len: 60,
                data: vec![0xab, 0xcd]
            }
        );
        assert_eq!(recs.len(), 1);
        // cut inside the record
        let r: Vec<_> = PcapReader::new(&f[..f.len() - 1]).unwrap().collect();
        assert!(matches!(
            r[0],
            Err(PcapError::TruncatedRecord {
                format: Format::Pcap,
                index: 0
            })
        ));
    }

    #[test]
    fn write_read_roundtrip_both_resolutions_and_pcapng() {
        for res in [
            Some(TimeResolution::Micro),
            Some(TimeResolution::Nano),
            None,
        ] {
            let mut w = match res {
                Some(r) => PcapWriter::new(Vec::new(), r).unwrap(),
                None => PcapWriter::new_pcapng(Vec::new()).unwrap(),
            };
            w.write_frame(1_500_000_123, &[1, 2, 3]).unwrap();
            w.write_frame(0, &[]).unwrap();
            let bytes = w.finish().unwrap();
            let r = PcapReader::new(&bytes[..]).unwrap();
            assert_eq!(r.resolution(), res);
            let recs: Vec<_> = r.map(|x| x.unwrap()).collect();
            let ts = if res == Some(TimeResolution::Micro) {
                1_500_000_000
            } else {
                1_500_000_123
            };
            assert_eq!(recs[0].ts_ns, Some(ts));
            assert_eq!(recs[0].data, [1, 2, 3]);
            assert_eq!(recs[1].data, [0u8; 0]);
            assert_eq!(recs.len(), 2);
        }
    }

    /// if_tsresol: absent = µs, decimal and binary exponents.
    #[test]
    fn pcapng_timestamp_units() {
        let idb = |opt: Option<u8>| InterfaceDescriptionBlock {
            linktype: DataLink::ETHERNET,
            snaplen: 0,
            options: opt
                .map(InterfaceDescriptionOption::IfTsResol)
                .into_iter()
                .collect(),
        };
        let raw = Duration::from_nanos(1_234);
        assert_eq!(ng_timestamp_ns(raw, &idb(None)), 1_234_000);
        assert_eq!(ng_timestamp_ns(raw, &idb(Some(9))), 1_234);
        assert_eq!(ng_timestamp_ns(raw, &idb(Some(3))), 1_234_000_000);
        assert_eq!(ng_timestamp_ns(raw, &idb(Some(10))), 123);
        assert_eq!(ng_timestamp_ns(raw, &idb(Some(0x80 | 10))), 1_205_078_125);
        assert_eq!(ng_timestamp_ns(raw, &idb(Some(0x7F))), 0);
        assert_eq!(ng_timestamp_ns(raw, &idb(Some(0xFF))), 0);
        let big = Duration::from_nanos(u64::MAX);
        assert_eq!(ng_timestamp_ns(big, &idb(Some(0))), u64::MAX);
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
    fn rejects_non_pcap_and_bad_records() {
        // A pcapng section header whose block length is 0 is refused, not looped on.
        let mut ng = vec![0x0a, 0x0d, 0x0d, 0x0a];
        ng.resize(8, 0);
        ng.extend_from_slice(&0x1a2b_3c4du32.to_le_bytes());
        ng.resize(28, 0);
        let e = PcapReader::new(&ng[..]).unwrap_err();
        assert!(e.to_string().starts_with("pcapng block 0"), "{e}");
        let junk = [0u8; 24];
        assert!(matches!(
            PcapReader::new(&junk[..]),
            Err(PcapError::BadMagic(0))
        ));
        // A classic global header: magic, version 2.4, zone and sigfigs 0, snaplen, linktype.
        let header = |magic: [u8; 4], version: [u8; 4], snaplen: [u8; 4], linktype: [u8; 4]| {
            [magic, version, [0; 4], [0; 4], snaplen, linktype].concat()
        };
        let raw_ip = header(
            MAGIC_MICROS.to_le_bytes(),
            [2, 0, 4, 0],
            [0; 4],
            101u32.to_le_bytes(),
        );
        assert!(matches!(
            PcapReader::new(&raw_ip[..]),
            Err(PcapError::UnsupportedLinktype(101))
        ));
        // big-endian header is accepted
        let be = header(
            MAGIC_NANOS.to_be_bytes(),
            [0, 2, 0, 4],
            SNAPLEN.to_be_bytes(),
            1u32.to_be_bytes(),
        );
        assert_eq!(
            PcapReader::new(&be[..]).unwrap().resolution(),
            Some(TimeResolution::Nano)
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
