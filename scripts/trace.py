#!/usr/bin/env python3
"""Requirement traceability: every REQ-<AREA>-<NNN> defined in spec/SPEC.md and spec/req/*.md
must be cited by code and by at least one test or proof; every property P1..P6 of SPEC.md §2
must be cited in proofs/ and listed in docs/verification.md.

  scripts/trace.py            print the table
  scripts/trace.py --check    also gate: fail if an id is untraced and not in the committed
                              snapshot scripts/trace-untraced.txt (the snapshot may only shrink;
                              each line is `ID  # reason`, a line without a reason fails)
  scripts/trace.py --self-test  run the checker on a small made-up tree (negative controls)
  scripts/trace.py --update   rewrite the snapshot to the current untraced ids (and ids
                              cited but not defined, which the gate also freezes)

A "definition" is a requirement id in bold (`**REQ-DC-004 ...**`) or in the first cell of a
table row. A "code" citation is an occurrence in non-test Rust code of core/, spec/ or
harness/ (`src/**.rs` before the first `#[cfg(test)]`), an `// implements: REQ-...` line being
the explicit form. A "test" citation is only an explicit marker line in test code (a test
module, a `tests/` directory, proofs/, fuzz/ or benches/):

    // verifies: REQ-DC-014, REQ-WIRE-020..022

A test that merely mentions an id in prose does not trace it. Ranges `REQ-X-NNN..MMM` (and
`REQ-X-NNN..REQ-X-MMM`) are expanded in markers and in code citations alike. Properties
P1..P6 are traced by a `verifies: P6` marker in proofs/.
"""
import pathlib
import re
import sys

ROOT = pathlib.Path(__file__).resolve().parent.parent
SNAPSHOT = ROOT / "scripts" / "trace-untraced.txt"


def set_root(root):
    global ROOT, SNAPSHOT
    ROOT = pathlib.Path(root)
    SNAPSHOT = ROOT / "scripts" / "trace-untraced.txt"
REQ = re.compile(r"REQ-[A-Z]+-\d{3}")
# An id or a range of ids: REQ-DC-014..017 or REQ-DC-014..REQ-DC-017.
REQ_OR_RANGE = re.compile(r"REQ-([A-Z]+)-(\d{3})(?:\s*\.\.\s*(?:REQ-\1-)?(\d{3}))?")
MARKER = re.compile(r"^\s*(?://+!?|/?\*+|#)\s*verifies:\s*(.*)$", re.M)
PROP_ID = re.compile(r"\bP\d\b")
# A range wider than this is a typo, not a citation.
MAX_RANGE = 40


DEFINED = None


def expand(text):
    """Every REQ id in `text`, with ranges expanded: both ends always, the ids between them
    when spec/ defines them (numbering has gaps, and a range means the ids it spans)."""
    out = set()
    for m in REQ_OR_RANGE.finditer(text):
        area, lo, hi = m.group(1), int(m.group(2)), m.group(3)
        hi = int(hi) if hi else lo
        if hi < lo or hi - lo > MAX_RANGE:
            hi = lo
        ids = [f"REQ-{area}-{n:03d}" for n in range(lo, hi + 1)]
        ends = {ids[0], ids[-1]}
        out.update(r for r in ids if r in ends or DEFINED is None or r in DEFINED)
    return out


def markers(text):
    """The ids and properties named on explicit `verifies:` lines of `text`."""
    out = set()
    for m in MARKER.finditer(text):
        out |= expand(m.group(1)) | set(PROP_ID.findall(m.group(1)))
    return out
DEF = re.compile(r"(?:\*\*|^\|\s*)(REQ-[A-Z]+-\d{3})", re.M)
PROP = re.compile(r"^\|\s*(P\d+)\s*\|", re.M)
CODE_CRATES = ["core", "spec", "harness"]
TEST_DIRS = ["proofs", "fuzz", "benches"]


def definitions():
    files = [ROOT / "spec" / "SPEC.md"] + sorted((ROOT / "spec" / "req").glob("*.md"))
    defs = {}
    for f in files:
        if not f.exists():
            continue
        for m in DEF.finditer(f.read_text(encoding="utf-8")):
            defs.setdefault(m.group(1), f.relative_to(ROOT).as_posix())
    return defs


def rust_files(base):
    if not base.exists():
        return []
    return [p for p in base.rglob("*.rs") if "target" not in p.relative_to(ROOT).parts]


def citations():
    code, test = {}, {}

    def add(table, text, where):
        ids = markers(text) if table is test else expand(text) | set(PROP_ID.findall(text))
        for rid in ids:
            table.setdefault(rid, set()).add(where)

    for crate in CODE_CRATES:
        for f in rust_files(ROOT / crate):
            rel = f.relative_to(ROOT).as_posix()
            text = f.read_text(encoding="utf-8", errors="replace")
            # A `tests.rs` module file is declared under `#[cfg(test)]` by its parent.
            if "/tests/" in "/" + rel or "/benches/" in "/" + rel or rel.endswith("/tests.rs"):
                add(test, text, rel)
                continue
            cut = text.find("#[cfg(test)]")
            add(code, text if cut < 0 else text[:cut], rel)
            if cut >= 0:
                add(test, text[cut:], rel)
    for d in TEST_DIRS:
        for f in rust_files(ROOT / d):
            add(test, f.read_text(encoding="utf-8", errors="replace"), f.relative_to(ROOT).as_posix())
    return code, test


def properties():
    spec = ROOT / "spec" / "SPEC.md"
    return PROP.findall(spec.read_text(encoding="utf-8")) if spec.exists() else []


def self_test():
    """The gate must fail on a new untraced id and on a dangling citation, and pass otherwise."""
    import contextlib
    import io
    import tempfile

    def tree(files):
        d = tempfile.mkdtemp()
        for rel, text in files.items():
            f = pathlib.Path(d) / rel
            f.parent.mkdir(parents=True, exist_ok=True)
            f.write_text(text, encoding="utf-8")
        return d

    spec = "| id | p |\n|---|---|\n| P1 | x |\n"
    req = "- **REQ-AB-001 A.** a\n- **REQ-AB-002 B.** b\n"
    doc = "| P1 | row |\n"
    good = {
        "spec/SPEC.md": spec,
        "spec/req/ab.md": req,
        "docs/verification.md": doc,
        "core/src/a.rs": "// REQ-AB-001 REQ-AB-002\n#[cfg(test)]\n    // verifies: REQ-AB-001\n",
        "proofs/src/p.rs": "// verifies: P1, REQ-AB-002\n",
    }
    ranged = {
        **good,
        "spec/req/ab.md": req + "- **REQ-AB-003 C.** c\n",
        "core/src/a.rs": "// implements: REQ-AB-001..003\n#[cfg(test)]\n",
        "proofs/src/p.rs": "// verifies: P1, REQ-AB-001..REQ-AB-003\n",
    }
    cases = [
        ("all traced", good, 0),
        ("ranges expanded", ranged, 0),
        ("range end missing", {**ranged, "proofs/src/p.rs": "// verifies: P1, REQ-AB-001..002\n"}, 1),
        ("test missing", {**good, "proofs/src/p.rs": "// verifies: P1\n"}, 1),
        ("mention is no marker", {**good, "proofs/src/p.rs": "// verifies: P1\n// REQ-AB-002\n"}, 1),
        ("property mention is no marker", {**good, "proofs/src/p.rs": "// P1\n// verifies: REQ-AB-002\n"}, 1),
        ("code missing", {**good, "core/src/a.rs": "#[cfg(test)]\n// REQ-AB-001 REQ-AB-002\n"}, 1),
        ("dangling citation", {**good, "proofs/src/q.rs": "// verifies: REQ-AB-009\n"}, 1),
        ("property not in docs", {**good, "docs/verification.md": ""}, 1),
        ("frozen in snapshot", {**good, "proofs/src/p.rs": "// verifies: P1\n", "scripts/trace-untraced.txt": "REQ-AB-002  # not testable here\n"}, 0),
        ("frozen without a reason", {**good, "proofs/src/p.rs": "// verifies: P1\n", "scripts/trace-untraced.txt": "REQ-AB-002\n"}, 1),
    ]
    ok = True
    for name, files, want in cases:
        set_root(tree(files))
        sys.argv = ["trace.py", "--check"]
        with contextlib.redirect_stdout(io.StringIO()):
            got = main()
        print(f"self-test {name}: exit {got} (want {want})")
        ok &= got == want
    return 0 if ok else 1


def main():
    args = set(sys.argv[1:])
    if "--self-test" in args:
        return self_test()
    global DEFINED
    defs = definitions()
    DEFINED = set(defs)
    code, test = citations()
    matrix = (ROOT / "docs" / "verification.md")
    matrix_text = matrix.read_text(encoding="utf-8") if matrix.exists() else ""
    rows, untraced = [], []
    for rid in sorted(defs, key=lambda r: (r.split("-")[1], r)):
        c, t = len(code.get(rid, ())), len(test.get(rid, ()))
        missing = [w for w, n in (("code", c), ("test", t)) if n == 0]
        rows.append((rid, c, t, "ok" if not missing else "MISSING " + "+".join(missing)))
        if missing:
            untraced.append(rid)
    for pid in properties():
        t = len([w for w in test.get(pid, ()) if w.startswith("proofs/")])
        in_doc = re.search(rf"^\|\s*{pid}\b", matrix_text, re.M) is not None
        missing = ([] if t else ["proof"]) + ([] if in_doc else ["docs/verification.md"])
        rows.append((pid, "-", t, "ok" if not missing else "MISSING " + "+".join(missing)))
        if missing:
            untraced.append(pid)
    cited_undefined = sorted((set(code) | set(test)) - set(defs) - set(properties()))
    cited_undefined = [r for r in cited_undefined if r.startswith("REQ-")]

    print(f"{'id':<14} {'code':>5} {'tests':>5}  status")
    for rid, c, t, st in rows:
        print(f"{rid:<14} {c!s:>5} {t!s:>5}  {st}")
    traced = len(rows) - len(untraced)
    print(f"\n{traced}/{len(rows)} traced; {len(untraced)} untraced")
    if cited_undefined:
        print("cited but not defined in spec/: " + ", ".join(cited_undefined))

    if "--update" in args:
        reasons = {}
        if SNAPSHOT.exists():
            for l in SNAPSHOT.read_text(encoding="utf-8").splitlines():
                rid, _, why = l.partition("#")
                if rid.strip():
                    reasons[rid.strip()] = why.strip()
        frozen = sorted(set(untraced) | set(cited_undefined))
        SNAPSHOT.write_text(
            "".join(f"{r}  # {reasons.get(r) or 'TODO: reason'}\n" for r in frozen), encoding="utf-8"
        )
        print(f"wrote {SNAPSHOT.relative_to(ROOT)} ({len(frozen)} ids)")
        return 0
    if "--check" in args:
        allowed = set()
        if SNAPSHOT.exists():
            allowed = set()
            for l in SNAPSHOT.read_text(encoding="utf-8").splitlines():
                rid, _, why = l.partition("#")
                rid = rid.strip()
                if not rid:
                    continue
                if not why.strip():
                    print(f"FAIL: {rid} is frozen in the snapshot without a reason (`ID  # why`)")
                    return 1
                allowed.add(rid)
        new = sorted(set(untraced) - allowed)
        shrunk = sorted(allowed - set(untraced) - set(cited_undefined))
        if shrunk:
            print("now traced or gone (remove from the snapshot with --update): " + ", ".join(shrunk))
        dangling = sorted(set(cited_undefined) - allowed)
        if dangling:
            print("FAIL: cited in code/tests but defined nowhere in spec/: " + ", ".join(dangling))
            return 1
        if new:
            print("FAIL: untraced ids not in the snapshot: " + ", ".join(new))
            return 1
        print("traceability gate: ok")
    return 0


if __name__ == "__main__":
    sys.exit(main())
