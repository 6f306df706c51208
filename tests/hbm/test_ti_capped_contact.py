"""A step whose contact solve cannot converge is counted, kept in ti.h5 and named in the
run's log, never hidden.

One contact node whose mass couples its radial and tangential dof (M_rtheta = 0.9 kg
against M_rr = M_thetatheta = 1 kg): an explicit step's radial compliance with sliding
friction is B_rr + s mu B_rtheta, B = M^-1 (B_rr = 1 / 0.19, B_rtheta = -0.9 / 0.19), which
changes sign at mu = B_rr / |B_rtheta| = 1 / 0.9 = 1.11 for s = +1 (the sliding direction is
the casing's, s e_theta). Below it the node's multiplier is the positive solution of a
1 x 1 problem; above it a positive force pulls the node further into the casing, no
multiplier >= 0 removes the penetration, and the active set cycles until its cap. The
counts: none at mu = 0 and 0.9, some at mu = 1.4 (above the analytic limit), and the sweep's
warning names that speed.
"""
import numpy as np
import pytest

from hbm.options import CasingOptions, TimeIntegrationOptions
from hbm.ti.march import modal_system
from hbm.ti.sweep import SpeedResponse, _stack, simulate
from pipelines.stages.ti import capped_contact_warning
from rom.model import modal_damping

OMEGA = 50.0  # rad/s


def _speed(mu: float) -> SpeedResponse:
    M = np.array([[1.0, 0.9, 0.0], [0.9, 1.0, 0.0], [0.0, 0.0, 1.0]])  # kg, (r, theta, z)
    K = 1e6 * np.eye(3)  # N/m: periods ~ 1e-3 s against a revolution of 0.126 s
    C, _ = modal_damping(K, M, np.full(3, 0.05))
    system = modal_system(K, M, C, np.array([0.25]), np.array([0.0]), rotation=1)
    options = TimeIntegrationOptions(dt=1e-6, n_revolutions=4, n_keep=1, samples_per_revolution=16,
                                     stop_when_settled=False)
    return simulate(system, CasingOptions(), mu, OMEGA, options)


@pytest.mark.parametrize("mu", [0.0, 0.9])
def test_below_the_sign_change_every_contact_step_is_solved(mu):
    r = _speed(mu)
    assert r.contact_fraction > 0.01 and r.active_set_failures == 0


def test_above_it_the_capped_steps_are_counted_and_named():
    r = _speed(1.4)
    assert r.contact_fraction > 0.01 and r.active_set_failures > 0
    line = capped_contact_warning(_stack([_speed(0.0), r]))
    assert f"at 1 speed(s), rad/s: {OMEGA:.0f} ({r.active_set_failures} steps)" in line


def test_a_speed_resumed_from_an_older_file_is_unknown_not_clean():
    r = _speed(0.0)
    old = SpeedResponse(**{**r.__dict__, "active_set_failures": None})
    assert _stack([r, old]).active_set_failures.tolist() == [0, -1]


@pytest.mark.parametrize("mu, capped", [(0.0, False), (1.4, True)])
def test_a_validation_march_says_when_its_contact_was_capped(mu, capped):
    """The validation's march from an orbit (here rest, which the casing's lobes indent)
    counts the capped steps and its verdict names them, as a numerical failure."""
    from hbm.ti.validation import march_from_hbm

    M = np.array([[1.0, 0.9, 0.0], [0.9, 1.0, 0.0], [0.0, 0.0, 1.0]])
    K = 1e6 * np.eye(3)
    C, _ = modal_damping(K, M, np.full(3, 0.05))
    system = modal_system(K, M, C, np.array([0.25]), np.array([0.0]), rotation=1)
    ti = march_from_hbm(system, CasingOptions(), mu, np.zeros((3, 3)), OMEGA, n_periods=3, dt=1e-6, n_time=64)
    assert (ti.active_set_failures > 0) is capped
    assert ("iteration cap" in ti.verdict()) is capped


def _toy_system():
    M = np.array([[1.0, 0.9, 0.0], [0.9, 1.0, 0.0], [0.0, 0.0, 1.0]])
    K = 1e6 * np.eye(3)
    C, _ = modal_damping(K, M, np.full(3, 0.05))
    return modal_system(K, M, C, np.array([0.25]), np.array([0.0]), rotation=1)


def test_the_step_lock_is_where_the_capped_steps_begin():
    """The Carpenter step's own lock (rom.friction_lock.lock_table of
    hbm.ti.march.step_compliance) is the analytic 1 / 0.9 of the module doc, between the
    clean mu = 0.9 and the capped mu = 1.4 above; the ti stage warns at 1.4 only."""
    from hbm.ti.march import step_compliance
    from pipelines.stages.ti import step_lock_warning
    from rom.friction_lock import lock_table

    dt = 1e-6
    a_rr, a_rt = step_compliance(_toy_system(), dt)
    B = np.linalg.inv(np.array([[1.0, 0.9], [0.9, 1.0]]))  # r, theta block of M^-1, 1/kg
    np.testing.assert_allclose([a_rr[0, 0], a_rt[0, 0]], dt ** 2 * B[0], rtol=1e-3)  # damping: a = xi w dt <= 1.6e-4
    lock = lock_table(a_rr, a_rt, 1)
    assert lock.mu_set == pytest.approx(1 / 0.9, rel=1e-3)
    assert step_lock_warning("carpenter", 0.9, lock) is None
    assert "friction mu = 1.4 >= 1.11" in step_lock_warning("carpenter", 1.4, lock)
    assert step_lock_warning("massless", 1.4, lock) is None


def test_on_rotor_67_the_step_lock_is_the_inverse_mass_bound_far_above_the_static_one():
    """Coarse rotor 67 ROM, dt = 1e-7 s: the step's lock from the modal update equals the
    P-matrix bound of the inverse mass's radial-tangential blocks taken from M directly
    (dt^2 M^-1: the step's damping factors are 1 + O(1e-3)), and lies far above the static
    mu_set of the stiffness (0.123): at the scene's mu = 0.15 the step's contact problem is
    well posed while the static contact set can wedge."""
    from hbm.ti.march import rom_modal_system, step_compliance
    from rom.friction_lock import lock_table
    from support import coarse_rom

    rom = coarse_rom()
    nb = len(rom.rho)
    step = lock_table(*step_compliance(rom_modal_system(rom), 1e-7), rom.rotation)
    Minv = np.linalg.inv(rom.M)[:3 * nb, :3 * nb]
    direct = lock_table(Minv[0::3, 0::3], Minv[0::3, 1::3], rom.rotation)
    assert step.mu_set == pytest.approx(direct.mu_set, rel=1e-3)
    assert 2.0 < step.mu_set < 2.5 and rom.friction_lock.mu_set < 0.15 < step.mu_set
