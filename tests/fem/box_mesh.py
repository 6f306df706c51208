"""Test support: gmsh tet10 boxes in the BladeMesh layout (until mesh/ lands, and for references).

The box spans [0, L] x [0, b] x [0, h]; the face x = 0 is the clamped root, the face
x = L the tip. `n_boundary` tip nodes along y at mid-height stand in for the contact nodes.
"""
from __future__ import annotations

import numpy as np

from mesh.model import BladeMesh


def box_mesh(length: float, width: float, height: float, size: float, n_boundary: int = 9,
             transfinite: tuple[int, int, int] | None = None) -> BladeMesh:
    """Quadratic tetrahedral mesh of a box clamped at x = 0.

    length, width, height: box dimensions along x, y, z, m. size: target edge length, m.
    transfinite: (nx, ny, nz) divisions for a structured tet mesh (uniform refinement
    families for convergence tests); None for gmsh's unstructured mesh of `size`.
    """
    import gmsh

    gmsh.initialize(["-noenv"])
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("box")
        gmsh.model.occ.addBox(0, 0, 0, length, width, height)
        gmsh.model.occ.synchronize()
        if transfinite is not None:
            nx, ny, nz = transfinite
            for dim, tag in gmsh.model.getEntities(1):
                xmin, ymin, zmin, xmax, ymax, zmax = gmsh.model.getBoundingBox(dim, tag)
                d = np.array([xmax - xmin, ymax - ymin, zmax - zmin])
                n = (nx, ny, nz)[int(np.argmax(d))]
                gmsh.model.mesh.setTransfiniteCurve(tag, n + 1)
            for dim, tag in gmsh.model.getEntities(2):
                gmsh.model.mesh.setTransfiniteSurface(tag)
            for dim, tag in gmsh.model.getEntities(3):
                gmsh.model.mesh.setTransfiniteVolume(tag)
        else:
            gmsh.option.setNumber("Mesh.CharacteristicLengthMin", size)
            gmsh.option.setNumber("Mesh.CharacteristicLengthMax", size)
        gmsh.model.addPhysicalGroup(3, [1], 1)
        gmsh.model.mesh.generate(3)
        gmsh.model.mesh.setOrder(2)
        tags, coords, _ = gmsh.model.mesh.getNodes()
        x = coords.reshape(-1, 3)
        index = np.full(int(tags.max()) + 1, -1, dtype=np.int64)
        index[tags.astype(np.int64)] = np.arange(len(tags))
        _, etags, enodes = gmsh.model.mesh.getElements(3)
        cells = index[np.asarray(enodes[0], dtype=np.int64)].reshape(-1, 10)
        # faces on x = 0 (root) and x = L (tip), tri6
        root, tip = [], []
        for dim, tag in gmsh.model.getEntities(2):
            xmin, _, _, xmax, _, _ = gmsh.model.getBoundingBox(dim, tag)
            if xmax - xmin > 1e-3 * length:  # occ boxes are padded by ~1e-7
                continue
            types, _, fn = gmsh.model.mesh.getElements(2, tag)
            tri = index[np.asarray(fn[list(types).index(9)], dtype=np.int64)].reshape(-1, 6)
            (root if xmax < 0.5 * length else tip).append(tri)
    finally:
        gmsh.finalize()
    # only nodes used by the volume cells (gmsh may keep geometry points)
    used = np.unique(cells)
    renum = np.full(len(x), -1, dtype=np.int64)
    renum[used] = np.arange(len(used))
    x, cells = x[used], renum[cells]
    root, tip = renum[np.concatenate(root)], renum[np.concatenate(tip)]
    # contact stand-ins: tip nodes nearest to points along y at mid-height
    targets = np.stack([np.full(n_boundary, length), np.linspace(0.05, 0.95, n_boundary) * width,
                        np.full(n_boundary, 0.5 * height)], 1)
    tip_nodes = np.unique(tip)
    bidx = tip_nodes[np.argmin(np.linalg.norm(x[tip_nodes][None] - targets[:, None], axis=2), axis=1)]
    bxyz = x[bidx]
    # rotation axis along z, through (-R, y0): the box is a "blade" at radius R + x
    frames = np.zeros((n_boundary, 3, 3))
    frames[:, 0] = [1, 0, 0]
    frames[:, 1] = [0, 1, 0]
    frames[:, 2] = [0, 0, 1]
    return BladeMesh(nodes=x, cells=cells, root_facets=root, tip_facets=tip,
                     boundary_node_index=bidx, boundary_xyz=bxyz,
                     boundary_rho=bxyz[:, 0].copy(), boundary_theta=np.zeros(n_boundary),
                     boundary_frames=frames, volume=length * width * height,
                     reference_volume=length * width * height)
