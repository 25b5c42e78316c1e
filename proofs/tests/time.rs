//! Property tests (proptest) of the kernels at full 32/64-bit width and of the typed time API,
//! with explicit boundary values mixed into every strategy, plus the `num` Kani harnesses run
//! under the random-value shim (a random test here, a proof under `cargo kani`).

use ecdc_core::time::{PortTime, SystemTime};
use ecdc_proofs::{kani_shim, num as p};
use proptest::prelude::*;

fn u32s() -> impl Strategy<Value = u32> {
    prop_oneof![
        Just(0u32),
        Just(1),
        Just(0x7FFF_FFFF),
        Just(0x8000_0000),
        Just(0x8000_0001),
        Just(u32::MAX),
        Just(u32::MAX - 1),
        any::<u32>(),
    ]
}
fn u64s() -> impl Strategy<Value = u64> {
    prop_oneof![
        Just(0u64),
        Just(1),
        Just(i64::MAX as u64),
        Just(1u64 << 63),
        Just((1u64 << 63) + 1),
        Just(u64::MAX),
        Just(u64::MAX - 1),
        Just(1u64 << 32),
        Just((1u64 << 32) - 1),
        any::<u64>(),
    ]
}
fn i32s() -> impl Strategy<Value = i32> {
    u32s().prop_map(|v| v as i32)
}
fn i64s() -> impl Strategy<Value = i64> {
    u64s().prop_map(|v| v as i64)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    /// P2, REQ-TIME-003/004 at 32 and 64 bits.
    // verifies: P2, REQ-TIME-003
    #[test]
    fn p2_wrapping_diff(tb in u64s(), d32 in i32s(), a in u64s(), b in u64s()) {
        p::prop_wrapping_diff_true::<u32>(i128::from(tb), i128::from(d32));
        p::prop_wrapping_diff_true::<u64>(i128::from(tb), i128::from(a >> 1) - i128::from(b >> 1));
        p::prop_wrapping_diff_any::<u64>(a, b);
        p::prop_wrapping_diff_any::<u32>(a as u32, b as u32);
    }

    /// P2, REQ-TIME-005 at 32 bits with 4 ports.
    // verifies: P2, REQ-TIME-005
    #[test]
    fn p2_earliest(base in u32s(), o in proptest::array::uniform4(0u32..0x8000_0000), m in any::<[bool; 4]>(), t in proptest::array::uniform4(u32s())) {
        p::prop_earliest_true_min::<u32, 4>(base, o, m);
        p::prop_earliest_any::<u32, 4>(t, m);
    }

    /// P2, REQ-TIME-007/008 at 32 and 64 bits (64-bit division: here and at reduced width).
    // verifies: P2, REQ-TIME-007
    #[test]
    fn p2_fold_phase(x in i64s(), per in u64s(), x32 in i32s(), p32 in u32s()) {
        p::prop_fold::<u64>(x, per);
        p::prop_phase::<u64>(x as u64, per);
        p::prop_fold::<u32>(x32, p32);
        p::prop_fold::<u64>(x, per % 1_000_000_000);
    }

    /// REQ-TIME-006/009..013 at 64 bits.
    // verifies: REQ-TIME-006
    #[test]
    fn other_kernels(x in i64s(), y in i64s(), z in i64s(), m in u64s(), low in u32s(), r in u64s()) {
        p::prop_extend_near::<u64>(u64::from(low), r, 32);
        p::prop_clamp::<u64>(x, y, z);
        p::prop_clamp_magnitude::<u64>(x, m);
        p::prop_saturating::<u64>(x, y);
        p::prop_half::<u64>(x);
        p::prop_sign_magnitude::<u64>(x, m);
        p::prop_sign_magnitude::<u32>(x as i32, low);
        p::prop_low32(m);
    }

    /// REQ-TIME-003/004/006/013 through the typed API: SystemTime and PortTime agree with the
    /// kernels and with i128 arithmetic.
    // verifies: REQ-TIME-003
    #[test]
    fn typed_api(t in u64s(), step in i64s(), low in u32s(), a in u32s(), b in u32s()) {
        let s = SystemTime(t);
        let u = s.wrapping_add_signed(step);
        prop_assert_eq!(u.wrapping_since(s), step);
        prop_assert_eq!(u.is_after(s), step > 0);
        let e = SystemTime::extend_low32(low, s);
        prop_assert_eq!(e.low32(), low);
        prop_assert!((-(1i64 << 31)..(1i64 << 31)).contains(&e.wrapping_since(s)));
        let (pa, pb) = (PortTime(a), PortTime(b));
        prop_assert_eq!(pa.wrapping_since(pb), a.wrapping_sub(b) as i32);
        prop_assert_eq!(PortTime(b.wrapping_add(1)).wrapping_since(pb), 1);
    }

    /// REQ-TIME-005 typed: entry port across a wrap, given the port times span < 2^31.
    // verifies: REQ-TIME-005
    #[test]
    fn typed_earliest(base in u32s(), o in proptest::array::uniform4(0u32..0x8000_0000), m in any::<[bool; 4]>()) {
        let ports: Vec<Option<PortTime>> = (0..4).map(|i| m[i].then(|| PortTime(base.wrapping_add(o[i])))).collect();
        let expect = (0..4).filter(|&i| m[i]).min_by_key(|&i| (o[i], i));
        prop_assert_eq!(PortTime::earliest(&ports), expect);
    }

    /// REQ-TIME-014: the calendar text parses back (with the forward days-from-civil formula,
    /// an independent computation) to exactly the same nanosecond count, for any u64.
    // verifies: REQ-TIME-014
    #[test]
    fn typed_display_round_trips(t in u64s()) {
        let text = SystemTime(t).to_string();
        prop_assert_eq!(parse_calendar(&text), Some(t), "{}", text);
    }

    /// REQ-TIME-015: the elapsed time is the forward distance when it is below 2^63, else 0.
    // verifies: REQ-TIME-015
    #[test]
    fn typed_saturating_since(e in u64s(), d in u64s()) {
        let t = SystemTime(e).wrapping_add(d);
        let expect = if d < (1 << 63) { d } else { 0 };
        prop_assert_eq!(t.saturating_since(SystemTime(e)), expect);
    }

    /// REQ-TIME-007: cycle alignment yields a multiple at or after t (when no 2^64 wrap).
    // verifies: REQ-TIME-007
    #[test]
    fn typed_phase(t in 0u64..(1u64 << 62), cycle in 1u64..10_000_000_000) {
        let s = SystemTime(t);
        let n = s.next_multiple_of(cycle).unwrap();
        prop_assert_eq!(n.as_nanos() % cycle, 0);
        prop_assert!(n.as_nanos() >= t && n.as_nanos() - t < cycle);
        prop_assert_eq!(s.phase_in(cycle), Some(t % cycle));
    }
}

/// `YYYY-MM-DDTHH:MM:SS.nnnnnnnnnZ` → ns since 2000-01-01 (days_from_civil, forward direction).
fn parse_calendar(s: &str) -> Option<u64> {
    let b = s.as_bytes();
    if b.len() != 30 || &s[4..5] != "-" || &s[10..11] != "T" || &s[29..] != "Z" {
        return None;
    }
    let num = |r: std::ops::Range<usize>| s.get(r)?.parse::<i128>().ok();
    let (y, m, d) = (num(0..4)?, num(5..7)?, num(8..10)?);
    let (hh, mm, ss, ns) = (num(11..13)?, num(14..16)?, num(17..19)?, num(20..29)?);
    let y = if m <= 2 { y - 1 } else { y };
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let mp = (m + 9) % 12;
    let doy = (153 * mp + 2) / 5 + d - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    let days_since_0000_03_01 = era * 146_097 + doe;
    let days = days_since_0000_03_01 - 730_425;
    let total = ((days * 86_400 + hh * 3600 + mm * 60 + ss) * 1_000_000_000) + ns;
    u64::try_from(total).ok()
}

/// The `num` Kani harnesses, run under the shim with 20 000 boundary-biased random inputs each;
/// every `cover!` in them must be reached, so a harness cannot silently test nothing.
#[test]
fn num_kani_harnesses_under_shim() {
    kani_shim::run_all(p::KANI_HARNESSES, 0xECDC_0000, 20_000, 10_000);
}
