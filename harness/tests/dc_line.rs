//! End-to-end: DC bring-up of a 6-slave line on the emulator (default scenario: ±50 ppm
//! crystals, 8 ns PHY jitter, 10 ns quantisation, wander) reaches lock, and the locked network
//! stays within the Beckhoff "< 100 ns" figure by both the registers the master reads and the
//! emulator's true clocks.

mod dc_support;

use dc_support::*;
use ecdc_core::dc::{Event, State};
use ecdc_harness::emu::{EscKind, Scenario};
use ecdc_harness::sim::Sim;

#[test]
fn six_slave_line_locks_and_stays_within_100ns() {
    let mut s = sim::<8>(&Scenario::line(6), config());
    let (frames, t_lock) = lock(&mut s, 2_000_000_000);
    print_events(&s);
    assert_eq!(s.machine.state(), State::Cyclic);
    assert_eq!(s.machine.slaves().len(), 6);
    // Delays increase along the line (one hop ≈ t_P + cable ≈ 545 ns).
    let d: Vec<u32> = s.machine.slaves().iter().map(|x| x.delay_ns).collect();
    assert_eq!(d[0], 0);
    for w in d.windows(2) {
        assert!(w[1] > w[0] + 400 && w[1] < w[0] + 700, "delays {d:?}");
    }
    // Let the loops settle for 0.5 s, then measure 1 s of steady state.
    let _ = steady(&mut s, 500_000_000, &[EscKind::Dc64; 6]);
    let st = steady(&mut s, 1_000_000_000, &[EscKind::Dc64; 6]);
    println!(
        "LINE6 lock_frames={frames} lock_time_ms={:.1} steady={st:?}",
        t_lock as f64 / 1e6
    );
    assert!(st.cycles >= 990, "{st:?}");
    // No fault, no retry on a clean network.
    assert_clean_lock(&s, &st);
    assert_eq!(s.machine.stats().retries, 0);
    assert_eq!(s.machine.stats().foreign_frames, 0);
}

/// The SYNC0 start time is on the cycle grid anchored at the DC epoch (plus shift), in the
/// future when written, and every slave fires its first SYNC0 at that system time.
#[test]
fn sync0_start_on_grid_and_fires() {
    let mut cfg = config();
    let sync = cfg.sync.as_mut().unwrap();
    sync.shift_ns = 250_000;
    let mut s = sim::<8>(&Scenario::line(3), cfg);
    let ev = s
        .drive_until(2_000_000_000, |e| matches!(e, Event::SyncStarted { .. }))
        .expect("sync start");
    let Event::SyncStarted { start, slaves } = ev else {
        unreachable!()
    };
    let start = start.as_nanos();
    assert_eq!(slaves, 3);
    assert_eq!(start % 1_000_000, 250_000, "start {start}");
    // Programmed registers (exact widths) in every slave.
    for i in 0..3 {
        let st = s.net.peek(i, 0x0990, 8).unwrap();
        let v = u64::from_le_bytes(st.try_into().unwrap());
        assert!(
            v >= start,
            "slave {i}: 0x0990 {v} (next pulse) before start {start}"
        );
        assert_eq!(
            s.net.peek(i, 0x09A0, 4).unwrap(),
            1_000_000u32.to_le_bytes()
        );
        assert_eq!(s.net.peek(i, 0x0981, 1).unwrap(), [0x03]);
    }
    // Run past the start and past lock: SYNC0 edges appear, at the same true time on every
    // slave once the loops have settled.
    lock(&mut s, 2_000_000_000);
    s.run_until(s.now() + 400_000_000).unwrap();
    let edges = s.net.take_sync_edges();
    let sync0: Vec<_> = edges
        .iter()
        .filter(|e| e.signal == ecdc_harness::emu::SyncSignal::Sync0)
        .collect();
    assert!(sync0.len() >= 3 * 100, "only {} SYNC0 edges", sync0.len());
    let first = sync0.iter().map(|e| e.system_time).min().unwrap();
    assert_eq!(first, start, "first SYNC0 not at the programmed start");
    // Same programmed instant -> same true time on every slave.
    let mut spreads = Vec::new();
    for st in sync0
        .iter()
        .map(|e| e.system_time)
        .collect::<std::collections::BTreeSet<_>>()
    {
        let ts: Vec<u64> = sync0
            .iter()
            .filter(|e| e.system_time == st)
            .map(|e| e.true_time)
            .collect();
        if ts.len() == 3 {
            spreads.push(ts.iter().max().unwrap() - ts.iter().min().unwrap());
        }
    }
    println!(
        "true err now {:?} spreads {:?}",
        s.true_sync_error((0, true), &[(1, true), (2, true)])
            .unwrap(),
        spreads.iter().step_by(20).collect::<Vec<_>>()
    );
    let first_half = spreads[..spreads.len() / 2]
        .iter()
        .max()
        .copied()
        .unwrap_or(0);
    let second_half = spreads[spreads.len() / 2..]
        .iter()
        .max()
        .copied()
        .unwrap_or(0);
    println!(
        "SYNC0 groups {}, worst true-time spread: first half {first_half} ns, second half {second_half} ns",
        spreads.len()
    );
    assert!(spreads.len() >= 300);
    // Right after lock the loops are still pulling in the last ~100 ns (the lock gate is 200 ns
    // on the OR bound); 200 ms later every SYNC0 pulse is within 100 ns on every slave.
    assert!(first_half < 400, "SYNC0 spread {first_half} ns");
    assert!(second_half < 100, "SYNC0 spread {second_half} ns");
}

/// The simulation is deterministic: the same scenario and seed give the same events at the same
/// true times and the same counters.
#[test]
fn simulation_is_deterministic() {
    let run = || {
        let mut sc = Scenario::line(4);
        sc.frame_loss_rate = 0.01;
        let mut s = sim::<8>(&sc, config());
        lock(&mut s, 2_000_000_000);
        s.run_until(s.now() + 100_000_000).unwrap();
        (s.events().to_vec(), *s.machine.stats(), s.stats())
    };
    assert_eq!(run(), run());
}

/// Brings a line of four 64-bit slaves up with the master clock `clock` sets and checks lock
/// and the true error of the steady state.
fn locks_with_master_clock(clock: impl FnOnce(Sim<8>) -> Sim<8>) {
    let net = ecdc_harness::emu::Network::new(&Scenario::line(4)).unwrap();
    let m: ecdc_core::dc::Machine<8> = ecdc_core::dc::Machine::new(config()).unwrap();
    let mut s = clock(Sim::new(m, net));
    s.start();
    lock(&mut s, 2_000_000_000);
    let _ = steady(&mut s, 300_000_000, &[EscKind::Dc64; 4]);
    let st = steady(&mut s, 500_000_000, &[EscKind::Dc64; 4]);
    assert!(st.max_true_err < 100, "{st:?}");
}

/// The master's own clock running 80 ppm fast changes nothing for the slaves: they follow the
/// reference clock, the master clock only seeds the offsets.
#[test]
fn drifting_master_clock_still_locks() {
    locks_with_master_clock(|s| s.with_master_ppb(80_000));
}

/// A master clock in the upper half of the 64-bit range (wrapping time orders it before 0)
/// brings the line up and locks as well: no deadline of the machine is an absolute instant
/// of its own choosing (the first cycle is due when the bring-up ends, not at the epoch).
#[test]
fn master_clock_in_the_upper_half_locks() {
    locks_with_master_clock(|s| s.with_master_epoch((1 << 63) + 1_000_000_000));
}

/// ARMW (by the reference's position, as TwinCAT) instead of FRMW works the same.
#[test]
fn armw_drift_command_locks() {
    let cfg = ecdc_core::dc::Config {
        drift_command: ecdc_core::dc::DriftCommand::Armw,
        ..config()
    };
    let mut s = sim::<8>(&Scenario::line(4), cfg);
    lock(&mut s, 2_000_000_000);
    let _ = steady(&mut s, 300_000_000, &[EscKind::Dc64; 4]);
    let st = steady(&mut s, 500_000_000, &[EscKind::Dc64; 4]);
    assert!(st.max_true_err < 100, "{st:?}");
    assert!(st.max_abs_diff < 100, "{st:?}");
}

/// The embedding master's own cyclic frame: it pushes its process data (an LRW with an index
/// outside the machine's range) and lets the machine append the DC datagrams into the same
/// frame; the reply is handed to the machine whole. Lock holds for 1 000 such cycles and the
/// LRW is counted as foreign, never used.
#[test]
fn dc_datagrams_ride_in_the_callers_process_data_frame() {
    use ecdc_core::wire::{Address, Command, FrameBuilder};
    let mut s = sim::<8>(&Scenario::line(4), config());
    lock(&mut s, 2_000_000_000);
    let foreign0 = s.machine.stats().foreign_datagrams;
    let mut buf = vec![0u8; 1514];
    let mut t = s.now();
    for _ in 0..1_000 {
        t += 1_000_000;
        let now = s.master_time_at(t);
        let mut b = FrameBuilder::new(&mut buf).unwrap();
        b.push(
            Command::Lrw,
            0x01,
            Address::logical(0x0001_0000),
            &[0u8; 32],
        )
        .unwrap();
        assert!(s.machine.poll_transmit_into(now, &mut b));
        let n = b.finish().unwrap();
        let frame = buf[..n].to_vec();
        let r = s
            .net
            .transact(&frame, t)
            .unwrap()
            .returned()
            .expect("returned");
        s.machine
            .handle_frame(s.master_time_at(r.arrival), &r.frame);
        while s.machine.poll_event().is_some() {}
    }
    assert!(s.machine.is_locked());
    assert_eq!(s.machine.stats().foreign_datagrams - foreign0, 1_000);
    assert!(s.machine.diff_bound_ns().unwrap() < 200);
}
