"""Craig-Bampton ROM, friction-lock table and sense of rotation against references computed
here, independently of the code under test.

The full model is a clamped 3-D truss (6 x 3 x 2 nodes, bars up to the face diagonals,
random bar stiffnesses, consistent bar masses): 90 free dof, small enough for dense numpy
to do the whole reduction by the textbook (constraint modes -K_ii^-1 K_ib, fixed-interface
modes of (K_ii, M_ii), T, T^T K T, T^T M T) and the full eigen-solve. Nodes are numbered
x fastest, so the clamped root nodes (x = 0) are interleaved with the free ones. The three
contact nodes carry cylindrical frames about a z axis 0.2 m away, tilted about e_r by a
different angle each (identity frames would hide a transposed rotation).
"""
import itertools
from types import SimpleNamespace

import numpy as np
import pytest
import scipy.linalg as sl
import scipy.sparse as sp
import scipy.sparse.linalg as sla

from rom.craig_bampton import build_craig_bampton
from rom.friction_lock import _first_singular_mu, friction_lock
from rom.options import RomOptions
from rom.rotation import rotation_sign


def _truss(nx=6, ny=3, nz=2, h=0.01, ea=1e6, rho_l=0.05, seed=0):
    """Nodes (n, 3) m, clamped K (N/m) and M (kg) on the free dof, node_dofs (n, 3)."""
    rng = np.random.default_rng(seed)
    x = h * np.array([(i, j, k) for k in range(nz) for j in range(ny) for i in range(nx)], dtype=float)
    n = len(x)
    K, M = np.zeros((3 * n, 3 * n)), np.zeros((3 * n, 3 * n))
    for a, b in itertools.combinations(range(n), 2):
        d = x[b] - x[a]
        length = np.linalg.norm(d)
        if length > 1.8 * h:
            continue
        e = d / length
        ke = ea / length * (1.0 + 0.5 * rng.random()) * np.outer(e, e)
        me = rho_l * length / 6.0 * np.eye(3)  # consistent bar mass: m/6 [[2, 1], [1, 2]]
        ia, ib = slice(3 * a, 3 * a + 3), slice(3 * b, 3 * b + 3)
        K[ia, ia] += ke
        K[ib, ib] += ke
        K[ia, ib] -= ke
        K[ib, ia] -= ke
        M[ia, ia] += 2 * me
        M[ib, ib] += 2 * me
        M[ia, ib] += me
        M[ib, ia] += me
    clamped = x[:, 0] == 0.0
    node_dofs = np.full((n, 3), -1, dtype=np.int64)
    node_dofs[~clamped] = np.arange(3 * int((~clamped).sum())).reshape(-1, 3)  # node-major
    keep = np.repeat(~clamped, 3)
    return x, K[np.ix_(keep, keep)], M[np.ix_(keep, keep)], node_dofs


def bare_fem(K, M, node_dofs) -> SimpleNamespace:
    """A FEM result of the dense truss without an interface basis (build_craig_bampton
    computes its own): K, M as CSR, its first 8 frequencies, rad/s."""
    n = K.shape[0]
    return SimpleNamespace(K=sp.csr_matrix(K), M=sp.csr_matrix(M), node_dofs=node_dofs,
                           frequencies=np.sqrt(sl.eigh(K, M, eigvals_only=True)[:8]),
                           boundary_dofs=np.zeros(0, np.int64), constraint_modes=np.zeros((n, 0)),
                           fixed_interface_modes=np.zeros((n, 0)), fixed_interface_frequencies=np.zeros(0))


@pytest.fixture(scope="module")
def model():
    x, K, M, node_dofs = _truss()
    b = np.flatnonzero((x[:, 0] == x[:, 0].max()) & (x[:, 2] == 0.0))  # 3 tip nodes along y
    xy = x[b, :2] + [0.2, 0.0]
    phi = np.arctan2(xy[:, 1], xy[:, 0])
    o = np.zeros_like(phi)
    frames = np.stack([np.column_stack([np.cos(phi), np.sin(phi), o]),
                       np.column_stack([-np.sin(phi), np.cos(phi), o]),
                       np.column_stack([o, o, o + 1.0])], axis=1)
    for j, a in enumerate(np.linspace(-0.5, 0.8, len(b))):
        c, s = np.cos(a), np.sin(a)
        frames[j] = np.array([[1.0, 0, 0], [0, c, s], [0, -s, c]]) @ frames[j]
    mesh = SimpleNamespace(boundary_node_index=b, boundary_frames=frames, boundary_xyz=x[b],
                           boundary_rho=np.hypot(xy[:, 0], xy[:, 1]), boundary_theta=phi - phi[0])
    n = K.shape[0]
    fem = bare_fem(K, M, node_dofs)
    # the textbook reduction, dense
    bd = node_dofs[b].ravel()
    ii = np.setdiff1d(np.arange(n), bd)
    psi = np.zeros((n, len(bd)))
    psi[bd] = np.eye(len(bd))
    psi[ii] = -np.linalg.solve(K[np.ix_(ii, ii)], K[np.ix_(ii, bd)])
    w2, v = sl.eigh(K[np.ix_(ii, ii)], M[np.ix_(ii, ii)])
    phi_fi = np.zeros((n, len(ii)))
    phi_fi[ii] = v
    rot = sl.block_diag(*[f.T for f in frames])  # local (r, theta, z) -> global (x, y, z), per node
    return SimpleNamespace(x=x, K=K, M=M, node_dofs=node_dofs, mesh=mesh, fem=fem, bd=bd, ii=ii, psi=psi,
                           phi=phi_fi, w_fi=np.sqrt(w2), rot=rot, nb=len(b))


def _reference(model, eta):
    T = np.hstack([model.psi @ model.rot, model.phi[:, :eta]])
    return T, T.T @ model.K @ T, T.T @ model.M @ T


ETA = 8


@pytest.fixture(scope="module")
def rom(model):
    return build_craig_bampton(model.fem, model.mesh, RomOptions(n_fixed_modes=ETA), rotation="+")


def _aligned(model, rom, T):
    """The reference T with each fixed-interface mode's sign flipped to match the ROM's
    (an eigenvector's sign is arbitrary), and those signs (n,)."""
    free = model.node_dofs.ravel() >= 0
    d = np.sign(np.einsum("ij,ij->j", rom.recovery[free].astype(float), T))
    return T * d, d


def test_rom_matrices_are_the_dense_craig_bampton_reduction(model, rom):
    T, Kr, Mr = _reference(model, ETA)
    _, d = _aligned(model, rom, T)
    Kr, Mr = d[:, None] * Kr * d, d[:, None] * Mr * d
    # K to 1e-10: its modal block is diag(w^2), converged to the eigen-solve's tolerance (1e-10,
    # measured 3e-12); M to 1e-7: its boundary-modal coupling is linear in the modes' vectors,
    # whose error is the eigenvalue tolerance over the gap (5e-9 measured, the 8th mode 3 % from the 9th)
    np.testing.assert_allclose(rom.K, Kr, rtol=0, atol=1e-10 * abs(Kr).max())
    np.testing.assert_allclose(rom.M, Mr, rtol=0, atol=1e-7 * abs(Mr).max())
    np.testing.assert_allclose(rom.fixed_interface_frequencies, model.w_fi[:ETA], rtol=1e-10)


def test_given_basis_is_projected_to_round_off(model):
    # with the dense basis handed over in the FEM result, only the rotation and the projection remain
    fem = SimpleNamespace(**vars(model.fem))
    fem.boundary_dofs, fem.constraint_modes = model.bd, model.psi
    fem.fixed_interface_modes, fem.fixed_interface_frequencies = model.phi[:, :ETA], model.w_fi[:ETA]
    rom = build_craig_bampton(fem, model.mesh, RomOptions(n_fixed_modes=ETA), rotation="+")
    _, Kr, Mr = _reference(model, ETA)
    np.testing.assert_allclose(rom.K, Kr, rtol=0, atol=1e-13 * abs(Kr).max())
    np.testing.assert_allclose(rom.M, Mr, rtol=0, atol=1e-13 * abs(Mr).max())


def test_boundary_stiffness_is_the_schur_complement_in_local_frames(model, rom):
    # K_bb - K_bi K_ii^-1 K_ib (global x, y, z) turned into each node's (r, theta, z): R^T S R
    K, bd, ii = model.K, model.bd, model.ii
    S = K[np.ix_(bd, bd)] - K[np.ix_(bd, ii)] @ np.linalg.solve(K[np.ix_(ii, ii)], K[np.ix_(ii, bd)])
    local = model.rot.T @ S @ model.rot
    nb3 = 3 * model.nb
    np.testing.assert_allclose(rom.K[:nb3, :nb3], local, rtol=0, atol=1e-12 * abs(local).max())
    # constraint modes are K-orthogonal to the fixed-interface modes
    assert abs(rom.K[:nb3, nb3:]).max() < 1e-10 * abs(local).max()


def test_recovery_gives_the_static_field_of_a_local_boundary_displacement(model, rom):
    nb3 = 3 * model.nb
    u_local = np.random.default_rng(1).normal(size=nb3) * 1e-4  # m, (r, theta, z) per node
    u_b = model.rot @ u_local
    K, bd, ii = model.K, model.bd, model.ii
    u = np.zeros(K.shape[0])
    u[bd] = u_b
    u[ii] = -np.linalg.solve(K[np.ix_(ii, ii)], K[np.ix_(ii, bd)] @ u_b)  # static, no interior load
    field = rom.recovery.astype(float) @ np.concatenate([u_local, np.zeros(ETA)])
    free = model.node_dofs.ravel() >= 0
    np.testing.assert_allclose(field[free], u, rtol=0, atol=1e-6 * abs(u).max())  # float32 recovery
    assert not field[~free].any()  # the clamped root stays at 0


def test_modal_damping_is_diagonal_with_the_asked_ratios(rom):
    w2, v = sl.eigh(rom.K, rom.M)
    modal = v.T @ rom.C @ v
    expected = np.where(np.arange(len(w2)) < 3, 1e-3, 5e-3)
    np.testing.assert_allclose(np.diag(modal) / (2.0 * np.sqrt(w2)), expected, rtol=1e-8)
    off = modal - np.diag(np.diag(modal))
    assert abs(off).max() < 1e-10 * abs(np.diag(modal)).max()


def test_rom_frequencies_bound_the_full_model_and_converge(model):
    w2, _ = sla.eigsh(model.fem.K, M=model.fem.M, k=6, sigma=0.0)
    full = np.sqrt(np.sort(w2))
    errors = []
    for eta in (0, 2, 4, 8, 16):
        w = build_craig_bampton(model.fem, model.mesh, RomOptions(n_fixed_modes=eta), store_recovery=False,
                                rotation="+").frequencies[:6]
        ratio = w / full
        assert (ratio >= 1 - 1e-10).all(), (eta, ratio)  # Rayleigh-Ritz: upper bounds
        errors.append((ratio - 1).max())
    # measured 2.4, 0.16, 0.049, 0.0052, 0.0011
    assert all(b < a for a, b in zip(errors, errors[1:])), errors
    assert errors[-1] < 2e-3, errors
    # every fixed-interface mode kept: the ROM spans the whole space, its frequencies are the full model's
    _, Kr, Mr = _reference(model, len(model.ii))
    np.testing.assert_allclose(np.sqrt(sl.eigh(Kr, Mr, eigvals_only=True)[:6]), full, rtol=1e-9)


def test_friction_lock_compliance_is_the_inverse_schur_complement(model, rom):
    K, bd, ii = model.K, model.bd, model.ii
    S = K[np.ix_(bd, bd)] - K[np.ix_(bd, ii)] @ np.linalg.solve(K[np.ix_(ii, ii)], K[np.ix_(ii, bd)])
    G = model.rot.T @ np.linalg.inv(S) @ model.rot  # local (r, theta, z) per node, m/N
    lock = rom.friction_lock
    np.testing.assert_allclose(lock.compliance_rr, G[0::3, 0::3], rtol=0, atol=1e-10 * abs(G).max())
    np.testing.assert_allclose(lock.compliance_rtheta, G[0::3, 1::3], rtol=0, atol=1e-10 * abs(G).max())


def _toy(G, eta=2):
    """A ROM stiffness whose boundary compliance is G: blockdiag(G^-1, modal stiffness), N/m."""
    n = G.shape[0]
    K = np.zeros((n + eta, n + eta))
    K[:n, :n] = np.linalg.inv(G)
    K[n:, n:] = np.diag(np.linspace(1e9, 2e9, eta))
    return K


@pytest.mark.parametrize("s", [1, -1])
def test_pair_that_locks_although_neither_node_does(s):
    # G_rr = a I, G[r_0, theta_1] = G[r_1, theta_0] = c, no r-theta coupling at a node: by hand
    # A(mu) = [[a, s mu c], [s mu c, a]], neither diagonal ever vanishes, det = a^2 - mu^2 c^2
    # vanishes at mu = a / c
    a, c = 2e-8, 0.5e-8
    G = a * np.eye(6)
    G[0, 4] = G[4, 0] = G[3, 1] = G[1, 3] = c
    lock = friction_lock(_toy(G), 2, s)
    np.testing.assert_array_equal(lock.mu_node, [np.inf, np.inf])
    assert lock.mu_set == pytest.approx(a / c, rel=1e-12)
    np.testing.assert_array_equal(lock.set_nodes, [1, 1])


def _brute_force_mu_set(grr, grt, s, mu_max=20.0, n=4001):
    """Smallest mu at which a principal minor of G_rr + s mu G_rt reaches 0: every subset's
    determinant on a grid of mu, the first sign change refined by brentq; (mu, nodes)."""
    from scipy.optimize import brentq

    best, nodes = np.inf, None
    mus = np.linspace(0.0, mu_max, n)
    for k in range(1, len(grr) + 1):
        for sub in map(list, itertools.combinations(range(len(grr)), k)):
            B, C = grr[np.ix_(sub, sub)], s * grt[np.ix_(sub, sub)]
            det = np.linalg.det(B[None] + mus[:, None, None] * C[None])
            hit = np.flatnonzero(det <= 0.0)
            if len(hit):
                i = hit[0]
                mu = brentq(lambda m: np.linalg.det(B + m * C), mus[i - 1], mus[i], xtol=1e-14, rtol=1e-14)
                if mu < best:
                    best, nodes = mu, sub
    return best, nodes


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("s", [1, -1])
def test_mu_set_against_brute_force_principal_minors(seed, s):
    # random SPD 4-node compliances: the first minor to vanish is a single node, a pair, a
    # triple or all four, depending on the seed (seed 0, s = +1: nodes 1-3; seed 4, s = -1: 1, 2)
    rng = np.random.default_rng(seed)
    X = rng.normal(size=(12, 12))
    G = 1e-8 * (X @ X.T / 12 + 0.3 * np.eye(12))
    lock = friction_lock(_toy(G), 4, s)
    mu, nodes = _brute_force_mu_set(G[0::3, 0::3], G[0::3, 1::3], s)
    assert lock.mu_set == pytest.approx(mu, rel=1e-10)
    np.testing.assert_array_equal(np.flatnonzero(lock.set_nodes), nodes)
    # single nodes by hand: A_jj = G_rr,jj + s mu G_rt,jj = 0
    d = s * np.diag(G[0::3, 1::3])
    np.testing.assert_allclose(lock.mu_node, np.where(d < 0, -np.diag(G[0::3, 0::3]) / np.where(d < 0, d, 1), np.inf),
                               rtol=1e-12)


def test_first_singular_mu_takes_the_smallest_positive_root():
    # det(B + mu C) = (1 - mu)(1 - mu / 3)(1 + mu) for B = I, C = diag(-1, -1/3, 1): roots 1, 3, -1
    assert _first_singular_mu(np.eye(3), np.diag([-1.0 / 3.0, -1.0, 1.0])) == pytest.approx(1.0, rel=1e-14)
    # no positive root (C positive semi-definite): never singular
    assert _first_singular_mu(np.eye(2), np.diag([1.0, 0.0])) == np.inf
    # complex eigenvalues of B^-1 C only: det = (1 + mu)^2 + mu^2 > 0 for every real mu
    assert _first_singular_mu(np.eye(2), np.array([[1.0, 1.0], [-1.0, 1.0]])) == np.inf


def test_le_leads_across_the_cut_at_pi():
    # absolute angles of a blade crossing the -x axis: LE at +3.0 rad, TE at -3.1 rad is
    # 2 pi - 6.1 = +0.18 rad ahead of the LE, the same blade as relative angles 0 .. +0.18 rad
    span = 2.0 * np.pi - 6.1
    assert rotation_sign("le-leads", np.array([0.0, 0.1, span])) == -1
    assert rotation_sign("le-leads", np.array([3.0, 3.1, -3.1])) == -1
    assert rotation_sign("le-leads", np.array([-3.0, -3.1, 3.1])) == 1
    assert rotation_sign("le-leads", np.array([0.1, -0.05, -0.2])) == 1  # no wrap: -0.3 rad
    with pytest.raises(ValueError, match="span an angle"):
        rotation_sign("le-leads", np.array([np.pi, 0.0, -np.pi]))  # the same angle, written both ways
