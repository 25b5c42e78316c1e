//! Property bodies for the DC maths (REQ-PROP P3 delay, P4 offset; spec/req/dc.md).
//!
//! One body per property. Each is a plain `pub fn` that panics (assert) when the property is
//! violated, and is called by
//! - the Kani harnesses in [`harness`] (`cfg(kani)`; Kani is not installed on the build machine,
//!   so these have never been run here),
//! - the property tests in `proofs/tests/dc_math.rs`.
//!
//! P3 is stated over *physically generated* port times (a line or tree of ESCs with
//! non-negative delays), because for arbitrary numbers "delay ≥ 0" is not a property of any
//! formula: the core must then return a typed error instead, which [`p3_arbitrary_latches`]
//! checks.
//!
//! verifies: P3, P4

// Index loops mirror the physical description and keep Kani's unwinding obvious.
#![allow(clippy::needless_range_loop)]

use ecdc_core::dc::delay;
use ecdc_core::dc::offset::{self, ClockWidth};
use ecdc_core::dc::port::{Port, PortSet};
use ecdc_core::dc::sync;
use ecdc_core::dc::topology::{Latches, SlaveSample, Topology};
use ecdc_core::time::SystemTime;
use ecdc_spec::seed000;

/// A line of `n ≤ N` DC ESCs (ports 0 in, 1 out) with one common `t_F` and `t_Diff` (seed 000's
/// assumptions), per-ESC cables and clock phases. Small integer types keep the Kani state small;
/// every physically meaningful value fits.
#[derive(Debug, Clone, Copy)]
pub struct Line<const N: usize> {
    /// Number of ESCs, 1..=N (clamped).
    pub n: usize,
    /// Forwarding delay, ns.
    pub t_f: u16,
    /// `t_P − t_F`, ns (non-negative here; any sign is covered by the tree property).
    pub t_diff: u16,
    /// Cable to the upstream neighbour, ns.
    pub cable: [u16; N],
    /// Low 32 bits of each ESC's local clock phase (any value: wraps anywhere).
    pub phase: [u32; N],
}

/// Port times a line produces, plus the true arrival times (ns after the master sent).
fn line_latches<const N: usize>(line: &Line<N>) -> ([SlaveSample; N], [i64; N]) {
    let n = line.n.clamp(1, N);
    let t_p = i64::from(line.t_f) + i64::from(line.t_diff);
    let t_f = i64::from(line.t_f);
    let mut arrival = [0i64; N];
    let mut acc = 0i64;
    for i in 0..n {
        acc += i64::from(line.cable[i]) + if i > 0 { t_p } else { 0 };
        arrival[i] = acc;
    }
    // Frame comes back at ESC i's port 1 (i < n−1).
    let mut back = [0i64; N];
    if n >= 2 {
        back[n - 2] = arrival[n - 1] + t_p + i64::from(line.cable[n - 1]);
        let mut i = n - 2;
        while i > 0 {
            back[i - 1] = back[i] + t_f + i64::from(line.cable[i]);
            i -= 1;
        }
    }
    let mut samples = [SlaveSample::default(); N];
    for i in 0..n {
        let local = |t: i64| line.phase[i].wrapping_add(t as u32);
        let mut ports = PortSet::EMPTY.with(Port::P0);
        let mut raw = [0u32; 4];
        raw[0] = local(arrival[i]);
        if i + 1 < n {
            ports = ports.with(Port::P1);
            raw[1] = local(back[i]);
        }
        samples[i] = SlaveSample {
            ports,
            latches: Some(Latches::from_raw(raw, u64::from(raw[0]))),
            t_diff: i32::from(line.t_diff),
        };
    }
    (samples, arrival)
}

/// P3 on lines (REQ-DC-014..020): for every line within capacity and every clock phase (any
/// 32-bit phase, so stamps wrap inside the latch: REQ-DC-016), the
/// computed delays exist (no overflow, no error), are ≥ 0, are bounded by the reference's round
/// trip, increase along the processing order, equal seed 000 eq. 23 (derived form, i128) and
/// equal the true propagation delays.
pub fn p3_line<const N: usize>(line: &Line<N>) {
    let n = line.n.clamp(1, N);
    let (samples, arrival) = line_latches(line);
    let samples = &samples[..n];
    let topo = Topology::<N>::build(samples).expect("a line is a valid topology");
    let delays = delay::compute(samples, &topo, 0).expect("physical latches give delays");
    let lat = |i: usize| samples[i].latches.expect("DC");
    let rtt: [i128; N] = core::array::from_fn(|i| {
        if i + 1 < n {
            i128::from(lat(i).ports[1].wrapping_since(lat(i).ports[0]))
        } else {
            0
        }
    });
    let mut prev = -1i64;
    for i in 0..n {
        let d = delays.ns(i).expect("every slave has a delay");
        assert!(d >= 0, "delay {d} < 0 at {i}");
        assert!(
            i128::from(d) <= rtt[0].max(0),
            "delay {d} above the round trip at {i}"
        );
        assert!(d >= prev, "not monotone at {i}");
        prev = d;
        let (num, den) = delays.exact(i).expect("exact");
        let eq23 = seed000::eq23_t_ref_x2(&rtt[..n], n, i + 1, i128::from(line.t_diff))
            .expect("i in range");
        assert_eq!((i128::from(num), den), (eq23, 2), "eq. 23 at {i}");
        assert_eq!(d, arrival[i] - arrival[0], "true delay at {i}");
        assert_eq!(delays.register_value(i), Ok(d as u32));
    }
}

/// A fixed tree for P3 beyond lines: A (ports 0, 1, 2) with B on port 1, D behind B, and C on
/// A's port 2 — the datasheet's fork shape. Per-ESC `t_Diff` (the correction terms of
/// REQ-DC-014 differ per hop kind), one `t_F`, per-link cables, per-ESC phases.
#[derive(Debug, Clone, Copy)]
pub struct Fork {
    /// Common forwarding delay, ns.
    pub t_f: u16,
    /// `t_P − t_F` of A, B, C, D.
    pub t_diff: [u16; 4],
    /// Cable into A (from the master), B, C, D.
    pub cable: [u16; 4],
    /// Low 32 bits of the clock phase of A, B, C, D.
    pub phase: [u32; 4],
}

/// P3 on the fork: delays of B, C, D relative to A are exact (equal to the true arrival
/// differences), ≥ 0, at most A's round trip, and non-decreasing in auto-increment order
/// A, B, D, C.
pub fn p3_fork(f: &Fork) {
    let tf = i64::from(f.t_f);
    let tp = |k: usize| tf + i64::from(f.t_diff[k]);
    let c = |k: usize| i64::from(f.cable[k]);
    // True times (ns after the master sends), walking the frame by hand.
    let t_a = c(0);
    let t_b = t_a + tp(0) + c(1); // A: 0 → EPU → 1
    let t_d = t_b + tp(1) + c(3); // B: 0 → EPU → 1
    let r_b1 = t_d + tp(3) + c(3); // D is a line end: 0 → EPU → 0
    let r_a1 = r_b1 + tf + c(1); // B: 1 → 0 forwarding
    let t_c = r_a1 + tf + c(2); // A: 1 → 2 forwarding
    let r_a2 = t_c + tp(2) + c(2); // C is a line end
    let stamp = |k: usize, t: i64| f.phase[k].wrapping_add(t as u32);
    let sample = |k: usize, ports: PortSet, raw: [u32; 4]| SlaveSample {
        ports,
        latches: Some(Latches::from_raw(raw, u64::from(raw[0]))),
        t_diff: i32::from(f.t_diff[k]),
    };
    let p01 = PortSet::EMPTY.with(Port::P0).with(Port::P1);
    let p0 = PortSet::EMPTY.with(Port::P0);
    // Auto-increment order: A, B, D, C.
    let samples = [
        sample(
            0,
            p01.with(Port::P2),
            [stamp(0, t_a), stamp(0, r_a1), stamp(0, r_a2), 0],
        ),
        sample(1, p01, [stamp(1, t_b), stamp(1, r_b1), 0, 0]),
        sample(3, p0, [stamp(3, t_d), 0, 0, 0]),
        sample(2, p0, [stamp(2, t_c), 0, 0, 0]),
    ];
    let topo = Topology::<4>::build(&samples).expect("fork topology");
    let delays = delay::compute(&samples, &topo, 0).expect("physical latches give delays");
    let truth = [0, t_b - t_a, t_d - t_a, t_c - t_a];
    let mut prev = 0i64;
    for (i, want) in truth.iter().enumerate() {
        let d = delays.ns(i).expect("DC");
        assert_eq!(d, *want, "slave {i}");
        assert!(d >= prev && d <= r_a2 - t_a, "bounds at {i}");
        prev = d;
    }
}

/// P3, robustness half: for ANY latch values and DL status (not necessarily physical), topology
/// and delay computation never panic and either fail with a typed error or return delays whose
/// register values are non-negative (`BeforeReference` otherwise).
pub fn p3_arbitrary_latches(samples: &[SlaveSample], reference: usize) {
    let Ok(topo) = Topology::<8>::build(samples) else {
        return;
    };
    let Ok(delays) = delay::compute(samples, &topo, reference) else {
        return;
    };
    for i in 0..samples.len() {
        match (delays.ns(i), delays.register_value(i)) {
            (Some(d), Ok(r)) => assert_eq!(i64::from(r), d),
            (Some(d), Err(_)) => assert!(d < 0 || d > i64::from(u32::MAX)),
            (None, Err(_)) => assert!(samples[i].latches.is_none()),
            (None, Ok(_)) => panic!("register value without a delay"),
        }
    }
}

/// P3 on trees via the network model (REQ-DC-061): delays relative to the first DC ESC are
/// ≥ 0, at most its round trip through all its ports, non-decreasing along the auto-increment
/// (processing) order, and equal to the model's; no overflow, no error. Quantised stamps are not
/// used here (exactness); the model tests cover them.
pub fn p3_tree(net: &ecdc_spec::network::Network) {
    use ecdc_spec::network::{core_samples, Dc};
    let latch = net.latch().expect("tree");
    let samples = core_samples(net, &latch, 1, true);
    let topo = Topology::<64>::build(&samples).expect("valid topology");
    let reference = net
        .escs
        .iter()
        .position(|e| e.dc != Dc::None)
        .expect("a DC ESC");
    let delays = delay::compute(&samples, &topo, reference).expect("delays");
    let node = topo.node(reference).expect("ref");
    let lat = samples[reference].latches.expect("ref latches");
    let rtt_ref = i64::from(lat.at(node.last_port()).wrapping_since(lat.at(node.entry)));
    let mut prev = 0i64;
    for (i, e) in net.escs.iter().enumerate() {
        let Some(d) = delays.ns(i) else {
            assert_eq!(e.dc, Dc::None);
            continue;
        };
        assert!(
            d >= 0 && d <= rtt_ref,
            "delay {d} outside [0, {rtt_ref}] at {i}"
        );
        assert!(d >= prev, "delays not monotone at {i}");
        prev = d;
        assert_eq!(i128::from(d), latch.delay(reference, i));
    }
}

/// P4 (REQ-DC-021, 023): for every master time, delay and entry local time, the offset makes
/// `local + offset ≡ master + delay` modulo 2^64 (64-bit slaves) or 2^32 (32-bit slaves), and
/// its register image has exactly the slave's width.
pub fn p4_offset(master: u64, delay_ns: i64, entry_local: u64, bits64: bool) {
    let width = if bits64 {
        ClockWidth::Bits64
    } else {
        ClockWidth::Bits32
    };
    let off = offset::initial_offset(SystemTime(master), delay_ns, entry_local, width);
    let target = master.wrapping_add(delay_ns as u64);
    let img = off.to_register();
    if bits64 {
        assert_eq!(entry_local.wrapping_add(off.as_u64()), target);
        assert_eq!(img.as_slice().len(), 8);
    } else {
        let off32 = u32::try_from(off.as_u64()).expect("32-bit offset fits 32 bits");
        assert_eq!((entry_local as u32).wrapping_add(off32), target as u32);
        assert_eq!(img.as_slice().len(), 4);
    }
    assert_eq!(
        img.as_slice(),
        &off.as_u64().to_le_bytes()[..img.as_slice().len()]
    );
}

/// P4 (REQ-DC-022): widening the entry port's 32-bit stamp with the EPU stamp gives a 64-bit
/// local time whose low 32 bits are the entry stamp and which precedes the EPU stamp by exactly
/// the wrapping gap (< 2^32), for every EPU value, entry stamp and entry port.
pub fn p4_entry_local(epu: u64, entry_stamp: u32, entry_port: u8) {
    let port = Port::from_number(entry_port % 4).expect("0..=3");
    let mut raw = [0u32; 4];
    raw[port.index()] = entry_stamp;
    let lat = Latches::from_raw(raw, epu);
    let r = offset::entry_local_time(&lat, port);
    assert_eq!(r as u32, entry_stamp);
    assert_eq!(
        epu.wrapping_sub(r),
        u64::from((epu as u32).wrapping_sub(entry_stamp))
    );
}

/// REQ-DC-050..052: the SYNC start equals the exact i128 definition — first multiple of the
/// period at or after `now + margin`, plus shift — whenever that lies strictly after `now`, less
/// than 2^31 ns ahead and inside u64; otherwise the matching typed error. The 0x0990 images have
/// exact widths (8 bytes, or the low 32 bits in 4).
pub fn sync_start(now: u64, margin: u64, period: u64, shift: i64) {
    let got = sync::start_time(SystemTime(now), margin, period, shift);
    if period == 0 {
        assert_eq!(got, Err(sync::SyncError::ZeroCycle));
        return;
    }
    let max = i128::from(u64::MAX);
    let earliest = i128::from(now) + i128::from(margin);
    let p = i128::from(period);
    let grid = (earliest + p - 1).div_euclid(p) * p;
    let start = grid + i128::from(shift);
    if earliest > max || grid > max || start < 0 || start > max {
        assert_eq!(got, Err(sync::SyncError::Overflow));
        return;
    }
    let lead = start - i128::from(now);
    if lead <= 0 || lead >= 1i128 << 31 {
        assert_eq!(got, Err(sync::SyncError::StartOutOfWindow));
        return;
    }
    let start = got.expect("inside the window");
    assert_eq!(i128::from(start.as_nanos()), grid + i128::from(shift));
    let s = start.as_nanos();
    let r64 = sync::start_time_register(start, ClockWidth::Bits64);
    let r32 = sync::start_time_register(start, ClockWidth::Bits32);
    assert_eq!(r64.as_slice(), &s.to_le_bytes());
    assert_eq!(r32.as_slice(), &(s as u32).to_le_bytes());
}

/// Adapter for fuzzing [`p3_arbitrary_latches`] from plain integers: one
/// `(DL port bits, port stamps, EPU stamp, has DC, t_Diff)` tuple per slave.
pub fn p3_arbitrary_latches_raw(raw: &[(u8, [u32; 4], u64, bool, i32)], reference: usize) {
    let samples: Vec<SlaveSample> = raw
        .iter()
        .map(|&(ports, t, epu, dc, t_diff)| SlaveSample {
            ports: PortSet::from_bits(ports),
            latches: dc.then(|| Latches::from_raw(t, epu)),
            t_diff,
        })
        .collect();
    p3_arbitrary_latches(&samples, reference);
}

/// Adapter for fuzzing [`p3_tree`] from plain integers: generates the network the same way as
/// `proofs/tests/dc_math.rs` (`count` clamped to 1..=64, `shape` 0..=3 = line, fork, cross,
/// any; `non_dc` percent clamped to 0..=30).
pub fn p3_tree_generated(seed: u64, count: usize, shape: u8, non_dc: u64) {
    use ecdc_spec::network::{generate, GenParams, Shape, SplitMix};
    let shape = [Shape::Line, Shape::Fork, Shape::Cross, Shape::Any][usize::from(shape % 4)];
    let p = GenParams {
        t_f: (0, 800),
        t_diff: (0, 400),
        ..GenParams::new(count.clamp(1, 64), shape, non_dc.min(30), 30)
    };
    p3_tree(&generate(&mut SplitMix::new(seed), &p));
}

// ------------------------------------------------------------------ Kani harnesses
//
// Under `cargo kani` these are proofs over every input within the assumptions. In ordinary
// builds `kani::` is `crate::kani_shim` and `proofs/tests/dc_math.rs` runs them with random
// inputs through `kani_shim::run` (a random test, not a proof). Kani is not installed on the
// build machine, so they have never been run as proofs here.

#[cfg(not(kani))]
use crate::kani_shim as kani;

/// P3 on lines of up to 3 ESCs, every clock phase, bounded physical delays.
#[cfg_attr(kani, kani::proof)]
#[cfg_attr(kani, kani::unwind(6))]
pub fn kani_p3_line() {
    // Bounds by reduction rather than `assume`, so the random shim wastes no runs.
    let cable: [u16; 3] = kani::any();
    let line = Line::<3> {
        n: 1 + usize::from(kani::any::<u8>() % 3),
        t_f: kani::any::<u16>() % 2_001,
        t_diff: kani::any::<u16>() % 1_001,
        cable: cable.map(|c| c % 10_001),
        phase: kani::any(),
    };
    // Every real ESC takes time to forward a frame.
    kani::assume(line.t_f > 0);
    kani::cover!(line.phase[0] > u32::MAX - 10_000, "wrap inside the latch");
    kani::cover!(line.n == 3 && line.t_diff > 0, "three slaves with t_Diff");
    p3_line(&line);
}

/// P3 on the fork shape with per-ESC t_Diff (second branch: q ≠ entry, forwarding hop).
#[cfg_attr(kani, kani::proof)]
#[cfg_attr(kani, kani::unwind(6))]
pub fn kani_p3_fork() {
    let t_diff: [u16; 4] = kani::any();
    let cable: [u16; 4] = kani::any();
    let f = Fork {
        t_f: kani::any::<u16>() % 2_001,
        t_diff: t_diff.map(|d| d % 1_001),
        cable: cable.map(|c| c % 10_001),
        phase: kani::any(),
    };
    kani::cover!(f.t_diff[2] != f.t_diff[0], "branch ESCs of different types");
    kani::cover!(
        f.phase[0] > u32::MAX - 40_000,
        "reference wraps inside the latch"
    );
    p3_fork(&f);
}

/// P4 offset congruence for every master time, local time, width and bounded delay.
#[cfg_attr(kani, kani::proof)]
pub fn kani_p4_offset() {
    // Sign-extending the low 41 bits bounds the delay to [−2^40, 2^40) with shifts; `% 2^40`
    // would put a 64-bit signed divider in front of an otherwise division-free path.
    let delay: i64 = (kani::any::<i64>() << 23) >> 23;
    kani::cover!(delay < 0, "slave before the reference");
    p4_offset(kani::any(), delay, kani::any(), kani::any());
}

/// P4 entry-time widening for every EPU value, stamp and entry port.
#[cfg_attr(kani, kani::proof)]
pub fn kani_p4_entry_local() {
    let port: u8 = kani::any();
    kani::cover!(!port.is_multiple_of(4), "entry port other than 0");
    p4_entry_local(kani::any(), kani::any(), port);
}

/// SYNC start against its i128 definition, for every `now`, margin and shift, and a period
/// that is either any value below 2^16 ns or one of seven concrete grid periods.
///
/// Why not a free 64-bit period: `start_time` takes `earliest mod period` (u64) and the reference
/// side rounds up with an i128 `div_euclid`, and CBMC encodes a division as a multiplication of
/// the quotient by the divisor, so a symbolic 64-bit divisor means a 64×64 and a 128×128
/// multiplier. Here a branch either passes a literal period, which constant propagation turns
/// into a multiplication by a constant, or a `u16` widened to 64 (and 128) bits, whose high bits
/// are constant zeros, so only 16 columns of each multiplier remain. Periods of every size are
/// covered by the proptests `sync_start` and `sync_start_realistic` (proofs/tests/dc_math.rs).
#[cfg_attr(kani, kani::proof)]
pub fn kani_sync_start() {
    let (now, margin, shift): (u64, u64, i64) = (kani::any(), kani::any(), kani::any());
    // A literal period per branch (not a period chosen from a table, which would be symbolic).
    match kani::any::<u8>() & 7 {
        0 => {
            let period = u64::from(kani::any::<u16>());
            kani::cover!(period == 0, "zero period");
            sync_start(now, margin, period, shift);
        }
        1 => sync_start(now, margin, 125_000, shift),
        2 => sync_start(now, margin, 250_000, shift),
        3 => sync_start(now, margin, 1_000_000, shift),
        4 => sync_start(now, margin, 4_000_000, shift),
        // The start window is 2^31 ns: periods at its edge.
        5 => sync_start(now, margin, (1 << 31) - 1, shift),
        6 => sync_start(now, margin, 1 << 31, shift),
        _ => sync_start(now, margin, 1 << 34, shift),
    }
}

// ------------------------------------------------------------------ P3 line kernel for SMT

/// `delay::compute` on a *line* of `n ≤ 3` DC slaves (reference = slave 0; ports 0 in, 1 out;
/// the line end has only port 0), Word-generic so z3 can prove P3 on it at full width
/// (`smt::props::p3_line_kernel`): per slave `i` the 32-bit stamps `p0[i]`, `p1[i]`
/// (zero-extended into the word) and `t_diff[i]` (signed). The hop arithmetic is the **shipped**
/// `delay::twice_delay_step` (the function `compute` runs on `u64`); only the glue around it is
/// restated here, because the topology walk is not Word-generic: for `c ≥ 1`, `a = c − 1`,
/// q = a's entry (so `before` = 0), excursion = p1[a] − p0[a] and rtt_c = p1[c] − p0[c] (0 at the
/// line end), both wrapping 32-bit differences read as signed (`since`, `None` if negative),
/// corr_a = t_Diff(a), corr_c = t_Diff(c) at the line end (else 0), non_dc = 0; and the rounding
/// of `Delays::ns` for one round, ⌊(2·delay + 1)/2⌋. Returns the delays, twice the delays, and an
/// error flag (a negative stamp difference, or any flag of `twice_delay_step`).
/// [`p3_line_kernel_matches`] checks this glue against `delay::compute`.
pub fn p3_line_kernel<W: ecdc_core::num::Word>(
    n: usize,
    p0: [W; 3],
    p1: [W; 3],
    t_diff: [W; 3],
) -> ([W; 3], [W; 3], W::Bool) {
    use ecdc_core::num::Logic;
    let zero = W::lit(0);
    let mask = W::lit(1).shl(32).wrapping_sub(W::lit(1));
    let bit31 = W::lit(1).shl(31);
    // Signed 32-bit wrapping difference, sign-extended into the word (`PortTime::
    // wrapping_since` then `i64::from`).
    let since = |to: W, from: W| {
        let d = to.wrapping_sub(from).bit_and(mask);
        let neg = d.bit_and(bit31).eq(zero).not();
        W::select(neg, d.wrapping_sub(mask).wrapping_sub(W::lit(1)), d)
    };
    let mut bad = zero.eq(W::lit(1)); // false
    let mut abs2 = [zero; 3];
    let mut out = [zero; 3];
    for c in 1..n.min(3) {
        let a = c - 1;
        let end = c + 1 == n;
        let excursion = since(p1[a], p0[a]);
        let rtt_c = if end { zero } else { since(p1[c], p0[c]) };
        bad = bad.or(excursion.slt(zero)).or(rtt_c.slt(zero));
        let corr_c = if end { t_diff[c] } else { zero };
        let s = delay::twice_delay_step(abs2[a], zero, excursion, rtt_c, t_diff[a], corr_c, zero);
        bad = bad
            .or(s.measured_overflow)
            .or(s.inconsistent)
            .or(s.hop_overflow)
            .or(s.negative_hop)
            .or(s.sum_overflow);
        abs2[c] = s.abs2;
    }
    for i in 0..n.min(3) {
        // ⌊(x + 1) / 2⌋ for x ≥ 0 (the only case without an error).
        out[i] = abs2[i].wrapping_add(W::lit(1)).shr(1);
    }
    (out, abs2, bad)
}

/// [`p3_line_kernel`] at 64 bits equals `delay::compute` (delays, or an error exactly when the
/// kernel flags one) for a line of `n` 64-bit DC slaves with these stamps and `t_Diff`s, when
/// every slave's entry port is port 0. Returns whether the delays were compared and equal.
pub fn p3_line_kernel_matches(n: usize, p0: [u32; 3], p1: [u32; 3], t_diff: [i32; 3]) -> bool {
    let n = n.clamp(1, 3);
    let samples: Vec<SlaveSample> = (0..n)
        .map(|i| {
            let dl = if i + 1 < n { 0x5A00 } else { 0x5600 };
            let ports = if i + 1 < n {
                [p0[i], p1[i], 0, 0]
            } else {
                [p0[i], 0, 0, 0]
            };
            SlaveSample::from_registers(dl, 0x000C, ports, u64::from(p0[i]), t_diff[i])
        })
        .collect();
    let topo = Topology::<4>::build(&samples).expect("a line is a valid topology");
    // Arbitrary stamps can make port 1 look earlier than port 0 (entry detection, REQ-TIME-005):
    // then the shipped code walks another topology than the kernel's line; not compared.
    if (0..n).any(|i| topo.node(i).is_none_or(|nd| nd.entry != Port::P0)) {
        return false;
    }
    let w = |x: [u32; 3]| x.map(u64::from);
    let (d, twice, bad) =
        p3_line_kernel::<u64>(n, w(p0), w(p1), t_diff.map(|t| i64::from(t) as u64));
    match delay::compute(&samples, &topo, 0) {
        Ok(delays) => {
            assert!(!bad, "kernel flags an error the shipped code does not");
            for i in 0..n {
                assert_eq!(delays.ns(i), Some(d[i] as i64), "slave {i}");
                assert_eq!(delays.exact(i), Some((twice[i] as i64, 2)), "slave {i}");
            }
            true
        }
        Err(e) => {
            assert!(bad, "shipped code fails ({e:?}) where the kernel does not");
            false
        }
    }
}
