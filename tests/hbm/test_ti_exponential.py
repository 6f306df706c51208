"""The exponential scheme (hbm.ti.march.recurrence, exponential=True): each mode's free motion
exact over a step, Carpenter's forward-increment multipliers for the contact.

References: the matrix exponential of the first-order system (scipy), the closed-form
solutions of the constrained 1- and 2-dof problems of tests/hbm/test_time_integration.py,
and the exact energy of a free state (no discrete invariant: the scheme has none of its own).
"""
import math

import numpy as np
import pytest
import scipy.linalg

from hbm.options import CasingOptions
from hbm.ti.march import Recording, critical_time_step, march, massless_system, modal_system, recurrence
from rom.model import modal_damping


def flat_wall(gap):
    return CasingOptions(clearance=gap, penetration=-gap)


def record_all(n_steps, dofs, nodes=(0,)):
    return Recording(start=1, stride=1, n_samples=n_steps, dofs=np.asarray(dofs), force_nodes=np.asarray(nodes))


def test_free_motion_is_exact_at_any_step_overdamped_modes_included():
    """A 4-dof chain with modal damping ratios 0.02, 0.3, 1.0 (critical) and 2.5 (cos becomes
    cosh), marched at 4 times the central-difference limit: every step equals exp(A t) of
    the first-order system to round-off (measured 1e-13 of the motion), where central
    differences refuse the step."""
    K = 1e4 * np.array([[2.0, -1.0, 0.0, 0.0], [-1.0, 2.0, -1.0, 0.0], [0.0, -1.0, 2.0, -1.0], [0.0, 0.0, -1.0, 1.0]])
    M = np.diag([1.0, 0.5, 2.0, 1.0])
    C, _ = modal_damping(K, M, np.array([0.02, 0.3, 1.0, 2.5]))
    s = modal_system(K, M, C, [0.25], [0.0])
    dt = 4.0 * critical_time_step(s)
    assert critical_time_step(s, exponential=True) == math.inf
    n = 200
    x0 = np.array([1e-3, -2e-3, 5e-4, 1e-3])
    v0 = np.array([0.1, 0.0, -0.2, 0.05])
    m = march(s, flat_wall(1.0), 0.0, 0.0, x0, v0, dt, n, record_all(n, [0, 1, 2, 3]), exponential=True)
    A = np.block([[np.zeros((4, 4)), np.eye(4)], [-np.linalg.solve(M, K), -np.linalg.solve(M, C)]])
    step = scipy.linalg.expm(A * dt)
    z = np.concatenate([x0, v0])
    exact = []
    for _ in range(n):
        z = step @ z
        exact.append(z[:4])
    exact = np.array(exact)
    assert np.abs(m.displacement - exact).max() <= 1e-10 * np.abs(exact).max()
    with pytest.raises(ValueError, match="scheme = exponential is stable at any dt"):
        march(s, flat_wall(1.0), 0.0, 0.0, x0, v0, dt, n, record_all(n, [0, 1, 2, 3]))


def test_its_contact_compliance_is_positive_and_tends_to_centred_differences():
    """s_k = (1 - c1 + c2) / w^2 >= 0 at any w dt (a positive contact compliance), and both
    recurrences tend to dt^2 for w dt -> 0 (relative difference O((w dt)^2))."""
    K = np.diag([1.0, 1e2, 1e4, 1e6]) * 1e4
    s = modal_system(K, np.eye(4), modal_damping(K, np.eye(4), np.full(4, 0.05))[0], [0.25], [0.0])
    for dt in (1e-6, 1e-4, 1e-2):
        c1, c2, gain = recurrence(s, dt, exponential=True)
        assert (gain > 0).all()
        cd = recurrence(s, dt)[2]
        h = s.omega * dt
        small = h < 1e-2
        assert np.all(np.abs(gain[small] / cd[small] - 1.0) <= h[small] ** 2)


def test_exponential_scheme_needs_modal_damping_and_the_full_system():
    K = np.diag([1.0, 4.0, 9.0, 16.0]) * 1e6
    C = np.zeros((4, 4))
    C[0, 1] = C[1, 0] = 10.0
    C[0, 0] = C[1, 1] = 20.0
    coupled = modal_system(K, np.eye(4), C, [0.25], [0.0])
    with pytest.raises(ValueError, match="needs modal damping"):
        critical_time_step(coupled, exponential=True)
    light = modal_system(K, np.eye(4), np.zeros((4, 4)), [0.25], [0.0])
    with pytest.raises(ValueError, match="full modal system"):
        critical_time_step(massless_system(light, 2.5e3), exponential=True)


def test_single_impact_is_perfectly_plastic_and_exact():
    """The 1-dof oscillator (w = 100 rad/s) thrown at a wall at gap g with speed V = 2 g w, at
    ten times the step of the central-difference test: free flight exact, the multiplier
    stops the mass on the wall and holds it there one step more, and from there it swings
    freely through those two points, exactly (the grazings of later periods clip it by
    O((w dt)^2)). The impact is late by at most ~1.5 dt: |x - x_exact| <= 2 g w dt."""
    k, mass, g = 1e4, 1.0, 1e-3
    w = math.sqrt(k / mass)
    K = np.diag([k, 4e4, 9e4])
    s = modal_system(K, np.eye(3) * mass, np.zeros((3, 3)), [0.25], [0.0])
    dt = 1e-2 / w
    V = 2.0 * g * w
    n = int(5 * 2 * math.pi / w / dt)
    m = march(s, flat_wall(g), 0.0, 0.0, np.zeros(3), np.array([V, 0, 0]), dt, n, record_all(n, [0, 1, 2]),
              exponential=True)
    t, x = m.times, m.displacement[:, 0]
    ts = math.asin(g * w / V) / w
    exact = np.where(t < ts, V / w * np.sin(w * t), g * np.cos(w * (t - ts)))
    assert np.abs(x - exact).max() <= 2.0 * g * w * dt
    assert x.max() <= g * (1 + 1e-15) and m.max_penetration <= 1e-15 * g
    assert m.min_multiplier >= 0.0 and m.normal_force.min() >= 0.0
    hit = np.argmax(x >= g)
    assert x[hit + 1] == pytest.approx(g, rel=1e-15) and x[hit + 2] < g
    # the first period after the impact: the free motion through (t_h, g) and (t_h + dt, g),
    # turning at t_h + dt / 2, exact on the grid to round-off
    one = slice(hit, hit + int(0.9 * 2 * math.pi / w / dt))
    swing = g * np.cos(w * (t[one] - t[hit] - 0.5 * dt)) / math.cos(0.5 * w * dt)
    assert np.abs(x[one] - swing).max() <= 1e-12 * g
    # the impulse of the impact stops the mass: sum lam dt = momentum at impact m v*
    v_star = math.sqrt(V ** 2 - (w * g) ** 2)
    assert m.normal_force[:, 0].sum() * dt == pytest.approx(mass * v_star, rel=2 * w * dt)


def _free_energy(s, x_now, x_before, dt):
    """Energy of the undamped free state whose exact motion passes x_before, then x_now one
    step later, J: each mode's velocity from q_{m-1} = q_m cos(w dt) - v / w sin(w dt)."""
    q, qm = s.phi_t_m @ x_now, s.phi_t_m @ x_before
    w = s.omega
    v = w * (q * np.cos(w * dt) - qm) / np.sin(w * dt)
    return 0.5 * float(np.sum(v * v + (w * q) ** 2))


def test_two_dof_impact_loses_exactly_the_kinetic_energy_of_the_struck_mass():
    """ground -k- m1 -k2- m2, wall at g on m1, at a step 20 times the central-difference
    test's: only m1 stops at the impact; the energy lost is 1/2 m1 v1*^2 (v1* from the exact
    modal solution at the first contact) to O(w_max dt), and the free motion before and
    after keeps its energy exactly (no discrete energy error to allow for)."""
    k, m1, m2, k2, g = 1e4, 1.0, 0.5, 3e4, 1e-3
    K = np.zeros((4, 4))
    K[:3, :3] = np.diag([k + k2, 4e4, 9e4])
    K[0, 3] = K[3, 0] = -k2
    K[3, 3] = k2
    M = np.diag([m1, m1, m1, m2])
    s = modal_system(K, M, np.zeros((4, 4)), [0.25], [0.0])
    w_max = s.omega.max()
    dt = 2e-2 / w_max
    x0 = np.zeros(4)
    v0 = np.array([0.3, 0.0, 0.0, -0.2])
    n = int(0.3 / dt)
    m = march(s, flat_wall(g), 0.0, 0.0, x0, v0, dt, n, record_all(n, [0, 1, 2, 3]), exponential=True)
    x = np.vstack([x0, m.displacement])
    q0, qd0 = s.phi_t_m @ x0, s.phi_t_m @ v0
    xr = lambda t: s.phi[0] @ (q0 * np.cos(s.omega * t) + qd0 / s.omega * np.sin(s.omega * t))
    first = np.argmax(x[:, 0] >= g)  # first step at the wall
    lo, hi = (first - 1) * dt, first * dt
    assert xr(lo) < g <= xr(hi)
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if xr(mid) < g else (lo, mid)
    v1 = s.phi[0] @ (-q0 * s.omega * np.sin(s.omega * lo) + qd0 * np.cos(s.omega * lo))
    E0 = 0.5 * float(v0 @ M @ v0)
    lam = m.normal_force[:, 0]
    assert _free_energy(s, x[first - 1], x[first - 2], dt) == pytest.approx(E0, rel=1e-12)
    # the first free step after the impact (the multiplier needs one or two steps)
    free = first + 1 + np.argmax(lam[first:] == 0)
    after = _free_energy(s, x[free + 1], x[free], dt)
    assert E0 - after == pytest.approx(0.5 * m1 * v1 ** 2, rel=5 * w_max * dt)
    assert x[:, 0].max() <= g * (1 + 1e-15) and lam.min() >= 0.0 and m.min_multiplier >= 0.0


def test_the_stage_warns_where_the_step_leaves_the_measured_accurate_range():
    """The coarse rotor 67 ROM: half the period of its highest mode, pi / w_max, from the
    generalised eigenproblem of K and M (scipy, not the march's modal system); the ti stage's
    warning is silent at 0.9 of it and for Carpenter, and above it names the ratio and the
    largest step within the range."""
    from hbm.ti.march import rom_modal_system
    from pipelines.stages.ti import exponential_step_warning
    from support import coarse_rom

    rom = coarse_rom()
    limit = math.pi / math.sqrt(scipy.linalg.eigh(rom.K, rom.M, eigvals_only=True).max())
    assert 1.35e-6 < limit < 1.45e-6  # 1.40e-6 s (README, *Time integration*: the limits of the ROMs)
    system = rom_modal_system(rom)
    assert exponential_step_warning("exponential", 0.9 * limit, system) is None
    assert exponential_step_warning("carpenter", 1.5 * limit, system) is None
    line = exponential_step_warning("exponential", 1.5 * limit, system)
    assert f"is 1.50 times half the period of this ROM's highest mode, pi / w_max = {limit:.3g} s" in line
    assert f"[ti] dt <= {limit:.3g} s" in line


def test_every_scheme_marches_with_the_one_compiled_step_loop():
    """Carpenter, exponential and massless marches hand the step loop arguments of the same
    types, so a process compiles it once (15.5 s of CPU on a Zen 3 host) and numba's cache
    holds one entry. The exponential recurrence's c1 came as a strided view (the .real of a
    complex array), another type to numba: a process that ran validation marches (Carpenter)
    and a sweep (exponential) compiled the loop twice."""
    from hbm.ti import kernel

    K = 1e4 * np.array([[2.0, -1.0, 0.0], [-1.0, 2.0, -1.0], [0.0, -1.0, 1.0]])
    s = modal_system(K, np.eye(3), modal_damping(K, np.eye(3), np.full(3, 0.02))[0], [0.25], [0.0])
    x0 = np.array([1e-3, 0.0, -1e-3])
    dt = 0.5 * critical_time_step(s)
    for system, exponential in ((s, False), (s, True), (massless_system(s, 50.0), False)):
        march(system, flat_wall(1.0), 0.1, 10.0, x0, 0.0 * x0, dt, 3, record_all(3, [0]), exponential=exponential)
    assert len(kernel.run_steps.signatures) == 1, kernel.run_steps.signatures
