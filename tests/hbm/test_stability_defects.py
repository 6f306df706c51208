"""Defects of hbm.stability found in review, each on a synthetic case whose answer is known:
the monitor fed spectra given in closed form (as in test_stability_monitor.py), and Hill's
operator of a Mathieu oscillator, whose multipliers shooting gives."""
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from hbm.harmonic.fourier import FourierBasis
from hbm.stability import selection
from hbm.stability.bifurcation import BRANCH_POINT, FOLD, PERIOD_DOUBLING, Bifurcation, upper_half
from hbm.stability.hill import HillOperator
from hbm.stability.monitor import StabilityMonitor, StabilityOptions
from hbm.stability.spectrum import FloquetSpectrum, dense_spectrum

OMEGA = 1000.0


def spec_of(mu, ceiling: float | None = None) -> FloquetSpectrum:
    """An Arnoldi-like spectrum of the multipliers mu; ceiling: log of its modulus_ceiling
    (the multipliers beyond it are not listed; None: e^3, every one listed)."""
    mu = np.asarray(mu, complex)
    floor = 0.05
    if ceiling is not None:
        mu = mu[np.log(np.abs(mu)) < ceiling]
        floor = float(np.exp(-ceiling))
    mu = mu[np.argsort(-np.abs(mu), kind="stable")]
    k = len(mu)
    return FloquetSpectrum(omega=OMEGA, exponents=np.log(mu) * OMEGA / (2 * np.pi), multipliers=mu,
                           centred=np.ones(k, bool), edge_energy=np.zeros(k),
                           eigenvectors=np.zeros((k, 3, 2), complex), modulus_floor=floor, method="arnoldi")


def point(i: int, omega: float):
    return SimpleNamespace(index=i, omega=float(omega), step=1.0, x=np.array([float(i)]))


def feed(mon: StabilityMonitor, omegas, start: int = 0) -> dict:
    """Push points start, start + 1, ... (Omega = omegas, unknowns x = [index], le_amplitude
    1e-4 index) and finish: {index: extras handed back}; each point handed back once."""
    got = []
    for i, w in enumerate(omegas, start):
        got += mon.push(point(i, w), {"le_amplitude": 1e-4 * i})
    got += mon.finish()
    idx = [q.index for q, _ in got]
    assert sorted(idx) == list(range(start, start + len(omegas)))
    return {q.index: ex for q, ex in got}


def kinds(mon: StabilityMonitor) -> list:
    return [(b.kind, b.index, b.direction) for b in mon.bifurcations]


# -- 1: a held point widened by the next analysis ----------------------------------------
@pytest.mark.parametrize("log_mod, crossing", [
    # a real multiplier jumps past the default window's ceiling e^2.5 between points 4 and 5,
    # then falls back into the window, where an analysis sees it: the analysed point before
    # that one (9) is widened and its count rises 0 -> 1
    (lambda s: -0.5 if s <= 4 else 2.8 - 0.05 * (s - 5), 4),
    # the same, rising smoothly through the circle between points 3 and 4
    (lambda s: -0.5 if s <= 2 else min(-0.5 + 0.5 * (s - 2), 2.75) if s <= 8.5 else 2.75 - 0.05 * (s - 8.5), 3),
])
def test_a_held_point_whose_widening_raises_its_count_has_its_stability_change_located(log_mod, crossing):
    widened = []

    def widen(x, w, k):
        widened.append(int(x[0]))
        return spec_of([-np.exp(log_mod(x[0])), 0.5, 0.3], ceiling=2.5 if k <= 40 else 5.0), 1

    mon = StabilityMonitor(analyse=lambda x, w: widen(x, w, 40), widen=lambda x, w, k: widen(x, w, k),
                           options=StabilityOptions())
    n = 40
    got = feed(mon, OMEGA - np.arange(n))
    assert 9 in widened
    assert kinds(mon) == [(PERIOD_DOUBLING, crossing, 1)]
    assert [i for i in range(n) if got[i]["stable"] != (log_mod(i) <= 1e-6)] == []
    assert [got[i]["n_unstable"] for i in range(n)] == [0] * (crossing + 1) + [1] * (n - crossing - 1)


# -- 2: a fold at the junction of a resumed branch ----------------------------------------
TURN = 30
FOLD_OMEGAS = [OMEGA + 0.05 * (i - TURN) ** 2 for i in range(60)]


def _fold_analyse(x, w):
    # a real multiplier 1.95 outside the circle past the turn (the fold's +1, far beyond)
    return spec_of([0.5 + 0.2j, 0.5 - 0.2j, 0.3] + ([1.95] if x[0] > TURN else [])), 1


@pytest.mark.parametrize("stored_counts", [False, True])
def test_a_fold_at_the_junction_of_a_resumed_branch_is_recorded(stored_counts):
    # points 0..TURN stored, the continuation resumes at TURN + 1: the turn at TURN is seen at
    # the first new point, its trio (TURN - 1, TURN, TURN + 1) spans the junction
    full = StabilityMonitor(analyse=_fold_analyse, options=StabilityOptions())
    feed(full, FOLD_OMEGAS)
    assert [(b.kind, b.index) for b in full.bifurcations] == [(FOLD, TURN - 1)]

    stop = TURN + 1
    mon = StabilityMonitor(analyse=_fold_analyse, options=StabilityOptions())
    seeds = [point(i, FOLD_OMEGAS[i]) for i in range(stop - 3, stop)]
    extras = [dict({"le_amplitude": 1e-4 * i}, **({"n_unstable": 0, "period_ratio": 1} if stored_counts else {}))
              for i in range(stop - 3, stop)]
    mon.seed(seeds, extras)
    assert mon.n_analyses == (1 if stored_counts else 2)  # the last seed; the one before it unless stored
    feed(mon, FOLD_OMEGAS[stop:], start=stop)
    assert [(b.kind, b.index, b.direction) for b in mon.bifurcations] == [(FOLD, TURN - 1, 1)]
    assert mon.bifurcations[0].omega == pytest.approx(OMEGA, abs=1e-9)
    assert mon._folds == [] and min(mon._counts) > stop


# -- 3: _classify answers for the bracket asked -------------------------------------------
def test_locate_period_doubling_classifies_the_bracket_asked_not_its_neighbours(monkeypatch):
    # a multiplier -1.05 comes inside the circle between points 0 and 1, another one goes
    # out through -1.08 between 1 and 2: the bracket asked is (1, 2)
    mus = {0: [-1.05, -0.5], 1: [-0.95, -0.5], 2: [-0.95, -1.08], 3: [-0.95, -1.08]}
    monkeypatch.setattr(selection, "orbit_spectrum", lambda residual, x, w, **k: (spec_of(mus[int(round(x[0]))]), 1))
    x = np.arange(4.0)[:, None] * np.ones((1, 3))
    res = selection.locate_period_doubling(None, OMEGA - np.arange(4.0), x, 1e-4 * np.arange(4.0), np.ones(4, bool),
                                           brackets=[1])
    b = res.bifurcation
    assert (b.kind, b.index, b.direction, b.multiplier) == (PERIOD_DOUBLING, 1, 1, -1.08)
    assert b.omega_bracket == (OMEGA - 1, OMEGA - 2)
    assert res.index == 2  # the unstable side


# -- 4 and 8: the dense spectrum of a Mathieu oscillator ----------------------------------
def mathieu(n_harmonics: int):
    """x'' + 0.02 x' + (1 + 0.9 cos 2t) x = 0 (principal tongue: one multiplier beyond -1) as
    Hill's operator, with two stiff, damped dof that do not couple; and its multipliers by
    shooting."""
    w, eps, z = 2.0, 0.9, 0.01
    T = 2 * np.pi / w

    def rhs(t, y):
        A = np.array([[0.0, 1.0], [-(1 + eps * np.cos(w * t)), -2 * z]])
        return (A @ y.reshape(2, 2)).ravel()

    phi = solve_ivp(rhs, (0, T), np.eye(2).ravel(), rtol=1e-12, atol=1e-12).y[:, -1].reshape(2, 2)
    basis = FourierBasis(n_harmonics, 32)
    wt = eps * np.cos(w * np.arange(32) * T / 32)
    H = HillOperator(K=np.diag([1.0, 100.0, 100.0]), M=np.eye(3), C=np.diag([2 * z, 101.0, 101.0]), omega=w,
                     basis=basis, nodes=np.array([0]), weights=wt[None, None], sigma=np.ones(2 * n_harmonics + 1),
                     g_eps=1.0, g_z=0.0, nl=np.arange(3))
    return H, np.sort(np.linalg.eigvals(phi).real)


def test_the_dense_spectrum_counts_a_real_negative_multiplier_once():
    # at N_h = 2 the truncation moves the exponent of mu = -1.934 off omega / 2 by 3e-6 omega:
    # its two centred members were kept as two multipliers
    H, shoot = mathieu(2)
    assert shoot[0] < -1.0 < shoot[1] < 0.0
    sp = dense_spectrum(H)
    assert len(sp.multipliers) == 6 and sp.n_unstable == 1
    assert sp.multipliers[0] == pytest.approx(shoot[0], rel=1e-3)
    assert sp.multipliers[1] == pytest.approx(shoot[1], rel=1e-3)


def test_the_dense_spectrum_says_when_a_family_is_dropped_whole():
    # at N_h = 1 no member of the unstable family (mu = -1.934) or of its partner lies
    # inside the band: both are dropped, and the spectrum says that its verdict lacks them
    H, _ = mathieu(1)
    sp = dense_spectrum(H)
    assert sp.stable and len(sp.multipliers) == 4
    assert sp.note.startswith("2 of 6 exponent families have no eigenvector inside the harmonic band")
    assert dense_spectrum(mathieu(8)[0]).note == ""


# -- 5: a near-real complex pair ----------------------------------------------------------
@pytest.mark.parametrize("arg, kind", [(0.01, BRANCH_POINT), (np.pi - 0.01, PERIOD_DOUBLING)])
def test_a_near_real_complex_pair_crossing_the_circle_is_one_bifurcation(arg, kind):
    def analyse(x, w):
        lm = -0.3 + 0.03 * x[0]
        return spec_of([np.exp(lm + 1j * arg), np.exp(lm - 1j * arg), 0.3]), 1

    mon = StabilityMonitor(analyse=analyse, options=StabilityOptions())
    feed(mon, OMEGA - np.arange(30))
    assert kinds(mon) == [(kind, 10, 1)]
    assert mon.bifurcations[0].multiplier.imag > 0
    pair = np.exp(np.array([1j * arg, -1j * arg]))
    assert list(upper_half(pair)) == [True, False]
    assert list(upper_half(pair[1:])) == [True]  # alone: a real one the truncation moved


# -- 6: a released branch point stays released --------------------------------------------
def test_a_released_branch_point_is_not_replaced_by_a_fold_afterwards():
    # a real multiplier crosses -1 between points 9 and 10, then +1 between 29 and 30, where
    # Omega turns (at 30): that crossing is a fold, known as such only once the turn's third
    # point is handed on
    omegas = [OMEGA + 0.05 * (i - TURN) ** 2 for i in range(40)]

    def analyse(x, w):
        return spec_of([0.5 + 0.2j, 0.5 - 0.2j, 0.95 + 0.1 * (x[0] - 29)]), 1

    mon = StabilityMonitor(analyse=analyse, options=StabilityOptions(max_gap=1))
    seen = []
    for i, w in enumerate(omegas):
        mon.push(point(i, w), {"le_amplitude": 1e-4 * i})
        rel = mon.released_bifurcations()
        assert all(any(b is r for r in rel) for b in seen)  # what was released stays released
        seen = rel
        if i == TURN + 1:
            assert [(b.kind, b.index) for b in rel] == [(PERIOD_DOUBLING, 9)]
    mon.finish()
    assert [(b.kind, b.index) for b in mon.bifurcations] == [(PERIOD_DOUBLING, 9), (FOLD, TURN - 1)]


# -- 7: a fold's Omega and its bracket ----------------------------------------------------
def test_a_fold_s_omega_is_the_vertex_beyond_its_bracket_as_documented():
    s_v = 30.4
    omegas = [OMEGA + 0.05 * (i - s_v) ** 2 for i in range(60)]
    mon = StabilityMonitor(analyse=lambda x, w: (spec_of([0.5 + 0.2j, 0.5 - 0.2j, 0.3]), 1),
                           options=StabilityOptions())
    feed(mon, omegas)
    (b,) = mon.bifurcations
    assert b.kind == FOLD and b.index == 30 and b.fraction == pytest.approx(0.4, abs=1e-9)
    assert b.omega == pytest.approx(OMEGA, abs=1e-9) and b.omega_bracket == (omegas[30], omegas[31])
    assert b.omega < min(b.omega_bracket)  # an extremum of Omega: outside the two points' Omegas
    doc = Bifurcation.__doc__
    assert "except for a fold" in doc[doc.index("omega_bracket"):doc.index("multiplier:")]
