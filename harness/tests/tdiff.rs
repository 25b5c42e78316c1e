//! t_Diff measurement (REQ-DC-120..126) on the emulator with PHY jitter on: the machine is told
//! nothing (`t_diff_ns` 0) and must find every ESC's t_P − t_F within ±5 ns of the emulator's
//! truth on seed 000's 6-slave line, the 100-slave tree and the 512-slave line; every slave's
//! value carries its source; DL control is restored exactly; a running slave stops the step.
//!
//! verifies: REQ-DC-120, REQ-DC-121, REQ-DC-122, REQ-DC-123, REQ-DC-124, REQ-DC-125, REQ-DC-126

mod dc_support;

use std::path::Path;

use dc_support::{fault_in_10ms, side_write, sim, to_op};
use ecdc_core::dc::{Config, Error, Event, TdiffFallback, TdiffMode, TdiffSource};
use ecdc_harness::emu::Scenario;

/// Target of the measurement, ns.
const TOLERANCE_NS: i64 = 5;

fn nothing_told() -> Config {
    Config {
        t_diff_ns: 0,
        ..Config::default()
    }
}

fn scenario(name: &str) -> Scenario {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenarios")
        .join(name);
    Scenario::load(&p).expect("scenario")
}

/// Runs the bring-up to the delay measurement; returns per slave (measured value, source,
/// truth t_P − t_F) and checks that DL control 0x0101 is back to its power-on value
/// (REQ-DC-124). Reaching the delays at all means every trigger's working counter with slaves
/// cut off was accepted (REQ-DC-125); the values and sources are read from `Machine::slaves`
/// (REQ-DC-126).
fn measure<const N: usize>(sc: &Scenario, cfg: Config) -> Vec<(i32, TdiffSource, i64)> {
    let mut s = sim::<N>(sc, cfg);
    s.drive_until(60_000_000_000, |e| {
        matches!(e, Event::DelaysMeasured { .. })
    })
    .unwrap_or_else(|e| {
        for (t, e) in s.events() {
            eprintln!("{t:>12} {e:?}");
        }
        panic!("no delays: {e}")
    });
    assert!(
        s.events()
            .iter()
            .any(|(_, e)| matches!(e, Event::TdiffResolved { .. })),
        "TdiffResolved event"
    );
    let n = s.net.slave_count();
    assert_eq!(s.machine.slaves().len(), n, "every slave found");
    (0..n)
        .map(|i| {
            assert_eq!(dl_control(&s, i), 0x0001, "slave {i}: DL control restored");
            let info = s.net.slave_info(i).unwrap();
            let sl = &s.machine.slaves()[i];
            (
                sl.t_diff_ns,
                sl.t_diff_source,
                info.t_p_ns as i64 - info.t_f_ns as i64,
            )
        })
        .collect()
}

/// Every slave's value within the tolerance, and every one measured or from a measured slave
/// of its type. Returns the worst error.
fn check(name: &str, r: &[(i32, TdiffSource, i64)]) -> i64 {
    let mut worst = 0i64;
    let mut measured = 0;
    let mut bad = Vec::new();
    let mut hist = std::collections::BTreeMap::new();
    for (i, (v, src, truth)) in r.iter().enumerate() {
        measured += usize::from(*src == TdiffSource::Measured);
        let err = i64::from(*v) - truth;
        *hist.entry(err).or_insert(0u32) += 1;
        worst = worst.max(err.abs());
        let known = matches!(src, TdiffSource::Measured | TdiffSource::SameType { .. });
        if !known || err.abs() > TOLERANCE_NS {
            bad.push(format!("slave {i}: {v} ns, truth {truth} ns ({src:?})"));
        }
    }
    println!("{name}: error histogram (ns -> slaves) {hist:?}");
    assert!(bad.is_empty(), "{name}: {} slaves off: {bad:?}", bad.len());
    let lo = r.iter().map(|x| x.0).min().unwrap();
    let hi = r.iter().map(|x| x.0).max().unwrap();
    println!(
        "{name}: {} slaves, {measured} measured, values {lo}..{hi} ns, worst |error| {worst} ns",
        r.len()
    );
    assert!(measured > 0, "{name}: nothing measured");
    worst
}

#[test]
fn seed000_line_within_5_ns() {
    let r = measure::<16>(&Scenario::line(6), nothing_told());
    check("line(6)", &r);
    // The first slave (no DC slave upstream) and the line end (no downstream port) are not
    // measurable; the 4 middle slaves are.
    assert_eq!(r[0].1, TdiffSource::SameType { from: 1 });
    assert_eq!(r[5].1, TdiffSource::SameType { from: 1 });
    for x in &r[1..5] {
        assert_eq!(x.1, TdiffSource::Measured);
    }
}

#[test]
fn tree100_within_5_ns() {
    let r = measure::<128>(&scenario("bench_tree100.toml"), nothing_told());
    check("tree100", &r);
}

#[test]
fn line512_within_5_ns() {
    let r = measure::<512>(&scenario("bench_line512.toml"), nothing_told());
    check("line512", &r);
}

/// The cheaper mode measures one slave per ESC type and revision.
#[test]
fn per_esc_type_measures_once() {
    let cfg = Config {
        tdiff: ecdc_core::dc::TdiffConfig {
            mode: TdiffMode::PerEscType,
            ..Default::default()
        },
        ..nothing_told()
    };
    let r = measure::<16>(&Scenario::line(6), cfg);
    check("line(6) per type", &r);
    let measured = r.iter().filter(|x| x.1 == TdiffSource::Measured).count();
    assert_eq!(measured, 1);
}

/// User values win and are labelled; mode Off leaves the default with its source.
#[test]
fn configured_and_off() {
    let sc = Scenario::line(4);
    let mut s = sim::<8>(&sc, nothing_told());
    s.machine.set_slave_t_diff(2, Some(77)).unwrap();
    s.drive_until(10_000_000_000, |e| {
        matches!(e, Event::DelaysMeasured { .. })
    })
    .unwrap();
    let sl = s.machine.slaves();
    assert_eq!(
        (sl[2].t_diff_ns, sl[2].t_diff_source),
        (77, TdiffSource::Configured)
    );
    assert_eq!(sl[1].t_diff_source, TdiffSource::Measured);

    let cfg = Config {
        t_diff_ns: 80,
        tdiff: ecdc_core::dc::TdiffConfig {
            mode: TdiffMode::Off,
            ..Default::default()
        },
        ..Config::default()
    };
    let mut s = sim::<8>(&sc, cfg);
    s.drive_until(10_000_000_000, |e| {
        matches!(e, Event::DelaysMeasured { .. })
    })
    .unwrap();
    for sl in s.machine.slaves() {
        assert_eq!((sl.t_diff_ns, sl.t_diff_source), (80, TdiffSource::Default));
    }
}

/// DL control 0x0100..0x0101 of emulator slave `i` (power-on value 0x0001).
fn dl_control<const N: usize>(s: &ecdc_harness::sim::Sim<N>, i: usize) -> u16 {
    let b = s.net.peek(i, 0x0100, 2).unwrap();
    u16::from_le_bytes([b[0], b[1]])
}

/// REQ-DC-123: with a slave in OP no port is closed; the configured value is used and the
/// source says why.
// verifies: REQ-DC-123
#[test]
fn running_slave_stops_the_step() {
    let mut sc = Scenario::line(4);
    // Slave 2 was addressed and put into OP by an application before this bring-up.
    sc.slaves[0].repeat = 2;
    sc = sc.with_slave(ecdc_harness::emu::SlaveSpec {
        station: 0x2000,
        ..Default::default()
    });
    sc = sc.with_slave(ecdc_harness::emu::SlaveSpec::default());
    let cfg = Config {
        t_diff_ns: 70,
        ..Config::default()
    };
    let mut s = sim::<8>(&sc, cfg);
    to_op(&mut s, 0x2000);
    s.drive_until(10_000_000_000, |e| {
        matches!(e, Event::DelaysMeasured { .. })
    })
    .unwrap();
    let sl = s.machine.slaves();
    assert_eq!(sl[2].al_status.map(|a| a & 0x0F), Some(0x08));
    assert_eq!(
        (sl[1].t_diff_ns, sl[1].t_diff_source),
        (70, TdiffSource::Fallback(TdiffFallback::Running))
    );
    for i in 0..4 {
        assert_eq!(dl_control(&s, i), 0x0001);
    }
}

/// The emulator's closed-port assumption (docs/emulator.md "Closed ports"): a port forced
/// closed by DL control turns the frame round exactly like an unconnected one, unless
/// `forced_loop_ns` says otherwise. The measured t_Diff of every middle slave shifts by exactly
/// that difference (jitter off, so the shift is not hidden in noise): the measurement cannot
/// tell a slower forced loop from a larger t_P, which is why the assumption is stated.
#[test]
fn forced_loop_delay_shifts_the_measurement() {
    let run = |extra: u64| {
        let mut sc = Scenario::line(6).ideal();
        sc.defaults.forced_loop_ns = extra;
        measure::<16>(&sc, nothing_told())
    };
    let same = run(0);
    let slow = run(30);
    for i in 1..5 {
        assert_eq!(same[i].1, TdiffSource::Measured);
        assert_eq!(
            i64::from(same[i].0),
            same[i].2,
            "slave {i}: exact with jitter off"
        );
        assert_eq!(slow[i].0 - same[i].0, 30, "slave {i}: {slow:?} vs {same:?}");
    }
}

/// REQ-DC-124: a value outside the plausible range is not used. A forced loop 600 ns slower than
/// an open end makes every measurement 680 ns, above `max_ns` (500): each measured slave falls
/// back to `Config::t_diff_ns` with the rejected value in its source.
// verifies: REQ-DC-124
#[test]
fn implausible_measurement_falls_back() {
    let mut sc = Scenario::line(4).ideal();
    sc.defaults.forced_loop_ns = 600;
    let cfg = Config {
        t_diff_ns: 33,
        ..Config::default()
    };
    let r = measure::<8>(&sc, cfg);
    for x in &r[1..3] {
        assert_eq!(
            (x.0, x.1),
            (
                33,
                TdiffSource::Fallback(TdiffFallback::Implausible { measured_ns: 680 })
            )
        );
    }
    // Nothing usable was measured, so the unmeasurable slaves keep the default.
    assert_eq!((r[0].0, r[0].1), (33, TdiffSource::Default));
}

/// REQ-DC-126: `ecdc scan`'s table carries each slave's t_Diff and its source.
// verifies: REQ-DC-126
#[test]
fn scan_report_lists_t_diff_and_source() {
    let mut s = sim::<16>(&Scenario::line(3), nothing_told());
    s.drive_until(10_000_000_000, |e| {
        matches!(e, Event::DelaysMeasured { .. })
    })
    .unwrap();
    let (rows, err) = ecdc_harness::cli::scan::report_slaves::<16>(s.machine.slaves(), true);
    assert!(err.is_none());
    let src: Vec<&str> = rows
        .iter()
        .map(|r| r.t_diff_source.as_deref().unwrap())
        .collect();
    assert_eq!(src, ["same type as 1", "measured", "same type as 1"]);
    for (r, sl) in rows.iter().zip(s.machine.slaves()) {
        assert_eq!(r.t_diff_ns, Some(sl.t_diff_ns));
    }
}

/// A 5-slave line whose t_Diff step has closed a target's ports and run a closed latch with
/// them: the machine and the target's position.
fn line5_with_a_port_closed() -> (ecdc_harness::sim::Sim<8>, usize) {
    let mut s = sim::<8>(&Scenario::line(5), nothing_told());
    let mut closed_at = None;
    for _ in 0..200_000 {
        s.step().unwrap();
        if let Some(i) = (0..5).find(|i| dl_control(&s, *i) != 0x0001) {
            closed_at = Some(i);
            break;
        }
    }
    let i = closed_at.expect("a port was closed");
    // Let the close take effect and a closed latch run.
    for _ in 0..4 {
        s.step().unwrap();
    }
    assert_ne!(dl_control(&s, i), 0x0001, "slave {i} still closed");
    (s, i)
}

/// REQ-DC-124: a bring-up interrupted while a port is closed (here: `start` again) first
/// reopens it, so the next count sees every slave and DL control ends as it was.
// verifies: REQ-DC-124
#[test]
fn restart_while_closed_restores_the_port_first() {
    let (mut s, _) = line5_with_a_port_closed();
    // Restart with the port closed.
    let now = s.master_time_at(s.now());
    s.machine.start(now);
    s.drive_until(10_000_000_000, |e| {
        matches!(e, Event::DelaysMeasured { .. })
    })
    .unwrap();
    assert_eq!(
        s.machine.slaves().len(),
        5,
        "every slave counted after the restart"
    );
    for k in 0..5 {
        assert_eq!(dl_control(&s, k), 0x0001, "slave {k}");
    }
    assert!(s
        .events()
        .iter()
        .any(|(_, e)| matches!(e, Event::SlavesFound { count: 5, .. })));
}

/// REQ-DC-124 after a topology change: the restore of a port left closed is addressed by the
/// target's station address, which another slave may hold too by then (a bring-up after a link
/// break addresses only the slaves it reaches; the ones behind the break keep their old
/// addresses and come back with them). Found by `ecdc soak --topology tree100 --stay-init`:
/// treating the working counter 2 as a fault repeated the same restore before every count, so
/// the bring-up never reached the address step that ends the duplicate.
// verifies: REQ-DC-124
#[test]
fn restore_answered_by_two_slaves_ends_the_recovery() {
    let station = |s: &ecdc_harness::sim::Sim<8>, i: usize| {
        let b = s.net.peek(i, 0x0010, 2).unwrap();
        u16::from_le_bytes([b[0], b[1]])
    };
    let (mut s, target) = line5_with_a_port_closed();
    // The first slave (upstream of the target, so reachable) takes the target's address, as a
    // slave re-addressed by a bring-up that did not reach the target would.
    assert_ne!(target, 0, "the first slave is never a target");
    let (first, shared) = (station(&s, 0), station(&s, target));
    assert_eq!(side_write(&mut s, first, 0x0010, &shared.to_le_bytes()), 1);

    let now = s.master_time_at(s.now());
    s.machine.start(now);
    s.drive_until(10_000_000_000, |e| {
        matches!(e, Event::DelaysMeasured { .. })
    })
    .expect("the bring-up passes the restore and measures the delays");
    assert_eq!(s.machine.slaves().len(), 5, "every slave counted");
    let stations: Vec<u16> = (0..5).map(|k| station(&s, k)).collect();
    for k in 0..5 {
        assert_eq!(dl_control(&s, k), 0x0001, "DL control of slave {k}");
        assert!(
            !stations[..k].contains(&stations[k]),
            "unique again: {stations:?}"
        );
    }
    assert!(
        !s.events()
            .iter()
            .any(|(_, e)| matches!(e, Event::Error(Error::Wkc { .. }))),
        "the duplicate restore is no working-counter fault"
    );
}

/// REQ-DC-121: one frame per latch round. On seed 000's 6-slave line (every read step fits one
/// frame) the step is the TdiffRead frame, the first read with the first trigger, one frame per
/// all-open round, and per target its close, its first trigger, one frame per closed round and
/// its restore. A two-slave line has no target and stops after the first all-open latch.
#[test]
fn one_frame_per_round() {
    // verifies: REQ-DC-121
    let frames = |sc: &Scenario| {
        let cfg = nothing_told();
        let mut s = sim::<16>(sc, cfg);
        let mut start = None;
        loop {
            let st = s.machine.state();
            if start.is_none() && st == ecdc_core::dc::State::TdiffRead {
                start = Some(s.stats().sent);
            }
            if st == ecdc_core::dc::State::LatchReadBefore {
                break;
            }
            assert!(s.step().unwrap(), "machine stopped");
        }
        let targets = s
            .machine
            .slaves()
            .iter()
            .filter(|x| x.t_diff_source == TdiffSource::Measured)
            .count() as u64;
        (s.stats().sent - start.unwrap(), targets, cfg.tdiff)
    };
    let (sent, targets, t) = frames(&Scenario::line(6));
    assert_eq!(targets, 4);
    let want = 2 + u64::from(t.base_rounds) + targets * (u64::from(t.rounds) + 3);
    assert_eq!(sent, want, "frames of the t_Diff step on line(6)");
    let (sent, targets, _) = frames(&Scenario::line(2));
    assert_eq!(
        (sent, targets),
        (3, 0),
        "line(2): read, first latch, its read"
    );
}

/// REQ-DC-123: a re-initialisation while the application holds the slaves in OP closes no
/// port, and every slave keeps the value measured at its position in the first bring-up
/// (source `Earlier`) instead of falling back to `Config::t_diff_ns`.
#[test]
fn restart_while_running_keeps_the_measured_values() {
    // verifies: REQ-DC-123
    use ecdc_harness::emu::Fault;
    let sc = Scenario::line(4);
    let mut s = sim::<8>(&sc, nothing_told());
    s.drive_until(20_000_000_000, |e| matches!(e, Event::Locked { .. }))
        .expect("first lock");
    let first: Vec<(i32, TdiffSource)> = s
        .machine
        .slaves()
        .iter()
        .map(|x| (x.t_diff_ns, x.t_diff_source))
        .collect();
    assert!(first.iter().any(|x| x.1 == TdiffSource::Measured));
    // The application takes every slave to OP (INIT → PRE-OP → SAFE-OP → OP).
    let stations: Vec<u16> = s.machine.slaves().iter().map(|x| x.station).collect();
    for st in stations {
        to_op(&mut s, st);
    }
    // A silence beyond the hold-over limit: the machine re-initialises.
    let (mark, at) = fault_in_10ms(
        &mut s,
        Fault::WireSilence {
            duration_ns: 1_500_000_000,
        },
    );
    s.run_until(at + 1_500_000_000).unwrap();
    s.drive_until(at + 20_000_000_000, |e| {
        matches!(e, Event::DelaysMeasured { .. })
    })
    .expect("second bring-up");
    assert!(s.events()[mark..]
        .iter()
        .any(|(_, e)| matches!(e, Event::Restarting)));
    for (i, (x, (v, src))) in s.machine.slaves().iter().zip(&first).enumerate() {
        assert_eq!(x.t_diff_ns, *v, "slave {i}");
        let want = match src {
            TdiffSource::Measured => TdiffSource::Earlier,
            other => *other,
        };
        assert_eq!(x.t_diff_source, want, "slave {i}");
        assert_eq!(dl_control(&s, i), 0x0001, "slave {i}: no port closed");
    }
}
