"""The continuation's edges: bad inputs named, landing on the bound next to a fold, and an
NFRC resumed after a start at the other end. Synthetic residuals with known solution sets."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from hbm.continuation.arclength import ContinuationOptions, continue_branch
from hbm.continuation.branch import STATUS_MAX_POINTS, STATUS_OMEGA_MAX, STATUS_STEP_FLOOR, Branch
from hbm.continuation.newton import NewtonOptions, newton_solve
from hbm.linalg.dense import DirectSolver
from hbm.linalg.errors import SingularMatrixError

from systems import Wave

TOL = 1e-10


def opts(lo, hi, **kw):
    return ContinuationOptions(lo, hi, newton=NewtonOptions(tol_residual=TOL), **kw)


class Parabola:
    """x = w^2 (R = x - w^2); dR_dx (bad="J") or dR_domega (bad="w") is NaN for w > w_bad, or
    the residual is undefined there (bad="pole": SingularMatrixError, as the condensation
    raises at a fixed-interface eigenfrequency)."""

    def __init__(self, bad: str, w_bad: float = 1.5):
        self.bad, self.w_bad = bad, w_bad

    def __call__(self, x, w):
        J, r_w = np.array([[1.0]]), np.array([-2.0 * w])
        if w > self.w_bad and self.bad == "pole":
            raise SingularMatrixError(f"condensation at omega={w:.9g} rad/s: harmonic 1 sits on a pole")
        if w > self.w_bad:
            if self.bad == "J":
                J = np.array([[np.nan]])
            else:
                r_w = np.array([np.nan])
        return np.array([x[0] - w * w]), J, r_w


# ---------------------------------------------------------------- bad inputs named
def test_a_residual_undefined_at_the_iterate_is_a_failed_solve_with_its_reason():
    # the exception used to escape Newton and end the whole NFRC
    r = newton_solve(Parabola("pole", w_bad=0.0), np.array([1.2]), 1.0, NewtonOptions(tol_residual=TOL))
    assert not r.converged and r.reason.startswith("residual not defined at omega=1: condensation at omega=1 rad/s"), r.reason


def test_nan_jacobian_is_named_not_called_singular():
    r = newton_solve(Parabola("J", w_bad=0.0), np.array([1.2]), 1.0, NewtonOptions(tol_residual=TOL))
    assert not r.converged
    assert "non-finite Jacobian" in r.reason and "singular" not in r.reason


class _InfiniteStep:
    """A linear solver whose solve overflows without raising (a pivot of 1e-320)."""

    def factorize(self, J):
        return self

    def solve(self, b):
        return np.full_like(b, np.inf)


def test_a_non_finite_newton_step_is_named_singular():
    r = newton_solve(Parabola("pole", w_bad=9.0), np.array([1.2]), 1.0, NewtonOptions(tol_residual=TOL),
                     solver=_InfiniteStep())
    assert not r.converged and r.reason == "singular Jacobian at omega=1: non-finite step"
    np.testing.assert_array_equal(r.x, [1.2])  # the last finite iterate, not the overflow


def _arctan(x, w):
    """R = arctan(x - 1), undefined (a pole, as the condensation raises) for x < 0: Newton's
    full step from x = 2.5 lands on 2.5 - atan(1.5) (1 + 1.5^2) = -0.694."""
    if x[0] < 0.0:
        raise SingularMatrixError("pole at x < 0")
    d = x[0] - 1.0
    return np.array([np.arctan(d)]), np.array([[1.0 / (1.0 + d * d)]]), np.array([0.0])


def test_the_line_search_shortens_a_step_into_an_undefined_residual():
    no_search = newton_solve(_arctan, np.array([2.5]), 1.0, NewtonOptions(tol_residual=TOL))
    assert not no_search.converged and no_search.reason.startswith("residual not defined at omega=1: pole")
    r = newton_solve(_arctan, np.array([2.5]), 1.0, NewtonOptions(tol_residual=TOL, line_search=True))
    assert r.converged and abs(r.x[0] - 1.0) < 1e-10


def _stored(converged):
    """A stored branch x = w^2 of len(converged) points with these flags (as a branch file holds)."""
    w = np.linspace(1.0, 1.1, len(converged))
    return Branch(omega=w, x=(w * w)[:, None], converged=np.array(converged), residual_norm=np.zeros(len(w)),
                  iterations=np.ones(len(w), dtype=int), step=np.full(len(w), 0.05), time=np.zeros(len(w)),
                  status=STATUS_MAX_POINTS, detail="")


@pytest.mark.parametrize("flags, message", [
    ([False, True, True], "resume: the branch to continue has no converged start point"),
    ([False, False], "resume: the branch to continue has no converged start point"),
    ([True, False, True], "resume: unconverged point inside the branch"),
])
def test_a_branch_that_cannot_be_resumed_is_refused_by_name(flags, message):
    with pytest.raises(ValueError, match=f"^{message}$"):
        continue_branch(Parabola("pole", w_bad=9.0), None, None, opts(0.5, 2.0), resume=_stored(flags))


def test_a_start_outside_the_range_is_refused():
    with pytest.raises(ValueError, match=r"^omega0 = 2.5 outside \[0.5, 2.0\]$"):
        continue_branch(Parabola("pole", w_bad=9.0), np.array([6.25]), 2.5, opts(0.5, 2.0))


@pytest.mark.parametrize("bad, name", [("J", "non-finite Jacobian"), ("w", "non-finite dR_domega"),
                                       ("pole", "residual not defined")])
def test_nan_derivative_along_the_branch_is_named(bad, name):
    b = continue_branch(Parabola(bad), np.array([1.0]), 1.0, opts(0.0, 5.0, ds=0.05, ds_max=0.1, ds_min=1e-4))
    assert b.status.startswith(STATUS_STEP_FLOOR) and name in b.status, b.status
    assert "singular" not in b.status and "non-finite residual" not in b.status
    ok = b.converged
    assert ok[:-1].all() and not ok[-1]
    np.testing.assert_allclose(b.x[ok, 0], b.omega[ok] ** 2, atol=TOL)  # on x = w^2
    assert b.omega[ok].max() <= 1.5 and b.omega[ok].max() > 1.5 - 1e-2  # followed it up to w = 1.5


@pytest.mark.parametrize("bad, name", [("J", "dR_dx"), ("w", "dR_domega")])
def test_nan_derivative_at_the_start_raises_a_named_error(bad, name):
    # x0 solves R exactly: the start converges without a solve, the tangent needs dR_dx, dR_domega.
    with pytest.raises(ValueError, match=name):
        continue_branch(Parabola(bad, w_bad=0.0), np.array([1.0]), 1.0, opts(0.0, 5.0))


# ---------------------------------------------------------------- landing on the bound
@pytest.mark.parametrize("eps, ds", [(1e-5, 0.01), (1e-5, 0.02), (1e-4, 0.01), (1e-4, 0.05)])
def test_lands_on_the_bound_below_a_fold_just_beyond_it(eps, ds):
    # Wave: w = 1 + 0.3 sin(4 x1), crests (folds) at w = 1.3, just above omega_max = 1.3 - eps.
    # The corrector lands in a crest's cap (w > omega_max, within 2e-3 of the crest in x1);
    # the bound is met exactly at 4 x1 = asin(1 - eps / 0.3) + 2 pi j, on the way up (cos > 0),
    # a fraction of a step behind; the other root, past the crest, is farther than the step.
    w = Wave(w0=1.0, h=0.3, kappa=4.0, x2_0=10.0)
    hi = 1.3 - eps
    b = continue_branch(w, np.array([0.0, 10.0]), 1.0, opts(0.0, hi, ds=ds, ds_max=0.05, max_points=400))
    assert b.status == STATUS_OMEGA_MAX and b.converged.all()
    assert b.omega[-1] == hi and b.omega.max() == hi  # on the bound, never past it
    x1 = b.x[-1, 0]
    j = np.round((4 * x1 - np.arcsin(1 - eps / 0.3)) / (2 * np.pi))
    assert 4 * x1 == pytest.approx(np.arcsin(1 - eps / 0.3) + 2 * np.pi * j, abs=1e-8)  # the near root
    assert np.cos(4 * x1) > 0
    assert b.x[-1, 1] == pytest.approx(10.0, abs=TOL)


# ---------------------------------------------------------------- NFRC resume after a start at the other end
def test_nfrc_resume_keeps_the_reversed_direction():
    """compute_nfrc starts at the other end, going back, when no start converges at the end
    that the direction names; a resume of that run must go back too (the first steps follow
    the start's tangent, oriented by the direction)."""
    from hbm.harmonic.nfrc import compute_nfrc, default_continuation
    from hbm.harmonic.residual import build_residual
    from hbm.options import CasingOptions, ContactOptions, HbmOptions
    from support import coarse_rom

    hbm = HbmOptions(n_harmonics=5, n_time=64, omega_min=400.0, omega_max=500.0)
    cont = replace(default_continuation(hbm), direction=1, ds=0.02, ds_max=0.05, max_points=10)
    rom = coarse_rom()
    inner = build_residual(rom, CasingOptions(), ContactOptions(), hbm, method="dlft")

    class NoStartAtMin:
        """The DLFT residual, NaN at omega_min: no start there."""

        def __init__(self, r):
            self.__dict__["_r"] = r

        def __getattr__(self, k):
            return getattr(self._r, k)

        def __call__(self, u, omega, jacobian=True):
            out = self._r(u, omega, jacobian=jacobian)
            if float(omega) == hbm.omega_min:
                return (np.full_like(out[0], np.nan),) + tuple(out[1:]) if jacobian else np.full_like(out, np.nan)
            return out

    res = NoStartAtMin(inner)

    def run(**kw):
        return compute_nfrc(rom, CasingOptions(), ContactOptions(), hbm, "dlft", continuation=cont, residual=res,
                            solver=DirectSolver(), **kw)

    full = run()
    assert full.status == STATUS_MAX_POINTS and full.omega[0] == 500.0 and "other end" in full.start
    assert np.all(np.diff(full.omega) < 0)  # going down from 500 rad/s
    for k in (1, 2):
        old = Branch(omega=full.omega[:k], x=full.unknowns[:k], converged=full.converged[:k],
                     residual_norm=full.residual_norm[:k], iterations=full.iterations[:k], step=full.step[:k],
                     time=full.time[:k])
        r = run(resume=old)
        assert r.status == full.status and len(r.omega) == len(full.omega)
        assert np.all(np.diff(r.omega) < 0) and r.omega[-1] >= 400.0
        for u, w in zip(r.unknowns, r.omega):  # every point solves the residual
            assert np.linalg.norm(inner(u, w, jacobian=False)) <= cont.newton.tol_residual
        np.testing.assert_allclose(r.omega, full.omega, rtol=1e-8)  # the uninterrupted run's steps
