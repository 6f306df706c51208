"""Imported decks: the tip contact nodes are file nodes, LE to TE along the camber line.

The hex20 box (tests/decks.py: L = 0.3 m radially along x, chord b = 0.02 m along the axis z,
here thickness t = 0.004 m along y, 2 elements across the chord and 1 across the thickness) has
its tip face at x = R0 + L. Five contact points evenly spaced along the tip's camber line
(y = 0) fall at z = -b/2, -b/4, 0, b/4, b/2. At z = +-b/4, y = 0 lie the centres of the two
quadrilateral tip faces, where the split puts new nodes (face diagonals' midpoints) that
are no node of the file; the contact nodes must be file nodes (mesh.imported: "n file nodes
of the tip face"), so there the nearest file nodes are taken: the mid-edge nodes at
z = +-b/4, y = +-t/2, 2 mm away (the file's nodes on y = 0 are 5 mm away). By hand, every contact node lies on the tip face, its file id is
known, and the z coordinates do not decrease from LE (z = -b/2) to TE (z = +b/2).
"""
import numpy as np
import pytest

from decks import box, root_nodes, write_deck
from mesh.imported import import_blade
from mesh.options import BladeOptions, MeshOptions


@pytest.fixture(scope="module")
def imported(tmp_path_factory):
    bx = box("hexahedron20", t=0.004)
    deck = tmp_path_factory.mktemp("deck") / "hex.inp"
    ids = write_deck(deck, bx, root=root_nodes(bx))
    m = import_blade(BladeOptions(mesh=deck.name, units="m"), MeshOptions(n_boundary=5), deck)
    return bx, ids, m


def test_contact_nodes_are_file_nodes_on_the_tip_face(imported):
    bx, ids, m = imported
    k = m.boundary_node_index
    assert len(k) == 5
    src = m.source_node_ids[k]
    assert np.all(np.isin(src, ids))  # file nodes, not nodes the split created
    x = m.nodes[k]
    np.testing.assert_allclose(x[:, 0], bx.R0 + bx.L, atol=1e-12)
    # where the file has them: the same coordinates as the file's node of that id
    np.testing.assert_allclose(x, bx.points[np.searchsorted(ids, src)], atol=1e-12)
    assert x[0, 2] == pytest.approx(-bx.b / 2, abs=1e-12) and x[-1, 2] == pytest.approx(bx.b / 2, abs=1e-12)
    assert np.all(np.diff(x[:, 2]) >= -1e-12)
    # the middle point: the file node on the tip's centre line (z = 0, y = 0); the second
    # and fourth: mid-edge nodes at z = -+b/4 on a face of the thickness
    np.testing.assert_allclose(x[2, 1:], 0.0, atol=1e-12)
    np.testing.assert_allclose(x[[1, 3], 2], [-bx.b / 4, bx.b / 4], atol=1e-12)
    np.testing.assert_allclose(np.abs(x[[1, 3], 1]), bx.t / 2, atol=1e-12)
