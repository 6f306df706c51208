"""Arc-length continuation of R(x, omega) = 0 (section 1.6 of the reference paper).

The continuation knows only a callable `residual(x, omega) -> (R, dR_dx, dR_domega)`
(R (n,), dR_dx whatever the LinearSolver accepts, dR_domega (n,)) and a LinearSolver
(hbm.linalg.protocol). Its parts, kept apart as in BifurcationKit:

- parameterisation, eq. (22): the hypersphere ||dx / x_scale||^2 + (dw / omega_scale)^2
  = ds^2 around the previous point; the scales make x and omega commensurable, ds is
  dimensionless;
- predictor, eq. (23): secant through the last two points, or the parabola through the
  last three (tangent from the Jacobians for the first step);
- corrector, eq. (24)-(25): the Newton loop of hbm.continuation.newton on (x, omega), each
  step the solver's bordered solve;
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

from hbm.continuation.branch import (STATUS_CLOSED_LOOP, STATUS_CRAWL, STATUS_MAX_POINTS, STATUS_OMEGA_MAX,
                                     STATUS_OMEGA_MIN, STATUS_START_FAILED, STATUS_STEP_FLOOR, Branch,
                                     ContinuationPoint)
from hbm.continuation.newton import (NewtonOptions, NewtonResult, Residual, named_solve, newton_iterate, newton_solve,
                                     nonfinite_jacobian)
from hbm.linalg.dense import DirectSolver
from hbm.linalg.errors import SingularMatrixError
from hbm.linalg.protocol import LinearSolver
from hbm.options import check_flag, check_option


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
    max_turn_deg: a corrected point whose secant turns more than this from the previous
      secant is refused and ds shrinks: a large turn at a large step is how a corrector
      lands on another stretch of the branch (through a cluster of close folds) or goes
      back along it. At the step floor ds_min a turn up to 90 deg is accepted (a genuinely
      sharp corner of the branch, e.g. at a contact onset with the stiff penalty law, turns
      by tens of degrees even at ds ~ 1e-5, where no other stretch is that close); a turn
      beyond 90 deg there ends the branch.
    corner_turns: with it set, a turn up to 90 deg is also accepted above the floor when the
      last corner_turns corrections refused at this point, each at twice the step of the
      next, turned within corner_tol_deg of it: a turn that does not shrink with the step
      is a corner of the branch (DLFT's non-smooth law makes them: 52, 50, 50 deg at ds =
      0.057, 0.029, 0.014 on a period-doubled branch of rotor 67 at 719.9 rad/s), whereas
      a landing on another stretch turns less as the step shrinks. None (the default):
      corners only at the floor. Halving down to the floor, a corrector that takes the
      prediction itself (0 iterations, its residual below tolerance at ds ~ 1e-5) keeps
      the old direction past the corner, and the branch crawls there at the floor.
    turn_shrink_deg: a point whose secant turns more than this is kept but the next step
      shrinks instead of growing: the branch curves too much for the current step.
    rejoin_check: refuse a correction that lands back on the branch's own earlier path
      (the same solution, to rejoin_tol times the step, travelled the other way: in a
      cluster of close folds stretches run parallel a fraction of a step apart, and a
      corrector that lands on an earlier one turns by only a few degrees yet retraces the
      branch). The same landing in the old direction of travel, persisting down to ds_min,
      is a loop closing away from the start: the branch ends as a closed loop (unless
      closed_loop_tol is None: then it goes round again). The two sheets of a fold are never
      taken for each other: at the same omega they lie about twice the arc length from the
      fold's tip apart, and a step away from the tip that is far more than rejoin_tol ds.
    closed_loop_tol: d_min of eq. (27), relative to |x| (1e-3, what the NFRC and the isola
      search run with); None disables the test. The test is armed only
      once some point x_j has been farther than d_min from the start in the same metric,
      ||x_j - x_0|| / ||x_j|| > d_min: "back within d_min" presupposes having left, and
      a fold next to the start (whose sheets cross omega_0 within d_min) is no loop. The
      crossing step must also head the way the first step left the start (scaled
      directions less than 90 deg apart): a return through the start comes in along the
      branch's start tangent, while a crossing at another angle (a figure-eight drawn along
      another unknown, another stretch passing by the start) is a near-miss, not a loop.
    land_on_bounds: replace the point that overshoots omega_min/omega_max by a Newton
      solution at the bound (kept as it is if that solve fails).
    predictor: "secant" (eq. 23: along the chord of the last two points) or "quadratic"
      (the parabola through the last three points, in their arc length, evaluated ds
      beyond the last: its error is O(ds^3) instead of O(ds^2), which saves about one
      Newton iteration per point on smooth parts; the secant still gives the direction
      for the max_turn_deg test, and the first steps use it).
    iter_reject: refuse a correction that converged in more than this many iterations and
      shrink ds, except at the step floor (None: never). A slow correction at a large step
      is the other way a corrector lands on another sheet, with a turn under max_turn_deg
      (the NFRC's default_continuation says where it happened).
    crawl_points: end the branch (STATUS_CRAWL) after this many successive points taken
      with a step below crawl_ratio ds_min; None (the default): never. A branch that
      creeps along at the floor for long costs many corrections for little arc length
      (searches over many branches, hbm.isolas, cap it).
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
    max_turn_deg: float = 45.0
    turn_shrink_deg: float = 30.0
    corner_turns: int | None = None
    corner_tol_deg: float = 2.0
    rejoin_check: bool = True
    rejoin_tol: float = 1e-3
    iter_reject: int | None = None
    closed_loop_tol: float | None = 1e-3
    land_on_bounds: bool = True
    predictor: str = "secant"
    crawl_points: int | None = None
    crawl_ratio: float = 4.0

    def __post_init__(self):
        if not self.omega_min < self.omega_max:
            raise ValueError(f"need omega_min < omega_max, got {self.omega_min}, {self.omega_max}")
        for k in ("ds_min", "ds", "ds_max"):
            check_option(k, getattr(self, k), 0, low_open=True)
        if not 0 < self.ds_min <= self.ds <= self.ds_max:
            raise ValueError(f"need 0 < ds_min <= ds <= ds_max, got {self.ds_min}, {self.ds}, {self.ds_max}")
        if self.direction not in (1, -1):
            raise ValueError(f"direction must be +1 or -1, got {self.direction}")
        check_option("max_points", self.max_points, 1, integer=True)
        x_scale = np.asarray(self.x_scale)
        if not (x_scale.dtype.kind in "iuf" and np.all(np.isfinite(x_scale)) and np.all(x_scale > 0)):
            raise ValueError(f"x_scale must be finite and > 0 (scalar or (n,)), got {self.x_scale}")
        check_option("omega_scale", self.omega_scale, 0, low_open=True, unit="rad/s")
        check_option("iter_grow", self.iter_grow, 0, integer=True)
        check_option("iter_shrink", self.iter_shrink, 0, integer=True)
        check_option("grow", self.grow, 1)
        check_option("shrink", self.shrink, 0, 1, low_open=True, high_open=True)
        if self.iter_reject is not None:
            check_option("iter_reject", self.iter_reject, 1, integer=True, note="or None")
        check_flag("rejoin_check", self.rejoin_check)
        check_option("rejoin_tol", self.rejoin_tol, 0, low_open=True)
        if self.closed_loop_tol is not None:
            check_option("closed_loop_tol", self.closed_loop_tol, 0, low_open=True, note="or None")
        check_flag("land_on_bounds", self.land_on_bounds)
        # a step is never below ds_min, so a ratio of 1 or less would never see a crawl
        check_option("crawl_ratio", self.crawl_ratio, 1, low_open=True)
        if self.predictor not in ("secant", "quadratic"):
            raise ValueError(f"predictor must be 'secant' or 'quadratic', got {self.predictor!r}")
        if not 0 < self.max_turn_deg <= 180:
            raise ValueError(f"max_turn_deg must be in (0, 180], got {self.max_turn_deg}")
        if not 0 < self.turn_shrink_deg <= 180:
            raise ValueError(f"turn_shrink_deg must be in (0, 180], got {self.turn_shrink_deg}")
        if self.crawl_points is not None:
            check_option("crawl_points", self.crawl_points, 1, integer=True, note="or None")
        if self.corner_turns is not None:
            check_option("corner_turns", self.corner_turns, 1, integer=True, note="or None")
        check_option("corner_tol_deg", self.corner_tol_deg, 0, low_open=True)

    def next_step(self, ds: float, iterations: int, turn_deg: float = 0.0) -> float:
        """Step after a correction that converged in `iterations` with step `ds` and turned
        the secant by `turn_deg`."""
        if iterations > self.iter_shrink or turn_deg > self.turn_shrink_deg:
            ds *= self.shrink
        elif iterations <= self.iter_grow:
            ds *= self.grow
        return min(max(ds, self.ds_min), self.ds_max)


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


def _correct(residual, x, w, x_prev, w_prev, ds, sc: _Scaling, nopt: NewtonOptions,
             solver: LinearSolver) -> NewtonResult:
    """Newton on eq. (24)-(25) from the prediction (x, w), on the sphere of radius ds around
    (x_prev, w_prev). The result's x is (x, omega) stacked, (n + 1,)."""
    n = x.size
    scale = np.append(sc.sx, sc.sw)

    def linearise(y):
        xi, wi = y[:n], float(y[n])
        R, J, r_w = residual(xi, wi)
        R = np.asarray(R, dtype=float).reshape(-1)
        r_w = np.asarray(r_w, dtype=float).reshape(-1)
        rn = float(np.linalg.norm(R))
        dxs, dws = (xi - x_prev) / sc.sx, (wi - w_prev) / sc.sw
        P = float(dxs @ dxs) + dws * dws - ds * ds  # eq. (22)

        def step():
            dx, dw, _ = named_solve(J, lambda: solver.factorize(J).solve_bordered(r_w, 2.0 * dxs / sc.sx,
                                                                                   2.0 * dws / sc.sw, R, P))
            return np.append(dx, dw)

        if math.isfinite(rn) and not np.all(np.isfinite(r_w)):
            return math.nan, step, "dR_domega"
        return rn, step

    return newton_iterate(np.append(x, w), linearise, nopt, scale=scale, where=f" near omega={w:.6g}")


def _tangent(residual, x, w, direction, sc: _Scaling, solver: LinearSolver):
    """Unit scaled tangent (tx, tw) of the branch at a solution, omega part along `direction`.

    Solves J b = dR_domega, tangent ~ (-b, 1); at a singular J (start on a fold) the null
    vector of the dense [J, dR_domega] is used instead.
    """
    _, J, r_w = residual(x, w)
    r_w = np.asarray(r_w, dtype=float).reshape(-1)
    if not np.all(np.isfinite(r_w)):
        raise ValueError(f"the residual's dR_domega has NaN or inf entries at the solution omega={w:.6g} "
                         f"(needed for the tangent)")
    try:
        b = np.asarray(solver.factorize(J).solve(r_w)).reshape(-1)
        if not np.all(np.isfinite(b)):
            raise SingularMatrixError("non-finite tangent")
        tx, tw = sc.unit(-b, 1.0)
    except SingularMatrixError:
        if nonfinite_jacobian(J):
            raise ValueError(f"the residual's dR_dx has NaN or inf entries at the solution omega={w:.6g} "
                             f"(needed for the tangent)") from None
        Jd = J.toarray() if hasattr(J, "toarray") else np.asarray(J, dtype=float)
        v = np.linalg.svd(np.column_stack([Jd, r_w]))[2][-1]
        tx, tw = sc.unit(v[:-1], v[-1])
    sign = 1.0 if tw * direction > 0 or (tw == 0 and direction > 0) else -1.0
    return sign * tx, sign * tw


def _resumed_points(resume) -> list[ContinuationPoint]:
    """The converged points of an interrupted branch (trailing failures dropped)."""
    old = getattr(resume, "branch", resume)
    good = np.flatnonzero(np.asarray(old.converged, dtype=bool))
    if good.size == 0 or good[0] != 0:
        raise ValueError("resume: the branch to continue has no converged start point")
    m = good[-1] + 1
    if not np.all(np.asarray(old.converged[:m], dtype=bool)):
        raise ValueError("resume: unconverged point inside the branch")
    return [ContinuationPoint(i, float(old.omega[i]), np.array(old.x[i], dtype=float), True,
                              float(old.residual_norm[i]), int(old.iterations[i]), float(old.step[i]),
                              float(old.time[i])) for i in range(m)]


class _Trail:
    """The branch's points as arrays, grown in place, for the rejoin test: x (m, n), omega
    (m,), cumulative scaled arc length s (m,)."""

    def __init__(self, n: int):
        self.x, self.w, self.s, self.m = np.empty((64, n)), np.empty(64), np.empty(64), 0

    def add(self, p: ContinuationPoint) -> None:
        if self.m == len(self.w):
            self.x = np.concatenate([self.x, np.empty_like(self.x)])
            self.w, self.s = np.concatenate([self.w, np.empty_like(self.w)]), np.concatenate([self.s, np.empty_like(self.s)])
        self.x[self.m], self.w[self.m] = p.x, p.omega
        self.s[self.m] = (self.s[self.m - 1] + p.step) if self.m else 0.0
        self.m += 1


def _rejoined(trail: _Trail, x, w, tx, tw, ds: float, sc: _Scaling, residual, opt: "ContinuationOptions", solver):
    """Whether the corrected point (x, w), reached by a step ds moving along the unit scaled
    direction (tx, tw), is a point of the branch's earlier path: returns (segment index, cos
    of the angle between the directions of travel now and then), or None.

    Segments of the earlier path that bracket w are tried, nearest first: Newton at w from
    the segment's interpolation; a solution within rejoin_tol * ds of (x, w) (scaled) is the
    same point, and the path is rejoined. The last 3 ds of arc length are not looked at: the
    other sheet of a fold just passed lies within 2 ds of arc behind the new point.
    """
    m = int(np.searchsorted(trail.s[:trail.m], trail.s[trail.m - 1] - 3.0 * ds, side="right"))
    if m < 2:
        return None
    W = trail.w[:m]
    lo, hi = np.minimum(W[:-1], W[1:]), np.maximum(W[:-1], W[1:])
    cand = np.flatnonzero((lo <= w) & (w <= hi) & (hi > lo))
    if not cand.size:
        return None
    f = (w - W[cand]) / (W[cand + 1] - W[cand])
    X = trail.x[cand] + f[:, None] * (trail.x[cand + 1] - trail.x[cand])
    d = np.linalg.norm((X - x) / sc.sx, axis=1)
    chord = np.sqrt(np.sum(((trail.x[cand + 1] - trail.x[cand]) / sc.sx) ** 2, axis=1)
                    + ((W[cand + 1] - W[cand]) / sc.sw) ** 2)
    for k in np.argsort(d)[:3]:
        if d[k] > 0.5 * max(chord[k], ds):  # not even near that chord (its sag is below half of it)
            break
        sol = newton_solve(residual, X[k], w, opt.newton, solver=solver, x_scale=sc.sx)
        if sol.converged and np.linalg.norm((sol.x - x) / sc.sx) <= opt.rejoin_tol * ds:
            i = int(cand[k])
            ox, ow = sc.unit(trail.x[i + 1] - trail.x[i], trail.w[i + 1] - trail.w[i])
            return i, float(ox @ tx + ow * tw)
    return None


def _turn(points, sc: _Scaling, start_tangent=None) -> float:
    """Angle between the last two secants of a branch, deg; with two points, between the
    start's unit tangent (tx, tw), the direction the first step was taken in, and the
    secant (0 with fewer points, or two and no tangent)."""
    if len(points) < 2 or len(points) == 2 and start_tangent is None:
        return 0.0
    p1, p0 = points[-2], points[-1]
    if len(points) == 2:
        a = np.append(*start_tangent)
    else:
        p2 = points[-3]
        a = np.append(*sc.unit(p1.x - p2.x, p1.omega - p2.omega))
    b = np.append(*sc.unit(p0.x - p1.x, p0.omega - p1.omega))
    return math.degrees(math.acos(max(-1.0, min(1.0, float(a @ b)))))


def _prediction(points, ds, tx, tw, sc: _Scaling, quadratic: bool):
    """Predicted (x, omega) ds beyond the last point: along the unit secant (tx, tw), or on
    the parabola through the last three points in their arc length (Lagrange weights)."""
    last = points[-1]
    if quadratic and len(points) >= 3:
        p2, p1 = points[-3], points[-2]
        h1 = sc.dist(p1.x, p1.omega, p2.x, p2.omega)
        h2 = sc.dist(last.x, last.omega, p1.x, p1.omega)
        if h1 > 0 and h2 > 0:
            s0, s1, s2, s = 0.0, h1, h1 + h2, h1 + h2 + ds
            l0 = (s - s1) * (s - s2) / ((s0 - s1) * (s0 - s2))
            l1 = (s - s0) * (s - s2) / ((s1 - s0) * (s1 - s2))
            l2 = (s - s0) * (s - s1) / ((s2 - s0) * (s2 - s1))
            return l0 * p2.x + l1 * p1.x + l2 * last.x, l0 * p2.omega + l1 * p1.omega + l2 * last.omega
    return last.x + ds * tx * sc.sx, last.omega + ds * tw * sc.sw


def continue_branch(residual: Residual, x0: np.ndarray | None, omega0: float | None, options: ContinuationOptions,
                    *, on_point: Callable[[ContinuationPoint], None] | None = None,
                    solver: LinearSolver | None = None, resume=None,
                    admit: Callable[[ContinuationPoint, np.ndarray, float], str | None] | None = None) -> Branch:
    """Follow the solution branch of residual(x, omega) = 0 through folds, from (x0, omega0).

    x0: initial guess (n,), corrected at fixed omega0 (rad/s) by Newton first.
    options: see ContinuationOptions. on_point(point): called after each point, converged
    or the final failure, e.g. to append it to a store (an exception raised there stops
    the run; the points already handed over are complete).
    solver: the LinearSolver (hbm.linalg.protocol) for dR_dx; default: direct LU.
    resume: a Branch (or anything with its fields) whose points continue here: x0, omega0
    are then ignored (may be None), trailing unconverged points are dropped, the first
    point stays the closed-loop reference and the next step length is rebuilt from the
    last point's step and iterations, so that a resumed run gives the points of an
    uninterrupted one. The returned Branch holds the resumed points followed by the new
    ones; on_point is called for the new ones only.
    admit(last, x, omega): the caller's own test of a converged correction from the point
    `last` to (x (n,), omega rad/s), after the turn test: a reason (str) refuses it and
    the step shrinks, as for a turn; None admits it. At the step floor every correction is
    admitted: what the caller refuses there is a genuine feature of the branch (the isola
    search refuses a landing on symmetric orbits from broken ones, hbm.isolas.search).
    Returns a Branch whose `status` says why it stopped; the run never raises on a
    correction that fails (only on errors of the caller's residual or on_point).
    """
    opt = options
    solver = solver or DirectSolver()
    t_start = time.perf_counter()
    points: list[ContinuationPoint] = []

    def emit(x, w, conv, rn, it, step, t0):
        p = ContinuationPoint(len(points), float(w), np.array(x, dtype=float), bool(conv), float(rn), int(it),
                              float(step), time.perf_counter() - t0)
        points.append(p)
        if on_point is not None:
            on_point(p)
        return p

    if resume is not None:
        points = _resumed_points(resume)
        n = points[0].x.size
        ds = None  # rebuilt below from the last points, as the uninterrupted run set it
    else:
        x0 = np.array(x0, dtype=float).reshape(-1)
        n = x0.size
        if not opt.omega_min <= omega0 <= opt.omega_max:
            raise ValueError(f"omega0 = {omega0} outside [{opt.omega_min}, {opt.omega_max}]")
        sol = newton_solve(residual, x0, omega0, opt.newton, solver=solver, x_scale=opt.x_scale)
        emit(sol.x, omega0, sol.converged, sol.residual_norm, sol.iterations, 0.0, t_start)
        if not sol.converged:
            return Branch.from_points(points, n, f"{STATUS_START_FAILED}: {sol.reason}")
        ds = opt.ds

    def done(status, detail=""):
        return Branch.from_points(points, n, status, detail)

    sc = _Scaling(np.broadcast_to(np.asarray(opt.x_scale, dtype=float), (n,)), float(opt.omega_scale))
    if ds is None:  # resumed: the step the uninterrupted run took after its last point
        ds = opt.ds
        if len(points) >= 2:  # point 1 turned from the start's tangent, later ones from a secant
            start = _tangent(residual, points[0].x, points[0].omega, opt.direction, sc, solver) \
                if len(points) == 2 else None
            ds = opt.next_step(points[-1].step, points[-1].iterations, _turn(points, sc, start))
    ref_x, ref_w = points[0].x, points[0].omega
    d_min = opt.closed_loop_tol

    def far(x):  # left the d_min neighbourhood of the start, metric of eq. (27)
        return d_min is not None and np.linalg.norm(x - ref_x) > d_min * np.linalg.norm(x)

    def closes(last, x_new, w_new):  # eq. (26)-(27): the step from last to (x_new, w_new) crosses omega_0 within d_min
        # and heads the way the first step left the start
        if not ((armed or far(x_new)) and last.index >= 1
                and ((last.omega < ref_w <= w_new) or (last.omega > ref_w >= w_new))):
            return None
        x_int = last.x + (ref_w - last.omega) / (w_new - last.omega) * (x_new - last.x)
        d_int = float(np.linalg.norm(x_int - ref_x) / max(np.linalg.norm(x_int), 1e-300))
        if not d_int < d_min:
            return None
        first = np.append(*sc.unit(points[1].x - ref_x, points[1].omega - ref_w))
        now = np.append(*sc.unit(x_new - last.x, w_new - last.omega))
        return d_int if float(first @ now) > 0.0 else None

    armed = any(far(p.x) for p in points)
    crawl = 0  # successive points taken at a step below crawl_ratio ds_min (a resumed run's last ones)
    for p in reversed(points[1:]):
        if not p.step < opt.crawl_ratio * opt.ds_min:
            break
        crawl += 1
    trail = _Trail(n)
    for p in points:
        trail.add(p)

    while True:
        if len(points) >= opt.max_points:
            return done(STATUS_MAX_POINTS)
        last = points[-1]
        if len(points) >= 2:  # eq. (23)
            prev = points[-2]
            tx, tw = sc.unit(last.x - prev.x, last.omega - prev.omega)
        else:
            tx, tw = _tangent(residual, last.x, last.omega, opt.direction, sc, solver)
        t0 = time.perf_counter()
        turns = []  # turns of the corrections refused for their turn at this point, degrees
        while True:
            xp, wp = _prediction(points, ds, tx, tw, sc, opt.predictor == "quadratic")
            c = _correct(residual, xp, wp, last.x, last.omega, ds, sc, opt.newton, solver)
            cx, cw = c.x[:n], float(c.x[n])
            floor = ds * opt.shrink < opt.ds_min
            turned = False  # refused for its turn alone
            if c.converged and not floor and opt.iter_reject is not None and c.iterations > opt.iter_reject:
                c = c._replace(converged=False, reason=f"correction took {c.iterations} iterations (more than "
                                                       f"{opt.iter_reject}) near omega={cw:.6g}")
            elif c.converged:
                d = sc.dist(cx, cw, last.x, last.omega)
                cos = (float(((cx - last.x) / sc.sx) @ tx) + (cw - last.omega) / sc.sw * tw) / max(d, 1e-300)
                turn = math.degrees(math.acos(max(-1.0, min(1.0, cos))))
                rejoin = None
                k = opt.corner_turns
                corner = (k is not None and len(turns) >= k
                          and max(abs(t - turn) for t in turns[-k:]) <= opt.corner_tol_deg)
                turn_ok = d > 0 and (turn <= opt.max_turn_deg or ((floor or corner) and turn <= 90.0))
                refused = admit(last, cx, cw) if turn_ok and admit is not None and not floor else None
                if refused is not None:
                    c = c._replace(converged=False, reason=f"{refused} near omega={cw:.6g}")
                elif turn_ok:
                    # A loop coming back to its start lands on its own first segment: the
                    # crossing test closes it there, before the rejoin test would refuse it.
                    if not opt.rejoin_check or closes(last, cx, cw) is not None:
                        break
                    rejoin = _rejoined(trail, cx, cw, *sc.unit(cx - last.x, cw - last.omega), ds, sc, residual,
                                       opt, solver)
                    if rejoin is None or (rejoin[1] > 0 and d_min is None):  # going round again: allowed
                        break
                    if rejoin[1] > 0 and floor:  # the loop closes on itself, away from its start
                        emit(cx, cw, True, c.residual_norm, c.iterations, ds, t0)
                        return done(STATUS_CLOSED_LOOP, f"rejoined its own path between points {rejoin[0]} "
                                                        f"and {rejoin[0] + 1}")
                    why = "backwards" if rejoin[1] <= 0 else "forwards"
                    c = c._replace(converged=False, reason=f"correction landed {why} on the branch's own path "
                                                           f"(points {rejoin[0]}-{rejoin[0] + 1}) near omega={cw:.6g}")
                else:
                    turned = True
                    turns.append(turn)
                    c = c._replace(converged=False, reason=f"correction turned {turn:.0f} deg from the previous "
                                                           f"secant near omega={cw:.6g}")
            if not turned:
                turns.clear()  # a corner is told by refusals at successive halvings only
            if floor:
                emit(cx, cw, False, c.residual_norm, c.iterations, ds, t0)
                return done(f"{STATUS_STEP_FLOOR}: {c.reason} (ds={ds:.3g}, ds_min={opt.ds_min:.3g})")
            ds *= opt.shrink

        x_new, w_new, rn, it, step = cx, cw, c.residual_norm, c.iterations, ds
        bound = opt.omega_max if w_new > opt.omega_max else opt.omega_min if w_new < opt.omega_min else None
        if bound is not None:
            if last.omega == bound:  # started on the bound, heading out of the range: nothing to add
                return done(STATUS_OMEGA_MAX if bound == opt.omega_max else STATUS_OMEGA_MIN)
            if opt.land_on_bounds:
                # From the chord's interpolation first; near a fold beyond the bound (the
                # corrected point in the fold's cap) that guess can lead Newton to the far
                # sheet, more than a step away: then from the last point, on its own sheet.
                f = (bound - last.omega) / (w_new - last.omega)
                for guess in (last.x + f * (x_new - last.x), last.x):
                    sol = newton_solve(residual, guess, bound, opt.newton, solver=solver, x_scale=sc.sx)
                    if sol.converged and sc.dist(sol.x, bound, last.x, last.omega) <= step * (1 + 1e-9) + 1e-300:
                        x_new, w_new, rn, it = sol.x, bound, sol.residual_norm, sol.iterations
                        step = sc.dist(x_new, w_new, last.x, last.omega)
                        break
            emit(x_new, w_new, True, rn, it, step, t0)
            return done(STATUS_OMEGA_MAX if bound == opt.omega_max else STATUS_OMEGA_MIN)

        trail.add(emit(x_new, w_new, True, rn, it, step, t0))
        crawl = crawl + 1 if step < opt.crawl_ratio * opt.ds_min else 0
        d_int = closes(last, x_new, w_new)
        armed = armed or far(x_new)
        if d_int is not None:
            return done(STATUS_CLOSED_LOOP, f"d_int={d_int:.3e} < {d_min:.3e} "
                                            f"between points {last.index} and {last.index + 1}")
        if opt.crawl_points is not None and crawl >= opt.crawl_points:
            return done(f"{STATUS_CRAWL}: {crawl} successive points with ds < {opt.crawl_ratio:g} ds_min "
                        f"near omega={w_new:.6g}")
        ds = opt.next_step(step, it, turn)
