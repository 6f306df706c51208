"""Nonlinear frequency response curve of the rotor blade against the ovalised casing.

`compute_nfrc` follows the omega = Omega branch over [omega_min, omega_max] with the
arc-length continuation of hbm.continuation.arclength, from a start point at the end of the
range that `HbmOptions.start` names (see hbm.harmonic.start), for one contact treatment
(DLFT or RL), and returns every point with the
leading-edge (LE) radial amplitude of Fig. 6: half the peak-to-peak LE radial
displacement, (max - min) / 2, the convention of the time-integration side.
"""
from __future__ import annotations

import time
from contextlib import nullcontext
from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np
from threadpoolctl import threadpool_limits

from hbm.continuation.arclength import ContinuationOptions, continue_branch
from hbm.continuation.branch import ContinuationPoint
from hbm.continuation.newton import NewtonOptions
from hbm.harmonic.condensation import HarmonicForcing
from hbm.harmonic.residual import HarmonicBalanceResidual, build_residual
from hbm.harmonic.solver import HbmSolver
from hbm.harmonic.start import damped_newton, pad_harmonics, solve_start
from hbm.linalg.protocol import LinearSolver
from hbm.options import CasingOptions, ContactOptions, HbmOptions
from hbm.stability.monitor import PER_POINT, StabilityMonitor, StabilityOptions, unknown_stability


@dataclass(frozen=True)
class NfrcPoint:
    """One point handed to on_point.

    index; omega: Omega = omega, rad/s; harmonics: condensed boundary-dof harmonics,
    (2 N_h + 1, 3 n_b), m, eq. (5) order; le_amplitude: half the peak-to-peak LE radial
    displacement (max - min) / 2 over the period, m; le_max: max over the period of the LE
    radial displacement, m; residual_norm (scaled residual, 1); iterations; step (scaled
    arc length); time, s; converged; reason ("" when converged).
    """

    index: int
    omega: float
    harmonics: np.ndarray
    le_amplitude: float
    le_max: float
    residual_norm: float
    iterations: int
    step: float
    time: float
    converged: bool
    reason: str


@dataclass(frozen=True)
class NfrcResult:
    """A computed NFRC, m points.

    method: "dlft" or "rl". omega (m,), rad/s. harmonics (m, 2 N_h + 1, 3 n_b), m.
    le_amplitude (m,), m: half the peak-to-peak LE radial displacement, (max - min) / 2
    (the y-axis of Fig. 6, as the time integration reports it).
    le_max (m,), m. residual_norm, iterations, step, time (s), converged (m,).
    reason (m,) str: "" for converged points, why for the last failed one.
    status: why the branch stopped (hbm.continuation.arclength STATUS_*). wall_time, s.
    n_factorizations: LU factorisations of the Jacobian. unknowns: x of every point in
    the residual's scaled unknowns (m, n_u), to restart or expand (residual.expand_harmonics).
    start: how the start point was found (solve_start's note; "resumed" for a resume), or
      why it was not, at either end of the range.
    With stability (see compute_nfrc; None otherwise): stable (m,) bool; n_unstable (m,)
    int, Floquet multipliers of the minimal period outside the unit circle (-1: unknown,
    the failed last point); stability_note (m,) object array of str, why n_unstable is -1
    ("" where it is not; hbm.stability.monitor); stability_analysed (m,) bool, computed there (else inferred
    from the analysed neighbours, hbm.stability.monitor); leading_multipliers (m, k), the
    k largest |multipliers| (nan where not analysed). bifurcations: the located
    hbm.stability.bifurcation.Bifurcation, in branch order (after a resume: with the
    resume_bifurcations given). n_stability_analyses: Floquet analyses made; stability_time: their wall time, s.
    """

    method: str
    omega: np.ndarray
    harmonics: np.ndarray
    le_amplitude: np.ndarray
    le_max: np.ndarray
    residual_norm: np.ndarray
    iterations: np.ndarray
    step: np.ndarray
    time: np.ndarray
    converged: np.ndarray
    reason: np.ndarray
    status: str
    wall_time: float
    n_factorizations: int
    unknowns: np.ndarray = field(repr=False)
    start: str = ""
    stable: np.ndarray | None = None
    n_unstable: np.ndarray | None = None
    stability_note: np.ndarray | None = None
    stability_analysed: np.ndarray | None = None
    leading_multipliers: np.ndarray | None = None
    bifurcations: tuple = ()
    n_stability_analyses: int = 0
    stability_time: float = 0.0


def _in_branch_order(bifurcations) -> tuple:
    return tuple(sorted(bifurcations, key=lambda b: (b.index, b.fraction)))


def default_continuation(hbm: HbmOptions) -> ContinuationOptions:
    """Continuation settings used by compute_nfrc, from the scene's [hbm] keys (range, start,
    max_points, ds_max, tolerance).

    u is already ~1: x_scale = 1; omega_scale = 100 rad/s: a unit arc length is 100 rad/s
    on a flat branch. predictor = "quadratic": at N_h = 40 on the coarse rotor 67 ROM, RL
    956 -> 865 points, DLFT 513 -> 504 against the secant, same peaks to 0.05 %
    (iter_grow = 4 on top sent RL back up from 400 rad/s on another sheet). ds_min = 1e-5:
    the sharpest turns of the rotor 67 branches pass at ds ~ 1e-4. iter_reject = 8 (a
    corrector iteration cap, as AUTO's and MATCONT's, above which the step is halved; the
    Newton itself may take 12 at the step floor): on the default rotor 67 scene without it
    RL left its NFRC at 968 rad/s by a 9-iteration correction at ds_max onto a nearby
    sheet and ended there at the step floor (1218 points), and DLFT ended at 402 rad/s;
    with it both reach 400 rad/s (RL 1932, DLFT 1365 points; the coarse ROM's NFRCs keep
    their peaks, RL 1017 -> 985 points, DLFT 641 -> 640). A cap makes such a jump less
    likely, it cannot exclude it: a nearby sheet can also be reached in few iterations.
    corner_turns = 2 (ContinuationOptions): a corner passed above the step floor, as the
    isola search passes them. With corners only at the floor, RL on the coarse rotor 37
    ROM (its scene then at N_t = 1024) ended at 635.6 rad/s instead of 450: a step of ds_max
    cut across a bend of the branch (a node's contact splitting into more intervals),
    every correction from the new point turned 48-62 deg from that chord whatever the step
    (2.5 down to 0.005), the branch crawled at the floor and ended there on a 97 deg turn;
    with the rule it goes on at ds = 0.078. The coarse rotor 67 NFRCs keep their points and
    peaks but RL's corners (985 -> 972 points, peak within 0.03 %).
    """
    return ContinuationOptions(omega_min=hbm.omega_min, omega_max=hbm.omega_max, ds=0.05, ds_min=1e-5,
                               ds_max=hbm.ds_max, direction=-1 if hbm.start == "omega_max" else 1,
                               max_points=hbm.max_points, x_scale=1.0, omega_scale=100.0,
                               newton=NewtonOptions(tol_residual=hbm.tolerance, max_iter=12), iter_grow=3,
                               iter_shrink=6, iter_reject=8, predictor="quadratic", corner_turns=2)


def nfrc_extras(res: HarmonicBalanceResidual, u: np.ndarray) -> dict:
    """Per-point NFRC data for a store, from the unknowns u (n_u,) of a point.

    le_amplitude: (max - min) / 2 of the LE (node 0) radial displacement on the AFT grid, m.
    le_max: its max, m. harmonics: condensed harmonics, (2 N_h + 1, 3 n_b), m.
    """
    xr = res.to_coefficients(u)
    r = res.basis.to_time(xr[:, 0])
    return {"le_amplitude": float(0.5 * (r.max() - r.min())), "le_max": float(r.max()), "harmonics": xr}


def compute_nfrc(rom, casing: CasingOptions = CasingOptions(), contact: ContactOptions = ContactOptions(),
                 hbm: HbmOptions = HbmOptions(), method: str = "dlft", *,
                 on_point: Callable[[ContinuationPoint, dict], None] | None = None,
                 continuation: ContinuationOptions | None = None, forcing: HarmonicForcing | None = None,
                 residual: HarmonicBalanceResidual | None = None, solver: LinearSolver | None = None,
                 resume=None, guess: tuple[float, np.ndarray] | None = None,
                 stability: bool | StabilityOptions | None = None,
                 resume_bifurcations: tuple = (),
                 on_bifurcations: Callable[[tuple], None] | None = None) -> NfrcResult:
    """NFRC over Omega in [hbm.omega_min, hbm.omega_max] for one method.

    rom: RomModel (node 0 = LE). casing, contact, hbm: scene options. method: "dlft" | "rl".
    on_point(point, extras): called after each new point, converged or the final failure:
      point is the hbm.continuation.ContinuationPoint (x = the scaled unknowns u), extras
      = nfrc_extras(...) (le_amplitude, le_max, harmonics); exactly what
      BranchStore.append(point, extras) takes. The final failed point is handed over
      once the branch has ended (its reason is the result's status).
    continuation: overrides default_continuation(hbm) (omega range taken from it).
    residual: a prepared HarmonicBalanceResidual (default: built from the options).
    solver: the LinearSolver (default: HbmSolver, GMRES on the structured Jacobian, with
      atol = tol_residual / 10; hbm.linalg.dense.DirectSolver factorises the dense form).
    resume: a StoredBranch (load_branch(..., allow_partial=True)) or Branch of an
      interrupted run of the same inputs: its converged points are kept and the branch goes
      on from them (no start solve); on_point sees the new points only; the result holds
      all of them and follows the branch of an uninterrupted run (the same points where
      the linear solves are direct; with GMRES and a reused preconditioner, which is not
      stored, the step sequence can differ at the solver's tolerance: the same curve,
      sampled at other arc lengths).
    Start (without resume): see solve_start, at the end of the range that the direction
      names; if no start converges there, at the other end with the direction reversed
      (the RL law at kappa = 1e9 has no solution reachable from the contact-free one at
      400 rad/s on the rotor 67 ROM, but starts at 2000 rad/s). result.start says which.
    guess: (omega0, u0): start instead at omega0 (rad/s, inside the range) by damped
      Newton from u0, the unknowns of a solution at any N_h (pad_harmonics adapts them),
      e.g. a low-N_h NFRC's point; the branch then goes in the continuation's direction.
    stability: Floquet stability of every point and the bifurcations (hbm.stability.monitor;
      True: StabilityOptions.of(hbm); None: hbm.stability). on_point then sees each point
      once its stability is final (up to StabilityOptions.max_gap + 1 points later), its extras
      completed with hbm.stability.monitor.PER_POINT (stable, n_unstable, stability_analysed,
      stability_widened, stability_cpu_time, leading_multipliers, period_ratio; the failed
      last point: n_unstable -1).
    resume_bifurcations: with resume and stability, the bifurcations located along the
      resumed points (hbm.stability.bifurcation.bifurcations_from_arrays of the interrupted
      run's table); those between two resumed points are kept (the others cannot have been
      located: they need a point not on disk) and the result's bifurcations include them.
    on_bifurcations(bifurcations): with stability, called with every bifurcation located so
      far (the Bifurcation tuple in branch order) each time that set changes, after on_point
      has seen the points they lie between: an interrupted run's points and bifurcations then
      agree, and resume_bifurcations takes them back.
    """
    res = residual or build_residual(rom, casing, contact, hbm, method=method, forcing=forcing)
    opts = continuation or default_continuation(hbm)
    fac = solver or HbmSolver(atol=0.1 * opts.newton.tol_residual)
    rows = []
    pending = []
    if stability is None:
        stability = hbm.stability
    sopts = stability if isinstance(stability, StabilityOptions) else StabilityOptions.of(hbm)
    monitor = StabilityMonitor.for_residual(res, sopts, newton=opts.newton) if stability else None
    per_point = {}  # index -> stability extras
    t_stab = [0.0]

    told = [[]]  # ids of the bifurcations on_bifurcations last saw

    def hand_on(items):
        for q, exq in items:
            per_point[q.index] = exq
            if on_point is not None:
                on_point(q, exq)
        settled = monitor.released_bifurcations()
        if on_bifurcations is not None and [id(b) for b in settled] != told[0]:
            told[0] = [id(b) for b in settled]
            on_bifurcations(_in_branch_order(settled))

    def row(p: ContinuationPoint, reason: str):
        ex = nfrc_extras(res, p.x)
        pt = NfrcPoint(index=p.index, omega=p.omega, harmonics=ex["harmonics"], le_amplitude=ex["le_amplitude"],
                       le_max=ex["le_max"], residual_norm=p.residual_norm, iterations=p.iterations,
                       step=p.step, time=p.time, converged=p.converged, reason=reason)
        return pt, np.array(p.x), ex

    def record(p: ContinuationPoint):
        pt, x, ex = row(p, "" if p.converged else "failed")
        rows.append((pt, x))
        if p.converged:
            if monitor is None:
                if on_point is not None:
                    on_point(p, ex)
            else:
                t = time.perf_counter()
                done = monitor.push(p, ex)
                t_stab[0] += time.perf_counter() - t
                hand_on(done)
        else:
            pending.append((p, ex))

    t0 = time.perf_counter()
    # The structured solve works on small blocks (27 x 27, m x m with m <= 9 (2 N_h + 1)):
    # a second BLAS thread costs more than it gives (RL NFRC at N_h = 40: 47 s with one
    # thread, 52 s with two, two runs each) and would keep the other core busy spinning.
    threads = threadpool_limits(limits=1, user_api="blas") if isinstance(fac, HbmSolver) else nullcontext()
    with threads:
        start_note = "resumed"
        if resume is not None:
            old = getattr(resume, "branch", resume)
            conv = np.asarray(old.converged, dtype=bool)
            m0 = int(np.flatnonzero(conv)[-1]) + 1 if conv.any() else 0
            for i in range(m0):
                p = ContinuationPoint(i, float(old.omega[i]), np.asarray(old.x[i], dtype=float), True,
                                      float(old.residual_norm[i]), int(old.iterations[i]), float(old.step[i]),
                                      float(old.time[i]))
                rows.append(row(p, "")[:2])
            if monitor is not None and m0:
                old_ex = getattr(resume, "extras", None) or {}
                for i in range(m0):
                    if "stable" in old_ex:
                        per_point[i] = {k: old_ex[k][i] for k in PER_POINT if k in old_ex}
                seeds = [ContinuationPoint(i, float(old.omega[i]), np.asarray(old.x[i], dtype=float), True,
                                           float(old.residual_norm[i]), int(old.iterations[i]), float(old.step[i]),
                                           float(old.time[i])) for i in range(max(0, m0 - 3), m0)]
                t = time.perf_counter()
                # the stored counts spare the monitor an analysis of the second-to-last point
                monitor.seed(seeds, [{**nfrc_extras(res, q.x), **per_point.get(q.index, {})} for q in seeds])
                # a crossing or a fold lies before the last of the points it was located from
                monitor.bifurcations.extend(b for b in resume_bifurcations if b.index <= m0 - 2)
                told[0] = [id(b) for b in monitor.bifurcations]
                t_stab[0] += time.perf_counter() - t
            # A run that could not start at the end its direction names started at the other
            # end, going back (below): its first steps (the start's tangent) go that way again.
            if m0 and float(old.omega[0]) == (opts.omega_max if opts.direction > 0 else opts.omega_min):
                opts = replace(opts, direction=-opts.direction)
            branch = continue_branch(res, None, None, opts, on_point=record, solver=fac, resume=old)
        elif guess is not None:
            w0 = float(guess[0])
            sol = damped_newton(res, pad_harmonics(guess[1], res.n_r, res.basis.n_harmonics), w0, opts.newton, fac)
            start_note = f"damped Newton from the guess at omega={w0:.6g}" + ("" if sol.converged else f": {sol.reason}")
            branch = continue_branch(res, sol.x, w0, opts, on_point=record, solver=fac)
        else:
            w0 = opts.omega_min if opts.direction > 0 else opts.omega_max
            x0, start_note = solve_start(res, w0, opts, fac)
            if not _solves(res, x0, w0, opts):  # start from the other end of the range, going back
                w1 = opts.omega_max if opts.direction > 0 else opts.omega_min
                x1, note1 = solve_start(res, w1, opts, fac)
                if _solves(res, x1, w1, opts):
                    opts, w0, x0 = replace(opts, direction=-opts.direction), w1, x1
                    start_note = f"no start at the first end ({start_note}); {note1} at the other end"
                else:  # the continuation corrects x0 once more and fails: why at either end
                    start_note = f"at omega={w0:.6g}: {start_note}; at omega={w1:.6g}: {note1}"
            branch = continue_branch(res, x0, w0, opts, on_point=record, solver=fac)
        if monitor is not None:
            t = time.perf_counter()
            done = monitor.finish()
            t_stab[0] += time.perf_counter() - t
            hand_on(done)
    wall = time.perf_counter() - t0
    if rows and not rows[-1][0].converged:  # the final failure carries the branch status
        last, xl = rows[-1]
        rows[-1] = (replace(last, reason=branch.status), xl)
    for p, ex in pending:
        if monitor is not None:
            ex = unknown_stability(ex, sopts)
            per_point[p.index] = ex
        if on_point is not None:
            on_point(p, ex)
    pts = [r[0] for r in rows]
    m = len(pts)
    stab = {}
    if monitor is not None:
        def col(key, fill, dtype):
            return np.array([per_point.get(p.index, {}).get(key, fill) for p in pts], dtype=dtype)

        k = sopts.n_leading
        stab = dict(stable=col("stable", False, bool), n_unstable=col("n_unstable", -1, int),
                    stability_note=col("stability_note", "", object),
                    stability_analysed=col("stability_analysed", False, bool),
                    leading_multipliers=np.array([np.asarray(per_point.get(p.index, {}).get(
                        "leading_multipliers", np.full(k, np.nan)), dtype=float) for p in pts]).reshape(m, k),
                    bifurcations=_in_branch_order(monitor.bifurcations),
                    n_stability_analyses=monitor.n_analyses, stability_time=t_stab[0])
    return NfrcResult(
        method=method, omega=np.array([p.omega for p in pts]),
        harmonics=np.array([p.harmonics for p in pts]).reshape(m, res.n_c, res.n_r),
        le_amplitude=np.array([p.le_amplitude for p in pts]), le_max=np.array([p.le_max for p in pts]),
        residual_norm=np.array([p.residual_norm for p in pts]),
        iterations=np.array([p.iterations for p in pts], dtype=int), step=np.array([p.step for p in pts]),
        time=np.array([p.time for p in pts]), converged=np.array([p.converged for p in pts], dtype=bool),
        reason=np.array([p.reason for p in pts], dtype=object), status=branch.status, wall_time=wall,
        n_factorizations=fac.n_factorizations, unknowns=np.array([r[1] for r in rows]).reshape(m, res.size),
        start=start_note, **stab)


def _solves(res, u, omega, opts: ContinuationOptions) -> bool:
    """Whether u is a solution at omega to the continuation's tolerance."""
    R = res(u, omega, jacobian=False)
    return bool(np.all(np.isfinite(R)) and np.linalg.norm(R) <= opts.newton.tol_residual)
