"""Does RL's Hill verdict depend on its penalty? At every point of OUT/validation.h5, DLFT's
orbit at the point's Omega (the point itself, or damped Newton from RL's), then RL's orbit
for each penalty kappa of --kappas (damped Newton from the previous kappa's orbit, the
first from the point), and Hill's method on each.

    PYTHONPATH=. .venv/bin/python benchmarks/bench_rl_penalty.py OUT --scene scenes/rotor67.toml
        [--kappas 1e9,3e9,1e10,3e10,1e11] [--gamma G]

Needs OUT/rom.h5 and OUT/validation.h5. Prints, per point: DLFT's largest multiplier
modulus and unstable count, then per kappa the distance of RL's orbit to DLFT's (relative
2-norm of the harmonic coefficients) and RL's largest modulus and unstable count. The
scene's kappa should come first: the validation stage compared the treatments there.
"""
from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main(argv=None) -> None:
    from hbm.continuation.newton import NewtonOptions
    from hbm.harmonic.residual import build_residual
    from hbm.harmonic.solver import HbmSolver
    from hbm.harmonic.start import damped_newton
    from hbm.stability.spectrum import orbit_spectrum
    from pipelines.scene import load_scene
    from pipelines.stages.rom import read_rom
    from pipelines.stages.validation import KINDS, _options_for, read_validation, ti_verdict

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("out", type=Path)
    p.add_argument("--scene", type=Path, default=ROOT / "scenes" / "rotor67.toml")
    p.add_argument("--kappas", default="1e9,3e9,1e10,3e10,1e11", help="RL penalties, N/m, comma-separated")
    p.add_argument("--gamma", type=float, default=None, help="RL regularisation, N (default: the scene's)")
    a = p.parse_args(argv)
    scene = load_scene(a.scene)
    rom = read_rom(a.out)
    val = read_validation(a.out)
    n_r = 3 * rom.n_boundary
    tol = scene.hbm.tolerance
    kappas = [float(k) for k in a.kappas.split(",")]

    def verdict(res, x, omega):
        sp, _ = orbit_spectrum(res, x, omega)
        m = np.abs(sp.multipliers)
        return f"{m.max():.3f} ({int((m > 1 + 1e-6).sum())} unstable)"

    for method in ("dlft", "rl"):
        for kind in KINDS:
            pt = getattr(getattr(val, method), kind)
            if not pt.found:
                continue
            om = pt.omega
            opts = _options_for(scene.hbm, len(pt.u), n_r, pt.subharmonic)

            def solve(res, c, om=om):
                return damped_newton(res, res.to_unknowns(c), om, NewtonOptions(tol_residual=tol), HbmSolver(atol=0.1 * tol))

            dl = build_residual(rom, scene.casing, scene.contact, opts, method="dlft")
            own = build_residual(rom, scene.casing, scene.contact, opts, method=method)
            c_pt = own.to_coefficients(pt.u)
            print(f"{method.upper()} {kind} {om:.1f} rad/s (time integration: {ti_verdict(pt.ti, rom, scene.contact.mu)})")
            if method == "dlft":
                c_d = c_pt
            else:
                s = solve(dl, c_pt)
                if not s.converged:
                    print(f"  DLFT: no solution at this Omega ({s.reason})")
                    continue
                c_d = dl.to_coefficients(s.x)
            print(f"  DLFT: largest |mu| {verdict(dl, dl.to_unknowns(c_d), om)}")
            start = c_pt
            for kappa in kappas:
                contact = replace(scene.contact, kappa=kappa, **({} if a.gamma is None else {"gamma": a.gamma}))
                rl = build_residual(rom, scene.casing, contact, opts, method="rl")
                s = solve(rl, start)
                if not s.converged:
                    print(f"  RL kappa {kappa:.0e} N/m: no solution ({s.reason})")
                    continue
                start = rl.to_coefficients(s.x)
                dist = np.linalg.norm(start - c_d) / np.linalg.norm(c_d)
                print(f"  RL kappa {kappa:.0e} N/m: {dist:.1%} from DLFT, largest |mu| {verdict(rl, s.x, om)}")


if __name__ == "__main__":
    main()
