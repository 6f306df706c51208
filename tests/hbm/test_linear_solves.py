"""GMRES must not report convergence that no solution can reach.

With A singular and b outside its range, every x leaves ||b - A x|| >= ||P b||, P the
projector on the orthogonal complement of range(A) (a least-squares bound computed here by
hand or by the SVD, independently of GMRES). When that bound exceeds rtol ||b||, a
converged=True is false: the Arnoldi estimate alone read converged there (the last
Hessenberg pivot is round-off, the update ~1e16).
"""
import dataclasses

import numpy as np
import pytest
import scipy.linalg as sla

from hbm.harmonic.residual import build_residual
from hbm.harmonic.solver import HbmSolver, norm_estimate
from hbm.linalg.errors import SingularMatrixError
from hbm.linalg.gmres import gmres
from hbm.options import CasingOptions, ContactOptions, HbmOptions
from support import standin_rom


def test_singular_diagonal_system_is_not_reported_converged():
    A = np.diag([1.0, 1.0, 1.0, 1.0, 1.0, 0.0])
    b = np.ones(6)
    # (A x)_6 = 0 for every x, so ||b - A x|| >= |b_6| = 1 = ||b|| / sqrt(6)
    x, it, ok = gmres(lambda v: A @ v, lambda v: v, b, np.zeros(6), 1e-8, 20)
    assert np.linalg.norm(b - A @ x) >= 1.0 - 1e-12
    assert not ok  # the estimate alone read ok=True (3 iterations, |x| = 4e16)


def test_rank_deficient_system_is_not_reported_converged():
    rng = np.random.default_rng(1)
    n = 50
    U, s, Vt = np.linalg.svd(rng.standard_normal((n, n)))
    s[-1] = 0.0
    A = U @ np.diag(s) @ Vt
    b = rng.standard_normal(n)
    bound = abs(U[:, -1] @ b) / np.linalg.norm(b)  # least-squares residual, relative
    assert bound > 0.1
    x, it, ok = gmres(lambda v: A @ v, lambda v: v, b, np.zeros(n), 1e-8, 60)
    assert not ok  # the estimate alone read ok=True with a true relative residual of 1.2
    # and a regular system still converges, its claim true
    A[np.diag_indices(n)] += 3.0
    x, it, ok = gmres(lambda v: A @ v, lambda v: v, b, np.zeros(n), 1e-10, 60)
    assert ok and np.linalg.norm(b - A @ x) <= 1e-10 * np.linalg.norm(b)


def test_a_claim_of_convergence_on_an_ill_conditioned_system_is_true():
    """Regular but ill-conditioned systems (singular values from 1 to 1e-8, random bases,
    n = 40), a preconditioner 1e-6 off the exact inverse, rtol = 1e-10: the products' round-off
    (eps ||A|| ||x||, ||x|| up to 1e8 ||b||) is about what rtol asks, so the Arnoldi estimate
    can read converged where the true residual misses rtol. Whatever GMRES returns, a
    converged=True must hold for the true residual computed here, to the 1 % the trust rule
    itself allows (it keeps the estimate when round-off bounds it at 0.01 rtol; 5 % asserted).
    Trusting the estimate whenever that bound is within 100 rtol made 2 false claims over
    these 20 systems, 1.43 and 3.1 times rtol."""
    n, rtol = 40, 1e-10
    for seed in range(20):
        rng = np.random.default_rng(seed)
        U, _ = np.linalg.qr(rng.standard_normal((n, n)))
        V, _ = np.linalg.qr(rng.standard_normal((n, n)))
        s = np.logspace(0.0, -8.0, n)
        A = U @ np.diag(s) @ V.T
        P = (V @ np.diag(1.0 / s) @ U.T) @ (np.eye(n) + 1e-6 * rng.standard_normal((n, n)))
        b = rng.standard_normal(n)
        x, it, ok = gmres(lambda v: A @ v, lambda v: P @ v, b, np.zeros(n), rtol, 60, anorm=1.0)
        assert not ok or np.linalg.norm(b - A @ x) <= 1.05 * rtol * np.linalg.norm(b), seed


def test_stale_preconditioner_is_not_trusted_on_a_singular_jacobian():
    """The HBM Jacobian out of contact at an undamped eigenfrequency is singular (the
    condensed block of harmonic 1); the solve must not stop on the stale preconditioner's
    GMRES, whose answer cannot meet rtol (SVD bound), but go on to J's own preconditioner."""
    rom = standin_rom()
    rom = dataclasses.replace(rom, C=np.zeros_like(rom.C))
    w1 = float(np.sqrt(sla.eigh(rom.K, rom.M, eigvals_only=True)[0]))  # 1050 rad/s
    res = build_residual(rom, CasingOptions(), ContactOptions(mu=0.0), HbmOptions(n_harmonics=2, n_time=8),
                         method="dlft", distance=lambda tau: np.full((len(tau), rom.n_boundary), 1.0))
    u = np.zeros(res.size)
    J_old = res(u, 0.999 * w1)[1]
    J = res(u, w1)[1]
    A = np.asarray(J)
    b = np.random.default_rng(0).standard_normal(res.size)
    Ua, sa, _ = np.linalg.svd(A)
    null = Ua[:, sa < 1e-12 * sa[0]]
    assert null.shape[1] >= 1 and np.linalg.norm(null.T @ b) > 1e3 * HbmSolver().rtol * np.linalg.norm(b)
    solver = HbmSolver()
    solver.precondition(J_old)
    # no answer meets rtol: refused, after J's own preconditioner and the dense LU were tried
    with pytest.raises(SingularMatrixError, match="relative residual"):
        solver.factorize(J).solve(b)
    # the estimate alone accepted the stale preconditioner's GMRES (9 iterations, true relative
    # residual 0.11): one preconditioner, no fall-back
    assert solver.stats["preconditioners"] + solver.stats.get("dense_fallback", 0) >= 2


def test_block_elimination_refines_once_then_solves_the_whole():
    """A solver too poor for the tolerance (1 % error per solve): block elimination, one
    refinement, then the full bordered matrix, whose answer is the dense solve's; a second
    refinement (one more J solve, a GMRES run or a dense LU in the HBM) was computed and
    an unchecked one would be thrown away (3 solves)."""
    from hbm.linalg.bordered import eliminate_bordered

    rng = np.random.default_rng(0)
    n = 20
    A = rng.standard_normal((n, n))
    calls = []

    def poor_solve(b):
        calls.append(1)
        x = np.linalg.solve(A, b)
        return x * (1.0 + 1e-2 * rng.standard_normal(x.shape))

    c, p, r = rng.standard_normal((3, n))
    q, s = 0.3, 0.1
    step = eliminate_bordered(poor_solve, A, c, p, q, r, s, 1e-12)
    ref = np.linalg.solve(np.block([[A, c[:, None]], [p[None, :], np.array([[q]])]]), -np.append(r, s))
    assert step.full and np.allclose(np.append(step.dx, step.dw), ref, rtol=1e-10, atol=1e-12)
    assert len(calls) == 2  # the elimination's solve of [r, c], one refinement


def test_start_from_a_preconditioner_of_a_singular_matrix_is_not_reported_converged():
    """x0 = P^-1 b, P the LU of a singular A: |x0| ~ 1e16 along the null vector, so the start's
    residual b - A x0 is round-off of eps ||A|| |x0|, which the Arnoldi estimate cannot see.
    The least-squares bound |q_n . b| (q_n A's null vector, by construction) is 0.01 to 0.34 of
    ||b||: no x meets rtol. Before the start's round-off entered the trust rule, every one of
    these six systems read converged (true relative residuals 0.019 to 8.8)."""
    rng = np.random.default_rng(3)
    n = 30
    for _ in range(6):
        Q = np.linalg.qr(rng.standard_normal((n, n)))[0]
        s = np.logspace(0, -2, n)
        s[-1] = 0.0
        A = (Q * s) @ Q.T
        b = rng.standard_normal(n)
        bound = abs(Q[:, -1] @ b) / np.linalg.norm(b)
        assert bound > 1e-3
        lu = sla.lu_factor(A)

        def pre(v):
            return sla.lu_solve(lu, v)

        x0 = pre(b)
        assert np.linalg.norm(x0) > 1e14 * np.linalg.norm(b)
        x, it, ok = gmres(lambda v: A @ v, pre, b, x0, 1e-8, 40, anorm=np.linalg.norm(A, 2))
        assert not ok
        # a regular system from a large but honest start still converges, its claim true
        B = A + 1e-6 * np.eye(n)
        lu = sla.lu_factor(B)
        x, it, ok = gmres(lambda v: B @ v, pre, b, pre(b), 1e-8, 40, anorm=np.linalg.norm(B, 2))
        assert ok and np.linalg.norm(b - B @ x) <= 1e-8 * np.linalg.norm(b)


def test_singular_jacobian_solve_through_the_preconditioner_start_is_refused():
    """The HBM's own path: an undamped stand-in ROM with friction, in contact, at a parameter
    where the condensed Jacobian is singular; the solver's GMRES starts from its
    preconditioner's answer. A solve must either meet rtol on the true residual or raise."""
    rom = standin_rom()
    rom = dataclasses.replace(rom, C=np.zeros_like(rom.C))
    w1 = float(np.sqrt(sla.eigh(rom.K, rom.M, eigvals_only=True)[0]))
    res = build_residual(rom, CasingOptions(), ContactOptions(mu=0.0), HbmOptions(n_harmonics=2, n_time=8),
                         method="dlft", distance=lambda tau: np.full((len(tau), rom.n_boundary), 1.0))
    J = res(np.zeros(res.size), w1)[1]
    A = np.asarray(J)
    # the norm estimate: within a small factor of ||J||_2 (it bounds round-off, not a result)
    assert 0.1 * np.linalg.norm(A, 2) <= norm_estimate(J) <= np.linalg.norm(A, 2)
    b = np.random.default_rng(0).standard_normal(res.size)
    solver = HbmSolver()
    pre = solver.precondition(J)
    x0 = pre(b)
    assert np.linalg.norm(x0) > 1e14 * np.linalg.norm(b)
    x, it, ok = gmres(J.__matmul__, pre, b, x0, solver.rtol, 40, anorm=norm_estimate(J))
    # the estimate alone read converged after 7 iterations, the true relative residual 0.069
    assert not ok or np.linalg.norm(b - A @ x) <= solver.rtol * np.linalg.norm(b)
    try:
        y = solver.factorize(J).solve(b)
    except SingularMatrixError:
        return
    assert np.linalg.norm(b - A @ y) <= solver.rtol * np.linalg.norm(b)
