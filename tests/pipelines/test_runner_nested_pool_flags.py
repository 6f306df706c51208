"""hbm.processes' start flags (which tasks a dead worker was computing) belong to the pool whose
initializer set them: a pool started from one of its tasks forks workers that inherit them, and
their tasks must not mark the outer pool's tasks of the same index as running."""
from __future__ import annotations

import concurrent.futures
import time

from hbm.processes import process_context, run_flagged, running, set_start_flags, start_flags


def _inner(t):
    time.sleep(t)
    return "inner"


def _outer():
    with concurrent.futures.ProcessPoolExecutor(1, mp_context=process_context()) as pool:
        return pool.submit(run_flagged, 2, _inner, 1.0).result()


def test_a_nested_pools_tasks_leave_the_outer_pools_flags_alone():
    ctx = process_context()
    flags = start_flags(ctx, 3)
    with concurrent.futures.ProcessPoolExecutor(1, mp_context=ctx, initializer=set_start_flags,
                                                initargs=(flags,)) as pool:
        f = pool.submit(run_flagged, 0, _outer)
        time.sleep(0.6)  # the inner task (its own index 2) is running now
        during = running(flags)
        assert f.result() == "inner"
    # before: [0, 2] while it ran, and task 2 of the outer pool "returned" at the end
    assert during == [0]
    assert list(flags) == [2, 0, 0]
