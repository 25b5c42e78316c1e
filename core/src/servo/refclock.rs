//! Reference-follows-master: the value and schedule of the FPWR that writes the master's time
//! to the reference clock's System Time register 0x0910 (REQ-SERVO-110..112).
//!
//! An ECAT write covering 0x0910 is a sample for the ESC's own time-control loop: the ESC
//! compares the written value, at end of frame, with its local copy latched when the frame's
//! start passed it (REQ-ESC-006, REQ-ESC-050). So the value must be the master's time *at the
//! moment the frame passes the reference*: the master's time at send plus `lead_ns` (NIC TX
//! latency + wire and forwarding delay up to the reference). IgH's `sync_reference_clock_to`
//! writes 4 bytes; a 64-bit reference may take 8.
//!
//! The ESC loop slews at most ≈ 763 ppm at the default bandwidth (REQ-ESC-056), so a jump in the master's time would
//! pull the whole network for minutes. Each written value is therefore checked against the
//! previous one advanced by the elapsed cycles; a deviation beyond `max_jump_ns` is refused with
//! a typed error, and nothing is written until the caller re-anchors with [`RefFollower::resync`]
//! (after re-running offset compensation). A refused write is never a wrong value on the wire.

use crate::num::wrapping_diff;

/// Configuration.
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::refclock::{RefFollowConfig, RefFollower, RefWrite};
///
/// // 1 ms cycle, write every cycle, the frame passes the reference 2 µs after send, 32-bit
/// // reference, refuse jumps above 10 µs.
/// let cfg = RefFollowConfig {
///     period_ns: 1_000_000,
///     every: 1,
///     lead_ns: 2_000,
///     ref_32bit: true,
///     max_jump_ns: 10_000,
/// };
/// let mut follower = RefFollower::new(cfg)?;
/// let w = follower.on_cycle(0x1_0000_0000)?;
/// assert_eq!(
///     w,
///     Some(RefWrite {
///         value: 2_000,
///         len: 4
///     })
/// ); // low 32 bits
/// # Ok::<(), ecdc_core::servo::refclock::RefError>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct RefFollowConfig {
    /// Cycle period, ns (> 0).
    pub period_ns: u32,
    /// Write every `every`-th cycle (≥ 1; IgH's dc_user example uses 10 at 100 Hz... or 1).
    pub every: u16,
    /// Master send time → frame passes the reference, ns.
    pub lead_ns: u32,
    /// The reference is a 32-bit DC: write 4 bytes (the low 32 bits).
    pub ref_32bit: bool,
    /// Largest tolerated deviation from the expected progression, ns (0 = no check).
    pub max_jump_ns: u64,
}

/// Why a write was refused.
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::refclock::{RefError, RefFollowConfig, RefFollower};
///
/// let cfg = RefFollowConfig {
///     period_ns: 1_000_000,
///     every: 1,
///     lead_ns: 0,
///     ref_32bit: false,
///     max_jump_ns: 10_000,
/// };
/// let mut follower = RefFollower::new(cfg)?;
/// follower.on_cycle(5_000_000_000)?;
/// // The master's clock jumped 1 ms forward between two cycles.
/// assert_eq!(
///     follower.on_cycle(5_002_000_000),
///     Err(RefError::Jump {
///         deviation_ns: 1_000_000
///     })
/// );
/// assert_eq!(
///     RefFollower::new(RefFollowConfig { every: 0, ..cfg }),
///     Err(RefError::Config)
/// );
/// # Ok::<(), RefError>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum RefError {
    /// period_ns or every was 0.
    Config,
    /// The master's time deviated from the expected progression by `deviation_ns`.
    Jump {
        /// value − expected, ns (wrap-safe).
        deviation_ns: i64,
    },
}

/// One write to perform this cycle: FPWR of `len` bytes of `value` (little-endian) to 0x0910
/// of the reference clock.
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::refclock::RefWrite;
///
/// // The FPWR to queue: `len` bytes of `bytes()` to 0x0910 of the reference.
/// let w = RefWrite {
///     value: 0x0102_0304,
///     len: 4,
/// };
/// let data = w.bytes();
/// assert_eq!(&data[..usize::from(w.len)], [0x04, 0x03, 0x02, 0x01]);
/// assert_eq!(RefWrite::REGISTER, 0x0910);
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct RefWrite {
    /// System time to write (only the low 32 bits matter when `len == 4`).
    pub value: u64,
    /// 4 or 8.
    pub len: u8,
}

impl RefWrite {
    /// Register address written.
    pub const REGISTER: u16 = 0x0910;

    /// Payload bytes, little-endian; only the first `len` are sent.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::refclock::RefWrite;
    ///
    /// assert_eq!(
    ///     RefWrite { value: 1, len: 8 }.bytes(),
    ///     [1, 0, 0, 0, 0, 0, 0, 0]
    /// );
    /// ```
    pub fn bytes(&self) -> [u8; 8] {
        self.value.to_le_bytes()
    }
}

/// Schedule and value computation for reference-follows-master.
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::refclock::{RefFollowConfig, RefFollower};
///
/// // Every 10th cycle of 1 ms.
/// let cfg = RefFollowConfig {
///     period_ns: 1_000_000,
///     every: 10,
///     lead_ns: 0,
///     ref_32bit: false,
///     max_jump_ns: 0,
/// };
/// let mut follower = RefFollower::new(cfg)?;
/// let mut writes = 0;
/// for k in 0..30u64 {
///     if follower.on_cycle(k * 1_000_000)?.is_some() {
///         writes += 1;
///     }
/// }
/// assert_eq!(writes, 3);
/// # Ok::<(), ecdc_core::servo::refclock::RefError>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct RefFollower {
    cfg: RefFollowConfig,
    cycle: u64,
    last: Option<(u64, u64)>,
    blocked: bool,
}

impl RefFollower {
    /// Validate and build.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::refclock::{RefError, RefFollowConfig, RefFollower};
    ///
    /// let cfg = RefFollowConfig {
    ///     period_ns: 0,
    ///     every: 1,
    ///     lead_ns: 0,
    ///     ref_32bit: false,
    ///     max_jump_ns: 0,
    /// };
    /// assert_eq!(RefFollower::new(cfg), Err(RefError::Config));
    /// ```
    pub fn new(cfg: RefFollowConfig) -> Result<Self, RefError> {
        if cfg.period_ns == 0 || cfg.every == 0 {
            return Err(RefError::Config);
        }
        Ok(RefFollower {
            cfg,
            cycle: 0,
            last: None,
            blocked: false,
        })
    }

    /// REQ-SERVO-110/111: call once per cycle with the master's time at send (ns). Returns the
    /// write to queue this cycle, `Ok(None)` on cycles without a write, or the refusal.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::refclock::{RefFollowConfig, RefFollower, RefWrite};
    ///
    /// let cfg = RefFollowConfig { period_ns: 1_000_000, every: 2, lead_ns: 1_500, ref_32bit: false, max_jump_ns: 10_000 };
    /// let mut follower = RefFollower::new(cfg)?;
    /// assert_eq!(follower.on_cycle(9_000_000)?, Some(RefWrite { value: 9_001_500, len: 8 }));
    /// assert_eq!(follower.on_cycle(10_000_000)?, None); // not this cycle
    /// # Ok::<(), ecdc_core::servo::refclock::RefError>(())
    /// ```
    pub fn on_cycle(&mut self, master_send_ns: u64) -> Result<Option<RefWrite>, RefError> {
        let c = self.cycle;
        self.cycle = self.cycle.wrapping_add(1);
        if c.checked_rem(u64::from(self.cfg.every)) != Some(0) {
            return Ok(None);
        }
        let value = master_send_ns.wrapping_add(u64::from(self.cfg.lead_ns));
        // REQ-SERVO-112: progression check against the last written value.
        if let Some((v0, c0)) = self.last {
            let cycles = c.wrapping_sub(c0);
            let expected = v0.wrapping_add(cycles.wrapping_mul(u64::from(self.cfg.period_ns)));
            let dev = wrapping_diff::<u64>(value, expected);
            if self.cfg.max_jump_ns > 0 && dev.unsigned_abs() > self.cfg.max_jump_ns {
                self.blocked = true;
                return Err(RefError::Jump { deviation_ns: dev });
            }
        }
        if self.blocked {
            return Err(RefError::Jump { deviation_ns: 0 });
        }
        self.last = Some((value, c));
        let (value, len) = if self.cfg.ref_32bit {
            (value & 0xFFFF_FFFF, 4)
        } else {
            (value, 8)
        };
        Ok(Some(RefWrite { value, len }))
    }

    /// Forget the progression anchor (after the master's time was deliberately stepped and the
    /// offsets re-written); the next scheduled cycle writes again.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::refclock::{RefFollowConfig, RefFollower};
    ///
    /// let cfg = RefFollowConfig { period_ns: 1_000_000, every: 1, lead_ns: 0, ref_32bit: false, max_jump_ns: 10_000 };
    /// let mut follower = RefFollower::new(cfg)?;
    /// follower.on_cycle(5_000_000_000)?;
    /// assert!(follower.on_cycle(9_000_000_000).is_err()); // jumped: writes stop
    /// // After the offsets were re-written for the new time, re-anchor.
    /// follower.resync();
    /// assert!(follower.on_cycle(9_001_000_000)?.is_some());
    /// # Ok::<(), ecdc_core::servo::refclock::RefError>(())
    /// ```
    pub fn resync(&mut self) {
        self.last = None;
        self.blocked = false;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // verifies: REQ-SERVO-110, REQ-SERVO-111, REQ-SERVO-112
    #[test]
    fn schedule_value_and_jump_refusal() {
        let mut r = RefFollower::new(RefFollowConfig {
            period_ns: 1_000_000,
            every: 2,
            lead_ns: 1500,
            ref_32bit: true,
            max_jump_ns: 50_000,
        })
        .unwrap();
        let base = 0x1_FFFF_0000u64;
        let w = r.on_cycle(base).unwrap().unwrap();
        assert_eq!((w.value, w.len), ((base + 1500) & 0xFFFF_FFFF, 4));
        assert_eq!(r.on_cycle(base + 1_000_000), Ok(None));
        let w = r.on_cycle(base + 2_000_020).unwrap().unwrap();
        assert_eq!(w.value, (base + 2_001_520) & 0xFFFF_FFFF);
        assert_eq!(&w.bytes()[..4], &((base + 2_001_520) as u32).to_le_bytes());
        assert_eq!(r.on_cycle(0), Ok(None));
        assert!(matches!(
            r.on_cycle(base + 4_200_000),
            Err(RefError::Jump {
                deviation_ns: 199_980
            })
        ));
        assert_eq!(r.on_cycle(0), Ok(None));
        assert!(r.on_cycle(base + 6_000_000).is_err()); // stays blocked
        r.resync();
        assert_eq!(r.on_cycle(0), Ok(None));
        assert!(r.on_cycle(base + 8_000_000).unwrap().is_some());
        assert!(RefFollower::new(RefFollowConfig {
            period_ns: 0,
            every: 1,
            lead_ns: 0,
            ref_32bit: false,
            max_jump_ns: 0
        })
        .is_err());
    }

    /// A deviation of exactly `max_jump_ns` is still accepted, one more refused; with
    /// `max_jump_ns` 0 the check is off and any deviation is accepted.
    #[test]
    fn jump_limit_boundary_and_off() {
        let follower = |max_jump_ns| {
            RefFollower::new(RefFollowConfig {
                period_ns: 1_000_000,
                every: 1,
                lead_ns: 0,
                ref_32bit: false,
                max_jump_ns,
            })
            .unwrap()
        };
        let mut r = follower(100);
        r.on_cycle(5_000_000).unwrap();
        assert!(r.on_cycle(6_000_100).is_ok());
        assert!(r.on_cycle(7_000_201).is_err());
        let mut r = follower(0);
        r.on_cycle(5_000_000).unwrap();
        assert!(r.on_cycle(6_000_001).unwrap().is_some());
    }
}
