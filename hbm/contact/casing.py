"""Rigid ovalised casing, eq. (28) of the reference paper."""
from __future__ import annotations

import numpy as np

from hbm.options import CasingOptions


def casing_distance(tau: np.ndarray, theta: np.ndarray, casing: CasingOptions) -> np.ndarray:
    """Radial distance d_j(tau) between each boundary node's undeformed tip and the casing.

    tau: blade angle Omega t, any shape (..., ), rad. theta: node angular shifts, (n_b,), rad.
    Returns d, shape tau.shape + (n_b,), m; contact when the radial displacement r_j >= d_j.
    d = c - (c + p) exp(-(phi / w)^2), phi = ((tau + theta_j) mod 2 pi / n_l) - pi / n_l
    (the phase written in the paper is garbled; this is the intended one: the lobe centre
    is at tau + theta_j = pi / n_l modulo 2 pi / n_l, where d = -p).
    """
    c, p, w, n = casing.clearance, casing.penetration, casing.width, casing.n_lobes
    period = 2.0 * np.pi / n
    phi = np.mod(np.asarray(tau)[..., None] + np.asarray(theta), period) - np.pi / n
    return c - (c + p) * np.exp(-(phi / w) ** 2)
