//! The runtime's DC driving code (bring-up driver, cyclic DC task, master servo) against the
//! ESC emulator through an in-memory link in real time: what `ecdc scan` and `ecdc run` do,
//! without sockets or root. The netns test (scripts/netns-test.sh) repeats it over veth.

use std::io;
use std::sync::atomic::AtomicBool;

use ecdc_core::dc::{Config, DcKind, Event, Machine, State};
use ecdc_core::servo::master::{MasterConfig, MasterServo};
use ecdc_core::wire::MASTER_MAC;
use ecdc_harness::emu::{Network, Scenario};
use ecdc_harness::runtime::bringup::{self, BringupError, Limits, Outcome, Until};
use ecdc_harness::runtime::clock::{self, DcClock};
use ecdc_harness::runtime::cyclic::{self, CycleConfig};
use ecdc_harness::runtime::dc_task::DcTask;
use ecdc_harness::runtime::emu_link::EmuLink;
use ecdc_harness::runtime::errors::RuntimeError;
use ecdc_harness::runtime::socket::Link;
use ecdc_harness::runtime::transport::Transport;

/// The emulated chain behind an in-memory link; a reply's wait ends in a 200 µs spin, so it
/// arrives on time.
fn emu_link(sc: &Scenario) -> EmuLink {
    let mut link = EmuLink::new(Network::new(sc).unwrap());
    link.spin_ns = 200_000;
    link
}

type M = Machine<16>;

fn machine(cycle_ns: u64) -> Box<M> {
    let mut cfg = Config::default();
    cfg.monitor.cycle_ns = cycle_ns;
    if let Some(s) = cfg.sync.as_mut() {
        s.sync0_cycle_ns = cycle_ns as u32;
    }
    Box::new(Machine::new(cfg).unwrap())
}

/// `bringup::bring_up` on the host's clock with the default limits, never asked to stop,
/// events and progress ignored.
fn bring_up_quietly<L: Link>(
    m: &mut M,
    t: &mut Transport<L>,
    iface: &str,
    until: Until,
) -> Result<Outcome, BringupError> {
    bringup::bring_up(
        m,
        t,
        &DcClock::from_realtime(),
        iface,
        until,
        &Limits::default(),
        &AtomicBool::new(false),
        |_| {},
        |_| {},
    )
}

#[test]
fn scan_stops_after_delays_without_writing_offsets() {
    let mut t = Transport::new(emu_link(&Scenario::line(3)), MASTER_MAC);
    let mut m = machine(1_000_000);
    let stop = AtomicBool::new(false);
    let mut events = Vec::new();
    let out = bringup::bring_up(
        &mut m,
        &mut t,
        &DcClock::from_realtime(),
        "emu",
        Until::DelaysMeasured,
        &Limits::default(),
        &stop,
        |e| events.push(*e),
        |_| {},
    )
    .unwrap();
    assert_eq!(out, Outcome::Reached);
    assert!(
        matches!(events.first(), Some(Event::SlavesFound { count: 3, dc: 3 })),
        "{events:?}"
    );
    assert!(
        matches!(events.last(), Some(Event::DelaysMeasured { .. })),
        "{events:?}"
    );
    let s = m.slaves();
    assert_eq!(s.len(), 3);
    assert_eq!(m.reference(), Some(0));
    assert!(s.iter().all(|x| x.dc == DcKind::Bits64));
    assert_eq!(s[0].delay_ns, 0);
    assert!(
        s[0].delay_ns < s[1].delay_ns && s[1].delay_ns < s[2].delay_ns,
        "{s:?}"
    );
    assert!(
        s.iter().all(|x| !x.offset_written),
        "scan must not write offsets"
    );
    let c = t.counters();
    assert_eq!(c.sent, c.matched);
    assert_eq!(c.lost + c.stale + c.foreign + c.other_master, 0);
}

#[test]
fn run_brings_up_dc_and_locks_in_cyclic_operation() {
    let cycle = 1_000_000;
    let mut t = Transport::new(emu_link(&Scenario::line(3)), MASTER_MAC);
    let mut m = machine(cycle);
    let stop = AtomicBool::new(false);
    let dc = DcClock::from_realtime();
    let mut drift_converged = false;
    let out = bringup::bring_up(
        &mut m,
        &mut t,
        &dc,
        "emu",
        Until::Cyclic,
        &Limits::default(),
        &stop,
        |e| drift_converged |= matches!(e, Event::DriftConverged { .. }),
        |_| {},
    )
    .unwrap();
    assert_eq!(out, Outcome::Reached);
    assert!(drift_converged);
    assert_eq!(m.state(), State::Cyclic);
    assert!(m
        .slaves()
        .iter()
        .all(|s| s.offset_written && s.sync_programmed));

    let servo = MasterServo::new(MasterConfig::for_period(cycle as u32).unwrap()).unwrap();
    let mut events = Vec::new();
    let mut task = DcTask::new(&mut m, servo, dc, cycle, |_, e| events.push(*e));
    let mut cfg = CycleConfig::new(cycle);
    cfg.max_cycles = Some(400);
    let s = cyclic::run(&mut t, &mut task, &cfg, &stop, |_| {}).unwrap();
    assert_eq!(s.cycles, 400);
    assert!(
        !s.stopped_by_task,
        "the machine left cyclic operation: {events:?}"
    );
    assert_eq!(s.locked_at_end, Some(true), "{events:?}");
    assert!(events.iter().any(|e| matches!(e, Event::Locked { .. })));
    assert!(s.max_092c_ns.is_some());
    assert_eq!(s.wkc_errors, 0);
    let f = s.frames;
    assert_eq!(f.sent, f.matched + f.lost, "{f:?}");
    assert_eq!(
        f.foreign + f.other_master + f.own_unprocessed + f.mismatched,
        0
    );
    assert!(s.servo_rms_ns.is_some(), "the servo got samples");
}

#[test]
fn silent_wire_is_reported_as_no_slaves() {
    /// A link where nothing ever answers.
    struct Void;
    impl Link for Void {
        fn send(&mut self, _: &[u8]) -> io::Result<()> {
            Ok(())
        }
        fn recv(&mut self, _: &mut [u8], deadline_ns: u64) -> io::Result<Option<usize>> {
            clock::sleep_until(deadline_ns, 0, &AtomicBool::new(false));
            Ok(None)
        }
    }
    let mut t = Transport::new(Void, MASTER_MAC);
    let mut m = machine(1_000_000);
    let err = bring_up_quietly(&mut m, &mut t, "void0", Until::Cyclic).unwrap_err();
    match err {
        BringupError::Runtime(RuntimeError::NoSlaves { name, sent, .. }) => {
            assert_eq!(name, "void0");
            assert!(sent >= 5);
        }
        other => panic!("expected NoSlaves, got {other}"),
    }
}

#[test]
fn another_master_on_the_segment_is_an_error() {
    let mut link = emu_link(&Scenario::line(2));
    // A request from a master with SOEM's default MAC, as a switch would flood it to us.
    let mut other = vec![0xff; 6];
    other.extend_from_slice(&[0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x88, 0xa4]);
    other.extend_from_slice(&(14u16 | 0x1000).to_le_bytes());
    other.extend_from_slice(&[7, 0x42, 0, 0, 0x30, 0x01, 2, 0, 0, 0, 0, 0, 0, 0]);
    other.resize(60, 0);
    link.inject = Some(other);
    let mut t = Transport::new(link, MASTER_MAC);
    let mut m = machine(1_000_000);
    // Our replies do come back, but bringing DC up next to another master is refused.
    let r = bring_up_quietly(&mut m, &mut t, "emu", Until::DelaysMeasured);
    let c = t.counters();
    assert!(c.other_master > 0);
    assert_eq!(c.other_master_mac, Some([0x01; 6]));
    match r {
        Err(BringupError::Runtime(RuntimeError::OtherMaster { mac, .. })) => {
            assert_eq!(mac, [0x01; 6])
        }
        other => panic!("expected OtherMaster, got {other:?}"),
    }
}
