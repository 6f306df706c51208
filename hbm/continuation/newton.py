"""Newton corrections for `residual(x, omega) -> (R, dR_dx, dR_domega)` callables.

Two solvers share one convergence rule (section 1.2 of the reference paper, plus an
optional bound on the correction):

- `newton_solve`: plain Newton at fixed omega, eq. (9);
- `solve_bordered`: one linear step of the arc-length corrector, eq. (25), by block
  elimination so that only dR_dx is factorised, with a fall-back to the full bordered
  matrix when dR_dx is singular (a fold of the branch).

Linear algebra is pluggable: `factorize(J) -> solve(b)` where `b` is (n,) or (n, k).
The default handles dense ndarrays (LU) and scipy sparse matrices (SuperLU); a caller
with its own Jacobian type (a block structure, a matrix-free operator) passes its own.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Callable, NamedTuple

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

Solve = Callable[[np.ndarray], np.ndarray]
Factorize = Callable[[object], Solve]
Residual = Callable[[np.ndarray, float], tuple]


class SingularJacobian(RuntimeError):
    """dR_dx could not be factorised or its solve gave non-finite numbers."""


@dataclass(frozen=True)
class NewtonOptions:
    """Convergence rule of every Newton solve.

    tol_residual: a point is a solution when ||R||_2 <= tol_residual (units of R; the
      caller scales R, e.g. N for a force balance).
    tol_step: if set, the last correction must also satisfy ||dy / scale||_2 <= tol_step
      (dimensionless, in the continuation's scaled variables); None: residual only.
    max_iter: linear solves allowed per correction.
    """

    tol_residual: float = 1e-8
    tol_step: float | None = None
    max_iter: int = 12

    def __post_init__(self):
        if not self.tol_residual > 0:
            raise ValueError(f"tol_residual must be > 0, got {self.tol_residual}")
        if self.tol_step is not None and not self.tol_step > 0:
            raise ValueError(f"tol_step must be > 0 or None, got {self.tol_step}")
        if self.max_iter < 1:
            raise ValueError(f"max_iter must be >= 1, got {self.max_iter}")


class NewtonResult(NamedTuple):
    """Outcome of `newton_solve`.

    x: last iterate (n,) (the solution only if `converged`). residual_norm: ||R(x)||_2.
    iterations: linear solves done. reason: "" when converged, else why not.
    """

    x: np.ndarray
    converged: bool
    residual_norm: float
    iterations: int
    reason: str


def factorize_default(J) -> Solve:
    """LU of a dense ndarray or SuperLU of a scipy sparse matrix; returns `solve(b)`.

    Raises SingularJacobian when the factorisation reports an exactly singular matrix.
    Dense LU of a singular matrix only warns; its non-finite results are caught by the
    callers, which check every solve.
    """
    if sp.issparse(J):
        try:
            lu = spla.splu(sp.csc_matrix(J))
        except RuntimeError as exc:  # "Factor is exactly singular"
            raise SingularJacobian(str(exc)) from exc
        return lu.solve
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sla.LinAlgWarning)
        lu = sla.lu_factor(np.asarray(J, dtype=float), check_finite=False)
    if not np.all(np.isfinite(lu[0])) or np.any(np.diag(lu[0]) == 0.0):
        raise SingularJacobian("dense LU: zero pivot")

    def solve(b):
        return sla.lu_solve(lu, b, check_finite=False)

    return solve


def _finite(*arrays) -> bool:
    return all(np.all(np.isfinite(a)) for a in arrays)


def _full_bordered_solve(J, r_omega, p, q, R, P):
    """Solve [[J, r_omega], [p^T, q]] [dx; dw] = -[R; P] as one matrix (dense or sparse)."""
    rhs = -np.concatenate([R, [P]])
    if not (sp.issparse(J) or isinstance(J, np.ndarray)) and hasattr(J, "toarray"):
        J = J.toarray()  # a structured Jacobian (hbm.harmonic.jacobian.HbmJacobian): its dense form
    if sp.issparse(J):
        A = sp.bmat([[J, sp.csc_matrix(r_omega[:, None])], [sp.csr_matrix(p[None, :]), q]], format="csc")
        try:
            d = spla.splu(A).solve(rhs)
        except RuntimeError as exc:
            raise SingularJacobian(f"bordered matrix: {exc}") from exc
    elif isinstance(J, np.ndarray):
        A = np.block([[J, r_omega[:, None]], [p[None, :], np.array([[q]])]])
        try:
            d = np.linalg.solve(A, rhs)
        except np.linalg.LinAlgError as exc:
            raise SingularJacobian(f"bordered matrix: {exc}") from exc
    else:
        raise SingularJacobian(f"dR_dx is singular and of type {type(J).__name__}: no bordered fall-back")
    if not _finite(d):
        raise SingularJacobian("bordered matrix: non-finite solution")
    return d[:-1], float(d[-1])


def solve_bordered(J, r_omega: np.ndarray, p: np.ndarray, q: float, R: np.ndarray, P: float,
                   factorize: Factorize = factorize_default, *, refine_tol: float = 1e-6):
    """One step of eq. (25): [[J, r_omega], [p^T, q]] [dx; dw] = -[R; P].

    J: dR_dx (n, n), any type `factorize` accepts. r_omega: dR_domega (n,). p: dP/dx (n,).
    q: dP/domega. R: residual (n,). P: constraint value. Returns (dx (n,), dw, used_full)
    where used_full says the full bordered matrix was needed.

    A `solve` that has a `bordered(r_omega, p, q, R, P) -> (dx, dw, tol)` method (an
    iterative solver that can take the bordered system in one run, to the relative
    residual tol it chose: an inexact Newton step) is asked first; its answer is checked
    against max(refine_tol, 2 tol). Otherwise block elimination (J a = R, J b = r_omega;
    dw = (p.a - P) / (q - p.b); dx = -a - b dw) factorises J only. It fails at an exact
    fold (J singular) and loses accuracy near one, so its answer is checked on the
    bordered system (when J supports `@`), refined once
    with the same factors, and replaced by the full solve when the relative error still
    exceeds refine_tol (Newton needs no more than a few exact digits in its step).
    """
    rhs_norm = max(float(np.sqrt(R @ R + P * P)), np.finfo(float).tiny)
    try:
        solve = factorize(J)
        if hasattr(solve, "bordered"):  # the solver's own bordered solve (one Krylov run)
            try:
                dx, dw, tol_b = solve.bordered(r_omega, p, q, R, P)
                eR = J @ dx + r_omega * dw + R
                eP = p @ dx + q * dw + P
                if _finite(dx, dw) and np.sqrt(eR @ eR + eP * eP) <= max(refine_tol, 2.0 * tol_b) * rhs_norm:
                    return dx, float(dw), False
            except SingularJacobian:
                pass  # the block elimination below
        ab = np.asarray(solve(np.column_stack([R, r_omega])))
        a, b = ab[:, 0], ab[:, 1]
        den = q - p @ b
        if not (_finite(a, b) and np.isfinite(den) and den != 0.0):
            raise SingularJacobian("block elimination: non-finite or zero pivot")

        def eliminate(rP, a):  # [dx; dw] from a = J^-1 (right-hand side of the R rows)
            dw = (p @ a - rP) / den
            return -a - b * dw, dw

        dx, dw = eliminate(P, a)
        for _ in range(2):  # check, refine once with the same factors, check again
            if not _finite(dx, dw):
                raise SingularJacobian("block elimination: non-finite step")
            try:
                eR = J @ dx + r_omega * dw + R
                eP = p @ dx + q * dw + P
            except (TypeError, ValueError):  # J without a product: trust the elimination
                return dx, float(dw), False
            if np.sqrt(eR @ eR + eP * eP) <= refine_tol * rhs_norm:
                return dx, float(dw), False
            ea = np.asarray(solve(eR)).reshape(-1)
            cx, cw = eliminate(eP, ea)
            dx, dw = dx + cx, dw + cw
    except SingularJacobian:
        pass
    dx, dw = _full_bordered_solve(J, np.asarray(r_omega, float), p, q, R, P)
    return dx, dw, True


def evaluate(residual: Residual, x: np.ndarray, omega: float):
    """Call `residual` and normalise its outputs: (R (n,), J, r_omega (n,))."""
    R, J, r_omega = residual(x, omega)
    return np.asarray(R, dtype=float).reshape(-1), J, np.asarray(r_omega, dtype=float).reshape(-1)


def newton_solve(residual: Residual, x0: np.ndarray, omega: float, options: NewtonOptions = NewtonOptions(),
                 *, factorize: Factorize | None = None, x_scale: float | np.ndarray = 1.0) -> NewtonResult:
    """Solve R(x, omega) = 0 at fixed omega by Newton's method, eq. (9).

    x0: initial iterate (n,). omega: the fixed parameter, rad/s. x_scale: scalar or (n,),
    the size of x used by options.tol_step. Converged when ||R||_2 <= tol_residual (and the
    last scaled correction <= tol_step when set). Never raises on non-convergence: check
    `converged` and `reason`.
    """
    factorize = factorize or factorize_default
    x = np.array(x0, dtype=float).reshape(-1)
    step_norm = np.inf
    for it in range(options.max_iter + 1):
        R, J, _ = evaluate(residual, x, omega)
        rn = float(np.linalg.norm(R))
        if not np.isfinite(rn):
            return NewtonResult(x, False, rn, it, f"non-finite residual at omega={omega:.6g}")
        step_ok = options.tol_step is None or (it > 0 and step_norm <= options.tol_step)
        if rn <= options.tol_residual and step_ok:
            return NewtonResult(x, True, rn, it, "")
        if it == options.max_iter:
            break
        try:
            dx = np.asarray(factorize(J)(-R)).reshape(-1)
        except SingularJacobian as exc:
            return NewtonResult(x, False, rn, it, f"singular Jacobian at omega={omega:.6g}: {exc}")
        if not _finite(dx):
            return NewtonResult(x, False, rn, it, f"singular Jacobian at omega={omega:.6g}: non-finite step")
        x = x + dx
        step_norm = float(np.linalg.norm(dx / x_scale))
    return NewtonResult(x, False, rn, options.max_iter,
                        f"no convergence in {options.max_iter} iterations at omega={omega:.6g} "
                        f"(||R||={rn:.3e} > {options.tol_residual:.1e})")
