"""Pieces of the compiled time-integration loop (hbm.ti.kernel) against LAPACK."""
import numpy as np
import pytest

from hbm.ti.kernel import _solve_small


@pytest.mark.parametrize("m", [1, 2, 3, 4, 5])
def test_the_small_contact_solve_agrees_with_lapack(m):
    """The active-set step solves A[:m, :m] x = b[:m] in a larger work array; m <= 3 by the
    adjugate (Cramer's rule). Random systems, and ones whose natural pivots are zero (an
    elimination would need row exchanges), must agree with numpy.linalg.solve to a few ulps
    times the condition number; the entries beyond m are left alone."""
    rng = np.random.default_rng(m)
    worst = 0.0
    for trial in range(300):
        A = rng.standard_normal((9, 9))
        if trial % 3 == 0 and m > 1:
            A[0, 0] = 0.0  # the first pivot must come from another row
        if trial % 3 == 1 and m > 2:  # zero second pivot after the first elimination: rows 1, 2 exchange
            A[1, 1] = A[1, 0] * A[0, 1] / A[0, 0] if abs(A[0, 0]) >= abs(A[1, 0]) else A[1, 1]
        b = rng.standard_normal(9)
        x = np.linalg.solve(A[:m, :m], b[:m])
        A_work, b_work = A.copy(), b.copy()
        _solve_small(A_work, b_work, m)
        worst = max(worst, np.abs(b_work[:m] - x).max() / np.abs(x).max() / np.linalg.cond(A[:m, :m]))
        np.testing.assert_array_equal(b_work[m:], b[m:])
    assert worst < 1e-14
