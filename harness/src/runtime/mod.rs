//! The Linux raw-socket runtime: drives real or emulated slaves over `AF_PACKET`.
//!
//! Layers, outermost first:
//! - [`sys`]: every libc call (the harness's only `unsafe`, each with a `SAFETY` comment);
//! - [`errors`]: errors worded as the fix a user must apply;
//! - [`socket`]: the raw socket bound to 0x88A4 on one interface, and the [`socket::Link`]
//!   trait tests replace with an in-memory link;
//! - [`transport`]: index-matched request/response with per-kind frame accounting;
//! - [`clock`]: `CLOCK_MONOTONIC` nanoseconds and absolute-deadline sleeps;
//! - [`rt`]: SCHED_FIFO, mlockall, `/dev/cpu_dma_latency`, pinning, degrading to warnings;
//! - [`stats`]: allocation-free histograms and per-second rms/max windows;
//! - [`cyclic`]: the fixed-period loop with its per-second stats line;
//! - [`bringup`]: drives the DC machine's request steps up to delays (scan) or cyclic (run);
//! - [`dc_task`]: the machine + master-follows-reference servo as the cyclic loop's task;
//! - [`capture_link`]: records every frame sent and received into a pcap file;
//! - [`emu_link`]: an in-memory link to the ESC emulator in real time, for tests;
//! - [`serve`]: the slave side (`ecdc emulate`): answer masters' frames in real time.
//!
//! See `docs/runtime.md` for the design and measured round trips.

pub mod bringup;
pub mod capture_link;
pub mod clock;
pub mod cyclic;
pub mod dc_task;
pub mod emu_link;
pub mod errors;
pub mod rt;
pub mod serve;
pub mod socket;
pub mod stats;
pub mod sys;
pub mod transport;
