"""compute_nfrc with stability: what on_point and the result carry, and a resumed run.

Rotor 67 coarse ROM at N_h = 12, N_t = 256 over [1940, 2000] rad/s (DLFT): ~60 points, a few
seconds. The verdicts themselves are checked against time integration and shooting in
test_stability_rotor67.py and test_stability_hill.py; here the bookkeeping: every point
handed on once, in order, with stability keys consistent with the result's arrays and
with an own analysis of the point where it was analysed, and a bifurcation between two
points exactly where the count changes.
"""

import numpy as np
import pytest

from hbm.continuation.branch import Branch
from hbm.harmonic.nfrc import compute_nfrc
from hbm.harmonic.residual import build_residual
from hbm.options import CasingOptions, ContactOptions, HbmOptions
from hbm.stability.bifurcation import KINDS, bifurcation_arrays
from hbm.stability.monitor import StabilityOptions
from hbm.stability.spectrum import orbit_spectrum
from support import coarse_rom

OPTS = HbmOptions(n_harmonics=12, n_time=256, omega_min=1940.0, omega_max=2000.0)
KEYS = {"stable", "n_unstable", "stability_analysed", "stability_widened", "stability_cpu_time",
        "leading_multipliers", "period_ratio"}


@pytest.fixture(scope="module")
def run():
    rom = coarse_rom()
    seen = []
    r = compute_nfrc(rom, CasingOptions(), ContactOptions(), OPTS, "dlft", on_point=lambda p, ex: seen.append((p, ex)),
                     stability=StabilityOptions(max_gap=4))
    return rom, r, seen


def test_every_point_handed_on_once_in_order_with_its_stability(run):
    rom, r, seen = run
    assert [p.index for p, _ in seen] == list(range(len(r.omega)))
    for (p, ex), i in zip(seen, range(len(r.omega))):
        assert KEYS <= set(ex)
        assert ex["stable"] == r.stable[i] and ex["n_unstable"] == r.n_unstable[i]
        assert ex["stable"] == (ex["n_unstable"] == 0)
        assert np.shape(ex["leading_multipliers"]) == (4,) and ex["period_ratio"] == 2  # 2-lobe casing: T / 2
        assert np.isnan(ex["leading_multipliers"]).all() != ex["stability_analysed"]
        # the cost lies where the analyses were made; a widened point was analysed
        assert (ex["stability_cpu_time"] > 0) == ex["stability_analysed"]
        assert ex["stability_analysed"] or not ex["stability_widened"]
    assert r.stability_analysed[0] and r.stability_analysed[-1]
    assert 0 < r.n_stability_analyses <= len(r.omega) + 1 and r.stability_time > 0


def test_analysed_points_match_an_own_analysis_and_changes_are_bifurcations(run):
    rom, r, _ = run
    res = build_residual(rom, CasingOptions(), ContactOptions(), OPTS, method="dlft")
    for i in np.flatnonzero(r.stability_analysed)[::5]:
        sp, g = orbit_spectrum(res, r.unknowns[i], r.omega[i])
        assert sp.n_unstable == r.n_unstable[i] and g == 2
        # the same computation, up to round-off: ARPACK's random start vector and the BLAS
        # threads (one inside compute_nfrc) change it, amplified by the non-normal Hill
        # pencil's eigenvalue condition (measured 4e-6 relative); 1e-4
        assert np.allclose(sp.leading(4), r.leading_multipliers[i], rtol=1e-4, equal_nan=True)
    changes = np.flatnonzero(np.diff(r.n_unstable) != 0)
    located = sorted({b.index for b in r.bifurcations if b.kind != "fold"})
    assert set(changes) <= set(located) | {b.index for b in r.bifurcations}
    for b in r.bifurcations:
        assert b.kind in KINDS and min(b.omega_bracket) - 1e-9 <= b.omega <= max(b.omega_bracket) + 1e-9
    table = bifurcation_arrays(r.bifurcations)
    assert {k: v[0].shape for k, v in table.items()} == {k: (len(r.bifurcations),) for k in table}
    assert table["omega"][1] == "rad/s" and table["le_amplitude"][1] == "m"


def test_scene_max_gap_1_analyses_every_point_and_finds_what_the_gaps_do(run):
    """[hbm] stability_max_gap = 1 (HbmOptions, the scene's section) reaches the monitor:
    every point is analysed, and the counts there agree with the gapped run's analysed
    points; every stability change the gapped run located is one of the exhaustive run's."""
    import dataclasses

    rom, gapped, _ = run
    opts = dataclasses.replace(OPTS, stability=True, stability_max_gap=1)
    r = compute_nfrc(rom, CasingOptions(), ContactOptions(), opts, "dlft")
    assert r.stability_analysed.all() and r.n_stability_analyses >= len(r.omega)
    assert gapped.n_stability_analyses < r.n_stability_analyses
    np.testing.assert_array_equal(r.omega, gapped.omega)  # the same continuation
    both = gapped.stability_analysed
    np.testing.assert_array_equal(r.n_unstable[both], gapped.n_unstable[both])
    every = {(b.kind, b.index) for b in r.bifurcations}
    assert {(b.kind, b.index) for b in gapped.bifurcations} <= every


def test_resumed_run_keeps_the_old_points_and_goes_on_with_stability(run):
    rom, r, _ = run
    m0 = len(r.omega) // 2
    old = Branch(omega=r.omega[:m0], x=r.unknowns[:m0], converged=r.converged[:m0], residual_norm=r.residual_norm[:m0],
                 iterations=r.iterations[:m0], step=r.step[:m0], time=r.time[:m0])
    seen = []
    r2 = compute_nfrc(rom, CasingOptions(), ContactOptions(), OPTS, "dlft", resume=old,
                      on_point=lambda p, ex: seen.append(p.index), stability=StabilityOptions(max_gap=4))
    assert r2.status == r.status
    assert seen == list(range(m0, len(r2.omega)))  # only the new points are handed on
    assert np.all(r2.n_unstable[m0:] >= 0)
    assert np.all(r2.n_unstable[:m0] == -1)  # a Branch carries no stability: unknown, not invented


def test_scene_refine_bifurcations_locates_the_crossings_between_the_points(run):
    """[hbm] refine_bifurcations reaches the NFRC's monitor: the same continuation and the
    same bifurcations, each paired crossing narrowed to two points within refine_rtol of
    Omega (1e-5: 0.02 rad/s here, against stored brackets of 0.07 to 2.6 rad/s). Checked
    with own analyses of orbits solved at fixed Omega at the two ends: the count of
    unstable multipliers differs there, more of them on the side the direction names."""
    import dataclasses

    from hbm.continuation.newton import NewtonOptions, newton_solve

    rom, gapped, _ = run
    opts = dataclasses.replace(OPTS, stability=True, stability_max_gap=4, refine_bifurcations=6)
    r = compute_nfrc(rom, CasingOptions(), ContactOptions(), opts, "dlft")
    np.testing.assert_array_equal(r.omega, gapped.omega)
    assert [(b.kind, b.index, b.kind_from) for b in r.bifurcations] == \
        [(b.kind, b.index, b.kind_from) for b in gapped.bifurcations]
    res = build_residual(rom, CasingOptions(), ContactOptions(), OPTS, method="dlft")
    refined = [b for b in r.bifurcations if b.kind_from == "crossing" and b.kind != "fold"]
    assert len(refined) >= 2
    for b, g in zip(r.bifurcations, gapped.bifurcations):
        if b not in refined:
            assert b.refine_steps == 0 and b.omega == g.omega
            continue
        assert 1 <= b.refine_steps <= 6 and b.refine_note == ""
        lo, hi = sorted(b.bracket)
        assert min(b.omega_bracket) <= lo <= b.omega <= hi <= max(b.omega_bracket)
        stored = abs(b.omega_bracket[1] - b.omega_bracket[0])
        assert hi - lo <= 1e-5 * hi * 1.0001
        # tenfold narrower, unless the stored points lie within ten tolerances already (the
        # flicker at 1961.5-1961.7 rad/s, where the count goes 4, 2, 4, 2 from point to point)
        assert hi - lo < 0.1 * stored or stored < 10 * 1e-5 * hi
        counts = []
        for w in b.bracket:  # the end on a's side, then b's
            sol = newton_solve(res, r.unknowns[b.index], w, NewtonOptions(tol_residual=1e-8, max_iter=20))
            assert sol.converged, sol.reason
            counts.append(orbit_spectrum(res, sol.x, w)[0].n_unstable)
        assert np.sign(counts[1] - counts[0]) == b.direction, (b, counts)


def test_a_failed_final_point_is_marked_not_analysed_not_unstable():
    """A branch that stops on a failed correction (here one Newton iteration for a fixed step of
    3: the first step fails at 1997 rad/s) hands on its failed point with stability unknown:
    n_unstable -1, no multipliers, the note saying why, in on_point's extras and the arrays
    alike; the converged start keeps its analysis."""
    from dataclasses import replace

    from hbm.harmonic.nfrc import default_continuation
    from hbm.stability.monitor import NOT_CONVERGED

    rom = coarse_rom()
    c = default_continuation(OPTS)
    c = replace(c, ds=3.0, ds_min=3.0, ds_max=3.0, newton=replace(c.newton, max_iter=1), max_points=50)
    seen = []
    r = compute_nfrc(rom, CasingOptions(), ContactOptions(), OPTS, "dlft", continuation=c,
                     on_point=lambda p, ex: seen.append((p, ex)), stability=StabilityOptions(max_gap=4))
    assert r.status.startswith("step below floor") and r.converged.tolist() == [True, False]
    assert r.n_unstable.tolist()[1] == -1 and not r.stable[1] and not r.stability_analysed[1]
    assert r.n_unstable[0] >= 0 and r.stability_analysed[0]
    assert r.stability_note.tolist() == ["", NOT_CONVERGED] and NOT_CONVERGED.startswith("not analysed")
    (p0, ex0), (p1, ex1) = seen
    assert not p1.converged and ex1["n_unstable"] == -1 and ex1["stability_note"] == NOT_CONVERGED
    assert np.isnan(ex1["leading_multipliers"]).all() and np.isfinite(ex0["leading_multipliers"]).all()
    assert ex1["period_ratio"] == 2  # from its harmonics: even ones only (2-lobe casing)
