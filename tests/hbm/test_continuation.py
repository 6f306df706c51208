"""Arc-length continuation against systems with known solution sets (tests/hbm/systems.py)."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from hbm.continuation.arclength import ContinuationOptions, continue_branch
from hbm.continuation.branch import (STATUS_CLOSED_LOOP, STATUS_MAX_POINTS, STATUS_OMEGA_MAX, STATUS_OMEGA_MIN,
                                     STATUS_START_FAILED, STATUS_STEP_FLOOR)
from hbm.continuation.newton import NewtonOptions, newton_solve
from hbm.linalg.dense import DirectSolver
from systems import Circle, Duffing1, Hairpin, Helix, Vee, Wall, Wave, ZigZag

TOL = 1e-10  # residual tolerance of every run here
DS_MAX = 0.05


def opts(lo, hi, **kw):
    kw.setdefault("ds", 0.02)
    kw.setdefault("ds_max", DS_MAX)
    return ContinuationOptions(lo, hi, newton=NewtonOptions(tol_residual=TOL), **kw)


def reversals(omega):
    s = np.sign(np.diff(omega))
    return np.flatnonzero(s[1:] != s[:-1]) + 1  # indices of the turning points in omega


def gaps(branch, x_scale=1.0, omega_scale=1.0):
    """Scaled distances between consecutive points."""
    return np.hypot(np.linalg.norm(np.diff(branch.x, axis=0) / x_scale, axis=1), np.diff(branch.omega) / omega_scale)


# ---------------------------------------------------------------- Duffing resonance
@pytest.fixture(scope="module")
def duffing():
    return Duffing1(zeta=0.02, gamma=1.0, force=0.1)


@pytest.mark.parametrize("predictor", ["secant", "quadratic"])
@pytest.mark.parametrize("direction, omega0, bound, status", [(1, 0.5, 2.5, STATUS_OMEGA_MAX),
                                                              (-1, 2.5, 0.5, STATUS_OMEGA_MIN)])
def test_duffing_nfrc_through_both_folds(duffing, direction, omega0, bound, status, predictor):
    b = continue_branch(duffing, np.zeros(2), omega0, opts(0.5, 2.5, direction=direction, predictor=predictor))
    assert b.status == status and b.omega[-1] == bound  # landed exactly on the bound
    assert b.converged.all()
    A = np.hypot(b.x[:, 0], b.x[:, 1])

    # Every point is on the exact 1-harmonic branch: |Z x| = |F + R|, so the
    # frequency-amplitude relation |Z x|^2 - F^2 is bounded by 2 F |R| + |R|^2.
    G = duffing.relation(A, b.omega)
    bound_G = 2 * duffing.force * b.residual_norm + b.residual_norm ** 2
    assert np.all(np.abs(G) <= 1.01 * bound_G + 1e-15)

    # Hardening resonance: omega reverses exactly twice, at the two folds, without jumping
    # (consecutive points lie on the arc-length sphere, <= ds_max apart).
    turns = reversals(b.omega)
    assert len(turns) == 2
    assert gaps(b).max() <= DS_MAX * (1 + 1e-6)
    f_hi, f_lo = max(duffing.folds()), min(duffing.folds())
    w_turn = np.sort(b.omega[turns])
    # A sampled turning point is on the curve next to the fold: never past it, and within
    # the sag of one step, ~ omega'' (ds_max/2)^2 / 2 < 1e-3 here.
    assert f_lo - 1e-8 <= w_turn[0] <= f_lo + 1e-3
    assert f_hi - 1e-3 <= w_turn[1] <= f_hi + 1e-8
    # The upper sheet is followed first when going up, the lower one first when going down.
    assert b.omega[turns[0]] == pytest.approx(f_hi if direction > 0 else f_lo, abs=1e-3)

    # Peak: exact for 1-harmonic HB (Duffing1.peak); no point exceeds it, the best point
    # is within the sag of a ds_max step (A'' ~ 1 per unit arc length -> ~3e-4).
    A_peak, w_peak = duffing.peak()
    assert A.max() <= A_peak * (1 + 1e-8)
    assert A.max() == pytest.approx(A_peak, rel=1e-3)
    assert b.omega[np.argmax(A)] == pytest.approx(w_peak, abs=2e-3)


def test_quadratic_predictor_saves_newton_iterations(duffing):
    """The parabola through three points errs by O(ds^3) against the secant's O(ds^2): at
    the same (capped) steps the corrections start closer and need fewer iterations in all."""
    its = {}
    for pred in ("secant", "quadratic"):
        b = continue_branch(duffing, np.zeros(2), 0.5, opts(0.5, 2.5, predictor=pred, ds_max=0.2))
        assert b.status == STATUS_OMEGA_MAX and b.converged.all()
        its[pred] = int(b.iterations.sum())
    assert its["quadratic"] < 0.9 * its["secant"]


def test_slow_corrections_are_refused_above_the_step_floor(duffing):
    """iter_reject = 2: a correction that needs more iterations is refused and the step halved,
    so every point above the step floor converged in at most 2 (without the cap, some took
    more at the same steps), and the branch is still the exact one through both folds."""
    base = continue_branch(duffing, np.zeros(2), 0.5, opts(0.5, 2.5, ds_max=0.2, ds_min=1e-4))
    capped = continue_branch(duffing, np.zeros(2), 0.5, opts(0.5, 2.5, ds_max=0.2, ds_min=1e-4, iter_reject=2))
    for b in (base, capped):
        assert b.status == STATUS_OMEGA_MAX and b.converged.all() and len(reversals(b.omega)) == 2
        A = np.hypot(b.x[:, 0], b.x[:, 1])
        G = duffing.relation(A, b.omega)
        assert np.all(np.abs(G) <= 1.01 * (2 * duffing.force * b.residual_norm + b.residual_norm ** 2) + 1e-15)
    assert base.iterations[1:].max() > 2
    above_floor = capped.step[1:] >= 2e-4
    assert above_floor.all() and capped.iterations[1:].max() <= 2
    assert len(capped) > len(base)  # the refused steps were taken shorter
    with pytest.raises(ValueError, match="iter_reject"):
        opts(0.5, 2.5, iter_reject=0)


def test_a_refusal_by_the_caller_halves_the_step_and_the_floor_admits(duffing):
    """admit refuses every correction that ends above Omega = 1.2: the step halves down to the
    floor, where the correction is admitted (a refusal never ends the branch), so the branch
    creeps past 1.2 at steps under twice ds_min, every point still the exact branch's. The
    refusals are the caller's: each carries the last point and the corrected (x, omega)."""
    seen = []

    def admit(last, x, omega):
        seen.append((last.omega, omega))
        return "above 1.2" if omega > 1.2 else None

    b = continue_branch(duffing, np.zeros(2), 0.5, opts(0.5, 2.5, ds_min=1e-4, max_points=400), admit=admit)
    assert b.status == STATUS_MAX_POINTS and b.converged.all()
    above = b.omega > 1.2
    assert above.sum() > 100 and b.omega.max() < 1.25
    assert (b.step[1:][above[1:]] < 2e-4).all()  # every step that ended above 1.2 taken at the floor
    assert (b.step[1:][~above[1:]] > 2e-4).any()
    A = np.hypot(b.x[:, 0], b.x[:, 1])
    assert np.all(np.abs(duffing.relation(A, b.omega)) <= 1.01 * (2 * duffing.force * b.residual_norm
                                                                 + b.residual_norm ** 2) + 1e-15)
    assert any(w_new > 1.2 and w_last <= 1.2 for w_last, w_new in seen)


def test_unknown_predictor_is_refused():
    with pytest.raises(ValueError, match="predictor"):
        opts(0.5, 2.5, predictor="tangent")


def test_duffing_sparse_and_custom_factorisation_give_the_same_branch(duffing):
    ref = continue_branch(duffing, np.zeros(2), 0.5, opts(0.5, 2.5))
    calls = []

    def sparse_residual(x, w):
        R, J, dw = duffing(x, w)
        return R, sp.csr_matrix(J), dw

    class CountingSolver(DirectSolver):
        def factorize(self, J):
            calls.append(1)
            return super().factorize(J)

    for kw in ({"residual": sparse_residual}, {"residual": duffing, "solver": CountingSolver()}):
        b = continue_branch(kw.pop("residual"), np.zeros(2), 0.5, opts(0.5, 2.5), **kw)
        assert len(b) == len(ref)
        np.testing.assert_allclose(b.x, ref.x, rtol=0, atol=1e-9)  # same steps, LU vs SuperLU rounding
    assert len(calls) >= ref.iterations.sum()  # the caller's solver did the solves


# ---------------------------------------------------------------- closed loops
@pytest.mark.parametrize("direction", [1, -1])
def test_isola_stops_after_one_turn(direction):
    c = Circle(c=2.0, wc=1.5, r=0.5)
    x0 = np.array([2.5, 0.25 * 2.5 ** 2])
    b = continue_branch(c, x0, 1.5, opts(0.0, 5.0, direction=direction, closed_loop_tol=1e-2))
    assert b.status == STATUS_CLOSED_LOOP
    assert b.converged.all()
    # Closed by the crossing test of eq. (26)-(27) at full steps: landing on its own first
    # segment is the loop's end, not a retrace to refuse down to the step floor.
    assert b.detail.startswith("d_int=") and b.step[1:].min() >= 0.02
    # Went round once: through both omega extremes of the circle (two folds), back to the start,
    # and not through the other crossing of omega0 (x1 = 1.5, d_int = 0.88).
    assert len(reversals(b.omega)) == 2
    assert b.omega.min() == pytest.approx(1.0, abs=2e-3) and b.omega.max() == pytest.approx(2.0, abs=2e-3)
    # Chords add up to the curve's length in (x1, x2, omega), once round plus at most one step
    # (chords of <= ds_max on a curve of radius >= 0.5 fall short by < ds_max^2 / 24 r^2 ~ 4e-4).
    th = np.linspace(0, 2 * np.pi, 20001)
    x1, dx1 = 2 + 0.5 * np.cos(th), -0.5 * np.sin(th)
    speed = np.sqrt(dx1 ** 2 + (0.5 * x1 * dx1) ** 2 + (0.5 * np.cos(th)) ** 2)
    loop = np.sum(0.5 * (speed[1:] + speed[:-1]) * np.diff(th))
    assert loop * (1 - 1e-3) <= b.step.sum() <= loop + DS_MAX
    assert np.linalg.norm(b.x[-1] - x0) <= 2 * DS_MAX
    np.testing.assert_allclose((b.x[:, 0] - 2) ** 2 + (b.omega - 1.5) ** 2, 0.25, atol=2 * TOL)


def test_isola_without_the_test_goes_round_again():
    """Control: the closed-loop test, not something else, is what stopped the run above."""
    b = continue_branch(Circle(), np.array([2.5, 1.5625]), 1.5, opts(0.0, 5.0, closed_loop_tol=None, max_points=200))
    assert b.status == STATUS_MAX_POINTS and len(b) == 200
    assert len(reversals(b.omega)) >= 4


def test_curve_passing_near_its_start_is_not_a_loop():
    # Helix: after each turn it crosses omega0 again at the start's x1 but with x2 shifted by
    # 2 pi h = 0.14, i.e. d_int = 0.140 / 2.70 = 0.052 (0.093, 0.13 at the next turns).
    hx = Helix(h=0.0223)
    x0, w0 = hx.start()
    b = continue_branch(hx, x0, w0, opts(0.0, 5.0, closed_loop_tol=0.03, max_points=250))
    assert b.status == STATUS_MAX_POINTS
    crossings = np.flatnonzero(np.diff(np.sign(b.omega[1:] - w0)) != 0)
    assert len(crossings) >= 4  # came back over omega0 near x1 = 2.5 at least twice
    np.testing.assert_allclose((b.x[:, 0] - 2) ** 2 + (b.omega - 1.5) ** 2, 0.25, atol=2 * TOL)
    # Control, same curve with d_min = 0.06 > 0.052: the first return counts as a loop.
    b = continue_branch(hx, x0, w0, opts(0.0, 5.0, closed_loop_tol=0.06, max_points=250))
    assert b.status == STATUS_CLOSED_LOOP
    assert b.x[-1, 1] == pytest.approx(1.0 + 2 * np.pi * 0.0223, abs=DS_MAX)
    assert len(reversals(b.omega)) == 2


def test_fold_next_to_the_start_is_not_a_loop():
    # Start 1e-4 below a crest of Wave (|x| ~ 10): the two sheets cross omega0 ~6.5e-3 apart
    # in x1, so the return a few small steps later has d_int ~ 6.5e-4 < d_min = 1e-2, and
    # eq. (27) alone would call it a loop. The branch never left the d_min neighbourhood
    # of its start, so the test is not armed.
    w = Wave(w0=1.0, h=0.3, kappa=4.0, x2_0=10.0)
    x0 = np.array([np.arcsin(1 - 1e-4 / 0.3) / 4, 10.0])
    w0 = 1.3 - 1e-4
    b = continue_branch(w, x0, w0, opts(0.0, 5.0, ds=0.005, closed_loop_tol=1e-2, max_points=40))
    assert b.status == STATUS_MAX_POINTS
    i = np.flatnonzero((b.omega[1:-1] - w0) * (b.omega[2:] - w0) < 0)[0] + 1  # first return over w0
    x_int = b.x[i] + (w0 - b.omega[i]) / (b.omega[i + 1] - b.omega[i]) * (b.x[i + 1] - b.x[i])
    assert np.linalg.norm(x_int - x0) / np.linalg.norm(x_int) < 1e-2  # the naive test would have fired


def test_turn_limit_is_enforced():
    # On the circle of radius 0.5 a step ds turns the chord by ~ds / 0.5 rad (5.7 deg at ds_max):
    # with max_turn_deg = 2 the steps must shrink until each chord turns by <= 2 deg from the
    # previous secant.
    c, x0 = Circle(), np.array([2.5, 1.5625])
    b = continue_branch(c, x0, 1.5, opts(0.0, 5.0, max_turn_deg=2.0, ds_min=1e-4, max_points=60))
    assert b.status == STATUS_MAX_POINTS
    d = np.column_stack([np.diff(b.x, axis=0), np.diff(b.omega)])
    d /= np.linalg.norm(d, axis=1)[:, None]
    turn = np.degrees(np.arccos(np.clip(np.sum(d[1:] * d[:-1], axis=1), -1, 1)))
    assert turn.max() <= 2.0 + 1e-9 and turn.max() > 1.0  # bounded, and the bound was active


@pytest.mark.parametrize("a, passes", [(0.5, True), (5.0, False)])
def test_sharp_corner_at_the_step_floor(a, passes):
    # A corner of the branch (Vee, rounded over 1e-7) turns it by 53 deg (a = 0.5) or 157 deg
    # (a = 5) whatever the step: above max_turn_deg = 45 at any ds. At the step floor a turn up
    # to 90 deg is a genuine corner and is passed; beyond it no correction can both converge
    # and go on forwards (the sphere meets the branch only behind the corner or on an arm that
    # turns back by 157 deg), and the branch ends there, saying why, with no wrong point.
    v = Vee(a=a)
    assert (v.turn_deg() < 90.0) == passes
    b = continue_branch(v, np.array([-0.5, 0.0]), 1.0 + 0.5 * a,
                        opts(0.0, 5.0, ds_min=1e-3, max_points=400, direction=-1))  # towards the corner
    ok = b.converged
    np.testing.assert_allclose(b.omega[ok], 1.0 + a * np.hypot(b.x[ok, 0], 1e-7), atol=TOL)  # on the branch
    if passes:
        assert b.x[:, 0].max() > 0.1 and np.all(np.diff(b.x[ok, 0]) > 0)  # through the corner, forwards
    else:
        assert b.status.startswith(STATUS_STEP_FLOOR)
        assert abs(b.x[ok][-1, 0]) < 0.01 and np.all(np.diff(b.x[ok, 0]) > 0)  # it ended at the corner



def test_a_corner_is_passed_above_the_step_floor():
    # Vee (a = 0.9) turns by 84 deg at its corner, whatever the step. Without corner_turns
    # the steps there halve down to the floor (1e-6); with corner_turns = 2 the third
    # halving that turns by the same angle (within 2 deg) is taken, at a step of ds_max / 8
    # or more; every point on the branch, forwards through the corner.
    v = Vee(a=0.9)
    runs = {}
    for k in (None, 2):
        b = continue_branch(v, np.array([-0.5, 0.0]), 1.45,
                            opts(0.0, 5.0, ds_min=1e-6, max_points=60, direction=-1, corner_turns=k))
        assert np.all(b.converged)
        np.testing.assert_allclose(b.omega, 1.0 + 0.9 * np.hypot(b.x[:, 0], 1e-7), atol=TOL)  # on the branch
        assert np.all(np.diff(b.x[:, 0]) > 0)
        runs[k] = b
    assert gaps(runs[None]).min() < 2e-6
    assert gaps(runs[2]).min() >= DS_MAX / 16
    assert runs[2].x[-1, 0] > 2 * runs[None].x[-1, 0] > 0  # 60 points reach further


def test_the_nfrcs_continuation_passes_a_corner_above_the_step_floor():
    # The NFRC's settings (hbm.harmonic.nfrc.default_continuation), omega scaled as Vee's x:
    # its 84 deg corner is passed at a step far above the floor (1e-5), where without the
    # corner rule the branch crawled there (RL on the coarse rotor 37 ROM then ended at the
    # floor on a turn over 90 deg, 185 rad/s short of its range)
    from dataclasses import replace

    from hbm.harmonic.nfrc import default_continuation
    from hbm.options import HbmOptions

    o = replace(default_continuation(HbmOptions()), omega_min=0.0, omega_max=5.0, omega_scale=1.0, ds=0.02,
                ds_max=DS_MAX, direction=-1, max_points=60, newton=NewtonOptions(tol_residual=TOL))
    b = continue_branch(Vee(a=0.9), np.array([-0.5, 0.0]), 1.45, o)
    assert np.all(b.converged) and np.all(np.diff(b.x[:, 0]) > 0)  # forwards through the corner
    np.testing.assert_allclose(b.omega, 1.0 + 0.9 * np.hypot(b.x[:, 0], 1e-7), atol=TOL)  # on the branch
    assert b.x[-1, 0] > 0.1 and gaps(b).min() >= DS_MAX / 16


def test_a_turn_that_shrinks_with_the_step_is_no_corner():
    # On the circle of radius 0.5 a chord of ds = 0.6 turns by ~74 deg from the previous
    # secant, one of 0.3 by ~35: the turn halves with the step, the corner rule never fires,
    # and the points are those without it.
    c, x0 = Circle(), np.array([2.5, 1.5625])
    b0, b2 = (continue_branch(c, x0, 1.5, opts(0.0, 5.0, ds=0.6, ds_max=0.6, ds_min=1e-4, max_points=40,
                                                    corner_turns=k)) for k in (None, 2))
    np.testing.assert_array_equal(b0.x, b2.x)
    np.testing.assert_array_equal(b0.omega, b2.omega)
    assert b0.step[1:].min() < 0.6  # steps were refused for their turn


def test_a_corner_beyond_90_degrees_still_ends_the_branch():
    # corner_turns accepts turns up to 90 deg only: Vee's 157 deg corner ends the branch at
    # the floor, as without it
    b = continue_branch(Vee(a=5.0), np.array([-0.5, 0.0]), 3.5,
                        opts(0.0, 5.0, ds_min=1e-3, max_points=400, direction=-1, corner_turns=2))
    assert b.status.startswith(STATUS_STEP_FLOOR)
    assert abs(b.x[b.converged][-1, 0]) < 0.01

def test_zigzag_branch_traverses_every_fold():
    # ZigZag folds every pi / kappa = 0.26 in x1 between stretches ~0.26 apart, a cluster like
    # RL-HBM's over 420-432 rad/s on rotor 67. With ds_max = 1 a step can reach a later stretch.
    # The turn control (refuse > 45 deg, shrink the next step after > 30 deg) keeps the run on
    # its own stretch: every fold in the x1 span covered shows up as a reversal of omega.
    z = ZigZag(h=0.05, kappa=12.0)

    def run(**kw):
        o = opts(0.0, 5.0, ds=0.05, ds_max=1.0, ds_min=1e-4, max_points=300, closed_loop_tol=None, **kw)
        b = continue_branch(z, np.zeros(2), 1.0, o)
        assert b.status == STATUS_MAX_POINTS and b.converged.all()
        folds = int(np.sum(np.diff(np.sign(np.diff(b.omega))) != 0))
        return folds, z.extrema_between(b.x[0, 0], b.x[-1, 0])

    folds, expected = run()
    assert folds == expected >= 40
    # the control matters: with only the old 90 deg refusal the run skips most folds
    folds, expected = run(max_turn_deg=90.0, turn_shrink_deg=180.0)
    assert folds < 0.2 * expected


def test_no_retrace_onto_a_parallel_stretch():
    # Hairpin: down the left lane, round a U-turn of radius 0.01, up the right lane 0.02 away.
    # Steps of up to 0.5 on the way up can land back on the left lane a few degrees off the
    # secant: the run then retraces its own descent (the rotor 67 RL branch at N_h = 60 did,
    # over 420-432 rad/s). The rejoin check refuses such a landing (Newton from the old path
    # finds the same solution) and the run stays on the right lane up to omega_max.
    h = Hairpin(r=0.01, a=0.1, k=2.0)

    def run(check):
        o = opts(0.0, 3.0, ds=0.05, ds_max=0.5, ds_min=1e-5, max_points=400, direction=-1, rejoin_check=check)
        b = continue_branch(h, np.array([h.lane(3.0, -1), 0.0]), 3.0, o)
        assert b.status == STATUS_OMEGA_MAX and b.converged.all()
        up = np.arange(int(np.argmin(b.omega)) + 1, len(b))
        lanes = np.sign(b.x[up, 0] - np.array([h.lane(w, 0) for w in b.omega[up]]))
        return lanes[b.omega[up] >= h.w0]

    assert np.all(run(True) == 1)  # the right lane all the way up
    assert np.any(run(False) == -1)  # without the check: back on the left lane


# ---------------------------------------------------------------- failures
def test_dead_end_ends_with_a_reason_and_no_wrong_point():
    seen = []
    b = continue_branch(Wall(2.0), np.array([1.0]), 1.0, opts(0.0, 5.0, ds_min=1e-4), on_point=seen.append)
    assert b.status.startswith(STATUS_STEP_FLOOR + ": ") and "non-finite" in b.status
    assert not b.converged[-1] and b.converged[:-1].all()
    assert len(seen) == len(b) and not seen[-1].converged
    ok = b.converged
    assert np.all(b.omega[ok] <= 2.0)
    np.testing.assert_allclose(b.x[ok, 0], np.sqrt(2.0 - b.omega[ok]), atol=TOL)
    assert b.omega[ok][-1] > 2.0 - 1e-3  # it followed the branch up to the wall


def test_start_point_failure_is_reported():
    b = continue_branch(Wall(2.0), np.array([1.0]), 2.5, opts(0.0, 5.0))
    assert b.status.startswith(STATUS_START_FAILED) and len(b) == 1 and not b.converged[0]


def test_unconverged_newton_is_not_converged(duffing):
    r = newton_solve(duffing, np.zeros(2), 1.4, NewtonOptions(tol_residual=1e-12, max_iter=1))
    assert not r.converged and "no convergence" in r.reason and r.residual_norm > 1e-12
    r = newton_solve(duffing, np.zeros(2), 1.0, NewtonOptions(tol_residual=1e-12))
    assert r.converged
    assert abs(duffing.relation(np.hypot(*r.x), 1.0)) <= 2 * duffing.force * 1e-12 * 1.01
    # With a step criterion, a solution is confirmed by one (tiny) correction, not accepted as given.
    again = newton_solve(duffing, r.x, 1.0, NewtonOptions(tol_residual=1e-12, tol_step=1e-9))
    assert again.converged and again.iterations == 1
    assert newton_solve(duffing, r.x, 1.0, NewtonOptions(tol_residual=1e-12)).iterations == 0


@pytest.mark.parametrize("max_halvings", [0, 1, 4])
def test_line_search_halves_at_most_max_halvings_times(max_halvings):
    """The line search tries t = 1, 1/2, ..., 2^-max_halvings and takes the first that
    decreases ||R||, else the last it tried."""
    def uphill(x, w, jacobian=True):  # Jacobian of the wrong sign: ||R|| grows at every t > 0
        return x.copy() if not jacobian else (x.copy(), -np.eye(1), np.zeros(1))

    def atan(x, w, jacobian=True):  # from x = 2: t = 1 overshoots to |R| = 1.30 > 1.11, t = 1/2 gives 0.65
        R = np.arctan(x)
        return R if not jacobian else (R, np.array([[1.0 / (1.0 + x[0] ** 2)]]), np.zeros(1))

    o = NewtonOptions(max_iter=1, line_search=True, max_halvings=max_halvings)
    r = newton_solve(uphill, np.array([1.0]), 1.0, o)
    assert r.x[0] == pytest.approx(1.0 + 2.0 ** -max_halvings, rel=1e-14)
    r = newton_solve(atan, np.array([2.0]), 1.0, o)
    t = 1.0 if max_halvings == 0 else 0.5
    assert r.x[0] == pytest.approx(2.0 - t * 5.0 * np.arctan(2.0), rel=1e-14)


# ---------------------------------------------------------------- bordered solve
@pytest.mark.parametrize("sparse", [False, True])
@pytest.mark.parametrize("case", ["exact", "rotated", "near"])
def test_bordered_solve_at_a_fold(sparse, case):
    rng = np.random.default_rng(1)
    n = 6
    Q = np.eye(n) if case == "exact" else np.linalg.qr(rng.standard_normal((n, n)))[0]
    J = Q @ np.diag([1e-14 if case == "near" else 0.0, 1, 2, 3, 4, 5.0]) @ Q.T  # singular or nearly so
    r_w, p, R = rng.standard_normal(n), rng.standard_normal(n), rng.standard_normal(n)
    q, P = 0.3, -0.2
    A = np.block([[J, r_w[:, None]], [p[None, :], np.array([[q]])]])
    ref = np.linalg.solve(A, -np.concatenate([R, [P]]))
    dx, dw, used_full = DirectSolver().factorize(sp.csr_matrix(J) if sparse else J).solve_bordered(r_w, p, q, R, P)
    np.testing.assert_allclose(np.concatenate([dx, [dw]]), ref, rtol=1e-8, atol=1e-10)
    if case == "exact":  # a zero pivot: only the full bordered matrix can do it
        assert used_full


def test_bordered_solve_regular_uses_block_elimination():
    rng = np.random.default_rng(2)
    J = np.eye(4) * 3 + 0.1 * rng.standard_normal((4, 4))
    r_w, p, R = rng.standard_normal((3, 4))
    dx, dw, used_full = DirectSolver().factorize(J).solve_bordered(r_w, p, 0.5, R, 0.1)
    A = np.block([[J, r_w[:, None]], [p[None, :], np.array([[0.5]])]])
    np.testing.assert_allclose(A @ np.concatenate([dx, [dw]]), -np.concatenate([R, [0.1]]), atol=1e-12)
    assert not used_full


def test_newton_names_the_step_test_when_only_it_fails():
    """R = x^3 from x = 1e-3: ||R|| is below tol_residual at once, the steps (x / 3) stay above
    tol_step for 3 iterations: the reason says so, not that ||R|| is too large."""
    from hbm.continuation.newton import NewtonOptions, newton_solve

    def cubic(x, w):
        return np.array([x[0] ** 3]), np.array([[3 * x[0] ** 2]]), np.array([0.0])

    r = newton_solve(cubic, np.array([1e-3]), 1.0, NewtonOptions(tol_residual=1e-8, tol_step=1e-6, max_iter=3))
    assert not r.converged and r.residual_norm < 1e-8
    assert "within tolerance, but the last step 1.481e-04 > tol_step 1.0e-06" in r.reason


def test_a_start_on_the_bound_heading_out_adds_no_point():
    from hbm.continuation.arclength import ContinuationOptions, continue_branch

    def line(x, w):
        return np.array([x[0] - w]), np.array([[1.0]]), np.array([-1.0])

    b = continue_branch(line, [2.0], 2.0, ContinuationOptions(0.0, 2.0, direction=1))
    assert len(b) == 1 and b.status.startswith("reached omega_max")
    b = continue_branch(line, [0.5], 0.5, ContinuationOptions(0.5, 2.0, direction=-1))
    assert len(b) == 1 and b.status.startswith("reached omega_min")


def test_a_branch_point_taken_from_the_end_carries_its_position():
    """Branch.point(-1) is the last point, with index m - 1 (what a monitor fed from it
    stores); an index past either end is an IndexError, not another point."""
    from hbm.continuation.branch import Branch, ContinuationPoint

    pts = [ContinuationPoint(i, 100.0 + i, np.full(2, float(i)), True, 1e-9, 2, 0.1 * i, 0.01) for i in range(3)]
    br = Branch.from_points(pts, 2, status=STATUS_OMEGA_MAX)
    last = br.point(-1)
    assert last.index == 2 and last.omega == 102.0 and np.array_equal(last.x, [2.0, 2.0])
    assert br.point(-3).index == 0
    for i in (3, -4):
        with pytest.raises(IndexError):
            br.point(i)
