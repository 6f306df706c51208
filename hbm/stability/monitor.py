"""Stability of every point of a branch, and its bifurcations, computed as the branch grows.

A Floquet analysis (hbm.stability.spectrum.orbit_spectrum: shift-invert Arnoldi on Hill's
problem, ~0.13 s at N_h = 40 on the coarse rotor 67 ROM) costs 3 to 4 continuation
points, so not every point is analysed. The monitor analyses a point when the stability
may have changed since the last analysed one, and infers the others:

- the branch turned back in Omega (a fold: one real multiplier crosses +1 there);
- `gap` points have passed since the last analysis. After each analysis the multipliers
  are paired with the previous analysis' (bifurcation.pair_multipliers); each pair's
  speed d log|mu| / ds along the arc length gives the arc length it needs to reach the
  unit circle (multipliers moving away from it are not counted), and the next analysis
  comes after a quarter of the smallest of these (StabilityOptions.reach_fraction), in points
  (at most max_gap; 1 after a change of the count or an unpaired multiplier within
  `margin` of the circle). The lightly damped modes' multipliers sit at |mu| ~ 0.95-0.99
  over the minimal period, so a fixed margin would analyse every point;
- when two consecutive analyses disagree on the number of unstable multipliers (other
  than by multipliers far from the unit circle where both are unstable: see
  StabilityMonitor), the point half-way between them is analysed, and so on (bisection on the stored points), until
  the change lies between two neighbouring points. There the crossing multipliers are
  paired (bifurcation.crossings), classified on the minimal period, and located by linear
  interpolation of log|mu| in arc length between the two points, or with
  StabilityOptions.refine_steps by points solved and analysed between them
  (hbm.stability.refinement) (folds: at the vertex of the parabola through the three
  points around the turn in Omega). Where none pairs across,
  or the paired ones do not add up to the count change, the parities of the real
  multipliers beyond -1 and +1 give the kind where they can, and it is guessed where they
  cannot (Bifurcation.kind_from).

Points between two analyses with the same count, and no fold between them, get that count
(`stability_analysed` False). What this can miss: an even number of crossings between two
analyses gap points apart (e.g. a Neimark-Sacker pair leaving and coming back); the gap
control keeps such stretches short where multipliers are near the unit circle.

An analysis without a verdict (FloquetSpectrum.decided: ARPACK stopped short of the
eigenvalues asked for after orbit_spectrum's retries with wider windows, or no multiplier
is left) gives its point n_unstable -1 and stable False, stability_analysed True, the
reason in StabilityMonitor.undecided. Such a point is no reference: nothing is inferred
from it, no crossing is located against it, bisection passes it by. The next point is
analysed and compared with the last analysed point that has a verdict, the stretch
between them resolved as usual (a crossing located there has the undecided points inside
its bracket); when more than max_gap + 1 points wait past that point without one, the
chain is cut: the points without a count are handed on with n_unstable -1 and the next
analysis starts afresh.

The points are handed on (`on_point`) only once their stability is final: the last
analysed point is held back until the next analysis has been compared with it, because
that comparison may widen its window (below) and change its count; and the points between
it and the analysed point before it too, because such a change moves the stability change
to between those two, where it is then bisected and located. Up to 2 max_gap points are
held back (2 max_gap + 2 after an analysis without a verdict).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace

import numpy as np

from hbm.continuation.newton import NewtonOptions
from hbm.linalg.errors import SingularMatrixError
from hbm.options import HbmOptions, check_option
from hbm.stability.bifurcation import (BRANCH_POINT, CROSSING, FOLD, GUESS, NEIMARK_SACKER, PARITY, PERIOD_DOUBLING,
                                      UNCLASSIFIED, Bifurcation, classify, crossings, lone_real, pair_multipliers,
                                      parabola_vertex, real_parities, upper_half)
from hbm.stability.hill import harmonic_period
from hbm.stability.refinement import Refinement, refine_crossing, solve_between, tracked_log_modulus
from hbm.stability.spectrum import MAX_EIG, FloquetSpectrum, orbit_spectrum

#: a neighbour's unstable multiplier of modulus above ceiling^WIDEN_FRACTION may lie beyond a
#: spectrum's window: the missed multipliers on rotor 67 had log|mu| 1.01-1.24 times the
#: ceilings that missed them, and where they were found they set the window's edge themselves
#: (log|mu| = log ceiling); 0.8 leaves room for their growth between two analyses.
WIDEN_FRACTION = 0.8


@dataclass(frozen=True)
class StabilityOptions:
    """Settings of the stability monitor.

    n_eig: Hill eigenvalues computed per analysis (see arnoldi_spectrum). max_gap: most
    points between two analyses (1: every point). margin: |log|mu|| under which an unpaired
    multiplier (no counterpart at the previous analysis) counts as near the unit circle and
    resets the gap to 1 (0.02: |mu| within 2 %). n_leading: leading multiplier moduli stored per point. window: |log|mu|| within
    which multipliers are paired across two points to find a crossing (3: |mu| in
    [0.05, 20]; a stiff contact's multipliers move by factors of 10 between points).
    reach_fraction: the next analysis comes after this fraction of the arc length the
    fastest multiplier needs to reach the unit circle at its present speed. Multipliers
    accelerate, so a gap of half the reach lets a short stretch of the other stability
    lie between two analyses that agree: on the coarse rotor 67 NFRCs (N_h = 40), against
    every point analysed, 0.5 missed 20 of 140 crossings and gave 8 of 1625 points the
    wrong stable flag; 0.25 misses 12 and gives 3, for 1.27 to 1.30 times the analyses
    (benchmarks/bench_stability.py --schedule --replay). Which pairs are missed moves with
    the rule and with round-off; only max_gap = 1 finds them all.
    turn_tol: a change of direction in Omega is a turn (a fold) only when Omega moves by
    more than this fraction of itself on at least one side of the middle point. A branch
    that crawls at the continuation's step floor (at a corner the rule of
    ContinuationOptions.corner_turns did not take) moves along x at an Omega fixed to the
    corrector's round-off, ~1e-9 of Omega, and that round-off changes sign every other
    point: a "fold" at every other point, and an analysis at each (22 on a crawl of rotor
    67's coarse DLFT doubled branch). One side is enough: the point after a real turn can
    land next to the vertex (RL NFRC at 1478.3 rad/s: -0.48 then +4.6e-6 rad/s), and
    requiring both lost that fold. A crawl's first or last step can still make one turn.
    refine_steps: points solved and analysed per paired crossing to locate it finer than the
    stored points (hbm.stability.refinement; 0: linear interpolation of log|mu| between
    them). Not a fold (the parabola's vertex locates it), nor a crossing next to a turn in
    Omega (between two points around a turn the branch need not cross each hyperplane of
    the refinement once). Each costs a Newton solve and an analysis. refine_rtol: the
    refinement stops once the two points around the crossing are within this fraction of
    Omega (1e-5: 0.013 rad/s at 1300 rad/s). refine_tolerance: Newton's test on ||R|| for
    those points (the scene's [hbm] tolerance, as for the branch's own points).
    """

    n_eig: int = 40
    max_gap: int = HbmOptions.stability_max_gap  # the scene's default ([hbm] stability_max_gap)
    margin: float = 0.02
    n_leading: int = 4
    window: float = 3.0
    reach_fraction: float = 0.25
    turn_tol: float = 1e-7
    refine_steps: int = HbmOptions.refine_bifurcations  # the scene's default ([hbm] refine_bifurcations)
    refine_rtol: float = 1e-5
    refine_tolerance: float = HbmOptions.tolerance

    @classmethod
    def of(cls, hbm: HbmOptions) -> "StabilityOptions":
        """The settings a scene's [hbm] keys give (stability_max_gap, refine_bifurcations,
        tolerance)."""
        return cls(max_gap=hbm.stability_max_gap, refine_steps=hbm.refine_bifurcations,
                   refine_tolerance=hbm.tolerance)

    def __post_init__(self):
        check_option("n_eig", self.n_eig, 2, integer=True)
        check_option("max_gap", self.max_gap, 1, integer=True)
        check_option("margin", self.margin, 0)
        check_option("n_leading", self.n_leading, 1, integer=True)
        check_option("window", self.window, 0, low_open=True)
        check_option("reach_fraction", self.reach_fraction, 0, 1, low_open=True)
        check_option("turn_tol", self.turn_tol, 0)
        check_option("refine_steps", self.refine_steps, 0, integer=True, note="0: no refinement")
        check_option("refine_rtol", self.refine_rtol, 0, low_open=True)
        check_option("refine_tolerance", self.refine_tolerance, 0, low_open=True)


@dataclass(eq=False)
class _Entry:
    index: int
    omega: float
    s: float  # cumulative scaled arc length
    amplitude: float
    x: np.ndarray
    payload: tuple  # what to hand on: (point, extras)
    spectrum: FloquetSpectrum | None = None
    g: int = 1
    n_unstable: int | None = None
    n_eig: int = 0  # Hill eigenvalues of a widened analysis (0: the default window)
    cpu: float = 0.0  # CPU time of the analyses made at this point, s

    @property
    def undecided(self) -> bool:
        """Analysed, without a verdict (FloquetSpectrum.decided)."""
        return self.spectrum is not None and not self.spectrum.decided


@dataclass
class StabilityMonitor:
    """Feed converged branch points with push(); it returns the points whose stability is
    now known, their extras completed with:

    stable (bool), n_unstable (int): multipliers outside the unit circle (minimal period);
    -1 (and stable False) where no verdict is known: an analysis at the point that gave
    none (the reason in `undecided`), or a point between analyses with none;
    stability_note (str): why n_unstable is -1 ("" where it is not): the analysis' reason
    (FloquetSpectrum.undecided_reason) or NOT_INFERRED;
    stability_analysed (bool): computed at this point (else inferred, see the module doc);
    stability_widened (bool): analysed again with a wider window (below);
    stability_cpu_time (float): CPU time of the analyses made at this point, s (0 when
    inferred; where the cost of stability goes along a branch);
    leading_multipliers ((n_leading,) float): the largest |mu|, nan when not analysed;
    period_ratio (int): g, minimal period T / g.
    finish() hands on the rest. bifurcations: the located ones, in the order found.
    undecided: {index: why} of the points whose analysis gave no verdict (module doc).
    analyse(x, omega) -> (FloquetSpectrum, g) is the Floquet analysis of one point;
    widen(x, omega, n_eig) -> the same with n_eig Hill eigenvalues (None: never widened);
    refine(xa, wa, xb, wb, f) -> (x, omega, le_amplitude), or a str saying why not, is the
    branch's point between two points (hbm.stability.refinement.solve_between), used with
    options.refine_steps > 0 (None: crossings are interpolated between stored points).

    Widening: an analysis lists every multiplier below its modulus_ceiling only (see
    hbm.stability.spectrum), so a multiplier that grows past it drops out and the count
    falls as if it had come back inside the unit circle. Where two analysed points disagree
    on the count, the one with fewer has none unstable, and its ceiling is within
    WIDEN_FRACTION (in log) of the other's largest unstable multiplier, it is analysed again
    with twice the eigenvalues (up to spectrum.MAX_EIG) before the change is bisected. On
    the coarse rotor 67 NFRCs a multiplier mu ~ -21 drops out at 1335-1341 rad/s (DLFT) and
    1331-1340 rad/s (RL): seven points called stable and a spurious period-doubling pair on
    each, without this.

    Between two unstable points the stable flag is not at stake, and a count that differs
    only by multipliers far from the unit circle is not a crossing of it: a multiplier
    leaving the window, or one of |mu| ~ 1e5 that one analysis lists and the next does not.
    When the two counts agree on the multipliers with log|mu| below the pairing window
    (options.window, where bifurcation.crossings can pair a crossing) and below
    WIDEN_FRACTION of the smaller ceiling, neither point is widened and nothing is
    bisected; the points between them get the first one's count. On a strongly unstable
    period-doubled branch of rotor 67 (|mu| up to 3e9), 200 points analysed by the earlier
    rule took 100 analyses, 91 of them widened, for 7 times the CPU, and recorded 39
    "crossings" of which 36 had |mu| of 2e4 to 4e8 on their unstable side
    (benchmarks/bench_branch_stability.py --monitor --span). n_unstable is then the count
    within the window, and a crossing whose multiplier is already past the pairing window
    at the next analysis, between two unstable points, is not located.
    """

    analyse: object
    widen: object = None
    refine: object = None
    options: StabilityOptions = field(default_factory=StabilityOptions)
    bifurcations: list = field(default_factory=list)
    n_analyses: int = 0
    #: analyses by what asked for them (they sum to n_analyses): "first", "turn" (Omega
    #: turned), "next point" (the gap rule gave 1: a multiplier close to the circle and moving
    #: towards it), "reach" (a longer gap from the same rule), "gap cap" (max_gap points),
    #: "last", "bisection", "widening", "after undecided" (the point after an analysis without
    #: a verdict), "refinement" (a point solved between two stored ones); "first" also counts
    #: the seeded points of a resumed branch (seed)
    causes: dict = field(default_factory=dict)
    undecided: dict = field(default_factory=dict)
    _buffer: list = field(default_factory=list)
    _last: _Entry | None = None  # last analysed point (held until the next analysis)
    _before: _Entry | None = None  # the analysed point before _last (handed on; the points between are held)
    _recent: list = field(default_factory=list)  # the last three points: (index, omega, s, amplitude)
    _counts: dict = field(default_factory=dict)  # index -> n_unstable of recent points
    _folds: list = field(default_factory=list)  # trios (f - 1, f, f + 1) around a turn in Omega
    _gap: int = 1
    _s: float = 0.0

    @classmethod
    def for_residual(cls, residual, options: StabilityOptions = StabilityOptions(), *,
                     newton: NewtonOptions | None = None, solver=None) -> "StabilityMonitor":
        """A monitor analysing points of hbm.harmonic.residual.HarmonicBalanceResidual. newton
        and solver: the refinement's Newton rule and LinearSolver (defaults: NewtonOptions with
        options.refine_tolerance, and an HbmSolver of its own, as compute_nfrc builds one: the
        continuation's keeps its preconditioner), used with options.refine_steps > 0."""
        refine = None
        if options.refine_steps:
            from hbm.harmonic.nfrc import nfrc_extras
            from hbm.harmonic.solver import HbmSolver

            nopt = newton or NewtonOptions(tol_residual=options.refine_tolerance)
            lin = solver or HbmSolver(atol=0.1 * nopt.tol_residual)

            def refine(xa, wa, xb, wb, f):
                got = solve_between(residual, xa, wa, xb, wb, f, nopt, lin)
                if isinstance(got, str):
                    return got
                return got[0], got[1], float(nfrc_extras(residual, got[0])["le_amplitude"])

        # no min_ceiling per analysis (it would double most stable ones): the monitor widens
        # where a neighbour says it must
        return cls(analyse=lambda x, w: orbit_spectrum(residual, x, w, n_eig=options.n_eig, min_ceiling=1.0),
                   widen=lambda x, w, k: orbit_spectrum(residual, x, w, n_eig=k, min_ceiling=1.0),
                   refine=refine, options=options)

    # -- feeding ----------------------------------------------------------------------------
    def push(self, point, extras: dict) -> list:
        """point: a converged hbm.continuation.branch.ContinuationPoint; extras: its dict (with
        le_amplitude and harmonics). Returns [(point, extras), ...] now complete (maybe [])."""
        self._s += float(point.step) if self._recent else 0.0
        e = _Entry(point.index, float(point.omega), self._s, float(extras.get("le_amplitude", np.nan)),
                   np.asarray(point.x), (point, extras))
        self._buffer.append(e)
        self._recent = (self._recent + [(e.index, e.omega, e.s, e.amplitude)])[-3:]
        turned = False
        if len(self._recent) == 3:
            w0, w1, w2 = (o[1] for o in self._recent)
            if (w1 - w0) * (w2 - w1) < 0 and max(abs(w1 - w0), abs(w2 - w1)) > self.options.turn_tol * abs(w1):
                self._folds.append(list(self._recent))
                turned = True
        since = e.index - self._last.index if self._last is not None else 0
        waiting = sum(q.index > self._last.index for q in self._buffer) if self._last is not None \
            else len(self._buffer)  # points not yet analysed
        if self._last is None or turned or since >= self._gap or waiting >= self.options.max_gap:
            cause = ("first" if self._last is None else "turn" if turned
                     else "after undecided" if any(q.undecided and q.index > self._last.index for q in self._buffer)
                     else "gap cap" if self._gap >= self.options.max_gap or since < self._gap
                     else "next point" if self._gap == 1 else "reach")
            return self._analyse_and_release(e, cause)
        return []

    def seed(self, points, extras: list) -> None:
        """Start after points already handed on (a resumed branch): the last one is analysed
        (the reference for the next), the last three feed the fold detection. A turn in Omega
        at the last or the one before it is seen only with the new points, and its fold needs
        their counts (_record_folds): the stored ones where extras hold them (n_unstable,
        period_ratio: the monitor's per-point keys), else from an analysis."""
        pts = list(points)[-3:]
        exs = list(extras)[-3:]
        for k, (p, ex) in enumerate(zip(pts, exs)):
            self._s += float(p.step) if self._recent else 0.0
            self._recent = (self._recent + [(p.index, float(p.omega), self._s, float(ex.get("le_amplitude", np.nan)))])[-3:]
            e = _Entry(p.index, float(p.omega), self._s, float(ex.get("le_amplitude", np.nan)), np.asarray(p.x), (p, ex))
            if k == len(pts) - 1:
                self._spectrum(e, "first")
                if not e.undecided:  # else the first new point is analysed as the first
                    self._last = e
                self._counts[e.index] = (e.n_unstable, e.g)
            elif "n_unstable" in ex and "period_ratio" in ex:
                self._counts[e.index] = (int(ex["n_unstable"]), int(ex["period_ratio"]))
            elif k == len(pts) - 2:
                self._spectrum(e, "first")
                self._counts[e.index] = (e.n_unstable, e.g)

    def finish(self) -> list:
        """Analyse the last held point and hand on everything still held."""
        if not self._buffer:
            return []
        out = self._analyse_and_release(self._buffer[-1], "last")
        out += self._release(len(self._buffer))
        self._record_folds()
        return out

    def released_bifurcations(self) -> list:
        """The located bifurcations whose two points have been handed on (a caller that
        stores points as they come stores these with them: the others may still move), less
        the branch points that a fold still waiting for its counts will take (_record_folds)."""
        first_held = self._buffer[0].index if self._buffer else math.inf
        claimed = {id(b) for trio in self._folds for b in self._claimed_by(trio)}
        return [b for b in self.bifurcations if b.index + 1 < first_held and id(b) not in claimed]

    # -- internals --------------------------------------------------------------------------
    def _spectrum(self, e: _Entry, cause: str) -> None:
        if e.spectrum is None:
            c0 = time.process_time()
            e.spectrum, e.g = self.analyse(e.x, e.omega)
            e.cpu += time.process_time() - c0
            e.n_unstable = e.spectrum.n_unstable  # -1 without a verdict
            if e.undecided:
                self.undecided[e.index] = e.spectrum.undecided_reason
            self._count(cause)

    def _count(self, cause: str) -> None:
        self.n_analyses += 1
        self.causes[cause] = self.causes.get(cause, 0) + 1

    def _analyse_and_release(self, e: _Entry, cause: str) -> list:
        """Analyse e, resolve it against the last analysed point prev, hand on the points up to
        prev (those after it are held: the next analysis may widen e's window, and then the
        stretch from prev to e is resolved again)."""
        self._spectrum(e, cause)
        prev = self._last
        if e.undecided and e is not prev:
            # no reference (module doc): the next point is analysed and compared with prev, or
            # the chain is cut
            self._gap = 1
            if prev is not None and sum(q.index > prev.index for q in self._buffer) <= self.options.max_gap + 1:
                return []
            out = self._release(len(self._buffer))
            self._last = self._before = None
            self._record_folds()
            return out
        if prev is not None and prev is not e:
            n_prev = prev.n_unstable
            self._resolve(prev, e)
            if prev.n_unstable != n_prev and self._before is not None:
                self._redo(self._before, prev)
            self._gap = self._next_gap(prev, e)
            self._before = prev
        self._last = e
        out = self._release(self._buffer.index(prev) + 1 if prev is not None and prev in self._buffer else 0)
        self._record_folds()
        return out

    def _next_gap(self, a: _Entry, b: _Entry) -> int:
        """Points until the next analysis, from the speed of the multipliers between a and b
        (the changes between them are already located: they do not shorten the gap)."""
        if b.s <= a.s or b.index <= a.index:
            return 1
        sa, sb = a.spectrum, b.spectrum
        floor = max(sa.modulus_floor, sb.modulus_floor)
        pairs = pair_multipliers(sa.multipliers, sb.multipliers, floor, self.options.window)
        paired = {j for _, j in pairs}
        lb_all = np.log(np.abs(sb.multipliers))
        up = upper_half(sb.multipliers)
        for j in range(len(lb_all)):
            if j not in paired and up[j] and abs(sb.multipliers[j]) > floor \
                    and abs(lb_all[j]) < self.options.margin:
                return 1  # a multiplier near the circle that came from nowhere: look closely
        reach = np.inf
        for i, j in pairs:
            la, lb = math.log(abs(sa.multipliers[i])), math.log(abs(sb.multipliers[j]))
            if la * lb > 0 and abs(lb) >= abs(la):
                continue  # moving away from the circle: no crossing ahead on its present course
            speed = abs(lb - la) / (b.s - a.s)
            if speed > 0:
                reach = min(reach, abs(lb) / speed)
        ds = (b.s - a.s) / (b.index - a.index)  # mean arc length per point
        if not np.isfinite(reach):
            return self.options.max_gap
        return int(np.clip(self.options.reach_fraction * reach / ds, 1, self.options.max_gap))

    def _release(self, k: int) -> list:
        out = []
        for e in self._buffer[:k]:
            point, extras = e.payload
            if e.spectrum is None and "harmonics" in extras:
                e.g = harmonic_period(np.asarray(extras["harmonics"]), 1e-4)
            lead = (e.spectrum.leading(self.options.n_leading) if e.spectrum is not None and not e.undecided
                    else np.full(self.options.n_leading, np.nan))
            note = self.undecided.get(e.index, "") if e.undecided else ""
            if e.n_unstable is None:  # no verdict on either side (a cut chain, the end of the branch)
                e.n_unstable = -1
                note = NOT_INFERRED
            out.append((point, dict(extras, stable=bool(e.n_unstable == 0), n_unstable=int(e.n_unstable),
                                    stability_analysed=e.spectrum is not None, stability_widened=e.n_eig > 0,
                                    stability_cpu_time=float(e.cpu), leading_multipliers=lead,
                                    period_ratio=int(e.g), stability_note=note)))
            self._counts[e.index] = (e.n_unstable, e.g)
        if k:
            # a fold waits for the counts of its three points (_record_folds), the last of them
            # released only at the analysis after the turn, maybe max_gap points later
            keep = min([self._buffer[k - 1].index - 4] + [t[0][0] for t in self._folds])
            self._counts = {i: c for i, c in self._counts.items() if i >= keep}
        self._buffer = self._buffer[k:]
        return out

    def _widen(self, a: _Entry, b: _Entry) -> None:
        """Analyse again, with a wider window, the one of a and b whose count may lack a large
        unstable multiplier of the other (see the class doc)."""
        if self.widen is None:
            return
        for x, y in ((a, b), (b, a)):
            while y.n_unstable == 0 < x.n_unstable:  # only where the stable flag is at stake
                sx, sy = x.spectrum, y.spectrum
                big = float(np.abs(sx.multipliers[sx.unstable]).max(initial=1.0))
                ceiling = sy.modulus_ceiling
                done = y.n_eig >= MAX_EIG or not np.isfinite(ceiling) or sy.note
                if done or math.log(big) < WIDEN_FRACTION * math.log(max(ceiling, 1.0 + 1e-12)):
                    break
                k = min(2 * (y.n_eig or self.options.n_eig), MAX_EIG)
                c0 = time.process_time()
                sp, g = self.widen(y.x, y.omega, k)
                y.cpu += time.process_time() - c0
                self._count("widening")
                if not sp.decided:  # no verdict from the wider window: y keeps its narrow one
                    break
                y.n_eig, y.spectrum, y.g = k, sp, g
                y.n_unstable = y.spectrum.n_unstable
                if y.index in self._counts:
                    self._counts[y.index] = (y.n_unstable, y.g)

    def _resolve(self, a: _Entry, b: _Entry) -> None:
        """Make each stability change between the analysed points a and b lie between
        neighbours (bisection), record its bifurcations, give the points between their counts."""
        if a.n_unstable != b.n_unstable:
            self._widen(a, b)
        # the points analysed without a verdict keep -1, and are no bisection's reference
        mid = [e for e in self._buffer if a.index < e.index < b.index and not e.undecided]
        if a.n_unstable == b.n_unstable or self._far_only(a, b):
            for e in mid:
                e.n_unstable, e.g = a.n_unstable, a.g
            return
        while mid:
            m = mid[len(mid) // 2]
            self._spectrum(m, "bisection")
            if not m.undecided:
                break
            mid.remove(m)
        if mid:
            self._resolve(a, m)
            n_m = m.n_unstable
            self._resolve(m, b)
            if m.n_unstable != n_m:
                self._redo(a, m)
            return
        self._locate(a, b)

    def _redo(self, a: _Entry, b: _Entry) -> None:
        """Resolve the stretch from a to b again after b's count changed (b widened at its
        comparison with the analysed point after it, when a and b had been resolved on b's
        narrow count): the crossings recorded from the last analysed point c before b (a, or
        one a bisection analysed) go, c and b are resolved again, and so on back to a while
        that widens c. Each widening raises a count from 0, once per point: this ends. a itself,
        already handed on, may be widened here too: it keeps the verdict it was handed on
        with, and the stretch before it is not resolved again (a multiplier past the window
        of three analyses in a row)."""
        c = max((e for e in self._buffer if a.index < e.index < b.index and e.spectrum is not None
                 and not e.undecided),
                key=lambda e: e.index, default=a)
        # a fold is recorded only once its three points are handed on: none lies in (c, b)
        self.bifurcations = [x for x in self.bifurcations if x.kind == FOLD or not c.index <= x.index < b.index]
        n_c = c.n_unstable
        self._resolve(c, b)
        if c is not a and c.n_unstable != n_c:
            self._redo(a, c)

    def _far_only(self, a: _Entry, b: _Entry) -> bool:
        """Whether a and b, both unstable, differ only by multipliers far from the unit circle
        (see the class doc): their counts agree on the multipliers of log|mu| below the
        pairing window and below WIDEN_FRACTION of the smaller ceiling."""
        if min(a.n_unstable, b.n_unstable) == 0:
            return False
        near = self._near(a, b)

        def below(sp: FloquetSpectrum) -> int:
            return int(np.count_nonzero(sp.unstable & (np.log(np.abs(sp.multipliers)) < near)))

        return below(a.spectrum) == below(b.spectrum)

    def _near(self, a: _Entry, b: _Entry) -> float:
        """log|mu| under which both a's and b's spectra list every multiplier and a crossing can
        be paired: the pairing window, and WIDEN_FRACTION of the smaller ceiling."""
        ceiling = min(a.spectrum.modulus_ceiling, b.spectrum.modulus_ceiling)
        return min(self.options.window, WIDEN_FRACTION * math.log(max(ceiling, 1.0)))

    def _turn_near(self, a: _Entry, b: _Entry) -> bool:
        """Whether Omega turns at a or b (a fold whose real multiplier +1 crosses between them)."""
        return any(t[1][0] in (a.index, b.index) for t in self._folds)

    def _locate(self, a: _Entry, b: _Entry) -> None:
        """Crossings between the neighbouring analysed points a and b, except the fold's (see
        _record_folds)."""
        sa, sb = a.spectrum, b.spectrum
        floor = max(sa.modulus_floor, sb.modulus_floor)
        fold = self._turn_near(a, b)
        found = 0
        first = len(self.bifurcations)
        for i, j in crossings(sa.multipliers, sb.multipliers, floor, self.options.window):
            la, lb = math.log(abs(sa.multipliers[i])), math.log(abs(sb.multipliers[j]))
            frac = la / (la - lb)
            # the crossing multiplier and its mode from the unstable side: a real multiplier
            # that crossed stays real there, whereas on the stable side it may still be half
            # of a complex pair about to collide on the real axis (both within one step)
            side, k = (b, j) if lb > la else (a, i)
            mu = side.spectrum.multipliers[k]
            kind = classify(mu, fold)
            found += 1
            if kind == FOLD:
                continue
            where = dict(omega=a.omega + frac * (b.omega - a.omega),
                         le_amplitude=a.amplitude + frac * (b.amplitude - a.amplitude), fraction=float(frac))
            if self.refine is not None and self.options.refine_steps and not fold:
                r = self._refined(a, b, i, j, kind, floor)
                where = dict(omega=r.omega, le_amplitude=r.le_amplitude, fraction=r.fraction,
                             refine_steps=r.steps, located_bracket=r.bracket, refine_note=r.note)
            # the multiplier and mode stay the stored side's: a branch switch starts from a
            # stored point (hbm.stability.switching)
            self.bifurcations.append(Bifurcation(
                kind=kind, index=a.index, omega_bracket=(a.omega, b.omega), multiplier=complex(mu),
                direction=1 if lb > la else -1, period_ratio=side.g, exponent=complex(side.spectrum.exponents[k]),
                mode_omega=float(side.spectrum.omega), eigenvector=side.spectrum.eigenvectors[k], **where))
        if not found:
            self._unpaired(a, b, fold, floor)
        elif not fold:
            self._reconcile(a, b, first)

    def _refined(self, a: _Entry, b: _Entry, i: int, j: int, kind: str, floor: float) -> Refinement:
        """The crossing of a's multiplier i (b's j) located by points solved between a and b
        (hbm.stability.refinement). At each solved point the crossing multiplier is the one
        nearest, in (log|mu|, |arg mu|), to the linear interpolation of a's and b's at that
        point's f, among those that can be it: for a period doubling those with Re mu < 0, for
        a branch point Re mu > 0 (on its stable side a real crossing multiplier may still be
        one of a complex pair about to meet on the real axis; its modulus has the sign the
        root finding needs), for a Neimark-Sacker the complex ones. The CPU time goes to a's
        stability_cpu_time."""
        mu_a, mu_b = a.spectrum.multipliers[i], b.spectrum.multipliers[j]
        ca = (math.log(abs(mu_a)), abs(np.angle(mu_a)))
        cb = (math.log(abs(mu_b)), abs(np.angle(mu_b)))
        candidate = {PERIOD_DOUBLING: lambda m: m.real < 0.0, BRANCH_POINT: lambda m: m.real > 0.0}.get(
            kind, lambda m: classify(m, False) == NEIMARK_SACKER)

        def evaluate(f):
            c0 = time.process_time()
            w = a.omega + f * (b.omega - a.omega)  # the prediction's, until a point is solved
            try:
                got = self.refine(a.x, a.omega, b.x, b.omega, f)
                if isinstance(got, str):
                    return got
                x, w, amp = got
                self._count("refinement")
                sp, _ = self.analyse(x, w)
            except SingularMatrixError as exc:  # H(0) singular: a multiplier exactly +1 there
                return f"no analysis at omega={w:.6g}: {exc}"
            finally:
                a.cpu += time.process_time() - c0
            if not sp.decided:
                return f"no verdict at omega={w:.6g}: {sp.undecided_reason}"
            target = (ca[0] + f * (cb[0] - ca[0]), ca[1] + f * (cb[1] - ca[1]))
            lm = tracked_log_modulus(sp.multipliers, max(floor, sp.modulus_floor), target, candidate)
            if lm is None:
                return f"no {kind} multiplier at omega={w:.6g}"
            return lm, w, amp

        ends = ((ca[0], a.omega, a.amplitude), (cb[0], b.omega, b.amplitude))
        return refine_crossing(evaluate, ends, self.options.refine_steps, self.options.refine_rtol)

    def _parities(self, a: _Entry, b: _Entry):
        """real_parities of a and b within _near (None when either is unclear)."""
        near = self._near(a, b)
        pa = real_parities(a.spectrum.multipliers, a.spectrum.unstable, near)
        pb = real_parities(b.spectrum.multipliers, b.spectrum.unstable, near)
        return (pa, pb, near) if pa is not None and pb is not None else None

    def _nearest_real(self, a: _Entry, b: _Entry, negative: bool, near: float):
        """(entry, index) of the real unstable multiplier of that sign nearest the circle, on a
        or b (None if neither has one): the representative of a crossing known by parity."""
        best = None
        for e in (a, b):
            sp = e.spectrum
            ok = sp.unstable & lone_real(sp.multipliers) & (np.log(np.abs(sp.multipliers)) < near) \
                & ((sp.multipliers.real < 0) == negative)
            for j in np.flatnonzero(ok):
                lm = math.log(abs(sp.multipliers[j]))
                if best is None or lm < best[0]:
                    best = (lm, e, j)
        return None if best is None else best[1:]

    def _reconcile(self, a: _Entry, b: _Entry, first: int) -> None:
        """Make the crossings paired between a and b (self.bifurcations[first:]) agree with the
        parities of the real multipliers (no turn between them). A complex pair changes the
        count by two and neither parity, so where det(I + M) changed sign and no period
        doubling was paired, a real multiplier went through -1 that the pairing took for one
        of a pair: near a 1:2 resonance two real multipliers meet on the negative real axis
        and leave it as a pair within one step (rotor 67's DLFT NFRC, 1607.5 rad/s: a
        multiplier -1.11 + 0.14i paired across the circle, the count 2 -> 1). If turning one
        Neimark-Sacker of the matching direction into that crossing makes the counts add
        up, it is turned (the one nearest that side of the real axis); if one more crossing
        does, it is added half-way; kind_from "parity" either way. The same for +1. A pair
        within REAL_ARG_TOL of the real axis, recorded once as a branch point or a period
        doubling (bifurcation.upper_half), counts two and changes no parity (_members)."""
        got = self._parities(a, b)
        if got is None:
            return
        pa, pb, near = got
        for col, kind in ((1, PERIOD_DOUBLING), (2, BRANCH_POINT)):
            recs = self.bifurcations[first:]
            members = [self._members(r, a, b) for r in recs]
            if pa[col] == pb[col] or sum(r.kind == kind and n == 1 for r, n in zip(recs, members)) % 2:
                continue
            rest = (pb[0] - pa[0]) - sum(n * r.direction for r, n in zip(recs, members))
            axis = np.pi if kind == PERIOD_DOUBLING else 0.0
            pairs = [k for k, r in enumerate(recs) if r.kind == NEIMARK_SACKER and r.direction == -rest
                     and (r.multiplier.real < 0) == (kind == PERIOD_DOUBLING)]
            rep = self._nearest_real(a, b, kind == PERIOD_DOUBLING, near)
            if pairs:
                k = first + min(pairs, key=lambda q: abs(abs(np.angle(recs[q].multiplier)) - axis))
                r = self.bifurcations[k]
                if rep is not None:
                    r = replace(r, **_mode(*rep))
                self.bifurcations[k] = replace(r, kind=kind, kind_from=PARITY)
            elif abs(rest) == 1 and rep is not None:
                self._append_unpaired(a, b, kind, int(rest), *rep, PARITY)

    @staticmethod
    def _members(r: Bifurcation, a: _Entry, b: _Entry) -> int:
        """Multipliers that the record r between a and b stands for in the count of unstable
        ones: 2 for a complex pair (a Neimark-Sacker, or a crossing whose multiplier's
        conjugate is listed on its unstable side: a pair near the real axis, classified by its
        argument), 1 for a real one (and for a crossing the parities turned into one)."""
        if r.kind == NEIMARK_SACKER:
            return 2
        if r.kind_from != CROSSING:
            return 1
        mu = (b if r.direction > 0 else a).spectrum.multipliers
        return 1 if lone_real(mu)[mu == r.multiplier].all() else 2

    def _unpaired(self, a: _Entry, b: _Entry, fold: bool, floor: float) -> None:
        """A count change between neighbours a and b with no multiplier paired across the
        circle, placed half-way (bracket stated in omega_bracket). Its kind comes from the
        parities of the real multipliers beyond -1 and +1 (bifurcation.real_parities) where
        they settle it, else it is guessed (Bifurcation.kind_from)."""
        got = self._parities(a, b)
        side = b if b.n_unstable > a.n_unstable else a
        direction = 1 if b.n_unstable > a.n_unstable else -1
        if got is not None:
            pa, pb, near = got
            if (pb[0] - pa[0]) % 2 and (pa[1] != pb[1]) != (pa[2] != pb[2]):
                # an odd number of real multipliers went through -1 (minus changed) or +1
                kind = PERIOD_DOUBLING if pa[1] != pb[1] else FOLD if fold else BRANCH_POINT
                if kind == FOLD:
                    return  # the turn's own (_record_folds)
                rep = self._nearest_real(a, b, kind == PERIOD_DOUBLING, near)
                if rep is not None:
                    self._append_unpaired(a, b, kind, 1 if pb[0] > pa[0] else -1, *rep, PARITY)
                    return
        # guess the one that crossed: the unstable one nearest the unit circle on the side with
        # more of them, leaving out those paired with an unstable multiplier of the other side
        # (they did not cross)
        other = a if side is b else b
        sp = side.spectrum
        unst = np.flatnonzero(sp.unstable & upper_half(sp.multipliers))
        stayed = {i for i, j in pair_multipliers(sp.multipliers, other.spectrum.multipliers, floor,
                                                 self.options.window)
                  if abs(other.spectrum.multipliers[j]) > 1.0}
        moved = np.array([i for i in unst if i not in stayed], dtype=int)
        unst = moved if len(moved) else unst  # every one paired across: a count the window cut
        if len(unst):
            j = int(unst[np.argmin(np.abs(np.log(np.abs(sp.multipliers[unst]))))])
            kind = classify(sp.multipliers[j], fold)
            if kind == FOLD:
                return  # the turn's own (_record_folds), as for a paired crossing
            self._append_unpaired(a, b, kind, direction, side, j, GUESS)
        else:
            self._append_unpaired(a, b, UNCLASSIFIED, direction, side, None, GUESS)

    def _append_unpaired(self, a: _Entry, b: _Entry, kind: str, direction: int, side: _Entry, j, source: str) -> None:
        """Record a crossing between a and b placed half-way, its multiplier and mode the
        j-th of side's spectrum (None: none known)."""
        self.bifurcations.append(Bifurcation(
            kind=kind, omega=0.5 * (a.omega + b.omega), le_amplitude=0.5 * (a.amplitude + b.amplitude),
            index=a.index, fraction=0.5, omega_bracket=(a.omega, b.omega), direction=direction, kind_from=source,
            **_mode(side, j)))

    def _claimed_by(self, trio) -> list:
        """The branch points that are the fold of trio's: its real multiplier +1, located
        between two of the trio's points before the turn was seen (it needs the point after
        the turn)."""
        return [x for x in self.bifurcations if x.kind == BRANCH_POINT and x.index in (trio[0][0], trio[1][0])]

    def _record_folds(self) -> None:
        """Folds whose three points all have their counts: the vertex of the parabola Omega(s)
        through them (interpolation error O(ds^3) in Omega), direction from the counts."""
        for trio in list(self._folds):
            if not all(t[0] in self._counts for t in trio):
                continue
            self._folds.remove(trio)
            s, w, amp = (np.array([t[k] for t in trio]) for k in (2, 1, 3))
            ss, ww, aa = parabola_vertex(s, w, amp)
            k = 0 if ss <= s[1] else 1
            frac = (ss - s[k]) / (s[k + 1] - s[k]) if s[k + 1] > s[k] else 0.0
            n0, n2 = self._counts[trio[0][0]][0], self._counts[trio[2][0]][0]
            if min(n0, n2) < 0:  # a count without a verdict: the direction is not known
                n0 = n2 = 0
            near = self._claimed_by(trio)
            if near:
                self.bifurcations.remove(near[0])
            self.bifurcations.append(Bifurcation(
                kind=FOLD, omega=ww, le_amplitude=aa, index=int(trio[k][0]), fraction=float(frac),
                omega_bracket=(float(w[k]), float(w[k + 1])), multiplier=complex(1.0),
                direction=near[0].direction if near else int(np.sign(n2 - n0)),
                period_ratio=int(self._counts[trio[1][0]][1])))


def _mode(e: _Entry, j) -> dict:
    """The Bifurcation fields of the j-th multiplier of e's spectrum (None: no multiplier known)."""
    sp = e.spectrum
    if j is None:
        return dict(multiplier=complex(np.nan), exponent=0j, eigenvector=None, period_ratio=e.g,
                    mode_omega=float(sp.omega))
    return dict(multiplier=complex(sp.multipliers[j]), exponent=complex(sp.exponents[j]),
                eigenvector=sp.eigenvectors[j], period_ratio=e.g, mode_omega=float(sp.omega))


def unknown_stability(extras: dict, options: StabilityOptions = StabilityOptions()) -> dict:
    """extras completed with the stability keys of a point that was not analysed and cannot
    be inferred (a failed final point): stable False, n_unstable -1, leading nan."""
    g = harmonic_period(np.asarray(extras["harmonics"]), 1e-4) if "harmonics" in extras else 1
    return dict(extras, stable=False, n_unstable=-1, stability_analysed=False, stability_widened=False,
                stability_cpu_time=0.0, leading_multipliers=np.full(options.n_leading, np.nan), period_ratio=int(g),
                stability_note=NOT_CONVERGED)


#: the per-point stability keys the monitor adds to a point's extras
PER_POINT = ("stable", "n_unstable", "stability_analysed", "stability_widened", "stability_cpu_time",
             "leading_multipliers", "period_ratio", "stability_note")

#: stability_note of a point without a count because no analysis with a verdict lies on one
#: side of it within reach (the chain cut after analyses without one; module doc)
NOT_INFERRED = "not inferred: no analysis with a verdict on one side within the gap cap"
#: stability_note of a point that was not analysed because it is not a solution
NOT_CONVERGED = "not analysed: the point did not converge"


@dataclass(frozen=True, eq=False)
class BranchStability:
    """The stability of a stored branch's m points (monitor_branch).

    stable (m,) bool; n_unstable (m,) int; stability_analysed (m,) bool; stability_widened
    (m,) bool; stability_cpu_time (m,) s; leading_multipliers (m, n_leading) float (nan where
    not analysed); period_ratio (m,) int; stability_note (m,) object array of str (why
    n_unstable is -1, "" where it is not);
    bifurcations: Bifurcation tuple, `index` counting the given points; n_analyses.
    undecided: {index: why} of the points analysed without a verdict (n_unstable -1).
    """

    stable: np.ndarray
    n_unstable: np.ndarray
    stability_analysed: np.ndarray
    stability_widened: np.ndarray
    stability_cpu_time: np.ndarray
    leading_multipliers: np.ndarray
    period_ratio: np.ndarray
    stability_note: np.ndarray
    bifurcations: tuple
    n_analyses: int
    undecided: dict = field(default_factory=dict)

    def per_point(self) -> dict:
        """{name: (m, ...) array} of the per-point fields."""
        return {k: getattr(self, k) for k in PER_POINT}


def monitor_branch(analyse, omega: np.ndarray, x: np.ndarray, extras: list, x_scale=1.0, omega_scale: float = 1.0,
                   options: StabilityOptions = StabilityOptions(), widen=None, refine=None) -> BranchStability:
    """The monitor run over the points of a branch computed without it (e.g. a branch of the
    isola search): the same gapped analyses, bisection on the stored points and located
    bifurcations as if it had watched the continuation, analysing a fraction of the points
    (a quarter on a smooth branch; about half on rotor 67's isolas and detached branches,
    whose multipliers stay near the unit circle).

    analyse(x, omega) -> (FloquetSpectrum, g), widen(x, omega, n_eig) and refine (StabilityMonitor.analyse,
    .widen and .refine; widen None: never widened; refine None: crossings interpolated
    between the stored points). omega (m,) rad/s
    and x (m, n): consecutive converged points of one branch; extras: m dicts with
    le_amplitude (m) and harmonics (hbm.harmonic.nfrc.nfrc_extras). x_scale (scalar or
    (n,)) and omega_scale (rad/s): the continuation's scales, which give the arc length
    between points that the gap control measures in.
    """
    from hbm.continuation.branch import ContinuationPoint

    omega = np.asarray(omega, dtype=float)
    x = np.asarray(x, dtype=float)
    m = len(omega)
    mon = StabilityMonitor(analyse=analyse, widen=widen, refine=refine, options=options)
    done = {}
    for i in range(m):
        step = 0.0 if i == 0 else float(np.sqrt(np.sum(((x[i] - x[i - 1]) / x_scale) ** 2)
                                                + ((omega[i] - omega[i - 1]) / omega_scale) ** 2))
        p = ContinuationPoint(i, float(omega[i]), x[i], True, 0.0, 0, step, 0.0)
        done.update((q.index, ex) for q, ex in mon.push(p, extras[i]))
    done.update((q.index, ex) for q, ex in mon.finish())
    k = options.n_leading
    return BranchStability(
        stable=np.array([done[i]["stable"] for i in range(m)], dtype=bool),
        n_unstable=np.array([done[i]["n_unstable"] for i in range(m)], dtype=np.int64),
        stability_analysed=np.array([done[i]["stability_analysed"] for i in range(m)], dtype=bool),
        stability_widened=np.array([done[i]["stability_widened"] for i in range(m)], dtype=bool),
        stability_cpu_time=np.array([done[i]["stability_cpu_time"] for i in range(m)], dtype=float),
        leading_multipliers=np.array([done[i]["leading_multipliers"] for i in range(m)], dtype=float).reshape(m, k),
        period_ratio=np.array([done[i]["period_ratio"] for i in range(m)], dtype=np.int64),
        stability_note=np.array([done[i]["stability_note"] for i in range(m)], dtype=object),
        bifurcations=tuple(sorted(mon.bifurcations, key=lambda b: (b.index, b.fraction))), n_analyses=mon.n_analyses,
        undecided=dict(mon.undecided))
