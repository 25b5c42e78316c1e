//! Datagram header codec, ecdc against `ethercrab-wire` (crates.io), same inputs, same run.
//!
//! Inputs: 64 datagrams (10-byte header + data + WKC) of a DC cycle and a scan: FRMW 0x0910
//! 8 B, BRD 0x092C 4 B, BRD 0x0130 2 B, FPRD 0x092C 4 B, LRW 64 B, APWR 0x0010 2 B, with varied
//! indexes, addresses, IRQ and C/M bits. Both sides decode every header field (command, index,
//! ADP, ADO, length, C, M, IRQ) into the same plain struct [`Hdr`], and encode that struct back
//! into 10 header bytes.
//!
//! - ecdc decode: `Datagram::new_checked` (which also validates the command code, the reserved
//!   bits and that data + WKC are present — more work than ethercrab does) and its accessors;
//! - ethercrab decode: `EtherCrabWireRead::unpack_from_slice` of a header type written the way
//!   ethercrab writes its `PduHeader` (derived struct; hand-written flags word, as ethercrab's
//!   `PduFlags`), which checks only that 10 bytes are present;
//! - ecdc encode: `Datagram` setters; ethercrab encode: `EtherCrabWireWrite::pack_to_slice`.
//!
//! Times are this thread's CPU time (`common::ThreadCpu`). Every decode is checked against the
//! other side's result before timing. Prints
//! `ecdc/ethercrab = x` for decode and encode from criterion's medians (and from an interleaved
//! re-measurement, which is robust to load changes between the two criterion runs).

use criterion::{black_box, criterion_group, criterion_main, Criterion, Throughput};

mod common;
use common::ThreadCpu;
use ecdc_core::wire::{Address, Command, Datagram, FrameBuilder};
use ethercrab_wire::{
    EtherCrabWireRead, EtherCrabWireReadWrite, EtherCrabWireSized, EtherCrabWireWrite, WireError,
};

/// Every field of a datagram header.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
struct Hdr {
    command: u8,
    index: u8,
    adp: u16,
    ado: u16,
    len: u16,
    circulating: bool,
    more: bool,
    irq: u16,
}

/// The length/flags word as ethercrab models it (`PduFlags`): 11-bit length, C, M.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
struct CrabFlags {
    length: u16,
    circulated: bool,
    is_not_last: bool,
}

impl EtherCrabWireSized for CrabFlags {
    const PACKED_LEN: usize = 2;
    type Buffer = [u8; 2];
    fn buffer() -> Self::Buffer {
        [0; 2]
    }
}

impl EtherCrabWireRead for CrabFlags {
    fn unpack_from_slice(buf: &[u8]) -> Result<Self, WireError> {
        let raw = u16::unpack_from_slice(buf)?;
        Ok(CrabFlags {
            length: raw & 0x07FF,
            circulated: raw & 0x4000 != 0,
            is_not_last: raw & 0x8000 != 0,
        })
    }
}

impl EtherCrabWireWrite for CrabFlags {
    fn pack_to_slice_unchecked<'b>(&self, buf: &'b mut [u8]) -> &'b [u8] {
        let raw = (self.length & 0x07FF)
            | (u16::from(self.circulated) << 14)
            | (u16::from(self.is_not_last) << 15);
        raw.pack_to_slice_unchecked(buf)
    }
    fn packed_len(&self) -> usize {
        2
    }
}

/// The 10-byte header, derived with ethercrab-wire.
#[derive(Debug, Clone, Copy, PartialEq, Eq, EtherCrabWireReadWrite)]
#[wire(bytes = 10)]
struct CrabHeader {
    #[wire(bytes = 1)]
    command: u8,
    #[wire(bytes = 1)]
    index: u8,
    #[wire(bytes = 2)]
    adp: u16,
    #[wire(bytes = 2)]
    ado: u16,
    #[wire(bytes = 2)]
    flags: CrabFlags,
    #[wire(bytes = 2)]
    irq: u16,
}

#[inline]
fn ecdc_decode(b: &[u8]) -> Option<Hdr> {
    let d = Datagram::new_checked(b).ok()?;
    Some(Hdr {
        command: d.command_raw(),
        index: d.index(),
        adp: d.adp(),
        ado: d.ado(),
        len: d.data_len(),
        circulating: d.circulating(),
        more: d.more(),
        irq: d.irq(),
    })
}

#[inline]
fn crab_decode(b: &[u8]) -> Option<Hdr> {
    let h = CrabHeader::unpack_from_slice(b).ok()?;
    Some(Hdr {
        command: h.command,
        index: h.index,
        adp: h.adp,
        ado: h.ado,
        len: h.flags.length,
        circulating: h.flags.circulated,
        more: h.flags.is_not_last,
        irq: h.irq,
    })
}

#[inline]
fn ecdc_encode(h: &Hdr, out: &mut [u8]) -> bool {
    if out.len() < 10 {
        return false;
    }
    let mut d = Datagram::new_unchecked(out);
    d.set_command_raw(h.command);
    d.set_index(h.index);
    d.set_adp(h.adp);
    d.set_ado(h.ado);
    d.set_len_flags(
        (h.len & 0x07FF) | (u16::from(h.circulating) << 14) | (u16::from(h.more) << 15),
    );
    d.set_irq(h.irq);
    true
}

#[inline]
fn crab_encode(h: &Hdr, out: &mut [u8]) -> bool {
    CrabHeader {
        command: h.command,
        index: h.index,
        adp: h.adp,
        ado: h.ado,
        flags: CrabFlags {
            length: h.len,
            circulated: h.circulating,
            is_not_last: h.more,
        },
        irq: h.irq,
    }
    .pack_to_slice(out)
    .is_ok()
}

/// 64 datagrams (each its own buffer: header + data + WKC), built by ecdc's frame builder.
fn inputs() -> Vec<Vec<u8>> {
    let kinds: [(Command, Address, usize); 6] = [
        (Command::Frmw, Address::configured(0x1001, 0x0910), 8),
        (Command::Brd, Address::broadcast(0x092C), 4),
        (Command::Brd, Address::broadcast(0x0130), 2),
        (Command::Fprd, Address::configured(0x1005, 0x092C), 4),
        (Command::Lrw, Address::logical(0x0001_0000), 64),
        (Command::Apwr, Address::position(3, 0x0010), 2),
    ];
    let mut out = Vec::new();
    for i in 0..64usize {
        let (c, a, len) = kinds[i % kinds.len()];
        let mut buf = vec![0u8; 128];
        let mut b = FrameBuilder::new(&mut buf).expect("buffer");
        let data: Vec<u8> = (0..len).map(|k| (k * 7 + i) as u8).collect();
        let slot = b.push(c, (0x80 + i) as u8, a, &data).expect("fits");
        let mut d = b.datagram_mut(slot).expect("slot");
        d.set_irq((i as u16).wrapping_mul(0x1111));
        d.set_circulating(i % 5 == 0);
        d.set_more(i % 2 == 0);
        d.set_wkc(i as u16);
        let start = slot.offset();
        let end = slot.data_offset() + len + 2;
        out.push(buf[start..end].to_vec());
    }
    out
}

fn decode_all(f: fn(&[u8]) -> Option<Hdr>, ins: &[Vec<u8>]) -> u64 {
    let mut acc = 0u64;
    for b in ins {
        if let Some(h) = f(black_box(b)) {
            acc = acc
                .wrapping_add(u64::from(h.command))
                .wrapping_add(u64::from(h.index))
                .wrapping_add(u64::from(h.adp))
                .wrapping_add(u64::from(h.ado))
                .wrapping_add(u64::from(h.len))
                .wrapping_add(u64::from(h.circulating))
                .wrapping_add(u64::from(h.more) << 1)
                .wrapping_add(u64::from(h.irq));
        }
    }
    acc
}

fn encode_all(f: fn(&Hdr, &mut [u8]) -> bool, hs: &[Hdr], out: &mut [[u8; 10]]) -> usize {
    let mut ok = 0;
    for (h, o) in hs.iter().zip(out.iter_mut()) {
        ok += usize::from(f(black_box(h), o));
    }
    black_box(out);
    ok
}

/// Median of `rounds` interleaved timings (thread CPU ns per header) of `a` and `b`.
fn interleaved(rounds: usize, mut a: impl FnMut(), mut b: impl FnMut(), per: f64) -> (f64, f64) {
    let mut ta = Vec::with_capacity(rounds);
    let mut tb = Vec::with_capacity(rounds);
    for _ in 0..rounds {
        let t = common::thread_cpu_ns();
        a();
        ta.push(common::thread_cpu_ns().saturating_sub(t) as f64 / per);
        let t = common::thread_cpu_ns();
        b();
        tb.push(common::thread_cpu_ns().saturating_sub(t) as f64 / per);
    }
    ta.sort_by(f64::total_cmp);
    tb.sort_by(f64::total_cmp);
    (ta[rounds / 2], tb[rounds / 2])
}

/// Criterion's median for `group/name` from its estimates file, if it can be found.
fn criterion_median(group: &str, name: &str) -> Option<f64> {
    let base = std::env::var_os("CRITERION_HOME")
        .map(std::path::PathBuf::from)
        .or_else(|| {
            std::env::var_os("CARGO_TARGET_DIR")
                .map(|t| std::path::PathBuf::from(t).join("criterion"))
        })
        .unwrap_or_else(|| {
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/criterion")
        });
    let p = base.join(group).join(name).join("new/estimates.json");
    let s = std::fs::read_to_string(p).ok()?;
    // {"mean":{...},"median":{"confidence_interval":{...},"point_estimate":X,...
    let m = s.find("\"median\"")?;
    let rest = &s[m..];
    let k = rest.find("\"point_estimate\":")? + "\"point_estimate\":".len();
    let v = &rest[k..];
    let end = v.find([',', '}'])?;
    v[..end].trim().parse().ok()
}

fn bench_codec(c: &mut Criterion<ThreadCpu>) {
    let ins = inputs();
    let n = ins.len();
    // Both decoders agree on every field of every input.
    let hs: Vec<Hdr> = ins
        .iter()
        .map(|b| {
            let a = ecdc_decode(b).expect("ecdc decodes");
            assert_eq!(Some(a), crab_decode(b), "same fields");
            a
        })
        .collect();
    // Both encoders write the same 10 bytes, equal to the input header.
    for (h, b) in hs.iter().zip(&ins) {
        let (mut x, mut y) = ([0u8; 10], [0u8; 10]);
        assert!(ecdc_encode(h, &mut x) && crab_encode(h, &mut y));
        assert_eq!(x, y, "same bytes");
        assert_eq!(&x[..], &b[..10], "round trip");
    }

    let mut g = c.benchmark_group("header_codec");
    g.throughput(Throughput::Elements(n as u64));
    g.bench_function("decode/ecdc", |b| b.iter(|| decode_all(ecdc_decode, &ins)));
    g.bench_function("decode/ethercrab", |b| {
        b.iter(|| decode_all(crab_decode, &ins))
    });
    let mut out = vec![[0u8; 10]; n];
    g.bench_function("encode/ecdc", |b| {
        b.iter(|| encode_all(ecdc_encode, &hs, &mut out))
    });
    g.bench_function("encode/ethercrab", |b| {
        b.iter(|| encode_all(crab_encode, &hs, &mut out))
    });
    g.finish();

    let reps = 20_000usize;
    let per = (reps * n) as f64;
    let (de, dc) = interleaved(
        31,
        || {
            for _ in 0..reps {
                black_box(decode_all(ecdc_decode, &ins));
            }
        },
        || {
            for _ in 0..reps {
                black_box(decode_all(crab_decode, &ins));
            }
        },
        per,
    );
    let mut out2 = out.clone();
    let (ee, ec) = interleaved(
        31,
        || {
            for _ in 0..reps {
                black_box(encode_all(ecdc_encode, &hs, &mut out));
            }
        },
        || {
            for _ in 0..reps {
                black_box(encode_all(crab_encode, &hs, &mut out2));
            }
        },
        per,
    );
    println!();
    println!("header codec, ecdc vs ethercrab-wire 0.3, {n} headers per iteration");
    for (what, e_name, c_name) in [
        ("decode", "decode_ecdc", "decode_ethercrab"),
        ("encode", "encode_ecdc", "encode_ethercrab"),
    ] {
        match (
            criterion_median("header_codec", e_name),
            criterion_median("header_codec", c_name),
        ) {
            (Some(e), Some(x)) => println!(
                "  {what} (criterion medians): ecdc {:.2} ns/header, ethercrab {:.2} ns/header, ecdc/ethercrab = {:.3}",
                e / n as f64,
                x / n as f64,
                e / x
            ),
            _ => println!("  {what}: criterion estimates not found (run without --test)"),
        }
    }
    println!(
        "  decode (interleaved, median of 31): ecdc {de:.2} ns/header, ethercrab {dc:.2} ns/header, ecdc/ethercrab = {:.3}",
        de / dc
    );
    println!(
        "  encode (interleaved, median of 31): ecdc {ee:.2} ns/header, ethercrab {ec:.2} ns/header, ecdc/ethercrab = {:.3}",
        ee / ec
    );
}

criterion_group! {
    name = benches;
    config = common::criterion();
    targets = bench_codec
}
criterion_main!(benches);
