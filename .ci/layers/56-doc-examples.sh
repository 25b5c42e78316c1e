# Sourced by .ci/run. Every public item of ecdc-core has a code example in its docs, for the
# default and for all features (scripts/check-doc-examples.sh prints the items without one).
# The examples run as doc tests in the tests layer.
if bash scripts/check-doc-examples.sh; then layer doc-examples passed; else layer doc-examples failed; fi
