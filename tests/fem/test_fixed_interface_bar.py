"""fem.interface.compute_interface_basis against the closed-form Craig-Bampton basis of a
finite-element bar.

A bar of N linear elements (length 1, EA = 2, rho A = 1, h = 1 / N), clamped at x = 0, with
its tip node x = 1 as the only boundary dof:
- constraint mode: the static response to a unit tip displacement with the root clamped,
  u(x) = x, exact at the nodes of linear elements: Psi_i = x_i = i h (EA != 1, so that the
  tip compliance 1 / EA that scales K^{-1} e_tip into it is not 1);
- fixed-interface modes: the bar fixed at both ends, N - 1 interior nodes, stiffness
  EA tridiag(-1, 2, -1) / h and consistent mass h tridiag(1, 4, 1) / 6; eigenvalues
  lam_j = 6 EA (1 - cos t_j) / (h^2 (2 + cos t_j)), t_j = j pi / N, shapes sin(j t_i)
  (a discrete sine transform diagonalises both matrices).
"""
import numpy as np
import pytest
import scipy.sparse as sp

from fem.cholesky import CholeskyFactor
from fem.interface import compute_interface_basis

N = 40
H = 1.0 / N
EA = 2.0


def _clamped_free_bar():
    # free dof: nodes 1..N (node 0 clamped); node N is the free tip (one element only)
    main_k = np.full(N, 2.0)
    main_k[-1] = 1.0
    main_m = np.full(N, 4.0)
    main_m[-1] = 2.0
    K = sp.diags([-np.ones(N - 1), main_k, -np.ones(N - 1)], [-1, 0, 1], format="csr") * (EA / H)
    M = sp.diags([np.ones(N - 1), main_m, np.ones(N - 1)], [-1, 0, 1], format="csr") * H / 6
    return K, M


@pytest.fixture(scope="module")
def basis():
    K, M = _clamped_free_bar()
    factor = CholeskyFactor(K)
    try:
        yield K, M, compute_interface_basis(K, M, np.array([N - 1]), 5, factor)
    finally:
        factor.destroy()


def test_constraint_mode_is_the_linear_static_shape(basis):
    _, _, b = basis
    assert b.constraint_modes.shape == (N, 1)
    x = H * np.arange(1, N + 1)
    np.testing.assert_allclose(b.constraint_modes[:, 0], x, rtol=0, atol=1e-12)


def test_fixed_interface_modes_are_those_of_the_fixed_fixed_bar(basis):
    K, M, b = basis
    t = np.arange(1, 6) * np.pi / N
    lam = 6 * EA * (1 - np.cos(t)) / (H ** 2 * (2 + np.cos(t)))
    np.testing.assert_allclose(b.fixed_interface_frequencies, np.sqrt(lam), rtol=1e-9)
    X = b.fixed_interface_modes
    assert X.shape == (N, 5)
    np.testing.assert_array_equal(X[N - 1], 0.0)  # the boundary (tip) dof held
    # mass-normalised: X^T M X = I (kg^-1/2 units)
    np.testing.assert_allclose(X.T @ (M @ X), np.eye(5), atol=1e-10)
    # shapes sin(j t_i) on the interior nodes i = 1 .. N - 1, up to sign, normalised by hand:
    # sum_i sin^2(j t_i) = N / 2 and M's quadratic form on a sine is (h / 6)(4 + 2 cos t_j) N / 2
    i = np.arange(1, N)
    for j in range(5):
        s = np.sin((j + 1) * np.pi * i / N)
        s /= np.sqrt(H / 6 * (4 + 2 * np.cos(t[j])) * N / 2)
        x = X[:N - 1, j]
        # the eigen-solve stops on the eigenvalues (tol 1e-10): the vectors are right to ~1e-8
        np.testing.assert_allclose(np.sign(x @ s) * x, s, atol=1e-6)
