//! Distributed Clocks: the pure maths (topology, propagation delays, offsets, SYNC start) and
//! the sans-IO bring-up and cyclic state machine.
//!
//! Pipeline: discover → latch receive times → delays → offsets → static drift compensation →
//! SYNC0/SYNC1 start → cyclic drift compensation and monitoring.
//!
//! The machine ([`Machine`], `machine.rs`) is its phase and the parts every phase shares:
//!
//! - `phase.rs`: the `Phase` enum, one variant per phase holding that phase's own data (the
//!   drift gate, cyclic operation's bookkeeping), with typed steps; [`State`] (`state.rs`) is
//!   its observable projection and the one transition table;
//! - the shared parts (`shared.rs`): configuration, the line (`line.rs`: slave table,
//!   reference, running domain, SYNC start), the in-flight table (`request.rs`), the timer
//!   table (`timer.rs`), events (`event.rs`), counters, restart bookkeeping, and the tables too
//!   large for a phase value (`measure.rs`'s latch rounds, `tdiff.rs`'s plan, `scratch.rs`);
//! - request steps (`steps.rs` dispatches by phase; `work.rs` maps items to slaves): discovery
//!   (`discovery.rs`, `stations.rs`), t_Diff (`tdiff.rs`), delays (`measure.rs`), offsets
//!   (`adjust.rs`), drift (`drift.rs`), SYNC (`activation.rs`); `bridge.rs` feeds the replies to
//!   the pure maths below;
//! - cyclic operation (`cyclic.rs`, run through a `CyclicCx`: its data and the shared parts),
//!   its fast paths (`cyclic_fast.rs`, `monitor.rs`), lock hysteresis (`lock.rs`), hold-over
//!   (`holdover.rs`) and delay re-measurement (`remeasure.rs`).

// --- DC maths: pure functions the machine calls ---
pub mod delay;
pub mod offset;
pub mod port;
pub mod sync;
pub mod topology;

// --- state machine ---
mod activation;
mod adjust;
mod bridge;
pub mod config;
#[cfg(any(test, feature = "verification"))]
pub mod control;
mod cyclic;
mod cyclic_fast;
mod discovery;
mod drift;
pub mod error;
pub mod event;
pub mod holdover;
mod line;
mod lock;
pub mod machine;
mod measure;
mod monitor;
mod phase;
mod remeasure;
mod request;
mod scratch;
mod shared;
pub mod slave;
pub mod state;
pub mod stations;
mod steps;
pub mod tdiff;
#[cfg(test)]
mod testing;
#[cfg(test)]
mod tests;
mod timer;
mod work;

pub use config::{
    Config, ConfigError, DriftCheck, DriftCommand, DriftConfig, MonitorConfig, SyncConfig,
    TdiffConfig, TdiffMode, TdiffType,
};
#[cfg(any(test, feature = "verification"))]
pub use control::ControlState;
pub use error::Error;
pub use event::Event;
pub use holdover::{HoldoverCause, ResumeCheck, ResumeFailure};
pub use machine::{Machine, Stats};
pub use request::MAX_INFLIGHT;
pub use slave::{DcKind, SlaveInfo};
pub use state::State;
pub use stations::Stations;
pub use tdiff::{TdiffFallback, TdiffSource};
