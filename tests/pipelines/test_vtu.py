"""ParaView output (pipelines.vtu): VTU files read back with meshio give the same nodes,
cells and fields, and VTK's own quadratic tetrahedron interpolates a quadratic field
exactly between the nodes, which holds only if the tet10 node order is VTK's."""
import json
import subprocess
import sys
import xml.etree.ElementTree as ET

import meshio
import numpy as np
import pytest

from pipelines.vtu import GMSH_TO_VTK_TET10, mode_name, write_mode_shapes, write_time_series, write_vtu

#: gmsh tet10 edges of nodes 4..9 (mesh.model.BladeMesh): 01, 12, 20, 30, 32, 31
GMSH_EDGES = [(0, 1), (1, 2), (2, 0), (3, 0), (3, 2), (3, 1)]


def _tet10(vertices):
    """One straight-sided tet10 in gmsh's order: vertices, then edge midpoints."""
    v = np.asarray(vertices, float)
    return np.vstack([v, [(v[a] + v[b]) / 2 for a, b in GMSH_EDGES]]), np.arange(10)[None, :]


def _field(x):
    """A quadratic vector field, exactly represented by P2 interpolation, (k, 3)."""
    x, y, z = x.T
    return np.stack([1 + x + 2 * y * y - 3 * x * z, y * z - x * x + 0.5, z - 2 * x * y + y * y], 1)


VERTS = [[0.0, 0.0, 0.0], [1.0, 0.1, 0.0], [0.2, 0.9, 0.1], [0.1, 0.2, 1.1]]
# interior points (barycentric combinations), away from the nodes
BARY = np.array([[0.1, 0.2, 0.3, 0.4], [0.4, 0.3, 0.2, 0.1], [0.25, 0.25, 0.25, 0.25], [0.05, 0.6, 0.05, 0.3]])

PROBE = r"""
import json, sys
import numpy as np, pyvista as pv
a = json.loads(sys.argv[1])
grid = pv.read(a["file"])
probe = pv.PolyData(np.array(a["points"])).sample(grid)
print(json.dumps(np.asarray(probe[a["name"]]).tolist()))
"""


def _vtk_interpolate(path, points, name):
    """VTK's (pyvista's) interpolation of a point field at points, in a child process (VTK
    and the FEniCSx stack do not share a process well, see pipelines.render)."""
    out = subprocess.run([sys.executable, "-c", PROBE, json.dumps({"file": str(path), "points": points.tolist(),
                                                                  "name": name})],
                         capture_output=True, text=True, timeout=120, check=True)
    return np.array(json.loads(out.stdout.splitlines()[-1]))


def test_vtu_round_trip_and_vtk_interpolates_a_quadratic_field_exactly(tmp_path):
    nodes, cells = _tet10(VERTS)
    f = _field(nodes)
    path = write_vtu(tmp_path / "one.vtu", nodes, cells, {"u": f, "s": f[:, 0]})
    back = meshio.read(path)
    np.testing.assert_array_equal(back.points, nodes)
    assert [c.type for c in back.cells] == ["tetra10"]
    np.testing.assert_array_equal(back.cells[0].data, cells[:, GMSH_TO_VTK_TET10])
    np.testing.assert_array_equal(back.point_data["u"], f)
    # VTK's tet10 shape functions reproduce quadratics exactly at interior points, up to
    # VTK's inverse mapping: it finds a point's parametric coordinates in a quadratic cell by
    # Newton iterations stopped near 1e-5 (1.2e-5 measured here, on values ~1): 1e-4
    pts = BARY @ np.asarray(VERTS)
    np.testing.assert_allclose(_vtk_interpolate(path, pts, "u"), _field(pts), rtol=0, atol=1e-4)
    # the same file with gmsh's order kept (edges 32 and 31 swapped for VTK) is wrong there:
    # what this test would catch
    meshio.write(tmp_path / "gmsh_order.vtu", meshio.Mesh(nodes, [("tetra10", cells)], point_data={"u": f}))
    wrong = _vtk_interpolate(tmp_path / "gmsh_order.vtu", pts, "u")
    err = np.abs(wrong - _field(pts)).max()
    assert err > 1e-2, err


def test_mode_shapes_and_time_series_read_back(tmp_path):
    nodes, cells = _tet10(VERTS)
    modes = np.random.default_rng(0).standard_normal((3, 10, 3))
    path = write_mode_shapes(tmp_path / "modes.vtu", nodes, cells, modes, [100.0, 250.0, 400.0, 900.0])
    back = meshio.read(path)
    assert sorted(back.point_data) == ["mode_01 (100.00 Hz)", "mode_02 (250.00 Hz)", "mode_03 (400.00 Hz)"]
    for j, f in enumerate([100.0, 250.0, 400.0]):  # float32 in the file: 7 digits
        np.testing.assert_allclose(back.point_data[mode_name(j, f)], modes[j], rtol=1e-6, atol=1e-6)
    t = np.array([0.0, 1e-3, 2e-3])
    disp = 1e-3 * np.random.default_rng(1).standard_normal((3, 10, 3))
    pvd = write_time_series(tmp_path, "hbm", nodes, cells, t, disp, "a test -- series")
    entries = ET.parse(pvd).getroot().findall("./Collection/DataSet")
    assert [float(e.get("timestep")) for e in entries] == pytest.approx(t.tolist(), abs=1e-15)
    for i, e in enumerate(entries):
        m = meshio.read(tmp_path / e.get("file"))
        np.testing.assert_array_equal(m.points, nodes)
        np.testing.assert_allclose(m.point_data["displacement"], disp[i], rtol=1e-6, atol=1e-12)


def test_a_failed_snapshot_stops_the_series_without_its_collection(tmp_path, monkeypatch):
    """A snapshot whose write fails (a full disk) ends the series with that error: the
    snapshots not started yet are not written, and no PVD names files that are not there."""
    import time

    import pipelines.vtu as vtu

    nodes, cells = _tet10(VERTS)
    started = []
    real = vtu.write_vtu

    def write(path, *args):
        started.append(path.name)
        if path.name.endswith("_000.vtu"):
            raise OSError(28, "No space left on device")
        time.sleep(0.2)
        return real(path, *args)

    monkeypatch.setattr(vtu, "write_vtu", write)
    with pytest.raises(OSError, match="No space"):
        vtu.write_time_series(tmp_path, "hbm", nodes, cells, np.arange(12) * 1e-3, np.zeros((12, 10, 3)))
    assert len(started) <= 4, started  # the first and what the other threads had begun
    assert not (tmp_path / "hbm.pvd").exists()
