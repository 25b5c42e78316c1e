//! A re-initialisation of ecdc while ethercrab holds the slaves in OP (the loss of ecdc's
//! cyclic frames that a host stall causes): the machine cannot close ports to measure t_Diff
//! in OP and keeps the offsets, so the second bring-up must reuse the t_Diff values of the
//! first, pinned by the loop, or its delays are off by t_Diff/2 per hop and the SYNC0 pulses
//! spread.

mod support;

use ecdc_harness::emu::Scenario;
use support::{run_for, sync0_spreads, EmuLink};

#[test]
fn restart_in_op_reuses_the_measured_t_diff() {
    let slaves = 3;
    let mut link = EmuLink::new(&Scenario::line(slaves));
    // 200 ms after all slaves are in OP, 1.2 s of ecdc frames lost: longer than the machine's
    // hold-over (`Config::holdover_ns`, 1 s by default), which shorter silences end in.
    link.drop_ecdc = Some((200_000_000, 1_200_000_000));
    let (r, mut link) = run_for(link, 3.0);
    let s = &r.status;
    for (t, e) in &s.events {
        let ms = (*t as f64 - r.op_mono_ns as f64) / 1e6;
        eprintln!("{ms:+.1} ms from OP: {e}");
    }
    eprintln!(
        "init {:.0} ms, lock {:.0} ms, OP {:.0} ms",
        r.init_ms, r.dc_lock_ms, r.op_ms
    );
    assert!(link.dropped >= 5, "dropped {}", link.dropped);
    // The second bring-up found the slaves running.
    assert!(
        s.events
            .iter()
            .any(|(_, e)| e.contains("written: 0, skipped_running: 3")),
        "{:?}",
        s.events
    );
    // At least one re-initialisation: those started while the wire is still silent fail in
    // `CountSlaves` and restart again.
    assert!(s.restarts >= 1, "{:?}", s.events);
    assert!(s.locked, "not locked again");
    let resolved: Vec<&str> = s
        .events
        .iter()
        .filter(|(_, e)| e.starts_with("TdiffResolved"))
        .map(|(_, e)| &e[..])
        .collect();
    assert_eq!(resolved.len(), 2, "{resolved:?}");
    // The second bring-up (in OP) takes every value from the pin, none from the fallback.
    assert!(
        resolved[1].contains("configured: 3") && resolved[1].contains("fallback: 0"),
        "{resolved:?}"
    );
    // The last 0.5 s, well after the second lock: the pulses still coincide.
    let spreads = sync0_spreads(&mut link.emu.net, slaves);
    let end = spreads.last().expect("pulses").0;
    let tail: Vec<u64> = spreads
        .iter()
        .filter(|(t, _)| *t + 500_000_000 > end)
        .map(|(_, s)| *s)
        .collect();
    let worst = *tail.iter().max().expect("pulses in the tail");
    eprintln!("tail pulses {} worst spread {worst} ns", tail.len());
    assert!(tail.len() > 400, "{} pulses", tail.len());
    // The emulator's t_Diff is 80 ns (t_P 540, t_F 460): a fallback to 0 misplaces each hop
    // by 40 ns, two hops on this line; within 30 ns only with the right values.
    assert!(
        worst < 30,
        "worst SYNC0 spread {worst} ns after the restart"
    );
}
