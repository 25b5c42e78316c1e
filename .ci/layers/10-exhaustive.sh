# Sourced by .ci/run. Exhaustive checks: every #[ignore]d test of ecdc-proofs (the kernels at
# 8/16 bits in proofs/tests/exhaustive.rs, and the 2^16 flag-word checks of the other areas),
# in release mode so the enumeration is fast. Fails the layer on any failure.
if cargo test -p ecdc-proofs --release --tests -- --ignored --nocapture; then
    layer exhaustive passed
else
    layer exhaustive failed
fi
