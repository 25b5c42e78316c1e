//! Property tests for P3 (delay) and P4 (offset) and the SYNC start, calling the same bodies as
//! the Kani harnesses (`proofs/src/dc_math.rs`). Random tests, not proofs.
//!
//! verifies: P3, P4

use ecdc_core::dc::port::PortSet;
use ecdc_core::dc::topology::{Latches, SlaveSample};
use ecdc_proofs::dc_math::{self, Line};
use proptest::prelude::*;

fn cfg(cases: u32) -> ProptestConfig {
    ProptestConfig {
        cases,
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

proptest! {
    #![proptest_config(cfg(2000))]

    /// P3 on the fork shape with per-ESC t_Diff.
    // verifies: P3
    #[test]
    fn p3_fork(
        t_f in 0u16..=2_000,
        t_diff in prop::array::uniform4(0u16..=1_000),
        cable in prop::array::uniform4(0u16..=10_000),
        phase in prop::array::uniform4(prop_oneof![any::<u32>(), (u32::MAX - 100_000)..=u32::MAX]),
    ) {
        dc_math::p3_fork(&dc_math::Fork { t_f, t_diff, cable, phase });
    }

    /// P3 on lines of up to 16 ESCs, any clock phases (wraps anywhere).
    // verifies: P3
    #[test]
    fn p3_line(
        n in 1usize..=16,
        t_f in 0u16..=2_000,
        t_diff in 0u16..=1_000,
        cable in prop::array::uniform16(0u16..=10_000),
        phase in prop::array::uniform16(prop_oneof![any::<u32>(), (u32::MAX - 200_000)..=u32::MAX]),
    ) {
        dc_math::p3_line(&Line::<16> { n, t_f, t_diff, cable, phase });
    }

    /// P3 robustness: arbitrary DL status bits and latch values never panic.
    // verifies: P3
    #[test]
    fn p3_arbitrary(
        raw in prop::collection::vec((0u8..16, any::<[u32; 4]>(), any::<u64>(), any::<bool>(), -500i32..500), 0..8),
        reference in 0usize..8,
    ) {
        let samples: Vec<SlaveSample> = raw
            .iter()
            .map(|(ports, t, epu, dc, d)| SlaveSample {
                ports: PortSet::from_bits(*ports),
                latches: dc.then(|| Latches::from_raw(*t, *epu)),
                t_diff: *d,
            })
            .collect();
        dc_math::p3_arbitrary_latches(&samples, reference);
    }

    /// P4 over the whole input space.
    // verifies: P4
    #[test]
    fn p4_offset(master in any::<u64>(), delay in any::<i64>(), local in any::<u64>(), bits64 in any::<bool>()) {
        dc_math::p4_offset(master, delay, local, bits64);
    }

    #[test]
    fn p4_entry_local(epu in any::<u64>(), stamp in any::<u32>(), port in any::<u8>()) {
        dc_math::p4_entry_local(epu, stamp, port);
    }

    #[test]
    fn sync_start(
        now in prop_oneof![any::<u64>(), 0u64..1 << 62],
        margin in prop_oneof![any::<u64>(), 0u64..3_000_000_000],
        period in prop_oneof![Just(0u64), 1u64..5_000_000, any::<u64>()],
        shift in prop_oneof![any::<i64>(), -5_000_000i64..5_000_000],
    ) {
        dc_math::sync_start(now, margin, period, shift);
    }
}

proptest! {
    #![proptest_config(cfg(2000))]

    /// The realistic region of the SYNC start (so the `Ok` branch is exercised, not only errors).
    #[test]
    fn sync_start_realistic(
        now in 0u64..1 << 62,
        margin in 0u64..1_000_000_000,
        period in 1u64..5_000_000,
        shift in 0i64..5_000_000,
    ) {
        let start = ecdc_core::dc::sync::start_time(ecdc_core::time::SystemTime(now), margin, period, shift);
        prop_assert!(start.is_ok());
        dc_math::sync_start(now, margin, period, shift);
    }
}

proptest! {
    #![proptest_config(cfg(300))]

    /// P3 on generated trees (lines, forks, crosses, any entry port, non-DC ESCs, 32/64-bit).
    // verifies: P3
    #[test]
    fn p3_tree(seed in any::<u64>(), count in 1usize..=64, shape in 0u8..4, non_dc in 0u64..=30) {
        dc_math::p3_tree_generated(seed, count, shape, non_dc);
    }
}

/// The Kani harnesses, run with random inputs through the shim (not proofs): each must pass and
/// reach its `cover!` conditions.
#[test]
fn kani_harnesses_random() {
    use ecdc_proofs::kani_shim::run;
    for (name, harness, covers) in [
        (
            "p3_line",
            dc_math::kani_p3_line as fn(),
            &["wrap inside the latch", "three slaves with t_Diff"][..],
        ),
        (
            "p3_fork",
            dc_math::kani_p3_fork,
            &[
                "branch ESCs of different types",
                "reference wraps inside the latch",
            ][..],
        ),
        (
            "p4_offset",
            dc_math::kani_p4_offset,
            &["slave before the reference"][..],
        ),
        (
            "p4_entry_local",
            dc_math::kani_p4_entry_local,
            &["entry port other than 0"][..],
        ),
        ("sync_start", dc_math::kani_sync_start, &["zero period"][..]),
    ] {
        let report = run(0x00DC_0000, 3_000, harness);
        assert!(
            report.passed > 100,
            "{name}: only {} runs passed",
            report.passed
        );
        for c in covers {
            assert!(
                report.covered.contains_key(c),
                "{name}: cover {c:?} never reached"
            );
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(3000))]

    /// The P3 line transcription proved by SMT (`dc_math::p3_line_kernel`) equals
    /// `delay::compute` on 1–3 slave lines: physically generated stamps (any phase, so wraps
    /// inside the latch) and arbitrary stamps (errors must coincide).
    // verifies: P3
    #[test]
    fn p3_line_kernel_matches_compute(n in 1usize..=3, phase in any::<[u32; 3]>(),
                                      x1 in 0u32..1_000_000, hop in 0u32..1_000_000,
                                      td in 0i32..2_000, raw in any::<([u32; 3], [u32; 3], [i32; 3])>(),
                                      physical in any::<bool>()) {
        if physical {
            let x0 = x1 + 2 * hop;
            let p0 = phase;
            let p1 = [phase[0].wrapping_add(x0), phase[1].wrapping_add(x1), phase[2]];
            prop_assert!(dc_math::p3_line_kernel_matches(n, p0, p1, [td; 3]));
        } else {
            let _ = dc_math::p3_line_kernel_matches(n, raw.0, raw.1, raw.2);
        }
    }
}
