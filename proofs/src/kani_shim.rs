//! Stand-in for the `kani` crate in ordinary builds, so every Kani harness in this crate
//! type-checks and *runs* here, where Kani itself cannot be installed.
//!
//! Under `cargo kani`, `cfg(kani)` is set, this module is not compiled and `kani::` names the
//! real crate: `kani::any()` is then a symbolic value covering every input. Here `kani::any()`
//! draws a pseudo-random value (biased towards boundaries: 0, 1, MAX, MIN, sign-bit
//! neighbours), `kani::assume(false)` discards the run, and `kani::cover!` records that the
//! condition was reached. [`run`] executes a harness many times; a test that runs the
//! harnesses through it is a random test, NOT a proof, and is reported as such.
//!
//! Harnesses are written as
//! `#[cfg_attr(kani, kani::proof)] #[cfg_attr(kani, kani::unwind(N))] pub fn harness() { … }`
//! so that the attributes only exist for Kani and the body is the same in both builds.

use std::cell::{Cell, RefCell};
use std::collections::BTreeMap;

thread_local! {
    static STATE: Cell<u64> = const { Cell::new(0x9E37_79B9_7F4A_7C15) };
    static COVERED: RefCell<BTreeMap<&'static str, u64>> = const { RefCell::new(BTreeMap::new()) };
}

/// Panic payload used by [`assume`] to discard a run.
struct Discard;

/// splitmix64: small, deterministic, good enough to spread test inputs.
fn next_u64() -> u64 {
    STATE.with(|s| {
        let z = s.get().wrapping_add(0x9E37_79B9_7F4A_7C15);
        s.set(z);
        let z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        let z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    })
}

/// Types `kani::any()` can produce (mirrors `kani::Arbitrary`).
pub trait Arbitrary: Sized {
    /// One value, boundary-biased.
    fn any() -> Self;
}

macro_rules! arbitrary_int {
    ($($t:ty),*) => {$(
        impl Arbitrary for $t {
            #[allow(clippy::cast_possible_truncation, clippy::cast_possible_wrap)]
            fn any() -> Self {
                let r = next_u64();
                match r % 8 {
                    0 => [0 as $t, 1 as $t, <$t>::MAX, <$t>::MIN, <$t>::MAX / 2, (<$t>::MAX / 2).wrapping_add(1), <$t>::MAX.wrapping_sub(1), <$t>::MIN.wrapping_add(1)][((r >> 8) % 8) as usize],
                    // Small magnitudes, where off-by-one errors live.
                    1 => ((r >> 8) % 16) as $t,
                    _ => (r >> 3) as $t,
                }
            }
        }
    )*};
}
arbitrary_int!(u8, u16, u32, u64, usize, i8, i16, i32, i64, isize);

impl Arbitrary for bool {
    fn any() -> Self {
        next_u64() & 1 == 1
    }
}

impl<T: Arbitrary> Arbitrary for Option<T> {
    fn any() -> Self {
        if next_u64() & 3 == 0 {
            None
        } else {
            Some(T::any())
        }
    }
}

impl<T: Arbitrary, const N: usize> Arbitrary for [T; N] {
    fn any() -> Self {
        core::array::from_fn(|_| T::any())
    }
}

/// `kani::any()`.
pub fn any<T: Arbitrary>() -> T {
    T::any()
}

/// `kani::any_where(f)`: retries a bounded number of times, then discards the run.
pub fn any_where<T: Arbitrary, F: Fn(&T) -> bool>(f: F) -> T {
    for _ in 0..64 {
        let v = T::any();
        if f(&v) {
            return v;
        }
    }
    std::panic::panic_any(Discard)
}

/// `kani::assume(cond)`: a false assumption discards this run (Kani prunes the path).
pub fn assume(cond: bool) {
    if !cond {
        std::panic::panic_any(Discard)
    }
}

/// Records a reached `kani::cover!` (used by the macro).
pub fn record_cover(msg: &'static str, hit: bool) {
    if hit {
        COVERED.with(|c| *c.borrow_mut().entry(msg).or_insert(0) += 1);
    }
}

/// `kani::cover!(cond, "msg")`: records that `cond` was true at least once.
#[macro_export]
macro_rules! kani_shim_cover {
    ($cond:expr, $msg:literal) => {
        $crate::kani_shim::record_cover($msg, $cond)
    };
    ($cond:expr) => {
        $crate::kani_shim::record_cover(stringify!($cond), $cond)
    };
}
pub use crate::kani_shim_cover as cover;

/// Outcome of [`run`].
#[derive(Debug)]
pub struct Report {
    /// Runs that completed.
    pub passed: u64,
    /// Runs discarded by `assume`.
    pub discarded: u64,
    /// `cover!` messages reached, with counts.
    pub covered: BTreeMap<&'static str, u64>,
}

/// Runs `harness` `iterations` times with the given seed. A failing assertion propagates
/// (the calling test fails with the harness's own message); `assume(false)` is counted.
pub fn run(seed: u64, iterations: u64, harness: fn()) -> Report {
    STATE.with(|s| s.set(seed));
    COVERED.with(|c| c.borrow_mut().clear());
    let mut passed = 0;
    let mut discarded = 0;
    // Discarded runs print a panic line into the (captured) test output; that is harmless and
    // avoids touching the process-global panic hook while tests run in parallel.
    for _ in 0..iterations {
        match std::panic::catch_unwind(harness) {
            Ok(()) => passed += 1,
            Err(p) if p.downcast_ref::<Discard>().is_some() => discarded += 1,
            Err(p) => std::panic::resume_unwind(p),
        }
    }
    let covered = COVERED.with(|c| c.borrow().clone());
    Report {
        passed,
        discarded,
        covered,
    }
}

/// Runs each of `harnesses` `iterations` times (seeds `seed`, `seed + 1`, … in order) and
/// panics unless each passes more than `min_passed` runs and reaches at least one `cover!`, so
/// a harness cannot silently test nothing. Returns the reports by harness name.
pub fn run_all(
    harnesses: &[(&'static str, fn())],
    seed: u64,
    iterations: u64,
    min_passed: u64,
) -> Vec<(&'static str, Report)> {
    let mut reports = Vec::with_capacity(harnesses.len());
    for (i, &(name, h)) in harnesses.iter().enumerate() {
        let r = run(seed + i as u64, iterations, h);
        assert!(
            r.passed > min_passed,
            "{name}: only {} runs passed ({} discarded)",
            r.passed,
            r.discarded
        );
        assert!(!r.covered.is_empty(), "{name}: no cover! reached: {r:?}");
        reports.push((name, r));
    }
    reports
}
