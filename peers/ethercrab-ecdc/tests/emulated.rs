//! The whole embedding without root or sockets: ethercrab and ecdc through one `TxRx` loop
//! against the ESC emulator in this process, in real time (true time = monotonic time since
//! the link was made). Checks what the emulator saw: every slave fires SYNC0 and the pulses
//! of each cycle coincide across slaves, and ecdc used the addresses ethercrab assigned.

mod support;

use ecdc_harness::emu::Scenario;
use support::{run_for, sync0_spreads, EmuLink};

#[test]
fn ethercrab_configures_ecdc_synchronises() {
    let slaves = 3;
    let link = EmuLink::new(&Scenario::line(slaves));
    let (r, mut link) = run_for(link, 1.0);
    let s = &r.status;
    eprintln!("{r:#?}");
    assert_eq!(r.subdevices, slaves);
    // ethercrab's addresses (0x1000 + position), adopted, not ecdc's default 0x1001 + position.
    assert_eq!(s.stations, [0x1000, 0x1001, 0x1002]);
    for pos in 0..slaves {
        let reg = link.emu.net.peek(pos, 0x0010, 2).expect("peek");
        assert_eq!(u16::from_le_bytes([reg[0], reg[1]]), 0x1000 + pos as u16);
    }
    assert!(s.locked, "ecdc not locked at the end");
    assert_eq!((s.faults, s.restarts), (0, 0), "{:?}", s.events);
    assert!(r.cycles > 500, "{} cycles in 1 s", r.cycles);
    assert_eq!(r.wkc_changes, 0);
    let c = s.counters;
    assert!(c.crab_sent > 500 && c.ecdc_sent > 500, "{c:?}");
    assert_eq!(c.crab_refused, 0, "{c:?}");
    assert_eq!(c.crab_received, c.crab_sent, "{c:?}");

    let spreads: Vec<u64> = sync0_spreads(&mut link.emu.net, slaves)
        .into_iter()
        .map(|(_, s)| s)
        .collect();
    // 1 s of OP at 1 ms, plus the lock wait and the OP transition.
    assert!(spreads.len() > 900, "{} pulses fired by all", spreads.len());
    let worst = *spreads.iter().max().unwrap();
    eprintln!("pulses {} worst spread {worst} ns", spreads.len());
    // The emulator's SYNC output jitter and 10 ns clock ticks, on locked clocks: well under
    // the 100 ns the DC machine's lock gate certifies (REQ-DC-106's threshold is 200 ns
    // on a bitwise bound, the drift gate 100 ns).
    assert!(worst < 200, "worst SYNC0 spread {worst} ns");
}
