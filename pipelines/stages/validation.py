"""Stage validation: the paper's three validation points (section 3.3, Figs. 9 and 10), chosen
automatically for each contact treatment, time integration marched from each and compared
with both HBM treatments (validation.h5); the full view of the solution set (Fig. 8); and
the dynamical content along the isolas and along every branch (Figs. 11-12).

For each treatment of [hbm] methods:
- primary: a stable point near the primary resonance of its NFRC (hbm.stability.selection.
  choose_point: the stored verdicts when the NFRC was computed with [hbm] stability, else
  Floquet analyses of a few points near the peak, and when none of those is stable the
  NFRC's stability computed here along the whole branch, as [hbm] stability would have
  stored it: on rotor 67 the stable stretches of the NFRCs are short and away from the
  peak); when time integration leaves it, the next
  one outside its stable stretch whose verdict the march can check (DECISIVE_DECAY), up to
  [validation] primary_tries in all, until it stays; a stable choice is first solved again
  with 2 N_h (check_harmonics) and passed over, unmarched, when it is not converged in N_h;
- isola: a point (stable if any) of a branch of isolas.h5 in the scene's basis (not the
  search's period-doubled ones) that never meets the primary: of kind "isola" first, then
  "detached" (an isola that the Omega range cuts: on the coarse
  rotor 67 ROM the detached 400-1188 rad/s branch carries stable orbits that time
  integration keeps, where the closed isolas have one stable stretch or none), when that
  file exists and holds one (else the reason is recorded); chosen as the primary point is
  (stored verdicts, else analyses near each branch's peak, and when no branch has a stable
  point there, each branch's stability computed along it in turn until one has) and tried
  again as it is, up to [validation] isola_tries; when time integration keeps none of
  those (or there are none), the same on the closed isolas of the period-doubled search;
- period doubling: the first period doubling of the NFRC (its bifurcation table, or located
  here by a bounded scan, and from the NFRC's stability computed along it when the scan
  finds none whose branch switch converges), the period-doubled branch switched to there
  and continued both ways (stored here), and a point of it (stable if any, checked with 2 N_h as the primary
  point is: one that fails is passed over for the next stable choice of the same branch,
  unmarched; a switched branch with no stable point, a subcritical doubling's, is passed over
  for the next try and marched only when no try gives a point); when time integration leaves
  that point, the isola search's own branches of
  twice the period (searched_doubled_branches: its second search, seeded from the sweep),
  then the NFRC's other period doublings where a stable stretch begins or ends, the longest
  stretch first (from its stability, computed here if neither its file nor the primary
  point's choice holds it), then the period doublings that end stable stretches of the
  search's branches (doubling_candidates), up to [validation] pd_tries in all, until it stays
  on one.
From each point time integration is marched [validation] n_periods periods of the orbit
(hbm.ti.validation.march_from_hbm); when it leaves a stable point for anything but the
friction lock, it is marched again with [validation] dt / dt_refinement, and that march
is the verdict (the step's error, not the orbit, may be what left). Its last period is
compared with the orbit itself and
with the other treatment's orbit at the same Omega, corrected by damped Newton from the
point (not the nearest point of the other NFRC: the other treatment's branch need not pass
there, e.g. on an isola or the period-doubled branch).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from hbm.stability.bifurcation import GUESS, PERIOD_DOUBLING, kind_sources
from hbm.stability.selection import DoubledBranch
from hbm.ti.validation import DEVIATION_TOL, GROWTH_TOL, LANDING_TOL, OrbitComparison, OrbitValidation
from pipelines import artifacts as art
from pipelines.stages.base import Context, Figure, Output, Stage
from pipelines.stages.hbm import nfrc_output
from pipelines.stages.rom import past_friction_lock, read_rom
from pipelines.stages.treatments import run_treatments

VALIDATION = Output("validation.h5")

#: The isolas stage's artifact: the isola validation point is taken from it.
ISOLAS = "isolas.h5"
UPSTREAM = ("rom", "hbm", "isolas")
#: kinds of isolas.h5 branches the isola point is taken from, in this order of preference
ISOLA_KINDS = ("isola", "detached")

KINDS = ("primary", "isola", "period_doubling")


@dataclass(frozen=True)
class ValidationPoint:
    """One validation point and what time integration says of it.

    kind: "primary", "isola" or "period_doubling". method: the treatment whose branch it lies
    on. found: whether there is one (reason: how it was chosen, or why there is none).
    branch: where it lies, in words (file and branch). index: its index there. omega: Omega,
    rad/s. subharmonic: nu of its basis (the orbit's period 2 pi nu / Omega). u: its
    unknowns, (n_u,). le_amplitude: m. stable, verdict, n_unstable, multiplier: its stability
    (hbm.stability.selection.ChosenPoint). ti: the march from it; dlft, rl: each treatment's
    orbit at that Omega against the march (hbm.ti.validation.OrbitComparison: the RL force is
    the sigma-filtered one of the RL-HBM equilibrium), absent when not found.
    refined_from: when the march with [validation] dt left a stable point for anything but the
    friction lock and the point was marched again with dt / [validation] dt_refinement (ti,
    dlft and rl are then from that march, [validation] dt its step): the first march's verdict and
    step, in words; "" otherwise.
    """

    kind: str
    method: str
    found: bool = field(metadata={"unit": "1"})
    reason: str
    branch: str = ""
    index: int = field(default=-1, metadata={"unit": "1"})
    omega: float = field(default=float("nan"), metadata={"unit": "rad/s"})
    subharmonic: int = field(default=1, metadata={"unit": "1"})
    u: np.ndarray = field(default_factory=lambda: np.zeros(0), metadata={"unit": "1"})
    le_amplitude: float = field(default=float("nan"), metadata={"unit": "m"})
    stable: bool = field(default=False, metadata={"unit": "1"})
    verdict: str = ""
    n_unstable: int = field(default=-1, metadata={"unit": "1"})
    multiplier: float = field(default=float("nan"), metadata={"unit": "1"})
    ti: OrbitValidation | None = None
    dlft: OrbitComparison | None = None
    rl: OrbitComparison | None = None
    refined_from: str = ""


@dataclass(frozen=True)
class TreatmentValidation:
    """The three points of one treatment, and its period-doubled branch.

    method: "dlft" or "rl". cpu_time: process CPU time spent on this treatment, s.
    pd_branch: hbm.stability.selection.DoubledBranch (found False with the reason when there
    is no period doubling or the switch failed). nfrc_stable: (m,) bool, the stable flag of
    each NFRC point when the stage computed the NFRC's stability (its file holding none),
    else empty; nfrc_stability: where it comes from, in words ("" when not computed).
    """

    method: str
    primary: ValidationPoint
    isola: ValidationPoint
    period_doubling: ValidationPoint
    pd_branch: DoubledBranch
    cpu_time: float = field(metadata={"unit": "s"})
    nfrc_stable: np.ndarray = field(default_factory=lambda: np.zeros(0, bool), metadata={"unit": "1"})
    nfrc_stability: str = ""


@dataclass(frozen=True)
class ValidationArtifact:
    """What validation.h5 holds: one TreatmentValidation per treatment of [hbm] methods.
    isolas: how isolas.h5 was used ("absent" or its path). growth_tol, deviation_tol: the
    stated tolerances of "TI stays on the orbit" (hbm.ti.validation.GROWTH_TOL,
    DEVIATION_TOL), -. cpu_time: the stage's CPU time, s (its treatments' summed, each in the
    process that ran it, or the stage's own process's when that is larger)."""

    isolas: str
    growth_tol: float = field(metadata={"unit": "1"})
    deviation_tol: float = field(metadata={"unit": "1"})
    cpu_time: float = field(metadata={"unit": "s"})
    dlft: TreatmentValidation | None = None
    rl: TreatmentValidation | None = None


def read_validation(out: Path) -> ValidationArtifact:
    return art.read_artifact(Path(out) / VALIDATION.file, ValidationArtifact)


# -- isolas.h5 ---------------------------------------------------------------------------------
def read_branch_set(path: Path, method: str) -> list:
    """The branches (pipelines.stages.isolas.IsolaBranch) of one treatment in isolas.h5 ([]
    when the file or the treatment's group is absent)."""
    from pipelines.stages.isolas import read_isolas

    path = Path(path)
    return read_isolas(path).get(method, []) if path.is_file() else []


# -- compute -----------------------------------------------------------------------------------
def _pd_brackets(path: Path):
    """Indices after which the NFRC file's bifurcation table places a period doubling, or None
    when the file holds no stability (no table)."""
    import h5py

    from hbm.stability.bifurcation import PERIOD_DOUBLING

    with h5py.File(path, "r") as h5:
        if "bifurcations" not in h5:
            return None
        g = h5["bifurcations"]
        kinds = [k.decode() if isinstance(k, bytes) else str(k) for k in g["kind"][()]]
        return [int(i) for i, k in zip(g["index"][()], kinds) if k == PERIOD_DOUBLING]


def _options_for(hbm, n_u: int, n_r: int, nu: int):
    """The scene's HbmOptions for unknowns of size n_u in the basis of Omega / nu."""
    n_h = (n_u // n_r - 1) // 2
    ratio = max(1, round(n_h / hbm.n_harmonics))
    return replace(hbm, subharmonic=int(nu), n_harmonics=int(n_h), n_time=max(hbm.n_time * ratio, 2 * n_h + 2))


def _validate(ctx, rom, system, kind, method, chosen, residual, branch, dt: float | None = None,
              previous: ValidationPoint | None = None) -> ValidationPoint:
    """March from a chosen point with step dt (s; None: [validation] dt) and compare with both
    treatments' orbits at its Omega (those of `previous`, the same point's earlier march,
    when given: the orbits do not depend on the step)."""
    from hbm.harmonic.residual import build_residual
    from hbm.harmonic.solver import HbmSolver
    from hbm.harmonic.start import damped_newton
    from hbm.continuation.newton import NewtonOptions
    from hbm.stability.spectrum import orbit_spectrum
    from hbm.ti.validation import compare_again, compare_with_hbm, confirm_orbit, march_from_hbm

    scene = ctx.scene
    if not chosen.found:
        return ValidationPoint(kind, method, False, chosen.reason, branch)
    u, omega, nu = chosen.u, chosen.omega, residual.nu
    ti = march_from_hbm(system, scene.casing, scene.contact.mu, residual.expand_harmonics(u, omega), omega,
                        subharmonic=nu, n_periods=scene.validation.n_periods,
                        dt=scene.validation.dt if dt is None else dt, record_all=True)
    # the distance rule cannot tell the orbit from another solution next to it: the HBM
    # solution through the march's last period can
    ti = confirm_orbit(residual, ti, u, omega)
    comps = {}
    for m in ("dlft", "rl"):
        if previous is not None:
            comps[m] = compare_again(ti, getattr(previous, m))
            continue
        if m == method:
            res, sol_u, src = residual, u, "the point itself"
        else:
            res = build_residual(rom, scene.casing, scene.contact, residual.options, method=m)
            sol = damped_newton(res, res.to_unknowns(residual.to_coefficients(u)), omega,
                                NewtonOptions(tol_residual=scene.hbm.tolerance),
                                HbmSolver(atol=0.1 * scene.hbm.tolerance))
            if not sol.converged:
                comps[m] = compare_with_hbm(ti, None, None, f"damped Newton at the same Omega from the point "
                                                            f"failed: {sol.reason}")
                continue
            sol_u = sol.x
            dist = np.linalg.norm(sol.x - u) / max(np.linalg.norm(u), 1e-300)
            src = f"damped Newton at the same Omega from the point ({sol.iterations} iterations, moved {dist:.3g})"
        if m == method and chosen.n_unstable >= 0 and np.isfinite(chosen.multiplier):
            mu, n_unstable = chosen.multiplier, chosen.n_unstable  # the choice analysed this orbit already
        else:
            sp, _ = orbit_spectrum(res, sol_u, omega)
            mu, n_unstable = sp.largest_modulus, sp.n_unstable
        comps[m] = replace(compare_with_hbm(ti, res.expand_harmonics(sol_u, omega), res.signals(sol_u, omega)["lam"],
                                            src, sigma=res.sigma), multiplier=float(mu), n_unstable=int(n_unstable))
    return ValidationPoint(kind, method, True, chosen.reason, branch, chosen.index, omega, nu, np.asarray(u, float),
                           chosen.le_amplitude, chosen.stable, chosen.verdict, chosen.n_unstable, chosen.multiplier,
                           ti, comps["dlft"], comps["rl"])


def _treatment(ctx, rom, system, method: str, update) -> TreatmentValidation:
    from hbm.harmonic.residual import build_residual
    from pipelines.branch_store import load_branch

    scene, opts = ctx.scene, ctx.scene.validation
    c0 = time.process_time()
    path = ctx.out / nfrc_output(method).file
    stored = load_branch(path)
    # a file without points (the hbm stage found no start) holds no extras either
    b, ex = stored.branch, {"le_amplitude": np.zeros(0), **stored.extras}
    res = build_residual(rom, scene.casing, scene.contact, scene.hbm, method=method)
    tag = method.upper()
    nfrc = Candidate(path.name, res, b.omega, b.x, ex["le_amplitude"], b.converged, ex.get("stable"),
                     monitor=_branch_monitor(scene.hbm))
    update(f"{tag}: a stable point near the primary resonance")
    primary = _try_until_kept(ctx, rom, system, "primary", method, [nfrc], opts.primary_tries, update)
    # isola
    isolas = ctx.out / ISOLAS
    branches = read_branch_set(isolas, method)
    lock = lambda br: locked_branch(br, scene.contact.mu, rom)  # noqa: E731
    groups = [g for g in isola_branches(branches, scene.hbm.subharmonic, locked=lock) if g]
    if not isolas.is_file():
        isola = ValidationPoint("isola", method, False, f"no {ISOLAS} in the output folder (the isolas stage has not run)")
    elif not groups:
        artefacts = [br.name for g in isola_branches(branches, scene.hbm.subharmonic, artefacts=True, locked=lock)
                     for br in g]
        locks = [br.name for g in isola_branches(branches, scene.hbm.subharmonic) for br in g if lock(br)]
        left = (f" (left out, none of their points holds with twice the harmonics: {', '.join(artefacts)})"
                if artefacts else "") + (f" (left out, the friction lock: {', '.join(locks)})" if locks else "")
        isola = ValidationPoint("isola", method, False, f"{ISOLAS} holds no branch of kind "
                                                         f"{' or '.join(map(repr, ISOLA_KINDS))} for {method}, "
                                                         f"nor an isola of its period-doubled search{left}")
    else:
        update(f"{tag}: a point on an isola")

        def try_group(branches):
            cands = []
            for br in branches:
                hbm = _options_for(scene.hbm, br.x.shape[1], res.n_r, br.subharmonic)
                cands.append(Candidate(f"{ISOLAS} {method}/branches/{br.name}",
                                       build_residual(rom, scene.casing, scene.contact, hbm, method=method),
                                       br.omega, br.x, br.le_amplitude, br.converged, br.stable,
                                       monitor=_branch_monitor(hbm)))
            return _try_until_kept(ctx, rom, system, "isola", method, cands, opts.isola_tries, update)

        isola = first_kept(groups, try_group)
    # period doubling
    pd, pd_branch = _period_doubling(ctx, rom, system, method, res, b, ex, path, update, nfrc)
    computed = nfrc._stability is not None  # kept for Fig. 8 and the user: 800-1200 analyses on rotor 67
    return TreatmentValidation(method, primary, isola, pd, pd_branch, time.process_time() - c0,
                               nfrc.stable if computed else np.zeros(0, bool), nfrc.computed_words() if computed else "")


@dataclass(eq=False)
class Candidate:
    """A branch a validation point may be taken from. where: its file and group, in words.
    residual: its HarmonicBalanceResidual. omega (m,) rad/s, x (m, n_u), amplitude (m,) m,
    converged (m,) bool, stable (m,) bool or None: the branch. eligible: (m,) bool, the
    points not yet ruled out (the stable stretches of points time integration left).
    monitor: (x_scale, omega_scale, StabilityOptions) under which a branch stored without
    stability may have it computed (stability()), or None: never."""

    where: str
    residual: object
    omega: np.ndarray
    x: np.ndarray
    amplitude: np.ndarray
    converged: np.ndarray
    stable: np.ndarray | None
    eligible: np.ndarray = None
    monitor: tuple | None = None
    _chosen: dict = field(default_factory=dict, repr=False)  # margin -> ChosenPoint, until rule_out
    _stability: object = field(default=None, repr=False)

    def __post_init__(self):
        if self.eligible is None:
            self.eligible = np.ones(len(self.omega), bool)

    def choose(self, n_candidates: int, margin: float, analyse_along: bool = True):
        """choose_point on the eligible points; kept until rule_out, so that a branch passed
        over on one try is not analysed again on the next. When the branch holds no
        stability, none of the candidates near its peak is stable, `monitor` is given and
        analyse_along, the branch's stability is computed (stability()) and the choice made
        from it."""
        from hbm.stability.selection import choose_point

        def choose():
            source = "the branch file" if self._stability is None else self.computed_words()
            return choose_point(self.residual, self.omega, self.x, self.amplitude, self.converged, self.stable,
                                eligible=self.eligible, n_candidates=n_candidates, margin=margin, verdicts_from=source)

        if margin not in self._chosen:
            self._chosen[margin] = choose()
        ch = self._chosen[margin]
        if analyse_along and ch.found and not ch.stable and self.stable is None and self.monitor is not None:
            self.stability()
            ch = self._chosen[margin] = choose()
        return ch

    def computed_words(self) -> str:
        """Where the stable flags of stability() come from, in words."""
        return f"the branch's stability computed here ({self._stability.n_analyses} Floquet analyses along it)"

    def stability(self):
        """hbm.stability.selection.branch_stability of the branch, computed once (monitor:
        (x_scale, omega_scale, StabilityOptions)); its stable flags become the branch's."""
        from hbm.stability.selection import branch_stability

        if self._stability is None:
            x_scale, omega_scale, options = self.monitor
            self._stability = branch_stability(self.residual, self.omega, self.x, self.converged, x_scale=x_scale,
                                               omega_scale=omega_scale, options=options)
            self.stable = self._stability.stable
            self._chosen.clear()  # choices made without it
        return self._stability

    def rule_out(self, index: int) -> None:
        """Rule out the stable stretch of point `index` (hbm.stability.selection.stable_stretch)."""
        from hbm.stability.selection import stable_stretch

        lo, hi = stable_stretch(self.residual, self.omega, self.x, self.converged, index, self.stable)
        self.eligible[lo: hi + 1] = False
        self._chosen.clear()


#: A retry asks for a verdict the march can check: its largest multiplier must shrink a
#: perturbation by e^DECISIVE_DECAY (to 5 %) over the march, log|mu| < -DECISIVE_DECAY /
#: n_periods. The first try's largest stable amplitude lies next to the fold or bifurcation
#: that ends its stretch, where |mu| is close to 1: at |mu| = 0.994 (coarse rotor 67, DLFT,
#: 1461 rad/s) a perturbation keeps 55 % of itself over 100 periods, and the march, whose
#: distance to the orbit stays bounded, fails the growth bound (hbm.ti.validation).
DECISIVE_DECAY = 3.0


def isola_branches(branches, nu: int, artefacts: bool = False, locked=None) -> tuple[list, list]:
    """The branches of isolas.h5 (IsolaBranch list) the isola point is taken from, in two
    groups tried in turn: those of the scene's basis (subharmonic nu) of kind "isola", then
    "detached" (ISOLA_KINDS); then the closed isolas of the period-doubled search
    (subharmonic 2 nu), isolas still, whose orbits have twice the period. The search's other
    doubled branches are born at period doublings: the period-doubling point's. A branch none
    of whose checked points holds with twice the harmonics (harmonic_verdict "not converged")
    is left out: its orbits are the truncation's, which a march from them would only measure
    (artefacts=True: those left out instead, in the same two groups). locked(branch) -> bool:
    branches left out in either case, the friction lock's (locked_branch): an orbit of the
    model past its mu_set, not an isola of the blade."""
    def kept(br) -> bool:
        return (br.harmonic_verdict == "not converged") == artefacts and not (locked is not None and locked(br))

    own = [br for kind in ISOLA_KINDS for br in branches if br.subharmonic == nu and br.kind == kind and kept(br)]
    return own, [br for br in branches if br.subharmonic == 2 * nu and br.kind == "isola" and kept(br)]


def first_kept(groups: list, try_group) -> ValidationPoint:
    """The isola point from groups of branches tried in turn (isola_branches' two):
    try_group(branches) -> ValidationPoint for each until time integration stays on one. The
    point kept, else the first found (the scene's basis first: its own isolas are the
    search's answer), else the first; its reason ends with each other group's try."""
    tried = []
    for branches in groups:
        tried.append(try_group(branches))
        if tried[-1].ti is not None and tried[-1].ti.stays:
            break
    last = tried[-1]
    point = last if last.ti is not None and last.ti.stays else next((p for p in tried if p.found), tried[0])
    others = [f"also tried, {p.branch or 'no branch'}: {p.reason}" for p in tried if p is not point]
    return replace(point, reason="; ".join([point.reason, *others])) if others else point


def _try_until_kept(ctx, rom, system, kind: str, method: str, candidates: list, tries: int, update) -> ValidationPoint:
    """The primary or isola point: a stable point chosen on the candidate branches (the first
    branch with a stable choice near its peak, else the first whose stability computed along
    it (Candidate.monitor) gives one, else the first with any), marched; when time integration
    leaves it, the next choice outside the stable stretches of the points already tried (the
    stable neighbours of a point that time integration leaves are orbits of the same family,
    and leave too), with a decisive verdict (DECISIVE_DECAY), up to `tries` marches in all,
    until it stays. Before a stable choice is marched it is solved again with twice the
    harmonics (check_harmonics, up to [validation] harmonic_checks per point): one that is not
    converged in N_h is not marched, and its stretch is ruled out as a left one's. The first
    try is kept when none stays; the reason lists every try and check that failed."""
    from hbm.stability.convergence import check_harmonics
    from hbm.stability.selection import STABILITY_MARGIN

    opts, tag = ctx.scene.validation, method.upper()
    first, kept, tried, marched, checked = None, None, [], 0, 0
    fallback = None  # the first stable choice that failed its check: marched when nothing else is left
    while marched < tries:
        margin = STABILITY_MARGIN if marched == 0 else max(STABILITY_MARGIN, DECISIVE_DECAY / opts.n_periods)
        # the candidates near every branch's peak first; a branch's stability along it (hundreds
        # of analyses) only when no branch has a stable one there
        for analyse_along in (False, True):
            best, none = None, []
            for c in candidates:
                ch = c.choose(opts.n_candidates, margin, analyse_along)
                if not ch.found:
                    none.append(ch.reason)
                elif best is None or (ch.stable and not best[1].stable):
                    best = (c, ch)
                if best is not None and best[1].stable:
                    break
            if best is not None and best[1].stable:
                break
        unchecked = False
        if best is None or (not best[1].stable and (first is not None or fallback is not None)):
            if first is None and fallback is not None:  # nothing marched yet: rather a point than none
                best, fallback, unchecked = fallback, None, True
                tried.append("no stable point left that passes the check: the first checked is marched")
            else:
                why = (best[1].reason if best else none[0] if len(none) == 1 else
                       f"no converged point left on the {len(candidates)} branches")
                first = first or ValidationPoint(kind, method, False, why, candidates[0].where)
                tried.append(f"no stable point left ({why})")
                break
        c, ch = best
        if ch.stable and not unchecked and checked < opts.harmonic_checks:
            update(f"{tag} {kind} point at {ch.omega:.1f} rad/s: solved again with twice the harmonics")
            check = check_harmonics(c.residual, ch.u, ch.omega)
            checked += 1
            if not check.passed:  # not an orbit of the ODE: no march; its stable neighbours lie by the same fold
                tried.append(f"{ch.omega:.1f} rad/s{'' if len(candidates) == 1 else ' of ' + c.where} (stable), "
                             f"not marched: {check.reason}")
                fallback = fallback or (c, ch)
                update(f"{tag}: the stable stretch of the {ch.omega:.1f} rad/s point")
                c.rule_out(ch.index)
                continue
        update(f"{tag} {kind} point at {ch.omega:.1f} rad/s: {opts.n_periods} periods of time integration")
        p = _validate(ctx, rom, system, kind, method, ch, c.residual, c.where)
        marched += 1
        if _worth_refining(p, rom, ctx.scene.contact.mu, opts.dt_refinement):
            fine = opts.dt / opts.dt_refinement
            update(f"{tag} {kind} point at {ch.omega:.1f} rad/s: time integration left it; marched again "
                   f"with dt = {fine:.3g} s")
            first_words = f"{ti_verdict(p.ti, rom, ctx.scene.contact.mu)} with dt = {p.ti.dt:.3g} s"
            p = replace(_validate(ctx, rom, system, kind, method, ch, c.residual, c.where, dt=fine, previous=p),
                        refined_from=first_words)
        words = ti_verdict(p.ti, rom, ctx.scene.contact.mu)
        tried.append(f"{p.omega:.1f} rad/s{'' if len(candidates) == 1 else ' of ' + c.where} "
                     f"({'stable' if p.stable else 'unstable'}), time integration "
                     + (f"{p.refined_from}, {words} with dt = {p.ti.dt:.3g} s" if p.refined_from else words))
        first = first or p
        if p.ti is not None and p.ti.stays:
            kept = p
            break
        if not ch.stable or marched == tries:  # unstable: the next choice would be too
            break
        if not unchecked:  # the fallback's stretch was ruled out when its check failed
            update(f"{tag}: the stable stretch of the {ch.omega:.1f} rad/s point")
            c.rule_out(ch.index)
    result = kept or first
    if len(tried) > 1:
        result = replace(result, reason=f"{result.reason}; {marched} marched, {checked} checked with 2 N_h: "
                                        + " | ".join(tried))
    return result


def doubling_candidates(branches) -> list:
    """[(branch, index)]: the period doublings of isola-search branches (IsolaBranch with a
    bifurcation table and stable flags) where a stable stretch begins or ends, the
    longest stretch first; index: the branch point after which the doubling lies. Why these:
    a supercritical doubling hands the old orbit's stability on to the doubled branch, and
    the longest stable stretches are the likeliest to be the stable orbits that time
    integration keeps (a heuristic: on the coarse rotor 67 ROM the third candidate of DLFT
    and the second of RL were the first kept)."""
    out = []
    for br in branches:
        t, st = br.bifurcations, br.stable
        if t is None or st is None:
            continue
        st = np.asarray(st, bool)
        for kind, i in zip(t["kind"], np.asarray(t["index"], dtype=np.int64)):
            i = int(i)
            if kind != PERIOD_DOUBLING or not 0 <= i < len(st) - 1 or st[i] == st[i + 1]:
                continue
            j = i if st[i] else i + 1
            lo, hi = j, j
            while lo > 0 and st[lo - 1]:
                lo -= 1
            while hi + 1 < len(st) and st[hi + 1]:
                hi += 1
            out.append((hi - lo + 1, br, i))
    out.sort(key=lambda c: -c[0])  # stable sort: branch order, then position, among equal stretches
    return [(br, i) for _, br, i in out]


def searched_doubled_branches(branches, nu: int) -> list:
    """The isola search's branches in the basis of twice the scene's period (subharmonic 2 nu:
    its second search, seeded from the sweep's omega = Omega / 2 points), those that more sweep
    points landed on first. Why first: time integration from rest ended on them, so they hold
    the doubled orbits a blade is found on, where a doubling of the NFRC may lead into the
    friction lock (coarse rotor 67 ROM). A branch none of whose checked points holds with twice
    the harmonics is left out (isola_branches)."""
    doubled = [br for br in branches if br.subharmonic == 2 * nu and br.harmonic_verdict != "not converged"]
    return sorted(doubled, key=lambda br: -len(br.seeds))  # stable: file order among equals


#: A doubled branch of the isola search is validated near the speeds of its seeds, within
#: this fraction of them: time integration from rest ended on its orbit there, whereas its
#: largest stable amplitude elsewhere may lead into the friction lock (coarse rotor 67 ROM,
#: DLFT: the points at 811.7 and 702.3 rad/s of the branches seeded at 850 and 1110 rad/s).
SEED_WINDOW = 0.02


def _searched_point(ctx, rom, system, method: str, n_r: int, where: str, br, update):
    """(ValidationPoint, DoubledBranch) of a doubled branch of the isola search (IsolaBranch):
    a point carrying the Omega / 2 harmonics within SEED_WINDOW of a seed's speed (anywhere
    on the branch when there is none), chosen and marched as the switched branches' are."""
    from hbm.harmonic.residual import build_residual
    from hbm.stability.selection import new_content

    scene = ctx.scene
    hbm = _options_for(scene.hbm, br.x.shape[1], n_r, br.subharmonic)
    r_b = build_residual(rom, scene.casing, scene.contact, hbm, method=method)
    content = np.array([new_content(r_b, u, 2) for u in br.x])
    far = (content >= 0.05) & np.asarray(br.converged, bool)  # as on a switched branch: not the old orbit
    seeds = np.asarray(br.seed_omega if br.seed_omega is not None else [], float)
    near = far & np.any(np.abs(np.asarray(br.omega)[:, None] - seeds[None, :]) <= SEED_WINDOW * seeds[None, :], axis=1)
    far = near if near.any() else far
    # no monitor: a branch stored without stability is not analysed along its whole length
    # (hundreds of analyses of twice the size, ~20 min a branch on the coarse scene); the
    # candidates near its seeds decide, and when none is stable the march does
    c = Candidate(where, r_b, br.omega, br.x, br.le_amplitude, br.converged, br.stable,
                  eligible=far if far.any() else None)
    p = _try_until_kept(ctx, rom, system, "period_doubling", method, [c], 1, update)
    stable = c.stable if c.stable is not None else np.zeros(0, bool)
    n_unstable = br.n_unstable if br.n_unstable is not None else np.zeros(0, int)
    reason = (f"{where}: a {br.kind} branch of the isola search in the basis of Omega / {br.subharmonic} "
              f"({len(br.seeds)} seed(s); {br.status})")
    return p, DoubledBranch(True, reason, subharmonic=br.subharmonic, n_harmonics=hbm.n_harmonics,
                            n_time=hbm.n_time, omega=np.asarray(br.omega, float), x=np.asarray(br.x, float),
                            le_amplitude=np.asarray(br.le_amplitude, float), stable=np.asarray(stable, bool),
                            n_unstable=np.asarray(n_unstable, int), new_content=content)


#: In _period_doubling's list of tries: the NFRC's doublings after the first, whose brackets
#: may need its stability (hundreds of analyses), computed only when the earlier tries failed.
_LATER = ("the NFRC's other period doublings",)


@dataclass(frozen=True)
class _Doublings:
    """A branch's period doublings and stable flags in the shape doubling_candidates reads."""

    bifurcations: dict
    stable: np.ndarray


def _branch_monitor(hbm) -> tuple:
    """Candidate.monitor of a branch computed with `hbm`: the continuation's scales and the
    scene's stability gap."""
    from hbm.harmonic.nfrc import default_continuation
    from hbm.stability.monitor import StabilityOptions

    co = default_continuation(hbm)
    return co.x_scale, co.omega_scale, StabilityOptions.of(hbm)


def _period_doubling(ctx, rom, system, method: str, res, b, ex, path: Path, update, nfrc: Candidate | None = None):
    """(ValidationPoint, DoubledBranch) of the period-doubling point: the NFRC's first period
    doubling, then searched_doubled_branches of isolas.h5, the NFRC's other doublings (ranked
    as doubling_candidates ranks a branch's; the NFRC's stability is computed for them only
    once the earlier tries have failed) and doubling_candidates of isolas.h5, up to
    [validation] pd_tries, until time
    integration stays on the doubled branch's chosen point (the first try marched is kept when
    none does; a switched branch with no stable point is marched only when no other try gives
    a point; the reason lists every try). An NFRC stored without stability: its doublings from
    the branch stability that nfrc (Candidate of the NFRC with a monitor) computed for the
    primary point, else from a scan; when the scan finds none, or none whose branch switch
    converges, from that stability computed here."""
    from hbm.harmonic.nfrc import default_continuation
    from hbm.harmonic.residual import build_residual
    from hbm.stability.bifurcation import PERIOD_DOUBLING
    from hbm.stability.selection import continue_doubled_branch, locate_period_doubling

    scene, opts, tag = ctx.scene, ctx.scene.validation, method.upper()

    def computed_brackets():
        return [bf.index for bf in nfrc.stability().bifurcations if bf.kind == PERIOD_DOUBLING]

    brackets, nfrc_from = _pd_brackets(path), "the branch file's bifurcation table"
    if brackets is None and nfrc is not None and nfrc._stability is not None:
        brackets = computed_brackets()
        nfrc_from = nfrc.computed_words()
    sources = [("the NFRC", res, b.omega, b.x, ex["le_amplitude"], b.converged, brackets)]
    # whether the NFRC's stability can be computed here: a doubling lies between two converged
    # points, and with fewer branch_stability would raise (e.g. an NFRC whose start failed)
    computable = (nfrc is not None and nfrc.monitor is not None
                  and np.count_nonzero(np.asarray(b.converged, bool)) >= 2)
    monitor_left = brackets is None and computable
    if opts.pd_tries > 1:
        found = read_branch_set(ctx.out / ISOLAS, method)
        # the search's own doubled branches first (time integration from rest ended on them),
        # then the NFRC's other doublings (their brackets once the first try is known: _LATER),
        # then the doublings of the search's branches, each switched to here
        for br in searched_doubled_branches(found, scene.hbm.subharmonic):
            sources.append((f"{ISOLAS} {method}/branches/{br.name}", br))
        sources.append(_LATER)
        for br, i in doubling_candidates(found)[: max(0, opts.pd_tries - len(sources))]:
            r_b = build_residual(rom, scene.casing, scene.contact,
                                 _options_for(scene.hbm, br.x.shape[1], res.n_r, br.subharmonic), method=method)
            sources.append((f"{ISOLAS} {method}/branches/{br.name}", r_b, br.omega, br.x, br.le_amplitude,
                            br.converged, [i]))
        del sources[opts.pd_tries:]

    def later_doublings(k: int) -> list:
        """The NFRC's doublings other than the first try's, as sources, at most the tries left
        after k: from its file's table, else from its stability (computed here when the stage
        has not yet: the first try's march left, and these are the next candidates)."""
        nonlocal nfrc_from
        brackets = _pd_brackets(path)
        stable = None if nfrc is None else nfrc.stable
        if brackets is None:
            if not computable:
                return []
            if nfrc._stability is None:
                update(f"{tag}: the NFRC's stability along the whole branch, for its other period doublings")
            brackets, stable, nfrc_from = computed_brackets(), nfrc.stable, nfrc.computed_words()
        near = [int(i) for i in first_bracket]
        left = [i for i in brackets if all(abs(int(i) - j) > 1 for j in near)]
        if stable is not None:
            ranked = doubling_candidates([_Doublings({"kind": [PERIOD_DOUBLING] * len(left), "index": left},
                                                     np.asarray(stable, bool))])
            left = [i for _, i in ranked]
        return [(f"the NFRC (its period doubling after point {i})", res, b.omega, b.x, ex["le_amplitude"],
                 b.converged, [i]) for i in left[: max(0, opts.pd_tries - k)]]

    def switch(r_s, loc, where, omega, x):
        """(DoubledBranch, its residual) switched to at loc (located on the branch omega, x),
        or None when nothing was located."""
        if loc.bifurcation is None:
            return None
        update(f"{tag}: period-doubled branch from Omega = {loc.bifurcation.omega:.1f} rad/s ({where})")
        return continue_doubled_branch(r_s, loc.u, loc.omega, loc.bifurcation, default_continuation(scene.hbm),
                                       n_points=opts.pd_points, more_starts=loc.switch_starts(omega, x)[1:])

    first, tried = None, []
    # the first switched branch without a stable point: (its index in tried, where, the located
    # Omega, its Candidate, its DoubledBranch)
    deferred = None
    first_bracket: tuple = ()  # the stored points around the NFRC's first try's doubling
    k = -1
    while k + 1 < len(sources):
        k += 1
        if sources[k] is _LATER:  # replaced by what it stands for, then index k again
            sources[k: k + 1] = later_doublings(k)
            del sources[opts.pd_tries:]
            k -= 1
            continue
        where, *source = sources[k]
        if len(source) == 1:  # a doubled branch of the isola search: no switch
            update(f"{tag}: the isola search's period-doubled branch {where}")
            result = _searched_point(ctx, rom, system, method, res.n_r, where, source[0], update)
            p = result[0]
            tried.append(f"{where} (the search's), point at {p.omega:.1f} rad/s, time integration "
                         f"{ti_verdict(p.ti, rom, scene.contact.mu)}" if p.found else f"{where}: none ({p.reason})")
            first = first or result
            if p.found and p.ti is not None and bool(p.ti.stays):
                break
            continue
        r_s, omega, x, amp, conv, brackets = source
        update(f"{tag}: period doubling of {where}")
        loc = locate_period_doubling(r_s, omega, x, amp, conv, brackets=brackets, n_scan=opts.n_scan,
                                     **({"brackets_from": nfrc_from} if where.startswith("the NFRC") else {}))
        switched = switch(r_s, loc, where, omega, x)
        if monitor_left and where == "the NFRC" and (switched is None or not switched[0].found):
            # the scan of an NFRC stored without stability found nothing to switch to
            monitor_left = False
            why = loc.reason if switched is None else f"{loc.reason}; {switched[0].reason}"
            update(f"{tag}: the NFRC's stability along the whole branch (its file holds none)")
            brackets = computed_brackets()
            again = locate_period_doubling(r_s, omega, x, amp, conv, brackets=brackets,
                                           brackets_from=nfrc.computed_words())
            loc = replace(again, reason=f"the scan found nothing to switch to ({why}); {again.reason}")
            switched = switch(r_s, loc, where, omega, x)
        if where == "the NFRC":
            first_bracket = tuple(loc.bracket) or ((loc.index,) if loc.index >= 0 else ())
        if loc.bifurcation is None:
            result = (ValidationPoint("period_doubling", method, False, f"{where}: {loc.reason}"),
                      DoubledBranch(False, f"{where}: {loc.reason}"))
        else:
            pd_branch, r_pd = switched
            pd_branch = replace(pd_branch, reason=f"{where}: {loc.reason}; {pd_branch.reason}")
            if not pd_branch.found:
                result = (ValidationPoint("period_doubling", method, False, pd_branch.reason), pd_branch)
            else:
                # points that carry the new frequencies: the start's neighbours are still the old orbit
                far = pd_branch.new_content >= 0.05
                eligible = far if far.any() else None
                doubled = Candidate(f"{VALIDATION.file} period-doubled branch of {method}, from {where}", r_pd,
                                    pd_branch.omega, pd_branch.x, pd_branch.le_amplitude,
                                    np.ones(len(pd_branch.omega), bool), pd_branch.stable, eligible=eligible)
                stable = np.asarray(pd_branch.stable, bool)
                if k < len(sources) - 1 and not (stable if eligible is None else stable[eligible]).any():
                    # a subcritical doubling: its doubled branch is unstable throughout, and time
                    # integration from it goes to the stable orbit beside it (default rotor 67
                    # scene, DLFT: the primary orbit 0.3 % away, the branch's odd content). The
                    # next try first; this branch is marched only when no other try gives a point.
                    tried.append(f"{where}: PD at {loc.bifurcation.omega:.1f} rad/s, no stable point on its "
                                 f"doubled branch ({len(pd_branch.omega)} points), not marched")
                    deferred = deferred or (len(tried) - 1, where, loc.bifurcation.omega, doubled, pd_branch)
                    continue
                # one march per doubled branch, its stable choice checked with 2 N_h first as the
                # primary's is (the next doubling is the retry, not the next stretch)
                result = (_try_until_kept(ctx, rom, system, "period_doubling", method, [doubled], 1, update),
                          pd_branch)
        p = result[0]
        stays = p.found and p.ti is not None and bool(p.ti.stays)
        tried.append(f"{where}: PD at {loc.bifurcation.omega:.1f} rad/s, point at {p.omega:.1f} rad/s, time integration "
                     f"{ti_verdict(p.ti, rom, scene.contact.mu)}" if p.found else f"{where}: none ({p.reason})")
        first = first or result
        if stays:
            break
    else:
        result = first
        # first is None only when every try was a deferred branch (the NFRC's other doublings,
        # counted as a try left, turned out to be none)
        if deferred is not None and (first is None or not first[0].found):
            # no try gave a point time integration keeps, nor any point: the least unstable
            # point of the first branch without a stable one, rather than none
            i, where, omega_pd, doubled, pd_branch = deferred
            p = _try_until_kept(ctx, rom, system, "period_doubling", method, [doubled], 1, update)
            tried[i] = (f"{where}: PD at {omega_pd:.1f} rad/s, no stable point on its doubled branch, point at "
                        f"{p.omega:.1f} rad/s, time integration {ti_verdict(p.ti, rom, scene.contact.mu)}"
                        if p.found else f"{where}: none ({p.reason})")
            result = (p, pd_branch)
    if len(tried) > 1:
        note = f"tried {len(tried)}: " + " | ".join(tried)
        result = (replace(result[0], reason=f"{result[0].reason}; {note}"),
                  replace(result[1], reason=f"{result[1].reason}; {note}"))
    return result


def _friction_lock(ti: OrbitValidation, rom, mu: float) -> bool:
    """Whether the march ended in permanent contact with mu at or above the ROM's contact-set
    limit mu_set (rom.friction_lock): the lock, a state of the model, not of the step."""
    return ti is not None and ti.outcome == "permanent contact" and past_friction_lock(mu, rom)


def _worth_refining(p: ValidationPoint, rom, mu: float, refinement: int) -> bool:
    """Whether a march that left point p is repeated with a finer step: p is stable by Hill's
    method and time integration left it for anything but the friction lock. On heavy-contact
    orbits the forward-increment multipliers' O(dt) error at each impact can move the march
    off a stable orbit whose basin is small ([validation] dt_refinement says by how much)."""
    return (refinement > 1 and p.found and bool(p.stable) and p.ti is not None and not p.ti.stays
            and not _friction_lock(p.ti, rom, mu))


def ti_verdict(ti: OrbitValidation, rom, mu: float) -> str:
    """ti.verdict(), and when it ends in permanent contact with mu at or above the ROM's
    contact-set limit mu_set (rom.friction_lock), that this is the friction lock."""
    words = ti.verdict() if ti is not None else "not marched"
    if _friction_lock(ti, rom, mu):
        words += f": the friction lock, mu = {mu:g} >= mu_set = {rom.friction_lock.mu_set:.3g}"
    return words


def _landing(ti: OrbitValidation) -> str:
    """Where the march went in the HBM's unknowns, in words ("" when not known)."""
    r = ti.reached
    if r is None:
        return ""
    newton = ("Newton from it fails" if not r.converged else "Newton from it finds the orbit"
              if r.solution_distance <= LANDING_TOL else f"Newton from it finds another solution "
              f"{r.solution_percent()} away{r.period_words(ti.subharmonic)}")
    return f", last period {100 * r.distance:.1f} % from the orbit in the unknowns, {newton}"


def _hill_words(c) -> str:
    """A treatment's own Hill verdict on its orbit at the point, in words ("" when not analysed)."""
    if c.n_unstable < 0:
        return ""
    return f", Hill {'stable' if c.n_unstable == 0 else 'UNSTABLE'} (|mu| {c.multiplier:.4g})"


def _summary(t: TreatmentValidation, rom, mu: float) -> list[str]:
    lines = []
    for p in (t.primary, t.isola, t.period_doubling):
        head = f"  {t.method.upper()} {p.kind}: "
        if not p.found:
            lines.append(head + f"none ({p.reason})")
            continue
        s = (f"Omega = {p.omega:.1f} rad/s, nu = {p.subharmonic}, {'stable' if p.stable else 'UNSTABLE'} "
             f"(|mu| {p.multiplier:.4g}); TI {ti_verdict(p.ti, rom, mu).replace('leaves', 'LEAVES', 1)} "
             f"(growth {p.ti.growth:.2f}, "
             f"last deviation {p.ti.last_deviation:.3f}{_landing(p.ti)}"
             + (f"; dt = {p.ti.dt:.3g} s, the first march {p.refined_from})" if p.refined_from else ")"))
        for m in ("dlft", "rl"):
            c = getattr(p, m)
            if c is not None and c.converged:
                s += (f"; vs {m.upper()}: displacement LE {100 * c.displacement_error[0]:.1f} % TE "
                      f"{100 * c.displacement_error[1]:.1f} %, force LE {100 * c.force_error[0]:.1f} % TE "
                      f"{100 * c.force_error[1]:.1f} %{_hill_words(c)}")
            elif c is not None:
                s += f"; no {m.upper()} orbit ({c.source})"
        lines.append(head + s)
    return lines


def _compute(ctx: Context, outputs, workers: int | None = None) -> None:
    """workers: processes, one treatment each (default: one per core, at most one per
    treatment; 1 runs them one after the other in this process)."""
    c0 = time.process_time()
    isolas = ctx.out / ISOLAS
    methods = ctx.scene.hbm.methods
    done = run_treatments(ctx, {m: m for m in methods}, _validate_treatment, "validation", "validation", workers)
    # this process's own time, and each treatment's in its process (the same time when they run here)
    own = time.process_time() - c0
    cpu = max(own, sum(t.cpu_time for t in done.values()))
    a = ValidationArtifact(isolas=str(isolas) if isolas.is_file() else "absent", growth_tol=GROWTH_TOL,
                           deviation_tol=DEVIATION_TOL, cpu_time=cpu, **done)
    art.write_artifact(ctx.out / VALIDATION.file, a, **ctx.provenance(VALIDATION, "validation"))
    rom = read_rom(ctx.out)
    for t in done.values():
        for line in _summary(t, rom, ctx.scene.contact.mu):
            ctx.log(line)
    ctx.log(f"  validation: {a.cpu_time:.1f} s CPU")


def _validate_treatment(ctx: Context, method: str, say) -> TreatmentValidation:
    """One treatment's three points (run_treatments' work)."""
    from hbm.ti.march import rom_modal_system

    rom = read_rom(ctx.out)
    return _treatment(ctx, rom, rom_modal_system(rom), method, say.update)


# -- figures -----------------------------------------------------------------------------------
def _points(a: ValidationArtifact):
    return {m: getattr(a, m) for m in ("dlft", "rl") if getattr(a, m) is not None}


def draw_time_signals(ctx: Context) -> None:
    """Fig. 9, one PNG per treatment whose points are shown (validation_METHOD.png), and Fig.
    10 (contact_METHOD.png): the primary point's LE and second-node displacement against the
    casing during a contact event."""
    from pipelines.figures import plot_contact_event, plot_validation_signals

    a = read_validation(ctx.out)
    fig = ctx.out / "figures"
    # the verdicts in the log's words (ti_verdict: permanent contact past the ROM's mu_set is the
    # friction lock); rom.h5 and [contact] are not among the figure's inputs: validation.h5,
    # which is, is computed again whenever either changes
    rom = read_rom(ctx.out) if (ctx.out / "rom.h5").is_file() else None
    mu = ctx.scene.contact.mu
    for m, t in _points(a).items():
        plot_validation_signals({p.kind: p for p in (t.primary, t.isola, t.period_doubling)}, fig / f"validation_{m}.png",
                                title=f"points on the {m.upper()}-HBM solution set against time integration",
                                verdict=lambda ti: ti_verdict(ti, rom, mu))
        plot_contact_event(t.primary, fig / f"contact_{m}.png",
                           title=f"{m.upper()} primary point, \u03a9 = {t.primary.omega:.1f} rad/s")


def _signal_files(scene) -> tuple[str, ...]:
    return tuple(f for m in scene.hbm.methods for f in (f"validation_{m}.png", f"contact_{m}.png"))


def locked_branch(br, mu: float, rom) -> bool:
    """Whether every converged point of an isola-search branch holds a node on the casing
    over its whole period with mu >= the ROM's mu_set: the friction lock (the stage log's
    words, pipelines.stages.isolas.locked_text)."""
    return bool(len(br.locked_nodes)) and past_friction_lock(mu, rom)


def drawn_kind(br, nu: int, mu: float, rom) -> str:
    """The kind Fig. 8 draws an isola-search branch as: "friction lock" where every point holds a
    node on the casing over its whole period and mu >= the ROM's mu_set (the log's words,
    pipelines.stages.isolas.locked_text), "period-doubled" for the branches of the search in
    the basis of twice the scene's period (subharmonic > nu), else its kind."""
    if locked_branch(br, mu, rom):
        return "friction lock"
    return "period-doubled" if br.subharmonic > nu else br.kind


def _stability_bounds(table: dict, stable) -> list:
    """[(kind, omega, le_amplitude, guessed)] of the bifurcations of a branch's table
    ({column: array}) where a stable stretch begins or ends (the stable flag differs between
    the two points around it); guessed: the kind is a guess (bifurcation.kind_sources). The
    others, crossings among orbits already
    unstable, stay in the files: on the coarse rotor 67 ROM a single long isola has 100 to
    250 of them, which would bury the figure's curves."""
    kinds, om, amp, idx = (np.asarray(table[k]) for k in ("kind", "omega", "le_amplitude", "index"))
    guessed = kind_sources(table) == GUESS
    if stable is None:
        return [(str(k), w, a, bool(g)) for k, w, a, g in zip(kinds, om, amp, guessed)]
    st = np.asarray(stable, bool)
    j = np.clip(idx.astype(np.int64), 0, len(st) - 2) if len(st) > 1 else idx.astype(np.int64) * 0
    keep = st[j] != st[np.minimum(j + 1, len(st) - 1)]
    return [(str(k), w, a, bool(g)) for k, w, a, g, ok in zip(kinds, om, amp, guessed, keep) if ok]


def draw_solution_set(ctx: Context) -> None:
    """Fig. 8: the solution set of each treatment (solution_set_METHOD.png) and both together
    (solution_set.png), from the files that exist; the bifurcations marked are those where a
    stable stretch begins or ends (_stability_bounds); points without a verdict (n_unstable
    -1) drawn as unknown; the search's branches none of whose checked points holds with 2 N_h
    (harmonic_check "not converged") faded."""
    import h5py

    from pipelines.branch_store import load_branch, read_table
    from pipelines.figures import plot_solution_set
    from pipelines.stages.ti import FLAGGED_LABEL, sweep_points

    scene, out = ctx.scene, ctx.out
    validation = read_validation(out) if (out / VALIDATION.file).is_file() else None
    rom = read_rom(out) if (out / "rom.h5").is_file() else None  # its mu_set: which branches are the lock
    curves = {}
    for m in scene.hbm.methods:
        lines, marks = [], []
        path = out / nfrc_output(m).file
        t = getattr(validation, m) if validation is not None else None
        if path.is_file():
            s = load_branch(path)
            stable, count = s.extras.get("stable"), s.extras.get("n_unstable")
            if stable is None and t is not None and len(t.nfrc_stable) == len(s.branch.omega):
                stable = t.nfrc_stable  # computed by the validation stage
            lines.append(("primary", s.branch.omega, s.extras["le_amplitude"], s.branch.converged, stable, count))
            with h5py.File(path, "r") as h5:
                if "bifurcations" in h5:
                    marks += _stability_bounds({k: v for k, (v, _) in read_table(h5["bifurcations"]).items()},
                                               s.extras.get("stable"))
        for br in read_branch_set(out / ISOLAS, m):
            if br.kind != "primary":
                lines.append((drawn_kind(br, scene.hbm.subharmonic, scene.contact.mu, rom), br.omega,
                              br.le_amplitude, br.converged, br.stable, br.n_unstable,
                              br.harmonic_verdict == "not converged"))
                if br.bifurcations is not None:
                    marks += _stability_bounds(br.bifurcations, br.stable)
        if t is not None:
            marks += [("validation point", p.omega, p.le_amplitude) for p in (t.primary, t.isola, t.period_doubling)
                      if p.found]
            if t.pd_branch.found and not t.period_doubling.branch.startswith(ISOLAS):  # else drawn above
                d = t.pd_branch
                lines.append(("period-doubled", d.omega, d.le_amplitude, np.ones(len(d.omega), bool), d.stable,
                              d.n_unstable if len(d.n_unstable) == len(d.omega) else None))
        curves[m.upper()] = (lines, marks)
    ti = sweep_points(out)
    rng = (scene.hbm.omega_min, scene.hbm.omega_max)
    order = scene.ti.classified_order(scene.casing.n_lobes)
    for m in scene.hbm.methods:
        plot_solution_set({m.upper(): curves[m.upper()]}, out / "figures" / f"solution_set_{m}.png", ti_points=ti,
                          omega_range=rng, n_lobes=scene.casing.n_lobes, max_order=order,
                          title=f"{m.upper()}-HBM solution set", flagged_label=FLAGGED_LABEL)
    plot_solution_set(curves, out / "figures" / "solution_set.png", ti_points=ti, omega_range=rng,
                      n_lobes=scene.casing.n_lobes, max_order=order, title="solution set, both treatments",
                      flagged_label=FLAGGED_LABEL)


def _set_files(scene) -> tuple[str, ...]:
    return tuple(f"solution_set_{m}.png" for m in scene.hbm.methods) + ("solution_set.png",)


def _set_inputs(scene) -> tuple[str, ...]:
    return tuple(nfrc_output(m).file for m in scene.hbm.methods) + (ISOLAS, VALIDATION.file, "ti.h5", "rom.h5")


def _add_content(modal: dict, harmonic: dict, label: str, omega, converged, nu: int, modal_c, harmonic_c) -> None:
    """One branch's curves for pipelines.figures.plot_content, under `label`, where it carries
    them (None: not stored)."""
    for curves, c in ((modal, modal_c), (harmonic, harmonic_c)):
        if c is not None:
            curves[label] = (omega, c, nu, converged)


def _mode_frequencies(out: Path):
    """The ROM's mode frequencies (n,), rad/s, for the content figures' crossings; None without
    rom.h5."""
    from hbm.harmonic.content import rom_modes

    if not (out / "rom.h5").is_file():
        return None
    rom = read_rom(out)
    return rom_modes(rom.K, rom.M)[0]


def draw_content(ctx: Context) -> None:
    """Figs. 11 and 12 (dynamical content along the isolas, one panel per isola) when
    isolas.h5 carries it; the harmonic panels mark where a harmonic's frequency k Omega meets
    one of the ROM's first four modes."""
    from pipelines.figures import plot_content

    scene, out = ctx.scene, ctx.out
    modal, harmonic = {}, {}
    for m in scene.hbm.methods:
        for br in read_branch_set(out / ISOLAS, m):
            if br.kind == "isola":
                _add_content(modal, harmonic, f"{m.upper()} isola {br.name}", br.omega, br.converged,
                             br.subharmonic, br.modal_contribution, br.harmonic_contribution)
    freq = _mode_frequencies(out) if harmonic or modal else None
    # drawn (with a note) even without content: a figure that is never drawn would be redrawn by every run
    plot_content(modal, out / "figures" / "isola_modal_content.png", kind="modal", mode_frequencies=freq)
    plot_content(harmonic, out / "figures" / "isola_harmonic_content.png", kind="harmonic", mode_frequencies=freq)


#: Panels of a treatment's content figures: more than the search finds on rotor 67 (at most 11
#: branches besides the NFRC on its default and coarse scenes).
MAX_BRANCH_PANELS = 16


def draw_branch_content(ctx: Context) -> None:
    """Figs. 11 and 12 along every branch of each treatment (content_modal_METHOD.png,
    content_harmonic_METHOD.png): one panel for the NFRC ("primary") and one for each branch
    of isolas.h5 whatever its kind, from the contributions stored with their points (the
    isola figures hold the isolas of both treatments side by side, as the paper's do)."""
    from pipelines.branch_store import load_branch
    from pipelines.figures import plot_content

    scene, out = ctx.scene, ctx.out
    freq = _mode_frequencies(out)
    for m in scene.hbm.methods:
        modal, harmonic = {}, {}
        path = out / nfrc_output(m).file
        if path.is_file():
            s = load_branch(path)
            _add_content(modal, harmonic, f"{m.upper()} primary", s.branch.omega, s.branch.converged,
                         scene.hbm.subharmonic, s.extras.get("modal_contribution"),
                         s.extras.get("harmonic_contribution"))
        for br in read_branch_set(out / ISOLAS, m):
            _add_content(modal, harmonic, f"{m.upper()} {br.kind} {br.name}", br.omega, br.converged,
                         br.subharmonic, br.modal_contribution, br.harmonic_contribution)
        for kind, curves in (("modal", modal), ("harmonic", harmonic)):
            plot_content(curves, out / "figures" / f"content_{kind}_{m}.png", kind=kind, mode_frequencies=freq,
                         max_panels=MAX_BRANCH_PANELS)


def _content_files(scene) -> tuple[str, ...]:
    return tuple(f"content_{k}_{m}.png" for m in scene.hbm.methods for k in ("modal", "harmonic"))


SIGNALS = Figure("validation", files=_signal_files, depends=("hbm.methods",),
                 inputs=lambda s: (VALIDATION.file,), draw=draw_time_signals)
SOLUTION_SET = Figure("solution_set", files=_set_files,
                      depends=("hbm.methods", "hbm.omega_min", "hbm.omega_max", "casing.n_lobes",
                               "ti.max_order", "ti.n_keep", "contact.mu"),
                      inputs=_set_inputs, draw=draw_solution_set)
CONTENT = Figure("isola_content", files=lambda s: ("isola_modal_content.png", "isola_harmonic_content.png"),
                 depends=("hbm.methods",), inputs=lambda s: (ISOLAS, "rom.h5"), draw=draw_content)

BRANCH_CONTENT = Figure("branch_content", files=_content_files, depends=("hbm.methods", "hbm.subharmonic"),
                        inputs=lambda s: tuple(nfrc_output(m).file for m in s.hbm.methods) + (ISOLAS, "rom.h5"),
                        draw=draw_branch_content)

STAGE = Stage("validation", depends=("casing", "contact", "hbm", "validation"), upstream=UPSTREAM,
              outputs=lambda scene: (VALIDATION,) if scene.hbm.methods else (), compute=_compute,
              figures=(SIGNALS, SOLUTION_SET, CONTENT, BRANCH_CONTENT))
