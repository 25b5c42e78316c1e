//! Scenario: everything that makes a run reproducible — topology, delays, oscillator errors,
//! faults and the seed. Loadable from TOML or JSON (serde) and buildable in code.
//!
//! Example (see harness/scenarios/*.toml):
//! ```toml
//! seed = 7
//! [defaults]
//! ppm = { uniform = { min = -50.0, max = 50.0 } }
//! [[slaves]]
//! repeat = 10            # ten slaves in a line
//! [[faults]]
//! at_ns = 2_000_000_000
//! kind = "link_break"
//! slave = 5
//! port = 0
//! ```

use super::control_loop::LoopGains;
use super::device::{BuildSpec, Device, DEFAULT_VENDOR};
use super::fault::{Fault, FaultSpec};
use super::registers::EscKind;
use super::sii::{Identity, SiiImage, SiiTiming};
use super::EmuError;
use serde::{Deserialize, Serialize};

/// Seed 000 Table 2, row "传输补偿值" (delay compensation, 0x0928) for slaves 2–6, ns: what the
/// paper's master wrote on its six-slave line (Chen et al. 2025, §4, Table 2).
pub const SEED000_TABLE2_DELAYS_NS: [u32; 5] = [105, 206, 310, 410, 520];

/// t_P of [`Scenario::seed000_line`], ns. Calibration, not a datasheet value: Table 2's
/// least-squares slope of 103.4 ns per hop, minus the 1 m cable (5 ns, DS S1-88) and the mean
/// PHY jitter of one cable traversal (4 ns, half of [`Timing::phy_jitter_ns`]), rounded down.
pub const SEED000_T_P_NS: u64 = 94;

/// t_F of [`Scenario::seed000_line`], ns. Model choice: t_Diff = t_P − t_F = 10 ns. The paper
/// gives no t_F (only that t_Diff depends on the PHY medium); 10 ns is one DC tick and the size
/// of the excess of Table 2's last slave over the trend of the others (7.5 ns), which the last
/// case of eq. 23 as printed adds. Positive because the processing path (through the EPU) is
/// the longer one.
pub const SEED000_T_F_NS: u64 = 84;

/// Global timing model. Defaults marked "model" have no source (docs/emulator.md §Constants).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Timing {
    /// Observation quantum of local time (10 ns: 100 MHz DC clock). 1 disables quantisation.
    pub tick_ns: u64,
    /// PHY jitter per hop: uniform in [0, phy_jitter_ns] ns added to every cable traversal
    /// (model). 0 makes hop times exact.
    pub phy_jitter_ns: u64,
    /// SYNC output jitter: uniform in [0, sync_jitter_ns] ns added to recorded edges (model;
    /// the 10 ns quantisation is already in the clock).
    pub sync_jitter_ns: u64,
    /// Cable delay per metre (≈ 5 ns/m, DS S1-88).
    pub cable_ns_per_m: f64,
    /// Cable from the master to the first slave, metres.
    pub master_cable_m: f64,
    /// Local times at true time 0 are uniform in [0, power_on_spread_ns) (slaves powered up at
    /// different instants before the run). Model.
    pub power_on_spread_ns: u64,
    /// Frequency wander piece length, ns (0 = no wander). Model.
    pub wander_interval_ns: u64,
    /// Standard deviation of the wander step per piece, ppb. Model.
    pub wander_step_ppb: f64,
    /// Mean reversion of the wander, in pieces. Model.
    pub wander_revert_pieces: f64,
}

impl Default for Timing {
    fn default() -> Self {
        Timing {
            tick_ns: 10,
            phy_jitter_ns: 8,
            sync_jitter_ns: 0,
            cable_ns_per_m: 5.0,
            master_cable_m: 1.0,
            power_on_spread_ns: 5_000_000_000,
            wander_interval_ns: 100_000_000,
            wander_step_ppb: 2.0,
            wander_revert_pieces: 600.0,
        }
    }
}

/// How a slave's crystal error is drawn.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum PpmSpec {
    /// Uniform in [min, max] ppm.
    Uniform { min: f64, max: f64 },
    /// Normal(mean, sd) ppm, clipped to ±limit.
    Normal { mean: f64, sd: f64, limit: f64 },
    /// Exactly this value.
    Fixed(f64),
}

impl Default for PpmSpec {
    fn default() -> Self {
        PpmSpec::Uniform {
            min: -50.0,
            max: 50.0,
        }
    }
}

/// Values every slave gets unless its own spec overrides them.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SlaveDefaults {
    pub kind: EscKind,
    /// Number of ports (2..=4).
    pub ports: u8,
    /// Processing delay t_P: port 0 RX → EPU → next port TX, ns (model).
    pub t_p_ns: u64,
    /// Forwarding delay t_F: port n RX → next port TX, ns (model).
    pub t_f_ns: u64,
    /// Cable into the slave's port 0, metres.
    pub cable_m: f64,
    pub ppm: PpmSpec,
    /// Process RAM, bytes.
    pub ram_bytes: u16,
    /// 0x0982 SYNC pulse length, 10 ns units (EEPROM value; model default 1 µs).
    pub pulse_len: u16,
    /// Extra time, ns, a frame spends turning round at a downstream port that DL control
    /// 0x0101 forces closed (loop bits 0b11), compared with a port closed because nothing is
    /// connected. Model default 0: both loop back in the port logic at no cost
    /// (docs/emulator.md "Closed ports"); a non-zero value shows how the t_Diff measurement,
    /// which closes ports, depends on that assumption.
    pub forced_loop_ns: u64,
    /// The device behind the ESC (`bare`, `io8`, `servo`): its SII image and process data.
    pub device: Device,
    /// A standard mailbox (SM0/SM1 in the SII); nothing is served on it.
    pub mailbox: bool,
    /// Identity words of built images (default: ecdc's vendor ID and the device's product
    /// code, revision 1).
    pub vendor: Option<u32>,
    pub product: Option<u32>,
    pub revision: Option<u32>,
    /// EEPROM interface: bytes per read (4 or 8) and busy times (model choices).
    pub sii: SiiTiming,
}

impl Default for SlaveDefaults {
    fn default() -> Self {
        SlaveDefaults {
            kind: EscKind::Dc64,
            ports: 2,
            t_p_ns: 540,
            t_f_ns: 460,
            cable_m: 1.0,
            ppm: PpmSpec::default(),
            ram_bytes: 4096,
            pulse_len: 100,
            forced_loop_ns: 0,
            device: Device::Bare,
            mailbox: false,
            vendor: None,
            product: None,
            revision: None,
            sii: SiiTiming::default(),
        }
    }
}

/// One slave, or `repeat` identical slaves in a line.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SlaveSpec {
    /// Free text for reports; also the device name string of a built SII image.
    pub name: Option<String>,
    /// Instantiate this many copies, each attached to the previous one (port 1).
    pub repeat: usize,
    pub kind: Option<EscKind>,
    pub ports: Option<u8>,
    /// Index of the slave this one's port 0 is cabled to (default: the previous slave; the
    /// first slave is always cabled to the master).
    pub parent: Option<usize>,
    /// Port of the parent (default: the parent's first free port among 1, 2, 3).
    pub port: Option<u8>,
    pub cable_m: Option<f64>,
    pub t_p_ns: Option<u64>,
    pub t_f_ns: Option<u64>,
    /// Fixed crystal error, ppm (overrides the distribution).
    pub ppm: Option<f64>,
    /// 0x0012 station alias (from EEPROM).
    pub alias: u16,
    /// 0x0010 at the start of the run, as if a master had already addressed it (it resets to
    /// 0 on a power cycle). 0 = not addressed.
    pub station: u16,
    /// Raw local time at true time 0 (overrides the power-on spread).
    pub initial_local_ns: Option<u64>,
    /// 0x0000 type byte.
    pub esc_type: Option<u8>,
    /// [`SlaveDefaults::forced_loop_ns`] of this slave.
    pub forced_loop_ns: Option<u64>,
    /// [`SlaveDefaults::device`] of this slave.
    pub device: Option<Device>,
    pub vendor: Option<u32>,
    pub product: Option<u32>,
    pub revision: Option<u32>,
    /// Serial number (default: position + 1; with `repeat`, consecutive numbers).
    pub serial: Option<u32>,
    pub mailbox: Option<bool>,
    /// An SII image file (the binary layout SOEM's eepromtool and `ethercat sii_read`
    /// write) instead of a built image. Relative paths are relative to the scenario file.
    /// The identity, alias and SyncManagers then come from the file.
    pub sii_file: Option<std::path::PathBuf>,
}

impl Default for SlaveSpec {
    fn default() -> Self {
        SlaveSpec {
            name: None,
            repeat: 1,
            kind: None,
            ports: None,
            parent: None,
            port: None,
            cable_m: None,
            t_p_ns: None,
            t_f_ns: None,
            ppm: None,
            alias: 0,
            station: 0,
            initial_local_ns: None,
            esc_type: None,
            forced_loop_ns: None,
            device: None,
            vendor: None,
            product: None,
            revision: None,
            serial: None,
            mailbox: None,
            sii_file: None,
        }
    }
}

/// A complete, reproducible emulator setup.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Scenario {
    /// Seed of every random stream (ppm draw, power-on phase, jitter, wander, loss).
    pub seed: u64,
    pub timing: Timing,
    pub defaults: SlaveDefaults,
    pub slaves: Vec<SlaveSpec>,
    /// Probability that a frame is corrupted somewhere on its path (it does not return and
    /// slaves after the corruption commit nothing).
    pub frame_loss_rate: f64,
    /// Gains of the ESC control-loop law (model).
    pub loop_gains: LoopGains,
    pub faults: Vec<FaultSpec>,
}

impl Default for Scenario {
    fn default() -> Self {
        Scenario {
            seed: 0,
            timing: Timing::default(),
            defaults: SlaveDefaults::default(),
            slaves: Vec::new(),
            frame_loss_rate: 0.0,
            loop_gains: LoopGains::default(),
            faults: Vec::new(),
        }
    }
}

/// A slave after defaults, repeats and the topology have been resolved.
#[derive(Debug, Clone, PartialEq)]
pub struct ResolvedSlave {
    pub name: Option<String>,
    pub kind: EscKind,
    pub ports: u8,
    /// (parent index, parent port); `None` = cabled to the master.
    pub parent: Option<(usize, u8)>,
    pub cable_m: f64,
    pub t_p_ns: u64,
    pub t_f_ns: u64,
    pub ppm: Option<f64>,
    pub alias: u16,
    pub station: u16,
    pub initial_local_ns: Option<u64>,
    pub esc_type: Option<u8>,
    pub forced_loop_ns: u64,
    /// Where the EEPROM content comes from.
    pub sii: SiiSource,
    /// The application behind the ESC (`Bare` for image files).
    pub device: Device,
}

/// The EEPROM content of a resolved slave.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SiiSource {
    Built(BuildSpec),
    File(std::path::PathBuf),
}

impl SiiSource {
    /// The image (reads the file for `File`).
    pub fn image(&self) -> Result<SiiImage, super::sii::SiiError> {
        match self {
            SiiSource::Built(b) => Ok(b.build()),
            SiiSource::File(p) => SiiImage::load(p),
        }
    }
}

impl Scenario {
    /// `n` default slaves in a line.
    pub fn line(n: usize) -> Self {
        Scenario {
            slaves: vec![SlaveSpec {
                repeat: n,
                ..SlaveSpec::default()
            }],
            ..Scenario::default()
        }
    }

    /// Seed 000's test line (§4: six slaves in a line), with hop delays calibrated to its
    /// Table 2 delay row (105 / 206 / 310 / 410 / 520 ns for slaves 2–6, least-squares
    /// 103.4 ns per hop through the origin): t_P = [`SEED000_T_P_NS`], t_F =
    /// [`SEED000_T_F_NS`], 1 m cables. Everything else (crystals, jitter, wander) is the
    /// emulator default. docs/background/seed000-line.md gives the derivation.
    pub fn seed000_line() -> Self {
        let mut sc = Scenario::line(6);
        sc.defaults.t_p_ns = SEED000_T_P_NS;
        sc.defaults.t_f_ns = SEED000_T_F_NS;
        sc.defaults.cable_m = 1.0;
        sc
    }

    /// `n` default slaves as a tree: slave 0 a 4-port junction, the other `n − 1` in three
    /// branches on its ports 3, 1 and 2 (processing order) of ⌈(n−1)/3⌉, ⌊(n−1)/3⌋ and the
    /// rest; an empty branch is left out.
    pub fn junction_tree(n: usize) -> Self {
        let mut v = vec![SlaveSpec {
            ports: Some(4),
            ..SlaveSpec::default()
        }];
        let rest = n.saturating_sub(1);
        let a = rest.div_ceil(3);
        let b = rest / 3;
        for (port, size) in [3u8, 1, 2].into_iter().zip([a, b, rest - a - b]) {
            if size > 0 {
                v.push(SlaveSpec {
                    repeat: size,
                    parent: Some(0),
                    port: Some(port),
                    ..SlaveSpec::default()
                });
            }
        }
        Scenario {
            slaves: v,
            ..Scenario::default()
        }
    }

    /// A 100-slave tree in processing (auto-increment) order: 10 groups, each a junction and
    /// its branches (even groups: a 3-port junction, a branch of 9 on port 1; odd groups: a
    /// 4-port junction, branches of 2 on port 3 and of 7 on port 1); the next junction hangs on
    /// port 2. Default slaves and seed otherwise.
    pub fn tree_100() -> Self {
        let mut sc = Scenario::default();
        let mut prev: Option<usize> = None;
        let mut i = 0usize;
        for g in 0..10 {
            let four = g % 2 == 1;
            let j = i;
            sc.slaves.push(SlaveSpec {
                ports: Some(if four { 4 } else { 3 }),
                parent: prev,
                port: prev.map(|_| 2),
                ..SlaveSpec::default()
            });
            i += 1;
            let branches: &[(usize, u8)] = if four { &[(2, 3), (7, 1)] } else { &[(9, 1)] };
            for &(repeat, port) in branches {
                sc.slaves.push(SlaveSpec {
                    repeat,
                    parent: Some(j),
                    port: Some(port),
                    ..SlaveSpec::default()
                });
                i += repeat;
            }
            prev = Some(j);
        }
        debug_assert_eq!(i, 100);
        sc
    }

    /// Appends a slave spec (builder style).
    pub fn with_slave(mut self, s: SlaveSpec) -> Self {
        self.slaves.push(s);
        self
    }

    /// Appends a fault at a true time (builder style).
    pub fn with_fault(mut self, at_ns: u64, fault: Fault) -> Self {
        self.faults.push(FaultSpec { at_ns, fault });
        self
    }

    /// Jitter, wander and quantisation off: hop times and clocks are exact (for tests).
    pub fn ideal(mut self) -> Self {
        self.timing.phy_jitter_ns = 0;
        self.timing.sync_jitter_ns = 0;
        self.timing.wander_interval_ns = 0;
        self.timing.wander_step_ppb = 0.0;
        self
    }

    /// Parses TOML.
    pub fn from_toml_str(s: &str) -> Result<Self, EmuError> {
        toml::from_str(s).map_err(|e| EmuError::Scenario(e.to_string()))
    }

    /// Parses JSON.
    pub fn from_json_str(s: &str) -> Result<Self, EmuError> {
        serde_json::from_str(s).map_err(|e| EmuError::Scenario(e.to_string()))
    }

    /// Loads a `.toml` or `.json` file (by extension; anything else is tried as TOML).
    pub fn load(path: &std::path::Path) -> Result<Self, EmuError> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| EmuError::Scenario(format!("{}: {e}", path.display())))?;
        let mut sc = if path.extension().is_some_and(|e| e == "json") {
            Self::from_json_str(&text)?
        } else {
            Self::from_toml_str(&text)?
        };
        // Image files are named relative to the scenario file.
        if let Some(dir) = path.parent() {
            for s in &mut sc.slaves {
                if let Some(f) = s.sii_file.as_mut() {
                    if f.is_relative() {
                        *f = dir.join(&*f);
                    }
                }
            }
        }
        Ok(sc)
    }

    /// Serialises to TOML.
    pub fn to_toml_string(&self) -> Result<String, EmuError> {
        toml::to_string(self).map_err(|e| EmuError::Scenario(e.to_string()))
    }

    /// Expands repeats and defaults and checks the topology.
    pub fn resolve(&self) -> Result<Vec<ResolvedSlave>, EmuError> {
        let d = &self.defaults;
        let mut out: Vec<ResolvedSlave> = Vec::new();
        let mut used: Vec<[bool; 4]> = Vec::new();
        for spec in &self.slaves {
            for r in 0..spec.repeat {
                let i = out.len();
                let ports = spec.ports.unwrap_or(d.ports);
                if !(2..=4).contains(&ports) {
                    return Err(EmuError::Scenario(format!(
                        "slave {i}: ports must be 2..=4, got {ports}"
                    )));
                }
                let parent = if i == 0 {
                    None
                } else {
                    let p = if r == 0 {
                        spec.parent.unwrap_or(i - 1)
                    } else {
                        i - 1
                    };
                    if p >= i {
                        return Err(EmuError::Scenario(format!(
                            "slave {i}: parent {p} must come before it"
                        )));
                    }
                    let pports = out[p].ports;
                    let port = match (r, spec.port) {
                        (0, Some(q)) => q,
                        _ => [1u8, 2, 3]
                            .into_iter()
                            .find(|q| *q < pports && !used[p][usize::from(*q)])
                            .ok_or_else(|| {
                                EmuError::Scenario(format!(
                                    "slave {i}: parent {p} has no free port"
                                ))
                            })?,
                    };
                    if port == 0 || port >= pports || used[p][usize::from(port)] {
                        return Err(EmuError::Scenario(format!(
                            "slave {i}: port {port} of slave {p} is invalid or taken"
                        )));
                    }
                    used[p][usize::from(port)] = true;
                    Some((p, port))
                };
                if spec.parent.is_some() && i == 0 {
                    return Err(EmuError::Scenario(
                        "slave 0 is cabled to the master and has no parent".into(),
                    ));
                }
                let kind = spec.kind.unwrap_or(d.kind);
                let device = spec.device.unwrap_or(d.device);
                let (sii, device) = match &spec.sii_file {
                    Some(f) => (SiiSource::File(f.clone()), Device::Bare),
                    None => (
                        SiiSource::Built(BuildSpec {
                            device,
                            identity: Identity {
                                vendor: spec.vendor.or(d.vendor).unwrap_or(DEFAULT_VENDOR),
                                product: spec
                                    .product
                                    .or(d.product)
                                    .unwrap_or(device.default_product()),
                                revision: spec.revision.or(d.revision).unwrap_or(1),
                                serial: spec
                                    .serial
                                    .map(|x| x.wrapping_add(r as u32))
                                    .unwrap_or((i as u32).wrapping_add(1)),
                                alias: spec.alias,
                                name: spec.name.clone(),
                            },
                            pulse_len: d.pulse_len,
                            mailbox: spec.mailbox.unwrap_or(d.mailbox),
                            dc: kind.has_system_time(),
                        }),
                        device,
                    ),
                };
                out.push(ResolvedSlave {
                    name: spec.name.clone(),
                    kind,
                    ports,
                    parent,
                    cable_m: spec.cable_m.unwrap_or(d.cable_m),
                    t_p_ns: spec.t_p_ns.unwrap_or(d.t_p_ns),
                    t_f_ns: spec.t_f_ns.unwrap_or(d.t_f_ns),
                    ppm: spec.ppm,
                    alias: spec.alias,
                    station: spec.station,
                    initial_local_ns: spec.initial_local_ns,
                    esc_type: spec.esc_type,
                    forced_loop_ns: spec.forced_loop_ns.unwrap_or(d.forced_loop_ns),
                    sii,
                    device,
                });
                let mut u = [false; 4];
                u[0] = true;
                used.push(u);
            }
        }
        if !(0.0..=1.0).contains(&self.frame_loss_rate) {
            return Err(EmuError::Scenario(
                "frame_loss_rate must be in [0, 1]".into(),
            ));
        }
        if self.timing.tick_ns == 0 {
            return Err(EmuError::Scenario("tick_ns must be ≥ 1".into()));
        }
        if !matches!(d.sii.read_bytes, 4 | 8) {
            return Err(EmuError::Scenario(
                "defaults.sii.read_bytes must be 4 or 8".into(),
            ));
        }
        Ok(out)
    }
}

/// Most slaves a scenario may hold. Auto-increment (position) addressing counts slaves in the
/// 16-bit ADP field, so a segment has at most 65 536 positions (IEC 61158-4-12 datagram
/// header; docs/background/cli-inputs.md); ecdc choice: one fewer, so that the slave count
/// itself fits a u16.
pub const MAX_SLAVES: usize = 65_535;

/// Largest |crystal error| a scenario may give, ppm: at −10^6 ppm a clock stands still and
/// beyond it runs backwards, which no oscillator model here represents.
pub const MAX_ABS_PPM: f64 = 1e6;

impl Scenario {
    /// Checks that the scenario makes sense before anything is built: at least one slave, at
    /// most [`MAX_SLAVES`], parents that exist and come earlier, ports that the ESC has,
    /// finite and in-range numbers, faults that name existing slaves and ports and that fall
    /// inside the run (`run_ns`: the run length, `None` = open-ended), then everything
    /// [`Scenario::resolve`] checks. The message names the slave or fault and the valid range.
    pub fn validate(&self, run_ns: Option<u64>) -> Result<(), EmuError> {
        let bad = |m: String| Err(EmuError::Scenario(m));
        let d = &self.defaults;
        // Expanded slave index -> port count, to check parents and fault ports.
        let mut ports_of: Vec<u8> = Vec::new();
        for (k, spec) in self.slaves.iter().enumerate() {
            if spec.repeat == 0 {
                return bad(format!(
                    "slaves[{k}]: repeat = 0 adds no slave; remove the entry or use repeat >= 1"
                ));
            }
            let first = ports_of.len();
            if first.saturating_add(spec.repeat) > MAX_SLAVES {
                return bad(format!(
                    "more than {MAX_SLAVES} slaves (the 16-bit position address limit)"
                ));
            }
            let ports = spec.ports.unwrap_or(d.ports);
            if !(2..=4).contains(&ports) {
                return bad(format!(
                    "slave {first}: ports = {ports}; an ESC has 2..=4 ports"
                ));
            }
            if first == 0 && (spec.parent.is_some() || spec.port.is_some()) {
                return bad(
                    "slave 0 is cabled to the master: it takes no parent or port".to_string(),
                );
            }
            if let Some(p) = spec.parent {
                if p >= first {
                    return bad(format!(
                        "slave {first}: parent {p} does not exist before it \
                         (valid: 0..={})",
                        first.saturating_sub(1)
                    ));
                }
            }
            if let Some(q) = spec.port {
                let parent = spec.parent.unwrap_or(first.saturating_sub(1));
                let pports = ports_of.get(parent).copied().unwrap_or(0);
                if q == 0 || q >= pports {
                    return bad(format!(
                        "slave {first}: port {q} of slave {parent}, which has ports 0..={} \
                         (0 leads to the master; valid: 1..={})",
                        pports.saturating_sub(1),
                        pports.saturating_sub(1)
                    ));
                }
            }
            if let Some(f) = &spec.sii_file {
                let given = [
                    ("device", spec.device.is_some()),
                    ("vendor", spec.vendor.is_some()),
                    ("product", spec.product.is_some()),
                    ("revision", spec.revision.is_some()),
                    ("serial", spec.serial.is_some()),
                    ("mailbox", spec.mailbox.is_some()),
                    ("alias", spec.alias != 0),
                ];
                if let Some((what, _)) = given.iter().find(|(_, g)| *g) {
                    return bad(format!(
                        "slave {first}: {what} is given together with sii_file; the image \
                         file holds the identity, alias and SyncManagers"
                    ));
                }
                if let Err(error) = SiiImage::load(f) {
                    return Err(EmuError::Sii {
                        slave: first,
                        error,
                    });
                }
            }
            for (what, v) in [("cable_m", spec.cable_m), ("ppm", spec.ppm)] {
                if let Some(v) = v {
                    check_number(&format!("slave {first}: {what}"), v, what == "ppm")?;
                }
            }
            ports_of.extend(std::iter::repeat_n(ports, spec.repeat));
        }
        if ports_of.is_empty() {
            return bad("no slaves: add at least one [[slaves]] entry".to_string());
        }
        check_number("defaults.cable_m", d.cable_m, false)?;
        if !matches!(d.sii.read_bytes, 4 | 8) {
            return bad(format!(
                "defaults.sii.read_bytes = {}; an ESC reads 4 or 8 bytes per command",
                d.sii.read_bytes
            ));
        }
        check_ppm_spec("defaults.ppm", &d.ppm)?;
        let t = &self.timing;
        for (what, v) in [
            ("timing.cable_ns_per_m", t.cable_ns_per_m),
            ("timing.master_cable_m", t.master_cable_m),
            ("timing.wander_step_ppb", t.wander_step_ppb),
            ("timing.wander_revert_pieces", t.wander_revert_pieces),
        ] {
            check_number(what, v, false)?;
        }
        if !(0.0..=1.0).contains(&self.frame_loss_rate) {
            return bad(format!(
                "frame_loss_rate = {}; a probability: 0..=1",
                self.frame_loss_rate
            ));
        }
        let n = ports_of.len();
        for (k, f) in self.faults.iter().enumerate() {
            let name = fault_name(&f.fault);
            if let Some(end) = run_ns {
                if f.at_ns > end {
                    return bad(format!(
                        "faults[{k}] ({name}) at_ns = {} is after the end of the run ({end} ns): \
                         it would never happen",
                        f.at_ns
                    ));
                }
            }
            let (slave, port) = fault_target(&f.fault);
            if let Some(s) = slave {
                let Some(&sp) = ports_of.get(s) else {
                    return bad(format!(
                        "faults[{k}] ({name}): slave {s} does not exist (valid: 0..={})",
                        n.saturating_sub(1)
                    ));
                };
                if let Some(q) = port {
                    if q >= sp {
                        return bad(format!(
                            "faults[{k}] ({name}): slave {s} has ports 0..={}, not {q}",
                            sp.saturating_sub(1)
                        ));
                    }
                }
            }
            match f.fault {
                Fault::FrameLossRate { rate } if !(0.0..=1.0).contains(&rate) => {
                    return bad(format!(
                        "faults[{k}] ({name}): rate = {rate}; a probability: 0..=1"
                    ));
                }
                Fault::FrequencyStep { ppm, .. } => {
                    check_number(&format!("faults[{k}] ({name}): ppm"), ppm, true)?;
                }
                Fault::CableLength { meters, .. } => {
                    check_number(&format!("faults[{k}] ({name}): meters"), meters, false)?;
                }
                _ => {}
            }
        }
        self.resolve().map(drop)
    }
}

/// A finite number, ≥ 0 (lengths, rates) or within ±[`MAX_ABS_PPM`] (`ppm`).
fn check_number(what: &str, v: f64, ppm: bool) -> Result<(), EmuError> {
    let ok = v.is_finite() && if ppm { v.abs() < MAX_ABS_PPM } else { v >= 0.0 };
    if ok {
        Ok(())
    } else if ppm {
        Err(EmuError::Scenario(format!(
            "{what} = {v}; valid: finite, |ppm| < {MAX_ABS_PPM}"
        )))
    } else {
        Err(EmuError::Scenario(format!(
            "{what} = {v}; valid: finite and >= 0"
        )))
    }
}

fn check_ppm_spec(what: &str, p: &PpmSpec) -> Result<(), EmuError> {
    match *p {
        PpmSpec::Uniform { min, max } => {
            check_number(&format!("{what}.uniform.min"), min, true)?;
            check_number(&format!("{what}.uniform.max"), max, true)?;
            if min > max {
                return Err(EmuError::Scenario(format!(
                    "{what}: uniform min {min} > max {max}"
                )));
            }
        }
        PpmSpec::Normal { mean, sd, limit } => {
            check_number(&format!("{what}.normal.mean"), mean, true)?;
            check_number(&format!("{what}.normal.sd"), sd, false)?;
            check_number(&format!("{what}.normal.limit"), limit, false)?;
            check_number(&format!("{what}.normal.limit"), limit, true)?;
        }
        PpmSpec::Fixed(v) => check_number(&format!("{what}.fixed"), v, true)?,
    }
    Ok(())
}

/// The scenario-file name of a fault kind (its `kind = "…"`).
fn fault_name(f: &Fault) -> &'static str {
    match f {
        Fault::LinkBreak { .. } => "link_break",
        Fault::LinkRestore { .. } => "link_restore",
        Fault::PowerOff { .. } => "power_off",
        Fault::PowerOn { .. } => "power_on",
        Fault::PowerCycle { .. } => "power_cycle",
        Fault::FrameLossRate { .. } => "frame_loss_rate",
        Fault::FrequencyStep { .. } => "frequency_step",
        Fault::CableLength { .. } => "cable_length",
        Fault::PortTimeWrap { .. } => "port_time_wrap",
        Fault::WireSilence { .. } => "wire_silence",
        Fault::MasterStall { .. } => "master_stall",
    }
}

/// The slave and port a fault acts on, if any.
fn fault_target(f: &Fault) -> (Option<usize>, Option<u8>) {
    match *f {
        Fault::LinkBreak { slave, port } | Fault::LinkRestore { slave, port } => {
            (Some(slave), Some(port))
        }
        Fault::PowerOff { slave }
        | Fault::PowerOn { slave }
        | Fault::PowerCycle { slave, .. }
        | Fault::FrequencyStep { slave, .. }
        | Fault::CableLength { slave, .. } => (Some(slave), None),
        Fault::PortTimeWrap { slave } => (slave, None),
        Fault::FrameLossRate { .. } | Fault::WireSilence { .. } | Fault::MasterStall { .. } => {
            (None, None)
        }
    }
}
