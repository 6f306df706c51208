"""Ctrl-C in every stage of a `bladerub run` subprocess, sent as a terminal sends it (SIGINT
to the run's whole process group) once the stage's "[stage] running" line is out: one line
on standard error naming the stage, what was kept and the command to go on; exit code 130;
no temporary file and no process of the run left; and the next run goes on from there.
"""
from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest

from coarse_runs import ROOT, clone
from support import shell_env
from pipelines import artifacts as art
from pipelines.branch_store import load_branch
from pipelines.cli import main
from pipelines.runner import plan
from pipelines.scene import load_scene

#: The rom, ti and validation stages take about a second on a fast machine: too short to be sure a signal lands in it. Here it
#: first sleeps (a pure-Python stage answers Ctrl-C the same way during its numpy work).
SLOW = ("import dataclasses, sys, time; from pipelines.stages import REGISTRY; name = sys.argv.pop(1); "
        "s = REGISTRY[name]; REGISTRY[name] = dataclasses.replace(s, compute=lambda ctx, outputs: "
        "(time.sleep(60), s.compute(ctx, outputs))); from pipelines.cli import main; sys.exit(main(sys.argv[1:]))")


def _group(pgid: int) -> list[int]:
    """Live processes of a process group (the run and anything it started)."""
    found = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                stat = (d / "stat").read_text()
            except OSError:
                continue
            fields = stat[stat.rindex(")") + 2:].split()
            if int(fields[2]) == pgid and fields[0] != "Z":
                found.append(int(d.name))
    return found


def interrupt(scene: Path, out: Path, stage: str, delay: float, *args, slow: bool = False,
              once: tuple[str, ...] = (), child: float | None = None) -> str:
    """Start a run, Ctrl-C it `delay` s after "[stage] running" (with `once`: as soon as one of
    these files of `out` exists, checked every 10 ms, at most `delay` s later; with `child`:
    `child` s after a second process of the run appeared, at most `delay` s later); check the
    outcome; return the line it printed."""
    cmd = [sys.executable, "-c", SLOW, stage] if slow else [sys.executable, "-m", "pipelines.cli"]
    # a run started from a terminal answers SIGINT; a test run started as a background job of a
    # non-interactive shell ignores it, and its children would inherit that (exec keeps SIG_IGN)
    # the environment a shell gives: with this process's singleton MPI environment the run
    # would join this process's MPI job as its rank 0
    p = subprocess.Popen(cmd + ["run", str(scene), "--out", str(out), *args], cwd=ROOT, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, start_new_session=True, env=shell_env(),
                         preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    for line in p.stdout:
        if line.startswith(f"[{stage}] running"):
            end = time.perf_counter() + delay
            while not (once and any((out / f).exists() for f in once)) and time.perf_counter() < end:
                if child is not None and len(_group(p.pid)) > 1:
                    end = min(end, time.perf_counter() + child)
                    child = None
                time.sleep(0.01)
            os.killpg(p.pid, signal.SIGINT)
            break
    else:
        p.kill()
        pytest.fail(f"stage {stage} never ran: {p.communicate()[1]}")
    t0 = time.perf_counter()
    _, err = p.communicate(timeout=60)
    # within the watcher's grace (3 s) plus the time for the run and its helpers (the pool's
    # resource tracker) to leave: 3.5 s measured on a quiet machine, 8 s with load 13 on 2 cores
    assert time.perf_counter() - t0 < 15.0
    assert p.returncode == 130, err
    lines = [x for x in err.splitlines() if x.strip()]
    assert len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith(f"bladerub: interrupted during stage {stage}; kept: ")
    command = " ".join(["bladerub", "run", str(scene), "--out", str(out), *args])
    assert lines[0].endswith(f"; run `{command}` again to go on from there")
    for _ in range(50):  # the pool's workers, the mesher: ended with the run
        if not _group(p.pid):
            break
        time.sleep(0.1)
    assert not _group(p.pid), "a process of the interrupted run is still alive"
    # a folder the run made and left empty is gone (pipelines.folder.removed_if_unused)
    assert not out.exists() or not [q.name for q in out.iterdir() if art.TEMP_MARK in q.name]
    return lines[0]


def test_ctrl_c_while_meshing(coarse_run, tmp_path):
    out = tmp_path / "run"
    scene = tmp_path / "scene.toml"
    scene.write_text(coarse_run[0].read_text())
    # the whole stage takes 2 s here and less on CI: the signal goes 0.3 s after the mesher's
    # process started (gmsh imported and meshing in it), not after a fixed delay
    line = interrupt(scene, out, "mesh", 2.0, "--until", "mesh", child=0.3)
    assert "; kept: nothing new;" in line and not (out / "mesh.h5").exists()
    assert main(["run", str(scene), "--out", str(out), "--until", "mesh", "--quiet"]) == 0
    # gmsh meshes the same solid the same way (serial meshers): the shared run's very mesh,
    # dataset by dataset (the attributes' entry holds each run's own instant and timings)
    sums = [json.loads(art.read_attrs(d / "mesh.h5")["checksums"]) for d in (out, coarse_run[1])]
    for s in sums:
        s.pop(art.LAYOUT, None)
    assert sums[0] == sums[1] and len(sums[0]) > 5


def test_ctrl_c_in_fem(coarse_run, tmp_path):
    """The next run computes fem from the kept mesh.h5 (the plan below; computing fem from it
    is what the shared run itself did)."""
    scene = clone(coarse_run[1], tmp_path, copy=("mesh.h5",))
    for name in ("fem.h5", "rom.h5"):
        (tmp_path / name).unlink()
    line = interrupt(scene, tmp_path, "fem", 1.5, "--until", "fem")  # the stage: 5.6 s here
    assert "; kept: mesh.h5;" in line and not (tmp_path / "fem.h5").exists()
    steps = plan(load_scene(scene), tmp_path, ("mesh", "fem"))
    assert [(s.stage.name, s.why) for s in steps] == [("mesh", "up to date"), ("fem", "no artifact")]


def test_ctrl_c_in_rom(coarse_run, tmp_path):
    scene = clone(coarse_run[1], tmp_path)
    (tmp_path / "rom.h5").unlink()
    line = interrupt(scene, tmp_path, "rom", 0.5, "--until", "rom", slow=True)
    assert "; kept: mesh.h5, fem.h5;" in line
    assert main(["run", str(scene), "--out", str(tmp_path), "--until", "rom", "--quiet"]) == 0
    with h5py.File(tmp_path / "rom.h5") as new, h5py.File(coarse_run[1] / "rom.h5") as ref:
        assert np.array_equal(new["K"][()], ref["K"][()])


def test_ctrl_c_in_hbm(coarse_run, coarse_nfrc, tmp_path, capsys):
    scene = clone(coarse_run[1], tmp_path)
    # once the first points are on disk: a fixed delay outlasted the whole stage on a fast host
    line = interrupt(scene, tmp_path, "hbm", 30.0, "--until", "hbm",
                     once=("nfrc_dlft.partial.h5", "nfrc_rl.partial.h5"))
    kept = line.split("; kept: ")[1].split(";")[0]
    assert kept.startswith("mesh.h5, fem.h5, rom.h5")
    assert main(["run", str(scene), "--out", str(tmp_path), "--until", "hbm"]) == 0
    out = capsys.readouterr().out
    if "points of nfrc_dlft.partial.h5" in kept:  # the points on disk are where it goes on from
        n = kept.split(" points of nfrc_dlft.partial.h5")[0].split()[-1]
        assert f"dlft: resuming from {n} points on disk" in out
    for name in ("nfrc_dlft.h5", "nfrc_rl.h5"):  # complete, and ended as an uninterrupted run did
        stored = load_branch(tmp_path / name)
        assert stored.complete and art.verify(tmp_path / name) is None
        assert stored.attrs["status"] == load_branch(coarse_nfrc[1] / name).attrs["status"]


def test_ctrl_c_in_hbm_with_the_sweep_started_beside_it(coarse_run, tmp_path, capsys):
    """--until ti starts the sweep's pool beside the NFRCs (pipelines.runner): Ctrl-C in hbm
    ends its workers too, writes no ti.h5, and the next run computes the sweep."""
    scene = clone(coarse_run[1], tmp_path)
    line = interrupt(scene, tmp_path, "hbm", 30.0, "--until", "ti",
                     once=("nfrc_dlft.partial.h5", "nfrc_rl.partial.h5"))
    assert line.split("; kept: ")[1].startswith("mesh.h5, fem.h5, rom.h5")
    assert not (tmp_path / "ti.h5").exists()
    assert main(["run", str(scene), "--out", str(tmp_path), "--until", "ti"]) == 0
    assert art.verify(tmp_path / "ti.h5") is None
    if len(os.sched_getaffinity(0)) >= 2:
        assert "[ti] running (no artifact) beside hbm" in capsys.readouterr().out


def test_ctrl_c_in_the_sweep_keeps_its_finished_speeds(coarse_nfrc, tmp_path, capsys):
    """Ctrl-C once the sweep has kept a speed (ti.partial.h5): the line counts the speeds
    kept, and the next run goes on from them to a complete ti.h5."""
    scene = clone(coarse_nfrc[1], tmp_path)
    # 12 speeds of 200 revolutions: ~2 s of sweep here, ~0.3 s a speed
    args = ("--set", "ti.n_omega=12", "--set", "ti.n_revolutions=200", "--until", "ti")
    line = interrupt(scene, tmp_path, "ti", 30.0, *args, once=("ti.partial.h5",))
    kept = line.split("; kept: ")[1].split(";")[0]
    assert kept.startswith("mesh.h5, fem.h5, rom.h5, nfrc_dlft.h5, nfrc_rl.h5") and not (tmp_path / "ti.h5").exists()
    capsys.readouterr()
    assert main(["run", str(scene), "--out", str(tmp_path), *args]) == 0
    out = capsys.readouterr().out
    if "speeds of ti.partial.h5" in kept:  # the signal came after the first speed was complete
        assert re.search(r"resuming from \d+ of 12 speeds on disk \(ti.partial.h5\)", out), out
    assert art.verify(tmp_path / "ti.h5") is None and not (tmp_path / "ti.partial.h5").exists()


def test_ctrl_c_in_ti_then_in_validation(coarse_nfrc, tmp_path):
    scene = clone(coarse_nfrc[1], tmp_path)
    # both stages take about a second on a fast machine: each first sleeps, as rom's does
    line = interrupt(scene, tmp_path, "ti", 0.5, slow=True)
    assert "; kept: mesh.h5, fem.h5, rom.h5, nfrc_dlft.h5, nfrc_rl.h5;" in line and not (tmp_path / "ti.h5").exists()
    line = interrupt(scene, tmp_path, "validation", 0.5, slow=True)
    assert "; kept: mesh.h5, fem.h5, rom.h5, nfrc_dlft.h5, nfrc_rl.h5, ti.h5, isolas.h5;" in line
    assert main(["run", str(scene), "--out", str(tmp_path), "--quiet"]) == 0
    for name in ("ti.h5", "isolas.h5", "validation.h5"):
        assert art.verify(tmp_path / name) is None
    assert (tmp_path / "figures" / "validation_dlft.png").is_file()
