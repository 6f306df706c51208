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
    """LU found a zero pivot; callers relying on hbm.newton catch its SingularJacobian."""


def _lu(J: np.ndarray):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sla.LinAlgWarning)
        lu = sla.lu_factor(J, check_finite=False)
    if not np.all(np.isfinite(lu[0])) or np.any(np.diag(lu[0]) == 0.0):
        try:
            from hbm.newton import SingularJacobian
        except ImportError:  # pragma: no cover - the continuation module is optional here
            SingularJacobian = SingularJacobianError
        raise SingularJacobian("dense LU: zero pivot")
    return lu


def gmres(matvec, precond, b: np.ndarray, x0: np.ndarray, rtol: float, max_iter: int):
    """Right-preconditioned GMRES (no restart). Returns (x, iterations, converged)."""
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
    V[0] = r / beta
    y = np.zeros(0)
    for j in range(max_iter):
        Zs[j] = precond(V[j])
        w = matvec(Zs[j])
        for i in range(j + 1):  # modified Gram-Schmidt, twice for safety at tight tolerance
            H[i, j] = V[i] @ w
            w -= H[i, j] * V[i]
        for i in range(j + 1):
            c = V[i] @ w
            H[i, j] += c
            w -= c * V[i]
        H[j + 1, j] = np.linalg.norm(w)
        e = np.zeros(j + 2)
        e[0] = beta
        y, *_ = np.linalg.lstsq(H[:j + 2, :j + 1], e, rcond=None)
        res = float(np.linalg.norm(H[:j + 2, :j + 1] @ y - e))
        if res <= rtol * bn or H[j + 1, j] == 0.0:
            return x0 + y @ Zs[:j + 1], j + 1, True
        V[j + 1] = w / H[j + 1, j]
    return x0 + y @ Zs[:max_iter], max_iter, False


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
