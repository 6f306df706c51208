"""A Floquet analysis that gives no verdict (FloquetSpectrum.decided): ARPACK stopping short of
the eigenvalues asked for (the ones it did not converge may be the unstable ones), or a
spectrum left without any multiplier. Such a point is neither stable nor unstable: the
spectrum, the monitor and the choice of a point for validation say so, and no bifurcation
is located against it. The principal Mathieu tongue (test_stability_defects.mathieu: one
multiplier -1.934, by shooting) with ARPACK made to drop its unstable family, and spectra
given in closed form."""
from types import SimpleNamespace

import numpy as np
import pytest
import scipy.sparse.linalg as spla

from hbm.stability import selection
from hbm.stability import spectrum as spm
from hbm.stability.bifurcation import FOLD, PERIOD_DOUBLING
from hbm.stability.monitor import NOT_INFERRED, StabilityMonitor, StabilityOptions, monitor_branch
from test_stability_defects import OMEGA, mathieu, spec_of

EIGS = spla.eigs
BAND = "no eigenvector inside the harmonic band (too few harmonics)"


def short_eigs(keep, calls=None, fail_first: int | None = None):
    """eigs that computes the answer, then raises ArpackNoConvergence with the eigenpairs keep(theta)
    selects, as ARPACK does when it runs out of iterations (only on the first fail_first calls
    when given; calls: list that counts them)."""
    def eigs(A, k=6, **kw):
        theta, V = EIGS(A, k=k, **kw)
        if calls is not None:
            calls.append(k)
        if fail_first is not None and len(calls) > fail_first:
            return theta, V
        m = keep(theta)
        raise spla.ArpackNoConvergence("No convergence (synthetic)", theta[m], V[:, m])
    return eigs


def without_unstable(H):
    """keep: the Hill eigenvalues lam = 1 / theta whose multiplier is inside the unit circle."""
    T = 2 * np.pi / H.omega
    return lambda theta: (1.0 / theta).real * T < 1e-3


def empty(note: str = BAND) -> spm.FloquetSpectrum:
    """An Arnoldi spectrum without multipliers, as _spectrum gives when every family is dropped."""
    return spm.FloquetSpectrum(omega=OMEGA, exponents=np.zeros(0, complex), multipliers=np.zeros(0, complex),
                               centred=np.zeros(0, bool), edge_energy=np.zeros(0),
                               eigenvectors=np.zeros((0, 3, 2), complex), modulus_floor=1.0, method="arnoldi",
                               note=note)


# -- the spectrum ---------------------------------------------------------------------------
def test_an_arnoldi_spectrum_arpack_left_short_of_the_unstable_multiplier_is_no_verdict(monkeypatch):
    H, shoot = mathieu(8)
    full = spm.arnoldi_spectrum(H)
    assert full.note == "" and full.n_unstable == 1 and full.multipliers[0] == pytest.approx(shoot[0], rel=1e-6)
    monkeypatch.setattr(spla, "eigs", short_eigs(without_unstable(H)))
    sp = spm.arnoldi_spectrum(H)
    # 30 of the 40 eigenvalues converged, none of the unstable family: the 9 multipliers listed
    # are all inside the circle (largest -0.4856, the tongue's other multiplier)
    assert sp.note == "ARPACK converged 30 of 40 eigenvalues" and len(sp.multipliers) == 9
    assert sp.largest_modulus == pytest.approx(-shoot[1], rel=1e-6)
    assert not sp.unstable.any()
    assert not sp.stable and sp.n_unstable == -1 and not sp.decided and not sp.complete
    assert sp.modulus_floor == 1.0


def test_the_widened_spectrum_retries_where_arpack_stopped_short(monkeypatch):
    # ARPACK stops short at the first window (40) and converges at the second (80): the retry
    # gives the verdict, with the unstable multiplier
    H, shoot = mathieu(8)
    calls = []
    monkeypatch.setattr(spla, "eigs", short_eigs(without_unstable(H), calls, fail_first=1))
    sp = spm.widened_spectrum(H, n_eig=40, min_ceiling=1.0)
    assert calls == [40, 80]
    assert sp.decided and sp.note == "" and sp.n_unstable == 1 and not sp.stable
    assert sp.multipliers[0] == pytest.approx(shoot[0], rel=1e-6)


@pytest.mark.parametrize("how", ["arnoldi, every family at the band's edge", "dense, every family at the band's edge",
                                 "arpack converged none"])
def test_a_spectrum_without_multipliers_is_no_verdict(monkeypatch, how):
    H, _ = mathieu(8)
    if how.startswith("arnoldi"):
        sp, note = spm.arnoldi_spectrum(H, max_edge=-1.0), BAND
    elif how.startswith("dense"):
        sp, note = spm.dense_spectrum(H, max_edge=-1.0), BAND
    else:  # scipy's ArpackNoConvergence when no eigenpair can be extracted: (0,) and (n, 0)
        monkeypatch.setattr(spla, "eigs", short_eigs(lambda theta: np.zeros(len(theta), bool)))
        sp, note = spm.arnoldi_spectrum(H), "ARPACK converged 0 of 40 eigenvalues"
    assert len(sp.multipliers) == 0 and sp.note == note
    assert not sp.stable and sp.n_unstable == -1 and not sp.decided
    assert not empty().stable and empty().n_unstable == -1


# -- the monitor ----------------------------------------------------------------------------
def push_all(mon: StabilityMonitor, n: int) -> dict:
    """Points 0..n-1 (Omega = OMEGA - i, x = [i], one unit of arc length apart), finished:
    {index: extras handed back}, each point once."""
    got = []
    for i in range(n):
        got += mon.push(SimpleNamespace(index=i, omega=OMEGA - i, step=1.0, x=np.array([float(i)])),
                        {"le_amplitude": 1e-4 * i})
    got += mon.finish()
    assert sorted(q.index for q, _ in got) == list(range(n))
    return {q.index: ex for q, ex in got}


def test_the_monitor_neither_calls_a_point_arpack_left_short_stable_nor_locates_a_crossing_against_it(monkeypatch):
    # stable up to point 8, a multiplier beyond -1 from point 10 on; at point 9 ARPACK stops short
    # of the unstable family. The crossing lies between 8 and 10, the only verdicts around it
    H, _ = mathieu(8)
    monkeypatch.setattr(spla, "eigs", short_eigs(without_unstable(H)))
    partial = spm.arnoldi_spectrum(H)

    def analyse(x, w):
        i = int(x[0])
        return (partial if i == 9 else spec_of([0.5, 0.3] if i < 9 else [-1.5, 0.3])), 1

    mon = StabilityMonitor(analyse=analyse, options=StabilityOptions(max_gap=1))
    got = push_all(mon, 14)
    ex = got[9]
    assert (ex["stable"], ex["n_unstable"], ex["stability_analysed"]) == (False, -1, True)
    assert np.isnan(ex["leading_multipliers"]).all()
    assert mon.undecided == {9: "ARPACK converged 30 of 40 eigenvalues"}
    # the reason travels with the point (the NFRC files' stability_note)
    assert [got[i]["stability_note"] for i in (8, 9, 10)] == ["", "ARPACK converged 30 of 40 eigenvalues", ""]
    assert [got[i]["n_unstable"] for i in range(14)] == [0] * 9 + [-1] + [1] * 4
    assert [got[i]["stable"] for i in range(14)] == [True] * 9 + [False] * 5
    assert [(b.kind, b.index, b.omega_bracket, b.direction) for b in mon.bifurcations] == [
        (PERIOD_DOUBLING, 8, (OMEGA - 8, OMEGA - 10), 1)]
    assert mon.causes["after undecided"] == 1  # point 10, compared with 8


def test_a_point_without_multipliers_inside_an_unstable_stretch_is_no_stability_change():
    # unstable everywhere; the analysis of point 10 is left without a multiplier: no point is
    # stable and nothing crosses (the empty spectrum read as stable made two crossings there)
    def analyse(x, w):
        return (empty() if int(x[0]) == 10 else spec_of([-1.5, 0.3])), 1

    n = 20
    st = monitor_branch(analyse, OMEGA - np.arange(n), np.arange(n, dtype=float)[:, None],
                        [{"le_amplitude": 1e-4 * i} for i in range(n)], options=StabilityOptions(max_gap=1))
    assert not st.stable.any()
    assert st.n_unstable.tolist() == [1] * 10 + [-1] + [1] * 9
    assert st.stability_analysed.all() and st.bifurcations == ()
    assert st.undecided == {10: BAND}
    assert st.stability_note.tolist() == [""] * 10 + [BAND] + [""] * 9


def test_a_long_stretch_without_verdicts_is_cut_and_handed_on_as_unknown():
    # stable everywhere, but the analyses at points 8 to 12 give no verdict. Analysed: 0, 1, then
    # 9 (the gap cap, max_gap 8: no verdict), 10 and 11 (the points after it), where 10 points
    # wait past 1, more than max_gap + 1: the chain is cut, points 2..11 handed on unknown; 12
    # analysed as the first of a new chain (no verdict either), 13 the first with one
    def analyse(x, w):
        return (empty() if 8 <= int(x[0]) <= 12 else spec_of([0.5, 0.3])), 1

    n = 40
    mon = StabilityMonitor(analyse=analyse, options=StabilityOptions(max_gap=8))
    got = push_all(mon, n)
    counts = [got[i]["n_unstable"] for i in range(n)]
    assert counts == [0, 0] + [-1] * 11 + [0] * 27
    assert [i for i in range(n) if got[i]["stability_analysed"]][:7] == [0, 1, 9, 10, 11, 12, 13]
    assert all(got[i]["stable"] == (counts[i] == 0) for i in range(n))
    assert sorted(mon.undecided) == [9, 10, 11, 12] and mon.bifurcations == []
    # each point without a count says why: its own analysis' reason, or none inferable
    notes = [got[i]["stability_note"] for i in range(n)]
    assert notes == [""] * 2 + [NOT_INFERRED] * 7 + [BAND] * 4 + [""] * 27
    assert (mon.causes["after undecided"], mon.causes["first"]) == (2, 3)


def test_a_fold_beside_a_point_without_a_verdict_has_no_direction():
    # Omega falls to point 10 and rises after it (a fold between 10 and 11); every orbit is
    # stable but point 11's analysis gives no verdict. The fold is recorded once, at the
    # parabola's vertex, with direction 0 (not known); read as a count, the -1 of point 11
    # would say that the orbit gains stability there
    n = 16
    omega = OMEGA - np.abs(np.arange(n) - 10.3)
    mon = StabilityMonitor(analyse=lambda x, w: (empty() if int(x[0]) == 11 else spec_of([0.5, 0.3]), 1),
                           options=StabilityOptions(max_gap=1))
    got = []
    for i in range(n):
        got += mon.push(SimpleNamespace(index=i, omega=float(omega[i]), step=1.0, x=np.array([float(i)])),
                        {"le_amplitude": 1e-4 * i})
    got += mon.finish()
    assert [ex["n_unstable"] for _, ex in sorted(got, key=lambda g: g[0].index)] == [0] * 11 + [-1] + [0] * 4
    assert [(b.kind, b.index, b.direction) for b in mon.bifurcations] == [(FOLD, 10, 0)]
    # the vertex of the parabola through points 9, 10 and 11 (unit arc length apart): beyond both
    assert mon.bifurcations[0].omega > max(omega[10], omega[11])


# -- the choice of a point ------------------------------------------------------------------
def test_choose_point_takes_no_point_without_a_verdict_for_stable_or_least_unstable(monkeypatch):
    # five points by decreasing amplitude, the candidates near the peak 0, 2 and 4: 0 with ARPACK
    # short of its unstable multiplier (which read as stable), 2 stable (|mu| 0.5), 4 unstable
    H, _ = mathieu(8)
    monkeypatch.setattr(spla, "eigs", short_eigs(without_unstable(H)))
    partial = spm.arnoldi_spectrum(H)
    specs = {0: partial, 2: spec_of([0.5, 0.3]), 4: spec_of([-1.5, 0.3])}
    monkeypatch.setattr(selection, "orbit_spectrum", lambda residual, x, w, **k: (specs[int(round(x[0]))], 1))
    args = (None, OMEGA - np.arange(5.0), np.arange(5.0)[:, None] * np.ones((1, 3)), 1e-3 * np.arange(5.0, 0.0, -1.0),
            np.ones(5, bool))
    ch = selection.choose_point(*args, n_candidates=3)
    assert (ch.index, ch.stable, ch.n_unstable, ch.n_analyses) == (2, True, 0, 2)
    assert ch.multiplier == pytest.approx(0.5)
    # no stable one: the least unstable of those with a verdict (|mu| 1.2), not the undecided one
    specs[2] = spec_of([-1.2, 0.3])
    ch = selection.choose_point(*args, n_candidates=3)
    assert (ch.index, ch.stable, ch.n_unstable, ch.n_analyses) == (2, False, 1, 3)
    assert ch.multiplier == pytest.approx(1.2) and ", 1 without a verdict:" in ch.reason
    # none with a verdict: the first, said to be unknown
    specs.update({2: partial, 4: empty()})
    ch = selection.choose_point(*args, n_candidates=3)
    assert (ch.index, ch.stable, ch.n_unstable) == (0, False, -1) and np.isnan(ch.multiplier)
    assert ch.reason.startswith("no analysis of the 3 candidates near the peak gave a verdict (ARPACK converged")


def test_a_period_doubling_is_located_between_the_verdicts_around_a_point_without_one(monkeypatch):
    # stable up to point 4, a multiplier -1.05 from point 6 on, no verdict at 5: the scan
    # brackets (4, 6), not (5, 6) with 5 read as stable
    mus = {i: ([0.5, 0.3] if i < 5 else [-1.05, 0.3]) for i in range(11)}
    specs = {i: empty() if i == 5 else spec_of(mus[i]) for i in mus}
    monkeypatch.setattr(selection, "orbit_spectrum", lambda residual, x, w, **k: (specs[int(round(x[0]))], 1))
    x = np.arange(11.0)[:, None] * np.ones((1, 3))
    res = selection.locate_period_doubling(None, OMEGA - np.arange(11.0), x, 1e-4 * np.arange(11.0),
                                           np.ones(11, bool))
    b = res.bifurcation
    assert (b.kind, b.index, b.direction) == (PERIOD_DOUBLING, 4, 1)
    assert b.omega_bracket == (OMEGA - 4, OMEGA - 6)
    assert res.index == 6 and res.bracket == (6, 4)



def test_an_arnoldi_window_that_bounds_nothing_is_no_verdict():
    """The Mathieu tongue beside two slow, overdamped dof (x'' + 10 x' + x = 0: exponents near
    -0.1): the two Hill eigenvalues nearest 0 are theirs, within omega / 2 of 0, so the window
    bounds nothing (modulus_floor 1) and the unstable multiplier -1.934 (shooting, and the
    dense spectrum) lies outside it. Two eigenvalues give no verdict, and the widened window
    (the monitor's min_ceiling 1) finds the unstable one, where both used to call it stable."""
    from hbm.harmonic.fourier import FourierBasis
    from hbm.stability.hill import HillOperator

    w, eps, z = 2.0, 0.9, 0.01
    T = 2 * np.pi / w
    wt = eps * np.cos(w * np.arange(32) * T / 32)
    H = HillOperator(K=np.eye(3), M=np.eye(3), C=np.diag([2 * z, 10.0, 10.0]), omega=w, basis=FourierBasis(8, 32),
                     nodes=np.array([0]), weights=wt[None, None], sigma=np.ones(17), g_eps=1.0, g_z=0.0,
                     nl=np.arange(3))
    shoot = mathieu(8)[1][0]  # the same Mathieu dof: -1.934
    assert spm.dense_spectrum(H).n_unstable == 1
    two = spm.arnoldi_spectrum(H, n_eig=2)
    assert two.modulus_floor == 1.0 and np.all(np.abs(two.multipliers) < 1.0)
    assert not two.decided and not two.stable and two.n_unstable == -1
    assert "window bounds no multiplier" in two.undecided_reason
    wide = spm.widened_spectrum(H, n_eig=2, min_ceiling=1.0)
    assert wide.decided and wide.n_unstable == 1
    assert wide.multipliers[0].real == pytest.approx(shoot, rel=1e-6)
