//! `ecdc-core`: the EtherCAT Distributed Clocks protocol core.
//!
//! No I/O, no clock reads, no allocation: time is always passed in, frames are read from and
//! written into caller-owned buffers, and capacity is fixed by const generics. Every public
//! function returns a typed error or a defined recovery for bad input; none of them panics.
//! Requirement ids (`REQ-…`) refer to `spec/SPEC.md`.
//!
//! Data path, outermost first:
//! - [`wire`]: zero-copy views over Ethernet / EtherCAT frames and datagrams, a frame builder,
//!   typed register codecs.
//! - [`time`]: system time, port (latch) time, wrap-safe differences, phase folding.
//! - [`dc`]: DC maths (topology, propagation delays, offsets) and the sans-IO bring-up and
//!   cyclic state machine.
//! - [`servo`]: clock servos (master-follows-reference PI, IEEE 1588 math, seed 004 filters).
//!
//! # Example: the whole DC bring-up and cyclic loop
//!
//! The machine never does I/O: the host sends what [`dc::Machine::poll_transmit`] writes,
//! hands every received frame to [`dc::Machine::handle_frame`] and sleeps until
//! [`dc::Machine::poll_timeout`]. Time is the master's clock in ns since 2000-01-01
//! ([`time::SystemTime`], spec/SPEC.md REQ-CONV-002). The three host functions below stand for
//! a raw socket and a clock; `harness/src/runtime/` is the Linux AF_PACKET version of this loop.
//!
//! ```no_run
//! use ecdc_core::dc::{Config, Event, Machine};
//! use ecdc_core::time::SystemTime;
//!
//! # fn now() -> SystemTime { SystemTime::from_nanos(0) }
//! # fn send(_frame: &[u8]) {}
//! # fn try_recv(_buf: &mut [u8]) -> Option<usize> { None }
//! # fn sleep_until(_t: SystemTime) {}
//! # fn main() -> Result<(), ecdc_core::dc::ConfigError> {
//! // Capacity for 64 slaves, fixed at compile time: no allocation, ever.
//! let mut dc = Machine::<64>::new(Config::default())?;
//! dc.start(now());
//! let mut tx = [0u8; 1514];
//! let mut rx = [0u8; 1514];
//! loop {
//!     while let Some(len) = dc.poll_transmit(now(), &mut tx) {
//!         send(tx.get(..len).unwrap_or_default());
//!     }
//!     while let Some(len) = try_recv(&mut rx) {
//!         dc.handle_frame(now(), rx.get(..len).unwrap_or_default());
//!     }
//!     while let Some(ev) = dc.poll_event() {
//!         if let Event::Locked { frames, .. } = ev {
//!             // SYNC0 runs and every slave is within the lock bound.
//!             let _ = frames;
//!         }
//!     }
//!     if let Some(deadline) = dc.poll_timeout() {
//!         sleep_until(deadline);
//!         dc.handle_timeout(now());
//!     }
//! }
//! # }
//! ```
//!
//! In a cyclic master, [`dc::Machine::poll_transmit_into`] appends the DC datagrams (one FRMW
//! to 0x0910 plus monitoring reads) to the frame that already carries the process data.
//!
//! # Stability
//!
//! The public API follows semantic versioning from 1.0; before it, a minor release
//! (0.x → 0.(x+1)) may break the API and a patch release never does. CHANGELOG.md lists
//! every change. The minimum supported Rust version is the `rust-version` in Cargo.toml,
//! checked in CI by building this crate with exactly that toolchain; raising it is a minor
//! release.
#![no_std]
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![deny(
    clippy::indexing_slicing,
    clippy::arithmetic_side_effects,
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::unreachable,
    clippy::cast_possible_truncation
)]
#![cfg_attr(
    test,
    allow(
        clippy::indexing_slicing,
        clippy::arithmetic_side_effects,
        clippy::unwrap_used,
        clippy::expect_used,
        clippy::panic,
        clippy::cast_possible_truncation
    )
)]

#[cfg(any(test, feature = "std"))]
extern crate std;

pub mod dc;
#[cfg(test)]
mod digest;
pub mod num;
pub mod servo;
pub mod time;
pub mod wire;
