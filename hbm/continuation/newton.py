"""The one Newton loop, for `residual(x, omega) -> (R, dR_dx, dR_domega)` callables.

`newton_iterate` is the loop and its convergence rule (section 1.2 of the reference
paper, plus an optional bound on the last correction and an optional backtracking line
search); it knows neither what the unknowns are nor how a step is solved. Two users:

- `newton_solve`: Newton at fixed omega, eq. (9), with a LinearSolver's solve;
- `newton_solve_on_plane`: Newton on (x, omega) with one linear constraint (a hyperplane),
  with the LinearSolver's bordered solve;
- the arc-length corrector (hbm.continuation.arclength), eq. (25), whose unknowns are
  (x, omega) and whose step is the LinearSolver's bordered solve.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, NamedTuple

import numpy as np
import scipy.sparse as sp

from hbm.linalg.dense import DirectSolver
from hbm.linalg.errors import SingularMatrixError
from hbm.linalg.protocol import LinearSolver
from hbm.options import check_flag, check_option

Residual = Callable[[np.ndarray, float], tuple]


class NonFiniteJacobianError(SingularMatrixError):
    """dR_dx holds NaN or inf: the caller's residual, not a singular matrix, is at fault."""


def nonfinite_jacobian(J) -> bool:
    """Whether a Jacobian (ndarray, scipy sparse, or anything with __array__) holds NaN or inf.
    Called only once a solve has failed: it may make a structured Jacobian dense."""
    try:
        a = J.data if sp.issparse(J) else np.asarray(J, dtype=float)
        return not bool(np.all(np.isfinite(a)))
    except (TypeError, ValueError):
        return False


def named_solve(J, solve):
    """solve() with its failure named: NonFiniteJacobianError where J has NaN or inf entries
    (the factorisation then reports a zero pivot or a non-finite result, which would read as
    a singular Jacobian)."""
    try:
        out = solve()
    except SingularMatrixError as exc:
        if nonfinite_jacobian(J):
            raise NonFiniteJacobianError("dR_dx has NaN or inf entries") from exc
        raise
    return out


@dataclass(frozen=True)
class NewtonOptions:
    """Convergence rule of every Newton solve.

    tol_residual: a point is a solution when ||R||_2 <= tol_residual (units of R; the
      caller scales R, e.g. N for a force balance).
    tol_step: if set, the last correction must also satisfy ||dy / scale||_2 <= tol_step
      (dimensionless, in the continuation's scaled variables); None: residual only.
    max_iter: linear solves allowed per correction.
    line_search: backtrack along each step, halving it up to max_halvings times until
      ||R|| decreases by the Armijo factor (1 - 1e-4 t) (the last halving is taken even if
      it does not): a start-up aid for far-off guesses
      (the stiff penalty contact from the contact-free solution). The continuation's
      corrector stays plain Newton: a shortened step leaves its hypersphere.
    """

    tol_residual: float = 1e-8
    tol_step: float | None = None
    max_iter: int = 12
    line_search: bool = False
    max_halvings: int = 8
    stall_iterations: int | None = None
    stall_factor: float = 0.1

    def __post_init__(self):
        check_option("tol_residual", self.tol_residual, 0, low_open=True)
        if self.tol_step is not None:
            check_option("tol_step", self.tol_step, 0, low_open=True, note="or None")
        check_option("max_iter", self.max_iter, 1, integer=True)
        check_flag("line_search", self.line_search)
        check_option("max_halvings", self.max_halvings, 0, integer=True)
        if self.stall_iterations is not None:
            check_option("stall_iterations", self.stall_iterations, 1, integer=True, note="or None")
        check_option("stall_factor", self.stall_factor, 0, 1, low_open=True)


class NewtonResult(NamedTuple):
    """Outcome of a Newton solve.

    x: last iterate (n,) (the solution only if `converged`). residual_norm: ||R(x)||_2.
    iterations: linear solves done. reason: "" when converged, else why not.
    """

    x: np.ndarray
    converged: bool
    residual_norm: float
    iterations: int
    reason: str


def stalled(history: list[float], k: int, factor: float) -> bool:
    """The stall rule: whether the last k residual norms of history all stay above factor
    times the best one before them (a Newton run that has stopped making progress)."""
    return len(history) > k and min(history[-k:]) > factor * min(history[:-k])


def newton_iterate(y0: np.ndarray, linearise, options: NewtonOptions, *, scale: float | np.ndarray = 1.0,
                   merit=None, where: str = "") -> NewtonResult:
    """The Newton loop.

    y0: first iterate (n,). linearise(y) -> (||R(y)||, step): the residual norm at y and a
    callable step() -> dy solving the linearised system (either may raise SingularMatrixError:
    the point fails with that reason);
    or (||R(y)||, step, what): what names the non-finite quantity when the norm is not
    finite (default "residual", e.g. "dR_domega").
    scale: scalar or (n,), the size of y for options.tol_step. merit(y) -> ||R(y)||, used by
    the line search only. where: appended to failure reasons (e.g. " at omega=1000").
    Never raises on non-convergence: check `converged` and `reason`.
    """
    y = np.array(y0, dtype=float)
    step_norm = math.inf
    rn = math.nan
    history = []
    k = options.stall_iterations
    for it in range(options.max_iter + 1):
        try:
            out = linearise(y)
        except SingularMatrixError as exc:  # the residual itself undefined there (a pole of a condensation)
            return NewtonResult(y, False, rn, it, f"residual not defined{where}: {exc}")
        rn, step = out[0], out[1]
        if not math.isfinite(rn):
            what = out[2] if len(out) > 2 else "residual"
            return NewtonResult(y, False, rn, it, f"non-finite {what}{where}")
        step_ok = options.tol_step is None or (it > 0 and step_norm <= options.tol_step)
        if rn <= options.tol_residual and step_ok:
            return NewtonResult(y, True, rn, it, "")
        history.append(rn)
        if k is not None and stalled(history, k, options.stall_factor):
            return NewtonResult(y, False, rn, it, f"stalled{where}: ||R|| {min(history[-k:]):.3e} after {k} more "
                                                  f"iterations, not below {options.stall_factor:g} x "
                                                  f"{min(history[:-k]):.3e}")
        if it == options.max_iter:
            break
        try:
            dy = np.asarray(step(), dtype=float).reshape(y.shape)
        except NonFiniteJacobianError as exc:
            return NewtonResult(y, False, rn, it, f"non-finite Jacobian{where}: {exc}")
        except SingularMatrixError as exc:
            return NewtonResult(y, False, rn, it, f"singular Jacobian{where}: {exc}")
        if not np.all(np.isfinite(dy)):
            return NewtonResult(y, False, rn, it, f"singular Jacobian{where}: non-finite step")
        t = 1.0
        if options.line_search and merit is not None:
            for halvings in range(options.max_halvings + 1):  # t = 1, 1/2, ..., 2^-max_halvings
                if halvings:
                    t *= 0.5
                try:
                    rt = merit(y + t * dy)
                except SingularMatrixError:  # undefined there: a shorter step
                    rt = math.inf
                if math.isfinite(rt) and rt < (1.0 - 1e-4 * t) * rn:
                    break
        y = y + t * dy
        step_norm = float(np.linalg.norm(t * dy / scale))
    why = (f"||R||={rn:.3e} > {options.tol_residual:.1e}" if rn > options.tol_residual
           else f"||R||={rn:.3e} within tolerance, but the last step {step_norm:.3e} > tol_step {options.tol_step:.1e}")
    return NewtonResult(y, False, rn, options.max_iter, f"no convergence in {options.max_iter} iterations{where} ({why})")


def newton_solve(residual: Residual, x0: np.ndarray, omega: float, options: NewtonOptions = NewtonOptions(),
                 *, solver: LinearSolver | None = None, x_scale: float | np.ndarray = 1.0) -> NewtonResult:
    """Solve R(x, omega) = 0 at fixed omega by Newton's method, eq. (9).

    x0: initial iterate (n,). omega: the fixed parameter, rad/s. solver: the LinearSolver
    (default: direct LU). x_scale: scalar or (n,), the size of x for options.tol_step.
    The line search calls residual(x, omega, jacobian=False) (R alone, no Jacobian) where
    the residual takes that keyword.
    """
    solver = solver or DirectSolver()
    omega = float(omega)

    def linearise(x):
        R, J, _ = residual(x, omega)
        R = np.asarray(R, dtype=float).reshape(-1)
        return float(np.linalg.norm(R)), lambda: named_solve(J, lambda: solver.factorize(J).solve(-R))

    def merit(x):
        # the line search needs ||R|| only: skip the Jacobian where the residual can
        try:
            R = residual(x, omega, jacobian=False)
        except TypeError:  # a residual without the keyword
            R = residual(x, omega)[0]
        return float(np.linalg.norm(R))

    return newton_iterate(x0, linearise, options, scale=x_scale, merit=merit, where=f" at omega={omega:.6g}")


def newton_solve_on_plane(residual: Residual, x0: np.ndarray, omega0: float, p: np.ndarray, q: float,
                          options: NewtonOptions = NewtonOptions(), *, solver: LinearSolver | None = None,
                          where: str = "") -> NewtonResult:
    """Solve R(x, omega) = 0 on the hyperplane through the start (x0 (n,), omega0 rad/s) with
    normal (p, q): p . (x - x0) + q (omega - omega0) = 0, with the bordered solve of the
    LinearSolver (default: direct LU). p: (n,) per unit of x; q: per rad/s. The convergence
    measure is hypot(||R||, constraint). The result's x is (x, omega) stacked, (n + 1,).
    """
    solver = solver or DirectSolver()
    x0 = np.asarray(x0, dtype=float)
    n = x0.size
    p = np.asarray(p, dtype=float)

    def linearise(y):
        xi, wi = y[:n], float(y[n])
        R, J, r_w = residual(xi, wi)
        R = np.asarray(R, dtype=float).reshape(-1)
        r_w = np.asarray(r_w, dtype=float).reshape(-1)
        P = float((xi - x0) @ p + q * (wi - omega0))

        def step():
            dx, dw, _ = named_solve(J, lambda: solver.factorize(J).solve_bordered(r_w, p, q, R, P))
            return np.append(dx, dw)

        rn = float(np.hypot(np.linalg.norm(R), P))
        if math.isfinite(rn) and not np.all(np.isfinite(r_w)):
            return math.nan, step, "dR_domega"
        return rn, step

    return newton_iterate(np.append(x0, float(omega0)), linearise, options, where=where)
