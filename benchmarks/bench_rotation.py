"""The NFRC of one ROM turning both ways: rotation sense s = +1 and s = -1 side by side.

Usage:
  .venv/bin/python benchmarks/bench_rotation.py [--rom tests/data/rotor67_coarse_rom.h5]
      [--methods dlft rl] [--nh 40] [--nt 1024] [--mu 0.15] [--ti 41] [--save DIR]
      [--png rotation.png]

Runs compute_nfrc for each method and each sense on the same ROM (its `rotation` replaced),
prints a markdown table per run (wall time, points, status, largest LE amplitude and where,
the amplitude's median over the branch, the share of points whose LE stays in contact over
the whole period with an amplitude within 1 % of (c + p) / 2: the blade locked on the
casing, following its profile); with --ti N also the time-integration sweep from rest at N
speeds (the paper's Fig. 5: 200 revolutions, dt = 1e-7 s) and, per sense, how many speeds
end locked (LE amplitude within 1 % of (c + p) / 2); then draws the two NFRCs side by side
on one amplitude scale with the sweep's points. --save keeps the curves (npz) for --replot.
"""
from __future__ import annotations

import argparse
import dataclasses
import sys
import tempfile
import time
from pathlib import Path

import hbm  # noqa: F401  (before numpy: OpenBLAS's kernels for the host, hbm.openblas)
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from hbm.harmonic.nfrc import compute_nfrc  # noqa: E402
from hbm.harmonic.residual import build_residual  # noqa: E402
from hbm.options import CasingOptions, ContactOptions, HbmOptions  # noqa: E402
from rom.model import load_rom  # noqa: E402


def locked_share(rom, casing, contact, hbm, method, result) -> tuple[np.ndarray, np.ndarray]:
    """Per converged point: the share of the period the LE is in contact (lam > 0), and
    whether it is locked (in contact all period, amplitude within 1 % of (c + p) / 2)."""
    res = build_residual(rom, casing, contact, hbm, method=method)
    half = 0.5 * (casing.clearance + casing.penetration)
    share = np.full(len(result.omega), np.nan)
    for i in np.flatnonzero(result.converged):
        smp = res.samples(result.harmonics[i], float(result.omega[i]))
        share[i] = float(np.mean(smp.lam[:, 0] > 0.0))
    locked = (share >= 1.0) & (np.abs(result.le_amplitude - half) <= 0.01 * half)
    return share, locked


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--rom", default=str(ROOT / "tests" / "data" / "rotor67_coarse_rom.h5"))
    ap.add_argument("--methods", nargs="+", default=["dlft", "rl"])
    ap.add_argument("--nh", type=int, default=40)
    ap.add_argument("--nt", type=int, default=1024)
    ap.add_argument("--mu", type=float, default=ContactOptions().mu)
    ap.add_argument("--omega-min", type=float, default=400.0)
    ap.add_argument("--omega-max", type=float, default=2000.0)
    ap.add_argument("--ti", type=int, default=0, help="speeds of a time-integration sweep per sense (0: none)")
    ap.add_argument("--save", default=None, help="folder for the curves (npz); default: a temporary one")
    ap.add_argument("--replot", action="store_true", help="draw from the curves in --save, compute nothing")
    ap.add_argument("--png", default="rotation_senses.png")
    a = ap.parse_args()
    rom0 = load_rom(a.rom)
    casing, contact = CasingOptions(), ContactOptions(mu=a.mu)
    hbm = HbmOptions(methods=tuple(a.methods), n_harmonics=a.nh, n_time=a.nt, omega_min=a.omega_min,
                     omega_max=a.omega_max)
    half = 0.5 * (casing.clearance + casing.penetration)
    print(f"ROM: {a.rom} (rotation stored: {rom0.rotation:+d}); N_h = {a.nh}, N_t = {a.nt}, mu = {a.mu}; "
          f"(c + p) / 2 = {1e3 * half:.4f} mm\n")
    print("| s | method | wall (s) | points (converged) | status | max LE amp (mm) at Omega | median LE amp (mm) "
          "| points locked on the casing | median LE contact share |")
    print("|---|---|---|---|---|---|---|---|---|")
    panels = []
    tmp = Path(a.save) if a.save else Path(tempfile.mkdtemp())
    tmp.mkdir(parents=True, exist_ok=True)
    if a.replot:
        for s in (1, -1):
            label = "plus" if s > 0 else "minus"
            curves = {}
            for m in a.methods:
                d = np.load(tmp / f"nfrc_{m}_{label}.npz")
                curves[f"{m.upper()}-HBM"] = (d["omega"], d["amp"], d["converged"])
            ti = np.load(tmp / f"ti_{label}.npz") if (tmp / f"ti_{label}.npz").is_file() else None
            panels.append((_title(rom0, s), curves, None if ti is None else (ti["omega"], ti["amp"], ti["cls"])))
        draw_panels(panels, a.png, (a.omega_min, a.omega_max), half)
        return
    for s in (1, -1):
        rom = dataclasses.replace(rom0, rotation=s)
        curves = {}
        for m in a.methods:
            r = compute_nfrc(rom, casing, contact, hbm, m)
            share, locked = locked_share(rom, casing, contact, hbm, m, r)
            amp = np.where(r.converged, r.le_amplitude, np.nan)
            i = int(np.nanargmax(amp))
            print(f"| {s:+d} | {m} | {r.wall_time:.1f} | {len(r.omega)} ({int(r.converged.sum())}) | {r.status} | "
                  f"{1e3 * amp[i]:.3f} at {r.omega[i]:.0f} | {1e3 * np.nanmedian(amp):.3f} | "
                  f"{int(locked.sum())} of {int(r.converged.sum())} | {np.nanmedian(share):.2f} |", flush=True)
            curves[f"{m.upper()}-HBM"] = (r.omega, r.le_amplitude, r.converged)
            np.savez(tmp / f"nfrc_{m}_{'plus' if s > 0 else 'minus'}.npz", omega=r.omega, amp=r.le_amplitude,
                     converged=r.converged, share=share)
        ti = None
        if a.ti:
            from hbm.options import TimeIntegrationOptions
            from hbm.ti.sweep import sweep

            t0 = time.perf_counter()
            sw = sweep(rom, casing, contact, TimeIntegrationOptions(omega_min=a.omega_min, omega_max=a.omega_max,
                                                                    n_omega=a.ti))
            ti = (sw.omega, sw.amplitude, sw.period_class)
            locked = np.abs(sw.amplitude - half) <= 0.01 * half
            counts = {int(c): int(n) for c, n in zip(*np.unique(sw.period_class, return_counts=True))}
            print(f"| {s:+d} | TI sweep | {time.perf_counter() - t0:.0f} | {len(sw.omega)} speeds | classes {counts} | "
                  f"{1e3 * sw.amplitude.max():.3f} at {sw.omega[np.argmax(sw.amplitude)]:.0f} | "
                  f"{1e3 * np.median(sw.amplitude):.3f} | {int(locked.sum())} of {len(sw.omega)} | - |", flush=True)
            np.savez(tmp / f"ti_{'plus' if s > 0 else 'minus'}.npz", omega=sw.omega, amp=sw.amplitude,
                     cls=sw.period_class)
        panels.append((_title(rom, s), curves, ti))
    draw_panels(panels, a.png, (a.omega_min, a.omega_max), half)
    print(f"\nfigure: {a.png}; curves: {tmp}")


def _title(rom, s) -> str:
    from rom.friction_lock import friction_lock

    fl = friction_lock(rom.K, rom.n_boundary, s)
    lead = "LE leads" if s == -np.sign(rom.theta[-1] - rom.theta[0]) else "TE leads"
    sense = "+" if s > 0 else "\u2212"
    return f"rotation {sense} ({lead}); static lock above \u03bc = {fl.mu_set:.3f}"


def draw_panels(panels, png, omega_range, half):
    """The NFRCs side by side on one amplitude scale, (c + p) / 2 dotted."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from pipelines.figures import _scatter_classes

    fig, axes = plt.subplots(1, len(panels), figsize=(13.0, 4.5), sharey=True, constrained_layout=True)
    for ax, (title, curves, ti) in zip(np.atleast_1d(axes), panels):
        handles = []
        for label, (om, amp, ok) in curves.items():
            handles += ax.plot(om, np.where(ok, 1e3 * amp, np.nan), lw=1.2, label=label)
        if ti is not None:
            handles += _scatter_classes(ax, ti[0], 1e3 * np.asarray(ti[1]), ti[2], size=14)
        handles.append(ax.axhline(1e3 * half, color="0.5", ls=":", lw=1.0,
                                  label="(c + p) / 2: LE following the casing"))
        ax.set_xlim(*omega_range)
        ax.set_ylim(bottom=0.0)
        ax.set_xlabel("angular speed \u03a9 (rad/s)")
        ax.set_title(title, fontsize=10)
        ax.grid(True, lw=0.4, alpha=0.5)
        ax.legend(handles=handles, fontsize=7, loc="upper right", ncol=2)
    np.atleast_1d(axes)[0].set_ylabel("LE radial amplitude, half peak-to-peak (mm)")
    fig.savefig(png, dpi=150)
    plt.close(fig)


if __name__ == "__main__":
    main()
