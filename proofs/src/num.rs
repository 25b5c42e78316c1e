//! Property bodies for the width-generic kernels in `ecdc_core::num` (P2 and REQ-TIME-003..012).
//!
//! Each body takes concrete inputs, computes the kernel's result on a machine word and compares
//! it with a plain definition over i128 (the "spec" of the kernel), panicking with a message on
//! any mismatch. The same bodies are driven by:
//! - `proofs/tests/exhaustive.rs`: every input at 8 and 16 bits (where the domain allows);
//! - `proofs/tests/time.rs`: proptest at 32 and 64 bits with explicit boundary values;
//! - the Kani harnesses at the bottom of this file (symbolic at 32/64 bits, for users' CI).
//!
//! The full-width proofs run on the *same kernel code* instantiated with a z3 bit-vector
//! (`crate::smt`, feature `smt`), with the properties restated over wide bit-vectors.
//!
//! verifies: P2, REQ-TIME-003, REQ-TIME-004, REQ-TIME-005, REQ-TIME-006, REQ-TIME-007, REQ-TIME-008, REQ-TIME-009, REQ-TIME-010, REQ-TIME-011, REQ-TIME-012

use core::fmt::Debug;
use ecdc_core::num::{self as k, Word};

/// A machine word whose values can be read exactly as integers (reference semantics).
pub trait Exact: Word<Bool = bool> + Debug + Eq {
    /// The value as an unsigned integer in [0, 2^N).
    fn to_i128(self) -> i128;
    /// `v mod 2^N` as a word.
    fn wrap(v: i128) -> Self;
    /// A signed reading as an integer in [−2^(N−1), 2^(N−1)).
    fn signed_to_i128(s: Self::Signed) -> i128;
    /// `v` (which must fit) as the signed type; wraps modulo 2^N otherwise.
    fn signed_wrap(v: i128) -> Self::Signed {
        Self::wrap(v).to_signed()
    }
}

macro_rules! exact {
    ($u:ty) => {
        impl Exact for $u {
            fn to_i128(self) -> i128 {
                i128::from(self)
            }
            // Two's complement truncation keeps exactly v mod 2^N. Not `rem_euclid`: the Kani
            // harnesses call this, and CBMC would encode that as a 128-bit divider.
            #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
            fn wrap(v: i128) -> Self {
                v as $u
            }
            fn signed_to_i128(s: Self::Signed) -> i128 {
                i128::from(s)
            }
        }
    };
}
exact!(u8);
exact!(u16);
exact!(u32);
exact!(u64);

/// 2^(N−1) as an integer.
pub fn half_range<W: Exact>() -> i128 {
    1i128 << (W::BITS - 1)
}

/// P2 / REQ-TIME-003: for a true time `t_b` (any integer) and a true difference `delta` with
/// |delta| < 2^(N−1), the kernel on the wrapped times returns exactly `delta`. Also asserts
/// REQ-TIME-004 (`is_after` ⇔ delta > 0, distance = |delta|).
pub fn prop_wrapping_diff_true<W: Exact>(t_b: i128, delta: i128) {
    let h = half_range::<W>();
    if delta <= -h || delta >= h {
        return; // outside the precondition: nothing is claimed
    }
    let a = W::wrap(t_b + delta);
    let b = W::wrap(t_b);
    let d = W::signed_to_i128(k::wrapping_diff(a, b));
    assert_eq!(d, delta, "wrapping_diff({a:?}, {b:?})");
    assert_eq!(
        k::is_after(a, b),
        delta > 0,
        "is_after({a:?}, {b:?}), delta {delta}"
    );
    assert_eq!(
        k::wrapping_distance(a, b).to_i128(),
        delta.abs(),
        "distance({a:?}, {b:?})"
    );
}

/// REQ-TIME-003 total form: for every pair of words, the result d is in [−2^(N−1), 2^(N−1)) and
/// b + d ≡ a (mod 2^N); the distance is |d| (in [0, 2^(N−1)]).
pub fn prop_wrapping_diff_any<W: Exact>(a: W, b: W) {
    let h = half_range::<W>();
    let d = W::signed_to_i128(k::wrapping_diff(a, b));
    assert!(
        (-h..h).contains(&d),
        "range of wrapping_diff({a:?}, {b:?}) = {d}"
    );
    assert_eq!(
        W::wrap(b.to_i128() + d),
        a,
        "b + wrapping_diff != a for ({a:?}, {b:?})"
    );
    assert_eq!(
        k::wrapping_distance(a, b).to_i128(),
        d.abs(),
        "distance({a:?}, {b:?})"
    );
    assert_eq!(k::is_after(a, b), d > 0, "is_after({a:?}, {b:?})");
}

/// P2 / REQ-TIME-005: true times `base + offsets[i]` with offsets in [0, 2^(N−1)) (so the set
/// spans less than 2^(N−1), wherever the wrap falls); the kernel on the wrapped times returns
/// the first active index with the smallest true time, and `found` iff any port is active.
pub fn prop_earliest_true_min<W: Exact, const P: usize>(
    base: W,
    offsets: [W; P],
    active: [bool; P],
) {
    let h = half_range::<W>();
    let mut times = [W::lit(0); P];
    for (t, o) in times.iter_mut().zip(offsets) {
        if o.to_i128() >= h {
            return; // outside the precondition
        }
        *t = W::wrap(base.to_i128() + o.to_i128());
    }
    let (found, idx) = k::earliest(&times, &active);
    let mut expect: Option<usize> = None;
    for i in 0..P {
        if active[i] && expect.is_none_or(|e| offsets[i].to_i128() < offsets[e].to_i128()) {
            expect = Some(i);
        }
    }
    assert_eq!(found, expect.is_some(), "found for {times:?} {active:?}");
    if let Some(e) = expect {
        assert_eq!(idx.to_i128(), e as i128, "earliest of {times:?} {active:?}");
    }
}

/// REQ-TIME-005 without the window precondition: never panics, `found` iff any active, and the
/// chosen index is active and in range.
pub fn prop_earliest_any<W: Exact, const P: usize>(times: [W; P], active: [bool; P]) {
    let (found, idx) = k::earliest(&times, &active);
    assert_eq!(found, active.iter().any(|&a| a));
    if found {
        let i = usize::try_from(idx.to_i128()).unwrap_or(usize::MAX);
        assert!(
            i < P && active[i],
            "earliest chose inactive/out-of-range {i}"
        );
    }
}

/// REQ-TIME-006: r ≡ low (mod 2^k) and wrapping_diff(r, reference) ∈ [−2^(k−1), 2^(k−1)).
pub fn prop_extend_near<W: Exact>(low: W, reference: W, kbits: u32) {
    if kbits == 0 || kbits >= W::BITS {
        return;
    }
    let r = k::extend_near(low, reference, kbits);
    // Masks and shifts rather than `% 2^k` and `/ 2`: no i128 division on a Kani path.
    let m = 1i128 << kbits;
    let half = 1i128 << (kbits - 1);
    assert_eq!(
        r.to_i128() & (m - 1),
        low.to_i128() & (m - 1),
        "low bits of extend_near({low:?}, {reference:?}, {kbits})"
    );
    let d = W::signed_to_i128(k::wrapping_diff(r, reference));
    assert!(
        (-half..half).contains(&d),
        "extend_near({low:?}, {reference:?}, {kbits}) = {r:?} is {d} away"
    );
}

/// REQ-TIME-007: phase(x, p) = x mod p for p > 0.
pub fn prop_phase<W: Exact>(x: W, p: W) {
    if p.to_i128() == 0 {
        return;
    }
    assert_eq!(
        k::phase(x, p).to_i128(),
        x.to_i128() % p.to_i128(),
        "phase({x:?}, {p:?})"
    );
}

/// P2 / REQ-TIME-008: fold(x, p) ∈ (−p/2, p/2] and ≡ x (mod p), for every x and p > 0.
pub fn prop_fold<W: Exact>(x: W::Signed, p: W) {
    let pi = p.to_i128();
    if pi == 0 {
        return;
    }
    let xi = W::signed_to_i128(x);
    let f = W::signed_to_i128(k::fold::<W>(x, p));
    assert!(
        -pi < 2 * f && 2 * f <= pi,
        "fold({xi}, {pi}) = {f} out of (−p/2, p/2]"
    );
    // Congruence through the N-bit remainder, not an i128 `rem_euclid` (for Kani a 128-bit
    // divider by a symbolic p): with x an N-bit signed value and f in (−p/2, p/2], |x − f| < 2^N,
    // so the word holds |x − f| exactly and `urem` by p decides "p divides x − f".
    let d = (xi - f).abs();
    assert!(
        d < 1i128 << W::BITS,
        "fold({xi}, {pi}) = {f}: |x − f| ≥ 2^N"
    );
    assert_eq!(
        W::wrap(d).urem(p),
        W::lit(0),
        "fold({xi}, {pi}) = {f} not congruent"
    );
}

/// REQ-TIME-009: clamp = min(max(x, lo), hi) over integers.
pub fn prop_clamp<W: Exact>(x: W::Signed, lo: W::Signed, hi: W::Signed) {
    let (xi, l, h) = (
        W::signed_to_i128(x),
        W::signed_to_i128(lo),
        W::signed_to_i128(hi),
    );
    let c = W::signed_to_i128(k::clamp::<W>(x, lo, hi));
    assert_eq!(c, xi.max(l).min(h), "clamp({xi}, {l}, {h})");
}

/// REQ-TIME-009: clamp_magnitude(x, m) = clamp(x, −m', m') with m' = min(m, 2^(N−1) − 1).
pub fn prop_clamp_magnitude<W: Exact>(x: W::Signed, m: W) {
    let lim = m.to_i128().min(half_range::<W>() - 1);
    let xi = W::signed_to_i128(x);
    let c = W::signed_to_i128(k::clamp_magnitude::<W>(x, m));
    assert_eq!(c, xi.clamp(-lim, lim), "clamp_magnitude({xi}, {m:?})");
}

/// REQ-TIME-010: saturating add and sub equal the exact result clamped to the signed range.
pub fn prop_saturating<W: Exact>(a: W::Signed, b: W::Signed) {
    let h = half_range::<W>();
    let (ai, bi) = (W::signed_to_i128(a), W::signed_to_i128(b));
    let s = W::signed_to_i128(k::saturating_add::<W>(a, b));
    assert_eq!(s, (ai + bi).clamp(-h, h - 1), "saturating_add({ai}, {bi})");
    let d = W::signed_to_i128(k::saturating_sub::<W>(a, b));
    assert_eq!(d, (ai - bi).clamp(-h, h - 1), "saturating_sub({ai}, {bi})");
}

/// REQ-TIME-011: half_toward_zero(x) = x / 2 truncated toward zero, i.e. ⌊|x|/2⌋ with the sign
/// of x (written with a shift of the magnitude: no i128 division on the Kani path).
pub fn prop_half<W: Exact>(x: W::Signed) {
    let xi = W::signed_to_i128(x);
    let want = if xi < 0 { -((-xi) >> 1) } else { xi >> 1 };
    assert_eq!(
        W::signed_to_i128(k::half_toward_zero::<W>(x)),
        want,
        "half({xi})"
    );
}

/// REQ-TIME-012: sign-magnitude encode matches its definition, decode inverts it, and decode
/// of any word lies in [−(2^(N−1)−1), 2^(N−1)−1] with the sign bit meaning "negative".
pub fn prop_sign_magnitude<W: Exact>(x: W::Signed, v: W) {
    let h = half_range::<W>();
    let xi = W::signed_to_i128(x);
    let e = k::sign_magnitude_encode::<W>(x).to_i128();
    let expect = xi.abs().min(h - 1) + if xi < 0 { h } else { 0 };
    assert_eq!(e, expect, "encode({xi})");
    let back = W::signed_to_i128(k::sign_magnitude_decode::<W>(W::wrap(e)));
    assert_eq!(back, xi.max(-(h - 1)), "decode(encode({xi}))");
    let vi = v.to_i128();
    let dv = W::signed_to_i128(k::sign_magnitude_decode::<W>(v));
    let mag = vi & (h - 1); // vi mod 2^(N−1), without an i128 remainder
    assert_eq!(dv, if vi >= h { -mag } else { mag }, "decode({vi:#x})");
    if vi != h {
        // Every word except "negative zero" round-trips.
        assert_eq!(
            k::sign_magnitude_encode::<W>(W::signed_wrap(dv)),
            v,
            "encode(decode({vi:#x}))"
        );
    }
}

/// REQ-TIME-013: low32 keeps exactly t mod 2^32.
pub fn prop_low32(t: u64) {
    assert_eq!(u64::from(k::low32(t)), t % (1u64 << 32));
}

// ---------------------------------------------------------------- Kani harnesses
//
// Symbolic at full width for users with Kani (see .github/workflows/kani.yml). Here the same
// functions run under `crate::kani_shim` with random boundary-biased values
// (proofs/tests/time.rs). Bounds: no loops except `earliest` over 4 ports (unwind 6, 10).
// Divisions: the reference side (`Exact`, the `prop_*` bodies) uses truncation, masks and
// shifts, never an i128 `/` or `%`, so the only dividers CBMC sees are the 32-bit ones of
// `kani_p2_fold_u32` (docs/verification.md, "Kani harness sizes").

#[cfg(not(kani))]
use crate::kani_shim as kani;

/// Kani: P2 wrapping difference, 32-bit port times, true times spanning any number of wraps.
#[cfg_attr(kani, kani::proof)]
pub fn kani_p2_wrapping_diff_u32() {
    let t_b: u64 = kani::any();
    let delta: i32 = kani::any();
    kani::assume(delta != i32::MIN);
    kani::cover!(
        t_b.wrapping_add_signed(i64::from(delta)) < t_b && delta > 0,
        "wrap between b and a"
    );
    prop_wrapping_diff_true::<u32>(i128::from(t_b), i128::from(delta));
}

/// Kani: P2 wrapping difference, 64-bit system time.
#[cfg_attr(kani, kani::proof)]
pub fn kani_p2_wrapping_diff_u64() {
    let a: u64 = kani::any();
    let b: u64 = kani::any();
    kani::cover!(a < b && k::is_after(a, b), "a after b across the wrap");
    prop_wrapping_diff_any::<u64>(a, b);
}

/// Four port times for the entry-port harnesses: a base, an offset per port below 2^31 (the
/// true times span less than half the 32-bit circle) and which ports take part.
fn any_port_times() -> (u32, [u32; 4], [bool; 4]) {
    let base: u32 = kani::any();
    let offsets: [u32; 4] = kani::any::<[u32; 4]>().map(|o| o & 0x7FFF_FFFF);
    (base, offsets, kani::any())
}

/// Kani: P2 entry port under wrap, 4 ports, any activity mask.
#[cfg_attr(kani, kani::proof)]
#[cfg_attr(kani, kani::unwind(6))]
pub fn kani_p2_earliest_port() {
    let (base, offsets, active) = any_port_times();
    kani::cover!(
        base.checked_add(offsets[0]).is_none() && active[0],
        "active port past the wrap"
    );
    prop_earliest_true_min::<u32, 4>(base, offsets, active);
}

/// Kani: P2 fold range and congruence, 32-bit. The divisions on this path are two 32-bit
/// remainders by the symbolic p (the kernel's `urem` and the congruence check's); the 64-bit
/// instance is proved on z3 with `urem` abstracted and checked exhaustively at 8/16 bits.
#[cfg_attr(kani, kani::proof)]
pub fn kani_p2_fold_u32() {
    let x: i32 = kani::any();
    let p: u32 = kani::any();
    kani::assume(p > 0);
    kani::cover!(x < 0 && p & 1 == 1, "negative x, odd period");
    prop_fold::<u32>(x, p);
}

/// Kani: REQ-TIME-006 widening a 32-bit time near a 64-bit reference.
#[cfg_attr(kani, kani::proof)]
pub fn kani_extend_low32() {
    let low: u32 = kani::any();
    let reference: u64 = kani::any();
    kani::cover!(
        reference < (1 << 31) && low > (1 << 31),
        "result below zero wraps"
    );
    prop_extend_near::<u64>(u64::from(low), reference, 32);
}

/// Kani: REQ-TIME-009/010/011 clamp, saturation and halving at 64 bits.
#[cfg_attr(kani, kani::proof)]
pub fn kani_clamp_saturate_i64() {
    let (x, lo, hi): (i64, i64, i64) = (kani::any(), kani::any(), kani::any());
    let m: u64 = kani::any();
    kani::cover!(lo > hi, "inverted bounds");
    prop_clamp::<u64>(x, lo, hi);
    prop_clamp_magnitude::<u64>(x, m);
    prop_saturating::<u64>(x, lo);
    prop_half::<u64>(x);
}

/// Kani: REQ-TIME-012 sign-magnitude (0x092C) at 32 bits.
#[cfg_attr(kani, kani::proof)]
pub fn kani_sign_magnitude_u32() {
    let x: i32 = kani::any();
    let v: u32 = kani::any();
    kani::cover!(v == 0x8000_0000, "negative zero");
    prop_sign_magnitude::<u32>(x, v);
}

/// Kani: REQ-TIME-005 through the typed API the DC topology code calls: for 4 optional port
/// times within half the 32-bit circle of a base, `PortTime::earliest` returns the present
/// port with the least true time (first on ties), or `None` when no port is present.
#[cfg_attr(kani, kani::proof)]
#[cfg_attr(kani, kani::unwind(10))]
pub fn kani_port_time_earliest() {
    use ecdc_core::time::PortTime;
    let (base, offsets, present) = any_port_times();
    let ports: [Option<PortTime>; 4] =
        core::array::from_fn(|i| present[i].then(|| PortTime(base.wrapping_add(offsets[i]))));
    kani::cover!(
        present.iter().filter(|&&p| p).count() >= 2 && base > u32::MAX - 0x7FFF_FFFF,
        "several ports, wrap possible"
    );
    let mut expect: Option<usize> = None;
    for i in 0..4 {
        if present[i] && expect.is_none_or(|e| offsets[i] < offsets[e]) {
            expect = Some(i);
        }
    }
    assert_eq!(PortTime::earliest(&ports), expect);
}

/// Every harness in this file, for the shim runner.
pub const KANI_HARNESSES: &[(&str, fn())] = &[
    ("kani_p2_wrapping_diff_u32", kani_p2_wrapping_diff_u32),
    ("kani_p2_wrapping_diff_u64", kani_p2_wrapping_diff_u64),
    ("kani_p2_earliest_port", kani_p2_earliest_port),
    ("kani_p2_fold_u32", kani_p2_fold_u32),
    ("kani_extend_low32", kani_extend_low32),
    ("kani_clamp_saturate_i64", kani_clamp_saturate_i64),
    ("kani_sign_magnitude_u32", kani_sign_magnitude_u32),
    ("kani_port_time_earliest", kani_port_time_earliest),
];
