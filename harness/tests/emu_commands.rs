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

/// REQ-ESC-002: APRD acts at ADP 0, every slave increments ADP.
// verifies: REQ-ESC-002
#[test]
fn aprd_auto_increment() {
    let (mut net, t) = net3();
    let (r, _) = aprd_at(&mut net, t, 1, 0x0010, 2);
    assert_eq!(r.wkc, 1);
    assert_eq!(u16_of(&r.data), 0x1001);
    // Sent 0xFFFF, passed 3 slaves.
    assert_eq!(r.adp, 0xFFFFu16.wrapping_add(3));
    // Position beyond the chain: nobody answers.
    let (r, _) = aprd_at(&mut net, t + 100_000, 5, 0x0010, 2);
    assert_eq!(r.wkc, 0);
    assert_eq!(r.data, vec![0, 0]);
}

/// REQ-ESC-002: APWR writes only the addressed slave; APRW returns the old value, WKC 3.
// verifies: REQ-ESC-002
#[test]
fn apwr_aprw() {
    let (mut net, t) = net3();
    let (r, _) = apwr_at(&mut net, t, 2, 0x1000, &[0xAB]);
    assert_eq!(r.wkc, 1);
    assert_eq!(net.peek(2, 0x1000, 1).unwrap(), vec![0xAB]);
    assert_eq!(net.peek(1, 0x1000, 1).unwrap(), vec![0x00]);
    let (r, _) = one(
        &mut net,
        t + 100_000,
        Command::Aprw,
        Address::position(2, 0x1000),
        &[0xCD],
    );
    assert_eq!(r.wkc, 3);
    assert_eq!(r.data, vec![0xAB]);
    assert_eq!(net.peek(2, 0x1000, 1).unwrap(), vec![0xCD]);
}

/// REQ-ESC-002: FPxx match the configured address, ADP is left untouched.
// verifies: REQ-ESC-002
#[test]
fn configured_address_commands() {
    let (mut net, t) = net3();
    let (r, _) = fprd_at(&mut net, t, 0x1002, 0x0010, 2);
    assert_eq!((r.wkc, u16_of(&r.data), r.adp), (1, 0x1002, 0x1002));
    let (r, _) = fpwr_at(&mut net, t + 100_000, 0x1001, 0x1004, &[7]);
    assert_eq!(r.wkc, 1);
    assert_eq!(net.peek(1, 0x1004, 1).unwrap(), vec![7]);
    let (r, _) = one(
        &mut net,
        t + 200_000,
        Command::Fprw,
        Address::configured(0x1001, 0x1004),
        &[9],
    );
    assert_eq!((r.wkc, r.data.clone()), (3, vec![7]));
    let (r, _) = fprd_at(&mut net, t + 300_000, 0x7777, 0x0010, 2);
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
    let mut net = Network::new(&sc).unwrap();
    let (r, t) = one(
        &mut net,
        0,
        Command::Fprd,
        Address::configured(0x0ABC, 0x0000),
        &[0],
    );
    assert_eq!(r.wkc, 0);
    let (r, t) = fpwr_at(&mut net, t + 1000, 0, 0x0103, &[1]);
    assert_eq!(r.wkc, 1);
    let (r, _) = one(
        &mut net,
        t + 1000,
        Command::Fprd,
        Address::configured(0x0ABC, 0x0000),
        &[0],
    );
    assert_eq!((r.wkc, r.data[0]), (1, 0x11));
}

/// REQ-ESC-002: BRD ORs every slave's memory into the data; BWR/BRW count every slave.
// verifies: REQ-ESC-002
#[test]
fn broadcast_commands() {
    let (mut net, mut t) = net3();
    for (i, v) in [0x01u8, 0x02, 0x10].iter().enumerate() {
        let (r, a) = fpwr_at(&mut net, t, 0x1000 + i as u16, 0x1010, &[*v]);
        assert_eq!(r.wkc, 1);
        t = a + 1000;
    }
    let (r, a) = one(
        &mut net,
        t,
        Command::Brd,
        Address::broadcast(0x1010),
        &[0x80],
    );
    assert_eq!((r.wkc, r.data[0], r.adp), (3, 0x93, 3));
    let (r, a) = one(
        &mut net,
        a + 1000,
        Command::Bwr,
        Address::broadcast(0x1011),
        &[0x44],
    );
    assert_eq!((r.wkc, r.adp), (3, 3));
    for i in 0..3 {
        assert_eq!(net.peek(i, 0x1011, 1).unwrap(), vec![0x44]);
    }
    let (r, _) = one(
        &mut net,
        a + 1000,
        Command::Brw,
        Address::broadcast(0x1010),
        &[0x20],
    );
    assert_eq!((r.wkc, r.data[0]), (9, 0x33));
    // BRW: each slave writes the data as it arrives (already ORed by the slaves before it).
    for (i, v) in [0x20u8, 0x21, 0x23].iter().enumerate() {
        assert_eq!(net.peek(i, 0x1010, 1).unwrap(), vec![*v]);
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
    let (mut net, t) = net3();
    // Slave 0: logical 0x10000..0x10004 written to 0x1100. Slave 1: same range read from 0x1200.
    let (r, a) = fpwr_at(&mut net, t, 0x1000, 0x0600, &fmmu(0x10000, 4, 0x1100, 2));
    assert_eq!(r.wkc, 1);
    let (r, a) = fpwr_at(
        &mut net,
        a + 1000,
        0x1001,
        0x0600,
        &fmmu(0x10000, 4, 0x1200, 1),
    );
    assert_eq!(r.wkc, 1);
    let (r, a) = fpwr_at(&mut net, a + 1000, 0x1001, 0x1200, &[1, 2, 3, 4]);
    assert_eq!(r.wkc, 1);
    let (r, a) = one(
        &mut net,
        a + 1000,
        Command::Lrw,
        Address::Logical(0x10000),
        &[9, 9, 9, 9],
    );
    assert_eq!(r.wkc, 3);
    assert_eq!(r.data, vec![1, 2, 3, 4]);
    assert_eq!(net.peek(0, 0x1100, 4).unwrap(), vec![9, 9, 9, 9]);
    let (r, a) = read(
        &mut net,
        a + 1000,
        Command::Lrd,
        Address::Logical(0x0FFFE),
        4,
    );
    assert_eq!((r.wkc, r.data.clone()), (1, vec![0, 0, 1, 2]));
    let (r, a) = one(
        &mut net,
        a + 1000,
        Command::Lwr,
        Address::Logical(0x10002),
        &[5, 5, 5, 5],
    );
    assert_eq!(r.wkc, 1);
    assert_eq!(net.peek(0, 0x1100, 4).unwrap(), vec![9, 9, 5, 5]);
    let (r, _) = read(
        &mut net,
        a + 1000,
        Command::Lrd,
        Address::Logical(0x20000),
        4,
    );
    assert_eq!(r.wkc, 0);
}

/// REQ-ESC-006: ARMW/FRMW — the addressed slave reads, every other slave (before and after it
/// in the path) writes; each counts 1.
// verifies: REQ-ESC-006
#[test]
fn read_multiple_write() {
    let (mut net, t) = net3();
    let (r, a) = read(&mut net, t, Command::Armw, Address::position(1, 0x0910), 8);
    assert_eq!(r.wkc, 3);
    assert_eq!(r.adp, 0xFFFFu16.wrapping_add(3));
    let sys1 = u64_of(&r.data);
    assert!(sys1 > 0);
    // Loop samples are applied at the end of the frame at each slave.
    net.advance_to(a).unwrap();
    // Slaves 0 and 2 took a sample: their 0x092C is no longer the reset value 0.
    assert_ne!(u32_of(&net.peek(0, 0x092C, 4).unwrap()), 0);
    assert_ne!(u32_of(&net.peek(2, 0x092C, 4).unwrap()), 0);
    assert_eq!(u32_of(&net.peek(1, 0x092C, 4).unwrap()), 0);
    let (r, _) = read(
        &mut net,
        a + 1000,
        Command::Frmw,
        Address::configured(0x1001, 0x0910),
        8,
    );
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
    let (mut net, t) = addressed(&sc);
    let (r, a) = read(
        &mut net,
        t,
        Command::Frmw,
        Address::configured(0x1000, 0x0910),
        8,
    );
    assert_eq!(r.wkc, 2);
    // IgH's "has system time" probe: FPRD 0x0910 answers only with system time.
    let (r, a) = fprd_at(&mut net, a + 1000, 0x1002, 0x0910, 8);
    assert_eq!(r.wkc, 0);
    let (r, a) = fprd_at(&mut net, a + 1000, 0x1002, 0x0900, 4);
    assert_eq!(r.wkc, 1);
    let (r, _) = one(
        &mut net,
        a + 1000,
        Command::Bwr,
        Address::broadcast(0x0900),
        &[0; 4],
    );
    assert_eq!(r.wkc, 3);
}

/// NOP and unknown command codes pass untouched.
#[test]
fn nop_and_unknown() {
    let (mut net, t) = net3();
    let (r, a) = one(
        &mut net,
        t,
        Command::Nop,
        Address::Raw(0x0010_0000),
        &[1, 2],
    );
    assert_eq!((r.wkc, r.adp, r.data.clone()), (0, 0, vec![1, 2]));
    let mut f = frame(&[(Command::Aprd, Address::position(0, 0x10), &[0, 0])]);
    f[16] = 15; // unknown command code
    let back = net.transact(&f, a + 1000).unwrap().returned().unwrap();
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
    let (r, _) = one(
        &mut net,
        1_000_000,
        Command::Brd,
        Address::broadcast(0x0000),
        &[0],
    );
    assert_eq!(r.wkc, 2);
    assert!(!r.circulating);
}
