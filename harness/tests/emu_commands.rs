//! WKC and ADP behaviour of every command (REQ-ESC-001..REQ-ESC-006), checked through frames
//! built and parsed with `ecdc_core::wire`.
//!
//! verifies: REQ-ESC-001, REQ-ESC-002, REQ-ESC-003, REQ-ESC-004, REQ-ESC-005, REQ-ESC-006

mod emu_support;

use ecdc_core::wire::{Address, Command};
use ecdc_harness::emu::{Delivery, EscKind, Fault, LossReason, Network, Scenario, SlaveSpec};
use emu_support::*;

fn net3() -> (Network, u64) {
    addressed(&Scenario::line(3).ideal())
}

/// A network driven one datagram at a time, each sent 1 µs after the previous reply came back.
struct Bus {
    net: Network,
    t: u64,
}

impl Bus {
    /// The network of [`net3`] or [`addressed`], from the time they return.
    fn new((net, t): (Network, u64)) -> Self {
        Bus { net, t }
    }

    /// One datagram carrying `d`; its reply.
    fn one(&mut self, c: Command, a: Address, d: &[u8]) -> Reply {
        let (r, back) = one(&mut self.net, self.t, c, a, d);
        self.t = back + 1000;
        r
    }

    /// One datagram carrying `len` zero bytes; its reply.
    fn read(&mut self, c: Command, a: Address, len: usize) -> Reply {
        self.one(c, a, &vec![0; len])
    }

    /// `len` bytes of register `ado` of slave `i`, as the emulator holds them.
    fn peek(&self, i: usize, ado: u16, len: usize) -> Vec<u8> {
        self.net.peek(i, ado, len).unwrap()
    }
}

/// REQ-ESC-002: APRD acts at ADP 0, every slave increments ADP.
// verifies: REQ-ESC-002
#[test]
fn aprd_auto_increment() {
    let mut bus = Bus::new(net3());
    let r = bus.read(Command::Aprd, Address::position(1, 0x0010), 2);
    assert_eq!(r.wkc, 1);
    assert_eq!(u16_of(&r.data), 0x1001);
    // Sent 0xFFFF, passed 3 slaves.
    assert_eq!(r.adp, 0xFFFFu16.wrapping_add(3));
    // Position beyond the chain: nobody answers.
    let r = bus.read(Command::Aprd, Address::position(5, 0x0010), 2);
    assert_eq!(r.wkc, 0);
    assert_eq!(r.data, vec![0, 0]);
}

/// REQ-ESC-002: APWR writes only the addressed slave; APRW returns the old value, WKC 3.
// verifies: REQ-ESC-002
#[test]
fn apwr_aprw() {
    let mut bus = Bus::new(net3());
    let r = bus.one(Command::Apwr, Address::position(2, 0x1000), &[0xAB]);
    assert_eq!(r.wkc, 1);
    assert_eq!(bus.peek(2, 0x1000, 1), vec![0xAB]);
    assert_eq!(bus.peek(1, 0x1000, 1), vec![0x00]);
    let r = bus.one(Command::Aprw, Address::position(2, 0x1000), &[0xCD]);
    assert_eq!(r.wkc, 3);
    assert_eq!(r.data, vec![0xAB]);
    assert_eq!(bus.peek(2, 0x1000, 1), vec![0xCD]);
}

/// REQ-ESC-002: FPxx match the configured address, ADP is left untouched.
// verifies: REQ-ESC-002
#[test]
fn configured_address_commands() {
    let mut bus = Bus::new(net3());
    let r = bus.read(Command::Fprd, Address::configured(0x1002, 0x0010), 2);
    assert_eq!((r.wkc, u16_of(&r.data), r.adp), (1, 0x1002, 0x1002));
    let r = bus.one(Command::Fpwr, Address::configured(0x1001, 0x1004), &[7]);
    assert_eq!(r.wkc, 1);
    assert_eq!(bus.peek(1, 0x1004, 1), vec![7]);
    let r = bus.one(Command::Fprw, Address::configured(0x1001, 0x1004), &[9]);
    assert_eq!((r.wkc, r.data.clone()), (3, vec![7]));
    let r = bus.read(Command::Fprd, Address::configured(0x7777, 0x0010), 2);
    assert_eq!(r.wkc, 0);
}

/// REQ-ESC-003: the station alias answers only when DL control bit 24 is set.
// verifies: REQ-ESC-003
#[test]
fn alias_addressing() {
    let sc = Scenario::default().ideal().with_slave(SlaveSpec {
        alias: 0x0ABC,
        ..SlaveSpec::default()
    });
    let mut bus = Bus::new((Network::new(&sc).unwrap(), 0));
    let by_alias = Address::configured(0x0ABC, 0x0000);
    assert_eq!(bus.read(Command::Fprd, by_alias, 1).wkc, 0);
    let r = bus.one(Command::Fpwr, Address::configured(0, 0x0103), &[1]);
    assert_eq!(r.wkc, 1);
    let r = bus.read(Command::Fprd, by_alias, 1);
    assert_eq!((r.wkc, r.data[0]), (1, 0x11));
}

/// REQ-ESC-002: BRD ORs every slave's memory into the data; BWR/BRW count every slave.
// verifies: REQ-ESC-002
#[test]
fn broadcast_commands() {
    let mut bus = Bus::new(net3());
    for (i, v) in [0x01u8, 0x02, 0x10].into_iter().enumerate() {
        let station = 0x1000 + i as u16;
        let r = bus.one(Command::Fpwr, Address::configured(station, 0x1010), &[v]);
        assert_eq!(r.wkc, 1);
    }
    let r = bus.one(Command::Brd, Address::broadcast(0x1010), &[0x80]);
    assert_eq!((r.wkc, r.data[0], r.adp), (3, 0x93, 3));
    let r = bus.one(Command::Bwr, Address::broadcast(0x1011), &[0x44]);
    assert_eq!((r.wkc, r.adp), (3, 3));
    for i in 0..3 {
        assert_eq!(bus.peek(i, 0x1011, 1), vec![0x44]);
    }
    let r = bus.one(Command::Brw, Address::broadcast(0x1010), &[0x20]);
    assert_eq!((r.wkc, r.data[0]), (9, 0x33));
    // BRW: each slave writes the data as it arrives (already ORed by the slaves before it).
    for (i, v) in [0x20u8, 0x21, 0x23].into_iter().enumerate() {
        assert_eq!(bus.peek(i, 0x1010, 1), vec![v]);
    }
}

fn fmmu(log: u32, len: u16, phys: u16, typ: u8) -> Vec<u8> {
    let mut f = vec![0u8; 16];
    f[0..4].copy_from_slice(&log.to_le_bytes());
    f[4..6].copy_from_slice(&len.to_le_bytes());
    f[7] = 7;
    f[8..10].copy_from_slice(&phys.to_le_bytes());
    f[11] = typ;
    f[12] = 1;
    f
}

/// REQ-ESC-002: logical commands go through the FMMU table; LRW counts +1 read, +2 write.
// verifies: REQ-ESC-002
#[test]
fn logical_commands() {
    let mut bus = Bus::new(net3());
    // Slave 0: logical 0x10000..0x10004 written to 0x1100. Slave 1: same range read from 0x1200.
    for (station, ado, d) in [
        (0x1000, 0x0600, fmmu(0x10000, 4, 0x1100, 2)),
        (0x1001, 0x0600, fmmu(0x10000, 4, 0x1200, 1)),
        (0x1001, 0x1200, vec![1, 2, 3, 4]),
    ] {
        let r = bus.one(Command::Fpwr, Address::configured(station, ado), &d);
        assert_eq!(r.wkc, 1);
    }
    let r = bus.one(Command::Lrw, Address::Logical(0x10000), &[9, 9, 9, 9]);
    assert_eq!(r.wkc, 3);
    assert_eq!(r.data, vec![1, 2, 3, 4]);
    assert_eq!(bus.peek(0, 0x1100, 4), vec![9, 9, 9, 9]);
    let r = bus.read(Command::Lrd, Address::Logical(0x0FFFE), 4);
    assert_eq!((r.wkc, r.data.clone()), (1, vec![0, 0, 1, 2]));
    let r = bus.one(Command::Lwr, Address::Logical(0x10002), &[5, 5, 5, 5]);
    assert_eq!(r.wkc, 1);
    assert_eq!(bus.peek(0, 0x1100, 4), vec![9, 9, 5, 5]);
    let r = bus.read(Command::Lrd, Address::Logical(0x20000), 4);
    assert_eq!(r.wkc, 0);
}

/// REQ-ESC-006: ARMW/FRMW — the addressed slave reads, every other slave (before and after it
/// in the path) writes; each counts 1.
// verifies: REQ-ESC-006
#[test]
fn read_multiple_write() {
    let mut bus = Bus::new(net3());
    let r = bus.read(Command::Armw, Address::position(1, 0x0910), 8);
    assert_eq!(r.wkc, 3);
    assert_eq!(r.adp, 0xFFFFu16.wrapping_add(3));
    let sys1 = u64_of(&r.data);
    assert!(sys1 > 0);
    // Loop samples are applied at the end of the frame at each slave, which has passed by
    // the time of the next command.
    bus.net.advance_to(bus.t).unwrap();
    // Slaves 0 and 2 took a sample: their 0x092C is no longer the reset value 0.
    assert_ne!(u32_of(&bus.peek(0, 0x092C, 4)), 0);
    assert_ne!(u32_of(&bus.peek(2, 0x092C, 4)), 0);
    assert_eq!(u32_of(&bus.peek(1, 0x092C, 4)), 0);
    let r = bus.read(Command::Frmw, Address::configured(0x1001, 0x0910), 8);
    assert_eq!((r.wkc, r.adp), (3, 0x1001));
    assert!(u64_of(&r.data) > sys1);
}

/// REQ-ESC-006: FRMW to 0x0910 counts only slaves with system time.
// verifies: REQ-ESC-006
#[test]
fn frmw_counts_dc_slaves_only() {
    let mut sc = Scenario::default().ideal();
    for k in [
        EscKind::Dc64,
        EscKind::NoDc,
        EscKind::DcReceiveTimesOnly,
        EscKind::Dc32,
    ] {
        sc = sc.with_slave(SlaveSpec {
            kind: Some(k),
            ports: Some(3),
            ..SlaveSpec::default()
        });
    }
    let mut bus = Bus::new(addressed(&sc));
    let r = bus.read(Command::Frmw, Address::configured(0x1000, 0x0910), 8);
    assert_eq!(r.wkc, 2);
    // IgH's "has system time" probe: FPRD 0x0910 answers only with system time.
    let r = bus.read(Command::Fprd, Address::configured(0x1002, 0x0910), 8);
    assert_eq!(r.wkc, 0);
    let r = bus.read(Command::Fprd, Address::configured(0x1002, 0x0900), 4);
    assert_eq!(r.wkc, 1);
    let r = bus.one(Command::Bwr, Address::broadcast(0x0900), &[0; 4]);
    assert_eq!(r.wkc, 3);
}

/// NOP and unknown command codes pass untouched.
#[test]
fn nop_and_unknown() {
    let mut bus = Bus::new(net3());
    let r = bus.one(Command::Nop, Address::Raw(0x0010_0000), &[1, 2]);
    assert_eq!((r.wkc, r.adp, r.data.clone()), (0, 0, vec![1, 2]));
    let mut f = frame(&[(Command::Aprd, Address::position(0, 0x10), &[0, 0])]);
    f[16] = 15; // unknown command code
    let back = bus.net.transact(&f, bus.t).unwrap().returned().unwrap();
    assert_eq!(&back.frame[16..30], &f[16..30]);
}

/// REQ-ESC-004/REQ-ESC-001: the first slave sets 0x02 in the source MAC; frames shorter than
/// 60 bytes are processed and come back at the same length.
// verifies: REQ-ESC-001, REQ-ESC-004
#[test]
fn mac_bit_and_short_frames() {
    let (mut net, t) = net3();
    let mut f = frame(&[(Command::Brd, Address::broadcast(0x0000), &[0])]);
    assert_eq!(f[6] & 0x02, 0);
    f.truncate(14 + 2 + 12 + 1); // unpadded: 29 bytes
    let back = net.transact(&f, t).unwrap().returned().unwrap();
    assert_eq!(back.frame.len(), 29);
    assert_eq!(back.frame[6] & 0x02, 0x02);
    let wkc = u16::from_le_bytes([back.frame[27], back.frame[28]]);
    assert_eq!(wkc, 3);
    assert!(back.unprocessed.is_none());
}

/// Non-EtherCAT frames are forwarded unprocessed with the chain's delay.
#[test]
fn foreign_frames_forwarded() {
    let (mut net, t) = net3();
    let mut f = vec![0u8; 60];
    f[12] = 0x08;
    let back = net.transact(&f, t).unwrap().returned().unwrap();
    assert_eq!(back.frame, f);
    assert!(back.unprocessed.is_some());
    assert!(back.arrival > t);
}

/// REQ-ESC-005: a frame caught behind a link that breaks while it is downstream circulates
/// once (circulating bit set by the slave whose port 0 closed) and is then destroyed.
// verifies: REQ-ESC-005
#[test]
fn circulating_frame_destroyed() {
    let mut net = Network::new(&Scenario::line(4).ideal()).unwrap();
    let epu = net.epu_arrival_times(0);
    let t2 = epu[2].unwrap();
    // Break the cable into slave 2 after the frame passed it, before it comes back.
    net.schedule_fault(t2 + 100, Fault::LinkBreak { slave: 2, port: 0 })
        .unwrap();
    let f = frame(&[(Command::Brd, Address::broadcast(0x0000), &[0])]);
    assert_eq!(
        net.transact(&f, 0).unwrap(),
        Delivery::Lost(LossReason::Circulated)
    );
    // Afterwards slave 1 loops port 1 back: only slaves 0 and 1 answer.
    let r = Bus::new((net, 1_000_000)).read(Command::Brd, Address::broadcast(0x0000), 1);
    assert_eq!(r.wkc, 2);
    assert!(!r.circulating);
}
