"""Benchmark of one Floquet analysis (hbm.stability.spectrum.orbit_spectrum) at points of an NFRC,
or (--schedule) of the stability monitor's choice of points along a whole NFRC.

Usage:
  .venv/bin/python benchmarks/bench_stability.py [--rom tests/data/rotor67_coarse_rom.h5]
      [--methods dlft rl] [--points 12] [--nh 40] [--nt 1024] [--omega-min 1800] [--omega-max 2000]
  .venv/bin/python benchmarks/bench_stability.py --schedule [--methods dlft] [--omega-min 400 --omega-max 2000]

--schedule: the NFRC with stability twice, with the default StabilityOptions and with every
point analysed (max_gap 1, the reference); prints analyses, stability time and the
bifurcations of each, and which of the reference's the default schedule missed (same kind
within 2 rad/s).
--widen-check: the NFRC once, every point analysed with the monitor's 40-eigenvalue window,
and each one it calls stable again with orbit_spectrum's widening (a stable verdict must
hold up to MIN_CEILING); prints the points whose verdict the wider window changes, and the
cost of both.
--filter-check [--every 6]: RL only. Every k-th point of the NFRC analysed twice, with
Hill's operator as the product builds it (the residual's Lanczos filter on the force rows)
and without the filter, both widened to MIN_CEILING; where the verdicts differ, 100 periods
of time integration from the point (hbm.ti.validation.march_from_hbm, its verdict).
--woodbury-check: at `points` points, H(0)^-1's condensed solve two ways: the dense LU
(HillSolver) and the NFRC's Woodbury preconditioner (hbm.harmonic.preconditioner, exact but
for the friction's fluctuating sliding terms) completed by refinement or by GMRES to 1e-13;
prints the build and per-solve CPU times and how each iteration converges to the LU's answer.
--schedule --replay 0.5,0.25: the NFRC once, every point analysed once, then the monitor
replayed on those spectra for each StabilityOptions.reach_fraction given (and --max-gap; --spectra
keeps the NFRC and the spectra for the next replay; the schedule's
decisions are all that differ: the same analyses give the same spectra; the monitor's
widened analyses, hbm.stability.monitor, are made on demand and kept); prints per fraction
the analyses (and what asked for them: StabilityMonitor.causes), the crossings of the
every-point reference missed, and the points whose stable flag differs from the reference's.

Computes the NFRC over [omega_min, omega_max] without stability (one BLAS thread, as
compute_nfrc), then analyses `points` of its points spread along it, twice each (the
monitor's analysis: 40 eigenvalues, no widening), and prints
per method: the NFRC's time per point, and per analysis the median wall and CPU (process)
time, the share of its parts (the LU of H(0), the ~100 shift-invert solves, the rest:
ARPACK and the family selection), the nodes in contact, and the analysis' cost in NFRC
points. CPU time is the figure to compare between runs on a shared machine: wall time
there also counts the waits for a core.
"""
from __future__ import annotations

import argparse
import pickle
import statistics
import sys
import time
from pathlib import Path

import hbm  # noqa: F401  (before numpy: OpenBLAS's kernels for the host, hbm.openblas)
import numpy as np
from threadpoolctl import threadpool_limits

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from hbm.harmonic.nfrc import compute_nfrc  # noqa: E402
from hbm.harmonic.residual import build_residual  # noqa: E402
from hbm.options import CasingOptions, ContactOptions, HbmOptions  # noqa: E402
from hbm.stability import hill  # noqa: E402
from hbm.stability.monitor import StabilityOptions  # noqa: E402
from hbm.stability.spectrum import orbit_spectrum  # noqa: E402
from pipelines.artifacts import atomic_output  # noqa: E402
from rom.model import load_rom  # noqa: E402


class _Timed:
    """Wraps a callable and sums the CPU time spent in it."""

    def __init__(self, f):
        self.f, self.cpu, self.calls = f, 0.0, 0

    def __call__(self, *a, **k):
        t = time.process_time()
        try:
            return self.f(*a, **k)
        finally:
            self.cpu += time.process_time() - t
            self.calls += 1


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--rom", default=str(ROOT / "tests" / "data" / "rotor67_coarse_rom.h5"))
    ap.add_argument("--methods", nargs="+", default=["dlft", "rl"])
    ap.add_argument("--points", type=int, default=12)
    ap.add_argument("--nh", type=int, default=40)
    ap.add_argument("--nt", type=int, default=1024)
    ap.add_argument("--omega-min", type=float, default=1800.0)
    ap.add_argument("--omega-max", type=float, default=2000.0)
    ap.add_argument("--schedule", action="store_true")
    ap.add_argument("--replay", default="", help="with --schedule: reach fractions to replay, e.g. 0.5,0.25")
    ap.add_argument("--widen-check", action="store_true")
    ap.add_argument("--filter-check", action="store_true")
    ap.add_argument("--woodbury-check", action="store_true")
    ap.add_argument("--every", type=int, default=6)
    ap.add_argument("--spectra", default="",
                    help="with --replay: keep the NFRC and its spectra in SPECTRA.<method>.pkl, and read them "
                         "from there when it exists (refused for another ROM, N_h, N_t or Omega range): other "
                         "fractions replayed in seconds")
    ap.add_argument("--max-gap", default=str(StabilityOptions().max_gap),
                    help="with --replay: StabilityOptions.max_gap of the replayed schedules, e.g. 8,16")
    a = ap.parse_args()
    rom = load_rom(a.rom)
    if a.widen_check:
        return widen_check(rom, a)
    if a.filter_check:
        return filter_check(rom, a)
    if a.woodbury_check:
        return woodbury_check(rom, a)
    if a.schedule and a.replay:
        return replay(rom, a)
    if a.schedule:
        return schedule(rom, a)
    opts = HbmOptions(n_harmonics=a.nh, n_time=a.nt, omega_min=a.omega_min, omega_max=a.omega_max)
    print(f"ROM {a.rom}, N_h = {a.nh}, N_t = {a.nt}, Omega in [{a.omega_min:g}, {a.omega_max:g}] rad/s\n")
    print("| method | NFRC s / point (wall, CPU) | analysis wall (s) | analysis CPU (s) | LU | solves | rest "
          "| solves / analysis | nodes in contact | analysis / NFRC point (CPU) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for m in a.methods:
        c0 = time.process_time()
        r = compute_nfrc(rom, CasingOptions(), ContactOptions(), opts, m, stability=False)
        per_point = (r.wall_time / len(r.omega), (time.process_time() - c0) / len(r.omega))
        res = build_residual(rom, CasingOptions(), ContactOptions(), opts, method=m)
        init, call = hill.HillSolver.__init__, hill.HillSolver.__call__
        t_init, t_call = _Timed(init), _Timed(call)
        hill.HillSolver.__init__ = lambda self, *x, **k: t_init(self, *x, **k)
        hill.HillSolver.__call__ = lambda self, *x, **k: t_call(self, *x, **k)
        walls, cpus, nodes = [], [], []
        try:
            with threadpool_limits(limits=1, user_api="blas"):
                for i in np.linspace(0, len(r.omega) - 1, a.points).astype(int):
                    for _ in range(2):
                        w0, c0 = time.perf_counter(), time.process_time()
                        orbit_spectrum(res, r.unknowns[i], float(r.omega[i]), min_ceiling=1.0)
                        walls.append(time.perf_counter() - w0)
                        cpus.append(time.process_time() - c0)
                    nodes.append(len(res(r.unknowns[i], float(r.omega[i]))[1].nodes))
        finally:
            hill.HillSolver.__init__, hill.HillSolver.__call__ = init, call
        tot = sum(cpus)
        print(f"| {m} | {per_point[0]:.3f}, {per_point[1]:.3f} | {statistics.median(walls):.3f} | "
              f"{statistics.median(cpus):.3f} | {t_init.cpu / tot:.0%} | {t_call.cpu / tot:.0%} | "
              f"{1 - (t_init.cpu + t_call.cpu) / tot:.0%} | {t_call.calls / len(cpus):.0f} | "
              f"{min(nodes)}-{max(nodes)} of 9 | {statistics.median(cpus) / per_point[1]:.1f} |", flush=True)


def _missed(reference, found, tol=2.0):
    """The reference's bifurcations with no bifurcation of the same kind within tol rad/s in
    `found` (each used once): ["kind omega", ...]."""
    got = [(b.kind, b.omega) for b in found]
    used, missed = set(), []
    for b in reference:
        near = [i for i, (k, x) in enumerate(got) if k == b.kind and i not in used and abs(x - b.omega) < tol]
        if near:
            used.add(min(near, key=lambda i: abs(got[i][1] - b.omega)))
        else:
            missed.append(f"{b.kind} {b.omega:.1f}")
    return missed


def replay(rom, a):
    from types import SimpleNamespace

    from hbm.stability.monitor import StabilityMonitor, StabilityOptions

    fractions = [float(f) for f in a.replay.split(",")]
    opts = HbmOptions(n_harmonics=a.nh, n_time=a.nt, omega_min=a.omega_min, omega_max=a.omega_max)
    for m in a.methods:
        res = build_residual(rom, CasingOptions(), ContactOptions(), opts, method=m)
        cache = Path(f"{a.spectra}.{m}.pkl") if a.spectra else None
        key = (str(Path(a.rom).resolve()), a.nh, a.nt, a.omega_min, a.omega_max)  # what the spectra depend on
        if cache is not None and cache.is_file():  # an earlier run's NFRC and spectra
            with cache.open("rb") as f:
                cached, r, n, spectra, wider, per = pickle.load(f)
            if cached != key:
                raise SystemExit(f"{cache} holds the spectra of (ROM, N_h, N_t, omega_min, omega_max) = {cached}, "
                                 f"not of {key}: remove it or name another --spectra")
        else:
            r = compute_nfrc(rom, CasingOptions(), ContactOptions(), opts, m, stability=False)
            n = int(np.argmin(r.converged)) if not r.converged.all() else len(r.omega)
            c0 = time.process_time()
            with threadpool_limits(limits=1, user_api="blas"):
                spectra = [orbit_spectrum(res, r.unknowns[i], float(r.omega[i]), min_ceiling=1.0) for i in range(n)]
            per = (time.process_time() - c0) / n
            wider = {}

        def widen(x, w, k):  # the monitor's widening, each (point, n_eig) analysed once
            i = int(x[0])
            if (i, k) not in wider:
                with threadpool_limits(limits=1, user_api="blas"):
                    wider[(i, k)] = orbit_spectrum(res, r.unknowns[i], float(r.omega[i]), n_eig=k, min_ceiling=1.0)
            return wider[(i, k)]

        def monitor(options):
            mon = StabilityMonitor(analyse=lambda x, w: spectra[int(x[0])], widen=widen, options=options)
            flags = {}
            for i in range(n):
                p = SimpleNamespace(index=i, omega=float(r.omega[i]), step=float(r.step[i]), x=np.array([i]))
                done = mon.push(p, {"le_amplitude": float(r.le_amplitude[i]), "harmonics": r.harmonics[i]})
                flags.update((q.index, ex["stable"]) for q, ex in done)
            flags.update((q.index, ex["stable"]) for q, ex in mon.finish())
            return mon, flags

        ref, ref_flags = monitor(StabilityOptions(max_gap=1))
        print(f"{m}: {n} points, every point analysed: {len(ref.bifurcations)} crossings located, "
              f"{per:.3f} s CPU per analysis", flush=True)
        print("| max gap | reach fraction | analyses | ratio to 0.5 | crossings missed | points with another "
              "stable flag | analyses by cause |")
        print("|---|---|---|---|---|---|---|")
        for g in (int(v) for v in a.max_gap.split(",")):
            base = None
            for f in fractions:
                mon, flags = monitor(StabilityOptions(reach_fraction=f, max_gap=g))
                missed = _missed(ref.bifurcations, mon.bifurcations)
                wrong = sum(flags[i] != ref_flags[i] for i in ref_flags)
                base = base or (mon.n_analyses if f == 0.5 else None)
                ratio = f"{mon.n_analyses / base:.2f}" if base else "-"
                print(f"| {g} | {f:g} | {mon.n_analyses} | {ratio} | {len(missed)} of {len(ref.bifurcations)}"
                      f"{': ' + '; '.join(missed) if missed else ''} | {wrong} of {n} | "
                      f"{', '.join(f'{k} {v}' for k, v in sorted(mon.causes.items(), key=lambda kv: -kv[1]))} |",
                      flush=True)
        if cache is not None:  # with the widenings the replays asked for
            with atomic_output(cache) as tmp, open(tmp, "wb") as f:
                pickle.dump((key, r, n, spectra, wider, per), f)


def widen_check(rom, a):
    opts = HbmOptions(n_harmonics=a.nh, n_time=a.nt, omega_min=a.omega_min, omega_max=a.omega_max)
    for m in a.methods:
        r = compute_nfrc(rom, CasingOptions(), ContactOptions(), opts, m, stability=False)
        res = build_residual(rom, CasingOptions(), ContactOptions(), opts, method=m)
        n = int(np.argmin(r.converged)) if not r.converged.all() else len(r.omega)
        narrow_cpu, wide_cpu, stable, flips = 0.0, 0.0, 0, []
        with threadpool_limits(limits=1, user_api="blas"):
            for i in range(n):
                c = time.process_time()
                sp, _ = orbit_spectrum(res, r.unknowns[i], float(r.omega[i]), min_ceiling=1.0)
                narrow_cpu += time.process_time() - c
                if not sp.stable:
                    continue
                stable += 1
                c = time.process_time()
                sw, _ = orbit_spectrum(res, r.unknowns[i], float(r.omega[i]))
                wide_cpu += time.process_time() - c
                if not sw.stable:
                    j = int(np.argmax(np.abs(sw.multipliers)))
                    flips.append(f"{r.omega[i]:.1f} rad/s (ceiling e^{np.log(sp.modulus_ceiling):.2f} -> "
                                 f"e^{np.log(sw.modulus_ceiling):.2f}: {sw.n_unstable} unstable, largest |mu| "
                                 f"{abs(sw.multipliers[j]):.3g}, centred {bool(sw.centred[j])})")
        print(f"{m}: {n} points, {stable} stable with 40 eigenvalues ({narrow_cpu / n:.3f} s CPU per analysis); "
              f"widened, {wide_cpu / max(stable, 1):.3f} s per stable point; {len(flips)} become unstable:", flush=True)
        for f in flips:
            print("   ", f, flush=True)


def _cpu_per_call(f, *args, repeat=20):
    """Median CPU time of f(*args), s (process time of `repeat` calls, in 5 groups)."""
    times = []
    for _ in range(5):
        c = time.process_time()
        for _ in range(repeat // 5):
            f(*args)
        times.append((time.process_time() - c) / (repeat // 5))
    return statistics.median(times)


def woodbury_check(rom, a):
    import scipy.linalg as sla
    import scipy.sparse.linalg as spla

    from hbm.harmonic.preconditioner import ContactPreconditioner
    from hbm.stability.hill import harmonic_period, restrict

    opts = HbmOptions(n_harmonics=a.nh, n_time=a.nt, omega_min=a.omega_min, omega_max=a.omega_max)
    print("| method | Omega (rad/s) | nodes | LU: build, solve (ms) | Woodbury: build, solve, J product (ms) "
          "| refinement: error after 1, 2, 4, 8 solves | GMRES to 1e-13: iterations, ms, error |")
    print("|---|---|---|---|---|---|---|")
    for m in a.methods:
        r = compute_nfrc(rom, CasingOptions(), ContactOptions(), opts, m, stability=False)
        res = build_residual(rom, CasingOptions(), ContactOptions(), opts, method=m)
        with threadpool_limits(limits=1, user_api="blas"):
            for i in np.linspace(0, len(r.omega) - 1, a.points).astype(int):
                u, w = r.unknowns[i], float(r.omega[i])
                H = restrict(hill.HillOperator.from_residual(res, u, w), harmonic_period(res.to_coefficients(u), 1e-4))
                c = time.process_time()
                S = hill.HillSolver(H)
                t_lu = time.process_time() - c
                J = S.condensed
                c = time.process_time()
                P = ContactPreconditioner(J, single=False)
                t_p = time.process_time() - c
                b = np.random.default_rng(1).standard_normal(J.shape[0])
                ref = sla.lu_solve(S.lu, b, check_finite=False)
                t_s = _cpu_per_call(sla.lu_solve, S.lu, b)
                t_ps, t_mv = _cpu_per_call(P, b), _cpu_per_call(J.__matmul__, b)
                x, errs = P(b), []
                for k in range(1, 9):
                    if k in (1, 2, 4, 8):
                        errs.append(np.linalg.norm(x - ref) / np.linalg.norm(ref))
                    x = x + P(b - J @ x)
                its = [0]
                c = time.process_time()
                xg, info = spla.gmres(spla.LinearOperator(J.shape, matvec=J.__matmul__, dtype=float), b,
                                      M=spla.LinearOperator(J.shape, matvec=P, dtype=float), tol=1e-13, atol=0.0,
                                      restart=40, maxiter=10, callback_type="pr_norm",
                                      callback=lambda _: its.__setitem__(0, its[0] + 1))
                t_g = time.process_time() - c
                eg = np.linalg.norm(xg - ref) / np.linalg.norm(ref)
                print(f"| {m} | {w:.1f} | {len(H.nodes)} | {t_lu * 1e3:.1f}, {t_s * 1e3:.3f} | {t_p * 1e3:.1f}, "
                      f"{t_ps * 1e3:.3f}, {t_mv * 1e3:.3f} | {', '.join(f'{e:.1e}' for e in errs)} | "
                      f"{its[0]}{'' if info == 0 else ' (not converged)'}, {t_g * 1e3:.1f}, {eg:.1e} |", flush=True)


def filter_check(rom, a):
    import dataclasses

    from hbm.stability.hill import harmonic_period, restrict
    from hbm.stability.spectrum import widened_spectrum
    from hbm.ti.validation import march_from_hbm

    opts = HbmOptions(n_harmonics=a.nh, n_time=a.nt, omega_min=a.omega_min, omega_max=a.omega_max)
    casing, contact = CasingOptions(), ContactOptions()
    r = compute_nfrc(rom, casing, contact, opts, "rl", stability=False)
    res = build_residual(rom, casing, contact, opts, method="rl")
    n = int(np.argmin(r.converged)) if not r.converged.all() else len(r.omega)
    rows = []
    with threadpool_limits(limits=1, user_api="blas"):
        for i in range(0, n, a.every):
            u, w = r.unknowns[i], float(r.omega[i])
            H = hill.HillOperator.from_residual(res, u, w)
            H = restrict(H, harmonic_period(res.to_coefficients(u), 1e-4))
            f, nf = widened_spectrum(H), widened_spectrum(dataclasses.replace(H, sigma=np.ones_like(H.sigma)))
            rows.append((i, w, f.stable, nf.stable, np.log(f.largest_modulus), np.log(nf.largest_modulus)))
    diff = [x for x in rows if x[2] != x[3]]
    print(f"rl: {len(rows)} points (every {a.every}th of {n}): verdicts agree at {len(rows) - len(diff)}; "
          f"stable {sum(x[2] for x in rows)} with the filter, {sum(x[3] for x in rows)} without", flush=True)
    print("| Omega (rad/s) | with the filter: log abs mu | without | time integration, 100 periods |")
    print("|---|---|---|---|")
    for i, w, _, _, lf, lnf in diff:
        v = march_from_hbm(rom, casing, contact.mu, res.expand_harmonics(r.unknowns[i], w), w, n_periods=100)
        print(f"| {w:.1f} | {lf:+.3f} | {lnf:+.3f} | {v.verdict()} (growth {v.growth:.2f}) |", flush=True)


def schedule(rom, a):
    from collections import Counter

    from hbm.stability.monitor import StabilityOptions

    opts = HbmOptions(n_harmonics=a.nh, n_time=a.nt, omega_min=a.omega_min, omega_max=a.omega_max)
    for m in a.methods:
        runs = {}
        for name, so in (("default", StabilityOptions()), ("every point", StabilityOptions(max_gap=1))):
            c0 = time.process_time()
            r = compute_nfrc(rom, CasingOptions(), ContactOptions(), opts, m, stability=so)
            runs[name] = r
            kinds = Counter(b.kind for b in r.bifurcations)
            print(f"{m} {name}: {len(r.omega)} points, {r.n_stability_analyses} analyses, stability "
                  f"{r.stability_time:.1f} s wall, whole run {time.process_time() - c0:.1f} s CPU; "
                  + ", ".join(f"{n} {k}" for k, n in sorted(kinds.items())), flush=True)
        ref, got = runs["every point"].bifurcations, runs["default"].bifurcations
        missed = _missed(ref, got)
        found = len(ref) - len(missed)
        print(f"{m}: the default schedule located {found} of the reference's {len(ref)}, {len(got) - found} others; "
              "missed: " + ("; ".join(missed) or "none"), flush=True)


if __name__ == "__main__":
    main()
