"""Time-integration speed and accuracy (prints markdown tables).

    .venv/bin/python benchmarks/bench_ti.py [--rom ROM.h5|standin] [--repeat 3] [--full-sweep]
        [--schemes exponential,carpenter,massless] [--exponential-dt 1e-6,2e-6] [--massless-dt 1e-6,2e-6]
        [--mu 0.1,0.15] [--no-early-stop] [--sweep SCHEME:DT,...] [--sweep-against SCHEME:DT] [--scene SCENE]

1. Time per Omega point on one core, per scheme: from rest until settled or 200 revolutions
   ([ti] defaults; --no-early-stop: always 200), Carpenter at dt = 1e-7 s, the exponential
   scheme at each of --exponential-dt, massless at
   each of --massless-dt (median of --repeat runs, CPU time of this process, so that other
   users' load counts less); ns per step, share of steps in contact, revolutions marched,
   the class and its non-repeat (the Poincare sections' mismatch at the period found,
   relative to their range: hbm.ti.periodicity; --revolutions N,...: each N marched in full);
   for each friction coefficient of --mu (default [contact] mu; the header gives the ROM's
   mu_set, above which a massless contact node can lock, rom.friction_lock). --casing
   table,law: each point with the casing profile tabulated over a casing period (the
   default, hbm.ti.march.casing_profile) and with eq. (28) evaluated at every step,
   alternated run by run in this process.
2. Speed against error: LE amplitude at a few Omega, Carpenter for dt in {4e-7, 2e-7, 1e-7,
   5e-8, 2.5e-8}, the exponential scheme for dt in {1e-6, 5e-7, 2.5e-7, 1.25e-7} (with
   --schemes ...exponential...); the error is taken against Carpenter's Richardson
   extrapolation to dt = 0 from 5e-8 and 2.5e-8, 2 A(2.5e-8) - A(5e-8) (its error is O(dt)),
   where both have the class of 2.5e-8, else against 2.5e-8 (responses can be chaotic: a
   difference there is a different trajectory, not a discretisation error).
3. --full-sweep: the whole 161-point sweep with all cores (wall time; per-speed wall time in
   its worker, which is its CPU time when no more processes run than cores); per class, the
   speeds that ran every revolution (no early stop can shorten those) and their CPU share.
   --compare-full: then the same sweep again with stop_when_settled = false (always 200
   revolutions): per class, the revolutions the early stop needed, whether every point kept
   the class of the full run, and the largest LE amplitude difference. --sweep SCHEME:DT,...:
   the sweeps' schemes and steps (default: [ti]'s; the first one is --compare-full's).
   --sweep-against SCHEME:DT: then the same sweep with that scheme and step, once, and each
   --sweep compared with it (per class of this sweep). The line of each sweep also counts
   its contact steps that hit the active set's cap and those whose friction direction did
   not settle (hbm.ti.sweep.SweepResult), with each such speed's share of its contact steps.
4. --scene SCENE: the casing, [contact] and [ti] of a scene instead of the defaults (rotor
   67's), e.g. scenes/rotor37.toml with its ROM: its lobes, speed range and grid.
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from contextlib import contextmanager
from pathlib import Path

from dataclasses import replace

import hbm  # noqa: F401  (before numpy: OpenBLAS's kernels for the host, hbm.openblas)
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
    ap.add_argument("--schemes", default="carpenter", help="comma-separated, among exponential, carpenter, massless")
    ap.add_argument("--exponential-dt", default="1e-6", help="time steps of the exponential scheme, s, "
                                                             "comma-separated")
    ap.add_argument("--sweep", default="", help="--full-sweep with this SCHEME:DT (default: [ti]'s)")
    ap.add_argument("--sweep-against", default="", help="--full-sweep: then with this SCHEME:DT, and compare")
    ap.add_argument("--massless-dt", default="1e-6", help="time steps of the massless scheme, s, comma-separated")
    ap.add_argument("--mu", default="", help="friction coefficients of the per-speed table, comma-separated "
                                             "(default: [contact] mu)")
    ap.add_argument("--no-early-stop", action="store_true", help="always n_revolutions (the old behaviour)")
    ap.add_argument("--revolutions", default="", help="per-speed table: these n_revolutions, comma-separated, each "
                                                      "marched in full (no early stop), e.g. 50,100,200")
    ap.add_argument("--sweep-points", type=int, default=None, help="--full-sweep on this many speeds of the grid")
    ap.add_argument("--compare-full", action="store_true",
                    help="--full-sweep: also run it without the early stop and compare class and amplitude")
    ap.add_argument("--casing", default="table",
                    help="per-speed table: how the march finds the casing, comma-separated among table and law")
    ap.add_argument("--scene", default="", help="casing, contact and [ti] options of this scene (default: the "
                                                "defaults, rotor 67's), e.g. scenes/rotor37.toml")
    a = ap.parse_args()
    rom, label = load_rom(a.rom)
    system = rom_modal_system(rom)
    cas, con = CasingOptions(), ContactOptions()
    opts = TimeIntegrationOptions(stop_when_settled=not a.no_early_stop)
    if a.scene:
        from pipelines.scene import load_scene

        scene = load_scene(a.scene)
        cas, con = scene.casing, scene.contact
        opts = replace(scene.ti, stop_when_settled=not a.no_early_stop)
    schemes = a.schemes.split(",")
    omegas = [float(w) for w in a.omegas.split(",") if w]  # "" for none (e.g. --full-sweep alone)
    simulate(system, cas, con.mu, 2000.0, TimeIntegrationOptions(n_revolutions=2, n_keep=1))  # JIT / cache
    lock = getattr(rom, "friction_lock", None)
    print(f"ROM: {label}; {os.cpu_count()} cores; load average {os.getloadavg()[0]:.1f}"
          f"{f'; mu_set {lock.mu_set:.3g}' if lock is not None else ''}\n")
    print("| mu | scheme | Omega (rad/s) | dt (s) | steps | CPU time per point (s), median | ns/step | contact steps "
          "| revolutions | LE amplitude (m) | class | non-repeat |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    mus = [float(m) for m in a.mu.split(",")] if a.mu else [con.mu]
    runs = [("carpenter", 1e-7)] if "carpenter" in schemes else []
    runs += [("exponential", float(dt)) for dt in a.exponential_dt.split(",") if "exponential" in schemes]
    runs += [("massless", float(dt)) for dt in a.massless_dt.split(",") if "massless" in schemes]
    revs = [int(n) for n in a.revolutions.split(",")] if a.revolutions else [None]
    for mu, w, (scheme, dt), n in ((m, w, r, n) for m in mus for w in omegas for r in runs for n in revs):
        ropts = replace(opts, scheme=scheme, dt=dt)
        if n is not None:
            ropts = replace(ropts, n_revolutions=n, stop_when_settled=False)
        modes = a.casing.split(",")
        ts, res = {c: [] for c in modes}, {}
        for _ in range(a.repeat):
            for c in modes:
                with _casing(c):  # the speed's CPU time, numba's compile left out
                    res[c] = simulate(system, cas, mu, w, ropts)
                    ts[c].append(res[c].cpu_time)
        for c in modes:
            r, med = res[c], statistics.median(ts[c])
            steps = round(r.revolutions * 2 * np.pi / (w * r.dt))
            label = f"{scheme} ({c})" if len(modes) > 1 else scheme
            print(f"| {mu:g} | {label} | {w:.0f} | {r.dt:.3g} | {steps:.3e} | {med:.2f} | "
                  f"{1e9 * med / steps:.0f} | {r.contact_fraction:.2f} | {r.revolutions} | {r.amplitude:.4e} | "
                  f"{r.period_class} | {r.mismatch:.1e} |", flush=True)
    print()
    if not a.skip_dt:
        # error against Carpenter extrapolated to dt = 0 for every scheme (the massless one is another model)
        runs = [("carpenter", dt) for dt in (4e-7, 2e-7, 1e-7, 5e-8, 2.5e-8)]
        if "exponential" in schemes:
            runs += [("exponential", dt) for dt in (1e-6, 5e-7, 2.5e-7, 1.25e-7)]
        if "massless" in schemes:
            runs += [("massless", dt) for dt in (5e-6, 2e-6, 1e-6, 1e-7)]
        print("| Omega (rad/s) | scheme | dt (s) | CPU time (s) | revolutions | LE amplitude (m) "
              "| vs the reference | class |")
        print("|---|---|---|---|---|---|---|---|")
        for w in omegas:
            res = {}
            for scheme, dt in runs:
                r = simulate(system, cas, con.mu, w, replace(opts, scheme=scheme, dt=dt))
                res[scheme, dt] = (r.cpu_time, r)
            fine, half = res["carpenter", 2.5e-8][1], res["carpenter", 5e-8][1]
            same = fine.period_class == half.period_class
            ref = 2.0 * fine.amplitude - half.amplitude if same else fine.amplitude
            print(f"| {w:.0f} | reference: {'Carpenter extrapolated to dt = 0' if same else 'Carpenter 2.5e-8'} "
                  f"| | | | {ref:.5e} | | {fine.period_class} |")
            for scheme, dt in runs:
                t, r = res[scheme, dt]
                print(f"| {w:.0f} | {scheme} | {dt:.1e} | {t:.2f} | {r.revolutions} | {r.amplitude:.5e} | "
                      f"{abs(r.amplitude - ref) / ref:.2e} | {r.period_class} |", flush=True)
    if a.full_sweep:
        from pipelines.stages.ti import fallback_shares

        grid = np.linspace(opts.omega_min, opts.omega_max, a.sweep_points or opts.n_omega)
        labels = dict(n_lobes=cas.n_lobes, max_order=opts.classified_order(cas.n_lobes))  # the classes' names
        done = []  # (options, SweepResult, wall s) of each --sweep
        for text in a.sweep.split(",") if a.sweep else [""]:
            t0 = time.perf_counter()
            sopts = _scheme_dt(opts, text)
            s = sweep(system, cas, con, sopts, omegas=grid)
            wall = time.perf_counter() - t0
            done.append((sopts, s, wall))
            print(f"\nFull sweep ({sopts.scheme}, dt = {sopts.dt:g} s): {len(s.omega)} points in {wall:.0f} s wall "
                  f"({wall / 60:.1f} min), "
                  f"classes {np.bincount(s.period_class, minlength=5).tolist()} (casing, Omega, sub, none, super); "
                  f"per speed: median {np.median(s.cpu_time):.2f} s, max {s.cpu_time.max():.2f} s, "
                  f"{int((s.cpu_time > 5.0).sum())} over 5 s {_over(s, 5.0)}, sum {s.cpu_time.sum():.0f} s; "
                  f"contact steps capped {int(s.active_set_failures.sum())}, with the prediction's direction "
                  f"{int(s.explicit_direction_steps.sum())} (at {int((s.explicit_direction_steps > 0).sum())} speeds"
                  + "".join(f"; {s.omega[i]:.0f} rad/s {s.explicit_direction_steps[i]}, share of its contact steps "
                            f"{fallback_shares(s)[i]:.1e}" for i in np.flatnonzero(s.explicit_direction_steps > 0))
                  + ")")
            _split(s, opts.n_revolutions, labels)
        if a.compare_full:
            sopts, s, wall = done[0]
            t0 = time.perf_counter()
            f = sweep(system, cas, con, replace(sopts, stop_when_settled=False), omegas=grid)
            wall_f = time.perf_counter() - t0
            print(f"Without the early stop: {wall_f:.0f} s wall, per-speed sum {f.cpu_time.sum():.0f} s; "
                  f"ratio {wall / wall_f:.2f} (wall), {s.cpu_time.sum() / f.cpu_time.sum():.2f} (sum)\n")
            _compare(s, f, labels)
        if a.sweep_against:
            t0 = time.perf_counter()
            oopts = _scheme_dt(replace(opts, scheme="carpenter", dt=1e-7), a.sweep_against)
            f = sweep(system, cas, con, oopts, omegas=grid)
            wall_f = time.perf_counter() - t0
            print(f"Against {oopts.scheme}, dt = {oopts.dt:g} s: {wall_f:.0f} s wall, per-speed sum "
                  f"{f.cpu_time.sum():.0f} s, classes {np.bincount(f.period_class, minlength=5).tolist()}")
            for sopts, s, wall in done:
                print(f"\n{sopts.scheme}, dt = {sopts.dt:g} s against it: ratio {wall / wall_f:.2f} (wall), "
                      f"{s.cpu_time.sum() / f.cpu_time.sum():.2f} (sum)\n")
                _compare_schemes(s, f, labels)

def _compare_schemes(new, ref, labels):
    """Per class of the reference sweep: speeds, those the first sweep puts in the same class,
    and over those the LE amplitude difference (median and largest) and the revolutions; labels:
    PeriodClass.label's arguments (the casing's lobes name its class)."""
    from hbm.ti.periodicity import PeriodClass

    print("| class (second sweep) | speeds | same class | LE amplitude difference, same class: median, max "
          "| revolutions, median: first, second |")
    print("|---|---|---|---|---|")
    for code in PeriodClass:
        sel = ref.period_class == code
        if not sel.any():
            continue
        same = sel & (new.period_class == code)
        rel = np.abs(new.amplitude[same] / ref.amplitude[same] - 1.0)
        diff = f"{np.median(rel):.1e}, {rel.max():.1e}" if same.any() else "-"
        print(f"| {code.label(**labels)} | {int(sel.sum())} | {int(same.sum())} | {diff} | "
              f"{np.median(new.revolutions[sel]):.0f}, {np.median(ref.revolutions[sel]):.0f} |")
    # the LE's mean normal force over the kept window, at the periodic speeds of the same class
    per = (new.period_class == ref.period_class) & (ref.period_class != PeriodClass.NONE)
    f_new, f_ref = new.normal_force[:, :, 0].mean(axis=1), ref.normal_force[:, :, 0].mean(axis=1)
    sel = per & (f_ref > 0)
    if sel.any():
        rel = np.abs(f_new[sel] / f_ref[sel] - 1.0)
        print(f"\nLE mean contact force, periodic speeds of the same class ({int(sel.sum())}): difference median "
              f"{np.median(rel):.1e}, 95 % {np.quantile(rel, 0.95):.1e}, max {rel.max():.1e}")
    moved = np.flatnonzero(new.period_class != ref.period_class)
    print("\nclass changed at " + (", ".join(f"{new.omega[i]:.0f} ({ref.period_class[i]} -> "
                                              f"{new.period_class[i]})" for i in moved) or "no speed"))


def _scheme_dt(opts, text: str):
    """opts with the scheme and time step of "SCHEME:DT" ("" keeps them)."""
    if not text:
        return opts
    scheme, dt = text.split(":")
    return replace(opts, scheme=scheme, dt=float(dt))


@contextmanager
def _casing(mode: str):
    """Marches made inside find the casing by its table over a casing period ("table", the
    default) or by eq. (28) at every step ("law": no profile is tabulated)."""
    from hbm.ti import march

    if mode not in ("table", "law"):
        raise SystemExit(f"--casing: unknown mode {mode!r}; known: table, law")
    kept = march.PROFILE_MAX_ENTRIES
    march.PROFILE_MAX_ENTRIES = kept if mode == "table" else 0
    try:
        yield
    finally:
        march.PROFILE_MAX_ENTRIES = kept


def _split(s, n_revolutions: int, labels):
    """Per class: speeds, those that ran all n_revolutions, and their share of the
    per-speed CPU sum (a speed with no period never stops early: its cost is a floor)."""
    from hbm.ti.periodicity import PeriodClass

    full = s.revolutions >= n_revolutions
    print("\n| class | speeds | ran every revolution | CPU s (of which those) | share of the sum |")
    print("|---|---|---|---|---|")
    for code in PeriodClass:
        sel = s.period_class == code
        if sel.any():
            print(f"| {code.label(**labels)} | {int(sel.sum())} | {int((sel & full).sum())} | {s.cpu_time[sel].sum():.1f} "
                  f"({s.cpu_time[sel & full].sum():.1f}) | {s.cpu_time[sel].sum() / s.cpu_time.sum():.0%} |")
    print()


def _over(s, limit):
    return "(" + ", ".join(f"{w:.0f} rad/s {t:.1f} s" for w, t in zip(s.omega, s.cpu_time) if t > limit) + ")"


def _compare(early, full, labels):
    """Per class of the full run: speeds, revolutions of the early stop, class kept, LE amplitude."""
    from hbm.ti.periodicity import PeriodClass

    print("| class (200 revolutions) | speeds | stopped early | revolutions when stopped: median (min-max) "
          "| class kept | largest LE amplitude difference |")
    print("|---|---|---|---|---|---|")
    for code in PeriodClass:
        sel = full.period_class == code
        if not sel.any():
            continue
        stop = sel & (early.revolutions < full.revolutions)
        revs = early.revolutions[stop]
        kept = int((early.period_class[sel] == code).sum())
        rel = np.abs(early.amplitude[sel] / full.amplitude[sel] - 1.0)
        spread = f"{np.median(revs):.0f} ({revs.min()}-{revs.max()})" if len(revs) else "-"
        print(f"| {code.label(**labels)} | {int(sel.sum())} | {int(stop.sum())} | {spread} | {kept} of {int(sel.sum())} "
              f"| {rel.max():.1e} |")


if __name__ == "__main__":
    main()
