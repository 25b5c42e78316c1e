#!/usr/bin/env bash
# Fails if any source, doc, manifest or script in the repository cites a document that is not in
# the repository (the research notes the background pages replace) or an absolute machine path.
# Facts the code relies on belong in docs/background/*.md or spec/req/*.md, cited from there.
#
# Usage: scripts/check-citations.sh [repo-root]   (default: the repository holding this script)
# Exit status: 0 clean, 1 offending lines found (printed as path:line:text), 2 usage error.
set -euo pipefail

root="${1:-$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)}"
if [[ ! -d "$root" ]]; then
    echo "check-citations: no such directory: $root" >&2
    exit 2
fi
cd "$root"

# The bracketed slashes keep this file from matching its own pattern.
pattern='shared[/]|esc-dc\.md|masters\.md|servo\.md|wire-and-runtime\.md|style\.md|[/]work[/]|[/]root[/]'
# The repository's own requirement file spec/req/servo.md (also cited as req/servo.md) is allowed.
self_ref='req/servo.md'

hits="$(grep -rnE "$pattern" \
    --include='*.rs' --include='*.md' --include='*.toml' --include='*.sh' --include='*.py' \
    --exclude-dir=target --exclude-dir=.git . || true)"

bad=0
while IFS= read -r hit; do
    [[ -z "$hit" ]] && continue
    file="${hit%%:*}"
    rest="${hit#*:}"
    text="${rest#*:}"
    # Drop the allowed self-references (a literal glob pattern here), then look again: a line
    # citing both still fails.
    stripped="${text//"$self_ref"/}"
    if [[ "$stripped" =~ $pattern ]]; then
        printf '%s\n' "${file#./}:${rest}"
        bad=1
    fi
done <<< "$hits"

if [[ "$bad" -ne 0 ]]; then
    echo "check-citations: cite docs/background/*.md, a REQ id or the original source instead" >&2
    exit 1
fi
echo "check-citations: clean"
