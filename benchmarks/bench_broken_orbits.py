"""The symmetry-broken orbits an AFT grid that is not a multiple of the lobes led the NFRC to:
are they solutions on a grid that is, and are they the blade's?

    OPENBLAS_NUM_THREADS=1 PYTHONPATH=. .venv/bin/python benchmarks/bench_broken_orbits.py
        --rom out/r37/rom.h5 --scene scenes/rotor37.toml [--method rl] [--bad-grid 1024]
        [--omega 671 686] [--checks 4] [--marches 4]

1. The NFRC of `--method` on `--bad-grid` samples (the scene refuses such a grid: built
   through hbm.harmonic.nfrc.compute_nfrc), and its points in `--omega` whose energy outside
   the harmonics k n_l of Omega exceeds 5 % (the broken share).
2. Each Newton-corrected at its Omega on the scene's grid (iterations, the share kept).
3. One of them (the largest share) continued with the isola search's settings against the
   scene's primary NFRC (computed here on the scene's grid): its kind, whether it closes, its
   Omega range, its status, the smallest broken share along it and where; then, from the
   least broken of its points that are not symmetric, steps of at most 0.1 each way: how
   close the broken orbits come to the symmetric ones (a branch point of the primary has the
   share fall to zero there), and the primary's multipliers near the argument 2 pi / n_l at
   its points within 0.5 rad/s of there.
4. Along that branch: Hill's verdict every 12th point; `--checks` points solved again with
   2 N_h (hbm.stability.convergence.check_harmonics) and with the other contact law at N_h;
   `--marches` points marched 100 periods with the validation stage's Carpenter step
   (hbm.ti.validation.march_from_hbm): the first period's deviation, where the march ends
   (broken share of its last period, its period ratio).
Prints one line per step; the README's *Rotor 37* holds a run (about 5.5 min on one core).
With --from-branch FILE:GROUP only the closest approach, from a branch of an isolas.h5 (and,
with --along, step 4 along that branch).
"""
from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

import hbm  # noqa: F401  (before numpy: OpenBLAS's kernels for the host, hbm.openblas)
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def coefficient_share(xr: np.ndarray, period: int) -> float:
    """Share of the energy (sum of squared coefficients) of harmonics xr ((2 N + 1, n), eq. (5)
    order) in the harmonics that are not multiples of `period`, -."""
    k = np.r_[0, np.repeat(np.arange(1, (len(xr) - 1) // 2 + 1), 2)]
    return float(np.sum(xr[k % period != 0] ** 2) / np.sum(xr ** 2))


def broken_share(res, u: np.ndarray) -> float:
    """Share of the energy of the orbit u (the residual's unknowns) outside the harmonics of
    the casing's lobes, -: the square of the search's asymmetry (the part outside the mean
    over the casing's images, relative), which coefficient_share gives for a signal's
    harmonics."""
    from hbm.isolas.search import asymmetry

    return asymmetry(res, u) ** 2


def closest_approach(res, solver, x0: np.ndarray, w0: float, options, n_points: int = 80):
    """From the orbit x0 at w0 (rad/s), continuation with steps of at most 0.1 (options: the
    search's ContinuationOptions otherwise), n_points each way -> (Omega (m,), broken share
    (m,), the Omegas where Omega turns (folds)); the least broken point is where the branch
    comes closest to the symmetric orbits (a branch point has the share fall to zero)."""
    from dataclasses import replace

    from hbm.continuation.arclength import continue_branch

    w, sh, folds = [], [], []
    for d in (1, -1):
        pts = []
        co = replace(options, ds=0.025, ds_max=0.1, max_points=n_points, direction=d)
        continue_branch(res, x0, w0, co, solver=solver,
                        on_point=lambda p: pts.append((p.omega, broken_share(res, p.x))) if p.converged else None)
        om = np.array([p[0] for p in pts])
        turn = np.flatnonzero(np.diff(np.sign(np.diff(om))) != 0) + 1
        folds += [float(om[t]) for t in turn]
        w += [p[0] for p in pts]
        sh += [p[1] for p in pts]
    return np.array(w), np.array(sh), sorted({round(f, 2) for f in folds})  # a fold once, however often met


def along_branch(res, om, xs, sh, scene, rom, a, label: str = "4. along it") -> None:
    """Step 4 on a branch's points (Omega (m,) rad/s, orbits (m, n), broken shares (m,)): Hill's
    verdict every 12th point, then a.checks of the broken ones (the stable first) solved again
    with 2 N_h and with the other contact law, and a.marches of them marched 100 periods."""
    from hbm.continuation.newton import NewtonOptions, newton_solve
    from hbm.harmonic.residual import build_residual
    from hbm.stability.convergence import check_harmonics
    from hbm.stability.spectrum import orbit_spectrum
    from hbm.ti.march import rom_modal_system
    from hbm.ti.validation import confirm_orbit, march_from_hbm

    other = build_residual(rom, scene.casing, scene.contact, scene.hbm, method="dlft" if a.method == "rl" else "rl")
    fine = res.refined(2)
    system = rom_modal_system(rom)
    print(f"{label}:", flush=True)
    verdicts = {}
    for i in range(0, len(om), 12):
        spec, g = orbit_spectrum(res, xs[i], float(om[i]), min_ceiling=1.0)
        verdicts[i] = spec.stable
        print(f"   {om[i]:.3f} rad/s, share {sh[i]:.3f}: stable {spec.stable}, largest |mu| "
              f"{spec.largest_modulus:.3f} (period T/{g})", flush=True)
    broken = [i for i in verdicts if sh[i] > 0.05]
    chosen = sorted(broken, key=lambda i: (not verdicts[i], -sh[i]))
    for i in chosen[: a.checks]:
        c = check_harmonics(res, xs[i], float(om[i]), fine=fine)
        s2 = broken_share(fine, c.u) if len(c.u) else float("nan")
        o = newton_solve(other, other.to_unknowns(res.to_coefficients(xs[i])), float(om[i]), NewtonOptions(max_iter=60))
        so = broken_share(other, o.x) if o.converged else float("nan")
        print(f"   {om[i]:.3f} rad/s (stable {verdicts[i]}): 2 N_h: {c.reason}, its share {s2:.2e}; "
              f"{other.method} at N_h: converged {o.converged}, share {so:.2e}", flush=True)
    for i in chosen[: a.marches]:
        ti = march_from_hbm(system, scene.casing, scene.contact.mu, res.expand_harmonics(xs[i], float(om[i])),
                            float(om[i]), n_periods=100, dt=scene.validation.dt, record_all=True)
        ti = confirm_orbit(res, ti, xs[i], float(om[i]))
        r = ti.reached
        last = coefficient_share(ti.last_harmonics, res.nu * int(res.casing.n_lobes))
        print(f"   {om[i]:.3f} rad/s (stable {verdicts[i]}): time integration stays {ti.stays}, first period's "
              f"deviation (LE, TE) {np.round(ti.deviation[0], 3)}, last period's broken share {last:.3f}; Newton "
              f"from it: converged {r.converged}, period T/{r.period_ratio} (the orbit's T/{r.orbit_period_ratio}), "
              f"{r.solution_distance:.3f} from the orbit", flush=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rom", type=Path, required=True)
    ap.add_argument("--scene", type=Path, required=True)
    ap.add_argument("--method", default="rl", choices=["dlft", "rl"])
    ap.add_argument("--bad-grid", type=int, default=1024)
    ap.add_argument("--omega", type=float, nargs=2, default=[671.0, 686.0])
    ap.add_argument("--checks", type=int, default=4)
    ap.add_argument("--marches", type=int, default=4)
    ap.add_argument("--from-branch", metavar="FILE:GROUP",
                    help="only the closest approach, from a branch of an isolas.h5 (e.g. out/r37/isolas.h5:dlft/000): "
                         "from its least broken point that is not symmetric")
    ap.add_argument("--along", action="store_true",
                    help="with --from-branch: also step 4 along that branch (Hill's verdicts, --checks, --marches)")
    a = ap.parse_args(argv)

    from hbm.continuation.newton import NewtonOptions, newton_solve
    from hbm.harmonic.nfrc import compute_nfrc
    from hbm.harmonic.residual import build_residual
    from hbm.isolas.harmonic import HbmProblem, search_options
    from hbm.isolas.membership import KnownBranch
    from hbm.isolas.search import Seed, search
    from hbm.stability.spectrum import orbit_spectrum
    from pipelines.scene import load_scene
    from rom.model import load_rom

    scene, rom = load_scene(a.scene), load_rom(a.rom)
    if a.from_branch:
        import h5py

        path, group = a.from_branch.split(":")
        res, solver = HbmProblem(rom, scene.casing, scene.contact, scene.hbm, a.method)()
        with h5py.File(path, "r") as h5:
            b = h5[f"{group.split('/')[0]}/branches/{group.split('/')[1]}"]
            ok = b["converged"][()].astype(bool)
            om, xs = b["omega"][()][ok], b["x"][()][ok]
        sh = np.array([broken_share(res, u) for u in xs])
        m = int(np.argmin(np.where(sh > 1e-12, sh, np.inf)))
        w_f, s_f, folds = closest_approach(res, solver, xs[m], float(om[m]), search_options(scene.hbm, scene.isolas)
                                           .continuation, n_points=200)
        k = int(np.argmin(s_f))
        print(f"{a.from_branch}: {len(om)} points, {(sh < 1e-12).sum()} on symmetric orbits; from {om[m]:.3f} rad/s "
              f"(share {sh[m]:.2e}), steps of at most 0.1, {len(s_f)} points: share down to {s_f[k]:.2e} (its square "
              f"root {np.sqrt(s_f[k]):.2e}) at {w_f[k]:.3f} rad/s, {(s_f < 1e-12).sum()} points on symmetric orbits, "
              f"Omega turns at {', '.join(f'{f:.2f}' for f in folds) or 'none'} rad/s")
        if a.along:
            along_branch(res, om, xs, sh, scene, rom, a, label=f"along {a.from_branch}")
        return 0
    lo, hi = a.omega
    bad_opts = replace(scene.hbm, n_time=a.bad_grid)
    t = time.process_time()
    bad = compute_nfrc(rom, scene.casing, scene.contact, bad_opts, a.method)
    bad_res = build_residual(rom, scene.casing, scene.contact, bad_opts, method=a.method)
    shares = np.array([broken_share(bad_res, u) for u in bad.unknowns])
    pick = np.flatnonzero((bad.omega > lo) & (bad.omega < hi) & (shares > 0.05) & bad.converged)
    print(f"1. {a.method} NFRC on {a.bad_grid} samples: {len(bad.omega)} points, {bad.status}, "
          f"{len(pick)} in {lo:g}-{hi:g} rad/s with a broken share over 5 % (max {shares.max():.3f}); "
          f"CPU {time.process_time() - t:.0f} s", flush=True)
    if not len(pick):
        return 0

    res = build_residual(rom, scene.casing, scene.contact, scene.hbm, method=a.method)
    print(f"2. Newton on the scene's {res.basis.n_time} samples:", flush=True)
    start = None
    for i in pick[:: max(1, len(pick) // 8)]:
        sol = newton_solve(res, res.to_unknowns(bad_res.to_coefficients(bad.unknowns[i])), float(bad.omega[i]),
                           NewtonOptions(max_iter=40))
        s = broken_share(res, sol.x) if sol.converged else float("nan")
        print(f"   {bad.omega[i]:.3f} rad/s, share {shares[i]:.3f}: converged {sol.converged} in {sol.iterations}, "
              f"share {s:.3f}", flush=True)
        if sol.converged and (start is None or s > start[2]):
            start = (sol.x, float(bad.omega[i]), s)
    if start is None:
        return 0

    t = time.process_time()
    primary = compute_nfrc(rom, scene.casing, scene.contact, scene.hbm, a.method)
    known = [KnownBranch.of(primary.omega, primary.unknowns, f"primary {a.method.upper()} NFRC", primary.converged)]
    problem = HbmProblem(rom, scene.casing, scene.contact, scene.hbm, a.method)
    opts = search_options(scene.hbm, scene.isolas)
    found = search(problem, [Seed(start[1], start[0], "broken orbit", of_model=True)], known, opts,
                   seed_factory=problem.for_seeds())
    if not found.branches:
        print(f"3. the broken orbit at {start[1]:.3f} rad/s lies on no new branch (seed {found.seed_branch[0]})")
        return 0
    fb = found.branches[0]
    om, xs = fb.omega[fb.converged], fb.x[fb.converged]
    sh = np.array([broken_share(res, u) for u in xs])
    j = int(np.argmin(sh))
    print(f"3. continued from {start[1]:.3f} rad/s: {fb.kind}, closed {fb.closed}, {len(om)} points, "
          f"{om.min():.2f}-{om.max():.2f} rad/s; broken share {sh.min():.2e} (its square root "
          f"{np.sqrt(sh.min()):.2e}) at {om[j]:.3f} rad/s, up to {sh.max():.3f}; CPU {time.process_time() - t:.0f} s "
          f"with the primary; status: {fb.status}", flush=True)
    # the closest approach to the symmetric orbits, with short steps from the least broken of
    # the search's points not on them (its corrector may have landed on the primary)
    m = int(np.argmin(np.where(sh > 1e-12, sh, np.inf)))
    w_f, s_f, _ = closest_approach(res, problem()[1], xs[m], float(om[m]), opts.continuation)
    k = int(np.argmin(s_f))
    print(f"   with steps of at most 0.1 from {om[m]:.3f} rad/s ({len(s_f)} points): broken share down to {s_f[k]:.2e} "
          f"(its square root {np.sqrt(s_f[k]):.2e}) at {w_f[k]:.3f} rad/s, {(s_f < 1e-12).sum()} points on symmetric "
          "orbits", flush=True)
    # a branch point of T-periodic orbits on the primary (T / n_l periodic) needs a multiplier
    # of its minimal period on the unit circle at the argument 2 pi / n_l
    arg = 360.0 / int(scene.casing.n_lobes)
    near = np.flatnonzero(primary.converged & (np.abs(primary.omega - w_f[k]) < 0.5))
    for q in near:
        spec, g = orbit_spectrum(res, primary.unknowns[q], float(primary.omega[q]), min_ceiling=1.0)
        mu = spec.multipliers[(np.abs(np.degrees(np.angle(spec.multipliers)) - arg) < 30.0)
                              & (np.abs(np.log(np.abs(spec.multipliers))) < 0.3)]
        print(f"   primary at {primary.omega[q]:.3f} rad/s (period T/{g}): multipliers within 30 deg of {arg:.0f} deg: "
              + (", ".join(f"|mu| {abs(z):.3f} at {np.degrees(np.angle(z)):.1f} deg" for z in mu) or "none"),
              flush=True)
    along_branch(res, om, xs, sh, scene, rom, a)
    return 0


if __name__ == "__main__":
    sys.exit(main())
