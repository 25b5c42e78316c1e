//! Full-width statements of the kernel requirements, as `(precondition, claim)` pairs over z3
//! terms. Each runs the real kernel on [`Sym`] inputs and states the requirement over wider
//! bit-vectors where "true" (unwrapped) values are needed, so the statement cannot share the
//! kernel's wrap-around. Proved by `proofs/tests/smt.rs` at N = 32 and N = 64.

use super::{ctx, Sym, SymBool};
use ecdc_core::num::{self as k, Word};
use z3::ast::{Ast, Bool, BV};

/// `(precondition, claim)`.
pub type Goal = (Bool<'static>, Bool<'static>);

fn t() -> Bool<'static> {
    Bool::from_bool(ctx(), true)
}
fn and(xs: &[&Bool<'static>]) -> Bool<'static> {
    Bool::and(ctx(), xs)
}
fn int(v: i128, size: u32) -> BV<'static> {
    // Two's complement bits of v at `size` (≤ 128) bits, built from two 64-bit halves.
    let lo = BV::from_u64(ctx(), (v as u128 & u128::from(u64::MAX)) as u64, 64);
    let hi = BV::from_u64(ctx(), ((v as u128) >> 64) as u64, 64);
    hi.concat(&lo).extract(size - 1, 0)
}
fn abs(x: &BV<'static>) -> BV<'static> {
    x.bvslt(&int(0, x.get_size())).ite(&x.bvneg(), x)
}

/// P2 / REQ-TIME-003/004: for true times A, B (2N-bit, non-negative) with |A − B| < 2^(N−1),
/// the kernels on the low N bits give wrapping_diff = A − B, is_after ⇔ A > B, distance = |A − B|.
pub fn wrapping_diff_true<const N: u32>() -> Goal {
    let w = 2 * N;
    let (ta, tb) = (BV::new_const(ctx(), "A", w), BV::new_const(ctx(), "B", w));
    let d = ta.bvsub(&tb);
    let h = 1i128 << (N - 1);
    let pre = and(&[
        &ta.bvslt(&int(0, w)).not(),
        &tb.bvslt(&int(0, w)).not(),
        &d.bvsgt(&int(-h, w)),
        &d.bvslt(&int(h, w)),
    ]);
    let a = Sym::<N>::of(ta.extract(N - 1, 0));
    let b = Sym::<N>::of(tb.extract(N - 1, 0));
    let claim = and(&[
        &k::wrapping_diff(a, b).bv().sign_ext(N)._eq(&d),
        &k::is_after(a, b).b()._eq(&d.bvsgt(&int(0, w))),
        &k::wrapping_distance(a, b).bv().zero_ext(N)._eq(&abs(&d)),
    ]);
    (pre, claim)
}

/// P2 / REQ-TIME-005: P port times base + o_i with every o_i < 2^(N−1) (so the true times span
/// less than half the circle, wherever the wrap falls) and any activity mask: `found` ⇔ some
/// port is active, and the chosen index is active, has the least true time, and is the first
/// such.
pub fn earliest_true_min<const N: u32, const P: usize>() -> Goal {
    let base = Sym::<N>::var("base");
    let offs: [Sym<N>; P] = core::array::from_fn(|i| Sym::var(&format!("o{i}")));
    let act = port_activity::<P>();
    let times: [Sym<N>; P] = core::array::from_fn(|i| base.wrapping_add(offs[i]));
    let (found, idx) = k::earliest(&times, &act);
    let offs: Vec<BV<'static>> = offs.iter().map(|o| o.bv().clone()).collect();
    (
        within_half_circle::<N>(&offs),
        earliest_claim::<N, P>(&offs, &act, &found, &idx),
    )
}

/// [`earliest_true_min`] with the port times as free leaves: a free `base` with every
/// t_i − base < 2^(N−1) (the times fit in half the circle), true order = order of t_i − base.
pub fn earliest_leaves<const N: u32, const P: usize>() -> Goal {
    let base = Sym::<N>::var("base");
    let times: [Sym<N>; P] = core::array::from_fn(|i| Sym::var(&format!("t{i}")));
    let act = port_activity::<P>();
    let offs: Vec<BV<'static>> = times.iter().map(|t| t.bv().bvsub(base.bv())).collect();
    let (found, idx) = k::earliest(&times, &act);
    (
        within_half_circle::<N>(&offs),
        earliest_claim::<N, P>(&offs, &act, &found, &idx),
    )
}

/// One free activity flag per port, `act0` … `act{P-1}`.
fn port_activity<const P: usize>() -> [SymBool; P] {
    core::array::from_fn(|i| SymBool::of(Bool::new_const(ctx(), format!("act{i}"))))
}

/// Every offset below 2^(N−1): the true times span less than half the circle.
fn within_half_circle<const N: u32>(offs: &[BV<'static>]) -> Bool<'static> {
    let half = int(1i128 << (N - 1), N);
    let terms: Vec<Bool<'static>> = offs.iter().map(|o| o.bvult(&half)).collect();
    Bool::and(ctx(), &terms.iter().collect::<Vec<_>>())
}

/// The claim of both `earliest` goals, given each port's true position `offs` on the circle
/// (order of `offs` = true order): `found` ⇔ some port is active, and when found the chosen
/// index is in range, active, has the least true time, and is the first such.
fn earliest_claim<const N: u32, const P: usize>(
    offs: &[BV<'static>],
    act: &[SymBool; P],
    found: &SymBool,
    idx: &Sym<N>,
) -> Bool<'static> {
    let any: Vec<&Bool<'static>> = act.iter().map(|a| a.b()).collect();
    let mut claims = vec![found.b()._eq(&Bool::or(ctx(), &any))];
    let mut in_range = Vec::new();
    for i in 0..P {
        let is_i = idx.bv()._eq(&int(i as i128, N));
        in_range.push(is_i.clone());
        let mut ok = vec![act[i].b().clone()];
        for j in 0..P {
            let le = if j < i {
                offs[i].bvult(&offs[j])
            } else {
                offs[i].bvule(&offs[j])
            };
            ok.push(act[j].b().implies(&le));
        }
        let ok = Bool::and(ctx(), &ok.iter().collect::<Vec<_>>());
        claims.push(Bool::and(ctx(), &[found.b(), &is_i]).implies(&ok));
    }
    claims.push(
        found
            .b()
            .implies(&Bool::or(ctx(), &in_range.iter().collect::<Vec<_>>())),
    );
    Bool::and(ctx(), &claims.iter().collect::<Vec<_>>())
}

/// REQ-TIME-006: r = extend_near(low, ref, kb) keeps the low kb bits of `low` and lies in
/// [−2^(kb−1), 2^(kb−1)) of `ref`, for 0 < kb < N.
pub fn extend_near<const N: u32>(kb: u32) -> Goal {
    let (low, r0) = (Sym::<N>::var("low"), Sym::<N>::var("ref"));
    let r = k::extend_near(low, r0, kb);
    let d = r.bv().bvsub(r0.bv());
    let h = 1i128 << (kb - 1);
    let claim = and(&[
        &r.bv().extract(kb - 1, 0)._eq(&low.bv().extract(kb - 1, 0)),
        &d.bvsge(&int(-h, N)),
        &d.bvslt(&int(h, N)),
    ]);
    (t(), claim)
}

/// P2 / REQ-TIME-008 with the divider bit-blasted: for every x and every p > 0,
/// −p < 2·fold(x, p) ≤ p and p divides x − fold(x, p), at N + 2 bits so nothing wraps.
/// Practical at small N only (a 32-bit divider does not finish in minutes); see [`fold`].
pub fn fold_bitblasted<const N: u32>() -> Goal {
    let (x, p) = (Sym::<N>::var("x"), Sym::<N>::var("p"));
    let f = k::fold::<Sym<N>>(x, p);
    let (xw, fw, pw) = (x.bv().sign_ext(2), f.bv().sign_ext(2), p.bv().zero_ext(2));
    let f2 = fw.bvadd(&fw);
    let pre = p.bv()._eq(&int(0, N)).not();
    let claim = and(&[
        &pw.bvneg().bvslt(&f2),
        &f2.bvsle(&pw),
        &xw.bvsub(&fw).bvsrem(&pw)._eq(&int(0, N + 2)),
    ]);
    (pre, claim)
}

/// P2 / REQ-TIME-008 at full width, with `urem` abstracted (see `smt::with_abstract_urem`):
/// the kernel's single remainder m = urem(u, p) is a free value, and the proof assumes only
/// the two facts of unsigned remainder it needs: m < p, and u − m is a multiple of p. It proves
/// the divisor is p, u = |x|, −p < 2·f ≤ p, and σ·m − f ∈ {0, p, −p} (σ = sign of x). Since
/// x − f = σ·(u − m) + (σ·m − f), that gives x − f ≡ 0 (mod p) for every x and p > 0. Everything except the divider itself is the kernel's own
/// code; the divider is SMT-LIB `bvurem`/Rust `%`, checked exhaustively at 8/16 bits.
pub fn fold<const N: u32>() -> Goal {
    fold_case::<N>(None)
}

/// [`fold`] restricted to x < 0 (`Some(true)`) or x ≥ 0 (`Some(false)`): the two cases together
/// are the full statement, and each is much easier for the solver than the whole.
pub fn fold_case<const N: u32>(negative: Option<bool>) -> Goal {
    let (x, p) = (Sym::<N>::var("x"), Sym::<N>::var("p"));
    let (f, recs) = super::with_abstract_urem(|| k::fold::<Sym<N>>(x, p));
    assert_eq!(
        recs.len(),
        1,
        "fold is expected to take exactly one remainder"
    );
    let (u, d, m) = recs[0];
    let w = N + 2;
    let (xw, fw, pw) = (x.bv().sign_ext(2), f.bv().sign_ext(2), p.bv().zero_ext(2));
    let (uw, mw) = (u.zero_ext(2), m.zero_ext(2));
    let xneg = xw.bvslt(&int(0, w));
    // x − f = σ·(u − m) + (σ·m − f) once u = |x| (σ = sign of x); σ·(u − m) is a multiple of p,
    // so "σ·m − f ∈ {0, ±p}" together with "u = |x|" gives x − f ≡ 0 (mod p). Stating the
    // residue without x keeps the solver away from re-deriving |x| inside one adder chain.
    let diff = xneg.ite(&mw.bvneg(), &mw).bvsub(&fw);
    let f2 = fw.bvadd(&fw);
    let case = match negative {
        None => t(),
        Some(true) => x.bv().bvslt(&int(0, N)),
        Some(false) => x.bv().bvslt(&int(0, N)).not(),
    };
    let pre = and(&[&p.bv()._eq(&int(0, N)).not(), &m.bvult(p.bv()), &case]);
    let claim = and(&[
        &d._eq(p.bv()),
        &uw._eq(&abs(&xw)),
        &pw.bvneg().bvslt(&f2),
        &f2.bvsle(&pw),
        &Bool::or(
            ctx(),
            &[
                &diff._eq(&int(0, w)),
                &diff._eq(&pw),
                &diff._eq(&pw.bvneg()),
            ],
        ),
    ]);
    (pre, claim)
}

/// REQ-TIME-009: clamp(x, lo, hi) for lo ≤ hi lies in [lo, hi], is x when x is inside and the
/// violated bound otherwise; for lo > hi it is hi.
pub fn clamp<const N: u32>() -> Goal {
    let (x, lo, hi) = (Sym::<N>::var("x"), Sym::<N>::var("lo"), Sym::<N>::var("hi"));
    let c = k::clamp::<Sym<N>>(x, lo, hi);
    let (x, lo, hi, c) = (x.bv(), lo.bv(), hi.bv(), c.bv());
    let ordered = lo.bvsle(hi);
    let inside = and(&[&lo.bvsle(x), &x.bvsle(hi)]);
    let good = and(&[
        &lo.bvsle(c),
        &c.bvsle(hi),
        &inside.implies(&c._eq(x)),
        &x.bvslt(lo).implies(&c._eq(lo)),
        &hi.bvslt(x).implies(&c._eq(hi)),
    ]);
    let claim = ordered.ite(&good, &c._eq(hi));
    (t(), claim)
}

/// REQ-TIME-009: clamp_magnitude(x, m) lies in [−m', m'] with m' = min(m, 2^(N−1) − 1), is x
/// when |x| ≤ m', and the nearer bound otherwise.
pub fn clamp_magnitude<const N: u32>() -> Goal {
    let (x, m) = (Sym::<N>::var("x"), Sym::<N>::var("m"));
    let c = k::clamp_magnitude::<Sym<N>>(x, m);
    let smax = int((1i128 << (N - 1)) - 1, N);
    let lim = m.bv().bvugt(&smax).ite(&smax, m.bv());
    let nlim = lim.bvneg();
    let (x, c) = (x.bv(), c.bv());
    let claim = and(&[
        &nlim.bvsle(c),
        &c.bvsle(&lim),
        &and(&[&nlim.bvsle(x), &x.bvsle(&lim)]).implies(&c._eq(x)),
        &x.bvsgt(&lim).implies(&c._eq(&lim)),
        &x.bvslt(&nlim).implies(&c._eq(&nlim)),
    ]);
    (t(), claim)
}

/// REQ-TIME-010: saturating add/sub equal the exact (N + 1)-bit result clamped to the signed
/// N-bit range.
pub fn saturating<const N: u32>() -> Goal {
    let (a, b) = (Sym::<N>::var("a"), Sym::<N>::var("b"));
    let (aw, bw) = (a.bv().sign_ext(1), b.bv().sign_ext(1));
    let h = 1i128 << (N - 1);
    let (lo, hi) = (int(-h, N + 1), int(h - 1, N + 1));
    let sat = |e: BV<'static>| e.bvslt(&lo).ite(&lo, &e.bvsgt(&hi).ite(&hi, &e));
    let claim = and(&[
        &k::saturating_add::<Sym<N>>(a, b)
            .bv()
            .sign_ext(1)
            ._eq(&sat(aw.bvadd(&bw))),
        &k::saturating_sub::<Sym<N>>(a, b)
            .bv()
            .sign_ext(1)
            ._eq(&sat(aw.bvsub(&bw))),
    ]);
    (t(), claim)
}

/// `overflowing_add`/`overflowing_sub` (the `checked_*` of `delay::twice_delay_step`): the
/// word is the wrapped result and the flag is set iff the exact (N + 1)-bit result differs from
/// it read as signed (i.e. left the signed N-bit range).
pub fn overflowing<const N: u32>() -> Goal {
    let (a, b) = (Sym::<N>::var("a"), Sym::<N>::var("b"));
    let (aw, bw) = (a.bv().sign_ext(1), b.bv().sign_ext(1));
    let (s, so) = k::overflowing_add(a, b);
    let (d, dor) = k::overflowing_sub(a, b);
    let (es, ed) = (aw.bvadd(&bw), aw.bvsub(&bw));
    let claim = and(&[
        &s.bv()._eq(&es.extract(N - 1, 0)),
        &d.bv()._eq(&ed.extract(N - 1, 0)),
        &so.b()._eq(&s.bv().sign_ext(1)._eq(&es).not()),
        &dor.b()._eq(&d.bv().sign_ext(1)._eq(&ed).not()),
    ]);
    (t(), claim)
}

/// REQ-TIME-011: half_toward_zero(x) equals SMT-LIB `bvsdiv x 2` (truncating division).
pub fn half<const N: u32>() -> Goal {
    let x = Sym::<N>::var("x");
    let claim = k::half_toward_zero::<Sym<N>>(x)
        .bv()
        ._eq(&x.bv().bvsdiv(&int(2, N)));
    (t(), claim)
}

/// REQ-TIME-012: sign-magnitude encode (magnitude = min(|x|, 2^(N−1) − 1) computed at N + 1
/// bits, sign bit ⇔ x < 0), decode∘encode = max(x, −(2^(N−1) − 1)), decode of any word has
/// |value| = its magnitude bits and is negative iff the sign bit is set with a non-zero
/// magnitude, and encode∘decode = identity except on "negative zero".
pub fn sign_magnitude<const N: u32>() -> Goal {
    let (x, v) = (Sym::<N>::var("x"), Sym::<N>::var("v"));
    let smax = int((1i128 << (N - 1)) - 1, N);
    let sign = int(1i128 << (N - 1), N);
    let e = k::sign_magnitude_encode::<Sym<N>>(x);
    let ax = abs(&x.bv().sign_ext(1));
    let smax1 = smax.zero_ext(1);
    let mag = ax.bvugt(&smax1).ite(&smax1, &ax);
    let xneg = x.bv().bvslt(&int(0, N));
    let one = BV::from_u64(ctx(), 1, 1);
    let dv = k::sign_magnitude_decode::<Sym<N>>(v);
    let vmag = v.bv().extract(N - 2, 0).zero_ext(1);
    let vneg = v.bv().extract(N - 1, N - 1)._eq(&one);
    let nonzero = vmag._eq(&int(0, N)).not();
    let claim = and(&[
        &e.bv().extract(N - 2, 0).zero_ext(2)._eq(&mag),
        &e.bv().extract(N - 1, N - 1)._eq(&one)._eq(&xneg),
        &k::sign_magnitude_decode::<Sym<N>>(e)
            .bv()
            ._eq(&x.bv()._eq(&sign).ite(&smax.bvneg(), x.bv())),
        &abs(dv.bv())._eq(&vmag),
        &dv.bv().bvslt(&int(0, N))._eq(&and(&[&vneg, &nonzero])),
        &v.bv()
            ._eq(&sign)
            .not()
            .implies(&k::sign_magnitude_encode::<Sym<N>>(dv).bv()._eq(v.bv())),
    ]);
    (t(), claim)
}

// ------------------------------------------------------------------ P4: offset arithmetic

/// P4 / REQ-DC-021, REQ-DC-023: `local + offset_to(target, local) ≡ target (mod 2^N)` for every
/// target and local time.
pub fn offset_to<const N: u32>() -> Goal {
    let (target, local) = (Sym::<N>::var("target"), Sym::<N>::var("local"));
    let o = k::offset_to(target, local);
    (t(), local.wrapping_add(o).bv()._eq(target.bv()))
}

/// P4 / REQ-DC-021, REQ-DC-023 for both clock widths on the shipped arithmetic of
/// `offset::initial_offset` (`offset::initial_offset_word`, which it runs on `u64`): for any
/// 64-bit master time, any signed 64-bit delay and any 64-bit entry local time, with target =
/// master + delay (mod 2^64): a 64-bit slave's offset o64 gives local + o64 ≡ target
/// (mod 2^64); a 32-bit slave's offset o32 fits 32 bits and, as it counts with the low half of
/// its local time, low32(local) + o32 ≡ low32(target) (mod 2^32). The target is stated here
/// as the plain 64-bit sum, independently of the kernel.
pub fn initial_offset_both_widths() -> Goal {
    use ecdc_core::dc::offset::{initial_offset_word, ClockWidth};
    let (m, d, local) = (
        Sym::<64>::var("master"),
        Sym::<64>::var("delay"),
        Sym::<64>::var("local"),
    );
    let target = m.bv().bvadd(d.bv());
    let o64 = initial_offset_word(m, d, local, ClockWidth::Bits64);
    let o32 = initial_offset_word(m, d, local, ClockWidth::Bits32);
    let lo = |x: &BV<'static>| x.extract(31, 0);
    let claim = and(&[
        &local.bv().bvadd(o64.bv())._eq(&target),
        &o32.bv().extract(63, 32)._eq(&int(0, 32)),
        &lo(local.bv()).bvadd(&lo(o32.bv()))._eq(&lo(&target)),
    ]);
    (t(), claim)
}

/// P4 / REQ-DC-024: with the slave reading `read = local + current` when the reference read
/// `reference`, `local + corrected_offset(current, read, reference) ≡ reference (mod 2^N)`.
pub fn corrected_offset<const N: u32>() -> Goal {
    let (local, cur, reference) = (
        Sym::<N>::var("local"),
        Sym::<N>::var("current"),
        Sym::<N>::var("reference"),
    );
    let read = local.wrapping_add(cur);
    let new = k::corrected_offset(cur, read, reference);
    (t(), local.wrapping_add(new).bv()._eq(reference.bv()))
}

/// P4 / REQ-DC-022: a frame entered at true 64-bit local time E and the EPU stamp follows e <
/// 2^32 ns later; the entry port keeps only low32(E). Then entry_local(E + e, low32(E)) = E.
pub fn entry_local() -> Goal {
    let (e_true, e) = (Sym::<64>::var("entry"), Sym::<64>::var("elapsed"));
    let pre = e.bv().bvult(&int(1i128 << 32, 64));
    let epu = e_true.wrapping_add(e);
    let stamp = Sym::<64>::of(e_true.bv().extract(31, 0).zero_ext(32));
    let r = k::entry_local(epu, stamp);
    (pre, r.bv()._eq(e_true.bv()))
}

// ------------------------------------------------------------------ P5: PI step bound

/// P5 / REQ-SERVO-011..013, one-step inductive bound at 64 bits on the shipped add/compare/clamp
/// part of the PI step (`ecdc_core::servo::pi::pi_update`, which `pi_step` calls on `u64`), the
/// products Kp·θ and Ki·θ being free values within their proven ranges (|Kp·θ| ≤ 2^61 from
/// Kp < 2^33, |θ| ≤ 2^28; |Ki·θ| ≤ 2^62 from Ki < 2^34): for every integrator I (clamped on
/// entry) and limits 0 < I_max ≤ y_max ≤ 2^60, |y| ≤ y_max, |I'| ≤ I_max, the 64-bit sum v
/// equals the exact 66-bit sum (no wrap), and saturated ⇔ |v| > y_max.
pub fn pi_update_bounded() -> Goal {
    let v64 = |n: &str| Sym::<64>::var(n);
    let (i, p, it, ym, im) = (v64("I"), v64("p"), v64("it"), v64("y_max"), v64("i_max"));
    // −b ≤ x ≤ b (b ≥ 0 and small here, so −b does not wrap; unlike |x| ≤ b it is false
    // for x = −2^63).
    let abs_le = |x: &BV<'static>, b: &BV<'static>| and(&[&x.bvsle(b), &b.bvneg().bvsle(x)]);
    let pre = and(&[
        &int(0, 64).bvslt(im.bv()),
        &im.bv().bvsle(ym.bv()),
        &ym.bv().bvsle(&int(1i128 << 60, 64)),
        &abs_le(p.bv(), &int(1i128 << 61, 64)),
        &abs_le(it.bv(), &int(1i128 << 62, 64)),
    ]);
    let r = ecdc_core::servo::pi::pi_update(i, p, it, ym, im);
    let (y, i2, sat, v) = (r.y, r.integrator, r.saturated, r.v);
    let ic = i.bv().bvslt(&im.bv().bvneg()).ite(
        &im.bv().bvneg(),
        &i.bv().bvsgt(im.bv()).ite(im.bv(), i.bv()),
    );
    let x = |b: &BV<'static>| b.sign_ext(2);
    let exact = x(p.bv()).bvadd(&x(&ic)).bvadd(&x(it.bv()));
    let claim = and(&[
        &abs_le(y.bv(), ym.bv()),
        &abs_le(i2.bv(), im.bv()),
        &x(v.bv())._eq(&exact),
        &sat.b()._eq(&abs_le(v.bv(), ym.bv()).not()),
    ]);
    (pre, claim)
}

/// The gain pairs `PiGains::from_q32` accepts, as a z3 precondition on 64-bit words:
/// MARGIN ≤ Kp ≤ 2·ONE − MARGIN, 0 < Ki ≤ 4·ONE − MARGIN and 2·Kp + Ki ≤ 4·ONE − MARGIN (Q32,
/// ONE = 2^32, MARGIN = 2^22). `sum_max` stands for 4·ONE − MARGIN (`from_q32`'s SUM_MAX, the
/// bound of both Ki and 2·Kp + Ki), so a refutation check can admit larger gains.
fn admissible_gains(kp: &BV<'static>, ki: &BV<'static>, sum_max: i128) -> Bool<'static> {
    use ecdc_core::servo::gains::{MARGIN, ONE};
    let c = |v: i64| int(i128::from(v), 64);
    and(&[
        &c(MARGIN).bvsle(kp),
        &kp.bvsle(&c(2 * ONE - MARGIN)),
        &c(0).bvslt(ki),
        &ki.bvsle(&int(sum_max, 64)),
        // 2·Kp + Ki at 66 bits, so the sum itself cannot wrap.
        &kp.sign_ext(2)
            .bvadd(&kp.sign_ext(2))
            .bvadd(&ki.sign_ext(2))
            .bvsle(&int(sum_max, 66)),
    ])
}

/// P5 / REQ-SERVO-013, first stage of the shipped PI step (`ecdc_core::servo::pi::clamp_theta`,
/// which `pi_step_word` applies to θ): for every 64-bit θ the result is min(max(θ, −2^28), 2^28).
pub fn pi_theta_clamp() -> Goal {
    let th = Sym::<64>::var("theta");
    let m = int(1 << 28, 64);
    let want = th
        .bv()
        .bvslt(&m.bvneg())
        .ite(&m.bvneg(), &m.bvslt(th.bv()).ite(&m, th.bv()));
    let got = ecdc_core::servo::pi::clamp_theta(th);
    (t(), got.bv()._eq(&want))
}

/// P5 / REQ-SERVO-013, second stage (`ecdc_core::servo::pi::pi_products` at 64 bits): for gains
/// `PiGains::from_q32` accepts (with `sum_max` for its SUM_MAX) and every clamped θ (|θ| ≤ `theta_max`),
/// the product Kp·θ (`ki_side` false) or Ki·θ (true) does not overflow — z3's
/// `bvsmul_noovfl`/`bvsmul_noudfl`: the 64-bit result is the integer product — and lies in
/// ±2^61 (Kp·θ) or ±2^62 (Ki·θ), the ranges [`pi_update_bounded`] assumes. One goal per product
/// keeps each multiplier alone in its formula.
pub fn pi_product_goal(ki_side: bool, sum_max: i128, theta_max: i128) -> Goal {
    let (kp, ki, th) = (
        Sym::<64>::var("kp"),
        Sym::<64>::var("ki"),
        Sym::var("theta"),
    );
    let pre = and(&[
        &admissible_gains(kp.bv(), ki.bv(), sum_max),
        &int(-theta_max, 64).bvsle(th.bv()),
        &th.bv().bvsle(&int(theta_max, 64)),
    ]);
    let (p, it) = ecdc_core::servo::pi::pi_products(kp, ki, th);
    let (gain, prod, bound) = if ki_side {
        (ki, it, 1i128 << 62)
    } else {
        (kp, p, 1i128 << 61)
    };
    let b = int(bound, 64);
    let claim = and(&[
        &gain.bv().bvmul_no_overflow(th.bv(), true),
        &gain.bv().bvmul_no_underflow(th.bv()),
        &prod.bv().bvsle(&b),
        &b.bvneg().bvsle(prod.bv()),
    ]);
    (pre, claim)
}

/// [`pi_product_goal`] for both products with the validated gain bound and θ clamp.
pub fn pi_products_exact() -> [Goal; 2] {
    use ecdc_core::servo::gains::{MARGIN, ONE};
    let sum_max = i128::from(4 * ONE - MARGIN);
    let th = i128::from(ecdc_core::servo::pi::THETA_MAX);
    [
        pi_product_goal(false, sum_max, th),
        pi_product_goal(true, sum_max, th),
    ]
}

// ------------------------------------------------------------------ P3: delay formula on lines

/// P3 / REQ-DC-014, REQ-DC-016, REQ-DC-020 on a line of 3 DC slaves (`crate::dc_math::
/// p3_line_kernel`, 64-bit words, whose hop arithmetic is the shipped `ecdc_core::dc::delay::
/// twice_delay_step`): the frame enters slave i at true local time E_i (any 32-bit
/// phase: the stamps are the low 32 bits, so they may wrap anywhere) and returns through port 1
/// X_i ns later, with X_0 ≥ X_1 + h (what slave 1 sees is inside what slave 0 sees: X_0 = X_1 +
/// 2·hop, hop ≥ 0), round trips < 2^30 ns and 0 ≤ t_Diff < 2^16 ns (one common value, seed 000's
/// assumption). Claims: no error or overflow flag, every delay ≥ 0, d_0 = 0 ≤ d_1 ≤ d_2
/// (monotone along the line), d_2 ≤ X_0 + t_Diff (bounded by the round trip), twice the delays
/// from `twice_delay_step` equal 2·d_1 = X_0 − X_1 + t_Diff and 2·d_2 = X_0 + t_Diff exactly, and
/// d_i equals seed 000 eq. 23 (derived form, REQ-DC-020) evaluated on the true round trips at 66
/// bits: d_1 = ⌈(X_0 − X_1 + t_Diff)/2⌉, d_2 = ⌈(X_0 + t_Diff)/2⌉ (round half up of an integer
/// halving).
pub fn p3_line_kernel() -> Goal {
    let v32 = |n: &str| BV::new_const(ctx(), n, 32);
    let (e0, e1, e2) = (v32("E0"), v32("E1"), v32("E2"));
    let (x0, x1, hop) = (v32("X0"), v32("X1"), v32("hop"));
    let td = v32("t_diff");
    let lim30 = int(1 << 30, 32);
    let pre = and(&[
        &x0.bvult(&lim30),
        &x1.bvult(&lim30),
        &hop.bvult(&lim30),
        &x0._eq(&x1.bvadd(&hop).bvadd(&hop)),
        &td.bvult(&int(1 << 16, 32)),
    ]);
    let z = |b: &BV<'static>| Sym::<64>::of(b.zero_ext(32));
    let p0 = [z(&e0), z(&e1), z(&e2)];
    let p1 = [z(&e0.bvadd(&x0)), z(&e1.bvadd(&x1)), z(&e2)];
    let t = z(&td);
    let (d, twice, bad) = crate::dc_math::p3_line_kernel::<Sym<64>>(3, p0, p1, [t, t, t]);
    let w = |b: &BV<'static>| b.zero_ext(34);
    let half_up = |x: BV<'static>| x.bvadd(&int(1, 66)).bvlshr(&int(1, 66));
    let want1 = half_up(w(&x0).bvsub(&w(&x1)).bvadd(&w(&td)));
    let want2 = half_up(w(&x0).bvadd(&w(&td)));
    let (d0, d1, d2) = (d[0].bv(), d[1].bv(), d[2].bv());
    let claim = and(&[
        &bad.b().not(),
        &d0._eq(&int(0, 64)),
        &int(0, 64).bvsle(d1),
        &d1.bvsle(d2),
        &d2.bvsle(&w(&x0).extract(63, 0).bvadd(&w(&td).extract(63, 0))),
        &d1.sign_ext(2)._eq(&want1),
        &d2.sign_ext(2)._eq(&want2),
        // The shipped `twice_delay_step` results, exactly (no rounding): 2·d_1 = X_0 − X_1 +
        // t_Diff and 2·d_2 = X_0 + t_Diff.
        &twice[1]
            .bv()
            .sign_ext(2)
            ._eq(&w(&x0).bvsub(&w(&x1)).bvadd(&w(&td))),
        &twice[2].bv().sign_ext(2)._eq(&w(&x0).bvadd(&w(&td))),
    ]);
    (pre, claim)
}

// ------------------------------------------------------------------ fold_near (servo)

/// Which path of `fold_near` a [`fold_near`] goal is restricted to: the candidate x + k·p
/// (k ∈ −2..=2) inside the window, or none of them (the division).
#[derive(Clone, Copy, Debug)]
pub enum FoldNearCase {
    /// x + k·p lies in (⌊p/2⌋ − p, ⌊p/2⌋], computed at N + 2 bits.
    Step(i8),
    /// No candidate lies in the window: `fold_near` must fall back to the division.
    Far,
}

/// REQ-TIME-008: `num::fold_near(x, p) = num::fold(x, p)` for every x and p ≥ `p_min` ≤ p ≤
/// `p_max` (the servo calls it with any i64 x and p in [1000, 2^29]), restricted to one
/// `case` so that the precondition check of [`super::prove`] shows each path is reachable.
/// Both sides run the shipped kernels with `urem` abstracted (`smt::with_abstract_urem`); the
/// facts of unsigned remainder assumed for each recorded `urem(u, d) = m` are: it is a function
/// (same operands, same m), m < d for d ≠ 0, and for u < 4·d, m is one of u, u − d, u − 2d,
/// u − 3d (the definition, with the quotient ⌊u/d⌋ ≤ 3). The last fact is what ties the
/// division-free result to `fold`'s; without it the near cases are refuted
/// ([`fold_near_without_remainder_facts`]).
pub fn fold_near<const N: u32>(p_min: u64, p_max: u64, case: FoldNearCase) -> Goal {
    fold_near_goal::<N>(p_min, p_max, case, true)
}

/// [`fold_near`] without the "u < 4d ⇒ m ∈ {u − jd}" fact: must be refuted in the near cases
/// (the proof depends on what the remainder is, not on the two sides sharing a term).
pub fn fold_near_without_remainder_facts<const N: u32>(case: FoldNearCase) -> Goal {
    fold_near_goal::<N>(1, u64::MAX, case, false)
}

fn fold_near_goal<const N: u32>(
    p_min: u64,
    p_max: u64,
    case: FoldNearCase,
    quotient_fact: bool,
) -> Goal {
    let (x, p) = (Sym::<N>::var("x"), Sym::<N>::var("p"));
    let ((near, far), recs) =
        super::with_abstract_urem(|| (k::fold_near::<Sym<N>>(x, p), k::fold::<Sym<N>>(x, p)));
    let w = N + 2;
    let (xw, pw) = (x.bv().sign_ext(2), p.bv().zero_ext(2));
    let hi = pw.bvlshr(&int(1, w));
    let lo = hi.bvsub(&pw);
    let times = |v: &BV<'static>, j: i128| (0..j).fold(int(0, w), |acc, _| acc.bvadd(v));
    let in_window = |k: i128| {
        let kp = times(&pw, k.abs());
        let y = if k < 0 { xw.bvsub(&kp) } else { xw.bvadd(&kp) };
        and(&[&lo.bvslt(&y), &y.bvsle(&hi)])
    };
    let case_pre = match case {
        FoldNearCase::Step(k) => in_window(i128::from(k)),
        FoldNearCase::Far => {
            let any: Vec<Bool<'static>> = (-2..=2).map(in_window).collect();
            Bool::or(ctx(), &any.iter().collect::<Vec<_>>()).not()
        }
    };
    let mut facts = vec![
        p.bv().bvuge(&int(i128::from(p_min), N)),
        p.bv().bvule(&int(i128::from(p_max), N)),
        case_pre,
    ];
    for (i, &(u, d, m)) in recs.iter().enumerate() {
        let nz = d._eq(&int(0, N)).not();
        facts.push(nz.implies(&m.bvult(d)));
        if quotient_fact {
            let (uw, dw, mw) = (u.zero_ext(2), d.zero_ext(2), m.zero_ext(2));
            let small = and(&[&nz, &uw.bvult(&times(&dw, 4))]);
            let opts: Vec<Bool<'static>> =
                (0..4).map(|j| mw._eq(&uw.bvsub(&times(&dw, j)))).collect();
            facts.push(small.implies(&Bool::or(ctx(), &opts.iter().collect::<Vec<_>>())));
        }
        for &(u2, d2, m2) in &recs[i + 1..] {
            facts.push(and(&[&u._eq(u2), &d._eq(d2)]).implies(&m._eq(m2)));
        }
    }
    let pre = Bool::and(ctx(), &facts.iter().collect::<Vec<_>>());
    (pre, near.bv()._eq(far.bv()))
}
