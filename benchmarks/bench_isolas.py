"""Benchmark of the isola search (hbm.isolas) on the coarse rotor 67 ROM.

Usage:
  PYTHONPATH=. .venv/bin/python benchmarks/bench_isolas.py [--rom tests/data/rotor67_coarse_rom.h5]
      [--methods dlft rl] [--ti out/coarse/ti.h5] [--nh 40] [--n-omega 41] [--amplitudes ...]
      [--harmonics ...] [--primary-amplitudes [...]] [--n-modes 4] [--workers N] [--max-points 600]
      [--save branches.npz] [--stage-describe]

The scene defaults ([hbm] N_h = 40, N_t = 1024, Omega in [400, 2000] rad/s; [isolas]
defaults) unless told otherwise. For each treatment: the primary NFRC (compute_nfrc, timed
apart), then the search from the modal seeds (RL: DLFT's corrected ones when both run, as
the stage does; the modal seeds include those around the primary NFRC unless
--primary-amplitudes is given without a value), and the periodic points of a ti.h5 when
--ti names one. Prints per treatment: seeds, converged, distinct, branches per class with
their Omega range, closed, dominant harmonic, and the search's CPU and wall time;
--save writes the branches to an .npz (keys METHOD_K_omega, _x, _converged, _le_amplitude).
--stage-describe: each branch described as the isolas stage does ([isolas] harmonic_checks
points solved again with 2 N_h, modal and harmonic contributions), not only its LE
amplitude and harmonics.
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


def main():
    from dataclasses import replace

    from hbm.harmonic.nfrc import compute_nfrc
    from hbm.isolas.harmonic import (BranchDescriber, HbmProblem, dominant_harmonic, modal_seeds, rl_seeds,
                                     search_options, ti_seeds)
    from hbm.isolas.membership import KnownBranch
    from hbm.isolas.options import IsolaOptions
    from hbm.isolas.search import search
    from hbm.options import CasingOptions, ContactOptions, HbmOptions
    from rom.model import load_rom

    ap = argparse.ArgumentParser()
    ap.add_argument("--rom", default=str(ROOT / "tests/data/rotor67_coarse_rom.h5"))
    ap.add_argument("--methods", nargs="+", default=["dlft", "rl"])
    ap.add_argument("--ti")
    ap.add_argument("--nh", type=int, default=40)
    ap.add_argument("--n-omega", type=int)
    ap.add_argument("--n-modes", type=int)
    ap.add_argument("--harmonics", type=int, nargs="+")
    ap.add_argument("--amplitudes", type=float, nargs="+")
    ap.add_argument("--primary-amplitudes", type=float, nargs="*",
                    help="the seeds around the primary ([isolas] primary_amplitudes); no value: none")
    ap.add_argument("--workers", type=int)
    ap.add_argument("--rl-branch-seeds", type=int, help="[isolas] rl_branch_seeds")
    ap.add_argument("--max-points", type=int)
    ap.add_argument("--save", help="write each treatment's branches (omega, x, converged, le_amplitude) to this .npz")
    ap.add_argument("--stage-describe", action="store_true", help="describe the branches as the isolas stage does")
    a = ap.parse_args()
    rom = load_rom(a.rom)
    hbm = HbmOptions(n_harmonics=a.nh, n_time=max(1024, 4 * a.nh))
    iso = IsolaOptions()
    changes = {k: v for k, v in (("n_omega", a.n_omega), ("n_modes", a.n_modes), ("workers", a.workers),
                                 ("max_points", a.max_points), ("rl_branch_seeds", a.rl_branch_seeds),
                                 ("harmonics", tuple(a.harmonics) if a.harmonics else None),
                                 ("amplitudes", tuple(a.amplitudes) if a.amplitudes else None),
                                 ("primary_amplitudes",
                                  tuple(a.primary_amplitudes) if a.primary_amplitudes is not None else None))
               if v is not None}
    iso = replace(iso, **changes)
    sweep = None
    if a.ti:
        from pipelines.artifacts import read_artifact
        from pipelines.stages.ti import TiArtifact

        sweep = read_artifact(a.ti, TiArtifact).sweep
    casing, contact = CasingOptions(), ContactOptions()
    lo, hi = iso.omega_range(hbm)
    print(f"ROM {a.rom}; N_h = {hbm.n_harmonics}, N_t = {hbm.n_time}; isolas {iso}")
    done = {}
    for method in sorted(a.methods):  # DLFT first: RL's modal seeds are DLFT's solutions (as the stage)
        t = time.perf_counter()
        nfrc = compute_nfrc(rom, casing, contact, hbm, method)
        print(f"\n## {method.upper()}: primary NFRC {len(nfrc.omega)} points, {time.perf_counter() - t:.0f} s wall, "
              f"status {nfrc.status}", flush=True)
        problem = HbmProblem(rom, casing, contact, hbm, method)
        res, _ = problem()
        known = [KnownBranch.of(nfrc.omega, nfrc.unknowns, "primary", nfrc.converged)]
        if method == "rl" and "dlft" in done:
            seeds = rl_seeds(done["dlft"], search_options(hbm, iso), iso.rl_branch_seeds)
        else:
            seeds = modal_seeds(res, rom, iso, np.linspace(lo, hi, iso.n_omega), around=tuple(known))
        if sweep is not None:
            seeds += ti_seeds(res, sweep, (lo, hi), casing.n_lobes)
        t_seeds = {}

        def on_progress(phase, done, total):
            if phase == "seeds" and (done == total or done % 500 < 120 and done > 0 and print(f"  [{time.perf_counter() - t0:.0f} s] seeds {done}/{total}", flush=True)):
                t_seeds["wall"] = time.perf_counter() - t0
            if phase == "branches":
                print(f"  [{time.perf_counter() - t0:.0f} s] branches: candidate {done}/{total}", flush=True)

        printed = set()

        def on_branch(i, b):  # a branch is passed again each time a seed joins it: said once
            if i in printed:
                return
            printed.add(i)
            ok = b.converged
            print(f"  [{time.perf_counter() - t0:.0f} s] branch {i}: {b.kind}, {int(ok.sum())} points, "
                  f"{b.cpu_time:.0f} s CPU, {b.status}", flush=True)

        t0 = time.perf_counter()
        r = search(problem, seeds, known, search_options(hbm, iso), seed_factory=problem.for_seeds(),
                   describe=BranchDescriber(problem, checks=iso.harmonic_checks, content=True) if a.stage_describe
                   else BranchDescriber(problem),
                   on_progress=on_progress, on_branch=on_branch)
        done[method] = r
        kinds = r.kind_counts()  # linked pieces of one branch counted once
        print(f"{method.upper()}: {len(seeds)} seeds, {r.n_converged} converged, {r.n_distinct} distinct, "
              f"{int((r.seed_branch == -2).sum())} on the primary; {r.n_continued} continued; branches "
              f"({len(r.branches)} records): "
              + (", ".join(f"{n} {k}" for k, n in sorted(kinds.items())) or "none")
              + f"; CPU {r.cpu_time:.0f} s (seeds {r.corrections.cpu_time:.0f} s), wall {r.wall_time:.0f} s "
                f"(seeds {t_seeds.get('wall', float('nan')):.0f} s)")
        print("| branch | kind | Omega range, rad/s | closed | points | dominant harmonic | max LE amplitude, mm | seeds | status |")
        print("|---|---|---|---|---|---|---|---|---|")
        for k, b in enumerate(r.branches):
            ok = b.converged
            dom = dominant_harmonic(b.extras["harmonics"][ok]) if "harmonics" in b.extras else 0
            amp = 1e3 * np.nanmax(b.extras["le_amplitude"][ok]) if "le_amplitude" in b.extras else np.nan
            print(f"| {k} | {b.kind} | {b.omega[ok].min():.0f}-{b.omega[ok].max():.0f} | {b.closed} | "
                  f"{int(ok.sum())} | {dom} | {amp:.3f} | {len(b.seeds)} | {b.status} |", flush=True)
    if a.save:
        arrays = {}
        for method, r in done.items():
            for k, b in enumerate(r.branches):
                arrays.update({f"{method}_{k}_omega": b.omega, f"{method}_{k}_x": b.x,
                               f"{method}_{k}_converged": b.converged,
                               f"{method}_{k}_le_amplitude": b.extras.get("le_amplitude", np.full(len(b.omega), np.nan))})
        np.savez(a.save, **arrays)


if __name__ == "__main__":
    main()
