"""fem.modes.compute_modes checks each returned mode by its residual ||K x - w^2 M x|| / ||K x||.

The block solver stops when the eigenvalues stop changing, which a factor of the wrong matrix
does as readily as the right one: with a factor of 1.05 K the iteration converges to the
eigenvectors of K with w^2 1.05 times too large, whose residual is exactly 0.05 (by hand:
K x - 1.05 lam M x = -0.05 K x), and must be refused. On a clamped box the modes are
accepted, their residual recomputed here is below the tolerance, and their frequencies are
ARPACK's (shift-invert eigsh of the same K, M)."""
import re

import numpy as np
import pytest
import scipy.sparse.linalg as sla
from box_mesh import box_mesh

from fem.assembly import assemble_system
from fem.cholesky import CholeskyFactor
from fem.material import Material
from fem.modes import RESIDUAL_TOL, compute_modes

N_MODES = 6


@pytest.fixture(scope="module")
def system():
    b = box_mesh(0.1, 0.03, 0.01, 0.006)
    return assemble_system(b.nodes, b.cells, b.root_facets, Material())


def _residuals(K, M, X, w2):
    KX = K @ X
    return np.linalg.norm(KX - (M @ X) * w2, axis=0) / np.linalg.norm(KX, axis=0)


def test_modes_of_a_box_pass_the_residual_check_and_match_arpack(system):
    r = compute_modes(system.K, system.M, N_MODES)
    res = _residuals(system.K, system.M, r.vectors, r.frequencies ** 2)
    assert (res < RESIDUAL_TOL).all(), res
    np.testing.assert_allclose(r.residuals, res, rtol=1e-6)
    w2 = np.sort(sla.eigsh(system.K, M=system.M, k=N_MODES, sigma=0.0)[0])
    np.testing.assert_allclose(r.frequencies ** 2, w2, rtol=1e-9)


def test_modes_from_a_factor_of_another_stiffness_are_refused(system):
    factor = CholeskyFactor((1.05 * system.K).tocsr())
    try:
        with pytest.raises(RuntimeError, match=r"residual .* above 0\.01 for mode 1 \(") as info:
            compute_modes(system.K, system.M, N_MODES, factor=factor)
    finally:
        factor.destroy()
    # every mode is named, with the residual 0.05 worked out by hand
    named = re.findall(r"mode (\d+) \([^)]*Hz\): ([0-9.e+-]+)", str(info.value))
    assert [int(j) for j, _ in named] == list(range(1, N_MODES + 1)), str(info.value)
    np.testing.assert_allclose([float(v) for _, v in named], 0.05, rtol=1e-2)


def test_a_loose_tolerance_is_not_refused_for_its_larger_residuals(system):
    # tol = 1e-4 is a valid [fem] tol: its modes' residuals exceed 1e-2 while their eigenvalues
    # are ARPACK's to ~1e-7, so the limit grows with tol (residual_limit)
    r = compute_modes(system.K, system.M, N_MODES, tol=1e-4)
    w2 = np.sort(sla.eigsh(system.K, M=system.M, k=N_MODES, sigma=0.0)[0])
    np.testing.assert_allclose(r.frequencies ** 2, w2, rtol=1e-6)
