"""The casing law of eq. (28) (hbm.contact.casing): one source for the HBM (numpy) and the
time-integration kernel (numba), pinned against the equation written out independently."""
import math

import numpy as np
import pytest

from hbm.contact.casing import casing_distance, gap_at, lobe_coordinate
from hbm.options import CasingOptions


def eq28(tau, theta_j, c, p, w, n_l):
    """Eq. (28) from the paper's definitions, scalar by scalar with Python's math: lobes of
    Gaussian shape centred where the node's angle tau + theta_j is pi / n_l modulo 2 pi / n_l."""
    period = 2 * math.pi / n_l
    phase = math.fmod(tau + theta_j, period)
    if phase < 0:
        phase += period
    phi = phase - math.pi / n_l
    return c - (c + p) * math.exp(-(phi / w) ** 2)


@pytest.mark.parametrize("n_l", [2, 3])
def test_lobe_centres_depth_and_width_for_a_shifted_node(n_l):
    """A node at theta_j = 0.3 rad: the lobe centres (d = -p, the deepest point) are at
    tau = pi / n_l - theta_j + k 2 pi / n_l; one lobe width w away d = c - (c + p) / e;
    half-way between centres d = c - (c + p) exp(-(pi / (n_l w))^2) ~ c."""
    c, p, w, theta_j = 4e-4, 1.25e-4, 0.15, 0.3
    cas = CasingOptions(n_lobes=n_l, width=w, clearance=c, penetration=p)
    centres = math.pi / n_l - theta_j + 2 * math.pi / n_l * np.arange(-1, 2 * n_l)
    d = casing_distance(centres, np.array([0.0, theta_j]), cas)[:, 1]
    np.testing.assert_allclose(d, -p, rtol=0, atol=1e-18)  # depth c + p below the clearance
    for side in (-1.0, 1.0):
        np.testing.assert_allclose(casing_distance(centres + side * w, np.array([theta_j]), cas)[:, 0],
                                   c - (c + p) / math.e, rtol=1e-12)
    mid = casing_distance(centres + math.pi / n_l, np.array([theta_j]), cas)[:, 0]
    np.testing.assert_allclose(mid, c - (c + p) * math.exp(-(math.pi / (n_l * w)) ** 2), rtol=1e-12)
    # the deepest point over a fine grid of one casing period is where eq. (28) says
    tau = np.linspace(0.0, 2 * math.pi / n_l, 200001)
    dd = casing_distance(tau, np.array([theta_j]), cas)[:, 0]
    centre = (math.pi / n_l - theta_j) % (2 * math.pi / n_l)
    assert abs(tau[np.argmin(dd)] - centre) <= tau[1]


def test_casing_distance_equals_eq28_written_out():
    """Every angle, node shift and lobe count against the scalar transcription, to round-off
    (the modulo of a large angle loses |tau| eps of phase: d' |tau| eps < 1e-15 m here)."""
    rng = np.random.default_rng(4)
    for n_l in (1, 2, 3, 5):
        cas = CasingOptions(n_lobes=n_l, width=0.2, clearance=3e-4, penetration=1e-4)
        theta = rng.uniform(-1.0, 1.0, 4)
        tau = rng.uniform(-50.0, 50.0, 500)
        d = casing_distance(tau, theta, cas)
        ref = np.array([[eq28(t, th, 3e-4, 1e-4, 0.2, n_l) for th in theta] for t in tau])
        np.testing.assert_allclose(d, ref, rtol=0, atol=1e-15)


def test_numba_and_numpy_compile_the_same_law():
    """The time-integration kernel compiles lobe_coordinate and gap_at with numba; the HBM
    runs them through numpy. Same source and the same IEEE operations, so the same value to
    round-off at 1e5 angles over 100 revolutions: z to |x| eps / w (the modulo of x ~ 600 rad,
    1e-12) and d to a few ulp of the exponential."""
    import numba  # a required dependency: the parity test must never be skipped
    from hbm.ti import kernel

    @numba.njit
    def both(x, n_l, w, c, p):
        z = np.empty_like(x)
        d = np.empty_like(x)
        for i in range(x.shape[0]):
            z[i] = kernel.lobe_coordinate(x[i], n_l, w)
            d[i] = kernel.gap_at(z[i], c, p)
        return z, d

    rng = np.random.default_rng(5)
    x = rng.uniform(0.0, 200 * math.pi, 100_000)
    for n_l, w in ((2, 0.15), (3, 0.4)):
        z_nb, d_nb = both(x, n_l, w, 4e-4, 1.25e-4)
        np.testing.assert_allclose(z_nb, lobe_coordinate(x, n_l, w), rtol=0, atol=1e-12)
        np.testing.assert_allclose(d_nb, gap_at(z_nb, 4e-4, 1.25e-4), rtol=0, atol=4 * np.finfo(float).eps * 5.25e-4)
