"""Dynamical content (eqs. 32-34) of a static motion (N_h = 0, a basis with the mean only):
the peak over the period of a constant is its absolute value, and the relative modal
contributions of a static deflection are |q_j| / sum |q_k| of its modal coordinates, whatever
their signs (hand computation on a diagonal mass matrix with explicit M-orthonormal shapes)."""
import numpy as np

from hbm.harmonic.content import harmonic_contributions, modal_contributions, modal_contributions_of_harmonics, \
    peak_magnitudes


def _mass_and_modes():
    # M = diag(m), shapes M^(-1/2) Q with Q orthogonal: Phi^T M Phi = Q^T Q = I by construction
    m = np.array([2.0, 0.5, 1.5, 4.0])
    q, _ = np.linalg.qr(np.random.default_rng(11).standard_normal((4, 4)))
    return np.diag(m), q / np.sqrt(m)[:, None]


def test_peak_of_a_constant_is_its_absolute_value():
    np.testing.assert_array_equal(peak_magnitudes(np.array([[-3.0, 2.0, 0.0, -1e-9]])), [3.0, 2.0, 0.0, 1e-9])


def test_static_deflection_with_negative_modal_coordinates():
    M, phi = _mass_and_modes()
    qm = np.array([-1e-4, 3e-4, 0.0, -4e-4])  # modal coordinates, m
    x = phi @ qm  # a static deflection, the mean of a basis with no harmonic
    expected = np.abs(qm) / np.abs(qm).sum()  # [1, 3, 0, 4] / 8
    np.testing.assert_allclose(modal_contributions_of_harmonics(x[None, :], M, phi), expected, rtol=1e-12, atol=1e-15)
    # the same deflection held over a sampled period, and eq. (34) of its first dof: |mean| at k = 0
    np.testing.assert_allclose(modal_contributions(np.tile(x, (8, 1)), M, phi), expected, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(harmonic_contributions(-x[None, :]), np.abs(x)[None, :], rtol=0, atol=0)
