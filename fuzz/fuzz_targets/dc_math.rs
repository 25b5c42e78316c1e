//! Fuzz target for REQ-PROP P3 (delay) and P4 (offset), spec/req/dc.md: physically generated
//! lines, the fork and generated trees with arbitrary bounded port times must give exact,
//! non-negative, monotone delays; arbitrary latch values and DL status never panic; the offset
//! and entry-time widening hold for every input; SYNC start matches its i128 definition.
//! Bodies: `ecdc_proofs::dc_math::{p3_line, p3_fork, p3_tree_generated,
//! p3_arbitrary_latches_raw, p4_offset, p4_entry_local, sync_start}`.
#![no_main]

use arbitrary::Arbitrary;
use ecdc_proofs::dc_math::{self as p, Fork, Line};
use libfuzzer_sys::fuzz_target;

#[derive(Debug, Arbitrary)]
struct Input {
    // P3 line / fork: bounds as in proofs/tests/dc_math.rs (t_F ≤ 2 µs, t_Diff ≤ 1 µs,
    // cables ≤ 10 µs), applied by reduction.
    n: u8,
    t_f: u16,
    t_diff: [u16; 4],
    cable: [u16; 16],
    phase: [u32; 16],
    // P3 generated tree.
    tree_seed: u64,
    tree_count: u8,
    tree_shape: u8,
    tree_non_dc: u8,
    // P3 robustness: (DL port bits, port stamps, EPU stamp, has DC, t_Diff) per slave.
    latches: Vec<(u8, [u32; 4], u64, bool, i32)>,
    reference: u8,
    // P4 and SYNC start.
    master: u64,
    delay_ns: i64,
    entry_local: u64,
    bits64: bool,
    entry_port: u8,
    margin: u64,
    period: u64,
    shift: i64,
}

fuzz_target!(|i: Input| {
    let line = Line::<16> {
        n: 1 + usize::from(i.n % 16),
        t_f: i.t_f % 2_001,
        t_diff: i.t_diff[0] % 1_001,
        cable: i.cable.map(|c| c % 10_001),
        phase: i.phase,
    };
    p::p3_line(&line);
    let mut cable4 = [0u16; 4];
    let mut phase4 = [0u32; 4];
    cable4.copy_from_slice(&i.cable[..4]);
    phase4.copy_from_slice(&i.phase[..4]);
    p::p3_fork(&Fork {
        t_f: i.t_f % 2_001,
        t_diff: i.t_diff.map(|d| d % 1_001),
        cable: cable4.map(|c| c % 10_001),
        phase: phase4,
    });
    p::p3_tree_generated(
        i.tree_seed,
        usize::from(i.tree_count % 64) + 1,
        i.tree_shape,
        u64::from(i.tree_non_dc % 31),
    );
    let n = i.latches.len().min(10); // a little beyond the capacity of 8
    p::p3_arbitrary_latches_raw(&i.latches[..n], usize::from(i.reference));
    // Delay bounded as in the Kani harness (|delay| < 2^40 ns).
    p::p4_offset(i.master, i.delay_ns % (1 << 40), i.entry_local, i.bits64);
    p::p4_entry_local(i.entry_local, i.master as u32, i.entry_port);
    p::sync_start(i.master, i.margin, i.period, i.shift);
});
