"""The stability monitor's schedule on a branch whose multipliers are known in closed form:
the crossings it locates against the exact ones, and the stable flags it infers for the
points it did not analyse."""
from types import SimpleNamespace

import numpy as np
import pytest

from hbm.stability.bifurcation import NEIMARK_SACKER
from hbm.stability.monitor import StabilityMonitor, StabilityOptions
from hbm.stability.spectrum import FloquetSpectrum

OMEGA = 1000.0


def listed(mu, omega: float = OMEGA, floor: float = 0.05) -> FloquetSpectrum:
    """The Arnoldi spectrum that lists the multipliers mu (k,) at omega (rad/s), modulus floor
    `floor`, every family centred (placeholder eigenvectors)."""
    mu = np.asarray(mu, complex)
    k = len(mu)
    return FloquetSpectrum(omega=omega, exponents=np.log(mu) * omega / (2 * np.pi), multipliers=mu,
                           centred=np.ones(k, bool), edge_energy=np.zeros(k),
                           eigenvectors=np.zeros((k, 3, 2), complex), modulus_floor=floor, method="arnoldi")


def spectrum(log_mod: float) -> FloquetSpectrum:
    """A complex pair exp(log_mod +- 1.1 i) and two real stable multipliers (0.5, 0.3)."""
    mu = np.array([np.exp(log_mod + 1.1j), np.exp(log_mod - 1.1j), 0.5 + 0j, 0.3 + 0j])
    return listed(mu)


def _feed(mon, omegas, step=1.0):
    """Push points 0..n-1 (Omega = omegas[i], unknowns x = [i], le_amplitude 1e-4 i) through
    the monitor and finish it: {index: the extras it hands back}."""
    got = {}
    for i, w in enumerate(omegas):
        p = SimpleNamespace(index=i, omega=float(w), step=step, x=np.array([float(i)]))
        got.update((q.index, ex) for q, ex in mon.push(p, {"le_amplitude": 1e-4 * i}))
    got.update((q.index, ex) for q, ex in mon.finish())
    return got


def run(log_mod, n: int, options: StabilityOptions):
    """Points 0..n-1 one unit of arc length apart, Omega decreasing (no fold)."""
    mon = StabilityMonitor(analyse=lambda x, w: (spectrum(log_mod(float(x[0]))), 1), options=options)
    return mon, {i: ex["stable"] for i, ex in _feed(mon, OMEGA - np.arange(n)).items()}


@pytest.mark.parametrize("name, log_mod", [
    # a pair that leaves the circle and comes back 7 points later
    ("bump", lambda s: -0.3 + 0.4 * np.exp(-((s - 100) / 6) ** 2)),
    # a pair that creeps, then accelerates out, then falls back in fast
    ("accelerating", lambda s: -0.3 + 0.3 * (s / 100) ** 6 - 0.32 * max(0.0, (s - 100) / 10) ** 2),
])
def test_a_short_unstable_stretch_is_found_where_it_is(name, log_mod):
    n = 160
    mon, flags = run(log_mod, n, StabilityOptions())
    exact = [i for i in range(n - 1) if (log_mod(i) > 0) != (log_mod(i + 1) > 0)]
    assert len(exact) == 2  # out and back in
    assert [(b.kind, b.index) for b in mon.bifurcations] == [(NEIMARK_SACKER, i) for i in exact]
    assert all(b.paired for b in mon.bifurcations)  # one multiplier seen on both sides
    for b, i in zip(mon.bifurcations, exact):
        # the crossing by linear interpolation of log|mu| between the neighbours
        frac = log_mod(i) / (log_mod(i) - log_mod(i + 1))
        assert b.omega == pytest.approx(OMEGA - i - frac, abs=1e-9)
        assert b.direction == (1 if log_mod(i + 1) > 0 else -1)
    assert flags == {i: log_mod(i) <= 0 for i in range(n)}
    assert mon.n_analyses < n / 3  # the quiet stretches are skipped
    # every analysis has its cause, and the crossings were brought between neighbours
    assert sum(mon.causes.values()) == mon.n_analyses and mon.causes["first"] == 1
    assert mon.causes.get("bisection", 0) + mon.causes.get("next point", 0) >= 2


def appearing(s: float) -> FloquetSpectrum:
    """The spectrum of spectrum(-0.3) plus, from s = 50 on, a pair exp(l(s) +- 2 i) that
    no earlier analysis listed (a family the window had not caught, or one born from two real
    multipliers): l = -0.015 + 0.0015 (s - 50) up to s = 62, then 0.003 - 0.02 (s - 62).
    Unstable at s = 61 and 62 only."""
    base = spectrum(-0.3)
    if s < 50:
        return base
    lm = -0.015 + 0.0015 * (s - 50) if s <= 62 else 0.003 - 0.02 * (s - 62)
    mu = np.concatenate([[np.exp(lm + 2j), np.exp(lm - 2j)], base.multipliers])
    return listed(mu)


def test_a_multiplier_that_appears_next_to_the_circle_is_watched_from_the_next_point():
    """A pair that no earlier analysis listed appears within 2 % of the unit circle
    (StabilityOptions.margin), creeps out for two points and falls back in. Its first
    analysis has nothing to pair it with, so no speed and no reach: only the margin rule
    brings the next analysis to the next point, from which its speed is known. Without it
    the gap stays at its cap (8 points: the other multipliers sit still, far inside), the
    next analysis finds it inside again, and the unstable stretch is never seen."""
    n = 90
    mon = StabilityMonitor(analyse=lambda x, w: (appearing(float(x[0])), 1), options=StabilityOptions())
    flags = {i: ex["stable"] for i, ex in _feed(mon, OMEGA - np.arange(n)).items()}
    exact = {i: i not in (61, 62) for i in range(n)}
    assert flags == exact
    assert [(b.kind, b.index, b.direction) for b in mon.bifurcations] == [(NEIMARK_SACKER, 60, 1),
                                                                         (NEIMARK_SACKER, 62, -1)]


def test_a_fold_far_along_a_branch_is_placed_at_the_parabola_s_vertex():
    """parabola_vertex on three points 1e-5 apart in arc length at s ~ 2e3 (a fold reached
    crawling, far along a long branch): the vertex of Omega(s) = 1500 - 3e8 (s - s_v)^2 and
    the amplitude there, exactly (analytic), without numpy's RankWarning; a fit in s itself
    is ill-conditioned there."""
    import warnings

    from hbm.stability.bifurcation import parabola_vertex

    s_v = 2345.678901234
    s = s_v + np.array([-1.3e-5, 0.2e-5, 1.1e-5])
    w = 1500.0 - 3e8 * (s - s_v) ** 2
    amp = 1e-3 + 2.0 * (s - s_v)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ss, ww, aa = parabola_vertex(s, w, amp)
    assert abs(ss - s_v) < 1e-9 and abs(ww - 1500.0) < 1e-9 and abs(aa - 1e-3) < 1e-9


def windowed(log_mod: float, n_eig: int) -> FloquetSpectrum:
    """What shift-invert Arnoldi sees of a branch with a real multiplier -exp(log_mod) and two
    stable ones: its window lists the multipliers of modulus below the ceiling e^2.5 with 40
    eigenvalues, e^5 with 80 (modulus_floor = 1 / ceiling), and misses the others, as on
    rotor 67 at 1335-1341 rad/s."""
    ceiling = 2.5 if n_eig <= 40 else 5.0
    mu = np.array([-np.exp(log_mod) + 0j, 0.5 + 0j, 0.3 + 0j])
    mu = mu[np.log(np.abs(mu)) < ceiling]
    return listed(mu, floor=float(np.exp(-ceiling)))


@pytest.mark.parametrize("widen", [True, False])
def test_a_multiplier_that_grows_past_the_window_is_not_taken_for_stability(widen):
    # a period-doubling multiplier leaves the circle between s = 10 and 11 and grows to e^4.35,
    # past the default window's ceiling e^2.5 from s = 73 on: one crossing, and every point
    # after it unstable. Without widening the multiplier drops out of the window and the
    # monitor records a second crossing and calls the rest stable (the rotor 67 failure).
    log_mod = lambda s: -0.41 + 0.04 * s  # noqa: E731
    n = 120
    mon = StabilityMonitor(analyse=lambda x, w: (windowed(log_mod(float(x[0])), 40), 1),
                           widen=(lambda x, w, k: (windowed(log_mod(float(x[0])), k), 1)) if widen else None,
                           options=StabilityOptions())
    flags = {i: ex["stable"] for i, ex in _feed(mon, OMEGA - np.arange(n)).items()}
    exact = {i: log_mod(i) <= 0 for i in range(n)}
    assert 2.5 < log_mod(n - 1) < 5.0  # past the default window, inside the widened one
    assert sum(mon.causes.values()) == mon.n_analyses
    if widen:
        assert [b.index for b in mon.bifurcations] == [10]
        assert flags == exact
        assert mon.causes["widening"] >= 1
    else:
        assert len(mon.bifurcations) == 2 and flags != exact
        assert "widening" not in mon.causes


def test_a_point_widened_by_its_successor_is_stored_with_the_widened_verdict():
    # the mirror of the case above: a real multiplier shrinks from e^4.35 (past the default
    # window) back inside the circle at s = 108.75. The first analysis that sees it (at
    # log|mu| < 2.5) widens the analysed point before it, whose count rises from 0 to 1:
    # that point must be handed on with its widened verdict, not the narrow one it had when
    # it was analysed; and so must the points between it and the analysis before it, which
    # is widened in turn (its count rises too, but it was handed on already). The points up
    # to that one, analysed with the narrow window only, are "stable up to the ceiling" (a
    # window's documented limit).
    log_mod = lambda s: 4.35 - 0.04 * s  # noqa: E731
    n = 120
    widened = []

    def widen(x, w, k):
        widened.append(int(x[0]))
        return windowed(log_mod(float(x[0])), k), 1

    mon = StabilityMonitor(analyse=lambda x, w: (windowed(log_mod(float(x[0])), 40), 1), widen=widen,
                           options=StabilityOptions())
    got = _feed(mon, OMEGA - np.arange(n))
    assert sorted(got) == list(range(n))
    assert len(widened) == 2
    w, v = widened
    assert 2.0 < log_mod(w) < 2.5 + 0.04 * StabilityOptions().max_gap  # found near the narrow window's edge
    ex = got[w]
    assert not ex["stable"] and ex["n_unstable"] == 1 and ex["stability_analysed"]
    assert [i for i in range(n) if got[i]["stability_widened"]] == [w]
    assert ex["leading_multipliers"][0] == pytest.approx(np.exp(log_mod(w)), rel=1e-12)
    assert all(got[i]["stable"] == (log_mod(i) <= 0) for i in range(v + 1, n))
    assert [(b.index, b.direction) for b in mon.bifurcations] == [(108, -1)]
    # up to v, only the narrow window: the multiplier past its ceiling e^2.5 is not seen
    assert v == w - StabilityOptions().max_gap and got[v]["stability_analysed"]
    assert all(got[i]["stable"] for i in range(v + 1)) and log_mod(v) > 2.5


def test_a_multiplier_leaving_the_window_of_an_unstable_orbit_is_neither_widened_nor_bisected():
    # an orbit already unstable through a complex pair exp(0.3 +- 1.1 i), where a second,
    # real multiplier -exp(-0.41 + 0.04 s) crosses -1 between s = 10 and 11 and grows past
    # the default window's ceiling e^2.5 from s = 73 on. The count then falls from 3 to 2
    # with no multiplier near the unit circle: the stable flag is not at stake, so no point
    # is widened and the fall is not bisected into a crossing that does not exist. The
    # real crossing is located as before.
    from hbm.stability.bifurcation import PERIOD_DOUBLING

    log_mod = lambda s: -0.41 + 0.04 * s  # noqa: E731
    n = 120

    def window(s: float, n_eig: int) -> FloquetSpectrum:
        ceiling = 2.5 if n_eig <= 40 else 5.0
        mu = np.array([np.exp(0.3 + 1.1j), np.exp(0.3 - 1.1j), -np.exp(log_mod(s)) + 0j, 0.5 + 0j])
        mu = mu[np.log(np.abs(mu)) < ceiling]
        return listed(mu, floor=float(np.exp(-ceiling)))

    widened, analysed = [], []

    def analyse(x, w):
        analysed.append(int(x[0]))
        return window(float(x[0]), 40), 1

    def widen(x, w, k):
        widened.append(int(x[0]))
        return window(float(x[0]), k), 1

    mon = StabilityMonitor(analyse=analyse, widen=widen, options=StabilityOptions())
    got = _feed(mon, OMEGA - np.arange(n))
    assert sorted(got) == list(range(n))
    assert widened == []
    assert [(b.kind, b.index, b.direction) for b in mon.bifurcations] == [(PERIOD_DOUBLING, 10, 1)]
    assert not any(got[i]["stable"] for i in range(n))
    # the counts as far as the window sees: 2, then 3 from the crossing on, then 2 from the
    # first analysis past the ceiling (the points before it get the count of the analysis
    # before them)
    first_out = min(i for i in analysed if log_mod(i) >= 2.5)
    last_in = max(i for i in analysed if i < first_out)
    assert all(got[i]["n_unstable"] == (2 if i <= 10 else 3) for i in range(first_out))
    assert all(got[i]["n_unstable"] == 2 for i in range(first_out, n))
    assert last_in < 73 <= first_out
    # no analysis crowds round the window's edge: the gap there is the quiet stretch's
    assert sum(1 for i in analysed if last_in <= i <= first_out) == 2


def test_a_fold_followed_by_a_long_gap_is_recorded_at_the_turn():
    # Omega turns at point 30 (a parabola in arc length) where no analysed multiplier comes
    # near the circle (as at rotor 67's RL folds at 400.4 and 466.1 rad/s, on orbits with
    # |mu| ~ 1e2-1e3, where Hill's window shows no multiplier within e^0.5 of +1): the
    # analysis after the turn is followed by a max_gap-long gap. The fold waits for the
    # counts of its three points; until this was kept in mind the first two were forgotten
    # before the third arrived, and the fold was never recorded.
    from hbm.stability.bifurcation import FOLD

    turn, n = 30, 80
    omega = lambda s: OMEGA + 0.05 * (s - turn) ** 2  # noqa: E731

    def analyse(x, w):
        mu = np.array([0.5 + 0.2j, 0.5 - 0.2j, 0.3 + 0j])
        return listed(mu, w), 1

    mon = StabilityMonitor(analyse=analyse, options=StabilityOptions())
    got = _feed(mon, [omega(i) for i in range(n)])
    assert sorted(got) == list(range(n))
    analysed = sorted(i for i, ex in got.items() if ex["stability_analysed"])
    after = [i for i in analysed if i > turn]
    assert after[0] == turn + 1 and after[1] - after[0] >= 5  # the turn seen, then a long gap
    assert mon.causes["turn"] == 1 and mon.causes["gap cap"] >= 5
    assert [b.kind for b in mon.bifurcations] == [FOLD]
    assert mon.bifurcations[0].omega == pytest.approx(OMEGA, abs=1e-9)  # the parabola's vertex
    assert sorted(mon.bifurcations[0].omega_bracket) in ([omega(turn), omega(turn - 1)], [omega(turn), omega(turn + 1)])


def _spectra(before, after, at: int = 40):
    """analyse(x, w) for the monitor: the multipliers `before` up to point `at`, `after` past it."""
    def analyse(x, w):
        return listed(before if x[0] <= at else after, w), 1
    return analyse


def _stable_then(unstable_after: int):
    """analyse(x, w): a stable spectrum, with a real multiplier 1.95 from point
    unstable_after + 1 on (one the previous analysis has no counterpart for)."""
    stable = [0.5 + 0.2j, 0.5 - 0.2j, 0.3]
    return _spectra(stable, stable + [1.95], at=unstable_after)


def test_a_fold_whose_multiplier_cannot_be_paired_is_recorded_once():
    # Omega turns at point 30 and a real multiplier 1.95 appears past it with no counterpart
    # at the point before (as at 537.3 rad/s on rotor 67's DLFT 400-629 rad/s branch, mu
    # 1.95): the crossing cannot be paired, and its fallback took it for a second fold
    from hbm.stability.bifurcation import FOLD

    turn = 30
    mon = StabilityMonitor(analyse=_stable_then(turn), options=StabilityOptions())
    got = _feed(mon, [OMEGA + 0.05 * (i - turn) ** 2 for i in range(60)])
    assert [(b.kind, b.multiplier, b.direction, b.paired) for b in mon.bifurcations] == [(FOLD, 1.0, 1, True)]
    assert mon.bifurcations[0].omega == pytest.approx(OMEGA, abs=1e-9)
    assert [got[i]["stable"] for i in range(60)] == [i <= turn for i in range(60)]


def test_a_count_change_no_multiplier_explains_takes_its_kind_from_the_parities():
    # no turn, and a real multiplier 1.95 appears after point 40 with no counterpart before:
    # the count changes, no multiplier pairs across the circle. The change is recorded (the
    # stable flag does change there), half-way between the two analyses around it; the count
    # changed by one and det(I - M) changed sign: a real multiplier went through +1, a
    # branch point (without a turn), in the file's table too.
    from hbm.stability.bifurcation import BRANCH_POINT, PARITY, bifurcation_arrays, bifurcations_from_arrays

    mon = StabilityMonitor(analyse=_stable_then(40), options=StabilityOptions())
    got = _feed(mon, OMEGA - np.arange(80))
    assert [got[i]["stable"] for i in range(80)] == [i <= 40 for i in range(80)]
    (b,) = mon.bifurcations
    assert (b.kind, b.multiplier, b.direction, b.kind_from, b.paired) == (BRANCH_POINT, 1.95, 1, PARITY, False)
    assert (b.index, b.fraction, b.omega) == (40, 0.5, OMEGA - 40.5)
    table = bifurcation_arrays(mon.bifurcations)
    assert table["kind_from"][0].tolist() == [PARITY]
    (back,) = bifurcations_from_arrays({k: v for k, (v, _) in table.items()})
    assert back.kind_from == PARITY and back.kind == BRANCH_POINT
    # tables written before the column: a bool column paired (False: a guess), or none at all
    old = {k: v for k, (v, _) in table.items() if k != "kind_from"}
    assert bifurcations_from_arrays(dict(old, paired=np.array([False])))[0].kind_from == "guess"
    assert bifurcations_from_arrays(old)[0].kind_from == "crossing"


def test_a_complex_pair_that_splits_on_the_real_axis_is_a_period_doubling():
    # rotor 67's DLFT NFRC at 1455 rad/s: a complex pair just off the negative real axis,
    # |mu| 1.21, beside a real multiplier -0.81 inside; one point later two real multipliers
    # -2.38 and -0.38 (the pair met on the real axis, one real multiplier went back inside
    # through -1). No multiplier pairs across the circle, the count goes from 2 to 1: by the
    # parity of the real multipliers beyond -1 (det(I + M) changed sign) a period doubling,
    # where the nearest unstable multiplier (the complex pair) made the guess a
    # Neimark-Sacker. Its multiplier is the real one beyond -1, on the side where it is.
    from hbm.stability.bifurcation import PARITY, PERIOD_DOUBLING

    pair = 1.2104 * np.exp(1j * (np.pi - 0.035))
    mon = StabilityMonitor(analyse=_spectra([pair, np.conj(pair), -0.81, 0.5], [-2.384 - 0.0059j, -0.379, 0.5]),
                           options=StabilityOptions())
    got = _feed(mon, OMEGA - np.arange(80))
    assert [got[i]["n_unstable"] for i in range(80)] == [2 if i <= 40 else 1 for i in range(80)]
    (b,) = mon.bifurcations
    assert (b.kind, b.kind_from, b.multiplier, b.direction, b.index) == (PERIOD_DOUBLING, PARITY, -2.384 - 0.0059j, -1, 40)


def test_a_paired_neimark_sacker_the_counts_deny_becomes_a_period_doubling():
    # rotor 67's DLFT NFRC at 1607.5 rad/s: a pair just off the negative real axis (|mu|
    # 1.11, arg pi - 0.125) pairs across the circle with a real multiplier -0.95, while a
    # real multiplier -2.5 appears: the count goes from 2 to 1. A pair changes the count by
    # two and det(I + M) by nothing, so the crossing is a real one through -1: the
    # Neimark-Sacker the pairing gave becomes a period doubling (at the same place), whose
    # multiplier is the real one beyond -1
    from hbm.stability.bifurcation import PARITY, PERIOD_DOUBLING

    pair = 1.11 * np.exp(1j * (np.pi - 0.125))
    mon = StabilityMonitor(analyse=_spectra([pair, np.conj(pair), 0.5], [-0.95, -2.5, 0.5]), options=StabilityOptions())
    _feed(mon, OMEGA - np.arange(80))
    (b,) = mon.bifurcations
    assert (b.kind, b.kind_from, b.multiplier, b.direction, b.index) == (PERIOD_DOUBLING, PARITY, -2.5, -1, 40)
    # where the pair crossed between the two points (log|mu| interpolated), not half-way
    assert b.fraction == pytest.approx(np.log(1.11) / (np.log(1.11) - np.log(0.95)))


def test_a_real_crossing_beside_a_paired_neimark_sacker_is_added():
    # a complex pair goes out through the circle (paired: a Neimark-Sacker, +2) while a real
    # multiplier -2.5 appears with no counterpart: the count goes from 0 to 3 and det(I + M)
    # changes sign: a period doubling too, added half-way
    from hbm.stability.bifurcation import CROSSING, PARITY, PERIOD_DOUBLING

    inner, outer = 0.95 * np.exp(1.5j), 1.05 * np.exp(1.5j)
    mon = StabilityMonitor(analyse=_spectra([inner, np.conj(inner), 0.5], [outer, np.conj(outer), 0.5, -2.5]),
                           options=StabilityOptions())
    _feed(mon, OMEGA - np.arange(80))
    assert sorted((b.kind, b.kind_from, b.direction, b.index) for b in mon.bifurcations) == [
        (NEIMARK_SACKER, CROSSING, 1, 40), (PERIOD_DOUBLING, PARITY, 1, 40)]


def test_a_count_change_the_parities_do_not_explain_is_a_guess():
    # a complex pair exp(0.5 +- 2.5 i) appears with no counterpart: the count changes by two
    # and neither parity changes (a Neimark-Sacker, or two real multipliers through the same
    # side): the kind is guessed from the new pair
    from hbm.stability.bifurcation import GUESS

    new = np.exp(0.5 + 2.5j)
    mon = StabilityMonitor(analyse=_spectra([0.5, 0.3], [new, np.conj(new), 0.5, 0.3]), options=StabilityOptions())
    _feed(mon, OMEGA - np.arange(80))
    (b,) = mon.bifurcations
    assert (b.kind, b.kind_from, b.multiplier, b.direction) == (NEIMARK_SACKER, GUESS, new, 1)


def test_a_guess_leaves_out_the_multipliers_that_stayed_unstable():
    # an orbit unstable through a real multiplier -1.2 (-1.25 further on) gains a complex pair
    # exp(0.8 +- 1.5 i) after point 40, with no counterpart before it: the count changes by
    # two, no parity changes, the kind is a guess. The real multiplier is nearer the circle,
    # but it is unstable on both sides (paired across the count change), so it did not
    # cross: the guess is the new pair, a Neimark-Sacker, not a period doubling.
    from hbm.stability.bifurcation import GUESS

    new = np.exp(0.8 + 1.5j)
    mon = StabilityMonitor(analyse=_spectra([-1.2, 0.5], [-1.25, new, np.conj(new), 0.5]), options=StabilityOptions())
    got = _feed(mon, OMEGA - np.arange(80))
    assert [got[i]["n_unstable"] for i in range(80)] == [1 if i <= 40 else 3 for i in range(80)]
    (b,) = mon.bifurcations
    assert (b.kind, b.kind_from, b.multiplier, b.index, b.direction) == (NEIMARK_SACKER, GUESS, new, 40, 1)


@pytest.mark.parametrize("after, source, words", [
    # a real multiplier -1.05 appears: one real multiplier through -1, by the parity
    ([-1.05], "parity", "the kind comes from the parity of the real multipliers beyond -1"),
    # two appear (-1.05, -1.5): the count changes by two and the parity does not: a guess
    ([-1.05, -1.5], "guess", "the kind is a guess"),
])
def test_a_period_doubling_located_without_a_paired_multiplier_says_how_its_kind_is_known(monkeypatch, after, source,
                                                                                          words):
    # the validation stage's locate_period_doubling on a bracket where real multipliers
    # appear with no counterpart: the one nearest the circle is taken (a real negative
    # multiplier past it), and the reason says how the kind is known
    from hbm.stability import selection

    def spectrum_at(residual, x, omega):
        mu = np.array([0.5 + 0.2j, 0.5 - 0.2j, 0.3 + 0j] + (after if x[0] > 40 else []), dtype=complex)
        k = len(mu)
        return FloquetSpectrum(omega=omega, exponents=np.log(mu) * omega / (2 * np.pi), multipliers=mu,
                               centred=np.ones(k, bool), edge_energy=np.zeros(k),
                               eigenvectors=np.ones((k, 3, 2), complex), modulus_floor=0.05, method="arnoldi"), 1

    monkeypatch.setattr(selection, "orbit_spectrum", spectrum_at)
    n = 80
    x = np.arange(n, dtype=float)[:, None] * np.ones((1, 2))
    loc = selection.locate_period_doubling(None, OMEGA - np.arange(n), x, 1e-4 * np.arange(n), np.ones(n, bool),
                                           brackets=[40])
    assert loc.bifurcation is not None and loc.bifurcation.kind == selection.PERIOD_DOUBLING
    assert loc.bifurcation.kind_from == source and loc.bifurcation.multiplier == -1.05
    assert words in loc.reason


def test_a_branch_crawling_at_a_fixed_omega_has_no_folds():
    # the step floor's crawl of rotor 67's DLFT doubled branch at 719.9 rad/s: Omega moves by
    # the corrector's round-off, +4.8e-7, -1.03e-6, -1.34e-6, +8.0e-7 rad/s in turn, then
    # the branch leaves it going down in Omega (after a last -9.2e-7, as there)
    jitter = np.r_[np.tile([4.8e-7, -1.03e-6, -1.34e-6, 8.0e-7], 10), -9.2e-7]
    omegas = np.concatenate([719.9 + np.cumsum(np.r_[0.0, jitter]), 719.9 - 0.13 * np.arange(1, 11)])
    mon = StabilityMonitor(analyse=_stable_then(len(omegas)), options=StabilityOptions())
    got = _feed(mon, omegas, step=2e-6)
    assert mon.bifurcations == [] and "turn" not in mon.causes
    assert all(ex["stable"] for ex in got.values()) and len(got) == len(omegas)
    # the same jitter 1e3 times larger (1e-3 rad/s, 1.4e-6 of Omega) is resolved: every
    # change of direction is a turn
    omegas = np.concatenate([719.9 + np.cumsum(np.r_[0.0, 1e3 * jitter]), 719.9 - 0.13 * np.arange(1, 11)])
    turns = int(np.sum(np.diff(np.sign(np.diff(omegas))) != 0))
    mon = StabilityMonitor(analyse=_stable_then(len(omegas)), options=StabilityOptions())
    _feed(mon, omegas)
    assert len(mon.bifurcations) == mon.causes["turn"] == turns > 15


def test_a_turn_whose_next_point_lands_at_the_vertex_is_a_fold():
    # rotor 67's RL NFRC at 1478.3 rad/s: Omega falls by 0.48 rad/s, rises by 4.6e-6 rad/s
    # (3e-9 of Omega: the point after the turn next to the vertex), then by 0.4 rad/s
    from hbm.stability.bifurcation import FOLD

    steps = np.r_[np.full(20, -0.48), 4.6e-6, np.full(20, 0.4)]
    omegas = 1487.9 + np.cumsum(np.r_[0.0, steps])
    mon = StabilityMonitor(analyse=_stable_then(len(omegas)), options=StabilityOptions())
    _feed(mon, omegas)
    assert [(b.kind, b.index) for b in mon.bifurcations] in ([(FOLD, 19)], [(FOLD, 20)])
    assert mon.bifurcations[0].omega == pytest.approx(omegas[20], abs=0.1)  # the parabola through 3 points
