"""The isola search's check of each branch with twice the harmonics
(hbm.isolas.harmonic.check_points, harmonic_checks, harmonic_verdict):

- where on a branch the points are checked, against indices derived by hand;
- the verdict against time integration (scipy's solve_ivp, another method) on the forced RL
  obstacle oscillator of test_period_doubling at N_h = 3: the main resonance's stretch is
  converged there, every point checked ends within 10 % of its amplitude after 100 periods of
  time integration; its superharmonic resonance near W = 0.743 (which needs more than 3
  harmonics) is not, and time integration from the points checked ends 30 % or more away.
"""
import numpy as np
import pytest

from hbm.isolas.harmonic import check_points, describe, harmonic_checks, harmonic_verdict
from test_period_doubling import low_harmonic_branch, obstacle_residual, ti_distance


def test_the_points_checked_lie_inside_the_longest_monotone_stretch():
    # up over points 0-4, down over 4-13 (the longest: 9 steps), up again over 13-16
    w = np.r_[np.linspace(1.0, 5.0, 5), np.linspace(4.6, 1.0, 9), np.linspace(1.5, 2.5, 3)]
    # fractions 1/4, 1/2, 3/4 of the 9 steps after point 4, rounded down: 4 + 2, 4 + 4, 4 + 6
    np.testing.assert_array_equal(check_points(w, 3), [6, 8, 10])
    np.testing.assert_array_equal(check_points(w, 1), [8])
    np.testing.assert_array_equal(check_points(np.linspace(0.0, 1.0, 9), 3), [2, 4, 6])
    np.testing.assert_array_equal(check_points(np.array([1.0, 2.0]), 3), [0])  # one step: its first point, once
    np.testing.assert_array_equal(check_points(np.array([1.0]), 2), [0])
    assert check_points(w, 0).size == 0 and check_points(np.zeros(0), 3).size == 0


def test_the_verdict_counts_the_points_that_hold():
    assert harmonic_verdict({"passed": np.array([True, True])}) == "converged"
    assert harmonic_verdict({"passed": np.array([False, False, False])}) == "not converged"
    assert harmonic_verdict({"passed": np.array([False, True])}) == "partly converged"
    assert harmonic_verdict(None) == harmonic_verdict({"passed": np.zeros(0, bool)}) == "unchecked"


@pytest.fixture(scope="module")
def low_branch():
    """The oscillator's branch at N_h = 3, continued from W = 4.6 down to 0.3 (~2100 points):
    the main resonance folds near W = 1.55-1.58, the superharmonic one zig-zags through
    small folds at W = 0.742-0.746."""
    return low_harmonic_branch(obstacle_residual()[0])


def test_a_stretch_needing_more_harmonics_is_not_converged_as_time_integration_says(low_branch):
    res, br = low_branch
    w = br.omega
    turns = np.flatnonzero(np.diff(np.sign(np.diff(w))) != 0) + 1  # the folds
    # the main resonance down to its first fold, and the superharmonic one's zig-zag: from its
    # first fold below W = 0.8 to its last fold above W = 0.74
    main = slice(0, int(turns[0]) + 1)
    sup = [int(i) for i in turns if 0.74 < w[i] < 0.8]
    zigzag = slice(sup[0], sup[-1] + 1)
    assert w[main].min() > 1.5 and len(sup) >= 10
    for part, verdict, near in ((main, "converged", lambda d: d < 0.1), (zigzag, "not converged", lambda d: d > 0.3)):
        t = {k: v for k, (v, _) in describe(res, False, checks=3)(w[part], br.x[part])["tables"]["harmonic_checks"]
             .items()}
        assert harmonic_verdict(t) == verdict and len(t["index"]) == 3, (t["omega"], t["reason"])
        assert (t["n_harmonics"] == 6).all()
        for i, ok, moved in zip(t["index"], t["passed"], t["moved"]):
            j = part.start + int(i)
            assert ok == (moved <= 0.25)
            d = ti_distance(res, br.x[j], float(w[j]))
            assert near(d), (verdict, w[j], moved, d)
    # the table as the search stores it: the same checks called directly
    direct = harmonic_checks(res, w[main], br.x[main], 3)
    np.testing.assert_array_equal(direct["index"][0], check_points(w[main], 3))
    assert direct["omega"][1] == "rad/s" and direct["cpu_time"][1] == "s"
