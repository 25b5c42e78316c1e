//! What the machine knows about one slave. Public read-only through
//! [`crate::dc::Machine::slaves`], so users can see delays, offsets and the last 0x092C value
//! (the per-slave report of a failed convergence gate).

use crate::wire::register::ReceiveTimes;

/// DC capability from ESC features 0x0008 and the system-time probe.
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::DcKind;
///
/// // A 32-bit DC slave: latches, a system time, 4-byte time registers.
/// let k = DcKind::Bits32;
/// assert!(k.has_latches() && k.has_system_time());
/// assert_eq!(k.time_width(), 4);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum DcKind {
    /// No DC unit (0x0008 bit 2 clear): only adds wire delay.
    #[default]
    None,
    /// DC receive-time latches, but no system time (FPRD 0x0910 came back with WKC 0).
    DelayOnly,
    /// 32-bit system time (0x0008 bit 3 clear).
    Bits32,
    /// 64-bit system time.
    Bits64,
}

impl DcKind {
    /// Has receive-time latches (takes part in delay measurement).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::DcKind;
    ///
    /// assert!(DcKind::DelayOnly.has_latches());
    /// assert!(!DcKind::None.has_latches());
    /// ```
    pub const fn has_latches(self) -> bool {
        !matches!(self, DcKind::None)
    }
    /// Has a system time (gets an offset, a delay, drift compensation, SYNC).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::DcKind;
    ///
    /// // Timed for delays, but no clock to synchronise.
    /// assert!(!DcKind::DelayOnly.has_system_time());
    /// assert!(DcKind::Bits64.has_system_time());
    /// ```
    pub const fn has_system_time(self) -> bool {
        matches!(self, DcKind::Bits32 | DcKind::Bits64)
    }
    /// Width in bytes of 0x0910/0x0920/0x0990 on this slave (8, or 4 for 32-bit DC).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::DcKind;
    ///
    /// assert_eq!(DcKind::Bits64.time_width(), 8);
    /// assert_eq!(DcKind::Bits32.time_width(), 4);
    /// ```
    pub const fn time_width(self) -> u16 {
        match self {
            DcKind::Bits64 => 8,
            _ => 4,
        }
    }
}

/// One slave, by position (auto-increment order = processing order).
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::{DcKind, SlaveInfo};
///
/// // What `Machine::slaves` reports, e.g. for a per-slave table after a bring-up.
/// fn describe(s: &SlaveInfo) -> (u16, u32, bool) {
///     (s.station, s.delay_ns, s.dc.has_system_time())
/// }
/// let mut s = SlaveInfo::EMPTY;
/// (s.station, s.dc, s.delay_ns) = (0x1002, DcKind::Bits64, 480);
/// assert_eq!(describe(&s), (0x1002, 480, true));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct SlaveInfo {
    /// Station address assigned (0x0010).
    pub station: u16,
    /// ESC features register 0x0008.
    pub features: u16,
    /// DL status 0x0110 read at discovery.
    pub dl_status: u16,
    /// DC capability.
    pub dc: DcKind,
    /// AL status 0x0130 (low 16 bits) read just before the offset write; `None` if it was not
    /// read in this bring-up.
    pub al_status: Option<u16>,
    /// Port receive times (0x0900..0x090F) before the latest trigger.
    pub times_before: [u32; 4],
    /// Port receive times after the latest trigger.
    pub times_after: [u32; 4],
    /// EPU receive time 0x0918 of the latest trigger.
    pub epu_time: u64,
    /// Delay of the latest single latch round (re-measurement, REQ-DC-107); the bring-up's
    /// rounds are averaged exactly in the machine instead (REQ-DC-019).
    pub(crate) delay_sum: u64,
    /// Propagation delay from the reference, ns (0x0928).
    pub delay_ns: u32,
    /// Delay from a running re-measurement, not yet written.
    pub(crate) delay_new: u32,
    /// System time offset computed for 0x0920 (full 64 bits; 32-bit slaves get the low half).
    pub offset: u64,
    /// Whether 0x0920 was written in the last bring-up.
    pub offset_written: bool,
    /// Local time (64 bit) at which the last latch frame entered the slave (REQ-DC-022).
    pub(crate) entry_local: u64,
    /// 0x0920 as read from a slave found running in this bring-up (REQ-DC-131), zero-extended.
    pub(crate) running_offset: Option<u64>,
    /// Whether the SYNC unit was programmed in the last bring-up.
    pub sync_programmed: bool,
    /// Last 0x092C value decoded to signed ns (negative = local copy behind), if read.
    pub last_diff_ns: Option<i64>,
    /// Sum of |0x092C| over the current passing streak of drift checks (REQ-DC-104).
    pub(crate) diff_abs_sum: u64,
    /// Sum of the signed 0x092C values over the same streak.
    pub(crate) diff_sum: i64,
    /// ESC type (0x0000, low byte) and revision (0x0001, high byte), read by the t_Diff step
    /// (0 if not read).
    pub esc_type: u16,
    /// t_Diff used in this bring-up's delay measurement, ns (REQ-DC-126).
    pub t_diff_ns: i32,
    /// Where `t_diff_ns` came from.
    pub t_diff_source: crate::dc::tdiff::TdiffSource,
}

/// AL status state codes (0x0130 bits 3:0), ETG.1000.6.
pub(crate) const AL_INIT: u16 = 0x1;
pub(crate) const AL_PREOP: u16 = 0x2;
pub(crate) const AL_BOOT: u16 = 0x3;

impl SlaveInfo {
    /// A slave not found yet (the `Default`), usable in a `const` context.
    pub const EMPTY: SlaveInfo = SlaveInfo {
        station: 0,
        features: 0,
        dl_status: 0,
        dc: DcKind::None,
        al_status: None,
        times_before: [0; 4],
        times_after: [0; 4],
        epu_time: 0,
        delay_sum: 0,
        delay_ns: 0,
        delay_new: 0,
        offset: 0,
        offset_written: false,
        entry_local: 0,
        running_offset: None,
        sync_programmed: false,
        last_diff_ns: None,
        diff_abs_sum: 0,
        diff_sum: 0,
        esc_type: 0,
        t_diff_ns: 0,
        t_diff_source: crate::dc::tdiff::TdiffSource::Default,
    };

    /// REQ-DC-103: a slave may get a new 0x0920 (a step of its system time) only if its AL
    /// status was read in this bring-up and says INIT, PRE-OP or BOOT. SAFE-OP, OP, an error
    /// combination or an unread status all mean "possibly running": leave the offset alone.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::SlaveInfo;
    ///
    /// let mut s = SlaveInfo::EMPTY;
    /// s.al_status = Some(0x0002); // PRE-OP
    /// assert!(s.may_step_offset());
    /// s.al_status = Some(0x0008); // OP: running outputs, leave its clock alone
    /// assert!(!s.may_step_offset());
    /// assert!(!SlaveInfo::EMPTY.may_step_offset()); // status not read
    /// ```
    pub fn may_step_offset(&self) -> bool {
        matches!(
            self.al_status.map(|s| s & 0x0F),
            Some(AL_INIT | AL_PREOP | AL_BOOT)
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Receive-time latches exactly for the slaves with a DC unit (0x0008 bit 2): a delay-only
    /// slave has them and takes part in delay measurement, a slave without DC has none.
    #[test]
    fn latches_and_system_time_by_kind() {
        let kinds = [
            (DcKind::None, false, false, 4),
            (DcKind::DelayOnly, true, false, 4),
            (DcKind::Bits32, true, true, 4),
            (DcKind::Bits64, true, true, 8),
        ];
        for (k, latches, system_time, width) in kinds {
            assert_eq!(k.has_latches(), latches, "{k:?}");
            assert_eq!(k.has_system_time(), system_time, "{k:?}");
            assert_eq!(k.time_width(), width, "{k:?}");
        }
    }
}

/// Which read of the receive-time block (0x0900..) a reply is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum LatchRead {
    /// Before the latching write: the four port times (16 bytes), for stale-latch detection.
    Before,
    /// After it: the whole 32-byte block (port times, system time, EPU time).
    After,
}

impl LatchRead {
    /// Bytes read from 0x0900.
    pub(crate) const fn len(self) -> u16 {
        match self {
            LatchRead::Before => 16,
            LatchRead::After => 32,
        }
    }
}

const _: () = assert!(ReceiveTimes::PORTS_LEN == 16 && ReceiveTimes::LEN == 32);

impl SlaveInfo {
    /// Stores a read of the receive-time block into `times_before`, or into `times_after` and
    /// `epu_time`. `None`, with nothing stored, when `data` is shorter than the read.
    pub(crate) fn store_latches(&mut self, read: LatchRead, data: &[u8]) -> Option<()> {
        match read {
            LatchRead::Before => self.times_before = ReceiveTimes::parse_ports(data).ok()?,
            LatchRead::After => {
                let t = ReceiveTimes::parse(data).ok()?;
                self.times_after = t.port;
                self.epu_time = t.epu;
            }
        }
        Some(())
    }
}

#[cfg(test)]
mod latch_tests {
    use super::*;

    /// The two reads of the receive-time block, their lengths and what each one stores.
    #[test]
    fn latch_reads_store_ports_and_epu() {
        assert_eq!((LatchRead::Before.len(), LatchRead::After.len()), (16, 32));
        let mut block = [0u8; 32];
        for (k, b) in block.iter_mut().enumerate() {
            *b = u8::try_from(k).unwrap();
        }
        let port = |k: u8| u32::from_le_bytes([4 * k, 4 * k + 1, 4 * k + 2, 4 * k + 3]);
        let mut s = SlaveInfo::EMPTY;
        assert_eq!(s.store_latches(LatchRead::Before, &block[..16]), Some(()));
        assert_eq!(s.times_before, [port(0), port(1), port(2), port(3)]);
        assert_eq!((s.times_after, s.epu_time), ([0; 4], 0));
        assert_eq!(s.store_latches(LatchRead::After, &block), Some(()));
        assert_eq!(s.times_after, s.times_before);
        assert_eq!(
            s.epu_time,
            u64::from_le_bytes(block[24..32].try_into().unwrap())
        );
        // Too short: nothing stored.
        let mut t = SlaveInfo::EMPTY;
        assert_eq!(t.store_latches(LatchRead::Before, &block[..15]), None);
        assert_eq!(t.store_latches(LatchRead::After, &block[..31]), None);
        assert_eq!(t, SlaveInfo::EMPTY);
    }
}
