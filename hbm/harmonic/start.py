"""Start points of an NFRC: Newton from the contact-free solution, then homotopies.

The stiff contact laws (RL's kappa = 1e9 N/m penalty) are out of Newton's reach from the
contact-free solution at some speeds; these strategies bring the start point into contact
gently. They are start-up aids only: the continuation corrects what they return again and
records a failure, with its reason, if it is no solution.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from hbm.continuation.arclength import ContinuationOptions, continue_branch
from hbm.continuation.newton import NewtonOptions, NewtonResult, newton_solve
from hbm.harmonic.residual import HarmonicBalanceResidual, build_residual
from hbm.linalg.protocol import LinearSolver


def damped_newton(res, u0: np.ndarray, omega: float, opts: NewtonOptions, solver: LinearSolver,
                  max_iter: int = 40) -> NewtonResult:
    """Newton at fixed omega with backtracking on ||R|| (up to 8 halvings of each step) and
    max_iter iterations: for far-off guesses (stiff penalty contact, u0 = contact-free
    solution). The continuation's corrector stays plain Newton."""
    return newton_solve(res, u0, omega, replace(opts, line_search=True, max_iter=max_iter), solver=solver)


def solve_start(res: HarmonicBalanceResidual, omega: float, opts: ContinuationOptions,
                solver: LinearSolver) -> tuple[np.ndarray, str]:
    """Start point at omega, tried in order until one converges:

    1. damped Newton from the contact-free solution;
    2. (RL only) the DLFT solution at omega (same N_h, N_t, epsilon of the scene; DLFT
       starts easily because its Jacobian outside contact is Z_r and inside it is
       epsilon-regular), then a penalty homotopy kappa = epsilon -> kappa of the scene: the
       stiff kappa = 1e9 law is out of Newton's reach from far away but close to the
       softer solutions; an arc length in log10 kappa, as the RL solution can fold in
       kappa (it does at Omega = 400 rad/s on the rotor 67 ROM);
    3. an arc-length homotopy from a round casing (obstacle scale s = 0) to the real one.
    Returns (u, note); u is the best available guess (continue_branch corrects it again
    and records a failure with its reason if it is no solution).
    """
    u_lin = res.linear_solution(omega)
    sol = damped_newton(res, u_lin, omega, opts.newton, solver)
    if sol.converged:
        return sol.x, "damped Newton from the contact-free solution"
    if res.method == "rl":
        c = res.contact
        dl = build_residual(res.rom, res.casing, c, res.options, method="dlft", forcing=res.model.forcing,
                            alpha=res.alpha, friction=res.friction, distance=res._distance)
        sd = damped_newton(dl, u_lin, omega, opts.newton, solver)
        if sd.converged:
            rk = build_residual(res.rom, res.casing, c, res.options, method="rl", forcing=res.model.forcing,
                                alpha=res.alpha, friction=res.friction, distance=res._distance)
            lo, hi = np.log10(min(c.epsilon, c.kappa)), np.log10(c.kappa)

            def penalty(u, q, jacobian=True):  # q = log10 kappa; dR/dq by central difference
                rk.contact = replace(c, kappa=float(10.0 ** q))
                R, J, _ = rk(u, omega)
                h = 1e-5
                rk.contact = replace(c, kappa=float(10.0 ** (q + h)))
                Rp = rk(u, omega, jacobian=False)
                rk.contact = replace(c, kappa=float(10.0 ** (q - h)))
                Rm = rk(u, omega, jacobian=False)
                return R, J, (Rp - Rm) / (2 * h)

            if hi > lo:
                kopt = replace(opts, omega_min=lo, omega_max=hi, omega_scale=0.5, ds=0.05, ds_max=0.5,
                               closed_loop_tol=None, direction=1, max_points=300)
                br = continue_branch(penalty, sd.x, lo, kopt, solver=solver)
                if br.converged[-1] and abs(br.omega[-1] - hi) < 1e-9:
                    return br.x[-1], f"DLFT solution then kappa homotopy ({len(br)} points)"
            else:
                return sd.x, "DLFT solution"

    def homotopy(u, s, jacobian=True):
        res.set_obstacle_scale(s)
        try:
            R, J, _ = res(u, omega)
            h = 1e-6
            res.set_obstacle_scale(s + h)
            Rp = res(u, omega, jacobian=False)
            res.set_obstacle_scale(s - h)
            Rm = res(u, omega, jacobian=False)
        finally:
            res.set_obstacle_scale(1.0)
        return R, J, (Rp - Rm) / (2 * h)  # dR/ds by central difference: a start-up aid only

    hopt = replace(opts, omega_min=0.0, omega_max=1.0, omega_scale=0.2, ds=0.05, ds_max=0.5,
                   closed_loop_tol=None, direction=1, max_points=200)
    br = continue_branch(homotopy, u_lin, 0.0, hopt, solver=solver)
    return br.x[-1], f"obstacle homotopy: {br.status} ({len(br)} points)"


def pad_harmonics(u: np.ndarray, n_r: int, n_harmonics: int) -> np.ndarray:
    """Unknowns of another N_h on n_harmonics: u ((2 N_h' + 1) n_r,) in eq. (5) order ->
    ((2 n_harmonics + 1) n_r,), the missing higher harmonics zero (or the extra ones
    dropped). A start guess from a cheap low-N_h solution, which carries the contact
    phase and the low harmonics that the contact-free solution lacks."""
    u = np.asarray(u, dtype=float).reshape(-1, n_r)
    out = np.zeros((2 * n_harmonics + 1, n_r))
    m = min(len(u), len(out))
    out[:m] = u[:m]
    return out.reshape(-1)
