"""The direct solves (DirectSolver's LU, the HBM's exact preconditioner and dense fall-back LU,
the full bordered matrix) are held to GMRES's true-residual rule, ||J x - b|| <= tol ||b||.

An LU of a nearly singular J meets no zero pivot: it returns x ~ 1e16 whose residual is
O(||b||), and Newton took that step silently. The matrices here have a known condition (built
from their SVD by hand) and the references are independent of the solvers: the least-squares
bound |u_n . b| that no x of moderate size can beat, and the solution V diag(1/s) U^T b.
"""
import dataclasses

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp

import hbm.harmonic.solver as hbm_solver
from hbm.harmonic.residual import build_residual
from hbm.harmonic.solver import HbmSolver
from hbm.linalg.dense import DirectSolver
from hbm.linalg.errors import SingularMatrixError
from hbm.options import CasingOptions, ContactOptions, HbmOptions
from support import standin_rom


def _with_singular_values(s, seed=0):
    """(J, U, V) with J = U diag(s) V^T, U and V random orthogonal."""
    rng = np.random.default_rng(seed)
    n = len(s)
    U = np.linalg.qr(rng.standard_normal((n, n)))[0]
    V = np.linalg.qr(rng.standard_normal((n, n)))[0]
    return U @ np.diag(s) @ V.T, U, V


@pytest.mark.parametrize("sparse", [False, True])
def test_direct_solve_of_a_nearly_singular_matrix_is_refused(sparse):
    n = 40
    s = np.ones(n)
    s[-1] = 1e-17  # condition ~2e16
    J, U, V = _with_singular_values(s)
    b = np.random.default_rng(1).standard_normal(n)
    b += np.linalg.norm(b) * U[:, -1]
    # b has a part along u_n: J x = b needs |x| >= |u_n . b| / 1e-17 ~ 1e16 |b|, beyond double
    assert abs(U[:, -1] @ b) > 0.5 * np.linalg.norm(b)
    f = DirectSolver().factorize(sp.csc_matrix(J) if sparse else J)
    # the LU answered with a relative residual of 6.8 (dense) / 6.3 (SuperLU), |x| ~1e17, no error
    with pytest.raises(SingularMatrixError, match="relative residual"):
        f.solve(b)
    with pytest.raises(SingularMatrixError, match="relative residual"):
        f.solve(np.column_stack([U[:, 0], b]))  # checked column by column


@pytest.mark.parametrize("sparse", [False, True])
def test_direct_solve_of_an_ill_conditioned_matrix_is_kept_when_it_meets_the_rule(sparse):
    n = 40
    s = np.ones(n)
    s[-1] = 1e-8  # condition 1e8: LU loses 8 digits of x, its residual stays round-off
    J, U, V = _with_singular_values(s)
    b = np.random.default_rng(1).standard_normal(n)
    x = DirectSolver().factorize(sp.csc_matrix(J) if sparse else J).solve(b)
    ref = V @ ((U.T @ b) / s)
    assert np.linalg.norm(x - ref) <= 1e-6 * np.linalg.norm(ref)
    # b in range(J) of a condition-2e16 J: a residual at round-off exists and is kept
    s[-1] = 1e-17
    J, U, V = _with_singular_values(s)
    b = b - U[:, -1] * (U[:, -1] @ b)
    x = DirectSolver().factorize(sp.csc_matrix(J) if sparse else J).solve(b)
    assert np.linalg.norm(J @ x - b) <= 1e-12 * np.linalg.norm(b)


def test_bordered_solve_at_a_fold_is_solved_and_a_singular_bordered_matrix_refused():
    n = 30
    rng = np.random.default_rng(2)
    c, p, r = rng.standard_normal((3, n))
    q, s_ = 0.3, 0.1
    sv = np.ones(n)
    sv[-1] = 1e-17  # a fold: J singular, the bordered matrix not
    J, U, V = _with_singular_values(sv)
    B = np.block([[J, c[:, None]], [p[None, :], np.array([[q]])]])
    assert np.linalg.cond(B) < 1e4
    step = DirectSolver().factorize(J).solve_bordered(c, p, q, r, s_)
    ref = np.linalg.solve(B, -np.append(r, s_))
    assert np.allclose(np.append(step.dx, step.dw), ref, rtol=1e-8, atol=1e-10)
    # two null directions: one border cannot make the bordered matrix regular; its LU gave a
    # relative residual of 1.1 as a full step, no error
    sv[-2] = 1e-17
    J, U, V = _with_singular_values(sv)
    with pytest.raises(SingularMatrixError, match="bordered matrix: relative residual"):
        DirectSolver().factorize(J).solve_bordered(c, p, q, r, s_)


def _undamped(omega_factor):
    """The stand-in ROM without damping, out of contact, at omega_factor times its first
    eigenfrequency: at 1 the condensed harmonic-1 block is singular (cos and sin: nullity 2)."""
    rom = standin_rom()
    rom = dataclasses.replace(rom, C=np.zeros_like(rom.C))
    w1 = float(np.sqrt(sla.eigh(rom.K, rom.M, eigvals_only=True)[0]))
    res = build_residual(rom, CasingOptions(), ContactOptions(mu=0.0), HbmOptions(n_harmonics=2, n_time=8),
                         method="dlft", distance=lambda tau: np.full((len(tau), rom.n_boundary), 1.0))
    J = res(np.zeros(res.size), omega_factor * w1)[1]
    b = np.random.default_rng(0).standard_normal(res.size)
    return J, np.asarray(J), b


def _least_squares_bound(A, b):
    """min over x of ||A x - b|| / ||b||, x of moderate size: b's part off A's numerical range."""
    Ua, sa, _ = np.linalg.svd(A)
    null = Ua[:, sa < 1e-12 * sa[0]]
    return float(np.linalg.norm(null.T @ b) / np.linalg.norm(b))


def test_hbm_exact_preconditioner_answer_is_checked():
    J, A, b = _undamped(1.0)
    solver = HbmSolver()
    assert _least_squares_bound(A, b) > 1e3 * solver.rtol
    f = solver.factorize(J)
    assert f._exact
    # the exact preconditioner answered with a relative residual of 0.24 (|x| 1e16), no error
    with pytest.raises(SingularMatrixError, match="exact preconditioner: relative residual"):
        f.solve(b)
    J, A, b = _undamped(0.999)  # regular: the same answer as a dense solve
    x = HbmSolver().factorize(J).solve(b)
    assert np.allclose(x, np.linalg.solve(A, b), rtol=1e-8, atol=1e-12 * np.linalg.norm(x))


def test_hbm_dense_fallback_answer_is_checked(monkeypatch):
    # GMRES stalls (its own check refused it, or max_krylov): the dense LU is the last resort
    monkeypatch.setattr(hbm_solver, "gmres", lambda matvec, prec, b, x0, rtol, max_iter, anorm=0.0: (x0, max_iter, False))
    J_old, _, _ = _undamped(0.999)
    J, A, b = _undamped(1.0)
    solver = HbmSolver()
    solver.precondition(J_old)  # not J's exact inverse: the GMRES path, then the dense LU
    assert _least_squares_bound(A, b) > 1e3 * solver.rtol
    # the dense LU answered with a relative residual of 0.21 (|x| ~1e16), no error
    with pytest.raises(SingularMatrixError, match="dense fall-back LU: relative residual"):
        solver.factorize(J).solve(b)
    assert solver.stats["dense_fallback"] == 1
    solver = HbmSolver()
    solver.precondition(J)
    x = solver.factorize(J_old).solve(b)  # regular: kept, the dense solve's answer
    assert solver.stats["dense_fallback"] == 1
    assert np.allclose(x, np.linalg.solve(np.asarray(J_old), b), rtol=1e-8, atol=1e-12 * np.linalg.norm(x))


def test_hbm_bordered_solve_of_a_singular_bordered_matrix_is_refused():
    J, A, b = _undamped(1.0)
    rng = np.random.default_rng(1)
    c, p = rng.standard_normal((2, A.shape[0]))
    B = np.block([[A, c[:, None]], [p[None, :], np.array([[0.3]])]])
    assert np.linalg.svd(B, compute_uv=False)[-1] < 1e-12 * np.linalg.norm(B, 2)  # nullity 2 - 1
    # GMRES, the block elimination and the full bordered LU all failed; the last answered a
    # relative residual of 2.2 as a full step
    with pytest.raises(SingularMatrixError, match="bordered matrix: relative residual"):
        HbmSolver().factorize(J).solve_bordered(c, p, 0.3, b, 0.1)
