//! Initial System Time Offset (0x0920) with the propagation delay folded in (REQ-DC-021..025).
//!
//! The master samples its clock `M` just before the latching write to 0x0900 (machine's job,
//! REQ-DC-002). ecdc defines the reference clock's system time at the instant the latch frame
//! passes it as `M`. The frame reaches slave `s` a propagation delay `D_s` later, so at that
//! instant the reference's system time is `M + D_s`; the offset is chosen so that `s`'s local
//! copy of system time reads exactly that:
//!
//! ```text
//!   offset_s = (M + D_s) − local_s(entry)        (mod 2^64, or 2^32 on a 32-bit slave)
//!   ⇒ local_s(T) + offset_s = M + (T − T_ref)    for every true time T (no drift)
//! ```
//!
//! SOEM, IgH and ethercrab write `M − local` instead and leave every slave `D_s` behind for the
//! drift loop to remove; folding `D_s` in starts the loop at zero error (docs/background/masters-dc.md §9 item 5).
//! Seed 000 eq. 24 and seed 003 eq. 5 are the `D_s = 0` case (eq. 24 with its sign corrected,
//! see `spec::seed000`).
//!
//! `local_s(entry)` is the 64-bit local time at which the frame entered `s`: the EPU stamp 0x0918
//! moved back by the (wrapping, 32-bit) time from the entry port's stamp to the EPU stamp, which
//! is 0 when the frame enters through port 0 (REQ-DC-022).

use super::port::Port;
use super::topology::Latches;
use crate::num::{low32, Word};
use crate::time::SystemTime;

/// Width of a slave's DC clock (ESC features 0x0008 bit 3).
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::offset::ClockWidth;
/// use ecdc_core::wire::register::EscFeatures;
///
/// // ESC features 0x000C: DC with 64-bit system time.
/// let width = ClockWidth::from_features(0x000C);
/// assert_eq!(width, ClockWidth::Bits64);
/// assert_eq!(width.bytes(), EscFeatures(0x000C).dc_time_width());
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ClockWidth {
    /// 32-bit system time: 0x0910, 0x0920 and 0x0990 are 4 bytes wide.
    Bits32,
    /// 64-bit system time: 0x0910, 0x0920 and 0x0990 are 8 bytes wide.
    Bits64,
}

impl ClockWidth {
    /// From ESC features 0x0008 (bit 3 set = 64-bit).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::offset::ClockWidth;
    ///
    /// assert_eq!(ClockWidth::from_features(0x000C), ClockWidth::Bits64);
    /// assert_eq!(ClockWidth::from_features(0x0004), ClockWidth::Bits32);
    /// ```
    pub const fn from_features(features: u16) -> ClockWidth {
        if features & 0x0008 != 0 {
            ClockWidth::Bits64
        } else {
            ClockWidth::Bits32
        }
    }

    /// Register width in bytes (4 or 8).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::offset::ClockWidth;
    ///
    /// assert_eq!(ClockWidth::Bits32.bytes(), 4);
    /// assert_eq!(ClockWidth::Bits64.bytes(), 8);
    /// ```
    pub const fn bytes(self) -> usize {
        match self {
            ClockWidth::Bits32 => 4,
            ClockWidth::Bits64 => 8,
        }
    }
}

/// A little-endian register image of exactly the slave's width: write `as_slice()` as the
/// datagram data, never more (REQ-CONV-003).
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::offset::{ClockWidth, WidthValue};
///
/// // The datagram data for 0x0920 on a 32-bit slave: 4 bytes, never 8.
/// let image = WidthValue::new(0x1_0000_0500, ClockWidth::Bits32).to_register();
/// assert_eq!(image.as_slice(), [0x00, 0x05, 0x00, 0x00]);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct RegisterBytes {
    buf: [u8; 8],
    len: u8,
}

impl RegisterBytes {
    /// A 4-byte image.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::offset::RegisterBytes;
    ///
    /// assert_eq!(
    ///     RegisterBytes::u32(1_000_000).as_slice(),
    ///     1_000_000u32.to_le_bytes()
    /// );
    /// ```
    pub const fn u32(v: u32) -> RegisterBytes {
        let b = v.to_le_bytes();
        RegisterBytes {
            buf: [b[0], b[1], b[2], b[3], 0, 0, 0, 0],
            len: 4,
        }
    }

    /// An 8-byte image.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::offset::RegisterBytes;
    ///
    /// assert_eq!(RegisterBytes::u64(1).as_slice(), [1, 0, 0, 0, 0, 0, 0, 0]);
    /// ```
    pub const fn u64(v: u64) -> RegisterBytes {
        RegisterBytes {
            buf: v.to_le_bytes(),
            len: 8,
        }
    }

    /// The bytes to write (4 or 8).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::offset::RegisterBytes;
    ///
    /// assert_eq!(RegisterBytes::u32(7).as_slice().len(), 4);
    /// assert_eq!(RegisterBytes::u64(7).as_slice().len(), 8);
    /// ```
    pub fn as_slice(&self) -> &[u8] {
        self.buf.get(..usize::from(self.len)).unwrap_or(&[])
    }
}

/// A time-like register value of a DC slave's width (0x0920 offset, 0x0990 start time).
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::offset::{ClockWidth, WidthValue};
///
/// let v = WidthValue::new(0x1_2345_6789, ClockWidth::Bits32);
/// assert_eq!(v, WidthValue::Bits32(0x2345_6789));
/// assert_eq!(v.as_u64(), 0x2345_6789);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum WidthValue {
    /// For a 32-bit slave: the low 32 bits.
    Bits32(u32),
    /// For a 64-bit slave.
    Bits64(u64),
}

impl WidthValue {
    /// The value reduced to `width`.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::offset::{ClockWidth, WidthValue};
    ///
    /// assert_eq!(
    ///     WidthValue::new(0x1_0000_0001, ClockWidth::Bits64),
    ///     WidthValue::Bits64(0x1_0000_0001)
    /// );
    /// assert_eq!(
    ///     WidthValue::new(0x1_0000_0001, ClockWidth::Bits32),
    ///     WidthValue::Bits32(1)
    /// );
    /// ```
    pub fn new(value: u64, width: ClockWidth) -> WidthValue {
        match width {
            ClockWidth::Bits32 => WidthValue::Bits32(low32(value)),
            ClockWidth::Bits64 => WidthValue::Bits64(value),
        }
    }

    /// The register image, exactly 4 or 8 bytes.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::offset::WidthValue;
    ///
    /// assert_eq!(
    ///     WidthValue::Bits64(0x0102).to_register().as_slice(),
    ///     [2, 1, 0, 0, 0, 0, 0, 0]
    /// );
    /// assert_eq!(
    ///     WidthValue::Bits32(0x0102).to_register().as_slice(),
    ///     [2, 1, 0, 0]
    /// );
    /// ```
    pub fn to_register(self) -> RegisterBytes {
        match self {
            WidthValue::Bits32(v) => RegisterBytes::u32(v),
            WidthValue::Bits64(v) => RegisterBytes::u64(v),
        }
    }

    /// The value zero-extended to 64 bits.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::offset::WidthValue;
    ///
    /// assert_eq!(WidthValue::Bits32(u32::MAX).as_u64(), 0xFFFF_FFFF);
    /// ```
    pub fn as_u64(self) -> u64 {
        match self {
            WidthValue::Bits32(v) => u64::from(v),
            WidthValue::Bits64(v) => v,
        }
    }
}

/// REQ-DC-022: the 64-bit local time at which the latch frame entered the slave through
/// `entry`. Exact whenever the EPU stamp follows the entry stamp by less than 2^32 ns (it
/// follows by at most one round trip through the slave's subtree).
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::{offset, port::Port, topology::Latches};
///
/// // Entered through port 1 at local time 0x5_0000_0100; the EPU stamped it 0x300 ns later.
/// let latches = Latches::from_raw([0x0000_0400, 0x0000_0100, 0, 0], 0x5_0000_0400);
/// assert_eq!(offset::entry_local_time(&latches, Port::P1), 0x5_0000_0100);
/// // Through port 0 the EPU stamp is the entry time itself.
/// assert_eq!(offset::entry_local_time(&latches, Port::P0), 0x5_0000_0400);
/// ```
pub fn entry_local_time(latches: &Latches, entry: Port) -> u64 {
    // = epu − (low32(epu) − entry stamp mod 2^32); the kernel is SMT-proved (P4).
    crate::num::entry_local(latches.epu, u64::from(latches.at(entry).raw()))
}

/// REQ-DC-021, REQ-DC-023: the System Time Offset for a slave whose latch frame entered at local time
/// `entry_local` (see [`entry_local_time`]), `delay_ns` after it passed the reference clock (the
/// same value written to 0x0928; negative before the reference), when the master sampled
/// `master_time` just before the latch. For the reference itself `delay_ns` is 0.
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::offset::{self, ClockWidth};
/// use ecdc_core::time::SystemTime;
///
/// // The master's clock read 1 s (since 2000-01-01) just before the latch; the frame
/// // reached the slave 500 ns after the reference clock, at the slave's local time 90 000.
/// let master = SystemTime::from_nanos(1_000_000_000);
/// let off = offset::initial_offset(master, 500, 90_000, ClockWidth::Bits64);
/// // The slave's system time at that instant = the reference's then.
/// assert_eq!(90_000u64.wrapping_add(off.as_u64()), 1_000_000_500);
/// assert_eq!(off.to_register().as_slice().len(), 8);
/// ```
pub fn initial_offset(
    master_time: SystemTime,
    delay_ns: i64,
    entry_local: u64,
    width: ClockWidth,
) -> WidthValue {
    let offset = initial_offset_word::<u64>(
        master_time.as_nanos(),
        u64::from_signed(delay_ns),
        entry_local,
        width,
    );
    WidthValue::new(offset, width)
}

/// REQ-DC-021, REQ-DC-023: the arithmetic of [`initial_offset`], written once against
/// [`Word`] so the P4 SMT proof runs this code: `(master + delay) − entry_local` modulo 2^N
/// (`delay` two's complement), reduced to the low 32 bits for a 32-bit slave. `initial_offset`
/// runs it on `u64`; the reduction makes its `WidthValue::new` a plain type conversion.
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::offset::{self, ClockWidth, WidthValue};
/// use ecdc_core::time::SystemTime;
///
/// let w =
///     offset::initial_offset_word::<u64>(1_000_000_000, 500, 0x1_0000_0000, ClockWidth::Bits32);
/// assert!(w <= u64::from(u32::MAX)); // reduced for a 32-bit slave
/// let v = offset::initial_offset(
///     SystemTime(1_000_000_000),
///     500,
///     0x1_0000_0000,
///     ClockWidth::Bits32,
/// );
/// assert_eq!(WidthValue::Bits32(w as u32), v);
/// ```
#[inline]
pub fn initial_offset_word<W: Word>(master: W, delay: W, entry_local: W, width: ClockWidth) -> W {
    let offset = crate::num::offset_to(master.wrapping_add(delay), entry_local);
    match width {
        ClockWidth::Bits64 => offset,
        ClockWidth::Bits32 => offset.bit_and(W::lit(1).shl(32).wrapping_sub(W::lit(1))),
    }
}

/// REQ-DC-024: re-offset without a new latch (IgH style): given the offset currently in 0x0920
/// and a system time read back from the slave when the reference's system time was
/// `reference_time`, the offset that removes the difference. Computed modulo the slave's width.
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::offset::{self, WidthValue};
/// use ecdc_core::time::SystemTime;
///
/// // The slave's system time read 1 000 050 while the reference read 1 000 000: 50 ns ahead.
/// let current = WidthValue::Bits64(200);
/// let new = offset::corrected_offset(current, 1_000_050, SystemTime(1_000_000));
/// assert_eq!(new, WidthValue::Bits64(150));
/// ```
pub fn corrected_offset(
    current: WidthValue,
    read_system_time: u64,
    reference_time: SystemTime,
) -> WidthValue {
    let (read, reference) = (read_system_time, reference_time.as_nanos());
    match current {
        WidthValue::Bits32(v) => WidthValue::Bits32(crate::num::corrected_offset(
            v,
            low32(read),
            low32(reference),
        )),
        WidthValue::Bits64(v) => {
            WidthValue::Bits64(crate::num::corrected_offset(v, read, reference))
        }
    }
}

/// REQ-DC-030: whether 0x0920 may be written to a slave with this AL Status (0x0130). Only in
/// INIT, PRE-OP or BOOT: stepping the offset of a slave in SAFE-OP or OP moves its SYNC grid
/// under running outputs, which can make it miss SYNC pulses until a 32-bit clock wraps (~4 s)
/// or, on a 64-bit clock, forever (IgH Lambert patch 0009, docs/background/masters-dc.md §2.3 item 7). Unknown states
/// count as running.
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::offset::offset_write_permitted;
///
/// assert!(offset_write_permitted(0x0002)); // PRE-OP
/// assert!(!offset_write_permitted(0x0008)); // OP: would move a running SYNC grid
/// assert!(!offset_write_permitted(0x0000)); // unknown: treated as running
/// ```
pub const fn offset_write_permitted(al_status: u16) -> bool {
    matches!(al_status & 0x000F, 0x1..=0x3)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dc::topology::Latches;

    #[test]
    fn offset_makes_system_time_equal_reference_plus_delay() {
        let m = SystemTime(0x0123_4567_89AB_CDEF);
        for local in [0u64, 5, u64::MAX, 0xFFFF_FFFF_0000_0010] {
            for delay in [0i64, 1, 123_456, -77] {
                let off = initial_offset(m, delay, local, ClockWidth::Bits64).as_u64();
                assert_eq!(
                    local.wrapping_add(off),
                    m.wrapping_add_signed(delay).as_nanos()
                );
                let off32 = initial_offset(m, delay, local, ClockWidth::Bits32);
                assert_eq!(off32.to_register().as_slice().len(), 4);
                assert_eq!(
                    low32(local).wrapping_add(low32(off32.as_u64())),
                    m.wrapping_add_signed(delay).low32()
                );
            }
        }
    }

    /// `initial_offset` through the Word kernel equals the direct `SystemTime` computation it
    /// replaced, for both widths, on boundary and pseudo-random inputs.
    #[test]
    fn initial_offset_equals_direct_form() {
        let mut xs = [
            0u64,
            1,
            2,
            u64::MAX,
            u64::MAX - 1,
            1 << 63,
            (1 << 63) - 1,
            1 << 32,
            0xFFFF_FFFF,
        ]
        .to_vec();
        let mut seed = 0x9E37_79B9_7F4A_7C15u64;
        for _ in 0..40 {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            xs.push(seed >> (seed % 64));
        }
        for &m in &xs {
            for &d in &xs {
                for &l in &xs {
                    for width in [ClockWidth::Bits32, ClockWidth::Bits64] {
                        let target = SystemTime(m).wrapping_add_signed(d as i64);
                        let direct = WidthValue::new(target.as_nanos().wrapping_sub(l), width);
                        assert_eq!(initial_offset(SystemTime(m), d as i64, l, width), direct);
                    }
                }
            }
        }
    }

    #[test]
    fn entry_time_from_epu() {
        // Entry port 0: EPU stamp is the entry stamp.
        let l = Latches::from_raw([0x10, 0x500, 0, 0], 0x0000_0007_0000_0010);
        assert_eq!(entry_local_time(&l, Port::P0), 0x0000_0007_0000_0010);
        // Entry on port 1 before a wrap, EPU (port 0 return) after it.
        let l = Latches::from_raw([0x0000_0100, 0xFFFF_FF00, 0, 0], 0x0000_0008_0000_0100);
        assert_eq!(entry_local_time(&l, Port::P1), 0x0000_0007_FFFF_FF00);
    }

    #[test]
    fn register_widths_and_state_rule() {
        assert_eq!(RegisterBytes::u64(1).as_slice(), &[1, 0, 0, 0, 0, 0, 0, 0]);
        assert_eq!(RegisterBytes::u32(0x0403_0201).as_slice(), &[1, 2, 3, 4]);
        assert_eq!(ClockWidth::from_features(0x000C), ClockWidth::Bits64);
        assert_eq!(ClockWidth::from_features(0x0004), ClockWidth::Bits32);
        assert!(offset_write_permitted(0x0001));
        assert!(offset_write_permitted(0x0002));
        assert!(offset_write_permitted(0x0012)); // PRE-OP with error flag
        assert!(offset_write_permitted(0x0003));
        assert!(!offset_write_permitted(0x0004));
        assert!(!offset_write_permitted(0x0008));
        assert!(!offset_write_permitted(0x0000));
        let c = corrected_offset(
            WidthValue::Bits32(10),
            0x1_0000_0005,
            SystemTime(0x2_0000_0008),
        );
        assert_eq!(c, WidthValue::Bits32(13));
    }
}
