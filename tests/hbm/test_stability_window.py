"""A multiplier beyond the Arnoldi window: what the widening of hbm.stability.spectrum and
hbm.stability.monitor is for, on the rotor 67 coarse ROM.

Shift-invert Arnoldi at lam = 0 lists every Floquet multiplier between its modulus_floor and
modulus_ceiling = 1 / modulus_floor, no more. On the DLFT NFRC (N_h = 40, N_t = 1024) at
1335-1341 rad/s a multiplier mu ~ -21 lies just past the ceiling of 40 eigenvalues
(log|mu| 3.04-3.07 against ceilings 2.64-2.90), so that window calls the orbit stable.
orbit_spectrum widens the window until a stable verdict holds up to MIN_CEILING and finds
it; time integration (hbm.ti, an independent code: exact contact, sliding friction)
started on the orbit leaves it, which says the widened verdict is the right one.
"""

import numpy as np
import pytest

from hbm.stability.spectrum import orbit_spectrum
from hbm.ti.validation import march_from_hbm
from support import coarse_dlft_nfrc


@pytest.fixture(scope="module")
def point():
    rom, casing, contact, res, r = coarse_dlft_nfrc()
    i = int(np.argmin(np.abs(r.omega - 1338.2)))
    assert abs(r.omega[i] - 1338.2) < 1.0, r.omega[-6:]
    return rom, casing, contact, res, r.unknowns[i], float(r.omega[i])


def test_the_widened_window_finds_the_multiplier_the_default_one_misses(point):
    _, _, _, res, u, w = point
    narrow, _ = orbit_spectrum(res, u, w, min_ceiling=1.0)  # 40 eigenvalues, no widening
    # the premise: the default window stops short of the multiplier (ceiling e^2.64 measured)
    assert narrow.stable and np.log(narrow.modulus_ceiling) < 3.0, (narrow.n_unstable, narrow.modulus_ceiling)
    wide, g = orbit_spectrum(res, u, w)
    assert g == 2 and not wide.stable and np.log(wide.modulus_ceiling) >= 4.0
    mu = wide.multipliers[0]
    # real and negative over the orbit's minimal period pi / Omega: log|mu| 3.066 measured
    assert abs(abs(np.angle(mu)) - np.pi) < 0.02 and 2.9 < np.log(abs(mu)) < 3.3, mu
    # the rest of the spectrum is the narrow window's, to the truncation: the wider window
    # may represent a family by a better-centred member (0.5 % apart measured)
    np.testing.assert_allclose(np.abs(wide.multipliers[1:4]), np.abs(narrow.multipliers[:3]), rtol=1e-2)


def test_time_integration_leaves_the_orbit_the_narrow_window_calls_stable(point):
    rom, casing, contact, res, u, w = point
    # |mu| ~ 21 per half revolution: a perturbation of the orbit grows 400-fold a revolution,
    # so 20 periods (of 2 pi / Omega) are plenty
    v = march_from_hbm(rom, casing, contact.mu, res.expand_harmonics(u, w), w, n_periods=20)
    dev = v.deviation.max(axis=1)
    # left: the last periods farther from the HBM orbit than its amplitude and than 3 times
    # the first period's distance (the criterion of test_stability_rotor67.py)
    assert dev[-5:].max() > 3.0 * dev[0] and dev[-5:].max() > 1.0, (dev[0], dev[-5:])
