"""What the Cholesky factorisation of a bring-your-own mesh would cost done another way.

Two questions about the ~200 000-node wedge deck's 5-minute target, answered without
changing the product:

--deck DECK   the stiffness pattern the deck's own 15-node wedges (or 20-node hexahedra)
              would give without the split into tet10 (no new mid-edge nodes): a matrix
              with that pattern, SPD values (graph Laplacian + shift, times a 3 x 3 SPD
              block per node pair), root dof (*BOUNDARY) removed, factorised by MUMPS with
              the product's METIS ordering. Fill and flops depend on the pattern only;
              the time is that of a real factorisation of that size.
--fem FEM.H5  the stored K (the split mesh's, as the product factorises it), exact or with
              MUMPS Block Low-Rank at --blr EPS (ICNTL(35) = 2, CNTL(7) = EPS): time,
              entries, and the error of the 3 n_b constraint-mode solves against fem.h5's.

    nice -n 10 .venv/bin/python benchmarks/bench_factor_pattern.py --deck out/bench_mesh_import/rotor67_wedge15.inp
    nice -n 10 .venv/bin/python benchmarks/bench_factor_pattern.py --fem out/bench_mesh_import/run/fem.h5 --blr 1e-8

Prints one line per factorisation; the peak resident memory of the process at the end.
"""
from __future__ import annotations

import argparse
import resource
import sys
import time
from pathlib import Path

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


def factorise(K: sp.csr_matrix, blr: float):
    """(seconds, PETSc factor matrix, KSP) of MUMPS Cholesky, METIS, optionally BLR."""
    from petsc4py import PETSc

    n = K.shape[0]
    U = sp.triu(K, format="csr")
    U.sort_indices()
    A = PETSc.Mat().createSBAIJ(size=(n, n), bsize=1, csr=(U.indptr.astype(PETSc.IntType),
                                U.indices.astype(PETSc.IntType), U.data), comm=PETSc.COMM_SELF)
    A.assemble()
    ksp = PETSc.KSP().create(PETSc.COMM_SELF)
    ksp.setOperators(A)
    ksp.setType("preonly")
    pc = ksp.getPC()
    pc.setType("cholesky")
    pc.setFactorSolverType("mumps")
    pc.setFactorSetUpSolverType()
    F = pc.getFactorMatrix()
    F.setMumpsIcntl(7, 5)
    F.setMumpsIcntl(24, 0)
    if blr > 0:
        F.setMumpsIcntl(35, 2)
        F.setMumpsCntl(7, blr)
    t = time.perf_counter()
    ksp.setUp()
    return time.perf_counter() - t, F, ksp


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--deck", type=Path, help="mesh file whose own elements' pattern is factorised")
    ap.add_argument("--fem", type=Path, help="fem.h5 whose K is factorised")
    ap.add_argument("--blr", type=float, default=0.0, help="BLR dropping tolerance (0: exact)")
    a = ap.parse_args(argv)
    if (a.deck is None) == (a.fem is None):
        ap.error("give exactly one of --deck and --fem")
    from petsc4py import PETSc

    ref = bd = None
    if a.deck is not None:
        K = native_pattern(a.deck)
    else:
        import h5py

        with h5py.File(a.fem, "r") as f:
            K = sp.csr_matrix((f["K/data"][:], f["K/indices"][:], f["K/indptr"][:]))
            bd, ref = f["boundary_dofs"][:], f["constraint_modes"][:]
    n = K.shape[0]
    seconds, F, ksp = factorise(K, a.blr)
    print(f"{n} dof, nnz {K.nnz}: factorisation {seconds:.1f} s wall, {F.getMumpsInfog(29):.3e} entries "
          f"(exact), {F.getMumpsInfog(35):.3e} kept (BLR), {F.getMumpsRinfog(3):.3e} flop (exact), "
          f"{F.getMumpsRinfog(14):.3e} (BLR)", flush=True)
    if bd is not None:
        E = np.zeros((n, len(bd)), order="F")
        E[bd, np.arange(len(bd))] = 1.0
        X = np.empty((n, len(bd)), order="F")
        Bm = PETSc.Mat().createDense(((n, n), (None, len(bd))), array=E, comm=PETSc.COMM_SELF)
        Xm = PETSc.Mat().createDense(((n, n), (None, len(bd))), array=X, comm=PETSc.COMM_SELF)
        t = time.perf_counter()
        F.matSolve(Bm, Xm)
        solve = time.perf_counter() - t
        psi = np.linalg.solve(X[bd], X.T).T
        err = np.abs(psi - ref).max() / np.abs(ref).max()
        print(f"{len(bd)}-column solve {solve:.1f} s; residual {np.linalg.norm(K @ X - E, axis=0).max():.2e}; "
              f"constraint modes against fem.h5: {err:.2e} relative", flush=True)
    ksp.destroy()
    print(f"peak resident memory {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6:.2f} GB")


if __name__ == "__main__":
    main()
