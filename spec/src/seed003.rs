//! Seed 003 (Su et al., "Dual-linear-motor position linkage control based on EtherCAT", TwinCAT
//! DC analysis), eq. 1–6, written literally over `i128`.
//!
//! Two slaves: 1 (A) then 2 (B). `t_A0` is the frame's first arrival at slave 1, `t_B0` its
//! arrival at slave 2, `t_A1` its return to slave 1. Eq. 1–3 are assumptions (symmetric cable,
//! equal processing delays); eq. 4 is the measurement the master can actually make.

/// Eq. 2, first line, doubled nothing: the true forward delay `t_AB = t_p1 + t_WAB`.
pub fn eq2_forward(t_p1: i128, t_wab: i128) -> i128 {
    t_p1 + t_wab
}

/// Eq. 2, second line: the true return delay `t_BA = t_p2 + t_WBA`.
pub fn eq2_return(t_p2: i128, t_wba: i128) -> i128 {
    t_p2 + t_wba
}

/// Eq. 4: `t_AB = t_BA = (t_A1 − t_A0) / 2`, returned doubled (exact). Equals eq. 2 when eq. 1
/// (`t_WAB = t_WBA`) and eq. 3 (`t_p1 = t_p2`) hold; this is seed 000 eq. 5 for two slaves.
pub fn eq4_delay_x2(t_a1: i128, t_a0: i128) -> i128 {
    t_a1 - t_a0
}

/// Eq. 5: `t_offset = t_sys − t_local` (REQ-CONV-004 sign).
pub fn eq5_offset(t_sys: i128, t_local: i128) -> i128 {
    t_sys - t_local
}

/// Eq. 6: `t_drift = t_sys − (t_ref + t_pd)`: a slave's copy of system time when the frame
/// arrives, minus the reference's time carried by the frame plus the propagation delay. Positive:
/// the slave is ahead (same sign as REQ-CONV-006).
pub fn eq6_drift(t_sys: i128, t_ref: i128, t_pd: i128) -> i128 {
    t_sys - (t_ref + t_pd)
}
