"""Node order of a mesh (mesh.ordering): reverse Cuthill-McKee narrows the band of K and M,
changes no cell, node set or contact node, and leaves the FEM results as they were."""
import dataclasses

import numpy as np
import pytest
import scipy.sparse as sp

from box_mesh import box_mesh
from fem.assembly import assemble_system
from fem.material import Material
from fem.modes import compute_modes
from mesh.ordering import bandwidth, renumber_nodes


@pytest.fixture(scope="module")
def meshed():
    # gmsh's order: the vertices first, the mid-edge nodes of the second order after them
    box = box_mesh(0.1, 0.03, 0.01, 0.004)
    ids = 1000 + 7 * np.arange(box.n_nodes)  # stand-in for an imported file's node ids
    return dataclasses.replace(box, source_node_ids=ids)


@pytest.fixture(scope="module")
def rcm(meshed):
    return renumber_nodes(meshed)


def _dof_bandwidth(A: sp.csr_matrix) -> int:
    C = A.tocoo()
    return int(np.abs(C.row - C.col).max())


def test_the_band_narrows(meshed, rcm):
    n = meshed.n_nodes
    assert bandwidth(meshed.cells) > 0.5 * n  # a cell's mid-edge nodes lie past all vertices
    # RCM's band is about one level set, a cross-section of the box: 0.15 of n here, and a
    # smaller share the longer the part (~1 % on the default rotor 67 blade)
    assert bandwidth(rcm.cells) < 0.2 * bandwidth(meshed.cells)
    K0 = assemble_system(meshed.nodes, meshed.cells, meshed.root_facets, Material()).K
    K1 = assemble_system(rcm.nodes, rcm.cells, rcm.root_facets, Material()).K
    assert _dof_bandwidth(K1) < 0.2 * _dof_bandwidth(K0)


def test_every_cell_facet_and_contact_node_is_kept(meshed, rcm):
    assert sorted(np.asarray(rcm.nodes).tolist()) == sorted(np.asarray(meshed.nodes).tolist())
    assert not np.array_equal(rcm.cells, meshed.cells)
    # the same cells in the same order with the same local node order, by coordinates
    np.testing.assert_array_equal(rcm.nodes[rcm.cells], meshed.nodes[meshed.cells])
    for name in ("root_facets", "tip_facets", "boundary_node_index"):
        np.testing.assert_array_equal(rcm.nodes[getattr(rcm, name)], meshed.nodes[getattr(meshed, name)])
    # the source ids travel with their nodes
    np.testing.assert_array_equal(rcm.source_node_ids[rcm.cells], meshed.source_node_ids[meshed.cells])
    for name in ("boundary_xyz", "boundary_frames", "volume"):
        np.testing.assert_array_equal(getattr(rcm, name), getattr(meshed, name))


def test_the_fem_results_do_not_depend_on_it(meshed, rcm):
    # the stiffness and mass of each node pair, wherever the pair is numbered, and the modes
    s0, s1 = (assemble_system(m.nodes, m.cells, m.root_facets, Material()) for m in (meshed, rcm))
    order = np.empty(meshed.n_nodes, dtype=np.int64)  # rcm node of each meshed node, by coordinates
    key0 = np.lexsort(meshed.nodes.T)
    key1 = np.lexsort(rcm.nodes.T)
    order[key0] = key1
    d0 = s0.node_dofs[s0.node_dofs[:, 0] >= 0].ravel()
    d1 = s1.node_dofs[order[s0.node_dofs[:, 0] >= 0]].ravel()
    p = np.empty_like(d0)
    p[d0] = d1  # free dof of the renumbered system for each free dof of the meshed one
    for A0, A1 in ((s0.K, s1.K), (s0.M, s1.M)):
        assert abs(A1[p][:, p] - A0).max() <= 1e-12 * abs(A0).max()
    w0, w1 = (compute_modes(s.K, s.M, 6).frequencies for s in (s0, s1))
    np.testing.assert_allclose(w1, w0, rtol=1e-10)


def test_an_unknown_order_is_named(meshed):
    assert renumber_nodes(meshed, "meshed") is meshed
    with pytest.raises(ValueError, match="node order must be one of"):
        renumber_nodes(meshed, "metis")
