"""fem.modes.solve_eigenproblem asked for as many modes as its space holds: every eigenpair,
against scipy's dense eigh, and a count beyond it refused naming n_modes and the dof count."""
import numpy as np
import pytest
import scipy.linalg as sl
import scipy.sparse as sp

from fem.modes import solve_eigenproblem

N = 40


def _pencil(n=N, seed=0):
    """A random SPD pair (K, M), (n, n), dense, well conditioned."""
    rng = np.random.default_rng(seed)
    A, B = rng.standard_normal((n, n)), rng.standard_normal((n, n))
    return A @ A.T + n * np.eye(n), B @ B.T / n + np.eye(n)


def _constrained_inverse(K, fixed):
    """K^{-1} on the dof not in `fixed`, those rows held at 0 (as fem.interface's)."""
    free = np.setdiff1d(np.arange(len(K)), fixed)
    lu = sl.lu_factor(K[np.ix_(free, free)])

    def apply(B):
        X = np.zeros_like(B)
        X[free] = sl.lu_solve(lu, B[free])
        return X
    return apply, free


@pytest.mark.parametrize("n_modes", [21, 30, N])
def test_all_eigenpairs_of_the_whole_space(n_modes):
    # the Krylov basis filled the n dof and took round-off as new directions: numpy's
    # LinAlgError from about n / 2 modes on, and n_modes = n was refused as out of 1..n-1
    K, M = _pencil()
    lu = sl.lu_factor(K)
    r = solve_eigenproblem(sp.csr_matrix(K), sp.csr_matrix(M), n_modes, lambda B: sl.lu_solve(lu, B))
    np.testing.assert_allclose(r.eigenvalues, sl.eigh(K, M, eigvals_only=True)[:n_modes], rtol=1e-10)
    np.testing.assert_allclose(r.vectors.T @ M @ r.vectors, np.eye(n_modes), atol=1e-10)


@pytest.mark.parametrize("n_modes", [16, 25, N - 6])
def test_all_eigenpairs_with_fixed_dof(n_modes):
    K, M = _pencil()
    fixed = np.array([3, 17, 18, 25, 30, 39])
    apply, free = _constrained_inverse(K, fixed)
    r = solve_eigenproblem(sp.csr_matrix(K), sp.csr_matrix(M), n_modes, apply, fixed=fixed)
    ref = sl.eigh(K[np.ix_(free, free)], M[np.ix_(free, free)], eigvals_only=True)
    np.testing.assert_allclose(r.eigenvalues, ref[:n_modes], rtol=1e-10)
    assert (r.vectors[fixed] == 0).all()


def test_more_modes_than_dof_are_refused_naming_the_count():
    K, M = _pencil()
    fixed = np.array([3, 17, 18, 25, 30, 39])
    apply, _ = _constrained_inverse(K, fixed)
    with pytest.raises(ValueError, match=r"n_modes must be in 1\.\.34, got 35: the problem has 34 dof "
                                         r"\(40 rows, 6 of them fixed\)"):
        solve_eigenproblem(sp.csr_matrix(K), sp.csr_matrix(M), N - 5, apply, fixed=fixed)
    with pytest.raises(ValueError, match=r"n_modes must be in 1\.\.40, got 41"):
        solve_eigenproblem(sp.csr_matrix(K), sp.csr_matrix(M), N + 1, apply)
