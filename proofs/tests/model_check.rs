//! Bounded model check of P6 (spec/SPEC.md §2; REQ-DC-103, REQ-DC-113) on the real no_std DC
//! state machine: every placement of up to `F` faults, each of 11 kinds, among the first `R`
//! rounds of bring-up, for 12 slave configurations, each continued by `TAIL` fault-free rounds
//! so recovery (and any later 0x0920 write) is exercised too.
//!
//! The executor and the property body are `ecdc_proofs::machine::run_script` (one body for P6,
//! shared with the proptest, the fuzz target and the Kani harness): it drives `Machine` against
//! a small consistent line of slaves whose AL status is truthful, and checks on every frame and
//! input: no panic, index matching (indices in range, distinct per frame, foreign frames
//! ignored), 0x0920 written only by FPWR of 4/8 bytes to a station in INIT/PREOP/BOOT, and
//! register widths. Each fault and the nominal round are byte sequences of that script language.
//!
//! A second check enumerates *every interleaving* of `D` single actions (transmit, replies to the
//! newest or an older frame, WKC-0 copy, garbage, ticks, timeouts, reset, start, re-measure,
//! foreign-datagram transmit, stall) after each of several bring-up prefixes, so orders the
//! nominal round never produces (reply before transmit, two transmits, reset mid-exchange) are
//! covered from early, middle and cyclic states.
//!
//! Fault kinds include a slave reset (station address lost, AL back to INIT) and a 32-bit
//! port-time wrap inside a latch round (the model line's latch times straddle 2^32 ns).
//!
//! What this is not: a state-space search with state hashing (stateright). The explored spaces
//! are "nominal bring-up with ≤ F faults at any rounds" and "prefix + any D actions", each
//! enumerated exhaustively. The model line has no clocks, so a reset slave's clock jump is
//! covered by the harness end-to-end tests on the ESC emulator, not here.
//! `#[ignore]`d: run by `.ci/layers/30-model-check.sh` in release mode.
//!
//! verifies: P6, REQ-DC-103, REQ-DC-113

use ecdc_proofs::machine::{run_script, Outcome};
use std::time::Instant;

/// Transmit, modelled reply to the newest frame, 10 µs later a timer tick.
const NOMINAL: &[u8] = &[1, 3, 0, 0x80, 0, 100, 0];

/// The fault kinds (name, script bytes replacing one nominal round).
const FAULTS: &[(&str, &[u8])] = &[
    // The frame is lost: no reply, time skips to the machine's deadline.
    ("loss", &[1, 7, 3]),
    // Reordering: a late modelled reply to the previous frame instead of this one.
    ("late", &[1, 4, 1, 0, 0x80]),
    // The frame returns unprocessed (a copy of what was sent, first byte mangled): every WKC 0.
    ("wkc0", &[1, 5, 1, 1, 0, 0, 0xFF]),
    // 8 bytes of garbage arrive instead of a reply.
    ("garbage", &[1, 5, 8, 0, 1, 2, 3, 4, 5, 6, 7, 8]),
    // The reply arrives twice.
    ("duplicate", &[1, 3, 0, 0x80, 3, 0, 0x80]),
    // The application resets and restarts the machine.
    ("reset", &[7, 0, 7, 1]),
    // The application asks for a new delay measurement, then a nominal exchange.
    ("remeasure", &[7, 2, 1, 3, 0, 0x80]),
    // A 6.5 ms stall of the host before the exchange.
    ("stall", &[0, 0xFF, 0xFF, 1, 3, 0, 0x80]),
    // The embedding master's frame carries a foreign datagram before ours.
    ("foreign", &[6, 3, 0, 0x80]),
    // Slave 1 power-cycles (station address lost, AL back to INIT), then a nominal exchange.
    ("slave_reset", &[7, 4, 1, 1, 3, 0, 0x80]),
    // The slaves' 32-bit port times wrap during the next latch round, then a nominal exchange.
    ("wrap", &[7, 5, 1, 3, 0, 0x80]),
];

/// Rounds in which faults may be placed (bring-up reaches `Cyclic` after about 17).
const R: usize = 20;
/// Fault-free rounds appended after the fault window.
const TAIL: usize = 20;

/// Script header: AL state selector per station (0 INIT, 4 PREOP, 5 SAFEOP, 6 OP, 7 SAFEOP+ERR)
/// and the line size selector (k = 1 + byte).
fn headers() -> Vec<[u8; 5]> {
    let mut h = Vec::new();
    for al in [[0u8, 0, 0, 0], [6, 6, 6, 6], [0, 5, 6, 4], [7, 0, 5, 0]] {
        for k in [0u8, 1, 3] {
            h.push([al[0], al[1], al[2], al[3], k]);
        }
    }
    h
}

fn script(header: &[u8; 5], faults: &[(usize, usize)]) -> Vec<u8> {
    let mut s = header.to_vec();
    for round in 0..R + TAIL {
        match faults.iter().find(|(at, _)| *at == round) {
            Some(&(_, kind)) => s.extend_from_slice(FAULTS[kind].1),
            None => s.extend_from_slice(NOMINAL),
        }
    }
    s
}

#[derive(Default, Debug)]
struct Tally {
    scripts: u64,
    cyclic: u64,
    with_offset_writes: u64,
}

impl Tally {
    /// Runs `search` on a fresh tally and prints the result with the time taken.
    fn timed(what: &str, search: impl FnOnce(&mut Tally)) -> Tally {
        let start = Instant::now();
        let mut t = Tally::default();
        search(&mut t);
        println!(
            "P6 model check, {what}: {t:?} in {:.1} s",
            start.elapsed().as_secs_f64()
        );
        t
    }

    fn count(&mut self, o: &Outcome) {
        self.scripts += 1;
        self.cyclic += u64::from(o.reached_cyclic);
        self.with_offset_writes += u64::from(o.offset_writes > 0);
    }
}

fn check(header: &[u8; 5], faults: &[(usize, usize)], t: &mut Tally) {
    let s = script(header, faults);
    let o: Outcome = match run_script(&s) {
        Ok(o) => o,
        Err(v) => {
            let named: Vec<_> = faults.iter().map(|&(at, k)| (at, FAULTS[k].0)).collect();
            panic!("P6 violated: {v:?}\nheader {header:?}, faults {named:?}\nscript {s:?}");
        }
    };
    t.count(&o);
}

/// Every header × every placement of ≤ 2 faults (11 kinds) in the first R rounds.
// verifies: P6
#[test]
#[ignore]
fn p6_all_placements_of_two_faults() {
    let nf = FAULTS.len();
    let t = Tally::timed("≤2 faults", |t| {
        for h in headers() {
            check(&h, &[], t);
            for a in 0..R {
                for ka in 0..nf {
                    check(&h, &[(a, ka)], t);
                    for b in a + 1..R {
                        for kb in 0..nf {
                            check(&h, &[(a, ka), (b, kb)], t);
                        }
                    }
                }
            }
        }
    });
    // Not vacuous: most runs still reach Cyclic, and offsets are written where slaves allow it.
    assert!(t.cyclic * 2 > t.scripts, "{t:?}");
    assert!(t.with_offset_writes * 4 > t.scripts, "{t:?}");
}

/// Mixed AL states (INIT, SAFEOP, OP, PREOP; 4 slaves) × every placement of exactly 3 faults.
/// (The all-INIT header, 1.5 M more runs, was dropped to keep the layer within a few minutes:
/// the explicit-state search in `model_check_bfs.rs` covers multi-fault interleavings from every
/// bring-up state of an all-INIT line.)
// verifies: P6
#[test]
#[ignore]
fn p6_all_placements_of_three_faults() {
    let nf = FAULTS.len();
    let h = [0u8, 5, 6, 4, 3];
    let t = Tally::timed("3 faults", |t| {
        for a in 0..R {
            for b in a + 1..R {
                for c in b + 1..R {
                    for ka in 0..nf {
                        for kb in 0..nf {
                            for kc in 0..nf {
                                check(&h, &[(a, ka), (b, kb), (c, kc)], t);
                            }
                        }
                    }
                }
            }
        }
    });
    assert!(t.cyclic * 2 > t.scripts, "{t:?}");
}

/// Single actions of the script language (name, bytes), for the interleaving check.
const ACTIONS: &[(&str, &[u8])] = &[
    ("tx", &[1]),
    ("reply-newest", &[3, 0, 0x80]),
    ("reply-older", &[4, 1, 0, 0x80]),
    ("wkc0-copy", &[5, 1, 1, 0, 0, 0xFF]),
    ("garbage", &[5, 8, 0, 1, 2, 3, 4, 5, 6, 7, 8]),
    ("tick-10us", &[0, 100, 0]),
    ("to-deadline", &[7, 3]),
    ("reset", &[7, 0]),
    ("start", &[7, 1]),
    ("remeasure", &[7, 2]),
    ("tx-with-foreign", &[6]),
    ("stall-6.5ms", &[0, 0xFF, 0xFF]),
    ("slave-reset", &[7, 4, 2]),
    ("port-time-wrap", &[7, 5]),
];

/// Actions enumerated after each prefix.
const D: u32 = 5;

/// Every sequence of `D` actions (14^5 = 537 824) after 0, 8, 16 and 20 nominal rounds (start,
/// offsets/drift phase, SYNC set-up, cyclic), for all-INIT and mixed-AL lines of 4 slaves.
// verifies: P6
#[test]
#[ignore]
fn p6_all_interleavings_after_bringup_prefixes() {
    let n = ACTIONS.len();
    let total = n.pow(D);
    let t = Tally::timed(&format!("all {D}-action interleavings"), |t| {
        for h in [[0u8, 0, 0, 0, 3], [0, 5, 6, 4, 3]] {
            for prefix in [0usize, 8, 16, 20] {
                let mut base = h.to_vec();
                for _ in 0..prefix {
                    base.extend_from_slice(NOMINAL);
                }
                for code in 0..total {
                    let mut s = base.clone();
                    let mut c = code;
                    let mut names = Vec::new();
                    for _ in 0..D {
                        let (name, bytes) = ACTIONS[c % n];
                        s.extend_from_slice(bytes);
                        names.push(name);
                        c /= n;
                    }
                    match run_script(&s) {
                        Ok(o) => t.count(&o),
                        Err(v) => panic!(
                            "P6 violated: {v:?}\nheader {h:?}, {prefix} nominal rounds, then {names:?}"
                        ),
                    }
                }
            }
        }
    });
    assert_eq!(t.scripts, 8 * total as u64);
    // Not vacuous: the 20-round prefixes are in Cyclic (a quarter of all runs).
    assert!(t.cyclic * 4 >= t.scripts, "{t:?}");
}
