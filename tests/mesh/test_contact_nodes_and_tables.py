"""Contact nodes independent of the file's numbering; tables with NaN or stations
that do not advance are refused by name.

References: the box's own analytic camber line (y = 0 at the tip x = R0 + L, evenly spaced
in z from -b/2 to b/2) and the deck's node coordinates; the corrupted tables' values as
written by the test.
"""
from pathlib import Path

import numpy as np
import pytest

from decks import Box, box, root_nodes, write_deck
from mesh.geometry import GeometryError, read_geometry
from mesh.imported import import_blade
from mesh.options import BladeOptions, MeshOptions
from support import SHARED

R67 = SHARED / "data" / "rotor67" / "rotor67geometry.dat"
R37 = SHARED / "data" / "rotor37" / "rotor37geometry.dat"


def test_contact_nodes_do_not_depend_on_the_numbering(tmp_path):
    # The same box numbered four ways, the last two also turned about the axis (180 and
    # 100 degrees). 6 chord divisions: 13 file nodes along the tip's chord, 1.667 mm apart; 9 targets
    # 2.5 mm apart, every other one midway between two nodes.
    n_b = 9
    bx = box("wedge15", n=(12, 6, 1))
    rng = np.random.default_rng(1)
    x_tip = bx.R0 + bx.L
    targets = np.column_stack([np.full(n_b, x_tip), np.zeros(n_b), np.linspace(-bx.b / 2, bx.b / 2, n_b)])
    tip = bx.points[np.abs(bx.points[:, 0] - x_tip) < 1e-12]
    nearest = np.linalg.norm(tip[None] - targets[:, None], axis=2).min(axis=1)
    chosen = []
    for trial, angle in enumerate((0.0, 0.0, 180.0, 100.0)):
        c, s = np.cos(np.radians(angle)), np.sin(np.radians(angle))
        turn = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        pts, cells = bx.points, bx.cells
        if trial:
            p = rng.permutation(len(pts))
            inv = np.empty_like(p)
            inv[p] = np.arange(len(p))
            pts, cells = pts[p], inv[cells][rng.permutation(len(cells))]
        root = root_nodes(Box(bx.kind, pts, cells, bx.R0, bx.L, bx.b, bx.t))
        deck = tmp_path / f"box_{trial}.inp"
        write_deck(deck, Box(bx.kind, pts @ turn.T, cells, bx.R0, bx.L, bx.b, bx.t), root=root)
        m = import_blade(BladeOptions(mesh=deck.name, units="m"), MeshOptions(n_boundary=n_b), deck)
        xyz = m.boundary_xyz @ turn  # turned back
        # each on the tip, nearest to its target, LE (z = -b/2) to TE
        np.testing.assert_allclose(xyz[:, 0], x_tip, atol=1e-12)
        np.testing.assert_allclose(np.linalg.norm(xyz - targets, axis=1), nearest, atol=1e-12)
        assert np.all(np.diff(xyz[:, 2]) > 0)
        chosen.append(xyz)
    for xyz in chosen[1:]:
        np.testing.assert_allclose(xyz, chosen[0], atol=1e-12)


def _write(tmp_path, lines, name="bad.dat") -> Path:
    p = tmp_path / name
    p.write_text("\n".join(lines) + "\n")
    return p


def _r37_row(lines, surface, j):
    s = next(i for i, l in enumerate(lines) if l.strip().startswith(f"SURFACE NUMBER     {surface} "))
    i = next(k for k in range(s, len(lines)) if lines[k].split()[:1] == [str(j)])
    return i


def test_rotor37_nan_is_named(tmp_path):
    lines = R37.read_text().splitlines()
    i = _r37_row(lines, 5, 10)
    t = lines[i].split()
    t[2] = "nan"  # R of surface 5, J = 10
    lines[i] = "   ".join(t)
    with pytest.raises(GeometryError, match=r"surface 5: non-finite value at row 10"):
        read_geometry(_write(tmp_path, lines), "rotor37", "cm")


@pytest.mark.parametrize("what", ["repeated", "backwards"])
def test_rotor37_station_that_does_not_advance_is_named(tmp_path, what):
    lines = R37.read_text().splitlines()
    i = _r37_row(lines, 5, 10)
    a, b = lines[i].split(), lines[i + 1].split()
    assert float(b[1]) > float(a[1])  # the printed table advances: 0.2060862 cm, then more
    if what == "repeated":
        b[1:] = a[1:]  # J = 11 repeats J = 10
    else:
        a[1], b[1] = b[1], a[1]  # J = 10 and 11 swap their axial distances
    lines[i], lines[i + 1] = "   ".join(a), "   ".join(b)
    with pytest.raises(GeometryError, match=r"surface 5: .* at point J=11"):
        read_geometry(_write(tmp_path, lines), "rotor37", "cm")


def test_rotor67_repeated_station_inside_the_blade_is_named(tmp_path):
    lines = R67.read_text().splitlines()
    s = next(i for i, l in enumerate(lines) if l.strip().startswith("Surface number  3"))
    k = next(i for i in range(s, len(lines)) if "Axial Distance" in lines[i])
    # line k + 1: the scale factor; line k + 4: J = 17..24 (inside the blade, JLE..JTE)
    vals = lines[k + 4].split()
    assert vals[0] == "0.007267" and vals[1] == "0.007308"
    vals[1] = vals[0]  # J = 18 at the axial distance of J = 17
    lines[k + 4] = " " + " ".join(vals)
    with pytest.raises(GeometryError, match=r"surface 3, block 'Axial Distance': .* at point J=18"):
        read_geometry(_write(tmp_path, lines), "rotor67", "ft")


def test_contact_points_on_too_few_tip_nodes_are_refused():
    """The nine camber points of rotor 67's tip section snapped onto a tip face of six nodes
    (one tri6, its nodes six points of the camber line itself): two points land on one node,
    which would be one contact node counted twice, and the mesh is refused by name."""
    from mesh.blade import MeshingError, boundary_nodes, camber_points

    tip = read_geometry(R67, "rotor67", "ft").section(13)
    nodes = camber_points(tip, 6)
    with pytest.raises(MeshingError, match=r"9 boundary nodes snap onto fewer distinct tip nodes; refine the mesh"):
        boundary_nodes(nodes, np.arange(6)[None, :], tip, 9)
    # as many points as nodes: each node is the nearest to one point
    b = boundary_nodes(nodes, np.arange(6)[None, :], tip, 6)
    assert b.index.tolist() == list(range(6))
