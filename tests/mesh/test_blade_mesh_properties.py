"""Properties of the table-built blade mesh that test_blade.py does not check, each against
an independent reference: the tet10 shape functions written out from their definition
(barycentric products) and a curved cell whose volume is known in closed form; the caps
found again from the cells' boundary faces and the streamsurfaces of the table; the
contact nodes by brute-force nearest search, their camber targets evenly spaced in arc
length by projection on the camber line, and their angles on the same blade turned across
the atan2 cut; node orders checked as permutations on graphs built by hand.
"""
import dataclasses

import numpy as np
import pytest

from mesh import tet10
from mesh.blade import boundary_nodes, camber_points
from mesh.model import BladeMesh
from mesh.ordering import rcm_order, renumber_nodes

# the coarse rotor 67 mesh and its table: the fixtures mesh and geometry (tests/mesh/conftest.py)
# gmsh tet10 mid-edge nodes, as BladeMesh documents them (not read from mesh.tet10)
EDGES = ((0, 1), (1, 2), (2, 0), (3, 0), (3, 2), (3, 1))
VERTICES = np.array([[0.0, 0.0, 0.0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
REFERENCE_NODES = np.vstack([VERTICES, [(VERTICES[a] + VERTICES[b]) / 2 for a, b in EDGES]])


def _shape_functions(p):
    """(10,) tet10 shape functions at a reference point: L_i (2 L_i - 1), then 4 L_a L_b."""
    lam = np.array([1.0 - p.sum(), *p])
    return np.array([l * (2 * l - 1) for l in lam] + [4 * lam[a] * lam[b] for a, b in EDGES])


def test_tet10_shape_gradients_are_those_of_the_gmsh_ordering():
    # one at its own node, zero at the nine others, in the documented order
    np.testing.assert_allclose([_shape_functions(p) for p in REFERENCE_NODES], np.eye(10), atol=1e-15)
    points = np.random.default_rng(0).dirichlet(np.ones(4), 12)[:, 1:]
    h = 1e-6
    fd = np.stack([np.stack([(_shape_functions(p + h * e) - _shape_functions(p - h * e)) / (2 * h)
                             for e in np.eye(3)], axis=1) for p in points])
    np.testing.assert_allclose(tet10.shape_gradients(points), fd, atol=1e-8)


def test_curved_tet10_jacobian_and_volume_in_closed_form():
    # x = xi + c xi_1^2 e_1 is exactly quadratic: det J = 1 + 2 c xi_1 and the volume is
    # the integral over the reference tet, 1/6 + 2 c / 24
    c = 0.3
    x = REFERENCE_NODES.copy()
    x[:, 0] += c * REFERENCE_NODES[:, 0] ** 2
    cells = np.arange(10)[None]
    det = tet10.jacobian_determinants(x, cells)[0]
    np.testing.assert_allclose(det, 1.0 + 2.0 * c * tet10.CHECK_POINTS[:, 0], rtol=1e-14)
    assert tet10.cell_volumes(x, cells)[0] == pytest.approx(1.0 / 6.0 + c / 12.0, rel=1e-14)


def test_jacobians_at_the_quadrature_points_of_the_blade(mesh):
    # straight-sided cells: det J is the vertices' triple product at every point
    x, cells = mesh.nodes, mesh.cells
    a, b, c, d = (x[cells[:, i]] for i in range(4))
    triple = np.einsum("ij,ij->i", b - a, np.cross(c - a, d - a))
    det = tet10.jacobian_determinants(x, cells, tet10.KEAST5_POINTS)
    np.testing.assert_allclose(det, np.broadcast_to(triple[:, None], det.shape), rtol=1e-9)
    assert triple.min() > 0


def _boundary_faces(cells):
    """Sorted vertex triples of the faces that belong to one cell only."""
    v = cells[:, :4]
    key = np.sort(np.concatenate([v[:, [0, 1, 2]], v[:, [0, 1, 3]], v[:, [1, 2, 3]], v[:, [0, 2, 3]]]), axis=1)
    faces, count = np.unique(key, axis=0, return_counts=True)
    return faces[count == 1]


def test_root_and_tip_facets_are_exactly_the_cap_faces(mesh, geometry):
    # A boundary face with its three vertices within 0.15 mm of the hub (tip) streamsurface:
    # the caps' vertices lie within 0.034 (0.032) mm of it, every other boundary vertex of
    # the coarse mesh at least 0.30 mm away.
    x = mesh.nodes
    faces = _boundary_faces(mesh.cells)
    for facets, number in ((mesh.root_facets, 1), (mesh.tip_facets, 13)):
        off = np.abs(np.hypot(x[:, 0], x[:, 1]) - geometry.surface_radius(number, x[:, 2]))
        on_cap = faces[np.all(off[faces] < 1.5e-4, axis=1)]
        assert {tuple(f) for f in on_cap} == {tuple(f) for f in np.sort(facets[:, :3], axis=1)}
    # the clamped nodes: vertices and edges of a disk's triangulation, V - E + T = 1
    f = mesh.root_facets
    edges = np.unique(np.sort(f[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1), axis=0)
    n_vertices = len(np.unique(f[:, :3]))
    assert n_vertices - len(edges) + len(f) == 1
    assert len(np.unique(f)) == n_vertices + len(edges)


def test_contact_nodes_are_the_nearest_tip_nodes_and_keep_their_angles_across_the_cut(mesh, geometry):
    tip = geometry.section(13)
    x, tip_nodes = mesh.nodes, np.unique(mesh.tip_facets)
    targets = camber_points(tip, 9)
    dist = np.linalg.norm(x[tip_nodes][None] - targets[:, None], axis=2)
    np.testing.assert_array_equal(mesh.boundary_node_index, tip_nodes[dist.argmin(axis=1)])
    xb = mesh.boundary_xyz
    phi = np.arctan2(xb[:, 1], xb[:, 0])
    theta = phi - phi[0]  # the table's blade lies near +x: nothing to wrap
    assert 0.0 < theta[-1] < 1.0
    # the blade and its table turned so that the tip straddles the -x axis (phi = +-pi)
    for alpha in (np.pi - phi.mean(), np.pi - 0.05 - phi[0]):
        cs, sn = np.cos(alpha), np.sin(alpha)
        turn = np.array([[cs, -sn, 0.0], [sn, cs, 0.0], [0.0, 0.0, 1.0]])
        turned = dataclasses.replace(tip, rtheta_upper=tip.rtheta_upper + tip.r * alpha)
        b = boundary_nodes(x @ turn.T, mesh.tip_facets, turned, 9)
        phi_b = np.arctan2(b.xyz[:, 1], b.xyz[:, 0])
        assert phi_b.max() > 0.9 * np.pi and phi_b.min() < -0.9 * np.pi  # across the cut
        np.testing.assert_array_equal(b.index, mesh.boundary_node_index)
        np.testing.assert_allclose(b.theta, theta, atol=1e-14)
        # frames of the node itself: e_r along its own radius, e_r x e_theta = e_z
        rho = np.hypot(b.xyz[:, 0], b.xyz[:, 1])
        np.testing.assert_allclose(b.rho, rho, rtol=1e-15)
        np.testing.assert_allclose(b.frames[:, 0, :2], b.xyz[:, :2] / rho[:, None], atol=1e-15)
        np.testing.assert_allclose(np.cross(b.frames[:, 0], b.frames[:, 1]), b.frames[:, 2], atol=1e-15)
        np.testing.assert_allclose(b.frames[:, 2], np.tile([0.0, 0.0, 1.0], (9, 1)))


def test_contact_targets_are_evenly_spaced_along_the_tip_camber_from_le_to_te(geometry):
    # each target's arc length along the camber polyline, by projection on its segments
    tip = geometry.section(13)
    c = tip.camber_xyz()
    seg = np.diff(c, axis=0)
    start = np.concatenate([[0.0], np.cumsum(np.linalg.norm(seg, axis=1))])
    targets = camber_points(tip, 9)
    arc = []
    for p in targets:
        t = np.clip(np.einsum("ij,ij->i", p - c[:-1], seg) / np.einsum("ij,ij->i", seg, seg), 0.0, 1.0)
        d = np.linalg.norm(c[:-1] + t[:, None] * seg - p, axis=1)
        k = int(d.argmin())
        assert d[k] < 1e-12  # on the camber line
        arc.append(start[k] + t[k] * np.linalg.norm(seg[k]))
    np.testing.assert_allclose(arc, np.linspace(0.0, start[-1], 9), rtol=0.0, atol=1e-12 * start[-1])


def test_node_orders_are_permutations_of_every_node():
    # two separate cells, nodes no cell uses, and a node in 300 cells (its node-graph
    # count overflows the pattern's int8): every node once, no other
    fan = np.column_stack([np.zeros(300, dtype=np.int64), 1 + 9 * np.arange(300)[:, None] + np.arange(9)])
    for cells, n in ((np.array([np.arange(10), 20 + np.arange(10)]), 35), (fan, 2701)):
        order = rcm_order(cells, n)
        np.testing.assert_array_equal(np.sort(order), np.arange(n))
    # every node-indexed array follows its node, the isolated ones too
    cells = np.array([np.arange(10), 20 + np.arange(10)])
    nodes = np.random.default_rng(2).random((35, 3))
    m = BladeMesh(nodes=nodes, cells=cells, root_facets=cells[:1, [0, 1, 2, 4, 5, 6]],
                  tip_facets=cells[1:, [1, 2, 3, 5, 9, 8]], boundary_node_index=np.array([21, 33, 12]),
                  boundary_xyz=nodes[[21, 33, 12]], boundary_rho=np.zeros(3), boundary_theta=np.zeros(3),
                  boundary_frames=np.tile(np.eye(3), (3, 1, 1)), source_node_ids=100 + np.arange(35))
    r = renumber_nodes(m)
    assert sorted(map(tuple, r.nodes)) == sorted(map(tuple, nodes))
    for name in ("cells", "root_facets", "tip_facets", "boundary_node_index"):
        np.testing.assert_array_equal(r.nodes[getattr(r, name)], nodes[getattr(m, name)])
        np.testing.assert_array_equal(r.source_node_ids[getattr(r, name)], 100 + getattr(m, name))
    np.testing.assert_array_equal(nodes[r.source_node_ids - 100], r.nodes)  # each id with its own node
