//! Fixtures shared by the criterion benches (`benches/`) and the `scale` binary.
//!
//! - [`cyclic`]: a DC [`Machine`](ecdc_core::dc::Machine) brought up on the emulator until
//!   locked, plus a ring of real request/response pairs captured from it, replayed without the
//!   emulator so a bench measures only the core's per-cycle work.
//! - [`trees`]: network-model trees (spec crate) and the `SlaveSample`s a master would read
//!   after one latch, for the delay-computation benches.
//! - [`timed`]: a bring-up driver that times the core's calls apart from the emulator's.
//! - [`provenance`]: date, commit and machine for the header of a generated result file.

pub mod cyclic;
pub mod provenance;
pub mod timed;
pub mod trees;
