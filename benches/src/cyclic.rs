//! A locked DC machine and a replayable ring of its cyclic frames.
//!
//! [`bring_up`] runs the sans-IO [`Machine`] against the emulator (the same [`Sim`] driver as
//! `ecdc simulate`) until it reports lock. [`capture`] then sends the machine's cyclic frames
//! through the emulator for a whole period of the frame pattern (datagram indexes advance by the
//! number of datagrams per cycle, the per-slave FPRD 0x092C round robin by
//! `monitor.slaves_per_cycle`; both are periodic) and keeps each request's real response.
//! [`Replay`] starts from a clone of the machine taken before the capture and replays the ring
//! without the emulator: per cycle `poll_transmit`, the captured response (FRMW reference time
//! moved forward with the clock), `handle_frame`, `poll_event`. Every replayed reply matches
//! its request by index, command, register, station and length, exactly as during the capture.

use ecdc_core::dc::{Config, Event, Machine, MonitorConfig, State, SyncConfig};
use ecdc_core::servo::master::{MasterConfig, MasterInput, MasterServo};
use ecdc_core::time::SystemTime;
use ecdc_core::wire::{Command, EthernetFrame};
use ecdc_harness::emu::{Delivery, Network, Scenario};
use ecdc_harness::sim::{Sim, DEFAULT_MASTER_EPOCH_NS};

/// Cycle period of every fixture (1 ms, the default DC cycle).
pub const CYCLE_NS: u64 = 1_000_000;

/// Shape of the emulated network.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Shape {
    /// Every slave on port 1 of the previous one.
    Line,
    /// Slave 0 is a 4-port junction; the others form three branches on its ports 3, 1 and 2
    /// (as `ecdc simulate --topology tree`).
    Tree,
}

impl Shape {
    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            Shape::Line => "line",
            Shape::Tree => "tree",
        }
    }
}

/// The emulator scenario: `n` default slaves (±50 ppm crystals, jitter on), seed `seed`.
pub fn scenario(shape: Shape, n: usize, seed: u64) -> Scenario {
    let mut sc = match shape {
        Shape::Tree => Scenario::junction_tree(n),
        Shape::Line => Scenario::line(n),
    };
    sc.seed = seed;
    sc
}

/// ecdc's configuration for a run (as `ecdc simulate`): t_Diff from the emulator's default ESC
/// (t_P − t_F), SYNC0 and the monitor at [`CYCLE_NS`].
pub fn config(sc: &Scenario) -> Config {
    config_with_cycle(sc, CYCLE_NS)
}

/// [`config`] with another cycle (networks whose round trip exceeds 1 ms need a longer one).
pub fn config_with_cycle(sc: &Scenario, cycle_ns: u64) -> Config {
    let t_diff = i64::try_from(sc.defaults.t_p_ns).unwrap_or(0)
        - i64::try_from(sc.defaults.t_f_ns).unwrap_or(0);
    let d = Config::default();
    Config {
        t_diff_ns: i32::try_from(t_diff).unwrap_or(0),
        sync: Some(SyncConfig {
            sync0_cycle_ns: u32::try_from(cycle_ns).unwrap_or(u32::MAX),
            ..SyncConfig::default()
        }),
        monitor: MonitorConfig {
            cycle_ns,
            ..d.monitor
        },
        ..d
    }
}

/// What a bring-up cost.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BringUp {
    /// Frames from `start` to the `Locked` event (`Stats::lock_frames`).
    pub lock_frames: u64,
    /// Simulated (true) time from `start` to the `Locked` event, ns.
    pub lock_true_ns: u64,
    /// Wall time of the whole bring-up (emulator and machine), s.
    pub wall_s: f64,
    /// Simulation steps.
    pub steps: u64,
}

/// Brings `machine` up on a fresh emulated network for `sc` until it is locked in `Cyclic`.
pub fn bring_up<const N: usize>(
    sc: &Scenario,
    machine: Machine<N>,
) -> anyhow::Result<(Sim<N>, BringUp)> {
    let net = Network::new(sc).map_err(|e| anyhow::anyhow!("scenario: {e:?}"))?;
    let started = std::time::Instant::now();
    let mut sim = Sim::new(machine, net);
    sim.start();
    // 60 s of simulated time is far beyond any bring-up (the 100-slave tree locks in ~1.4 s).
    let ev = sim
        .drive_until(60_000_000_000, |e| matches!(e, Event::Locked { .. }))
        .map_err(|e| anyhow::anyhow!("bring-up: {e}"))?;
    let wall_s = started.elapsed().as_secs_f64();
    let lock_true_ns = sim
        .events()
        .iter()
        .find(|(_, e)| *e == ev)
        .map_or(sim.now(), |(t, _)| *t);
    let lock_frames = match ev {
        Event::Locked { frames, .. } => frames,
        _ => 0,
    };
    let steps = sim.stats().steps;
    Ok((
        sim,
        BringUp {
            lock_frames,
            lock_true_ns,
            wall_s,
            steps,
        },
    ))
}

/// One captured cycle: the response frame and where its FRMW reference time sits.
#[derive(Debug, Clone)]
pub struct Response {
    /// The frame as the master received it from the emulator.
    pub frame: Vec<u8>,
    /// Byte offset and width (4 or 8) of the FRMW data (reference time) in `frame`.
    pub frmw: Option<(usize, usize)>,
    /// Reference time minus the master time the request was sent at, ns.
    pub ref_minus_sent: i64,
    /// Arrival minus send time (round trip), ns.
    pub rtt_ns: u64,
}

/// The machine at the start of the ring, and the ring.
#[derive(Debug, Clone)]
pub struct Capture<const N: usize> {
    /// The machine as it was before the first captured cycle (Cyclic, locked, idle).
    pub machine: Machine<N>,
    /// Master time at which the first captured cycle is due.
    pub first_due: u64,
    /// One response per cycle of the frame pattern's period.
    pub ring: Vec<Response>,
    /// The first request (for inspection).
    pub request: Vec<u8>,
    /// Cycle period, ns.
    pub cycle_ns: u64,
}

/// Request bytes with the FRMW payload (master time) zeroed, for comparing patterns.
fn pattern(frame: &[u8]) -> Vec<u8> {
    let mut v = frame.to_vec();
    if let Some((off, w)) = frmw_data(frame) {
        if let Some(d) = v.get_mut(off..off + w) {
            d.fill(0);
        }
    }
    v
}

/// Offset (in the Ethernet frame) and length of the first FRMW datagram's data.
pub fn frmw_data(frame: &[u8]) -> Option<(usize, usize)> {
    let eth = EthernetFrame::new_checked(frame).ok()?;
    let ecat = eth.ecat_frame().ok()?;
    let start = frame.len() - eth.payload().len();
    for (d, span) in ecat.iter().zip(ecat.datagram_offsets()) {
        let (d, (off, _)) = (d.ok()?, span.ok()?);
        if d.command_raw() == Command::Frmw.code() {
            return Some((start + off + 10, usize::from(d.data_len())));
        }
    }
    None
}

fn read_le(b: &[u8]) -> u64 {
    let mut a = [0u8; 8];
    a[..b.len().min(8)].copy_from_slice(&b[..b.len().min(8)]);
    u64::from_le_bytes(a)
}

/// Master clock of the [`Sim`] (ideal: epoch + true time).
fn true_of(master: u64) -> u64 {
    master.saturating_sub(DEFAULT_MASTER_EPOCH_NS)
}

/// Sends the machine's cyclic frame due at master time `sent` through the emulator and hands
/// the response back to the machine.
fn one_cycle<const N: usize>(
    m: &mut Machine<N>,
    net: &mut Network,
    buf: &mut [u8],
    sent: u64,
) -> anyhow::Result<(Vec<u8>, Response)> {
    let n = m
        .poll_transmit(SystemTime(sent), buf)
        .ok_or_else(|| anyhow::anyhow!("no cyclic frame at {sent}"))?;
    let req = &buf[..n];
    let t = true_of(sent).max(net.now());
    let r = match net
        .transact(req, t)
        .map_err(|e| anyhow::anyhow!("emu: {e:?}"))?
    {
        Delivery::Returned(r) => r,
        Delivery::Lost(l) => anyhow::bail!("cycle lost: {l:?}"),
    };
    let rtt_ns = r.arrival.saturating_sub(t);
    m.handle_frame(SystemTime(sent + rtt_ns), &r.frame);
    while m.poll_event().is_some() {}
    let frmw = frmw_data(&r.frame);
    let ref_minus_sent = frmw.map_or(0, |(off, w)| {
        (read_le(&r.frame[off..off + w]) as i64).wrapping_sub(sent as i64)
    });
    Ok((
        req.to_vec(),
        Response {
            frame: r.frame,
            frmw,
            ref_minus_sent,
            rtt_ns,
        },
    ))
}

/// Captures the ring from a locked simulation (see the module docs). Fails if the machine
/// leaves `Cyclic`, loses lock or a cycle does not come back during the capture.
pub fn capture<const N: usize>(sim: Sim<N>) -> anyhow::Result<Capture<N>> {
    let now = sim.master_time_at(sim.now());
    capture_from(*sim.machine, sim.net, now)
}

/// [`capture`] from a locked machine and its network, the machine's clock being `now`.
pub fn capture_from<const N: usize>(
    mut m: Machine<N>,
    mut net: Network,
    now: SystemTime,
) -> anyhow::Result<Capture<N>> {
    let mut buf = vec![0u8; 1514];
    m.handle_timeout(now);
    anyhow::ensure!(m.is_locked(), "machine not locked: {}", m.state());
    let cycle = m.config().monitor.cycle_ns;
    let mut due = m
        .poll_timeout()
        .ok_or_else(|| anyhow::anyhow!("no cycle scheduled"))?
        .0;
    // Two cycles first, so nothing of the bring-up is in flight any more.
    for _ in 0..2 {
        one_cycle(&mut m, &mut net, &mut buf, due)?;
        due += cycle;
    }
    let start = m.clone();
    let lost0 = m.stats().lost_cycles;
    let mut ring = Vec::new();
    let mut first: Option<Vec<u8>> = None;
    let mut request = Vec::new();
    for k in 0..4096u64 {
        let sent = due + k * cycle;
        // The pattern repeats when the request about to be sent equals the first one; look
        // at it on a copy of the machine so the ring ends exactly there.
        let mut probe = m.clone();
        let n = probe
            .poll_transmit(SystemTime(sent), &mut buf)
            .ok_or_else(|| anyhow::anyhow!("no cyclic frame at cycle {k}"))?;
        let pat = pattern(&buf[..n]);
        match &first {
            None => first = Some(pat),
            Some(p) if *p == pat => {
                return Ok(Capture {
                    machine: start,
                    first_due: due,
                    ring,
                    request,
                    cycle_ns: cycle,
                });
            }
            Some(_) => {}
        }
        let (req, resp) = one_cycle(&mut m, &mut net, &mut buf, sent)?;
        if k == 0 {
            request = req;
        }
        anyhow::ensure!(
            m.state() == State::Cyclic && m.is_locked() && m.stats().lost_cycles == lost0,
            "machine left locked Cyclic during the capture: {} ({:?})",
            m.state(),
            m.stats()
        );
        ring.push(resp);
    }
    anyhow::bail!("frame pattern did not repeat within 4096 cycles")
}

/// Replays a [`Capture`] without the emulator.
#[derive(Debug, Clone)]
pub struct Replay<const N: usize> {
    /// The machine.
    pub machine: Machine<N>,
    ring: Vec<Response>,
    next: usize,
    now: u64,
    cycle_ns: u64,
    buf: Vec<u8>,
    base: ecdc_core::dc::Stats,
}

impl<const N: usize> Replay<N> {
    /// Starts at the capture's first cycle.
    pub fn new(c: &Capture<N>) -> Self {
        Replay {
            machine: c.machine.clone(),
            ring: c.ring.clone(),
            next: 0,
            now: c.first_due,
            cycle_ns: c.cycle_ns,
            buf: vec![0u8; 1514],
            base: *c.machine.stats(),
        }
    }

    /// Master time of the next cycle.
    pub fn now(&self) -> u64 {
        self.now
    }

    /// Prepares the next response: writes the reference time (moved with the clock) into the
    /// FRMW data. Returns the master time the frame is sent at. Not part of the core's work;
    /// [`Replay::cycle`] calls it, and benches may time it alone.
    #[inline]
    pub fn prepare(&mut self) -> u64 {
        let now = self.now;
        if let Some(r) = self.ring.get_mut(self.next) {
            if let Some((off, w)) = r.frmw {
                let v = now.wrapping_add(r.ref_minus_sent as u64).to_le_bytes();
                // Fixed-width stores (no `memcpy` call in the timed loop).
                match (w, r.frame.get_mut(off..)) {
                    (8, Some(d)) => {
                        if let Some(d) = d.first_chunk_mut::<8>() {
                            *d = v;
                        }
                    }
                    (4, Some(d)) => {
                        if let (Some(d), Some(s)) = (d.first_chunk_mut::<4>(), v.first_chunk::<4>())
                        {
                            *d = *s;
                        }
                    }
                    _ => {}
                }
            }
        }
        now
    }

    /// One cycle of the core: `poll_transmit` at the due time, `handle_frame` on the response,
    /// drain `poll_event`. Returns the reference time the machine extracted.
    #[inline]
    pub fn cycle(&mut self) -> Option<SystemTime> {
        let now = self.prepare();
        let n = self.machine.poll_transmit(SystemTime(now), &mut self.buf);
        std::hint::black_box((n, &self.buf));
        let r = self.ring.get(self.next)?;
        self.machine
            .handle_frame(SystemTime(now.wrapping_add(r.rtt_ns)), &r.frame);
        while let Some(e) = self.machine.poll_event() {
            std::hint::black_box(e);
        }
        self.next += 1;
        if self.next == self.ring.len() {
            self.next = 0;
        }
        self.now = now.wrapping_add(self.cycle_ns);
        self.machine.reference_time()
    }

    /// Whether the replay is still healthy: locked in `Cyclic`, no lost cycle, no foreign
    /// datagram (every reply matched its request).
    pub fn healthy(&self) -> bool {
        let s = self.machine.stats();
        self.machine.is_locked()
            && s.lost_cycles == self.base.lost_cycles
            && s.foreign_datagrams == self.base.foreign_datagrams
            && s.foreign_frames == self.base.foreign_frames
    }
}

/// Brings up `n` slaves (shape, seed 0) on a `Machine<N>` and captures the ring.
pub fn fixture<const N: usize>(shape: Shape, n: usize) -> anyhow::Result<(Capture<N>, BringUp)> {
    let sc = scenario(shape, n, 0);
    let m: Machine<N> = Machine::new(config(&sc)).map_err(|e| anyhow::anyhow!("config: {e:?}"))?;
    let (sim, b) = bring_up(&sc, m)?;
    Ok((capture(sim)?, b))
}

/// The master-follows-reference servo closed through a [`Replay`]: the cycles are replayed on
/// the fixed grid, and a wake-up `shift` (the sum of the servo's deadline corrections) is added
/// to the reference time the machine returned, which is what waking `shift` ns later would
/// have read. App time advances with the grid plus the servo's whole-period steps.
#[derive(Debug, Clone)]
pub struct MasterLoop {
    /// The servo.
    pub servo: MasterServo,
    shift: i64,
    app_base: i64,
}

impl MasterLoop {
    /// A servo for `cycle_ns` with the default configuration.
    pub fn new(cycle_ns: u64) -> anyhow::Result<Self> {
        let period = u32::try_from(cycle_ns)?;
        let cfg = MasterConfig::for_period(period).map_err(|e| anyhow::anyhow!("{e:?}"))?;
        Ok(MasterLoop {
            servo: MasterServo::new(cfg).map_err(|e| anyhow::anyhow!("{e:?}"))?,
            shift: 0,
            app_base: 0,
        })
    }

    /// One servo step for the cycle sent at `now` whose FRMW returned `reference` (or was
    /// lost). Returns the folded phase error.
    #[inline]
    pub fn step(&mut self, now: u64, reference: Option<SystemTime>) -> i64 {
        let input = match reference {
            Some(r) => MasterInput::Sample {
                local_ns: now.wrapping_add_signed(self.shift),
                app_ns: now.wrapping_add_signed(self.app_base),
                ref_ns: r.0.wrapping_add_signed(self.shift),
            },
            None => MasterInput::Lost,
        };
        let out = self.servo.update(input);
        self.shift = self.shift.wrapping_add(out.deadline_correction_ns);
        self.app_base = self.app_base.wrapping_add(out.app_time_step_ns);
        out.phase_error_ns
    }
}
