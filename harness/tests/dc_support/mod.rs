//! Shared helpers of the DC end-to-end tests (`harness/tests/dc_*.rs`): configuration matching
//! the emulator, bring-up to lock, steady-state measurement.
#![allow(dead_code)]

use ecdc_core::dc::{Config, Event};
use ecdc_core::wire::{Address, Command, EthernetFrame, FrameBuilder};
use ecdc_harness::emu::{EscKind, Fault, Network, Scenario, SEED000_T_F_NS, SEED000_T_P_NS};
use ecdc_harness::sim::Sim;

/// The machine's default configuration plus the emulator's t_Diff (t_P 540 − t_F 460 ns, the
/// emulator's model defaults): what a user would take from the ESI.
pub fn config() -> Config {
    Config {
        t_diff_ns: 80,
        ..Config::default()
    }
}

/// The machine's default configuration plus seed 000's t_Diff (its t_P − t_F).
pub fn seed000_config() -> Config {
    Config {
        t_diff_ns: i32::try_from(SEED000_T_P_NS - SEED000_T_F_NS).unwrap(),
        ..Config::default()
    }
}

/// A machine and the emulator for `sc`, started.
pub fn sim<const N: usize>(sc: &Scenario, cfg: Config) -> Sim<N> {
    let net = Network::new(sc).expect("scenario");
    let mut s = Sim::<N>::configured(cfg, net).expect("config");
    s.start();
    s
}

/// Drives until the first `Locked` event; panics with the event log on an error or time limit.
/// Returns (frames to lock, true time of lock).
pub fn lock<const N: usize>(s: &mut Sim<N>, limit_ns: u64) -> (u64, u64) {
    match s.drive_until(limit_ns, |e| matches!(e, Event::Locked { .. })) {
        Ok(Event::Locked { frames, .. }) => (frames, s.now()),
        other => {
            for (t, e) in s.events() {
                eprintln!("{t:>12} {e:?}");
            }
            panic!("no lock: {other:?}, stats {:?}", s.machine.stats());
        }
    }
}

/// Steady-state figures over a window of cyclic operation.
#[derive(Debug, Default, Clone, Copy)]
pub struct Steady {
    /// Largest |0x092C| any slave reported (per-slave FPRD, as read by the machine), ns.
    pub max_abs_diff: i64,
    /// Mean of the per-slave |0x092C| samples, ns.
    pub mean_abs_diff: f64,
    /// Largest BRD 0x092C upper bound, ns.
    pub max_bound: u32,
    /// Largest true |system time − reference system time| (emulator observer), ns.
    pub max_true_err: i64,
    /// Cycles observed.
    pub cycles: u64,
}

/// Runs `window_ns` of cyclic operation after lock and collects [`Steady`]. `kinds` says which
/// emulator slaves have a system time and whether it is 64-bit.
pub fn steady<const N: usize>(s: &mut Sim<N>, window_ns: u64, kinds: &[EscKind]) -> Steady {
    let reference = kinds
        .iter()
        .position(|k| k.has_system_time())
        .expect("a DC slave");
    let clocks: Vec<(usize, bool)> = kinds
        .iter()
        .enumerate()
        .filter(|(_, k)| k.has_system_time())
        .map(|(i, k)| (i, k.is_64bit()))
        .collect();
    let mut out = Steady::default();
    let mut sum = 0f64;
    let mut n = 0u64;
    let end = s.now() + window_ns;
    let cycle = s.machine.config().monitor.cycle_ns;
    let mut next_true = s.now();
    let cycles0 = s.machine.stats().cycles;
    while s.now() < end {
        let t = s.now() + cycle;
        s.run_until(t).expect("sim");
        for sl in s.machine.slaves() {
            if let Some(d) = sl.last_diff_ns {
                out.max_abs_diff = out.max_abs_diff.max(d.abs());
                sum += d.abs() as f64;
                n += 1;
            }
        }
        out.max_bound = out.max_bound.max(s.machine.diff_bound_ns().unwrap_or(0));
        if s.now() >= next_true {
            next_true = s.now() + 10 * cycle;
            let e = s
                .true_sync_error((reference, kinds[reference].is_64bit()), &clocks)
                .expect("sim")
                .unwrap_or(0);
            out.max_true_err = out.max_true_err.max(e);
        }
    }
    out.cycles = s.machine.stats().cycles - cycles0;
    out.mean_abs_diff = if n > 0 { sum / n as f64 } else { 0.0 };
    out
}

/// `st` within 100 ns (0x092C and true error), the machine locked, and no error and no lock
/// loss in the whole event log.
pub fn assert_clean_lock<const N: usize>(s: &Sim<N>, st: &Steady) {
    assert!(st.max_abs_diff < 100, "{st:?}");
    assert!(st.max_true_err < 100, "{st:?}");
    assert!(s.machine.is_locked());
    assert!(!s
        .events()
        .iter()
        .any(|(_, e)| matches!(e, Event::Error(_) | Event::LockLost { .. })));
}

/// The 100-slave tree of [`Scenario::tree_100`] with seed 7.
pub fn tree_100() -> Scenario {
    Scenario {
        seed: 7,
        ..Scenario::tree_100()
    }
}

/// Schedules `fault` 10 ms from now. Returns (the index the events after this call start at,
/// the fault's time).
pub fn fault_in_10ms<const N: usize>(s: &mut Sim<N>, fault: Fault) -> (usize, u64) {
    let mark = s.events().len();
    let at = s.now() + 10_000_000;
    s.net.schedule_fault(at, fault).unwrap();
    (mark, at)
}

/// Events after index `from`.
pub fn events_since<const N: usize>(s: &Sim<N>, from: usize) -> Vec<Event> {
    s.events()[from..].iter().map(|(_, e)| *e).collect()
}

/// Sends one FPWR on the side channel (a test fixture, not the machine); returns the WKC.
pub fn side_write<const N: usize>(s: &mut Sim<N>, station: u16, reg: u16, data: &[u8]) -> u16 {
    let mut buf = [0u8; 128];
    let mut b = FrameBuilder::new(&mut buf).unwrap();
    b.push(Command::Fpwr, 0x01, Address::configured(station, reg), data)
        .unwrap();
    let n = b.finish().unwrap();
    let rep = s.side_channel(&buf[..n]).unwrap().expect("reply");
    let eth = EthernetFrame::new_checked(&rep[..]).unwrap();
    let f = eth.ecat_frame().unwrap();
    let d = f.iter().next().unwrap().unwrap();
    d.wkc()
}

/// An application takes the slave at `station` to OP (AL control INIT → PRE-OP → SAFE-OP →
/// OP over the side channel, each write answered with WKC 1).
pub fn to_op<const N: usize>(s: &mut Sim<N>, station: u16) {
    for req in [2u16, 4, 8] {
        let wkc = side_write(s, station, 0x0120, &req.to_le_bytes());
        assert_eq!(wkc, 1, "station {station:#x} AL control {req}");
    }
}

/// Prints the event log (for `--nocapture` runs and failure analysis).
pub fn print_events<const N: usize>(s: &Sim<N>) {
    for (t, e) in s.events() {
        println!("{t:>12} {e:?}");
    }
}
