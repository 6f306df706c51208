"""An indefinite ROM stiffness is refused by the modal analyses of hbm, not turned into a
zero eigenfrequency (a ROM file may come from another FE code: nothing upstream checked K)."""
from types import SimpleNamespace

import numpy as np
import pytest

from hbm.harmonic.content import rom_modes
from hbm.isolas.harmonic import boundary_modes


def _rotated(w2):
    """(K, M) with the eigenvalues w2 (rad^2/s^2) for a diagonal M, rotated so that eigh works
    on a full matrix: K = M^1/2 Q diag(w2) Q^T M^1/2."""
    n = len(w2)
    Q, _ = np.linalg.qr(np.random.default_rng(3).standard_normal((n, n)))
    m = np.linspace(1.0, 2.0, n)
    S = np.diag(np.sqrt(m))
    K = S @ Q @ np.diag(w2) @ Q.T @ S
    return 0.5 * (K + K.T), np.diag(m)


def test_rom_modes_refuses_a_negative_eigenvalue():
    K, M = _rotated([-4.0e4, 1.0e6, 4.0e6, 9.0e6])
    with pytest.raises(ValueError, match=r"not positive semi-definite.*w\^2 = -40000 rad"):
        rom_modes(K, M)


def test_rom_modes_takes_round_off_below_zero_as_zero():
    # a zero eigenvalue comes back from eigh as +-1e-10 or so: within n eps cond(M) max|w^2|
    K, M = _rotated([0.0, 1.0e6, 4.0e6, 9.0e6])
    w, phi = rom_modes(K, M)
    np.testing.assert_allclose(w, [0.0, 1.0e3, 2.0e3, 3.0e3], atol=1e-3)
    np.testing.assert_allclose(phi.T @ M @ phi, np.eye(4), atol=1e-12)


def test_boundary_modes_refuses_a_negative_eigenvalue():
    K, M = _rotated([-4.0e4, 1.0e6, 4.0e6, 9.0e6, 1.6e7, 2.5e7])
    with pytest.raises(ValueError, match=r"not positive semi-definite.*w\^2 = -40000 rad"):
        boundary_modes(SimpleNamespace(K=K, M=M, n_boundary=1), 2)


def test_boundary_modes_frequencies_and_shapes():
    # diagonal (K, M): mode j is the unit vector e_j / sqrt(m_j), w_j = sqrt(k_j / m_j)
    k = np.array([4.0, 1.0, 9.0, 16.0, 25.0, 36.0]) * 1e6
    m = np.array([1.0, 1.0, 1.0, 4.0, 1.0, 1.0])
    rom = SimpleNamespace(K=np.diag(k), M=np.diag(m), n_boundary=2)
    w, b = boundary_modes(rom, 3)
    np.testing.assert_allclose(w, [1.0e3, 2.0e3, 2.0e3], rtol=1e-12)
    assert b.shape == (3, 6)
    # the radial dof of the boundary nodes are 0 and 3: mode 1 (dof 1) has none, so it is
    # scaled by its largest entry; the others are 1 at their radial dof
    np.testing.assert_allclose(np.abs(b[0]), [0, 1, 0, 0, 0, 0], atol=1e-12)
    radial = {tuple(np.round(np.abs(r), 12)) for r in b[1:]}
    assert radial == {(1.0, 0, 0, 0, 0, 0), (0, 0, 0, 1.0, 0, 0)}


def _bordered_system():
    """A friction state of the stand-in ROM (several nodes in contact), its structured and
    dense Jacobians, and a preconditioner from another state and speed."""
    from hbm.harmonic.preconditioner import ContactPreconditioner
    from support import forced_standin_residual, perturbed_state

    res = forced_standin_residual("dlft", mu=0.15)

    def state(seed, omega):
        return perturbed_state(res, seed, omega), omega

    R, Js, rw = res(*state(3, 900.0))
    old = ContactPreconditioner(res(*state(4, 880.0))[1])
    return R, Js, np.asarray(Js), rw, old


def test_a_failed_bordered_gmres_is_counted():
    from hbm.harmonic.solver import HbmSolver

    R, Js, Jd, rw, old = _bordered_system()
    p, q, P = np.random.default_rng(5).standard_normal(len(R)), 0.7, 0.3
    A = np.block([[Jd, rw[:, None]], [p[None, :], np.array([[q]])]])
    rhs = np.append(R, P)
    # two Krylov iterations with a stale preconditioner cannot reach rtol = 1e-10: the
    # bordered GMRES fails, the block elimination (dense LU here) solves the system
    solver = HbmSolver(rtol=1e-10, forcing=0.0, max_krylov=2)
    dx, dw, full = solver.factorize(Js, preconditioner=old).solve_bordered(rw, p, q, R, P)
    assert np.linalg.norm(A @ np.append(dx, dw) + rhs) <= 1e-10 * np.linalg.norm(rhs)
    assert solver.stats["bordered_fallback"] == 1
    # with room to converge the one-GMRES path is taken and nothing is counted
    solver = HbmSolver(rtol=1e-10, forcing=0.0)
    solver.factorize(Js).solve_bordered(rw, p, q, R, P)
    assert solver.stats.get("bordered_fallback", 0) == 0
