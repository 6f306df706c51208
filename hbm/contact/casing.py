"""Rigid ovalised casing, eq. (28) of the reference paper: the one casing law of the project.

The law is written once, in `lobe_coordinate` and `gap_at`, with operations that numpy
vectorises (arrays of any shape) and that numba compiles (scalars): the harmonic balance
calls `casing_distance` on arrays, the time-integration kernel (hbm.ti.kernel) compiles the
same two functions with numba.njit. Neither this module nor the HBM needs numba.
"""
from __future__ import annotations

import math

import numpy as np

from hbm.options import CasingOptions


def lobe_coordinate(x, n_lobes, width):
    """Signed distance to the nearest lobe centre in lobe widths, z = phi / w, -.

    x: tau + theta_j, the casing angle seen by node j, rad (array or scalar).
    phi = (x mod 2 pi / n_l) - pi / n_l: the lobe centre is at x = pi / n_l modulo 2 pi / n_l.
    The modulo is x - P floor(x / P), P = 2 pi / n_l: round-off may give phi = +pi / n_l
    instead of -pi / n_l at exact multiples of P, where both are the same point between lobes
    (d differs there by (c + p) exp(-(pi / (n_l w))^2), 1e-52 m for the default casing).
    """
    period = 2.0 * math.pi / n_lobes
    # reciprocals, not divisions: the kernel evaluates this for every node at every step
    return (x - period * np.floor(x * (n_lobes / (2.0 * math.pi))) - math.pi / n_lobes) * (1.0 / width)


def gap_at(z, clearance, penetration):
    """d = c - (c + p) exp(-z^2), m: radial distance to the casing at lobe coordinate z (array or scalar)."""
    return clearance - (clearance + penetration) * np.exp(-(z * z))


def casing_distance(tau: np.ndarray, theta: np.ndarray, casing: CasingOptions) -> np.ndarray:
    """Radial distance d_j(tau) between each boundary node's undeformed tip and the casing.

    tau: blade angle Omega t, any shape (..., ), rad. theta: node angular shifts, (n_b,), rad.
    Returns d, shape tau.shape + (n_b,), m; contact when the radial displacement r_j >= d_j.
    d = c - (c + p) exp(-(phi / w)^2), phi = ((tau + theta_j) mod 2 pi / n_l) - pi / n_l
    (the phase written in the paper is garbled; this is the intended one: the lobe centre
    is at tau + theta_j = pi / n_l modulo 2 pi / n_l, where d = -p).
    """
    x = np.asarray(tau, dtype=float)[..., None] + np.asarray(theta, dtype=float)
    z = lobe_coordinate(x, casing.n_lobes, casing.width)
    return gap_at(z, casing.clearance, casing.penetration)
