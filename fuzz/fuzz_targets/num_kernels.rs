//! Fuzz target for REQ-PROP P2 and REQ-TIME-003..013: the width-generic kernels of
//! `ecdc_core::num` at 32 and 64 bits (wrapping difference, earliest port, extend, phase, fold,
//! clamp, saturate, halve, sign-magnitude, low32) against their i128 definitions.
//! Bodies: `ecdc_proofs::num::prop_*`. The 8/16-bit widths are covered exhaustively by
//! `proofs/tests/exhaustive.rs`, so they are not fuzzed here.
//! verifies: REQ-TIME-003, REQ-TIME-004, REQ-TIME-005, REQ-TIME-006, REQ-TIME-007, REQ-TIME-008, REQ-TIME-009, REQ-TIME-010, REQ-TIME-011, REQ-TIME-012, REQ-TIME-013
#![no_main]

use arbitrary::Arbitrary;
use ecdc_proofs::num as p;
use libfuzzer_sys::fuzz_target;

#[derive(Debug, Arbitrary)]
struct Input {
    a32: u32,
    b32: u32,
    a64: u64,
    b64: u64,
    delta32: i32,
    delta64: i64,
    offsets32: [u32; 4],
    offsets64: [u64; 4],
    active: [bool; 4],
    kbits: u8,
    x32: i32,
    lo32: i32,
    hi32: i32,
    x64: i64,
    lo64: i64,
    hi64: i64,
}

fuzz_target!(|i: Input| {
    // Wrapping difference: true-difference form (|delta| < 2^(N−1) else skipped) and total form.
    p::prop_wrapping_diff_true::<u32>(i128::from(i.a64), i128::from(i.delta32));
    p::prop_wrapping_diff_true::<u64>(i128::from(i.a64), i128::from(i.delta64));
    p::prop_wrapping_diff_any::<u32>(i.a32, i.b32);
    p::prop_wrapping_diff_any::<u64>(i.a64, i.b64);
    // Earliest of four ports: inside the half-range window (offsets masked) and anywhere.
    p::prop_earliest_true_min::<u32, 4>(i.a32, i.offsets32.map(|o| o & 0x7FFF_FFFF), i.active);
    p::prop_earliest_true_min::<u64, 4>(i.a64, i.offsets64.map(|o| o >> 1), i.active);
    p::prop_earliest_any::<u32, 4>(i.offsets32, i.active);
    p::prop_earliest_any::<u64, 4>(i.offsets64, i.active);
    // Extension of a k-bit stamp near a reference, phase and fold.
    p::prop_extend_near::<u64>(i.b64, i.a64, u32::from(i.kbits % 64));
    p::prop_extend_near::<u32>(i.b32, i.a32, u32::from(i.kbits % 32));
    p::prop_phase::<u32>(i.a32, i.b32);
    p::prop_phase::<u64>(i.a64, i.b64);
    p::prop_fold::<u32>(i.x32, i.b32);
    p::prop_fold::<u64>(i.x64, i.b64);
    // Clamp, saturate, halve.
    p::prop_clamp::<u32>(i.x32, i.lo32, i.hi32);
    p::prop_clamp::<u64>(i.x64, i.lo64, i.hi64);
    p::prop_clamp_magnitude::<u32>(i.x32, i.b32);
    p::prop_clamp_magnitude::<u64>(i.x64, i.b64);
    p::prop_saturating::<u32>(i.x32, i.lo32);
    p::prop_saturating::<u64>(i.x64, i.lo64);
    p::prop_half::<u32>(i.x32);
    p::prop_half::<u64>(i.x64);
    // Sign-magnitude (0x092C shape) and low 32 bits.
    p::prop_sign_magnitude::<u32>(i.x32, i.a32);
    p::prop_sign_magnitude::<u64>(i.x64, i.a64);
    p::prop_low32(i.a64);
});
