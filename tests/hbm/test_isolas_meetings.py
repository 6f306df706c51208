"""How hbm.isolas.search tells branches apart and where they meet, on residuals whose
solution sets are known in closed form: straight lines in (x, Omega), so every branch and
every distance is exact."""
from __future__ import annotations

import numpy as np

from hbm.continuation.arclength import ContinuationOptions
from hbm.continuation.newton import NewtonOptions
from hbm.isolas.search import SearchOptions, Seed, search
from hbm.linalg.dense import DirectSolver

G = 0.005  # the second line of TwoLines


class TwoLines:
    """R(x, w) = x (x - G): the solution lines x = 0 and x = G at every Omega. Picklable."""

    def __call__(self, x, w, jacobian=True):
        R = np.array([x[0] * (x[0] - G)])
        if not jacobian:
            return R
        return R, np.array([[2 * x[0] - G]]), np.array([0.0])


def two_lines():
    return TwoLines(), DirectSolver()


def _options(x_scale):
    co = ContinuationOptions(omega_min=0.0, omega_max=1.0, ds=0.05, ds_min=1e-6, ds_max=0.1, x_scale=x_scale,
                             omega_scale=1.0, max_points=200, closed_loop_tol=1e-3,
                             newton=NewtonOptions(tol_residual=1e-12, max_iter=12))
    return SearchOptions(tolerance=1e-2, continuation=co, workers=1,
                         newton=NewtonOptions(tol_residual=1e-12, max_iter=30, line_search=True))


def test_two_solutions_at_one_omega_are_told_apart_in_the_membership_metric():
    """x_scale = 0.1: the lines x = 0 and x = G lie G / x_scale = 0.05 apart in the scaled
    metric, five tolerances: two branches, whether their seeds share an Omega or not (the
    duplicate test at one Omega measured the unscaled distance, G = 0.005 < tolerance, and
    lost the second line)."""
    for w2 in (0.5, 0.6):
        seeds = [Seed(0.5, np.array([-0.001]), "near 0"), Seed(w2, np.array([0.0062]), "near G")]
        res = search(two_lines, seeds, [], _options(0.1))
        np.testing.assert_allclose(res.corrections.x[:, 0], [0.0, G], atol=1e-12)
        assert list(res.corrections.same_as) == [-1, -1]
        assert len(res.branches) == 2 and list(res.seed_branch) == [0, 1]
        assert res.n_converged == res.n_distinct == 2
        for b, line in zip(res.branches, (0.0, G)):
            np.testing.assert_allclose(b.x[:, 0], line, atol=1e-12)
            assert b.omega.min() == 0.0 and b.omega.max() == 1.0


def test_with_unit_scale_the_two_lines_are_one_within_the_tolerance():
    """x_scale = 1: G = 0.005 is below the tolerance 0.01: one solution at Omega = 0.5."""
    seeds = [Seed(0.5, np.array([-0.001]), "near 0"), Seed(0.5, np.array([0.0062]), "near G")]
    res = search(two_lines, seeds, [], _options(1.0))
    assert list(res.corrections.same_as) == [-1, 0] and len(res.branches) == 1
    assert (res.n_converged, res.n_distinct) == (2, 1)  # two seeds converged, onto one solution


class Cross:
    """R(x, w) = (x - (w - 1/2)) (x + (w - 1/2)): the lines x = w - 1/2 and x = 1/2 - w, crossing
    at (x, Omega) = (0, 1/2) (a branch point). Picklable."""

    def __call__(self, x, w, jacobian=True):
        p, m = x[0] - (w - 0.5), x[0] + (w - 0.5)
        R = np.array([p * m])
        if not jacobian:
            return R
        return R, np.array([[p + m]]), np.array([p - m])


def cross():
    return Cross(), DirectSolver()


def test_two_crossing_branches_meet_and_are_both_bifurcated_in_either_seed_order():
    """Steps of up to 0.05 (five tolerances) put no point within the tolerance of the other
    line near the crossing: the meeting test on points alone let both halves of the second
    branch run through it (both branches "detached"). The chord from the previous point passes
    through the crossing: the second branch's half ends there, and both are bifurcated."""
    from dataclasses import replace

    opts = _options(1.0)
    opts = replace(opts, continuation=replace(opts.continuation, ds=0.02, ds_max=0.05))
    up, down = Seed(0.8, np.array([0.31]), "on x = w - 1/2"), Seed(0.2, np.array([0.29]), "on x = 1/2 - w")
    for seeds, lines in (([up, down], (1.0, -1.0)), ([down, up], (-1.0, 1.0))):
        res = search(cross, seeds, [], opts)
        first, second = res.branches
        assert [b.kind for b in res.branches] == ["bifurcated", "bifurcated"], [b.status for b in res.branches]
        for b, sign in zip(res.branches, lines):  # every point on its own line
            np.testing.assert_allclose(b.x[:, 0], sign * (b.omega - 0.5), atol=1e-9)
        assert first.omega.min() == 0.0 and first.omega.max() == 1.0  # found first: bound to bound
        assert "crossed by the branch from seed 1" in first.status
        assert "met branch 0" in second.status
        # the second ends one step past the crossing on the side it came from
        start = seeds[1].omega
        end = second.omega.max() if start < 0.5 else second.omega.min()
        assert abs(end - 0.5) <= 0.05 and (end - 0.5) * (start - 0.5) <= 0


class Ends:
    """R(x, w) = x - 0.01: the line x = 0.01, its residual NaN above Omega = 0.7, where Newton
    fails and the continuation keeps the failed last point, marked. Picklable."""

    def __call__(self, x, w, jacobian=True):
        R = np.array([x[0] - 0.01]) if w <= 0.7 else np.array([np.nan])
        if not jacobian:
            return R
        return R, np.array([[1.0]]), np.array([0.0])


def ends():
    return Ends(), DirectSolver()


class Described:
    """describe(omega, u): a count, a flag, a number and a text per point, as the stability
    monitor gives (n_unstable 0, stable, le_amplitude, stability_note). Picklable."""

    def __call__(self, omega, u):
        m = len(omega)
        return {"n_unstable": np.zeros(m, np.int64), "stable": np.ones(m, bool), "le_amplitude": u[:, 0].copy(),
                "stability_note": np.array([""] * m, dtype=object)}


def test_a_point_that_did_not_converge_has_no_description():
    """The branch's failed last point (above Omega = 0.7) was given n_unstable 0 ("no
    multiplier out") and an empty note; it has the files' unknown: -1, "not converged", nan."""
    co = ContinuationOptions(omega_min=0.0, omega_max=1.0, ds=0.05, ds_min=1e-3, ds_max=0.1, x_scale=1.0,
                             omega_scale=1.0, max_points=200, closed_loop_tol=1e-3,
                             newton=NewtonOptions(tol_residual=1e-12, max_iter=6))
    opts = SearchOptions(tolerance=1e-2, continuation=co, workers=1, newton=NewtonOptions(tol_residual=1e-12))
    res = search(ends, [Seed(0.3, np.array([0.0]), "on the line")], [], opts, describe=Described())
    (b,) = res.branches
    bad = ~np.asarray(b.converged, bool)
    assert bad.sum() == 1 and b.omega[bad][0] > 0.7  # the failed point, past the NaN edge
    ex = b.extras
    assert ex["n_unstable"][bad].tolist() == [-1] and set(ex["n_unstable"][~bad]) == {0}
    assert ex["stability_note"][bad].tolist() == ["not converged"] and set(ex["stability_note"][~bad]) == {""}
    assert not ex["stable"][bad].any() and ex["stable"][~bad].all()
    assert np.isnan(ex["le_amplitude"][bad]).all()
    np.testing.assert_allclose(ex["le_amplitude"][~bad], 0.01, atol=1e-12)


def _half(omega, x, status="closed loop"):
    from hbm.continuation.branch import Branch

    m = len(omega)
    return Branch(np.asarray(omega, float), np.asarray(x, float).reshape(m, -1), np.ones(m, bool), np.zeros(m),
                  np.zeros(m, int), np.zeros(m), np.zeros(m), status)


def test_a_half_is_back_at_its_start_only_travelling_the_way_it_left():
    """_back_at_start on exact polylines (no Newton needed: the start lies on them): a circle
    in (x, Omega) that comes round onto its start is a closed loop; a half that went out along
    a line and came back along it, past its start the other way (a branch retraced after a
    cusp), is not, though its last points pass through the start just as closely."""
    from hbm.isolas.search import _back_at_start

    options = _options(1.0)
    t = np.linspace(0.0, 2 * np.pi, 41)[:-1]
    w, x = 0.5 + 0.2 * np.sin(t), 0.2 * (1.0 - np.cos(t))
    loop = _half(np.append(w, [w[0], w[1]]), np.append(x, [x[0], x[1]]))
    assert _back_at_start(None, loop, options, None)
    out = 0.5 + 0.02 * np.arange(8)
    back = np.concatenate([out, out[-2::-1], [out[0] - 0.02]])
    assert not _back_at_start(None, _half(back, 0.1 + 0.3 * (back - 0.5)), options, None)
