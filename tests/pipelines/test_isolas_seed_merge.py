"""pipelines.stages.isolas._merged: a seed of the period-doubled search that lies on a branch of
the first search (a known branch there) is that branch's, also when it duplicates another seed
at its Omega. Residual: R(x, w) = x (x - R1) (x - R2), the lines x = 0, R1, R2 at every Omega."""
from types import SimpleNamespace

import numpy as np

from hbm.isolas.membership import KnownBranch
from hbm.isolas.search import ON_KNOWN, Seed, search
from hbm.linalg.dense import DirectSolver
from pipelines.stages.isolas import _merged
from support import unit_search_options

R1, R2 = 0.007, 0.015
TOL = 1e-2


class ThreeLines:
    def __call__(self, x, w, jacobian=True):
        y = x[0]
        R = np.array([y * (y - R1) * (y - R2)])
        if not jacobian:
            return R
        return R, np.array([[(y - R1) * (y - R2) + y * (y - R2) + y * (y - R1)]]), np.array([0.0])


def three_lines():
    return ThreeLines(), DirectSolver()


def test_a_duplicate_seed_lying_on_a_first_search_branch_is_that_branchs():
    opts = unit_search_options(max_points=100, ds_max=0.2, newton_tol=1e-14, seed_iterations=40, tolerance=TOL)
    first = search(three_lines, [Seed(0.3, np.array([-0.002]), "to 0")], [], opts)
    (line0,) = first.branches  # x = 0 over the range
    np.testing.assert_allclose(line0.x[:, 0], 0.0, atol=1e-9)
    primary = KnownBranch(np.array([0.0, 1.0]), np.array([[1.0], [1.0]]), "primary")  # x = 1: far from all
    known = [primary, KnownBranch.of(line0.omega, line0.x, "branch 000")]
    # at Omega = 0.5: seed a lands on R2 (1.5 tolerances from x = 0: new), seed b on R1 (0.7
    # tolerances from x = 0: on the first search's branch; 0.8 from R2: a duplicate of a)
    seeds = [Seed(0.5, np.array([0.02]), "to R2"), Seed(0.5, np.array([0.0072]), "to R1")]
    second = search(three_lines, seeds, known, opts, primaries=1)
    np.testing.assert_allclose(second.corrections.x[:, 0], [R2, R1], atol=1e-12)
    assert list(second.corrections.on_known) == [-1, 1] and list(second.corrections.same_as) == [-1, 0]
    nu = SimpleNamespace(nu=1)
    _, _, seed_branch, branches = _merged([(first, nu), (second, nu)])
    # seed 0: the first search's line; 1: the period-doubled part's own branch (x = R2); 2: on
    # the first search's line x = 0, not "on the primary" (x = 1)
    assert list(seed_branch) == [0, 1, 0] and ON_KNOWN not in seed_branch
    assert branches[0][0].seeds == (0, 2)
    np.testing.assert_allclose(branches[1][0].x[:, 0], R2, atol=1e-12)
