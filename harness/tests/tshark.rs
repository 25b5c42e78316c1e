//! Differential check against Wireshark's EtherCAT dissector (tshark), an implementation we
//! did not write (REQ-WIRE-001..005, REQ-WIRE-031, REQ-WIRE-041, REQ-WIRE-060).
//!
//! Builds a pcap with every command (alone and in mixed multi-datagram frames, replies with
//! WKC and ADP as slaves leave them, a VLAN-tagged frame, an unpadded one and an
//! EtherCAT-over-UDP one) using `ecdc_core::wire::FrameBuilder` and our pcap writer, runs
//! tshark on it and requires: zero malformed frames, and for every datagram the same command,
//! index, ADP/ADO or logical address, length, M/C bits and WKC that our parser reads.
//!
//! tshark is installed by CI (.ci/install.sh). If it is absent the test prints a skip message
//! and returns.
//!
//! verifies: REQ-WIRE-001, REQ-WIRE-002, REQ-WIRE-003, REQ-WIRE-004, REQ-WIRE-005, REQ-WIRE-031, REQ-WIRE-041, REQ-WIRE-060

use ecdc_core::wire::{
    Address, Addressing, Command, DatagramRepr, EthernetFrame, FrameBuilder, MASTER_MAC,
};
use ecdc_harness::capture::{pcap, udp};
use std::process::Command as Process;

/// What we expect tshark to report for one datagram.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Expect {
    cmd: u8,
    idx: u8,
    adp_ado: Option<(u16, u16)>,
    lad: Option<u32>,
    len: u16,
    more: bool,
    circulating: bool,
    wkc: u16,
}

fn sample_address(c: Command, i: u16) -> Address {
    match c.addressing() {
        Addressing::Position => Address::position(i, 0x0130),
        Addressing::Configured => Address::configured(0x1000 + i, 0x0910),
        Addressing::Broadcast => Address::broadcast(0x0900),
        Addressing::Logical => Address::logical(0x0001_0000 + u32::from(i) * 0x100),
        Addressing::None => Address::Raw(0),
    }
}

/// Builds the frames; returns (frame bytes, expected datagrams per frame).
fn frames() -> Vec<(Vec<u8>, Vec<Expect>)> {
    let mut out = Vec::new();
    let mut push_frame = |reprs: &[(DatagramRepr, Vec<u8>)], tagged: bool, reply: bool| {
        let mut buf = vec![0u8; 1514];
        let n = {
            let mut b = FrameBuilder::new(&mut buf).unwrap();
            for (r, d) in reprs {
                b.push_repr(r, d).unwrap();
            }
            b.finish().unwrap()
        };
        buf.truncate(n);
        if reply {
            EthernetFrame::new_unchecked(&mut buf[..]).mark_processed_by_slave();
        }
        if tagged {
            // insert an 802.1Q tag (VID 7) after the source MAC
            buf.splice(12..12, [0x81, 0x00, 0x00, 0x07]);
        }
        out.push((buf, expectations(reprs)));
    };
    // 1..15: every command alone, as a request.
    for (i, c) in Command::ALL.iter().enumerate() {
        let i16 = i as u16;
        let len = [0usize, 1, 2, 4, 8][i % 5];
        let repr = DatagramRepr {
            command: *c,
            index: i as u8,
            address: sample_address(*c, i16),
            len: len as u16,
            circulating: false,
            irq: 0,
            wkc: 0,
        };
        push_frame(&[(repr, vec![0xA0 + i as u8; len])], false, false);
    }
    // 16: all 15 commands in one frame, as replies (WKC, ADP advanced, one C bit).
    let all: Vec<_> = Command::ALL
        .iter()
        .enumerate()
        .map(|(i, c)| {
            let addr = match sample_address(*c, 1) {
                Address::Broadcast { ado, .. } => Address::Broadcast { adp: 3, ado },
                Address::Position { ado, .. } => Address::Position { adp: 2, ado },
                a => a,
            };
            (
                DatagramRepr {
                    command: *c,
                    index: 0x80 + i as u8,
                    address: addr,
                    len: (i % 7) as u16 * 3,
                    circulating: i == 5,
                    irq: 0,
                    wkc: c.expected_wkc(3),
                },
                (0..(i % 7) * 3).map(|b| b as u8).collect(),
            )
        })
        .collect();
    push_frame(&all, false, true);
    // 17: the typical cyclic frame: FRMW 0x0910 8 B + BRD 0x092C 4 B + LRW 64 B.
    let cyclic = vec![
        (
            DatagramRepr {
                command: Command::Frmw,
                index: 1,
                address: Address::configured(0x1001, 0x0910),
                len: 8,
                circulating: false,
                irq: 0,
                wkc: 0,
            },
            vec![0; 8],
        ),
        (
            DatagramRepr {
                command: Command::Brd,
                index: 2,
                address: Address::broadcast(0x092C),
                len: 4,
                circulating: false,
                irq: 0,
                wkc: 0,
            },
            vec![0; 4],
        ),
        (
            DatagramRepr {
                command: Command::Lrw,
                index: 3,
                address: Address::logical(0),
                len: 64,
                circulating: false,
                irq: 0,
                wkc: 0,
            },
            (0..64).collect(),
        ),
    ];
    push_frame(&cyclic, false, false);
    // 18: the same, VLAN-tagged.
    push_frame(&cyclic, true, false);
    // 19: full-size frame, one 1486-byte LWR.
    push_frame(
        &[(
            DatagramRepr {
                command: Command::Lwr,
                index: 9,
                address: Address::logical(0x1234_5678),
                len: 1486,
                circulating: false,
                irq: 0,
                wkc: 1,
            },
            vec![0x55; 1486],
        )],
        false,
        true,
    );
    out
}

fn expectations(reprs: &[(DatagramRepr, Vec<u8>)]) -> Vec<Expect> {
    let n = reprs.len();
    reprs
        .iter()
        .enumerate()
        .map(|(i, (r, _))| {
            let raw = r.address.to_raw();
            let logical = r.command.addressing() == Addressing::Logical;
            Expect {
                cmd: r.command.code(),
                idx: r.index,
                adp_ado: (!logical).then_some((raw as u16, (raw >> 16) as u16)),
                lad: logical.then_some(raw),
                len: r.len,
                more: i + 1 < n,
                circulating: r.circulating,
                wkc: r.wkc,
            }
        })
        .collect()
}

/// EtherCAT over UDP: the cyclic frame's EtherCAT payload inside IPv4/UDP.
fn udp_frame() -> (Vec<u8>, Vec<Expect>) {
    let mut payload = vec![0u8; 200];
    let n = {
        let mut b = FrameBuilder::new_udp_payload(&mut payload).unwrap();
        b.push(Command::Aprd, 4, Address::position(2, 0x0010), &[0, 0])
            .unwrap();
        b.push(Command::Lrd, 5, Address::logical(0x0002_0000), &[0; 6])
            .unwrap();
        b.finish().unwrap()
    };
    let frame = udp::wrap(
        [0xff; 6],
        MASTER_MAC,
        [192, 168, 0, 1],
        [192, 168, 0, 2],
        &payload[..n],
    );
    let reprs = vec![
        (
            DatagramRepr {
                command: Command::Aprd,
                index: 4,
                address: Address::position(2, 0x0010),
                len: 2,
                circulating: false,
                irq: 0,
                wkc: 0,
            },
            vec![0; 2],
        ),
        (
            DatagramRepr {
                command: Command::Lrd,
                index: 5,
                address: Address::logical(0x0002_0000),
                len: 6,
                circulating: false,
                irq: 0,
                wkc: 0,
            },
            vec![0; 6],
        ),
    ];
    (frame, expectations(&reprs))
}

/// Negative control: a cut copy of a valid frame must show up in `_ws.malformed`, so the
/// "zero malformed" check above cannot pass just because the column is never filled.
fn assert_malformed_is_detectable(dir: &std::path::Path, good: &[u8]) {
    let path = dir.join("cut.pcap");
    pcap::write_file(&path, [(0u64, &good[..50])]).unwrap();
    let out = Process::new("tshark")
        .arg("-r")
        .arg(&path)
        .args(["-T", "fields", "-e", "_ws.malformed"])
        .output()
        .expect("run tshark");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("Malformed"),
        "tshark did not flag a cut frame: {text:?}"
    );
    // and our codec rejects it with a typed error too
    let eth = EthernetFrame::new_checked(&good[..50]).unwrap();
    assert_eq!(
        eth.into_ecat_frame().err(),
        Some(ecdc_core::wire::Error::Truncated)
    );
}

fn num(s: &str) -> u64 {
    let s = s.trim();
    if let Some(h) = s.strip_prefix("0x") {
        u64::from_str_radix(h, 16).unwrap_or_else(|_| panic!("bad hex {s:?}"))
    } else {
        s.parse()
            .unwrap_or_else(|_| panic!("bad number {s:?} in tshark output"))
    }
}

fn list(field: &str) -> Vec<u64> {
    if field.is_empty() {
        Vec::new()
    } else {
        field.split(',').map(num).collect()
    }
}

fn flag_list(field: &str) -> Vec<bool> {
    list(field).into_iter().map(|v| v != 0).collect()
}

#[test]
fn tshark_agrees_with_our_codec() {
    if Process::new("tshark").arg("--version").output().is_err() {
        eprintln!(
            "SKIPPED tshark_agrees_with_our_codec: tshark not installed \
             (apt-get install tshark; CI installs it)"
        );
        return;
    }
    let mut frames = frames();
    frames.push(udp_frame());
    // also an unpadded copy of frame 17 (host-side captures are not padded)
    let (mut unpadded, e) = frames[16].clone();
    let real_len = 14 + 2 + (12 + 8) + (12 + 4) + (12 + 64);
    unpadded.truncate(real_len);
    frames.push((unpadded, e));

    // Our own parser agrees with the expectations first (so a mismatch below is tshark's view).
    for (i, (bytes, exp)) in frames.iter().enumerate() {
        let payload: Vec<u8> = match EthernetFrame::new_checked(&bytes[..])
            .unwrap()
            .into_ecat_frame()
        {
            Ok(f) => f.into_inner().to_vec(),
            Err(_) => {
                let u = udp::unwrap(bytes).expect("udp frame");
                bytes[u.offset..u.offset + u.len].to_vec()
            }
        };
        let f = ecdc_core::wire::EcatFrame::new_checked(&payload[..])
            .unwrap_or_else(|e| panic!("frame {i}: {e}"));
        assert_eq!(f.datagram_count().unwrap(), exp.len(), "frame {i}");
    }

    let dir = std::env::temp_dir().join(format!("ecdc-tshark-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("all-commands.pcap");
    pcap::write_file(
        &path,
        frames
            .iter()
            .enumerate()
            .map(|(i, (b, _))| (i as u64 * 1_000_000, &b[..])),
    )
    .unwrap();

    let fields = [
        "frame.number",
        "ecat.cmd",
        "ecat.idx",
        "ecat.adp",
        "ecat.ado",
        "ecat.lad",
        "ecat.subframe.length",
        "ecat.subframe.more",
        "ecat.subframe.circulating",
        "ecat.cnt",
        "_ws.malformed",
        "_ws.expert.message",
    ];
    let mut cmd = Process::new("tshark");
    // No `-d udp.port==34980,ecatf`: tshark must recognise the UDP port by itself.
    cmd.arg("-r").arg(&path).args([
        "-T",
        "fields",
        "-E",
        "occurrence=a",
        "-E",
        "aggregator=,",
        "-E",
        "separator=/t",
    ]);
    for f in fields {
        cmd.args(["-e", f]);
    }
    let out = cmd.output().expect("run tshark");
    assert_malformed_is_detectable(&dir, &frames[16].0);
    assert!(
        out.status.success(),
        "tshark failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    let rows: Vec<Vec<&str>> = text
        .lines()
        .map(|l| {
            let mut v: Vec<&str> = l.split('\t').collect();
            v.resize(fields.len(), "");
            v
        })
        .collect();
    assert_eq!(rows.len(), frames.len(), "tshark output:\n{text}");

    let mut datagrams_checked = 0;
    for (row, (_, exp)) in rows.iter().zip(&frames) {
        let n = row[0];
        assert!(row[10].is_empty(), "frame {n} malformed: {row:?}");
        assert!(row[11].is_empty(), "frame {n} expert message: {row:?}");
        let cmds = list(row[1]);
        let idxs = list(row[2]);
        let adps = list(row[3]);
        let ados = list(row[4]);
        let lads = list(row[5]);
        let lens = list(row[6]);
        let mores = flag_list(row[7]);
        let circs = flag_list(row[8]);
        let wkcs = list(row[9]);
        assert_eq!(cmds.len(), exp.len(), "frame {n}: {row:?}");
        let want_adp: Vec<u64> = exp
            .iter()
            .filter_map(|e| e.adp_ado.map(|a| u64::from(a.0)))
            .collect();
        let want_ado: Vec<u64> = exp
            .iter()
            .filter_map(|e| e.adp_ado.map(|a| u64::from(a.1)))
            .collect();
        let want_lad: Vec<u64> = exp.iter().filter_map(|e| e.lad.map(u64::from)).collect();
        assert_eq!(adps, want_adp, "frame {n} ADP");
        assert_eq!(ados, want_ado, "frame {n} ADO");
        assert_eq!(lads, want_lad, "frame {n} logical address");
        for (k, e) in exp.iter().enumerate() {
            assert_eq!(cmds[k], u64::from(e.cmd), "frame {n} dg {k} cmd");
            assert_eq!(idxs[k], u64::from(e.idx), "frame {n} dg {k} idx");
            assert_eq!(lens[k], u64::from(e.len), "frame {n} dg {k} len");
            assert_eq!(mores[k], e.more, "frame {n} dg {k} M");
            assert_eq!(circs[k], e.circulating, "frame {n} dg {k} C");
            assert_eq!(wkcs[k], u64::from(e.wkc), "frame {n} dg {k} WKC");
            datagrams_checked += 1;
        }
    }
    eprintln!(
        "tshark agreed on {} frames, {datagrams_checked} datagrams",
        frames.len()
    );
    if std::env::var_os("ECDC_KEEP_PCAP").is_some() {
        eprintln!("kept {}", path.display());
    } else {
        let _ = std::fs::remove_dir_all(&dir);
    }
}
