"""The structured HBM Jacobian (hbm/harmonic/jacobian.py) and its solver against dense algebra.

The dense form is the one checked against finite differences in test_jacobians.py, so
what must hold here is algebra: the FFT product J @ v equals the dense product to
rounding, the Woodbury preconditioner is an exact inverse where it claims to be (no
friction), and the GMRES solves meet their tolerance, with a fresh or a reused
preconditioner, for J x = b and for the bordered system of the arc-length corrector.
The last test runs an NFRC window both ways: the same points, to the Newton tolerance.
"""
import dataclasses

import numpy as np
import pytest

from hbm.harmonic.residual import build_residual
from hbm.harmonic.nfrc import compute_nfrc, default_continuation
from hbm.harmonic.preconditioner import ContactPreconditioner
from hbm.harmonic.solver import HbmSolver
from hbm.linalg.dense import DirectSolver
from hbm.options import CasingOptions, ContactOptions, HbmOptions
from support import coarse_rom, distance_to_polyline, forced_standin_residual, perturbed_state


CASES = [("dlft", 0.0), ("dlft", 0.15), ("rl", 0.0), ("rl", 0.15)]


def _state(method, mu, seed=3, omega=900.0, nh=8, nt=128):
    """A residual and a state with several nodes in contact part of the period."""
    res = forced_standin_residual(method, n_harmonics=nh, n_time=nt, mu=mu)
    return res, perturbed_state(res, seed, omega), omega


def _pair(res, u, omega):
    R, Js, rw = res(u, omega)
    return R, np.asarray(Js), Js, rw


@pytest.mark.parametrize("method,mu", CASES)
def test_product_and_dense_form_agree(method, mu):
    res, u, om = _state(method, mu)
    R, Jd, Js, _ = _pair(res, u, om)
    assert len(Js.nodes) >= 3  # the contact part is exercised
    V = np.random.default_rng(0).standard_normal((res.size, 3))
    # FFT path against the dense matrix: rounding of two real FFTs, ~1e-15 relative
    assert np.abs(Js @ V - Jd @ V).max() <= 1e-12 * np.abs(Jd @ V).max()


@pytest.mark.parametrize("method", ["dlft", "rl"])
def test_preconditioner_is_exact_without_friction(method):
    res, u, om = _state(method, 0.0)
    _, Jd, Js, _ = _pair(res, u, om)
    b = np.random.default_rng(1).standard_normal(res.size)
    x = ContactPreconditioner(Js)(b)
    # a direct solve (Woodbury form): its error is rounding times the condition number
    assert np.linalg.norm(Jd @ x - b) <= 1e-9 * np.linalg.norm(b)
    solver = HbmSolver()
    solver.factorize(Js).solve(b)
    assert solver.stats.get("krylov", 0) == 0  # no Krylov iteration needed
    # asked for in single precision, it is no longer exact: GMRES takes over and meets rtol
    solver = HbmSolver(rtol=1e-10, single=True)
    x = solver.factorize(Js).solve(b)
    assert solver.stats["krylov"] >= 1 and np.linalg.norm(Jd @ x - b) <= 1e-9 * np.linalg.norm(b)


@pytest.mark.parametrize("method", ["dlft", "rl"])
def test_single_precision_preconditioner_costs_at_most_two_iterations(method):
    """With friction the contact system's LU is single precision (the preconditioner is not
    J's inverse anyway): GMRES still meets 1e-10 in double, at most 2 iterations more than
    with the double-precision LU (stand-in: DLFT 5 / 5, RL 12 / 10)."""
    res, u, om = _state(method, 0.15)
    _, Jd, Js, _ = _pair(res, u, om)
    b = np.random.default_rng(1).standard_normal(res.size)
    its = {}
    for single in (True, False):
        pre = ContactPreconditioner(Js, single)
        assert pre.single is single and pre.lu[0].dtype == (np.float32 if single else np.float64)
        solver = HbmSolver(rtol=1e-10)
        x = solver.factorize(Js, preconditioner=pre).solve(b)
        assert np.linalg.norm(Jd @ x - b) <= 1e-9 * np.linalg.norm(b)
        its[single] = solver.stats["krylov"]
    assert its[True] <= its[False] + 2
    assert ContactPreconditioner(Js).single  # the default with friction
    res0, u0, om0 = _state(method, 0.0)
    assert not ContactPreconditioner(res0(u0, om0)[1]).single  # exact: double


@pytest.mark.parametrize("method,mu", CASES)
def test_solves_meet_their_tolerance_fresh_and_reused(method, mu):
    res, u, om = _state(method, mu)
    _, Jd, Js, rw = _pair(res, u, om)
    b = np.random.default_rng(2).standard_normal(res.size)
    x_ref = np.linalg.solve(Jd, b)
    # a preconditioner from another state and speed: GMRES has to do the work
    res2, u2, om2 = _state(method, mu, seed=4, omega=880.0)
    old = ContactPreconditioner(res2(u2, om2)[1])
    for pre in (None, old):
        solver = HbmSolver(rtol=1e-10)
        x = solver.factorize(Js, preconditioner=pre).solve(b)
        assert np.linalg.norm(Jd @ x - b) <= 1e-9 * np.linalg.norm(b)
        assert np.linalg.norm(x - x_ref) <= 1e-6 * np.linalg.norm(x_ref)
        assert solver.stats.get("dense_fallback", 0) == 0


@pytest.mark.parametrize("method,mu", CASES)
def test_bordered_solve_matches_the_dense_one(method, mu):
    res, u, om = _state(method, mu)
    R, Jd, Js, rw = _pair(res, u, om)
    rng = np.random.default_rng(5)
    p, q, P = rng.standard_normal(res.size), 0.7, 0.3
    A = np.block([[Jd, rw[:, None]], [p[None, :], np.array([[q]])]])
    d_ref = np.linalg.solve(A, -np.append(R, P))
    rhs = np.linalg.norm(np.append(R, P))
    solver = HbmSolver(rtol=1e-10, forcing=0.0)  # an exact step
    dx, dw, full = solver.factorize(Js).solve_bordered(rw, p, q, R, P)
    assert not full
    d = np.append(dx, dw)
    assert np.linalg.norm(A @ d + np.append(R, P)) <= 1e-8 * rhs
    assert np.linalg.norm(d - d_ref) <= 1e-6 * np.linalg.norm(d_ref)
    assert "last_krylov" in solver.stats  # it went through the one-GMRES bordered path
    # inexact Newton step: relative residual min(1e-3, max(rtol, forcing ||rhs||)), here 1e-3
    solver = HbmSolver(rtol=1e-10, forcing=1e-2)
    dx, dw, full = solver.factorize(Js).solve_bordered(rw, p, q, R, P)
    err = np.linalg.norm(A @ np.append(dx, dw) + np.append(R, P)) / rhs
    assert not full and err <= 2e-3
    assert solver.stats["krylov"] < HbmSolver(rtol=1e-10, forcing=0.0).max_krylov
    if not mu:
        return  # without friction the preconditioner is exact: one iteration, nothing to relax
    # atol: an absolute residual target (what Newton's test can see) relaxes a tight rtol
    exact_its = HbmSolver(rtol=1e-10, forcing=0.0)
    exact_its.factorize(Js).solve_bordered(rw, p, q, R, P)
    atol = 1e-5 * rhs
    solver = HbmSolver(rtol=1e-10, forcing=0.0, atol=atol)
    dx, dw, full = solver.factorize(Js).solve_bordered(rw, p, q, R, P)
    res_abs = np.linalg.norm(A @ np.append(dx, dw) + np.append(R, P))
    assert not full and res_abs <= 2.0 * atol  # GMRES's estimate, checked by solve_bordered
    assert res_abs > 1e-8 * rhs  # it did stop early ...
    assert solver.stats["krylov"] < exact_its.stats["krylov"]  # ... and saved iterations


@pytest.mark.parametrize("method", ["dlft", "rl"])
def test_nfrc_window_same_with_dense_and_structured_jacobians(method):
    """Same continuation, two linear algebras, on the coarse rotor 67 ROM from 2000 rad/s
    down into the contact of the 2B superharmonic: the points agree to what Newton's
    tolerance (1e-8 on the scaled residual) leaves; the curves agree to the sag of the
    chords between points (0.1 % of a step at ds_max = 0.5)."""
    rom = coarse_rom()
    hbm = HbmOptions(n_harmonics=5, n_time=64, omega_min=1900.0, omega_max=2000.0)
    cont = dataclasses.replace(default_continuation(hbm), max_points=40, ds_max=0.5)  # small chords: small sag
    out = {}
    for structured in (False, True):
        out[structured] = compute_nfrc(rom, hbm=hbm, method=method, continuation=cont,
                                       solver=None if structured else DirectSolver())
    a, b = out[False], out[True]
    assert len(a.omega) == len(b.omega) >= 20 and a.converged.all() and b.converged.all()
    n_contact = sum(bool(np.any(r.samples(r.to_coefficients(x), w).active))
                    for r in [build_residual(rom, CasingOptions(), ContactOptions(), hbm, method=method)]
                    for x, w in zip(b.unknowns, b.omega))
    assert n_contact >= 10  # the window is in contact, not a linear stretch
    # The runs take different Newton paths (GMRES steps are inexact Newton steps), so their
    # step sequences differ and the points do not coincide. What must hold: every point of
    # one run lies on the other's polyline, in the continuation's scaled metric (u, omega /
    # 100), to a small fraction of a step: the chord's sag between points is the limit.
    pa = np.column_stack([a.unknowns, a.omega / 100.0])
    pb = np.column_stack([b.unknowns, b.omega / 100.0])

    step = np.median(np.linalg.norm(np.diff(pa, axis=0), axis=1))
    n = min(len(pa), len(pb)) - 3  # the common stretch (the ends may differ by a step)
    worst = max(distance_to_polyline(pb[:n], pa).max(), distance_to_polyline(pa[:n], pb).max())
    assert worst < 1e-3 * step  # measured 2e-6 (DLFT), 1e-8 (RL) at ds_max = 0.5


def test_structured_jacobian_is_a_frozen_record():
    res, u, om = _state("rl", 0.15)
    J = res(u, om)[1]
    with pytest.raises(dataclasses.FrozenInstanceError):
        J.scale = 2.0
