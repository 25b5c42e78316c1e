//! Fuzz target for the register decoders (REQ-WIRE-071..074): ESC features 0x0008, DL status
//! 0x0110, System Time Difference 0x092C (sign-magnitude) and the receive-time block
//! 0x0900..0x091F, each from arbitrary bytes as a slave might return them, plus the word-level
//! bodies on the first words. Body: `ecdc_proofs::wire::registers_target` (replayed on stable by
//! proofs/tests/exhaustive_fuzz_inputs.rs).
//! verifies: REQ-WIRE-071, REQ-WIRE-072, REQ-WIRE-073, REQ-WIRE-074
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| ecdc_proofs::wire::registers_target(data));
