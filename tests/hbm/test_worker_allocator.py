"""hbm.processes.keep_freed_memory: a worker that allocates and frees the same few-MB arrays
over and over (a Newton step's) reuses the memory instead of having the kernel map and zero
fresh pages each time. Counted as minor page faults in a fresh interpreter, with and without."""
from __future__ import annotations

import ctypes
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

SCRIPT = """
import resource, sys
import numpy as np
from hbm.processes import keep_freed_memory
if sys.argv[1] == "on":
    keep_freed_memory()
# three arrays of ~3 MiB: under numpy's 4 MiB huge-page threshold, over glibc's first mmap one
sizes = [3 * 2**20 // 8 + 1000 * k for k in range(3)]
for _ in range(3):  # glibc's thresholds adapt to the first frees
    arrays = [np.ones(n) for n in sizes]; del arrays
f0 = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
for _ in range(100):
    arrays = [np.ones(n) for n in sizes]; del arrays
print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - f0)
"""


def _glibc() -> bool:
    try:
        return hasattr(ctypes.CDLL(None), "mallopt") and bool(ctypes.CDLL(None).gnu_get_libc_version())
    except (OSError, AttributeError):
        return False


@pytest.mark.skipif(not _glibc(), reason="mallopt is glibc's")
def test_freed_memory_is_reused_without_page_faults():
    def faults(mode: str) -> int:
        out = subprocess.run([sys.executable, "-c", SCRIPT, mode], cwd=ROOT, capture_output=True, text=True,
                             check=True, env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"})
        return int(out.stdout.split()[-1])

    off, on = faults("off"), faults("on")
    # default glibc: the heap's free top (9 MiB) is over twice the adapted mmap threshold and
    # is given back after each round, then faulted in again: ~2300 pages a round
    assert off > 100 * 2300 // 2
    assert on < 0.01 * off
