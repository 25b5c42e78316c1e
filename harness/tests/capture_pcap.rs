//! pcap files: our writer and reader round-trip frames built by the codec, and our reader
//! accepts a file written by an independent tool (Wireshark's `text2pcap`, installed with
//! tshark; skipped with a message if absent). Files ours writes are opened by tshark in
//! `tshark.rs`.

use ecdc_core::wire::{Address, Command, EthernetFrame, FrameBuilder};
use ecdc_harness::capture::{pcap, PcapReader, PcapWriter, TimeResolution};
use std::path::{Path, PathBuf};
use std::process::{Command as Process, Output};

fn sample_frames() -> Vec<Vec<u8>> {
    (0..5u8)
        .map(|i| {
            let mut buf = vec![0u8; 1514];
            let n = {
                let mut b = FrameBuilder::new(&mut buf).unwrap();
                b.push(Command::Brd, i, Address::broadcast(0x0130), &[i, 0])
                    .unwrap();
                b.push(
                    Command::Lrw,
                    i.wrapping_add(100),
                    Address::logical(0),
                    &vec![i; 10 * usize::from(i)],
                )
                .unwrap();
                b.finish().unwrap()
            };
            buf.truncate(n);
            buf
        })
        .collect()
}

#[test]
fn write_then_read_back_equal() {
    let frames = sample_frames();
    for res in [TimeResolution::Micro, TimeResolution::Nano] {
        let mut w = PcapWriter::new(Vec::new(), res).unwrap();
        for (i, f) in frames.iter().enumerate() {
            w.write_frame(1_700_000_000_000_000_000 + i as u64 * 1_001_001, f)
                .unwrap();
        }
        let bytes = w.finish().unwrap();
        assert_eq!(
            bytes.len(),
            24 + frames.iter().map(|f| 16 + f.len()).sum::<usize>()
        );
        let recs: Vec<_> = PcapReader::new(&bytes[..])
            .unwrap()
            .map(|r| r.unwrap())
            .collect();
        assert_eq!(recs.len(), frames.len());
        for (i, (r, f)) in recs.iter().zip(&frames).enumerate() {
            assert_eq!(&r.data, f);
            assert_eq!(r.orig_len as usize, f.len());
            let ts = 1_700_000_000_000_000_000 + i as u64 * 1_001_001;
            let want = match res {
                TimeResolution::Nano => ts,
                TimeResolution::Micro => ts / 1000 * 1000,
            };
            assert_eq!(r.ts_ns, Some(want));
            // and each frame still parses
            let eth = EthernetFrame::new_checked(&r.data[..]).unwrap();
            assert_eq!(eth.into_ecat_frame().unwrap().datagram_count(), Ok(2));
        }
    }
}

/// Wireshark's `text2pcap -F format` turns the hex dump `txt` into `out`.
fn text2pcap(format: &str, txt: &Path, out: &Path) {
    succeed(
        Process::new("text2pcap")
            .args(["-q", "-F", format, "-l", "1"])
            .arg(txt)
            .arg(out),
        &format!("text2pcap -F {format}"),
    );
}

/// A fresh directory `ecdc-TAG-PID` under the temporary directory for `test`, which needs
/// Wireshark's `tool`; `None` (the test is skipped, and says so) when `tool` is not installed.
fn work_dir(tool: &str, test: &str, tag: &str) -> Option<PathBuf> {
    if Process::new(tool).arg("-v").output().is_err() {
        eprintln!("SKIPPED {test}: {tool} not installed (it comes with tshark)");
        return None;
    }
    let dir = std::env::temp_dir().join(format!("ecdc-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    Some(dir)
}

/// Runs `cmd`, which must succeed (`what` and its stderr in the message otherwise); returns
/// its output.
fn succeed(cmd: &mut Process, what: &str) -> Output {
    let out = cmd.output().unwrap();
    assert!(
        out.status.success(),
        "{what}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// The records hold exactly `frames`, in order.
fn assert_same_frames(recs: &[pcap::Record], frames: &[Vec<u8>]) {
    assert_eq!(recs.len(), frames.len());
    for (r, f) in recs.iter().zip(frames) {
        assert_eq!(&r.data, f);
    }
}

#[test]
fn reads_text2pcap_output() {
    let Some(dir) = work_dir("text2pcap", "reads_text2pcap_output", "capture") else {
        return;
    };
    let frames = sample_frames();
    // od-style hex dump: one block per frame, offsets restart at 0000.
    let mut dump = String::new();
    for f in &frames {
        for (k, chunk) in f.chunks(16).enumerate() {
            dump.push_str(&format!("{:06x}", k * 16));
            for b in chunk {
                dump.push_str(&format!(" {b:02x}"));
            }
            dump.push('\n');
        }
        dump.push('\n');
    }
    let txt = dir.join("frames.txt");
    let out = dir.join("frames.pcap");
    std::fs::write(&txt, dump).unwrap();
    text2pcap("pcap", &txt, &out);
    let recs = pcap::read_file(&out).unwrap();
    assert_same_frames(&recs, &frames);
    // The same frames as pcapng, Wireshark's default format.
    let out_ng = dir.join("frames.pcapng");
    text2pcap("pcapng", &txt, &out_ng);
    let mut reader = PcapReader::open(&out_ng).unwrap();
    assert_eq!(reader.format(), pcap::Format::PcapNg);
    let recs: Vec<_> = reader.by_ref().map(|r| r.unwrap()).collect();
    assert_same_frames(&recs, &frames);
    let _ = std::fs::remove_dir_all(&dir);
}

/// Our pcapng (nanosecond interface) is read by tshark with the same times and bytes.
#[test]
fn tshark_reads_our_pcapng_with_ns_times() {
    let Some(dir) = work_dir(
        "tshark",
        "tshark_reads_our_pcapng_with_ns_times",
        "capture-ng",
    ) else {
        return;
    };
    let frames = sample_frames();
    let path = dir.join("ours.pcapng");
    let stamps: Vec<u64> = (0..frames.len() as u64)
        .map(|i| 1_700_000_000_123_456_789 + i * 1_001)
        .collect();
    pcap::write_file(
        &path,
        stamps.iter().copied().zip(frames.iter().map(|f| &f[..])),
    )
    .unwrap();
    let out = succeed(
        Process::new("tshark").arg("-r").arg(&path).args([
            "-T",
            "fields",
            "-e",
            "frame.time_epoch",
            "-e",
            "frame.len",
        ]),
        "tshark",
    );
    let text = String::from_utf8_lossy(&out.stdout);
    let rows: Vec<_> = text.lines().collect();
    assert_eq!(rows.len(), frames.len(), "{text}");
    for ((row, ts), f) in rows.iter().zip(&stamps).zip(&frames) {
        let mut cols = row.split('\t');
        let epoch = cols.next().unwrap();
        let want = format!("{}.{:09}", ts / 1_000_000_000, ts % 1_000_000_000);
        assert_eq!(epoch, want, "{row}");
        assert_eq!(cols.next().unwrap(), f.len().to_string(), "{row}");
    }
    // and we read back what we wrote
    let recs = pcap::read_file(&path).unwrap();
    let got: Vec<_> = recs.iter().map(|r| r.ts_ns.unwrap()).collect();
    assert_eq!(got, stamps);
    let _ = std::fs::remove_dir_all(&dir);
}
