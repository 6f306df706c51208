"""Sparse Cholesky factorisation of the stiffness (MUMPS through PETSc), reused for many solves.

On the default blade (~600k dof) the factorisation is the single most expensive step of
mesh -> ROM (about 1.6e12 flop, two minutes of CPU), while a block solve with 12 right-hand
sides costs about as much as one with a single one (the triangular factor, ~5 GB, is read
from memory once per block). Everything downstream therefore factorises K once and feeds
it blocks of right-hand sides.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

# MUMPS ICNTL(7): symmetric permutation for the analysis; 5 = METIS (fewest flops on the
# quadratic tet meshes measured here), 3 = SCOTCH, 4 = PORD, 0 = AMD.
ORDERINGS = {"metis": 5, "scotch": 3, "pord": 4, "amd": 0}


class CholeskyFactor:
    """LDL^T (MUMPS, symmetric positive definite) of a scipy sparse matrix.

    `solve(B)` with B (n,) or (n, k) returns A^{-1} B in the same shape (float64).
    """

    def __init__(self, A: sp.spmatrix, ordering: str = "metis"):
        from petsc4py import PETSc

        if ordering not in ORDERINGS:
            raise ValueError(f"unknown ordering '{ordering}'; known: {', '.join(ORDERINGS)}")
        A = sp.csr_matrix(A)
        n = A.shape[0]
        if A.shape != (n, n):
            raise ValueError(f"matrix must be square, got shape {A.shape}")
        self.n = n
        # MUMPS reads only the upper triangle of a symmetric matrix: hand it just that (SBAIJ),
        # half the memory of a full AIJ copy.
        U = sp.triu(A, format="csr")
        U.sort_indices()
        self._A = PETSc.Mat().createSBAIJ(size=(n, n), bsize=1, csr=(U.indptr.astype(PETSc.IntType),
                                          U.indices.astype(PETSc.IntType), U.data), comm=PETSc.COMM_SELF)
        self._A.assemble()
        del U
        ksp = PETSc.KSP().create(PETSc.COMM_SELF)
        ksp.setOperators(self._A)
        ksp.setType("preonly")
        pc = ksp.getPC()
        pc.setType("cholesky")
        pc.setFactorSolverType("mumps")
        pc.setFactorSetUpSolverType()
        F = pc.getFactorMatrix()
        F.setMumpsIcntl(7, ORDERINGS[ordering])
        F.setMumpsIcntl(24, 0)  # no null-pivot detection: K is SPD once the root is clamped
        ksp.setUp()
        info = F.getMumpsInfog(1)
        if info < 0:
            raise RuntimeError(f"MUMPS factorisation failed, INFOG(1) = {info}, INFOG(2) = {F.getMumpsInfog(2)}"
                               " (-10: numerically singular: is the structure clamped?)")
        n_neg = F.getMumpsInfog(12)  # negative pivots: K not positive definite
        if n_neg > 0:
            raise np.linalg.LinAlgError(f"stiffness is not positive definite ({n_neg} negative pivots)")
        self._ksp, self._F = ksp, F
        self.factor_entries = int(F.getMumpsInfog(29))
        self.factor_flops = float(F.getMumpsRinfog(3))

    def solve(self, B: np.ndarray) -> np.ndarray:
        from petsc4py import PETSc

        B = np.asarray(B, dtype=np.float64)
        if B.shape[0] != self.n:
            raise ValueError(f"right-hand side has {B.shape[0]} rows, factor is {self.n} x {self.n}")
        if B.ndim == 1:
            b = PETSc.Vec().createWithArray(np.ascontiguousarray(B), comm=PETSc.COMM_SELF)
            x = b.duplicate()
            self._ksp.solve(b, x)
            return x.getArray().copy()
        k = B.shape[1]
        if k == 0:
            return np.zeros_like(B)
        # PETSc dense matrices are column-major: a Fortran-ordered buffer is used in place
        Bf = np.asfortranarray(B)
        X = np.empty((self.n, k), dtype=np.float64, order="F")
        Bm = PETSc.Mat().createDense((self.n, k), array=Bf, comm=PETSc.COMM_SELF)
        Xm = PETSc.Mat().createDense((self.n, k), array=X, comm=PETSc.COMM_SELF)
        self._F.matSolve(Bm, Xm)
        Bm.destroy()
        Xm.destroy()
        return X

    def destroy(self) -> None:
        """Free the factor (several GB on the default blade) now rather than at garbage collection."""
        for obj in (self._ksp, self._A):
            obj.destroy()
