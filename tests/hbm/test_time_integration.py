"""Central differences (and the exponential recurrence) with forward-increment Lagrange multiplier
contact (hbm.ti.march).

References are independent of the kernel: closed-form solutions of the constrained problems,
the discrete energy that central differences conserve exactly, and a step-by-step numpy
implementation in physical coordinates.
"""
import math

import numpy as np
import pytest

from hbm.contact.casing import casing_distance
from hbm.options import CasingOptions
from hbm.ti.march import (Marcher, Recording, critical_time_step, march, massless_system, modal_system,
                          rom_modal_system)
from support import standin_rom


def flat_wall(gap):
    """A casing whose lobes vanish (c + p = 0): a flat wall at r = gap."""
    return CasingOptions(clearance=gap, penetration=-gap)


def record_all(n_steps, dofs, nodes=(0,)):
    return Recording(start=1, stride=1, n_samples=n_steps, dofs=np.asarray(dofs), force_nodes=np.asarray(nodes))


def oscillator(k=1e4, m=1.0, k_theta=4e4, k_z=9e4, extra=None):
    """One contact node (r, theta, z) on independent springs; extra=(m2, k2) adds a mass
    coupled to r by a spring k2 (a 2-dof radial chain: ground -k- m -k2- m2)."""
    if extra is None:
        K = np.diag([k, k_theta, k_z])
        M = np.diag([m, m, m])
    else:
        m2, k2 = extra
        K = np.zeros((4, 4))
        K[:3, :3] = np.diag([k + k2, k_theta, k_z])
        K[0, 3] = K[3, 0] = -k2
        K[3, 3] = k2
        M = np.diag([m, m, m, m2])
    return K, M


def discrete_energy(x, M, K, dt):
    """E_{n+1/2} = 1/2 v^T M v + 1/2 x_n^T K x_{n+1}, v = (x_{n+1} - x_n) / dt: the invariant
    of undamped central differences (exact to round-off in free flight). x: (n_t, n)."""
    v = np.diff(x, axis=0) / dt
    return 0.5 * np.einsum("ti,ij,tj->t", v, M, v) + 0.5 * np.einsum("ti,ij,tj->t", x[:-1], K, x[1:])


def test_free_flight_conserves_the_discrete_energy():
    K, M = oscillator()
    s = modal_system(K, M, np.zeros((3, 3)), [0.25], [0.0])
    dt = 1e-3 / math.sqrt(9e4)
    n = 20000
    x0 = np.array([1e-3, -2e-3, 5e-4])
    m = march(s, flat_wall(1.0), 0.15, 0.0, x0, np.array([0.1, 0.0, 0.2]), dt, n, record_all(n, [0, 1, 2]))
    E = discrete_energy(np.vstack([x0, m.displacement]), M, K, dt)
    # round-off only: a relative error eps on x is one of eps / (w dt) on the step velocity,
    # accumulated at worst linearly over n steps (w dt = 3.3e-4 for the slowest dof)
    eps = np.finfo(float).eps
    assert np.ptp(E) / E[0] < n * eps / (100.0 * dt)
    assert m.contact_steps == 0


def test_single_impact_is_perfectly_plastic_and_exact():
    """1-dof oscillator (w = 100 rad/s) thrown at a wall at gap g with speed V = 2 g w.

    Exact constrained solution: free flight x = (V / w) sin(w t) up to t* = asin(g w / V) / w;
    the forward-increment multiplier stops the mass in one step (restitution 0), and as the
    spring pulls it back (g > 0) it leaves at once: x = g cos(w (t - t*)) afterwards, grazing
    the wall with zero speed every period. The discrete impact is late by at most ~1.5 dt
    (the first grid step past t*, then one step at the wall), so |x - x_exact| <= 2 g w dt
    plus O((w dt)^2 w t) phase drift (1e-6 g here).
    """
    k, mass, g = 1e4, 1.0, 1e-3
    w = math.sqrt(k / mass)
    K, M = oscillator(k, mass)
    s = modal_system(K, M, np.zeros((3, 3)), [0.25], [0.0])
    dt = 1e-3 / w
    V = 2.0 * g * w
    n = int(5 * 2 * math.pi / w / dt)
    m = march(s, flat_wall(g), 0.0, 0.0, np.zeros(3), np.array([V, 0, 0]), dt, n, record_all(n, [0, 1, 2]))
    t = m.times
    x = m.displacement[:, 0]
    ts = math.asin(g * w / V) / w
    exact = np.where(t < ts, V / w * np.sin(w * t), g * np.cos(w * (t - ts)))
    assert np.abs(x - exact).max() <= 2.0 * g * w * dt
    # the constraint holds to round-off at every step, multipliers are never negative
    assert x.max() <= g * (1 + 1e-15)
    assert m.max_penetration <= 1e-15 * g
    assert m.min_multiplier >= 0.0 and m.normal_force.min() >= 0.0
    # energy: 1/2 m V^2 before, exactly 1/2 k g^2 right after the impact (state (g, g) at
    # rest), then never more; each later grazing may clip the discrete orbit (amplitude
    # g / cos(w dt / 2)) by O((w dt)^2): at most 5 grazings here
    E = discrete_energy(np.vstack([np.zeros(3), m.displacement])[:, :1], M[:1, :1], K[:1, :1], dt)
    hit = np.argmax(x >= g)
    assert abs(E[0] - 0.5 * mass * V ** 2) <= 1e-6 * 0.5 * mass * V ** 2
    assert abs(E[hit + 1] - 0.5 * k * g ** 2) <= 1e-9 * 0.5 * k * g ** 2
    after = E[hit + 1:]
    assert after.max() <= 0.5 * k * g ** 2 * (1 + 1e-9)
    assert after.min() >= 0.5 * k * g ** 2 * (1 - 5 * (w * dt) ** 2)
    # the impulse of the impact stops the mass: sum lam dt = momentum at impact m v*
    v_star = math.sqrt(V ** 2 - (w * g) ** 2)
    impulse = m.normal_force[:, 0].sum() * dt
    assert impulse == pytest.approx(mass * v_star, rel=2 * w * dt)


def test_two_dof_impact_loses_exactly_the_kinetic_energy_of_the_struck_mass():
    """ground -k- m1 -k2- m2, wall at g on m1. An impact is instantaneous in the continuous
    problem, springs transmit no impulse: only m1 stops, the energy lost is 1/2 m1 v1*^2 with
    v1* from the exact modal solution at the first contact time. The discrete impact spreads
    over ~2 steps, so the loss agrees to O(w_max dt)."""
    k, m1, m2, k2, g = 1e4, 1.0, 0.5, 3e4, 1e-3
    K, M = oscillator(k, m1, extra=(m2, k2))
    s = modal_system(K, M, np.zeros((4, 4)), [0.25], [0.0])
    w_max = s.omega.max()
    dt = 1e-3 / w_max
    x0 = np.zeros(4)
    v0 = np.array([0.3, 0.0, 0.0, -0.2])
    n = int(0.3 / dt)
    m = march(s, flat_wall(g), 0.0, 0.0, x0, v0, dt, n, record_all(n, [0, 1, 2, 3]))
    x = np.vstack([x0, m.displacement])
    # exact free solution x(t) = Phi (q0 cos wt + qd0 / w sin wt), first contact by bisection
    q0, qd0 = s.phi_t_m @ x0, s.phi_t_m @ v0
    xr = lambda t: s.phi[0] @ (q0 * np.cos(s.omega * t) + qd0 / s.omega * np.sin(s.omega * t))
    tt = np.linspace(0, 0.3, 300001)
    i = np.argmax(s.phi[0] @ (np.outer(q0, np.ones_like(tt)) * np.cos(np.outer(s.omega, tt))
                             + np.outer(qd0 / s.omega, np.ones_like(tt)) * np.sin(np.outer(s.omega, tt))) >= g)
    assert i > 0
    lo, hi = tt[i - 1], tt[i]
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if xr(mid) < g else (lo, mid)
    v1 = s.phi[0] @ (-q0 * s.omega * np.sin(s.omega * lo) + qd0 * np.cos(s.omega * lo))
    E = discrete_energy(x, M, K, dt)
    first = np.argmax(x[:, 0] >= g)  # first step at the wall
    before, after = E[first - 2], E[first + 2]
    assert before - after == pytest.approx(0.5 * m1 * v1 ** 2, rel=5 * w_max * dt)
    # between contact steps the discrete energy is exactly conserved, it never increases
    lam = m.normal_force[:, 0]
    free = lam[:-1] == 0  # E[i + 1] - E[i] is changed only by lam at step i + 1 = lam[i]
    dE = np.diff(E)
    tol = 10 * np.finfo(float).eps / (s.omega.min() * dt) * E[0]  # round-off of one step
    assert np.abs(dE[free]).max() <= tol
    assert dE.max() <= tol
    assert x[:, 0].max() <= g * (1 + 1e-15) and lam.min() >= 0.0 and m.min_multiplier >= 0.0
    assert m.contact_steps >= 2  # the impact: one step to stop, one at the wall


def test_persistent_contact_with_sliding_friction_matches_the_closed_form():
    """Node on a wall at r = 0 (c = 0), pushed outward by a mass m2 (spring k2) released from
    X: while in contact r = 0, m2 oscillates at w2 = sqrt(k2 / m2) and lam(t) = k2 X cos(w2 t).
    Friction slides along +theta (rho Omega >> v_theta, v_z = 0): the theta dof obeys
    m x'' + k_t x = -mu lam, x = -mu k2 X / (k_t - m w2^2) (cos w2 t - cos w_t t).
    Central differences reproduce both to O((w dt)^2)."""
    m, k, k_t, m2, k2, X, mu = 1.0, 1e4, 4e4, 0.5, 1e4, 1e-3, 0.15
    K, M = oscillator(k, m, k_theta=k_t, extra=(m2, k2))
    s = modal_system(K, M, np.zeros((4, 4)), [0.25], [0.0])
    dt = 1e-3 / s.omega.max()
    w2, wt = math.sqrt(k2 / m2), math.sqrt(k_t / m)
    n = int(0.45 * math.pi / w2 / dt)  # stop before lam -> 0 at w2 t = pi / 2
    x0 = np.array([0.0, 0.0, 0.0, X])
    rec = record_all(n, [0, 1, 2])
    r = march(s, flat_wall(0.0), mu, 1000.0, x0, np.zeros(4), dt, n, rec)
    # force sample i is lam at step i + 1 (the multiplier moving x_{i+1} to x_{i+2}); the
    # last one would move past the end and is not computed
    lam_exact = k2 * X * np.cos(w2 * r.times[:-1])
    assert np.abs(r.normal_force[:-1, 0] - lam_exact).max() <= 1e-5 * k2 * X
    ti = r.times
    xt = -mu * k2 * X / (k_t - m * w2 ** 2) * (np.cos(w2 * ti) - np.cos(wt * ti))
    assert np.abs(r.displacement[:, 1] - xt).max() <= 1e-3 * np.abs(xt).max()
    assert np.abs(r.displacement[:, 0]).max() <= 1e-18 and np.abs(r.displacement[:, 2]).max() == 0.0
    # friction on the blade opposes sliding (+theta) with magnitude mu lam
    np.testing.assert_allclose(r.friction_force[:, 0, 0], -mu * r.normal_force[:, 0], rtol=1e-14)
    assert (r.friction_force[:, 0, 1] == 0).all()


def reference_march(K, M, C, rho, theta, casing, mu, Om, x0, v0, dt, n):
    """Step-by-step numpy implementation in physical coordinates (slow, independent). The
    friction of a contact step acts along the unit sliding direction of the step's own
    centred velocity (x_{n+1} - x_{n-1}) / 2 dt, which its forces move: the fixed point by
    plain iteration to 1e-12, from the last step's direction for a node in contact then,
    else the prediction's; the prediction's where the sliding reverses within the step."""
    nb = len(rho)
    Minv = np.linalg.inv(M)
    A_lhs = M / dt ** 2 + C / (2 * dt)
    A_inv = np.linalg.inv(A_lhs)
    a0 = Minv @ (-K @ x0 - C @ v0)
    xm, x = x0 - dt * v0 + 0.5 * dt ** 2 * a0, x0.copy()

    def direction(xn):  # (n_b, 2)
        vt = (xn[1:3 * nb:3] - xm[1:3 * nb:3]) / (2 * dt) + rho * Om
        vz = (xn[2:3 * nb:3] - xm[2:3 * nb:3]) / (2 * dt)
        return np.stack([vt, vz], axis=1) / np.hypot(vt, vz)[:, None]

    def solve(xh, r, d, e):  # lam and x_{n+1} with friction along e
        G = np.zeros((len(x), nb))
        for j in range(nb):
            G[3 * j, j] = 1.0
            G[3 * j + 1, j] = mu * e[j, 0]
            G[3 * j + 2, j] = mu * e[j, 1]
        Acomp = (A_inv @ G)[0:3 * nb:3]  # dr_{n+1} / dlam
        act = r >= d
        lam = np.zeros(nb)
        for _ in range(50):  # active set by enumeration of sign fixes
            lam[:] = 0
            if act.any():
                lam[act] = np.linalg.solve(Acomp[np.ix_(act, act)], (r - d)[act])
            if (lam < 0).any():
                act[np.argmin(lam)] = False
                continue
            rn = r - Acomp @ lam
            if (rn - d > 1e-300)[~act].any():
                act[np.argmax(np.where(act, -np.inf, rn - d))] = True
                continue
            break
        return lam, xh - A_inv @ G @ lam

    xs, lams = [], []
    on_last, e_last = np.zeros(nb, dtype=bool), np.zeros((nb, 2))
    for it in range(n):
        t1 = (it + 1) * dt
        rhs = M @ (2 * x - xm) / dt ** 2 + C @ xm / (2 * dt) - K @ x
        xh = A_inv @ rhs
        d = casing_distance(np.array(Om * t1), theta, casing)
        r = xh[0:3 * nb:3]
        e_pred = direction(xh)
        e = np.where(on_last[:, None], e_last, e_pred)
        for k in range(200):
            lam, xn = solve(xh, r, d, e)
            u, on = direction(xn), lam > 0
            if ((u * e).sum(axis=1)[on] < 0).any():
                k = None  # the sliding reverses: the prediction's direction
                break
            if np.abs(u - e)[on].sum(axis=1).max(initial=0.0) <= 1e-12:
                break
            e = np.where(on[:, None], u, e)
        if k is None or k == 199:
            e = e_pred
            lam, xn = solve(xh, r, d, e)
        on_last, e_last = lam > 0, e
        xm, x = x, xn
        xs.append(xn.copy())
        lams.append(lam.copy())
    return np.array(xs), np.array(lams)


def test_kernel_matches_a_physical_coordinate_reference_on_the_standin_rom():
    """Modal kernel vs the numpy reference on the 39-dof stand-in with the ovalised casing,
    friction and modal damping, from an initial state that hits the lobes within 400 steps.
    The same algorithm in other coordinates: agreement to round-off amplified by the
    (stable) dynamics, 1e-8 of the motion."""
    rom = standin_rom()
    s = rom_modal_system(rom)
    cas = CasingOptions()
    Om, dt, n = 1500.0, 2e-6, 600
    rng = np.random.default_rng(1)
    x0 = np.zeros(39)
    x0[0:27:3] = 3e-4
    v0 = 0.05 * rng.standard_normal(39)
    x0[1:27:3] = 1e-5 * rng.standard_normal(9)
    xr, lr = reference_march(rom.K, rom.M, rom.C, rom.rho, rom.theta, cas, 0.15, Om, x0, v0, dt, n)
    m = Marcher(s, cas, 0.15, Om, x0, v0, dt, n, record_all(n, np.arange(39), np.arange(9)),
                direction_tol=1e-10).advance(n).result()
    assert m.contact_steps > 20 and (lr > 0).sum(axis=1).max() >= 2  # several nodes at once
    scale = np.abs(xr).max()
    assert np.abs(m.displacement - xr).max() <= 1e-8 * scale
    # force sample i is lam at step i + 1, the reference's lams[i] is lam at step i
    assert np.abs(m.normal_force[:-1] - lr[1:]).max() <= 1e-6 * np.abs(lr).max()
    # constraint at every step against the casing module, multipliers >= 0
    d = casing_distance(Om * m.times, rom.theta, cas)
    assert (m.displacement[:, 0:27:3] - d).max() <= 1e-15
    assert m.normal_force.min() >= 0.0 and m.active_set_failures == 0


def test_time_step_above_the_stability_limit_is_refused():
    rom = standin_rom()
    s = rom_modal_system(rom)
    dt_crit = critical_time_step(s)
    w_max = np.sqrt(np.linalg.eigvals(np.linalg.solve(rom.M, rom.K)).real.max())
    assert dt_crit == pytest.approx(2.0 / w_max, rel=1e-9)  # modal damping does not lower it
    rec = Recording(start=1, stride=1, n_samples=1, dofs=np.array([0]), force_nodes=np.array([0]))
    with pytest.raises(ValueError, match=r"dt = .*dt_crit = "):
        march(s, CasingOptions(), 0.15, 1000.0, np.zeros(39), np.zeros(39), 1.01 * dt_crit, 10, rec)


def test_time_step_just_below_the_limit_stays_bounded():
    """At dt = 0.99 dt_crit the highest mode's discrete amplification is 1 (|z| = 1, undamped)
    or below: from a random state without contact nothing grows over 20000 steps."""
    K = np.diag([1.0, 4.0, 9.0, 16.0]) * 1e6
    M = np.eye(4)
    C = np.zeros((4, 4))
    s = modal_system(K, M, C, [0.25], [0.0])
    dt = 0.99 * critical_time_step(s)
    n = 20000
    x0 = np.array([1e-3, 2e-3, -1e-3, 1e-3])
    m = march(s, flat_wall(1.0), 0.0, 0.0, x0, np.zeros(4), dt, n, record_all(n, [0, 1, 2, 3]))
    x = m.displacement
    # discrete amplitude of the mode at w dt = 1.98 is x0 / sqrt(1 - (w dt / 2)^2) ~ 7 x0
    assert np.abs(x[n // 2:]).max() <= 1.01 * np.abs(x[:n // 2]).max()
    assert np.isfinite(x).all()


def test_more_than_twelve_contact_nodes_match_the_physical_coordinate_reference():
    """14 contact nodes take the kernel's general path (the 12-accumulator fast path stops at
    12): against the same numpy reference as above, with the same tolerances and reasons."""
    rom = standin_rom(n_boundary=14, n_modes=6)
    s = rom_modal_system(rom)
    cas = CasingOptions()
    Om, dt, n = 1500.0, 2e-6, 500
    rng = np.random.default_rng(2)
    nd, nb = rom.n_dof, 14
    x0 = np.zeros(nd)
    x0[0:3 * nb:3] = 3e-4
    x0[1:3 * nb:3] = 1e-5 * rng.standard_normal(nb)
    v0 = 0.05 * rng.standard_normal(nd)
    xr, lr = reference_march(rom.K, rom.M, rom.C, rom.rho, rom.theta, cas, 0.15, Om, x0, v0, dt, n)
    m = Marcher(s, cas, 0.15, Om, x0, v0, dt, n, record_all(n, np.arange(nd), np.arange(nb)),
                direction_tol=1e-10).advance(n).result()
    assert (lr > 0).sum(axis=1).max() >= 3 and (lr[:, 12:] > 0).any()  # nodes beyond the 12th in contact
    assert np.abs(m.displacement - xr).max() <= 1e-8 * np.abs(xr).max()
    assert np.abs(m.normal_force[:-1] - lr[1:]).max() <= 1e-6 * np.abs(lr).max()
    assert m.normal_force.min() >= 0.0 and m.active_set_failures == 0


def test_non_modal_damping_matches_an_ode_solver_without_contact():
    """A 4-dof chain with a dashpot between two masses only (C not diagonal in the modes):
    the kernel lags the off-diagonal modal damping (backward-difference velocity), a first-
    order error c dt / m = 2.5e-4 of the damping force per step; scipy's solve_ivp (RK45 at
    rtol 1e-10) is the reference. Over 10 periods of the slowest mode the response agrees
    to 1e-3 of its size, and it visibly differs from the same march with the off-diagonal
    damping dropped (which tests that the coupling is there at all)."""
    from scipy.integrate import solve_ivp

    k, m = 1e4, 1.0
    K = k * np.array([[2.0, -1, 0, 0], [-1, 2, -1, 0], [0, -1, 2, -1], [0, 0, -1, 1]])
    M = m * np.eye(4)
    C = np.zeros((4, 4))
    C[0, 0] = C[3, 3] = 5.0
    C[0, 3] = C[3, 0] = -5.0  # dashpot between dof 0 and 3
    s = modal_system(K, M, C, [0.25], [0.0])
    assert not s.is_modally_damped
    dt = 5e-5
    T = 2 * np.pi / s.omega.min()
    n = int(10 * T / dt)
    x0 = np.array([1e-3, 0.0, -5e-4, 2e-4])
    v0 = np.array([0.0, 0.05, 0.0, -0.02])
    mch = march(s, flat_wall(1.0), 0.0, 0.0, x0, v0, dt, n, record_all(n, [0, 1, 2, 3]))
    Minv = np.linalg.inv(M)
    sol = solve_ivp(lambda t, y: np.concatenate([y[4:], -Minv @ (K @ y[:4] + C @ y[4:])]), (0.0, n * dt),
                    np.concatenate([x0, v0]), t_eval=mch.times, rtol=1e-10, atol=1e-14, method="RK45")
    ref = sol.y[:4].T
    err = np.abs(mch.displacement - ref).max() / np.abs(ref).max()
    assert err <= 1e-3
    modal_only = march(modal_system(K, M, s.phi_t_m.T @ np.diag(np.diag(s.damping)) @ s.phi_t_m, [0.25], [0.0]),
                       flat_wall(1.0), 0.0, 0.0, x0, v0, dt, n, record_all(n, [0, 1, 2, 3]))
    assert np.abs(modal_only.displacement - ref).max() / np.abs(ref).max() > 30 * err


# ----------------------------------------------------------------------------------------
# Massless boundary (hbm.ti.march.massless_system)
# ----------------------------------------------------------------------------------------
def bilinear_parent(k=1e4, m=1.0, k_b=3e4, m_b=1e-9, k_t=2e5, k_z=3e5):
    """A contact node (r, theta, z) of tiny mass m_b tied by a spring k_b (radial) to a mass m
    on a spring k to ground: dof (r, theta, z, u). Its modes: sqrt(k / m) (the node follows
    the mass) and three at sqrt(k_. / m_b) (the node's own), which the massless model drops."""
    K = np.zeros((4, 4))
    K[0, 0], K[1, 1], K[2, 2] = k_b, k_t, k_z
    K[0, 3] = K[3, 0] = -k_b
    K[3, 3] = k + k_b
    M = np.diag([m_b, m_b, m_b, m])
    return K, M


def bilinear_exact(t, V, g, k, m, k_b):
    """Exact motion of the massless-node limit thrown from u = 0 at speed V towards a wall at g:
    free u = (V / w1) sin(w1 t) until u = g; then the node rests on the wall, the mass swings on
    k + k_b about u_e = k_b g / (k + k_b) (lam = k_b (u - g) >= 0) until u = g again; free
    again (elastic: it leaves with the speed it came). Returns (u, r, lam) on t (one bounce)."""
    w1, w2 = math.sqrt(k / m), math.sqrt((k + k_b) / m)
    t1 = math.asin(g * w1 / V) / w1
    v1 = math.sqrt(V ** 2 - (w1 * g) ** 2)
    ue = k_b * g / (k + k_b)
    # in contact: u - ue = (g - ue) cos(w2 s) + v1 / w2 sin(w2 s) = A cos(w2 s - phi); back at g at s2
    A, phi = math.hypot(g - ue, v1 / w2), math.atan2(v1 / w2, g - ue)
    s2 = 2 * phi / w2
    s = t - t1
    u = np.where(t < t1, V / w1 * np.sin(w1 * t), ue + A * np.cos(w2 * s - phi))
    after = s > s2
    u = np.where(after, g * np.cos(w1 * (s - s2)) - v1 / w1 * np.sin(w1 * (s - s2)), u)
    contact = (t >= t1) & ~after
    return u, np.where(contact, g, u), np.where(contact, k_b * (u - g), 0.0), t1 + s2


def test_massless_impact_follows_the_exact_bilinear_oscillator():
    """The massless scheme on the node-spring-mass system: the node never enters the wall,
    lam >= 0, and the mass follows the exact piecewise-linear solution. The contact force is
    continuous (it grows from 0 as the mass compresses k_b), so central differences keep
    their second order: |u - u_exact| <= (w2 dt)^2 V / w1 (1e-6 V / w1 here), measured 9e-8;
    the parent's node mass perturbs the kept mode by m_b / m = 1e-9."""
    k, m, k_b, g, V = 1e4, 1.0, 3e4, 1e-3, 0.3
    K, M = bilinear_parent(k, m, k_b)
    full = modal_system(K, M, np.zeros((4, 4)), [0.25], [0.0])
    s = massless_system(full, cutoff=1e3)  # keeps sqrt(k / m) = 100 rad/s, drops the node's modes
    assert s.n_modes == 1 and s.is_massless
    w2 = math.sqrt((k + k_b) / m)
    dt = 1e-3 / w2
    n = int(0.04 / dt)
    m_ = march(s, flat_wall(g), 0.0, 0.0, np.zeros(4), np.array([V, 0, 0, V]), dt, n, record_all(n, [0, 3]))
    u_ex, r_ex, lam_ex, t_out = bilinear_exact(m_.times, V, g, k, m, k_b)
    assert m_.times[-1] > t_out + 0.005  # the bounce is over and the mass is free again
    scale = V / math.sqrt(k / m)
    assert np.abs(m_.displacement[:, 1] - u_ex).max() <= (w2 * dt) ** 2 * scale
    assert np.abs(m_.displacement[:, 0] - r_ex).max() <= (w2 * dt) ** 2 * scale
    assert m_.displacement[:, 0].max() <= g * (1 + 1e-15) and m_.max_penetration <= 1e-15 * g
    assert m_.min_multiplier >= 0.0 and m_.normal_force.min() >= 0.0
    # lam = k_b (u - g): the same second-order error, times k_b (measured 2e-7 k_b g)
    assert np.abs(m_.normal_force[:, 0] - lam_ex).max() <= k_b * (w2 * dt) ** 2 * scale
    # elastic: the mass leaves the wall with the speed it came with (energy 1/2 m V^2 kept)
    u = m_.displacement[m_.times > t_out + 1e-3, 1]
    E = 0.5 * k * u[1:-1] ** 2 + 0.5 * m * ((u[2:] - u[:-2]) / (2 * dt)) ** 2
    assert np.abs(E / (0.5 * m * V ** 2) - 1).max() <= 1e-6  # (w1 dt)^2 = 6e-9 plus the bounce's O(dt^2)


def test_massless_contact_conserves_the_energy_of_a_two_mass_interior():
    """Node-spring-mass-spring-mass: repeated bounces off the wall. The massless model is
    conservative (the contact force is that of the spring k_b between the mass and the wall),
    so its energy 1/2 v^T M v + 1/2 x^T K x + 1/2 lam^2 / k_b (the compressed spring) stays
    at its initial value up to central differences' O((w dt)^2) oscillation (w dt = 2e-3:
    1e-5; tolerance 1e-4), no penetration, lam >= 0, many contact steps."""
    k, m, k_b, k2, m2, g = 1e4, 1.0, 3e4, 2e4, 0.5, 5e-4
    K4, M4 = bilinear_parent(k, m, k_b)
    K = np.zeros((5, 5))
    K[:4, :4] = K4
    K[3, 3] += k2
    K[3, 4] = K[4, 3] = -k2
    K[4, 4] = k2
    M = np.diag(np.concatenate([np.diag(M4), [m2]]))
    s = massless_system(modal_system(K, M, np.zeros((5, 5)), [0.25], [0.0]), cutoff=1e4)
    assert s.n_modes == 2
    w_c = 2.0 / critical_time_step(s)  # the in-contact frequency bounds the step
    dt = 2e-3 / w_c
    n = int(0.2 / dt)
    x0 = np.zeros(5)
    v0 = np.array([0.2, 0, 0, 0.2, -0.1])
    mch = march(s, flat_wall(g), 0.0, 0.0, x0, v0, dt, n, record_all(n, [0, 1, 2, 3, 4]))
    x = mch.displacement
    lam = mch.normal_force[:, 0]
    # u, u2 and their centred velocities; the node's static position is not a state
    u = x[:, 3:]
    v = (u[2:] - u[:-2]) / (2 * dt)
    Kin = K[3:, 3:].copy()
    Kin[0, 0] = k + k2  # the mass sees k to ground and k2; k_b is the wall spring below
    E = (0.5 * np.einsum("ti,ij,tj->t", v, M[3:, 3:], v) + 0.5 * np.einsum("ti,ij,tj->t", u[1:-1], Kin, u[1:-1])
         + 0.5 * k_b * (u[1:-1, 0] - x[1:-1, 0]) ** 2)
    E0 = 0.5 * (m * 0.2 ** 2 + m2 * 0.1 ** 2)
    assert mch.contact_steps > 1000
    assert np.abs(E / E0 - 1).max() <= 1e-4
    assert x[:, 0].max() <= g * (1 + 1e-15) and lam.min() >= 0.0 and mch.min_multiplier >= 0.0
    # the multiplier is the force of the wall spring at the same step (massless: a static balance)
    assert np.abs(lam - k_b * (u[:, 0] - x[:, 0])).max() <= 1e-6 * np.abs(lam).max()


def test_massless_time_step_limit_includes_the_contact_stiffness():
    """In contact the massless node pins the mass to the wall through k_b: the kept mode's
    frequency rises from sqrt(k / m) to sqrt((k + k_b) / m), and that is the limit."""
    k, m, k_b = 1e4, 1.0, 3e4
    K, M = bilinear_parent(k, m, k_b)
    s = massless_system(modal_system(K, M, np.zeros((4, 4)), [0.25], [0.0]), cutoff=1e3)
    assert critical_time_step(s) == pytest.approx(2.0 / math.sqrt((k + k_b) / m), rel=1e-6)
    rec = record_all(1, [0])
    with pytest.raises(ValueError, match="dt_crit"):
        march(s, flat_wall(1e-3), 0.0, 0.0, np.zeros(4), np.zeros(4), 1.01 * critical_time_step(s), 1, rec)
