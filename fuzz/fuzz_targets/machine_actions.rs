//! Fuzz target for REQ-PROP P6 through the model checker's world (`ecdc_proofs::model`): bytes
//! choose a line of 1–4 ideal DC slaves and their AL states, then one input or fault per byte
//! (transmit, deliver newest/older/duplicate, wrong WKC, loss, junk, foreign frame with our
//! index, tick, deadline, slave reset, port-time wrap, reset, start, re-measure). Any panic or
//! violated check (frame properties, index matching, deadline, bounded liveness) is a crash.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    ecdc_proofs::model::check_actions(data);
});
