"""GMRES must not report convergence that no solution can reach.

With A singular and b outside its range, every x leaves ||b - A x|| >= ||P b||, P the
projector on the orthogonal complement of range(A) (a least-squares bound computed here by
hand or by the SVD, independently of GMRES). When that bound exceeds rtol ||b||, a
converged=True is false: the Arnoldi estimate alone read converged there (the last
Hessenberg pivot is round-off, the update ~1e16).
"""
import dataclasses

import numpy as np
import scipy.linalg as sla

from hbm.harmonic.residual import build_residual
from hbm.harmonic.solver import HbmSolver
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
