"""Decks as real exports write them, read as CalculiX reads them: one test per defect found
in an audit of the .inp import (the syntax that was read wrongly or refused).

References: CalculiX (ccx) runs the deck in the syntax under test and a plain spelling of
it and finds the same frequencies (so it reads both as one model); bladerub must then read
the two alike, to the bit. Where CalculiX does not read the syntax (*NSET, ELSET= is
Abaqus's), the node ids written into the test.
"""
from pathlib import Path

import numpy as np
import pytest

from decks import ccx_frequencies
from mesh.abaqus import read_deck
from mesh.source import MeshImportError
from test_deck_defects import MATERIAL, PLAIN_ROOT, _column, _import, _root_ids


def _exponent(line: str, letter: str) -> str:
    """A *NODE line "id, x, y, z" with its reals in exponent notation, exponent letter
    `letter` ("E", or Fortran's "D"); 12 decimals, as CalculiX reads 20 columns a number."""
    t = [v.strip() for v in line.split(",")]
    return ", ".join([t[0]] + [f"{float(v):.12E}".replace("E", letter) for v in t[1:]])


def test_fortran_exponents_are_read_as_calculix_reads_them(tmp_path):
    nodes, elements = _column()
    head, body = nodes[:3], nodes[3:]
    element_lines = ["*ELEMENT, TYPE=C3D20, ELSET=EALL"] + elements
    plain = tmp_path / "plain.inp"
    plain.write_text("\n".join(head + [_exponent(x, "E") for x in body] + element_lines + PLAIN_ROOT + MATERIAL)
                     + "\n")
    fortran = tmp_path / "fortran.inp"
    root = PLAIN_ROOT[:-1] + ["ROOT, 1, 3, 0.0D0"]  # a zero value with an exponent letter too
    fortran.write_text("\n".join(head + [_exponent(x, "D") for x in body] + element_lines + root + MATERIAL) + "\n")
    assert "D-01" in fortran.read_text()
    np.testing.assert_array_equal(ccx_frequencies(fortran, tmp_path / "ccx_f"),
                                  ccx_frequencies(plain, tmp_path / "ccx_p"))
    a, b = _import(plain), _import(fortran)
    np.testing.assert_array_equal(b.nodes, a.nodes)
    np.testing.assert_array_equal(b.cells, a.cells)
    assert _root_ids(b) == _root_ids(a) == list(range(1, 9))
    assert b.volume == pytest.approx(0.3 * 0.02 * 0.01, rel=1e-13)


def test_unsupported_element_type_is_refused_with_its_line(tmp_path):
    # a 13-node pyramid block, in an included file after two comment lines: the refusal
    # names the type, its count and where its *ELEMENT line is (file and line number)
    nodes, elements = _column()
    (tmp_path / "pyramids.inp").write_text("** pyramids\n**\n*ELEMENT, TYPE=C3D13, ELSET=PYR\n"
                                           + "91, " + ", ".join(map(str, [*range(1, 9), *range(51, 55), 101])) + "\n")
    deck = tmp_path / "blade.inp"
    deck.write_text("\n".join(nodes + ["*ELEMENT, TYPE=C3D20, ELSET=EALL"] + elements
                              + ["*INCLUDE, INPUT=pyramids.inp"] + PLAIN_ROOT) + "\n")
    with pytest.raises(MeshImportError, match=r"unsupported element type 'C3D13' \(1 elements, at pyramids\.inp:3\)"):
        _import(deck)


def test_sets_may_name_skipped_elements(tmp_path):
    # The root face marked by an S8R skin and a truss to a spare node 999 (skipped: not
    # solids; the skin's line ends in "," as some exporters write every line), whose element
    # set an *ELSET aggregates and an *NSET, ELSET= turns into the root (Abaqus reads both;
    # the set is not "unknown"): the root is the skin's nodes, 1-8, as written here.
    nodes, elements = _column()
    deck = tmp_path / "skin.inp"
    deck.write_text("\n".join(nodes + ["999, 0.0, 0.0, 0.0", "*ELEMENT, TYPE=C3D20, ELSET=EALL"] + elements
                              + ["*ELEMENT, TYPE=S8R, ELSET=ROOTSKIN", "900, 1, 2, 3, 4, 5, 6, 7, 8,",
                                 "*ELEMENT, TYPE=T3D2, ELSET=ROOTSKIN", "901, 1, 999",
                                 "*ELSET, ELSET=EVERYTHING", "EALL, ROOTSKIN",
                                 "*NSET, NSET=ROOT, ELSET=ROOTSKIN", "*NSET, NSET=ALLN, ELSET=EVERYTHING",
                                 "*BOUNDARY", "ROOT, ENCASTRE"]) + "\n")
    src = read_deck(deck)
    assert sorted(src.node_ids[src.node_sets["ROOT"]].tolist()) == [*range(1, 9), 999]
    assert src.node_sets["ALLN"].size == 7 * 8 + 6 * 4 + 1  # the column's nodes and 999
    assert src.ignored == {"S8R": 1, "T3D2": 1}
    assert _root_ids(_import(deck)) == list(range(1, 9))  # 999 is no node of the solid


def test_quoted_set_names_are_the_names(tmp_path):
    # Abaqus quotes a name with a space: NSET="Root Face" is the set Root Face, in the
    # keyword, in another set's data line and in *BOUNDARY; `root = "nset:Root Face"` finds it,
    # and both decks clamp the same nodes (1-8, as written here)
    nodes, elements = _column()
    ids = PLAIN_ROOT[1]
    deck = tmp_path / "quoted.inp"
    deck.write_text("\n".join(nodes + ["*ELEMENT, TYPE=C3D20, ELSET=EALL"] + elements
                              + ['*NSET, NSET="Root Face"', ids, '*NSET, NSET="Clamped nodes"', '"Root Face"',
                                 "*BOUNDARY", '"Clamped nodes", 1, 3']) + "\n")
    src = read_deck(deck)
    assert sorted(src.node_ids[src.node_sets["ROOT FACE"]].tolist()) == list(range(1, 9))
    assert _root_ids(_import(deck, root="nset:Root Face")) == list(range(1, 9))
    assert _root_ids(_import(deck, root="boundary")) == list(range(1, 9))
