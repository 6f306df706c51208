"""How a time-integration march is compared with an HBM orbit (hbm.ti.validation), against
references that do not go through that code:

- an exact orbit, the free vibration of an undamped linear mode at the basis' fundamental
  Omega / nu: time integration stays on it period by period at nu = 1 and nu = 2, to the
  central-difference scheme's period error, so the march's period (2 pi nu / Omega) and the
  alignment of its samples with the orbit's phases are right;
- a march that went to nan is "leaves" and its differences read nan, never 0.
"""
import numpy as np
import pytest
from scipy.linalg import eigh

from hbm.harmonic.residual import build_residual
from hbm.options import CasingOptions, ContactOptions, HbmOptions
from hbm.ti.march import modal_system
from hbm.ti.validation import compare_with_hbm, march_from_hbm
from support import standin_rom
from test_validation_defects import N_H, OMEGA, _rubbing_orbit, _validation


def _undamped_mode():
    """(system, w, phi): 12 dof, 3 contact nodes, no damping; its lowest mode w (rad/s) and
    shape phi (12,), M-normalised."""
    rng = np.random.default_rng(0)
    n = 12
    a = rng.standard_normal((n, n))
    K = 1e5 * (a @ a.T + n * np.eye(n))  # N/m
    M = 0.05 * np.eye(n)  # kg
    w2, v = eigh(K, M)
    system = modal_system(K, M, np.zeros((n, n)), np.full(3, 0.24), np.array([0.0, 0.1, 0.2]))
    return system, float(np.sqrt(w2[0])), v[:, 0]


@pytest.mark.parametrize("nu, n_time", [(1, 64), (2, 128)])
def test_time_integration_stays_on_an_exact_orbit_sample_by_sample(nu, n_time):
    """x(t) = A phi (cos w t + 0.3 sin w t), 0.1 mm at the LE, is an orbit of the undamped
    system at Omega = nu w (harmonic 1 of the basis Omega / nu, no contact: the casing lies 0.5 m
    or more away); its period 2 pi nu / Omega is one w-cycle. Over 5 periods of 4000 steps or
    more the scheme's period error, (w h)^2 / 24 rad per rad, lags it by 3.1e-6 rad, which is
    the deviation (relative to the half peak-to-peak); one grid sample of shift would read
    2 sin(pi / n_time) = 0.05 to 0.1, a march period of 2 pi / Omega (half a w-cycle at nu =
    2) of order 1."""
    system, w, phi = _undamped_mode()
    nh = 3 * nu
    c = np.zeros((2 * nh + 1, system.n_dof))
    a = 1e-4 / abs(phi[0])
    c[1], c[2] = a * phi, 0.3 * a * phi  # cos and sin of harmonic 1: w = Omega / nu
    casing = CasingOptions(clearance=1.0, penetration=-0.5)  # d = 1 - 0.5 exp(...) >= 0.5 m
    ti = march_from_hbm(system, casing, 0.0, c, nu * w, subharmonic=nu, n_periods=5, dt=2 * np.pi / (4000 * w),
                        n_time=n_time)
    lag = 5 * 2 * np.pi * (w * ti.dt) ** 2 / 24  # rad, after 5 w-cycles
    assert lag == pytest.approx(3.1e-6, rel=0.05)
    assert ti.deviation.max() < 1.3 * lag and ti.deviation[-1].min() > 0.7 * lag, ti.deviation
    assert ti.stays and ti.verdict() == "stays"
    comp = compare_with_hbm(ti, c, np.zeros((2 * nh + 2, 3)), "the orbit")
    np.testing.assert_allclose(comp.displacement_error, ti.deviation[-1], rtol=1e-12)
    assert np.all(comp.force_error == 0.0)  # neither is ever in contact


def test_a_march_that_went_to_nan_leaves_and_its_differences_read_nan():
    """The stand-in ROM marched from a state holding a nan: every deviation is nan, the
    verdict "leaves" (nan never passes the growth or distance bound). A march whose forces
    overflowed (inf impulses: their harmonics are nan) has a nan force difference: it read
    0 where the displacement read nan. A finite one is |lam_TI - lam_HBM| over the larger
    peak: a TI force 0.8 of the HBM's differs by 0.2."""
    rom = standin_rom()
    res = build_residual(rom, CasingOptions(), ContactOptions(mu=0.0), HbmOptions(n_harmonics=N_H, n_time=64),
                         method="dlft")
    u = _rubbing_orbit(res)
    c = res.expand_harmonics(u, OMEGA)
    c[1, 5] = np.nan
    ti = march_from_hbm(rom, CasingOptions(), 0.0, c, OMEGA, n_periods=3, dt=2 * np.pi / (OMEGA * 1023.5), n_time=64)
    # the verdict says it is a numerical failure (it read a plain "leaves")
    assert np.isnan(ti.deviation).all() and not ti.stays
    assert ti.verdict() == "leaves: the march went to NaN or inf from period 1", ti.verdict()
    # the orbit's own forces against a march delivering nan, then 0.8 of them
    tau = ti.tau
    hbm_c, lam = res.expand_harmonics(u, OMEGA), res.signals(u, OMEGA)["lam"]
    orbit = compare_with_hbm(_validation(tau), hbm_c, lam, "the orbit")
    assert orbit.force.max() > 10.0  # N: it rubs
    nan = compare_with_hbm(_validation(tau, force=np.full((len(tau), 3), np.nan)), hbm_c, lam, "the orbit")
    assert np.isnan(nan.force_error).all(), nan.force_error
    less = compare_with_hbm(_validation(tau, force=0.8 * orbit.force), hbm_c, lam, "the orbit")
    np.testing.assert_allclose(less.force_error, 0.2, rtol=1e-12)
