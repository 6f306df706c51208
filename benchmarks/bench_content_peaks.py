"""Time of hbm.harmonic.content.peak_magnitudes (the period maximum of eqs. (32)-(34)) per
call, on random harmonics of N_h = 40 and 80 with 1 and 12 columns (12: a coarse rotor 67
point's modal coordinates), median of --repeat runs of 200 calls. --against FILE times
another version of hbm/harmonic/content.py too (e.g. `git show REV:hbm/harmonic/content.py
> old.py`), alternated with the current one.

    PYTHONPATH=. .venv/bin/python benchmarks/bench_content_peaks.py [--against old.py]
"""
import argparse
import importlib.util
import time

import hbm  # noqa: F401  (before numpy: OpenBLAS's kernels for the host, hbm.openblas)
import numpy as np

from hbm.harmonic.content import peak_magnitudes


def _load(path):
    spec = importlib.util.spec_from_file_location("content_against", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.peak_magnitudes


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--against")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    versions = [("current", peak_magnitudes)] + ([("against", _load(args.against))] if args.against else [])
    rng = np.random.default_rng(0)
    print("| N_h | columns | " + " | ".join(f"{name}, ms" for name, _ in versions) + " |")
    print("|---|---|" + "---|" * len(versions))
    for nh, m in ((40, 1), (40, 12), (80, 12)):
        c = rng.standard_normal((2 * nh + 1, m)) / np.arange(1, 2 * nh + 2)[:, None]
        times = {name: [] for name, _ in versions}
        for _ in range(args.repeat):
            for name, f in versions:
                t0 = time.perf_counter()
                for _ in range(200):
                    f(c)
                times[name].append((time.perf_counter() - t0) / 200 * 1e3)
        print(f"| {nh} | {m} | " + " | ".join(f"{np.median(times[n]):.3f}" for n, _ in versions) + " |")


if __name__ == "__main__":
    main()
