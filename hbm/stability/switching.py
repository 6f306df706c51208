"""Branch switching at a period doubling: the start point and direction of the new branch.

At a period doubling of an orbit of minimal period T_min (multiplier -1), a branch of
period 2 T_min is born in a pitchfork: its orbits are the old one plus eps times the
critical Floquet mode y(t) = Re(exp(lam t) p(t)), lam = i pi / T_min (mod 2 i pi / T_min),
and y has the harmonics of 1 / (2 T_min) that are odd multiples of it.

- An orbit of the HBM basis' own period (T = 2 pi nu / Omega, g = 1): the new branch needs
  the basis of Omega / (2 nu) (HbmOptions.subharmonic = 2 nu, with 2 N_h + 1 harmonics
  and 2 N_t samples: the same first dropped frequency; RL's Lanczos factors follow the
  frequency, FourierBasis.lanczos_sigma); the old orbit is embedded on its even harmonics
  (embed_harmonics), an exact solution there, and y lies on the odd ones.
- An orbit of period T / 2 in that basis (g = 2, the rotor 67 NFRC: only even harmonics of
  Omega): the doubled period T is already the basis', y lies on its odd harmonics (in the
  omega = Omega basis this is the symmetry-breaking branch point of the even solution).

The new branch's tangent at the bifurcation is (y, 0) (a pitchfork: Omega is extremal on it
there), so the start point is found by Newton on R = 0 with the plane constraint
<(u, Omega) - (u_b, Omega_b), (y, 0)> = eps (not at fixed Omega: the new branch meets that
Omega only at the bifurcation point).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from hbm.continuation.newton import NewtonOptions, NewtonResult, newton_solve_on_plane
from hbm.harmonic.residual import HarmonicBalanceResidual, build_residual
from hbm.harmonic.solver import HbmSolver
from hbm.stability.bifurcation import PERIOD_DOUBLING, Bifurcation
from hbm.stability.spectrum import exponential_coefficients, real_coefficients


def embed_harmonics(u: np.ndarray, n_r: int, ratio: int, n_harmonics: int) -> np.ndarray:
    """Unknowns in a basis whose fundamental is `ratio` times smaller: harmonic k -> k ratio.

    u: ((2 N_h + 1) n_r,) (or (2 N_h + 1, n_r)) eq. (5) order; returns ((2 n_harmonics + 1)
    n_r,), the harmonics beyond n_harmonics dropped. ratio = 2 embeds an Omega-periodic
    solution in the basis of Omega / 2 (subharmonic 2): an exact solution there too.
    """
    x = np.asarray(u).reshape(-1, n_r)
    nh = (x.shape[0] - 1) // 2
    out = np.zeros((2 * n_harmonics + 1, n_r), dtype=x.dtype)
    out[0] = x[0]
    for k in range(1, nh + 1):
        kk = k * ratio
        if kk > n_harmonics:
            break
        out[2 * kk - 1], out[2 * kk] = x[2 * k - 1], x[2 * k]
    return out.reshape(-1)


def mode_coefficients(bifurcation: Bifurcation, n_harmonics: int, target_omega: float) -> np.ndarray:
    """The real critical mode y(t) = Re(exp(i Im(lam) t) p(t)) in the basis of target_omega.

    p was computed in the basis of bifurcation.mode_omega (rad/s: the orbit's minimal
    period's fundamental); a coefficient c_k of p (harmonic k there) with Im(lam) = beta
    lands on harmonic (k mode_omega + beta) / target_omega of the target. A period
    doubling's multiplier is real only up to the truncation: DLFT's moves its argument off
    pi by up to 0.03 rad on rotor 67 (beta 14 1/s off the harmonic at 1457 rad/s), more
    than the classification's REAL_ARG_TOL where its kind comes from the parities. So each
    coefficient is put on the nearest harmonic of the target, within a quarter of one
    (Newton corrects the start). Returns (2 n_harmonics + 1, n) real, eq. (5) order, unit
    2-norm, the phase chosen to make y real (a real multiplier's mode is real up to a
    constant complex factor).
    """
    p = np.asarray(bifurcation.eigenvector)
    nh_a = (p.shape[0] - 1) // 2
    c = exponential_coefficients(p)  # (2 nh_a + 1, n), index k + nh_a
    beta = bifurcation.exponent.imag
    out = np.zeros((2 * n_harmonics + 1, p.shape[1]), dtype=complex)  # index m + n_harmonics
    for k in range(-nh_a, nh_a + 1):
        mf = (k * bifurcation.mode_omega + beta) / target_omega
        m = int(np.round(mf))
        if abs(mf - m) > 0.25:
            raise ValueError(f"the mode's frequencies are not harmonics of {target_omega:.6g} rad/s "
                             f"(Im lam = {beta:.6g} 1/s, basis {bifurcation.mode_omega:.6g} rad/s)")
        if abs(m) <= n_harmonics:
            out[m + n_harmonics] += c[k + nh_a]
    # the phase: the eigenvector's is arbitrary, and Re(exp(-i phi) f) is largest where
    # phi = arg(int f^2) / 2 (int f(t)^2 dt ~ sum_m c_m c_-m): rotate f before taking Re
    z = np.sum(out * out[::-1])
    if z != 0.0:
        out = out * np.exp(-0.5j * np.angle(z))
    full = 0.5 * (out + np.conj(out[::-1]))  # Re(.) = (f + conj f) / 2
    y = real_coefficients(full).real
    nrm = np.linalg.norm(y)
    if nrm == 0.0:
        raise ValueError("the critical mode has no content in the target basis")
    return y / nrm


@dataclass(frozen=True, eq=False)
class BranchStart:
    """Start of the branch born at a bifurcation.

    residual: the HarmonicBalanceResidual of the new branch (its own subharmonic and N_h).
    omega: Omega of the start point, rad/s. u: its scaled unknowns (n_u,), a converged
    solution on the new branch. tangent: (n_u + 1,) unit tangent (u part, then Omega / 100
    rad/s: the metric of hbm.harmonic.nfrc.default_continuation) at the start point,
    pointing away from the bifurcation. bifurcation_u: the bifurcation point embedded in
    the new unknowns (n_u,). odd_content: share of the start point's harmonics (2-norm)
    on the frequencies that the old orbit lacks (the odd multiples of the new fundamental
    / the mode's), -. newton: the corrector's result.
    """

    residual: HarmonicBalanceResidual
    omega: float
    u: np.ndarray
    tangent: np.ndarray
    bifurcation_u: np.ndarray
    odd_content: float
    newton: NewtonResult


def switch_branch(residual: HarmonicBalanceResidual, u: np.ndarray, omega: float, bifurcation: Bifurcation, *,
                  step: float = 1e-2, newton: NewtonOptions = NewtonOptions(tol_residual=1e-8, max_iter=20),
                  solver=None) -> BranchStart:
    """Start point and direction of the period-doubled branch at a period doubling.

    residual: the old branch's residual; u (n_u,), omega (rad/s): a solution on it near the
    bifurcation (e.g. the nearer branch point, or the bifurcation located on it); the
    bifurcation: a PERIOD_DOUBLING from hbm.stability (its critical mode).
    step: distance from the bifurcation along the mode, relative to ||u|| (scaled
    unknowns): the new branch's Omega departs as step^2, so 1e-2 lands on it within
    Newton's reach while far from the old branch in the scaled metric.
    Returns a BranchStart; its newton.converged says whether the corrector found the new
    branch (reason otherwise).
    """
    if bifurcation.kind != PERIOD_DOUBLING or bifurcation.eigenvector is None:
        raise ValueError(f"switch_branch needs a period doubling with its mode, got {bifurcation.kind!r}")
    g = int(bifurcation.period_ratio)
    nu = residual.nu
    opts = residual.options
    if g % 2 == 0:  # the doubled period is the basis' own: same residual, odd multiples of g / 2
        new = residual
        u_b = np.asarray(u, dtype=float)
    else:  # double the basis period: subharmonic 2 nu, same resolution
        new_opts = replace(opts, subharmonic=2 * nu, n_harmonics=2 * opts.n_harmonics + 1, n_time=2 * opts.n_time)
        new = build_residual(residual.rom, residual.casing, residual.contact, new_opts, method=residual.method,
                             forcing=residual.forcing, alpha=residual.alpha, friction=residual.friction,
                             distance=residual._distance)
        u_b = embed_harmonics(u, residual.n_r, 2, new_opts.n_harmonics)
    # the new basis' fundamental in the mode's units (the analysed point's Omega, not the
    # interpolated one: the harmonic indices must come out exact)
    ratio = 1 if g % 2 == 0 else 2
    y = mode_coefficients(bifurcation, new.basis.n_harmonics, bifurcation.mode_omega / (g * ratio))
    nl = np.asarray(new.model.nl)
    t = new.to_unknowns(y[:, nl])  # boundary dof, scaled like u
    t /= np.linalg.norm(t)
    eps = step * max(np.linalg.norm(u_b), 1.0)
    solver = solver or HbmSolver(atol=0.1 * newton.tol_residual)
    n = u_b.size
    # R(u, Omega) = 0 and <u - u_b, t> = eps (t is a unit vector): the plane through u_b + eps t
    res = newton_solve_on_plane(new, u_b + eps * t, omega, t, 0.0, newton, solver=solver,
                                where=f" switching near Omega={omega:.6g}")
    u1, w1 = res.x[:n], float(res.x[n])
    d = np.append(u1 - u_b, (w1 - omega) / 100.0)
    tangent = d / max(np.linalg.norm(d), 1e-300)
    xr = new.to_coefficients(u1)
    mask = np.zeros(new.n_c, dtype=bool)
    orders = new.basis.orders
    if g % 2 == 0:
        mask = (orders % g) != 0  # harmonics the T/g orbit lacks
    else:
        mask = (orders % 2) == 1
    odd = float(np.linalg.norm(xr[mask]) / max(np.linalg.norm(xr), 1e-300))
    return BranchStart(residual=new, omega=w1, u=u1, tangent=tangent, bifurcation_u=u_b, odd_content=odd, newton=res)
