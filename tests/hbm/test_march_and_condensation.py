"""hbm.ti.march (modal system, step compliance, critical time step, decay time, final state)
and hbm.harmonic.condensation (static force, pole refusal) on cases the other tests leave
open, each against a reference written here: a dense physical-coordinate formula, the
amplification matrix of the recurrence, roots of the characteristic polynomial, closed-form
oscillators, a dense full solve (one test, marked as such, checks the final state against
the kernel's own record of the last step).
"""
import math

import numpy as np
import pytest
import scipy.linalg as sla

from hbm.harmonic.condensation import CondensedModel, HarmonicForcing, linear_block_inverse
from hbm.harmonic.fourier import FourierBasis
from hbm.linalg.errors import SingularMatrixError
from hbm.options import CasingOptions
from hbm.ti.march import (Recording, critical_time_step, march, massless_system, modal_system,
                          step_compliance)


def _spd(n, rng, scale):
    X = rng.standard_normal((n, n))
    return scale * (X @ X.T / n + 0.5 * np.eye(n))


def test_step_compliance_is_the_centred_schemes_impulse_map_in_physical_coordinates():
    """Central differences with a centred velocity in physical coordinates,
    M (x+ - 2x + x-) / dt^2 + C (x+ - x-) / (2 dt) + K x = f, move x+ by
    dt^2 (M + dt C / 2)^-1 f per unit force f: A_rr and A_rtheta are its (r_j, r_k) and
    (r_j, theta_k) entries. Two contact nodes, 8 dof, modal damping of 20 % at a step 0.9 of
    the limit (xi w dt up to 0.36: the damping factor is far from 1)."""
    rng = np.random.default_rng(7)
    K, M = _spd(8, rng, 1e6), _spd(8, rng, 1.0)
    w2, phi = sla.eigh(K, M)
    C = M @ phi @ np.diag(2 * 0.2 * np.sqrt(w2)) @ phi.T @ M  # modal damping, xi = 0.2
    system = modal_system(K, M, C, [0.2, 0.21], [0.0, 0.05])
    dt = 0.9 * 2.0 / math.sqrt(w2.max())
    A = dt * dt * np.linalg.inv(M + 0.5 * dt * C)
    a_rr, a_rt = step_compliance(system, dt)
    scale = np.abs(A).max()
    np.testing.assert_allclose(a_rr, A[0:6:3, 0:6:3], rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(a_rt, A[0:6:3, 1:6:3], rtol=0, atol=1e-12 * scale)
    assert abs(a_rt[0, 1] - a_rt[1, 0]) > 1e-3 * scale  # not symmetric: the order of r and theta matters


def _amplification_radius(w, D, dt):
    """Spectral radius of the modal recurrence with the diagonal damping centred and the
    off-diagonal part lagged on the backward-difference velocity:
    (1 + a_k) q+_k = (2 - w_k^2 dt^2) q_k - (1 - a_k) q-_k - dt^2 sum_l D_kl (q_l - q-_l) / dt,
    a_k = D_kk dt / 2."""
    n = len(w)
    a = 0.5 * np.diag(D) * dt
    off = (D - np.diag(np.diag(D))) * dt / (1 + a)[:, None]
    top = np.hstack([np.diag((2 - (w * dt) ** 2) / (1 + a)) - off, -np.diag((1 - a) / (1 + a)) + off])
    T = np.vstack([top, np.hstack([np.eye(n), np.zeros((n, n))])])
    return np.abs(np.linalg.eigvals(T)).max()


def test_critical_step_with_non_modal_damping_is_the_documented_bound_and_stable():
    """Modes 1000, 2000, 3000 rad/s (K = diag(w^2), M = I), damping coupling modes 1 and 3
    (D = [[4000, 0, 3000], [0, 1000, 0], [3000, 0, 6000]] 1/s, positive definite). By hand,
    z_k = sum_l |D_kl| / (2 w_k) = 3.5, 0.25, 1.5 and dt_k = 2 / w_k (sqrt(1 + z_k^2) - z_k) =
    2.8011e-4, 7.8078e-4, 2.0185e-4 s: dt_crit = 2.0185e-4 s. The recurrence is stable there
    (its amplification matrix, built here); 2 / w_max = 6.67e-4 s is not."""
    w = np.array([1000.0, 2000.0, 3000.0])
    D = np.array([[4000.0, 0.0, 3000.0], [0.0, 1000.0, 0.0], [3000.0, 0.0, 6000.0]])
    system = modal_system(np.diag(w ** 2), np.eye(3), D, [0.2], [0.0])
    assert not system.is_modally_damped
    dt = critical_time_step(system)
    assert dt == pytest.approx(2.0 / 3000.0 * (math.sqrt(1 + 1.5 ** 2) - 1.5), rel=1e-12)
    assert dt == pytest.approx(2.0185e-4, rel=1e-4)
    assert _amplification_radius(w, D, 0.999 * dt) <= 1.0 + 1e-12
    assert _amplification_radius(w, D, 0.999 * 2.0 / w.max()) > 1.01  # the undamped limit is not stable here


def test_slowest_decay_time_of_an_overdamped_mode():
    """Modes 1000, 2000, 3000 rad/s with damping ratios 0.9, 1.5, 0.5: the decay rates are
    the slowest |Re s| of s^2 + 2 xi w s + w^2 (np.roots): 900, 2000 (1.5 - sqrt(1.25)) = 763.9
    (overdamped), 1500 1/s; the slowest is the overdamped mode's."""
    w, xi = np.array([1000.0, 2000.0, 3000.0]), np.array([0.9, 1.5, 0.5])
    system = modal_system(np.diag(w ** 2), np.eye(3), np.diag(2 * xi * w), [0.2], [0.0])
    rates = [np.abs(np.roots([1.0, 2 * x * v, v * v]).real).min() for x, v in zip(xi, w)]
    assert rates[1] == pytest.approx(2000.0 * (1.5 - math.sqrt(1.25)), rel=1e-12)
    assert system.slowest_decay_time() == pytest.approx(1.0 / min(rates), rel=1e-12)


def _no_contact():
    return CasingOptions(clearance=1.0, penetration=-1.0)  # a flat wall 1 m away


def test_final_state_of_a_free_oscillator():
    """Undamped modes 1000, 2000, 3000 rad/s (K = diag(w^2), M = I), released from
    x0 = (1, 2, 3) mm at rest, no contact: x(t) = x0 cos(w t), v(t) = -x0 w sin(w t). With
    w dt <= 0.003 the backward-difference velocity is within 1e-2 relative of it."""
    w = np.array([1000.0, 2000.0, 3000.0])
    system = modal_system(np.diag(w ** 2), np.eye(3), np.zeros((3, 3)), [0.2], [0.0])
    dt, n = 1e-6, 1200
    x0 = np.array([1e-3, 2e-3, 3e-3])
    rec = Recording(start=1, stride=1, n_samples=1, dofs=np.array([0]), force_nodes=np.array([0]))
    m = march(system, _no_contact(), 0.0, 0.0, x0, np.zeros(3), dt, n, rec)
    t = n * dt
    np.testing.assert_allclose(m.x_final, x0 * np.cos(w * t), rtol=0, atol=1e-2 * 3e-3)
    v = -x0 * w * np.sin(w * t)
    np.testing.assert_allclose(m.v_final, v, rtol=0, atol=1e-2 * np.abs(v).max())


def test_massless_cutoff_keeps_the_mode_at_the_cutoff():
    # "modes with w_k <= cutoff kept": a cut-off equal to the second frequency keeps two
    w = np.array([1000.0, 2000.0, 3000.0])
    system = modal_system(np.diag(w ** 2), np.eye(3), np.zeros((3, 3)), [0.2], [0.0])
    cut = massless_system(system, float(system.omega[1]))
    np.testing.assert_allclose(cut.omega, [1000.0, 2000.0], rtol=1e-12)
    # the dropped mode's static share of K^-1 on the boundary: 1 / 3000^2 on dof 2
    np.testing.assert_allclose(cut.residual, np.diag([0.0, 0.0, 1.0 / 9e6]), rtol=0, atol=1e-22)


def test_massless_final_state_carries_the_friction_force():
    """A contact node (m = 1 kg; r: k = 1e4 N/m, theta: k_t = 4e4, z: 9e4) pushed onto a wall
    at r = 0 by a mass m2 = 0.5 kg on a spring k2 = 1e4 N/m (released from X = 1 mm), sliding
    along +theta (s = +1, Omega > 0). The massless model keeps the lowest mode only: the
    theta dof carries no mass, so at every step k_t x_theta = -mu lam (friction on the blade
    against the sliding), with lam the static contact force of that step (the massless
    scheme solves the contact at the step itself: the last sample holds the final step's)."""
    k, k_t, k_z, m2, k2, X, mu = 1e4, 4e4, 9e4, 0.5, 1e4, 1e-3, 0.3
    K = np.zeros((4, 4))
    K[:3, :3] = np.diag([k + k2, k_t, k_z])
    K[0, 3] = K[3, 0] = -k2
    K[3, 3] = k2
    M = np.diag([1.0, 1.0, 1.0, m2])
    full = modal_system(K, M, np.zeros((4, 4)), [0.25], [0.0], rotation=1)
    system = massless_system(full, float(full.omega[0]))
    assert system.n_modes == 1
    dt = 1e-5
    n = 400  # 4 ms: the pushing mass stays on (lam > 0)
    rec = Recording(start=1, stride=1, n_samples=n, dofs=np.array([0, 1]), force_nodes=np.array([0]))
    r = march(system, CasingOptions(clearance=0.0, penetration=0.0), mu, 1000.0,
              np.array([0.0, 0.0, 0.0, X]), np.zeros(4), dt, n, rec)
    lam = r.normal_force[-1, 0]  # the contact force at step n
    assert lam > 0.1 * k2 * X
    assert r.x_final[1] == pytest.approx(-mu * lam / k_t, rel=1e-9)
    assert r.x_final[0] == pytest.approx(0.0, abs=1e-12 * X)
    np.testing.assert_allclose(r.displacement[:, 1] * k_t, -mu * r.normal_force[:, 0], rtol=1e-9)


def _chain(n=5, seed=2):
    """A general (not Craig-Bampton) symmetric model: K couples every dof, n dof."""
    rng = np.random.default_rng(seed)
    return _spd(n, rng, 1e6), _spd(n, rng, 1.0), _spd(n, rng, 10.0)


def test_static_condensed_force_of_a_model_whose_stiffness_couples_the_linear_dof():
    """harmonic-0 forcing on every dof of a 5-dof model (2 kept): the condensed static problem
    Z0 x_n = force_0 must give the kept part of the full solution K^-1 f, and recover() the rest
    (in a Craig-Bampton ROM K_nl = 0 and the coupling term vanishes; here it does not)."""
    K, M, C = _chain()
    f = np.array([1.0, -2.0, 3.0, 0.5, -1.5])
    nl = np.array([0, 1])
    model = CondensedModel(K, M, C, nl, FourierBasis(2, 8), HarmonicForcing(f, 0))
    op = model.operator(300.0)
    x = np.linalg.solve(K, f)
    np.testing.assert_allclose(np.linalg.solve(op.Z0, op.force[0]), x[nl], rtol=1e-12)
    full = model.recover(np.vstack([x[nl], np.zeros((4, 2))]), 300.0)
    np.testing.assert_allclose(full[0], x, rtol=1e-12)


@pytest.mark.parametrize("small, refused", [(1e-8, False), (1e-11, True)])
def test_a_linear_block_this_ill_conditioned_is_refused(small, refused):
    """Z_ll = diag(small, 1): cond_1 = 1 / small by hand; eps cond = 2.2e-8 is accepted,
    2.2e-5 is above MAX_POLE_ERROR = 1e-6 and refused, naming harmonic 2."""
    Zll = np.array([np.eye(2), np.diag([small, 1.0])], dtype=complex)
    if refused:
        with pytest.raises(SingularMatrixError, match=r"harmonic 2 .*cond_1\(Z_ll\) = 1\.000e\+11"):
            linear_block_inverse(Zll, 100.0)
    else:
        np.testing.assert_allclose(linear_block_inverse(Zll, 100.0)[1], np.diag([1.0 / small, 1.0]), rtol=1e-15)


def test_massless_critical_step_takes_the_worse_sliding_direction():
    """One kept mode (w = 100 rad/s, boundary rows pr = 1, pt = -2 per unit modal
    coordinate) and a massless boundary (G_rr = 1e-4, G_rt = 0.4e-4 m/N), mu = 0.5. In
    contact, sliding along s e_theta, the static force lam = (pr q - d) / (G_rr + s mu G_rt)
    acts on the mode as -(pr + s mu pt) lam: the mode sees, by hand,
    s = 0: 1e4 + 1 / 1e-4 = 2e4; s = +1: 1e4 + 0 / 1.2e-4 = 1e4; s = -1: 1e4 + 2 / 0.8e-4 =
    3.5e4 1/s^2. Central differences need dt < 2 / sqrt(3.5e4) = 1.069e-2 s; the sense of
    rotation may be either, and the -theta sliding decides here."""
    from hbm.ti.march import ModalSystem

    residual = np.array([[1e-4, 0.4e-4, 0.0], [0.4e-4, 3e-4, 0.0], [0.0, 0.0, 2e-4]])
    for rotation in (1, -1):
        system = ModalSystem(omega=np.array([100.0]), phi=np.array([[1.0], [-2.0], [0.0]]),
                             phi_t_m=np.array([[1.0, -2.0, 0.0]]), damping=np.zeros((1, 1)), rho=np.array([0.2]),
                             theta=np.array([0.0]), residual=residual, rotation=rotation)
        assert critical_time_step(system, 0.5) == pytest.approx(2.0 / math.sqrt(3.5e4), rel=1e-12)
        assert critical_time_step(system, 0.0) == pytest.approx(2.0 / math.sqrt(2e4), rel=1e-12)


def test_poincare_sections_up_to_the_last_step():
    """Free undamped oscillator (r: w = 1000 rad/s) from x0 = 1 mm at rest: central differences
    started with the Taylor step give exactly x_n = x0 cos(W n dt), cos(W dt) = 1 - (w dt)^2 / 2.
    Sections from step 10 every 30 steps of 100: steps 10, 40, 70 and 100 (the last step)."""
    w = np.array([1000.0, 2000.0, 3000.0])
    system = modal_system(np.diag(w ** 2), np.eye(3), np.zeros((3, 3)), [0.2], [0.0])
    dt, n = 1e-4, 100
    rec = Recording(start=10, stride=1, n_samples=1, dofs=np.array([0]), force_nodes=np.array([0]),
                    section_stride=30)
    m = march(system, _no_contact(), 0.0, 0.0, np.array([1e-3, 0.0, 0.0]), np.zeros(3), dt, n, rec)
    steps = np.array([10, 40, 70, 100])
    np.testing.assert_allclose(m.section_times, steps * dt, rtol=1e-14)
    W = math.acos(1.0 - 0.5 * (w[0] * dt) ** 2) / dt
    np.testing.assert_allclose(m.sections[:, 0], 1e-3 * np.cos(W * steps * dt), rtol=0, atol=1e-14)


def test_slowest_decay_time_with_non_modal_damping():
    """Random SPD K, M and a damping C that is not modal: the decay rates are -Re s of the
    quadratic eigenproblem (s^2 M + s C + K) x = 0, solved here as the generalized pencil
    [[0, I], [-K, -C]] - s [[I, 0], [0, M]] in physical coordinates (scipy.linalg.eig)."""
    rng = np.random.default_rng(11)
    K, M, C = _spd(6, rng, 1e6), _spd(6, rng, 1.0), _spd(6, rng, 50.0)
    system = modal_system(K, M, C, [0.2, 0.3], [0.0, 0.1])
    assert not system.is_modally_damped
    n = 6
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-K, -C]])
    B = np.block([[np.eye(n), np.zeros((n, n))], [np.zeros((n, n)), M]])
    s = sla.eig(A, B, right=False)
    assert s.real.max() < 0.0
    assert system.slowest_decay_time() == pytest.approx(1.0 / np.abs(s.real).min(), rel=1e-9)


def test_massless_final_state_is_the_last_recorded_step_with_sliding_along_theta_and_z():
    """Consistency of the march's two reconstructions of x_n (the final state, assembled in
    python from the last contact forces, and the kernel's recorded displacement of the last
    step) where the contact node slides along theta and z at once: node (r, theta, z) on a
    wall at r = 0, pressed by m2 (r chain as above), its z dof tied to a mass m3 = 1 kg by a
    stiff spring (1e5 N/m; ground 2e3 N/m), released with v_z = 0.2 m/s; Omega = 1 rad/s
    (tip speed 0.25 m/s, comparable). The massless model keeps the modes up to the r chain's
    lowest: the z chain's lower mode moves the node, its upper one is static (residual)."""
    k, k_t, m2, k2, kz, k3, X, mu = 1e4, 4e4, 0.5, 1e4, 2e3, 1e5, 1e-3, 0.3
    K = np.zeros((5, 5))
    K[:3, :3] = np.diag([k + k2, k_t, kz + k3])
    K[0, 3] = K[3, 0] = -k2
    K[3, 3] = k2
    K[2, 4] = K[4, 2] = -k3
    K[4, 4] = k3
    M = np.diag([1.0, 1.0, 1.0, m2, 1.0])
    full = modal_system(K, M, np.zeros((5, 5)), [0.25], [0.0], rotation=1)
    w_r = math.sqrt(2e4 - math.sqrt(2e8))  # the r chain's lower mode, by hand: 76.5 rad/s
    system = massless_system(full, w_r * (1 + 1e-9))
    assert system.n_modes == 2 and abs(system.residual[2, 2]) > 0  # z chain's upper mode dropped
    dt, n = 1e-5, 400
    rec = Recording(start=n, stride=1, n_samples=1, dofs=np.array([0, 1, 2]), force_nodes=np.array([0]))
    v0 = np.array([0.0, 0.0, 0.2, 0.0, 0.2])
    r = march(system, CasingOptions(clearance=0.0, penetration=0.0), mu, 1.0, np.array([0.0, 0.0, 0.0, X, 0.0]),
              v0, dt, n, rec)
    lam, ft, fz = r.normal_force[0, 0], r.friction_force[0, 0, 0], r.friction_force[0, 0, 1]
    assert lam > 0 and ft < 0 and fz < -0.1 * mu * lam  # sliding along +theta and +z
    assert math.hypot(ft, fz) == pytest.approx(mu * lam, rel=1e-12)
    np.testing.assert_allclose(r.x_final[:3], r.displacement[0], rtol=0, atol=1e-12 * X)
