"""Conforming split of quadratic wedges and hexahedra into 10-node tetrahedra.

dolfinx 0.5.2 assembles quadratic tetrahedra but neither quadratic prisms nor serendipity
hexahedra, so an imported wedge15/hex20 mesh is split:

- Which tetrahedra: the "smallest vertex" (pulling) rule of Dompierre, Labbé, Vallet and
  Camarero (1999), "How to subdivide pyramids, prisms and hexahedra into tetrahedra".
  Every quadrilateral face is cut along the diagonal through its smallest global vertex
  index, a rule the two elements sharing the face agree on; each element is then the union
  of the cones from its own smallest vertex over the (triangulated) faces that do not
  contain it: 3 tetrahedra per wedge, 6 per hexahedron. The faces through that vertex get
  its diagonal too (it is also their smallest vertex), so the split is conforming, and it
  is valid on any convex reference element, so no configuration needs an extra point.
- Where the new mid-edge nodes go: every new edge (a face diagonal, or the hexahedron's
  body diagonal) gets its mid node on the element's own quadratic geometry, the wedge15 /
  hex20 map evaluated at the edge's midpoint in the reference element. Curved faces stay
  curved, and two neighbours compute the same point for a shared face diagonal (the face's
  map depends on the face's nodes only); the node is created once, keyed by the edge's
  global vertex pair.

For straight-sided elements the tet10 cells reproduce the parent's geometry exactly (on
planar boundary faces the union of the tet10 cells is the union of the parents, so the
volume is preserved to round-off); on curved elements the tet10 faces interpolate the
parent's quadratic faces at their six nodes.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from mesh.elements import ReferenceElement
from mesh.tet10 import EDGES as TET10_EDGES

VTK_TO_GMSH_TET10 = np.array([0, 1, 2, 3, 4, 5, 6, 7, 9, 8])  # mid nodes 13, 23 swap places


@dataclass(frozen=True)
class Subdivision:
    """The tetrahedral mesh of a split.

    nodes: (n_orig + n_new, 3), the original nodes first, in their order; then the new
        mid-edge nodes, in the units of the input.
    cells: (n_tets, 10) tet10 in gmsh ordering (BladeMesh's), positively oriented in the
        reference element of their parent.
    parent: (n_tets,) index of the source element, counting the blocks' elements in order.
    weights: (n_new, n_orig) CSR: the shape-function values that place each new node,
        new = weights @ original (the parent's nodes with a non-zero value).
    """

    nodes: np.ndarray
    cells: np.ndarray
    parent: np.ndarray
    weights: sp.csr_matrix


def pulled_tetrahedra(element: ReferenceElement, vertices: np.ndarray) -> np.ndarray:
    """(k, T, 4) local corner indices of the tetrahedra of k elements, positively oriented.

    vertices: (k, n_v) global indices of the elements' corners (they decide the diagonals).
    """
    k = len(vertices)
    p0 = np.argmin(vertices, axis=1)
    n_tets = 2 * sum(len(f) == 4 for f in element.faces if 0 not in f) + sum(
        len(f) == 3 for f in element.faces if 0 not in f)
    tets = np.empty((k, n_tets, 4), dtype=np.int64)
    for p in range(element.n_vertices):
        sel = np.flatnonzero(p0 == p)
        if sel.size == 0:
            continue
        tris = []
        for f in element.faces:
            if p in f:
                continue
            if len(f) == 3:
                tris.append(np.broadcast_to(np.array(f), (sel.size, 3)))
                continue
            a, b, c, d = f
            m = np.argmin(vertices[np.ix_(sel, f)], axis=1)
            ac = (m % 2 == 0)[:, None]  # smallest vertex is a or c: diagonal a-c, else b-d
            tris.append(np.where(ac, [a, b, c], [b, c, d]))
            tris.append(np.where(ac, [a, c, d], [b, d, a]))
        if len(tris) != n_tets:
            raise AssertionError(f"{element.name}: {len(tris)} tetrahedra from corner {p}, expected {n_tets}")
        t = np.stack(tris, axis=1)  # (sel, T, 3)
        tets[sel] = np.concatenate([np.full((sel.size, n_tets, 1), p), t], axis=2)
    x = element.vertices[tets]  # (k, T, 4, 3)
    det = np.linalg.det(x[:, :, 1:] - x[:, :, :1])
    if np.any(np.abs(det) < 1e-12):
        raise AssertionError(f"{element.name}: degenerate tetrahedron in the reference split")
    flip = det < 0
    tets[flip, 2], tets[flip, 3] = tets[flip, 3].copy(), tets[flip, 2].copy()
    return tets


def subdivide(points: np.ndarray, blocks: list[tuple[ReferenceElement | None, np.ndarray]]) -> Subdivision:
    """Split quadratic elements into conforming tet10.

    points: (n_orig, 3) node coordinates. blocks: (element, connectivity) pairs, the
    connectivity (k, n) 0-based in VTK/Abaqus node order; element None means tet10 (kept
    as they are, reordered to gmsh's convention).
    """
    points = np.asarray(points, dtype=np.float64)
    n_orig = len(points)
    cells, parents = [], []
    # new-edge entries: block, element, local corners a and b, global vertex pair, and the
    # flat position in the cell array that the new node fills
    ent_block, ent_elem, ent_a, ent_b, ent_lo, ent_hi, ent_pos = [], [], [], [], [], [], []
    n_elements = n_cells = 0
    for ib, (element, conn) in enumerate(blocks):
        conn = np.asarray(conn, dtype=np.int64)
        if element is None:
            cells.append(conn[:, VTK_TO_GMSH_TET10])
            parents.append(n_elements + np.arange(len(conn)))
            n_elements += len(conn)
            n_cells += len(conn)
            continue
        nv = element.n_vertices
        local = pulled_tetrahedra(element, conn[:, :nv])  # (k, T, 4)
        k, T = local.shape[:2]
        edge_mid = np.full((nv, nv), -1, dtype=np.int64)
        for j, (a, b) in enumerate(element.edges):
            edge_mid[a, b] = edge_mid[b, a] = nv + j
        tet = np.full((k, T, 10), -1, dtype=np.int64)
        elem = np.broadcast_to(np.arange(k)[:, None], (k, T))
        flat_tet = n_cells + np.arange(k * T).reshape(k, T)
        tet[:, :, :4] = np.take_along_axis(conn, local.reshape(k, -1), axis=1).reshape(k, T, 4)
        for j, (i0, i1) in enumerate(TET10_EDGES):
            a, b = local[:, :, i0], local[:, :, i1]
            mid = edge_mid[a, b]
            old = mid >= 0
            tet[:, :, 4 + j][old] = conn[elem[old], mid[old]]
            new = ~old
            ga, gb = conn[elem[new], a[new]], conn[elem[new], b[new]]
            ent_block.append(np.full(ga.size, ib))
            ent_elem.append(elem[new])
            ent_a.append(a[new])
            ent_b.append(b[new])
            ent_lo.append(np.minimum(ga, gb))
            ent_hi.append(np.maximum(ga, gb))
            ent_pos.append(10 * flat_tet[new] + 4 + j)
        cells.append(tet.reshape(-1, 10))
        parents.append(n_elements + np.repeat(np.arange(k), T))
        n_elements += k
        n_cells += k * T
    cells = np.concatenate(cells) if cells else np.zeros((0, 10), dtype=np.int64)
    parent = np.concatenate(parents) if parents else np.zeros(0, dtype=np.int64)
    if not ent_lo:
        return Subdivision(nodes=points.copy(), cells=cells, parent=parent,
                           weights=sp.csr_matrix((0, n_orig)))

    lo, hi = np.concatenate(ent_lo), np.concatenate(ent_hi)
    key = lo * n_orig + hi  # < n_orig^2: fits int64 for any mesh that fits in memory
    uniq, first, inverse = np.unique(key, return_index=True, return_inverse=True)
    cells.reshape(-1)[np.concatenate(ent_pos)] = n_orig + inverse.ravel()

    blk, el = np.concatenate(ent_block)[first], np.concatenate(ent_elem)[first]
    a, b = np.concatenate(ent_a)[first], np.concatenate(ent_b)[first]
    new_xyz = np.empty((len(uniq), 3))
    rows, cols, vals = [], [], []
    for ib, (element, conn) in enumerate(blocks):
        s = np.flatnonzero(blk == ib)
        if s.size == 0:
            continue
        v = element.vertices
        N = element.shape(0.5 * (v[a[s]] + v[b[s]]))  # (s, n) parent map at the edge midpoint
        N[np.abs(N) < 1e-13] = 0.0
        en = np.asarray(conn, dtype=np.int64)[el[s]]
        new_xyz[s] = np.einsum("sn,snd->sd", N, points[en])
        nz = N != 0.0
        rows.append(np.broadcast_to(s[:, None], N.shape)[nz])
        cols.append(en[nz])
        vals.append(N[nz])
    weights = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                            shape=(len(uniq), n_orig))
    return Subdivision(nodes=np.vstack([points, new_xyz]), cells=cells, parent=parent, weights=weights)
