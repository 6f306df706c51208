"""The HBM's LinearSolver: GMRES on the structured Jacobian, preconditioned by a direct solve
of an earlier, nearby one (hbm.harmonic.preconditioner), kept across Newton iterations and
continuation points while it works.

Nothing is approximated: each solve meets its tolerance on the true J (or falls back, in
turn, to this J's own preconditioner and to the dense LU); a direct answer (the exact
preconditioner, the dense LU) that misses it, J being (nearly) singular, is refused with a
SingularMatrixError, as GMRES's is. The tolerances are those of an
inexact Newton method: the corrector's step needs only the digits Newton's test can see.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import partial

import numpy as np
import scipy.linalg as sla

from hbm.harmonic.jacobian import HbmJacobian
from hbm.harmonic.preconditioner import ContactPreconditioner
from hbm.linalg.bordered import bordered_residual, eliminate_bordered, finite, refined_solution
from hbm.linalg.dense import lu_factor
from hbm.linalg.errors import SingularMatrixError
from hbm.linalg.gmres import gmres
from hbm.linalg.protocol import BorderedStep


@dataclass
class HbmSolver:
    """LinearSolver (hbm.linalg.protocol) for hbm.harmonic.jacobian.HbmJacobian.

    rtol: ||J x - b|| / ||b|| asked of each plain solve. 3e-7 keeps Newton's convergence
      (its own test is on ||R||) and passes the bordered check (refine_tol) with margin.
    forcing: the bordered (corrector) solves are inexact Newton steps with relative
      tolerance min(1e-3, max(rtol, forcing ||rhs||, atol / ||rhs||)): loose far from the
      solution, tight near it. Measured on the coarse rotor 67 ROM, [1500, 2000] rad/s,
      N_h = 40: forcing 0 / 1e-3 / 1e-2: RL 33.3 / 31.8 / 29.9 s, DLFT 14.7 / 12.8 / 13.5 s
      (DLFT's semi-smooth law dislikes inexact steps: 696 / 941 / 1063 Newton iterations);
      1e-3 is the compromise.
    atol: absolute residual asked of the bordered solves at most; compute_nfrc sets
      tol_residual / 10, which relaxes the last Newton step of each point to what Newton's
      test can see (RL NFRC 77 -> 67 s).
    plain_forcing: the plain solves (J x = b) as inexact Newton steps too, with relative
      tolerance min(1e-2, max(rtol, plain_forcing ||b||, atol / ||b||)); 0 (the default)
      keeps them at rtol, which the bordered fall-back, the stability analysis and the
      start strategies need. The isola search's seed corrections use 1e-2 (see
      hbm.isolas.harmonic.HbmProblem).
    max_krylov: GMRES iterations before a solve is declared stalled.
    refactor_after: a preconditioner costs ~12 ms at N_h = 40, a GMRES iteration ~1 ms,
      and its solves take 1.6, 2.5, 3.8, 5.7, 6.5 ... 9 iterations as it ages; rebuilding
      after a solve of more than 6 iterations measured best over a whole NFRC at N_h = 40
      (refactor_after 4 / 6 / 8 / 12: RL 51.0 / 47.8 / 50.1 / 54.6 s, DLFT 23.8 / 24.1 /
      27.0 / 27.5 s).
    single: the preconditioner's m x m LU in single precision (None: with friction, i.e.
      whenever it is a preconditioner only and not J's exact inverse).
    refine_tol: accepted relative residual of the bordered system's fall-back (block
      elimination, hbm.linalg.bordered).
    stats: counters "preconditioners", "krylov", "last_krylov", "dense_fallback",
    "bordered_fallback" (bordered solves that fell back to the block elimination).
    """

    rtol: float = 3e-7
    forcing: float = 1e-3
    atol: float = 0.0
    plain_forcing: float = 0.0
    max_krylov: int = 60
    refactor_after: int = 6
    single: bool | None = None
    refine_tol: float = 1e-6
    stats: dict = field(default_factory=dict)
    _pre: ContactPreconditioner | None = field(default=None, repr=False)
    _stale: bool = field(default=True, repr=False)
    _anorm: float = field(default=0.0, repr=False)  # ||J|| of the kept preconditioner's J (estimate)

    @property
    def n_factorizations(self) -> int:
        """Preconditioners built plus dense fall-back LUs."""
        return self.stats.get("preconditioners", 0) + self.stats.get("dense_fallback", 0)

    def _count(self, key: str, n: int = 1) -> None:
        self.stats[key] = self.stats.get(key, 0) + n

    def precondition(self, J: HbmJacobian) -> ContactPreconditioner:
        """Build (and keep, for the next factorize calls) J's own preconditioner."""
        self._pre = ContactPreconditioner(J, self.single)
        self._stale = False
        self._anorm = norm_estimate(J)
        self._count("preconditioners")
        return self._pre

    def factorize(self, J: HbmJacobian, preconditioner: ContactPreconditioner | None = None) -> "HbmFactorization":
        """J at the current point; reuses the kept preconditioner unless it has aged or was
        built for a Jacobian of another shape (another N_h or ROM: one solver may serve
        several residuals), or the given one (e.g. from another state, to test a stale
        preconditioner; ValueError if its shape is not J's)."""
        if not isinstance(J, HbmJacobian):
            raise TypeError(f"HbmSolver solves HbmJacobian, got {type(J).__name__} "
                            f"(use hbm.linalg.dense.DirectSolver for dense or sparse matrices)")
        error = None
        if preconditioner is not None:
            if preconditioner.source.shape != J.shape:
                raise ValueError(f"preconditioner built for a {preconditioner.source.shape} Jacobian, "
                                 f"J is {J.shape}")
            self._pre, self._stale, self._anorm = preconditioner, False, norm_estimate(preconditioner.source)
        elif self._stale or self._pre is None or self._pre.source.shape != J.shape:
            try:
                self.precondition(J)
            except SingularMatrixError as exc:  # Z_r or the contact system singular: see solve()
                self._pre, self._stale, error = None, True, exc
        return HbmFactorization(J, self, error)

    def _inexact_rtol(self, forcing: float, norm: float, cap: float) -> float:
        """Relative tolerance of an inexact Newton step whose right-hand side has this norm:
        min(cap, max(rtol, forcing norm, atol / norm)), loose far from the solution."""
        return min(cap, max(self.rtol, forcing * norm, self.atol / max(norm, 1e-300)))

    def _gmres(self, matvec, prec, b, x0, rtol):
        x, it, ok = gmres(matvec, prec, b, x0, rtol, self.max_krylov, self._anorm)
        self._count("krylov", it)
        self.stats["last_krylov"] = it
        if it > self.refactor_after:
            self._stale = True
        return x, ok


def norm_estimate(J) -> float:
    """||J v|| / ||v|| for a fixed random v: within a small factor of ||J||_2 for the harmonic
    blocks (a random v weighs every harmonic alike), at one product. GMRES bounds the
    round-off of its products with it (hbm.linalg.gmres)."""
    v = np.random.default_rng(0).standard_normal(J.shape[1])
    return float(np.linalg.norm(J @ v) / np.linalg.norm(v))


class HbmFactorization:
    """HbmSolver's Factorization of one J (see hbm.linalg.protocol)."""

    def __init__(self, J: HbmJacobian, solver: HbmSolver, error: SingularMatrixError | None = None):
        self.J, self.solver = J, solver
        self._dense_lu = None
        self._error = error  # no preconditioner could be built: solves fail, the bordered
        # system falls back to its full dense matrix (a fold where Z_r itself is singular)

    @property
    def _exact(self) -> bool:
        """The kept preconditioner is J's exact inverse (no friction, double precision)."""
        pre, J = self.solver._pre, self.J
        return pre.source is J and not pre.single and (not J.friction or not len(J.nodes))

    def _solve_one(self, b: np.ndarray, checked: bool = True) -> np.ndarray:
        """J^-1 b for b (n,). The direct answers (the exact preconditioner, the dense LU) are
        held to GMRES's rule, at one product with J, refined once where they miss
        (hbm.linalg.bordered.refined_solution); unless not `checked`: the block elimination
        checks its answer on the bordered system."""
        s, J = self.solver, self.J
        tol = s._inexact_rtol(s.plain_forcing, float(np.linalg.norm(b)), 1e-2) if s.plain_forcing > 0 else s.rtol
        if self._exact:  # J singular: no zero pivot, but x ~ 1e16 and ||J x - b|| ~ ||b||
            return refined_solution(J, s._pre, b, tol, "structured solve by the exact preconditioner") if checked \
                else s._pre(b)
        x, ok = s._gmres(J.__matmul__, s._pre, b, s._pre(b), tol)
        if ok:
            return x
        if s._pre.source is not J:  # the reused preconditioner is too far off: build this J's
            pre = s.precondition(J)
            x, ok = s._gmres(J.__matmul__, pre, b, pre(b), tol)
            if ok:
                return x
        s._count("dense_fallback")  # GMRES stalled even with J's own preconditioner
        if self._dense_lu is None:
            self._dense_lu = lu_factor(J.toarray())
        dense = partial(sla.lu_solve, self._dense_lu, check_finite=False)
        return refined_solution(J, dense, b, tol, "structured solve by the dense fall-back LU") if checked else dense(b)

    def solve(self, b: np.ndarray, checked: bool = True) -> np.ndarray:
        if self._error is not None:
            raise self._error
        b = np.asarray(b, dtype=float)
        cols = b.reshape(b.shape[0], -1)
        out = np.column_stack([self._solve_one(cols[:, c], checked) for c in range(cols.shape[1])])
        if not finite(out):
            raise SingularMatrixError("structured solve: non-finite result")
        return out.reshape(b.shape)

    def solve_bordered(self, c, p, q, r, s) -> BorderedStep:
        """One GMRES run on the whole bordered system (instead of the two solves of the block
        elimination), preconditioned by the block elimination done with the preconditioner,
        to the inexact-Newton tolerance (see HbmSolver); checked on the bordered system, and
        the block elimination with this factorisation's solve if GMRES stalls."""
        sv, J = self.solver, self.J
        rhs = -np.append(r, s)
        rn = float(np.linalg.norm(rhs))
        try:
            if self._error is not None:
                raise self._error
            pre = sv._pre
            cc = pre(c)
            den = q - p @ cc
            if not (np.isfinite(den) and den != 0.0):
                raise SingularMatrixError("bordered preconditioner: zero pivot")

            def prec(v):
                a = pre(v[:-1])
                dw = (v[-1] - p @ a) / den
                return np.append(a - cc * dw, dw)

            def mv(v):
                return np.append(J @ v[:-1] + c * v[-1], p @ v[:-1] + q * v[-1])

            tol = sv._inexact_rtol(sv.forcing, rn, 1e-3) if sv.forcing > 0 or sv.atol > 0 else sv.rtol
            d, ok = sv._gmres(mv, prec, rhs, prec(rhs), tol)
            if not (ok and finite(d)):
                raise SingularMatrixError("bordered GMRES: no convergence")
        except SingularMatrixError:
            sv._stale = True  # the next solve starts from a fresh preconditioner
        else:
            dx, dw = d[:-1], float(d[-1])
            if bordered_residual(J, c, p, q, r, s, dx, dw) <= max(sv.refine_tol, 2.0 * tol) * max(rn, 1e-300):
                return BorderedStep(dx, dw, False)
        sv._count("bordered_fallback")  # the one-GMRES path failed (or missed its check): recorded
        return eliminate_bordered(lambda v: self.solve(v, checked=False), J, c, p, q, r, s, sv.refine_tol)
