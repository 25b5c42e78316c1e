//! Width-generic arithmetic kernels (wrapping difference, folding, clamping, sign-magnitude),
//! written once against the [`Word`] trait so the SMT proofs check this very code.
//!
//! Why a trait: the same kernel body runs on `u32`/`u64` in the protocol code, on `u8`/`u16` in
//! the exhaustive checks, and on a symbolic bit-vector in `ecdc-proofs` (z3), where every
//! `if` must become a symbolic choice. So kernels never branch on a comparison: they compute a
//! [`Word::Bool`] and pick with [`Word::select`]. For machine words `Bool` is `bool` and
//! `select` is an ordinary `if`, which the optimiser turns back into the obvious code.
//!
//! A [`Word`] is an N-bit unsigned bit pattern. "Signed" below means the same bits read as two's
//! complement; [`Word::Signed`] is that reading as a separate type (`i32` for `u32`) so public
//! APIs cannot confuse the two. All operations wrap modulo 2^N, so no kernel can overflow or
//! panic for any input (REQ-CONV-008); every precondition below is about the *meaning* of the
//! result, never about safety.
//!
//! Requirement ids: REQ-TIME-0xx in `spec/req/time.md`.

/// Symbolic-or-concrete truth value returned by [`Word`] comparisons.
///
/// # Examples
///
/// ```
/// use ecdc_core::num::Logic;
///
/// // For machine words the truth value is a plain `bool`.
/// assert!(Logic::and(true, Logic::not(false)));
/// assert!(!Logic::or(false, false));
/// ```
pub trait Logic: Copy {
    /// Logical and.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::num::Logic;
    ///
    /// assert!(Logic::and(true, true));
    /// assert!(!Logic::and(true, false));
    /// ```
    fn and(self, rhs: Self) -> Self;
    /// Logical or.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::num::Logic;
    ///
    /// assert!(Logic::or(false, true));
    /// assert!(!Logic::or(false, false));
    /// ```
    fn or(self, rhs: Self) -> Self;
    /// Logical not.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::num::Logic;
    ///
    /// assert!(Logic::not(false));
    /// ```
    fn not(self) -> Self;
}

impl Logic for bool {
    #[inline]
    fn and(self, rhs: Self) -> Self {
        self && rhs
    }
    #[inline]
    fn or(self, rhs: Self) -> Self {
        self || rhs
    }
    #[inline]
    fn not(self) -> Self {
        !self
    }
}

/// An N-bit unsigned machine word with modular arithmetic: the only operations the kernels use.
///
/// Kept deliberately small so the z3 bit-vector implementation in `ecdc-proofs` is a few lines
/// per method and obviously faithful (each method is one SMT-LIB `bv*` operator).
///
/// # Examples
///
/// ```
/// use ecdc_core::num::{self, Word};
///
/// // The same kernel on two widths: the 8-bit run is what the exhaustive checks enumerate.
/// assert_eq!(num::wrapping_diff::<u8>(2, 250), 8);
/// assert_eq!(num::wrapping_diff::<u32>(2, u32::MAX - 5), 8);
/// assert_eq!(<u16 as Word>::BITS, 16);
/// ```
pub trait Word: Copy {
    /// Result of comparisons: `bool` for machine words, a symbolic Boolean for SMT.
    type Bool: Logic;
    /// The same N bits read as two's complement (`i32` for `u32`, the word itself for SMT).
    type Signed: Copy;
    /// Width N in bits.
    const BITS: u32;

    /// The word with value `v` (`v` < 2^N for every width used; u8 fits all of them).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::num::Word;
    ///
    /// assert_eq!(<u64 as Word>::lit(7), 7u64);
    /// ```
    fn lit(v: u8) -> Self;
    /// `self + rhs mod 2^N` (`bvadd`).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::num::Word;
    ///
    /// assert_eq!(Word::wrapping_add(250u8, 10), 4);
    /// ```
    fn wrapping_add(self, rhs: Self) -> Self;
    /// `self − rhs mod 2^N` (`bvsub`).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::num::Word;
    ///
    /// assert_eq!(Word::wrapping_sub(4u8, 10), 250);
    /// ```
    fn wrapping_sub(self, rhs: Self) -> Self;
    /// `self · rhs mod 2^N` (`bvmul`): the low N bits of the product, the same bits whether the
    /// operands are read as unsigned or as two's complement.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::num::Word;
    ///
    /// // 0xFF is −1 read as two's complement: −1 · 3 = −3 = 0xFD, and 255 · 3 = 765 ≡ 0xFD.
    /// assert_eq!(Word::wrapping_mul(0xFFu8, 3), 0xFD);
    /// ```
    fn wrapping_mul(self, rhs: Self) -> Self;
    /// Bitwise and (`bvand`).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::num::Word;
    ///
    /// assert_eq!(Word::bit_and(0b1100u8, 0b1010), 0b1000);
    /// ```
    fn bit_and(self, rhs: Self) -> Self;
    /// Bitwise or (`bvor`).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::num::Word;
    ///
    /// assert_eq!(Word::bit_or(0b1100u8, 0b1010), 0b1110);
    /// ```
    fn bit_or(self, rhs: Self) -> Self;
    /// Logical shift left by `n` < N (`bvshl`).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::num::Word;
    ///
    /// assert_eq!(Word::shl(0x81u8, 1), 0x02);
    /// ```
    fn shl(self, n: u32) -> Self;
    /// Logical shift right by `n` < N (`bvlshr`).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::num::Word;
    ///
    /// // Logical: the sign bit is not copied.
    /// assert_eq!(Word::shr(0x80u8, 7), 1);
    /// ```
    fn shr(self, n: u32) -> Self;
    /// Unsigned remainder; `rhs` must be non-zero (`bvurem`; machine words return 0 for 0).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::num::Word;
    ///
    /// assert_eq!(Word::urem(17u32, 5), 2);
    /// assert_eq!(Word::urem(17u32, 0), 0);
    /// ```
    fn urem(self, rhs: Self) -> Self;
    /// Equality.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::num::Word;
    ///
    /// assert!(Word::eq(5u16, 5));
    /// assert!(!Word::eq(5u16, 6));
    /// ```
    fn eq(self, rhs: Self) -> Self::Bool;
    /// Unsigned less-than (`bvult`).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::num::Word;
    ///
    /// assert!(Word::ult(1u8, 0xFF));
    /// ```
    fn ult(self, rhs: Self) -> Self::Bool;
    /// Signed (two's complement) less-than (`bvslt`).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::num::Word;
    ///
    /// // 0xFF read as two's complement is −1, which is less than 1.
    /// assert!(Word::slt(0xFFu8, 1));
    /// ```
    fn slt(self, rhs: Self) -> Self::Bool;
    /// `if c { a } else { b }` (`ite`).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::num::Word;
    ///
    /// assert_eq!(<u32 as Word>::select(true, 1, 2), 1);
    /// assert_eq!(<u32 as Word>::select(false, 1, 2), 2);
    /// ```
    fn select(c: Self::Bool, a: Self, b: Self) -> Self;
    /// [`Word::select`] with `b` computed only when needed: machine words evaluate `b` only when
    /// `c` is false, so a rare expensive fallback (a division) stays off the common path; a
    /// symbolic word evaluates both (`ite`), which is the default.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::num::Word;
    ///
    /// // The fallback is not evaluated when the condition holds.
    /// assert_eq!(<u64 as Word>::select_or_else(true, 1, || unreachable!()), 1);
    /// assert_eq!(<u64 as Word>::select_or_else(false, 1, || 1_000 % 7), 6);
    /// ```
    #[inline]
    fn select_or_else(c: Self::Bool, a: Self, b: impl FnOnce() -> Self) -> Self {
        Self::select(c, a, b())
    }
    /// Reinterpret as two's complement.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::num::Word;
    ///
    /// assert_eq!(Word::to_signed(0xFFFF_FFFEu32), -2i32);
    /// ```
    fn to_signed(self) -> Self::Signed;
    /// Reinterpret two's complement bits as the word.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::num::Word;
    ///
    /// assert_eq!(<u32 as Word>::from_signed(-2), 0xFFFF_FFFE);
    /// ```
    fn from_signed(s: Self::Signed) -> Self;
}

macro_rules! machine_word {
    ($u:ty, $s:ty) => {
        impl Word for $u {
            type Bool = bool;
            type Signed = $s;
            const BITS: u32 = <$u>::BITS;
            #[inline]
            fn lit(v: u8) -> Self {
                <$u>::from(v)
            }
            #[inline]
            fn wrapping_add(self, rhs: Self) -> Self {
                <$u>::wrapping_add(self, rhs)
            }
            #[inline]
            fn wrapping_sub(self, rhs: Self) -> Self {
                <$u>::wrapping_sub(self, rhs)
            }
            #[inline]
            fn wrapping_mul(self, rhs: Self) -> Self {
                <$u>::wrapping_mul(self, rhs)
            }
            #[inline]
            fn bit_and(self, rhs: Self) -> Self {
                self & rhs
            }
            #[inline]
            fn bit_or(self, rhs: Self) -> Self {
                self | rhs
            }
            #[inline]
            fn shl(self, n: u32) -> Self {
                <$u>::wrapping_shl(self, n)
            }
            #[inline]
            fn shr(self, n: u32) -> Self {
                <$u>::wrapping_shr(self, n)
            }
            #[inline]
            fn urem(self, rhs: Self) -> Self {
                <$u>::checked_rem(self, rhs).unwrap_or(0)
            }
            #[inline]
            fn eq(self, rhs: Self) -> bool {
                self == rhs
            }
            #[inline]
            fn ult(self, rhs: Self) -> bool {
                self < rhs
            }
            #[inline]
            fn slt(self, rhs: Self) -> bool {
                <$s>::from_ne_bytes(self.to_ne_bytes()) < <$s>::from_ne_bytes(rhs.to_ne_bytes())
            }
            #[inline]
            fn select(c: bool, a: Self, b: Self) -> Self {
                if c {
                    a
                } else {
                    b
                }
            }
            #[inline]
            fn select_or_else(c: bool, a: Self, b: impl FnOnce() -> Self) -> Self {
                if c {
                    a
                } else {
                    b()
                }
            }
            #[inline]
            fn to_signed(self) -> $s {
                <$s>::from_ne_bytes(self.to_ne_bytes())
            }
            #[inline]
            fn from_signed(s: $s) -> Self {
                <$u>::from_ne_bytes(s.to_ne_bytes())
            }
        }
    };
}

// u8/u16 exist for exhaustive checks of the same kernels at reduced width (docs/verification.md).
machine_word!(u8, i8);
machine_word!(u16, i16);
machine_word!(u32, i32);
machine_word!(u64, i64);

// ------------------------------------------------------------------ constants

/// 2^(N−1): the sign bit, also the bit pattern of the most negative signed value.
///
/// # Examples
///
/// ```
/// use ecdc_core::num;
///
/// assert_eq!(num::sign_bit::<u8>(), 0x80);
/// assert_eq!(num::sign_bit::<u32>(), 0x8000_0000);
/// ```
#[inline]
pub fn sign_bit<W: Word>() -> W {
    W::lit(1).shl(W::BITS.wrapping_sub(1))
}

/// 2^(N−1) − 1: the largest signed value, also the largest sign-magnitude magnitude.
///
/// # Examples
///
/// ```
/// use ecdc_core::num;
///
/// assert_eq!(num::signed_max::<u16>(), i16::MAX as u16);
/// ```
#[inline]
pub fn signed_max<W: Word>() -> W {
    sign_bit::<W>().wrapping_sub(W::lit(1))
}

/// Signed "x < 0".
///
/// # Examples
///
/// ```
/// use ecdc_core::num;
///
/// assert!(num::is_negative(0x80u8));
/// assert!(!num::is_negative(0x7Fu8));
/// ```
#[inline]
pub fn is_negative<W: Word>(x: W) -> W::Bool {
    x.slt(W::lit(0))
}

/// Two's complement negation `0 − x` (wraps for the most negative value).
///
/// # Examples
///
/// ```
/// use ecdc_core::num;
///
/// assert_eq!(num::wrapping_neg(1u8), 0xFF);
/// // The most negative value is its own negation.
/// assert_eq!(num::wrapping_neg(0x80u8), 0x80);
/// ```
#[inline]
pub fn wrapping_neg<W: Word>(x: W) -> W {
    W::lit(0).wrapping_sub(x)
}

/// |x| of a signed bit pattern, as an unsigned word in [0, 2^(N−1)]. Exact for every input,
/// including the most negative value (whose magnitude 2^(N−1) is representable unsigned).
///
/// # Examples
///
/// ```
/// use ecdc_core::num;
///
/// assert_eq!(num::unsigned_abs(0xFFu8), 1); // |−1|
/// assert_eq!(num::unsigned_abs(0x80u8), 128); // |−128|, representable unsigned
/// ```
#[inline]
pub fn unsigned_abs<W: Word>(x: W) -> W {
    W::select(is_negative(x), wrapping_neg(x), x)
}

// ------------------------------------------------------------------ wrap-safe time arithmetic

/// REQ-TIME-003: `a − b mod 2^N`, read as signed. Equals the true signed difference of the
/// unwrapped times whenever |a − b| < 2^(N−1), whatever wraps lie between them.
///
/// # Examples
///
/// ```
/// use ecdc_core::num;
///
/// // A 32-bit latch wrapped between two stamps 32 ns apart.
/// assert_eq!(num::wrapping_diff(16u32, u32::MAX - 15), 32);
/// assert_eq!(num::wrapping_diff(u32::MAX - 15, 16u32), -32);
/// ```
#[inline]
pub fn wrapping_diff<W: Word>(a: W, b: W) -> W::Signed {
    a.wrapping_sub(b).to_signed()
}

/// REQ-TIME-004: `a` is strictly after `b` on the wrapping circle (`wrapping_diff(a, b) > 0`).
///
/// # Examples
///
/// ```
/// use ecdc_core::num;
///
/// assert!(num::is_after(3u32, u32::MAX));
/// assert!(!num::is_after(7u32, 7));
/// ```
#[inline]
pub fn is_after<W: Word>(a: W, b: W) -> W::Bool {
    W::lit(0).slt(a.wrapping_sub(b))
}

/// REQ-TIME-004: |a − b| on the wrapping circle: the shorter way round, in [0, 2^(N−1)].
///
/// # Examples
///
/// ```
/// use ecdc_core::num;
///
/// assert_eq!(num::wrapping_distance(3u32, u32::MAX), 4);
/// assert_eq!(num::wrapping_distance(u32::MAX, 3u32), 4);
/// ```
#[inline]
pub fn wrapping_distance<W: Word>(a: W, b: W) -> W {
    unsigned_abs(a.wrapping_sub(b))
}

/// REQ-TIME-005: index (as a word) of the earliest *active* time, i.e. the active time that
/// every other active time is at-or-after by wrapping difference; the first such on ties.
/// Returns `(found, index)`; `index` is 0 when nothing is active.
///
/// Correct (the true minimum of the unwrapped times) whenever all active times lie within a
/// window shorter than 2^(N−1): then "is after" is a total order agreeing with the true one, so
/// the linear scan finds the true minimum. A plain `<` on wrapped values fails as soon as a
/// wrap falls inside the window (SOEM #979, ethercrab #374).
/// `times` and `active` are paired by position; extra entries of the longer slice are ignored.
///
/// # Examples
///
/// ```
/// use ecdc_core::num;
///
/// // Index 2 wrapped past zero, so index 0 (just before the wrap) is the earliest; index 1
/// // is inactive and ignored.
/// let times = [u32::MAX - 10, 0, 20];
/// let active = [true, false, true];
/// assert_eq!(num::earliest(&times, &active), (true, 0));
/// assert_eq!(num::earliest::<u32>(&times, &[false; 3]), (false, 0));
/// ```
pub fn earliest<W: Word>(times: &[W], active: &[W::Bool]) -> (W::Bool, W) {
    let mut found = false_of::<W>();
    let mut best_t = W::lit(0);
    let mut best_i = W::lit(0);
    let mut i = W::lit(0);
    for (&t, &a) in times.iter().zip(active) {
        // Take t if active and (nothing found yet, or t strictly before the best so far).
        let take = a.and(found.not().or(is_after(best_t, t)));
        best_t = W::select(take, t, best_t);
        best_i = W::select(take, i, best_i);
        found = found.or(a);
        i = i.wrapping_add(W::lit(1));
    }
    (found, best_i)
}

/// A `false` of `W::Bool`, built from the trait alone.
#[inline]
fn false_of<W: Word>() -> W::Bool {
    W::lit(0).ult(W::lit(0))
}

/// REQ-TIME-006: the full-width time nearest to `reference` whose low `k` bits equal those of
/// `low`, for 0 < k < N. The result `r` satisfies `r ≡ low (mod 2^k)` and
/// `wrapping_diff(r, reference) ∈ [−2^(k−1), 2^(k−1))`. Used to widen a 32-bit port/system
/// time read from a 32-bit DC slave back to 64 bits near a known 64-bit time.
///
/// # Examples
///
/// ```
/// use ecdc_core::num;
///
/// // Widen the low 32 bits 0x10 read just after a wrap, near a 64-bit time just before it.
/// let r = num::extend_near(0x10u64, 0x4_FFFF_FF00u64, 32);
/// assert_eq!(r, 0x5_0000_0010);
/// ```
#[inline]
pub fn extend_near<W: Word>(low: W, reference: W, k: u32) -> W {
    let full = W::lit(1).shl(k);
    let half = W::lit(1).shl(k.wrapping_sub(1));
    let mask = full.wrapping_sub(W::lit(1));
    // Forward distance from reference to low, modulo 2^k, in [0, 2^k).
    let d = low.wrapping_sub(reference).bit_and(mask);
    // Read it as a k-bit signed value: [half, full) means "behind the reference".
    let back = d.ult(half).not();
    reference.wrapping_add(W::select(back, d.wrapping_sub(full), d))
}

// ------------------------------------------------------------------ phase folding

/// REQ-TIME-007: `x mod p` in [0, p) for an unsigned `x`; `p` must be non-zero (0 yields 0 on
/// machine words). Phase of a system time within a cycle.
///
/// # Examples
///
/// ```
/// use ecdc_core::num;
///
/// assert_eq!(num::phase(2_500_000u64, 1_000_000), 500_000);
/// ```
#[inline]
pub fn phase<W: Word>(x: W, p: W) -> W {
    x.urem(p)
}

/// REQ-TIME-008: fold a signed `x` into (−p/2, p/2] with the result ≡ x (mod p), for any
/// unsigned period p > 0 (p = 0 yields a meaningless value, never a panic). Phase error of a
/// SYNC edge relative to the nearest cycle boundary. |result| ≤ p/2 < 2^(N−1), so it is
/// always representable.
///
/// # Examples
///
/// ```
/// use ecdc_core::num;
///
/// // With a 1 ms cycle, a SYNC edge 900 µs late is 100 µs early for the next cycle.
/// assert_eq!(num::fold::<u64>(900_000, 1_000_000), -100_000);
/// assert_eq!(num::fold::<u64>(-2_300_000, 1_000_000), -300_000);
/// // Exactly half a period folds to +p/2.
/// assert_eq!(num::fold::<u64>(-500_000, 1_000_000), 500_000);
/// ```
pub fn fold<W: Word>(x: W::Signed, p: W) -> W::Signed {
    let x = W::from_signed(x);
    let neg = is_negative(x);
    // Euclidean remainder r = x mod p in [0, p) using only unsigned operations.
    let m = unsigned_abs(x).urem(p);
    let r_neg = W::select(m.eq(W::lit(0)), W::lit(0), p.wrapping_sub(m));
    let r = W::select(neg, r_neg, m);
    // (p/2, p) maps to (−p/2, 0) by subtracting one period.
    let upper = p.shr(1).ult(r);
    W::select(upper, r.wrapping_sub(p), r).to_signed()
}

/// REQ-TIME-008: [`fold`] without its division when `x` lies within two periods of the fold
/// window (the common case of a phase error). `fold_near(x, p) = fold(x, p)` for every `x` and
/// `p` (p = 0 too, where both are the division's value): proved at 64 and 32 bits, checked
/// exhaustively at 8/16 bits. The window is (lo, hi] with hi = ⌊p/2⌋, lo = hi − p; the
/// candidates are x, x ∓ p, x ∓ 2p (stepping towards the window), none of which wraps, and one
/// inside the window is ≡ x (mod p), so it is the unique representative `fold` returns.
/// Otherwise the division in [`fold`] runs (only then, on machine words:
/// [`Word::select_or_else`]).
///
/// # Examples
///
/// ```
/// use ecdc_core::num;
///
/// for x in [-2_300_000i64, 900_000, 5, i64::MIN] {
///     assert_eq!(
///         num::fold_near::<u64>(x, 1_000_000),
///         num::fold::<u64>(x, 1_000_000)
///     );
/// }
/// ```
#[inline]
pub fn fold_near<W: Word>(x: W::Signed, p: W) -> W::Signed {
    let xw = W::from_signed(x);
    let hi = p.shr(1);
    let lo = hi.wrapping_sub(p); // exclusive
    let above = lo.slt(xw);
    // One step towards the window: −p from above it, +p from below.
    let step = W::select(above, wrapping_neg(p), p);
    let y1 = xw.wrapping_add(step);
    let y2 = y1.wrapping_add(step);
    let inside = |y: W| lo.slt(y).and(hi.slt(y).not());
    let (in0, in1, in2) = (inside(xw), inside(y1), inside(y2));
    let near = W::select(in0, xw, W::select(in1, y1, y2));
    W::select_or_else(in0.or(in1).or(in2), near, || {
        W::from_signed(fold::<W>(x, p))
    })
    .to_signed()
}

// ------------------------------------------------------------------ clamping and saturation

/// REQ-TIME-009: signed `min(max(x, lo), hi)`. With `lo ≤ hi` the result is in [lo, hi] and
/// equals `x` when `x` already is; with `lo > hi` it is `hi` (the upper bound wins).
///
/// # Examples
///
/// ```
/// use ecdc_core::num;
///
/// assert_eq!(num::clamp::<u32>(-50, -10, 10), -10);
/// assert_eq!(num::clamp::<u32>(5, -10, 10), 5);
/// ```
#[inline]
pub fn clamp<W: Word>(x: W::Signed, lo: W::Signed, hi: W::Signed) -> W::Signed {
    let (x, lo, hi) = (W::from_signed(x), W::from_signed(lo), W::from_signed(hi));
    let up = W::select(x.slt(lo), lo, x);
    W::select(hi.slt(up), hi, up).to_signed()
}

/// REQ-TIME-009: clamp a signed `x` to [−limit, limit] for an unsigned magnitude `limit`;
/// limits ≥ 2^(N−1) − 1 act as 2^(N−1) − 1, so the result always has a representable negation.
///
/// # Examples
///
/// ```
/// use ecdc_core::num;
///
/// assert_eq!(num::clamp_magnitude::<u32>(-5_000, 1_000), -1_000);
/// // A limit beyond the signed range keeps the result negatable.
/// assert_eq!(num::clamp_magnitude::<u8>(i8::MIN, 0xFF), -127);
/// ```
#[inline]
pub fn clamp_magnitude<W: Word>(x: W::Signed, limit: W) -> W::Signed {
    let smax = signed_max::<W>();
    let lim = W::select(smax.ult(limit), smax, limit);
    clamp::<W>(x, wrapping_neg(lim).to_signed(), lim.to_signed())
}

/// REQ-TIME-010: signed `a + b`, saturating at the signed range instead of wrapping.
///
/// # Examples
///
/// ```
/// use ecdc_core::num;
///
/// assert_eq!(num::saturating_add::<u8>(100, 100), i8::MAX);
/// assert_eq!(num::saturating_add::<u8>(-100, 50), -50);
/// ```
#[inline]
pub fn saturating_add<W: Word>(a: W::Signed, b: W::Signed) -> W::Signed {
    let (a, b) = (W::from_signed(a), W::from_signed(b));
    let s = a.wrapping_add(b);
    let (na, nb, ns) = (is_negative(a), is_negative(b), is_negative(s));
    // Overflow iff the operands share a sign and the sum's sign differs.
    let same = na.and(nb).or(na.not().and(nb.not()));
    let overflow = same.and(ns.and(na.not()).or(ns.not().and(na)));
    let limit = W::select(na, sign_bit::<W>(), signed_max::<W>());
    W::select(overflow, limit, s).to_signed()
}

/// REQ-TIME-010: signed `a − b`, saturating at the signed range instead of wrapping.
///
/// # Examples
///
/// ```
/// use ecdc_core::num;
///
/// assert_eq!(num::saturating_sub::<u8>(-100, 100), i8::MIN);
/// assert_eq!(num::saturating_sub::<u8>(10, 30), -20);
/// ```
#[inline]
pub fn saturating_sub<W: Word>(a: W::Signed, b: W::Signed) -> W::Signed {
    let (a, b) = (W::from_signed(a), W::from_signed(b));
    let d = a.wrapping_sub(b);
    let (na, nb, nd) = (is_negative(a), is_negative(b), is_negative(d));
    // Overflow iff the operands differ in sign and the result's sign differs from a's.
    let differ = na.and(nb.not()).or(na.not().and(nb));
    let overflow = differ.and(nd.and(na.not()).or(nd.not().and(na)));
    let limit = W::select(na, sign_bit::<W>(), signed_max::<W>());
    W::select(overflow, limit, d).to_signed()
}

/// Signed `a + b` mod 2^N and whether the true sum left the signed range (what `i64::
/// checked_add` reports as `None`).
///
/// # Examples
///
/// ```
/// use ecdc_core::num;
///
/// // 100 + 100 leaves i8's range: the wrapped bits are −56.
/// assert_eq!(num::overflowing_add(100u8, 100), (0xC8, true));
/// assert_eq!(num::overflowing_add(0xFFu8, 1), (0, false)); // −1 + 1
/// ```
#[inline]
pub fn overflowing_add<W: Word>(a: W, b: W) -> (W, W::Bool) {
    let s = a.wrapping_add(b);
    let (na, nb, ns) = (is_negative(a), is_negative(b), is_negative(s));
    // Overflow iff the operands share a sign and the sum's sign differs.
    let same = na.and(nb).or(na.not().and(nb.not()));
    (s, same.and(ns.and(na.not()).or(ns.not().and(na))))
}

/// Signed `a − b` mod 2^N and whether the true difference left the signed range (what
/// `i64::checked_sub` reports as `None`).
///
/// # Examples
///
/// ```
/// use ecdc_core::num;
///
/// assert_eq!(num::overflowing_sub(0x80u8, 1), (0x7F, true)); // −128 − 1
/// assert_eq!(num::overflowing_sub(5u8, 7), (0xFE, false)); // 5 − 7 = −2
/// ```
#[inline]
pub fn overflowing_sub<W: Word>(a: W, b: W) -> (W, W::Bool) {
    let d = a.wrapping_sub(b);
    let (na, nb, nd) = (is_negative(a), is_negative(b), is_negative(d));
    // Overflow iff the operands differ in sign and the result's sign differs from a's.
    let differ = na.and(nb.not()).or(na.not().and(nb));
    (d, differ.and(nd.and(na.not()).or(nd.not().and(na))))
}

/// REQ-TIME-011: signed `x / 2` rounded toward zero, exact for every input (no overflow even
/// for the most negative value). Used for "half a round trip" in delay computation.
///
/// # Examples
///
/// ```
/// use ecdc_core::num;
///
/// assert_eq!(num::half_toward_zero::<u32>(-7), -3);
/// assert_eq!(num::half_toward_zero::<u32>(7), 3);
/// assert_eq!(num::half_toward_zero::<u32>(i32::MIN), i32::MIN / 2);
/// ```
#[inline]
pub fn half_toward_zero<W: Word>(x: W::Signed) -> W::Signed {
    let x = W::from_signed(x);
    let h = unsigned_abs(x).shr(1);
    W::select(is_negative(x), wrapping_neg(h), h).to_signed()
}

// ------------------------------------------------------------------ sign-magnitude (0x092C)

/// REQ-TIME-012: encode a signed value as saturating sign-magnitude: bits N−2..0 hold
/// min(|x|, 2^(N−1) − 1) and bit N−1 is set iff x < 0 (REQ-CONV-006: for 0x092C, set means
/// the local copy is behind). Never produces "negative zero".
///
/// # Examples
///
/// ```
/// use ecdc_core::num;
///
/// // 0x092C: the local copy is 300 ns behind.
/// assert_eq!(num::sign_magnitude_encode::<u32>(-300), 0x8000_012C);
/// assert_eq!(num::sign_magnitude_encode::<u32>(300), 0x0000_012C);
/// ```
#[inline]
pub fn sign_magnitude_encode<W: Word>(x: W::Signed) -> W {
    let x = W::from_signed(x);
    let smax = signed_max::<W>();
    let mag = unsigned_abs(x);
    let mag = W::select(smax.ult(mag), smax, mag);
    W::select(is_negative(x), mag.bit_or(sign_bit::<W>()), mag)
}

/// REQ-TIME-012: decode sign-magnitude to a signed value; "negative zero" (only the sign bit)
/// decodes to 0. Every result lies in [−(2^(N−1) − 1), 2^(N−1) − 1].
///
/// # Examples
///
/// ```
/// use ecdc_core::num;
///
/// assert_eq!(num::sign_magnitude_decode(0x8000_012Cu32), -300);
/// // "Negative zero" decodes to 0.
/// assert_eq!(num::sign_magnitude_decode(0x8000_0000u32), 0);
/// ```
#[inline]
pub fn sign_magnitude_decode<W: Word>(v: W) -> W::Signed {
    let mag = v.bit_and(signed_max::<W>());
    let neg = v.bit_and(sign_bit::<W>()).eq(W::lit(0)).not();
    W::select(neg, wrapping_neg(mag), mag).to_signed()
}

// ------------------------------------------------------------------ offset arithmetic (P4)

/// REQ-DC-021, REQ-DC-023 (P4): the System Time Offset `o` with `local + o ≡ target`
/// (mod 2^N). A 32-bit slave keeps the low 32 bits of a 64-bit result, which is the N = 32
/// result of the low halves (add/sub carry only upwards).
///
/// # Examples
///
/// ```
/// use ecdc_core::num;
///
/// let (target, local) = (5_000u64, 7_000u64);
/// let o = num::offset_to(target, local);
/// assert_eq!(local.wrapping_add(o), target);
/// ```
#[inline]
pub fn offset_to<W: Word>(target: W, local: W) -> W {
    target.wrapping_sub(local)
}

/// REQ-DC-024 (P4): re-offset without a new latch. A slave whose offset is `current` read
/// `read` (= its local time + `current`) when the reference read `reference`; the new offset
/// makes that local time + offset ≡ reference (mod 2^N).
///
/// # Examples
///
/// ```
/// use ecdc_core::num;
///
/// // The slave read 1 050 with offset 100 when the reference read 1 000: it is 50 ns ahead.
/// assert_eq!(num::corrected_offset(100u64, 1_050, 1_000), 50);
/// ```
#[inline]
pub fn corrected_offset<W: Word>(current: W, read: W, reference: W) -> W {
    current.wrapping_add(reference.wrapping_sub(read))
}

/// REQ-DC-022 (P4): the N-bit (N > 32) local time at which a frame entered a slave whose EPU
/// stamp is `epu` (full width) and whose entry-port stamp is the 32-bit `entry` (zero-extended):
/// `epu − ((epu − entry) mod 2^32)`. Exact whenever the EPU stamp follows the entry stamp by
/// less than 2^32 ns.
///
/// # Examples
///
/// ```
/// use ecdc_core::num;
///
/// // EPU stamp 0x1_0000_0100, entry port latched 0xFFFF_FF00 (just before the low 32 bits
/// // wrapped): the frame entered at 0x0_FFFF_FF00 local time.
/// assert_eq!(
///     num::entry_local(0x1_0000_0100u64, 0xFFFF_FF00),
///     0x0_FFFF_FF00
/// );
/// ```
#[inline]
pub fn entry_local<W: Word>(epu: W, entry: W) -> W {
    let low_mask = W::lit(1).shl(32).wrapping_sub(W::lit(1));
    epu.wrapping_sub(epu.wrapping_sub(entry).bit_and(low_mask))
}

// ------------------------------------------------------------------ width conversion

/// REQ-TIME-013: the low 32 bits of a 64-bit word (what a 32-bit DC slave keeps).
///
/// # Examples
///
/// ```
/// use ecdc_core::num;
///
/// assert_eq!(num::low32(0xDEAD_BEEF_0000_0001), 1);
/// ```
#[inline]
pub fn low32(x: u64) -> u32 {
    // Truncation is the point; the mask makes it explicit and the conversion infallible.
    u32::try_from(x & u64::from(u32::MAX)).unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrapping_mul_is_the_low_bits_of_the_signed_product() {
        for a in 0..=u8::MAX {
            for b in 0..=u8::MAX {
                let signed = i16::from(i8::from_ne_bytes([a])) * i16::from(i8::from_ne_bytes([b]));
                assert_eq!(Word::wrapping_mul(a, b), signed.to_le_bytes()[0]);
                assert_eq!(
                    Word::wrapping_mul(a, b),
                    (u16::from(a) * u16::from(b)).to_le_bytes()[0]
                );
            }
        }
        assert_eq!(Word::wrapping_mul(u64::MAX, 3), u64::MAX - 2);
        assert_eq!(Word::wrapping_mul(1u32 << 31, 2), 0);
    }

    #[test]
    fn wrapping_diff_boundaries() {
        assert_eq!(wrapping_diff(0u32, u32::MAX), 1);
        assert_eq!(wrapping_diff(u32::MAX, 0u32), -1);
        assert_eq!(wrapping_diff(0x8000_0000u32, 0), i32::MIN);
        assert_eq!(wrapping_diff(0x7FFF_FFFFu32, 0), i32::MAX);
        assert_eq!(wrapping_diff(5u64, u64::MAX - 4), 10);
        assert!(is_after(0u32, u32::MAX));
        assert!(!is_after(7u32, 7));
        assert_eq!(wrapping_distance(0u32, 0x8000_0000), 0x8000_0000);
        assert_eq!(wrapping_distance(u32::MAX, 1u32), 2);
    }

    #[test]
    fn earliest_across_wrap() {
        // Port 1 latched just before the 32-bit wrap, the others after: port 1 is earliest.
        let t = [0x0000_0100u32, 0xFFFF_FF00, 0x0000_0050, 0];
        let (found, i) = earliest(&t, &[true, true, true, false]);
        assert!(found);
        assert_eq!(i, 1);
        // A plain minimum would have chosen port 2 (0x50) or the inactive port 3.
        let (found, i) = earliest(&t, &[true, false, true, false]);
        assert!(found && i == 2);
        let (found, _) = earliest(&t, &[false; 4]);
        assert!(!found);
        // Ties: first wins.
        let (_, i) = earliest(&[9u32, 9, 9], &[true, true, true]);
        assert_eq!(i, 0);
    }

    #[test]
    fn extend_near_boundaries() {
        let r = 0x0000_0001_0000_0010u64;
        assert_eq!(extend_near(0x0000_0020u64, r, 32), 0x0000_0001_0000_0020);
        assert_eq!(extend_near(0xFFFF_FFF0u64, r, 32), 0x0000_0000_FFFF_FFF0);
        // Exactly half a wrap ahead reads as behind (window is [−2^31, 2^31)).
        assert_eq!(extend_near(0x8000_0010u64, r, 32), 0x0000_0000_8000_0010);
        assert_eq!(extend_near(0x8000_000Fu64, r, 32), 0x0000_0001_8000_000F);
        // Near zero: wraps below zero modulo 2^64.
        assert_eq!(extend_near(0xFFFF_FFFFu64, 0, 32), u64::MAX);
    }

    #[test]
    fn fold_boundaries() {
        assert_eq!(fold::<u32>(0, 1000), 0);
        assert_eq!(fold::<u32>(500, 1000), 500);
        assert_eq!(fold::<u32>(501, 1000), -499);
        assert_eq!(fold::<u32>(-500, 1000), 500);
        assert_eq!(fold::<u32>(-499, 1000), -499);
        assert_eq!(
            i128::from(fold::<u32>(i32::MIN, 1000)),
            fold_ref(i32::MIN.into(), 1000)
        );
        assert_eq!(
            i128::from(fold::<u32>(i32::MAX, 3)),
            fold_ref(i32::MAX.into(), 3)
        );
        assert_eq!(
            i128::from(fold::<u32>(-1, u32::MAX)),
            fold_ref(-1, u32::MAX.into())
        );
        assert_eq!(
            i128::from(fold::<u32>(i32::MIN, u32::MAX)),
            fold_ref(i32::MIN.into(), u32::MAX.into())
        );
        assert_eq!(
            i128::from(fold::<u64>(i64::MIN, i64::MAX as u64)),
            fold_ref(i64::MIN.into(), i64::MAX.into())
        );
        assert_eq!(
            i128::from(fold::<u64>(-3, u64::MAX)),
            fold_ref(-3, u64::MAX.into())
        );
        assert_eq!(fold::<u32>(7, 1), 0);
        assert_eq!(phase(1_000_000_123u64, 1_000_000), 123);
    }

    /// Plain wide-integer definition: Euclidean remainder, upper half moved down one period.
    fn fold_ref(x: i128, p: i128) -> i128 {
        let r = x.rem_euclid(p);
        if 2 * r > p {
            r - p
        } else {
            r
        }
    }

    #[test]
    fn clamp_and_saturate() {
        assert_eq!(clamp::<u32>(5, -3, 3), 3);
        assert_eq!(clamp::<u32>(-5, -3, 3), -3);
        assert_eq!(clamp::<u32>(1, 3, -3), -3);
        assert_eq!(clamp_magnitude::<u32>(i32::MIN, u32::MAX), -i32::MAX);
        assert_eq!(clamp_magnitude::<u32>(i32::MIN, 10), -10);
        assert_eq!(saturating_add::<u32>(i32::MAX, 1), i32::MAX);
        assert_eq!(saturating_add::<u32>(i32::MIN, -1), i32::MIN);
        assert_eq!(saturating_sub::<u32>(i32::MIN, 1), i32::MIN);
        assert_eq!(saturating_sub::<u32>(0, i32::MIN), i32::MAX);
        assert_eq!(saturating_sub::<u64>(-1, i64::MIN), i64::MAX);
        assert_eq!(half_toward_zero::<u32>(-3), -1);
        assert_eq!(half_toward_zero::<u32>(i32::MIN), i32::MIN / 2);
        assert_eq!(half_toward_zero::<u32>(i32::MAX), i32::MAX / 2);
    }

    #[test]
    fn overflowing_matches_checked() {
        let xs = [
            0i64,
            1,
            -1,
            2,
            i64::MAX,
            i64::MIN,
            i64::MAX - 1,
            i64::MIN + 1,
            1 << 62,
            -(1 << 62),
        ];
        for a in xs {
            for b in xs {
                let (ua, ub) = (a as u64, b as u64);
                let (s, o) = overflowing_add(ua, ub);
                assert_eq!(
                    (s as i64, o),
                    (a.wrapping_add(b), a.checked_add(b).is_none())
                );
                let (d, o) = overflowing_sub(ua, ub);
                assert_eq!(
                    (d as i64, o),
                    (a.wrapping_sub(b), a.checked_sub(b).is_none())
                );
            }
        }
        for a in i8::MIN..=i8::MAX {
            for b in i8::MIN..=i8::MAX {
                let (s, o) = overflowing_add(a as u8, b as u8);
                assert_eq!(
                    (s as i8, o),
                    (a.wrapping_add(b), a.checked_add(b).is_none())
                );
                let (d, o) = overflowing_sub(a as u8, b as u8);
                assert_eq!(
                    (d as i8, o),
                    (a.wrapping_sub(b), a.checked_sub(b).is_none())
                );
            }
        }
    }

    #[test]
    fn sign_magnitude_boundaries() {
        assert_eq!(sign_magnitude_encode::<u32>(0), 0);
        assert_eq!(sign_magnitude_encode::<u32>(-1), 0x8000_0001);
        assert_eq!(sign_magnitude_encode::<u32>(i32::MAX), 0x7FFF_FFFF);
        assert_eq!(sign_magnitude_encode::<u32>(i32::MIN), 0xFFFF_FFFF);
        assert_eq!(sign_magnitude_decode::<u32>(0x8000_0000), 0);
        assert_eq!(sign_magnitude_decode::<u32>(0x8000_0001), -1);
        assert_eq!(sign_magnitude_decode::<u32>(0xFFFF_FFFF), -i32::MAX);
        assert_eq!(sign_magnitude_decode::<u32>(0x7FFF_FFFF), i32::MAX);
        assert_eq!(low32(0x1234_5678_9ABC_DEF0), 0x9ABC_DEF0);
    }
}
