"""Arc-length continuation of R(x, omega) = 0 (section 1.6 of the reference paper).

The continuation knows only a callable `residual(x, omega) -> (R, dR_dx, dR_domega)`:
R (n,), dR_dx (n, n) (dense ndarray, scipy sparse, or anything the caller's `factorize`
accepts), dR_domega (n,). Its parts, kept apart as in BifurcationKit:

- parameterisation, eq. (22): the hypersphere ||dx / x_scale||^2 + (dw / omega_scale)^2
  = ds^2 around the previous point; the scales make x and omega commensurable, ds is
  dimensionless;
- predictor, eq. (23): secant through the last two points (tangent from the Jacobians
  for the first step);
- corrector, eq. (24)-(25): Newton on the bordered system (`hbm.continuation.newton.solve_bordered`);
- step control: ds grows after fast corrections, shrinks after slow or failed ones, and
  the branch ends, with its reason, once a failure would need ds < ds_min;
- stops: omega leaving [omega_min, omega_max] (landing on the bound), max_points, and the
  closed-loop test of eq. (26)-(27).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Callable, NamedTuple

import numpy as np
import scipy.sparse as sp

from hbm.continuation.newton import (Factorize, NewtonOptions, Residual, SingularJacobian, evaluate,
                        factorize_default, newton_solve, solve_bordered)

STATUS_OMEGA_MAX = "reached omega_max"
STATUS_OMEGA_MIN = "reached omega_min"
STATUS_CLOSED_LOOP = "closed loop"
STATUS_MAX_POINTS = "max points reached"
STATUS_STEP_FLOOR = "step below floor"  # followed by ": <why the last correction failed>"
STATUS_START_FAILED = "start point did not converge"  # followed by ": <why>"


@dataclass(frozen=True)
class ContinuationOptions:
    """Settings of `continue_branch`.

    omega_min, omega_max: range of the parameter, rad/s; the branch stops on leaving it.
    ds: first arc-length step; ds_min, ds_max: its bounds (dimensionless: scaled units).
    direction: +1 to start towards increasing omega, -1 towards decreasing omega.
    max_points: most points in the branch, the start point included.
    x_scale: scalar or (n,), typical size of x (its units); omega_scale: of omega, rad/s.
    newton: convergence rule of every correction (shared with `newton_solve`).
    iter_grow: ds *= grow after a correction of at most this many iterations;
    iter_shrink: ds *= shrink after one of more than this many; failure: ds *= shrink.
    max_turn_deg: a corrected point whose secant turns more than this from the predictor
      is refused (it went back along the branch or jumped to another one) and ds shrinks.
    closed_loop_tol: d_min of eq. (27); None disables the test. The test is armed only
      once some point x_j has been farther than d_min from the start in the same metric,
      ||x_j - x_0|| / ||x_j|| > d_min: "back within d_min" presupposes having left, and
      a fold next to the start (whose sheets cross omega_0 within d_min) is no loop.
    land_on_bounds: replace the point that overshoots omega_min/omega_max by a Newton
      solution at the bound (kept as it is if that solve fails).
    predictor: "secant" (eq. 23: along the chord of the last two points) or "quadratic"
      (the parabola through the last three points, in their arc length, evaluated ds
      beyond the last: its error is O(ds^3) instead of O(ds^2), which saves about one
      Newton iteration per point on smooth parts; the secant still gives the direction
      for the max_turn_deg test, and the first steps use it).
    """

    omega_min: float
    omega_max: float
    ds: float = 1e-2
    ds_min: float = 1e-6
    ds_max: float = 1e-1
    direction: int = 1
    max_points: int = 10_000
    x_scale: float | np.ndarray = 1.0
    omega_scale: float = 1.0
    newton: NewtonOptions = field(default_factory=NewtonOptions)
    iter_grow: int = 3
    iter_shrink: int = 7
    grow: float = 1.5
    shrink: float = 0.5
    max_turn_deg: float = 90.0
    closed_loop_tol: float | None = 1e-2
    land_on_bounds: bool = True
    predictor: str = "secant"

    def __post_init__(self):
        if not self.omega_min < self.omega_max:
            raise ValueError(f"need omega_min < omega_max, got {self.omega_min}, {self.omega_max}")
        if not 0 < self.ds_min <= self.ds <= self.ds_max:
            raise ValueError(f"need 0 < ds_min <= ds <= ds_max, got {self.ds_min}, {self.ds}, {self.ds_max}")
        if self.direction not in (1, -1):
            raise ValueError(f"direction must be +1 or -1, got {self.direction}")
        if self.max_points < 1:
            raise ValueError(f"max_points must be >= 1, got {self.max_points}")
        if not (np.all(np.asarray(self.x_scale) > 0) and self.omega_scale > 0):
            raise ValueError("x_scale and omega_scale must be > 0")
        if not (self.grow >= 1.0 and 0 < self.shrink < 1.0):
            raise ValueError(f"need grow >= 1 and 0 < shrink < 1, got {self.grow}, {self.shrink}")
        if self.predictor not in ("secant", "quadratic"):
            raise ValueError(f"predictor must be 'secant' or 'quadratic', got {self.predictor!r}")
        if not 0 < self.max_turn_deg <= 180:
            raise ValueError(f"max_turn_deg must be in (0, 180], got {self.max_turn_deg}")

    def next_step(self, ds: float, iterations: int) -> float:
        """Step after a correction that converged in `iterations` with step `ds`."""
        if iterations <= self.iter_grow:
            ds *= self.grow
        elif iterations > self.iter_shrink:
            ds *= self.shrink
        return min(max(ds, self.ds_min), self.ds_max)


class ContinuationPoint(NamedTuple):
    """One point of a branch, as handed to `on_point`.

    index: position in the branch (0: start point). omega: rad/s. x: (n,).
    converged: False only for a final failed attempt (its x, omega are the last iterate).
    residual_norm: ||R||_2. iterations: Newton iterations of the accepted correction.
    step: scaled arc length from the previous point (0 for the start point).
    time: wall-clock seconds spent on this point, failed attempts included.
    """

    index: int
    omega: float
    x: np.ndarray
    converged: bool
    residual_norm: float
    iterations: int
    step: float
    time: float


@dataclass(frozen=True, eq=False)  # arrays: compare fields explicitly, not with ==
class Branch:
    """A computed branch, m points of n unknowns.

    omega (m,) rad/s; x (m, n); converged (m,) bool; residual_norm (m,); iterations (m,)
    int; step (m,) scaled arc length from the previous point; time (m,) s per point.
    status: why it stopped (one of the STATUS_* strings; the failure ones followed by
    ": details"). detail: extra information (e.g. d_int of a closed loop).
    Only the last point can be unconverged (the failure that ended the branch).
    """

    omega: np.ndarray
    x: np.ndarray
    converged: np.ndarray
    residual_norm: np.ndarray
    iterations: np.ndarray
    step: np.ndarray
    time: np.ndarray
    status: str = ""
    detail: str = ""

    def __len__(self) -> int:
        return len(self.omega)

    def point(self, i: int) -> ContinuationPoint:
        """The i-th point (negative i counts from the end)."""
        i = range(len(self))[i]
        return ContinuationPoint(i, float(self.omega[i]), self.x[i], bool(self.converged[i]),
                                 float(self.residual_norm[i]), int(self.iterations[i]),
                                 float(self.step[i]), float(self.time[i]))

    @classmethod
    def from_points(cls, points, n: int, status: str = "", detail: str = "") -> "Branch":
        """Stack ContinuationPoints (x of size n each) into a Branch."""
        pts = list(points)
        return cls(omega=np.array([p.omega for p in pts], dtype=float),
                   x=np.array([p.x for p in pts], dtype=float).reshape(len(pts), n),
                   converged=np.array([p.converged for p in pts], dtype=bool),
                   residual_norm=np.array([p.residual_norm for p in pts], dtype=float),
                   iterations=np.array([p.iterations for p in pts], dtype=np.int64),
                   step=np.array([p.step for p in pts], dtype=float),
                   time=np.array([p.time for p in pts], dtype=float),
                   status=status, detail=detail)


class _Correction(NamedTuple):
    x: np.ndarray
    omega: float
    converged: bool
    residual_norm: float
    iterations: int
    reason: str


class _Scaling(NamedTuple):
    """Maps (x, omega) to the dimensionless y = (x / x_scale, omega / omega_scale)."""

    sx: np.ndarray  # (n,)
    sw: float

    def dist(self, x1, w1, x0, w0) -> float:
        d = (x1 - x0) / self.sx
        return math.sqrt(float(d @ d) + ((w1 - w0) / self.sw) ** 2)

    def unit(self, dx, dw):
        """Scaled direction of (dx, dw), normalised: (tx (n,), tw)."""
        tx, tw = dx / self.sx, dw / self.sw
        nrm = math.sqrt(float(tx @ tx) + tw * tw)
        return tx / nrm, tw / nrm


def _correct(residual, x, w, x_prev, w_prev, ds, sc: _Scaling, nopt: NewtonOptions, fac) -> _Correction:
    """Newton on eq. (24)-(25) from the prediction (x, w), on the sphere of radius ds."""
    step_norm = math.inf
    rn = math.nan
    for it in range(nopt.max_iter + 1):
        R, J, r_w = evaluate(residual, x, w)
        rn = float(np.linalg.norm(R))
        if not (math.isfinite(rn) and np.all(np.isfinite(r_w))):
            return _Correction(x, w, False, rn, it, f"non-finite residual at omega={w:.6g}")
        step_ok = nopt.tol_step is None or (it > 0 and step_norm <= nopt.tol_step)
        if rn <= nopt.tol_residual and step_ok:
            return _Correction(x, w, True, rn, it, "")
        if it == nopt.max_iter:
            break
        dxs, dws = (x - x_prev) / sc.sx, (w - w_prev) / sc.sw
        P = float(dxs @ dxs) + dws * dws - ds * ds  # eq. (22)
        try:
            dx, dw, _ = solve_bordered(J, r_w, 2.0 * dxs / sc.sx, 2.0 * dws / sc.sw, R, P, fac)
        except SingularJacobian as exc:
            return _Correction(x, w, False, rn, it, f"singular bordered system at omega={w:.6g}: {exc}")
        x, w = x + dx, w + dw
        step_norm = math.sqrt(float(((dx / sc.sx) @ (dx / sc.sx))) + (dw / sc.sw) ** 2)
    return _Correction(x, w, False, rn, nopt.max_iter,
                       f"no convergence in {nopt.max_iter} iterations near omega={w:.6g} "
                       f"(||R||={rn:.3e} > {nopt.tol_residual:.1e})")


def _tangent(residual, x, w, direction, sc: _Scaling, fac):
    """Unit scaled tangent (tx, tw) of the branch at a solution, omega part along `direction`.

    Solves J b = dR_domega, tangent ~ (-b, 1); at a singular J (start on a fold) the null
    vector of the dense [J, dR_domega] is used instead.
    """
    _, J, r_w = evaluate(residual, x, w)
    try:
        b = np.asarray(fac(J)(r_w)).reshape(-1)
        if not np.all(np.isfinite(b)):
            raise SingularJacobian("non-finite tangent")
        tx, tw = sc.unit(-b, 1.0)
    except SingularJacobian:
        Jd = J.toarray() if sp.issparse(J) else np.asarray(J, dtype=float)
        v = np.linalg.svd(np.column_stack([Jd, r_w]))[2][-1]
        tx, tw = sc.unit(v[:-1], v[-1])
    sign = 1.0 if tw * direction > 0 or (tw == 0 and direction > 0) else -1.0
    return sign * tx, sign * tw


def continue_branch(residual: Residual, x0: np.ndarray | None, omega0: float | None, options: ContinuationOptions,
                    *, on_point: Callable[[ContinuationPoint], None] | None = None,
                    factorize: Factorize | None = None, resume=None) -> Branch:
    """Follow the solution branch of residual(x, omega) = 0 through folds, from (x0, omega0).

    x0: initial guess (n,), corrected at fixed omega0 (rad/s) by Newton first.
    options: see ContinuationOptions. on_point(point): called after each point, converged
    or the final failure, e.g. to append it to a BranchStore (an exception raised there
    stops the run; the points already handed over are complete).
    factorize(dR_dx) -> solve(b): linear solver (default: LU / SuperLU).
    resume: a Branch (or anything with its fields, e.g. `load_branch(...).branch`) whose
    points continue here: x0, omega0 are then ignored (may be None), trailing unconverged
    points are dropped, the first point stays the closed-loop reference and the next step
    length is rebuilt from the last point's step and iterations, so that a resumed run
    gives the points of an uninterrupted one. The returned Branch holds the resumed points
    followed by the new ones; on_point is called for the new ones only.
    Returns a Branch whose `status` says why it stopped; the run never raises on a
    correction that fails (only on errors of the caller's residual or on_point).
    """
    opt = options
    fac = factorize or factorize_default
    t_start = time.perf_counter()
    points: list[ContinuationPoint] = []

    def emit(x, w, conv, rn, it, step, t0):
        p = ContinuationPoint(len(points), float(w), np.array(x, dtype=float), bool(conv), float(rn), int(it),
                              float(step), time.perf_counter() - t0)
        points.append(p)
        if on_point is not None:
            on_point(p)
        return p

    def done(status, detail=""):
        return Branch.from_points(points, n, status, detail)

    if resume is not None:
        old = getattr(resume, "branch", resume)
        good = np.flatnonzero(np.asarray(old.converged, dtype=bool))
        if good.size == 0 or good[0] != 0:
            raise ValueError("resume: the branch to continue has no converged start point")
        m = good[-1] + 1
        if not np.all(np.asarray(old.converged[:m], dtype=bool)):
            raise ValueError("resume: unconverged point inside the branch")
        n = np.asarray(old.x).shape[1]
        points = [ContinuationPoint(i, float(old.omega[i]), np.array(old.x[i], dtype=float), True,
                                    float(old.residual_norm[i]), int(old.iterations[i]), float(old.step[i]),
                                    float(old.time[i])) for i in range(m)]
        if len(points) >= 2:
            ds = opt.next_step(points[-1].step, points[-1].iterations)
        else:
            ds = opt.ds
    else:
        x0 = np.array(x0, dtype=float).reshape(-1)
        n = x0.size
        if not opt.omega_min <= omega0 <= opt.omega_max:
            raise ValueError(f"omega0 = {omega0} outside [{opt.omega_min}, {opt.omega_max}]")
        sol = newton_solve(residual, x0, omega0, opt.newton, factorize=fac, x_scale=opt.x_scale)
        emit(sol.x, omega0, sol.converged, sol.residual_norm, sol.iterations, 0.0, t_start)
        if not sol.converged:
            return done(f"{STATUS_START_FAILED}: {sol.reason}")
        ds = opt.ds

    sc = _Scaling(np.broadcast_to(np.asarray(opt.x_scale, dtype=float), (n,)), float(opt.omega_scale))
    ref_x, ref_w = points[0].x, points[0].omega
    d_min = opt.closed_loop_tol

    def far(x):  # left the d_min neighbourhood of the start, metric of eq. (27)
        return d_min is not None and np.linalg.norm(x - ref_x) > d_min * np.linalg.norm(x)

    armed = any(far(p.x) for p in points)
    cos_max_turn = math.cos(math.radians(opt.max_turn_deg))

    while True:
        if len(points) >= opt.max_points:
            return done(STATUS_MAX_POINTS)
        last = points[-1]
        if len(points) >= 2:  # eq. (23)
            prev = points[-2]
            tx, tw = sc.unit(last.x - prev.x, last.omega - prev.omega)
        else:
            tx, tw = _tangent(residual, last.x, last.omega, opt.direction, sc, fac)
        quad = None
        if opt.predictor == "quadratic" and len(points) >= 3:
            p2, p1 = points[-3], points[-2]
            h1 = sc.dist(p1.x, p1.omega, p2.x, p2.omega)
            h2 = sc.dist(last.x, last.omega, p1.x, p1.omega)
            if h1 > 0 and h2 > 0:
                quad = (p2, p1, h1, h2)
        t0 = time.perf_counter()
        while True:
            if quad is None:
                xp, wp = last.x + ds * tx * sc.sx, last.omega + ds * tw * sc.sw
            else:  # Lagrange weights of the parabola at arc length s = h1 + h2 + ds (p2 at 0)
                p2, p1, h1, h2 = quad
                s0, s1, s2, s = 0.0, h1, h1 + h2, h1 + h2 + ds
                l0 = (s - s1) * (s - s2) / ((s0 - s1) * (s0 - s2))
                l1 = (s - s0) * (s - s2) / ((s1 - s0) * (s1 - s2))
                l2 = (s - s0) * (s - s1) / ((s2 - s0) * (s2 - s1))
                xp, wp = l0 * p2.x + l1 * p1.x + l2 * last.x, l0 * p2.omega + l1 * p1.omega + l2 * last.omega
            c = _correct(residual, xp, wp, last.x, last.omega, ds, sc, opt.newton, fac)
            if c.converged:
                d = sc.dist(c.x, c.omega, last.x, last.omega)
                cos = (float(((c.x - last.x) / sc.sx) @ tx) + (c.omega - last.omega) / sc.sw * tw) / max(d, 1e-300)
                if d > 0 and cos >= cos_max_turn:
                    break
                c = c._replace(converged=False,
                               reason=f"correction turned {math.degrees(math.acos(max(-1.0, min(1.0, cos)))):.0f} deg "
                                      f"from the predictor near omega={c.omega:.6g}")
            if ds * opt.shrink < opt.ds_min:
                emit(c.x, c.omega, False, c.residual_norm, c.iterations, ds, t0)
                return done(f"{STATUS_STEP_FLOOR}: {c.reason} (ds={ds:.3g}, ds_min={opt.ds_min:.3g})")
            ds *= opt.shrink

        x_new, w_new, rn, it, step = c.x, c.omega, c.residual_norm, c.iterations, ds
        bound = opt.omega_max if w_new > opt.omega_max else opt.omega_min if w_new < opt.omega_min else None
        if bound is not None:
            if opt.land_on_bounds:
                f = (bound - last.omega) / (w_new - last.omega)
                sol = newton_solve(residual, last.x + f * (x_new - last.x), bound, opt.newton, factorize=fac,
                                   x_scale=sc.sx)
                if sol.converged and sc.dist(sol.x, bound, last.x, last.omega) <= step * (1 + 1e-9) + 1e-300:
                    x_new, w_new, rn, it = sol.x, bound, sol.residual_norm, sol.iterations
                    step = sc.dist(x_new, w_new, last.x, last.omega)
            emit(x_new, w_new, True, rn, it, step, t0)
            return done(STATUS_OMEGA_MAX if bound == opt.omega_max else STATUS_OMEGA_MIN)

        emit(x_new, w_new, True, rn, it, step, t0)
        armed = armed or far(x_new)
        crossed = (last.omega < ref_w <= w_new) or (last.omega > ref_w >= w_new)
        if armed and last.index >= 1 and crossed:  # eq. (26)-(27)
            x_int = last.x + (ref_w - last.omega) / (w_new - last.omega) * (x_new - last.x)
            d_int = float(np.linalg.norm(x_int - ref_x) / max(np.linalg.norm(x_int), 1e-300))
            if d_int < d_min:
                return done(STATUS_CLOSED_LOOP, f"d_int={d_int:.3e} < {d_min:.3e} "
                                                f"between points {last.index} and {last.index + 1}")
        ds = opt.next_step(step, it)
