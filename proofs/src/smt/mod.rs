//! SMT layer: the `ecdc_core::num` kernels instantiated with z3 bit-vectors (feature `smt`).
//!
//! [`Sym<N>`] implements `ecdc_core::num::Word` with one SMT-LIB operator per method, so calling
//! a kernel on `Sym` values builds the formula of *our* code, not of a copy. [`props`] states
//! each kernel's requirement over wider bit-vectors (so "true" values cannot wrap) and
//! [`prove`] asks z3 for a counterexample: `unsat` means the property holds for all 2^N… inputs.
//!
//! Faithfulness of the wrapper itself is checked by `proofs/tests/smt.rs`
//! (`wrapper_matches_machine_words`): every method on constant operands, simplified by z3, must
//! equal the `u32`/`u64` method. Two deliberate gaps, both outside every kernel's precondition:
//! `urem` by 0 (machine: 0, SMT-LIB: the dividend) and shifts by ≥ N (machine: amount mod N).

pub mod props;
pub mod walk;
mod word;

pub use word::{ctx, with_abstract_urem, Sym, SymBool, UremRecord};

use std::time::{Duration, Instant};
use z3::{ast::Bool, Params, SatResult, Solver, Tactic};

/// Outcome of one proof attempt.
#[derive(Debug)]
pub enum Verdict {
    /// No counterexample exists (the negated claim is unsat).
    Proved(Duration),
    /// z3 found a counterexample (model shown).
    Refuted(String),
    /// z3 gave up (timeout or incompleteness), with its reason.
    Unknown(String),
}

/// Timeout of the default-solver attempt. The slowest proof kept in CI (`earliest`, 4 ports at
/// 32 bits) takes about 20 s on this machine under load.
pub const TIMEOUT_MS: u32 = 240_000;
/// Budget of the bit-blasting attempt before falling back to the default solver.
pub const BITBLAST_MS: u32 = 30_000;

/// Proves `claim` under `pre` (`pre ⇒ claim` for all values of the free constants), and also
/// checks that `pre` is satisfiable, so a contradictory precondition cannot prove anything.
///
/// Each check uses a fresh solver (z3's incremental mode is much slower on bit-vectors). The
/// main check first runs the eager bit-blasting pipeline `simplify; solve-eqs; bit-blast; sat`
/// (fastest on these goals), then z3's default solver if that gives up.
pub fn prove(pre: &Bool<'static>, claim: &Bool<'static>) -> Verdict {
    let start = Instant::now();
    let c = ctx();
    let sat_pre = {
        let s = Solver::new(c);
        s.set_params(&timeout_params(TIMEOUT_MS));
        s.assert(pre);
        (s.check(), s.get_reason_unknown())
    };
    match sat_pre {
        (SatResult::Sat, _) => {}
        (SatResult::Unsat, _) => {
            return Verdict::Refuted("precondition is unsatisfiable (vacuous)".into())
        }
        (SatResult::Unknown, r) => return Verdict::Unknown(r.unwrap_or_default()),
    }
    let bitblast = ["solve-eqs", "bit-blast", "sat"]
        .iter()
        .fold(Tactic::new(c, "simplify"), |t, n| {
            t.and_then(&Tactic::new(c, n))
        })
        .solver();
    let mut last = String::new();
    for (solver, budget) in [(bitblast, BITBLAST_MS), (Solver::new(c), TIMEOUT_MS)] {
        solver.set_params(&timeout_params(budget));
        solver.assert(pre);
        solver.assert(&claim.not());
        match solver.check() {
            SatResult::Unsat => return Verdict::Proved(start.elapsed()),
            SatResult::Sat => {
                return Verdict::Refuted(
                    solver
                        .get_model()
                        .map(|m| m.to_string())
                        .unwrap_or_default(),
                )
            }
            SatResult::Unknown => last = solver.get_reason_unknown().unwrap_or_default(),
        }
    }
    Verdict::Unknown(last)
}

fn timeout_params(ms: u32) -> Params<'static> {
    let mut params = Params::new(ctx());
    params.set_u32("timeout", ms);
    params
}
