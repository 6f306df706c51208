"""The blade mesh, checked with plain numpy against the table, not against gmsh's own figures.

Runs on the coarse setting (element_size 8 mm, one element across the edges: ~24 000 nodes,
a few seconds) that the fast scenes use.
"""
import numpy as np
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from support import COARSE_MESH, R67_TABLE, SHARED
from mesh.blade import camber_points, mesh_blade
from mesh.geometry import GeometryError, read_geometry
from mesh.options import BladeOptions, MeshOptions

R67 = R67_TABLE
COARSE = MeshOptions(**COARSE_MESH)  # the mesh and geometry fixtures: tests/mesh/conftest.py
TET10_EDGES = ((0, 1), (1, 2), (2, 0), (3, 0), (3, 2), (3, 1))  # gmsh order, as in BladeMesh
TRI6_EDGES = ((0, 1), (1, 2), (2, 0))


def _tet_volumes(x, cells):
    a, b, c, d = (x[cells[:, i]] for i in range(4))
    return np.einsum("ij,ij->i", b - a, np.cross(c - a, d - a)) / 6.0


def _boundary_faces(cells):
    """Vertex triples of the faces used by one tet only, oriented outward for positive tets."""
    v = cells[:, :4]
    faces = np.concatenate([v[:, [0, 2, 1]], v[:, [0, 1, 3]], v[:, [1, 2, 3]], v[:, [0, 3, 2]]])
    key = np.sort(faces, axis=1)
    _, inv, count = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    return faces[count[inv.ravel()] == 1]


def test_layout_of_the_contract(mesh):
    n = mesh.n_nodes
    assert mesh.nodes.shape == (n, 3) and mesh.nodes.dtype == np.float64
    for a, w in ((mesh.cells, 10), (mesh.root_facets, 6), (mesh.tip_facets, 6)):
        assert a.dtype == np.int64 and a.ndim == 2 and a.shape[1] == w
        assert a.min() >= 0 and a.max() < n
    assert np.array_equal(np.unique(mesh.cells), np.arange(n))  # no orphan nodes
    assert mesh.boundary_node_index.shape == (9,) and mesh.boundary_frames.shape == (9, 3, 3)
    assert 15_000 <= n <= 30_000  # the coarse setting promised for fast runs


def test_nodes_are_numbered_for_a_narrow_band(mesh):
    # mesh.ordering: gmsh numbers the mid-edge nodes after every vertex, which makes a cell
    # span nearly the whole node range; reverse Cuthill-McKee keeps the same cells, facets
    # and contact nodes within a small fraction of it
    from mesh.ordering import bandwidth

    meshed = mesh_blade(BladeOptions(), COARSE, R67, node_order="meshed")
    assert bandwidth(meshed.cells) > 0.5 * meshed.n_nodes
    assert bandwidth(mesh.cells) < 0.2 * bandwidth(meshed.cells)
    np.testing.assert_array_equal(mesh.nodes[mesh.cells], meshed.nodes[meshed.cells])
    for name in ("root_facets", "tip_facets", "boundary_node_index"):
        np.testing.assert_array_equal(mesh.nodes[getattr(mesh, name)], meshed.nodes[getattr(meshed, name)])


def test_node_ordering_is_gmsh_tet10_and_tri6(mesh):
    # Straight-sided quadratic cells: each mid-edge node is the midpoint of its edge in the
    # documented ordering; a wrong ordering would miss by about an edge length.
    x = mesh.nodes
    for k, (a, b) in enumerate(TET10_EDGES):
        np.testing.assert_allclose(x[mesh.cells[:, 4 + k]], 0.5 * (x[mesh.cells[:, a]] + x[mesh.cells[:, b]]), atol=1e-12)
    for f in (mesh.root_facets, mesh.tip_facets):
        for k, (a, b) in enumerate(TRI6_EDGES):
            np.testing.assert_allclose(x[f[:, 3 + k]], 0.5 * (x[f[:, a]] + x[f[:, b]]), atol=1e-12)


def test_jacobians_positive(mesh):
    # Affine (straight-sided) tet10: the Jacobian is the linear tet's, constant per cell.
    vol = _tet_volumes(mesh.nodes, mesh.cells)
    assert vol.min() > 0
    # and not just positive by roundoff: far above eps * h^3 for the smallest edge h ~ 0.2 mm
    assert vol.min() > 1e-6 * (2e-4) ** 3


def test_watertight_single_volume(mesh):
    cells = mesh.cells
    faces = _boundary_faces(cells)
    # closed surface: every boundary edge belongs to exactly two boundary faces
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    _, count = np.unique(edges, axis=0, return_counts=True)
    assert np.all(count == 2)
    # divergence theorem: (1/3) sum over faces of x.n dA equals the sum of tet volumes
    x = mesh.nodes
    a, b, c = (x[faces[:, i]] for i in range(3))
    v_surface = np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0
    v_cells = _tet_volumes(x, cells).sum()
    assert v_surface == pytest.approx(v_cells, rel=1e-10)
    assert mesh.volume == pytest.approx(v_cells, rel=1e-10)
    # one connected component through shared nodes
    n = mesh.n_nodes
    rows = np.repeat(cells[:, 0], 9)
    cols = cells[:, 1:].ravel()
    graph = coo_matrix((np.ones(rows.size), (rows, cols)), shape=(n, n))
    assert connected_components(graph, directed=False)[0] == 1
    # root and tip facets are boundary faces
    bkeys = {tuple(f) for f in np.sort(faces, axis=1)}
    assert all(tuple(f) in bkeys for f in np.sort(mesh.root_facets[:, :3], axis=1))
    assert all(tuple(f) in bkeys for f in np.sort(mesh.tip_facets[:, :3], axis=1))


def test_volume_agrees_with_section_integral(mesh):
    # README: about 4.8e-5 m^3 for both; the section-wise integral spans the sections over
    # their mean radius (ignoring the streamsurfaces' slope and the blade's lean), an O(few %)
    # approximation, hence 4 % between the two; a solid missing a cap or a slice is >10 % off.
    assert mesh.reference_volume == pytest.approx(4.8e-5, rel=0.02)
    assert mesh.volume == pytest.approx(4.8e-5, rel=0.05)
    assert mesh.volume == pytest.approx(mesh.reference_volume, rel=0.04)


def test_root_and_tip_lie_on_their_streamsurfaces(mesh, geometry):
    # The caps are filling surfaces pinned to the section's camber points; across the blade
    # width w they may leave the surface of revolution by ~ w^2 / (8 r) < 0.1 mm. 0.2 mm is
    # still 70x smaller than the 14 mm between sections 1 and 2.
    for facets, number in ((mesh.root_facets, 1), (mesh.tip_facets, 13)):
        x = mesh.nodes[np.unique(facets)]
        r = np.hypot(x[:, 0], x[:, 1])
        assert np.abs(r - geometry.surface_radius(number, x[:, 2])).max() < 2e-4
        s = geometry.section(number)
        assert x[:, 2].min() >= s.z.min() - 1e-6 and x[:, 2].max() <= s.z.max() + 1e-6


def test_boundary_nodes(mesh, geometry):
    tip = geometry.section(13)
    idx = mesh.boundary_node_index
    x = mesh.nodes[idx]
    np.testing.assert_array_equal(mesh.boundary_xyz, x)
    assert set(idx) <= set(np.unique(mesh.tip_facets))
    # LE and TE of the tip are geometry vertices, hence mesh nodes: hit exactly.
    np.testing.assert_allclose(x[0], tip.upper_xyz()[0], atol=1e-9)
    np.testing.assert_allclose(x[-1], tip.upper_xyz()[-1], atol=1e-9)
    # Even camber spacing: each node within ~half a tip-face element of its target point.
    targets = camber_points(tip, 9)
    assert np.linalg.norm(x - targets, axis=1).max() < 0.6 * COARSE.element_size
    # LE -> TE: the position along the camber grows node by node.
    c = tip.camber_xyz()
    s = np.concatenate([[0], np.cumsum(np.linalg.norm(np.diff(c, axis=0), axis=1))])
    along = s[np.argmin(np.linalg.norm(x[:, None] - c[None], axis=2), axis=1)]
    assert np.all(np.diff(along) > 0)
    # radius and angle
    np.testing.assert_allclose(mesh.boundary_rho, np.hypot(x[:, 0], x[:, 1]), rtol=1e-14)
    assert mesh.boundary_theta[0] == 0.0
    phi = np.arctan2(x[:, 1], x[:, 0])
    np.testing.assert_allclose(mesh.boundary_theta, phi - phi[0], atol=1e-14)
    # frames: orthonormal, right-handed, e_r along the node's radius, e_z the axis
    F = mesh.boundary_frames
    np.testing.assert_allclose(F @ F.transpose(0, 2, 1), np.broadcast_to(np.eye(3), F.shape), atol=1e-14)
    np.testing.assert_allclose(np.linalg.det(F), 1.0, atol=1e-14)
    np.testing.assert_allclose(F[:, 0, :2] * mesh.boundary_rho[:, None], x[:, :2], atol=1e-14)
    np.testing.assert_allclose(F[:, 2], np.tile([0, 0, 1.0], (9, 1)))


def test_deterministic(mesh):
    again = mesh_blade(BladeOptions(), COARSE, R67)
    np.testing.assert_array_equal(again.nodes, mesh.nodes)
    np.testing.assert_array_equal(again.cells, mesh.cells)
    np.testing.assert_array_equal(again.boundary_node_index, mesh.boundary_node_index)


def test_tip_section_beyond_the_table():
    with pytest.raises(GeometryError, match="tip_section 15"):
        mesh_blade(BladeOptions(tip_section=15), COARSE, R67)


def test_rotor37_blade_is_swappable():
    # Rotor 37 (NASA TP-1659): a closed solid whose volume agrees with its own section-wise
    # integral within the same 4 % as rotor 67; contact nodes on its tip, LE first.
    r37 = SHARED / "data" / "rotor37" / "rotor37geometry.dat"
    m = mesh_blade(BladeOptions(format="rotor37", units="cm", tip_section=13), COARSE, r37)
    assert _tet_volumes(m.nodes, m.cells).min() > 0
    assert m.volume == pytest.approx(m.reference_volume, rel=0.04)
    tip = read_geometry(r37, "rotor37", "cm").section(13)
    np.testing.assert_allclose(m.boundary_xyz[0], tip.upper_xyz()[0], atol=1e-9)
    assert m.boundary_theta[0] == 0.0
