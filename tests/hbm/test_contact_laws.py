"""Edge values of the contact laws (hbm.contact.normal, hbm.contact.friction) against hand
computations: the penalty law (gamma = 0) at a zero gap, the sliding direction at a relative
speed far below the blade speed but far above the documented 1e-12 m/s floor, and a sense of
rotation of 0 refused by the one check every nonlinear stage makes."""
import warnings

import numpy as np
import pytest

from hbm.contact.friction import rotation_sense, slide_direction
from hbm.contact.normal import correct_dlft, regularised_penalty


def test_penalty_law_at_zero_gap_has_finite_one_sided_slope():
    # eq. (18): lam = kappa max(g, 0); its slope is 0 for g < 0 and kappa for g > 0, and at
    # g = 0 exactly one of the two one-sided derivatives (a Jacobian entry), never NaN
    kappa = 3.0e7
    g = np.array([-1e-3, -1e-300, 0.0, 1e-300, 2e-4])
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no 0 / 0 evaluated anywhere
        lam, dlam = regularised_penalty(g, kappa, 0.0)
    np.testing.assert_array_equal(lam, [0.0, 0.0, 0.0, kappa * 1e-300, kappa * 2e-4])
    assert np.all(np.isfinite(dlam))
    np.testing.assert_array_equal(dlam[[0, 1, 3, 4]], [0.0, 0.0, kappa, kappa])
    assert dlam[2] in (0.0, kappa)


def test_regularised_law_against_its_closed_form_and_slope():
    # eq. (19) lam = kappa g / 2 + sqrt((kappa g / 2)^2 + gamma^2), written out with Python
    # floats where no cancellation occurs (g >= 0), and lam * (root - h) = gamma^2 elsewhere;
    # the slope against a central difference
    kappa, gamma = 2.0e7, 5.0
    g = np.array([-1e-4, -1e-6, 0.0, 1e-7, 3e-5])
    lam, dlam = regularised_penalty(g, kappa, gamma)
    h = 0.5 * kappa * g
    root = np.sqrt(h * h + gamma * gamma)
    np.testing.assert_allclose(lam[2:], h[2:] + root[2:], rtol=1e-14)
    np.testing.assert_allclose(lam[:2] * (root[:2] - h[:2]), gamma ** 2, rtol=1e-13)
    assert lam[2] == gamma  # lam(0) = gamma
    step = 1e-9
    fd = (regularised_penalty(g + step, kappa, gamma)[0] - regularised_penalty(g - step, kappa, gamma)[0]) / (2 * step)
    np.testing.assert_allclose(dlam, fd, rtol=1e-5, atol=1e-6 * kappa)


def test_dlft_correction_at_exactly_zero_prediction_is_inactive():
    # eq. (15): lam = max(0, lam_pre); at lam_pre = 0 there is no compressive force, and the
    # documented indicator (lam_pre > 0) is False there
    lam, active = correct_dlft(np.array([-2.0, 0.0, 3.5]))
    np.testing.assert_array_equal(lam, [0.0, 0.0, 3.5])
    np.testing.assert_array_equal(active, [False, False, True])


@pytest.mark.parametrize("s", [1, -1])
def test_sliding_direction_stays_unit_at_a_small_relative_speed(s):
    # blade speed s rho Omega cancelled by the vibration to within dv: the relative velocity is
    # (dv, v_z), a unit direction (dv, v_z) / |.| however small, down to the 1e-12 m/s floor
    rho, omega = np.array([0.25]), 400.0
    for dv, vz in ((1e-6, 0.0), (3e-7, -4e-7), (0.0, 2e-5)):
        vt = np.array([-s * rho[0] * omega + dv])
        sd = slide_direction(vt, np.array([vz]), rho, omega, s)
        rel = vt[0] + s * rho[0] * omega  # the exact relative speed, up to round-off of 100 m/s
        n = np.hypot(rel, vz)
        np.testing.assert_allclose([sd.s_theta[0], sd.s_z[0]], [rel / n, vz / n], rtol=1e-6, atol=1e-6)
        np.testing.assert_allclose(np.hypot(sd.s_theta, sd.s_z), 1.0, rtol=1e-12)
        # d s_z / d v_z = rel^2 / n^3: 1 / |rel| for v_z = 0 (a 1e6 s/m slope at 1e-6 m/s)
        np.testing.assert_allclose(sd.ds_z_dvz[0], rel ** 2 / n ** 3, rtol=1e-6)


@pytest.mark.parametrize("bad", [0, 0.0, 2, -2, 0.5])
def test_rotation_sense_refuses_values_other_than_plus_or_minus_one(bad):
    with pytest.raises(ValueError, match="rotation must be"):
        rotation_sense(bad)
    with pytest.raises(ValueError, match="rotation must be"):
        slide_direction(np.zeros(1), np.zeros(1), np.ones(1), 100.0, bad)
