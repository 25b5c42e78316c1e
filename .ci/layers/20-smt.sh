# Sourced by .ci/run. SMT proofs (z3) of the ecdc-core arithmetic kernels at full 32/64-bit
# width: proofs/tests/smt.rs, feature `smt` of ecdc-proofs. The z3 crate links the system libz3
# (libz3-dev) and its bindings are generated with bindgen, which needs libclang.
smt_ready=1
[ -e /usr/include/z3.h ] || smt_ready=0
if ! ls /usr/lib/llvm-*/lib/libclang.so* >/dev/null 2>&1; then
    # Normally installed by .ci/install.sh; repeated here so this layer is self-sufficient.
    { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq libclang-dev; } >/dev/null 2>&1 || true
    ls /usr/lib/llvm-*/lib/libclang.so* >/dev/null 2>&1 || smt_ready=0
fi
if [ "$smt_ready" = 0 ]; then
    layer smt "failed: libz3-dev or libclang-dev missing (see .ci/install.sh)"
elif cargo clippy -p ecdc-proofs --features smt --all-targets -- -D warnings \
    && cargo test -p ecdc-proofs --release --features smt --test smt -- --nocapture --test-threads 2; then
    layer smt passed
else
    layer smt failed
fi
unset smt_ready
