"""fem.interface.boundary_dofs_of: node-major free-dof indices [x_1, y_1, z_1, x_2, ...] in
the order the boundary nodes are given (InterfaceBasis.boundary_dofs' contract, on which
the ROM's contact directions rest), written out by hand for a small numbering."""
import numpy as np
import pytest

from fem.interface import boundary_dofs_of

# node 0 clamped; free dof numbered node-major in node order (FemSystem.node_dofs)
NODE_DOFS = np.array([[-1, -1, -1], [0, 1, 2], [3, 4, 5], [6, 7, 8]])


def test_node_major_in_the_given_node_order():
    np.testing.assert_array_equal(boundary_dofs_of(NODE_DOFS, np.array([3, 1])), [6, 7, 8, 0, 1, 2])
    np.testing.assert_array_equal(boundary_dofs_of(NODE_DOFS, np.array([1, 2, 3])), np.arange(9))
    np.testing.assert_array_equal(boundary_dofs_of(NODE_DOFS, np.array([2])), [3, 4, 5])


def test_clamped_node_is_refused():
    with pytest.raises(ValueError, match=r"boundary nodes \[0\] lie on the clamped root"):
        boundary_dofs_of(NODE_DOFS, np.array([2, 0]))
