//! The ESC datasheet's delay formulas for trees (Beckhoff Section I §9.1.3, summarised in
//! docs/background/esc-registers.md §5), plain `i128`, plus the general per-hop rule they instantiate.
//!
//! Frame path inside an ESC: ports are visited in the processing order 0 → 3 → 1 → 2 → 0; a
//! closed port is skipped (internal loopback). The EtherCAT Processing Unit (EPU) sits between
//! port 0's receiver and the next port, so a hop *from port 0's receiver* (or across a closed
//! port 0) is a processing hop (`t_P`), every other hop a forwarding hop (`t_F`);
//! `t_Diff = t_P − t_F`.
//!
//! Example network of the datasheet: A (reference) — B (branch node with ports 0/1/2) — C — D
//! on B's port 1, more on B's port 2. All results doubled (exact).

/// Processing order successor: 0 → 3 → 1 → 2 → 0.
pub fn next_port(p: u8) -> u8 {
    match p {
        0 => 3,
        3 => 1,
        1 => 2,
        _ => 0,
    }
}

/// True when the ESC-internal walk from the receiver of port `from` to the transmitter of port
/// `to` passes the EPU, i.e. when port 0 is among `from, next(from), …` strictly before `to`
/// (for `from == to` the walk is the full circle). Such a hop costs `t_P`, otherwise `t_F`.
pub fn hop_is_processing(from: u8, to: u8) -> bool {
    let mut p = from;
    loop {
        if p == 0 {
            return true;
        }
        p = next_port(p);
        if p == to {
            return false;
        }
    }
}

/// `t_CD = t_DC = (t_C1 − t_C0) / 2`: C's only downstream neighbour D is a line end. Doubled.
pub fn t_cd_x2(t_c1: i128, t_c0: i128) -> i128 {
    t_c1 - t_c0
}

/// `t_BC = ((t_B1 − t_B0) − (t_C1 − t_C0) + t_Diff) / 2`. Doubled.
pub fn t_bc_x2(t_b1: i128, t_b0: i128, t_c1: i128, t_c0: i128, t_diff: i128) -> i128 {
    (t_b1 - t_b0) - (t_c1 - t_c0) + t_diff
}

/// `t_CB = ((t_B1 − t_B0) − (t_C1 − t_C0) − t_Diff) / 2`. Doubled.
pub fn t_cb_x2(t_b1: i128, t_b0: i128, t_c1: i128, t_c0: i128, t_diff: i128) -> i128 {
    (t_b1 - t_b0) - (t_c1 - t_c0) - t_diff
}

/// `t_AB = ((t_A1 − t_A0) − (t_B2 − t_B0) + t_Diff) / 2`: B's round trip spans its ports 0..2.
/// Doubled.
pub fn t_ab_x2(t_a1: i128, t_a0: i128, t_b2: i128, t_b0: i128, t_diff: i128) -> i128 {
    (t_a1 - t_a0) - (t_b2 - t_b0) + t_diff
}

/// General hop rule (the formulas above are instances; REQ-DC-014). Parent `s` sends the frame
/// out of its port `p` after it came in (or back) at port `q`; `excursion = t_s(p) − t_s(q)`.
/// The child `c` behind `p` has internal round trip `rtt_c = t_c(last) − t_c(entry)`.
///
/// Returns twice the time from the frame's stamp at `s`'s port `q` to its arrival at `c`:
/// `excursion − rtt_c + t_Diff(s)·[q→p processing] − t_Diff(c)·[last→entry processing]
///  + Σ_n t_Diff(n)·(±1)` where `n` are 2-port non-DC ESCs on the cable path, `+1` when their
/// downstream hop is the processing one and `−1` when the upstream one is. This assumes one
/// common `t_F` for all ESCs (only `t_Diff` may differ per ESC).
pub fn tree_hop_x2(
    excursion: i128,
    rtt_child: i128,
    parent_diff_if_processing: i128,
    child_diff_if_processing: i128,
    non_dc_sum: i128,
) -> i128 {
    excursion - rtt_child + parent_diff_if_processing - child_diff_if_processing + non_dc_sum
}
