#!/usr/bin/env bash
# P6 explicit-state search deeper than CI runs it: every configuration of
# proofs/tests/model_check_bfs.rs to depth DEPTH (default 8), one after the other, each with its
# wall time and peak memory, into benches/results/p6-deep.md. Heavy (tens of minutes to hours on
# 2 vCPUs): run by hand, commit the result file. CI searches to depth 5-6
# (.ci/layers/30-model-check.sh).
#
# Usage: scripts/p6-deep.sh [DEPTH] [TEST...]   (TEST: a p6_bfs_* name; default all four)
set -uo pipefail
cd "$(dirname "$0")/.."
DEPTH="${1:-8}"
shift || true
tests="${*:-p6_bfs_one_slave_op p6_bfs_two_slaves_init p6_bfs_three_slaves_mixed_widths p6_bfs_four_slaves_mixed}"
out=benches/results/p6-deep.md
cargo test -p ecdc-proofs --profile model-check --test model_check_bfs --no-run || exit 1
commit=$(git rev-parse --short HEAD)
dirty=$(git status --porcelain --untracked-files=no -- core proofs | grep -q . && echo "+dirty")
rows=()
fail=0
for t in $tests; do
    log=$(mktemp)
    P6_DEPTH="$DEPTH" /usr/bin/time -v cargo test -q -p ecdc-proofs --profile model-check \
        --test model_check_bfs -- --ignored --exact "$t" --nocapture >"$log" 2>&1
    rc=$?
    line=$(grep -m1 '^P6 BFS' "$log" || echo "no result line")
    rss=$(sed -n 's/.*Maximum resident set size (kbytes): *//p' "$log")
    wall=$(sed -n 's/.*Elapsed (wall clock) time (h:mm:ss or m:ss): *//p' "$log")
    status=passed
    [ "$rc" = 0 ] || { status="FAILED (exit $rc)"; fail=1; grep -m3 'panicked\|violated' "$log"; }
    echo "[p6-deep] $t depth $DEPTH: $status, $wall, $((${rss:-0} / 1024)) MB: $line"
    rows+=("| \`$t\` | $DEPTH | $status | $line | $wall | $((${rss:-0} / 1024)) | \`$commit$dirty\`, $(date -u +%Y-%m-%d) |")
    rm -f "$log"
done
# Rows of configurations not run now are kept from the previous file (each row says its
# commit and day).
for t in p6_bfs_one_slave_op p6_bfs_two_slaves_init p6_bfs_three_slaves_mixed_widths p6_bfs_four_slaves_mixed; do
    case " $tests " in *" $t "*) continue ;; esac
    [ -f "$out" ] && old=$(grep "^| \`$t\` |" "$out") && rows+=("$old")
done
{
    echo "# P6 search beyond the depth CI runs"
    echo
    echo "Produced by \`scripts/p6-deep.sh $DEPTH [TEST...]\` on $(nproc) shared vCPUs; each row gives the"
    echo "code's commit (+dirty: uncommitted changes under core/ or proofs/) and the day it ran,"
    echo "\`model-check\` profile (optimised, debug assertions and overflow checks on). Each row is"
    echo "one configuration of proofs/tests/model_check_bfs.rs searched breadth-first from every"
    echo "state of its fault-free bring-up to the depth given, with every check of the CI search on"
    echo "every state and transition (docs/verification.md, P6). Peak memory is the test"
    echo "process's maximum resident set."
    echo
    echo "| test | depth | result | search | wall | peak RSS MB | commit, day |"
    echo "|---|---:|---|---|---:|---:|---|"
    printf '%s\n' "${rows[@]}"
} >"$out"
echo "wrote $out"
exit "$fail"
