//! ESC registers the DC code touches: addresses, widths, and typed codecs (REQ-WIRE-070..074).
//!
//! Sources: docs/background/esc-registers.md §2 (ESC datasheet Section II tables, Infineon XMC SVD, IgH).
//! [`reg`] holds plain `u16` addresses; [`typed`] pairs each DC register with its value type,
//! so reading the 64-bit System Time as a `u32` does not compile.

use super::{Error, Result};
use core::marker::PhantomData;

/// Register addresses (ADO values).
pub mod reg {
    /// ESC Features Supported, u16. See [`super::EscFeatures`].
    pub const ESC_FEATURES: u16 = 0x0008;
    /// Configured Station Address, u16.
    pub const STATION_ADDRESS: u16 = 0x0010;
    /// Configured Station Alias, u16.
    pub const STATION_ALIAS: u16 = 0x0012;
    /// ESC DL Status, u16. See [`super::DlStatus`].
    pub const DL_STATUS: u16 = 0x0110;
    /// AL Control, u16.
    pub const AL_CONTROL: u16 = 0x0120;
    /// AL Status, u16.
    pub const AL_STATUS: u16 = 0x0130;
    /// AL Status Code, u16.
    pub const AL_STATUS_CODE: u16 = 0x0134;
    /// Receive Time Port 0, u32 (a write latches all ports). Ports 1..3 follow at +4.
    pub const RECEIVE_TIME_PORT0: u16 = 0x0900;
    /// Receive Time Port 1, u32.
    pub const RECEIVE_TIME_PORT1: u16 = 0x0904;
    /// Receive Time Port 2, u32.
    pub const RECEIVE_TIME_PORT2: u16 = 0x0908;
    /// Receive Time Port 3, u32.
    pub const RECEIVE_TIME_PORT3: u16 = 0x090C;
    /// System Time, u64 (u32 on 32-bit DC slaves).
    pub const SYSTEM_TIME: u16 = 0x0910;
    /// Receive Time ECAT Processing Unit, u64.
    pub const RECEIVE_TIME_EPU: u16 = 0x0918;
    /// System Time Offset, u64 (u32 on 32-bit DC slaves).
    pub const SYSTEM_TIME_OFFSET: u16 = 0x0920;
    /// System Time Delay, u32.
    pub const SYSTEM_TIME_DELAY: u16 = 0x0928;
    /// System Time Difference, u32 sign-magnitude. See [`super::SystemTimeDifference`].
    pub const SYSTEM_TIME_DIFFERENCE: u16 = 0x092C;
    /// Speed Counter Start, u16 (any write resets the time-loop filters).
    pub const SPEED_COUNTER_START: u16 = 0x0930;
    /// Speed Counter Diff, i16.
    pub const SPEED_COUNTER_DIFF: u16 = 0x0932;
    /// System Time Difference Filter Depth, u8.
    pub const SYSTEM_TIME_DIFF_FILTER_DEPTH: u16 = 0x0934;
    /// Speed Counter Filter Depth, u8.
    pub const SPEED_COUNTER_FILTER_DEPTH: u16 = 0x0935;
    /// Receive Time Latch Mode, u8 (newer ESCs).
    pub const RECEIVE_TIME_LATCH_MODE: u16 = 0x0936;
    /// Cyclic Unit Control, u8 (IgH writes u16 here together with 0x0981: "AssignActivate").
    pub const CYCLIC_UNIT_CONTROL: u16 = 0x0980;
    /// Activation (SYNC out unit, SYNC0/1 enable), u8.
    pub const SYNC_ACTIVATION: u16 = 0x0981;
    /// Pulse Length of SyncSignals, u16 (10 ns units).
    pub const SYNC_PULSE_LENGTH: u16 = 0x0982;
    /// Activation Status, u8.
    pub const SYNC_ACTIVATION_STATUS: u16 = 0x0984;
    /// SYNC0 Status, u8.
    pub const SYNC0_STATUS: u16 = 0x098E;
    /// SYNC1 Status, u8.
    pub const SYNC1_STATUS: u16 = 0x098F;
    /// Start Time Cyclic Operation, u64 (u32 on 32-bit DC slaves).
    pub const SYNC0_START_TIME: u16 = 0x0990;
    /// Next SYNC1 Pulse, u64.
    pub const NEXT_SYNC1_PULSE: u16 = 0x0998;
    /// SYNC0 Cycle Time, u32 ns.
    pub const SYNC0_CYCLE: u16 = 0x09A0;
    /// SYNC1 Cycle Time, u32 ns.
    pub const SYNC1_CYCLE: u16 = 0x09A4;
    /// Latch0 Control, u8.
    pub const LATCH0_CONTROL: u16 = 0x09A8;
    /// Latch1 Control, u8.
    pub const LATCH1_CONTROL: u16 = 0x09A9;
    /// Latch0 Status, u8.
    pub const LATCH0_STATUS: u16 = 0x09AE;
    /// Latch1 Status, u8.
    pub const LATCH1_STATUS: u16 = 0x09AF;
    /// Latch0 Time Positive Edge, u64.
    pub const LATCH0_POS: u16 = 0x09B0;
    /// Latch0 Time Negative Edge, u64.
    pub const LATCH0_NEG: u16 = 0x09B8;
    /// Latch1 Time Positive Edge, u64.
    pub const LATCH1_POS: u16 = 0x09C0;
    /// Latch1 Time Negative Edge, u64.
    pub const LATCH1_NEG: u16 = 0x09C8;
}

/// A register value type with a fixed little-endian width.
///
/// # Examples
///
/// ```
/// use ecdc_core::wire::register::RegisterValue;
///
/// // Every register value is little-endian on the wire.
/// assert_eq!(<u32 as RegisterValue>::WIDTH, 4);
/// assert_eq!(u32::decode_le(&[0x78, 0x56, 0x34, 0x12]), Some(0x1234_5678));
/// ```
pub trait RegisterValue: Copy {
    /// Width in bytes.
    const WIDTH: usize;
    /// Decodes from exactly `WIDTH` bytes (callers pass a checked slice).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::wire::register::RegisterValue;
    ///
    /// assert_eq!(i16::decode_le(&[0xFE, 0xFF]), Some(-2));
    /// assert_eq!(u64::decode_le(&[0; 4]), None); // too short
    /// ```
    fn decode_le(bytes: &[u8]) -> Option<Self>;
    /// Encodes into exactly `WIDTH` bytes.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::wire::register::RegisterValue;
    ///
    /// let mut out = [0u8; 2];
    /// assert_eq!(0x0C00u16.encode_le(&mut out), Some(()));
    /// assert_eq!(out, [0x00, 0x0C]);
    /// ```
    fn encode_le(self, out: &mut [u8]) -> Option<()>;
}

macro_rules! int_value {
    ($($t:ty),*) => {$(
        impl RegisterValue for $t {
            const WIDTH: usize = core::mem::size_of::<$t>();
            fn decode_le(bytes: &[u8]) -> Option<Self> {
                Some(<$t>::from_le_bytes(bytes.get(..Self::WIDTH)?.try_into().ok()?))
            }
            fn encode_le(self, out: &mut [u8]) -> Option<()> {
                out.get_mut(..Self::WIDTH)?.copy_from_slice(&self.to_le_bytes());
                Some(())
            }
        }
    )*};
}
int_value!(u8, u16, u32, u64, i16);

/// A register: its address plus the type (and so the width) of its value.
///
/// # Examples
///
/// ```
/// use ecdc_core::wire::register::{typed, Register};
///
/// // The System Time Delay register 0x0928 is a u32.
/// let delay: Register<u32> = typed::SYSTEM_TIME_DELAY;
/// assert_eq!((delay.address(), delay.len()), (0x0928, 4));
/// let mut data = [0u8; 4];
/// delay.encode(1_250, &mut data)?;
/// assert_eq!(delay.decode(&data)?, 1_250);
/// # Ok::<(), ecdc_core::wire::Error>(())
/// ```
#[derive(Debug, PartialEq, Eq)]
pub struct Register<V> {
    address: u16,
    _value: PhantomData<V>,
}

impl<V> Clone for Register<V> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<V> Copy for Register<V> {}

impl<V: RegisterValue> Register<V> {
    /// A register at `address`.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::wire::register::Register;
    ///
    /// // A register this crate has no constant for: 0x0502 EEPROM control/status, a u16.
    /// const EEPROM_CONTROL: Register<u16> = Register::new(0x0502);
    /// assert_eq!(EEPROM_CONTROL.address(), 0x0502);
    /// ```
    pub const fn new(address: u16) -> Register<V> {
        Register {
            address,
            _value: PhantomData,
        }
    }
    /// Its address (ADO).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::wire::register::typed;
    ///
    /// assert_eq!(typed::SYSTEM_TIME.address(), 0x0910);
    /// ```
    pub const fn address(self) -> u16 {
        self.address
    }
    /// Its width in bytes (the datagram length to read or write it).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::wire::register::typed;
    ///
    /// assert_eq!(typed::SYSTEM_TIME.width(), 8);
    /// assert_eq!(typed::SYSTEM_TIME_32.width(), 4);
    /// ```
    pub const fn width(self) -> usize {
        V::WIDTH
    }
    /// Its width as a datagram length.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::wire::register::typed;
    ///
    /// // The datagram length for a read of 0x0130 AL status.
    /// assert_eq!(typed::AL_STATUS.len(), 2);
    /// ```
    pub const fn len(self) -> u16 {
        // widths are 1..=8
        let [lo, _, _, _, _, _, _, _] = (V::WIDTH as u64).to_le_bytes();
        lo as u16
    }
    /// Always false (every register is at least one byte); for API symmetry with `len`.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::wire::register::typed;
    ///
    /// assert!(!typed::SYNC_ACTIVATION.is_empty());
    /// ```
    pub const fn is_empty(self) -> bool {
        V::WIDTH == 0
    }
    /// Decodes the value from the first `width` bytes of `data` ([`Error::Truncated`] if
    /// shorter).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::wire::{register::typed, Error};
    ///
    /// // A datagram's data may be longer than the register: only the first bytes count.
    /// assert_eq!(
    ///     typed::SPEED_COUNTER_DIFF.decode(&[0xF6, 0xFF, 0xAA]),
    ///     Ok(-10)
    /// );
    /// assert_eq!(typed::SYSTEM_TIME.decode(&[0; 4]), Err(Error::Truncated));
    /// ```
    pub fn decode(self, data: &[u8]) -> Result<V> {
        V::decode_le(data).ok_or(Error::Truncated)
    }
    /// Encodes `value` into the first `width` bytes of `out` ([`Error::Truncated`] if shorter).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::wire::{register::typed, Error};
    ///
    /// let mut data = [0u8; 4];
    /// typed::SYNC0_CYCLE.encode(1_000_000, &mut data)?;
    /// assert_eq!(data, 1_000_000u32.to_le_bytes());
    /// assert_eq!(
    ///     typed::SYSTEM_TIME.encode(0, &mut data),
    ///     Err(Error::Truncated)
    /// );
    /// # Ok::<(), Error>(())
    /// ```
    pub fn encode(self, value: V, out: &mut [u8]) -> Result<()> {
        value.encode_le(out).ok_or(Error::Truncated)
    }
}

/// DC registers with their value types (REQ-WIRE-070). 64-bit registers are 32-bit on slaves
/// whose [`EscFeatures::dc_64bit`] is false; use the `_32` variants for those.
pub mod typed {
    use super::{reg, Register};
    /// 0x0008 ESC features.
    pub const ESC_FEATURES: Register<u16> = Register::new(reg::ESC_FEATURES);
    /// 0x0010 configured station address.
    pub const STATION_ADDRESS: Register<u16> = Register::new(reg::STATION_ADDRESS);
    /// 0x0110 DL status.
    pub const DL_STATUS: Register<u16> = Register::new(reg::DL_STATUS);
    /// 0x0120 AL control.
    pub const AL_CONTROL: Register<u16> = Register::new(reg::AL_CONTROL);
    /// 0x0130 AL status.
    pub const AL_STATUS: Register<u16> = Register::new(reg::AL_STATUS);
    /// 0x0900 receive time port 0.
    pub const RECEIVE_TIME_PORT0: Register<u32> = Register::new(reg::RECEIVE_TIME_PORT0);
    /// 0x0904 receive time port 1.
    pub const RECEIVE_TIME_PORT1: Register<u32> = Register::new(reg::RECEIVE_TIME_PORT1);
    /// 0x0908 receive time port 2.
    pub const RECEIVE_TIME_PORT2: Register<u32> = Register::new(reg::RECEIVE_TIME_PORT2);
    /// 0x090C receive time port 3.
    pub const RECEIVE_TIME_PORT3: Register<u32> = Register::new(reg::RECEIVE_TIME_PORT3);
    /// 0x0910 system time (64-bit DC).
    pub const SYSTEM_TIME: Register<u64> = Register::new(reg::SYSTEM_TIME);
    /// 0x0910 system time on a 32-bit DC slave (and what FRMW drift compensation sends).
    pub const SYSTEM_TIME_32: Register<u32> = Register::new(reg::SYSTEM_TIME);
    /// 0x0918 receive time ECAT processing unit.
    pub const RECEIVE_TIME_EPU: Register<u64> = Register::new(reg::RECEIVE_TIME_EPU);
    /// 0x0920 system time offset (64-bit DC).
    pub const SYSTEM_TIME_OFFSET: Register<u64> = Register::new(reg::SYSTEM_TIME_OFFSET);
    /// 0x0920 system time offset on a 32-bit DC slave.
    pub const SYSTEM_TIME_OFFSET_32: Register<u32> = Register::new(reg::SYSTEM_TIME_OFFSET);
    /// 0x0928 system time delay.
    pub const SYSTEM_TIME_DELAY: Register<u32> = Register::new(reg::SYSTEM_TIME_DELAY);
    /// 0x092C system time difference (sign-magnitude raw word).
    pub const SYSTEM_TIME_DIFFERENCE: Register<u32> = Register::new(reg::SYSTEM_TIME_DIFFERENCE);
    /// 0x0930 speed counter start.
    pub const SPEED_COUNTER_START: Register<u16> = Register::new(reg::SPEED_COUNTER_START);
    /// 0x0932 speed counter diff (two's complement).
    pub const SPEED_COUNTER_DIFF: Register<i16> = Register::new(reg::SPEED_COUNTER_DIFF);
    /// 0x0934 system time difference filter depth.
    pub const SYSTEM_TIME_DIFF_FILTER_DEPTH: Register<u8> =
        Register::new(reg::SYSTEM_TIME_DIFF_FILTER_DEPTH);
    /// 0x0935 speed counter filter depth.
    pub const SPEED_COUNTER_FILTER_DEPTH: Register<u8> =
        Register::new(reg::SPEED_COUNTER_FILTER_DEPTH);
    /// 0x0980 cyclic unit control.
    pub const CYCLIC_UNIT_CONTROL: Register<u8> = Register::new(reg::CYCLIC_UNIT_CONTROL);
    /// 0x0980..0x0981 written together (IgH "AssignActivate").
    pub const ASSIGN_ACTIVATE: Register<u16> = Register::new(reg::CYCLIC_UNIT_CONTROL);
    /// 0x0981 activation.
    pub const SYNC_ACTIVATION: Register<u8> = Register::new(reg::SYNC_ACTIVATION);
    /// 0x0990 start time cyclic operation (64-bit DC).
    pub const SYNC0_START_TIME: Register<u64> = Register::new(reg::SYNC0_START_TIME);
    /// 0x0990 start time on a 32-bit DC slave.
    pub const SYNC0_START_TIME_32: Register<u32> = Register::new(reg::SYNC0_START_TIME);
    /// 0x09A0 SYNC0 cycle time.
    pub const SYNC0_CYCLE: Register<u32> = Register::new(reg::SYNC0_CYCLE);
    /// 0x09A4 SYNC1 cycle time.
    pub const SYNC1_CYCLE: Register<u32> = Register::new(reg::SYNC1_CYCLE);
}

/// 0x0008 ESC Features Supported (REQ-WIRE-071). Bit positions per the Infineon SVD `feature`
/// register and IgH: bit 2 DC available, bit 3 DC width (1 = 64 bit), bit 8 enhanced DC SYNC
/// activation (0x0981 bits 3..7 exist).
///
/// # Examples
///
/// ```
/// use ecdc_core::wire::register::EscFeatures;
///
/// // A 64-bit DC slave with enhanced SYNC activation, read from 0x0008.
/// let f = EscFeatures::parse(&[0x0C, 0x01])?;
/// assert!(f.dc_supported() && f.dc_64bit() && f.enhanced_sync());
/// assert_eq!(f.dc_time_width(), 8);
/// # Ok::<(), ecdc_core::wire::Error>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct EscFeatures(pub u16);

impl EscFeatures {
    /// Bit 2: Distributed Clocks available.
    pub const DC: u16 = 1 << 2;
    /// Bit 3: DC width, 1 = 64 bit.
    pub const DC_64BIT: u16 = 1 << 3;
    /// Bit 8: enhanced DC SYNC activation.
    pub const ENHANCED_SYNC: u16 = 1 << 8;

    /// Decodes from register bytes ([`Error::Truncated`] if fewer than 2).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::wire::{register::EscFeatures, Error};
    ///
    /// assert_eq!(
    ///     EscFeatures::parse(&[0x04, 0x00]),
    ///     Ok(EscFeatures(EscFeatures::DC))
    /// );
    /// assert_eq!(EscFeatures::parse(&[0x04]), Err(Error::Truncated));
    /// ```
    pub fn parse(data: &[u8]) -> Result<EscFeatures> {
        typed::ESC_FEATURES.decode(data).map(EscFeatures)
    }
    /// The raw word.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::wire::register::EscFeatures;
    ///
    /// assert_eq!(EscFeatures(0x010C).raw(), 0x010C);
    /// ```
    pub const fn raw(self) -> u16 {
        self.0
    }
    /// DC unit present.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::wire::register::EscFeatures;
    ///
    /// assert!(EscFeatures(EscFeatures::DC).dc_supported());
    /// assert!(!EscFeatures(0).dc_supported());
    /// ```
    pub const fn dc_supported(self) -> bool {
        self.0 & Self::DC != 0
    }
    /// DC registers are 64 bit wide (else 32).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::wire::register::EscFeatures;
    ///
    /// assert!(EscFeatures(EscFeatures::DC | EscFeatures::DC_64BIT).dc_64bit());
    /// assert!(!EscFeatures(EscFeatures::DC).dc_64bit());
    /// ```
    pub const fn dc_64bit(self) -> bool {
        self.0 & Self::DC_64BIT != 0
    }
    /// Enhanced SYNC activation bits exist in 0x0981.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::wire::register::EscFeatures;
    ///
    /// assert!(EscFeatures(EscFeatures::ENHANCED_SYNC).enhanced_sync());
    /// ```
    pub const fn enhanced_sync(self) -> bool {
        self.0 & Self::ENHANCED_SYNC != 0
    }
    /// Width of System Time / Offset / Start Time on this slave in bytes: 8 or 4.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::wire::register::EscFeatures;
    ///
    /// assert_eq!(
    ///     EscFeatures(EscFeatures::DC | EscFeatures::DC_64BIT).dc_time_width(),
    ///     8
    /// );
    /// assert_eq!(EscFeatures(EscFeatures::DC).dc_time_width(), 4);
    /// ```
    pub const fn dc_time_width(self) -> usize {
        if self.dc_64bit() {
            8
        } else {
            4
        }
    }
}

/// One port's state in [`DlStatus`].
///
/// # Examples
///
/// ```
/// use ecdc_core::wire::register::{DlStatus, PortState};
///
/// // Port 1 has a link and communication; its loop is open, so frames go on through it.
/// let open = PortState {
///     link: true,
///     loop_closed: false,
///     communication: true,
/// };
/// assert_eq!(DlStatus(0x0820).port(1), open);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct PortState {
    /// Physical link detected.
    pub link: bool,
    /// Loop closed (port looped back internally: nothing behind it is reached).
    pub loop_closed: bool,
    /// Communication established on the port.
    pub communication: bool,
}

/// 0x0110 ESC DL Status (REQ-WIRE-072): bits 4..7 physical link on port 0..3; bit 8+2p loop
/// port p (1 = closed); bit 9+2p communication on port p (IgH `ec_slave_set_dl_status`).
/// Bits 0..3 (PDI operational, watchdog, enhanced link detection) are kept in `raw` only:
/// their positions are unverified.
///
/// # Examples
///
/// ```
/// use ecdc_core::wire::register::DlStatus;
///
/// // Link on port 0 and 1; port 0 open with communication, port 1 too, ports 2/3 closed.
/// let dl = DlStatus::parse(&[0x30, 0x5A])?;
/// assert!(dl.link(0) && dl.link(1) && !dl.link(2));
/// assert!(dl.loop_closed(2) && dl.loop_closed(3) && !dl.loop_closed(1));
/// # Ok::<(), ecdc_core::wire::Error>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct DlStatus(pub u16);

impl DlStatus {
    /// Decodes from register bytes ([`Error::Truncated`] if fewer than 2).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::wire::{register::DlStatus, Error};
    ///
    /// assert_eq!(DlStatus::parse(&[0x10, 0x02]), Ok(DlStatus(0x0210)));
    /// assert_eq!(DlStatus::parse(&[]), Err(Error::Truncated));
    /// ```
    pub fn parse(data: &[u8]) -> Result<DlStatus> {
        typed::DL_STATUS.decode(data).map(DlStatus)
    }
    /// The raw word.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::wire::register::DlStatus;
    ///
    /// assert_eq!(DlStatus(0x0210).raw(), 0x0210);
    /// ```
    pub const fn raw(self) -> u16 {
        self.0
    }
    const fn bit(self, n: u32) -> bool {
        match 1u16.checked_shl(n) {
            Some(m) => self.0 & m != 0,
            None => false,
        }
    }
    /// Physical link on `port` (0..=3; false for other ports).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::wire::register::DlStatus;
    ///
    /// let dl = DlStatus(0x0010); // bit 4: link on port 0
    /// assert!(dl.link(0));
    /// assert!(!dl.link(1));
    /// assert!(!dl.link(4)); // no such port
    /// ```
    pub const fn link(self, port: u8) -> bool {
        port < 4 && self.bit((port as u32).wrapping_add(4))
    }
    /// Loop closed on `port` (0..=3; false for other ports).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::wire::register::DlStatus;
    ///
    /// let dl = DlStatus(0x0100); // bit 8: loop port 0 closed
    /// assert!(dl.loop_closed(0));
    /// assert!(!dl.loop_closed(1));
    /// ```
    pub const fn loop_closed(self, port: u8) -> bool {
        port < 4 && self.bit((port as u32).wrapping_mul(2).wrapping_add(8))
    }
    /// Communication on `port` (0..=3; false for other ports).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::wire::register::DlStatus;
    ///
    /// let dl = DlStatus(0x0200); // bit 9: communication on port 0
    /// assert!(dl.communication(0));
    /// assert!(!dl.communication(3));
    /// ```
    pub const fn communication(self, port: u8) -> bool {
        port < 4 && self.bit((port as u32).wrapping_mul(2).wrapping_add(9))
    }
    /// A physical link on any of the four ports (bits 4..7). A slave that answered has a
    /// link on the port the frame entered by, so a reply without one is not a DL status.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::wire::register::DlStatus;
    ///
    /// assert!(DlStatus(0x0080).any_link()); // port 3
    /// assert!(!DlStatus(0x0F00).any_link()); // loops closed, no link
    /// ```
    pub const fn any_link(self) -> bool {
        self.link(0) || self.link(1) || self.link(2) || self.link(3)
    }
    /// All three flags of `port`.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::wire::register::{DlStatus, PortState};
    ///
    /// let p0 = DlStatus(0x0210).port(0);
    /// assert_eq!(
    ///     p0,
    ///     PortState {
    ///         link: true,
    ///         loop_closed: false,
    ///         communication: true
    ///     }
    /// );
    /// ```
    pub const fn port(self, port: u8) -> PortState {
        PortState {
            link: self.link(port),
            loop_closed: self.loop_closed(port),
            communication: self.communication(port),
        }
    }
    /// Encodes the port flags (bits 4..15) over `low_bits` (bits 0..3 kept, higher ignored).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::wire::register::{DlStatus, PortState};
    ///
    /// // A slave at the end of a line: link on port 0 only, ports 1..3 looped back.
    /// let open = PortState {
    ///     link: true,
    ///     loop_closed: false,
    ///     communication: true,
    /// };
    /// let closed = PortState {
    ///     link: false,
    ///     loop_closed: true,
    ///     communication: false,
    /// };
    /// let dl = DlStatus::from_ports([open, closed, closed, closed], 0);
    /// assert_eq!(dl, DlStatus(0x5610));
    /// assert_eq!(dl.port(0), open);
    /// ```
    pub fn from_ports(ports: [PortState; 4], low_bits: u16) -> DlStatus {
        let mut v = low_bits & 0x000F;
        for (p, s) in (0u32..).zip(ports) {
            let twice = p.wrapping_mul(2);
            v |= u16::from(s.link).wrapping_shl(p.wrapping_add(4));
            v |= u16::from(s.loop_closed).wrapping_shl(twice.wrapping_add(8));
            v |= u16::from(s.communication).wrapping_shl(twice.wrapping_add(9));
        }
        DlStatus(v)
    }
}

/// 0x092C System Time Difference (REQ-WIRE-073, REQ-CONV-006): sign-magnitude, bits 30..0 =
/// |Δt| in ns, bit 31 set when Δt < 0, i.e. the slave's local copy is **behind** the received
/// system time. Not an `i32`.
///
/// # Examples
///
/// ```
/// use ecdc_core::wire::register::SystemTimeDifference;
///
/// // Read from 0x092C: bit 31 set, the slave's local copy is 40 ns behind.
/// let d = SystemTimeDifference::parse(&[0x28, 0x00, 0x00, 0x80])?;
/// assert!(d.local_behind());
/// assert_eq!(d.to_ns(), -40);
/// # Ok::<(), ecdc_core::wire::Error>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct SystemTimeDifference(u32);

impl SystemTimeDifference {
    /// Bit 31.
    pub const SIGN: u32 = 0x8000_0000;
    /// Bits 30..0.
    pub const MAGNITUDE: u32 = 0x7FFF_FFFF;

    /// From the raw register word.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::wire::register::SystemTimeDifference;
    ///
    /// assert_eq!(SystemTimeDifference::from_raw(0x8000_0028).to_ns(), -40);
    /// ```
    pub const fn from_raw(raw: u32) -> SystemTimeDifference {
        SystemTimeDifference(raw)
    }
    /// Decodes from register bytes ([`Error::Truncated`] if fewer than 4).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::wire::register::SystemTimeDifference;
    ///
    /// let d = SystemTimeDifference::parse(&[0x0A, 0x00, 0x00, 0x00])?;
    /// assert_eq!(d.to_ns(), 10);
    /// assert!(SystemTimeDifference::parse(&[0x0A, 0x00]).is_err());
    /// # Ok::<(), ecdc_core::wire::Error>(())
    /// ```
    pub fn parse(data: &[u8]) -> Result<SystemTimeDifference> {
        typed::SYSTEM_TIME_DIFFERENCE
            .decode(data)
            .map(SystemTimeDifference)
    }
    /// The raw register word.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::wire::register::SystemTimeDifference;
    ///
    /// assert_eq!(SystemTimeDifference::from_ns(-40).raw(), 0x8000_0028);
    /// ```
    pub const fn raw(self) -> u32 {
        self.0
    }
    /// Bit 31: local copy behind the reference.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::wire::register::SystemTimeDifference;
    ///
    /// assert!(SystemTimeDifference::from_ns(-1).local_behind());
    /// assert!(!SystemTimeDifference::from_ns(1).local_behind());
    /// ```
    pub const fn local_behind(self) -> bool {
        self.0 & Self::SIGN != 0
    }
    /// |Δt| in ns (0..=2^31−1).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::wire::register::SystemTimeDifference;
    ///
    /// assert_eq!(SystemTimeDifference::from_ns(-40).magnitude(), 40);
    /// ```
    pub const fn magnitude(self) -> u32 {
        self.0 & Self::MAGNITUDE
    }
    /// Signed Δt in ns: −magnitude when bit 31 is set. "Negative zero" (0x8000_0000) is 0.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::wire::register::SystemTimeDifference;
    ///
    /// assert_eq!(SystemTimeDifference::from_raw(0x0000_0064).to_ns(), 100);
    /// assert_eq!(SystemTimeDifference::from_raw(0x8000_0064).to_ns(), -100);
    /// // "Negative zero".
    /// assert_eq!(SystemTimeDifference::from_raw(0x8000_0000).to_ns(), 0);
    /// ```
    pub const fn to_ns(self) -> i32 {
        // magnitude ≤ 2^31 − 1, so both the conversion and the negation are exact.
        let m = self.magnitude() as i32;
        if self.local_behind() {
            0i32.wrapping_sub(m)
        } else {
            m
        }
    }
    /// Encodes Δt in ns, saturating |Δt| at 2^31 − 1 (the register's range). 0 encodes as +0.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::wire::register::SystemTimeDifference;
    ///
    /// assert_eq!(SystemTimeDifference::from_ns(-100).raw(), 0x8000_0064);
    /// // Beyond the register's range the magnitude saturates.
    /// assert_eq!(SystemTimeDifference::from_ns(i64::MAX).to_ns(), i32::MAX);
    /// ```
    pub const fn from_ns(ns: i64) -> SystemTimeDifference {
        let mag = ns.unsigned_abs();
        let mag = if mag > Self::MAGNITUDE as u64 {
            Self::MAGNITUDE
        } else {
            let [a, b, c, d, _, _, _, _] = mag.to_le_bytes();
            u32::from_le_bytes([a, b, c, d])
        };
        if ns < 0 {
            SystemTimeDifference(mag | Self::SIGN)
        } else {
            SystemTimeDifference(mag)
        }
    }
}

/// The 32-byte receive-time block 0x0900..0x091F as read in one datagram (REQ-WIRE-074):
/// port receive times 0..3, System Time (0x0910) and the ECAT processing unit receive time.
///
/// # Examples
///
/// ```
/// use ecdc_core::wire::register::ReceiveTimes;
///
/// let times = ReceiveTimes {
///     port: [1_000, 1_900, 0, 0],
///     system_time: 5_000,
///     epu: 1_000,
/// };
/// let mut block = [0u8; ReceiveTimes::LEN];
/// times.emit(&mut block)?;
/// let read = ReceiveTimes::parse(&block)?;
/// // Port 1 saw the frame 900 ns after port 0: the round trip through what is behind port 1.
/// assert_eq!(read.port[1] - read.port[0], 900);
/// # Ok::<(), ecdc_core::wire::Error>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct ReceiveTimes {
    /// Receive Time Port 0..3 (32-bit local time of the latching frame at each port).
    pub port: [u32; 4],
    /// System Time (0x0910..0x0917) as read in the same datagram.
    pub system_time: u64,
    /// Receive Time ECAT Processing Unit (0x0918..0x091F).
    pub epu: u64,
}

impl ReceiveTimes {
    /// Length of the block.
    pub const LEN: usize = 32;

    /// Length of the port receive times that start the block (0x0900..0x090F).
    pub const PORTS_LEN: usize = 16;

    /// Decodes from at least 32 bytes starting at 0x0900 ([`Error::Truncated`] otherwise).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::wire::{register::ReceiveTimes, Error};
    ///
    /// let mut block = [0u8; 32];
    /// block[16..24].copy_from_slice(&7_000u64.to_le_bytes()); // 0x0910 system time
    /// let t = ReceiveTimes::parse(&block)?;
    /// assert_eq!(t.system_time, 7_000);
    /// assert_eq!(ReceiveTimes::parse(&block[..16]), Err(Error::Truncated));
    /// # Ok::<(), Error>(())
    /// ```
    pub fn parse(data: &[u8]) -> Result<ReceiveTimes> {
        let b = data.get(..Self::LEN).ok_or(Error::Truncated)?;
        let (ports, rest) = b
            .split_at_checked(Self::PORTS_LEN)
            .ok_or(Error::Truncated)?;
        let (st, epu) = rest.split_at_checked(8).ok_or(Error::Truncated)?;
        Ok(ReceiveTimes {
            port: Self::parse_ports(ports)?,
            system_time: typed::SYSTEM_TIME.decode(st)?,
            epu: typed::RECEIVE_TIME_EPU.decode(epu)?,
        })
    }

    /// Decodes the four port receive times from at least 16 bytes starting at 0x0900 (a read
    /// of the ports alone, or of the whole block; [`Error::Truncated`] otherwise).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::wire::register::ReceiveTimes;
    ///
    /// // A read of 0x0900..0x090F alone.
    /// let mut ports = [0u8; ReceiveTimes::PORTS_LEN];
    /// ports[4..8].copy_from_slice(&1_900u32.to_le_bytes());
    /// assert_eq!(ReceiveTimes::parse_ports(&ports)?, [0, 1_900, 0, 0]);
    /// # Ok::<(), ecdc_core::wire::Error>(())
    /// ```
    pub fn parse_ports(data: &[u8]) -> Result<[u32; 4]> {
        let b = data.get(..Self::PORTS_LEN).ok_or(Error::Truncated)?;
        let mut port = [0u32; 4];
        for (p, chunk) in port.iter_mut().zip(b.chunks_exact(4)) {
            *p = typed::RECEIVE_TIME_PORT0.decode(chunk)?;
        }
        Ok(port)
    }

    /// Encodes into the first 32 bytes of `out` ([`Error::Truncated`] if shorter).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::wire::{register::ReceiveTimes, Error};
    ///
    /// let t = ReceiveTimes {
    ///     port: [1, 2, 3, 4],
    ///     system_time: 5,
    ///     epu: 6,
    /// };
    /// let mut out = [0u8; 32];
    /// t.emit(&mut out)?;
    /// assert_eq!(out[..4], [1, 0, 0, 0]);
    /// assert_eq!(t.emit(&mut [0u8; 31]), Err(Error::Truncated));
    /// # Ok::<(), Error>(())
    /// ```
    pub fn emit(&self, out: &mut [u8]) -> Result<()> {
        let b = out.get_mut(..Self::LEN).ok_or(Error::Truncated)?;
        let (ports, rest) = b.split_at_mut_checked(16).ok_or(Error::Truncated)?;
        let (st, epu) = rest.split_at_mut_checked(8).ok_or(Error::Truncated)?;
        for (p, chunk) in self.port.iter().zip(ports.chunks_exact_mut(4)) {
            typed::RECEIVE_TIME_PORT0.encode(*p, chunk)?;
        }
        typed::SYSTEM_TIME.encode(self.system_time, st)?;
        typed::RECEIVE_TIME_EPU.encode(self.epu, epu)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every typed register has a width: `len` is its byte count and it is never empty.
    #[test]
    fn typed_registers_have_a_width() {
        assert_eq!(
            (
                typed::SYNC_ACTIVATION.len(),
                typed::SYNC_ACTIVATION.is_empty()
            ),
            (1, false)
        );
        assert_eq!(
            (typed::DL_STATUS.len(), typed::DL_STATUS.is_empty()),
            (2, false)
        );
    }

    /// REQ-WIRE-073: sign-magnitude, bit 31 = local behind = negative.
    // verifies: REQ-WIRE-073
    #[test]
    fn system_time_difference() {
        assert_eq!(SystemTimeDifference::from_raw(0x0000_0010).to_ns(), 16);
        assert_eq!(SystemTimeDifference::from_raw(0x8000_0010).to_ns(), -16);
        assert_eq!(SystemTimeDifference::from_raw(0x8000_0000).to_ns(), 0);
        assert_eq!(
            SystemTimeDifference::from_raw(0xFFFF_FFFF).to_ns(),
            -0x7FFF_FFFF
        );
        assert_eq!(
            SystemTimeDifference::from_raw(0x7FFF_FFFF).to_ns(),
            0x7FFF_FFFF
        );
        assert!(SystemTimeDifference::from_raw(0x8000_0001).local_behind());
        assert_eq!(SystemTimeDifference::from_ns(-16).raw(), 0x8000_0010);
        assert_eq!(SystemTimeDifference::from_ns(16).raw(), 0x10);
        assert_eq!(SystemTimeDifference::from_ns(0).raw(), 0);
        assert_eq!(SystemTimeDifference::from_ns(i64::MIN).raw(), 0xFFFF_FFFF);
        assert_eq!(SystemTimeDifference::from_ns(i64::MAX).raw(), 0x7FFF_FFFF);
        assert_eq!(SystemTimeDifference::from_ns(1 << 31).raw(), 0x7FFF_FFFF);
        assert_eq!(
            SystemTimeDifference::parse(&[0x10, 0, 0, 0x80])
                .unwrap()
                .to_ns(),
            -16
        );
        assert_eq!(
            SystemTimeDifference::parse(&[0, 0, 0]),
            Err(Error::Truncated)
        );
        // encode∘decode is the identity on every non-negative-zero word, sampled densely.
        for raw in (0..=u32::MAX)
            .step_by(65_521)
            .chain([0x8000_0001, 0x7FFF_FFFF])
        {
            let d = SystemTimeDifference::from_raw(raw);
            if raw != 0x8000_0000 {
                assert_eq!(SystemTimeDifference::from_ns(i64::from(d.to_ns())), d);
            }
        }
    }

    /// REQ-WIRE-072: all 2^16 DL status words against bit arithmetic written independently.
    // verifies: REQ-WIRE-072
    #[test]
    fn dl_status_exhaustive() {
        for w in 0..=u16::MAX {
            let s = DlStatus(w);
            let mut ports = [PortState::default(); 4];
            for p in 0..4u8 {
                let link = (w >> (4 + p)) & 1 == 1;
                let lp = (w >> (8 + 2 * p)) & 1 == 1;
                let com = (w >> (9 + 2 * p)) & 1 == 1;
                assert_eq!(s.link(p), link);
                assert_eq!(s.loop_closed(p), lp);
                assert_eq!(s.communication(p), com);
                ports[usize::from(p)] = s.port(p);
            }
            assert_eq!(DlStatus::from_ports(ports, w), s);
            assert_eq!(s.any_link(), w & 0x00F0 != 0);
            for p in 4..=255u8 {
                assert_eq!(s.port(p), PortState::default());
            }
        }
    }

    /// REQ-WIRE-071: features seen on real devices (KickCAT default 0x01CC: DC, 64-bit,
    /// enhanced sync).
    // verifies: REQ-WIRE-071
    #[test]
    fn esc_features() {
        let f = EscFeatures::parse(&[0xCC, 0x01]).unwrap();
        assert!(f.dc_supported() && f.dc_64bit() && f.enhanced_sync());
        assert_eq!(f.dc_time_width(), 8);
        let f = EscFeatures(0x0004);
        assert!(f.dc_supported() && !f.dc_64bit() && !f.enhanced_sync());
        assert_eq!(f.dc_time_width(), 4);
    }

    /// REQ-WIRE-074: a hand-written 32-byte block.
    // verifies: REQ-WIRE-074
    #[test]
    fn receive_times() {
        let block: [u8; 32] = [
            0x01, 0x00, 0x00, 0x00, // port 0 = 1
            0x02, 0x01, 0x00, 0x00, // port 1 = 0x102
            0xff, 0xff, 0xff, 0xff, // port 2 = 0xFFFF_FFFF
            0x00, 0x00, 0x00, 0x80, // port 3 = 0x8000_0000
            0x08, 0x07, 0x06, 0x05, 0x04, 0x03, 0x02, 0x01, // system time
            0x11, 0x22, 0x33, 0x44, 0x55, 0x66, 0x77, 0x88, // EPU
        ];
        let t = ReceiveTimes::parse(&block).unwrap();
        assert_eq!(t.port, [1, 0x102, 0xFFFF_FFFF, 0x8000_0000]);
        assert_eq!(t.system_time, 0x0102_0304_0506_0708);
        assert_eq!(t.epu, 0x8877_6655_4433_2211);
        let mut out = [0u8; 32];
        t.emit(&mut out).unwrap();
        assert_eq!(out, block);
        assert_eq!(ReceiveTimes::parse(&block[..31]), Err(Error::Truncated));
    }

    // verifies: REQ-WIRE-070
    #[test]
    fn typed_registers() {
        assert_eq!(typed::SYSTEM_TIME.width(), 8);
        assert_eq!(typed::SYSTEM_TIME.len(), 8);
        assert_eq!(typed::SYSTEM_TIME_32.width(), 4);
        assert_eq!(typed::SYSTEM_TIME_DIFF_FILTER_DEPTH.width(), 1);
        assert_eq!(typed::SYSTEM_TIME.address(), 0x0910);
        let mut b = [0u8; 8];
        typed::SYSTEM_TIME
            .encode(0x0102_0304_0506_0708, &mut b)
            .unwrap();
        assert_eq!(b, [8, 7, 6, 5, 4, 3, 2, 1]);
        assert_eq!(typed::SYSTEM_TIME.decode(&b[..7]), Err(Error::Truncated));
        assert_eq!(typed::SPEED_COUNTER_DIFF.decode(&[0xff, 0xff]), Ok(-1));
    }
}
