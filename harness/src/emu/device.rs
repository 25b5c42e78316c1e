//! The slave behind the ESC: which device a scenario slave is (its SII image, its
//! SyncManager layout) and what its application does with process data.
//!
//! Two device kinds have built images: `io8` (8 digital outputs, 8 digital inputs, one byte
//! each way) and `servo` (control word + 32-bit target position out, status word + 32-bit
//! actual position in). `bare` is an ESC without process data (a coupler-like slave): it
//! has an image with identity and strings only and goes to OP without SyncManagers, as
//! ecdc's own bring-up and DC-only masters expect. Layout of the categories: ETG.2010
//! (docs/background/sii-al.md §2).

use super::sii::{
    config_crc, Category, Identity, SiiImage, CATEGORY_START_WORD, MIN_CAPACITY_BYTES,
};
use serde::{Deserialize, Serialize};

/// What sits behind the ESC.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Device {
    /// No process data, no mailbox (unless asked): identity only.
    #[default]
    Bare,
    /// 8 digital outputs + 8 digital inputs.
    Io8,
    /// Servo-like: control word + target position out, status word + actual position in.
    Servo,
}

/// ecdc choice: a vendor ID for built images. 0x0000ECDC is not an ETG-assigned ID that
/// ecdc knows of; scenarios that must look like a real product set `vendor`.
pub const DEFAULT_VENDOR: u32 = 0x0000_ECDC;

impl Device {
    /// ecdc choice: product codes of the built images (no real product behind them).
    pub fn default_product(self) -> u32 {
        match self {
            Device::Bare => 0x0000_0001,
            Device::Io8 => 0x0000_0008,
            Device::Servo => 0x0000_0402,
        }
    }
    /// Device name, group and order number strings of the built images (ecdc choice).
    fn strings(self) -> (&'static str, &'static str, &'static str) {
        match self {
            Device::Bare => ("ecdc bare ESC", "ecdc", "ECDC-BARE"),
            Device::Io8 => ("ecdc IO8 8DO/8DI", "DigIO", "ECDC-IO8"),
            Device::Servo => ("ecdc servo (CSP)", "Drive", "ECDC-SERVO"),
        }
    }
    /// (output bytes, input bytes) of the process data.
    pub fn process_bytes(self) -> (u16, u16) {
        match self {
            Device::Bare => (0, 0),
            Device::Io8 => (1, 1),
            Device::Servo => (6, 6),
        }
    }
}

/// The SyncManagers of built images, one per [`sm_type`], enabled. Process RAM addresses are
/// an ecdc choice: mailboxes (128 bytes each) at the start of process RAM, process data after
/// them, as Beckhoff terminals lay them out; a process-data length here is a placeholder for
/// the device's. Control bytes: datasheet 0x0804, bits 1:0 mode 00 buffered / 10 mailbox,
/// bits 3:2 direction 00 ECAT reads / 01 ECAT writes, bit 5 PDI interrupt, bit 6 watchdog.
pub mod built_sm {
    use super::{sm_type, SmEntry};

    const fn sm(start: u16, len: u16, control: u8, typ: u8) -> SmEntry {
        SmEntry {
            start,
            len,
            control,
            enable: 1,
            typ,
        }
    }

    pub const MBX_OUT: SmEntry = sm(0x1000, 128, 0x26, sm_type::MBX_OUT);
    pub const MBX_IN: SmEntry = sm(0x1080, 128, 0x22, sm_type::MBX_IN);
    pub const PD_OUT: SmEntry = sm(0x1100, 0, 0x64, sm_type::PD_OUT);
    pub const PD_IN: SmEntry = sm(0x1180, 0, 0x20, sm_type::PD_IN);
}

/// SyncManager types of the SII SyncManager category (ETG.2010).
pub mod sm_type {
    pub const MBX_OUT: u8 = 1;
    pub const MBX_IN: u8 = 2;
    pub const PD_OUT: u8 = 3;
    pub const PD_IN: u8 = 4;
}

/// Everything a built image holds.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BuildSpec {
    pub device: Device,
    /// Identity words and device name string (default name: the device's).
    pub identity: Identity,
    /// SYNC pulse length, word 2 (10 ns units).
    pub pulse_len: u16,
    /// A standard mailbox (SM0/SM1); no protocol is served on it.
    pub mailbox: bool,
    /// The ESC has DC (adds the DC category).
    pub dc: bool,
}

/// One SyncManager as the SII describes it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SmEntry {
    pub start: u16,
    pub len: u16,
    pub control: u8,
    pub enable: u8,
    pub typ: u8,
}

fn push_category(w: &mut Vec<u16>, typ: Category, bytes: &[u8]) {
    let words: Vec<u16> = bytes
        .chunks(2)
        .map(|c| u16::from_le_bytes([c[0], c.get(1).copied().unwrap_or(0)]))
        .collect();
    w.push(typ.0);
    w.push(words.len() as u16);
    w.extend(words);
}

/// A PDO entry: object index, subindex, data type, bit length.
type PdoEntry = (u16, u8, u8, u8);

/// One PDO of a PDO category: index, SM, entries.
fn pdo(out: &mut Vec<u8>, index: u16, sm: u8, entries: &[PdoEntry]) {
    out.extend_from_slice(&index.to_le_bytes());
    out.push(entries.len() as u8);
    out.push(sm);
    out.push(0); // synchronisation
    out.push(0); // name index
    out.extend_from_slice(&0u16.to_le_bytes()); // flags
    for &(i, s, dt, bits) in entries {
        out.extend_from_slice(&i.to_le_bytes());
        out.push(s);
        out.push(0); // name index
        out.push(dt);
        out.push(bits);
        out.extend_from_slice(&0u16.to_le_bytes());
    }
}

impl BuildSpec {
    /// The SyncManagers of this device, in SM order.
    pub fn sync_managers(&self) -> Vec<SmEntry> {
        let mut v = Vec::new();
        if self.mailbox {
            v.extend([built_sm::MBX_OUT, built_sm::MBX_IN]);
        }
        let (o, i) = self.device.process_bytes();
        let pd_out = SmEntry {
            len: o,
            ..built_sm::PD_OUT
        };
        let pd_in = SmEntry {
            len: i,
            ..built_sm::PD_IN
        };
        v.extend([pd_out, pd_in].into_iter().filter(|sm| sm.len > 0));
        v
    }

    /// The SII image (ETG.2010 layout), CRC included. REQ-ESC-024.
    pub fn build(&self) -> SiiImage {
        let mut w = vec![0u16; CATEGORY_START_WORD];
        // Word 0: PDI control (0x0140) 0x05 = 32-bit digital I/O (ecdc choice: a PDI with
        // no microcontroller protocol to emulate); word 1 PDI configuration 0.
        w[0] = 0x0005;
        w[2] = self.pulse_len;
        let id = &self.identity;
        w[4] = id.alias;
        w[7] = u16::from(config_crc(&w));
        for (k, v) in [id.vendor, id.product, id.revision, id.serial]
            .into_iter()
            .enumerate()
        {
            w[8 + 2 * k] = v as u16;
            w[9 + 2 * k] = (v >> 16) as u16;
        }
        if self.mailbox {
            w[0x18] = built_sm::MBX_OUT.start;
            w[0x19] = built_sm::MBX_OUT.len;
            w[0x1A] = built_sm::MBX_IN.start;
            w[0x1B] = built_sm::MBX_IN.len;
            w[0x1C] = 0; // no mailbox protocol is served
        }
        w[0x3E] = (MIN_CAPACITY_BYTES * 8 / 1024 - 1) as u16; // size in Kbit − 1
        w[0x3F] = 1; // version
        let (dname, group, order) = self.device.strings();
        let name = id.name.as_deref().unwrap_or(dname);
        // Strings: 1 = device name, 2 = group, 3 = order number.
        let mut s = vec![3u8];
        for t in [name, group, order] {
            let b = &t.as_bytes()[..t.len().min(255)];
            s.push(b.len() as u8);
            s.extend_from_slice(b);
        }
        push_category(&mut w, Category::STRINGS, &s);
        let mut g = [0u8; 32];
        g[0] = 2; // group index
        g[2] = 3; // order index
        g[3] = 1; // name index
        g[0x0E] = 2; // group index again (ETG.2010 keeps a copy for old masters)
                     // Physical ports (4 bits each: 1 = MII): two ports (ecdc choice; informational).
        g[0x10] = 0x11;
        push_category(&mut w, Category::GENERAL, &g);
        let sms = self.sync_managers();
        let (o, i) = self.device.process_bytes();
        if o > 0 || i > 0 {
            let mut f = Vec::new();
            if o > 0 {
                f.push(1); // outputs
            }
            if i > 0 {
                f.push(2); // inputs
            }
            push_category(&mut w, Category::FMMU, &f);
            let mut b = Vec::new();
            for e in &sms {
                b.extend_from_slice(&e.start.to_le_bytes());
                b.extend_from_slice(&e.len.to_le_bytes());
                b.extend_from_slice(&[e.control, 0, e.enable, e.typ]);
            }
            push_category(&mut w, Category::SYNC_MANAGER, &b);
            let sm_of = |t: u8| sms.iter().position(|e| e.typ == t).unwrap_or(0) as u8;
            let (tx, rx): (Vec<PdoEntry>, Vec<PdoEntry>) = match self.device {
                // BOOL = 0x0001, INTEGER32 = 0x0004, UNSIGNED16 = 0x0006 (ETG.1000.6 types).
                Device::Io8 => (
                    (1..=8).map(|k| (0x6000, k, 0x01, 1)).collect(),
                    (1..=8).map(|k| (0x7000, k, 0x01, 1)).collect(),
                ),
                Device::Servo => (
                    vec![(0x6041, 0, 0x06, 16), (0x6064, 0, 0x04, 32)],
                    vec![(0x6040, 0, 0x06, 16), (0x607A, 0, 0x04, 32)],
                ),
                Device::Bare => (Vec::new(), Vec::new()),
            };
            let mut t = Vec::new();
            pdo(&mut t, 0x1A00, sm_of(sm_type::PD_IN), &tx);
            push_category(&mut w, Category::TXPDO, &t);
            let mut r = Vec::new();
            pdo(&mut r, 0x1600, sm_of(sm_type::PD_OUT), &rx);
            push_category(&mut w, Category::RXPDO, &r);
        }
        if self.dc && self.device != Device::Bare {
            // One operation mode: SYNC0 synchronous, assign-activate 0x0300 (0x0980/0x0981
            // values: SYNC0 + cyclic unit active), cycle and shifts given by the master.
            let mut d = [0u8; 24];
            d[14..16].copy_from_slice(&0x0300u16.to_le_bytes());
            push_category(&mut w, Category::DC, &d);
        }
        w.push(Category::END.0);
        let mut bytes: Vec<u8> = w.iter().flat_map(|x| x.to_le_bytes()).collect();
        bytes.resize(bytes.len().max(2 * CATEGORY_START_WORD), 0xFF);
        SiiImage::padded(&bytes)
    }
}

/// The SyncManager category of an image (the layout the slave's firmware checks).
pub fn sync_managers_of(img: &SiiImage) -> Vec<SmEntry> {
    let Some(d) = img.category(Category::SYNC_MANAGER) else {
        return Vec::new();
    };
    let b: Vec<u8> = d.iter().flat_map(|w| w.to_le_bytes()).collect();
    b.chunks_exact(8)
        .map(|c| SmEntry {
            start: u16::from_le_bytes([c[0], c[1]]),
            len: u16::from_le_bytes([c[2], c[3]]),
            control: c[4],
            enable: c[6],
            typ: c[7],
        })
        .collect()
}

/// The application of a built device: what it does with outputs and which inputs it
/// produces. Model choices (the point is a plausible, checkable data path, not a product):
/// io8 inputs are wired to its outputs; the servo reports its control word back as the status
/// word and follows the target position exactly.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Application {
    device: Device,
    /// Outputs the device drives: the last ones received in OP; zero (safe state) outside
    /// OP (ETG.1000.6: outputs are in safe state in SAFEOP).
    applied: Vec<u8>,
    /// Servo: actual position (held when outputs go to safe state).
    position: i32,
}

impl Application {
    pub fn new(device: Device) -> Self {
        let (o, _) = device.process_bytes();
        Application {
            device,
            applied: vec![0; usize::from(o)],
            position: 0,
        }
    }

    pub fn device(&self) -> Device {
        self.device
    }

    /// Outputs as the device drives them.
    pub fn applied(&self) -> &[u8] {
        &self.applied
    }

    /// Takes the outputs the master wrote (in OP), or the safe state (elsewhere).
    pub fn take_outputs(&mut self, out: Option<&[u8]>) {
        match out {
            Some(o) => {
                let n = self.applied.len().min(o.len());
                self.applied[..n].copy_from_slice(&o[..n]);
                if self.device == Device::Servo && n >= 6 {
                    self.position = i32::from_le_bytes([o[2], o[3], o[4], o[5]]);
                }
            }
            None => self.applied.iter_mut().for_each(|b| *b = 0),
        }
    }

    /// The inputs the device presents now.
    pub fn inputs(&self) -> Vec<u8> {
        match self.device {
            Device::Bare => Vec::new(),
            Device::Io8 => vec![self.applied.first().copied().unwrap_or(0)],
            Device::Servo => {
                let mut v = vec![0u8; 6];
                v[..2].copy_from_slice(&self.applied[..2]);
                v[2..].copy_from_slice(&self.position.to_le_bytes());
                v
            }
        }
    }
}
