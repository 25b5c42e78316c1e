//! Per-slave t_Diff (REQ-DC-015): a line mixing two ESC types with different processing delays
//! (one common forwarding delay, as the exactness condition of REQ-DC-015 requires). With each
//! slave's own t_Diff set on the machine, the measured delays equal the emulator's true frame
//! path; with one common value for all, they are off by the accumulated t_Diff error — the
//! second half shows this test can tell the two apart.
//!
//! verifies: REQ-DC-015

mod dc_support;

use dc_support::{config, sim};
use ecdc_core::dc::{Config, Event};
use ecdc_harness::emu::{Scenario, SlaveSpec};

/// t_F of every ESC in this line, ns (the emulator's default).
const T_F: u64 = 460;
/// t_P of the two ESC types, ns: t_Diff = 80 (the emulator's default) and 240.
const T_P: [u64; 2] = [540, 700];

fn mixed_line() -> Scenario {
    let mut sc = Scenario {
        slaves: Vec::new(),
        ..Scenario::line(1)
    };
    for i in 0..8 {
        sc = sc.with_slave(SlaveSpec {
            t_p_ns: Some(T_P[i % 2]),
            t_f_ns: Some(T_F),
            ..SlaveSpec::default()
        });
    }
    sc.ideal()
}

/// Worst |measured − true| delay over the line after the delay measurement, ns.
fn worst_delay_error(cfg: Config, per_slave: bool) -> i64 {
    let sc = mixed_line();
    let mut s = sim::<16>(&sc, cfg);
    if per_slave {
        for i in 0..8u16 {
            let t_diff = (T_P[usize::from(i) % 2] - T_F) as i32;
            s.machine
                .set_slave_t_diff(i, Some(t_diff))
                .expect("capacity");
        }
    }
    s.drive_until(1_000_000_000, |e| matches!(e, Event::DelaysMeasured { .. }))
        .expect("delays measured");
    let arr = s.net.epu_arrival_times(s.now() + 1_000);
    let a0 = arr[0].expect("first slave reached") as i64;
    let mut worst = 0i64;
    for (i, sl) in s.machine.slaves().iter().enumerate().take(8) {
        let truth = arr[i].expect("slave reached") as i64 - a0;
        worst = worst.max((i64::from(sl.delay_ns) - truth).abs());
    }
    worst
}

#[test]
fn per_slave_t_diff_gives_exact_delays_on_a_mixed_line() {
    let worst = worst_delay_error(config(), true);
    println!("mixed line, per-slave t_Diff: worst delay error {worst} ns");
    assert!(worst <= 10, "delay error {worst} ns with per-slave t_Diff");
}

// verifies: REQ-DC-121
#[test]
fn one_common_t_diff_is_wrong_on_a_mixed_line() {
    // Every second slave's t_Diff is 160 ns off: the error accumulates along the line
    // (80 ns per such hop before halving), far above the 10 ns quantisation bound. The
    // measurement (REQ-DC-121) is off here: it would find each slave's own value.
    let mut cfg = config();
    cfg.tdiff.mode = ecdc_core::dc::TdiffMode::Off;
    let worst = worst_delay_error(cfg, false);
    println!("mixed line, common t_Diff 80: worst delay error {worst} ns");
    assert!(
        worst >= 100,
        "expected a large error without per-slave t_Diff, got {worst} ns"
    );
}

/// With nothing told (`t_diff_ns` 0) the bring-up measures the t_Diff of slaves 1..=6
/// (REQ-DC-121). Slave 0 (no DC slave upstream) and the line end cannot be measured and take
/// the value of the first measured slave of their ESC type (REQ-DC-122); both t_P variants
/// share one type code here, so slave 0 gets 240 instead of its 80 ns and every delay behind
/// it is off by (240 − 80)/2 = 80 ns: the limit of the type rule, against 240 ns with one
/// common value.
// verifies: REQ-DC-121, REQ-DC-122
#[test]
fn measured_t_diff_gives_exact_delays_on_a_mixed_line() {
    let mut cfg = config();
    cfg.t_diff_ns = 0;
    let worst = worst_delay_error(cfg, false);
    println!("mixed line, measured t_Diff: worst delay error {worst} ns");
    assert!(worst <= 90, "delay error {worst} ns with measured t_Diff");
}

#[test]
fn t_diff_override_beyond_capacity_is_refused() {
    let sc = mixed_line();
    let mut s = sim::<16>(&sc, config());
    assert!(s.machine.set_slave_t_diff(16, Some(80)).is_err());
    assert_eq!(s.machine.set_slave_t_diff(3, Some(240)), Ok(None));
    assert_eq!(s.machine.slave_t_diff(3), 240);
    assert_eq!(s.machine.set_slave_t_diff(3, None), Ok(Some(240)));
    assert_eq!(s.machine.slave_t_diff(3), 80);
}
