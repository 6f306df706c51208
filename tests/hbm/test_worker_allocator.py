"""hbm.processes.keep_freed_memory: a worker that allocates and frees the same arrays over and
over (a Newton step's) reuses the memory instead of having the kernel map and zero fresh
pages each time. Counted as minor page faults in a fresh interpreter, with and without."""
from __future__ import annotations

import ctypes
import resource
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
n = 100 * 1024 // 8  # 100 KiB: under glibc's first mmap threshold, from the heap
f0 = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
for _ in range(20):  # 20 MiB a round, allocated, written and freed
    arrays = [np.ones(n) for _ in range(200)]
    del arrays
print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - f0)
"""


def _glibc() -> bool:
    try:
        return hasattr(ctypes.CDLL(None), "gnu_get_libc_version")
    except OSError:
        return False


@pytest.mark.skipif(not _glibc(), reason="needs glibc: keep_freed_memory sets glibc's mallopt parameters and "
                                         "does nothing with another C library (musl, macOS)")
def test_freed_memory_is_reused_without_page_faults():
    def faults(mode: str) -> int:
        out = subprocess.run([sys.executable, "-c", SCRIPT, mode], cwd=ROOT, capture_output=True, text=True,
                             check=True, env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"})
        return int(out.stdout.split()[-1])

    off, on = faults("off"), faults("on")
    page = resource.getpagesize()
    one_round = 200 * 100 * 1024 // page
    # default glibc: the heap's free top (20 MiB) is past the trim threshold (128 KiB, as no
    # mapped block was freed to raise it) and is given back after each round, then faulted in
    # again; kept, only the first round faults
    assert off > 5 * one_round
    assert on < 1.2 * one_round
