//! One module per `ecdc` subcommand; `src/bin/ecdc.rs` only parses arguments and dispatches.

pub mod decode;
