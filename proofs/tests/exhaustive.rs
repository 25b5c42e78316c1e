//! Exhaustive checks of the `ecdc_core::num` kernels at reduced width (8 and 16 bits): the same
//! generic kernel code as the 32/64-bit instances, over every input (or, where 2^48 inputs
//! would be needed, every value of the first operands × a boundary-rich set for the rest).
//! `#[ignore]`d so `cargo test --workspace` stays fast; `.ci/layers/10-exhaustive.sh` runs them
//! with `-- --ignored` in release mode. Each prints how many cases it checked.

use ecdc_proofs::num::{self as p, Exact};

/// Every 8-bit value.
fn all8() -> impl Iterator<Item = u8> + Clone {
    0..=u8::MAX
}
/// Every 16-bit value.
fn all16() -> impl Iterator<Item = u16> + Clone {
    0..=u16::MAX
}
/// Boundary-rich 16-bit sample: small, around the sign bit, top, and a stride through the rest.
fn some16() -> Vec<u16> {
    let mut v: Vec<u16> = (0..=40).collect();
    for c in [0x7FFFu16, 0x8000, 0xFFFF] {
        for d in 0..=20u16 {
            v.push(c.wrapping_sub(d));
            v.push(c.wrapping_add(d));
        }
    }
    v.extend((0..=u16::MAX).step_by(251));
    v.sort_unstable();
    v.dedup();
    v
}
fn s8(v: u8) -> i8 {
    i8::from_ne_bytes([v])
}
fn s16(v: u16) -> i16 {
    i16::from_ne_bytes(v.to_ne_bytes())
}

/// P2, REQ-TIME-003/004: every true time b (one full period plus a wrap) × every |Δ| < 2^(N−1).
// verifies: P2, REQ-TIME-003
#[test]
#[ignore]
fn p2_wrapping_diff_8_16() {
    let mut n = 0u64;
    for tb in -256i128..512 {
        for d in -127i128..=127 {
            p::prop_wrapping_diff_true::<u8>(tb, d);
            n += 1;
        }
    }
    for tb in 0i128..=0xFFFF {
        for d in -0x7FFFi128..=0x7FFF {
            p::prop_wrapping_diff_true::<u16>(tb, d);
        }
        n += 0xFFFF;
    }
    for a in all8() {
        for b in all8() {
            p::prop_wrapping_diff_any::<u8>(a, b);
        }
    }
    println!("wrapping_diff: {n} true-difference cases + 65536 total-form cases");
}

/// P2, REQ-TIME-005: 8-bit, 2 ports fully (every base, offset pair, mask), 3 ports with every
/// offset triple and mask for 8 bases, and the no-window form on every third triple; 16-bit,
/// 4 ports with boundary offsets over every base.
// verifies: P2, REQ-TIME-005
#[test]
#[ignore]
fn p2_earliest_8_16() {
    let masks2 = [[false, false], [true, false], [false, true], [true, true]];
    let mut n = 0u64;
    for base in all8() {
        for o0 in 0..128u8 {
            for o1 in 0..128u8 {
                for m in masks2 {
                    p::prop_earliest_true_min::<u8, 2>(base, [o0, o1], m);
                }
            }
        }
        n += 128 * 128 * 4;
    }
    // 3 ports: every offset triple and mask, for bases around the wrap and the sign bit.
    for base in [0u8, 1, 64, 127, 128, 129, 192, 255] {
        for a in 0..128u8 {
            for b in 0..128u8 {
                for c in 0..128u8 {
                    for m in 0..8u8 {
                        let mask = [m & 1 != 0, m & 2 != 0, m & 4 != 0];
                        p::prop_earliest_true_min::<u8, 3>(base, [a, b, c], mask);
                    }
                }
            }
        }
        n += 128 * 128 * 128 * 8;
    }
    // Without the window precondition: every triple of 8-bit times, every mask.
    for a in all8() {
        for b in all8() {
            for c in (0..=u8::MAX).step_by(3) {
                for m in 0..8u8 {
                    let mask = [m & 1 != 0, m & 2 != 0, m & 4 != 0];
                    p::prop_earliest_any::<u8, 3>([a, b, c], mask);
                }
            }
        }
        n += 256 * 86 * 8;
    }
    let offs16 = [0u16, 1, 2, 0x3FFF, 0x4000, 0x7FFE, 0x7FFF];
    for base in all16() {
        for &a in &offs16 {
            for &b in &offs16 {
                for &c in &offs16 {
                    for &d in &offs16 {
                        p::prop_earliest_true_min::<u16, 4>(
                            base,
                            [a, b, c, d],
                            [true, true, b != 1, true],
                        );
                        n += 1;
                    }
                }
            }
        }
    }
    println!("earliest: {n} cases");
}

/// REQ-TIME-006: 8-bit all (low, ref, k); 16-bit every ref × every low byte at k = 8, and every
/// (low, ref) pair sampled at every k.
// verifies: REQ-TIME-006
#[test]
#[ignore]
fn extend_near_8_16() {
    let mut n = 0u64;
    for kb in 1..8 {
        for low in all8() {
            for r in all8() {
                p::prop_extend_near::<u8>(low, r, kb);
                n += 1;
            }
        }
    }
    for r in all16() {
        for low in 0..=0xFFu16 {
            p::prop_extend_near::<u16>(low, r, 8);
            n += 1;
        }
    }
    let s = some16();
    for kb in 1..16 {
        for &low in &s {
            for &r in &s {
                p::prop_extend_near::<u16>(low, r, kb);
                n += 1;
            }
        }
    }
    println!("extend_near: {n} cases");
}

/// P2, REQ-TIME-007/008: 8-bit every (x, p); 16-bit every x × boundary-rich periods.
// verifies: P2, REQ-TIME-007
#[test]
#[ignore]
fn p2_fold_phase_8_16() {
    let mut n = 0u64;
    for x in all8() {
        for per in all8() {
            p::prop_fold::<u8>(s8(x), per);
            p::prop_phase::<u8>(x, per);
            n += 1;
        }
    }
    for per in some16() {
        for x in all16() {
            p::prop_fold::<u16>(s16(x), per);
            p::prop_phase::<u16>(x, per);
        }
        n += 65536;
    }
    println!("fold/phase: {n} cases");
}

/// REQ-TIME-009/010: 8-bit every (x, lo, hi) and (a, b); 16-bit every x × boundary sets.
// verifies: REQ-TIME-009
#[test]
#[ignore]
fn clamp_saturate_8_16() {
    let mut n = 0u64;
    for x in all8() {
        for lo in all8() {
            for hi in all8() {
                p::prop_clamp::<u8>(s8(x), s8(lo), s8(hi));
            }
            p::prop_clamp_magnitude::<u8>(s8(x), lo);
            p::prop_saturating::<u8>(s8(x), s8(lo));
        }
        n += 256 * 257;
    }
    let s = some16();
    for x in all16() {
        for &a in &s {
            p::prop_clamp_magnitude::<u16>(s16(x), a);
            p::prop_saturating::<u16>(s16(x), s16(a));
            p::prop_saturating::<u16>(s16(a), s16(x));
            for &b in s.iter().step_by(7) {
                p::prop_clamp::<u16>(s16(x), s16(a), s16(b));
            }
        }
        n += s.len() as u64 * 3;
    }
    println!("clamp/saturate: {n} cases");
}

/// REQ-TIME-011/012: every value at 8 and 16 bits (encode, decode, both round trips).
// verifies: REQ-TIME-011
#[test]
#[ignore]
fn half_sign_magnitude_8_16() {
    for x in all8() {
        p::prop_half::<u8>(s8(x));
        for v in all8() {
            p::prop_sign_magnitude::<u8>(s8(x), v);
        }
    }
    for x in all16() {
        p::prop_half::<u16>(s16(x));
        p::prop_sign_magnitude::<u16>(s16(x), x);
        p::prop_sign_magnitude::<u16>(s16(x), x ^ 0x8000);
    }
    assert_eq!(<u16 as Exact>::wrap(-1), 0xFFFF);
    println!(
        "half/sign-magnitude: {} cases",
        256 + 65536 + 2 * 65536 + 65536
    );
}

/// REQ-TIME-008: `fold_near` (the servo's division-free fold) equals `fold` for every (x, p) at
/// 8 and 16 bits, p = 0 included (2^32 cases at 16 bits); both paths (a candidate within two
/// periods of the window, and the division) are taken.
// verifies: REQ-TIME-008
#[test]
#[ignore]
fn fold_near_equals_fold_8_16() {
    use ecdc_core::num::{fold, fold_near};
    let (mut n, mut near) = (0u64, 0u64);
    for per in all8() {
        for x in all8() {
            let f = fold::<u8>(s8(x), per);
            assert_eq!(fold_near::<u8>(s8(x), per), f, "x {x} p {per}");
            let k = (i32::from(s8(x)) - i32::from(f)).abs();
            near += u64::from(per != 0 && [0, 1, 2].map(|j| j * i32::from(per)).contains(&k));
        }
        n += 256;
    }
    for per in all16() {
        for x in all16() {
            let x = s16(x);
            assert_eq!(
                fold_near::<u16>(x, per),
                fold::<u16>(x, per),
                "x {x} p {per}"
            );
        }
        n += 65536;
    }
    assert!(near > 0 && near < 256 * 256, "8 bits: both paths taken");
    println!("fold_near = fold: {n} cases (8 bits: {near} within two periods)");
}
