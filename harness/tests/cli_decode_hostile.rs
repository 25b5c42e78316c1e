//! `ecdc decode` on hostile capture files: truncated records, absurd record lengths, a huge
//! snaplen, pcapng (a block whose length would loop a reader, a block claiming 1 GiB, a
//! packet of an undescribed interface) and a 50 MiB file of records of maximum length. Each
//! fails with a typed message or decodes, never panics, and the process's peak memory stays
//! bounded (getrusage of the child): a length field never becomes an allocation beyond the
//! reader's buffer, and the file is streamed, not held.

use std::io::Write;
use std::process::{Command, Output};

use ecdc_harness::capture::pcap::MAX_RECORD;

const MAGIC_NANOS: u32 = 0xa1b2_3c4d;

/// ecdc choice: 64 MiB peak resident memory for decoding any of these files, because the
/// largest legitimate allocation is one record (256 KiB) plus the binary itself (a few MiB);
/// a reader that trusted a 4 GiB length would blow through it.
const MAX_RSS_KIB: i64 = 64 * 1024;

fn global_header(snaplen: u32) -> Vec<u8> {
    let mut h = Vec::new();
    h.extend_from_slice(&MAGIC_NANOS.to_le_bytes());
    h.extend_from_slice(&2u16.to_le_bytes());
    h.extend_from_slice(&4u16.to_le_bytes());
    h.extend_from_slice(&0i32.to_le_bytes());
    h.extend_from_slice(&0u32.to_le_bytes());
    h.extend_from_slice(&snaplen.to_le_bytes());
    h.extend_from_slice(&1u32.to_le_bytes()); // Ethernet
    h
}

fn record_header(incl: u32, orig: u32) -> Vec<u8> {
    let mut r = Vec::new();
    r.extend_from_slice(&1u32.to_le_bytes());
    r.extend_from_slice(&2u32.to_le_bytes());
    r.extend_from_slice(&incl.to_le_bytes());
    r.extend_from_slice(&orig.to_le_bytes());
    r
}

/// A minimal EtherCAT frame (one BRD of 2 bytes).
fn ecat_frame() -> Vec<u8> {
    let mut buf = [0u8; 128];
    let mut b = ecdc_core::wire::FrameBuilder::new(&mut buf).unwrap();
    b.push(
        ecdc_core::wire::Command::Brd,
        1,
        ecdc_core::wire::Address::broadcast(0x0130),
        &[0, 0],
    )
    .unwrap();
    let n = b.finish().unwrap();
    buf[..n].to_vec()
}

/// Runs `ecdc decode FILE` in a child and returns (output, its peak RSS in KiB).
fn decode(name: &str, bytes: &[u8]) -> (Output, i64) {
    let path = temp_path(name);
    std::fs::File::create(&path)
        .unwrap()
        .write_all(bytes)
        .unwrap();
    decode_file(&path)
}

fn temp_path(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("ecdc-hostile-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

/// Runs `ecdc decode` on `path` (then removes it). The caller must not hold large buffers:
/// the child's peak RSS includes what it shared with this process before `exec`.
fn decode_file(path: &std::path::Path) -> (Output, i64) {
    // /usr/bin/time would add a dependency on the host; the child's rusage is exact.
    let child = Command::new(env!("CARGO_BIN_EXE_ecdc"))
        .arg("decode")
        .arg(path)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let out = child.wait_with_output().unwrap();
    let mut ru: libc::rusage = unsafe { std::mem::zeroed() };
    // RUSAGE_CHILDREN: the largest peak of any waited-for child so far (of this test
    // process), so an earlier larger child would show here too: each test runs its own files.
    let rc = unsafe { libc::getrusage(libc::RUSAGE_CHILDREN, &mut ru) };
    assert_eq!(rc, 0);
    let _ = std::fs::remove_file(path);
    (out, ru.ru_maxrss)
}

/// A pcapng Section Header Block (little-endian, no options) and one Ethernet Interface
/// Description Block (nanosecond timestamps).
fn pcapng_head() -> Vec<u8> {
    let mut f = Vec::new();
    for w in [0x0a0d_0d0au32, 28, 0x1a2b_3c4d] {
        f.extend_from_slice(&w.to_le_bytes());
    }
    f.extend_from_slice(&1u16.to_le_bytes());
    f.extend_from_slice(&0u16.to_le_bytes());
    f.extend_from_slice(&(-1i64).to_le_bytes());
    f.extend_from_slice(&28u32.to_le_bytes());
    // IDB: type 1, length 32, linktype 1, reserved, snaplen 0, if_tsresol = 9, opt_endofopt.
    for w in [1u32, 32] {
        f.extend_from_slice(&w.to_le_bytes());
    }
    f.extend_from_slice(&1u16.to_le_bytes());
    f.extend_from_slice(&0u16.to_le_bytes());
    f.extend_from_slice(&0u32.to_le_bytes());
    f.extend_from_slice(&[9, 0, 1, 0, 9, 0, 0, 0]);
    f.extend_from_slice(&0u32.to_le_bytes());
    f.extend_from_slice(&32u32.to_le_bytes());
    f
}

/// An Enhanced Packet Block for `interface` holding `data`, timestamp 5 ns.
fn pcapng_epb(interface: u32, data: &[u8]) -> Vec<u8> {
    let padded = data.len().div_ceil(4) * 4;
    let total = (32 + padded) as u32;
    let mut b = Vec::new();
    for w in [
        6u32,
        total,
        interface,
        0,
        5,
        data.len() as u32,
        data.len() as u32,
    ] {
        b.extend_from_slice(&w.to_le_bytes());
    }
    b.extend_from_slice(data);
    b.resize(28 + padded, 0);
    b.extend_from_slice(&total.to_le_bytes());
    b
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// One test, in order: RUSAGE_CHILDREN is the peak of every child this process has waited
/// for, so the large file goes last and nothing runs in parallel with it.
#[test]
fn hostile_capture_files() {
    hostile_pcap_files_fail_cleanly_with_bounded_memory();
    hand_written_pcapng_decodes();
    huge_snaplen_with_real_records_decodes();
    many_maximum_records_decode_without_panic();
}

fn hostile_pcap_files_fail_cleanly_with_bounded_memory() {
    let frame = ecat_frame();
    let mut cases: Vec<(&str, Vec<u8>, Option<&str>)> = Vec::new();
    // Truncated record header.
    let mut f = global_header(65535);
    f.extend_from_slice(&record_header(10, 10)[..7]);
    cases.push(("trunc-header.pcap", f, Some("ends inside")));
    // Truncated record data.
    let mut f = global_header(65535);
    f.extend(record_header(frame.len() as u32, frame.len() as u32));
    f.extend_from_slice(&frame[..frame.len() / 2]);
    cases.push(("trunc-data.pcap", f, Some("ends inside")));
    // Absurd record length (4 GiB − 1), with nothing behind it.
    let mut f = global_header(65535);
    f.extend(record_header(u32::MAX, u32::MAX));
    cases.push(("absurd-len.pcap", f, Some("")));
    // Just above the per-record limit.
    let mut f = global_header(65535);
    f.extend(record_header(MAX_RECORD + 1, MAX_RECORD + 1));
    cases.push(("over-limit.pcap", f, Some("")));
    // At the limit, but the file ends: the allocation is the limit at most.
    let mut f = global_header(u32::MAX);
    f.extend(record_header(MAX_RECORD, MAX_RECORD));
    f.extend_from_slice(&[0u8; 100]);
    cases.push(("at-limit-truncated.pcap", f, Some("ends inside")));
    // pcapng: a section header block whose total length is 0 (a reader walking blocks by
    // their length would loop on it).
    let mut f = vec![0x0a, 0x0d, 0x0d, 0x0a, 0, 0, 0, 0];
    f.extend_from_slice(&0x1a2b_3c4du32.to_le_bytes());
    f.extend_from_slice(&[0u8; 16]);
    cases.push(("loop.pcapng", f, Some("pcapng")));
    // pcapng: a valid section and interface, then an Enhanced Packet Block that claims
    // 1 GiB and ends: refused without allocating it.
    let mut f = pcapng_head();
    f.extend_from_slice(&6u32.to_le_bytes());
    f.extend_from_slice(&0x4000_0000u32.to_le_bytes());
    f.extend_from_slice(&[0u8; 64]);
    cases.push(("huge-block.pcapng", f, Some("pcapng block 2")));
    // pcapng: a packet of an interface that was never described.
    let mut f = pcapng_head();
    f.extend(pcapng_epb(7, &frame));
    cases.push(("no-interface.pcapng", f, Some("not described")));
    for (name, bytes, want) in &cases {
        let (o, rss) = decode(name, bytes);
        let err = stderr(&o);
        assert!(!o.status.success(), "{name}: accepted; stderr {err}");
        assert!(!err.contains("panicked"), "{name}: {err}");
        if let Some(w) = want {
            assert!(err.contains(w), "{name}: {err}");
        }
        assert!(rss < MAX_RSS_KIB, "{name}: peak RSS {rss} KiB");
        eprintln!("{name}: peak RSS {rss} KiB: {}", err.trim());
    }
}

fn hand_written_pcapng_decodes() {
    let frame = ecat_frame();
    let mut f = pcapng_head();
    for _ in 0..3 {
        f.extend(pcapng_epb(0, &frame));
    }
    let (o, rss) = decode("three.pcapng", &f);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("frame 1  t=0.000000005"), "{out}");
    assert!(out.contains("3 frame(s): 3 valid"), "{out}");
    assert!(rss < MAX_RSS_KIB, "peak RSS {rss} KiB");
}

fn huge_snaplen_with_real_records_decodes() {
    let frame = ecat_frame();
    let mut f = global_header(u32::MAX);
    for _ in 0..3 {
        f.extend(record_header(frame.len() as u32, frame.len() as u32));
        f.extend_from_slice(&frame);
    }
    let (o, rss) = decode("huge-snaplen.pcap", &f);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(rss < MAX_RSS_KIB, "peak RSS {rss} KiB");
}

fn many_maximum_records_decode_without_panic() {
    // 200 records of MAX_RECORD bytes of junk (50 MiB file). `decode` streams one record at
    // a time, so peak memory stays under the bound although the file is close to it.
    let path = temp_path("many-max.pcap");
    {
        let mut f = std::io::BufWriter::new(std::fs::File::create(&path).unwrap());
        f.write_all(&global_header(u32::MAX)).unwrap();
        let junk = vec![0xEEu8; MAX_RECORD as usize];
        for _ in 0..200 {
            f.write_all(&record_header(MAX_RECORD, MAX_RECORD)).unwrap();
            f.write_all(&junk).unwrap();
        }
    }
    let (o, rss) = decode_file(&path);
    let err = stderr(&o);
    assert!(!err.contains("panicked"), "{err}");
    eprintln!("many-max: exit {:?}, peak RSS {rss} KiB", o.status.code());
    // A reader that held the 50 MiB file, or its records, would pass 16 MiB.
    assert!(rss < 16 * 1024, "many-max: peak RSS {rss} KiB");
}

/// A reader that closes the pipe early (`ecdc decode big.pcap | head -1`) ends the process
/// quietly: no panic message about a failed print.
#[test]
fn closed_stdout_ends_quietly() {
    let path = temp_path("pipe.pcap");
    {
        let mut f = std::io::BufWriter::new(std::fs::File::create(&path).unwrap());
        f.write_all(&global_header(65535)).unwrap();
        let frame = ecat_frame();
        for _ in 0..20_000 {
            f.write_all(&record_header(frame.len() as u32, frame.len() as u32))
                .unwrap();
            f.write_all(&frame).unwrap();
        }
    }
    let mut child = Command::new(env!("CARGO_BIN_EXE_ecdc"))
        .arg("decode")
        .arg(&path)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Read one line, then close the pipe while the child is still writing.
    {
        let out = child.stdout.take().unwrap();
        let mut line = String::new();
        std::io::BufRead::read_line(&mut std::io::BufReader::new(out), &mut line).unwrap();
        assert!(line.starts_with("frame 1"), "{line}");
    }
    let o = child.wait_with_output().unwrap();
    let err = stderr(&o);
    assert!(!err.contains("panicked"), "{err}");
    assert!(!err.contains("Broken pipe"), "{err}");
    let _ = std::fs::remove_file(&path);
}
