"""Interrupt a continuation, reload it from its branch file, resume: same branch as one run."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from pipelines.branch_store import BranchStore, load_branch
from hbm.continuation.arclength import ContinuationOptions, continue_branch
from hbm.continuation.branch import STATUS_MAX_POINTS, STATUS_OMEGA_MAX, STATUS_STEP_FLOOR
from hbm.continuation.newton import NewtonOptions
from systems import Duffing1, Wall

DUFFING = Duffing1(zeta=0.02, gamma=1.0, force=0.1)
OPTS = ContinuationOptions(0.5, 2.5, ds=0.02, ds_max=0.05, newton=NewtonOptions(tol_residual=1e-10))
FIELDS = ("omega", "x", "converged", "residual_norm", "iterations", "step")


class Interrupt(Exception):
    pass


def writer(store, stop_after=None):
    def on_point(p):
        store.append(p, {"amplitude": np.hypot(*p.x)})
        if stop_after is not None and p.index + 1 >= stop_after:
            raise Interrupt
    return on_point


def assert_same_points(a, b):
    # Resuming rebuilds the exact state (last two points, step from the stored step and
    # iterations), so the arithmetic is the same: equal up to rounding, if any at all.
    assert len(a) == len(b)
    for f in FIELDS:
        np.testing.assert_allclose(getattr(a, f), getattr(b, f), rtol=1e-12, atol=1e-14, err_msg=f)


@pytest.fixture(scope="module")
def reference():
    return continue_branch(DUFFING, np.zeros(2), 0.5, OPTS)


@pytest.mark.parametrize("how", ["exception", "max_points"])
def test_resumed_branch_equals_uninterrupted(tmp_path, reference, how):
    path = tmp_path / "nfrc.h5"
    k = 80  # on the middle sheet: the resumed secant must carry on backwards in omega
    s = np.sign(np.diff(reference.omega))
    turns = np.flatnonzero(s[1:] != s[:-1]) + 1
    assert len(turns) == 2 and turns[0] + 1 < k < turns[1] - 1
    store = BranchStore.create(path, 2, attrs={"units": "-", "inputs_hash": "x"})
    if how == "exception":
        with pytest.raises(Interrupt):
            continue_branch(DUFFING, np.zeros(2), 0.5, OPTS, on_point=writer(store, stop_after=k))
    else:
        first = continue_branch(DUFFING, np.zeros(2), 0.5, replace(OPTS, max_points=k), on_point=writer(store))
        assert first.status == STATUS_MAX_POINTS
    store.close()
    assert not path.exists()

    saved = load_branch(path, allow_partial=True)
    assert len(saved.branch) == k and not saved.complete
    store = BranchStore.reopen(path)
    resumed = continue_branch(DUFFING, None, None, OPTS, resume=saved.branch, on_point=writer(store))
    store.finalize(resumed.status, resumed.detail)

    assert resumed.status == reference.status == STATUS_OMEGA_MAX
    assert_same_points(resumed, reference)
    final = load_branch(path)
    assert final.complete
    assert_same_points(final.branch, reference)
    np.testing.assert_allclose(final.extras["amplitude"], np.hypot(*reference.x.T), rtol=1e-12)


def test_resume_drops_a_failed_tail_and_can_go_further(tmp_path):
    wall = Wall(2.0)
    opts = replace(OPTS, omega_max=5.0, ds_min=1e-3)
    b = continue_branch(wall, np.array([1.0]), 1.0, opts)
    assert b.status.startswith(STATUS_STEP_FLOOR) and not b.converged[-1]
    # Same options: it fails again at the same place, from the last converged point.
    again = continue_branch(wall, None, None, opts, resume=b)
    assert again.status.startswith(STATUS_STEP_FLOOR)
    assert_same_points(head(again, len(b) - 1), head(b, len(b) - 1))
    # A finer floor lets it get closer to the end of the branch.
    finer = continue_branch(wall, None, None, replace(opts, ds_min=1e-6), resume=b)
    ok = finer.omega[finer.converged]
    assert ok.max() > b.omega[b.converged].max() and ok.max() <= 2.0



def head(b, m):
    """The first m points of a Branch."""
    return replace(b, **{f: getattr(b, f)[:m] for f in FIELDS + ("time",)})


def test_a_resume_keeps_counting_the_points_at_the_step_floor():
    """A straight branch walked at ds = ds_min (below crawl_ratio ds_min): the crawl rule
    ends it after 5 such points, resumed after 3 of them or not."""
    import numpy as np

    from hbm.continuation.arclength import ContinuationOptions, continue_branch
    from hbm.continuation.newton import NewtonOptions

    def line(x, w):
        return np.array([x[0] - w]), np.array([[1.0]]), np.array([-1.0])

    kw = dict(ds=0.01, ds_min=0.01, ds_max=0.02, crawl_points=5, crawl_ratio=4.0,
              newton=NewtonOptions(tol_residual=1e-12))
    full = continue_branch(line, [0.0], 0.0, ContinuationOptions(0.0, 10.0, **kw))
    part = continue_branch(line, [0.0], 0.0, ContinuationOptions(0.0, 10.0, max_points=4, **kw))
    resumed = continue_branch(line, None, None, ContinuationOptions(0.0, 10.0, **kw), resume=part)
    assert len(full) == 6 and full.status.startswith("crawled")
    assert (len(resumed), resumed.status) == (len(full), full.status)


def test_a_resume_after_the_first_step_takes_the_uninterrupted_second_step():
    """On the circle, the first step turns from the start's tangent: with turn_shrink_deg = 1
    the uninterrupted run halves the next step; a run resumed from those two points does too."""
    import numpy as np

    from hbm.continuation.arclength import ContinuationOptions, continue_branch
    from hbm.continuation.newton import NewtonOptions
    from systems import Circle

    kw = dict(ds=0.02, ds_max=0.05, turn_shrink_deg=1.0, newton=NewtonOptions(tol_residual=1e-10))
    x0 = np.array([2.5, 1.5625])
    full = continue_branch(Circle(), x0, 1.5, ContinuationOptions(0.0, 5.0, max_points=6, **kw))
    part = continue_branch(Circle(), x0, 1.5, ContinuationOptions(0.0, 5.0, max_points=2, **kw))
    resumed = continue_branch(Circle(), None, None, ContinuationOptions(0.0, 5.0, max_points=6, **kw), resume=part)
    assert full.step[2] == 0.5 * full.step[1]
    np.testing.assert_array_equal(resumed.step, full.step)
    np.testing.assert_allclose(resumed.x, full.x, rtol=0, atol=1e-12)
