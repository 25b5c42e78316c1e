//! Fuzz target: the `Display` impls of frames, datagrams and errors on arbitrary bytes, as a
//! bare EtherCAT payload and after a 14-byte Ethernet header.
//! Body: `ecdc_proofs::wire::display_any` (REQ-WIRE-020). Kept apart from `wire_parse`
//! because formatting allocates and slows that target down.
//! verifies: REQ-WIRE-020
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    ecdc_proofs::wire::display_any(data);
    if let Some(payload) = data.get(14..) {
        ecdc_proofs::wire::display_any(payload);
    }
});
