//! Positional command-line arguments of the peer drivers that take `IFACE [SECONDS]
//! [CYCLE_US]`. Each peer is its own Cargo workspace, so they include this file with
//! `#[path]` rather than share a crate.

/// Positional argument `i` (as `std::env::args` counts, 1 = the first after the program name)
/// parsed as `T`, or `default` when it is absent.
pub fn arg<T: std::str::FromStr>(i: usize, default: T) -> Result<T, String> {
    match std::env::args().nth(i) {
        None => Ok(default),
        Some(s) => s
            .parse()
            .map_err(|_| format!("argument {i}: cannot parse {s:?}")),
    }
}
