"""The dynamical content (eqs. 32-34) and of the Fourier basis against independent
references (numpy's complex FFT, hand-built modal motions); bad inputs give a clear error."""

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


def _modes_by_hand(rom):
    """Mass-normalised modes from numpy's unsymmetric eigen-solver of M^-1 K (not scipy's eigh)."""
    lam, vec = np.linalg.eig(np.linalg.solve(rom.M, rom.K))
    order = np.argsort(lam.real)
    phi = np.real(vec[:, order])
    return phi / np.sqrt(np.einsum("ij,ik,kj->j", phi, rom.M, phi))


def test_a_motion_with_nan_is_refused_not_reported_at_rest(rom):
    # two modes, a static part and a higher harmonic, one sample lost to NaN: unchecked, it
    # returned 0 for every mode (the answer for a motion at rest)
    phi = _modes_by_hand(rom)
    tau = 2 * np.pi * np.arange(128) / 128
    x = ((1e-3 * np.cos(tau - tau[9]) + 2e-4)[:, None] * phi[:, 0]  # peaks on the grid: sampled maxima exact
         + 3e-4 * np.cos(5 * (tau - tau[3]))[:, None] * phi[:, 1])
    np.testing.assert_allclose(modal_contributions(x, rom.M, rom_modes(rom.K, rom.M)[1])[:2],
                               [1.2e-3 / 1.5e-3, 0.3e-3 / 1.5e-3], rtol=1e-6)
    x[7, 4] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        modal_contributions(x, rom.M, rom_modes(rom.K, rom.M)[1])


def test_branch_content_of_a_nan_point_is_nan_not_zero(rom):
    res = build_residual(rom, CasingOptions(), ContactOptions(), HbmOptions(n_harmonics=4, n_time=32), method="dlft")
    u = np.zeros((2, res.size))
    u[:, 3 * res.n_r] = 0.5  # a_2 of the LE radial dof, scaled: 0.5 / alpha m
    u[1, 5] = np.nan
    out = branch_content(res, rom, u, np.array([800.0, 800.0]))
    le = res.signals(u[0], 800.0)["displacement"][:, 0]
    ref = np.abs(np.fft.fft(le)) / len(le)
    np.testing.assert_allclose(out["harmonic_contribution"][0], np.r_[ref[0], 2 * ref[1:5]], atol=1e-15)
    assert out["modal_contribution"][0].sum() == pytest.approx(1.0)
    assert np.all(np.isnan(out["modal_contribution"][1]))  # without the check: all 0, "at rest"
    assert np.all(np.isnan(out["harmonic_contribution"][1]))


def test_harmonic_contributions_refuse_an_even_number_of_rows():
    # [c_0, a_1, b_1, a_2]: unchecked, it paired a_1 with a_2 ... and gave [1, 3.61, 5]
    assert harmonic_contributions(np.array([1.0, 3.0, 4.0])) == pytest.approx([1.0, 5.0])
    with pytest.raises(ValueError, match="2 N_h \\+ 1"):
        harmonic_contributions(np.array([1.0, 2.0, 3.0, 4.0]))
    with pytest.raises(ValueError):
        harmonic_contributions(np.array([1.0, 2.0]))


@pytest.mark.parametrize("nh, nt", [(5, 11), (3, 7), (0, 1)])
def test_the_smallest_odd_grid_is_alias_free_against_numpy_fft(nh, nt):
    # N_t = 2 N_h + 1 resolves every harmonic up to N_h (N_t / 2 = N_h + 1/2): it must be accepted
    b = FourierBasis(nh, nt)
    rng = np.random.default_rng(nh)
    c = rng.standard_normal(2 * nh + 1)
    tau = 2 * np.pi * np.arange(nt) / nt
    k = np.arange(1, nh + 1)
    x = c[0] + np.cos(np.outer(tau, k)) @ c[1::2] + np.sin(np.outer(tau, k)) @ c[2::2]
    np.testing.assert_allclose(b.to_time(c), x, atol=1e-13)
    spec = np.fft.fft(x) / nt  # exp(-i k tau): a_k = 2 Re, b_k = -2 Im
    ref = np.empty(2 * nh + 1)
    ref[0], ref[1::2], ref[2::2] = spec[0].real, 2 * spec[1:nh + 1].real, -2 * spec[1:nh + 1].imag
    np.testing.assert_allclose(b.to_freq(x), ref, atol=1e-13)
    np.testing.assert_allclose(ref, c, atol=1e-13)
    np.testing.assert_allclose(harmonic_contributions(b.to_freq(x)), np.r_[abs(c[0]), np.hypot(c[1::2], c[2::2])],
                               atol=1e-13)
    dx = np.cos(np.outer(tau, k)) @ (k * c[2::2]) - np.sin(np.outer(tau, k)) @ (k * c[1::2])
    np.testing.assert_allclose(b.to_time(b.derivative(c)), dx, atol=1e-12)
    assert np.mean(x ** 2) == pytest.approx(c[0] ** 2 + 0.5 * np.sum(c[1:] ** 2))  # Parseval


@pytest.mark.parametrize("nh, nt", [(5, 10), (5, 9), (1, 2)])
def test_aliasing_grids_are_refused(nh, nt):
    with pytest.raises(ValueError, match="too small"):
        FourierBasis(nh, nt)


@pytest.mark.parametrize("nh, nt", [(-1, 4), (5.5, 20), (5, 20.7), (float("nan"), 20)])
def test_a_basis_needs_whole_non_negative_counts(nh, nt):
    # each must be refused: N_t = 20.7 sampled 21 angles 2 pi i / 20.7, past one period
    with pytest.raises(ValueError):
        FourierBasis(nh, nt)


def test_transforms_refuse_the_wrong_number_of_samples_or_coefficients():
    b = FourierBasis(3, 16)
    with pytest.raises(ValueError, match="16"):
        b.to_freq(np.ones(6))  # unchecked: rfft of 6 samples divided by 16, returned silently
    with pytest.raises(ValueError, match="16"):
        b.to_freq(np.ones((3, 6)), axis=-1)
    with pytest.raises(ValueError, match="16"):
        b.weighted_product(np.ones(6))  # unchecked: silently the product of another grid
    with pytest.raises(ValueError, match="7"):
        b.to_time(np.ones(6))
    np.testing.assert_allclose(b.to_freq(np.full(16, 2.0)), np.r_[2.0, np.zeros(6)], atol=1e-15)
