//! One module per `ecdc` subcommand; `src/bin/ecdc.rs` only parses arguments and dispatches.

pub mod bench;
pub mod check;
pub mod decode;
pub mod emulate;
pub mod link_args;
pub mod rtt;
pub mod run;
pub mod scan;
pub mod sensitivity;
pub mod simulate;
pub mod soak;
pub mod validate;
