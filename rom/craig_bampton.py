"""Craig-Bampton reduction of the clamped blade onto its contact nodes (the ROM stage).

The expensive ingredients (constraint modes, fixed-interface modes) come with the FEM
result, computed from the factorisation of K that also gave the full-model modes; this
stage rotates the boundary dof into each node's cylindrical frame, projects K and M
(two sparse products with 39 columns), adds modal damping and builds the recovery matrix.
"""
from __future__ import annotations

import numpy as np

from rom.friction_lock import friction_lock
from rom.model import RomModel, check_frames, modal_damping
from rom.options import RomOptions
from rom.rotation import rotation_sign


def build_craig_bampton(fem, mesh, options: RomOptions = RomOptions(), store_recovery: bool = True,
                        rotation: str | int = "le-leads") -> RomModel:
    """Reduce a FEM result to the 3 n_b + eta dof Craig-Bampton model.

    fem: fem.analysis.FemResult (K, M, node_dofs, frequencies and, normally, the interface
        basis of mesh.boundary_node_index with >= options.n_fixed_modes fixed-interface modes;
        if that basis is missing or too short it is recomputed here, at the cost of a
        second factorisation of K).
    mesh: mesh.model.BladeMesh (boundary nodes, rho, theta, frames).
    store_recovery: keep the (3 n_nodes, n) float32 full-field recovery matrix.
    rotation: the scene's [blade] rotation ("+", "-", "le-leads") or a sign; stored as the
        sign s (rom.rotation.rotation_sign), with the friction-lock table it decides.
    Raises ValueError naming the field or option when fem's K, M, node_dofs or interface
    basis disagree (check_fem_layout, check_given_basis), or when options.n_fixed_modes
    exceeds the interior dof count (the fixed-interface problem has no more modes).
    """
    from fem.interface import boundary_dofs_of, check_fixed_mode_count

    nb_nodes = np.asarray(mesh.boundary_node_index, dtype=np.int64)
    frames = np.asarray(mesh.boundary_frames, dtype=np.float64)
    nb = len(nb_nodes)
    check_frames("boundary_frames", frames, nb)
    eta = options.n_fixed_modes
    K, M = fem.K, fem.M
    n_free = check_fem_layout(fem)
    bd = boundary_dofs_of(fem.node_dofs, nb_nodes)
    check_fixed_mode_count(eta, n_free, len(bd), "[rom] n_fixed_modes")

    have = (len(fem.boundary_dofs) == len(bd) and np.array_equal(fem.boundary_dofs, bd)
            and check_given_basis(fem, n_free) >= eta)
    if have:
        psi, phi, wfi = fem.constraint_modes, fem.fixed_interface_modes[:, :eta], fem.fixed_interface_frequencies[:eta]
    else:
        from fem.cholesky import CholeskyFactor
        from fem.interface import compute_interface_basis

        factor = CholeskyFactor(K)
        try:
            basis = compute_interface_basis(K, M, bd, eta, factor)
        finally:
            factor.destroy()
        psi, phi, wfi = basis.constraint_modes, basis.fixed_interface_modes, basis.fixed_interface_frequencies

    # Boundary dof in local frames: u_global = F^T u_local per node (F rows e_r, e_theta, e_z),
    # so the constraint modes for local unit displacements are Psi_global F^T, node by node.
    R = np.zeros((3 * nb, 3 * nb))
    for j in range(nb):
        R[3 * j:3 * j + 3, 3 * j:3 * j + 3] = frames[j].T
    T = np.hstack([psi @ R, phi])  # (n_free, 3 n_b + eta)
    KT, MT = K @ T, M @ T
    Kr, Mr = T.T @ KT, T.T @ MT
    Kr, Mr = 0.5 * (Kr + Kr.T), 0.5 * (Mr + Mr.T)
    n = Kr.shape[0]
    ratios = np.where(np.arange(n) < options.n_low_modes, options.damping_low, options.damping_high)
    C, w = modal_damping(Kr, Mr, ratios)

    recovery = None
    if store_recovery:
        # float32: the recovery only maps ROM dof to displacement fields for output; 7
        # significant digits are far below the ROM's own error, and it halves a matrix of
        # 3 n_nodes x 39 (~100 MB instead of ~200 MB on the default blade).
        nn = fem.node_dofs.shape[0]
        recovery = np.zeros((3 * nn, n), dtype=np.float32)
        free = fem.node_dofs.ravel() >= 0  # node-major x, y, z rows; free dof are node-major too
        recovery[free] = T
    xyz = np.asarray(mesh.boundary_xyz, dtype=np.float64)
    sign = rotation_sign(rotation, mesh.boundary_theta)
    return RomModel(K=Kr, M=Mr, C=C, rho=np.asarray(mesh.boundary_rho, dtype=np.float64),
                    theta=np.asarray(mesh.boundary_theta, dtype=np.float64), xyz=xyz, frames=frames,
                    node_index=nb_nodes, fixed_interface_frequencies=np.asarray(wfi, dtype=np.float64),
                    frequencies=w, full_frequencies=np.asarray(fem.frequencies, dtype=np.float64),
                    damping_ratios=ratios, rotation=sign, friction_lock=friction_lock(Kr, nb, sign),
                    recovery=recovery)


def check_fem_layout(fem) -> int:
    """n_free after checking that K and M are (n_free, n_free) and that node_dofs, (n_nodes, 3),
    numbers those dof 0..n_free-1 in node order (fem.assembly's layout, -1 on the root): the
    boundary dof and the recovery's rows are read from it, so a node_dofs of another model
    would pick other dof of K. Raises ValueError naming the field."""
    n_free = fem.K.shape[0]
    if fem.K.shape != (n_free, n_free) or fem.M.shape != (n_free, n_free):
        raise ValueError(f"the FEM result's K and M must be square and of one size, got K {fem.K.shape}, "
                         f"M {fem.M.shape}")
    node_dofs = np.asarray(fem.node_dofs)
    if node_dofs.ndim != 2 or node_dofs.shape[1] != 3 or not np.issubdtype(node_dofs.dtype, np.integer):
        raise ValueError(f"node_dofs must be an (n_nodes, 3) integer array, got shape {node_dofs.shape}, "
                         f"dtype {node_dofs.dtype}")
    free = node_dofs[node_dofs >= 0]
    if not np.array_equal(free, np.arange(n_free)):
        raise ValueError(f"node_dofs does not number K's {n_free} free dof 0..{n_free - 1} in node order (it holds "
                         f"{free.size} free dof): K, M and node_dofs are not of one model")
    return n_free


def check_given_basis(fem, n_free: int) -> int:
    """The number k of fixed-interface modes the FEM result holds, after checking the shapes
    of its interface basis: constraint_modes (n_free, len(boundary_dofs)),
    fixed_interface_modes (n_free, k), fixed_interface_frequencies (k,); raises ValueError
    naming the field (a corrupt fem.h5 would otherwise be projected as it is)."""
    k = np.size(fem.fixed_interface_frequencies)
    for name, want, meaning in (("constraint_modes", (n_free, len(fem.boundary_dofs)), "n_free, boundary dof"),
                                ("fixed_interface_modes", (n_free, k), "n_free, one per frequency"),
                                ("fixed_interface_frequencies", (k,), "one per fixed-interface mode")):
        if np.shape(getattr(fem, name)) != want:
            raise ValueError(f"the FEM result's {name} must have shape {want} ({meaning}), "
                             f"got {np.shape(getattr(fem, name))}")
    return k
