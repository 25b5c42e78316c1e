//! Shared helpers for the emulator tests: frames are built and parsed with `ecdc_core::wire`,
//! so every emulator test also checks that what the emulator returns is a valid frame.
#![allow(dead_code)]

use ecdc_core::wire::{Address, Command, EcatFrame, EthernetFrame, FrameBuilder};
use ecdc_harness::emu::{Delivery, Network, Returned, Scenario};

/// One datagram as the master sees it in the reply.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Reply {
    pub adp: u16,
    pub ado: u16,
    pub data: Vec<u8>,
    pub wkc: u16,
    pub circulating: bool,
}

/// Builds an Ethernet frame with the given datagrams.
pub fn frame(dgs: &[(Command, Address, &[u8])]) -> Vec<u8> {
    let mut buf = vec![0u8; 1514];
    let mut b = FrameBuilder::new(&mut buf).unwrap();
    for (i, (c, a, d)) in dgs.iter().enumerate() {
        b.push(*c, i as u8, *a, d).unwrap();
    }
    let n = b.finish().unwrap();
    buf.truncate(n);
    buf
}

/// Parses the datagrams of a returned frame (strictly, with the core codec).
pub fn replies(frame: &[u8]) -> Vec<Reply> {
    let eth = EthernetFrame::new_checked(frame).unwrap();
    let ecat = EcatFrame::new_checked(eth.payload()).unwrap();
    ecat.iter()
        .map(|d| {
            let d = d.unwrap();
            Reply {
                adp: d.adp(),
                ado: d.ado(),
                data: d.data().to_vec(),
                wkc: d.wkc(),
                circulating: d.circulating(),
            }
        })
        .collect()
}

/// Sends one frame, expects it back.
pub fn send(
    net: &mut Network,
    t: u64,
    dgs: &[(Command, Address, &[u8])],
) -> (Vec<Reply>, Returned) {
    let f = frame(dgs);
    match net.transact(&f, t).unwrap() {
        Delivery::Returned(r) => (replies(&r.frame), r),
        Delivery::Lost(why) => panic!("frame lost: {why:?}"),
    }
}

/// Sends one datagram, expects it back; returns (reply, arrival).
pub fn one(net: &mut Network, t: u64, c: Command, a: Address, d: &[u8]) -> (Reply, u64) {
    let (r, ret) = send(net, t, &[(c, a, d)]);
    (r.into_iter().next().unwrap(), ret.arrival)
}

/// Sends one read datagram of `len` bytes (zeros) at `t`; returns (reply, arrival).
pub fn read(net: &mut Network, t: u64, c: Command, a: Address, len: usize) -> (Reply, u64) {
    one(net, t, c, a, &vec![0; len])
}

/// FPRD of `len` bytes from register `ado` of station `st` at `t`; returns (reply, arrival).
pub fn fprd_at(net: &mut Network, t: u64, st: u16, ado: u16, len: usize) -> (Reply, u64) {
    read(net, t, Command::Fprd, Address::configured(st, ado), len)
}

/// APRD of `len` bytes from register `ado` of the slave at position `pos` at `t`; returns
/// (reply, arrival).
pub fn aprd_at(net: &mut Network, t: u64, pos: u16, ado: u16, len: usize) -> (Reply, u64) {
    read(net, t, Command::Aprd, Address::position(pos, ado), len)
}

/// FPWR of `d` to register `ado` of station `st` at `t`; returns (reply, arrival).
pub fn fpwr_at(net: &mut Network, t: u64, st: u16, ado: u16, d: &[u8]) -> (Reply, u64) {
    one(net, t, Command::Fpwr, Address::configured(st, ado), d)
}

/// APWR of `d` to register `ado` of the slave at position `pos` at `t`; returns (reply,
/// arrival).
pub fn apwr_at(net: &mut Network, t: u64, pos: u16, ado: u16, d: &[u8]) -> (Reply, u64) {
    one(net, t, Command::Apwr, Address::position(pos, ado), d)
}

pub fn u16_of(d: &[u8]) -> u16 {
    u16::from_le_bytes([d[0], d[1]])
}
pub fn u32_of(d: &[u8]) -> u32 {
    u32::from_le_bytes(d[..4].try_into().unwrap())
}
pub fn u64_of(d: &[u8]) -> u64 {
    u64::from_le_bytes(d[..8].try_into().unwrap())
}

/// The network of `sc` with its slaves addressed ([`address_all`] from 0); returns it and the
/// time after the last reply.
pub fn addressed(sc: &Scenario) -> (Network, u64) {
    let mut net = Network::new(sc).unwrap();
    let t = address_all(&mut net, 0);
    (net, t)
}

/// Assigns station addresses 0x1000 + i by APWR, returns the time after the last reply.
pub fn address_all(net: &mut Network, mut t: u64) -> u64 {
    for i in 0..net.slave_count() {
        let a = (0x1000 + i as u16).to_le_bytes();
        let (r, arr) = apwr_at(net, t, i as u16, 0x0010, &a);
        assert_eq!(r.wkc, 1);
        t = arr + 1_000;
    }
    t
}

/// BWR of `d` to register `ado` at `t`; returns the time 1 µs after the reply.
pub fn bwr(net: &mut Network, t: u64, ado: u16, d: &[u8]) -> u64 {
    let (_, a) = one(net, t, Command::Bwr, Address::broadcast(ado), d);
    a + 1000
}

/// Starts SYNC0 on every slave by BWR from `t`: start time 0x0990, cycle 0x09A0, then the
/// activation 0x0981 (cyclic unit and SYNC0). Returns the time 1 µs after the last reply.
pub fn start_sync0_all(net: &mut Network, t: u64, start_ns: u64, cycle_ns: u32) -> u64 {
    let t = bwr(net, t, 0x0990, &start_ns.to_le_bytes());
    let t = bwr(net, t, 0x09A0, &cycle_ns.to_le_bytes());
    bwr(net, t, 0x0981, &[0x03])
}
