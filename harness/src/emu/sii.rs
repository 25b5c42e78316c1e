//! The slave information interface (SII): the EEPROM image every ESC carries and the
//! register interface 0x0500..0x050F through which a master reads, writes and reloads it.
//!
//! Image layout (ETG.2010, "EEPROM content"): words 0..7 are the ESC configuration area
//! (word 2 SYNC pulse length, word 4 configured station alias, word 7 CRC-8 of bytes 0..13),
//! words 8..15 the identity (vendor, product code, revision, serial number, each u32), words
//! 0x18..0x1C the standard mailbox, 0x3E the EEPROM size and 0x3F the version; categories
//! start at word 0x40 (type word, size in words, data) and end with type 0xFFFF.
//! Register interface: Beckhoff ESC datasheet Section II, "SII EEPROM Interface"
//! (0x0500..0x050F). docs/background/sii-al.md collects both, with what is a model choice.

use super::registers::{addr, RegisterFile};
use serde::{Deserialize, Serialize};

/// Word address where the categories start (ETG.2010).
pub const CATEGORY_START_WORD: usize = 0x40;

/// Largest image the interface accepts, bytes: 4 Mbit, the largest EEPROM the ESC's two-byte
/// address algorithm addresses (datasheet, 0x0502 bit 7).
pub const MAX_IMAGE_BYTES: usize = 512 * 1024;

/// A category type (ETG.2010, "Category types"). Types this emulator does not know, such as
/// vendor-specific ones, are kept as they are.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Category(pub u16);

impl Category {
    /// Strings (names the other categories refer to by index).
    pub const STRINGS: Category = Category(10);
    /// General (group, image and name indices, CoE/FoE details, ports).
    pub const GENERAL: Category = Category(30);
    /// FMMU usage.
    pub const FMMU: Category = Category(40);
    /// SyncManager layout (start, length, control, enable, type per SyncManager).
    pub const SYNC_MANAGER: Category = Category(41);
    /// Transmit PDOs (the slave's inputs).
    pub const TXPDO: Category = Category(50);
    /// Receive PDOs (the slave's outputs).
    pub const RXPDO: Category = Category(51);
    /// Distributed-clock operation modes.
    pub const DC: Category = Category(60);
    /// The type word that ends the category list.
    pub const END: Category = Category(0xFFFF);
}

/// CRC-8 of the configuration area (ETG.2010): polynomial x^8 + x^2 + x + 1 (0x07), initial
/// value 0xFF, no reflection, no final XOR, over bytes 0..13 (words 0..6).
pub fn crc8(bytes: &[u8]) -> u8 {
    let mut crc: u8 = 0xFF;
    for b in bytes {
        crc ^= b;
        for _ in 0..8 {
            crc = if crc & 0x80 != 0 {
                (crc << 1) ^ 0x07
            } else {
                crc << 1
            };
        }
    }
    crc
}

/// CRC-8 over words 0..6 of an image given as words.
pub fn config_crc(words: &[u16]) -> u8 {
    let mut b = [0xFFu8; 14];
    for (i, w) in words.iter().take(7).enumerate() {
        b[2 * i..2 * i + 2].copy_from_slice(&w.to_le_bytes());
    }
    crc8(&b)
}

/// Who a slave says it is: SII words 4 and 8..15 and the device name string.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Identity {
    pub vendor: u32,
    pub product: u32,
    pub revision: u32,
    pub serial: u32,
    /// Configured station alias, SII word 4.
    pub alias: u16,
    /// The General category's device name string, if the image has one.
    pub name: Option<String>,
}

/// Why an image file cannot be used at all. Images that load but are wrong (bad CRC,
/// truncated, odd length) are not errors: the ESC shows them through 0x0502 as a real one
/// does.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SiiError {
    /// The file could not be read.
    Io(String),
    /// The file is empty.
    Empty,
    /// Larger than [`MAX_IMAGE_BYTES`].
    TooLarge(usize),
}

impl core::fmt::Display for SiiError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            SiiError::Io(m) => write!(f, "cannot read the SII image: {m}"),
            SiiError::Empty => write!(f, "the SII image is empty"),
            SiiError::TooLarge(n) => write!(
                f,
                "the SII image has {n} bytes; an ESC addresses at most {MAX_IMAGE_BYTES}"
            ),
        }
    }
}

impl std::error::Error for SiiError {}

/// An EEPROM's content as 16-bit words, padded with 0xFFFF (erased cells) to the EEPROM's
/// capacity (a power of two, at least 2 KiB: ecdc choice, the 16 Kbit EEPROM of the
/// smallest ESC designs, so that a built image has room to grow by SII writes).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SiiImage {
    words: Vec<u16>,
    /// Bytes the file or builder gave (the rest is erased padding).
    content_bytes: usize,
}

/// Word 7 value that makes the ESC skip the CRC check (Section I, "ESC Configuration Area":
/// for debugging only).
pub const CRC_BYPASS: u16 = 0x88A4;

/// Smallest capacity, bytes (see [`SiiImage`]).
pub const MIN_CAPACITY_BYTES: usize = 2048;

impl SiiImage {
    /// From raw bytes in the order SOEM's eepromtool and `ethercat sii_read` write them
    /// (little-endian words from word 0). An odd last byte is completed with 0xFF, the value
    /// of an erased cell; a file shorter than the configuration area reads 0xFF beyond its
    /// end and so fails the CRC, as a partly programmed EEPROM would.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, SiiError> {
        if bytes.is_empty() {
            return Err(SiiError::Empty);
        }
        if bytes.len() > MAX_IMAGE_BYTES {
            return Err(SiiError::TooLarge(bytes.len()));
        }
        Ok(Self::padded(bytes))
    }

    /// [`SiiImage::from_bytes`] without the size checks (for images built here).
    pub(crate) fn padded(bytes: &[u8]) -> Self {
        let cap = bytes.len().next_power_of_two().max(MIN_CAPACITY_BYTES) / 2;
        let mut words = vec![0xFFFFu16; cap];
        for (w, c) in words.iter_mut().zip(bytes.chunks(2)) {
            let lo = c.first().copied().unwrap_or(0xFF);
            let hi = c.get(1).copied().unwrap_or(0xFF);
            *w = u16::from_le_bytes([lo, hi]);
        }
        SiiImage {
            words,
            content_bytes: bytes.len(),
        }
    }

    /// Reads an image file.
    pub fn load(path: &std::path::Path) -> Result<Self, SiiError> {
        let b =
            std::fs::read(path).map_err(|e| SiiError::Io(format!("{}: {e}", path.display())))?;
        Self::from_bytes(&b)
    }

    /// All words, including the erased padding.
    pub fn words(&self) -> &[u16] {
        &self.words
    }

    /// The content as bytes (without the erased padding beyond what was given).
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut b: Vec<u8> = self.words.iter().flat_map(|w| w.to_le_bytes()).collect();
        b.truncate(self.content_bytes.max(2 * CATEGORY_START_WORD));
        b
    }

    /// Capacity in bytes.
    pub fn capacity_bytes(&self) -> usize {
        2 * self.words.len()
    }

    /// Word `i` (addresses wrap modulo the capacity: an EEPROM ignores address bits it does
    /// not have).
    pub fn word(&self, i: u32) -> u16 {
        let n = self.words.len().max(1);
        self.words
            .get(usize::try_from(i).unwrap_or(0) % n)
            .copied()
            .unwrap_or(0xFFFF)
    }

    fn set_word(&mut self, i: u32, v: u16) {
        let n = self.words.len().max(1);
        let k = usize::try_from(i).unwrap_or(0) % n;
        if let Some(w) = self.words.get_mut(k) {
            *w = v;
        }
        self.content_bytes = self.content_bytes.max(2 * k + 2);
    }

    /// Whether word 7's low byte matches the CRC-8 of words 0..6.
    pub fn crc_ok(&self) -> bool {
        (self.word(7) & 0xFF) as u8 == config_crc(&self.words)
    }

    /// Whether the ESC accepts the configuration area: a right CRC, or word 7 = 0x88A4,
    /// the value the datasheet names to skip the check for debugging.
    pub fn config_ok(&self) -> bool {
        self.crc_ok() || self.word(7) == CRC_BYPASS
    }

    fn u32_at(&self, w: u32) -> u32 {
        u32::from(self.word(w)) | (u32::from(self.word(w + 1)) << 16)
    }

    /// The categories from word 0x40 on: (type, data words), stopping at the end marker, at
    /// the end of the image or at a category that runs past it.
    pub fn categories(&self) -> Vec<(Category, &[u16])> {
        let mut out = Vec::new();
        let mut i = CATEGORY_START_WORD;
        while let (Some(&typ), Some(&len)) = (self.words.get(i), self.words.get(i + 1)) {
            if Category(typ) == Category::END {
                break;
            }
            let start = i + 2;
            let Some(data) = self.words.get(start..start + usize::from(len)) else {
                break;
            };
            out.push((Category(typ & 0x7FFF), data));
            i = start + usize::from(len);
        }
        out
    }

    /// The data words of the first category of type `typ`.
    pub fn category(&self, typ: Category) -> Option<&[u16]> {
        self.categories()
            .into_iter()
            .find(|(t, _)| *t == typ)
            .map(|(_, data)| data)
    }

    /// String `idx` (1-based) of the Strings category; `None` for 0 or a missing string.
    pub fn string(&self, idx: u8) -> Option<String> {
        if idx == 0 {
            return None;
        }
        let data = self.category(Category::STRINGS)?;
        let bytes: Vec<u8> = data.iter().flat_map(|w| w.to_le_bytes()).collect();
        let n = *bytes.first()?;
        let mut p = 1usize;
        for k in 1..=n {
            let len = usize::from(*bytes.get(p)?);
            let s = bytes.get(p + 1..p + 1 + len)?;
            if k == idx {
                return Some(String::from_utf8_lossy(s).into_owned());
            }
            p += 1 + len;
        }
        None
    }

    /// Identity words and the General category's device name.
    pub fn identity(&self) -> Identity {
        let name_idx = self
            .category(Category::GENERAL)
            .and_then(|d| d.get(1).map(|w| (w >> 8) as u8));
        Identity {
            vendor: self.u32_at(8),
            product: self.u32_at(0x0A),
            revision: self.u32_at(0x0C),
            serial: self.u32_at(0x0E),
            alias: self.word(4),
            name: name_idx.and_then(|i| self.string(i)),
        }
    }
}

/// Access timing of the EEPROM interface: how long 0x0502 shows busy per command. The
/// datasheet gives no durations (they depend on the EEPROM and its I2C clock); all three are
/// model choices, scenario inputs (`SlaveDefaults::sii_*`), and tests show the data a master
/// reads does not depend on them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SiiTiming {
    /// Bytes one read command delivers: 4 or 8 (0x0502 bit 6 advertises which). Default 8,
    /// what ET1100-class ESCs advertise.
    pub read_bytes: u8,
    /// Busy time of a read, ns. Model choice 100 µs: an I2C read of 8 data bytes plus
    /// addressing (≈ 110 bit times) at a 1 MHz clock.
    pub read_ns: u64,
    /// Busy time of a one-word write, ns. Model choice 5 ms: the maximum write-cycle time
    /// typical of I2C EEPROMs (24Cxx family).
    pub write_ns: u64,
    /// Busy time of a reload of the configuration area, ns. Model choice 200 µs: two reads.
    pub reload_ns: u64,
}

impl Default for SiiTiming {
    fn default() -> Self {
        SiiTiming {
            read_bytes: 8,
            read_ns: 100_000,
            write_ns: 5_000_000,
            reload_ns: 200_000,
        }
    }
}

/// 0x0502/0x0503 bits (datasheet, "EEPROM Control/Status").
pub mod ctl {
    pub const WRITE_ENABLE: u16 = 1 << 0;
    pub const READ_8_BYTES: u16 = 1 << 6;
    pub const TWO_ADDRESS_BYTES: u16 = 1 << 7;
    pub const CMD_MASK: u16 = 0x0700;
    pub const CMD_READ: u16 = 0x0100;
    pub const CMD_WRITE: u16 = 0x0200;
    pub const CMD_RELOAD: u16 = 0x0400;
    pub const CHECKSUM_ERROR: u16 = 1 << 11;
    pub const NOT_LOADED: u16 = 1 << 12;
    pub const ACK_ERROR: u16 = 1 << 13;
    pub const WRITE_ERROR: u16 = 1 << 14;
    pub const BUSY: u16 = 1 << 15;
}

/// What the configuration area gives the ESC when it loads correctly.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ConfigArea {
    /// Word 0: PDI control (0x0140) and ESC configuration (0x0141).
    pub pdi_control: u16,
    /// Word 2: SYNC pulse length (0x0982).
    pub pulse_len: u16,
    /// Word 4: configured station alias (0x0012).
    pub alias: u16,
}

/// A command that finished; the ESC applies its effects.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Completed {
    Read,
    Write,
    /// Reload: the configuration area, if its CRC is right.
    Reload(Option<ConfigArea>),
}

/// The EEPROM and its interface state. Register bytes 0x0500..0x050F live in the ESC's
/// register file; this keeps them consistent.
#[derive(Debug, Clone)]
pub struct Sii {
    image: SiiImage,
    timing: SiiTiming,
    /// A command in progress: (command bits, completes at true time).
    running: Option<u16>,
    /// The PDI holds the interface (0x0501 bit 0). No PDI is emulated; tests set it to show
    /// that ECAT is locked out then.
    pdi_owns: bool,
}

impl Sii {
    pub fn new(image: SiiImage, timing: SiiTiming) -> Self {
        Sii {
            image,
            timing,
            running: None,
            pdi_owns: false,
        }
    }

    pub fn image(&self) -> &SiiImage {
        &self.image
    }

    /// Status bits that describe the interface itself (read-only).
    fn static_bits(&self) -> u16 {
        let mut v = 0;
        if self.timing.read_bytes == 8 {
            v |= ctl::READ_8_BYTES;
        }
        if self.image.capacity_bytes() > MIN_CAPACITY_BYTES {
            // More than 16 Kbit needs the two-address-byte algorithm.
            v |= ctl::TWO_ADDRESS_BYTES;
        }
        v
    }

    /// Power-up (or a reset): the interface is idle, the ESC loads the configuration area
    /// (REQ-ESC-023).
    /// Returns it when the CRC is right (else 0x0502 shows the checksum error and "not
    /// loaded", and the registers keep their reset values).
    pub fn power_up(&mut self, regs: &mut RegisterFile) -> Option<ConfigArea> {
        self.running = None;
        self.pdi_owns = false;
        regs.set_u8(addr::SII_CONFIG, 0);
        regs.set_u8(addr::SII_PDI_ACCESS, 0);
        regs.set_u32(addr::SII_ADDRESS, 0);
        regs.set_u32(addr::SII_DATA, 0);
        regs.set_u32(addr::SII_DATA + 4, 0);
        let (bits, area) = self.load_config();
        regs.set_u16(addr::SII_CONTROL, self.static_bits() | bits);
        area
    }

    fn load_config(&self) -> (u16, Option<ConfigArea>) {
        if self.image.config_ok() {
            let area = ConfigArea {
                pdi_control: self.image.word(0),
                pulse_len: self.image.word(2),
                alias: self.image.word(4),
            };
            (0, Some(area))
        } else {
            (ctl::CHECKSUM_ERROR | ctl::NOT_LOADED, None)
        }
    }

    /// Whether the last load of the configuration area succeeded (DL status bit 0 "PDI
    /// operational / EEPROM loaded correctly").
    pub fn loaded(&self, regs: &RegisterFile) -> bool {
        regs.get_u16(addr::SII_CONTROL) & ctl::NOT_LOADED == 0
    }

    /// The PDI takes (true) or releases (false) the interface (0x0501 bit 0). It can take it
    /// only while ECAT offers it (0x0500 bit 0) and no command runs. Returns whether the PDI
    /// holds the interface afterwards.
    pub fn set_pdi_access(&mut self, regs: &mut RegisterFile, on: bool) -> bool {
        let offered = regs.get_u8(addr::SII_CONFIG) & 0x01 != 0;
        if !on || (offered && self.running.is_none()) {
            self.pdi_owns = on;
            regs.set_u8(addr::SII_PDI_ACCESS, u8::from(on));
        }
        self.pdi_owns
    }

    /// Start of a frame at this ESC: the write-enable bit clears itself (datasheet: "self
    /// clearing at the SOF of the next frame"; REQ-ESC-022).
    pub fn on_sof(&mut self, regs: &mut RegisterFile) {
        let c = regs.get_u16(addr::SII_CONTROL);
        if c & ctl::WRITE_ENABLE != 0 {
            regs.set_u16(addr::SII_CONTROL, c & !ctl::WRITE_ENABLE);
        }
    }

    /// Applies the ECAT writes of one datagram to 0x0500..0x050F (`staged[k]` = the byte
    /// written to 0x0500 + k, if any). Returns how long a command started now keeps the
    /// interface busy; the ESC calls [`Sii::complete`] after that time. REQ-ESC-021/022.
    pub fn ecat_write(
        &mut self,
        staged: &[Option<u8>; 16],
        regs: &mut RegisterFile,
    ) -> Option<u64> {
        if let Some(b) = staged[0] {
            // 0x0500: bit 0 "PDI may take over", bit 1 "force ECAT access" (resets 0x0501.0).
            regs.set_u8(addr::SII_CONFIG, b & 0x03);
            if b & 0x02 != 0 {
                self.set_pdi_access(regs, false);
            }
        }
        // 0x0501 is read-only from ECAT. The rest is ECAT's only while ECAT owns the
        // interface and it is idle.
        if self.pdi_owns || self.running.is_some() {
            return None;
        }
        for (k, b) in staged.iter().enumerate().skip(4) {
            if let Some(b) = b {
                regs.set_u8(addr::SII_CONFIG + k as u16, *b);
            }
        }
        let mut c = regs.get_u16(addr::SII_CONTROL);
        if let Some(b) = staged[2] {
            c = (c & !ctl::WRITE_ENABLE) | (u16::from(b) & ctl::WRITE_ENABLE);
        }
        let Some(hi) = staged[3] else {
            regs.set_u16(addr::SII_CONTROL, c);
            return None;
        };
        let cmd = (u16::from(hi) << 8) & ctl::CMD_MASK;
        // Any command value, including "no command", clears the error bits.
        c &= !(ctl::ACK_ERROR | ctl::WRITE_ERROR);
        let dur = match cmd {
            0 => None,
            ctl::CMD_READ => Some(self.timing.read_ns),
            ctl::CMD_RELOAD => Some(self.timing.reload_ns),
            ctl::CMD_WRITE if c & ctl::WRITE_ENABLE != 0 => Some(self.timing.write_ns),
            ctl::CMD_WRITE => {
                c |= ctl::WRITE_ERROR;
                None
            }
            _ => {
                // Two command bits at once: an invalid command.
                c |= ctl::ACK_ERROR;
                None
            }
        };
        if dur.is_some() {
            self.running = Some(cmd);
            c = (c & !ctl::CMD_MASK) | cmd | ctl::BUSY;
        }
        regs.set_u16(addr::SII_CONTROL, c);
        dur
    }

    /// The running command finishes: data, image or configuration area change, busy and
    /// the command bits clear (REQ-ESC-022; a reload per REQ-ESC-023).
    pub fn complete(&mut self, regs: &mut RegisterFile) -> Option<Completed> {
        let cmd = self.running.take()?;
        let a = regs.get_u32(addr::SII_ADDRESS);
        let mut c = regs.get_u16(addr::SII_CONTROL) & !(ctl::BUSY | ctl::CMD_MASK);
        let done = match cmd {
            ctl::CMD_READ => {
                let n = u32::from(self.timing.read_bytes / 2);
                for k in 0..n {
                    let w = self.image.word(a.wrapping_add(k));
                    regs.set_u16(addr::SII_DATA + 2 * k as u16, w);
                }
                Completed::Read
            }
            ctl::CMD_WRITE => {
                self.image.set_word(a, regs.get_u16(addr::SII_DATA));
                Completed::Write
            }
            _ => {
                // A failed reload sets the checksum error; the device-information bit (and
                // everything else the area initialises) keeps its value.
                let (_, area) = self.load_config();
                c &= !ctl::CHECKSUM_ERROR;
                match area {
                    Some(_) => c &= !ctl::NOT_LOADED,
                    None => c |= ctl::CHECKSUM_ERROR,
                }
                Completed::Reload(area)
            }
        };
        regs.set_u16(addr::SII_CONTROL, c);
        Some(done)
    }
}

#[cfg(test)]
mod test {
    use super::*;

    #[test]
    fn odd_and_short_images_pad_with_erased_cells() {
        let i = SiiImage::from_bytes(&[1, 2, 3]).unwrap();
        assert_eq!(i.word(0), 0x0201);
        assert_eq!(i.word(1), 0xFF03);
        assert_eq!(i.word(2), 0xFFFF);
        assert_eq!(i.capacity_bytes(), MIN_CAPACITY_BYTES);
        assert!(!i.crc_ok());
        assert_eq!(SiiImage::from_bytes(&[]), Err(SiiError::Empty));
        let big = vec![0u8; MAX_IMAGE_BYTES + 1];
        assert_eq!(
            SiiImage::from_bytes(&big),
            Err(SiiError::TooLarge(MAX_IMAGE_BYTES + 1))
        );
        assert!(i.categories().is_empty());
    }

    #[test]
    fn category_walk_stops_at_an_overrun() {
        let mut b = vec![0u8; 2 * CATEGORY_START_WORD];
        b.extend_from_slice(&[30, 0, 0xFF, 0x7F]);
        let i = SiiImage::from_bytes(&b).unwrap();
        assert!(i.categories().is_empty());
        assert_eq!(i.identity().name, None);
    }
}
