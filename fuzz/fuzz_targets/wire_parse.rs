//! Fuzz target: arbitrary bytes as an Ethernet frame and as a bare EtherCAT payload (UDP).
//! Body: `ecdc_proofs::wire::parse_any` (P1, REQ-WIRE-020..022): no panic, every datagram span
//! inside the input, iter / iter_mut / offsets agree, new_checked agrees with the walk.
//! verifies: REQ-WIRE-020, REQ-WIRE-021, REQ-WIRE-022
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    ecdc_proofs::wire::parse_any(data);
});
