//! `ecdc-proofs`: property bodies shared by Kani harnesses (`#[cfg(kani)]`), property tests,
//! exhaustive/SMT checks and fuzz targets. One body per property (see `docs/verification.md`).
//!
//! Harnesses are plain `pub fn`s marked `#[cfg_attr(kani, kani::proof)]`; in ordinary builds
//! `kani::` resolves to [`kani_shim`] (write `#[cfg(not(kani))] use crate::kani_shim as kani;`
//! in the area module), so every harness compiles here and can be run with random inputs.
//! The SMT layer ([`smt`], feature `smt`) instantiates `ecdc_core::num` kernels with z3
//! bit-vectors so the solver checks the shipped code.

pub mod clocks;
pub mod dc_math;
#[cfg(not(kani))]
pub mod kani_shim;
pub mod machine;
pub mod model;
pub mod num;
pub mod servo;
#[cfg(feature = "smt")]
pub mod smt;
pub mod wire;
