"""Off-screen mode-shape pictures of a quadratic tetrahedral blade mesh (pyvista/VTK).

Rendering never needs a display. The first call picks, once per process, an OpenGL
window class that VTK (>= 9.4 wheels choose at run time) can really draw with, trying
in order:

1. whatever the user set in ``VTK_DEFAULT_OPENGL_WINDOW`` (respected, tried first);
2. ``vtkOSOpenGLRenderWindow``: Mesa's software OSMesa (Debian ``libosmesa6``). Pure CPU,
   no GPU driver, no X server: the same result on every machine, so it is preferred;
3. ``vtkEGLRenderWindow``: EGL (headless GPU, or Mesa's surfaceless llvmpipe);
4. ``vtkXOpenGLRenderWindow`` on ``$DISPLAY`` or, without one, on an ``Xvfb`` server this
   module starts (and stops at exit); the only route for older X-only VTK wheels.

Each candidate is checked by drawing a small scene and reading the pixels back; if none
works, :class:`RenderError` says what each attempt gave and how to fix it.
"""
from __future__ import annotations

import atexit
import ctypes
import os
import shutil
import subprocess
from io import BytesIO
from pathlib import Path

import numpy as np

from pipelines import artifacts as art
from pipelines.vtu import require_finite

_LIBRARIES = {  # window class -> shared libraries VTK dlopens for it
    "vtkOSOpenGLRenderWindow": ("libOSMesa.so.8", "libOSMesa.so.6", "libOSMesa.so"),
    "vtkEGLRenderWindow": ("libEGL.so.1", "libEGL.so"),
    "vtkXOpenGLRenderWindow": ("libGL.so.1", "libGL.so"),
}
_ENV = "VTK_DEFAULT_OPENGL_WINDOW"
ANTI_ALIASING = "ssaa"
_chosen: str | None = None
_xvfb: subprocess.Popen | None = None


class RenderError(RuntimeError):
    """No off-screen OpenGL route works on this machine (or the process drawing the modes
    ended without its pictures)."""


#: exit code of the drawing process (`python -m pipelines.render`) when no route works: its
#: standard error then holds RenderError's report alone, which the parent raises again
NO_ROUTE_EXIT = 3


def _loadable(names) -> bool:
    for name in names:
        try:
            ctypes.CDLL(name)
            return True
        except OSError:
            continue
    return False


def _draws(window_class: str) -> str | None:
    """None if VTK gives `window_class` and it draws a non-blank picture, else the reason."""
    import pyvista as pv

    os.environ[_ENV] = window_class
    plotter = pv.Plotter(off_screen=True, window_size=(64, 48))
    try:
        got = plotter.ren_win.GetClassName()
        if got != window_class:  # VTK fell back (unknown class, or an X-only wheel)
            return f"VTK made a {got} instead"
        plotter.add_mesh(pv.Sphere(), color="white")
        img = plotter.screenshot(return_img=True)
        if img is None or img.shape[:2] != (48, 64) or float(np.std(img)) < 1.0:
            return "it rendered a blank picture"
        return None
    except Exception as exc:  # a broken driver shows up here, not at construction
        return f"{type(exc).__name__}: {exc}"
    finally:
        plotter.close()


def _start_xvfb() -> str | None:
    """Start a private Xvfb, point $DISPLAY at it; None on success, else the reason."""
    global _xvfb
    exe = shutil.which("Xvfb")
    if exe is None:
        return "no Xvfb on PATH (Debian package xvfb)"
    r, w = os.pipe()
    # -displayfd: the server picks a free display number and writes it to us. -noreset: by
    # default the server resets when its last client leaves and refuses connections meanwhile;
    # VTK connects and leaves several times while making one window, and on a loaded host a
    # connection fell in a reset: VTK then made another window class (a failed route).
    proc = subprocess.Popen([exe, "-displayfd", str(w), "-screen", "0", "1920x1080x24",
                             "-nolisten", "tcp", "-noreset"], pass_fds=(w,),
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    os.close(w)
    with os.fdopen(r) as f:
        number = f.readline().strip()
    if not number:
        proc.kill()
        return "Xvfb did not start"
    _xvfb = proc
    atexit.register(proc.terminate)
    os.environ["DISPLAY"] = f":{number}"
    return None


def ensure_offscreen() -> str:
    """Make VTK render off-screen in this process; return the OpenGL window class used.

    Idempotent and cached: the probing (about 0.2 s) runs once per process. Sets
    ``VTK_DEFAULT_OPENGL_WINDOW`` (and ``DISPLAY`` when it has to start Xvfb).
    Raises RenderError when no route works.
    """
    global _chosen
    if _chosen is not None:
        os.environ[_ENV] = _chosen
        return _chosen
    user = os.environ.get(_ENV)
    order = ([user] if user else []) + [c for c in _LIBRARIES if c != user]
    failures = []
    for window_class in order:
        if window_class in _LIBRARIES and not _loadable(_LIBRARIES[window_class]):
            failures.append(f"{window_class}: library {_LIBRARIES[window_class][0]} not found")
            continue
        if window_class == "vtkXOpenGLRenderWindow" and not os.environ.get("DISPLAY"):
            reason = _start_xvfb()
            if reason:
                failures.append(f"{window_class}: {reason}")
                continue
        reason = _draws(window_class)
        if reason is None:
            _chosen = window_class
            return window_class
        failures.append(f"{window_class}: {reason}")
    if user:
        os.environ[_ENV] = user
    else:
        os.environ.pop(_ENV, None)
    # one line, as every failure the command line reports (pipelines.cli)
    raise RenderError(
        "no off-screen OpenGL route works for VTK (" + "; ".join(failures) + "): install Mesa's software "
        "renderer (`apt-get install libosmesa6`, done by .ci/install) with a VTK wheel >= 9.4, or install xvfb")


def boundary_triangles(cells: np.ndarray) -> np.ndarray:
    """Outer surface of a tetrahedral mesh as corner-node triangles.

    cells: (n_cells, >=4) int, corners first (gmsh and VTK tet4/tet10 orderings agree on
    them). Returns (n_faces, 3) int, faces that belong to exactly one tetrahedron, wound
    so that their normals point out of the solid. Mid-edge nodes are ignored: a linear
    surface is plenty for a picture and four times lighter to draw.
    """
    tets = np.asarray(cells)[:, :4].astype(np.int64)
    # Faces of a positively oriented tet (0,1,2,3), each wound outward.
    local = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    faces = tets[:, local].reshape(-1, 3)
    key_rows = np.sort(faces, axis=1)
    n = int(tets.max()) + 1
    if n < 2_000_000:  # pack a sorted triple in one int64: 1-D unique is much faster
        keys = (key_rows[:, 0] * n + key_rows[:, 1]) * n + key_rows[:, 2]
        _, first, counts = np.unique(keys, return_index=True, return_counts=True)
    else:
        _, first, counts = np.unique(key_rows, axis=0, return_index=True, return_counts=True)
    return faces[first[counts == 1]]


def _orient_outward(nodes: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """cells with the corner order of negatively oriented tets swapped (1 <-> 2)."""
    tets = np.asarray(cells)[:, :4].astype(np.int64)
    p = nodes[tets]
    vol = np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), p[:, 3] - p[:, 0])
    flip = vol < 0
    tets[flip] = tets[flip][:, [0, 2, 1, 3]]
    return tets


def _as_node_displacements(modes: np.ndarray, n_nodes: int) -> np.ndarray:
    """(3n, k) node-major or (k, n, 3) -> (k, n, 3)."""
    modes = np.asarray(modes, dtype=float)
    if modes.ndim == 2 and modes.shape[0] == 3 * n_nodes:
        return modes.T.reshape(modes.shape[1], n_nodes, 3)
    if modes.ndim == 3 and modes.shape[1:] == (n_nodes, 3):
        return modes
    raise ValueError(f"modes has shape {modes.shape}; expected (3n, k) or (k, n, 3) with n={n_nodes}")


def _camera(points: np.ndarray):
    """Camera (position, focal point, view up) for a blade: radial span upwards, looking at
    the blade's face (along its thinnest principal direction), slightly from above and aside.
    """
    center = 0.5 * (points.min(0) + points.max(0))
    size = float(np.ptp(points, axis=0).max())
    radial = np.array([center[0], center[1], 0.0])
    _, _, vt = np.linalg.svd(points[:: max(1, len(points) // 20000)] - points.mean(0), full_matrices=False)
    if np.linalg.norm(radial) > 0.05 * size:  # a blade off the axis: radial span points up
        up = radial / np.linalg.norm(radial)
    else:  # a test body centred on the axis: its longest direction points up
        up = vt[0]
    look = vt[2] - (vt[2] @ up) * up  # blade-face normal, made orthogonal to "up"
    if np.linalg.norm(look) < 1e-6:
        look = vt[1] - (vt[1] @ up) * up
    look /= np.linalg.norm(look)
    if look[np.argmax(np.abs(look))] < 0:  # SVD signs are arbitrary: pick a fixed side
        look = -look
    side = np.cross(up, look)
    direction = look + 0.6 * side + 0.3 * up  # a little 3-D perspective
    direction /= np.linalg.norm(direction)
    return [tuple(center + 2.6 * size * direction), tuple(center), tuple(up)]


def render_mode_shapes(nodes, cells, modes, frequencies_hz, out_dir, *, n_modes: int = 6,
                       scale: float = 0.08, window=(1200, 900), title_prefix: str = "") -> list[Path]:
    """Write one PNG per mode: deformed outer surface coloured by |u|, undeformed outline.

    nodes: (n, 3) float, m. cells: (n_cells, 10) int, quadratic tets in gmsh ordering
    (any tet with corners first works; only boundary corner nodes are drawn).
    modes: (3n, k) float, column j is mode j with rows node-major [u0x, u0y, u0z, u1x, ...]
    in the order of `nodes` (also accepted: (k, n, 3)); any normalisation; the modes drawn
    must be finite (ValueError naming the mode, before any picture is written).
    frequencies_hz: (k,) float, Hz. Draws the first min(n_modes, k) modes, each scaled so
    its largest displacement is `scale` times the largest bounding-box side of the mesh.
    window: (width, height) pixels of each PNG. Returns the paths out_dir/mode_01.png, ...
    """
    ensure_offscreen()
    import pyvista as pv

    nodes = np.asarray(nodes, dtype=float)
    u_all = _as_node_displacements(modes, len(nodes))
    freqs = np.asarray(frequencies_hz, dtype=float).ravel()
    count = min(int(n_modes), u_all.shape[0], freqs.size)
    for j in range(count):
        require_finite(f"mode {j + 1} ({freqs[j]:.2f} Hz)", u_all[j])
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)

    tris = boundary_triangles(_orient_outward(nodes, cells))
    used, inverse = np.unique(tris, return_inverse=True)  # draw surface nodes only
    points = nodes[used]
    faces = np.hstack([np.full((len(tris), 1), 3), inverse.reshape(-1, 3)]).ravel()
    size = float(np.ptp(points, axis=0).max())

    undeformed = pv.PolyData(points, faces)
    outline = undeformed.extract_feature_edges(feature_angle=35.0, boundary_edges=True,
                                               non_manifold_edges=False, manifold_edges=False)
    surface = undeformed.copy()
    surface.point_data["|u|"] = np.zeros(len(points))

    plotter = pv.Plotter(off_screen=True, window_size=tuple(int(v) for v in window))
    plotter.set_background("white")
    # Undeformed shape as its feature edges only: a translucent surface in front of the
    # deformed one greys its colours out.
    if outline.n_points:
        plotter.add_mesh(outline, color="#303030", line_width=1.5, opacity=0.7)
    plotter.add_mesh(surface, scalars="|u|", cmap="RdYlBu_r", clim=(0.0, 1.0), smooth_shading=True,
                     ambient=0.35, diffuse=0.75, specular=0.15, show_edges=False,
                     scalar_bar_args=dict(title="relative displacement", color="black", vertical=True,
                                          position_x=0.86, position_y=0.15, height=0.7, width=0.05,
                                          fmt="%.1f", n_labels=6, title_font_size=15,
                                          label_font_size=16))
    plotter.camera_position = _camera(points)
    plotter.camera.zoom(1.05)
    plotter.enable_anti_aliasing(ANTI_ALIASING)

    paths = []
    for j in range(count):
        u = u_all[j][used]
        mag = np.linalg.norm(u, axis=1)
        peak = float(mag.max())
        factor = scale * size / peak if peak > 0 else 0.0
        surface.points = points + factor * u
        surface.point_data["|u|"] = mag / peak if peak > 0 else mag
        plotter.add_text(f"{title_prefix}mode {j + 1} \u2014 {freqs[j]:.1f} Hz", name="title",
                         position="upper_edge", font_size=16, color="black")
        path = out_dir / f"mode_{j + 1:02d}.png"
        png = BytesIO()
        plotter.screenshot(png)  # PNG bytes, written under a temporary name then renamed
        with art.atomic_output(path) as tmp:
            tmp.write_bytes(png.getvalue())
        paths.append(path)
    plotter.close()
    return paths


def render_artifacts(mesh_h5: Path, fem_h5: Path, out_dir: Path, *, n_modes: int = 6, scale: float = 0.08,
                     window=(1200, 900), title_prefix: str = "", timeout: float = 600.0) -> list[Path]:
    """Render the modes of `fem_h5` on the mesh of `mesh_h5` in a separate process.

    VTK's wheels and the FEniCSx stack carry different C++ runtimes: in a process that has
    loaded dolfinx/PETSc, VTK crashed in its scalar-bar layout (std::regex). A child process
    that loads only h5py and pyvista avoids that and keeps a crash from taking the run down.
    """
    import json
    import sys

    args = json.dumps({"mesh": str(mesh_h5), "fem": str(fem_h5), "out": str(out_dir), "n_modes": n_modes,
                       "scale": scale, "window": list(window), "title_prefix": title_prefix})
    proc = subprocess.run([sys.executable, "-m", "pipelines.render", args], capture_output=True, text=True,
                          timeout=timeout)
    said = [line.strip() for line in proc.stderr.splitlines() if line.strip()]
    if proc.returncode == NO_ROUTE_EXIT and said:
        raise RenderError(said[-1])  # the report, not the child's traceback
    if proc.returncode != 0:  # a crash: its last word (a traceback's exception line)
        raise RenderError(f"mode-shape rendering failed (exit {proc.returncode})"
                          + (f": {said[-1]}" if said else ""))
    return [Path(line) for line in proc.stdout.splitlines() if line.endswith(".png")]


def _main(argv) -> int:
    import json
    import sys

    import h5py

    a = json.loads(argv[0])
    with h5py.File(a["mesh"], "r") as h5:
        nodes, cells = h5["nodes"][()], h5["cells"][()]
    with h5py.File(a["fem"], "r") as h5:
        modes, freqs = h5["modes"][()], h5["frequencies_hz"][()]
    try:
        for p in render_mode_shapes(nodes, cells, modes, freqs, Path(a["out"]), n_modes=a["n_modes"],
                                    scale=a["scale"], window=tuple(a["window"]), title_prefix=a["title_prefix"]):
            print(p)
    except RenderError as exc:
        print(exc, file=sys.stderr)
        return NO_ROUTE_EXIT
    return 0


if __name__ == "__main__":
    import sys

    sys.exit(_main(sys.argv[1:]))
