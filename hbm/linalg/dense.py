"""Direct solves: dense LU (LAPACK) or sparse LU (SuperLU), as a LinearSolver.

For small problems, tests and references: the HBM's own solver (hbm.harmonic.solver) keeps
the Jacobian's structure instead. A Jacobian that is neither an ndarray nor scipy sparse
but has __array__ (the structured HBM Jacobian) is made dense.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from hbm.linalg.bordered import eliminate_bordered, finite, refined_solution
from hbm.linalg.errors import SingularMatrixError
from hbm.linalg.protocol import BorderedStep


def lu_factor(A: np.ndarray):
    """scipy's LU of a dense matrix; raises SingularMatrixError on a zero or non-finite pivot
    (LAPACK only warns)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sla.LinAlgWarning)
        lu = sla.lu_factor(A, check_finite=False)
    if not np.all(np.isfinite(lu[0])) or np.any(np.diag(lu[0]) == 0.0):
        raise SingularMatrixError("dense LU: zero pivot")
    return lu


class DirectFactorization:
    """J factorised once; solve(b) and the checked block elimination of the bordered system.

    A singular J is not an error here but in solve(): the bordered system of a fold (J
    singular, the bordered matrix not) is then solved as a whole. solve() checks its answer
    (||J x - b|| <= refine_tol ||b||, one product with J; refined once where it misses): an LU
    of a nearly singular J gives no zero pivot but x ~ 1e16 with a residual of O(||b||). The
    block elimination uses the unchecked solve: it checks (and refines) its answer on the
    bordered system instead.
    """

    def __init__(self, J, refine_tol: float):
        self.refine_tol = refine_tol
        self._error: SingularMatrixError | None = None
        self._solve = None
        try:
            if sp.issparse(J):
                self.J = sp.csc_matrix(J)
                try:
                    self._solve = spla.splu(self.J).solve
                except RuntimeError as exc:  # "Factor is exactly singular"
                    raise SingularMatrixError(str(exc)) from exc
            else:
                self.J = np.asarray(J, dtype=float)
                lu = lu_factor(self.J)
                self._solve = lambda b: sla.lu_solve(lu, b, check_finite=False)
        except SingularMatrixError as exc:
            self._error = exc

    def _solve_unchecked(self, b: np.ndarray) -> np.ndarray:
        if self._error is not None:
            raise self._error
        x = self._solve(np.asarray(b, dtype=float))
        if not finite(x):
            raise SingularMatrixError("direct solve: non-finite result")
        return x

    def solve(self, b: np.ndarray) -> np.ndarray:
        b = np.asarray(b, dtype=float)
        return refined_solution(self.J, self._solve_unchecked, b, self.refine_tol, "direct solve")

    def solve_bordered(self, c, p, q, r, s) -> BorderedStep:
        return eliminate_bordered(self._solve_unchecked, self.J, c, p, q, r, s, self.refine_tol)


@dataclass
class DirectSolver:
    """LinearSolver by LU (dense) or SuperLU (scipy sparse), one factorisation per call.

    refine_tol: relative residual below which a solve is accepted: ||J x - b|| / ||b|| of a
    plain solve, that of the bordered system for the block elimination and the full bordered
    solve (see hbm.linalg.bordered). n_factorizations: factorisations done.
    """

    refine_tol: float = 1e-6
    n_factorizations: int = 0

    def factorize(self, J) -> DirectFactorization:
        self.n_factorizations += 1
        return DirectFactorization(J, self.refine_tol)
