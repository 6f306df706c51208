"""The CPU model numba tunes its code for.

numba compiles for the host's instruction set and tunes the code with the scheduling model
of the CPU that LLVM names for the host. LLVM 14 (Debian's llvmlite 0.39, numba 0.56) names
AMD Zen 3 'znver3', and tuned for it, LLVM unrolls at run time the loops whose trip count
is known only then. The time integration's step loop (hbm.ti.kernel.run_steps) is made of
such loops, over 9 contact nodes and 48 padded modes: tuned for 'znver3' it compiles to
21 000 instructions, against 8 100 tuned for 'znver2', and 8 200 tuned for 'znver3' with
LLVM's runtime unrolling switched off (-unroll-runtime=false: that is the difference); on a
Zen 3 host its steps take 1.6 to 1.8 times as long (README, *Time integration*). The host's
own features are kept (numba asks LLVM for them apart from the name): the code uses the
same instructions, tuned otherwise.

The choice is numba's process-wide one: the NUMBA_CPU_NAME environment variable, read into
numba.core.config.CPU_NAME, which numba uses when the process compiles or loads from its
cache its first function. It is made when hbm is imported (hbm/__init__.py): the bladerub
command imports hbm before any stage compiles, and spawned workers import it again. A CPU
name the user gave numba is kept (NUMBA_CPU_NAME, an empty one, numba's generic CPU,
included, or numba.core.config.CPU_NAME): set NUMBA_CPU_NAME=znver3 for LLVM's own tuning.
numba's cache keys its entries by the CPU name, so code tuned either way is never loaded
for the other. A process that compiled numba code before importing hbm keeps the tuning it
had.
"""
from __future__ import annotations

import os
import sys

#: LLVM's name for a host -> the model numba tunes for there instead (module docstring).
RETUNED = {"znver3": "znver2"}


def tuning_cpu(host: str, configured: str | None) -> str | None:
    """The CPU model to tune for on a host that LLVM names `host`, or None to leave numba's
    own choice; `configured` is the CPU name the user gave numba (None: none), which always
    wins, an empty one too (numba's generic CPU)."""
    if configured is not None:
        return None
    return RETUNED.get(host)


def retune_numba() -> str | None:
    """Set numba's CPU model for this process (and the processes it starts) where LLVM's
    tuning for the host is known to be slow; returns the model set, or None where nothing
    changed."""
    config = sys.modules.get("numba.core.config")  # numba already imported: it read the
    # environment then (and its config file), and reads it again only at a compile after
    # some NUMBA_ variable changed; a name set in its config directly counts as the user's
    configured = os.environ.get("NUMBA_CPU_NAME")
    if configured is None and config is not None:
        configured = config.CPU_NAME
    import llvmlite.binding as llvm

    cpu = tuning_cpu(llvm.get_host_cpu_name(), configured)
    if cpu is None:
        return None
    os.environ["NUMBA_CPU_NAME"] = cpu
    if config is not None:
        config.CPU_NAME = cpu
    return cpu
