"""A crossing located finer than the spacing of the stored points.

The monitor (hbm.stability.monitor) brackets each stability change between two neighbouring
points a and b of a branch and interpolates log|mu| of the crossing multiplier linearly
between them. Near a resonance mu moves far from linearly: on the coarse rotor 67 NFRCs the
interpolation lies up to 3.8 rad/s from the refined crossing, in brackets of 1 to 8 rad/s
(README, *Where a bifurcation lies*). Refinement solves points between a and b and analyses
them, closing the bracket on the crossing multiplier by Brent's method. Where the
multiplier crosses the unit circle several times between a and b (an odd number: DLFT's
multipliers are not monotone along a branch), it locates one of the crossings.

The points between a and b are parametrised by f in [0, 1]: the point of the branch on the
hyperplane through a + f (b - a) normal to the secant b - a (in (x, Omega)). Between two
neighbouring points the branch crosses each such plane once, and f follows the arc length
to the branch's curvature.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np
import scipy.optimize

from hbm.continuation.newton import NewtonOptions, newton_solve_on_plane
from hbm.stability.bifurcation import upper_half


@dataclass(frozen=True)
class Refinement:
    """Where refine_crossing put a crossing.

    fraction: position between the stored points a (0) and b (1), in the hyperplanes'
    parameter f. omega: Omega there, rad/s; le_amplitude: m; both interpolated linearly in
    log|mu| between the two bracketing points (solved or stored). bracket: (Omega, Omega)
    of those two points, rad/s. steps: points tried between a and b, the one that ended it
    included. note: why it stopped before the bracket reached its tolerance with steps left
    ("" otherwise): a point that did not converge, an analysis without a verdict, no
    multiplier that can be the crossing one.
    """

    fraction: float
    omega: float
    le_amplitude: float
    bracket: tuple[float, float]
    steps: int
    note: str = ""


class _Stop(Exception):
    """evaluate gave no value: the refinement ends with the bracket it has."""


def refine_crossing(evaluate: Callable[[float], tuple | str], ends: tuple, steps: int, rtol: float) -> Refinement:
    """Brent's method (scipy.optimize.brentq) on l(f) = log|mu| of the crossing multiplier over
    f in [0, 1]: inverse quadratic interpolation where l is smooth, bisection where it is not
    (a crossing multiplier often moves slowly as one of a complex pair on the stable side,
    then fast once real: regula falsi crawls there).

    evaluate(f) -> (l, omega rad/s, le_amplitude m) at the branch's point f, or a str saying
    why there is none. ends: ((l, omega, amplitude) at f = 0, the same at f = 1), l of
    opposite signs. At most `steps` evaluations; stops once the bracket is within rtol
    |Omega| in Omega (Omega taken linear in f between the ends for the test).
    """
    (l0, w0, a0), (l1, w1, a1) = ends
    if not (l0 < 0.0 < l1 or l1 < 0.0 < l0):
        raise ValueError(f"the ends do not bracket a crossing: log|mu| = {l0:.3g}, {l1:.3g}")
    seen = {0.0: (l0, w0, a0), 1.0: (l1, w1, a1)}
    note = [""]

    def l_of(f):
        f = float(f)
        if f not in seen:
            if len(seen) - 2 >= steps:
                raise _Stop()
            got = evaluate(f)
            if isinstance(got, str):
                note[0] = got
                raise _Stop()
            seen[f] = tuple(float(v) for v in got)
        return seen[f][0]

    span = abs(w1 - w0)
    xtol = max(rtol * max(abs(w0), abs(w1)) / span, 1e-12) if span > 0.0 else 1.0
    if steps > 0 and xtol < 1.0:
        try:
            scipy.optimize.brentq(l_of, 0.0, 1.0, xtol=xtol, rtol=4 * np.finfo(float).eps, maxiter=steps,
                                  disp=False)
        except _Stop:
            pass
    # the tightest bracket among the points evaluated, the crossing interpolated in it (an
    # exact zero is its own bracket)
    zero = [f for f, v in seen.items() if v[0] == 0.0]
    if zero:
        _, w, a = seen[zero[0]]
        return Refinement(fraction=float(zero[0]), omega=w, le_amplitude=a, bracket=(w, w), steps=len(seen) - 2,
                          note=note[0])
    fs = sorted(seen)
    sign0 = seen[0.0][0] < 0.0
    k = max(i for i, f in enumerate(fs) if (seen[f][0] < 0.0) == sign0)
    lo, hi = fs[k], fs[k + 1]
    (la, wa, aa), (lb, wb, ab) = seen[lo], seen[hi]
    t = la / (la - lb)
    return Refinement(fraction=float(lo + t * (hi - lo)), omega=float(wa + t * (wb - wa)),
                      le_amplitude=float(aa + t * (ab - aa)), bracket=(float(wa), float(wb)),
                      steps=len(seen) - 2 + bool(note[0]), note=note[0])


def solve_between(residual, xa: np.ndarray, wa: float, xb: np.ndarray, wb: float, f: float,
                  newton: NewtonOptions, solver=None):
    """(x (n,), Omega rad/s) of the branch's point f between the points (xa, wa) and (xb, wb),
    or Newton's reason where it fails: Newton on the hyperplane through a + f (b - a) normal
    to the secant, from that point."""
    xa, xb = np.asarray(xa, float), np.asarray(xb, float)
    p, q = xb - xa, float(wb - wa)
    w0 = wa + f * q
    r = newton_solve_on_plane(residual, xa + f * p, w0, p, q, newton, solver=solver, where=f" at omega={w0:.6g}")
    if not r.converged:
        return f"no point at f = {f:.3f}: {r.reason}"
    return r.x[:-1], float(r.x[-1])


def tracked_log_modulus(multipliers: np.ndarray, floor: float, target: tuple, candidate) -> float | None:
    """log|mu| of the multiplier nearest the target (log|mu|, |arg mu|) among those above
    floor, one of each conjugate pair, for which candidate(mu) holds (None: no such one).
    multipliers: (m,) complex."""
    mu = np.asarray(multipliers)
    ok = upper_half(mu) & (np.abs(mu) > floor)
    ok &= np.array([bool(candidate(m)) for m in mu], dtype=bool) if len(mu) else ok
    if not ok.any():
        return None
    c = np.stack([np.log(np.abs(mu[ok])), np.abs(np.angle(mu[ok]))], axis=-1)
    k = int(np.argmin(np.hypot(c[:, 0] - target[0], c[:, 1] - target[1])))
    return float(c[k, 0]) if math.isfinite(c[k, 0]) else None
