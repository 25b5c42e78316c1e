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
# Bounded, in three ways. At most MUTANTS_MAX (4) mutants are tested, one at a time (--jobs 1);
# a larger diff is sampled (--shard 1/k, round-robin over the listed mutants) and the status
# says so. Each mutant's tests stop after --timeout 60 s (6 s unmutated, measured below), so
# a mutant that makes a test loop costs a minute, not three. And the whole cargo-mutants run is
# cut at MUTANTS_BUDGET (600) s of wall clock (SIGINT, then KILL 30 s later): the layer cannot
# take much more than 11 min whatever the diff or the load; mutants tested by then still count.
# Measured 2026-12-03 on the 2-core box while a mutation run kept the load average near 5,
# with profile `mutants` at opt-level 1 and incremental: the first mutant costs 73 s (70 s to
# build core, spec and proofs from scratch, 3 s of tests), each further one 9-11 s (7-8 s
# rebuild, 2-3 s of tests; 6 s for the whole unmutated suite). At opt-level 3 without
# incremental builds the same costs were 290 s and 195 s, and the budget covered 2 mutants;
# now all 4 fit with room to spare. The tests layer has already run the same tests on the
# unmutated tree, so the baseline run is skipped (--baseline skip).
#
# Fails on a missed mutant (cargo-mutants exit 2, or one listed before the budget ran out) or
# if cargo-mutants cannot run; a mutant that only times out (exit 3: the mutation made a test
# loop) is reported, not failed; reaching the budget is reported with the count tested
# (`skipped` if not one mutant finished).
mut_base="${MUTANTS_BASE:-HEAD~1}"
mut_max="${MUTANTS_MAX:-4}"
mut_budget="${MUTANTS_BUDGET:-600}"
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
                mut_args=(--in-diff "$mut_work/core.diff" --jobs 1 --timeout 60 --build-timeout 600
                    --baseline skip --output "$mut_work")
                mut_note=""
                if [ "$mut_shards" -gt 1 ]; then
                    mut_args+=(--shard "1/$mut_shards" --sharding round-robin)
                    mut_note=" (sampled: shard 1/$mut_shards of $mut_n mutants)"
                fi
                mut_t0=$(date +%s)
                # SIGINT to the whole process group (cargo-mutants, cargo, the test binaries);
                # KILL 30 s later if anything is still there. Exit 124: the budget ran out.
                timeout --signal=INT --kill-after=30 "$mut_budget" cargo mutants "${mut_args[@]}" -- -j 1
                mut_rc=$?
                mut_secs=$(($(date +%s) - mut_t0))
                mut_done=0
                for k in caught missed timeout unviable; do
                    mut_k=$(grep -c . "$mut_work/mutants.out/$k.txt" 2>/dev/null)
                    mut_done=$((mut_done + ${mut_k:-0}))
                    printf '%-9s %s\n' "$k" "${mut_k:-0}"
                done
                if [ "$mut_rc" = 124 ] || [ "$mut_rc" = 137 ]; then
                    # Out of time: a mutant already missed still fails the layer.
                    if [ -s "$mut_work/mutants.out/missed.txt" ]; then
                        mut_rc=2
                    elif [ "$mut_done" = 0 ]; then
                        mut_rc=budget0
                    else
                        mut_rc=budget
                    fi
                    mut_note="$mut_note (budget ${mut_budget}s reached after $mut_done tested)"
                fi
                case "$mut_rc" in
                    0) layer mutants "passed: no missed mutant, ${mut_secs}s$mut_note" ;;
                    3) layer mutants "passed: no missed mutant, some timed out, ${mut_secs}s$mut_note" ;;
                    budget) layer mutants "passed: no missed mutant so far, ${mut_secs}s$mut_note" ;;
                    budget0) layer mutants "skipped: budget ${mut_budget}s reached before the first mutant finished$mut_note" ;;
                    2)
                        echo "missed mutants (add a test that kills each, or justify it in benches/results/mutants.md):"
                        cat "$mut_work/mutants.out/missed.txt"
                        layer mutants "failed: missed mutants in the core/src diff$mut_note"
                        ;;
                    *) layer mutants "failed: cargo mutants exited $mut_rc" ;;
                esac
                unset mut_shards mut_args mut_note mut_t0 mut_rc mut_secs mut_done mut_k
            fi
            unset mut_n
        fi
    fi
    rm -rf "$mut_work"
    unset mut_work
fi
unset mut_base mut_max mut_budget
