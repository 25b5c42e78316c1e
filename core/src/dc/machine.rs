//! [`Machine`]: the sans-IO DC bring-up and cyclic state machine.

use crate::dc::config::{Config, ConfigError};
use crate::dc::error::Error;
use crate::dc::event::{Event, EventQueue};
use crate::dc::line::Line;
use crate::dc::measure::LatchRounds;
use crate::dc::phase::Phase;
use crate::dc::request::{Inflight, Op, Pending, Reply, Tag};
use crate::dc::scratch::Scratch;
use crate::dc::shared::{Restarts, Shared, StepProgress};
use crate::dc::slave::SlaveInfo;
use crate::dc::state::State;
use crate::dc::tdiff::Tdiff;
use crate::dc::timer::{earliest, Timer, TimerTable};
use crate::time::SystemTime;
use crate::wire::{EthernetFrame, FrameBuilder};

/// Counters for diagnostics. Every field only grows (saturating), except `lock_frames`.
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::{Config, Machine};
/// use ecdc_core::time::SystemTime;
///
/// let mut dc = Machine::<8>::new(Config::default())?;
/// let now = SystemTime::from_nanos(1_000_000_000);
/// dc.start(now);
/// let mut frame = [0u8; 1514];
/// assert!(dc.poll_transmit(now, &mut frame).is_some());
/// dc.handle_frame(now, b"not an EtherCAT frame");
/// let s = dc.stats();
/// assert_eq!(
///     (s.frames_sent, s.frames_received, s.foreign_frames),
///     (1, 1, 1)
/// );
/// # Ok::<(), ecdc_core::dc::ConfigError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct Stats {
    /// Transmissions (own frames, or appends into a caller's frame).
    pub frames_sent: u64,
    /// Frames handed to `handle_frame`.
    pub frames_received: u64,
    /// Frames with none of our datagrams (malformed, not EtherCAT, not processed by a slave,
    /// or only someone else's datagrams).
    pub foreign_frames: u64,
    /// Datagrams in received frames that matched nothing in flight.
    pub foreign_datagrams: u64,
    /// Response timeouts.
    pub timeouts: u64,
    /// Resent request chunks.
    pub retries: u64,
    /// Re-initialisations after a fault.
    pub restarts: u64,
    /// Hold-overs that ended with a passed resume check (REQ-DC-127).
    pub holdovers: u64,
    /// Cyclic transmissions.
    pub cycles: u64,
    /// Cycles whose DC datagrams did not come back.
    pub lost_cycles: u64,
    /// Events dropped because the queue was full.
    pub events_dropped: u64,
    /// Frames from the last `start`/re-initialisation to the last `Locked` event.
    pub lock_frames: Option<u64>,
}

impl Stats {
    /// All zero (the `Default`), usable in a `const` context.
    pub const ZERO: Stats = Stats {
        frames_sent: 0,
        frames_received: 0,
        foreign_frames: 0,
        foreign_datagrams: 0,
        timeouts: 0,
        retries: 0,
        restarts: 0,
        holdovers: 0,
        cycles: 0,
        lost_cycles: 0,
        events_dropped: 0,
        lock_frames: None,
    };
}

/// One item of a request step.
pub(crate) enum Item {
    /// Send this datagram.
    Send(Op),
    /// Nothing to send for this item (e.g. a non-DC slave).
    Skip,
}

/// The sans-IO DC state machine for up to `N` slaves.
///
/// Method families (as quinn-proto's `Connection`):
/// - commands: [`start`](Self::start), [`reset`](Self::reset),
///   [`request_delay_measurement`](Self::request_delay_measurement);
/// - input: [`handle_frame`](Self::handle_frame), [`handle_timeout`](Self::handle_timeout);
/// - output: [`poll_transmit`](Self::poll_transmit) / [`poll_transmit_into`](Self::poll_transmit_into),
///   [`poll_timeout`](Self::poll_timeout), [`poll_event`](Self::poll_event);
/// - getters: [`state`](Self::state), [`slaves`](Self::slaves), [`stats`](Self::stats), ….
///
/// Loop: feed every received frame to `handle_frame`; call `poll_transmit` until it returns
/// `None` and send what it wrote; drain `poll_event`; sleep until `poll_timeout` and call
/// `handle_timeout` (an early or extra call is a harmless no-op). `now` must not go backwards.
/// It is the master's clock in the DC epoch (REQ-CONV-002): the offsets make the slaves' system
/// time follow it.
///
/// No input (any bytes, any order, any timing) makes a method panic (REQ-CONV-008, property
/// P6), and only datagrams matched by index, command, register, station and length are used.
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::{Config, Error, Event, Machine, State};
/// use ecdc_core::time::SystemTime;
/// use ecdc_core::wire::MAC_PROCESSED_BIT;
///
/// let mut dc = Machine::<8>::new(Config::default())?;
/// let now = SystemTime::from_nanos(1_000_000_000);
/// dc.start(now);
/// // The first frame counts the slaves (BRD 0x0000): 60 bytes, EtherType 0x88A4.
/// let mut frame = [0u8; 1514];
/// let len = dc
///     .poll_transmit(now, &mut frame)
///     .expect("the slave count to send");
/// assert_eq!((len, &frame[12..14]), (60, &[0x88, 0xA4][..]));
/// // It comes back with working counter 0: nobody is there. The machine reports it and
/// // schedules a re-initialisation instead of failing for good.
/// frame[6] |= MAC_PROCESSED_BIT;
/// dc.handle_frame(now.wrapping_add(20_000), &frame[..len]);
/// assert_eq!(dc.poll_event(), Some(Event::Error(Error::NoSlaves)));
/// assert_eq!(dc.state(), State::RestartWait);
/// # Ok::<(), ecdc_core::dc::ConfigError>(())
/// ```
#[derive(Debug, Clone)]
pub struct Machine<const N: usize> {
    /// The phase and its own data (`dc/phase.rs`).
    pub(crate) phase: Phase,
    /// What every phase reads and uses (`Shared`).
    pub(crate) sh: Shared<N>,
}

impl<const N: usize> Machine<N> {
    /// A machine in `Idle`. Fails if the configuration is inconsistent.
    ///
    /// The machine is returned by value, so it passes over the caller's stack (about
    /// `size_of::<Machine<N>>()`, 460 bytes per slave). Where that does not fit (e.g.
    /// thousands of slaves on a small thread stack), put a [`Machine::idle`] in a `static`
    /// and [`configure`](Self::configure) it in place.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::{Config, ConfigError, Machine, State};
    ///
    /// let dc = Machine::<64>::new(Config::default())?;
    /// assert_eq!(dc.state(), State::Idle);
    /// // 64 slaves from station 0xFFF0 would run past 0xFFFF.
    /// let cfg = Config {
    ///     station_base: 0xFFF0,
    ///     ..Config::DEFAULT
    /// };
    /// assert_eq!(
    ///     Machine::<64>::new(cfg).err(),
    ///     Some(ConfigError::StationRange)
    /// );
    /// # Ok::<(), ConfigError>(())
    /// ```
    pub fn new(cfg: Config) -> Result<Self, ConfigError> {
        cfg.validate(N)?;
        Ok(Self::blank(cfg))
    }

    /// A machine in `Idle` with [`Config::DEFAULT`], built at compile time: the initial value
    /// of a `static` (or of any place that is never on the stack), to be given its
    /// configuration in place with [`configure`](Self::configure). No method ever puts a value
    /// of size `N` on the stack, so a machine obtained this way runs on a stack independent of
    /// `N`. Compiling it fails if `N` is too large for the default station addresses
    /// (`N` > 0xEFFF).
    ///
    /// ```
    /// use ecdc_core::dc::{Config, Machine, State};
    /// use std::sync::Mutex;
    ///
    /// // 1024 slaves: about 460 KiB, in the program's data, not on a stack.
    /// static MACHINE: Mutex<Machine<1024>> = Mutex::new(Machine::idle());
    ///
    /// let cfg = Config {
    ///     latch_rounds: 8,
    ///     ..Config::DEFAULT
    /// };
    /// let mut m = MACHINE.lock().unwrap();
    /// m.configure(cfg).unwrap();
    /// assert_eq!(m.config().latch_rounds, 8);
    /// assert_eq!(m.state(), State::Idle);
    /// ```
    pub const fn idle() -> Self {
        const { assert!(N <= 0x1_0000 - 0x1001, "N too large for Config::DEFAULT") };
        Self::blank(Config::DEFAULT)
    }

    /// Validates `cfg` and makes this machine what [`Machine::new(cfg)`](Self::new) returns,
    /// in place (nothing of size `N` on the stack): in `Idle`, with no slaves, counters,
    /// events, per-slave `t_Diff` overrides or kept `t_Diff` values. The one exception: a
    /// slave whose ports an interrupted `t_Diff` measurement may have left closed is still
    /// reopened first by the next [`start`](Self::start) (REQ-DC-124). On `Err` the machine is
    /// unchanged.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::{Config, ConfigError, Machine};
    ///
    /// let mut dc = Machine::<8>::new(Config::default())?;
    /// dc.configure(Config {
    ///     latch_rounds: 8,
    ///     ..Config::DEFAULT
    /// })?;
    /// assert_eq!(dc.config().latch_rounds, 8);
    /// // A refused configuration leaves the machine as it was.
    /// assert_eq!(
    ///     dc.configure(Config {
    ///         latch_rounds: 0,
    ///         ..Config::DEFAULT
    ///     }),
    ///     Err(ConfigError::Zero)
    /// );
    /// assert_eq!(dc.config().latch_rounds, 8);
    /// # Ok::<(), ConfigError>(())
    /// ```
    pub fn configure(&mut self, cfg: Config) -> Result<(), ConfigError> {
        cfg.validate(N)?;
        // Every field is named, so that a new one cannot be forgotten here.
        let Machine { phase, sh } = self;
        let Shared {
            cfg: c,
            line,
            inflight,
            timers,
            step,
            events,
            stats,
            last_sent,
            restarts,
            latch,
            tdiff,
            scratch,
        } = sh;
        *c = cfg;
        *phase = Phase::Idle;
        line.clear();
        *inflight = Inflight::new(cfg.index_first);
        *timers = TimerTable::new();
        *step = StepProgress::START;
        *events = EventQueue::new();
        *stats = Stats::ZERO;
        *last_sent = SystemTime::EPOCH;
        *restarts = Restarts::NONE;
        latch.clear();
        scratch.monitor.invalidate();
        tdiff.forget();
        // The working tables' other contents are overwritten before they are read.
        scratch.topo.clear();
        scratch.round.clear();
        Ok(())
    }

    /// The machine of [`new`](Self::new) and [`idle`](Self::idle), for a validated `cfg`.
    const fn blank(cfg: Config) -> Self {
        Machine {
            phase: Phase::Idle,
            sh: Shared {
                cfg,
                line: Line::new(),
                inflight: Inflight::new(cfg.index_first),
                timers: TimerTable::new(),
                step: StepProgress::START,
                events: EventQueue::new(),
                stats: Stats::ZERO,
                last_sent: SystemTime::EPOCH,
                restarts: Restarts::NONE,
                latch: LatchRounds::new(),
                tdiff: Tdiff::new(),
                scratch: Scratch::new(),
            },
        }
    }

    // ----- commands -------------------------------------------------------------------------

    /// Starts (or restarts) the bring-up from `CountSlaves`.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::{Config, Machine, State};
    /// use ecdc_core::time::SystemTime;
    ///
    /// let mut dc = Machine::<8>::new(Config::default())?;
    /// dc.start(SystemTime::from_nanos(1_000_000_000));
    /// assert_eq!(dc.state(), State::CountSlaves);
    /// # Ok::<(), ecdc_core::dc::ConfigError>(())
    /// ```
    pub fn start(&mut self, _now: SystemTime) {
        self.reset();
        self.sh.restarts.streak = 0;
        self.sh.restarts.frames_at_start = self.sh.stats.frames_sent;
        self.enter(State::CountSlaves);
    }

    /// Stops everything and returns to `Idle`; replies still in flight will be ignored.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::{Config, Machine, State};
    /// use ecdc_core::time::SystemTime;
    ///
    /// let mut dc = Machine::<8>::new(Config::default())?;
    /// let now = SystemTime::from_nanos(1_000_000_000);
    /// dc.start(now);
    /// let mut frame = [0u8; 1514];
    /// assert!(dc.poll_transmit(now, &mut frame).is_some());
    /// dc.reset(); // e.g. the application is shutting the bus down
    /// assert_eq!(
    ///     (dc.state(), dc.is_awaiting_reply(), dc.poll_timeout()),
    ///     (State::Idle, false, None)
    /// );
    /// # Ok::<(), ecdc_core::dc::ConfigError>(())
    /// ```
    pub fn reset(&mut self) {
        self.sh.stop_awaiting();
        self.enter(State::Idle);
    }

    /// Asks for a propagation-delay re-measurement during cyclic operation (ETG.1500
    /// "continuous propagation delay measurement"). It runs in spare room of the following
    /// cycles and rewrites only 0x0928 (REQ-DC-107). Ignored outside `Cyclic`.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::{Config, Machine, State};
    ///
    /// let mut dc = Machine::<8>::new(Config::default())?;
    /// // Outside `Cyclic` the request is ignored: nothing changes, nothing is sent.
    /// dc.request_delay_measurement();
    /// assert_eq!((dc.state(), dc.poll_timeout()), (State::Idle, None));
    /// # Ok::<(), ecdc_core::dc::ConfigError>(())
    /// ```
    pub fn request_delay_measurement(&mut self) {
        if let Some(c) = self.phase.cyclic_mut() {
            c.remeasure.requested = true;
        }
    }

    /// Sets `t_Diff = t_P − t_F` (ns, from the ESI or the ESC datasheet) of the slave at
    /// auto-increment `position` (0 = first slave), overriding [`Config::t_diff_ns`] for that
    /// slave at the next delay measurement (REQ-DC-015: seed 000 eq. 23 is the line case with
    /// one common value; mixed ESC types need one per slave). Returns the previous override.
    /// Fails with [`ConfigError::Capacity`] when `position` is beyond the capacity `N`.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::{Config, ConfigError, Machine};
    ///
    /// // Slave 2 is a different ESC with t_Diff = 40 ns; the others use `Config::t_diff_ns`.
    /// let mut dc = Machine::<8>::new(Config::default())?;
    /// assert_eq!(dc.set_slave_t_diff(2, Some(40))?, None);
    /// assert_eq!(dc.set_slave_t_diff(2, Some(45))?, Some(40));
    /// assert_eq!(dc.set_slave_t_diff(8, Some(40)), Err(ConfigError::Capacity));
    /// # Ok::<(), ConfigError>(())
    /// ```
    pub fn set_slave_t_diff(
        &mut self,
        position: u16,
        t_diff_ns: Option<i32>,
    ) -> Result<Option<i32>, ConfigError> {
        let slot = self
            .sh
            .line
            .t_diff
            .get_mut(usize::from(position))
            .ok_or(ConfigError::Capacity)?;
        Ok(core::mem::replace(slot, t_diff_ns))
    }

    /// The configured `t_Diff` of the slave at `position`: its override, else
    /// `Config::t_diff_ns`. The value a bring-up used (measured or configured) and its source
    /// are in [`SlaveInfo::t_diff_ns`] / [`SlaveInfo::t_diff_source`].
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::{Config, Machine};
    ///
    /// let mut dc = Machine::<8>::new(Config {
    ///     t_diff_ns: 20,
    ///     ..Config::DEFAULT
    /// })?;
    /// dc.set_slave_t_diff(1, Some(40))?;
    /// assert_eq!((dc.slave_t_diff(0), dc.slave_t_diff(1)), (20, 40));
    /// # Ok::<(), ecdc_core::dc::ConfigError>(())
    /// ```
    pub fn slave_t_diff(&self, position: u16) -> i32 {
        self.sh
            .line
            .t_diff
            .get(usize::from(position))
            .copied()
            .flatten()
            .unwrap_or(self.sh.cfg.t_diff_ns)
    }

    // ----- getters --------------------------------------------------------------------------

    /// Current state.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::{Config, Machine, State};
    ///
    /// let dc = Machine::<8>::new(Config::default())?;
    /// assert_eq!(dc.state().name(), "idle");
    /// assert_eq!(dc.state(), State::Idle);
    /// # Ok::<(), ecdc_core::dc::ConfigError>(())
    /// ```
    pub fn state(&self) -> State {
        self.phase.state()
    }
    /// The configuration.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::{Config, Machine};
    ///
    /// let dc = Machine::<8>::new(Config::default())?;
    /// assert_eq!(dc.config().monitor.cycle_ns, 1_000_000);
    /// # Ok::<(), ecdc_core::dc::ConfigError>(())
    /// ```
    pub fn config(&self) -> &Config {
        &self.sh.cfg
    }
    /// The slaves found, in position order.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::{Config, Machine};
    ///
    /// let dc = Machine::<8>::new(Config::default())?;
    /// // Filled by the bring-up (addresses, DC kind, delays, offsets) in position order,
    /// // e.g. for the largest propagation delay on the network.
    /// assert!(dc.slaves().is_empty());
    /// let worst = dc.slaves().iter().map(|s| s.delay_ns).max();
    /// assert_eq!(worst, None);
    /// # Ok::<(), ecdc_core::dc::ConfigError>(())
    /// ```
    pub fn slaves(&self) -> &[SlaveInfo] {
        self.sh
            .line
            .slaves
            .get(..usize::from(self.sh.line.count))
            .unwrap_or(&[])
    }
    /// Position of the reference clock, once chosen.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::{Config, Machine};
    ///
    /// // Chosen by the bring-up: the first slave with a system time.
    /// let dc = Machine::<8>::new(Config::default())?;
    /// assert_eq!(dc.reference(), None);
    /// # Ok::<(), ecdc_core::dc::ConfigError>(())
    /// ```
    pub fn reference(&self) -> Option<u16> {
        (self.sh.line.sys_count > 0).then_some(self.sh.line.reference)
    }
    /// Counters.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::{Config, Machine, Stats};
    ///
    /// let dc = Machine::<8>::new(Config::default())?;
    /// assert_eq!(*dc.stats(), Stats::ZERO);
    /// # Ok::<(), ecdc_core::dc::ConfigError>(())
    /// ```
    pub fn stats(&self) -> &Stats {
        &self.sh.stats
    }
    /// Whether cyclic operation is locked.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::{Config, Event, Machine};
    ///
    /// let mut dc = Machine::<8>::new(Config::default())?;
    /// // Lock is reported as `Event::Locked` and can be polled at any time.
    /// while let Some(ev) = dc.poll_event() {
    ///     assert!(!matches!(ev, Event::Locked { .. }));
    /// }
    /// assert!(!dc.is_locked());
    /// # Ok::<(), ecdc_core::dc::ConfigError>(())
    /// ```
    pub fn is_locked(&self) -> bool {
        self.phase
            .cyclic()
            .is_some_and(|c| c.lock.locked && c.holdover.is_none())
    }
    /// Last BRD 0x092C upper bound of |Δt| over all slaves (ns), if read this cycle run.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::{Config, Machine};
    ///
    /// // Only `Cyclic` reads the 0x092C bound.
    /// let dc = Machine::<8>::new(Config::default())?;
    /// assert_eq!(dc.diff_bound_ns(), None);
    /// # Ok::<(), ecdc_core::dc::ConfigError>(())
    /// ```
    pub fn diff_bound_ns(&self) -> Option<u32> {
        self.phase.cyclic().and_then(|c| c.bound_ns)
    }
    /// Reference system time returned by the last cyclic FRMW (64 bit; for a 32-bit reference,
    /// extended around the master's clock).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::{Config, Machine};
    ///
    /// // Only `Cyclic` has a reference time (from its FRMW).
    /// let dc = Machine::<8>::new(Config::default())?;
    /// assert_eq!(dc.reference_time(), None);
    /// # Ok::<(), ecdc_core::dc::ConfigError>(())
    /// ```
    pub fn reference_time(&self) -> Option<SystemTime> {
        self.phase.cyclic().and_then(|c| c.ref_time)
    }
    /// System time of the first SYNC0 pulse programmed in the last bring-up.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::{Config, Machine};
    ///
    /// // Set once a bring-up programmed the SYNC units (`Config::sync`).
    /// let dc = Machine::<8>::new(Config::default())?;
    /// assert_eq!(dc.sync_start(), None);
    /// # Ok::<(), ecdc_core::dc::ConfigError>(())
    /// ```
    pub fn sync_start(&self) -> Option<SystemTime> {
        self.sh.line.sync_start
    }
    /// Whether a transmitted frame's datagrams are still awaited (until all came back, the
    /// deadline passed, or `reset`/`start`). Only replies to that frame can be used.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::{Config, Machine};
    /// use ecdc_core::time::SystemTime;
    ///
    /// let mut dc = Machine::<8>::new(Config::default())?;
    /// let now = SystemTime::from_nanos(1_000_000_000);
    /// dc.start(now);
    /// let mut frame = [0u8; 1514];
    /// assert!(dc.poll_transmit(now, &mut frame).is_some());
    /// assert!(dc.is_awaiting_reply());
    /// // While a reply is awaited there is nothing more to send.
    /// assert_eq!(dc.poll_transmit(now, &mut frame), None);
    /// # Ok::<(), ecdc_core::dc::ConfigError>(())
    /// ```
    pub fn is_awaiting_reply(&self) -> bool {
        self.sh.timers.is_set(Timer::Reply)
    }

    // ----- output ---------------------------------------------------------------------------

    /// Next event, if any.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::{Config, Error, Event, Machine};
    /// use ecdc_core::time::SystemTime;
    ///
    /// let mut dc = Machine::<8>::new(Config::default())?;
    /// let now = SystemTime::from_nanos(1_000_000_000);
    /// dc.start(now);
    /// // A 20-byte buffer cannot hold a frame: reported as an event, not a panic.
    /// assert_eq!(dc.poll_transmit(now, &mut [0u8; 20]), None);
    /// assert_eq!(dc.poll_event(), Some(Event::Error(Error::BufferTooSmall)));
    /// assert_eq!(dc.poll_event(), None);
    /// # Ok::<(), ecdc_core::dc::ConfigError>(())
    /// ```
    #[must_use]
    pub fn poll_event(&mut self) -> Option<Event> {
        self.sh.events.pop()
    }

    /// When `handle_timeout` (or, for a paced drift burst, `poll_transmit`) should be called
    /// next: the earliest armed timer (a reply deadline, the next cycle, the end of a restart
    /// pause; `dc/timer.rs`), or the end of the pause before a burst's last FRMW while nothing
    /// is in flight. `None` when nothing is scheduled.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::{Config, Machine};
    /// use ecdc_core::time::SystemTime;
    ///
    /// let mut dc = Machine::<8>::new(Config::default())?;
    /// let now = SystemTime::from_nanos(1_000_000_000);
    /// assert_eq!(dc.poll_timeout(), None); // idle: nothing scheduled
    /// dc.start(now);
    /// let mut frame = [0u8; 1514];
    /// assert!(dc.poll_transmit(now, &mut frame).is_some());
    /// // The reply deadline: `response_timeout_ns` (10 ms) after sending.
    /// assert_eq!(dc.poll_timeout(), Some(now.wrapping_add(10_000_000)));
    /// # Ok::<(), ecdc_core::dc::ConfigError>(())
    /// ```
    #[must_use]
    pub fn poll_timeout(&self) -> Option<SystemTime> {
        let next = self.sh.timers.next();
        let gate = self.pace_until().filter(|g| g.is_after(self.sh.last_sent));
        if let Some(gate) =
            gate.filter(|_| self.state().is_request_step() && !self.is_awaiting_reply())
        {
            return Some(next.map_or(gate, |t| earliest(t, gate)));
        }
        next
    }

    /// Writes the next frame of the machine into `buf` (Ethernet frame, padded to 60 bytes) and
    /// returns its length, or `None` when nothing is to be sent now (waiting for a reply, for
    /// the next cycle, or idle). In `Cyclic` a frame is produced once per `monitor.cycle_ns`.
    ///
    /// It first handles the timers that expired by `now`, exactly as
    /// [`handle_timeout`](Self::handle_timeout) would (a lost reply is a loss, an ended
    /// restart pause starts the bring-up), because what to send depends on them: a caller
    /// that polls only transmissions still sees every deadline act, and one that also calls
    /// `handle_timeout` changes nothing by it.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::{Config, Machine};
    /// use ecdc_core::time::SystemTime;
    /// use ecdc_core::wire::{Command, EthernetFrame};
    ///
    /// let mut dc = Machine::<8>::new(Config::default())?;
    /// let now = SystemTime::from_nanos(1_000_000_000);
    /// dc.start(now);
    /// let mut buf = [0u8; 1514];
    /// let len = dc
    ///     .poll_transmit(now, &mut buf)
    ///     .expect("the slave count to send");
    /// // Hand `&buf[..len]` to the NIC. Here: check it is the BRD that counts the slaves.
    /// let frame = EthernetFrame::new_checked(&buf[..len]).expect("a well-formed frame");
    /// assert_eq!(frame.ethertype(), 0x88A4);
    /// assert_eq!(buf[16], Command::Brd as u8);
    /// # Ok::<(), ecdc_core::dc::ConfigError>(())
    /// ```
    #[must_use]
    pub fn poll_transmit(&mut self, now: SystemTime, buf: &mut [u8]) -> Option<usize> {
        self.handle_timeout(now);
        let mut b = match FrameBuilder::new(buf) {
            Ok(b) => b,
            Err(_) => {
                self.sh.push_event(Event::Error(Error::BufferTooSmall));
                return None;
            }
        };
        if !self.fill(now, &mut b, false) {
            return None;
        }
        match b.finish() {
            Ok(n) => Some(n),
            Err(_) => {
                // Cannot happen for a builder that accepted the datagrams; treat as a loss.
                self.sh.stop_awaiting();
                None
            }
        }
    }

    /// Appends the machine's datagrams for this moment into a frame the caller is building
    /// (for example its process-data frame). In `Cyclic` this always appends the cycle's FRMW
    /// and monitoring datagrams: the caller's cadence *is* the cycle. Returns whether anything
    /// was appended; datagrams that do not fit are left for the next call. Expired timers are
    /// handled first, as in [`poll_transmit`](Self::poll_transmit).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::{Config, Machine};
    /// use ecdc_core::time::SystemTime;
    /// use ecdc_core::wire::FrameBuilder;
    ///
    /// let mut dc = Machine::<8>::new(Config::default())?;
    /// let now = SystemTime::from_nanos(1_000_000_000);
    /// dc.start(now);
    /// // The host master's own frame; its process-data datagrams would be pushed here too.
    /// let mut buf = [0u8; 1514];
    /// let mut frame = FrameBuilder::new(&mut buf).expect("a full-size buffer");
    /// assert!(dc.poll_transmit_into(now, &mut frame));
    /// assert_eq!(frame.finish(), Ok(60));
    /// # Ok::<(), ecdc_core::dc::ConfigError>(())
    /// ```
    pub fn poll_transmit_into(&mut self, now: SystemTime, builder: &mut FrameBuilder<'_>) -> bool {
        self.handle_timeout(now);
        self.fill(now, builder, true)
    }

    // ----- input ----------------------------------------------------------------------------

    /// Handles an expiry of the time returned by `poll_timeout`; harmless when nothing expired.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::{Config, Machine};
    /// use ecdc_core::time::SystemTime;
    ///
    /// let mut dc = Machine::<8>::new(Config::default())?;
    /// let now = SystemTime::from_nanos(1_000_000_000);
    /// dc.start(now);
    /// let mut frame = [0u8; 1514];
    /// assert!(dc.poll_transmit(now, &mut frame).is_some());
    /// // No reply by the deadline: counted, and the request is sent again.
    /// let deadline = dc.poll_timeout().expect("a reply deadline");
    /// dc.handle_timeout(deadline);
    /// assert_eq!((dc.stats().timeouts, dc.stats().retries), (1, 1));
    /// assert!(dc.poll_transmit(deadline, &mut frame).is_some());
    /// # Ok::<(), ecdc_core::dc::ConfigError>(())
    /// ```
    pub fn handle_timeout(&mut self, now: SystemTime) {
        if self.sh.timers.expired(Timer::Reply, now) {
            self.sh.stats.timeouts = self.sh.stats.timeouts.saturating_add(1);
            if self.phase.is_cyclic() {
                self.in_cyclic(now, |cx| cx.cyclic_lost(now));
            } else {
                self.sh.stop_awaiting();
                let e = self.sh.step.error.take().unwrap_or(Error::Timeout {
                    state: self.state(),
                });
                self.retry_or_fail(now, e);
            }
        }
        if self.sh.timers.expired(Timer::Restart, now) {
            self.sh.restarts.frames_at_start = self.sh.stats.frames_sent;
            self.enter(State::CountSlaves);
        }
    }

    /// Handles one received Ethernet frame (any bytes). Datagrams matched to requests in flight
    /// (index, command, register, station, length: REQ-DC-032) are used; everything else is
    /// counted in `Stats` and ignored.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::{Config, Machine};
    /// use ecdc_core::time::SystemTime;
    ///
    /// let mut dc = Machine::<8>::new(Config::default())?;
    /// let now = SystemTime::from_nanos(1_000_000_000);
    /// dc.start(now);
    /// // Any bytes are safe to hand over; what is not a reply to us is only counted.
    /// dc.handle_frame(now, &[0xFF; 3]);
    /// dc.handle_frame(now, &[0u8; 60]);
    /// assert_eq!(dc.stats().foreign_frames, 2);
    /// # Ok::<(), ecdc_core::dc::ConfigError>(())
    /// ```
    pub fn handle_frame(&mut self, now: SystemTime, bytes: &[u8]) {
        self.handle_frame_with(now, bytes, true);
    }

    /// [`Machine::handle_frame`]; `fast` = false skips the cyclic fast path (tests compare).
    #[inline]
    pub(crate) fn handle_frame_with(&mut self, now: SystemTime, bytes: &[u8], fast: bool) {
        self.sh.stats.frames_received = self.sh.stats.frames_received.saturating_add(1);
        let Ok(eth) = EthernetFrame::new_checked(bytes) else {
            return self.count_foreign_frame();
        };
        // Our own transmission seen again (e.g. on a tap or veth) was not processed by any ESC.
        if !eth.processed_by_slave() {
            return self.count_foreign_frame();
        }
        // In `Cyclic`, a reply frame laid out exactly as sent takes one validating, matching
        // pass (same result as the general path below, which handles everything else).
        if fast && self.phase.is_cyclic() && self.is_awaiting_reply() {
            if let Some(frame) = eth.ecat_frame_unvalidated() {
                if self.in_cyclic(now, |cx| cx.cyclic_fast(now, frame.into_inner())) == Some(true) {
                    return self.replies_done(now);
                }
            }
        }
        let Ok(frame) = eth.ecat_frame() else {
            return self.count_foreign_frame();
        };
        let mut matched = 0u32;
        // `ecat_frame` validated every datagram: walk them once more without the checks.
        for d in frame.iter_valid() {
            // A circulated datagram went round a broken ring: its contents are not a reply.
            if d.circulating() {
                self.sh.stats.foreign_datagrams = self.sh.stats.foreign_datagrams.saturating_add(1);
                continue;
            }
            match self.sh.inflight.take_match(d.header) {
                Some(p) => {
                    matched = matched.saturating_add(1);
                    self.on_reply(now, p, d.wkc, d.data);
                }
                None => {
                    self.sh.stats.foreign_datagrams =
                        self.sh.stats.foreign_datagrams.saturating_add(1);
                }
            }
        }
        if matched == 0 {
            return self.count_foreign_frame();
        }
        self.replies_done(now);
    }

    /// After a frame with at least one matched reply: completes the step or cycle when no
    /// reply is outstanding.
    #[inline]
    fn replies_done(&mut self, now: SystemTime) {
        if self.is_awaiting_reply() && self.sh.inflight.is_empty() {
            self.sh.timers.stop(Timer::Reply);
            if self.phase.is_cyclic() {
                self.in_cyclic(now, |cx| cx.cyclic_complete(now));
            } else if self.state().is_request_step() {
                self.step_complete(now);
            }
        }
    }

    // ----- engine ---------------------------------------------------------------------------

    fn count_foreign_frame(&mut self) {
        self.sh.stats.foreign_frames = self.sh.stats.foreign_frames.saturating_add(1);
    }

    /// Enters `to` with a fresh cursor. Internal transitions follow [`State::can_go`]; one that
    /// does not is a machine bug, reported as [`Error::Internal`] with the machine stopped in
    /// `Failed` (every state may go to `Failed`, so this cannot recurse) rather than a panic
    /// (REQ-CONV-008). The model check asserts that no explored run reports it.
    pub(crate) fn enter(&mut self, to: State) {
        let to = if self.state().can_go(to) {
            to
        } else {
            self.sh.push_event(Event::Error(Error::Internal {
                state: self.state(),
            }));
            self.sh.stop_awaiting();
            State::Failed
        };
        self.phase = self.phase.enter(to);
        // The state-bound timers run only in their state (`dc/timer.rs`).
        if to != State::RestartWait {
            self.sh.timers.stop(Timer::Restart);
        }
        if to != State::Cyclic {
            self.sh.timers.stop(Timer::Cycle);
        }
        self.sh.step = StepProgress::START;
        self.on_enter(to);
    }

    /// Reports a fault and stops or schedules a re-initialisation (REQ-DC-111).
    pub(crate) fn fault(&mut self, now: SystemTime, e: Error) {
        self.sh.push_event(Event::Error(e));
        self.sh.stop_awaiting();
        if self.sh.cfg.auto_restart {
            self.sh.stats.restarts = self.sh.stats.restarts.saturating_add(1);
            let wake = now.wrapping_add(self.restart_delay());
            self.sh.restarts.streak = self.sh.restarts.streak.saturating_add(1);
            self.enter(State::RestartWait);
            if self.state() == State::RestartWait {
                self.sh.timers.set(Timer::Restart, wake);
            }
            self.sh.push_event(Event::Restarting);
        } else {
            self.enter(State::Failed);
        }
    }

    /// The pause before the next re-initialisation: `restart_delay_ns` doubled per
    /// re-initialisation since the last lock, capped at `restart_backoff_max_ns` (REQ-DC-130).
    fn restart_delay(&self) -> u64 {
        let base = self.sh.cfg.restart_delay_ns;
        let factor = 1u64
            .checked_shl(u32::from(self.sh.restarts.streak.min(40)))
            .unwrap_or(u64::MAX);
        base.saturating_mul(factor)
            .min(self.sh.cfg.restart_backoff_max_ns.max(base))
    }

    fn retry_or_fail(&mut self, now: SystemTime, e: Error) {
        if self.sh.step.tries < self.sh.cfg.retries && e.is_retryable() {
            self.sh.stats.retries = self.sh.stats.retries.saturating_add(1);
            let tries = self.sh.step.tries.saturating_add(1);
            if matches!(self.state(), State::LatchTrigger | State::LatchReadAfter) {
                // The trigger may or may not have latched: measure the whole round again.
                self.enter(State::LatchReadBefore);
            } else if let Some(s) = self.tdiff_retry_state() {
                self.enter(s);
            } else {
                self.sh.step.cursor = self.sh.step.chunk_start;
                self.sh.step.error = None;
            }
            self.sh.step.tries = tries;
        } else {
            self.fault(now, e);
        }
    }

    fn fill(&mut self, now: SystemTime, b: &mut FrameBuilder<'_>, into_caller: bool) -> bool {
        if self.phase.is_cyclic() {
            return self
                .in_cyclic(now, |cx| cx.fill_cyclic(now, b, into_caller))
                .unwrap_or(false);
        }
        if !self.state().is_request_step() || self.is_awaiting_reply() {
            return false;
        }
        // Skip items with nothing to send; finish steps that have nothing (left) to send.
        // Bounded: every step finishes after at most its item count, and there are < 64 steps
        // between two sends.
        for _ in 0..64u8 {
            if !self.state().is_request_step() {
                return self
                    .in_cyclic(now, |cx| cx.fill_cyclic(now, b, into_caller))
                    .unwrap_or(false);
            }
            if self.skip_to_item(now) {
                break;
            }
            self.step_done(now);
        }
        if !self.state().is_request_step() {
            return false;
        }
        if self.pace_until().is_some_and(|gate| gate.is_after(now)) {
            return false;
        }
        let before = b.datagram_count();
        self.sh.step.chunk_start = self.sh.step.cursor;
        self.sh.inflight.clear();
        let count = self.item_count();
        let max = self.max_per_frame();
        let mut sent = 0usize;
        while self.sh.step.cursor < count && sent < max {
            match self.item(now, self.sh.step.cursor) {
                Item::Skip => self.sh.step.cursor = self.sh.step.cursor.saturating_add(1),
                Item::Send(op) => {
                    if !self.drift_check_room(now, b, op)
                        || !self.sh.push_op(b, op, Tag::Item(self.sh.step.cursor))
                    {
                        break;
                    }
                    self.before_send(now);
                    sent = sent.saturating_add(1);
                    self.sh.step.cursor = self.sh.step.cursor.saturating_add(1);
                }
            }
        }
        if sent > 0 && self.sh.step.cursor < count {
            self.drift_check_epilogue(now, b);
        }
        if self.sh.inflight.is_empty() {
            if before == 0 {
                self.sh.push_event(Event::Error(Error::BufferTooSmall));
            }
            self.sh.step.cursor = self.sh.step.chunk_start;
            return false;
        }
        self.sh.last_sent = now;
        let due = now.wrapping_add(self.sh.cfg.response_timeout_ns);
        self.sh.timers.set(Timer::Reply, due);
        self.sh.stats.frames_sent = self.sh.stats.frames_sent.saturating_add(1);
        true
    }

    #[inline]
    fn on_reply(&mut self, now: SystemTime, p: Pending, wkc: u16, data: &[u8]) {
        // The cyclic path first (neither guard below holds in `Cyclic`; a cyclic reply is
        // tagged for the cycle, never `Item`).
        if self.phase.is_cyclic() {
            self.in_cyclic(now, |cx| cx.on_cyclic_reply(now, p, wkc, data));
            return;
        }
        match p.tag {
            Tag::Item(i) if self.state().is_request_step() => {
                if let Err(e) = self.on_item(
                    now,
                    Reply {
                        item: i,
                        sent: p,
                        wkc,
                        data,
                    },
                ) {
                    self.sh.step.error.get_or_insert(e);
                }
            }
            Tag::Frmw if self.state() == State::DriftCheck => {
                if let Err(e) = self.sh.check_frmw(p, wkc) {
                    self.sh.step.error.get_or_insert(e);
                }
            }
            _ => {}
        }
    }

    fn step_complete(&mut self, now: SystemTime) {
        if let Some(e) = self.sh.step.error.take() {
            return self.retry_or_fail(now, e);
        }
        self.sh.step.tries = 0;
        if !self.skip_to_item(now) {
            self.step_done(now);
        }
    }

    /// Moves the cursor past the items with nothing to send; whether an item is left. A range,
    /// not a loop condition: at most `count` items are looked at whatever `item` says.
    fn skip_to_item(&mut self, now: SystemTime) -> bool {
        let count = self.item_count();
        let start = self.sh.step.cursor;
        self.sh.step.cursor = (start..count)
            .find(|&i| !matches!(self.item(now, i), Item::Skip))
            .unwrap_or(count.max(start));
        self.sh.step.cursor < count
    }

    /// Positions `0..count`, as u16.
    pub(crate) fn positions(&self) -> core::ops::Range<u16> {
        0..self.sh.line.count
    }
}
