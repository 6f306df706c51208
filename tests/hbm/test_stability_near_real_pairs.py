"""A complex pair of Floquet multipliers within REAL_ARG_TOL of the real axis: recorded as
one bifurcation where it crosses the unit circle (bifurcation.upper_half keeps one member
for the pairing), but two multipliers in every count of unstable ones. The spectra are
given in closed form (as in test_stability_monitor.py); the counts are made by hand."""
from types import SimpleNamespace

import numpy as np
import pytest

from hbm.stability.bifurcation import BRANCH_POINT, CROSSING, PARITY, PERIOD_DOUBLING, real_parities, upper_half
from hbm.stability.monitor import StabilityMonitor, StabilityOptions
from hbm.stability.spectrum import FloquetSpectrum

OMEGA = 1000.0


def spectrum(mu) -> FloquetSpectrum:
    """An Arnoldi-like spectrum listing the multipliers mu (every one with |log|mu|| < 3)."""
    mu = np.asarray(mu, complex)
    mu = mu[np.argsort(-np.abs(mu), kind="stable")]
    k = len(mu)
    return FloquetSpectrum(omega=OMEGA, exponents=np.log(mu) * OMEGA / (2 * np.pi), multipliers=mu,
                           centred=np.ones(k, bool), edge_energy=np.zeros(k),
                           eigenvectors=np.zeros((k, 3, 2), complex), modulus_floor=0.05, method="arnoldi")


def monitored(before, after, at: int = 40, n: int = 80):
    """The monitor over n points (Omega decreasing, no turn) whose multipliers are `before` up
    to point `at` and `after` past it: (monitor, {index: extras handed back})."""
    mon = StabilityMonitor(analyse=lambda x, w: (spectrum(before if x[0] <= at else after), 1),
                           options=StabilityOptions())
    got = {}
    for i in range(n):
        p = SimpleNamespace(index=i, omega=OMEGA - i, step=1.0, x=np.array([float(i)]))
        got.update((q.index, ex) for q, ex in mon.push(p, {"le_amplitude": 1e-4 * i}))
    got.update((q.index, ex) for q, ex in mon.finish())
    return mon, got


def pair(modulus: float, arg: float) -> list:
    return [modulus * np.exp(1j * arg), modulus * np.exp(-1j * arg)]


@pytest.mark.parametrize("mu, counts", [
    # a pair at arg +-0.01 and at pi -+ 0.01, |mu| 1.05: two unstable, and |1 -+ mu|^2 > 0
    # changes neither sign; a lone near-real one (no conjugate: a real one the truncation
    # moved, arg -0.015) is one real multiplier beyond +1
    (pair(1.05, 0.01), (2, 0, 0)),
    (pair(1.05, np.pi - 0.01), (2, 0, 0)),
    ([1.05 * np.exp(-0.015j)], (1, 0, 1)),
])
def test_a_near_real_pair_outside_the_circle_counts_two_unstable_multipliers(mu, counts):
    sp = spectrum(mu + [0.5, 0.3])
    assert sp.n_unstable == counts[0]
    assert real_parities(sp.multipliers, sp.unstable, 3.0) == counts
    # the pairing keeps one member of a pair, a lone one, and the stable real ones
    assert np.count_nonzero(upper_half(sp.multipliers)) == 3


@pytest.mark.parametrize("arg, kind", [(0.01, BRANCH_POINT), (np.pi - 0.01, PERIOD_DOUBLING)])
def test_a_near_real_pair_crossing_is_one_record_and_two_in_the_stored_counts(arg, kind):
    mon, got = monitored(pair(0.98, arg) + [0.5], pair(1.02, arg) + [0.5])
    assert [got[i]["n_unstable"] for i in (40, 41)] == [0, 2]
    assert [(b.kind, b.kind_from, b.direction, b.index) for b in mon.bifurcations] == [(kind, CROSSING, 1, 40)]


# a real multiplier -0.9 goes out through -1 and meets -1.3 there, both leaving the real axis
# as a pair 1.144 exp(+-(pi - 0.266) i): -1.3 pairs with it (unstable on both sides), -0.9 with
# nothing, while det(I + M) changes sign
THROUGH_MINUS_ONE = ([-1.3, -0.9], pair(1.144, np.pi - 0.266), (PERIOD_DOUBLING, PARITY, 1, 40, -1.3))
# a real multiplier 1.95 appears with no counterpart while det(I - M) changes sign
THROUGH_PLUS_ONE = ([], [1.95], (BRANCH_POINT, PARITY, 1, 40, 1.95))


@pytest.mark.parametrize("arg, near_kind", [(0.01, BRANCH_POINT), (np.pi - 0.01, PERIOD_DOUBLING)])
@pytest.mark.parametrize("before, after, real", [THROUGH_MINUS_ONE, THROUGH_PLUS_ONE])
def test_a_real_crossing_beside_a_near_real_pair_crossing_is_recorded(arg, near_kind, before, after, real):
    # the near-real pair 0.98 -> 1.02 counts two of the count change and changes no parity:
    # the rest of the change (one) and the sign change are the real crossing's, added half-way
    mon, got = monitored(pair(0.98, arg) + before + [0.5], pair(1.02, arg) + after + [0.5])
    n_a, n_b = got[40]["n_unstable"], got[41]["n_unstable"]
    assert n_b - n_a == 3  # by hand: the pair (2) and the real one (1) went out
    recs = sorted((b.kind, b.kind_from, b.direction, b.index) for b in mon.bifurcations)
    assert recs == sorted([(near_kind, CROSSING, 1, 40), real[:4]])
    (added,) = [b for b in mon.bifurcations if b.kind_from == PARITY]
    assert added.multiplier == real[4] and added.fraction == 0.5
