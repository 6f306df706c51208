"""Off-screen mode-shape rendering on a small hand-made tet10 plate."""
from __future__ import annotations

import os

import numpy as np
import pytest

import pyvista  # noqa: F401  (a dependency: a missing pyvista must fail, not skip)
from matplotlib.image import imread  # noqa: E402

from pipelines import render  # noqa: E402

# Kuhn split of the unit cube into 6 positively and negatively oriented tets (corner ids).
_KUHN = np.array([[0, 1, 3, 7], [0, 1, 5, 7], [0, 2, 3, 7], [0, 2, 6, 7], [0, 4, 5, 7], [0, 4, 6, 7]])
_GMSH_EDGES = np.array([[0, 1], [1, 2], [2, 0], [3, 0], [2, 3], [3, 1]])  # nodes 4..9


def plate_tet10(nx=12, ny=3, nz=2, lengths=(0.15, 0.04, 0.004)):
    """A tet10 box mesh (gmsh node ordering), sides `lengths` in m, spanning x.

    Returns nodes (n, 3) m and cells (n_cells, 10); mid-edge nodes are shared.
    """
    grid = np.stack(np.meshgrid(*[np.linspace(0, L, k + 1) for L, k in zip(lengths, (nx, ny, nz))],
                                indexing="ij"), -1)
    ids = np.arange(grid[..., 0].size).reshape(grid.shape[:3])
    corners = np.array([[ids[i + a, j + b, k + c] for c in (0, 1) for b in (0, 1) for a in (0, 1)]
                        for i in range(nx) for j in range(ny) for k in range(nz)])
    tets = corners[:, _KUHN].reshape(-1, 4)
    nodes = grid.reshape(-1, 3)
    edges = np.sort(tets[:, _GMSH_EDGES].reshape(-1, 2), axis=1)
    unique, inverse = np.unique(edges, axis=0, return_inverse=True)
    mids = 0.5 * (nodes[unique[:, 0]] + nodes[unique[:, 1]])
    cells = np.hstack([tets, len(nodes) + inverse.reshape(-1, 6)])
    return np.vstack([nodes, mids]), cells


def bending_modes(nodes):
    """(3n, 2) node-major: a first flap (z) bending and a first edgewise (y) bending shape."""
    s = nodes[:, 0] / np.ptp(nodes[:, 0])
    flap = np.zeros_like(nodes)
    flap[:, 2] = s ** 2
    edge = np.zeros_like(nodes)
    edge[:, 1] = s ** 2
    return np.stack([flap.ravel(), edge.ravel()], 1)


def test_boundary_triangles_of_a_cube_are_its_twelve_outer_faces():
    nodes, cells = plate_tet10(1, 1, 1, (1.0, 1.0, 1.0))
    tris = render.boundary_triangles(render._orient_outward(nodes, cells))
    assert tris.shape == (12, 3)
    p = nodes[tris]
    normals = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    outward = p.mean(1) - 0.5
    assert np.all(np.einsum("ij,ij->i", normals, outward) > 0)


def test_offscreen_route_is_found_and_cached():
    first = render.ensure_offscreen()
    assert first in ("vtkOSOpenGLRenderWindow", "vtkEGLRenderWindow", "vtkXOpenGLRenderWindow")
    assert render.ensure_offscreen() == first


def test_mode_pictures_have_the_size_asked_and_show_the_deformation(tmp_path):
    nodes, cells = plate_tet10()
    modes = bending_modes(nodes)
    paths = render.render_mode_shapes(nodes, cells, modes, [123.4, 456.7], tmp_path / "modes",
                                      n_modes=6, scale=0.15, window=(320, 240), title_prefix="plate ")
    assert [p.name for p in paths] == ["mode_01.png", "mode_02.png"]
    flap = imread(paths[0])[..., :3]
    assert flap.shape == (240, 320, 3)
    assert flap.std() > 0.05  # not a blank picture

    # drawn again in the same folder, of which a copy holds hard links: the copy keeps its
    # picture (each file is written under a temporary name and renamed)
    os.link(paths[0], tmp_path / "copy.png")
    still = render.render_mode_shapes(nodes, cells, 0 * modes[:, :1], [123.4], tmp_path / "modes",
                                      scale=0.15, window=(320, 240), title_prefix="plate ")
    rest = imread(still[0])[..., :3]
    changed = np.abs(flap - rest).max(axis=2) > 0.1
    assert changed.mean() > 0.01  # the bent plate covers other pixels than the flat one
    assert np.array_equal(imread(tmp_path / "copy.png")[..., :3], flap)
    assert sorted(p.name for p in (tmp_path / "modes").iterdir()) == ["mode_01.png", "mode_02.png"]
    assert np.abs(imread(paths[1])[..., :3] - flap).max(axis=2).__gt__(0.1).mean() > 0.01


def test_modes_given_per_node_are_accepted_and_bad_shapes_refused(tmp_path):
    nodes, cells = plate_tet10(4, 1, 1)
    modes = bending_modes(nodes)
    per_node = modes.T.reshape(2, len(nodes), 3)
    paths = render.render_mode_shapes(nodes, cells, per_node, [1.0, 2.0], tmp_path, n_modes=1,
                                      window=(160, 120))
    assert len(paths) == 1 and paths[0].stat().st_size > 0
    with pytest.raises(ValueError, match="expected"):
        render.render_mode_shapes(nodes, cells, modes[:-1], [1.0, 2.0], tmp_path)
