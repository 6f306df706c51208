"""march_from_hbm and compare_with_hbm (hbm.ti.validation) on an orbit known by linear algebra,
with contact at every instant: what a contact-free orbit cannot check.

A 12-dof linear structure whose three contact nodes are pressed on a casing of negative
clearance at every instant (d_j < 0 for every angle, the preload keeps every multiplier
positive): the radial displacement of each node is the casing's, r_j(t) = d_j(Omega t +
s theta_j), and the other dof and the multipliers follow, harmonic by harmonic, from
(K - (k w)^2 M + i k w C) x_k = -lam_k e_r - mu s lam_k e_theta (sliding friction along the
sense s of rotation: the tip speed rho Omega dwarfs the vibration's). That orbit is exact up to
the casing's harmonics beyond N_h (a Gaussian lobe: below 1e-12 here), so a march from it must
stay on it, its radial displacement to round-off (the constraint holds it on the casing) and its
multipliers to the force sampling's error, for both senses of rotation and nu = 1 and 2. A
march started with the casing at the wrong angle (not shifted by Omega t0, or shifted against
the sense) reads a displacement difference of order 1 here; one over the wrong period or with
the wrong sign or unit of force would read order 1 in the force difference.
"""
from dataclasses import dataclass

import numpy as np
import pytest

from hbm.contact.casing import casing_distance
from hbm.harmonic.fourier import FourierBasis
from hbm.ti.march import modal_system
from hbm.ti.validation import compare_with_hbm, march_from_hbm

OMEGA = 300.0  # rad/s: far below the pressed structure's modes (> 2.2e4 rad/s), every node stays pressed
N_LOBE_HARMONICS = 48  # harmonics of Omega kept: a 0.3 rad Gaussian lobe's drop below 1e-12 of its depth by 40


@dataclass(frozen=True)
class PressingCasing:
    """Eq. (28)'s fields without CasingOptions' clearance >= 0 check: c = -2 mm, p = 1 mm give
    d between -2 and -1 mm at every angle, m."""

    n_lobes: int = 2
    width: float = 0.3
    clearance: float = -2e-3
    penetration: float = 1e-3


CASING = PressingCasing()


def _structure(rotation: int):
    """(system, K, M, C): 12 dof, contact nodes at dof 0-8 (r, theta, z), rho = 0.24 m, theta =
    0, 0.3, 0.6 rad; K diagonally dominant so each node pushes back on the casing, light modal
    damping (C = 1e-9 K + 0.5 M, N s/m). The start velocity is checked by the contact-free orbit
    of test_validation_comparisons.py: here the constraint sets the compared dof whatever it is."""
    rng = np.random.default_rng(1)
    n = 12
    a = rng.standard_normal((n, n))
    K = 1e6 * (0.15 * (a + a.T) + n * np.eye(n))  # N/m
    M = 0.02 * (np.eye(n) + 0.1 * np.diag(rng.random(n)))  # kg
    C = 1e-9 * K + 0.5 * M  # N s/m
    return modal_system(K, M, C, np.full(3, 0.24), np.array([0.0, 0.3, 0.6]), rotation), K, M, C


def _pressed_orbit(system, K, M, C, nu: int, mu: float, n_fine: int = 4096):
    """The exact orbit in the basis of Omega / nu: (coeffs (2 N_h + 1, 12), m, eq. (5) order;
    lam (2 N_h + 1, 3), N, harmonics of the multipliers), N_h = nu N_LOBE_HARMONICS."""
    nh = nu * N_LOBE_HARMONICS
    w = OMEGA / nu
    fine = FourierBasis(nh, n_fine)
    d = fine.to_freq(casing_distance(nu * fine.tau, system.rotation * system.theta, CASING))  # (2 N_h + 1, 3)
    radial = np.array([0, 3, 6])
    free = np.setdiff1d(np.arange(K.shape[0]), radial)
    tangential = np.searchsorted(free, radial + 1)  # the theta dof among the free ones
    nf = len(free)
    coeffs, lam = np.zeros((2 * nh + 1, K.shape[0])), np.zeros((2 * nh + 1, 3))
    for k in range(nh + 1):
        z = K - (k * w) ** 2 * M + 1j * k * w * C
        xr = d[0] + 0j if k == 0 else d[2 * k - 1] - 1j * d[2 * k]  # x = Re(X e^{i k tau})
        # unknowns: free dof X_f and multipliers L; rows f: Z_ff X_f + mu s E L = -Z_fr xr,
        # rows r: Z_rf X_f + L = -Z_rr xr (the force on the blade is -L radially)
        a = np.zeros((nf + 3, nf + 3), complex)
        a[:nf, :nf] = z[np.ix_(free, free)]
        a[tangential, nf + np.arange(3)] = mu * system.rotation
        a[nf:, :nf] = z[np.ix_(radial, free)]
        a[nf:, nf:] = np.eye(3)
        sol = np.linalg.solve(a, -np.concatenate([z[np.ix_(free, radial)] @ xr, z[np.ix_(radial, radial)] @ xr]))
        x = np.zeros(K.shape[0], complex)
        x[free], x[radial] = sol[:nf], xr
        rows = [0] if k == 0 else [2 * k - 1, 2 * k]
        parts = [np.real] if k == 0 else [np.real, lambda v: -np.imag(v)]
        for row, part in zip(rows, parts):
            coeffs[row], lam[row] = part(x), part(sol[nf:])
    return coeffs, lam


@pytest.mark.parametrize("rotation, nu, mu", [(1, 1, 0.0), (-1, 1, 0.1), (-1, 2, 0.1), (1, 2, 0.0)])
def test_a_march_from_an_exact_pressed_orbit_stays_on_it_and_matches_its_forces(rotation, nu, mu):
    """4 periods of 2 pi nu / Omega at dt <= 2 us from the exact orbit: deviation and
    displacement difference below 1e-9 (1e-12 measured), force difference below 1e-3 (2e-5 at
    nu = 1, 7e-5 at nu = 2 measured: the block means' half-step offset), the TI force within
    that of the orbit's multipliers, every node in contact at every step."""
    system, K, M, C = _structure(rotation)
    coeffs, lam = _pressed_orbit(system, K, M, C, nu, mu)
    nh = (coeffs.shape[0] - 1) // 2
    lam_t = FourierBasis(nh, 1024).to_time(lam)
    assert lam_t.min() > 1e4 and lam_t.max() < 3e4  # N: pressed throughout, the reference holds
    ti = march_from_hbm(system, CASING, mu, coeffs, OMEGA, subharmonic=nu, n_periods=4, dt=2e-6, n_time=1024)
    # the start is not at a whole number of casing periods, where any casing shift would pass
    lobes = ti.t0 * OMEGA * CASING.n_lobes / (2 * np.pi)
    assert abs(lobes - round(lobes)) > 0.05, ti.t0
    assert ti.deviation.max() < 1e-9, ti.deviation
    assert ti.stays and ti.verdict() == "stays"
    np.testing.assert_array_equal(ti.contact_fraction, 1.0)
    comp = compare_with_hbm(ti, coeffs, FourierBasis(nh, 2 * nh + 2).to_time(lam), "the exact orbit")
    assert comp.displacement_error.max() < 1e-9, comp.displacement_error
    assert comp.force_error.max() < 1e-3, comp.force_error
    np.testing.assert_allclose(ti.force, lam_t[:, [0, 1, 2]], rtol=1e-3)
    # the casing stored beside the signals is where the marched nodes are held
    np.testing.assert_allclose(ti.distance, ti.displacement, rtol=0, atol=1e-12 * 2e-3)
