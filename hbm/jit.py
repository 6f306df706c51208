"""The CPU model numba tunes its code for.

numba compiles for the host's instruction set and tunes the code with the scheduling model
of the CPU that LLVM names for the host. LLVM 14 (Debian's llvmlite 0.39, numba 0.56) names
AMD Zen 3 'znver3', and tuned for it, LLVM unrolls at run time the loops whose trip count
is known only then. The time integration's step loop (hbm.ti.kernel.run_steps) is made of
such loops, over 9 contact nodes and 48 padded modes: tuned for 'znver3' it compiles to
21 000 instructions, against 8 100 tuned for 'znver2', and 8 200 tuned for 'znver3' with
LLVM's runtime unrolling switched off (-unroll-runtime=false: that is the difference); on a
Zen 3 host its steps take 1.6 to 1.8 times as long (benchmarks/README.md, *Time
integration*). The host's own features are kept (numba asks LLVM for them apart from the
name): the code uses the same instructions, tuned otherwise.

The choice is numba's process-wide one: the NUMBA_CPU_NAME environment variable, read into
numba.core.config.CPU_NAME, which numba uses when the process compiles or loads from its
cache its first function. It is made when hbm is imported (hbm/__init__.py): the bladerub
command imports hbm before any stage compiles, and spawned workers import it again. A CPU
name the user gave numba is kept (NUMBA_CPU_NAME, an empty one, numba's generic CPU,
included, or numba.core.config.CPU_NAME): set NUMBA_CPU_NAME=znver3 for LLVM's own tuning.
numba's cache keys its entries by the CPU name, so code tuned either way is never loaded
for the other. A process that compiled numba code before importing hbm keeps the tuning it
had.

Vector width. On a host with AVX-512, LLVM tunes for 256-bit vectors where its model of the
CPU says so (Intel's server models since Skylake) and uses 512-bit ones otherwise, which it
does tuned for 'znver2' or 'znver3' on AMD Zen 4 (LLVM 14 names Zen 4 'znver3': it has no
model for it). The kernels' loops run over 9 to 12 contact nodes and 48 padded modes: a
node loop is one 512-bit vector and a masked tail, and Zen 4 executes each 512-bit
operation as two 256-bit halves. So where the host has AVX-512 and the user gave numba no
features (NUMBA_CPU_FEATURES or numba.core.config.CPU_FEATURES), the host's features are
passed with LLVM's '+prefer-256-bit' added: on a Zen 4 host the time integration's speeds
then take 0.79 to 0.89 of the time they took with 512-bit vectors (benchmarks/README.md,
*Time integration*). On Intel's models the flag is already part of the tuning, and the code is
the same. numba's cache keys its entries by the features too.
"""
from __future__ import annotations

import os
import sys

#: LLVM's name for a host -> the model numba tunes for there instead (module docstring).
RETUNED = {"znver3": "znver2"}
#: LLVM's tuning flag for 256-bit vectors on a host with 512-bit ones (module docstring).
PREFER_256 = "+prefer-256-bit"


def tuning_cpu(host: str, configured: str | None) -> str | None:
    """The CPU model to tune for on a host that LLVM names `host`, or None to leave numba's
    own choice; `configured` is the CPU name the user gave numba (None: none), which always
    wins, an empty one too (numba's generic CPU)."""
    if configured is not None:
        return None
    return RETUNED.get(host)


def tuning_features(host: str, configured: str | None) -> str | None:
    """The CPU features to compile for on a host whose features LLVM lists as `host`
    (comma-separated, '+avx512f,-amx-tile,...'), or None to leave numba's own choice:
    `host` with 256-bit vectors preferred where it has AVX-512 (module docstring).
    `configured`: the features the user gave numba (None: none), which always win."""
    flags = host.split(",")
    if configured is not None or "+avx512f" not in flags or PREFER_256 in flags:
        return None
    return f"{host},{PREFER_256}"


def retune_numba() -> str | None:
    """Set numba's CPU model and features for this process (and the processes it starts)
    where LLVM's tuning for the host is known to be slow; returns the model set, or None
    where the model is left as it was."""
    import llvmlite.binding as llvm

    config = sys.modules.get("numba.core.config")  # numba already imported: it read the
    # environment then (and its config file), and reads it again only at a compile after
    # some NUMBA_ variable changed; a value set in its config directly counts as the user's
    given = {}
    for var, attr in (("NUMBA_CPU_NAME", "CPU_NAME"), ("NUMBA_CPU_FEATURES", "CPU_FEATURES")):
        given[var] = os.environ.get(var)
        if given[var] is None and config is not None:
            given[var] = getattr(config, attr)
    try:
        host_features = llvm.get_host_cpu_features().flatten()
    except RuntimeError:  # LLVM cannot list them on this host: numba's own choice
        host_features = ""
    new = {"NUMBA_CPU_NAME": tuning_cpu(llvm.get_host_cpu_name(), given["NUMBA_CPU_NAME"]),
           "NUMBA_CPU_FEATURES": tuning_features(host_features, given["NUMBA_CPU_FEATURES"])}
    if all(v is None for v in new.values()):
        return None
    for var, attr in (("NUMBA_CPU_NAME", "CPU_NAME"), ("NUMBA_CPU_FEATURES", "CPU_FEATURES")):
        # numba re-reads every NUMBA_ variable once one of them changes: a value the user
        # set in its config goes to the environment too, or that re-read would drop it
        value = new[var] if new[var] is not None else given[var]
        if value is not None:
            os.environ[var] = value
            if config is not None:
                setattr(config, attr, value)
    return new["NUMBA_CPU_NAME"]
