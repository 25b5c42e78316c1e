//! End-to-end: mixed networks. 64-bit and 32-bit DC slaves, a slave without DC between DC
//! slaves and a receive-times-only ESC; also a 32-bit reference clock. Each reaches lock, every
//! slave's 0x0920/0x0990 is written with its own width, and lock holds across the 4.29 s wrap of
//! the 32-bit clocks.

mod dc_support;

use dc_support::*;
use ecdc_core::dc::{DcKind, State};
use ecdc_harness::emu::{EscKind, Scenario, SlaveSpec};

fn mixed(kinds: &[EscKind]) -> Scenario {
    let mut sc = Scenario {
        seed: 11,
        ..Scenario::default()
    };
    for k in kinds {
        sc.slaves.push(SlaveSpec {
            kind: Some(*k),
            ..SlaveSpec::default()
        });
    }
    sc
}

fn run(kinds: &[EscKind], window_ns: u64) {
    let sc = mixed(kinds);
    let mut s = sim::<16>(&sc, config());
    let (frames, t) = lock(&mut s, 3_000_000_000);
    print_events(&s);
    assert_eq!(s.machine.state(), State::Cyclic);
    for (i, (sl, k)) in s.machine.slaves().iter().zip(kinds).enumerate() {
        let expect = match k {
            EscKind::Dc64 => DcKind::Bits64,
            EscKind::Dc32 => DcKind::Bits32,
            EscKind::DcReceiveTimesOnly => DcKind::DelayOnly,
            EscKind::NoDc => DcKind::None,
        };
        assert_eq!(sl.dc, expect, "slave {i}");
        assert_eq!(sl.offset_written, k.has_system_time(), "slave {i}");
        assert_eq!(sl.sync_programmed, k.has_system_time(), "slave {i}");
        if k.has_system_time() {
            // The written offset and start time, read back with the slave's own width.
            let w = if k.is_64bit() { 8 } else { 4 };
            let mut off = s.net.peek(i, 0x0920, 8).unwrap();
            off.truncate(w);
            let mut want = sl.offset.to_le_bytes().to_vec();
            want.truncate(w);
            assert_eq!(off, want, "slave {i} 0x0920");
        }
    }
    let _ = steady(&mut s, 300_000_000, kinds);
    let st = steady(&mut s, window_ns, kinds);
    println!(
        "MIXED {kinds:?} lock_frames={frames} lock_ms={:.1} {st:?}",
        t as f64 / 1e6
    );
    assert_clean_lock(&s, &st);
}

#[test]
fn mixed_32_64_nodc_delayonly_locks_across_32bit_wrap() {
    use EscKind::*;
    // 5 s of cyclic operation: every 32-bit clock wraps at least once.
    run(
        &[Dc64, Dc32, NoDc, Dc64, DcReceiveTimesOnly, Dc32, Dc64],
        5_000_000_000,
    );
}

#[test]
fn thirty_two_bit_reference_locks() {
    use EscKind::*;
    run(&[Dc32, Dc64, Dc64, Dc32], 1_000_000_000);
}
