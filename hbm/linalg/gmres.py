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


def gmres(matvec, precond, b: np.ndarray, x0: np.ndarray, rtol: float, max_iter: int):
    """Solve A x = b, A given by matvec(v) and a preconditioner precond(v) ~ A^-1 v.

    b, x0: (n,). Converged when the Arnoldi estimate of ||b - A x|| <= rtol ||b||.
    Givens rotations on the Hessenberg matrix; classical Gram-Schmidt applied twice (as
    accurate as modified Gram-Schmidt, in BLAS-2 products). Returns (x, iterations, converged);
    converged is checked on the true residual where the estimate cannot be trusted (see
    converged() below: with A singular the estimate alone can read converged).
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
    az = np.zeros(max_iter)  # ||A z_j||: the Hessenberg columns' norms before the rotations
    cs, sn = np.zeros(max_iter), np.zeros(max_iter)
    g = np.zeros(max_iter + 1)
    g[0] = beta
    V[0] = r / beta

    def update(j):
        y = sla.solve_triangular(H[:j, :j], g[:j], check_finite=False)
        return x0 + y @ Zs[:j], y

    def converged(j):
        """x after j iterations and whether it meets rtol. The Arnoldi estimate is trusted
        while the update is well within double precision's reach: eps sum_i |y_i|
        ||A z_i|| well below rtol ||b||. A (near) singular least-squares factor (J singular,
        b outside its range: the estimate can read converged while the true residual is
        O(||b||)) makes y huge; then the true residual decides, at one more product."""
        x, y = update(j)
        if np.all(np.isfinite(y)) and 1e-15 * (bn + float(np.abs(y) @ az[:j])) <= 0.01 * rtol * bn:
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
        az[j] = np.hypot(float(np.linalg.norm(h)), hn)
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
