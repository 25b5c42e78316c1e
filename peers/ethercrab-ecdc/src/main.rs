//! ethercrab for the slaves' configuration and process data, ecdc-core for Distributed
//! Clocks, one TX/RX loop on one raw socket ([`ethercrab_ecdc::run`]). Measures nothing
//! itself: run it against `ecdc emulate --json`, whose yardstick reports what the SYNC0
//! pulses did (scripts/peers-bench.sh, master "ethercrab+ecdc").
//!
//! Usage: ethercrab-ecdc IFACE [SECONDS] [CYCLE_US]   (defaults: 10 s, 1000 us)

#[path = "../../common/arg.rs"]
mod arg;
#[path = "../../common/logged_main.rs"]
mod logged_main;

use arg::arg;
use ecdc_harness::runtime::socket::{RawSocket, SocketOptions};
use ethercrab::PduStorage;
use ethercrab_ecdc::{run, Options};
use logged_main::logged_main;

const MAX_PDU_DATA: usize = PduStorage::element_size(1100);
const MAX_FRAMES: usize = 32;

static PDU_STORAGE: PduStorage<MAX_FRAMES, MAX_PDU_DATA> = PduStorage::new();

fn main() {
    logged_main("ethercrab-ecdc", "warn", main_inner);
}

fn main_inner() -> Result<(), String> {
    let iface: String = std::env::args()
        .nth(1)
        .ok_or("usage: ethercrab-ecdc IFACE [SECONDS] [CYCLE_US]")?;
    let opts = Options {
        seconds: arg(2, 10.0)?,
        cycle_us: arg(3, 1000)?,
        ..Options::default()
    };
    let link = RawSocket::open(&iface, &SocketOptions::default())
        .map_err(|e| format!("opening {iface}: {e}"))?;
    let (tx, rx, pdu_loop) = PDU_STORAGE
        .try_split()
        .map_err(|_| "PDU storage already split")?;
    let (r, _link) = run(link, tx, rx, pdu_loop, &opts)?;
    let s = &r.status;
    eprintln!(
        "ethercrab-ecdc: {} SubDevices after ethercrab init ({:.0} ms); ecdc locked {:.0} ms \
         after its start, stations {:04x?}; all in OP {:.0} ms after the request",
        r.subdevices, r.init_ms, r.dc_lock_ms, s.stations, r.op_ms
    );
    let c = s.counters;
    eprintln!(
        "ethercrab-ecdc: {} cycles, {} working-counter changes; ecdc {:?}, locked {}, {} faults, \
         {} restarts; frames ethercrab {} sent / {} received / {} refused, ecdc {} sent / {} \
         received, {} other, {} send errors",
        r.cycles,
        r.wkc_changes,
        s.state,
        s.locked,
        s.faults,
        s.restarts,
        c.crab_sent,
        c.crab_received,
        c.crab_refused,
        c.ecdc_sent,
        c.ecdc_received,
        c.other,
        c.send_errors
    );
    eprintln!(
        "ethercrab-ecdc: ecdc cycles {} lost {} timeouts {}; longest loop turn {} us",
        s.machine.cycles,
        s.machine.lost_cycles,
        s.machine.timeouts,
        s.max_turn_gap_ns / 1000
    );
    // The machine's event log, relative to its first event; all of it with
    // ETHERCRAB_ECDC_EVENTS=1, else the faults.
    let all = std::env::var_os("ETHERCRAB_ECDC_EVENTS").is_some_and(|v| v == "1");
    let t0 = s.events.first().map_or(0, |(t, _)| *t);
    for (t, e) in &s.events {
        if all || e.starts_with("Error") {
            let ms = t.saturating_sub(t0) as f64 / 1e6;
            eprintln!("ethercrab-ecdc: ecdc event at {ms:.1} ms: {e}");
        }
    }
    Ok(())
}
