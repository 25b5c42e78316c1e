//! The `#[repr(C)]` types of the ABI and their conversions to and from `ecdc-core`, in safe
//! Rust. C-style names so the generated header reads like a C library.
//!
//! Input structs (`ecdc_config`) carry enumerations and flags as plain integers: a C caller can
//! store any value in them, and a Rust enum or `bool` holding an invalid value would be
//! undefined behaviour, so they are checked here instead. Output structs use C enums freely:
//! only Rust writes them.
#![allow(non_camel_case_types)]

use core::fmt::Write as _;

use ecdc_core::dc::{
    Config, ConfigError, DcKind, DriftCheck, DriftCommand, DriftConfig, Error, Event,
    HoldoverCause, MonitorConfig, ResumeFailure, SlaveInfo, State, Stats, SyncConfig, TdiffConfig,
    TdiffMode, TdiffType,
};

/// Result of every fallible call. `ECDC_OK` is 0; `ecdc_strerror` names each code.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ecdc_status {
    /// Success.
    ECDC_OK = 0,
    /// A required pointer argument was NULL.
    ECDC_ERR_NULL = 1,
    /// The machine pointer is not a live handle (never initialised, freed, misaligned).
    ECDC_ERR_INVALID_HANDLE = 2,
    /// The storage given to `ecdc_machine_init*` is smaller than `ecdc_machine_size*()`.
    ECDC_ERR_STORAGE_TOO_SMALL = 3,
    /// The storage given to `ecdc_machine_init*` is not aligned to `ecdc_machine_align()`.
    ECDC_ERR_STORAGE_MISALIGNED = 4,
    /// Config: `index_count` below 2 × the 32 requests in flight.
    ECDC_ERR_CONFIG_TOO_FEW_INDICES = 5,
    /// Config: station addresses `station_base ..= station_base + capacity - 1` include 0 or
    /// pass 0xFFFF.
    ECDC_ERR_CONFIG_STATION_RANGE = 6,
    /// Config: SYNC0 cycle 0 or shift ≥ cycle.
    ECDC_ERR_CONFIG_SYNC_CYCLE = 7,
    /// Config: a field that must be positive is 0.
    ECDC_ERR_CONFIG_ZERO = 8,
    /// Config: `lock_ns` above `unlock_ns`.
    ECDC_ERR_CONFIG_HYSTERESIS = 9,
    /// Config: `speed_counter_start` outside 0x0080..=0x3FFF.
    ECDC_ERR_CONFIG_SPEED_COUNTER_START = 10,
    /// A slave position beyond the machine's capacity.
    ECDC_ERR_CAPACITY = 11,
    /// Config: an enumeration field holds an unknown value.
    ECDC_ERR_CONFIG_ENUM = 12,
    /// Config: rejected for a reason this header predates.
    ECDC_ERR_CONFIG_OTHER = 13,
    /// A frame buffer below the 60-byte minimum Ethernet frame.
    ECDC_ERR_BUFFER_TOO_SMALL = 14,
    /// The datagram does not fit in the frame (nothing was written).
    ECDC_ERR_FRAME_FULL = 15,
    /// The frame buffer does not hold a frame started by `ecdc_frame_init`.
    ECDC_ERR_FRAME_INVALID = 16,
    /// `ecdc_frame_finish` on a frame without datagrams.
    ECDC_ERR_FRAME_EMPTY = 17,
    /// An invalid argument: unknown command code, address kind not matching the command,
    /// data longer than a datagram can carry.
    ECDC_ERR_ARGUMENT = 18,
    /// `ecdc_machine_new*` could not allocate.
    ECDC_ERR_ALLOC = 19,
    /// A call panicked inside the library (a bug); the machine is poisoned and refuses every
    /// further call except `ecdc_machine_free`.
    ECDC_ERR_PANIC = 20,
    /// The machine was poisoned by an earlier `ECDC_ERR_PANIC`.
    ECDC_ERR_POISONED = 21,
}

/// `ecdc_config.drift_check` values: what the static drift compensation reads between bursts.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ecdc_drift_check {
    /// FPRD 0x092C of every DC slave.
    ECDC_DRIFT_CHECK_PER_SLAVE = 0,
    /// One BRD 0x092C (bitwise OR of all slaves' values: an upper bound).
    ECDC_DRIFT_CHECK_BROADCAST = 1,
    /// Both (the default).
    ECDC_DRIFT_CHECK_BOTH = 2,
}

/// `ecdc_config.drift_command` values: which datagram distributes the reference time.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ecdc_drift_command {
    /// FRMW to the reference's station address (the default).
    ECDC_DRIFT_FRMW = 0,
    /// ARMW to the reference's auto-increment position.
    ECDC_DRIFT_ARMW = 1,
}

/// `ecdc_config.tdiff_mode` values: which slaves the bring-up measures t_Diff on.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ecdc_tdiff_mode {
    /// Measure nothing: per-slave values, the per-type table or `t_diff_ns` are used.
    ECDC_TDIFF_OFF = 0,
    /// Measure every slave whose t_Diff enters a delay and can be measured (the default).
    ECDC_TDIFF_PER_SLAVE = 1,
    /// Measure one slave per ESC type and revision and use its value for the others.
    ECDC_TDIFF_PER_ESC_TYPE = 2,
}

/// A user-supplied t_Diff for every ESC of one type and revision (`ecdc_config.tdiff_types`).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ecdc_tdiff_type {
    /// 1 = this entry is used, 0 = empty.
    pub used: u8,
    /// Reserved, keep 0.
    pub reserved: u8,
    /// 0x0000 (type, low byte) and 0x0001 (revision, high byte) as one word.
    pub esc_type: u16,
    /// t_Diff = t_P − t_F of that ESC, ns.
    pub t_diff_ns: i32,
}

/// Machine configuration: the knobs of `ecdc_core::dc::Config`, flattened. Always start from
/// `ecdc_config_default()` and change fields; the meaning and source of every default is
/// documented in `core/src/dc/config.rs`. Times are ns, flags are 0 = false / other = true.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ecdc_config {
    /// Station address of the first slave; slave `i` gets `station_base + i`. Default 0x1001.
    pub station_base: u16,
    /// First datagram index the machine uses (it owns `index_count` indices from here, mod
    /// 256; the host keeps the others). Default 0x80.
    pub index_first: u8,
    /// Number of indices the machine owns, at least 64. Default 0x80 (0x80..=0xFF).
    pub index_count: u8,
    /// Reply timeout. Default 10 ms.
    pub response_timeout_ns: u64,
    /// Resends of a request chunk before the step fails. Default 3.
    pub retries: u8,
    /// Latch rounds averaged into the propagation delays. Default 4.
    pub latch_rounds: u8,
    /// `t_Diff = t_P − t_F` of the ESCs (ns) for every slave without its own value
    /// (`ecdc_set_slave_t_diff`). Default 0 (unknown).
    pub t_diff_ns: i32,
    /// Largest plausible propagation delay. Default 1 ms.
    pub max_delay_ns: u32,
    /// Value written to 0x0934 (filter depths). Default 0x0C00.
    pub filter_depths: u16,
    /// Value written to 0x0930 (speed counter start). Default 0x0C00.
    pub speed_counter_start: u16,
    /// Static drift: FRMW frames per burst. Default 20.
    pub drift_burst_frames: u16,
    /// Static drift: checks in a passing streak. Default 20.
    pub drift_consecutive: u8,
    /// Static drift: an `ecdc_drift_check` value. Default `ECDC_DRIFT_CHECK_BOTH`.
    pub drift_check: u8,
    /// Static drift: convergence threshold on each slave's mean offset. Default 100 ns.
    pub drift_threshold_ns: u32,
    /// Static drift: bound on each slave's mean |0x092C|. Default 200 ns.
    pub drift_scatter_ns: u32,
    /// Static drift: bound on every single reading of a streak. Default 400 ns.
    pub drift_spike_ns: u32,
    /// Static drift: FRMW frames before giving up. Default 30 000.
    pub drift_max_frames: u32,
    /// Static drift: free-running pause before each check. Default 1 ms.
    pub drift_check_pause_ns: u64,
    /// An `ecdc_drift_command` value. Default `ECDC_DRIFT_FRMW`.
    pub drift_command: u8,
    /// Program the SYNC units (1) or leave them untouched (0). Default 1.
    pub sync_enabled: u8,
    /// AssignActivate word written to 0x0980. Default 0x0300 (SYNC0 only).
    pub sync_assign_activate: u16,
    /// SYNC0 cycle (0x09A0). Default 1 ms.
    pub sync0_cycle_ns: u32,
    /// SYNC1 cycle (0x09A4), 0 = mirrors SYNC0. Default 0.
    pub sync1_cycle_ns: u32,
    /// Shift of SYNC0 from the common grid, `0 <= shift < sync0_cycle_ns`. Default 0.
    pub sync_shift_ns: u32,
    /// Lead time from reading the reference clock to the first pulse. Default 100 ms.
    pub sync_start_delay_ns: u64,
    /// Cycle period when the machine paces itself (`ecdc_poll_transmit`). Default 1 ms.
    pub cycle_ns: u64,
    /// Per-slave 0x092C reads per cycle (round robin). Default 8.
    pub slaves_per_cycle: u8,
    /// Restart automatically after a fault (1) or stop in `ECDC_STATE_FAILED` (0). Default 1.
    pub auto_restart: u8,
    /// Consecutive good cycles to declare lock. Default 10.
    pub lock_cycles: u16,
    /// Lock when the BRD 0x092C bound stays at or below this. Default 200 ns.
    pub lock_ns: u32,
    /// Unlock when the bound stays above this. Default 1 µs.
    pub unlock_ns: u32,
    /// Consecutive bad cycles to declare loss of lock. Default 3.
    pub unlock_cycles: u16,
    /// Consecutive lost cycles before re-initialisation. Default 5.
    pub max_lost_cycles: u16,
    /// Cycles without lock before a `NOT_LOCKED` fault. Default 5 000.
    pub lock_timeout_cycles: u32,
    /// Consecutive wrong-WKC cycles before re-initialisation. Default 3.
    pub max_wkc_errors: u16,
    /// Reserved, keep 0.
    pub reserved: u16,
    /// Pause before a re-initialisation. Default 10 ms.
    pub restart_delay_ns: u64,
    /// t_Diff measurement mode (`ecdc_tdiff_mode`). Default per slave.
    pub tdiff_mode: u8,
    /// Latches per closed-port measurement. Default 48.
    pub tdiff_rounds: u8,
    /// Latches with every port open, the measurement's baseline. Default 128.
    pub tdiff_base_rounds: u8,
    /// Reserved, keep 0.
    pub tdiff_reserved: u8,
    /// Smallest plausible measured t_Diff, ns; below it the slave falls back. Default −10.
    pub tdiff_min_ns: i32,
    /// Largest plausible measured t_Diff, ns. Default 500.
    pub tdiff_max_ns: i32,
    /// User-supplied t_Diff per ESC type and revision (unused entries: `used` 0).
    pub tdiff_types: [ecdc_tdiff_type; 4],
    /// Longest pause between re-initialisations (backoff cap). Default 1 s.
    pub restart_backoff_max_ns: u64,
    /// Longest silence held over in cyclic operation before re-initialising; 0 disables
    /// hold-over. Default 1 s.
    pub holdover_ns: u64,
    /// Largest BRD 0x092C bound the resume check after a hold-over accepts. Default 100 µs.
    pub holdover_check_ns: u32,
    /// Reserved, keep 0.
    pub holdover_reserved: u32,
}

/// The C view of a Rust [`Config`].
pub fn config_to_c(c: &Config) -> ecdc_config {
    let s = c.sync.unwrap_or_default();
    ecdc_config {
        station_base: c.station_base,
        index_first: c.index_first,
        index_count: c.index_count,
        response_timeout_ns: c.response_timeout_ns,
        retries: c.retries,
        latch_rounds: c.latch_rounds,
        t_diff_ns: c.t_diff_ns,
        max_delay_ns: c.max_delay_ns,
        filter_depths: c.filter_depths,
        speed_counter_start: c.speed_counter_start,
        drift_burst_frames: c.drift.burst_frames,
        drift_consecutive: c.drift.consecutive,
        drift_check: match c.drift.check {
            DriftCheck::PerSlave => ecdc_drift_check::ECDC_DRIFT_CHECK_PER_SLAVE as u8,
            DriftCheck::Broadcast => ecdc_drift_check::ECDC_DRIFT_CHECK_BROADCAST as u8,
            DriftCheck::Both => ecdc_drift_check::ECDC_DRIFT_CHECK_BOTH as u8,
        },
        drift_threshold_ns: c.drift.threshold_ns,
        drift_scatter_ns: c.drift.scatter_ns,
        drift_spike_ns: c.drift.spike_ns,
        drift_max_frames: c.drift.max_frames,
        drift_check_pause_ns: c.drift.check_pause_ns,
        drift_command: match c.drift_command {
            DriftCommand::Frmw => ecdc_drift_command::ECDC_DRIFT_FRMW as u8,
            DriftCommand::Armw => ecdc_drift_command::ECDC_DRIFT_ARMW as u8,
        },
        sync_enabled: u8::from(c.sync.is_some()),
        sync_assign_activate: s.assign_activate,
        sync0_cycle_ns: s.sync0_cycle_ns,
        sync1_cycle_ns: s.sync1_cycle_ns,
        sync_shift_ns: s.shift_ns,
        sync_start_delay_ns: s.start_delay_ns,
        cycle_ns: c.monitor.cycle_ns,
        slaves_per_cycle: c.monitor.slaves_per_cycle,
        auto_restart: u8::from(c.auto_restart),
        lock_cycles: c.monitor.lock_cycles,
        lock_ns: c.monitor.lock_ns,
        unlock_ns: c.monitor.unlock_ns,
        unlock_cycles: c.monitor.unlock_cycles,
        max_lost_cycles: c.monitor.max_lost_cycles,
        lock_timeout_cycles: c.monitor.lock_timeout_cycles,
        max_wkc_errors: c.monitor.max_wkc_errors,
        reserved: 0,
        restart_delay_ns: c.restart_delay_ns,
        tdiff_mode: match c.tdiff.mode {
            TdiffMode::Off => ecdc_tdiff_mode::ECDC_TDIFF_OFF as u8,
            TdiffMode::PerSlave => ecdc_tdiff_mode::ECDC_TDIFF_PER_SLAVE as u8,
            TdiffMode::PerEscType => ecdc_tdiff_mode::ECDC_TDIFF_PER_ESC_TYPE as u8,
        },
        tdiff_rounds: c.tdiff.rounds,
        tdiff_base_rounds: c.tdiff.base_rounds,
        tdiff_reserved: 0,
        tdiff_min_ns: c.tdiff.min_ns,
        tdiff_max_ns: c.tdiff.max_ns,
        tdiff_types: c.tdiff.types.map(|t| match t {
            Some(t) => ecdc_tdiff_type {
                used: 1,
                reserved: 0,
                esc_type: t.esc_type,
                t_diff_ns: t.t_diff_ns,
            },
            None => ecdc_tdiff_type {
                used: 0,
                reserved: 0,
                esc_type: 0,
                t_diff_ns: 0,
            },
        }),
        restart_backoff_max_ns: c.restart_backoff_max_ns,
        holdover_ns: c.holdover_ns,
        holdover_check_ns: c.holdover_check_ns,
        holdover_reserved: 0,
    }
}

/// The Rust [`Config`] of a C one; `ECDC_ERR_CONFIG_ENUM` for an unknown enumeration value.
/// The machine's own validation (`Config::validate`) runs later, in `Machine::new`.
pub fn config_from_c(c: &ecdc_config) -> Result<Config, ecdc_status> {
    use ecdc_drift_check as K;
    let check = match c.drift_check {
        x if x == K::ECDC_DRIFT_CHECK_PER_SLAVE as u8 => DriftCheck::PerSlave,
        x if x == K::ECDC_DRIFT_CHECK_BROADCAST as u8 => DriftCheck::Broadcast,
        x if x == K::ECDC_DRIFT_CHECK_BOTH as u8 => DriftCheck::Both,
        _ => return Err(ecdc_status::ECDC_ERR_CONFIG_ENUM),
    };
    let drift_command = match c.drift_command {
        x if x == ecdc_drift_command::ECDC_DRIFT_FRMW as u8 => DriftCommand::Frmw,
        x if x == ecdc_drift_command::ECDC_DRIFT_ARMW as u8 => DriftCommand::Armw,
        _ => return Err(ecdc_status::ECDC_ERR_CONFIG_ENUM),
    };
    let tdiff_mode = match c.tdiff_mode {
        x if x == ecdc_tdiff_mode::ECDC_TDIFF_OFF as u8 => TdiffMode::Off,
        x if x == ecdc_tdiff_mode::ECDC_TDIFF_PER_SLAVE as u8 => TdiffMode::PerSlave,
        x if x == ecdc_tdiff_mode::ECDC_TDIFF_PER_ESC_TYPE as u8 => TdiffMode::PerEscType,
        _ => return Err(ecdc_status::ECDC_ERR_CONFIG_ENUM),
    };
    Ok(Config {
        tdiff: TdiffConfig {
            mode: tdiff_mode,
            rounds: c.tdiff_rounds,
            base_rounds: c.tdiff_base_rounds,
            min_ns: c.tdiff_min_ns,
            max_ns: c.tdiff_max_ns,
            types: c.tdiff_types.map(|t| {
                (t.used != 0).then_some(TdiffType {
                    esc_type: t.esc_type,
                    t_diff_ns: t.t_diff_ns,
                })
            }),
        },
        station_base: c.station_base,
        // The C configuration has no field for adopting a host's addresses (REQ-DC-140) yet:
        // a C host assigns them as `station_base` says.
        stations: ecdc_core::dc::Stations::Assign,
        index_first: c.index_first,
        index_count: c.index_count,
        response_timeout_ns: c.response_timeout_ns,
        retries: c.retries,
        latch_rounds: c.latch_rounds,
        t_diff_ns: c.t_diff_ns,
        max_delay_ns: c.max_delay_ns,
        filter_depths: c.filter_depths,
        speed_counter_start: c.speed_counter_start,
        drift: DriftConfig {
            burst_frames: c.drift_burst_frames,
            threshold_ns: c.drift_threshold_ns,
            scatter_ns: c.drift_scatter_ns,
            spike_ns: c.drift_spike_ns,
            consecutive: c.drift_consecutive,
            max_frames: c.drift_max_frames,
            check,
            check_pause_ns: c.drift_check_pause_ns,
        },
        drift_command,
        sync: (c.sync_enabled != 0).then_some(SyncConfig {
            assign_activate: c.sync_assign_activate,
            sync0_cycle_ns: c.sync0_cycle_ns,
            sync1_cycle_ns: c.sync1_cycle_ns,
            shift_ns: c.sync_shift_ns,
            start_delay_ns: c.sync_start_delay_ns,
        }),
        monitor: MonitorConfig {
            cycle_ns: c.cycle_ns,
            slaves_per_cycle: c.slaves_per_cycle,
            lock_ns: c.lock_ns,
            unlock_ns: c.unlock_ns,
            lock_cycles: c.lock_cycles,
            unlock_cycles: c.unlock_cycles,
            lock_timeout_cycles: c.lock_timeout_cycles,
            max_lost_cycles: c.max_lost_cycles,
            max_wkc_errors: c.max_wkc_errors,
        },
        auto_restart: c.auto_restart != 0,
        restart_delay_ns: c.restart_delay_ns,
        restart_backoff_max_ns: c.restart_backoff_max_ns,
        holdover_ns: c.holdover_ns,
        holdover_check_ns: c.holdover_check_ns,
    })
}

/// The status code of a [`ConfigError`].
pub fn status_of_config_error(e: ConfigError) -> ecdc_status {
    use ecdc_status as S;
    #[allow(unreachable_patterns)] // a variant added to ecdc-core maps to the generic code
    match e {
        ConfigError::TooFewIndices => S::ECDC_ERR_CONFIG_TOO_FEW_INDICES,
        ConfigError::StationRange => S::ECDC_ERR_CONFIG_STATION_RANGE,
        ConfigError::SyncCycle => S::ECDC_ERR_CONFIG_SYNC_CYCLE,
        ConfigError::Zero => S::ECDC_ERR_CONFIG_ZERO,
        ConfigError::Hysteresis => S::ECDC_ERR_CONFIG_HYSTERESIS,
        ConfigError::SpeedCounterStart => S::ECDC_ERR_CONFIG_SPEED_COUNTER_START,
        ConfigError::Capacity => S::ECDC_ERR_CAPACITY,
        _ => S::ECDC_ERR_CONFIG_OTHER,
    }
}

/// NUL-terminated description of a status code (any integer; unknown ones get a generic text).
pub fn strerror(code: i64) -> &'static core::ffi::CStr {
    use ecdc_status as S;
    const ALL: [(ecdc_status, &core::ffi::CStr); 22] = [
        (S::ECDC_OK, c"success"),
        (S::ECDC_ERR_NULL, c"a required pointer argument was NULL"),
        (
            S::ECDC_ERR_INVALID_HANDLE,
            c"not a live ecdc machine handle",
        ),
        (
            S::ECDC_ERR_STORAGE_TOO_SMALL,
            c"storage smaller than ecdc_machine_size()",
        ),
        (
            S::ECDC_ERR_STORAGE_MISALIGNED,
            c"storage not aligned to ecdc_machine_align()",
        ),
        (
            S::ECDC_ERR_CONFIG_TOO_FEW_INDICES,
            c"config: index_count below 64",
        ),
        (
            S::ECDC_ERR_CONFIG_STATION_RANGE,
            c"config: station addresses include 0 or pass 0xFFFF",
        ),
        (
            S::ECDC_ERR_CONFIG_SYNC_CYCLE,
            c"config: SYNC0 cycle 0 or shift not below the cycle",
        ),
        (
            S::ECDC_ERR_CONFIG_ZERO,
            c"config: a field that must be positive is 0",
        ),
        (
            S::ECDC_ERR_CONFIG_HYSTERESIS,
            c"config: lock_ns above unlock_ns",
        ),
        (
            S::ECDC_ERR_CONFIG_SPEED_COUNTER_START,
            c"config: speed_counter_start outside 0x0080..0x3FFF",
        ),
        (
            S::ECDC_ERR_CAPACITY,
            c"slave position beyond the machine's capacity",
        ),
        (
            S::ECDC_ERR_CONFIG_ENUM,
            c"config: unknown enumeration value",
        ),
        (S::ECDC_ERR_CONFIG_OTHER, c"config: rejected"),
        (S::ECDC_ERR_BUFFER_TOO_SMALL, c"frame buffer below 60 bytes"),
        (
            S::ECDC_ERR_FRAME_FULL,
            c"datagram does not fit in the frame",
        ),
        (
            S::ECDC_ERR_FRAME_INVALID,
            c"buffer does not hold a frame started by ecdc_frame_init",
        ),
        (S::ECDC_ERR_FRAME_EMPTY, c"frame has no datagram"),
        (S::ECDC_ERR_ARGUMENT, c"invalid argument"),
        (S::ECDC_ERR_ALLOC, c"allocation failed"),
        (S::ECDC_ERR_PANIC, c"internal panic (bug); machine poisoned"),
        (
            S::ECDC_ERR_POISONED,
            c"machine poisoned by an earlier panic",
        ),
    ];
    ALL.iter()
        .find(|(s, _)| *s as i64 == code)
        .map_or(c"unknown ecdc status code", |(_, t)| t)
}

/// The machine's state (returned by `ecdc_state`). The values are part of the ABI and never renumbered.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ecdc_machine_state {
    /// Not started.
    ECDC_STATE_IDLE = 0,
    /// BRD 0x0000: counting slaves.
    ECDC_STATE_COUNT_SLAVES = 1,
    /// Assigning station addresses.
    ECDC_STATE_ASSIGN_ADDRESSES = 2,
    /// Reading features and DL status.
    ECDC_STATE_READ_INFO = 3,
    /// Probing which slaves have a system time.
    ECDC_STATE_PROBE_SYSTEM_TIME = 4,
    /// Reading latches before the trigger.
    ECDC_STATE_LATCH_READ_BEFORE = 5,
    /// Latch trigger (BWR 0x0900).
    ECDC_STATE_LATCH_TRIGGER = 6,
    /// Reading latches after the trigger.
    ECDC_STATE_LATCH_READ_AFTER = 7,
    /// Reading AL status before the offset write.
    ECDC_STATE_READ_AL_STATUS = 8,
    /// Writing offsets and delays.
    ECDC_STATE_WRITE_OFFSETS = 9,
    /// Resetting the slaves' control loops.
    ECDC_STATE_RESET_LOOPS = 10,
    /// Static drift compensation: FRMW bursts.
    ECDC_STATE_DRIFT_BURST = 11,
    /// Static drift compensation: convergence check.
    ECDC_STATE_DRIFT_CHECK = 12,
    /// Reading the reference time for the SYNC start.
    ECDC_STATE_READ_REFERENCE_TIME = 13,
    /// Clearing SYNC activation.
    ECDC_STATE_CLEAR_ACTIVATION = 14,
    /// Programming SYNC start and cycle times.
    ECDC_STATE_PROGRAM_SYNC = 15,
    /// Activating SYNC.
    ECDC_STATE_ACTIVATE_SYNC = 16,
    /// Cyclic operation.
    ECDC_STATE_CYCLIC = 17,
    /// Pausing before a re-initialisation.
    ECDC_STATE_RESTART_WAIT = 18,
    /// Stopped after a fault (`auto_restart` 0).
    ECDC_STATE_FAILED = 19,
    /// t_Diff measurement: read ESC type, AL status and DL control.
    ECDC_STATE_TDIFF_READ = 20,
    /// t_Diff measurement: read the port times of a latch.
    ECDC_STATE_TDIFF_LATCH = 21,
    /// t_Diff measurement: BWR 0x0900 latch trigger.
    ECDC_STATE_TDIFF_TRIGGER = 22,
    /// t_Diff measurement: close the target's downstream ports (DL control 0x0100).
    ECDC_STATE_TDIFF_CLOSE = 23,
    /// t_Diff measurement: restore the target's DL control exactly.
    ECDC_STATE_TDIFF_RESTORE = 24,
    /// A state this header predates (a newer library), or no valid handle.
    ECDC_STATE_UNKNOWN = 255,
}

/// The C state of a Rust [`State`]. New core states map to `ECDC_STATE_UNKNOWN` until they
/// get a number here.
pub fn state_to_c(s: State) -> ecdc_machine_state {
    use ecdc_machine_state as C;
    #[allow(unreachable_patterns)] // a state added to ecdc-core maps to UNKNOWN
    match s {
        State::Idle => C::ECDC_STATE_IDLE,
        State::CountSlaves => C::ECDC_STATE_COUNT_SLAVES,
        State::AssignAddresses => C::ECDC_STATE_ASSIGN_ADDRESSES,
        State::ReadInfo => C::ECDC_STATE_READ_INFO,
        State::ProbeSystemTime => C::ECDC_STATE_PROBE_SYSTEM_TIME,
        State::LatchReadBefore => C::ECDC_STATE_LATCH_READ_BEFORE,
        State::LatchTrigger => C::ECDC_STATE_LATCH_TRIGGER,
        State::LatchReadAfter => C::ECDC_STATE_LATCH_READ_AFTER,
        State::ReadAlStatus => C::ECDC_STATE_READ_AL_STATUS,
        State::WriteOffsets => C::ECDC_STATE_WRITE_OFFSETS,
        State::ResetLoops => C::ECDC_STATE_RESET_LOOPS,
        State::DriftBurst => C::ECDC_STATE_DRIFT_BURST,
        State::DriftCheck => C::ECDC_STATE_DRIFT_CHECK,
        State::ReadReferenceTime => C::ECDC_STATE_READ_REFERENCE_TIME,
        State::ClearActivation => C::ECDC_STATE_CLEAR_ACTIVATION,
        State::ProgramSync => C::ECDC_STATE_PROGRAM_SYNC,
        State::ActivateSync => C::ECDC_STATE_ACTIVATE_SYNC,
        State::Cyclic => C::ECDC_STATE_CYCLIC,
        State::RestartWait => C::ECDC_STATE_RESTART_WAIT,
        State::Failed => C::ECDC_STATE_FAILED,
        State::TdiffRead => C::ECDC_STATE_TDIFF_READ,
        State::TdiffLatch => C::ECDC_STATE_TDIFF_LATCH,
        State::TdiffTrigger => C::ECDC_STATE_TDIFF_TRIGGER,
        State::TdiffClose => C::ECDC_STATE_TDIFF_CLOSE,
        State::TdiffRestore => C::ECDC_STATE_TDIFF_RESTORE,
        _ => C::ECDC_STATE_UNKNOWN,
    }
}

/// NUL-terminated lower-case name of a state value (the CLI's names), "unknown" otherwise.
pub fn state_name(code: i64) -> &'static core::ffi::CStr {
    const NAMES: [&core::ffi::CStr; 25] = [
        c"idle",
        c"count-slaves",
        c"assign-addresses",
        c"read-info",
        c"probe-system-time",
        c"latch-read-before",
        c"latch-trigger",
        c"latch-read-after",
        c"read-al-status",
        c"write-offsets",
        c"reset-loops",
        c"drift-burst",
        c"drift-check",
        c"read-reference-time",
        c"clear-activation",
        c"program-sync",
        c"activate-sync",
        c"cyclic",
        c"restart-wait",
        c"failed",
        c"tdiff-read",
        c"tdiff-latch",
        c"tdiff-trigger",
        c"tdiff-close",
        c"tdiff-restore",
    ];
    usize::try_from(code)
        .ok()
        .and_then(|i| NAMES.get(i))
        .copied()
        .unwrap_or(c"unknown")
}

/// `ecdc_event.kind`. The values are part of the ABI and never renumbered.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ecdc_event_kind {
    /// No event (`ecdc_poll_event` returned false).
    ECDC_EVENT_NONE = 0,
    /// The network was counted and addressed: `u.slaves_found`.
    ECDC_EVENT_SLAVES_FOUND = 1,
    /// Propagation delays measured: `u.delays_measured`.
    ECDC_EVENT_DELAYS_MEASURED = 2,
    /// Offsets and delays written: `u.offsets_written`.
    ECDC_EVENT_OFFSETS_WRITTEN = 3,
    /// Static drift compensation converged: `u.drift_converged`.
    ECDC_EVENT_DRIFT_CONVERGED = 4,
    /// SYNC units programmed: `u.sync_started`.
    ECDC_EVENT_SYNC_STARTED = 5,
    /// Cyclic operation locked: `u.locked`.
    ECDC_EVENT_LOCKED = 6,
    /// Lock lost: `u.lock_lost`.
    ECDC_EVENT_LOCK_LOST = 7,
    /// A delay re-measurement finished: `u.delays_updated`.
    ECDC_EVENT_DELAYS_UPDATED = 8,
    /// A fault: `u.error`.
    ECDC_EVENT_ERROR = 9,
    /// The machine re-initialises after `restart_delay_ns` (no data).
    ECDC_EVENT_RESTARTING = 10,
    /// Every slave's t_Diff is known: `u.tdiff_resolved`.
    ECDC_EVENT_TDIFF_RESOLVED = 11,
    /// Cyclic operation holds over a silence or stall: `u.holdover_started`.
    ECDC_EVENT_HOLDOVER_STARTED = 12,
    /// A hold-over ended with a passed resume check: `u.holdover_ended`.
    ECDC_EVENT_HOLDOVER_ENDED = 13,
    /// An event this header predates (a newer library); only `text` describes it.
    ECDC_EVENT_OTHER = 255,
}

/// `ecdc_fault.kind`: the fault of an `ECDC_EVENT_ERROR`. Never renumbered.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ecdc_fault_kind {
    /// Wrong working counter: `command`, `station`, `register_`, `expected`, `actual`.
    ECDC_FAULT_WKC = 1,
    /// No valid reply in the step `state`, after all retries.
    ECDC_FAULT_TIMEOUT = 2,
    /// Slave count changed: `expected` at bring-up, `actual` now.
    ECDC_FAULT_TOPOLOGY_CHANGED = 3,
    /// A slave stopped answering: `station`.
    ECDC_FAULT_SLAVE_LOST = 4,
    /// Static drift did not converge: `count` frames, `actual` slaves over the threshold,
    /// worst `station` at `diff_ns`.
    ECDC_FAULT_NOT_CONVERGED = 5,
    /// No lock after `count` cycles; last bound `diff_ns`.
    ECDC_FAULT_NOT_LOCKED = 6,
    /// A value read back was implausible: `station`, `register_`.
    ECDC_FAULT_OUT_OF_RANGE = 7,
    /// Receive times could not be turned into delays: first rejected `station` (0 = all).
    ECDC_FAULT_MEASUREMENT = 8,
    /// More slaves (`actual`) than the capacity (`expected`).
    ECDC_FAULT_TOO_MANY_SLAVES = 9,
    /// No slave answered.
    ECDC_FAULT_NO_SLAVES = 10,
    /// No slave with a system time.
    ECDC_FAULT_NO_REFERENCE_CLOCK = 11,
    /// The transmit buffer cannot hold one datagram.
    ECDC_FAULT_BUFFER_TOO_SMALL = 12,
    /// A hold-over outlasted `holdover_ns`: `count` = the silence in µs (saturated).
    ECDC_FAULT_HOLDOVER_EXPIRED = 13,
    /// The resume check after a hold-over failed; `command` holds an `ecdc_resume_failure`:
    /// SLAVE_COUNT (`expected`, `actual`), REFERENCE_WKC (`expected`, `actual`), SLAVE_LOST
    /// (`station`), SLAVE_RESET (`actual` = AL status OR now, `expected` = before), BOUND
    /// (`diff_ns`).
    ECDC_FAULT_RESUME_CHECK_FAILED = 14,
    /// An internal consistency check of the machine failed in the step `state`; the machine
    /// stopped instead of panicking.
    ECDC_FAULT_INTERNAL = 15,
    /// A fault this header predates; only `ecdc_event.text` describes it.
    ECDC_FAULT_OTHER = 255,
}

/// `ecdc_fault.command` of an `ECDC_FAULT_RESUME_CHECK_FAILED`. Never renumbered.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ecdc_resume_failure {
    /// A different number of slaves answers.
    ECDC_RESUME_SLAVE_COUNT = 1,
    /// The FRMW's working counter is not the DC slave count.
    ECDC_RESUME_REFERENCE_WKC = 2,
    /// A slave lost its station address.
    ECDC_RESUME_SLAVE_LOST = 3,
    /// A slave is in INIT although none was before.
    ECDC_RESUME_SLAVE_RESET = 4,
    /// The 0x092C bound exceeds `holdover_check_ns`.
    ECDC_RESUME_BOUND = 5,
    /// A failure this header predates.
    ECDC_RESUME_OTHER = 255,
}

/// `ecdc_ev_holdover_started.cause` values. Never renumbered.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ecdc_holdover_cause {
    /// `max_lost_cycles` cycles in a row without a complete reply.
    ECDC_HOLDOVER_SILENCE = 1,
    /// No transmission for more than `max_lost_cycles` periods.
    ECDC_HOLDOVER_STALL = 2,
    /// A cause this header predates.
    ECDC_HOLDOVER_OTHER = 255,
}

/// A fault, flattened: which fields mean something depends on `kind` (see `ecdc_fault_kind`);
/// the others are 0.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ecdc_fault {
    /// What happened.
    pub kind: ecdc_fault_kind,
    /// Step that timed out (`ECDC_FAULT_TIMEOUT`), else `ECDC_STATE_IDLE`.
    pub state: ecdc_machine_state,
    /// EtherCAT command code of the datagram (`ECDC_FAULT_WKC`).
    pub command: u8,
    /// Station address concerned (0 = broadcast or not slave specific).
    pub station: u16,
    /// Register concerned.
    pub register_: u16,
    /// Expected working counter, slave count at bring-up, or capacity.
    pub expected: u16,
    /// Working counter received, slaves answering now or found, slaves over the threshold.
    pub actual: u16,
    /// Frames (NOT_CONVERGED) or cycles (NOT_LOCKED).
    pub count: u32,
    /// Worst |Δt| or last bound, ns.
    pub diff_ns: u32,
}

/// `SLAVES_FOUND` data.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ecdc_ev_slaves_found {
    /// All slaves.
    pub count: u16,
    /// Slaves with DC and a system time.
    pub dc: u16,
}
/// `TDIFF_RESOLVED` data: how many slaves got their t_Diff from where (per-slave values:
/// `ecdc_slave_info`).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ecdc_ev_tdiff_resolved {
    /// Slaves measured themselves (forced port loop).
    pub measured: u16,
    /// Slaves given the value of a measured slave of the same ESC type and revision.
    pub same_type: u16,
    /// Slaves with a user-supplied value.
    pub configured: u16,
    /// Slaves whose measurement was wanted but not used (running network, implausible value).
    pub fallback: u16,
}
/// `DELAYS_MEASURED` data.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ecdc_ev_delays_measured {
    /// Largest delay from the reference, ns.
    pub max_delay_ns: u32,
}
/// `OFFSETS_WRITTEN` data.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ecdc_ev_offsets_written {
    /// Slaves whose 0x0920 was written.
    pub written: u16,
    /// Running slaves left alone.
    pub skipped_running: u16,
}
/// `DRIFT_CONVERGED` data.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ecdc_ev_drift_converged {
    /// FRMW frames it took.
    pub frames: u32,
    /// Worst |Δt| at the last check, ns.
    pub max_diff_ns: u32,
}
/// `SYNC_STARTED` data.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ecdc_ev_sync_started {
    /// System time of the first SYNC0 pulse, ns since 2000-01-01.
    pub start: u64,
    /// Slaves programmed.
    pub slaves: u16,
}
/// `LOCKED` data.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ecdc_ev_locked {
    /// Frames sent since start (or the last re-initialisation).
    pub frames: u64,
    /// BRD 0x092C bound at lock, ns.
    pub bound_ns: u32,
}
/// `LOCK_LOST` data.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ecdc_ev_lock_lost {
    /// BRD 0x092C bound, ns.
    pub bound_ns: u32,
}
/// `HOLDOVER_STARTED` data.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ecdc_ev_holdover_started {
    /// Master time of the first missed cycle, ns since 2000-01-01.
    pub since: u64,
    /// An `ecdc_holdover_cause` value.
    pub cause: u8,
}
/// `HOLDOVER_ENDED` data.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ecdc_ev_holdover_ended {
    /// Time from the first missed cycle to the end of the resume cycle, ns.
    pub after_ns: u64,
    /// Slaves answering in the resume cycle.
    pub slaves: u16,
    /// OR of every AL status in the resume cycle.
    pub al_status: u16,
    /// BRD 0x092C bound in the resume cycle, ns.
    pub bound_ns: u32,
}
/// `DELAYS_UPDATED` data.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ecdc_ev_delays_updated {
    /// Largest change of any slave's delay, ns.
    pub max_change_ns: u32,
}

/// The data of an event; read the member named by `ecdc_event.kind`.
#[repr(C)]
#[derive(Clone, Copy)]
pub union ecdc_event_data {
    /// `ECDC_EVENT_SLAVES_FOUND`.
    pub slaves_found: ecdc_ev_slaves_found,
    /// `ECDC_EVENT_DELAYS_MEASURED`.
    pub delays_measured: ecdc_ev_delays_measured,
    /// `ECDC_EVENT_OFFSETS_WRITTEN`.
    pub offsets_written: ecdc_ev_offsets_written,
    /// `ECDC_EVENT_DRIFT_CONVERGED`.
    pub drift_converged: ecdc_ev_drift_converged,
    /// `ECDC_EVENT_SYNC_STARTED`.
    pub sync_started: ecdc_ev_sync_started,
    /// `ECDC_EVENT_LOCKED`.
    pub locked: ecdc_ev_locked,
    /// `ECDC_EVENT_LOCK_LOST`.
    pub lock_lost: ecdc_ev_lock_lost,
    /// `ECDC_EVENT_DELAYS_UPDATED`.
    pub delays_updated: ecdc_ev_delays_updated,
    /// `ECDC_EVENT_ERROR`.
    pub error: ecdc_fault,
    /// `ECDC_EVENT_TDIFF_RESOLVED`.
    pub tdiff_resolved: ecdc_ev_tdiff_resolved,
    /// `ECDC_EVENT_HOLDOVER_STARTED`.
    pub holdover_started: ecdc_ev_holdover_started,
    /// `ECDC_EVENT_HOLDOVER_ENDED`.
    pub holdover_ended: ecdc_ev_holdover_ended,
    /// Sizes the union and zero-fills it before a member is written.
    pub raw: [u64; 4],
}

/// Length of `ecdc_event.text`, NUL included.
pub const ECDC_EVENT_TEXT_LEN: usize = 112;

/// One event from `ecdc_poll_event`: a tag, its data and a one-line description.
#[repr(C)]
#[derive(Clone, Copy)]
pub struct ecdc_event {
    /// Which member of `u` is valid.
    pub kind: ecdc_event_kind,
    /// The event's data.
    pub u: ecdc_event_data,
    /// One-line English description, NUL-terminated (truncated if longer).
    pub text: [core::ffi::c_char; ECDC_EVENT_TEXT_LEN],
}

impl ecdc_event {
    /// The empty event (`ECDC_EVENT_NONE`, zeroed data, empty text).
    pub const fn none() -> Self {
        ecdc_event {
            kind: ecdc_event_kind::ECDC_EVENT_NONE,
            u: ecdc_event_data { raw: [0; 4] },
            text: [0; ECDC_EVENT_TEXT_LEN],
        }
    }

    /// The description up to the first NUL (invalid UTF-8 replaced).
    pub fn text_string(&self) -> String {
        // `c_char` is `i8` or `u8` by target: reinterpret each as the byte it holds.
        let bytes: Vec<u8> = self
            .text
            .iter()
            .take_while(|c| **c != 0)
            .map(|c| u8::from_ne_bytes(c.to_ne_bytes()))
            .collect();
        String::from_utf8_lossy(&bytes).into_owned()
    }
}

/// Writes into a fixed byte buffer, keeping one byte for the NUL, cutting at a character
/// boundary when full.
struct TextBuf<'a> {
    buf: &'a mut [u8],
    len: usize,
}

impl core::fmt::Write for TextBuf<'_> {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        let room = self.buf.len().saturating_sub(1).saturating_sub(self.len);
        let mut take = s.len().min(room);
        while !s.is_char_boundary(take) {
            take = take.saturating_sub(1);
        }
        let (src, dst_start) = (s.as_bytes().get(..take).unwrap_or_default(), self.len);
        if let Some(dst) = self.buf.get_mut(dst_start..dst_start.saturating_add(take)) {
            dst.copy_from_slice(src);
            self.len = dst_start.saturating_add(take);
        }
        if let Some(nul) = self.buf.get_mut(self.len) {
            *nul = 0;
        }
        Ok(())
    }
}

/// The flattened fault of a core [`Error`]. Core faults added later map to `ECDC_FAULT_OTHER`.
pub fn fault_to_c(e: &Error) -> ecdc_fault {
    use ecdc_fault_kind as K;
    let mut f = ecdc_fault {
        kind: K::ECDC_FAULT_OTHER,
        state: ecdc_machine_state::ECDC_STATE_IDLE,
        command: 0,
        station: 0,
        register_: 0,
        expected: 0,
        actual: 0,
        count: 0,
        diff_ns: 0,
    };
    match *e {
        Error::Wkc {
            command,
            station,
            register,
            expected,
            actual,
        } => {
            f.kind = K::ECDC_FAULT_WKC;
            f.command = command.code();
            f.station = station;
            f.register_ = register;
            f.expected = expected;
            f.actual = actual;
        }
        Error::Timeout { state } => {
            f.kind = K::ECDC_FAULT_TIMEOUT;
            f.state = state_to_c(state);
        }
        Error::TopologyChanged { expected, found } => {
            f.kind = K::ECDC_FAULT_TOPOLOGY_CHANGED;
            f.expected = expected;
            f.actual = found;
        }
        Error::SlaveLost { station } => {
            f.kind = K::ECDC_FAULT_SLAVE_LOST;
            f.station = station;
        }
        Error::NotConverged {
            frames,
            slaves_over,
            worst_station,
            worst_diff_ns,
        } => {
            f.kind = K::ECDC_FAULT_NOT_CONVERGED;
            f.count = frames;
            f.actual = slaves_over;
            f.station = worst_station;
            f.diff_ns = worst_diff_ns;
        }
        Error::NotLocked { cycles, bound_ns } => {
            f.kind = K::ECDC_FAULT_NOT_LOCKED;
            f.count = cycles;
            f.diff_ns = bound_ns;
        }
        Error::OutOfRange { station, register } => {
            f.kind = K::ECDC_FAULT_OUT_OF_RANGE;
            f.station = station;
            f.register_ = register;
        }
        Error::Measurement { station } => {
            f.kind = K::ECDC_FAULT_MEASUREMENT;
            f.station = station;
        }
        Error::TooManySlaves { found, capacity } => {
            f.kind = K::ECDC_FAULT_TOO_MANY_SLAVES;
            f.actual = found;
            f.expected = capacity;
        }
        Error::NoSlaves => f.kind = K::ECDC_FAULT_NO_SLAVES,
        Error::NoReferenceClock => f.kind = K::ECDC_FAULT_NO_REFERENCE_CLOCK,
        Error::BufferTooSmall => f.kind = K::ECDC_FAULT_BUFFER_TOO_SMALL,
        Error::HoldoverExpired { silent_ns } => {
            f.kind = K::ECDC_FAULT_HOLDOVER_EXPIRED;
            f.count = u32::try_from(silent_ns / 1000).unwrap_or(u32::MAX);
        }
        Error::ResumeCheckFailed { failure } => {
            use ecdc_resume_failure as R;
            f.kind = K::ECDC_FAULT_RESUME_CHECK_FAILED;
            #[allow(unreachable_patterns)] // a failure added to ecdc-core maps to OTHER
            let code = match failure {
                ResumeFailure::SlaveCount { expected, found } => {
                    f.expected = expected;
                    f.actual = found;
                    R::ECDC_RESUME_SLAVE_COUNT
                }
                ResumeFailure::ReferenceWkc { expected, actual } => {
                    f.expected = expected;
                    f.actual = actual;
                    R::ECDC_RESUME_REFERENCE_WKC
                }
                ResumeFailure::SlaveLost { station } => {
                    f.station = station;
                    R::ECDC_RESUME_SLAVE_LOST
                }
                ResumeFailure::SlaveReset { al_status, before } => {
                    f.actual = al_status;
                    f.expected = before;
                    R::ECDC_RESUME_SLAVE_RESET
                }
                ResumeFailure::Bound { bound_ns } => {
                    f.diff_ns = bound_ns;
                    R::ECDC_RESUME_BOUND
                }
                _ => R::ECDC_RESUME_OTHER,
            };
            f.command = code as u8;
        }
        Error::Internal { state } => {
            f.kind = K::ECDC_FAULT_INTERNAL;
            f.state = state_to_c(state);
        }
        // `Error` is non-exhaustive: a newer core's fault keeps ECDC_FAULT_OTHER and its text.
        _ => {}
    }
    f
}

/// The C event of a core [`Event`]: the one place that maps event variants, so a variant added
/// to `ecdc-core` is added here (until then it arrives as `ECDC_EVENT_OTHER` with its text).
pub fn event_to_c(e: &Event) -> ecdc_event {
    use ecdc_event_kind as K;
    let mut out = ecdc_event::none();
    let mut text = [0u8; ECDC_EVENT_TEXT_LEN];
    let mut w = TextBuf {
        buf: &mut text,
        len: 0,
    };
    // Writing into TextBuf never fails (it truncates), so the fmt results carry nothing.
    // `out.u` starts zeroed (`none()`); each arm writes one member, so the bytes a smaller
    // member leaves stay defined for C.
    out.kind = match *e {
        Event::SlavesFound { count, dc } => {
            let _ = write!(w, "{count} slaves found, {dc} with a DC system time");
            out.u.slaves_found = ecdc_ev_slaves_found { count, dc };
            K::ECDC_EVENT_SLAVES_FOUND
        }
        Event::TdiffResolved {
            measured,
            same_type,
            configured,
            fallback,
        } => {
            let _ = write!(
                w,
                "t_Diff known: {measured} measured, {same_type} from the same ESC type, \
                 {configured} configured, {fallback} fallback"
            );
            out.u.tdiff_resolved = ecdc_ev_tdiff_resolved {
                measured,
                same_type,
                configured,
                fallback,
            };
            K::ECDC_EVENT_TDIFF_RESOLVED
        }
        Event::DelaysMeasured { max_delay_ns } => {
            let _ = write!(w, "propagation delays measured, largest {max_delay_ns} ns");
            out.u.delays_measured = ecdc_ev_delays_measured { max_delay_ns };
            K::ECDC_EVENT_DELAYS_MEASURED
        }
        Event::OffsetsWritten {
            written,
            skipped_running,
        } => {
            let _ = write!(
                w,
                "offsets written to {written} slaves, {skipped_running} running slaves left alone"
            );
            out.u.offsets_written = ecdc_ev_offsets_written {
                written,
                skipped_running,
            };
            K::ECDC_EVENT_OFFSETS_WRITTEN
        }
        Event::DriftConverged {
            frames,
            max_diff_ns,
        } => {
            let _ = write!(
                w,
                "static drift converged after {frames} frames, worst {max_diff_ns} ns"
            );
            out.u.drift_converged = ecdc_ev_drift_converged {
                frames,
                max_diff_ns,
            };
            K::ECDC_EVENT_DRIFT_CONVERGED
        }
        Event::SyncStarted { start, slaves } => {
            let start = start.as_nanos();
            let _ = write!(
                w,
                "SYNC0 programmed on {slaves} slaves, first pulse at {start} ns"
            );
            out.u.sync_started = ecdc_ev_sync_started { start, slaves };
            K::ECDC_EVENT_SYNC_STARTED
        }
        Event::Locked { frames, bound_ns } => {
            let _ = write!(
                w,
                "locked after {frames} frames, 0x092C bound {bound_ns} ns"
            );
            out.u.locked = ecdc_ev_locked { frames, bound_ns };
            K::ECDC_EVENT_LOCKED
        }
        Event::LockLost { bound_ns } => {
            let _ = write!(w, "lock lost, 0x092C bound {bound_ns} ns");
            out.u.lock_lost = ecdc_ev_lock_lost { bound_ns };
            K::ECDC_EVENT_LOCK_LOST
        }
        Event::DelaysUpdated { max_change_ns } => {
            let _ = write!(w, "delays re-measured, largest change {max_change_ns} ns");
            out.u.delays_updated = ecdc_ev_delays_updated { max_change_ns };
            K::ECDC_EVENT_DELAYS_UPDATED
        }
        Event::Error(err) => {
            let _ = write!(w, "error: {err}");
            out.u.error = fault_to_c(&err);
            K::ECDC_EVENT_ERROR
        }
        Event::Restarting => {
            let _ = write!(w, "restarting the bring-up");
            K::ECDC_EVENT_RESTARTING
        }
        Event::HoldoverStarted { since, cause } => {
            #[allow(unreachable_patterns)] // a cause added to ecdc-core maps to OTHER
            let (c, name) = match cause {
                HoldoverCause::Silence => (ecdc_holdover_cause::ECDC_HOLDOVER_SILENCE, "silence"),
                HoldoverCause::Stall => (ecdc_holdover_cause::ECDC_HOLDOVER_STALL, "stall"),
                _ => (ecdc_holdover_cause::ECDC_HOLDOVER_OTHER, "other"),
            };
            let since = since.as_nanos();
            let _ = write!(w, "hold-over ({name}) since {since} ns");
            out.u.holdover_started = ecdc_ev_holdover_started {
                since,
                cause: c as u8,
            };
            K::ECDC_EVENT_HOLDOVER_STARTED
        }
        Event::HoldoverEnded { after_ns, check } => {
            let _ = write!(
                w,
                "hold-over ended after {after_ns} ns: {} slaves, 0x092C bound {} ns",
                check.slaves, check.bound_ns
            );
            out.u.holdover_ended = ecdc_ev_holdover_ended {
                after_ns,
                slaves: check.slaves,
                al_status: check.al_status,
                bound_ns: check.bound_ns,
            };
            K::ECDC_EVENT_HOLDOVER_ENDED
        }
        // `Event` is non-exhaustive: a newer core's event arrives as OTHER with its Debug text.
        _ => {
            let _ = write!(w, "{e:?}");
            K::ECDC_EVENT_OTHER
        }
    };
    for (dst, src) in out.text.iter_mut().zip(text) {
        // `c_char` is `i8` or `u8` by target: the same byte either way.
        *dst = core::ffi::c_char::from_ne_bytes([src]);
    }
    out
}

/// Counters of `ecdc_stats` (see `ecdc_core::dc::Stats`).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ecdc_stats {
    /// Transmissions (own frames, or appends into a caller's frame).
    pub frames_sent: u64,
    /// Frames handed to `ecdc_handle_frame`.
    pub frames_received: u64,
    /// Frames with none of the machine's datagrams.
    pub foreign_frames: u64,
    /// Datagrams that matched nothing in flight.
    pub foreign_datagrams: u64,
    /// Response timeouts.
    pub timeouts: u64,
    /// Resent request chunks.
    pub retries: u64,
    /// Re-initialisations after a fault.
    pub restarts: u64,
    /// Cyclic transmissions.
    pub cycles: u64,
    /// Cycles whose DC datagrams did not come back.
    pub lost_cycles: u64,
    /// Events dropped because the queue (32) was full.
    pub events_dropped: u64,
    /// Frames from the last start to the last lock; valid when `has_lock_frames`.
    pub lock_frames: u64,
    /// Whether the machine locked since its last start.
    pub has_lock_frames: bool,
    /// Hold-overs that ended with a passed resume check.
    pub holdovers: u64,
}

/// The C view of [`Stats`].
pub fn stats_to_c(s: &Stats) -> ecdc_stats {
    ecdc_stats {
        frames_sent: s.frames_sent,
        frames_received: s.frames_received,
        foreign_frames: s.foreign_frames,
        foreign_datagrams: s.foreign_datagrams,
        timeouts: s.timeouts,
        retries: s.retries,
        restarts: s.restarts,
        cycles: s.cycles,
        lost_cycles: s.lost_cycles,
        events_dropped: s.events_dropped,
        lock_frames: s.lock_frames.unwrap_or(0),
        has_lock_frames: s.lock_frames.is_some(),
        holdovers: s.holdovers,
    }
}

/// `ecdc_slave.dc` values.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ecdc_dc_kind {
    /// No DC unit.
    ECDC_DC_NONE = 0,
    /// Receive-time latches but no system time.
    ECDC_DC_DELAY_ONLY = 1,
    /// 32-bit system time.
    ECDC_DC_32 = 2,
    /// 64-bit system time.
    ECDC_DC_64 = 3,
    /// A kind this header predates.
    ECDC_DC_OTHER = 255,
}

/// What the bring-up learnt about one slave (`ecdc_slave_info`).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ecdc_slave {
    /// Station address assigned.
    pub station: u16,
    /// ESC features register 0x0008.
    pub features: u16,
    /// DC capability.
    pub dc: ecdc_dc_kind,
    /// Propagation delay from the reference, ns (0x0928).
    pub delay_ns: u32,
    /// System time offset written to 0x0920.
    pub offset: u64,
    /// Last 0x092C reading in signed ns; valid when `has_last_diff`.
    pub last_diff_ns: i64,
    /// Whether `last_diff_ns` was read.
    pub has_last_diff: bool,
    /// Whether 0x0920 was written in the last bring-up.
    pub offset_written: bool,
    /// Whether the SYNC unit was programmed in the last bring-up.
    pub sync_programmed: bool,
    /// Whether this slave is the reference clock.
    pub is_reference: bool,
}

/// The C view of a [`SlaveInfo`].
pub fn slave_to_c(s: &SlaveInfo, is_reference: bool) -> ecdc_slave {
    #[allow(unreachable_patterns)] // a kind added to ecdc-core maps to OTHER
    let dc = match s.dc {
        DcKind::None => ecdc_dc_kind::ECDC_DC_NONE,
        DcKind::DelayOnly => ecdc_dc_kind::ECDC_DC_DELAY_ONLY,
        DcKind::Bits32 => ecdc_dc_kind::ECDC_DC_32,
        DcKind::Bits64 => ecdc_dc_kind::ECDC_DC_64,
        _ => ecdc_dc_kind::ECDC_DC_OTHER,
    };
    ecdc_slave {
        station: s.station,
        features: s.features,
        dc,
        delay_ns: s.delay_ns,
        offset: s.offset,
        last_diff_ns: s.last_diff_ns.unwrap_or(0),
        has_last_diff: s.last_diff_ns.is_some(),
        offset_written: s.offset_written,
        sync_programmed: s.sync_programmed,
        is_reference,
    }
}

/// A frame under construction in caller memory (`ecdc_frame_init`). The frame in `buf` is a
/// valid EtherCAT frame after every successful call, so the library keeps no other state:
/// `len` and `datagrams` are refreshed by every `ecdc_frame_*` / `ecdc_poll_transmit_into`
/// call for the caller to read, and ignored on input.
#[repr(C)]
#[derive(Debug)]
pub struct ecdc_frame {
    /// The caller's buffer; it must stay valid and unmoved while the frame is used.
    pub buf: *mut u8,
    /// Its size in bytes (at least 60; 1514 holds the largest frame).
    pub capacity: usize,
    /// Frame length so far without padding.
    pub len: usize,
    /// Datagrams in the frame so far.
    pub datagrams: usize,
}

/// Where a datagram pushed by `ecdc_frame_push` is, to read its reply at the same offsets in
/// the returned frame.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ecdc_datagram_slot {
    /// Offset of the datagram's header in the frame.
    pub offset: usize,
    /// Offset of its first data byte.
    pub data_offset: usize,
    /// Offset of its working counter (2 bytes, little-endian, after the data).
    pub wkc_offset: usize,
    /// Data length.
    pub len: u16,
    /// Index written into the datagram.
    pub index: u8,
}
