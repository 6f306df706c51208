"""Whether a solution lies on a known branch: distance to the branch's polyline.

Metric: the continuation's scaled variables, y = (x / x_scale, omega / omega_scale); the
distance of a point to a polyline is the smallest distance to its segments.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class KnownBranch:
    """A branch to test against: omega (m,) rad/s, x (m, n) its points (converged ones),
    label: what it is called in reports (e.g. "primary", "branch 3")."""

    omega: np.ndarray
    x: np.ndarray
    label: str

    @classmethod
    def of(cls, omega, x, label: str, converged=None) -> "KnownBranch":
        omega, x = np.asarray(omega, dtype=float), np.asarray(x, dtype=float)
        if converged is not None:
            keep = np.asarray(converged, dtype=bool)
            omega, x = omega[keep], x[keep]
        return cls(omega, x.reshape(len(omega), -1), label)


def polyline_distance(x: np.ndarray, omega: float, branch: KnownBranch, x_scale=1.0,
                      omega_scale: float = 1.0) -> tuple[float, np.ndarray, float]:
    """Distance of (x (n,), omega) to the branch's polyline in the scaled metric, with the
    nearest point on it: (distance, x_near (n,), omega_near). inf for an empty branch."""
    m = len(branch.omega)
    if m == 0:
        return np.inf, x, omega
    P = np.column_stack([branch.x / x_scale, branch.omega / omega_scale])  # (m, n + 1)
    q = np.append(np.asarray(x, dtype=float) / x_scale, omega / omega_scale)
    if m == 1:
        d = float(np.linalg.norm(P[0] - q))
        return d, branch.x[0], float(branch.omega[0])
    seg = P[1:] - P[:-1]
    rel = q - P[:-1]
    L2 = np.einsum("sn,sn->s", seg, seg)
    t = np.clip(np.einsum("sn,sn->s", rel, seg) / np.where(L2 > 0, L2, 1.0), 0.0, 1.0)
    diff = rel - t[:, None] * seg
    d2 = np.einsum("sn,sn->s", diff, diff)
    k = int(np.argmin(d2))
    near = P[k] + t[k] * seg[k]
    return float(np.sqrt(d2[k])), near[:-1] * x_scale, float(near[-1] * omega_scale)


def nearest_branch(x: np.ndarray, omega: float, branches, x_scale=1.0, omega_scale: float = 1.0):
    """(index, distance, x_near, omega_near) of the branch nearest to (x, omega), index -1
    when there is none."""
    best = (-1, np.inf, x, omega)
    for i, b in enumerate(branches):
        d, xn, wn = polyline_distance(x, omega, b, x_scale, omega_scale)
        if d < best[1]:
            best = (i, d, xn, wn)
    return best
