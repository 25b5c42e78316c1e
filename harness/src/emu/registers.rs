//! The register file of one ESC: which bytes exist, which the EtherCAT side may write, and
//! their reset values. Side effects of writes live in `esc.rs`; this file is only the map.
//!
//! Addresses, widths and access follow docs/background/esc-registers.md §2 (Beckhoff Section II) and spec/req/esc.md
//! (REQ-ESC-010..REQ-ESC-031).

use serde::{Deserialize, Serialize};

/// Register addresses the emulator gives meaning to.
pub mod addr {
    pub const TYPE: u16 = 0x0000;
    pub const REVISION: u16 = 0x0001;
    pub const BUILD: u16 = 0x0002;
    pub const FMMUS_SUPPORTED: u16 = 0x0004;
    pub const SYNC_MANAGERS_SUPPORTED: u16 = 0x0005;
    pub const RAM_SIZE: u16 = 0x0006;
    pub const PORT_DESCRIPTOR: u16 = 0x0007;
    pub const FEATURES: u16 = 0x0008;
    pub const STATION_ADDRESS: u16 = 0x0010;
    pub const STATION_ALIAS: u16 = 0x0012;
    pub const DL_CONTROL: u16 = 0x0100;
    pub const DL_STATUS: u16 = 0x0110;
    pub const AL_CONTROL: u16 = 0x0120;
    pub const AL_STATUS: u16 = 0x0130;
    pub const AL_STATUS_CODE: u16 = 0x0134;
    pub const PDI_CONTROL: u16 = 0x0140;
    /// SII EEPROM interface (0x0500..0x050F): configuration, PDI access state,
    /// control/status, word address, data.
    pub const SII_CONFIG: u16 = 0x0500;
    pub const SII_PDI_ACCESS: u16 = 0x0501;
    pub const SII_CONTROL: u16 = 0x0502;
    pub const SII_ADDRESS: u16 = 0x0504;
    pub const SII_DATA: u16 = 0x0508;
    /// SyncManager 0; SyncManager n at SM0 + 8n.
    pub const SM0: u16 = 0x0800;
    pub const FMMU0: u16 = 0x0600;
    pub const RECEIVE_TIME_PORT0: u16 = 0x0900;
    pub const SYSTEM_TIME: u16 = 0x0910;
    pub const RECEIVE_TIME_EPU: u16 = 0x0918;
    pub const SYSTEM_TIME_OFFSET: u16 = 0x0920;
    pub const SYSTEM_TIME_DELAY: u16 = 0x0928;
    pub const SYSTEM_TIME_DIFFERENCE: u16 = 0x092C;
    pub const SPEED_COUNTER_START: u16 = 0x0930;
    pub const SPEED_COUNTER_DIFF: u16 = 0x0932;
    pub const DIFF_FILTER_DEPTH: u16 = 0x0934;
    pub const SPEED_FILTER_DEPTH: u16 = 0x0935;
    pub const RECEIVE_TIME_LATCH_MODE: u16 = 0x0936;
    pub const CYCLIC_UNIT_CONTROL: u16 = 0x0980;
    pub const SYNC_ACTIVATION: u16 = 0x0981;
    pub const SYNC_PULSE_LENGTH: u16 = 0x0982;
    pub const SYNC_ACTIVATION_STATUS: u16 = 0x0984;
    pub const SYNC0_STATUS: u16 = 0x098E;
    pub const SYNC1_STATUS: u16 = 0x098F;
    pub const START_TIME: u16 = 0x0990;
    pub const NEXT_SYNC1: u16 = 0x0998;
    pub const SYNC0_CYCLE: u16 = 0x09A0;
    pub const SYNC1_CYCLE: u16 = 0x09A4;
    pub const LATCH0_CONTROL: u16 = 0x09A8;
    pub const LATCH1_CONTROL: u16 = 0x09A9;
    pub const LATCH0_STATUS: u16 = 0x09AE;
    pub const LATCH1_STATUS: u16 = 0x09AF;
    /// First byte of process RAM.
    pub const PROCESS_RAM: u16 = 0x1000;
}

/// What kind of ESC a slave is. REQ-ESC-060.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum EscKind {
    /// 64-bit DC with system time and enhanced SYNC activation (ET1100 / IP-core like).
    #[default]
    Dc64,
    /// 32-bit DC with system time, no enhanced SYNC activation (ET1200 / ESC20 like).
    Dc32,
    /// Receive-time registers only (0x0900..0x090F), no system time: the master must treat it
    /// as a delay element (docs/background/esc-registers.md §5 "more than 2 ports must at least support receive times").
    DcReceiveTimesOnly,
    /// No DC at all: forwards and processes datagrams, only adds delay.
    NoDc,
}

impl EscKind {
    /// Has the system-time machinery (0x0910..0x09FF).
    pub fn has_system_time(self) -> bool {
        matches!(self, EscKind::Dc64 | EscKind::Dc32)
    }
    /// Latches receive times.
    pub fn has_receive_times(self) -> bool {
        !matches!(self, EscKind::NoDc)
    }
    /// Width of system time, offset and start time.
    pub fn is_64bit(self) -> bool {
        matches!(self, EscKind::Dc64)
    }
    /// 0x0981 bits 3..7 exist (feature bit 8).
    pub fn enhanced_sync(self) -> bool {
        matches!(self, EscKind::Dc64)
    }
    /// Register 0x0008. Bit 2 DC, bit 3 64-bit, bit 6 enhanced link detection MII, bit 7
    /// separate FCS error handling, bit 8 enhanced DC SYNC activation (SVD field list).
    /// REQ-ESC-011.
    pub fn features(self) -> u16 {
        match self {
            EscKind::Dc64 => 0x01CC,
            EscKind::Dc32 => 0x00C4,
            EscKind::DcReceiveTimesOnly => 0x00C4,
            EscKind::NoDc => 0x00C0,
        }
    }
    /// Default ESC type byte (0x0000): 0x11 ET1100, 0x12 ET1200.
    pub fn default_type(self) -> u8 {
        match self {
            EscKind::Dc32 => 0x12,
            _ => 0x11,
        }
    }
}

/// Byte offsets of the upper halves of 64-bit DC registers; a 32-bit DC reads them as 0 and
/// ignores writes to them. REQ-ESC-061.
fn upper_half_of_64bit(a: u16) -> bool {
    matches!(a,
        0x0914..=0x0917 | 0x091C..=0x091F | 0x0924..=0x0927 | 0x0994..=0x0997 |
        0x099C..=0x099F | 0x09B4..=0x09B7 | 0x09BC..=0x09BF | 0x09C4..=0x09C7 | 0x09CC..=0x09CF)
}

/// Reserved bytes inside the DC block: read 0, not writable.
fn reserved_dc(a: u16) -> bool {
    matches!(a, 0x0937..=0x097F | 0x0985..=0x098D | 0x09AA..=0x09AD | 0x09D0..=0x09EF)
}

/// The memory of one ESC: 4 KiB of registers followed by process RAM.
#[derive(Debug, Clone)]
pub struct RegisterFile {
    kind: EscKind,
    mem: Vec<u8>,
    /// Some FMMU among the first `min(0x0004, 16)` has its enable bit set (kept up to date
    /// by every store; lets logical datagrams skip the table scan).
    fmmu_on: bool,
}

/// Stores to these bytes can change [`RegisterFile::any_fmmu_enabled`].
fn touches_fmmu(a: usize, len: usize) -> bool {
    let fmmus = usize::from(addr::FMMU0)..usize::from(addr::FMMU0) + 16 * 16;
    let n = usize::from(addr::FMMUS_SUPPORTED);
    (a < fmmus.end && a + len > fmmus.start) || (a <= n && a + len > n)
}

/// Little-endian typed reads (and writes) of the register file, one pair per width.
macro_rules! le_accessors {
    ($($get:ident $(, $set:ident)?: $t:ty;)*) => {
        $(
            #[inline]
            pub fn $get(&self, a: u16) -> $t {
                <$t>::from_le_bytes(self.get_n(a))
            }
            $(
                #[inline]
                pub fn $set(&mut self, a: u16, v: $t) {
                    self.set_n(a, &v.to_le_bytes());
                }
            )?
        )*
    };
}

impl RegisterFile {
    /// A register file in its power-on state.
    pub fn new(kind: EscKind, ram_bytes: u16, ports: u8, esc_type: u8, pulse_len: u16) -> Self {
        let len = usize::from(addr::PROCESS_RAM) + usize::from(ram_bytes);
        let mut r = RegisterFile {
            kind,
            mem: vec![0; len],
            fmmu_on: false,
        };
        r.set_u8(addr::TYPE, esc_type);
        r.set_u8(addr::REVISION, 0x02);
        r.set_u16(addr::BUILD, 0x0001);
        r.set_u8(addr::FMMUS_SUPPORTED, 8);
        r.set_u8(addr::SYNC_MANAGERS_SUPPORTED, 8);
        r.set_u8(addr::RAM_SIZE, (ram_bytes / 1024) as u8);
        // Port descriptor: 2 bits per port, 0b11 = MII, 0b00 = not implemented.
        let mut pd = 0u8;
        for p in 0..ports.min(4) {
            pd |= 0b11 << (2 * p);
        }
        r.set_u8(addr::PORT_DESCRIPTOR, pd);
        r.set_u16(addr::FEATURES, kind.features());
        r.set_u8(addr::DL_CONTROL, 0x01);
        r.set_u16(addr::AL_STATUS, 0x0001);
        if kind.has_system_time() {
            r.set_u16(
                addr::SPEED_COUNTER_START,
                super::control_loop::SPEED_COUNTER_START_RESET,
            );
            r.set_u8(
                addr::DIFF_FILTER_DEPTH,
                super::control_loop::DIFF_FILTER_DEPTH_RESET,
            );
            r.set_u8(
                addr::SPEED_FILTER_DEPTH,
                super::control_loop::SPEED_FILTER_DEPTH_RESET,
            );
            r.set_u16(addr::SYNC_PULSE_LENGTH, pulse_len);
        }
        r
    }

    /// Kind of this ESC.
    #[inline]
    pub fn kind(&self) -> EscKind {
        self.kind
    }

    /// Whether the byte at `a` exists (an access touching only missing bytes does not count
    /// in the working counter). REQ-ESC-012.
    #[inline]
    pub fn implemented(&self, a: u16) -> bool {
        if usize::from(a) >= self.mem.len() {
            return false;
        }
        match a {
            0x0900..=0x09FF => match self.kind {
                EscKind::Dc64 | EscKind::Dc32 => true,
                EscKind::DcReceiveTimesOnly => a <= 0x090F,
                EscKind::NoDc => false,
            },
            _ => true,
        }
    }

    /// Static EtherCAT-side write permission of one byte (dynamic gates, e.g. the start time
    /// while the SYNC unit is active, are applied by the ESC). REQ-ESC-013.
    pub fn ecat_writable(&self, a: u16) -> bool {
        if !self.implemented(a) {
            return false;
        }
        if !self.kind.is_64bit() && upper_half_of_64bit(a) {
            return false;
        }
        if reserved_dc(a) {
            return false;
        }
        // SII interface: written through its own rules (emu/sii.rs), never stored directly.
        // SyncManager status (+5) and PDI control (+7) are read-only from ECAT.
        if (0x0500..=0x050F).contains(&a)
            || ((0x0800..=0x087F).contains(&a) && matches!(a & 7, 5 | 7))
        {
            return false;
        }
        !matches!(a,
            0x0000..=0x000F | 0x0012..=0x0013 | 0x0110..=0x0111 | 0x0130..=0x013F |
            0x0900..=0x091F | 0x092C..=0x092F | 0x0932..=0x0933 | 0x0982..=0x098F |
            0x0998..=0x099F | 0x09AE..=0x09FF)
    }

    /// Raw byte (0 outside memory).
    #[inline]
    pub fn get_u8(&self, a: u16) -> u8 {
        self.mem.get(usize::from(a)).copied().unwrap_or(0)
    }
    /// Raw byte store (ignored outside memory).
    #[inline]
    pub fn set_u8(&mut self, a: u16, v: u8) {
        if let Some(b) = self.mem.get_mut(usize::from(a)) {
            *b = v;
        }
        if touches_fmmu(usize::from(a), 1) {
            self.refresh_fmmu();
        }
    }

    fn refresh_fmmu(&mut self) {
        let nf = usize::from(self.get_u8(addr::FMMUS_SUPPORTED).min(16));
        let start = usize::from(addr::FMMU0);
        self.fmmu_on = self
            .mem
            .get(start..start + 16 * nf)
            .is_some_and(|t| t.chunks_exact(16).any(|f| f[12] & 0x01 != 0));
    }

    /// Whether some FMMU among the first `min(0x0004, 16)` is enabled (0x060C bit 0 etc.).
    #[inline]
    pub fn any_fmmu_enabled(&self) -> bool {
        self.fmmu_on
    }
    #[inline]
    fn get_n<const N: usize>(&self, a: u16) -> [u8; N] {
        let a = usize::from(a);
        if let Some(s) = self.mem.get(a..a + N) {
            let mut out = [0u8; N];
            out.copy_from_slice(s);
            return out;
        }
        let mut out = [0u8; N];
        for (i, o) in out.iter_mut().enumerate() {
            *o = self.mem.get(a + i).copied().unwrap_or(0);
        }
        out
    }
    #[inline]
    fn set_n(&mut self, a: u16, bytes: &[u8]) {
        let a = usize::from(a);
        if let Some(s) = self.mem.get_mut(a..a + bytes.len()) {
            s.copy_from_slice(bytes);
        } else {
            for (i, b) in bytes.iter().enumerate() {
                if let Some(m) = self.mem.get_mut(a + i) {
                    *m = *b;
                }
            }
        }
        if touches_fmmu(a, bytes.len()) {
            self.refresh_fmmu();
        }
    }
    /// Raw memory (for fast scans such as the FMMU table).
    #[inline]
    pub fn bytes(&self) -> &[u8] {
        &self.mem
    }
    le_accessors! {
        get_u16, set_u16: u16;
        get_u32, set_u32: u32;
        get_u64: u64;
    }
    /// Stores a 64-bit DC value; on a 32-bit DC only the low half is kept.
    #[inline]
    pub fn set_dc64(&mut self, a: u16, v: u64) {
        if self.kind.is_64bit() {
            self.set_n(a, &v.to_le_bytes());
        } else {
            self.set_u32(a, v as u32);
        }
    }
    /// Whole memory length.
    pub fn len(&self) -> usize {
        self.mem.len()
    }
    /// Never empty (kept for clippy's `len_without_is_empty`).
    pub fn is_empty(&self) -> bool {
        self.mem.is_empty()
    }
}

#[cfg(test)]
mod test {
    use super::*;

    /// REQ-ESC-014: DC reset values.
    // verifies: REQ-ESC-014
    #[test]
    fn reset_values() {
        let r = RegisterFile::new(EscKind::Dc64, 4096, 2, 0x11, 100);
        assert_eq!(r.get_u16(addr::SPEED_COUNTER_START), 0x1000);
        assert_eq!(r.get_u8(addr::DIFF_FILTER_DEPTH), 4);
        assert_eq!(r.get_u8(addr::SPEED_FILTER_DEPTH), 0x0C);
        assert_eq!(r.get_u16(addr::FEATURES), 0x01CC);
        assert_eq!(r.get_u16(addr::AL_STATUS), 1);
        assert_eq!(r.get_u8(addr::PORT_DESCRIPTOR), 0x0F);
        assert_eq!(r.get_u32(addr::SYSTEM_TIME_DIFFERENCE), 0);
    }

    #[test]
    fn access_rules() {
        let r = RegisterFile::new(EscKind::Dc32, 4096, 2, 0x12, 100);
        assert!(!r.ecat_writable(0x0924));
        assert!(r.ecat_writable(0x0920));
        assert!(!r.ecat_writable(0x092C));
        assert!(r.ecat_writable(0x0930));
        assert!(!r.ecat_writable(0x0012));
        let n = RegisterFile::new(EscKind::NoDc, 4096, 2, 0x11, 100);
        assert!(!n.implemented(0x0910));
        let rt = RegisterFile::new(EscKind::DcReceiveTimesOnly, 4096, 3, 0x11, 100);
        assert!(rt.implemented(0x090F));
        assert!(!rt.implemented(0x0910));
    }

    /// The cached "some FMMU enabled" flag follows every store that can change it: byte and
    /// multi-byte stores over the enable bytes, only FMMUs below 0x0004 counting.
    #[test]
    fn fmmu_enabled_flag_tracks_stores() {
        let mut r = RegisterFile::new(EscKind::Dc64, 4096, 2, 0x11, 100);
        let scan = |r: &RegisterFile| {
            let nf = usize::from(r.get_u8(addr::FMMUS_SUPPORTED).min(16));
            (0..nf).any(|f| r.get_u8(addr::FMMU0 + 16 * f as u16 + 12) & 1 != 0)
        };
        assert!(!r.any_fmmu_enabled());
        r.set_u8(addr::FMMU0 + 16 * 3 + 12, 0x01);
        assert!(r.any_fmmu_enabled() && scan(&r));
        r.set_u32(addr::FMMU0 + 16 * 3 + 12, 0);
        assert!(!r.any_fmmu_enabled() && !scan(&r));
        // FMMU 9 is beyond the 8 this ESC has.
        r.set_u8(addr::FMMU0 + 16 * 9 + 12, 0x01);
        assert!(!r.any_fmmu_enabled() && !scan(&r));
        r.set_u8(addr::FMMUS_SUPPORTED, 10);
        assert!(r.any_fmmu_enabled() && scan(&r));
        r.set_dc64(addr::FMMU0 + 16 * 9 + 8, 0);
        assert!(!r.any_fmmu_enabled() && !scan(&r));
    }
}
