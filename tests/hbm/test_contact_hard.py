"""Hard cases: grazing contact, stiff/soft contact parameters, many harmonics. Each must
converge, be in contact, and agree with a reference: the free orbit (grazing), the rigid
DLFT orbit (stiffer penalty), the epsilon-independence of DLFT, a lower N_h (truncation)."""

import numpy as np
import pytest

from hbm.continuation.newton import NewtonOptions
from hbm.harmonic.fourier import FourierBasis
from hbm.harmonic.nfrc import nfrc_extras
from hbm.harmonic.residual import build_residual
from hbm.harmonic.solver import HbmSolver
from hbm.harmonic.start import damped_newton, pad_harmonics
from hbm.options import CasingOptions, ContactOptions, HbmOptions
from support import coarse_rom
from test_obstacle import C, D, F, K, M, W, _solve


def test_grazing_contact_converges_to_the_free_orbit(monkeypatch):
    """Obstacle exactly at the peak of the free orbit: penetration ~0, contact force ~0."""
    import test_obstacle as t
    amp = F / np.hypot(K - M * W ** 2, C * W)  # free steady amplitude
    monkeypatch.setattr(t, "D", amp)
    for method in ("rl", "dlft"):
        full, fdof = _solve(method, 16, 1024)
        a1 = np.hypot(full[1, fdof], full[2, fdof])
        # a grazing contact of zero depth cannot change the orbit: relative change at the
        # level of the sampled penetration (the grid misses the exact peak by <~1e-5)
        assert abs(a1 - amp) / amp < 1e-4, method
        assert np.abs(full[3:, fdof]).max() < 1e-4 * amp, method  # no harmonics generated
        x = FourierBasis(16, 4096).to_time(full[:, fdof])
        assert abs(x.max() - amp) < 1e-4 * amp, method  # and the orbit does reach the obstacle


# ---- the rotor 67 ROM at 1700 rad/s, N_h = 40: a converged contact state of both treatments
# (the coarse ROM's primary branch there: ~1 mm LE amplitude, contact 10-15 % of the period)
OMEGA = 1700.0


def _solve_at(method, contact, nh, nt, guess=None):
    """Damped Newton at OMEGA (from the contact-free solution, or a guess of any N_h);
    returns (LE amplitude m, share of the AFT samples in contact, residual, u)."""
    rom = coarse_rom()
    res = build_residual(rom, CasingOptions(), contact, HbmOptions(n_harmonics=nh, n_time=nt), method=method)
    u0 = res.linear_solution(OMEGA) if guess is None else pad_harmonics(guess, res.n_r, nh)
    sol = damped_newton(res, u0, OMEGA, NewtonOptions(tol_residual=1e-8), HbmSolver())
    assert sol.converged, sol.reason
    # the residual recomputed independently of the solver's own test
    assert np.linalg.norm(res(sol.x, OMEGA, jacobian=False)) <= 1e-8 * (1 + 1e-6)
    active = res.samples(res.to_coefficients(sol.x), OMEGA).active.mean()
    return nfrc_extras(res, sol.x)["le_amplitude"], active, sol.x


@pytest.fixture(scope="module")
def base():
    """DLFT (epsilon = 1e7) and RL (kappa = 1e9) at N_h = 40, N_t = 512: the references."""
    return {m: _solve_at(m, ContactOptions(), 40, 512) for m in ("dlft", "rl")}


@pytest.mark.parametrize("epsilon", [1e6, 1e8])
def test_dlft_weight_ten_times_smaller_or_larger_gives_the_same_orbit(base, epsilon):
    """epsilon is a numerical weight of the augmented Lagrangian, not a stiffness: the
    converged DLFT solution solves the same contact problem whatever it is. What remains is
    the N_h-truncation (Gibbs) error of the contact law on the AFT grid, about 1 % of the
    amplitude at N_h = 40 here (N_h = 80 moves it by 1.0 %, see below): measured 0.4 % and
    0.3 % from epsilon = 1e7."""
    amp, active, _ = _solve_at("dlft", ContactOptions(epsilon=epsilon), 40, 512)
    assert active > 0.1  # a real contact state, not a free orbit
    assert abs(amp - base["dlft"][0]) / base["dlft"][0] < 1e-2


def test_stiffer_penalty_moves_rl_towards_the_rigid_dlft_orbit(base):
    """RL's penalty law allows a penetration ~ lam / kappa; at kappa = 1e10 (ten times the
    scene's) the orbit must move towards DLFT's, which enforces the rigid casing: measured
    1.4 % from DLFT at kappa = 1e9 and 0.15 % at 1e10 (started from the 1e9 solution, as the
    NFRC's kappa homotopy does)."""
    amp, active, _ = _solve_at("rl", ContactOptions(kappa=1e10), 40, 512, guess=base["rl"][2])
    ref = base["dlft"][0]
    assert active > 0.03
    assert abs(amp - ref) < 0.5 * abs(base["rl"][0] - ref)
    assert abs(amp - ref) / ref < 5e-3


def test_eighty_harmonics_on_the_blade(base):
    """N_h = 80 from the N_h = 40 solutions: both converge, stay within the N_h = 40
    truncation error (measured: DLFT 1.0 %, RL 0.3 %) and come closer to each other (0.74 %
    apart at N_h = 80, 1.4 % at N_h = 40)."""
    amps = {}
    for m in ("dlft", "rl"):
        amps[m], active, _ = _solve_at(m, ContactOptions(), 80, 1024, guess=base[m][2])
        assert active > 0.05
        assert abs(amps[m] - base[m][0]) / base[m][0] < 2e-2
    gap40 = abs(base["dlft"][0] - base["rl"][0])
    assert abs(amps["dlft"] - amps["rl"]) < gap40


@pytest.mark.parametrize("method", ["rl", "dlft"])
def test_eighty_harmonics_converge_to_the_same_orbit(method):
    """N_h = 80 on the exact 1-dof obstacle problem: converges and agrees with N_h = 32
    to the N_h = 32 truncation error (~2e-5 of the amplitude, see test_obstacle)."""
    f32, dof = _solve(method, 32, 8192)
    f80, _ = _solve(method, 80, 8192, guess_full=f32)
    x32 = FourierBasis(32, 4096).to_time(f32[:, dof])
    x80 = FourierBasis(80, 4096).to_time(f80[:, dof])
    assert x80.max() > D + 0.05  # in contact: the orbit enters the obstacle
    assert np.abs(x80 - x32).max() / np.abs(x80).max() < 5e-5
