"""Bifurcation records and multiplier pairing (hbm.stability.bifurcation) on hand-built
cases."""
import math

import numpy as np
import pytest

from hbm.stability.bifurcation import (CROSSING, GUESS, PARITY, PERIOD_DOUBLING, Bifurcation, bifurcation_arrays,
                                       bifurcations_from_arrays, classify, crossings, pair_multipliers,
                                       parabola_vertex, real_parities)


def test_a_real_multiplier_moved_below_the_axis_still_pairs_with_itself_across_minus_one():
    """The truncation moves a real multiplier off the axis (DLFT): at point a it is
    -0.95 - 0.005 i (no conjugate listed), at point b -1.05 + 0.005 i; another real one, below
    the floor 0.25 at a (0.2), has risen to 0.97 at b. In (log|mu|, |arg mu|) the first two are
    0.1 apart, -0.95 - 0.005 i and 0.97 are pi apart: the crossing is the first multiplier going
    through -1, a period doubling."""
    mu_a = np.array([-0.95 - 0.005j, 0.2 + 0.0j])
    mu_b = np.array([-1.05 + 0.005j, 0.97 + 0.0j])
    cr = crossings(mu_a, mu_b, floor=0.25)
    assert cr == [(0, 0)]
    assert classify(mu_b[0], fold=False) == PERIOD_DOUBLING


def test_a_multiplier_beyond_the_window_is_not_paired():
    """|log|mu|| >= window (1) is not paired: 0.5 at a and e^1.25 at b are not the same
    multiplier crossing; 0.9 and 1.1 (|log| < 1) are."""
    assert pair_multipliers(np.array([0.5 + 0j]), np.array([math.exp(1.25) + 0j]), floor=0.0) == []
    assert crossings(np.array([0.5 + 0j]), np.array([math.exp(1.25) + 0j]), floor=0.0) == []
    assert crossings(np.array([0.9 + 0j]), np.array([1.1 + 0j]), floor=0.0) == [(0, 0)]


def test_the_vertex_of_a_parabola_beyond_the_points_is_clipped_to_them():
    """y(s) = 1.05 s - 0.05 s^2 through s = 0, 1, 2 has its vertex at s = 10.5, far beyond the
    points: the located extremum stays at the last point, s = 2, y = 1.9 (z(s) = 3 s there: 6)."""
    s = np.array([0.0, 1.0, 2.0])
    y = 1.05 * s - 0.05 * s ** 2
    ss, yy, zz = parabola_vertex(s, y, 3.0 * s)
    assert ss == pytest.approx(2.0, abs=1e-12)
    assert yy == pytest.approx(1.9, abs=1e-12)
    assert zz == pytest.approx(6.0, abs=1e-12)
    # inside: y = -(s - 1.3)^2 has its vertex at 1.3, y 0, z 3.9
    ss, yy, zz = parabola_vertex(s, -(s - 1.3) ** 2, 3.0 * s)
    assert (ss, yy, zz) == (pytest.approx(1.3, abs=1e-12), pytest.approx(0.0, abs=1e-12), pytest.approx(3.9, abs=1e-12))


def test_the_table_holds_each_field_of_a_bifurcation():
    bifs = (Bifurcation(kind=PERIOD_DOUBLING, omega=1450.5, le_amplitude=2e-4, index=7, fraction=0.25,
                        omega_bracket=(1450.0, 1452.0), multiplier=-1.02 + 0.003j, direction=-1, period_ratio=2,
                        kind_from=PARITY),
            Bifurcation(kind="fold", omega=1500.0, le_amplitude=3e-4, index=11, fraction=0.5,
                        omega_bracket=(1499.0, 1498.0), multiplier=1.01 - 0.0j, direction=1, kind_from=GUESS))
    tab = bifurcation_arrays(bifs)
    assert list(tab["omega_low"][0]) == [1450.0, 1499.0] and list(tab["omega_high"][0]) == [1452.0, 1498.0]
    assert list(tab["multiplier_real"][0]) == [-1.02, 1.01] and list(tab["multiplier_imag"][0]) == [0.003, 0.0]
    assert list(tab["direction"][0]) == [-1, 1] and list(tab["period_ratio"][0]) == [2, 1]
    back = bifurcations_from_arrays({k: v for k, (v, _) in tab.items()})
    for a, b in zip(bifs, back):
        assert (b.kind, b.omega, b.le_amplitude, b.index, b.fraction, b.omega_bracket, b.multiplier, b.direction,
                b.period_ratio, b.kind_from) == (a.kind, a.omega, a.le_amplitude, a.index, a.fraction,
                                                 a.omega_bracket, a.multiplier, a.direction, a.period_ratio,
                                                 a.kind_from)
    # a table written before kind_from existed: paired False -> guess, no column -> crossing
    old = {k: v for k, (v, _) in tab.items() if k != "kind_from"}
    assert [b.kind_from for b in bifurcations_from_arrays(dict(old, paired=np.array([True, False])))] == [CROSSING,
                                                                                                          GUESS]
    assert [b.kind_from for b in bifurcations_from_arrays(old)] == [CROSSING, CROSSING]


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_the_parity_of_a_multiplier_sitting_on_minus_one_off_the_axis_is_unknown(sign):
    """A lone near-real multiplier -1.01 +- 0.05 i: 1 + mu = -0.01 +- 0.05 i has argument
    +-(pi / 2 + 0.197), within pi / 4 of +-pi / 2: whether it lies beyond -1 is not known (None),
    on either side of the axis. Moved off -1 by more (-1.3 +- 0.05 i: argument +-(pi - 0.165)),
    it is one real multiplier beyond -1: n 1, minus parity 1, plus parity 0
    (1 - mu = 2.3 -+ 0.05 i)."""
    assert real_parities(np.array([-1.01 + sign * 0.05j]), np.array([True]), 1.0) is None
    assert real_parities(np.array([-1.3 + sign * 0.05j]), np.array([True]), 1.0) == (1, 1, 0)
