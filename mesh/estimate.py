"""How many nodes `mesh_blade` will make, from the table and the options, without meshing.

The size field of mesh.blade: h(d) = h_e + (h_b - h_e) min(d / ramp, 1) at a distance d
from the LE/TE lines (h_e the edge size, h_b = element_size). Over the blade's mid-surface
(the sections' camber lines, chord coordinate s, stacked over the span) a tetrahedral mesh
of local size h has a node density ~ t / h^3 through a thickness t > h, and ~ 1 / h^2 on
each face where the blade is thinner than its elements. So

    n ~ A * integral(t / h^3) + B * integral(2 / h^2)   over the mid-surface,

with A and B fitted (least squares on the relative error) to eight gmsh meshes of rotor 67
between 23 600 and 196 955 nodes (element_size 0.00145-0.016 m, edge_layers 1-3, size_growth
0.2-1): estimate / actual from 0.79 to 1.16 (ESTIMATE_SPREAD). The estimate is for the size
guard (refuse what cannot fit), not for planning to the node.
"""
from __future__ import annotations

import numpy as np

from mesh.blade import edge_sizing
from mesh.geometry import Section
from mesh.options import MeshOptions

#: Fitted constants of the model above (nodes per unit of each integral, tet10 nodes).
_A, _B = 2.31, 7.95
#: Largest ratio estimate / actual (or its inverse) over the meshes the constants were fitted on
#: (1 / 0.79, for element_size 0.016 m with 3 edge layers).
ESTIMATE_SPREAD = 1.3


def _chord(section: Section):
    """Chord coordinate along the camber (unrolled streamsurface) and normal thickness, m."""
    m = section.meridional_arc()
    camber = section.rtheta_upper - 0.5 * section.thickness
    s = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(m), np.diff(camber)))])
    slope = np.gradient(camber, m)
    return s, section.thickness / np.sqrt(1.0 + slope ** 2)


def mesh_integrals(sections: tuple[Section, ...], options: MeshOptions) -> tuple[float, float]:
    """(integral of t / h^3, integral of 2 / h^2) over the blade's mid-surface, (1/m, 1)."""
    sizing = edge_sizing(sections, options)
    per_section = []
    for sec in sections:
        s, t = _chord(sec)
        fine = np.linspace(0.0, s[-1], 4000)
        tt = np.interp(fine, s, t)
        d = np.minimum(fine, s[-1] - fine)
        ramp = max(sizing.ramp, 1e-300)
        h = sizing.edge_size + (sizing.bulk_size - sizing.edge_size) * np.minimum(d / ramp, 1.0)
        per_section.append((np.trapz(tt / h ** 3, fine), np.trapz(2.0 / h ** 2, fine)))
    span = np.array([sec.r.mean() for sec in sections])
    v, a = np.array(per_section).T
    return float(np.trapz(v, span)), float(np.trapz(a, span))


def estimate_nodes(sections: tuple[Section, ...], options: MeshOptions) -> float:
    """Estimated node count of the tet10 mesh of these sections (see the module's docstring)."""
    v, a = mesh_integrals(sections, options)
    return _A * v + _B * a


def imported_nodes(src) -> int:
    """Nodes of the tet10 mesh mesh.imported makes of a file's solids (mesh.source.SourceMesh),
    without splitting: the nodes the solid elements use, plus the mid node of each new edge
    mesh.subdivide creates, one per distinct quadrilateral face (its diagonal, shared by the
    two elements on the face) and one per hexahedron (its body diagonal, from its smallest
    vertex to the opposite one). Exact for a mesh the import accepts."""
    from mesh.elements import HEX20, quad_faces

    if not src.blocks:
        return 0
    used = np.unique(np.concatenate([b.connectivity.ravel() for b in src.blocks]))
    quads = quad_faces(src.blocks)
    n_faces = len(np.unique(np.sort(np.concatenate(quads), axis=1), axis=0)) if quads else 0
    n_hex = sum(len(b.connectivity) for b in src.blocks if b.type == HEX20.name)
    return int(len(used) + n_faces + n_hex)
