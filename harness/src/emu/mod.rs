//! The ESC emulator: a deterministic, event-driven EtherCAT slave chain with Distributed Clocks.
//!
//! Everything ecdc claims about DC precision, lock time and fault handling is measured here,
//! so the model follows the ESC register and timing contract in `spec/req/esc.md`
//! (REQ-ESC-nnn) and documents every constant without a source in `docs/emulator.md`.
//!
//! # Time
//! [`TrueTime`] is `u64` nanoseconds since the start of the run (the analyzer's clock, not any
//! slave's). Nothing sleeps: time only moves when the caller sends a frame, advances, or
//! samples. Each slave's local time is a piecewise-linear function of true time evaluated in
//! closed form and quantised to 10 ns where observed.
//!
//! # Public API (small and stable)
//! - [`Scenario`]: topology, delays, crystal errors, faults, seed; `Scenario::line(n)`,
//!   `from_toml_str`, `from_json_str`, `load(path)`; builder methods `with_slave`,
//!   `with_fault`, `ideal`.
//! - [`Network::new`]`(&scenario)`, then
//!   - [`Network::transact`]`(frame, send_time) -> Delivery` — the frame comes back processed
//!     at a later true time, or is lost (with the reason);
//!   - [`Network::advance_to`]`(t)` — time passes without frames (SYNC pulses keep coming);
//!   - [`Network::clock`]`(slave, t)` — local time and local copy of system time at `t`;
//!   - [`Network::take_sync_edges`]`()` — every SYNC0/SYNC1 edge up to now, in true time;
//!   - [`Network::schedule_fault`]`(t, fault)` — inject a [`Fault`] at a true time;
//!   - observers: `slave_info`, `oscillator_ppb`, `peek`, `esc`, `epu_arrival_times`, `stats`;
//!     per slave [`Network::identity`] (from its SII EEPROM), [`Network::al_state`],
//!     [`Network::process_image`], [`Network::sii_image`].
//!
//! ```
//! use ecdc_harness::emu::{Network, Scenario};
//! let mut net = Network::new(&Scenario::line(3)).unwrap();
//! net.advance_to(1_000_000).unwrap();
//! let c = net.clock(2, 1_000_000).unwrap();
//! assert!(c.system_time.is_some());
//! ```
//!
//! # Layout (one concept per file)
//! - `oscillator.rs`: drifting crystal, wander, loop correction, quantisation, inversion.
//! - `control_loop.rs`: 0x092C/0x0932 filters and the rate-correction law.
//! - `registers.rs`: register map, widths, access rules, reset values, chip variants.
//! - `sync_unit.rs`: SYNC0/SYNC1 activation, start time, cycles.
//! - `datagram.rs`: how the hardware walks the datagrams of a frame.
//! - `esc.rs`: one ESC: EPU command semantics, WKC/ADP, latches, lazy per-ESC time.
//! - `sii.rs`: the SII EEPROM image (CRC, categories, identity) and its 0x0500 interface.
//! - `device.rs`: the device behind the ESC (`bare`, `io8`, `servo`): built SII images,
//!   SyncManager layout, the application's data path.
//! - `al.rs`: AL control/status/status code, SyncManager checks at the transitions.
//! - `process_data.rs`: SyncManager gating of logical access, the process image.
//! - `topology.rs`: tree, cables, time-indexed link and power state.
//! - `network/`: the chain: the frame path (`frame.rs`), the walk 0→EPU→3→1→2→0 (`walk.rs`),
//!   faults (`faults.rs`), the SYNC edge log (`edge_log.rs`), observers (`mod.rs`).
//! - `scenario.rs`, `fault.rs`: the serde description of a run.
//! - `yardstick.rs`: true-time DC measurement from the observers (skew, lock, clock error),
//!   shared by `ecdc simulate` and `ecdc emulate`.
//!
//! # What is not modelled
//! See docs/emulator.md §"Not modelled": the latch unit inputs (0x09A8.. registers exist with
//! reset values only), mailbox traffic (a mailbox can be configured, nothing answers
//! on it), SyncManager three-buffer exchange, EtherCAT-over-UDP, redundancy (a second
//! master port), ET1200 "arm then stamp" receive-time behaviour, 0x0936 reverse mode, FMMU
//! bit granularity, PDI access.

pub mod al;
pub mod control_loop;
pub mod datagram;
pub mod device;
pub mod esc;
pub mod fault;
pub mod network;
pub mod oscillator;
pub mod process_data;
pub mod registers;
pub mod scenario;
pub mod sii;
pub mod sync_unit;
pub mod topology;
pub mod yardstick;

pub use control_loop::LoopGains;
pub use device::Device;
pub use esc::SyncEdge;
pub use fault::{Fault, FaultSpec};
pub use network::{ClockSample, Delivery, LossReason, Network, Returned, SlaveInfo, Stats};
pub use process_data::ProcessImage;
pub use registers::EscKind;
pub use scenario::{
    PpmSpec, Scenario, SlaveDefaults, SlaveSpec, Timing, SEED000_TABLE2_DELAYS_NS, SEED000_T_F_NS,
    SEED000_T_P_NS,
};
pub use sii::{Identity, SiiError, SiiImage, SiiTiming};
pub use sync_unit::SyncSignal;

/// True (analyzer) time: nanoseconds since the start of the run.
pub type TrueTime = u64;

/// Errors of the emulator API (misuse or a bad scenario). Frames never produce errors: a
/// malformed frame is forwarded unprocessed, as a slave would.
#[derive(Debug, Clone, PartialEq)]
pub enum EmuError {
    /// The requested time is before the network's (or that slave's) current time.
    TimeInPast { t: TrueTime, now: TrueTime },
    /// No slave with this index.
    NoSuchSlave(usize),
    /// No cable at this port.
    NoSuchPort { slave: usize, port: u8 },
    /// This fault can only be given in the scenario (it sets the initial state).
    NotSchedulable,
    /// The scenario is invalid (message says why).
    Scenario(String),
    /// A slave's SII image file cannot be used.
    Sii { slave: usize, error: SiiError },
}

impl core::fmt::Display for EmuError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            EmuError::TimeInPast { t, now } => {
                write!(f, "time {t} ns is before the current time {now} ns")
            }
            EmuError::NoSuchSlave(i) => write!(f, "no slave {i}"),
            EmuError::NoSuchPort { slave, port } => {
                write!(f, "slave {slave} has no cable at port {port}")
            }
            EmuError::NotSchedulable => {
                write!(f, "this fault can only be given in the scenario")
            }
            EmuError::Scenario(m) => write!(f, "invalid scenario: {m}"),
            EmuError::Sii { slave, error } => write!(f, "invalid scenario: slave {slave}: {error}"),
        }
    }
}

impl std::error::Error for EmuError {}
