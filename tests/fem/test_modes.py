"""fem.modes.solve_eigenproblem against the analytic spectrum of a finite-element bar.

A fixed-fixed bar of N + 1 linear elements (length 1, EA = rho A = 1) has stiffness
tridiag(-1, 2, -1) / h and consistent mass h tridiag(1, 4, 1) / 6 on its N interior nodes;
its eigenvalues are lam_j = 6 (1 - cos t_j) / (h^2 (2 + cos t_j)), t_j = j pi / (N + 1), with
mode shapes sin(j t_i)."""
import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as sla

from fem.modes import solve_eigenproblem
from fem.symmetric import SymmetricMatrix


def _bar(N):
    h = 1.0 / (N + 1)
    K = sp.diags([-np.ones(N - 1), 2 * np.ones(N), -np.ones(N - 1)], [-1, 0, 1], format="csc") / h
    M = sp.diags([np.ones(N - 1), 4 * np.ones(N), np.ones(N - 1)], [-1, 0, 1], format="csc") * h / 6
    return K, M, h


def _exact(N, h, k):
    t = np.arange(1, k + 1) * np.pi / (N + 1)
    return 6 * (1 - np.cos(t)) / (h ** 2 * (2 + np.cos(t)))


@pytest.mark.parametrize("max_basis", [None, 20])
def test_bar_spectrum_with_and_without_restarts(max_basis):
    N, k = 3000, 8
    K, M, h = _bar(N)
    lu = sla.splu(K)
    r = solve_eigenproblem(SymmetricMatrix.from_csr(K), SymmetricMatrix.from_csr(M), k, lu.solve,
                           block_size=4, max_basis=max_basis)
    # the solver stops when no wanted Ritz value moved by more than 1e-10 in the last block
    # step; the error left is that step's change times rho / (1 - rho), rho the mode's
    # convergence factor per step, so a few times 1e-10 (1.4e-10 for mode 8 on some CPUs)
    np.testing.assert_allclose(r.eigenvalues, _exact(N, h, k), rtol=1e-9)
    np.testing.assert_allclose(r.vectors.T @ (M @ r.vectors), np.eye(k), atol=1e-10)
    i = np.arange(1, N + 1)
    for j in range(k):  # the analytic shape, up to sign and scale
        s = np.sin((j + 1) * i * np.pi / (N + 1))
        cos = abs(s @ r.vectors[:, j]) / (np.linalg.norm(s) * np.linalg.norm(r.vectors[:, j]))
        assert cos > 1 - 1e-9
    if max_basis is not None:
        # a basis of 20 columns cannot hold the 8 modes' Krylov space without restarting:
        # more block solves than the unrestarted run, and the same answer
        free = solve_eigenproblem(K, M, k, lu.solve, block_size=4)
        assert r.n_solves > free.n_solves


def test_fixed_dof_give_the_shorter_bar():
    # holding the last interior node makes a bar of N - 1 interior nodes and length N h
    N, k = 2000, 6
    K, M, h = _bar(N)
    fixed = np.array([N - 1])
    Kc = K.tolil()
    Kc[N - 1, :] = 0.0
    Kc[:, N - 1] = 0.0
    Kc[N - 1, N - 1] = 1.0
    lu = sla.splu(Kc.tocsc())

    def constrained(B):
        B = B.copy()
        B[fixed] = 0.0
        X = lu.solve(B)
        X[fixed] = 0.0
        return X

    r = solve_eigenproblem(K, M, k, constrained, fixed=fixed, block_size=4, max_basis=16)
    np.testing.assert_allclose(r.eigenvalues, _exact(N - 1, h, k), rtol=1e-10)
    assert (r.vectors[fixed] == 0).all()
