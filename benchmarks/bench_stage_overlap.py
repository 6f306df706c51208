"""The NFRCs and the time-integration sweep one after the other, or on one shared pool.

    .venv/bin/python benchmarks/bench_stage_overlap.py --rom out/main/rom.h5 [--scene scenes/rotor67.toml] [--repeat 1]

One after the other: the treatments (one process each), then the sweep (one process per
core): the core of the shorter NFRC (DLFT's) idles until the longer one ends. "shared"
submits the treatments first and then the sweep's speeds (slowest first, as hbm.ti.sweep
does) to one pool of one worker per core, so a worker freed by an NFRC takes speeds (the
runner does the same with the stages' own processes: pipelines.runner._start_beside).
Both ways are timed on the same ROM and scene, alternated `--repeat` times; the
NFRCs (points, LE amplitudes) and the sweep (classes, amplitudes) must come out the same.
Nothing is written.
"""
from __future__ import annotations

import argparse
import concurrent.futures as cf
import os
import sys
import time
from pathlib import Path

import hbm  # noqa: F401  (before numpy: OpenBLAS's kernels for the host, hbm.openblas)
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def nfrc(rom, scene, method: str):
    """(method, wall s, Omega (n,) rad/s) of one treatment's NFRC, BLAS on one thread."""
    from threadpoolctl import threadpool_limits

    from hbm.harmonic.nfrc import compute_nfrc

    t = time.perf_counter()
    with threadpool_limits(limits=1, user_api="blas"):
        r = compute_nfrc(rom, scene.casing, scene.contact, scene.hbm, method=method)
    return method, time.perf_counter() - t, np.asarray(r.omega)


def run(rom, scene, shared: bool, workers: int):
    from hbm.processes import limit_blas_threads, process_context
    from hbm.ti.sweep import rom_modal_system, scheme_system, simulate

    t = scene.ti
    system = scheme_system(rom_modal_system(rom), t.scheme, t.massless_cutoff)
    omegas = t.omegas
    methods = sorted(scene.hbm.methods, key=lambda m: m != "rl")  # the longer NFRC first
    pool = lambda: cf.ProcessPoolExecutor(workers, mp_context=process_context(), initializer=limit_blas_threads)

    def speeds(p):
        return {p.submit(simulate, system, scene.casing, scene.contact.mu, omegas[i], t): i for i in np.argsort(omegas)}

    t0 = time.perf_counter()
    with pool() as p:
        curves = [p.submit(nfrc, rom, scene, m) for m in methods]
        sweep = speeds(p) if shared else {}
        ends = {f.result()[0]: (time.perf_counter() - t0, f.result()) for f in cf.as_completed(curves)}
        if shared:
            points = {sweep[f]: f.result() for f in cf.as_completed(sweep)}
    t_hbm = max(e[0] for e in ends.values())
    if not shared:
        with pool() as p:
            sweep = speeds(p)
            points = {sweep[f]: f.result() for f in cf.as_completed(sweep)}
    wall = time.perf_counter() - t0
    amp = np.array([points[i].amplitude for i in range(len(omegas))])
    cls = np.array([points[i].period_class for i in range(len(omegas))])
    return wall, t_hbm, {m: e[1] for m, e in ends.items()}, amp, cls


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rom", type=Path, required=True)
    p.add_argument("--scene", type=Path, default=ROOT / "scenes" / "rotor67.toml")
    p.add_argument("--repeat", type=int, default=1)
    args = p.parse_args(argv)

    from pipelines.scene import load_scene
    from rom.model import load_rom

    scene = load_scene(args.scene)
    rom = load_rom(args.rom)
    workers = len(os.sched_getaffinity(0))
    print(f"{scene.hbm.methods} NFRCs and {scene.ti.n_omega} speeds on {workers} workers", flush=True)
    ref = None
    for k in range(args.repeat):
        for shared in (False, True):
            wall, t_hbm, curves, amp, cls = run(rom, scene, shared, workers)
            name = "shared pool" if shared else "one after the other"
            print(f"{name:<20} total {wall:7.1f} s; NFRCs " + ", ".join(
                f"{m} {c[1]:.1f} s ({len(c[2])} points)" for m, c in curves.items())
                + f"; last NFRC ends at {t_hbm:.1f} s", flush=True)
            got = ({m: c[2] for m, c in curves.items()}, amp, cls)
            if ref is None:
                ref = got
            else:
                same = (all(np.array_equal(ref[0][m], got[0][m]) for m in ref[0]) and np.array_equal(ref[1], got[1])
                        and np.array_equal(ref[2], got[2]))
                print(f"{'':<20} the same NFRC points, sweep amplitudes and classes as the first run: {same}",
                      flush=True)


if __name__ == "__main__":
    main()
