"""Bring your own mesh: wedge15/hex20 decks split into tet10, root, tip and contact nodes.

The references are independent of the code under test: exact volumes of boxes (L b t),
the analytic map that made a curved deck, the deck's own *BOUNDARY set written by the
test, and the table-built rotor 67 mesh exported as a deck.
"""
import dataclasses
from pathlib import Path

import numpy as np
import pytest

from decks import AXIS_ROTATIONS, UNITS, box, deck_ids, root_nodes, write_deck
from mesh import tet10
from mesh.imported import import_blade
from mesh.options import BladeOptions, MeshOptions
from mesh.source import MeshImportError

KINDS = ("wedge15", "hexahedron20")
CONE_DEG = 45.0  # root face tilt of the "conical hub" decks
TET10_EDGES = ((0, 1), (1, 2), (2, 0), (3, 0), (3, 2), (3, 1))


def _import(deck: Path, n_boundary=5, **blade):
    blade = {"mesh": deck.name, "units": "m", **blade}
    return import_blade(BladeOptions(**blade), MeshOptions(n_boundary=n_boundary), deck)


def _faces(cells):
    """Every tet face as (sorted corner triple, mid nodes of its three edges in a canonical order)."""
    out = []
    for a, b, c in ((0, 1, 2), (0, 1, 3), (0, 2, 3), (1, 2, 3)):
        v = cells[:, [a, b, c]]
        mid = {}
        for k, (i, j) in enumerate(TET10_EDGES):
            mid[frozenset((i, j))] = cells[:, 4 + k]
        out.append((v, np.stack([mid[frozenset((a, b))], mid[frozenset((b, c))], mid[frozenset((a, c))]], 1)))
    return out


def conformity(cells):
    """(interior face count, boundary faces as corner triples): asserts that each triple is
    used by one or two cells, and by two only with the same six nodes."""
    faces = {}
    for v, m in _faces(cells):
        for tri, mids in zip(v, m):
            key = tuple(sorted(tri))
            # mid nodes keyed by their edge's corner pair, whatever the face orientation
            edge_mid = {frozenset(p): x for p, x in zip(((tri[0], tri[1]), (tri[1], tri[2]), (tri[0], tri[2])), mids)}
            faces.setdefault(key, []).append(edge_mid)
    interior, boundary = 0, []
    for key, uses in faces.items():
        assert len(uses) <= 2, f"face {key} used by {len(uses)} cells"
        if len(uses) == 2:
            assert uses[0] == uses[1], f"face {key}: the two cells disagree on its mid-edge nodes"
            interior += 1
        else:
            boundary.append(key)
    return interior, np.array(boundary)


@pytest.fixture(scope="module")
def decks(tmp_path_factory):
    d = tmp_path_factory.mktemp("decks")
    out = {}
    for kind in KINDS:
        for variant, kw in (("plain", {}), ("perturbed", {"perturb": 0.3, "n": (12, 3, 2)}),
                            ("cone", {"cone_deg": CONE_DEG, "n": (24, 3, 2)})):
            bx = box(kind, **kw)
            deck = d / f"{kind}_{variant}.inp"
            write_deck(deck, bx, root=root_nodes(bx, kw.get("cone_deg", 0.0)))
            out[kind, variant] = (bx, deck)
    return out


@pytest.mark.parametrize("kind", KINDS)
def test_split_preserves_volume_per_element(decks, kind):
    bx, deck = decks[kind, "plain"]
    m = _import(deck, n_boundary=3)
    # each parent's tets add up to the parent's exact volume: the straight box elements of
    # n = (30, 2, 1) divisions (wedges: half a brick, "Alternate" cuts each rectangle in two)
    brick = (bx.L / 30) * (bx.b / 2) * (bx.t / 1)
    exact = brick / 2 if kind == "wedge15" else brick
    v = tet10.cell_volumes(m.nodes, m.cells)
    assert v.min() > 0
    per_parent = np.bincount(np.repeat(np.arange(len(bx.cells)), 3 if kind == "wedge15" else 6), weights=v)
    # gmsh places the nodes within 3e-14 m of the ideal grid (transfinite interpolation),
    # 6e-12 of the 5 mm thickness: that, not the split, bounds the agreement
    np.testing.assert_allclose(per_parent, exact, rtol=2e-11)
    # the product's own figures: its tet10 volume and its Gauss volume of the file's elements
    assert m.volume == pytest.approx(bx.L * bx.b * bx.t, rel=2e-11)
    assert m.reference_volume == pytest.approx(bx.L * bx.b * bx.t, rel=2e-11)
    # and the split against the parents' own volumes (same coordinates): round-off
    assert m.volume == pytest.approx(m.reference_volume, rel=1e-13)
    # straight-sided parents: every mid-edge node at its edge's midpoint in gmsh tet10 order
    # (gmsh's own mid nodes to its 3e-14 m noise; a wrong ordering misses by millimetres)
    x = m.nodes
    for k, (a, b) in enumerate(TET10_EDGES):
        np.testing.assert_allclose(x[m.cells[:, 4 + k]], 0.5 * (x[m.cells[:, a]] + x[m.cells[:, b]]), atol=1e-13)


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("variant", ("perturbed", "cone"))
def test_split_conforms_and_keeps_the_volume_of_distorted_decks(decks, kind, variant):
    bx, deck = decks[kind, variant]
    m = _import(deck, n_boundary=3)
    # Perturbed: corner nodes moved inside the box (warped interior faces, trilinear
    # elements), the box's faces still planar. Cone: x -> x + (1 - s) tan(45 deg) z, a
    # bilinear map (det J = 1 - tan z / L, odd in z). Both keep the volume L b t exactly, and
    # a conforming tet10 mesh encloses exactly its boundary surface: to round-off (and to
    # gmsh's 3e-14 m node noise, 2e-11 relative, as above).
    assert m.volume == pytest.approx(bx.L * bx.b * bx.t, rel=2e-11)
    assert m.volume == pytest.approx(m.reference_volume, rel=1e-13)
    assert tet10.jacobian_determinants(m.nodes, m.cells).min() > 0
    interior, boundary = conformity(m.cells)
    assert interior > 0
    # no face is left unmatched inside: every unshared face lies on the box's surface, and
    # they cover its area 2 (L b + L t + b t) once (the cone's root face: the tilted plane)
    x = m.nodes
    c = x[boundary].mean(axis=1)
    tan = np.tan(np.radians(CONE_DEG)) if variant == "cone" else 0.0
    on = ((np.abs(c[:, 0] - bx.R0 - tan * c[:, 2]) < 1e-12) | (np.abs(c[:, 0] - bx.R0 - bx.L) < 1e-12)
          | (np.abs(np.abs(c[:, 1]) - bx.t / 2) < 1e-12) | (np.abs(np.abs(c[:, 2]) - bx.b / 2) < 1e-12))
    assert on.all()
    a, b_, c_ = (x[boundary[:, i]] for i in range(3))
    area = 0.5 * np.linalg.norm(np.cross(b_ - a, c_ - a), axis=1).sum()
    root_area = bx.b * bx.t / np.cos(np.radians(CONE_DEG)) if variant == "cone" else bx.b * bx.t
    # side faces x-z of the cone deck are planar trapezoids of area L b (shear keeps it)
    assert area == pytest.approx(2 * bx.L * bx.b + 2 * bx.L * bx.t + bx.b * bx.t + root_area, rel=2e-11)
    if variant == "cone":
        # new mid nodes sit on the parent's own (curved) geometry: the analytic map of the
        # unmapped chord's midpoint, not the chord midpoint of the mapped corners
        k = np.tan(np.radians(CONE_DEG))
        new = np.flatnonzero(m.source_node_ids < 0)
        cells_with_new = np.isin(m.cells[:, 4:], new)
        r, j = np.nonzero(cells_with_new)
        pa, pb = (m.cells[r, [TET10_EDGES[q][i] for q in j]] for i in (0, 1))
        xa, xb = x[pa].copy(), x[pb].copy()
        for p in (xa, xb):  # invert the map: x = u + (1 - (u - R0) / L) k z  =>  u from x, z
            p[:, 0] = (p[:, 0] - k * p[:, 2] * (1 + bx.R0 / bx.L)) / (1 - k * p[:, 2] / bx.L)
        u = 0.5 * (xa + xb)
        u[:, 0] += (1 - (u[:, 0] - bx.R0) / bx.L) * k * u[:, 2]
        np.testing.assert_allclose(x[m.cells[r, 4 + j]], u, atol=1e-13)  # gmsh's node noise
        chord_mid = 0.5 * (x[pa] + x[pb])
        assert np.abs(x[m.cells[r, 4 + j]] - chord_mid).max() > 1e-5  # curved indeed


@pytest.mark.parametrize("kind", KINDS)
def test_conical_root_is_clamped_exactly_on_the_boundary_set(decks, kind):
    bx, deck = decks[kind, "cone"]
    root = root_nodes(bx, CONE_DEG)
    ids_root = set(deck_ids(len(bx.points))[root].tolist())
    m = _import(deck, n_boundary=3)
    clamped = np.unique(m.root_facets)
    x = m.nodes
    file_clamped = m.source_node_ids[clamped[m.source_node_ids[clamped] >= 0]]
    assert set(file_clamped.tolist()) == ids_root
    # the split's new nodes that are clamped are exactly those on the root face
    on_root_face = np.abs(x[:, 0] - bx.R0 - np.tan(np.radians(CONE_DEG)) * x[:, 2]) < 1e-12
    new = m.source_node_ids < 0
    assert set(clamped[new[clamped]].tolist()) == set(np.flatnonzero(new & on_root_face).tolist())
    # not a radius threshold: the root spans 2 cm of radius and free nodes lie inside that band
    r = np.hypot(x[:, 0], x[:, 1])
    assert r[clamped].max() - r[clamped].min() > 1.5e-2
    free = np.setdiff1d(np.arange(len(x)), clamped)
    assert (r[free] < r[clamped].max()).sum() > 10
    # the same set by name and by the faces that face the axis (cross-check of 'hub')
    for how in ("nset:root", "hub"):
        other = _import(deck, n_boundary=3, root=how)
        np.testing.assert_array_equal(np.unique(other.root_facets), clamped)


@pytest.mark.parametrize("axis, units", [("z", "m"), ("x", "mm"), ("y", "cm")])
def test_axis_and_units_map_the_file_onto_the_product_frame(decks, tmp_path, axis, units):
    bx, _ = decks["wedge15", "plain"]
    deck = tmp_path / "box.inp"
    ids = write_deck(deck, bx, axis=axis, units=units, root=root_nodes(bx))
    m = _import(deck, units=units, axis=axis)
    keep = m.source_node_ids >= 0
    pos = np.searchsorted(ids, m.source_node_ids[keep])
    np.testing.assert_allclose(m.nodes[keep], bx.points[pos], atol=1e-12)
    # the stored transform takes the file's coordinates to the product's
    xf = (bx.points @ AXIS_ROTATIONS[axis]) / UNITS[units]
    np.testing.assert_allclose(m.source_scale * xf[pos] @ m.source_rotation.T, m.nodes[keep], atol=1e-12)
    assert np.linalg.det(m.source_rotation) == pytest.approx(1.0)
    # contact nodes: on the tip (x = R0 + L), LE (smallest z) first, evenly along the chord
    xb = m.boundary_xyz
    np.testing.assert_allclose(xb[:, 0], bx.R0 + bx.L, atol=1e-12)
    np.testing.assert_allclose(xb[:, 2], np.linspace(-bx.b / 2, bx.b / 2, 5), atol=1e-12)
    np.testing.assert_allclose(xb[:, 1], 0.0, atol=1e-12)
    assert m.boundary_theta[0] == 0.0


def test_listed_contact_nodes_are_taken_in_order(decks, tmp_path):
    bx, _ = decks["hexahedron20", "plain"]
    deck = tmp_path / "box.inp"
    ids = write_deck(deck, bx, root=root_nodes(bx))
    tip = np.flatnonzero(np.abs(bx.points[:, 0] - bx.R0 - bx.L) < 1e-12)
    chosen = ids[tip[[4, 0, 7]]].tolist()
    m = _import(deck, contact_nodes=chosen)
    np.testing.assert_array_equal(m.source_node_ids[m.boundary_node_index], chosen)
    np.testing.assert_allclose(m.boundary_xyz, bx.points[tip[[4, 0, 7]]], atol=1e-15)


def _bad(tmp_path, bx, **kw):
    deck = tmp_path / "bad.inp"
    write_deck(deck, bx, root=root_nodes(bx), **kw)
    return deck


def test_bad_meshes_are_named(decks, tmp_path):
    bx, _ = decks["wedge15", "plain"]
    cases = [
        (dict(kind="wedge"), {}, r"linear elements, 6-node wedges \(120\).*quadratic"),
        (dict(extra="*ELEMENT, TYPE=C3D6\n999, 1001, 1002, 1003, 1004, 1005, 1006"), {},
         r"mixed element types, linear 6-node wedges \(1\) with quadratic wedge15"),
        (dict(extra="*ELEMENT, TYPE=C3D13\n999, " + ", ".join(str(1001 + i) for i in range(13))), {},
         r"unsupported element type 'C3D13'"),
        (dict(boundary=False), {}, r"fixes no node"),
        (dict(boundary=False, extra="*BOUNDARY\nROOT, 1, 1"), {}, r"fixes only some translations"),
        # a blank last dof is the first (CalculiX): x alone, not x to z
        (dict(boundary=False, extra="*BOUNDARY\nROOT, 1,, 0"), {}, r"fixes only some translations"),
        (dict(extra="*BOUNDARY\nROOT, 1, 3, 0.5"), {}, r"non-zero displacement"),
        (dict(extra="*NSET, NSET=EMPTY"), {"root": "nset:EMPTY"}, r"root node set 'EMPTY' is empty"),
        ({}, {"root": "nset:HUB"}, r"root node set 'HUB' not found; the file's node sets: NALL, ROOT"),
        ({}, {"contact_nodes": [1001, 99999, 5]}, r"contact_nodes \[99999, 5\] are not node ids of the file"),
        ({}, {"axis": "x"}, r"no tip face along axis 'x'"),  # x: the blade's span
    ]
    for deck_kw, blade_kw, message in cases:
        with pytest.raises(MeshImportError, match=message):
            _import(_bad(tmp_path, bx, **deck_kw), **blade_kw)


def test_more_bad_meshes_are_named(decks, tmp_path):
    bx, _ = decks["hexahedron20", "plain"]
    loose = "*NODE, NSET=LOOSE\n99990, 0.21, 0.0, 0.0"  # a node of no element
    cases = [
        (dict(extra=loose), {"root": "nset:LOOSE"}, r"the root set 'nset:LOOSE' holds no node of the solid elements"),
        (dict(extra=loose), {"contact_nodes": [99990, 1001]}, r"contact_nodes \[99990\] belong to no solid element"),
        # the tip face has 5 x 3 corner and mid nodes across its 0.02 m chord: 60 cannot be distinct
        ({}, {"n_boundary": 60}, r"60 contact nodes \(\[mesh\] n_boundary\) snap onto fewer distinct nodes of the tip"),
        # one element written twice under another id: its split tetrahedra overlap
        (dict(extra="*ELEMENT, TYPE=C3D20, ELSET=EALL\n999, " + ", ".join(map(str, deck_ids(len(bx.points))[bx.cells[0]][:15]))
              + ",\n" + ", ".join(map(str, deck_ids(len(bx.points))[bx.cells[0]][15:]))), {},
         r"a triangular face is shared by 4 cells \(overlapping elements\)"),
    ]
    for deck_kw, blade_kw, message in cases:
        n_boundary = blade_kw.pop("n_boundary", 5)
        with pytest.raises(MeshImportError, match=message):
            _import(_bad(tmp_path, bx, **deck_kw), n_boundary=n_boundary, **blade_kw)
    shell = tmp_path / "shell.inp"
    shell.write_text("*NODE\n1, 0, 0, 0\n2, 1, 0, 0\n3, 1, 1, 0\n4, 0, 1, 0\n*ELEMENT, TYPE=S4\n1, 1, 2, 3, 4\n")
    with pytest.raises(MeshImportError, match=r"shell.inp: no solid elements \(other elements: S4 x 1\)$"):
        _import(shell)


def test_a_tip_sloped_past_60_degrees_is_no_tip_face(decks, tmp_path):
    # x += s z shears the box: its tip plane's normal turns atan(s) from the radial direction
    # (26.6 deg at s = 0.5, 71.6 deg at 3), and the facet farthest from the axis, on the
    # sheared tip's far edge, is a side facet (normal along z) once the tip slopes past 60 deg
    bx, _ = decks["hexahedron20", "plain"]
    for s, refused in ((0.5, False), (3.0, True)):
        pts = bx.points.copy()
        pts[:, 0] += s * pts[:, 2]
        deck = _bad(tmp_path, dataclasses.replace(bx, points=pts))
        if refused:
            with pytest.raises(MeshImportError, match=r"no tip face along axis 'z': the boundary facet farthest from "
                                                      r"the axis faces 90 deg away from the outward radial direction"):
                _import(deck)
        else:
            m = _import(deck)
            tip = m.nodes[np.unique(m.tip_facets)]
            # the tip face found is the sheared plane x = R0 + L + s z, whole (5 x 3 nodes per column)
            np.testing.assert_allclose(tip[:, 0], bx.R0 + bx.L + s * tip[:, 2], atol=1e-12)


def test_tetrahedra_glued_onto_a_hexahedron_face_are_refused(decks, tmp_path):
    # a tet10 cap on three corners of a tip quadrilateral: conforming would need a pyramid
    bx, _ = decks["hexahedron20", "plain"]
    ids = deck_ids(len(bx.points))
    cell = bx.cells[-1]
    a, b, c = cell[4], cell[5], cell[6]  # corners 5-7 of the last hex: on the tip face x = R0 + L
    assert np.allclose(bx.points[[a, b, c], 0], bx.R0 + bx.L)
    pa, pb, pc = bx.points[[a, b, c]]
    apex = (pa + pb + pc) / 3 + [0.005, 0.0, 0.0]
    new = [apex, (pa + pb) / 2, (pb + pc) / 2, (pc + pa) / 2, (pa + apex) / 2, (pb + apex) / 2, (pc + apex) / 2]
    lines = ["*NODE"] + [f"{99900 + i}, {p[0]!r}, {p[1]!r}, {p[2]!r}" for i, p in enumerate(new)]
    conn = [ids[a], ids[b], ids[c]] + [99900 + i for i in range(7)]
    lines += ["*ELEMENT, TYPE=C3D10, ELSET=CAP", "999, " + ", ".join(map(str, conn))]
    named = ", ".join(map(str, sorted(ids[[a, b, c]])))
    with pytest.raises(MeshImportError, match=rf"tetrahedra meet a quadrilateral face of a wedge or hexahedron "
                                              rf"\(nodes \[{named}\] \.\.\.\); such a junction needs pyramids"):
        _import(_bad(tmp_path, bx, extra="\n".join(lines)))


def test_inverted_element_is_named(decks, tmp_path):
    bx, _ = decks["hexahedron20", "plain"]
    cells = bx.cells.copy()
    # element 8 upside down: corners 0-3 <-> 4-7 and the mid nodes with them
    cells[7] = cells[7][[4, 5, 6, 7, 0, 1, 2, 3, 12, 13, 14, 15, 8, 9, 10, 11, 16, 17, 18, 19]]
    bad = dataclasses.replace(bx, cells=cells)
    with pytest.raises(MeshImportError, match=r"1 inverted or degenerate element .*element ids \[8\]"):
        _import(_bad(tmp_path, bad))


@pytest.mark.parametrize("kind", KINDS)
def test_an_element_inverted_only_near_one_corner_is_named(decks, tmp_path, kind):
    # A mid-edge node slid along its straight edge to a fraction a of it from corner A: the
    # edge's map x(xi) = quadratic through 0, a, 1 has dx/dxi = 4a - 1 at A (times the edge's
    # length), negative for a < 1/4 (the quarter-point limit) and positive from the edge's
    # middle on. So det J < 0 at A's check point only, and every element holding the node is
    # refused; at a = 0.3 (dx/dxi >= 0.2 everywhere on the edge) the same mesh is accepted.
    bx, _ = decks[kind, "plain"]
    first_mid = {"wedge15": 6, "hexahedron20": 8}[kind]  # the mid node of corners 0-1
    cell = bx.cells[7]
    node, a, b = cell[first_mid], cell[0], cell[1]
    owners = 1 + np.flatnonzero((bx.cells == node).any(axis=1))  # deck element ids (1-based)
    for frac, refused in ((0.2, True), (0.3, False)):
        pts = bx.points.copy()
        pts[node] = pts[a] + frac * (pts[b] - pts[a])
        moved = dataclasses.replace(bx, points=pts)
        deck = _bad(tmp_path, moved)
        if refused:
            n = len(owners)
            ids = ", ".join(str(i) for i in owners)
            with pytest.raises(MeshImportError, match=rf"{n} inverted or degenerate elements? .*element ids \[{ids}\]"):
                _import(deck, n_boundary=3)
        else:
            assert len(_import(deck, n_boundary=3).cells) > 0


def test_contact_node_on_the_root_is_refused(decks, tmp_path):
    bx, _ = decks["wedge15", "plain"]
    deck = tmp_path / "box.inp"
    ids = write_deck(deck, bx, root=root_nodes(bx))
    with pytest.raises(MeshImportError, match="lie on the clamped root"):
        _import(deck, contact_nodes=[int(ids[root_nodes(bx)[0]]), int(ids[-1])])


def test_rotor67_table_mesh_read_back_as_a_deck(tmp_path):
    # The coarse rotor 67 mesh bladerub makes from the NASA table, written as a C3D10 deck in
    # mm about the file's y axis, read back with root = "hub" and contact nodes chosen on the
    # tip: the same nodes, root face, tip face, and contact nodes near the table's camber
    # points: the tip/hub finders and the LE convention (smallest axial coordinate) on a
    # twisted blade with conical hub and tip, against the table's own definitions.
    from support import SHARED
    from mesh.blade import mesh_blade

    table = BladeOptions()
    m0 = mesh_blade(table, MeshOptions(element_size=0.008, edge_layers=1, size_growth=0.5),
                    SHARED / "data" / "rotor67" / "rotor67geometry.dat")
    from decks import Box

    bx = Box("tetra10", m0.nodes, m0.cells[:, [0, 1, 2, 3, 4, 5, 6, 7, 9, 8]], 0.0, 1.0, 1.0, 1.0)
    deck = tmp_path / "r67.inp"
    ids = write_deck(deck, bx, axis="y", units="mm")
    m = _import(deck, n_boundary=9, units="mm", axis="y", root="hub")
    pos = np.searchsorted(ids, m.source_node_ids)
    np.testing.assert_allclose(m.nodes, m0.nodes[pos], atol=1e-12)
    assert set(pos[np.unique(m.root_facets)].tolist()) == set(np.unique(m0.root_facets).tolist())
    assert set(pos[np.unique(m.tip_facets)].tolist()) == set(np.unique(m0.tip_facets).tolist())
    # LE and TE of the table are mesh nodes (geometry vertices): hit exactly; the others within
    # half the 12 mm spacing of the table's even camber points (the camber traced from the
    # mesh differs from the table's by less than an element)
    b0 = m0.boundary_xyz
    np.testing.assert_allclose(m.boundary_xyz[[0, -1]], b0[[0, -1]], atol=1e-12)
    spacing = np.linalg.norm(np.diff(b0, axis=0), axis=1).min()
    assert np.linalg.norm(m.boundary_xyz - b0, axis=1).max() < 0.5 * spacing
    np.testing.assert_allclose(m.boundary_frames, m0.boundary_frames[np.argmin(
        np.linalg.norm(m.boundary_xyz[:, None] - b0[None], axis=2), axis=1)], atol=0.05)
    assert m.volume == pytest.approx(m0.volume, rel=1e-12)


@pytest.mark.parametrize("kind", KINDS)
def test_gmsh_msh_file_through_meshio(tmp_path, kind):
    # the same gmsh mesh as .msh (read by meshio, with its 15-node wedges registered) and as
    # a deck: the same solid, and root = "nset:ROOT" (a physical surface) = the deck's *BOUNDARY
    bx = box(kind, n=(12, 2, 1), msh=tmp_path / "box.msh")
    write_deck(tmp_path / "box.inp", bx, root=root_nodes(bx))
    a = _import(tmp_path / "box.inp", n_boundary=3)
    b = _import(tmp_path / "box.msh", n_boundary=3, root="nset:ROOT")
    assert b.n_nodes == a.n_nodes and len(b.cells) == len(a.cells)
    assert b.volume == pytest.approx(bx.L * bx.b * bx.t, rel=2e-11)
    key = lambda x: np.round(x / 1e-9).astype(np.int64).tolist()  # noqa: E731
    assert sorted(map(tuple, key(b.nodes))) == sorted(map(tuple, key(a.nodes)))
    ra, rb = a.nodes[np.unique(a.root_facets)], b.nodes[np.unique(b.root_facets)]
    assert sorted(map(tuple, key(ra))) == sorted(map(tuple, key(rb)))
    np.testing.assert_allclose(b.boundary_xyz, a.boundary_xyz, atol=1e-12)
    with pytest.raises(MeshImportError, match=r"root = \"boundary\" needs the file's own boundary conditions"):
        _import(tmp_path / "box.msh")


@pytest.mark.parametrize("text, message", [
    ('mesh = "b.inp"\ngeometry = "t.dat"\nunits = "mm"', r"\[blade\] geometry .* and mesh .* are mutually exclusive"),
    ('mesh = "b.inp"', r"\[blade\] units is required with mesh"),
    ('mesh = "b.inp"\nunits = "furlong"', r"unknown length unit 'furlong'"),
    ('mesh = "b.inp"\nunits = "mm"\naxis = "w"', r"\[blade\] axis must be one of x, y, z"),
    ('mesh = "b.inp"\nunits = "mm"\nroot = "clamp"', r"\[blade\] root must be"),
    ('mesh = "b.inp"\nunits = "mm"\nroot = "nset:"', r"\[blade\] root must be"),
    ('mesh = "b.inp"\nunits = "mm"\ncontact_nodes = [3]', r"contact_nodes needs at least 2 node ids"),
    ('mesh = "b.inp"\nunits = "mm"\ncontact_nodes = [3, 4, 3]', r"contact_nodes lists a node twice"),
    ('mesh = "b.inp"\nunits = "mm"\ncontact_nodes = [3, 4.5]', r"\[blade\] contact_nodes"),
    ('axis = "x"', r"\[blade\] axis applies to a mesh file only"),
    ('contact_nodes = [1, 2]', r"\[blade\] contact_nodes applies to a mesh file only"),
    ('mesh = "b.inp"\nunits = "mm"\nroots = "hub"', r"unknown key 'roots' in \[blade\] \(did you mean 'root'\?\)"),
])
def test_scene_keys_are_validated(text, message):
    from pipelines.scene import SceneError, parse_scene

    with pytest.raises(SceneError, match=message):
        parse_scene("[blade]\n" + text + "\n")


def test_scene_defaults():
    from pipelines.scene import parse_scene

    table = parse_scene("")
    assert table.blade.geometry.endswith("rotor67geometry.dat") and table.blade.units is None  # the unit the table states
    assert table.blade.mesh is None and table.blade.source == table.blade.geometry
    own = parse_scene('[blade]\nmesh = "b.inp"\nunits = "mm"\ncontact_nodes = [12, 40]\n')
    assert own.blade.geometry is None and own.blade.source == "b.inp"
    assert (own.blade.axis, own.blade.root, own.blade.contact_nodes) == ("z", "boundary", (12, 40))


def test_deck_dialects_read_alike(decks, tmp_path):
    # What meshio 5's Abaqus reader gets wrong, read here: two *NODE blocks (meshio keeps the
    # last), an *INCLUDE, lower-case keywords and comments inside data, C3D20R elements
    # continued on a second line, NSET ... GENERATE and sets of sets, *BOUNDARY ENCASTRE.
    bx, _ = decks["hexahedron20", "plain"]
    plain = tmp_path / "plain.inp"
    ids = write_deck(plain, bx, root=root_nodes(bx))
    a = _import(plain, n_boundary=3)
    node_lines = [f"{i},{x:.17g},{y:.17g},{z:.17g}" for i, (x, y, z) in zip(ids, bx.points)]
    half = len(node_lines) // 2
    (tmp_path / "more_nodes.inp").write_text("*node\n" + "\n".join(node_lines[half:]) + "\n")
    body = ["** another dialect", "*Heading", "dialects", "*node, nset=nall", *node_lines[:half],
            "** between blocks", "*include, input=more_nodes.inp", "*element, type=C3D20R, elset=eall"]
    for e, row in enumerate(ids[bx.cells], 1):
        body += [f"{e}, " + ", ".join(map(str, row[:15])) + ",", ", ".join(map(str, row[15:]))]
        if e == 3:
            body.append("** a comment inside the data")
    root = np.sort(ids[root_nodes(bx)])
    body += ["*nset, nset=first, generate", f"{root[0]}, {root[0]}, 1", "*nset, nset=rest"]
    body += [", ".join(map(str, root[1:][i:i + 8])) for i in range(0, len(root) - 1, 8)]
    body += ["*nset, nset=root_all", "first, rest", "*boundary", "root_all, ENCASTRE"]
    dialect = tmp_path / "dialect.inp"
    dialect.write_text("\n".join(body) + "\n")
    b = _import(dialect, n_boundary=3)
    np.testing.assert_array_equal(b.source_node_ids, a.source_node_ids)
    np.testing.assert_array_equal(b.nodes, a.nodes)
    np.testing.assert_array_equal(b.cells, a.cells)
    np.testing.assert_array_equal(np.unique(b.root_facets), np.unique(a.root_facets))
    from mesh.source import source_files

    assert [p.name for p in source_files(dialect)] == ["dialect.inp", "more_nodes.inp"]


def test_clamped_node_on_no_complete_face_is_kept(decks, tmp_path):
    # A root set may hold nodes that complete no boundary facet (here: one extra node on a
    # side face); they stay clamped, as degenerate root rows (the node six times).
    bx, _ = decks["wedge15", "plain"]
    x = bx.points
    side = np.flatnonzero((np.abs(x[:, 1] - bx.t / 2) < 1e-12) & (np.abs(x[:, 0] - bx.R0 - 0.15) < 1e-9))[0]
    deck = tmp_path / "box.inp"
    ids = write_deck(deck, bx, root=np.append(root_nodes(bx), side))
    m = _import(deck)
    k = int(np.flatnonzero(m.source_node_ids == ids[side])[0])
    assert k in np.unique(m.root_facets)
    rows = m.root_facets[np.any(m.root_facets == k, axis=1)]
    np.testing.assert_array_equal(rows, np.full((1, 6), k))
    assert set(m.source_node_ids[np.unique(m.root_facets)].tolist()) - {-1} == set(ids[np.append(root_nodes(bx), side)].tolist())


def test_a_node_set_keeps_its_nodes_beside_a_cell_set_of_the_same_name(tmp_path, monkeypatch):
    """A file read through meshio with a node set and a cell set both named ROOT (a MED
    node group and a face group, say): root = "nset:ROOT" means the node set's nodes, not
    the faces' (a cell set becomes a node set only under a name no node set has); a
    cell set of its own name gives its cells' nodes."""
    import meshio

    from mesh.source import read_source

    points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]], dtype=float)
    tets = meshio.CellBlock("tetra", np.array([[0, 1, 2, 3], [1, 2, 3, 4]]))
    tris = meshio.CellBlock("triangle", np.array([[0, 1, 2], [1, 2, 4]]))
    fake = meshio.Mesh(points, [tets, tris], point_sets={"ROOT": np.array([0, 3])},
                       cell_sets={"ROOT": [None, np.array([1])], "TIP": [None, np.array([0])]})
    monkeypatch.setattr(meshio, "read", lambda path, *a, **k: fake)
    (tmp_path / "blade.vtu").write_bytes(b"")
    src = read_source(tmp_path / "blade.vtu")
    assert src.node_sets["ROOT"].tolist() == [0, 3]
    assert src.node_sets["TIP"].tolist() == [0, 1, 2]
    assert src.ignored == {"triangle": 2} and [b.type for b in src.blocks] == ["tetra"]


def test_unmerged_mid_nodes_and_a_solid_in_two_parts_are_named(decks, tmp_path):
    """Two hex20 elements that share a face's corners but each have their own copy of one of
    its mid-edge nodes (an exporter that merged the corners only), and a deck of two boxes
    side by side that share no node: each refused by name, where the FEM would otherwise
    take a crack through the blade, or a free-floating part, for the blade."""
    bx, _ = decks["hexahedron20", "plain"]
    # element 1's mid-edge nodes on the face it shares with element 2: a copy for element 1
    shared = np.intersect1d(bx.cells[0], bx.cells[1])
    mid = [k for k in range(8, 20) if bx.cells[0][k] in shared]
    assert len(shared) == 8 and mid  # 4 corners and 4 mid nodes of a shared quadrilateral face
    cells = bx.cells.copy()
    cells[0][mid[0]] = len(bx.points)
    points = np.vstack([bx.points, bx.points[bx.cells[0][mid[0]]]])
    cracked = dataclasses.replace(bx, points=points, cells=cells)
    with pytest.raises(MeshImportError, match=r"non-conforming mesh: two cells share a face's corners but not its "
                                              r"mid-edge nodes"):
        _import(_bad(tmp_path, cracked))
    n = len(bx.points)
    two = dataclasses.replace(bx, points=np.vstack([bx.points, bx.points + [0.0, 3.0 * bx.b, 0.0]]),
                              cells=np.vstack([bx.cells, bx.cells + n]))
    with pytest.raises(MeshImportError, match=r"the solid falls into 2 disconnected parts"):
        _import(_bad(tmp_path, two))
