"""A branch of solutions as the continuation hands it over: points and why it stopped."""
from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

STATUS_OMEGA_MAX = "reached omega_max"
STATUS_OMEGA_MIN = "reached omega_min"
STATUS_CLOSED_LOOP = "closed loop"
STATUS_MAX_POINTS = "max points reached"
STATUS_STEP_FLOOR = "step below floor"  # followed by ": <why the last correction failed>"
STATUS_START_FAILED = "start point did not converge"  # followed by ": <why>"
STATUS_CRAWL = "crawled at the step floor"  # followed by ": <n> points ..."


class ContinuationPoint(NamedTuple):
    """One point of a branch, as handed to `on_point`.

    index: position in the branch (0: start point). omega: rad/s. x: (n,).
    converged: False only for a final failed attempt (its x, omega are the last iterate).
    residual_norm: ||R||_2. iterations: Newton iterations of the accepted correction.
    step: scaled arc length from the previous point (0 for the start point).
    time: wall-clock seconds spent on this point, failed attempts included.
    """

    index: int
    omega: float
    x: np.ndarray
    converged: bool
    residual_norm: float
    iterations: int
    step: float
    time: float


@dataclass(frozen=True, eq=False)  # arrays: compare fields explicitly, not with ==
class Branch:
    """A computed branch, m points of n unknowns.

    omega (m,) rad/s; x (m, n); converged (m,) bool; residual_norm (m,); iterations (m,)
    int; step (m,) scaled arc length from the previous point; time (m,) s per point.
    status: why it stopped (one of the STATUS_* strings; the failure ones followed by
    ": details"). detail: extra information (e.g. d_int of a closed loop).
    Only the last point can be unconverged (the failure that ended the branch).
    """

    omega: np.ndarray
    x: np.ndarray
    converged: np.ndarray
    residual_norm: np.ndarray
    iterations: np.ndarray
    step: np.ndarray
    time: np.ndarray
    status: str = ""
    detail: str = ""

    def __len__(self) -> int:
        return len(self.omega)

    def point(self, i: int) -> ContinuationPoint:
        """The i-th point (negative i counts from the end)."""
        i = range(len(self))[i]
        return ContinuationPoint(i, float(self.omega[i]), self.x[i], bool(self.converged[i]),
                                 float(self.residual_norm[i]), int(self.iterations[i]),
                                 float(self.step[i]), float(self.time[i]))

    @classmethod
    def from_points(cls, points, n: int, status: str = "", detail: str = "") -> "Branch":
        """Stack ContinuationPoints (x of size n each) into a Branch."""
        pts = list(points)
        return cls(omega=np.array([p.omega for p in pts], dtype=float),
                   x=np.array([p.x for p in pts], dtype=float).reshape(len(pts), n),
                   converged=np.array([p.converged for p in pts], dtype=bool),
                   residual_norm=np.array([p.residual_norm for p in pts], dtype=float),
                   iterations=np.array([p.iterations for p in pts], dtype=np.int64),
                   step=np.array([p.step for p in pts], dtype=float),
                   time=np.array([p.time for p in pts], dtype=float),
                   status=status, detail=detail)
