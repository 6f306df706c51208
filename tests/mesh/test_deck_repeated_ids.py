"""An .inp deck that defines an element id twice is broken (two meshes written with
overlapping numbering): CalculiX refuses it ("*ERROR reading *ELEMENT: element 2"), and the
reader used to take both elements silently. It is refused, naming the file and line of the
repeat, the id and where the id was first defined; so is a node id defined twice, whether
or not the coordinates differ (CalculiX keeps the last definition without a word).

The expected lines are counted from the decks as the tests write them."""
import re

import numpy as np
import pytest

from mesh.abaqus import read_deck
from mesh.source import MeshImportError

CORNERS = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
EDGES = [(0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)]  # tet10's mid-side nodes 5-10


def _tet10_nodes(first_id: int, shift: float) -> list[str]:
    """*NODE data lines of a tet10 (ids first_id .. first_id + 9) moved by `shift` along x."""
    x = np.vstack([CORNERS, [(CORNERS[a] + CORNERS[b]) / 2 for a, b in EDGES]]) + [shift, 0.0, 0.0]
    return [f"{first_id + k}, {p[0]!r}, {p[1]!r}, {p[2]!r}" for k, p in enumerate(x)]


def _tet10_element(eid: int, first_id: int, continued: bool = False) -> list[str]:
    """An element's data line(s); continued: cut after the sixth node, as some exporters do."""
    ids = [str(first_id + k) for k in range(10)]
    if continued:
        return [f"{eid}, " + ", ".join(ids[:6]) + ",", ", ".join(ids[6:])]
    return [f"{eid}, " + ", ".join(ids)]


def _write(path, lines):
    path.write_text("\n".join(lines) + "\n")
    return path


def _line_of(lines, text) -> list[int]:
    """1-based numbers of the lines that start with `text`."""
    return [k for k, line in enumerate(lines, 1) if line.startswith(text)]


def _refused(path, message):
    with pytest.raises(MeshImportError) as info:
        read_deck(path)
    assert re.fullmatch(message, str(info.value)), str(info.value)


# part A: elements 1, 2 on nodes 1-10 and 11-20; part B, written apart with its own
# numbering: element 2 on nodes 101-110 (the repeat), element 3 on 111-120
NODES = (["*NODE, NSET=NALL"] + _tet10_nodes(1, 0.0) + _tet10_nodes(11, 2.0) + _tet10_nodes(101, 4.0)
         + _tet10_nodes(111, 6.0))


@pytest.mark.parametrize("layout", ["one block", "two blocks", "continued lines", "other type between"])
def test_an_element_id_defined_twice_is_refused_with_both_lines(layout, tmp_path):
    continued = layout == "continued lines"
    a = _tet10_element(1, 1, continued) + _tet10_element(2, 11, continued)
    b = _tet10_element(2, 101, continued) + _tet10_element(3, 111, continued)
    head = "*ELEMENT, TYPE=C3D10, ELSET=EALL"
    if layout == "one block":
        lines = ["*HEADING", "two parts"] + NODES + [head] + a + b
    elif layout == "other type between":  # a skin of shells between the parts: read past, not counted
        lines = (["*HEADING", "two parts"] + NODES + [head] + a + ["*ELEMENT, TYPE=S3, ELSET=SKIN", "7, 1, 2, 3"]
                 + ["*ELEMENT, TYPE=C3D10R, ELSET=EB"] + b)
    else:
        lines = ["*HEADING", "two parts"] + NODES + [head] + a + ["** part B", head] + b
    deck = _write(tmp_path / "parts.inp", lines)
    (first,), (repeat,) = _line_of(lines, "2, 11, "), _line_of(lines, "2, 101, ")
    _refused(deck, rf"parts\.inp:{repeat}: element id 2 is defined twice, first at parts\.inp:{first}: .*"
                   r"Renumber one so that every \*ELEMENT id is defined once")


def test_the_repeat_in_an_included_file_is_named_there(tmp_path):
    """Part B *INCLUDEd: the repeat's line is that of the included file, the first one the top deck's."""
    part_b = ["*ELEMENT, TYPE=C3D10, ELSET=EB"] + _tet10_element(3, 111) + _tet10_element(1, 101)
    _write(tmp_path / "part_b.inp", ["** part B"] + part_b)
    lines = ["*HEADING"] + NODES + ["*ELEMENT, TYPE=C3D10, ELSET=EA"] + _tet10_element(1, 1) + _tet10_element(
        2, 11) + ["*INCLUDE, INPUT=part_b.inp"]
    deck = _write(tmp_path / "blade.inp", lines)
    (first,) = _line_of(lines, "1, 1, 2")
    _refused(deck, rf"part_b\.inp:4: element id 1 is defined twice, first at blade\.inp:{first}: .*")


def test_distinct_element_ids_are_read_as_numbered(tmp_path):
    """The parts renumbered apart: read, ids kept; element ids that are also node ids, and a
    continuation line that begins with an earlier element's id, are no repeats."""
    elements = (_tet10_element(1, 1, True) + _tet10_element(2, 11, True) + _tet10_element(7, 101, True)
                + _tet10_element(17, 111, True))
    deck = _write(tmp_path / "parts.inp", ["*HEADING"] + NODES + ["*ELEMENT, TYPE=C3D10, ELSET=EALL"] + elements)
    mesh = read_deck(deck)
    assert [b.ids.tolist() for b in mesh.blocks] == [[1, 2, 7, 17]]
    assert mesh.node_ids[mesh.blocks[0].connectivity[2]].tolist() == list(range(101, 111))


@pytest.mark.parametrize("moved", [False, True])
def test_a_node_id_defined_twice_is_refused_with_both_lines(moved, tmp_path):
    again = _tet10_nodes(11, 2.0)[3]  # node 14, as first written, or moved
    if moved:
        again = "14, 9.0, 9.0, 9.0"
    lines = (["*HEADING"] + NODES + ["*NODE, NSET=MORE", again, "*ELEMENT, TYPE=C3D10, ELSET=EALL"]
             + _tet10_element(1, 1) + _tet10_element(2, 11))
    deck = _write(tmp_path / "nodes.inp", lines)
    first, repeat = _line_of(lines, "14, ")
    what = ", with other coordinates" if moved else r" \(same coordinates\)"
    _refused(deck, rf"nodes\.inp:{repeat}: node id 14 is defined twice, first at nodes\.inp:{first}{what}: .*"
                   r"Renumber one so that every \*NODE id is defined once")


@pytest.mark.parametrize("where", ["after the solids", "before the solids", "two skins"])
def test_a_skipped_element_with_a_taken_id_is_refused_with_both_lines(where, tmp_path):
    """A shell is skipped, but its id is the deck's all the same: CalculiX refuses an S3 whose
    id a C3D10 has ("*ERROR reading *ELEMENT: element 1", ccx 2.20), and an *NSET, ELSET= naming
    the id would take both elements' nodes. Two skins repeating an id among themselves too."""
    solids = ["*ELEMENT, TYPE=C3D10, ELSET=EALL"] + _tet10_element(1, 1) + _tet10_element(2, 11)
    if where == "after the solids":
        lines = ["*HEADING"] + NODES + solids + ["*ELEMENT, TYPE=S3, ELSET=SKIN", "5, 1, 2, 3", "2, 11, 12, 13"]
        first, repeat = _line_of(lines, "2, 11, 12, 13, ")[0], lines.index("2, 11, 12, 13") + 1
    elif where == "before the solids":
        lines = ["*HEADING"] + NODES + ["*ELEMENT, TYPE=S3, ELSET=SKIN", "2, 11, 12, 13,"] + solids
        first, repeat = lines.index("2, 11, 12, 13,") + 1, _line_of(lines, "2, 11, 12, 13, ")[0]
    else:
        lines = (["*HEADING"] + NODES + solids + ["*ELEMENT, TYPE=S3, ELSET=SKIN", "7, 1, 2, 3"]
                 + ["*ELEMENT, TYPE=S6, ELSET=SKIN2", "8, 1, 2, 3, 5, 6, 7", "7, 11, 12, 13, 15, 16, 17"])
        first, repeat = lines.index("7, 1, 2, 3") + 1, lines.index("7, 11, 12, 13, 15, 16, 17") + 1
    deck = _write(tmp_path / "skin.inp", lines)
    eid = 7 if where == "two skins" else 2
    _refused(deck, rf"skin\.inp:{repeat}: element id {eid} is defined twice, first at skin\.inp:{first}: .*")


def test_skipped_elements_with_their_own_ids_are_read_as_before(tmp_path):
    """A root skin numbered apart from the solids: skipped and counted, its nodes still taken
    by a set of its elements."""
    lines = (["*HEADING"] + NODES + ["*ELEMENT, TYPE=C3D10, ELSET=EALL"] + _tet10_element(1, 1)
             + _tet10_element(2, 11) + ["*ELEMENT, TYPE=S3, ELSET=SKIN", "3, 1, 2, 3", "4, 11, 12, 13,"]
             + ["*NSET, NSET=ROOT, ELSET=SKIN"])
    mesh = read_deck(_write(tmp_path / "skin.inp", lines))
    assert mesh.ignored == {"S3": 2}
    assert sorted(mesh.node_ids[mesh.node_sets["ROOT"]].tolist()) == [1, 2, 3, 11, 12, 13]
