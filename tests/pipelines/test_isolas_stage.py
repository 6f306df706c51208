"""Stage isolas end to end on the coarse ROM, with a tiny seed grid (coarse_runs.SHORT).

`bladerub run --until isolas` on a clone of the short NFRCs: runs the sweep (the seeds from
its periodic points) and the search, writes isolas.h5 in the documented layout; a second
run reuses it; an interrupted search resumes from isolas.partial.h5.
"""
import os

import h5py
import numpy as np
import pytest

from coarse_runs import clone
from pipelines import artifacts as art
from pipelines.cli import main
from pipelines.progress import Progress
from pipelines.runner import run_scene
from pipelines.scene import load_scene, parse_scene
from pipelines.stages.isolas import read_isolas


@pytest.fixture(scope="module")
def searched(coarse_nfrc, tmp_path_factory):
    scene0, base = coarse_nfrc
    out = tmp_path_factory.mktemp("isolas")
    scene = clone(base, out, copy=("nfrc_dlft.h5", "nfrc_rl.h5"))
    assert main(["run", str(scene), "--out", str(out), "--until", "isolas", "--quiet"]) == 0
    return scene, out


def test_layout(searched):
    scene, out = searched
    path = out / "isolas.h5"
    assert art.verify(path) is None  # checksums hold (fixed-length origins)
    attrs = art.read_attrs(path)
    assert attrs["stage"] == "isolas" and attrs["inputs_hash"]
    with h5py.File(path) as h5:
        assert set(h5) == {"dlft", "rl"}
        for method in ("dlft", "rl"):
            g = h5[method]
            for k in ("n_seeds", "n_converged", "n_distinct", "n_branches", "cpu_time", "wall_time", "status"):
                assert k in g.attrs, k
            s = g["seeds"]
            n = int(g.attrs["n_seeds"])
            # DLFT: the 2 modal seeds and those around the primary; RL: DLFT's solutions of them;
            # plus the sweep's periodic points
            assert n >= 1
            for k in ("omega", "origin", "converged", "branch"):
                assert s[k].shape == (n,), k
            origins = [o.decode() for o in s["origin"][()]]
            if method == "dlft":
                assert origins.count("modal j=1 k=2 A=0.001") == 2
            else:  # RL's modal seeds: DLFT's converged ones (hbm.isolas.harmonic.rl_seeds)
                modal = [o for o in origins if o.startswith("modal")]
                d = h5["dlft"]["seeds"]
                done = {o.decode() + " via DLFT" for o, c in zip(d["origin"][()], d["converged"][()]) if c}
                assert modal and set(modal) <= done
            assert int(s["converged"][()].sum()) == int(g.attrs["n_converged"])
            # every seed says how Newton ended: "" and ||R|| within the NFRC's tolerance where
            # it converged; a reason that names the seed's speed and ||R|| over it where not
            conv, rn = s["converged"][()], s["residual_norm"][()]
            why = [w.decode() for w in s["reason"][()]]
            tol = load_scene(scene).hbm.tolerance
            assert s["iterations"].shape == rn.shape == (n,) and len(why) == n
            assert all(w == "" for w, c in zip(why, conv) if c) and (rn[conv] <= tol).all()
            for w, r, om in zip(np.array(why)[~conv], rn[~conv], s["omega"][()][~conv]):
                assert f" at omega={om:.6g}" in w and (r > tol or "non-finite" in w or "within tolerance" in w), (w, r)
            br = s["branch"][()]
            assert ((br >= -2) & (br < int(g.attrs["n_branches"]))).all()
            assert (br[~s["converged"][()]] == -1).all()
            assert len(g["branches"]) == int(g.attrs["n_branches"])
    # DLFT: the 2 modal seeds at 1900 and 2000 rad/s, 0.24 mm of 2nd harmonic of 1B, both
    # converge on the primary NFRC and are recognised as such (RL's stiff penalty takes
    # neither within the seeds' Newton budget); so do the same shape added to the primary's
    # point at each speed (the NFRC starts at 2000 rad/s and passes 1900 once): the family
    # around the primary is built in the residual's unknowns
    found = read_isolas(path)
    with h5py.File(path) as h5:
        s = h5["dlft"]["seeds"]
        origins = [o.decode() for o in s["origin"][()]]
        modal = [i for i, o in enumerate(origins) if o.startswith("modal")]
        assert [origins[i] for i in modal] == ["modal j=1 k=2 A=0.001",
                                               "modal j=1 k=2 A=0.001 + primary DLFT NFRC 1/1"] * 2
        assert np.array_equal(s["omega"][()][modal], [1900.0, 1900.0, 2000.0, 2000.0])
        conv, br = s["converged"][()][modal], s["branch"][()][modal]
        assert conv.all() and (br == -2).all(), (conv, br)
        for method in ("dlft", "rl"):
            assert len(found[method]) == int(h5[method].attrs["n_branches"])


def test_the_sweep_keeps_the_boundary_state_and_seeds_from_it(searched):
    """ti.h5 keeps every boundary dof over the last two revolutions (the LE radial one is
    the last two revolutions of the LE signal), one seed per periodic speed, and DLFT's
    Newton from those states lands on the primary NFRC (the only solution there)."""
    from pipelines.stages.ti import read_sweep

    _, out = searched
    sw = read_sweep(out)
    assert sw.boundary.shape == (4, 128, 27)  # 4 speeds, 2 revolutions of 64 samples, 3 x 9 dof
    np.testing.assert_array_equal(sw.boundary[:, :, 0], sw.displacement[:, -128:, 0])
    np.testing.assert_array_equal(sw.boundary[:, :, -3], sw.displacement[:, -128:, 1])  # TE radial
    with h5py.File(out / "isolas.h5") as h5:
        s = h5["dlft"]["seeds"]
        ti = np.array([o.decode().startswith("ti class") for o in s["origin"][()]])
        periodic = np.isin(sw.period_class, (0, 1)).sum()
        assert ti.sum() == periodic  # one seed per periodic speed (the short sweep of 20 revolutions has none)
        assert s["converged"][()][ti].all() and (s["branch"][()][ti] == -2).all()


def test_branch_layout(searched):
    """Whatever branches were found carry the documented datasets and attributes."""
    _, out = searched
    with h5py.File(out / "isolas.h5") as h5:
        for method in ("dlft", "rl"):
            for name, b in h5[method]["branches"].items():
                m = len(b["omega"])
                assert b["x"].shape[0] == m and b["converged"].shape == (m,)
                assert b["harmonics"].shape[:2] == (m, 11)  # 2 N_h + 1, N_h = 5
                assert b.attrs["kind"] in ("primary", "isola", "bifurcated", "detached")
                assert b.attrs["subharmonic"] == 1
                # [isolas] harmonic_checks (default 3): points of the branch solved again with
                # 2 N_h = 10, inside its longest monotone stretch; the verdict follows them
                t = b["harmonic_checks"]
                k = len(t["index"])
                assert 1 <= k <= 6 and all(t[c].shape == (k,) for c in
                                           ("omega", "passed", "moved", "n_harmonics", "cpu_time", "reason"))
                idx = t["index"][()]
                np.testing.assert_array_equal(t["omega"][()], b["omega"][()][idx])
                assert (t["n_harmonics"][()] == 10).all() and b["converged"][()][idx].all()
                passed = t["passed"][()]
                verdict = b.attrs["harmonic_check"]
                assert verdict == ("converged" if passed.all() else "not converged" if not passed.any()
                                   else "partly converged"), (verdict, passed)
                assert (t["moved"][()][passed] <= 0.25).all()
                # eq. (33)'s contributions, computed with the branch (describe): they sum to 1
                # at each converged point; a point not converged has none
                mc, conv = b["modal_contribution"][()], b["converged"][()].astype(bool)
                assert mc.shape == (m, 39) and b["harmonic_contribution"].shape == (m, 6)
                np.testing.assert_allclose(mc[conv].sum(axis=1), 1.0, rtol=1e-12)
                assert np.isnan(mc[~conv]).all() and (mc[conv] >= 0).all()
                np.testing.assert_array_equal(b["modes/frequencies"].shape, (39,))
                # each contact node's share of the period in contact (hbm.isolas.harmonic.
                # contact_fraction), on the AFT grid of N_t = 1024 samples
                cf = b["contact_fraction"][()]
                assert cf.shape == (m, 9) and np.isnan(cf[~conv]).all()
                assert ((cf[conv] >= 0) & (cf[conv] <= 1)).all()
                np.testing.assert_allclose(cf[conv] * 1024, np.round(cf[conv] * 1024), atol=1e-9)


def test_a_second_run_reuses_it(searched):
    scene, out = searched
    before = (out / "isolas.h5").stat().st_mtime_ns
    progress = Progress(quiet=True)
    run_scene(load_scene(scene), out, until="isolas", progress=progress)
    rec = {r.stage: r.action for r in progress.records}
    assert rec["isolas"] == "reused"
    assert (out / "isolas.h5").stat().st_mtime_ns == before


def test_the_partial_file_gives_back_what_was_finished(tmp_path):
    """What isolas.partial.h5 keeps of an interrupted search is what the resume reads back."""
    from hbm.isolas.search import Corrections, FoundBranch
    from pipelines.stages.isolas import _Partial

    c = Corrections(converged=np.array([True, False, True]), iterations=np.array([3, 5, 4]),
                    on_known=np.array([-1, -1, 0]), same_as=np.array([-1, -1, -1]),
                    x=np.array([[1.0, 2.0], [np.nan, np.nan], [3.0, 4.0]]), cpu_time=1.5,
                    residual_norm=np.array([1e-9, 2.5e-3, 3e-9]),
                    reason=("", "no convergence in 5 iterations at omega=1000 (||R||=2.500e-03 > 1.0e-08)", ""))
    fb = FoundBranch(omega=np.array([1.0, 1.1]), x=np.array([[1.0, 2.0], [1.1, 2.1]]), converged=np.array([True, True]),
                     kind="isola", closed=True, status="+: closed loop", start=0, seeds=(0,),
                     extras={"le_amplitude": np.array([1e-4, 2e-4]), "harmonics": np.zeros((2, 3, 2)),
                             "stable": np.array([True, False]),
                             "n_unstable": np.array([0, 1]), "stability_analysed": np.array([True, True]),
                             "stability_widened": np.array([False, True]), "stability_cpu_time": np.array([0.1, 0.7]),
                             "leading_multipliers": np.array([[0.9, 0.5, 0.1, 0.1], [1.2, 0.9, 0.5, 0.1]]),
                             "period_ratio": np.array([2, 2]),
                             "tables": {"bifurcations": {"kind": (np.array(["period doubling"], dtype=object), "-"),
                                                         "omega": (np.array([1.05]), "rad/s"),
                                                         "index": (np.array([0]), "-")},
                                        "harmonic_checks": {"index": (np.array([1]), "-"),
                                                            "omega": (np.array([1.1]), "rad/s"),
                                                            "passed": (np.array([False]), "-"),
                                                            "moved": (np.array([np.nan]), "1"),
                                                            "reason": (np.array(["no solution"], dtype=object), "-")}}},
                     n_points_computed=2, cpu_time=0.5)
    p = _Partial(tmp_path / "isolas.partial.h5", "hash-a")
    assert p.spent("dlft") == 0.0  # nothing on disk: a search that starts now
    p.corrections("dlft", c, wall=12.0)
    assert p.spent("dlft") == 12.0
    p.branch("dlft", 0, fb, 1, wall=30.5)
    p.corrections("rl", c, wall=40.0)
    p.branch("rl", 0, fb, 1)  # no wall given: what is on disk stays
    p.branch("rl", 1, fb, 1, wall=55.0)
    # a resumed search's wall time starts from what the interrupted runs spent
    assert (p.spent("dlft"), p.spent("rl")) == (30.5, 55.0)
    assert _Partial(tmp_path / "isolas.partial.h5", "hash-b").spent("dlft") == 0.0  # other inputs
    # what an interrupted run says it kept
    assert art.read_attrs(tmp_path / "isolas.partial.h5")["n_branches"] == 3
    c2, done = p.resume("dlft")
    np.testing.assert_array_equal(c2.candidates(), [0])
    assert c2.reason == c.reason  # why a seed failed survives the resume
    np.testing.assert_array_equal(c2.residual_norm, c.residual_norm)
    np.testing.assert_array_equal(c2.x[0], [1.0, 2.0])
    assert len(done) == 1 and done[0].kind == "isola" and done[0].seeds == (0,) and done[0].closed
    np.testing.assert_array_equal(done[0].x, fb.x)
    for k in ("stable", "n_unstable", "stability_analysed", "stability_widened", "stability_cpu_time",
              "leading_multipliers", "period_ratio"):
        np.testing.assert_array_equal(done[0].extras[k], fb.extras[k])
    t = done[0].extras["tables"]["bifurcations"]
    assert list(t["kind"][0]) == ["period doubling"] and t["omega"] == (1.05, "rad/s") and t["index"][0] == [0]
    # the final file carries the same table, read back with the branch
    from pipelines.stages.isolas import _write_branch, read_isolas

    with h5py.File(tmp_path / "isolas.h5", "w") as h5:
        _write_branch(h5.create_group("dlft/branches/000"), done[0], 1)
    b = read_isolas(tmp_path / "isolas.h5")["dlft"][0]
    assert list(b.bifurcations["kind"]) == ["period doubling"] and b.bifurcations["omega"][0] == 1.05
    # and the harmonic check's table, with its verdict (the one point checked failed)
    assert list(b.harmonic_checks["reason"]) == ["no solution"] and b.harmonic_verdict == "not converged"
    np.testing.assert_array_equal(b.stable, [True, False])
    assert len(p.resume("rl")[1]) == 2
    # an earlier branch saved again with the seeds that joined it keeps the later ones
    from dataclasses import replace

    with h5py.File(tmp_path / "isolas.partial.h5", "r") as h5:
        offset = h5["rl/branches/000/x"].id.get_offset()
    p.branch("rl", 0, replace(fb, seeds=(0, 2), kind="primary", status="+: closed loop; joined"), 1)
    done = p.resume("rl")[1]
    assert [b.seeds for b in done] == [(0, 2), (0,)]
    assert (done[0].kind, done[0].status) == ("primary", "+: closed loop; joined")
    np.testing.assert_array_equal(done[0].x, fb.x)
    assert art.read_attrs(tmp_path / "isolas.partial.h5")["n_branches"] == 3
    with h5py.File(tmp_path / "isolas.partial.h5", "r") as h5:  # its points were not written again
        assert h5["rl/branches/000/x"].id.get_offset() == offset
    assert _Partial(tmp_path / "isolas.partial.h5", "hash-b").resume("dlft") == (None, [])  # other inputs
    # in folders copied with hard links (cp -al), a search resumed or started over writes its
    # own file, never through the link into the original's
    before = (tmp_path / "isolas.partial.h5").read_bytes()
    for name, inputs_hash in (("resumed", "hash-a"), ("started over", "hash-b")):
        (tmp_path / name).mkdir()
        os.link(tmp_path / "isolas.partial.h5", tmp_path / name / "isolas.partial.h5")
        q = _Partial(tmp_path / name / "isolas.partial.h5", inputs_hash)
        q.corrections("dlft", c)
        q.branch("dlft", 1, fb, 1)
        assert art.read_attrs(tmp_path / name / "isolas.partial.h5")["inputs_hash"] == inputs_hash
    assert (tmp_path / "isolas.partial.h5").read_bytes() == before


def test_every_mpi_rank_goes_past_a_ti_h5_without_boundary_states(tmp_path, monkeypatch):
    """A ti.h5 of an older version has no boundary states: rank 0 warns and every rank goes
    on without the sweep's seeds (rank 1 used to read the missing array's shape). The fake
    context stops each rank at the next thing it lacks, the output's hash."""
    from types import SimpleNamespace

    import pipelines.parallel as parallel
    import pipelines.stages.isolas as stage
    import pipelines.stages.ti as ti

    class Comm:
        rank, size = 0, 2

        def bcast(self, obj, root=0):
            return obj

    monkeypatch.setattr(parallel, "world", lambda: Comm())
    monkeypatch.setattr(stage, "read_rom", lambda out: "rom")
    monkeypatch.setattr(ti, "read_sweep", lambda out: SimpleNamespace(boundary=None))
    (tmp_path / "ti.h5").write_bytes(b"")
    for rank in (0, 1):
        Comm.rank = rank
        warned = []
        ctx = SimpleNamespace(scene=parse_scene(""), out=tmp_path, progress=SimpleNamespace(warn=warned.append))
        with pytest.raises(AttributeError, match="hashes"):
            stage._compute(ctx, None)
        assert len(warned) == (1 if rank == 0 else 0)


def test_the_log_counts_seed_failures_by_kind():
    """The run's log line counts Newton's reasons by kind, the point left out of each."""
    from hbm.continuation.newton import NewtonOptions, newton_solve
    from pipelines.stages.isolas import failure_counts

    def flat(x, omega, jacobian=True):  # R = 1 everywhere: Newton's step is singular
        R = np.ones(1)
        return R if not jacobian else (R, np.zeros((1, 1)), np.zeros(1))

    def slow(x, omega, jacobian=True):  # R = x^2 + 1: no root, ||R|| stalls at 1
        R = np.array([x[0] ** 2 + 1.0])
        return R if not jacobian else (R, np.array([[2.0 * x[0]]]), np.zeros(1))

    reasons = ["", newton_solve(flat, np.zeros(1), 400.0).reason,
               newton_solve(slow, np.array([3.0]), 440.0, NewtonOptions(max_iter=5)).reason,
               newton_solve(slow, np.array([2.0]), 450.0, NewtonOptions(max_iter=5)).reason,
               newton_solve(slow, np.array([3.0]), 460.0, NewtonOptions(max_iter=30, stall_iterations=3)).reason]
    assert failure_counts(reasons) == {"singular Jacobian": 1, "no convergence in 5 iterations": 2, "stalled": 1}, reasons


def test_seed_failures_follow_the_merged_order():
    """isolas.h5's seeds/ lists the first search's seeds, then the period-doubled one's: their
    iterations, ||R|| and reasons in that order; a part resumed from a partial file of an
    earlier version (no reasons) says "unknown" where a seed failed."""
    from types import SimpleNamespace

    from hbm.isolas.search import Corrections
    from pipelines.stages.isolas import _seed_failures

    first = Corrections(np.array([True, False]), np.array([4, 60]), np.full(2, -1), np.full(2, -1), np.zeros((2, 1)),
                        residual_norm=np.array([1e-9, 0.34]),
                        reason=("", "no convergence in 60 iterations at omega=440 (||R||=3.4e-01 > 1.0e-08)"))
    resumed = Corrections(np.array([False, True]), np.array([3, 7]), np.full(2, -1), np.full(2, -1), np.zeros((2, 1)))
    parts = [(SimpleNamespace(corrections=first), None), (SimpleNamespace(corrections=resumed), None)]
    its, rn, why = _seed_failures(parts)
    np.testing.assert_array_equal(its, [4, 60, 3, 7])
    np.testing.assert_array_equal(rn[:2], [1e-9, 0.34])
    assert np.isnan(rn[2:]).all()
    assert why == ["", first.reason[1], "unknown", ""]


def test_the_log_names_the_nodes_a_branch_never_lets_go():
    """A branch whose converged points all hold a node in contact over the whole period is
    named with that node, as the friction lock where mu >= the ROM's mu_set (the validation
    stage's words for a march's permanent contact); a node in contact at only some points, or
    at a point that did not converge, is not."""
    from types import SimpleNamespace

    from pipelines.stages.isolas import locked_text

    f = np.full((3, 9), 0.25)
    f[:, 6] = 1.0
    f[:2, 7] = 1.0  # the third point lets node 7 go
    f[2, 8], f[:2, 8] = 0.5, 1.0  # node 8 held only at the two converged points
    rom = SimpleNamespace(friction_lock=SimpleNamespace(mu_set=0.123))
    conv = np.array([True, True, False])
    assert locked_text(f, conv, 0.15, rom) == \
        ", nodes 6, 7, 8 never leave the casing (the friction lock: mu = 0.15 >= mu_set = 0.123)"
    assert locked_text(f, np.ones(3, bool), 0.1, rom) == ", node 6 never leaves the casing"
    assert locked_text(np.full((3, 9), 0.99), conv, 0.15, rom) == ""
    assert locked_text(None, conv, 0.15, rom) == "" and locked_text(f, np.zeros(3, bool), 0.15, rom) == ""
    assert locked_text(f, conv, 0.15, SimpleNamespace()) == ", nodes 6, 7, 8 never leave the casing"


def test_fig_8_draws_a_branch_the_lock_holds_as_the_friction_lock(searched):
    """Fig. 8 calls a branch "friction lock" where every converged point holds a node on the
    casing and mu >= mu_set, as the log does; below mu_set, or with a node let go at one
    point, the branch keeps its kind (a doubled one: period-doubled). The stored fractions
    come back with the branches (read_isolas)."""
    from types import SimpleNamespace

    import h5py

    from pipelines.stages.isolas import IsolaBranch
    from pipelines.stages.validation import drawn_kind

    _, out = searched
    with h5py.File(out / "isolas.h5") as h5:
        for method, branches in read_isolas(out / "isolas.h5").items():
            for b in branches:
                np.testing.assert_array_equal(b.contact_fraction,
                                              h5[f"{method}/branches/{b.name}/contact_fraction"][()])
    f = np.full((3, 9), 0.3)
    f[:, 7] = 1.0
    conv = np.ones(3, bool)
    common = dict(method="dlft", index=0, closed=False, status="", seeds=np.zeros(0, int), omega=np.ones(3),
                  x=np.zeros((3, 1)), converged=conv, le_amplitude=np.ones(3), harmonics=np.zeros((3, 1, 1)))
    held = IsolaBranch(kind="detached", subharmonic=1, contact_fraction=f, **common)
    doubled = IsolaBranch(kind="isola", subharmonic=2, contact_fraction=f, **common)
    g = f.copy()
    g[1, 7] = 0.9
    let_go = IsolaBranch(kind="detached", subharmonic=1, contact_fraction=g, **common)
    rom = SimpleNamespace(friction_lock=SimpleNamespace(mu_set=0.123))
    assert held.locked_nodes.tolist() == [7] and let_go.locked_nodes.tolist() == []
    assert drawn_kind(held, 1, 0.15, rom) == "friction lock" == drawn_kind(doubled, 1, 0.15, rom)
    assert drawn_kind(held, 1, 0.1, rom) == "detached" and drawn_kind(doubled, 1, 0.1, rom) == "period-doubled"
    assert drawn_kind(let_go, 1, 0.15, rom) == "detached" and drawn_kind(held, 1, 0.15, None) == "detached"
