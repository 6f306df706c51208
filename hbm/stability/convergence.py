"""Whether an HBM solution is converged in the number of harmonics: the same point solved
again with more harmonics (and AFT samples). Used on the validation stage's chosen points
before they are marched (pipelines.stages.validation) and on points of each branch of the
isola search (hbm.isolas.harmonic.harmonic_checks).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from hbm.continuation.newton import NewtonOptions
from hbm.harmonic.solver import HbmSolver
from hbm.stability.spectrum import orbit_spectrum

#: check_harmonics: a solution with twice the harmonics whose first N_h harmonics moved by
#: more than this (relative 2-norm) is another orbit, not the point refined. Points that time
#: integration keeps on rotor 67 (N_h = 40) move by at most 0.08; on the RL obstacle
#: oscillator at N_h = 3 (tests/hbm/test_validation_selection.py) points that move by 0.06 to
#: 0.10 are kept by time integration within 0.15 of their amplitude, those that move by 0.37
#: or more end 0.9 or more of it away.
HARMONIC_MOVE_TOL = 0.25


@dataclass(frozen=True)
class HarmonicCheck:
    """A branch point solved again with more harmonics (check_harmonics).

    passed: it exists there and, when checked, is stable there too. n_harmonics: the finer
    N_h. moved: relative 2-norm change of its first N_h harmonics (condensed unknowns), 1
    (nan when there is no solution). multiplier: largest |mu| over the minimal period with
    the finer N_h (nan when not analysed). u: the finer solution's unknowns, scaled as the
    finer residual's ((2 factor N_h + 1) n_r,), empty when there is none. reason: in words.
    """

    passed: bool
    reason: str
    n_harmonics: int = field(default=0, metadata={"unit": "1"})
    moved: float = field(default=math.nan, metadata={"unit": "1"})
    multiplier: float = field(default=math.nan, metadata={"unit": "1"})
    u: np.ndarray = field(default_factory=lambda: np.zeros(0), metadata={"unit": "1"})


def check_harmonics(residual, u: np.ndarray, omega: float, *, factor: int = 2, stable: bool = True,
                    max_iter: int = 20, fine=None) -> HarmonicCheck:
    """Whether the solution u at omega is converged in the number of harmonics: damped Newton
    at the same Omega with factor times the harmonics (residual.refined), from u padded with
    zeros, must converge to a solution whose first N_h harmonics moved by at most
    HARMONIC_MOVE_TOL; and, with the regularised law (RL) and a point called stable, Hill's
    method must call the finer solution stable too.

    Why: on the default rotor 67 scene (N_h = 40) five of the six points that time
    integration left without a friction lock have no solution at N_h = 80 next to them (they
    lie by folds that move with N_h), the sixth (RL) is unstable there, and every point it
    kept exists at N_h = 80, moved by at most 8 % (benchmarks/bench_harmonic_convergence.py).
    DLFT's verdict is not re-checked: its law is not differentiable and Hill's multiplier at a
    point time integration keeps moves from 0.95 at N_h = 40 to 1.08 at 80 (1338 rad/s there).
    max_iter: Newton iterations (converged points take 3 to 8 there; 20 halves the cost of a
    point with no solution against damped_newton's default 40). fine: residual.refined(factor)
    when the caller has it already (checking many points of one branch).
    """
    from hbm.harmonic.start import damped_newton

    fine = residual.refined(factor) if fine is None else fine
    xr = residual.to_coefficients(u)
    lifted = np.zeros((fine.n_c, fine.n_r))
    lifted[: len(xr)] = xr
    nh = fine.basis.n_harmonics
    tol = residual.options.tolerance
    sol = damped_newton(fine, fine.to_unknowns(lifted), float(omega), NewtonOptions(tol_residual=tol),
                        HbmSolver(atol=0.1 * tol), max_iter=max_iter)
    if not sol.converged:
        return HarmonicCheck(False, f"no solution with N_h = {nh} next to it ({sol.reason})", nh)
    moved = float(np.linalg.norm(fine.to_coefficients(sol.x)[: len(xr)] - xr) / max(np.linalg.norm(xr), 1e-300))
    if moved > HARMONIC_MOVE_TOL:
        return HarmonicCheck(False, f"the solution with N_h = {nh} next to it is another orbit (moved {moved:.0%})",
                             nh, moved, u=sol.x)
    if not (stable and residual.method == "rl"):
        return HarmonicCheck(True, f"exists with N_h = {nh} (moved {moved:.1%})", nh, moved, u=sol.x)
    spec, _ = orbit_spectrum(fine, sol.x, float(omega))
    if not spec.decided:
        return HarmonicCheck(False, f"no stability verdict with N_h = {nh} ({spec.note}; moved {moved:.1%})", nh,
                             moved, u=sol.x)
    mu = float(np.abs(spec.multipliers).max(initial=0.0))
    if not spec.stable:
        return HarmonicCheck(False, f"unstable with N_h = {nh} (|mu| = {mu:.4g}, moved {moved:.1%})", nh, moved, mu,
                             sol.x)
    return HarmonicCheck(True, f"stable with N_h = {nh} (|mu| = {mu:.4g}, moved {moved:.1%})", nh, moved, mu, sol.x)
