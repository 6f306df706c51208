"""Where do the sweep's seeds that RL's Newton gives up on lead? For every seed of OUT's
ti.h5 at the given speeds (hbm.isolas.harmonic.ti_seeds in the basis of Omega), the search's
patient Newton (SearchOptions.model_newton) with DLFT and with RL, and RL's Newton again
from DLFT's corrected solution of the same seed, as RL's modal seeds are made
(hbm.isolas.harmonic.rl_seeds).

    PYTHONPATH=. .venv/bin/python benchmarks/bench_seed_reach.py OUT [--scene scenes/rotor67.toml]
        [--omegas 440,450,460,470,480,660,690,700,1350] [--no-period]
    PYTHONPATH=. .venv/bin/python benchmarks/bench_seed_reach.py OUT --singular 512,528 [--method rl]
    PYTHONPATH=. .venv/bin/python benchmarks/bench_seed_reach.py OUT --modal --omegas 560,560.5
    PYTHONPATH=. .venv/bin/python benchmarks/bench_seed_reach.py OUT --modal --omegas grid [--around 1e-3,1e-2] [--method rl] [--stall-check]
    PYTHONPATH=. .venv/bin/python benchmarks/bench_seed_reach.py OUT --from-branch dlft/005 [--every 10]

Prints, per speed and correction: the start's distance to the treatment's primary NFRC (the
search's scaled polyline metric, hbm.isolas.membership; its tolerance is [isolas] tolerance),
converged or not, Newton's iterations and last ||R||, the solution's distance to the
primary, the CPU time, and which known branch the search's own test puts the solution on
(hbm.isolas.search.lies_on_any: the polyline distance, or Newton onto the branch's curve
there; against the primary and OUT/isolas.h5's branches in the basis of Omega): a solution
at a distance well above the tolerance may still lie on the primary.

--modal: instead, the modal seeds of eq. (31) at those speeds (DLFT's; --method rl: RL's;
any speed, on the grid or not; `grid`: the scene's [isolas] grid;
hbm.isolas.harmonic.modal_seeds), with the seeds' Newton rule (SearchOptions.newton), one
line per converged seed off every known branch (the primary and OUT/isolas.h5's branches
in the basis of Omega; --all: every converged seed) with the LE's three leading harmonics
and the share of odd ones (the primary NFRC of rotor 67 has none), and per speed the seeds,
converged, off every known branch and CPU s: where a narrow branch is reached from.
--around A1,A2: the seeds around the primary NFRC instead, eq. (31)'s shapes with these
amplitudes added to its points at each speed ([isolas] primary_amplitudes); with --method
rl, RL's primary and RL's branches. --stall-check: then, replayed on the seeds' Newton
histories, what the seeds' stall rule (hbm.isolas.harmonic.search_options: given up once
three iterations fail to lower ||R|| tenfold) would have done with one or two iterations:
converged seeds it would have lost, and the residual evaluations of all seeds.

--from-branch METHOD/NNN: instead, the other treatment's patient Newton from every --every-th
converged point of that branch of OUT/isolas.h5, one line each as above (the known branches:
the other treatment's primary and its branches of the same basis): whether the other
treatment has that branch, or puts its orbits elsewhere.

--no-period: the sweep's points without a period (class 3) at --omegas are seeds too, the
harmonics of their last revolution (as if of period one revolution): whether such a march
wanders near a branch (where Newton from it lands).

--singular OMIN,OMAX: instead, at every other converged point of the treatment's primary NFRC
in that speed range, the smallest two and the largest singular value of its dense Jacobian
(scipy.linalg.svdvals): where Newton is slow because the root is nearly singular.
"""
from __future__ import annotations

import argparse
import contextlib
import copy
import dataclasses
import sys
import time
from pathlib import Path

import hbm  # noqa: F401  (before numpy: OpenBLAS's kernels for the host, hbm.openblas)
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main() -> None:
    from hbm.continuation.newton import newton_solve
    from hbm.isolas.harmonic import HbmProblem, modal_seeds, search_options, ti_seeds
    from hbm.isolas.membership import KnownBranch, nearest_on_polyline
    from hbm.isolas.search import lies_on_any
    from pipelines.scene import load_scene
    from pipelines.stages.isolas import _known, read_isolas
    from pipelines.stages.rom import read_rom
    from pipelines.stages.ti import read_sweep

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--scene", type=Path, default=ROOT / "scenes" / "rotor67.toml")
    ap.add_argument("--omegas", default="440,450,460,470,480,660,690,700,1350")
    ap.add_argument("--singular", default=None, help="OMIN,OMAX (rad/s): singular values along the primary")
    ap.add_argument("--method", default=None, choices=("dlft", "rl"),
                    help="--singular's treatment (default rl), --modal's (default dlft)")
    ap.add_argument("--modal", action="store_true", help="the modal seeds (eq. 31) at --omegas instead")
    ap.add_argument("--around", default=None, help="A1,A2: with --modal, the seeds around the primary instead")
    ap.add_argument("--all", action="store_true", help="with --modal, a line for every converged seed")
    ap.add_argument("--stall-check", action="store_true",
                    help="with --modal, what a stall rule of fewer iterations would have cut")
    ap.add_argument("--from-branch", default=None, metavar="METHOD/NNN",
                    help="the other treatment's Newton from every --every-th point of this branch of OUT/isolas.h5")
    ap.add_argument("--every", type=int, default=10)
    ap.add_argument("--no-period", action="store_true",
                    help="also the sweep's points without a period, from their last revolution")
    args = ap.parse_args()
    scene = load_scene(args.scene)
    if args.singular:
        singular_values(args, scene)
        return
    rom, sweep = read_rom(args.out), read_sweep(args.out)
    hbm, iso = scene.hbm, scene.isolas
    opts = search_options(hbm, iso)
    co = opts.continuation
    lo, hi = iso.omega_range(hbm)
    omegas = ({float(w) for w in np.linspace(lo, hi, iso.n_omega)} if args.omegas == "grid"
              else {float(w) for w in args.omegas.split(",")})
    found = read_isolas(args.out / "isolas.h5") if (args.out / "isolas.h5").is_file() else {}

    def known_of(method, nu):
        """The treatment's primary NFRC and its branches of OUT/isolas.h5 in the basis of Omega / nu."""
        return _known(args.out, method)[0] + [KnownBranch.of(b.omega, b.x, f"branch {b.name}", b.converged)
                                              for b in found.get(method, []) if b.subharmonic == nu]

    def distance(x, w, primary):
        return nearest_on_polyline(x, w, primary, co.x_scale, co.omega_scale)[0]

    def correct(res, solver, x0, w, known, label):
        t = time.process_time()
        primary = known[0]
        sol = newton_solve(res, x0, w, opts.model_newton, solver=copy.deepcopy(solver))
        cpu = time.process_time() - t  # the correction's alone, not the membership test's
        d, on = "-", "-"
        if sol.converged:
            d = f"{distance(sol.x, w, primary):.3g}"
            k = lies_on_any(res, sol.x, w, known, opts, copy.deepcopy(solver))
            on = known[k].label if k >= 0 else "none"
        print(f"{w:7.1f}  {label:<14} {distance(x0, w, primary):8.3g}  {str(sol.converged):<9} {sol.iterations:5d}  "
              f"{sol.residual_norm:9.2e}  {d:>8}  {cpu:5.1f}  {on}", flush=True)
        return sol

    if args.modal:
        method = args.method or "dlft"
        res, solver = HbmProblem(rom, scene.casing, scene.contact, hbm, method).for_seeds()()
        known = known_of(method, 1)
        if args.around:
            amps = tuple(float(a) for a in args.around.split(","))
            family = dataclasses.replace(iso, amplitudes=(), primary_amplitudes=amps)
        else:
            family = dataclasses.replace(iso, primary_amplitudes=())
        print("  Omega  seed                    its  LE harmonics (leading)  odd share  lies on")
        total = [0, 0, 0, 0.0]
        histories = []  # (||R|| at each iterate, converged) of every seed's Newton, with --stall-check
        for w in sorted(omegas):
            seeds = modal_seeds(res, rom, family, np.array([w]), around=tuple(known[:1]))
            conv = off = 0
            t = time.process_time()
            for sd in seeds:
                with _recorded(histories if args.stall_check else None):
                    sol = newton_solve(res, sd.x, w, opts.newton, solver=copy.deepcopy(solver))
                if not sol.converged:
                    continue
                conv += 1
                k = lies_on_any(res, sol.x, w, known, opts, copy.deepcopy(solver))
                off += k < 0
                if k < 0 or args.all:
                    a = np.abs(res.to_coefficients(sol.x)[1:, 0].reshape(-1, 2)).max(axis=1)  # LE, per harmonic
                    print(f"{w:7.1f}  {sd.origin:<22} {sol.iterations:4d}  {str(list(np.argsort(a)[::-1][:3] + 1)):<22}  "
                          f"{a[0::2].max() / a.max():9.2g}  {known[k].label if k >= 0 else 'none'}", flush=True)
            cpu = time.process_time() - t
            print(f"{w:7.1f}  {len(seeds)} seeds, {conv} converged, {off} off every known branch, CPU {cpu:.1f} s",
                  flush=True)
            total = [total[0] + len(seeds), total[1] + conv, total[2] + off, total[3] + cpu]
        print(f"all: {total[0]} seeds, {total[1]} converged, {total[2]} off every known branch, CPU {total[3]:.0f} s, "
              f"at {sum(1 for _ in omegas)} speeds", flush=True)
        if args.stall_check:
            _stall_report(histories, opts.newton)
        return
    print(f"tolerance {iso.tolerance:g} (scaled)")
    print("  Omega  correction      start-d  converged   its      ||R||  solution-d  CPU s  lies on")
    if args.from_branch:
        # the other treatment's patient Newton from every k-th converged point of a branch
        method, name = args.from_branch.split("/")
        other = "rl" if method == "dlft" else "dlft"
        (br,) = [b for b in found[method] if b.name == name]
        if br.subharmonic != hbm.subharmonic:
            raise SystemExit(f"--from-branch: {args.from_branch} is a branch of Omega / {br.subharmonic}, "
                             f"not of the scene's basis (Omega / {hbm.subharmonic})")
        res, solver = HbmProblem(rom, scene.casing, scene.contact, hbm, other)()
        known = known_of(other, br.subharmonic)
        for i in np.flatnonzero(np.asarray(br.converged, bool))[::args.every]:
            correct(res, solver, br.x[i], float(br.omega[i]), known, f"{other.upper()} from {name}")
        return
    if args.no_period:  # the points without a period taken as orbits of one revolution: their last one
        period = np.asarray(sweep.period).copy()
        period[period < 1] = 1
        sweep = dataclasses.replace(sweep, period=period)
    dlft = {}
    for method in ("dlft", "rl"):
        res, solver = HbmProblem(rom, scene.casing, scene.contact, hbm, method).for_seeds()()
        known = known_of(method, 1)
        for sd in ti_seeds(res, sweep, (lo, hi), scene.casing.n_lobes):
            if sd.omega in omegas:
                sol = correct(res, solver, sd.x, sd.omega, known, f"{method.upper()} from TI")
                if method == "dlft" and sol.converged:
                    dlft[sd.omega] = sol.x
        if method == "rl":
            for w in sorted(dlft):
                correct(res, solver, dlft[w], w, known, "RL from DLFT")


@contextlib.contextmanager
def _recorded(histories):
    """Within: each hbm.continuation.newton.newton_iterate call appends (its ||R|| at every
    iterate, converged) to histories (None: nothing recorded)."""
    import hbm.continuation.newton as nw

    if histories is None:
        yield
        return
    plain = nw.newton_iterate

    def recording(y0, linearise, options, **kw):
        norms = []

        def lin(y):
            out = linearise(y)
            norms.append(float(out[0]))
            return out

        result = plain(y0, lin, options, **kw)
        histories.append((norms, bool(result.converged)))
        return result

    nw.newton_iterate = recording
    try:
        yield
    finally:
        nw.newton_iterate = plain


def _stall_report(histories, newton) -> None:
    """What the seeds' stall rule (hbm.continuation.newton.stalled) would have done with k = 1,
    2 and the scene's k, replayed on the histories of the scene's rule: converged runs it would
    have cut, and the residual evaluations of all runs. Exact: a rule with fewer iterations
    stops a run where the scene's does or before."""
    from hbm.continuation.newton import stalled

    def evaluations(norms, k, converged):
        """(evaluations, cut): where the rule with k stops the run, and whether it does (a
        converged run's last norm passed the tolerance, which Newton tests first)."""
        last = len(norms) - 1 if converged else len(norms)
        it = next((i for i in range(last) if stalled(norms[:i + 1], k, newton.stall_factor)), None)
        return (len(norms), False) if it is None else (it + 1, True)

    n_conv = sum(1 for _, c in histories if c)
    print(f"stall rule: {n_conv} converged runs, {len(histories) - n_conv} not")
    for k in range(1, newton.stall_iterations + 1):
        runs = [(evaluations(h, k, c), c) for h, c in histories]
        cut = sum(1 for (n, stopped), c in runs if c and stopped)
        total = sum(n for (n, _), _ in runs)
        print(f"  k = {k}: cuts {cut} converged runs; residual evaluations {total}")


def singular_values(args, scene) -> None:
    import scipy.linalg as sla

    from hbm.harmonic.residual import build_residual
    from pipelines.branch_store import load_branch
    from pipelines.stages.hbm import nfrc_output
    from pipelines.stages.rom import read_rom

    lo, hi = (float(w) for w in args.singular.split(","))
    method = args.method or "rl"
    res = build_residual(read_rom(args.out), scene.casing, scene.contact, scene.hbm, method=method)
    b = load_branch(args.out / nfrc_output(method).file).branch
    print("  Omega      s_min       s_2     s_max  (points in continuation order)")
    for i in np.flatnonzero((b.omega > lo) & (b.omega < hi) & b.converged)[::2]:
        J = res(b.x[i], float(b.omega[i]))[1]
        s = sla.svdvals(J.toarray() if hasattr(J, "toarray") else np.asarray(J))
        print(f"{b.omega[i]:7.2f}  {s[-1]:9.3e} {s[-2]:9.3e} {s[0]:9.3e}", flush=True)


if __name__ == "__main__":
    main()
