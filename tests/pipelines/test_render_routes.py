"""The off-screen route's choice and its failure report (pipelines.render.ensure_offscreen),
each in a fresh process: VTK's window class and the cached choice are per process.

Where no route works, the error must list every route tried, in order, with what each gave
and how to fix it, and leave VTK_DEFAULT_OPENGL_WINDOW as the user had it.
"""
import json
import os
import re
import signal
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

from support import shell_env

ROOT = Path(__file__).resolve().parents[2]

_SCRIPT = """
import json, os, sys
import pipelines.render as r
case = sys.argv[1]
if case != "unknown":
    os.environ.pop("DISPLAY", None)
    if case != "x and xvfb":
        r.shutil.which = lambda name: None  # no Xvfb
    loadable = {"none": (), "x only": ("libGL.so.1",), "x and xvfb": ("libGL.so.1",)}[case]
    r._loadable = lambda names: names[0] in loadable
try:
    chosen, error = r.ensure_offscreen(), None
except r.RenderError as exc:
    chosen, error = None, str(exc)
drawn = None
if chosen:  # a picture through the chosen route: its spread of grey levels
    import numpy as np, pyvista as pv
    p = pv.Plotter(off_screen=True, window_size=(80, 60))
    p.add_mesh(pv.Cube(), color="white")
    drawn = float(np.std(p.screenshot(return_img=True)))
    p.close()
kept = None
if r._xvfb:  # does the server outlive its clients? An atom is forgotten at a server reset
    import ctypes, time
    x11 = ctypes.CDLL("libX11.so.6")
    x11.XOpenDisplay.restype, x11.XOpenDisplay.argtypes = ctypes.c_void_p, [ctypes.c_char_p]
    x11.XInternAtom.restype, x11.XInternAtom.argtypes = ctypes.c_ulong, [ctypes.c_void_p, ctypes.c_char_p, ctypes.c_int]
    x11.XCloseDisplay.argtypes = [ctypes.c_void_p]
    def connect():
        for _ in range(200):  # a resetting server refuses connections for a moment
            d = x11.XOpenDisplay(os.environ["DISPLAY"].encode())
            if d:
                return d
            time.sleep(0.05)
        raise SystemExit("no connection to the Xvfb in 10 s")
    d = connect(); made = x11.XInternAtom(d, b"BLADERUB_PROBE", 0); x11.XCloseDisplay(d)  # the only client leaves
    time.sleep(0.5)
    d = connect(); kept = x11.XInternAtom(d, b"BLADERUB_PROBE", 1) == made != 0; x11.XCloseDisplay(d)
print(json.dumps({"chosen": chosen, "error": error, "env": os.environ.get(r._ENV), "drawn": drawn,
                  "display": os.environ.get("DISPLAY"), "xvfb": r._xvfb.pid if r._xvfb else None, "kept": kept}))
"""


def _run(case: str, user_class: str | None = None) -> dict:
    env = shell_env()
    env.pop("VTK_DEFAULT_OPENGL_WINDOW", None)
    if user_class:
        env["VTK_DEFAULT_OPENGL_WINDOW"] = user_class
    out = subprocess.run([sys.executable, "-c", _SCRIPT, case], cwd=ROOT, env=env, capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_no_route_names_each_one_tried_and_the_fix():
    got = _run("none")
    assert got["chosen"] is None and got["env"] is None  # nothing of the probe left behind
    # one line, as every failure the command line reports
    assert got["error"] == (
        "no off-screen OpenGL route works for VTK (vtkOSOpenGLRenderWindow: library libOSMesa.so.8 not found; "
        "vtkEGLRenderWindow: library libEGL.so.1 not found; vtkXOpenGLRenderWindow: library libGL.so.1 not "
        "found): install Mesa's software renderer (`apt-get install libosmesa6`, done by .ci/install) with a VTK "
        "wheel >= 9.4, or install xvfb")


def test_x_without_a_display_or_xvfb_says_so_and_the_users_class_is_kept():
    got = _run("x only", user_class="vtkEGLRenderWindow")
    assert got["chosen"] is None and got["env"] == "vtkEGLRenderWindow"
    assert got["error"].startswith(
        "no off-screen OpenGL route works for VTK (vtkEGLRenderWindow: library libEGL.so.1 not found; "  # the user's, first
        "vtkOSOpenGLRenderWindow: library libOSMesa.so.8 not found; "
        "vtkXOpenGLRenderWindow: no Xvfb on PATH (Debian package xvfb)): install ")


def test_a_users_class_that_vtk_does_not_make_gives_way_to_one_that_draws():
    got = _run("unknown", user_class="vtkNoSuchWindow")
    assert got["error"] is None
    assert got["chosen"] in ("vtkOSOpenGLRenderWindow", "vtkEGLRenderWindow", "vtkXOpenGLRenderWindow")
    assert got["env"] == got["chosen"]  # what VTK's next window reads


@pytest.mark.skipif(shutil.which("Xvfb") is None, reason="no Xvfb on PATH (Debian package xvfb, which .ci/install "
                    "installs)")
def test_x_without_a_display_starts_a_private_xvfb_that_draws_and_ends_with_the_process():
    """The last route (GL through X, no $DISPLAY): a private Xvfb on the display number it picks,
    a picture that is not blank, and the server gone once the process has ended."""
    got = _run("x and xvfb")
    assert got["error"] is None and got["chosen"] == got["env"] == "vtkXOpenGLRenderWindow", got["error"]
    assert re.fullmatch(r":\d+", got["display"]) and got["drawn"] > 1.0, got
    # no reset when its last client leaves: a resetting server refuses connections for a moment,
    # which VTK reported as "bad X server connection" and replaced the X window by another class
    assert got["kept"] is True
    for _ in range(600):  # terminated at the process's exit (atexit); reaped or a zombie: gone (30 s: a loaded host)
        try:
            state = Path(f"/proc/{got['xvfb']}/status").read_text()
        except FileNotFoundError:
            break
        if "\nState:\tZ" in state:
            break
        time.sleep(0.05)
    else:
        os.kill(got["xvfb"], signal.SIGTERM)  # not left behind by this failure
        pytest.fail(f"Xvfb (pid {got['xvfb']}) still runs after its process ended")
