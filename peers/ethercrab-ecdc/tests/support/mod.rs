//! The in-process emulator link of the tests and the SYNC0 spread they judge by.
#![allow(dead_code)]

use std::collections::{BTreeMap, VecDeque};
use std::io;
use std::sync::atomic::AtomicBool;

use ecdc_harness::emu::{Delivery, Network, Scenario, SyncSignal};
use ecdc_harness::runtime::clock;
use ecdc_harness::runtime::socket::Link;
use ethercrab::PduStorage;
use ethercrab_ecdc::{route, run, Options, Report, Route};

static PDU_STORAGE: PduStorage<32, { PduStorage::element_size(1100) }> = PduStorage::new();

/// Runs ethercrab and ecdc on `link` for `seconds` with the default options; returns the
/// report and the link. Once per test binary: the PDU storage splits only once.
pub fn run_for(link: EmuLink, seconds: f64) -> (Report, EmuLink) {
    let (tx, rx, pdu_loop) = PDU_STORAGE.try_split().expect("split once");
    let opts = Options {
        seconds,
        ..Options::default()
    };
    run(link, tx, rx, pdu_loop, &opts).expect("run")
}

/// The emulated chain behind an in-memory link: a sent frame goes through the network at once
/// (at the current true time) and its reply is handed out when its last bit would arrive.
pub struct EmuLink {
    pub net: Network,
    start: u64,
    queue: VecDeque<(u64, Vec<u8>)>,
    /// Drop ecdc's frames for this long (ns), starting this long (ns) after every slave is
    /// in OP (AL status 0x0130 = 8 in the emulator): the loss a host stall of the DC side
    /// looks like.
    pub drop_ecdc: Option<(u64, u64)>,
    all_op: Option<u64>,
    /// ecdc frames dropped.
    pub dropped: u64,
}

impl EmuLink {
    pub fn new(sc: &Scenario) -> Self {
        EmuLink {
            net: Network::new(sc).expect("scenario"),
            start: clock::now_ns(),
            queue: VecDeque::new(),
            drop_ecdc: None,
            all_op: None,
            dropped: 0,
        }
    }

    fn dropping(&mut self, frame: &[u8], t: u64) -> bool {
        if self.all_op.is_none() {
            let n = self.net.slave_count();
            let op = (0..n).all(|i| {
                self.net
                    .peek(i, 0x0130, 1)
                    .is_ok_and(|v| v.first().is_some_and(|s| s & 0x1F == 8))
            });
            if op {
                self.all_op = Some(t);
            }
        }
        if route(frame) != Route::Ecdc {
            return false;
        }
        match (self.drop_ecdc, self.all_op) {
            (Some((after, len)), Some(op)) => {
                let from = op + after;
                t >= from && t < from + len
            }
            _ => false,
        }
    }
}

impl Link for EmuLink {
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        let t = clock::now_ns()
            .saturating_sub(self.start)
            .max(self.net.now());
        if self.dropping(frame, t) {
            self.dropped += 1;
            return Ok(());
        }
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

/// SYNC0 edges since the last call grouped by programmed system time (one pulse of the common
/// grid); for each pulse every one of `slaves` fired: (true time of its first edge, spread
/// between its first and last edge), in pulse order.
pub fn sync0_spreads(net: &mut Network, slaves: usize) -> Vec<(u64, u64)> {
    let mut pulses: BTreeMap<u64, Vec<u64>> = BTreeMap::new();
    for e in net.take_sync_edges() {
        if e.signal == SyncSignal::Sync0 {
            pulses.entry(e.system_time).or_default().push(e.true_time);
        }
    }
    pulses
        .values()
        .filter(|t| t.len() == slaves)
        .map(|t| {
            let lo = *t.iter().min().unwrap();
            (lo, t.iter().max().unwrap() - lo)
        })
        .collect()
}
