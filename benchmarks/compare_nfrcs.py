"""How far NFRCs lie from a reference NFRC in LE amplitude.

    .venv/bin/python benchmarks/compare_nfrcs.py REFERENCE.h5 OTHER.h5 [OTHER.h5 ...]
        [--omega-min 400] [--omega-max 2000] [--step 1]

Each file is an NFRC artifact (nfrc_METHOD.h5 of `bladerub run`). On a grid of speeds
`--step` rad/s apart, each curve's LE amplitude (half peak-to-peak radial displacement, m)
is interpolated linearly where the curve crosses the speed. Only the speeds where both the
reference and the other curve cross exactly once are compared: near folds and on stretches
one curve holds and the other lacks, "the same point" has no meaning. Prints per file the
number of speeds compared, the median signed relative difference (other - reference) /
reference, the mean and 90th percentile of its size, and the largest.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import hbm  # noqa: F401  (before numpy: OpenBLAS's kernels for the host, hbm.openblas)
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def crossings(omega: np.ndarray, amplitude: np.ndarray, w: float) -> list[float]:
    """Amplitudes where the polyline (omega (m,) rad/s, amplitude (m,)) reaches omega = w: its
    points there and its chords across w (the isola search's own reading of a branch at a
    speed, hbm.isolas.membership.points_at)."""
    from hbm.isolas.membership import KnownBranch, points_at

    return [float(v) for v in points_at(KnownBranch.of(omega, np.asarray(amplitude)[:, None], ""), w)[:, 0]]


def read_curve(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """(omega (m,) rad/s, LE amplitude (m,) m) of an NFRC artifact's converged points."""
    import h5py

    with h5py.File(path, "r") as f:
        ok = f["converged"][()].astype(bool)
        return f["omega"][()][ok], f["extras/le_amplitude"][()][ok]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("reference", type=Path)
    ap.add_argument("others", type=Path, nargs="+")
    ap.add_argument("--omega-min", type=float, default=400.0)
    ap.add_argument("--omega-max", type=float, default=2000.0)
    ap.add_argument("--step", type=float, default=1.0, help="grid spacing, rad/s")
    a = ap.parse_args()
    ref = read_curve(a.reference)
    grid = np.arange(a.omega_min + a.step, a.omega_max, a.step)
    print(f"reference {a.reference}, {a.omega_min:g}-{a.omega_max:g} rad/s every {a.step:g} rad/s")
    print("| NFRC | speeds compared | median difference | mean size | 90th percentile | largest |")
    print("| --- | --- | --- | --- | --- | --- |")
    for path in a.others:
        other = read_curve(path)
        d = []
        for w in grid:
            r, o = crossings(*ref, w), crossings(*other, w)
            if len(r) == 1 and len(o) == 1:
                d.append((o[0] - r[0]) / r[0])
        d = np.array(d)
        if not d.size:
            print(f"| {path} | 0 | - | - | - | - |")
            continue
        s = np.abs(d)
        print(f"| {path} | {d.size} | {np.median(d):+.1%} | {s.mean():.1%} | {np.percentile(s, 90):.1%} | {s.max():.1%} |")


if __name__ == "__main__":
    main()
