//! `ecdc decode` end to end: runs the built binary on hex strings and on a pcap file
//! (REQ-WIRE-016: a bad frame is reported with its typed error).
//!
//! verifies: REQ-WIRE-016

use ecdc_core::wire::{Address, Command, FrameBuilder};
use ecdc_harness::capture::pcap;
use std::process::{Command as Process, Output};

fn ecdc(args: &[&str]) -> Output {
    Process::new(env!("CARGO_BIN_EXE_ecdc"))
        .args(args)
        .output()
        .expect("run ecdc")
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// The base frame of docs/background/wire-format.md §2.3, as hex written by hand.
const BASE: &str = "ffffffffffff 101010101010 88a4 2210 \
    07 01 0000 0000 0280 0000 0000 0000 \
    0e 02 0110 1009 0800 0000 0102030405060708 0300 \
    00000000000000000000";

#[test]
fn decodes_hex_frame() {
    let o = ecdc(&["decode", BASE]);
    let out = stdout(&o);
    assert!(
        o.status.success(),
        "{out}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(out.contains("EtherCAT header: length 34 type 1"), "{out}");
    let brd = out.lines().find(|l| l.contains("BRD")).expect("BRD row");
    assert!(brd.contains("0x01") && brd.contains("-M"), "{brd}");
    let frmw = out.lines().find(|l| l.contains("FRMW")).expect("FRMW row");
    assert!(frmw.contains("station 0x1001 ado 0x0910"), "{frmw}");
    assert!(frmw.contains("01 02 03 04 05 06 07 08"), "{frmw}");
    assert!(frmw.trim_end().contains("  3  "), "WKC 3: {frmw}");
}

#[test]
fn reports_typed_error_and_fails() {
    // header length 32 although the M-bit walk needs 34
    let bad = BASE.replacen("2210", "2010", 1);
    let o = ecdc(&["decode", &bad]);
    let out = stdout(&o);
    assert!(!o.status.success());
    assert!(
        out.contains("LengthMismatch { header: 32, walked: 34 }"),
        "{out}"
    );
    assert!(String::from_utf8_lossy(&o.stderr).contains("1 of 1 EtherCAT frame(s) invalid"));
    // command 15
    let bad = BASE.replacen("0e 02", "0f 02", 1);
    let out = stdout(&ecdc(&["decode", &bad]));
    assert!(out.contains("UnknownCommand { code: 15 }"), "{out}");
    // not EtherCAT: skipped, and with no EtherCAT frame at all the command fails
    let other = BASE.replacen("88a4", "0806", 1);
    let o = ecdc(&["decode", &other]);
    let out = stdout(&o);
    assert!(out.contains("skipped: EtherType 0x0806"), "{out}");
    assert!(out.contains("NotEtherCat { ethertype: 2054 }"), "{out}");
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("no EtherCAT frame found"));
}

#[test]
fn decodes_bare_payload() {
    // EtherCAT header + one APRD (a UDP payload)
    let o = ecdc(&[
        "decode",
        "--payload",
        "0e10 01 07 feff 1000 0200 0000 abcd 0000",
    ]);
    let out = stdout(&o);
    assert!(o.status.success(), "{out}");
    let row = out.lines().find(|l| l.contains("APRD")).expect("APRD row");
    assert!(row.contains("pos 2 ado 0x0010"), "{row}");
    assert!(row.contains("ab cd"), "{row}");
}

#[test]
fn decodes_pcap_file() {
    let mut good = vec![0u8; 128];
    let n = {
        let mut b = FrameBuilder::new(&mut good).unwrap();
        b.push(Command::Lrw, 7, Address::logical(0x0001_0000), &[0xEE; 20])
            .unwrap();
        b.finish().unwrap()
    };
    good.truncate(n);
    let mut cut = good.clone();
    cut.truncate(30);
    let dir = std::env::temp_dir().join(format!("ecdc-cli-decode-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut arp = vec![0xffu8; 6];
    arp.extend_from_slice(&[0x02, 0, 0, 0, 0, 1, 0x08, 0x06]);
    arp.resize(60, 0);
    let path = dir.join("three.pcap");
    pcap::write_file(
        &path,
        [
            (1_000_000_123, &good[..]),
            (1_500_000_000, &arp[..]),
            (2_000_000_000, &cut[..]),
        ],
    )
    .unwrap();
    let o = ecdc(&["decode", path.to_str().unwrap(), "--full"]);
    let out = stdout(&o);
    assert!(!o.status.success(), "the cut frame makes decode fail");
    assert!(out.contains("frame 1  t=1.000000123"), "{out}");
    assert!(out.contains("logical 0x00010000"), "{out}");
    assert!(
        out.contains(&["ee"; 20].join(" ")),
        "--full prints all data: {out}"
    );
    assert!(
        out.contains("skipped: EtherType 0x0806"),
        "ARP is skipped: {out}"
    );
    assert!(
        out.contains("3 frame(s): 1 valid, 1 invalid, 1 not EtherCAT"),
        "{out}"
    );
    assert!(out.contains("frame 3"), "{out}");
    assert!(out.contains("error: buffer truncated (Truncated)"), "{out}");
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("1 of 2 EtherCAT frame(s) invalid"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn rejects_garbage_input() {
    let o = ecdc(&["decode", "not-hex-and-not-a-file"]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("neither an existing file nor a hex string"),
        "{err}"
    );
}
