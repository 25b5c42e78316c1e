//! Property test for REQ-PROP P6 (`ecdc_proofs::machine::run_script`): random scripts of
//! replies, garbage, loss, reordering and commands never make the DC machine panic, break
//! index matching, step 0x0920 of a running slave or write a wrong register width.
//!
//! verifies: P6

use ecdc_proofs::machine::{run_script, Outcome};
use proptest::prelude::*;

/// Scripts biased towards "mostly plausible" replies so the deep states are reached too.
fn script() -> impl Strategy<Value = Vec<u8>> {
    let op = prop_oneof![
        4 => Just(vec![1u8]),                                     // transmit
        4 => proptest::collection::vec(any::<u8>(), 1..12).prop_map(|mut v| { v.insert(0, 3); v }), // reply
        1 => proptest::collection::vec(any::<u8>(), 1..12).prop_map(|mut v| { v.insert(0, 4); v }), // late reply
        1 => proptest::collection::vec(any::<u8>(), 1..40).prop_map(|mut v| { v.insert(0, 5); v }), // garbage
        1 => proptest::collection::vec(any::<u8>(), 2..3).prop_map(|mut v| { v.insert(0, 0); v }),  // time
        1 => Just(vec![6u8]),                                     // into caller frame
        1 => any::<u8>().prop_map(|b| vec![7u8, b]),              // command / jump to deadline
    ];
    (
        proptest::collection::vec(any::<u8>(), 4..5),
        proptest::collection::vec(op, 0..200),
    )
        .prop_map(|(head, ops)| head.into_iter().chain(ops.into_iter().flatten()).collect())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 400, ..ProptestConfig::default() })]
    /// P6 on random scripts.
    // verifies: P6
    #[test]
    fn machine_script_holds(s in script()) {
        let r = run_script(&s);
        prop_assert!(r.is_ok(), "{:?}", r);
    }
}

/// The next state of the xorshift64 generator the script tests draw their bytes from.
fn xorshift(x: &mut u64) -> u64 {
    *x ^= *x << 13;
    *x ^= *x >> 7;
    *x ^= *x << 17;
    *x
}

/// P6 on fully arbitrary bytes (no structure at all).
// verifies: P6
#[test]
fn machine_script_arbitrary_bytes() {
    let mut x: u64 = 0x1234_5678_9ABC_DEF0;
    for _ in 0..300 {
        let mut v = Vec::new();
        for _ in 0..600 {
            v.push(xorshift(&mut x) as u8);
        }
        assert_eq!(run_script(&v).map(|_| ()), Ok(()));
    }
}

/// The scripts are not vacuous: with modelled replies (a consistent line of ideal slaves, all
/// INIT) the machine gets through offsets, drift gate and SYNC into `Cyclic`; with every slave
/// in OP it reaches `Cyclic` too but never writes 0x0920.
#[test]
fn modelled_script_reaches_cyclic() {
    for (al, expect_writes) in [(0u8, true), (6u8, false)] {
        // AL states, model size byte (3 -> 4 slaves), then transmit + modelled reply, repeated.
        let mut s = vec![al, al, al, al, 3];
        for _ in 0..200 {
            s.extend_from_slice(&[1, 3, 0, 0x80, 0, 100, 0]);
        }
        let o: Outcome = run_script(&s).expect("no violation");
        assert!(o.reached_cyclic, "{o:?}");
        assert_eq!(o.offset_writes > 0, expect_writes, "{o:?}");
    }
}

/// Random scripts over modelled replies mixed with loss, garbage and reordering.
#[test]
fn modelled_random_scripts() {
    let mut x: u64 = 0x0DDB_A11C_AFE0_0001;
    let mut cyclic = 0;
    for _ in 0..200 {
        let mut s = Vec::new();
        for _ in 0..5 {
            s.push(xorshift(&mut x) as u8);
        }
        for _ in 0..300 {
            xorshift(&mut x);
            match x % 16 {
                0 => s.extend_from_slice(&[5, 20, 0]),
                1 => s.extend_from_slice(&[4, 0, 0x80]),
                2 => s.extend_from_slice(&[0, (x >> 8) as u8, 0]),
                3 => s.extend_from_slice(&[7, 3]),
                4 => s.extend_from_slice(&[3, 0, 0x10, 2]),
                5 => s.push(6),
                _ => s.extend_from_slice(&[1, 3, 0, 0x80]),
            }
        }
        let o = run_script(&s).expect("no violation");
        cyclic += usize::from(o.reached_cyclic);
    }
    assert!(cyclic > 20, "only {cyclic} of 200 scripts reached Cyclic");
}

/// The Kani harness body under the shim (random 8-byte scripts; a random test, not a proof).
#[test]
fn kani_harness_under_shim() {
    let r = ecdc_proofs::kani_shim::run(
        0xECDC_0600,
        5_000,
        ecdc_proofs::machine::kani_machine_script,
    );
    assert!(r.passed > 4_000, "{r:?}");
}
