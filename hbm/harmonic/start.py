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
from hbm.continuation.branch import STATUS_OMEGA_MAX
from hbm.continuation.newton import NewtonOptions, NewtonResult, newton_solve
from hbm.harmonic.residual import HarmonicBalanceResidual, build_residual
from hbm.linalg.protocol import LinearSolver


def damped_newton(res, u0: np.ndarray, omega: float, opts: NewtonOptions, solver: LinearSolver,
                  max_iter: int = 40) -> NewtonResult:
    """Newton at fixed omega with backtracking on ||R|| (up to 8 halvings of each step) and
    max_iter iterations: for far-off guesses (stiff penalty contact, u0 = contact-free
    solution). The continuation's corrector stays plain Newton."""
    return newton_solve(res, u0, omega, replace(opts, line_search=True, max_iter=max_iter), solver=solver)


def _in_parameter(res, omega: float, set_value, h: float, *, forward: bool = False, reset=None):
    """residual(u, p, jacobian=True) -> (R, dR/du, dR/dp) of an arc length in a parameter p
    that set_value(p) puts into res (at fixed omega, rad/s): dR/dp by a central difference
    of step h, or a forward one (a parameter that may not go below its start); reset(), when
    given, runs after every call. jacobian False: R alone (a line search's merit). The
    derivative is a start-up aid only: the continuation's corrector checks the answer."""
    def residual(u, p, jacobian=True):
        try:
            set_value(p)
            if not jacobian:
                return res(u, omega, jacobian=False)
            R, J, _ = res(u, omega)
            set_value(p + h)
            Rp = res(u, omega, jacobian=False)
            if forward:
                return R, J, (Rp - R) / h
            set_value(p - h)
            return R, J, (Rp - res(u, omega, jacobian=False)) / (2 * h)
        finally:
            if reset is not None:
                reset()
    return residual


def penalty_homotopy(res: HarmonicBalanceResidual, u_soft: np.ndarray, omega: float, opts: ContinuationOptions,
                     solver: LinearSolver, kappa_start: float) -> tuple[np.ndarray | None, str]:
    """RL's solution at the scene's kappa, followed from u_soft, a solution (or a close guess,
    corrected first) at the penalty kappa_start, by an arc length in q = log10 kappa, up or
    down (the RL solution can fold in kappa: it does at Omega = 400 rad/s on the rotor 67
    ROM); at kappa_start = kappa, Newton from u_soft. Returns (u, note), u None when
    neither reaches a solution at the scene's kappa."""
    c = res.contact
    rk = build_residual(res.rom, res.casing, c, res.options, method="rl", forcing=res.forcing,
                        alpha=res.alpha, friction=res.friction, distance=res._distance)
    lo, hi = np.log10(kappa_start), np.log10(c.kappa)
    if hi == lo:
        sol = newton_solve(rk, u_soft, omega, opts.newton, solver=solver)
        return (sol.x, "Newton at kappa") if sol.converged else (None, f"Newton at kappa: {sol.reason}")

    # q = log10 kappa
    penalty = _in_parameter(rk, omega, lambda q: setattr(rk, "contact", replace(c, kappa=float(10.0 ** q))), 1e-5)
    kopt = replace(opts, omega_min=min(lo, hi), omega_max=max(lo, hi), omega_scale=0.5, ds=0.05, ds_max=0.5,
                   closed_loop_tol=None, direction=1 if hi > lo else -1, max_points=300)
    br = continue_branch(penalty, u_soft, lo, kopt, solver=solver)
    if br.converged[-1] and abs(br.omega[-1] - hi) < 1e-9:
        return br.x[-1], f"kappa homotopy ({len(br)} points)"
    return None, f"kappa homotopy: {br.status}"


def obstacle_homotopy(res: HarmonicBalanceResidual, omega: float, opts: ContinuationOptions,
                      solver: LinearSolver) -> tuple[np.ndarray, str]:
    """An arc length in the obstacle scale s (hbm.harmonic.residual set_obstacle_scale) from
    a round casing at the clearance (s = 0: the contact-free solution solves it) to the real
    casing (s = 1). Returns (u, note): u the last point, a solution only if the note says
    the homotopy reached s = 1 ("reached omega_max")."""
    homotopy = _in_parameter(res, omega, res.set_obstacle_scale, 1e-6, reset=lambda: res.set_obstacle_scale(1.0))
    hopt = replace(opts, omega_min=0.0, omega_max=1.0, omega_scale=0.2, ds=0.05, ds_max=0.5,
                   closed_loop_tol=None, direction=1, max_points=200)
    br = continue_branch(homotopy, res.linear_solution(omega), 0.0, hopt, solver=solver)
    # the branch's parameter is s, not a speed: its reasons' "omega=0.15" read "s=0.15"
    return br.x[-1], f"obstacle homotopy: {br.status.replace('omega=', 's=')} ({len(br)} points)"


def friction_homotopy(res: HarmonicBalanceResidual, omega: float, opts: ContinuationOptions,
                      solver: LinearSolver) -> tuple[np.ndarray | None, str]:
    """The solution at the scene's mu followed from the frictionless one (mu = 0, started by
    solve_start) by an arc length in mu. Past the friction lock the solutions can fold in mu,
    out of a jump's reach: on the coarse rotor 67 ROM at 2000 rad/s and N_h = 40, damped
    Newton from the solutions at mu = 0, 0.1 or 0.15 fails at mu = 0.25 (at 0.2 no other
    strategy starts), while the branch in mu climbs to 0.19, folds back to 0.14 and climbs
    again, reaching 0.25 in about 480 points (DLFT and RL alike). Returns (u, note), u None
    when it does not reach the scene's mu."""
    c = res.contact
    try:
        res.contact = replace(c, mu=0.0)  # res.friction stays on: the friction terms vanish
        u0, note0 = solve_start(res, omega, opts, solver)
        if not note0 or note0.startswith("no start found"):
            return None, f"friction homotopy: no start at mu = 0 ({note0})"

        in_mu = _in_parameter(res, omega, lambda mu: setattr(res, "contact", replace(c, mu=mu)), 1e-6, forward=True)

        def friction(u, mu, jacobian=True):  # a predictor past mu = 0 (a fold back): ContactOptions refuses mu < 0
            return in_mu(u, max(float(mu), 0.0), jacobian)

        mopt = replace(opts, omega_min=0.0, omega_max=c.mu, omega_scale=0.05, ds=0.05, ds_max=0.5,
                       closed_loop_tol=None, direction=1, max_points=1000)
        br = continue_branch(friction, u0, 0.0, mopt, solver=solver)
    finally:
        res.contact = c
    if br.converged[-1] and abs(br.omega[-1] - c.mu) < 1e-12:
        return br.x[-1], f"friction homotopy from mu = 0 ({note0}; {len(br)} points)"
    # the branch's parameter is mu, not a speed: its reasons' "omega=0.15" read "mu=0.15"
    return None, f"friction homotopy: {br.status.replace('omega=', 'mu=')} ({len(br)} points)"


def solve_start(res: HarmonicBalanceResidual, omega: float, opts: ContinuationOptions,
                solver: LinearSolver) -> tuple[np.ndarray, str]:
    """Start point at omega, tried in order until one converges:

    1. damped Newton from the contact-free solution;
    2. (RL only) the DLFT solution at omega (same N_h, N_t, epsilon of the scene; DLFT
       starts easily because its Jacobian outside contact is Z_r and inside it is
       epsilon-regular), then penalty_homotopy from kappa = epsilon to the scene's kappa:
       the stiff kappa = 1e9 law is out of Newton's reach from far away but close to the
       softer solutions;
    3. obstacle_homotopy from a round casing to the real one;
    4. (with friction) friction_homotopy from mu = 0, past the friction lock.
    Returns (u, note); u is the best available guess (continue_branch corrects it again
    and records a failure with its reason if it is no solution). When no strategy reaches
    a solution, the note gives each one's reason for failing.
    """
    u_lin = res.linear_solution(omega)
    sol = damped_newton(res, u_lin, omega, opts.newton, solver)
    if sol.converged:
        return sol.x, "damped Newton from the contact-free solution"
    failed = [f"damped Newton from the contact-free solution: {sol.reason}"]
    if res.method == "rl":
        dl = build_residual(res.rom, res.casing, res.contact, res.options, method="dlft", forcing=res.forcing,
                            alpha=res.alpha, friction=res.friction, distance=res._distance)
        sd = damped_newton(dl, u_lin, omega, opts.newton, solver)
        if sd.converged:
            u, note = penalty_homotopy(res, sd.x, omega, opts, solver, res.contact.epsilon)
            if u is not None:
                return u, f"DLFT solution then {note}"
            failed.append(f"DLFT solution then {note}")
        else:
            failed.append(f"DLFT solution: {sd.reason}")
    u, note = obstacle_homotopy(res, omega, opts, solver)
    if note.startswith(f"obstacle homotopy: {STATUS_OMEGA_MAX}"):
        return u, note
    failed.append(note)
    if res.friction and res.contact.mu > 0.0:
        uf, notef = friction_homotopy(res, omega, opts, solver)
        if uf is not None:
            return uf, notef
        failed.append(notef)
    return u, f"no start found: {'; '.join(failed)}"


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
