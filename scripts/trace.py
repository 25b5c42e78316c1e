#!/usr/bin/env python3
"""Requirement traceability: every REQ-<AREA>-<NNN> defined in spec/SPEC.md and spec/req/*.md
must be cited by code and by at least one test or proof; every property P1..P6 of SPEC.md §2
must be cited in proofs/ and listed in docs/verification.md.

  scripts/trace.py            print the table
  scripts/trace.py --check    also gate: fail if an id is untraced and not in the committed
                              snapshot scripts/trace-untraced.txt (the snapshot may only shrink)
  scripts/trace.py --update   rewrite the snapshot to the current untraced ids (and ids
                              cited but not defined, which the gate also freezes)

A "definition" is a requirement id in bold (`**REQ-DC-004 ...**`) or in the first cell of a
table row. A "code" citation is an occurrence in non-test Rust code of core/, spec/ or
harness/ (`src/**.rs` before the first `#[cfg(test)]`). A "test" citation is an occurrence in
a test module, a `tests/` directory, proofs/, fuzz/ or benches/.
"""
import pathlib
import re
import sys

ROOT = pathlib.Path(__file__).resolve().parent.parent
SNAPSHOT = ROOT / "scripts" / "trace-untraced.txt"
REQ = re.compile(r"REQ-[A-Z]+-\d{3}")
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
        for rid in set(REQ.findall(text)) | set(re.findall(r"\bP\d\b", text)):
            table.setdefault(rid, set()).add(where)

    for crate in CODE_CRATES:
        for f in rust_files(ROOT / crate):
            rel = f.relative_to(ROOT).as_posix()
            text = f.read_text(encoding="utf-8", errors="replace")
            if "/tests/" in "/" + rel or "/benches/" in "/" + rel:
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


def main():
    args = set(sys.argv[1:])
    defs = definitions()
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
        frozen = sorted(set(untraced) | set(cited_undefined))
        SNAPSHOT.write_text("".join(f"{r}\n" for r in frozen), encoding="utf-8")
        print(f"wrote {SNAPSHOT.relative_to(ROOT)} ({len(frozen)} ids)")
        return 0
    if "--check" in args:
        allowed = set()
        if SNAPSHOT.exists():
            allowed = {l.strip() for l in SNAPSHOT.read_text(encoding="utf-8").splitlines() if l.strip() and not l.startswith("#")}
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
