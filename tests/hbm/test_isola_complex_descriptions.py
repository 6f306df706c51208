"""A complex per-point description of a found branch (e.g. a Floquet multiplier)."""
from __future__ import annotations

import warnings

import numpy as np

from hbm.continuation.arclength import ContinuationOptions
from hbm.continuation.newton import NewtonOptions
from hbm.isolas.search import SearchOptions, Seed, search
from hbm.linalg.dense import DirectSolver


class LineToNan:
    """R(x, w) = x - 0.01: the line x = 0.01, NaN above Omega = 0.7, where the continuation
    keeps its failed last point. Picklable."""

    def __call__(self, x, w, jacobian=True):
        R = np.array([x[0] - 0.01]) if w <= 0.7 else np.array([np.nan])
        if not jacobian:
            return R
        return R, np.array([[1.0]]), np.array([0.0])


def line_to_nan():
    return LineToNan(), DirectSolver()


class Multiplier:
    """describe(omega, u): the complex number omega + 2j at every point. Picklable."""

    def __call__(self, omega, u):
        return {"multiplier": omega + 2.0j}


def test_a_complex_description_keeps_its_imaginary_part_and_is_nan_where_not_converged():
    co = ContinuationOptions(omega_min=0.0, omega_max=1.0, ds=0.05, ds_min=1e-3, ds_max=0.1, x_scale=1.0,
                             omega_scale=1.0, max_points=200, closed_loop_tol=1e-3,
                             newton=NewtonOptions(tol_residual=1e-12, max_iter=6))
    opts = SearchOptions(tolerance=1e-2, continuation=co, workers=1, newton=NewtonOptions(tol_residual=1e-12))
    with warnings.catch_warnings():
        warnings.simplefilter("error", np.ComplexWarning)  # a cast to float would drop the imaginary part
        (b,) = search(line_to_nan, [Seed(0.3, np.array([0.0]), "on the line")], [], opts,
                      describe=Multiplier()).branches
    ok = np.asarray(b.converged, bool)
    mu = b.extras["multiplier"]
    assert (~ok).sum() == 1 and mu.dtype == np.complex128
    np.testing.assert_array_equal(mu[ok], b.omega[ok] + 2.0j)
    assert np.isnan(mu[~ok].real).all() and np.isnan(mu[~ok].imag).all()
