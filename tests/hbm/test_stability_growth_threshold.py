"""The stability verdict's threshold, against exact Floquet exponents.

A linear, time-invariant oscillator x'' + c x' + w0^2 x = 0 seen as a periodic system of any
period T = 2 pi / omega has the Floquet exponents lam = -c / 2 +- i sqrt(w0^2 - c^2 / 4)
exactly, so log|mu| = -c T / 2. With c < 0 the orbit x = 0 grows by g = -c T / 2 per
period. A verdict is "unstable" when g exceeds 1e-6 (hbm.stability.spectrum.GROWTH_TOL: the
exponents of a converged orbit carry ~1e-10 relative error, and the multiplier +1 of an
exact fold must not count), a growth per period, so the same g gives the same verdict on a
test system's time scale (T ~ 4 s) and on the rotor's (T ~ 4 ms). The values are written
here, not read from the module: a looser tolerance would call slowly growing orbits stable,
and a tolerance on Re(lam) in 1/s instead of per period would move the threshold with T by
a factor of 1000 between these two scales.
"""
import numpy as np
import pytest

from hbm.harmonic.fourier import FourierBasis
from hbm.stability.hill import HillOperator
from hbm.stability.spectrum import arnoldi_spectrum, dense_spectrum

NH, NT = 5, 16


def oscillator(k: float, c: float, omega: float, w0: float) -> HillOperator:
    """Hill's operator of x'' + c x' + k x = 0 (dof 0) in the basis of omega, without contact;
    dofs 1, 2 (the 'theta, z' of the one node Hill's operator needs) are decoupled and
    overdamped (exponents -w0 and -100 w0)."""
    return HillOperator(K=np.diag([k, 100.0 * w0 * w0, 100.0 * w0 * w0]), M=np.eye(3),
                        C=np.diag([c, 101.0 * w0, 101.0 * w0]), omega=omega, basis=FourierBasis(NH, NT),
                        nodes=np.array([0]), weights=np.zeros((1, 1, NT)), sigma=np.ones(2 * NH + 1),
                        g_eps=1.0, g_z=0.0, nl=np.arange(3))


def spectrum(growth: float, omega: float, w0: float):
    """Dense Hill spectrum of the oscillator of natural frequency w0 whose multipliers grow by
    `growth` per period 2 pi / omega."""
    return dense_spectrum(oscillator(w0 * w0, -2.0 * growth * omega / (2.0 * np.pi), omega, w0))


SCALES = {"test system (T = 3.7 s)": (1.7, 1.0), "rotor (T = 4.2 ms)": (1500.0, 1000.0)}


@pytest.mark.parametrize("scale", SCALES)
@pytest.mark.parametrize("growth, unstable", [(1e-4, 2), (2e-6, 2), (5e-7, 0), (0.0, 0), (-2e-6, 0)])
def test_a_growth_per_period_above_1e_6_is_unstable_at_any_time_scale(scale, growth, unstable):
    omega, w0 = SCALES[scale]
    sp = spectrum(growth, omega, w0)
    # the pair of the oscillator leads, exact to round-off (measured: 2e-16 at most)
    assert np.allclose(np.log(np.abs(sp.multipliers[:2])), growth, rtol=0.0, atol=1e-10)
    assert sp.decided
    assert sp.n_unstable == unstable
    assert sp.stable == (unstable == 0)


@pytest.mark.parametrize("r", [1e-3, 3e-3, 1e-2])
def test_a_saddles_two_real_multipliers_are_two_in_the_arnoldi_window_too(r):
    """x'' - k x = 0 with k = (r omega)^2: exponents +-r omega exactly, both eigenvectors on
    dof 0's mean (parallel). A saddle's pair beside a fold looks so (one multiplier just
    outside the circle, its partner just inside). They differ by no harmonic shift, so they
    are two families however close their real parts: grouped as one (within MEMBER_DRIFT
    omega = 4e-3 omega, as members of one family are) the window keeps the stable one."""
    omega = 1.7
    H = oscillator(-(r * omega) ** 2, 0.0, omega, 1.0)
    growth = 2.0 * np.pi * r  # log|mu| = +-r omega T
    for sp in (dense_spectrum(H), arnoldi_spectrum(H, n_eig=16)):
        assert sp.decided and sp.n_unstable == 1, sp.method
        np.testing.assert_allclose(np.log(np.abs(sp.multipliers[:2])), [growth, -growth], rtol=1e-9)
