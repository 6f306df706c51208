"""Small residuals R(x, omega) -> (R, dR_dx, dR_domega) with known solution sets.

They test the continuation only: none of them uses the project's AFT or contact laws.
"""
from __future__ import annotations

import numpy as np
import scipy.optimize as so


class Duffing1:
    """One-harmonic HB of x'' + 2 zeta x' + x + gamma x^3 = F cos(Omega t), x = a cos + b sin.

    Unknowns x = (a, b), parameter omega = Omega (dimensionless time). The x^3 term's first
    harmonic is 3/4 gamma A^2 (a, b), A^2 = a^2 + b^2, so
      R_a = (1 - w^2 + k A^2) a + 2 zeta w b - F,   R_b = (1 - w^2 + k A^2) b - 2 zeta w a,
    with k = 3 gamma / 4, and the amplitude obeys [(1 - w^2 + k A^2)^2 + (2 zeta w)^2] A^2 = F^2.
    """

    def __init__(self, zeta: float = 0.02, gamma: float = 1.0, force: float = 0.1):
        self.zeta, self.gamma, self.force = zeta, gamma, force
        self.k = 0.75 * gamma

    def __call__(self, x, w):
        a, b = x
        z, k = self.zeta, self.k
        A2 = a * a + b * b
        s = 1.0 - w * w + k * A2
        R = np.array([s * a + 2 * z * w * b - self.force, s * b - 2 * z * w * a])
        J = np.array([[s + 2 * k * a * a, 2 * z * w + 2 * k * a * b],
                      [-2 * z * w + 2 * k * a * b, s + 2 * k * b * b]])
        dw = np.array([-2 * w * a + 2 * z * b, -2 * w * b - 2 * z * a])
        return R, J, dw

    def relation(self, amplitude, w):
        """Frequency-amplitude relation, zero on the exact HB branch: [..] A^2 - F^2."""
        A2 = np.asarray(amplitude) ** 2
        return ((1 - w ** 2 + self.k * A2) ** 2 + (2 * self.zeta * w) ** 2) * A2 - self.force ** 2

    def peak(self):
        """(A, omega) of the resonance peak of the 1-harmonic HB, exactly.

        dA/dw = 0 on the relation gives 1 - w^2 + k A^2 = 2 zeta^2; substituting back,
        u = A^2 solves 4 zeta^2 k u^2 + 4 zeta^2 (1 - zeta^2) u - F^2 = 0.
        """
        z, k, F = self.zeta, self.k, self.force
        u = max(np.roots([4 * z * z * k, 4 * z * z * (1 - z * z), -F * F]).real)
        return float(np.sqrt(u)), float(np.sqrt(1 + k * u - 2 * z * z))

    def folds(self):
        """Omegas of the two turning points (jump-down, jump-up), from the cubic in u = A^2.

        At fixed w, k^2 u^3 + 2 c k u^2 + (c^2 + d^2) u - F^2 = 0 (c = 1 - w^2, d = 2 zeta w);
        the folds are where it has a double root: its discriminant vanishes.
        """
        def disc(w):
            c, d = 1 - w * w, 2 * self.zeta * w
            a3, a2, a1, a0 = self.k ** 2, 2 * c * self.k, c * c + d * d, -self.force ** 2
            return (18 * a3 * a2 * a1 * a0 - 4 * a2 ** 3 * a0 + a2 ** 2 * a1 ** 2 - 4 * a3 * a1 ** 3
                    - 27 * a3 ** 2 * a0 ** 2)

        _, w_peak = self.peak()
        grid = np.linspace(1.0, 1.2 * w_peak, 4001)
        v = disc(grid)
        roots = [so.brentq(disc, grid[i], grid[i + 1], xtol=1e-14)
                 for i in np.flatnonzero(np.sign(v[:-1]) != np.sign(v[1:]))]
        return roots


class Circle:
    """Isola: (x1 - c)^2 + (w - wc)^2 = r^2 with x2 = x1^2 / 4 riding along (n = 2)."""

    def __init__(self, c: float = 2.0, wc: float = 1.5, r: float = 0.5):
        self.c, self.wc, self.r = c, wc, r

    def __call__(self, x, w):
        x1, x2 = x
        R = np.array([(x1 - self.c) ** 2 + (w - self.wc) ** 2 - self.r ** 2, x2 - 0.25 * x1 * x1])
        J = np.array([[2 * (x1 - self.c), 0.0], [-0.5 * x1, 1.0]])
        return R, J, np.array([2 * (w - self.wc), 0.0])


class Wave:
    """w = w0 + h sin(kappa (x1 - x1_0)), x2 = x2_0: an open curve that keeps coming back to w0,

    at x1 = x1_0 + j pi / kappa, i.e. at a relative distance (pi / kappa) j / |x| from the
    start; every crest and trough is a fold (dR1/dx1 = 0 there).
    """

    def __init__(self, w0=1.0, h=0.3, kappa=4.0, x1_0=0.0, x2_0=10.0):
        self.w0, self.h, self.kappa, self.x1_0, self.x2_0 = w0, h, kappa, x1_0, x2_0

    def __call__(self, x, w):
        x1, x2 = x
        ph = self.kappa * (x1 - self.x1_0)
        R = np.array([w - self.w0 - self.h * np.sin(ph), x2 - self.x2_0])
        J = np.array([[-self.h * self.kappa * np.cos(ph), 0.0], [0.0, 1.0]])
        return R, J, np.array([1.0, 0.0])


class Wall:
    """x = sqrt(w_wall - w): the branch ends at w_wall, beyond which R is NaN (no solution)."""

    def __init__(self, w_wall: float = 2.0):
        self.w_wall = w_wall

    def __call__(self, x, w):
        with np.errstate(invalid="ignore", divide="ignore"):
            root = np.sqrt(self.w_wall - w)
            R = np.array([x[0] - root])
            return R, np.array([[1.0]]), np.array([0.5 / root])


class Helix:
    """x1 = c + r cos t, omega = wc + r sin t, x2 = x2_0 + h t: comes back to omega0 = wc
    after each turn at the same x1 but x2 shifted by 2 pi h (no closed loop).

    Written as cylinder and helicoid: (x1 - c)^2 + (w - wc)^2 = r^2 and
    (x1 - c) sin(phi) - (w - wc) cos(phi) = 0, phi = (x2 - x2_0) / h.
    """

    def __init__(self, c=2.0, wc=1.5, r=0.5, x2_0=1.0, h=0.0223):
        self.c, self.wc, self.r, self.x2_0, self.h = c, wc, r, x2_0, h

    def start(self):
        """(x, omega) at t = 0."""
        return np.array([self.c + self.r, self.x2_0]), self.wc

    def __call__(self, x, w):
        x1, x2 = x
        u, v = x1 - self.c, w - self.wc
        phi = (x2 - self.x2_0) / self.h
        s, co = np.sin(phi), np.cos(phi)
        R = np.array([u * u + v * v - self.r ** 2, u * s - v * co])
        J = np.array([[2 * u, 0.0], [s, (u * co + v * s) / self.h]])
        return R, J, np.array([2 * v, -co])


class Vee:
    """omega = w0 + a sqrt(x1^2 + eps^2), x2 = 0: a corner at x1 = 0 where the branch turns by
    180 - 2 atan(1 / a) deg (a = 0.5: 53 deg, a = 5: 157 deg), rounded over |x1| ~ eps."""

    def __init__(self, w0=1.0, a=0.5, eps=1e-7):
        self.w0, self.a, self.eps = w0, a, eps

    def turn_deg(self) -> float:
        return 180.0 - 2.0 * np.degrees(np.arctan(1.0 / self.a))

    def __call__(self, x, w):
        x1, x2 = x
        r = np.hypot(x1, self.eps)
        return (np.array([w - self.w0 - self.a * r, x2]), np.array([[-self.a * x1 / r, 0.0], [0.0, 1.0]]),
                np.array([1.0, 0.0]))


class ZigZag:
    """A branch folding back and forth many times over a narrow omega band, as RL-HBM's does
    over 420-432 rad/s on rotor 67: omega = w0 + h sin(kappa x1), x2 = 0, a fold every
    pi / kappa in x1. With h kappa >> 1 the stretches between folds run nearly parallel to
    the omega axis, pi / kappa apart: a step longer than that can land on a later stretch
    and skip the folds in between."""

    def __init__(self, w0=1.0, h=0.05, kappa=12.0):
        self.w0, self.h, self.kappa = w0, h, kappa

    def __call__(self, x, w):
        x1, x2 = x
        ph = self.kappa * x1
        return (np.array([w - self.w0 - self.h * np.sin(ph), x2]),
                np.array([[-self.h * self.kappa * np.cos(ph), 0.0], [0.0, 1.0]]), np.array([1.0, 0.0]))

    def extrema_between(self, a: float, b: float) -> int:
        """Number of folds (crests and troughs, kappa x1 = pi/2 + j pi) with a < x1 < b."""
        lo, hi = sorted((a, b))
        j = np.arange(np.floor((self.kappa * lo - np.pi / 2) / np.pi) - 1, np.ceil((self.kappa * hi) / np.pi) + 2)
        xs = (np.pi / 2 + j * np.pi) / self.kappa
        return int(np.sum((xs > lo) & (xs < hi)))


class Hairpin:
    """Two wavy lanes 2 r apart joined by a U-turn at the bottom, as the stretches of a fold
    cluster run parallel a fraction of a step apart:

    (x1 - a sin(k w))^2 + max(0, w0 - w)^2 = r^2, x2 = 0: the left lane x1 = a sin(k w) - r
    and the right lane a sin(k w) + r for w >= w0, a half circle of radius r below w0.
    Going down the left lane and round the U-turn, the branch goes up the right lane; a
    step longer than 2 r can land back on the left lane and retrace it.
    """

    def __init__(self, w0=1.0, r=0.01, a=0.3, k=6.0):
        self.w0, self.r, self.a, self.k = w0, r, a, k

    def lane(self, w, side: int) -> float:
        """x1 of the left (side -1) or right (+1) lane at w >= w0."""
        return self.a * np.sin(self.k * w) + side * self.r

    def __call__(self, x, w):
        x1, x2 = x
        e = x1 - self.a * np.sin(self.k * w)
        b = max(0.0, self.w0 - w)
        R = np.array([e * e + b * b - self.r ** 2, x2])
        J = np.array([[2 * e, 0.0], [0.0, 1.0]])
        dw = np.array([-2 * e * self.a * self.k * np.cos(self.k * w) - 2 * b, 0.0])
        return R, J, dw
