"""hbm.isolas.harmonic.ti_seeds: which time-integration points seed a search in the basis of
Omega / nu, and the harmonics it fits to their boundary states, on synthetic sweeps whose
signals are sums of known harmonics."""
from types import SimpleNamespace

import numpy as np
import pytest

from hbm.isolas.harmonic import ti_seeds

SPR = 32  # samples per revolution
N_LOBES = 2
N_H = 6


def _residual(nu):
    """What ti_seeds reads of a HarmonicBalanceResidual: nu, N_h, the unknowns' layout (one dof)."""
    return SimpleNamespace(nu=nu, basis=SimpleNamespace(n_harmonics=N_H), n_c=2 * N_H + 1, n_r=1,
                           to_unknowns=lambda xr: np.asarray(xr, float).reshape(-1))


def _sweep(revolutions):
    """Four speeds: period 4 casing periods (omega = Omega / 2), 2 (omega = Omega), 3 (1.5
    revolutions) and none; boundary over the last `revolutions` revolutions, from Omega t = 0."""
    omega = np.array([1000.0, 1100.0, 1200.0, 1300.0])
    period = np.array([4, 2, 3, 0])
    cls = np.array([2, 1, 2, 3])
    n = revolutions * SPR
    B = np.zeros((4, n, 1))
    times = np.zeros((4, 5 * SPR))
    for i, w in enumerate(omega):
        times[i] = 0.3 + np.arange(5 * SPR) * 2 * np.pi / (w * SPR)
        phi = 2 * np.pi * np.arange(-n, 0) / SPR  # Omega t of each sample, the last revolutions
        if period[i] == 4:  # harmonics 0, 1 and 3 of Omega / 2
            B[i, :, 0] = 1e-4 + 5e-4 * np.cos(phi / 2) + 2e-4 * np.sin(3 * phi / 2)
        elif period[i] == 2:  # harmonic 1 of Omega
            B[i, :, 0] = 3e-4 * np.cos(phi)
        else:
            B[i, :, 0] = 7e-4 * np.cos(phi / 3)
    return SimpleNamespace(omega=omega, period=period, period_class=cls, times=times, boundary=B)


def test_nu_2_takes_the_period_doubled_and_the_revolution_orbits_with_their_harmonics():
    seeds = ti_seeds(_residual(2), _sweep(2), (0.0, 1e4), N_LOBES)
    assert [s.omega for s in seeds] == [1000.0, 1100.0]  # p = 3 (1.5 revolutions) and none left out
    pd = np.zeros(2 * N_H + 1)
    pd[[0, 1, 6]] = 1e-4, 5e-4, 2e-4  # mean, cos 1, sin 3 of Omega / 2
    np.testing.assert_allclose(seeds[0].x, pd, atol=1e-15)
    rev = np.zeros(2 * N_H + 1)
    rev[3] = 3e-4  # cos 2 of Omega / 2
    np.testing.assert_allclose(seeds[1].x, rev, atol=1e-15)
    assert "period 4" in seeds[0].origin
    assert all(s.of_model for s in seeds)  # corrected with the search's patient Newton


def test_nu_1_takes_the_revolution_orbit_only():
    seeds = ti_seeds(_residual(1), _sweep(2), (0.0, 1e4), N_LOBES)
    assert [s.omega for s in seeds] == [1100.0]
    rev = np.zeros(2 * N_H + 1)
    rev[1] = 3e-4
    np.testing.assert_allclose(seeds[0].x, rev, atol=1e-15)


@pytest.mark.parametrize("nu, expected", [(1, [1100.0]), (2, [])])
def test_a_file_with_one_revolution_seeds_what_one_revolution_holds(nu, expected):
    assert [s.omega for s in ti_seeds(_residual(nu), _sweep(1), (0.0, 1e4), N_LOBES)] == expected


def test_the_range_and_a_file_without_states():
    assert ti_seeds(_residual(2), _sweep(2), (1050.0, 2000.0), N_LOBES)[0].omega == 1100.0
    sw = _sweep(2)
    sw.boundary = None
    assert ti_seeds(_residual(2), sw, (0.0, 1e4), N_LOBES) == []
