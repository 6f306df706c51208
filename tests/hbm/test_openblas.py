"""OpenBLAS's kernels on a CPU its tables do not know (hbm.openblas).

Debian's OpenBLAS 0.3.21 runs its oldest x86-64 kernels (Prescott) on an Intel Xeon of the
Emerald Rapids generation; importing hbm before numpy names the AVX-512 (or AVX2) set
instead. Each check runs in a fresh interpreter, since OpenBLAS reads its kernel choice
once, when numpy loads it.
"""
import os
import subprocess
import sys

import pytest

from hbm.openblas import FALLBACK, better_kernels, cpu_flags

REPORT = ("import os\n{first}\nimport numpy\n"
          "from threadpoolctl import threadpool_info\n"
          "print(os.environ.get('OPENBLAS_CORETYPE'), *[i.get('architecture') for i in threadpool_info()"
          " if i.get('internal_api') == 'openblas'])")


def _kernels(first: str, **env) -> list[str]:
    """[OPENBLAS_CORETYPE after the imports, the kernel set numpy's OpenBLAS runs] in a fresh
    interpreter that runs `first` (imports), with the test's environment less
    OPENBLAS_CORETYPE plus `env`."""
    e = {k: v for k, v in os.environ.items() if k != "OPENBLAS_CORETYPE"}
    e.update(env)
    run = subprocess.run([sys.executable, "-c", REPORT.format(first=first)], capture_output=True, text=True,
                         env=e, timeout=120)
    assert run.returncode == 0, run.stderr
    out = run.stdout.split()
    if len(out) < 2:
        pytest.skip("numpy's BLAS is not OpenBLAS here (MKL, or the reference BLAS): hbm.openblas has no kernels to choose")
    return out


def test_kernel_sets_follow_the_instruction_sets():
    # the flags /proc/cpuinfo lists on the Emerald Rapids host (AVX-512 F CD BW DQ VL among them)
    emerald = frozenset("fpu sse sse2 ssse3 sse4_1 sse4_2 avx avx2 fma avx512f avx512dq avx512cd avx512bw "
                        "avx512vl avx512ifma avx512vbmi".split())
    assert better_kernels(emerald) == "SkylakeX"
    assert better_kernels(emerald - {"avx512vl"}) == "Haswell"  # SkylakeX's kernels use AVX-512 VL
    assert better_kernels(frozenset({"sse3", "avx", "avx2"})) is None  # no FMA: Haswell's kernels need it
    assert better_kernels(frozenset({"sse3", "ssse3", "sse4_2"})) is None


def test_cpu_flags_reads_the_first_cpu(tmp_path):
    info = tmp_path / "cpuinfo"
    info.write_text("processor\t: 0\nvendor_id\t: GenuineIntel\nflags\t\t: fpu avx2 fma\n\n"
                    "processor\t: 1\nflags\t\t: fpu\n")
    assert cpu_flags(str(info)) == frozenset({"fpu", "avx2", "fma"})
    assert cpu_flags(str(tmp_path / "missing")) == frozenset()


@pytest.mark.skipif(better_kernels(cpu_flags()) is None,
                    reason="this CPU has neither AVX2 with FMA nor AVX-512: Prescott's kernels may be its best")
def test_hbm_first_never_leaves_openblas_on_its_oldest_kernels():
    """On a CPU that OpenBLAS knows, its own choice (OPENBLAS_CORETYPE stays unset); on one
    it does not (Emerald Rapids, Prescott without hbm), the set the flags allow."""
    named, kernels = _kernels("import hbm")
    assert kernels != FALLBACK
    if named != "None":
        assert (named, kernels) == (better_kernels(cpu_flags()),) * 2
        assert _kernels("import numpy")[1] == FALLBACK  # the reason it was named


def test_a_kernel_set_the_user_named_is_kept():
    assert _kernels("import hbm", OPENBLAS_CORETYPE="Haswell") == ["Haswell", "Haswell"]


def test_numpy_imported_first_keeps_its_kernels():
    """numpy already loaded: OpenBLAS has chosen, so hbm names nothing (the children of
    such a process keep the same kernels as it)."""
    named, kernels = _kernels("import numpy\nimport hbm")
    assert named == "None"
    assert kernels == _kernels("import numpy")[1]
