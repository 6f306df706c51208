"""Lanczos sigma factors of eq. (21) (hbm.harmonic.fourier.FourierBasis.lanczos_sigma) written
out by hand with math.sin: sigma_k = sin(pi chi_k) / (pi chi_k), chi_k = k / (N_h + 1) for
1 <= k <= N_h and sigma_0 = 1, on every coefficient row [c_0, a_1, b_1, ..., a_Nh, b_Nh];
in a basis of Omega / nu, chi_k = k / (nu (floor(N_h / nu) + 1)) (the filter of the basis of
Omega at its own frequencies k / nu)."""
import math

import numpy as np
import pytest

from hbm.harmonic.fourier import FourierBasis


def _sinc(x):
    return 1.0 if x == 0 else math.sin(math.pi * x) / (math.pi * x)


@pytest.mark.parametrize("nh", [1, 3, 10])
def test_sigma_factors_of_eq21(nh):
    sigma = FourierBasis(nh, 2 * nh + 2).lanczos_sigma()
    expected = [1.0] + [_sinc(k / (nh + 1)) for k in range(1, nh + 1) for _ in (0, 1)]
    np.testing.assert_allclose(sigma, expected, rtol=1e-14, atol=0)
    # closed forms: N_h = 1 gives sinc(1 / 2) = 2 / pi on a_1 and b_1
    if nh == 1:
        np.testing.assert_allclose(sigma, [1.0, 2 / math.pi, 2 / math.pi], rtol=1e-15)


@pytest.mark.parametrize("nh, nu", [(6, 2), (7, 2), (9, 3)])
def test_sigma_factors_in_a_subharmonic_basis(nh, nu):
    sigma = FourierBasis(nh, 2 * nh + 1).lanczos_sigma(nu)
    expected = [1.0] + [_sinc(k / (nu * (nh // nu + 1))) for k in range(1, nh + 1) for _ in (0, 1)]
    np.testing.assert_allclose(sigma, expected, rtol=1e-14, atol=0)
    # harmonic k = nu m of the basis is harmonic m of Omega: the sigma of the basis of Omega
    # with floor(N_h / nu) harmonics
    omega_basis = FourierBasis(nh // nu, 2 * (nh // nu) + 1).lanczos_sigma()
    np.testing.assert_allclose(sigma[np.r_[0, [2 * nu * m - 1 for m in range(1, nh // nu + 1)]]],
                               omega_basis[np.r_[0, 1:len(omega_basis):2]], rtol=1e-14)
