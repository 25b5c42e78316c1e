//! Deterministic simulation driver: a DC [`Machine`] and the emulated chain ([`Network`]) under
//! simulated time (quinn-proto's `Pair`, adapted).
//!
//! One clock drives everything: true time (`TrueTime`, ns since the start of the run). The
//! master's own clock, which the machine receives as `now`, is `master_epoch + true time · (1 +
//! master_ppm)` in the DC epoch; nothing reads the wall clock and every random stream is seeded
//! by the scenario, so a run is reproducible bit for bit.
//!
//! [`Sim::step`] does one thing at one instant: deliver every frame that has arrived, let the
//! machine handle its timeouts and send everything it wants (each frame goes through
//! [`Network::transact`] at the current time and comes back at its arrival time, or is lost),
//! collect events, and then advance time to the next instant something happens (the earliest
//! arrival or the machine's `poll_timeout`). [`Sim::drive_until`] loops until a predicate on
//! the events holds or a true-time limit passes; [`Sim::drive_bounded`] gives up after a number
//! of steps (livelock guard).

use ecdc_core::dc::{Config, ConfigError, Event, Machine, State};
use ecdc_core::time::SystemTime;

use crate::emu::{Delivery, EmuError, Network, TrueTime};

/// Master clock at true time 0: 2026-01-01 in the DC epoch (26 years after 2000-01-01, with
/// 7 leap days), so system times look like real ones.
pub const DEFAULT_MASTER_EPOCH_NS: u64 = (26 * 365 + 7) * 86_400 * 1_000_000_000;

/// Why a drive stopped without reaching its goal.
#[derive(Debug, Clone, PartialEq)]
pub enum SimError {
    /// The emulator refused a call (a bug in the driver or the scenario).
    Emu(EmuError),
    /// The true-time limit passed.
    TimeLimit {
        /// True time reached.
        at: TrueTime,
        /// Machine state then.
        state: State,
    },
    /// The step limit passed (livelock guard).
    StepLimit {
        /// Steps done.
        steps: u64,
        /// Machine state then.
        state: State,
    },
    /// Nothing is scheduled any more (machine idle or failed, no frame in flight).
    Idle {
        /// Machine state then.
        state: State,
    },
}

impl From<EmuError> for SimError {
    fn from(e: EmuError) -> Self {
        SimError::Emu(e)
    }
}

impl core::fmt::Display for SimError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            SimError::Emu(e) => write!(f, "emulator: {e:?}"),
            SimError::TimeLimit { at, state } => {
                write!(f, "time limit at {at} ns in state {state}")
            }
            SimError::StepLimit { steps, state } => {
                write!(f, "step limit after {steps} steps in state {state}")
            }
            SimError::Idle { state } => write!(f, "nothing scheduled in state {state}"),
        }
    }
}

impl std::error::Error for SimError {}

/// Frame counters of a run.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SimStats {
    /// Frames the machine sent.
    pub sent: u64,
    /// Frames that came back.
    pub returned: u64,
    /// Frames lost in the network.
    pub lost: u64,
    /// Steps taken.
    pub steps: u64,
}

/// A frame on its way back to the master.
#[derive(Debug, Clone)]
struct InFlight {
    arrival: TrueTime,
    frame: Vec<u8>,
}

/// The machine (capacity `N`) coupled to an emulated network.
pub struct Sim<const N: usize> {
    /// The state machine under test, on the heap: a `Machine<1024>` is about 460 KiB, and an
    /// unoptimised build copies a value that size several times on its way into a struct.
    pub machine: Box<Machine<N>>,
    /// The emulated chain (observable in true time).
    pub net: Network,
    now: TrueTime,
    master_epoch: u64,
    master_ppb: i64,
    flight: Vec<InFlight>,
    events: Vec<(TrueTime, Event)>,
    buf: Vec<u8>,
    stats: SimStats,
}

impl<const N: usize> Sim<N> {
    /// Couples `machine` (a `Machine` or a `Box` of one) and `net` at true time `net.now()`
    /// with an ideal master clock.
    pub fn new(machine: impl Into<Box<Machine<N>>>, net: Network) -> Self {
        let now = net.now();
        Sim {
            machine: machine.into(),
            net,
            now,
            master_epoch: DEFAULT_MASTER_EPOCH_NS,
            master_ppb: 0,
            flight: Vec::new(),
            events: Vec::new(),
            buf: vec![0u8; 1514],
            stats: SimStats::default(),
        }
    }

    /// A machine configured with `cfg`, built in place on the heap (`Machine::idle` then
    /// `configure`), coupled to `net`: no machine-sized value passes over the stack, whatever
    /// `N`.
    pub fn configured(cfg: Config, net: Network) -> Result<Self, ConfigError> {
        let mut machine = Box::new(Machine::<N>::idle());
        machine.configure(cfg)?;
        Ok(Sim::new(machine, net))
    }

    /// Sets the master clock's rate error in ppb (positive = master clock fast).
    pub fn with_master_ppb(mut self, ppb: i64) -> Self {
        self.master_ppb = ppb;
        self
    }

    /// Current true time.
    pub fn now(&self) -> TrueTime {
        self.now
    }

    /// Sets what the master's clock reads at true time 0 (default
    /// [`DEFAULT_MASTER_EPOCH_NS`]).
    pub fn with_master_epoch(mut self, ns: u64) -> Self {
        self.master_epoch = ns;
        self
    }

    /// The master's clock (DC epoch) at true time `t`.
    pub fn master_time_at(&self, t: TrueTime) -> SystemTime {
        let drift = i128::from(t) * i128::from(self.master_ppb) / 1_000_000_000;
        let ns = i128::from(self.master_epoch) + i128::from(t) + drift;
        SystemTime(u64::try_from(ns.max(0)).unwrap_or(u64::MAX))
    }

    /// True time at which the master's clock reads `m` (inverse of `master_time_at`, rounded up).
    fn true_time_of(&self, m: SystemTime) -> TrueTime {
        let d = i128::from(m.as_nanos()) - i128::from(self.master_epoch);
        let scale = 1_000_000_000i128 + i128::from(self.master_ppb);
        let t = (d * 1_000_000_000 + scale - 1).div_euclid(scale.max(1));
        u64::try_from(t.max(0)).unwrap_or(u64::MAX)
    }

    /// Every event so far with the true time it was polled at.
    pub fn events(&self) -> &[(TrueTime, Event)] {
        &self.events
    }

    /// Frame counters.
    pub fn stats(&self) -> SimStats {
        self.stats
    }

    /// Starts the machine's bring-up now.
    pub fn start(&mut self) {
        let m = self.master_time_at(self.now);
        self.machine.start(m);
    }

    /// Delivers arrivals, lets the machine send, then advances time to the next instant
    /// something is scheduled. Returns `Ok(false)` when nothing is scheduled any more.
    pub fn step(&mut self) -> Result<bool, SimError> {
        self.stats.steps += 1;
        // A stalled master does nothing until the stall ends; replies wait for it.
        if let Some(end) = self.net.master_stalled(self.now) {
            self.now = end;
            return Ok(true);
        }
        let now = self.now;
        let m_now = self.master_time_at(now);
        // 1. Deliver every frame that has arrived, in arrival order.
        self.flight.sort_by_key(|f| f.arrival);
        while self.flight.first().is_some_and(|f| f.arrival <= now) {
            let f = self.flight.remove(0);
            let at = self.master_time_at(f.arrival);
            self.machine.handle_frame(at, &f.frame);
        }
        // 2. Timeouts, then everything the machine wants to send now.
        self.machine.handle_timeout(m_now);
        for _ in 0..64 {
            let Some(n) = self.machine.poll_transmit(m_now, &mut self.buf) else {
                break;
            };
            self.stats.sent += 1;
            let frame = self.buf[..n].to_vec();
            match self.net.transact(&frame, now)? {
                Delivery::Returned(r) => {
                    self.stats.returned += 1;
                    self.flight.push(InFlight {
                        arrival: r.arrival.max(now),
                        frame: r.frame,
                    });
                }
                Delivery::Lost(_) => self.stats.lost += 1,
            }
        }
        while let Some(e) = self.machine.poll_event() {
            self.events.push((now, e));
        }
        // 3. Advance to the next instant.
        let next_arrival = self.flight.iter().map(|f| f.arrival).min();
        let next_timeout = self.machine.poll_timeout().map(|t| self.true_time_of(t));
        let next = match (next_arrival, next_timeout) {
            (Some(a), Some(b)) => a.min(b),
            (Some(a), None) | (None, Some(a)) => a,
            (None, None) => return Ok(false),
        };
        // Never stand still: a deadline "now" that produced nothing moves on by 1 ns.
        self.now = next.max(now.saturating_add(u64::from(next <= now)));
        Ok(true)
    }

    /// Steps until `goal` returns true for a newly polled event, or true time passes `limit`.
    /// Returns the event that satisfied the goal.
    pub fn drive_until(
        &mut self,
        limit: TrueTime,
        mut goal: impl FnMut(&Event) -> bool,
    ) -> Result<Event, SimError> {
        let mut seen = self.events.len();
        loop {
            if self.now > limit {
                return Err(SimError::TimeLimit {
                    at: self.now,
                    state: self.machine.state(),
                });
            }
            let more = self.step()?;
            while seen < self.events.len() {
                let e = self.events[seen].1;
                seen += 1;
                if goal(&e) {
                    return Ok(e);
                }
            }
            if !more {
                return Err(SimError::Idle {
                    state: self.machine.state(),
                });
            }
        }
    }

    /// Steps until true time reaches `t` (or nothing is scheduled).
    pub fn run_until(&mut self, t: TrueTime) -> Result<(), SimError> {
        while self.now < t {
            if !self.step()? {
                break;
            }
        }
        Ok(())
    }

    /// At most `max_steps` steps until the machine is in `Cyclic` and locked.
    pub fn drive_bounded(&mut self, max_steps: u64) -> Result<(), SimError> {
        for _ in 0..max_steps {
            if self.machine.is_locked() {
                return Ok(());
            }
            if !self.step()? {
                return Err(SimError::Idle {
                    state: self.machine.state(),
                });
            }
        }
        Err(SimError::StepLimit {
            steps: max_steps,
            state: self.machine.state(),
        })
    }

    /// Sends one frame of the test's own (e.g. an AL control write) at the current time and
    /// returns the reply, bypassing the machine. For setting up scenarios.
    pub fn side_channel(&mut self, frame: &[u8]) -> Result<Option<Vec<u8>>, SimError> {
        Ok(self
            .net
            .transact(frame, self.now)?
            .returned()
            .map(|r| r.frame))
    }

    /// Greatest |system time of slave i − system time of the reference| over the given
    /// `(slave, is_64_bit)` pairs at the current true time (ns), from the emulator's true-time
    /// observers; `None` if the reference has no system time. Whenever the reference or the
    /// slave is a 32-bit DC, only the low 32 bits are compared (that is all a 32-bit slave keeps).
    pub fn true_sync_error(
        &mut self,
        reference: (usize, bool),
        slaves: &[(usize, bool)],
    ) -> Result<Option<i64>, SimError> {
        let t = self.now;
        let Some(r) = self.net.clock(reference.0, t)?.system_time else {
            return Ok(None);
        };
        let mut worst = 0i64;
        for &(i, is64) in slaves {
            if let Some(s) = self.net.clock(i, t)?.system_time {
                let d = if is64 && reference.1 {
                    s.wrapping_sub(r) as i64
                } else {
                    i64::from(s.wrapping_sub(r) as u32 as i32)
                };
                worst = worst.max(d.abs());
            }
        }
        Ok(Some(worst))
    }
}
