//! `ecdc decode FILE.pcap|FILE.pcapng|HEX`: print each frame's datagrams as a table, or the typed
//! `ecdc_core::wire::Error` that makes the frame invalid (REQ-WIRE-016).
//!
//! Frames may be EtherCAT over Ethernet (EtherType 0x88A4, one 802.1Q tag tolerated) or over
//! UDP port 0x88A4. Datagrams before the first error are still shown, so a broken frame can be
//! diagnosed. Frames that are not EtherCAT at all (ARP, IP traffic in a mixed capture) are
//! listed as skipped. The command fails (exit status 1) if any EtherCAT frame is invalid or if
//! no EtherCAT frame was found; an input that is neither a readable capture (classic pcap or
//! pcapng) nor hex is a usage error (exit status 2) whose message says which. A capture is
//! read and printed a record at a time, so a file cut or corrupted part-way prints the frames
//! before the damage, then the error.

use super::validate::usage;
use crate::capture::{pcap, udp};
use anyhow::bail;
use ecdc_core::wire::{Command, Datagram, EcatFrame, EthernetFrame, ETHERTYPE_ETHERCAT};
use std::fmt::Write as _;
use std::io::Write as IoWrite;
use std::path::Path;

/// Arguments of `ecdc decode`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// A capture file (classic pcap or pcapng), or one frame as hex (whitespace, ':' and '-' are ignored; an
    /// optional leading 0x is allowed).
    pub input: String,
    /// The hex is a bare EtherCAT payload (EtherCAT header + datagrams, e.g. a UDP payload)
    /// rather than an Ethernet frame.
    #[arg(long)]
    pub payload: bool,
    /// Print all data bytes (default: the first 16, then the count of the rest).
    #[arg(long)]
    pub full: bool,
}

/// Runs `ecdc decode`.
pub fn run(args: &Args) -> anyhow::Result<()> {
    let stdout = std::io::stdout();
    let mut out = std::io::BufWriter::new(stdout.lock());
    let mut tally = Tally::default();
    match open(args)? {
        Input::Hex(bytes) => tally.frame(&mut out, None, &bytes, args)?,
        Input::Capture(reader) => {
            // One record at a time: memory does not grow with the file.
            for rec in reader {
                match rec {
                    Ok(r) => tally.frame(&mut out, r.ts_ns, &r.data, args)?,
                    Err(e) => {
                        out.flush()?;
                        return Err(match e {
                            pcap::PcapError::Io(e) => {
                                anyhow::Error::new(e).context(format!("reading {}", args.input))
                            }
                            e => usage(format!("{}: {e}", args.input)),
                        });
                    }
                }
            }
            if tally.frames == 0 {
                return Err(usage(format!(
                    "{}: the capture holds no frames (header only)",
                    args.input
                )));
            }
        }
    }
    let Tally {
        frames,
        bad,
        skipped,
        ..
    } = tally;
    let ecat = frames - skipped;
    writeln!(
        out,
        "{frames} frame(s): {} valid, {bad} invalid, {skipped} not EtherCAT",
        ecat - bad
    )?;
    out.flush()?;
    if bad > 0 {
        bail!("{bad} of {ecat} EtherCAT frame(s) invalid");
    }
    if ecat == 0 {
        bail!("no EtherCAT frame found ({skipped} other frame(s) skipped)");
    }
    Ok(())
}

/// Counts of what was decoded so far.
#[derive(Debug, Default)]
struct Tally {
    frames: usize,
    bad: usize,
    skipped: usize,
    text: String,
}

impl Tally {
    /// Renders one frame to `out` and counts it.
    fn frame(
        &mut self,
        out: &mut impl IoWrite,
        ts: Option<u64>,
        bytes: &[u8],
        args: &Args,
    ) -> anyhow::Result<()> {
        self.frames += 1;
        self.text.clear();
        match render_frame(
            &mut self.text,
            self.frames,
            ts,
            bytes,
            args.payload,
            args.full,
        ) {
            Outcome::Valid => {}
            Outcome::Invalid => self.bad += 1,
            Outcome::NotEtherCat => self.skipped += 1,
        }
        out.write_all(self.text.as_bytes())?;
        Ok(())
    }
}

/// What `ecdc decode` reads.
enum Input {
    /// A capture file, read record by record.
    Capture(pcap::PcapReader<std::io::BufReader<std::fs::File>>),
    /// One frame given as hex.
    Hex(Vec<u8>),
}

/// Opens the capture or parses the hex.
fn open(args: &Args) -> anyhow::Result<Input> {
    let path = Path::new(&args.input);
    if path.is_dir() {
        return Err(usage(format!(
            "{}: is a directory; give a pcap/pcapng file or a hex string",
            args.input
        )));
    }
    // Anything that exists and is not a directory is read as a capture (a FIFO, /dev/stdin).
    if path.exists() {
        return match pcap::PcapReader::open(path) {
            Ok(r) => Ok(Input::Capture(r)),
            Err(pcap::PcapError::Io(e)) => {
                Err(anyhow::Error::new(e).context(format!("reading {}", args.input)))
            }
            Err(e) => Err(usage(format!("{}: {e}", args.input))),
        };
    }
    let looks_like_path = args.input.contains('/')
        || [".pcap", ".pcapng", ".cap"]
            .iter()
            .any(|x| args.input.to_ascii_lowercase().ends_with(x));
    if looks_like_path {
        return Err(usage(format!(
            "{}: no such file (give an existing pcap/pcapng file or a hex string)",
            args.input
        )));
    }
    let bytes = parse_hex(&args.input).map_err(|e| {
        usage(format!(
            "{:?} is neither an existing file nor a hex string: {e}",
            args.input
        ))
    })?;
    Ok(Input::Hex(bytes))
}

/// Parses hex digits, ignoring whitespace, ':' and '-', and an optional leading "0x".
pub fn parse_hex(s: &str) -> anyhow::Result<Vec<u8>> {
    let s = s.trim();
    let s = s
        .strip_prefix("0x")
        .or_else(|| s.strip_prefix("0X"))
        .unwrap_or(s);
    let digits: Vec<u8> = s
        .bytes()
        .filter(|c| !c.is_ascii_whitespace() && *c != b':' && *c != b'-')
        .collect();
    if digits.is_empty() {
        bail!("empty hex string");
    }
    if digits.len() & 1 == 1 {
        bail!("odd number of hex digits ({})", digits.len());
    }
    digits
        .chunks(2)
        .map(|p| {
            let hi = hex_val(p[0])?;
            let lo = hex_val(p[1])?;
            Ok(hi << 4 | lo)
        })
        .collect()
}

fn hex_val(c: u8) -> anyhow::Result<u8> {
    match c {
        b'0'..=b'9' => Ok(c - b'0'),
        b'a'..=b'f' => Ok(c - b'a' + 10),
        b'A'..=b'F' => Ok(c - b'A' + 10),
        _ => bail!("invalid hex digit {:?}", c as char),
    }
}

fn mac(m: [u8; 6]) -> String {
    m.iter()
        .map(|b| format!("{b:02x}"))
        .collect::<Vec<_>>()
        .join(":")
}

fn hex(bytes: &[u8], full: bool) -> String {
    const SHOWN: usize = 16;
    let n = if full {
        bytes.len()
    } else {
        bytes.len().min(SHOWN)
    };
    let mut s = bytes[..n]
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect::<Vec<_>>()
        .join(" ");
    if n < bytes.len() {
        let _ = write!(s, " … (+{})", bytes.len() - n);
    }
    s
}

/// What [`render_frame`] found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    /// A valid EtherCAT frame.
    Valid,
    /// An EtherCAT frame (or a frame cut before its EtherType) that fails validation.
    Invalid,
    /// Not EtherCAT (other EtherType, or IP traffic not on port 34980): skipped.
    NotEtherCat,
}

/// Appends the description of one frame to `out`.
pub fn render_frame(
    out: &mut String,
    number: usize,
    ts_ns: Option<u64>,
    bytes: &[u8],
    bare_payload: bool,
    full: bool,
) -> Outcome {
    let _ = write!(out, "frame {number}");
    if let Some(ts) = ts_ns {
        let _ = write!(out, "  t={}.{:09}", ts / 1_000_000_000, ts % 1_000_000_000);
    }
    let _ = write!(out, "  {} bytes", bytes.len());
    let payload: &[u8] = if bare_payload {
        let _ = writeln!(out, "  (bare EtherCAT payload)");
        bytes
    } else {
        let eth = match EthernetFrame::new_checked(bytes) {
            Ok(e) => e,
            Err(e) => {
                let _ = writeln!(out, "\n  error: Ethernet header: {e} ({e:?})");
                return Outcome::Invalid;
            }
        };
        let who = if eth.processed_by_slave() {
            "returned through a slave"
        } else {
            "not processed by a slave"
        };
        let _ = write!(out, "  {} -> {}  ({who})", mac(eth.src()), mac(eth.dst()));
        if let Some(tci) = eth.vlan() {
            let _ = write!(out, "  vlan {} pcp {}", tci & 0x0FFF, tci >> 13);
        }
        if eth.ethertype() == ETHERTYPE_ETHERCAT {
            let _ = writeln!(out);
            eth.into_payload()
        } else if let Some(u) = udp::unwrap(bytes) {
            let ip = |a: [u8; 4]| format!("{}.{}.{}.{}", a[0], a[1], a[2], a[3]);
            let _ = writeln!(out, "  UDP {} -> {} port 34980", ip(u.src_ip), ip(u.dst_ip));
            &bytes[u.offset..u.offset + u.len]
        } else {
            let e = ecdc_core::wire::Error::NotEtherCat {
                ethertype: eth.ethertype(),
            };
            let _ = writeln!(out, "\n  skipped: {e} ({e:?})");
            return Outcome::NotEtherCat;
        }
    };
    if render_ecat(out, payload, full) {
        Outcome::Valid
    } else {
        Outcome::Invalid
    }
}

fn render_ecat(out: &mut String, payload: &[u8], full: bool) -> bool {
    let frame = EcatFrame::new_unchecked(payload);
    let _ = writeln!(
        out,
        "  EtherCAT header: length {} type {}{}  padding {}",
        frame.length(),
        frame.frame_type(),
        if frame.reserved() {
            " RESERVED-BIT"
        } else {
            ""
        },
        frame.padding().len()
    );
    let _ = writeln!(
        out,
        "  {:>2}  {:<4}  {:>4}  {:<26}  {:>4}  {:<3}  {:>6}  {:>5}  data",
        "#", "cmd", "idx", "address", "len", "CM", "irq", "wkc"
    );
    let mut ok = true;
    for (i, d) in frame.iter().enumerate() {
        match d {
            Ok(d) => {
                let _ = writeln!(out, "  {}", datagram_row(i, &d, full));
            }
            Err(e) => {
                let _ = writeln!(out, "  error: {e} ({e:?})");
                ok = false;
            }
        }
    }
    ok
}

fn datagram_row(i: usize, d: &Datagram<&[u8]>, full: bool) -> String {
    let (name, addr) = match d.command() {
        Ok(c) => (c.name().to_string(), address(c, d)),
        Err(_) => (format!("?{}", d.command_raw()), String::new()),
    };
    let flags = format!(
        "{}{}",
        if d.circulating() { 'C' } else { '-' },
        if d.more() { 'M' } else { '-' }
    );
    format!(
        "{i:>2}  {name:<4}  {:#04x}  {addr:<26}  {:>4}  {flags:<3}  {:#06x}  {:>5}  {}",
        d.index(),
        d.data_len(),
        d.irq(),
        d.wkc(),
        hex(d.data(), full)
    )
}

fn address(c: Command, d: &Datagram<&[u8]>) -> String {
    use ecdc_core::wire::Addressing;
    match c.addressing() {
        Addressing::Position => format!(
            "pos {} ado {:#06x}",
            ecdc_core::wire::Address::position_of_adp(d.adp()),
            d.ado()
        ),
        Addressing::Configured => format!("station {:#06x} ado {:#06x}", d.adp(), d.ado()),
        Addressing::Broadcast => format!("adp {:#06x} ado {:#06x}", d.adp(), d.ado()),
        Addressing::Logical => format!("logical {:#010x}", d.logical_address()),
        Addressing::None => format!("raw {:#010x}", d.logical_address()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hex_parsing() {
        assert_eq!(
            parse_hex("0x0a ff:10-2B").unwrap(),
            [0x0a, 0xff, 0x10, 0x2b]
        );
        assert!(parse_hex("abc").is_err());
        assert!(parse_hex("zz").is_err());
        assert!(parse_hex("  ").is_err());
    }

    /// The base frame of docs/background/wire-format.md §2.3, by hand, and a corrupted copy.
    #[test]
    fn renders_base_frame_and_error() {
        let hex_frame = "ffffffffffff 101010101010 88a4 2210 \
            07 01 0000 0000 0280 0000 0000 0000 \
            0e 02 0110 1009 0800 0000 0000000000000000 0000 \
            00000000000000000000";
        let bytes = parse_hex(hex_frame).unwrap();
        let mut out = String::new();
        assert_eq!(
            render_frame(&mut out, 1, None, &bytes, false, false),
            Outcome::Valid
        );
        assert!(out.contains("BRD"), "{out}");
        assert!(out.contains("FRMW"), "{out}");
        assert!(out.contains("station 0x1001 ado 0x0910"), "{out}");
        let mut bad = bytes.clone();
        bad[14] = 32; // header length 32: FRMW ends past it
        let mut out = String::new();
        assert_eq!(
            render_frame(&mut out, 1, None, &bad, false, false),
            Outcome::Invalid
        );
        assert!(
            out.contains("LengthMismatch { header: 32, walked: 34 }"),
            "{out}"
        );
        assert!(
            out.contains("BRD"),
            "datagrams before the error are shown: {out}"
        );
    }
}
