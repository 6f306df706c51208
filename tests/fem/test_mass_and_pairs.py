"""Consistent mass against rho V, and the repeated bending pairs of a square cantilever.

Mass: the free-dof M of one clamp lacks the root nodes' rows, so 1^T M 1 over it is not
rho V. Two clamps, of the face x = 0 and of the face x = L, miss disjoint node sets, and no
element touches both faces: their free-dof blocks together hold every entry of the whole
M, once each outside the overlap (the entries between nodes on neither face, which both
must give alike). Partition of unity then makes each direction's sum exactly rho V.

Pairs: a square section has every bending frequency twice (bending in y and in z); the
eigen-solver must return both members, M-orthonormal, neither lost (the next mode moved
up) nor repeated (two copies of one shape).
"""
import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as sla

from box_mesh import box_mesh
from fem.assembly import assemble_system
from fem.material import Material
from fem.modes import compute_modes

MAT = Material()


def _global(system) -> tuple[np.ndarray, sp.coo_matrix]:
    """(node of each free-dof entry's row and column, M as COO in node-major global dof 3 node + c)."""
    nd = system.node_dofs
    to_global = np.empty(system.n_free, dtype=np.int64)
    nodes, comps = np.nonzero(nd >= 0)
    to_global[nd[nodes, comps]] = 3 * nodes + comps
    M = system.M.tocoo()
    return to_global, sp.coo_matrix((M.data, (to_global[M.row], to_global[M.col])), shape=(3 * len(nd),) * 2)


@pytest.fixture(scope="module")
def box():
    return box_mesh(0.06, 0.02, 0.01, 0.005, n_boundary=3)


def test_every_direction_carries_rho_v(box):
    a = assemble_system(box.nodes, box.cells, box.root_facets, MAT)  # clamped at x = 0
    b = assemble_system(box.nodes, box.cells, box.tip_facets, MAT)  # clamped at x = L
    _, Ma = _global(a)
    _, Mb = _global(b)
    Ma, Mb = Ma.tocsr(), Mb.tocsr()
    both = np.zeros(3 * box.n_nodes, dtype=bool)
    both[np.repeat(3 * np.setdiff1d(np.arange(box.n_nodes), np.union1d(box.root_facets, box.tip_facets)), 3)
         + np.tile(np.arange(3), box.n_nodes - len(np.union1d(box.root_facets, box.tip_facets)))] = True
    overlap = sp.diags(both.astype(float))
    # the two assemblies agree where both hold the entry
    Oa, Ob = overlap @ Ma @ overlap, overlap @ Mb @ overlap
    assert abs(Oa - Ob).max() <= 1e-13 * abs(Ma).max()
    M = Ma + Mb - Oa  # every entry of the whole consistent mass, once
    rho_v = MAT.rho * 0.06 * 0.02 * 0.01
    for c in range(3):
        for d in range(3):
            ec, ed = np.zeros(M.shape[0]), np.zeros(M.shape[0])
            ec[c::3], ed[d::3] = 1.0, 1.0
            expected = rho_v if c == d else 0.0
            assert abs(ec @ (M @ ed) - expected) <= 1e-12 * rho_v, (c, d, ec @ (M @ ed))


def test_square_cantilever_keeps_both_members_of_each_bending_pair():
    L, a = 0.1, 0.01
    # gmsh's unstructured mesh: nearly symmetric in y and z, so the pairs are close
    # (measured 1e-5 apart), the hard case for an eigen-solver; a structured split of the
    # square is not symmetric and parts them by 1e-3
    m = box_mesh(L, a, a, 0.004, n_boundary=3)
    s = assemble_system(m.nodes, m.cells, m.root_facets, MAT)
    r = compute_modes(s.K, s.M, 6)
    w2 = np.sort(sla.eigsh(s.K, M=s.M, k=6, sigma=0.0)[0])
    np.testing.assert_allclose(r.frequencies ** 2, w2, rtol=1e-9)  # none lost, none repeated
    X = r.vectors
    np.testing.assert_allclose(X.T @ (s.M @ X), np.eye(6), atol=1e-10)
    f = r.frequencies_hz
    assert abs(f[1] / f[0] - 1) < 1e-4 and abs(f[3] / f[2] - 1) < 1e-4, f  # 1F and 2F pairs
    assert f[2] > 5 * f[1], f  # the pair is not 1F and a neighbour
    # Euler-Bernoulli 1F, L/a = 10: the solid sits within 1 % (shear, rotary inertia, clamp)
    eb = 1.875104068711961 ** 2 * np.sqrt(MAT.E * a ** 4 / 12 / (MAT.rho * a * a * L ** 4)) / (2 * np.pi)
    assert abs(f[0] / eb - 1) < 1e-2 and abs(f[1] / eb - 1) < 1e-2, (f[:2], eb)
    # the two members bend the tip in the two directions: their mean tip (y, z) motion spans the plane
    tip = np.unique(m.tip_facets)
    u = s.to_nodal(X[:, :2])[:, tip, 1:].mean(axis=1)  # (2 modes, y z)
    s_ = np.linalg.svd(u, compute_uv=False)
    assert s_[1] > 0.5 * s_[0], u
