//! Seed 000 (Chen et al., "Clock synchronization compensation scheme based on IgH EtherCAT",
//! Science Technology and Engineering 25(3), 2025), §2: the DC compensation formulas, written
//! literally over `i128` so no wrap or overflow can hide a mistake.
//!
//! Notation of the paper: `t_iA` / `t_iB` are slave *i*'s receive times at port A (where the frame
//! enters, port 0) and port B (where it returns from downstream, port 1); `t_DIFF = t_P − t_F`
//! (processing minus forwarding delay, eq. 8); slave 1 is the reference clock.
//!
//! Halving: the paper divides by 2 without saying how to round. These functions return the
//! exact numerator (`…_x2`, i.e. twice the delay) so that tests compare exact values; the
//! rounding rule used by `ecdc-core` is [`half`] (REQ-DC-014).
//!
//! Errata found while transcribing (REQ-DC-090):
//! - eq. 23, case `i = n`, prints `(t_1B − t_1A) + i·t_DIFF`. Eq. 22 (the case it generalises,
//!   n = 4) and the derivation from eq. 5 and 17–19 give `(t_1B − t_1A) + (n − 2)·t_DIFF`: the last
//!   hop (eq. 5) carries no `t_DIFF`. [`eq23_t_ref_x2`] implements the derived form;
//!   [`eq23_printed_last_x2`] and [`eq23_printed_x2`] keep the printed one so a test shows the
//!   discrepancy.
//! - eq. 24 prints `t_OFF = t_LOCAL − t_SYS,REF`, but eq. 25 (`Δt = t_LOCAL + t_OFF − t_DELAY −
//!   t_SYS,REF`) is zero for a synchronised slave only with `t_OFF = t_SYS,REF − t_LOCAL`, which is
//!   also the datasheet's definition of 0x0920 (REQ-CONV-004). [`eq24_offset_printed`] is the
//!   printed form; ecdc uses [`offset_consistent_with_eq25`].

/// Rounds `x2 / 2` to the nearest integer, ties towards +∞ (`⌊(x2 + 1) / 2⌋`). The one halving
/// rule of ecdc (REQ-DC-014).
pub fn half(x2: i128) -> i128 {
    (x2 + 1).div_euclid(2)
}

/// Eq. 5: delay between the last two slaves of a line, `t_34 = t_43 = (t_3B − t_3A) / 2`,
/// returned doubled.
pub fn eq5_last_hop_x2(t_b: i128, t_a: i128) -> i128 {
    t_b - t_a
}

/// Eq. 13 (and 15, the same formula one slave earlier): forward delay from slave i to slave i+1
/// of a line, `t_i,i+1 = ((t_iB − t_iA) − (t_i+1,B − t_i+1,A) + t_DIFF) / 2`, doubled.
pub fn eq13_forward_x2(ti_b: i128, ti_a: i128, tj_b: i128, tj_a: i128, t_diff: i128) -> i128 {
    (ti_b - ti_a) - (tj_b - tj_a) + t_diff
}

/// Eq. 14 (and 16): return delay from slave i+1 back to slave i,
/// `t_i+1,i = ((t_iB − t_iA) − (t_i+1,B − t_i+1,A) − t_DIFF) / 2`, doubled.
pub fn eq14_return_x2(ti_b: i128, ti_a: i128, tj_b: i128, tj_a: i128, t_diff: i128) -> i128 {
    (ti_b - ti_a) - (tj_b - tj_a) - t_diff
}

/// Eq. 20–22 are eq. 23 for n = 4; see [`eq23_t_ref_x2`].
///
/// Eq. 23 (derived form, see module errata): delay from the reference (slave 1) to slave `i` of a
/// line of `n` slaves, doubled. `rtt[k]` is `t_(k+1)B − t_(k+1)A` (0-based; the last slave's entry
/// is ignored, it has no port B). `i` is 1-based as in the paper.
///
/// Returns `None` when `i` is out of `1..=n` or `rtt` is shorter than `n`.
pub fn eq23_t_ref_x2(rtt: &[i128], n: usize, i: usize, t_diff: i128) -> Option<i128> {
    if i == 0 || i > n || rtt.len() < n {
        return None;
    }
    let r1 = *rtt.first()?;
    if i == 1 {
        Some(0)
    } else if i < n {
        let ri = *rtt.get(i - 1)?;
        Some(r1 - ri + (i as i128 - 1) * t_diff)
    } else {
        Some(r1 + (n as i128 - 2) * t_diff)
    }
}

/// Eq. 23, case `i = n`, exactly as printed: `(t_1B − t_1A) + i·t_DIFF`, doubled. Kept only to show
/// that it disagrees with eq. 22 and with the network model whenever `t_DIFF ≠ 0`.
pub fn eq23_printed_last_x2(rtt1: i128, n: usize, t_diff: i128) -> i128 {
    rtt1 + n as i128 * t_diff
}

/// Eq. 23 with all three cases exactly as printed, doubled: [`eq23_t_ref_x2`] for `i < n`,
/// [`eq23_printed_last_x2`] for `i = n` (n > 1). Same arguments and `None` cases as
/// [`eq23_t_ref_x2`].
pub fn eq23_printed_x2(rtt: &[i128], n: usize, i: usize, t_diff: i128) -> Option<i128> {
    if i == n && n > 1 && rtt.len() >= n {
        Some(eq23_printed_last_x2(*rtt.first()?, n, t_diff))
    } else {
        eq23_t_ref_x2(rtt, n, i, t_diff)
    }
}

/// Eq. 22 exactly as printed, doubled: the last slave of a four-slave line,
/// `t_REF,4 = ((t_1B − t_1A) + 2·t_DIFF) / 2`. The case eq. 23 generalises for `i = n`.
pub fn eq22_t_ref4_x2(rtt1: i128, t_diff: i128) -> i128 {
    rtt1 + 2 * t_diff
}

/// Eq. 17–19 (the definition eq. 23 simplifies): `t_REF,i = Σ_{k<i} t_k,k+1`, each hop from
/// eq. 13 except the last hop of the line, which is eq. 5. Doubled. Used by tests to confirm that
/// [`eq23_t_ref_x2`] is the correct simplification.
pub fn eq17_19_sum_of_hops_x2(rtt: &[i128], n: usize, i: usize, t_diff: i128) -> Option<i128> {
    if i == 0 || i > n || rtt.len() < n {
        return None;
    }
    let mut sum = 0i128;
    for k in 1..i {
        // hop k → k+1 (1-based)
        let rk = *rtt.get(k - 1)?;
        let hop = if k + 1 == n {
            eq5_last_hop_x2(rk, 0)
        } else {
            let rk1 = *rtt.get(k)?;
            eq13_forward_x2(rk, 0, rk1, 0, t_diff)
        };
        sum += hop;
    }
    Some(sum)
}

/// Eq. 24 as printed: `t_OFF = t_LOCAL − t_SYS,REF` (sign inconsistent with eq. 25, see errata).
pub fn eq24_offset_printed(t_local: i128, t_sys_ref: i128) -> i128 {
    t_local - t_sys_ref
}

/// The offset that makes eq. 25 zero at the latch instant: `t_OFF = t_SYS,REF + t_DELAY − t_LOCAL`.
/// With `t_DELAY = 0` this is the datasheet's `system time − local time` (REQ-CONV-004); with the
/// propagation delay folded in it is ecdc's initial offset (REQ-DC-021).
pub fn offset_consistent_with_eq25(t_local: i128, t_sys_ref: i128, t_delay: i128) -> i128 {
    t_sys_ref + t_delay - t_local
}

/// Eq. 25: drift seen by a slave, `Δt = t_LOCAL + t_OFF − t_DELAY − t_SYS,REF`. Positive: the
/// slave's copy of system time is ahead (REQ-CONV-006).
pub fn eq25_drift(t_local: i128, t_off: i128, t_delay: i128, t_sys_ref: i128) -> i128 {
    t_local + t_off - t_delay - t_sys_ref
}
