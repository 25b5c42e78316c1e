//! End-to-end: a 100-slave tree (3- and 4-port junctions, branches, default emulator noise)
//! brought up by the machine reaches lock and stays within 100 ns; on a jitter-free copy of the
//! same tree the measured delays equal the emulator's frame path.

mod dc_support;

use dc_support::*;
use ecdc_core::dc::{Event, State};
use ecdc_harness::emu::EscKind;

#[test]
fn hundred_slave_tree_locks() {
    let sc = tree_100();
    let mut s = sim::<128>(&sc, config());
    let (frames, t_lock) = lock(&mut s, 5_000_000_000);
    print_events(&s);
    assert_eq!(s.machine.state(), State::Cyclic);
    assert_eq!(s.machine.slaves().len(), 100);
    let kinds = [EscKind::Dc64; 100];
    let _ = steady(&mut s, 500_000_000, &kinds);
    let st = steady(&mut s, 1_000_000_000, &kinds);
    println!(
        "TREE100 lock_frames={frames} lock_time_ms={:.1} steady={st:?}",
        t_lock as f64 / 1e6
    );
    // 0x092C compares against the reference time carried through up to ~90 jittery cables
    // (8 ns uniform PHY jitter each), so single samples scatter more than the clocks do: the
    // register bound is looser than the true-clock bound.
    assert!(st.max_abs_diff < 150, "{st:?}");
    assert!(st.mean_abs_diff < 30.0, "{st:?}");
    assert!(st.max_true_err < 100, "{st:?}");
    assert!(s.machine.is_locked());
    assert!(!s.events().iter().any(|(_, e)| matches!(e, Event::Error(_))));
}

/// Without PHY jitter (the emulator's jitter has a mean of half its range per cable, which the
/// jitter-free path oracle does not include), every delay equals the true EPU arrival time
/// difference to the reference within the 10 ns stamp quantisation.
// verifies: REQ-DC-121
#[test]
fn tree_delays_match_emulator_path() {
    let sc = tree_100().ideal();
    let mut s = sim::<128>(&sc, config());
    // 5 s: the t_Diff measurement before the delays takes ~1.2 s of network time here (74
    // slaves measured, 130 frames each, REQ-DC-121).
    s.drive_until(5_000_000_000, |e| matches!(e, Event::DelaysMeasured { .. }))
        .expect("delays");
    let arr = s.net.epu_arrival_times(s.now() + 1_000);
    let a0 = arr[0].unwrap();
    let mut worst = 0i64;
    for (i, sl) in s.machine.slaves().iter().enumerate() {
        let truth = arr[i].unwrap() as i64 - a0 as i64;
        worst = worst.max((i64::from(sl.delay_ns) - truth).abs());
    }
    println!("TREE100 (no jitter) worst delay error vs emulator path: {worst} ns");
    assert!(worst <= 10, "delay error {worst} ns");
}
