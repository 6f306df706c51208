"""The settle test and the periodicity classifier against what must not settle (a transient
left in the forces only, a weak quasi-periodic part, a march that blew up), on constructed
histories whose answer is known analytically (hbm.ti.settle, hbm.ti.periodicity).

Histories are recorded as the sweep records them (tests/hbm/test_settle.py: sub-sections at
SUBSECTIONS per casing period from the end of the first revolution, per-revolution radial
extremes then the lone final step, force block samples).
"""
import math

import numpy as np
import pytest

from hbm.ti.periodicity import PeriodClass, classify_period
from hbm.ti.settle import SUBSECTIONS, settle_test

OMEGA, N_KEEP, RTOL = 1000.0, 20, 1e-2
T_REV = 2 * math.pi / OMEGA


def history(y, f, revs, n_l, spr, fine=256):
    """(subsections, extremes, forces) after `revs` revolutions of y(t) (n_ch,) and f(t) (n_ch,)."""
    t_sub = T_REV + np.arange((revs - 1) * n_l * SUBSECTIONS + 1) * T_REV / (n_l * SUBSECTIONS)
    ext = []
    for b in range(revs):
        tt = (b + 1) * T_REV + (np.arange(fine) * T_REV / fine if b < revs - 1 else np.zeros(1))
        yy = y(tt)
        ext.append(np.stack([yy.max(axis=0), yy.min(axis=0)]))
    t_f = T_REV + np.arange((revs - 1) * spr) * T_REV / spr
    return y(t_sub), np.array(ext), f(t_f)


def test_three_lobes_a_transient_left_in_the_contact_force_keeps_the_march_going():
    """Three lobes at 64 samples a revolution: a casing period is 64 / 3 force samples, not a
    whole number. Displacements exactly periodic (period T_c) from the start, the contact
    force not: f = max(cos(3 Omega t), 0) + 0.5 exp(-t / tau), tau the decay time the test
    assumes. The force transient left at the start of the window is 0.5 exp(-t_0 / tau)
    of the force's range (1) analytically: the test may stop only once that is <= the
    tolerance. (It used to skip the forces over one period and stop at once.)"""
    n_l, spr, settle = 3, 64, 1e-4
    tau = 5 * T_REV
    w = n_l * OMEGA

    def y(t):
        return np.stack([np.cos(w * t + c) for c in (0.0, 0.9)], axis=1)

    def f(t):
        return np.maximum(y(t), 0.0) + 0.5 * np.exp(-t / tau)[:, None]

    first = None
    for revs in range(N_KEEP + 2, 121):
        v = settle_test(*history(y, f, revs, n_l, spr, fine=64), spr, n_l, N_KEEP, OMEGA, tau, RTOL, 10.0, settle)
        assert v.periodicity.period == 1
        if v.settled:
            first = revs
            break
    assert first is not None
    t0 = T_REV * (first - N_KEEP)  # first instant of the window (sample times start at T_rev)
    left = 0.5 * math.exp(-t0 / tau)
    assert left <= settle, (first, left)
    # the same history without the force transient settles at once
    v = settle_test(*history(y, lambda t: np.maximum(y(t), 0.0), N_KEEP + 2, n_l, spr, fine=64), spr, n_l,
                    N_KEEP, OMEGA, tau, RTOL, 10.0, settle)
    assert v.settled


def periodic(t):
    """Three channels of period T_rev / 2 (p = 1 of two lobes), each of range ~2.6."""
    w = 2 * OMEGA
    return np.stack([np.cos(w * t + c) + 0.3 * np.sin(3 * w * t + 2 * c) for c in (0.0, 0.9, 2.1)], axis=1)


@pytest.mark.parametrize("part", [3e-3, 4.5e-3])
def test_a_weak_quasi_periodic_part_never_stops_the_march(part):
    """periodic + a cos(sqrt(2) Omega t): quasi-periodic, the incommensurate part `part` of
    each channel's range (3 and 4.5 times the sweep's settle_rtol of 1e-3, below the
    classifier's 1e-2, which calls it periodic). Nothing decays: the window is never within
    1e-3 of a periodic orbit, so the march must run to its 200-revolution cap. With the
    decay time of rotor 67's 1B (~60 revolutions), a lag of 128 revolutions (nearly 181
    cycles of the sqrt(2) part) used to let it stop at 149 revolutions with a bound of 1e-4."""
    tau = 60 * T_REV
    rng = np.ptp(periodic(np.linspace(0.0, T_REV, 4001)), axis=0)

    def y(t):
        return periodic(t) + part * rng * np.cos(math.sqrt(2) * OMEGA * t[:, None] + np.array([0.0, 1.0, 2.0]))

    def f(t):
        return np.maximum(periodic(t)[:, :2], 0.0)

    spr = 64
    h = history(y, f, 200, 2, spr)
    for revs in range(N_KEEP + 2, 201):
        n_sub = (revs - 1) * 2 * SUBSECTIONS + 1
        ext = np.concatenate([h[1][:revs - 1], np.repeat(y(np.array([revs * T_REV])), 2, axis=0)[None]])
        v = settle_test(h[0][:n_sub], ext, h[2][:(revs - 1) * spr], spr, 2, N_KEEP, OMEGA, tau, RTOL, 10.0, 1e-3)
        assert v.periodicity.code == PeriodClass.CASING
        assert not v.settled, (revs, v.bound, v.lag)
        assert v.bound >= 0.5 * part  # at least half the part's non-repeat over the window


def test_a_quasi_periodic_part_well_below_the_tolerance_still_stops():
    """The control: a persistent part of 1e-5 of the range (below the time grid's floor on
    rotor 67) plus a transient at the assumed decay, in the displacements and in a force of
    1 kN with a floor of 1e-6 of its range: the march stops, with what is left (transient
    and part together) within the tolerance."""
    tau = 5 * T_REV
    settle = 1e-4
    rng = np.ptp(periodic(np.linspace(0.0, T_REV, 4001)), axis=0)

    def y(t):
        return (periodic(t) + 1e-5 * rng * np.cos(math.sqrt(2) * OMEGA * t[:, None])
                + 0.5 * np.exp(-t / tau)[:, None] * np.cos(2.7 * OMEGA * t[:, None]))

    def f(t):
        # with 1e-6 of jitter (the time grid's floor: contact starts and ends on steps)
        return 1e3 * (np.maximum(periodic(t)[:, :2], 0.0) + 0.5 * np.exp(-t / tau)[:, None]
                      + 1e-6 * np.sin(1.2345e7 * t)[:, None])

    for revs in range(N_KEEP + 2, 201):
        v = settle_test(*history(y, f, revs, 2, 64), 64, 2, N_KEEP, OMEGA, tau, RTOL, 10.0, settle)
        if v.settled:
            break
    assert v.settled
    t = T_REV * (1 + np.linspace(revs - N_KEEP - 1, revs - 1, 4000))
    assert (np.abs(y(t) - periodic(t)) / rng).max() <= 1.2 * settle  # between samples: up to ~10 % over


def test_a_signal_that_blows_up_has_no_period_and_never_settles():
    """Sections NaN from the 30th on (a march that diverged): no period, not 'omega = 2 Omega'
    with mismatch 0."""
    y = np.cos(np.pi * np.arange(41))[:, None] * np.ones((1, 2))
    y[30:] = np.nan
    p = classify_period(y)
    assert p.code == PeriodClass.NONE and p.period == 0
    p = classify_period(np.cos(np.pi * np.arange(41)), scale=np.array([np.nan]))
    assert p.code == PeriodClass.NONE

    def bad(t):
        out = periodic(t)
        out[t > 24.5 * T_REV] = np.nan
        return out

    v = settle_test(*history(bad, lambda t: np.zeros((len(t), 2)), 30, 2, 64, fine=64), 64, 2, N_KEEP, OMEGA,
                    5 * T_REV, RTOL, 10.0, 1e-4)
    assert not v.settled and v.periodicity.code == PeriodClass.NONE
