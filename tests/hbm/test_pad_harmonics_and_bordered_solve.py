"""Two contracts: padding a solution with harmonics, and the bordered solve.

1. hbm.harmonic.start.pad_harmonics: a guess carried to another N_h keeps every harmonic
   both bases share and zeroes (or drops) the others. Reference: the time signal
   x(tau) = c_0 + sum_k a_k cos(k tau) + b_k sin(k tau) evaluated by hand.
2. hbm.harmonic.solver.HbmFactorization.solve_bordered: without friction the kept
   preconditioner is J's exact inverse (double precision), so the bordered preconditioner
   (block elimination with it) is the bordered matrix's exact inverse: its first guess
   already meets the tolerance and GMRES needs no iteration. A wrong sign in the
   elimination still converges (GMRES repairs the rank-one error) but costs iterations on
   every corrector step. Reference for the step: numpy's dense solve of the bordered matrix.
"""
import numpy as np
import pytest

from hbm.harmonic.solver import HbmSolver
from hbm.harmonic.start import pad_harmonics
from support import forced_standin_residual, perturbed_state


def _signal(coeffs: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """x(tau) of eq. (5)-ordered coefficients (2 N_h + 1, n_r), by explicit cos/sin sums."""
    x = np.tile(coeffs[0], (len(tau), 1))
    for k in range(1, (len(coeffs) - 1) // 2 + 1):
        x += np.outer(np.cos(k * tau), coeffs[2 * k - 1]) + np.outer(np.sin(k * tau), coeffs[2 * k])
    return x


@pytest.mark.parametrize("n_from,n_to", [(3, 5), (3, 3), (5, 2)])
def test_padding_keeps_the_shared_harmonics_and_zeroes_the_rest(n_from, n_to):
    n_r = 4
    rng = np.random.default_rng(11)
    c = rng.standard_normal((2 * n_from + 1, n_r))
    out = pad_harmonics(c.reshape(-1), n_r, n_to)
    assert out.shape == ((2 * n_to + 1) * n_r,)
    tau = np.linspace(0.0, 2 * np.pi, 37)
    kept = c[: 2 * min(n_from, n_to) + 1]  # the harmonics 0 .. min(N_h, N_h') by hand
    np.testing.assert_allclose(_signal(out.reshape(-1, n_r), tau), _signal(kept, tau), rtol=0, atol=1e-12)
    if n_to > n_from:  # the new harmonics are exactly zero, not noise
        assert not np.any(out.reshape(-1, n_r)[2 * n_from + 1:])


@pytest.mark.parametrize("method", ["dlft", "rl"])
def test_frictionless_bordered_step_needs_no_krylov_iteration(method):
    res = forced_standin_residual(method, n_harmonics=5, n_time=64, mu=0.0)
    om = 900.0
    u = perturbed_state(res, 3, om)
    assert res.samples(res.to_coefficients(u), om).active.any()  # contact: J is not Z_r alone
    R, Js, c = res(u, om)
    rng = np.random.default_rng(7)
    p, q, s = rng.standard_normal(res.size), 0.7, 0.3
    solver = HbmSolver(rtol=1e-10, forcing=0.0)
    step = solver.factorize(Js).solve_bordered(c, p, q, R, s)
    # the independent reference: the dense bordered matrix solved by LAPACK
    A = np.block([[np.asarray(Js), c[:, None]], [p[None, :], np.array([[q]])]])
    ref = np.linalg.solve(A, -np.append(R, s))
    np.testing.assert_allclose(np.append(step.dx, step.dw), ref, rtol=0, atol=1e-8 * np.abs(ref).max())
    assert not step.full and solver.stats.get("bordered_fallback", 0) == 0
    # the block elimination with J's exact inverse is the bordered matrix's exact inverse
    assert solver.stats["last_krylov"] == 0
