"""Craig-Bampton ROM on a clamped tet10 box with 9 tip nodes in tilted local frames.

Box 0.12 x 0.04 x 0.006 m (a plate-like "blade"), h = 5 mm: ~6 000 nodes, fast, and the
first 6 modes (bending, torsion, edgewise) resolved well enough that the ROM error is the
reduction's, not noise. References are independent: ARPACK (scipy eigsh) on the full
model and on K_ii, and scipy's sparse LU for the constraint modes.
"""
import dataclasses

import numpy as np
import pytest
import scipy.sparse.linalg as sla

from box_mesh import box_mesh
from fem.analysis import analyse_blade
from fem.material import Material
from fem.options import FemOptions
from rom.craig_bampton import build_craig_bampton
from rom.options import RomOptions


def tilted(mesh):
    """Frames rotated about the span (x) by a different angle at each node: exercises the
    boundary rotation (identity frames would hide a transposed rotation)."""
    a = np.linspace(-0.6, 0.9, len(mesh.boundary_node_index))
    c, s = np.cos(a), np.sin(a)
    f = np.zeros((len(a), 3, 3))
    f[:, 0] = [1.0, 0.0, 0.0]
    f[:, 1] = np.stack([0 * a, c, s], 1)
    f[:, 2] = np.stack([0 * a, -s, c], 1)
    return dataclasses.replace(mesh, boundary_frames=f)


@pytest.fixture(scope="module")
def mesh():
    return tilted(box_mesh(0.12, 0.04, 0.006, 0.005))


@pytest.fixture(scope="module")
def fem(mesh):
    return analyse_blade(mesh, Material(), FemOptions(n_modes=12, n_fixed_interface_modes=12))


@pytest.fixture(scope="module")
def rom(fem, mesh):
    return build_craig_bampton(fem, mesh, RomOptions(), rotation="+")  # a box: its tip nodes span no angle


def test_layout(rom, mesh):
    assert rom.n_dof == 39 and rom.K.shape == rom.M.shape == rom.C.shape == (39, 39)
    assert rom.recovery.shape == (3 * mesh.n_nodes, 39)
    np.testing.assert_array_equal(rom.node_index, mesh.boundary_node_index)
    # a unit local dof k of node j moves that node by e_k (global), nothing else at the boundary
    for j, node in enumerate(mesh.boundary_node_index):
        block = rom.recovery[3 * node:3 * node + 3, 3 * j:3 * j + 3]
        np.testing.assert_allclose(block, mesh.boundary_frames[j].T, atol=1e-6)


def test_out_of_core_factor_gives_the_same_fem_result(fem, mesh, tmp_path, monkeypatch):
    import tempfile

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))  # where solve_system puts the factor's files
    ooc = analyse_blade(mesh, Material(), FemOptions(n_modes=12, n_fixed_interface_modes=12, out_of_core=True))
    assert not any(tmp_path.iterdir())  # removed with the factor
    np.testing.assert_allclose(ooc.frequencies, fem.frequencies, rtol=1e-10)
    np.testing.assert_allclose(ooc.fixed_interface_frequencies, fem.fixed_interface_frequencies, rtol=1e-10)
    np.testing.assert_allclose(ooc.constraint_modes, fem.constraint_modes, rtol=0, atol=1e-10)


def test_full_modes_match_arpack(fem):
    w2, _ = sla.eigsh(fem.K, M=fem.M, k=6, sigma=0.0)
    np.testing.assert_allclose(fem.frequencies[:6], np.sqrt(np.sort(w2)), rtol=1e-9)


def test_rom_frequencies_bound_full_from_above_within_half_percent(rom, fem):
    ratio = rom.frequencies[:6] / fem.frequencies[:6]
    # Ritz bound (the ROM is a Galerkin projection of the same K, M); 1e-8 for the
    # round-off of the projection (see the eta test)
    assert (ratio >= 1 - 1e-8).all(), ratio
    assert (ratio - 1 < 5e-3).all(), ratio


def test_adding_fixed_interface_modes_never_raises_frequencies(fem, mesh):
    prev = None
    for eta in range(0, 13):
        w = build_craig_bampton(fem, mesh, RomOptions(n_fixed_modes=eta), store_recovery=False,
                                rotation="+").frequencies[:6]
        if prev is not None:  # nested bases: each ROM space contains the previous one
            # 1e-8: round-off of the projection T^T K T (its entries cancel down to the 1B
            # stiffness), measured ~1e-10 relative; a real violation would be >> 1e-6
            assert (w <= prev * (1 + 1e-8)).all(), (eta, w / prev)
        prev = w


def test_matrices_symmetric_spd(rom):
    for A in (rom.K, rom.M, rom.C):
        np.testing.assert_allclose(A, A.T, rtol=0, atol=1e-12 * abs(A).max())
    assert np.linalg.eigvalsh(rom.M).min() > 0
    assert np.linalg.eigvalsh(rom.K).min() > 0  # root clamped: no rigid-body mode


def test_modal_damping_ratios(rom):
    import scipy.linalg

    w2, phi = scipy.linalg.eigh(rom.K, rom.M)
    c = np.diag(phi.T @ rom.C @ phi) / (2 * np.sqrt(w2))
    expected = np.where(np.arange(39) < 3, 1e-3, 5e-3)
    np.testing.assert_allclose(c, expected, rtol=1e-6)
    np.testing.assert_array_equal(rom.damping_ratios, expected)


def test_interface_basis_against_direct_solves(fem):
    bd = fem.boundary_dofs
    n = fem.K.shape[0]
    interior = np.setdiff1d(np.arange(n), bd)
    Kii = fem.K[interior][:, interior].tocsc()
    Kib = fem.K[interior][:, bd]
    psi = -sla.splu(Kii).solve(Kib.toarray())
    np.testing.assert_allclose(fem.constraint_modes[interior], psi, atol=1e-9 * abs(psi).max())
    Mii = fem.M[interior][:, interior]
    w2, _ = sla.eigsh(Kii, M=Mii, k=6, sigma=0.0)
    np.testing.assert_allclose(fem.fixed_interface_frequencies[:6], np.sqrt(np.sort(w2)), rtol=1e-9)


def test_boundary_node_on_root_raises(fem, mesh):
    bad = mesh.boundary_node_index.copy()
    bad[0] = mesh.root_facets[0, 0]
    with pytest.raises(ValueError, match="clamped root"):
        build_craig_bampton(fem, dataclasses.replace(mesh, boundary_node_index=bad), RomOptions(), rotation="+")


def test_friction_lock_compliance_is_the_full_models(rom, fem, mesh):
    # The friction-lock table's static compliance G at the contact nodes (local r, theta, z)
    # against direct sparse solves of the full model: K u = unit local force at node j,
    # read in node i's frame. Craig-Bampton's constraint modes make the static condensation
    # exact, so the two agree to the solves' round-off (1e-8 of the largest entry).
    F = mesh.boundary_frames
    nb = len(mesh.boundary_node_index)
    lu = sla.splu(fem.K.tocsc())
    dofs = fem.node_dofs[mesh.boundary_node_index]  # (n_b, 3) free dof of each node (x, y, z)
    rhs = np.zeros((fem.K.shape[0], 3 * nb))
    for j in range(nb):
        for k in range(3):
            rhs[dofs[j], 3 * j + k] = F[j, k]  # unit force along e_k of node j, global components
    u = lu.solve(rhs)
    G = np.einsum("ilx,ixc->ilc", F, u[dofs]).reshape(3 * nb, 3 * nb)
    lock = rom.friction_lock
    scale = abs(G).max()
    np.testing.assert_allclose(lock.compliance_rr, G[0::3, 0::3], rtol=0, atol=1e-8 * scale)
    np.testing.assert_allclose(lock.compliance_rtheta, G[0::3, 1::3], rtol=0, atol=1e-8 * scale)
