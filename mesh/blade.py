"""Blade solid and its quadratic tetrahedral mesh (gmsh, OpenCASCADE kernel).

Why tet10: the reference mesh of the paper uses quadratic prisms (pentahedra), but
dolfinx 0.5.2 cannot assemble quadratic prisms; quadratic tetrahedra are supported and,
being quadratic, still bend correctly with few elements across a thin blade.

The solid: each section (streamsurface) is a closed wire of two interpolating splines
through the tabulated points, x = r cos(theta), y = r sin(theta), z = axial, the upper
(suction) spline from LE to TE and the lower one back. All wires start at the LE, so the
lofted lateral faces meet along two lines, the LE and the TE. OpenCASCADE's ThruSections
cannot cap a non-planar wire, and hub and tip sections lie on cones, not planes; the
caps are therefore filling surfaces through the first and last wire, pinned to the camber
points of that section (which lie on the streamsurface), then sewn with the lateral faces
into one closed shell and volume. The cap deviates from the surface of revolution by less
than its width squared over 8 r (< 0.1 mm at the hub); cutting the lofted solid with
revolved streamsurfaces would be exact but takes 6-25 s of boolean operations.

Mesh size: `element_size` in the bulk; on the LE/TE lines the thinnest edge thickness of
the table over `edge_layers`, growing linearly with distance from those lines
(`size_growth`). The blade is less than 0.5 mm thick just behind the LE round at the tip,
so a uniform size would either be huge or give flat, intersecting surface triangles at the
edges (gmsh then fails with "PLC Error: a segment and a facet intersect").
"""
from __future__ import annotations

import contextlib
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mesh.geometry import GeometryError, Section, read_geometry
from mesh.model import BladeMesh
from mesh.options import BladeOptions, MeshOptions
from mesh.ordering import renumber_nodes
from mesh import tet10

GMSH_TET10 = 11
GMSH_TRI6 = 9


class MeshingError(RuntimeError):
    """gmsh could not build a valid solid or mesh from the sections."""


@dataclass(frozen=True)
class EdgeSizing:
    """Size field near the LE/TE lines.

    edge_thickness: thinnest normal thickness of the blade one thickness behind an edge, m.
    edge_size: element size on the LE/TE lines, m. bulk_size: element size far away, m.
    ramp: distance from the edge lines over which the size grows to bulk_size, m.
    """

    edge_thickness: float
    edge_size: float
    bulk_size: float
    ramp: float


def edge_thickness(section: Section) -> float:
    """Normal thickness one thickness behind the thinner of LE and TE (the edge round's size), m.

    Works in the unrolled streamsurface (meridional arc m, r*theta): the normal thickness is
    the tangential one times cos of the camber angle; the distance is along the camber.
    """
    m = section.meridional_arc()
    camber = section.rtheta_upper - 0.5 * section.thickness
    slope = np.gradient(camber, m)
    tn = section.thickness / np.sqrt(1.0 + slope ** 2)
    s = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(m), np.diff(camber)))])
    out = []
    for d in (s, s[-1] - s):  # distance from the LE, from the TE
        order = np.argsort(d)
        dd, tt = d[order], tn[order]
        f = tt - dd  # > 0 at the edge (d = 0 has tn = 0 only at the very point; skip it)
        k = 1 + int(np.argmax(f[1:] <= 0))
        if k == 1:
            out.append(float(tt[1]))
            continue
        w = f[k - 1] / (f[k - 1] - f[k])  # linear crossing of tn(d) = d
        out.append(float(tt[k - 1] + w * (tt[k] - tt[k - 1])))
    return min(out)


def edge_sizing(sections: tuple[Section, ...], options: MeshOptions) -> EdgeSizing:
    """The LE/TE size field from the thinnest edge of the given sections."""
    t = min(edge_thickness(s) for s in sections)
    h_edge = min(options.element_size, t / options.edge_layers)
    return EdgeSizing(edge_thickness=t, edge_size=h_edge, bulk_size=options.element_size,
                      ramp=(options.element_size - h_edge) / options.size_growth)


def reference_volume(sections: tuple[Section, ...]) -> float:
    """Blade volume from the table alone, m^3.

    Section area = integral of tangential thickness over the meridional arc length, then
    integrated (trapezoids) over the mean radius of the sections. Independent of the solid,
    but not exact: it spans the sections radially, not normal to the sloping streamsurfaces,
    and overestimates the table's blade (int int t dr dz over the meridional plane) by 2.2 %
    on rotor 67 (4.790e-5 against 4.687e-5 m^3, which the default mesh matches to 0.01 %)
    and 0.9 % on rotor 37.
    """
    area = np.array([s.area() for s in sections])
    r_mean = np.array([s.r.mean() for s in sections])
    return float(np.trapz(area, r_mean))


@contextlib.contextmanager
def _gmsh_session():
    """A gmsh session of our own (gmsh 4.8 cannot tell whether one is already open)."""
    import gmsh

    gmsh.initialize()
    try:
        gmsh.model.add("bladerub_blade")
        yield gmsh
    finally:
        gmsh.finalize()


def _build_solid(gmsh, sections: tuple[Section, ...]):
    """Closed blade volume; returns (volume tag, root face tag, tip face tag, LE/TE curve tags)."""
    occ = gmsh.model.occ
    wires, curves = [], []
    for s in sections:
        up, lo = s.upper_xyz(), s.lower_xyz()
        pu = [occ.addPoint(*p) for p in up]
        # LE and TE have zero thickness in the table: the lower spline reuses those points.
        pl = [pu[-1]] + [occ.addPoint(*p) for p in lo[-2:0:-1]] + [pu[0]]
        c = (occ.addSpline(pu), occ.addSpline(pl))
        curves.append(c)
        wires.append(occ.addWire(list(c)))
    lateral = [t for d, t in occ.addThruSections(wires, makeSolid=False, makeRuled=False) if d == 2]
    caps = []
    for s, c in ((sections[0], curves[0]), (sections[-1], curves[-1])):
        pins = [occ.addPoint(*p) for p in s.camber_xyz()[2:-2:4]]
        caps.append(occ.addSurfaceFilling(occ.addWire(list(c)), pointTags=pins))
    loop = occ.addSurfaceLoop(lateral + caps, sewing=True)
    vol = occ.addVolume([loop])
    occ.synchronize()
    keep = {(2, t) for _, t in gmsh.model.getBoundary([(3, vol)], oriented=False)}
    stale = [e for e in gmsh.model.getEntities(2) if e not in keep]
    occ.remove(stale, recursive=True)
    occ.remove([e for e in gmsh.model.getEntities(0)
                if not gmsh.model.getAdjacencies(*e)[0].size], recursive=False)
    occ.synchronize()
    vols = gmsh.model.getEntities(3)
    faces = [t for _, t in gmsh.model.getBoundary([(3, vol)], oriented=False)]
    if len(vols) != 1 or len(faces) != 4:
        raise MeshingError(f"blade solid is not one volume with 4 faces: volumes {vols}, faces {faces}")
    # Root and tip caps: the faces whose centres lie nearest the hub and tip sections' radii.
    radius = {t: float(np.hypot(*occ.getCenterOfMass(2, t)[:2])) for t in faces}
    root = min(faces, key=lambda t: abs(radius[t] - sections[0].r.mean()))
    tip = min(faces, key=lambda t: abs(radius[t] - sections[-1].r.mean()))
    if root == tip:
        raise MeshingError("could not tell the root face from the tip face")
    cap_curves = {abs(t) for f in (root, tip) for _, t in gmsh.model.getBoundary([(2, f)], oriented=False)}
    all_curves = {abs(t) for f in faces for _, t in gmsh.model.getBoundary([(2, f)], oriented=False)}
    edges = sorted(all_curves - cap_curves)
    if len(edges) != 2:
        raise MeshingError(f"expected LE and TE lines between the caps, found curves {edges}")
    return vol, root, tip, edges


def _set_size_field(gmsh, sizing: EdgeSizing, edges: list[int]):
    field = gmsh.model.mesh.field
    lengths = [gmsh.model.occ.getMass(1, c) for c in edges]
    dist = field.add("Distance")
    field.setNumbers(dist, "CurvesList", edges)
    # Sample the lines finely enough that the sampled distance errs by < edge_size / 2.
    field.setNumber(dist, "NumPointsPerCurve", int(np.ceil(max(lengths) / sizing.edge_size)) + 1)
    thr = field.add("Threshold")
    field.setNumber(thr, "InField", dist)
    field.setNumber(thr, "SizeMin", sizing.edge_size)
    field.setNumber(thr, "SizeMax", sizing.bulk_size)
    field.setNumber(thr, "DistMin", 0.0)
    field.setNumber(thr, "DistMax", sizing.ramp)
    field.setAsBackgroundMesh(thr)
    gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
    gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
    gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
    gmsh.option.setNumber("Mesh.MeshSizeMax", sizing.bulk_size)


def mesh_blade(blade: BladeOptions, options: MeshOptions, geometry_path: Path, node_order: str = "rcm") -> BladeMesh:
    """Read the table, build the blade solid from hub_section to tip_section, mesh it in tet10.

    The table is read in [blade] units, or in the unit it states when units is None
    (mesh.geometry.read_geometry refuses a units that contradicts the table's statement).

    Returns a `BladeMesh` (nodes in m, 0-based int64 gmsh-ordered connectivity, root/tip tri6,
    `options.n_boundary` tip contact nodes LE -> TE with their radius, angle and frames).
    node_order: mesh.ordering.NODE_ORDERS ("meshed": gmsh's tag order).
    Raises GeometryError for a bad table, MeshingError if gmsh fails or the mesh is invalid.
    """
    geometry = read_geometry(geometry_path, blade.format, blade.units)
    numbers = [s.number for s in geometry.sections]
    if blade.tip_section > numbers[-1]:
        raise GeometryError(f"tip_section {blade.tip_section} beyond the table's last surface {numbers[-1]}")
    sections = tuple(geometry.section(k) for k in range(blade.hub_section, blade.tip_section + 1))
    sizing = edge_sizing(sections, options)

    with _gmsh_session() as gmsh:
        # BLADERUB_GMSH_VERBOSE=1 shows gmsh's log
        gmsh.option.setNumber("General.Terminal", int(os.environ.get("BLADERUB_GMSH_VERBOSE", "0")))
        gmsh.option.setNumber("General.NumThreads", 2)
        # Determinism: gmsh's multi-threaded 1D/2D meshing gave different surface meshes from
        # run to run (with this size field), and HXT 3D did even on one thread; so curves
        # and surfaces are meshed serially and the volume by the serial Delaunay mesher.
        gmsh.option.setNumber("Mesh.MaxNumThreads1D", 1)
        gmsh.option.setNumber("Mesh.MaxNumThreads2D", 1)
        try:
            vol, root, tip, edges = _build_solid(gmsh, sections)
        except Exception as exc:  # gmsh raises bare Exception
            raise MeshingError(f"gmsh could not build the blade solid: {exc}") from exc
        solid_volume = gmsh.model.occ.getMass(3, vol)
        _set_size_field(gmsh, sizing, edges)
        gmsh.option.setNumber("Mesh.Algorithm", 6)  # Frontal-Delaunay surfaces
        gmsh.option.setNumber("Mesh.Algorithm3D", 1)  # Delaunay: deterministic
        gmsh.option.setNumber("Mesh.ElementOrder", 2)
        # Straight-sided tet10: mid-edge nodes at chord midpoints. Curving them onto the filling
        # caps took minutes (point projections), and at the default sizes the chord sagitta
        # h^2 / (8 R) is < 0.03 mm at the LE round (R ~ 0.2 mm) and a few um on the blade faces
        # and caps (the caps curve about the axis, R = r); the coarse scenes' h = 8 mm leaves
        # mid-edge nodes of the hub cap up to 0.1 mm below its streamsurface. Affine cells also
        # have positive Jacobians wherever their vertices do.
        gmsh.option.setNumber("Mesh.SecondOrderLinear", 1)
        try:
            gmsh.model.mesh.generate(3)
        except Exception as exc:
            raise MeshingError(f"gmsh could not mesh the blade: {exc}") from exc
        tags, coords, _ = gmsh.model.mesh.getNodes()
        _, cell_tags = gmsh.model.mesh.getElementsByType(GMSH_TET10, vol)
        _, root_tags = gmsh.model.mesh.getElementsByType(GMSH_TRI6, root)
        _, tip_tags = gmsh.model.mesh.getElementsByType(GMSH_TRI6, tip)

    # Keep the nodes used by the cells, in tag order: 0-based, deterministic indices.
    tags = np.asarray(tags, dtype=np.int64)
    coords = np.asarray(coords).reshape(-1, 3)
    cell_tags = np.asarray(cell_tags, dtype=np.int64).reshape(-1, 10)
    used = np.unique(cell_tags)
    order = np.argsort(tags)
    pos = order[np.searchsorted(tags[order], used)]
    nodes = np.ascontiguousarray(coords[pos])

    def index(t, width):
        return np.searchsorted(used, np.asarray(t, dtype=np.int64).reshape(-1, width)).astype(np.int64)

    cells = index(cell_tags, 10)
    root_facets, tip_facets = index(root_tags, 6), index(tip_tags, 6)

    det = tet10.jacobian_determinants(nodes, cells)
    if not np.all(det > 0):
        bad = int(np.sum(np.any(det <= 0, axis=1)))
        raise MeshingError(f"{bad} quadratic cells have non-positive Jacobians; refine element_size")
    volume = float(tet10.cell_volumes(nodes, cells).sum())
    if not np.isclose(volume, solid_volume, rtol=1e-2):  # OCC mass of B-spline solids: ~0.3 %
        raise MeshingError(f"mesh volume {volume:.6e} m^3 differs from the solid's {solid_volume:.6e} m^3")

    b = boundary_nodes(nodes, tip_facets, sections[-1], options.n_boundary)
    mesh = BladeMesh(nodes=nodes, cells=cells, root_facets=root_facets, tip_facets=tip_facets,
                     boundary_node_index=b.index, boundary_xyz=b.xyz, boundary_rho=b.rho,
                     boundary_theta=b.theta, boundary_frames=b.frames, volume=volume,
                     reference_volume=reference_volume(sections))
    return renumber_nodes(mesh, node_order)


@dataclass(frozen=True)
class BoundaryNodes:
    """Tip contact nodes, LE (0) to TE.

    index: (n_b,) mesh node indices. xyz: (n_b, 3), m. rho: (n_b,) radius, m.
    theta: (n_b,) angle relative to node 0, rad, in (-pi, pi]. frames: (n_b, 3, 3) rows e_r, e_theta, e_z.
    targets: (n_b, 3) the evenly spaced camber points the nodes were snapped from, m.
    """

    index: np.ndarray
    xyz: np.ndarray
    rho: np.ndarray
    theta: np.ndarray
    frames: np.ndarray
    targets: np.ndarray


def camber_points(section: Section, n: int) -> np.ndarray:
    """(n, 3) points evenly spaced in arc length along the section's camber line, LE to TE, m."""
    return points_along(section.camber_xyz(), n)


def points_along(polyline: np.ndarray, n: int) -> np.ndarray:
    """(n, 3) points evenly spaced in arc length along a (k, 3) polyline, first to last point."""
    c = np.asarray(polyline, dtype=np.float64)
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(c, axis=0), axis=1))])
    u = np.linspace(0.0, s[-1], n)
    return np.column_stack([np.interp(u, s, c[:, i]) for i in range(3)])


def nearest_nodes(nodes: np.ndarray, candidates: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """(n,) the candidate node nearest to each of the (n, 3) targets (not necessarily distinct).

    A target midway between nodes (as on a regular mesh, to round-off) takes, of those, the
    one of smallest axial coordinate z, then radius, then angle from the candidates' mean
    angle: never the lower node index, so that the same blade numbered differently, or
    turned about the axis, gets the same nodes.
    Raises ValueError when there is no candidate or `targets` is not (n, 3)."""
    candidates = np.asarray(candidates, dtype=np.int64)
    targets = np.asarray(targets, dtype=np.float64)
    if targets.ndim != 2 or targets.shape[1] != 3:
        raise ValueError(f"targets must be (n, 3) points, m, got shape {targets.shape}")
    if candidates.size == 0:
        raise ValueError(f"no candidate nodes to snap the {len(targets)} target points to (empty candidate set)")
    x = nodes[candidates]
    d = np.linalg.norm(x[None, :, :] - targets[:, None, :], axis=2)
    tol = 1e-9 * float(np.abs(x).max())
    r = np.hypot(x[:, 0], x[:, 1])
    phi = np.arctan2(x[:, 1], x[:, 0])
    arc = r * np.angle(np.exp(1j * (phi - np.angle(np.exp(1j * phi).mean()))))  # m, about the mean angle
    out = np.empty(len(d), dtype=np.int64)
    for k, row in enumerate(d):
        s = np.flatnonzero(row <= row.min() + tol)
        for key in (x[:, 2], r, arc):
            if s.size == 1:
                break
            s = s[key[s] <= key[s].min() + tol]
        out[k] = s[0]
    return candidates[out]


def contact_geometry(nodes: np.ndarray, index: np.ndarray, targets: np.ndarray | None = None) -> BoundaryNodes:
    """Radius, angle relative to the first node, and local frames (e_r, e_theta, e_z) of the
    contact nodes `index` (LE first); z is the rotation axis."""
    index = np.asarray(index, dtype=np.int64)
    n = len(index)
    xyz = nodes[index]
    rho = np.hypot(xyz[:, 0], xyz[:, 1])
    phi = np.arctan2(xyz[:, 1], xyz[:, 0])
    zero = np.zeros(n)
    frames = np.stack([np.column_stack([np.cos(phi), np.sin(phi), zero]),
                       np.column_stack([-np.sin(phi), np.cos(phi), zero]),
                       np.column_stack([zero, zero, zero + 1.0])], axis=1)
    return BoundaryNodes(index=index, xyz=xyz, rho=rho, theta=_wrapped(phi - phi[0]), frames=frames,
                         targets=xyz.copy() if targets is None else targets)


def _wrapped(angle: np.ndarray) -> np.ndarray:
    """Angles in (-pi, pi]: atan2 jumps by 2 pi where a blade crosses its cut (the -x axis), and
    a jump would turn the sign of theta_TE - theta_LE (rom.rotation's sense of rotation). Only
    the angles beyond +-pi move, so theta is bit for bit phi - phi[0] where nothing wraps."""
    out = np.where(angle > np.pi, angle - 2.0 * np.pi, angle)
    return np.where(out <= -np.pi, out + 2.0 * np.pi, out)


def boundary_nodes(nodes: np.ndarray, tip_facets: np.ndarray, tip: Section, n: int) -> BoundaryNodes:
    """Snap n evenly spaced tip camber points to the nearest nodes of the tip face."""
    targets = camber_points(tip, n)
    index = nearest_nodes(nodes, np.unique(tip_facets), targets)
    if len(np.unique(index)) != n:
        raise MeshingError(f"{n} boundary nodes snap onto fewer distinct tip nodes; refine the mesh")
    return contact_geometry(nodes, index, targets)
