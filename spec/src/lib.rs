//! `ecdc-spec`: the executable specification. Plain, obviously-correct functions over wide
//! integers (i128), the register contract, and a network model; `SPEC.md` numbers the
//! requirements that code, tests and proofs cite.
//!
//! - [`seed000`]: IgH DC compensation paper, eq. 1–25, written literally (with its errata noted).
//! - [`seed003`]: TwinCAT DC paper, eq. 1–6.
//! - [`esc_dc`]: the ESC datasheet's general tree delay formulas (docs/background/esc-registers.md §5).
//! - [`register`]: what an ESC does with 0x0910/0x0920/0x0928/0x0990 (the contract DC maths relies on).
//! - [`network`]: a simulation-by-definition of a latch frame walking a tree of ESCs; the oracle
//!   for propagation delays, receive times and offsets.
//! - [`servo`]: servo specification.
//! - [`machine_model`]: reference model of the DC machine's observable contract (states,
//!   allowed requests per state, events after responses).

pub mod esc_dc;
pub mod machine_model;
pub mod network;
pub mod register;
pub mod seed000;
pub mod seed003;
pub mod servo;
