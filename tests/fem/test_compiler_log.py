"""The fem stage's first run on a machine prints no compiler command lines.

ffcx compiles the elements and forms with cffi on a first run, and setuptools' build logs
each compiler call at INFO through the root logger (fem.assembly._quiet_compiler_log). The
check runs in a fresh process with an empty JIT cache, so that the compile does happen.
"""
import os
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]

SCRIPT = """
import logging, sys
sys.path[:0] = [{root!r}, {here!r}]
from box_mesh import box_mesh
from fem.assembly import assemble_system
from fem.material import Material
box = box_mesh(0.1, 0.03, 0.01, 0.01)
system = assemble_system(box.nodes, box.cells, box.root_facets, Material())
logging.getLogger("bladerub.test").warning("a warning after the compile")
print("root filters", len(logging.getLogger().filters))
"""


def test_first_compile_prints_no_build_log(tmp_path):
    env = dict(os.environ, XDG_CACHE_HOME=str(tmp_path), XDG_CONFIG_HOME=str(tmp_path / "config"))
    run = subprocess.run([sys.executable, "-c", SCRIPT.format(root=str(ROOT), here=str(HERE))],
                         capture_output=True, text=True, env=env, cwd=tmp_path, timeout=600)
    assert run.returncode == 0, run.stderr
    compiled = list((tmp_path / "fenics").glob("*.so"))
    assert len(compiled) >= 2, "the JIT cache was not empty: nothing was compiled"
    out = run.stdout + run.stderr
    assert "build_ext" not in out and "gcc" not in out, out
    # warnings still print, and nothing is left on the root logger after the compile
    assert "a warning after the compile" in run.stderr
    assert "root filters 0" in run.stdout, run.stdout
