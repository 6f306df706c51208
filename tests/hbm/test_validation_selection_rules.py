"""Choice of validation points (hbm.stability.selection) with hand-derived expectations.
The Floquet analyses are replaced by spectra whose largest multiplier
is given per point, so that each rule of choose_point / stable_stretch / _candidates is
checked on its own against the outcome computed by hand."""
import math
from types import SimpleNamespace

import numpy as np
import pytest

from hbm.harmonic.fourier import FourierBasis
from hbm.stability import convergence, selection
from hbm.stability.selection import _candidates, choose_point, new_content, stable_stretch


def test_candidates_crowd_the_peak_down_to_half_of_it():
    """Amplitudes 1 - 0.99 i / 39 decreasing along 40 points: R = 20 points at >= half the
    peak; n = 4 ranks (i / 4)^2 R = 0, 1.25, 5, 11.25 -> 0, 1, 5, 11; rank 1 is point 1, next
    to point 0 already taken: point 2 instead."""
    amp = 1.0 - 0.99 * np.arange(40) / 39
    order = np.argsort(-amp, kind="stable")
    assert _candidates(order, amp, 4) == [0, 2, 5, 11]


def spectra(mu):
    """orbit_spectrum stand-in: point i's largest multiplier is mu[i] (nan: no verdict)."""
    def orbit_spectrum(residual, u, omega):
        i = int(u[0])
        m = mu[i]
        ok = not math.isnan(m)
        return SimpleNamespace(decided=ok, largest_modulus=m if ok else math.nan, stable=ok and m < 1.0,
                               n_unstable=(int(m > 1.0) if ok else -1), note="" if ok else "no verdict"), None
    return orbit_spectrum


def branch(amp):
    m = len(amp)
    return np.linspace(1000.0, 1100.0, m), np.arange(m, dtype=float)[:, None], np.asarray(amp, float), np.ones(m, bool)


def test_a_multiplier_within_the_margin_of_the_circle_is_not_a_stable_choice(monkeypatch):
    """Amplitudes 3, 2, 1.9, 1, 0.5: R = 3 points at >= half the peak, 3 candidates at ranks
    0, 0, 1 -> points 0, 2, 4 (neighbours of those taken skipped), analysed in that order:
    |mu| = 0.9995 at 0 (log -5e-4: within the 1e-3 margin, no clear verdict), 0.995 at 2
    (log -5e-3: clearly stable): point 2, not 0 nor 4 (0.5)."""
    omega, x, amp, conv = branch([3.0, 2.0, 1.9, 1.0, 0.5])
    monkeypatch.setattr(selection, "orbit_spectrum", spectra([0.9995, 1.2, 0.995, 0.5, 0.5]))
    c = choose_point(None, omega, x, amp, conv, n_candidates=3)
    assert c.found and c.stable and c.index == 2 and c.multiplier == pytest.approx(0.995)


def test_without_a_stable_candidate_the_least_unstable_is_chosen(monkeypatch):
    """All unstable: the least unstable of the candidates analysed."""
    omega, x, amp, conv = branch([3.0, 2.5, 2.0, 1.8, 1.6, 1.5])
    mu = [1.5, 1.1, 1.3, 1.05, 1.4, 2.0]
    monkeypatch.setattr(selection, "orbit_spectrum", spectra(mu))
    c = choose_point(None, omega, x, amp, conv, n_candidates=4)
    # R = 6; ranks 0, 0, 2, 3 -> candidates 0, 2, 4 (the fourth finds only neighbours of those):
    # |mu| 1.5, 1.3, 1.4 -> point 2 (points 1 and 3, less unstable, are not candidates)
    assert not c.stable and c.index == 2 and c.multiplier == pytest.approx(1.3) and c.n_analyses == 3
    assert c.n_unstable == 1


def test_stored_verdicts_are_tried_in_turn_until_one_is_confirmed(monkeypatch):
    """The file calls points 1 and 3 stable; the analysis denies point 1 (|mu| 1.02) and
    confirms point 3 (0.9): point 3, chosen from the stored verdicts (the candidates near
    the peak, 0, 2, 4, would give point 4)."""
    omega, x, amp, conv = branch([3.0, 2.5, 2.0, 1.8, 1.6, 1.5])
    monkeypatch.setattr(selection, "orbit_spectrum", spectra([1.5, 1.02, 1.3, 0.9, 0.8, 0.8]))
    stored = np.array([False, True, False, True, False, False])
    c = choose_point(None, omega, x, amp, conv, stored)
    assert c.index == 3 and c.stable and "confirmed" in c.reason


@pytest.mark.parametrize("index, want", [(2, (0, 3)), (6, (5, 8))])
def test_a_stored_stable_run_reaches_the_ends_of_the_converged_stretch(index, want):
    """Converged points 0..3 and 5..8 (4 did not converge), all called stable: the run around
    a point is its whole converged stretch, both ends included, and does not cross point 4."""
    conv = np.array([1, 1, 1, 1, 0, 1, 1, 1, 1], bool)
    stored = np.ones(9, bool)
    assert stable_stretch(None, np.zeros(9), np.zeros((9, 1)), conv, index, stored) == want


@pytest.mark.parametrize("row, period_ratio, want", [(2, 1, 0.8), (2, 3, 0.8), (2, 2, 0.8), (3, 1, 0.0),
                                                     (3, 2, 0.0), (3, 4, 0.8)])
def test_new_content_is_the_share_of_the_harmonics_the_old_orbit_lacks(row, period_ratio, want):
    """Coefficients [c0, a1, b1, a2, b2, a3, b3] with c0 = 3 and 4 in one row (b1: order 1, or
    a2: order 2): the share (2-norm) of the new frequencies is 4 / 5 when that row is new,
    0 when not. An odd period ratio doubles into the basis of Omega / 2: the odd harmonics are
    new; an even one g keeps the basis: the harmonics that are not multiples of g are new
    (order 2 for g = 4, not for g = 2)."""
    xr = np.zeros((7, 1))
    xr[0, 0], xr[row, 0] = 3.0, 4.0
    res = SimpleNamespace(basis=FourierBasis(3, 8), to_coefficients=lambda u: xr)
    assert new_content(res, np.zeros(1), period_ratio) == pytest.approx(want, rel=1e-12, abs=1e-15)


class _Residual:
    """The parts of a HarmonicBalanceResidual check_harmonics uses: coefficients (n_c, n_r)
    flattened as the unknowns."""

    def __init__(self, nh, n_r, method):
        self.basis, self.n_r, self.method = FourierBasis(nh, 4 * nh + 2), n_r, method
        self.n_c = 2 * nh + 1
        self.options = SimpleNamespace(tolerance=1e-8)

    def to_coefficients(self, u):
        return np.asarray(u).reshape(self.n_c, self.n_r)

    def to_unknowns(self, x):
        return np.asarray(x).reshape(-1)

    def refined(self, factor):
        return _Residual(factor * self.basis.n_harmonics, self.n_r, self.method)


@pytest.mark.parametrize("method", ["dlft", "rl"])
def test_only_the_regularised_law_s_stable_points_are_judged_again_with_more_harmonics(method, monkeypatch):
    """The finer solution (N_h 2 -> 4) moves the first harmonics by 10 % (relative 2-norm, by
    construction) and Hill's method calls it unstable (|mu| 1.3): an RL point called stable
    fails the check; a DLFT one passes on existing alone (its verdict is not re-checked,
    hbm.stability.convergence.check_harmonics), with no analysis made."""
    import hbm.harmonic.start as start

    res = _Residual(2, 3, method)
    rng = np.random.default_rng(5)
    xr = rng.standard_normal((5, 3))
    d = rng.standard_normal((5, 3))
    d *= 0.1 * np.linalg.norm(xr) / np.linalg.norm(d)
    fine_x = np.zeros((9, 3))
    fine_x[:5] = xr + d
    fine_x[5:] = 0.01
    monkeypatch.setattr(start, "damped_newton",
                        lambda fine, x0, omega, *a, **k: SimpleNamespace(converged=True, x=fine_x.reshape(-1), reason=""))
    calls = []

    def unstable(residual, u, omega):
        calls.append(omega)
        return SimpleNamespace(decided=True, stable=False, multipliers=np.array([1.3, 0.5]), note=""), None

    monkeypatch.setattr(convergence, "orbit_spectrum", unstable)
    chk = convergence.check_harmonics(res, xr.reshape(-1), 1200.0, stable=True)
    assert chk.n_harmonics == 4 and chk.moved == pytest.approx(0.1, rel=1e-12)
    if method == "rl":
        assert not chk.passed and chk.multiplier == pytest.approx(1.3) and calls == [1200.0]
    else:
        assert chk.passed and math.isnan(chk.multiplier) and calls == []


def test_the_isola_point_falls_back_on_the_isolas_of_the_doubled_search():
    """Branches of isolas.h5 by kind and basis (Omega / nu), in two groups: the scene's
    isolas, then its detached branches; then the closed isolas of the period-doubled search
    (basis Omega / 2 nu), never its branches born at doublings nor those of another basis,
    nor a branch none of whose points holds with 2 N_h."""
    from pipelines.stages.validation import isola_branches

    def br(name, kind, nu, verdict="converged"):
        return SimpleNamespace(name=name, kind=kind, subharmonic=nu, harmonic_verdict=verdict)

    doubled = [br("d0", "bifurcated", 2), br("d1", "isola", 2), br("d2", "detached", 2), br("d3", "isola", 2),
               br("q0", "isola", 4)]
    own = [br("a0", "bifurcated", 1), br("a1", "detached", 1), br("a2", "isola", 1), br("a3", "primary", 1)]
    names = lambda bs: [b.name for b in bs]  # noqa: E731
    groups = lambda bs, nu: [names(g) for g in isola_branches(bs, nu)]  # noqa: E731
    assert groups(own + doubled, 1) == [["a2", "a1"], ["d1", "d3"]]
    assert groups(own[:1] + own[3:] + doubled, 1) == [[], ["d1", "d3"]]
    assert groups(own[:1] + doubled[:1], 1) == [[], []]
    # a scene of basis Omega / 2: its own isolas are the nu = 2 ones, its doubled search's nu = 4
    assert groups(doubled, 2) == [["d1", "d3", "d2"], ["q0"]]
    assert groups(doubled[:1] + doubled[4:], 2) == [[], ["q0"]]
    # the truncation's artefacts are left out (and named on request); partly converged and
    # unchecked branches (files written before the checks) stay
    checked = [br("c0", "isola", 1, "not converged"), br("c1", "isola", 1, "partly converged"),
               br("c2", "detached", 1, "unchecked"), br("c3", "isola", 2, "not converged"), br("c4", "isola", 2)]
    assert groups(checked, 1) == [["c1", "c2"], ["c4"]]
    assert [names(g) for g in isola_branches(checked, 1, artefacts=True)] == [["c0"], ["c3"]]


def test_the_isola_point_is_never_taken_from_the_friction_lock():
    """A branch every point of which holds a node on the casing past mu_set (on both rotor 67
    scenes the 400-2000 rad/s 'detached' one) is no isola of the blade: isola_branches leaves
    it out of both groups, and out of the artefacts; below mu_set, or with no node held
    throughout, it stays."""
    from pipelines.stages.validation import isola_branches, locked_branch

    def br(name, kind, nu, held=()):
        return SimpleNamespace(name=name, kind=kind, subharmonic=nu, harmonic_verdict="converged",
                               locked_nodes=np.asarray(held, dtype=int))

    rom = SimpleNamespace(friction_lock=SimpleNamespace(mu_set=0.123))
    bs = [br("a1", "detached", 1, (6, 7, 8)), br("a2", "isola", 1), br("d1", "isola", 2, (7,)), br("d3", "isola", 2)]
    names = lambda g: [b.name for b in g]  # noqa: E731
    for mu, expected in ((0.15, [["a2"], ["d3"]]), (0.1, [["a2", "a1"], ["d1", "d3"]])):
        got = isola_branches(bs, 1, locked=lambda b, mu=mu: locked_branch(b, mu, rom))
        assert [names(g) for g in got] == expected
    assert not locked_branch(bs[0], 0.15, SimpleNamespace())  # a ROM without the check: no lock known
    assert [names(g) for g in isola_branches(bs, 1, artefacts=True, locked=lambda b: True)] == [[], []]


def test_the_doubled_search_s_isolas_are_tried_when_time_integration_keeps_none_of_the_others():
    """first_kept: the groups are tried in turn until time integration stays on a point; the
    one kept, else the first found (the scene's basis' own isola point, time integration
    leaving it), else the first; the reason names every other try."""
    from pipelines.stages.validation import ValidationPoint, first_kept

    def point(branch, found=True, stays=None):
        ti = None if stays is None else SimpleNamespace(stays=stays)
        return ValidationPoint("isola", "rl", found, f"chosen on {branch}", branch, ti=ti)

    def run(outcomes):
        calls = []

        def try_group(group):
            calls.append(group)
            return outcomes[group]
        return first_kept(["own", "doubled"], try_group), calls

    own_left, doubled_kept = point("rl/004", stays=False), point("rl/011", stays=True)
    p, calls = run({"own": own_left, "doubled": doubled_kept})
    assert calls == ["own", "doubled"] and p.branch == "rl/011" and p.ti.stays
    assert p.reason == "chosen on rl/011; also tried, rl/004: chosen on rl/004"
    # kept at once: the doubled search's isolas are not tried
    p, calls = run({"own": point("rl/004", stays=True), "doubled": doubled_kept})
    assert calls == ["own"] and p.branch == "rl/004" and p.reason == "chosen on rl/004"
    # time integration keeps neither: the scene's basis' point, the other try in its reason
    p, _ = run({"own": own_left, "doubled": point("rl/011", stays=False)})
    assert p.branch == "rl/004" and p.reason.endswith("also tried, rl/011: chosen on rl/011")
    # the scene's isolas give no point: the doubled one, even where time integration leaves it
    none = ValidationPoint("isola", "rl", False, "no stable point left")
    p, _ = run({"own": none, "doubled": point("rl/011", stays=False)})
    assert p.branch == "rl/011" and p.found and p.reason.endswith("also tried, no branch: no stable point left")
