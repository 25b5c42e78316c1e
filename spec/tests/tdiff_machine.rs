//! The shipped machine's t_Diff step (REQ-DC-120..126) run against the network model.
//!
//! A [`Ring`] answers every datagram of a bring-up from a [`Network`] (per-ESC t_P, t_F,
//! cables, clock phases and rates): it counts and addresses the slaves, reports their
//! features, DL status, ESC type and AL state, keeps DL control 0x0100 as written, and on each
//! latch trigger walks the frame through the network with the ports that DL control forces
//! closed cut off, stamping every port the frame reaches on its ESC's own clock. The machine
//! runs until it moves on to the delay measurement; each slave's t_Diff and source are then
//! compared with the model's `t_P − t_F`.
//!
//! `tdiff.rs` (this crate) checks the method as algebra on the same model and the harness
//! runs it end to end on the ESC emulator; this file runs the machine's own step logic
//! (targets, stale-latch checks, working counters, the clock-rate correction, restores,
//! fallbacks) at the speed of a unit test, so every change to it is judged by the tests that
//! exercise core.
//!
//! verifies: REQ-DC-120, REQ-DC-121, REQ-DC-122, REQ-DC-123, REQ-DC-124, REQ-DC-125, REQ-DC-126

use ecdc_core::dc::{
    Config, Error, Event, Machine, SlaveInfo, State, TdiffFallback, TdiffMode, TdiffSource,
    TdiffType,
};
use ecdc_core::time::SystemTime;
use ecdc_core::wire::{Address, Command, EthernetFrame};
use ecdc_spec::network::{generate, Dc, Esc, GenParams, Latch, Network, Shape, SplitMix};

/// DL control 0x0100..0x0101 at power-on (forwarding rule bit set, every loop on "auto").
const DL_CONTROL_RESET: u16 = 0x0001;
const AL_INIT: u16 = 0x0001;
const AL_OP: u16 = 0x0008;

/// The slaves of a [`Network`] as the master's frames find them. Positions and ESC indices
/// agree: the network is numbered in auto-increment order.
struct Ring {
    net: Network,
    esc_type: Vec<u16>,
    al: Vec<u16>,
    station: Vec<u16>,
    dl_control: Vec<u16>,
    /// Receive Time Port 0..3 registers (a closed port keeps what it had).
    ports: Vec<[u32; 4]>,
    /// True time the frame being answered passes the slaves, ns.
    now: u64,
    /// Every write to DL control: (station, value).
    dl_writes: Vec<(u16, u16)>,
    /// The register of every FPRD, in order.
    reads: Vec<u16>,
    /// Latch triggers answered so far.
    triggers: usize,
    /// (ESC, trigger number, ports): that ESC's latch unit misses that trigger on those ports
    /// (bit `p`: port `p`), stamping only the others.
    missed_latch: Option<(usize, usize, u8)>,
    /// Every trigger's working counter counts every DC slave, cut off or not (a faulty ring).
    wkc_ignores_cut: bool,
    /// The number of every frame that carried a latch trigger (frames counted from 1).
    trigger_frames: Vec<usize>,
    frames: usize,
    /// [`Ring::reach`] until DL control changes.
    cache: Option<Reach>,
    /// DL status 0x0110 of each ESC (its open ports; forcing a loop closed does not change it).
    dl_status: Vec<u16>,
}

/// What a frame reaches while DL control forces some ports closed.
struct Reach {
    /// The ESCs reached, in auto-increment order.
    order: Vec<usize>,
    /// The index of each ESC in the reduced network (`None`: cut off).
    map: Vec<Option<usize>>,
    /// A latch frame's walk through the reduced network.
    latch: Latch,
}

impl Ring {
    fn new(net: Network, esc_type: Vec<u16>) -> Ring {
        let n = net.escs.len();
        assert_eq!(esc_type.len(), n);
        let full = net.latch().expect("a tree");
        let dl_status = (0..n).map(|j| net.observe(&full, j, 1).dl_status).collect();
        Ring {
            dl_status,
            ports: net.escs.iter().map(|e| e.stale).collect(),
            net,
            esc_type,
            al: vec![AL_INIT; n],
            station: vec![0; n],
            dl_control: vec![DL_CONTROL_RESET; n],
            now: 0,
            dl_writes: Vec::new(),
            reads: Vec::new(),
            triggers: 0,
            missed_latch: None,
            wkc_ignores_cut: false,
            trigger_frames: Vec::new(),
            frames: 0,
            cache: None,
        }
    }

    /// Whether DL control forces port `port` of ESC `i` closed (loop bits 0b11).
    fn forced_closed(&self, i: usize, port: u8) -> bool {
        (self.dl_control[i] >> (8 + 2 * u16::from(port))) & 0b11 == 0b11
    }

    /// What a frame reaches with the ports DL control forces closed now.
    fn reach(&self) -> Reach {
        let (net, map) = self.net.with_closed_ports(|i, p| self.forced_closed(i, p));
        let mut back = vec![0; net.escs.len()];
        for (old, new) in map.iter().enumerate() {
            if let Some(k) = new {
                back[*k] = old;
            }
        }
        let latch = net.latch().expect("a tree");
        let order = latch.order.iter().map(|&k| back[k]).collect();
        Reach { order, map, latch }
    }

    /// The slaves' answer to one of the machine's frames.
    fn answer(&mut self, frame: &[u8]) -> Vec<u8> {
        let mut out = frame.to_vec();
        let mut eth = EthernetFrame::new_unchecked(&mut out[..]);
        eth.mark_processed_by_slave();
        self.frames += 1;
        for d in eth.ecat_frame_mut().expect("an EtherCAT frame").iter_mut() {
            let mut d = d.expect("a datagram");
            let (cmd, adp, ado) = (d.command().expect("a command"), d.adp(), d.ado());
            let wkc = self.datagram(cmd, adp, ado, d.data_mut());
            d.set_wkc(wkc);
        }
        out
    }

    fn datagram(&mut self, cmd: Command, adp: u16, ado: u16, data: &mut [u8]) -> u16 {
        let reach = self.cache.take().unwrap_or_else(|| self.reach());
        let wkc = self.datagram_on(cmd, adp, ado, data, &reach);
        if !(cmd == Command::Fpwr && ado == 0x0100) {
            self.cache = Some(reach);
        }
        wkc
    }

    fn datagram_on(
        &mut self,
        cmd: Command,
        adp: u16,
        ado: u16,
        data: &mut [u8],
        reach: &Reach,
    ) -> u16 {
        let reached = &reach.order;
        let count = |n: usize| u16::try_from(n).expect("small");
        match cmd {
            Command::Brd => count(reached.len()),
            Command::Apwr => match reached.get(usize::from(Address::position_of_adp(adp))) {
                Some(&j) => {
                    if ado == 0x0010 {
                        self.station[j] = u16::from_le_bytes([data[0], data[1]]);
                    }
                    1
                }
                None => 0,
            },
            Command::Fprd | Command::Fpwr => {
                let hits: Vec<usize> = reached
                    .iter()
                    .copied()
                    .filter(|&j| self.station[j] == adp)
                    .collect();
                for &j in &hits {
                    if cmd == Command::Fprd {
                        self.reads.push(ado);
                        self.read(j, ado, data);
                    } else if ado == 0x0100 {
                        let v = u16::from_le_bytes([data[0], data[1]]);
                        self.dl_control[j] = v;
                        self.dl_writes.push((adp, v));
                    }
                }
                count(hits.len())
            }
            Command::Bwr if ado == 0x0900 => {
                self.triggers += 1;
                self.trigger_frames.push(self.frames);
                self.latch(reach);
                let dc = |j: &usize| self.net.escs[*j].dc != Dc::None;
                if self.wkc_ignores_cut {
                    count(self.net.escs.iter().filter(|e| e.dc != Dc::None).count())
                } else {
                    count(reached.iter().filter(|j| dc(j)).count())
                }
            }
            _ => 0,
        }
    }

    /// FPRD `ado` of ESC `j` into `data`.
    fn read(&self, j: usize, ado: u16, data: &mut [u8]) {
        let esc = &self.net.escs[j];
        let v: u64 = match ado {
            0x0000 => u64::from(self.esc_type[j]),
            0x0008 => match esc.dc {
                Dc::None => 0x0000,
                Dc::Bits32 => 0x0004,
                Dc::Bits64 => 0x000C,
            },
            0x0100 => u64::from(self.dl_control[j]),
            0x0110 => u64::from(self.dl_status[j]),
            0x0130 => u64::from(self.al[j]),
            0x0900 => {
                for (chunk, t) in data.chunks_mut(4).zip(self.ports[j]) {
                    chunk.copy_from_slice(&t.to_le_bytes()[..chunk.len()]);
                }
                return;
            }
            0x0910 => u64::try_from(self.net.local_time(j, i128::from(self.now))).expect("wrapped"),
            _ => 0,
        };
        for (b, v) in data.iter_mut().zip(v.to_le_bytes()) {
            *b = v;
        }
    }

    /// A latch trigger at `self.now` through what the frame reaches: every DC ESC it reaches
    /// stamps the ports the frame passes.
    fn latch(&mut self, reach: &Reach) {
        let latch = &reach.latch;
        let t0 = i128::from(self.now);
        for (j, k) in reach.map.iter().enumerate() {
            let Some(k) = *k else { continue };
            if self.net.escs[j].dc == Dc::None {
                continue;
            }
            let missed = match self.missed_latch {
                Some((esc, trigger, ports)) if (esc, trigger) == (j, self.triggers) => ports,
                _ => 0,
            };
            for (p, rx) in latch.port_rx[k].iter().enumerate() {
                if missed & (1 << p) != 0 {
                    continue;
                }
                if let Some(t) = rx {
                    let local = self.net.local_time(j, t0 + t).rem_euclid(1 << 32);
                    self.ports[j][p] = u32::try_from(local).expect("32 bits");
                }
            }
        }
    }
}

/// What a run of the machine against a ring saw.
struct Run {
    slaves: Vec<SlaveInfo>,
    events: Vec<Event>,
    /// Frames sent while in a t_Diff state.
    tdiff_frames: usize,
}

/// Time from sending a frame to handling its reply, ns.
const TURN_NS: u64 = 20_000;

/// Starts (or restarts) `m` and runs it against `ring` until `stop` holds (checked before each
/// frame) or it reaches the delay measurement; frames whose number (from 1) is in `lost` get
/// no reply. Panics if the machine fails or stalls.
fn run_until<const N: usize>(
    m: &mut Machine<N>,
    ring: &mut Ring,
    lost: &[usize],
    stop: impl Fn(&Machine<N>, &Ring) -> bool,
) -> Run {
    let mut now = ring.now + 1_000_000;
    m.start(SystemTime(now));
    let mut buf = [0u8; 1514];
    let (mut frames, mut tdiff_frames) = (0, 0);
    let mut events = Vec::new();
    for _ in 0..50_000 {
        while let Some(e) = m.poll_event() {
            events.push(e);
        }
        let state = m.state();
        let delays = matches!(
            state,
            State::LatchReadBefore | State::LatchTrigger | State::LatchReadAfter
        );
        if delays || stop(m, ring) {
            return Run {
                slaves: m.slaves().to_vec(),
                events,
                tdiff_frames,
            };
        }
        assert!(state != State::Failed, "failed: {events:?}");
        if let Some(n) = m.poll_transmit(SystemTime(now), &mut buf) {
            frames += 1;
            if state.name().starts_with("tdiff") {
                tdiff_frames += 1;
            }
            ring.now = now + TURN_NS / 4;
            let reply = ring.answer(&buf[..n]);
            now += TURN_NS;
            if !lost.contains(&frames) {
                m.handle_frame(SystemTime(now), &reply);
            }
        } else {
            let t = m.poll_timeout().expect("a machine waiting for nothing");
            now = now.max(t.0);
            m.handle_timeout(SystemTime(now));
        }
    }
    panic!("no delay measurement after 50 000 steps: {events:?}");
}

fn run<const N: usize>(m: &mut Machine<N>, ring: &mut Ring) -> Run {
    run_until(m, ring, &[], |_, _| false)
}

/// A configuration with few latch rounds (the method is exact on the model whatever their
/// number; `line_with_default_rounds` runs the defaults).
fn quick() -> Config {
    let mut c = Config::default();
    c.tdiff.base_rounds = 6;
    c.tdiff.rounds = 3;
    c
}

/// A line: ESC `i` entered at port 0, wired to port 1 of ESC `i − 1`; `[t_P, t_F, cable]` per
/// ESC, 64-bit DC, ideal clocks with phases that make port times wrap.
fn line(delays: &[[i128; 3]]) -> Network {
    let escs = (0..delays.len())
        .map(|i| {
            let [t_p, t_f, cable] = delays[i];
            Esc {
                parent: i.checked_sub(1).map(|p| (p, 1)),
                entry: 0,
                cable,
                t_p,
                t_f,
                dc: Dc::Bits64,
                phase: (1 << 32) - 300_000 + 7_919 * i as u64,
                rate_ppb: 0,
                stale: [0x5A5A_0000 + i as u32; 4],
            }
        })
        .collect();
    let net = Network { escs };
    net.validate().expect("a line");
    net
}

/// [t_P, t_F, cable] of six slaves with their own t_P and t_F.
const LINE6: [[i128; 3]; 6] = [
    [420, 300, 200],
    [390, 310, 35],
    [505, 280, 60],
    [300, 300, 15],
    [610, 330, 500],
    [470, 290, 40],
];

fn line6() -> Network {
    line(&LINE6)
}

fn truth(net: &Network, i: usize) -> i32 {
    i32::try_from(net.escs[i].t_p - net.escs[i].t_f).expect("small")
}

fn resolved(run: &Run) -> Vec<(i32, TdiffSource)> {
    run.slaves
        .iter()
        .map(|s| (s.t_diff_ns, s.t_diff_source))
        .collect()
}

/// The close of target `station` written by the machine: its DL control with the loop bits of
/// port 1 set to "closed".
fn close_of(station: u16) -> (u16, u16) {
    (station, DL_CONTROL_RESET | 0b11 << 10)
}

/// REQ-DC-121, REQ-DC-122, REQ-DC-124, REQ-DC-126 on a line of one ESC type: every middle
/// slave is measured exactly, the first slave and the line end take the first measured
/// value of their type; each target's port is closed and restored once, in position order,
/// and DL control ends as it was; one frame per latch round.
#[test]
fn line_measures_every_middle_slave() {
    let net = line6();
    let mut ring = Ring::new(net.clone(), vec![0x1111; 6]);
    let mut m = Machine::<8>::new(quick()).unwrap();
    let r = run(&mut m, &mut ring);
    let first = truth(&net, 1);
    let same = TdiffSource::SameType { from: 1 };
    let mut want = vec![(first, same)];
    want.extend((1..5).map(|i| (truth(&net, i), TdiffSource::Measured)));
    want.push((first, same));
    assert_eq!(resolved(&r), want);
    let mut writes = Vec::new();
    for station in 0x1002..=0x1005 {
        writes.push(close_of(station));
        writes.push((station, DL_CONTROL_RESET));
    }
    assert_eq!(ring.dl_writes, writes);
    assert!(ring.dl_control.iter().all(|&v| v == DL_CONTROL_RESET));
    // DL control is read from the possible targets only: slaves with two open ports, not the
    // line end.
    let dl_reads = ring.reads.iter().filter(|&&r| r == 0x0100).count();
    assert_eq!(dl_reads, 5);
    assert!(r.events.contains(&Event::TdiffResolved {
        measured: 4,
        same_type: 2,
        configured: 0,
        fallback: 0,
    }));
    // The reads (one frame), the first read with the first trigger, one frame per all-open
    // round; per target its close, its first trigger, one frame per closed round, its
    // restore.
    let (base, rounds) = (6, 3);
    assert_eq!(r.tdiff_frames, 1 + 1 + base + 4 * (1 + 1 + rounds + 1));
    // One trigger per round: the last round of a kind carries none.
    assert_eq!(ring.triggers, base + 4 * rounds);
    // The step leaves nothing behind: the delay measurement follows.
    assert_eq!(m.state(), State::LatchReadBefore);
}

/// The default number of rounds gives the same exact values.
#[test]
fn line_with_default_rounds() {
    let net = line6();
    let mut ring = Ring::new(net.clone(), (0..6).map(|i| 0x2000 + i).collect());
    let mut m = Machine::<8>::new(Config::default()).unwrap();
    let r = run(&mut m, &mut ring);
    for (i, (v, src)) in resolved(&r).into_iter().enumerate() {
        if (1..5).contains(&i) {
            assert_eq!(
                (v, src),
                (truth(&net, i), TdiffSource::Measured),
                "slave {i}"
            );
        } else {
            assert_eq!((v, src), (0, TdiffSource::Default), "slave {i}");
        }
    }
}

/// Whether the model says slave `b` can be measured (REQ-DC-121, REQ-DC-122): a DC ESC entered
/// at port 0 with a downstream port, below a DC ESC reached through plain-wire non-DC ESCs.
fn measurable(net: &Network, b: usize) -> bool {
    let esc = &net.escs[b];
    if esc.dc == Dc::None || esc.entry != 0 || net.children(b).iter().all(Option::is_none) {
        return false;
    }
    let mut up = esc.parent;
    while let Some((a, _)) = up {
        if net.escs[a].dc != Dc::None {
            return true;
        }
        up = net.escs[a].parent;
    }
    false
}

/// REQ-DC-121..126 on random trees (forks, crosses, non-DC ESCs in between, 32-bit clocks,
/// ESCs entered at other ports, port times that wrap): every measurable slave is measured
/// exactly, or falls back with the exact value when that is outside the plausible range;
/// every other slave keeps the default (each ESC has its own type, so nothing is shared).
#[test]
fn random_trees_measure_every_measurable_slave() {
    let cfg = quick();
    let (lo, hi) = (cfg.tdiff.min_ns, cfg.tdiff.max_ns);
    let (mut measured, mut implausible) = (0, 0);
    for seed in 0..24u64 {
        let mut rng = SplitMix::new(seed);
        let net = generate(&mut rng, &GenParams::new(12, Shape::Any, 20, 30));
        let n = net.escs.len();
        let mut ring = Ring::new(net.clone(), (0..n).map(|i| 0x3000 + i as u16).collect());
        let mut m = Machine::<16>::new(cfg).unwrap();
        let r = run(&mut m, &mut ring);
        for (b, (v, src)) in resolved(&r).into_iter().enumerate() {
            let t = truth(&net, b);
            let want = if !measurable(&net, b) {
                (0, TdiffSource::Default)
            } else if (lo..=hi).contains(&t) {
                measured += 1;
                (t, TdiffSource::Measured)
            } else {
                implausible += 1;
                let f = TdiffFallback::Implausible { measured_ns: t };
                (0, TdiffSource::Fallback(f))
            };
            assert_eq!((v, src), want, "seed {seed}, slave {b}");
        }
        assert!(ring.dl_control.iter().all(|&v| v == DL_CONTROL_RESET));
    }
    assert!(measured > 50 && implausible > 0, "{measured} {implausible}");
}

/// REQ-DC-121: the excursion is read on the upstream slave's clock and the round trip on the
/// target's, 200 ppm apart here; over a long subtree (a 40 µs cable behind the target, so an
/// 80 µs round trip) the uncorrected difference would be 16 ns. The rate correction brings it
/// within the rounding of the integer stamps.
#[test]
fn clock_rates_are_corrected() {
    let mut net = line(&[[420, 300, 200], [390, 310, 35], [505, 280, 40_000]]);
    net.escs[0].rate_ppb = 100_000;
    net.escs[1].rate_ppb = -100_000;
    net.escs[2].rate_ppb = 30_000;
    let mut ring = Ring::new(net.clone(), vec![0x1111, 0x2222, 0x3333]);
    let mut m = Machine::<4>::new(quick()).unwrap();
    let r = run(&mut m, &mut ring);
    let (v, src) = (r.slaves[1].t_diff_ns, r.slaves[1].t_diff_source);
    assert_eq!(src, TdiffSource::Measured);
    assert!((v - truth(&net, 1)).abs() <= 1, "{v} vs {}", truth(&net, 1));
}

/// `TdiffMode::PerEscType`: one slave per ESC type and revision is measured (the first
/// measurable one), every other slave of that type takes its value.
#[test]
fn per_esc_type_measures_one_of_each() {
    let net = line(&[&LINE6[..], &[[400, 300, 40]]].concat());
    let (a, b) = (0xA000, 0xB000);
    let mut ring = Ring::new(net.clone(), vec![a, a, b, a, b, b, a]);
    let mut cfg = quick();
    cfg.tdiff.mode = TdiffMode::PerEscType;
    let mut m = Machine::<8>::new(cfg).unwrap();
    let r = run(&mut m, &mut ring);
    let (ta, tb) = (truth(&net, 1), truth(&net, 2));
    let from = |from| TdiffSource::SameType { from };
    assert_eq!(
        resolved(&r),
        vec![
            (ta, from(1)),
            (ta, TdiffSource::Measured),
            (tb, TdiffSource::Measured),
            (ta, from(1)),
            (tb, from(2)),
            (tb, from(2)),
            (ta, from(1)),
        ]
    );
    let closes: Vec<u16> = ring
        .dl_writes
        .iter()
        .filter(|w| w.1 != DL_CONTROL_RESET)
        .map(|w| w.0)
        .collect();
    assert_eq!(closes, [0x1002, 0x1003]);
}

/// REQ-DC-126: a per-slave value and a per-type entry are used as given and those slaves are
/// not measured (their ports are never closed); mode Off reads and writes no DL control and
/// leaves `Config::t_diff_ns` everywhere.
#[test]
fn configured_values_and_mode_off() {
    let net = line6();
    let types = vec![0x1111, 0x1111, 0x2222, 0x1111, 0x2222, 0x1111];
    let mut cfg = quick();
    cfg.tdiff.types[2] = Some(TdiffType {
        esc_type: 0x2222,
        t_diff_ns: 77,
    });
    let mut ring = Ring::new(net.clone(), types.clone());
    let mut m = Machine::<8>::new(cfg).unwrap();
    m.set_slave_t_diff(3, Some(-5)).unwrap();
    let r = run(&mut m, &mut ring);
    let t1 = truth(&net, 1);
    assert_eq!(
        resolved(&r),
        vec![
            (t1, TdiffSource::SameType { from: 1 }),
            (t1, TdiffSource::Measured),
            (77, TdiffSource::Configured),
            (-5, TdiffSource::Configured),
            (77, TdiffSource::Configured),
            (t1, TdiffSource::SameType { from: 1 }),
        ]
    );
    assert_eq!(
        ring.dl_writes,
        [close_of(0x1002), (0x1002, DL_CONTROL_RESET)]
    );

    let mut cfg = quick();
    cfg.tdiff.mode = TdiffMode::Off;
    cfg.t_diff_ns = 12;
    let mut ring = Ring::new(net, types);
    let mut m = Machine::<8>::new(cfg).unwrap();
    let r = run(&mut m, &mut ring);
    assert_eq!(resolved(&r), vec![(12, TdiffSource::Default); 6]);
    assert!(ring.dl_writes.is_empty());
    for register in [0x0000, 0x0100, 0x0130] {
        assert!(!ring.reads.contains(&register), "Off read {register:#06x}");
    }
}

/// REQ-DC-123, REQ-DC-126: with a slave in OP no port is closed. A re-initialisation of the
/// same network keeps the values measured at each position in the first bring-up (source
/// `Earlier`, the unmeasurable ones sharing them by type); a slave whose ESC type changed
/// and a network with another slave count get the fallback "running".
#[test]
fn running_slave_closes_no_port_and_keeps_earlier_values() {
    let net = line6();
    let mut ring = Ring::new(net.clone(), vec![0x1111; 6]);
    let mut cfg = quick();
    cfg.t_diff_ns = 9;
    let mut m = Machine::<8>::new(cfg).unwrap();
    let first = resolved(&run(&mut m, &mut ring));
    assert_eq!(first[2], (truth(&net, 2), TdiffSource::Measured));

    ring.al[3] = AL_OP;
    ring.dl_writes.clear();
    let r = run(&mut m, &mut ring);
    assert!(
        ring.dl_writes.is_empty(),
        "a port closed under a running slave"
    );
    let mut want: Vec<_> = first.clone();
    for (i, w) in want.iter_mut().enumerate().take(5).skip(1) {
        *w = (truth(&net, i), TdiffSource::Earlier);
    }
    assert_eq!(resolved(&r), want);

    // Position 2 now holds an ESC of another type: it is not given the old value.
    ring.esc_type[2] = 0x7777;
    let r = run(&mut m, &mut ring);
    let running = TdiffSource::Fallback(TdiffFallback::Running);
    assert_eq!(resolved(&r)[2], (9, running));
    assert_eq!(resolved(&r)[3], (truth(&net, 3), TdiffSource::Earlier));

    // One slave fewer: no position can be trusted to hold the same slave.
    let mut short = net.clone();
    short.escs.pop();
    let mut ring = Ring::new(short, vec![0x1111; 5]);
    ring.al[3] = AL_OP;
    let r = run(&mut m, &mut ring);
    assert_eq!(resolved(&r), vec![(9, running); 5]);
    assert!(r.events.contains(&Event::TdiffResolved {
        measured: 0,
        same_type: 0,
        configured: 0,
        fallback: 5,
    }));
}

/// REQ-DC-124: a lost frame and a latch that did not happen on one slave (its stamps did not
/// change) are retried from a new trigger; the values stay exact.
#[test]
fn lost_frames_and_stale_latches_are_retried() {
    let net = line6();
    for lost in [&[6usize][..], &[9, 25], &[30, 31, 32]] {
        let mut ring = Ring::new(net.clone(), vec![0x1111; 6]);
        let mut m = Machine::<8>::new(quick()).unwrap();
        let r = run_until(&mut m, &mut ring, lost, |_, _| false);
        for i in 1..5 {
            assert_eq!(r.slaves[i].t_diff_ns, truth(&net, i), "lost {lost:?}");
        }
        assert!(ring.dl_control.iter().all(|&v| v == DL_CONTROL_RESET));
    }
    // Trigger 3 is an all-open round (slave 1 is the first target and the second one's
    // upstream slave, 2 the second target), 12 a closed round of the second target (its
    // upstream slave 1 misses it), 5 an all-open round missed by the last target. A latch
    // missed on one port only (the last target's last port, a target's entry port, the upstream
    // slave's port towards it or the one before) is stale as well.
    let all = 0b1111;
    for (esc, trigger, ports) in [
        (1, 3, all),
        (2, 3, all),
        (1, 12, all),
        (4, 5, all),
        (4, 3, 0b0010),
        (2, 3, 0b0001),
        (1, 3, 0b0010),
        (0, 3, 0b0010),
        (0, 3, 0b0001),
        (1, 12, 0b0010),
    ] {
        let mut ring = Ring::new(net.clone(), vec![0x1111; 6]);
        ring.missed_latch = Some((esc, trigger, ports));
        let mut m = Machine::<8>::new(quick()).unwrap();
        let r = run(&mut m, &mut ring);
        for i in 1..5 {
            assert_eq!(r.slaves[i].t_diff_ns, truth(&net, i), "{esc} {trigger}");
        }
        let stale = r
            .events
            .iter()
            .any(|e| matches!(e, Event::Error(Error::Measurement { .. })));
        assert!(
            stale,
            "missed latch of {esc} ports {ports:#b} at {trigger} not seen: {:?}",
            r.events
        );
    }
}

/// REQ-DC-125: while a target's ports are closed the slaves behind it cannot answer the
/// trigger; a working counter that counts them anyway is refused.
#[test]
fn trigger_wkc_counts_only_reachable_slaves() {
    let mut ring = Ring::new(line6(), vec![0x1111; 6]);
    ring.wkc_ignores_cut = true;
    let mut m = Machine::<8>::new(quick()).unwrap();
    let r = run_until(&mut m, &mut ring, &[], |_, ring| ring.triggers > 40);
    let refused = r.events.iter().any(|e| {
        matches!(
            e,
            Event::Error(Error::Wkc {
                command: Command::Bwr,
                ..
            })
        )
    });
    assert!(refused, "{:?}", r.events);
    assert!(r
        .slaves
        .iter()
        .all(|s| s.t_diff_source != TdiffSource::Measured));
}

/// REQ-DC-124: a bring-up started again while a target's ports are closed first reopens them
/// (before the slave count, which would otherwise miss the slaves behind them) and then
/// measures every slave as usual.
#[test]
fn restart_while_closed_reopens_first() {
    let net = line6();
    let mut ring = Ring::new(net.clone(), vec![0x1111; 6]);
    let mut m = Machine::<8>::new(quick()).unwrap();
    let closed = |_: &Machine<8>, ring: &Ring| ring.dl_control[3] != DL_CONTROL_RESET;
    run_until(&mut m, &mut ring, &[], closed);
    assert_eq!(ring.dl_writes.last(), Some(&close_of(0x1004)));
    let r = run(&mut m, &mut ring);
    assert_eq!(ring.dl_writes[5], (0x1004, DL_CONTROL_RESET));
    assert!(r.events.contains(&Event::SlavesFound { count: 6, dc: 6 }));
    for i in 1..5 {
        assert_eq!(
            (r.slaves[i].t_diff_ns, r.slaves[i].t_diff_source),
            (truth(&net, i), TdiffSource::Measured)
        );
    }
    assert!(ring.dl_control.iter().all(|&v| v == DL_CONTROL_RESET));
}

/// REQ-DC-124: on a line long enough that each latch round's reads take two frames, a lost
/// frame that carried a trigger is not simply sent again: its trigger was executed, so the
/// reads it carried would see a newer latch than the reads of the frame before. The step
/// latches again and reads every slave anew, and every value stays exact.
#[test]
fn lost_trigger_frame_relatches_every_slave() {
    let delays: Vec<_> = (0..60).map(|i| [400 + 3 * i, 300, 20 + i]).collect();
    let net = line(&delays);
    let measure = |lost: &[usize]| {
        let mut ring = Ring::new(net.clone(), vec![0x1111; 60]);
        let mut m = Machine::<64>::new(quick()).unwrap();
        let r = run_until(&mut m, &mut ring, lost, |_, _| false);
        (r, ring.trigger_frames)
    };
    let (_, frames) = measure(&[]);
    // The first all-open round's reads end in the frame with the second trigger.
    let (r, _) = measure(&[frames[1]]);
    assert_eq!(frames[1] - frames[0], 2, "two frames a round: {frames:?}");
    for i in 1..59 {
        assert_eq!(r.slaves[i].t_diff_ns, truth(&net, i), "slave {i}");
    }
}
