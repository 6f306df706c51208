"""Assembly, dof map, eigen-solver and bad input of the fem stage on small tet10 boxes."""
import dataclasses

import numpy as np
import pytest
import scipy.sparse.linalg as sla

from box_mesh import box_mesh
from fem.assembly import assemble_system
from fem.material import Material
from fem.modes import compute_modes


@pytest.fixture(scope="module")
def box():
    return box_mesh(0.1, 0.03, 0.01, 0.006)


@pytest.fixture(scope="module")
def system(box):
    return assemble_system(box.nodes, box.cells, box.root_facets, Material())


def test_node_dofs_layout(box, system):
    nd = system.node_dofs
    clamped = np.unique(box.root_facets)
    assert (nd[clamped] == -1).all()
    free = nd[nd >= 0]
    np.testing.assert_array_equal(free, np.arange(system.n_free))  # node-major, mesh order
    assert system.n_free == 3 * (box.n_nodes - len(clamped))


def test_matrices_symmetric_and_mass_of_translation(box, system):
    for A in (system.K, system.M):
        assert abs(A - A.T).max() <= 1e-12 * abs(A).max()
    # rigid x-translation of the free nodes: u^T M u is the mass those nodes carry. Bounds:
    # the whole box (rho V) from above, the box minus one element layer at the root from below.
    u = np.zeros(system.n_free)
    u[0::3] = 1.0
    m = u @ system.M @ u
    rho_v = 4400.0 * 0.1 * 0.03 * 0.01
    assert 0.9 * rho_v < m < rho_v


def test_dof_map_gives_consistent_gravity_load(box, system):
    # consistent load of a unit body force along z must integrate to rho g V over the free
    # part: checks that node_dofs picks the z component (a wrong component order would put
    # the load on x or y).
    u = np.zeros(system.n_free)
    u[2::3] = 1.0
    f = system.M @ u
    assert abs(f[0::3].sum()) < 1e-12 * f[2::3].sum()
    assert abs(f[1::3].sum()) < 1e-12 * f[2::3].sum()


def test_modes_match_arpack(system):
    r = compute_modes(system.K, system.M, 6)
    w2, _ = sla.eigsh(system.K, M=system.M, k=6, sigma=0.0)
    np.testing.assert_allclose(r.frequencies ** 2, np.sort(w2), rtol=1e-9)
    np.testing.assert_allclose(r.frequencies_hz, r.frequencies / (2 * np.pi))
    # mass-normalised
    np.testing.assert_allclose(np.diag(r.vectors.T @ system.M @ r.vectors), 1.0, rtol=1e-9)
    nodal = system.to_nodal(r.vectors)
    assert nodal.shape == (6, system.n_nodes, 3)
    assert (nodal[:, system.node_dofs[:, 0] < 0] == 0).all()


def test_out_of_core_factor_lives_in_files_and_matches_arpack(system, tmp_path):
    from fem.cholesky import CholeskyFactor

    factor = CholeskyFactor(system.K, out_of_core=str(tmp_path))
    try:
        assert any(tmp_path.iterdir())  # MUMPS wrote the factor there
        r = compute_modes(system.K, system.M, 6, factor=factor)
    finally:
        factor.destroy()
    assert not any(tmp_path.iterdir())  # and deleted it when the factor was freed
    w2, _ = sla.eigsh(system.K, M=system.M, k=6, sigma=0.0)
    np.testing.assert_allclose(r.frequencies ** 2, np.sort(w2), rtol=1e-9)


def test_the_ordering_asked_for_is_the_one_applied():
    """[fem] ordering reaches MUMPS: AMD and PORD give different factors of a 3-D Laplacian
    (30^3 grid: AMD's minimum degree fills ~1.6 times what PORD's nested dissection does),
    each solves it, and ordering_used names what MUMPS applied. (PETSc 3.18 resets an
    ICNTL(7) set on the factor matrix: every ordering then gave the same factor.)"""
    import scipy.sparse as sp

    from fem.cholesky import CholeskyFactor

    L = sp.diags([-1.0, 2.01, -1.0], [-1, 0, 1], shape=(30, 30))
    eye = sp.eye(30)
    A = (sp.kron(sp.kron(L, eye), eye) + sp.kron(sp.kron(eye, L), eye) + sp.kron(sp.kron(eye, eye), L)).tocsr()
    b = np.random.default_rng(0).standard_normal(A.shape[0])
    entries = {}
    for name in ("pord", "amd"):
        f = CholeskyFactor(A, ordering=name, solver="mumps")
        try:
            assert f.ordering_used == name
            entries[name] = f.factor_entries
            assert np.linalg.norm(A @ f.solve(b) - b) < 1e-10 * np.linalg.norm(b)
        finally:
            f.destroy()
    assert entries["amd"] > 1.3 * entries["pord"], entries


def test_nu_at_incompressible_limit_raises():
    with pytest.raises(ValueError, match="Poisson"):
        Material(nu=0.5)


def test_mesh_without_root_facets_raises(box):
    with pytest.raises(ValueError, match="no root facets"):
        assemble_system(box.nodes, box.cells, np.zeros((0, 6), dtype=np.int64), Material())


def test_bad_cell_shape_raises(box):
    with pytest.raises(ValueError, match="tet10"):
        assemble_system(box.nodes, box.cells[:, :4], box.root_facets, Material())


def test_bad_options_raise():
    from fem.options import FemOptions

    with pytest.raises(ValueError, match="ordering"):
        FemOptions(ordering="nested")
    with pytest.raises(ValueError, match="n_modes"):
        FemOptions(n_modes=0)


def test_boundary_node_on_root_raises(box, system):
    from fem.interface import boundary_dofs_of

    with pytest.raises(ValueError, match="clamped root"):
        boundary_dofs_of(system.node_dofs, box.root_facets[0, :2])
