//! The `main` of the ethercrab-based peer drivers. Each peer is its own Cargo workspace, so
//! they include this file with `#[path]` rather than share a crate.

/// Initialises env_logger (level `default_level` unless `RUST_LOG` says otherwise), then runs
/// `run`; on an error prints `name: error` and exits with status 1.
pub fn logged_main(name: &str, default_level: &str, run: impl FnOnce() -> Result<(), String>) {
    env_logger::Builder::from_env(env_logger::Env::default().default_filter_or(default_level))
        .init();
    if let Err(e) = run() {
        eprintln!("{name}: {e}");
        std::process::exit(1);
    }
}
