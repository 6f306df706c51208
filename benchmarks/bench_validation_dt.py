"""Does the validation stage's verdict depend on the time step? Time integration is marched
from each validation point (read from OUT/validation.h5), or from the stable points of one
branch of OUT/isolas.h5 (or of the NFRC: METHOD/nfrc) nearest given speeds, with each step
of --dts, as the stage marches (hbm.ti.validation.march_from_hbm from the orbit's state
farthest from the casing).

    PYTHONPATH=. .venv/bin/python benchmarks/bench_validation_dt.py OUT [--scene scenes/rotor67.toml]
        [--dts 1e-7,5e-8,2.5e-8,1.25e-8] [--periods 100] [--methods dlft rl]
        [--branch dlft/000 --omegas 823.3,859.0] [--branch rl/nfrc --omegas 1459.5]

Prints, per point and step: the verdict, the growth of the distance to the orbit, that
distance over the last tenth of the periods (max of LE and TE, relative to the orbit's
amplitude), the period-to-period drift at the end, the smallest number of periods over which
the last tenth repeats (hbm.ti.validation.repeat_period; 0: none up to MAX_REPEAT), the
march's LE amplitude (half the peak to peak over the last period) against the orbit's, the
march's CPU time, and where it went in
the HBM's unknowns (hbm.ti.validation.confirm_orbit, as the stage judges it): the distance
of its last period's harmonics to the orbit, and that of the solution Newton finds from them
("-" when Newton fails).
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


def points(args):
    """(label, method, omega, u, nu, LE amplitude in m) of every point to march."""
    import h5py

    if args.branch:
        from pipelines.stages.validation import read_branch_set

        method, name = args.branch.split("/")
        if name == "nfrc":  # the primary NFRC (nfrc_METHOD.h5)
            from pipelines.branch_store import load_branch

            stored = load_branch(args.out / f"nfrc_{method}.h5")
            omega, x, stable = stored.branch.omega, stored.branch.x, stored.extras.get("stable")
            amplitude, nu = stored.extras["le_amplitude"], 1
        else:
            br = next(b for b in read_branch_set(args.out / "isolas.h5", method) if b.name == name)
            omega, x, stable, amplitude, nu = br.omega, br.x, br.stable, br.le_amplitude, br.subharmonic
        pool = np.flatnonzero(stable) if stable is not None and stable.any() else np.arange(len(omega))
        for w in args.omegas:
            i = int(pool[np.argmin(np.abs(omega[pool] - w))])
            yield f"{name}[{i}]", method, float(omega[i]), x[i], nu, float(amplitude[i])
        return
    with h5py.File(args.out / "validation.h5", "r") as f:
        for method in args.methods:
            for kind in ("primary", "isola", "period_doubling"):
                g = f[f"{method}/{kind}"]
                if g["found"][()]:
                    yield (kind, method, float(g["omega"][()]), g["u"][()], int(g["subharmonic"][()]),
                           float(g["le_amplitude"][()]))


def main() -> None:
    from hbm.harmonic.residual import build_residual
    from hbm.ti.march import rom_modal_system
    from hbm.ti.validation import confirm_orbit, march_from_hbm
    from pipelines.scene import load_scene
    from pipelines.stages.rom import read_rom
    from pipelines.stages.validation import _options_for

    ap = argparse.ArgumentParser()
    ap.add_argument("out", type=Path)
    ap.add_argument("--scene", type=Path, default=ROOT / "scenes" / "rotor67_coarse.toml")
    ap.add_argument("--dts", type=lambda s: [float(v) for v in s.split(",")], default=[1e-7, 5e-8, 2.5e-8, 1.25e-8])
    ap.add_argument("--periods", type=int, default=None, help="periods marched (default: [validation] n_periods)")
    ap.add_argument("--methods", nargs="+", default=["dlft", "rl"])
    ap.add_argument("--branch", help="METHOD/NAME of a branch of OUT/isolas.h5, e.g. dlft/000, or METHOD/nfrc")
    ap.add_argument("--omegas", type=lambda s: [float(v) for v in s.split(",")], default=[],
                    help="with --branch: march from its stable points nearest these speeds, rad/s")
    args = ap.parse_args()
    if args.branch and not args.omegas:
        ap.error("--branch needs --omegas")
    scene = load_scene(args.scene)
    n_periods = args.periods or scene.validation.n_periods
    rom = read_rom(args.out)
    system = rom_modal_system(rom)
    n_r = 3 * rom.n_boundary
    print(f"{'method':6} {'point':16} {'Omega':>8} {'dt (s)':>8} {'verdict':38} {'growth':>7} {'last dist':>9} "
          f"{'drift':>7} {'repeat':>6} {'LE amp mm':>9} {'orbit mm':>8} {'CPU s':>6} {'u dist':>7} {'Newton':>7}")
    for label, method, omega, u, nu, amplitude in points(args):
        res = build_residual(rom, scene.casing, scene.contact, _options_for(scene.hbm, len(u), n_r, nu), method=method)
        coeffs = res.expand_harmonics(u, omega)
        for dt in args.dts:
            c0 = time.process_time()
            ti = march_from_hbm(system, scene.casing, scene.contact.mu, coeffs, omega, subharmonic=nu,
                                n_periods=n_periods, dt=dt, record_all=True)
            cpu = time.process_time() - c0
            ti = confirm_orbit(res, ti, u, omega)
            went = ti.reached
            le = ti.displacement[:, 0]
            last = ti.deviation[-max(1, n_periods // 10):].max()
            print(f"{method:6} {label:16} {omega:8.1f} {ti.dt:8.2e} {ti.verdict()[:38]:38} {ti.growth:7.2f} "
                  f"{last:9.3f} {np.max(ti.drift):7.3f} {ti.repeat:6d} {1e3 * 0.5 * np.ptp(le):9.3f} {1e3 * amplitude:8.3f} {cpu:6.1f} "
                  f"{went.distance:7.3f} {went.solution_distance if went.converged else '-':>7.3}",
                  flush=True)


if __name__ == "__main__":
    main()
