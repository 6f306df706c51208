"""Dynamical content (paper Figs. 11 and 12) along chosen branches of an isola search, whatever
their kind, on one figure (the stage draws each treatment's on its own), and the figures the
README quotes from it: for every crossing k Omega = omega_j of a harmonic k of Omega in
--harmonics (column k nu on a branch of basis Omega / nu) with one of the ROM's first four
modes inside a branch's span, the largest |c_k| of the LE radial displacement within
--window of the crossing's speed, where it lies, and that mode's relative contribution there
(eqs. (32)-(34), as stored in isolas.h5), against their medians over the branch.

    PYTHONPATH=. .venv/bin/python benchmarks/draw_branch_content.py OUT --branches dlft/003 rl/002
        [--harmonics 8,10] [--window 0.03] [--png content.png]

Needs OUT/rom.h5 and OUT/isolas.h5 (a search run with its content, the default). --png draws
the harmonic content of those branches (pipelines.figures.plot_content, the stage's figure).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import hbm  # noqa: F401  (before numpy: OpenBLAS's kernels for the host, hbm.openblas)
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main(argv=None) -> None:
    from hbm.harmonic.content import rom_modes
    from pipelines.figures import plot_content
    from pipelines.stages.isolas import read_isolas
    from pipelines.stages.rom import read_rom

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--branches", nargs="+", required=True, metavar="METHOD/NNN")
    ap.add_argument("--harmonics", type=lambda t: [int(v) for v in t.split(",")], default=[8, 10],
                    help="harmonics k of Omega whose crossings with the first four modes are measured")
    ap.add_argument("--window", type=float, default=0.03, help="relative half-width in Omega around a crossing")
    ap.add_argument("--png", type=Path, help="draw the branches' harmonic content there")
    a = ap.parse_args(argv)

    found = read_isolas(a.out / "isolas.h5")  # read once: the branches are looked up by name below
    rom = read_rom(a.out)
    omega_j = rom_modes(rom.K, rom.M)[0][:4]
    print("modes (rad/s): " + ", ".join(f"{j + 1}: {w:.1f}" for j, w in enumerate(omega_j)))
    curves = {}
    for name in a.branches:
        method, nnn = name.split("/")
        b = next((b for b in found.get(method, []) if b.name == nnn), None)
        if b is None:
            raise SystemExit(f"{a.out / 'isolas.h5'} has no branch {name}")
        if b.harmonic_contribution is None or b.modal_contribution is None:
            raise SystemExit(f"branch {name} carries no content (isolas.h5 written without it)")
        ok = b.converged
        om, harm, modal, nu = b.omega[ok], b.harmonic_contribution[ok], b.modal_contribution[ok].real, b.subharmonic
        harm = np.abs(harm)
        label = f"{method.upper()} {b.kind} {om.min():.0f}-{om.max():.0f}"
        curves[label] = (b.omega, np.abs(b.harmonic_contribution), nu, b.converged)
        print(f"{name} ({label} rad/s, {len(om)} points): mode 1 share median {np.median(modal[:, 0]):.2f}")
        for k in a.harmonics:
            col = k * nu
            if col >= harm.shape[1]:
                continue
            for j, w in enumerate(omega_j):
                c = w / k
                near = np.abs(om - c) <= a.window * c
                if not near.any():
                    continue
                i = np.flatnonzero(near)[np.argmax(harm[near, col])]
                print(f"  {k} Omega = w{j + 1} at {c:.1f} rad/s: |c_{k}| peaks at {om[i]:.1f} rad/s, "
                      f"{1e3 * harm[i, col]:.3f} mm (branch median {1e3 * np.median(harm[:, col]):.3f}); "
                      f"mode {j + 1} share there {modal[i, j]:.2f} (median {np.median(modal[:, j]):.2f})")
    if a.png:
        plot_content(curves, a.png, kind="harmonic", mode_frequencies=omega_j)
        print(f"drawn: {a.png}")


if __name__ == "__main__":
    main()
