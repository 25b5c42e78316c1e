//! End-to-end REQ-DC-140: a host master addressed the slaves with its own scheme; the machine
//! in `Stations::Adopt` locks on the emulator using those addresses and leaves 0x0010 alone.

mod dc_support;

use dc_support::*;
use ecdc_core::dc::{Event, Machine, State, Stations};
use ecdc_core::wire::{Address, Command, FrameBuilder};
use ecdc_harness::emu::{Network, Scenario};
use ecdc_harness::sim::Sim;

/// The host's addresses: not ecdc's `station_base + position`, and not consecutive.
fn host_station(pos: u16) -> u16 {
    0x2000 + 3 * pos
}

#[test]
fn adopted_addresses_are_used_and_kept() {
    // verifies: REQ-DC-140
    let sc = Scenario::line(4);
    let mut net = Network::new(&sc).expect("scenario");
    // The host's addressing, one APWR 0x0010 per position, before the machine starts.
    let mut buf = [0u8; 128];
    let mut b = FrameBuilder::new(&mut buf).unwrap();
    for pos in 0..4u16 {
        b.push(
            Command::Apwr,
            u8::try_from(pos).unwrap(),
            Address::position(pos, 0x0010),
            &host_station(pos).to_le_bytes(),
        )
        .unwrap();
    }
    let n = b.finish().unwrap();
    let t = net.now();
    assert!(net.transact(&buf[..n], t).unwrap().returned().is_some());

    let cfg = ecdc_core::dc::Config {
        stations: Stations::Adopt,
        ..config()
    };
    let m: Machine<8> = Machine::new(cfg).expect("config");
    let mut s = Sim::new(m, net);
    s.start();
    let _ = lock(&mut s, 2_000_000_000);
    assert_eq!(s.machine.state(), State::Cyclic);
    let stations: Vec<u16> = s.machine.slaves().iter().map(|x| x.station).collect();
    assert_eq!(stations, [0x2000, 0x2003, 0x2006, 0x2009]);
    for pos in 0..4u16 {
        let reg = s.net.peek(usize::from(pos), 0x0010, 2).unwrap();
        assert_eq!(
            u16::from_le_bytes([reg[0], reg[1]]),
            host_station(pos),
            "0x0010 of position {pos}"
        );
    }
    let st = steady(&mut s, 500_000_000, &[ecdc_harness::emu::EscKind::Dc64; 4]);
    assert!(st.max_true_err < 100, "{st:?}");
    assert!(!s.events().iter().any(|(_, e)| matches!(e, Event::Error(_))));
}

/// Unaddressed slaves (0x0010 still at its reset value 0) are refused, not silently addressed.
#[test]
fn adopt_without_host_addresses_faults() {
    // verifies: REQ-DC-140
    let cfg = ecdc_core::dc::Config {
        stations: Stations::Adopt,
        auto_restart: false,
        ..config()
    };
    let mut s = sim::<8>(&Scenario::line(2), cfg);
    let r = s.drive_until(100_000_000, |e| matches!(e, Event::Error(_)));
    assert!(
        matches!(
            r,
            Ok(Event::Error(ecdc_core::dc::Error::OutOfRange {
                station: 0,
                register: 0x0010
            }))
        ),
        "{r:?}"
    );
}
