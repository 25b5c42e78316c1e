//! Network model: the oracle for propagation delays, receive times and offsets.
//!
//! Simulation by definition. A tree of ESCs, each with its own processing delay `t_P`,
//! forwarding delay `t_F`, a symmetric cable to its upstream neighbour, a free-running local
//! clock (`local = true time + phase`, 64- or 32-bit) and a DC capability. One latch frame is
//! walked through the tree exactly as the ESC datasheet describes (Section I Table 9, docs/background/esc-registers.md
//! §5): it enters an ESC at its entry port, visits the ports in the order 0 → 3 → 1 → 2 → 0
//! starting after the entry port, skips closed ports, goes out of and comes back into each open
//! port, and leaves through the entry port. The hop from a port's receiver to the next open
//! port's transmitter costs `t_P` if it passes the EtherCAT Processing Unit (the walk crosses
//! port 0's position) and `t_F` otherwise. Every port stamps the true arrival time of the frame's
//! first bit; the register value is that time on the ESC's local clock (optionally quantised).
//!
//! Nothing here knows any delay formula: delays are arrival-time differences. All arithmetic is
//! `i128`; clocks are reduced modulo 2^64 or 2^32 only when a register value is produced.
//!
//! Clock rate errors are modelled (`rate_ppb`: the local clock runs `1 + rate_ppb·10⁻⁹` times
//! true time during the latch); the delay formulas assume equal rates, so tests with non-zero
//! rates measure that error (100 ppm over a 100 µs round trip is 10 ns). Not modelled:
//! asymmetric cables, PHY jitter.
// implements: REQ-DC-060

use crate::esc_dc::{hop_is_processing, next_port};
use crate::register::wrap;

/// DC capability of an ESC as announced in ESC Features 0x0008.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dc {
    /// No DC: no receive times, no system time. Acts as wire delay for the master.
    None,
    /// 32-bit DC (0x0008 bit 2 set, bit 3 clear).
    Bits32,
    /// 64-bit DC (0x0008 bits 2 and 3 set).
    Bits64,
}

impl Dc {
    /// Width of the local clock in bits (64 for a non-DC ESC; irrelevant there).
    pub fn width(self) -> u32 {
        match self {
            Dc::Bits32 => 32,
            Dc::None | Dc::Bits64 => 64,
        }
    }
}

/// One ESC of the model.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Esc {
    /// Upstream neighbour `(index, port of the neighbour)`; `None` for the ESC wired to the master.
    pub parent: Option<(usize, u8)>,
    /// This ESC's port wired upstream.
    pub entry: u8,
    /// One-way delay of the cable between `entry` and the upstream neighbour, ns (symmetric).
    pub cable: i128,
    /// Processing delay (hop through the EPU), ns.
    pub t_p: i128,
    /// Forwarding delay (any other hop), ns.
    pub t_f: i128,
    /// DC capability.
    pub dc: Dc,
    /// Local clock phase: `local(T) = (T + ⌊T·rate_ppb/10⁹⌋ + phase) mod 2^width`, T = true time
    /// of the simulation (0 = the master sends the latch frame).
    pub phase: u64,
    /// Rate error of the local clock in parts per billion (0 = ideal).
    pub rate_ppb: i64,
    /// Values the receive-time registers of *closed* ports hold (left over from earlier frames;
    /// the master must ignore them).
    pub stale: [u32; 4],
}

/// A network: ESCs plus the children each port leads to (derived from `parent`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Network {
    /// The ESCs. Index order is arbitrary; [`Latch::order`] gives the auto-increment order.
    pub escs: Vec<Esc>,
}

/// Why a network description is not a tree the model can walk.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ModelError {
    /// No ESC, or not exactly one ESC wired to the master.
    NoRoot,
    /// A port number above 3, a parent index out of range, or two ESCs on one port.
    BadWiring(usize),
    /// An ESC's entry port is also used for a child.
    EntryUsed(usize),
    /// The parent links contain a cycle or an ESC is unreachable from the master.
    NotATree,
}

/// The result of walking one latch frame through the network (true times, master sends at 0).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Latch {
    /// ESC indices in the order the frame first reaches them: the auto-increment order.
    pub order: Vec<usize>,
    /// True arrival time at each ESC's entry port (indexed by ESC index).
    pub arrival: Vec<i128>,
    /// True receive time at each port; `None` for ports the frame never reaches (closed).
    pub port_rx: Vec<[Option<i128>; 4]>,
    /// True time at which the frame passed each ESC's processing unit (the receive time of the
    /// port whose outgoing hop crossed the EPU).
    pub epu_rx: Vec<i128>,
    /// True time the frame is back at the master.
    pub back_at_master: i128,
}

/// Register values the master reads from one ESC after the latch.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Observation {
    /// ESC Features 0x0008.
    pub features: u16,
    /// ESC DL Status 0x0110.
    pub dl_status: u16,
    /// Receive Time Port 0..3 (0x0900..0x090F); meaningful only for open ports of DC ESCs.
    pub port_times: [u32; 4],
    /// Receive Time ECAT Processing Unit 0x0918 (local time; zero-extended on 32-bit ESCs).
    pub epu_time: u64,
}

impl Network {
    /// Children per port of ESC `i`.
    pub fn children(&self, i: usize) -> [Option<usize>; 4] {
        let mut out = [None; 4];
        for (c, esc) in self.escs.iter().enumerate() {
            if let Some((p, port)) = esc.parent {
                if p == i && usize::from(port) < 4 {
                    out[usize::from(port)] = Some(c);
                }
            }
        }
        out
    }

    /// Open ports of ESC `i`: its entry port and every port with a child.
    pub fn open_ports(&self, i: usize) -> [bool; 4] {
        let mut open = [false; 4];
        let children = self.children(i);
        for p in 0..4 {
            open[p] = children[p].is_some();
        }
        open[usize::from(self.escs[i].entry)] = true;
        open
    }

    /// Checks the wiring is a tree rooted at the master.
    pub fn validate(&self) -> Result<(), ModelError> {
        let n = self.escs.len();
        let roots = self.escs.iter().filter(|e| e.parent.is_none()).count();
        if n == 0 || roots != 1 {
            return Err(ModelError::NoRoot);
        }
        for (i, esc) in self.escs.iter().enumerate() {
            if esc.entry > 3 {
                return Err(ModelError::BadWiring(i));
            }
            if let Some((p, port)) = esc.parent {
                if p >= n || port > 3 || p == i {
                    return Err(ModelError::BadWiring(i));
                }
                let same = self
                    .escs
                    .iter()
                    .filter(|e| e.parent == Some((p, port)))
                    .count();
                if same != 1 {
                    return Err(ModelError::BadWiring(i));
                }
                if self.escs[p].entry == port {
                    return Err(ModelError::EntryUsed(p));
                }
            }
        }
        // every ESC reaches the root by following parents, in at most n steps
        for i in 0..n {
            let mut cur = i;
            let mut steps = 0;
            while let Some((p, _)) = self.escs[cur].parent {
                cur = p;
                steps += 1;
                if steps > n {
                    return Err(ModelError::NotATree);
                }
            }
        }
        Ok(())
    }

    /// Walks one latch frame sent by the master at true time 0.
    pub fn latch(&self) -> Result<Latch, ModelError> {
        self.validate()?;
        let n = self.escs.len();
        let root = self
            .escs
            .iter()
            .position(|e| e.parent.is_none())
            .ok_or(ModelError::NoRoot)?;
        let mut latch = Latch {
            order: Vec::with_capacity(n),
            arrival: vec![0; n],
            port_rx: vec![[None; 4]; n],
            epu_rx: vec![0; n],
            back_at_master: 0,
        };
        let arrive = self.escs[root].cable;
        let leave = self.visit(root, arrive, &mut latch);
        latch.back_at_master = leave + self.escs[root].cable;
        Ok(latch)
    }

    /// The frame arrives at ESC `s`'s entry port at true time `t`; returns the true time it is
    /// transmitted back out of the entry port.
    fn visit(&self, s: usize, t: i128, latch: &mut Latch) -> i128 {
        let esc = &self.escs[s];
        let open = self.open_ports(s);
        let children = self.children(s);
        latch.order.push(s);
        latch.arrival[s] = t;
        latch.port_rx[s][usize::from(esc.entry)] = Some(t);
        let mut rx_port = esc.entry;
        let mut rx_time = t;
        loop {
            // next open port after rx_port in processing order (the entry port is open)
            let mut tx_port = next_port(rx_port);
            while !open[usize::from(tx_port)] {
                tx_port = next_port(tx_port);
            }
            let processing = hop_is_processing(rx_port, tx_port);
            if processing {
                latch.epu_rx[s] = rx_time;
            }
            let tx_time = rx_time + if processing { esc.t_p } else { esc.t_f };
            if tx_port == esc.entry {
                return tx_time;
            }
            let child = children[usize::from(tx_port)].expect("open non-entry port has a child");
            let cable = self.escs[child].cable;
            let back = self.visit(child, tx_time + cable, latch);
            rx_port = tx_port;
            rx_time = back + cable;
            latch.port_rx[s][usize::from(tx_port)] = Some(rx_time);
        }
    }

    /// The network a frame sees while some ports are forced closed (DL control 0x0101 loop
    /// bits): a closed port loops back inside the ESC as an unconnected one does (the
    /// datasheet's loop-back rule), so everything behind it is cut off. `closed(i, port)`:
    /// port `port` of ESC `i` is forced closed (an entry port cannot be: it is the way in).
    /// Returns the reduced network, its ESCs in the original order, and the new index of every
    /// old ESC that is kept.
    pub fn with_closed_ports(
        &self,
        closed: impl Fn(usize, u8) -> bool,
    ) -> (Network, Vec<Option<usize>>) {
        let n = self.escs.len();
        let cut_off = |mut i: usize| {
            let mut steps = 0;
            while let Some((p, port)) = self.escs[i].parent {
                if closed(p, port) || steps > n {
                    return true;
                }
                i = p;
                steps += 1;
            }
            false
        };
        let mut map = vec![None; n];
        let mut escs: Vec<Esc> = Vec::new();
        for (i, slot) in map.iter_mut().enumerate() {
            if !cut_off(i) {
                *slot = Some(escs.len());
                escs.push(self.escs[i].clone());
            }
        }
        for e in &mut escs {
            e.parent = e
                .parent
                .map(|(p, port)| (map[p].expect("the parent of a kept ESC is kept"), port));
        }
        (Network { escs }, map)
    }

    /// Local clock value of ESC `i` at true time `t` (full width, unquantised).
    pub fn local_time(&self, i: usize, t: i128) -> i128 {
        let esc = &self.escs[i];
        let drift = (t * i128::from(esc.rate_ppb)).div_euclid(1_000_000_000);
        wrap(t + drift + i128::from(esc.phase), esc.dc.width())
    }

    /// Register values of ESC `i` after `latch`, with receive times quantised down to multiples
    /// of `granularity` ns of local time (1 = exact; real ESCs tick every 10 ns).
    pub fn observe(&self, latch: &Latch, i: usize, granularity: i128) -> Observation {
        let esc = &self.escs[i];
        let open = self.open_ports(i);
        let stamp = |t: i128| {
            let local = self.local_time(i, t);
            local - local.rem_euclid(granularity)
        };
        let mut port_times = esc.stale;
        let mut dl_status = 0u16;
        for p in 0..4usize {
            if open[p] {
                // link up, loop open, communication established
                dl_status |= 1 << (4 + p);
                dl_status |= 1 << (9 + 2 * p);
                if esc.dc != Dc::None {
                    if let Some(t) = latch.port_rx[i][p] {
                        port_times[p] = u32::try_from(wrap(stamp(t), 32)).expect("wrapped");
                    }
                }
            } else {
                // no link: loop closed
                dl_status |= 1 << (8 + 2 * p);
            }
        }
        let (features, epu_time) = match esc.dc {
            Dc::None => (0x0000, 0),
            Dc::Bits32 => (
                0x0004,
                u64::try_from(wrap(stamp(latch.epu_rx[i]), 32)).expect("wrapped"),
            ),
            Dc::Bits64 => (
                0x000C,
                u64::try_from(stamp(latch.epu_rx[i])).expect("wrapped"),
            ),
        };
        Observation {
            features,
            dl_status,
            port_times: if esc.dc == Dc::None {
                esc.stale
            } else {
                port_times
            },
            epu_time,
        }
    }
}

impl Latch {
    /// Exact propagation delay from ESC `reference` to ESC `s`: the difference of the true
    /// times the latch frame reached them (negative if `s` comes first).
    pub fn delay(&self, reference: usize, s: usize) -> i128 {
        self.arrival[s] - self.arrival[reference]
    }
}

/// Tiny deterministic generator (SplitMix64) so the spec needs no dependency and any test or
/// the emulator can rebuild a network from a seed.
#[derive(Clone, Debug)]
pub struct SplitMix(u64);

impl SplitMix {
    /// Seeds the generator.
    pub fn new(seed: u64) -> Self {
        SplitMix(seed)
    }
    /// Next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in `lo..=hi` (`lo <= hi`), slightly biased; fine for test generation.
    pub fn range(&mut self, lo: i128, hi: i128) -> i128 {
        let span = u128::try_from(hi - lo + 1).expect("lo <= hi");
        lo + i128::try_from(u128::from(self.next_u64()) % span).expect("fits")
    }
    /// True with probability `num / den`.
    pub fn chance(&mut self, num: u64, den: u64) -> bool {
        self.next_u64() % den < num
    }
}

/// Shape of a generated network.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Shape {
    /// Every ESC uses ports 0 (in) and 1 (out).
    Line,
    /// ESCs use ports 0, 1 and 2 (EK1100-like junctions).
    Fork,
    /// ESCs use ports 0, 3, 1 and 2.
    Cross,
    /// Any port may be the entry port of a DC ESC, children on any free port.
    Any,
}

/// Parameters of [`generate`].
#[derive(Clone, Copy, Debug)]
pub struct GenParams {
    /// Number of ESCs (≥ 1).
    pub count: usize,
    /// Topology shape.
    pub shape: Shape,
    /// Common forwarding delay range, ns (one value per network).
    pub t_f: (i128, i128),
    /// `t_P − t_F` range per ESC, ns. Use `(d, d)` for one common `t_Diff`.
    pub t_diff: (i128, i128),
    /// Cable delay range, ns (≈ 5 ns per metre).
    pub cable: (i128, i128),
    /// Percent of ESCs without DC (the first DC ESC always exists). Non-DC ESCs get at most one
    /// child (datasheet: ESCs with more than two ports support receive times).
    pub non_dc_percent: u64,
    /// Percent of DC ESCs with a 32-bit clock.
    pub bits32_percent: u64,
    /// Clock rate error range, ppb (`(0, 0)` = ideal clocks).
    pub rate_ppb: (i64, i64),
}

impl GenParams {
    /// `count` ESCs of `shape` with the delays of common hardware (t_F 100..800 ns, t_Diff
    /// −80..400 ns, cables up to 5 µs) and ideal clocks; change fields for other ranges.
    pub fn new(count: usize, shape: Shape, non_dc_percent: u64, bits32_percent: u64) -> Self {
        GenParams {
            count,
            shape,
            t_f: (100, 800),
            t_diff: (-80, 400),
            cable: (0, 5_000),
            non_dc_percent,
            bits32_percent,
            rate_ppb: (0, 0),
        }
    }
}

/// Generates a random network with `count` ESCs (indices in auto-increment order). Half of the
/// clocks get a phase whose low 32 bits are just below 2^32, so port times wrap inside the latch.
pub fn generate(rng: &mut SplitMix, params: &GenParams) -> Network {
    let count = params.count.max(1);
    let t_f = rng.range(params.t_f.0, params.t_f.1);
    let ports_allowed: &[u8] = match params.shape {
        Shape::Line => &[0, 1],
        Shape::Fork => &[0, 1, 2],
        Shape::Cross | Shape::Any => &[0, 1, 2, 3],
    };
    let mut escs: Vec<Esc> = Vec::with_capacity(count);
    for i in 0..count {
        let non_dc = i > 0 && rng.chance(params.non_dc_percent, 100);
        let dc = if non_dc {
            Dc::None
        } else if rng.chance(params.bits32_percent, 100) {
            Dc::Bits32
        } else {
            Dc::Bits64
        };
        let entry = if params.shape == Shape::Any && dc != Dc::None && rng.chance(1, 4) {
            ports_allowed[usize::try_from(rng.range(0, 3)).expect("small")]
        } else {
            0
        };
        let parent = if i == 0 {
            None
        } else {
            // candidate (esc, port) slots
            let mut slots = Vec::new();
            for (j, e) in escs.iter().enumerate() {
                if params.shape == Shape::Line && j + 1 != i {
                    continue;
                }
                let used: Vec<u8> = escs
                    .iter()
                    .filter_map(|c| c.parent.filter(|(p, _)| *p == j).map(|(_, port)| port))
                    .collect();
                if e.dc == Dc::None && !used.is_empty() {
                    continue;
                }
                for &port in ports_allowed {
                    if port != e.entry && !used.contains(&port) {
                        slots.push((j, port));
                    }
                }
            }
            if slots.is_empty() {
                break;
            }
            let k = usize::try_from(rng.range(0, slots.len() as i128 - 1)).expect("small");
            Some(slots[k])
        };
        let phase = if rng.chance(1, 2) {
            let low = (1u64 << 32) - u64::try_from(rng.range(1, 400_000)).expect("small");
            (rng.next_u64() & 0xFFFF_FFFF_0000_0000) | low
        } else {
            rng.next_u64()
        };
        let mut stale = [0u32; 4];
        for s in stale.iter_mut() {
            *s = u32::try_from(rng.next_u64() >> 32).expect("32 bits");
        }
        escs.push(Esc {
            parent,
            entry,
            cable: rng.range(params.cable.0, params.cable.1),
            t_p: t_f + rng.range(params.t_diff.0, params.t_diff.1),
            t_f,
            dc,
            phase,
            rate_ppb: i64::try_from(
                rng.range(i128::from(params.rate_ppb.0), i128::from(params.rate_ppb.1)),
            )
            .expect("in range"),
            stale,
        });
    }
    renumber_in_processing_order(Network { escs })
}

/// Reorders ESCs so index order equals the auto-increment (first arrival) order.
pub fn renumber_in_processing_order(net: Network) -> Network {
    let Ok(latch) = net.latch() else {
        return net;
    };
    let mut new_index = vec![0usize; net.escs.len()];
    for (new, &old) in latch.order.iter().enumerate() {
        new_index[old] = new;
    }
    let escs = latch
        .order
        .iter()
        .map(|&old| {
            let mut e = net.escs[old].clone();
            e.parent = e.parent.map(|(p, port)| (new_index[p], port));
            e
        })
        .collect();
    Network { escs }
}

/// What the master would feed `ecdc-core`'s DC maths after this latch: one
/// [`ecdc_core::dc::topology::SlaveSample`] per ESC in auto-increment order (the network must be
/// numbered in that order, as [`generate`] does). `with_t_diff` passes each ESC's true
/// `t_P − t_F`; otherwise 0 ("unknown").
pub fn core_samples(
    net: &Network,
    latch: &Latch,
    granularity: i128,
    with_t_diff: bool,
) -> Vec<ecdc_core::dc::topology::SlaveSample> {
    use ecdc_core::dc::topology::SlaveSample;
    (0..net.escs.len())
        .map(|i| {
            let obs = net.observe(latch, i, granularity);
            let esc = &net.escs[i];
            let t_diff = if with_t_diff {
                i32::try_from(esc.t_p - esc.t_f).expect("t_Diff fits i32")
            } else {
                0
            };
            SlaveSample::from_registers(
                obs.dl_status,
                obs.features,
                obs.port_times,
                obs.epu_time,
                t_diff,
            )
        })
        .collect()
}
