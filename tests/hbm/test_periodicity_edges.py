"""Edge cases of the periodicity classifier (hbm.ti.periodicity.classify_period) on section
sequences whose smallest period is known by construction: a random pattern of p values
repeated (no shorter period), plus noise or drift of a known size.

What each test pins: the max_order boundary and the two-periods rule, that the smallest period
within rtol wins, that a period is not claimed at a multiple of one that failed only because
the multiple is compared over fewer pairs, drift of just below / above rtol per period,
channels of very different ranges, and that meaningless arguments raise.
"""
import numpy as np
import pytest

from hbm.ti.periodicity import PeriodClass, classify_period

CASING, REVOLUTION, SUBHARMONIC, NONE, SUPERHARMONIC = PeriodClass
RTOL = 1e-2


def repeated(p, n_sec, channels=2, seed=0):
    """A random pattern of p sections, (p, channels), in [-1, 1], repeated to n_sec sections:
    smallest period exactly p. Returns (sections (n_sec, channels), scale (channels,))."""
    base = np.random.default_rng(seed).uniform(-1.0, 1.0, (p, channels))
    y = base[np.arange(n_sec) % p]
    return y, np.ptp(y, axis=0)


@pytest.mark.parametrize("n_l", [2, 3])
def test_period_at_the_max_order_boundary_and_seen_twice(n_l):
    """p = max_order n_l (nu = max_order) is found once the window holds it twice plus one
    section (n_sec = 2 p + 1), not with one section less; p + 1 (nu just above) never is."""
    p = 10 * n_l
    c = classify_period(repeated(p, 2 * p + 1)[0], n_lobes=n_l, rtol=RTOL, max_order=10.0)
    assert (c.code, c.period, c.mismatch) == (SUBHARMONIC, p, 0.0)
    assert c.order == pytest.approx(10.0)
    assert classify_period(repeated(p, 2 * p)[0], n_lobes=n_l, rtol=RTOL, max_order=10.0).code == NONE
    for n_sec in (2 * p + 3, 4 * p + 4):
        assert classify_period(repeated(p + 1, n_sec)[0], n_lobes=n_l, rtol=RTOL, max_order=10.0).code == NONE
    # a max_order that is not a whole number of casing periods: nu = 10 / 3 is p = 10 of 3 lobes
    c = classify_period(repeated(10, 21)[0], n_lobes=3, rtol=RTOL, max_order=10.0 / 3.0)
    assert (c.code, c.period) == (SUBHARMONIC, 10)


def noisy(p, pair_noise, n_sec=41, seed=0):
    """repeated(p) plus uniform noise whose largest difference between sections p apart is
    exactly pair_noise of the scale, 2 on every channel (the pattern's values lie in [-1, 1]).
    Returns (sections (n_sec, 2), scale (2,))."""
    y, _ = repeated(p, n_sec)
    noise = np.random.default_rng(100 + seed).uniform(-1.0, 1.0, y.shape)
    noise *= pair_noise / np.abs(noise[p:] - noise[:-p]).max()
    return y + 2.0 * noise, np.full(2, 2.0)


@pytest.mark.parametrize("n_l,p", [(2, 2), (2, 1), (3, 3)])
def test_an_orbit_whose_noise_exceeds_rtol_is_none_not_a_multiple_of_its_period(n_l, p):
    """Noise of 1.3 rtol between sections one true period apart: no period within rtol. The
    multiples of p are compared over fewer pairs and used to pass by chance (p = 2 of two lobes
    called subharmonic with nu = 4, 9 or 10, a figure's marker for an orbit that has none)."""
    for seed in range(12):
        y, scale = noisy(p, 1.3 * RTOL, seed=seed)
        c = classify_period(y, n_lobes=n_l, rtol=RTOL, scale=scale)
        assert (c.code, c.period) == (NONE, 0), seed


@pytest.mark.parametrize("pair_noise", [0.0, 0.5 * RTOL, 0.9 * RTOL])
def test_a_genuine_period_doubling_just_above_rtol_is_found_under_noise(pair_noise):
    """A p = 2 orbit with a period-4 part of amplitude c = 0.6 rtol of the scale (difference
    2 c = 1.2 rtol after two sections, above rtol) is period 4 as long as c >= noise / 2, the
    margin of hbm.ti.periodicity.MULTIPLE_MARGIN = 2; and a nu = 10 orbit (p = 20) under noise just below rtol is
    still p = 20."""
    k = np.arange(41)
    base = np.where(k % 2 == 0, 1.0, -1.0)
    doubled = np.where(k % 4 == 0, 1.0, np.where(k % 4 == 2, -1.0, 0.0))
    y = base + 0.6 * RTOL * 2.0 * doubled  # scale 2 (the base's range)
    y += 2.0 * pair_noise * np.random.default_rng(7).uniform(-0.5, 0.5, 41)
    c = classify_period(y, rtol=RTOL, scale=np.array([2.0]))
    assert (c.code, c.period) == (SUBHARMONIC, 4)
    for seed in range(5):
        y, scale = noisy(20, 0.9 * RTOL, seed=seed)
        c = classify_period(y, rtol=RTOL, scale=scale)
        assert (c.code, c.period) == (SUBHARMONIC, 20)


def test_the_smallest_period_within_rtol_wins_over_its_multiples():
    """Period 4 [1, -1, 1 + 2 d, -1] of scale 2 + 2 d: after 2 sections the difference is
    2 d / scale. Within rtol it is p = 2 (the docstring's choice), just above it is p = 4."""
    for rel, period in ((0.98 * RTOL, 2), (1.02 * RTOL, 4)):
        d = rel / (1.0 - rel)  # 2 d / (2 + 2 d) = rel
        y = np.array([1.0, -1.0, 1.0 + 2 * d, -1.0])[np.arange(41) % 4]
        c = classify_period(y, rtol=RTOL)
        assert c.period == period
        assert c.mismatch == pytest.approx(rel if period == 2 else 0.0, abs=1e-12)


@pytest.mark.parametrize("rel,code", [(0.98 * RTOL, REVOLUTION), (1.02 * RTOL, NONE)])
def test_a_drift_per_period_just_below_rtol_is_periodic_just_above_is_none(rel, code):
    """y_k = (-1)^k + delta k (an unfinished transient, p = 2 of two lobes), scale 2: the
    mismatch after p = 2 is 2 delta / 2 exactly, after any multiple more."""
    delta = rel
    y = np.where(np.arange(41) % 2 == 0, 1.0, -1.0) + delta * np.arange(41)
    c = classify_period(y, rtol=RTOL, scale=np.array([2.0]))
    assert c.code == code
    assert c.mismatch == pytest.approx(rel, rel=1e-9)


def test_channels_of_very_different_ranges_are_each_held_to_their_own_scale():
    """A p = 3 channel of range 2 and a p = 3 channel of range 1e-9: exact, each to its own
    range, p = 3. Round-off-level noise on the small one (0.1 of its range) breaks the period
    of all with the sections' own ranges; a common scale (the large channel's) restores it. A
    channel of zero range next to them is ignored without a division by zero."""
    y, _ = repeated(3, 31)
    y[:, 1] *= 1e-9
    with np.errstate(all="raise"):
        assert classify_period(np.column_stack([y, np.full(31, 4.0)]), n_lobes=3, rtol=RTOL).period == 3
    y[:, 1] += 1e-10 * np.random.default_rng(3).uniform(-1.0, 1.0, 31)
    assert classify_period(y, n_lobes=3, rtol=RTOL).code == NONE
    common = np.full(2, np.ptp(y[:, 0]))
    assert classify_period(y, n_lobes=3, rtol=RTOL, scale=common).code == REVOLUTION


@pytest.mark.parametrize("kwargs,message", [
    (dict(rtol=float("nan")), "rtol must be a finite number >= 0"),
    (dict(rtol=-1e-2), "rtol must be a finite number >= 0"),
    (dict(max_order=float("nan")), "max_order must be finite"),
    (dict(max_order=float("inf")), "max_order must be finite"),
    (dict(max_order=0.4), r"max_order must be finite and >= 1 / n_lobes = 0.5"),
    (dict(n_lobes=0), "n_lobes must be a whole number >= 1"),
    (dict(n_lobes=2.5), "n_lobes must be a whole number >= 1"),
    (dict(scale=np.array([-1.0])), "scale is a range and must be >= 0"),
])
def test_arguments_that_make_the_classification_meaningless_raise(kwargs, message):
    """An rtol of nan used to accept nothing silently (NONE for an exactly periodic signal)."""
    y = np.where(np.arange(21) % 2 == 0, 1.0, -1.0)
    with pytest.raises(ValueError, match=message):
        classify_period(y, **kwargs)


def test_a_quasi_periodic_part_whose_near_repeat_beats_the_margin_is_periodic_as_stated():
    """The docstring's example: cos(pi k) (p = 2) + a cos(sqrt(2) pi k + 0.3), a part at
    sqrt(2) Omega. Closed form of its non-repeat after p sections: at most
    2 a |sin(pi frac(p sqrt(2) / 2))| / range. a = 0.02 (1 % of the range): after 2 sections
    that is 0.019 (> rtol), after 10 (7.07 cycles) 0.0044 (< rtol and < half of 0.019): p = 10,
    the classifier's limit for quasi-periodic parts. a = 0.05: 0.011 after 10, and NONE."""
    k = np.arange(41)
    for a, code, period in ((0.02, SUBHARMONIC, 10), (0.05, NONE, 0)):
        y = np.where(k % 2 == 0, 1.0, -1.0) + a * np.cos(np.sqrt(2.0) * np.pi * k + 0.3)
        c = classify_period(y, rtol=RTOL)
        assert (c.code, c.period) == (code, period)
        bound = 2 * a * abs(np.sin(np.pi * (10 * np.sqrt(2.0) / 2 % 1.0))) / np.ptp(y)
        if period:
            assert c.mismatch <= bound and c.mismatch == pytest.approx(bound, rel=0.05)
        else:
            assert bound > RTOL
