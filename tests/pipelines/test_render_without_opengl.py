"""A machine without any off-screen OpenGL route (no Mesa software renderer, no EGL, no GL
with Xvfb), as a user's server can be: the mode pictures cannot be drawn, and the user must
read why and how to fix it, not a traceback.

The mode pictures are drawn in a child process (`python -m pipelines.render`); the machine is
made so for that child only, by a `sitecustomize` on its PYTHONPATH that refuses to load the
GL libraries (the route probe's own check, pipelines.render._loadable) and hides Xvfb. The
report was the child's traceback ("mode-shape rendering failed (exit 1): Traceback ...") for
`bladerub render`, and a `bladerub run` ended on it at the first figure, without drawing the
NFRC plots, which need no OpenGL. Both now say it in one line, as every failure.
"""
import json

import pytest

from coarse_runs import clone
from pipelines.cli import main

#: what `bladerub render` prints (pipelines.render.ensure_offscreen's report)
REPORT = ("no off-screen OpenGL route works for VTK (vtkOSOpenGLRenderWindow: library libOSMesa.so.8 not found; "
          "vtkEGLRenderWindow: library libEGL.so.1 not found; vtkXOpenGLRenderWindow: library libGL.so.1 not "
          "found): install Mesa's software renderer (`apt-get install libosmesa6`, done by .ci/install) with a VTK "
          "wheel >= 9.4, or install xvfb")

SITECUSTOMIZE = '''
import ctypes, os, shutil
_CDLL = ctypes.CDLL
class _NoGL(_CDLL):
    def __init__(self, name, *args, **kwargs):
        if name and any(lib in str(name) for lib in ("libOSMesa", "libEGL", "libGL")):
            raise OSError(f"{name}: cannot open shared object file: No such file or directory")
        super().__init__(name, *args, **kwargs)
ctypes.CDLL = _NoGL
shutil.which = lambda *args, **kwargs: None
os.environ.pop("DISPLAY", None)
'''


@pytest.fixture
def no_opengl(tmp_path, monkeypatch):
    """Child processes started from here see a machine without OpenGL (module doc)."""
    site = tmp_path / "site"
    site.mkdir()
    (site / "sitecustomize.py").write_text(SITECUSTOMIZE)
    monkeypatch.setenv("PYTHONPATH", str(site))
    monkeypatch.delenv("VTK_DEFAULT_OPENGL_WINDOW", raising=False)


def _without_mode_pictures(coarse_run, out):
    scene = clone(coarse_run[1], out)
    for png in (out / "figures").glob("mode_*.png"):
        png.unlink()
    return scene


def test_render_says_why_and_how_to_fix_it_and_writes_nothing(coarse_run, tmp_path, no_opengl, capsys):
    out = tmp_path / "out"
    scene = _without_mode_pictures(coarse_run, out)
    before = sorted(p.name for p in (out / "figures").iterdir())
    assert main(["render", str(scene), "--out", str(out)]) == 1
    assert capsys.readouterr().err.strip().splitlines() == [f"bladerub: error: {REPORT}"]  # one line
    assert sorted(p.name for p in (out / "figures").iterdir()) == before  # no picture, no temporary file


def test_a_run_draws_its_other_figures_and_fails_naming_the_mode_pictures(coarse_run, tmp_path, no_opengl, capsys):
    """`bladerub run` where the mode pictures and the ParaView modes are both to be drawn:
    modes.vtu is written (it needs no OpenGL), the run's error is one line with the report
    and the scene's way out ([render] n_modes = 0), exit 1; the next run with that setting
    ends with exit 0."""
    out = tmp_path / "out"
    scene = _without_mode_pictures(coarse_run, out)
    (out / "figures" / "modes.vtu").unlink()
    assert main(["run", str(scene), "--out", str(out), "--until", "rom", "--quiet"]) == 1
    assert capsys.readouterr().err.strip().splitlines() == [
        f"bladerub: error: figure modes failed: {REPORT}; or draw no mode pictures in runs: [render] n_modes = 0; "
        "kept: mesh.h5, fem.h5, rom.h5"]
    assert (out / "figures" / "modes.vtu").is_file() and not list((out / "figures").glob("mode_*.png"))
    manifest = json.loads((out / "figures" / "manifest.json").read_text())
    assert "modes.vtu" in manifest["modes_vtu"]["files"]
    assert main(["run", str(scene), "--out", str(out), "--until", "rom", "--quiet", "--set", "render.n_modes=0"]) == 0
