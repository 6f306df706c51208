"""The maximum over the period of |g(tau)| (hbm.harmonic.content.peak_magnitudes, the max_t of
eq. 33) for trigonometric polynomials whose largest local maxima of |g| are nearly equal: the
sampled grid may rank them the wrong way round, and only refining every candidate finds the
true maximum. Reference: g evaluated directly (cos / sin sums) on a dense grid, each of its
local maxima of |g| refined by scipy's bounded scalar minimisation."""
import numpy as np
import pytest
from scipy.optimize import minimize_scalar

from hbm.harmonic.content import peak_magnitudes


def _g(c, tau):
    nh = (len(c) - 1) // 2
    k = np.arange(1, nh + 1)
    tau = np.atleast_1d(tau)
    return c[0] + np.cos(np.outer(tau, k)) @ c[1::2] + np.sin(np.outer(tau, k)) @ c[2::2]


def _reference_peak(c, n=20000):
    tau = 2 * np.pi * np.arange(n) / n
    a = np.abs(_g(c, tau))
    local = np.flatnonzero((a >= np.roll(a, 1)) & (a >= np.roll(a, -1)))
    best = a.max()
    h = 2 * np.pi / n
    for i in local:
        r = minimize_scalar(lambda t: -abs(_g(c, t)[0]), bounds=(tau[i] - h, tau[i] + h), method="bounded",
                            options={"xatol": 1e-13})
        best = max(best, -r.fun)
    return best


# c_0 + cos(tau - t0) + a small second harmonic: two peaks of |g| (near t0 and t0 + pi) within
# 4e-4 of each other, less than the sampling error of the 16 (N_h + 1)-point grid, so the grid
# ranks them the wrong way round (refining only the best-sampled one fell short by up to 5e-4)
NEAR_TIES = [
    [0.001209519040123716, 0.36643431081183225, -0.9304439240813266, -0.0019398498881179273, 0.003760746656273776],
    [-0.000908097381590818, -0.5244922433796814, -0.851415225747431, 0.006522645332528899, 0.00428527590744231,
     0.0, 0.0],
    [0.0022758790488532684, 0.23640316178733156, -0.971655054583134, -0.002067405917158013, 0.00882256417084505],
    [-0.003121788281932607, -0.8992312281784329, -0.43747365437098823, 0.005154184034192093, -0.000416941736811836],
    [0.0011378862643364029, 0.40293151243342, -0.915230132965538, 0.005612111766303201, -0.003962028714314988],
]


def test_nearly_equal_peaks_ranked_the_wrong_way_by_the_grid():
    for c in map(np.array, NEAR_TIES):
        ref = _reference_peak(c)
        assert 1.0 < ref < 1.001
        np.testing.assert_allclose(peak_magnitudes(c[:, None]), [ref], rtol=1e-13)


def test_random_polynomials_against_a_dense_refined_maximum():
    rng = np.random.default_rng(2026)
    nh = 5
    coeffs = rng.standard_normal((2 * nh + 1, 40)) / (1.0 + np.repeat(np.arange(nh + 1), 2)[1:])[:, None]
    ref = np.array([_reference_peak(coeffs[:, j]) for j in range(coeffs.shape[1])])
    np.testing.assert_allclose(peak_magnitudes(coeffs), ref, rtol=1e-12)


def test_pure_harmonic_peaking_half_way_between_samples():
    # cos(k (tau - t0)) has |g| = 1 at its peaks, hand value; t0 half a sample of the
    # 16 (N_h + 1)-point grid off it, two samples tie at every peak (a plateau of the sampled
    # |g|): the peak must still be found (a strict local-maximum test missed it by up to 1.2 %)
    for nh in range(1, 9):
        dtau = 2 * np.pi / (16 * (nh + 1))
        cols = []
        for k in range(1, nh + 1):
            for j in range(3):
                t0 = (j + 0.5) * dtau
                c = np.zeros(2 * nh + 1)
                c[2 * k - 1], c[2 * k] = np.cos(k * t0), np.sin(k * t0)
                cols.append(c)
        np.testing.assert_allclose(peak_magnitudes(np.stack(cols, axis=1)), 1.0, rtol=1e-13)


@pytest.mark.parametrize("t0", [0.0, 0.37, 1.0])
def test_a_peak_of_the_other_sign_between_samples_is_found(t0):
    """Harmonic 16 of N_h = 16 plus a small negative mean: 16 (N_h + 1) / 16 = 17 samples a
    period of the harmonic, so its positive peaks can all fall on samples and its negative
    ones half-way between; the maximum of |g| is a negative peak, 1.002 exactly."""
    nh = k = 16
    c = np.zeros((2 * nh + 1, 1))
    c[0], c[2 * k - 1], c[2 * k] = -0.002, np.cos(k * t0), np.sin(k * t0)
    assert peak_magnitudes(c)[0] == pytest.approx(1.002, rel=1e-12)
