"""The settle test (hbm.ti.settle) on synthetic histories with a known transient.

A history is built exactly as the sweep records it (sub-sections at SUBSECTIONS per casing
period from the end of the first revolution, per-revolution radial extremes, force samples)
from y(t) = periodic(t) + transient(t). The bound of the module docstring must hold whenever
the test says "settled": the transient left anywhere in the window is at most settle_rtol of
the range. Signals without a period never settle.
"""
import math

import numpy as np
import pytest

from hbm.ti.settle import SUBSECTIONS, settle_test

OMEGA, N_L, SPR, N_KEEP, RTOL, SETTLE = 1000.0, 2, 64, 20, 1e-2, 1e-4
T_REV = 2 * math.pi / OMEGA


def history(y, f, revs, fine=512):
    """(subsections, extremes, forces) after `revs` revolutions of y(t) (n_ch,) and f(t) (n_ch,)."""
    t_sub = T_REV + np.arange((revs - 1) * N_L * SUBSECTIONS + 1) * T_REV / (N_L * SUBSECTIONS)
    sub = y(t_sub)
    ext = []
    for b in range(revs):  # block b: steps (b + 1) T_rev .. (b + 2) T_rev (exclusive), the last only its start
        tt = (b + 1) * T_REV + (np.arange(fine) * T_REV / fine if b < revs - 1 else np.zeros(1))
        yy = y(tt)
        ext.append(np.stack([yy.max(axis=0), yy.min(axis=0)]))
    t_f = T_REV + np.arange((revs - 1) * SPR) * T_REV / SPR
    return sub, np.array(ext), f(t_f)


def periodic(t):
    """Three channels of period T_rev / 2 (the casing's, p = 1)."""
    w = N_L * OMEGA
    return np.stack([np.cos(w * t + c) + 0.3 * np.sin(3 * w * t + 2 * c) for c in (0.0, 0.9, 2.1)], axis=1)


def run(y, f, decay_time, revs_max=200):
    """First revolution at which the test settles (None if never) and, at every revolution it
    says settled, the transient actually left in the window relative to each channel's range."""
    first, worst = None, 0.0
    for revs in range(N_KEEP + 3, revs_max + 1):
        v = settle_test(*history(y, f, revs), SPR, N_L, N_KEEP, OMEGA, decay_time, RTOL, 10.0, SETTLE)
        if v.settled:
            first = first or revs
            t = T_REV * (1 + np.linspace(revs - N_KEEP - 1, revs - 1, 2000))
            rng = np.ptp(periodic(t), axis=0)
            worst = max(worst, float((np.abs(y(t) - periodic(t)) / rng).max()))
            break
    return first, worst


@pytest.mark.parametrize("w_t", [6.0 * OMEGA, 2.7 * OMEGA, 0.0])
@pytest.mark.parametrize("slower", [1.0, 0.1])
def test_a_decaying_transient_is_within_the_tolerance_when_the_test_stops(w_t, slower):
    """Transient 0.5 exp(-t / tau_t) cos(w_t t + phase): tau_t equal to the decay time the test
    assumes (the slowest allowed) or 10 times faster; w_t a multiple of the casing's frequency
    (the transient then looks periodic, the hardest case), a non-commensurate one, and 0 (a
    drift). The march must not stop while the transient exceeds 1e-4 of the range, and must
    stop once it has long died out (within 40 % more revolutions than the bound needs)."""
    decay = 5 * T_REV  # short, to keep the test cheap: 5 revolutions
    tau_t = slower * decay

    def y(t):
        return periodic(t) + 0.5 * np.exp(-t / tau_t)[:, None] * np.cos(w_t * t[:, None] + np.array([0.3, 1.0, 2.0]))

    def f(t):
        return np.maximum(periodic(t)[:, :2], 0.0)

    first, worst = run(y, f, decay)
    assert first is not None and worst <= SETTLE
    # the bound needs 0.5 e^{-(first - n_keep) T / tau_t} ~ 1e-4 (1 - rho) / rho, i.e. about
    # n_keep + tau_t / T ln(0.5 / (1e-4 (1 - rho))) revolutions for a transient at the assumed rate
    rho = math.exp(-T_REV / N_L / decay)
    needed = N_KEEP + tau_t / T_REV * math.log(0.5 / (SETTLE * (1 - rho)))
    assert first <= 1.4 * needed + 2


def test_a_transient_hidden_in_the_contact_force_keeps_the_march_going():
    """Displacements exactly periodic from the start, the force not (a node held on the casing
    while the structure behind it still rings): no stop until the force has settled too."""
    decay = 5 * T_REV

    def f(t):
        return np.maximum(periodic(t)[:, :2], 0.0) + 0.5 * np.exp(-t / decay)[:, None]

    v = settle_test(*history(periodic, f, 30), SPR, N_L, N_KEEP, OMEGA, decay, RTOL, 10.0, SETTLE)
    assert not v.settled and v.periodicity.period == 1
    v = settle_test(*history(periodic, lambda t: np.maximum(periodic(t)[:, :2], 0.0), 30), SPR, N_L, N_KEEP,
                    OMEGA, decay, RTOL, 10.0, SETTLE)
    assert v.settled


def test_quasi_periodic_and_chaotic_histories_never_settle():
    def qp(t):
        return np.stack([np.cos(OMEGA * t), np.cos(math.sqrt(2) * OMEGA * t + 0.4)], axis=1)

    def chaotic(t):  # one logistic-map iterate per sample instant
        y = np.empty((len(t), 2))
        y[0] = (0.3, 0.6)
        for k in range(1, len(t)):
            y[k] = 3.9 * y[k - 1] * (1 - y[k - 1])
        return y

    force = lambda t: np.zeros((len(t), 2))  # noqa: E731
    for y in (qp, chaotic):
        for revs in (25, 60, 120, 200):
            v = settle_test(*history(y, force, revs, fine=64), SPR, N_L, N_KEEP, OMEGA, 0.1, RTOL, 10.0, SETTLE)
            assert not v.settled and not math.isfinite(v.bound)


def test_an_undamped_structure_never_settles():
    v = settle_test(*history(periodic, lambda t: np.zeros((len(t), 1)), 30), SPR, N_L, N_KEEP, OMEGA, math.inf,
                    RTOL, 10.0, SETTLE)
    assert v.periodicity.period == 1 and not v.settled


def test_a_march_that_repeats_only_to_a_floor_settles_through_the_longer_lags():
    """A march on a time grid repeats its limit cycle only to a floor (contact starts and ends
    on steps): here 3e-5 m of deterministic jitter at every sample, no period, on top of the
    periodic signal and a transient at the slowest decay the test assumes. Over one casing
    period the bound multiplies the floor by rho / (1 - rho) ~ 9.5 and stays above 1e-4 for
    ever; compared over whole revolutions further back the floor counts about once, so the
    march stops, and the transient left in the window is within the tolerance."""
    decay = 5 * T_REV

    def jitter(t):
        return 3e-5 * np.sin(1.2345e7 * t[:, None] + np.array([0.0, 1.0, 2.0]))

    def y(t):
        return periodic(t) + jitter(t) + 0.5 * np.exp(-t / decay)[:, None] * np.cos(2.7 * OMEGA * t[:, None])

    def f(t):
        return np.maximum(periodic(t)[:, :2], 0.0)

    first = None
    for revs in range(N_KEEP + 3, 201):
        v = settle_test(*history(y, f, revs), SPR, N_L, N_KEEP, OMEGA, decay, RTOL, 10.0, SETTLE)
        if v.settled:
            first = revs
            break
    assert first is not None
    one_period = v.mismatch * v.decay / (1.0 - v.decay)
    assert one_period > SETTLE and v.lag > v.periodicity.period  # the floor alone keeps the one-period bound up
    t = T_REV * (1 + np.linspace(first - N_KEEP - 1, first - 1, 2000))
    rng = np.ptp(periodic(t), axis=0)
    assert (0.5 * np.exp(-t / decay)[:, None] / rng).max() <= SETTLE
