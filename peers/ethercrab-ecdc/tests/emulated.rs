//! The whole embedding without root or sockets: ethercrab and ecdc through one `TxRx` loop
//! against the ESC emulator in this process, in real time (true time = monotonic time since
//! the link was made). Checks what the emulator saw: every slave fires SYNC0 and the pulses
//! of each cycle coincide across slaves, and ecdc used the addresses ethercrab assigned.

use std::collections::{BTreeMap, VecDeque};
use std::io;
use std::sync::atomic::AtomicBool;

use ecdc_harness::emu::{Delivery, Network, Scenario, SyncSignal};
use ecdc_harness::runtime::clock;
use ecdc_harness::runtime::socket::Link;
use ethercrab::PduStorage;
use ethercrab_ecdc::{run, Options};

static PDU_STORAGE: PduStorage<32, { PduStorage::element_size(1100) }> = PduStorage::new();

/// The emulated chain behind an in-memory link: a sent frame goes through the network at once
/// (at the current true time) and its reply is handed out when its last bit would arrive.
struct EmuLink {
    net: Network,
    start: u64,
    queue: VecDeque<(u64, Vec<u8>)>,
}

impl Link for EmuLink {
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        let t = clock::now_ns()
            .saturating_sub(self.start)
            .max(self.net.now());
        match self.net.transact(frame, t) {
            Ok(Delivery::Returned(r)) => self.queue.push_back((self.start + r.arrival, r.frame)),
            Ok(Delivery::Lost(_)) => {}
            Err(e) => return Err(io::Error::other(format!("{e:?}"))),
        }
        Ok(())
    }

    fn recv(&mut self, buf: &mut [u8], deadline_ns: u64) -> io::Result<Option<usize>> {
        let stop = AtomicBool::new(false);
        match self.queue.front() {
            Some((at, _)) if *at <= deadline_ns => {
                clock::sleep_until(*at, 0, &stop);
                let Some((_, f)) = self.queue.pop_front() else {
                    return Ok(None);
                };
                let n = f.len().min(buf.len());
                buf[..n].copy_from_slice(&f[..n]);
                Ok(Some(f.len()))
            }
            _ => {
                clock::sleep_until(deadline_ns, 0, &stop);
                Ok(None)
            }
        }
    }
}

#[test]
fn ethercrab_configures_ecdc_synchronises() {
    let slaves = 3;
    let link = EmuLink {
        net: Network::new(&Scenario::line(slaves)).expect("scenario"),
        start: clock::now_ns(),
        queue: VecDeque::new(),
    };
    let (tx, rx, pdu_loop) = PDU_STORAGE.try_split().expect("split once");
    let opts = Options {
        seconds: 1.0,
        ..Options::default()
    };
    let (r, mut link) = run(link, tx, rx, pdu_loop, &opts).expect("run");
    let s = &r.status;
    eprintln!("{r:#?}");
    assert_eq!(r.subdevices, slaves);
    // ethercrab's addresses (0x1000 + position), adopted, not ecdc's default 0x1001 + position.
    assert_eq!(s.stations, [0x1000, 0x1001, 0x1002]);
    for pos in 0..slaves {
        let reg = link.net.peek(pos, 0x0010, 2).expect("peek");
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

    // The emulator's true SYNC0 edges: group by the programmed system time (one pulse of
    // the common grid), keep the pulses every slave fired, and take the spread of each.
    let mut pulses: BTreeMap<u64, Vec<u64>> = BTreeMap::new();
    for e in link.net.take_sync_edges() {
        if e.signal == SyncSignal::Sync0 {
            pulses.entry(e.system_time).or_default().push(e.true_time);
        }
    }
    let spreads: Vec<u64> = pulses
        .values()
        .filter(|t| t.len() == slaves)
        .map(|t| t.iter().max().unwrap() - t.iter().min().unwrap())
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
