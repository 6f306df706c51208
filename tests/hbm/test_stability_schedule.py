"""The stability monitor's schedule (hbm.stability.monitor), point by point, on branches whose
multipliers are known in closed form: where the next analysis comes (the reach rule, after
an analysis without a verdict), how a crossing inside a gap is bisected,
what a widening without a verdict leaves, and the crossings of a stretch resolved again.
(What it locates and the flags it infers: test_stability_monitor.py.)"""
from dataclasses import replace

import numpy as np

from hbm.stability.bifurcation import NEIMARK_SACKER, PERIOD_DOUBLING
from hbm.stability.monitor import StabilityMonitor, StabilityOptions
from test_stability_monitor import OMEGA, _feed, _stable_then, listed

OPTIONS = StabilityOptions()


def _analysed(got: dict) -> list:
    return sorted(i for i, ex in got.items() if ex["stability_analysed"])


def _creeping(s: float):
    """A complex pair exp(l +- 1.1 i), l = -0.305 + 0.01 s (unstable from s = 30.5), and two
    stable real multipliers."""
    lm = -0.305 + 0.01 * s
    return listed([np.exp(lm + 1.1j), np.exp(lm - 1.1j), 0.5, 0.3])


def test_the_next_analysis_comes_at_a_quarter_of_the_reach():
    """A complex pair creeping towards the circle at a constant speed, log|mu| = -0.305 +
    0.01 s (points one unit of arc length apart: crossing at s = 30.5). After the analyses
    at a and b the next one comes floor(0.25 |log|mu_b|| / speed) points on (at least 1,
    at most the cap of 8): the arc length the pair needs to reach the circle, measured from
    the latest analysis, per point."""
    lm = lambda s: -0.305 + 0.01 * s  # noqa: E731  (_creeping's pair)
    mon = StabilityMonitor(analyse=lambda x, w: (_creeping(float(x[0])), 1), options=OPTIONS)
    got = _feed(mon, OMEGA - np.arange(60))
    expected, b = [0, 1], 1
    while True:
        gap = int(np.clip(OPTIONS.reach_fraction * abs(lm(b)) / 0.01, 1, OPTIONS.max_gap))
        b += gap
        if b > 30:
            break
        expected.append(b)
    assert expected[:8] == [0, 1, 8, 13, 17, 20, 22, 24]  # the rule, spelt out
    assert [i for i in _analysed(got) if i <= 30] == expected
    assert [(b.kind, b.index) for b in mon.bifurcations] == [(NEIMARK_SACKER, 30)]


def test_a_crossing_inside_a_gap_is_bisected():
    """A real multiplier 1.95 appears after point 44, where the spectrum sat still and the gap
    was at its cap (analyses at 41 and 49): the change is brought between neighbours by
    bisection, 3 analyses for a gap of 8 (45, 43, 44), not by walking the gap."""
    mon = StabilityMonitor(analyse=_stable_then(44), options=OPTIONS)
    got = _feed(mon, OMEGA - np.arange(60))
    assert {41, 49} <= set(_analysed(got))
    assert mon.causes["bisection"] == 3
    assert {43, 44, 45} <= set(_analysed(got))
    assert [got[i]["stable"] for i in range(60)] == [i <= 44 for i in range(60)]


def test_a_bisection_passes_a_midpoint_without_a_verdict_by():
    """The change of the test above, but the bisection's first midpoint (45) gives no verdict:
    the bisection takes the next one (46) instead and goes on around 45, the change is located
    between the neighbours with a verdict, 44 and 46, and 45 keeps -1 with its reason."""
    base = _stable_then(44)

    def analyse(x, w):
        sp, g = base(x, w)
        if int(x[0]) == 45:
            sp = replace(sp, complete=False, note="ARPACK converged 1 of 40 eigenvalues")
        return sp, g

    mon = StabilityMonitor(analyse=analyse, options=OPTIONS)
    got = _feed(mon, OMEGA - np.arange(60))
    assert {41, 43, 44, 45, 46, 49} <= set(_analysed(got)) and mon.causes["bisection"] == 4
    assert [(b.index, b.omega_bracket) for b in mon.bifurcations] == [(44, (OMEGA - 44, OMEGA - 46))]
    assert [got[i]["n_unstable"] for i in range(60)] == [0] * 45 + [-1] + [1] * 14
    assert "ARPACK converged 1 of 40" in got[45]["stability_note"]


def test_an_analysis_without_a_verdict_is_followed_at_the_next_point():
    """The creeping pair of the first test, whose analyses come at 0, 1, 8, 13, 17, ...; the
    analysis at 13 gives no verdict (ARPACK stopped short): 14 is analysed next (not 16,
    where the gap from 8 would have brought it), and 13 keeps -1 with the reason."""
    def analyse(x, w):
        sp = _creeping(float(x[0]))
        if int(x[0]) == 13:
            sp = replace(sp, complete=False, note="ARPACK converged 1 of 40 eigenvalues")
        return sp, 1

    mon = StabilityMonitor(analyse=analyse, options=OPTIONS)
    got = _feed(mon, OMEGA - np.arange(40))
    assert _analysed(got)[:5] == [0, 1, 8, 13, 14]
    assert mon.causes["after undecided"] == 1
    assert got[13]["n_unstable"] == -1 and "ARPACK converged 1 of 40" in got[13]["stability_note"]
    assert all(got[i]["n_unstable"] == (0 if i <= 30 else 2) for i in range(40) if i != 13)


def windowed(log_pd: float, n_eig: int, pair: float | None = None):
    """A branch's spectrum as a window of 40 eigenvalues (ceiling e^2.5) or more (e^5) lists
    it: a real multiplier -exp(log_pd), beside a complex pair exp(pair +- 1.1 i) when
    given, and two stable real ones."""
    ceiling = 2.5 if n_eig <= 40 else 5.0
    mu = [-np.exp(log_pd), 0.5, 0.3] + ([np.exp(pair + 1.1j), np.exp(pair - 1.1j)] if pair is not None else [])
    mu = np.asarray(mu, complex)
    return listed(mu[np.log(np.abs(mu)) < ceiling], floor=float(np.exp(-ceiling)))


def test_a_widening_without_a_verdict_leaves_the_narrow_one():
    """A real multiplier grows past the narrow window (as in test_stability_monitor's
    test_a_multiplier_that_grows_past_the_window_is_not_taken_for_stability), but each wider
    analysis stops short (no verdict): every point keeps what its narrow analysis said, as
    without widening."""
    lm = lambda s: -0.41 + 0.04 * s  # noqa: E731

    def run(widen):
        mon = StabilityMonitor(analyse=lambda x, w: (windowed(lm(float(x[0])), 40), 1), widen=widen, options=OPTIONS)
        return mon, _feed(mon, OMEGA - np.arange(120))

    def short(x, w, k):
        return replace(windowed(lm(float(x[0])), k), complete=False, note="ARPACK stopped short"), 1

    mon, got = run(short)
    ref_mon, ref = run(None)
    assert mon.causes["widening"] >= 1
    assert [(b.kind, b.index) for b in mon.bifurcations] == [(b.kind, b.index) for b in ref_mon.bifurcations]
    for i in range(120):
        assert (got[i]["stable"], got[i]["n_unstable"], got[i]["stability_widened"]) == \
            (ref[i]["stable"], ref[i]["n_unstable"], False), i


def test_a_stretch_resolved_again_keeps_its_crossing_once():
    """An unstable pair exp(p +- 1.1 i) falls inside the circle between points 44 and 45
    while a real multiplier -exp(4.32 - 0.04 s), past the narrow window (e^2.5) up to
    s = 45.5, shrinks into it. The pair's crossing is located between 44 and 45 on the
    narrow counts (2 -> 0); the analysis at 46 sees the real multiplier (count 1), widens 45
    (0 -> 1) and resolves 44-45 again. The pair's crossing is recorded once, and the real
    multiplier's own one (through -1 at s = 108) after it."""
    pair = lambda s: 0.445 - 0.01 * s  # noqa: E731  (0 at s = 44.5)
    lpd = lambda s: 4.32 - 0.04 * s  # noqa: E731

    def analyse(x, w):
        s = float(x[0])
        return windowed(lpd(s), 40, pair(s)), 1

    def widen(x, w, k):
        s = float(x[0])
        return windowed(lpd(s), k, pair(s)), 1

    mon = StabilityMonitor(analyse=analyse, widen=widen, options=OPTIONS)
    got = _feed(mon, OMEGA - np.arange(120))
    assert [i for i in range(120) if got[i]["stability_widened"]] == [45]
    assert [(b.kind, b.index, b.direction) for b in mon.bifurcations] == [(NEIMARK_SACKER, 44, -1),
                                                                         (PERIOD_DOUBLING, 107, -1)]
    # the narrow window's counts up to 44 (the real multiplier past its ceiling), then the real one alone
    assert [got[i]["n_unstable"] for i in range(120)] == [2] * 45 + [1] * 63 + [0] * 12
