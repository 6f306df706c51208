"""mesh.blade.nearest_nodes on inputs it cannot snap: a ValueError that names what is wrong."""
import numpy as np
import pytest

from mesh.blade import nearest_nodes

NODES = np.random.default_rng(0).random((10, 3))


def test_an_empty_candidate_set_is_named():
    # unchecked: numpy's "attempt to get argmin of an empty sequence"
    with pytest.raises(ValueError, match=r"no candidate nodes to snap the 2 target points to \(empty candidate set\)"):
        nearest_nodes(NODES, np.array([], dtype=np.int64), NODES[:2])


def test_targets_must_be_points():
    # unchecked: numpy's IndexError "too many indices for array"
    with pytest.raises(ValueError, match=r"targets must be \(n, 3\) points, m, got shape \(3,\)"):
        nearest_nodes(NODES, np.arange(10), NODES[0])


def test_each_target_gets_its_nearest_candidate():
    cand = np.array([1, 4, 7])
    targets = NODES[[4, 1, 7]] + 1e-6
    d = np.linalg.norm(NODES[cand][None] - targets[:, None], axis=2)
    np.testing.assert_array_equal(nearest_nodes(NODES, cand, targets), cand[np.argmin(d, axis=1)])
    assert nearest_nodes(NODES, cand, np.zeros((0, 3))).shape == (0,)
