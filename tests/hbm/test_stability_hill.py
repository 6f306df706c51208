"""Hill's method (hbm.stability) against shooting: the monodromy matrix of the variational
equations integrated along the periodic orbit with scipy's solve_ivp (DOP853, rtol = atol =
1e-12), which shares no code with the HBM.

1. Forced Duffing oscillator x'' + 2 zeta x' + x + gamma x^3 = F cos(W t) at a speed with
   three periodic orbits (two stable, the middle one a saddle). The orbit comes from
   shooting; Hill's operator is built from its Fourier coefficients (the cubic term's
   stiffness 3 gamma x(t)^2 as the time weight of one 'contact' dof).
2. Forced oscillator against a regularised-penalty (RL) obstacle,
   m x'' + c x' + k x + lam(x - d) = F cos(W t), lam(g) = kappa g / 2 + sqrt((kappa g / 2)^2
   + gamma^2), at a speed with three orbits: the orbit is the project's RL-HBM solution and
   the shooting ODE uses the same smooth force, so both sides solve the same problem.
"""
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from hbm.continuation.arclength import ContinuationOptions, continue_branch
from hbm.continuation.newton import NewtonOptions, newton_solve
from hbm.harmonic.condensation import HarmonicForcing
from hbm.harmonic.fourier import FourierBasis
from hbm.harmonic.residual import build_residual
from hbm.options import CasingOptions, ContactOptions, HbmOptions
from hbm.stability.hill import HillOperator
from hbm.stability.spectrum import dense_spectrum


def _shoot(rhs, y0, T):
    """Periodic orbit through Newton on y(T) - y(0) and its monodromy matrix (2 x 2)."""
    def flow(y):
        s = solve_ivp(rhs, (0.0, T), np.concatenate([y, np.eye(2).ravel()]), rtol=1e-12, atol=1e-12,
                      method="DOP853")
        return s.y[:2, -1], s.y[2:, -1].reshape(2, 2)

    y = np.array(y0, dtype=float)
    for _ in range(30):
        yT, Phi = flow(y)
        r = yT - y
        if np.linalg.norm(r) < 1e-11:
            break
        y = y - np.linalg.solve(Phi - np.eye(2), r)
    yT, Phi = flow(y)
    assert np.linalg.norm(yT - y) < 1e-10
    return y, Phi


def _match(mu_ref, mu_hill):
    """Largest distance from a reference multiplier to the nearest Hill multiplier."""
    return max(np.min(np.abs(mu_hill - m)) for m in mu_ref)


ZETA, GAMMA_D, F_D, W_D = 0.05, 1.0, 0.5, 1.7


def _duffing_rhs(t, y):
    x, v = y[:2]
    A = np.array([[0.0, 1.0], [-1.0 - 3.0 * GAMMA_D * x * x, -2.0 * ZETA]])
    return np.concatenate([[v, -2 * ZETA * v - x - GAMMA_D * x ** 3 + F_D * np.cos(W_D * t)],
                           (A @ y[2:].reshape(2, 2)).ravel()])


def test_duffing_multipliers_match_shooting_on_stable_and_unstable_orbits():
    T = 2 * np.pi / W_D
    # three orbits at W_D: one-harmonic balance amplitudes as the shooting guesses
    k, c, d = 0.75 * GAMMA_D, 1 - W_D ** 2, 2 * ZETA * W_D
    u = np.roots([k * k, 2 * c * k, c * c + d * d, -F_D ** 2])
    amps = np.sqrt(np.sort(u[np.abs(u.imag) < 1e-9].real))
    assert len(amps) == 3
    nh, nt = 15, 256
    basis = FourierBasis(nh, nt)
    verdicts = []
    for a in amps:
        s = c + k * a * a
        ab = np.linalg.solve([[s, d], [-d, s]], [F_D, 0.0])
        y0, Phi = _shoot(_duffing_rhs, [ab[0], W_D * ab[1]], T)
        mu_ref = np.linalg.eigvals(Phi)
        x = solve_ivp(lambda t, y: _duffing_rhs(t, np.concatenate([y, np.eye(2).ravel()]))[:2], (0, T), y0,
                      t_eval=np.arange(nt) * T / nt, rtol=1e-12, atol=1e-12, method="DOP853").y[0]
        xs = basis.to_time(basis.to_freq(x))
        # dof 0 is x; dofs 1, 2 (the 'theta, z' of the one node) are decoupled, overdamped
        # (multipliers exp(-1.01 T) ~ 0.02 and below, away from x's)
        H = HillOperator(K=np.diag([1.0, 100.0, 100.0]), M=np.eye(3), C=np.diag([2 * ZETA, 101.0, 101.0]),
                         omega=W_D, basis=basis, nodes=np.array([0]), weights=(3 * GAMMA_D * xs ** 2)[None, None],
                         sigma=np.ones(2 * nh + 1), g_eps=1.0, g_z=0.0, nl=np.arange(3))
        sp = dense_spectrum(H)
        # x(t) is analytic: its harmonics decay geometrically and N_h = 15 resolves the
        # orbit and Hill's eigenvectors to round-off: measured 5e-13 to 9e-13 (the shooting
        # tolerance); 1e-8 leaves room for other BLAS and integrator versions
        assert _match(mu_ref, sp.multipliers) < 1e-8, (mu_ref, sp.multipliers[:3])
        assert sp.n_unstable == int(np.sum(np.abs(mu_ref) > 1.0))
        verdicts.append(sp.stable)
    assert verdicts == [True, False, True]  # the saddle between the two stable orbits


M_C, C_C, K_C, F_C, D_C, KAPPA_C, GAMMA_C, W_C = 1.0, 0.05, 1.0, 0.15, 0.5, 4.0, 0.02, 1.22


def _rl(g):
    h = 0.5 * KAPPA_C * g
    r = np.sqrt(h * h + GAMMA_C ** 2)
    return h + r, 0.5 * KAPPA_C * (1.0 + h / r)


def _contact_rhs(t, y):
    x, v = y[:2]
    lam, dlam = _rl(x - D_C)
    A = np.array([[0.0, 1.0], [-(K_C + dlam) / M_C, -C_C / M_C]])
    return np.concatenate([[v, (-C_C * v - K_C * x - lam + F_C * np.cos(W_C * t)) / M_C],
                           (A @ y[2:].reshape(2, 2)).ravel()])


@pytest.fixture(scope="module")
def contact_branch():
    nh, nt = 48, 1024
    rom = SimpleNamespace(K=np.diag([K_C, 1.0, 1.0]), M=np.diag([M_C, 0.0, 0.0]), C=np.diag([C_C, 0.0, 0.0]),
                          rho=np.array([0.25]), theta=np.array([0.0]), rotation=1, n_boundary=1, nonlinear_dofs=np.arange(3))
    f = np.array([F_C, 0.0, 0.0])
    contact = ContactOptions(kappa=KAPPA_C, gamma=GAMMA_C, epsilon=3.0, mu=0.0, lanczos=False)
    res = build_residual(rom, CasingOptions(), contact, HbmOptions(n_harmonics=nh, n_time=nt), method="rl",
                         forcing=HarmonicForcing(f, 1), alpha=1.0, distance=lambda tau: np.full((len(tau), 1), D_C))
    nopt = NewtonOptions(tol_residual=1e-11, max_iter=40)
    sol = newton_solve(res, res.linear_solution(0.6), 0.6, nopt)
    opts = ContinuationOptions(omega_min=0.6, omega_max=2.0, ds=0.01, ds_max=0.05, direction=1, newton=nopt,
                               closed_loop_tol=None)
    return res, continue_branch(res, sol.x, 0.6, opts)


def test_rl_contact_multipliers_match_shooting_on_three_coexisting_orbits(contact_branch):
    res, br = contact_branch
    w = br.omega
    turns = np.flatnonzero(np.sign(np.diff(w)[1:]) != np.sign(np.diff(w)[:-1])) + 1
    assert len(turns) == 2 and w[turns[1]] < W_C < w[turns[0]]  # folds at 1.305 and 1.143 rad/s
    b = res.basis
    T = 2 * np.pi / W_C
    verdicts = []
    for seg in (np.arange(0, turns[0]), np.arange(turns[0], turns[1]), np.arange(turns[1], len(w))):
        j = seg[np.argmin(np.abs(w[seg] - W_C))]
        s = newton_solve(res, br.x[j], W_C, NewtonOptions(tol_residual=1e-11, max_iter=40))
        assert s.converged
        xc = res.to_coefficients(s.x)[:, 0]
        y0 = [b.to_time(xc)[0], W_C * b.to_time(b.derivative(xc[:, None]))[0, 0]]
        _, Phi = _shoot(_contact_rhs, y0, T)
        mu_ref = np.linalg.eigvals(Phi)
        sp = dense_spectrum(HillOperator.from_residual(res, s.x, W_C))
        # the penalty force turns on over a gap of ~gamma / kappa = 5e-3: its harmonics
        # decay slowly at first; at N_h = 48 the HBM orbit of the upper (most penetrating)
        # sheet is ~1e-5 off the shooting one, and so are its multipliers (measured 1.0e-5,
        # 3e-8 and 6e-13 on the three sheets; at N_h = 24: 7e-4): 1e-4
        assert _match(mu_ref, sp.multipliers) < 1e-4, (mu_ref, sp.multipliers[:3])
        assert sp.n_unstable == int(np.sum(np.abs(mu_ref) > 1.0))
        verdicts.append(sp.stable)
    assert verdicts == [True, False, True]
