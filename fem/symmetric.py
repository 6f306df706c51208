"""A symmetric sparse matrix stored as its upper triangle, which can wait on disk.

K and M of the blade are symmetric: keeping both triangles doubles what the FEM stage holds
beside the Cholesky factor (1.87 GB against 0.93 GB on the ~200k-node wedge deck, whose
factor takes 9 GB). The product A X reads each stored entry once for both triangles
(y_i += a_ij x_j and y_j += a_ij x_i); it is bound by gathering rows of X, as scipy's CSR
product is, and costs about the same.

While K is factorised neither K nor M is needed in memory (the factorisation works on its
own copy), and K is needed again only for the residuals at the end of each eigen-solve:
`spill` writes the triangle to a folder and frees it; the matrix then reads it back through
a memory map whenever it is used (the pages come from the page cache and leave the resident
set when the map is dropped).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import scipy.sparse as sp
from numba import get_num_threads, njit, prange

_PARTS = ("data", "indices", "indptr")


@njit(parallel=True, cache=True)
def _product(indptr, indices, data, X, Y, n_chunks):
    # Threads own disjoint column ranges of Y, so no two write the same entry; the row loop
    # scatters into rows j > i as well, which a row split could not do without races.
    n, k = X.shape
    for chunk in prange(n_chunks):
        c0 = chunk * k // n_chunks
        c1 = (chunk + 1) * k // n_chunks
        for i in range(n):
            for p in range(indptr[i], indptr[i + 1]):
                j = indices[p]
                v = data[p]
                if j == i:
                    for c in range(c0, c1):
                        Y[i, c] += v * X[i, c]
                else:
                    for c in range(c0, c1):
                        Y[i, c] += v * X[j, c]
                        Y[j, c] += v * X[i, c]


@njit(cache=True)
def _lower_entries(indptr, indices) -> int:
    count = 0
    for i in range(len(indptr) - 1):
        for p in range(indptr[i], indptr[i + 1]):
            if indices[p] < i:
                count += 1
    return count


@njit(cache=True)
def _upper_part(indptr, indices, data):
    # scipy's triu goes through COO: 5 s and two extra copies on the ~200k deck's K
    n = len(indptr) - 1
    counts = np.zeros(n + 1, dtype=np.int64)
    for i in range(n):
        for p in range(indptr[i], indptr[i + 1]):
            if indices[p] >= i:
                counts[i + 1] += 1
    out_ptr = np.cumsum(counts).astype(indptr.dtype)
    out_idx = np.empty(out_ptr[n], dtype=indices.dtype)
    out_data = np.empty(out_ptr[n], dtype=data.dtype)
    q = 0
    for i in range(n):
        for p in range(indptr[i], indptr[i + 1]):
            if indices[p] >= i:
                out_idx[q] = indices[p]
                out_data[q] = data[p]
                q += 1
    return out_ptr, out_idx, out_data


@njit(cache=True)
def _both_triangles(indptr, indices, data):
    # every stored entry, explicit zeros included (the pattern is part of fem.h5's contract);
    # row r gets its lower part (columns < r, ascending with the source row) first, then
    # its own upper part: sorted without a sort
    n = len(indptr) - 1
    counts = np.zeros(n + 1, dtype=np.int64)
    for i in range(n):
        counts[i + 1] += indptr[i + 1] - indptr[i]
        for p in range(indptr[i], indptr[i + 1]):
            if indices[p] != i:
                counts[indices[p] + 1] += 1
    out_ptr = np.cumsum(counts)
    out_idx = np.empty(out_ptr[n], dtype=indices.dtype)
    out_data = np.empty(out_ptr[n], dtype=data.dtype)
    fill = out_ptr[:n].copy()
    for i in range(n):
        for p in range(indptr[i], indptr[i + 1]):
            j = indices[p]
            if j != i:
                out_idx[fill[j]] = i
                out_data[fill[j]] = data[p]
                fill[j] += 1
    for i in range(n):
        for p in range(indptr[i], indptr[i + 1]):
            out_idx[fill[i]] = indices[p]
            out_data[fill[i]] = data[p]
            fill[i] += 1
    return out_ptr, out_idx, out_data


class SymmetricMatrix:
    """A real symmetric (n, n) sparse matrix held as its upper triangle (CSR, sorted indices).

    `A @ X` for X (n,) or (n, k) returns the product with the whole matrix (float64).
    """

    def __init__(self, upper: sp.csr_matrix):
        upper = sp.csr_matrix(upper)
        n = upper.shape[0]
        if upper.shape != (n, n):
            raise ValueError(f"matrix must be square, got shape {upper.shape}")
        if _lower_entries(upper.indptr, upper.indices):
            raise ValueError("SymmetricMatrix takes the upper triangle only (entries below the diagonal found)")
        upper.sort_indices()
        self.shape = (n, n)
        self.nnz_upper = int(upper.nnz)
        self._upper: sp.csr_matrix | None = upper
        self._folder: Path | None = None

    @classmethod
    def from_csr(cls, A: sp.spmatrix) -> "SymmetricMatrix":
        """The upper triangle of A (A is taken to be symmetric; its lower triangle is not read)."""
        A = sp.csr_matrix(A)  # (the constructor refuses a matrix that is not square)
        indptr, indices, data = _upper_part(A.indptr, A.indices, A.data)
        return cls(sp.csr_matrix((data, indices, indptr), shape=A.shape))

    @property
    def spilled(self) -> bool:
        return self._upper is None

    def upper(self) -> sp.csr_matrix:
        """The stored upper triangle (n, n) CSR: in memory, or memory-mapped from the folder
        `spill` wrote (read only; the map is dropped with the returned matrix)."""
        if self._upper is not None:
            return self._upper
        # plain ndarray views of the maps (numba types ndarrays, not np.memmap)
        parts = [np.asarray(np.load(self._folder / f"{p}.npy", mmap_mode="r")) for p in _PARTS]
        U = sp.csr_matrix(self.shape)  # no copy of the mapped arrays: assigned, not converted
        U.data, U.indices, U.indptr = parts
        return U

    def spill(self, folder: Path | str) -> None:
        """Write the triangle to `folder` (which the caller owns and removes) and free it."""
        if self._upper is None:
            return
        folder = Path(folder)
        for p in _PARTS:
            np.save(folder / f"{p}.npy", getattr(self._upper, p))
        self._folder, self._upper = folder, None

    def to_csr(self) -> sp.csr_matrix:
        """The whole matrix, both triangles, as CSR with sorted indices and the stored
        pattern (explicit zeros kept)."""
        U = self.upper()
        indptr, indices, data = _both_triangles(U.indptr, U.indices, U.data)
        if indptr[-1] < 2 ** 31:
            indptr = indptr.astype(np.int32)
        A = sp.csr_matrix((data, indices, indptr), shape=self.shape)
        A.has_sorted_indices = True
        return A

    def without_zeros(self) -> "SymmetricMatrix":
        """A copy without the explicit zeros of the pattern: the same products, cheaper (the
        consistent mass of a vector field has no coupling between directions: 2/3 of the
        entries of the assembled M are structural zeros)."""
        U = self.upper().copy()
        U.eliminate_zeros()
        return SymmetricMatrix(U)

    def __matmul__(self, X: np.ndarray) -> np.ndarray:
        X = np.asarray(X, dtype=np.float64)
        if X.shape[0] != self.shape[0]:
            raise ValueError(f"cannot multiply a {self.shape} matrix by an array of shape {X.shape}")
        cols = np.ascontiguousarray(X.reshape(X.shape[0], -1))
        Y = np.zeros_like(cols)
        if cols.shape[1]:
            U = self.upper()
            _product(U.indptr, U.indices, U.data, cols, Y, max(1, min(get_num_threads(), cols.shape[1])))
        return Y.reshape(X.shape)
