"""HbmSolver's rule for keeping a preconditioner.

A preconditioner is kept across Newton iterations and continuation points until a solve
with it takes more than refactor_after GMRES iterations; the next factorize then builds
a fresh one for its own J. A solver that never drops an aged preconditioner still gives
right answers (GMRES, then its fall-backs, meet the tolerance) but pays ever more Krylov
iterations at every later step of a branch: the counters must show the rule.
Each answer is also checked against numpy's dense solve of the same J.
"""
import numpy as np
import pytest

from hbm.harmonic.solver import HbmSolver
from support import forced_standin_residual, perturbed_state


def _jacobians():
    res = forced_standin_residual("dlft", n_harmonics=5, n_time=64, mu=0.15)
    return (res(perturbed_state(res, 3, 900.0), 900.0)[1], res(perturbed_state(res, 4, 880.0), 880.0)[1])


@pytest.mark.parametrize("margin,expected", [(-1, 2), (0, 1), (1000, 1)])
def test_an_aged_preconditioner_is_rebuilt_at_the_next_factorization(margin, expected):
    Ja, Jb = _jacobians()
    b = np.random.default_rng(9).standard_normal(Ja.shape[0])
    probe = HbmSolver(rtol=1e-10)
    probe.factorize(Ja).solve(b)
    n = probe.stats["last_krylov"]  # iterations of this solve with Ja's own preconditioner
    # with friction the preconditioner (single precision, no sliding terms) is not J's
    # inverse: GMRES iterates
    assert n >= 1
    solver = HbmSolver(rtol=1e-10, refactor_after=n + margin)
    xa = solver.factorize(Ja).solve(b)
    assert solver.stats["last_krylov"] == n
    xb = solver.factorize(Jb).solve(b)
    # more than refactor_after iterations (margin -1) aged it: Jb gets its own; exactly
    # refactor_after (margin 0) or fewer did not
    assert solver.stats["preconditioners"] == expected
    for J, x in ((Ja, xa), (Jb, xb)):  # right answers either way (numpy's dense solve)
        ref = np.linalg.solve(np.asarray(J), b)
        assert np.linalg.norm(x - ref) <= 1e-7 * np.linalg.norm(ref)
