//! The targets `ecdc bench dc --check` holds ecdc to (docs/bench.md "--check"). `simulate
//! --check` uses the targets its report states ([`crate::report::Report`]).

use super::bench::{DcReport, ScenarioResult};

/// Largest steady-state SYNC0 skew ecdc may show in any bench scenario, ns: the lock bound of
/// the report's own lock definition (every slave within 100 ns of the reference), so a
/// scenario passes only if every pulse pair in the window stayed inside it.
pub const BENCH_SKEW_MAX_NS: u64 = 100;

/// Fraction of the run after which a lock counts as too late (the `*` of the bench tables:
/// it held only until the end of the run).
pub const BENCH_LATE_LOCK: f64 = 0.9;

/// The targets ecdc missed in one scenario (empty = all met; nothing when ecdc did not run).
pub fn bench_scenario(r: &ScenarioResult) -> Vec<String> {
    let Some(e) = r.schemes.iter().find(|s| s.name == "ecdc") else {
        return Vec::new();
    };
    let mut missed = Vec::new();
    let at = |what: String| format!("{}: ecdc {what}", r.name);
    if let Some(err) = &e.error {
        missed.push(at(format!("stopped early ({err})")));
    }
    match e.lock_ms {
        None => missed.push(at("never locked".into())),
        Some(ms) if ms * 1e6 > BENCH_LATE_LOCK * r.duration_ns as f64 => missed.push(at(format!(
            "locked only at {ms:.1} ms, in the last 10 % of the run"
        ))),
        Some(_) => {}
    }
    if e.sync0_slaves < r.dc_slaves {
        missed.push(at(format!(
            "SYNC0 fired on {} of {} DC slaves in the window",
            e.sync0_slaves, r.dc_slaves
        )));
    }
    match e.skew.max_ns {
        None => missed.push(at("no SYNC0 skew samples in the window".into())),
        Some(m) if m > BENCH_SKEW_MAX_NS => {
            missed.push(at(format!("skew max {m} ns > {BENCH_SKEW_MAX_NS} ns")))
        }
        Some(_) => {}
    }
    missed
}

/// The targets ecdc missed over the whole report.
pub fn bench(rep: &DcReport) -> Vec<String> {
    rep.scenarios.iter().flat_map(bench_scenario).collect()
}
