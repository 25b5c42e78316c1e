//! Configuration of the DC state machine: every knob with its default and where that default
//! comes from (a citation, or "ecdc choice" with the reason).

/// What the static drift compensation reads between bursts to decide convergence (REQ-DC-104).
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::{Config, DriftCheck, DriftConfig, Machine};
///
/// // A large network: one BRD per check instead of one FPRD per slave.
/// let cfg = Config {
///     drift: DriftConfig {
///         check: DriftCheck::Broadcast,
///         ..DriftConfig::DEFAULT
///     },
///     ..Config::DEFAULT
/// };
/// assert_eq!(
///     Machine::<512>::new(cfg)?.config().drift.check,
///     DriftCheck::Broadcast
/// );
/// # Ok::<(), ecdc_core::dc::ConfigError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum DriftCheck {
    /// FPRD 0x092C of every DC slave: exact per-slave values, one datagram per slave.
    PerSlave,
    /// One BRD 0x092C: the bitwise OR of all sign-magnitude values, whose magnitude bits are an
    /// upper bound of every slave's |Δt| (IgH `sync_monitor`). Cheap, but pessimistic.
    Broadcast,
    /// Both; convergence requires both to be below the threshold.
    Both,
}

/// Which datagram distributes the reference clock's time (static bursts and every cycle).
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::{Config, DriftCommand};
///
/// // TwinCAT style: ARMW to the reference's position instead of FRMW to its station address.
/// let cfg = Config {
///     drift_command: DriftCommand::Armw,
///     ..Config::DEFAULT
/// };
/// assert_eq!(cfg.validate(64), Ok(()));
/// assert_eq!(Config::default().drift_command, DriftCommand::Frmw);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum DriftCommand {
    /// FRMW to the reference's station address (SOEM, IgH, ethercrab): independent of
    /// positions.
    Frmw,
    /// ARMW to the reference's auto-increment position (TwinCAT, seed 003 Fig. 10).
    Armw,
}

/// Static drift compensation (ARMW/FRMW bursts with a convergence gate), REQ-DC-104.
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::{Config, DriftConfig};
///
/// // Converge faster on a quiet test bench: a 200 ns gate held for 5 checks.
/// let drift = DriftConfig {
///     threshold_ns: 200,
///     scatter_ns: 400,
///     consecutive: 5,
///     ..DriftConfig::DEFAULT
/// };
/// let cfg = Config {
///     drift,
///     ..Config::DEFAULT
/// };
/// assert_eq!(cfg.validate(16), Ok(()));
/// assert_eq!(DriftConfig::default().burst_frames, 20);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct DriftConfig {
    /// FRMW frames per burst between two 0x092C checks. ecdc choice: 20. Convergence is bound
    /// by the ESCs' loop slew (time), not by the number of samples: on the default simulate
    /// scenario (measured with the earlier strict per-reading gate) 100-frame bursts
    /// locked after 4 026 frames / 91 ms, 20-frame bursts after 1 763 frames / 104 ms with the
    /// same steady-state skew, so smaller bursts spend less
    /// bandwidth for about the same lock time (docs/simulate.md). The cost showed on large
    /// networks, where each 1 ms check pause weighs more: with that gate the emulated 100-slave
    /// tree locked after 6 517 frames / 1.38 s with 20-frame bursts against 5 954 frames /
    /// 0.83 s with 100; with the current gate it locks after 1 006 frames / 288 ms with 20.
    /// Raise it when bring-up time matters more than bus load.
    pub burst_frames: u16,
    /// Convergence threshold in ns on each slave's clock offset, estimated as |mean 0x092C|
    /// over the `consecutive` checks of a passing streak (the BRD bound's mean in `Broadcast`
    /// mode). ecdc choice: 100 ns, the "< 100 ns" DC accuracy Beckhoff states (EL6685 docs)
    /// and CherryECAT's `EC_DC_MAX_SYNC_DIFF_NS`; 100× stricter than IgH's 10 µs gate,
    /// affordable because the offsets already fold the delay in. A mean, not every reading: a
    /// slave n cables down latches the reference time with the PHY jitter of all n cables, so
    /// on long lines single readings scatter by more than the clocks do (the emulated
    /// 1024-slave line: true clocks within 30–80 ns, readings up to 230 ns) and a per-reading
    /// gate never passes; the jitter is zero-mean once the delays are measured, so the signed
    /// mean over K readings keeps the offset and divides the jitter by √K.
    pub threshold_ns: u32,
    /// Bound on each slave's mean |0x092C| over the streak, ns: catches a loop that swings
    /// around the reference (a small signed mean of large readings). ecdc choice: 200 ns
    /// (2 × `threshold_ns`).
    pub scatter_ns: u32,
    /// Upper bound of every single reading (per-slave |0x092C| and the BRD bound) in a check
    /// of a streak, ns; a check with a reading above it does not count and restarts the streak.
    /// It catches a slave that is still slewing or has not learned the rate (a 0.4 ppm rate
    /// error is 400 ns over the 1 ms check pause). ecdc choice: 400 ns.
    pub spike_ns: u32,
    /// Checks in a passing streak (K): every reading ≤ `spike_ns` in each, then the means are
    /// judged; a streak whose means miss the threshold starts over. After the first passing
    /// check, the remaining ones are one cycle-paced FRMW each, so K also is the number of
    /// cycles the network must stay converged at the cyclic sample rate. ecdc choice: 20
    /// (20 ms at 1 ms).
    pub consecutive: u8,
    /// Upper bound of FRMW frames before giving up with a per-slave report. 30 000 = twice the
    /// ~15 000 frames quoted by KickCAT/CherryECAT and seed 000 §2.3.
    pub max_frames: u32,
    /// What to read at each check.
    pub check: DriftCheck,
    /// Free-running pause before the last FRMW of every burst, ns. The check then reads the
    /// Δt that one pause accumulated, so the gate passes only once the loops have learned the
    /// clock *rate*, not just the phase (back-to-back frames hide a rate error). ecdc choice:
    /// 1 ms, the default cycle; 0 disables the pause.
    pub check_pause_ns: u64,
}

impl DriftConfig {
    /// The defaults (`Default::default()`), usable in a `const` context.
    pub const DEFAULT: DriftConfig = DriftConfig {
        burst_frames: 20,
        threshold_ns: 100,
        scatter_ns: 200,
        spike_ns: 400,
        consecutive: 20,
        max_frames: 30_000,
        check: DriftCheck::Both,
        check_pause_ns: 1_000_000,
    };
}

impl Default for DriftConfig {
    fn default() -> Self {
        DriftConfig::DEFAULT
    }
}

/// SYNC0/SYNC1 programming for the DC slaves (REQ-DC-105).
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::{Config, ConfigError, SyncConfig};
///
/// // SYNC0 and SYNC1 every 500 µs, SYNC0 shifted 100 µs into the cycle.
/// let sync = SyncConfig {
///     assign_activate: 0x0700,
///     sync0_cycle_ns: 500_000,
///     shift_ns: 100_000,
///     ..SyncConfig::DEFAULT
/// };
/// assert_eq!(
///     Config {
///         sync: Some(sync),
///         ..Config::DEFAULT
///     }
///     .validate(8),
///     Ok(())
/// );
/// // A shift of a whole cycle or more is refused.
/// let bad = SyncConfig {
///     shift_ns: 500_000,
///     ..sync
/// };
/// assert_eq!(
///     Config {
///         sync: Some(bad),
///         ..Config::DEFAULT
///     }
///     .validate(8),
///     Err(ConfigError::SyncCycle)
/// );
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct SyncConfig {
    /// AssignActivate word from the ESI, written as 2 bytes to 0x0980 (low byte 0x0980 cyclic
    /// unit control, high byte 0x0981 activation). 0x0300 = SYNC0 only, 0x0700 = SYNC0 + SYNC1.
    pub assign_activate: u16,
    /// SYNC0 cycle time (0x09A0, 32 bit) in ns. Must be > 0.
    pub sync0_cycle_ns: u32,
    /// SYNC1 cycle time (0x09A4, 32 bit) in ns; 0 = SYNC1 mirrors SYNC0.
    pub sync1_cycle_ns: u32,
    /// Shift of the first SYNC0 pulse from the common grid, in ns (0 ≤ shift < cycle).
    pub shift_ns: u32,
    /// Lead time between reading the reference clock and the first pulse. 100 ms, as IgH
    /// (`EC_DC_START_OFFSET`) and SOEM (`SyncDelay`).
    pub start_delay_ns: u64,
}

impl SyncConfig {
    /// The defaults (`Default::default()`), usable in a `const` context.
    pub const DEFAULT: SyncConfig = SyncConfig {
        assign_activate: 0x0300,
        sync0_cycle_ns: 1_000_000,
        sync1_cycle_ns: 0,
        shift_ns: 0,
        start_delay_ns: 100_000_000,
    };
}

impl Default for SyncConfig {
    fn default() -> Self {
        SyncConfig::DEFAULT
    }
}

/// Cyclic monitoring and lock detection (REQ-DC-106).
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::{Config, ConfigError, MonitorConfig};
///
/// // A 250 µs cycle, locking below 100 ns.
/// let monitor = MonitorConfig {
///     cycle_ns: 250_000,
///     lock_ns: 100,
///     ..MonitorConfig::DEFAULT
/// };
/// assert_eq!(
///     Config {
///         monitor,
///         ..Config::DEFAULT
///     }
///     .validate(8),
///     Ok(())
/// );
/// // The lock threshold may not lie above the unlock threshold.
/// let flat = MonitorConfig {
///     lock_ns: 2_000,
///     ..monitor
/// };
/// assert_eq!(
///     Config {
///         monitor: flat,
///         ..Config::DEFAULT
///     }
///     .validate(8),
///     Err(ConfigError::Hysteresis)
/// );
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct MonitorConfig {
    /// Cycle period when the machine paces itself (`poll_transmit`); an embedding master that
    /// calls `poll_transmit_into` sets its own cadence. ecdc choice: 1 ms, the usual DC cycle.
    pub cycle_ns: u64,
    /// Per-slave FPRD 0x092C datagrams per cycle (round robin). ecdc choice: 8 keeps the cyclic
    /// overhead at 8 × 16 bytes while sweeping 100 slaves in 13 cycles.
    pub slaves_per_cycle: u8,
    /// Lock when the BRD 0x092C upper bound stays ≤ this for `lock_cycles` cycles. ecdc choice:
    /// 200 ns: the bound is a bitwise OR of magnitudes, at most twice the worst slave, so this
    /// certifies every slave within 200 ns.
    pub lock_ns: u32,
    /// Unlock when the bound stays > this for `unlock_cycles` cycles (hysteresis). ecdc choice:
    /// 1 µs, five times the lock threshold and ten times below IgH's 10 µs gate.
    pub unlock_ns: u32,
    /// Consecutive good cycles to declare lock. ecdc choice: 10.
    pub lock_cycles: u16,
    /// Consecutive bad cycles to declare loss of lock. ecdc choice: 3.
    pub unlock_cycles: u16,
    /// Cycles in `Cyclic` without lock before a `NotLocked` error is reported (once per lock
    /// attempt). ecdc choice: 5 000 (5 s at 1 ms, IgH's `EC_DC_SYNC_WAIT_MS`).
    pub lock_timeout_cycles: u32,
    /// Consecutive cycles whose DC datagrams did not come back before the machine gives up and
    /// re-initialises. ecdc choice: 5 (coast over short bursts of loss).
    pub max_lost_cycles: u16,
    /// Consecutive cycles with a wrong working counter before re-initialisation. ecdc choice: 3.
    pub max_wkc_errors: u16,
}

impl MonitorConfig {
    /// The defaults (`Default::default()`), usable in a `const` context.
    pub const DEFAULT: MonitorConfig = MonitorConfig {
        cycle_ns: 1_000_000,
        slaves_per_cycle: 8,
        lock_ns: 200,
        unlock_ns: 1_000,
        lock_cycles: 10,
        unlock_cycles: 3,
        lock_timeout_cycles: 5_000,
        max_lost_cycles: 5,
        max_wkc_errors: 3,
    };
}

impl Default for MonitorConfig {
    fn default() -> Self {
        MonitorConfig::DEFAULT
    }
}

/// Complete machine configuration. `Config::default()` is a sane setup for a line or tree of
/// ESCs; every field is documented with its source.
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::{Config, Machine, Stations};
///
/// // Embedded in a host master that already addressed the slaves, with datagram indices
/// // 0x00..=0x7F left to it (the machine owns 0x80..=0xFF), and ESCs whose t_Diff is 40 ns.
/// let cfg = Config {
///     stations: Stations::Adopt,
///     index_first: 0x80,
///     index_count: 0x80,
///     t_diff_ns: 40,
///     ..Config::DEFAULT
/// };
/// let dc = Machine::<32>::new(cfg)?;
/// assert_eq!(dc.slave_t_diff(0), 40);
/// # Ok::<(), ecdc_core::dc::ConfigError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Config {
    /// Station address of the first slave (position 0); slave `i` gets `station_base + i`.
    /// 0x1001 is the customary first configured address (SOEM, IgH).
    pub station_base: u16,
    /// Whether the machine assigns the station addresses (default) or adopts the ones a host
    /// master wrote (REQ-DC-140).
    pub stations: crate::dc::Stations,
    /// First datagram index the machine may use. The machine owns `index_count` consecutive
    /// indices (mod 256), so an embedding master keeps the others for its own datagrams.
    pub index_first: u8,
    /// Number of indices owned; at least [`crate::dc::MAX_INFLIGHT`] × 2 so a late reply to
    /// an abandoned frame cannot match a fresh request. ecdc choice: 0x80..=0xFF.
    pub index_count: u8,
    /// Time to wait for a frame to come back. ecdc choice: 10 ms, far above any line's round
    /// trip (≈ 1 µs per slave, DS S1-88) and below the SYNC start lead time.
    pub response_timeout_ns: u64,
    /// Resends of one request chunk (after a timeout or a wrong WKC) before the step fails.
    /// ecdc choice: 3.
    pub retries: u8,
    /// Latch measurements (BWR 0x0900) averaged into the propagation delays. ecdc choice: 4
    /// halves the 10 ns stamp quantisation noise.
    pub latch_rounds: u8,
    /// `t_Diff = t_P − t_F` of the ESCs (processing minus forwarding delay), ns, from the ESI
    /// or the ESC datasheet (DS S1-73); used for every slave without its own value
    /// ([`Machine::set_slave_t_diff`](crate::dc::Machine::set_slave_t_diff)). 0 when unknown:
    /// then each hop's delay is off by t_Diff/2 (seed 000 eq. 13).
    pub t_diff_ns: i32,
    /// Largest plausible propagation delay from the reference to any slave, ns; a larger
    /// computed delay is rejected as out of range instead of being written. ecdc choice: 1 ms
    /// (≈ 1 000 hops at the 1 µs per hop of DS S1-88).
    pub max_delay_ns: u32,
    /// Value written to 0x0934 (2 bytes: 0x0934 system-time-difference filter depth, 0x0935
    /// speed-counter filter depth) before the loop reset. 0x0C00 as SOEM, ethercrab, KickCAT.
    pub filter_depths: u16,
    /// Value written to 0x0930 (speed counter start) to reset the loop. ecdc choice: 0x0C00,
    /// below the reset value 0x1000 (DS S2-76) that IgH writes. The loop's output is the
    /// speed counter diff D (0x0932), and the rate one D step buys grows as 1/S² (DS-II
    /// Tab.105), so with the same loop law a smaller S is a wider bandwidth, as the datasheet
    /// describes 0x0930: a ±50 ppm crystal needs D ≈ 1667 of 2945 at 0x0C00 against 2560 of
    /// 3969 at 0x1000, and the loop gets there sooner. The price is the resolution, 0.021
    /// instead of 0.012 ppm per LSB (21 ps per ms), far below the 10 ns tick; the compensable
    /// range stays ≈ ±760 ppm (docs/background/esc-registers.md §4.2a). On the emulator
    /// (whose loop law is a model choice) seed 000's line locks about 3× sooner with the same
    /// skew; docs/simulate.md has the per-seed figures, including the scenarios where it is
    /// slower. The same larger rate per D step makes a hold-over drift about twice as fast
    /// (docs/background/holdover.md §1). Write 0x1000 to keep the reset value.
    pub speed_counter_start: u16,
    /// Static drift compensation.
    pub drift: DriftConfig,
    /// Command that carries the reference time (bursts and cycles). Default FRMW.
    pub drift_command: DriftCommand,
    /// SYNC0/SYNC1 programming; `None` leaves the SYNC units untouched.
    pub sync: Option<SyncConfig>,
    /// Cyclic monitoring.
    pub monitor: MonitorConfig,
    /// Re-initialise automatically after a fault (topology change, slave lost, timeout).
    pub auto_restart: bool,
    /// Pause before a re-initialisation. ecdc choice: 10 ms, lets a flapping link settle.
    /// It doubles with every further re-initialisation that did not reach lock, up to
    /// `restart_backoff_max_ns` (REQ-DC-130).
    pub restart_delay_ns: u64,
    /// Longest pause between re-initialisations (the backoff's cap). ecdc choice: 1 s: a
    /// network that stays away costs about one bring-up attempt (a few frames) per second,
    /// and once it is back the next attempt starts at most a second later.
    pub restart_backoff_max_ns: u64,
    /// Longest silence (no complete cycle, or no transmission) the cyclic phase holds over
    /// before it re-initialises (REQ-DC-127, 129), counted from the first missed cycle with
    /// one cycle period of grace for the resume cycle; 0 disables hold-over (re-initialise after
    /// `monitor.max_lost_cycles`). ecdc choice: 1 s (1 000 cycles at 1 ms), because the slaves'
    /// clocks keep their offsets and learnt rates through a silence, so only the residual
    /// rate error accumulates (docs/background/holdover.md §1: 21 → 259 ns worst SYNC0 skew
    /// over 1 s on seed 000's emulated line at 0x0930 = 0x0C00), while a stopped peer or a stalled host of a few
    /// hundred ms is common on machines without real-time scheduling.
    pub holdover_ns: u64,
    /// Largest BRD 0x092C bound the resume check after a hold-over accepts, ns (REQ-DC-128).
    /// ecdc choice: 100 µs: a clock free-running at the ±100 ppm 100BASE-TX tolerates drifts
    /// 100 µs in the default 1 s hold-over even with no compensation at all, while an ESC that
    /// was reset has a difference spread over the whole ±2.1 s of the 32-bit comparison
    /// (docs/background/holdover.md §3). Raise it with `holdover_ns`.
    pub holdover_check_ns: u32,
    /// How the t_Diff of each ESC is learned (REQ-DC-120).
    pub tdiff: TdiffConfig,
}

impl Config {
    /// The defaults (`Default::default()`), usable in a `const` context.
    pub const DEFAULT: Config = Config {
        station_base: 0x1001,
        stations: crate::dc::Stations::Assign,
        index_first: 0x80,
        index_count: 0x80,
        response_timeout_ns: 10_000_000,
        retries: 3,
        latch_rounds: 4,
        t_diff_ns: 0,
        max_delay_ns: 1_000_000,
        filter_depths: 0x0C00,
        speed_counter_start: 0x0C00,
        drift: DriftConfig::DEFAULT,
        drift_command: DriftCommand::Frmw,
        sync: Some(SyncConfig::DEFAULT),
        monitor: MonitorConfig::DEFAULT,
        auto_restart: true,
        restart_delay_ns: 10_000_000,
        restart_backoff_max_ns: 1_000_000_000,
        holdover_ns: 1_000_000_000,
        holdover_check_ns: 100_000,
        tdiff: TdiffConfig::DEFAULT,
    };
}

impl Default for Config {
    fn default() -> Self {
        Config::DEFAULT
    }
}

/// Why a [`Config`] was rejected by [`crate::dc::Machine::new`].
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::{Config, ConfigError, Machine};
///
/// // 0x0930 must be in 0x0080..=0x3FFF.
/// let cfg = Config {
///     speed_counter_start: 0x4000,
///     ..Config::DEFAULT
/// };
/// assert_eq!(
///     Machine::<8>::new(cfg).err(),
///     Some(ConfigError::SpeedCounterStart)
/// );
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ConfigError {
    /// `index_count` < 2 × MAX_INFLIGHT.
    TooFewIndices,
    /// Station addresses would wrap past 0xFFFF or include 0 for the given capacity.
    StationRange,
    /// A SYNC0 cycle of 0, or a shift ≥ the cycle.
    SyncCycle,
    /// A zero that must be positive (timeout, cycle, burst size, rounds, K).
    Zero,
    /// Lock threshold above the unlock threshold (no hysteresis).
    Hysteresis,
    /// 0x0930 value outside the valid range 0x0080..=0x3FFF (DS S2-76).
    SpeedCounterStart,
    /// A per-slave setting for a position beyond the machine's capacity `N`.
    Capacity,
}

impl Config {
    /// Checks the invariants the machine relies on. `capacity` is the slave capacity `N`.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::{Config, ConfigError};
    ///
    /// let cfg = Config {
    ///     station_base: 0xFFF0,
    ///     ..Config::DEFAULT
    /// };
    /// // Station addresses 0xFFF0.. fit 16 slaves, not 17.
    /// assert_eq!(cfg.validate(16), Ok(()));
    /// assert_eq!(cfg.validate(17), Err(ConfigError::StationRange));
    /// ```
    pub fn validate(&self, capacity: usize) -> Result<(), ConfigError> {
        if usize::from(self.index_count) < crate::dc::request::MAX_INFLIGHT.saturating_mul(2) {
            return Err(ConfigError::TooFewIndices);
        }
        let cap = u32::try_from(capacity).unwrap_or(u32::MAX);
        if self.station_base == 0 || u32::from(self.station_base).saturating_add(cap) > 0x1_0000 {
            return Err(ConfigError::StationRange);
        }
        if self.response_timeout_ns == 0
            || self.latch_rounds == 0
            || self.drift.burst_frames == 0
            || self.drift.consecutive == 0
            || self.monitor.cycle_ns == 0
            || self.monitor.lock_cycles == 0
            || self.monitor.unlock_cycles == 0
            || self.monitor.max_lost_cycles == 0
            || self.monitor.max_wkc_errors == 0
        {
            return Err(ConfigError::Zero);
        }
        if self.monitor.lock_ns > self.monitor.unlock_ns {
            return Err(ConfigError::Hysteresis);
        }
        if !(0x0080..=0x3FFF).contains(&self.speed_counter_start) {
            return Err(ConfigError::SpeedCounterStart);
        }
        if self.tdiff.mode != TdiffMode::Off
            && (self.tdiff.rounds == 0 || self.tdiff.base_rounds == 0)
        {
            return Err(ConfigError::Zero);
        }
        if let Some(s) = self.sync {
            if s.sync0_cycle_ns == 0 || s.shift_ns >= s.sync0_cycle_ns {
                return Err(ConfigError::SyncCycle);
            }
        }
        Ok(())
    }
}

/// Which slaves the bring-up measures t_Diff on (REQ-DC-120).
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::config::{TdiffConfig, TdiffMode};
/// use ecdc_core::dc::Config;
///
/// // A long line of identical ESCs: measure one slave per ESC type, use it for all.
/// let tdiff = TdiffConfig {
///     mode: TdiffMode::PerEscType,
///     ..TdiffConfig::DEFAULT
/// };
/// assert_eq!(
///     Config {
///         tdiff,
///         ..Config::DEFAULT
///     }
///     .validate(1024),
///     Ok(())
/// );
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum TdiffMode {
    /// Nothing is measured: per-slave overrides, [`TdiffConfig::types`] or
    /// [`Config::t_diff_ns`] are used.
    Off,
    /// Every DC slave whose t_Diff enters a delay and can be measured (entered at port 0, with
    /// a downstream port, below another DC slave) is measured; the others take the value of a
    /// measured slave of the same ESC type and revision.
    PerSlave,
    /// One slave per ESC type and revision (0x0000..0x0001) is measured and the value is used
    /// for every slave of that type: fewer port closings on large networks, exact only if
    /// ESCs of one type do not differ.
    PerEscType,
}

/// A user-supplied t_Diff for every ESC of one type and revision.
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::config::{TdiffConfig, TdiffType};
///
/// // ESC type 0x11, revision 0x00 (low byte type, high byte revision): t_Diff 40 ns, not measured.
/// let known = TdiffType {
///     esc_type: 0x0011,
///     t_diff_ns: 40,
/// };
/// let tdiff = TdiffConfig {
///     types: [Some(known), None, None, None],
///     ..TdiffConfig::DEFAULT
/// };
/// assert_eq!(tdiff.types[0].map(|t| t.t_diff_ns), Some(40));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct TdiffType {
    /// 0x0000 (type, low byte) and 0x0001 (revision, high byte) as one little-endian word.
    pub esc_type: u16,
    /// t_Diff = t_P − t_F of that ESC, ns (ESI or datasheet).
    pub t_diff_ns: i32,
}

/// t_Diff measurement settings (REQ-DC-120..126).
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::config::{TdiffConfig, TdiffMode};
/// use ecdc_core::dc::{Config, ConfigError};
///
/// // No port closing at all: use the configured t_Diff.
/// let off = TdiffConfig {
///     mode: TdiffMode::Off,
///     ..TdiffConfig::DEFAULT
/// };
/// assert_eq!(
///     Config {
///         tdiff: off,
///         ..Config::DEFAULT
///     }
///     .validate(8),
///     Ok(())
/// );
/// // Measuring with zero rounds is refused.
/// let zero = TdiffConfig {
///     rounds: 0,
///     ..TdiffConfig::DEFAULT
/// };
/// assert_eq!(
///     Config {
///         tdiff: zero,
///         ..Config::DEFAULT
///     }
///     .validate(8),
///     Err(ConfigError::Zero)
/// );
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct TdiffConfig {
    /// What is measured. Default [`TdiffMode::PerSlave`].
    pub mode: TdiffMode,
    /// Latches averaged with the target's downstream ports closed, per measured slave (one
    /// frame each: a latch's read shares its frame with the next latch's trigger; plus the
    /// close, the first trigger and the restore: `rounds + 3` frames). ecdc choice: 48,
    /// together with 128 [`Self::base_rounds`]. Each closed round gives `X'` (two 10
    /// ns-quantised stamps on the upstream slave's clock, PHY jitter of two cable crossings),
    /// each all-open round `X − rtt` (four stamps), so the variance of the result goes as
    /// 2/`rounds` + 4/`base_rounds`: 48/128 is below 64/64 (0.073 against 0.094 per-stamp
    /// variances) and costs 51 instead of 67 frames per measured slave. Measured on the
    /// emulated 512-slave line (errors against the truth, 510 measured slaves): seed 7
    /// −3..+4 ns with 48/128 (−3..+4 ns with 64/64, more of them at the edges), seed 1
    /// −3..+3 ns (target ±5 ns, harness/tests/tdiff.rs). On a long line each closed round
    /// costs a round trip to the target, so [`TdiffMode::PerEscType`] is much cheaper there.
    pub rounds: u8,
    /// All-open latches, shared by every measured slave (one read step each, its last frame
    /// carrying the next trigger). ecdc choice: 128 (see [`Self::rounds`]): paid once per
    /// bring-up, and the term with four stamps per round.
    pub base_rounds: u8,
    /// Smallest plausible t_Diff, ns; a smaller mean is rejected (source
    /// `Fallback(Implausible)`). ecdc choice: −10 ns: the processing path includes the
    /// forwarding path's port logic plus the EPU, so t_P < t_F beyond one 10 ns stamp tick
    /// means the loop did not close or a latch is stale.
    pub min_ns: i32,
    /// Largest plausible t_Diff, ns. ecdc choice: 500 ns: an order of magnitude above the
    /// tens of ns expected of real ESCs and the emulator's 80 ns, and below one hop's
    /// ≈ 1 µs (DS S1-88), which a port that stayed open would add.
    pub max_ns: i32,
    /// Known values per ESC type + revision; slaves of these types are not measured.
    pub types: [Option<TdiffType>; 4],
}

impl TdiffConfig {
    /// The defaults (`Default::default()`), usable in a `const` context.
    pub const DEFAULT: TdiffConfig = TdiffConfig {
        mode: TdiffMode::PerSlave,
        rounds: 48,
        base_rounds: 128,
        min_ns: -10,
        max_ns: 500,
        types: [None; 4],
    };
}

impl Default for TdiffConfig {
    fn default() -> Self {
        TdiffConfig::DEFAULT
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `validate` refuses each bad field on its own, and accepts each bound itself.
    #[test]
    fn validate_checks_each_field_alone() {
        let ok = Config::DEFAULT;
        assert_eq!(ok.validate(16), Ok(()));
        let zeroed: [fn(&mut Config); 9] = [
            |c| c.response_timeout_ns = 0,
            |c| c.latch_rounds = 0,
            |c| c.drift.burst_frames = 0,
            |c| c.drift.consecutive = 0,
            |c| c.monitor.cycle_ns = 0,
            |c| c.monitor.lock_cycles = 0,
            |c| c.monitor.unlock_cycles = 0,
            |c| c.monitor.max_lost_cycles = 0,
            |c| c.monitor.max_wkc_errors = 0,
        ];
        for (i, zero) in zeroed.iter().enumerate() {
            let mut c = ok;
            zero(&mut c);
            assert_eq!(c.validate(16), Err(ConfigError::Zero), "field {i}");
        }
        // Indices: twice the in-flight table, exactly, is enough.
        let twice = u8::try_from(crate::dc::request::MAX_INFLIGHT * 2).unwrap();
        let c = Config {
            index_count: twice,
            ..ok
        };
        assert_eq!(c.validate(16), Ok(()));
        let c = Config {
            index_count: twice - 1,
            ..ok
        };
        assert_eq!(c.validate(16), Err(ConfigError::TooFewIndices));
        // Stations: the last slave may take 0xFFFF.
        let c = Config {
            station_base: 0xFFF0,
            ..ok
        };
        assert_eq!(
            (c.validate(16), c.validate(17)),
            (Ok(()), Err(ConfigError::StationRange))
        );
        let c = Config {
            station_base: 0,
            ..ok
        };
        assert_eq!(c.validate(1), Err(ConfigError::StationRange));
        // Hysteresis: lock at the unlock threshold is allowed, above it not.
        let mut c = ok;
        c.monitor.lock_ns = c.monitor.unlock_ns;
        assert_eq!(c.validate(16), Ok(()));
        c.monitor.lock_ns = c.monitor.unlock_ns + 1;
        assert_eq!(c.validate(16), Err(ConfigError::Hysteresis));
        // 0x0930 range ends.
        for (v, want) in [
            (0x0080u16, Ok(())),
            (0x3FFF, Ok(())),
            (0x007F, Err(ConfigError::SpeedCounterStart)),
            (0x4000, Err(ConfigError::SpeedCounterStart)),
        ] {
            assert_eq!(
                Config {
                    speed_counter_start: v,
                    ..ok
                }
                .validate(16),
                want,
                "{v:#06x}"
            );
        }
        // t_Diff rounds matter only when t_Diff is measured.
        for mode in [TdiffMode::Off, TdiffMode::PerSlave] {
            for (rounds, base) in [(0u8, 1u8), (1, 0)] {
                let mut c = ok;
                c.tdiff.mode = mode;
                c.tdiff.rounds = rounds;
                c.tdiff.base_rounds = base;
                let want = if mode == TdiffMode::Off {
                    Ok(())
                } else {
                    Err(ConfigError::Zero)
                };
                assert_eq!(c.validate(16), want, "{mode:?} {rounds} {base}");
            }
        }
        // SYNC: the shift must stay inside the SYNC0 cycle.
        let sync = SyncConfig::default();
        let c = Config {
            sync: Some(SyncConfig {
                shift_ns: sync.sync0_cycle_ns - 1,
                ..sync
            }),
            ..ok
        };
        assert_eq!(c.validate(16), Ok(()));
        let c = Config {
            sync: Some(SyncConfig {
                shift_ns: sync.sync0_cycle_ns,
                ..sync
            }),
            ..ok
        };
        assert_eq!(c.validate(16), Err(ConfigError::SyncCycle));
        let c = Config {
            sync: Some(SyncConfig {
                sync0_cycle_ns: 0,
                shift_ns: 0,
                ..sync
            }),
            ..ok
        };
        assert_eq!(c.validate(16), Err(ConfigError::SyncCycle));
    }

    /// The t_Diff defaults are the documented ecdc choices (`TdiffConfig`'s field docs).
    #[test]
    fn tdiff_defaults_as_documented() {
        let d = TdiffConfig::DEFAULT;
        assert_eq!(d, TdiffConfig::default());
        assert_eq!(
            (d.mode, d.rounds, d.base_rounds),
            (TdiffMode::PerSlave, 48, 128)
        );
        assert_eq!((d.min_ns, d.max_ns), (-10, 500));
    }
}
