"""Lowest eigenpairs of K x = w^2 M x by block Krylov on a reused Cholesky factor.

Why not SLEPc's Krylov-Schur: it applies (K - sigma M)^{-1} one vector at a time, and on
the default blade one MUMPS solve costs ~3 s whatever the number of right-hand sides up to
~12 (the factor is streamed from memory once per solve). A block Krylov space
span{X, A X, A^2 X, ...}, A = K^{-1} M, grows by a whole block per solve; the Ritz pairs
come from the exact K and M projected on it, so the eigenvalues are Rayleigh quotients
(upper bounds that decrease monotonically as the space grows, error quadratic in the
subspace error). Convergence is declared when no wanted Ritz value moves by more than `tol`
(relative) in one block step; the residuals ||K x - lam M x|| / ||K x|| are reported, and
compute_modes refuses modes whose residual exceeds residual_limit(tol). (On thin blades a residual
test stalls at ~1e-7 for the first mode, a round-off floor of the cancellation in
K x - lam M x, long after the eigenvalue has converged to 1e-14: so the residual is a check
after convergence, not the convergence test.)
The spectrum of A (1 / w^2) decays fast, so a few block steps suffice.

Memory: beside the factor, the basis is the eigen-solve's whole cost (n rows, 8 bytes per
entry). It is kept Euclidean-orthonormal, so that M V need not be stored (the Ritz problem
becomes H y = theta Gm y with Gm = V^T M V, and each block step multiplies by M once
more), and capped at n_modes + 4 blocks by a thick restart that keeps the best Ritz
vectors (see solve_eigenproblem). On the ~200k-node deck this took the FEM stage's peak
from 14.0 to 11.2 GB (with fem.symmetric's upper triangles) for the same number of block
solves and about the same time; on the default table blade, where the solves are cheaper
beside the products, the eigen-solves take ~25 % longer (README).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import scipy.linalg
import scipy.sparse as sp


@dataclass(frozen=True)
class EigenResult:
    """eigenvalues: (k,) w^2, rad^2/s^2, ascending. vectors: (n, k), M-orthonormal (kg^-1/2),
    each signed so that r^T x > 0 for a fixed random r (see solve_eigenproblem).
    residuals: (k,) ||K x - lam M x|| / ||K x||, NaN where not asked for. n_solves: block
    solves used."""

    eigenvalues: np.ndarray = field(metadata={"unit": "rad^2/s^2"})
    vectors: np.ndarray = field(metadata={"unit": "kg^-0.5"})
    residuals: np.ndarray = field(metadata={"unit": "1"})
    n_solves: int = 0


def _grow(H: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """Symmetric (m, m) from the old (m - k, m - k) block and the new columns (m, k)."""
    m, k = cols.shape
    out = np.empty((m, m))
    out[:m - k, :m - k] = H
    out[:, m - k:] = cols
    out[m - k:, :m - k] = cols[:m - k].T
    out[m - k:, m - k:] = 0.5 * (cols[m - k:] + cols[m - k:].T)
    return out


def _space_dimension(n: int, fixed: np.ndarray | None, layout) -> int:
    """Dimension of the eigenproblem's space: n less the distinct `fixed` rows of all ranks."""
    if fixed is None:
        return n
    held = np.zeros((layout.n_local, 1))
    held[np.asarray(fixed, dtype=np.int64)] = 1.0
    return n - int(round(float(layout.dot(held, held)[0, 0])))


def solve_eigenproblem(K: sp.spmatrix, M: sp.spmatrix, n_modes: int,
                       apply_inverse: Callable[[np.ndarray], np.ndarray], *,
                       fixed: np.ndarray | None = None, block_size: int | None = None,
                       max_basis: int | None = None, tol: float = 1e-10, max_steps: int = 40, seed: int = 0,
                       start: np.ndarray | None = None, layout=None, residuals: bool = True) -> EigenResult:
    """Lowest `n_modes` eigenpairs of K x = lam M x (K, M: (n, n) SPD sparse).

    n_modes: 1 up to the problem's dof, n less the `fixed` ones (ValueError beyond: the
        space holds no more eigenpairs).

    apply_inverse(B): (n, k) -> K^{-1} B, or the constrained inverse when `fixed` is given.
    fixed: dof indices held at zero (the problem is then the one on the other dof); the
        vectors keep those rows at 0 and apply_inverse must return them at 0.
    block_size: right-hand sides per solve (default n_modes + 2, at least 6).
    max_basis: most columns the Krylov basis holds (default n_modes + 4 block_size). When the
        next block would not fit, the basis restarts from its n_modes + block_size best Ritz
        vectors (thick restart, see below): the basis is the eigen-solve's memory (7.6 MB
        per column on the ~200k deck), and without a cap the fixed-interface solve held 126
        columns at the FEM stage's peak.
    tol: bound on the relative change of every wanted Ritz value in the last block step.
    start: (n, k) start block (e.g. modes of a nearby problem); random columns fill it up
        to block_size.
    residuals: compute the residuals (one product with K, which is used for nothing else:
        a K waiting on disk, fem.symmetric, is read back for it).
    layout: fem.distributed.Distributed when K, M (DistributedMatrix), the blocks of
        apply_inverse, `start`, `fixed` (local row numbers) and the returned vectors are
        this rank's rows; None: everything on this process. The random start block is
        drawn for all n rows whatever the layout, so every rank count runs the same
        iteration.
    """
    from fem.distributed import Local

    n = K.shape[0]
    layout = Local(n) if layout is None else layout
    n_space = _space_dimension(n, fixed, layout)
    if not 1 <= n_modes <= n_space:
        raise ValueError(f"n_modes must be in 1..{n_space}, got {n_modes}: the problem has {n_space} dof "
                         f"({n} rows, {n - n_space} of them fixed)")
    n_loc = layout.n_local
    b = block_size or max(n_modes + 2, 6)
    rng = np.random.default_rng(seed)

    def restrict(X):
        if fixed is not None:
            X[fixed] = 0.0
        return X

    def orthonormalise(W, V):
        # Euclidean, against the basis (classical Gram-Schmidt twice: once loses
        # orthogonality, twice is enough), then within the block, dropping directions
        # already in the basis. Euclidean rather than M-orthonormal so that no M V is kept.
        for _ in range(2):
            W = W - V @ layout.dot(V, W)
        s, U = np.linalg.eigh(layout.dot(W, W))
        keep = s > 1e-12 * s.max()
        # The space has n_space dimensions: once the basis holds them all, what is left of W
        # is round-off, which the relative test above keeps (it is relative to W's own largest
        # direction) and which would make Gm singular. s is ascending: keep the largest.
        keep[:max(len(s) - max(n_space - V.shape[1], 0), 0)] = False
        return W @ (U[:, keep] / np.sqrt(s[keep]))

    X0 = layout.take(rng.standard_normal((n, b)))
    if start is not None:
        k0 = min(start.shape[1], b)
        X0[:, :k0] = start[:, :k0]
    W = orthonormalise(apply_inverse(M @ restrict(X0)), np.empty((n_loc, 0)))
    del X0
    # The basis V lives in a preallocated buffer of `cap` columns: appending with hstack
    # would copy it at each step (~1 GB on the default blade). A V (A = K^{-1} M,
    # constrained) is needed for its newest block only: the new columns of H and the next
    # Krylov block. M V is not kept: its new columns are recomputed (one more product with M
    # per block step, ~1 s on the ~200k deck, where keeping M V held 0.96 GB at the FEM
    # stage's peak).
    # Column-major, so that a block of columns is one contiguous slab: np.empty pages become
    # resident only when written, so a solve that converges early never pays for the whole
    # capacity. Row-major buffers would have every page touched by the first block
    # (measured: +1.2 GB peak on the 655k-dof box).
    n_keep = min(n_modes + b, n - 1)
    cap = max(max_basis or n_modes + 4 * b, n_keep + b)
    Vb = np.empty((n_loc, cap), order="F")
    m = 0
    H, Gm = np.zeros((0, 0)), np.zeros((0, 0))
    n_solves = 1
    lam_old = np.zeros(0)
    for step in range(max_steps):
        k_new = W.shape[1]
        Vb[:, m:m + k_new] = W
        m += k_new
        V = Vb[:, :m]
        # Rayleigh-Ritz on the inverse operator: theta = 1 / lam, from
        # H = V^T M K^{-1} M V and Gm = V^T M V. Projecting K itself would lose the lowest
        # eigenvalues to cancellation (x^T K x carries a round-off of eps * lam_max / lam_1,
        # ~1e-7 on a thin blade); V^T M K^{-1} M V does not.
        # Only the new columns are computed (n m b flop, not n m^2): both are symmetric, so
        # their new rows are the new columns transposed.
        MW = M @ W
        Gc = layout.dot(V, MW)
        Z = apply_inverse(MW)  # A applied to the newest block
        del MW
        n_solves += 1
        Hc = layout.dot(V, M @ Z)
        H, Gm = _grow(H, Hc), _grow(Gm, Gc)
        theta, Y = scipy.linalg.eigh(H, Gm)
        theta, Y = theta[::-1], Y[:, ::-1]
        k = min(n_modes, len(theta))
        lam = 1.0 / theta[:k]
        change = np.abs(lam - lam_old[:k]) / lam if len(lam_old) >= k else np.full(k, np.inf)
        lam_old = lam
        if layout.agree(bool(k == n_modes and np.all(change < tol))):
            X = V @ Y[:, :k]  # M-orthonormal: Y^T Gm Y = I
            del Vb, V, Z
            # An eigenvector's sign is arbitrary, and eigh may flip it for a round-off change
            # of H (seen between 1 and 2 MPI ranks): fix it by r^T x > 0 for a fixed random
            # r, which no round-off flips (|r^T x| ~ ||x||), so that every rank count, BLAS
            # and machine stores the same modes and the same ROM coupling blocks.
            r = layout.take(np.random.default_rng(seed + 1).standard_normal((n, 1)))
            X *= np.where(layout.dot(r, X)[0] < 0, -1.0, 1.0)
            res = np.full(k, np.nan)
            if residuals:
                KX = K @ X
                R = restrict(KX - (M @ X) * lam)
                res = layout.column_norms(R) / layout.column_norms(restrict(KX))
            return EigenResult(eigenvalues=lam, vectors=X, residuals=res, n_solves=n_solves)
        if m + b > cap:
            # Thick restart: keep the n_keep best Ritz vectors, and as the next block the
            # part of Z that is M-orthogonal to the whole old basis, Z - V Gm^{-1} V^T M Z
            # (V^T M Z is Hc). The residual of every Ritz vector, A x - theta x, lies in
            # that part's span (Galerkin: it is M-orthogonal to V, and lies in span(V, Z)), so
            # the new space holds A x for each kept x and the iteration goes on as a Krylov
            # one would for them (block thick-restart Lanczos, Wu and Simon's idea).
            Z -= V @ scipy.linalg.solve(Gm, Hc, assume_a="pos")
            Q = np.linalg.qr(Y[:, :n_keep])[0]  # V Q: Euclidean-orthonormal again
            for r0 in range(0, n_loc, 65536):  # in place, a slab of rows at a time
                Vb[r0:r0 + 65536, :n_keep] = Vb[r0:r0 + 65536, :m] @ Q
            H, Gm = Q.T @ H @ Q, Q.T @ Gm @ Q
            m = n_keep
            V = Vb[:, :m]
        # next Krylov block: A applied to the newest block
        W = orthonormalise(Z, V)
        del Z
    raise RuntimeError(f"eigen-solver did not converge in {max_steps} block steps: "
                       f"Ritz value changes {change} (tol {tol})")


#: Largest relative residual ||K x - w^2 M x|| / ||K x|| accepted for a full-model mode, -.
#: This residual weighs a vector's error by the stiffness of its parts, so high-frequency
#: parts of negligible energy dominate it: at the default tol (1e-10) the last mode's residual
#: was 7.8e-6 on a 5 139-dof box (eigenvalues right to 2e-12 against ARPACK) and 1.3e-4 on the
#: default blade (587k dof), and it grows with the mesh's lam_max / lam. 1e-2 leaves a
#: factor ~100 above that, and still refuses a pair that is not one of (K, M): the modes of a
#: factor of 1.05 K have a residual of 0.05. A looser `tol` leaves larger residuals on good
#: eigenvalues (tol = 1e-4: 5e-2 on the box's sixth mode, its eigenvalue right to 5e-8), about
#: as tol^0.6: the limit is max(RESIDUAL_TOL, 1e3 sqrt(tol)) (residual_limit).
RESIDUAL_TOL = 1e-2


def residual_limit(tol: float) -> float:
    """The largest residual accepted after a solve to the eigenvalue change `tol`, -."""
    return max(RESIDUAL_TOL, 1e3 * float(np.sqrt(tol)))


def check_residuals(residuals: np.ndarray, frequencies_hz: np.ndarray, tol: float = RESIDUAL_TOL) -> None:
    """Raise RuntimeError naming every mode (1-based, with its frequency) whose relative
    residual (n_modes,) exceeds `tol` or is not finite; NaN (not computed) is refused too."""
    bad = np.flatnonzero(~(np.asarray(residuals) <= tol))
    if bad.size:
        modes = ", ".join(f"mode {j + 1} ({frequencies_hz[j]:.6g} Hz): {residuals[j]:.3g}" for j in bad)
        raise RuntimeError(f"eigen-solver returned modes that are not eigenpairs of K, M: relative residual "
                           f"||K x - w^2 M x|| / ||K x|| above {tol:g} for {modes}")


@dataclass(frozen=True)
class ModalResult:
    """Full-model modes of the clamped blade.

    frequencies: (n_modes,), rad/s. frequencies_hz: (n_modes,), Hz.
    vectors: (n_free, n_modes) free-dof mode shapes, mass-normalised, kg^-1/2 (m per unit
        modal coordinate with kg^1/2).
    residuals: (n_modes,) relative residuals ||K x - w^2 M x|| / ||K x||, each <= residual_limit(tol).
    """

    frequencies: np.ndarray = field(metadata={"unit": "rad/s"})
    frequencies_hz: np.ndarray = field(metadata={"unit": "Hz"})
    vectors: np.ndarray = field(metadata={"unit": "kg^-0.5"})
    residuals: np.ndarray = field(metadata={"unit": "1"})
    n_solves: int = 0


def compute_modes(K: sp.spmatrix, M: sp.spmatrix, n_modes: int, factor=None,
                  tol: float = 1e-10, layout=None) -> ModalResult:
    """First `n_modes` eigenpairs of the free-dof system (K, M: (n_free, n_free)).

    factor: a fem.cholesky.CholeskyFactor of K to reuse; made (and kept by nobody) if None.
    layout: see solve_eigenproblem (vectors are then this rank's rows).
    Raises RuntimeError when a mode's residual exceeds residual_limit(tol) (check_residuals): the
    solve stops on the change of the eigenvalues, which says nothing of a factor that is not
    one of this K.
    """
    from fem.cholesky import CholeskyFactor

    if factor is None:
        factor = CholeskyFactor(K)
    r = solve_eigenproblem(K, M, n_modes, factor.solve, tol=tol, layout=layout)
    w = np.sqrt(np.clip(r.eigenvalues, 0.0, None))
    check_residuals(r.residuals, w / (2 * np.pi), residual_limit(tol))
    return ModalResult(frequencies=w, frequencies_hz=w / (2 * np.pi), vectors=r.vectors, residuals=r.residuals,
                       n_solves=r.n_solves)
