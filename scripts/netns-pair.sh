# Sourced by the network-namespace tests (scripts/netns-test.sh, scripts/ffi-netns-test.sh):
# the SKIP/FAIL convention (exit 77 = skipped with the reason on the last line, 1 = failed),
# and `netns_pair TAG`, which creates two namespaces ecdc-TAGm-PID / ecdc-TAGs-PID joined by a
# veth pair (ecm0 in the master namespace, left down; ecs0 in the slave namespace, up), a work
# directory $WORK, and a cleanup on exit that stops every pid in PIDS and always deletes both
# namespaces and $WORK. Nothing touches the host's real interfaces. `ecdc_binary` finds or
# builds the `ecdc` binary ($ECDC); `start_emulator` / `stop_emulator` run its `emulate` in the
# slave namespace.

skip() { echo "SKIP: $*"; exit 77; }
fail() { echo "FAIL: $*"; exit 1; }

netns_pair() { # netns_pair TAG
    [ "$(id -u)" = 0 ] || skip "needs root to create network namespaces (run: sudo $0)"
    command -v ip >/dev/null 2>&1 || skip "iproute2 'ip' not installed"
    NS_M="ecdc-${1}m-$$"
    NS_S="ecdc-${1}s-$$"
    WORK="$(mktemp -d "/tmp/ecdc-${1}netns.XXXXXX")"
    PIDS=()
    trap netns_cleanup EXIT
    trap 'exit 130' INT TERM
    ip netns add "$NS_M" 2>/dev/null || skip "cannot create network namespaces (no netns support or not permitted)"
    ip netns add "$NS_S" || fail "creating namespace $NS_S"
    ip link add ecm0 netns "$NS_M" type veth peer name ecs0 netns "$NS_S" 2>/dev/null \
        || skip "cannot create a veth pair (veth module missing?)"
    ip -n "$NS_S" link set ecs0 up || fail "bringing ecs0 up"
}

netns_cleanup() {
    for p in "${PIDS[@]:-}"; do
        [ -n "$p" ] && kill -TERM "$p" 2>/dev/null
    done
    for p in "${PIDS[@]:-}"; do
        [ -n "$p" ] && wait "$p" 2>/dev/null
    done
    ip netns del "$NS_M" 2>/dev/null
    ip netns del "$NS_S" 2>/dev/null
    rm -rf "$WORK"
}

# ecdc_binary PATH PROFILE: ECDC is PATH made absolute; an empty PATH builds the `ecdc` binary
# with cargo in PROFILE (debug or release) and takes that one.
ecdc_binary() {
    ECDC="$1"
    if [ -z "$ECDC" ]; then
        if [ "$2" = release ]; then
            cargo build -q --release -p ecdc-harness --bin ecdc || fail "cargo build --release (ecdc)"
        else
            cargo build -q -p ecdc-harness --bin ecdc || fail "cargo build (ecdc)"
        fi
        ECDC="${CARGO_TARGET_DIR:-target}/$2/ecdc"
    fi
    [ -x "$ECDC" ] || fail "no ecdc binary at $ECDC"
    ECDC="$(cd "$(dirname "$ECDC")" && pwd)/$(basename "$ECDC")"
}

# start_emulator NAME [ARGS...]: runs `ecdc emulate --iface ecs0 --json ARGS...` in the slave
# namespace and waits until it serves. Its log is $WORK/NAME.err; its JSON summary lands in
# $WORK/NAME.json when it is stopped. EMU_PID is its pid.
start_emulator() {
    local name="$1"
    shift
    ip netns exec "$NS_S" "$ECDC" emulate --iface ecs0 --json "$@" \
        >"$WORK/$name.json" 2>"$WORK/$name.err" &
    EMU_PID=$!
    PIDS+=("$EMU_PID")
    for _ in $(seq 50); do
        grep -q "serving" "$WORK/$name.err" 2>/dev/null && return 0
        kill -0 "$EMU_PID" 2>/dev/null || break
        sleep 0.1
    done
    return 1
}

# stop_emulator: SIGTERM, wait, leaves its JSON summary in place; its exit status.
stop_emulator() {
    kill -TERM "$EMU_PID" 2>/dev/null
    wait "$EMU_PID"
    local rc=$?
    PIDS=("${PIDS[@]/$EMU_PID}")
    return $rc
}
