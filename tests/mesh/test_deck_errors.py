"""A malformed deck is refused with the file, the line of the keyword whose block is wrong,
and what is wrong: one case per check of `mesh.abaqus.read_deck`.

Each deck is the clean hex20 column of test_deck_defects (read without error, first test)
with one defect written into it; the expected line is found in the written text, not
counted by the code under test.
"""
import re
from pathlib import Path

import pytest

from mesh.abaqus import read_deck
from mesh.source import MeshImportError
from test_deck_defects import PLAIN_ROOT, _deck


def _write(path: Path, extra=()) -> Path:
    """The column with its plain root, `extra` lines after its elements."""
    return _deck(path, PLAIN_ROOT, extra)


def _line_of(path: Path, text: str) -> int:
    """1-based number of the first line of `path` that is `text`."""
    return path.read_text().splitlines().index(text) + 1


def test_the_clean_column_is_read(tmp_path):
    # the reference the cases below break: 6 hex20, the 8 root nodes fixed in x, y and z
    src = read_deck(_write(tmp_path / "clean.inp"))
    assert [(b.type, len(b.ids)) for b in src.blocks] == [("hexahedron20", 6)]
    assert src.fixed.sum(axis=0).tolist() == [8, 8, 8]


# (extra lines after the elements, the keyword line the error names, message after "file:line: ")
AFTER_ELEMENTS = [
    (["*INCLUDE"], "*INCLUDE", r"\*INCLUDE without INPUT=$"),
    (["*PART, NAME=BLADE"], "*PART, NAME=BLADE", r"\*PART: decks with parts and assemblies are not supported; write a "
                                                 r"flat deck \(Abaqus/CAE: model attributes"),
    (["*NODE, SYSTEM=C", "9001, 1.0, 0.0, 0.0"], "*NODE, SYSTEM=C",
     r"\*NODE, SYSTEM=C: only rectangular coordinates$"),
    (["*NODE", "9001, 1.0, 0.0"], "*NODE", r"\*NODE lines need 'id, x, y, z', got '9001, 1.0, 0.0'$"),
    (["*NODE", "9001, 1.0, 0.0, abc"], "*NODE", r"'abc' is not a number \(9001, 1.0, 0.0, abc\)$"),
    (["*ELEMENT, ELSET=MORE", "7, 1, 2"], "*ELEMENT, ELSET=MORE", r"\*ELEMENT without TYPE=$"),
    (["*ELEMENT, TYPE=C3D20, ELSET=MORE", "7, " + ", ".join(["1"] * 19)], "*ELEMENT, TYPE=C3D20, ELSET=MORE",
     r"\*ELEMENT, TYPE=C3D20: 20 numbers are not whole elements of 20 nodes plus an id$"),
    (["*ELEMENT, TYPE=S8R, ELSET=SKIN", "S1, 1, 2, 3, 4, 5, 6, 7, 8"], "*ELEMENT, TYPE=S8R, ELSET=SKIN",
     r"element lines need an integer id first$"),
    (["*NSET", "1, 2"], "*NSET", r"\*NSET without NSET=$"),
    (["*ELSET", "1, 2"], "*ELSET", r"\*ELSET without ELSET=$"),
    (["*NSET, NSET=SKIN, ELSET=NOPE"], "*NSET, NSET=SKIN, ELSET=NOPE", r"\*NSET, ELSET=NOPE: unknown element set$"),
    (["*NSET, NSET=MORE", "1, TYPO"], "*NSET, NSET=MORE", r"unknown node set 'TYPO'$"),
    (["*ELSET, ELSET=MORE", "EALL, TYPO"], "*ELSET, ELSET=MORE", r"unknown element set 'TYPO'$"),
    (["*NSET, NSET=MORE, GENERATE", "1, 8, 1, 4"], "*NSET, NSET=MORE, GENERATE",
     r"GENERATE needs 'first, last\[, increment\]' lines, got '1, 8, 1, 4'$"),
    (["*NSET, NSET=MORE, GENERATE", "1, x"], "*NSET, NSET=MORE, GENERATE",
     r"GENERATE needs 'first, last\[, increment\]' lines, got '1, x'$"),
    (["*NSET, NSET=MORE, GENERATE", "8, 1"], "*NSET, NSET=MORE, GENERATE",
     r"GENERATE line '8, 1' needs first <= last and a positive increment$"),
    (["*ELSET, ELSET=MORE, GENERATE", "1, 6, -1"], "*ELSET, ELSET=MORE, GENERATE",
     r"GENERATE line '1, 6, -1' needs first <= last and a positive increment$"),
    (["*BOUNDARY", "ROOT"], "*BOUNDARY", r"\*BOUNDARY line 'ROOT' names no dof$"),
    (["*BOUNDARY", "ROOT, , 3"], "*BOUNDARY", r"\*BOUNDARY line 'ROOT, , 3' names no dof$"),
    (["*BOUNDARY", "ROOT, x, 3"], "*BOUNDARY", r"cannot read \*BOUNDARY line 'ROOT, x, 3'$"),
    (["*BOUNDARY", "ROOT, 1, 3, zero"], "*BOUNDARY", r"cannot read \*BOUNDARY line 'ROOT, 1, 3, zero'$"),
    (["*BOUNDARY", "TYPO, 1, 3"], "*BOUNDARY", r"\*BOUNDARY names an unknown node set 'TYPO'$"),
]


@pytest.mark.parametrize("extra, keyword_line, message", AFTER_ELEMENTS,
                         ids=[re.sub(r"\W+", "_", c[2])[:40] for c in AFTER_ELEMENTS])
def test_a_malformed_block_is_named_with_its_line(tmp_path, extra, keyword_line, message):
    deck = _write(tmp_path / "bad.inp", extra)
    line = _line_of(deck, keyword_line)
    with pytest.raises(MeshImportError, match=rf"^(.*/)?bad.inp:{line}: " + message):
        read_deck(deck)


def test_a_fixed_node_id_not_in_the_deck_is_named(tmp_path):
    deck = _write(tmp_path / "bad.inp", ["*BOUNDARY", "99999, 1, 3"])
    line = _line_of(deck, "*BOUNDARY")
    with pytest.raises(MeshImportError, match=rf"\*BOUNDARY \(bad.inp:{line}\) refer to node ids not in the deck: "
                                              r"\[99999\]$"):
        read_deck(deck)


def test_an_element_on_a_missing_node_is_named(tmp_path):
    deck = _write(tmp_path / "bad.inp", ["*ELEMENT, TYPE=C3D20, ELSET=MORE", "7, 99999, " + ", ".join(["1"] * 19)])
    line = _line_of(deck, "*ELEMENT, TYPE=C3D20, ELSET=MORE")
    with pytest.raises(MeshImportError, match=rf"\*ELEMENT, TYPE hexahedron20 \(bad.inp:{line}\) refer to node "
                                              r"ids not in the deck: \[99999\]$"):
        read_deck(deck)


def test_a_deck_without_nodes_is_named(tmp_path):
    deck = _write(tmp_path / "bad.inp")
    text = deck.read_text()
    deck.write_text(text[:text.index("*NODE")] + text[text.index("*ELEMENT"):])
    with pytest.raises(MeshImportError, match=r"bad.inp: no \*NODE lines$"):
        read_deck(deck)


def test_a_node_id_that_is_not_an_integer_is_named(tmp_path):
    deck = _write(tmp_path / "bad.inp")
    deck.write_text(deck.read_text().replace("*NODE, NSET=NALL\n", "*NODE, NSET=NALL\n9001.5, 1.0, 0.0, 0.0\n"))
    with pytest.raises(MeshImportError, match=r"bad.inp: node ids must be integers$"):
        read_deck(deck)


def test_an_include_loop_and_an_unreadable_deck_are_named(tmp_path):
    deck = _write(tmp_path / "loop.inp", ["*INCLUDE, INPUT=loop.inp"])
    with pytest.raises(MeshImportError, match=r"loop.inp: \*INCLUDE loop$"):
        read_deck(deck)
    (tmp_path / "folder.inp").mkdir()
    with pytest.raises(MeshImportError, match=r"^cannot read .*folder.inp: "):
        read_deck(tmp_path / "folder.inp")


def test_a_boundary_of_another_type_fixes_nothing(tmp_path):
    # CalculiX: *BOUNDARY, TYPE=VELOCITY prescribes a velocity in a dynamic step, not a clamp
    deck = _write(tmp_path / "v.inp", ["*NSET, NSET=TIP", "601, 602, 603, 604", "*BOUNDARY, TYPE=VELOCITY", "TIP, 1, 3"])
    src = read_deck(deck)
    assert src.fixed.sum(axis=0).tolist() == [8, 8, 8]
    assert not src.fixed[[src.node_ids.tolist().index(i) for i in (601, 602, 603, 604)]].any()
