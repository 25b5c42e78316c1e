//! Frame-path timing: processing order, t_P ≠ t_F, cable delays, non-DC slaves, 32-bit port
//! time wrap (REQ-ESC-080..REQ-ESC-083, REQ-ESC-094).
//!
//! verifies: REQ-ESC-080, REQ-ESC-081, REQ-ESC-082, REQ-ESC-083, REQ-ESC-094

mod emu_support;

use ecdc_core::wire::{Address, Command};
use ecdc_harness::emu::{EscKind, Fault, Network, PpmSpec, Scenario, SlaveSpec};
use emu_support::*;

/// Exact stamps: no jitter, no drift, 1 ns observation quantum.
fn exact(mut sc: Scenario) -> Scenario {
    sc = sc.ideal();
    sc.timing.tick_ns = 1;
    sc.defaults.ppm = PpmSpec::Fixed(0.0);
    sc
}

fn latch_and_read(net: &mut Network, t: u64, station: u16) -> [u32; 4] {
    let (_, ret) = send(
        net,
        t,
        &[(Command::Bwr, Address::broadcast(0x0900), &[0; 4])],
    );
    let (r, _) = fprd_at(net, ret.arrival + 1000, station, 0x0900, 16);
    [0, 4, 8, 12].map(|o| u32_of(&r.data[o..]))
}

/// REQ-ESC-081/082: a cross (4-port) slave stamps ports in the order 0 → 3 → 1 → 2 with the
/// configured t_P, t_F and cable delays, exactly when jitter is off.
// verifies: REQ-ESC-081
#[test]
fn cross_topology_stamps_reproduce_delays() {
    let sc = exact(Scenario::default())
        .with_slave(SlaveSpec {
            ports: Some(4),
            ..SlaveSpec::default()
        })
        .with_slave(SlaveSpec {
            parent: Some(0),
            port: Some(3),
            cable_m: Some(10.0),
            t_p_ns: Some(600),
            ..SlaveSpec::default()
        })
        .with_slave(SlaveSpec {
            parent: Some(0),
            port: Some(1),
            cable_m: Some(2.0),
            ..SlaveSpec::default()
        })
        .with_slave(SlaveSpec {
            parent: Some(0),
            port: Some(2),
            cable_m: Some(30.0),
            ..SlaveSpec::default()
        });
    let (mut net, t) = addressed(&sc);
    let p = latch_and_read(&mut net, t, 0x1000);
    // t_P = 540, t_F = 460; cables 50/10/150 ns; end slaves return after their t_P.
    assert_eq!(p[3].wrapping_sub(p[0]), 540 + 50 + 600 + 50);
    assert_eq!(p[1].wrapping_sub(p[3]), 460 + 10 + 540 + 10);
    assert_eq!(p[2].wrapping_sub(p[1]), 460 + 150 + 540 + 150);
}

/// REQ-ESC-082: in a line, port 1 − port 0 of each slave is the round trip behind it, and
/// t_P ≠ t_F shows up in the differences (the master's t_Diff).
// verifies: REQ-ESC-082
#[test]
fn line_round_trips() {
    let mut sc = exact(Scenario::line(3));
    sc.defaults.t_p_ns = 500;
    sc.defaults.t_f_ns = 300;
    sc.defaults.cable_m = 4.0; // 20 ns
    let (mut net, t) = addressed(&sc);
    let p0 = latch_and_read(&mut net, t, 0x1000);
    let p1 = latch_and_read(&mut net, t + 1_000_000, 0x1001);
    let p2 = latch_and_read(&mut net, t + 2_000_000, 0x1002);
    let rt = |p: [u32; 4]| p[1].wrapping_sub(p[0]);
    assert_eq!(p2[1], 0, "last slave: port 1 closed, never stamped");
    assert_eq!(rt(p1), 500 + 20 + 500 + 20);
    assert_eq!(rt(p0), 500 + 20 + (500 + 20 + 500 + 20 + 300) + 20);
}

/// The frame comes back after the whole path plus its own length on the wire; a 2-port
/// slave without DC only adds delay.
#[test]
fn return_time_and_non_dc_delay() {
    let mut sc = exact(Scenario::default());
    sc.timing.master_cable_m = 0.0;
    sc = sc
        .with_slave(SlaveSpec::default())
        .with_slave(SlaveSpec {
            kind: Some(EscKind::NoDc),
            ..SlaveSpec::default()
        })
        .with_slave(SlaveSpec::default());
    let mut net = Network::new(&sc).unwrap();
    let f = frame(&[(Command::Brd, Address::broadcast(0x0000), &[0; 2])]);
    let r = net.transact(&f, 1_000).unwrap().returned().unwrap();
    // Three slaves: two with t_P + t_F, the last with t_P; cables 5 ns each way between slaves.
    let path = (540 + 460) * 2 + 540 + 4 * 5;
    assert_eq!(r.first_bit, 1_000 + path);
    assert_eq!(r.arrival, r.first_bit + (8 + 60 + 4) * 80);
    // The NoDc slave is not stamped, and its delay appears in slave 0's round trip.
    let t = address_all(&mut net, 100_000);
    let p = latch_and_read(&mut net, t, 0x1000);
    // Slave 0's round trip is the whole path minus its own final t_F towards the master.
    assert_eq!(p[1].wrapping_sub(p[0]), (path - 460) as u32);
}

/// REQ-ESC-094: a 32-bit port-time wrap in the middle of a delay measurement — the stamps
/// wrap, and the wrapping difference still gives the configured round trip.
// verifies: REQ-ESC-094
#[test]
fn port_time_wrap_during_measurement() {
    let wrap_at = 50_000_000;
    let sc = exact(Scenario::line(2)).with_fault(wrap_at, Fault::PortTimeWrap { slave: None });
    let (mut net, _) = addressed(&sc);
    // Slave 0's port 0 is stamped ≈ 500 ns before the wrap, its port 1 ≈ 590 ns after.
    let p = latch_and_read(&mut net, wrap_at - 505, 0x1000);
    assert!(p[0] > 0xFFFF_F000, "{:#x}", p[0]);
    assert!(p[1] < 0x1000, "{:#x}", p[1]);
    assert_eq!(p[1].wrapping_sub(p[0]), 540 + 5 + 540 + 5);
}

/// PHY jitter is small and bounded: stamps vary by at most 2 × phy_jitter per round trip
/// plus the 10 ns quantisation.
#[test]
fn jitter_is_bounded() {
    let mut sc = Scenario::line(2);
    sc.defaults.ppm = PpmSpec::Fixed(0.0);
    sc.timing.wander_interval_ns = 0;
    let (mut net, _) = addressed(&sc);
    let mut seen = std::collections::BTreeSet::new();
    for k in 1..50u64 {
        let p = latch_and_read(&mut net, k * 1_000_000, 0x1000);
        let rt = i64::from(p[1].wrapping_sub(p[0]));
        assert!((rt - 1090).abs() <= 2 * 8 + 10, "{rt}");
        seen.insert(rt);
    }
    assert!(seen.len() > 1, "jitter on by default");
}

/// Closed ports (docs/emulator.md): with every port open a frame leaves the middle slave's
/// port 0 after t_P + round trip behind port 1 + t_F; with port 1 forced closed through DL
/// control 0x0101 (loop bits 0b11) it leaves after t_P, as from a line end, plus
/// `forced_loop_ns` of the scenario (0 by default).
#[test]
fn forced_closed_port_turns_round_like_a_line_end() {
    use ecdc_harness::emu::Network;
    for extra in [0u64, 25] {
        let mut sc = Scenario::line(3).ideal();
        sc.defaults.forced_loop_ns = extra;
        let mut net = Network::new(&sc).unwrap();
        // Close slave 1's port 1 (APWR to auto-increment position 1).
        let mut buf = [0u8; 64];
        let mut b = ecdc_core::wire::FrameBuilder::new(&mut buf).unwrap();
        b.push(
            ecdc_core::wire::Command::Apwr,
            0x01,
            ecdc_core::wire::Address::position(1, 0x0101),
            &[0b0000_1100],
        )
        .unwrap();
        let n = b.finish().unwrap();
        let rt = |net: &mut Network, t: u64| {
            let mut buf = [0u8; 64];
            let mut b = ecdc_core::wire::FrameBuilder::new(&mut buf).unwrap();
            b.push_zeroed(
                ecdc_core::wire::Command::Brd,
                0x02,
                ecdc_core::wire::Address::broadcast(0x0000),
                2,
            )
            .unwrap();
            let n = b.finish().unwrap();
            match net.transact(&buf[..n], t).unwrap() {
                ecdc_harness::emu::Delivery::Returned(r) => r.arrival - t,
                other => panic!("{other:?}"),
            }
        };
        let t_open = rt(&mut net, 1_000);
        net.transact(&buf[..n], 2_000).unwrap();
        let t_closed = rt(&mut net, 2_000_000);
        // Slave 2 is cut off: its t_P, slave 1's t_F and two 1 m cables (5 ns each) are gone;
        // slave 1's forced loop adds `extra`.
        let d = &sc.defaults;
        assert_eq!(t_open - t_closed, d.t_p_ns + d.t_f_ns + 10 - extra);
        let mut sc2 = Scenario::line(2).ideal();
        sc2.defaults.forced_loop_ns = extra;
        let mut net2 = Network::new(&sc2).unwrap();
        let t_end = rt(&mut net2, 2_000_000);
        assert_eq!(t_closed, t_end + extra, "forced loop {extra} ns");
    }
}
