"""The casing's symmetry in the HBM residual (HarmonicBalanceResidual.images): shifting an
orbit in time by 1 / n_l of a revolution maps solutions to solutions, so the isola search
counts a branch and its images once.

Checked against the residual itself: R(image of u) = image of R(u) at arbitrary u, for both
contact laws, in the basis of Omega and of Omega / 2; an orbit with the casing's symmetry
(the primary NFRC's, only even harmonics of Omega) is its own image; a forcing or another
obstacle has no images.
"""
from dataclasses import replace

import numpy as np
import pytest

from hbm.harmonic.residual import HarmonicBalanceResidual, build_residual
from hbm.options import CasingOptions, ContactOptions, HbmOptions
from support import coarse_rom


@pytest.fixture(scope="module")
def rom():
    return coarse_rom()


@pytest.mark.parametrize("nu", [1, 2])
@pytest.mark.parametrize("method", ["dlft", "rl"])
def test_the_residual_commutes_with_its_images(rom, nu, method):
    opts = replace(HbmOptions(n_harmonics=10, n_time=256), subharmonic=nu)
    res = build_residual(rom, CasingOptions(), ContactOptions(), opts, method=method)
    u = 0.3 * np.random.default_rng(1).standard_normal(res.size)  # contact on part of the period
    R = res(u, 1200.0, jacobian=False)
    assert np.linalg.norm(R) > 0
    imgs, imgs_R = res.images(u), res.images(R)  # R has the unknowns' harmonic layout
    assert len(imgs) == 2 * nu - 1  # shifts by 1 / 2, (and 1 / 4, 3 / 4 with nu = 2) of a revolution
    for ui, Ri in zip(imgs, imgs_R):
        assert np.linalg.norm(ui - u) > 0.1 * np.linalg.norm(u)
        np.testing.assert_allclose(res(ui, 1200.0, jacobian=False), Ri, atol=1e-12 * np.linalg.norm(R))


def test_an_orbit_with_the_casing_symmetry_is_its_own_image(rom):
    res = build_residual(rom, CasingOptions(), ContactOptions(), HbmOptions(n_harmonics=10, n_time=256))
    xr = res.to_coefficients(np.random.default_rng(2).standard_normal(res.size))
    xr[1::4] = xr[2::4] = 0.0  # odd harmonics (rows 1, 2 of each pair of harmonics) removed
    u = res.to_unknowns(xr)
    (img,) = res.images(u)
    np.testing.assert_allclose(img, u, atol=1e-14 * np.linalg.norm(u))


def test_no_images_with_another_obstacle_or_an_odd_aft_grid(rom):
    opts = HbmOptions(n_harmonics=5, n_time=64)
    res = HarmonicBalanceResidual(rom, CasingOptions(), ContactOptions(), opts,
                                  distance=lambda tau: np.full((len(tau), rom.n_boundary), 1e-3))
    assert res.images(np.zeros(res.size)) == []
    odd = build_residual(rom, CasingOptions(), ContactOptions(), HbmOptions(n_harmonics=5, n_time=65))
    assert odd.images(np.zeros(odd.size)) == []  # a shift of half a period is not a whole AFT sample


@pytest.mark.parametrize("method", ["dlft", "rl"])
def test_an_aft_grid_of_a_multiple_of_the_lobes_keeps_a_symmetric_orbit_symmetric(rom, method):
    """Three lobes (rotor 37's scenes): the residual of an orbit holding only the harmonics
    3 k of Omega holds only those when N_t is a multiple of 3; on N_t = 1024 (the scenes'
    grid before) the AFT breaks the symmetry by a share of |R| far above round-off, so the
    symmetric branch is no exact invariant of the discrete problem and its branch points
    are imperfect: the scene refuses such an N_t (pipelines.scene)."""
    nh = 10
    k = np.r_[0, np.repeat(np.arange(1, nh + 1), 2)]  # harmonic of each row, eq. (5) order
    broken = {}
    for n_time in (1024, 1026, 1152):
        res = build_residual(rom, CasingOptions(n_lobes=3), ContactOptions(),
                             HbmOptions(n_harmonics=nh, n_time=n_time), method=method)
        xr = res.to_coefficients(0.3 * np.random.default_rng(4).standard_normal(res.size))
        xr[k % 3 != 0] = 0.0
        R = res.to_coefficients(res(res.to_unknowns(xr), 1500.0, jacobian=False))
        broken[n_time] = np.linalg.norm(R[k % 3 != 0]) / np.linalg.norm(R)
        assert (len(res.images(res.to_unknowns(xr))) == 2) == (n_time % 3 == 0)
    assert broken[1026] < 1e-12 and broken[1152] < 1e-12, broken
    assert broken[1024] > 1e-6, broken  # measured 4.5e-5 (DLFT) and 8.4e-5 (RL) on this state


@pytest.mark.parametrize("method", ["dlft", "rl"])
def test_in_the_basis_of_half_omega_the_grid_needs_a_multiple_of_twice_the_lobes(rom, method):
    """With [hbm] subharmonic = 2 the AFT grid spans two revolutions, so the casing's turn by
    1/3 of a revolution (three lobes) is N_t / 6 samples: the residual commutes with that turn
    (harmonic k of Omega / 2 turned by k 2 pi / 6, done here by hand) on N_t = 1032 and not on
    1029, a multiple of 3 only; the scene asks for a multiple of nu n_l (pipelines.scene)."""
    nh = 20
    k = np.r_[0, np.repeat(np.arange(1, nh + 1), 2)][:, None]
    c, s = np.cos(k[1::2] * 2.0 * np.pi / 6), np.sin(k[1::2] * 2.0 * np.pi / 6)
    defect = {}
    for n_time in (1029, 1032):
        res = build_residual(rom, CasingOptions(n_lobes=3), ContactOptions(),
                             HbmOptions(n_harmonics=nh, n_time=n_time, subharmonic=2), method=method)

        def turn(u):
            xr = res.to_coefficients(u)
            y = xr.copy()
            y[1::2], y[2::2] = c * xr[1::2] + s * xr[2::2], c * xr[2::2] - s * xr[1::2]
            return res.to_unknowns(y)

        u = 0.3 * np.random.default_rng(5).standard_normal(res.size)
        R = res(u, 1500.0, jacobian=False)
        defect[n_time] = np.linalg.norm(res(turn(u), 1500.0, jacobian=False) - turn(R)) / np.linalg.norm(R)
        assert (len(res.images(u)) == 5) == (n_time % 6 == 0)
    assert defect[1032] < 1e-12, defect
    assert defect[1029] > 1e-6, defect  # measured 1.6e-4 (DLFT) and 4.1e-4 (RL) on this state
