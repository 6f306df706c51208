"""Closed-loop test of the arc-length continuation on a curve that crosses back near its start
at another angle (a near-miss, not a return)."""
from __future__ import annotations

import numpy as np
import pytest

from hbm.continuation.arclength import ContinuationOptions, continue_branch
from hbm.continuation.branch import STATUS_CLOSED_LOOP
from hbm.continuation.newton import NewtonOptions

TOL = 1e-12  # residual tolerance of the runs here
D_MIN = 1e-2  # closed_loop_tol of eq. (27)


class Eight:
    """x1 = c + sin t, omega = wc + a sin t cos t, x2 = x2_0 + h t: a figure-eight in (x1, omega)
    drawn along x2 (n = 2), parameterised by t = (x2 - x2_0) / h.

    It passes over the start's (x1, omega) at t = pi, x2 shifted by pi h, with the tangent
    (dx1, dx2, dw) = (-1, h, a) against (1, h, a) at t = 0 (127 deg apart for a = 0.5), and again at
    t = 2 pi, x2 shifted by 2 pi h, with the start's tangent.
    """

    def __init__(self, c=2.0, wc=1.5, a=0.5, x2_0=10.0, h=0.01):
        self.c, self.wc, self.a, self.x2_0, self.h = c, wc, a, x2_0, h

    def t(self, x2):
        return (np.asarray(x2) - self.x2_0) / self.h

    def __call__(self, x, w):
        x1, x2 = x
        t = self.t(x2)
        R = np.array([x1 - self.c - np.sin(t), w - self.wc - self.a * np.sin(t) * np.cos(t)])
        J = np.array([[1.0, -np.cos(t) / self.h], [0.0, -self.a * np.cos(2 * t) / self.h]])
        return R, J, np.array([0.0, 1.0])


def d_int_at(b, i, x0, w0):
    """eq. (27)'s relative distance where the chord i -> i + 1 crosses w0."""
    x_int = b.x[i] + (w0 - b.omega[i]) / (b.omega[i + 1] - b.omega[i]) * (b.x[i + 1] - b.x[i])
    return np.linalg.norm(x_int - x0) / np.linalg.norm(x_int)


@pytest.mark.parametrize("direction", [1, -1])
def test_crossing_near_the_start_at_another_angle_is_not_a_loop(direction):
    e = Eight()
    x0, w0 = np.array([e.c, e.x2_0]), e.wc
    o = ContinuationOptions(0.0, 5.0, ds=0.02, ds_max=0.05, direction=direction, closed_loop_tol=D_MIN,
                            max_points=2000, newton=NewtonOptions(tol_residual=TOL))
    b = continue_branch(e, x0, w0, o)
    t = np.abs(e.t(b.x[:, 1]))
    assert b.status == STATUS_CLOSED_LOOP and b.converged.all()
    # every point on the analytic curve
    np.testing.assert_allclose(b.x[:, 0], e.c + np.sin(e.t(b.x[:, 1])), atol=1e-10)
    np.testing.assert_allclose(b.omega, e.wc + e.a * np.sin(e.t(b.x[:, 1])) * np.cos(e.t(b.x[:, 1])), atol=1e-10)
    # The crossing of w0 near t = pi is within d_min of the start (eq. (27) alone would call it
    # a loop: d_int = pi h / |x| = 3.1e-3), yet the run went on to the return with the start's
    # tangent at t = 2 pi (d_int = 2 pi h / |x| = 6.1e-3) and stopped one step past it: near
    # t = 2 pi the curve's speed |d(x, w)/dt| is >= 1, so a step of ds_max covers dt <= ds_max.
    def expected(t):
        return t * e.h / np.hypot(e.c, e.x2_0 + t * e.h)

    half = np.flatnonzero((t[:-1] < np.pi) & (t[1:] >= np.pi))
    assert half.size == 1
    assert d_int_at(b, half[0], x0, w0) == pytest.approx(expected(np.pi), rel=0.05)
    assert expected(np.pi) < D_MIN
    assert 2 * np.pi <= t[-1] <= 2 * np.pi + 0.05
    assert float(b.detail.split("=")[1].split()[0]) == pytest.approx(expected(2 * np.pi), rel=0.05)


class Helix:
    """x1 = c + r cos t, omega = wc + a sin t, x2 = h t: a helix that never closes, drawn along
    x2 and parameterised by t = x2 / h; a = 100 r rad/s makes its turns circles of radius r in
    the continuation's metric (omega / 100 rad/s). Each turn crosses the start's omega with the
    start's tangent, at d_int = 2 pi h k / |x| after k turns (eq. (27)): a near return as far
    from the start as h says. The chords' interpolation adds ~r dt^2 / 8 at a crossing (dt the
    turn of a step, ~0.5 rad), 1.5e-4 of |x| here."""

    def __init__(self, h, c=20.0, r=0.1, wc=1000.0):
        self.h, self.c, self.r, self.wc, self.a = h, c, r, wc, 100.0 * r

    def __call__(self, x, w):
        x1, x2 = x
        t = x2 / self.h
        R = np.array([(x1 - self.c) / self.r - np.cos(t), (w - self.wc) / self.a - np.sin(t)])
        J = np.array([[1.0 / self.r, np.sin(t) / self.h], [0.0, -np.cos(t) / self.h]])
        return R, J, np.array([0.0, 1.0 / self.a])


@pytest.mark.parametrize("d_first, closes", [(4e-3, False), (3e-4, True)])
def test_the_products_continuation_calls_a_return_a_loop_only_within_its_tolerance(d_first, closes):
    """The NFRC's and the isola search's settings (hbm.harmonic.nfrc.default_continuation: u and
    omega / 100 rad/s, d_min = 1e-3) on a helix in (x1, omega) drawn along x2: its first return
    to the start's omega, with the start's tangent, passes d_first from the start in eq. (27)'s
    metric. 4e-3 is a near-miss (the branch goes round again, up to its point cap); 3e-4 is
    within d_min, a closed loop after one turn."""
    from dataclasses import replace
    from hbm.harmonic.nfrc import default_continuation
    from hbm.options import HbmOptions

    x0 = np.array([20.0 + 0.1, 0.0])
    e = Helix(h=d_first * np.linalg.norm(x0) / (2 * np.pi))
    o = replace(default_continuation(HbmOptions()), direction=1, max_points=120)
    b = continue_branch(e, x0, e.wc, o)
    t = b.x[:, 1] / e.h
    assert b.converged.all()
    np.testing.assert_allclose(b.x[:, 0], e.c + e.r * np.cos(t), atol=1e-9)
    np.testing.assert_allclose(b.omega, e.wc + e.a * np.sin(t), atol=1e-6)
    if closes:
        assert b.status == STATUS_CLOSED_LOOP and 2 * np.pi <= t[-1] < 2 * np.pi + 1.0
    else:
        assert b.status != STATUS_CLOSED_LOOP and t[-1] > 4 * np.pi  # past the first two returns
