"""Time-integration speed and accuracy (prints markdown tables).

    .venv/bin/python benchmarks/bench_ti.py [--rom ROM.h5|standin] [--repeat 3] [--full-sweep]

1. Time per Omega point on one core: 200 revolutions at dt = 1e-7 s from rest (median of
   --repeat runs, CPU time of this process, so that other users' load counts less).
2. Speed against error: LE amplitude at a few Omega for dt in {4e-7, 2e-7, 1e-7, 5e-8}; the
   error is taken against dt = 5e-8 (responses can be chaotic: a difference there is a
   different trajectory, not a discretisation error).
3. --full-sweep: the whole 161-point sweep with all cores (wall time).
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

from hbm.options import CasingOptions, ContactOptions, TimeIntegrationOptions  # noqa: E402
from hbm.ti.sweep import simulate, sweep  # noqa: E402
from hbm.ti.march import rom_modal_system  # noqa: E402


def load_rom(name):
    if name == "standin":
        from support import standin_rom
        return standin_rom(), "stand-in (tests/support.py)"
    from rom.model import load_rom as _load  # the ROM stage's reader (h5py only)
    return _load(name), name


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--rom", default="standin")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--omegas", default="400,1000,2000")
    ap.add_argument("--full-sweep", action="store_true")
    ap.add_argument("--skip-dt", action="store_true")
    a = ap.parse_args()
    rom, label = load_rom(a.rom)
    system = rom_modal_system(rom)
    cas, con = CasingOptions(), ContactOptions()
    opts = TimeIntegrationOptions()
    omegas = [float(w) for w in a.omegas.split(",")]
    simulate(system, cas, con.mu, 2000.0, TimeIntegrationOptions(n_revolutions=2, n_keep=1))  # JIT / cache
    print(f"ROM: {label}; {os.cpu_count()} cores; load average {os.getloadavg()[0]:.1f}\n")
    print("| Omega (rad/s) | steps | CPU time per point (s), median | ns/step | contact steps | LE amplitude (m) | class |")
    print("|---|---|---|---|---|---|---|")
    per_point = {}
    for w in omegas:
        ts, r = [], None
        for _ in range(a.repeat):
            t0 = time.process_time()
            r = simulate(system, cas, con.mu, w, opts)
            ts.append(time.process_time() - t0)
        steps = round(opts.n_revolutions * 2 * np.pi / (w * r.dt))
        med = statistics.median(ts)
        per_point[w] = med
        print(f"| {w:.0f} | {steps:.3e} | {med:.2f} | {1e9 * med / steps:.0f} | {r.contact_fraction:.2f} | "
              f"{r.amplitude:.4e} | {r.period_class} |")
    # cost of a point ~ steps ~ 1 / Omega: average over the default grid from the measured ns/step
    grid = np.linspace(opts.omega_min, opts.omega_max, opts.n_omega)
    ns = statistics.median(1e9 * per_point[w] * w / (opts.n_revolutions * 2 * np.pi / 1e-7) for w in omegas)
    total = (ns * 1e-9 * opts.n_revolutions * 2 * np.pi / (grid * 1e-7)).sum()
    print(f"\nExtrapolated (not measured): mean {total / len(grid):.2f} s per point over the {len(grid)}-point grid, "
          f"{total:.0f} s CPU for the sweep, {total / 2 / 60:.1f} min on 2 free cores.\n")
    if not a.skip_dt:
        dts = [4e-7, 2e-7, 1e-7, 5e-8]
        print("| Omega (rad/s) | dt (s) | CPU time (s) | LE amplitude (m) | vs dt = 5e-8 | class |")
        print("|---|---|---|---|---|---|")
        for w in omegas:
            res = {}
            for dt in dts:
                t0 = time.process_time()
                r = simulate(system, cas, con.mu, w, TimeIntegrationOptions(dt=dt))
                res[dt] = (time.process_time() - t0, r)
            ref = res[5e-8][1].amplitude
            for dt in dts:
                t, r = res[dt]
                print(f"| {w:.0f} | {dt:.0e} | {t:.2f} | {r.amplitude:.5e} | {abs(r.amplitude - ref) / ref:.2e} | "
                      f"{r.period_class} |")
    if a.full_sweep:
        t0 = time.perf_counter()
        s = sweep(system, cas, con, opts)
        wall = time.perf_counter() - t0
        print(f"\nFull sweep: {len(s.omega)} points in {wall:.0f} s wall ({wall / 60:.1f} min), "
              f"classes {np.bincount(s.period_class, minlength=5).tolist()} (casing, Omega, sub, none, super)")


if __name__ == "__main__":
    main()
