"""Stage isolas: the search for the branches the primary NFRC misses (isolas.h5).

Per contact treatment: seeds from eq. (31), from rest and added to the primary NFRC's
solutions at each grid speed ([isolas] primary_amplitudes), and from the periodic
time-integration points (ti.h5), corrected by Newton, continued both ways, classified
(hbm.isolas). With both treatments, RL's modal seeds are DLFT's corrected ones and
[isolas] rl_branch_seeds points along each of DLFT's branches (hbm.isolas.harmonic.rl_seeds).
Then, with [isolas] ti_period_doubled, a second search in the basis of twice the period
(Omega / (2 nu), 2 N_h harmonics) from the sweep's orbits of that period only (omega =
Omega / 2), with the primary and the branches just found known (embedded there): the
period-doubled branches time integration lands on. A doubled branch that passes through an
orbit of a known branch (the period doubling it is born at, hbm.isolas.harmonic.doubling_origin)
is "bifurcated". Every branch is
written to isolas.partial.h5 as soon as it is finished (and the seeds' corrections once
done), under the treatment's name or NAME.period_doubled; an interrupted run of the same
inputs resumes from them without recomputing. The final file is written atomically, both
searches of a treatment in its group.

Layout of isolas.h5 (root: the usual provenance attributes):
  /<method>/ per treatment ("dlft", "rl"); attrs n_seeds, n_converged, n_distinct,
      n_branches, cpu_time (s), wall_time (s; a resumed search's counts the interrupted
      runs' time up to their last saved step), status (str)
  /<method>/seeds/ omega (s,) rad/s; origin (s,) fixed-length ASCII; converged (s,) bool;
      branch (s,) int (the branch it lies on; -1 not converged, -2 on the primary NFRC);
      iterations (s,) int, Newton's; residual_norm (s,), ||R|| of its last iterate (nan
      where unknown); reason (s,) fixed-length ASCII, why Newton gave up ("" converged,
      "unknown" where a resumed search's partial file of an earlier version lacks it);
      the period-doubled search's seeds last, their branches numbered after the first's
  /<method>/branches/NNN/ omega (m,) rad/s; x (m, n_u) scaled unknowns; converged (m,) bool;
      le_amplitude (m,) m; harmonics (m, 2 N_h + 1, 3 n_b) m, eq. (5) order;
      modal_contribution (m, n) and harmonic_contribution (m, N_h + 1) m (eqs. 32-34, nan at
      the points not converged) with modes/frequencies (n,) rad/s; with [hbm] stability, as
      in the NFRC files: stable (m,) bool, n_unstable (m,) int,
      stability_analysed (m,) bool, stability_widened (m,) bool, stability_cpu_time (m,) s
      (of the analyses at each point: sum it for a branch's stability cost),
      leading_multipliers (m, 4), period_ratio (m,) int, stability_note (m,) text (why
      n_unstable is -1, "" where it is not), and bifurcations/ (the table of hbm.stability.bifurcation.bifurcation_arrays, index
      counting this branch's points); with [isolas] harmonic_checks > 0, harmonic_checks/
      (hbm.isolas.harmonic.harmonic_checks: index, omega rad/s, passed, moved, n_harmonics,
      cpu_time s, reason; index counting this branch's points). attrs kind ("primary" |
      "isola" | "bifurcated" | "detached"), closed (bool), status (str), subharmonic (nu),
      seeds (int array), start (seed continued), n_points_computed, cpu_time (s),
      harmonic_check ("converged" | "not converged" | "partly converged" | "unchecked": the
      points checked with 2 N_h all hold, none, some; hbm.isolas.harmonic.harmonic_verdict)
"""
from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from pipelines import artifacts as art
from pipelines.branch_store import read_column, read_table, write_column, write_tables
from pipelines.stages.base import Context, Estimate, Output, Stage
from pipelines.stages.hbm import STABILITY_FACTOR, nfrc_output, point_seconds
from pipelines.stages.rom import past_friction_lock, read_rom

ISOLAS = Output("isolas.h5")

#: Units of the per-branch datasets
_UNITS = {"omega": "rad/s", "x": "1", "converged": "1", "le_amplitude": "m", "harmonics": "m", "stable": "1",
          "modal_contribution": "1", "harmonic_contribution": "m",
          "n_unstable": "1", "stability_analysed": "1", "stability_widened": "1", "stability_cpu_time": "s",
          "leading_multipliers": "1", "period_ratio": "1", "stability_note": "-", "contact_fraction": "1"}


#: What the content columns hold (hbm.harmonic.content), written beside them: a reader of
#: isolas.h5 alone cannot tell whose modes, nor the frequency of a harmonic column
_CONTENT_MEANING = {
    "modal_contribution": "eq. (33): max over the period of |Phi_j^T M x| over their sum, for the n modes of "
                          "rom.h5's K, M at rest (Ritz approximations of the full model's, through the Craig-Bampton "
                          "basis), ascending frequency: modes/frequencies",
    "harmonic_contribution": "eq. (34): |c_k| of the LE radial displacement; column k is harmonic k of the branch's "
                             "basis, frequency k Omega / nu, nu the branch's attribute subharmonic",
    "contact_fraction": "share of the period each contact node (LE to TE) is in contact, by the contact law on its "
                        "AFT grid; 1: the node never leaves the casing (with mu >= rom.h5's mu_set, the friction lock)",
}


@dataclass(frozen=True, eq=False)
class IsolaBranch:
    """One branch of isolas.h5 (m points).

    method: "dlft" | "rl"; index: its NNN. kind: "primary" | "isola" | "bifurcated" |
    "detached"; closed; status (how each half ended); subharmonic: nu (basis Omega / nu);
    seeds (k,) int: indices into the treatment's seeds. omega (m,) rad/s; x (m, n_u) scaled
    unknowns; converged (m,) bool; le_amplitude (m,) m; harmonics (m, 2 N_h + 1, 3 n_b) m;
    stable (m,) bool and n_unstable (m,) int, or None without stability; stability_note (m,)
    str, why n_unstable is -1 ("" where it is not; None in files without it). modal_contribution
    (m, n) and harmonic_contribution (m, N_h + 1), m: the dynamical content of each point
    (hbm.harmonic.content, eqs. 32-34), or None in files without it. bifurcations: the
    branch's table {column: array} (hbm.stability.bifurcation.bifurcation_arrays; index
    counts this branch's points), or None without stability. seed_omega (k,) rad/s: Omega of
    each of its seeds (a sweep point's speed for the seeds from time integration). linked
    (j,) int: the indices of the other records of the same branch (pieces a later branch
    linked, hbm.isolas.search.connected; empty when it is whole), or None in files without it.
    harmonic_checks: the table {column: array} of the points solved again with 2 N_h
    (hbm.isolas.harmonic.harmonic_checks; index counts this branch's points), or None.
    contact_fraction (m, n_b): each contact node's share of the period in contact
    (hbm.isolas.harmonic.contact_fraction), or None in files without it.
    """

    method: str
    index: int
    kind: str
    closed: bool
    status: str
    subharmonic: int
    seeds: np.ndarray
    omega: np.ndarray
    x: np.ndarray
    converged: np.ndarray
    le_amplitude: np.ndarray
    harmonics: np.ndarray
    stable: np.ndarray | None = None
    n_unstable: np.ndarray | None = None
    stability_note: np.ndarray | None = None
    modal_contribution: np.ndarray | None = None
    harmonic_contribution: np.ndarray | None = None
    bifurcations: dict | None = None
    seed_omega: np.ndarray | None = None
    linked: np.ndarray | None = None
    harmonic_checks: dict | None = None
    contact_fraction: np.ndarray | None = None

    @property
    def locked_nodes(self) -> np.ndarray:
        """The contact nodes every converged point holds in contact over its whole period
        (locked_nodes below), (j,) int; empty when none is or the fraction is not stored."""
        return locked_nodes(self.contact_fraction, self.converged)

    @property
    def harmonic_verdict(self) -> str:
        """"converged", "not converged", "partly converged" in the number of harmonics (its
        harmonic_checks table, hbm.isolas.harmonic.harmonic_verdict), or "unchecked"."""
        return _verdict(self.harmonic_checks)

    @property
    def name(self) -> str:
        """Its group name under branches/: NNN."""
        return f"{self.index:03d}"


def _text(v) -> str:
    return v.decode() if isinstance(v, bytes) else str(v)


def read_isolas(path) -> dict[str, list[IsolaBranch]]:
    """{method: [IsolaBranch, ...]} of an isolas.h5 (branches in index order)."""
    import h5py

    out = {}
    with h5py.File(path, "r") as h5:
        for method in h5:
            g = h5[method]
            if not isinstance(g, h5py.Group) or "branches" not in g:
                continue
            rows = []
            seed_omega = g["seeds/omega"][()] if "seeds/omega" in g else np.zeros(0)
            for name in sorted(g["branches"]):
                b = g["branches"][name]
                a = b.attrs
                seeds = np.asarray(a["seeds"], dtype=np.int64).reshape(-1)
                rows.append(IsolaBranch(
                    method=method, index=int(name), kind=_text(a["kind"]), closed=bool(a["closed"]),
                    status=_text(a["status"]), subharmonic=int(a["subharmonic"]),
                    seeds=seeds, omega=b["omega"][()], x=b["x"][()],
                    converged=b["converged"][()].astype(bool), le_amplitude=b["le_amplitude"][()],
                    harmonics=b["harmonics"][()], stable=b["stable"][()].astype(bool) if "stable" in b else None,
                    n_unstable=b["n_unstable"][()] if "n_unstable" in b else None,
                    stability_note=read_column(b["stability_note"]) if "stability_note" in b else None,
                    modal_contribution=b["modal_contribution"][()] if "modal_contribution" in b else None,
                    harmonic_contribution=b["harmonic_contribution"][()] if "harmonic_contribution" in b else None,
                    bifurcations=({k: v for k, (v, _) in read_table(b["bifurcations"]).items()}
                                  if "bifurcations" in b else None),
                    seed_omega=seed_omega[seeds[(seeds >= 0) & (seeds < len(seed_omega))]],
                    linked=np.asarray(a["linked"], dtype=np.int64).reshape(-1) if "linked" in a else None,
                    harmonic_checks=({k: v for k, (v, _) in read_table(b["harmonic_checks"]).items()}
                                     if "harmonic_checks" in b else None),
                    contact_fraction=b["contact_fraction"][()] if "contact_fraction" in b else None))
            out[method] = rows
    return out


# -- writing ---------------------------------------------------------------------------------
def _write_branch(group, fb, nu: int, content: dict | None = None, linked=None) -> None:
    """linked: the file indices of the other records of fb's branch (_linked), or None (a
    partial file's record: its statuses name them)."""
    data = {"omega": fb.omega, "x": fb.x, "converged": np.asarray(fb.converged, bool)}
    data.update({k: v for k, v in fb.extras.items() if k in _UNITS})
    data.update({k: v for k, v in (content or {}).items() if k in _UNITS})
    for name, v in data.items():
        write_column(group, name, v, _UNITS[name])
    for name, text in _CONTENT_MEANING.items():
        if name in group:
            group[name].attrs["description"] = text
    write_tables(group, fb.extras.get("tables", {}))
    if content is not None and "mode_frequencies" in content:
        write_tables(group, {"modes": {"frequencies": (content["mode_frequencies"], "rad/s")}})
    a = group.attrs
    a["kind"], a["closed"], a["status"], a["subharmonic"] = fb.kind, bool(fb.closed), fb.status, int(nu)
    a["harmonic_check"] = _verdict(_check_table(fb))
    a["seeds"] = np.asarray(fb.seeds, dtype=np.int64)
    a["start"], a["n_points_computed"], a["cpu_time"] = int(fb.start), int(fb.n_points_computed), float(fb.cpu_time)
    if linked is not None:
        a["linked"] = np.asarray(linked, dtype=np.int64)


def locked_nodes(fraction, converged) -> np.ndarray:
    """The contact nodes in contact over the whole period at every converged point, (j,) int:
    fraction (m, n_b), the points' contact_fraction (None: not known, none); converged (m,)
    bool."""
    if fraction is None or not np.any(converged):
        return np.zeros(0, np.int64)
    f = np.asarray(fraction, float)[np.asarray(converged, bool)]
    return np.flatnonzero(np.all(f >= 1.0, axis=0))


def locked_text(fraction, converged, mu: float, rom) -> str:
    """", nodes 6, 7 never leave the casing (the friction lock: ...)" for a branch whose converged
    points all hold those nodes in contact over the whole period (locked_nodes); the friction
    lock where mu >= the ROM's mu_set (rom.friction_lock), as the validation stage calls a
    march's permanent contact. "" when no node is, or the fraction is not known (a branch of
    an older file)."""
    nodes = locked_nodes(fraction, converged)
    if not len(nodes):
        return ""
    why = f" (the friction lock: mu = {mu:g} >= mu_set = {rom.friction_lock.mu_set:.3g})" \
        if past_friction_lock(mu, rom) else ""
    names = ", ".join(str(int(j)) for j in nodes)
    return (f", nodes {names} never leave the casing" if len(nodes) > 1 else
            f", node {names} never leaves the casing") + why


def _check_table(fb) -> dict | None:
    """{column: array} of a FoundBranch's harmonic_checks table, or None."""
    t = fb.extras.get("tables", {}).get("harmonic_checks")
    return None if t is None else {k: v for k, (v, _) in t.items()}


def _verdict(table) -> str:
    """hbm.isolas.harmonic.harmonic_verdict, imported when a branch is written: this module is
    loaded at every command's start, the isola search's only by the runs that need it."""
    from hbm.isolas.harmonic import harmonic_verdict

    return harmonic_verdict(table)


def _read_found(group):
    from hbm.isolas.search import FoundBranch
    from hbm.stability.monitor import PER_POINT

    a = group.attrs
    # per-point datasets read back into the FoundBranch's extras (resume)
    extras = {k: read_column(group[k]) for k in ("le_amplitude", "harmonics", "modal_contribution",
                                                 "harmonic_contribution", "contact_fraction") + PER_POINT
              if k in group}
    tables = {name: read_table(group[name]) for name in ("bifurcations", "harmonic_checks") if name in group}
    if tables:
        extras["tables"] = tables
    return FoundBranch(omega=group["omega"][()], x=group["x"][()], converged=group["converged"][()].astype(bool),
                       kind=_text(a["kind"]), closed=bool(a["closed"]), status=_text(a["status"]),
                       start=int(a["start"]), seeds=tuple(int(s) for s in np.asarray(a["seeds"]).reshape(-1)),
                       extras=extras, n_points_computed=int(a["n_points_computed"]), cpu_time=float(a["cpu_time"]))


def _ascii(texts) -> np.ndarray:
    """Fixed-length ASCII (plain bytes, which the checksums read as they are) of a list of str."""
    b = [t.encode("ascii", "replace") for t in texts]
    return np.array(b, dtype=f"S{max([len(x) for x in b] + [1])}")


def _write_corrections(group, c) -> None:
    kept = np.flatnonzero(c.converged & (c.same_as < 0))  # the distinct solutions (RL seeds from DLFT's)
    for name in ("converged", "iterations", "on_known", "same_as"):
        group.create_dataset(name, data=getattr(c, name)).attrs["unit"] = "1"
    group.create_dataset("kept", data=kept).attrs["unit"] = "1"
    group.create_dataset("kept_x", data=c.x[kept]).attrs["unit"] = "1"
    if c.residual_norm is not None:
        group.create_dataset("residual_norm", data=c.residual_norm).attrs["unit"] = "1"
    if len(c.reason):
        group.create_dataset("reason", data=_ascii(c.reason)).attrs["unit"] = "-"
    group.attrs["cpu_time"] = float(c.cpu_time)


def _read_corrections(group):
    from hbm.isolas.search import Corrections

    conv = group["converged"][()].astype(bool)
    cand, xc = group["kept"][()], group["kept_x"][()]
    X = np.full((len(conv), xc.shape[1] if xc.ndim == 2 else 0), np.nan)
    X[cand] = xc
    rn = group["residual_norm"][()] if "residual_norm" in group else None
    why = tuple(_text(v) for v in group["reason"][()]) if "reason" in group else ()
    return Corrections(conv, group["iterations"][()], group["on_known"][()], group["same_as"][()], X,
                       float(group.attrs["cpu_time"]), rn, why)


def _seed_failures(parts) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """One treatment's searches' seeds in _merged's order: Newton iterations (s,), ||R|| of
    the last iterate (s,) (nan where unknown) and why Newton gave up (s,) ("" where it
    converged, "unknown" where a resumed part's partial file did not keep it)."""
    its, rn, why = [], [], []
    for r, _ in parts:
        c = r.corrections
        s = len(c.converged)
        its.append(np.asarray(c.iterations, np.int64))
        rn.append(np.full(s, np.nan) if c.residual_norm is None else np.asarray(c.residual_norm, float))
        why += list(c.reason) if len(c.reason) == s else ["" if ok else "unknown" for ok in c.converged]
    return np.concatenate(its), np.concatenate(rn), why


def failure_counts(reasons) -> dict[str, int]:
    """{kind of failure: seeds} of Newton's reasons (hbm.continuation.newton): each reason
    up to where it names the point (" at omega=..."), e.g. "stalled", "no convergence in 60
    iterations"; converged seeds ("") left out."""
    out: dict = {}
    for w in reasons:
        if w:
            k = w.split(" at omega=")[0].split(":")[0]
            out[k] = out.get(k, 0) + 1
    return out


class _Partial:
    """isolas.partial.h5: the corrections and finished branches of each treatment, flushed as
    they come (h5py, reopened per write so that a kill leaves at most the last one cut)."""

    def __init__(self, path, inputs_hash: str):
        self.path, self.hash = path, inputs_hash

    def _ours(self) -> bool:
        """The file exists and was written for these inputs."""
        return self.path.is_file() and art.read_attrs(self.path).get("inputs_hash") == self.hash

    def resume(self, method: str, seeds=None):
        """(corrections or None, [FoundBranch]) of an interrupted run of these inputs; (None, [])
        when that run corrected other seeds than `seeds` (given: e.g. a sweep computed again
        under the same inputs brings other seeds from time integration)."""
        import h5py

        if not self._ours():
            return None, []
        try:
            with h5py.File(self.path, "r") as h5:
                if method not in h5 or "corrections" not in h5[method]:
                    return None, []
                g = h5[method]
                c = _read_corrections(g["corrections"])
                if seeds is not None and (len(c.converged) != len(seeds) or _text(
                        g["corrections"].attrs.get("seeds_digest", _seeds_digest(seeds))) != _seeds_digest(seeds)):
                    return None, []
                found = []
                for k in range(int(g.attrs.get("n_branches", 0))):
                    found.append(_read_found(g["branches"][f"{k:03d}"]))
                return c, found
        except (OSError, KeyError, ValueError):
            return None, []

    def spent(self, method: str) -> float:
        """Wall time (s) the interrupted run(s) of these inputs spent on `method` up to their
        last saved step: a resumed search's wall time is theirs plus the resume's."""
        import h5py

        if not self._ours():
            return 0.0
        try:
            with h5py.File(self.path, "r") as h5:
                return float(h5[method].attrs.get("wall_time", 0.0)) if method in h5 else 0.0
        except (OSError, KeyError, ValueError):
            return 0.0

    def _open(self):
        if not self._ours():
            h5 = art.open_in_place(self.path, "w")
            h5.attrs["inputs_hash"] = self.hash
            return h5
        return art.open_in_place(self.path, "a")

    def corrections(self, method: str, c, seeds=None, wall: float = 0.0) -> None:
        """wall: s spent on `method` so far, resumed runs included (see `spent`)."""
        with self._open() as h5:
            if method in h5:
                del h5[method]
            g = h5.create_group(method)
            _write_corrections(g.create_group("corrections"), c)
            if seeds is not None:
                g["corrections"].attrs["seeds_digest"] = _seeds_digest(seeds)
            g.create_group("branches")
            g.attrs["n_branches"] = 0
            g.attrs["wall_time"] = float(wall)
            _count_branches(h5)

    def branch(self, method: str, index: int, fb, nu: int, wall: float | None = None) -> None:
        """wall: as in `corrections`, at this branch's end (None: left as it is)."""
        with self._open() as h5:
            g = h5[method]
            if wall is not None:
                g.attrs["wall_time"] = float(wall)
            name = f"{index:03d}"
            if name in g["branches"]:
                old = g["branches"][name]
                if int(old.attrs.get("start", -1)) == fb.start and old["omega"].shape == np.shape(fb.omega):
                    # the same branch, joined by more seeds: only its attributes change (a search
                    # saves a branch again at every seed that joins it; rewriting its points
                    # each time would write its megabytes hundreds of times); seeds last, so
                    # that a kill before them leaves the seed to be tried again
                    a = old.attrs
                    a["kind"], a["status"] = fb.kind, fb.status
                    a["n_points_computed"], a["cpu_time"] = int(fb.n_points_computed), float(fb.cpu_time)
                    a["seeds"] = np.asarray(fb.seeds, dtype=np.int64)
                    return
                del g["branches"][name]
            _write_branch(g["branches"].create_group(name), fb, nu)
            # last: the branch counts once all of it is written (an earlier one saved again
            # with the seeds that joined it leaves the count as it is)
            g.attrs["n_branches"] = max(int(g.attrs.get("n_branches", 0)), index + 1)
            _count_branches(h5)


def _seeds_digest(seeds) -> str:
    """sha256 of the seeds' Omega and start guesses: what the corrections on disk were made from."""
    import hashlib

    h = hashlib.sha256()
    for sd in seeds:
        h.update(np.float64(sd.omega).tobytes())
        h.update(np.ascontiguousarray(sd.x, dtype=np.float64).tobytes())
    return h.hexdigest()


def _count_branches(h5) -> None:
    """The root attribute n_branches: every treatment's finished branches, for what an
    interrupted run says it kept (pipelines.runner)."""
    h5.attrs["n_branches"] = sum(int(h5[m].attrs.get("n_branches", 0)) for m in h5)


def _merged(parts):
    """One treatment's searches as one: (seeds, converged (s,) bool, seed_branch (s,) int,
    [(FoundBranch, nu)]), the branches numbered on from part to part. A seed of a later part
    (the period-doubled one) that lies on a known branch other than the first (the primary)
    lies on a branch of the first part, embedded: it gets that branch's number."""
    from hbm.isolas.search import ON_KNOWN

    seeds, converged, seed_branch, branches = [], [], [], []
    first = len(parts[0][0].branches)
    for r, res in parts:
        offset = len(seeds)  # a part's seed indices count from its own first seed
        sb = np.array(r.seed_branch, dtype=np.int64)
        sb[sb >= 0] += len(branches)
        if branches:  # known branches: [primary, the first part's branches in order]
            c = r.corrections
            on = np.array(c.on_known, dtype=np.int64)
            # a duplicate on no known branch itself lies where its representative does (one on
            # a known branch keeps it: a representative is on none)
            dup = (np.asarray(c.same_as) >= 0) & (on < 0)
            on[dup] = on[np.asarray(c.same_as)[dup]]
            moved = (sb == ON_KNOWN) & (on >= 1) & (on <= first)
            sb[moved] = on[moved] - 1
            for i in np.flatnonzero(moved):  # the branch carries the seeds that lie on it
                fb, nu = branches[sb[i]]
                branches[sb[i]] = (replace(fb, seeds=tuple(sorted(fb.seeds + (offset + int(i),)))), nu)
        seeds += list(r.seeds)
        converged.append(np.asarray(r.corrections.converged, bool))
        seed_branch.append(sb)
        branches += [(replace(fb, start=fb.start + offset, seeds=tuple(offset + s for s in fb.seeds)), res.nu)
                     for fb in r.branches]
    return seeds, np.concatenate(converged), np.concatenate(seed_branch), branches


def _linked(parts) -> list[tuple[int, ...]]:
    """Per branch in _merged's numbering, the indices of the other records of its branch: a
    search's statuses name linked pieces in that search's own numbering
    (hbm.isolas.search.connected), which _merged shifts for the later parts."""
    out: list = []
    for r, _ in parts:
        rows = [()] * len(r.branches)
        for g in r.groups:
            for k in g:
                rows[k] = tuple(len(out) + j for j in g if j != k)
        out += rows
    return out


def _born_at_doublings(result, res, pd_res, known, options, ctx=None):
    """The doubled search's result with each branch that passes through an orbit of a known
    branch of res's basis (hbm.isolas.harmonic.doubling_origin: the continuation's own join
    test misses these crossings) made "bifurcated", the crossing named in its status; also
    sought for the branches the search called bifurcated only because they merge into the
    primary without its symmetry (hbm.isolas.search.LEAVES_SYMMETRY): where they were born."""
    from dataclasses import replace

    from hbm.harmonic.solver import HbmSolver
    from hbm.isolas.harmonic import doubling_origin
    from hbm.isolas.search import LEAVES_SYMMETRY

    solver = HbmSolver(atol=0.1 * res.options.tolerance)
    out = list(result.branches)
    for i, fb in enumerate(result.branches):
        seek = fb.kind != "bifurcated" or LEAVES_SYMMETRY in fb.status
        hit = doubling_origin(res, pd_res, solver, fb, known, options) if seek else None
        if hit is not None:
            k, w = hit
            out[i] = replace(fb, kind="bifurcated",
                             status=f"{fb.status}; born at a period doubling of {known[k].label} near {w:.1f} rad/s")
            if ctx is not None:
                ctx.log(f"    doubled branch {i:03d}: a period doubling of {known[k].label} near {w:.1f} rad/s: bifurcated")
    for group in result.groups:  # the pieces of one branch (hbm.isolas.search) share its kind
        if any(out[i].kind == "bifurcated" for i in group):
            for i in group:
                if out[i].kind != "bifurcated":
                    out[i] = replace(out[i], kind="bifurcated",
                                     status=f"{out[i].status}; bifurcated: one branch with a branch born at a period doubling")
    final = replace(result, branches=tuple(out))
    if ctx is not None and any(a.kind != b.kind for a, b in zip(out, result.branches)):
        # the search's own line counted the kinds before this test
        ctx.log(f"    branches by kind, the doublings above included: {_kinds_text(final.kind_counts())}")
    return final


def _kinds_text(kinds: dict) -> str:
    """{kind: branches} in words for the log, e.g. "2 bifurcated, 1 isola" ("none" when empty)."""
    return ", ".join(f"{n} {k}" for k, n in sorted(kinds.items())) or "none"


def _embedded(branch, res, target):
    """A KnownBranch of res's unknowns in those of `target`, whose fundamental is an integer
    fraction of res's (hbm.stability.switching.embed_harmonics: an exact solution there too)."""
    from hbm.isolas.membership import KnownBranch
    from hbm.stability.switching import embed_harmonics

    ratio = target.nu // res.nu
    x = np.array([embed_harmonics(u, res.n_r, ratio, target.basis.n_harmonics) for u in branch.x])
    return KnownBranch(branch.omega, x.reshape(len(branch.omega), -1), branch.label)


def _content(res, rom, fb, modes) -> dict:
    """What _write_branch adds to a FoundBranch's own columns: the modes' frequencies, and the
    modal and harmonic contributions (hbm.harmonic.content.branch_content) where the search's
    describe did not compute them (a branch resumed from a partial file of an earlier
    version). modes: rom_modes(rom.K, rom.M)."""
    from hbm.harmonic.content import branch_content

    if "modal_contribution" in fb.extras:
        return {"mode_frequencies": modes[0]}
    return branch_content(res, rom, fb.x, fb.omega, modes)


def _write_final(path, results: dict, provenance: dict, content: dict) -> None:
    """content: {method: [_content of each branch]} (the modes' frequencies, and the
    contributions where the branch lacks them; hbm.harmonic.content, eqs. 32-34)."""
    import h5py

    with art.atomic_output(path) as tmp:
        with h5py.File(tmp, "w") as h5:
            h5.attrs["stage"] = provenance["stage"]
            h5.attrs["units"] = art.UNITS_SI
            h5.attrs["scene"] = provenance["scene_text"]
            h5.attrs["inputs_hash"] = provenance["inputs_hash"]
            h5.attrs["code_version"] = art.code_version()
            h5.attrs["created"] = art.now()
            for k, v in provenance["extra_attrs"].items():
                h5.attrs[k] = v
            for method, (parts, status, cpu, wall) in results.items():
                seeds, converged, seed_branch, branches = _merged(parts)
                linked = _linked(parts)
                g = h5.create_group(method)
                g.attrs.update({"n_seeds": len(seeds), "n_converged": int(converged.sum()),
                                "n_distinct": sum(r.n_distinct for r, _ in parts), "n_branches": len(branches),
                                "cpu_time": float(cpu), "wall_time": float(wall), "status": status})
                s = g.create_group("seeds")
                s.create_dataset("omega", data=np.array([sd.omega for sd in seeds], float)).attrs["unit"] = "rad/s"
                s.create_dataset("origin", data=_ascii([sd.origin for sd in seeds])).attrs["unit"] = "-"
                s.create_dataset("converged", data=converged).attrs["unit"] = "1"
                s.create_dataset("branch", data=seed_branch).attrs["unit"] = "1"
                its, rn, why = _seed_failures(parts)
                s.create_dataset("iterations", data=its).attrs["unit"] = "1"
                s.create_dataset("residual_norm", data=rn).attrs["unit"] = "1"
                s.create_dataset("reason", data=_ascii(why)).attrs["unit"] = "-"
                b = g.create_group("branches")
                for k, (fb, nu) in enumerate(branches):
                    _write_branch(b.create_group(f"{k:03d}"), fb, nu, content.get(method, [None] * (k + 1))[k],
                                  linked[k])
        art.add_checksums(tmp)


# -- the stage ---------------------------------------------------------------------------------
def _known(out, method: str):
    """(primary KnownBranch list, bifurcation points KnownBranch or None) from nfrc_METHOD.h5."""
    import h5py

    from hbm.isolas.membership import KnownBranch
    from pipelines.branch_store import load_branch
    from pipelines.stages.hbm import nfrc_output

    path = out / nfrc_output(method).file
    stored = load_branch(path)
    b = stored.branch
    primary = KnownBranch.of(b.omega, b.x, f"primary {method.upper()} NFRC", b.converged)
    bif = None
    with h5py.File(path, "r") as h5:
        if "bifurcations" in h5 and len(h5["bifurcations/omega"]):
            t = h5["bifurcations"]
            idx, frac, om = t["index"][()], t["fraction"][()], t["omega"][()]
            j = np.minimum(idx + 1, len(b.omega) - 1)
            xb = b.x[idx] + frac[:, None] * (b.x[j] - b.x[idx])
            bif = KnownBranch(om, xb, "bifurcations")
    return [primary], bif


def _compute(ctx: Context, outputs) -> None:
    """Under `mpirun -n N` the seeds' Newton corrections are shared among the ranks, rank 0
    continues the branches and writes."""
    from hbm.isolas.harmonic import (BranchDescriber, HbmProblem, dominant_harmonic, doubled_options, modal_seeds,
                                     rl_seeds, search_options, ti_seeds)
    from hbm.isolas.membership import KnownBranch
    from hbm.isolas.search import search
    from pipelines.branch_store import partial_path
    from pipelines.parallel import is_root, on_root, world

    scene, out = ctx.scene, ctx.out
    iso, hbm = scene.isolas, scene.hbm
    comm = world()
    root = is_root(comm)
    rom = read_rom(out)
    sweep = None
    if iso.ti_seeds and (out / "ti.h5").is_file():
        from pipelines.stages.ti import read_sweep

        sweep = read_sweep(out)
        if sweep.boundary is None:
            if root:
                ctx.progress.warn("ti.h5 holds no boundary states (written by an older version): no seeds from the "
                                  "time integration; rerun the ti stage (--force) to get them")
        else:
            held = sweep.boundary.shape[1] // scene.ti.samples_per_revolution
            need = hbm.subharmonic * (2 if iso.ti_period_doubled else 1)
            if root and held < need:
                ctx.progress.warn(f"ti.h5 holds {held} revolution(s) of boundary state per speed, fewer than the "
                                  f"{need} that its orbits of period {need} revolutions need: no seeds from those "
                                  f"(a ti.h5 of an older version holds 1: rerun the ti stage with --force)")
    lo, hi = iso.omega_range(hbm)
    omegas = np.linspace(lo, hi, iso.n_omega)
    opts = search_options(hbm, iso)
    co = opts.continuation
    stab = None  # the monitor's options: [hbm] stability_max_gap and refine_bifurcations, as for the NFRC
    if hbm.stability:
        from hbm.stability.monitor import StabilityOptions

        stab = StabilityOptions.of(hbm)
    final = out / ISOLAS.file
    partial = _Partial(partial_path(final), ctx.hashes[ISOLAS.file])
    unreadable = art.read_failure(partial.path) if root else ""
    if unreadable:
        ctx.progress.warn(f"{partial.path.name} cannot be read ({unreadable}): the search starts over")
    results = {}  # method -> ([(IsolaSearch, its residual), ...], status, cpu, wall), in hbm.methods' order
    mains = {}  # method -> its search in the scene's basis
    content = {}  # method -> the dynamical content of each branch
    from hbm.harmonic.content import rom_modes

    modes = rom_modes(rom.K, rom.M)
    def run_part(key, problem, res, seeds, known, bif, label, primaries=None):
        """One search (a treatment, or its period-doubled part; res: problem's residual, built
        once by the caller for its seeds): resumed from and saved to isolas.partial.h5 under
        `key`; known[:primaries] are the primary NFRC (None: all). -> (IsolaSearch, CPU s, wall s)."""
        corrections, done = partial.resume(key, seeds) if root else (None, [])
        if comm is not None:
            corrections, done = comm.bcast((corrections, done), root=0)
        # the wall time of the runs this one resumes: the search's wall time is all of them
        before = partial.spent(key) if root and corrections is not None else 0.0
        if root and corrections is not None:
            ctx.log(f"  {label}: resuming: seeds corrected, {len(done)} branches on disk")
        t0 = time.perf_counter()

        def spent() -> float:
            return before + time.perf_counter() - t0
        with ctx.progress.step(f"isolas {label}", len(seeds)) as update:
            def on_progress(phase, d, total):
                if phase == "seeds":
                    update(f"seeds {d}/{total}", completed=d)
                else:
                    update(f"branches {d}/{total} candidates")

            result = search(problem, seeds, known, opts, comm=comm, corrections=corrections,
                            seed_factory=problem.for_seeds(), branches=done,
                            bifurcation_points=bif, primaries=primaries,
                            describe=BranchDescriber(problem, problem.hbm.stability, (co.x_scale, co.omega_scale),
                                                     stab, iso.harmonic_checks, content=True),
                            on_corrections=lambda c: partial.corrections(key, c, seeds, spent()) if root else None,
                            on_branch=lambda i, fb: partial.branch(key, i, fb, res.nu, spent()) if root else None,
                            on_progress=on_progress)
        wall = spent()
        cpu = result.cpu_time + sum(b.cpu_time for b in done)
        if root:
            kinds = result.kind_counts()  # linked pieces of one branch (several records) counted once
            records = "" if len(result.groups) == len(result.branches) else f" in {len(result.branches)} records"
            ctx.log(f"  {label}: {len(seeds)} seeds, {result.n_converged} converged ({result.n_distinct} distinct), "
                    f"{len(result.groups)} branches{records} ({_kinds_text(kinds)}), CPU {cpu:.0f} s, wall {wall:.0f} s"
                    + (f" ({before:.0f} s of it before the resume)" if before else ""))
            failed = failure_counts(result.corrections.reason)
            if failed:  # Newton's verdicts on the seeds that did not converge, by kind
                ctx.log("    seeds not converged: " + ", ".join(f"{n} {k}" for k, n in sorted(failed.items())))
            for k, b in enumerate(result.branches):
                ok = b.converged
                h = b.extras.get("harmonics")
                dom = dominant_harmonic(h[ok]) if h is not None else 0
                t = _check_table(b)
                checked = "" if t is None else \
                    f", {int(np.sum(t['passed']))} of {len(t['passed'])} points hold with 2 N_h ({_verdict(t)})"
                ctx.log(f"    branch {k:03d}: {b.kind}{' (closed)' if b.closed else ''}, Omega "
                        f"{b.omega[ok].min():.0f}-{b.omega[ok].max():.0f} rad/s, {int(ok.sum())} points, "
                        f"dominant harmonic {dom} of Omega / {res.nu}, {len(b.seeds)} seeds{checked}"
                        + locked_text(b.extras.get("contact_fraction"), ok, scene.contact.mu, rom))
        return result, cpu, wall

    for method in sorted(hbm.methods):  # DLFT first: RL's modal seeds are its solutions
        problem = HbmProblem(rom, scene.casing, scene.contact, hbm, method)
        res, _ = problem()
        known, bif = _known(out, method)
        if method == "rl" and "dlft" in results:
            seeds = rl_seeds(mains["dlft"], opts, iso.rl_branch_seeds)
        else:
            seeds = modal_seeds(res, rom, iso, omegas, around=tuple(known))
        if sweep is not None:
            seeds += ti_seeds(res, sweep, (lo, hi), scene.casing.n_lobes)
        result, cpu, wall = run_part(method, problem, res, seeds, known, bif, method)
        mains[method] = result
        parts = [(result, res)]
        if sweep is not None and iso.ti_period_doubled:
            # the sweep's orbits of twice the basis' period, in the basis of Omega / (2 nu) with
            # 2 N_h harmonics (the same resolution); the branches found so far, embedded there,
            # are known: a seed that falls back to an orbit without the new harmonics is on one
            pd_problem = HbmProblem(rom, scene.casing, scene.contact, doubled_options(hbm), method)
            pd_res, _ = pd_problem()
            pd_seeds = ti_seeds(pd_res, sweep, (lo, hi), scene.casing.n_lobes, only_new_to=res.nu)
            if pd_seeds:
                found = [KnownBranch.of(b.omega, b.x, f"branch {i:03d}", b.converged)
                         for i, b in enumerate(result.branches)]
                pd_known = [_embedded(k, res, pd_res) for k in known + found]
                pd_bif = _embedded(bif, res, pd_res) if bif is not None else None
                pd_result, pd_cpu, pd_wall = run_part(f"{method}.period_doubled", pd_problem, pd_res, pd_seeds,
                                                      pd_known, pd_bif, f"{method}, period-doubled orbits of the sweep",
                                                      primaries=len(known))
                pd_result = _born_at_doublings(pd_result, res, pd_res, known + found, opts, ctx if root else None)
                parts.append((pd_result, pd_res))
                cpu, wall = cpu + pd_cpu, wall + pd_wall
        results[method] = (parts, "complete", cpu, wall)
        if root:
            content[method] = [_content(r, rom, b, modes) for part, r in parts for b in part.branches]

    def write():
        _write_final(final, results, ctx.provenance(ISOLAS, "isolas"), content)
        partial.path.unlink(missing_ok=True)

    on_root(comm, write)


def _estimate(scene, out, outputs) -> Estimate:
    """Seeds: n_modes x harmonics x (amplitudes + primary_amplitudes) x n_omega for the first
    treatment, a Newton each (3 to 5 iterations on rotor 67: most stall after 3), costed as
    one continuation point (pipelines.stages.hbm.point_seconds; measured: half of one on an
    Emerald Rapids host, the slowest hosts seen take twice as long), over the cores (with
    both treatments RL's seeds are DLFT's distinct solutions and points along its branches,
    a few hundred on rotor 67: left out); then, per treatment, a few branches of up to 2
    max_points points. With [hbm] stability (every branch analysed and its bifurcations
    located) the stage took 1.9 (coarse) to 2.9 (default scene) times as long on one host,
    about what the NFRCs take: STABILITY_FACTOR times."""
    import os

    iso, h = scene.isolas, scene.hbm
    n_c = 2 * h.n_harmonics + 1
    per_point = point_seconds(scene)
    # harmonic k of Omega is harmonic k nu of the basis (hbm.isolas.harmonic.modal_seeds)
    n_kept = len([k for k in iso.harmonics if k * h.subharmonic <= h.n_harmonics])
    # and the family around the primary: one of its points a speed (more where it folds)
    n_seeds = iso.n_modes * n_kept * (len(iso.amplitudes) + len(iso.primary_amplitudes)) * iso.n_omega
    cores = len(os.sched_getaffinity(0)) if iso.workers is None else iso.workers
    seconds = n_seeds * per_point / cores + len(h.methods) * 5 * 2 * iso.max_points * per_point / 4
    if h.stability:
        seconds *= STABILITY_FACTOR
    # the memory (what the guard refuses on) is that of the worker processes, ~0.3 GB each,
    # whatever the seeds: one per core for the seeds, four for the branches (two halves, two
    # describing) with two workers or more; the advice names the key that sets their number
    workers = (f"lower [isolas] workers (now {iso.workers}; ~0.3 GB each)" if iso.workers is not None
               else f"set [isolas] workers below {cores} (unset: one per core; ~0.3 GB each)")
    processes = max(cores, 4) if cores >= 2 else 1
    return Estimate(size=f"{n_seeds} seeds per treatment", memory=0.3e9 * processes, seconds=seconds,
                    disk=len(h.methods) * 10 * iso.max_points * n_c * 3 * scene.n_contact_nodes * 8.0 * 2,
                    advice=workers)


def _outputs(scene) -> tuple[Output, ...]:
    """isolas.h5, one file for the treatments searched: RL's own [contact] keys (those of its
    NFRC, pipelines.stages.hbm.nfrc_output) count only where RL is among them; a DLFT search
    never reads them."""
    rl = nfrc_output("rl").depends
    contact = "contact" if "rl" in scene.hbm.methods else "~".join(["contact", *(k.split(".", 1)[1] for k in rl)])
    return (Output(ISOLAS.file, depends=(contact,)),)


STAGE = Stage("isolas", depends=("isolas~workers", "hbm", "casing"), upstream=("rom", "hbm", "ti"),
              outputs=_outputs, compute=_compute, estimate=_estimate, distributed=True)
