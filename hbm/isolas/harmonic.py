"""The isola search on the HBM residual of the rotor blade: problem factory, seeds, per-point data.

Unknowns: the HBM's scaled condensed boundary harmonics u = alpha x~_r (eq. (5) order,
hbm.harmonic.residual), so seeds are built as boundary harmonics in m and scaled with the
residual's to_unknowns.
"""
from __future__ import annotations

import uuid
from dataclasses import dataclass, field, replace

import numpy as np

from hbm.continuation.newton import NewtonOptions, newton_solve
from hbm.harmonic.content import rom_modes
from hbm.harmonic.nfrc import default_continuation, nfrc_extras
from hbm.harmonic.residual import HarmonicBalanceResidual, build_residual
from hbm.harmonic.solver import HbmSolver
from hbm.isolas.membership import KnownBranch, points_at
from hbm.isolas.options import IsolaOptions
from hbm.isolas.search import SearchOptions, Seed, lies_on_any, same_solution
from hbm.options import CasingOptions, ContactOptions, HbmOptions
from hbm.ti.periodicity import PeriodClass


@dataclass(frozen=True)
class HbmProblem:
    """Picklable factory of (residual, solver) for hbm.isolas.search: the HBM residual of one
    contact treatment and the NFRC's LinearSolver (GMRES on the structured Jacobian, atol a
    tenth of Newton's tolerance, as compute_nfrc).

    seeds: the solver of the seeds' corrections instead (`for_seeds()`): a preconditioner
    built for every Jacobian (refactor_after 0) and inexact plain solves (plain_forcing
    1e-2). From a far-off seed every Newton step changes the contact set, so a kept
    preconditioner costs ~18 GMRES iterations a solve against ~3 for a fresh one; measured
    on the coarse rotor 67 ROM, DLFT, N_h = 40, the 120 modal seeds at 960 and 1215 rad/s:
    0.22-0.25 s a seed with the NFRC's solver, 0.13-0.14 s with this one, the same
    solutions found (and 40-47 converged seeds against 41-47).
    """

    rom: object
    casing: CasingOptions
    contact: ContactOptions
    hbm: HbmOptions
    method: str
    seeds: bool = False

    def for_seeds(self) -> "HbmProblem":
        return replace(self, seeds=True)

    def __call__(self) -> tuple[HarmonicBalanceResidual, HbmSolver]:
        res = build_residual(self.rom, self.casing, self.contact, self.hbm, method=self.method)
        if self.seeds:
            return res, HbmSolver(atol=0.1 * self.hbm.tolerance, refactor_after=0, plain_forcing=1e-2)
        return res, HbmSolver(atol=0.1 * self.hbm.tolerance)


def search_options(hbm: HbmOptions, iso: IsolaOptions) -> SearchOptions:
    """The search's settings: the NFRC's continuation (hbm.harmonic.nfrc.default_continuation,
    which passes corners above the step floor: a branch that reached one at the floor could
    crawl there, and a crawl ends a half) on the isolas' omega range, with max_points and
    crawl_points per half branch; the seeds' Newton with
    backtracking and newton_iterations iterations, given up once three iterations in a row
    fail to lower the best ||R|| tenfold (hbm.continuation.newton stall_iterations: most
    seeds never converge; this makes them cost ~4 iterations); the seeds that are solutions
    of a model (Seed.of_model) get model_seed_iterations and no stall rule."""
    lo, hi = iso.omega_range(hbm)
    co = replace(default_continuation(hbm), omega_min=lo, omega_max=hi, max_points=iso.max_points,
                 crawl_points=iso.crawl_points)
    newton = NewtonOptions(tol_residual=hbm.tolerance, max_iter=iso.newton_iterations, line_search=True,
                           max_halvings=4, stall_iterations=3, stall_factor=0.1)
    model = replace(newton, max_iter=iso.model_seed_iterations, stall_iterations=None)
    return SearchOptions(tolerance=iso.tolerance, continuation=co, newton=newton, workers=iso.workers,
                         model_newton=model)


def boundary_modes(rom, n_modes: int) -> tuple[np.ndarray, np.ndarray]:
    """The first n_modes modes of the ROM (K, M): (frequencies (n_modes,) rad/s, boundary
    part (n_modes, 3 n_b)), each scaled to a largest radial displacement of 1 (m per unit)
    over the contact nodes, its sign making that largest one positive."""
    n = min(n_modes, rom.K.shape[0])
    if n == 0:
        return np.zeros(0), np.zeros((0, 3 * rom.n_boundary))
    # all modes (a ROM is small): rom_modes' check that K is semi-definite needs max |w^2|
    w, phi = rom_modes(rom.K, rom.M)
    b = phi[: 3 * rom.n_boundary, :n].T.copy()  # (n, 3 n_b)
    for j in range(n):
        r = b[j, 0::3]
        k = int(np.argmax(np.abs(r)))
        b[j] /= r[k] if r[k] != 0 else np.abs(b[j]).max()
    return w[:n], b


def modal_seeds(res: HarmonicBalanceResidual, rom, iso: IsolaOptions, omegas: np.ndarray,
                around: tuple[KnownBranch, ...] = ()) -> list[Seed]:
    """Eq. (31): x0(t) = A rho_tip Phi_j cos(k Omega t) for every Omega of the grid (rad/s),
    mode j < n_modes, harmonic k of Omega of iso.harmonics, amplitude A of iso.amplitudes
    (rho_tip: mean radius of the contact nodes, m; Phi_j: boundary_modes). In the basis of
    Omega / nu, k Omega is the basis' harmonic k nu: the k with k nu above the residual's N_h
    are left out. Origins read "modal j=2 k=4 A=0.0032" (j from 1, k of Omega).

    around: branches (the primary NFRC, in the residual's unknowns) whose points at each
    Omega (hbm.isolas.membership.points_at) get the same shapes added with the amplitudes
    iso.primary_amplitudes (IsolaOptions says why); origins read "modal j=1 k=5 A=0.001
    + primary DLFT NFRC 2/3" (its 2nd point of 3 at that Omega)."""
    _, phi = boundary_modes(rom, iso.n_modes)
    rho_tip = float(np.mean(rom.rho))
    nh = res.basis.n_harmonics
    nu = int(res.nu)
    out = []
    for w in omegas:
        bases = [(None, iso.amplitudes, "")]
        if iso.primary_amplitudes:
            for b in around:
                pts = points_at(b, float(w))
                bases += [(p, iso.primary_amplitudes, f" + {b.label} {i + 1}/{len(pts)}") for i, p in enumerate(pts)]
        for base, amplitudes, on in bases:
            for j, shape in enumerate(phi):
                for k in iso.harmonics:
                    q = k * nu  # k Omega in the basis of Omega / nu
                    if q > nh:
                        continue
                    for a in amplitudes:
                        xr = np.zeros((res.n_c, res.n_r))
                        xr[2 * q - 1] = a * rho_tip * shape  # the cosine of harmonic q, eq. (5) order
                        x = res.to_unknowns(xr)
                        out.append(Seed(float(w), x if base is None else base + x,
                                        f"modal j={j + 1} k={k} A={a:.2g}{on}"))
    return out


def rl_seeds(dlft, options: SearchOptions, branch_points: int = 0) -> list[Seed]:
    """RL's seeds from a DLFT search (hbm.isolas.search.IsolaSearch on the same ROM, basis,
    N_h and options), each of a model (Seed.of_model):
    - every distinct converged DLFT solution of a modal seed, on DLFT's primary or not,
      origin suffixed " via DLFT". Distinct: at one omega, none within options.tolerance of
      an earlier one in the membership's metric (the search's own test for duplicates,
      which leaves out the solutions on a known branch: the seeds around the primary land
      there by the dozen at each speed, one RL seed each otherwise);
    - branch_points converged points of each of DLFT's branches, evenly spaced by index
      along it ("DLFT branch 004 point 12/39"): a seed solution gives RL one speed of a
      branch, where RL's Newton may fail or RL's branch may not reach (IsolaOptions.
      rl_branch_seeds has the measurement).

    Why: from eq. (31)'s raw seeds RL's stiff penalty (kappa = 1e9 N/m) makes Newton cost
    3 to 6 s per seed on the coarse rotor 67 ROM at N_h = 40 (GMRES stalls, dense
    fall-backs), against ~0.5 s for DLFT, and almost none converge; DLFT's solutions are
    close to RL's wherever both laws have one (the same correction the NFRC's RL start uses,
    hbm.harmonic.start). Those on DLFT's primary are kept: where RL's branch is cut off
    from its primary, its piece lies next to DLFT's primary (the paper's Fig. 6, frames
    i-iii). Not from DLFT: the time-integration seeds, which RL also gets.
    """
    c = dlft.corrections
    kept: dict[float, list[np.ndarray]] = {}
    out = []
    for i in np.flatnonzero(c.converged & (c.same_as < 0)):
        sd = dlft.seeds[i]
        if not sd.origin.startswith("modal"):
            continue
        x = np.array(c.x[i])
        here = kept.setdefault(float(sd.omega), [])
        if any(same_solution(x, y, options) for y in here):
            continue
        here.append(x)
        out.append(Seed(sd.omega, x, f"{sd.origin} via DLFT", of_model=True))
    for k, b in enumerate(dlft.branches if branch_points else ()):
        ok = np.flatnonzero(np.asarray(b.converged, bool))
        for i in np.unique(np.linspace(0, len(ok) - 1, min(branch_points, len(ok))).round().astype(int)):
            j = int(ok[i])
            out.append(Seed(float(b.omega[j]), np.array(b.x[j]), f"DLFT branch {k:03d} point {j + 1}/{len(b.omega)}",
                            of_model=True))
    return out


def doubled_options(hbm: HbmOptions) -> HbmOptions:
    """hbm in the basis of twice the period, Omega / (2 nu), at the same resolution: 2 N_h
    harmonics and 2 N_t samples (the period-doubled orbits of the sweep, hbm.isolas.ti_seeds)."""
    return replace(hbm, subharmonic=2 * hbm.subharmonic, n_harmonics=2 * hbm.n_harmonics, n_time=2 * hbm.n_time)


def ti_seeds(res: HarmonicBalanceResidual, sweep, omega_range: tuple[float, float], n_lobes: int,
             only_new_to: int | None = None) -> list[Seed]:
    """A seed from every periodic time-integration point within omega_range (rad/s) whose
    orbit the residual's basis holds: period p casing periods dividing its nu revolutions
    (p | nu n_l: omega = n_l Omega and omega = Omega for nu = 1, and omega = Omega / 2 too for
    nu = 2). The seed is the harmonics of Omega / nu of the point's boundary dof over its last
    nu revolutions (sweep.boundary, (n_omega, n_held spr, 3 n_b), m, from Omega t = 0 mod 2 pi;
    spr samples a revolution, read from sweep.times), least-squares fitted on the residual's
    N_h. [] when the sweep holds no boundary states (a ti.h5 written before they were kept);
    a point whose nu revolutions the file does not hold gives none. Each is of a model
    (Seed.of_model: a time-integration orbit). only_new_to: skip the points whose orbit the
    basis of Omega / only_new_to holds already (e.g. 1: only the period-doubled orbits, for
    a search at nu = 2 beside the one at nu = 1).

    The window may start an odd number of revolutions into the march, i.e. at Omega t / nu
    = pi for nu = 2: the fit then gives the orbit shifted by one revolution, which the
    casing's period makes a solution as well."""
    B = getattr(sweep, "boundary", None)
    if B is None:
        return []
    B = np.asarray(B, dtype=float)
    nu = int(res.nu)
    out = []
    for i, (w, p, c) in enumerate(zip(sweep.omega, sweep.period, sweep.period_class)):
        p = int(p)
        if p < 1 or (nu * n_lobes) % p or not omega_range[0] <= w <= omega_range[1]:
            continue
        if only_new_to is not None and (only_new_to * n_lobes) % p == 0:
            continue
        spr = int(round(2.0 * np.pi / (w * (sweep.times[i][1] - sweep.times[i][0]))))
        n_s = nu * spr
        if n_s > B.shape[1]:
            continue
        tau = 2 * np.pi * np.arange(n_s) / n_s  # basis angle Omega t / nu of each sample
        nh = min(res.basis.n_harmonics, (n_s - 1) // 2)
        cols = [np.ones(n_s)]
        for k in range(1, nh + 1):
            cols += [np.cos(k * tau), np.sin(k * tau)]
        coef = np.linalg.lstsq(np.column_stack(cols), B[i, -n_s:], rcond=None)[0]  # (2 nh + 1, 3 n_b)
        xr = np.zeros((res.n_c, res.n_r))
        xr[: len(coef)] = coef
        label = PeriodClass(int(c)).label(n_lobes).replace(" ", "")
        out.append(Seed(float(w), res.to_unknowns(xr), f"ti class {label} period {p} Omega={w:.6g}", of_model=True))
    return out


#: Share of a doubled branch's LE harmonic energy at the harmonics the doubled basis adds
#: (odd multiples of its fundamental) below which a point is taken for an orbit of the old
#: basis, i.e. a period doubling: the crossings measured on rotor 67 reach 0.000-0.016, and
#: a doubled branch that meets no old one stays above 0.1 (README, Isola search).
DOUBLING_SHARE = 0.02


def new_share(harmonics: np.ndarray) -> np.ndarray:
    """Share of the energy (mean excluded) at odd harmonics, per point: harmonics
    (m, 2 N_h + 1, k) (the LE radial one, column 0, is used) or (m, 2 N_h + 1) -> (m,), -."""
    h = np.asarray(harmonics, dtype=float)
    h = h[..., 0] if h.ndim == 3 else h
    n_h = (h.shape[1] - 1) // 2
    odd = sum(h[:, 2 * k - 1] ** 2 + h[:, 2 * k] ** 2 for k in range(1, n_h + 1, 2))
    return odd / np.maximum(np.sum(h[:, 1:] ** 2, axis=1), 1e-300)


def coarsened(fine: HarmonicBalanceResidual, coarse: HarmonicBalanceResidual, u: np.ndarray) -> np.ndarray:
    """Unknowns u of `fine`, whose fundamental is coarse's / r (r = fine.nu / coarse.nu), on
    coarse's basis: harmonic r k of fine is harmonic k of coarse, the others are dropped."""
    r = fine.nu // coarse.nu
    xf = fine.to_coefficients(u)
    xc = np.zeros((coarse.n_c, coarse.n_r))
    xc[0] = xf[0]
    for k in range(1, coarse.basis.n_harmonics + 1):
        if r * k > fine.basis.n_harmonics:
            break
        xc[2 * k - 1], xc[2 * k] = xf[2 * r * k - 1], xf[2 * r * k]
    return coarse.to_unknowns(xc)


def doubling_origin(coarse: HarmonicBalanceResidual, fine: HarmonicBalanceResidual, solver, branch, known,
                    options: SearchOptions, tries: int = 3):
    """Where a branch of the doubled basis (`fine`, e.g. Omega / 2) passes through an orbit of
    a known branch of `coarse` (e.g. Omega), i.e. the period doubling it is born at.

    branch: FoundBranch (x (m, n_u) fine's unknowns, omega (m,) rad/s, converged (m,),
    extras["harmonics"] (m, 2 N_h + 1, 3 n_b) m). known: KnownBranch list of coarse's unknowns.
    The points where new_share enters or leaves a stretch below DOUBLING_SHARE lie next to
    such a crossing (past it a continuation may run on along the old branch, where the share
    is 0). From up to `tries` of them, in branch order: Newton in coarse's basis
    (options.newton) from the point's even harmonics, then the isola search's membership
    test on the solution and its images (hbm.isolas.search.lies_on_any). The continuation's
    own test, the distance to the known polyline, misses these crossings: they fall between
    the known branch's points.
    Returns (index into known, Omega in rad/s) of the first hit, or None."""
    ok = np.flatnonzero(np.asarray(branch.converged, dtype=bool))
    h = branch.extras.get("harmonics")
    if h is None or len(ok) < 1 or not known:
        return None
    low = new_share(np.asarray(h)[ok]) < DOUBLING_SHARE
    before = np.r_[False, low[:-1]]
    after = np.r_[low[1:], False]
    ends = np.flatnonzero(low & ~(before & after))  # first and last point of each low stretch
    for j in ends[:tries]:
        i = ok[j]
        w = float(branch.omega[i])
        sol = newton_solve(coarse, coarsened(fine, coarse, branch.x[i]), w, options.newton, solver=solver)
        if not sol.converged:
            continue
        k = lies_on_any(coarse, sol.x, w, known, options, solver)
        if k >= 0:
            return k, w
    return None


def check_points(omega: np.ndarray, n: int) -> np.ndarray:
    """Indices of up to n points of a branch (omega (m,) rad/s, in branch order) at which to
    ask whether it is converged in the number of harmonics: evenly inside its longest stretch
    of monotone Omega, at fractions 1 / (n + 1), ..., n / (n + 1) of it (rounded down). A
    fold moves with N_h, so points of a converged branch near one may have no solution with
    more harmonics next to them (on the default rotor 67 scene, at N_h = 80, the points with
    none lay near the branches' ends in Omega; benchmarks/README.md, *The harmonic check*);
    the middle of a monotone stretch is as far from the folds as the branch allows. Returns
    (k,) int, k <= n, ascending."""
    w = np.asarray(omega, dtype=float)
    if n < 1 or not len(w):
        return np.zeros(0, np.int64)
    d = np.sign(np.diff(w))
    # the runs of one sign of dOmega, as ranges of points; the first longest
    cuts = np.r_[0, np.flatnonzero(d[1:] != d[:-1]) + 1, len(d)]
    k = int(np.argmax(np.diff(cuts)))
    a, b = int(cuts[k]), int(cuts[k + 1])
    return np.unique(np.array([a + (q + 1) * (b - a) // (n + 1) for q in range(n)], dtype=np.int64))


def harmonic_checks(res: HarmonicBalanceResidual, omega: np.ndarray, u: np.ndarray, n: int, fine=None) -> dict:
    """The table "harmonic_checks" of a branch (omega (m,) rad/s, u (m, n_u) res's unknowns):
    at each of check_points(omega, n), hbm.stability.convergence.check_harmonics without the
    stability part (twice the harmonics and AFT samples, Newton from the point padded with
    zeros, 20 iterations): whether a solution with 2 N_h lies next to it, its first N_h
    harmonics moved by at most HARMONIC_MOVE_TOL. A branch none of whose points pass is not a
    solution of the blade's equations but of their truncation (the search does not drop it:
    the file says so). fine: res.refined(2) when the caller has it.

    Returns {column: (array, unit)}: index (k,) (position among the points given), omega (k,)
    rad/s, passed (k,) bool, moved (k,) 1 (nan without a solution), n_harmonics (k,) (the
    finer N_h), cpu_time (k,) s, reason (k,) str."""
    import time

    from hbm.stability.convergence import check_harmonics

    idx = check_points(omega, n)
    fine = res.refined(2) if fine is None and len(idx) else fine
    rows = []
    for i in idx:
        t = time.process_time()
        ch = check_harmonics(res, u[i], float(omega[i]), stable=False, fine=fine)
        rows.append((ch, time.process_time() - t))
    return {"index": (idx, "-"), "omega": (np.asarray(omega, float)[idx], "rad/s"),
            "passed": (np.array([c.passed for c, _ in rows], bool), "-"),
            "moved": (np.array([c.moved for c, _ in rows], float), "1"),
            "n_harmonics": (np.array([c.n_harmonics for c, _ in rows], np.int64), "-"),
            "cpu_time": (np.array([t for _, t in rows], float), "s"),
            "reason": (np.array([c.reason for c, _ in rows], dtype=object), "-")}


def harmonic_verdict(table: dict | None) -> str:
    """A branch's verdict from its harmonic_checks table ({column: array}): "converged" (every
    point checked passed), "not converged" (none did), "partly converged", or "unchecked"
    (no table or no row)."""
    if table is None or not len(table.get("passed", ())):
        return "unchecked"
    p = np.asarray(table["passed"], bool)
    return "converged" if p.all() else "not converged" if not p.any() else "partly converged"


def describe(res: HarmonicBalanceResidual, stability: bool, scales: tuple = (1.0, 1.0), options=None,
             checks: int = 0, fine=None, content: bool = False):
    """describe(omega (m,), u (m, n_u)) for hbm.isolas.search: le_amplitude (m,) m and
    harmonics (m, 2 N_h + 1, 3 n_b) m (hbm.harmonic.nfrc.nfrc_extras); with stability, the
    branch's stability as the NFRC gets it (hbm.stability.monitor.monitor_branch: gapped
    Floquet analyses, bisection on the stored points): stable (m,) bool, n_unstable (m,)
    int, stability_analysed (m,) bool, stability_widened (m,) bool, stability_cpu_time (m,)
    s, leading_multipliers (m, n_leading), period_ratio
    (m,) int, and the table "bifurcations" (hbm.stability.bifurcation.bifurcation_arrays,
    its index counting the described points) under "tables". scales: (x_scale,
    omega_scale), the continuation's, in which the monitor measures arc length. options:
    StabilityOptions (default: the monitor's). checks: with checks > 0, the table
    "harmonic_checks" (harmonic_checks, at up to that many points; fine: res.refined(2)).
    content: also modal_contribution (m, n) and harmonic_contribution (m, N_h + 1) m of each
    point (hbm.harmonic.content.branch_content with the modes of res.rom's K and M): 6 ms a
    point on the coarse rotor 67 ROM, computed here so that the search's two processes share
    it rather than the stage's end. Always: contact_fraction (m, n_b), - (contact_fraction below).
    """
    def run(omega, u):
        ex = [nfrc_extras(res, x) for x in u]
        out = {"le_amplitude": np.array([e["le_amplitude"] for e in ex]),
               "harmonics": np.array([e["harmonics"] for e in ex]),
               "contact_fraction": contact_fraction(res, omega, u)}
        if content:
            from hbm.harmonic.content import branch_content

            c = branch_content(res, res.rom, u, omega)
            out.update({k: c[k] for k in ("modal_contribution", "harmonic_contribution")})
        if stability:
            from hbm.stability.bifurcation import bifurcation_arrays
            from hbm.stability.monitor import StabilityMonitor, StabilityOptions, monitor_branch

            opts = options or StabilityOptions()
            mon = StabilityMonitor.for_residual(res, opts)
            st = monitor_branch(mon.analyse, omega, u, ex, scales[0], scales[1], opts, widen=mon.widen,
                                refine=mon.refine)
            out.update(st.per_point())
            out["tables"] = {"bifurcations": bifurcation_arrays(st.bifurcations)}
        if checks:
            out.setdefault("tables", {})["harmonic_checks"] = harmonic_checks(res, omega, u, checks, fine)
        return out

    return run


def contact_fraction(res: HarmonicBalanceResidual, omega: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Share of the period in which each contact node is in contact, (m, n_b), -, at the points
    omega (m,) rad/s, u (m, n_u) (the contact law's own indicator on its AFT grid: the DLFT
    correction's active set, RL's positive gap). 1 for a node that never leaves the casing:
    past the ROM's mu_set, the friction lock (the validation stage's "permanent contact")."""
    out = np.zeros((len(omega), res.n_b))
    for i, (w, x) in enumerate(zip(omega, u)):
        out[i] = np.asarray(res.samples(res.to_coefficients(x), float(w)).active, float).mean(axis=0)
    return out


#: [residual, its refined one or None] built by BranchDescriber in this process, by the
#: describer's token, the most recently used last; at most _MAX_RESIDUALS are kept (a
#: residual holds its ROM's matrices, and a long-lived process, a notebook or a test
#: session, describes for many searches)
_RESIDUALS: dict = {}
#: one per treatment and search basis of a run (DLFT and RL, Omega and Omega / 2)
_MAX_RESIDUALS = 4


@dataclass(frozen=True, eq=False)
class BranchDescriber:
    """describe (above) for hbm.isolas.search, picklable: the search describes the two halves
    of a long branch at once in its worker processes, so a long branch gets up to `checks`
    harmonic checks in each half. content: the points' modal and harmonic contributions too.
    problem: HbmProblem (or any picklable factory() -> (residual, solver)); each process
    builds the residual once (~1 s on the coarse rotor 67 ROM at N_h = 40), and its refined
    one when first needed, kept under `token`."""

    problem: object
    stability: bool = False
    scales: tuple = (1.0, 1.0)
    options: object = None
    checks: int = 0
    content: bool = False
    token: str = field(default_factory=lambda: uuid.uuid4().hex)

    def __call__(self, omega: np.ndarray, u: np.ndarray) -> dict:
        built = _RESIDUALS.pop(self.token, None)
        if built is None:
            built = [self.problem()[0], None]
            while len(_RESIDUALS) >= _MAX_RESIDUALS:
                del _RESIDUALS[next(iter(_RESIDUALS))]  # the least recently used
        _RESIDUALS[self.token] = built
        if self.checks and built[1] is None:
            built[1] = built[0].refined(2)
        return describe(built[0], self.stability, self.scales, self.options, self.checks, built[1],
                        self.content)(omega, u)


def dominant_harmonic(harmonics: np.ndarray) -> int:
    """The harmonic k >= 1 (of the basis) with the largest mean amplitude of the LE radial
    displacement over a branch's points; harmonics (m, 2 N_h + 1, 3 n_b), m."""
    h = np.asarray(harmonics, dtype=float)
    if h.ndim != 3 or h.shape[0] == 0:
        return 0
    r = h[:, :, 0]
    amp = np.hypot(r[:, 1::2], r[:, 2::2])  # (m, N_h)
    return int(np.argmax(np.nanmean(amp, axis=0))) + 1
