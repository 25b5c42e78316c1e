//! Fuzz target for the register decoders (REQ-WIRE-071..074): ESC features 0x0008, DL status
//! 0x0110, System Time Difference 0x092C (sign-magnitude) and the receive-time block
//! 0x0900..0x091F, each from arbitrary bytes as a slave might return them, plus the word-level
//! bodies on the first words. Bodies: `ecdc_proofs::wire::{register_bytes_any,
//! esc_features_word, dl_status_word, system_time_difference}`.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    ecdc_proofs::wire::register_bytes_any(data);
    // Every suffix start too, so short and misaligned reads are exercised from one input.
    for start in 1..data.len().min(40) {
        if let Some(rest) = data.get(start..) {
            ecdc_proofs::wire::register_bytes_any(rest);
        }
    }
    let w = |at: usize| {
        data.get(at..at + 2)
            .map(|b| u16::from_le_bytes([b[0], b[1]]))
    };
    if let (Some(a), Some(b)) = (w(0), w(2)) {
        ecdc_proofs::wire::esc_features_word(a);
        ecdc_proofs::wire::dl_status_word(b);
        let raw = u32::from(a) | (u32::from(b) << 16);
        let ns = data
            .get(4..12)
            .and_then(|s| s.try_into().ok())
            .map_or(i64::from(raw), i64::from_le_bytes);
        ecdc_proofs::wire::system_time_difference(raw, ns);
    }
});
