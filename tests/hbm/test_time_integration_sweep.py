"""Validation mode (TI started on a periodic solution) and the sweep, on a problem whose
periodic solution with contact is exact.

One contact node (r, theta, z) on springs, casing with zero clearance (d <= 0 everywhere).
r(t) = d(Omega t) is a solution of the constrained problem as long as the force needed to
follow the casing, lam = -(m r'' + c r' + k r), is >= 0: with r = -p G, G the Gaussian lobe
of width w, lam = p G [k - c Omega 2 phi / w^2 + m Omega^2 (4 phi^2 / w^4 - 2 / w^2)] >= 0 once
k > 2 m Omega^2 / w^2 (w_r >= 9.4 Omega), true here with a margin of 3. Friction then slides
along +theta (v_z = 0, rho Omega >> v_theta) and the theta dof is a damped linear oscillator
forced by -mu lam(t), solved harmonic by harmonic. Coefficients are exact to round-off at
N_h = 100 (the Gaussian's spectrum decays as exp(-(k w)^2 / 4), e^-56 at k = 100).
"""
import math

import numpy as np
import pytest

from hbm.harmonic.fourier import FourierBasis
from hbm.contact.casing import casing_distance
from hbm.options import CasingOptions, ContactOptions, TimeIntegrationOptions
from hbm.ti.periodicity import PeriodClass
from hbm.ti.sweep import sweep
from hbm.ti.march import modal_system
from hbm.ti.validation import validate_against_hbm
from rom.model import modal_damping
from support import standin_rom

CAS = CasingOptions(clearance=0.0, penetration=1e-4, width=0.15, n_lobes=2)
W_R, W_T, W_Z, XI, MU, RHO, THETA = 3000.0, 750.0, 1234.5, 1e-3, 0.15, 0.25, 0.2


def following_system():
    K = np.diag([W_R ** 2, W_T ** 2, W_Z ** 2])
    M = np.eye(3)
    C, _ = modal_damping(K, M, np.full(3, XI))
    return K, M, C, modal_system(K, M, C, [RHO], [THETA])


def exact_orbit(omega, n_h=100, n_fine=8192):
    """Harmonics (2 N_h + 1, 3), m, and lam(t) on n_fine instants, N, of the casing-following orbit."""
    K, M, C, _ = following_system()
    fine = FourierBasis(n_h, n_fine)
    d = casing_distance(fine.tau, np.array([THETA]), CAS)[:, 0]
    cd = fine.to_freq(d)
    D = fine.derivative_matrix
    lam_c = -(M[0, 0] * omega ** 2 * (D @ D @ cd) + C[0, 0] * omega * (D @ cd) + K[0, 0] * cd)
    lam = fine.to_time(lam_c)
    assert lam.min() >= -1e-9 * lam.max()  # the orbit is admissible: contact force >= 0
    # theta: m x'' + c x' + k x = -mu lam, harmonic by harmonic (complex form a - i b)
    k = fine.orders[1::2]
    F = -MU * (lam_c[1::2] - 1j * lam_c[2::2])
    X = F / (K[1, 1] - M[1, 1] * (k * omega) ** 2 + 1j * k * omega * C[1, 1])
    coeffs = np.zeros((2 * n_h + 1, 3))
    coeffs[:, 0] = cd
    coeffs[0, 1] = -MU * lam_c[0] / K[1, 1]
    coeffs[1::2, 1], coeffs[2::2, 1] = X.real, -X.imag
    return coeffs, lam, fine


def test_time_marching_from_the_exact_periodic_solution_stays_on_it():
    """Displacement: the multiplier puts r on the casing at every step, so TI and the exact
    orbit differ by round-off only (1e-9 allows for the truncated series of d). Force: the
    discrete multiplier is -(m delta^2 d / dt^2 + ...) = exact lam + O((dt / t_lobe)^2 d''''),
    t_lobe = w / Omega = 1.5 ms, dt ~ 2 us: ~1e-5 relative; 1e-3 is the stated bound."""
    omega = 100.0
    coeffs, lam, fine = exact_orbit(omega)
    n_t = 1024
    lam_t = lam[:: fine.n_time // n_t][:, None]
    *_, system = following_system()
    v = validate_against_hbm(system, CAS, ContactOptions(mu=MU), coeffs, omega, forces=lam_t, n_periods=100,
                             dt=2e-6)
    assert v.dt <= 2e-6 and v.n_periods == 100
    assert v.displacement_error.max() <= 1e-9
    assert v.force_error.max() <= 1e-3
    assert v.drift.max() <= 1e-9
    assert v.max_penetration <= 1e-18
    # a solution a quarter lobe off is not a periodic solution: the comparison must see it
    shifted = coeffs.copy()
    shifted[:, 0] = FourierBasis(100, 8192).to_freq(
        casing_distance(fine.tau + 0.05, np.array([THETA]), CAS)[:, 0])
    bad = validate_against_hbm(system, CAS, ContactOptions(mu=MU), shifted, omega, forces=lam_t, n_periods=3,
                               dt=2e-6)
    assert bad.displacement_error.max() > 0.1


def test_sweep_from_rest_locks_onto_the_casing():
    """From rest the node starts on the casing (d(0) ~ -p e^-110 ~ 0) and stays on it: the
    steady response is the casing itself, period T / 2 (omega = 2 Omega), amplitude exactly
    (max d - min d) / 2 = p / 2 (to round-off, since the constraint holds at every step and
    the lobe centre falls on a step: steps per revolution are a multiple of 256)."""
    *_, system = following_system()
    opts = TimeIntegrationOptions(dt=2e-6, n_revolutions=10, n_keep=4, samples_per_revolution=256)
    res = sweep(system, CAS, ContactOptions(mu=MU), opts, omegas=np.array([100.0, 150.0]), workers=1)
    np.testing.assert_allclose(res.amplitude, CAS.penetration / 2, rtol=1e-6)
    assert (res.period_class == PeriodClass.CASING).all() and (res.period == 1).all()
    np.testing.assert_allclose(res.max_abs, CAS.penetration, rtol=1e-6)
    assert (res.dt <= 2e-6).all() and res.max_penetration.max() <= 1e-18
    assert res.times.shape == (2, 4 * 256) and res.displacement.shape == (2, 1024, 2)
    assert res.sections.shape == (2, 4 * 2 + 1, 1)
    # block means of the force keep the impulse: mean force over the window = mean lam
    coeffs, lam, _ = exact_orbit(100.0)
    assert res.normal_force[0, :, 0].mean() == pytest.approx(lam.mean(), rel=1e-3)


def test_sweep_workers_and_serial_agree_on_the_standin_rom():
    rom = standin_rom()
    opts = TimeIntegrationOptions(dt=1e-6, n_revolutions=8, n_keep=2, samples_per_revolution=64)
    om = np.array([1900.0, 1500.0, 1700.0])
    a = sweep(rom, CasingOptions(), ContactOptions(), opts, omegas=om, workers=1)
    b = sweep(rom, CasingOptions(), ContactOptions(), opts, omegas=om, workers=2)
    np.testing.assert_array_equal(a.omega, om)
    for name in ("amplitude", "max_abs", "period_class", "displacement", "normal_force", "sections"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    # amplitude is (max - min) / 2 over every step of the window: at least the samples' half range
    half = 0.5 * np.ptp(a.displacement[:, :, 0], axis=1)
    assert (a.amplitude >= half).all()
    assert (a.max_abs >= np.abs(a.displacement[:, :, 0]).max(axis=1)).all()
    assert (a.contact_fraction > 0).all() and a.max_penetration.max() <= 1e-15


def test_sweep_refuses_an_unstable_time_step():
    with pytest.raises(ValueError, match="dt_crit"):
        sweep(standin_rom(), CasingOptions(), ContactOptions(), TimeIntegrationOptions(dt=1e-4), omegas=[1000.0])
