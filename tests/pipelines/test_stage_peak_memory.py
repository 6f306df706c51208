"""The run summary's peak memory per stage (pipelines.progress): each stage's own high-water
mark, not the run's so far. A stage that touches 300 MB reports at least that much; the stage
after it, which touches almost nothing, reports less by nearly as much (Linux lets a process
reset its mark, /proc/self/clear_refs)."""
from pathlib import Path

import numpy as np
import pytest

from pipelines.progress import Progress

MB = 1e6


def test_each_stage_reports_its_own_peak():
    try:  # what pipelines.progress does at each stage's start
        Path("/proc/self/clear_refs").write_text("5")
    except OSError:
        pytest.skip("this kernel lets no process reset its memory high-water mark (/proc/self/clear_refs, "
                    "Linux): the summary then shows each stage the run's peak so far, by design, and there is "
                    "no per-stage peak to check")
    p = Progress(quiet=True)
    with p.stage("big"):
        a = np.ones(int(300 * MB) // 8)  # every page written
        del a
    with p.stage("small"):
        b = np.ones(1000)
        del b
    big, small = p.records
    assert big.peak_memory >= 300 * MB
    assert small.peak_memory <= big.peak_memory - 250 * MB, (big.peak_memory / MB, small.peak_memory / MB)
    assert (big.stage, big.action, small.action) == ("big", "computed", "computed")


def test_a_stage_that_fails_or_is_interrupted_is_recorded_so():
    p = Progress(quiet=True)
    for exc in (OSError("disk full"), KeyboardInterrupt()):
        with pytest.raises(type(exc)):
            with p.stage("hbm"):
                raise exc
    assert [r.action for r in p.records] == ["failed", "interrupted"]
