"""Where the FEM stage's peak memory goes, step by step, on a stored K and M.

    nice -n 10 .venv/bin/python benchmarks/bench_fem_memory.py --fem out/bench_mesh_import/run/fem.h5 [--solver S]

Reads K, M and the boundary dof from a fem.h5, then does what the FEM stage does after
the assembly (fem.analysis.solve_system: one Cholesky factorisation, the full-model
eigen-solve, the constraint modes and the fixed-interface eigen-solve, with the scene
defaults of fem.options.FemOptions) and prints the resident set size (RSS, GB) before and
after every block solve, the largest RSS sampled every 0.1 s in each step, and the wall
time of each step. The assembly is left out: its peak is below the factorisation's (its
temporaries are given back before the factorisation, fem.memory).
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
    from fem.cholesky import SOLVERS, CholeskyFactor
    from fem.interface import compute_interface_basis
    from fem.memory import return_freed_memory
    from fem.modes import compute_modes
    from fem.options import FemOptions

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fem", type=Path, required=True, help="a fem.h5 (K, M, boundary_dofs)")
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
        K = sp.csr_matrix((f["K/data"][:], f["K/indices"][:], f["K/indptr"][:]))
        M = sp.csr_matrix((f["M/data"][:], f["M/indices"][:], f["M/indptr"][:]))
        bd = f["boundary_dofs"][:]
    return_freed_memory()
    print(f"{args.fem}: {K.shape[0]} dof, K {K.nnz} and M {M.nnz} entries; RSS with K and M {rss_gb():.2f} GB",
          flush=True)

    def timed(name, fn):
        step[0] = name
        t = time.perf_counter()
        out = fn()
        print(f"{name}: {time.perf_counter() - t:.1f} s, RSS at the end {rss_gb():.2f} GB, "
              f"largest {peaks.get(name, 0.0):.2f} GB", flush=True)
        return out

    factor = timed("factorisation", lambda: CholeskyFactor(K, ordering=opts.ordering, solver=opts.solver))
    print(f"  {factor.solver_used}: {factor.factor_entries:.3e} factor entries", flush=True)
    solve = factor.solve

    def logged_solve(B):
        before = rss_gb()
        t = time.perf_counter()
        X = solve(B)
        print(f"  block solve of {B.shape[1]} columns: {time.perf_counter() - t:.1f} s, "
              f"RSS {before:.2f} -> {rss_gb():.2f} GB", flush=True)
        return X

    factor.solve = logged_solve
    modal = timed("modes", lambda: compute_modes(K, M, opts.n_modes, factor=factor, tol=opts.tol))
    return_freed_memory()
    timed("interface", lambda: compute_interface_basis(K, M, bd, opts.n_fixed_interface_modes, factor,
                                                       start=modal.vectors, tol=opts.tol))
    timed("destroy", factor.destroy)
    print("largest RSS: " + ", ".join(f"{k} {v:.2f} GB" for k, v in peaks.items()), flush=True)


if __name__ == "__main__":
    main()
