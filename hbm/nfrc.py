"""Nonlinear frequency response curve of the rotor blade against the ovalised casing.

`compute_nfrc` follows the omega = Omega branch over [omega_start, omega_end] with the
arc-length continuation of hbm.continuation, from the contact-free solution at
omega_start, for one contact treatment (DLFT or RL), and returns every point with the
leading-edge (LE) radial amplitude of Fig. 6.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np

from hbm.continuation import ContinuationOptions, ContinuationPoint, continue_branch
from hbm.harmonic_balance import HarmonicBalanceResidual, HarmonicForcing, build_residual
from hbm.jacobian_solver import ReusedLu
from hbm.newton import NewtonOptions, newton_solve
from hbm.options import CasingOptions, ContactOptions, HbmOptions


@dataclass(frozen=True)
class NfrcPoint:
    """One point handed to on_point.

    index; omega: Omega = omega, rad/s; harmonics: condensed boundary-dof harmonics,
    (2 N_h + 1, 3 n_b), m, eq. (5) order; le_amplitude: peak-to-peak LE radial
    displacement max - min over the period, m; le_max: max over the period of the LE
    radial displacement, m; residual_norm (scaled residual, 1); iterations; step (scaled
    arc length); time, s; converged; reason ("" when converged).
    """

    index: int
    omega: float
    harmonics: np.ndarray
    le_amplitude: float
    le_max: float
    residual_norm: float
    iterations: int
    step: float
    time: float
    converged: bool
    reason: str


@dataclass(frozen=True)
class NfrcResult:
    """A computed NFRC, m points.

    method: "dlft" or "rl". omega (m,), rad/s. harmonics (m, 2 N_h + 1, 3 n_b), m.
    le_amplitude (m,), m: peak-to-peak LE radial displacement (the y-axis of Fig. 6).
    le_max (m,), m. residual_norm, iterations, step, time (s), converged (m,).
    reason (m,) str: "" for converged points, why for the last failed one.
    status: why the branch stopped (hbm.continuation STATUS_*). wall_time, s.
    n_factorizations: LU factorisations of the Jacobian. unknowns: x of every point in
    the residual's scaled unknowns (m, n_u), to restart or expand (residual.expand_harmonics).
    """

    method: str
    omega: np.ndarray
    harmonics: np.ndarray
    le_amplitude: np.ndarray
    le_max: np.ndarray
    residual_norm: np.ndarray
    iterations: np.ndarray
    step: np.ndarray
    time: np.ndarray
    converged: np.ndarray
    reason: np.ndarray
    status: str
    wall_time: float
    n_factorizations: int
    unknowns: np.ndarray = field(repr=False)


def default_continuation(hbm: HbmOptions) -> ContinuationOptions:
    """Continuation settings used by compute_nfrc (u is already ~1: x_scale = 1;
    omega_scale = 100 rad/s: a unit arc length is 100 rad/s on a flat branch)."""
    return ContinuationOptions(omega_min=hbm.omega_start, omega_max=hbm.omega_end, ds=0.05, ds_min=1e-5,
                               ds_max=0.5, direction=1, max_points=4000, x_scale=1.0, omega_scale=100.0,
                               newton=NewtonOptions(tol_residual=1e-8, max_iter=12), iter_grow=3, iter_shrink=6,
                               closed_loop_tol=1e-3)


def solve_start(res: HarmonicBalanceResidual, omega: float, opts: ContinuationOptions, fac) -> tuple[np.ndarray, str]:
    """Start point at omega: Newton from the contact-free solution; if that fails, an
    arc-length homotopy from a round casing (obstacle scale s = 0) to the real one (s = 1)
    at fixed omega, which passes the folds that a plain Newton sweep in s stops at.
    Returns (u, note); u is the best available guess (continue_branch corrects it again).
    """
    u_lin = res.linear_solution(omega)
    sol = newton_solve(res, u_lin, omega, opts.newton, factorize=fac)
    if sol.converged:
        return sol.x, "newton from the contact-free solution"

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
                   closed_loop_tol=None, direction=1, max_points=2000)
    br = continue_branch(homotopy, u_lin, 0.0, hopt, factorize=fac)
    return br.x[-1], f"obstacle homotopy: {br.status} ({len(br)} points)"


def compute_nfrc(rom, casing: CasingOptions = CasingOptions(), contact: ContactOptions = ContactOptions(),
                 hbm: HbmOptions = HbmOptions(), method: str = "dlft", *,
                 on_point: Callable[[NfrcPoint], None] | None = None,
                 continuation: ContinuationOptions | None = None, forcing: HarmonicForcing | None = None,
                 residual: HarmonicBalanceResidual | None = None) -> NfrcResult:
    """NFRC over Omega in [hbm.omega_start, hbm.omega_end] for one method.

    rom: RomModel (node 0 = LE). casing, contact, hbm: scene options. method: "dlft" | "rl".
    on_point(NfrcPoint): called after each point (converged or the final failure).
    continuation: overrides default_continuation(hbm) (omega range taken from it).
    Start: the contact-free (linear) solution at omega_start, corrected by Newton.
    """
    res = residual or build_residual(rom, casing, contact, hbm, method=method, forcing=forcing)
    opts = continuation or default_continuation(hbm)
    fac = ReusedLu()
    rows = []

    def record(p: ContinuationPoint):
        xr = res.to_coefficients(p.x)
        r = res.basis.to_time(xr[:, 0])
        reason = "" if p.converged else "failed"
        pt = NfrcPoint(index=p.index, omega=p.omega, harmonics=xr, le_amplitude=float(r.max() - r.min()),
                       le_max=float(r.max()), residual_norm=p.residual_norm, iterations=p.iterations,
                       step=p.step, time=p.time, converged=p.converged, reason=reason)
        rows.append((pt, np.array(p.x)))
        if on_point is not None and p.converged:
            on_point(pt)

    t0 = time.perf_counter()
    w0 = opts.omega_min if opts.direction > 0 else opts.omega_max
    x0, start_note = solve_start(res, w0, opts, fac)
    branch = continue_branch(res, x0, w0, opts, on_point=record, factorize=fac)
    wall = time.perf_counter() - t0
    if rows and not rows[-1][0].converged:  # the final failure carries the branch status
        last, xl = rows[-1]
        rows[-1] = (replace(last, reason=branch.status), xl)
        if on_point is not None:
            on_point(rows[-1][0])
    pts = [r[0] for r in rows]
    m = len(pts)
    return NfrcResult(
        method=method, omega=np.array([p.omega for p in pts]),
        harmonics=np.array([p.harmonics for p in pts]).reshape(m, res.n_c, res.n_r),
        le_amplitude=np.array([p.le_amplitude for p in pts]), le_max=np.array([p.le_max for p in pts]),
        residual_norm=np.array([p.residual_norm for p in pts]),
        iterations=np.array([p.iterations for p in pts], dtype=int), step=np.array([p.step for p in pts]),
        time=np.array([p.time for p in pts]), converged=np.array([p.converged for p in pts], dtype=bool),
        reason=np.array([p.reason for p in pts], dtype=object), status=branch.status, wall_time=wall,
        n_factorizations=fac.n_factorizations, unknowns=np.array([r[1] for r in rows]).reshape(m, res.size))
