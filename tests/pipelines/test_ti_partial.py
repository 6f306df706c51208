"""The sweep keeps each speed in ti.partial.h5 as it ends (pipelines.stages.ti.SweepPartial),
and a run of the same inputs goes on from the speeds on disk instead of marching them again
(the interrupted case itself: tests/pipelines/test_interrupt.py), also after a worker of the
sweep was killed, which is one line naming it."""
import os
import subprocess
import sys
from dataclasses import fields, replace

import h5py
import numpy as np
import pytest

from coarse_runs import ROOT, clone
from support import mpirun_command, needs_mpirun, shell_env
from hbm.ti.sweep import SpeedResponse
from pipelines import artifacts as art
from pipelines.cli import main
from pipelines.stages.ti import SweepPartial, read_sweep


def _speed(result, i: int) -> SpeedResponse:
    return SpeedResponse(**{f.name: getattr(result, f.name)[i] for f in fields(result)})


def test_a_sweep_goes_on_from_the_speeds_on_disk(coarse_nfrc, tmp_path, capsys):
    scene = clone(coarse_nfrc[1], tmp_path)
    run = ["run", str(scene), "--out", str(tmp_path), "--until", "ti", "--set", "ti.n_omega=6"]
    assert main(run + ["--quiet"]) == 0
    whole = read_sweep(tmp_path)
    part = tmp_path / "ti.partial.h5"
    assert not part.exists()  # gone once ti.h5 holds every speed
    inputs_hash = art.read_attrs(tmp_path / "ti.h5")["inputs_hash"]

    # an interrupted sweep's file: speeds 0, 2 and 5 kept, speed 3 cut by a kill while it was
    # written; the kept ones marked (a CPU time of -1 s) to tell them from speeds marched again
    kept = SweepPartial(part, inputs_hash)
    for i in (0, 2, 5, 3):
        kept.speed(i, replace(_speed(whole, i), cpu_time=-1.0))
    with h5py.File(part, "a") as h5:
        del h5["speeds/003"].attrs["complete"]
    (tmp_path / "ti.h5").unlink()
    capsys.readouterr()
    assert main(run) == 0
    assert "resuming from 3 of 6 speeds on disk (ti.partial.h5)" in capsys.readouterr().out
    got = read_sweep(tmp_path)
    np.testing.assert_array_equal(got.cpu_time[[0, 2, 5]], -1.0)
    assert (got.cpu_time[[1, 3, 4]] > 0).all()
    for f in fields(whole):  # the speeds taken from disk and those marched: the whole sweep's rows
        if f.name != "cpu_time":
            np.testing.assert_array_equal(getattr(got, f.name), getattr(whole, f.name), err_msg=f.name)
    assert not part.exists() and art.verify(tmp_path / "ti.h5") is None

    # speeds kept for other inputs (another [ti] step, say) are not taken, nor those of
    # another grid; a speed kept for other inputs starts the file over
    SweepPartial(part, inputs_hash).speed(1, _speed(whole, 1))
    assert list(SweepPartial(part, inputs_hash).resume(whole.omega)) == [1]
    assert SweepPartial(part, "0" * 64).resume(whole.omega) == {}
    assert SweepPartial(part, inputs_hash).resume(whole.omega[::-1]) == {}
    SweepPartial(part, "0" * 64).speed(2, _speed(whole, 2))
    assert list(SweepPartial(part, "0" * 64).resume(whole.omega)) == [2]

    # under MPI each rank keeps its speeds in a file of its own; a resume takes all of them
    # and a finished sweep removes all of them
    part.unlink()
    SweepPartial(part, inputs_hash, rank=1).speed(4, _speed(whole, 4))
    SweepPartial(part, inputs_hash, rank=3).speed(5, _speed(whole, 5))
    SweepPartial(part, inputs_hash).speed(0, _speed(whole, 0))
    both = SweepPartial(part, inputs_hash)
    assert [p.name for p in both.files()] == ["ti.partial.h5", "ti.r1.partial.h5", "ti.r3.partial.h5"]
    assert sorted(both.resume(whole.omega)) == [0, 4, 5]
    # what a stopped run says it kept (pipelines.runner) sums these counts
    assert [art.read_attrs(p)["n_speeds"] for p in both.files()] == [1, 1, 1]
    both.remove()
    assert both.files() == [] and not list(tmp_path.glob("*.partial.h5"))


#: `bladerub` whose time-integration worker marching 2000 rad/s (the last speed of the SHORT
#: grid; the slowest go first) is killed, as the OOM killer would.
KILLED = """import os, signal, sys
import hbm.ti.sweep as s
real = s.simulate
def simulate(system, casing, mu, omega, options):
    if omega == 2000.0:
        os.kill(os.getpid(), signal.SIGKILL)
    return real(system, casing, mu, omega, options)
s.simulate = simulate
from pipelines.cli import main
sys.exit(main(sys.argv[1:]))
"""


@pytest.mark.skipif(len(os.sched_getaffinity(0)) < 2, reason="one core: the sweep marches in the run's own process, "
                    "which the kill would end (the worker's case needs a pool)")
def test_a_killed_sweep_worker_is_one_line_and_the_speeds_done_are_kept(coarse_nfrc, tmp_path, capsys):
    scene = clone(coarse_nfrc[1], tmp_path)
    run = ["run", str(scene), "--out", str(tmp_path), "--until", "ti"]
    r = subprocess.run([sys.executable, "-c", KILLED] + run, cwd=ROOT, capture_output=True, text=True,
                       env=shell_env(), timeout=600)
    assert r.returncode == 1, r.stderr
    head = ("bladerub: error: stage ti failed: a worker process of the time-integration sweep ended without an "
            "answer (killed, perhaps for lack of memory); speeds being marched: ")
    line = r.stderr.strip()
    assert line.startswith(head) and "\n" not in line, r.stderr
    marched, _, rest = line[len(head):].partition(" rad/s; kept: ")
    marched = marched.split(", ")  # the killed one, and the other worker's if it ran one
    assert "speeds of ti.partial.h5" in rest and rest.endswith("again to go on from there"), r.stderr
    assert "2000" in marched and len(marched) <= 2, r.stderr
    assert not (tmp_path / "ti.h5").exists()
    kept = art.read_attrs(tmp_path / "ti.partial.h5")["n_speeds"]
    # two workers, slowest first: whichever took 2000 rad/s had ended one or two speeds, the
    # other one or none (the fourth speed goes to a worker once three have been taken)
    assert 2 <= kept <= 3
    capsys.readouterr()
    assert main(run) == 0
    assert f"resuming from {kept} of 4 speeds on disk" in capsys.readouterr().out
    assert art.verify(tmp_path / "ti.h5") is None and not (tmp_path / "ti.partial.h5").exists()


#: `bladerub` under mpirun whose rank 1 is killed once it has kept its first speed (it
#: marches speeds 1 and 3 of the 4, 2000 rad/s last), as a batch system's time limit would.
KILLED_RANK = """import os, signal, sys
from mpi4py import MPI
import hbm.ti.sweep as s
real = s.simulate
def simulate(system, casing, mu, omega, options):
    if omega == 2000.0 and MPI.COMM_WORLD.rank == 1:
        os.kill(os.getpid(), signal.SIGKILL)
    return real(system, casing, mu, omega, options)
s.simulate = simulate
from pipelines.cli import main
sys.exit(main(sys.argv[1:]))
"""


@needs_mpirun
def test_an_interrupted_mpi_sweep_keeps_every_ranks_speeds(coarse_nfrc, tmp_path, capsys):
    scene = clone(coarse_nfrc[1], tmp_path)
    run = ["run", str(scene), "--out", str(tmp_path), "--until", "ti"]
    mpirun, env = mpirun_command(ROOT)
    r = subprocess.run(mpirun + [sys.executable, "-c", KILLED_RANK] + run, cwd=ROOT,
                       capture_output=True, text=True, env=env, timeout=600)
    assert r.returncode != 0 and not (tmp_path / "ti.h5").exists(), r.stderr
    files = SweepPartial(tmp_path / "ti.partial.h5", "").files()
    rank1 = tmp_path / "ti.r1.partial.h5"
    assert rank1 in files, [p.name for p in tmp_path.iterdir()]
    with h5py.File(rank1, "r") as h5:  # rank 1's first speed, kept before it was killed
        assert list(h5["speeds"]) == ["001"] and h5["speeds/001"].attrs["complete"] == 1
    kept = sum(art.read_attrs(p)["n_speeds"] for p in files)
    # rank 0's own speeds (0 and 2) may or may not have ended before mpirun stopped it
    capsys.readouterr()
    assert main(run) == 0  # one process now: the speeds of both ranks' files are taken
    out = capsys.readouterr().out
    assert f"resuming from {kept} of 4 speeds on disk" in out and "ti.r1.partial.h5" in out, out
    assert art.verify(tmp_path / "ti.h5") is None and not list(tmp_path.glob("*.partial.h5"))

    # the same stage under mpirun to its end: the rows of the resumed one-process run, and no
    # rank's file left behind
    resumed = read_sweep(tmp_path)
    (tmp_path / "ti.h5").unlink()
    r = subprocess.run(mpirun + [sys.executable, "-m", "pipelines.cli"] + run, cwd=ROOT,
                       capture_output=True, text=True, env=env, timeout=600)
    assert r.returncode == 0, r.stdout + r.stderr
    got = read_sweep(tmp_path)
    for f in fields(got):
        if f.name != "cpu_time":
            np.testing.assert_array_equal(getattr(got, f.name), getattr(resumed, f.name), err_msg=f.name)
    assert not list(tmp_path.glob("*.partial.h5"))
