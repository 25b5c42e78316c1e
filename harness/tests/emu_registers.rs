//! Register contract: reset values, access rules, widths, AL and DL status, receive-time latch
//! rules (REQ-ESC-010..REQ-ESC-032, REQ-ESC-061).
//!
//! verifies: REQ-ESC-010, REQ-ESC-011, REQ-ESC-012, REQ-ESC-013, REQ-ESC-014, REQ-ESC-015, REQ-ESC-020, REQ-ESC-021, REQ-ESC-022, REQ-ESC-023, REQ-ESC-024, REQ-ESC-025, REQ-ESC-026, REQ-ESC-027, REQ-ESC-030, REQ-ESC-031, REQ-ESC-032, REQ-ESC-061

mod emu_support;

use ecdc_core::wire::{Address, Command};
use ecdc_harness::emu::{EscKind, Fault, Network, PpmSpec, Scenario, SlaveSpec};
use emu_support::*;

fn kinds_net(kinds: &[EscKind]) -> (Network, u64) {
    let mut sc = Scenario::default().ideal();
    for k in kinds {
        sc = sc.with_slave(SlaveSpec {
            kind: Some(*k),
            ..SlaveSpec::default()
        });
    }
    addressed(&sc)
}

/// REQ-ESC-011/014: type, features per kind and DC reset values as the master reads them.
// verifies: REQ-ESC-011, REQ-ESC-060
#[test]
fn reset_values_per_kind() {
    let kinds = [
        EscKind::Dc64,
        EscKind::Dc32,
        EscKind::DcReceiveTimesOnly,
        EscKind::NoDc,
    ];
    let (mut net, mut t) = kinds_net(&kinds);
    let want_features = [0x01CCu16, 0x00C4, 0x00C4, 0x00C0];
    for (i, f) in want_features.iter().enumerate() {
        let st = 0x1000 + i as u16;
        let (r, a) = fprd_at(&mut net, t, st, 0x0000, 10);
        assert_eq!(u16_of(&r.data[8..]), *f, "slave {i}");
        let (r, a) = fprd_at(&mut net, a + 1000, st, 0x0130, 2);
        assert_eq!(u16_of(&r.data), 0x0001, "AL status INIT");
        t = a + 1000;
    }
    let (r, a) = fprd_at(&mut net, t, 0x1000, 0x092C, 10);
    assert_eq!(u32_of(&r.data), 0, "0x092C");
    assert_eq!(u16_of(&r.data[4..]), 0x1000, "0x0930");
    assert_eq!(u16_of(&r.data[6..]), 0, "0x0932");
    assert_eq!(r.data[8], 4, "0x0934");
    assert_eq!(r.data[9], 0x0C, "0x0935");
    let (r, _) = fprd_at(&mut net, a + 1000, 0x1000, 0x0980, 0x30);
    assert!(
        r.data.iter().enumerate().all(|(i, b)| *b == 0 || i == 2),
        "SYNC block resets to 0"
    );
    assert_eq!(u16_of(&r.data[2..]), 100, "pulse length from EEPROM");
}

/// REQ-ESC-013: read-only bytes ignore ECAT writes, yet the write counts in the WKC.
// verifies: REQ-ESC-013
#[test]
fn read_only_registers() {
    let (mut net, t) = kinds_net(&[EscKind::Dc64]);
    let (r, a) = fpwr_at(&mut net, t, 0x1000, 0x0000, &[0xFF; 2]);
    assert_eq!(r.wkc, 1);
    assert_eq!(net.peek(0, 0x0000, 1).unwrap(), vec![0x11]);
    let (r, a) = fpwr_at(&mut net, a + 1000, 0x1000, 0x092C, &[0xFF; 8]);
    assert_eq!(r.wkc, 1);
    net.advance_to(a).unwrap();
    assert_eq!(net.peek(0, 0x092C, 4).unwrap(), vec![0; 4]);
    assert_eq!(
        net.peek(0, 0x0930, 2).unwrap(),
        vec![0xFF, 0xFF],
        "0x0930 is writable"
    );
}

/// REQ-ESC-061: a 32-bit DC keeps only the low halves of 64-bit DC registers.
// verifies: REQ-ESC-061
#[test]
fn dc32_widths() {
    let (mut net, t) = kinds_net(&[EscKind::Dc32]);
    let v = 0x1122_3344_5566_7788u64.to_le_bytes();
    let (_, a) = fpwr_at(&mut net, t, 0x1000, 0x0920, &v);
    let (r, a) = fprd_at(&mut net, a + 1000, 0x1000, 0x0920, 8);
    assert_eq!(u64_of(&r.data), 0x5566_7788);
    let (r, _) = fprd_at(&mut net, a + 1000, 0x1000, 0x0910, 8);
    assert_eq!(u32_of(&r.data[4..]), 0, "upper half of 0x0910 reads 0");
}

/// REQ-ESC-020: valid AL requests are reflected in 0x0130; invalid ones set the error flag and
/// code 0x0011 until acknowledged.
// verifies: REQ-ESC-020
#[test]
fn al_state_machine() {
    let (mut net, t) = kinds_net(&[EscKind::Dc64]);
    let mut t = t;
    let mut req = |net: &mut Network, v: u16| {
        let (_, a) = fpwr_at(net, t, 0x1000, 0x0120, &v.to_le_bytes());
        let (r, a) = fprd_at(net, a + 1000, 0x1000, 0x0130, 6);
        t = a + 1000;
        (u16_of(&r.data), u16_of(&r.data[4..]))
    };
    assert_eq!(req(&mut net, 2), (0x02, 0));
    assert_eq!(req(&mut net, 8), (0x12, 0x0011), "PREOP -> OP is invalid");
    assert_eq!(req(&mut net, 0x14), (0x04, 0), "ack + SAFEOP");
    assert_eq!(req(&mut net, 8), (0x08, 0));
    assert_eq!(req(&mut net, 1), (0x01, 0));
    assert_eq!(req(&mut net, 7), (0x11, 0x0012), "unknown state");
}

/// REQ-ESC-015: DL status matches the topology (link, loop, communication per port).
// verifies: REQ-ESC-015
#[test]
fn dl_status_matches_topology() {
    let (mut net, t) = addressed(&Scenario::line(3).ideal());
    let (r, a) = fprd_at(&mut net, t, 0x1000, 0x0110, 2);
    assert_eq!(u16_of(&r.data), 0x5A31);
    let (r, a) = fprd_at(&mut net, a + 1000, 0x1002, 0x0110, 2);
    assert_eq!(u16_of(&r.data), 0x5611);
    net.schedule_fault(a + 500, Fault::LinkBreak { slave: 1, port: 1 })
        .unwrap();
    let (r, _) = fprd_at(&mut net, a + 1000, 0x1001, 0x0110, 2);
    assert_eq!(u16_of(&r.data), 0x5611, "port 1 lost link and closed");
}

/// REQ-ESC-030/031: BWR to 0x0900 latches every port; the new values are not visible in the
/// same frame; APWR does not latch; ports the frame does not reach keep their old values.
/// REQ-ESC-032: 0x0918 reads port 0's stamp.
// verifies: REQ-ESC-030, REQ-ESC-032
#[test]
fn receive_time_latch_rules() {
    let mut sc = Scenario::line(3).ideal();
    sc.defaults.ppm = PpmSpec::Fixed(0.0);
    let (mut net, t) = addressed(&sc);
    let (r, ret) = send(
        &mut net,
        t,
        &[
            (Command::Bwr, Address::broadcast(0x0900), &[0; 1]),
            (Command::Fprd, Address::configured(0x1001, 0x0900), &[0; 16]),
        ],
    );
    assert_eq!(r[0].wkc, 3);
    assert_eq!(r[1].data, vec![0; 16], "same frame sees the old values");
    let (x, a) = fprd_at(&mut net, ret.arrival + 1000, 0x1001, 0x0900, 32);
    let p0 = u32_of(&x.data);
    let p1 = u32_of(&x.data[4..]);
    assert_ne!(p0, 0);
    assert!(p1.wrapping_sub(p0) > 0 && p1.wrapping_sub(p0) < 10_000);
    assert_eq!(u32_of(&x.data[8..]), 0, "port 2 not present");
    assert_eq!(
        u64_of(&x.data[24..]),
        u64::from(p0),
        "0x0918 = port 0 stamp"
    );
    // APWR to 0x0900 does not latch.
    let (_, a) = apwr_at(&mut net, a + 1000, 1, 0x0900, &[0; 4]);
    let (y, a) = fprd_at(&mut net, a + 1000, 0x1001, 0x0900, 8);
    assert_eq!(y.data, x.data[..8].to_vec());
    // Break slave 1's port 1: the next latch updates port 0 only; port 1 keeps its value.
    net.schedule_fault(a + 100, Fault::LinkBreak { slave: 1, port: 1 })
        .unwrap();
    let t = bwr(&mut net, a + 1000, 0x0900, &[0; 4]);
    let (z, _) = fprd_at(&mut net, t, 0x1001, 0x0900, 8);
    assert_ne!(u32_of(&z.data), p0);
    assert_eq!(u32_of(&z.data[4..]), p1);
}
