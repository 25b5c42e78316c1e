#!/usr/bin/env bash
# Integration test of the C ABI: the C example master (ffi/examples/c_master.c, linked against
# target/release/libecdc_ffi.a) brings DC up on emulated ESCs over a veth pair between two
# network namespaces created (and always deleted) by this script.
#
#   master ns  [ecm0] <--veth--> [ecs0]  slave ns
#   c_master                       ecdc emulate
#
# Part 1: c_master with ecdc_machine_new and ecdc_poll_transmit: lock reached, every frame
#   answered by the emulator, round trips measured.
# Part 2: c_master -s -i: machine in caller storage (ecdc_machine_init), cyclic frames built by
#   the host (its own BRD plus ecdc_poll_transmit_into): lock reached, the host's datagram came
#   back with the right working counter.
# Part 3: c_master under valgrind (memcheck: no error, no definite leak) or, without valgrind,
#   built with -fsanitize=address,undefined: lock reached and a clean report.
#
# Exit 0 = passed, 77 = skipped (reason on the last line, "SKIP: ..."), anything else = failed.
# Usage: scripts/ffi-netns-test.sh [path/to/ecdc]   (default: builds it with cargo)
set -uo pipefail
cd "$(dirname "$0")/.."

# shellcheck source=scripts/netns-pair.sh
source scripts/netns-pair.sh
CC="${CC:-cc}"
command -v "$CC" >/dev/null 2>&1 || skip "no C compiler ($CC)"
netns_pair f
# c_master does not bring interfaces up (it says how when one is down).
ip -n "$NS_M" link set ecm0 up || fail "bringing ecm0 up"

ecdc_binary "${1:-}" debug

cargo build -q --release -p ecdc-ffi || fail "cargo build --release -p ecdc-ffi"
LIB="${CARGO_TARGET_DIR:-target}/release/libecdc_ffi.a"
[ -f "$LIB" ] || fail "no static library at $LIB"
CFLAGS=(-std=c99 -Wall -Wextra -Werror -pedantic -O2 -g -Iffi/include)
LIBS=("$LIB" -lpthread -ldl -lm)
"$CC" "${CFLAGS[@]}" ffi/examples/c_master.c "${LIBS[@]}" -o "$WORK/c_master" \
    || fail "compiling ffi/examples/c_master.c"

# emulator_up: the ESC emulator in the slave namespace (start_emulator, log and summary in
# $WORK/emu.{err,json}); the test fails when it does not start.
emulator_up() {
    start_emulator emu || { cat "$WORK/emu.err"; fail "emulator did not start"; }
}

FAILED=0
ok() { echo "  ok   $*"; }
bad() { echo "  FAIL $*"; FAILED=1; }
# field FILE KEY: the value of KEY=... on the summary line.
field() { grep -m1 '^summary:' "$1" | grep -o "\b$2=[^ ]*" | cut -d= -f2; }
# run_master LABEL OUT [PREFIX...] -- [ARGS...]: runs c_master in the master namespace.
run_master() {
    local out="$1"
    shift
    ip netns exec "$NS_M" "$@" >"$out" 2>&1
}
# master_part OUT ARGS...: c_master ARGS against a fresh emulator, output in OUT; shows its
# summary line and checks the lock. RC is its exit status.
master_part() {
    local out="$1"
    shift
    emulator_up
    run_master "$out" "$WORK/c_master" "$@"
    RC=$?
    stop_emulator || bad "emulator exited with an error"
    grep -m1 '^summary:' "$out" || tail -n 20 "$out"
    check_lock "$out" "$RC"
}
check_lock() { # check_lock OUT RC
    if [ "$2" -eq 0 ] && [ "$(field "$1" lock_reached)" = yes ]; then
        ok "lock reached (lock_frames $(field "$1" lock_frames), locked at end: $(field "$1" locked_at_end), restarts $(field "$1" restarts))"
    else
        bad "no lock (exit $2):"
        tail -n 15 "$1" | sed 's/^/    /'
    fi
}

echo "== part 1: ecdc_machine_new + ecdc_poll_transmit"
master_part "$WORK/p1.out" -d 3 ecm0
SENT=$(field "$WORK/p1.out" frames_sent)
RECV=$(field "$WORK/p1.out" frames_received)
EMU_RX=$(jq -r '.frames.received' "$WORK/emu.json" 2>/dev/null || grep -o '"received": *[0-9]*' "$WORK/emu.json" | grep -o '[0-9]*$')
if [ -n "$SENT" ] && [ "$SENT" -gt 0 ] && [ "$EMU_RX" = "$SENT" ]; then
    ok "emulator received all $SENT frames the master sent"
else
    bad "master sent ${SENT:-?}, emulator received ${EMU_RX:-?}"
fi
# Every reply comes back on a veth; a reply the master waited too long for still arrives.
if [ -n "$RECV" ] && [ "$RECV" -le "$SENT" ] && [ $((RECV * 20)) -ge $((SENT * 19)) ]; then
    ok "master received $RECV of $SENT replies"
else
    bad "master received ${RECV:-?} of ${SENT:-?} replies"
fi
# The emulator's true-time DC yardstick on the C master (docs/emulator.md "DC yardstick").
jq -c '.sync' "$WORK/emu.json"
if jq -e '.sync.slaves_firing == 3 and .sync.lock_ms != null and .sync.skew_max_ns < 100' "$WORK/emu.json" >/dev/null; then
    ok "emulator yardstick: 3 slaves fire SYNC0, locked, max |skew| $(jq .sync.skew_max_ns "$WORK/emu.json") ns"
else
    bad "emulator yardstick: $(jq -c .sync "$WORK/emu.json")"
fi
MED=$(field "$WORK/p1.out" rtt_us_median)
[ -n "$MED" ] && [ "$MED" != "0.0" ] && ok "round trip median $MED us" || bad "no round trip measured"

echo "== part 2: ecdc_machine_init (caller storage) + host frames with ecdc_poll_transmit_into"
master_part "$WORK/p2.out" -d 3 -s -i -q ecm0
HF=$(field "$WORK/p2.out" host_frames)
HW=$(field "$WORK/p2.out" host_wkc_ok)
if [ -n "$HF" ] && [ "$HF" -gt 100 ] && [ "$HW" -le "$HF" ] && [ $((HW * 10)) -ge $((HF * 9)) ]; then
    ok "host-built cyclic frames: $HW of $HF came back with the host BRD's working counter = slaves"
else
    bad "host-built cyclic frames: ${HW:-?} of ${HF:-?} with the right working counter"
fi

echo "== part 3: memory checking"
if command -v valgrind >/dev/null 2>&1; then
    emulator_up
    run_master "$WORK/p3.out" valgrind --error-exitcode=99 --leak-check=full --errors-for-leak-kinds=definite \
        "$WORK/c_master" -d 8 -q ecm0
    RC=$?
    stop_emulator || bad "emulator exited with an error"
    grep -m1 '^summary:' "$WORK/p3.out" || tail -n 20 "$WORK/p3.out"
    grep -m1 'ERROR SUMMARY' "$WORK/p3.out"
    if [ "$RC" -eq 99 ] || ! grep -q 'ERROR SUMMARY: 0 errors' "$WORK/p3.out"; then
        bad "valgrind reported errors:"
        grep -A8 '^==[0-9]*== [A-Z]' "$WORK/p3.out" | head -n 40 | sed 's/^/    /'
    else
        ok "valgrind memcheck: 0 errors, no definite leak"
    fi
    check_lock "$WORK/p3.out" "$RC"
elif "$CC" "${CFLAGS[@]}" -fsanitize=address,undefined -fno-omit-frame-pointer ffi/examples/c_master.c \
    "${LIBS[@]}" -o "$WORK/c_master_asan" 2>"$WORK/asan-build.err"; then
    emulator_up
    ASAN_OPTIONS=detect_leaks=1:abort_on_error=0:exitcode=99 UBSAN_OPTIONS=halt_on_error=1:exitcode=99 \
        run_master "$WORK/p3.out" "$WORK/c_master_asan" -d 4 -q ecm0
    RC=$?
    stop_emulator || bad "emulator exited with an error"
    grep -m1 '^summary:' "$WORK/p3.out"
    if [ "$RC" -eq 99 ] || grep -q 'Sanitizer' "$WORK/p3.out"; then
        bad "sanitizer report:"
        head -n 40 "$WORK/p3.out" | sed 's/^/    /'
    else
        ok "AddressSanitizer + UBSan: clean"
    fi
    check_lock "$WORK/p3.out" "$RC"
else
    bad "neither valgrind nor -fsanitize=address available (install valgrind)"
fi

[ "$FAILED" = 0 ] || fail "see the lines marked FAIL above"
echo "PASS: C ABI netns integration test"
