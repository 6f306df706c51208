"""The root clamp must hold the whole structure: a root given as tri3 (corners only) or one
that leaves a rigid-body motion free is refused, not turned into wrong frequencies.

References: the box's root face is the plane x = 0 (geometry, not the code), and a
structure clamped on collinear nodes keeps the rotation about that line (statics)."""
import numpy as np
import pytest

from box_mesh import box_mesh
from fem.assembly import assemble_system
from fem.material import Material
from fem.modes import compute_modes

MAT = Material(E=100e9, nu=0.3, rho=4000.0)


@pytest.fixture(scope="module")
def box():
    return box_mesh(0.05, 0.02, 0.01, 0.008)


def _well_posed_or_refused(box, root):
    """None when assembly refuses the root; else the first frequency (Hz) and residual."""
    try:
        s = assemble_system(box.nodes, box.cells, root, MAT)
    except ValueError as exc:
        return str(exc)
    m = compute_modes(s.K, s.M, 1)
    return s, m


def test_clamped_nodes_are_the_root_plane(box):
    s = assemble_system(box.nodes, box.cells, box.root_facets, MAT)
    on_root = np.abs(box.nodes[:, 0]) < 1e-9  # geometry: the face x = 0
    np.testing.assert_array_equal(s.node_dofs[:, 0] < 0, on_root)


def test_tri3_root_is_refused_not_partly_clamped(box):
    # corners only: the root's mid-edge nodes (x = 0 too) would stay free
    on_root = int((np.abs(box.nodes[:, 0]) < 1e-9).sum())
    out = _well_posed_or_refused(box, box.root_facets[:, :3])
    assert isinstance(out, str) and "tri6" in out, (
        f"accepted: {out[0].n_free} free dof, geometry says {3 * (box.n_nodes - on_root)}")


@pytest.mark.parametrize("which", ["two nodes", "a line of root nodes"])
def test_root_that_leaves_a_rigid_rotation_is_refused(box, which):
    x = box.nodes
    root = np.unique(box.root_facets)
    if which == "two nodes":
        keep = root[:2]
    else:  # every root node on the edge x = 0, z = 0: collinear, the rotation about y stays free
        keep = root[np.abs(x[root, 2]) < 1e-9]
        assert len(keep) >= 3
    out = _well_posed_or_refused(box, np.repeat(keep[:, None], 6, axis=1))
    # a rigid rotation has zero frequency: accepted, the first "mode" is a mechanism
    assert isinstance(out, str) and "rigid body" in out, (
        f"accepted: first frequency {out[1].frequencies_hz[0]:.3g} Hz, residual {out[1].residuals[0]:.3g}")


def test_unclamped_second_piece_is_refused(box):
    # two disjoint boxes, only the first clamped: the second floats freely (CHOLMOD meets
    # exact zero pivots here, so this one was refused before the geometric check as well)
    from fem.cholesky import CholeskyFactor

    nodes = np.vstack([box.nodes, box.nodes + [0.0, 0.1, 0.0]])
    cells = np.vstack([box.cells, box.cells + box.n_nodes])
    with pytest.raises((ValueError, np.linalg.LinAlgError)):
        s = assemble_system(nodes, cells, box.root_facets, MAT)
        CholeskyFactor(s.K).destroy()
