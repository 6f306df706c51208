"""Quadratic tetrahedra (tet10) in gmsh node ordering: shape functions, Jacobians, volumes.

Ordering: vertices 0..3 at reference (0,0,0), (1,0,0), (0,1,0), (0,0,1), then the mid-edge
nodes of edges 01, 12, 20, 30, 32, 31. Plain numpy, so that checks of a mesh do not depend
on the mesher that produced it.
"""
from __future__ import annotations

import numpy as np

EDGES = ((0, 1), (1, 2), (2, 0), (3, 0), (3, 2), (3, 1))

# Keast's 5-point rule, exact for cubics: det J of a tet10 is a cubic in the reference coords.
_A, _B = 0.5, 1.0 / 6.0
KEAST5_POINTS = np.array([[0.25, 0.25, 0.25], [_B, _B, _B], [_A, _B, _B], [_B, _A, _B], [_B, _B, _A]])
KEAST5_WEIGHTS = np.array([-4.0 / 5.0, 9.0 / 20.0, 9.0 / 20.0, 9.0 / 20.0, 9.0 / 20.0]) / 6.0

# Where validity is checked: vertices, mid-edges, face centroids, centroid and Keast points.
CHECK_POINTS = np.vstack([
    [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]],
    [[0.5, 0, 0], [0.5, 0.5, 0], [0, 0.5, 0], [0, 0, 0.5], [0, 0.5, 0.5], [0.5, 0, 0.5]],
    [[1 / 3, 1 / 3, 0], [1 / 3, 0, 1 / 3], [0, 1 / 3, 1 / 3], [1 / 3, 1 / 3, 1 / 3]],
    KEAST5_POINTS,
])


def shape_gradients(points: np.ndarray) -> np.ndarray:
    """(p, 10, 3) derivatives of the 10 shape functions w.r.t. reference coords at (p, 3) points."""
    points = np.atleast_2d(points)
    lam = np.column_stack([1.0 - points.sum(1), points])  # (p, 4) barycentric
    dlam = np.array([[-1.0, -1.0, -1.0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])  # (4, 3)
    g = np.empty((points.shape[0], 10, 3))
    for i in range(4):  # N_i = L_i (2 L_i - 1)
        g[:, i] = (4.0 * lam[:, i] - 1.0)[:, None] * dlam[i]
    for k, (a, b) in enumerate(EDGES):  # N = 4 L_a L_b
        g[:, 4 + k] = 4.0 * (lam[:, a, None] * dlam[b] + lam[:, b, None] * dlam[a])
    return g


def det3(J: np.ndarray) -> np.ndarray:
    """Determinants of (..., 3, 3) matrices by the rule of Sarrus (several times faster than
    np.linalg.det's batched LU on millions of 3 x 3 blocks)."""
    return (J[..., 0, 0] * (J[..., 1, 1] * J[..., 2, 2] - J[..., 1, 2] * J[..., 2, 1])
            - J[..., 0, 1] * (J[..., 1, 0] * J[..., 2, 2] - J[..., 1, 2] * J[..., 2, 0])
            + J[..., 0, 2] * (J[..., 1, 0] * J[..., 2, 1] - J[..., 1, 1] * J[..., 2, 0]))


def jacobians(x: np.ndarray, gradients: np.ndarray) -> np.ndarray:
    """(c, p, 3, 3) d(x_i)/d(xi_j) from (c, n, 3) node coordinates and (p, n, 3) shape gradients."""
    return np.tensordot(x, gradients, axes=([1], [1])).transpose(0, 2, 1, 3)  # BLAS, not einsum


def jacobian_determinants(nodes: np.ndarray, cells: np.ndarray, points: np.ndarray = CHECK_POINTS) -> np.ndarray:
    """(n_cells, p) det of d(x)/d(reference) of each tet10 at (p, 3) reference points (m^3 per unit)."""
    return det3(jacobians(nodes[cells], shape_gradients(points)))


def cell_volumes(nodes: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """(n_cells,) volumes of curved tet10 cells, m^3 (exact: Keast rule on the cubic det J)."""
    return jacobian_determinants(nodes, cells, KEAST5_POINTS) @ KEAST5_WEIGHTS
