"""hbm.isolas.membership.segment_polyline_distance, the search's meeting test (a chord of a
continuation against a branch's polyline), against a brute-force reference and against
distances worked out by hand for the degenerate cases."""
from __future__ import annotations

import numpy as np
import pytest

from hbm.isolas.membership import KnownBranch, segment_polyline_distance


def _branch(points) -> KnownBranch:
    """A branch through points (m, 3) = (x_0, x_1, omega)."""
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    return KnownBranch(points[:, 2].copy(), points[:, :2].copy(), "b")


def _distance(p0, p1, points, x_scale=1.0, omega_scale=1.0, within=None):
    p0, p1 = np.asarray(p0, dtype=float), np.asarray(p1, dtype=float)
    return segment_polyline_distance(p0[:2], p0[2], p1[:2], p1[2], _branch(points), x_scale, omega_scale, within)


def _sampled(p0, p1, points, n=401):
    """Smallest distance between n samples of the segment and n samples of each polyline
    segment, and its bound on the error: the exact minimum lies in [d - err, d]."""
    s = np.linspace(0.0, 1.0, n)[:, None]
    chord = p0 + s * (p1 - p0)
    best, err = np.inf, 0.0
    for a, b in zip(points[:-1], points[1:]) if len(points) > 1 else [(points[0], points[0])]:
        d = np.sqrt((((chord[:, None, :] - (a + s * (b - a))[None, :, :]) ** 2).sum(axis=-1)).min())
        if d < best:  # a nearest pair lies half a sample step from a sampled one on each segment
            best, err = d, (np.linalg.norm(p1 - p0) + np.linalg.norm(b - a)) / (2 * (n - 1))
    return best, err


def _to_segment(p, a, b) -> float:
    """Distance of the point p to the segment a-b, by projection."""
    ab = b - a
    t = 0.0 if ab @ ab == 0 else min(max((p - a) @ ab / (ab @ ab), 0.0), 1.0)
    return float(np.linalg.norm(p - a - t * ab))


def test_the_distance_is_the_smallest_over_dense_samples_of_both_segments():
    """Random polylines of 1 to 5 points (some with a repeated point) and chords (some of
    zero length), in a scaled metric. The nearest point returned lies on the polyline at the
    distance returned from the chord; with within=w the distance is the same (to round-off)
    whenever it is <= w, and never claimed <= w when it is not."""
    rng = np.random.default_rng(7)
    scale = np.array([2.0, 0.5, 3.0])  # x_scale (2,), omega_scale
    checked = {"near": 0, "far": 0}
    for trial in range(40):
        points = rng.normal(size=(rng.integers(1, 6), 3)) * scale
        if trial % 4 == 1 and len(points) > 2:
            points[2] = points[1]
        p0, p1 = rng.normal(size=3) * scale, rng.normal(size=3) * scale
        if trial % 5 == 2:
            p1 = p0.copy()
        d, xn, wn = _distance(p0, p1, points, scale[:2], scale[2])
        ref, err = _sampled(p0 / scale, p1 / scale, points / scale)
        assert ref - err - 1e-12 <= d <= ref + 1e-12, (trial, d, ref, err)
        near = np.append(xn, wn) / scale
        on = min(_to_segment(near, a / scale, b / scale) for a, b in zip(points[:-1], points[1:])) \
            if len(points) > 1 else float(np.linalg.norm(near - points[0] / scale))
        assert on <= 1e-12 and _to_segment(near, p0 / scale, p1 / scale) == pytest.approx(d, rel=1e-9, abs=1e-12)
        for tol in (0.1, 0.5, 2.0):
            dw = _distance(p0, p1, points, scale[:2], scale[2], within=tol)[0]
            if d <= tol:
                # the same minimum over fewer segments: equal to round-off (numpy's vectorised
                # reductions over another array length differ in the last bit on some hosts)
                assert dw == pytest.approx(d, rel=1e-13, abs=0.0)
                checked["near"] += 1
            else:
                assert dw > tol
                checked["far"] += 1
    assert checked["near"] > 10 and checked["far"] > 10


@pytest.mark.parametrize("p0, p1, points, expected", [
    # a chord of zero length: a point's distance to the polyline
    ((1, 1, 0), (1, 1, 0), [(0, 0, 0), (2, 0, 0)], 1.0),
    ((3, 0, 4), (3, 0, 4), [(0, 0, 0), (2, 0, 0)], np.sqrt(17.0)),  # past the end: to (2, 0, 0)
    # a polyline of one point
    ((-1, 1, 0), (1, 1, 0), [(0, 0, 0)], 1.0),
    ((1, 1, 1), (2, 2, 2), [(0, 0, 0)], np.sqrt(3.0)),
    ((1, 2, 2), (1, 2, 2), [(0, 0, 0)], 3.0),
    # a polyline segment of zero length (a repeated point), then one along omega
    ((3, -1, 2), (3, 1, 2), [(0, 0, 0), (0, 0, 0), (0, 0, 5)], 3.0),
    ((2, 0, -4), (2, 0, -3), [(0, 0, 0), (0, 0, 0), (0, 0, 5)], np.sqrt(13.0)),
    # parallel to the polyline's segment (0, 0, 0)-(4, 0, 0): beside it, past its end (either
    # direction), on its line
    ((1, 2, 0), (3, 2, 0), [(0, 0, 0), (4, 0, 0)], 2.0),
    ((5, 0, 3), (7, 0, 3), [(0, 0, 0), (4, 0, 0)], np.sqrt(10.0)),
    ((7, 0, 3), (5, 0, 3), [(0, 0, 0), (4, 0, 0)], np.sqrt(10.0)),
    ((2, 0, 0), (6, 0, 0), [(0, 0, 0), (4, 0, 0)], 0.0),
    # crossing: the chord meets the polyline between its points
    ((1, -1, 1), (1, 1, 1), [(0, 0, 0), (2, 0, 2), (2, 0, 4)], 0.0),
])
def test_degenerate_and_parallel_segments_have_their_distance_by_hand(p0, p1, points, expected):
    d = _distance(p0, p1, points)[0]
    assert d == pytest.approx(expected, rel=1e-12, abs=1e-12)
    assert _distance(p0, p1, points, within=expected + 1e-9)[0] == d


def test_an_empty_branch_is_infinitely_far():
    d, xn, wn = segment_polyline_distance(np.zeros(2), 0.0, np.ones(2), 1.0, KnownBranch.of([], np.zeros((0, 2)), "b"))
    assert d == np.inf and wn == 1.0 and xn.tolist() == [1.0, 1.0]


def test_the_refined_tests_window_gives_the_whole_polylines_nearest_segment():
    """lies_on's refined test scans only the segments whose omega span comes within
    refine_ratio times the longest chord (KnownBranch.longest_segment) of the point: wherever
    the whole polyline's nearest segment passes the test (distance at most refine_ratio times
    the chords at its nearest vertex), the window gives that segment, bit for bit, and
    elsewhere nothing that passes. Random wavy polylines with chords of unequal lengths."""
    from hbm.isolas.membership import nearest_segment, segment_length

    rng = np.random.default_rng(7)
    ratio, passed = 0.5, 0
    for trial in range(60):
        m = int(rng.integers(2, 80))
        w = np.cumsum(rng.uniform(0.05, 3.0, m))  # rad/s, chords of very different lengths
        x = np.column_stack([np.sin(w / rng.uniform(1, 20)), rng.normal(0, 0.3, m).cumsum()])
        b = KnownBranch(w, x, "b")
        x_scale, w_scale = np.array([0.5, 2.0]), 4.0
        longest = max(segment_length(b, k, x_scale, w_scale) for k in range(m))
        assert longest <= b.longest_segment(x_scale, w_scale) <= longest * (1 + 2e-9)
        reach = ratio * b.longest_segment(x_scale, w_scale)
        for _ in range(20):
            k = int(rng.integers(m))
            q = x[k] + rng.normal(0, 10 ** rng.uniform(-3, 0.5), 2)
            qw = w[k] + rng.normal(0, 10 ** rng.uniform(-2, 1))
            whole = nearest_segment(q, qw, b, x_scale, w_scale)
            window = nearest_segment(q, qw, b, x_scale, w_scale, within=reach)

            def passes(found):
                d, _, _, s, t = found
                return bool(np.isfinite(d) and d <= ratio * segment_length(b, s + int(t > 0.5), x_scale, w_scale))

            assert passes(window) == passes(whole)
            if passes(whole):
                passed += 1
                assert window[0] == whole[0] and window[3:] == whole[3:]
                assert np.array_equal(window[1], whole[1]) and window[2] == whole[2]
    assert passed > 100  # the test saw points that pass, not only far ones
