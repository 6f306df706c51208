"""The kernels OpenBLAS runs on this host.

OpenBLAS (Debian's 0.3.21, built with every x86-64 kernel set) picks its kernels from the
CPU's family and model, and a CPU newer than its tables gets the oldest x86-64 set,
Prescott (SSE3). On an Intel Xeon of the Emerald Rapids generation (model 207), which
0.3.21 does not know, the coarse DLFT NFRC then takes 2.2 to 2.4 times as long as with the
AVX-512 or AVX2 kernels (72.8 s against 29.9 to 33.0 s; benchmarks/README.md, *OpenBLAS on a
CPU it does not know*). OPENBLAS_CORETYPE names the set to use instead, but
OpenBLAS reads it once, when the library is loaded: it must be in the environment before the
process first imports numpy.

choose_openblas_core does that where it helps: on a CPU with AVX2 and FMA (OpenBLAS's
Haswell set) or AVX-512 F, CD, BW, DQ and VL (its SkylakeX set), it asks a child interpreter
(~0.1 s) which set numpy's OpenBLAS picks, and where that is Prescott, names the better set
for this process and the processes it starts. Everything else is left as it was: a set the
user named (OPENBLAS_CORETYPE, even empty), a CPU OpenBLAS knows (its choice is kept, so the
round-off of a run on such a host does not change), a process that has imported numpy
already (it keeps its kernels, and so do its children: one kernel set per run), and a
worker process that multiprocessing spawned (it has its parent's environment).
"""
from __future__ import annotations

import os
import subprocess
import sys

#: OpenBLAS's kernel set for a CPU that has these instruction sets, best first.
KERNEL_SETS = (
    ("SkylakeX", frozenset({"avx512f", "avx512cd", "avx512bw", "avx512dq", "avx512vl"})),
    ("Haswell", frozenset({"avx2", "fma"})),
)
#: The kernel set OpenBLAS falls back to on an x86-64 CPU it does not know.
FALLBACK = "Prescott"

_PROBE = ("import numpy\n"
          "from threadpoolctl import threadpool_info\n"
          "print(*[i.get('architecture') or '' for i in threadpool_info() if i.get('internal_api') == 'openblas'])")


def cpu_flags(cpuinfo: str = "/proc/cpuinfo") -> frozenset[str]:
    """The instruction-set flags of the first CPU listed in `cpuinfo` (Linux); empty where
    the file is missing or lists none."""
    try:
        with open(cpuinfo, encoding="utf-8", errors="replace") as f:
            for line in f:
                key, _, value = line.partition(":")
                if key.strip() == "flags":
                    return frozenset(value.split())
    except OSError:
        pass
    return frozenset()


def better_kernels(flags: frozenset[str]) -> str | None:
    """The best OpenBLAS kernel set the CPU's `flags` allow above Prescott, or None."""
    for name, needs in KERNEL_SETS:
        if needs <= flags:
            return name
    return None


def probe_kernels(timeout: float = 60.0) -> str | None:
    """The kernel set numpy's OpenBLAS picks in a fresh interpreter with this environment
    (e.g. 'Prescott', 'SkylakeX'), or None where numpy's BLAS is not OpenBLAS or the child
    fails."""
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1")
    try:
        run = subprocess.run([sys.executable, "-c", _PROBE], capture_output=True, text=True, env=env,
                             timeout=timeout)
    except (OSError, subprocess.SubprocessError):
        return None
    names = run.stdout.split()
    return names[0] if run.returncode == 0 and names else None


def choose_openblas_core() -> str | None:
    """Set OPENBLAS_CORETYPE for this process and its children where OpenBLAS would run its
    Prescott kernels on a CPU that has better ones (module docstring); returns the set named,
    or None where nothing was changed."""
    if "OPENBLAS_CORETYPE" in os.environ or "numpy" in sys.modules:
        return None
    if "--multiprocessing-fork" in getattr(sys, "orig_argv", ()):
        return None
    better = better_kernels(cpu_flags())
    if better is None or probe_kernels() != FALLBACK:
        return None
    os.environ["OPENBLAS_CORETYPE"] = better
    return better
