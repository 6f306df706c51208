"""The seeds' stall rule (hbm.continuation.newton.stalled, NewtonOptions.stall_iterations) on
scalar problems whose Newton iterates are known in closed form."""
from __future__ import annotations

import numpy as np

from hbm.continuation.newton import NewtonOptions, newton_iterate

STALL = NewtonOptions(tol_residual=1e-10, max_iter=40, stall_iterations=3, stall_factor=0.1)


def _scalar(R, dR):
    """linearise for a scalar residual R(x) with derivative dR(x)."""
    def linearise(y):
        r = R(y[0])
        return abs(r), lambda: np.array([-r / dR(y[0])])
    return linearise


def test_a_residual_without_a_root_stalls_after_three_iterations():
    """x^2 + 1 >= 1 everywhere: no iterate lowers |R| tenfold below its start, so the run is
    given up at the fourth evaluation (three solves), not at max_iter."""
    sol = newton_iterate(np.array([0.3]), _scalar(lambda x: x * x + 1.0, lambda x: 2.0 * x), STALL)
    assert not sol.converged
    assert sol.reason.startswith("stalled")
    assert sol.iterations == 3


def test_a_slow_root_is_not_a_stall():
    """x^3: Newton's iterate is 2 x / 3, so |R| falls by (2/3)^3 = 0.30 an iteration and by
    0.026 over three: never three in a row without a tenfold fall. It converges where the
    closed form says: the first n with (2/3)^(3 n) <= 1e-10, n = 19."""
    sol = newton_iterate(np.array([1.0]), _scalar(lambda x: x ** 3, lambda x: 3.0 * x * x), STALL)
    assert sol.converged, sol.reason
    assert sol.iterations == int(np.ceil(np.log(1e-10) / (3 * np.log(2.0 / 3.0))))
    assert abs(sol.x[0] - (2.0 / 3.0) ** sol.iterations) < 1e-15


def test_a_plateau_of_two_iterations_passes_three_and_fails_two():
    """|R| = 1, 0.5, 0.4, 0.01: two iterations without a tenfold fall, then one. The rule of
    three lets the run reach 0.01; a rule of two gives it up at 0.4."""
    norms = iter([1.0, 0.5, 0.4, 0.01, 1e-12])

    def linearise(y):
        return next(norms), lambda: np.zeros(1)

    sol = newton_iterate(np.zeros(1), linearise, STALL)
    assert sol.converged and sol.iterations == 4
    norms = iter([1.0, 0.5, 0.4, 0.01, 1e-12])
    two = NewtonOptions(tol_residual=1e-10, max_iter=40, stall_iterations=2, stall_factor=0.1)
    sol = newton_iterate(np.zeros(1), linearise, two)
    assert not sol.converged and sol.iterations == 2 and sol.residual_norm == 0.4


def test_the_reference_is_the_best_residual_so_far():
    """|R| = 1, 0.05, then 0.08, 0.07, 0.06: three iterations above a tenth of the best (0.05),
    though below a tenth of the start: given up there, at the fifth evaluation."""
    norms = iter([1.0, 0.05, 0.08, 0.07, 0.06, 1e-12])

    def linearise(y):
        return next(norms), lambda: np.zeros(1)

    sol = newton_iterate(np.zeros(1), linearise, STALL)
    assert not sol.converged and sol.iterations == 4 and sol.residual_norm == 0.06
