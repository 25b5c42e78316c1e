# Sourced by .ci/run. Exhaustive checks: every #[ignore]d test of ecdc-proofs (the kernels at
# 8/16 bits in proofs/tests/exhaustive.rs, and any other area's long enumeration),
# in release mode so the enumeration is fast. Fails the layer on any failure. The P6 model check
# (its tests are named p6_all_*, also #[ignore]d) is left to 30-model-check.sh.
if cargo test -p ecdc-proofs --release --tests -- --ignored --nocapture --skip p6_all_; then
    layer exhaustive passed
else
    layer exhaustive failed
fi
