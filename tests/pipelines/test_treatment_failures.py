"""A stage's treatments (pipelines.stages.treatments) where one fails: one after the other in
the run's own process (one core, or under an MPI launcher) as at once in processes of their
own, a failing treatment does not stop the others, and the first failure in key order is
raised once every one has ended. Ctrl-C stops them all."""
from __future__ import annotations

import pytest

from pipelines.progress import Progress
from pipelines.stages.base import Context
from pipelines.stages.treatments import run_treatments

DONE: list = []


def _work(ctx, item, say):
    if item in ("disk", "other"):
        raise OSError(f"{item} failed")
    if item == "ctrl-c":
        raise KeyboardInterrupt
    DONE.append(item)
    return item.upper()


def _run(tmp_path, items):
    DONE.clear()
    ctx = Context(scene=None, out=tmp_path, progress=Progress(quiet=True))
    return run_treatments(ctx, items, _work, "test", "treatment", workers=1)


def test_a_failing_treatment_does_not_stop_the_next(tmp_path):
    assert _run(tmp_path, {"dlft": "a", "rl": "b"}) == {"dlft": "A", "rl": "B"}
    with pytest.raises(OSError, match="disk failed"):
        _run(tmp_path, {"dlft": "disk", "rl": "b", "x": "other"})
    assert DONE == ["b"]


def test_ctrl_c_stops_the_treatments_after_it(tmp_path):
    with pytest.raises(KeyboardInterrupt):
        _run(tmp_path, {"dlft": "ctrl-c", "rl": "b"})
    assert DONE == []


def test_at_once_the_first_failure_in_key_order_is_raised(tmp_path):
    """In processes of their own, whichever ends first: the error raised is that of the first
    failing treatment in key order, and the others' results are not lost to it."""
    ctx = Context(scene=None, out=tmp_path, progress=Progress(quiet=True))
    assert run_treatments(ctx, {"dlft": "a", "rl": "b"}, _work, "test", "treatment", workers=2) == \
        {"dlft": "A", "rl": "B"}
    for items, first in (({"dlft": "disk", "rl": "other"}, "disk"), ({"dlft": "other", "rl": "disk"}, "other"),
                         ({"dlft": "a", "rl": "disk"}, "disk")):
        with pytest.raises(OSError, match=f"{first} failed"):
            run_treatments(ctx, items, _work, "test", "treatment", workers=2)
