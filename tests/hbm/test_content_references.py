"""Dynamical content (eqs. 32-34) against closed forms: two modes at exact resonance with
known amplitudes on different harmonics, in the bases of Omega and Omega / 2; the same orbit
in both bases; the maximum over the period of trigonometric polynomials whose maximum is
known; mode shapes that are not mass-normalised."""

from dataclasses import replace

import numpy as np
import pytest

from hbm.harmonic import content
from hbm.harmonic.content import branch_content, modal_contributions, rom_modes
from hbm.harmonic.residual import build_residual
from hbm.options import CasingOptions, ContactOptions, HbmOptions
from support import coarse_rom, standin_rom

W = np.r_[1000.0, 4000.0, np.linspace(7000.0, 40000.0, 10)]  # rad/s: mode 2 at exactly 4 x mode 1


def _undamped_rom():
    """A 21-dof ROM (3 boundary nodes) with eigenfrequencies W, random M-orthonormal shapes
    and no damping: a mode at its own frequency solves Z_k x = 0, so the recovery of the
    linear dof from the boundary dof (expand_harmonics) gives that mode shape exactly."""
    r = standin_rom(n_boundary=3, n_modes=len(W) - 9, seed=5)
    n = r.K.shape[0]
    q, _ = np.linalg.qr(np.random.default_rng(1).standard_normal((n, n)))
    phi = np.linalg.solve(np.linalg.cholesky(r.M).T, q)  # phi^T M phi = I
    K = (r.M @ phi) @ np.diag(W ** 2) @ (r.M @ phi).T
    return replace(r, K=0.5 * (K + K.T), C=np.zeros((n, n)), frequencies=W.copy(), damping_ratios=np.zeros(n))


@pytest.mark.parametrize("nu, nh, nt, ka, kb", [(1, 4, 16, 1, 4), (2, 8, 32, 2, 8), (2, 8, 18, 2, 8),
                                                (1, 4, 1024, 1, 4)])
def test_two_resonant_modes_give_their_closed_form_content_whatever_the_grid(nu, nh, nt, ka, kb):
    # x = A cos(ka tau + 0.3) phi_1 + B sin(kb tau + pi / 4) phi_2, tau the basis angle Omega t / nu,
    # at Omega = nu omega_1 / ka (so kb Omega / nu = omega_2): eq. (33) gives A / (A + B), B / (A + B)
    # = 0.25, 0.75, and eq. (34) A |phi_1(LE r)| at the basis' harmonic ka, B |phi_2(LE r)| at kb.
    # The maximum over the AFT grid's samples gave 0.319 / 0.681 at N_t = 16 and 32 (sin(kb tau +
    # pi / 4) sampled at 4 phases: 0.707 of its peak) and 0.2505 at N_t = 18.
    rom = _undamped_rom()
    res = build_residual(rom, CasingOptions(), ContactOptions(),
                         HbmOptions(n_harmonics=nh, n_time=nt, subharmonic=nu), method="dlft")
    _, phi = rom_modes(rom.K, rom.M)
    A, B = 1e-4, 3e-4
    full = np.zeros((2 * nh + 1, rom.K.shape[0]))
    full[2 * ka - 1], full[2 * ka] = A * np.cos(0.3) * phi[:, 0], -A * np.sin(0.3) * phi[:, 0]
    full[2 * kb - 1], full[2 * kb] = B * np.sin(np.pi / 4) * phi[:, 1], B * np.cos(np.pi / 4) * phi[:, 1]
    omega = nu * W[0] / ka
    u = res.to_unknowns(full[:, :res.n_r])
    np.testing.assert_allclose(res.expand_harmonics(u, omega), full, atol=1e-12 * abs(full).max())  # the premise
    out = branch_content(res, rom, np.stack([u, 0 * u]), np.array([omega, omega]))
    modal = out["modal_contribution"]
    np.testing.assert_allclose(modal[0, :2], [0.25, 0.75], atol=1e-10)
    assert modal[0, 2:].max() < 1e-10
    h = out["harmonic_contribution"][0]
    assert h.shape == (nh + 1,)  # harmonics of the basis, k Omega / nu: k = nu is Omega itself
    expected = np.zeros(nh + 1)
    expected[ka], expected[kb] = A * abs(phi[0, 0]), B * abs(phi[0, 1])
    np.testing.assert_allclose(h, expected, rtol=1e-10, atol=1e-12 * B)
    # a motion at rest: no contribution (0 / 0 read as 0, not nan) and no harmonic
    assert np.all(modal[1] == 0) and np.all(out["harmonic_contribution"][1] == 0)


def test_the_same_orbit_in_the_bases_of_omega_and_omega_over_2_has_the_same_content():
    # an Omega-periodic orbit of the coarse rotor 67 ROM written in the basis of Omega / 2
    # (harmonic k -> 2 k, by hand): the same motion, so the same modal contributions, and
    # harmonic k of Omega at column 2 k, none at odd columns. N_t = 64 and 36 sample it at
    # other instants: the grid maxima differed by 6.4e-3.
    rom = coarse_rom()
    r1 = build_residual(rom, CasingOptions(), ContactOptions(), HbmOptions(n_harmonics=8, n_time=64), method="dlft")
    r2 = build_residual(rom, CasingOptions(), ContactOptions(),
                        HbmOptions(n_harmonics=16, n_time=36, subharmonic=2), method="dlft")
    rng = np.random.default_rng(7)
    x1 = rng.standard_normal((17, r1.n_r)) * 1e-4 / (1.0 + np.arange(17))[:, None]
    x2 = np.zeros((33, r1.n_r))
    x2[0], x2[3::4], x2[4::4] = x1[0], x1[1::2], x1[2::2]  # a_k, b_k of Omega -> a_2k, b_2k of Omega / 2
    omega = 1400.0
    even = np.r_[0, np.c_[np.arange(3, 33, 4), np.arange(4, 33, 4)].ravel()]  # rows of c_0, a_2k, b_2k
    f1, f2 = r1.expand_harmonics(r1.to_unknowns(x1), omega), r2.expand_harmonics(r2.to_unknowns(x2), omega)
    np.testing.assert_allclose(f2[even], f1, rtol=0, atol=1e-12 * abs(f1).max())  # the same motion, all dof
    assert np.all(np.delete(f2, even, axis=0) == 0)
    c1 = branch_content(r1, rom, r1.to_unknowns(x1)[None], np.array([omega]))
    c2 = branch_content(r2, rom, r2.to_unknowns(x2)[None], np.array([omega]))
    np.testing.assert_allclose(c2["modal_contribution"], c1["modal_contribution"], rtol=0, atol=1e-10)
    np.testing.assert_allclose(c2["harmonic_contribution"][0, ::2], c1["harmonic_contribution"][0], rtol=1e-12)
    assert np.all(c2["harmonic_contribution"][0, 1::2] == 0)


def test_the_maximum_over_the_period_of_known_polynomials():
    # c0 + A cos(k (tau - t0)) + B cos(2 k (tau - t0)) with c0, A, B > 0: max c0 + A + B at t0,
    # off any grid; -(...) has the same |max|; a + b cos(tau): |a| + |b|; a constant: |c0|
    nh, t0 = 12, 0.123456789
    rows = []
    for k, c0, A, B in [(1, 0.2, 1.0, 0.5), (3, 0.0, 2.0, 1.0), (6, 1.0, 0.3, 0.7)]:
        c = np.zeros(2 * nh + 1)
        c[0] = c0
        for kk, amp in ((k, A), (2 * k, B)):  # amp cos(kk tau - kk t0) = amp (cos kk t0 cos + sin kk t0 sin)
            c[2 * kk - 1], c[2 * kk] = amp * np.cos(kk * t0), amp * np.sin(kk * t0)
        rows += [(c, c0 + A + B), (-c, c0 + A + B)]
    c = np.zeros(2 * nh + 1)
    c[0], c[1] = -0.4, 0.25
    rows += [(c, 0.65), (np.r_[-3.0, np.zeros(2 * nh)], 3.0), (np.zeros(2 * nh + 1), 0.0)]
    coeffs = np.stack([r[0] for r in rows], axis=1)
    np.testing.assert_allclose(content.peak_magnitudes(coeffs), [r[1] for r in rows], rtol=1e-13, atol=1e-15)


def test_mode_shapes_that_are_not_mass_normalised_are_refused():
    # numpy's eig gives unit Euclidean norm: unchecked, 2 phi_1 + 6 phi_3 (0.25, 0.75) read 0.33, 0.67
    rom = coarse_rom()
    _, phi = rom_modes(rom.K, rom.M)
    tau = np.linspace(0, 2 * np.pi, 512, endpoint=False)
    x = 2e-4 * np.cos(tau)[:, None] * phi[:, 0] + 6e-4 * np.sin(4 * tau)[:, None] * phi[:, 2]
    np.testing.assert_allclose(modal_contributions(x, rom.M, phi)[[0, 2]], [0.25, 0.75], atol=1e-10)
    with pytest.raises(ValueError, match="mass-normalised"):
        modal_contributions(x, rom.M, phi / np.linalg.norm(phi, axis=0))
