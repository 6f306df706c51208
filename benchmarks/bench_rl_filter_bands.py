"""Which harmonics of RL's Lanczos filter change the shape of RL's NFRC? The RL NFRC of OUT's
ROM with the filter applied to some harmonics only (sigma_k of eq. 21 on those, 1 on the
others), each over [--omega-min, the scene's omega_max]; prints per filter the points, the
LE amplitudes where the curve crosses each --at speed (the number of crossings tells a loop
joined to the primary from one apart), and the peak.

    PYTHONPATH=. .venv/bin/python benchmarks/bench_rl_filter_bands.py OUT [--scene scenes/rotor67.toml]
        [--filters all,none,from:24,below:32,band:24-32] [--omega-min 1000] [--at 1130,1200]

A filter is `all` (the scene's RL-HBM), `none`, `from:K` (harmonics k >= K), `below:K`
(k < K), `band:K1-K2` (K1 <= k < K2), or `strength:S` (every harmonic, with the factors
1 - S (1 - sigma_k): S = 0 is `none`, S = 1 `all`). One BLAS thread, one NFRC after the
other.
"""
from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

import hbm  # noqa: F401  (before numpy: OpenBLAS's kernels for the host, hbm.openblas)
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from compare_nfrcs import crossings  # noqa: E402


def filter_factors(spec: str, orders: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """(2 N_h + 1,) the factors on the coefficient rows (harmonic orders `orders`) of the
    filter `spec`, from the scene's filter factors `sigma` (2 N_h + 1,)."""
    k = np.abs(orders)
    kind, _, arg = spec.partition(":")
    if kind == "strength":
        return 1.0 - float(arg) * (1.0 - sigma)
    if kind == "all":
        on = np.ones(k.shape, bool)
    elif kind == "none":
        on = np.zeros(k.shape, bool)
    elif kind == "from":
        on = k >= int(arg)
    elif kind == "below":
        on = k < int(arg)
    elif kind == "band":
        lo, hi = (int(v) for v in arg.split("-"))
        on = (k >= lo) & (k < hi)
    else:
        raise SystemExit(f"unknown filter {spec!r}: all, none, from:K, below:K, band:K1-K2 or strength:S")
    return np.where(on, sigma, 1.0)


def main() -> None:
    from threadpoolctl import threadpool_limits

    from hbm.harmonic.nfrc import compute_nfrc
    from hbm.harmonic.residual import build_residual
    from pipelines.scene import load_scene
    from pipelines.stages.rom import read_rom

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--scene", type=Path, default=ROOT / "scenes" / "rotor67.toml")
    ap.add_argument("--filters", default="all,none,from:24,from:32,below:24,below:32,band:24-32")
    ap.add_argument("--omega-min", type=float, default=1000.0)
    ap.add_argument("--at", default="1130,1200", help="speeds (rad/s) at which to list the curve's crossings")
    a = ap.parse_args()
    scene = load_scene(a.scene)
    rom = read_rom(a.out)
    hbm = replace(scene.hbm, omega_min=a.omega_min)
    contact = replace(scene.contact, lanczos=True)
    at = [float(w) for w in a.at.split(",")]
    print(f"RL NFRC of {a.out}, N_h = {hbm.n_harmonics}, {hbm.omega_min:g}-{hbm.omega_max:g} rad/s")
    for spec in a.filters.split(","):
        res = build_residual(rom, scene.casing, contact, hbm, method="rl")
        # the residual and its Jacobian read sigma per call
        res.sigma = filter_factors(spec, res.basis.orders, res.sigma)
        c0 = time.process_time()
        with threadpool_limits(limits=1, user_api="blas"):
            r = compute_nfrc(rom, scene.casing, contact, hbm, "rl", residual=res)
        ok = np.asarray(r.converged, bool)
        om, le = np.asarray(r.omega)[ok], np.asarray(r.le_amplitude)[ok]
        cuts = "; ".join(f"{w:g}: " + ", ".join(f"{v * 1e3:.3f}" for v in sorted(crossings(om, le, w))) for w in at)
        i = int(np.argmax(le))
        print(f"{spec:>12}: {len(om)} points ({r.status}), LE (mm) at {cuts}; peak {le[i] * 1e3:.3f} mm at "
              f"{om[i]:.1f} rad/s; {time.process_time() - c0:.0f} s CPU", flush=True)


if __name__ == "__main__":
    main()
