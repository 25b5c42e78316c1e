#!/usr/bin/env bash
# Other masters on the emulator, measured by its DC yardstick (docs/emulator.md "DC yardstick").
# Over a veth pair between two network namespaces created (and always deleted) by this script:
#
#   master ns  [ecm0] <--veth--> [ecs0]  slave ns
#   MASTER                         ecdc emulate --json
#
# Masters, one after the other, each against a fresh `ecdc emulate` with the same scenario
# (default: 3 slaves in a line, seed 0), each run for the same SECONDS of cyclic operation at a
# 1 ms cycle:
#   ethercrab  peers/ethercrab-driver: the real ethercrab crate, DC as its own docs do it
#   ecdc       `ecdc run --cycle-us 1000`
#   ethercrab+ecdc  peers/ethercrab-ecdc: ethercrab's init, AL states and process data, ecdc-core
#              doing DC in the same TX/RX loop (ethercrab's own DC off; docs/ethercrab-ecdc.md)
# Neither is told anything about the emulated network; both only get the interface. The numbers
# are the emulator's true-time measurement of the SYNC0 pulses, not what either master believes.
# Host scheduling makes each run's wire timing different, so runs differ by a few ns.
#
# Exit 0 = every master ran, 77 = skipped (reason on the last line), anything else = failed.
# Usage: scripts/peers-bench.sh [SECONDS] [-- extra `ecdc emulate` args, e.g. --slaves 6]
set -uo pipefail
cd "$(dirname "$0")/.."
SECONDS_RUN="${1:-10}"
shift || true
[ "${1:-}" = "--" ] && shift
EMU_ARGS=("$@")

# shellcheck source=scripts/netns-pair.sh
source scripts/netns-pair.sh
command -v jq >/dev/null 2>&1 || skip "jq not installed (needed to read the JSON summaries)"
netns_pair "peer"
ip -n "$NS_M" link set ecm0 up || fail "bringing ecm0 up"

TARGET="${CARGO_TARGET_DIR:-$PWD/target}"
cargo build -q --release -p ecdc-harness --bin ecdc || fail "cargo build ecdc"
(cd peers/ethercrab-driver && CARGO_TARGET_DIR="$TARGET" cargo build -q --release) \
    || fail "cargo build peers/ethercrab-driver"
ECDC="$TARGET/release/ecdc"
CRAB="$TARGET/release/ethercrab-driver"

# measure NAME COMMAND...: a fresh emulator, the master in the master namespace, then the
# emulator's JSON in $WORK/NAME.json.
measure() {
    local name="$1"
    shift
    ip netns exec "$NS_S" "$ECDC" emulate --iface ecs0 --json "${EMU_ARGS[@]}" \
        >"$WORK/$name.json" 2>"$WORK/$name-emu.err" &
    local emu=$!
    PIDS+=("$emu")
    for _ in $(seq 50); do
        grep -q "serving" "$WORK/$name-emu.err" 2>/dev/null && break
        sleep 0.1
    done
    timeout $((SECONDS_RUN + 60)) ip netns exec "$NS_M" "$@" >"$WORK/$name.out" 2>"$WORK/$name.err"
    local rc=$?
    sleep 0.2
    kill -TERM "$emu" 2>/dev/null
    wait "$emu"
    PIDS=("${PIDS[@]/$emu}")
    if [ "$rc" -ne 0 ]; then
        tail -n 20 "$WORK/$name.err"
        fail "$name exited with $rc"
    fi
    grep -h "ethercrab-driver:" "$WORK/$name.err" || true
}

MASTERS=(ethercrab ecdc)
measure ethercrab env RUST_LOG=warn "$CRAB" ecm0 "$SECONDS_RUN" 1000
measure ecdc "$ECDC" run --iface ecm0 --cycle-us 1000 --duration "$SECONDS_RUN" --json
jq -r '"ecdc run: restarts \(.restarts), frames sent \(.frames.sent) lost \(.frames.lost), cyclic overruns \(.cyclic.overruns), wake max \(.cyclic.wake.max / 1000 | round) us"' \
    "$WORK/ecdc.out"

# ---- ethercrab+ecdc (peers/ethercrab-ecdc): told the same as the others, only the interface ----
(cd peers/ethercrab-ecdc && CARGO_TARGET_DIR="$TARGET" cargo build -q --release) \
    || fail "cargo build peers/ethercrab-ecdc"
measure ethercrab+ecdc env RUST_LOG=warn ETHERCRAB_ECDC_EVENTS="${ETHERCRAB_ECDC_EVENTS:-0}" "$TARGET/release/ethercrab-ecdc" ecm0 "$SECONDS_RUN" 1000
grep -h "ethercrab-ecdc:" "$WORK/ethercrab+ecdc.err" || true
MASTERS+=(ethercrab+ecdc)
# ---- end ethercrab+ecdc ----

echo "== the emulator's yardstick ($SECONDS_RUN s cyclic, 1 ms; emulate ${EMU_ARGS[*]:-(3 slaves, seed 0)}; load average $(cut -d' ' -f1 /proc/loadavg))"
printf '%-15s %7s %7s %9s %8s %8s %12s %10s %s\n' master firing pairs "mean|.|" "p99|.|" "max|.|" "signed mean" "lock ms" "AL states"
for name in "${MASTERS[@]}"; do
    jq -r --arg n "$name" '
      def f: if . == null then "-" else (. * 10 | round / 10 | tostring) end;
      [$n, (.sync.slaves_firing|tostring), (.sync.pairs|tostring), (.sync.skew_mean_ns|f),
       (.sync.skew_p99_ns|f), (.sync.skew_max_ns|f), (.sync.skew_signed_mean_ns|f),
       (.sync.lock_ms|f), ([.slaves[].al_state] | unique | join(","))] | @tsv' "$WORK/$name.json" |
        awk -F'\t' '{printf "%-15s %7s %7s %9s %8s %8s %12s %10s %s\n", $1, $2, $3, $4, $5, $6, $7, $8, $9}'
done
echo "per slave (clock error vs the reference in the window: signed mean / max |.|, ns)"
for name in "${MASTERS[@]}"; do
    jq -r --arg n "$name" '"  \($n): " + ([.slaves[] | "\(.position): \(.clock_error_mean_ns // "-" | if type == "number" then (. * 10 | round / 10) else . end)/\(.clock_error_max_abs_ns // "-")"] | join("  "))' "$WORK/$name.json"
done
echo "PASS: every master ran against the emulator"
