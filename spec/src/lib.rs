//! `ecdc-spec`: the executable specification. Plain, obviously-correct functions over wide
//! integers (i128), the register contract, and a network model; `SPEC.md` numbers the
//! requirements that code, tests and proofs cite.

pub mod servo;
