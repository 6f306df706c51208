"""Right-preconditioned GMRES without restart.

scipy.sparse.linalg.gmres is not used: the HBM solves need the Arnoldi residual estimate
at every iteration to stop at an absolute target (an inexact Newton step), a preconditioner
applied on the right so that the estimate is the true residual's, and the iteration count
to decide when a reused preconditioner has aged; scipy's restarted, left-preconditioned
variant reports none of these cheaply.
"""
from __future__ import annotations

import numpy as np
import scipy.linalg as sla


def gmres(matvec, precond, b: np.ndarray, x0: np.ndarray, rtol: float, max_iter: int, anorm: float = 0.0):
    """Solve A x = b, A given by matvec(v) and a preconditioner precond(v) ~ A^-1 v.

    b, x0: (n,). Converged when the Arnoldi estimate of ||b - A x|| <= rtol ||b||.
    Givens rotations on the Hessenberg matrix; classical Gram-Schmidt applied twice (as
    accurate as modified Gram-Schmidt, in BLAS-2 products). Returns (x, iterations, converged);
    converged is checked on the true residual where the estimate cannot be trusted (see
    converged() below: with A singular the estimate alone can read converged).
    anorm: an estimate of ||A|| (0: none). Forming A v rounds to about eps ||A|| ||v||, far
    above ||A v|| for a v along a near null vector: a start x0 = precond(b) of a (nearly)
    singular A is such a v, and the residual b - A x0 the iteration starts from is then
    round-off that the estimate cannot see.
    """
    bn = float(np.linalg.norm(b))
    if bn == 0.0:
        return np.zeros_like(b), 0, True
    r = b - matvec(x0)
    start_error = 1e-15 * float(anorm) * float(np.linalg.norm(x0))  # round-off left in r
    beta = float(np.linalg.norm(r))
    if beta <= rtol * bn:  # beta is the true residual: no estimate to trust
        return x0, 0, True
    n = b.size
    V = np.empty((max_iter + 1, n))
    Zs = np.empty((max_iter, n))
    H = np.zeros((max_iter + 1, max_iter))
    az = np.zeros(max_iter)  # max(||A z_j||, anorm ||z_j||): what forming A z_j rounds on
    cs, sn = np.zeros(max_iter), np.zeros(max_iter)
    g = np.zeros(max_iter + 1)
    g[0] = beta
    V[0] = r / beta

    def update(j):
        y = sla.solve_triangular(H[:j, :j], g[:j], check_finite=False)
        return x0 + y @ Zs[:j], y

    def converged(j):
        """x after j iterations and whether it meets rtol. The Arnoldi estimate is trusted
        while the start and the update are well within double precision's reach: eps (anorm
        ||x0|| + sum_i |y_i| max(||A z_i||, anorm ||z_i||)) well below rtol ||b||. A (near)
        singular least-squares factor (J singular, b outside its range: the estimate can read
        converged while the true residual is O(||b||)) makes y huge, a preconditioner of a
        singular J makes x0 huge; then the true residual decides, at one more product."""
        x, y = update(j)
        bound = start_error + 1e-15 * (bn + float(np.abs(y) @ az[:j]))
        if np.all(np.isfinite(y)) and bound <= 0.01 * rtol * bn:
            return x, True
        res = float(np.linalg.norm(b - matvec(x))) if np.all(np.isfinite(x)) else np.inf
        return x, res <= rtol * bn

    for j in range(max_iter):
        Zs[j] = precond(V[j])
        w = matvec(Zs[j])
        h = V[:j + 1] @ w
        w -= h @ V[:j + 1]
        c = V[:j + 1] @ w
        w -= c @ V[:j + 1]
        h += c
        hn = float(np.linalg.norm(w))
        az[j] = max(float(np.hypot(float(np.linalg.norm(h)), hn)), float(anorm) * float(np.linalg.norm(Zs[j])))
        for i in range(j):  # previous rotations on the new column
            h[i], h[i + 1] = cs[i] * h[i] + sn[i] * h[i + 1], -sn[i] * h[i] + cs[i] * h[i + 1]
        d = float(np.hypot(h[j], hn))
        if d == 0.0:  # breakdown with a zero column: nothing more to gain
            return (update(j)[0] if j else x0), j, False
        cs[j], sn[j] = h[j] / d, hn / d
        h[j] = d
        H[:j + 1, j] = h
        g[j + 1] = -sn[j] * g[j]
        g[j] *= cs[j]
        if abs(g[j + 1]) <= rtol * bn or hn == 0.0:
            x, ok = converged(j + 1)
            return x, j + 1, ok
        V[j + 1] = w / hn
    return update(max_iter)[0], max_iter, False
