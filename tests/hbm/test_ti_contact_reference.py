"""The time integration's contact mechanics (hbm.ti.march, hbm.ti.kernel) against a plain
numpy implementation of the documented scheme, step by step, on a 3-node stand-in ROM.

The reference is written from the scheme's description alone: explicit central differences
in the M-orthonormal eigenbasis of (K, M) (its own scipy eigendecomposition), modal damping
through the centred velocity, forward-increment Lagrange multipliers that put each node
exactly on the casing of eq. (28) at the next step, the multipliers found by enumerating
every active set of the linear complementarity problem (not by the kernel's active-set
iteration), and sliding Coulomb friction -mu lam e with e the unit relative sliding
velocity (v_theta + s rho Omega, v_z) of the step's own centred velocity, which its forces
move (a fixed point, found by plain iteration; the prediction's velocity where the sliding
reverses within the step). The casing is
evaluated at the node's absolute angle s Omega t + theta_j (the kernel uses tau + s theta_j
and the casing's evenness). Other checks use only the kernel's recorded output and first
principles: friction against the recorded sliding velocity, complementarity on the casing
law, the discrete energy balance with the physical K, M, C and each mode's decay against
exp(-2 xi_k w_k t).

The stand-in's tip nodes sit 0.05 rad apart around a lobe centre, pressed onto it by the
static contact state, so one, two and three nodes (coupled through the inverse mass) carry
forces at once and let go as the start velocity shakes them.
"""
import dataclasses
import itertools
import math

import numpy as np
import pytest
import scipy.linalg

from hbm.options import CasingOptions
from hbm.ti import march as ti_march
from hbm.ti.march import Marcher, Recording, rom_modal_system
from support import mirrored_rom, standin_rom

MU = 0.3
THETA = 0.5 * math.pi + np.array([-0.05, 0.0, 0.05])  # rad: around a lobe centre (pi / 2 mod pi)

#: name: (stand-in seed, Omega rad/s, start velocity scale m/s, casing, steps per casing period, steps)
CASES = {
    # slow rotation (rho Omega = 7 m/s) shaken at 10 m/s: the sliding velocity turns,
    # its theta part changes sign at some contact steps, its z part dominates at others
    "slow_sliding_reversal": (4, 30.0, 10.0, CasingOptions(), 50000, 600),
    # slower still (rho Omega = 2.3 m/s): the sliding direction swings through every angle, and
    # an update can turn it by 90 to 120 degrees: a reversal by the scheme's rule (6 steps
    # fall back at s = 1, 4 at s = -1), 3 of which a rule of 120 degrees iterates on and settles
    "slow_sliding_turns": (4, 10.0, 10.0, CasingOptions(), 50000, 300),
    # pressed onto the lobe and shaken gently: up to three nodes at once, many releases
    "three_nodes_coupled": (8, 30.0, 0.3, CasingOptions(), 50000, 600),
    # rotor speed (rho Omega = 364 m/s): lobes 0.3 rad wide pass, impacts and rubbing
    "lobe_passages": (1, 1500.0, 0.3, CasingOptions(width=0.3), 1000, 3000),
}


def casing_gap(x, casing):
    """Eq. (28) at absolute casing angles x (any shape), rad: d = c - (c + p) exp(-(phi / w)^2),
    phi the angle from the nearest lobe centre pi / n_l + k 2 pi / n_l; m."""
    period = 2.0 * math.pi / casing.n_lobes
    phi = np.mod(x - 0.5 * period, period)
    phi = np.where(phi > 0.5 * period, phi - period, phi)
    return casing.clearance - (casing.clearance + casing.penetration) * np.exp(-(phi / casing.width) ** 2)


def lcp_by_enumeration(r_hat, d, A):
    """Every active set S of r = r_hat - A lam <= d, lam >= 0, lam_j (d_j - r_j) = 0: lam_S
    from A_SS lam_S = (r_hat - d)_S, kept when lam >= 0 and r <= d (to round-off).
    r_hat, d: (n_b,), m. A: (n_b, n_b), m/N. Returns the list of lam, (n_b,), N."""
    nb = len(r_hat)
    lam_tol = 1e-9 * np.abs(r_hat - d).max() / np.abs(A).max()
    gap_tol = 1e-12 * np.abs(r_hat - d).max()
    out = []
    for mask in itertools.product((False, True), repeat=nb):
        act = np.array(mask)
        lam = np.zeros(nb)
        if act.any():
            lam[act] = np.linalg.solve(A[np.ix_(act, act)], (r_hat - d)[act])
        if (lam >= -lam_tol).all() and (r_hat - A @ lam - d <= gap_tol).all():
            out.append(np.maximum(lam, 0.0))
    return out


class ModalReference:
    """The scheme in the ROM's modal basis, in plain numpy (see the module docstring)."""

    def __init__(self, rom, casing, mu, omega, dt):
        w2, self.phi = scipy.linalg.eigh(rom.K, rom.M)
        self.w2 = w2
        self.m = rom.M
        self.a = 0.5 * np.diag(self.phi.T @ rom.C @ self.phi) * dt  # xi_k w_k dt
        self.rom, self.casing, self.mu, self.omega, self.dt = rom, casing, mu, omega, dt
        nb = rom.n_boundary
        self.pr, self.pt, self.pz = self.phi[0:3 * nb:3], self.phi[1:3 * nb:3], self.phi[2:3 * nb:3]

    def modal(self, x):
        return self.phi.T @ self.m @ x

    def direction(self, q_next, qm):
        """(n_b, 2): the unit relative sliding direction (v_theta + s rho Omega, v_z) / |.| of
        the centred velocity (q_next - q_{n-1}) / 2 dt."""
        rom = self.rom
        vt = self.pt @ (q_next - qm) / (2.0 * self.dt) + rom.rotation * rom.rho * self.omega
        vz = self.pz @ (q_next - qm) / (2.0 * self.dt)
        return np.stack([vt, vz], axis=1) / np.hypot(vt, vz)[:, None]

    def step(self, q, qm, t_next, e=None):
        """(r_hat, d, A, e, q_hat): the prediction at t_next from q_n, q_{n-1}, the casing
        there, dr / dlam with each node's friction along e (n_b, 2) (default: the direction
        of the prediction's velocity)."""
        rom, dt, a = self.rom, self.dt, self.a
        q_hat = ((2.0 - self.w2 * dt * dt) * q - (1.0 - a) * qm) / (1.0 + a)
        d = casing_gap(rom.rotation * self.omega * t_next + rom.theta, self.casing)
        if e is None:
            e = self.direction(q_hat, qm)
        s = dt * dt / (1.0 + a)
        A = (self.pr * s) @ (self.pr + self.mu * e[:, :1] * self.pt + self.mu * e[:, 1:] * self.pz).T
        return self.pr @ q_hat, d, A, e, q_hat

    def forced(self, q_hat, lam, e):
        """q_{n+1}: the prediction moved by the forces lam (e_r + mu e) of the nodes."""
        nb = self.rom.n_boundary
        f = np.zeros(self.rom.n_dof)
        f[0:3 * nb:3] = -lam
        f[1:3 * nb:3] = -self.mu * e[:, 0] * lam
        f[2:3 * nb:3] = -self.mu * e[:, 1] * lam
        return q_hat + self.dt ** 2 / (1.0 + self.a) * (self.phi.T @ f)

    def settled(self, q, qm, t_next, e0):
        """(lam, e, number of LCP solutions) of a contact step whose friction acts along the
        direction of its own centred velocity: the fixed point e = direction(q_{n+1}(e)) from
        e0, by plain iteration (halfway from the 50th), to 1e-12 (the round-off of a velocity
        from two positions is ~1e-12 of it here); None where an iterate's
        velocity turns against its direction at an active node (the sliding reverses) or it
        does not settle in 200."""
        e = e0.copy()
        for k in range(200):
            r_hat, d, A, _, q_hat = self.step(q, qm, t_next, e)
            sols = lcp_by_enumeration(r_hat, d, A)
            lam = sols[0]
            u = self.direction(self.forced(q_hat, lam, e), qm)
            on = lam > 0
            if ((u * e).sum(axis=1)[on] < 0).any():
                return None
            if np.abs(u - e)[on].sum(axis=1).max(initial=0.0) <= 1e-12:
                return lam, e, len(sols)
            relax = 1.0 if k < 50 else 0.5
            new = e + relax * (u - e)
            e = np.where(on[:, None], new / np.hypot(new[:, 0], new[:, 1])[:, None], e)
        return None

    def march(self, x0, v0, n):
        """n steps from (x0, v0) at t = 0: x (n, n_dof) at steps 1..n; lam, friction (theta,
        z) on the blade (n, n_b, 2), the number of LCP solutions and whether the step took the
        prediction's direction (no settled one), per step 0..n-1. A node in contact at the
        last step starts the fixed point from its last direction, a new one from the
        prediction's."""
        dt = self.dt
        q = self.modal(x0)
        qd = self.modal(v0)
        qm = q - dt * qd + 0.5 * dt * dt * (-self.w2 * q - 2.0 * self.a / dt * qd)
        nb = self.rom.n_boundary
        xs, lams, fr, n_sol, explicit = [], [], [], [], []
        was_on, e_last = np.zeros(nb, dtype=bool), np.zeros((nb, 2))
        for i in range(n):
            r_hat, d, A, e, q_hat = self.step(q, qm, (i + 1) * dt)
            lam, n_s, fell_back = np.zeros(nb), 1, False
            if (r_hat >= d).any():
                out = self.settled(q, qm, (i + 1) * dt, np.where(was_on[:, None], e_last, e))
                if out is None:  # the prediction's direction, as an explicit scheme
                    sols = lcp_by_enumeration(r_hat, d, A)
                    lam, n_s, fell_back = sols[0], len(sols), True
                else:
                    lam, e, n_s = out
            was_on, e_last = lam > 0, e
            qm, q = q, self.forced(q_hat, lam, e)
            xs.append(self.phi @ q)
            lams.append(lam)
            fr.append(np.stack([-self.mu * e[:, 0] * lam, -self.mu * e[:, 1] * lam], axis=1))
            n_sol.append(n_s)
            explicit.append(fell_back)
        return np.array(xs), np.array(lams), np.array(fr), np.array(n_sol), np.array(explicit)


def pressed_standin(seed, s):
    """The 12-dof stand-in (3 tip nodes, 3 other dof) with its nodes at THETA, turning at s."""
    return dataclasses.replace(standin_rom(n_boundary=3, n_modes=3, seed=seed, rotation=s), theta=THETA)


def pressed_start(rom, casing, v_scale):
    """(x0, v0): the static state with every node on the casing at t = 0 (sliding friction
    along -s e_theta), and a random start velocity of scale v_scale, m/s."""
    nb, nd, s = rom.n_boundary, rom.n_dof, rom.rotation
    G = np.zeros((nd, nb))
    for j in range(nb):
        G[3 * j, j] = -1.0
        G[3 * j + 1, j] = -MU * s
    F = np.linalg.solve(rom.K, G)
    lam0 = np.linalg.solve(F[0:3 * nb:3], casing_gap(rom.theta, casing))
    assert (lam0 > 0).all()  # the stand-in's seeds are chosen so
    return F @ lam0, v_scale * np.random.default_rng(1).standard_normal(nd)


def kernel_march(case, s, path="table", monkeypatch=None, direction_tol=None):
    """(rom, casing, omega, dt, x0, march) of a case on the casing table or the law
    (direction_tol: the kernel's tolerance on the sliding direction, default its own)."""
    seed, omega, v_scale, casing, period_steps, n = CASES[case]
    rom = pressed_standin(seed, s)
    dt = 2.0 * math.pi / (casing.n_lobes * omega * period_steps)
    x0, v0 = pressed_start(rom, casing, v_scale)
    if path == "law":
        monkeypatch.setattr(ti_march, "PROFILE_MAX_ENTRIES", 0)
    rec = Recording(start=1, stride=1, n_samples=n, dofs=np.arange(rom.n_dof), force_nodes=np.arange(3))
    marcher = Marcher(rom_modal_system(rom), casing, MU, omega, x0, v0, dt, n, rec, direction_tol=direction_tol)
    assert marcher._profile.shape[0] == (period_steps if path == "table" else 0)
    m = marcher.advance(n).result()
    assert m.active_set_failures == 0
    return rom, casing, omega, dt, x0, v0, m


@pytest.mark.parametrize("path", ["table", "law"])
@pytest.mark.parametrize("s", [1, -1])
@pytest.mark.parametrize("case", list(CASES))
def test_kernel_follows_the_modal_reference_step_by_step(case, s, path, monkeypatch):
    """Displacements, multipliers and friction forces at every step, the kernel's sliding
    direction settled to 1e-10 (the reference's to 1e-12, by another iteration). The same
    scheme in other operations: agreement to round-off amplified by the contact history
    (a sense missing from the friction or the casing gives O(1); the prediction's direction
    instead of the settled one 1e-4 to 1e-2 of the multipliers). The steps that fall back to
    the prediction's direction (a sliding reversal) are the same steps."""
    rom, casing, omega, dt, x0, v0, m = kernel_march(case, s, path, monkeypatch, direction_tol=1e-10)
    n = m.n_steps
    x, lam, fr, n_sol, explicit = ModalReference(rom, casing, MU, omega, dt).march(x0, v0, n)
    contact = (lam > 0).any(axis=1)
    assert contact.sum() >= 200 and m.contact_steps == contact.sum()
    assert (n_sol[contact] == 1).all()  # the LCP's solution is unique at every contact step
    assert m.explicit_direction_steps == explicit.sum()
    np.testing.assert_allclose(m.displacement, x, rtol=0, atol=1e-9 * np.abs(x).max())
    # force sample i is lam at step i + 1 (it moves x_{i+1} to x_{i+2}); the reference's
    # row i is lam at step i; the last sample's would move past the end and reads 0
    scale = np.abs(lam).max()
    np.testing.assert_allclose(m.normal_force[:-1], lam[1:], rtol=0, atol=1e-7 * scale)
    np.testing.assert_allclose(m.friction_force[:-1], fr[1:], rtol=0, atol=1e-7 * scale)
    np.testing.assert_array_equal(m.normal_force[:-1] > 0, lam[1:] > 0)  # the same active sets


def sliding_velocity(rom, omega, dt, x0, m):
    """Relative sliding velocity (v_theta + s rho Omega, v_z) of each node at steps 1..n-1 from
    the recorded displacements (centred differences), (n - 1, n_b, 2), m/s."""
    nb = rom.n_boundary
    x = np.vstack([x0, m.displacement])
    v = (x[2:] - x[:-2]) / (2.0 * dt)
    return np.stack([v[:, 1:3 * nb:3] + rom.rotation * rom.rho * omega, v[:, 2:3 * nb:3]], axis=2)


@pytest.mark.parametrize("case", ["slow_sliding_reversal", "slow_sliding_turns"])
def test_the_mirror_image_turning_the_other_way_is_the_mirrored_march(case):
    """The stand-in turning at s = -1 and its mirror image (theta_j -> -theta_j, v_theta ->
    -v_theta, K, M, C -> P K P, ...) turning at s = +1, started from the mirrored state: sign
    flips are exact in floating point, so the marches are mirror images to round-off, the
    directions' passes included. These cases turn the sliding directions so that a step moves
    one several times (the secant on its angle, hbm.ti.kernel._redirect, measured from the
    theta axis the node slides along); at the default tolerance the pass a direction settles
    at shows in the forces at ~1e-3 of them, so a secant measured on one set of axes and
    rotated on the other breaks the equality (tests/hbm/test_ti_rotation.py checks the sense
    at rotor speed, where no step moves a direction twice)."""
    seed, omega, v_scale, casing, period_steps, n = CASES[case]
    rom = pressed_standin(seed, -1)
    x0, v0 = pressed_start(rom, casing, v_scale)
    mirrored, p = mirrored_rom(rom)
    dt = 2.0 * math.pi / (casing.n_lobes * omega * period_steps)
    rec = Recording(start=1, stride=1, n_samples=n, dofs=np.arange(rom.n_dof), force_nodes=np.arange(3))
    a = Marcher(rom_modal_system(rom), casing, MU, omega, x0, v0, dt, n, rec).advance(n).result()
    b = Marcher(rom_modal_system(mirrored), casing, MU, omega, p * x0, p * v0, dt, n, rec).advance(n).result()
    assert a.contact_steps >= 200 and a.active_set_failures == 0
    np.testing.assert_allclose(a.displacement, p * b.displacement, rtol=0, atol=1e-10 * np.abs(a.displacement).max())
    scale = np.abs(a.normal_force).max()
    np.testing.assert_allclose(a.normal_force, b.normal_force, rtol=0, atol=1e-10 * scale)
    np.testing.assert_allclose(a.friction_force[..., 0], -b.friction_force[..., 0], rtol=0, atol=1e-10 * scale)
    np.testing.assert_allclose(a.friction_force[..., 1], b.friction_force[..., 1], rtol=0, atol=1e-10 * scale)


@pytest.mark.parametrize("s", [1, -1])
def test_friction_opposes_the_relative_sliding_velocity(s):
    """From the kernel's output alone: on every contact step the friction on the blade has
    magnitude mu lam and points against the tip's velocity relative to the casing. The kernel
    takes the direction from the predicted velocity; the recorded (corrected) one differs by
    the step's own friction impulse, measured 5e-3 rad at most here (0.045 rad allowed).
    The case has steps where the tip slides against its blade speed s rho Omega and where
    the axial sliding dominates, so a sign taken from s alone would fail."""
    rom, casing, omega, dt, x0, v0, m = kernel_march("slow_sliding_reversal", s)
    lam = m.normal_force[:-1]  # lam at steps 1..n-1
    f = m.friction_force[:-1]
    v = sliding_velocity(rom, omega, dt, x0, m)
    on = lam > 0
    assert on.sum() >= 300
    reversed_ = on & (np.sign(v[..., 0]) == -s)
    axial = on & (np.abs(v[..., 1]) > np.abs(v[..., 0]))
    assert reversed_.sum() >= 3 and axial.sum() >= 3
    np.testing.assert_allclose(np.hypot(f[..., 0], f[..., 1])[on], MU * lam[on], rtol=1e-12)
    cos = (f * v).sum(axis=2)[on] / (np.hypot(f[..., 0], f[..., 1]) * np.hypot(v[..., 0], v[..., 1]))[on]
    assert cos.max() <= -0.999
    # against the blade speed: the friction pushes the blade along s e_theta there
    assert (np.sign(f[..., 0][reversed_]) == s).all()
    assert (f[~on] == 0).all()  # no friction without a normal force


@pytest.mark.parametrize("s", [1, -1])
def test_released_nodes_carry_nothing_and_active_nodes_sit_on_the_casing(s):
    """Complementarity against the casing law written here: lam_m >= 0, the node is on the
    casing at m + 1 (r = d to round-off) where lam_m > 0, never beyond it, and a node that
    carried a force at m - 1 and leaves at m + 1 gets exactly lam_m = 0."""
    rom, casing, omega, dt, x0, v0, m = kernel_march("three_nodes_coupled", s)
    nb = rom.n_boundary
    d = casing_gap(s * omega * m.times[:, None] + rom.theta, casing)  # at steps 1..n
    gap = m.displacement[:, 0:3 * nb:3] - d
    lam = m.normal_force[:-1]  # lam_m, m = 1..n-1, moves x_m to x_{m+1} = displacement[m]
    after = gap[1:]  # r_{m+1} - d_{m+1}
    tol = 1e-12 * (casing.clearance + casing.penetration)
    assert lam.min() >= 0.0 and m.min_multiplier >= 0.0
    assert gap.max() <= tol and m.max_penetration <= tol
    assert np.abs(after[lam > 0]).max() <= tol
    released = (lam[:-1] > 0) & (after[1:] < -tol)  # carried at m - 1, free at m + 1
    assert released.sum() >= 10
    assert (lam[1:][released] == 0.0).all()
    assert (lam[after < -tol] == 0.0).all()  # no force on any node off the casing
    assert ((lam > 0).sum(axis=1) == 3).sum() >= 50  # three nodes at once


@pytest.mark.parametrize("s", [1, -1])
def test_simultaneous_multipliers_solve_the_contact_lcp_found_by_enumeration(s):
    """At every contact step, from the kernel's own states x_{m-1}, x_m (projected on the
    reference's modes), the LCP of the step built in numpy has one solution among all 2^3
    active sets, and it is the kernel's lam_m, whatever the number of nodes in contact."""
    rom, casing, omega, dt, x0, v0, m = kernel_march("three_nodes_coupled", s, direction_tol=1e-10)
    ref = ModalReference(rom, casing, MU, omega, dt)
    q = ref.modal(m.displacement.T).T  # q at steps 1..n
    lam_k = m.normal_force[:-1]  # lam_m, m = 1..n-1
    seen = np.zeros(4, dtype=int)
    worst = 0.0
    for i in range(1, len(lam_k)):  # lam_{i+1} from q_i, q_{i+1} (rows i - 1, i)
        # the friction along the kernel's own step: the direction of its centred velocity
        e = ref.direction(q[i + 1], q[i - 1]) if i + 1 < len(q) else None
        r_hat, d, A, _, _ = ref.step(q[i], q[i - 1], (i + 2) * dt, e)
        if not (r_hat >= d).any():
            assert (lam_k[i] == 0).all()
            continue
        sols = lcp_by_enumeration(r_hat, d, A)
        assert len(sols) == 1
        seen[(sols[0] > 0).sum()] += 1
        worst = max(worst, np.abs(lam_k[i] - sols[0]).max() / np.abs(sols[0]).max())
    assert seen[2] >= 50 and seen[3] >= 50  # coupled nodes: two and three at once
    # the states are the kernel's to round-off; the projection and the reference's
    # prediction repeat it (measured 5e-10)
    assert worst <= 1e-7


@pytest.mark.parametrize("s", [1, -1])
def test_the_casing_table_and_the_law_give_the_same_forces(s, monkeypatch):
    """A casing period of 1000 whole steps: the table read at row m mod P and the law at
    every step give the same march, forces and friction to round-off, over lobe passages."""
    *_, table = kernel_march("lobe_passages", s, "table")
    *_, law = kernel_march("lobe_passages", s, "law", monkeypatch)
    assert table.contact_steps == law.contact_steps >= 200
    scale = np.abs(law.normal_force).max()
    np.testing.assert_allclose(table.normal_force, law.normal_force, rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(table.friction_force, law.friction_force, rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(table.displacement, law.displacement, rtol=0,
                               atol=1e-11 * np.abs(law.displacement).max())


def test_free_decay_balances_the_energy_and_follows_each_modes_analytic_decay():
    """No contact (a flat wall 1 m away), every mode started with the same energy. Central
    differences with the centred velocity conserve exactly, with the physical K, M, C,
    E_{n+1/2} - E_{n-1/2} = -dt v_n^T C v_n, E_{n+1/2} = 1/2 v^T M v + 1/2 x_n^T K x_{n+1}
    (measured below 1e-12 of E_0, accumulated over the march). Mode k's discrete energy decays by
    exactly (1 - a_k) / (1 + a_k) per step, a_k = xi_k w_k dt, i.e. as exp(-2 xi_k w_k t)
    up to 2/3 a_k^3 per step, with xi_k, w_k the ROM's damping ratios and frequencies."""
    rom = standin_rom(n_boundary=3, n_modes=3)
    dt, n = 2e-6, 5000
    w2, phi = scipy.linalg.eigh(rom.K, rom.M)
    w = np.sqrt(w2)
    np.testing.assert_allclose(w, rom.frequencies, rtol=1e-12)
    q0 = 1e-4 * w[0] / w * np.random.default_rng(3).choice([-1.0, 1.0], rom.n_dof)
    x0 = phi @ q0
    rec = Recording(start=1, stride=1, n_samples=n, dofs=np.arange(rom.n_dof), force_nodes=np.arange(3))
    marcher = Marcher(rom_modal_system(rom), CasingOptions(clearance=1.0, penetration=-1.0), MU, 1500.0, x0,
                      np.zeros(rom.n_dof), dt, n, rec)
    m = marcher.advance(n).result()
    assert m.contact_steps == 0
    x = np.vstack([x0, m.displacement])
    v = np.diff(x, axis=0) / dt
    E = 0.5 * np.einsum("ti,ij,tj->t", v, rom.M, v) + 0.5 * np.einsum("ti,ij,tj->t", x[:-1], rom.K, x[1:])
    vc = (x[2:] - x[:-2]) / (2.0 * dt)
    dissipated = dt * np.einsum("ti,ij,tj->t", vc, rom.C, vc)
    assert np.abs(np.cumsum(np.diff(E) + dissipated)).max() <= 1e-11 * E[0]
    assert E[-1] < 0.5 * E[0]  # the damping acts
    # each mode's discrete energy (the quadratic form that the damped recurrence scales by
    # its root product (1 - a) / (1 + a) per step)
    q = x @ (rom.M @ phi)
    a = rom.damping_ratios * rom.frequencies * dt
    e = 0.5 * (np.diff(q, axis=0) ** 2 / dt ** 2 + w2 * q[:-1] * q[1:] + a / dt ** 2 * (q[1:] ** 2 - q[:-1] ** 2))
    steps = np.arange(n)[:, None]
    log_decay = np.log(e / e[0])
    np.testing.assert_allclose(log_decay, steps * np.log((1.0 - a) / (1.0 + a)), rtol=0, atol=1e-9)
    analytic = -2.0 * rom.damping_ratios * rom.frequencies * dt * steps
    assert (np.abs(log_decay - analytic) <= 2.0 / 3.0 * steps * a ** 3 * 1.01 + 1e-9).all()
