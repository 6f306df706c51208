"""The bordered system of the arc-length corrector by block elimination, with its fall-back.

[[J, c], [p^T, q]] [dx; dw] = -[r; s]: with J a = r and J b = c, dw = (p.a - s) / (q - p.b)
and dx = -a - b dw, so only J is factorised. Block elimination fails at an exact fold
(J singular) and loses digits near one, so its answer is checked on the bordered system,
refined once with the same factors, and replaced by a solve of the full bordered matrix
when the relative error still exceeds refine_tol: Newton needs only a few exact digits in
its step, but those it needs. The full solve is checked too (a nearly singular bordered
matrix, e.g. J with a two-dimensional null space, gives an LU answer with an O(1) residual
and no error): refused past refine_tol, with a SingularMatrixError that Newton records.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from hbm.linalg.errors import SingularMatrixError
from hbm.linalg.protocol import BorderedStep


def finite(*arrays) -> bool:
    """Whether every entry of every array is finite."""
    return all(np.all(np.isfinite(a)) for a in arrays)


def _relative_misses(J, x, b, tol):
    """(whether some column of b (n,) or (n, k) misses ||b - J x|| <= tol ||b||, b - J x,
    the worst relative residual); NaN misses."""
    r = b - J @ x
    res = np.linalg.norm(np.reshape(r, (len(b), -1)), axis=0)
    bn = np.linalg.norm(np.reshape(b, (len(b), -1)), axis=0)
    return not np.all(res <= tol * bn), r, float(np.max(res / np.maximum(bn, np.finfo(float).tiny)))


def check_solution(J, x: np.ndarray, b: np.ndarray, tol: float, what: str) -> np.ndarray:
    """x, if it meets GMRES's true-residual rule (hbm.linalg.gmres): ||b - J x|| <= tol ||b||,
    column by column for b (n, k); else SingularMatrixError naming the residual. A direct
    solve of a nearly singular J (LU, the exact preconditioner) returns ~1e16-sized x with a
    residual of O(||b||) and no error otherwise. Costs one product with J."""
    miss, _, worst = _relative_misses(J, x, b, tol)
    if miss:
        raise SingularMatrixError(f"{what}: relative residual {worst:.2e} > {tol:.1e} "
                                  f"(singular or too ill-conditioned)")
    return x


def refined_solution(J, solve, b: np.ndarray, tol: float, what: str) -> np.ndarray:
    """solve(b) held to check_solution's rule at one product with J; where it misses (an
    ill-conditioned J, digits short of a tight tol), refined once with the same solve, as
    the block elimination is, and checked again (a second product), else refused."""
    x = solve(b)
    miss, r, _ = _relative_misses(J, x, b, tol)
    if not miss:
        return x
    return check_solution(J, x + solve(r), b, tol, what)


def bordered_residual(J, c, p, q, r, s, dx, dw) -> float:
    """||[[J, c], [p^T, q]] [dx; dw] + [r; s]||_2 (J needs `@`)."""
    eR = J @ dx + c * dw + r
    eP = p @ dx + q * dw + s
    return float(np.sqrt(eR @ eR + eP * eP))


def solve_full_bordered(J, c, p, q, r, s, refine_tol: float = 1e-6) -> BorderedStep:
    """The bordered matrix factorised as a whole: dense LU, or SuperLU for scipy sparse J;
    the answer checked on the bordered system (one product) against refine_tol.

    J: (n, n) ndarray, scipy sparse, or anything with __array__ (made dense).
    """
    rhs = -np.concatenate([r, [s]])
    if sp.issparse(J):
        A = sp.bmat([[J, sp.csc_matrix(c[:, None])], [sp.csr_matrix(p[None, :]), q]], format="csc")
        try:
            d = spla.splu(A).solve(rhs)
        except RuntimeError as exc:  # "Factor is exactly singular"
            raise SingularMatrixError(f"bordered matrix: {exc}") from exc
    else:
        A = np.block([[np.asarray(J, dtype=float), c[:, None]], [p[None, :], np.array([[q]])]])
        try:
            d = np.linalg.solve(A, rhs)
        except np.linalg.LinAlgError as exc:
            raise SingularMatrixError(f"bordered matrix: {exc}") from exc
    if not finite(d):
        raise SingularMatrixError("bordered matrix: non-finite solution")
    check_solution(A, d, rhs, refine_tol, "bordered matrix")  # the last resort: refused, not hidden
    return BorderedStep(d[:-1], float(d[-1]), True)


def eliminate_bordered(solve, J, c, p, q, r, s, refine_tol: float = 1e-6) -> BorderedStep:
    """Block elimination with `solve(b)` (J^-1 b for b (n,) or (n, 2)), checked on the
    bordered system (J needs `@`), refined once, else the full bordered solve."""
    rhs_norm = max(float(np.sqrt(r @ r + s * s)), np.finfo(float).tiny)
    try:
        ab = np.asarray(solve(np.column_stack([r, c])))
        a, b = ab[:, 0], ab[:, 1]
        den = q - p @ b
        if not (finite(a, b) and np.isfinite(den) and den != 0.0):
            raise SingularMatrixError("block elimination: non-finite or zero pivot")

        def eliminate(rs, a):  # [dx; dw] from a = J^-1 (right-hand side of the R rows)
            dw = (p @ a - rs) / den
            return -a - b * dw, dw

        dx, dw = eliminate(s, a)
        for refine in (True, False):  # check, refine once with the same factors, check again
            if not finite(dx, dw):
                raise SingularMatrixError("block elimination: non-finite step")
            eR = J @ dx + c * dw + r
            eP = p @ dx + q * dw + s
            if np.sqrt(eR @ eR + eP * eP) <= refine_tol * rhs_norm:
                return BorderedStep(dx, float(dw), False)
            if not refine:  # a second refinement would go unchecked: solve the whole instead
                break
            cx, cw = eliminate(eP, np.asarray(solve(eR)).reshape(-1))
            dx, dw = dx + cx, dw + cw
    except SingularMatrixError:
        pass
    return solve_full_bordered(J, np.asarray(c, float), p, q, r, s, refine_tol)
