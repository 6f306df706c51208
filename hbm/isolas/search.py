"""The isola search, generic over a residual R(x, omega) -> (R, dR_dx, dR_domega).

Two phases:

1. corrections: every seed (a guess x0 at a fixed omega) is corrected by Newton at that
   omega (hbm.continuation.newton, backtracking, a capped number of iterations: most seeds
   fail or land on the primary branch, and should cost little). A converged solution that
   lies on a known branch (hbm.isolas.membership: polyline distance below the tolerance, or
   Newton from the branch's curve near the polyline's nearest point landing on it: lies_on)
   is dropped at once; converged
   solutions at the same omega closer than the tolerance are one. A solution and its images
   (the residual's symmetries, `images`: on the blade, the orbit shifted by a lobe of the
   casing) are one: each test also runs on the images. Seeds are independent: they are
   spread over local processes (concurrent.futures, one task per omega) or over the MPI
   ranks (each takes its share, then allgather).
2. branches: each remaining solution, in seed order, unless it lies on a branch found so
   far, is continued both ways by arc length (hbm.continuation.arclength), the two halves
   at the same time, each sending the other its points. The halves meet where a loop
   closes: a half stops (STATUS_HALVES_MET) at its first point k whose chord from point
   k - 1 runs against the other's points 0 .. k - _HALF_LAG within the tolerance, away from
   the seed (_met_segment); the loop is the two halves, each about half of it plus the lag,
   their overlap kept once (_trimmed). Where they meet depends on the points only: the
   halves run on two processes, or on two threads of one process that take turns (one
   core: under MPI, where rank 0 continues alone, or with one worker), and give the same
   branch. A half that came back onto its own start by the
   closed-loop test of eq. (26)-(27) (the other having ended first, or a loop too small for
   the halves to meet away from the seed) went round alone, and the other is dropped, once
   it is checked to have come back onto its start, travelling the way it left: eq. (27)
   measures the return relative to |x|, which one turn of a coil later can pass; such a
   half is no loop, and the branch is both halves (_back_at_start). A
   half branch also ends when it (or its image) meets a known or found branch: when the
   chord from its previous point passes within the tolerance of that branch's polyline (a
   branch that only touches another, tangentially, closer than the tolerance meets it, and
   merges into it: the tolerance is the resolution of "the same solution"; one that stays
   farther does not), or when its part without the residual's symmetry turns over through
   zero between two points and the symmetric solution there lies on that branch (a
   symmetry-breaking pitchfork, which the polyline test misses where the chords cut a bend:
   _symmetric_crossing). A half that crosses a branch ends there, on its first point past it:
   a branch crossing another twice is continued between the crossings only, and a later
   seed beyond them gives another branch. That last step past a crossing is left out of
   the polyline later halves and seeds are measured against (_meeting_polyline): a half
   coming from beyond the crossing crosses the branch there too, rather than running into
   the step, merging and having its points, the piece beyond the crossing, dropped. On two
   processes the wall time of a branch halves, open or closed. The halves are merged into
   one branch and classified:
     primary: it merges into (runs along) the primary NFRC;
     bifurcated: it crosses another branch (a branch point; a found branch it crosses is
       made bifurcated too, with the pieces it is one branch with), merges into a known
       branch other than the primary (search's `primaries`), or passes through a located
       bifurcation point of one;
     isola: a closed loop, or both ends inside the omega range;
     detached: otherwise (an end on the range's bound, never meeting the primary). A half
       that "closes" while the other reached the range's bound has come back near its
       start without closing (a loop through the seed cannot leave the range): such a
       branch is not closed (_classify), nor is one whose "closed loop" did not come back
       onto its start.
   closed: the branch is one closed loop: its halves met, or one was followed round back
   onto the start, and no other branch runs into it. Closed branches are isolas or bifurcated
   (through a located bifurcation point, or crossed by another branch: a crossing leaves
   both branches whole), never primary or detached.
   A half that merges into a branch found earlier makes the new one part of it: its seeds
   go to that branch, its points are dropped, and the branch takes the connection the new
   one brings (primary before bifurcated before detached before isola: an open isola that
   a branch reaching the range's bound runs into is detached). A closed loop that a branch
   runs into is no longer closed (the set is the loop and what runs into it; the status
   says so), unless every half of that branch ran into the loop (a stretch of it that the
   membership test missed): it is then the same set whichever of the two was found first
   (the loop merging into the branch found before it ends on that branch, not closed).
   When its two halves merge into two different branches found earlier, those are pieces
   of one branch: all the pieces take the kind of the whole (the pieces each was linked to
   before included), and each target's status names the other ("one branch with branch
   k", which `connected` reads back); the seed goes to the first met, and both keep their
   index and points (a branch saved by on_branch is never withdrawn). One branch may thus
   be several records: IsolaSearch.groups and kind_counts count it once. Seeds lying on a branch
   found later are attributed to it and never continued (a seed within the tolerance of
   two branches, as at a crossing, to the first found). Either way the branch is passed
   to on_branch again, so that an interrupted run has them on disk. The caller's
   `describe` (per-point data, e.g. the stability, and per-branch tables) runs on the
   merged branch, in two chunks when it is long (_Description): with two workers on two
   more processes, while the search goes on with the next candidates (what it decides needs
   a branch's points only; at most _UNDESCRIBED branches wait for their description, which
   fills the time a half waits for the other or runs alone); with one, the same chunks in
   turn in this process. A branch reaches on_branch
   once described, in index order: the branches on disk are always whole, a prefix of
   the found ones.

Resume: `search` takes the corrections and finished branches of an interrupted run of the
same inputs and only computes what is missing; the result is the uninterrupted one.
"""
from __future__ import annotations

import concurrent.futures
import copy
import math
import os
import pickle
import queue
import re
import threading
import time
from dataclasses import dataclass, field, replace
from types import SimpleNamespace
from typing import Callable

import numpy as np
from threadpoolctl import threadpool_limits

from hbm.continuation.arclength import ContinuationOptions, continue_branch
from hbm.continuation.branch import STATUS_CLOSED_LOOP, STATUS_OMEGA_MAX, STATUS_OMEGA_MIN, Branch
from hbm.continuation.missing import NO_VALUE
from hbm.continuation.newton import NewtonOptions, newton_solve
from hbm.isolas.membership import (KnownBranch, nearest_segment, polyline_distance,
                                     segment_length, segment_polyline_distance)
from hbm.options import check_option
from hbm.processes import (gathered, keep_freed_memory, limit_blas_threads, on_root, process_context, reported_deaths,
                           run_flagged, running, set_start_flags, start_flags)

#: seed verdicts (IsolaSearch.seed_branch): not converged; on a known branch (the primary)
NOT_CONVERGED = -1
ON_KNOWN = -2

#: |cos| between a half branch's direction and the branch it meets above which it merges
#: into (runs along) that branch rather than crossing it
_PARALLEL_COS = 0.9


@dataclass(frozen=True)
class Seed:
    """A start guess: omega, rad/s; x (n,) in the residual's unknowns; origin, in words
    (e.g. "modal j=2 k=4 A=0.0032"). of_model: x is a solution of a model (a time-integration
    orbit, another contact treatment's HBM solution), corrected with SearchOptions.model_newton:
    most of eq. (31)'s guesses lead nowhere and should cost little, such a seed leads
    somewhere and is worth more iterations."""

    omega: float
    x: np.ndarray
    origin: str
    of_model: bool = False


@dataclass(frozen=True)
class SearchOptions:
    """tolerance: the membership distance (scaled, see hbm.isolas.membership); Newton from
    the polyline's nearest point must land within tolerance / 100 for a point closer than
    refine_ratio times the local chord. continuation: the arc length's options (its omega
    range is the search's; direction is set per half; max_points per half). newton: the
    seeds' Newton rule (line search on); model_newton: that of the seeds of_model (None: newton).
    workers: local processes for the corrections (None: every usable core)."""

    tolerance: float
    continuation: ContinuationOptions
    newton: NewtonOptions
    workers: int | None = None
    refine_ratio: float = 0.5
    model_newton: NewtonOptions | None = None

    def __post_init__(self):
        check_option("tolerance", self.tolerance, 0, low_open=True)
        check_option("refine_ratio", self.refine_ratio, 0, low_open=True)
        if self.workers is not None:
            check_option("workers", self.workers, 1, integer=True, note="or unset")


@dataclass(frozen=True)
class Corrections:
    """Phase 1, per seed (s seeds): converged (s,) bool; iterations (s,) int; on_known (s,)
    int, index of the known branch it lies on (-1: none); same_as (s,) int, the seed it
    duplicates at the same omega (-1: none); x (s, n), the corrected solution (nan where
    not converged); cpu_time, s (summed over processes); residual_norm (s,), ||R|| of the
    last iterate, as Newton measures it against its tolerance (nan where unknown); reason
    (s,) str, why Newton gave up ("" where it converged; () when unknown: read from a
    partial file of an earlier version)."""

    converged: np.ndarray
    iterations: np.ndarray
    on_known: np.ndarray
    same_as: np.ndarray
    x: np.ndarray
    cpu_time: float = 0.0
    residual_norm: np.ndarray | None = None
    reason: tuple[str, ...] = ()

    def candidates(self) -> np.ndarray:
        """Seeds to continue unless they lie on a branch found before them: converged, on
        no known branch, not a duplicate."""
        return np.flatnonzero(self.converged & (self.on_known < 0) & (self.same_as < 0))


@dataclass(frozen=True, eq=False)
class FoundBranch:
    """A branch of the search, m points.

    omega (m,) rad/s; x (m, n); converged (m,) bool (the halves' failed last points are
    kept, marked). kind: "primary" | "bifurcated" | "isola" | "detached", that of the whole
    set it is one branch with (module doc). closed: one closed loop, which nothing else
    runs into (only an isola or a bifurcated branch is closed). status: how each half ended
    ("+: ...; -: ...", then what later branches did to it). start: the seed it was
    continued from. seeds: the seeds attributed to it (start included). extras: per-point
    arrays of the caller's `describe` (e.g. le_amplitude (m,)). n_points_computed:
    continuation points computed for it. cpu_time, s.
    """

    omega: np.ndarray
    x: np.ndarray
    converged: np.ndarray
    kind: str
    closed: bool
    status: str
    start: int
    seeds: tuple[int, ...]
    extras: dict = field(default_factory=dict)
    n_points_computed: int = 0
    cpu_time: float = 0.0


@dataclass(frozen=True)
class IsolaSearch:
    """Result: seeds; corrections (phase 1); branches (FoundBranch, in order found);
    seed_branch (s,) int: the branch each seed lies on, NOT_CONVERGED, or ON_KNOWN;
    n_continued: branches continued in this call (resumed ones not counted);
    n_points_computed: continuation points computed in this call; cpu_time, wall_time, s."""

    seeds: tuple[Seed, ...]
    corrections: Corrections
    branches: tuple[FoundBranch, ...]
    seed_branch: np.ndarray
    n_continued: int
    n_points_computed: int
    cpu_time: float
    wall_time: float

    @property
    def n_converged(self) -> int:
        return int(self.corrections.converged.sum())

    @property
    def n_distinct(self) -> int:
        """Converged seeds that are no duplicate at their omega (on a known branch or not)."""
        c = self.corrections
        return int((c.converged & (c.same_as < 0)).sum())

    @property
    def groups(self) -> tuple[tuple[int, ...], ...]:
        """The branches' indices grouped into the sets that are one branch: pieces that later
        branches linked (their statuses say "one branch with branch k") are one group
        (connected)."""
        return tuple(connected(self.branches))

    def kind_counts(self) -> dict[str, int]:
        """{kind: how many branches of that kind}, the pieces of one branch (groups) counted
        once: len(branches) counts records, of which two linked pieces are two."""
        out: dict = {}
        for g in self.groups:
            kind = _joined_kind([self.branches[k].kind for k in g])
            out[kind] = out.get(kind, 0) + 1
        return out


class _Joined(Exception):
    """Raised from on_point: the half branch met branch `label` (merging: runs along it)."""

    def __init__(self, label: str, index: int, merging: bool):
        super().__init__(label)
        self.label, self.index, self.merging = label, index, merging


# -- phase 1: corrections ---------------------------------------------------------------------
class _Corrector:
    """Newton on one omega's seeds, with the membership test against the known branches.

    Each seed gets a fresh copy of the factory's solver: a solver may keep state between
    solves (hbm.harmonic.solver.HbmSolver keeps its preconditioner while GMRES meets the
    loose tolerance of a seed's first steps), and a seed started with the last seed's would
    take other inexact steps; on the coarse rotor 67 ROM (RL) 2 of 13 TI seeds converged
    alone and failed after others. Which seeds a process corrects before another depends on
    the scheduling, so with a kept state the converged set changed from run to run.
    """

    def __init__(self, factory, known, options: SearchOptions):
        self.residual, self._solver = factory()
        self.known, self.options = list(known), options

    def __call__(self, items):
        """items: [(seed index, omega, x0, of_model)] of one omega -> [(index, converged,
        iterations, on_known, same_as, x or None, ||R||, reason)]."""
        out = []
        kept = []  # (index, x) of the distinct converged solutions at this omega
        model = self.options.model_newton or self.options.newton
        for i, w, x0, of_model in items:
            solver = copy.deepcopy(self._solver)
            sol = newton_solve(self.residual, x0, w, model if of_model else self.options.newton, solver=solver)
            if not sol.converged or not np.all(np.isfinite(sol.x)):
                why = sol.reason or f"non-finite solution at omega={w:.6g}"
                out.append((i, False, sol.iterations, -1, -1, None, sol.residual_norm, why))
                continue
            mine = [sol.x, *images(self.residual, sol.x)]
            k = lies_on_any(self.residual, sol.x, w, self.known, self.options, solver, x_images=mine[1:])
            same = next((j for j, xj in kept if any(same_solution(xq, xj, self.options) for xq in mine)), -1)
            if k < 0 and same < 0:
                kept.append((i, sol.x))
            out.append((i, True, sol.iterations, k, same, sol.x, sol.residual_norm, ""))
        return out


_WORKER: dict = {}


def _init_worker(factory, known, options, started):
    """Pool initializer: one BLAS thread for the worker's lifetime, freed memory kept for
    reuse (keep_freed_memory), its corrector, and the start flags of the pool's tasks (a dead
    worker's speeds are named)."""
    limit_blas_threads()
    keep_freed_memory()
    set_start_flags(started)
    _WORKER["corrector"] = _Corrector(factory, known, options)


def _run_worker(items):
    return _timed(_WORKER["corrector"], items)


def _timed(corrector, items):
    t = time.process_time()
    return corrector(items), time.process_time() - t


def correct_seeds(factory, seeds, known, options: SearchOptions, comm=None,
                  on_progress: Callable[[int, int], None] | None = None) -> Corrections:
    """Phase 1 on every seed. factory() -> (residual, LinearSolver): picklable (spawned
    workers under MPI-initialised processes build their own). known: KnownBranch list.
    comm: an MPI communicator (mpi4py) to share the omegas among ranks, or None for local
    processes. on_progress(done, total): seeds done (this rank's under MPI)."""
    s = len(seeds)
    groups: dict = {}
    for i, sd in enumerate(seeds):
        groups.setdefault(float(sd.omega), []).append((i, float(sd.omega), np.asarray(sd.x, dtype=float),
                                                       bool(sd.of_model)))
    tasks = [groups[w] for w in sorted(groups)]
    progress = on_progress or (lambda done, total: None)
    rows, cpu = [], 0.0
    if comm is not None:
        mine = tasks[comm.rank::comm.size]
        # one BLAS thread as in a pool's worker, for this phase only: a limit that outlived
        # it would change the later stages of the rank's run (their round-off too)
        error = None
        try:
            with threadpool_limits(limits=1, user_api="blas"):
                corrector = _Corrector(factory, known, options)
                done = 0
                for t in mine:
                    r, c = _timed(corrector, t)
                    rows += r
                    cpu += c
                    done += len(t)
                    progress(done, sum(len(m) for m in mine))
        except Exception as exc:  # noqa: BLE001 - raised by gathered() on every rank
            error = exc
        parts = gathered(comm, (rows, cpu), error, "the isola search's seed corrections")
        rows = [r for part, _ in parts for r in part]
        cpu = sum(c for _, c in parts)
    else:
        workers = min(options.workers or len(os.sched_getaffinity(0)), max(1, len(tasks)))
        if workers <= 1:
            with threadpool_limits(limits=1, user_api="blas"):  # as above: this phase only
                corrector = _Corrector(factory, known, options)
                for t in tasks:
                    r, c = _timed(corrector, t)
                    rows += r
                    cpu += c
                    progress(len(rows), s)
        else:
            ctx = process_context()  # fork: the residual is built once per worker from the inherited factory
            started = start_flags(ctx, len(tasks))

            def correcting() -> str:  # each task is one speed's seeds (t[0][1]: its Omega)
                w = [f"{tasks[k][0][1]:g}" for k in running(started)]
                return f"seeds being corrected at {', '.join(w)} rad/s" if w else ""

            with reported_deaths("the isola search", correcting), concurrent.futures.ProcessPoolExecutor(
                    workers, mp_context=ctx, initializer=_init_worker,
                    initargs=(factory, known, options, started)) as pool:
                futures = [pool.submit(run_flagged, k, _run_worker, t) for k, t in enumerate(tasks)]
                for f in concurrent.futures.as_completed(futures):
                    r, c = f.result()
                    rows += r
                    cpu += c
                    progress(len(rows), s)
    n = len(np.asarray(seeds[0].x)) if s else 0
    conv, its = np.zeros(s, bool), np.zeros(s, np.int64)
    on_known, same = np.full(s, -1, np.int64), np.full(s, -1, np.int64)
    X = np.full((s, n), np.nan)
    rn, why = np.full(s, np.nan), [""] * s
    for i, c, it, k, sm, x, r, w in rows:
        conv[i], its[i], on_known[i], same[i], rn[i], why[i] = c, it, k, sm, r, w
        if x is not None:
            X[i] = x
    return Corrections(conv, its, on_known, same, X, cpu, rn, tuple(why))


def same_solution(x: np.ndarray, y: np.ndarray, options: SearchOptions) -> bool:
    """Whether two solutions (n,) at one omega are one: within options.tolerance of each other
    in the membership's metric (the scaled unknowns over continuation.x_scale)."""
    return bool(np.linalg.norm((x - y) / options.continuation.x_scale) <= options.tolerance)


def images(residual, x: np.ndarray) -> list:
    """The other solutions x implies by a symmetry of the residual (its `images` method,
    e.g. hbm.harmonic.residual.HarmonicBalanceResidual.images: the orbit shifted by a lobe
    of the casing), [] when it has none: a branch and its image are one branch."""
    f = getattr(residual, "images", None)
    return list(f(x)) if f is not None else []


def lies_on_any(residual, x, omega: float, branches, options: SearchOptions, solver=None,
                x_images: list | None = None) -> int:
    """lies_on for x or any of its images (x_images: images(residual, x) when already at
    hand): the index of the branch, -1 when none."""
    for xq in [x, *(images(residual, x) if x_images is None else x_images)]:
        k = lies_on(residual, xq, omega, branches, options, solver)
        if k >= 0:
            return k
    return -1


def lies_on(residual, x, omega: float, branches, options: SearchOptions, solver=None) -> int:
    """Index of the first branch (KnownBranch list) the solution (x, omega) lies on, -1 when
    none: polyline distance (scaled: x / x_scale, omega / omega_scale) <= tolerance (every
    branch is tried so first), or, closer than refine_ratio times the nearest chord (the
    polyline cuts the curve's bends), Newton at omega lands within tolerance / 100 of x
    from the branch's curve there: the parabola through the three vertices around the
    nearest segment, at the nearest point's place along it (_curve_guess; from the chord's
    nearest point when Newton does not converge from there). Not from the
    chord's nearest point: another branch lying between the chord and the curve, closer
    than the chord's sagitta but farther than the tolerance from both (e.g. a concentric
    isola), is nearer to it than the branch's own curve, and Newton from there landed on
    it: its seeds were taken for the branch's, and it was never continued."""
    co = options.continuation
    # most solutions lie on a branch: the cheap test (only segments near omega) first, on all
    for k, b in enumerate(branches):
        if polyline_distance(x, omega, b, co.x_scale, co.omega_scale, within=options.tolerance)[0] <= options.tolerance:
            return k
    for k, b in enumerate(branches):
        if len(b.omega) < 2:
            continue
        # only the segments within reach of the test below: a point farther than refine_ratio
        # times the longest chord fails it whichever segment is nearest (the same answer as
        # the whole polyline's, at a third of the cost on a branch over the whole range)
        reach = options.refine_ratio * b.longest_segment(co.x_scale, co.omega_scale)
        d, xn, wn, s, t = nearest_segment(x, omega, b, co.x_scale, co.omega_scale, within=reach)
        if not math.isfinite(d):
            continue
        if d <= options.refine_ratio * segment_length(b, s + int(t > 0.5), co.x_scale, co.omega_scale):
            sol = newton_solve(residual, _curve_guess(b, x, omega, co.x_scale, co.omega_scale, (xn, s, t)), omega,
                               options.newton, solver=solver)
            if not sol.converged:  # no curve point from there (e.g. a corner the parabola cuts): the chord's
                sol = newton_solve(residual, xn, omega, options.newton, solver=solver)
            if sol.converged and np.linalg.norm((sol.x - x) / co.x_scale) <= 0.01 * options.tolerance:
                return k
    return -1


def _curve_guess(b: KnownBranch, x, omega: float, x_scale, omega_scale: float, nearest=None) -> np.ndarray:
    """The branch's curve at omega near the polyline's point nearest to (x, omega), x part:
    the parabola (in the scaled chord length) through the three vertices around the nearest
    segment, where its omega is omega (nearest to the nearest point's place; that place
    where it never is, as at a fold); the chord's point for a two-point branch. nearest:
    (x_near, s, t) of nearest_segment when already at hand."""
    if nearest is None:
        _, xn, _, s, t = nearest_segment(x, omega, b, x_scale, omega_scale)
    else:
        xn, s, t = nearest
    m = len(b.omega)
    if m < 3:
        return xn
    lo = min(max(s - 1 if t < 0.5 else s, 0), m - 3)  # vertices lo .. lo + 2, segment s among them
    sx = np.broadcast_to(np.asarray(x_scale, dtype=float), b.x.shape[1:])
    Y = np.column_stack([b.x[lo:lo + 3] / sx, b.omega[lo:lo + 3] / omega_scale])
    L = np.linalg.norm(np.diff(Y, axis=0), axis=1)
    p = np.array([0.0, L[0], L[0] + L[1]])
    if not (L > 0).all():
        return xn
    u = p[s - lo] + t * L[s - lo]
    # the Lagrange basis as polynomials in u: Y(u) = sum_i Y_i l_i(u); Newton runs at omega,
    # so the place along the parabola is where its omega is omega (the root nearest to u;
    # none near a fold in omega: the nearest point's place)
    basis = [np.poly1d(np.poly(np.delete(p, i))) / np.prod(p[i] - np.delete(p, i)) for i in range(3)]
    wq = sum(bi * Y[i, -1] for i, bi in enumerate(basis)) - omega / omega_scale
    r = np.atleast_1d(wq.r) if wq.order > 0 else np.array([])
    r = r[np.isfinite(r) & (np.abs(np.imag(r)) <= 1e-12 * max(1.0, p[2]))].real
    r = r[(r >= p[0] - L[0]) & (r <= p[2] + L[1])]  # on the three vertices' stretch (and a chord beyond)
    if r.size:
        u = float(r[np.argmin(np.abs(r - u))])
    return sum(bi(u) * Y[i] for i, bi in enumerate(basis))[:-1] * sx


# -- phase 2: branches -------------------------------------------------------------------------
#: How a half ends that met the other half (module doc): the two are one closed loop.
STATUS_HALVES_MET = f"{STATUS_CLOSED_LOOP} (the halves met)"

#: A half meets the other one only where the stretch of the branch between the two places
#: (back through the seed) goes farther than this many tolerances from where they meet: at
#: the seed the halves' first chords touch, and a seed at a sharp turn keeps both within the
#: tolerance of it for several points, whereas a loop's far side is its diameter away.
_LOOP_REACH = 10.0

#: A half's point k is tested against the other half's points 0 .. k - _HALF_LAG: a half
#: waits only for one that lags further behind (a point costs 1 to 10 times another: step
#: refusals, Newton iterations), and both overrun the place they meet by about this many
#: points, which the merged loop leaves out (_trimmed). Point for point (lag 0) the halves
#: of the coarse rotor 67 doubled branches took about as much wall time as before they met.
_HALF_LAG = 16


class _OtherHalf:
    """The other half of the branch being continued, as its points come (module doc: the
    halves meet). send, recv: queues of (tag, kind, payload): kind "P" a converged point
    (omega, x), "E" the half ended, "F" it failed (raised); recv skips messages of another
    tag (an earlier branch's, left in a pool's queues). baton: a lock held while computing
    and released while waiting, so that two halves on two threads of one process take
    turns (the work of one core); None on two processes."""

    def __init__(self, send, recv, tag, baton=None):
        self.send, self.recv, self.tag, self.baton = send, recv, tag, baton
        self.omega = np.zeros(0)
        self.x = None
        self.m = 0  # points received
        self.ended = False

    def begin(self):
        if self.baton is not None:
            self.baton.acquire()

    def end(self, failed: bool = False):
        """Say this half ended, and read the other's messages up to its own end: none is left
        in a queue for a later branch. failed: this half raised (an error, an interrupt): the
        other stops at its next message (_OtherHalfFailed) instead of going on alone."""
        try:
            self.post("F" if failed else "E")
            while not (self.ended or failed):
                self.take()
        finally:
            if self.baton is not None:
                self.baton.release()

    def post(self, kind: str, payload=None):
        self.send.put((self.tag, kind, payload))

    def take(self):
        """Read the other half's next message, waiting for it."""
        if self.baton is not None:
            self.baton.release()
        try:
            while True:
                tag, kind, payload = self.recv.get()
                if tag == self.tag:
                    break
        finally:
            if self.baton is not None:
                self.baton.acquire()
        if kind == "F":
            self.ended = True
            raise _OtherHalfFailed()
        if kind == "E":
            self.ended = True
        elif kind == "P":
            w, x = payload
            if self.x is None or self.m == len(self.omega):  # grown by doubling: views, no copy per point
                cap = max(64, 2 * self.m)
                om, X = np.zeros(cap), np.zeros((cap, len(x)))
                if self.m:
                    om[: self.m], X[: self.m] = self.omega[: self.m], self.x[: self.m]
                self.omega, self.x = om, X
            self.omega[self.m], self.x[self.m] = w, x
            self.m += 1

    def points_upto(self, k: int) -> KnownBranch:
        """The other half's points 0 .. k, waiting for them; fewer when it ended before k."""
        while self.m <= k and not self.ended:
            self.take()
        m = min(self.m, k + 1)
        return KnownBranch(self.omega[:m], self.x[:m], "the other half")


def _met_segment(points, b: KnownBranch, opts: ContinuationOptions, tol: float) -> int:
    """The segment s (points s, s + 1) of the other half's polyline b that this half's last
    chord (points[-2] to points[-1], ContinuationPoints or anything with x and omega, from the
    seed, converged) meets, -1 when it does not: within tol, running against it (the halves
    leave the seed in opposite directions, so along a loop they come back towards each
    other: |cos| above _PARALLEL_COS, negative), and where the stretch of the branch between
    the two places, back through the seed, goes farther than _LOOP_REACH tol from them."""
    if len(b.omega) < 2 or len(points) < 2:
        return -1
    prev, p = points[-2], points[-1]
    sx = np.broadcast_to(np.asarray(opts.x_scale, dtype=float), np.shape(p.x))
    sw = opts.omega_scale
    d, xn, wn = segment_polyline_distance(prev.x, prev.omega, p.x, p.omega, b, sx, sw, within=tol)
    if not d <= tol:
        return -1
    cos, s = _chord_cos(points, b, xn, wn, opts)
    if not cos < -_PARALLEL_COS:  # nan (a zero-length chord) included
        return -1
    stretch = np.vstack([b.x[: s + 1]] + [np.asarray(q.x)[None] for q in points[1:-1]])
    w_str = np.concatenate([b.omega[: s + 1], [q.omega for q in points[1:-1]]])
    reach = np.sqrt(np.sum(((stretch - xn) / sx) ** 2, axis=1) + ((w_str - wn) / sw) ** 2)
    return s if reach.max() > _LOOP_REACH * tol else -1


def _trimmed(met: Branch, other: Branch, opts: ContinuationOptions, tol: float) -> Branch:
    """other without its points past the place where the half `met` met it (its points
    there overlap met's last ones, _HALF_LAG): the segment met's last chord met, among the
    points 0 .. len(met) - 1 - _HALF_LAG of other it was tested against, is kept whole."""
    ok = np.asarray(met.converged, bool)
    pts = [SimpleNamespace(x=x, omega=w) for x, w in zip(met.x[ok], met.omega[ok])]
    # the points it was tested against: other's converged ones (a failed last point was never sent)
    upto = min(len(met) - 1 - _HALF_LAG, len(other) - 1 - int(not other.converged[-1]))
    b = KnownBranch(other.omega[: upto + 1], other.x[: upto + 1], "the other half")
    s = _met_segment(pts, b, opts, tol)
    if s < 0:  # not found again (cannot happen: the same points): keep the whole
        return other
    keep = slice(0, s + 2)
    return replace(other, omega=other.omega[keep], x=other.x[keep], converged=other.converged[keep],
                   residual_norm=other.residual_norm[keep], iterations=other.iterations[keep],
                   step=other.step[keep], time=other.time[keep])


class _HalvesMet(Exception):
    """Raised from on_point: this half met the other."""


class _OtherHalfFailed(Exception):
    """Raised in a half whose other half raised: the search fails with the other's error."""


def _half(residual, solver, x0, w0, direction: int, opts: ContinuationOptions, others, tol: float,
          search_options: SearchOptions | None = None, other: _OtherHalf | None = None):
    """One half branch from (x0, w0): (Branch, joined) with joined = (label, index, merging)
    when it stopped on meeting a branch of `others` [(label, index, KnownBranch)].
    search_options: also stop where the half crosses a symmetric branch (_symmetric_crossing).
    other: the other half, run at the same time: this one stops (STATUS_HALVES_MET) at its
    first point k whose chord from k - 1 meets the other's points 0 .. k - _HALF_LAG
    (_met_segment; fewer when the other ended before), so its points do not depend on which
    half ran faster."""
    points = []

    def on_point(p):
        points.append(p)
        if not p.converged:
            return
        if other is not None:
            other.post("P", (p.omega, p.x))
        if p.index == 0:
            return
        # the chord from the previous point: a branch crossed between two points passes farther
        # than tol from it at both when the step is longer than tol
        prev = points[-2] if len(points) >= 2 and points[-2].converged else p
        met = _meeting(residual, prev, p, others, opts, tol, search_options, solver)
        if met is not None:
            raise _Joined(*met)
        if other is not None and p.index - _HALF_LAG >= 1:
            if _met_segment(points, other.points_upto(p.index - _HALF_LAG), opts, tol) >= 0:
                raise _HalvesMet()

    if other is not None:
        other.begin()
    failed = True
    try:
        try:
            br = continue_branch(residual, x0, w0, replace(opts, direction=direction), on_point=on_point,
                                 solver=solver, admit=_keeps_off_symmetric_orbits(residual))
            out = br, None
        except _Joined as j:
            out = Branch.from_points(points, len(x0), f"met {j.label}"), (j.label, j.index, j.merging)
        except _HalvesMet:
            out = Branch.from_points(points, len(x0), STATUS_HALVES_MET), None
        failed = False
        return out
    finally:
        if other is not None:
            other.end(failed)


def _meeting(residual, prev, p, others, opts: ContinuationOptions, tol: float,
             search_options: SearchOptions | None = None, solver=None):
    """(label, index, merging) of the first branch of `others` [(label, index, KnownBranch)]
    that the chord from prev to p (anything with x, omega), or its image, passes within tol
    of; merging: the chord runs along it (_parallel) rather than across it. With
    search_options, then the branch of `others` the chord crosses at a symmetric solution
    (_symmetric_crossing, merging False). None: none."""
    prev_images = [prev.x, *images(residual, prev.x)]
    p_images = [p.x, *images(residual, p.x)]
    for q, xq in enumerate(p_images):
        for label, idx, b in others:
            d, xn, wn = segment_polyline_distance(prev_images[q], prev.omega, xq, p.omega, b, opts.x_scale,
                                                  opts.omega_scale, within=tol)
            if d <= tol:  # q > 0: this branch's image meets b, i.e. this branch meets b's image
                tail = [prev, p] if q == 0 else [SimpleNamespace(x=images(residual, t.x)[q - 1], omega=t.omega)
                                                 for t in (prev, p)]
                return label + (", an image of it" if q else ""), idx, _parallel(tail, b, xn, wn, opts)
    if search_options is not None:
        return _symmetric_crossing(residual, prev, p, others, search_options, solver, prev_images[1:], p_images[1:])
    return None


def _symmetric_parts(x: np.ndarray, x_images: list) -> list[np.ndarray]:
    """The projections of x on the solutions each subgroup of the residual's symmetries
    leaves unchanged, one per proper divisor d of the group's order N = len(x_images) + 1:
    the mean of x and its images j = d, 2 d, ... (x_images[j - 1] is x under the j-th power of
    the group's generator, as HarmonicBalanceResidual.images lists the lobe shifts)."""
    n = len(x_images) + 1
    return [(x + sum(x_images[j - 1] for j in range(d, n, d))) / (n // d) for d in range(1, n) if n % d == 0]


#: the most the chord's part without the symmetry may keep of its ends' at a crossing
#: (_symmetric_crossing): a part that only turns keeps cos(phi / 2), over 0.25 for phi < 151 deg
_CROSSING_FRACTION = 0.25


def _symmetric_crossing(residual, prev, p, others, options: SearchOptions, solver, pi: list, qi: list):
    """(label, index, False) of the branch of `others` that the chord from prev to p crosses
    where it passes through solutions a symmetry leaves unchanged; None: none. pi, qi:
    images(residual, x) of prev.x and p.x (the caller's, computed once a point).

    A branch of solutions without the casing's symmetry (odd harmonics of Omega with two
    lobes) meets the symmetric branch it bifurcates from at a symmetry-breaking pitchfork,
    where it passes through the symmetric subspace: its non-symmetric part x - P x turns
    over between two points. The chord-to-polyline test sees that crossing only where the
    step and the crossed branch's chords are short beside their bends (on the default
    rotor 67 scene both treatments' 3 Omega = w_1 branches crossed their primary NFRC twice
    unseen and were called closed isolas). So the crossing is located on the chord (where
    its non-symmetric part is smallest), projected on the symmetric subspace, solved by
    Newton at its Omega (a symmetric start stays symmetric) and tested with lies_on_any, which
    refines near a polyline's bends."""
    if not pi:
        return None
    co = options.continuation
    sx = np.broadcast_to(np.asarray(co.x_scale, dtype=float), np.shape(p.x))
    for k, (sp, sq) in enumerate(zip(_symmetric_parts(prev.x, pi), _symmetric_parts(p.x, qi))):
        a, b = (prev.x - sp) / sx, (p.x - sq) / sx  # the non-symmetric parts, scaled
        if not float(a @ b) < 0.0:  # not turned over
            continue
        da = b - a
        t = float(-(a @ da) / (da @ da))  # in (0, 1): a . b < 0
        # through zero, not turned round it: at a crossing the chord's part without the symmetry
        # falls to the step's sagitta (1e-4 to 1e-3 of the ends' on rotor 67), where a part
        # turned by an angle phi at constant size keeps cos(phi / 2) of it
        if float(np.linalg.norm(a + t * da)) > _CROSSING_FRACTION * min(float(np.linalg.norm(a)),
                                                                          float(np.linalg.norm(b))):
            continue
        xt, wt = prev.x + t * (p.x - prev.x), float(prev.omega + t * (p.omega - prev.omega))
        xs = _symmetric_parts(xt, images(residual, xt))[k]
        sol = newton_solve(residual, xs, wt, options.newton, solver=copy.deepcopy(solver))
        if not sol.converged:
            continue
        for label, idx, kb in others:
            if lies_on_any(residual, sol.x, wt, [kb], options, copy.deepcopy(solver)) == 0:
                return f"{label} (at a symmetric solution, {wt:.6g} rad/s)", idx, False
    return None


def _meeting_polyline(fb: "FoundBranch", label: str, earlier, residual, opts: ContinuationOptions,
                      tol: float, search_options: SearchOptions | None = None, solver=None) -> KnownBranch:
    """The polyline of the found branch fb that later halves and seeds are measured against:
    its converged points, less an end that lies one step past a branch it crossed.

    A half that crosses a branch ends on its first point past it (_half); that last step
    overlaps the crossed branch's far side, where the curve goes on as another piece. A
    later seed's half coming from there ran into that step and merged into fb, its points
    dropped: the piece beyond the crossing was lost, and the seed was attributed to a branch
    whose points do not reach it. Without the step it crosses the branch as fb did, and is
    a (bifurcated) branch of its own. Which end crossed is found again from the points
    (_meeting on each end's last chord against `earlier`, the branches fb's halves were
    measured against: the known ones and the ones found before it), so a resumed search,
    whose branches come from disk, trims alike."""
    ok = np.asarray(fb.converged, bool)
    keep = ok.copy()
    idx = np.flatnonzero(ok)
    if len(idx) >= 3:  # an end of a two-point branch is its start
        for end, inner in ((0, idx[1]), (len(ok) - 1, idx[-2])):
            if not ok[end]:  # a half that failed did not meet anything
                continue
            prev, p = (SimpleNamespace(x=fb.x[j], omega=float(fb.omega[j])) for j in (inner, end))
            met = _meeting(residual, prev, p, earlier, opts, tol, search_options, solver)
            if met is not None and not met[2]:
                keep[end] = False
    return KnownBranch.of(fb.omega, fb.x, label, keep)


#: points at the end of a closed half among which its start must lie (_back_at_start)
_TAIL = 5


def _back_at_start(residual, half: Branch, options: "SearchOptions", solver) -> bool:
    """Whether a half that ended as a closed loop (eq. (26)-(27)) came back onto its start,
    travelling the way it left: the start lies on the polyline of its last _TAIL points
    (lies_on: within the tolerance, or Newton at the start's omega from their curve lands
    on it; the closing step, which crosses the start's omega, is among them, and a loop
    that closed on its own path just past the start a step later), and the last chord runs
    along the first one (positive scalar product in the scaled metric). Eq. (27) measures
    the return relative to |x|: a coil whose next turn passes near the start (many
    tolerances off it when |x| is large) passes it, and the branch goes on."""
    ok = np.asarray(half.converged, bool)
    w, x = half.omega[ok], half.x[ok]
    if len(w) < 3:
        return False
    co = options.continuation
    lo = max(1, len(w) - _TAIL)  # never the start itself
    tail = KnownBranch.of(w[lo:], x[lo:], "its end")
    if lies_on(residual, x[0], float(w[0]), [tail], options, solver) < 0:
        return False
    a = np.append((x[-1] - x[-2]) / co.x_scale, (w[-1] - w[-2]) / co.omega_scale)
    b = np.append((x[1] - x[0]) / co.x_scale, (w[1] - w[0]) / co.omega_scale)
    return float(a @ b) > 0.0


#: A branch-phase worker's queues to the other half, by the direction of the half that posts
#: to it (_init_branch_worker)
_HALF_QUEUES: dict = {}


def _init_branch_worker(queues: dict) -> None:
    """Pool initializer of the branch phase: one BLAS thread, freed memory kept for reuse
    (keep_freed_memory), and the two queues the halves of a branch talk through (a
    multiprocessing queue reaches a worker only as it starts). A worker's exit does not wait
    for what it posted to be read (after a failure the other half reads no more)."""
    limit_blas_threads()
    keep_freed_memory()
    for q in queues.values():
        q.cancel_join_thread()
    _HALF_QUEUES.clear()
    _HALF_QUEUES.update(queues)


def _run_half(factory, x0, w0, direction: int, opts: ContinuationOptions, others, tol: float,
              search_options: SearchOptions | None = None, other=None):
    """_half with a fresh (residual, solver) from factory, in this process or a worker: a
    half branch does not depend on which process ran it nor on what that process solved
    before (a kept preconditioner would change its last digits). other: an _OtherHalf, or the
    tag of the branch in a pool's worker (its queues: _HALF_QUEUES). -> (Branch, joined, CPU s)."""
    t = time.process_time()
    if other is not None and not isinstance(other, _OtherHalf):
        other = _OtherHalf(_HALF_QUEUES[direction], _HALF_QUEUES[-direction], other)
    residual, solver = factory()
    br, joined = _half(residual, solver, x0, w0, direction, opts, others, tol, search_options, other)
    return br, joined, time.process_time() - t


def _both_halves(args, tag, pool=None):
    """The two halves of a branch from _run_half's args (direction +1 in them), at the same
    time: on the pool's two processes, or on two threads of this one taking turns.
    -> ((Branch, joined, CPU s) of the + half, the same of the - half)."""
    minus = args[:3] + (-1,) + args[4:]
    if pool is not None:
        futures = [pool.submit(_run_half, *args, other=tag), pool.submit(_run_half, *minus, other=tag)]
        concurrent.futures.wait(futures)
        # the error of the half that failed, not the other's _OtherHalfFailed
        for f in sorted(futures, key=lambda f: isinstance(f.exception(), _OtherHalfFailed)):
            if f.exception() is not None:
                raise f.exception()
        return tuple(f.result() for f in futures)
    # the + half in this thread: an interrupt (Ctrl-C) reaches it, and the - half stops at its next point
    q_plus, q_minus, baton = queue.SimpleQueue(), queue.SimpleQueue(), threading.Lock()
    with concurrent.futures.ThreadPoolExecutor(1) as thread:
        f_minus = thread.submit(_run_half, *minus, other=_OtherHalf(q_minus, q_plus, tag, baton))
        try:
            plus = _run_half(*args, other=_OtherHalf(q_plus, q_minus, tag, baton))
        except _OtherHalfFailed:
            f_minus.result()  # raises the - half's error
            raise
        return plus, f_minus.result()


def _chord_cos(points, b: KnownBranch, xn, wn, opts) -> tuple[float, int]:
    """(cos, k): the cosine (scaled metric) between the half's last chord (points[-2] to
    points[-1]) and b's segment k (points k, k + 1) on which (xn, wn) lies; nan when either
    has zero length. The segment (xn, wn) lies on, not the one after the nearest vertex: past
    a segment's middle that is the next one, which at a fold runs the other way."""
    sx, sw = opts.x_scale, opts.omega_scale
    a = np.append((points[-1].x - points[-2].x) / sx, (points[-1].omega - points[-2].omega) / sw)
    k = nearest_segment(xn, wn, b, sx, sw)[3]
    g = np.append((b.x[k + 1] - b.x[k]) / sx, (b.omega[k + 1] - b.omega[k]) / sw)
    na, ng = np.linalg.norm(a), np.linalg.norm(g)
    return (float(a @ g) / (na * ng) if na > 0 and ng > 0 else np.nan), k


def _parallel(points, b: KnownBranch, xn, wn, opts) -> bool:
    """Whether the half branch's last secant runs along b's segment near (xn, wn)."""
    if len(points) < 2 or len(b.omega) < 2:
        return True
    cos = _chord_cos(points, b, xn, wn, opts)[0]
    return bool(np.isnan(cos) or abs(cos) > _PARALLEL_COS)


def _merge(first: Branch, second: Branch | None):
    """One branch from the halves: the second reversed, then the first (shared start)."""
    if second is None or len(second) <= 1:
        return first.omega, first.x, first.converged
    return (np.concatenate([second.omega[::-1], first.omega[1:]]),
            np.concatenate([second.x[::-1], first.x[1:]]),
            np.concatenate([second.converged[::-1], first.converged[1:]]))


#: fewest points per chunk when a branch is described on two processes
_MIN_CHUNK = 16

#: most branches being described while the search goes on: their descriptions share the
#: cores with the next branches' halves, and an interrupt loses them (they are saved once
#: described)
_UNDESCRIBED = 2


def _run_describe(describe, omega, x):
    t = time.process_time()
    return dict(describe(omega, x)), time.process_time() - t


class _Description:
    """describe's answer for one branch, computed here now or submitted to a pool: result() ->
    (describe's dict, CPU s spent in worker processes). A long branch is described in two
    chunks sharing one point k, where Omega runs monotonically through k-1, k, k+1: what
    describe finds between two neighbours (e.g. a stability change) lies in one chunk, and
    no turn in Omega is cut. With a pool the chunks run there at once, else one after the
    other here: the same chunks either way, so that the result does not depend on the worker
    count (a describe that schedules its work along the points, as the stability monitor
    does, would otherwise analyse other points). The chunks' per-point arrays are joined (k
    once) and their tables concatenated, the second's `index` shifted by k."""

    def __init__(self, describe, omega: np.ndarray, x: np.ndarray, pool=None):
        self.n = n = len(omega)
        self.k = None
        d = np.diff(omega)
        mid = n // 2
        if n >= 2 * _MIN_CHUNK:
            self.k = next((j for r in range(n // 2 - _MIN_CHUNK) for j in (mid - r, mid + r)
                           if d[j - 1] * d[j] > 0), None)
        k = self.k
        chunks = [slice(None)] if k is None else [slice(None, k + 1), slice(k, None)]
        if pool is not None:
            try:
                pickle.dumps(describe)
            except (pickle.PicklingError, AttributeError, TypeError):  # e.g. a closure: described here
                pool = None
        if pool is None:  # CPU spent in this process: counted by the caller's clock
            self.parts = [(dict(describe(omega[c], x[c])), 0.0) for c in chunks]
        else:
            self.parts = [pool.submit(_run_describe, describe, omega[c], x[c]) for c in chunks]

    def done(self) -> bool:
        return all(not isinstance(p, concurrent.futures.Future) or p.done() for p in self.parts)

    def result(self) -> tuple[dict, float]:
        parts = [p.result() if isinstance(p, concurrent.futures.Future) else p for p in self.parts]
        if len(parts) == 1:
            return parts[0]
        (a, ca), (b, cb) = parts
        a, b = dict(a), dict(b)
        ta, tb = a.pop("tables", {}), _reindexed(b.pop("tables", {}), np.arange(self.k, self.n))
        out = {name: np.concatenate([np.asarray(a[name]), np.asarray(b[name])[1:]]) for name in a}
        tables = {}
        for name in list(ta) + [t for t in tb if t not in ta]:
            pieces = [t[name] for t in (ta, tb) if name in t]
            tables[name] = {c: (np.concatenate([np.asarray(q[c][0]) for q in pieces]), pieces[0][c][1])
                            for c in pieces[0]}
        if tables:
            out["tables"] = tables
        return out, ca + cb


def _full_extras(extras: dict, ok: np.ndarray) -> dict:
    """describe's dict of a branch's converged points (ok: (m,) bool) on all its m points:
    per-point arrays filled with NOT_DESCRIBED's value where ok is False, the tables'
    `index` mapped to the branch's points."""
    extras = dict(extras)
    tables = _reindexed(extras.pop("tables", {}), np.flatnonzero(ok))
    full = {}
    for name, v in extras.items():
        v = np.asarray(v)
        shape = (len(ok),) + v.shape[1:]
        fill = NOT_DESCRIBED.get(v.dtype.kind, np.nan)
        arr = np.full(shape, fill, dtype=object if v.dtype.kind in "OU" else
                      v.dtype if v.dtype.kind in "biuc" else float)
        arr[ok] = v
        full[name] = arr
    if tables:
        full["tables"] = tables
    return full


def _reindexed(tables: dict, positions: np.ndarray) -> dict:
    """describe's tables ({name: {column: (array, unit)}}) with their `index` column (a
    position among the described, converged points) mapped to the branch's points."""
    out = {}
    for name, cols in tables.items():
        cols = dict(cols)
        if "index" in cols:
            idx, unit = cols["index"]
            cols["index"] = (positions[np.asarray(idx, dtype=np.int64)], unit)
        out[name] = cols
    return out


def _closes(residual, half: Branch, options: SearchOptions, solver) -> bool:
    """Whether the half ended as a closed loop that came back onto its start (_back_at_start,
    with a fresh copy of the solver: the answer must not depend on what it solved before)."""
    return half.status.startswith(STATUS_CLOSED_LOOP) and \
        _back_at_start(residual, half, options, copy.deepcopy(solver))


def _at_bound(status: str) -> bool:
    return status.startswith(STATUS_OMEGA_MIN) or status.startswith(STATUS_OMEGA_MAX)


#: the non-symmetric part (relative 2-norm, the residual's unknowns) above which an orbit breaks
#: the residual's symmetry: the symmetric orbits of the NFRCs keep theirs at 1e-8 and below,
#: those without it at percents (hbm.stability.hill.harmonic_period's threshold)
BROKEN_RTOL = 1e-4

#: the note a branch's status gets when it merges into the primary without its symmetry
LEAVES_SYMMETRY = "bifurcated: it leaves the symmetry of the primary it merges into"


def asymmetry(residual, x: np.ndarray) -> float:
    """The largest non-symmetric part over the orbits x ((m, n) in the residual's unknowns):
    max over them of |x - P x| / |x|, P x the mean of x and all its images (the projection on
    the orbits every symmetry of the residual leaves unchanged), -; 0 without images."""
    worst = 0.0
    for xi in np.atleast_2d(x):
        xi_images = images(residual, xi)
        if not xi_images:
            return 0.0
        full = (xi + sum(xi_images)) / (len(xi_images) + 1)  # the whole group's mean
        worst = max(worst, float(np.linalg.norm(xi - full) / max(np.linalg.norm(xi), 1e-300)))
    return worst


#: how much smaller than its last point's a correction's non-symmetric part must be for the
#: correction to be a landing on the symmetric orbits (_keeps_off_symmetric_orbits): along a
#: branch that runs into a pitchfork the part falls as the square root of the distance, a
#: hundredth of it over one step only when the step is 10^4 times the distance left
_LANDING_FALL = 1e-2


def _keeps_off_symmetric_orbits(residual):
    """continue_branch's `admit` for the search's halves: refuses a correction from an orbit
    that breaks the residual's symmetry (asymmetry over BROKEN_RTOL) onto one that keeps it
    (asymmetry at most BROKEN_RTOL and _LANDING_FALL times the last point's). A branch reaches
    the symmetric orbits only at a pitchfork, where its non-symmetric part goes to zero
    continuously; a corrector that lands on them from a point clearly off them has crossed a
    gap narrower than its step (a broken branch folding a few percent of the orbit short of
    the primary would run onto it and be taken for one of its pitchforks). The refusal halves
    the step; at the step floor the landing is admitted."""

    def admit(last, x, omega):
        before = asymmetry(residual, last.x)
        if not before > BROKEN_RTOL:
            return None
        after = asymmetry(residual, x)
        if after <= BROKEN_RTOL and after <= _LANDING_FALL * before:
            return (f"correction landed on an orbit with the symmetry (non-symmetric part {after:.1e}) "
                    f"from one without it ({before:.1e})")
        return None

    return admit


def _merges_into_primary(halves, primaries: int) -> bool:
    """Whether a half ended running along a primary NFRC (its join is a merge, known index
    -1 - k for k < primaries)."""
    return any(j is not None and -1 - primaries < j[1] < 0 and j[2] for _, j in halves)


def _classify(halves, omega, x, bifurcation_points, options: SearchOptions, primaries: int, residual=None,
              back=None, broken: float = 0.0):
    """(kind, closed) of a merged branch from its halves [(Branch, joined)]; the known
    branches of index < primaries are the primary NFRC(s). back: per half, whether its
    "closed loop" came back onto its start (_back_at_start) or met the other half
    (STATUS_HALVES_MET); None: every one did.

    A "closed loop" of eq. (26)-(27) is back within d_min of the start relative to |x|,
    which one turn of a coil later can be: it closes the branch only when it came back onto
    the start (back), and when no half reached the range's bound (a loop through the seed
    cannot leave the range). Otherwise the branch is not closed, and detached unless it
    meets another branch or both its ends lie inside the range. A branch through a located
    bifurcation point, or through one of its images (residual's `images`: the image of a
    bifurcation is one of the image branch, which is the same branch), is bifurcated.
    broken: the branch's asymmetry (its converged points'). A branch merging into the
    primary is a piece of it only when it keeps its symmetry (broken <= BROKEN_RTOL): one
    whose orbits break it ran onto the primary by a corrector landing on the symmetric
    orbits (the part without the symmetry is then zero at a point, and _symmetric_crossing
    sees nothing turn over), which _keeps_off_symmetric_orbits lets through only from a
    point already near them or at the step floor: bifurcated, the kind the search can tell
    from its points."""
    back = [True] * len(halves) if back is None else back
    closed = any(br.status.startswith(STATUS_CLOSED_LOOP) and ok for (br, _), ok in zip(halves, back)) \
        and not any(_at_bound(br.status) for br, _ in halves)
    joined = [j for _, j in halves if j is not None]
    if _merges_into_primary(halves, primaries):
        return ("primary" if broken <= BROKEN_RTOL else "bifurcated"), closed
    if any(not j[2] or j[1] < 0 for j in joined):  # crosses a branch, or merges into a known non-primary one
        return "bifurcated", closed
    if bifurcation_points is not None and len(bifurcation_points.omega) and len(omega) > 1:
        b = KnownBranch.of(omega, x, "new")
        co = options.continuation
        for w, xb in zip(bifurcation_points.omega, bifurcation_points.x):
            for xq in [xb, *(images(residual, xb) if residual is not None else [])]:
                if polyline_distance(xq, w, b, co.x_scale, co.omega_scale,
                                     within=options.tolerance)[0] <= options.tolerance:
                    return "bifurcated", closed
    if closed or not any(_at_bound(br.status) for br, _ in halves):
        return "isola", closed
    return "detached", closed


#: Which kind a branch that another one joins takes: the connection to the primary first,
#: then a crossing, then an end on the range's bound (detached); isola only when neither
#: part brings any of these (an open isola that a branch reaching the bound runs into is
#: detached: its ends are no longer both inside the range).
_KIND_RANK = {"primary": 0, "bifurcated": 1, "detached": 2, "isola": 3}


#: How a branch's status names another branch it is one with (two pieces that a later
#: branch links, module doc); `connected` reads it back, so that a resumed search, whose
#: branches come from disk, knows the pieces too.
_LINKED = "one branch with branch {other} (linked by the branch from seed {seed})"
_LINKED_RE = re.compile(r"one branch with branch (\d+) \(linked by the branch from seed \d+\)")


def connected(branches) -> list[tuple[int, ...]]:
    """The branches (FoundBranch list, as a search returns them) grouped into the sets
    that are one branch: each alone, or the pieces that later branches linked (their
    statuses name each other, _LINKED), transitively; each group sorted, the groups in the
    order of their first branch."""
    parent = list(range(len(branches)))

    def root(a):
        while parent[a] != a:
            a = parent[a] = parent[parent[a]]
        return a

    for k, b in enumerate(branches):
        for u in _LINKED_RE.findall(b.status):
            if int(u) < len(branches):
                parent[max(root(k), root(int(u)))] = min(root(k), root(int(u)))
    groups: dict = {}
    for k in range(len(branches)):
        groups.setdefault(root(k), []).append(k)
    return [tuple(g) for g in sorted(groups.values())]


def _group(branches, members) -> list[int]:
    """The indices of the branches that are one branch with any of `members` (connected)."""
    return sorted({k for g in connected(branches) if set(g) & set(members) for k in g})


def _joined_kind(kinds) -> str:
    """The kind of a branch made of parts of these kinds (_KIND_RANK: the strongest connection)."""
    return min(kinds, key=lambda c: _KIND_RANK.get(c, len(_KIND_RANK)))

#: What a per-point extra holds at a point describe did not see (not converged), by numpy
#: dtype kind: NO_VALUE's, and text saying so.
NOT_DESCRIBED = {**NO_VALUE, "O": "not converged", "U": "not converged"}


def search(factory, seeds, known, options: SearchOptions, *, comm=None, corrections: Corrections | None = None,
           seed_factory=None, branches=(), bifurcation_points: KnownBranch | None = None, primaries: int | None = None,
           describe: Callable[[np.ndarray, np.ndarray], dict] | None = None,
           on_corrections: Callable[[Corrections], None] | None = None,
           on_branch: Callable[[int, FoundBranch], None] | None = None,
           on_progress: Callable[[str, int, int], None] | None = None) -> IsolaSearch:
    """The isola search (module doc).

    factory() -> (residual, LinearSolver), picklable. seeds: Seed list (all x of one size
    n). known: KnownBranch list (the primary NFRC(s)): index i of a known branch is
    reported as ON_KNOWN. options: SearchOptions (continuation's omega range = the search's).
    comm: MPI communicator (mpi4py) or None: phase 1 is shared among its ranks; phase 2
      runs on rank 0 and its result is broadcast.
    corrections, branches: what an interrupted run of the same inputs finished (resume):
      phase 1 is skipped when corrections are given; the given branches are kept as they are
      and their seeds never continued again.
    seed_factory: like factory, for phase 1 (e.g. a linear solver tuned for far-off
      starts); None: factory.
    bifurcation_points: located bifurcations of the known branches (omega (k,), x (k, n)):
      a branch through one is "bifurcated".
    primaries: the first `primaries` known branches are the primary NFRC(s) (None: all); a
      branch merging into another known one (e.g. an isola of the scene's basis, embedded
      in that of Omega / 2) is "bifurcated", not "primary".
    describe(omega (m,), x (m, n)) -> {name: (m, ...) array}: per-point data of each branch
      (of its converged points; nan or 0 elsewhere), and optionally "tables": {name:
      {column: (array, unit)}}, per-branch tables whose `index` column (a position among
      the points described) is mapped to the branch's points; kept in extras["tables"].
    on_corrections(c): called once phase 1 is done (not on resume); on_branch(index,
      branch): called as each new branch is finished (to save it); on_progress(phase,
      done, total): "seeds" or "branches".
    """
    t_wall = time.perf_counter()
    seeds = tuple(seeds)
    primaries = len(known) if primaries is None else primaries
    progress = on_progress or (lambda phase, done, total: None)
    if corrections is None:
        corrections = correct_seeds(seed_factory or factory, seeds, known, options, comm,
                                    on_progress=lambda d, t: progress("seeds", d, t))
        if on_corrections is not None and (comm is None or comm.rank == 0):
            on_corrections(corrections)
    cpu_phase1 = corrections.cpu_time

    doing = [""]  # what the phase's pool computes now: named if one of its workers dies

    def branches_phase(pool=None, describing=None):
        t_start = time.process_time()
        cpu_workers = 0.0
        residual, solver = factory()
        found = list(branches)
        owner = {}  # seed -> branch index
        for b_i, b in enumerate(found):
            for sd in b.seeds:
                owner[sd] = b_i
        cand = corrections.candidates()
        n_cont, n_pts = 0, 0
        co = options.continuation
        known_others = [(f"known branch {j} ({b.label})", -1 - j, b) for j, b in enumerate(known)]
        polys = []  # found[k]'s meeting polyline (_meeting_polyline), made once: its points never change

        def add_polyline(k):
            polys.append(_meeting_polyline(found[k], f"branch {k}", known_others + [
                (f"branch {j}", j, p) for j, p in enumerate(polys)], residual, co, options.tolerance, options,
                solver))

        for k in range(len(found)):
            add_polyline(k)
        # Branches are described (describing: their own pool, or here) while the search goes on:
        # what it decides needs a branch's points only. A branch is saved once it is described,
        # in index order, so that an interrupted run's branches on disk are a prefix of the
        # found ones, each whole; a change to one not yet saved waits for its save.
        undescribed = {}  # index -> (_Description, converged mask, whence)
        saved = [len(found)]  # found[:saved[0]] are on disk (or given)

        def save(k):
            if on_branch is not None and k < saved[0]:
                on_branch(k, found[k])

        def finish(wait: bool, upto: int | None = None):
            """Save the described branches in index order, up to `upto` (None: all); wait:
            for their descriptions, else stop at the first not done."""
            nonlocal cpu_workers
            while saved[0] < (len(found) if upto is None else upto):
                k = saved[0]
                if k in undescribed:
                    job, ok, whence = undescribed[k]
                    if not (wait or job.done()):
                        return
                    doing[0] = f"branch being described: {whence}"
                    extras, cpu_desc = job.result()
                    del undescribed[k]
                    cpu_workers += cpu_desc
                    found[k] = replace(found[k], extras=_full_extras(extras, ok),
                                       cpu_time=found[k].cpu_time + cpu_desc)
                saved[0] += 1
                save(k)
        for c_i, i in enumerate(cand):
            finish(wait=False)
            progress("branches", c_i, len(cand))
            i = int(i)
            if i in owner:
                continue
            x0, w0 = corrections.x[i], float(seeds[i].omega)
            # a fresh solver, as for the seeds: the answer must not depend on the candidates
            # before (a resumed search has not solved them)
            k = lies_on_any(residual, x0, w0, polys, options, copy.deepcopy(solver))
            if k >= 0:
                owner[i] = k
                found[k] = replace(found[k], seeds=found[k].seeds + (i,))
                save(k)  # saved again: a resumed search must not continue i
                continue
            t0 = time.process_time()
            others = known_others + [(f"branch {j}", j, p) for j, p in enumerate(polys)]
            args = (factory, x0, w0, +1, co, others, options.tolerance, options)
            doing[0] = f"branch being continued: from seed {i} at {w0:g} rad/s"
            # both halves at once, until they meet (a closed loop) or each ends otherwise
            (first, j1, c1), (second, j2, c2) = _both_halves(args, i, pool)
            cpu_half = c1 + c2
            if pool is not None:
                cpu_workers += cpu_half
            met = [br.status == STATUS_HALVES_MET for br in (first, second)]
            n_computed = len(first) + len(second) - 1
            if met[0]:  # the halves overrun the place they meet: the overlap is kept once, on the half that met
                second = _trimmed(first, second, co, options.tolerance)
            elif met[1]:
                first = _trimmed(second, first, co, options.tolerance)
            halves = [(first, j1)]
            # a "closed loop" of eq. (26)-(27) that did not come back onto the start (a coil's
            # next turn) is no loop: the branch goes on the other way
            back = [met[0] or _closes(residual, first, options, solver)]
            if any(met) or (not back[0] and first.converged[0]):
                halves.append((second, j2))
                back.append(met[1] or _closes(residual, second, options, solver))
            else:  # the + half went round a loop back onto the start by itself: the - half repeats it
                second = None
            n_cont += 1
            computed = n_computed if any(met) else len(first) + (len(second) - 1 if second is not None else 0)
            n_pts += computed
            merged_into = [j[1] for _, j in halves if j is not None and j[1] >= 0 and j[2]]
            omega, x, conv = _merge(first, second)
            broken = asymmetry(residual, x[np.asarray(conv, bool)]) if _merges_into_primary(halves, primaries) else 0.0
            kind, closed = _classify(halves, omega, x, bifurcation_points, options, primaries, residual, back, broken)
            for k in sorted({j[1] for _, j in halves if j is not None and j[1] >= 0 and not j[2]}):
                # a crossing is a branch point of both branches: the one crossed is bifurcated
                # too, whichever of the two was found first, and so are the pieces it is one
                # branch with
                for t in _group(found, [k]):
                    old = found[t]
                    if _KIND_RANK["bifurcated"] < _KIND_RANK.get(old.kind, 2):
                        through = f" (through branch {k})" if t != k else ""
                        found[t] = replace(old, kind="bifurcated",
                                           status=f"{old.status}; crossed by the branch from seed {i}{through}")
                        save(t)
            if merged_into:  # part of a branch found before: its seeds go there, and its other
                k = merged_into[0]  # end's connection (to the primary, a crossing, the range's bound) too
                targets = list(dict.fromkeys(merged_into))  # its halves may link two branches found before
                # the whole: the targets and the pieces each is already one branch with
                whole = _group(found, targets)
                new_kind = _joined_kind([found[t].kind for t in whole] + [kind])
                # a closed loop stays one only when this branch is a stretch of it (every half ran
                # into it): else the set it belongs to now reaches beyond the loop
                stretch = len(whole) == 1 and all(j is not None and j[2] and j[1] == k for _, j in halves)
                changed = []
                for t in whole:
                    old = found[t]
                    note = ""
                    if new_kind != old.kind and t == k:
                        note = f"; joined by the branch from seed {i}: {kind}"
                    elif new_kind != old.kind and t not in targets:  # a piece linked to a target before
                        note = f"; {new_kind}: the branch it is one with was joined by the branch from seed {i}"
                    if t in targets:
                        note += "".join("; " + _LINKED.format(other=u, seed=i) for u in targets if u != t)
                    if old.closed and not stretch:
                        note += f"; not a closed loop as a whole: the branch from seed {i} runs into it"
                    closed_t = old.closed and stretch
                    if new_kind != old.kind or closed_t != old.closed or note:
                        found[t] = replace(old, kind=new_kind, closed=closed_t, status=old.status + note)
                        changed.append(t)
                owner[i] = k
                found[k] = replace(found[k], seeds=found[k].seeds + (i,),
                                   n_points_computed=found[k].n_points_computed + computed)
                for t in sorted(set(changed) | {k}):
                    save(t)
                continue
            status = "; ".join(f"{'+' if d > 0 else '-'}: {br.status}" for d, (br, _) in zip((1, -1), halves))
            if broken > BROKEN_RTOL:
                status += f"; {LEAVES_SYMMETRY} (its part without it up to {broken:.2g} of the orbit)"
            for d, (br, _), onto in zip((1, -1), halves, back):
                if br.status.startswith(STATUS_CLOSED_LOOP) and not closed:
                    why = ([] if onto else ["it came back near its start, not onto it"]) + \
                          (["the other half left the omega range"] if any(_at_bound(b.status) for b, _ in halves)
                           else [])
                    status += f"; not a closed loop ({'+' if d > 0 else '-'}): {' and '.join(why)}"
            ok = np.asarray(conv, bool)
            fb = FoundBranch(omega=omega, x=x, converged=conv, kind=kind, closed=closed, status=status, start=i,
                             seeds=(i,), extras={}, n_points_computed=computed,
                             cpu_time=time.process_time() - t0 + (cpu_half if pool is not None else 0.0))
            found.append(fb)
            add_polyline(len(found) - 1)
            owner[i] = len(found) - 1
            if describe is not None and ok.any():
                t1 = time.process_time()
                job = _Description(describe, omega[ok], x[ok], describing)
                # described here (no pool, or a describe that does not pickle): this process's clock
                cpu_here = time.process_time() - t1
                found[-1] = replace(found[-1], cpu_time=found[-1].cpu_time + cpu_here)
                undescribed[len(found) - 1] = (job, ok, f"from seed {i} at {w0:g} rad/s")
            save(len(found) - 1)
            finish(wait=False)
            while len(undescribed) > _UNDESCRIBED:
                finish(wait=True, upto=min(undescribed) + 1)
        finish(wait=True)
        progress("branches", len(cand), len(cand))
        return found, owner, n_cont, n_pts, time.process_time() - t_start + cpu_workers

    if comm is None:
        workers = min(options.workers or len(os.sched_getaffinity(0)), 2)
        if workers < 2 or not len(corrections.candidates()):
            found, owner, n_cont, n_pts, cpu2 = branches_phase()
        else:  # the two halves of each branch on two processes (fork or spawn: see correct_seeds)
            ctx = process_context()
            queues = {+1: ctx.Queue(), -1: ctx.Queue()}
            # and the branches' descriptions on two more, beside the next branches' halves: they
            # fill the time a half waits for the other or runs alone
            with reported_deaths("the isola search", lambda: doing[0]), concurrent.futures.ProcessPoolExecutor(
                    2, mp_context=ctx, initializer=_init_branch_worker, initargs=(queues,)) as pool, \
                    concurrent.futures.ProcessPoolExecutor(2, mp_context=ctx, initializer=_init_branch_worker,
                                                           initargs=({},)) as describing:
                try:
                    found, owner, n_cont, n_pts, cpu2 = branches_phase(pool, describing)
                except BaseException:  # an interrupt, an error: the descriptions not started are not wanted
                    describing.shutdown(wait=False, cancel_futures=True)
                    raise
    else:  # rank 0 continues, the others wait (idle, not spinning a core) for its branches
        found, owner, n_cont, n_pts, cpu2 = on_root(comm, branches_phase, "the isola search's continuation")
    seed_branch = np.full(len(seeds), NOT_CONVERGED, np.int64)
    c = corrections
    for i in range(len(seeds)):
        if not c.converged[i]:
            continue
        if c.on_known[i] >= 0:
            seed_branch[i] = ON_KNOWN
        elif c.same_as[i] >= 0:
            rep = int(c.same_as[i])
            seed_branch[i] = ON_KNOWN if c.on_known[rep] >= 0 else owner.get(rep, NOT_CONVERGED)
        else:
            seed_branch[i] = owner.get(i, NOT_CONVERGED)
    for i in range(len(seeds)):  # duplicates join their representative's branch's seeds
        k = int(seed_branch[i])
        if k >= 0 and i not in found[k].seeds:
            found[k] = replace(found[k], seeds=tuple(sorted(found[k].seeds + (i,))))
    return IsolaSearch(seeds=seeds, corrections=c, branches=tuple(found), seed_branch=seed_branch,
                       n_continued=n_cont, n_points_computed=n_pts, cpu_time=cpu_phase1 + cpu2,
                       wall_time=time.perf_counter() - t_wall)
