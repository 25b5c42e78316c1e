//! Property bodies for the wire area (REQ-PROP P1; spec/req/wire.md REQ-WIRE-020..030).
//!
//! One body per property. Each is a plain `pub fn` that panics (assert) when the property is
//! violated, and is called by
//! - the Kani harnesses `kani_*` below (symbolic under `cargo kani`; Kani is not installed on
//!   the build machine, so they have never been run as proofs here; the shim runs them as
//!   random tests),
//! - the property tests and exhaustive checks in `proofs/tests/wire*.rs`,
//! - the fuzz targets in `fuzz/fuzz_targets/wire_*.rs`.
//!
//! verifies: P1, REQ-WIRE-020, REQ-WIRE-021, REQ-WIRE-022, REQ-WIRE-030

use ecdc_core::wire::{
    Address, Command, Datagram, DatagramRepr, EcatFrame, Error, EthernetFrame, FrameBuilder,
    MAX_DATAGRAM_DATA, MAX_ECAT_PAYLOAD, MIN_FRAME_LEN,
};

/// Offset of `inner` in `outer`, asserting that `inner` lies entirely inside `outer`.
fn span_in(outer: &[u8], inner: &[u8]) -> (usize, usize) {
    let o = outer.as_ptr() as usize;
    let i = inner.as_ptr() as usize;
    assert!(i >= o, "datagram starts before the input");
    let start = i - o;
    assert!(
        start + inner.len() <= outer.len(),
        "datagram span {start}+{} outside input of {} bytes",
        inner.len(),
        outer.len()
    );
    (start, inner.len())
}

/// P1 / REQ-WIRE-020..022: for ANY byte string, parsing as an EtherCAT payload (Ethernet payload
/// or UDP payload) and as an Ethernet frame never panics; every yielded datagram lies inside the
/// input; `iter`, `iter_mut` and `datagram_offsets` agree; `new_checked` is `Ok` exactly when
/// the walk yields no error; on `Ok` the walk covers exactly the header length, which is at most
/// 1498, and every datagram re-parses as a `DatagramRepr`.
pub fn parse_any(bytes: &[u8]) {
    check_ecat_payload(bytes);
    // As an Ethernet frame (possibly tagged, possibly not EtherCAT).
    let eth = EthernetFrame::new_unchecked(bytes);
    let _ = (
        eth.dst(),
        eth.src(),
        eth.ethertype(),
        eth.vlan(),
        eth.payload(),
    );
    let _ = eth.processed_by_slave();
    match eth.ecat_frame() {
        Ok(f) => {
            assert!(EthernetFrame::new_checked(bytes).is_ok());
            let inner = f.into_inner();
            span_in(bytes, inner);
            check_ecat_payload(inner);
        }
        Err(Error::NotEtherCat { ethertype }) => assert_ne!(ethertype, 0x88A4),
        Err(_) => {}
    }
}

/// REQ-WIRE-020: the `Display` impls (frame, datagrams, errors) never panic on any bytes, and a
/// valid frame prints one line per datagram. Not a Kani harness (formatting is too heavy for
/// the model checker); run by proptest and the `wire_parse` fuzz target.
pub fn display_any(bytes: &[u8]) {
    let frame = EcatFrame::new_unchecked(bytes);
    let text = frame.to_string();
    if let Ok(n) = frame.datagram_count() {
        assert_eq!(text.lines().count(), 1 + n, "{text}");
    }
    for d in frame.iter() {
        match d {
            Ok(d) => assert!(!d.to_string().is_empty()),
            Err(e) => assert!(!e.to_string().is_empty()),
        }
    }
    let _ = Datagram::new_unchecked(bytes).to_string();
}

fn check_ecat_payload(bytes: &[u8]) {
    let frame = EcatFrame::new_unchecked(bytes);
    let _ = (frame.length(), frame.reserved(), frame.frame_type());
    let _ = (frame.datagrams_bytes(), frame.padding());
    let checked = EcatFrame::new_checked(bytes);

    let mut spans = Vec::new();
    let mut first_err = None;
    let mut walked = 0usize;
    let mut n_items = 0usize;
    for item in frame.iter() {
        n_items += 1;
        assert!(n_items <= bytes.len() + 1, "iterator does not terminate");
        match item {
            Ok(d) => {
                assert!(first_err.is_none(), "Ok after Err: iterator must fuse");
                // Every accessor, on every yielded datagram.
                let _ = (
                    d.command_raw(),
                    d.index(),
                    d.adp(),
                    d.ado(),
                    d.logical_address(),
                );
                let _ = (d.irq(), d.wkc(), d.more(), d.circulating(), d.data());
                let repr = DatagramRepr::parse(&d).expect("a yielded datagram is valid");
                assert_eq!(repr.buffer_len(), d.total_len());
                assert!(usize::from(repr.len) <= MAX_DATAGRAM_DATA);
                let inner = d.into_inner();
                assert_eq!(inner.len(), d.total_len());
                let s = span_in(bytes, inner);
                assert_eq!(s.0, 2 + walked, "datagrams are contiguous from the header");
                walked += s.1;
                spans.push(s);
            }
            Err(e) => {
                assert!(first_err.is_none(), "at most one error");
                first_err = Some(e);
            }
        }
    }
    match checked {
        Ok(_) => {
            assert!(first_err.is_none());
            assert!(!spans.is_empty());
            assert_eq!(walked, usize::from(frame.length()), "walk = header length");
            assert!(walked <= MAX_ECAT_PAYLOAD);
            assert_eq!(frame.datagram_count(), Ok(spans.len()));
        }
        Err(e) => assert_eq!(first_err, Some(e), "iter reports new_checked's error"),
    }
    // datagram_offsets agrees with iter.
    let offs: Vec<_> = frame.datagram_offsets().collect();
    let ok_offs: Vec<_> = offs.iter().filter_map(|o| o.ok()).collect();
    assert_eq!(ok_offs, spans);
    // iter_mut yields the same spans on a copy, and writing through it stays inside.
    let mut copy = bytes.to_vec();
    let base = copy.as_ptr() as usize;
    let mut mut_spans = Vec::new();
    {
        let mut f = EcatFrame::new_unchecked(&mut copy[..]);
        for d in f.iter_mut().flatten() {
            let mut d: Datagram<&mut [u8]> = d;
            d.add_wkc(1);
            d.set_adp(d.adp().wrapping_add(1));
            d.set_circulating(true);
            d.data_mut().fill(0x5A);
            let inner = d.into_inner();
            mut_spans.push((inner.as_ptr() as usize - base, inner.len()));
        }
    }
    assert_eq!(mut_spans, spans);
}

/// A datagram description for the round-trip property, normalised so that every input is valid:
/// command code taken mod 15, address interpreted for that command, data length capped at 1486.
pub fn normalise(
    cmd: u8,
    index: u8,
    address: u32,
    circulating: bool,
    irq: u16,
    wkc: u16,
    data_len: usize,
) -> DatagramRepr {
    let command = Command::from_u8(cmd % 15).unwrap_or(Command::Nop);
    let len = u16::try_from(data_len.min(MAX_DATAGRAM_DATA)).unwrap_or(0);
    DatagramRepr {
        command,
        index,
        address: Address::from_raw(command, address),
        len,
        circulating,
        irq,
        wkc,
    }
}

/// P1 / REQ-WIRE-030, REQ-WIRE-040..042: pushing `datagrams` (each `(repr, data)` with
/// `data.len() == repr.len`) into a builder over `buf` and parsing the result gives back exactly
/// the same datagrams; the builder fails with `BufferFull` exactly when a datagram does not fit
/// (buffer or 1498 datagram bytes) and then leaves the frame unchanged; the frame is padded to
/// 60 bytes with zeros. Returns the number of datagrams that fit.
pub fn roundtrip(datagrams: &[(DatagramRepr, &[u8])], buf: &mut [u8]) -> usize {
    let cap = buf.len();
    let mut builder = match FrameBuilder::new(buf) {
        Ok(b) => b,
        Err(e) => {
            assert_eq!(e, Error::BufferFull);
            assert!(cap < MIN_FRAME_LEN);
            return 0;
        }
    };
    let mut used = 14 + 2;
    let mut pushed = 0;
    for (repr, data) in datagrams {
        assert_eq!(usize::from(repr.len), data.len(), "test input invariant");
        let need = repr.buffer_len();
        let fits = used + need <= cap && used - 16 + need <= MAX_ECAT_PAYLOAD;
        let before = builder.len();
        match builder.push_repr(repr, data) {
            Ok(slot) => {
                assert!(fits, "builder accepted a datagram beyond capacity");
                assert_eq!(slot.offset(), used);
                assert_eq!(slot.index(), repr.index);
                used += need;
                pushed += 1;
            }
            Err(e) => {
                assert_eq!(e, Error::BufferFull);
                assert!(!fits, "builder refused a datagram that fits");
                assert_eq!(builder.len(), before);
                break;
            }
        }
    }
    if pushed == 0 {
        assert_eq!(builder.finish(), Err(Error::NoDatagram));
        return 0;
    }
    let n = builder.finish().expect("non-empty frame finishes");
    assert_eq!(n, used.max(MIN_FRAME_LEN));
    let frame = &buf[..n];
    assert!(frame[used..].iter().all(|b| *b == 0), "padding is zero");
    let eth = EthernetFrame::new_checked(frame).expect("ethernet header");
    assert_eq!(eth.src(), ecdc_core::wire::MASTER_MAC);
    assert!(!eth.processed_by_slave());
    let ecat = eth.ecat_frame().expect("built frame parses");
    assert_eq!(usize::from(ecat.length()), used - 16);
    let parsed: Vec<_> = ecat.iter().map(|d| d.expect("valid")).collect();
    assert_eq!(parsed.len(), pushed);
    for (i, d) in parsed.iter().enumerate() {
        let (repr, data) = &datagrams[i];
        assert_eq!(&DatagramRepr::parse(d).expect("valid"), repr);
        assert_eq!(d.data(), *data);
        assert_eq!(d.more(), i + 1 < pushed, "M bit set on all but the last");
    }
    pushed
}

/// REQ-WIRE-004, REQ-WIRE-013: the datagram length/flags word `w` decodes to the fields an
/// independent shift-and-mask formula gives, and validation accepts it exactly when the reserved
/// bits are clear and the length is at most 1486. Domain: all 2^16 words (exhaustive test).
pub fn len_flags_word(w: u16) {
    let mut buf = [0u8; 12 + 2047];
    buf[0] = Command::Lrw.code();
    buf[6..8].copy_from_slice(&w.to_le_bytes());
    let d = Datagram::new_unchecked(&buf[..]);
    let len = w & 0x07FF;
    assert_eq!(d.data_len(), len);
    assert_eq!(u16::from(d.reserved_bits()), (w >> 11) & 0x7);
    assert_eq!(d.circulating(), w & 0x4000 != 0);
    assert_eq!(d.more(), w & 0x8000 != 0);
    assert_eq!(d.total_len(), 12 + usize::from(len));
    let valid = len <= 1486 && (w >> 11) & 0x7 == 0;
    assert_eq!(Datagram::new_checked(&buf[..]).is_ok(), valid);
    // Emit of the decoded repr gives back the word with the M bit as passed.
    if valid {
        let repr = DatagramRepr::parse(&d).expect("valid");
        let mut out = [0u8; 12 + 1486];
        let mut o = Datagram::new_unchecked(&mut out[..]);
        repr.emit(&mut o, d.more()).expect("fits");
        assert_eq!(o.len_flags(), w);
    }
}

/// REQ-WIRE-005, 012..015: the EtherCAT header word `w` in front of one empty NOP datagram
/// (12 bytes, M clear) and zero padding is classified exactly as the documented check order
/// says. Domain: all 2^16 words (exhaustive test).
pub fn ecat_header_word(w: u16) {
    let mut buf = [0u8; 2 + 2047];
    buf[..2].copy_from_slice(&w.to_le_bytes());
    // bytes 2..14: NOP, idx 0, address 0, len 0, M 0, irq 0, wkc 0 (all zero already)
    let f = EcatFrame::new_unchecked(&buf[..]);
    let (len, reserved, ty) = (w & 0x07FF, w & 0x0800 != 0, (w >> 12) as u8);
    assert_eq!(
        (f.length(), f.reserved(), f.frame_type()),
        (len, reserved, ty)
    );
    let expected = if ty != 1 {
        Err(Error::NotDlpdu { frame_type: ty })
    } else if reserved {
        Err(Error::HeaderReservedBit)
    } else if usize::from(len) > MAX_ECAT_PAYLOAD {
        Err(Error::FrameTooLong {
            len: usize::from(len),
        })
    } else if len == 0 {
        Err(Error::NoDatagram)
    } else if len < 12 {
        Err(Error::LengthMismatch {
            header: len,
            walked: 12,
        })
    } else if len > 12 {
        Err(Error::TrailingData)
    } else {
        Ok(1)
    };
    assert_eq!(
        EcatFrame::new_checked(&buf[..]).map(|f| f.datagram_count().unwrap_or(0)),
        expected,
        "header word {w:#06x}"
    );
}

/// REQ-WIRE-072: DL status decode for word `w` agrees with the bit layout (link 4+p, loop 8+2p,
/// communication 9+2p) and re-encodes to the same word. Domain: all 2^16 words.
pub fn dl_status_word(w: u16) {
    use ecdc_core::wire::register::{DlStatus, PortState};
    let s = DlStatus(w);
    let mut ports = [PortState::default(); 4];
    for p in 0..4u8 {
        assert_eq!(s.link(p), w & (1 << (4 + p)) != 0);
        assert_eq!(s.loop_closed(p), w & (1 << (8 + 2 * p)) != 0);
        assert_eq!(s.communication(p), w & (1 << (9 + 2 * p)) != 0);
        ports[usize::from(p)] = s.port(p);
    }
    assert_eq!(DlStatus::from_ports(ports, w), s);
}

/// REQ-WIRE-073: 0x092C sign-magnitude. For every raw word: |to_ns| = bits 30..0, sign = bit
/// 31 (negative zero decodes to 0), and from_ns(to_ns(raw)) == raw except for negative zero.
/// For every i64: from_ns saturates the magnitude at 2^31 − 1 and keeps the sign.
pub fn system_time_difference(raw: u32, ns: i64) {
    use ecdc_core::wire::register::SystemTimeDifference as D;
    let d = D::from_raw(raw);
    let mag = i64::from(raw & 0x7FFF_FFFF);
    let expect = if raw & 0x8000_0000 != 0 { -mag } else { mag };
    assert_eq!(i64::from(d.to_ns()), expect);
    if raw != 0x8000_0000 {
        assert_eq!(D::from_ns(i64::from(d.to_ns())), d);
    }
    let e = D::from_ns(ns);
    let m = i128::from(ns).abs().min(0x7FFF_FFFF);
    assert_eq!(i128::from(e.magnitude()), m);
    assert_eq!(e.local_behind(), ns < 0);
}

/// REQ-WIRE-071: ESC features word `w` (0x0008) decodes to the bit layout (bit 2 DC, bit 3
/// 64-bit DC, bit 8 enhanced SYNC), and the DC time width is 8 exactly when bit 3 is set, else 4.
/// Domain: all 2^16 words.
pub fn esc_features_word(w: u16) {
    use ecdc_core::wire::register::EscFeatures;
    let f = EscFeatures(w);
    assert_eq!(f.raw(), w);
    assert_eq!(f.dc_supported(), w & (1 << 2) != 0);
    assert_eq!(f.dc_64bit(), w & (1 << 3) != 0);
    assert_eq!(f.enhanced_sync(), w & (1 << 8) != 0);
    assert_eq!(f.dc_time_width(), if w & (1 << 3) != 0 { 8 } else { 4 });
}

/// The `registers` fuzz target's body (also replayed on stable by
/// proofs/tests/exhaustive_fuzz_inputs.rs): [`register_bytes_any`] on the input and on every
/// suffix starting within its first 40 bytes (short and misaligned reads from one input), then
/// the word-level bodies on the leading words and, when 12 bytes are there, the 0x092C decoder
/// against an arbitrary 64-bit value.
pub fn registers_target(data: &[u8]) {
    register_bytes_any(data);
    for start in 1..data.len().min(40) {
        if let Some(rest) = data.get(start..) {
            register_bytes_any(rest);
        }
    }
    let w = |at: usize| -> Option<u16> {
        Some(u16::from_le_bytes(data.get(at..at + 2)?.try_into().ok()?))
    };
    if let (Some(a), Some(b)) = (w(0), w(2)) {
        esc_features_word(a);
        dl_status_word(b);
        let raw = u32::from(a) | (u32::from(b) << 16);
        let ns = data
            .get(4..12)
            .and_then(|s| s.try_into().ok())
            .map_or(i64::from(raw), i64::from_le_bytes);
        system_time_difference(raw, ns);
    }
}

/// A register parsed from `bytes` against the little-endian value of its leading bytes: the
/// same raw value, then `body` on it; or `Truncated` exactly when the bytes are too short.
fn leading_value_agrees<P: core::fmt::Debug, R: Copy + PartialEq + core::fmt::Debug>(
    register: &str,
    width: &str,
    parsed: Result<P, Error>,
    leading: Option<R>,
    raw: impl Fn(&P) -> R,
    body: impl Fn(R),
) {
    match (parsed, leading) {
        (Ok(p), Some(v)) => {
            assert_eq!(raw(&p), v);
            body(v);
        }
        (Err(e), None) => assert_eq!(e, Error::Truncated),
        (got, want) => panic!("{register} parse {got:?} vs leading {width} {want:?}"),
    }
}

/// REQ-WIRE-071..074 on ANY byte string read back from a slave: the register parsers never
/// panic, fail with `Truncated` exactly when the bytes are shorter than the register, and
/// otherwise decode the little-endian value of the leading bytes (0x0008, 0x0110, 0x092C agree
/// with their word bodies; the 0x0900..0x091F block has ports at 0/4/8/12, System Time at 16 and
/// the EPU time at 24, and emits back to the same 32 bytes).
pub fn register_bytes_any(bytes: &[u8]) {
    use ecdc_core::wire::register::{DlStatus, EscFeatures, ReceiveTimes, SystemTimeDifference};
    let word = |at: usize| -> Option<u16> {
        Some(u16::from_le_bytes(bytes.get(at..at + 2)?.try_into().ok()?))
    };
    let dword = |at: usize| -> Option<u32> {
        Some(u32::from_le_bytes(bytes.get(at..at + 4)?.try_into().ok()?))
    };
    let qword = |at: usize| -> Option<u64> {
        Some(u64::from_le_bytes(bytes.get(at..at + 8)?.try_into().ok()?))
    };

    leading_value_agrees(
        "0x0008",
        "word",
        EscFeatures::parse(bytes),
        word(0),
        |f| f.raw(),
        esc_features_word,
    );
    leading_value_agrees(
        "0x0110",
        "word",
        DlStatus::parse(bytes),
        word(0),
        |s| s.raw(),
        dl_status_word,
    );
    leading_value_agrees(
        "0x092C",
        "dword",
        SystemTimeDifference::parse(bytes),
        dword(0),
        |d| d.raw(),
        |raw| system_time_difference(raw, i64::from(raw as i32)),
    );
    match ReceiveTimes::parse(bytes) {
        Err(e) => {
            assert_eq!(e, Error::Truncated);
            assert!(bytes.len() < ReceiveTimes::LEN, "valid block refused");
        }
        Ok(rt) => {
            assert!(bytes.len() >= ReceiveTimes::LEN);
            for (p, t) in rt.port.iter().enumerate() {
                assert_eq!(Some(*t), dword(4 * p), "receive time port {p}");
            }
            assert_eq!(Some(rt.system_time), qword(16), "system time");
            assert_eq!(Some(rt.epu), qword(24), "EPU receive time");
            let mut out = [0u8; ReceiveTimes::LEN];
            rt.emit(&mut out).expect("32 bytes fit");
            assert_eq!(
                bytes.get(..ReceiveTimes::LEN),
                Some(&out[..]),
                "emit(parse(b)) != b"
            );
            assert_eq!(
                rt.emit(&mut out[..ReceiveTimes::LEN - 1]),
                Err(Error::Truncated)
            );
        }
    }
}

// Kani harnesses. Kani is not installable on the build machine: under `cargo kani -p
// ecdc-proofs` these are symbolic proofs (NOT run here); in ordinary builds `kani::` is
// `crate::kani_shim` and `proofs/tests/wire.rs` runs them with random boundary-biased inputs,
// which is a random test, not a proof.
#[cfg(not(kani))]
use crate::kani_shim as kani;

/// Largest symbolic buffer for the no-panic proof.
const KANI_N: usize = 40;

/// P1: parsing any buffer of up to 40 bytes never panics and every span lies inside it
/// (symbolic length over a fixed buffer).
#[cfg_attr(kani, kani::proof)]
#[cfg_attr(kani, kani::unwind(42))]
pub fn kani_parse_never_panics() {
    let mut buf: [u8; KANI_N] = kani::any();
    // A byte reduced modulo KANI_N + 1: under Kani every length 0..=KANI_N; under the shim
    // (where `any_where` on a `usize` only ever accepts the small draws) every length too.
    let len = usize::from(kani::any::<u8>()) % (KANI_N + 1);
    // Half of the runs get a consistent DLPDU header so the walk is reached often (under Kani
    // the other half still covers every header word).
    if kani::any::<bool>() && len >= 2 {
        let h = u16::try_from(len - 2).unwrap_or(0) | 0x1000;
        buf[..2].copy_from_slice(&h.to_le_bytes());
        // ... and a first datagram whose length fills the frame exactly.
        if kani::any::<bool>() && len >= 14 {
            buf[2] %= 15;
            let w = u16::try_from(len - 14).unwrap_or(0);
            buf[8..10].copy_from_slice(&w.to_le_bytes());
        }
    }
    kani::cover!(len == KANI_N, "the longest buffer is reachable");
    let bytes = &buf[..len];
    let checked = EcatFrame::new_checked(bytes);
    kani::cover!(checked.is_ok(), "a valid frame is reachable");
    kani::cover!(
        matches!(checked, Err(Error::LengthMismatch { .. })),
        "a length mismatch is reachable"
    );
    kani::cover!(
        checked.map(|f| f.datagram_count()) == Ok(Ok(2)),
        "two datagrams are reachable"
    );
    parse_any(bytes);
}

/// P1: emit -> parse is the identity for two datagrams with up to 4 data bytes each.
#[cfg_attr(kani, kani::proof)]
#[cfg_attr(kani, kani::unwind(64))]
pub fn kani_emit_parse_roundtrip() {
    let data: [u8; 8] = kani::any();
    let l0: usize = kani::any_where(|l: &usize| *l <= 4);
    let l1: usize = kani::any_where(|l: &usize| *l <= 4);
    let r0 = normalise(
        kani::any(),
        kani::any(),
        kani::any(),
        kani::any(),
        kani::any(),
        kani::any(),
        l0,
    );
    let r1 = normalise(
        kani::any(),
        kani::any(),
        kani::any(),
        kani::any(),
        kani::any(),
        kani::any(),
        l1,
    );
    let list = [(r0, &data[..l0]), (r1, &data[4..4 + l1])];
    let mut buf = [0u8; 64];
    let n = roundtrip(&list, &mut buf);
    kani::cover!(n == 2, "both datagrams fit");
}

/// REQ-WIRE-004/013 for every length/flags word.
#[cfg_attr(kani, kani::proof)]
#[cfg_attr(kani, kani::unwind(2))]
pub fn kani_len_flags_every_word() {
    let w: u16 = kani::any();
    kani::cover!(w & 0x3800 != 0, "reserved bits set");
    len_flags_word(w);
}

/// REQ-WIRE-005, 012..015 for every EtherCAT header word.
#[cfg_attr(kani, kani::proof)]
#[cfg_attr(kani, kani::unwind(4))]
pub fn kani_ecat_header_every_word() {
    let w: u16 = kani::any();
    kani::cover!(w >> 12 == 1, "a DLPDU header is reachable");
    ecat_header_word(w);
}

/// REQ-WIRE-073 for every raw word and every i64.
#[cfg_attr(kani, kani::proof)]
pub fn kani_system_time_difference_all() {
    let raw: u32 = kani::any();
    let ns: i64 = kani::any();
    kani::cover!(ns < -0x7FFF_FFFF, "saturating negative encode");
    system_time_difference(raw, ns);
}

/// Every wire harness, for running under the shim.
pub const KANI_HARNESSES: [(&str, fn()); 5] = [
    ("kani_parse_never_panics", kani_parse_never_panics),
    ("kani_emit_parse_roundtrip", kani_emit_parse_roundtrip),
    ("kani_len_flags_every_word", kani_len_flags_every_word),
    ("kani_ecat_header_every_word", kani_ecat_header_every_word),
    (
        "kani_system_time_difference_all",
        kani_system_time_difference_all,
    ),
];
