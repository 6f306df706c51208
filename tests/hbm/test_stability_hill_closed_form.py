"""Hill's operator (hbm.stability.hill) against closed forms.

With contact weights constant in time, every AFT product is a scalar (T_c = w_c I), and
H(lam) P has a closed form per harmonic: with p(t) = sum_k c_k exp(i k omega t) and
s_k = lam + i k omega (the Floquet ansatz's d/dt),

    (H_lin(lam) p)_k = (K + s_k C + s_k^2 M) c_k,
    g_k = g_eps c_k,r - g_z (H_lin(lam) p)_k,r,         v_k = s_k c_k  (sliding velocity),
    force on node j: r += w_0 g, theta += w_1 g + w_3 v_theta + w_4 v_z, z += w_2 g + w_4 v_theta + w_5 v_z.

Each of terms/apply, dense and tail (the three forms the code builds) must give it. The
restriction to a sub-period's basis is checked against the full-period operator on the
harmonics it keeps (time-varying, T / 2-periodic weights and the Lanczos filter).
"""
import numpy as np
import pytest

from hbm.harmonic.fourier import FourierBasis
from hbm.stability.hill import HillOperator, harmonic_period, restrict

OMEGA = 3.0
NH, NT = 3, 16


def system(n=6, seed=3):
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n))
    K = A @ A.T + n * np.eye(n)
    B = rng.standard_normal((n, n))
    M = B @ B.T / n + np.eye(n)
    C = 0.05 * K + 0.01 * M
    return K, M, C


def to_complex(P):
    """eq. (5) coefficients (2 N_h + 1, n) -> c_k for k = -N_h .. N_h, (2 N_h + 1, n) complex."""
    nh = (P.shape[0] - 1) // 2
    c = np.zeros(P.shape, complex)
    c[nh] = P[0]
    for k in range(1, nh + 1):
        a, b = P[2 * k - 1], P[2 * k]
        c[nh + k], c[nh - k] = (a - 1j * b) / 2, (a + 1j * b) / 2
    return c


def from_complex(c):
    nh = (c.shape[0] - 1) // 2
    P = np.zeros(c.shape, complex)
    P[0] = c[nh]
    for k in range(1, nh + 1):
        P[2 * k - 1] = c[nh + k] + c[nh - k]
        P[2 * k] = 1j * (c[nh + k] - c[nh - k])
    return P


def reference(lam, P, K, M, C, omega, node, w, g_eps, g_z):
    """The closed form of the module docstring; w: (n_w,) constant weights (1 or 6 channels)."""
    nh = (P.shape[0] - 1) // 2
    c = to_complex(np.asarray(P, complex))
    y = np.zeros(c.shape, complex)
    r = 3 * node
    for i, k in enumerate(range(-nh, nh + 1)):
        s = lam + 1j * k * omega
        lin = (K + s * C + s * s * M) @ c[i]
        g = g_eps * c[i, r] - g_z * lin[r]
        y[i] = lin
        y[i, r] += w[0] * g
        if len(w) == 6:
            vt, vz = s * c[i, r + 1], s * c[i, r + 2]
            y[i, r + 1] += w[1] * g + w[3] * vt + w[4] * vz
            y[i, r + 2] += w[2] * g + w[4] * vt + w[5] * vz
    return from_complex(y)


def operator(K, M, C, w, g_eps, g_z, node=1, basis=FourierBasis(NH, NT)):
    weights = np.broadcast_to(np.asarray(w, float)[None, :, None], (1, len(w), basis.n_time)).copy()
    return HillOperator(K=K, M=M, C=C, omega=OMEGA, basis=basis, nodes=np.array([node]), weights=weights,
                        sigma=np.ones(basis.n_coeffs), g_eps=g_eps, g_z=g_z)


CASES = {  # (weights, g_eps, g_z)
    "rl": ([2.5], 1.0, 0.0),
    "dlft": ([0.7], 3.0, 0.4),
    "rl-friction": ([2.5, 0.3, -0.2, 1.1, 0.15, 0.8], 1.0, 0.0),
    "dlft-friction": ([0.7, 0.3, -0.2, 1.1, 0.15, 0.8], 3.0, 0.4),
}


@pytest.mark.parametrize("case", list(CASES))
def test_every_form_of_the_operator_is_the_closed_form(case):
    K, M, C = system()
    w, g_eps, g_z = CASES[case]
    H = operator(K, M, C, w, g_eps, g_z)
    rng = np.random.default_rng(7)
    P = rng.standard_normal((H.n_c, H.n)) + 1j * rng.standard_normal((H.n_c, H.n))
    L = H.dense()
    for lam in (0.0, -0.3 + 1.7j, 2.0):
        ref = reference(lam, P, K, M, C, OMEGA, 1, w, g_eps, g_z)
        scale = np.abs(ref).max()
        assert np.abs(H.apply(lam, P) - ref).max() <= 1e-12 * scale, lam
        dense = ((L[0] + lam * L[1] + lam * lam * L[2]) @ P.reshape(-1)).reshape(P.shape)
        assert np.abs(dense - ref).max() <= 1e-12 * scale, lam
    # L1 P1 + L2 P2 from the closed form: H(1) - H(-1) = 2 L1, H(1) + H(-1) - 2 H(0) = 2 L2
    P1, P2 = P, rng.standard_normal(P.shape)
    ref = lambda lam, X: reference(lam, X, K, M, C, OMEGA, 1, w, g_eps, g_z)  # noqa: E731
    L1P1 = 0.5 * (ref(1.0, P1) - ref(-1.0, P1))
    L2P2 = 0.5 * (ref(1.0, P2) + ref(-1.0, P2)) - ref(0.0, P2)
    want = L1P1 + L2P2
    assert np.abs(H.tail(P1, P2) - want).max() <= 1e-11 * np.abs(want).max()
    Y1, Y2 = H.terms(P1, (1, 2))
    assert np.abs(Y1 - L1P1).max() <= 1e-11 * np.abs(L1P1).max()


def test_the_harmonics_present_give_the_minimal_period():
    """Coefficient rows [c0, a1, b1, a2, b2, ...]: sine-only harmonics 2 and 4 are period
    T / 2; a harmonic 1 at 1e-3 of the largest breaks it (far above the 1e-6 default)."""
    c = np.zeros((9, 2))
    c[4, 0], c[8, 1] = 1.0, 0.3  # b2, b4
    assert harmonic_period(c) == 2
    c[3, 1] = 0.5  # a2
    c[6, 0] = 0.2  # b3
    assert harmonic_period(c) == 1
    c[6, 0] = 0.0
    c[1, 0] = 1e-3  # a1
    assert harmonic_period(c) == 1
    c[1, 0] = 1e-8
    assert harmonic_period(c) == 2


@pytest.mark.parametrize("friction", [False, True])
def test_the_restricted_operator_is_the_full_one_on_the_harmonics_it_keeps(friction):
    """Weights of period T / 2 (w(t) = w0 (1 + 0.5 cos 2 omega t + 0.2 sin 4 omega t)), the
    Lanczos filter on the force rows: on the even harmonics of omega, the operator of the
    basis of 2 omega (N_h / 2 harmonics, N_t / 2 samples) is the full operator, whose result
    holds only even harmonics."""
    nh, nt = 6, 32
    b = FourierBasis(nh, nt)
    K, M, C = system()
    tau = 2 * np.pi * np.arange(nt) / nt
    shape = 1.0 + 0.5 * np.cos(2 * tau) + 0.2 * np.sin(4 * tau)
    w0 = np.array([0.7, 0.3, -0.2, 1.1, 0.15, 0.8]) if friction else np.array([0.7])
    weights = (w0[:, None] * shape[None, :])[None]
    H = HillOperator(K=K, M=M, C=C, omega=OMEGA, basis=b, nodes=np.array([1]), weights=weights,
                     sigma=b.lanczos_sigma(), g_eps=3.0, g_z=0.4)
    Hr = restrict(H, 2)
    assert Hr.omega == 2 * OMEGA and Hr.basis.n_harmonics == 3
    rng = np.random.default_rng(11)
    Pr = rng.standard_normal((Hr.n_c, H.n)) + 1j * rng.standard_normal((Hr.n_c, H.n))
    even = np.concatenate([[0], np.stack([4 * np.arange(1, 4) - 1, 4 * np.arange(1, 4)], 1).reshape(-1)])
    P = np.zeros((H.n_c, H.n), complex)
    P[even] = Pr
    lam = -0.2 + 0.9j
    full = H.apply(lam, P)
    odd = np.setdiff1d(np.arange(H.n_c), even)
    assert np.abs(full[odd]).max() <= 1e-12 * np.abs(full).max()
    assert np.abs(Hr.apply(lam, Pr) - full[even]).max() <= 1e-12 * np.abs(full).max()
    L = Hr.dense()
    dense = ((L[0] + lam * L[1] + lam * lam * L[2]) @ Pr.reshape(-1)).reshape(Pr.shape)
    assert np.abs(dense - full[even]).max() <= 1e-12 * np.abs(full).max()
