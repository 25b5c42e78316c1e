# Sourced by .ci/run. Fuzzing: every [[bin]] of fuzz/Cargo.toml.
#  1. regression replay: every input under fuzz/regressions/<target>/ (crashes found earlier,
#     committed once fixed) and the committed seed corpus fuzz/corpus/<target>/ must run clean;
#  2. fuzz each target for FUZZ_SECONDS (default 60) from its seed corpus (copied, so the
#     committed corpus is not rewritten); a crash is saved into fuzz/regressions/<target>/ and
#     fails the layer — commit it as a regression input once fixed.
fuzz_secs="${FUZZ_SECONDS:-60}"
fuzz_ok=1
fuzz_targets=$(sed -n '/^\[\[bin\]\]/,/^name/ s/^name *= *"\(.*\)"/\1/p' fuzz/Cargo.toml 2>/dev/null)
if [ -z "$fuzz_targets" ]; then
    layer fuzz "skipped: no [[bin]] targets in fuzz/Cargo.toml"
elif ! cargo +nightly --version >/dev/null 2>&1 || ! cargo fuzz --version >/dev/null 2>&1; then
    layer fuzz "failed: nightly toolchain or cargo-fuzz missing (see .ci/install.sh)"
elif ! cargo +nightly fuzz build; then
    layer fuzz "failed: fuzz targets do not build"
else
    fuzz_work=$(mktemp -d)
    for t in $fuzz_targets; do
        mkdir -p "fuzz/regressions/$t" "fuzz/corpus/$t" "$fuzz_work/$t"
        echo "--- $t: replay regressions and seed corpus"
        if ! cargo +nightly fuzz run "$t" "fuzz/regressions/$t" "fuzz/corpus/$t" -- -runs=0 \
            -artifact_prefix="$PWD/fuzz/regressions/$t/"; then
            echo "FAIL: $t crashes on a committed regression or seed input"
            fuzz_ok=0
            continue
        fi
        echo "--- $t: fuzz for ${fuzz_secs}s"
        if ! cargo +nightly fuzz run "$t" "$fuzz_work/$t" "fuzz/corpus/$t" -- \
            -max_total_time="$fuzz_secs" -timeout=10 -rss_limit_mb=2048 \
            -artifact_prefix="$PWD/fuzz/regressions/$t/"; then
            echo "FAIL: $t crashed; input saved under fuzz/regressions/$t/:"
            ls -l "fuzz/regressions/$t/"
            fuzz_ok=0
        fi
    done
    rm -rf "$fuzz_work"
    if [ "$fuzz_ok" = 1 ]; then layer fuzz passed; else layer fuzz failed; fi
    unset fuzz_work
fi
unset fuzz_secs fuzz_ok fuzz_targets
