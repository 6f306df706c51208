"""Where the FEM stage's peak memory goes, step by step, on a stored K and M.

    nice -n 10 .venv/bin/python benchmarks/bench_fem_memory.py --fem out/bench_mesh_import/run/fem.h5 [--solver S]

Reads K, M and the contact nodes from a fem.h5, then runs what the FEM stage runs after the
assembly (fem.analysis.solve_system, scene defaults of fem.options.FemOptions: one Cholesky
factorisation, the full-model eigen-solve, the constraint modes and the fixed-interface
eigen-solve) and prints the resident set size (RSS, GB) before and after every block solve,
the largest RSS sampled every 0.1 s in each step, and the wall time of each step. K and M
are handed over as upper triangles with the whole matrices freed, as analyse_blade does.
The assembly is left out: its peak is below the factorisation's (its temporaries are given
back before the factorisation, fem.memory). The frequencies and constraint modes are
compared with the file's.
"""
from __future__ import annotations

import argparse
import sys
import threading
import time
from pathlib import Path

import h5py
import scipy.sparse as sp

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def rss_gb() -> float:
    """This process's resident set size, GB (from /proc; Linux)."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS"):
                return int(line.split()[1]) / 1e6
    return float("nan")


def main() -> None:
    import numpy as np

    import fem.interface
    import fem.modes
    from fem.analysis import solve_system
    from fem.assembly import FemSystem
    from fem.cholesky import SOLVERS, CholeskyFactor
    from fem.memory import return_freed_memory
    from fem.options import FemOptions
    from fem.symmetric import SymmetricMatrix

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fem", type=Path, required=True, help="a fem.h5 (K, M, node_dofs, boundary_node_index)")
    ap.add_argument("--solver", choices=SOLVERS, default="auto")
    args = ap.parse_args()
    opts = FemOptions(solver=args.solver)

    peaks: dict[str, float] = {}
    step = ["load"]

    def sample():
        while True:
            peaks[step[0]] = max(peaks.get(step[0], 0.0), rss_gb())
            time.sleep(0.1)

    threading.Thread(target=sample, daemon=True).start()
    with h5py.File(args.fem, "r") as f:
        K, M = (SymmetricMatrix.from_csr(sp.csr_matrix((f[f"{A}/data"][:], f[f"{A}/indices"][:],
                                                        f[f"{A}/indptr"][:]))) for A in ("K", "M"))
        node_dofs, nodes = f["node_dofs"][:], f["boundary_node_index"][:]
    system = FemSystem(K=K, M=M, node_dofs=node_dofs)
    del K, M
    return_freed_memory()
    print(f"{args.fem}: {system.n_free} dof; RSS with K and M (upper triangles) {rss_gb():.2f} GB", flush=True)

    # step names for the sampler, and a line per block solve: the product's functions, wrapped
    marks = {}

    def named(name, fn):
        def run(*a, **kw):
            step[0] = name
            t = time.perf_counter()
            out = fn(*a, **kw)
            marks[name] = time.perf_counter() - t
            print(f"{name}: {marks[name]:.1f} s, RSS at the end {rss_gb():.2f} GB, "
                  f"largest {peaks.get(name, 0.0):.2f} GB", flush=True)
            return out
        return run

    init, solve = CholeskyFactor.__init__, CholeskyFactor.solve

    def factorise(self, *a, **kw):
        named("factorisation", init)(self, *a, **kw)
        print(f"  {self.solver_used}: {self.factor_entries:.3e} factor entries", flush=True)
        step[0] = "modes"

    def logged_solve(self, B):
        before = rss_gb()
        t = time.perf_counter()
        X = solve(self, B)
        print(f"  block solve of {B.shape[1]} columns: {time.perf_counter() - t:.1f} s, "
              f"RSS {before:.2f} -> {rss_gb():.2f} GB", flush=True)
        return X

    CholeskyFactor.__init__, CholeskyFactor.solve = factorise, logged_solve
    fem.modes.compute_modes = named("modes", fem.modes.compute_modes)
    fem.interface.compute_interface_basis = named("interface", fem.interface.compute_interface_basis)
    t = time.perf_counter()
    result = solve_system(system, opts, nodes)
    step[0] = "end"
    print(f"whole step {time.perf_counter() - t:.1f} s; largest RSS: "
          + ", ".join(f"{k} {v:.2f} GB" for k, v in peaks.items()), flush=True)
    # the file's results only now: read before, they would sit in the measured resident set
    with h5py.File(args.fem, "r") as f:
        ref = {k: f[k][:] for k in ("frequencies", "fixed_interface_frequencies", "constraint_modes")}
    rel = {k: float(np.abs(getattr(result, k) - v).max() / np.abs(v).max()) for k, v in ref.items()}
    print("largest relative difference from the file's: " + ", ".join(f"{k} {v:.1e}" for k, v in rel.items()),
          flush=True)


if __name__ == "__main__":
    main()
