"""The blade mesh as the later stages see it (plain numpy; what mesh.h5 holds)."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class BladeMesh:
    """Quadratic tetrahedral mesh of a blade with its root, tip and contact nodes.

    Global frame: z is the rotation axis (the table's axial distance), x = r cos(theta),
    y = r sin(theta). An imported mesh file (mesh.imported) is brought into this frame by
    x = source_scale * source_rotation @ x_file (results go back by the transpose).
    Connectivity uses gmsh's node ordering (tet10: 4 vertices, then the mid-edge nodes of
    edges 01, 12, 20, 30, 32, 31; tri6: 3 vertices, then 01, 12, 20).

    nodes: (n, 3), m. cells: (n_cells, 10) tet10, 0-based node indices.
    root_facets: (n_root, 6) tri6 of the clamped root face; every node on them is clamped.
        An imported mesh clamped on a node set that holds nodes on no complete boundary
        facet lists each such node as a degenerate row (the node six times).
    tip_facets: (n_tip, 6) tri6.
    boundary_node_index: (n_b,) mesh nodes of the contact points, LE (0) to TE (n_b - 1).
    boundary_xyz: (n_b, 3), m. boundary_rho: (n_b,) radius, m.
    boundary_theta: (n_b,) angular position relative to the LE node, rad, in (-pi, pi].
    boundary_frames: (n_b, 3, 3), rows e_r, e_theta, e_z (global components).
    volume: volume of the meshed solid, m^3.
    reference_volume: independent section-wise integral of the tabulated thickness, m^3;
        for an imported mesh, the volume of the file's own elements (Gauss quadrature of
        their wedge15/hex20/tet10 Jacobians), m^3.
    source_rotation: (3, 3) proper rotation from the source's frame to this one (identity
        for the tables). source_scale: metres per source length unit (1 for the tables,
        whose nodes are made in metres).
    source_node_ids: (n,) node ids as numbered in the imported file, -1 for the mid-edge
        nodes the split into tet10 created; None for a mesh made from a table.
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
    source_rotation: np.ndarray = field(default_factory=lambda: np.eye(3), metadata={"unit": "1"})
    source_scale: float = field(default=1.0, metadata={"unit": "m"})
    source_node_ids: np.ndarray | None = field(default=None, metadata={"unit": "1"})

    @property
    def n_nodes(self) -> int:
        return int(self.nodes.shape[0])
