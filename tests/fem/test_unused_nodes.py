"""A node that no cell uses would have three dof with zero rows in K and M (dolfinx's mesh
drops it, so it would get no dof at all): assembly refuses the mesh, naming the count."""
import numpy as np
import pytest

from box_mesh import box_mesh
from fem.assembly import assemble_distributed, assemble_system
from fem.material import Material


@pytest.fixture(scope="module")
def box():
    return box_mesh(0.05, 0.01, 0.01, 0.005, n_boundary=3)


@pytest.mark.parametrize("where", ["last", "first"])
def test_nodes_no_cell_uses_are_refused(box, where):
    stray = np.array([[1.0, 1.0, 1.0], [2.0, 0.0, 0.0]])
    if where == "last":
        nodes, cells, root = np.vstack([box.nodes, stray]), box.cells, box.root_facets
    else:  # numbered before the mesh's own nodes
        nodes, cells, root = np.vstack([stray, box.nodes]), box.cells + 2, box.root_facets + 2
    with pytest.raises(ValueError, match="2 nodes belong to no cell"):
        assemble_system(nodes, cells, root, Material())
    from mpi4py import MPI

    with pytest.raises(ValueError, match="2 nodes belong to no cell"):
        assemble_distributed(nodes, cells, root, Material(), MPI.COMM_SELF)
