"""The time signals a user reads from an HBM solution.

HarmonicBalanceResidual.signals(u, Omega) returns the displacement of every ROM dof on a
time axis t. For a harmonically forced ROM out of contact the exact periodic response is
the closed-form FRF of the full (uncondensed) ROM,
    x(t) = Re[(K - Omega^2 M + i Omega C)^-1 (f_c - i f_s) exp(i Omega t)],
for f(t) = f_c cos(Omega t) + f_s sin(Omega t). The test evaluates it at the returned t, for
the basis of Omega (nu = 1) and of Omega / 2 (nu = 2: one basis period holds two
revolutions, t spans 4 pi / Omega). It pins the time axis, the forcing's cos/sin phase,
the damping's sign and the condensation's recovery of the modal dof at once.
"""
from dataclasses import replace

import numpy as np
import pytest

from hbm.harmonic.condensation import HarmonicForcing
from hbm.harmonic.residual import build_residual
from hbm.options import CasingOptions, ContactOptions, HbmOptions
from support import standin_rom

OMEGA = 900.0  # rad/s, between the stand-in's first two eigenfrequencies (1050 rad/s is near)


@pytest.mark.parametrize("nu", [1, 2])
@pytest.mark.parametrize("n_time", [None, 50])
def test_signals_of_the_linear_forced_response_are_the_closed_form_frf(nu, n_time):
    rom = standin_rom()
    n = rom.n_dof
    rng = np.random.default_rng(21)
    # a round casing 1 mm away and a tiny force (~1e-8 m response): no contact
    fc, fs = 1e-3 * rng.standard_normal(n), 1e-3 * rng.standard_normal(n)
    opts = HbmOptions(n_harmonics=3 * nu, n_time=16 * nu)
    if nu != 1:
        opts = replace(opts, subharmonic=nu)
    round_casing = lambda tau: np.full((len(tau), rom.n_boundary), 1e-3)  # noqa: E731  1 mm everywhere, m
    res = build_residual(rom, CasingOptions(), ContactOptions(), opts, method="dlft",
                         forcing=HarmonicForcing(fc, 1, fs), distance=round_casing)
    u = res.linear_solution(OMEGA)
    sig = res.signals(u, OMEGA, n_time=n_time)
    nt = opts.n_time if n_time is None else n_time
    # the time axis: nt samples of one basis period, 2 pi nu / Omega
    np.testing.assert_allclose(sig["t"], 2 * np.pi * nu / OMEGA * np.arange(nt) / nt, rtol=1e-13, atol=0)
    assert not np.any(sig["lam"])  # out of contact: the closed form applies
    Z = rom.K - OMEGA ** 2 * rom.M + 1j * OMEGA * rom.C
    X = np.linalg.solve(Z, fc - 1j * fs)
    ref = np.real(np.exp(1j * OMEGA * sig["t"])[:, None] * X[None, :])
    assert np.abs(sig["displacement"] - ref).max() <= 1e-9 * np.abs(ref).max()


@pytest.mark.parametrize("method", ["dlft", "rl"])
def test_signals_on_a_finer_grid_see_the_same_casing_at_the_same_instants(method):
    """signals(n_time=...) resamples the orbit on another grid: at the instants both grids
    share, the casing distance, gap and normal force must be those of the AFT grid; and the
    casing is a function of the time t alone, whatever the basis (nu = 2 spans two
    revolutions, its first half is nu = 1's revolution)."""
    rom = standin_rom()
    casing = CasingOptions()
    sig = {}
    for nu in (1, 2):
        opts = HbmOptions(n_harmonics=4 * nu, n_time=32 * nu)
        if nu != 1:
            opts = replace(opts, subharmonic=nu)
        res = build_residual(rom, casing, ContactOptions(), opts, method=method)
        u = 0.5 * np.random.default_rng(nu).standard_normal(res.size)
        u.reshape(res.n_c, res.n_r)[0, 0::3] += 0.3  # pressed outward: some contact
        coarse, fine = res.signals(u, OMEGA), res.signals(u, OMEGA, n_time=3 * opts.n_time)
        assert 0.0 < np.mean(coarse["gap"] > 0) < 1.0  # a mix of contact and flight
        np.testing.assert_allclose(fine["t"][::3], coarse["t"], rtol=1e-13)
        for key in ("distance", "gap", "lam"):
            scale = np.abs(coarse[key]).max()
            assert np.abs(fine[key][::3] - coarse[key]).max() <= 1e-9 * scale, key
        sig[nu] = fine
    # the same instants t over the first revolution: the same casing
    np.testing.assert_allclose(sig[2]["t"][:96], sig[1]["t"], rtol=1e-13)
    np.testing.assert_allclose(sig[2]["distance"][:96], sig[1]["distance"], rtol=0, atol=1e-12 * casing.clearance)
    assert np.ptp(sig[1]["distance"]) > 0.5 * casing.clearance  # the lobes are really sampled
