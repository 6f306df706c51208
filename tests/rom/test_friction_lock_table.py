"""Friction-lock table, sense of rotation and RomModel symmetry check: cases the other rom
tests leave open, each against a hand computation or a dense reference written here.

- the ROM's lock table is taken with the ROM's own sense of rotation (a dense truss, G from
  the inverse Schur complement rotated into the local frames, mu_j by hand for s = +1, -1);
- a complex pair of eigenvalues of B^-1 C with negative real part is no vanishing minor
  (2 x 2 determinant by hand: never zero);
- decoupled nodes: the pair's minor vanishes with the single node's, the table names the
  single node (the smallest set);
- at mu = mu_set exactly a minor is zero: A is not a P-matrix, the warning is given;
- 12 contact nodes are tested exactly (every subset), 13 are not;
- the report's "s G_rt" column carries the sense;
- contact nodes on one ray from the axis (atan2 round-off between them) span no angle;
- an asymmetry of 1e-14 max|K| on an entry that is ~0 is round-off, accepted as the
  condensation accepts it;
- one scalar damping ratio for every mode (a diagonal 2-dof pencil, C by hand).
"""
import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest
import scipy.sparse as sp

from rom.craig_bampton import build_craig_bampton
from rom.friction_lock import lock_table
from rom.options import RomOptions
from rom.rotation import rotation_sign
from support import coarse_rom
from test_craig_bampton_reference import _truss


def _model(tilts=(-1.0, 1.0, -1.0)):
    """The truss with 3 contact nodes (cylindrical frames about an axis 0.2 m away, tilted
    about e_r by `tilts`), as fem and mesh namespaces, and the dense boundary compliance G."""
    x, K, M, node_dofs = _truss(nx=4, seed=3)
    b = np.flatnonzero((x[:, 0] == x[:, 0].max()) & (x[:, 2] == 0.0))  # 3 tip nodes along y
    xy = x[b, :2] + [0.2, 0.0]
    phi = np.arctan2(xy[:, 1], xy[:, 0])
    o = np.zeros_like(phi)
    frames = np.stack([np.column_stack([np.cos(phi), np.sin(phi), o]),
                       np.column_stack([-np.sin(phi), np.cos(phi), o]),
                       np.column_stack([o, o, o + 1.0])], axis=1)
    for j, a in enumerate(tilts):  # tilt e_theta, e_z about e_r
        c, s = np.cos(a), np.sin(a)
        frames[j] = np.array([[1.0, 0, 0], [0, c, s], [0, -s, c]]) @ frames[j]
    mesh = SimpleNamespace(boundary_node_index=b, boundary_frames=frames, boundary_xyz=x[b],
                           boundary_rho=np.hypot(xy[:, 0], xy[:, 1]), boundary_theta=phi - phi[0])
    n = K.shape[0]
    fem = SimpleNamespace(K=sp.csr_matrix(K), M=sp.csr_matrix(M), node_dofs=node_dofs,
                          frequencies=np.ones(3), boundary_dofs=np.zeros(0, np.int64),
                          constraint_modes=np.zeros((n, 0)), fixed_interface_modes=np.zeros((n, 0)),
                          fixed_interface_frequencies=np.zeros(0))
    # dense reference: the boundary compliance, inverse Schur complement, in the local frames
    bd = node_dofs[b].ravel()
    ii = np.setdiff1d(np.arange(n), bd)
    S = K[np.ix_(bd, bd)] - K[np.ix_(bd, ii)] @ np.linalg.solve(K[np.ix_(ii, ii)], K[np.ix_(ii, bd)])
    rot = np.zeros((3 * len(b), 3 * len(b)))
    for j, f in enumerate(frames):
        rot[3 * j:3 * j + 3, 3 * j:3 * j + 3] = f.T  # local -> global
    G = rot.T @ np.linalg.inv(S) @ rot
    return SimpleNamespace(mesh=mesh, fem=fem, G=G)


@pytest.fixture(scope="module")
def truss():
    return _model()


@pytest.mark.parametrize("rotation, s", [("+", 1), ("-", -1), (1, 1), (-1, -1)])
def test_the_roms_lock_table_is_taken_with_the_roms_sense(truss, rotation, s):
    rom = build_craig_bampton(truss.fem, truss.mesh, RomOptions(n_fixed_modes=4), store_recovery=False,
                              rotation=rotation)
    assert rom.rotation == s
    assert rom.friction_lock.rotation == s
    grr, grt = np.diag(truss.G[0::3, 0::3]), np.diag(truss.G[0::3, 1::3])
    # by hand: node j is dragged in above mu_j = -G_rr,jj / (s G_rt,jj) when s G_rt,jj < 0
    want = np.array([-r / (s * t) if s * t < 0 else np.inf for r, t in zip(grr, grt)])
    assert np.isfinite(want).any() and not np.isfinite(want).all()  # the sense decides which nodes lock
    np.testing.assert_allclose(rom.friction_lock.mu_node, want, rtol=1e-8)


def test_a_complex_pair_with_negative_real_part_is_no_vanishing_minor():
    # B = [[2, 1], [1, 1]], C = [[0, 1.5], [-0.5, 0]] (s = +1): the single minors are 2 and 1
    # for every mu, the pair's det(B + mu C) = 2 - (1 + 1.5 mu)(1 - 0.5 mu) = 1 - mu + 0.75 mu^2
    # > 0 for every real mu (discriminant 1 - 3 < 0): A(mu) is a P-matrix for all mu.
    # B^-1 C has the eigenvalues -0.5 +- 0.707 i: their real part alone would say mu = 2.
    B, C = 1e-8 * np.array([[2.0, 1.0], [1.0, 1.0]]), 1e-8 * np.array([[0.0, 1.5], [-0.5, 0.0]])
    mus = np.linspace(0.0, 50.0, 5001)
    assert (1 - mus + 0.75 * mus ** 2).min() > 0.6  # by hand, min 2/3 at mu = 2/3
    lock = lock_table(B, C, 1)
    assert lock.mu_set == np.inf
    np.testing.assert_array_equal(lock.mu_node, [np.inf, np.inf])
    np.testing.assert_array_equal(lock.set_nodes, [0, 0])
    assert lock.warnings(10.0) == []


def test_decoupled_nodes_name_the_single_node_that_locks():
    # G_rr = diag(4, 3), G_rt = diag(-8, 1) (s = +1): no coupling between the nodes; node 0
    # locks at mu = 4 / 8 = 0.5, node 1 never. The pair's minor (4 - 8 mu)(3 + mu) vanishes
    # at the same 0.5: the set that locks first is node 0 alone.
    lock = lock_table(1e-8 * np.diag([4.0, 3.0]), 1e-8 * np.diag([-8.0, 1.0]), 1)
    assert lock.mu_set == pytest.approx(0.5, rel=1e-14)
    np.testing.assert_allclose(lock.mu_node, [0.5, np.inf])
    np.testing.assert_array_equal(lock.set_nodes, [1, 0])
    assert lock.report(0.1)[-1].endswith("(nodes 0)")


def test_at_mu_set_exactly_the_set_is_past_its_p_matrix_bound():
    # G_rr = [[1, 0.5], [0.5, 1]], G_rt = [[0, 1], [1, 0]] (s = +1): the single minors stay 1,
    # det = 1 - (0.5 + mu)^2 vanishes at mu = 0.5. There A has a zero minor: not a P-matrix.
    lock = lock_table(1e-8 * np.array([[1.0, 0.5], [0.5, 1.0]]), 1e-8 * np.array([[0.0, 1.0], [1.0, 0.0]]), 1)
    assert lock.mu_set == pytest.approx(0.5, rel=1e-14)
    assert lock.warnings(0.49) == []
    for mu in (lock.mu_set, 0.51):
        (w,) = lock.warnings(mu)
        assert "is not a P-matrix" in w


@pytest.mark.parametrize("nb, exact", [(12, True), (13, False)])
def test_twelve_nodes_are_tested_exactly_thirteen_are_not(nb, exact):
    # decoupled nodes, node j locks at mu_j = (j + 1) / 10: mu_set = 0.1 whatever subsets are tested
    lock = lock_table(1e-8 * np.eye(nb), -1e-8 * np.diag(10.0 / np.arange(1.0, nb + 1)), 1)
    assert lock.mu_set == pytest.approx(0.1, rel=1e-12)
    assert lock.exact is exact
    assert ("an upper bound" in lock.report(0.0)[-1]) is (not exact)


@pytest.mark.parametrize("s", [1, -1])
def test_the_report_column_s_g_rt_carries_the_sense(s):
    # one node, G_rr = 5e-8, G_rt = 2e-8: s G_rt = +-2e-8, A(0.5) = 5e-8 +- 1e-8
    lock = lock_table(np.array([[5e-8]]), np.array([[2e-8]]), s)
    row = lock.report(0.5)[2].split()
    assert float(row[1]) == pytest.approx(5e-8, rel=1e-4)
    assert float(row[2]) == pytest.approx(s * 2e-8, rel=1e-4)
    assert float(row[3]) == pytest.approx(5e-8 + s * 1e-8, rel=1e-4)


def test_nodes_on_one_ray_span_no_angle():
    # two points on one ray from the axis (the second 1.56 times further out): the same angle,
    # but atan2 rounds them 1 ulp apart (1.1e-16 rad): that is no span, the sense cannot be derived
    x, y, k = 0.6732655185893088, 0.3428080423874833, 1.561460285904292
    theta = np.arctan2([y, k * y], [x, k * x])
    assert 0.0 < abs(theta[1] - theta[0]) < 1e-15
    with pytest.raises(ValueError, match="span an angle"):
        rotation_sign("le-leads", theta)


def test_round_off_asymmetry_of_a_near_zero_entry_is_accepted_by_rom_and_condensation():
    from hbm.harmonic.condensation import CondensedModel
    from hbm.harmonic.fourier import FourierBasis

    rom = coarse_rom()
    K = np.array(rom.K)
    scale = np.abs(K).max()
    off = np.abs(K) + np.eye(len(K)) * scale  # the smallest off-diagonal entry
    i, j = np.unravel_index(off.argmin(), K.shape)
    assert abs(K[i, j]) < 1e-6 * scale
    K[i, j] += 1e-14 * scale  # round-off of a symmetric assembly: 1e-14 of max|K|
    accepted = dataclasses.replace(rom, K=K)
    assert accepted.n_dof == 39
    CondensedModel(K, rom.M, rom.C, rom.nonlinear_dofs, FourierBasis(2, 16)).operator(1000.0)  # accepted too
    K[i, j] += 1e-9 * scale  # well above round-off
    with pytest.raises(ValueError, match="K is not symmetric"):
        dataclasses.replace(rom, K=K)


def test_one_damping_ratio_for_every_mode():
    # K = diag(4e6, 9e6) N/m, M = diag(1, 4) kg: w = 2000 and 1500 rad/s, modes along the axes;
    # C = diag(2 xi w_k m_k) = diag(2 xi sqrt(k m)) by hand for xi = 0.03: 120 and 360 N s/m
    from rom.model import modal_damping

    C, w = modal_damping(np.diag([4e6, 9e6]), np.diag([1.0, 4.0]), 0.03)
    np.testing.assert_allclose(w, [1500.0, 2000.0], rtol=1e-13)
    np.testing.assert_allclose(C, np.diag([120.0, 360.0]), rtol=1e-12, atol=1e-9)
