"""Incremental HDF5 branch files: round trip, partial files, interrupted appends."""
from __future__ import annotations

import h5py
import numpy as np
import pytest

from pipelines.branch_store import BranchStore, load_branch, partial_path
from hbm.continuation.branch import ContinuationPoint

ATTRS = {"units": "{length: m, angular_speed: rad/s}", "scene": "[hbm]\nn_harmonics = 40  # ω, é\n",
         "code_version": "0.1.0+abc123", "inputs_hash": "f" * 64, "method": "dlft",
         "metadata": {"epsilon": 1e7, "nodes": [1, 2, 3]}}


def make_points(m=7, n=5, seed=0):
    rng = np.random.default_rng(seed)
    return [ContinuationPoint(i, float(rng.random()), rng.standard_normal(n), i < m - 1, float(rng.random()),
                              int(rng.integers(0, 9)), float(rng.random()), float(rng.random())) for i in range(m)]


def extras_of(p):
    return {"le_amplitude": p.omega * 2.0, "tip_radial": p.x[:3] * 10.0, "n_contact": np.int32(p.iterations)}


def write(path, points, finalize=True):
    store = BranchStore.create(path, points[0].x.size, attrs=ATTRS)
    for p in points:
        store.append(p, extras_of(p))
    if finalize:
        return store.finalize("closed loop", "d_int=1e-3")
    store.close()


def test_round_trip_is_identical(tmp_path):
    pts = make_points()
    out = write(tmp_path / "nfrc_dlft.h5", pts)
    assert out == tmp_path / "nfrc_dlft.h5" and out.is_file() and not partial_path(out).exists()
    s = load_branch(out)
    assert s.complete and s.branch.status == "closed loop" and s.branch.detail == "d_int=1e-3"
    b = s.branch
    np.testing.assert_array_equal(b.omega, [p.omega for p in pts])
    np.testing.assert_array_equal(b.x, np.array([p.x for p in pts]))
    np.testing.assert_array_equal(b.converged, [p.converged for p in pts])
    np.testing.assert_array_equal(b.residual_norm, [p.residual_norm for p in pts])
    np.testing.assert_array_equal(b.iterations, [p.iterations for p in pts])
    np.testing.assert_array_equal(b.step, [p.step for p in pts])
    np.testing.assert_array_equal(b.time, [p.time for p in pts])
    assert b.converged.dtype == bool and b.iterations.dtype == np.int64
    for name in ("le_amplitude", "tip_radial", "n_contact"):
        np.testing.assert_array_equal(s.extras[name], np.array([extras_of(p)[name] for p in pts]))
    assert s.extras["n_contact"].dtype == np.int32 and s.extras["tip_radial"].shape == (len(pts), 3)
    for k in ("units", "scene", "code_version", "inputs_hash", "method"):
        assert s.attrs[k] == ATTRS[k]
    assert s.attrs["metadata"] == '{"epsilon": 10000000.0, "nodes": [1, 2, 3]}'
    with h5py.File(out, "r") as h5:
        assert h5["omega"].attrs["unit"] == "rad/s" and h5["time"].attrs["unit"] == "s"


def test_partial_file_is_never_taken_as_complete(tmp_path):
    path = tmp_path / "nfrc.h5"
    pts = make_points()
    write(path, pts[:4], finalize=False)
    assert not path.exists() and partial_path(path).is_file()
    with pytest.raises(FileNotFoundError, match="partial"):
        load_branch(path)
    with pytest.raises(ValueError, match="not a complete"):
        load_branch(partial_path(path))
    s = load_branch(path, allow_partial=True)
    assert not s.complete and len(s.branch) == 4 and s.branch.status == ""
    # A partial file copied to the final name is still not complete (its flag says so).
    partial_path(path).rename(path)
    with pytest.raises(ValueError, match="not a complete"):
        load_branch(path)


def test_points_survive_an_interruption_and_reopen_continues(tmp_path):
    path = tmp_path / "nfrc.h5"
    pts = make_points(m=9)
    with pytest.raises(KeyboardInterrupt):
        with BranchStore.create(path, 5, attrs=ATTRS) as store:
            for p in pts:
                store.append(p, extras_of(p))
                if p.index == 4:
                    raise KeyboardInterrupt
    # Simulate a crash in the middle of the next append: rows written, count not updated.
    with h5py.File(partial_path(path), "r+") as h5:
        h5["omega"].resize(6, axis=0)
        h5["omega"][5] = 123.0
    s = load_branch(path, allow_partial=True)
    assert len(s.branch) == 5 and s.extras["le_amplitude"].shape == (5,)
    np.testing.assert_array_equal(s.branch.omega, [p.omega for p in pts[:5]])

    store = BranchStore.reopen(path, keep=4)  # drop the last point, as a resume that redoes it would
    for p in pts[4:]:
        store.append(p, extras_of(p))
    store.finalize("reached omega_max")
    s = load_branch(path)
    assert s.complete and s.branch.status == "reached omega_max"
    np.testing.assert_array_equal(s.branch.omega, [p.omega for p in pts])
    np.testing.assert_array_equal(s.extras["tip_radial"], [extras_of(p)["tip_radial"] for p in pts])


def test_extras_must_stay_aligned(tmp_path):
    pts = make_points()
    store = BranchStore.create(tmp_path / "b.h5", 5)
    store.append(pts[0], {"a": 1.0})
    with pytest.raises(ValueError, match="extras"):
        store.append(pts[1], {"b": 1.0})
    with pytest.raises(ValueError, match="shape"):
        store.append(pts[1], {"a": [1.0, 2.0]})
    with pytest.raises(ValueError, match="unknowns"):
        store.append(pts[1]._replace(x=np.zeros(4)), {"a": 1.0})
    store.close()
    with pytest.raises(ValueError, match="reserved"):
        BranchStore.create(tmp_path / "c.h5", 5, attrs={"complete": 1})


def test_a_resume_takes_extras_its_earlier_points_lack(tmp_path):
    """A partial file written by an earlier version (no 'cpu', 'widened', 'count' extras) is
    resumed by a run that records them: the earlier rows say 'not recorded' (NaN, False,
    -1), the dataset says from which row it holds values, and the file finishes."""
    path = tmp_path / "nfrc.h5"
    pts = make_points(m=6)
    with BranchStore.create(path, 5, attrs=ATTRS, units={"a": "m"}) as store:
        for p in pts[:3]:
            store.append(p, {"a": float(p.index)})
    store = BranchStore.reopen(path, units={"a": "m", "cpu": "s"})
    for p in pts[3:]:
        store.append(p, {"a": float(p.index), "cpu": 0.5, "widened": True, "count": 2})
    store.finalize("reached omega_max")
    s = load_branch(path)
    assert s.complete and len(s.branch) == 6
    np.testing.assert_array_equal(s.extras["a"], np.arange(6.0))
    np.testing.assert_array_equal(s.extras["cpu"], [np.nan] * 3 + [0.5] * 3)
    np.testing.assert_array_equal(s.extras["widened"], [False] * 3 + [True] * 3)
    np.testing.assert_array_equal(s.extras["count"], [-1] * 3 + [2] * 3)
    with h5py.File(path) as h5:
        assert h5["extras/cpu"].attrs["recorded_from"] == 3 and h5["extras/cpu"].attrs["unit"] == "s"
        assert h5["extras/a"].attrs["unit"] == "m"
    # a store that wrote its own first point still refuses a change of extras
    store = BranchStore.create(tmp_path / "c.h5", 5)
    store.append(pts[0], {"a": 1.0})
    with pytest.raises(ValueError, match="extras"):
        store.append(pts[1], {"a": 1.0, "b": 2.0})
    store.close()


def two_run_folders(tmp_path):
    """(a, b, pts): folders a and b, a holding the partial file of an NFRC interrupted after 3
    of the 6 points pts (what a copy of a, b, links to)."""
    a, b = tmp_path / "a", tmp_path / "b"
    a.mkdir()
    b.mkdir()
    pts = make_points(m=6)
    with BranchStore.create(a / "nfrc.h5", 5, attrs=ATTRS) as store:
        for p in pts[:3]:
            store.append(p, extras_of(p))
    return a, b, pts


def test_a_partial_file_shared_by_hard_links_is_never_written_through(tmp_path):
    """A folder copied with `cp -al` shares its partial files with the original: resuming in
    the copy, or starting over there, leaves the original's points as they were."""
    import os

    a, b, pts = two_run_folders(tmp_path)
    os.link(partial_path(a / "nfrc.h5"), partial_path(b / "nfrc.h5"))
    original = partial_path(a / "nfrc.h5").read_bytes()

    store = BranchStore.reopen(b / "nfrc.h5", keep=2)  # the copy resumes
    for p in pts[2:]:
        store.append(p, extras_of(p))
    store.finalize("reached omega_max")
    assert len(load_branch(b / "nfrc.h5").branch) == 6
    assert partial_path(a / "nfrc.h5").read_bytes() == original
    assert len(load_branch(a / "nfrc.h5", allow_partial=True).branch) == 3

    os.link(partial_path(a / "nfrc.h5"), tmp_path / "c.partial.h5")
    BranchStore.create(tmp_path / "c.h5", 5, attrs=ATTRS).close()  # starts over: replaced, not truncated
    assert partial_path(a / "nfrc.h5").read_bytes() == original
