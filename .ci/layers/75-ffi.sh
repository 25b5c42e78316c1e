# Sourced by .ci/run: the C ABI (ffi/). The committed header must be what cbindgen generates
# from the crate, the C example must compile warning-free as C99, and the network-namespace
# test (scripts/ffi-netns-test.sh) must pass; it skips, with the reason, when not root or
# without netns/veth.
ffi_status=passed
if command -v cbindgen >/dev/null 2>&1; then
    if cbindgen --quiet --config ffi/cbindgen.toml --crate ecdc-ffi --output ffi/include/ecdc.h \
        && git diff --exit-code -- ffi/include/ecdc.h; then
        echo "ffi/include/ecdc.h is current"
    else
        echo "ffi/include/ecdc.h differs from what cbindgen generates (diff above): regenerate it"
        ffi_status="failed (header not current)"
    fi
else
    echo "cbindgen not installed"
    ffi_status="failed (cbindgen missing)"
fi
if cargo build -q --release -p ecdc-ffi \
    && cc -std=c99 -Wall -Wextra -Werror -pedantic -O2 -Iffi/include ffi/examples/c_master.c \
        "${CARGO_TARGET_DIR:-target}/release/libecdc_ffi.a" -lpthread -ldl -lm -o /tmp/ecdc-c_master.$$; then
    echo "c_master compiles with -std=c99 -Wall -Wextra -Werror -pedantic"
    rm -f /tmp/ecdc-c_master.$$
else
    ffi_status="failed (C build)"
fi
ffi_out="$(mktemp)"
bash scripts/ffi-netns-test.sh 2>&1 | tee "$ffi_out"
ffi_rc=${PIPESTATUS[0]}
case "$ffi_rc" in
    0) ;;
    77) [ "$ffi_status" = passed ] && ffi_status="passed (netns part skipped: $(grep -m1 '^SKIP:' "$ffi_out" | sed 's/^SKIP: //'))" ;;
    *) ffi_status="failed (netns test exit $ffi_rc)" ;;
esac
layer ffi "$ffi_status"
rm -f "$ffi_out"
