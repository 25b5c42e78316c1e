# Sourced by .ci/run. Bounded model checking of the DC state machine (P6): a model test binary
# proofs/tests/model_check*.rs that drives the real no_std machine against an emulated ring with
# fault actions over all interleavings up to its bound. Skipped until that model exists.
mc_tests=$(ls proofs/tests/model_check*.rs 2>/dev/null | xargs -r -n1 basename | sed 's/\.rs$//')
if [ -z "$mc_tests" ]; then
    layer model-check "skipped: no model-check harness yet (proofs/tests/model_check*.rs; issue 7 item 3)"
else
    mc_ok=1
    for t in $mc_tests; do
        cargo test -p ecdc-proofs --release --test "$t" -- --include-ignored --nocapture || mc_ok=0
    done
    if [ "$mc_ok" = 1 ]; then layer model-check passed; else layer model-check failed; fi
    unset mc_ok
fi
unset mc_tests
