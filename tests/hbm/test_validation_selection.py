"""The validation points chosen automatically (hbm.stability.selection) and time integration
from them (hbm.ti.validation), checked against independent references:

- rotor 67 coarse ROM, DLFT-HBM at N_h = 40 over [1960, 2000] rad/s (the 2B x 4 Omega
  resonance bent over, hbm/test_stability_rotor67.py): the point chosen near the peak is
  stable, and time integration (exact Lagrange-multiplier contact, another code) marched 100
  periods from it stays on it and agrees with it; the RL orbit found by Newton from it too;
- the forced RL-obstacle oscillator of hbm/test_period_doubling.py (a period doubling near
  W = 4.27, confirmed there by shooting): the period doubling is located without stored
  stability, the doubled branch carries the harmonics of W / 2, and time integration
  (scipy's solve_ivp) from the chosen point stays on it; on its branch stored without
  stability, the stability the validation stage computes along it gives shooting's verdict
  at every point, and the period doubling a scan misses.
"""
import re
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from hbm.continuation.arclength import ContinuationOptions, continue_branch
from hbm.continuation.newton import NewtonOptions, newton_solve
from hbm.harmonic.nfrc import compute_nfrc, nfrc_extras
from hbm.harmonic.residual import build_residual
from hbm.harmonic.solver import HbmSolver
from hbm.harmonic.start import damped_newton
from hbm.options import CasingOptions, ContactOptions, HbmOptions
from hbm.stability.bifurcation import PERIOD_DOUBLING
from hbm.stability.selection import LocatedDoubling, choose_point, continue_doubled_branch, locate_period_doubling
from hbm.ti.validation import DEVIATION_TOL, GROWTH_TOL, compare_with_hbm, march_from_hbm
from support import coarse_rom
from test_period_doubling import NOPT, _rhs, low_harmonic_branch, obstacle_residual, ti_distance


def test_rotor67_primary_point_is_stable_and_time_integration_stays_and_agrees():
    rom = coarse_rom()
    casing, contact = CasingOptions(), ContactOptions()
    opts = HbmOptions(n_harmonics=40, n_time=1024, omega_min=1960.0, omega_max=2000.0)
    r = compute_nfrc(rom, casing, contact, opts, "dlft", stability=False)
    res = build_residual(rom, casing, contact, opts, method="dlft")
    ch = choose_point(res, r.omega, r.unknowns, r.le_amplitude, r.converged)
    # the peak (1962 rad/s) is on the unstable sheet of the bent resonance; the chosen point
    # is the first stable candidate below it (1970 rad/s, |mu| = 0.9965 measured)
    assert ch.found and ch.stable and ch.verdict == "analysed" and ch.multiplier < 1.0
    assert ch.le_amplitude > 0.5 * r.le_amplitude.max() and ch.n_analyses <= 8
    ti = march_from_hbm(rom, casing, contact.mu, res.expand_harmonics(ch.u, ch.omega), ch.omega, n_periods=100,
                        dt=4e-7)
    # stays on its orbit: the distance to it over the last 10 periods at most GROWTH_TOL (1.5)
    # times that over the first 10 and below DEVIATION_TOL (0.6) of the amplitude (measured:
    # growth 0.98, deviation 0.06 LE and 0.14 TE)
    assert ti.stays and ti.growth <= GROWTH_TOL and ti.last_deviation <= DEVIATION_TOL
    assert ti.max_penetration < 1e-12
    own = compare_with_hbm(ti, res.expand_harmonics(ch.u, ch.omega), res.signals(ch.u, ch.omega)["lam"], "self")
    # measured, relative to the half peak-to-peak: displacement 5.3 % LE, 11.2 % TE (DLFT's
    # Gibbs ripple at the impacts); force after projection on N_h harmonics 2.6 % LE, 5.3 % TE
    assert np.all(own.displacement_error < [0.06, 0.16]), own.displacement_error
    assert np.all(own.force_error < [0.06, 0.08]), own.force_error
    # the RL orbit at the same Omega, by damped Newton from the DLFT point (moved 5.6 %):
    # displacement 12.5 % / 16.9 %, force 13.8 % / 17.4 % against the sigma-filtered force of
    # the RL-HBM equilibrium (37 % / 32 % against the raw penalty force)
    rl = build_residual(rom, casing, contact, opts, method="rl")
    sol = damped_newton(rl, ch.u, ch.omega, NewtonOptions(tol_residual=1e-8), HbmSolver(atol=1e-9))
    assert sol.converged, sol.reason
    other = compare_with_hbm(ti, rl.expand_harmonics(sol.x, ch.omega), rl.signals(sol.x, ch.omega)["lam"], "rl",
                             sigma=rl.sigma)
    assert np.all(other.displacement_error < [0.16, 0.24]), other.displacement_error
    assert np.all(other.force_error < [0.2, 0.24]), other.force_error


# -- period doubling: the forced RL obstacle oscillator of test_period_doubling ----------------


@pytest.fixture(scope="module")
def oscillator():
    res, sol = obstacle_residual()
    opts = ContinuationOptions(omega_min=3.4, omega_max=4.6, ds=0.005, ds_max=0.02, direction=-1, newton=NOPT,
                               closed_loop_tol=None, omega_scale=1.0)
    br = continue_branch(res, sol.x, 4.6, opts)
    amp = np.array([nfrc_extras(res, x)["le_amplitude"] for x in br.x])
    return res, br, amp, opts


def test_period_doubling_is_located_without_stored_stability(oscillator):
    res, br, amp, _ = oscillator
    loc = locate_period_doubling(res, br.omega, br.x, amp, br.converged, n_scan=12)
    pd = loc.bifurcation
    assert pd is not None and pd.kind == PERIOD_DOUBLING, loc.reason
    # between neighbouring points (ds_max = 0.02 apart at most), where hbm/test_period_doubling.py
    # finds it with the monitor along the whole branch and checks it against shooting (4.33)
    assert abs(np.diff(pd.omega_bracket)[0]) <= 0.02 + 1e-12 and 4.3 < pd.omega < 4.36
    assert pd.multiplier.real < -1.0
    assert loc.index in (pd.index, pd.index + 1) and loc.n_analyses < 30
    # from a table's bracket (as an NFRC file computed with stability gives it): the same one
    again = locate_period_doubling(res, br.omega, br.x, amp, br.converged, brackets=[pd.index])
    assert again.bifurcation is not None and abs(again.bifurcation.omega - pd.omega) < 1e-9
    # a bracket without a period doubling (a stretch of the stable branch) is reported
    none = locate_period_doubling(res, br.omega, br.x, amp, br.converged, brackets=[1])
    assert none.bifurcation is None and "period doubling" in none.reason


def test_a_search_out_of_analyses_says_how_far_it_got(oscillator):
    """The scan takes 12 analyses: a budget of 5 stops it, one of 13 stops the bisection after
    it, and each reason says how far it got instead of calling the branch free of period
    doublings; one converged point is no branch."""
    res, br, amp, _ = oscillator
    short = locate_period_doubling(res, br.omega, br.x, amp, br.converged, n_scan=12, max_analyses=5)
    assert short.bifurcation is None and short.n_analyses == 5
    assert short.reason == ("the scan of the branch needs more than the 5 Floquet analyses allowed; no stability "
                            "change examined"), short.reason
    # a budget that the scan fits in but the bisection does not: the changes examined are counted
    mid = locate_period_doubling(res, br.omega, br.x, amp, br.converged, n_scan=12, max_analyses=13)
    assert mid.bifurcation is None and mid.n_analyses == 13
    assert re.fullmatch(r"no period doubling among the 0 of \d+ stability change\(s\) examined within 13 Floquet "
                        r"analyses", mid.reason), mid.reason
    one = locate_period_doubling(res, br.omega[:1], br.x[:1], amp[:1], br.converged[:1])
    assert one.bifurcation is None and one.reason == "fewer than two converged points" and one.n_analyses == 0


@pytest.fixture(scope="module")
def doubled(oscillator):
    """(LocatedDoubling, DoubledBranch, its residual): the oscillator's period doubling and
    the branch switched to there, continued 30 points each way."""
    res, br, amp, opts = oscillator
    loc = locate_period_doubling(res, br.omega, br.x, amp, br.converged, n_scan=12)
    db, new = continue_doubled_branch(res, br.x[loc.index], br.omega[loc.index], loc.bifurcation, opts,
                                      n_points=30)
    return loc, db, new


def test_doubled_branch_has_half_frequency_content_and_time_integration_stays_on_it(doubled):
    _, db, new = doubled
    assert db.found and new.nu == 2 and db.subharmonic == 2, db.reason
    assert len(db.omega) > 30 and db.omega.min() < 4.2  # both ways, and down away from the bifurcation
    # content at W / 2 (odd harmonics of the new basis): none at the bifurcation, growing on the branch
    assert db.new_content[db.start] < 0.3 and db.new_content.max() > 0.2
    ch = choose_point(new, db.omega, db.x, db.le_amplitude, np.ones(len(db.omega), bool), db.stable,
                      eligible=db.new_content >= 0.05)
    assert ch.found and ch.stable and db.new_content[ch.index] >= 0.05, ch.reason
    # time integration from it: x(kT) alternates between the orbit's x(0) and x(T) for 200
    # periods T = 2 pi / W (N_h = 61 of W / 2: the orbit within ~1e-8 of the exact one)
    xr = new.to_coefficients(ch.u)[:, 0]
    k = np.arange(1, new.basis.n_harmonics + 1)
    wf, w = new.fundamental(ch.omega), ch.omega
    T = 2 * np.pi / w
    x_at = lambda t: xr[0] + np.sum(xr[1::2] * np.cos(k * wf * t) + xr[2::2] * np.sin(k * wf * t))
    v0 = np.sum(k * wf * xr[2::2])
    x = solve_ivp(_rhs, (0, 200 * T), [x_at(0.0), v0], args=(w,), t_eval=np.arange(201) * T, rtol=1e-10, atol=1e-12,
                  method="DOP853").y[0]
    assert abs(x_at(T) - x_at(0.0)) > 1e-3  # a period-doubled orbit: x(T) != x(0)
    assert np.abs(x[0::2] - x_at(0.0)).max() < 1e-6 and np.abs(x[1::2] - x_at(T)).max() < 1e-6


def _march_that_stays(marched: list):
    """A stand-in for the validation stage's _validate: records the chosen point's index in
    `marched` and says that time integration stays on it."""
    import pipelines.stages.validation as stage

    def fake_validate(ctx, rom, system, kind, method, ch, residual, where, dt=None):
        marched.append(ch.index)
        ti = SimpleNamespace(stays=True, outcome="stays", verdict=lambda: "stays")
        return stage.ValidationPoint(kind, method, True, ch.reason, where, ch.index, ch.omega,
                                     le_amplitude=ch.le_amplitude, stable=ch.stable, ti=ti)

    return fake_validate


def test_harmonic_check_of_a_doubled_orbit_gives_shootings_multiplier(doubled):
    """check_harmonics on the basis of W / 2: the chosen point of the doubled branch (N_h = 61
    of W / 2) exists with 122 harmonics, unmoved, and Hill's largest multiplier there is that
    of shooting over the orbit's period 2 T (scipy's variational equations, another method)."""
    from test_period_doubling import _rhs_var, _state

    from hbm.stability.convergence import check_harmonics

    _, db, new = doubled
    ch = choose_point(new, db.omega, db.x, db.le_amplitude, np.ones(len(db.omega), bool), db.stable,
                      eligible=db.new_content >= 0.05)
    check = check_harmonics(new, ch.u, ch.omega)
    assert check.passed and check.n_harmonics == 2 * new.basis.n_harmonics and check.moved < 1e-6, check.reason
    y = _state(new, ch.u, ch.omega)
    s = solve_ivp(_rhs_var, (0, 4 * np.pi / ch.omega), np.concatenate([y, np.eye(2).ravel()]), args=(ch.omega,),
                  rtol=1e-12, atol=1e-12, method="DOP853")
    assert np.linalg.norm(s.y[:2, -1] - y) < 1e-8  # the orbit closes after 2 T, not after T
    shoot = np.abs(np.linalg.eigvals(s.y[2:, -1].reshape(2, 2))).max()
    assert abs(check.multiplier - shoot) < 1e-5, (check.multiplier, shoot)


def test_a_doubled_point_that_fails_the_harmonic_check_is_not_marched(oscillator, doubled, tmp_path, monkeypatch):
    """_period_doubling of the validation stage, with the doubled branch's stable flags cut in
    two stretches, the check replaced by a rule (the first choice fails) and the march by one
    that keeps everything: the first choice is checked, not marched, and the march is from
    the other stretch, a point that carries W / 2 content."""
    import h5py

    import hbm.stability.selection as selection
    import pipelines.stages.validation as stage
    from hbm.options import ValidationOptions
    from hbm.stability import convergence
    from hbm.stability.convergence import HarmonicCheck

    res, br, amp, _ = oscillator
    _, db, new = doubled
    st = np.asarray(db.stable, bool).copy()
    st[8:11] = False  # two stretches: 0-7 and 11-
    cut = replace(db, stable=st)
    monkeypatch.setattr(selection, "continue_doubled_branch", lambda *a, **k: (cut, new))
    marched, checked = [], []

    def fake_check(residual, u, omega, **kw):
        checked.append(omega)
        return HarmonicCheck(len(checked) > 1, "rule", 122)

    monkeypatch.setattr(stage, "_validate", _march_that_stays(marched))
    monkeypatch.setattr(convergence, "check_harmonics", fake_check)
    nfrc = tmp_path / "nfrc_rl.h5"
    h5py.File(nfrc, "w").close()  # no stored stability: the doubling is located by a scan
    ctx = SimpleNamespace(out=tmp_path, scene=SimpleNamespace(
        validation=ValidationOptions(n_candidates=8, pd_tries=1), hbm=HbmOptions(omega_min=3.4, omega_max=4.6),
        contact=SimpleNamespace(mu=0.0)))
    p, pd_branch = stage._period_doubling(ctx, None, None, "rl", res, br, {"le_amplitude": amp}, nfrc,
                                          lambda text: None)
    assert np.array_equal(pd_branch.stable, st) and len(checked) == 2 and len(marched) == 1
    assert checked[0] in db.omega[:8] and checked[1] == db.omega[marched[0]]
    assert p.found and p.index == marched[0] >= 11 and db.new_content[p.index] >= 0.05
    assert "not marched: rule" in p.reason and "1 marched, 2 checked with 2 N_h" in p.reason


def test_a_crossing_far_past_minus_one_is_refined_on_the_branch(oscillator):
    """Stored points far apart (ds_max 0.2: the point past the period doubling has a
    multiplier well beyond -1, as RL's on rotor 67, mu = -2.8): the start of the switch is a
    branch point computed between them whose multiplier, by shooting (another method), is
    within REFINE_BEYOND of -1 in log|mu|, and the switch from it converges."""
    from test_period_doubling import _pd_multiplier, _state

    from hbm.stability.selection import REFINE_BEYOND

    res, _, _, opts = oscillator
    sol = newton_solve(res, res.linear_solution(4.6), 4.6, NOPT)
    coarse = continue_branch(res, sol.x, 4.6, replace(opts, ds_max=0.2, ds=0.1))
    amp = np.array([nfrc_extras(res, x)["le_amplitude"] for x in coarse.x])
    loc = locate_period_doubling(res, coarse.omega, coarse.x, amp, coarse.converged, n_scan=12)
    assert loc.bifurcation is not None and loc.bifurcation.kind == PERIOD_DOUBLING, loc.reason
    k = loc.index
    mu_stored = _pd_multiplier(_state(res, coarse.x[k], coarse.omega[k]), coarse.omega[k])
    assert np.log(abs(mu_stored)) > 2 * REFINE_BEYOND  # the case: the stored point is far past -1
    assert "refined" in loc.reason
    lo, hi = sorted(coarse.omega[[k - 1, k + 1]]) if 0 < k < len(coarse.omega) - 1 else (3.4, 4.6)
    assert lo <= loc.omega <= hi
    assert np.linalg.norm(res(loc.u, loc.omega, jacobian=False)) < 1e-8  # a point of the branch
    mu = _pd_multiplier(_state(res, loc.u, loc.omega), loc.omega)
    assert mu < -1.0 and np.log(abs(mu)) <= REFINE_BEYOND + 0.02, mu  # HBM's N_h = 30 vs shooting
    db, _ = continue_doubled_branch(res, loc.u, loc.omega, loc.bifurcation, opts, n_points=10)
    assert db.found, db.reason


# -- the stable stretch of a point, and the primary point tried again outside it ---------------
@pytest.fixture(scope="module")
def long_branch(oscillator):
    """The oscillator's branch continued down to W = 2: two stable stretches (above the period
    doubling near 4.33, and below ~2.36, where the amplitude is largest), unstable between."""
    res, br, _, opts = oscillator
    b = continue_branch(res, br.x[0], 4.6, replace(opts, omega_min=2.0, ds_max=0.03))
    amp = np.array([nfrc_extras(res, x)["le_amplitude"] for x in b.x])
    return res, b, amp


def _stable_flags(res, b):
    """(m,) bool: the long branch's two stable stretches (around the peak and point 2), as a
    branch file computed with stability would store them."""
    from hbm.stability.selection import stable_stretch

    st = np.zeros(len(b.omega), bool)
    for i in (len(b.omega) - 1, 2):
        lo, hi = stable_stretch(res, b.omega, b.x, b.converged, i)
        st[lo: hi + 1] = True
    return st


def test_stable_stretch_ends_where_shooting_sees_stability_change(long_branch, monkeypatch):
    from test_period_doubling import _multipliers, _state

    import hbm.stability.selection as selection
    from hbm.stability.selection import stable_stretch

    res, b, amp = long_branch
    m = len(b.omega)
    calls = []
    spectrum = selection.orbit_spectrum
    monkeypatch.setattr(selection, "orbit_spectrum", lambda *a, **k: calls.append(1) or spectrum(*a, **k))
    largest = lambda j: np.abs(_multipliers(_state(res, b.x[j], b.omega[j]), b.omega[j])).max()  # noqa: E731
    found = {}
    for i in (m - 1, 2):  # the peak (W = 2) and a point above the period doubling
        calls.clear()
        lo, hi = stable_stretch(res, b.omega, b.x, b.converged, i)
        assert lo <= i <= hi and hi - lo >= 5
        # the ends by shooting (another method): inside the unit circle at both ends of the
        # stretch, outside one point past each end that is not the branch's own end
        for j in (lo, hi):
            assert largest(j) < 1.0, (i, j)
        for j in (lo - 1, hi + 1):
            if 0 <= j < m:
                assert largest(j) > 1.0, (i, j)
        assert len(calls) < (hi - lo + 1)  # bisection, not every point
        found[i] = (lo, hi)
    assert found[m - 1][1] == m - 1 and found[2][0] == 0 and found[2][1] < found[m - 1][0]
    # an unstable point is its own stretch
    mid = (found[2][1] + found[m - 1][0]) // 2
    assert stable_stretch(res, b.omega, b.x, b.converged, mid) == (mid, mid)
    # stored verdicts are read, not recomputed
    calls.clear()
    st = np.zeros(m, bool)
    st[10:20] = True
    assert stable_stretch(res, b.omega, b.x, b.converged, 15, st) == (10, 19) and not calls
    conv = np.ones(m, bool)
    conv[17] = False  # an unconverged point ends the run
    assert stable_stretch(res, b.omega, b.x, conv, 12, st) == (10, 16)


def test_a_point_time_integration_leaves_is_tried_again_outside_its_stretch(long_branch, monkeypatch):
    """pipelines.stages.validation._try_until_kept (the primary and isola points), with the
    march replaced by a rule (time integration keeps the orbits above W = 3 only): the first
    try, the peak, is left; the second is the largest stored-stable amplitude outside the
    peak's stable stretch with a decisive verdict, and kept; with one try the first is kept;
    when every march leaves, the first is kept and the reason lists the tries; over two
    branches (the isola point's case) the second branch is tried once the first has no
    stable point left."""
    import pipelines.stages.validation as stage
    from hbm.options import ValidationOptions

    res, b, amp = long_branch
    m = len(b.omega)
    st = _stable_flags(res, b)
    marched = []

    def fake_validate(ctx, rom, system, kind, method, ch, residual, where, keep=lambda w: w > 3.0):
        marched.append((where, ch.index))
        stays = keep(ch.omega)
        ti = SimpleNamespace(stays=stays, outcome="leaves", verdict=lambda: "stays" if stays else "leaves")
        return stage.ValidationPoint(kind, method, True, ch.reason, where, ch.index, ch.omega,
                                     le_amplitude=ch.le_amplitude, stable=ch.stable, ti=ti)

    def run(tries, keep=lambda w: w > 3.0, branches=None, n_periods=100):
        marched.clear()
        monkeypatch.setattr(stage, "_validate", lambda *a: fake_validate(*a, keep=keep))
        ctx = SimpleNamespace(scene=SimpleNamespace(validation=ValidationOptions(n_candidates=8, n_periods=n_periods,
                                                                                    dt_refinement=1),
                                                    contact=SimpleNamespace(mu=0.0)))
        cands = [stage.Candidate(name, res, b.omega, b.x, amp, b.converged, flags)
                 for name, flags in (branches or [("nfrc_rl.h5", st)])]
        return stage._try_until_kept(ctx, None, None, "primary", "rl", cands, tries, lambda text: None)

    p = run(3)
    assert [i for _, i in marched][0] == m - 1 and len(marched) == 2  # the peak, then one outside its stretch
    assert st[p.index] and p.omega > 4.3 and p.ti.stays
    assert "2 marched" in p.reason and "2.0 rad/s (stable), time integration leaves" in p.reason
    # a retry asks for a decisive verdict: by shooting, the kept point's multipliers (0.965)
    # shrink a perturbation by e^3 over the 100 periods of the march; over a march of 50
    # periods no point of the upper stretch would (|mu| > e^-0.06 = 0.942 at every one), so
    # there is no retry
    from test_period_doubling import _multipliers, _state

    largest = lambda j: np.abs(_multipliers(_state(res, b.x[j], b.omega[j]), b.omega[j])).max()  # noqa: E731
    assert largest(p.index) < np.exp(-stage.DECISIVE_DECAY / 100)
    upper = np.flatnonzero(st[:20])
    assert all(largest(j) > np.exp(-stage.DECISIVE_DECAY / 50) for j in upper[::3])
    p = run(3, n_periods=50)
    assert len(marched) == 1 and p.index == m - 1 and "no stable point left" in p.reason
    p = run(1)
    assert marched == [("nfrc_rl.h5", m - 1)] and not p.ti.stays and "marched" not in p.reason
    p = run(3, keep=lambda w: False)
    assert len(marched) == 2 and p.index == m - 1 and "2 marched" in p.reason and "no stable point left" in p.reason
    # two branches: the first holds only the low stretch; once it is ruled out, the second's
    # upper stretch is tried
    low = st & (b.omega < 3.0)
    p = run(3, branches=[("isolas.h5 rl/branches/000", low), ("isolas.h5 rl/branches/001", st & (b.omega > 3.0))])
    assert [w for w, _ in marched] == ["isolas.h5 rl/branches/000", "isolas.h5 rl/branches/001"]
    assert p.ti.stays and p.branch == "isolas.h5 rl/branches/001" and "of isolas.h5 rl/branches/000" in p.reason


def test_a_stable_point_time_integration_leaves_is_marched_again_with_a_finer_step(long_branch, monkeypatch):
    """_try_until_kept with [validation] dt_refinement = 4 and the march replaced by a rule:
    time integration keeps the stable peak (W = 2) only with dt <= 2.5e-8 s. A stable point
    left with [validation] dt = 1e-7 s is marched again with 2.5e-8 s, which is its verdict (one try,
    refined_from says what the first march did); a march that ends in the friction lock, an
    unstable point, or dt_refinement = 1 gives no second march; a second march that leaves
    too rules the stretch out as one march does."""
    import pipelines.stages.validation as stage
    from hbm.options import ValidationOptions

    res, b, amp = long_branch
    m = len(b.omega)
    st = _stable_flags(res, b)
    marched = []
    rule = {"stays": lambda w, dt: dt <= 2.5e-8, "outcome": "leaves"}

    def fake_validate(ctx, rom, system, kind, method, ch, residual, where, dt=None, previous=None):
        step = ctx.scene.validation.dt if dt is None else dt
        marched.append((ch.index, step))
        stays = rule["stays"](ch.omega, step)
        outcome = "stays" if stays else rule["outcome"]
        ti = SimpleNamespace(stays=stays, outcome=outcome, dt=step,
                             verdict=lambda: "stays" if stays else "leaves" + (" for permanent contact (LE)"
                                                                                if outcome != "leaves" else ""))
        return stage.ValidationPoint(kind, method, True, ch.reason, where, ch.index, ch.omega,
                                     le_amplitude=ch.le_amplitude, stable=rule.get("stable", ch.stable), ti=ti)

    monkeypatch.setattr(stage, "_validate", fake_validate)
    lock = SimpleNamespace(friction_lock=SimpleNamespace(mu_set=0.1))

    def run(refinement=4, tries=3, flags=st):
        marched.clear()
        ctx = SimpleNamespace(scene=SimpleNamespace(
            validation=ValidationOptions(n_candidates=8, dt_refinement=refinement, harmonic_checks=0),
            contact=SimpleNamespace(mu=0.15)))
        cands = [stage.Candidate("nfrc_rl.h5", res, b.omega, b.x, amp, b.converged, flags)]
        return stage._try_until_kept(ctx, lock, None, "primary", "rl", cands, tries, lambda text: None)

    p = run()
    assert marched == [(m - 1, 1e-7), (m - 1, 2.5e-8)] and p.index == m - 1 and p.ti.stays and p.ti.dt == 2.5e-8
    assert p.refined_from == "leaves with dt = 1e-07 s" and "marched" not in p.reason
    # without refinement the peak is left, and so is the retry from the other stretch
    p = run(refinement=1)
    assert len(marched) == 2 and marched[0] == (m - 1, 1e-7) and all(dt == 1e-7 for _, dt in marched)
    assert p.index == m - 1 and not p.ti.stays
    assert p.refined_from == ""
    # the friction lock (mu = 0.15 >= mu_set = 0.1) is a state of the model: no second march
    rule["outcome"] = "permanent contact"
    p = run(tries=1)
    assert marched == [(m - 1, 1e-7)] and not p.ti.stays and p.refined_from == ""
    rule["outcome"] = "leaves"
    # an unstable point is not marched again
    rule["stable"] = False
    p = run(tries=1)
    assert len(marched) == 1 and not p.stable and p.refined_from == ""
    del rule["stable"]
    # left with both steps: the stretch is ruled out, and the retry (outside it) is refined too
    rule["stays"] = lambda w, dt: w > 3.0
    p = run()
    assert marched[:2] == [(m - 1, 1e-7), (m - 1, 2.5e-8)] and marched[2][0] != m - 1
    assert p.ti.stays and p.omega > 3.0 and len(marched) == 3 and "2 marched" in p.reason
    assert "2.0 rad/s (stable), time integration leaves with dt = 1e-07 s, leaves with dt = 2.5e-08 s" in p.reason


# -- a point not converged in N_h is not marched -------------------------------------------------
def test_harmonic_check_agrees_with_time_integration_at_low_harmonics(oscillator):
    """check_harmonics on the RL obstacle oscillator at N_h = 3 (continued from W = 4.6 down to
    0.3: its superharmonic resonances need more harmonics than 3). At stable points (Hill, N_h
    = 3) time integration (scipy's solve_ivp, another method) marched 100 periods from the
    orbit ends within 0.2 of the amplitude of it where the check passes, and 0.6 or more away
    where it fails (measured 0.11-0.14 and 1.09-1.67); on the main resonance (N_h = 30) the
    check passes and its multiplier with 60 harmonics is shooting's."""
    from test_period_doubling import _multipliers, _state

    from hbm.stability.convergence import check_harmonics
    from hbm.stability.spectrum import orbit_spectrum

    res30, br30, _, _ = oscillator
    res, br = low_harmonic_branch(res30)

    # the main resonance's upper stretch, then the superharmonic resonances near W = 0.74 and 0.49
    picks = [i for i in (300, 1000, 1500, 1884, 2026, 2033) if i < len(br.omega)]
    verdicts = {}
    for j in picks:
        # stable, or (1500 and 2026) no verdict: N_h = 3 leaves no eigenvector inside the band
        sp = orbit_spectrum(res, br.x[j], br.omega[j])[0]
        assert sp.stable or (not sp.decided and "harmonic band" in sp.note), (j, sp.note)
        ch = check_harmonics(res, br.x[j], br.omega[j], stable=False)
        d = ti_distance(res, br.x[j], float(br.omega[j]))
        verdicts[j] = ch.passed
        assert (d < 0.2) if ch.passed else (d > 0.6), (j, br.omega[j], ch.reason, d)
    assert sum(verdicts.values()) >= 3 and sum(not v for v in verdicts.values()) >= 3, verdicts
    # N_h = 30 is converged on the main resonance: the check passes, and with 60 harmonics
    # its largest multiplier is shooting's (another method)
    j = 2
    ch = check_harmonics(res30, br30.x[j], br30.omega[j])
    assert ch.passed and ch.n_harmonics == 60 and ch.moved < 1e-6, ch.reason
    shoot = np.abs(_multipliers(_state(res30, br30.x[j], br30.omega[j]), br30.omega[j])).max()
    assert abs(ch.multiplier - shoot) < 1e-5, (ch.multiplier, shoot)


def test_a_point_that_fails_the_harmonic_check_is_not_marched(long_branch, monkeypatch):
    """_try_until_kept with the check replaced by a rule (the orbits below W = 3 are not
    converged in N_h) and the march by one that keeps everything: the peak (W = 2) is checked,
    not marched, its stretch ruled out, and the upper stretch's point marched and kept, one
    march in all; with [validation] harmonic_checks = 0 the peak is marched; when every
    stable choice fails its check, the first one is marched."""
    import hbm.stability.selection as selection
    import pipelines.stages.validation as stage
    from hbm.options import ValidationOptions
    from hbm.stability import convergence
    from hbm.stability.convergence import HarmonicCheck

    res, b, amp = long_branch
    m = len(b.omega)
    st = _stable_flags(res, b)
    marched, checked = [], []

    passes = {"rule": lambda w: w > 3.0}

    def fake_check(residual, u, omega, **kw):
        checked.append(omega)
        return HarmonicCheck(passes["rule"](omega), "rule", 60)

    monkeypatch.setattr(stage, "_validate", _march_that_stays(marched))
    monkeypatch.setattr(convergence, "check_harmonics", fake_check)

    def run(checks):
        marched.clear()
        checked.clear()
        ctx = SimpleNamespace(scene=SimpleNamespace(validation=ValidationOptions(n_candidates=8, harmonic_checks=checks),
                                                    contact=SimpleNamespace(mu=0.0)))
        cands = [stage.Candidate("nfrc_rl.h5", res, b.omega, b.x, amp, b.converged, st)]
        return stage._try_until_kept(ctx, None, None, "primary", "rl", cands, 3, lambda text: None)

    p = run(6)
    assert len(checked) == 2 and checked[0] == b.omega[m - 1] and marched == [p.index]
    assert p.omega > 4.3 and p.ti.stays and "1 marched, 2 checked with 2 N_h" in p.reason
    assert "2.0 rad/s (stable), not marched: rule" in p.reason
    p = run(0)
    assert not checked and marched == [m - 1]
    # when every stable choice fails, the first one checked is marched rather than none
    passes["rule"] = lambda w: False
    p = run(6)
    assert len(checked) == 2 and marched == [m - 1] and p.found and p.index == m - 1
    assert "the first checked is marched" in p.reason


def test_a_branch_stored_without_stability_is_analysed_along_when_its_peak_has_no_stable_point(long_branch):
    """The NFRC of a scene run without [hbm] stability: when none of the candidates near the
    peak is stable (here the peak's stable stretch is ruled out, as after a march that left
    it), the validation stage's Candidate computes the branch's stability
    (hbm.stability.selection.branch_stability) and chooses from it: the largest amplitude
    that shooting (another method) calls stable, every point's verdict as shooting's."""
    from test_period_doubling import _multipliers, _state

    import pipelines.stages.validation as stage
    from hbm.stability.monitor import StabilityOptions
    from hbm.stability.selection import STABILITY_MARGIN

    res, b, amp = long_branch
    m = len(b.omega)
    shoot = np.array([np.abs(_multipliers(_state(res, b.x[j], b.omega[j]), b.omega[j])).max() for j in range(m)])
    eligible = b.omega > 2.4
    plain = choose_point(res, b.omega, b.x, amp, b.converged, None, eligible=eligible, n_candidates=8)
    assert plain.found and not plain.stable  # what the stage marched before: an unstable point
    c = stage.Candidate("nfrc_rl.h5", res, b.omega, b.x, amp, b.converged, None, eligible=eligible,
                        monitor=(1.0, 1.0, StabilityOptions()))
    ch = c.choose(8, STABILITY_MARGIN)
    assert ch.stable and "points the branch's stability computed here" in ch.reason, ch.reason
    assert shoot[ch.index] < 1.0 and amp[ch.index] == amp[eligible & (shoot < 1.0)].max()
    st = c.stability()
    assert np.array_equal(st.stable, shoot < 1.0) and np.array_equal(c.stable, st.stable)
    assert st.n_analyses < m / 3  # the monitor's gapped schedule, not every point
    # its period doublings where shooting's largest multiplier crosses the circle
    pds = [bf for bf in st.bifurcations if bf.kind == PERIOD_DOUBLING]
    assert len(pds) == 2 and all(shoot[bf.index] < 1.0 < shoot[bf.index + 1] or shoot[bf.index + 1] < 1.0 < shoot[bf.index]
                                 for bf in pds)
    # without a monitor the branch is never analysed along: the unstable choice stands
    bare = stage.Candidate("nfrc_rl.h5", res, b.omega, b.x, amp, b.converged, None, eligible=eligible)
    assert not bare.choose(8, STABILITY_MARGIN).stable and bare._stability is None


def test_isola_branches_stored_without_stability_are_analysed_along_only_when_no_peak_is_stable(long_branch,
                                                                                                  monkeypatch):
    """The isola point of a search run without [hbm] stability (_try_until_kept over several
    branches, each with a monitor): a branch with a stable point near its peak is chosen
    without analysing any branch along; only when no branch has one, the first branch's
    stability is computed along it, and the point chosen from it is one shooting calls
    stable; the second branch is then not analysed."""
    from test_period_doubling import _multipliers, _state

    import pipelines.stages.validation as stage
    from hbm.options import ValidationOptions
    from hbm.stability.monitor import StabilityOptions

    res, b, amp = long_branch
    monitor = (1.0, 1.0, StabilityOptions())
    ctx = SimpleNamespace(scene=SimpleNamespace(validation=ValidationOptions(n_candidates=8, dt_refinement=1,
                                                                             harmonic_checks=0),
                                                contact=SimpleNamespace(mu=0.0)))

    def stays(ctx, rom, system, kind, method, ch, residual, where):
        ti = SimpleNamespace(stays=True, outcome="stays", verdict=lambda: "stays")
        return stage.ValidationPoint(kind, method, True, ch.reason, where, ch.index, ch.omega,
                                     le_amplitude=ch.le_amplitude, stable=ch.stable, ti=ti)

    monkeypatch.setattr(stage, "_validate", stays)

    def branch(name, eligible=None):
        return stage.Candidate(f"isolas.h5 rl/branches/{name}", res, b.omega, b.x, amp, b.converged, None,
                               eligible=None if eligible is None else eligible.copy(), monitor=monitor)

    # the peak's stable stretch ruled out on the first branch (no stable candidate near its
    # peak: see the test above), whole on the second
    cut = b.omega > 2.4
    first, second = branch("000", cut), branch("001")
    p = stage._try_until_kept(ctx, None, None, "isola", "rl", [first, second], 1, lambda text: None)
    assert p.branch == second.where and p.stable
    assert first._stability is None and second._stability is None
    # neither branch has a stable point near its peak: the first is analysed along, not the second
    first, second = branch("000", cut), branch("001", cut)
    p = stage._try_until_kept(ctx, None, None, "isola", "rl", [first, second], 1, lambda text: None)
    assert p.branch == first.where and p.stable and "stability computed here" in p.reason, p.reason
    assert first._stability is not None and second._stability is None
    assert np.abs(_multipliers(_state(res, b.x[p.index], b.omega[p.index]), b.omega[p.index])).max() < 1.0


def test_a_period_doubling_the_scan_misses_is_found_from_the_branch_stability(long_branch, doubled, tmp_path,
                                                                             monkeypatch):
    """_period_doubling of the validation stage on the long branch stored without stability,
    with a scan of its two ends only (both stable: the scan sees no change): the doubling is
    then taken from the branch's stability computed along it, the first one (shooting's
    crossing near W = 4.34), and its doubled branch is marched (the switch and the march
    replaced by stand-ins). Without a monitor the scan's empty answer stands."""
    import h5py

    import hbm.stability.selection as selection
    import pipelines.stages.validation as stage
    from hbm.options import ValidationOptions
    from hbm.stability.monitor import StabilityOptions
    from hbm.stability import convergence
    from hbm.stability.convergence import HarmonicCheck

    res, b, amp = long_branch
    _, db, new = doubled
    switched_at, marched = [], []
    monkeypatch.setattr(selection, "continue_doubled_branch",
                        lambda r, u, w, bif, *a, **k: switched_at.append(bif.omega) or (db, new))
    monkeypatch.setattr(convergence, "check_harmonics", lambda *a, **k: HarmonicCheck(True, "rule", 122))
    monkeypatch.setattr(stage, "_validate", _march_that_stays(marched))
    nfrc = tmp_path / "nfrc_rl.h5"
    h5py.File(nfrc, "w").close()
    ctx = SimpleNamespace(out=tmp_path, scene=SimpleNamespace(
        validation=ValidationOptions(n_candidates=8, n_scan=2, pd_tries=1), hbm=HbmOptions(omega_min=2.0, omega_max=4.6),
        contact=SimpleNamespace(mu=0.0)))
    p, pd_branch = stage._period_doubling(ctx, None, None, "rl", res, b, {"le_amplitude": amp}, nfrc,
                                          lambda text: None)
    assert not p.found and not switched_at and "no change of stability among 2 points" in p.reason  # the scan alone
    c = stage.Candidate("nfrc_rl.h5", res, b.omega, b.x, amp, b.converged, None, monitor=(1.0, 1.0, StabilityOptions()))
    p, pd_branch = stage._period_doubling(ctx, None, None, "rl", res, b, {"le_amplitude": amp}, nfrc,
                                          lambda text: None, c)
    assert len(switched_at) == 1 and 4.3 < switched_at[0] < 4.36, switched_at
    assert p.found and len(marched) == 1 and pd_branch.found
    assert "from the branch's stability computed here" in pd_branch.reason and c._stability is not None


def test_the_search_s_doubled_branches_are_tried_after_the_nfrc_s(oscillator, doubled, tmp_path, monkeypatch):
    """_period_doubling with an isolas.h5 that holds two branches in the basis of W / 2 (the
    isola search's second search, seeded from time integration) and one in the scene's: when
    time integration leaves the NFRC's doubled branch, the search's doubled branch that more
    seeds landed on is tried next, as it is (no switch), at a point that carries the W / 2
    harmonics near a seed's speed, and kept when time integration stays; its DoubledBranch reports the same
    W / 2 share as the switch computed for those orbits. The switch, the check with 2 N_h
    and the march are stand-ins; the choice's Floquet analyses are real."""
    import h5py

    import hbm.harmonic.residual as residual_module
    import hbm.stability.selection as selection
    import pipelines.stages.validation as stage
    from hbm.options import ValidationOptions
    from hbm.stability import convergence
    from hbm.stability.convergence import HarmonicCheck
    from pipelines.stages.isolas import IsolaBranch

    res, br, amp, _ = oscillator
    _, db, new = doubled

    def branch(index, nu, seeds, seed_omega):
        return IsolaBranch("rl", index, "isola", True, "+: closed loop", nu, np.array(seeds), db.omega, db.x,
                           np.ones(len(db.omega), bool), db.le_amplitude, np.zeros((len(db.omega), 1, 1)),
                           seed_omega=np.array(seed_omega))

    # the seeds of branch 2 at the speed of the doubled orbits (W / 2 share >= 0.05) farthest
    # from the largest amplitude that a choice over the whole branch would take
    whole = choose_point(new, db.omega, db.x, db.le_amplitude, np.ones(len(db.omega), bool), None,
                         eligible=db.new_content >= 0.05, n_candidates=8)
    w_doubled = db.omega[db.new_content >= 0.05]
    w_seed = w_doubled[np.argmax(np.abs(w_doubled - whole.omega))]
    assert abs(whole.omega - w_seed) > stage.SEED_WINDOW * w_seed
    found = [branch(0, 1, [1, 2, 3], [4.0] * 3), branch(1, 2, [4], [4.0]), branch(2, 2, [5, 6], [w_seed, 9.0])]
    monkeypatch.setattr(stage, "read_branch_set", lambda path, method: found)
    # the modules that bind build_residual when first imported, imported before the stand-in:
    # one first imported under it would keep it for the rest of the process (a later isolas
    # stage in this test worker then built the oscillator's residual for rotor 67)
    import hbm.harmonic.nfrc  # noqa: F401
    import hbm.harmonic.start  # noqa: F401
    import hbm.isolas.harmonic  # noqa: F401
    import hbm.stability.switching  # noqa: F401

    monkeypatch.setattr(residual_module, "build_residual", lambda *a, **k: new)
    monkeypatch.setattr(selection, "continue_doubled_branch", lambda *a, **k: (db, new))
    monkeypatch.setattr(convergence, "check_harmonics", lambda *a, **k: HarmonicCheck(True, "rule", 122))
    marched = []

    def fake_validate(ctx, rom, system, kind, method, ch, residual, where, dt=None):
        marched.append((where, ch.index))
        stays = where.startswith("isolas.h5")
        ti = SimpleNamespace(stays=stays, outcome="stays" if stays else "leaves",
                             verdict=lambda: "stays" if stays else "leaves")
        return stage.ValidationPoint(kind, method, True, ch.reason, where, ch.index, ch.omega, 2,
                                     le_amplitude=ch.le_amplitude, stable=ch.stable, ti=ti)

    monkeypatch.setattr(stage, "_validate", fake_validate)
    nfrc = tmp_path / "nfrc_rl.h5"
    h5py.File(nfrc, "w").close()  # no stored stability: the NFRC's doubling is located by a scan
    ctx = SimpleNamespace(out=tmp_path, scene=SimpleNamespace(
        validation=ValidationOptions(n_candidates=8, pd_tries=3, dt_refinement=1),
        hbm=HbmOptions(omega_min=3.4, omega_max=4.6), contact=SimpleNamespace(mu=0.0), casing=None))
    assert [b.index for b in stage.searched_doubled_branches(found, 1)] == [2, 1]
    # a doubled branch with the most seeds, none of whose checked points holds with 2 N_h: left out
    artefact = replace(branch(3, 2, [7, 8, 9], [4.0] * 3), harmonic_checks={"passed": np.array([False, False])})
    assert [b.index for b in stage.searched_doubled_branches(found + [artefact], 1)] == [2, 1]
    assert [b.index for b in stage.searched_doubled_branches(
        found + [replace(artefact, harmonic_checks={"passed": np.array([False, True])})], 1)] == [3, 2, 1]
    p, pd_branch = stage._period_doubling(ctx, None, None, "rl", res, br, {"le_amplitude": amp}, nfrc,
                                          lambda text: None)
    assert [w for w, _ in marched] == [marched[0][0], "isolas.h5 rl/branches/002"]
    assert marched[0][0].startswith("validation.h5")
    assert p.found and p.branch == "isolas.h5 rl/branches/002" and p.stable and p.ti.stays
    assert db.new_content[p.index] >= 0.05 and "tried 2" in p.reason, p.reason
    assert abs(p.omega - w_seed) <= stage.SEED_WINDOW * w_seed  # where time integration found the orbit
    assert pd_branch.found and pd_branch.subharmonic == 2 and "2 seed(s)" in pd_branch.reason
    assert np.allclose(pd_branch.new_content, db.new_content, atol=1e-9)


def test_the_switch_starts_at_the_located_point_then_at_the_stored_points_around_it():
    """LocatedDoubling.switch_starts: the located (maybe refined) point first, then the two
    stored points of its bracket, unstable side first, none twice; nothing without a
    bifurcation."""
    omega = np.array([1470.0, 1465.0, 1460.0, 1455.0])
    x = np.arange(8.0).reshape(4, 2)
    refined = LocatedDoubling(SimpleNamespace(), 2, "", 0, 1462.5, np.array([9.0, 9.0]), (2, 1))
    starts = refined.switch_starts(omega, x)
    assert [w for _, w in starts] == [1462.5, 1460.0, 1465.0]
    assert np.array_equal(starts[1][0], x[2]) and np.array_equal(starts[2][0], x[1])
    stored = LocatedDoubling(SimpleNamespace(), 2, "", 0, 1460.0, x[2].copy(), (2, 1))
    assert [w for _, w in stored.switch_starts(omega, x)] == [1460.0, 1465.0]
    assert LocatedDoubling(None, -1, "none", 0).switch_starts(omega, x) == []
