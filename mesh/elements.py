"""Quadratic solid reference elements of imported meshes: 15-node wedge, 20-node hexahedron.

Node ordering is VTK's, which is also Abaqus/CalculiX's (C3D15, C3D20) and meshio's:
corners first, then the mid-edge nodes in the order of `edges`.

- wedge15: triangle coordinates (r, s), 0 <= r, s, r + s <= 1, and zeta in [-1, 1];
  corners 0, 1, 2 at zeta = -1 ((0, 0), (1, 0), (0, 1)), 3, 4, 5 above them at zeta = +1;
  mid-edge nodes of 01, 12, 20, 34, 45, 53, 03, 14, 25.
- hex20: (xi, eta, zeta) in [-1, 1]^3; corners 0-3 counter-clockwise at zeta = -1, 4-7 above
  them; mid-edge nodes of 01, 12, 23, 30, 45, 56, 67, 74, 04, 15, 26, 37 (serendipity).

The shape functions are the nodal (Lagrange) basis of each element's polynomial space,
obtained once by inverting the Vandermonde matrix of the space's monomials at the nodes:
wedge15: P2(r, s) x {1, zeta} + P1(r, s) zeta^2; hex20: the serendipity space (the
triquadratic monomials with at most one squared variable: 1, xi, ..., xi^2 eta zeta, ...). Plain numpy.
"""
from __future__ import annotations

from dataclasses import dataclass
from itertools import product

import numpy as np

from mesh.tet10 import det3, jacobians


@dataclass(frozen=True)
class ReferenceElement:
    """A quadratic solid reference element.

    name: meshio cell type. vertices: (n_v, 3) reference coordinates of the corners.
    edges: (n_e, 2) corner pairs, in the order of the mid-edge nodes n_v, n_v + 1, ...
    faces: corner tuples of the faces, each ordered around the face (3 or 4 corners).
    exponents: (n, 3) monomial exponents spanning the element's polynomial space.
    """

    name: str
    vertices: np.ndarray
    edges: np.ndarray
    faces: tuple[tuple[int, ...], ...]
    exponents: np.ndarray

    @property
    def n_vertices(self) -> int:
        return len(self.vertices)

    @property
    def n_nodes(self) -> int:
        return len(self.vertices) + len(self.edges)

    @property
    def nodes(self) -> np.ndarray:
        """(n, 3) reference coordinates of every node (mid-edge nodes at edge midpoints)."""
        v = self.vertices
        return np.vstack([v, 0.5 * (v[self.edges[:, 0]] + v[self.edges[:, 1]])])

    def _coefficients(self) -> np.ndarray:
        return _COEFFICIENTS[self.name]

    def shape(self, points: np.ndarray) -> np.ndarray:
        """(p, n) shape function values at (p, 3) reference points."""
        return _monomials(np.atleast_2d(points), self.exponents) @ self._coefficients()

    def gradients(self, points: np.ndarray) -> np.ndarray:
        """(p, n, 3) derivatives of the shape functions w.r.t. the reference coordinates."""
        points = np.atleast_2d(points)
        c = self._coefficients()
        out = np.empty((len(points), self.n_nodes, 3))
        for d in range(3):
            e = self.exponents.copy()
            factor = e[:, d].astype(float)
            e[:, d] = np.maximum(e[:, d] - 1, 0)
            out[:, :, d] = (_monomials(points, e) * factor) @ c
        return out

    def quadrature(self) -> tuple[np.ndarray, np.ndarray]:
        """(q, 3) points and (q,) weights summing to the reference volume.

        wedge15: 7-point degree-5 triangle rule (Radon) x 3-point Gauss in zeta; hex20:
        3 x 3 x 3 Gauss. Exact for det J of straight-sided (trilinear / linear-wedge)
        elements, which is of degree <= 2 per variable; a few 1e-6 relative on curved ones.
        """
        g, gw = np.polynomial.legendre.leggauss(3)
        if self.name == "hexahedron20":
            pts = np.array(list(product(g, g, g)))
            w = np.array([a * b * c for a, b, c in product(gw, gw, gw)])
            return pts, w
        tri, tw = _radon7()
        pts = np.array([[r, s, z] for (r, s), z in product(tri, g)])
        w = np.array([a * b for a, b in product(tw, gw)])
        return pts, w

    def volumes(self, nodes: np.ndarray, cells: np.ndarray) -> np.ndarray:
        """(n_cells,) volumes of (n_cells, n) elements on (n_nodes, 3) nodes, by quadrature of det J."""
        pts, w = self.quadrature()
        g = self.gradients(pts)  # (q, n, 3)
        out = np.empty(len(cells))
        for lo in range(0, len(cells), 20000):  # bounded memory: (chunk, q, 3, 3)
            out[lo:lo + 20000] = det3(jacobians(nodes[cells[lo:lo + 20000]], g)) @ w
        return out


def _monomials(points: np.ndarray, exponents: np.ndarray) -> np.ndarray:
    """(p, m) values of the monomials x^a y^b z^c at (p, 3) points."""
    return np.prod(points[:, None, :] ** exponents[None, :, :], axis=2)


def _radon7() -> tuple[np.ndarray, np.ndarray]:
    """Radon's 7-point rule on the reference triangle, exact for degree 5; weights sum to 1/2."""
    s15 = np.sqrt(15.0)
    a1, b1 = (6 - s15) / 21, (9 + 2 * s15) / 21
    a2, b2 = (6 + s15) / 21, (9 - 2 * s15) / 21
    w1, w2 = (155 - s15) / 1200, (155 + s15) / 1200
    pts = np.array([[1 / 3, 1 / 3], [a1, a1], [b1, a1], [a1, b1], [a2, a2], [b2, a2], [a2, b2]])
    w = np.array([9 / 40, w1, w1, w1, w2, w2, w2]) / 2
    return pts, w


WEDGE15 = ReferenceElement(
    name="wedge15",
    vertices=np.array([[0, 0, -1], [1, 0, -1], [0, 1, -1], [0, 0, 1], [1, 0, 1], [0, 1, 1]], dtype=float),
    edges=np.array([[0, 1], [1, 2], [2, 0], [3, 4], [4, 5], [5, 3], [0, 3], [1, 4], [2, 5]]),
    faces=((0, 1, 2), (3, 4, 5), (0, 1, 4, 3), (1, 2, 5, 4), (2, 0, 3, 5)),
    exponents=np.array([(a, b, c) for c in (0, 1) for a in range(3) for b in range(3) if a + b <= 2]
                       + [(0, 0, 2), (1, 0, 2), (0, 1, 2)]),
)

HEX20 = ReferenceElement(
    name="hexahedron20",
    vertices=np.array([[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1],
                       [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]], dtype=float),
    edges=np.array([[0, 1], [1, 2], [2, 3], [3, 0], [4, 5], [5, 6], [6, 7], [7, 4],
                    [0, 4], [1, 5], [2, 6], [3, 7]]),
    faces=((0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)),
    # serendipity: the triquadratic exponents with at most one squared variable
    exponents=np.array([e for e in product(range(3), repeat=3) if sum(k == 2 for k in e) <= 1]),
)

ELEMENTS = {e.name: e for e in (WEDGE15, HEX20)}


def quad_faces(blocks) -> list[np.ndarray]:
    """The quadrilateral faces of the wedge15 / hex20 blocks (objects with .type, a meshio
    cell type, and .connectivity (k, n)): one (k, 4) array of corner indices per face of each
    block's element, ordered around the face; blocks of other types give none."""
    return [b.connectivity[:, list(f)] for b in blocks if b.type in ELEMENTS
            for f in ELEMENTS[b.type].faces if len(f) == 4]

_COEFFICIENTS = {}
for _e in (WEDGE15, HEX20):
    assert _e.exponents.shape == (_e.n_nodes, 3), _e.name
    _COEFFICIENTS[_e.name] = np.linalg.inv(_monomials(_e.nodes, _e.exponents))
