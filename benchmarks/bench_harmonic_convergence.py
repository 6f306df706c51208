"""Are the validation stage's points converged in the number of harmonics? Every point the
stage marched from (the primary, isola and period-doubled points and each of their tries,
read from OUT/validation.h5) is solved again with `--factor` times the harmonics (and AFT
samples) by damped Newton at the same Omega from its own harmonics, padded with zeros; then
Hill's method at both resolutions.

    PYTHONPATH=. .venv/bin/python benchmarks/bench_harmonic_convergence.py OUT [--scene scenes/rotor67.toml]
        [--factor 2] [--methods dlft rl] [--branch rl/000 --every 5 [--no-lanczos]]

Needs OUT/rom.h5, OUT/validation.h5 and the branch files its points come from (nfrc_*.h5,
isolas.h5; the period-doubled branch is validation.h5's own), e.g. from `bladerub run SCENE
--out OUT --set hbm.stability=true`. Prints one line per marched point: what time
integration did (the stage's verdict), the largest multiplier modulus at N_h, whether a
solution exists at factor x N_h, how far it moved (relative 2-norm of the first N_h
harmonics of the condensed unknowns) and its largest multiplier modulus there, and the CPU
time of that check. With --branch METHOD/NAME, every --every-th
converged point of that branch of OUT/isolas.h5 instead (--branch nfrc/METHOD: of the
primary NFRC OUT/nfrc_METHOD.h5), and a summary: how many have no
solution next to them with factor x N_h, moved by more than 25 %, or change stability verdict.
With --no-lanczos (an RL branch), each point is first solved again at N_h without the Lanczos
filter, whose factors change with N_h, and that orbit is checked, also without it; the line
adds its distance to the filtered orbit ("none": no unfiltered orbit next to it).
"""
from __future__ import annotations

import argparse
import re
import sys
import time
from dataclasses import replace
from pathlib import Path

import hbm  # noqa: F401  (before numpy: OpenBLAS's kernels for the host, hbm.openblas)
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

#: one try in a validation point's reason: "882.9 rad/s (stable), time integration leaves"
TRY = re.compile(r"(\d+\.\d) rad/s(?: of ([^(]+?))? \((stable|unstable)\), time integration ([^|;]+)")


def _branch(out: Path, where: str, method: str):
    """(omega (m,), x (m, n_u), stable (m,) bool or None) of the branch named by a point's
    'branch' attribute ("nfrc_rl.h5", "isolas.h5 rl/branches/000", "validation.h5
    period-doubled branch of rl, from ...")."""
    from pipelines.branch_store import load_branch
    from pipelines.stages.validation import read_branch_set, read_validation

    if where.startswith("validation.h5"):
        pd = getattr(read_validation(out), method).pd_branch
        return pd.omega, pd.x, pd.stable
    if where.startswith("isolas.h5"):
        name = where.split("/")[-1]
        br = next(b for b in read_branch_set(out / "isolas.h5", method) if b.name == name)
        return br.omega, br.x, br.stable
    stored = load_branch(out / where.split()[0])
    return stored.branch.omega, stored.branch.x, stored.extras.get("stable")


def refine(coarse, fine, u, omega):
    """(largest |mu| at N_h, solution exists at the finer N_h, moved, largest |mu| there, CPU s):
    check_harmonics with damped_newton's default 40 iterations, then Hill's method on the
    finer solution whatever the treatment."""
    from hbm.stability.convergence import check_harmonics
    from hbm.stability.spectrum import orbit_spectrum

    mu0 = np.abs(orbit_spectrum(coarse, u, omega)[0].multipliers).max()
    c0 = time.process_time()
    check = check_harmonics(coarse, u, omega, stable=False, max_iter=40, fine=fine)
    if not check.u.size:
        return mu0, False, np.nan, np.nan, time.process_time() - c0
    mu1 = np.abs(orbit_spectrum(fine, check.u, omega)[0].multipliers).max()
    return mu0, True, check.moved, mu1, time.process_time() - c0


def unfilter(filtered, unfiltered, u, omega):
    """(u', how far it lies from u): the solution of the RL law without the Lanczos filter at
    the same N_h and omega, by damped Newton from u (the filtered one), and the relative
    2-norm of the difference of their harmonics; (None, "none") when Newton finds none."""
    from hbm.continuation.newton import NewtonOptions
    from hbm.harmonic.solver import HbmSolver
    from hbm.harmonic.start import damped_newton

    tol = filtered.options.tolerance
    sol = damped_newton(unfiltered, u, omega, NewtonOptions(tol_residual=tol), HbmSolver(atol=0.1 * tol))
    if not sol.converged:
        return None, "none"
    a, b = filtered.to_coefficients(u), unfiltered.to_coefficients(sol.x)
    return sol.x, float(np.linalg.norm(b - a) / np.linalg.norm(a))


def branch_points(args, scene, rom) -> None:
    """--branch: every --every-th converged point of one branch of isolas.h5 (METHOD/NAME) or
    of a primary NFRC (nfrc/METHOD: OUT/nfrc_METHOD.h5)."""
    from hbm.harmonic.residual import build_residual
    from hbm.stability.convergence import HARMONIC_MOVE_TOL
    from pipelines.branch_store import load_branch
    from pipelines.stages.validation import read_branch_set

    method, name = args.branch.split("/")
    if method == "nfrc":
        method = name
        br = load_branch(args.out / f"nfrc_{method}.h5").branch
        subharmonic = 1
    else:
        br = next(b for b in read_branch_set(args.out / "isolas.h5", method) if b.name == name)
        subharmonic = br.subharmonic
    nh = (br.x.shape[1] // (3 * rom.n_boundary) - 1) // 2
    hbm = replace(scene.hbm, subharmonic=subharmonic, n_harmonics=nh)
    coarse = build_residual(rom, scene.casing, scene.contact, hbm, method=method)
    if args.no_lanczos:  # the same law without the filter: each point is first solved again at N_h without it
        if method != "rl":
            sys.exit(f"--no-lanczos: only RL has the Lanczos filter, not {method}")
        filtered = coarse
        coarse = build_residual(rom, scene.casing, replace(scene.contact, lanczos=False), hbm, method=method)
    fine = coarse.refined(args.factor)
    rows, n_none = [], 0
    unfiltered = f" {'unfiltered':>10}" if args.no_lanczos else ""
    print(f"{'point':>5} {'Omega':>8}{unfiltered} {'|mu| N_h':>9} {'exists':>7} {'moved':>7} {'|mu|':>7} {'CPU s':>6}")
    for i in np.flatnonzero(br.converged)[:: args.every]:
        w, u = float(br.omega[i]), br.x[i]
        if args.no_lanczos:
            u, off = unfilter(filtered, coarse, u, w)
            if u is None:
                n_none += 1
                print(f"{i:5d} {w:8.1f} {off:>10}", flush=True)
                continue
            unfiltered = f" {off:10.3f}"
        mu0, ok, moved, mu1, cpu = refine(coarse, fine, u, w)
        rows.append((mu0, ok, moved, mu1, cpu))
        print(f"{i:5d} {w:8.1f}{unfiltered} {mu0:9.3f} {'yes' if ok else 'no':>7} {moved:7.3f} {mu1:7.3f} {cpu:6.1f}",
              flush=True)
    if not rows:
        sys.exit(f"{args.branch}: no point to check ({n_none} without an unfiltered orbit next to them)")
    mu0, ok, moved, mu1, cpu = (np.array(c) for c in zip(*rows))
    same = ok & (moved <= HARMONIC_MOVE_TOL)
    flips = same & ((mu0 < 1.0) != (mu1 < 1.0))
    print(f"{args.branch}: {len(rows)} points checked with N_h = {fine.basis.n_harmonics}: {int((~ok).sum())} without a "
          f"solution next to them, {int((ok & ~same).sum())} moved by more than {HARMONIC_MOVE_TOL:.0%}; of the "
          f"{int(same.sum())} others, {int(flips.sum())} change verdict ({int((flips & (mu0 < 1)).sum())} stable -> "
          f"unstable); stable at N_h: {int((mu0 < 1).sum())}; median CPU {np.median(cpu):.1f} s"
          + (f"; {n_none} points without an unfiltered orbit next to them, left out" if args.no_lanczos else ""))


def main() -> None:
    import h5py

    from hbm.harmonic.residual import build_residual
    from pipelines.scene import load_scene
    from pipelines.stages.rom import read_rom

    ap = argparse.ArgumentParser()
    ap.add_argument("out", type=Path)
    ap.add_argument("--scene", type=Path, default=ROOT / "scenes" / "rotor67_coarse.toml")
    ap.add_argument("--factor", type=int, default=2)
    ap.add_argument("--methods", nargs="+", default=["dlft", "rl"])
    ap.add_argument("--branch", help="METHOD/NAME of a branch of OUT/isolas.h5, e.g. rl/000, or nfrc/METHOD "
                                     "for OUT/nfrc_METHOD.h5")
    ap.add_argument("--every", type=int, default=5)
    ap.add_argument("--no-lanczos", action="store_true",
                    help="with --branch of RL: solve each point again without the Lanczos filter at N_h, then check "
                         "that unfiltered solution (does the filter, which changes with N_h, move the branch?)")
    args = ap.parse_args()
    scene = load_scene(args.scene)
    rom = read_rom(args.out)
    n_r = 3 * rom.n_boundary
    if args.branch:
        return branch_points(args, scene, rom)
    print(f"{'method':6} {'point':8} {'Omega':>8} {'time integration':40} {'|mu| N_h':>9} {'x' + str(args.factor) + ' N_h':>9} "
          f"{'moved':>7} {'|mu|':>7} {'CPU s':>6}")
    with h5py.File(args.out / "validation.h5", "r") as f:
        for method in args.methods:
            for kind in ("primary", "isola", "period_doubling"):
                g = f[f"{method}/{kind}"]
                if not g["found"][()]:
                    continue
                where, reason = g.attrs["branch"], g.attrs["reason"]
                nu = int(g["subharmonic"][()])
                # a try on another branch than the chosen point's names it ("... rad/s of isolas.h5 rl/branches/000")
                tries = [(float(w), b.strip() or where, st == "stable", v.strip()) for w, b, st, v in TRY.findall(reason)]
                if not tries:  # one march: the point itself
                    tries = [(float(g["omega"][()]), where, bool(g["stable"][()]), "(the point)")]
                built = {}  # branch -> (omega, x, stable, coarse residual, fine residual), once per branch
                for omega, on, stable, verdict in tries:
                    if on not in built:
                        omega_b, x_b, stable_b = _branch(args.out, on, method)
                        nh = (x_b.shape[1] // n_r - 1) // 2
                        coarse = build_residual(rom, scene.casing, scene.contact,
                                                replace(scene.hbm, subharmonic=nu, n_harmonics=nh), method=method)
                        built[on] = (omega_b, x_b, stable_b, coarse, coarse.refined(args.factor))
                    omega_b, x_b, stable_b, coarse, fine = built[on]
                    # the branch point the reason names (rounded to 0.1 rad/s; among the stable
                    # ones when the branch says which: a fold may put several points there)
                    pool = np.flatnonzero(np.asarray(stable_b, bool) == stable) if stable_b is not None else None
                    pool = pool if pool is not None and len(pool) else np.arange(len(omega_b))
                    i = int(pool[np.argmin(np.abs(omega_b[pool] - omega))])
                    w = float(omega_b[i])
                    mu0, ok, moved, mu1, cpu = refine(coarse, fine, x_b[i], w)
                    tail = (f"{'yes':>9} {moved:7.3f} {mu1:7.3f}" if ok else f"{'no':>9} {'-':>7} {'-':>7}")
                    print(f"{method:6} {kind:8} {w:8.1f} {verdict[:40]:40} {mu0:9.3f} {tail} {cpu:6.1f}", flush=True)


if __name__ == "__main__":
    main()
