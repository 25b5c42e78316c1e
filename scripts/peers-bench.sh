#!/usr/bin/env bash
# Other masters on the emulator beside ecdc, measured by its DC yardstick (docs/emulator.md
# "DC yardstick"). Over a veth pair between two network namespaces created (and always deleted)
# by this script:
#
#   master ns  [ecm0] <--veth--> [ecs0]  slave ns
#   MASTER                         ecdc emulate --json --scenario FILE
#
# For each scenario, PEERS_REPEATS rounds of the masters one after the other (so host load
# drifts over all masters alike), each run against a fresh `ecdc emulate` with the same
# scenario file (so the same seed: the same crystals and delays), each for the same SECONDS of
# cyclic operation at a 1 ms cycle:
#   ethercrab    peers/ethercrab-driver: the real ethercrab crate, DC as its own docs do it
#   soem         peers/soem-driver: the real SOEM (GPL-2.0, its own crate), DC as its samples do
#   ecdc         `ecdc run --cycle-us 1000`
#   soem-config  soem-driver --config-only: ec_config_init + ec_config_map + ec_configdc, no
#                cyclic phase (for CI; not in the default list)
#   ethercrab+ecdc  peers/ethercrab-ecdc: ethercrab's init, AL states and process data, ecdc-core
#                doing DC in the same TX/RX loop (ethercrab's own DC off; docs/ethercrab-ecdc.md;
#                not in the default list: PEERS_MASTERS="ethercrab ecdc ethercrab+ecdc")
#   ethercrab-eeprom100  a labelled variant, not in the default list: the ethercrab driver with
#                `--eeprom-timeout-ms 100`, everything else (DC included) as the example. With the
#                example's 10 ms EEPROM timeout and 5 ms wait-loop tick, one late wake-up on a
#                loaded host ends bring-up with `timeout: EEPROM` (docs/bench.md "Other masters").
# None is told anything about the emulated network; each only gets the interface and the cycle
# (the variant also its EEPROM timeout).
# The numbers are the emulator's true-time measurement of the SYNC0 pulses, not what a master
# believes. Host scheduling makes each run's wire timing different, so runs differ by a few ns.
#
# Scenarios (harness/scenarios/peers_*.toml): seed000-line6, seed003-line2, tree32.
# Writes OUT/peers.json (one record per run, with the commands, the emulator's frame accounting
# and reply turnaround), and from it OUT/peers.md and OUT/peers.svg (scripts/peers-report.py:
# per scenario and master the median and min–max over the runs).
#
# Exit 0 = every master ran, 77 = skipped (reason on the last line), anything else = failed.
# Usage: scripts/peers-bench.sh [SECONDS] [SCENARIO...]      (default 20 s, all three)
# Environment: PEERS_MASTERS (default "ethercrab soem ecdc"), PEERS_REPEATS (runs per scenario
# and master, default 3), PEERS_OUT (default benches/results), PEERS_NO_BUILD=1 to use already
# built binaries, PEERS_APPEND=1 to merge this invocation's runs into an existing
# OUT/peers.json instead of replacing it: its runs of the (scenario, master) pairs run now are
# replaced, all others kept; every run records the invocation ("batch") it came from, and
# peers.md/svg are rendered from the merged file.
set -uo pipefail
cd "$(dirname "$0")/.."
SECONDS_RUN="${1:-20}"
shift || true
SCENARIOS=("$@")
[ "${#SCENARIOS[@]}" -eq 0 ] && SCENARIOS=(seed000-line6 seed003-line2 tree32)
read -r -a MASTERS <<<"${PEERS_MASTERS:-ethercrab soem ecdc}"
OUT="${PEERS_OUT:-benches/results}"
REPEATS="${PEERS_REPEATS:-3}"
CYCLE_US=1000

scenario_file() {
    case "$1" in
        seed000-line6) echo harness/scenarios/peers_seed000_line6.toml ;;
        seed003-line2) echo harness/scenarios/peers_seed003.toml ;;
        tree32) echo harness/scenarios/peers_tree32.toml ;;
        *) return 1 ;;
    esac
}

# shellcheck source=scripts/netns-pair.sh
source scripts/netns-pair.sh
[[ "$REPEATS" =~ ^[1-9][0-9]*$ ]] || fail "PEERS_REPEATS=$REPEATS: a positive integer"
for s in "${SCENARIOS[@]}"; do
    scenario_file "$s" >/dev/null || fail "unknown scenario $s (seed000-line6, seed003-line2, tree32)"
done
command -v jq >/dev/null 2>&1 || skip "jq not installed (needed to read the JSON summaries)"
netns_pair "peer"
ip -n "$NS_M" link set ecm0 up || fail "bringing ecm0 up"

TARGET="${CARGO_TARGET_DIR:-$PWD/target}"
ECDC="$TARGET/release/ecdc"
CRAB="$TARGET/release/ethercrab-driver"
SOEM="$TARGET/release/soem-driver"
if [ -z "${PEERS_NO_BUILD:-}" ]; then
    cargo build -q --release -p ecdc-harness --bin ecdc || fail "cargo build ecdc"
    for m in "${MASTERS[@]}"; do
        case "$m" in
            ethercrab | ethercrab-eeprom100) (cd peers/ethercrab-driver && CARGO_TARGET_DIR="$TARGET" cargo build -q --release) \
                || fail "cargo build peers/ethercrab-driver" ;;
            ethercrab+ecdc) (cd peers/ethercrab-ecdc && CARGO_TARGET_DIR="$TARGET" cargo build -q --release) \
                || fail "cargo build peers/ethercrab-ecdc" ;;
            soem | soem-config) (cd peers/soem-driver && CARGO_TARGET_DIR="$TARGET" cargo build -q --release) \
                || fail "cargo build peers/soem-driver (needs cmake and libclang: .ci/install.sh)" ;;
        esac
    done
fi

# The command each master runs in the master namespace (as shown in the results).
master_cmd() {
    case "$1" in
        ethercrab) echo "env RUST_LOG=warn $CRAB ecm0 $SECONDS_RUN $CYCLE_US" ;;
        ethercrab-eeprom100) echo "env RUST_LOG=warn $CRAB --eeprom-timeout-ms 100 ecm0 $SECONDS_RUN $CYCLE_US" ;;
        soem) echo "$SOEM ecm0 $SECONDS_RUN $CYCLE_US" ;;
        soem-config) echo "$SOEM ecm0 --config-only" ;;
        ecdc) echo "$ECDC run --iface ecm0 --cycle-us $CYCLE_US --duration $SECONDS_RUN --json" ;;
        ethercrab+ecdc) echo "env RUST_LOG=warn $TARGET/release/ethercrab-ecdc ecm0 $SECONDS_RUN $CYCLE_US" ;;
        *) return 1 ;;
    esac
}

# How the report labels a master that is a variant of another (empty: the master as its docs
# run it). Stored in every run's record, so the report needs no list of its own.
master_label() {
    case "$1" in
        ethercrab-eeprom100) echo "variant: ethercrab, example settings except the EEPROM timeout 100 ms, because this host wakes late; DC setup unchanged" ;;
    esac
}

# The master's bring-up time, ms, from its own output: ethercrab's start to all SubDevices in
# OP; SOEM's ec_init to ec_dcsync0 done on every DC slave; ecdc's start to its cyclic phase.
bring_up_ms() {
    case "$1" in
        ethercrab | ethercrab-eeprom100) sed -n 's/.*all SubDevices in OP after [0-9]* ms (\([0-9]*\) ms since start).*/\1/p' "$2.err" ;;
        soem) sed -n 's/.*ec_dcsync0 on [0-9]* slaves (\([0-9]*\) ms since start).*/\1/p' "$2.err" ;;
        soem-config) sed -n 's/.*ec_configdc .*(\([0-9]*\) ms).*/\1/p' "$2.err" ;;
        ecdc) jq -r '.bringup_ms' "$2.out" ;;
    esac | tail -n 1
}

FAILED=()
RECORDS="$WORK/records.jsonl"
# This invocation, recorded in every run so that runs merged from several invocations
# (PEERS_APPEND=1) each keep their own command and time.
CMDLINE="${PEERS_NO_BUILD:+PEERS_NO_BUILD=1 }${PEERS_APPEND:+PEERS_APPEND=1 }${PEERS_MASTERS:+PEERS_MASTERS=\"$PEERS_MASTERS\" }PEERS_REPEATS=$REPEATS scripts/peers-bench.sh $SECONDS_RUN ${SCENARIOS[*]}"
BATCH="$(jq -cn --arg date "$(date -u +%Y-%m-%dT%H:%MZ)" --arg cmd "$CMDLINE" --argjson repeats "$REPEATS" \
    '{started: $date, command: $cmd, repeats: $repeats}')" || fail "jq"
: >"$RECORDS"
# measure SCENARIO MASTER RUN: a fresh emulator, the master in the master namespace, then one
# JSON record appended to $RECORDS.
measure() {
    local scen="$1" master="$2" run="$3" file cmd base emu rc
    file="$(scenario_file "$scen")"
    cmd="$(master_cmd "$master")" || fail "unknown master $master"
    base="$WORK/$scen-$master-$run"
    local emu_cmd=("$ECDC" emulate --iface ecs0 --json --scenario "$file")
    ip netns exec "$NS_S" "${emu_cmd[@]}" >"$base.json" 2>"$base-emu.err" &
    emu=$!
    PIDS+=("$emu")
    for _ in $(seq 50); do
        grep -q "serving" "$base-emu.err" 2>/dev/null && break
        sleep 0.1
    done
    local load
    load="$(cut -d' ' -f1 /proc/loadavg)"
    # shellcheck disable=SC2086 # the command is a word list by construction
    timeout $((SECONDS_RUN + 120)) ip netns exec "$NS_M" $cmd >"$base.out" 2>"$base.err"
    rc=$?
    sleep 0.2
    kill -TERM "$emu" 2>/dev/null
    wait "$emu"
    PIDS=("${PIDS[@]/$emu}")
    if [ "$rc" -ne 0 ]; then
        # Recorded, not fatal: the other runs still say something, and the row shows the exit.
        tail -n 20 "$base.err"
        echo "FAILED: $master on $scen exited with $rc"
        FAILED+=("$scen/$master#$run")
    fi
    grep -h "driver:" "$base.err" | sed "s/^/  [$scen $master #$run] /" || true
    local bu
    bu="$(bring_up_ms "$master" "$base")"
    jq -c --arg scen "$scen" --arg file "$file" --arg master "$master" \
        --arg cmd "${cmd//$TARGET\/release\//}" --arg emu "ecdc emulate --iface ecs0 --json --scenario $file" \
        --arg bu "${bu:-}" --arg load "$load" --argjson secs "$SECONDS_RUN" --argjson rc "$rc" \
        --argjson run "$run" --arg lbl "$(master_label "$master")" --argjson batch "$BATCH" \
        --rawfile log "$base.err" --slurpfile ecdc <(if [ "$master" = ecdc ]; then cat "$base.out"; else echo null; fi) '
        {scenario: $scen, scenario_file: $file, master: $master,
         "label": (if $lbl == "" then null else $lbl end), batch: $batch, run: $run, seconds: $secs,
         cycle_us: '"$CYCLE_US"', command: $cmd, emulate_command: $emu, exit: $rc,
         load_average_at_start: ($load | tonumber),
         bring_up_ms: (if $bu == "" or $bu == "null" then null else ($bu | tonumber) end),
         frames: .frames.received, sync: .sync,
         emulator: {dropped: .frames.dropped, truncated: .frames.truncated,
                    send_errors: .frames.send_errors, turnaround_ns: .turnaround},
         al_states: ([.slaves[].al_state] | unique),
         identities: [.slaves[].identity],
         slaves: [.slaves[] | {position, sync0_edges, clock_error_mean_ns, clock_error_max_abs_ns}],
         master_log: ($log | split("\n") | map(select(test("driver:"))))}
        + (if $ecdc[0] == null then {} else {ecdc_run: ($ecdc[0] | {restarts, bringup_ms,
             machine_frames_sent, frames_lost: .frames.lost, overruns: .cyclic.overruns})} end)' \
        "$base.json" >>"$RECORDS" || fail "reading $base.json"
}

for scen in "${SCENARIOS[@]}"; do
    for run in $(seq "$REPEATS"); do
        for m in "${MASTERS[@]}"; do
            echo "== $scen: $m, run $run of $REPEATS"
            measure "$scen" "$m" "$run"
        done
    done
done

mkdir -p "$OUT"
UPTIME="$(uptime)"
jq -s --arg date "$(date -u +%Y-%m-%dT%H:%MZ)" --arg host "$(nproc) CPUs, $(uname -r)" \
    --arg cmd "$CMDLINE" --arg uptime "$UPTIME" --argjson repeats "$REPEATS" \
    '{generated: $date, machine: $host, command: $cmd, repeats: $repeats,
      uptime_at_end: $uptime, runs: map(.batch += {uptime_at_end: $uptime})}' \
    "$RECORDS" >"$WORK/peers-new.json" || fail "summarising the runs"
if [ -n "${PEERS_APPEND:-}" ] && [ -f "$OUT/peers.json" ]; then
    # Runs of an older file without a batch get its top-level command and time, so each run
    # still says where it came from after the merge. The top level describes this invocation.
    jq -n --slurpfile old "$OUT/peers.json" --slurpfile new "$WORK/peers-new.json" '
        $old[0] as $o | $new[0] as $n
        | ($n.runs | map([.scenario, .master]) | unique) as $now
        | ($o.runs
           | map(if .batch then . else . + {batch: {started: $o.generated, command: $o.command,
                   repeats: $o.repeats, uptime_at_end: $o.uptime_at_end}} end)
           | map(select([.scenario, .master] as $k | any($now[]; . == $k) | not))) as $kept
        | $n + {runs: ($kept + $n.runs)}' >"$WORK/peers-merged.json" \
        || fail "merging into $OUT/peers.json"
    mv "$WORK/peers-merged.json" "$OUT/peers.json" || fail "writing $OUT/peers.json"
else
    mv "$WORK/peers-new.json" "$OUT/peers.json" || fail "writing $OUT/peers.json"
fi
python3 scripts/peers-report.py "$OUT/peers.json" "$OUT/peers.md" "$OUT/peers.svg" \
    || fail "scripts/peers-report.py"
cat "$OUT/peers.md"
[ "${#FAILED[@]}" -eq 0 ] || fail "exited non-zero: ${FAILED[*]} (rows kept in $OUT/peers.md)"
echo "PASS: every master ran against the emulator"
