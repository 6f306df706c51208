"""Dynamical content (eqs. 32-34) against constructed motions whose answer is known."""

import numpy as np
import pytest

from hbm.harmonic.content import branch_content, harmonic_contributions, modal_contributions, rom_modes
from hbm.harmonic.fourier import FourierBasis
from hbm.harmonic.residual import build_residual
from hbm.options import CasingOptions, ContactOptions, HbmOptions
from support import coarse_rom


@pytest.fixture(scope="module")
def rom():
    return coarse_rom()


def test_rom_modes_are_the_rom_stage_frequencies(rom):
    w, phi = rom_modes(rom.K, rom.M)
    np.testing.assert_allclose(w[:6], np.sort(rom.frequencies)[:6], rtol=1e-6)
    np.testing.assert_allclose(phi.T @ rom.M @ phi, np.eye(len(w)), atol=1e-8)


@pytest.mark.parametrize("j", [0, 1, 2, 3])
def test_a_pure_mode_shape_gives_one_for_that_mode(rom, j):
    # the shape from another eigen-solver (M^-1 K, unsymmetric), arbitrary scale and harmonic
    lam, vec = np.linalg.eig(np.linalg.solve(rom.M, rom.K))
    shape = np.real(vec[:, np.argsort(lam.real)[j]])
    tau = np.linspace(0, 2 * np.pi, 400, endpoint=False)
    x = 3e-4 * np.cos(7 * tau)[:, None] * shape[None, :] / np.abs(shape).max()
    c = modal_contributions(x, rom.M, rom_modes(rom.K, rom.M)[1])
    assert c[j] == pytest.approx(1.0, abs=1e-8)
    assert c.sum() == pytest.approx(1.0)


def test_two_modes_share_in_proportion_to_their_peaks(rom):
    _, phi = rom_modes(rom.K, rom.M)
    tau = np.linspace(0, 2 * np.pi, 512, endpoint=False)
    x = 2e-4 * np.cos(tau)[:, None] * phi[:, 0] + 6e-4 * np.sin(4 * tau)[:, None] * phi[:, 2]
    c = modal_contributions(x, rom.M, phi)
    np.testing.assert_allclose(c[[0, 2]], [0.25, 0.75], atol=1e-10)
    assert np.delete(c, [0, 2]).max() < 1e-10
    assert np.all(modal_contributions(0 * x, rom.M, phi) == 0)  # at rest: no contribution, no nan


def test_harmonic_contributions_of_a_synthetic_signal():
    b = FourierBasis(12, 64)
    tau = b.tau
    r = 0.3 + 2.0 * np.cos(3 * tau) + 1.5 * np.sin(3 * tau) - 0.7 * np.sin(10 * tau) + 0.1 * np.cos(12 * tau)
    expected = np.zeros(13)
    expected[[0, 3, 10, 12]] = [0.3, 2.5, 0.7, 0.1]
    np.testing.assert_allclose(harmonic_contributions(b.to_freq(r)), expected, atol=1e-12)


def test_branch_content_on_the_rotor67_rom_matches_an_independent_fft(rom):
    hbm = HbmOptions(n_harmonics=8, n_time=64)
    res = build_residual(rom, CasingOptions(), ContactOptions(), hbm, method="dlft")
    rng = np.random.default_rng(3)
    u = rng.standard_normal((3, res.size)) * np.repeat(1.0 / (1 + np.arange(res.n_c)), res.n_r)
    omega = np.array([600.0, 1200.0, 1800.0])
    out = branch_content(res, rom, u, omega)
    for i in range(3):
        le = res.signals(u[i], omega[i])["displacement"][:, 0]  # LE radial dof over one period, m
        spec = np.fft.rfft(le) / len(le)
        ref = np.concatenate([[abs(spec[0])], 2 * np.abs(spec[1:9])])
        np.testing.assert_allclose(out["harmonic_contribution"][i], ref, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(out["modal_contribution"].sum(axis=1), 1.0)
    assert out["modal_contribution"].shape == (3, rom.K.shape[0])
