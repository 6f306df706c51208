"""Bifurcations located between stored points against refined ones: speed against error.

    OPENBLAS_NUM_THREADS=1 PYTHONPATH=. .venv/bin/python benchmarks/bench_refinement.py OUT \
        [--scene scenes/rotor67_coarse.toml] [--methods dlft rl] [--steps 0 2 4 8] [--reference 24]
    ... bench_refinement.py OUT --scene SCENE --methods dlft --along OMEGA [--n-time 1024 4096] [--same-orbits]
    ... bench_refinement.py OUT --scene SCENE --methods dlft --monitor-n-time 1024 4096
    ... bench_refinement.py OUT --scene SCENE --methods dlft rl --every-point-n-time 1024 4096 [--every K]
    ... bench_refinement.py OUT --scene SCENE --methods rl --at 1422.65,1619.9 [--n-time 1024 2048 4096 8192]

OUT: a run's folder with rom.h5 and nfrc_METHOD.h5 (computed with or without stability).
The stability monitor runs over the NFRC's converged points as the isola search runs it
over its branches (hbm.isolas.harmonic.describe, the NFRC's arc-length scales): once per
--steps value (StabilityOptions.refine_steps, refine_rtol 1e-5, the scene's
[hbm] refine_bifurcations) and once as the reference (--reference steps, refine_rtol
1e-8). The monitor's schedule does not depend on the refinement, so every run locates the
same bifurcations, matched in order. Prints, per run: CPU time, analyses, and per kind the
median and largest |Omega - Omega_reference| (rad/s) of the crossings that were refined in
the reference (folds are located by their parabola, not refined), with the median bracket
between stored points for scale.

--along OMEGA: instead, the period-doubling multiplier (the real negative one of largest
modulus) at 11 points solved on the branch between the stored point nearest OMEGA and the
next one (hbm.stability.refinement.solve_between), for each --n-time (the AFT's instants;
the stored points are the scene's): whether it crosses -1 once between two points. With
--same-orbits the points are solved once, at the scene's N_t, and only Hill's operator is
built on each N_t's instants (the orbit's sampling against the Jacobian's).

--monitor-n-time N ...: the monitor over the NFRC's stored points (as above, no refinement)
with Hill's operator built on N instants: CPU time, points analysed and stable, and the
bifurcations by kind.

--every-point-n-time N1 N2: every K-th converged stored point (--every, default 1) analysed
with Hill's operator on N1 and on N2 instants (the same orbits, solved at the scene's N_t):
how many points get another stable flag or another count of unstable multipliers, and how
far the largest log|mu| moves (median, 95th percentile, largest), then each point whose flag
differs with its Omega and both largest log|mu|.

--at OMEGA,...: the stored point nearest each OMEGA analysed with Hill's operator on each
--n-time's instants: the count of unstable multipliers and the three of largest modulus.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import hbm  # noqa: F401  (before numpy: OpenBLAS's kernels for the host, hbm.openblas)
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def _run(res, scales, omega, x, steps: int, rtol: float):
    from hbm.isolas.harmonic import describe
    from hbm.stability.monitor import StabilityOptions

    c0 = time.process_time()
    d = describe(res, True, scales, StabilityOptions(refine_steps=steps, refine_rtol=rtol))(omega, x)
    cpu = time.process_time() - c0
    t = {k: np.asarray(v) for k, (v, _) in d["tables"]["bifurcations"].items()}
    return cpu, int(d["stability_analysed"].sum()), t


def _residual_on(scene, rom, method: str, n_time: int):
    """The scene's residual of `method` with the AFT on n_time instants."""
    import dataclasses

    from hbm.harmonic.residual import build_residual

    return build_residual(rom, scene.casing, scene.contact, dataclasses.replace(scene.hbm, n_time=n_time),
                          method=method)


def _monitor_n_time(out: Path, scene, rom, method: str, n_times) -> None:
    from collections import Counter

    from hbm.harmonic.nfrc import default_continuation
    from pipelines.branch_store import load_branch

    s = load_branch(out / f"nfrc_{method}.h5")
    ok = np.flatnonzero(s.branch.converged)
    co = default_continuation(scene.hbm)
    for nt in n_times:
        res = _residual_on(scene, rom, method, nt)
        cpu, n_an, t = _run(res, (co.x_scale, co.omega_scale), s.branch.omega[ok], s.branch.x[ok], 0, 1e-5)
        kinds = dict(sorted(Counter(str(k) for k in t["kind"]).items()))
        print(f"{method}, Hill's operator on N_t = {nt}: {cpu:.1f} s CPU, {n_an} of {len(ok)} points analysed, "
              f"bifurcations {kinds}", flush=True)


def _largest_log_modulus(sp) -> float:
    """log|mu| of the multiplier of largest modulus (nan without one)."""
    return float(np.log(np.abs(sp.multipliers)).max()) if len(sp.multipliers) else float("nan")


def _every_point_n_time(out: Path, scene, rom, method: str, n_times, every: int) -> None:
    from hbm.stability.spectrum import orbit_spectrum
    from pipelines.branch_store import load_branch

    s = load_branch(out / f"nfrc_{method}.h5")
    ok = np.flatnonzero(s.branch.converged)[::every]
    verdicts = []
    for nt in n_times:
        res = _residual_on(scene, rom, method, nt)
        c0 = time.process_time()
        rows = []
        for i in ok:
            sp, _ = orbit_spectrum(res, s.branch.x[i], float(s.branch.omega[i]), n_eig=40, min_ceiling=1.0)
            rows.append((sp.decided and sp.n_unstable == 0, sp.n_unstable if sp.decided else -1,
                         _largest_log_modulus(sp)))
        verdicts.append(rows)
        print(f"{method}, N_t = {nt}: {len(ok)} points, {time.process_time() - c0:.1f} s CPU, "
              f"{sum(r[0] for r in rows)} stable, {sum(r[1] < 0 for r in rows)} without a verdict", flush=True)
    (a, b) = verdicts[0], verdicts[-1]
    flag = [k for k in range(len(ok)) if a[k][0] != b[k][0]]
    count = [k for k in range(len(ok)) if a[k][1] != b[k][1]]
    d = np.abs([a[k][2] - b[k][2] for k in range(len(ok))])
    d = d[np.isfinite(d)]
    print(f"{method}: N_t = {n_times[0]} against {n_times[-1]}: stable flag differs at {len(flag)} of {len(ok)} "
          f"points, unstable count at {len(count)}; largest log|mu| moves by median {np.median(d):.2e}, "
          f"95th percentile {np.percentile(d, 95):.2e}, largest {d.max():.2e}", flush=True)
    for k in flag:
        print(f"  {float(s.branch.omega[ok[k]]):.2f} rad/s: largest log|mu| {a[k][2]:+.4f} ({n_times[0]}), "
              f"{b[k][2]:+.4f} ({n_times[-1]}); unstable {a[k][1]} and {b[k][1]}", flush=True)


def _at(out: Path, scene, rom, method: str, omegas, n_times) -> None:
    from hbm.stability.spectrum import orbit_spectrum
    from pipelines.branch_store import load_branch

    s = load_branch(out / f"nfrc_{method}.h5")
    ops = {nt: _residual_on(scene, rom, method, nt) for nt in n_times}
    for w in omegas:
        i = int(np.argmin(np.where(s.branch.converged, np.abs(s.branch.omega - w), np.inf)))
        row = []
        for nt, res in ops.items():
            sp, _ = orbit_spectrum(res, s.branch.x[i], float(s.branch.omega[i]), n_eig=40, min_ceiling=1.0)
            mu = sp.multipliers[np.argsort(-np.abs(sp.multipliers))][:3]
            row.append(f"N_t {nt}: {sp.n_unstable} unstable, |mu| " + " ".join(f"{abs(m):.4f}" for m in mu))
        print(f"{method} {float(s.branch.omega[i]):.2f} rad/s: " + "; ".join(row), flush=True)


def _along(out: Path, scene, rom, method: str, omega: float, n_times, same_orbits: bool = False) -> None:
    from hbm.harmonic.nfrc import default_continuation
    from hbm.harmonic.residual import build_residual
    from hbm.harmonic.solver import HbmSolver
    from hbm.stability.refinement import solve_between
    from hbm.stability.spectrum import orbit_spectrum
    from pipelines.branch_store import load_branch

    s = load_branch(out / f"nfrc_{method}.h5")
    om, xs = s.branch.omega, s.branch.x
    ia = int(np.argmin(np.where(s.branch.converged, np.abs(om - omega), np.inf)))
    nopt = default_continuation(scene.hbm).newton
    print(f"{method}: points {ia} and {ia + 1} ({om[ia]:.2f}, {om[ia + 1]:.2f} rad/s)", flush=True)
    scene_res = build_residual(rom, scene.casing, scene.contact, scene.hbm, method=method)
    for nt in n_times:
        res = _residual_on(scene, rom, method, nt)
        solver = HbmSolver(atol=0.1 * nopt.tol_residual)
        row = []
        for f in np.linspace(0.0, 1.0, 11):
            got = solve_between(scene_res if same_orbits else res, xs[ia], om[ia], xs[ia + 1], om[ia + 1], f, nopt,
                                solver)
            if isinstance(got, str):
                row.append(f"f = {f:.1f}: {got}")
                continue
            sp, _ = orbit_spectrum(res, got[0], got[1], n_eig=40, min_ceiling=1.0)
            mu = sp.multipliers[(sp.multipliers.real < 0) & (np.abs(np.angle(sp.multipliers)) > np.pi - 0.05)]
            row.append(f"{got[1]:.2f}: {-np.abs(mu).max() if len(mu) else np.nan:.4f}")
        print(f"  N_t = {nt}{' (Hill only)' if same_orbits else ''}: " + ", ".join(row), flush=True)


def main() -> None:
    from hbm.harmonic.nfrc import default_continuation
    from hbm.harmonic.residual import build_residual
    from pipelines.branch_store import load_branch
    from pipelines.scene import load_scene
    from pipelines.stages.rom import read_rom

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out", type=Path)
    ap.add_argument("--scene", type=Path, default=ROOT / "scenes" / "rotor67_coarse.toml")
    ap.add_argument("--methods", nargs="+", default=["dlft", "rl"])
    ap.add_argument("--steps", type=int, nargs="+", default=[0, 2, 4, 8])
    ap.add_argument("--reference", type=int, default=24)
    ap.add_argument("--along", type=float, metavar="OMEGA")
    ap.add_argument("--n-time", type=int, nargs="+", default=[1024, 4096])
    ap.add_argument("--same-orbits", action="store_true")
    ap.add_argument("--monitor-n-time", type=int, nargs="+", metavar="N")
    ap.add_argument("--every-point-n-time", type=int, nargs=2, metavar="N")
    ap.add_argument("--every", type=int, default=1)
    ap.add_argument("--at", type=lambda v: [float(w) for w in v.split(",")], metavar="OMEGA,...")
    a = ap.parse_args()
    scene = load_scene(a.scene)
    rom = read_rom(a.out)
    co = default_continuation(scene.hbm)
    if a.along is not None:
        for method in a.methods:
            _along(a.out, scene, rom, method, a.along, a.n_time, a.same_orbits)
        return
    if a.at:
        for method in a.methods:
            _at(a.out, scene, rom, method, a.at, a.n_time)
        return
    if a.every_point_n_time:
        for method in a.methods:
            _every_point_n_time(a.out, scene, rom, method, a.every_point_n_time, a.every)
        return
    if a.monitor_n_time:
        for method in a.methods:
            _monitor_n_time(a.out, scene, rom, method, a.monitor_n_time)
        return
    for method in a.methods:
        s = load_branch(a.out / f"nfrc_{method}.h5")
        ok = np.flatnonzero(s.branch.converged)
        omega, x = s.branch.omega[ok], s.branch.x[ok]
        res = build_residual(rom, scene.casing, scene.contact, scene.hbm, method=method)
        scales = (co.x_scale, co.omega_scale)
        cpu_r, _, ref = _run(res, scales, omega, x, a.reference, 1e-8)
        refined = ref["refine_steps"] > 0
        width = np.abs(ref["omega_high"] - ref["omega_low"])
        print(f"{method} NFRC, {len(ok)} points: {len(ref['kind'])} bifurcations, {int(refined.sum())} refined in "
              f"the reference ({cpu_r:.1f} s CPU; notes: "
              f"{sorted(set(str(n) for n in ref['refine_note'] if str(n))) or 'none'}); "
              f"stored-point brackets of those: median {np.median(width[refined]):.3g} rad/s, "
              f"largest {width[refined].max():.3g}", flush=True)
        for steps in a.steps:
            cpu, n_an, t = _run(res, scales, omega, x, steps, 1e-5)
            if len(t["kind"]) != len(ref["kind"]) or np.any(t["index"] != ref["index"]):
                print(f"  steps {steps}: other bifurcations than the reference's ({len(t['kind'])})", flush=True)
                continue
            err = np.abs(t["omega"] - ref["omega"])
            parts = []
            for kind in sorted(set(str(k) for k in ref["kind"][refined])):
                sel = refined & (ref["kind"].astype(str) == kind)
                parts.append(f"{kind} ({int(sel.sum())}): median {np.median(err[sel]):.2g}, largest "
                             f"{err[sel].max():.2g}")
            print(f"  steps {steps}: {cpu:.1f} s CPU, {n_an} points analysed, refinement solves "
                  f"{int(t['refine_steps'].sum())}, |Omega - reference| rad/s: " + "; ".join(parts), flush=True)


if __name__ == "__main__":
    main()
