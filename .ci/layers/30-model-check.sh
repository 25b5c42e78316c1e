# Sourced by .ci/run. Bounded model checking of the DC state machine (P6), built with the
# `model-check` profile (release optimisation, debug assertions and overflow checks on, so a
# panic path only debug builds have is part of the search):
# proofs/tests/model_check_bfs.rs: explicit-state BFS with state hashing (proofs/src/model.rs)
#   over (real no_std Machine, emulated line with 32/64-bit clocks, wire, master clock) from every
#   fault-free bring-up state
#   to depth 5-6 with 15+2k fault/input actions (AL races included), bounded liveness from
#   every visited state;
# proofs/tests/model_check.rs: every placement of <= 3 faults along the bring-up, and every
#   5-action interleaving after bring-up prefixes (script enumeration).
mc_tests=$(ls proofs/tests/model_check*.rs 2>/dev/null | xargs -r -n1 basename | sed 's/\.rs$//')
if [ -z "$mc_tests" ]; then
    layer model-check "skipped: no model-check harness yet (proofs/tests/model_check*.rs; issue 7 item 3)"
else
    mc_ok=1
    for t in $mc_tests; do
        cargo test -p ecdc-proofs --profile model-check --test "$t" -- --include-ignored --nocapture || mc_ok=0
    done
    if [ "$mc_ok" = 1 ]; then layer model-check passed; else layer model-check failed; fi
    unset mc_ok
fi
unset mc_tests
