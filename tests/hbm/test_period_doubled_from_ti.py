"""The sweep's period-doubled orbits are HBM solutions in the basis of Omega / 2.

On the coarse rotor 67 ROM (tests/data/rotor67_coarse_rom.h5) time integration from rest at
1108 rad/s ends, after 125 revolutions, on an orbit of 4 casing periods (omega = Omega / 2,
two revolutions). The isola search's seed from the sweep point's last two revolutions
(hbm.isolas.harmonic.ti_seeds, nu = 2) is corrected by the search's own Newton (DLFT, N_h =
80 harmonics of Omega / 2: the scene's resolution) to an HBM orbit that keeps the time
integration's Omega / 2 content and amplitude: the two methods share only the ROM, the
casing and the friction law. In the basis of Omega (nu = 1) the point seeds nothing: its
orbit does not fit in one revolution.
"""
from types import SimpleNamespace

import numpy as np
import pytest

from hbm.continuation.newton import newton_solve
from hbm.isolas.harmonic import HbmProblem, search_options, ti_seeds
from hbm.isolas.options import IsolaOptions
from hbm.options import CasingOptions, ContactOptions, HbmOptions, TimeIntegrationOptions
from hbm.ti.march import rom_modal_system
from hbm.ti.sweep import simulate
from support import coarse_rom

OMEGA = 1108.0


def _odd_share(xr):
    """Share of the harmonic energy (all but the mean) at odd multiples of the basis' fundamental."""
    n_h = (xr.shape[0] - 1) // 2
    odd = sum(np.sum(xr[2 * k - 1: 2 * k + 1] ** 2) for k in range(1, n_h + 1, 2))
    return odd / np.sum(xr[1:] ** 2)


@pytest.fixture(scope="module")
def point():
    rom = coarse_rom()
    r = simulate(rom_modal_system(rom), CasingOptions(), ContactOptions().mu, OMEGA, TimeIntegrationOptions())
    sweep = SimpleNamespace(omega=np.array([r.omega]), period=np.array([r.period]),
                            period_class=np.array([r.period_class]), times=r.times[None], boundary=r.boundary[None])
    return rom, r, sweep


def test_time_integration_ends_on_an_orbit_of_two_revolutions(point):
    _, r, _ = point
    assert r.period == 4 and r.order == 2.0


def test_the_seed_of_its_last_two_revolutions_converges_to_a_period_doubled_hbm_orbit(point):
    rom, r, sweep = point
    hbm = HbmOptions(subharmonic=2, n_harmonics=80, n_time=2048)
    res, solver = HbmProblem(rom, CasingOptions(), ContactOptions(), hbm, "dlft").for_seeds()()
    (seed,) = ti_seeds(res, sweep, (400.0, 2000.0), CasingOptions().n_lobes)
    seed_share = _odd_share(res.to_coefficients(seed.x))
    assert seed_share > 0.3  # time integration's own Omega / 2 content (0.43)
    sol = newton_solve(res, seed.x, OMEGA, search_options(hbm, IsolaOptions()).newton, solver=solver)
    assert sol.converged, sol.reason
    assert np.linalg.norm(sol.x - seed.x) / np.linalg.norm(seed.x) < 0.15  # measured 0.09
    assert _odd_share(res.to_coefficients(sol.x)) == pytest.approx(seed_share, abs=0.1)
    le = res.signals(sol.x, OMEGA)["displacement"][:, 0]
    assert 0.5 * np.ptp(le) == pytest.approx(r.amplitude, rel=0.03)  # measured -0.4 %


def test_in_the_basis_of_omega_it_seeds_nothing(point):
    rom, _, sweep = point
    res, _ = HbmProblem(rom, CasingOptions(), ContactOptions(), HbmOptions(), "dlft")()
    assert ti_seeds(res, sweep, (400.0, 2000.0), CasingOptions().n_lobes) == []
