//! Fuzz target for REQ-PROP P5 and the servo requirements with a crisp statement
//! (REQ-SERVO-002/012/013/031/040/041/060/080/081/090/101/102): the PI one-step bound and
//! overflow side-conditions, engine and master loops over an arbitrary input sequence, the
//! seed 004 filter step, the carry quantiser, the counter compensator's long run, gain
//! soundness and lock hysteresis. Bodies: `ecdc_proofs::servo::prop_*`.
//! verifies: REQ-SERVO-002
#![no_main]

use arbitrary::Arbitrary;
use ecdc_proofs::servo as p;
use libfuzzer_sys::fuzz_target;

#[derive(Debug, Arbitrary)]
struct Input {
    kp: i64,
    ki: i64,
    y_max: i64,
    i_max: i64,
    integrator: i64,
    theta: i64,
    u: i64,
    y: i64,
    step_ns: u32,
    first_step_ns: u32,
    step_confirm: u8,
    blank: u8,
    holdover_max: u8,
    y_max_ns: u32,
    i_max_ns: u32,
    engine_inputs: Vec<(bool, u64, i64)>,
    period_ns: u32,
    ref_32bit: bool,
    target_ns: i64,
    master_inputs: Vec<(bool, u64, u64, u64)>,
    crystal_hz: u32,
    npll: u8,
    deltas: Vec<i64>,
    lock_low: u16,
    lock_extra: u16,
    lock_count: u8,
    thetas: Vec<i16>,
}

fuzz_target!(|i: Input| {
    p::prop_pi_step_bounded(i.kp, i.ki, i.y_max, i.i_max, i.integrator, i.theta);
    p::prop_pi_intermediates_fit(i.kp, i.ki, i.i_max, i.integrator, i.theta);
    p::prop_gains_sound(i.kp, i.ki);
    p::prop_filter_step_bounded(i.u, i.y, i.theta);
    p::prop_carry_exact(i.u, i.theta);
    let e = &i.engine_inputs[..i.engine_inputs.len().min(400)];
    p::prop_engine_bounded_params(
        u64::from(i.step_ns),
        u64::from(i.first_step_ns),
        i.step_confirm,
        i.blank,
        u32::from(i.holdover_max),
        i64::from(i.y_max_ns),
        i64::from(i.i_max_ns),
        e,
    );
    let m = &i.master_inputs[..i.master_inputs.len().min(400)];
    p::prop_master_bounded_params(i.period_ns, i.ref_32bit, i.target_ns, m);
    let d = &i.deltas[..i.deltas.len().min(400)];
    p::prop_counter_long_run(u64::from(i.crystal_hz), u32::from(i.npll), d);
    let thetas: Vec<i64> = i.thetas.iter().take(400).map(|&t| i64::from(t)).collect();
    let low = u64::from(i.lock_low);
    p::prop_lock_hysteresis(
        low,
        low + u64::from(i.lock_extra),
        u16::from(i.lock_count),
        &thetas,
    );
});
