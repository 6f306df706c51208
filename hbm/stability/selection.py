"""Points of a solution set chosen for a check by time integration (section 3.3 of the
reference paper): a stable point near a branch's peak, the period doubling of a branch, and
the period-doubled branch born there.

Floquet analyses (hbm.stability.spectrum.orbit_spectrum) are made only where they decide
something: at a few candidate points near the peak, at a bounded scan of the branch when its
file holds no stability, and in the bisection down to the two neighbouring points between
which a multiplier crosses -1; the whole branch's stability (branch_stability) only when
those find nothing. Stored verdicts (an NFRC computed with [hbm] stability) are
used first and confirmed at the chosen point.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from hbm.continuation.arclength import ContinuationOptions, continue_branch
from hbm.continuation.branch import ContinuationPoint
from hbm.continuation.newton import NewtonOptions, newton_solve_on_plane
from hbm.harmonic.nfrc import nfrc_extras
from hbm.harmonic.solver import HbmSolver
from hbm.stability.bifurcation import GUESS, PARITY, PERIOD_DOUBLING, Bifurcation
from hbm.stability.monitor import NOT_CONVERGED, BranchStability, StabilityMonitor, StabilityOptions, monitor_branch
from hbm.stability.spectrum import orbit_spectrum
from hbm.stability.switching import BranchStart, switch_branch

#: a point is chosen as stable when its largest multiplier (minimal period) has
#: log|mu| < -STABILITY_MARGIN: a clear verdict, not a multiplier on the unit circle that the
#: truncation could move to either side (DLFT's exponents move by ~0.2 % of log|mu| between
#: N_h = 40 and 60 on rotor 67, hbm.stability.spectrum).
STABILITY_MARGIN = 1e-3


@dataclass(frozen=True)
class ChosenPoint:
    """A point of a branch chosen for validation.

    found: whether there is one (reason says why not, or how it was chosen).
    index: its index on the branch (-1 when none). omega: Omega, rad/s. u: its unknowns,
    (n_u,) scaled as the branch's residual. le_amplitude: m. stable: the verdict at the point.
    verdict: "analysed" (Floquet analysis made here) or "stored" (the branch file's, not
    recomputed). n_unstable: multipliers outside the unit circle (-1 unknown). multiplier:
    largest |mu| over the minimal period (nan when not analysed here, or without a verdict).
    n_analyses: Floquet analyses made to choose it.
    """

    found: bool
    reason: str
    index: int = field(default=-1, metadata={"unit": "1"})
    omega: float = field(default=math.nan, metadata={"unit": "rad/s"})
    u: np.ndarray = field(default_factory=lambda: np.zeros(0), metadata={"unit": "1"})
    le_amplitude: float = field(default=math.nan, metadata={"unit": "m"})
    stable: bool = False
    verdict: str = ""
    n_unstable: int = field(default=-1, metadata={"unit": "1"})
    multiplier: float = field(default=math.nan, metadata={"unit": "1"})
    n_analyses: int = field(default=0, metadata={"unit": "1"})


def _candidates(order: np.ndarray, amplitude: np.ndarray, n: int) -> list[int]:
    """n candidate indices near the peak: ranks (i / n)^2 R, i = 0 .. n - 1, of `order` (points
    by decreasing amplitude), R the number of points with at least half the peak amplitude:
    dense at the peak, reaching down to half of it (the stable sheet of a fold at the peak
    can lie a few percent below it, its unstable sheet crowds the first ranks); each rank
    taken at the first point at least one index away from those taken before."""
    R = max(1, int(np.count_nonzero(amplitude[order] >= 0.5 * amplitude[order[0]])))
    out: list[int] = []
    for i in range(n):
        r = int(round((i / n) ** 2 * R))
        for j in order[r:]:
            if all(abs(int(j) - k) > 1 for k in out):
                out.append(int(j))
                break
    return out


def choose_point(residual, omega, x, amplitude, converged, stable=None, *, eligible=None, n_candidates: int = 8,
                 margin: float = STABILITY_MARGIN, verdicts_from: str = "the branch file") -> ChosenPoint:
    """The stable point of largest LE amplitude among a few candidates of a branch.

    residual: the branch's HarmonicBalanceResidual. omega (m,) rad/s, x (m, n_u), amplitude
    (m,) m, converged (m,) bool: the branch. stable: (m,) bool stored verdicts, or None.
    eligible: (m,) bool, points that may be chosen (default all converged ones).
    verdicts_from: where `stable` comes from, in words, for the reason.
    With stored verdicts the points called stable are tried by decreasing amplitude and the
    first one whose analysis confirms it is chosen; otherwise (or when none is confirmed) the
    n_candidates points near the peak (_candidates: dense at the peak, down to half its
    amplitude) are analysed by decreasing amplitude and the first stable one (log|mu| <
    -margin) is chosen. When none is, the least unstable candidate is
    chosen and the reason says so (stable False); a candidate whose analysis gives no verdict
    (FloquetSpectrum.decided) is neither stable nor the least unstable, and is chosen (n_unstable
    -1) only when no candidate has a verdict.
    """
    omega, amplitude = np.asarray(omega, float), np.asarray(amplitude, float)
    ok = np.asarray(converged, bool) & np.isfinite(amplitude)
    if eligible is not None:
        ok &= np.asarray(eligible, bool)
    if not ok.any():
        return ChosenPoint(False, "no converged point on the branch")
    order = np.flatnonzero(ok)[np.argsort(-amplitude[ok], kind="stable")]
    tried: dict[int, tuple] = {}

    def analyse(i):
        if i not in tried:
            sp, _ = orbit_spectrum(residual, x[i], float(omega[i]))
            mu = sp.largest_modulus if sp.decided else math.nan
            tried[i] = (sp.stable and (mu == 0.0 or math.log(mu) < -margin), sp.n_unstable, mu, sp.note)
        return tried[i]

    def chosen(i, reason):
        s, n, mu, _ = tried[i]
        return ChosenPoint(True, reason, int(i), float(omega[i]), np.array(x[i], float), float(amplitude[i]), bool(s),
                           "analysed", int(n), float(mu), len(tried))

    if stable is not None:
        called = [i for i in order if bool(stable[i])]
        for i in called[:n_candidates]:
            if analyse(i)[0]:
                return chosen(i, f"largest LE amplitude among the {len(called)} points {verdicts_from} calls "
                                 f"stable, confirmed here")
    candidates = _candidates(order, amplitude, n_candidates)
    for i in candidates:
        if analyse(i)[0]:
            return chosen(i, f"largest LE amplitude among the stable ones of {len(candidates)} candidates near the "
                             f"peak (analysed here)")
    decided = [j for j in tried if tried[j][1] >= 0]
    if not decided:
        i = next(iter(tried))
        return chosen(i, f"no analysis of the {len(tried)} candidates near the peak gave a verdict "
                         f"({tried[i][3]}): the first one, stability unknown")
    i = min(decided, key=lambda j: tried[j][2])
    undecided = f", {len(tried) - len(decided)} without a verdict" if len(decided) < len(tried) else ""
    return chosen(i, f"no stable point among {len(tried)} analysed candidates near the peak{undecided}: the least "
                     f"unstable one (|mu| = {tried[i][2]:.4g})")


def branch_stability(residual, omega, x, converged, *, x_scale=1.0, omega_scale: float = 1.0,
                     options: StabilityOptions = StabilityOptions()) -> BranchStability:
    """The stability of a branch stored without it, as the continuation's monitor gives it
    (hbm.stability.monitor.monitor_branch: gapped Floquet analyses, bisection on the stored
    points, located bifurcations), for a choice that a few analyses near the peak or a scan
    cannot make: the stable stretches of rotor 67's NFRCs are a few points long, away from the
    peak (coarse DLFT NFRC: 64 stable points of 641 in short runs, none of 24 candidates near
    the peak stable).

    residual, omega (m,) rad/s, x (m, n_u), converged (m,) bool: the branch. x_scale (scalar
    or (n_u,)) and omega_scale (rad/s): the continuation's scales. The converged points are
    monitored as one consecutive run; the result covers all m points (an unconverged point:
    not stable, not analysed, n_unstable -1), bifurcation indices counting them.
    """
    omega, x = np.asarray(omega, float), np.asarray(x, float)
    idx = np.flatnonzero(np.asarray(converged, bool))
    m, k = len(omega), options.n_leading
    if len(idx) == 0:
        raise ValueError("branch_stability: the branch has no converged point")
    mon = StabilityMonitor.for_residual(residual, options)
    st = monitor_branch(mon.analyse, omega[idx], x[idx], [nfrc_extras(residual, xi) for xi in x[idx]],
                        x_scale, omega_scale, options, widen=mon.widen,
                        refine=mon.refine)
    full = {"stable": np.zeros(m, bool), "n_unstable": np.full(m, -1, np.int64),
            "stability_analysed": np.zeros(m, bool), "stability_widened": np.zeros(m, bool),
            "stability_cpu_time": np.zeros(m), "leading_multipliers": np.full((m, k), np.nan),
            "period_ratio": np.ones(m, np.int64), "stability_note": np.full(m, NOT_CONVERGED, dtype=object)}
    for name, a in st.per_point().items():
        full[name][idx] = a
    bifs = tuple(replace(b, index=int(idx[b.index])) for b in st.bifurcations)
    return BranchStability(**full, bifurcations=bifs, n_analyses=st.n_analyses,
                           undecided={int(idx[i]): why for i, why in st.undecided.items()})


def stable_stretch(residual, omega, x, converged, index: int, stable=None) -> tuple[int, int]:
    """(first, last): the run of converged branch points around `index` that are stable.

    residual, omega (m,) rad/s, x (m, n_u), converged (m,) bool: the branch, as for
    choose_point. stable: (m,) bool stored verdicts (the run is read from them), or None:
    the run's ends are then found by Floquet analyses, stepping out from `index` by doubling
    steps to the first point not stable (unstable, or no verdict: FloquetSpectrum.decided)
    and bisecting back to a neighbouring pair (about 2 log2 of the run's length analyses
    each way). Like every gapped schedule, a short unstable stretch between two stable
    points analysed is not seen. (index, index) when the point itself is not stable.
    """
    ok = np.asarray(converged, bool)
    m, i = len(ok), int(index)
    lo_ok, hi_ok = i, i
    while lo_ok > 0 and ok[lo_ok - 1]:
        lo_ok -= 1
    while hi_ok + 1 < m and ok[hi_ok + 1]:
        hi_ok += 1
    if stable is not None:
        st = np.asarray(stable, bool)
        if not st[i]:
            return i, i
        lo, hi = i, i
        while lo > lo_ok and st[lo - 1]:
            lo -= 1
        while hi < hi_ok and st[hi + 1]:
            hi += 1
        return lo, hi
    seen: dict[int, bool] = {}

    def is_stable(j):
        if j not in seen:
            seen[j] = bool(orbit_spectrum(residual, x[j], float(omega[j]))[0].stable)
        return seen[j]

    if not is_stable(i):
        return i, i
    ends = []
    for d, bound in ((-1, lo_ok), (1, hi_ok)):
        good, bad, step = i, None, 1
        while bad is None and good != bound:
            j = good + d * step
            j = max(j, bound) if d < 0 else min(j, bound)
            if is_stable(j):
                good, step = j, 2 * step
            else:
                bad = j
        while bad is not None and abs(bad - good) > 1:
            mid = (good + bad) // 2
            if is_stable(mid):
                good = mid
            else:
                bad = mid
        ends.append(good)
    return ends[0], ends[1]


@dataclass(frozen=True)
class LocatedDoubling:
    """A period doubling of a branch, or why none was found.

    bifurcation: hbm.stability.bifurcation.Bifurcation (with its critical mode) or None.
    index: the stored branch point on the bifurcation's unstable side, -1 when none.
    reason: how it was found, or why none. n_analyses: Floquet analyses made.
    omega (rad/s), u (n_u,): the start of the branch switch, where the mode was computed:
    the stored point `index`, or, where its multiplier is far past -1 (the crossing lies
    between two distant points), a point of the branch found between the two (see
    refine_crossing); nan and None when none. bracket: the two neighbouring stored points
    the crossing lies between, the unstable side first; () when none.
    """

    bifurcation: Bifurcation | None
    index: int
    reason: str
    n_analyses: int
    omega: float = math.nan
    u: np.ndarray | None = None
    bracket: tuple = ()

    def switch_starts(self, omega: np.ndarray, x: np.ndarray) -> list:
        """[(u (n_u,), Omega rad/s)]: where to start the branch switch, in turn (see
        switch_to_doubled): (u, omega), then the bracket's stored points of the branch
        (omega (m,) rad/s, x (m, n_u): the arrays it was located on) not already there."""
        if self.bifurcation is None:
            return []
        out = [(np.asarray(self.u, float), float(self.omega))]
        for i in self.bracket:
            if not (float(omega[i]) == out[0][1] and np.array_equal(x[i], out[0][0])):
                out.append((np.asarray(x[i], float), float(omega[i])))
        return out


def locate_period_doubling(residual, omega, x, amplitude, converged, *, brackets=None, n_scan: int = 24,
                           max_analyses: int = 80,
                           brackets_from: str = "the branch file's bifurcation table") -> LocatedDoubling:
    """The first period doubling along a branch, with its critical mode.

    residual: the branch's HarmonicBalanceResidual. omega (m,) rad/s, x (m, n_u), amplitude
    (m,) m, converged (m,) bool. brackets: point indices after which a period doubling lies
    (the `index` column of a branch file's bifurcation table), or None: then n_scan points
    evenly spread over the branch are analysed and every change of the number of unstable
    multipliers between two of them is a bracket. Each bracket is bisected on the stored
    points down to two neighbours, where a StabilityMonitor (hbm.stability.monitor) pairs,
    classifies and locates the crossing (folds told apart by the turn in Omega) and gives
    its mode. Points whose analysis gives no verdict (FloquetSpectrum.decided) are passed by:
    the scan's brackets join the points with one, the bisection takes the point nearest the
    middle with one, and stops at two points with only points without one between them.
    max_analyses bounds the Floquet analyses. brackets_from: where the brackets come from, in
    words, for the reason.
    """
    omega, x = np.asarray(omega, float), np.asarray(x, float)
    idx = np.flatnonzero(np.asarray(converged, bool))
    cache: dict[int, tuple] = {}
    if len(idx) < 2:
        return LocatedDoubling(None, -1, "fewer than two converged points", 0)

    def spec(i):
        if i not in cache:
            if len(cache) >= max_analyses:
                raise _Budget
            cache[i] = orbit_spectrum(residual, x[i], float(omega[i]))
        return cache[i]

    def count(i):
        return spec(i)[0].n_unstable

    pos = {int(i): k for k, i in enumerate(idx)}
    pairs, checked = [], 0
    try:
        if brackets is not None:
            pairs = [(int(i), int(i) + 1) for i in brackets if int(i) in pos and int(i) + 1 in pos]
            if not pairs:
                return LocatedDoubling(None, -1, f"{brackets_from} holds no period doubling", 0)
            how = f"from {brackets_from}"
        else:
            scan = idx[np.unique(np.linspace(0, len(idx) - 1, min(n_scan, len(idx))).round().astype(int))]
            known = [int(i) for i in scan if count(i) >= 0]
            pairs = [(a, b) for a, b in zip(known[:-1], known[1:]) if count(a) != count(b)]
            how = f"located here (scan of {len(scan)} points and bisection)"
            if not pairs:
                return LocatedDoubling(None, -1, f"no change of stability among {len(scan)} points spread over the "
                                                 f"branch", len(cache))
        for a, b in pairs:
            checked += 1
            while pos[b] - pos[a] > 1:
                inner = sorted(range(pos[a] + 1, pos[b]), key=lambda p: abs(p - 0.5 * (pos[a] + pos[b])))
                mid = next((int(idx[p]) for p in inner if count(int(idx[p])) >= 0), None)
                if mid is None:  # only points without a verdict between a and b
                    break
                if count(mid) != count(a):
                    b = mid
                else:
                    a = mid
            bif = _classify(residual, omega, x, amplitude, idx, pos, a, b, spec)
            if bif is not None:
                side = b if bif.direction > 0 else a
                why = (f"{how}: multiplier {bif.multiplier.real:.4g}{bif.multiplier.imag:+.2g}i between points "
                       f"{a} and {b}")
                w_s, u_s = float(omega[side]), x[side]
                if abs(math.log(abs(bif.multiplier))) > REFINE_BEYOND:
                    ref = refine_crossing(residual, omega, x, amplitude, idx, pos, a, b, spec)
                    if ref is not None:
                        bif, w_s, u_s, n_ref = ref
                        why += (f", refined between them ({n_ref} points of the branch): multiplier "
                                f"{bif.multiplier.real:.4g}{bif.multiplier.imag:+.2g}i at Omega = {w_s:.6g} rad/s")
                if bif.kind_from == PARITY:
                    why += (" (no multiplier pairs across the unit circle there: the kind comes from the parity of "
                            "the real multipliers beyond -1)")
                elif bif.kind_from == GUESS:
                    why += " (no multiplier pairs across the unit circle there: the kind is a guess)"
                return LocatedDoubling(bif, side, why, len(cache), w_s, np.asarray(u_s, float),
                                       (side, a if side == b else b))
    except _Budget:
        if not pairs:  # out of analyses in the scan itself: no stability change examined yet
            return LocatedDoubling(None, -1, f"the scan of the branch needs more than the {max_analyses} Floquet "
                                             "analyses allowed; no stability change examined", len(cache))
        return LocatedDoubling(None, -1, f"no period doubling among the {max(checked - 1, 0)} of {len(pairs)} stability "
                                         f"change(s) examined within {max_analyses} Floquet analyses", len(cache))
    return LocatedDoubling(None, -1, f"none of the {len(pairs)} stability change(s) is a period doubling "
                                     f"({how.split(' (')[0]})", len(cache))


class _Budget(Exception):
    pass


#: |log|mu|| of the crossing multiplier at the switch's start beyond which the crossing is
#: refined: the pitchfork's new branch leaves from mu = -1, and from a point far past it
#: (RL on rotor 67: mu = -2.8 at the next NFRC point) the switch's Newton does not reach it
REFINE_BEYOND = 0.1


def refine_crossing(residual, omega, x, amplitude, idx, pos, a, b, spec, levels: int = 8):
    """The crossing between the neighbouring stored points a and b, bisected on branch
    points computed between them: each new point is the solution on the hyperplane through
    the midpoint of the bracket, normal to its chord (Newton with the bordered solve, the
    metric of hbm.harmonic.nfrc.default_continuation: u, Omega / 100 rad/s), analysed and
    kept on the side whose number of unstable multipliers it shares. Stops when the
    bracket's unstable-side multiplier is within REFINE_BEYOND of the unit circle in
    |log|mu||, or after `levels` bisections.

    Returns (Bifurcation classified on the last bracket that classifies as a period
    doubling, with the stored neighbours; omega of its unstable-side point, rad/s; its
    unknowns (n_u,); branch points computed), or None when no refined bracket does.
    """
    tol = residual.options.tolerance
    solver = HbmSolver(atol=0.1 * tol)
    w = [float(omega[k]) for k in (a, b)]
    u = [np.asarray(x[k], float) for k in (a, b)]
    sp = [spec(a), spec(b)]
    n = u[0].size
    computed = 0
    best = None
    # the stored neighbours that classify each bracket with it (the turn in Omega of a fold)
    before = [int(idx[j]) for j in range(max(0, pos[a] - 1), pos[a])]
    after = [int(idx[j]) for j in range(pos[b] + 1, min(len(idx), pos[b] + 2))]
    for _ in range(levels):
        dx, dw = u[1] - u[0], (w[1] - w[0]) / 100.0
        nrm = math.hypot(float(np.linalg.norm(dx)), dw)
        dx, dw = dx / nrm, dw / nrm
        um, wm = 0.5 * (u[0] + u[1]), 0.5 * (w[0] + w[1])

        # the plane through the midpoint, normal to the chord (Omega in units of 100 rad/s)
        sol = newton_solve_on_plane(residual, um, wm, dx, dw / 100.0, NewtonOptions(tol_residual=tol, max_iter=12),
                                    solver=solver)
        if not sol.converged:
            break
        computed += 1
        u_m, w_m = sol.x[:n], float(sol.x[n])
        s_m = orbit_spectrum(residual, u_m, w_m)
        if not s_m[0].decided:  # no side to put it on: keep the last classified bracket
            break
        k = 0 if s_m[0].n_unstable == sp[0][0].n_unstable else 1
        u[k], w[k], sp[k] = u_m, w_m, s_m
        om = np.array([omega[j] for j in before] + w + [omega[j] for j in after], float)
        xs = np.array([x[j] for j in before] + u + [x[j] for j in after], float)
        specs = [spec(j) for j in before] + sp + [spec(j) for j in after]
        amp = np.array([amplitude[j] for j in before] + [nfrc_extras(residual, v)["le_amplitude"] for v in u]
                       + [amplitude[j] for j in after], float)
        loc = np.arange(len(om))
        bif = _classify(residual, om, xs, amp, loc, {int(i): int(i) for i in loc}, len(before), len(before) + 1,
                        lambda i, specs=specs: specs[i])
        if bif is None:  # e.g. the multiplier's partner on the negative axis has joined it in a
            break        # complex pair on the stable side: keep the last classified bracket
        side = 1 if bif.direction > 0 else 0
        best = (bif, w[side], u[side], computed)
        if abs(math.log(abs(bif.multiplier))) <= REFINE_BEYOND:
            break
    return best


def _classify(residual, omega, x, amplitude, idx, pos, a, b, spec) -> Bifurcation | None:
    """The period doubling between the neighbouring points a and b (None if the crossing
    there is of another kind), by a StabilityMonitor fed a's and b's neighbours too (the turn
    in Omega that makes a +1 crossing a fold)."""
    ks = [int(idx[k]) for k in range(max(0, pos[a] - 1), min(len(idx), pos[b] + 2))]
    by_key = {(float(omega[k]), float(x[k][0])): k for k in ks}
    mon = StabilityMonitor(analyse=lambda xx, w: spec(by_key[(float(w), float(xx[0]))]),
                           options=StabilityOptions(max_gap=1))
    prev = None
    for k in ks:
        step = 0.0 if prev is None else math.hypot(float(np.linalg.norm(x[k] - x[prev])), (omega[k] - omega[prev]) / 100.0)
        mon.push(ContinuationPoint(k, float(omega[k]), x[k], True, 0.0, 0, step, 0.0),
                 {"le_amplitude": float(amplitude[k])})
        prev = k
    mon.finish()
    # the neighbours' own crossings are located too: only the one between a and b is asked for
    pds = [bf for bf in mon.bifurcations if bf.kind == PERIOD_DOUBLING and bf.eigenvector is not None
           and bf.index == a]
    return pds[0] if pds else None


@dataclass(frozen=True)
class DoubledBranch:
    """The period-doubled branch born at a period doubling (omega = Omega / 2 content), m points
    ordered along the branch (the part continued towards decreasing Omega reversed, then the
    other part from the start point).

    found: whether the switch converged (reason otherwise, or the statuses of both parts).
    omega_bifurcation: Omega of the period doubling, rad/s. multiplier: its |mu| with sign
    (real part), -. subharmonic: nu of the new branch's basis; n_harmonics, n_time: its N_h,
    N_t. omega (m,) rad/s; x (m, n_u) the new residual's unknowns; le_amplitude (m,) m;
    stable (m,) bool, n_unstable (m,) int (hbm.stability.monitor along the branch);
    new_content (m,) share (2-norm) of the harmonics the old orbit lacks, the odd multiples
    of the new fundamental, -. start: index of the switch's start point in these arrays.
    """

    found: bool = field(metadata={"unit": "1"})
    reason: str
    omega_bifurcation: float = field(default=math.nan, metadata={"unit": "rad/s"})
    multiplier: float = field(default=math.nan, metadata={"unit": "1"})
    subharmonic: int = field(default=1, metadata={"unit": "1"})
    n_harmonics: int = field(default=0, metadata={"unit": "1"})
    n_time: int = field(default=0, metadata={"unit": "1"})
    omega: np.ndarray = field(default_factory=lambda: np.zeros(0), metadata={"unit": "rad/s"})
    x: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)), metadata={"unit": "1"})
    le_amplitude: np.ndarray = field(default_factory=lambda: np.zeros(0), metadata={"unit": "m"})
    stable: np.ndarray = field(default_factory=lambda: np.zeros(0, bool), metadata={"unit": "1"})
    n_unstable: np.ndarray = field(default_factory=lambda: np.zeros(0, int), metadata={"unit": "1"})
    new_content: np.ndarray = field(default_factory=lambda: np.zeros(0), metadata={"unit": "1"})
    start: int = field(default=-1, metadata={"unit": "1"})


def new_content(residual, u: np.ndarray, period_ratio: int) -> float:
    """Share (2-norm) of u's harmonics on the frequencies an orbit of period T / g (g =
    period_ratio, in the old basis) lacks once doubled: in the new basis, the harmonics that
    are not multiples of g (g even: same basis) or the odd ones (g odd: basis of Omega / 2 nu)."""
    xr = residual.to_coefficients(u)
    orders = residual.basis.orders
    mask = (orders % period_ratio) != 0 if period_ratio % 2 == 0 else (orders % 2) == 1
    return float(np.linalg.norm(xr[mask]) / max(np.linalg.norm(xr), 1e-300))


#: switch_branch's steps, tried in turn from each start: 1e-2 first; a point far past the
#: bifurcation (a multiplier well beyond -1 when the branch's points are far apart) may need
#: a shorter or a longer one
SWITCH_STEPS = (1e-2, 3e-3, 3e-2, 1e-3)


def switch_to_doubled(residual, starts, bifurcation: Bifurcation) -> BranchStart:
    """The branch switch at a period doubling (hbm.stability.switching.switch_branch) from
    the first of `starts` [(u (n_u,), Omega rad/s), ...] and step of SWITCH_STEPS where its
    Newton converges; the last attempt when none does. More than one start because DLFT's
    residual is not smooth: from a point where the contact's time samples sit on a kink,
    Newton stalls (on the coarse rotor 67 DLFT NFRC at 1459.6 rad/s, at |R| 6e-5 with every
    step), and from a stored point beside it (there, the one on the stable side) it
    converges to the doubled orbit.
    Raises ValueError as switch_branch (not a period doubling with its mode)."""
    st = None
    for u, omega in starts:
        for step in SWITCH_STEPS:
            st = switch_branch(residual, u, float(omega), bifurcation, step=step)
            if st.newton.converged:
                return st
    if st is None:
        raise ValueError("switch_to_doubled needs at least one start point")
    return st


def continue_doubled_branch(residual, u: np.ndarray, omega: float, bifurcation: Bifurcation,
                            continuation: ContinuationOptions, n_points: int = 40,
                            stability: StabilityOptions = StabilityOptions(), more_starts=()):
    """Switch to the period-doubled branch at `bifurcation` (hbm.stability.switching) and
    continue it both ways, at most n_points each way, with the stability of its points.

    residual, u (n_u,), omega (rad/s): the old branch's residual and the point on the
    bifurcation's unstable side. continuation: the old branch's continuation settings (its
    range, steps and Newton test; direction and max_points are set here). more_starts:
    [(u, omega)] tried in turn where the switch from (u, omega) does not converge
    (switch_to_doubled; e.g. LocatedDoubling.switch_starts(...)[1:]).
    Returns (DoubledBranch, the new branch's HarmonicBalanceResidual or None).
    """
    # a period doubling's exponent has Im = omega' / 2 (mod omega', omega' = mode_omega) for
    # Hill's exact problem; DLFT's truncated one moves it by ~1 1/s (hbm.stability.bifurcation
    # REAL_ARG_TOL), and the mode's frequencies must be exact harmonics of the new basis
    beta = bifurcation.exponent.imag
    half = 0.5 * bifurcation.mode_omega
    bif = replace(bifurcation, exponent=complex(bifurcation.exponent.real, round(beta / half) * half))
    starts = [(u, omega), *more_starts]
    try:
        st = switch_to_doubled(residual, starts, bif)
    except ValueError as exc:
        return DoubledBranch(False, f"no branch switch: {exc}", omega_bifurcation=float(bifurcation.omega),
                             multiplier=float(np.real(bifurcation.multiplier))), None
    if not st.newton.converged:
        return DoubledBranch(False, f"the branch switch did not converge from {len(starts)} start point(s) with "
                                    f"steps 1e-3 to 3e-2: {st.newton.reason}",
                             omega_bifurcation=float(bifurcation.omega),
                             multiplier=float(np.real(bifurcation.multiplier))), None
    new = st.residual
    g = int(bifurcation.period_ratio)
    parts, statuses = [], []
    for direction in (-1, 1):
        rows: dict[int, tuple] = {}
        mon = StabilityMonitor.for_residual(new, stability, newton=continuation.newton)

        def keep(items, rows=rows):
            for q, ex in items:
                rows[q.index] = (q.omega, q.x, ex["le_amplitude"], bool(ex["stable"]), int(ex["n_unstable"]))

        def on_point(p, mon=mon, keep=keep):
            if p.converged:
                keep(mon.push(p, nfrc_extras(new, p.x)))

        opts = replace(continuation, direction=direction, max_points=n_points)
        br = continue_branch(new, st.u, st.omega, opts, on_point=on_point,
                             solver=HbmSolver(atol=0.1 * opts.newton.tol_residual))
        keep(mon.finish())
        statuses.append(f"{'down' if direction < 0 else 'up'}: {br.status}")
        parts.append([rows[k] for k in sorted(rows)])
    down, up = parts
    pts = down[::-1] + up[1:] if down else up
    if not pts:
        return DoubledBranch(False, "no converged point on the doubled branch: " + "; ".join(statuses)), new
    om, xs, amp, stab, nun = (np.array([p[k] for p in pts]) for k in range(5))
    return DoubledBranch(True, f"switch at Omega = {st.omega:.6g} rad/s (new content {st.odd_content:.3g}); "
                               + "; ".join(statuses),
                         omega_bifurcation=float(bifurcation.omega), multiplier=float(np.real(bifurcation.multiplier)),
                         subharmonic=int(new.nu), n_harmonics=int(new.basis.n_harmonics),
                         n_time=int(new.basis.n_time), omega=om.astype(float), x=xs.astype(float),
                         le_amplitude=amp.astype(float), stable=stab.astype(bool), n_unstable=nun.astype(int),
                         new_content=np.array([new_content(new, xi, g) for xi in xs]),
                         start=max(len(down) - 1, 0)), new
