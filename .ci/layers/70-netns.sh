# Sourced by .ci/run: the network-namespace integration test of the raw-socket runtime
# (scripts/netns-test.sh). Skips, with the reason, when not root or without netns/veth.
netns_out="$(mktemp)"
bash scripts/netns-test.sh 2>&1 | tee "$netns_out"
netns_rc=${PIPESTATUS[0]}
case "$netns_rc" in
    0) layer netns passed ;;
    77) layer netns "skipped: $(grep -m1 '^SKIP:' "$netns_out" | sed 's/^SKIP: //')" ;;
    *) layer netns "failed (exit $netns_rc)" ;;
esac
rm -f "$netns_out"
