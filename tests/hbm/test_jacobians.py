"""Analytical Jacobians of the HBM residual (through AFT) against central finite differences.

Central differences of a smooth function err by O(h^2 f''') ~ 1e-10 relative at h = 1e-6
on unknowns of order 1, far below the 1e-6 asked. DLFT is piecewise smooth: at a random
point no time sample lies within the step of a switch (had one, the difference would
differ by O(1) and the test fail loudly, not pass wrongly).
"""
import dataclasses

import numpy as np
import pytest

from hbm.harmonic.fourier import FourierBasis
from hbm.harmonic.residual import build_residual
from hbm.options import CasingOptions, ContactOptions, HbmOptions
from support import forced_standin_residual, perturbed_state, standin_rom

H = 1e-6


def _fd(res, u, om):
    J = np.empty((res.size, res.size))
    for i in range(res.size):
        e = np.zeros(res.size)
        e[i] = H
        J[:, i] = (res(u + e, om, jacobian=False) - res(u - e, om, jacobian=False)) / (2 * H)
    dw = (res(u, om + 1e-3, jacobian=False) - res(u, om - 1e-3, jacobian=False)) / 2e-3
    return J, dw


CASES = [("dlft", dict(mu=0.0), 1), ("dlft", dict(mu=0.15), 1), ("rl", dict(lanczos=True, mu=0.0), 1),
         ("rl", dict(lanczos=False, mu=0.0), 1), ("rl", dict(lanczos=True, mu=0.15), 1),
         ("rl", dict(lanczos=False, mu=0.15), 1),
         # the other sense of rotation: the sliding speed's s rho Omega enters dR/domega
         ("dlft", dict(mu=0.15), -1), ("rl", dict(lanczos=True, mu=0.15), -1)]


@pytest.mark.parametrize("method,kw,rotation", CASES)
def test_jacobian_matches_finite_differences(method, kw, rotation):
    res = forced_standin_residual(method, n_harmonics=5, n_time=64, rotation=rotation, **kw)
    om = 900.0
    u = perturbed_state(res, 3, om)
    smp = res.samples(res.to_coefficients(u), om)
    assert 0.05 < smp.active.mean() < 0.95  # a mix of contact and flight
    R, Js, dw = res(u, om)
    Jfd, dwfd = _fd(res, u, om)
    # both forms of the structured Jacobian against the finite differences of the residual:
    # its dense form, and its FFT product (what the solvers use) on random vectors
    J = np.asarray(Js)
    assert np.abs(J - Jfd).max() <= 1e-6 * np.abs(J).max()
    V = np.random.default_rng(4).standard_normal((res.size, 4))
    assert np.abs(Js @ V - Jfd @ V).max() <= 1e-6 * np.abs(Jfd @ V).max()
    assert np.abs(dw - dwfd).max() <= 1e-6 * np.abs(dw).max()
    if kw.get("mu"):  # the friction blocks are really there (and were checked above)
        res0 = forced_standin_residual(method, n_harmonics=5, n_time=64, rotation=rotation, **{**kw, "mu": 0.0})
        assert np.abs(J - np.asarray(res0(u, om)[1])).max() > 1e-3 * np.abs(J).max()


def test_weighted_product_equals_dense_dft_product():
    b = FourierBasis(7, 40)  # N_t < 4 N_h + 1: orders k + l alias, the full-FFT path
    F = b.to_freq(np.eye(b.n_time))
    Ft = b.to_time(np.eye(b.n_coeffs))
    tau = b.tau
    Ft_ref = np.column_stack([np.ones_like(tau)] + [f(k * tau) for k in range(1, 8) for f in (np.cos, np.sin)])
    assert np.abs(Ft - Ft_ref).max() < 1e-13  # eq. (11) with c_0 = a_0 / 2 stored
    assert np.abs(F @ Ft - np.eye(b.n_coeffs)).max() < 1e-13
    # the last-axis layout is the same transform, transposed
    assert np.abs(b.to_time(np.eye(b.n_coeffs), axis=-1) - Ft.T).max() < 1e-13
    assert np.abs(b.to_freq(np.eye(b.n_time), axis=-1) - F.T).max() < 1e-13
    with pytest.raises(ValueError, match="axis"):
        b.to_time(np.zeros((b.n_coeffs, 2, 3)), axis=1)
    w = np.random.default_rng(0).random((2, b.n_time))
    for bb, ww in ((b, w), (FourierBasis(7, 64), np.random.default_rng(1).random((2, 64)))):
        F = bb.to_freq(np.eye(bb.n_time))
        Ft = bb.to_time(np.eye(bb.n_coeffs))
        assert np.abs(bb.weighted_product(ww) - np.einsum("ij,bj,jk->bik", F, ww, Ft)).max() < 1e-13


def test_non_symmetric_rom_matrix_is_named():
    """The exact condensation uses Z_ln = Z_nl^T: a non-symmetric K, M or C is refused by name."""
    rom = standin_rom()
    K = rom.K.copy()
    K[0, 30] *= 1.01
    with pytest.raises(ValueError, match="K is not symmetric"):
        build_residual(dataclasses.replace(rom, K=K), CasingOptions(), ContactOptions(),
                       HbmOptions(n_harmonics=3, n_time=16))
