"""Smoke checks of benchmarks/*.py, which CI does not run: a library change that renames or
removes what a benchmark uses should fail here, not months later when someone reruns the
README's command.

Three checks, ~10-15 s in all:
- every script answers --help (its parser builds; its module-level imports resolve), all in
  one child process;
- every project name a script imports, at module level or inside a function (most import
  lazily, after parsing their arguments, so --help alone misses those), and those of the
  code strings it runs in a child process, exists: one child process imports them all;
- one real run, the cheapest: bench_hbm.py's speed/error table for one (N_h, N_t) cell on
  the stand-in ROM of tests/support.py.
"""
from __future__ import annotations

import ast
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BENCH = ROOT / "benchmarks"
SCRIPTS = sorted(BENCH.glob("*.py"))
#: Folders the scripts put on sys.path (ROOT, tests, tests/fem, benchmarks): an import whose
#: top-level module lives in one of them is the project's.
SEARCH = (ROOT, ROOT / "tests", ROOT / "tests" / "fem", BENCH)


def _env() -> dict:
    return dict(os.environ, PYTHONPATH=str(ROOT), OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", MPLBACKEND="Agg")


def _run(args: list[str], timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, *args], capture_output=True, text=True, cwd=ROOT, env=_env(),
                          timeout=timeout)


def test_scripts_found():
    assert len(SCRIPTS) >= 20, [p.name for p in SCRIPTS]


HELP = r"""
import contextlib, io, json, runpy, sys
results = {}
for script in json.loads(sys.argv[1]):
    out = io.StringIO()
    sys.argv = [script, "--help"]
    code, error = None, ""
    try:
        with contextlib.redirect_stdout(out):
            runpy.run_path(script, run_name="__main__")
    except SystemExit as exc:
        code = exc.code or 0
    except BaseException as exc:
        import traceback
        code, error = 1, "".join(traceback.format_exception(exc))[-3000:]
    results[script] = (code, "usage:" in out.getvalue(), error)
sys.stdout = sys.__stdout__
print(json.dumps(results))
"""


def test_help():
    """Every script's --help, all in one process (a process each costs ~0.5 s of start-up
    and numpy import): exit 0 with a usage line."""
    r = subprocess.run([sys.executable, "-c", HELP, json.dumps([str(p) for p in SCRIPTS])], capture_output=True,
                       text=True, cwd=ROOT, env=_env(), timeout=120)
    assert r.returncode == 0, r.stderr[-3000:]
    results = json.loads(r.stdout.strip().splitlines()[-1])
    bad = {Path(k).name: v for k, v in results.items() if v[0] != 0 or not v[1]}
    assert not bad, "\n".join(f"{k}: exit {c}, usage printed: {u}\n{e}" for k, (c, u, e) in bad.items())


def _is_project(module: str) -> bool:
    top = module.split(".")[0]
    return any((d / top).is_dir() or (d / f"{top}.py").is_file() for d in SEARCH)


def _import_nodes(tree: ast.AST, lineno: int = 0):
    """(line, module, names) of every import in tree; names None for `import module`."""
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and not node.level:
            yield lineno or node.lineno, node.module, [a.name for a in node.names if a.name != "*"]
        elif isinstance(node, ast.Import):
            for a in node.names:
                yield lineno or node.lineno, a.name, None
        elif isinstance(node, ast.Constant) and isinstance(node.value, str) and "import " in node.value:
            # code run in a child process (bench_mesh.py's CHILD): its import lines, where they parse
            for line in node.value.splitlines():
                line = line.strip()
                if line.startswith(("from ", "import ")):
                    try:
                        sub = ast.parse(line)
                    except SyntaxError:  # prose in a docstring
                        continue
                    yield from _import_nodes(sub, node.lineno)


def _imports() -> list[tuple[str, int, str, list[str] | None]]:
    out = []
    for script in SCRIPTS:
        tree = ast.parse(script.read_text(), filename=str(script))
        out += [(script.name, line, module, names) for line, module, names in _import_nodes(tree)]
    return out


CHECK = r"""
import importlib, importlib.util, json, sys
sys.path[:0] = json.loads(sys.argv[1])
missing = []
for script, line, module, names, project in json.loads(sys.stdin.read()):
    where = f"{script}:{line}"
    if not project:  # a third-party or standard module: installed?
        if importlib.util.find_spec(module.split(".")[0]) is None:
            missing.append(f"{where}: module {module} is not installed")
        continue
    try:
        mod = importlib.import_module(module)
    except Exception as exc:
        missing.append(f"{where}: import {module} failed: {type(exc).__name__}: {exc}")
        continue
    for name in names or ():
        if hasattr(mod, name):
            continue
        try:
            importlib.import_module(f"{module}.{name}")
        except ImportError:
            missing.append(f"{where}: {module} has no {name}")
print(json.dumps(missing))
"""


def test_imported_names_exist():
    found = _imports()
    assert any(m.startswith("hbm.") for _, _, m, _ in found)  # the walk sees the lazy imports
    payload = json.dumps([(s, line, m, names, _is_project(m)) for s, line, m, names in found])
    r = subprocess.run([sys.executable, "-c", CHECK, json.dumps([str(d) for d in SEARCH])], input=payload,
                       capture_output=True, text=True, cwd=ROOT, env=_env(), timeout=120)
    assert r.returncode == 0, r.stderr[-3000:]
    missing = json.loads(r.stdout.strip().splitlines()[-1])
    assert not missing, "benchmark imports that no longer resolve:\n" + "\n".join(missing)


def test_bench_hbm_table_runs():
    r = _run([str(BENCH / "bench_hbm.py"), "--no-default", "--table", "--nh", "10", "--nt", "256",
              "--methods", "dlft"])
    assert r.returncode == 0, r.stderr[-3000:]
    assert "ROM: stand-in" in r.stdout
    assert "| 10 | " in r.stdout, r.stdout[-2000:]  # the table's one cell
