//! Distributed Clocks: the pure maths (topology, propagation delays, offsets, SYNC start) and
//! the sans-IO bring-up and cyclic state machine.
//!
//! Pipeline: discover → latch receive times → delays → offsets → static drift compensation →
//! SYNC0/SYNC1 start → cyclic drift compensation and monitoring.

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
pub mod machine;
mod measure;
mod monitor;
mod phase;
mod remeasure;
mod request;
mod scratch;
pub mod slave;
pub mod state;
pub mod stations;
mod steps;
pub mod tdiff;
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
