"""pipelines.branch_store: a run killed inside `finalize`, after the complete flag was written
but before the rename, leaves NAME.partial.h5 flagged complete. It is still a partial file (a
file is complete only under its final name), so the next run resumes from its points instead
of refusing it (the hbm stage would then compute the whole NFRC again)."""
from unittest import mock

import numpy as np

import pipelines.branch_store as bs
from hbm.continuation.branch import ContinuationPoint
from pipelines.artifacts import verify


def _point(i):
    return ContinuationPoint(index=i, omega=400.0 + i, x=np.array([i, 2.0 * i]), converged=True,
                             residual_norm=0.0, iterations=1, step=0.1, time=0.0)


def test_a_run_killed_between_the_complete_flag_and_the_rename_resumes_from_its_points(tmp_path):
    store = bs.BranchStore.create(tmp_path / "nfrc.h5", 2, attrs={"inputs_hash": "h"})
    for i in range(3):
        store.append(_point(i), {"a": float(i)})
    with mock.patch.object(bs, "commit", side_effect=KeyboardInterrupt), \
            np.testing.assert_raises(KeyboardInterrupt):
        store.finalize("reached omega_max")
    assert not (tmp_path / "nfrc.h5").exists() and (tmp_path / "nfrc.partial.h5").is_file()
    # a partial file, never taken as complete
    assert not bs.load_branch(tmp_path / "nfrc.h5", allow_partial=True).complete

    again = bs.BranchStore.reopen(tmp_path / "nfrc.h5")
    assert again.n_points == 3
    # the file says what it is again: not complete, no checksums (those of three points)
    assert int(again._h5.attrs["complete"]) == 0 and bs.CHECKSUMS not in again._h5.attrs
    again.append(_point(3), {"a": 3.0})
    path = again.finalize("reached omega_max")
    s = bs.load_branch(path)
    assert s.complete and s.branch.status == "reached omega_max"
    np.testing.assert_array_equal(s.branch.omega, [400.0, 401.0, 402.0, 403.0])
    np.testing.assert_array_equal(s.branch.x, [[0, 0], [1, 2], [2, 4], [3, 6]])
    np.testing.assert_array_equal(s.extras["a"], [0.0, 1.0, 2.0, 3.0])
    assert verify(path) is None  # the checksums are those of the four points
