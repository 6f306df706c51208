"""Seeds that are solutions of a model (the sweep's orbits, DLFT's solutions as RL's seeds)
get the search's patient Newton (SearchOptions.model_newton: more iterations, no stall rule);
eq. (31)'s guesses keep the cheap one. The residual R(x) = x - 1/2 reports a Jacobian twice
the true slope (as a kink's one-sided slope can be), so Newton converges linearly, halving
||R|| per iteration: the stall rule (tenfold in three iterations) gives up at once, 32
patient iterations reach 1e-10."""
from dataclasses import replace

import numpy as np
import pytest

from hbm.continuation.newton import NewtonOptions
from hbm.isolas.harmonic import search_options
from hbm.isolas.options import IsolaOptions
from hbm.isolas.search import Seed, correct_seeds
from hbm.linalg.dense import DirectSolver
from hbm.options import HbmOptions
from support import unit_search_options


class HalvingNewton:
    def __call__(self, x, w, jacobian=True):
        R = np.array([x[0] - 0.5])
        if not jacobian:
            return R
        return R, np.array([[2.0]]), np.array([0.0])


def halving():
    return HalvingNewton(), DirectSolver()


def test_a_seed_of_a_model_is_corrected_without_the_stall_rule():
    opts = unit_search_options(max_points=10, ds_max=0.2, newton_tol=1e-10)
    cheap = NewtonOptions(tol_residual=1e-10, max_iter=12, line_search=True, max_halvings=4, stall_iterations=3)
    opts = replace(opts, newton=cheap, model_newton=replace(cheap, max_iter=60, stall_iterations=None))
    seeds = [Seed(0.5, np.array([0.8]), "modal j=1 k=1"), Seed(0.5, np.array([0.8]), "ti class 1", of_model=True),
             Seed(0.7, np.array([0.8]), "modal j=1 k=2 via DLFT", of_model=True)]
    c = correct_seeds(halving, seeds, [], opts)
    assert list(c.converged) == [False, True, True]
    assert c.iterations[0] <= 4  # given up after three iterations without a tenfold fall
    # 0.3 / 2^k <= 1e-10: k = 32
    assert list(c.iterations[1:]) == [32, 32]
    np.testing.assert_allclose(c.x[1:, 0], 0.5, atol=1e-10)
    assert c.same_as[1] == -1 and np.isnan(c.x[0]).all()
    # why the first gave up, and where: ||R|| = 0.3 / 2^k after its k iterations
    assert c.reason[0].startswith("stalled at omega=0.5:") and c.reason[1:] == ("", "")
    np.testing.assert_allclose(c.residual_norm[0], 0.3 / 2 ** c.iterations[0], rtol=1e-12)
    assert (c.residual_norm[1:] <= 1e-10).all()
    # without a model Newton every seed takes the cheap one
    c = correct_seeds(halving, seeds, [], replace(opts, model_newton=None))
    assert not c.converged.any()


def test_rl_seeds_from_dlft_solutions_are_of_a_model():
    from types import SimpleNamespace

    from hbm.isolas.harmonic import rl_seeds
    from hbm.isolas.search import Corrections

    seeds = (Seed(500.0, np.zeros(3), "modal j=1 k=5 A=0.001"), Seed(500.0, np.zeros(3), "ti class 1"),
             Seed(600.0, np.zeros(3), "modal j=2 k=3 A=0.01"))
    x = np.arange(9.0).reshape(3, 3)
    c = Corrections(np.array([True, True, False]), np.zeros(3, int), np.full(3, -1), np.full(3, -1), x)
    opts = search_options(HbmOptions(), IsolaOptions())
    (sd,) = rl_seeds(SimpleNamespace(corrections=c, seeds=seeds), opts)  # TI seeds RL gets itself; 600 failed
    assert sd.of_model and sd.origin.endswith("via DLFT") and sd.omega == 500.0
    np.testing.assert_array_equal(sd.x, x[0])


def test_rl_gets_one_seed_per_dlft_solution_at_a_speed_on_the_primary_too():
    """The search leaves duplicates on a known branch unmarked (same_as -1): around the
    primary, dozens of seeds land on its one point at a speed. RL gets one of them; a
    solution just beyond the tolerance (in the scaled metric, x_scale per unknown), and the
    same solution at another speed, are seeds of their own."""
    from types import SimpleNamespace

    from hbm.isolas.harmonic import rl_seeds
    from hbm.isolas.search import Corrections

    opts = search_options(HbmOptions(), IsolaOptions())
    step = opts.tolerance * opts.continuation.x_scale  # one tolerance along the first unknown
    base = np.full(4, 1e-3)
    xs = [base, base + 0.5 * np.array([step, 0, 0, 0]), base + 1.5 * np.array([step, 0, 0, 0]), base, base]
    omegas = [700.0, 700.0, 700.0, 700.0, 740.0]
    seeds = tuple(Seed(w, np.zeros(4), f"modal j=1 k={k + 1} A=0.001 + primary DLFT NFRC 1/1")
                  for k, w in enumerate(omegas))
    same_as = np.array([-1, -1, -1, 0, -1])  # the 4th marked by the search (a solution off the primary)
    c = Corrections(np.ones(5, bool), np.zeros(5, int), np.array([0, 0, 0, -1, 0]), same_as, np.array(xs))
    got = rl_seeds(SimpleNamespace(corrections=c, seeds=seeds), opts)
    assert [(s.omega, s.origin.split()[2]) for s in got] == [(700.0, "k=1"), (700.0, "k=3"), (740.0, "k=5")]


def test_rl_gets_points_spread_along_each_dlft_branch():
    """Besides DLFT's seed solutions, rl_branch_seeds converged points of each DLFT branch,
    evenly spaced by index among its converged points (its halves' failed ends left out),
    each point once, as seeds of a model at the point's own speed."""
    from types import SimpleNamespace

    from hbm.isolas.harmonic import rl_seeds
    from hbm.isolas.search import Corrections, FoundBranch

    def branch(omega, converged):
        n = len(omega)
        return FoundBranch(np.array(omega, float), np.arange(2.0 * n).reshape(n, 2) + omega[0],
                           np.array(converged), "isola", False, "", 0, (0,))

    # converged points 1..8 of 10: the 1st, the 4.5th rounded to even and the 8th of them
    a = branch(np.arange(500.0, 510.0), [False] + [True] * 8 + [False])
    b = branch([700.0, 701.0, 702.0], [True, False, True])  # two converged: each once
    c = Corrections(np.zeros(0, bool), np.zeros(0, int), np.zeros(0, int), np.zeros(0, int), np.zeros((0, 2)))
    dlft = SimpleNamespace(corrections=c, seeds=(), branches=(a, b))
    opts = search_options(HbmOptions(), IsolaOptions())
    got = rl_seeds(dlft, opts, 3)
    assert [(s.omega, s.origin) for s in got] == [
        (501.0, "DLFT branch 000 point 2/10"), (505.0, "DLFT branch 000 point 6/10"),
        (508.0, "DLFT branch 000 point 9/10"), (700.0, "DLFT branch 001 point 1/3"),
        (702.0, "DLFT branch 001 point 3/3")]
    assert all(s.of_model for s in got)
    np.testing.assert_array_equal(got[1].x, a.x[5])
    np.testing.assert_array_equal(got[4].x, b.x[2])
    assert rl_seeds(dlft, opts, 0) == []
    assert len(rl_seeds(dlft, opts, 100)) == 8 + 2
    for bad in (-1, 2.5):
        with pytest.raises(ValueError, match="rl_branch_seeds"):
            IsolaOptions(rl_branch_seeds=bad)


def test_the_stage_options_give_model_seeds_the_patient_newton():
    o = search_options(HbmOptions(), IsolaOptions(model_seed_iterations=45))
    assert o.newton.stall_iterations == 3 and o.newton.max_iter == 12
    assert o.model_newton.stall_iterations is None and o.model_newton.max_iter == 45
    assert o.model_newton.line_search and o.model_newton.tol_residual == o.newton.tol_residual
    with pytest.raises(ValueError, match="model_seed_iterations"):
        IsolaOptions(model_seed_iterations=0)
