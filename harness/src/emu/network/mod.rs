//! The emulated chain as the master sees it: a frame goes in at a true time, the processed
//! frame comes back at a later true time. Also the observers the rest of the team needs: any
//! slave's local time and local copy of system time at a true time, SYNC edges in true time,
//! and faults scheduled at true times.
//!
//! - this file: the network's state, construction and observers;
//! - [`frame`]: one frame through the chain (`transact`);
//! - [`walk`]: open ports, DL status and the walk in processing order;
//! - [`faults`]: faults and network events at true times;
//! - [`edge_log`]: the SYNC edge log handed out in true-time order.

mod edge_log;
mod faults;
mod frame;
mod walk;

use edge_log::EDGE_LOG_CAPACITY;

use super::datagram::{DgSpan, ForwardReason};
use super::esc::{Esc, EscConfig, SyncEdge};
use super::fault::Fault;
use super::oscillator::Wander;
use super::process_data::ProcessImage;
use super::registers::EscKind;
use super::scenario::{PpmSpec, Scenario};
use super::sii::{Identity, SiiImage};
use super::topology::Topology;
use super::{EmuError, TrueTime};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A frame that came back to the master.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Returned {
    /// The frame as the master receives it (same length as sent; no padding added).
    pub frame: Vec<u8>,
    /// True time the first preamble bit reaches the master.
    pub first_bit: TrueTime,
    /// True time the last bit (FCS) has arrived: when software can see the frame.
    pub arrival: TrueTime,
    /// True time the first bit left the master (later than the requested send time if the
    /// master's port was still busy with the previous frame).
    pub sent: TrueTime,
    /// `Some` if the slaves forwarded the frame without processing it.
    pub unprocessed: Option<ForwardReason>,
}

/// Why a frame did not come back.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LossReason {
    /// Injected loss (frame corrupted on its path).
    Injected,
    /// The frame circulated in a segment cut off by a link break and was destroyed.
    Circulated,
    /// No link from the master to the first slave at send time.
    NoLink,
    /// Sent, or due back, during a [`Fault::WireSilence`].
    Silence,
}

/// Outcome of [`Network::transact`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Delivery {
    Returned(Returned),
    Lost(LossReason),
}

impl Delivery {
    /// The returned frame, if any.
    pub fn returned(self) -> Option<Returned> {
        match self {
            Delivery::Returned(r) => Some(r),
            Delivery::Lost(_) => None,
        }
    }
}

/// A slave's clocks at a true time.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ClockSample {
    /// The true time sampled.
    pub true_time: TrueTime,
    /// Local time (quantised, 64-bit); `None` while powered off.
    pub local: Option<u64>,
    /// Local copy of system time (width-masked); `None` without system time or power.
    pub system_time: Option<u64>,
}

/// Static facts about a slave (for reports and for computing expected values).
#[derive(Debug, Clone, PartialEq)]
pub struct SlaveInfo {
    pub name: Option<String>,
    pub kind: EscKind,
    pub ports: u8,
    pub parent: Option<(usize, u8)>,
    pub t_p_ns: u64,
    pub t_f_ns: u64,
    /// Cable into port 0, ns.
    pub cable_ns: u64,
    /// Configured crystal error (before wander and frequency steps), ppm.
    pub ppm: f64,
}

#[derive(Debug, Clone, Copy)]
enum Visit {
    Epu { slave: usize, t: u64, set_c: bool },
    Rx { slave: usize, port: u8, t: u64 },
}

#[derive(Debug, Clone, Copy)]
enum NetEvent {
    LossRate(f64),
    Cable { slave: usize, ns: u64 },
}

/// What the frame walk needs of a slave.
#[derive(Debug, Clone, Copy)]
struct Hop {
    ports: u8,
    t_p: u64,
    t_f: u64,
    /// Extra turn-round time at a downstream port forced closed by DL control (model).
    forced_loop: u64,
}

/// Statistics since construction.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Stats {
    pub frames: u64,
    pub returned: u64,
    pub lost: u64,
}

/// splitmix64: derives independent seeds for independent random streams. Every random
/// draw comes from a ChaCha8 stream seeded from the scenario seed (REQ-ESC-100).
fn sub_seed(seed: u64, stream: u64) -> u64 {
    let mut z = seed ^ stream.wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

fn draw_ppm(spec: &PpmSpec, rng: &mut ChaCha8Rng) -> f64 {
    match *spec {
        PpmSpec::Fixed(v) => v,
        PpmSpec::Uniform { min, max } => {
            if max > min {
                rng.gen_range(min..=max)
            } else {
                min
            }
        }
        PpmSpec::Normal { mean, sd, limit } => {
            let u1: f64 = rng.gen::<f64>().max(f64::MIN_POSITIVE);
            let u2: f64 = rng.gen();
            let n = (-2.0 * u1.ln()).sqrt() * (core::f64::consts::TAU * u2).cos();
            (mean + sd * n).clamp(-limit.abs(), limit.abs())
        }
    }
}

/// The emulated slave chain.
#[derive(Debug)]
pub struct Network {
    escs: Vec<Esc>,
    info: Vec<SlaveInfo>,
    topo: Topology,
    /// SYNC edges per slave (each in time order), merged on `take_sync_edges`.
    edges: Vec<Vec<SyncEdge>>,
    /// Scratch of `take_sync_edges`: due edges per slave, run bounds, merge buffer.
    due: Vec<usize>,
    bounds: Vec<usize>,
    edge_scratch: Vec<SyncEdge>,
    sort_keys: (Vec<u64>, Vec<u64>),
    /// Per-slave hop parameters, kept compact for the frame walk.
    hops: Vec<Hop>,
    /// Some slave has written DL control loop bits (else the walk skips that check).
    any_forced: bool,
    now: TrueTime,
    tx_free: TrueTime,
    master_cable_ns: u64,
    cable_ns_per_m: f64,
    phy_jitter_ns: u64,
    loss_rate: f64,
    net_events: Vec<(u64, NetEvent)>,
    jitter_rng: ChaCha8Rng,
    loss_rng: ChaCha8Rng,
    visits: Vec<Visit>,
    spans: Vec<DgSpan>,
    /// Scratch of `walk_static`: (slave, next port index, port) per level.
    walk_stack: Vec<(usize, usize, u8)>,
    latch: Vec<bool>,
    stats: Stats,
    /// [`Fault::WireSilence`] windows, [start, end) in true time.
    silences: Vec<(TrueTime, TrueTime)>,
    /// [`Fault::MasterStall`] windows, [start, end) in true time.
    stalls: Vec<(TrueTime, TrueTime)>,
}

impl Network {
    /// Builds the chain described by `sc`. Faults listed in the scenario are scheduled.
    pub fn new(sc: &Scenario) -> Result<Self, EmuError> {
        let slaves = sc.resolve()?;
        let t = &sc.timing;
        let mut ppm_rng = ChaCha8Rng::seed_from_u64(sub_seed(sc.seed, 1));
        let mut phase_rng = ChaCha8Rng::seed_from_u64(sub_seed(sc.seed, 2));
        let wander = Wander {
            interval_ns: t.wander_interval_ns,
            step_ppb: t.wander_step_ppb,
            revert_pieces: t.wander_revert_pieces,
        };
        let cable = |m: f64| (m.max(0.0) * t.cable_ns_per_m).round() as u64;
        let mut escs = Vec::with_capacity(slaves.len());
        let mut info = Vec::with_capacity(slaves.len());
        let mut parents = Vec::with_capacity(slaves.len());
        let mut cables = Vec::with_capacity(slaves.len());
        let mut forced_loop = Vec::with_capacity(slaves.len());
        for (i, s) in slaves.iter().enumerate() {
            let drawn = draw_ppm(&sc.defaults.ppm, &mut ppm_rng);
            let ppm = s.ppm.unwrap_or(drawn);
            let phase = if t.power_on_spread_ns > 0 {
                phase_rng.gen_range(0..t.power_on_spread_ns)
            } else {
                0
            };
            let mut initial = s.initial_local_ns.unwrap_or(phase);
            for f in &sc.faults {
                if let Fault::PortTimeWrap { slave } = f.fault {
                    if slave.is_none() || slave == Some(i) {
                        // REQ-ESC-094: local(at) = initial + at·(1 + ppm) ≡ 0 (mod 2^32).
                        let adv = (f.at_ns as f64 * (1.0 + ppm * 1e-6)).round() as u64;
                        let m = 1u64 << 32;
                        initial = m + (m - adv % m) % m;
                    }
                }
            }
            let cfg = EscConfig {
                kind: s.kind,
                ports: s.ports,
                t_p_ns: s.t_p_ns,
                t_f_ns: s.t_f_ns,
                ppb: ppm * 1000.0,
                sii: s
                    .sii
                    .image()
                    .map_err(|error| EmuError::Sii { slave: i, error })?,
                sii_timing: sc.defaults.sii,
                device: s.device,
                initial_station: s.station,
                esc_type: s.esc_type.unwrap_or(s.kind.default_type()),
                ram_bytes: sc.defaults.ram_bytes,
                pulse_len: sc.defaults.pulse_len,
                tick_ns: t.tick_ns,
                wander: wander.clone(),
                gains: sc.loop_gains,
                sync_jitter_ns: t.sync_jitter_ns,
                initial_local_ns: initial,
                seed: sub_seed(sc.seed, 1000 + i as u64),
            };
            escs.push(Esc::new(i, cfg));
            info.push(SlaveInfo {
                name: s.name.clone(),
                kind: s.kind,
                ports: s.ports,
                parent: s.parent,
                t_p_ns: s.t_p_ns,
                t_f_ns: s.t_f_ns,
                cable_ns: cable(s.cable_m),
                ppm,
            });
            forced_loop.push(s.forced_loop_ns);
            parents.push(s.parent);
            cables.push(cable(s.cable_m));
        }
        let n = escs.len();
        let mut net = Network {
            escs,
            info,
            topo: Topology::new(parents, cables),
            edges: (0..n)
                .map(|_| Vec::with_capacity(EDGE_LOG_CAPACITY))
                .collect(),
            due: Vec::with_capacity(n),
            bounds: Vec::with_capacity(n + 1),
            edge_scratch: Vec::new(),
            sort_keys: (Vec::new(), Vec::new()),
            hops: Vec::new(),
            any_forced: false,
            now: 0,
            tx_free: 0,
            master_cable_ns: cable(t.master_cable_m),
            cable_ns_per_m: t.cable_ns_per_m,
            phy_jitter_ns: t.phy_jitter_ns,
            loss_rate: sc.frame_loss_rate,
            net_events: Vec::new(),
            jitter_rng: ChaCha8Rng::seed_from_u64(sub_seed(sc.seed, 3)),
            loss_rng: ChaCha8Rng::seed_from_u64(sub_seed(sc.seed, 4)),
            visits: Vec::with_capacity(4 * n + 4),
            spans: Vec::with_capacity(16),
            walk_stack: Vec::new(),
            latch: vec![false; n],
            stats: Stats::default(),
            silences: Vec::new(),
            stalls: Vec::new(),
        };
        net.hops = net
            .info
            .iter()
            .zip(&forced_loop)
            .map(|(i, &forced_loop)| Hop {
                ports: i.ports,
                t_p: i.t_p_ns,
                t_f: i.t_f_ns,
                forced_loop,
            })
            .collect();
        for f in &sc.faults {
            if matches!(f.fault, Fault::PortTimeWrap { .. }) {
                continue;
            }
            net.schedule_fault(f.at_ns, f.fault.clone())?;
        }
        Ok(net)
    }

    /// Number of slaves.
    pub fn slave_count(&self) -> usize {
        self.escs.len()
    }

    /// Latest true time the network has been driven to (by frames, advances or samples).
    pub fn now(&self) -> TrueTime {
        self.now
    }

    /// Frame statistics.
    pub fn stats(&self) -> Stats {
        self.stats
    }

    /// Static facts about slave `i`.
    pub fn slave_info(&self, i: usize) -> Option<&SlaveInfo> {
        self.info.get(i)
    }

    /// The ESC model of slave `i` (register file, loop state), read-only.
    pub fn esc(&self, i: usize) -> Option<&Esc> {
        self.escs.get(i)
    }

    fn check_slave(&self, i: usize) -> Result<(), EmuError> {
        if i < self.escs.len() {
            Ok(())
        } else {
            Err(EmuError::NoSuchSlave(i))
        }
    }

    /// Drives every slave to true time `t` without frames: SYNC pulses keep firing, loops keep
    /// their rate, scheduled faults take effect.
    pub fn advance_to(&mut self, t: TrueTime) -> Result<(), EmuError> {
        if t < self.now {
            return Err(EmuError::TimeInPast { t, now: self.now });
        }
        self.apply_net_events(t);
        for (e, log) in self.escs.iter_mut().zip(self.edges.iter_mut()) {
            if e.anchor() <= t {
                e.advance_to(t, log);
            }
        }
        self.now = t;
        Ok(())
    }

    /// Slave `i`'s local time and local copy of system time at true time `t` (≥ now; the
    /// network's time moves to `t`). Use it for clock-error plots.
    pub fn clock(&mut self, i: usize, t: TrueTime) -> Result<ClockSample, EmuError> {
        self.check_slave(i)?;
        if t < self.now || t < self.escs[i].anchor() {
            return Err(EmuError::TimeInPast {
                t,
                now: self.now.max(self.escs[i].anchor()),
            });
        }
        self.apply_net_events(t);
        self.now = t;
        let e = &mut self.escs[i];
        e.advance_to(t, &mut self.edges[i]);
        Ok(ClockSample {
            true_time: t,
            local: e.powered().then(|| e.local()),
            system_time: e.system_time(),
        })
    }

    /// Debug read of a slave's registers without side effects (0x0910 = local copy now).
    pub fn peek(&self, i: usize, addr: u16, len: usize) -> Result<Vec<u8>, EmuError> {
        self.check_slave(i)?;
        Ok(self.escs[i].peek(addr, len))
    }

    /// Identity of slave `i` as its EEPROM holds it now (vendor, product, revision, serial,
    /// SII word 4 alias, device name).
    pub fn identity(&self, i: usize) -> Option<Identity> {
        self.escs.get(i).map(Esc::identity)
    }

    /// AL state of slave `i` (0x0130 bits 3:0: 1 INIT, 2 PREOP, 3 BOOT, 4 SAFEOP, 8 OP) at
    /// the slave's current time (call `advance_to` first for effects of returned frames).
    pub fn al_state(&self, i: usize) -> Option<u8> {
        self.escs.get(i).map(Esc::al)
    }

    /// AL state, driven outputs and presented inputs of slave `i`'s application.
    pub fn process_image(&self, i: usize) -> Option<ProcessImage> {
        self.escs.get(i).map(Esc::process_image)
    }

    /// Slave `i`'s EEPROM content now (SII writes included).
    pub fn sii_image(&self, i: usize) -> Option<&SiiImage> {
        self.escs.get(i).map(Esc::sii_image)
    }

    /// Lets slave `i`'s PDI take (or release) its EEPROM interface, 0x0501 bit 0. The
    /// emulator has no PDI side; this stands in for a slave controller that takes it. The PDI
    /// gets it only while ECAT offers it (0x0500 bit 0) and the interface is idle; returns
    /// whether the PDI holds it afterwards.
    pub fn set_sii_pdi_access(&mut self, i: usize, on: bool) -> Result<bool, EmuError> {
        self.check_slave(i)?;
        Ok(self.escs[i].set_sii_pdi_access(on))
    }

    /// Current oscillator frequency error of slave `i` (configured + wander + steps), ppb.
    pub fn oscillator_ppb(&self, i: usize) -> Result<f64, EmuError> {
        self.check_slave(i)?;
        Ok(self.escs[i].ppb())
    }
}
