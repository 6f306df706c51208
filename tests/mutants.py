"""Mutation check: do the tests fail where the code is wrong?

Each entry of tests/mutants.json names a file, an exact piece of its text, what to put in
its place (a plausible bug: a sign, a tolerance, a dropped term), and the tests that cover
it. For each, this script writes the mutated file into a copy of the working tree, runs
those tests there (pytest -x -n 2) and says whether they failed (the mutant is killed) or
passed (it survives). The working tree itself is never modified. An entry whose text no
longer occurs exactly once in its file is reported as stale (the code moved on: update it).
An entry may carry "survives": the reason its mutant is expected to pass (an equivalent
change, a tuning no test should pin); any other survivor is a test that cannot fail.

    .venv/bin/python tests/mutants.py               # every entry
    .venv/bin/python tests/mutants.py ID [ID ...]   # those entries
    .venv/bin/python tests/mutants.py --all-tests ID  # against the whole suite instead

Exit status 0 when every entry is killed or survives as expected, 1 otherwise. 1 to 120 s
an entry on a 2-core host (the kernels compile once in the copy), about an hour in all.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MUTANTS = Path(__file__).with_name("mutants.json")


def _copy_tree(dest: Path) -> Path:
    """The working tree's files (tracked, and untracked ones git does not ignore) under
    dest / "main", with dest / "shared" pointing at the data folder beside the repository
    (tests/support.py finds it there)."""
    files = subprocess.run(["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"], cwd=ROOT,
                           check=True, capture_output=True).stdout.decode().split("\0")
    main = dest / "main"
    for f in filter(None, files):
        src = ROOT / f
        if src.is_file():
            (main / f).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, main / f)
    shared = ROOT.parent / "shared"
    if shared.exists():
        (dest / "shared").symlink_to(shared.resolve())
    return main


def _run(entry: dict, main: Path, all_tests: bool) -> tuple[str, str]:
    path = main / entry["file"]
    src = path.read_text()
    n = src.count(entry["old"])
    if n != 1:
        return "stale", f"its text occurs {n} times in {entry['file']}"
    path.write_text(src.replace(entry["old"], entry["new"]))
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(main), os.environ.get("PYTHONPATH")])))
    try:
        r = subprocess.run([sys.executable, "-m", "pytest", "-q", "-x", "-n", "2", "-p", "no:cacheprovider", "-rf",
                            *(["tests"] if all_tests else entry["tests"])], cwd=main, env=env,
                           capture_output=True, text=True)
    finally:
        path.write_text(src)
    lines = r.stdout.strip().splitlines()
    failed = [ln.split(" - ")[0].split("FAILED ", 1)[1] for ln in lines if "FAILED " in ln]
    if r.returncode == 0:
        return "survived", lines[-1] if lines else ""
    # tests failed: exit 1, or 2 when -x stops the xdist workers (a collection error exits 2
    # too, without a failed test)
    if r.returncode in (1, 2) and failed:
        return "killed", "; ".join(failed[:2])
    return "error", (lines[-1] if lines else r.stderr.strip()[-300:])  # interrupted, internal error, no tests


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("ids", nargs="*", help="entries to run (default: all)")
    ap.add_argument("--all-tests", action="store_true", help="run the whole suite for each entry")
    args = ap.parse_args(argv)
    entries = json.loads(MUTANTS.read_text())
    unknown = set(args.ids) - {e["id"] for e in entries}
    if unknown:
        ap.error(f"no such entries: {', '.join(sorted(unknown))}")
    chosen = [e for e in entries if not args.ids or e["id"] in args.ids]
    bad = 0
    with tempfile.TemporaryDirectory(prefix="bladerub-mutants-") as tmp:
        tree = _copy_tree(Path(tmp))
        for e in chosen:
            t0 = time.perf_counter()
            verdict, detail = _run(e, tree, args.all_tests)
            expected = verdict == "killed" or (verdict == "survived" and "survives" in e)
            bad += not expected
            why = f" (expected: {e['survives']})" if verdict == "survived" and "survives" in e else ""
            print(f"{verdict.upper():8} {e['id']:24} {time.perf_counter() - t0:5.0f} s  {e['what']}{why}  [{detail}]",
                  flush=True)
    print(f"{len(chosen) - bad} of {len(chosen)} as expected")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
