"""The isola search (hbm.isolas.search) on a small system with a known isola.

The system: x'' + c(x) x' + x = F cos(Omega t), c(x) = c1 - c3 x^2 + c5 x^4 (dimensionless
time): a damping that falls, then rises again with amplitude (Habib et al., "Isolated
resonances and nonlinear damping", Nonlinear Dyn. 2018). Its one-harmonic balance, x = a
cos + b sin, has the equivalent damping c_eq(A) = c1 - c3 A^2 / 4 + c5 A^4 / 8 and the
amplitude relation A^2 [(1 - Omega^2)^2 + Omega^2 c_eq(A)^2] = F^2. With F below the local
maximum of A c_eq(A), a second, isolated family of large-amplitude solutions exists near
Omega = 1, a closed curve in (Omega, A) that never meets the primary curve. It is checked
here independently of the search: by the polynomial roots of the amplitude relation, and
by time integration (scipy) from rest (lands on the primary) and from the isola's upper
point (stays there).
"""
from __future__ import annotations

import os
import re
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import scipy.integrate as si

from hbm.continuation.arclength import ContinuationOptions, continue_branch
from hbm.continuation.newton import NewtonOptions
from hbm.isolas.membership import KnownBranch
from hbm.isolas.options import IsolaOptions
from hbm.isolas.search import ON_KNOWN, SearchOptions, Seed, search
from hbm.linalg.dense import DirectSolver
from support import mpirun_command, needs_mpirun

C1, C3, C5, F = 0.1, 0.18, 0.045, 0.05
W_MIN, W_MAX = 0.8, 1.2


class Oscillator:
    """The one-harmonic HB residual R(x, omega), x = (a, b), forcing amplitude `force`.
    Picklable (module level)."""

    def __init__(self, force: float = F):
        self.force = force

    def __call__(self, x, w, jacobian=True):
        F = self.force
        a, b = x
        A2 = a * a + b * b
        c = C1 - C3 * A2 / 4 + C5 * A2 * A2 / 8
        dc = -C3 / 4 + C5 * A2 / 4  # dc / d(A^2)
        s = 1.0 - w * w
        R = np.array([s * a + w * c * b - F, s * b - w * c * a])
        if not jacobian:
            return R
        J = np.array([[s + w * b * dc * 2 * a, w * c + w * b * dc * 2 * b],
                      [-w * c - w * a * dc * 2 * a, s - w * a * dc * 2 * b]])
        dw = np.array([-2 * w * a + c * b, -2 * w * b - c * a])
        return R, J, dw


def factory():
    return Oscillator(), DirectSolver()


def amplitudes(w: float, F: float = F) -> np.ndarray:
    """Every amplitude A > 0 of the one-harmonic balance at omega: real positive roots u =
    A^2 of the quintic u [(1 - w^2)^2 + w^2 c_eq(u)^2] - F^2 (c_eq(u) = C1 - C3 u / 4 + C5 u^2 / 8)."""
    ceq = np.polynomial.Polynomial([C1, -C3 / 4, C5 / 8])
    p = np.polynomial.Polynomial([0, 1]) * ((1 - w * w) ** 2 + w * w * ceq ** 2) - F * F
    r = p.roots()
    u = np.sort(r[(abs(r.imag) < 1e-9) & (r.real > 0)].real)
    return np.sqrt(u)


def isola_range(n=4001, F: float = F):
    """Omega range of the large-amplitude family (more than one root), from a fine grid."""
    w = np.linspace(W_MIN, W_MAX, n)
    multi = np.array([len(amplitudes(x, F)) > 1 for x in w])
    return w[multi].min(), w[multi].max()


def continuation():
    return ContinuationOptions(omega_min=W_MIN, omega_max=W_MAX, ds=0.02, ds_min=1e-6, ds_max=0.1, x_scale=1.0,
                               omega_scale=0.1, max_points=2000, closed_loop_tol=1e-3,
                               newton=NewtonOptions(tol_residual=1e-10, max_iter=12), crawl_points=50)


def options(workers=1):
    return SearchOptions(tolerance=1e-2, continuation=continuation(),
                         newton=NewtonOptions(tol_residual=1e-10, max_iter=20, line_search=True), workers=workers)


def modal_seeds():
    """Eq. (31)-type seeds, told nothing of the isola: A cos(Omega t) over an amplitude and
    an omega grid spanning the range."""
    return [Seed(w, np.array([a, 0.0]), f"modal k=1 A={a:.2g}")
            for w in np.linspace(W_MIN, W_MAX, 41) for a in (0.1, 0.3, 1.0, 3.0)]


@pytest.fixture(scope="module")
def primary():
    br = continue_branch(Oscillator(), np.array([F / (1 - W_MIN ** 2), 0.0]), W_MIN, continuation())
    assert br.status.startswith("reached omega_max")
    return KnownBranch.of(br.omega, br.x, "primary", br.converged)


def test_the_isola_exists_independently_of_the_search():
    # three amplitudes at Omega = 1: the primary's and the isola's two
    A = amplitudes(1.0)
    assert len(A) == 3 and A[0] < 0.95 < A[1]
    # time integration: from rest to the primary, from the isola's upper point it stays
    def rhs(t, y):
        x, v = y
        return [v, F * np.cos(t) - (C1 - C3 * x * x + C5 * x ** 4) * v - x]

    T = 2 * np.pi
    for x0, expect in ((0.0, A[0]), (A[2], A[2])):
        sol = si.solve_ivp(rhs, (0, 100 * T), [x0, 0.0], t_eval=np.linspace(95 * T, 100 * T, 2001), rtol=1e-8,
                           atol=1e-10)
        amp = 0.5 * (sol.y[0].max() - sol.y[0].min())
        assert amp == pytest.approx(expect, rel=0.05)  # one harmonic vs the exact orbit


def turns(omega, x):
    """A describe for the search: the per-point amplitude, and a table of the points where
    Omega turns back (the isola's two folds), its index counting the points given."""
    i = np.flatnonzero((omega[1:-1] - omega[:-2]) * (omega[2:] - omega[1:-1]) < 0) + 1
    return {"amplitude": np.hypot(x[:, 0], x[:, 1]), "tables": {"turns": {"index": (i, "-"), "omega": (omega[i], "1")}}}


def test_the_search_finds_the_isola_once(primary):
    res = search(factory, modal_seeds(), [primary], options(workers=2), describe=turns)
    isolas = [b for b in res.branches if b.kind == "isola"]
    assert len(isolas) == 1, [(b.kind, b.status) for b in res.branches]
    b = isolas[0]
    assert b.closed
    assert all(k.kind != "primary" for k in res.branches)
    ok = b.converged
    A = np.hypot(b.x[ok, 0], b.x[ok, 1])
    # every point solves the amplitude relation: one of the large roots at its omega
    for w, a in zip(b.omega[ok], A):
        roots = amplitudes(w)
        assert np.min(np.abs(roots[1:] - a)) < 1e-6 * max(a, 1)
    lo, hi = isola_range()
    assert b.omega[ok].min() == pytest.approx(lo, abs=2e-4)
    assert b.omega[ok].max() == pytest.approx(hi, abs=2e-4)
    assert A.max() == pytest.approx(amplitudes(1.0)[2], rel=0.02)
    # describe's per-point data and its table, indexed on the branch's points: two turns, at
    # the isola's ends
    assert np.allclose(b.extras["amplitude"][ok], A)
    t = b.extras["tables"]["turns"]
    assert sorted(b.omega[t["index"][0]]) == pytest.approx([lo, hi], abs=2e-4)
    assert np.array_equal(b.omega[t["index"][0]], t["omega"][0])
    # seeds: some land on the primary, some on the isola, none elsewhere
    assert (res.seed_branch == ON_KNOWN).any()
    idx = res.branches.index(b)
    assert (res.seed_branch == idx).sum() >= 2
    assert set(res.seed_branch) <= {-1, ON_KNOWN, idx}


#: Just below the force at which the isola merges with the primary (between 0.0607 and
#: 0.06075 on a 5e-5 grid of F): the isola's lower half passes 0.047 from the primary.
F_NEAR = 0.0607


def near_factory():
    return Oscillator(F_NEAR), DirectSolver()


def solutions(w: float, F: float = F) -> np.ndarray:
    """(a, b) of every one-harmonic solution at omega w, (m, 2): each amplitude of
    `amplitudes` fixes c_eq, and the balance is then linear in (a, b)."""
    out = []
    for A in amplitudes(w, F):
        c, s = C1 - C3 * A * A / 4 + C5 * A ** 4 / 8, 1.0 - w * w
        out.append(np.linalg.solve([[s, w * c], [-w * c, s]], [F, 0.0]))
    return np.array(out)


def test_an_isola_just_apart_from_the_primary_stays_an_isola_at_the_default_tolerance():
    """The search's resolution: with the scene's membership tolerance ([isolas] tolerance,
    1e-2 in the scaled unknowns), an isola 0.047 from the primary is found as a closed
    isola, where a tolerance of twice that gap makes it meet the primary. The steps
    (ds_max = 0.01) stay under the gap: with this module's ds_max = 0.1 the primary's own
    continuation jumps onto the isola there."""
    gap = min(np.linalg.norm(x[1] - x[0]) for w in np.linspace(0.98, 1.02, 4001)
              if len(x := solutions(w, F_NEAR)) == 3)  # primary to the isola's lower half, same Omega
    assert gap == pytest.approx(0.0468, abs=1e-3)
    fine = replace(continuation(), ds=0.005, ds_max=0.01, max_points=20000)
    br = continue_branch(Oscillator(F_NEAR), np.array([F_NEAR / (1 - W_MIN ** 2), 0.0]), W_MIN, fine)
    assert br.status.startswith("reached omega_max") and np.all(np.diff(br.omega) > 0)  # no turn: the primary only
    known = [KnownBranch.of(br.omega, br.x, "primary", br.converged)]

    def run(tolerance):
        return search(near_factory, modal_seeds(), known,
                      SearchOptions(tolerance=tolerance, continuation=fine,
                                    newton=NewtonOptions(tol_residual=1e-10, max_iter=20, line_search=True), workers=1))

    res = run(IsolaOptions().tolerance)
    assert [(b.kind, b.closed) for b in res.branches] == [("isola", True)], [b.status for b in res.branches]
    lo, hi = isola_range(F=F_NEAR)
    ok = res.branches[0].converged
    assert res.branches[0].omega[ok].min() == pytest.approx(lo, abs=2e-4)
    assert res.branches[0].omega[ok].max() == pytest.approx(hi, abs=2e-4)
    wide = run(2 * gap)  # the isola's lower half is "on" the primary
    assert [(b.kind, b.closed) for b in wide.branches] == [("bifurcated", False)], [b.status for b in wide.branches]


class Pair:
    """Two uncoupled copies of the oscillator, x = (a1, b1, a2, b2). Swapping them is a
    symmetry (`images`, like the casing's lobes for the blade): (primary, isola) and
    (isola, primary) are then one branch. Picklable."""

    def __init__(self, symmetric: bool):
        self.symmetric = symmetric

    def __call__(self, x, w, jacobian=True):
        o = Oscillator()
        if not jacobian:
            return np.r_[o(x[:2], w, False), o(x[2:], w, False)]
        (r1, j1, d1), (r2, j2, d2) = o(x[:2], w), o(x[2:], w)
        J = np.zeros((4, 4))
        J[:2, :2], J[2:, 2:] = j1, j2
        return np.r_[r1, r2], J, np.r_[d1, d2]

    def images(self, x):
        return [np.r_[x[2:], x[:2]]] if self.symmetric else []


def pair_factory():
    return Pair(True), DirectSolver()


def pair_factory_plain():
    return Pair(False), DirectSolver()


def test_a_branch_and_its_image_are_one_branch():
    # at Omega = 1 (a = 0): b c_eq(b^2) = F, the primary's root and the isola's upper one
    A = amplitudes(1.0)
    p, q = (0.0, A[0]), (0.0, A[2])
    seeds = [Seed(1.0, np.r_[p, q], "(primary, isola)"), Seed(1.0, np.r_[q, p], "(isola, primary) at 1"),
             Seed(0.995, np.r_[q, p], "(isola, primary) at 0.995")]
    x0 = F / (1 - W_MIN ** 2)
    br = continue_branch(Pair(True), np.array([x0, 0.0, x0, 0.0]), W_MIN, continuation())
    known = [KnownBranch.of(br.omega, br.x, "primary", br.converged)]
    # without the symmetry: two closed branches, mirror images of each other
    plain = search(pair_factory_plain, seeds, known, options())
    assert [b.kind for b in plain.branches] == ["isola", "isola"] and all(b.closed for b in plain.branches)
    a, b = plain.branches
    np.testing.assert_allclose(np.sort(a.omega), np.sort(b.omega), atol=1e-9)
    # with it: one, owning the three seeds (the second is its image at the same Omega, the
    # third lies on its image)
    res = search(pair_factory, seeds, known, options())
    assert len(res.branches) == 1 and res.branches[0].closed and res.n_continued == 1
    assert list(res.seed_branch) == [0, 0, 0]
    lo, hi = isola_range()
    assert res.branches[0].omega.min() == pytest.approx(lo, abs=2e-4)
    assert res.branches[0].omega.max() == pytest.approx(hi, abs=2e-4)


def test_an_interrupted_search_resumes_without_recomputing(primary):
    seeds = modal_seeds()
    # without the primary as known branch the search finds two: the primary and the isola
    full = search(factory, seeds, [], options())
    assert len(full.branches) == 2 and full.n_continued == 2
    saved = {}

    def stop(i, branch):
        saved.setdefault("branches", []).append(branch)
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        search(factory, seeds, [], options(), on_corrections=lambda c: saved.update(corrections=c), on_branch=stop)
    assert len(saved["branches"]) == 1
    again = search(factory, seeds, [], options(), corrections=saved["corrections"], branches=saved["branches"])
    assert again.n_continued == 1  # the first branch is kept, not recomputed
    assert again.n_points_computed == full.branches[1].n_points_computed
    assert [b.kind for b in again.branches] == [b.kind for b in full.branches]
    for a, b in zip(again.branches, full.branches):
        np.testing.assert_allclose(a.omega, b.omega)
        np.testing.assert_allclose(a.x, b.x)
        assert a.seeds == b.seeds
    np.testing.assert_array_equal(again.seed_branch, full.seed_branch)


@pytest.mark.parametrize("third", [1, 2])
def test_a_search_interrupted_after_merges_resumes_to_the_uninterrupted_result(third):
    """Short halves (15 points) make later seeds merge into branches found before, or lie on
    them: those seeds are saved with their branch as they join it, so a search interrupted
    after them continues none of them again and ends with the uninterrupted result."""

    opts = options()
    opts = replace(opts, continuation=replace(opts.continuation, max_points=15))
    seeds = modal_seeds()
    full = search(factory, seeds, [], opts)
    n_cand = len(full.corrections.candidates())
    assert full.n_continued > len(full.branches) + 5  # many merges
    cut = third * n_cand // 3
    saved = {"branches": {}}

    def stop(phase, done, total):
        if phase == "branches" and done == cut:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        search(factory, seeds, [], opts, on_corrections=lambda c: saved.update(corrections=c),
               on_branch=lambda i, b: saved["branches"].__setitem__(i, b), on_progress=stop)
    done = [saved["branches"][k] for k in range(len(saved["branches"]))]
    again = search(factory, seeds, [], opts, corrections=saved["corrections"], branches=done)
    np.testing.assert_array_equal(again.seed_branch, full.seed_branch)
    assert [(b.kind, b.seeds, b.n_points_computed) for b in again.branches] == \
        [(b.kind, b.seeds, b.n_points_computed) for b in full.branches]
    # every candidate the first run went through is on disk with its branch: none is tried again
    assert {int(i) for i in full.corrections.candidates()[:cut]} <= {sd for b in done for sd in b.seeds}
    assert again.n_continued < full.n_continued


def _primary_solution(w):
    """The primary curve's solution at w, from the one-harmonic balance's smallest amplitude."""
    from hbm.continuation.newton import newton_solve

    return newton_solve(Oscillator(), np.array([amplitudes(w)[0], 0.0]), w).x


def test_a_branch_merging_into_a_known_branch_other_than_the_primary_is_bifurcated(primary):
    """Known: the primary and a piece of the isola (as the period-doubled search knows the
    first search's branches); a seed on the isola's lower sheet runs into the piece at both
    ends. With only the first known branch the primary, it is not called primary."""

    a = amplitudes(1.0)
    piece = continue_branch(Oscillator(), np.array([0.0, a[2]]), 1.0, replace(continuation(), max_points=25))
    isola_piece = KnownBranch.of(piece.omega, piece.x, "an isola", piece.converged)
    seed = [Seed(1.0, np.array([0.0, a[1]]), "lower sheet")]
    res = search(factory, seed, [primary, isola_piece], options(), primaries=1)
    (b,) = res.branches
    assert "met known branch 1 (an isola)" in b.status and b.kind == "bifurcated"
    assert search(factory, seed, [primary, isola_piece], options()).branches[0].kind == "primary"  # all primaries


def test_a_branch_found_before_becomes_primary_when_a_later_one_links_it_to_the_primary():
    """The known primary is cut at 0.95; seed A (1.15) continues a piece of the primary curve
    that ends on the step cap short of it; seed B (1.0) runs into the known primary one way
    and into A's branch the other: A's branch is then connected to the primary."""

    prim = continue_branch(Oscillator(), np.array([F / (1 - W_MIN ** 2), 0.0]), W_MIN, continuation())
    keep = prim.converged & (prim.omega <= 0.95)
    known = KnownBranch.of(prim.omega[keep], prim.x[keep], "primary")
    seeds = [Seed(1.15, _primary_solution(1.15), "A"), Seed(1.0, _primary_solution(1.0), "B")]
    opts = options()
    opts = replace(opts, continuation=replace(opts.continuation, max_points=12))
    alone = search(factory, seeds[:1], [known], opts)
    assert [b.kind for b in alone.branches] == ["detached"]
    res = search(factory, seeds, [known], opts)
    (b,) = res.branches
    assert b.seeds == (0, 1) and b.kind == "primary" and "joined by the branch from seed 1: primary" in b.status


def test_a_join_is_measured_on_the_segment_it_lies_on():
    """The half branch runs along the known polyline's first segment, past its middle, the
    nearest vertex being that of the turn: merging, not crossing."""
    from types import SimpleNamespace

    from hbm.isolas.membership import nearest_on_polyline
    from hbm.isolas.search import _parallel

    b = KnownBranch.of([0.0, 1.0, 1.0], [[0.0], [0.0], [1.0]], "known")
    pts = [SimpleNamespace(x=np.array([0.0]), omega=0.8), SimpleNamespace(x=np.array([0.0]), omega=0.9)]
    d, xn, wn, _ = nearest_on_polyline(pts[-1].x, pts[-1].omega, b)
    opts = SimpleNamespace(x_scale=1.0, omega_scale=1.0)
    assert d == 0.0 and _parallel(pts, b, xn, wn, opts)
    turn = [SimpleNamespace(x=np.array([0.1]), omega=1.0), SimpleNamespace(x=np.array([0.2]), omega=1.0)]
    assert not _parallel(turn, b, np.array([0.0]), 0.9, opts)  # across the first segment


def test_a_primary_nfrc_with_no_converged_point_is_a_branch_nothing_lies_on():
    from hbm.isolas.membership import polyline_distance

    b = KnownBranch.of([2000.0, 1999.0], np.ones((2, 6)), "primary", converged=[False, False])
    assert b.x.shape == (0, 6)
    assert polyline_distance(np.zeros(6), 1990.0, b)[0] == np.inf


#: the third speed of modal_seeds' grid, where _killed kills its worker
KILLED_AT = float(np.linspace(W_MIN, W_MAX, 41)[2])


def _killed(items):
    """The seeds' worker task (hbm.isolas.search._run_worker), but the worker correcting the
    seeds at KILLED_AT is killed (SIGKILL: the OOM killer's signal)."""
    import signal

    from hbm.isolas.search import _timed, _WORKER

    if items[0][1] == KILLED_AT:
        os.kill(os.getpid(), signal.SIGKILL)
    return _timed(_WORKER["corrector"], items)


def _killed_half(*args, **kwargs):
    """A half branch's task (hbm.isolas.search._run_half), but its worker is killed."""
    import signal

    os.kill(os.getpid(), signal.SIGKILL)


def test_a_killed_worker_fails_the_search_with_a_line_that_names_its_seeds(primary, monkeypatch):
    """Python's BrokenProcessPool names nothing and the CLI shows a traceback for it; the
    search raises hbm.processes.WorkerDied, which the CLI prints as its one line, naming
    the speeds whose seeds were being corrected (the killed one, and at most the other
    worker's)."""
    import hbm.isolas.search as search_module
    from hbm.processes import WorkerDied

    monkeypatch.setattr(search_module, "_run_worker", _killed)
    with pytest.raises(WorkerDied, match="a worker process of the isola search ended without an answer") as e:
        search(factory, modal_seeds(), [primary], options(workers=2))
    head, _, named = str(e.value).partition("; seeds being corrected at ")
    assert head.endswith("(killed, perhaps for lack of memory)") and named.endswith(" rad/s")
    speeds = [float(w) for w in named[:-len(" rad/s")].split(", ")]
    assert any(w == pytest.approx(KILLED_AT, rel=1e-5) for w in speeds) and len(speeds) <= 2


def test_a_worker_killed_while_continuing_a_branch_names_the_branch(primary, monkeypatch):
    """In the continuation phase the message names the seed whose branch was being continued."""
    import hbm.isolas.search as search_module
    from hbm.processes import WorkerDied

    monkeypatch.setattr(search_module, "_run_half", _killed_half)
    seeds = modal_seeds()
    with pytest.raises(WorkerDied, match=r"ended without an answer \(killed, perhaps for lack of memory\); "
                                         r"branch being continued: from seed (\d+) at (\S+) rad/s$") as e:
        search(factory, seeds, [primary], options(workers=2))
    i, w = re.search(r"from seed (\d+) at (\S+) rad/s", str(e.value)).groups()
    assert float(w) == pytest.approx(seeds[int(i)].omega, rel=1e-5)
    assert W_MIN <= float(w) <= W_MAX


def test_a_search_in_this_process_leaves_the_blas_threads_as_it_found_them(primary):
    """With one worker the seeds are corrected in the caller's process on one BLAS thread,
    as in a pool's worker; the limit must end with the search, or whatever the process
    computes next (a ROM, the validation stage of the same run) has other round-off."""
    from threadpoolctl import threadpool_info, threadpool_limits

    def blas_threads():
        return sorted({p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"})

    with threadpool_limits(limits=2, user_api="blas"):  # two even on a one-core machine
        assert blas_threads() == [2]
        res = search(factory, modal_seeds(), [primary], options(workers=1))
        assert res.corrections.converged.any()
        assert blas_threads() == [2]


@needs_mpirun
def test_mpi_search_equals_the_serial_one(tmp_path, primary):
    """`mpirun -n 2` shares the seeds' omegas between the ranks (allgather) and continues the
    branches on rank 0: the same corrections, seed verdicts and branches as one process,
    to the bit (the same seeds solved by the same code, whichever rank solved them)."""
    import mpi4py  # noqa: F401  (installed with python3-dolfinx; a missing one must fail, not skip)
    out = tmp_path / "mpi.npz"
    cmd, env = mpirun_command(Path(__file__).resolve().parents[2])
    run = subprocess.run(cmd + [sys.executable, str(Path(__file__).with_name("mpi_isolas.py")), str(out)],
                         env=env, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stdout + run.stderr
    got = np.load(out)
    assert list(got["ranks"]) == [2, 2]
    serial = search(factory, modal_seeds(), [primary], options(workers=1))
    c = serial.corrections
    np.testing.assert_array_equal(got["converged"], c.converged)
    np.testing.assert_array_equal(got["x"], c.x)
    np.testing.assert_array_equal(got["on_known"], c.on_known)
    np.testing.assert_array_equal(got["same_as"], c.same_as)
    np.testing.assert_array_equal(got["seed_branch"], serial.seed_branch)
    assert list(got["kinds"]) == [b.kind for b in serial.branches] and "isola" in list(got["kinds"])
    for k, b in enumerate(serial.branches):
        np.testing.assert_array_equal(got[f"omega_{k}"], b.omega)
        np.testing.assert_array_equal(got[f"bx_{k}"], b.x)


@needs_mpirun
def test_a_failing_rank_ends_the_mpi_search_on_every_rank(tmp_path):
    """A seed correction that raises on one rank raises there and as RankFailed naming it on
    the other, which would otherwise wait for it forever where the ranks gather their
    corrections (the timeout turns such a hang into a failure)."""
    cmd, env = mpirun_command(Path(__file__).resolve().parents[2])
    run = subprocess.run(cmd + [sys.executable, str(Path(__file__).with_name("mpi_isolas.py")),
                                str(tmp_path / "mpi.npz"), "fail"], env=env, capture_output=True, text=True,
                         timeout=300)
    assert run.returncode != 0
    out = run.stdout  # (mpirun forwards each rank's lines as they come: they may run together)
    why = "FloatingPointError: a seed's correction failed on rank 1 for the test"
    assert out.count(" raised ") == 2, out + run.stderr
    assert f"rank 0 raised RankFailed: rank 1 failed in the isola search's seed corrections: {why}" in out, \
        out + run.stderr
    assert f"rank 1 raised {why}" in out, out + run.stderr


def test_the_polyline_distance_is_the_minimum_along_every_segment():
    """Against a bounded scalar minimisation of the distance along every segment. With within=w the
    distance is the same whenever it is <= w (only segments near omega are measured) and
    never claims a distance <= w that is not there."""
    from scipy.optimize import minimize_scalar

    from hbm.isolas.membership import polyline_distance

    rng = np.random.default_rng(3)
    n, m = 5, 25
    omega = np.cumsum(rng.uniform(-0.2, 1.0, m))  # turns back in omega now and then
    x = np.cumsum(rng.standard_normal((m, n)), axis=0)
    b = KnownBranch.of(omega, x, "zig-zag")
    xs, ws = np.array([1.0, 2.0, 0.5, 1.0, 3.0]), 0.5
    checked = {"near": 0, "far": 0}
    for _ in range(60):
        i = rng.integers(m - 1)
        f = rng.uniform()
        q = x[i] + f * (x[i + 1] - x[i]) + rng.normal(scale=rng.choice([1e-3, 0.3, 3.0]), size=n)
        w = omega[i] + f * (omega[i + 1] - omega[i]) + rng.normal(scale=0.3)
        best = min(minimize_scalar(lambda s: np.hypot(np.linalg.norm((x[j] + s * (x[j + 1] - x[j]) - q) / xs),
                                                      (omega[j] + s * (omega[j + 1] - omega[j]) - w) / ws),
                                   bounds=(0.0, 1.0), method="bounded", options={"xatol": 1e-10}).fun
                   for j in range(m - 1))
        d, xn, wn = polyline_distance(q, w, b, xs, ws)
        assert d == pytest.approx(best, rel=1e-8, abs=1e-12)
        assert np.hypot(np.linalg.norm((xn - q) / xs), (wn - w) / ws) == pytest.approx(d, rel=1e-12)
        for tol in (1e-2, 0.5, 2.0):
            dw = polyline_distance(q, w, b, xs, ws, within=tol)[0]
            if best <= tol:
                assert dw == d
                checked["near"] += 1
            else:
                assert dw > tol
                checked["far"] += 1
    assert checked["near"] > 20 and checked["far"] > 20


def test_describe_tables_are_indexed_on_the_branch_points():
    from hbm.isolas.search import _reindexed

    # the branch's first point failed: the described points are 1, 2, 3, 5 of it
    t = _reindexed({"b": {"index": (np.array([0, 3]), "-"), "omega": (np.array([1.0, 2.0]), "rad/s")}},
                   np.array([1, 2, 3, 5]))
    assert t["b"]["index"][0].tolist() == [1, 5] and t["b"]["omega"][0].tolist() == [1.0, 2.0]


def test_a_branch_described_in_two_chunks_is_described_as_a_whole():
    """The search describes long branches on its two processes (hbm.isolas.search._Description):
    per-point data and tables (re-indexed) as from one call, even with a turn in Omega at
    the middle of the points (the split moves off it)."""
    import concurrent.futures

    from hbm.isolas.search import _Description

    s = np.linspace(0.0, 1.0, 101)
    omega = 1.0 + 0.2 * np.sin(2 * np.pi * s * 1.5 + np.pi / 2 - 1.5 * np.pi)  # turns at points 33 and 67
    omega[50] = omega[49] + 0.5 * (omega[51] - omega[49])
    omega[51] = omega[50]  # a flat step at the middle: no strict monotony there
    x = np.column_stack([np.cos(7 * s), np.sin(7 * s)])
    whole, _ = _Description(turns, omega, x).result()
    assert len(whole["tables"]["turns"]["index"][0]) >= 2
    with concurrent.futures.ThreadPoolExecutor(2) as pool:
        parts, _ = _Description(turns, omega, x, pool).result()
    np.testing.assert_array_equal(parts["amplitude"], whole["amplitude"])
    for c in ("index", "omega"):
        np.testing.assert_array_equal(parts["tables"]["turns"][c][0], whole["tables"]["turns"][c][0])


def scheduled(omega, x):
    """A describe that, like the stability monitor, works on every third point from where
    it starts and fills the others in: its result depends on where a chunk starts."""
    analysed = np.arange(len(omega)) % 3 == 0
    return {"analysed": analysed, "value": np.where(analysed, x[:, 0], np.nan)}


def test_a_branch_is_described_alike_with_any_number_of_workers():
    """isolas.h5 does not depend on [isolas] workers (not in its inputs hash): the chunks are
    the same with two processes and with one."""
    import concurrent.futures

    from hbm.isolas.search import _Description

    s = np.linspace(0.0, 1.0, 101)
    omega, x = 1.0 + 0.1 * s, np.column_stack([np.cos(7 * s), np.sin(7 * s)])
    alone, _ = _Description(scheduled, omega, x).result()
    with concurrent.futures.ProcessPoolExecutor(2) as pool:
        two, _ = _Description(scheduled, omega, x, pool).result()
    np.testing.assert_array_equal(two["analysed"], alone["analysed"])
    np.testing.assert_array_equal(two["value"], alone["value"])
    assert not np.array_equal(alone["analysed"], scheduled(omega, x)["analysed"])  # chunked, not whole


def test_the_describers_keep_a_bounded_number_of_residuals(monkeypatch):
    """A process keeps the residuals of the last few BranchDescribers only (each holds its
    ROM's matrices): six describers used in turn build six residuals, keep four, and the
    first, used again after the others, builds its residual again."""
    from hbm.isolas import harmonic

    monkeypatch.setattr(harmonic, "_RESIDUALS", {})
    monkeypatch.setattr(harmonic, "describe", lambda res, *a: lambda omega, u: {"residual": res})
    built = []

    def factory(k):
        def problem():
            built.append(k)
            return (f"residual {k}", None)
        return problem

    describers = [harmonic.BranchDescriber(factory(k)) for k in range(6)]
    for d in describers:
        d(np.zeros(1), np.zeros((1, 2)))
    assert built == list(range(6)) and len(harmonic._RESIDUALS) == harmonic._MAX_RESIDUALS == 4
    assert describers[5](np.zeros(1), np.zeros((1, 2))) == {"residual": "residual 5"}
    assert built == list(range(6))  # kept: not built again
    assert describers[0](np.zeros(1), np.zeros((1, 2))) == {"residual": "residual 0"}
    assert built == list(range(6)) + [0] and len(harmonic._RESIDUALS) == 4
    # 0 took the place of the least recently used, 2 (3 and 4 came after it, then 5 again)
    assert [r for r, _ in harmonic._RESIDUALS.values()] == ["residual 3", "residual 4", "residual 5", "residual 0"]


def test_the_branches_are_the_same_with_one_worker_and_with_two(primary):
    """The halves of a branch run at the same time, on two processes or on two threads of
    one taking turns, and stop at the first point where either meets the other: where they
    meet depends only on their points, not on which half computed faster. The isola's
    halves meet; every branch is the same to the bit either way."""
    serial = search(factory, modal_seeds(), [primary], options(workers=1))
    two = search(factory, modal_seeds(), [primary], options(workers=2))
    assert [b.kind for b in two.branches] == [b.kind for b in serial.branches]
    (isola,) = [b for b in serial.branches if b.kind == "isola"]
    assert isola.closed and isola.status == "+: closed loop (the halves met); -: closed loop (the halves met)"
    for a, b in zip(serial.branches, two.branches):
        assert a.status == b.status
        np.testing.assert_array_equal(a.omega, b.omega)
        np.testing.assert_array_equal(a.x, b.x)
    assert serial.n_points_computed == two.n_points_computed


def timed_describe(omega, x):
    """A describe that takes a while and says when it ran (s since the epoch)."""
    import time

    t0 = time.time()
    time.sleep(0.6)
    return {"started": np.full(len(omega), t0), "ended": np.full(len(omega), time.time()),
            "value": x[:, 0].copy()}


def test_branches_are_described_while_the_search_goes_on_and_saved_once_described():
    """With two workers a branch's description runs on its own processes while the search
    corrects and continues the next candidates (progress reported meanwhile); each branch
    reaches on_branch only once described, first in index order; and the branches, their
    descriptions included, are those of one worker, where everything runs in turn."""
    import time

    seeds = modal_seeds()
    serial = search(factory, seeds, [], options(workers=1), describe=timed_describe)
    progress_at = []
    calls = []

    def paced(phase, d, t):  # the candidates at 0.1 s each (they take ~1 ms): the pool's start-up is not raced
        progress_at.append((phase, d, time.time()))
        if phase == "branches":
            time.sleep(0.1)

    two = search(factory, seeds, [], options(workers=2), describe=timed_describe,
                 on_branch=lambda i, b: calls.append((i, "value" in b.extras)), on_progress=paced)
    assert len(two.branches) == len(serial.branches) == 2
    for a, b in zip(serial.branches, two.branches):
        np.testing.assert_array_equal(a.omega, b.omega)
        np.testing.assert_array_equal(a.extras["value"], b.extras["value"])
        assert a.seeds == b.seeds and a.kind == b.kind
    # one worker: the first branch was described before the search went on
    first = two.branches[0].extras
    started, ended = np.nanmin(first["started"]), np.nanmax(first["ended"])
    during = [d for phase, d, t in progress_at if phase == "branches" and started < t < ended]
    assert during, "no candidate was handled while the first branch was described"
    assert all(has for _, has in calls)
    firsts = [i for n, (i, _) in enumerate(calls) if i not in [j for j, _ in calls[:n]]]
    assert firsts == sorted(firsts) == list(range(len(two.branches)))


def isola_slowly(omega, x):
    """Slow (4 s) on the isola only (amplitudes above 1.3; the primary's stay below 0.6)."""
    if np.hypot(x[:, 0], x[:, 1]).min() > 1.0:
        import time

        time.sleep(4.0)
    return {"value": x[:, 0].copy()}


def test_a_search_interrupted_while_describing_resumes_to_the_uninterrupted_result():
    """An interrupt while a branch is being described (the isola, the second found) keeps on
    disk the branches described before it, whole, and not it; the resumed search continues
    and describes it again, and ends with the uninterrupted result."""
    import time

    seeds = modal_seeds()
    full = search(factory, seeds, [], options(workers=2), describe=isola_slowly)
    assert [b.kind for b in full.branches] == ["detached", "isola"]
    after_isola = list(full.corrections.candidates()).index(full.branches[1].start) + 1
    saved = {"branches": {}}

    def stop(phase, done, total):  # a candidate after the isola's, the first branch saved, the isola being described
        if phase == "branches" and done >= after_isola and saved["branches"]:
            raise KeyboardInterrupt
        if phase == "branches":  # the candidates at 0.1 s each: 2.3 s after the isola's, under its description
            time.sleep(0.1)

    with pytest.raises(KeyboardInterrupt):
        search(factory, seeds, [], options(workers=2), describe=isola_slowly,
               on_corrections=lambda c: saved.update(corrections=c),
               on_branch=lambda i, b: saved["branches"].__setitem__(i, b), on_progress=stop)
    assert sorted(saved["branches"]) == [0]
    done = [saved["branches"][0]]
    np.testing.assert_array_equal(done[0].extras["value"], full.branches[0].extras["value"])
    again = search(factory, seeds, [], options(workers=2), corrections=saved["corrections"], branches=done,
                   describe=isola_slowly)
    assert again.n_continued == 1
    np.testing.assert_array_equal(again.seed_branch, full.seed_branch)
    assert [(b.kind, b.seeds) for b in again.branches] == [(b.kind, b.seeds) for b in full.branches]
    for a, b in zip(again.branches, full.branches):
        np.testing.assert_array_equal(a.extras["value"], b.extras["value"])
