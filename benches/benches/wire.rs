//! Wire codec throughput: parse (validate + walk every datagram, reading its fields) and emit
//! (build into a reused buffer) for
//! - `cyclic`: the typical DC cycle frame FRMW 0x0910 8 B + BRD 0x092C 4 B + LRW 64 B (128 B);
//! - `full`: a 1514-byte frame with one 1486-byte LRW;
//! - `many`: 40 FPRD datagrams of 4 bytes (a scan-style frame, 670 B).
//!
//! Throughput is reported in bytes of frame; frames/s = 1 / time per iteration.
//!
//! Times are this thread's CPU time (`common::ThreadCpu`: the machine is shared).

use criterion::{black_box, criterion_group, criterion_main, Criterion, Throughput};

mod common;
use common::ThreadCpu;
use ecdc_core::wire::{Address, Command, EthernetFrame, FrameBuilder};

type Build = fn(&mut FrameBuilder<'_>);

fn cyclic(b: &mut FrameBuilder<'_>) {
    let _ = b.push(
        Command::Frmw,
        1,
        Address::configured(0x1001, 0x0910),
        &[0; 8],
    );
    let _ = b.push(Command::Brd, 2, Address::broadcast(0x092C), &[0; 4]);
    let _ = b.push(Command::Lrw, 3, Address::logical(0), &[0x5A; 64]);
}

fn full(b: &mut FrameBuilder<'_>) {
    let _ = b.push(Command::Lrw, 1, Address::logical(0), &[0x5A; 1486]);
}

fn many(b: &mut FrameBuilder<'_>) {
    for i in 0..40u16 {
        let _ = b.push(
            Command::Fprd,
            i as u8,
            Address::configured(0x1000 + i, 0x0130),
            &[0; 4],
        );
    }
}

fn build(buf: &mut [u8], f: Build) -> usize {
    let mut b = FrameBuilder::new(buf).expect("buffer >= 60");
    f(&mut b);
    b.finish().expect("non-empty")
}

/// Validates the frame and touches every datagram's header, data and WKC.
fn parse(frame: &[u8]) -> u64 {
    let eth = EthernetFrame::new_checked(frame).expect("ethernet");
    let ecat = eth.into_ecat_frame().expect("valid frame");
    let mut acc = 0u64;
    for d in ecat.iter() {
        let d = d.expect("valid datagram");
        acc = acc
            .wrapping_add(u64::from(d.command_raw()))
            .wrapping_add(u64::from(d.logical_address()))
            .wrapping_add(u64::from(d.wkc()))
            .wrapping_add(d.data().len() as u64);
    }
    acc
}

fn bench_wire(c: &mut Criterion<ThreadCpu>) {
    let cases: [(&str, Build); 3] = [("cyclic", cyclic), ("full", full), ("many", many)];
    for (name, f) in cases {
        let mut buf = [0u8; 1514];
        let n = build(&mut buf, f);
        let frame = buf[..n].to_vec();
        assert!(parse(&frame) > 0, "{name} parses");

        let mut g = c.benchmark_group(format!("wire/{name}"));
        g.throughput(Throughput::Bytes(n as u64));
        g.bench_function("parse", |b| b.iter(|| black_box(parse(black_box(&frame)))));
        g.bench_function("emit", |b| {
            b.iter(|| black_box(build(black_box(&mut buf), f)))
        });
        g.finish();
    }
}

criterion_group! {
    name = benches;
    config = common::criterion();
    targets = bench_wire
}
criterion_main!(benches);
