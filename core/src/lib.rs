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
#![no_std]
#![forbid(unsafe_code)]
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
pub mod num;
pub mod servo;
pub mod time;
pub mod wire;
