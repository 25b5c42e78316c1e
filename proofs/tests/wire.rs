//! Property tests and exhaustive checks for the wire bodies in `ecdc_proofs::wire`
//! (REQ-PROP P1; spec/req/wire.md). These run the same bodies the Kani harnesses and the fuzz
//! targets call.
//!
//! verifies: P1

use ecdc_core::wire::{DatagramRepr, FrameBuilder};
use ecdc_proofs::wire;
use proptest::prelude::*;

/// One datagram description: fields drawn over their full ranges, data up to 96 bytes (with
/// occasional large ones so capacity limits are exercised).
fn datagram() -> impl Strategy<Value = (DatagramRepr, Vec<u8>)> {
    (
        any::<u8>(),
        any::<u8>(),
        any::<u32>(),
        any::<bool>(),
        any::<u16>(),
        any::<u16>(),
        prop_oneof![
            8 => proptest::collection::vec(any::<u8>(), 0..=96),
            1 => proptest::collection::vec(any::<u8>(), 400..=1486),
        ],
    )
        .prop_map(|(cmd, idx, addr, c, irq, wkc, data)| {
            (
                wire::normalise(cmd, idx, addr, c, irq, wkc, data.len()),
                data,
            )
        })
}

/// A valid frame as bytes (built by our builder) or a corrupted copy of one.
fn frame_bytes() -> impl Strategy<Value = Vec<u8>> {
    (
        proptest::collection::vec(datagram(), 1..6),
        proptest::collection::vec((any::<usize>(), any::<u8>()), 0..4),
        any::<usize>(),
    )
        .prop_map(|(dgs, flips, cut)| {
            let mut buf = vec![0u8; 1514];
            let n = {
                let mut b = FrameBuilder::new(&mut buf).unwrap();
                for (r, d) in &dgs {
                    if b.push_repr(r, d).is_err() {
                        break;
                    }
                }
                b.finish().unwrap_or(60)
            };
            buf.truncate(n);
            for (at, x) in flips {
                let i = at % n;
                buf[i] ^= x;
            }
            if cut % 4 == 0 {
                buf.truncate(cut % (n + 1));
            }
            buf
        })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]

    /// P1 / REQ-WIRE-030, REQ-WIRE-040: any valid datagram list survives emit→parse unchanged.
    // verifies: P1, REQ-WIRE-030, REQ-WIRE-040
    #[test]
    fn emit_parse_roundtrip(dgs in proptest::collection::vec(datagram(), 0..12), cap in 0usize..1600) {
        let list: Vec<(DatagramRepr, &[u8])> = dgs.iter().map(|(r, d)| (*r, &d[..])).collect();
        let mut buf = vec![0xA5u8; cap];
        wire::roundtrip(&list, &mut buf);
    }

    /// P1 / REQ-WIRE-020..022: arbitrary bytes never panic; spans stay inside the input.
    // verifies: P1, REQ-WIRE-020, REQ-WIRE-021, REQ-WIRE-022
    #[test]
    fn arbitrary_bytes_parse_safely(bytes in proptest::collection::vec(any::<u8>(), 0..1600)) {
        wire::parse_any(&bytes);
        wire::display_any(&bytes);
        // and the same bytes behind an EtherCAT Ethernet header
        let mut f = vec![0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0x10, 0x10, 0x10, 0x10, 0x10, 0x10, 0x88, 0xa4];
        f.extend_from_slice(&bytes);
        wire::parse_any(&f);
    }

    /// P1: near-valid frames (built, then bit-flipped and/or cut) never panic, and the walk
    /// either succeeds with spans inside the input or reports a typed error.
    // verifies: P1
    #[test]
    fn mutated_frames_parse_safely(bytes in frame_bytes()) {
        wire::parse_any(&bytes);
        if bytes.len() > 14 {
            wire::parse_any(&bytes[14..]);
            wire::display_any(&bytes[14..]);
        }
    }

    /// REQ-WIRE-073 over random i64 as well as boundary values.
    // verifies: REQ-WIRE-073
    #[test]
    fn system_time_difference(raw in any::<u32>(), ns in any::<i64>()) {
        wire::system_time_difference(raw, ns);
    }
}

/// Exhaustive over all 2^16 values of each 16-bit word the codec decodes: the datagram
/// length/flags word (REQ-WIRE-004/013), the EtherCAT header (REQ-WIRE-005, 012..015) and DL
/// status (REQ-WIRE-072).
// verifies: REQ-WIRE-004, REQ-WIRE-005, REQ-WIRE-072
#[test]
fn exhaustive_16_bit_words() {
    let words: [fn(u16); 3] = [
        wire::len_flags_word,
        wire::ecat_header_word,
        wire::dl_status_word,
    ];
    for check in words {
        for w in 0..=u16::MAX {
            check(w);
        }
    }
}

/// REQ-WIRE-073: boundary words and values of the sign-magnitude codec.
// verifies: REQ-WIRE-073
#[test]
fn system_time_difference_boundaries() {
    for raw in [
        0,
        1,
        0x7FFF_FFFE,
        0x7FFF_FFFF,
        0x8000_0000,
        0x8000_0001,
        0xFFFF_FFFF,
    ] {
        for ns in [
            i64::MIN,
            i64::MIN + 1,
            -(1 << 31),
            -(1 << 31) + 1,
            -1,
            0,
            1,
            (1 << 31) - 1,
            1 << 31,
            i64::MAX,
        ] {
            wire::system_time_difference(raw, ns);
        }
    }
}

/// REQ-WIRE-010..015: every prefix of a valid multi-datagram frame is handled (no panic, typed
/// error for cut ones).
// verifies: REQ-WIRE-010, REQ-WIRE-011, REQ-WIRE-012, REQ-WIRE-013, REQ-WIRE-014, REQ-WIRE-015
#[test]
fn every_prefix_of_a_frame() {
    let mut buf = vec![0u8; 200];
    let n = {
        let mut b = FrameBuilder::new(&mut buf).unwrap();
        for (i, c) in ecdc_core::wire::Command::ALL.iter().enumerate().take(6) {
            let r = wire::normalise(c.code(), i as u8, 0x0910_1001, false, 0, 0, i);
            b.push_repr(&r, &vec![i as u8; i]).unwrap();
        }
        b.finish().unwrap()
    };
    for cut in 0..=n {
        wire::parse_any(&buf[..cut]);
    }
}

/// The wire Kani harnesses, run under the shim with 3 000 boundary-biased random inputs each (a
/// random test, not a proof); every one must pass most runs and reach at least one `cover!`.
#[test]
fn wire_kani_harnesses_under_shim() {
    for (name, r) in
        ecdc_proofs::kani_shim::run_all(&wire::KANI_HARNESSES, 0xECDC_0100, 3_000, 1_500)
    {
        eprintln!("{name}: {r:?}");
    }
    // The parse harness draws every length up to its buffer, not only the small ones.
    let r = ecdc_proofs::kani_shim::run(0xECDC_0100, 3_000, wire::kani_parse_never_panics);
    assert!(
        r.covered.contains_key("the longest buffer is reachable"),
        "{r:?}"
    );
}
