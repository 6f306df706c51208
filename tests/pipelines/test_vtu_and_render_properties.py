"""Properties of the ParaView files (pipelines.vtu), the mode pictures (pipelines.render) and
the run's console output (pipelines.progress), each against an independent reference: VTK's
documented tet10 shape functions, a hand-computed deformation, the PNG header, the raw bytes
a child process writes to a pipe."""
import os
import struct
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import meshio
import numpy as np
import pytest
import pyvista as pv

from pipelines import render
from pipelines.progress import _duration
from pipelines.vtu import write_mode_shapes, write_time_series, write_vtu
from test_render import plate_tet10
from test_vtu import VERTS, _field, _tet10

#: vtkQuadraticTetra: nodes 4..9 are the midpoints of these corner pairs (VTK's documentation)
VTK_EDGES = [(0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3)]


def _vtk_tet10_shape(bary):
    """VTK's tet10 shape functions at barycentric (L0, L1, L2, L3): (10,)."""
    corners = [L * (2 * L - 1) for L in bary]
    return np.array(corners + [4 * bary[a] * bary[b] for a, b in VTK_EDGES])


def test_vtu_cells_read_back_interpolate_a_quadratic_exactly_along_every_edge(tmp_path):
    nodes, cells = _tet10(VERTS)
    back = meshio.read(write_vtu(tmp_path / "one.vtu", nodes, cells, {"u": _field(nodes)}))
    assert back.cells[0].type == "tetra10"  # VTK_QUADRATIC_TETRA (24)
    cell = back.cells[0].data[0]
    x, u = back.points[cell], back.point_data["u"][cell]
    for a, b in VTK_EDGES:
        bary = np.zeros(4)
        bary[a], bary[b] = 0.25, 0.75  # off the mid node: the mid node's place in the cell matters
        n = _vtk_tet10_shape(bary)
        point = 0.25 * x[a] + 0.75 * x[b]
        np.testing.assert_allclose(n @ x, point, rtol=0, atol=1e-12)
        np.testing.assert_allclose(n @ u, _field(point[None])[0], rtol=0, atol=1e-12)


def test_a_field_with_nan_is_refused_and_leaves_no_file(tmp_path):
    nodes, cells = _tet10(VERTS)
    u = np.zeros((10, 3))
    u[7, 1] = np.nan
    with pytest.raises(ValueError, match=r"'displacement' holds 1 non-finite value.*node 7"):
        write_vtu(tmp_path / "one.vtu", nodes, cells, {"displacement": u})
    modes = np.zeros((2, 10, 3))
    modes[1, 2, 0] = np.inf
    with pytest.raises(ValueError, match=r"mode_02 \(250.00 Hz\).*node 2"):
        write_mode_shapes(tmp_path / "modes.vtu", nodes, cells, modes, [100.0, 250.0])
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("times, count, message", [
    ([0.0, 2e-3, 1e-3], 3, r"increase strictly: times\[1\] = 0.002 s, times\[2\] = 0.001 s"),
    ([0.0, np.nan, 2e-3], 3, "non-finite"),
    ([0.0, 1e-3], 3, r"expected \(3,\), one per snapshot"),
])
def test_a_series_with_bad_times_writes_nothing(tmp_path, times, count, message):
    nodes, cells = _tet10(VERTS)
    with pytest.raises(ValueError, match=message):
        write_time_series(tmp_path, "hbm", nodes, cells, np.array(times), np.zeros((count, 10, 3)))
    assert list(tmp_path.rglob("*.vt*")) == [] and list(tmp_path.rglob("*.pvd")) == []


def test_a_series_with_nan_names_the_instant_and_writes_nothing(tmp_path):
    nodes, cells = _tet10(VERTS)
    disp = np.zeros((4, 10, 3))
    disp[2, 5, 2] = np.nan
    with pytest.raises(ValueError, match=r"instant 2 \(t = 0.002 s\).*node 5"):
        write_time_series(tmp_path, "hbm", nodes, cells, np.arange(4) * 1e-3, disp)
    assert list(tmp_path.rglob("*.vt*")) == [] and list(tmp_path.rglob("*.pvd")) == []
    # a good series: every referenced snapshot exists, at times in s as given
    pvd = write_time_series(tmp_path, "hbm", nodes, cells, np.arange(4) * 1e-3, np.zeros((4, 10, 3)))
    entries = ET.parse(pvd).getroot().findall("./Collection/DataSet")
    assert [float(e.get("timestep")) for e in entries] == [0.0, 1e-3, 2e-3, 3e-3]
    assert all((tmp_path / e.get("file")).is_file() for e in entries)


def _png_size(path):
    """(width, height) from the PNG's IHDR chunk (bytes 16..24, big-endian)."""
    head = path.read_bytes()[:24]
    assert head[:8] == b"\x89PNG\r\n\x1a\n" and head[12:16] == b"IHDR"
    return struct.unpack(">II", head[16:24])


def test_mode_pictures_deform_by_the_stated_fraction_and_have_the_size_asked(tmp_path, monkeypatch):
    nodes, cells = plate_tet10(4, 1, 1)  # 0.15 m along x: the largest side
    drawn = []
    shot = pv.Plotter.screenshot

    def screenshot(self, *args, **kwargs):  # record the deformed surface as drawn: the mesh coloured by |u|
        for actor in self.renderer.actors.values():
            data = actor.GetMapper().GetInput() if actor.GetMapper() is not None else None
            if data is not None and data.GetPointData().HasArray("|u|"):
                drawn.append(pv.wrap(data).points.copy())
        return shot(self, *args, **kwargs)

    monkeypatch.setattr(pv.Plotter, "screenshot", screenshot)
    modes = np.zeros((3, len(nodes), 3))
    modes[0, :, 2] = -2e-9 * nodes[:, 0] / 0.15  # linear flap: tip (x = 0.15 m) moves most
    modes[1, :, 1] = 7.0  # a translation: every node moves by the peak
    paths = render.render_mode_shapes(nodes, cells, modes, [1.0, 2.0, 3.0], tmp_path, scale=0.08,
                                      window=(333, 251))
    assert [_png_size(p) for p in paths] == [(333, 251)] * 3
    peak = 0.08 * 0.15  # m: scale times the largest bounding-box side
    flap, shift, still = drawn
    tip = np.isclose(flap[:, 0], 0.15)
    assert tip.sum() == 4
    np.testing.assert_allclose(0.004 - flap[tip, 2].max(), peak, rtol=1e-9)  # top of the tip, 4 mm thick
    np.testing.assert_allclose(shift[:, 1].min() - 0.0, peak, rtol=1e-9)
    np.testing.assert_allclose(shift[:, 1].max() - 0.04, peak, rtol=1e-9)
    # an all-zero mode is drawn undeformed (no division by its zero peak)
    np.testing.assert_allclose([still.min(0), still.max(0)], [[0, 0, 0], [0.15, 0.04, 0.004]], atol=1e-15)


def test_a_mode_with_nan_is_refused_before_any_picture(tmp_path):
    nodes, cells = plate_tet10(2, 1, 1)
    modes = np.ones((2, len(nodes), 3))
    modes[1, 3, 2] = np.nan
    with pytest.raises(ValueError, match=r"mode 2 \(20.00 Hz\) holds 1 non-finite.*node 3"):
        render.render_mode_shapes(nodes, cells, modes, [10.0, 20.0], tmp_path / "modes", window=(64, 48))
    assert not (tmp_path / "modes").exists() or list((tmp_path / "modes").iterdir()) == []


RUN = r"""
from pipelines.progress import Progress
p = Progress()
with p.step("fem", 3) as update:
    update("factorising", 1)
with p.stage("fem") as rec:
    rec.why = "material changed"
p.log("a line")
p.summary()
"""


@pytest.mark.parametrize("env", [{}, {"FORCE_COLOR": "1"}, {"TTY_COMPATIBLE": "1"}])
def test_output_to_a_pipe_has_no_control_characters(env):
    """Not a terminal: plain lines and the summary, no live line, whatever rich's variables say."""
    out = subprocess.run([sys.executable, "-c", RUN], capture_output=True, timeout=60, check=True,
                         cwd=Path(__file__).parents[2],
                         env={**os.environ, **env}).stdout
    assert b"a line\n" in out and b"run summary" in out and b"material changed" in out
    assert b"\r" not in out and b"\x1b" not in out, out[:200]


@pytest.mark.parametrize("seconds, text", [(0.4, "0.4 s"), (59.9, "59.9 s"), (59.96, "1 min 00 s"),
                                           (61.4, "1 min 01 s"), (3599.4, "59 min 59 s"), (3600, "1 h 00 min"),
                                           (90061, "25 h 01 min")])
def test_durations_read_in_one_unit_each(seconds, text):
    assert _duration(seconds) == text
