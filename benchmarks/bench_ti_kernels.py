"""Time-integration kernel variants against each other, in one process (prints a markdown table).

    .venv/bin/python benchmarks/bench_ti_kernels.py VARIANT.py [VARIANT.py ...] [--rom ROM.h5|standin]
        [--omegas 650,2000] [--revolutions 60] [--repeat 5]

Each VARIANT.py is a copy of hbm/ti/kernel.py with one change (hbm/ti/kernel.py itself may be
one of them). The variants march the same speeds from rest for a fixed number of revolutions
(no early stop, so that every variant takes the same steps), alternated repeat times; the
table gives the median and smallest CPU time per variant and speed, and the LE amplitude
(a variant that changes only the speed keeps it to the bit).

Why one process, alternated: this shared host's speed drifts by 5 to 10 % between runs and
within a run, and which variant LLVM compiles well changes with the rest of the loop, so
effects of 2 to 5 % are seen only side by side. Pin the process to one core for steadier
figures (`taskset -c 1 ...`).
"""
from __future__ import annotations

import argparse
import importlib.util
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from hbm.options import CasingOptions, ContactOptions, TimeIntegrationOptions  # noqa: E402
from hbm.ti import march  # noqa: E402
from hbm.ti.march import rom_modal_system  # noqa: E402
from hbm.ti.sweep import simulate  # noqa: E402
from bench_ti import load_rom  # noqa: E402


def load_kernel(path: Path, index: int, folder: Path):
    """The kernel module in `path`, copied into `folder` and imported under a name of its own.

    A copy, compiled afresh: numba's cache beside a file records the module name it was
    compiled under, and a cache written under another name (or by an earlier version of the
    file with the same time stamp) fails to load or loads stale code."""
    name = f"ti_kernel_variant_{index}"
    copy = folder / f"{name}.py"
    shutil.copyfile(path, copy)
    spec = importlib.util.spec_from_file_location(name, copy)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("variants", nargs="+", type=Path, help="kernel files (copies of hbm/ti/kernel.py)")
    ap.add_argument("--rom", default="standin")
    ap.add_argument("--omegas", default="650,2000")
    ap.add_argument("--revolutions", type=int, default=60)
    ap.add_argument("--repeat", type=int, default=5)
    a = ap.parse_args()
    for p in a.variants:
        if not p.is_file():
            raise SystemExit(f"no kernel file {p}")
    opts = TimeIntegrationOptions(n_revolutions=a.revolutions, stop_when_settled=False)  # checked first
    omegas = [float(w) for w in a.omegas.split(",") if w]
    folder = Path(tempfile.mkdtemp(prefix="bench_ti_kernels_"))
    try:
        run(a, [load_kernel(p, i, folder) for i, p in enumerate(a.variants)], opts, omegas)
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def run(a, kernels, opts, omegas):
    """Alternate the kernels over the speeds (rad/s) and print the table."""
    rom, label = load_rom(a.rom)
    system = rom_modal_system(rom)
    cas, con = CasingOptions(), ContactOptions()

    current = {}
    original_init = march.Marcher.__init__

    def init(self, *args, **kwargs):  # the march as usual, on the chosen variant's loop
        original_init(self, *args, **kwargs)
        self._kernel = current["kernel"]

    march.Marcher.__init__ = init
    for k in kernels:  # compile or load every variant before timing
        current["kernel"] = k
        simulate(system, cas, con.mu, 2000.0, TimeIntegrationOptions(n_revolutions=2, n_keep=1))
    times = {(i, w): [] for i in range(len(kernels)) for w in omegas}
    amplitude = {}
    for _ in range(a.repeat):
        for w in omegas:
            for i, k in enumerate(kernels):
                current["kernel"] = k
                t0 = time.process_time()
                r = simulate(system, cas, con.mu, w, opts)
                times[(i, w)].append(time.process_time() - t0)
                amplitude[(i, w)] = r.amplitude
    print(f"ROM: {label}; {a.revolutions} revolutions from rest; {a.repeat} alternated runs\n")
    print("| kernel | Omega (rad/s) | CPU s, median | CPU s, smallest | ratio to the first (median) | LE amplitude (m) |")
    print("|---|---|---|---|---|---|")
    for w in omegas:
        base = statistics.median(times[(0, w)])
        for i, p in enumerate(a.variants):
            t = times[(i, w)]
            print(f"| {p} | {w:g} | {statistics.median(t):.3f} | {min(t):.3f} | "
                  f"{statistics.median(t) / base:.3f} | {amplitude[(i, w)]:.10e} |")


if __name__ == "__main__":
    main()
