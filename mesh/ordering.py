"""Node order of a blade mesh: reverse Cuthill-McKee, so that the FEM matrices are banded.

gmsh numbers the vertices first and the mid-edge nodes it adds for the second order after
them, and a tet10 split of a wedge15/hex20 file appends its new nodes to the file's: a cell
then refers to nodes half the mesh apart, and the free dof (node-major in mesh order,
fem.assembly) give K and M a bandwidth of nearly the whole matrix (585 350 of the default
rotor 67 blade's 586 212 dof; 19 826 once renumbered): every sparse product of the
eigen-solves and the interface basis gathers rows from all over memory. Renumbered by
reverse Cuthill-McKee on the cells' node graph, a cell spans at most 3 % of the nodes
there (6 608 of 196 955, against 196 665 in gmsh's order), and mesh -> ROM is ~17 %
faster (README, node order); the Cholesky factorisations do not need it (CHOLMOD and
MUMPS apply their own fill-reducing order).
"""
from __future__ import annotations

import dataclasses

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import reverse_cuthill_mckee

from mesh.model import BladeMesh

#: Node orders a mesh can be written in: "rcm" (reverse Cuthill-McKee) or "meshed" (as the
#: mesher or the file gave them; for comparisons).
NODE_ORDERS = ("rcm", "meshed")


def node_graph(cells: np.ndarray, n_nodes: int) -> sp.csr_matrix:
    """(n_nodes, n_nodes) CSR pattern: i ~ j when a cell holds both (the pattern of K per
    dof direction). cells: (n_cells, k) 0-based node indices."""
    cells = np.asarray(cells)
    k = cells.shape[1]
    idx = np.int32 if n_nodes < 2 ** 31 else np.int64
    rows = np.repeat(cells.astype(idx), k, axis=1).ravel()
    cols = np.tile(cells.astype(idx), (1, k)).ravel()
    G = sp.csr_matrix((np.ones(len(rows), dtype=np.int8), (rows, cols)), shape=(n_nodes, n_nodes))
    G.data[:] = 1  # duplicates were summed
    return G


def bandwidth(cells: np.ndarray) -> int:
    """Largest |i - j| over the node pairs of one cell. cells: (n_cells, k)."""
    cells = np.asarray(cells)
    return int((cells.max(axis=1) - cells.min(axis=1)).max()) if len(cells) else 0


def rcm_order(cells: np.ndarray, n_nodes: int) -> np.ndarray:
    """(n_nodes,) permutation: new node i is old node order[i] (reverse Cuthill-McKee on the
    cells' node graph; deterministic: scipy starts each component at a node of least degree)."""
    return np.asarray(reverse_cuthill_mckee(node_graph(cells, n_nodes), symmetric_mode=True), dtype=np.int64)


def renumber_nodes(mesh: BladeMesh, order: str = "rcm") -> BladeMesh:
    """The same mesh with its nodes in `order` (one of NODE_ORDERS); every node index it holds
    (cells, root and tip facets, contact nodes) and every per-node array (coordinates, the
    source file's node ids) follow. "meshed" returns the mesh itself."""
    if order not in NODE_ORDERS:
        raise ValueError(f"node order must be one of {NODE_ORDERS}, got {order!r}")
    if order == "meshed":
        return mesh
    perm = rcm_order(mesh.cells, mesh.n_nodes)
    new = np.empty(mesh.n_nodes, dtype=np.int64)
    new[perm] = np.arange(mesh.n_nodes)
    ids = None if mesh.source_node_ids is None else np.ascontiguousarray(mesh.source_node_ids[perm])
    return dataclasses.replace(
        mesh, nodes=np.ascontiguousarray(mesh.nodes[perm]), cells=new[mesh.cells],
        root_facets=new[mesh.root_facets], tip_facets=new[mesh.tip_facets],
        boundary_node_index=new[mesh.boundary_node_index], source_node_ids=ids)
