"""The wedge15 / hex20 split (mesh.subdivide) and the parents' Gauss volumes
(mesh.elements) on single curved elements whose geometry is a known quadratic map.

Each element's nodes are phi(reference nodes), written out here in VTK/Abaqus order, with a
map phi that is quadratic in every coordinate and lies in the element's polynomial space, so
the element represents phi exactly:
- wedge15, phi(r, s, zeta) = (r + a r^2, s + a s^2, zeta): det J = (1 + 2 a r)(1 + 2 a s),
  volume 2 * int_T (1 + 2a r)(1 + 2a s) = 2 (1/2 + 2a/6 + 2a/6 + 4a^2/24) = 1 + 4a/3 + a^2/3
  (int_T r = 1/6, int_T r s = 1/24). Its det J has the term r s: a quadrature of the
  triangle that is not exact for degree 2 misses it.
- hex20, phi(xi, eta, zeta) = (xi + a xi^2, eta + a eta^2, zeta): volume 8 (the odd terms
  of det J integrate to zero).
The split's tetrahedra are straight in the reference element, so phi restricted to each is
quadratic and the tet10 interpolate reproduces it: every tet10 node must be phi of the
reference point it stands for (corners on reference corners, each mid node on the
reference midpoint of its gmsh edge 01, 12, 20, 30, 32, 31), and the tet10 volumes (Keast,
exact for the cubic det J) must add up to the closed-form volume.
"""
import numpy as np
import pytest

from mesh import tet10
from mesh.elements import HEX20, WEDGE15
from mesh.subdivide import subdivide

A = 0.3
GMSH_EDGES = ((0, 1), (1, 2), (2, 0), (3, 0), (3, 2), (3, 1))

# VTK orders, by hand (VTK_QUADRATIC_WEDGE, VTK_QUADRATIC_HEXAHEDRON)
WEDGE_REF = np.array([
    [0, 0, -1], [1, 0, -1], [0, 1, -1], [0, 0, 1], [1, 0, 1], [0, 1, 1],
    [.5, 0, -1], [.5, .5, -1], [0, .5, -1], [.5, 0, 1], [.5, .5, 1], [0, .5, 1],
    [0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=float)
HEX_REF = np.array([
    [-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1], [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1],
    [0, -1, -1], [1, 0, -1], [0, 1, -1], [-1, 0, -1], [0, -1, 1], [1, 0, 1], [0, 1, 1], [-1, 0, 1],
    [-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], dtype=float)


def phi(u):
    u = np.atleast_2d(u)
    return np.column_stack([u[:, 0] + A * u[:, 0] ** 2, u[:, 1] + A * u[:, 1] ** 2, u[:, 2]])


def phi_inverse(x):
    """Reference point of a physical point (componentwise root of u + a u^2 = x, u > -1/(2a))."""
    x = np.atleast_2d(x)
    u = (-1 + np.sqrt(1 + 4 * A * x[:, :2])) / (2 * A)
    return np.column_stack([u, x[:, 2]])


CASES = {"wedge15": (WEDGE15, WEDGE_REF, 1 + 4 * A / 3 + A ** 2 / 3),
         "hexahedron20": (HEX20, HEX_REF, 8.0)}


@pytest.mark.parametrize("kind", CASES)
def test_parent_gauss_volume_of_a_curved_element(kind):
    element, ref, exact = CASES[kind]
    v = element.volumes(phi(ref), np.arange(len(ref))[None, :])
    assert v[0] == pytest.approx(exact, rel=1e-13)


@pytest.mark.parametrize("kind", CASES)
@pytest.mark.parametrize("numbering", ("natural", "reversed"))
def test_split_nodes_lie_on_the_parents_quadratic_geometry(kind, numbering):
    element, ref, exact = CASES[kind]
    n = len(ref)
    # the global numbers decide the diagonals: try two numberings of the same element
    perm = np.arange(n) if numbering == "natural" else np.arange(n)[::-1]
    points = np.empty((n, 3))
    points[perm] = phi(ref)  # global node perm[i] is the element's local node i
    sub = subdivide(points, [(element, perm[None, :])])
    n_tets = 3 if kind == "wedge15" else 6
    assert sub.cells.shape == (n_tets, 10)
    u = phi_inverse(sub.nodes)  # reference coordinates of every node
    # the original nodes stay where they were
    np.testing.assert_allclose(sub.nodes[:n], points, rtol=0, atol=1e-15)
    for k, (a, b) in enumerate(GMSH_EDGES):
        mid = 0.5 * (u[sub.cells[:, a]] + u[sub.cells[:, b]])
        np.testing.assert_allclose(sub.nodes[sub.cells[:, 4 + k]], phi(mid), rtol=0, atol=1e-14)
    # the tetrahedra tile the reference element: straight reference volumes add up to its volume
    c = u[sub.cells[:, :4]]
    ref_vol = np.linalg.det(c[:, 1:] - c[:, :1]) / 6
    assert ref_vol.min() > 0  # positively oriented
    assert ref_vol.sum() == pytest.approx(1.0 if kind == "wedge15" else 8.0, rel=1e-13)
    # and the curved tet10 cells hold exactly the parent's volume
    assert tet10.cell_volumes(sub.nodes, sub.cells).sum() == pytest.approx(exact, rel=1e-13)
    assert tet10.jacobian_determinants(sub.nodes, sub.cells).min() > 0
