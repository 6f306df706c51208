"""A bifurcation located finer than the branch's points (hbm.stability.refinement): points
solved between the two stored points around the crossing, analysed, and the bracket closed
by Brent's method on the crossing multiplier's log|mu|.

References: shooting's multiplier -1 (solve_ivp's variational equations, independent of
the HBM and of Hill's method) on the period-doubling oscillator of test_period_doubling,
and closed-form test functions for the root finding."""
import re

import numpy as np
import pytest
from scipy.optimize import brentq

from hbm.continuation.arclength import ContinuationOptions, continue_branch
from hbm.continuation.newton import newton_solve
from hbm.harmonic.nfrc import nfrc_extras
from hbm.options import HbmOptions
from hbm.stability.bifurcation import PERIOD_DOUBLING, Bifurcation, bifurcation_arrays, bifurcations_from_arrays
from hbm.stability.monitor import StabilityMonitor, StabilityOptions
from hbm.stability.refinement import refine_crossing
from test_period_doubling import NOPT, _pd_multiplier, _state, obstacle_residual


@pytest.fixture(scope="module")
def oscillator():
    """The obstacle oscillator's W-periodic branch from 4.6 down to 4.0 at a fixed step of
    0.02 (its period doubling near W = 4.3275 falls inside one step)."""
    res, sol = obstacle_residual()
    opts = ContinuationOptions(omega_min=4.0, omega_max=4.6, ds=0.02, ds_max=0.02, direction=-1, newton=NOPT,
                               closed_loop_tol=None, omega_scale=1.0)
    br = continue_branch(res, sol.x, 4.6, opts)
    assert br.status == "reached omega_min"
    return res, br


def _monitor(res, br, steps, rtol=1e-9):
    mon = StabilityMonitor.for_residual(res, StabilityOptions(refine_steps=steps, refine_rtol=rtol), newton=NOPT)
    for i in range(len(br)):
        mon.push(br.point(i), nfrc_extras(res, br.x[i]))
    mon.finish()
    return mon


def _exact(res, br, pd):
    """Omega where shooting's multiplier is -1, from the stored point before the bracket."""
    lo, hi = sorted(pd.omega_bracket)
    y = _state(res, br.x[pd.index], br.omega[pd.index])
    return brentq(lambda w: _pd_multiplier(y, w) + 1.0, lo - 0.01, hi + 0.01, xtol=1e-10)


def test_a_refined_period_doubling_lies_where_shooting_puts_it(oscillator):
    res, br = oscillator
    plain = _monitor(res, br, 0)
    (pd0,) = plain.bifurcations
    w_exact = _exact(res, br, pd0)
    # interpolated between the stored points 0.02 apart: measured 6.2e-3 off, a third of the
    # bracket (log|mu| is flat on the stable side, where the crossing multiplier is one of
    # a complex pair, and steep once it is real)
    assert pd0.refine_steps == 0 and pd0.bracket == pd0.omega_bracket
    assert abs(pd0.omega - w_exact) > 2e-3
    ref = _monitor(res, br, 6)
    (pd,) = ref.bifurcations
    assert pd.kind == PERIOD_DOUBLING and pd.refine_note == ""
    assert pd.index == pd0.index and pd.omega_bracket == pd0.omega_bracket
    assert 1 <= pd.refine_steps <= 6 and ref.causes["refinement"] == pd.refine_steps
    assert ref.n_analyses == plain.n_analyses + pd.refine_steps
    # shooting's crossing inside the refined bracket, and the located Omega within 1e-5 of
    # it (measured 2e-7 after five solves)
    lo, hi = sorted(pd.bracket)
    assert lo <= w_exact <= hi and hi - lo < 2e-3
    assert abs(pd.omega - w_exact) < 1e-5
    assert min(pd.omega_bracket) < pd.omega < max(pd.omega_bracket)
    # the amplitude there: between those of the stored points, near the one of the solved
    # orbit at that Omega
    assert min(pd0.le_amplitude, pd.le_amplitude) > 0
    sol = newton_solve(res, br.x[pd.index], pd.omega, NOPT)
    assert pd.le_amplitude == pytest.approx(nfrc_extras(res, sol.x)["le_amplitude"], rel=1e-3)
    # the multiplier and mode stay the stored side's (a branch switch starts from a stored
    # point), and the table keeps how it was located
    assert pd.multiplier == pd0.multiplier
    back, = bifurcations_from_arrays({k: v for k, (v, _) in bifurcation_arrays([pd]).items()})
    assert (back.refine_steps, back.bracket, back.refine_note, back.omega) == (pd.refine_steps, pd.bracket, "",
                                                                                pd.omega)


def test_a_loose_tolerance_stops_the_refinement_early(oscillator):
    res, br = oscillator
    (pd,) = _monitor(res, br, 20, rtol=2e-4).bifurcations
    lo, hi = sorted(pd.bracket)
    assert hi - lo <= 2e-4 * hi * 1.0001
    assert pd.refine_steps < 20
    assert abs(pd.omega - _exact(res, br, pd)) < hi - lo


def test_brent_on_a_kinked_test_function_closes_the_bracket():
    """l(f) flat at -0.02 up to f = 0.628 then rising steeply through 0 at 0.632, as a
    crossing multiplier that leaves a complex pair; Omega = 100 - 10 f."""
    root = 0.6321

    def l_of(f):
        return max(-0.02, 5.0 * (f - root))

    calls = []

    def evaluate(f):
        calls.append(f)
        return l_of(f), 100.0 - 10.0 * f, 1e-3 * (1 + f)

    r = refine_crossing(evaluate, ((l_of(0.0), 100.0, 1e-3), (l_of(1.0), 90.0, 2e-3)), steps=30, rtol=1e-9)
    assert r.note == "" and r.steps == len(calls) <= 30
    assert r.fraction == pytest.approx(root, abs=1e-8)
    assert r.omega == pytest.approx(100.0 - 10.0 * root, abs=1e-7)
    assert r.le_amplitude == pytest.approx(1e-3 * (1 + root), rel=1e-6)
    lo, hi = sorted(r.bracket)
    assert lo <= 100.0 - 10.0 * root <= hi and hi - lo <= 1e-6
    # linear interpolation between the ends, as without refinement, is 0.61 off in f
    assert abs(0.02 / (0.02 + l_of(1.0)) - root) > 0.5


def test_a_failed_point_ends_the_refinement_with_its_reason_and_the_bracket_so_far():
    def evaluate(f):
        if len(seen) == 2:
            return "no point at f = 0.5: no convergence in 12 iterations"
        seen.append(f)
        return (f - 0.3) * (1.0 + 3.0 * f), 10.0 * f, 1.0

    seen = []
    r = refine_crossing(evaluate, ((-0.3, 0.0, 1.0), (2.8, 10.0, 1.0)), steps=10, rtol=1e-12)
    assert r.note.startswith("no point at f = 0.5") and r.steps == 3 and len(seen) == 2
    lo, hi = sorted(r.bracket)
    assert lo <= 3.0 <= hi and hi - lo < 10.0  # narrower than the stored points' bracket
    assert lo <= r.omega <= hi
    with pytest.raises(ValueError, match="do not bracket a crossing"):
        refine_crossing(evaluate, ((0.1, 0.0, 1.0), (0.7, 10.0, 1.0)), steps=3, rtol=1e-6)


def test_zero_steps_and_a_bracket_already_within_tolerance_solve_nothing():
    def evaluate(f):
        raise AssertionError("no point should be solved")

    ends = ((-1.0, 1000.0, 1.0), (3.0, 1000.001, 1.0))
    for steps, rtol in ((0, 1e-12), (5, 1e-5)):
        r = refine_crossing(evaluate, ends, steps=steps, rtol=rtol)
        assert r.steps == 0 and r.fraction == pytest.approx(0.25) and r.bracket == (1000.0, 1000.001)


def test_the_scene_key_reaches_the_monitor():
    opts = StabilityOptions.of(HbmOptions(stability_max_gap=3, refine_bifurcations=4, tolerance=1e-9))
    assert (opts.max_gap, opts.refine_steps, opts.refine_tolerance) == (3, 4, 1e-9)
    assert StabilityOptions.of(HbmOptions()).refine_steps == 0
    # a table written before refinement existed reads back as interpolated between its points
    b = Bifurcation(kind=PERIOD_DOUBLING, omega=10.0, le_amplitude=1.0, index=2, fraction=0.5,
                    omega_bracket=(9.0, 11.0), multiplier=-1.1, direction=1)
    cols = {k: v for k, (v, _) in bifurcation_arrays([b]).items()
            if k not in ("refine_steps", "located_low", "located_high", "refine_note")}
    (back,) = bifurcations_from_arrays(cols)
    assert back.refine_steps == 0 and back.bracket == (9.0, 11.0) and back.located_bracket is None


def test_the_monitor_refines_closed_form_crossings_and_reports_a_failed_analysis():
    """The monitor of test_stability_monitor on a complex pair whose log|mu| is a Gaussian
    bump along the arc length s (out of the circle and back, Omega = 1000 - s): refined, both
    Neimark-Sacker crossings lie at the bump's exact roots (brentq on the closed form) to
    1e-6 rad/s, where the interpolation between the stored points is 1e-3 off or more. An
    analysis that fails at the solved point (a singular H(0)) ends that refinement with its
    reason; the crossing keeps the interpolated place."""
    from hbm.linalg.errors import SingularMatrixError
    from hbm.stability.bifurcation import NEIMARK_SACKER
    from test_stability_monitor import OMEGA, _feed, spectrum

    def log_mod(s):
        return -0.3 + 0.4 * np.exp(-((s - 100) / 6) ** 2)

    def refine(xa, wa, xb, wb, f):  # the "branch": x = [s], Omega = 1000 - s
        s = float(xa[0] + f * (xb[0] - xa[0]))
        return np.array([s]), OMEGA - s, 1e-4 * s

    exact = [brentq(log_mod, 90, 100, xtol=1e-13), brentq(log_mod, 100, 110, xtol=1e-13)]
    found = {}
    for steps in (0, 12):
        mon = StabilityMonitor(analyse=lambda x, w: (spectrum(log_mod(float(x[0]))), 1), refine=refine,
                               options=StabilityOptions(refine_steps=steps, refine_rtol=1e-9))
        _feed(mon, OMEGA - np.arange(160))
        assert [b.kind for b in mon.bifurcations] == [NEIMARK_SACKER] * 2
        found[steps] = [b.omega for b in mon.bifurcations]
    assert all(abs(w - (OMEGA - s)) > 1e-3 for w, s in zip(found[0], exact))
    assert all(abs(w - (OMEGA - s)) < 1e-6 for w, s in zip(found[12], exact))

    def analyse(x, w):
        if float(x[0]) != round(float(x[0])):  # a solved point, between two stored ones
            raise SingularMatrixError("Hill operator at lam = 0: singular condensed matrix")
        return spectrum(log_mod(float(x[0]))), 1

    mon = StabilityMonitor(analyse=analyse, refine=refine, options=StabilityOptions(refine_steps=12))
    _feed(mon, OMEGA - np.arange(160))
    assert [b.omega for b in mon.bifurcations] == found[0]
    for b in mon.bifurcations:
        assert b.refine_steps == 1 and b.refine_note.startswith("no analysis at omega=")
        assert "singular condensed matrix" in b.refine_note and b.bracket == b.omega_bracket


def test_each_way_a_refinement_can_fail_is_its_own_note():
    """The bump of the test above, refined with 12 steps: the first solved point of each
    crossing fails in one of the ways a real branch can (the solve finds no point there, the
    analysis gives no verdict, or the crossing's multiplier is not among those listed: here
    the pair is gone and only real multipliers remain). Each refinement stops at that point
    with its own reason and the crossing keeps its interpolated place."""
    from dataclasses import replace

    from hbm.stability.bifurcation import NEIMARK_SACKER
    from test_stability_monitor import OMEGA, _feed, listed, spectrum

    def log_mod(s):
        return -0.3 + 0.4 * np.exp(-((s - 100) / 6) ** 2)

    def solved(x):
        return float(x[0]) != round(float(x[0]))  # a point between two stored ones

    def branch(xa, wa, xb, wb, f):
        s = float(xa[0] + f * (xb[0] - xa[0]))
        return np.array([s]), OMEGA - s, 1e-4 * s

    def unsolved(xa, wa, xb, wb, f):
        return "no convergence in 12 iterations near omega=904 (||R||=1e-3 > 1e-8)"

    def undecided(x, w):
        sp = spectrum(log_mod(float(x[0])))
        return (replace(sp, complete=False, note="ARPACK converged 3 of 40 eigenvalues") if solved(x) else sp), 1

    def pair_gone(x, w):
        return (listed([0.9 + 0j, 0.5 + 0j, 0.3 + 0j]) if solved(x) else spectrum(log_mod(float(x[0])))), 1

    plain = StabilityMonitor(analyse=lambda x, w: (spectrum(log_mod(float(x[0]))), 1), refine=branch,
                             options=StabilityOptions(refine_steps=0))
    _feed(plain, OMEGA - np.arange(160))
    interpolated = [b.omega for b in plain.bifurcations]
    for refine, analyse, note in [
        (unsolved, lambda x, w: (spectrum(log_mod(float(x[0]))), 1), r"no convergence in 12 iterations near omega=904"),
        (branch, undecided, r"no verdict at omega=\d+\.\d+: ARPACK converged 3 of 40 eigenvalues$"),
        (branch, pair_gone, rf"no {NEIMARK_SACKER} multiplier at omega=\d+\.\d+$"),
    ]:
        mon = StabilityMonitor(analyse=analyse, refine=refine, options=StabilityOptions(refine_steps=12))
        _feed(mon, OMEGA - np.arange(160))
        assert [b.kind for b in mon.bifurcations] == [NEIMARK_SACKER] * 2
        assert [b.omega for b in mon.bifurcations] == interpolated
        for b in mon.bifurcations:
            assert re.search(note, b.refine_note), b.refine_note
            assert b.bracket == b.omega_bracket
