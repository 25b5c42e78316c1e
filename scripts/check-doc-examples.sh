#!/usr/bin/env bash
# Fails if a public item of ecdc-core has no code example in its documentation. The check is
# rustdoc's `missing-doc-code-examples` lint, which only nightly has (behind a feature gate),
# run for the default features and for all features (servo::ptp, servo::refclock and the
# `verification` items are public only with theirs). The examples themselves are doc tests:
# `cargo test --workspace` compiles and runs them.
#
# Usage: scripts/check-doc-examples.sh [repo-root]   (default: the repository holding this script)
# Exit status: 0 every item has an example, 1 items without one (printed as path:line), 2 the
# check itself could not run (no nightly, rustdoc failed, the lint is unknown).
set -uo pipefail

root="${1:-$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)}"
cd "$root" || { echo "check-doc-examples: no such directory: $root" >&2; exit 2; }
if ! cargo +nightly --version >/dev/null 2>&1; then
    echo "check-doc-examples: the nightly toolchain is missing (see .ci/install.sh)" >&2
    exit 2
fi

# A fresh target directory: cargo does not re-run rustdoc on an unchanged crate, and a cached
# run prints no warnings, which would pass vacuously.
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT

status=0
for features in "" "--all-features"; do
    name="${features:-default features}"
    log="$tmp/rustdoc.log"
    # shellcheck disable=SC2086 # $features is empty or one flag
    RUSTDOCFLAGS="" cargo +nightly rustdoc -p ecdc-core $features --target-dir "$tmp/target" -- \
        -Z unstable-options -Zcrate-attr='feature(rustdoc_missing_doc_code_examples)' \
        -W rustdoc::missing-doc-code-examples >"$log" 2>&1
    rc=$?
    if grep -q 'unknown lint' "$log"; then
        cat "$log" >&2
        echo "check-doc-examples: rustdoc no longer knows the lint ($name)" >&2
        exit 2
    fi
    if [ "$rc" -ne 0 ]; then
        cat "$log" >&2
        echo "check-doc-examples: rustdoc failed ($name)" >&2
        exit 2
    fi
    missing="$(grep -A1 'missing code example' "$log" | sed -n 's/^ *--> //p')"
    count="$(printf '%s' "$missing" | grep -c . || true)"
    echo "check-doc-examples: $name: $count public items without a code example"
    if [ "$count" -gt 0 ]; then
        printf '%s\n' "$missing"
        status=1
    fi
done
exit "$status"
