//! The ESC register contract the DC maths relies on (Beckhoff Section II Tab. 95–118; see
//! docs/background/esc-registers.md §1–§3), as plain functions over `i128` with an explicit modulus.
//!
//! A DC ESC is either 64-bit or 32-bit (ESC Features 0x0008 bit 3). A 32-bit ESC keeps only the
//! low 32 bits of system time, offset and start time (REQ-CONV-003).

/// Width in bits of a DC ESC's system time.
pub fn modulus(width_bits: u32) -> i128 {
    1i128 << width_bits
}

/// Reduces `x` into `[0, 2^width)`.
pub fn wrap(x: i128, width_bits: u32) -> i128 {
    x.rem_euclid(modulus(width_bits))
}

/// Byte width of the System Time Offset (0x0920) write for an ESC of `width_bits` (REQ-DC-040).
pub fn offset_register_bytes(width_bits: u32) -> usize {
    if width_bits == 64 {
        8
    } else {
        4
    }
}

/// Byte width of the Start Time (0x0990) write for an ESC of `width_bits`.
pub fn start_time_register_bytes(width_bits: u32) -> usize {
    offset_register_bytes(width_bits)
}

/// Local copy of system time: `local + offset (mod 2^width)` (Tab. 101, REQ-CONV-004).
pub fn local_copy(local: i128, offset: i128, width_bits: u32) -> i128 {
    wrap(local + offset, width_bits)
}

/// An ECAT read of 0x0910: the local copy latched at the frame's start of frame, minus the System
/// Time Delay, i.e. "the time when the frame passed the reference clock" (Tab. 100).
pub fn ecat_read_system_time(
    local_at_sof: i128,
    offset: i128,
    delay: i128,
    width_bits: u32,
) -> i128 {
    wrap(local_at_sof + offset - delay, width_bits)
}

/// The time loop's input for an ECAT write of `received` to 0x0910 (Section I §9.1.4):
/// `Δt = (local + offset − delay) − received` on the lower 32 bits, read as a signed 32-bit value.
/// Positive: the slave's copy is ahead (REQ-CONV-006).
pub fn time_loop_delta(local_at_sof: i128, offset: i128, delay: i128, received: i128) -> i128 {
    let d = wrap(local_at_sof + offset - delay - received, 32);
    if d >= 1i128 << 31 {
        d - (1i128 << 32)
    } else {
        d
    }
}

/// Encoding of 0x092C: bits 30..0 `min(|Δt|, 2^31 − 1)`, bit 31 set when `Δt < 0` (Tab. 103).
pub fn system_time_difference_encode(delta: i128) -> u32 {
    let mag = delta.abs().min((1i128 << 31) - 1);
    let sign = if delta < 0 { 1i128 << 31 } else { 0 };
    u32::try_from(mag + sign).unwrap_or(u32::MAX)
}
