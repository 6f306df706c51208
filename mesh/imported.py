"""The user's own blade mesh -> BladeMesh: what the mesh stage does for [blade] mesh = "...".

Steps: read the file (mesh.source), accept only quadratic solids (tet10, wedge15, hex20),
scale to metres and turn the file's rotation axis onto z, split wedges and hexahedra
into conforming tet10 (mesh.subdivide), check every cell, find the clamped root, the tip
face and the contact nodes, and return the same BladeMesh the tables give.

Conventions that a file cannot state, and how they are decided:
- The rotation axis passes through the file's origin; "x" or "y" is turned onto z by a
  cyclic permutation of the axes (a proper rotation: right-handed about the file's axis
  stays right-handed about z), kept in BladeMesh.source_rotation.
- The tip face: the connected set of boundary facets whose outward normal lies within 60
  degrees of the radial direction, grown from the boundary facet farthest from the axis
  across edges where neighbouring normals differ by less than 30 degrees (the tip's
  corners with the blade's sides are creases of about 90 degrees). Its radial extent must
  stay below half the blade's, and the blade must extend radially over at least a fifth
  of its axial length, or the axis is not this blade's rotation axis (rotor 67: 0.15 m
  radially over 0.09 m axially). "hub" roots are found alike from the facet nearest the
  axis.
- The leading edge is the upstream end of the tip: flow along +axis, so the LE is the tip
  point with the smallest axial coordinate (the tables' convention: rotor 67's LE lies
  upstream at smaller z). Where a blade is meant the other way, list contact_nodes.
- Contact nodes, when not listed: the tip's camber line is traced through axial slabs (in
  each, the midpoint between the circumferentially outermost tip nodes, as the NASA tables
  define camber from the tangential thickness), from the LE to the TE; n_boundary points
  evenly spaced along it are snapped to the nearest tip nodes of the file (never to a node
  the split created, so they can be found in the user's model), as mesh.blade does.
- A new mid-edge node is clamped when every node of its parent with a non-zero shape
  function there is clamped (a diagonal of a clamped face); so the root is exactly the
  file's set, plus the diagonal nodes of its faces.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from mesh import tet10
from mesh.blade import contact_geometry, nearest_nodes, points_along
from mesh.elements import ELEMENTS, quad_faces
from mesh.model import BladeMesh
from mesh.options import KNOWN_UNITS, BladeOptions, MeshOptions
from mesh.ordering import renumber_nodes
from mesh.source import LINEAR, QUADRATIC, QUADRATIC_OF, MeshImportError, SourceMesh, read_source
from mesh.subdivide import VTK_TO_GMSH_TET10, subdivide

# product frame = R @ file frame: the file's rotation axis becomes z (cyclic permutations)
AXIS_ROTATIONS = {
    "z": np.eye(3),
    "x": np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]]),
    "y": np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]),
}
FACING_COS = 0.5  # a facet faces away from (towards) the axis within 60 degrees of e_r (-e_r)
CREASE_COS = np.cos(np.radians(30.0))  # neighbours across a sharper crease belong to another face
MAX_FACE_EXTENT = 0.5  # radial extent of the tip/hub face over the blade's: above it, wrong axis
MIN_ASPECT = 0.2  # radial extent over axial extent below which the axis cannot be the blade's
# tet10 faces in gmsh ordering, outward for a positive cell: vertices, then mid nodes of 01, 12, 20
TET10_FACES = np.array([[0, 2, 1, 6, 5, 4], [0, 1, 3, 4, 9, 7], [0, 3, 2, 7, 8, 6], [1, 2, 3, 5, 8, 9]])


def import_blade(blade: BladeOptions, options: MeshOptions, path: Path, node_order: str = "rcm") -> BladeMesh:
    """Read the mesh file `path` as [blade] says (units, axis, root, contact_nodes) -> BladeMesh.

    Returns nodes in m in the product's frame (z = rotation axis), tet10 cells, root and tip
    tri6 facets, the contact nodes LE -> TE ([mesh] n_boundary of them unless listed) with
    radius, angle and frames, and the transform back to the file (source_*). node_order:
    mesh.ordering.NODE_ORDERS ("meshed": the file's nodes in its order, then the split's).
    Raises MeshImportError (a ValueError) naming what is wrong; nothing is written.
    """
    if blade.mesh is None:
        raise ValueError("import_blade needs [blade] mesh")
    path = Path(path)
    src = read_source(path)
    _check_elements(src, path)
    rotation, scale = AXIS_ROTATIONS[blade.axis], KNOWN_UNITS[blade.units]
    points = scale * (src.points @ rotation.T)
    blocks = [(ELEMENTS.get(b.type), b.connectivity) for b in src.blocks]
    element_ids = np.concatenate([b.ids for b in src.blocks])
    _check_junctions(src, path)
    sub = subdivide(points, blocks)
    n_orig = len(points)

    # keep the nodes of the solid (files may hold others: geometry points, surface-only nodes)
    used = np.zeros(len(sub.nodes), dtype=bool)
    used[sub.cells.ravel()] = True
    renum = np.full(len(sub.nodes), -1, dtype=np.int64)
    renum[used] = np.arange(int(used.sum()))
    nodes = np.ascontiguousarray(sub.nodes[used])
    cells = renum[sub.cells]
    source_ids = np.concatenate([src.node_ids, np.full(len(sub.nodes) - n_orig, -1)])[used]

    _check_jacobians(nodes, cells, sub.parent, element_ids, path)
    _, boundary = _faces(cells, len(nodes), path)
    _check_connected(cells, len(nodes), path)

    # root: clamped file nodes, extended to the split's new nodes on clamped faces
    if blade.root == "hub":
        hub = _face_from_extreme(nodes, boundary, outward=False, axis=blade.axis, path=path)
        clamped = np.zeros(len(nodes), dtype=bool)
        clamped[boundary[hub].ravel()] = True
    else:
        clamped_orig = _root_set(src, blade.root, path)
        pattern = sub.weights.copy()
        pattern.data[:] = 1.0
        free_support = pattern @ (~clamped_orig).astype(np.float64)
        clamped_all = np.concatenate([clamped_orig, free_support == 0])
        if not clamped_all[used].any():
            raise MeshImportError(f"{path}: the root set '{blade.root}' holds no node of the solid elements")
        clamped = clamped_all[used]
    on_root = np.all(clamped[boundary], axis=1)
    root_facets = boundary[on_root]
    loose = np.setdiff1d(np.flatnonzero(clamped), root_facets.ravel())
    if loose.size:
        root_facets = np.vstack([root_facets, np.repeat(loose[:, None], 6, axis=1)])

    tip = _face_from_extreme(nodes, boundary, outward=True, axis=blade.axis, path=path)
    tip_facets = boundary[tip]

    if blade.contact_nodes is not None:
        index = _listed_contact_nodes(blade.contact_nodes, source_ids, src, path)
    else:
        index = _tip_contact_nodes(nodes, tip_facets, source_ids, options.n_boundary, path)
    bad = index[clamped[index]]
    if bad.size:
        raise MeshImportError(f"{path}: contact nodes {source_ids[bad].tolist()} lie on the clamped root")
    contact = contact_geometry(nodes, index)

    volume = float(_cell_volumes(nodes, cells).sum())
    reference = 0.0
    for element, conn in blocks:
        if element is None:
            reference += float(_cell_volumes(points, conn[:, VTK_TO_GMSH_TET10]).sum())
        else:
            reference += float(element.volumes(points, conn).sum())
    mesh = BladeMesh(nodes=nodes, cells=cells, root_facets=root_facets, tip_facets=tip_facets,
                     boundary_node_index=contact.index, boundary_xyz=contact.xyz, boundary_rho=contact.rho,
                     boundary_theta=contact.theta, boundary_frames=contact.frames, volume=volume,
                     reference_volume=reference, source_rotation=rotation.copy(), source_scale=float(scale),
                     source_node_ids=source_ids)
    return renumber_nodes(mesh, node_order)


def _check_elements(src: SourceMesh, path: Path) -> None:
    """Only quadratic solids; the message counts every block of a type (meshio files may hold
    several) and names the deck line of an unknown type's first block."""
    types, where = {}, {}
    for b in src.blocks:
        types[b.type] = types.get(b.type, 0) + len(b.ids)
        if b.where:
            where.setdefault(b.type, f", at {b.where}")
    if not types:
        other = ", ".join(f"{t} x {n}" for t, n in src.ignored.items()) or "none"
        raise MeshImportError(f"{path}: no solid elements (other elements: {other})")
    linear = [t for t in types if t in LINEAR]
    unknown = [t for t in types if t not in LINEAR and t not in QUADRATIC]
    quadratic = [t for t in types if t in QUADRATIC]
    if unknown:
        raise MeshImportError(
            f"{path}: unsupported element type{'s' if len(unknown) > 1 else ''} "
            + ", ".join(f"'{t}' ({types[t]} elements{where.get(t, '')})" for t in unknown)
            + "; bladerub reads 10-node tetrahedra, 15-node wedges and 20-node hexahedra")
    if linear and quadratic:
        raise MeshImportError(
            f"{path}: mixed element types, linear " + ", ".join(f"{LINEAR[t]} ({types[t]})" for t in linear)
            + " with quadratic " + ", ".join(f"{t} ({types[t]})" for t in quadratic)
            + ": the product is quadratic; export every element with mid-edge nodes")
    if linear:
        raise MeshImportError(
            f"{path}: linear elements, " + ", ".join(f"{LINEAR[t]} ({types[t]})" for t in linear)
            + ": the product is quadratic (linear elements are far too stiff in bending); export "
            + " / ".join(QUADRATIC_OF[t] for t in linear) + " (second-order mesh: C3D10/C3D15/C3D20)")


def _check_junctions(src: SourceMesh, path: Path) -> None:
    """Tetrahedra glued onto a quadrilateral face would need pyramids: refuse them."""
    tets = [b.connectivity[:, :4] for b in src.blocks if b.type == "tetra10"]
    quads = quad_faces(src.blocks)
    if not tets or not quads:
        return
    t = np.concatenate(tets)
    tri = np.sort(np.concatenate([t[:, [0, 1, 2]], t[:, [0, 1, 3]], t[:, [0, 2, 3]], t[:, [1, 2, 3]]]), axis=1)
    q = np.concatenate(quads)
    qtri = np.sort(np.concatenate([q[:, [0, 1, 2]], q[:, [1, 2, 3]], q[:, [2, 3, 0]], q[:, [3, 0, 1]]]), axis=1)
    both = np.concatenate([tri, qtri])
    _, inv = np.unique(both, axis=0, return_inverse=True)
    inv = inv.ravel()
    hit = np.intersect1d(inv[:len(tri)], inv[len(tri):])
    if hit.size:
        nodes = src.node_ids[np.unique(both[np.isin(inv, hit)])][:6]
        raise MeshImportError(f"{path}: tetrahedra meet a quadrilateral face of a wedge or hexahedron "
                              f"(nodes {nodes.tolist()} ...); such a junction needs pyramids, which bladerub "
                              "does not read")


def _cell_volumes(nodes: np.ndarray, cells: np.ndarray, chunk: int = 50000) -> np.ndarray:
    return np.concatenate([tet10.cell_volumes(nodes, cells[i:i + chunk]) for i in range(0, len(cells), chunk)])


def _check_jacobians(nodes, cells, parent, element_ids, path, chunk: int = 50000) -> None:
    """Every tet10 must have det J > 0 at its check points (mesh.tet10.CHECK_POINTS)."""
    bad = []
    for i in range(0, len(cells), chunk):
        det = tet10.jacobian_determinants(nodes, cells[i:i + chunk])
        bad.append(i + np.flatnonzero(np.any(det <= 0, axis=1)))
    bad = np.concatenate(bad)
    if bad.size:
        ids = np.unique(element_ids[parent[bad]])
        raise MeshImportError(f"{path}: {ids.size} inverted or degenerate element{'s' if ids.size > 1 else ''} "
                              f"(non-positive Jacobian after the split into tet10), element ids "
                              f"{ids[:10].tolist()}{' ...' if ids.size > 10 else ''}")


def _triple_keys(rows: np.ndarray, n: int) -> np.ndarray:
    """One int64 per sorted row of three node indices < n (packed; np.unique's ids beyond 2^21)."""
    if n < 2 ** 21:
        return (rows[:, 0] << 42) | (rows[:, 1] << 21) | rows[:, 2]
    return np.unique(rows, axis=0, return_inverse=True)[1].ravel()


def _faces(cells: np.ndarray, n_nodes: int, path: Path) -> tuple[np.ndarray, np.ndarray]:
    """All tri6 faces (4 per cell, outward) and the boundary ones; refuses a non-conforming mesh."""
    faces = cells[:, TET10_FACES].reshape(-1, 6)
    v = faces[:, :3]
    order = np.argsort(v, axis=1)
    sv = np.take_along_axis(v, order, axis=1)
    # the mid node opposite each corner: of corner 0 edge 12 (mid 1), of 1 edge 20, of 2 edge 01
    so = np.take_along_axis(faces[:, 3:][:, [1, 2, 0]], order, axis=1)
    key = _triple_keys(sv, n_nodes)
    by_key = np.argsort(key, kind="stable")
    ks = key[by_key]
    first = np.flatnonzero(np.concatenate([[True], ks[1:] != ks[:-1]]))
    count = np.diff(np.concatenate([first, [len(ks)]]))
    if count.max() > 2:
        raise MeshImportError(f"{path}: a triangular face is shared by {count.max()} cells (overlapping elements)")
    pair = first[count == 2]
    if not np.array_equal(so[by_key[pair]], so[by_key[pair + 1]]):
        raise MeshImportError(f"{path}: non-conforming mesh: two cells share a face's corners but not its "
                              "mid-edge nodes (duplicate or unmerged mid nodes)")
    return faces, faces[np.sort(by_key[first[count == 1]])]


def _check_connected(cells: np.ndarray, n: int, path: Path) -> None:
    rows = np.repeat(cells[:, 0], 9)
    graph = sp.coo_matrix((np.ones(rows.size, dtype=np.int8), (rows, cells[:, 1:].ravel())), shape=(n, n))
    k = connected_components(graph, directed=False)[0]
    if k != 1:
        raise MeshImportError(f"{path}: the solid falls into {k} disconnected parts (unmerged duplicate nodes?)")


def _root_set(src: SourceMesh, root: str, path: Path) -> np.ndarray:
    """(n_orig,) bool: the file's clamped nodes."""
    n = len(src.points)
    if root == "boundary":
        if src.fixed is None:
            raise MeshImportError(f"{path}: root = \"boundary\" needs the file's own boundary conditions "
                                  f"(*BOUNDARY of an .inp deck); a {path.suffix} file has none: "
                                  "use root = \"nset:NAME\" or \"hub\"")
        full = src.fixed.all(axis=1)
        partial = src.fixed.any(axis=1) & ~full
        if partial.any():
            raise MeshImportError(f"{path}: *BOUNDARY fixes only some translations of nodes "
                                  f"{src.node_ids[partial][:10].tolist()}; bladerub clamps the root (all three): "
                                  "fix 1-3 or name the root set with root = \"nset:NAME\"")
        if not full.any():
            raise MeshImportError(f"{path}: root = \"boundary\" but the deck fixes no node (no *BOUNDARY)")
        return full
    name = root[5:].strip()
    match = [k for k in src.node_sets if k.upper() == name.upper()]
    if not match:
        known = ", ".join(sorted(src.node_sets)) or "none"
        raise MeshImportError(f"{path}: root node set '{name}' not found; the file's node sets: {known}")
    missing = src.unknown_ids.get(match[0])
    if missing is not None:
        raise MeshImportError(f"{path}: root node set '{name}' names node ids not in the file: "
                              f"{missing[:10].tolist()}{' ...' if missing.size > 10 else ''}")
    idx = src.node_sets[match[0]]
    if idx.size == 0:
        raise MeshImportError(f"{path}: root node set '{name}' is empty")
    out = np.zeros(n, dtype=bool)
    out[idx] = True
    return out


def _facet_geometry(nodes, facets):
    """(cos of the angle between outward normal and e_r, centroid radius, unit normals)."""
    a, b, c = (nodes[facets[:, i]] for i in range(3))
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    centre = (a + b + c) / 3.0
    rho = np.hypot(centre[:, 0], centre[:, 1])
    er = np.column_stack([centre[:, 0], centre[:, 1], np.zeros(len(centre))]) / np.maximum(rho, 1e-300)[:, None]
    return np.einsum("ij,ij->i", n, er), rho, n


def _face_from_extreme(nodes, boundary, outward: bool, axis: str, path: Path) -> np.ndarray:
    """Indices of the boundary facets of the tip (outward) or hub face (see module doc)."""
    what = "tip" if outward else "hub"
    r = np.hypot(nodes[:, 0], nodes[:, 1])
    span, axial = r.max() - r.min(), np.ptp(nodes[:, 2])
    if span < MIN_ASPECT * axial:
        raise MeshImportError(
            f"{path}: no {what} face along axis '{axis}': the blade spans {span:.4g} m in radius but "
            f"{axial:.4g} m along the axis; a blade extends away from its rotation axis (check [blade] axis)")
    cos, rho, normal = _facet_geometry(nodes, boundary)
    sign = 1.0 if outward else -1.0
    seed = int(np.argmax(sign * rho))
    if sign * cos[seed] <= FACING_COS:
        angle = np.degrees(np.arccos(np.clip(sign * cos[seed], -1, 1)))
        raise MeshImportError(
            f"{path}: no {what} face along axis '{axis}': the boundary facet {'farthest from' if outward else 'nearest to'} "
            f"the axis faces {angle:.0f} deg away from the {'outward' if outward else 'inward'} radial direction "
            "(check [blade] axis: the rotation axis through the file's origin)")
    candidate = sign * cos > FACING_COS
    # edge adjacency among candidate facets
    idx = np.flatnonzero(candidate)
    f = boundary[idx, :3]
    edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    owner = np.tile(np.arange(len(idx)), 3)
    inv = edges[:, 0] * len(nodes) + edges[:, 1]
    order = np.argsort(inv, kind="stable")
    same = inv[order][1:] == inv[order][:-1]
    a, b = owner[order][:-1][same], owner[order][1:][same]
    smooth = np.einsum("ij,ij->i", normal[idx[a]], normal[idx[b]]) > CREASE_COS
    a, b = a[smooth], b[smooth]
    g = sp.coo_matrix((np.ones(a.size), (a, b)), shape=(len(idx), len(idx)))
    _, label = connected_components(g, directed=False)
    face = idx[label == label[np.searchsorted(idx, seed)]]
    rf = r[np.unique(boundary[face])]
    extent = rf.max() - rf.min()
    if extent > MAX_FACE_EXTENT * span:
        raise MeshImportError(
            f"{path}: no {what} face along axis '{axis}': the faces {'farthest from' if outward else 'nearest to'} "
            f"the axis span {extent:.4g} m of the blade's {span:.4g} m in radius, so the blade does not extend "
            "radially from this axis (check [blade] axis)")
    return face


def _listed_contact_nodes(ids, source_ids, src: SourceMesh, path: Path) -> np.ndarray:
    ids = np.asarray(ids, dtype=np.int64)
    in_file = np.isin(ids, src.node_ids)
    if not in_file.all():
        raise MeshImportError(f"{path}: contact_nodes {ids[~in_file].tolist()} are not node ids of the file")
    known = source_ids >= 0
    pos = {int(i): k for k, i in zip(np.flatnonzero(known), source_ids[known])}
    missing = [int(i) for i in ids if int(i) not in pos]
    if missing:
        raise MeshImportError(f"{path}: contact_nodes {missing} belong to no solid element")
    return np.array([pos[int(i)] for i in ids], dtype=np.int64)


def _tip_contact_nodes(nodes, tip_facets, source_ids, n: int, path: Path) -> np.ndarray:
    """n file nodes of the tip face along its camber line, LE (smallest axial coordinate) first."""
    tip = np.unique(tip_facets)
    x = nodes[tip]
    z = x[:, 2]
    phi = np.arctan2(x[:, 1], x[:, 0])
    phi0 = np.angle(np.exp(1j * phi).mean())
    phi = np.angle(np.exp(1j * (phi - phi0)))  # unwrapped about the tip's mean angle
    chord = z.max() - z.min()
    if not chord > 0:
        raise MeshImportError(f"{path}: the tip face has no extent along the axis; list contact_nodes")
    e = tip_facets[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    h = float(np.median(np.linalg.norm(nodes[e[:, 0]] - nodes[e[:, 1]], axis=1)))
    n_slabs = int(np.clip(chord / (1.5 * h), 2, 400))
    tol = 1e-6 * chord
    le = x[z <= z.min() + tol].mean(axis=0)
    te = x[z >= z.max() - tol].mean(axis=0)
    slab = np.minimum(((z - z.min()) / chord * n_slabs).astype(int), n_slabs - 1)
    line = [le]
    for k in range(n_slabs):
        s = np.flatnonzero(slab == k)
        if s.size < 2:
            continue
        lo, hi = s[np.argmin(phi[s])], s[np.argmax(phi[s])]
        line.append(0.5 * (x[lo] + x[hi]))
    line.append(te)
    targets = points_along(np.array(line), n)
    candidates = tip[source_ids[tip] >= 0]
    index = nearest_nodes(nodes, candidates, targets)
    if len(np.unique(index)) != n:
        raise MeshImportError(f"{path}: {n} contact nodes ([mesh] n_boundary) snap onto fewer distinct nodes of "
                              "the tip face; use fewer, a finer mesh, or list contact_nodes")
    return index
