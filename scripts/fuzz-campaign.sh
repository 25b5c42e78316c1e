#!/usr/bin/env bash
# A recorded fuzzing campaign: runs each cargo-fuzz target for a fixed number of executions
# (not a time), from its committed seed corpus, and writes what libFuzzer reports at the end
# (executions, exec/s, edges covered, features, corpus size, peak RSS) into
# benches/results/fuzz.md and fuzz.tsv. Heavy: run by hand, commit the result files; CI fuzzes
# for a minute per target only (.ci/layers/40-fuzz.sh).
#
# Usage: scripts/fuzz-campaign.sh [TARGET...]
#   PARSER_RUNS   executions per parser target  (default 10000000)
#   MACHINE_RUNS  executions per other target   (default 1000000)
#   JOBS          targets run side by side      (default 1)
#   TIMEOUT       libFuzzer's per-input limit, s (default 10; raise it for a run at low
#                 priority on a loaded machine, where a slow input is starvation, not a hang)
# A crash stops nothing else: it is saved under fuzz/regressions/<target>/ and its row says so;
# the script then exits 1.
set -uo pipefail
cd "$(dirname "$0")/.."
PARSER_RUNS="${PARSER_RUNS:-10000000}"
MACHINE_RUNS="${MACHINE_RUNS:-1000000}"
JOBS="${JOBS:-1}"
TIMEOUT="${TIMEOUT:-10}"
PARSERS=" wire_parse wire_roundtrip wire_display registers "

all=$(sed -n '/^\[\[bin\]\]/,/^name/ s/^name *= *"\(.*\)"/\1/p' fuzz/Cargo.toml)
targets="${*:-$all}"
cargo +nightly fuzz build --release || { echo "fuzz targets do not build"; exit 1; }
# The code that runs is the code built now: its commit is recorded, not the one at the end.
commit=$(git rev-parse --short HEAD)
# Untracked files do not count: a failing run itself writes its input under fuzz/regressions/.
dirty=$(git status --porcelain --untracked-files=no -- core proofs fuzz | grep -q . && echo "+dirty")

work=$(mktemp -d /tmp/ecdc-fuzz.XXXXXX)
trap 'rm -rf "$work"' EXIT

one() { # one TARGET: fuzz it, leave "$work/TARGET.row"
    local t="$1" runs log start end rc
    case "$PARSERS" in *" $t "*) runs="$PARSER_RUNS" ;; *) runs="$MACHINE_RUNS" ;; esac
    mkdir -p "$work/$t" "fuzz/regressions/$t" "fuzz/corpus/$t"
    log="$work/$t.log"
    start=$(date +%s.%N)
    cargo +nightly fuzz run --release "$t" "$work/$t" "fuzz/corpus/$t" -- \
        -runs="$runs" -print_final_stats=1 -timeout="$TIMEOUT" -rss_limit_mb=2048 \
        -artifact_prefix="$PWD/fuzz/regressions/$t/" >"$log" 2>&1
    rc=$?
    end=$(date +%s.%N)
    local execs eps rss cov ft corp
    execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
    eps=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log" | tail -1)
    rss=$(sed -n 's/^stat::peak_rss_mb: *//p' "$log" | tail -1)
    cov=$(grep -oE 'cov: [0-9]+' "$log" | tail -1 | grep -oE '[0-9]+')
    ft=$(grep -oE 'ft: [0-9]+' "$log" | tail -1 | grep -oE '[0-9]+')
    corp=$(grep -oE 'corp: [0-9]+' "$log" | tail -1 | grep -oE '[0-9]+')
    local status=ok
    [ "$rc" = 0 ] || status="FAILED (exit $rc, input under fuzz/regressions/$t/)"
    printf '%s\t%s\t%s\t%s\t%.0f\t%s\t%s\t%s\t%s\t%s\n' "$t" "$runs" "${execs:-?}" "${eps:-?}" \
        "$(awk -v a="$start" -v b="$end" 'BEGIN { print b - a }')" "${cov:-?}" "${ft:-?}" "${corp:-?}" "${rss:-?}" "$status" \
        >"$work/$t.row"
    echo "[fuzz-campaign] $t: $status, ${execs:-?} executions, ${eps:-?} exec/s, cov ${cov:-?}"
}
export -f one
export work PARSERS PARSER_RUNS MACHINE_RUNS TIMEOUT
printf '%s\n' $targets | xargs -P "$JOBS" -I{} bash -c 'one {}'

out=benches/results
mkdir -p "$out"
day=$(date -u +%Y-%m-%d)
header='target\trequested\texecutions\texec_per_s\twall_s\tedges\tfeatures\tcorpus\tpeak_rss_mb\tstatus\tcommit\tdate\ttoolchain'
# A campaign over some targets replaces their rows and keeps the others' (each row says at
# which commit and on which day it ran).
declare -A rows=()
if [ -f "$out/fuzz.tsv" ]; then
    while IFS=$'\t' read -r name rest; do
        [ "$name" = target ] && continue
        rows[$name]="$name"$'\t'"$rest"
    done <"$out/fuzz.tsv"
fi
toolchain=$(cargo +nightly --version | cut -d' ' -f2-)
for t in $targets; do
    rows[$t]="$(cat "$work/$t.row")"$'\t'"$commit$dirty"$'\t'"$day"$'\t'"$toolchain"
done
order=$(printf '%s\n' $all)
{
    printf "$header\n"
    for t in $order; do [ -n "${rows[$t]:-}" ] && printf '%s\n' "${rows[$t]}"; done
} >"$out/fuzz.tsv"
{
    echo "# Fuzzing campaign"
    echo
    echo "Produced by \`PARSER_RUNS=... MACHINE_RUNS=... JOBS=... scripts/fuzz-campaign.sh [TARGET...]\`"
    echo "on $(nproc) shared vCPUs; each row gives the commit (+dirty: with uncommitted changes"
    echo "under core/, proofs/ or fuzz/), the day and the nightly toolchain it ran with. Every"
    echo "target starts from its committed seed corpus (fuzz/corpus/<target>/); the corpus grown"
    echo "during the run is thrown away. Figures are libFuzzer's final statistics: \`edges\` = \`cov\`"
    echo "(coverage points reached), \`features\` = \`ft\`, \`corpus\` = entries kept. Parser targets"
    echo "(wire_parse, wire_roundtrip, wire_display, registers) are asked for 10^7 executions,"
    echo "the others (machine, maths, servo) for 10^6: \`requested\`."
    echo
    echo "| target | requested | executions | exec/s | wall s | edges | features | corpus | peak RSS MB | status | commit | date |"
    echo "|---|---:|---:|---:|---:|---:|---:|---:|---:|---|---|---|"
    tail -n +2 "$out/fuzz.tsv" | while IFS=$'\t' read -r name req execs eps wall cov ft corp rss status c d _tc; do
        echo "| $name | $req | $execs | $eps | $wall | $cov | $ft | $corp | $rss | $status | \`${c:-fd0dc7c}\` | ${d:-2026-12-02} |"
    done
} >"$out/fuzz.md"
echo "wrote $out/fuzz.md and $out/fuzz.tsv"
! grep -q FAILED "$out/fuzz.tsv"
