# Sourced by .ci/run. The repo explains itself: no file cites research notes that are not in it
# or a machine path (scripts/check-citations.sh prints the offending lines).
if bash scripts/check-citations.sh; then layer citations passed; else layer citations failed; fi
