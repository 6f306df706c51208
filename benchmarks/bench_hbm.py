"""Benchmark of the HBM NFRC: time of a whole NFRC for DLFT and RL, and speed vs error.

Usage:
  .venv/bin/python benchmarks/bench_hbm.py [--rom out/.../rom.h5] [--repeat 3]
      [--penetration 1.25e-4] [--table] [--nh 10 20 40 60] [--nt 256 512 1024 2048]
      [--methods dlft rl] [--no-default] [--stability {off,on,both}] [--iter-reject {8,none}]
  .venv/bin/python benchmarks/bench_hbm.py --stage [--scene scenes/rotor67_coarse.toml] [--rom ...] [--repeat 2]

Without --rom the 39-dof stand-in of tests/support.py is used (not a blade: figures
exercise the code paths only). Prints markdown tables: median wall time per method, and
for the table the time of each (N_h, N_t) NFRC with the LE amplitude error against the
finest setting: the error of the max LE amplitude over the NFRC, and the max over a
common omega grid of |A - A_ref| / max A_ref (interpolated along omega on the monotone
envelope of each branch: a rough figure on the multi-valued rotor 67 NFRC, where a fold
drawn a little earlier or later gives a large local difference). --no-default skips the N_h = 40, N_t = 1024 runs.
--stability on: the NFRC with Floquet stability and bifurcations (hbm.stability); both:
each repeat runs without, then with (alternating, so that the machine's load hits both
alike), and the table gives both medians, the stability monitor's own time, the analyses,
and the bifurcations found.
--iter-reject: the continuation's corrector iteration cap (ContinuationOptions.iter_reject;
default: default_continuation's), "none" for no cap.
--stage: the hbm stage itself on a scene (default the coarse rotor 67 scene with the ROM of
tests/data), its treatments one after the other in this process and then at once in one
process each (its default), alternated --repeat times; wall time, CPU time (this process
and its children) and the points of each NFRC.
"""
from __future__ import annotations

import argparse
import statistics
import sys
from pathlib import Path

import hbm  # noqa: F401  (before numpy: OpenBLAS's kernels for the host, hbm.openblas)
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

from hbm.harmonic.nfrc import compute_nfrc, default_continuation  # noqa: E402
from hbm.options import CasingOptions, ContactOptions, HbmOptions  # noqa: E402


def load(path: str | None):
    """The ROM of a rom.h5 file, or the stand-in without one."""
    if path is None:
        from support import standin_rom
        return standin_rom()
    from rom.model import load_rom
    return load_rom(path)


def run(rom, method, nh, nt, casing, stability=False, cap="default"):
    """One NFRC; cap: the corrector iteration cap (--iter-reject), "default" for
    default_continuation's."""
    from dataclasses import replace

    hbm = HbmOptions(n_harmonics=nh, n_time=nt)
    co = None if cap == "default" else replace(default_continuation(hbm), iter_reject=None if cap == "none" else int(cap))
    return compute_nfrc(rom, casing, ContactOptions(), hbm, method, stability=stability, continuation=co)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--rom")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--penetration", type=float, default=CasingOptions().penetration)
    ap.add_argument("--table", action="store_true")
    ap.add_argument("--no-default", dest="default", action="store_false",
                    help="skip the N_h = 40, N_t = 1024 runs (table only)")
    ap.add_argument("--nh", type=int, nargs="+", default=[10, 20, 40, 60])
    ap.add_argument("--nt", type=int, nargs="+", default=[256, 512, 1024, 2048])
    ap.add_argument("--methods", nargs="+", default=["dlft", "rl"])
    ap.add_argument("--stability", choices=["off", "on", "both"], default="off")
    ap.add_argument("--stage", action="store_true", help="time the hbm stage, serial against concurrent")
    ap.add_argument("--scene", default=str(ROOT / "scenes" / "rotor67_coarse.toml"))
    ap.add_argument("--iter-reject", default="default", help="corrector iteration cap: an integer or none")
    a = ap.parse_args()
    if a.stage:
        stage_table(a)
        return
    rom = load(a.rom)
    casing = CasingOptions(penetration=a.penetration)
    print(f"ROM: {a.rom or 'stand-in'}; casing penetration {a.penetration:g} m\n")
    if a.stability != "off" and a.default:
        stability_table(rom, a, casing)
        return
    print("| method | N_h | N_t | median wall (s) | points | omega covered (rad/s) | peak LE amp (mm) at Omega "
          "| factorisations | status |")
    print("|---|---|---|---|---|---|---|---|---|")
    for m in a.methods if a.default else ():
        runs = [run(rom, m, 40, 1024, casing, cap=a.iter_reject) for _ in range(a.repeat)]
        r = runs[-1]
        i = int(np.argmax(r.le_amplitude))
        print(f"| {m} | 40 | 1024 | {statistics.median(x.wall_time for x in runs):.1f} | {len(r.omega)} | "
              f"{r.omega.min():.0f}-{r.omega.max():.0f} | {1e3 * r.le_amplitude[i]:.3f} at {r.omega[i]:.0f} | "
              f"{r.n_factorizations} | {r.status[:60]} |", flush=True)
    if not a.table:
        return
    for m in a.methods:
        res = {}
        for nh in a.nh:  # one line per cell as it finishes (the whole table takes long)
            for nt in a.nt:
                if nt >= 2 * nh + 2:
                    r = res[(nh, nt)] = run(rom, m, nh, nt, casing, cap=a.iter_reject)
                    i = int(np.argmax(r.le_amplitude))
                    print(f"  {m} N_h={nh} N_t={nt}: {r.wall_time:.1f} s, {len(r.omega)} points, max LE amplitude "
                          f"{1e3 * r.le_amplitude[i]:.4f} mm at {r.omega[i]:.1f} rad/s, {r.status}", flush=True)
        ref = res[(max(a.nh), max(a.nt))]
        grid = np.linspace(ref.omega.min(), ref.omega.max(), 400)

        def curve(r):
            o, amp = (r.omega, r.le_amplitude) if r.omega[-1] >= r.omega[0] else (r.omega[::-1], r.le_amplitude[::-1])
            o = np.maximum.accumulate(o)  # monotone envelope: ignores fold overhangs
            return np.interp(grid, o, amp, left=np.nan, right=np.nan)

        A_ref = curve(ref)
        peak_ref = ref.le_amplitude.max()
        print(f"\n{m}: time of the whole NFRC (s) / error of the max LE amplitude over the NFRC / max error "
              f"along the curve (both relative to the max of N_h={max(a.nh)}, N_t={max(a.nt)})\n")
        print("| N_h \\ N_t | " + " | ".join(str(nt) for nt in a.nt) + " |")
        print("|---" * (len(a.nt) + 1) + "|")
        for nh in a.nh:
            cells = []
            for nt in a.nt:
                r = res.get((nh, nt))
                if r is None:
                    cells.append("-")
                    continue
                err = np.nanmax(np.abs(curve(r) - A_ref)) / peak_ref
                perr = abs(r.le_amplitude.max() - peak_ref) / peak_ref
                cells.append(f"{r.wall_time:.1f} / {perr:.1e} / {err:.1e}")
            print(f"| {nh} | " + " | ".join(cells) + " |", flush=True)


def stability_table(rom, a, casing):
    """N_h = 40, N_t = 1024 NFRCs with stability (and without, for --stability both)."""
    print("| method | median wall without (s) | median wall with (s) | added | monitor time (s) | analyses "
          "| points | bifurcations |")
    print("|---|---|---|---|---|---|---|---|")
    for m in a.methods:
        off, on = [], []
        for _ in range(a.repeat):
            if a.stability == "both":
                off.append(run(rom, m, 40, 1024, casing, False, a.iter_reject))
            on.append(run(rom, m, 40, 1024, casing, True, a.iter_reject))
            print(f"  {m}: without {off[-1].wall_time if off else float('nan'):.1f} s, with {on[-1].wall_time:.1f} s "
                  f"(monitor {on[-1].stability_time:.1f} s, {on[-1].n_stability_analyses} analyses)", flush=True)
        t_off = statistics.median(r.wall_time for r in off) if off else float("nan")
        t_on = statistics.median(r.wall_time for r in on)
        r = on[-1]
        kinds = {}
        for b in r.bifurcations:
            kinds[b.kind] = kinds.get(b.kind, 0) + 1
        print(f"| {m} | {t_off:.1f} | {t_on:.1f} | {100 * (t_on / t_off - 1):.0f} % | "
              f"{statistics.median(x.stability_time for x in on):.1f} | {r.n_stability_analyses} | {len(r.omega)} | "
              + ", ".join(f"{v} {k}" for k, v in sorted(kinds.items())) + " |", flush=True)
        for b in r.bifurcations:
            print(f"    {b.kind:16s} Omega = {b.omega:8.2f} rad/s (bracket {min(b.omega_bracket):.2f}-"
                  f"{max(b.omega_bracket):.2f}), LE amplitude {1e3 * b.le_amplitude:.3f} mm, |mu| = "
                  f"{abs(b.multiplier):.3f}, {'loses' if b.direction > 0 else 'gains'} stability", flush=True)


def stage_table(a):
    """The hbm stage (pipelines.stages.hbm) with workers=1 and its default, alternated."""
    import resource
    import shutil
    import tempfile
    import time

    from pipelines.branch_store import load_branch
    from pipelines.progress import Progress
    from pipelines.runner import expected_inputs
    from pipelines.scene import load_scene
    from pipelines.stages import REGISTRY, hbm
    from pipelines.stages.base import Context

    scene = load_scene(Path(a.scene))
    outputs = REGISTRY["hbm"].outputs(scene)
    expected = expected_inputs(scene, ("hbm",))
    rows = {"serial": [], "concurrent": []}
    print(f"scene {a.scene}, ROM {a.rom or 'tests/data/rotor67_coarse_rom.h5'}\n")
    for _ in range(a.repeat):
        for mode, workers in (("serial", 1), ("concurrent", None)):
            with tempfile.TemporaryDirectory(prefix="bench-hbm-stage-") as tmp:
                out = Path(tmp)
                shutil.copy(a.rom or ROOT / "tests" / "data" / "rotor67_coarse_rom.h5", out / "rom.h5")
                ctx = Context(scene, out, Progress(quiet=True))
                for o in outputs:
                    ctx.inputs[o.file], ctx.hashes[o.file] = expected[o.file]
                before = resource.getrusage(resource.RUSAGE_CHILDREN)
                c0, t0 = time.process_time(), time.perf_counter()
                hbm._compute(ctx, outputs, workers)
                wall, cpu = time.perf_counter() - t0, time.process_time() - c0
                after = resource.getrusage(resource.RUSAGE_CHILDREN)
                cpu += (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
                points = [len(load_branch(out / o.file).branch.omega) for o in outputs]
            rows[mode].append((wall, cpu, points))
            print(f"  {mode}: {wall:.1f} s wall, {cpu:.1f} s CPU, points {points}", flush=True)
    print("\n| run | wall (s), each repeat | median wall (s) | CPU (s), median | points per treatment |")
    print("|---|---|---|---|---|")
    for mode, r in rows.items():
        print(f"| {mode} | {', '.join(f'{w:.1f}' for w, _, _ in r)} | {statistics.median(w for w, _, _ in r):.1f} | "
              f"{statistics.median(c for _, c, _ in r):.1f} | {r[-1][2]} |")
    ratio = statistics.median(w for w, _, _ in rows["concurrent"]) / statistics.median(w for w, _, _ in rows["serial"])
    print(f"\nconcurrent / serial wall: {ratio:.2f}")


if __name__ == "__main__":
    main()
