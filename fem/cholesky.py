"""Sparse Cholesky factorisation of the stiffness (CHOLMOD or MUMPS through PETSc), reused
for many solves.

On the default blade (~600k dof) the factorisation is the single most expensive step of
mesh -> ROM (about 6e11 flop), while a block solve with 12 right-hand sides costs about as
much as one with a single one (the triangular factor, ~2.5 GB, is read from memory once per
block). Everything downstream therefore factorises K once and feeds it blocks of
right-hand sides.

Two factorisations, both in Debian's PETSc: CHOLMOD (SuiteSparse, supernodal, its own
choice of AMD or METIS) in one process with the factor in memory, and MUMPS (multifrontal)
under MPI or with the factor out of core, which CHOLMOD cannot do. Where both can, CHOLMOD
is the default ("auto"): on the ~200k-node rotor 67 wedge deck (952 890 dof) it factorises
in 97 s where MUMPS takes 141 s (one run of benchmarks/bench_factor_pattern.py --solvers:
3.3e12 against 3.5e12 flop, 9.6e8 against 1.17e9 entries), its block solves cost the same,
and the FEM stage's peak is 11.2 GB where MUMPS in core needs 12.6 (bench_mesh_import.py).
"""
from __future__ import annotations

import numpy as np

from fem.memory import return_freed_memory

# MUMPS ICNTL(7): symmetric permutation for the analysis ("auto": MUMPS chooses). METIS and
# SCOTCH exist only where MUMPS was built with them (Debian's sequential analysis has
# neither: MUMPS then falls back to its own choice, which CholeskyFactor.ordering_used says).
ORDERINGS = {"pord": 4, "amd": 0, "amf": 2, "qamd": 6, "metis": 5, "scotch": 3, "auto": 7}
ORDERING_NAMES = {v: k for k, v in ORDERINGS.items()}

#: [fem] solver: "auto" = CHOLMOD in one process with the factor in memory, else MUMPS.
SOLVERS = ("auto", "cholmod", "mumps")
#: CholeskyFactor.ordering_used with CHOLMOD, which keeps the better of AMD and METIS by fill
#: and does not say which (PETSc exposes no CHOLMOD statistics but through a viewer).
CHOLMOD_ORDERING = "cholmod (AMD or METIS)"


def resolve_solver(solver: str, distributed: bool, out_of_core: bool) -> str:
    """The factorisation package that `solver` (a key of SOLVERS) names for a matrix on one
    process or distributed, with the factor in memory or out of core: "cholmod" or "mumps".
    Raises ValueError for CHOLMOD where it cannot run (it is sequential and in core only)."""
    if solver not in SOLVERS:
        raise ValueError(f"unknown solver '{solver}'; known: {', '.join(SOLVERS)}")
    if solver == "auto":
        return "mumps" if distributed or out_of_core else "cholmod"
    if solver == "cholmod" and distributed:
        raise ValueError('solver "cholmod" factorises on one process; under MPI use "mumps" (or "auto")')
    if solver == "cholmod" and out_of_core:
        raise ValueError('solver "cholmod" keeps the factor in memory: out of core (out_of_core = true) needs '
                         '"mumps" (or "auto")')
    return solver


class CholeskyFactor:
    """Cholesky factor (CHOLMOD LL^T or MUMPS LDL^T, symmetric positive definite) of a sparse matrix.

    A: a fem.symmetric.SymmetricMatrix or a scipy sparse matrix (its upper triangle is read;
    this process only), or a fem.distributed.DistributedMatrix (factorised in parallel by
    MUMPS on the matrix's communicator).
    solver: a key of SOLVERS (resolve_solver); `solver_used` says which package factorised.
    ordering: a key of ORDERINGS, for MUMPS; ordering_used: the one MUMPS applied
        (INFOG(7)), which differs when this MUMPS lacks the one asked for; CHOLMOD_ORDERING
        with CHOLMOD, which chooses its own.
    out_of_core: None: the factor stays in memory. A directory: MUMPS writes the factor
        there as it computes it (ICNTL(22) = 1) and reads it back at every solve; the
        memory is then that of the active fronts only, the factor lives in files (and in
        the page cache, which the system can drop). The caller owns the directory.
    `solve(B)` with B (n,) or (n, k) returns A^{-1} B in the same shape (float64); for a
    distributed A, B and the result are this rank's row block (n_local rows), and the call
    is collective.
    """

    def __init__(self, A, ordering: str = "pord", out_of_core: str | None = None, solver: str = "auto"):
        from petsc4py import PETSc

        from fem.distributed import DistributedMatrix
        from fem.symmetric import SymmetricMatrix

        if ordering not in ORDERINGS:
            raise ValueError(f"unknown ordering '{ordering}'; known: {', '.join(ORDERINGS)}")
        distributed = isinstance(A, DistributedMatrix)
        self.solver_used = resolve_solver(solver, distributed, out_of_core is not None)
        if distributed:  # MUMPS reads the upper triangle of the AIJ rows
            self.n = int(A.shape[0])
            self.n_local = A.layout.n_local
            comm = A.petsc.comm
            mat = A.petsc
        else:
            if not isinstance(A, SymmetricMatrix):
                A = SymmetricMatrix.from_csr(A)  # (which refuses a matrix that is not square)
            n = A.shape[0]
            self.n = self.n_local = n
            comm = PETSc.COMM_SELF
            # both packages read only the upper triangle of a symmetric matrix: hand them just
            # that (SBAIJ), half the memory of a full AIJ copy.
            U = A.upper()
            # (asarray: no copy of the index arrays when they already have PETSc's integer type)
            mat = PETSc.Mat().createSBAIJ(size=(n, n), bsize=1, csr=(np.asarray(U.indptr, dtype=PETSc.IntType),
                                          np.asarray(U.indices, dtype=PETSc.IntType), U.data), comm=comm)
            mat.assemble()
            del U
        self._comm = comm
        ksp = PETSc.KSP().create(comm)
        ksp.setOperators(mat)
        ksp.setType("preonly")
        pc = ksp.getPC()
        pc.setType("cholesky")
        pc.setFactorSolverType(self.solver_used)
        pc.setFactorSetUpSolverType()
        F = pc.getFactorMatrix()
        try:
            if self.solver_used == "cholmod":
                self._setup_cholmod(ksp, F)
            else:
                self._setup_mumps(ksp, F, ordering, out_of_core)
        finally:
            # the solves need the factor only: the solver and our copy of the matrix (the upper
            # triangle, half a GB on the ~200k deck) go now, not when the factor is freed
            pc.destroy()  # this handle's reference: the PC holds one on the factor
            ksp.destroy()
            if not distributed:  # our SBAIJ copy; a distributed matrix is its owner's
                mat.destroy()
        self._F = F
        return_freed_memory()  # the factorisation's workspace

    def _setup_cholmod(self, ksp, F) -> None:
        from petsc4py import PETSc

        # supernodal always: it is LL^T and stops at a non-positive pivot, where CHOLMOD's
        # simplicial LDL^T (its choice for small, sparse factors) would factorise an
        # indefinite K without a word
        opts = PETSc.Options()
        opts["mat_cholmod_factor"] = "supernodal"
        try:
            ksp.setUp()
        except PETSc.Error as exc:
            if exc.ierr == 81:  # PETSC_ERR_MAT_CH_ZRPVT: a pivot <= 0 in the Cholesky factorisation
                raise np.linalg.LinAlgError("stiffness is not positive definite (CHOLMOD stopped at a pivot <= 0): "
                                            "is the structure clamped?") from None
            raise RuntimeError(f"CHOLMOD factorisation failed (PETSc error {exc.ierr})") from None
        finally:
            opts.delValue("mat_cholmod_factor")
        self.factor_entries = int(F.getInfo()["nz_used"])
        self.factor_flops = float("nan")  # CHOLMOD's count is printed by a viewer only
        self.ordering_used = CHOLMOD_ORDERING

    def _setup_mumps(self, ksp, F, ordering: str, out_of_core: str | None) -> None:
        from petsc4py import PETSc

        F.setMumpsIcntl(24, 0)  # no null-pivot detection: K is SPD once the root is clamped
        # ICNTL(7) through the options database: PETSc 3.18's Cholesky analysis resets a value
        # set with F.setMumpsIcntl(7, ...) to 7 (MUMPS's choice); the database value is kept
        opts = PETSc.Options()
        given = {"mat_mumps_icntl_7": ORDERINGS[ordering]}
        if out_of_core is not None:
            F.setMumpsIcntl(22, 1)
            given["mat_mumps_ooc_tmpdir"] = str(out_of_core)  # read by PETSc in setUp
        for k, v in given.items():
            opts[k] = v
        try:
            ksp.setUp()
        finally:
            for k in given:
                opts.delValue(k)
        info = F.getMumpsInfog(1)
        if info < 0:
            raise RuntimeError(f"MUMPS factorisation failed, INFOG(1) = {info}, INFOG(2) = {F.getMumpsInfog(2)}"
                               " (-10: numerically singular: is the structure clamped?)")
        n_neg = F.getMumpsInfog(12)  # negative pivots: K not positive definite
        if n_neg > 0:
            raise np.linalg.LinAlgError(f"stiffness is not positive definite ({n_neg} negative pivots)")
        self.factor_entries = int(F.getMumpsInfog(29))
        self.factor_flops = float(F.getMumpsRinfog(3))
        self.ordering_used = ORDERING_NAMES.get(int(F.getMumpsInfog(7)), f"ICNTL(7) = {F.getMumpsInfog(7)}")

    def solve(self, B: np.ndarray) -> np.ndarray:
        """A^{-1} B for B (n_local,) or (n_local, k): all k columns in one block solve
        (MatMatSolve; under MPI the block is centralised on rank 0 for MUMPS and the
        solution scattered back)."""
        from petsc4py import PETSc

        B = np.asarray(B, dtype=np.float64)
        if B.shape[0] != self.n_local:
            raise ValueError(f"right-hand side has {B.shape[0]} rows, factor has {self.n_local} here "
                             f"({self.n} x {self.n} in all)")
        sizes = (self.n_local, self.n)
        if B.ndim == 1:
            b = PETSc.Vec().createWithArray(np.ascontiguousarray(B), size=sizes, comm=self._comm)
            x = b.duplicate()
            self._F.solve(b, x)
            return x.getArray().copy()
        k = B.shape[1]
        if k == 0:
            return np.zeros_like(B)
        # PETSc dense matrices are column-major: a Fortran-ordered buffer is used in place
        Bf = np.asfortranarray(B)
        X = np.empty((self.n_local, k), dtype=np.float64, order="F")
        Bm = PETSc.Mat().createDense((sizes, (None, k)), array=Bf, comm=self._comm)
        Xm = PETSc.Mat().createDense((sizes, (None, k)), array=X, comm=self._comm)
        self._F.matSolve(Bm, Xm)
        Bm.destroy()
        Xm.destroy()
        # the solve's workspace comes in blocks below glibc's mmap threshold: kept by the
        # allocator it stayed resident through the eigen-solves (0.3 to 0.8 GB on the ~200k deck)
        return_freed_memory()
        return X

    def solve_columns(self, B: np.ndarray) -> np.ndarray:
        """The same as `solve` for B (n_local, k), one solve per column: the alternative
        to the block solve, kept for benchmarks/bench_mesh_to_rom.py --mpi to compare."""
        return np.column_stack([self.solve(np.ascontiguousarray(b)) for b in np.asarray(B).T])

    def destroy(self) -> None:
        """Free the factor (several GB on the default blade) now rather than at garbage collection.
        The factor matrix is released here too (this object holds a reference to it): only
        then is the factor freed (and MUMPS's out-of-core files deleted)."""
        if self._F is not None:
            self._F.destroy()
            self._F = None
        return_freed_memory()
