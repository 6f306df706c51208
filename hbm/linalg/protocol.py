"""What the continuation asks of a linear solver (structural typing, nothing to inherit).

A `LinearSolver` turns the Jacobian dR/dx that a residual callable returned into a
`Factorization` at the current point; the factorisation solves J x = b and the bordered
system of the arc-length corrector. The solver may keep state between calls (a reused
preconditioner, counters); the continuation never looks inside J.
"""
from __future__ import annotations

from typing import NamedTuple, Protocol

import numpy as np


class BorderedStep(NamedTuple):
    """Solution of [[J, c], [p^T, q]] [dx; dw] = -[r; s].

    dx: (n,). dw: the parameter's component. full: whether the full bordered matrix had to
    be factorised (J singular or too ill-conditioned for block elimination).
    """

    dx: np.ndarray
    dw: float
    full: bool


class Factorization(Protocol):
    """J factorised (or preconditioned) at one point."""

    def solve(self, b: np.ndarray) -> np.ndarray:
        """x with J x = b; b (n,) or (n, k), x the same shape. Raises SingularMatrixError."""

    def solve_bordered(self, c: np.ndarray, p: np.ndarray, q: float, r: np.ndarray, s: float) -> BorderedStep:
        """The corrector's step, eq. (25) of the reference paper: [[J, c], [p^T, q]] [dx; dw]
        = -[r; s], c = dR/domega (n,), p = dP/dx (n,), q = dP/domega, r = R (n,), s = P.
        Raises SingularMatrixError when no solve succeeds."""


class LinearSolver(Protocol):
    """Makes a Factorization of each Jacobian; `n_factorizations` counts the expensive ones."""

    n_factorizations: int

    def factorize(self, J) -> Factorization:
        """Factorise (or precondition) J, the dR/dx returned by the residual callable."""
