//! `Word` for z3 bit-vectors: each method is exactly one SMT-LIB operator.
//!
//! `Word` requires `Copy` (kernels pass words by value), and z3 terms are reference-counted
//! handles, so each term is leaked once and the wrappers hold `&'static` references. A proof
//! builds a few hundred terms; the leak is bounded by the test process's lifetime.

use ecdc_core::num::{Logic, Word};
use std::cell::RefCell;
use z3::ast::{Ast, Bool, BV};
use z3::{Config, Context};

/// A recorded `urem` in abstract mode: (dividend, divisor, fresh remainder).
pub type UremRecord = (
    &'static BV<'static>,
    &'static BV<'static>,
    &'static BV<'static>,
);

thread_local! {
    // One z3 context per thread, leaked so terms can be `'static`.
    static CTX: &'static Context = Box::leak(Box::new(Context::new(&Config::new())));
    static ABSTRACT_UREM: RefCell<Option<Vec<UremRecord>>> = const { RefCell::new(None) };
}

/// Runs `f` with `urem` abstracted: each `urem(x, p)` returns a fresh unconstrained constant
/// and is recorded, so a proof can assume only what it needs of the remainder (e.g. r < p and
/// "x − r is a multiple of p") instead of bit-blasting a divider. Proofs that use this state
/// which facts of `bvurem` they rely on.
pub fn with_abstract_urem<R>(f: impl FnOnce() -> R) -> (R, Vec<UremRecord>) {
    ABSTRACT_UREM.with(|a| *a.borrow_mut() = Some(Vec::new()));
    let r = f();
    let recs = ABSTRACT_UREM
        .with(|a| a.borrow_mut().take())
        .unwrap_or_default();
    (r, recs)
}

/// The calling thread's z3 context.
pub fn ctx() -> &'static Context {
    CTX.with(|c| *c)
}

fn leak<T>(t: T) -> &'static T {
    Box::leak(Box::new(t))
}

/// A symbolic N-bit word.
#[derive(Clone, Copy, Debug)]
pub struct Sym<const N: u32>(pub &'static BV<'static>);

/// A symbolic Boolean.
#[derive(Clone, Copy, Debug)]
pub struct SymBool(pub &'static Bool<'static>);

impl<const N: u32> Sym<N> {
    /// A fresh free constant named `name`.
    pub fn var(name: &str) -> Self {
        Sym(leak(BV::new_const(ctx(), name, N)))
    }
    /// The constant `v mod 2^N`.
    pub fn val(v: u64) -> Self {
        Sym(leak(BV::from_u64(ctx(), v, N)))
    }
    /// Wraps an existing N-bit term.
    pub fn of(bv: BV<'static>) -> Self {
        debug_assert_eq!(bv.get_size(), N);
        Sym(leak(bv))
    }
    /// The underlying term.
    pub fn bv(self) -> &'static BV<'static> {
        self.0
    }
}

impl SymBool {
    /// Wraps a Boolean term.
    pub fn of(b: Bool<'static>) -> Self {
        SymBool(leak(b))
    }
    /// The underlying term.
    pub fn b(self) -> &'static Bool<'static> {
        self.0
    }
}

impl Logic for SymBool {
    fn and(self, rhs: Self) -> Self {
        SymBool::of(Bool::and(ctx(), &[self.0, rhs.0]))
    }
    fn or(self, rhs: Self) -> Self {
        SymBool::of(Bool::or(ctx(), &[self.0, rhs.0]))
    }
    fn not(self) -> Self {
        SymBool::of(self.0.not())
    }
}

/// `Word` methods that are one Z3 bit-vector operation on both operands.
macro_rules! z3_binary_ops {
    ($($name:ident -> $ret:ty = $wrap:ident::of($op:ident);)*) => {
        $(
            fn $name(self, rhs: Self) -> $ret {
                $wrap::of(self.0.$op(rhs.0))
            }
        )*
    };
}

impl<const N: u32> Word for Sym<N> {
    type Bool = SymBool;
    type Signed = Sym<N>;
    const BITS: u32 = N;

    fn lit(v: u8) -> Self {
        Sym::val(u64::from(v))
    }
    z3_binary_ops! {
        wrapping_add -> Self = Sym::of(bvadd);
        wrapping_sub -> Self = Sym::of(bvsub);
        wrapping_mul -> Self = Sym::of(bvmul);
        bit_and -> Self = Sym::of(bvand);
        bit_or -> Self = Sym::of(bvor);
        eq -> SymBool = SymBool::of(_eq);
        ult -> SymBool = SymBool::of(bvult);
        slt -> SymBool = SymBool::of(bvslt);
    }
    fn shl(self, n: u32) -> Self {
        Sym::of(self.0.bvshl(Sym::<N>::val(u64::from(n)).0))
    }
    fn shr(self, n: u32) -> Self {
        Sym::of(self.0.bvlshr(Sym::<N>::val(u64::from(n)).0))
    }
    fn urem(self, rhs: Self) -> Self {
        let fresh = ABSTRACT_UREM.with(|a| {
            a.borrow_mut().as_mut().map(|recs| {
                let r = leak(BV::fresh_const(ctx(), "urem", N));
                recs.push((self.0, rhs.0, r));
                r
            })
        });
        match fresh {
            Some(r) => Sym(r),
            None => Sym::of(self.0.bvurem(rhs.0)),
        }
    }
    fn select(c: SymBool, a: Self, b: Self) -> Self {
        Sym::of(c.0.ite(a.0, b.0))
    }
    fn to_signed(self) -> Self {
        self
    }
    fn from_signed(s: Self) -> Self {
        s
    }
}
