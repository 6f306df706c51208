"""The NFRC's start strategies (hbm.harmonic.start) where plain Newton fails, and static
forcing, on the forced 1-dof oscillator against an obstacle of test_obstacle.py."""
from dataclasses import replace

import numpy as np
import pytest

import test_obstacle as t
from hbm.harmonic import nfrc as nfrc_module
from hbm.harmonic.condensation import HarmonicForcing
from hbm.harmonic.fourier import FourierBasis
from hbm.harmonic.nfrc import compute_nfrc, default_continuation, nfrc_extras
from hbm.harmonic.residual import build_residual
from hbm.harmonic.start import damped_newton, solve_start
from hbm.linalg.dense import DirectSolver
from hbm.options import CasingOptions, ContactOptions, HbmOptions

HBM = HbmOptions(n_harmonics=16, n_time=512)


def _lobe(tau, d0=1.5, d1=0.4, w=0.6):
    """An obstacle that comes down to d1 around tau = 0 (where the forced orbit peaks) and
    stays at d0, above the free orbit (amplitude 1.33), elsewhere. (N_t, 1), m."""
    phi = np.mod(tau + np.pi, 2 * np.pi) - np.pi
    return (d0 - (d0 - d1) * np.exp(-(phi / w) ** 2))[:, None]


def _residual(method, kappa, distance, hbm=HBM, forcing=None):
    rom, f, _ = t._model("rl")  # the boundary dof is x itself, for both treatments here
    contact = ContactOptions(kappa=kappa, gamma=0.0, epsilon=3.0, mu=0.0, lanczos=False)
    return build_residual(rom, CasingOptions(), contact, hbm, method=method,
                          forcing=forcing or HarmonicForcing(f, 1), alpha=1.0, distance=distance)


def _start(res):
    opts = default_continuation(HBM)
    free = damped_newton(res, res.linear_solution(t.W), t.W, opts.newton, DirectSolver())
    u, note = solve_start(res, t.W, opts, DirectSolver())
    assert np.linalg.norm(res(u, t.W, jacobian=False)) <= opts.newton.tol_residual  # recomputed here
    return free.converged, u, note


def test_obstacle_homotopy_reaches_a_start_newton_cannot():
    """A lobe that cuts into the forced orbit: damped Newton from the contact-free solution
    fails for both treatments (and RL's DLFT route too); the homotopy from a round obstacle
    above the orbit (no contact) to the lobe reaches a solution. RL's stiff penalty
    (kappa = 1e3 against k = 1) must then sit close to DLFT's rigid obstacle: within its
    penetration and the two laws' different N_h = 16 truncations (measured 3.2e-3)."""
    amps = {}
    for method, kappa in (("dlft", 1e3), ("rl", 1e3)):
        res = _residual(method, kappa, _lobe)
        newton_ok, u, note = _start(res)
        assert not newton_ok  # the fallback is what is under test
        assert note.startswith("obstacle homotopy: reached"), note
        assert res.samples(res.to_coefficients(u), t.W).active.any()  # in contact
        amps[method] = nfrc_extras(res, u)["le_amplitude"]
    assert amps["dlft"] > 1.5  # the lobe does change the orbit (free: 1.33)
    assert abs(amps["rl"] - amps["dlft"]) / amps["dlft"] < 5e-3


def test_kappa_homotopy_reaches_the_stiff_penalty_solution(monkeypatch):
    """The flat obstacle with a penalty 100 times the oscillator's stiffness: damped Newton
    from the contact-free solution fails; the DLFT solution (rigid) followed by the homotopy
    in log10 kappa from epsilon to kappa gives the RL solution, checked against the exact
    piecewise-linear periodic orbit (matrix-exponential shooting, test_obstacle) to the
    N_h = 32 truncation error (measured 3.4e-4)."""
    monkeypatch.setattr(t, "KAPPA", 100.0)
    hbm = HbmOptions(n_harmonics=32, n_time=2048)
    res = _residual("rl", 100.0, lambda tau: np.full((len(tau), 1), t.D), hbm=hbm)
    opts = default_continuation(hbm)
    assert not damped_newton(res, res.linear_solution(t.W), t.W, opts.newton, DirectSolver()).converged
    u, note = solve_start(res, t.W, opts, DirectSolver())
    assert note.startswith("DLFT solution then kappa homotopy"), note
    x = FourierBasis(32, t.NG).to_time(res.expand_harmonics(u, t.W)[:, 0])
    v = t.W * FourierBasis(32, t.NG).to_time(FourierBasis(32, t.NG).derivative(
        res.expand_harmonics(u, t.W)[:, [0]]))[:, 0]
    ref = t._reference(np.array([x[0], v[0]]))
    assert ref.max() > t.D + 5e-3  # the exact orbit is in contact (penetration ~0.8 % at kappa = 100)
    assert np.abs(x - ref).max() / np.abs(ref).max() < 1e-3


@pytest.mark.parametrize("kappa_start, line_search", [(3.0, True), (1e3, False), (100.0, False)])
def test_kappa_homotopy_from_either_side_and_with_a_line_search(monkeypatch, kappa_start, line_search):
    """The kappa homotopy from a softer (3), a stiffer (1e3: down) or the same penalty (100:
    Newton alone) reaches the solution at kappa = 100, the exact piecewise-linear orbit to the
    N_h = 32 truncation (3.4e-4, as above); with the corrector's line search on, its merit
    takes R alone from the homotopy's residual."""
    from hbm.harmonic.start import penalty_homotopy
    monkeypatch.setattr(t, "KAPPA", 100.0)
    hbm = HbmOptions(n_harmonics=32, n_time=2048)
    flat = lambda tau: np.full((len(tau), 1), t.D)  # noqa: E731
    res, dl = _residual("rl", 100.0, flat, hbm=hbm), _residual("dlft", 100.0, flat, hbm=hbm)
    opts = default_continuation(hbm)
    opts = replace(opts, newton=replace(opts.newton, line_search=line_search))
    u_dlft = damped_newton(dl, dl.linear_solution(t.W), t.W, opts.newton, DirectSolver()).x
    u, note = penalty_homotopy(res, u_dlft, t.W, opts, DirectSolver(), kappa_start)
    assert u is not None, note
    assert np.linalg.norm(res(u, t.W, jacobian=False)) <= opts.newton.tol_residual
    basis = FourierBasis(32, t.NG)
    c = res.expand_harmonics(u, t.W)[:, [0]]
    x, v = basis.to_time(c)[:, 0], t.W * basis.to_time(basis.derivative(c))[:, 0]
    ref = t._reference(np.array([x[0], v[0]]))
    assert np.abs(x - ref).max() / np.abs(ref).max() < 1e-3


def test_start_from_the_other_end(monkeypatch):
    """When no start converges at the end of the range the scene names, compute_nfrc starts
    at the other end and runs back: the same curve as a run started there."""
    dist = lambda tau: np.full((len(tau), 1), t.D)  # noqa: E731
    hbm = replace(HBM, omega_min=0.45, omega_max=0.55)
    cont = replace(default_continuation(hbm), omega_scale=0.1, ds_max=0.2)
    rom, f, _ = t._model("rl")
    kw = dict(hbm=hbm, method="dlft", continuation=cont, solver=DirectSolver())
    ref = compute_nfrc(rom, residual=_residual("dlft", 4.0, dist, hbm), **{**kw, "continuation": replace(
        cont, direction=1)})
    real = nfrc_module.solve_start

    def fail_at_the_top(res, omega, opts, solver):
        if omega == hbm.omega_max:
            return res.linear_solution(omega) + 1.0, "made to fail"
        return real(res, omega, opts, solver)

    monkeypatch.setattr(nfrc_module, "solve_start", fail_at_the_top)
    r = compute_nfrc(rom, residual=_residual("dlft", 4.0, dist, hbm), **kw)
    assert "at the other end" in r.start and r.converged.all()
    assert r.omega[0] == pytest.approx(hbm.omega_min) and r.omega[-1] == pytest.approx(hbm.omega_max)
    np.testing.assert_allclose(np.interp(ref.omega, r.omega, r.le_amplitude), ref.le_amplitude, rtol=1e-6)


def test_no_start_at_either_end_is_reported_at_the_scene_s_end(monkeypatch):
    """No start converges at either end: the NFRC is the failed start at the end the scene
    names (omega_max here), with its reason; it does not move to the other end, where
    nothing converged either, and its start note gives each end's reason (it gave the
    first end's alone)."""
    dist = lambda tau: np.full((len(tau), 1), t.D)  # noqa: E731
    hbm = replace(HBM, omega_min=0.45, omega_max=0.55)
    cont = replace(default_continuation(hbm), omega_scale=0.1, ds_max=0.2)
    rom, f, _ = t._model("rl")

    def fail(res, omega, opts, solver):
        return res.linear_solution(omega) + 1.0, f"made to fail at {omega:g}"

    monkeypatch.setattr(nfrc_module, "solve_start", fail)
    r = compute_nfrc(rom, residual=_residual("dlft", 4.0, dist, hbm), hbm=hbm, method="dlft", continuation=cont,
                     solver=DirectSolver())
    assert r.start == "at omega=0.55: made to fail at 0.55; at omega=0.45: made to fail at 0.45"
    assert r.omega.tolist() == [pytest.approx(hbm.omega_max)] and not r.converged.any()
    assert r.status.startswith("start point did not converge") and r.reason[0] == r.status


@pytest.mark.parametrize("method", ["rl", "dlft"])
def test_static_forcing_against_the_obstacle(method):
    """A static force (harmonic k = 0) pushing the oscillator into the obstacle: the exact
    equilibrium of k x + kappa (x - d)_+ = F is x = (F + kappa d) / (k + kappa) (RL, the
    penalty law with gamma = 0), and x = d for DLFT's rigid obstacle; nothing oscillates."""
    rom, _, fdof = t._model("rl")
    F = 3.0  # > k d = 1: in contact
    f = np.zeros(rom.K.shape[0])
    f[fdof] = F
    res = _residual(method, t.KAPPA, lambda tau: np.full((len(tau), 1), t.D),
                    forcing=HarmonicForcing(f, 0))
    u, _ = solve_start(res, t.W, default_continuation(HBM), DirectSolver())
    x = res.expand_harmonics(u, t.W)[:, fdof]
    exact = (F + t.KAPPA * t.D) / (t.K + t.KAPPA) if method == "rl" else t.D
    assert x[0] == pytest.approx(exact, rel=1e-9)
    assert np.abs(x[1:]).max() < 1e-9


def test_past_the_friction_lock_the_start_is_followed_from_the_frictionless_one():
    """The coarse rotor 67 ROM at 2000 rad/s, N_h = 40, mu = 0.25 (past its friction lock,
    mu_set = 0.123): damped Newton, the obstacle homotopy and Newton from the frictionless
    solution all fail there (the solutions fold in mu: climbing to 0.19, back to 0.14, on to
    0.25), and the NFRC had no start at either end of its range. The arc length in mu from
    mu = 0 reaches a solution: the residual of the scene's mu, built afresh, vanishes there,
    it is the one the isola search finds by another road, and the residual the homotopy was
    handed is left at the scene's mu."""
    from hbm.harmonic.solver import HbmSolver
    from support import coarse_rom

    rom = coarse_rom()
    hbm = HbmOptions(n_harmonics=40, n_time=1024)
    contact = ContactOptions(mu=0.25)
    opts = default_continuation(hbm)
    solver = HbmSolver(atol=0.1 * opts.newton.tol_residual)
    res = build_residual(rom, CasingOptions(), contact, hbm, method="dlft")
    u, note = solve_start(res, 2000.0, opts, solver)  # the other strategies first, as the NFRC does
    assert note.startswith("friction homotopy from mu = 0 (damped Newton from the contact-free solution; "), note
    assert res.contact == contact
    fresh = build_residual(rom, CasingOptions(), contact, hbm, method="dlft")
    assert np.linalg.norm(fresh(u, 2000.0, jacobian=False)) <= opts.newton.tol_residual
    # the solution the isola search reaches from its own seeds (`bladerub run
    # scenes/rotor67_coarse.toml --set contact.mu=0.25`: DLFT's detached branch over 1979-2000
    # rad/s, 0.9018315 mm at 2000 rad/s); the fold's other solution there has 0.9091 mm
    assert nfrc_extras(fresh, u)["le_amplitude"] == pytest.approx(0.9018315e-3, rel=1e-6)


def test_a_friction_homotopy_that_finds_no_frictionless_start_says_so_and_leaves_mu_alone():
    """With a tolerance no iterate meets, the frictionless start fails too: the friction
    homotopy's reason says so, after the other strategies' reasons, and the residual is left
    at the scene's mu (not at the mu = 0 the homotopy started from)."""
    from hbm.harmonic.solver import HbmSolver
    from support import coarse_rom

    hbm = HbmOptions(n_harmonics=3, n_time=32)
    contact = ContactOptions(mu=0.25)
    opts = default_continuation(hbm)
    opts = replace(opts, newton=replace(opts.newton, tol_residual=1e-300))
    res = build_residual(coarse_rom(), CasingOptions(), contact, hbm, method="dlft")
    u, note = solve_start(res, 2000.0, opts, HbmSolver(atol=1e-12))
    assert note.startswith("no start found: damped Newton from the contact-free solution: ") and \
        "; obstacle homotopy: " in note and "; friction homotopy: no start at mu = 0 (no start found: " in note, note
    assert res.contact == contact
