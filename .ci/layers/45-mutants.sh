# Sourced by .ci/run. Mutation testing of the lines a change touches (issue #17, deliverable 4):
# `cargo mutants --in-diff` over core/src, with .cargo/mutants.toml (profile `mutants`: release
# with debug assertions and overflow checks; tests of ecdc-core, ecdc-spec and ecdc-proofs,
# `--lib --tests`). The full-crate measurement is benches/results/mutants.md.
#
# Which diff. CI runs on a fresh clone of main: there is no upstream branch and no record of the
# last commit whose CI passed, so the base is MUTANTS_BASE if set (e.g. the last green commit,
# for a push of several commits), else HEAD~1: the layer checks the newest commit, which is
# what one CI run per pushed commit needs. `git diff BASE -- core/src` (BASE against the work
# tree, so a local run also sees uncommitted edits). A change to test code only has no mutants.
#
# Bounded: at most MUTANTS_MAX (8) mutants are tested, one at a time (--jobs 1), with a
# per-mutant test timeout; a larger diff is sampled (--shard 1/k, round-robin over the listed
# mutants) and the status says so. The tests layer has already run the same tests on the
# unmutated tree, so the baseline run is skipped (--baseline skip).
#
# Fails on a missed mutant (cargo-mutants exit 2) or if cargo-mutants cannot run; a mutant that
# only times out (exit 3: the mutation made a test loop) is reported, not failed.
mut_base="${MUTANTS_BASE:-HEAD~1}"
mut_max="${MUTANTS_MAX:-8}"
if ! cargo mutants --version >/dev/null 2>&1; then
    layer mutants "failed: cargo-mutants missing (see .ci/install.sh)"
elif ! git rev-parse --verify -q "$mut_base^{commit}" >/dev/null; then
    layer mutants "skipped: base $mut_base is not a commit here (shallow clone?); set MUTANTS_BASE"
else
    mut_work=$(mktemp -d)
    git diff "$mut_base" -- core/src >"$mut_work/core.diff"
    if [ ! -s "$mut_work/core.diff" ]; then
        layer mutants "skipped: no core/src change since $mut_base"
    else
        # Listing errors (bad diff, config) fail the layer; zero mutants is a clean skip.
        if ! cargo mutants --list --in-diff "$mut_work/core.diff" >"$mut_work/list.txt"; then
            layer mutants "failed: cargo mutants --list --in-diff did not run"
        else
            mut_n=$(grep -c . "$mut_work/list.txt" || true)
            echo "mutants in the diff since $mut_base: $mut_n"
            cat "$mut_work/list.txt"
            if [ "$mut_n" = 0 ]; then
                layer mutants "skipped: the core/src diff since $mut_base has no mutable code"
            else
                mut_shards=$(((mut_n + mut_max - 1) / mut_max))
                mut_args=(--in-diff "$mut_work/core.diff" --jobs 1 --timeout 180 --build-timeout 600
                    --baseline skip --output "$mut_work")
                mut_note=""
                if [ "$mut_shards" -gt 1 ]; then
                    mut_args+=(--shard "1/$mut_shards" --sharding round-robin)
                    mut_note=" (sampled: shard 1/$mut_shards of $mut_n mutants)"
                fi
                mut_t0=$(date +%s)
                cargo mutants "${mut_args[@]}" -- -j 1
                mut_rc=$?
                mut_secs=$(($(date +%s) - mut_t0))
                for k in caught missed timeout unviable; do
                    printf '%-9s %s\n' "$k" "$(grep -c . "$mut_work/mutants.out/$k.txt" 2>/dev/null || echo 0)"
                done
                case "$mut_rc" in
                    0) layer mutants "passed: no missed mutant, ${mut_secs}s$mut_note" ;;
                    3) layer mutants "passed: no missed mutant, some timed out, ${mut_secs}s$mut_note" ;;
                    2)
                        echo "missed mutants (add a test that kills each, or justify it in benches/results/mutants.md):"
                        cat "$mut_work/mutants.out/missed.txt"
                        layer mutants "failed: missed mutants in the core/src diff$mut_note"
                        ;;
                    *) layer mutants "failed: cargo mutants exited $mut_rc" ;;
                esac
                unset mut_shards mut_args mut_note mut_t0 mut_rc mut_secs
            fi
            unset mut_n
        fi
    fi
    rm -rf "$mut_work"
    unset mut_work
fi
unset mut_base mut_max
