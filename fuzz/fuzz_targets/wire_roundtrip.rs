//! Fuzz target: structured datagram lists through the builder and back.
//! Body: `ecdc_proofs::wire::roundtrip` (P1, REQ-WIRE-030, REQ-WIRE-040..042).
//! verifies: REQ-WIRE-030, REQ-WIRE-040, REQ-WIRE-041, REQ-WIRE-042
#![no_main]

use arbitrary::Arbitrary;
use libfuzzer_sys::fuzz_target;

#[derive(Debug, Arbitrary)]
struct Dg {
    cmd: u8,
    index: u8,
    address: u32,
    circulating: bool,
    irq: u16,
    wkc: u16,
    data: Vec<u8>,
}

#[derive(Debug, Arbitrary)]
struct Input {
    capacity: u16,
    datagrams: Vec<Dg>,
}

fuzz_target!(|input: Input| {
    let data: Vec<Vec<u8>> = input
        .datagrams
        .iter()
        .map(|d| d.data[..d.data.len().min(1486)].to_vec())
        .collect();
    let list: Vec<_> = input
        .datagrams
        .iter()
        .zip(&data)
        .map(|(d, bytes)| {
            let repr = ecdc_proofs::wire::normalise(
                d.cmd,
                d.index,
                d.address,
                d.circulating,
                d.irq,
                d.wkc,
                bytes.len(),
            );
            (repr, &bytes[..])
        })
        .collect();
    let mut buf = vec![0xA5u8; usize::from(input.capacity % 1600)];
    ecdc_proofs::wire::roundtrip(&list, &mut buf);
});
