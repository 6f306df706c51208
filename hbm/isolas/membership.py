"""Whether a solution lies on a known branch: distance to the branch's polyline.

Metric: the continuation's scaled variables, y = (x / x_scale, omega / omega_scale); the
distance of a point to a polyline is the smallest distance to its segments.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True, eq=False)
class KnownBranch:
    """A branch to test against: omega (m,) rad/s, x (m, n) its points (converged ones),
    label: what it is called in reports (e.g. "primary", "branch 3")."""

    omega: np.ndarray
    x: np.ndarray
    label: str
    _longest: dict = field(default_factory=dict, init=False, repr=False)

    def longest_segment(self, x_scale=1.0, omega_scale: float = 1.0) -> float:
        """An upper bound (by 1e-9 relative, for round-off) of the scaled length of the
        branch's longest segment, segment_length's metric; 0.0 below two points. Kept per
        scales: the isola search asks it of every branch for every candidate."""
        key = (np.asarray(x_scale, dtype=float).tobytes(), float(omega_scale))
        if key not in self._longest:
            if len(self.omega) < 2:
                self._longest[key] = 0.0
            else:
                lengths = np.hypot(np.linalg.norm(np.diff(self.x, axis=0) / x_scale, axis=1),
                                   np.diff(self.omega) / omega_scale)
                self._longest[key] = float(lengths.max()) * (1.0 + 1e-9)
        return self._longest[key]

    @classmethod
    def of(cls, omega, x, label: str, converged=None) -> "KnownBranch":
        omega, x = np.asarray(omega, dtype=float), np.asarray(x, dtype=float)
        if converged is not None:
            keep = np.asarray(converged, dtype=bool)
            omega, x = omega[keep], x[keep]
        # (m, n) even for m = 0 (an NFRC whose start did not converge: no point to meet)
        return cls(omega, x.reshape(len(omega), x.shape[-1] if x.ndim == 2 else -1), label)


def points_at(branch: KnownBranch, omega: float) -> np.ndarray:
    """The branch's points at the speed omega (rad/s), (k, n), in the branch's order: each of
    its points at omega, and on each segment that crosses omega the chord's point there
    (linear in omega). (0, n) where the branch never reaches omega."""
    om, x = branch.omega, branch.x
    d = om - omega
    cross = np.flatnonzero(d[:-1] * d[1:] < 0)
    on = np.flatnonzero(d == 0)
    t = (d[cross] / (d[cross] - d[cross + 1]))[:, None]
    pts = np.concatenate([x[on], x[cross] + t * (x[cross + 1] - x[cross])])
    return pts[np.argsort(np.concatenate([on, cross]), kind="stable")]


def polyline_distance(x: np.ndarray, omega: float, branch: KnownBranch, x_scale=1.0,
                      omega_scale: float = 1.0, within: float | None = None) -> tuple[float, np.ndarray, float]:
    """Distance of (x (n,), omega) to the branch's polyline in the scaled metric, with the
    nearest point on it: (distance, x_near (n,), omega_near). inf for an empty branch.

    within: only the segments whose omega span (scaled) comes within this distance of omega
    are measured; the result is the same (to round-off) whenever the distance is <= within,
    and (inf, x, omega) when no segment qualifies. A distance is never below its omega part,
    so a caller that only asks "closer than tol?" loses nothing with within=tol, and the test
    then costs a few segments instead of the whole branch (m x n, ~60 ms for 600 points at
    N_h = 40).
    """
    d, xn, wn, _ = nearest_on_polyline(x, omega, branch, x_scale, omega_scale, within)
    return d, xn, wn


def segment_length(branch: KnownBranch, k: int, x_scale=1.0, omega_scale: float = 1.0) -> float:
    """Scaled length of the longer of the polyline segments on either side of point k."""
    m = len(branch.omega)
    out = 0.0
    for a in (k - 1, k):
        if 0 <= a and a + 1 < m:
            out = max(out, float(np.hypot(np.linalg.norm((branch.x[a + 1] - branch.x[a]) / x_scale),
                                          (branch.omega[a + 1] - branch.omega[a]) / omega_scale)))
    return out


def nearest_on_polyline(x: np.ndarray, omega: float, branch: KnownBranch, x_scale=1.0, omega_scale: float = 1.0,
                        within: float | None = None) -> tuple[float, np.ndarray, float, int]:
    """polyline_distance's (distance, x_near, omega_near) and k, the index of the branch
    point that ends the nearest segment on the side of the nearest point (-1 when nothing
    was measured)."""
    d, xn, wn, seg, t = nearest_segment(x, omega, branch, x_scale, omega_scale, within)
    return d, xn, wn, seg + int(t > 0.5) if seg >= 0 else -1


def nearest_segment(x: np.ndarray, omega: float, branch: KnownBranch, x_scale=1.0, omega_scale: float = 1.0,
                    within: float | None = None) -> tuple[float, np.ndarray, float, int, float]:
    """(distance, x_near, omega_near, s, t): the nearest point lies on segment s (points s,
    s + 1) at the fraction t of it (s = 0, t = 0 for a one-point branch; s = -1 when nothing
    was measured; `within` as in polyline_distance)."""
    m = len(branch.omega)
    if m == 0:
        return np.inf, x, omega, -1, 0.0
    q = np.append(np.asarray(x, dtype=float) / x_scale, omega / omega_scale)
    W = branch.omega / omega_scale
    if m == 1:
        if within is not None and abs(W[0] - q[-1]) > within:
            return np.inf, x, omega, -1, 0.0
        d = float(np.linalg.norm(np.append(branch.x[0] / x_scale, W[0]) - q))
        return d, branch.x[0], float(branch.omega[0]), 0, 0.0
    seg_i = np.arange(m - 1)
    if within is not None:
        seg_i = seg_i[_near_in_omega(W[:-1], W[1:], q[-1], q[-1], within)]
        if not seg_i.size:
            return np.inf, x, omega, -1, 0.0
    A = np.column_stack([branch.x[seg_i] / x_scale, W[seg_i]])  # segment starts (s, n + 1)
    B = np.column_stack([branch.x[seg_i + 1] / x_scale, W[seg_i + 1]])
    seg = B - A
    rel = q - A
    L2 = np.einsum("sn,sn->s", seg, seg)
    t = np.clip(np.einsum("sn,sn->s", rel, seg) / np.where(L2 > 0, L2, 1.0), 0.0, 1.0)
    diff = rel - t[:, None] * seg
    d2 = np.einsum("sn,sn->s", diff, diff)
    j = int(np.argmin(d2))
    near = A[j] + t[j] * seg[j]
    return float(np.sqrt(d2[j])), near[:-1] * x_scale, float(near[-1] * omega_scale), int(seg_i[j]), float(t[j])


def _near_in_omega(wa: np.ndarray, wb: np.ndarray, w_lo: float, w_hi: float, within: float) -> np.ndarray:
    """(s,) bool: which segments, from scaled omega wa (s,) to wb (s,), have an omega span
    that comes within `within` of [w_lo, w_hi] (a point: w_lo = w_hi). A distance is never
    below its omega part, so the segments left out are all farther than `within`."""
    lo, hi = np.minimum(wa, wb), np.maximum(wa, wb)
    return (lo - within <= w_hi) & (w_lo <= hi + within)


def segment_polyline_distance(x0: np.ndarray, omega0: float, x1: np.ndarray, omega1: float, branch: KnownBranch,
                              x_scale=1.0, omega_scale: float = 1.0,
                              within: float | None = None) -> tuple[float, np.ndarray, float]:
    """Smallest distance between the segment (x0, omega0)-(x1, omega1) and the branch's
    polyline in the scaled metric, with the nearest point on the polyline: (distance, x_near,
    omega_near); (inf, x1, omega1) for an empty branch or when no segment qualifies.

    A continuation that crosses a branch between two of its points passes farther than the
    tolerance from the branch at both when its step is longer than the tolerance; the chord
    between them passes through (to the curves' sagitta). within: as in polyline_distance,
    on the omega span of the segment."""
    m = len(branch.omega)
    if m == 0:
        return np.inf, x1, omega1
    P0 = np.append(np.asarray(x0, dtype=float) / x_scale, omega0 / omega_scale)
    P1 = np.append(np.asarray(x1, dtype=float) / x_scale, omega1 / omega_scale)
    W = branch.omega / omega_scale
    start = np.zeros(1, dtype=np.int64) if m == 1 else np.arange(m - 1)
    end = start if m == 1 else start + 1
    if within is not None:  # the omega spans first: only the segments kept are copied (the search's
        # meeting test calls this at every point against every branch)
        keep = _near_in_omega(W[start], W[end], min(P0[-1], P1[-1]), max(P0[-1], P1[-1]), within)
        start, end = start[keep], end[keep]
        if not len(start):
            return np.inf, x1, omega1
    A = np.column_stack([branch.x[start] / x_scale, W[start]])
    B = np.column_stack([branch.x[end] / x_scale, W[end]])
    d1 = P1 - P0
    d2 = B - A
    r = P0 - A
    a = float(d1 @ d1)
    e = np.einsum("sn,sn->s", d2, d2)
    f = np.einsum("sn,sn->s", d2, r)
    c = r @ d1
    b = d2 @ d1
    tiny = 1e-300
    if a <= tiny:  # the segment is a point
        s = np.zeros(len(e))
        t = np.clip(f / np.where(e > tiny, e, 1.0), 0.0, 1.0)
    else:
        denom = a * e - b * b
        s = np.where(denom > 1e-14 * a * np.maximum(e, tiny), np.clip((b * f - c * e) / np.where(denom > 0, denom, 1.0),
                                                                         0.0, 1.0), 0.0)
        t = np.where(e > tiny, (b * s + f) / np.where(e > tiny, e, 1.0), 0.0)
        low, high = (t < 0.0) | (e <= tiny), t > 1.0  # a one-point polyline segment: t = 0
        t = np.clip(t, 0.0, 1.0)
        s = np.where(low, np.clip(-c / a, 0.0, 1.0), np.where(high, np.clip((b - c) / a, 0.0, 1.0), s))
    diff = (P0 + s[:, None] * d1) - (A + t[:, None] * d2)
    d2n = np.einsum("sn,sn->s", diff, diff)
    j = int(np.argmin(d2n))
    near = A[j] + t[j] * d2[j]
    return float(np.sqrt(d2n[j])), near[:-1] * x_scale, float(near[-1] * omega_scale)
