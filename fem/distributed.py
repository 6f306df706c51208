"""Free-dof blocks spread over MPI ranks: the row layout and the products the solvers need.

Under MPI every distributed array of the FEM stage holds a contiguous block of rows of the
SERIAL free-dof numbering (node-major in mesh node order, fem.assembly.FemSystem), split at
node boundaries: rank r owns rows start..stop-1. The same numbering on every rank count
means that the random start block of the eigen-solver, the boundary dof of the interface
basis and the gathered results are those of one process; only the order of floating-point
sums differs. (dolfinx partitions the mesh with its own numbering for the assembly; the
assembled matrices are permuted into this layout once, fem.assembly.assemble_distributed.)

`Local` is the one-process layout: the same operations as plain numpy, so that the serial
code path is the distributed one with the communication left out.
"""
from __future__ import annotations

import numpy as np


class Local:
    """All n rows on this process (no MPI)."""

    comm = None

    def __init__(self, n: int):
        self.n, self.start, self.stop = int(n), 0, int(n)

    @property
    def n_local(self) -> int:
        return self.stop - self.start

    def dot(self, A: np.ndarray, B: np.ndarray) -> np.ndarray:
        """A^T B for row blocks A (n_local, p), B (n_local, q) -> (p, q), the same on every rank."""
        return A.T @ B

    def column_norms(self, A: np.ndarray) -> np.ndarray:
        """2-norm of each column of a row block (n_local, k) -> (k,)."""
        return np.linalg.norm(A, axis=0)

    def take(self, X: np.ndarray) -> np.ndarray:
        """This rank's rows of an array with all n rows."""
        return X[self.start:self.stop]

    def local_rows(self, index: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """For global row indices `index` (k,): (positions in index, local row numbers) of
        those owned here."""
        index = np.asarray(index, dtype=np.int64)
        mine = np.flatnonzero((index >= self.start) & (index < self.stop))
        return mine, index[mine] - self.start

    def rows(self, X: np.ndarray, index: np.ndarray) -> np.ndarray:
        """X[index] of a row block X (n_local, k), for global rows `index`; on every rank."""
        return X[np.asarray(index, dtype=np.int64)]

    def gather(self, X: np.ndarray) -> np.ndarray | None:
        """All rows (n, ...) of a row block on rank 0; None on the other ranks."""
        return X

    def agree(self, value):
        """Rank 0's value of a decision, on every rank (keeps control flow in step)."""
        return value


class Distributed(Local):
    """Rows start..stop-1 of n on this rank of `comm` (mpi4py communicator)."""

    def __init__(self, comm, n: int, start: int, stop: int):
        super().__init__(n)
        self.comm, self.start, self.stop = comm, int(start), int(stop)
        self._counts = np.asarray(comm.allgather(self.n_local), dtype=np.int64)
        if self._counts.sum() != self.n:
            raise ValueError(f"row blocks of {self._counts.tolist()} rows do not add up to {self.n}")

    def _sum(self, a: np.ndarray) -> np.ndarray:
        # Reduce on rank 0, then broadcast: every rank gets the very same bits (an Allreduce
        # may sum in a rank-dependent order), so decisions taken on the result (block
        # deflation, convergence) agree on all ranks.
        from mpi4py import MPI

        a = np.ascontiguousarray(a, dtype=np.float64)
        out = np.empty_like(a)
        self.comm.Reduce(a, out, op=MPI.SUM, root=0)
        self.comm.Bcast(out, root=0)
        return out

    def dot(self, A, B):
        return self._sum(A.T @ B)

    def column_norms(self, A):
        return np.sqrt(self._sum(np.einsum("ij,ij->j", A, A)))

    def rows(self, X, index):
        index = np.asarray(index, dtype=np.int64)
        part = np.zeros((len(index),) + X.shape[1:])
        mine, loc = self.local_rows(index)
        part[mine] = X[loc]
        return self._sum(part)

    def gather(self, X):
        X = np.ascontiguousarray(X)
        width = int(np.prod(X.shape[1:], dtype=np.int64))
        counts = self._counts * width
        out = np.empty((self.n,) + X.shape[1:], dtype=X.dtype) if self.comm.rank == 0 else None
        self.comm.Gatherv(X, (out, counts) if out is not None else None, root=0)
        return out

    def agree(self, value):
        return self.comm.bcast(value, root=0)


class DistributedMatrix:
    """A PETSc MPIAIJ matrix in a `Distributed` row layout, applied to numpy row blocks.

    `A @ X` with X (n_local,) or (n_local, k) returns this rank's rows of the product.
    """

    def __init__(self, A, layout: Distributed):
        self.petsc, self.layout = A, layout
        self.shape = tuple(A.getSize())

    def __matmul__(self, X: np.ndarray) -> np.ndarray:
        from petsc4py import PETSc

        X = np.asarray(X, dtype=np.float64)
        cols = X.reshape(X.shape[0], -1)
        k = cols.shape[1]
        if k == 0:
            return np.zeros_like(X)
        n_loc = self.layout.n_local
        Xm = PETSc.Mat().createDense(((n_loc, self.shape[0]), (None, k)), array=np.asfortranarray(cols),
                                     comm=self.petsc.comm)
        Ym = self.petsc.matMult(Xm)
        Y = Ym.getDenseArray().copy(order="F")
        Xm.destroy()
        Ym.destroy()
        return Y.reshape(X.shape)

    def gather_csr(self):
        """The whole matrix as scipy CSR (int32 indices, sorted) on rank 0; None elsewhere."""
        import scipy.sparse as sp

        comm, layout = self.petsc.comm.tompi4py(), self.layout
        indptr, indices, data = self.petsc.getValuesCSR()
        nnz = np.asarray(comm.allgather(len(data)), dtype=np.int64)
        if nnz.sum() >= 2 ** 31:
            raise OverflowError(f"{nnz.sum()} nonzeros do not fit 32-bit CSR indices")
        root = comm.rank == 0
        all_data = np.empty(int(nnz.sum())) if root else None
        all_idx = np.empty(int(nnz.sum()), dtype=np.int32) if root else None
        comm.Gatherv(np.ascontiguousarray(data, dtype=np.float64), (all_data, nnz) if root else None, root=0)
        comm.Gatherv(np.ascontiguousarray(indices, dtype=np.int32), (all_idx, nnz) if root else None, root=0)
        counts = comm.gather(np.diff(indptr).astype(np.int64), root=0)
        if not root:
            return None
        indptr = np.concatenate([[0], np.cumsum(np.concatenate(counts))]).astype(np.int32)
        out = sp.csr_matrix((all_data, all_idx, indptr), shape=self.shape)
        out.sort_indices()
        return out

    def destroy(self) -> None:
        self.petsc.destroy()
