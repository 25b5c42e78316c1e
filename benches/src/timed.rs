//! A bring-up driver that also measures the core's own CPU time.
//!
//! Same loop as `ecdc_harness::sim::Sim::step` (deliver every arrived frame, `handle_timeout`,
//! `poll_transmit` until it returns `None` — at most 64 frames per instant — and send each
//! through the emulator, drain `poll_event`, advance to the earliest arrival or
//! `poll_timeout`), with the master clock ideal (master = epoch + true time). Every call into
//! the machine is timed, so a bring-up reports the core's share separately from the
//! emulator's. The `scale` binary checks that it reaches lock after the same number of frames
//! as `Sim` on the same scenario.

use std::time::{Duration, Instant};

use ecdc_core::dc::{Event, Machine};
use ecdc_core::time::SystemTime;
use ecdc_harness::emu::{Delivery, Network, Scenario};
use ecdc_harness::sim::DEFAULT_MASTER_EPOCH_NS;

/// Result of a timed bring-up.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimedBringUp {
    /// Frames from `start` to `Locked` (`Stats::lock_frames`).
    pub lock_frames: u64,
    /// Simulated (true) time from `start` to the `Locked` event, ns.
    pub lock_true_ns: u64,
    /// Wall time of the whole bring-up (emulator + machine).
    pub wall: Duration,
    /// Wall time spent inside the machine's methods.
    pub core: Duration,
    /// Calls into the machine.
    pub calls: u64,
    /// At the first entry into `DriftBurst` (discovery, delays and offsets done): frames sent
    /// since `start`, simulated ns, core CPU time.
    pub to_drift: Option<(u64, u64, Duration)>,
    /// Re-initialisations after a fault (`Stats::restarts`).
    pub restarts: u64,
    /// The first error event, if any.
    pub first_error: Option<ecdc_core::dc::Error>,
    /// Frames the machine sent (`Stats::frames_sent` since `start`).
    pub frames_sent: u64,
}

/// Why a bring-up did not lock.
#[derive(Debug, Clone)]
pub struct NoLock {
    /// Simulated time reached, ns.
    pub at_ns: u64,
    /// Machine state then.
    pub state: ecdc_core::dc::State,
    /// Frames sent.
    pub frames: u64,
    /// Restarts.
    pub restarts: u64,
    /// First error event.
    pub first_error: Option<ecdc_core::dc::Error>,
    /// As in [`TimedBringUp::to_drift`].
    pub to_drift: Option<(u64, u64, Duration)>,
    /// Wall time spent.
    pub wall: Duration,
    /// Core CPU time spent.
    pub core: Duration,
}

impl core::fmt::Display for NoLock {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "no lock within {:.0} s simulated (state {}, {} frames, {} restarts, first error {:?})",
            self.at_ns as f64 / 1e9,
            self.state,
            self.frames,
            self.restarts,
            self.first_error
        )
    }
}

struct InFlight {
    arrival: u64,
    frame: Vec<u8>,
}

/// One call into the machine, as the driver made it (time = master clock, ns).
#[derive(Debug, Clone)]
pub enum Call {
    /// `start`.
    Start(u64),
    /// `handle_frame` with these bytes.
    Frame(u64, Vec<u8>),
    /// `handle_timeout`.
    Timeout(u64),
    /// `poll_transmit` (returned a frame or not).
    Transmit(u64),
    /// `poll_event`.
    Event,
    /// `poll_timeout`.
    PollTimeout,
    /// Marker: the machine entered `DriftBurst` here (no call).
    DriftMark,
}

/// Every call of a bring-up, to replay it on a copy of the machine without the emulator.
#[derive(Debug, Clone, Default)]
pub struct CallLog {
    /// The calls in order.
    pub calls: Vec<Call>,
}

/// CPU time of this thread, ns (insensitive to other processes sharing the machine), through
/// the `cpu-time` crate (`CLOCK_THREAD_CPUTIME_ID`); 0 where the clock is missing. Every bench
/// and benchmark binary times with this one function.
pub fn thread_cpu_ns() -> u64 {
    cpu_time::ThreadTime::try_now()
        .map(|t| u64::try_from(t.as_duration().as_nanos()).unwrap_or(u64::MAX))
        .unwrap_or(0)
}

/// Replays `log` on `machine` (a copy of the machine the log was recorded with, before its
/// `start`): the core's whole work of that bring-up with no emulator. Returns the thread CPU
/// time up to the `DriftMark` (if any) and in total, ns, and the frames the machine sent.
pub fn replay<const N: usize>(mut machine: Machine<N>, log: &CallLog) -> (Option<u64>, u64, u64) {
    replay_in(&mut machine, log)
}

/// [`replay`] on a machine that lives on the heap (the `stack` binary measures the core's own
/// stack use this way: no `Machine` value on the replaying thread's stack).
pub fn replay_boxed<const N: usize>(
    mut machine: Box<Machine<N>>,
    log: &CallLog,
) -> (Option<u64>, u64, u64) {
    replay_in(&mut machine, log)
}

fn replay_in<const N: usize>(machine: &mut Machine<N>, log: &CallLog) -> (Option<u64>, u64, u64) {
    let mut buf = vec![0u8; 1514];
    let mut mark = None;
    let t0 = thread_cpu_ns();
    for c in &log.calls {
        match c {
            Call::Start(t) => machine.start(SystemTime(*t)),
            Call::Frame(t, f) => machine.handle_frame(SystemTime(*t), f),
            Call::Timeout(t) => machine.handle_timeout(SystemTime(*t)),
            Call::Transmit(t) => {
                std::hint::black_box(machine.poll_transmit(SystemTime(*t), &mut buf));
            }
            Call::Event => {
                std::hint::black_box(machine.poll_event());
            }
            Call::PollTimeout => {
                std::hint::black_box(machine.poll_timeout());
            }
            Call::DriftMark => mark = Some(thread_cpu_ns().saturating_sub(t0)),
        }
    }
    let total = thread_cpu_ns().saturating_sub(t0);
    (mark, total, machine.stats().frames_sent)
}

fn master(t: u64) -> SystemTime {
    SystemTime(DEFAULT_MASTER_EPOCH_NS.saturating_add(t))
}

fn true_of(m: SystemTime) -> u64 {
    m.0.saturating_sub(DEFAULT_MASTER_EPOCH_NS)
}

/// Brings `machine` up on a fresh network for `sc`; gives up after `limit_ns` simulated.
/// Returns the machine and network (locked, at the lock instant) with the measurements.
pub fn bring_up<const N: usize>(
    sc: &Scenario,
    machine: Machine<N>,
    limit_ns: u64,
) -> anyhow::Result<(Machine<N>, Network, TimedBringUp)> {
    match try_bring_up(sc, machine, limit_ns, None)? {
        Ok(v) => Ok(v),
        Err(e) => anyhow::bail!("{e}"),
    }
}

/// [`bring_up`], reporting a bring-up that does not lock within `limit_ns` as `Ok(Err(_))`
/// (errors of the emulator or the scenario are `Err`), and recording every call into `log`.
#[allow(clippy::type_complexity)]
pub fn try_bring_up<const N: usize>(
    sc: &Scenario,
    mut machine: Machine<N>,
    limit_ns: u64,
    mut log: Option<&mut CallLog>,
) -> anyhow::Result<Result<(Machine<N>, Network, TimedBringUp), NoLock>> {
    let mut rec = |c: Call| {
        if let Some(l) = log.as_deref_mut() {
            l.calls.push(c);
        }
    };
    let mut net = Network::new(sc).map_err(|e| anyhow::anyhow!("scenario: {e:?}"))?;
    let mut buf = vec![0u8; 1514];
    let mut flight: Vec<InFlight> = Vec::new();
    let mut core = Duration::ZERO;
    let mut calls = 0u64;
    let wall0 = Instant::now();
    let mut now = net.now();
    let t = Instant::now();
    machine.start(master(now));
    core += t.elapsed();
    rec(Call::Start(master(now).0));
    let frames0 = machine.stats().frames_sent;
    let mut to_drift = None;
    let mut first_error = None;
    loop {
        if to_drift.is_none() && machine.state() == ecdc_core::dc::State::DriftBurst {
            rec(Call::DriftMark);
            to_drift = Some((
                machine.stats().frames_sent.saturating_sub(frames0),
                now,
                core,
            ));
        }
        if now > limit_ns {
            return Ok(Err(NoLock {
                at_ns: now,
                state: machine.state(),
                frames: machine.stats().frames_sent.saturating_sub(frames0),
                restarts: machine.stats().restarts,
                first_error,
                to_drift,
                wall: wall0.elapsed(),
                core,
            }));
        }
        // 1. Deliver arrivals in arrival order.
        flight.sort_by_key(|f| f.arrival);
        while flight.first().is_some_and(|f| f.arrival <= now) {
            let f = flight.remove(0);
            let t = Instant::now();
            machine.handle_frame(master(f.arrival), &f.frame);
            core += t.elapsed();
            calls += 1;
            rec(Call::Frame(master(f.arrival).0, f.frame));
        }
        // 2. Timeouts, then everything the machine sends now.
        let t = Instant::now();
        machine.handle_timeout(master(now));
        core += t.elapsed();
        calls += 1;
        rec(Call::Timeout(master(now).0));
        for _ in 0..64 {
            let t = Instant::now();
            let sent = machine.poll_transmit(master(now), &mut buf);
            core += t.elapsed();
            calls += 1;
            rec(Call::Transmit(master(now).0));
            let Some(n) = sent else { break };
            match net
                .transact(&buf[..n], now)
                .map_err(|e| anyhow::anyhow!("emu: {e:?}"))?
            {
                Delivery::Returned(r) => flight.push(InFlight {
                    arrival: r.arrival.max(now),
                    frame: r.frame,
                }),
                Delivery::Lost(_) => {}
            }
        }
        loop {
            let t = Instant::now();
            let ev = machine.poll_event();
            core += t.elapsed();
            calls += 1;
            rec(Call::Event);
            match ev {
                Some(Event::Locked { frames, .. }) => {
                    let restarts = machine.stats().restarts;
                    let frames_sent = machine.stats().frames_sent.saturating_sub(frames0);
                    return Ok(Ok((
                        machine,
                        net,
                        TimedBringUp {
                            lock_frames: frames,
                            lock_true_ns: now,
                            wall: wall0.elapsed(),
                            core,
                            calls,
                            to_drift,
                            restarts,
                            first_error,
                            frames_sent,
                        },
                    )));
                }
                Some(Event::Error(e)) => {
                    first_error.get_or_insert(e);
                }
                Some(_) => {}
                None => break,
            }
        }
        // 3. Next instant.
        let next_arrival = flight.iter().map(|f| f.arrival).min();
        let t = Instant::now();
        let next_timeout = machine.poll_timeout().map(true_of);
        core += t.elapsed();
        calls += 1;
        rec(Call::PollTimeout);
        let next = match (next_arrival, next_timeout) {
            (Some(a), Some(b)) => a.min(b),
            (Some(a), None) | (None, Some(a)) => a,
            (None, None) => anyhow::bail!("nothing scheduled in state {}", machine.state()),
        };
        now = next.max(now.saturating_add(u64::from(next <= now)));
    }
}
