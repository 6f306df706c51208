"""HarmonicBalanceResidual.refined(factor): the same problem with factor times the harmonics
and AFT samples (hbm.stability.convergence.check_harmonics asks a solution for its refinement).

Every attribute that __init__ and the setters establish is the coarse residual's, except
those that are the finer grid's by design (checked to be that grid's); the casing stays the
casing, so images() (the orbit shifted by a lobe) works on the fine problem as on the coarse
one: the fine images of a padded state are the padded coarse images, and the fine residual
commutes with them, for nu = 1 and 2, DLFT and RL (with and without the Lanczos filter),
with and without friction, in both senses of rotation.
"""
from dataclasses import replace

import numpy as np
import pytest

from hbm.continuation.newton import NewtonOptions
from hbm.harmonic.fourier import FourierBasis
from hbm.harmonic.residual import HarmonicBalanceResidual, build_residual
from hbm.harmonic.solver import HbmSolver
from hbm.harmonic.start import damped_newton
from hbm.options import CasingOptions, ContactOptions, HbmOptions
from support import coarse_rom

NH, NT = 6, 64
KEPT = ("rom", "casing", "contact", "method", "friction", "nu", "n_b", "n_r", "forcing", "rho", "theta", "rotation",
        "_casing_obstacle", "obstacle_scale", "alpha", "k_ref")


@pytest.fixture(scope="module")
def rom():
    return coarse_rom()


def _padded(res, fine, u):
    """u of res as unknowns of fine: its harmonics, zero rows appended."""
    xr = res.to_coefficients(u)
    out = np.zeros((fine.n_c, fine.n_r))
    out[: len(xr)] = xr
    return fine.to_unknowns(out)


@pytest.mark.parametrize("rotation", [1, -1])
@pytest.mark.parametrize("mu", [0.0, 0.15])
@pytest.mark.parametrize("method, lanczos", [("dlft", True), ("rl", True), ("rl", False)])
@pytest.mark.parametrize("nu", [1, 2])
def test_the_refined_residual_is_the_same_problem_with_its_images(rom, nu, method, lanczos, mu, rotation):
    contact = ContactOptions(mu=mu, lanczos=lanczos)
    opts = replace(HbmOptions(n_harmonics=NH, n_time=NT), subharmonic=nu)
    res = build_residual(replace(rom, rotation=rotation), CasingOptions(), contact, opts, method=method)
    res.set_obstacle_scale(0.7)
    fine = res.refined(2)
    for name in KEPT:
        a, b = getattr(res, name), getattr(fine, name)
        assert (np.array_equal(a, b) if isinstance(a, np.ndarray) else a == b), name
    assert fine.friction == (mu > 0) and fine.rotation == rotation and fine.nu == nu
    assert fine.options == replace(opts, n_harmonics=2 * NH, n_time=2 * NT)
    grid = FourierBasis(2 * NH, 2 * NT)
    assert (fine.basis.n_harmonics, fine.basis.n_time) == (12, 128) and fine.size == 25 * res.n_r
    np.testing.assert_array_equal(fine.distance, res._distance(nu * grid.tau))
    want_sigma = grid.lanczos_sigma(nu) if (method == "rl" and lanczos) else np.ones(25)
    np.testing.assert_array_equal(fine.sigma, want_sigma)
    # images: shifts by 1 / 2 revolution (nu = 1), 1 / 4, 1 / 2, 3 / 4 (nu = 2) of the 2-lobe casing
    u = 0.3 * np.random.default_rng(1).standard_normal(res.size)  # contact on part of the period
    coarse, mine = res.images(u), fine.images(_padded(res, fine, u))
    assert len(coarse) == len(mine) == 2 * nu - 1
    for a, b in zip(coarse, mine):
        np.testing.assert_allclose(b, _padded(res, fine, a), rtol=0, atol=1e-14 * np.linalg.norm(u))
    uf = _padded(res, fine, u)
    R = fine(uf, 1200.0, jacobian=False)
    assert np.linalg.norm(R) > 0
    for ui, Ri in zip(fine.images(uf), fine.images(R)):
        assert np.linalg.norm(ui - uf) > 0.1 * np.linalg.norm(uf)
        np.testing.assert_allclose(fine(ui, 1200.0, jacobian=False), Ri, rtol=0, atol=1e-12 * np.linalg.norm(R))


def test_a_refined_solution_has_images_that_solve_the_fine_problem(rom):
    """Frictionless DLFT at 1700 rad/s, N_h = 8 (contact on 5 % of the samples): the fine
    residual's solution from the padded coarse one (N_h = 16) and its image by half a
    revolution solve the fine problem to Newton's tolerance 1e-8 (measured 4e-11); the primary
    orbit has the casing's symmetry, so the image is the orbit itself (to 4e-15)."""
    w = 1700.0
    res = build_residual(rom, CasingOptions(), ContactOptions(), HbmOptions(n_harmonics=8, n_time=128), friction=False)
    sol = damped_newton(res, res.linear_solution(w), w, NewtonOptions(tol_residual=1e-8), HbmSolver())
    assert sol.converged and 0.0 < res.samples(res.to_coefficients(sol.x), w).active.mean() < 0.2
    fine = res.refined(2)
    fs = damped_newton(fine, _padded(res, fine, sol.x), w, NewtonOptions(tol_residual=1e-8), HbmSolver())
    assert fs.converged
    (img,) = fine.images(fs.x)
    assert np.linalg.norm(fine(img, w, jacobian=False)) <= 1e-8
    assert np.linalg.norm(img - fs.x) <= 1e-12 * np.linalg.norm(fs.x)


def test_another_obstacle_stays_another_obstacle(rom):
    """A flat wall 1 mm out: no images on either grid, and the fine grid samples that wall."""
    wall = lambda tau: np.full((len(tau), rom.n_boundary), 1e-3)  # noqa: E731
    res = HarmonicBalanceResidual(rom, CasingOptions(), ContactOptions(), HbmOptions(n_harmonics=NH, n_time=NT),
                                  distance=wall)
    fine = res.refined(3)
    assert res.images(np.ones(res.size)) == [] and fine.images(np.ones(fine.size)) == []
    assert fine.distance.shape == (3 * NT, rom.n_boundary) and np.all(fine.distance == 1e-3)
