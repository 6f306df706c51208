"""Edge cases of the isola search's assembly of branches (hbm.isolas.search), on systems whose
solution sets are known in closed form: a first half that "closes" one turn of a coil
later, a closed isola a branch reaching the range's bound runs into, a later seed beyond
a crossing, and pieces of one branch linked in a chain (how many branches of each kind).
The systems of test_isola_classification_edges and test_isolas_meetings are reused."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from hbm.continuation.arclength import ContinuationOptions
from hbm.continuation.newton import NewtonOptions
from hbm.isolas.membership import KnownBranch, polyline_distance
from hbm.isolas.search import SearchOptions, Seed, search
from hbm.linalg.dense import DirectSolver
from support import unit_search_options
from test_isola_classification_edges import BW, CX, RW, RX, WC, Coil, _seed, coil_options, line
from test_isola_classification_edges import _options as line_options
from test_isolas_meetings import _options as cross_options
from test_isolas_meetings import cross


def _closed_means_whole(res):
    """closed (one closed loop nothing else runs into) is never primary nor detached."""
    for b in res.branches:
        assert not b.closed or b.kind in ("isola", "bifurcated"), (b.kind, b.status)


def _covers_its_seeds(res, opts):
    """Every seed attributed to a branch lies on that branch's points (within the tolerance)."""
    co = opts.continuation
    for s, k in enumerate(res.seed_branch):
        if k >= 0:
            b = res.branches[k]
            d = polyline_distance(res.corrections.x[s], res.seeds[s].omega, KnownBranch.of(b.omega, b.x, "b"),
                                  co.x_scale, co.omega_scale)[0]
            assert d <= opts.tolerance, (s, k, d, b.status)


# -- 1. a coil in the first direction: the + half comes back near its start one turn later --
def coil_ahead():
    """test_isola_classification_edges' coil the other way round: the + half (increasing
    Omega at t = 0) is the coil, the - half rises out of the range [0, 3]."""
    return Coil(ahead=True), DirectSolver()


@pytest.mark.parametrize("workers", [1, 2])
def test_a_first_half_back_near_its_start_one_coil_turn_later_is_no_closed_loop(workers):
    """Eq. (27) measures the return relative to |x| (~1e4): the + half, continued first, comes
    back within d_min of its start one turn later (x2 off by 2 pi, 63 tolerances) and ends
    as a "closed loop". A loop closed in the first direction was not followed back: the
    branch was "isola" and closed, the - half, which leaves the range, never continued. It
    is open, and reaches the bound: detached."""
    res = search(coil_ahead, [Seed(WC, np.array([CX + RX, 0.0]), "t = 0")], [], coil_options(workers))
    (b,) = res.branches
    t = b.x[:, 1]
    np.testing.assert_allclose(b.x[:, 0], CX + RX * np.cos(t), atol=1e-6)  # on the curve
    np.testing.assert_allclose(b.omega, WC + RW * np.sin(t) + BW * np.minimum(t, 0) ** 2, atol=1e-9)
    assert t.max() == pytest.approx(2 * np.pi, abs=0.2) and t.min() < -1.0  # both ways from the seed
    assert b.omega.max() == 3.0
    assert b.status.startswith("+: closed loop") and "-: reached omega_max" in b.status
    assert (b.kind, b.closed) == ("detached", False), b.status
    assert "not a closed loop (+): it came back near its start, not onto it" in b.status


@pytest.mark.parametrize("workers", [1, 2])
def test_a_genuine_loop_is_closed_by_its_halves_meeting_on_its_far_side(workers):
    """The ring of test_isola_classification_edges, alone, seeded at its right end (angle 0
    about its centre (x1, Omega) = (2, 1.5)): the two halves run round it at the same time,
    each tested against the other's points up to _HALF_LAG behind its own, and stop past
    the far side (angle pi) where they meet: one closed isola that covers the ring once
    (the overlap of the two halves kept once), every point on it, each half with about half
    the points plus the lag where one half going all the way round took 79 (the wall time
    of a closed branch nearly halves on two processes). The same points with one worker
    (two threads taking turns) as with two processes."""
    from test_isola_classification_edges import ring

    from hbm.isolas.search import _HALF_LAG

    co = ContinuationOptions(omega_min=0.0, omega_max=3.0, ds=0.02, ds_min=1e-6, ds_max=0.05, x_scale=1.0,
                             omega_scale=1.0, max_points=2000, closed_loop_tol=1e-3,
                             newton=NewtonOptions(tol_residual=1e-12, max_iter=12))
    opts = SearchOptions(tolerance=1e-2, continuation=co, workers=workers,
                         newton=NewtonOptions(tol_residual=1e-12, max_iter=30, line_search=True))
    res = search(ring, [Seed(1.5, np.array([2.51, 1.5]), "right")], [], opts)
    (b,) = res.branches
    assert (b.kind, b.closed) == ("isola", True), b.status
    assert b.status.startswith("+: closed loop (the halves met); -:"), b.status
    np.testing.assert_allclose((b.x[:, 0] - 2.0) ** 2 + (b.omega - 1.5) ** 2, 0.25, atol=1e-10)
    np.testing.assert_allclose(b.x[:, 1], 0.25 * b.x[:, 0] ** 2, atol=1e-10)
    angle = np.unwrap(np.arctan2(b.omega - 1.5, b.x[:, 0] - 2.0))
    start = int(np.argmin(np.abs(b.x[:, 0] - 2.5) + np.abs(b.omega - 1.5)))
    # once round: the ends within a step or two of each other (ds_max = 0.05 on a radius of 0.5)
    span = abs(angle[-1] - angle[0])
    assert 2 * np.pi - 0.2 < span < 2 * np.pi + 0.2, span
    plus = len(b.omega) - start  # the + half's points, the seed included
    minus_computed = res.n_points_computed + 1 - plus
    assert plus <= 63 / 2 + _HALF_LAG + 3 and minus_computed <= 63 / 2 + _HALF_LAG + 3, (plus, minus_computed)
    assert abs(angle[start] - angle[-1]) > np.pi  # the + half went past the far side


class Cup:
    """The parabola Omega = 1 + x^2: a fold (a minimum in Omega) at x = 0. Picklable."""

    def __call__(self, x, w, jacobian=True):
        R = np.array([w - 1.0 - x[0] ** 2])
        if not jacobian:
            return R
        return R, np.array([[-2.0 * x[0]]]), np.array([1.0])


def cup():
    return Cup(), DirectSolver()


@pytest.mark.parametrize("workers", [1, 2])
def test_halves_leaving_a_seed_at_a_fold_in_small_steps_do_not_meet(workers):
    """Seeded at the fold's tip, the halves leave it in opposite directions (+x and -x) with
    steps of a hundredth of the tolerance: for the first points tested each half's chord runs
    against the other's first segments within the tolerance, as where a loop's halves meet. The stretch
    between the two places (through the seed) stays within the tolerance of them, so they
    do not meet: both rise to omega_max, one open branch through the fold."""
    from hbm.isolas.search import _HALF_LAG

    co = ContinuationOptions(omega_min=0.5, omega_max=2.0, ds=1e-4, ds_min=1e-6, ds_max=0.05, x_scale=1.0,
                             omega_scale=1.0, max_points=2000, grow=1.05, closed_loop_tol=1e-3,
                             newton=NewtonOptions(tol_residual=1e-12, max_iter=12))
    opts = SearchOptions(tolerance=1e-2, continuation=co, workers=workers,
                         newton=NewtonOptions(tol_residual=1e-12, max_iter=30, line_search=True))
    res = search(cup, [Seed(1.0, np.array([0.0]), "tip")], [], opts)
    (b,) = res.branches
    assert b.status == "+: reached omega_max; -: reached omega_max", b.status
    assert (b.kind, b.closed) == ("detached", False)
    np.testing.assert_allclose(b.omega, 1.0 + b.x[:, 0] ** 2, atol=1e-10)
    assert b.x[:, 0].min() == pytest.approx(-1.0) and b.x[:, 0].max() == pytest.approx(1.0)
    start = int(np.argmin(np.abs(b.x[:, 0])))
    # the points each half's chords were first tested against (_HALF_LAG behind) within the tolerance of the seed
    lag = _HALF_LAG + 5
    assert np.abs(b.x[start - lag:start + lag + 1, 0]).max() < 1e-2


class BrokenCup(Cup):
    """Cup, whose residual raises past x = -0.5 (the - half's side only). Picklable."""

    def __call__(self, x, w, jacobian=True):
        if x[0] < -0.5:
            raise FloatingPointError(f"broken residual at x = {x[0]:.3f}")
        return super().__call__(x, w, jacobian)


def broken_cup():
    return BrokenCup(), DirectSolver()


def broken_search(workers: int) -> None:
    """A search on BrokenCup whose + half would rise for ever (run in a subprocess by the
    test below)."""
    co = ContinuationOptions(omega_min=0.5, omega_max=1e12, ds=1e-2, ds_min=1e-6, ds_max=0.05, x_scale=1.0,
                             omega_scale=1.0, max_points=10**9, closed_loop_tol=1e-3,
                             newton=NewtonOptions(tol_residual=1e-12, max_iter=12))
    opts = SearchOptions(tolerance=1e-2, continuation=co, workers=workers,
                         newton=NewtonOptions(tol_residual=1e-12, max_iter=30, line_search=True))
    search(broken_cup, [Seed(1.0, np.array([0.0]), "tip")], [], opts)


@pytest.mark.parametrize("workers", [1, 2])
def test_a_half_that_raises_fails_the_search_with_its_own_error(workers):
    """The two halves wait for each other point by point: when one raises, the other stops
    at its next point (here it would go on for ever), and the search fails with the error
    of the half that raised, not the other's "my other half failed"."""
    import subprocess
    import sys
    from pathlib import Path

    here = Path(__file__).resolve().parent
    code = (f"import sys; sys.path[:0] = [{str(here)!r}, {str(here.parent)!r}]; "
            f"from test_isola_search_edges import broken_search; broken_search({workers})")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=240,
                         cwd=here.parents[1])
    assert run.returncode != 0
    last = run.stderr.strip().splitlines()[-1]
    assert last.startswith("FloatingPointError: broken residual at x = -0.5"), run.stderr[-2000:]


# -- 2. a closed isola that a branch reaching the range's bound runs into ------------------
GAP = 0.5e-2  # half the tolerance


class RingAndLine:
    """x2 = 0: the ring (x1 - 2)^2 + (Omega - 1.5)^2 = 1/4; x2 = GAP: the line x1 = 1.5 at every
    Omega, which touches the ring's leftmost point (1.5, 0, 1.5) at the distance GAP, below
    the tolerance: the line runs into the ring there (tangentially). R = (x2 (x2 - GAP),
    (1 - s) ring + s (x1 - 1.5)), s = x2 / GAP: the two never meet, and a continuation
    stays on its own. Picklable."""

    def __call__(self, x, w, jacobian=True):
        a = (x[0] - 2.0) ** 2 + (w - 1.5) ** 2 - 0.25
        s = x[1] / GAP
        R = np.array([x[1] * (x[1] - GAP), (1 - s) * a + s * (x[0] - 1.5)])
        if not jacobian:
            return R
        J = np.array([[0.0, 2 * x[1] - GAP], [(1 - s) * 2 * (x[0] - 2.0) + s, (x[0] - 1.5 - a) / GAP]])
        return R, J, np.array([0.0, (1 - s) * 2 * (w - 1.5)])


def ring_and_line():
    return RingAndLine(), DirectSolver()


def _ring_options():
    """Steps of at most 0.05 round the ring (radius 0.5) over Omega in [0, 3], the tolerance 1e-2."""
    return unit_search_options(max_points=2000, ds_max=0.05, ds=0.02, omega_max=3.0)


RING_SEED = Seed(1.5, np.array([2.51, 0.0]), "ring's top")
LINE_SEED = Seed(0.5, np.array([1.49, 0.006]), "line")


def test_a_closed_isola_a_branch_reaching_the_bound_runs_into_is_no_closed_loop():
    """The ring, found first, closes; the line then runs into it and reaches both bounds.
    The ring's record became "detached" (the joined kind) and stayed closed: a closed loop
    cannot be detached. The line and the ring are one set, which reaches the bounds and is
    no closed loop: detached, not closed, as when the line is found first (the ring then
    runs into it, and its record is the line's)."""
    opts = _ring_options()
    res = search(ring_and_line, [RING_SEED, LINE_SEED], [], opts)
    (b,) = res.branches
    np.testing.assert_allclose((b.x[:, 0] - 2.0) ** 2 + (b.omega - 1.5) ** 2, 0.25, atol=1e-9)  # the ring's points
    assert b.status.startswith("+: closed loop") and "joined by the branch from seed 1: detached" in b.status
    assert (b.kind, b.closed) == ("detached", False), b.status
    assert "not a closed loop as a whole: the branch from seed 1 runs into it" in b.status
    assert list(res.seed_branch) == [0, 0] and res.kind_counts() == {"detached": 1}
    _closed_means_whole(res)
    other = search(ring_and_line, [LINE_SEED, RING_SEED], [], opts)
    (c,) = other.branches
    assert (c.kind, c.closed) == ("detached", False) and c.omega.min() == 0.0 and c.omega.max() == 3.0


def test_a_closed_isola_a_stretch_of_it_runs_into_stays_closed():
    """A later seed on the ring that the membership test misses (refine_ratio 1e-6: the
    polyline distance alone; the seed lies between two vertices, farther than the
    tolerance from their chord) is continued, and both its halves run into the ring: it
    is a stretch of it, which stays one closed isola."""
    opts = replace(_ring_options(), refine_ratio=1e-6)
    opts = replace(opts, continuation=replace(opts.continuation, ds=0.2, ds_max=0.2))  # chords 0.2: sagitta 0.01
    first = search(ring_and_line, [RING_SEED], [], opts)
    (ring,) = first.branches
    assert (ring.kind, ring.closed) == ("isola", True)
    # the point of the ring midway between two vertices near the bottom (Omega < 1.5)
    th = np.arctan2(ring.omega - 1.5, ring.x[:, 0] - 2.0)
    k = int(np.argmin(np.abs(th + 2.0)))
    mid = 0.5 * (th[k] + th[k + 1])
    seed = Seed(1.5 + 0.5 * np.sin(mid), np.array([2.0 + 0.5 * np.cos(mid), 0.0]), "between two vertices")
    co = opts.continuation
    assert polyline_distance(seed.x, seed.omega, KnownBranch.of(ring.omega, ring.x, "ring"), co.x_scale,
                             co.omega_scale)[0] > opts.tolerance
    res = search(ring_and_line, [RING_SEED, seed], [], opts)
    assert res.n_continued == 2 and list(res.seed_branch) == [0, 0], [b.status for b in res.branches]
    (b,) = res.branches
    assert (b.kind, b.closed) == ("isola", True), b.status


# -- 3. a later seed beyond a crossing -----------------------------------------------------
def _cross_options():
    opts = cross_options(1.0)
    return replace(opts, continuation=replace(opts.continuation, ds=0.02, ds_max=0.05))


CROSS_SEEDS = [Seed(0.8, np.array([0.31]), "on x = w - 1/2"), Seed(0.2, np.array([0.29]), "on x = 1/2 - w"),
               Seed(0.9, np.array([-0.41]), "on x = 1/2 - w, beyond the crossing")]


def test_a_seed_beyond_a_crossing_gives_a_branch_that_covers_it():
    """The second branch (x = 1/2 - w from 0.2) ends one step past the crossing with the first.
    The third seed, on its line beyond the crossing, came back towards it, ran into that last
    step and merged into the second branch, its points dropped: it was attributed to a branch
    ending near Omega = 0.51, and the line from there to omega_max was lost. It crosses the
    first branch there too, and is a bifurcated branch of its own."""
    opts = _cross_options()
    res = search(cross, CROSS_SEEDS, [], opts)
    assert list(res.seed_branch) == [0, 1, 2], [b.status for b in res.branches]
    third = res.branches[2]
    np.testing.assert_allclose(third.x[:, 0], 0.5 - third.omega, atol=1e-9)
    assert third.omega.max() == 1.0 and abs(third.omega.min() - 0.5) <= 0.05
    assert third.kind == "bifurcated" and "met branch 0" in third.status
    _covers_its_seeds(res, opts)


def test_a_resumed_search_leaves_out_the_step_past_a_crossing_alike():
    """Resumed with the first two branches from disk, the third seed gives the same branch."""
    opts = _cross_options()
    full = search(cross, CROSS_SEEDS, [], opts)
    again = search(cross, CROSS_SEEDS, [], opts, corrections=full.corrections, branches=full.branches[:2])
    assert again.n_continued == 1
    np.testing.assert_array_equal(again.seed_branch, full.seed_branch)
    np.testing.assert_array_equal(again.branches[2].omega, full.branches[2].omega)


# -- 4. pieces of one branch ---------------------------------------------------------------
def test_pieces_linked_in_a_chain_all_take_the_kind_of_the_whole_and_count_once():
    """Pieces of the line x = 0.3 on [-1, 1.5] (5 points a half): A (0.0) and B (0.6) are
    linked by C (0.3); D (1.3) reaches omega_max; E (0.95) links B and D. The five are one
    branch reaching the bound: B and D were made detached, A, linked to B before, stayed an
    isola. Three records are one detached branch."""
    opts = line_options()
    opts = replace(opts, continuation=replace(opts.continuation, omega_min=-1.0, omega_max=1.5))
    seeds = [_seed(0.0, "A"), _seed(0.6, "B"), _seed(0.3, "C"), _seed(1.3, "D"), _seed(0.95, "E")]
    res = search(line, seeds, [], opts)
    assert list(res.seed_branch) == [0, 1, 1, 2, 2]
    assert [b.kind for b in res.branches] == ["detached"] * 3, [b.status for b in res.branches]
    assert "detached: the branch it is one with was joined by the branch from seed 4" in res.branches[0].status
    assert res.groups == ((0, 1, 2),)
    assert res.kind_counts() == {"detached": 1}
    # resumed from the first two records (A's and B's, linked by C), the same
    again = search(line, seeds, [], opts, corrections=res.corrections, branches=res.branches[:2])
    assert again.groups == ((0, 1, 2),) and again.kind_counts() == {"detached": 1}


def test_two_linked_pieces_count_as_one_branch():
    """test_isola_classification_edges' A, B, C: two records, one detached branch."""
    res = search(line, [_seed(0.3, "A"), _seed(0.9, "B"), _seed(0.6, "C")], [], line_options())
    assert [b.kind for b in res.branches] == ["detached", "detached"]
    assert res.groups == ((0, 1),) and res.kind_counts() == {"detached": 1}
    alone = search(line, [_seed(0.3, "A"), _seed(0.9, "B")], [], line_options())
    assert alone.groups == ((0,), (1,)) and alone.kind_counts() == {"isola": 1, "detached": 1}


def test_a_crossed_piece_makes_the_pieces_it_is_one_with_bifurcated():
    """On Cross (x = w - 1/2 and x = 1/2 - w, crossing at Omega = 0.5), 9 points a half: A (0.1)
    and B (0.65), pieces of x = w - 1/2, linked by C (0.375); D (0.3), on the other line, crosses
    B. B was made bifurcated, A, one branch with it, stayed detached."""
    opts = replace(_cross_options(), continuation=replace(_cross_options().continuation, max_points=9))
    seeds = [Seed(0.1, np.array([-0.39]), "A"), Seed(0.65, np.array([0.16]), "B"), Seed(0.375, np.array([-0.12]), "C"),
             Seed(0.3, np.array([0.19]), "D")]
    res = search(cross, seeds, [], opts)
    assert res.groups[0] == (0, 1), [b.status for b in res.branches]
    assert "crossed by the branch from seed 3" in res.branches[1].status
    assert [b.kind for b in res.branches[:2]] == ["bifurcated", "bifurcated"], [b.status for b in res.branches]
    assert "crossed by the branch from seed 3 (through branch 1)" in res.branches[0].status
