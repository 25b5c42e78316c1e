//! SYNC0/SYNC1 start time, cycle registers and activation word (REQ-DC-050..055).
//!
//! One start time for every slave, computed once from the reference clock's 64-bit system time
//! (a 32-bit reference's time widened near the master's estimate, [`reference_now`]) on a grid
//! anchored at the EtherCAT epoch: `start = first multiple of the grid period at or after
//! now + margin, plus shift`. Because all DC slaves share system time, that one value lands on
//! the same instant everywhere; 32-bit slaves get its low 32 bits, which is the same instant in
//! their 32-bit system time. This avoids per-slave reads of 0x0910 (SOEM #792), the 64-bit vs
//! 32-bit phase mismatch (SOEM #354) and a random phase anchor (linuxcnc-ethercat #465).
//!
//! Register widths are exact (REQ-CONV-003): 0x0990 is 8 bytes on 64-bit slaves and 4 on 32-bit
//! ones, 0x09A0 and 0x09A4 are 4 bytes each (ethercrab writes u64 there and overruns into the
//! latch control registers), 0x0980 and 0x0981 one byte each.

use super::offset::{ClockWidth, RegisterBytes, WidthValue};
use crate::time::SystemTime;

/// Largest lead of the start time over the reference's current time: a 32-bit slave (and any
/// ESC with the ~2.1 s near-future window, 0x0981 bit 6) accepts only starts less than 2^31 ns
/// ahead (Section II Tab. 110; docs/background/esc-registers.md §2). ecdc choice: enforce it for every slave so one
/// start value is valid on all of them.
pub const MAX_START_LEAD_NS: u64 = 1 << 31;

/// Why a SYNC start could not be computed.
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::sync::{self, SyncError};
/// use ecdc_core::time::SystemTime;
///
/// assert_eq!(
///     sync::start_time(SystemTime(0), 100_000_000, 0, 0),
///     Err(SyncError::ZeroCycle)
/// );
/// assert_eq!(
///     sync::start_time(SystemTime(0), 3_000_000_000, 1_000_000, 0),
///     Err(SyncError::StartOutOfWindow) // 3 s ahead: a 32-bit slave would not accept it
/// );
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum SyncError {
    /// The grid period (cycle) is 0.
    ZeroCycle,
    /// The start lies at or before the reference's current time (a negative shift larger than
    /// the margin) or at least [`MAX_START_LEAD_NS`] ahead of it.
    StartOutOfWindow,
    /// `now + margin + period + shift` does not fit the 64-bit system time.
    Overflow,
    /// AssignActivate sets 0x0981 bit 7 (one-shot debug pulse, self-clearing): never wanted.
    DebugPulse,
    /// AssignActivate enables SYNC0/SYNC1 (0x0981 bit 1/2) without the sync unit (bit 0).
    SyncWithoutUnit,
    /// AssignActivate sets 0x0981 bits 3..6 but the ESC has no enhanced SYNC activation
    /// (0x0008 bit 8 clear): those bits do not exist there.
    EnhancedUnsupported,
    /// AssignActivate gives the cyclic unit to the PDI (0x0980 bit 0): the master's writes to
    /// 0x0981..0x09A7 would be ignored.
    PdiOwnsCyclicUnit,
}

impl core::fmt::Display for SyncError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let text = match self {
            SyncError::ZeroCycle => "SYNC grid period is 0",
            SyncError::StartOutOfWindow => "SYNC start not within (now, now + 2^31 ns)",
            SyncError::Overflow => "SYNC start overflows 64-bit system time",
            SyncError::DebugPulse => "AssignActivate sets the one-shot debug pulse (0x0981 bit 7)",
            SyncError::SyncWithoutUnit => "AssignActivate enables SYNC without the sync unit",
            SyncError::EnhancedUnsupported => {
                "AssignActivate uses enhanced activation bits the ESC lacks"
            }
            SyncError::PdiOwnsCyclicUnit => "AssignActivate gives the cyclic unit to the PDI",
        };
        f.write_str(text)
    }
}

#[cfg(feature = "std")]
impl std::error::Error for SyncError {}

/// REQ-DC-051: the reference clock's current 64-bit system time from a 0x0910 read. For a
/// 32-bit reference only the low 32 bits are meaningful; they are widened to the 64-bit time
/// nearest `estimate` (the master's own estimate of system time, e.g. its latch sample plus the
/// elapsed time), which is exact while the estimate is within ±2^31 ns.
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::{offset::ClockWidth, sync};
/// use ecdc_core::time::SystemTime;
///
/// // A 32-bit reference read 0x100 just after its clock wrapped; the master's estimate is
/// // slightly earlier.
/// let estimate = SystemTime(0x7_FFFF_FF00);
/// assert_eq!(
///     sync::reference_now(0x100, ClockWidth::Bits32, estimate),
///     SystemTime(0x8_0000_0100)
/// );
/// assert_eq!(
///     sync::reference_now(0x100, ClockWidth::Bits64, estimate),
///     SystemTime(0x100)
/// );
/// ```
pub fn reference_now(read: u64, width: ClockWidth, estimate: SystemTime) -> SystemTime {
    match width {
        ClockWidth::Bits64 => SystemTime(read),
        ClockWidth::Bits32 => SystemTime::extend_low32(crate::num::low32(read), estimate),
    }
}

/// REQ-DC-050: the common SYNC0 start time. `now` is the reference's 64-bit system time,
/// `margin_ns` the minimum lead (time to deliver the writes to every slave; IgH and SOEM use
/// 100 ms), `period_ns` the grid period (the bus cycle, or a common multiple of the slaves'
/// SYNC0 cycles) and `shift_ns` the SYNC0 shift relative to the grid.
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::sync::{self, SyncError};
/// use ecdc_core::time::SystemTime;
///
/// // 1 ms cycle, 100 ms margin, SYNC0 200 µs after the grid.
/// let now = SystemTime(5_000_250_000);
/// let start = sync::start_time(now, 100_000_000, 1_000_000, 200_000)?;
/// assert_eq!(start, SystemTime(5_101_200_000));
/// assert_eq!(start.phase_in(1_000_000), Some(200_000));
/// # Ok::<(), SyncError>(())
/// ```
pub fn start_time(
    now: SystemTime,
    margin_ns: u64,
    period_ns: u64,
    shift_ns: i64,
) -> Result<SystemTime, SyncError> {
    if period_ns == 0 {
        return Err(SyncError::ZeroCycle);
    }
    let earliest = now
        .as_nanos()
        .checked_add(margin_ns)
        .ok_or(SyncError::Overflow)?;
    let phase = earliest
        .checked_rem(period_ns)
        .ok_or(SyncError::ZeroCycle)?;
    let up = if phase == 0 {
        0
    } else {
        period_ns.checked_sub(phase).ok_or(SyncError::Overflow)?
    };
    let grid = earliest.checked_add(up).ok_or(SyncError::Overflow)?;
    let start = grid
        .checked_add_signed(shift_ns)
        .ok_or(SyncError::Overflow)?;
    let lead = start.saturating_sub(now.as_nanos());
    if lead == 0 || lead >= MAX_START_LEAD_NS {
        return Err(SyncError::StartOutOfWindow);
    }
    Ok(SystemTime(start))
}

/// REQ-DC-052: the 0x0990 image for a slave of `width` (8 bytes, or the low 32 bits in 4).
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::{offset::ClockWidth, sync};
/// use ecdc_core::time::SystemTime;
///
/// let start = SystemTime(0x1_0000_0010);
/// assert_eq!(
///     sync::start_time_register(start, ClockWidth::Bits32).as_slice(),
///     [0x10, 0, 0, 0]
/// );
/// assert_eq!(
///     sync::start_time_register(start, ClockWidth::Bits64)
///         .as_slice()
///         .len(),
///     8
/// );
/// ```
pub fn start_time_register(start: SystemTime, width: ClockWidth) -> RegisterBytes {
    WidthValue::new(start.as_nanos(), width).to_register()
}

/// REQ-DC-053: the 0x09A0 (SYNC0 cycle) or 0x09A4 (SYNC1 cycle) image: exactly 4 bytes.
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::sync;
///
/// // 0x09A0 for a 1 ms SYNC0 cycle: 4 bytes, so nothing spills into 0x09A4.
/// assert_eq!(
///     sync::cycle_register(1_000_000).as_slice(),
///     [0x40, 0x42, 0x0F, 0x00]
/// );
/// ```
pub fn cycle_register(cycle_ns: u32) -> RegisterBytes {
    RegisterBytes::u32(cycle_ns)
}

/// The two activation registers, from an ESI-style AssignActivate word (low byte → 0x0980,
/// high byte → 0x0981; e.g. 0x0300 = SYNC0, 0x0700 = SYNC0 + SYNC1).
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::sync::Activation;
///
/// // The ESI's AssignActivate 0x0300: sync unit and SYNC0 on, cyclic unit kept by the master.
/// let a = Activation::from_assign_activate(0x0300, 0x000C)?;
/// assert_eq!((a.cyclic_unit_control, a.activation), (0x00, 0x03));
/// assert!(a.sync0() && !a.sync1());
/// # Ok::<(), ecdc_core::dc::sync::SyncError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Activation {
    /// 0x0980 Cyclic Unit Control.
    pub cyclic_unit_control: u8,
    /// 0x0981 Activation.
    pub activation: u8,
}

impl Activation {
    /// 0x0981 value that switches the sync unit off; written first, before 0x0990/0x09A0
    /// (REQ-DC-034): the start time is only writable while 0x0981 bit 0 is clear.
    pub const OFF: u8 = 0;

    /// REQ-DC-054: validates an AssignActivate word for an ESC with the given features 0x0008.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::sync::{Activation, SyncError};
    ///
    /// assert!(Activation::from_assign_activate(0x0700, 0x000C)?.sync1());
    /// // SYNC0 without the sync unit bit.
    /// assert_eq!(
    ///     Activation::from_assign_activate(0x0200, 0x000C),
    ///     Err(SyncError::SyncWithoutUnit)
    /// );
    /// // Enhanced activation bits on an ESC without them (features bit 8 clear).
    /// assert_eq!(
    ///     Activation::from_assign_activate(0x0B00, 0x000C),
    ///     Err(SyncError::EnhancedUnsupported)
    /// );
    /// # Ok::<(), SyncError>(())
    /// ```
    pub fn from_assign_activate(assign_activate: u16, features: u16) -> Result<Self, SyncError> {
        let [low, high] = assign_activate.to_le_bytes();
        if low & 0x01 != 0 {
            return Err(SyncError::PdiOwnsCyclicUnit);
        }
        if high & 0x80 != 0 {
            return Err(SyncError::DebugPulse);
        }
        if high & 0x06 != 0 && high & 0x01 == 0 {
            return Err(SyncError::SyncWithoutUnit);
        }
        let enhanced = features & 0x0100 != 0;
        if high & 0x78 != 0 && !enhanced {
            return Err(SyncError::EnhancedUnsupported);
        }
        Ok(Activation {
            cyclic_unit_control: low,
            activation: high,
        })
    }

    /// The 2-byte image for one write at 0x0980 covering 0x0980 and 0x0981 (IgH style), in
    /// register order. Use it only after 0x0990/0x09A0/0x09A4 are written (REQ-DC-034).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::sync::Activation;
    ///
    /// let a = Activation::from_assign_activate(0x0700, 0x000C)?;
    /// assert_eq!(a.to_register(), [0x00, 0x07]); // 0x0980, 0x0981
    /// # Ok::<(), ecdc_core::dc::sync::SyncError>(())
    /// ```
    pub const fn to_register(self) -> [u8; 2] {
        [self.cyclic_unit_control, self.activation]
    }

    /// Whether SYNC0 is enabled (0x0981 bit 1).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::sync::Activation;
    ///
    /// assert!(Activation {
    ///     cyclic_unit_control: 0,
    ///     activation: 0x03
    /// }
    /// .sync0());
    /// assert!(!Activation {
    ///     cyclic_unit_control: 0,
    ///     activation: Activation::OFF
    /// }
    /// .sync0());
    /// ```
    pub const fn sync0(self) -> bool {
        self.activation & 0x02 != 0
    }

    /// Whether SYNC1 is enabled (0x0981 bit 2).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::sync::Activation;
    ///
    /// assert!(Activation {
    ///     cyclic_unit_control: 0,
    ///     activation: 0x07
    /// }
    /// .sync1());
    /// assert!(!Activation {
    ///     cyclic_unit_control: 0,
    ///     activation: 0x03
    /// }
    /// .sync1());
    /// ```
    pub const fn sync1(self) -> bool {
        self.activation & 0x04 != 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// REQ-DC-054: SYNC0 or SYNC1 without the sync unit (0x0981 bit 0) is refused, with it
    /// accepted, whichever of the two is asked for.
    // verifies: REQ-DC-054
    #[test]
    fn sync_needs_the_unit() {
        for sync in [0x0200u16, 0x0400, 0x0600] {
            assert_eq!(
                Activation::from_assign_activate(sync, 0),
                Err(SyncError::SyncWithoutUnit),
                "{sync:#06x}"
            );
            let with_unit = Activation::from_assign_activate(sync | 0x0100, 0).unwrap();
            assert_eq!(with_unit.activation, ((sync | 0x0100) >> 8) as u8);
        }
        assert!(
            Activation::from_assign_activate(0x0100, 0).is_ok(),
            "unit alone"
        );
        let off = Activation::from_assign_activate(0x0000, 0).unwrap();
        assert_eq!(
            off.to_register(),
            [0, 0],
            "no SYNC, no unit: nothing to refuse"
        );
        // Which SYNC signals the accepted word enables.
        for (word, s0, s1) in [
            (0x0100u16, false, false),
            (0x0300, true, false),
            (0x0500, false, true),
            (0x0700, true, true),
        ] {
            let a = Activation::from_assign_activate(word, 0).unwrap();
            assert_eq!((a.sync0(), a.sync1()), (s0, s1), "{word:#06x}");
        }
    }

    /// Every error says what went wrong, each in its own words.
    #[test]
    fn error_messages() {
        let all = [
            SyncError::ZeroCycle,
            SyncError::StartOutOfWindow,
            SyncError::Overflow,
            SyncError::DebugPulse,
            SyncError::SyncWithoutUnit,
            SyncError::EnhancedUnsupported,
            SyncError::PdiOwnsCyclicUnit,
        ];
        let texts: std::vec::Vec<_> = all.iter().map(|e| std::format!("{e}")).collect();
        for (i, t) in texts.iter().enumerate() {
            assert!(t.len() > 10, "{t}");
            assert!(texts[..i].iter().all(|u| u != t), "{t} twice");
        }
        assert_eq!(texts[0], "SYNC grid period is 0");
    }

    // verifies: REQ-DC-055
    #[test]
    fn start_on_grid_with_shift() {
        let now = SystemTime(1_000_000_123_456);
        let s = start_time(now, 100_000_000, 1_000_000, 0).unwrap();
        assert_eq!(s.as_nanos(), 1_000_101_000_000);
        let s = start_time(now, 100_000_000, 1_000_000, 250_000).unwrap();
        assert_eq!(s.as_nanos() % 1_000_000, 250_000);
        assert!(s.as_nanos() >= now.as_nanos() + 100_000_000);
        // Exactly on the grid: no extra period.
        let s = start_time(SystemTime(0), 2_000, 1_000, 0).unwrap();
        assert_eq!(s.as_nanos(), 2_000);
        assert_eq!(start_time(now, 1, 0, 0), Err(SyncError::ZeroCycle));
        assert_eq!(
            start_time(now, 0, 1_000, -2_000),
            Err(SyncError::StartOutOfWindow)
        );
        assert_eq!(
            start_time(now, 3_000_000_000, 1_000, 0),
            Err(SyncError::StartOutOfWindow)
        );
        assert_eq!(
            start_time(SystemTime(u64::MAX - 5), 100, 1_000, 0),
            Err(SyncError::Overflow)
        );
    }

    // verifies: REQ-DC-051, REQ-DC-052
    #[test]
    fn one_start_same_instant_for_32_and_64_bit() {
        // SOEM #354: mastertime64 mod cycle != low32(mastertime64) mod cycle; one 64-bit start
        // truncated to 32 bits is still the same instant in a 32-bit slave's system time.
        let now = SystemTime(0x0000_0123_FFFF_F000);
        let s = start_time(now, 100_000_000, 1_000_000, 0).unwrap();
        let r64 = start_time_register(s, ClockWidth::Bits64);
        let r32 = start_time_register(s, ClockWidth::Bits32);
        assert_eq!(r64.as_slice(), &s.as_nanos().to_le_bytes());
        assert_eq!(r32.as_slice(), &s.low32().to_le_bytes());
        assert_eq!(cycle_register(1_000_000).as_slice().len(), 4);
        // Widening a 32-bit reference read near the master's estimate.
        let est = SystemTime(0x0000_0124_0000_0100);
        assert_eq!(
            reference_now(0x0000_0010, ClockWidth::Bits32, est).as_nanos(),
            0x0000_0124_0000_0010
        );
        assert_eq!(
            reference_now(0xFFFF_FFF0, ClockWidth::Bits32, est).as_nanos(),
            0x0000_0123_FFFF_FFF0
        );
    }

    // verifies: REQ-DC-054
    #[test]
    fn assign_activate_rules() {
        let a = Activation::from_assign_activate(0x0300, 0).unwrap();
        assert_eq!((a.cyclic_unit_control, a.activation), (0x00, 0x03));
        assert!(a.sync0() && !a.sync1());
        assert_eq!(a.to_register(), [0x00, 0x03]);
        assert!(Activation::from_assign_activate(0x0700, 0).unwrap().sync1());
        // (AssignActivate, the ESC features 0x0008, the refusal).
        let refused = [
            (0x0301, 0, SyncError::PdiOwnsCyclicUnit),
            (0x8300, 0x0100, SyncError::DebugPulse),
            (0x0200, 0, SyncError::SyncWithoutUnit),
            (0x0B00, 0, SyncError::EnhancedUnsupported),
        ];
        for (assign, features, want) in refused {
            assert_eq!(
                Activation::from_assign_activate(assign, features),
                Err(want)
            );
        }
        assert!(Activation::from_assign_activate(0x0B00, 0x0100).is_ok());
    }
}
