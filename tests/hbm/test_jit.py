"""The CPU model numba tunes for (hbm.jit): the rule, that importing hbm applies it before
any compile, and the LLVM behaviour it works around."""
import os
import platform
import subprocess
import sys
from pathlib import Path

import pytest

from hbm.jit import RETUNED, tuning_cpu

ROOT = Path(__file__).resolve().parents[2]

# a fresh interpreter: the codegen's CPU is fixed at the first compile of a process
_CODEGEN_CPU = """
import sys
{first}
import hbm
from numba import njit
from numba.core.registry import cpu_target
import llvmlite.binding as llvm

@njit
def add(x):
    return x + 1

add(1)
print(llvm.get_host_cpu_name() + "|" + cpu_target.target_context.codegen().magic_tuple()[1])
"""


def _codegen_cpu(tmp_path, first="", **env):
    run_env = {k: v for k, v in os.environ.items() if k != "NUMBA_CPU_NAME"}
    run_env.update(env, NUMBA_CACHE_DIR=str(tmp_path), PYTHONPATH=str(ROOT))
    out = subprocess.run([sys.executable, "-c", _CODEGEN_CPU.format(first=first)], env=run_env,
                         capture_output=True, text=True, timeout=120, check=True)
    host, used = out.stdout.strip().split("|")
    return host, used


def test_the_rule_retunes_zen3_only_and_never_against_the_user():
    assert tuning_cpu("znver3", None) == "znver2"
    assert tuning_cpu("znver3", "") is None  # an empty NUMBA_CPU_NAME is numba's generic CPU
    assert tuning_cpu("znver3", "znver3") is None  # the user's choice wins
    assert tuning_cpu("haswell", None) is None
    assert tuning_cpu("sapphirerapids", None) is None
    assert tuning_cpu("znver2", None) is None


@pytest.mark.parametrize("first", ["", "import numba"], ids=["hbm first", "numba first"])
def test_importing_hbm_sets_the_model_the_first_compile_uses(tmp_path, first):
    """On every host: the codegen's CPU is the retuned one where the rule names one, the
    host's otherwise; whether numba was imported before hbm or not."""
    host, used = _codegen_cpu(tmp_path, first)
    assert used == RETUNED.get(host, host)


@pytest.mark.parametrize("name", ["znver3", ""], ids=["znver3", "generic"])
def test_a_cpu_name_set_by_the_user_is_kept(tmp_path, name):
    host, used = _codegen_cpu(tmp_path, NUMBA_CPU_NAME=name)
    assert used == name


def test_a_cpu_name_set_in_numbas_config_is_kept(tmp_path):
    host, used = _codegen_cpu(tmp_path, "import numba.core.config as c; c.CPU_NAME = 'haswell'")
    assert used == "haswell"


_KERNEL_SIZE = """
import sys
sys.path.insert(0, {tests!r})
from support import standin_rom
from hbm.options import CasingOptions, TimeIntegrationOptions
from hbm.ti import kernel
from hbm.ti.march import rom_modal_system
from hbm.ti.sweep import simulate

simulate(rom_modal_system(standin_rom()), CasingOptions(), 0.15, 2000.0,
         TimeIntegrationOptions(n_revolutions=2, n_keep=1))
asm = "".join(kernel.run_steps.inspect_asm().values())
print(sum(1 for line in asm.splitlines()
          if line.startswith("\\t") and not line.lstrip().startswith((".", "#"))))
"""


@pytest.mark.skipif(platform.machine() != "x86_64", reason="znver2 and znver3 are x86-64 models")
def test_llvm_still_unrolls_the_step_loop_for_zen3(tmp_path):
    """The premise of hbm.jit, on any x86 host (LLVM tunes for a named model with the host's
    features): tuned for 'znver3' the step loop compiles to more than twice the instructions
    it takes tuned for 'znver2' (21 000 against 8 100 on rotor 67's ROM with LLVM 14). If a
    later LLVM stops unrolling it, this fails, and the retuning can go."""
    sizes = {}
    for cpu in ("znver3", "znver2"):
        env = dict(os.environ, NUMBA_CPU_NAME=cpu, NUMBA_CACHE_DIR=str(tmp_path / cpu),
                   PYTHONPATH=str(ROOT))
        out = subprocess.run([sys.executable, "-c", _KERNEL_SIZE.format(tests=str(ROOT / "tests"))],
                             env=env, capture_output=True, text=True, timeout=300, check=True)
        sizes[cpu] = int(out.stdout.split()[-1])
    assert sizes["znver3"] > 2.0 * sizes["znver2"], sizes
