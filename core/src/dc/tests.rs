//! Unit tests of the machine's engine: transmission, reply matching, retries, timeouts,
//! foreign input. End-to-end behaviour is tested against the emulator in
//! `harness/tests/dc_*.rs`; the P6 property in `proofs/src/machine.rs`.

use crate::dc::{Config, ConfigError, Error, Event, Machine, State};
use crate::time::SystemTime;
use crate::wire::{Address, Command, Datagram, EthernetFrame, FrameBuilder};

const T0: u64 = 800_000_000_000_000_000;

fn machine() -> Machine<4> {
    machine_with(Config::default())
}

fn machine_with(cfg: Config) -> Machine<4> {
    Machine::new(cfg).unwrap()
}

/// A machine with the default configuration, started at `T0`.
fn started() -> Machine<4> {
    let mut m = machine();
    m.start(SystemTime(T0));
    m
}

/// A started machine whose first frame, the count BRD, came back with WKC `slaves` 1 µs later.
fn counted(slaves: u16) -> Machine<4> {
    let mut m = started();
    let mut buf = [0u8; 1514];
    let n = m.poll_transmit(SystemTime(T0), &mut buf).unwrap();
    m.handle_frame(SystemTime(T0 + 1_000), &reply(&buf[..n], slaves));
    m
}

/// A machine started at `T0` that resends a request chunk `retries` times and then fails
/// for good (no automatic restart).
fn started_without_restart(retries: u8) -> Machine<4> {
    let mut m = machine_with(Config {
        auto_restart: false,
        retries,
        ..Config::default()
    });
    m.start(SystemTime(T0));
    m
}

/// The reply an ESC chain would return: processed MAC, every datagram's WKC set to `wkc`.
fn reply(frame: &[u8], wkc: u16) -> std::vec::Vec<u8> {
    let mut out = frame.to_vec();
    let mut eth = EthernetFrame::new_unchecked(&mut out[..]);
    eth.mark_processed_by_slave();
    let mut ecat = eth.ecat_frame_mut().unwrap();
    for d in ecat.iter_mut() {
        d.unwrap().set_wkc(wkc);
    }
    out
}

fn datagrams(frame: &[u8]) -> std::vec::Vec<(Command, u8, u16, u16)> {
    crate::dc::testing::headers(frame)
        .into_iter()
        .map(|(cmd, index, _, ado, len)| (cmd, index, ado, len))
        .collect()
}

fn events(m: &mut Machine<4>) -> std::vec::Vec<Event> {
    core::iter::from_fn(|| m.poll_event()).collect()
}

#[test]
fn config_validation() {
    let ok = Config::default();
    assert!(ok.validate(4).is_ok());
    let c = Config {
        index_count: 10,
        ..ok
    };
    assert_eq!(Machine::<4>::new(c).err(), Some(ConfigError::TooFewIndices));
    let c = Config {
        station_base: 0xFFFE,
        ..ok
    };
    assert_eq!(Machine::<4>::new(c).err(), Some(ConfigError::StationRange));
    let c = Config {
        speed_counter_start: 0x4000,
        ..ok
    };
    assert_eq!(
        Machine::<4>::new(c).err(),
        Some(ConfigError::SpeedCounterStart)
    );
    let mut c = ok;
    c.monitor.lock_ns = 2_000;
    assert_eq!(Machine::<4>::new(c).err(), Some(ConfigError::Hysteresis));
    let mut c = ok;
    c.sync = Some(crate::dc::SyncConfig {
        shift_ns: 1_000_000,
        ..Default::default()
    });
    assert_eq!(Machine::<4>::new(c).err(), Some(ConfigError::SyncCycle));
}

#[test]
fn idle_sends_nothing_start_counts() {
    let mut m = machine();
    let mut buf = [0u8; 1514];
    assert_eq!(m.poll_transmit(SystemTime(T0), &mut buf), None);
    assert_eq!(m.poll_timeout(), None);
    m.start(SystemTime(T0));
    let n = m.poll_transmit(SystemTime(T0), &mut buf).unwrap();
    assert_eq!(n, 60);
    let sent = buf[..n].to_vec();
    let d = datagrams(&sent);
    assert_eq!(d.len(), 1);
    assert_eq!((d[0].0, d[0].2, d[0].3), (Command::Brd, 0x0000, 2));
    assert!(d[0].1 >= 0x80);
    // Waiting for the reply: nothing more to send, a deadline is set.
    assert_eq!(m.poll_transmit(SystemTime(T0), &mut buf), None);
    assert_eq!(m.poll_timeout(), Some(SystemTime(T0 + 10_000_000)));
    // The reply (3 slaves) moves the machine on.
    let r = reply(&sent, 3);
    m.handle_frame(SystemTime(T0 + 1_000), &r);
    assert_eq!(m.slaves().len(), 3);
    let n = m.poll_transmit(SystemTime(T0 + 1_000), &mut buf).unwrap();
    assert_eq!(m.state(), State::AssignAddresses);
    let d = datagrams(&buf[..n]);
    assert_eq!(d.len(), 3);
    assert!(d
        .iter()
        .all(|x| x.0 == Command::Apwr && x.2 == 0x0010 && x.3 == 2));
}

#[test]
fn foreign_and_garbage_frames_are_counted_not_used() {
    let mut m = started();
    let mut buf = [0u8; 1514];
    let n = m.poll_transmit(SystemTime(T0), &mut buf).unwrap();
    let sent = buf[..n].to_vec();
    // Garbage.
    m.handle_frame(SystemTime(T0), &[0xFF; 7]);
    m.handle_frame(SystemTime(T0), &[]);
    // Our own frame seen again (not processed by any ESC).
    m.handle_frame(SystemTime(T0), &sent);
    // A processed frame whose datagram has another index; one with the right index and
    // another register.
    let patches: [fn(&mut Datagram<&mut [u8]>); 2] = [|d| d.set_index(0x05), |d| d.set_ado(0x0130)];
    for patch in patches {
        let mut r = reply(&sent, 3);
        let mut eth = EthernetFrame::new_unchecked(&mut r[..]);
        let mut f = eth.ecat_frame_mut().unwrap();
        patch(&mut f.iter_mut().next().unwrap().unwrap());
        m.handle_frame(SystemTime(T0), &r);
    }
    assert_eq!(m.stats().foreign_frames, 5);
    assert_eq!(m.state(), State::CountSlaves);
    assert!(m.slaves().is_empty());
    // The real reply still works afterwards.
    m.handle_frame(SystemTime(T0), &reply(&sent, 2));
    assert_eq!(m.slaves().len(), 2);
}

#[test]
fn no_slaves_is_a_typed_error_then_restart() {
    let mut m = counted(0);
    let ev = events(&mut m);
    // Not retried in place (an empty network is not a lost frame): the restart pause is the
    // retry.
    assert_eq!(ev, [Event::Error(Error::NoSlaves), Event::Restarting]);
    assert_eq!(m.state(), State::RestartWait);
    assert_eq!(m.stats().retries, 0);
    // After the pause it counts again.
    let wake = m.poll_timeout().unwrap();
    let mut buf = [0u8; 1514];
    assert_eq!(
        m.poll_transmit(wake, &mut buf)
            .map(|n| datagrams(&buf[..n])[0].0),
        Some(Command::Brd)
    );
}

#[test]
fn timeouts_retry_then_fail() {
    let mut m = started_without_restart(2);
    let mut buf = [0u8; 1514];
    let mut t = T0;
    for _ in 0..3 {
        assert!(m.poll_transmit(SystemTime(t), &mut buf).is_some());
        t = m.poll_timeout().unwrap().as_nanos();
        m.handle_timeout(SystemTime(t));
    }
    assert_eq!(
        events(&mut m),
        [Event::Error(Error::Timeout {
            state: State::CountSlaves
        })]
    );
    assert_eq!(m.state(), State::Failed);
    assert_eq!(m.poll_transmit(SystemTime(t), &mut buf), None);
    assert_eq!(m.stats().timeouts, 3);
}

#[test]
fn appends_into_caller_frame_and_matches_mixed_reply() {
    let mut m = started();
    let mut buf = [0u8; 1514];
    let mut b = FrameBuilder::new(&mut buf).unwrap();
    b.push(Command::Lrw, 0x01, Address::logical(0x1000), &[1, 2, 3, 4])
        .unwrap();
    assert!(m.poll_transmit_into(SystemTime(T0), &mut b));
    let n = b.finish().unwrap();
    let d = datagrams(&buf[..n]);
    assert_eq!(d.len(), 2);
    assert_eq!(d[0].0, Command::Lrw);
    assert_eq!(d[1].0, Command::Brd);
    m.handle_frame(SystemTime(T0 + 1_000), &reply(&buf[..n], 2));
    assert_eq!(m.slaves().len(), 2);
    assert_eq!(m.stats().foreign_datagrams, 1);
    assert_eq!(m.stats().foreign_frames, 0);
}

#[test]
fn tiny_buffer_is_a_typed_error() {
    let mut m = started();
    let mut small = [0u8; 20];
    assert_eq!(m.poll_transmit(SystemTime(T0), &mut small), None);
    assert!(events(&mut m).contains(&Event::Error(Error::BufferTooSmall)));
    // Nothing was left in flight: a proper buffer works.
    let mut buf = [0u8; 1514];
    assert!(m.poll_transmit(SystemTime(T0), &mut buf).is_some());
}

#[test]
fn too_many_slaves_is_a_typed_error() {
    let mut m = counted(9);
    assert_eq!(
        events(&mut m),
        [
            Event::Error(Error::TooManySlaves {
                found: 9,
                capacity: 4
            }),
            Event::Restarting
        ]
    );
}

#[test]
fn implausible_register_value_is_out_of_range_and_nothing_is_written() {
    let mut m = started_without_restart(1);
    let mut buf = [0u8; 1514];
    // Count (1 slave), assign, then ReadInfo replies with all-zero data: a DL status without
    // any link cannot belong to a slave that answered.
    for t in (0..4).map(|k| T0 + k * 2_000) {
        let Some(n) = m.poll_transmit(SystemTime(t), &mut buf) else {
            break;
        };
        let sent = buf[..n].to_vec();
        for (cmd, ..) in datagrams(&sent) {
            assert_ne!(cmd, Command::Fpwr, "nothing may be written");
        }
        m.handle_frame(SystemTime(t + 1_000), &reply(&sent, 1));
    }
    assert_eq!(m.state(), State::Failed);
    assert_eq!(
        events(&mut m),
        [Event::Error(Error::OutOfRange {
            station: 0x1001,
            register: 0x0110
        })]
    );
}

/// A two-slave line with hand-made latches, ready for `accumulate_round`.
fn two_slave_line() -> Machine<4> {
    let mut m = machine();
    m.sh.line.count = 2;
    m.sh.line.reference = 0;
    m.sh.line.sys_count = 2;
    // Port 0 and 1 open (link + communication, loop open) on slave 0; port 0 only on slave 1.
    let dl_0 = 0x0010 | 0x0020 | 0x0200 | 0x0800 | (1 << 12) | (1 << 14);
    let dl_1 = 0x0010 | 0x0200 | (1 << 10) | (1 << 12) | (1 << 14);
    for (i, dl) in [dl_0, dl_1].into_iter().enumerate() {
        let s = &mut m.sh.line.slaves[i];
        s.station = 0x1001 + i as u16;
        s.dc = crate::dc::DcKind::Bits64;
        s.dl_status = dl;
        s.times_before = [1_000, 2_000, 0, 0];
    }
    // Frame reaches slave 0 at 10 000, slave 1 at 10 600 (its clock reads 50 000), comes back
    // to slave 0's port 1 at 11 210.
    m.sh.line.slaves[0].times_after = [10_000, 11_210, 0, 0];
    m.sh.line.slaves[1].times_after = [50_000, 2_000, 0, 0];
    m
}

#[test]
fn latched_ports_give_delays() {
    let mut m = two_slave_line();
    m.sh.accumulate_round().unwrap();
    assert_eq!(m.sh.line.slaves[0].delay_sum, 0);
    assert_eq!(m.sh.line.slaves[1].delay_sum, 605); // (1 210 + t_Diff 0) / 2, rounded half up
}

/// Stale-latch detection: slave 0's port 1 is open according to DL status but its receive time
/// did not change across the trigger, so the frame never came back through it. The port is
/// treated as closed, slave 1 then has nowhere to hang, and the round is rejected instead of
/// yielding a delay from a stale time.
// verifies: REQ-DC-101
#[test]
fn stale_latch_is_not_used() {
    let mut m = two_slave_line();
    m.sh.line.slaves[0].times_after[1] = m.sh.line.slaves[0].times_before[1];
    assert!(matches!(
        m.sh.accumulate_round(),
        Err(Error::Measurement { .. })
    ));
    // A slave none of whose latches changed was not reached at all.
    let mut m = two_slave_line();
    m.sh.line.slaves[1].times_after = m.sh.line.slaves[1].times_before;
    assert_eq!(
        m.sh.accumulate_round(),
        Err(Error::Measurement { station: 0x1002 })
    );
}

#[test]
fn transition_outside_can_go_is_a_typed_error() {
    // verifies: REQ-CONV-008
    // No input drives the machine there (the model check asserts that no explored run reports
    // `Error::Internal`); the engine is called directly to reach the guard.
    let mut m = started();
    assert_eq!(m.state(), State::CountSlaves);
    assert!(!State::CountSlaves.can_go(State::Cyclic));
    m.enter(State::Cyclic);
    assert_eq!(m.state(), State::Failed);
    assert!(events(&mut m).contains(&Event::Error(Error::Internal {
        state: State::CountSlaves
    })));
    // An allowed transition still goes where it was asked.
    m.enter(State::CountSlaves);
    assert_eq!(m.state(), State::CountSlaves);
}

/// REQ-DC-131: the AL status step sends its 0x0920 reads only after every AL status is in,
/// even with a non-DC slave among the positions and AL states left from an earlier read (here
/// the reverse of the truth), and the slave found running anchors the one found in INIT.
// verifies: REQ-DC-131, REQ-DC-103
#[test]
fn running_offsets_read_after_al_states_and_anchor_the_others() {
    use crate::dc::slave::DcKind;
    let mut m = machine();
    m.sh.line.count = 3;
    m.sh.line.reference = 0;
    m.sh.line.sys_count = 2;
    m.sh.latch.trigger_time = SystemTime(T0);
    for (i, dc) in [DcKind::Bits64, DcKind::None, DcKind::Bits64]
        .into_iter()
        .enumerate()
    {
        m.sh.line.slaves[i].station = 0x1001 + i as u16;
        m.sh.line.slaves[i].dc = dc;
    }
    m.sh.line.slaves[0].al_status = Some(0x01);
    m.sh.line.slaves[2].al_status = Some(0x08);
    m.sh.line.slaves[0].entry_local = 1_000;
    m.sh.line.slaves[2].entry_local = 7_000;
    m.sh.line.slaves[2].delay_ns = 300;
    m.phase = m.phase.enter(State::ReadAlStatus);
    let now = SystemTime(T0 + 1_000_000);
    let mut buf = [0u8; 1514];
    // Answers with the true AL states: the reference (station 0x1001) in OP, 0x1003 in INIT;
    // the reference's 0x0920 puts its system time 5 µs ahead of the master's at the latch.
    let answer = |frame: &[u8]| {
        let mut out = reply(frame, 1);
        let mut eth = EthernetFrame::new_unchecked(&mut out[..]);
        let mut ecat = eth.ecat_frame_mut().unwrap();
        for d in ecat.iter_mut() {
            let mut d = d.unwrap();
            let v: u64 = match (d.adp(), d.ado()) {
                (0x1001, 0x0130) => 0x08,
                (0x1003, 0x0130) => 0x01,
                (0x1001, 0x0920) => T0 + 5_000 - 1_000,
                _ => 0,
            };
            let data = d.data_mut();
            let n = data.len();
            data.copy_from_slice(&v.to_le_bytes()[..n]);
        }
        out
    };
    let n = m.poll_transmit(now, &mut buf).unwrap();
    let first = datagrams(&buf[..n]);
    assert_eq!(
        first
            .iter()
            .map(|&(c, _, ado, len)| (c, ado, len))
            .collect::<std::vec::Vec<_>>(),
        [(Command::Fprd, 0x0130, 2), (Command::Fprd, 0x0130, 2)]
    );
    m.handle_frame(now, &answer(&buf[..n]));
    let n = m.poll_transmit(now, &mut buf).unwrap();
    let eth = EthernetFrame::new_checked(&buf[..n]).unwrap();
    let second: std::vec::Vec<(u16, u16, u16)> = eth
        .ecat_frame()
        .unwrap()
        .iter()
        .map(|d| {
            let d = d.unwrap();
            (d.adp(), d.ado(), d.data_len())
        })
        .collect();
    assert_eq!(second, [(0x1001, 0x0920, 8)]);
    m.handle_frame(now, &answer(&buf[..n]));
    assert_eq!(m.state(), State::WriteOffsets);
    assert_eq!(m.sh.line.domain_shift, 5_000);
    assert_eq!(
        m.sh.line.slaves[2].offset.wrapping_add(7_000),
        T0 + 5_000 + 300
    );
}

/// The `const` values behind `Machine::idle` are the `Default`s, and `idle` is `new` of the
/// default configuration.
#[test]
fn const_defaults_match_default() {
    use crate::dc::config::{DriftConfig, MonitorConfig, SyncConfig, TdiffConfig};
    use crate::dc::machine::Stats;
    use crate::dc::slave::SlaveInfo;
    assert_eq!(Config::DEFAULT, Config::default());
    assert_eq!(DriftConfig::DEFAULT, DriftConfig::default());
    assert_eq!(SyncConfig::DEFAULT, SyncConfig::default());
    assert_eq!(MonitorConfig::DEFAULT, MonitorConfig::default());
    assert_eq!(TdiffConfig::DEFAULT, TdiffConfig::default());
    assert_eq!(SlaveInfo::EMPTY, SlaveInfo::default());
    assert_eq!(Stats::ZERO, Stats::default());
    assert_eq!(
        std::format!("{:?}", Machine::<4>::idle()),
        std::format!("{:?}", machine())
    );
}

/// `configure` makes a used machine the one `new` returns (slaves found, counters, events,
/// overrides all forgotten); a rejected configuration changes nothing.
#[test]
fn configure_in_place_is_new() {
    let mut m = machine();
    m.set_slave_t_diff(2, Some(40)).unwrap();
    m.start(SystemTime(T0));
    let mut buf = [0u8; 1514];
    let n = m.poll_transmit(SystemTime(T0), &mut buf).unwrap();
    m.handle_frame(SystemTime(T0), &reply(&buf[..n], 3));
    assert_ne!(m.state(), State::Idle);
    let bad = Config {
        latch_rounds: 0,
        ..Config::default()
    };
    let before = std::format!("{m:?}");
    assert_eq!(m.configure(bad), Err(ConfigError::Zero));
    assert_eq!(std::format!("{m:?}"), before);
    let cfg = Config {
        index_first: 0x10,
        latch_rounds: 2,
        ..Config::default()
    };
    m.configure(cfg).unwrap();
    let fresh = Machine::<4>::new(cfg).unwrap();
    assert_eq!(std::format!("{m:?}"), std::format!("{fresh:?}"));
    assert_eq!(m.slave_t_diff(2), cfg.t_diff_ns);
}

/// REQ-DC-103/131 in the offset step's items: a slave without a system time gets no offset or
/// delay write even when its AL state would allow one, and only a slave whose AL status was read
/// and says it may be running has its offset read.
#[test]
fn offset_step_items_follow_system_time_and_al_status() {
    use crate::dc::machine::Item;
    use crate::dc::phase::{AdjustStep, Phase};
    let mut m = machine();
    m.sh.line.count = 3;
    m.sh.line.sys_count = 2;
    for (i, (dc, al)) in [
        (crate::dc::DcKind::Bits64, Some(0x01u16)),
        (crate::dc::DcKind::None, Some(0x01)),
        (crate::dc::DcKind::Bits64, None),
    ]
    .into_iter()
    .enumerate()
    {
        let s = &mut m.sh.line.slaves[i];
        s.station = 0x1001 + i as u16;
        s.dc = dc;
        s.al_status = al;
    }
    let sent = |m: &Machine<4>, items: core::ops::Range<u16>| -> std::vec::Vec<(u16, u16)> {
        items
            .filter_map(|i| match m.adjust_item(i) {
                Item::Send(op) => Some((op.station(), op.register())),
                _ => None,
            })
            .collect()
    };
    m.phase = Phase::Adjust(AdjustStep::WriteOffsets);
    let writes = sent(&m, 0..6);
    assert!(writes.iter().all(|&(st, _)| st != 0x1002), "{writes:x?}");
    assert!(writes.contains(&(0x1001, 0x0920)) && writes.contains(&(0x1001, 0x0928)));
    // Second half of the AL-status step: offsets of slaves that may be running.
    m.phase = Phase::Adjust(AdjustStep::ReadAlStatus);
    assert_eq!(sent(&m, 3..6), []);
    m.sh.line.slaves[0].al_status = Some(0x08); // OP
    m.sh.line.slaves[1].al_status = Some(0x08);
    assert_eq!(sent(&m, 3..6), [(0x1001, 0x0920)]);
}

/// One 64-bit slave at 0x1001 (the reference), SYNC configured, in `ReadReferenceTime`.
fn reading_reference_time() -> Machine<4> {
    use crate::dc::phase::{ActivationStep, Phase};
    let c = Config {
        sync: Some(crate::dc::SyncConfig::default()),
        ..Config::default()
    };
    let mut m = crate::dc::testing::line_with::<4>(c, &[crate::dc::DcKind::Bits64]);
    m.phase = Phase::Activation(ActivationStep::ReadReferenceTime);
    m
}

/// The reference time read before the SYNC programming sets the start time all SYNC units
/// share; nothing else does.
#[test]
fn reference_time_reply_sets_the_sync_start() {
    use crate::dc::request::{Pending, Reply, Tag};
    let mut m = reading_reference_time();
    let sent = Pending {
        command: Command::Fprd,
        index: 1,
        station: 0x1001,
        register: 0x0910,
        len: 8,
        tag: Tag::Item(0),
    };
    let data = T0.to_le_bytes();
    assert_eq!(m.sh.line.sync_start, None);
    let r = Reply {
        item: 0,
        sent,
        wkc: 1,
        data: &data,
    };
    m.activation_reply(SystemTime(T0), r).unwrap();
    let start = m.sh.line.sync_start.unwrap();
    assert!(start.is_after(SystemTime(T0)), "{start}");
    let sync = m.sh.cfg.sync.unwrap();
    let now = SystemTime(T0);
    let expected =
        m.sh.compute_sync_start(now, T0, &m.sh.line.slaves[0], &sync);
    assert_eq!(Some(start), expected);
}

/// Without a reference time (the read skipped: the reference is no slave found) the SYNC
/// programming stops with a fault instead of writing a start time nobody computed, and
/// nothing of `ProgramSync` is sent.
// verifies: REQ-DC-036
#[test]
fn sync_programming_needs_the_reference_time() {
    use crate::dc::activation::SyncWrite;
    use crate::dc::machine::Item;
    use crate::dc::phase::{ActivationStep, Phase};
    use crate::dc::work::PerSlave;
    let mut m = reading_reference_time();
    m.sh.line.reference = 1;
    m.sh.line.slaves[0].al_status = Some(0x01);
    assert!(matches!(m.activation_item(0), Item::Skip));
    assert_eq!(m.activation_done(), Err(Error::NoReferenceClock));
    let program = |m: &Machine<4>| {
        (0..SyncWrite::items(1))
            .filter(|&i| matches!(m.activation_item(i), Item::Send(_)))
            .count()
    };
    m.phase = Phase::Activation(ActivationStep::ProgramSync);
    assert_eq!(program(&m), 0);
    m.sh.line.sync_start = Some(SystemTime(T0));
    assert_eq!(program(&m), 3);
    m.phase = Phase::Activation(ActivationStep::ReadReferenceTime);
    assert_eq!(m.activation_done(), Ok(State::ClearActivation));
}

/// The invariant the model checker asserts is not vacuous: each broken timer rule is named.
#[test]
fn invariant_violations_are_reported() {
    use crate::dc::timer::Timer;
    let mut m = machine();
    assert_eq!(m.invariant_violation(), None);
    m.sh.timers.set(Timer::Cycle, SystemTime(T0));
    assert_eq!(
        m.invariant_violation(),
        Some("cycle timer armed outside Cyclic, or not in it")
    );
    let mut m = machine();
    m.sh.timers.set(Timer::Restart, SystemTime(T0));
    assert!(m
        .invariant_violation()
        .is_some_and(|v| v.starts_with("restart timer")));
    let mut m = machine();
    m.sh.timers.set(Timer::Reply, SystemTime(T0));
    assert!(m
        .invariant_violation()
        .is_some_and(|v| v.starts_with("a reply awaited")));
}

/// The system-time probe asks only slaves with receive-time latches, and a WKC of 0 (latches,
/// no system time) makes a slave delay-only; a WKC of 1 leaves its kind as read from 0x0008.
#[test]
fn system_time_probe_reads_dc_slaves_only() {
    use crate::dc::machine::Item;
    use crate::dc::phase::{DiscoveryStep, Phase};
    use crate::dc::request::{Pending, Reply, Tag};
    use crate::dc::DcKind;
    let mut m = machine();
    m.sh.line.count = 3;
    for (i, dc) in [DcKind::Bits64, DcKind::None, DcKind::Bits32]
        .into_iter()
        .enumerate()
    {
        m.sh.line.slaves[i].station = 0x1001 + i as u16;
        m.sh.line.slaves[i].dc = dc;
    }
    m.phase = Phase::Discovery(DiscoveryStep::ProbeSystemTime);
    assert_eq!(m.discovery_count(DiscoveryStep::ProbeSystemTime), 3);
    let probes: std::vec::Vec<(u16, u16, u16)> = (0..3)
        .filter_map(|i| match m.discovery_item(i) {
            Item::Send(op) => Some((op.station(), op.register(), op.len)),
            _ => None,
        })
        .collect();
    assert_eq!(probes, [(0x1001, 0x0910, 4), (0x1003, 0x0910, 4)]);
    let reply = |m: &mut Machine<4>, item: u16, wkc: u16| {
        let sent = Pending {
            command: Command::Fprd,
            index: 1,
            station: 0x1001 + item,
            register: 0x0910,
            len: 4,
            tag: Tag::Item(item),
        };
        let data = [0u8; 4];
        m.discovery_reply(Reply {
            item,
            sent,
            wkc,
            data: &data,
        })
    };
    assert_eq!(reply(&mut m, 0, 1), Ok(()));
    assert_eq!(reply(&mut m, 2, 0), Ok(()));
    assert_eq!(m.sh.line.slaves[0].dc, DcKind::Bits64);
    assert_eq!(m.sh.line.slaves[2].dc, DcKind::DelayOnly);
    // Two slaves answering one station address is a WKC error, not a kind.
    assert!(reply(&mut m, 0, 2).is_err());
    assert_eq!(m.sh.line.slaves[0].dc, DcKind::Bits64);
}

/// A slave's t_Diff override replaces the configured value and returns the one it replaced;
/// a position beyond the capacity is refused.
// verifies: REQ-DC-015
#[test]
fn t_diff_overrides_fall_back_to_the_config() {
    let mut m = machine_with(Config {
        t_diff_ns: 20,
        ..Config::default()
    });
    assert_eq!(m.set_slave_t_diff(1, Some(-40)), Ok(None));
    assert_eq!(m.set_slave_t_diff(1, Some(45)), Ok(Some(-40)));
    assert_eq!(m.set_slave_t_diff(4, Some(1)), Err(ConfigError::Capacity));
    assert_eq!(
        (m.slave_t_diff(0), m.slave_t_diff(1), m.slave_t_diff(4)),
        (20, 45, 20)
    );
    assert_eq!(m.set_slave_t_diff(1, None), Ok(Some(45)));
    assert_eq!(m.slave_t_diff(1), 20);
}

/// The reference is known once a slave with a system time is; the SYNC start once chosen.
#[test]
fn reference_and_sync_start_getters() {
    let mut m = machine();
    assert_eq!((m.reference(), m.sync_start()), (None, None));
    m.sh.line.count = 4;
    m.sh.line.sys_count = 3;
    m.sh.line.reference = 2;
    m.sh.line.sync_start = Some(SystemTime(T0));
    assert_eq!(m.reference(), Some(2));
    assert_eq!(m.sync_start(), Some(SystemTime(T0)));
}

/// REQ-DC-113: a frame that answers only some of a step's datagrams does not complete the
/// step; it completes when the rest are answered.
// verifies: REQ-DC-113
#[test]
fn a_partial_reply_does_not_complete_the_step() {
    let mut m = started();
    let mut buf = [0u8; 1514];
    let mut t = T0;
    // Count two slaves and address them.
    for _ in 0..2 {
        let n = m.poll_transmit(SystemTime(t), &mut buf).unwrap();
        let wkc = if m.state() == State::CountSlaves {
            2
        } else {
            1
        };
        m.handle_frame(SystemTime(t + 1_000), &reply(&buf[..n], wkc));
        t += 2_000;
    }
    assert_eq!(m.state(), State::ReadInfo);
    let n = m.poll_transmit(SystemTime(t), &mut buf).unwrap();
    let sent = buf[..n].to_vec();
    assert!(datagrams(&sent).len() >= 2);
    // The first datagram alone, answered.
    let eth = EthernetFrame::new_checked(&sent[..]).unwrap();
    let ecat = eth.ecat_frame().unwrap();
    let first = ecat.iter().next().unwrap().unwrap();
    let mut part = [0u8; 1514];
    let mut b = FrameBuilder::new(&mut part).unwrap();
    let address = Address::configured(first.adp(), first.ado());
    b.push(
        first.command().unwrap(),
        first.index(),
        address,
        first.data(),
    )
    .unwrap();
    let len = b.finish().unwrap();
    m.handle_frame(SystemTime(t + 1_000), &reply(&part[..len], 1));
    assert_eq!(m.state(), State::ReadInfo);
    assert!(m.is_awaiting_reply());
    // The whole frame answers the rest (its first datagram is no longer awaited).
    m.handle_frame(SystemTime(t + 1_500), &reply(&sent, 1));
    assert!(!m.is_awaiting_reply());
    assert_eq!(m.stats().foreign_datagrams, 1);
}
