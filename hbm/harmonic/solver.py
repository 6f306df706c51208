"""Linear solves with the HBM Jacobian that reuse an LU factorisation across Newton
iterations and continuation steps.

The dense condensed Jacobian (n_u = 27 (2 N_h + 1) = 2187 for N_h = 40) costs ~0.2 s to
factorise on 2 cores but ~2 ms to multiply or back-substitute. Between successive
iterations it changes little (Z_r(omega) smoothly, the contact part where the contact
set moves), so a stale LU is an excellent preconditioner: GMRES on J with M = LU(J_old)
converges in a few iterations to a tight tolerance. The solve stays exact (to rtol) for
the current J; only when GMRES stalls is J factorised again.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla


class SingularJacobianError(RuntimeError):
    """LU found a zero pivot; callers relying on hbm.continuation.newton catch its SingularJacobian."""


def _lu(J: np.ndarray):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sla.LinAlgWarning)
        lu = sla.lu_factor(J, check_finite=False)
    if not np.all(np.isfinite(lu[0])) or np.any(np.diag(lu[0]) == 0.0):
        try:
            from hbm.continuation.newton import SingularJacobian
        except ImportError:  # pragma: no cover - the continuation module is optional here
            SingularJacobian = SingularJacobianError
        raise SingularJacobian("dense LU: zero pivot")
    return lu


def gmres(matvec, precond, b: np.ndarray, x0: np.ndarray, rtol: float, max_iter: int):
    """Right-preconditioned GMRES (no restart), Givens rotations on the Hessenberg matrix.

    Converged when the residual ||b - A x|| (the Arnoldi estimate) <= rtol ||b||.
    Returns (x, iterations, converged).
    """
    bn = float(np.linalg.norm(b))
    if bn == 0.0:
        return np.zeros_like(b), 0, True
    r = b - matvec(x0)
    beta = float(np.linalg.norm(r))
    if beta <= rtol * bn:
        return x0, 0, True
    n = b.size
    V = np.empty((max_iter + 1, n))
    Zs = np.empty((max_iter, n))
    H = np.zeros((max_iter + 1, max_iter))
    cs, sn = np.zeros(max_iter), np.zeros(max_iter)
    g = np.zeros(max_iter + 1)
    g[0] = beta
    V[0] = r / beta

    def update(j):
        y = sla.solve_triangular(H[:j, :j], g[:j], check_finite=False)
        return x0 + y @ Zs[:j]

    for j in range(max_iter):
        Zs[j] = precond(V[j])
        w = matvec(Zs[j])
        # classical Gram-Schmidt, twice (as accurate as modified GS, in BLAS-2 products)
        h = V[:j + 1] @ w
        w -= h @ V[:j + 1]
        c = V[:j + 1] @ w
        w -= c @ V[:j + 1]
        h += c
        hn = float(np.linalg.norm(w))
        for i in range(j):  # previous rotations on the new column
            h[i], h[i + 1] = cs[i] * h[i] + sn[i] * h[i + 1], -sn[i] * h[i] + cs[i] * h[i + 1]
        d = float(np.hypot(h[j], hn))
        if d == 0.0:  # breakdown with a zero column: nothing more to gain
            return (update(j) if j else x0), j, False
        cs[j], sn[j] = h[j] / d, hn / d
        h[j] = d
        H[:j + 1, j] = h
        g[j + 1] = -sn[j] * g[j]
        g[j] *= cs[j]
        if abs(g[j + 1]) <= rtol * bn or hn == 0.0:
            return update(j + 1), j + 1, True
        V[j + 1] = w / hn
    return update(max_iter), max_iter, False


@dataclass
class ReusedLu:
    """factorize(J) -> solve(b) keeping the last LU as a preconditioner.

    J: dense (n, n) ndarray. solve(b): b (n,) or (n, k); returns the same shape.
    rtol: relative residual ||J x - b|| / ||b|| required of each solve.
    max_krylov: GMRES iterations allowed before J is factorised afresh.
    refactor_after: a call that needed more than this many iterations factorises J
    at the next factorize() (cheaper than paying the slow convergence again).
    Counters: n_factorizations, n_solves, n_krylov (statistics, for benchmarks).
    """

    rtol: float = 1e-10
    max_krylov: int = 25
    refactor_after: int = 12
    n_factorizations: int = 0
    n_solves: int = 0
    n_krylov: int = 0
    _lu: object = field(default=None, repr=False)
    _stale: bool = field(default=True, repr=False)

    def reset(self):
        """Forget the stored factorisation (next call factorises)."""
        self._lu, self._stale = None, True

    def _factor(self, J):
        self._lu = _lu(J)
        self.n_factorizations += 1
        self._stale = False

    def __call__(self, J) -> callable:
        J = np.asarray(J, dtype=float)
        fresh = self._lu is None or self._stale
        if fresh:
            self._factor(J)
            self._stale = False
        holder = {"fresh": fresh}

        def solve(b):
            b = np.asarray(b, dtype=float)
            cols = b.reshape(b.shape[0], -1)
            out = np.empty_like(cols)
            for c in range(cols.shape[1]):
                self.n_solves += 1
                lu = self._lu
                x0 = sla.lu_solve(lu, cols[:, c], check_finite=False)
                if holder["fresh"]:
                    out[:, c] = x0
                    continue
                x, it, ok = gmres(J.__matmul__, lambda v: sla.lu_solve(lu, v, check_finite=False), cols[:, c], x0,
                                  self.rtol, self.max_krylov)
                self.n_krylov += it
                if not ok:  # the old LU no longer preconditions: factorise this J
                    self._factor(J)
                    holder["fresh"] = True
                    x = sla.lu_solve(self._lu, cols[:, c], check_finite=False)
                elif it > self.refactor_after:
                    self._stale = True
                out[:, c] = x
            return out.reshape(b.shape)

        return solve


@dataclass
class HbmSolver:
    """factorize(J) -> solve(b) for the HBM Jacobians of hbm.harmonic.residual.

    An hbm.harmonic.jacobian.HbmJacobian is solved by GMRES to rtol, preconditioned by the direct
    structured solve (hbm.harmonic.jacobian.ContactPreconditioner) of an earlier J, kept across
    Newton iterations and continuation points while it works: a solve that needed more
    than refactor_after iterations makes the next factorize() build a fresh one. A dense
    ndarray goes to the ReusedLu `dense`.
    rtol: an inexact Newton step: 3e-7 keeps Newton's convergence (its own test is on
    ||R||) and passes the continuation's check of each bordered solve (1e-6) with margin.
    forcing: the bordered (corrector) solves are inexact Newton steps with relative
    tolerance min(1e-3, max(rtol, forcing ||R||)): loose far from the solution, rtol
    near it (superlinear convergence is kept, fewer GMRES iterations are spent). Measured
    on the coarse rotor 67 ROM, [1500, 2000] rad/s, N_h = 40: forcing 0 / 1e-3 / 1e-2:
    RL 33.3 / 31.8 / 29.9 s, DLFT 14.7 / 12.8 / 13.5 s (DLFT's Newton iterations 696 / 941
    / 1063: its semi-smooth law dislikes inexact steps; 1e-3 is the compromise).
    atol: absolute residual asked of the bordered solves at most (see
    HbmJacobian.factorize); compute_nfrc sets tol_residual / 10, which relaxes the last
    Newton step of each point to what Newton's test can see (RL NFRC 77 -> 67 s).
    refactor_after: a preconditioner costs ~12 ms at N_h = 40, a GMRES iteration ~1 ms,
    and its solves take 1.6, 2.5, 3.8, 5.7, 6.5 ... 9 iterations as it ages (RL, [1500,
    2000] rad/s); rebuilding after a solve of more than 6 iterations (every ~3 to 4
    solves) measured, whole NFRC at N_h = 40, refactor_after = 4 / 6 / 8 / 12: RL 51.0 /
    47.8 / 50.1 / 54.6 s, DLFT 23.8 / 24.1 / 27.0 / 27.5 s (one run each, +-3 s noise).
    Counters: n_factorizations (preconditioners built plus dense LUs), n_krylov (GMRES
    iterations, both kinds).
    """

    rtol: float = 3e-7
    forcing: float = 1e-3
    max_krylov: int = 60
    refactor_after: int = 6
    atol: float = 0.0
    dense: ReusedLu = field(default_factory=ReusedLu)
    stats: dict = field(default_factory=dict)
    _pre: object = field(default=None, repr=False)
    _stale: bool = field(default=True, repr=False)

    @property
    def n_factorizations(self) -> int:
        return self.stats.get("preconditioners", 0) + self.dense.n_factorizations

    @property
    def n_krylov(self) -> int:
        return self.stats.get("krylov", 0) + self.dense.n_krylov

    def __call__(self, J):
        from hbm.harmonic.jacobian import HbmJacobian
        if not isinstance(J, HbmJacobian):
            return self.dense(J)
        if self._stale or self._pre is None:
            self._pre = J.preconditioner()
            self.stats["preconditioners"] = self.stats.get("preconditioners", 0) + 1
            self._stale = False
        inner = J.factorize(rtol=self.rtol, max_krylov=self.max_krylov, stats=self.stats, preconditioner=self._pre,
                            forcing=self.forcing, atol=self.atol)

        def after():
            self._pre = inner.preconditioner["pre"]  # a fresh one if the old one stalled
            if self.stats.get("last_krylov", 0) > self.refactor_after:
                self._stale = True

        def solve(b):
            x = inner(b)
            after()
            return x

        def bordered(*args):
            try:
                return inner.bordered(*args)
            except Exception:
                self._stale = True
                raise
            finally:
                after()

        solve.bordered = bordered
        return solve
