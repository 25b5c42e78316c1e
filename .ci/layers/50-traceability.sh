# Sourced by .ci/run. Every REQ id in spec/ must be cited by code and by a test/proof, except
# those frozen in scripts/trace-untraced.txt (which may only shrink). Prints the table.
if python3 scripts/trace.py --self-test && python3 scripts/trace.py --check; then
    layer traceability passed
else
    layer traceability failed
fi
