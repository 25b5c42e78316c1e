//! The emulated chain as the master sees it: a frame goes in at a true time, the processed
//! frame comes back at a later true time. Also the observers the rest of the team needs: any
//! slave's local time and local copy of system time at a true time, SYNC edges in true time,
//! and faults scheduled at true times.

use super::datagram::{self, DgSpan, ForwardReason, FrameClass, CIRCULATING, IFG_NS, SRC_MAC};
use super::esc::{EpuCtx, Esc, EscConfig, Scheduled, SyncEdge};
use super::fault::Fault;
use super::oscillator::Wander;
use super::process_data::ProcessImage;
use super::registers::EscKind;
use super::scenario::{PpmSpec, Scenario};
use super::sii::{Identity, SiiImage};
use super::topology::Topology;
use super::{EmuError, TrueTime};
use rand::{Rng, RngCore, SeedableRng};
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

/// Initial capacity of each slave's SYNC edge log (a 1 kHz SYNC0 drained every 100 ms
/// needs ≈ 100); reserved up front so a fresh network does not grow 100 logs step by step.
const EDGE_LOG_CAPACITY: usize = 128;

/// Below this many due edges `take_sync_edges` merges instead of radix-sorting.
const RADIX_MIN: usize = 4096;

/// Takes the first `due[s]` records of every log `s` (each sorted by true time) into one
/// vector sorted stably by true time — ties in slave order, then log order — by an LSD radix
/// sort (11-bit digits, stable) of keys that hold the true time relative to the earliest in
/// the upper 32 bits and (slave, position) in the lower 32, then a gather straight from the
/// logs (no concatenated copy, no scratch records). The taken records are drained. Returns
/// `None` (touching nothing) if the times span 2^32 ns or more, or a slave index or a due
/// count does not fit 16 bits.
fn radix_take(
    logs: &mut [Vec<SyncEdge>],
    due: &[usize],
    total: usize,
    keys: &mut Vec<u64>,
    keys2: &mut Vec<u64>,
) -> Option<Vec<SyncEdge>> {
    const DIGIT: u32 = 11;
    const BUCKETS: usize = 1 << DIGIT;
    if logs.len() > 1 << 16 || due.iter().any(|&n| n > 1 << 16) {
        return None;
    }
    let (mut lo, mut hi) = (u64::MAX, 0);
    for (log, &n) in logs.iter().zip(due) {
        if let (Some(a), Some(b)) = (log.first(), log[..n].last()) {
            lo = lo.min(a.true_time);
            hi = hi.max(b.true_time);
        }
    }
    if total == 0 {
        return Some(Vec::new());
    }
    let span = u32::try_from(hi - lo).ok()?;
    keys.clear();
    for (s, (log, &n)) in logs.iter().zip(due).enumerate() {
        let tag = (s as u64) << 16;
        keys.extend(
            log[..n]
                .iter()
                .enumerate()
                .map(|(i, e)| ((e.true_time - lo) << 32) | tag | i as u64),
        );
    }
    let passes = (u32::BITS - span.leading_zeros()).div_ceil(DIGIT);
    keys2.clear();
    keys2.resize(total, 0);
    for p in 0..passes {
        let shift = 32 + p * DIGIT;
        let digit = |k: u64| ((k >> shift) as usize) & (BUCKETS - 1);
        let mut count = [0u32; BUCKETS];
        for &k in keys.iter() {
            count[digit(k)] += 1;
        }
        let mut sum = 0;
        for c in count.iter_mut() {
            let x = *c;
            *c = sum;
            sum += x;
        }
        for &k in keys.iter() {
            let d = digit(k);
            keys2[count[d] as usize] = k;
            count[d] += 1;
        }
        core::mem::swap(keys, keys2);
    }
    let mut out = Vec::with_capacity(total);
    out.extend(
        keys.iter()
            .map(|k| logs[((k >> 16) & 0xFFFF) as usize][(k & 0xFFFF) as usize]),
    );
    // Drain in place so each log keeps its capacity for the next interval.
    for (log, &n) in logs.iter_mut().zip(due) {
        log.drain(..n);
    }
    Some(out)
}

/// Stably merges the sorted runs `buf[bounds[i]..bounds[i + 1]]` (by true time; the earlier
/// run wins ties) into one sorted run, pairwise and bottom-up, ping-ponging with `scratch`.
fn merge_runs(buf: &mut Vec<SyncEdge>, scratch: &mut Vec<SyncEdge>, bounds: &mut Vec<usize>) {
    while bounds.len() > 2 {
        scratch.clear();
        scratch.reserve(buf.len());
        let runs = bounds.len() - 1;
        let mut w = 1;
        let mut i = 0;
        while i < runs {
            let lo = bounds[i];
            let mid = bounds[i + 1];
            if i + 1 < runs {
                let hi = bounds[i + 2];
                let (a, b) = (&buf[lo..mid], &buf[mid..hi]);
                let (mut x, mut y) = (0, 0);
                while x < a.len() && y < b.len() {
                    if b[y].true_time < a[x].true_time {
                        scratch.push(b[y]);
                        y += 1;
                    } else {
                        scratch.push(a[x]);
                        x += 1;
                    }
                }
                scratch.extend_from_slice(&a[x..]);
                scratch.extend_from_slice(&b[y..]);
            } else {
                scratch.extend_from_slice(&buf[lo..mid]);
            }
            bounds[w] = scratch.len();
            w += 1;
            i += 2;
        }
        bounds.truncate(w);
        core::mem::swap(buf, scratch);
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

    /// Schedules a fault at true time `at` (≥ now).
    pub fn schedule_fault(&mut self, at: TrueTime, fault: Fault) -> Result<(), EmuError> {
        if at < self.now {
            return Err(EmuError::TimeInPast {
                t: at,
                now: self.now,
            });
        }
        match fault {
            // REQ-ESC-091: link state is a function of true time.
            Fault::LinkBreak { slave, port } | Fault::LinkRestore { slave, port } => {
                self.check_slave(slave)?;
                let id = self
                    .topo
                    .link_id(slave, port)
                    .ok_or(EmuError::NoSuchPort { slave, port })?;
                let up = matches!(fault, Fault::LinkRestore { .. });
                self.topo.set_link(id, at, up);
            }
            // REQ-ESC-093: reference loss is this fault on the reference slave.
            Fault::PowerOff { slave } => {
                self.check_slave(slave)?;
                self.topo.set_power(slave, at, false);
                self.escs[slave].schedule(at, Scheduled::PowerOff);
            }
            Fault::PowerOn { slave } => {
                self.check_slave(slave)?;
                self.topo.set_power(slave, at, true);
                self.escs[slave].schedule(at, Scheduled::PowerOn);
            }
            Fault::PowerCycle { slave, off_ns } => {
                self.schedule_fault(at, Fault::PowerOff { slave })?;
                self.schedule_fault(at.saturating_add(off_ns.max(1)), Fault::PowerOn { slave })?;
            }
            Fault::FrameLossRate { rate } => {
                if !(0.0..=1.0).contains(&rate) {
                    return Err(EmuError::Scenario("loss rate must be in [0, 1]".into()));
                }
                self.push_net_event(at, NetEvent::LossRate(rate));
            }
            Fault::FrequencyStep { slave, ppm } => {
                self.check_slave(slave)?;
                self.escs[slave].schedule(at, Scheduled::FrequencyPpb(ppm * 1000.0));
            }
            Fault::CableLength { slave, meters } => {
                self.check_slave(slave)?;
                let ns = (meters.max(0.0) * self.cable_ns_per_m).round() as u64;
                self.push_net_event(at, NetEvent::Cable { slave, ns });
            }
            Fault::PortTimeWrap { .. } => return Err(EmuError::NotSchedulable),
            Fault::WireSilence { duration_ns } => {
                self.silences.push((at, at.saturating_add(duration_ns)));
            }
            Fault::MasterStall { duration_ns } => {
                self.stalls.push((at, at.saturating_add(duration_ns)));
            }
        }
        Ok(())
    }

    /// Whether the wire is silent at true time `t` ([`Fault::WireSilence`]).
    fn silent_at(&self, t: TrueTime) -> bool {
        self.silences.iter().any(|&(a, b)| a <= t && t < b)
    }

    /// The end of the [`Fault::MasterStall`] that covers true time `t`, if one does: the
    /// master must not act before it.
    pub fn master_stalled(&self, t: TrueTime) -> Option<TrueTime> {
        self.stalls
            .iter()
            .filter(|&&(a, b)| a <= t && t < b)
            .map(|&(_, b)| b)
            .max()
    }

    fn push_net_event(&mut self, at: u64, e: NetEvent) {
        let pos = self.net_events.partition_point(|(x, _)| *x <= at);
        self.net_events.insert(pos, (at, e));
    }

    fn apply_net_events(&mut self, t: u64) {
        while let Some((at, e)) = self.net_events.first().copied() {
            if at > t {
                break;
            }
            self.net_events.remove(0);
            match e {
                NetEvent::LossRate(r) => self.loss_rate = r,
                NetEvent::Cable { slave, ns } => {
                    if let Some(c) = self.topo.cable_ns.get_mut(slave) {
                        *c = ns;
                    }
                    if let Some(i) = self.info.get_mut(slave) {
                        i.cable_ns = ns;
                    }
                }
            }
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

    /// All SYNC edges up to now, sorted by true time (then slave), removed from the log.
    pub fn take_sync_edges(&mut self) -> Vec<SyncEdge> {
        let now = self.now;
        // Each slave's log is put in (true time, signal) order — it almost always is already:
        // output jitter only reorders SYNC0/SYNC1 of one slave by a few ns. The due prefixes
        // are taken in (true time, slave, log position) order by a radix sort or a merge of
        // the per-slave runs: the same order as sorting everything by (true time, slave,
        // signal, log position).
        let mut due = core::mem::take(&mut self.due);
        due.clear();
        let mut total = 0;
        for (e, log) in self.escs.iter_mut().zip(self.edges.iter_mut()) {
            if e.anchor() <= now {
                e.advance_to(now, log);
            }
            let key = |x: &SyncEdge| (x.true_time, x.signal as u8);
            if !log.windows(2).all(|w| key(&w[0]) <= key(&w[1])) {
                log.sort_by_key(key);
            }
            let n = log.partition_point(|x| x.true_time <= now);
            due.push(n);
            total += n;
        }
        if total >= RADIX_MIN {
            let (k1, k2) = &mut self.sort_keys;
            if let Some(out) = radix_take(&mut self.edges, &due, total, k1, k2) {
                self.due = due;
                return out;
            }
        }
        // Few records (merging beats clearing the radix sort's bucket counts) or a wide span.
        let mut out = Vec::with_capacity(total);
        let mut bounds = core::mem::take(&mut self.bounds);
        bounds.clear();
        bounds.push(0);
        // Drain in place so each log keeps its capacity for the next interval.
        for (log, n) in self.edges.iter_mut().zip(&due) {
            if *n > 0 {
                out.extend(log.drain(..*n));
                bounds.push(out.len());
            }
        }
        let mut scratch = core::mem::take(&mut self.edge_scratch);
        merge_runs(&mut out, &mut scratch, &mut bounds);
        self.edge_scratch = scratch;
        self.bounds = bounds;
        self.due = due;
        out
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

    #[inline]
    fn jitter(&mut self, on: bool) -> u64 {
        if on && self.phy_jitter_ns > 0 {
            // Multiply-shift mapping of a 32-bit draw onto [0, J] (bias < 2^-20 for small J).
            (u64::from(self.jitter_rng.next_u32()) * (self.phy_jitter_ns + 1)) >> 32
        } else {
            0
        }
    }

    fn forced_closed(&self, s: usize, port: u8) -> bool {
        if !self.any_forced {
            return false;
        }
        // DL control 0x0101: two loop bits per port; 0b11 = always closed.
        let v = self.escs[s].loop_control();
        (v >> (2 * port)) & 0x03 == 0x03
    }

    /// Whether the frame can leave `s` through `port` at `t` (and reach the neighbour).
    fn port_open(&self, s: usize, port: u8, t: u64) -> bool {
        if port >= self.hops[s].ports {
            return false;
        }
        if !self.any_forced && self.topo.is_static() {
            // Nothing scheduled, no forced loop: exactly the cabled ports are open.
            return port == 0 || self.topo.children[s][usize::from(port)].is_some();
        }
        if self.forced_closed(s, port) {
            return false;
        }
        if port == 0 {
            let parent_ok = match self.topo.parent[s] {
                Some((p, q)) => !self.forced_closed(p, q),
                None => true,
            };
            return parent_ok && self.topo.link_up(s, t);
        }
        match self.topo.children[s][usize::from(port)] {
            Some(c) => self.topo.link_up(c, t) && !self.forced_closed(c, 0),
            None => false,
        }
    }

    /// DL status (0x0110) of `s` at `t`: bit 0 PDI operational, bits 4..7 link on port 0..3,
    /// bit 8+2p loop closed, bit 9+2p communication. REQ-ESC-015.
    fn dl_status(&self, s: usize, t: u64) -> u16 {
        // Bit 0: PDI operational / EEPROM loaded correctly.
        let mut v = u16::from(self.escs[s].sii_loaded());
        for p in 0..4u8 {
            let physical = p < self.info[s].ports
                && match p {
                    0 => self.topo.link_up(s, t),
                    _ => self.topo.children[s][usize::from(p)]
                        .is_some_and(|c| self.topo.link_up(c, t)),
                };
            let open = self.port_open(s, p, t);
            if physical {
                v |= 1 << (4 + p);
            }
            if !open {
                v |= 1 << (8 + 2 * p);
            }
            if open {
                v |= 1 << (9 + 2 * p);
            }
        }
        v
    }

    /// Walks the frame through slave `s` entering port 0 at `t`; returns the time the frame's
    /// first bit leaves port 0 back upstream, or `None` if it was destroyed (circulating).
    /// Order: 0 → EPU → 3 → 1 → 2 → 0; closed ports loop back at no cost. REQ-ESC-081/082.
    fn walk(
        &mut self,
        s: usize,
        t_in: u64,
        c: &mut bool,
        budget: &mut usize,
        jit: bool,
    ) -> Option<u64> {
        let mut t = t_in;
        let mut reentry = false;
        loop {
            *budget = budget.checked_sub(1)?;
            if reentry {
                // Port 0 closed: the frame re-enters the EPU. First time it gets the
                // circulating bit; the second time it is destroyed. REQ-ESC-005.
                if *c {
                    return None;
                }
                *c = true;
            }
            self.visits.push(Visit::Epu {
                slave: s,
                t,
                set_c: reentry,
            });
            // REQ-ESC-082: t_P from port 0, t_F from port n, cable + PHY jitter per traversal.
            t += self.hops[s].t_p;
            for q in [3u8, 1, 2] {
                if !self.port_open(s, q, t) {
                    // A port forced closed by DL control may turn the frame round later than
                    // an unconnected one (`SlaveDefaults::forced_loop_ns`, model).
                    if q < self.hops[s].ports && self.forced_closed(s, q) {
                        t += self.hops[s].forced_loop;
                    }
                    continue;
                }
                let Some(child) = self.topo.children[s][usize::from(q)] else {
                    continue;
                };
                let down = t + self.topo.cable_ns[child] + self.jitter(jit);
                let back = self.walk(child, down, c, budget, jit)?;
                let rx = back + self.topo.cable_ns[child] + self.jitter(jit);
                self.visits.push(Visit::Rx {
                    slave: s,
                    port: q,
                    t: rx,
                });
                t = rx + self.hops[s].t_f;
            }
            if self.port_open(s, 0, t) {
                return Some(t);
            }
            reentry = true;
        }
    }

    /// [`Network::walk`] from the master for the common case: no link or power change
    /// scheduled and no forced DL loop, so exactly the cabled ports are open, port 0 is always
    /// open and nothing circulates. Iterative; the visits and the jitter draws come in the same
    /// order as the recursive walk's. Returns the time the frame leaves slave 0's port 0.
    ///
    /// With `stamps` false the port receive visits are left out (for frames that cannot
    /// latch receive times, when no loss cut needs the full visit count).
    fn walk_static(&mut self, t_in: u64, jit: bool, stamps: bool) -> u64 {
        const ORDER: [u8; 3] = [3, 1, 2];
        let mut stack = core::mem::take(&mut self.walk_stack);
        stack.clear();
        let mut s = 0;
        let mut t = t_in;
        self.visits.push(Visit::Epu {
            slave: 0,
            t,
            set_c: false,
        });
        t += self.hops[0].t_p;
        let mut qi = 0;
        let back = loop {
            if let Some(&q) = ORDER.get(qi) {
                qi += 1;
                if q >= self.hops[s].ports {
                    continue;
                }
                let Some(child) = self.topo.children[s][usize::from(q)] else {
                    continue;
                };
                let down = t + self.topo.cable_ns[child] + self.jitter(jit);
                stack.push((s, qi, q));
                s = child;
                self.visits.push(Visit::Epu {
                    slave: s,
                    t: down,
                    set_c: false,
                });
                t = down + self.hops[s].t_p;
                qi = 0;
                continue;
            }
            let Some((parent, pqi, q)) = stack.pop() else {
                break t;
            };
            let rx = t + self.topo.cable_ns[s] + self.jitter(jit);
            if stamps {
                self.visits.push(Visit::Rx {
                    slave: parent,
                    port: q,
                    t: rx,
                });
            }
            s = parent;
            t = rx + self.hops[s].t_f;
            qi = pqi;
        };
        self.walk_stack = stack;
        back
    }

    /// Sends `frame` with its first bit leaving the master at `send_time` (≥ now) and returns
    /// what comes back. All slave effects of the frame happen at their true times.
    pub fn transact(&mut self, frame: &[u8], send_time: TrueTime) -> Result<Delivery, EmuError> {
        if send_time < self.now {
            return Err(EmuError::TimeInPast {
                t: send_time,
                now: self.now,
            });
        }
        self.now = send_time;
        self.apply_net_events(send_time);
        self.stats.frames += 1;
        // REQ-ESC-082: the master's port serialises frames (frame time + gap).
        let t0 = send_time.max(self.tx_free);
        let dur = datagram::wire_duration_ns(frame.len());
        self.tx_free = t0 + dur + IFG_NS;
        if self.escs.is_empty() || !self.port_open_master(t0) {
            self.stats.lost += 1;
            return Ok(Delivery::Lost(LossReason::NoLink));
        }
        if self.silent_at(t0) {
            self.stats.lost += 1;
            return Ok(Delivery::Lost(LossReason::Silence));
        }
        let mut buf = frame.to_vec();
        let mut spans = core::mem::take(&mut self.spans);
        let class = datagram::walk(&buf, &mut spans);
        let mut c = match (class, spans.first()) {
            (FrameClass::Ecat, Some(s)) => {
                u16::from_le_bytes([buf[s.start + 6], buf[s.start + 7]]) & CIRCULATING != 0
            }
            _ => false,
        };
        self.visits.clear();
        let t_in = t0 + self.master_cable_ns + self.jitter(true);
        let back = if !self.any_forced && self.topo.is_static() {
            // Port receive visits matter only to a frame that can latch (REQ-ESC-030: BWR or
            // FPWR covering 0x0900) or to a loss cut (it draws over the full visit count).
            let stamps = self.loss_rate > 0.0
                || spans.iter().any(|s| {
                    let c = buf[s.start];
                    let ado = usize::from(u16::from_le_bytes([buf[s.start + 4], buf[s.start + 5]]));
                    let latch_cmd = c == datagram::cmd::BWR || c == datagram::cmd::FPWR;
                    latch_cmd && ado <= 0x0900 && ado + s.len > 0x0900
                });
            Some(self.walk_static(t_in, true, stamps))
        } else {
            let mut budget = 8 * self.escs.len() + 8;
            self.walk(0, t_in, &mut c, &mut budget, true)
        };
        // REQ-ESC-092: a lost frame is cut at a uniformly chosen visit; later ones commit
        // nothing and the master gets nothing.
        let injected = self.loss_rate > 0.0 && self.loss_rng.gen::<f64>() < self.loss_rate;
        let cut = if injected {
            self.loss_rng.gen_range(0..=self.visits.len())
        } else {
            self.visits.len()
        };
        let visits = core::mem::take(&mut self.visits);
        let mut first = true;
        // DL status is only computed when some datagram can read 0x0110 (it costs a
        // topology query per port).
        let wants_dl = spans.iter().any(|s| {
            let c = buf[s.start];
            let ado = usize::from(u16::from_le_bytes([buf[s.start + 4], buf[s.start + 5]]));
            let physical = (1..=9).contains(&c) || (13..=14).contains(&c);
            physical && ado <= 0x0111 && ado + s.len > 0x0110
        });
        // Some EPU latched receive times (else every `latch` entry stays false).
        let mut any_latch = false;
        for (k, v) in visits.iter().enumerate() {
            match *v {
                Visit::Epu { slave, t, set_c } => {
                    self.latch[slave] = false;
                    if k >= cut {
                        continue;
                    }
                    let dl = if wants_dl {
                        self.dl_status(slave, t)
                    } else {
                        0
                    };
                    let esc = &mut self.escs[slave];
                    esc.advance_to(t, &mut self.edges[slave]);
                    if class != FrameClass::Ecat || !esc.powered() {
                        continue;
                    }
                    if first {
                        // REQ-ESC-004: the first slave marks the frame as processed.
                        buf[SRC_MAC] |= 0x02;
                        first = false;
                    }
                    if set_c {
                        if let Some(s) = spans.first() {
                            buf[s.start + 7] |= (CIRCULATING >> 8) as u8;
                        }
                    }
                    let ctx = EpuCtx {
                        t_sof: t,
                        t_eof: t + dur,
                        dl_status: dl,
                    };
                    let r = esc.process(&mut buf, &spans, ctx, &mut self.edges[slave]);
                    self.any_forced |= esc.loop_control() != 0;
                    self.latch[slave] = r.latch;
                    any_latch |= r.latch;
                }
                Visit::Rx { slave, port, t } => {
                    if self.latch[slave] {
                        self.escs[slave].stamp_port(port, t);
                    }
                }
            }
        }
        if any_latch {
            for v in &visits {
                if let Visit::Epu { slave, .. } = v {
                    self.latch[*slave] = false;
                }
            }
        }
        self.visits = visits;
        self.spans = spans;
        let Some(back) = back else {
            self.stats.lost += 1;
            return Ok(Delivery::Lost(LossReason::Circulated));
        };
        if injected {
            self.stats.lost += 1;
            return Ok(Delivery::Lost(LossReason::Injected));
        }
        let first_bit = back + self.master_cable_ns + self.jitter(true);
        if self.silent_at(first_bit) {
            self.stats.lost += 1;
            return Ok(Delivery::Lost(LossReason::Silence));
        }
        self.stats.returned += 1;
        Ok(Delivery::Returned(Returned {
            frame: buf,
            first_bit,
            arrival: first_bit + dur,
            sent: t0,
            unprocessed: match class {
                FrameClass::Ecat => None,
                FrameClass::Forward(r) => Some(r),
            },
        }))
    }

    fn port_open_master(&self, t: u64) -> bool {
        !self.forced_closed(0, 0) && self.topo.link_up(0, t)
    }

    /// True time at which a frame sent at `send_time` would reach each slave's EPU, without
    /// jitter and without side effects (`None` = not reached). For checking delay maths
    /// against the truth.
    pub fn epu_arrival_times(&mut self, send_time: TrueTime) -> Vec<Option<TrueTime>> {
        let mut out = vec![None; self.escs.len()];
        if self.escs.is_empty() || !self.port_open_master(send_time) {
            return out;
        }
        let saved = core::mem::take(&mut self.visits);
        let mut c = false;
        let mut budget = 8 * self.escs.len() + 8;
        let _ = self.walk(
            0,
            send_time + self.master_cable_ns,
            &mut c,
            &mut budget,
            false,
        );
        for v in &self.visits {
            if let Visit::Epu { slave, t, .. } = *v {
                if out[slave].is_none() {
                    out[slave] = Some(t);
                }
            }
        }
        self.visits = saved;
        out
    }
}

#[cfg(test)]
mod test {
    use super::*;
    use crate::emu::{SlaveSpec, SyncSignal};

    /// Random per-slave logs (sorted by time, with ties inside and across slaves), as
    /// `take_sync_edges` concatenates them, and their run bounds.
    fn logs(seed: u64, slaves: usize, span: u64) -> (Vec<SyncEdge>, Vec<usize>) {
        let mut r = ChaCha8Rng::seed_from_u64(seed);
        let mut out = Vec::new();
        let mut bounds = vec![0];
        for s in 0..slaves {
            let mut t = r.gen_range(0..span.min(1000) + 1);
            for k in 0..r.gen_range(0..40) {
                t += r.gen_range(0..=span / 20);
                out.push(SyncEdge {
                    slave: s,
                    signal: if k % 3 == 0 {
                        SyncSignal::Sync1
                    } else {
                        SyncSignal::Sync0
                    },
                    true_time: t,
                    system_time: r.gen(),
                });
            }
            if out.len() > *bounds.last().unwrap() {
                bounds.push(out.len());
            }
        }
        (out, bounds)
    }

    /// Both orderings of `take_sync_edges` equal a stable sort by true time of the
    /// slave-major concatenation; the radix path declines spans of 2^32 ns or more and
    /// leaves each log's not-due tail in place.
    #[test]
    fn edge_sorts_match_stable_sort() {
        for seed in 0..300 {
            let span = match seed % 3 {
                0 => 50,
                1 => 200_000_000,
                _ => 1 << 34,
            };
            let (buf, bounds) = logs(seed, 1 + seed as usize % 37, span);
            let mut want = buf.clone();
            want.sort_by_key(|e| e.true_time);
            // Per-slave logs with one record after the due prefix each.
            let mut per: Vec<Vec<SyncEdge>> = bounds
                .windows(2)
                .map(|w| buf[w[0]..w[1]].to_vec())
                .collect();
            let due: Vec<usize> = per.iter().map(Vec::len).collect();
            let tail = |s: usize| SyncEdge {
                slave: s,
                signal: SyncSignal::Sync0,
                true_time: u64::MAX - s as u64,
                system_time: 0,
            };
            for (s, log) in per.iter_mut().enumerate() {
                log.push(tail(s));
            }
            let (mut k1, mut k2) = (Vec::new(), Vec::new());
            let hi = buf.iter().map(|e| e.true_time).max().unwrap_or(0);
            let lo = buf.iter().map(|e| e.true_time).min().unwrap_or(0);
            let fits = hi - lo < 1 << 32;
            let got = radix_take(&mut per, &due, buf.len(), &mut k1, &mut k2);
            assert_eq!(got.is_some(), fits, "seed {seed}");
            if let Some(got) = got {
                assert_eq!(got, want, "radix, seed {seed}");
                for (s, log) in per.iter().enumerate() {
                    assert_eq!(log, &vec![tail(s)], "drained, seed {seed}");
                }
            } else {
                assert_eq!(
                    per.iter().map(Vec::len).sum::<usize>(),
                    buf.len() + per.len()
                );
            }
            let mut b = buf.clone();
            let mut bo = bounds.clone();
            let mut scratch = Vec::new();
            merge_runs(&mut b, &mut scratch, &mut bo);
            assert_eq!(b, want, "merge, seed {seed}");
        }
    }

    /// The iterative walk for static topologies visits, stamps and draws jitter exactly like
    /// the general recursive walk (random trees of 2..4-port slaves).
    #[test]
    fn static_walk_matches_recursive_walk() {
        let mut r = ChaCha8Rng::seed_from_u64(5);
        for case in 0..200 {
            let n = r.gen_range(1..40);
            let mut sc = Scenario {
                seed: case,
                ..Scenario::default()
            };
            let mut free: Vec<(usize, u8)> = Vec::new();
            for i in 0..n {
                let ports = r.gen_range(2..=4u8);
                let mut spec = SlaveSpec {
                    ports: Some(ports),
                    cable_m: Some(r.gen_range(0.0..100.0)),
                    ..SlaveSpec::default()
                };
                if i > 0 {
                    let (p, q) = free.swap_remove(r.gen_range(0..free.len()));
                    spec.parent = Some(p);
                    spec.port = Some(q);
                }
                free.extend((1..ports).map(|q| (i, q)));
                sc = sc.with_slave(spec);
            }
            let mut net = Network::new(&sc).expect("scenario");
            let rng = net.jitter_rng.clone();
            let t = r.gen_range(0..1_000_000_000);
            let fast = net.walk_static(t, true, true);
            let fast_visits = core::mem::take(&mut net.visits);
            net.jitter_rng = rng;
            let (mut c, mut budget) = (false, 8 * n + 8);
            let slow = net.walk(0, t, &mut c, &mut budget, true);
            assert_eq!(Some(fast), slow, "case {case}");
            assert_eq!(
                format!("{fast_visits:?}"),
                format!("{:?}", net.visits),
                "case {case}"
            );
            assert_eq!(net.visits.len(), 2 * n - 1, "case {case}");
        }
    }
}
