//! Width-generic arithmetic kernels (wrapping difference, folding, clamping, sign-magnitude), written once against the [`Word`] trait so the SMT proofs check this very code.
