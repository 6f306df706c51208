"""build_craig_bampton on inputs it must refuse, naming the option or field, before they fail
deep in numpy or give a ROM of the wrong dof; and on mode counts up to the true limit.

The full model is the clamped 3-D truss of test_craig_bampton_reference (90 free dof, 3 tip
contact nodes: 81 interior dof), small enough for dense references.
"""
import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest
import scipy.linalg as sl
import scipy.sparse as sp

from rom.craig_bampton import build_craig_bampton
from rom.friction_lock import friction_lock
from rom.options import RomOptions
from test_craig_bampton_reference import _truss, bare_fem


@pytest.fixture(scope="module")
def model():
    x, K, M, node_dofs = _truss()
    b = np.flatnonzero((x[:, 0] == x[:, 0].max()) & (x[:, 2] == 0.0))
    mesh = SimpleNamespace(boundary_node_index=b, boundary_frames=np.tile(np.eye(3), (len(b), 1, 1)),
                           boundary_xyz=x[b], boundary_rho=0.2 + x[b, 0], boundary_theta=np.zeros(len(b)))
    n = K.shape[0]
    fem = bare_fem(K, M, node_dofs)
    bd = node_dofs[b].ravel()
    ii = np.setdiff1d(np.arange(n), bd)
    w_fi = np.sqrt(sl.eigh(K[np.ix_(ii, ii)], M[np.ix_(ii, ii)], eigvals_only=True))
    return SimpleNamespace(K=K, M=M, mesh=mesh, fem=fem, bd=bd, n_interior=len(ii), w_fi=w_fi)


def _fem(model, **changes):
    return SimpleNamespace(**{**vars(model.fem), **changes})


@pytest.mark.parametrize("eta", [0, 40, 60, 81])
def test_fixed_interface_modes_up_to_the_interior_dof_count(model, eta):
    # the block eigen-solver took round-off into its basis once the Krylov space filled the
    # 81 interior dof and failed with numpy's LinAlgError from eta = 40 on (eta = 20 too)
    assert model.n_interior == 81
    rom = build_craig_bampton(model.fem, model.mesh, RomOptions(n_fixed_modes=eta), rotation="+")
    assert rom.n_dof == 9 + eta
    np.testing.assert_allclose(rom.fixed_interface_frequencies, model.w_fi[:eta], rtol=1e-10)
    if eta == 81:  # T spans every free dof: the ROM is the full model
        np.testing.assert_allclose(rom.frequencies, np.sqrt(sl.eigh(model.K, model.M, eigvals_only=True)),
                                   rtol=1e-8)


def test_more_fixed_interface_modes_than_interior_dof_are_refused_before_any_factorisation(model, monkeypatch):
    import fem.cholesky

    def no_factor(*args, **kwargs):
        raise AssertionError("K was factorised before the mode count was checked")

    monkeypatch.setattr(fem.cholesky, "CholeskyFactor", no_factor)
    with pytest.raises(ValueError, match=r"\[rom\] n_fixed_modes = 82\b.*allowed 0\.\.81, the interior dof count "
                                         r"\(90 free dof less 9 boundary dof\)"):
        build_craig_bampton(model.fem, model.mesh, RomOptions(n_fixed_modes=82), rotation="+")


def _shifted(node_dofs, by):
    out = node_dofs.copy()
    out[out >= 0] += by
    return out


def _reversed_nodes(node_dofs):
    out = node_dofs.copy()
    free = out >= 0
    out[free] = out[free].reshape(-1, 3)[::-1].ravel()
    return out


@pytest.mark.parametrize("store_recovery", [True, False])
@pytest.mark.parametrize("field, make, message", [
    # without the check: numpy's "dimension mismatch" in the eigen-solve
    ("M", lambda m: sp.csr_matrix(m.M[:-3, :-3]), r"K and M must be square and of one size, got K \(90, 90\), "
                                                  r"M \(87, 87\)"),
    # without the check: a ROM of other dof of K (K[0, 0] 4.03e8 instead of 1.40e8), silently
    ("node_dofs", lambda m: _shifted(m.fem.node_dofs, 3), r"node_dofs does not number K's 90 free dof 0\.\.89"),
    ("node_dofs", lambda m: _reversed_nodes(m.fem.node_dofs), r"node_dofs does not number K's 90 free dof"),
    # without the check: numpy's broadcast error in the recovery, or (not stored) a ROM silently
    ("node_dofs", lambda m: np.where(np.arange(len(m.fem.node_dofs))[:, None] == len(m.fem.node_dofs) - 1, -1,
                                     m.fem.node_dofs), r"it holds 87 free dof"),
    ("node_dofs", lambda m: m.fem.node_dofs.ravel(), r"node_dofs must be an \(n_nodes, 3\) integer array"),
])
def test_a_fem_result_whose_matrices_and_numbering_disagree_is_refused(model, field, make, message, store_recovery):
    with pytest.raises(ValueError, match=message):
        build_craig_bampton(_fem(model, **{field: make(model)}), model.mesh, RomOptions(n_fixed_modes=4),
                            rotation="+", store_recovery=store_recovery)


@pytest.mark.parametrize("changes, message", [
    (lambda m: dict(constraint_modes=np.zeros((89, 9))), r"constraint_modes must have shape \(90, 9\)"),
    (lambda m: dict(constraint_modes=np.zeros((90, 6))), r"constraint_modes must have shape \(90, 9\)"),
    (lambda m: dict(fixed_interface_frequencies=m.w_fi[:3]), r"fixed_interface_modes must have shape \(90, 3\)"),
])
def test_a_given_interface_basis_of_the_wrong_shape_is_refused(model, changes, message):
    given = dict(boundary_dofs=model.bd, constraint_modes=np.zeros((90, 9)),
                 fixed_interface_modes=np.zeros((90, 8)), fixed_interface_frequencies=model.w_fi[:8])
    given.update(changes(model))
    with pytest.raises(ValueError, match=message):
        build_craig_bampton(_fem(model, **given), model.mesh, RomOptions(n_fixed_modes=4), rotation="+")


def test_duplicated_boundary_nodes_are_named(model):
    b = model.mesh.boundary_node_index
    mesh = SimpleNamespace(**{**vars(model.mesh), "boundary_node_index": np.array([b[0], b[1], b[1]])})
    with pytest.raises(ValueError, match=rf"nodes \[{b[1]}\] appear more than once"):
        build_craig_bampton(model.fem, mesh, RomOptions(n_fixed_modes=4), rotation="+")


@pytest.mark.parametrize("n_boundary", [0, 5, 2.5, True])
def test_friction_lock_refuses_a_contact_node_count_k_cannot_hold(n_boundary):
    # unchecked, 2.5 was taken as 2 nodes, 0 gave an empty table, 5 numpy's broadcast error
    K = np.diag(np.arange(1.0, 14.0))
    with pytest.raises(ValueError, match=r"n_boundary must be an integer count of contact nodes in 1\.\.n / 3 = 4.*"
                                         + f"got {n_boundary!r}"):
        friction_lock(K, n_boundary, 1)


@pytest.mark.parametrize("value", ["1e-3", None, [0.01]])
def test_damping_ratios_must_be_numbers(value):
    # unchecked, a string or None failed with TypeError: '<=' not supported
    for key in ("damping_low", "damping_high"):
        with pytest.raises(ValueError, match=rf"{key} must be a damping ratio, a number in \[0, 1\), got "):
            dataclasses.replace(RomOptions(), **{key: value})
