"""The two sparse Cholesky packages behind [fem] solver: which one "auto" takes, that the
default one (CHOLMOD) solves blocks of right-hand sides, refuses what is not positive
definite, and gives MUMPS's modes. The FEM references (beam theory, ARPACK, CalculiX) run
through the default in tests/fem and tests/mesh; MUMPS through the out-of-core and MPI tests."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as sla

from fem.cholesky import CHOLMOD_ORDERING, CholeskyFactor, resolve_solver


def _laplacian(n: int, shift: float = 0.01) -> sp.csr_matrix:
    L = sp.diags([-1.0, 2.0 + shift, -1.0], [-1, 0, 1], shape=(n, n))
    eye = sp.eye(n)
    return (sp.kron(sp.kron(L, eye), eye) + sp.kron(sp.kron(eye, L), eye) + sp.kron(sp.kron(eye, eye), L)).tocsr()


def test_auto_takes_cholmod_where_it_can_run_and_mumps_elsewhere():
    assert resolve_solver("auto", distributed=False, out_of_core=False) == "cholmod"
    assert resolve_solver("auto", distributed=True, out_of_core=False) == "mumps"
    assert resolve_solver("auto", distributed=False, out_of_core=True) == "mumps"
    assert resolve_solver("mumps", distributed=False, out_of_core=False) == "mumps"
    with pytest.raises(ValueError, match="one process"):
        resolve_solver("cholmod", distributed=True, out_of_core=False)
    with pytest.raises(ValueError, match="out of core"):
        resolve_solver("cholmod", distributed=False, out_of_core=True)
    with pytest.raises(ValueError, match="unknown solver 'umfpack'"):
        resolve_solver("umfpack", distributed=False, out_of_core=False)


def test_scene_options_refuse_cholmod_out_of_core():
    from fem.options import FemOptions

    with pytest.raises(ValueError, match="out_of_core"):
        FemOptions(solver="cholmod", out_of_core=True)
    with pytest.raises(ValueError, match="solver"):
        FemOptions(solver="superlu")
    assert FemOptions(out_of_core=True).solver == "auto"


def test_cholmod_solves_a_block_of_right_hand_sides():
    """A 3-D Laplacian (27 000 unknowns): every column of a 12-column block solved to
    round-off, the single-vector path too; the factor is CHOLMOD's."""
    A = _laplacian(30)
    B = np.random.default_rng(1).standard_normal((A.shape[0], 12))
    f = CholeskyFactor(A)
    try:
        assert f.solver_used == "cholmod" and f.ordering_used == CHOLMOD_ORDERING
        assert f.factor_entries > A.nnz // 2  # the factor's entries, filled in beyond A's triangle
        X = f.solve(B)
        assert np.linalg.norm(A @ X - B, axis=0).max() < 1e-11 * np.linalg.norm(B, axis=0).min()
        x = f.solve(B[:, 3])
        assert np.linalg.norm(A @ x - B[:, 3]) < 1e-11 * np.linalg.norm(B[:, 3])
    finally:
        f.destroy()


@pytest.mark.parametrize("case", ["unclamped", "indefinite"])
def test_cholmod_refuses_a_matrix_that_is_not_positive_definite(case):
    """A free (unclamped) Laplacian is singular; one negative diagonal entry makes a small
    matrix indefinite, which CHOLMOD's simplicial LDL^T would factorise silently: both are
    refused, naming the likely cause."""
    A = _laplacian(8, shift=0.0 if case == "unclamped" else 0.01).tolil()
    if case == "unclamped":  # Neumann ends in every direction: constant null vector
        A = A - sp.diags(np.asarray(A.sum(axis=1)).ravel())
    else:
        A[5, 5] = -3.0
    with pytest.raises(np.linalg.LinAlgError, match="not positive definite.*clamped"):
        CholeskyFactor(A.tocsr())


def test_cholmod_and_mumps_give_the_same_modes_of_a_clamped_box():
    """The two packages factorise independently (supernodal LL^T with AMD/METIS against
    multifrontal LDL^T with PORD); the block eigen-solver on either gives ARPACK's first six
    eigenvalues of the clamped box to 1e-9."""
    from box_mesh import box_mesh
    from fem.assembly import assemble_system
    from fem.material import Material
    from fem.modes import compute_modes

    b = box_mesh(0.1, 0.03, 0.01, 0.006)
    system = assemble_system(b.nodes, b.cells, b.root_facets, Material())
    w2, _ = sla.eigsh(system.K, M=system.M, k=6, sigma=0.0)
    for solver in ("cholmod", "mumps"):
        f = CholeskyFactor(system.K, solver=solver)
        try:
            assert f.solver_used == solver
            r = compute_modes(system.K, system.M, 6, factor=f)
        finally:
            f.destroy()
        np.testing.assert_allclose(r.frequencies ** 2, np.sort(w2), rtol=1e-9, err_msg=solver)
