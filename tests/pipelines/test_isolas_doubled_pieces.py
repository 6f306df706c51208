"""The period-doubled search's classification of branches born at a period doubling
(pipelines.stages.isolas._born_at_doublings) reaches every record of a branch: two pieces
that a later branch linked (their statuses say "one branch with branch k") are one branch,
and when one is found to pass through a period doubling, both are bifurcated."""
from types import SimpleNamespace

import numpy as np

import hbm.isolas.harmonic as harmonic
from hbm.isolas.search import FoundBranch, IsolaSearch
from pipelines.stages import isolas as stage


def _branch(status, w0):
    w = np.linspace(w0, w0 + 10.0, 4)
    extras = {"le_amplitude": np.full(4, 1e-3), "harmonics": np.zeros((4, 3, 3))}
    return FoundBranch(omega=w, x=np.zeros((4, 3)), converged=np.ones(4, bool), kind="isola", closed=False,
                       status=status, start=0, seeds=(0,), extras=extras)


def _result(branches):
    return IsolaSearch(seeds=(), corrections=None, branches=tuple(branches), seed_branch=np.zeros(0, int),
                       n_continued=len(branches), n_points_computed=0, cpu_time=0.0, wall_time=0.0)


def test_a_piece_linked_to_a_branch_born_at_a_doubling_is_bifurcated_too(monkeypatch):
    a = _branch("+: point cap; -: point cap; one branch with branch 1 (linked by the branch from seed 5)", 100.0)
    b = _branch("+: point cap; -: point cap; one branch with branch 0 (linked by the branch from seed 5)", 200.0)
    c = _branch("+: point cap; -: point cap", 300.0)
    # only the second piece passes through a period doubling of known branch 0, at 205 rad/s
    monkeypatch.setattr(harmonic, "doubling_origin",
                        lambda res, pd_res, solver, fb, known, options: (0, 205.0) if fb.omega[0] == 200.0 else None)
    res = SimpleNamespace(options=SimpleNamespace(tolerance=1e-2))
    known = [SimpleNamespace(label="the primary NFRC")]
    lines = []
    out = stage._born_at_doublings(_result([a, b, c]), res, None, known, None, SimpleNamespace(log=lines.append))
    assert [f.kind for f in out.branches] == ["bifurcated", "bifurcated", "isola"]
    assert "born at a period doubling of the primary NFRC near 205.0 rad/s" in out.branches[1].status
    assert "one branch with a branch born at a period doubling" in out.branches[0].status
    assert out.kind_counts() == {"bifurcated": 1, "isola": 1}
    # the log says so after the search's own line, which counted them before this test
    assert lines == ["    doubled branch 001: a period doubling of the primary NFRC near 205.0 rad/s: bifurcated",
                     "    branches by kind, the doublings above included: 1 bifurcated, 1 isola"]


def test_a_branch_bifurcated_for_leaving_the_symmetry_still_gets_its_doubling_named(monkeypatch):
    """A doubled branch the search called bifurcated because it merges into the primary without
    its symmetry (hbm.isolas.search.LEAVES_SYMMETRY; before, such a branch was "primary") is
    still tested for the doubling it was born at, and the status names it; one bifurcated by
    a crossing is not tested again."""
    from dataclasses import replace

    from hbm.isolas.search import LEAVES_SYMMETRY

    left = replace(_branch(f"+: met known branch 0 (primary); -: point cap; {LEAVES_SYMMETRY} (up to 0.3)", 200.0),
                   kind="bifurcated")
    crossed = replace(_branch("+: met known branch 1 (another); -: point cap", 300.0), kind="bifurcated")
    asked = []

    def origin(res, pd_res, solver, fb, known, options):
        asked.append(fb.omega[0])
        return 0, 205.0

    monkeypatch.setattr(harmonic, "doubling_origin", origin)
    res = SimpleNamespace(options=SimpleNamespace(tolerance=1e-2))
    out = stage._born_at_doublings(_result([left, crossed]), res, None, [SimpleNamespace(label="the primary NFRC")],
                                   None)
    assert asked == [200.0]
    assert [f.kind for f in out.branches] == ["bifurcated", "bifurcated"]
    assert "born at a period doubling of the primary NFRC near 205.0 rad/s" in out.branches[0].status
    assert "born at" not in out.branches[1].status


def test_the_file_names_the_other_records_of_a_branch_in_its_own_numbering(tmp_path):
    """Statuses name linked pieces in their search's numbering, which the file shifts for
    the doubled search's branches (after the first search's three): `linked` holds the file's
    indices, read back by read_isolas."""
    import h5py

    first = _result([_branch("one branch with branch 1 (linked by the branch from seed 5)", 100.0),
                     _branch("one branch with branch 0 (linked by the branch from seed 5)", 200.0),
                     _branch("+: point cap", 300.0)])
    second = _result([_branch("+: point cap", 400.0),
                      _branch("one branch with branch 2 (linked by the branch from seed 1)", 500.0),
                      _branch("one branch with branch 1 (linked by the branch from seed 1)", 600.0)])
    linked = stage._linked([(first, None), (second, None)])
    assert linked == [(1,), (0,), (), (), (5,), (4,)]
    path = tmp_path / "isolas.h5"
    with h5py.File(path, "w") as h5:
        g = h5.create_group("dlft/branches")
        for k, fb in enumerate(first.branches + second.branches):
            stage._write_branch(g.create_group(f"{k:03d}"), fb, 1, linked=linked[k])
    rows = stage.read_isolas(path)["dlft"]
    assert [r.linked.tolist() for r in rows] == [[1], [0], [], [], [5], [4]]
