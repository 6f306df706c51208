"""A branch without the residual's symmetry that bifurcates from a symmetric branch at two
pitchforks, and crosses it where the symmetric branch's polyline cuts a bend: the search must
see both crossings (hbm.isolas.search._symmetric_crossing), not close the loop as an isola.
The solution sets are known in closed form."""
from __future__ import annotations

import re

import numpy as np
import pytest

from hbm.continuation.arclength import ContinuationOptions
from hbm.continuation.newton import NewtonOptions
from hbm.isolas.membership import KnownBranch
from hbm.isolas.search import SearchOptions, Seed, search
from hbm.linalg.dense import DirectSolver

C = 1.0  # curvature of the symmetric branch x1 = C (w - 1/2)^2
A, B = 0.1, 0.23  # the loop's half axes in x2 and Omega: pitchforks at Omega = 1/2 -+ B
X_SCALE, OMEGA_SCALE = 0.05, 0.01  # the branches run mostly along Omega in the scaled metric


class PitchforkLoop:
    """R = (x1 - C (w - 1/2)^2, x2 g) with g = x2^2 / A^2 + (w - 1/2)^2 / B^2 - 1, unchanged under
    x -> (x1, -x2) (`images`). Solutions: the symmetric branch x2 = 0 at every Omega, and the
    ellipse g = 0 (same x1), which passes through it at Omega = 1/2 -+ B. Picklable."""

    def g(self, x2, w):
        return x2 * x2 / A**2 + (w - 0.5) ** 2 / B**2 - 1.0, 2.0 * x2 / A**2, 2.0 * (w - 0.5) / B**2

    def __call__(self, x, w, jacobian=True):
        g, g_x, g_w = self.g(x[1], w)
        R = np.array([x[0] - C * (w - 0.5) ** 2, x[1] * g])
        if not jacobian:
            return R
        J = np.array([[1.0, 0.0], [0.0, g + x[1] * g_x]])
        return R, J, np.array([-2.0 * C * (w - 0.5), x[1] * g_w])

    def images(self, x):
        return [np.array([x[0], -x[1]])]


class DetachedLoops(PitchforkLoop):
    """The same symmetric branch, and two mirror-image loops with x2^2 between 0.5 A^2 and
    1.5 A^2: g = (x2^2 - A^2)^2 / (A^2 / 2)^2 + (w - 1/2)^2 / B^2 - 1 never lets x2 reach 0."""

    def g(self, x2, w):
        s = x2 * x2 - A**2
        h2 = (A**2 / 2) ** 2
        return s * s / h2 + (w - 0.5) ** 2 / B**2 - 1.0, 4.0 * s * x2 / h2, 2.0 * (w - 0.5) / B**2


def pitchfork_loop():
    return PitchforkLoop(), DirectSolver()


def detached_loops():
    return DetachedLoops(), DirectSolver()


def _options():
    co = ContinuationOptions(omega_min=0.0, omega_max=1.0, ds=0.5, ds_min=1e-5, ds_max=1.0, x_scale=X_SCALE,
                             omega_scale=OMEGA_SCALE, max_points=400, closed_loop_tol=1e-3,
                             newton=NewtonOptions(tol_residual=1e-12, max_iter=12))
    return SearchOptions(tolerance=1e-2, continuation=co, workers=1,
                         newton=NewtonOptions(tol_residual=1e-12, max_iter=30, line_search=True))


def _symmetric_branch():
    """The symmetric branch as an NFRC would store it: a point every 0.1 in Omega. Between two
    points its polyline lies up to C 0.1^2 / 4 / X_SCALE = 0.05 (five tolerances) off the curve
    in x1; at the pitchfork Omega = 0.27, 0.042."""
    w = np.linspace(0.0, 1.0, 11)
    return KnownBranch.of(w, np.column_stack([C * (w - 0.5) ** 2, np.zeros_like(w)]), "primary")


def test_the_polyline_alone_misses_the_crossing():
    """What makes the case hard: the chord from the loop's points to the symmetric branch's
    polyline is farther than the tolerance at the pitchfork."""
    from hbm.isolas.membership import polyline_distance

    w = 0.5 - B
    d = polyline_distance(np.array([C * (w - 0.5) ** 2, 0.0]), w, _symmetric_branch(), X_SCALE, OMEGA_SCALE)[0]
    # the offset in x1, C 0.07 0.03 / X_SCALE, seen across a segment 10 long in Omega, 1 in x1
    assert d == pytest.approx(C * 0.07 * 0.03 / X_SCALE * 10 / np.hypot(10, 1.0), rel=1e-9)
    assert d > 4 * _options().tolerance


@pytest.mark.parametrize("ds_max, workers", [(1.0, 1), (1.0, 2), (0.1, 1)])
def test_a_loop_through_two_pitchforks_is_bifurcated_and_meets_the_primary_at_both(ds_max, workers):
    """Seeded at the loop's top (Omega = 1/2, x2 = A). With long steps each half stepped onto
    the symmetric branch at a pitchfork and ran along it until it came near a vertex of its
    polyline: the loop was called part of the primary, stretches of the primary included; with
    short ones it went on through the pitchforks onto its own mirror image, an isola. Each
    half now ends one step past a pitchfork, at Omega = 1/2 -+ B."""
    from dataclasses import replace

    opts = _options()
    opts = replace(opts, workers=workers, continuation=replace(opts.continuation, ds=min(0.5, ds_max), ds_max=ds_max))
    res = search(pitchfork_loop, [Seed(0.5, np.array([0.0, A * 1.02]), "top")], [_symmetric_branch()], opts)
    (b,) = res.branches
    assert b.kind == "bifurcated" and not b.closed, b.status
    assert np.asarray(b.converged, bool).all()
    w, x = b.omega, b.x
    np.testing.assert_allclose(x[:, 0], C * (w - 0.5) ** 2, atol=1e-10)  # on both branches
    # every point on the ellipse on the side x2 > 0, but each half's last one, past a pitchfork:
    # on the ellipse's other side or on the symmetric branch (here it stepped onto that one)
    np.testing.assert_allclose((x[1:-1, 1] / A) ** 2 + ((w[1:-1] - 0.5) / B) ** 2, 1.0, atol=1e-8)
    assert (x[1:-1, 1] > 0).all() and (x[[0, -1], 1] <= 1e-9).all()
    met = [float(v) for v in re.findall(r"at a symmetric solution, ([0-9.eE+-]+) rad/s", b.status)]
    assert len(met) == 2, b.status
    np.testing.assert_allclose(sorted(met), [0.5 - B, 0.5 + B], atol=0.01)  # within the last step
    assert b.status.count("met known branch 0 (primary)") == 2


def test_loops_that_never_reach_the_symmetric_branch_stay_a_closed_isola():
    """The same search on loops that keep x2 >= 0.7 A: nothing turns over, one closed isola
    (its mirror image is the same branch)."""
    res = search(detached_loops, [Seed(0.5, np.array([0.0, A * 1.2]), "top")], [_symmetric_branch()], _options())
    (b,) = res.branches
    assert b.kind == "isola" and b.closed, b.status
    assert "symmetric" not in b.status


RHO, KAPPA = 0.02, 175.0  # the helix's radius (m-like units of x) and turn rate, rad per unit Omega


class TurningPart:
    """R = (x1 - C (w - 1/2)^2, -x2 s + x3 c, (x2 c + x3 s) ((x2^2 + x3^2) / RHO^2 - 1)) with
    c, s = cos, sin(KAPPA w), unchanged under x -> (x1, -x2, -x3). Solutions: the symmetric
    branch x2 = x3 = 0, and the helix (x2, x3) = +-RHO (c, s): its part without the symmetry
    keeps its size and turns, by ~100 degrees over a step of 0.01 in Omega. Picklable."""

    def __call__(self, x, w, jacobian=True):
        c, s = np.cos(KAPPA * w), np.sin(KAPPA * w)
        u, v = x[1] * c + x[2] * s, -x[1] * s + x[2] * c
        q = (x[1] ** 2 + x[2] ** 2) / RHO**2 - 1.0
        R = np.array([x[0] - C * (w - 0.5) ** 2, v, u * q])
        if not jacobian:
            return R
        J = np.array([[1.0, 0.0, 0.0], [0.0, -s, c],
                      [0.0, c * q + 2 * u * x[1] / RHO**2, s * q + 2 * u * x[2] / RHO**2]])
        return R, J, np.array([-2.0 * C * (w - 0.5), -KAPPA * u, KAPPA * v * q])

    def images(self, x):
        return [np.array([x[0], -x[1], -x[2]])]


def turning_part():
    return TurningPart(), DirectSolver()


def test_a_part_that_turns_without_shrinking_is_no_crossing(monkeypatch):
    """Over a step the helix's part without the symmetry turns by more than 90 degrees, so it
    'turns over' between two points, but its chord keeps cos(phi / 2) of its size: no crossing.
    Without that check (the fraction set to infinity) the symmetric projection's Newton lands on
    the symmetric branch and the helix was said to meet it."""
    from dataclasses import replace

    import hbm.isolas.search as search_module

    opts = _options()
    opts = replace(opts, continuation=replace(opts.continuation, ds=1.0, ds_max=1.0, x_scale=1.0))
    w0 = 0.5
    seed = [Seed(w0, np.array([0.0, RHO * np.cos(KAPPA * w0), RHO * np.sin(KAPPA * w0)]), "on the helix")]
    primary = KnownBranch.of(np.linspace(0.0, 1.0, 11), np.column_stack(
        [C * (np.linspace(0.0, 1.0, 11) - 0.5) ** 2, np.zeros(11), np.zeros(11)]), "primary")
    (b,) = search(turning_part, seed, [primary], opts).branches
    assert "symmetric" not in b.status and b.omega.min() == 0.0 and b.omega.max() == 1.0, b.status
    x = b.x[np.asarray(b.converged, bool)]
    np.testing.assert_allclose(np.hypot(x[:, 1], x[:, 2]), RHO, rtol=1e-8)  # every point on the helix
    turns = np.einsum("ij,ij->i", x[:-1, 1:], x[1:, 1:]) < 0
    assert turns.any()  # the part turned over between two points somewhere: the case is exercised
    monkeypatch.setattr(search_module, "_CROSSING_FRACTION", np.inf)
    (b,) = search(turning_part, seed, [primary], opts).branches
    assert "symmetric solution" in b.status, b.status


@pytest.mark.parametrize("nu, kept", [(1, [2]), (2, [4, 2])])
def test_symmetric_parts_of_a_two_lobe_residual_keep_the_harmonics_of_each_subgroup(nu, kept):
    """On the HBM residual of a 2-lobe casing the images are the orbit shifted by j / (2 nu)
    of the basis period; the projections keep exactly the harmonics k of the basis that those
    shifts leave unchanged: with nu = 1 the even ones (the symmetric orbits), with nu = 2 the
    multiples of 4 (symmetric) and the even ones (orbits of period T, which a period-doubled
    branch passes through where it is born)."""
    from hbm.harmonic.residual import build_residual
    from hbm.isolas.search import _symmetric_parts
    from hbm.options import CasingOptions, ContactOptions, HbmOptions
    from support import standin_rom

    res = build_residual(standin_rom(), CasingOptions(), ContactOptions(),
                         HbmOptions(n_harmonics=8, n_time=128, subharmonic=nu), method="dlft")
    u = np.random.default_rng(5).standard_normal(res.size)
    parts = _symmetric_parts(u, res.images(u))
    assert len(parts) == len(kept)
    order = np.concatenate([[0], np.repeat(np.arange(1, 9), 2)])  # harmonic of each coefficient row
    xr = res.to_coefficients(u)
    for part, m in zip(parts, kept):  # harmonics that are multiples of m
        expected = np.where((order % m == 0)[:, None], xr, 0.0)
        np.testing.assert_allclose(res.to_coefficients(part), expected, atol=1e-12 * np.abs(xr).max())


def test_a_branch_merging_into_the_primary_without_its_symmetry_is_bifurcated(monkeypatch):
    """Where the corrector lands exactly on a symmetric orbit past the pitchfork, the part
    without the symmetry is zero at that point, nothing 'turns over' and the crossing goes
    unseen (rotor 37's default DLFT search: a branch with up to 29 % of its energy outside
    the harmonics 3k left the primary near 491 rad/s and was stored as a piece of it). The
    crossing test switched off to make that happen here: the halves run onto the primary and
    merge into it, and the branch, whose orbits break the symmetry, is still bifurcated, not
    primary; with the rule's threshold out of reach it would be primary. The search's refusal
    of such landings (_keeps_off_symmetric_orbits) is switched off too: with it the halves go
    on through the pitchforks (onto the mirror image, here a closed loop), and only a landing
    at the step floor gets past it."""
    import hbm.isolas.search as search_module

    monkeypatch.setattr(search_module, "_symmetric_crossing", lambda *args: None)
    monkeypatch.setattr(search_module, "_keeps_off_symmetric_orbits", lambda residual: None)
    seed = [Seed(0.5, np.array([0.0, A * 1.02]), "top")]
    (b,) = search(pitchfork_loop, seed, [_symmetric_branch()], _options()).branches
    assert b.status.count("met known branch 0 (primary)") == 2 and "symmetric solution" not in b.status
    assert b.kind == "bifurcated" and search_module.LEAVES_SYMMETRY in b.status, b.status
    monkeypatch.setattr(search_module, "BROKEN_RTOL", np.inf)
    (b,) = search(pitchfork_loop, seed, [_symmetric_branch()], _options()).branches
    assert b.kind == "primary", b.status


GAP, TILT, LONG, SHORT = 0.1, 0.1, 20.0, 1.0  # scaled units: the tilted loops' gap, tilt (rad), half axes


def _tilted_ellipse(y, v):
    """E(y, v) of the ellipse of half axes LONG, SHORT tilted by TILT, in the scaled (v, y) =
    ((w - 1/2) / OMEGA_SCALE, x2 / X_SCALE) plane, whose lowest point is GAP above y = 0, two
    units of v from its end (its fold in Omega, 0.34 above y = 0): (E, dE/dy, dE/dv)."""
    yc = GAP + np.hypot(LONG * np.sin(TILT), SHORT * np.cos(TILT))
    c, s = np.cos(TILT), np.sin(TILT)
    p, q = v * c + (y - yc) * s, -v * s + (y - yc) * c
    return (p / LONG) ** 2 + (q / SHORT) ** 2 - 1.0, 2 * (p * s / LONG**2 + q * c / SHORT**2), \
        2 * (p * c / LONG**2 - q * s / SHORT**2)


class TiltedLoops(PitchforkLoop):
    """The same symmetric branch, and a long thin loop tilted so that its lowest point, GAP =
    0.1 scaled units (0.005 in x2) above the symmetric branch, lies next to its end, where it
    folds in Omega (at Omega ~ 0.3), with its mirror image: g = E(x2) E(-x2), never zero at
    x2 = 0."""

    def g(self, x2, w):
        y, v = x2 / X_SCALE, (w - 0.5) / OMEGA_SCALE
        (e1, e1y, e1v), (e2, e2y, e2v) = _tilted_ellipse(y, v), _tilted_ellipse(-y, v)
        return e1 * e2, (e1y * e2 - e1 * e2y) / X_SCALE, (e1v * e2 + e1 * e2v) / OMEGA_SCALE


def tilted_loops():
    return TiltedLoops(), DirectSolver()


def test_a_loop_folding_next_to_the_symmetric_branch_stays_a_closed_isola(monkeypatch):
    """Rotor 37's default DLFT search had a broken branch fold 3.3 % of the orbit short of the
    primary: its corrector, steps longer than the gap, landed on the primary's symmetric orbits
    and the branch was stored as leaving it. Here the loop comes within a tenth of the longest
    step (ds_max = 1) of the symmetric branch next to its fold: the search refuses the landing
    (the step halves) and closes the loop, its points all GAP or more off the symmetric
    branch. Without the refusal it lands and the loop is taken for a branch leaving the
    primary."""
    import hbm.isolas.search as search_module

    yc = GAP + np.hypot(LONG * np.sin(TILT), SHORT * np.cos(TILT))
    seed = [Seed(0.5, np.array([0.0, (yc + 0.9 * SHORT) * X_SCALE]), "top")]
    (b,) = search(tilted_loops, seed, [_symmetric_branch()], _options()).branches
    assert b.kind == "isola" and b.closed, b.status
    x2 = b.x[np.asarray(b.converged, bool), 1]
    assert x2.min() > 0.99 * GAP * X_SCALE and x2.min() < 1.1 * GAP * X_SCALE  # round its lowest point
    reach = OMEGA_SCALE * np.hypot(LONG * np.cos(TILT), SHORT * np.sin(TILT))  # the folds' distance from 1/2
    np.testing.assert_allclose([b.omega.min(), b.omega.max()], [0.5 - reach, 0.5 + reach], atol=2e-3)
    monkeypatch.setattr(search_module, "_keeps_off_symmetric_orbits", lambda residual: None)
    (b,) = search(tilted_loops, seed, [_symmetric_branch()], _options()).branches
    assert b.kind == "bifurcated" and not b.closed and search_module.LEAVES_SYMMETRY in b.status, b.status


@pytest.mark.parametrize("before, after, refused", [(2e-4, 5e-5, False), (2e-4, 1e-6, True), (0.3, 1e-3, False),
                                                     (0.3, 9e-5, True), (5e-5, 0.0, False)])
def test_a_landing_is_refused_only_from_a_broken_point_onto_a_hundred_times_smaller_part(before, after, refused):
    """On the pitchfork loop the non-symmetric part of (x1, x2) is |x2| / |x| (the mean with the
    mirror image is (x1, 0)). A correction is refused only when the last point's part is over
    1e-4 and the new one's is at most 1e-4 and a hundredth of it: a point running into a
    pitchfork may step from 2e-4 to 5e-5 (a fourfold fall: the square root of a sixteenfold
    one in distance)."""
    from types import SimpleNamespace

    from hbm.isolas.search import _keeps_off_symmetric_orbits

    def point(part):  # |x2| / |x| = part with x1 = 1
        return np.array([1.0, part / np.sqrt(1.0 - part * part)])

    admit = _keeps_off_symmetric_orbits(PitchforkLoop())
    why = admit(SimpleNamespace(x=point(before), omega=0.4), point(after), 0.41)
    assert (why is not None) == refused, why
    if refused:
        assert "landed on an orbit with the symmetry" in why


def test_the_asymmetry_of_an_orbit_is_its_part_outside_the_symmetric_harmonics():
    """On the HBM residual of a 2-lobe casing: an orbit with only even harmonics of Omega has
    none; adding odd harmonics of relative size e gives e / sqrt(1 + e^2)."""
    from hbm.harmonic.residual import build_residual
    from hbm.isolas.search import asymmetry
    from hbm.options import CasingOptions, ContactOptions, HbmOptions
    from support import standin_rom

    res = build_residual(standin_rom(), CasingOptions(), ContactOptions(), HbmOptions(n_harmonics=8, n_time=128),
                         method="dlft")
    rng = np.random.default_rng(6)
    order = np.concatenate([[0], np.repeat(np.arange(1, 9), 2)])
    even = np.where((order % 2 == 0)[:, None], rng.standard_normal((17, res.n_r)), 0.0)
    odd = np.where((order % 2 == 1)[:, None], rng.standard_normal((17, res.n_r)), 0.0)
    odd *= 0.3 * np.linalg.norm(even) / np.linalg.norm(odd)
    assert asymmetry(res, res.to_unknowns(even)[None]) < 1e-14
    both = np.stack([res.to_unknowns(even), res.to_unknowns(even + odd)])
    assert asymmetry(res, both) == pytest.approx(0.3 / np.hypot(1.0, 0.3), rel=1e-12)
