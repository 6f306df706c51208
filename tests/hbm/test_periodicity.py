"""Periodicity classification (hbm.ti.periodicity) on synthetic signals of known period.

Signals are continuous functions of t sampled at the Poincare sections t_k = k T_c,
T_c = pi / Omega (two lobes), with uniform noise of 10 % of the tolerance: every class must
come out right, and noise of twice the tolerance must destroy the period.
"""
import numpy as np
import pytest

from hbm.ti.periodicity import PeriodClass, classify_period

CASING, REVOLUTION, SUBHARMONIC, NONE, SUPERHARMONIC = PeriodClass

OMEGA = 1234.0
RTOL = 1e-2


def sections(f, n_sec=41, noise=0.1 * RTOL, channels=3, seed=0):
    """f(t, phase) sampled at t_k = k pi / Omega on a few channels (different phases), plus
    uniform noise of `noise` times each channel's range over the window (from 64 samples per
    casing period; a sampled map has no in-between and uses the sections' range).
    Returns (sections (n_sec, channels), range (channels,))."""
    t = np.arange(n_sec) * np.pi / OMEGA
    y = np.stack([f(t, 0.7 * c) for c in range(channels)], axis=1)
    try:
        tf = np.arange(64 * (n_sec - 1) + 1) * np.pi / OMEGA / 64
        rng_y = np.ptp(np.stack([f(tf, 0.7 * c) for c in range(channels)], axis=1), axis=0)
    except ValueError:
        rng_y = np.ptp(y, axis=0)
    gen = np.random.default_rng(seed)
    return y + noise * rng_y * gen.uniform(-1, 1, y.shape), rng_y


def classify(args, **kw):
    y, scale = args
    return classify_period(y, scale=scale, **kw)


def periodic(nu):
    """A multiharmonic signal of fundamental omega = Omega / nu (nu = Omega / omega)."""
    w = OMEGA / nu
    return lambda t, p: np.cos(w * t + p) + 0.4 * np.sin(2 * w * t + 2 * p) + 0.2 * np.cos(3 * w * t + 0.1)


@pytest.mark.parametrize("nu,code,period", [(0.5, CASING, 1), (1.0, REVOLUTION, 2), (1.5, SUBHARMONIC, 3),
                                            (3.0, SUBHARMONIC, 6), (7.0, SUBHARMONIC, 14), (10.0, SUBHARMONIC, 20)])
def test_periodic_signals_get_their_class_and_order(nu, code, period):
    c = classify(sections(periodic(nu)), n_lobes=2, rtol=RTOL, max_order=10)
    assert (c.code, c.period) == (code, period)
    assert c.order == pytest.approx(nu)
    assert c.mismatch <= 2 * 0.1 * RTOL * 1.0001  # two samples' noise at most


def test_casing_periodic_signal_with_many_harmonics_of_2_omega():
    f = lambda t, p: sum(np.cos(2 * k * OMEGA * t + k * p) / k for k in range(1, 30))
    assert classify(sections(f), rtol=RTOL).code == CASING


def test_quasi_periodic_and_chaotic_signals_have_no_period():
    qp = lambda t, p: np.cos(OMEGA * t + p) + np.cos(np.sqrt(2) * OMEGA * t)
    assert classify(sections(qp), rtol=RTOL).code == NONE

    def logistic(t, p):  # chaotic map, one iterate per casing period
        y = np.empty(len(t))
        y[0] = 0.3 + 0.1 * p
        for k in range(1, len(t)):
            y[k] = 3.9 * y[k - 1] * (1 - y[k - 1])
        return y
    c = classify(sections(logistic, noise=0.0), rtol=RTOL)
    assert c.code == NONE and np.isnan(c.order) and c.mismatch > RTOL


def test_omega_below_omega_over_max_order_is_none_and_found_with_a_larger_order():
    y = sections(periodic(12.0), n_sec=101)
    assert classify(y, rtol=RTOL, max_order=10).code == NONE
    c = classify(y, rtol=RTOL, max_order=15)
    assert (c.code, c.period) == (SUBHARMONIC, 24)


def test_window_too_short_for_the_period_is_none():
    # nu = 10 needs p = 20 casing periods seen twice: 41 sections do, 30 do not
    assert classify(sections(periodic(10.0), n_sec=30), rtol=RTOL).code == NONE


def test_noise_above_the_tolerance_breaks_periodicity():
    assert classify(sections(periodic(1.0), noise=2 * RTOL, seed=3), rtol=RTOL).code != REVOLUTION


def test_constant_signal_and_other_lobe_counts():
    assert classify_period(np.full((10, 2), 3.0)).code == CASING
    # three lobes: omega = 3 Omega / p; p = 3 is omega = Omega, p = 2 lies between Omega and 3 Omega
    t = np.arange(61) * 2 * np.pi / (3 * OMEGA)
    y = np.cos(1.5 * OMEGA * t)[:, None]
    c = classify_period(y, n_lobes=3, rtol=RTOL)
    assert (c.code, c.period, c.order) == (SUPERHARMONIC, 2, pytest.approx(2 / 3))
    y = np.cos(OMEGA * t + 0.3)[:, None]
    assert classify_period(y, n_lobes=3, rtol=RTOL).code == REVOLUTION
