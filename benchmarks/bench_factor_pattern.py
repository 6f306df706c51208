"""What the Cholesky factorisation of a bring-your-own mesh would cost done another way.

Two questions about the ~200 000-node wedge deck's 5-minute target, answered without
changing the product:

--deck DECK   the stiffness pattern the deck's own 15-node wedges (or 20-node hexahedra)
              would give without the split into tet10 (no new mid-edge nodes): a matrix
              with that pattern, SPD values (graph Laplacian + shift, times a 3 x 3 SPD
              block per node pair), root dof (*BOUNDARY) removed, factorised by MUMPS as
              the product factorises K. Fill and flops depend on the pattern only;
              the time is that of a real factorisation of that size.
--fem FEM.H5  the stored K (the split mesh's, as the product factorises it), exact or with
              MUMPS Block Low-Rank at --blr EPS (ICNTL(35) = 2, CNTL(7) = EPS): time,
              entries, and the error of the 3 n_b constraint-mode solves against fem.h5's.
--orderings   the fill-reducing orderings to compare (default: the product's, pord), for MUMPS.
--solvers     the factorisation packages to compare (default: mumps; cholmod: CHOLMOD with
              its own ordering, once, whatever --orderings says).

    nice -n 10 .venv/bin/python benchmarks/bench_factor_pattern.py --deck out/bench_mesh_import/rotor67_wedge15.inp
    nice -n 10 .venv/bin/python benchmarks/bench_factor_pattern.py --fem out/bench_mesh_import/run/fem.h5 --blr 1e-8
    nice -n 10 .venv/bin/python benchmarks/bench_factor_pattern.py --fem out/rotor67/fem.h5 --orderings pord,amd,amf,qamd,metis
    nice -n 10 .venv/bin/python benchmarks/bench_factor_pattern.py --fem out/rotor67/fem.h5 --solvers cholmod,mumps

Prints one line per factorisation; the peak resident memory of the process at the end.
"""
from __future__ import annotations

import argparse
import resource
import sys
import time
from pathlib import Path

import hbm  # noqa: F401  (before numpy: OpenBLAS's kernels for the host, hbm.openblas)
import numpy as np
import scipy.sparse as sp

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def native_pattern(deck: Path) -> sp.csr_matrix:
    """(3 n_free, 3 n_free) SPD matrix with the deck elements' node coupling, root removed."""
    from mesh.source import read_source

    src = read_source(deck)
    cells = [b.connectivity for b in src.blocks]
    n = len(src.points)
    rows = np.concatenate([np.repeat(c, c.shape[1], axis=1).ravel() for c in cells])
    cols = np.concatenate([np.tile(c, (1, c.shape[1])).ravel() for c in cells])
    A = sp.coo_matrix((np.full(len(rows), -1.0), (rows, cols)), shape=(n, n)).tocsr()
    A.data[:] = -1.0  # duplicates summed above: one coupling per node pair
    A = A + sp.diags(-np.asarray(A.sum(axis=1)).ravel() + 1.0 + 1e-3)
    K = sp.kron(A, np.array([[4.0, 1.0, 1.0], [1.0, 4.0, 1.0], [1.0, 1.0, 4.0]]), format="csr")
    fixed = src.fixed.any(axis=1) if src.fixed is not None else np.zeros(n, bool)
    free = np.repeat(~fixed, 3)
    print(f"{deck.name}: {n} nodes, {sum(len(c) for c in cells)} elements "
          f"({', '.join(sorted({b.type for b in src.blocks}))}), {int(free.sum())} free dof", flush=True)
    return K[free][:, free].tocsr()


def factorise(K: sp.csr_matrix, ordering: str, blr: float, solver: str = "mumps"):
    """(seconds, fem.cholesky.CholeskyFactor) of K by `solver`, with MUMPS Block Low-Rank at
    dropping tolerance blr (0: exact), set through PETSc's options as the product sets its own."""
    from petsc4py import PETSc

    from fem.cholesky import CholeskyFactor

    opts = PETSc.Options()
    given = {"mat_mumps_icntl_35": 2, "mat_mumps_cntl_7": blr} if blr > 0 else {}
    for k, v in given.items():
        opts[k] = v
    t = time.perf_counter()
    try:
        factor = CholeskyFactor(K, ordering=ordering, solver=solver)
    finally:
        for k in given:
            opts.delValue(k)
    return time.perf_counter() - t, factor


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--deck", type=Path, help="mesh file whose own elements' pattern is factorised")
    ap.add_argument("--fem", type=Path, help="fem.h5 whose K is factorised")
    ap.add_argument("--blr", type=float, default=0.0, help="BLR dropping tolerance (0: exact)")
    ap.add_argument("--orderings", default="pord", help="comma-separated keys of fem.cholesky.ORDERINGS")
    ap.add_argument("--solvers", default="mumps", help="comma-separated: mumps, cholmod")
    a = ap.parse_args(argv)
    if (a.deck is None) == (a.fem is None):
        ap.error("give exactly one of --deck and --fem")
    ref = bd = None
    if a.deck is not None:
        K = native_pattern(a.deck)
    else:
        import h5py

        with h5py.File(a.fem, "r") as f:
            K = sp.csr_matrix((f["K/data"][:], f["K/indices"][:], f["K/indptr"][:]))
            bd, ref = f["boundary_dofs"][:], f["constraint_modes"][:]
    n = K.shape[0]
    runs = [(solver, ordering) for solver in a.solvers.split(",")
            for ordering in (a.orderings.split(",") if solver == "mumps" else ["-"])]
    for solver, ordering in runs:
        seconds, factor = factorise(K, "pord" if ordering == "-" else ordering, a.blr, solver)
        if solver == "mumps":
            F = factor._F  # the MUMPS factor matrix, for the BLR counters the product does not read
            print(f"{n} dof, nnz {K.nnz}, MUMPS, ordering {ordering} (used: {factor.ordering_used}): factorisation "
                  f"{seconds:.1f} s wall, {factor.factor_entries:.3e} entries (exact), {F.getMumpsInfog(35):.3e} kept "
                  f"(BLR), {factor.factor_flops:.3e} flop (exact), {F.getMumpsRinfog(14):.3e} (BLR)", flush=True)
        else:
            print(f"{n} dof, nnz {K.nnz}, CHOLMOD ({factor.ordering_used}): factorisation {seconds:.1f} s wall, "
                  f"{factor.factor_entries:.3e} entries", flush=True)
        if bd is not None:
            E = np.zeros((n, len(bd)))
            E[bd, np.arange(len(bd))] = 1.0
            t = time.perf_counter()
            X = factor.solve(E)
            solve = time.perf_counter() - t
            t = time.perf_counter()
            factor.solve(E[:, :14])
            solve14 = time.perf_counter() - t
            psi = np.linalg.solve(X[bd], X.T).T
            err = np.abs(psi - ref).max() / np.abs(ref).max()
            res = np.linalg.norm(K @ X - E, axis=0).max()
            print(f"  {len(bd)}-column solve {solve:.1f} s, 14-column {solve14:.1f} s; residual {res:.2e}; "
                  f"constraint modes against fem.h5: {err:.2e} relative", flush=True)
        factor.destroy()
    print(f"peak resident memory {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6:.2f} GB")


if __name__ == "__main__":
    main()
