"""The blade mesh as the later stages see it (plain numpy; what mesh.h5 holds)."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class BladeMesh:
    """Quadratic tetrahedral mesh of a blade with its root, tip and contact nodes.

    Global frame: z is the rotation axis (the table's axial distance), x = r cos(theta),
    y = r sin(theta). Connectivity uses gmsh's node ordering (tet10: 4 vertices, then the
    mid-edge nodes of edges 01, 12, 20, 30, 32, 31; tri6: 3 vertices, then 01, 12, 20).

    nodes: (n, 3), m. cells: (n_cells, 10) tet10, 0-based node indices.
    root_facets: (n_root, 6) tri6 of the clamped root face. tip_facets: (n_tip, 6) tri6.
    boundary_node_index: (n_b,) mesh nodes of the contact points, LE (0) to TE (n_b - 1).
    boundary_xyz: (n_b, 3), m. boundary_rho: (n_b,) radius, m.
    boundary_theta: (n_b,) angular position relative to the LE node, rad.
    boundary_frames: (n_b, 3, 3), rows e_r, e_theta, e_z (global components).
    volume: volume of the meshed solid, m^3.
    reference_volume: independent section-wise integral of the tabulated thickness, m^3.
    """

    nodes: np.ndarray = field(metadata={"unit": "m"})
    cells: np.ndarray = field(metadata={"unit": "1"})
    root_facets: np.ndarray = field(metadata={"unit": "1"})
    tip_facets: np.ndarray = field(metadata={"unit": "1"})
    boundary_node_index: np.ndarray = field(metadata={"unit": "1"})
    boundary_xyz: np.ndarray = field(metadata={"unit": "m"})
    boundary_rho: np.ndarray = field(metadata={"unit": "m"})
    boundary_theta: np.ndarray = field(metadata={"unit": "rad"})
    boundary_frames: np.ndarray = field(metadata={"unit": "1"})
    volume: float = field(default=float("nan"), metadata={"unit": "m^3"})
    reference_volume: float = field(default=float("nan"), metadata={"unit": "m^3"})
    cell_type: str = "tetra10"

    @property
    def n_nodes(self) -> int:
        return int(self.nodes.shape[0])
