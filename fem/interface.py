"""Craig-Bampton ingredients from one factorisation of the full free-dof stiffness.

With K (free dof) partitioned into interior i and boundary b dof, and
K^{-1} = [[A, B], [B^T, D]], the columns U = K^{-1} E_b (one block solve of 3 n_b
right-hand sides) give B and D, and
  constraint modes  Psi = -K_ii^{-1} K_ib = B D^{-1}   (U D^{-1} has identity boundary rows)
  K_ii^{-1} x       = (K^{-1} [x; 0])_i - Psi (K^{-1} [x; 0])_b.
So the factor of K that yields the full-model modes also yields the constraint modes and
the fixed-interface modes: the mesh -> ROM chain factorises once (the factorisation is
~1.6e12 flop on the default blade, the largest single cost).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from fem.modes import solve_eigenproblem


@dataclass(frozen=True)
class InterfaceBasis:
    """Constraint and fixed-interface modes for a set of boundary nodes (global x, y, z dof).

    boundary_dofs: (3 n_b,) free-dof indices, node-major [x_1, y_1, z_1, x_2, ...].
    constraint_modes: (n_free, 3 n_b), displacement for a unit displacement of each boundary
        dof with the others at 0, m/m; rows boundary_dofs are the identity.
    fixed_interface_modes: (n_free, eta), M-orthonormal with the boundary dof held at 0, kg^-1/2.
    fixed_interface_frequencies: (eta,), rad/s.
    """

    boundary_dofs: np.ndarray = field(metadata={"unit": "1"})
    constraint_modes: np.ndarray = field(metadata={"unit": "m/m"})
    fixed_interface_modes: np.ndarray = field(metadata={"unit": "kg^-0.5"})
    fixed_interface_frequencies: np.ndarray = field(metadata={"unit": "rad/s"})
    n_solves: int = 0


def boundary_dofs_of(node_dofs: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    """Free-dof indices (3 len(nodes),) of the given mesh nodes; error if one is clamped."""
    nodes = np.asarray(nodes, dtype=np.int64)
    if nodes.ndim != 1 or len(nodes) == 0:
        raise ValueError(f"boundary nodes must be a non-empty 1-D index array, got shape {nodes.shape}")
    outside = nodes[(nodes < 0) | (nodes >= len(node_dofs))]
    if outside.size:
        raise ValueError(f"boundary nodes {outside.tolist()} are outside the mesh's nodes 0..{len(node_dofs) - 1}")
    seen, count = np.unique(nodes, return_counts=True)
    if (count > 1).any():
        raise ValueError(f"boundary nodes must be distinct: nodes {seen[count > 1].tolist()} appear more than once")
    d = node_dofs[nodes]
    if (d < 0).any():
        raise ValueError(f"boundary nodes {nodes[(d < 0).any(axis=1)].tolist()} lie on the clamped root")
    return d.ravel()


def check_fixed_mode_count(n_fixed_modes: int, n_free: int, n_boundary_dofs: int,
                           key: str = "n_fixed_modes") -> None:
    """Raise ValueError naming `key` unless 0 <= n_fixed_modes <= n_free - n_boundary_dofs,
    the interior dof count: the fixed-interface problem has no more eigenpairs."""
    n_interior = n_free - n_boundary_dofs
    if not 0 <= n_fixed_modes <= n_interior:
        raise ValueError(f"{key} = {n_fixed_modes}, but the fixed-interface problem has only {n_interior} modes: "
                         f"allowed 0..{n_interior}, the interior dof count ({n_free} free dof less "
                         f"{n_boundary_dofs} boundary dof)")


def compute_interface_basis(K: sp.spmatrix, M: sp.spmatrix, boundary_dofs: np.ndarray, n_fixed_modes: int,
                            factor, start: np.ndarray | None = None, tol: float = 1e-10,
                            layout=None) -> InterfaceBasis:
    """Constraint modes and the first `n_fixed_modes` fixed-interface modes.

    K, M: (n_free, n_free). boundary_dofs: (n_bd,) free-dof indices.
    factor: fem.cholesky.CholeskyFactor of the whole K (not K_ii).
    start: optional (n_free, k) start block for the fixed-interface eigen-solve (the
        full-model modes; on the blade they save no block step over a random start, the
        fixed-interface modes differ too much, but they cost nothing).
    layout: fem.distributed.Distributed when K, M, the factor, `start` and the returned
        modes are this rank's rows (boundary_dofs stay global); None: all on this process.
    """
    from fem.distributed import Local

    n = K.shape[0]
    layout = Local(n) if layout is None else layout
    bd = np.asarray(boundary_dofs, dtype=np.int64)
    check_fixed_mode_count(n_fixed_modes, n, len(bd),
                           "n_fixed_modes (the fem stage's max of [fem] n_fixed_interface_modes, [rom] n_fixed_modes)")
    mine, bd_loc = layout.local_rows(bd)  # this rank's boundary rows and their columns
    E = np.zeros((layout.n_local, len(bd)))
    E[bd_loc, mine] = 1.0
    U = factor.solve(E)
    del E
    D = layout.rows(U, bd)
    # U D^{-1} as (D^{-T} U^T)^T; D = (K^{-1})_bb is a small (3 n_b)^2 SPD compliance block
    Psi = np.linalg.solve(D, U.T).T
    del U
    Psi[bd_loc] = np.eye(len(bd))[mine]  # exact by construction; remove round-off

    def apply_inverse_ii(B):
        B = B.copy()
        B[bd_loc] = 0.0
        Y = factor.solve(B)
        Y -= Psi @ layout.rows(Y, bd)
        Y[bd_loc] = 0.0
        return Y

    if n_fixed_modes == 0:
        return InterfaceBasis(boundary_dofs=bd, constraint_modes=Psi,
                              fixed_interface_modes=np.zeros((layout.n_local, 0)),
                              fixed_interface_frequencies=np.zeros(0))
    # no residuals: InterfaceBasis does not keep them, and K need not be read for them
    r = solve_eigenproblem(K, M, n_fixed_modes, apply_inverse_ii, fixed=bd_loc, tol=tol, start=start,
                           layout=layout, residuals=False)
    return InterfaceBasis(boundary_dofs=bd, constraint_modes=Psi, fixed_interface_modes=r.vectors,
                          fixed_interface_frequencies=np.sqrt(np.clip(r.eigenvalues, 0.0, None)),
                          n_solves=1 + r.n_solves)
