//! The in-process emulator link of the tests and the SYNC0 spread they judge by.
#![allow(dead_code)]

use std::collections::BTreeMap;
use std::io;

use ecdc_harness::emu::{Network, Scenario, SyncSignal};
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

/// The emulated chain behind the runtime's in-memory link, able to drop ecdc's frames for a
/// while.
pub struct EmuLink {
    pub emu: ecdc_harness::runtime::emu_link::EmuLink,
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
            emu: ecdc_harness::runtime::emu_link::EmuLink::new(Network::new(sc).expect("scenario")),
            drop_ecdc: None,
            all_op: None,
            dropped: 0,
        }
    }

    fn dropping(&mut self, frame: &[u8], t: u64) -> bool {
        if self.all_op.is_none() {
            let net = &self.emu.net;
            let op = (0..net.slave_count()).all(|i| {
                net.peek(i, 0x0130, 1)
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
        if self.dropping(frame, self.emu.true_now()) {
            self.dropped += 1;
            return Ok(());
        }
        self.emu.send(frame)
    }

    fn recv(&mut self, buf: &mut [u8], deadline_ns: u64) -> io::Result<Option<usize>> {
        self.emu.recv(buf, deadline_ns)
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
