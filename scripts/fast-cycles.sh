#!/usr/bin/env bash
# Fast cycles on veth between two network namespaces created (and always deleted) by this
# script: `ecdc run --rt` at 250 and 125 us against `ecdc emulate --rt` on the other CPU, and
# the plain-C cyclic probe (scripts/cyclic-probe.c) the same way, back to back, so the figures
# separate what the host allows from what ecdc's loop adds (docs/runtime.md "Fast cycles").
#
#   master ns  [ecm0] <--veth--> [ecs0]  slave ns
#   ecdc run --rt --cpu 0            ecdc emulate --rt --cpu 1 (6 slaves, seed 0)
#   cyclic-probe ... --rt 0 80       (same emulator, one BRD per cycle)
#
# Per run: cycles, overruns, lost cycles, hold-overs, restarts, wake lateness and round trip,
# and (ecdc) the emulator's true-time SYNC0 skew. Results as JSON lines on stdout and a table
# on stderr; nothing is written into the repository.
#
# Exit 0 = every run completed, 77 = skipped (reason on the last line), anything else = failed.
# Usage: sudo scripts/fast-cycles.sh [SECONDS] [PERIOD_US ...]   (default: 60 s, 250 and 125)
set -uo pipefail
cd "$(dirname "$0")/.."
SECONDS_RUN="${1:-60}"
shift || true
PERIODS=("$@")
[ ${#PERIODS[@]} -eq 0 ] && PERIODS=(250 125)

# shellcheck source=scripts/netns-pair.sh
source scripts/netns-pair.sh
command -v jq >/dev/null 2>&1 || skip "jq not installed (needed to read the JSON summaries)"
command -v cc >/dev/null 2>&1 || skip "no C compiler (cc) for the probe"
[ "$(nproc)" -ge 2 ] || skip "needs two CPUs (master and emulator pinned apart)"
netns_pair "fast"
ip -n "$NS_M" link set ecm0 up || fail "bringing ecm0 up"

TARGET="${CARGO_TARGET_DIR:-$PWD/target}"
cargo build -q --release -p ecdc-harness --bin ecdc || fail "cargo build ecdc"
ECDC="$TARGET/release/ecdc"
cc -O2 -Wall -Wextra -o "$WORK/cyclic-probe" scripts/cyclic-probe.c || fail "building the probe"

# emulator NAME: a fresh `ecdc emulate --rt` on CPU 1 (start_emulator, log and summary in
# $WORK/NAME-emu.{err,json}).
emulator() {
    start_emulator "$1-emu" --slaves 6 --rt --cpu 1 \
        || fail "emulator for $1 did not start: $(tail -n 3 "$WORK/$1-emu.err")"
}

echo "load average before: $(cut -d' ' -f1-3 /proc/loadavg)" >&2
for p in "${PERIODS[@]}"; do
    name="ecdc-$p"
    emulator "$name"
    timeout $((SECONDS_RUN + 60)) ip netns exec "$NS_M" "$ECDC" run --iface ecm0 --rt --cpu 0 \
        --cycle-us "$p" --duration "$SECONDS_RUN" --json --quiet >"$WORK/$name.json" 2>"$WORK/$name.err"
    rc=$?
    stop_emulator
    [ "$rc" -eq 0 ] || fail "$name exited with $rc: $(tail -n 5 "$WORK/$name.err")"
    jq -c --arg p "$p" --slurpfile emu "$WORK/$name-emu.json" '{
        master: "ecdc run", period_us: ($p|tonumber), cycles: .cyclic_cycles_total,
        overruns: .cyclic.overruns, lost_cycles: .machine_lost_cycles,
        holdovers: .holdovers, restarts: .restarts,
        wake_us: {median: (.cyclic.wake.median/1000), p99: (.cyclic.wake.p99/1000),
                  max: (.cyclic.wake.max/1000)},
        rtt_us: {median: (.cyclic.rtt.median/1000), p99: (.cyclic.rtt.p99/1000),
                 max: (.cyclic.rtt.max/1000)},
        skew_ns: {mean: $emu[0].sync.skew_mean_ns, p99: $emu[0].sync.skew_p99_ns,
                  max: $emu[0].sync.skew_max_ns, lock_ms: $emu[0].sync.lock_ms}}' "$WORK/$name.json" \
        || fail "$name: unexpected JSON"

    name="probe-$p"
    emulator "$name"
    timeout $((SECONDS_RUN + 60)) ip netns exec "$NS_M" "$WORK/cyclic-probe" ecm0 "$p" \
        "$SECONDS_RUN" --rt 0 80 >"$WORK/$name.json" 2>"$WORK/$name.err"
    rc=$?
    stop_emulator
    [ "$rc" -eq 0 ] || fail "$name exited with $rc: $(tail -n 5 "$WORK/$name.err")"
    jq -c '{master: "cyclic-probe", period_us, cycles, overruns, lost_cycles: .lost,
            wake_us, rtt_us}' "$WORK/$name.json" || fail "$name: unexpected JSON"
done
echo "load average after: $(cut -d' ' -f1-3 /proc/loadavg)" >&2
