"""The period-doubling switch's direction (hbm.stability.switching.mode_coefficients)
against shooting, whatever the phase of Hill's eigenvector.

Damped Mathieu equation x'' + 2 zeta x' + (a + 2 q cos 2t) x = 0 (period pi, omega = 2)
inside its first instability tongue: a real multiplier mu < -1 of the period pi, whose
mode exp(lam t) p(t), Im lam = omega / 2, is real up to a constant complex factor. The
reference is the monodromy matrix's eigenvector of that multiplier (solve_ivp, DOP853,
rtol 1e-10): the mode's state (x, x') at t = 0. An eigenvector's phase is arbitrary (LAPACK,
ARPACK): the direction must not depend on it.
"""
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from hbm.harmonic.fourier import FourierBasis
from hbm.stability.bifurcation import PERIOD_DOUBLING, Bifurcation
from hbm.stability.hill import HillOperator
from hbm.stability.spectrum import dense_spectrum, exponential_coefficients
from hbm.stability.switching import mode_coefficients

ZETA, A, Q, W = 0.02, 1.0, 0.3, 2.0


def _reference():
    def rhs(t, y):
        Phi = y.reshape(2, 2)
        Amat = np.array([[0.0, 1.0], [-(A + 2 * Q * np.cos(2 * t)), -2 * ZETA]])
        return (Amat @ Phi).ravel()

    s = solve_ivp(rhs, (0.0, np.pi), np.eye(2).ravel(), method="DOP853", rtol=1e-10, atol=1e-12)
    mu, V = np.linalg.eig(s.y[:, -1].reshape(2, 2))
    i = int(np.argmin(mu.real))
    return mu[i].real, V[:, i].real


@pytest.mark.parametrize("phase", [1.0, 1j, np.exp(0.7j), -np.exp(-1.2j)])
def test_period_doubling_direction_matches_shooting_for_any_eigenvector_phase(phase):
    mu_ref, v = _reference()
    assert mu_ref < -1.0
    nh, nt = 12, 64
    basis = FourierBasis(nh, nt)
    t = np.arange(nt) * 2 * np.pi / (W * nt)
    H = HillOperator(K=np.diag([A, 100.0, 100.0]), M=np.eye(3), C=np.diag([2 * ZETA, 101.0, 101.0]), omega=W,
                     basis=basis, nodes=np.array([0]), weights=(2 * Q * np.cos(2 * t))[None, None],
                     sigma=np.ones(2 * nh + 1), g_eps=1.0, g_z=0.0, nl=np.arange(3))
    sp = dense_spectrum(H)
    j = int(np.argmin(np.abs(sp.multipliers - mu_ref)))
    assert abs(sp.multipliers[j] - mu_ref) < 1e-8
    lam = sp.exponents[j]
    # make the mode exp(i Im(lam) t) p(t) real (its value at t = 0 on x), then give it the phase
    P = sp.eigenvectors[j]
    k = np.arange(-nh, nh + 1)
    f = np.exp(1j * np.outer(t, lam.imag + k * W)) @ exponential_coefficients(P)[:, 0]  # x's mode on t
    c = f[np.argmax(np.abs(f))]
    assert np.max(np.abs((f / c).imag)) < 1e-8  # a real multiplier's mode is real up to c
    P = P / c
    bif = Bifurcation(kind=PERIOD_DOUBLING, omega=W, le_amplitude=0.0, index=0, fraction=0.0, omega_bracket=(W, W),
                      multiplier=sp.multipliers[j], direction=1, period_ratio=1, exponent=lam, mode_omega=W,
                      eigenvector=P * phase)
    y = mode_coefficients(bif, 2 * nh + 1, W / 2)[:, 0]  # x's coefficients in the basis of omega / 2
    orders = FourierBasis(2 * nh + 1, 2 * nt).orders
    assert np.linalg.norm(y[orders % 2 == 0]) < 1e-10  # only the odd harmonics of omega / 2
    # the mode x(t) = exp(Re(lam) t) y(t): state at t = 0 is (y(0), Re(lam) y(0) + y'(0))
    w2 = W / 2
    x0 = y[0] + np.sum(y[1::2])
    dx0 = lam.real * x0 + np.sum(np.arange(1, 2 * nh + 2) * w2 * y[2::2])
    state = np.array([x0, dx0])
    cos = abs(state @ v) / (np.linalg.norm(state) * np.linalg.norm(v))
    assert cos > 1 - 1e-9, (state, v)


def test_a_mode_off_the_target_harmonics_or_not_a_doubling_is_refused():
    """Im lam = 0.37 omega: (k omega + beta) / (omega / 2) = 2 k + 0.74 lies 0.26 from a
    harmonic of omega / 2, past the quarter mode_coefficients allows; at 0.1 omega (2 k + 0.2)
    each coefficient is put on the nearest one. A fold has no mode to switch along."""
    from hbm.stability.bifurcation import FOLD
    from hbm.stability.switching import switch_branch

    nh = 3
    P = np.zeros((2 * nh + 1, 1), complex)
    P[1] = 1.0  # eq. (5) order: the cosine of harmonic 1 of omega
    common = dict(omega=W, le_amplitude=0.0, index=0, fraction=0.0, omega_bracket=(W, W), multiplier=-1.0 + 0j,
                  direction=1, period_ratio=1, mode_omega=W, eigenvector=P)
    off = Bifurcation(kind=PERIOD_DOUBLING, exponent=0.37j * W, **common)
    with pytest.raises(ValueError, match=r"^the mode's frequencies are not harmonics of 1 rad/s \(Im lam = 0.74 1/s, "
                                         r"basis 2 rad/s\)$"):
        mode_coefficients(off, 8, W / 2)
    near = Bifurcation(kind=PERIOD_DOUBLING, exponent=0.1j * W, **common)
    y = mode_coefficients(near, 8, W / 2)[:, 0]
    # harmonic 1 of omega, 0.2 of a harmonic off harmonic 2 of omega / 2, lands there (rows 3, 4)
    assert np.linalg.norm(y[3:5]) == pytest.approx(1.0, abs=1e-12)
    fold = Bifurcation(kind=FOLD, exponent=0j, **common)
    with pytest.raises(ValueError, match=r"^switch_branch needs a period doubling with its mode, got 'fold'$"):
        switch_branch(None, np.zeros(3), W, fold)
