"""The CPU model numba tunes for (hbm.jit): the rule, that importing hbm applies it before
any compile, and the LLVM behaviour it works around."""
import os
import platform
import subprocess
import sys
from pathlib import Path

import pytest

from hbm.jit import PREFER_256, RETUNED, tuning_cpu, tuning_features

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
magic = cpu_target.target_context.codegen().magic_tuple()
print("|".join([llvm.get_host_cpu_name(), magic[1], llvm.get_host_cpu_features().flatten(), magic[2]]))
"""


def _codegen(tmp_path, first="", **env):
    """(host's CPU name, the name used, the host's features, the features used) of a fresh
    interpreter that imports hbm and compiles a function."""
    run_env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CPU_NAME", "NUMBA_CPU_FEATURES")}
    run_env.update(env, NUMBA_CACHE_DIR=str(tmp_path), PYTHONPATH=str(ROOT))
    out = subprocess.run([sys.executable, "-c", _CODEGEN_CPU.format(first=first)], env=run_env,
                         capture_output=True, text=True, timeout=120, check=True)
    return tuple(out.stdout.strip().split("|"))


def _codegen_cpu(tmp_path, first="", **env):
    host, used, _, _ = _codegen(tmp_path, first, **env)
    return host, used


def _host_features() -> str:
    import llvmlite.binding as llvm
    return llvm.get_host_cpu_features().flatten()


def test_the_rule_retunes_zen3_only_and_never_against_the_user():
    assert tuning_cpu("znver3", None) == "znver2"
    assert tuning_cpu("znver3", "") is None  # an empty NUMBA_CPU_NAME is numba's generic CPU
    assert tuning_cpu("znver3", "znver3") is None  # the user's choice wins
    assert tuning_cpu("haswell", None) is None
    assert tuning_cpu("sapphirerapids", None) is None
    assert tuning_cpu("znver2", None) is None


def test_the_feature_rule_prefers_256_bit_vectors_with_avx512_only_and_never_against_the_user():
    zen4 = "+sse2,+avx2,+avx512f,+avx512vl,-amx-tile"
    assert tuning_features(zen4, None) == zen4 + "," + PREFER_256
    assert tuning_features(zen4, "") is None  # the user's choice wins, an empty one too
    assert tuning_features(zen4, "+avx2") is None
    assert tuning_features("+sse2,+avx2,-avx512f,-amx-tile", None) is None  # Zen 3, or an AVX2 Intel
    assert tuning_features(zen4 + ",+prefer-256-bit", None) is None  # already there


@pytest.mark.parametrize("first", ["", "import numba"], ids=["hbm first", "numba first"])
def test_importing_hbm_sets_the_model_the_first_compile_uses(tmp_path, first):
    """On every host: the codegen's CPU is the retuned one where the rule names one, the
    host's otherwise, and its features the host's, with 256-bit vectors preferred where
    the host has AVX-512; whether numba was imported before hbm or not."""
    host, used, host_features, features = _codegen(tmp_path, first)
    assert used == RETUNED.get(host, host)
    assert features == (tuning_features(host_features, None) or host_features)
    assert (PREFER_256 in features.split(",")) == ("+avx512f" in host_features.split(","))


def test_features_set_by_the_user_are_kept(tmp_path):
    host, used, host_features, features = _codegen(tmp_path, NUMBA_CPU_FEATURES=_host_features())
    assert features == host_features


@pytest.mark.parametrize("name", ["znver3", ""], ids=["znver3", "generic"])
def test_a_cpu_name_set_by_the_user_is_kept(tmp_path, name):
    host, used = _codegen_cpu(tmp_path, NUMBA_CPU_NAME=name)
    assert used == name


def test_a_cpu_name_set_in_numbas_config_is_kept(tmp_path):
    host, used = _codegen_cpu(tmp_path, "import numba.core.config as c; c.CPU_NAME = 'haswell'")
    assert used == "haswell"


_KERNEL_SIZE = """
import sys
import time
sys.path.insert(0, {tests!r})
from support import COARSE_ROM, standin_rom
from rom.model import load_rom
from hbm.options import CasingOptions, TimeIntegrationOptions
from hbm.ti import kernel
from hbm.ti.march import rom_modal_system
from hbm.ti.sweep import simulate

point = simulate(rom_modal_system(standin_rom()), CasingOptions(), 0.15, 2000.0,
                 TimeIntegrationOptions(n_revolutions=2, n_keep=1))
asm = "".join(kernel.run_steps.inspect_asm().values())
# the coarse rotor 67 ROM at 1900 rad/s: steps whose sliding directions move several times
coarse = simulate(rom_modal_system(load_rom(COARSE_ROM)), CasingOptions(), 0.15, 1900.0,
                  TimeIntegrationOptions(dt=4e-7, n_revolutions=20, n_keep=5))
print(sum(1 for line in asm.splitlines()
          if line.startswith("\\t") and not line.lstrip().startswith((".", "#"))), asm.count("%zmm"),
      point.cpu_time, time.process_time(), coarse.amplitude.hex())
"""


@pytest.fixture(scope="module")
def kernel_code(tmp_path_factory):
    """kernel_code(cpu, features=None, cached=False) -> (instructions, mentions of a 512-bit
    register) of the step loop compiled for the model `cpu` (and these features; None: hbm's
    rule), then the cpu_time the sweep stored for the short march that compiled it and the
    process's CPU time, s, and the LE amplitude of a march of the coarse ROM (float.hex);
    each compiled once per module, in a process of its own on an empty numba cache (a
    compile takes 10 to 16 s). cached=True: the same script in another process, which
    loads the loop from that cache."""
    root, done, folders = tmp_path_factory.mktemp("kernel_code"), {}, {}

    def code(cpu, features=None, cached=False):
        if cached:
            code(cpu, features)
        if (cpu, features, cached) not in done:
            env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CPU_NAME", "NUMBA_CPU_FEATURES")}
            folder = folders.setdefault((cpu, features), root / f"{cpu}-{len(folders)}")
            env.update(NUMBA_CPU_NAME=cpu, NUMBA_CACHE_DIR=str(folder), PYTHONPATH=str(ROOT))
            if features is not None:
                env["NUMBA_CPU_FEATURES"] = features
            out = subprocess.run([sys.executable, "-c", _KERNEL_SIZE.format(tests=str(ROOT / "tests"))],
                                 env=env, capture_output=True, text=True, timeout=300, check=True)
            words = out.stdout.split()[-5:]
            done[cpu, features, cached] = (int(words[0]), int(words[1]), float(words[2]), float(words[3]),
                                           words[4])
        return done[cpu, features, cached]

    return code


@pytest.mark.skipif(platform.machine() != "x86_64", reason="znver2 and znver3 are x86-64 models")
def test_llvm_still_unrolls_the_step_loop_for_zen3(kernel_code):
    """The premise of hbm.jit, on any x86 host (LLVM tunes for a named model with the host's
    features): tuned for 'znver3' the step loop compiles to more than twice the instructions
    it takes tuned for 'znver2' (21 000 against 8 100 on rotor 67's ROM with LLVM 14). If a
    later LLVM stops unrolling it, this fails, and the retuning can go."""
    sizes = {cpu: kernel_code(cpu)[0] for cpu in ("znver3", "znver2")}
    assert sizes["znver3"] > 2.0 * sizes["znver2"], sizes


@pytest.mark.skipif(platform.machine() != "x86_64", reason="the fixture compiles for znver2, an x86-64 model")
def test_a_speeds_cpu_time_leaves_out_the_compile_of_the_step_loop(kernel_code):
    """The first speed a process marches on a cold numba cache: the process spends seconds
    compiling the step loop (the fixture's process, its cache folder empty), the speed's
    cpu_time in ti.h5 only its march (two revolutions of the stand-in ROM, well under a
    second). Charged to the speed, the compile (15.5 s on a Zen 3 host) would be two to three
    times the march of the sweep's slowest speed there."""
    *_, speed, process, _ = kernel_code("znver2")
    assert process > 2.0, (speed, process)
    assert 0.0 < speed < 0.25 * process, (speed, process)


@pytest.mark.skipif(platform.machine() != "x86_64", reason="the fixture compiles for znver2, an x86-64 model")
def test_the_step_loop_loaded_from_numbas_cache_marches_as_the_one_compiled(kernel_code):
    """A sweep's workers compile the step loop or load it from numba's cache, whichever their
    process finds; a ROM must give the same sweep either way (tests/pipelines/test_stages.py
    compares a sweep's speeds across processes). With the sliding direction's update a helper
    numba called rather than inlined, the loop loaded from the cache ended this march of the
    coarse ROM at 1900 rad/s with an LE amplitude 3.8e-6 away from the compiled loop's
    (measured; 8.7e-7 in the tiny scene's sweep, which failed that test on a clean clone)."""
    compiled = kernel_code("znver2")
    loaded = kernel_code("znver2", cached=True)
    assert loaded[3] < 0.5 * compiled[3]  # it did load: no compile in that process
    assert loaded[4] == compiled[4]


@pytest.mark.skipif(platform.machine() != "x86_64" or "+avx512f" not in _host_features().split(","),
                    reason="needs a host with AVX-512: the feature rule it checks acts only there")
def test_llvm_still_uses_512_bit_vectors_in_the_step_loop_unless_told_otherwise(kernel_code):
    """The premise of the feature rule (hbm.jit), on a host with AVX-512: tuned for 'znver2'
    with the host's features as they are, the step loop uses 512-bit registers; with the
    rule's '+prefer-256-bit', none. If a later LLVM stops using them, this fails, and the
    rule can go."""
    assert kernel_code("znver2", _host_features())[1] > 0
    assert kernel_code("znver2")[1] == 0
