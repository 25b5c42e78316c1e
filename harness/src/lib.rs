//! `ecdc-harness`: everything with I/O or `std` around the core: the ESC emulator, the
//! deterministic simulation driver, pcap capture, the Linux raw-socket runtime and the CLI.
//!
//! - [`emu`]: the ESC emulator (slave chain with drifting clocks, DC registers, SYNC, faults).
//! - [`capture`]: pcap and pcapng writing and reading.
//! - [`runtime`]: the Linux AF_PACKET transport and cyclic loop.
//! - [`cli`]: one module per `ecdc` subcommand.
//! - [`schemes`]: the DC masters `ecdc simulate` compares (ecdc, seed 000, uncompensated) and
//!   the true-time recorder; [`report`]: its JSON, text and SVG output.

#![deny(unsafe_code)] // the only exception is runtime/sys.rs (raw socket and scheduling syscalls)

pub mod capture;
pub mod cli;
pub mod emu;
pub mod report;
pub mod runtime;
pub mod schemes;
pub mod sim;
