"""The NASA table -> tet10 mesh path against the tables' own numbers.

References: values read off the printed files (quoted with their J), the volume of the
table's blade as the integral of the tangential thickness over the meridional (z, r) plane
(V = int int r dtheta dr dz = int int t dr dz, quadrature on the table's own (surface, J)
grid, independent of the solid and of mesh.blade.reference_volume), the streamsurfaces'
radii r_k(z) of the table, and tables whose surfaces were swapped or repeated by the test.
"""
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import cKDTree

from mesh.blade import mesh_blade
from mesh.geometry import GeometryError, read_geometry
from mesh.options import BladeOptions, MeshOptions
from support import COARSE_MESH, SHARED

R67 = SHARED / "data" / "rotor67" / "rotor67geometry.dat"
R37 = SHARED / "data" / "rotor37" / "rotor37geometry.dat"
FT, CM = 0.3048, 0.01


def meridional_volume(sections) -> float:
    """int int t dr dz over the quadrilaterals of the (surface, J) grid (shoelace area times
    the mean of the four corner thicknesses), m^3. Second order: 0.27 % (rotor 67) and
    0.11 % (rotor 37) below the same integral on a grid refined 8 times by monotone cubics."""
    Z, R, T = (np.stack([getattr(s, a) for s in sections]) for a in ("z", "r", "thickness"))
    c = lambda A: (A[:-1, :-1], A[:-1, 1:], A[1:, 1:], A[1:, :-1])  # noqa: E731
    (z0, z1, z2, z3), (r0, r1, r2, r3) = c(Z), c(R)
    area = 0.5 * np.abs((z2 - z0) * (r3 - r1) - (z3 - z1) * (r2 - r0))
    return float((area * sum(c(T)) / 4.0).sum())


# --- the tables' numbers ----------------------------------------------------------------

def test_rotor67_tip_section_against_the_printed_table():
    # "THE DIMENSIONS ARE IN FEET"; surface 13 (the tip), JLE = 16 and JTE = 85 as printed
    tip = read_geometry(R67, "rotor67", "ft").section(13)
    assert tip.z[0] == pytest.approx(0.073017 * FT, abs=1e-12)
    assert tip.z[-1] == pytest.approx(0.220372 * FT, abs=1e-12)
    assert tip.r[0] == pytest.approx(0.797848 * FT, abs=1e-12)
    assert tip.r[-1] == pytest.approx(0.780478 * FT, abs=1e-12)
    assert tip.rtheta_upper[0] == pytest.approx(0.003833 * FT, abs=1e-12)
    assert tip.rtheta_upper[-1] == pytest.approx(0.264482 * FT, abs=1e-12)
    assert tip.thickness[51 - 16] == pytest.approx(0.019107 * FT, abs=1e-12)  # J = 51
    # camber: the mean angle of the two surfaces, r * theta_upper - t / 2 at J = 51
    theta_c = np.arctan2(tip.camber_xyz()[:, 1], tip.camber_xyz()[:, 0])[51 - 16]
    assert theta_c * tip.r[51 - 16] == pytest.approx((tip.rtheta_upper[35] - 0.5 * tip.thickness[35]), rel=1e-12)


def test_rotor37_tip_section_against_the_printed_table():
    # Table IV, "Z and R are in centimeters", surface 12 (blade tip section), J = 1 and 100
    tip = read_geometry(R37, "rotor37", "cm").section(12)
    assert tip.z[0] == pytest.approx(0.6317154 * CM, abs=1e-12)
    assert tip.r[0] == pytest.approx(25.1972466 * CM, abs=1e-12)
    assert tip.z[-1] == pytest.approx(3.4227355 * CM, abs=1e-12)
    assert tip.r[-1] == pytest.approx(24.4330425 * CM, abs=1e-12)
    assert tip.theta_upper[0] == pytest.approx(-0.0988740, abs=1e-12)
    # J = 2: thickness r (THETA1 - THETA2)
    assert tip.thickness[1] == pytest.approx(25.1971092 * CM * (-0.0987322 + 0.0990158), rel=1e-9)


# --- surfaces out of order or repeated ----------------------------------------------------

def _r67_with_surfaces(tmp_path: Path, source_of) -> Path:
    """Rotor 67's table with surface k carrying the data of surface source_of(k)."""
    lines = R67.read_text().splitlines()
    starts = [i for i, l in enumerate(lines) if l.strip().startswith("Surface number")] + [len(lines)]
    blocks = {k + 1: lines[starts[k] + 1:starts[k + 1]] for k in range(14)}
    out = lines[:starts[0]]
    for k in range(1, 15):
        out += [f" Surface number {k:2d} from hub"] + blocks[source_of(k)]
    p = tmp_path / "r67.dat"
    p.write_text("\n".join(out) + "\n")
    return p


@pytest.mark.parametrize("case, source_of, match", [
    ("swapped", lambda k: {7: 8, 8: 7}.get(k, k), r"surface 8 lies below surface 7 at point J=16"),
    ("repeated", lambda k: 7 if k == 8 else k, r"surface 8 repeats the radius of surface 7 at point J=16"),
])
def test_rotor67_surfaces_out_of_order_are_named(tmp_path, case, source_of, match):
    # unchecked, gmsh fails after ~40 s on overlapping facets (swapped) or does not return
    # within 10 min (repeated)
    with pytest.raises(GeometryError, match=match):
        read_geometry(_r67_with_surfaces(tmp_path, source_of), "rotor67", "ft")


def test_rotor67_surfaces_listed_out_of_order_but_numbered_right_are_read(tmp_path):
    lines = R67.read_text().splitlines()
    starts = [i for i, l in enumerate(lines) if l.strip().startswith("Surface number")] + [len(lines)]
    blocks = [lines[starts[k]:starts[k + 1]] for k in range(14)]
    order = [0, 1, 2, 4, 3] + list(range(5, 14))  # surface 5 printed before surface 4
    p = tmp_path / "r67.dat"
    p.write_text("\n".join(lines[:starts[0]] + [l for k in order for l in blocks[k]]) + "\n")
    g, ref = read_geometry(p, "rotor67", "ft"), read_geometry(R67, "rotor67", "ft")
    for a, b in zip(g.sections, ref.sections):
        assert a.number == b.number and np.array_equal(a.r, b.r)


def test_rotor37_swapped_surfaces_are_named(tmp_path):
    lines = R37.read_text().splitlines()
    s = [i for i, l in enumerate(lines) if l.strip().upper().startswith("SURFACE NUMBER")] + [len(lines)]
    five, six = lines[s[4] + 1:s[5]], lines[s[5] + 1:s[6]]  # the rows of surfaces 5 and 6
    swapped = lines[:s[4] + 1] + six + [lines[s[5]]] + five + lines[s[6]:]
    p = tmp_path / "r37.dat"
    p.write_text("\n".join(swapped) + "\n")
    with pytest.raises(GeometryError, match=r"surface 6 lies below surface 5 at point J=1:"):
        read_geometry(p, "rotor37", "cm")


# --- the meshed blade against the table -------------------------------------------------

@pytest.fixture(scope="module")
def r37_mesh():
    return mesh_blade(BladeOptions(geometry=str(R37), format="rotor37", units="cm", tip_section=12),
                      MeshOptions(**COARSE_MESH), R37)


def test_rotor67_volume_against_the_meridional_integral(mesh, geometry):
    # 4.6707e-5 against 4.6744e-5 m^3 (the default mesh: 4.6869e-5); reference_volume's
    # spanwise trapezoids over the mean section radius give 4.790e-5 (+2.5 %)
    v = meridional_volume(geometry.sections[:13])
    assert v == pytest.approx(4.674e-5, rel=1e-3)
    assert mesh.volume == pytest.approx(v, rel=5e-3)


def test_rotor37_volume_against_the_meridional_integral(r37_mesh):
    # 7.844e-6 against 7.883e-6 m^3 (-0.5 %; element_size 3 mm: -0.02 %)
    v = meridional_volume(read_geometry(R37, "rotor37", "cm").sections[:12])
    assert v == pytest.approx(7.883e-6, rel=1e-3)
    assert r37_mesh.volume == pytest.approx(v, rel=1e-2)


def _longest_edge(x, facets):
    """Longest vertex-to-vertex edge of (n, 6) tri6 facets, m."""
    v = x[facets[:, :3]]
    return float(max(np.linalg.norm(v[:, a] - v[:, b], axis=1).max() for a, b in ((0, 1), (1, 2), (2, 0))))


def _check_against_streamsurfaces(m, g, tip_number):
    """Hub/tip radii of the nodes, root and contact nodes against the table's r_k(z)."""
    x = m.nodes
    r = np.hypot(x[:, 0], x[:, 1])
    above_hub = r - g.surface_radius(1, x[:, 2])
    below_tip = g.surface_radius(tip_number, x[:, 2]) - r
    # straight-sided tet10: the mid-edge node of a cap's edge of length L sits up to
    # L^2 / (8 r) inside the surface of revolution; the caps' vertices lie on the filling
    # surfaces, < 40 um off it (mesh.blade)
    L = max(_longest_edge(x, m.root_facets), _longest_edge(x, m.tip_facets))
    sag = L ** 2 / (8 * g.section(1).r.min()) + 4e-5
    assert above_hub.min() > -sag and below_tip.min() > -1e-5
    root = np.unique(m.root_facets)
    assert np.abs(above_hub[root]).max() < sag
    # nothing else on the hub: every node within 10 um of it is clamped
    assert set(np.flatnonzero(np.abs(above_hub) < 1e-5)) <= set(root)
    # contact nodes on the tip face, on the tip streamsurface, LE and TE exactly the table's
    tip = g.section(tip_number)
    assert np.abs(m.boundary_rho - g.surface_radius(tip_number, m.boundary_xyz[:, 2])).max() < sag
    assert m.boundary_rho[0] == pytest.approx(tip.r[0], abs=1e-9)
    assert m.boundary_rho[-1] == pytest.approx(tip.r[-1], abs=1e-9)
    assert np.all(np.diff(m.boundary_xyz[:, 2]) > 0)  # LE -> TE along the axis
    theta = m.boundary_theta
    assert np.all(np.diff(theta) > 0) or np.all(np.diff(theta) < 0)
    assert theta[-1] == pytest.approx(tip.theta_upper[-1] - tip.theta_upper[0], abs=1e-9)
    F = m.boundary_frames
    np.testing.assert_allclose(np.einsum("nij,nkj->nik", F, F), np.broadcast_to(np.eye(3), F.shape), atol=1e-14)
    np.testing.assert_allclose(np.cross(F[:, 0], F[:, 1]), F[:, 2], atol=1e-14)
    np.testing.assert_allclose(F[:, 0, :2] * m.boundary_rho[:, None], m.boundary_xyz[:, :2], atol=1e-14)


def test_rotor67_hub_tip_root_and_contact_nodes(mesh, geometry):
    _check_against_streamsurfaces(mesh, geometry, 13)


def test_rotor37_hub_tip_root_and_contact_nodes(r37_mesh):
    _check_against_streamsurfaces(r37_mesh, read_geometry(R37, "rotor37", "cm"), 12)


def _inside(nodes, cells, points):
    """(n,) whether each of the (n, 3) points lies in a (straight-sided) cell."""
    V = nodes[cells[:, :4]]
    tree = cKDTree(V.mean(axis=1))
    _, cand = tree.query(points, k=40)
    inv = np.linalg.inv(np.transpose(V[:, 1:] - V[:, :1], (0, 2, 1)))
    lam = np.einsum("nkij,nkj->nki", inv[cand], points[:, None, :] - V[cand, 0])
    lam = np.concatenate([1.0 - lam.sum(-1, keepdims=True), lam], axis=-1)
    return np.any(lam.min(axis=-1) >= -1e-10, axis=1)


@pytest.mark.parametrize("number", [2, 7, 12])
def test_rotor67_thickness_and_camber_in_the_mesh(mesh, geometry, number):
    # Along the circle (z_J, r_J) of stations away from the edges, the mesh's solid spans the
    # table's tangential thickness (to 3 %: 8 mm straight-sided cells on curved faces; measured -0.7 to +1.7 %) about
    # its camber (to 0.2 mm; measured up to 0.1 mm); the spanwise loft passes through the intermediate sections.
    s = geometry.section(number)
    for j in (20, 35, 50):
        th = np.linspace(s.theta_lower[j] - 0.02, s.theta_upper[j] + 0.02, 4001)
        p = np.column_stack([s.r[j] * np.cos(th), s.r[j] * np.sin(th), np.full_like(th, s.z[j])])
        ins = _inside(mesh.nodes, mesh.cells, p)
        assert ins.sum() * (th[1] - th[0]) * s.r[j] == pytest.approx(s.thickness[j], rel=0.03)
        assert abs(th[ins].mean() - 0.5 * (s.theta_upper[j] + s.theta_lower[j])) * s.r[j] < 2e-4


def test_element_size_beyond_the_blade_thickness_still_meshes_the_table(geometry):
    # 50 mm, six times the thickest section (8.1 mm) and about the chord: the edge size
    # (thinnest edge thickness) and the growth from the LE/TE lines still set the cells, so
    # the mesh is about the coarse one (23 626 nodes), not a few flat cells across the blade
    m = mesh_blade(BladeOptions(), MeshOptions(element_size=0.05, edge_layers=1, size_growth=0.5), R67)
    assert max(s.thickness.max() for s in geometry.sections[:13]) < 0.05 / 6
    assert m.volume == pytest.approx(meridional_volume(geometry.sections[:13]), rel=5e-3)
    assert len(np.unique(m.boundary_node_index)) == 9
    assert 15_000 < m.n_nodes < 40_000
