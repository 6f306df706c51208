"""The start lies_on gives Newton near a stored branch (hbm.isolas.search._curve_guess): the
parabola through the three vertices around the nearest segment, at the given Omega, against
a branch whose curve is known exactly (a circle in the (x, Omega) plane).

Its error must fall as h^3 with the vertex spacing h (the parabola's interpolation error),
where the chord's nearest point, which Newton started from before, falls as h^2 (the
sagitta), once the vertices are a few degrees of the bend apart: on a bend, the chord can lie nearer another branch than its own curve (the
docstring of lies_on). A branch of two points, or with two equal vertices, has no parabola:
the guess is then the chord's point.
"""
import numpy as np
import pytest

from hbm.isolas.membership import KnownBranch, nearest_segment
from hbm.isolas.search import _curve_guess

R, W0, X0 = 2.0, 1000.0, 0.5  # the circle: x = X0 + R cos(phi), Omega = W0 + R sin(phi)


def circle(phi):
    phi = np.asarray(phi, dtype=float)
    return X0 + R * np.cos(phi), W0 + R * np.sin(phi)


def branch(h: float, n: int = 7, start: float = 0.2) -> KnownBranch:
    x, w = circle(start + h * np.arange(n))
    return KnownBranch(w, np.column_stack([x, -3.0 * x]), "circle")  # two unknowns, the second -3 x


def errors(h: float):
    """(guess error, chord error) in x at a point 0.35 of the way along the 4th segment."""
    b = branch(h)
    phi = 0.2 + h * 3.35
    x, w = circle(phi)
    q = np.array([x, -3.0 * x])
    _, xn, _, s, t = nearest_segment(q, w, b)
    assert s == 3  # the segment the point is along
    guess = _curve_guess(b, q, w, 1.0, 1.0)
    assert guess[1] == pytest.approx(-3.0 * guess[0], rel=1e-12)  # every unknown from the same parabola
    return abs(guess[0] - x), abs(xn[0] - x)


def test_the_parabola_s_error_falls_as_h_cubed_and_soon_below_the_chord_s():
    hs = [0.05, 0.025, 0.0125, 0.00625]  # rad of the circle between vertices
    e = np.array([errors(h) for h in hs])
    guess_rate = np.log2(e[:-1, 0] / e[1:, 0])
    chord_rate = np.log2(e[:-1, 1] / e[1:, 1])
    # measured: 3.05, 3.07, 3.05 (from h = 0.2: 2.77, 2.95, then these); the chord's nearest
    # point, off the curve by the sagitta along the normal, 1.60, 1.81, 1.91 on its way to 2
    assert np.all(np.abs(guess_rate - 3.0) < 0.1), guess_rate
    assert np.all(chord_rate < 2.0 + 0.1) and chord_rate[-1] > 1.8, chord_rate
    # at these spacings the guess is 4 to 58 times nearer (at 0.2 rad the chord's point was
    # 3.6 times nearer: the parabola of three vertices 23 degrees apart is no better)
    assert np.all(e[:, 0] < 0.3 * e[:, 1]), e


def test_without_three_distinct_vertices_the_guess_is_the_chord_s_point():
    x, w = circle([0.2, 0.5])
    two = KnownBranch(w, x[:, None], "two points")
    q, wq = np.array([X0 + R * np.cos(0.3)]), W0 + R * np.sin(0.3)
    _, xn, _, _, _ = nearest_segment(q, wq, two)
    np.testing.assert_array_equal(_curve_guess(two, q, wq, 1.0, 1.0), xn)
    x, w = circle([0.2, 0.5, 0.5, 0.8])  # a vertex stored twice (a zero-length chord)
    twice = KnownBranch(w, x[:, None], "a vertex twice")
    _, xn, _, s, t = nearest_segment(q, wq, twice)
    assert s == 0
    np.testing.assert_array_equal(_curve_guess(twice, q, wq, 1.0, 1.0), xn)
