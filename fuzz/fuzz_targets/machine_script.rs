//! Fuzz target for REQ-PROP P6: an arbitrary byte script (time steps, transmissions, replies
//! with arbitrary WKC/data, late replies, garbage, foreign frames, start/reset) drives the DC
//! machine; any panic or violated property (index matching, 0x0920 on a running slave, wrong
//! register width, a foreign frame used) is a crash. Body: `ecdc_proofs::machine::check_script`.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    ecdc_proofs::machine::check_script(data);
});
