"""Poincare-section periodicity (hbm.ti.periodicity.classify_period) on sequences whose
mismatches are computed by hand.

With sections y_k and scale 1: mis_p = max_k |y_{k+p} - y_k|.
"""
import math

import numpy as np
import pytest

from hbm.ti.periodicity import PeriodClass, classify_period


def test_zero_tolerance_accepts_an_exact_repeat():
    """rtol = 0 asks for an exact repeat: the sections 1, 3, 1, 3, ... repeat exactly after 2."""
    y = np.tile([1.0, 3.0], 10)[:19]
    per = classify_period(y, n_lobes=2, rtol=0.0)
    assert (per.code, per.period, per.order, per.mismatch) == (PeriodClass.REVOLUTION, 2, 1.0, 0.0)


def test_a_multiple_of_the_failed_casing_period_must_beat_it_by_the_margin():
    """y_k = A (-1)^k + d k, A = d = 0.004 (scale 1, rtol 0.01): mis_1 = 2 A + d = 0.012 fails,
    mis_2 = 2 d = 0.008 is within rtol but not twice better than mis_1 (0.006): not accepted;
    mis_3 = 2 A + 3 d = 0.02, mis_p >= p d > rtol for p >= 3: no period. The reported mismatch is
    the smallest tried, mis_2."""
    k = np.arange(41)
    y = 0.004 * (-1.0) ** k + 0.004 * k
    per = classify_period(y, n_lobes=2, rtol=1e-2, scale=np.array([1.0]))
    assert per.code == PeriodClass.NONE and per.period == 0
    assert per.mismatch == pytest.approx(0.008, rel=1e-9)


def test_a_drift_has_no_period_and_its_mismatch_is_one_step():
    """y_k = d k with d = 0.02 > rtol (an unfinished transient): mis_p = p d, none within rtol;
    the smallest mismatch is that of p = 1, d."""
    y = 0.02 * np.arange(41)
    per = classify_period(y, n_lobes=2, rtol=1e-2, scale=np.array([1.0]))
    assert per.code == PeriodClass.NONE and math.isnan(per.order)
    assert per.mismatch == pytest.approx(0.02, rel=1e-9)


@pytest.mark.parametrize("n_lobes", [1, 2, 3])
def test_max_order_of_one_casing_period_is_allowed(n_lobes):
    """max_order = 1 / n_lobes is nu of p = 1 (the casing's period): valid, and a response of
    the casing's period is found with it."""
    y = 0.5 + 0.0 * np.arange(9)
    y[::2] += 1e-12  # round-off-sized non-repeat, far within rtol of the scale
    per = classify_period(y, n_lobes=n_lobes, rtol=1e-2, max_order=1.0 / n_lobes, scale=np.array([1.0]))
    assert per.code == PeriodClass.CASING and per.period == 1


def test_a_change_of_4e_11_of_the_size_still_counts_without_a_scale():
    """The default range is raised to 1e-9 of the largest |y| only: sections 1 +- 2e-11 (a
    change of 4e-11 of their size, 4 rtol of that floor at rtol = 1e-2) do not repeat after
    one casing period; they repeat exactly after two."""
    y = 1.0 + 2e-11 * (-1.0) ** np.arange(21)
    per = classify_period(y, n_lobes=2, rtol=1e-2)
    assert per.code == PeriodClass.REVOLUTION and per.period == 2
