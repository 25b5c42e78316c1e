//! Typed wire errors at their exact boundaries, the VLAN tag, ADP increment and expected
//! working counters (spec/req/wire.md): REQ-WIRE-002, REQ-WIRE-011, REQ-WIRE-012,
//! REQ-WIRE-014, REQ-WIRE-032, REQ-WIRE-051. Frames are built by hand (not with our builder)
//! and checked on both sides of each limit; the command tables are written out independently.
//!
//! verifies: REQ-WIRE-002, REQ-WIRE-011, REQ-WIRE-012, REQ-WIRE-014, REQ-WIRE-032, REQ-WIRE-051

use ecdc_core::wire::Address;
use ecdc_core::wire::{Command, Error, EthernetFrame, FrameBuilder};

/// An Ethernet frame (EtherType 0x88A4, optional 802.1Q tag) carrying EtherCAT header word `hdr`
/// followed by `payload` bytes.
fn frame(tag: Option<u16>, hdr: u16, payload: &[u8]) -> Vec<u8> {
    let mut f = vec![0xFF; 6];
    f.extend_from_slice(&[0x02, 0, 0, 0, 0, 1]);
    if let Some(tci) = tag {
        f.extend_from_slice(&0x8100u16.to_be_bytes());
        f.extend_from_slice(&tci.to_be_bytes());
    }
    f.extend_from_slice(&0x88A4u16.to_be_bytes());
    f.extend_from_slice(&hdr.to_le_bytes());
    f.extend_from_slice(payload);
    while f.len() < 60 {
        f.push(0);
    }
    f
}

/// One datagram header (NOP, index 0, address 0) with 11-bit length `len`, then `len` data
/// bytes and the WKC.
fn datagram(len: u16) -> Vec<u8> {
    let mut d = vec![0u8; 6];
    d.extend_from_slice(&(len & 0x07FF).to_le_bytes());
    d.extend_from_slice(&[0, 0]);
    d.extend(std::iter::repeat_n(0u8, usize::from(len) + 2));
    d
}

fn parse(bytes: &[u8]) -> Result<usize, Error> {
    let eth = EthernetFrame::new_checked(bytes)?;
    let ecat = eth.ecat_frame()?;
    let mut n = 0;
    for d in ecat.iter() {
        d?;
        n += 1;
    }
    Ok(n)
}

/// REQ-WIRE-011: a datagram of 1486 data bytes is fine, 1487 is `DatagramTooLong`.
// verifies: REQ-WIRE-011
#[test]
fn datagram_length_limit() {
    let ok = datagram(1486);
    assert_eq!(parse(&frame(None, 0x1000 | ok.len() as u16, &ok)), Ok(1));
    // The header length stays at the 1498 limit; only the datagram's own length is too long.
    let mut long = datagram(1487);
    long.truncate(1498);
    let r = parse(&frame(None, 0x1000 | 1498, &long));
    assert_eq!(r, Err(Error::DatagramTooLong { len: 1487 }));
}

/// REQ-WIRE-012: a header length of 1498 (one maximal datagram) parses; 1499 is `FrameTooLong`
/// with the header length, whatever the buffer holds.
// verifies: REQ-WIRE-012
#[test]
fn frame_length_limit() {
    let ok = datagram(1486);
    assert_eq!(ok.len(), 1498);
    let f = frame(None, 0x1000 | 1498, &ok);
    assert_eq!(f.len(), 1514);
    assert_eq!(parse(&f), Ok(1));
    let mut big = ok.clone();
    big.push(0);
    let r = parse(&frame(None, 0x1000 | 1499, &big));
    assert_eq!(r, Err(Error::FrameTooLong { len: 1499 }));
}

/// REQ-WIRE-014: every type other than 1 is `NotDlpdu` with that type, never interpreted.
// verifies: REQ-WIRE-014
#[test]
fn frame_type_other_than_dlpdu() {
    let d = datagram(2);
    for t in 0u16..16 {
        let r = parse(&frame(None, (t << 12) | d.len() as u16, &d));
        if t == 1 {
            assert_eq!(r, Ok(1));
        } else {
            assert_eq!(
                r,
                Err(Error::NotDlpdu {
                    frame_type: t as u8
                }),
                "type {t}"
            );
        }
    }
}

/// REQ-WIRE-002: one 802.1Q tag is skipped and its TCI exposed; two tags are not EtherCAT.
// verifies: REQ-WIRE-002
#[test]
fn vlan_tag() {
    let mut buf = [0u8; 128];
    let mut b = FrameBuilder::new(&mut buf).expect("buffer");
    b.push(Command::Brd, 7, Address::broadcast(0x0130), &[0, 0])
        .expect("fits");
    let n = b.finish().expect("frame");
    let plain = buf[..n].to_vec();
    let mut tagged = plain[..12].to_vec();
    tagged.extend_from_slice(&[0x81, 0x00, 0x20, 0x05]);
    tagged.extend_from_slice(&plain[12..]);
    let eth = EthernetFrame::new_checked(&tagged[..]).expect("tagged frame");
    assert_eq!(eth.vlan(), Some(0x2005));
    assert_eq!(parse(&tagged), Ok(1));
    assert_eq!(
        EthernetFrame::new_checked(&plain[..])
            .expect("plain")
            .vlan(),
        None
    );
    let mut double = plain[..12].to_vec();
    double.extend_from_slice(&[0x81, 0x00, 0x20, 0x05, 0x81, 0x00, 0x00, 0x01]);
    double.extend_from_slice(&plain[12..]);
    assert_eq!(
        parse(&double),
        Err(Error::NotEtherCat { ethertype: 0x8100 })
    );
}

/// REQ-WIRE-032: exactly the position-addressed (APRD, APWR, APRW, ARMW) and broadcast (BRD,
/// BWR, BRW) commands have their ADP incremented by every ESC; configured, logical and NOP not.
// verifies: REQ-WIRE-032
#[test]
fn adp_increment_by_command() {
    use Command::*;
    for c in Command::ALL {
        let expect = matches!(c, Aprd | Apwr | Aprw | Armw | Brd | Bwr | Brw);
        assert_eq!(c.increments_adp(), expect, "{c:?}");
    }
}

/// REQ-WIRE-051: expected working counters for n fully participating slaves, saturating.
// verifies: REQ-WIRE-051
#[test]
fn expected_wkc_table() {
    use Command::*;
    for n in [0u16, 1, 2, 7, 0x5555, 0x5556, u16::MAX] {
        for c in Command::ALL {
            let want = match c {
                Nop => 0,
                Aprw | Fprw | Brw | Lrw => n.saturating_mul(3),
                _ => n,
            };
            assert_eq!(c.expected_wkc(n), want, "{c:?} × {n}");
        }
        for r in [0u16, 1, 3, u16::MAX] {
            let want = (u32::from(n) * 2 + u32::from(r)).min(u32::from(u16::MAX)) as u16;
            assert_eq!(Command::lrw_expected_wkc(n, r), want, "LRW w={n} r={r}");
        }
    }
}
