"""Which branches of an isola search a blade can be found on: Floquet multipliers (Hill's
method, hbm.stability.spectrum.orbit_spectrum) at every k-th point of every branch of
OUT/isolas.h5, then time integration (100 periods, the validation stage's march and
verdict) from up to --march stable points per branch, spread over its stable points.

    PYTHONPATH=. .venv/bin/python benchmarks/bench_branch_stability.py OUT [--scene scenes/rotor67_coarse.toml]
        [--every 6] [--march 3] [--methods dlft rl] [--kinds isola detached]

Needs OUT/rom.h5 and OUT/isolas.h5 of that scene (e.g. from `bladerub run SCENE --out OUT`).
Prints one line per branch (points analysed, stable ones and their Omega span, the range of
the largest multiplier modulus, the minimal periods met and the median CPU time of one
analysis) and one per march (stays or leaves, growth, deviation of the
last 10 periods, largest contact force at the end).
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main() -> None:
    from hbm.harmonic.residual import build_residual
    from hbm.stability.spectrum import orbit_spectrum
    from hbm.ti.march import rom_modal_system
    from hbm.ti.validation import march_from_hbm
    from pipelines.scene import load_scene
    from pipelines.stages.isolas import read_isolas
    from pipelines.stages.rom import read_rom
    from pipelines.stages.validation import _options_for

    ap = argparse.ArgumentParser()
    ap.add_argument("out", type=Path)
    ap.add_argument("--scene", type=Path, default=ROOT / "scenes" / "rotor67_coarse.toml")
    ap.add_argument("--every", type=int, default=6, help="analyse every k-th point of a branch")
    ap.add_argument("--march", type=int, default=3, help="time integrations per branch, from its stable points")
    ap.add_argument("--methods", nargs="+", default=["dlft", "rl"])
    ap.add_argument("--kinds", nargs="+", default=["isola", "detached", "bifurcated"])
    a = ap.parse_args()
    scene = load_scene(a.scene)
    rom = read_rom(a.out)
    system = rom_modal_system(rom)
    found = read_isolas(a.out / "isolas.h5")
    n_r = 3 * rom.n_boundary
    for method in a.methods:
        for br in found.get(method, []):
            if br.kind not in a.kinds:
                continue
            t0 = time.process_time()
            res = build_residual(rom, scene.casing, scene.contact,
                                 _options_for(scene.hbm, br.x.shape[1], n_r, br.subharmonic), method=method)
            idx = [i for i in range(0, len(br.omega), a.every) if br.converged[i]]
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
            picks = idx[stable]
            if len(picks) > a.march:
                picks = picks[np.linspace(0, len(picks) - 1, a.march).round().astype(int)]
            for i in picks:
                ti = march_from_hbm(system, scene.casing, scene.contact.mu,
                                    res.expand_harmonics(br.x[i], float(br.omega[i])), float(br.omega[i]),
                                    subharmonic=br.subharmonic, n_periods=100, dt=scene.ti.dt)
                print(f"    TI from Omega = {br.omega[i]:.1f} rad/s (LE {1e3 * br.le_amplitude[i]:.3f} mm): "
                      f"{ti.verdict().replace('leaves', 'LEAVES', 1)} (growth {ti.growth:.2f}, last deviation "
                      f"{ti.deviation[-10:].max():.3g}), contact force at the end up to {ti.force_peak.max():.0f} N",
                      flush=True)


if __name__ == "__main__":
    main()
