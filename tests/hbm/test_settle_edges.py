"""The settle test (hbm.ti.settle) on histories that must not stop the march, or must stop it
only on the right orbit: a march that blew up in its forces or its history only, and a period
doubling that grows in view. Histories are recorded as the sweep records them
(tests/hbm/test_settle_persistent.py: history).
"""
import math

import numpy as np

from hbm.ti.periodicity import PeriodClass
from hbm.ti.settle import SUBSECTIONS, settle_test
from test_settle_persistent import history, periodic

OMEGA, N_KEEP, RTOL, SETTLE = 1000.0, 20, 1e-2, 1e-4
T_REV = 2 * math.pi / OMEGA
TAU = 5 * T_REV
RANGE = np.ptp(periodic(np.linspace(0.0, T_REV, 4001)), axis=0)


def contact(t):
    """Normal force of two nodes, periodic like the displacements, (n_t, 2), N."""
    return np.maximum(periodic(t)[:, :2], 0.0)


def test_a_march_with_a_value_that_is_not_finite_is_not_settled_and_has_no_period():
    """Displacements exactly periodic, so the Poincare sections say p = 1: a force that blew
    up (nan, inf) in the window, or a nan in the extremes before the window, used to be
    dropped by the comparisons (nan is never larger) and the march stopped as settled with
    a bound of 3e-14."""
    def blown(value):
        def f(t):
            out = contact(t)
            out[t > 20.5 * T_REV] = value
            return out
        return f

    verdicts = [settle_test(*history(periodic, blown(v), 30, 2, 64), 64, 2, N_KEEP, OMEGA, TAU, RTOL, 10.0, SETTLE)
                for v in (np.nan, np.inf)]
    sub, ext, f = history(periodic, contact, 30, 2, 64)
    ext[2, 0, 0] = np.nan
    verdicts.append(settle_test(sub, ext, f, 64, 2, N_KEEP, OMEGA, TAU, RTOL, 10.0, SETTLE))
    sub, ext, f = history(periodic, contact, 30, 2, 64)
    sub[-5, 0] = np.nan  # between two Poincare sections
    verdicts.append(settle_test(sub, ext, f, 64, 2, N_KEEP, OMEGA, TAU, RTOL, 10.0, SETTLE))
    for v in verdicts:
        assert not v.settled and v.bound == math.inf
        assert v.periodicity.code == PeriodClass.NONE and v.periodicity.period == 0
    # the same history, all finite, settles at once (the control)
    assert settle_test(*history(periodic, contact, 30, 2, 64), 64, 2, N_KEEP, OMEGA, TAU, RTOL, 10.0, SETTLE).settled


def test_a_period_doubling_that_grows_in_view_stops_only_on_the_doubled_orbit():
    """periodic (p = 1) + A(t) cos(Omega t + phase) (p = 2 of two lobes), A a logistic growth
    to 0.05 of the range with onset at 40 revolutions and 4 revolutions' rate (within the
    decay time of 10 revolutions the test assumes): 5e-4 of the range at the first test, so in
    view. The march must not stop on the p = 1 orbit it is leaving, and where it stops the
    window must be within the tolerance (plus the docstring's tenth between instants) of the
    doubled orbit periodic + 0.05 cos(Omega t + phase), with p = 2."""
    tau, t_on, width, a_sat = 10 * T_REV, 40.0, 4.0, 0.05
    phase = np.array([0.2, 1.0, 2.0])

    def y(t):
        a = a_sat / (1.0 + np.exp(-(t / T_REV - t_on) / width))
        return periodic(t) + (a[:, None] * RANGE) * np.cos(OMEGA * t[:, None] + phase)

    def doubled(t):
        return periodic(t) + a_sat * RANGE * np.cos(OMEGA * t[:, None] + phase)

    h = history(y, contact, 200, 2, 64)
    for revs in range(N_KEEP + 2, 201):
        n_sub = (revs - 1) * 2 * SUBSECTIONS + 1
        ext = np.concatenate([h[1][:revs - 1], np.repeat(y(np.array([revs * T_REV])), 2, axis=0)[None]])
        v = settle_test(h[0][:n_sub], ext, h[2][:(revs - 1) * 64], 64, 2, N_KEEP, OMEGA, tau, RTOL, 10.0, SETTLE)
        if v.settled:
            break
    assert v.settled and v.periodicity.code == PeriodClass.REVOLUTION and v.periodicity.period == 2
    t = T_REV * (1 + np.linspace(revs - N_KEEP - 1, revs - 1, 4000))
    assert (np.abs(y(t) - doubled(t)) / RANGE).max() <= 1.2 * SETTLE, revs
