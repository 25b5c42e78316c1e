#!/usr/bin/env python3
"""Summarise cargo-mutants runs (benches/results/mutants.md, issue #17 deliverable 4).

usage: scripts/mutants-summary.py [--tsv] [--killed KILLED.tsv] SOURCE... > table

Each SOURCE is a cargo-mutants `--output` directory (the one holding mutants.out/) or a TSV
written by `--tsv` (earlier results). KILLED lists mutants a run missed and a test added
since kills, verified by applying the mutation by hand and running core's tests (columns:
mutant name as the run printed it, the test); they count as `killed` (caught since), a column
of its own, and the TSV keeps the run's own outcome. A second column starting `gone:` says
why the mutant no longer exists (the code was rewritten); such mutants are not counted. A mutant named in several sources takes its outcome from
the last one, so `mutants.tsv NEW_DIR` updates the committed results with a re-run; a run
directory also replaces earlier rows of the same file and mutation text at other line numbers
(a re-run at a later commit, where lines moved).
Prints, as Markdown: per file caught / missed / timeout / unviable and the score
caught / (caught + missed + timeout); per area (dc/, wire/, servo/, num+time) the same; then
every missed or timed-out mutant. `--tsv` prints one row per mutant instead (file, line,
outcome, mutant name), the raw outcomes committed next to the table.
"""
import json
import sys
from collections import Counter, defaultdict
from pathlib import Path

KINDS = {"CaughtMutant": "caught", "MissedMutant": "missed", "Timeout": "timeout",
         "Unviable": "unviable"}


def area(path):
    for a in ("dc", "wire", "servo"):
        if path.startswith(f"core/src/{a}/"):
            return f"{a}/"
    return "num+time"


def load(sources):
    by_name = {}
    for src in sources:
        if src.endswith(".tsv"):
            for line in Path(src).read_text().splitlines()[1:]:
                f, ln, k, name = line.split("\t")
                by_name[name] = (f, int(ln), k, name)
            continue
        data = json.loads((Path(src) / "mutants.out" / "outcomes.json").read_text())
        new = {}
        for o in data["outcomes"]:
            m = o["scenario"]
            if not isinstance(m, dict) or "Mutant" not in m:
                continue  # the baseline
            m = m["Mutant"]
            new[m["name"]] = (m["file"], m["span"]["start"]["line"],
                              KINDS.get(o["summary"], o["summary"]), m["name"])
        # A run at a later commit supersedes every earlier row with the same file and mutation
        # text (the name without its line:col, which moves when lines above are added): re-runs
        # select mutants by function, so they hold all of a function's mutants of that text.
        redone = {(f, text(name)) for f, _, _, name in new.values()}
        by_name = {k: v for k, v in by_name.items() if (v[0], text(k)) not in redone}
        by_name.update(new)
    return sorted(by_name.values())


def text(name):
    """A mutant's name without its position: `file:line:col: what` -> `what`."""
    return name.split(": ", 1)[-1]


def score(c):
    """(caught + killed since) / viable, as a fraction and a percentage."""
    caught = c["caught"] + c["killed"]
    viable = caught + c["missed"] + c["timeout"]
    return f"{caught}/{viable} = {100 * caught / viable:.0f} %" if viable else "-"


def killed(path):
    """KILLED file: mutant name -> `killed`, or `gone` when the second column starts with
    `gone:` (the code was rewritten so that the mutant no longer exists; not counted)."""
    if path is None:
        return {}
    out = {}
    for line in Path(path).read_text().splitlines():
        if line.strip() and not line.startswith("#"):
            name, why = line.split("\t", 1)
            out[name] = "gone" if why.startswith("gone:") else "killed"
    return out


def main(argv):
    tsv = "--tsv" in argv
    argv = [a for a in argv if a != "--tsv"]
    kill_file = None
    if "--killed" in argv:
        i = argv.index("--killed")
        kill_file = argv[i + 1]
        del argv[i:i + 2]
    rows = load(argv)
    if tsv:
        print("file\tline\toutcome\tmutant")
        for f, line, k, name in rows:
            print(f"{f}\t{line}\t{k}\t{name}")
        return
    dead = killed(kill_file)
    unknown = set(dead) - {name for *_, name in rows}
    if unknown:
        sys.exit(f"--killed names mutants no source has: {sorted(unknown)[:3]}")
    rows = [(f, ln, dead[name] if k in ("missed", "timeout") and name in dead else k, name)
            for f, ln, k, name in rows]
    per_file, per_area = defaultdict(Counter), defaultdict(Counter)
    for f, _, k, _ in rows:
        per_file[f][k] += 1
        per_area[area(f)][k] += 1
    head = ("| {} | caught | killed since | missed | timeout | unviable | caught / viable |\n"
            "|---|---|---|---|---|---|---|")

    def row(label, c):
        return (f"| {label} | {c['caught']} | {c['killed']} | {c['missed']} | {c['timeout']} "
                f"| {c['unviable']} | {score(c)} |")
    print(head.format("file"))
    for f in sorted(per_file):
        print(row(f"`{f}`", per_file[f]))
    print()
    print(head.format("area"))
    for a in ("dc/", "wire/", "servo/", "num+time"):
        if sum(per_area[a].values()):
            print(row(a, per_area[a]))
    print()
    for f, _, k, name in rows:
        if k in ("missed", "timeout"):
            print(f"- {k}: `{name}`")


if __name__ == "__main__":
    main(sys.argv[1:])
