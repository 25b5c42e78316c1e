//! `ecdc-proofs`: property bodies shared by Kani harnesses (`#[cfg(kani)]`), property tests,
//! exhaustive/SMT checks and fuzz targets. One body per property (see `docs/verification.md`).

pub mod dc_math;
pub mod machine;
pub mod servo;
pub mod wire;
