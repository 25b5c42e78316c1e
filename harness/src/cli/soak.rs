//! `ecdc soak`: hours of simulated operation under a seeded random fault schedule, faster
//! than real time (docs/emulator.md "Soak").
//!
//! The DC machine runs against the emulator ([`crate::sim::Sim`]). After every lock the
//! driver plays the rest of a master: it takes every slave below SAFEOP through PREOP and
//! SAFEOP to OP with AL control writes, so that most of the run happens with applications
//! running and the emulator's observer ([`crate::emu::esc::Esc::offset_writes_running`]) can
//! check that DC never writes a system time offset under one (REQ-DC-103).
//!
//! Faults come one at a time: a quiet gap, then one fault drawn uniformly from the kinds in
//! [`KINDS`] with random parameters, its window (start to end of the fault), and a recovery
//! bound after the window. At the bound the fault's outcome is decided from the machine's
//! events: unaffected, hold-over (ended by a resume), re-lock, or a violation (none of these
//! by the bound). Skew is measured in true time on the emulator's SYNC0 edges with the
//! shared [`PulseMatcher`]; "outside fault windows" means from the recovery (or the window's
//! end) plus [`SETTLE_NS`] to the next fault.

use std::collections::BTreeMap;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use ecdc_core::dc::{Config, Event, State};
use ecdc_core::wire::{Address, Command, FrameBuilder};

use crate::emu::yardstick::{wide_slaves, PulseMatcher};
use crate::emu::{Fault, FaultSpec, Network, Scenario, SyncSignal, SEED000_T_F_NS, SEED000_T_P_NS};
use crate::sim::{Sim, SimError};

/// Machine capacity: the 100-slave tree plus room.
const N: usize = 128;

/// ecdc choice: a fault's outcome must be decided within 5 s of its window's end, because a
/// full bring-up of the 100-slave tree (delay measurement, drift burst, SYNC start) takes
/// well under 2 s in the emulator and the rest is margin for a bring-up retried after loss.
pub const RECOVERY_BOUND_NS: u64 = 5_000_000_000;
/// ecdc choice: skew samples within 1 s after a recovery still belong to the fault, because
/// after a ±50 ppm step or a re-lock the drift loop needs a few hundred ms to settle.
pub const SETTLE_NS: u64 = 1_000_000_000;
/// ecdc choice: 6..15 s quiet between faults, so that the next fault starts after the
/// previous one's recovery bound and every fault is judged on its own.
const GAP_NS: (u64, u64) = (6_000_000_000, 15_000_000_000);
/// Skew samples are kept as the worst |skew| per 10 ms (bounded memory over any run).
const CHUNK_NS: u64 = 10_000_000;

/// The fault kinds of the schedule.
pub const KINDS: [&str; 9] = [
    "loss_burst",
    "link_break",
    "power_cycle",
    "frequency_step",
    "cable_change",
    "master_stall",
    "wire_silence",
    "reference_loss",
    "port_time_wrap",
];

/// Which network the soak runs on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Topology {
    /// Seed 000's line (`Scenario::seed000_line`, t_P/t_F from the paper).
    Seed000Line,
    /// The 100-slave tree of 3- and 4-port junctions.
    Tree100,
}

/// Arguments of `ecdc soak`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Network.
    #[arg(long, value_enum, default_value_t = Topology::Seed000Line)]
    pub topology: Topology,
    /// Simulated time: `1h`, `300s`, `90min` (a bare number is seconds; `--seconds N` is the
    /// older spelling).
    #[arg(long = "duration", visible_alias = "seconds", default_value = "1h",
          allow_negative_numbers = true, value_parser = super::validate::seconds)]
    pub seconds: f64,
    /// Seed of the fault schedule and of the emulator.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
    /// Control run: leave the slaves in INIT (the driver never requests OP), so DC may
    /// rewrite every offset at each restart.
    #[arg(long)]
    pub stay_init: bool,
}

/// One planned fault.
#[derive(Debug, Clone, Serialize)]
pub struct Planned {
    pub kind: &'static str,
    pub at_ns: u64,
    pub end_ns: u64,
    pub detail: String,
    #[serde(skip)]
    faults: Vec<FaultSpec>,
}

impl Planned {
    /// The emulator faults that make up this one.
    pub fn faults(&self) -> &[FaultSpec] {
        &self.faults
    }
}

/// What a fault led to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// The machine neither lost lock nor held over.
    Unaffected,
    /// Hold-over, ended by a resume.
    Holdover,
    /// Lock lost or DC restarted, locked again.
    Relock,
    /// Not locked again by the bound, but the machine reported a typed error for it.
    TypedError,
    /// Not locked again by the bound and no typed error.
    Violation,
}

/// One judged fault.
#[derive(Debug, Clone, Serialize)]
pub struct Judged {
    #[serde(flatten)]
    pub fault: Planned,
    pub outcome: Outcome,
    /// Re-lock or resume time after the window's end (0 when it happened inside it), ms.
    pub recovery_ms: Option<f64>,
    /// Typed errors the machine reported for this fault.
    pub errors: Vec<String>,
}

/// Per-kind summary.
#[derive(Debug, Clone, Default, Serialize)]
pub struct KindSummary {
    pub count: u64,
    pub unaffected: u64,
    pub holdover: u64,
    pub relock: u64,
    pub typed_error: u64,
    pub violation: u64,
    pub errors: u64,
    /// Recovery times (re-lock or resume after the window's end), ms: p50, p90, max.
    pub recovery_ms_p50: Option<f64>,
    pub recovery_ms_p90: Option<f64>,
    pub recovery_ms_max: Option<f64>,
}

/// The soak's result.
#[derive(Debug, Clone, Serialize)]
pub struct SoakReport {
    pub topology: Topology,
    pub seed: u64,
    pub simulated_s: f64,
    pub slaves: usize,
    pub faults: usize,
    pub per_kind: BTreeMap<&'static str, KindSummary>,
    pub violations: u64,
    /// Frames that wrote 0x0920..0x0927 of a slave in SAFEOP or OP (emulator observer).
    pub offset_writes_in_safeop_op: u64,
    /// Slaves in OP when the faults began (summed over faults) / slaves × faults.
    pub op_at_fault_start: (u64, u64),
    /// Worst |SYNC0 skew| outside fault windows, ns; and the p99 of the 10 ms maxima.
    pub skew_outside_max_ns: Option<u64>,
    pub skew_outside_p99_ns: Option<u64>,
    pub skew_outside_chunks: u64,
    /// 10 ms chunks outside fault windows in which no pulse could be paired.
    pub unpaired_outside_chunks: u64,
    /// 10 ms chunks outside fault windows with the machine not locked (not in the skew).
    pub unlocked_outside_chunks: u64,
    pub frames_sent: u64,
    pub restarts_by_driver: u64,
    pub judged: Vec<Judged>,
}

/// A scenario and machine configuration for `topology`.
pub fn setup(topology: Topology, seed: u64) -> (Scenario, Config) {
    match topology {
        Topology::Seed000Line => {
            let mut sc = Scenario::seed000_line();
            sc.seed = seed;
            let cfg = Config {
                t_diff_ns: (SEED000_T_P_NS - SEED000_T_F_NS) as i32,
                ..Config::default()
            };
            (sc, cfg)
        }
        Topology::Tree100 => {
            let mut sc = Scenario::tree_100();
            sc.seed = seed;
            // The emulator's default t_P 540 − t_F 460 ns.
            let cfg = Config {
                t_diff_ns: 80,
                ..Config::default()
            };
            (sc, cfg)
        }
    }
}

/// `fault` at `at_ns`, then `undo` at `undo_ns`.
fn fault_then(at_ns: u64, fault: Fault, undo_ns: u64, undo: Fault) -> Vec<FaultSpec> {
    vec![
        FaultSpec { at_ns, fault },
        FaultSpec {
            at_ns: undo_ns,
            fault: undo,
        },
    ]
}

/// `slave`'s port 0 link broken at `at_ns`, restored at `restore_ns`.
fn link_bounce(slave: usize, at_ns: u64, restore_ns: u64) -> Vec<FaultSpec> {
    fault_then(
        at_ns,
        Fault::LinkBreak { slave, port: 0 },
        restore_ns,
        Fault::LinkRestore { slave, port: 0 },
    )
}

/// The seeded schedule: faults from `start_ns` until `until_ns`, one at a time.
pub fn schedule(seed: u64, slaves: usize, start_ns: u64, until_ns: u64) -> Vec<Planned> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x50AC_50AC);
    let mut out = Vec::new();
    let mut t = start_ns;
    let mut wrap_done = false;
    loop {
        t += rng.gen_range(GAP_NS.0..GAP_NS.1);
        let kind = KINDS[rng.gen_range(0..KINDS.len())];
        let ms = |rng: &mut ChaCha8Rng, lo: u64, hi: u64| rng.gen_range(lo..hi) * 1_000_000;
        let slave = rng.gen_range(0..slaves);
        let (end, detail, faults) = match kind {
            "loss_burst" => {
                let rate: f64 = rng.gen_range(0.01..0.30);
                let d = ms(&mut rng, 100, 3000);
                (
                    t + d,
                    format!("{:.0} % for {} ms", rate * 100.0, d / 1_000_000),
                    fault_then(
                        t,
                        Fault::FrameLossRate { rate },
                        t + d,
                        Fault::FrameLossRate { rate: 0.0 },
                    ),
                )
            }
            "link_break" => {
                let d = ms(&mut rng, 20, 3000);
                (
                    t + d,
                    format!("slave {slave} port 0 for {} ms", d / 1_000_000),
                    link_bounce(slave, t, t + d),
                )
            }
            "power_cycle" | "reference_loss" => {
                // The reference is the first slave with a system time: slave 0 here.
                let slave = if kind == "reference_loss" {
                    0
                } else {
                    rng.gen_range(1..slaves.max(2))
                };
                let off = ms(&mut rng, 50, 3000);
                (
                    t + off,
                    format!("slave {slave} off {} ms", off / 1_000_000),
                    vec![FaultSpec {
                        at_ns: t,
                        fault: Fault::PowerCycle { slave, off_ns: off },
                    }],
                )
            }
            "frequency_step" => {
                let ppm: f64 = rng.gen_range(-50.0..50.0);
                (
                    t,
                    format!("slave {slave} to {ppm:+.1} ppm"),
                    vec![FaultSpec {
                        at_ns: t,
                        fault: Fault::FrequencyStep { slave, ppm },
                    }],
                )
            }
            "cable_change" => {
                let meters: f64 = rng.gen_range(0.5..100.0);
                (
                    t,
                    format!("slave {slave} port 0 cable {meters:.1} m"),
                    vec![FaultSpec {
                        at_ns: t,
                        fault: Fault::CableLength { slave, meters },
                    }],
                )
            }
            "master_stall" | "wire_silence" => {
                let d = ms(&mut rng, 5, 2000);
                let fault = if kind == "master_stall" {
                    Fault::MasterStall { duration_ns: d }
                } else {
                    Fault::WireSilence { duration_ns: d }
                };
                (
                    t + d,
                    format!("{} ms", d / 1_000_000),
                    vec![FaultSpec { at_ns: t, fault }],
                )
            }
            _ => {
                // Port-time wrap: the emulator sets every slave's power-on phase so that the
                // 32-bit local times wrap at one instant (scenario-only, so only once), 50 us
                // after a 1 ms link bounce: the wrap falls inside the re-bring-up that the
                // repair starts (slave count, addresses, delay latch). Later ones are bounces
                // on the 2^32 ns grid after that wrap; each slave's own wrap drifts off the
                // grid by its crystal error times the elapsed time (50 ppm x 1 h = 180 ms).
                let d = 1_000_000;
                let mut f = link_bounce(slave, t, t + d);
                if !wrap_done {
                    f.push(FaultSpec {
                        at_ns: t + d + 50_000,
                        fault: Fault::PortTimeWrap { slave: None },
                    });
                    wrap_done = true;
                }
                (
                    t + d,
                    format!("slave {slave} port 0 bounced 1 ms before the wrap grid"),
                    f,
                )
            }
        };
        if end + RECOVERY_BOUND_NS > until_ns {
            break;
        }
        out.push(Planned {
            kind,
            at_ns: t,
            end_ns: end,
            detail,
            faults,
        });
        t = end;
    }
    // After the first explicit wrap every 32-bit local time wraps every 2^32 ns: move the
    // later port-time-wrap bounces onto a wrap (same offset from it as the first one).
    let first_wrap = out.iter().find_map(|p| {
        p.faults.iter().find_map(|f| match f.fault {
            Fault::PortTimeWrap { .. } => Some(f.at_ns),
            _ => None,
        })
    });
    if let Some(w) = first_wrap {
        for i in 0..out.len() {
            let (prev_end, next_at) = (
                i.checked_sub(1).and_then(|j| out.get(j)).map(|p| p.end_ns),
                out.get(i + 1).map(|p| p.at_ns),
            );
            let Some(p) = out.get_mut(i) else { continue };
            if p.kind != "port_time_wrap" || p.at_ns + 1_050_000 <= w {
                continue;
            }
            let k = (p.at_ns + 1_050_000 - w) >> 32;
            let at = w + (k << 32) - 1_050_000;
            let fits = prev_end.is_none_or(|e| at >= e + RECOVERY_BOUND_NS)
                && next_at.is_none_or(|n| at + 1_000_000 + RECOVERY_BOUND_NS <= n);
            if fits {
                let shift = at as i64 - p.at_ns as i64;
                for f in &mut p.faults {
                    f.at_ns = (f.at_ns as i64 + shift) as u64;
                }
                p.at_ns = at;
                p.end_ns = at + 1_000_000;
            } else {
                p.detail = p
                    .detail
                    .replace("before the wrap grid", "(off the wrap grid: spacing)");
            }
        }
    }
    out
}

/// One APWR by auto-increment position `i` (a side-channel frame, not the machine's).
fn apwr(s: &mut Sim<N>, i: usize, ado: u16, data: &[u8]) -> Result<(), SimError> {
    let mut buf = [0u8; 64];
    let Ok(mut b) = FrameBuilder::new(&mut buf) else {
        return Ok(());
    };
    if b.push(Command::Apwr, 0x7E, Address::position(i as u16, ado), data)
        .is_err()
    {
        return Ok(());
    }
    let Ok(n) = b.finish() else { return Ok(()) };
    s.side_channel(&buf[..n]).map(|_| ())
}

/// Takes every powered slave below SAFEOP to OP as a master's application layer would after
/// DC is up: the SyncManagers as its SII lists them (start, length, control, activate), one
/// FMMU per process-data SyncManager (write for outputs, read for inputs; logical addresses
/// 256 per slave, which nothing here exchanges), then AL control PREOP, SAFEOP, OP, by
/// auto-increment address.
fn to_op(s: &mut Sim<N>) -> Result<(), SimError> {
    use crate::emu::device::sm_type;
    for i in 0..s.net.slave_count() {
        let Some(al) = s.net.al_state(i) else {
            continue;
        };
        if al & 0x0F >= 4 {
            continue;
        }
        let sms = s
            .net
            .sii_image(i)
            .map(crate::emu::device::sync_managers_of)
            .unwrap_or_default();
        for (n, sm) in sms.iter().enumerate() {
            let mut reg = [0u8; 8];
            reg[..2].copy_from_slice(&sm.start.to_le_bytes());
            reg[2..4].copy_from_slice(&sm.len.to_le_bytes());
            reg[4] = sm.control;
            reg[6] = 0x01;
            apwr(s, i, 0x0800 + 8 * n as u16, &reg)?;
        }
        let pd = sms
            .iter()
            .filter(|sm| matches!(sm.typ, sm_type::PD_OUT | sm_type::PD_IN) && sm.len > 0);
        let mut log = 256 * i as u32;
        for (f, sm) in pd.enumerate() {
            let mut reg = [0u8; 16];
            reg[..4].copy_from_slice(&log.to_le_bytes());
            reg[4..6].copy_from_slice(&sm.len.to_le_bytes());
            reg[7] = 7;
            reg[8..10].copy_from_slice(&sm.start.to_le_bytes());
            reg[11] = if sm.typ == sm_type::PD_OUT {
                0x02
            } else {
                0x01
            };
            reg[12] = 0x01;
            apwr(s, i, 0x0600 + 16 * f as u16, &reg)?;
            log += u32::from(sm.len);
        }
        for state in [0x02u16, 0x04, 0x08] {
            apwr(s, i, 0x0120, &state.to_le_bytes())?;
        }
    }
    Ok(())
}

fn slaves_in_op(s: &Sim<N>) -> u64 {
    (0..s.net.slave_count())
        .filter(|&i| s.net.al_state(i).is_some_and(|a| a & 0x0F == 8))
        .count() as u64
}

/// Worst |skew| per chunk, keyed by chunk start.
struct Chunks {
    matcher: PulseMatcher,
    reference: usize,
    worst: BTreeMap<u64, u64>,
    /// Chunks in which the machine was not locked at some slice end.
    unlocked: std::collections::BTreeSet<u64>,
}

impl Chunks {
    fn drain(&mut self, net: &mut Network, locked: bool) {
        if !locked {
            let c = net.now() / CHUNK_NS * CHUNK_NS;
            self.unlocked.insert(c);
            self.unlocked.insert(c.saturating_sub(CHUNK_NS));
        }
        let edges = net.take_sync_edges();
        let reference = self.reference;
        let worst = &mut self.worst;
        for e in edges.iter().filter(|e| e.signal == SyncSignal::Sync0) {
            self.matcher
                .push(reference, e.slave, e.system_time, e.true_time, &mut |p| {
                    let c = p.reference_time / CHUNK_NS * CHUNK_NS;
                    let w = worst.entry(c).or_insert(0);
                    *w = (*w).max(p.skew_ns.unsigned_abs());
                });
        }
    }
}

fn percentile(sorted: &[f64], p: f64) -> Option<f64> {
    if sorted.is_empty() {
        return None;
    }
    let k = ((p * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len());
    sorted.get(k - 1).copied()
}

/// Runs a soak.
pub fn soak(
    topology: Topology,
    seconds: f64,
    seed: u64,
    stay_init: bool,
) -> anyhow::Result<SoakReport> {
    let until = (seconds * 1e9) as u64;
    let (mut sc, cfg) = setup(topology, seed);
    let n = sc.resolve().map_err(|e| anyhow::anyhow!("{e}"))?.len();
    // ecdc choice: the first fault no earlier than 5 s, after the first lock (< 2 s).
    let plan = schedule(seed, n, 5_000_000_000, until);
    for p in &plan {
        sc.faults.extend(p.faults.iter().cloned());
    }
    let net = Network::new(&sc).map_err(|e| anyhow::anyhow!("emulator: {e}"))?;
    let narrow = wide_slaves(&net).iter().any(|w| !w);
    let mut s =
        Sim::<N>::configured(cfg, net).map_err(|e| anyhow::anyhow!("machine config: {e:?}"))?;
    s.start();
    let mut chunks = Chunks {
        matcher: PulseMatcher::new(narrow),
        reference: 0,
        worst: BTreeMap::new(),
        unlocked: Default::default(),
    };
    let mut restarts_by_driver = 0u64;
    let mut seen_events = 0usize;
    let mut last_locked = false;
    // Runs to `t` in 10 ms slices; after every slice drains SYNC edges, and after every new
    // lock takes the slaves to OP. A failed machine is restarted (counted).
    let mut advance = |s: &mut Sim<N>, chunks: &mut Chunks, t: u64| -> anyhow::Result<()> {
        while s.now() < t {
            let to = (s.now() + CHUNK_NS).min(t);
            s.run_until(to).map_err(|e| anyhow::anyhow!("sim: {e}"))?;
            let locked = s.machine.is_locked();
            chunks.drain(&mut s.net, locked);
            if locked && !last_locked && !stay_init {
                to_op(s).map_err(|e| anyhow::anyhow!("sim: {e}"))?;
            }
            last_locked = locked;
            if matches!(s.machine.state(), State::Failed | State::Idle) {
                restarts_by_driver += 1;
                s.machine.reset();
                s.start();
            }
            if s.now() < to {
                // Nothing scheduled: let time pass.
                s.net
                    .advance_to(to)
                    .map_err(|e| anyhow::anyhow!("emulator: {e}"))?;
                break;
            }
        }
        Ok(())
    };
    let mut judged = Vec::new();
    let mut outside: Vec<u64> = Vec::new();
    let mut unpaired_outside = 0u64;
    let mut unlocked_outside = 0u64;
    let mut op = (0u64, 0u64);
    // Quiet segments outside fault windows: [from, to).
    let mut quiet_from = 2_000_000_000u64;
    let mut collect = |chunks: &mut Chunks, from: u64, to: u64, outside: &mut Vec<u64>| {
        let mut c = from.div_ceil(CHUNK_NS) * CHUNK_NS;
        while c + CHUNK_NS <= to {
            if chunks.unlocked.contains(&c) {
                unlocked_outside += 1;
                c += CHUNK_NS;
                continue;
            }
            match chunks.worst.get(&c) {
                Some(&w) => outside.push(w),
                None => unpaired_outside += 1,
            }
            c += CHUNK_NS;
        }
        let keep = chunks.worst.split_off(&to.saturating_sub(CHUNK_NS));
        chunks.worst = keep;
        let keep = chunks.unlocked.split_off(&to.saturating_sub(CHUNK_NS));
        chunks.unlocked = keep;
    };
    for p in &plan {
        advance(&mut s, &mut chunks, p.at_ns)?;
        collect(&mut chunks, quiet_from, p.at_ns, &mut outside);
        op.0 += slaves_in_op(&s);
        op.1 += n as u64;
        seen_events = seen_events.max(s.events().len());
        let first = seen_events;
        let deadline = p.end_ns + RECOVERY_BOUND_NS;
        advance(&mut s, &mut chunks, deadline)?;
        let evs = s.events().get(first..).unwrap_or(&[]);
        let mut errors = Vec::new();
        let mut lost_at: Option<u64> = None;
        let mut locked_at: Option<u64> = None;
        let mut hold_start = false;
        let mut hold_end: Option<u64> = None;
        for &(t, e) in evs {
            match e {
                Event::Error(err) => errors.push(format!("{err:?}")),
                Event::LockLost { .. } | Event::Restarting => {
                    lost_at = Some(t);
                    locked_at = None;
                }
                Event::Locked { .. } => locked_at = Some(t),
                Event::HoldoverStarted { .. } => hold_start = true,
                Event::HoldoverEnded { .. } => hold_end = Some(t),
                _ => {}
            }
        }
        let after = |t: u64| t.saturating_sub(p.end_ns) as f64 / 1e6;
        let (outcome, rec, recovered) = if lost_at.is_some() {
            match locked_at {
                Some(t) if s.machine.is_locked() => (Outcome::Relock, Some(after(t)), t),
                _ if !errors.is_empty() => (Outcome::TypedError, None, deadline),
                _ => (Outcome::Violation, None, deadline),
            }
        } else if hold_start {
            match hold_end {
                Some(t) if s.machine.is_locked() => (Outcome::Holdover, Some(after(t)), t),
                _ if !errors.is_empty() => (Outcome::TypedError, None, deadline),
                _ => (Outcome::Violation, None, deadline),
            }
        } else if s.machine.is_locked() {
            (Outcome::Unaffected, None, p.end_ns)
        } else if !errors.is_empty() {
            (Outcome::TypedError, None, deadline)
        } else {
            (Outcome::Violation, None, deadline)
        };
        seen_events = s.events().len();
        quiet_from = recovered.max(p.end_ns) + SETTLE_NS;
        if matches!(outcome, Outcome::Violation | Outcome::TypedError) {
            quiet_from = deadline;
        }
        judged.push(Judged {
            fault: p.clone(),
            outcome,
            recovery_ms: rec,
            errors,
        });
    }
    advance(&mut s, &mut chunks, until)?;
    collect(&mut chunks, quiet_from, until, &mut outside);

    let mut per_kind: BTreeMap<&'static str, KindSummary> = BTreeMap::new();
    let mut rec: BTreeMap<&'static str, Vec<f64>> = BTreeMap::new();
    for j in &judged {
        let k = per_kind.entry(j.fault.kind).or_default();
        k.count += 1;
        match j.outcome {
            Outcome::Unaffected => k.unaffected += 1,
            Outcome::Holdover => k.holdover += 1,
            Outcome::Relock => k.relock += 1,
            Outcome::TypedError => k.typed_error += 1,
            Outcome::Violation => k.violation += 1,
        }
        k.errors += j.errors.len() as u64;
        if let Some(r) = j.recovery_ms {
            rec.entry(j.fault.kind).or_default().push(r);
        }
    }
    for (kind, mut v) in rec {
        v.sort_by(f64::total_cmp);
        if let Some(k) = per_kind.get_mut(kind) {
            k.recovery_ms_p50 = percentile(&v, 0.5);
            k.recovery_ms_p90 = percentile(&v, 0.9);
            k.recovery_ms_max = v.last().copied();
        }
    }
    outside.sort_unstable();
    let p99 = crate::emu::yardstick::percentile(&outside, 0.99);
    let offset_writes = (0..s.net.slave_count())
        .filter_map(|i| s.net.esc(i).map(|e| e.offset_writes_running()))
        .sum();
    Ok(SoakReport {
        topology,
        seed,
        simulated_s: seconds,
        slaves: n,
        faults: judged.len(),
        violations: judged
            .iter()
            .filter(|j| j.outcome == Outcome::Violation)
            .count() as u64,
        per_kind,
        offset_writes_in_safeop_op: offset_writes,
        op_at_fault_start: op,
        skew_outside_max_ns: outside.last().copied(),
        skew_outside_p99_ns: p99,
        skew_outside_chunks: outside.len() as u64,
        unpaired_outside_chunks: unpaired_outside,
        unlocked_outside_chunks: unlocked_outside,
        frames_sent: s.stats().sent,
        restarts_by_driver,
        judged,
    })
}

/// Runs `ecdc soak`.
pub fn run(args: &Args) -> anyhow::Result<()> {
    let wall = std::time::Instant::now();
    let r = soak(args.topology, args.seconds, args.seed, args.stay_init)?;
    let wall_s = wall.elapsed().as_secs_f64();
    if args.json {
        #[derive(Serialize)]
        struct Out<'a> {
            #[serde(flatten)]
            r: &'a SoakReport,
            wall_s: f64,
        }
        println!("{}", serde_json::to_string_pretty(&Out { r: &r, wall_s })?);
    } else {
        print!("{}", markdown(&r, wall_s));
    }
    if r.violations > 0 || r.offset_writes_in_safeop_op > 0 {
        anyhow::bail!(
            "soak: {} violations, {} offset writes in SAFEOP/OP",
            r.violations,
            r.offset_writes_in_safeop_op
        );
    }
    Ok(())
}

/// The report as a Markdown section (what benches/results/soak.md holds).
pub fn markdown(r: &SoakReport, wall_s: f64) -> String {
    use std::fmt::Write;
    let f = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.1}"));
    let mut o = String::new();
    let _ = writeln!(
        o,
        "### {:?}, seed {}: {} s simulated in {wall_s:.1} s wall ({} slaves)\n",
        r.topology, r.seed, r.simulated_s, r.slaves
    );
    let _ = writeln!(
        o,
        "| kind | faults | unaffected | hold-over | re-lock | typed error | violation | errors reported | recovery p50 / p90 / max (ms after the window) |"
    );
    let _ = writeln!(o, "|---|---|---|---|---|---|---|---|---|");
    for (k, s) in &r.per_kind {
        let _ = writeln!(
            o,
            "| {k} | {} | {} | {} | {} | {} | {} | {} | {} / {} / {} |",
            s.count,
            s.unaffected,
            s.holdover,
            s.relock,
            s.typed_error,
            s.violation,
            s.errors,
            f(s.recovery_ms_p50),
            f(s.recovery_ms_p90),
            f(s.recovery_ms_max)
        );
    }
    let _ = writeln!(
        o,
        "\nFaults {}, violations {}; offset writes to slaves in SAFEOP/OP {}; slaves in OP at \
         fault starts {} of {}; machine restarts by the driver after Failed {}; frames sent {}.",
        r.faults,
        r.violations,
        r.offset_writes_in_safeop_op,
        r.op_at_fault_start.0,
        r.op_at_fault_start.1,
        r.restarts_by_driver,
        r.frames_sent
    );
    let _ = writeln!(
        o,
        "Skew outside fault windows (true time, SYNC0 edges): worst {} ns, p99 of 10 ms maxima {} \
         ns over {} locked chunks; {} chunks without a paired pulse, {} with the machine \
         not locked.",
        r.skew_outside_max_ns.map_or("-".into(), |v| v.to_string()),
        r.skew_outside_p99_ns.map_or("-".into(), |v| v.to_string()),
        r.skew_outside_chunks,
        r.unpaired_outside_chunks,
        r.unlocked_outside_chunks
    );
    o
}
