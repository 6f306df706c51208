"""Mesh files read as CalculiX (or the file's own numbering) reads them: defects found in
review of the user-mesh import, one test each.

References: CalculiX (ccx) runs the same deck written two ways (the syntax under test and
a plain spelling of it) and must find the same frequencies, which shows it reads both as
one model; otherwise explicit values written into the test (node ids, angles, counts).
"""
from pathlib import Path

import meshio
import numpy as np
import pytest

from decks import ccx_frequencies
from mesh.abaqus import read_deck
from mesh.blade import contact_geometry
from mesh.imported import _check_elements, import_blade
from mesh.options import BladeOptions, MeshOptions
from mesh.source import MeshImportError, SolidBlock, SourceMesh, read_source, source_files

ROOT_IDS = list(range(1, 9))  # the column's root face (x = R0): corner and mid-side nodes 1-8
MATERIAL = ["*MATERIAL, NAME=MAT", "*ELASTIC", "2e11, 0.3", "*DENSITY", "7800",
            "*SOLID SECTION, ELSET=EALL, MATERIAL=MAT", "*STEP", "*FREQUENCY", "3", "*END STEP"]


def _column(n_el=6, L=0.3, R0=0.2, t=0.01, b=0.02):
    """A radial column of n_el hex20 along x (R0 to R0 + L), chord b along z, thickness t
    along y: (the *HEADING and *NODE lines, the *ELEMENT data lines of element k). Node
    ids 100 k + 1-8 on the face x = R0 + k L / n_el, 100 k + 51-54 on the edges between:
    numbering with gaps, as decks have."""
    ys, zs = [-t / 2, t / 2, t / 2, -t / 2], [-b / 2, -b / 2, b / 2, b / 2]
    lines = ["*HEADING", "hex20 column", "*NODE, NSET=NALL"]
    for k in range(n_el + 1):
        x = R0 + L * k / n_el
        for j in range(4):
            jn = (j + 1) % 4
            lines.append(f"{100 * k + 1 + j}, {x!r}, {ys[j]!r}, {zs[j]!r}")
            lines.append(f"{100 * k + 5 + j}, {x!r}, {(ys[j] + ys[jn]) / 2!r}, {(zs[j] + zs[jn]) / 2!r}")
            if k < n_el:
                lines.append(f"{100 * k + 51 + j}, {x + L / n_el / 2!r}, {ys[j]!r}, {zs[j]!r}")

    def element(k):
        o = 100 * k
        c = [o + 1, o + 2, o + 3, o + 4, o + 101, o + 102, o + 103, o + 104, o + 5, o + 6, o + 7, o + 8,
             o + 105, o + 106, o + 107, o + 108, o + 51, o + 52, o + 53, o + 54]
        return [f"{k + 1}, " + ", ".join(map(str, c[:15])) + ",", ", ".join(map(str, c[15:]))]

    return lines, [line for k in range(n_el) for line in element(k)]


def _deck(path: Path, root: list[str], extra: list[str] = (), element_line="*ELEMENT, TYPE=C3D20, ELSET=EALL",
          material=False) -> Path:
    """The column as a deck: root = the lines that define and fix the root."""
    nodes, elements = _column()
    path.write_text("\n".join(nodes + [element_line] + elements + list(extra) + root
                              + (MATERIAL if material else [])) + "\n")
    return path


PLAIN_ROOT = ["*NSET, NSET=ROOT", ", ".join(map(str, ROOT_IDS)), "*BOUNDARY", "ROOT, 1, 3"]


def _import(deck: Path, n_boundary=3, **blade):
    blade = {"mesh": deck.name, "units": "m", **blade}
    return import_blade(BladeOptions(**blade), MeshOptions(n_boundary=n_boundary), deck)


def _root_ids(m) -> list[int]:
    ids = m.source_node_ids[np.unique(m.root_facets)]
    return sorted(ids[ids >= 0].tolist())


@pytest.fixture(scope="module")
def plain(tmp_path_factory):
    """The column with its root listed and fixed plainly: (deck, ccx frequencies, bladerub's root ids)."""
    d = tmp_path_factory.mktemp("plain")
    deck = _deck(d / "plain.inp", PLAIN_ROOT, material=True)
    return deck, ccx_frequencies(deck, d / "ccx"), _root_ids(_import(deck))


def test_generate_increment_is_optional(tmp_path, plain):
    # GENERATE lines are "first, last[, increment]", one per line: the numbers of a block
    # were cut into threes, so "1, 10 / 21, 30 / 41, 50" gave ranges 1-21 (step 10) and 30-41 (step 50)
    nodes = "\n".join(f"{i}, {float(i)}, 0.0, 0.0" for i in range(1, 61))
    deck = tmp_path / "gen.inp"
    deck.write_text(f"*NODE\n{nodes}\n*NSET, NSET=S, GENERATE\n1, 10\n21, 30,\n41, 50, 1\n*ELSET, ELSET=E, GENERATE\n"
                    "20, 24\n")
    s = read_deck(deck)
    assert s.node_ids[s.node_sets["S"]].tolist() == [*range(1, 11), *range(21, 31), *range(41, 51)]
    # the root by "1, 8" (no increment): CalculiX runs it as the plain deck, and so does bladerub
    _, f_plain, root_plain = plain
    gen = _deck(tmp_path / "root_gen.inp", ["*NSET, NSET=ROOT, GENERATE", "1, 8", "*BOUNDARY", "ROOT, 1, 3"],
                material=True)
    np.testing.assert_allclose(ccx_frequencies(gen, tmp_path / "ccx"), f_plain, rtol=1e-6)
    assert _root_ids(_import(gen)) == root_plain
    assert set(ROOT_IDS) <= set(root_plain)


def test_boundary_fields_are_read_by_position(tmp_path, plain):
    # "ROOT, 1,, 0": a blank last dof (= the first); dropping blank fields read 0 as the last
    # dof, so nothing was fixed (or "0." failed as a dof)
    _, f_plain, root_plain = plain
    blank = _deck(tmp_path / "blank.inp", ["*NSET, NSET=ROOT", ", ".join(map(str, ROOT_IDS)), "*BOUNDARY",
                                           "ROOT, 1,, 0", "ROOT, 2,, 0.", "ROOT, 3,, 0"], material=True)
    np.testing.assert_allclose(ccx_frequencies(blank, tmp_path / "ccx"), f_plain, rtol=1e-6)
    assert _root_ids(_import(blank)) == root_plain
    s = read_deck(blank)
    assert sorted(s.node_ids[s.fixed.all(axis=1)].tolist()) == ROOT_IDS
    moved = _deck(tmp_path / "moved.inp", ["*NSET, NSET=ROOT", ", ".join(map(str, ROOT_IDS)), "*BOUNDARY",
                                           "ROOT, 1,, 0.5"])
    with pytest.raises(MeshImportError, match=r"moved.inp:\d+: \*BOUNDARY 'ROOT, 1,, 0.5' prescribes a non-zero"):
        read_deck(moved)


def test_theta_is_continuous_across_the_atan2_cut():
    # contact nodes on either side of the -x axis: theta relative to the LE must not jump by 2 pi
    phi = np.array([np.pi - 0.010, np.pi - 0.004, -np.pi + 0.002, -np.pi + 0.008])
    nodes = 0.5 * np.column_stack([np.cos(phi), np.sin(phi), np.zeros(4)])
    theta = contact_geometry(nodes, np.arange(4)).theta
    np.testing.assert_allclose(theta, [0.0, 0.006, 0.012, 0.018], atol=1e-12)
    # the other way round (TE behind the LE across the cut)
    np.testing.assert_allclose(contact_geometry(nodes[::-1], np.arange(4)).theta, [0.0, -0.006, -0.012, -0.018],
                               atol=1e-12)
    # where nothing wraps (the NASA tables' blades), theta stays bit for bit phi - phi[0]
    rng = np.random.default_rng(1)
    phi = rng.uniform(-1.5, 1.5, 50)  # differences within +-3 rad: nothing to wrap
    nodes = rng.uniform(0.1, 0.3, 50)[:, None] * np.column_stack([np.cos(phi), np.sin(phi), np.zeros(50)])
    phi = np.arctan2(nodes[:, 1], nodes[:, 0])
    assert np.array_equal(contact_geometry(nodes, np.arange(50)).theta, phi - phi[0])


def test_blade_turned_onto_the_cut_keeps_its_contact_angles(tmp_path):
    # the same staggered column turned by 0 and 180 degrees about the axis: its tip then
    # straddles theta = +-pi, and theta must be the same numbers
    nodes, elements = _column()
    k = nodes.index("*NODE, NSET=NALL") + 1
    theta = []
    for angle in (0.0, 180.0):
        c, s = np.cos(np.radians(angle)), np.sin(np.radians(angle))
        turned = []
        for line in nodes[k:]:
            i, x, y, z = (float(v) for v in line.split(","))
            y += 0.2 * z  # stagger: the LE and the TE differ in angle
            turned.append(f"{int(i)}, {c * x - s * y!r}, {s * x + c * y!r}, {z!r}")
        deck = tmp_path / f"turned{int(angle)}.inp"
        deck.write_text("\n".join(nodes[:k] + turned + ["*ELEMENT, TYPE=C3D20, ELSET=EALL"] + elements
                                  + PLAIN_ROOT) + "\n")
        theta.append(_import(deck, n_boundary=3).boundary_theta)
    assert np.ptp(theta[0]) > 1e-3
    np.testing.assert_allclose(theta[1], theta[0], atol=1e-12)


@pytest.mark.parametrize("lines, keyword", [
    (["*NGEN, NSET=MORE", "1, 5, 1"], "*NGEN"),
    (["*NFILL, NSET=MORE", "A, B, 4, 10"], "*NFILL"),
    (["*NCOPY, OLD SET=NALL, NEW SET=COPY, CHANGE NUMBER=1000, SHIFT", "0., 0., 0.1"], "*NCOPY"),
    (["*NMAP, NSET=NALL, TYPE=RECTANGULAR", "0, 0, 0"], "*NMAP"),
    (["*SYSTEM", "0.0, 0.0, 0.1"], "*SYSTEM"),
    (["*ELGEN, ELSET=EALL", "1, 6, 100, 1"], "*ELGEN"),
    (["*ELCOPY, OLD SET=EALL, NEW SET=COPY, ELEMENT SHIFT=100, SHIFT NODES=1000"], "*ELCOPY"),
    (["*NODE, NSET=MORE, INPUT=more_nodes.inp"], "*NODE, INPUT=more_nodes.inp"),
    (["*ELEMENT, TYPE=C3D20, ELSET=EALL, INPUT=more_elements.inp"], "*ELEMENT, INPUT=more_elements.inp"),
    (["*NSET, NSET=MORE, INPUT=set.inp"], "*NSET, INPUT=set.inp"),
    (["*ELSET, ELSET=MORE, INPUT=set.inp"], "*ELSET, INPUT=set.inp"),
])
def test_keywords_that_make_or_move_nodes_or_elements_are_refused(tmp_path, lines, keyword):
    # they were skipped without a word: an *ELGEN deck imported as one element of six
    deck = _deck(tmp_path / "gen.inp", PLAIN_ROOT, extra=lines)
    with pytest.raises(MeshImportError, match=r"^gen.inp:\d+: " + keyword.replace("*", r"\*")):
        _import(deck)


def test_empty_element_blocks_are_dropped(tmp_path, monkeypatch):
    # an *ELEMENT block without data lines: a raw ValueError in the split (C3D15), and "mixed
    # element types ... 8-node hexahedra (0)" (C3D8)
    plain = _import(_deck(tmp_path / "plain.inp", PLAIN_ROOT))
    for etype in ("C3D15", "C3D8", "S8R"):
        deck = _deck(tmp_path / f"empty_{etype}.inp", PLAIN_ROOT, extra=[f"*ELEMENT, TYPE={etype}, ELSET=NONE"])
        src = read_deck(deck)
        assert [(b.type, len(b.ids)) for b in src.blocks] == [("hexahedron20", 6)] and src.ignored == {}
        m = _import(deck)
        np.testing.assert_array_equal(m.cells, plain.cells)
        np.testing.assert_array_equal(m.nodes, plain.nodes)
    # the meshio path: a file with an empty block (as meshio hands it over)
    s = read_deck(tmp_path / "plain.inp")
    pts = s.points
    empty = meshio.Mesh(pts, [("hexahedron", np.zeros((0, 8), dtype=np.int64)),
                              ("hexahedron20", s.blocks[0].connectivity), ("quad", np.zeros((0, 4), dtype=np.int64))])
    monkeypatch.setattr(meshio, "read", lambda path: empty)
    f = tmp_path / "empty.vtu"
    f.write_text("")
    src = read_source(f)
    assert [(b.type, len(b.ids)) for b in src.blocks] == [("hexahedron20", 6)] and src.ignored == {}
    _check_elements(src, f)


def test_bdf_node_ids_are_the_grid_ids(tmp_path):
    # meshio keeps a Nastran file's GRID ids (points_id) and element ids (cells_id): they are
    # the ids the user sees, so contact_nodes and source_node_ids use them, not positions
    src = read_deck(_deck(tmp_path / "column.inp", PLAIN_ROOT))
    f = tmp_path / "column.bdf"
    meshio.write(f, meshio.Mesh(src.points, [("hexahedron20", src.blocks[0].connectivity)]))
    # a first GRID numbered 99999 (unused): positions and ids part from the first node on
    text = f.read_text().replace(
        "BEGIN BULK\n", "BEGIN BULK\nGRID*   99999                                      0.E+0           0.E+0\n"
                        "*                  0.E+0\n", 1)
    f.write_text(text)
    s = read_source(f)
    assert s.node_ids[:4].tolist() == [99999, 1, 2, 3]
    np.testing.assert_allclose(s.points[1:], src.points, atol=1e-12)
    assert s.blocks[0].ids.tolist() == [1, 2, 3, 4, 5, 6]
    # two tip nodes by GRID id (meshio wrote GRID i for point i - 1; positions are one further on)
    tip = np.flatnonzero(np.isclose(src.points[:, 0], 0.5))[:2]
    ids = (tip + 1).tolist()
    m = _import(f, root="hub", contact_nodes=ids)
    np.testing.assert_allclose(m.boundary_xyz, src.points[tip], atol=1e-12)
    assert m.source_node_ids[m.boundary_node_index].tolist() == ids


def test_generate_range_across_gaps_and_unused_sets(tmp_path, plain):
    # "*NSET, GENERATE / 1, 120, 1" crosses ids the deck does not define (9-50, 55-100, ...):
    # CalculiX runs the deck, and bladerub refused it although the set is not used
    _, f_plain, root_plain = plain
    extra = ["*NSET, NSET=OTHER, GENERATE", "1, 120, 1", "*NSET, NSET=TYPO", "1, 2, 99999"]
    deck = _deck(tmp_path / "gap.inp", PLAIN_ROOT, extra=extra, material=True)
    np.testing.assert_allclose(ccx_frequencies(_deck(tmp_path / "gap_ccx.inp", PLAIN_ROOT, extra=extra[:2],
                                                     material=True), tmp_path / "ccx"), f_plain, rtol=1e-6)
    s = read_deck(deck)
    assert sorted(s.node_ids[s.node_sets["OTHER"]].tolist()) == [*range(1, 9), *range(51, 55), *range(101, 109)]
    assert s.unknown_ids["TYPO"].tolist() == [99999]
    assert _root_ids(_import(deck)) == root_plain
    # a set that is used must name nodes of the deck
    with pytest.raises(MeshImportError, match=r"root node set 'TYPO' names node ids not in the file: \[99999\]"):
        _import(deck, root="nset:TYPO")
    bad = _deck(tmp_path / "bad.inp", ["*NSET, NSET=ROOT", "1, 2, 3, 4, 5, 6, 7, 8, 99999", "*BOUNDARY", "ROOT, 1, 3"])
    with pytest.raises(MeshImportError, match=r"bad.inp:\d+: \*BOUNDARY set 'ROOT' names node ids not in the deck: "
                                              r"\[99999\]"):
        read_deck(bad)


def test_xdmf_source_files_list_the_heavy_data(tmp_path):
    # the .h5 holds the nodes and cells: a changed .h5 must change the mesh stage's inputs
    src = read_deck(_deck(tmp_path / "column.inp", PLAIN_ROOT))
    x = tmp_path / "blade.xdmf"
    meshio.write(x, meshio.Mesh(src.points, [("hexahedron20", src.blocks[0].connectivity)]))
    assert source_files(x) == [x, tmp_path / "blade.h5"]


def test_byte_order_mark_before_the_first_keyword(tmp_path):
    plain = _deck(tmp_path / "plain.inp", PLAIN_ROOT)
    text = plain.read_text()
    bom = tmp_path / "bom.inp"
    bom.write_bytes(b"\xef\xbb\xbf" + text[text.index("*NODE"):].encode())
    a, b = read_deck(plain), read_deck(bom)
    np.testing.assert_array_equal(b.points, a.points)
    np.testing.assert_array_equal(b.node_ids, a.node_ids)
    # an *INCLUDE'd file with a BOM, too
    (tmp_path / "root.inp").write_bytes(b"\xef\xbb\xbf" + "\n".join(PLAIN_ROOT).encode() + b"\n")
    inc = _deck(tmp_path / "inc.inp", ["*INCLUDE, INPUT=root.inp"])
    s = read_deck(inc)
    assert sorted(s.node_ids[s.fixed.all(axis=1)].tolist()) == ROOT_IDS


def test_continued_keyword_line_is_refused_by_line(tmp_path):
    # CalculiX stops at "*ELEMENT, TYPE=C3D20," + "ELSET=EALL" (continued keyword line): refused,
    # naming the line, rather than "'ELSET=EALL' is not a number"
    deck = _deck(tmp_path / "cont.inp", PLAIN_ROOT, element_line="*ELEMENT, TYPE=C3D20,\nELSET=EALL")
    line = deck.read_text().splitlines().index("*ELEMENT, TYPE=C3D20,") + 1
    with pytest.raises(MeshImportError, match=rf"^cont.inp:{line}: keyword line '\*ELEMENT, TYPE=C3D20,' is "
                                              r"continued on the next line \('ELSET=EALL'\)"):
        read_deck(deck)
    # a keyword line merely ending in "," before its data lines: CalculiX reads it, and so does bladerub
    trailing = _deck(tmp_path / "trailing.inp", PLAIN_ROOT, element_line="*ELEMENT, TYPE=C3D20, ELSET=EALL,")
    assert [(b.type, len(b.ids)) for b in read_deck(trailing).blocks] == [("hexahedron20", 6)]


def test_element_counts_sum_every_block_of_a_type(tmp_path):
    # meshio files may hold several blocks of one type (gmsh: one per physical group)
    def block(kind, n, k):
        return SolidBlock(kind, np.zeros((k, n), dtype=np.int64), np.arange(k))

    src = SourceMesh(points=np.zeros((20, 3)), node_ids=np.arange(1, 21),
                     blocks=(block("tetra", 4, 7), block("wedge", 6, 1), block("tetra", 4, 2)))
    with pytest.raises(MeshImportError, match=r"linear elements, 4-node tetrahedra \(9\), 6-node wedges \(1\):"):
        _check_elements(src, tmp_path / "three_blocks.msh")
    src = SourceMesh(points=np.zeros((20, 3)), node_ids=np.arange(1, 21),
                     blocks=(block("tetra10", 10, 3), block("tetra", 4, 7), block("tetra", 4, 2)))
    with pytest.raises(MeshImportError, match=r"linear 4-node tetrahedra \(9\) with quadratic tetra10 \(3\)"):
        _check_elements(src, tmp_path / "mixed.msh")


def test_a_nested_include_named_from_the_top_decks_folder_is_read(tmp_path, plain):
    """job.inp includes mesh/part.inp, which includes mesh/nodes.inp as "mesh/nodes.inp":
    CalculiX, run from job.inp's folder, reads it so (and gives the plain deck's
    frequencies); bladerub reads it too, the same nodes and root, and hashes the file."""
    deck, freqs, root = plain
    lines = deck.read_text().splitlines()
    i = lines.index("*NODE, NSET=NALL")
    j = next(k for k, line in enumerate(lines) if line.startswith("*ELEMENT"))
    (tmp_path / "mesh").mkdir()
    (tmp_path / "mesh" / "nodes.inp").write_text("\n".join(lines[i:j]) + "\n")
    (tmp_path / "mesh" / "part.inp").write_text("*INCLUDE, INPUT=mesh/nodes.inp\n")
    job = tmp_path / "top.inp"
    job.write_text("\n".join(lines[:i] + ["*INCLUDE, INPUT=mesh/part.inp"] + lines[j:]) + "\n")
    np.testing.assert_allclose(ccx_frequencies(job, tmp_path), freqs, rtol=1e-9)  # run from top.inp's folder
    assert _root_ids(_import(job)) == root
    assert source_files(job) == [job, tmp_path / "mesh" / "part.inp", tmp_path / "mesh" / "nodes.inp"]
    (tmp_path / "mesh" / "part.inp").write_text("*INCLUDE, INPUT=mesh/none.inp\n")
    with pytest.raises(MeshImportError, match=r"included file not found: .*mesh/mesh/none.inp \(nor .*"
                                              r"/mesh/none.inp, from the top deck's folder\)"):
        _import(job)
