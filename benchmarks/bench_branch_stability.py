"""Which branches of an isola search a blade can be found on: Floquet multipliers (Hill's
method, hbm.stability.spectrum.orbit_spectrum) at every k-th point of every branch of
OUT/isolas.h5, then time integration (100 periods, the validation stage's march and
verdict) from up to --march stable points per branch: spread over its stable points (the
first and last included), or with --picks centres the middle analysed point of each of its
longest stretches of stable analysed points (away from where stability changes: next to a
fold or a pitchfork the stable and unstable orbits are closer than the HBM orbit is to time
integration's own, and a march from there can fall either way). --picks all: every analysed
point, stable or not (where time integration's own stability changes against Hill's);
--omega-span: only the points with LO <= Omega <= HI; --periods: the march's length.

    PYTHONPATH=. .venv/bin/python benchmarks/bench_branch_stability.py OUT [--scene scenes/rotor67_coarse.toml]
        [--every 6] [--march 3] [--picks spread|centres|all] [--periods 100] [--omega-span LO:HI]
        [--methods dlft rl] [--kinds isola detached]
    PYTHONPATH=. .venv/bin/python benchmarks/bench_branch_stability.py OUT --window-check 12
        [--branches rl/007 dlft/008] [--seed 1]
    PYTHONPATH=. .venv/bin/python benchmarks/bench_branch_stability.py OUT --monitor --branches rl/006
        [--span 450:650] [--save new.npz]
    PYTHONPATH=. .venv/bin/python benchmarks/bench_branch_stability.py OUT --nfrc [--methods dlft]

--window-check N: on branches stored with stability ([hbm] stability), N of the points the
monitor analysed, drawn at random, are analysed again with the monitor's 40-eigenvalue
window (no widening) and with orbit_spectrum's widening; one line per point gives the
stored verdict and both of these, to show which stable verdicts a 40-eigenvalue window
gets wrong (a multiplier beyond its ceiling).

--monitor: the stability monitor is run again over each branch as the isolas stage runs it;
one line per branch gives the stored and the new analysed, widened and stable counts, the
bifurcations by kind (and those whose kind comes from the parities of the real multipliers
or is a guess: no multiplier paired across the circle, Bifurcation.kind_from, and how many
of those lie where the stable flag changes), the
count changes left unresolved (two analysed points apart that differ with nothing bisected
between them), and the CPU time of the analyses, split between plain and widened points.
--nfrc: the same over the NFRC files' converged points. Both also count the steps whose
records do not add up to the change of the count of unstable multipliers or to the sign
changes of det(I + M) and det(I - M) there (see hbm.stability.bifurcation.real_parities).

Needs OUT/rom.h5 and OUT/isolas.h5 of that scene (e.g. from `bladerub run SCENE --out OUT`).
Prints one line per branch (points analysed, stable ones and their Omega span, the range of
the largest multiplier modulus, the minimal periods met and the median CPU time of one
analysis) and one per march (stays or leaves, growth, deviation of the
last 10 periods, where Newton from the last period lands as the validation stage checks it,
largest contact force at the end).
"""
from __future__ import annotations

import argparse
import sys
import time
from collections import Counter
from pathlib import Path

import hbm  # noqa: F401  (before numpy: OpenBLAS's kernels for the host, hbm.openblas)
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main() -> None:
    from hbm.harmonic.residual import build_residual
    from hbm.stability.spectrum import orbit_spectrum
    from hbm.ti.march import rom_modal_system
    from hbm.ti.validation import confirm_orbit, march_from_hbm
    from pipelines.scene import load_scene
    from pipelines.stages.isolas import read_isolas
    from pipelines.stages.rom import read_rom
    from pipelines.stages.validation import _landing, _options_for

    ap = argparse.ArgumentParser()
    ap.add_argument("out", type=Path)
    ap.add_argument("--scene", type=Path, default=ROOT / "scenes" / "rotor67_coarse.toml")
    ap.add_argument("--every", type=int, default=6, help="analyse every k-th point of a branch")
    ap.add_argument("--march", type=int, default=3, help="time integrations per branch, from its stable points")
    ap.add_argument("--picks", choices=("spread", "centres", "all"), default="spread",
                    help="march from stable points spread over all of them, or from the middles of the longest "
                         "stable stretches, or from every analysed point")
    ap.add_argument("--periods", type=int, default=100, help="periods of each march")
    ap.add_argument("--omega-span", default="", metavar="LO:HI",
                    help="analyse only the points with LO <= Omega <= HI (rad/s)")
    ap.add_argument("--methods", nargs="+", default=["dlft", "rl"])
    ap.add_argument("--kinds", nargs="+", default=["isola", "detached", "bifurcated"])
    ap.add_argument("--window-check", type=int, default=0, metavar="N",
                    help="analyse N random stored-analysed points per branch with and without widening")
    ap.add_argument("--monitor", action="store_true",
                    help="run the stability monitor again over each branch, as the isolas stage does, and "
                         "compare it with the stored stability")
    ap.add_argument("--nfrc", action="store_true",
                    help="run the stability monitor again over the NFRC files' converged points instead "
                         "(OUT/nfrc_METHOD.h5, scene settings): bifurcations by kind, and which are guesses")
    ap.add_argument("--branches", nargs="+", help="METHOD/NNN of the branches to take (default: all of --kinds)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--span", default=":", metavar="A:B",
                    help="with --monitor: only the branch's converged points A to B - 1 (a Python slice)")
    ap.add_argument("--save", type=Path, metavar="NPZ",
                    help="with --monitor: write the new per-point stability and bifurcations there "
                         "(METHOD_NNN_ prefixed keys), to compare two codes")
    a = ap.parse_args()
    scene = load_scene(a.scene)
    rom = read_rom(a.out)
    system = rom_modal_system(rom)
    if a.nfrc:
        for method in a.methods:
            _monitor_nfrc(a.out, scene, rom, method)
        return
    found = read_isolas(a.out / "isolas.h5")
    n_r = 3 * rom.n_boundary
    for method in a.methods:
        for br in found.get(method, []):
            if (a.branches and f"{method}/{br.name}" not in a.branches) or (not a.branches and br.kind not in a.kinds):
                continue
            t0 = time.process_time()
            res = build_residual(rom, scene.casing, scene.contact,
                                 _options_for(scene.hbm, br.x.shape[1], n_r, br.subharmonic), method=method)
            if a.window_check:
                _window_check(a.out, method, br, res, a.window_check, a.seed)
                continue
            if a.monitor:
                _monitor_again(a.out, scene, method, br, res, slice(*(int(v) if v else None for v in a.span.split(":"))),
                               a.save)
                continue
            lo, hi = (float(v) for v in a.omega_span.split(":")) if a.omega_span else (-np.inf, np.inf)
            idx = [i for i in range(0, len(br.omega), a.every) if br.converged[i] and lo <= br.omega[i] <= hi]
            largest, stable, cost, ratios = [], [], [], set()
            for i in idx:
                c = time.process_time()
                spectrum, g = orbit_spectrum(res, br.x[i], float(br.omega[i]))
                cost.append(time.process_time() - c)
                ratios.add(int(g))
                largest.append(float(np.abs(spectrum.multipliers).max()))
                stable.append(spectrum.n_unstable == 0)
            largest, stable, idx = np.array(largest), np.array(stable, bool), np.array(idx)
            span = (f"stable {stable.sum()} at {br.omega[idx[stable]].min():.0f}-{br.omega[idx[stable]].max():.0f} rad/s"
                    if stable.any() else "none stable")
            print(f"{method} {br.name} {br.kind}{' (closed)' if br.closed else ''}, {br.omega.min():.0f}-"
                  f"{br.omega.max():.0f} rad/s, {len(br.omega)} points: {len(idx)} analysed, {span}; largest |mu| "
                  f"{largest.min():.3g} to {largest.max():.3g} (median {np.median(largest):.3g}); minimal period "
                  f"T / g, g in {sorted(ratios)}; one analysis {np.median(cost):.2f} s CPU (median); "
                  f"{time.process_time() - t0:.0f} s CPU", flush=True)
            picks = idx if a.picks == "all" else _picks(idx, stable, a.march, a.picks)
            for i in picks:
                ti = march_from_hbm(system, scene.casing, scene.contact.mu,
                                    res.expand_harmonics(br.x[i], float(br.omega[i])), float(br.omega[i]),
                                    subharmonic=br.subharmonic, n_periods=a.periods, dt=scene.ti.dt,
                                    record_all=True)
                # the stage's check: Newton from the last period tells the orbit from another
                # solution next to it, which the distance rule alone calls "stays"
                ti = confirm_orbit(res, ti, br.x[i], float(br.omega[i]))
                k = int(np.flatnonzero(idx == i)[0])
                print(f"    TI from Omega = {br.omega[i]:.2f} rad/s (LE {1e3 * br.le_amplitude[i]:.3f} mm; Hill: "
                      f"{'stable' if stable[k] else 'unstable'}, largest |mu| {largest[k]:.3g}): "
                      f"{ti.verdict().replace('leaves', 'LEAVES', 1)} (growth {ti.growth:.2f}, last deviation "
                      f"{ti.last_deviation:.3g}{_landing(ti)}), contact force at the end up to "
                      f"{ti.force_peak.max():.0f} N", flush=True)


def _picks(idx: np.ndarray, stable: np.ndarray, n: int, how: str) -> np.ndarray:
    """Up to n point indices among the analysed idx whose flag in stable is set: spread over
    them (first and last included), or the middle of each of the n longest runs of
    consecutive stable analysed points, in branch order."""
    picks = idx[stable]
    if how == "spread":
        return picks[np.linspace(0, len(picks) - 1, n).round().astype(int)] if len(picks) > n else picks
    runs, start = [], None
    for k, s in enumerate(list(stable) + [False]):
        if s and start is None:
            start = k
        elif not s and start is not None:
            runs.append((start, k))
            start = None
    runs = sorted(runs, key=lambda r: r[0] - r[1])[:n]  # longest first (stable sort: branch order on ties)
    return np.array(sorted(idx[(a + b - 1) // 2] for a, b in runs), dtype=int)


def _window_check(out: Path, method: str, br, res, n: int, seed: int) -> None:
    """The stored verdict of n random analysed points of br against a 40-eigenvalue analysis
    without widening (the monitor's plain one) and with orbit_spectrum's widening."""
    import h5py

    from hbm.stability.spectrum import orbit_spectrum

    with h5py.File(out / "isolas.h5", "r") as h5:
        g = h5[f"{method}/branches/{br.name}"]
        if "stability_analysed" not in g:
            print(f"{method} {br.name}: stored without stability, nothing to check")
            return
        analysed = np.flatnonzero(g["stability_analysed"][()])
        stored = np.abs(g["leading_multipliers"][()]).max(axis=1)
    pick = np.sort(np.random.default_rng(seed).choice(analysed, min(n, len(analysed)), replace=False))
    print(f"{method} {br.name} {br.kind}, {br.omega.min():.0f}-{br.omega.max():.0f} rad/s: {len(pick)} of "
          f"{len(analysed)} analysed points", flush=True)
    for i in pick:
        x, w = br.x[i], float(br.omega[i])
        plain, _ = orbit_spectrum(res, x, w, n_eig=40, min_ceiling=1.0)
        wide, _ = orbit_spectrum(res, x, w, n_eig=40)
        mark = "  <- 40 eigenvalues miss it" if plain.n_unstable == 0 and stored[i] > 1.0 else ""
        print(f"  {w:7.1f} rad/s: stored largest |mu| {stored[i]:.4g} ({'stable' if br.stable[i] else 'unstable'}); "
              f"40 eigenvalues {np.abs(plain.multipliers).max():.4g} (ceiling {plain.modulus_ceiling:.3g}); "
              f"widened {np.abs(wide.multipliers).max():.4g}{mark}", flush=True)


def _unresolved(analysed: np.ndarray, n_unstable: np.ndarray) -> int:
    """Pairs of consecutive analysed points, not neighbours, whose counts differ: the
    monitor bisects every such change down to neighbours unless its counts agreed when it
    compared them (a window widened after the point was stored)."""
    a = np.flatnonzero(analysed)
    return int(sum(1 for i, j in zip(a[:-1], a[1:]) if j > i + 1 and n_unstable[i] != n_unstable[j]))


def _bifurcation_counts(table: dict, stable: np.ndarray) -> str:
    """Counts by kind of a bifurcation table (bifurcation_arrays), those whose kind comes from
    the parities of the real multipliers and those whose kind is a guess (no multiplier
    paired across the circle, Bifurcation.kind_from) and, of the guesses, the ones where the
    stable flag changes (stable (m,) bool per described point)."""
    kinds = np.asarray(table["kind"][0], dtype=str)
    source = np.asarray(table["kind_from"][0], dtype=str)
    idx = np.asarray(table["index"][0], dtype=np.int64)
    st = np.asarray(stable, bool)
    change = np.array([st[i] != st[min(i + 1, len(st) - 1)] for i in idx], bool)
    guess, parity = source == "guess", source == "parity"
    return (f"{dict(sorted(Counter(str(k) for k in kinds).items()))}, of which from the parities "
            f"{dict(sorted(Counter(str(k) for k in kinds[parity]).items()))} ({int((parity & change).sum())} where "
            f"the stable flag changes), guessed {dict(sorted(Counter(str(k) for k in kinds[guess]).items()))} "
            f"({int((guess & change).sum())} where it changes)")


class _Spectra:
    """Keeps the last Floquet spectrum the monitor computed at each point (wrapping
    hbm.stability.monitor.orbit_spectrum), for _parity_check."""

    def __init__(self):
        import hbm.stability.monitor as monitor

        self.by_omega, self._module, self._inner = {}, monitor, monitor.orbit_spectrum

        def wrapped(res, u, w, **kw):
            out = self._inner(res, u, w, **kw)
            self.by_omega[float(w)] = out[0]
            return out

        monitor.orbit_spectrum = wrapped

    def close(self):
        self._module.orbit_spectrum = self._inner


def _parity_check(table: dict, omega: np.ndarray, spectra: dict) -> str:
    """Steps (neighbouring points with records, no fold) whose records do not add up to the
    change of the count of unstable multipliers (a Neimark-Sacker counts two) or whose
    period doublings and branch points do not match, in parity, the sign changes of
    det(I + M) and det(I - M) (bifurcation.real_parities over the spectra the monitor
    computed there)."""
    import math

    from hbm.stability.bifurcation import lone_real, real_parities
    from hbm.stability.monitor import WIDEN_FRACTION, StabilityOptions

    kinds = np.asarray(table["kind"][0], dtype=str)
    idx = np.asarray(table["index"][0], dtype=np.int64)
    direction = np.asarray(table["direction"][0], dtype=np.int64)
    source = np.asarray(table["kind_from"][0], dtype=str)
    mult = np.asarray(table["multiplier_real"][0], float) + 1j * np.asarray(table["multiplier_imag"][0], float)
    steps = {}
    for k, i, d, f, m in zip(kinds, idx, direction, source, mult):
        steps.setdefault(int(i), []).append((str(k), int(d), str(f), complex(m)))
    bad = total = 0
    for i, raw in steps.items():
        sa, sb = spectra.get(float(omega[i])), spectra.get(float(omega[i + 1]))
        if any(r[0] == "fold" for r in raw) or sa is None or sb is None:
            continue
        # the monitor's weights (StabilityMonitor._members): a crossing of a pair near the
        # real axis is one record of two multipliers, and no real crossing
        recs = []
        for k, d, f, m in raw:
            mu = (sb if d > 0 else sa).multipliers
            pair = k == "Neimark-Sacker" or (f == "crossing" and not lone_real(mu)[mu == m].all())
            recs.append((k if not pair or k == "Neimark-Sacker" else "pair", d, 2 if pair else 1))
        near = min(StabilityOptions().window,
                   WIDEN_FRACTION * math.log(max(min(sa.modulus_ceiling, sb.modulus_ceiling), 1.0)))
        pa = real_parities(sa.multipliers, sa.unstable, near)
        pb = real_parities(sb.multipliers, sb.unstable, near)
        if pa is None or pb is None:
            continue
        total += 1
        added = sum(n * d for _, d, n in recs)
        n_pd = sum(k == "period doubling" for k, _, _ in recs)
        n_bp = sum(k == "branch point" for k, _, _ in recs)
        if added != pb[0] - pa[0] or n_pd % 2 != (pa[1] != pb[1]) or n_bp % 2 != (pa[2] != pb[2]):
            bad += 1
    return f"{bad} of {total} steps with records (no turn) do not add up to the count change or the parities"


def _monitor_nfrc(out: Path, scene, rom, method: str) -> None:
    """The monitor over the converged points of OUT/nfrc_METHOD.h5, in the NFRC's arc-length
    scales, against the file's own stability."""
    import h5py

    from hbm.harmonic.nfrc import default_continuation
    from hbm.harmonic.residual import build_residual
    from hbm.isolas.harmonic import describe
    from hbm.stability.monitor import StabilityOptions
    from pipelines.branch_store import load_branch

    path = out / f"nfrc_{method}.h5"
    s = load_branch(path)
    ok = np.flatnonzero(s.branch.converged)
    res = build_residual(rom, scene.casing, scene.contact, scene.hbm, method=method)
    co = default_continuation(scene.hbm)
    spectra = _Spectra()
    c0 = time.process_time()
    new = describe(res, True, (co.x_scale, co.omega_scale),
                   StabilityOptions(max_gap=scene.hbm.stability_max_gap))(s.branch.omega[ok], s.branch.x[ok])
    cpu = time.process_time() - c0
    spectra.close()
    with h5py.File(path, "r") as h5:
        stored = Counter(k.decode() if isinstance(k, bytes) else str(k) for k in h5["bifurcations/kind"][()]) \
            if "bifurcations" in h5 else None
    old = s.extras.get("stable")
    print(f"{method} NFRC, {len(ok)} points: stored {None if old is None else int(np.asarray(old)[ok].sum())} stable, "
          f"bifurcations {None if stored is None else dict(sorted(stored.items()))}; again "
          f"{int(new['stability_analysed'].sum())} analysed, {int(new['stable'].sum())} stable, bifurcations "
          f"{_bifurcation_counts(new['tables']['bifurcations'], new['stable'])}; {cpu:.0f} s CPU; "
          f"{_parity_check(new['tables']['bifurcations'], s.branch.omega[ok], spectra.by_omega)}", flush=True)


def _monitor_again(out: Path, scene, method: str, br, res, span: slice = slice(None), save: Path | None = None) -> None:
    """The monitor over br's converged points (those of span) as the isolas stage runs it
    (one chunk here, where the stage splits a long branch in two), against the stored
    stability; save: an .npz to add the new per-point stability and bifurcations to."""
    import h5py

    from hbm.isolas.harmonic import describe, search_options
    from hbm.stability.monitor import StabilityOptions

    with h5py.File(out / "isolas.h5", "r") as h5:
        g = h5[f"{method}/branches/{br.name}"]
        if "stability_analysed" not in g:
            print(f"{method} {br.name}: stored without stability, nothing to compare")
            return
        old = {k: g[k][()] for k in ("stable", "n_unstable", "stability_analysed")}
        old_bif = [(k.decode() if isinstance(k, bytes) else str(k), int(i))
                   for k, i in zip(g["bifurcations/kind"][()], g["bifurcations/index"][()])] \
            if "bifurcations" in g else []
    ok = np.flatnonzero(br.converged)[span]
    co = search_options(res.options, scene.isolas).continuation
    spectra = _Spectra()
    c0 = time.process_time()
    new = describe(res, True, (co.x_scale, co.omega_scale),
                   StabilityOptions(max_gap=scene.hbm.stability_max_gap))(br.omega[ok], br.x[ok])
    cpu = time.process_time() - c0
    spectra.close()
    an, wid, t = new["stability_analysed"], new["stability_widened"], new["stability_cpu_time"]
    plain = t[an & ~wid]
    same = old["stability_analysed"][ok] & an
    differ = int((old["n_unstable"][ok][same] != new["n_unstable"][same]).sum())
    print(f"{method} {br.name} {br.kind}, {br.omega.min():.0f}-{br.omega.max():.0f} rad/s, {len(ok)} points: "
          f"stored {int(old['stability_analysed'][ok].sum())} analysed, {int(old['stable'][ok].sum())} stable, "
          f"{_unresolved(old['stability_analysed'][ok], old['n_unstable'][ok])} unresolved count changes; "
          f"again {int(an.sum())} analysed ({int(wid.sum())} widened), {int(new['stable'].sum())} stable, "
          f"{_unresolved(an, new['n_unstable'])} unresolved; at the {int(same.sum())} points analysed both "
          f"times the count differs at {differ}; analyses {t.sum():.0f} s CPU, of which widened points "
          f"{t[wid].sum():.0f} s (median {np.median(plain) if plain.size else float('nan'):.2f} s plain, "
          f"{np.median(t[wid]) if wid.any() else float('nan'):.2f} s widened); whole call {cpu:.0f} s CPU",
          flush=True)
    # bifurcations by kind, the stored ones counted over the same span of converged points
    bif = new["tables"]["bifurcations"]
    inside = {int(i) for i in ok}
    stored = Counter(k for k, i in old_bif if i in inside and i + 1 in inside)
    print(f"  bifurcations stored {dict(sorted(stored.items()))}; again "
          f"{_bifurcation_counts(bif, new['stable'])}; {_parity_check(bif, br.omega[ok], spectra.by_omega)}",
          flush=True)
    if save is not None:
        keys = ("stable", "n_unstable", "stability_analysed", "stability_widened", "stability_cpu_time")
        got = {f"{method}_{br.name}_{k}": np.asarray(new[k]) for k in keys}
        got.update({f"{method}_{br.name}_omega": br.omega[ok],
                    f"{method}_{br.name}_bif_kind": np.asarray(bif["kind"][0], dtype=str),
                    f"{method}_{br.name}_bif_omega": bif["omega"][0],
                    f"{method}_{br.name}_bif_kind_from": np.asarray(bif["kind_from"][0], dtype=str),
                    f"{method}_{br.name}_bif_multiplier": bif["multiplier_real"][0] + 1j * bif["multiplier_imag"][0]})
        if save.exists():
            got = dict(np.load(save), **got)
        np.savez(save, **got)


if __name__ == "__main__":
    main()
