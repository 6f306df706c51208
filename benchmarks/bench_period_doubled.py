"""The period-doubled branches of an isola search, and the sweep's omega = Omega / 2 orbits they
come from (prints markdown tables).

    PYTHONPATH=. .venv/bin/python benchmarks/bench_period_doubled.py OUT [--scene scenes/rotor67.toml]
        [--methods dlft rl]

Needs OUT/rom.h5, OUT/ti.h5 and OUT/isolas.h5 of that scene (`bladerub run SCENE --out OUT
--until isolas`). Two tables:
1. every branch of isolas.h5 in the basis of twice the scene's period (subharmonic 2 nu):
   kind, Omega span, points, LE amplitude range, and the share of the LE radial harmonic
   energy at odd multiples of the basis' fundamental (the Omega / 2 content: 0 for an orbit
   of period 2 pi / Omega), median and smallest;
2. every sweep point whose orbit is twice the scene's period: Newton at its Omega (damped,
   the validation stage's) from the harmonics of its last two revolutions (the isola
   search's seed, hbm.isolas.harmonic.ti_seeds), in the basis of Omega / 2 with 2 N_h
   harmonics; distance moved in the unknowns, Omega / 2 share of the seed and of the
   solution, LE amplitude against time integration's, and Hill's largest multiplier modulus;
3. every such branch's point of least Omega / 2 share: Newton in the basis of Omega from its
   even harmonics (the orbit it is closest to without the new harmonics), how far that moved,
   and the branch of the scene's basis it lies on by the search's own membership test
   (hbm.isolas.search.lies_on: polyline distance, then Newton from the nearest point), i.e.
   the branch whose period doubling the doubled branch passes through.
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


def main() -> None:
    from hbm.continuation.newton import NewtonOptions
    from hbm.harmonic.residual import build_residual
    from hbm.harmonic.solver import HbmSolver
    from hbm.harmonic.start import damped_newton
    from hbm.isolas.harmonic import coarsened, doubled_options, new_share, search_options, ti_seeds
    from hbm.isolas.membership import KnownBranch
    from hbm.isolas.search import lies_on
    from pipelines.branch_store import load_branch
    from hbm.stability.spectrum import orbit_spectrum
    from pipelines.scene import load_scene
    from pipelines.stages.isolas import read_isolas
    from pipelines.stages.ti import read_sweep
    from rom.model import load_rom

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--scene", default="scenes/rotor67.toml")
    ap.add_argument("--methods", nargs="+", default=["dlft", "rl"])
    a = ap.parse_args()
    scene = load_scene(a.scene)
    hbm = scene.hbm
    found = read_isolas(a.out / "isolas.h5")
    print("| treatment | branch | kind | Omega (rad/s) | points | LE amplitude (mm) | Omega/2 share: median | min |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for m in a.methods:
        for b in found.get(m, []):
            if b.subharmonic != 2 * hbm.subharmonic:
                continue
            ok = b.converged
            share = new_share(b.harmonics[ok])  # LE radial
            amp = 1e3 * b.le_amplitude[ok]
            print(f"| {m} | {b.name} | {b.kind}{' (closed)' if b.closed else ''} | {b.omega[ok].min():.0f}-"
                  f"{b.omega[ok].max():.0f} | {int(ok.sum())} | {amp.min():.2f}-{amp.max():.2f} | "
                  f"{np.median(share):.2f} | {share.min():.2f} |", flush=True)
    rom = load_rom(a.out / "rom.h5")
    sweep = read_sweep(a.out)
    lo, hi = hbm.omega_min, hbm.omega_max
    print()
    print("| treatment | Omega (rad/s) | Newton | iterations | moved | Omega/2 share, seed / solution | "
          "LE amplitude HBM / TI - 1 | largest abs mu (unstable) | CPU s |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for m in a.methods:
        res = build_residual(rom, scene.casing, scene.contact, doubled_options(hbm), method=m)
        for sd in ti_seeds(res, sweep, (lo, hi), scene.casing.n_lobes, only_new_to=hbm.subharmonic):
            i = int(np.argmin(np.abs(sweep.omega - sd.omega)))
            t = time.process_time()
            sol = damped_newton(res, sd.x, sd.omega, NewtonOptions(tol_residual=hbm.tolerance),
                                HbmSolver(atol=0.1 * hbm.tolerance))
            s0 = new_share(res.to_coefficients(sd.x)[None])[0]
            if not sol.converged:
                print(f"| {m} | {sd.omega:.0f} | no ({sol.reason[:40]}) | {sol.iterations} | - | {s0:.2f} / - | - | "
                      f"- | {time.process_time() - t:.1f} |", flush=True)
                continue
            sp, _ = orbit_spectrum(res, sol.x, sd.omega)
            le = res.signals(sol.x, sd.omega)["displacement"][:, 0]
            moved = np.linalg.norm(sol.x - sd.x) / np.linalg.norm(sd.x)
            s1 = new_share(res.to_coefficients(sol.x)[None])[0]
            ratio = 0.5 * np.ptp(le) / sweep.amplitude[i] - 1
            print(f"| {m} | {sd.omega:.0f} | yes | {sol.iterations} | {moved:.3f} | {s0:.2f} / {s1:.2f} | {ratio:+.3f} | "
                  f"{sp.largest_modulus:.3f} ({sp.n_unstable}) | {time.process_time() - t:.1f} |", flush=True)

    print()
    print("| treatment | branch | Omega (rad/s) | Omega/2 share | Newton in the basis of Omega | moved | lies on |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    opts = search_options(hbm, scene.isolas)
    for m in a.methods:
        res = build_residual(rom, scene.casing, scene.contact, hbm, method=m)
        pd_res = build_residual(rom, scene.casing, scene.contact, doubled_options(hbm), method=m)
        b0 = load_branch(a.out / f"nfrc_{m}.h5").branch
        known = [KnownBranch.of(b0.omega, b0.x, "the primary", b0.converged)] + [
            KnownBranch.of(b.omega, b.x, f"branch {b.name}", b.converged)
            for b in found.get(m, []) if b.subharmonic == hbm.subharmonic]
        for b in found.get(m, []):
            if b.subharmonic != 2 * hbm.subharmonic:
                continue
            ok = b.converged
            share = new_share(b.harmonics[ok])
            i = int(np.argmin(share))
            w = float(b.omega[ok][i])
            u = coarsened(pd_res, res, b.x[ok][i])  # its even harmonics of Omega / 2: those of Omega
            solver = HbmSolver(atol=0.1 * hbm.tolerance)
            sol = damped_newton(res, u, w, NewtonOptions(tol_residual=hbm.tolerance), solver)
            if not sol.converged:
                print(f"| {m} | {b.name} | {w:.1f} | {share[i]:.3f} | no | - | - |", flush=True)
                continue
            k = lies_on(res, sol.x, w, known, opts, solver)
            moved = np.linalg.norm(sol.x - u) / np.linalg.norm(u)
            print(f"| {m} | {b.name} | {w:.1f} | {share[i]:.3f} | yes | {moved:.3f} | "
                  f"{known[k].label if k >= 0 else 'none'} |", flush=True)


if __name__ == "__main__":
    main()
