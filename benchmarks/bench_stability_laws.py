"""Which Jacobian gives DLFT orbits the stability time integration sees? At points spread
along one DLFT branch of OUT/isolas.h5: Hill's method on the DLFT Jacobian (what the product
uses), Hill's method on the RL law's Jacobian at the same orbit (the regularised penalty
of [contact], linearised at the DLFT solution), and time integration marched from the orbit
(the validation stage's march and verdict) with each step of --dts.

    PYTHONPATH=. .venv/bin/python benchmarks/bench_stability_laws.py OUT [--scene scenes/rotor67.toml]
        [--branch 000] [--points 16] [--dts 1e-7,2.5e-8] [--periods 100] [--workers 2]

Prints one line per point (largest multiplier modulus by each Jacobian, each march's
verdict) and, per step, how many points each Jacobian's verdict agrees with time
integration (stable and stays, or unstable and leaves, the friction lock counted as
leaving). After each verdict: where the march went in the HBM's unknowns
(hbm.ti.validation.confirm_orbit, as the stage judges it), the distance of its last
period's harmonics to the orbit and, after "/", that of the DLFT solution Newton finds from
them ("-": Newton failed).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import hbm  # noqa: F401  (before numpy: OpenBLAS's kernels for the host, hbm.openblas)
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

_CTX = {}


def _setup(scene_path: Path, out: Path, name: str) -> None:
    from hbm.harmonic.residual import build_residual
    from hbm.ti.march import rom_modal_system
    from pipelines.scene import load_scene
    from pipelines.stages.rom import read_rom
    from pipelines.stages.validation import _options_for, read_branch_set

    scene = load_scene(scene_path)
    rom = read_rom(out)
    br = next(b for b in read_branch_set(out / "isolas.h5", "dlft") if b.name == name)
    opts = _options_for(scene.hbm, br.x.shape[1], 3 * rom.n_boundary, br.subharmonic)
    _CTX.update(scene=scene, br=br, system=rom_modal_system(rom),
                dlft=build_residual(rom, scene.casing, scene.contact, opts, method="dlft"),
                rl=build_residual(rom, scene.casing, scene.contact, opts, method="rl"))


def _point(args):
    """(index, Omega, largest |mu| DLFT, largest |mu| RL law, [TI verdict per dt])."""
    from hbm.stability.spectrum import orbit_spectrum
    from hbm.ti.validation import confirm_orbit, march_from_hbm

    i, dts, n_periods = args
    c = _CTX
    br, rd, rr, scene = c["br"], c["dlft"], c["rl"], c["scene"]
    u, w = br.x[i], float(br.omega[i])
    mu_d = float(np.abs(orbit_spectrum(rd, u, w)[0].multipliers).max())
    mu_r = float(np.abs(orbit_spectrum(rr, rr.to_unknowns(rd.to_coefficients(u)), w)[0].multipliers).max())
    verdicts = []
    for dt in dts:
        ti = march_from_hbm(c["system"], scene.casing, scene.contact.mu, rd.expand_harmonics(u, w), w,
                            subharmonic=br.subharmonic, n_periods=n_periods, dt=dt, record_all=True)
        ti = confirm_orbit(rd, ti, u, w)
        went = ti.reached
        verdicts.append(("stays" if ti.stays else "lock" if ti.outcome == "permanent contact" else "leaves",
                         went.distance, went.solution_distance))
    return i, w, mu_d, mu_r, verdicts


def main() -> None:
    from hbm.processes import process_context

    ap = argparse.ArgumentParser()
    ap.add_argument("out", type=Path)
    ap.add_argument("--scene", type=Path, default=ROOT / "scenes" / "rotor67.toml")
    ap.add_argument("--branch", default="000", help="name of a DLFT branch of OUT/isolas.h5")
    ap.add_argument("--points", type=int, default=16)
    ap.add_argument("--dts", type=lambda s: [float(v) for v in s.split(",")], default=[1e-7, 2.5e-8])
    ap.add_argument("--periods", type=int, default=100)
    ap.add_argument("--workers", type=int, default=2)
    a = ap.parse_args()
    _setup(a.scene, a.out, a.branch)
    br = _CTX["br"]
    conv = np.flatnonzero(br.converged)
    # spread over the branch; a closed loop's last point is its first
    picks = sorted(set(conv[np.linspace(0, len(conv) - 1, a.points).astype(int)].tolist()))
    if br.closed and len(picks) > 1 and picks[-1] == conv[-1]:
        picks = picks[:-1]
    jobs = [(i, a.dts, a.periods) for i in picks]
    if a.workers > 1:
        with process_context().Pool(a.workers, initializer=_setup, initargs=(a.scene, a.out, a.branch)) as pool:
            rows = pool.map(_point, jobs, chunksize=1)
    else:
        rows = [_point(j) for j in jobs]
    print(f"DLFT branch {a.branch} of {a.out / 'isolas.h5'} ({br.kind}, {br.omega.min():.0f}-{br.omega.max():.0f} "
          f"rad/s): {len(rows)} points, {a.periods} periods of time integration")
    print(f"{'point':>5} {'Omega':>7} {'|mu| DLFT':>9} {'|mu| RL law':>11} "
          + " ".join(f"{'TI ' + format(dt, 'g'):>22}" for dt in a.dts))
    for i, w, md, mr, v in rows:
        print(f"{i:5d} {w:7.1f} {md:9.3f} {mr:11.3f} "
              + " ".join(f"{x:>7} {d:6.3f}/{'-' if np.isnan(b) else format(b, '.3f'):>6}" for x, d, b in v))
    for k, dt in enumerate(a.dts):
        stays = np.array([r[4][k][0] == "stays" for r in rows])
        agree_d = int(np.sum((np.array([r[2] for r in rows]) < 1.0) == stays))
        agree_r = int(np.sum((np.array([r[3] for r in rows]) < 1.0) == stays))
        print(f"dt = {dt:g} s: DLFT Jacobian agrees with time integration at {agree_d} of {len(rows)} points, "
              f"the RL law's at {agree_r}")
    if len(a.dts) > 1:
        moved = sum(len({x[0] for x in r[4]}) > 1 for r in rows)
        print(f"time integration's verdict changes with the step at {moved} of {len(rows)} points")


if __name__ == "__main__":
    main()
