# Sourced by .ci/run. Kani harnesses (`cargo kani -p ecdc-proofs`). Kani's bundle is only
# published on GitHub releases, which this CI cannot reach, and a half-finished `cargo kani
# setup` makes every later `cargo kani` fail at once. So: look for an installed driver first
# (without running cargo-kani, which would try to set itself up), and only then run it.
# Here it reports "skipped", never "passed"; users run .github/workflows/kani.yml.
# Count harness attributes (`#[kani::proof]` or `#[cfg_attr(kani, kani::proof)]` at the start of
# a line), not every mention of the word in comments.
kani_harnesses=$(grep -rhE '^[[:space:]]*#\[(cfg_attr\(kani, *)?kani::proof\)?\]' proofs/src core/src 2>/dev/null | wc -l)
kani_driver=""
for d in "$HOME"/.kani/kani-*/bin/kani-driver "$HOME"/.kani/kani-*/bin/kani-compiler; do
    [ -x "$d" ] && kani_driver="$d" && break
done
if [ -z "$kani_driver" ] && command -v kani-compiler >/dev/null 2>&1; then
    kani_driver=$(command -v kani-compiler)
fi
if [ -z "$kani_driver" ]; then
    layer kani "skipped: Kani driver not installed ($kani_harnesses harnesses not model-checked here; bundle only on GitHub releases; see .github/workflows/kani.yml)"
elif ! command -v cargo-kani >/dev/null 2>&1 || ! cargo kani --version >/dev/null 2>&1; then
    layer kani "skipped: Kani driver at $kani_driver but \`cargo kani --version\` fails (incomplete setup)"
elif cargo kani -p ecdc-proofs; then
    layer kani passed
else
    layer kani failed
fi
unset kani_driver kani_harnesses
