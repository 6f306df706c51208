"""Does RL's Hill verdict depend on its penalty? At every point of OUT/validation.h5 (or, with
--nfrc METHOD --omegas, at the NFRC points nearest those speeds), DLFT's orbit at the
point's Omega (the point itself, or damped Newton from RL's), then RL's orbit for each
penalty kappa of --kappas (damped Newton from the previous kappa's orbit, the first from
the point), and Hill's method on each.

    PYTHONPATH=. .venv/bin/python benchmarks/bench_rl_penalty.py OUT --scene scenes/rotor67.toml
        [--kappas 1e9,3e9,1e10,3e10,1e11] [--gamma G] [--nfrc rl --omegas 1459.5]
        [--branch rl/001 --indices 10,54]

--branch METHOD/NNN --indices: those points of a branch of OUT/isolas.h5 instead (a branch
can pass a speed several times, so points are named by index).

Needs OUT/rom.h5 and OUT/validation.h5 (or OUT/isolas.h5 with --branch). Prints, per point:
DLFT's LE amplitude, largest multiplier modulus and unstable count, then per kappa RL's LE
amplitude, the distance of its orbit to DLFT's (relative 2-norm of the harmonic
coefficients; none when DLFT has no orbit there) and its largest modulus and unstable count. The
scene's kappa should come first: the validation stage compared the treatments there.
"""
from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import hbm  # noqa: F401  (before numpy: OpenBLAS's kernels for the host, hbm.openblas)
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main(argv=None) -> None:
    from hbm.continuation.newton import NewtonOptions
    from hbm.harmonic.nfrc import nfrc_extras
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
    p.add_argument("--nfrc", choices=("dlft", "rl"), help="the points of nfrc_METHOD.h5 nearest --omegas instead")
    p.add_argument("--omegas", type=lambda t: [float(v) for v in t.split(",")], default=[], help="rad/s")
    p.add_argument("--branch", metavar="METHOD/NNN", help="points of this branch of OUT/isolas.h5 instead")
    p.add_argument("--indices", type=lambda t: [int(v) for v in t.split(",")], default=[],
                   help="with --branch: the branch's point indices")
    a = p.parse_args(argv)
    if a.nfrc and not a.omegas:
        p.error("--nfrc needs --omegas")
    if a.branch and not a.indices:
        p.error("--branch needs --indices")
    scene = load_scene(a.scene)
    rom = read_rom(a.out)
    val = None if (a.nfrc or a.branch) else read_validation(a.out)
    n_r = 3 * rom.n_boundary
    tol = scene.hbm.tolerance
    kappas = [float(k) for k in a.kappas.split(",")]

    def verdict(res, x, omega):
        sp, _ = orbit_spectrum(res, x, omega)
        m = np.abs(sp.multipliers)
        return f"{m.max():.3f} ({int((m > 1 + 1e-6).sum())} unstable)"

    for method, kind, pt in points(a, val, KINDS):
        om = pt.omega
        opts = _options_for(scene.hbm, len(pt.u), n_r, pt.subharmonic)

        def solve(res, c, om=om):
            return damped_newton(res, res.to_unknowns(c), om, NewtonOptions(tol_residual=tol), HbmSolver(atol=0.1 * tol))

        dl = build_residual(rom, scene.casing, scene.contact, opts, method="dlft")
        own = build_residual(rom, scene.casing, scene.contact, opts, method=method)
        c_pt = own.to_coefficients(pt.u)
        ti = ti_verdict(pt.ti, rom, scene.contact.mu) if pt.ti is not None else "not marched here"
        amp = f", LE {1e3 * pt.le_amplitude:.3f} mm" if getattr(pt, "le_amplitude", None) is not None else ""
        print(f"{method.upper()} {kind} {om:.1f} rad/s{amp} (time integration: {ti})")
        if method == "dlft":
            c_d = c_pt
        else:
            s = solve(dl, c_pt)
            c_d = dl.to_coefficients(s.x) if s.converged else None
            if c_d is None:
                print(f"  DLFT: no solution at this Omega ({s.reason})")
        if c_d is not None:
            print(f"  DLFT: LE {1e3 * nfrc_extras(dl, dl.to_unknowns(c_d))['le_amplitude']:.3f} mm, "
                  f"largest |mu| {verdict(dl, dl.to_unknowns(c_d), om)}")
        start = c_pt
        for kappa in kappas:
            contact = replace(scene.contact, kappa=kappa, **({} if a.gamma is None else {"gamma": a.gamma}))
            rl = build_residual(rom, scene.casing, contact, opts, method="rl")
            s = solve(rl, start)
            if not s.converged:
                print(f"  RL kappa {kappa:.0e} N/m: no solution ({s.reason})")
                continue
            start = rl.to_coefficients(s.x)
            dist = "" if c_d is None else f"{np.linalg.norm(start - c_d) / np.linalg.norm(c_d):.1%} from DLFT, "
            print(f"  RL kappa {kappa:.0e} N/m: LE {1e3 * nfrc_extras(rl, s.x)['le_amplitude']:.3f} mm, {dist}"
                  f"largest |mu| {verdict(rl, s.x, om)}")


def points(a, val, kinds):
    """(method, kind, point) of the validation points, or of the NFRC points asked for (point:
    anything with omega, u, subharmonic and ti)."""
    from types import SimpleNamespace

    from pipelines.branch_store import load_branch

    if a.branch:
        from pipelines.stages.validation import read_branch_set

        method, name = a.branch.split("/")
        b = next((b for b in read_branch_set(a.out / "isolas.h5", method) if b.name == name), None)
        if b is None:
            raise SystemExit(f"{a.out / 'isolas.h5'} has no branch {a.branch}")
        for i in a.indices:
            yield method, f"{a.branch} point {i}", SimpleNamespace(
                omega=float(b.omega[i]), u=b.x[i], subharmonic=b.subharmonic, ti=None,
                le_amplitude=float(b.le_amplitude[i]))
        return
    if not a.nfrc:
        for method in ("dlft", "rl"):
            for kind in kinds:
                pt = getattr(getattr(val, method), kind)
                if pt.found:
                    yield method, kind, pt
        return
    b = load_branch(a.out / f"nfrc_{a.nfrc}.h5").branch
    for w in a.omegas:
        i = int(np.argmin(np.abs(b.omega - w)))
        yield a.nfrc, f"NFRC point {i}", SimpleNamespace(omega=float(b.omega[i]), u=b.x[i], subharmonic=1, ti=None)


if __name__ == "__main__":
    main()
