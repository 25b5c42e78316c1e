//! Property bodies for the servo area: P5 (REQ-SERVO-012/013/031/040/041) and the servo
//! requirements that have a crisp logical statement (REQ-SERVO-002, -060, -102).
//!
//! Each body takes concrete inputs and panics with a message on a violation. They are driven by
//! `proofs/tests/servo.rs` (proptest, plus the Kani harnesses below run under the random
//! `kani_shim`) and, for users with Kani installed, by the `#[kani::proof]` harnesses at the end
//! (symbolic inputs). Kani is not available on this project's build machine: the harnesses
//! have been *run* only under the shim, never model-checked.
//!
//! verifies: P5, REQ-SERVO-002, REQ-SERVO-012

use ecdc_core::servo::carry::{Carry, CARRY_X_MAX};
use ecdc_core::servo::counter::CounterCompensator;
use ecdc_core::servo::engine::{Input, Servo, ServoConfig};
use ecdc_core::servo::filter::{OffsetFilter, FILTER_FRAC, FILTER_X_MAX};
use ecdc_core::servo::gains::PiGains;
use ecdc_core::servo::lock::{LockConfig, LockDetector};
use ecdc_core::servo::master::{MasterInput, MasterServo};
use ecdc_core::servo::pi::{pi_step, PiLimits, PiStep, THETA_MAX};
use ecdc_core::servo::Verdict;
use ecdc_spec::servo as spec;

/// P5 one-step inductive bound for the PI kernel (REQ-SERVO-012/013): for admissible gains and
/// limits, |I| ≤ I_max and any θ ⇒ |y| ≤ y_max and |I'| ≤ I_max; and the kernel's i64 result
/// equals the i128 rule of the spec, so no intermediate wrapped. Inadmissible gains or limits
/// are skipped (their refusal is [`prop_gains_sound`]'s business).
pub fn prop_pi_step_bounded(kp: i64, ki: i64, y_max: i64, i_max: i64, i: i64, theta: i64) {
    let (Ok(g), Ok(lim)) = (PiGains::from_q32(kp, ki), PiLimits::from_q32(y_max, i_max)) else {
        return;
    };
    if i.unsigned_abs() > i_max.unsigned_abs() {
        return; // outside the induction hypothesis
    }
    let s = pi_step(g, lim, i, theta);
    assert!(s.y.abs() <= y_max, "|y| = {} > y_max = {y_max}", s.y);
    assert!(
        s.integrator.abs() <= i_max,
        "|I'| = {} > I_max = {i_max}",
        s.integrator
    );
    // The i64 result is the i128 rule's, so no intermediate wrapped.
    prop_pi_step_matches_spec(kp, ki, y_max, i_max, i, theta);
}

/// A kernel step as the spec states it: (y, I', saturated) in i128.
fn widened(s: PiStep) -> (i128, i128, bool) {
    (i128::from(s.y), i128::from(s.integrator), s.saturated)
}

/// P5 overflow side-conditions of the kernel, stated with checked arithmetic: with admissible
/// gains, |θ| ≤ THETA_MAX and |I| ≤ I_max ≤ 2^60, every intermediate of `pi_step` is
/// representable (this is the bound list in `core/src/servo/pi.rs`).
pub fn prop_pi_intermediates_fit(kp: i64, ki: i64, i_max: i64, i: i64, theta: i64) {
    let (Ok(g), Ok(lim)) = (PiGains::from_q32(kp, ki), PiLimits::from_q32(i_max, i_max)) else {
        return;
    };
    let th = theta.clamp(-THETA_MAX, THETA_MAX);
    let i = i.clamp(-lim.i_max(), lim.i_max());
    let p = g.kp().checked_mul(th).expect("Kp·θ overflows");
    let inc = g.ki().checked_mul(th).expect("Ki·θ overflows");
    let v = p.checked_add(i).and_then(|x| x.checked_add(inc));
    assert!(v.is_some(), "Kp·θ + I + Ki·θ overflows");
    assert!(i.checked_add(inc).is_some(), "I + Ki·θ overflows");
}

/// P5 for whole input sequences through the engine: every command and integrator stays within
/// its clamp whatever the samples, losses, times and errors (REQ-SERVO-012).
pub fn prop_engine_bounded(cfg: ServoConfig, inputs: &[(bool, u64, i64)]) {
    let Ok(mut s) = Servo::new(cfg) else {
        return;
    };
    let mut twin = s; // REQ-SERVO-090: a copy fed the same inputs must agree bit for bit
    let (y_max, i_max) = (cfg.limits.y_max(), cfg.limits.i_max());
    let mut since_step: Option<u32> = None;
    for &(present, t, theta) in inputs {
        let input = if present {
            Input::Sample {
                local_ns: t,
                theta_ns: theta,
            }
        } else {
            Input::Missing
        };
        let i_before = s.integrator_q32();
        let out = s.update(input);
        assert_eq!(out, twin.update(input), "non-deterministic update");
        assert!(
            out.command_q32.abs() <= y_max,
            "command {}",
            out.command_q32
        );
        assert!(out.integrator_q32.abs() <= i_max);
        assert!(s.integrator_q32().abs() <= i_max);
        // REQ-SERVO-080/081: a step comes only with the Stepped verdict, leaves I unchanged,
        // and is followed by at least `blank` samples that are not used.
        let used = out.verdict == Verdict::Accepted;
        if out.step_ns != 0 || out.verdict == Verdict::Stepped {
            assert_eq!(out.verdict, Verdict::Stepped);
            assert_eq!(out.integrator_q32, i_before, "a step changed I");
            since_step = Some(0);
        } else if let Some(n) = since_step.as_mut() {
            if present && out.verdict != Verdict::BadInterval {
                if *n < u32::from(cfg.blank) {
                    assert_eq!(out.verdict, Verdict::Blanked, "sample used while blanking");
                }
                *n += 1;
            }
        }
        if !used {
            // Held intervals never integrate.
            assert_eq!(
                s.integrator_q32(),
                i_before,
                "integrated on {:?}",
                out.verdict
            );
        }
    }
}

/// REQ-SERVO-101/102 and P5 for the master loop: for any sequence of (app, ref) pairs and
/// losses, the PI part of the deadline correction is within ±y_max_ns, the phase error is in
/// (−P/2, P/2], and every app-time step is a whole number of periods.
pub fn prop_master_bounded(cfg: ecdc_core::servo::MasterConfig, inputs: &[(bool, u64, u64, u64)]) {
    let Ok(mut m) = MasterServo::new(cfg) else {
        return;
    };
    let p = i64::from(cfg.period_ns);
    let y_max_ns = cfg.servo.limits.y_max() >> 32;
    for &(present, local, app, reference) in inputs {
        let input = if present {
            MasterInput::Sample {
                local_ns: local,
                app_ns: app,
                ref_ns: reference,
            }
        } else {
            MasterInput::Lost
        };
        let out = m.update(input);
        let pi_part = out.deadline_correction_ns - out.engine.step_ns;
        assert!(pi_part.abs() <= y_max_ns, "PI part {pi_part} > {y_max_ns}");
        assert!(out.engine.step_ns.abs() <= p / 2);
        assert!(2 * out.phase_error_ns <= p && 2 * out.phase_error_ns > -p);
        assert_eq!(out.app_time_step_ns % p, 0, "app step not whole periods");
        if present {
            // θ ≡ (app − ref) − target (mod P) in the configured width.
            let d = if cfg.ref_32bit {
                i128::from(app.wrapping_sub(reference) as u32 as i32)
            } else {
                i128::from(app.wrapping_sub(reference) as i64)
            };
            let raw = d - i128::from(cfg.target_ns);
            assert_eq!(
                (raw - i128::from(out.phase_error_ns)).rem_euclid(i128::from(p)),
                0,
                "θ not ≡ raw (mod P)"
            );
        }
    }
}

/// P5 one-step induction for the seed 004 filter (REQ-SERVO-031): |U|, |Y| ≤ M = 2^45·2^16 and
/// any input ⇒ |U'|, |Y'| ≤ M. Stronger, per interval: if U, Y and the (clamped) input are in
/// [lo, hi] then so are U', Y' (the filter never overshoots its inputs' range).
pub fn prop_filter_step_bounded(u: i64, y: i64, x: i64) {
    let m = FILTER_X_MAX << FILTER_FRAC;
    if u.unsigned_abs() > m.unsigned_abs() || y.unsigned_abs() > m.unsigned_abs() {
        return;
    }
    let mut f = OffsetFilter::from_state_q16(u, y);
    let _ = f.update(x);
    let (u2, y2) = f.state_q16();
    assert!(u2.abs() <= m && y2.abs() <= m, "filter left ±M");
    let xq = x.clamp(-FILTER_X_MAX, FILTER_X_MAX) << FILTER_FRAC;
    let lo = u.min(y).min(xq);
    let hi = u.max(y).max(xq);
    assert!(
        (lo..=hi).contains(&u2) && (lo..=hi).contains(&y2),
        "filter left the hull [{lo}, {hi}]: ({u2}, {y2})"
    );
}

/// P5 for the carry quantiser (REQ-SERVO-040): q·2^32 + r' = x + r exactly (nothing is lost)
/// for |x| ≤ 2^62, and r' ∈ [0, 2^32) (by type; asserted for readers).
pub fn prop_carry_exact(r_seed: i64, x: i64) {
    let mut c = Carry::new();
    // Reach remainder r_seed mod 2^32 first (quantising a pure fraction sets r to it).
    let _ = c.quantize(r_seed & 0xFFFF_FFFF);
    let r = i128::from(c.remainder());
    let q = c.quantize(x);
    let xc = i128::from(x.clamp(-CARRY_X_MAX, CARRY_X_MAX));
    assert_eq!(
        i128::from(q) * (1i128 << 32) + i128::from(c.remainder()),
        xc + r
    );
    assert!(u64::from(c.remainder()) < 1 << 32);
}

/// REQ-SERVO-041: after any sequence of per-period drifts, the total counter correction is the
/// exact total (floor) or one less — the long-run rate is exact, the phase error < 1 count plus
/// n·2^-32 (each period's exact value is floored to Q32 once).
pub fn prop_counter_long_run(crystal_hz: u64, npll: u32, deltas: &[i64]) {
    let Ok(mut c) = CounterCompensator::new(crystal_hz, npll) else {
        return;
    };
    let count_hz = i128::from(crystal_hz) * i128::from(npll);
    let mut total = 0i128;
    let mut wide = Vec::with_capacity(deltas.len());
    // Per-period corrections are limited to ±2^30 counts (CARRY_X_MAX); beyond that the output
    // saturates with the right sign and leaves the remainder untouched, so such periods are
    // checked on their own and left out of the long-run sums.
    let cap = 1i128 << 30;
    for &d in deltas {
        let dw = i128::from(d.clamp(-(1 << 40), 1 << 40));
        let r_before = c.remainder();
        let q = i128::from(c.per_period(d));
        assert!(u64::from(c.remainder()) < 1 << 32);
        if (dw * count_hz).abs() >= cap * 1_000_000_000 {
            assert_eq!(q, if dw > 0 { -cap } else { cap }, "saturated output");
            assert_eq!(c.remainder(), r_before);
            continue;
        }
        total += q;
        wide.push(dw);
    }
    let exact = spec::exact_counter_total(&wide, count_hz);
    assert!(
        total == exact || total == exact - 1,
        "total {total} vs exact floor {exact}"
    );
}

/// REQ-SERVO-002 soundness: gains the core accepts have both closed-loop poles strictly inside
/// the unit circle (checked by computing the roots in f64).
pub fn prop_gains_sound(kp: i64, ki: i64) {
    if PiGains::from_q32(kp, ki).is_ok() {
        let (fkp, fki) = (kp as f64 / 4_294_967_296.0, ki as f64 / 4_294_967_296.0);
        assert!(
            spec::pi_stable(fkp, fki),
            "accepted unstable gains Kp={fkp} Ki={fki} (radius {})",
            spec::pi_pole_radius(fkp, fki)
        );
    }
}

/// REQ-SERVO-060 lock hysteresis against a literal re-statement: `locked` rises only when the
/// last `count` errors were all below `low`, and falls only on an error above `high`.
pub fn prop_lock_hysteresis(low: u64, high: u64, count: u16, thetas: &[i64]) {
    let Ok(cfg) = (LockConfig {
        low_ns: low,
        high_ns: high,
        count,
    })
    .validate() else {
        return;
    };
    let mut d = LockDetector::new();
    let mut prev = false;
    for (k, &th) in thetas.iter().enumerate() {
        let now = d.update(&cfg, th);
        if now && !prev {
            let n = usize::from(count);
            assert!(k + 1 >= n, "locked after {} samples", k + 1);
            assert!(
                thetas[k + 1 - n..=k].iter().all(|t| t.unsigned_abs() < low),
                "rose without {count} samples below {low}"
            );
        }
        if prev && !now {
            assert!(
                th.unsigned_abs() > high,
                "fell on |θ| = {} ≤ high",
                th.unsigned_abs()
            );
        }
        prev = now;
    }
}

/// Adapter for fuzzing [`prop_engine_bounded`] from plain integers: the 1 ms master servo
/// configuration with the step, first-step, confirm, blank, holdover and limit fields replaced
/// (as `proofs/tests/servo.rs` does). Configurations the core refuses are skipped.
#[allow(clippy::too_many_arguments)]
pub fn prop_engine_bounded_params(
    step_ns: u64,
    first_step_ns: u64,
    step_confirm: u8,
    blank: u8,
    holdover_max: u32,
    y_max_ns: i64,
    i_max_ns: i64,
    inputs: &[(bool, u64, i64)],
) {
    let Ok(master) = ecdc_core::servo::MasterConfig::for_period(1_000_000) else {
        return;
    };
    let Ok(limits) = ecdc_core::servo::PiLimits::from_ns(y_max_ns, i_max_ns) else {
        return;
    };
    let mut cfg = master.servo;
    cfg.step_ns = step_ns;
    cfg.first_step_ns = first_step_ns;
    cfg.step_confirm = step_confirm;
    cfg.blank = blank;
    cfg.holdover_max = holdover_max;
    cfg.limits = limits;
    prop_engine_bounded(cfg, inputs);
}

/// Adapter for fuzzing [`prop_master_bounded`] from plain integers: `MasterConfig::for_period`
/// with the reference width and target phase set. Periods the core refuses are skipped.
pub fn prop_master_bounded_params(
    period_ns: u32,
    ref_32bit: bool,
    target_ns: i64,
    inputs: &[(bool, u64, u64, u64)],
) {
    let Ok(mut cfg) = ecdc_core::servo::MasterConfig::for_period(period_ns) else {
        return;
    };
    cfg.ref_32bit = ref_32bit;
    cfg.target_ns = target_ns;
    prop_master_bounded(cfg, inputs);
}

// ---------------------------------------------------------------------------- Kani harnesses
// Symbolic for users with Kani; here run under `crate::kani_shim` (random, boundary-biased) by
// proofs/tests/servo.rs. Gains are one of a few concrete admissible sets, each passed as a
// constant in its own branch, so the solver does not face a symbolic 64×64 multiply (a gain
// picked from a table after the branches join would be symbolic again); θ, I and the limits
// are fully symbolic. No harness here divides by a symbolic value: the filter's `div_euclid(3)`
// is by a constant. The products over every admissible gain are proved on z3 (`smt::props::
// pi_products_exact`).

#[cfg(not(kani))]
use crate::kani_shim as kani;

fn any_gains(sel: u8) -> PiGains {
    use ecdc_core::servo::gains::{Pole, MARGIN, ONE};
    let g = match sel % 4 {
        0 => PiGains::from_poles(Pole::from_q32(1 << 31), Pole::from_q32(0x5555_5555)), // 1/2, 1/3
        1 => PiGains::double_pole(Pole::from_q32(0xFD70_A3D7)),                         // 0.99
        2 => PiGains::from_q32(2 * ONE - MARGIN, 1),                                    // Kp corner
        _ => PiGains::from_q32(MARGIN, 4 * ONE - 3 * MARGIN),                           // Ki corner
    };
    g.expect("every gain set above is admissible")
}

/// Kani P5: one-step inductive bound of the PI kernel.
#[cfg_attr(kani, kani::proof)]
pub fn kani_p5_pi_step_inductive() {
    match kani::any::<u8>() & 3 {
        0 => pi_step_inductive(any_gains(0)),
        1 => pi_step_inductive(any_gains(1)),
        2 => pi_step_inductive(any_gains(2)),
        _ => pi_step_inductive(any_gains(3)),
    }
}

/// [`kani_p5_pi_step_inductive`] for one gain set.
fn pi_step_inductive(g: PiGains) {
    let y_max: i64 = kani::any();
    let i_max: i64 = kani::any();
    let i: i64 = kani::any();
    let theta: i64 = kani::any();
    kani::assume(y_max > 0 && y_max <= 1 << 60 && i_max > 0 && i_max <= y_max);
    kani::assume(i >= -i_max && i <= i_max);
    let lim = PiLimits::from_q32(y_max, i_max).expect("valid by assumption");
    let s = pi_step(g, lim, i, theta);
    assert!(s.y >= -y_max && s.y <= y_max);
    assert!(s.integrator >= -i_max && s.integrator <= i_max);
    kani::cover!(s.saturated, "saturated output");
    kani::cover!(!s.saturated && s.integrator != i, "integrating");
    kani::cover!(s.saturated && s.integrator == i, "frozen integrator");
}

/// Kani P5: the seed 004 filter's one-step bound.
#[cfg_attr(kani, kani::proof)]
pub fn kani_p5_filter_step() {
    prop_filter_step_bounded(kani::any(), kani::any(), kani::any());
}

/// Kani P5: the carried remainder stays in [0, 1) and nothing is lost.
#[cfg_attr(kani, kani::proof)]
pub fn kani_p5_carry_step() {
    let x: i64 = kani::any();
    kani::cover!(x < 0, "negative input");
    prop_carry_exact(kani::any(), x);
}

/// P5 / REQ-SERVO-010, REQ-SERVO-012: `pi_step` equals the i128 rule of the spec for admissible
/// gains and limits and *every* integrator `i` (the entry clamp of a corrupted integrator
/// included) and θ. Returns whether the inputs were admissible (and so checked).
pub fn prop_pi_step_matches_spec(
    kp: i64,
    ki: i64,
    y_max: i64,
    i_max: i64,
    i: i64,
    theta: i64,
) -> bool {
    let (Ok(g), Ok(lim)) = (PiGains::from_q32(kp, ki), PiLimits::from_q32(y_max, i_max)) else {
        return false;
    };
    let s = pi_step(g, lim, i, theta);
    let w = i128::from;
    assert_eq!(
        widened(s),
        spec::pi_step(w(kp), w(ki), w(y_max), w(i_max), w(i), w(theta)),
        "pi_step differs from the i128 rule (kp {kp} ki {ki} y_max {y_max} i_max {i_max} i {i} \
         theta {theta})"
    );
    true
}
