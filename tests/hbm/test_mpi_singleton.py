"""Outside mpirun, MPI starts as a singleton that starts no helper daemon once hbm is
imported (hbm.processes.isolate_mpi_singleton): the process initialising MPI has no orted
child. The same process without hbm first does have one on Open MPI 4 (the control: on an
MPI that never starts a daemon there is nothing to check)."""
import os
import shutil
import subprocess
import sys

import pytest

from support import mpirun_command, shell_env

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

CHILDREN = ("import os, subprocess; from mpi4py import MPI; MPI.COMM_WORLD.Barrier(); "
            "print(subprocess.run(['ps', '--ppid', str(os.getpid()), '-o', 'comm='], capture_output=True, "
            "text=True).stdout.split())")


def _children(first: str) -> list:
    out = subprocess.run([sys.executable, "-c", first + CHILDREN], cwd=ROOT, env=shell_env(), capture_output=True,
                         text=True, timeout=120, check=True).stdout
    return eval(out.strip().splitlines()[-1])  # noqa: S307 - our own print of a list of names


def test_a_singleton_starts_no_daemon_once_hbm_is_imported():
    if "orted" not in _children(""):
        pytest.skip("this MPI starts no daemon for a singleton: nothing to isolate")
    assert "orted" not in _children("import hbm; ")


def test_a_user_setting_and_a_launcher_are_left_alone(monkeypatch):
    from hbm.processes import isolate_mpi_singleton

    monkeypatch.setenv("OMPI_MCA_ess_singleton_isolated", "0")
    isolate_mpi_singleton()
    assert os.environ["OMPI_MCA_ess_singleton_isolated"] == "0"
    monkeypatch.delenv("OMPI_MCA_ess_singleton_isolated")
    monkeypatch.setenv("OMPI_COMM_WORLD_SIZE", "2")
    isolate_mpi_singleton()
    assert "OMPI_MCA_ess_singleton_isolated" not in os.environ


WORLD = "import hbm; from mpi4py import MPI; from hbm.processes import mpi_world; print(MPI.COMM_WORLD.Get_size(), mpi_world())"


def test_one_rank_is_the_serial_path():
    """MPI initialised in the process (the fem stage's dolfinx does it, and the main command's
    later stages run in that process) or `mpirun -n 1`: one rank, so no MPI world (the stages
    then spread their work over the cores with processes, not over a lone rank)."""
    out = subprocess.run([sys.executable, "-c", WORLD], cwd=ROOT, env=shell_env(), capture_output=True, text=True,
                         timeout=120, check=True).stdout
    assert out.split()[-2:] == ["1", "None"]
    if shutil.which("mpirun") is None:
        return
    mpirun, env = mpirun_command(ROOT, n=1)
    out = subprocess.run(mpirun + [sys.executable, "-c", WORLD], cwd=ROOT, env=env, capture_output=True, text=True,
                         timeout=120, check=True).stdout
    assert out.split()[-2:] == ["1", "None"]
