"""Faults injected into runs of the coarse_run scene: each is found and named in one line, never
taken as current, and costs nothing that was good.

Every test works in a clone of the shared runs (conftest.py): links to the artifacts it only
reads, copies of those it damages.
"""
from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from coarse_runs import ROOT, clone
from support import shell_env
from pipelines import artifacts as art
from pipelines import folder
from pipelines.errors import FolderBusy
from pipelines.branch_store import load_branch
from pipelines.cli import main
from pipelines.runner import plan
from pipelines.scene import load_scene


def run(scene, out, *args):
    return main(["run", str(scene), "--out", str(out), *args])


def one_line(err: str) -> str:
    """The only line on standard error (no traceback)."""
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def temps(out: Path) -> list:
    return [p.name for d in (out, out / "figures") if d.is_dir() for p in d.iterdir() if art.TEMP_MARK in p.name]


def flip(path: Path, offset: int, n: int = 1) -> None:
    """Invert n bytes of a file in place at offset."""
    with open(path, "r+b") as fh:
        fh.seek(offset)
        data = fh.read(n)
        fh.seek(offset)
        fh.write(bytes(b ^ 0xFF for b in data))


def storage(path: Path, name: str) -> tuple[int, int]:
    with h5py.File(path, "r") as h5:
        return h5[name].id.get_offset(), h5[name].id.get_storage_size()


def with_rom_damping(scene: Path, value: str) -> Path:
    """A copy of the scene whose [rom] damping_high differs: rom.h5 is no longer current."""
    other = scene.with_name("damping.toml")
    other.write_text(scene.read_text().replace("damping_high = 5e-3", f"damping_high = {value}"))
    return other


# --- damaged artifacts: detected, recomputed from their inputs, never used -------------
def test_flipped_bytes_in_a_large_dataset_are_recomputed(coarse_run, tmp_path, capsys):
    scene = clone(coarse_run[1], tmp_path, copy=("rom.h5",))
    offset, size = storage(tmp_path / "rom.h5", "recovery")  # 11 MB, rom.h5's largest dataset
    flip(tmp_path / "rom.h5", offset + size // 2, 8)
    assert run(scene, tmp_path, "--until", "rom") == 0
    out = capsys.readouterr().out
    assert "[rom] running (damaged: dataset 'recovery' changed on disk (checksum mismatch))" in out
    assert "[mesh] up to date" in out and "[fem] up to date" in out
    assert art.verify(tmp_path / "rom.h5") is None
    # the recomputed ROM is the intact one, bit for bit: the damaged bytes were not used
    with h5py.File(tmp_path / "rom.h5") as new, h5py.File(coarse_run[1] / "rom.h5") as ref:
        assert np.array_equal(new["recovery"][()], ref["recovery"][()])
        assert np.array_equal(new["K"][()], ref["K"][()])


def test_a_flipped_byte_anywhere_in_fem_is_found(coarse_run, tmp_path):
    """fem.h5 (144 MB) damaged at the first byte of K, at a 16 MiB block boundary inside it,
    and at the last byte of the modes: each time the plan recomputes fem and names the dataset
    (recomputing it is the previous test's business, on a cheaper file)."""
    clone(coarse_run[1], tmp_path, copy=("fem.h5",))
    path, scene = tmp_path / "fem.h5", load_scene(tmp_path / "scene.toml")
    k, k_size = storage(path, "K/data")
    m, m_size = storage(path, "modes")
    for offset, name in ((k, "K/data"), (k + (1 << 24), "K/data"), (m + m_size - 1, "modes")):
        flip(path, offset)
        step = plan(scene, tmp_path, ("mesh", "fem"))[1]
        assert step.todo and step.why == f"damaged: dataset '{name}' changed on disk (checksum mismatch)"
        flip(path, offset)  # back as it was: current again
        assert not plan(scene, tmp_path, ("mesh", "fem"))[1].todo


@pytest.mark.parametrize("fault, why", [
    ("deleted dataset", "damaged: dataset 'theta' is missing"),
    ("truncated file", "unreadable file"),
    ("zero-byte file", "empty file"),
])
def test_damaged_file_is_recomputed(fault, why, coarse_run, tmp_path, capsys):
    scene = clone(coarse_run[1], tmp_path, copy=("rom.h5",))
    path = tmp_path / "rom.h5"
    if fault == "deleted dataset":
        with h5py.File(path, "r+") as h5:
            del h5["theta"]
    else:
        os.truncate(path, path.stat().st_size // 2 if fault == "truncated file" else 0)
    assert run(scene, tmp_path, "--until", "rom") == 0
    assert f"[rom] running ({why}) ..." in capsys.readouterr().out
    assert art.verify(path) is None and not temps(tmp_path)


def test_artifact_path_that_is_a_folder_is_refused(coarse_run, tmp_path, capsys):
    scene = clone(coarse_run[1], tmp_path)
    (tmp_path / "rom.h5").unlink()
    (tmp_path / "rom.h5").mkdir()
    (tmp_path / "rom.h5" / "notes.txt").write_text("the user's")
    assert run(scene, tmp_path, "--until", "rom") == 2
    captured = capsys.readouterr()
    assert one_line(captured.err) == (f"bladerub: error: {tmp_path / 'rom.h5'} is a folder, where the run writes its "
                                      "artifact: move it away, or give another --out")
    assert "running" not in captured.out  # refused before computing anything
    assert (tmp_path / "rom.h5" / "notes.txt").read_text() == "the user's"


def test_an_mpi_ranks_partial_path_that_is_a_folder_is_refused(coarse_nfrc, tmp_path, capsys):
    # rank 1 of `mpirun -n 2` would keep its speeds there: refused up front, as rank 0's path
    scene = clone(coarse_nfrc[1], tmp_path)
    (tmp_path / "ti.r1.partial.h5").mkdir()
    (tmp_path / "ti.r1.partial.h5" / "notes.txt").write_text("the user's")
    assert run(scene, tmp_path, "--until", "ti") == 2
    captured = capsys.readouterr()
    assert one_line(captured.err) == (f"bladerub: error: {tmp_path / 'ti.r1.partial.h5'} is a folder, where the run "
                                      "writes its artifact: move it away, or give another --out")
    assert "running" not in captured.out and not (tmp_path / "ti.h5").exists()
    assert (tmp_path / "ti.r1.partial.h5" / "notes.txt").read_text() == "the user's"


def test_a_damaged_treatment_leaves_the_other_untouched(coarse_nfrc, tmp_path, capsys):
    scene = clone(coarse_nfrc[1], tmp_path, copy=("nfrc_dlft.h5", "nfrc_rl.h5"))
    rl = (tmp_path / "nfrc_rl.h5").read_bytes()
    with h5py.File(tmp_path / "nfrc_dlft.h5", "r") as h5:  # a byte inside the first chunk of x
        info = h5["x"].id.get_chunk_info(0)  # (chunked: its checksum goes through HDF5's decoding)
    flip(tmp_path / "nfrc_dlft.h5", info.byte_offset + 100)
    assert run(scene, tmp_path, "--until", "hbm") == 0
    out = capsys.readouterr().out
    assert "[hbm] running (nfrc_dlft.h5: damaged: dataset 'x' changed on disk (checksum mismatch)) ..." in out
    assert (tmp_path / "nfrc_rl.h5").read_bytes() == rl
    assert art.verify(tmp_path / "nfrc_dlft.h5") is None and load_branch(tmp_path / "nfrc_dlft.h5").complete


# --- figures and treatments are outputs of their own -----------------------------------
def test_interruption_between_artifact_and_figure(coarse_nfrc, tmp_path, monkeypatch, capsys):
    """Ctrl-C after nfrc_rl.h5 is written but while the NFRC figure is drawn: the next run
    draws the figure and recomputes nothing."""
    import pipelines.figures

    scene = clone(coarse_nfrc[1], tmp_path)
    (tmp_path / "nfrc_rl.h5").unlink()
    (tmp_path / "figures" / "nfrc.png").unlink()

    def ctrl_c(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(pipelines.figures, "plot_nfrc", ctrl_c)
    assert run(scene, tmp_path, "--until", "hbm") == 130
    assert one_line(capsys.readouterr().err) == (
        "bladerub: interrupted during the figures; kept: mesh.h5, fem.h5, rom.h5, nfrc_dlft.h5, nfrc_rl.h5; "
        f"run `bladerub run {scene} --out {tmp_path} --until hbm` again to go on from there")
    made = (tmp_path / "nfrc_rl.h5").stat().st_mtime_ns
    monkeypatch.undo()
    assert run(scene, tmp_path, "--until", "hbm") == 0
    out = capsys.readouterr().out
    assert "[hbm] up to date" in out and "[figures] drawn: nfrc" in out
    assert (tmp_path / "nfrc_rl.h5").stat().st_mtime_ns == made and (tmp_path / "figures" / "nfrc.png").is_file()
    # a damaged picture is redrawn too, from the same artifacts
    flip(tmp_path / "figures" / "nfrc.png", 1000, 4)
    assert run(scene, tmp_path, "--until", "hbm") == 0
    assert "[figures] drawn: nfrc" in capsys.readouterr().out


def _ctrl_c_before_point(monkeypatch, name: str, n_points: int) -> None:
    """The treatments one after the other in this process (one core: the patch reaches them),
    and Ctrl-C (KeyboardInterrupt) when NAME's store is about to append its point n_points + 1."""
    from pipelines import branch_store
    from pipelines.stages import treatments

    monkeypatch.setattr(treatments, "treatment_workers", lambda n: 1)
    real = branch_store.BranchStore.append

    def append(self, point, extras=None):
        if self.path.name == name and self.n_points == n_points:
            raise KeyboardInterrupt
        real(self, point, extras)

    monkeypatch.setattr(branch_store.BranchStore, "append", append)


def test_interrupting_the_second_treatment_keeps_the_first(coarse_run, tmp_path, monkeypatch, capsys):
    """The treatments one after the other (one core): Ctrl-C in the second keeps the first.
    (At once, each in its own process, a real Ctrl-C: test_interrupt.py.)"""
    scene = clone(coarse_run[1], tmp_path)
    _ctrl_c_before_point(monkeypatch, "nfrc_rl.h5", 3)
    assert run(scene, tmp_path, "--until", "hbm") == 130
    assert "kept: mesh.h5, fem.h5, rom.h5, nfrc_dlft.h5, 3 points of nfrc_rl.partial.h5;" in capsys.readouterr().err
    dlft = (tmp_path / "nfrc_dlft.h5").read_bytes()
    monkeypatch.undo()
    assert run(scene, tmp_path, "--until", "hbm") == 0
    out = capsys.readouterr().out
    assert "[hbm] running (nfrc_rl.h5: no artifact) ..." in out and "rl: resuming from 3 points on disk" in out
    assert (tmp_path / "nfrc_dlft.h5").read_bytes() == dlft
    assert load_branch(tmp_path / "nfrc_rl.h5").complete and art.verify(tmp_path / "nfrc_rl.h5") is None


def test_a_partial_file_without_its_start_point_starts_over(coarse_run, coarse_nfrc, tmp_path, monkeypatch, capsys):
    """Ctrl-C between the creation of NAME.partial.h5 and its first point (the file holds no
    point): the next run does not stop on it (it used to fail, and every run after it, on
    "resume: the branch to continue has no converged start point"); it computes that NFRC
    from the start, as an uninterrupted run does."""
    scene = clone(coarse_run[1], tmp_path)
    _ctrl_c_before_point(monkeypatch, "nfrc_dlft.h5", 0)
    assert run(scene, tmp_path, "--until", "hbm") == 130
    assert load_branch(tmp_path / "nfrc_dlft.partial.h5", allow_partial=True).branch.omega.size == 0
    capsys.readouterr()
    monkeypatch.undo()
    assert run(scene, tmp_path, "--until", "hbm") == 0
    assert "dlft: nfrc_dlft.partial.h5 holds no start point: the NFRC starts over" in capsys.readouterr().out
    done, ref = load_branch(tmp_path / "nfrc_dlft.h5"), load_branch(coarse_nfrc[1] / "nfrc_dlft.h5")
    assert done.complete and art.verify(tmp_path / "nfrc_dlft.h5") is None
    np.testing.assert_array_equal(done.branch.omega, ref.branch.omega)  # the same points as the uninterrupted run


def test_an_interrupted_nfrc_with_stability_keeps_its_bifurcations(coarse_run, tmp_path, monkeypatch, capsys):
    """[hbm] stability: Ctrl-C at DLFT's 41st point, after the folds near 1975 and 1979 rad/s
    and before the Neimark-Sacker points further down: the partial file holds the
    bifurcations located between its points, and the resumed run's table is the
    uninterrupted run's, kind by kind and Omega by Omega (to the continuation's resampling
    after the resume). The resume used to drop every bifurcation located before the
    interruption."""
    from pipelines.branch_store import read_tables

    # every point analysed: a gapped schedule restarted at the resume may find a pair of
    # crossings inside one of the uninterrupted run's gaps (benchmarks/README.md, the stability schedule)
    stab = ("--set", "hbm.stability=true", "--set", "hbm.stability_max_gap=1", "--set", 'hbm.methods=["dlft"]',
            "--until", "hbm")
    ref_dir = tmp_path / "ref"
    ref_scene = clone(coarse_run[1], ref_dir)
    assert run(ref_scene, ref_dir, *stab) == 0
    ref = read_tables(ref_dir / "nfrc_dlft.h5")["bifurcations"]
    assert len(ref["kind"]) >= 4 and np.sum(ref["index"] < 40) >= 2, ref  # some before the interruption, some after
    scene = clone(coarse_run[1], tmp_path / "cut")
    _ctrl_c_before_point(monkeypatch, "nfrc_dlft.h5", 40)
    assert run(scene, tmp_path / "cut", *stab) == 130
    part = read_tables(tmp_path / "cut" / "nfrc_dlft.partial.h5")["bifurcations"]
    assert list(part["kind"]) == list(ref["kind"][ref["index"] < 38]), part  # located between points on disk
    # as an earlier version wrote it: without the per-point stability cost
    with h5py.File(tmp_path / "cut" / "nfrc_dlft.partial.h5", "r+") as h5:
        del h5["extras/stability_cpu_time"], h5["extras/stability_widened"]
    capsys.readouterr()
    monkeypatch.undo()
    assert run(scene, tmp_path / "cut", *stab) == 0
    assert f"dlft: resuming from 40 points on disk and {len(part['kind'])} bifurcations" in capsys.readouterr().out
    done = read_tables(tmp_path / "cut" / "nfrc_dlft.h5")["bifurcations"]
    assert list(done["kind"]) == list(ref["kind"])
    # before the cut the same points: the same records; after it the resampled points may pair
    # a crossing's multiplier across the circle where the uninterrupted run's did not, or
    # the reverse (1964 rad/s on a Zen 4 host: "guess" resumed, "crossing" uninterrupted)
    kept = ref["index"] < 38
    assert list(np.asarray(done["kind_from"])[kept]) == list(np.asarray(ref["kind_from"])[kept])
    # a crossing is interpolated between its two points, a record without a paired
    # multiplier placed half-way (Bifurcation.kind_from): there the resampling moves it by
    # up to half its bracket too
    paired = ((np.asarray(ref["kind_from"]).astype(str) == "crossing")
              & (np.asarray(done["kind_from"]).astype(str) == "crossing"))
    half = np.where(paired, 0.0, 0.5 * np.maximum(np.abs(ref["omega_high"] - ref["omega_low"]),
                                                  np.abs(done["omega_high"] - done["omega_low"])))
    assert np.all(np.abs(done["omega"] - ref["omega"]) <= 0.5 + half), (done["omega"], ref["omega"], half)
    with h5py.File(tmp_path / "cut" / "nfrc_dlft.h5") as h5:
        cpu = h5["extras/stability_cpu_time"]
        assert cpu.attrs["recorded_from"] == 40 and cpu.attrs["unit"] == "s"
        assert np.isnan(cpu[:40]).all() and (cpu[40:] >= 0).all() and (cpu[40:] > 0).any()


#: `bladerub run` with a full disk in RL's process at its 4th point (a fresh interpreter that
#: starts at the hbm stage has not initialised MPI, so the treatments' processes are forked
#: and inherit the patch).
FULL_DISK_IN_RL = (
    "import errno, os, sys; from pipelines import branch_store; real = branch_store.BranchStore.append\n"
    "def append(self, point, extras=None):\n"
    "    if self.path.name == 'nfrc_rl.h5' and self.n_points == 3:\n"
    "        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(self.path))\n"
    "    real(self, point, extras)\n"
    "branch_store.BranchStore.append = append\n"
    "from pipelines.cli import main; sys.exit(main(sys.argv[1:]))")

#: The stage runs the treatments at once only where there are two cores or more.
TWO_CORES = pytest.mark.skipif(len(os.sched_getaffinity(0)) < 2, reason="one core: the treatments run one after the other")


@TWO_CORES
def test_a_treatment_that_fails_does_not_stop_the_other(coarse_run, tmp_path, capsys):
    """The treatments run at once, one process each: a full disk in RL's process ends RL
    only; DLFT's NFRC is finished and kept, the run fails in one line that names the error
    and what was kept, and the next run (here from this process, whose treatments are
    spawned) goes on with RL alone from its points on disk."""
    scene = clone(coarse_run[1], tmp_path)
    p = subprocess.run([sys.executable, "-c", FULL_DISK_IN_RL, "run", str(scene), "--out", str(tmp_path),
                        "--until", "hbm"], cwd=ROOT, capture_output=True, text=True, timeout=600, env=shell_env())
    assert p.returncode == 1, p.stdout + p.stderr
    assert "  dlft and rl at once, one process each" in p.stdout
    line = one_line(p.stderr)
    assert line.startswith("bladerub: error: stage hbm failed: No space left on device")
    assert line.endswith("kept: mesh.h5, fem.h5, rom.h5, nfrc_dlft.h5, 3 points of nfrc_rl.partial.h5")
    assert load_branch(tmp_path / "nfrc_dlft.h5").complete and art.verify(tmp_path / "nfrc_dlft.h5") is None
    dlft = (tmp_path / "nfrc_dlft.h5").read_bytes()
    assert run(scene, tmp_path, "--until", "hbm") == 0
    out = capsys.readouterr().out
    assert "[hbm] running (nfrc_rl.h5: no artifact) ..." in out and "rl: resuming from 3 points on disk" in out
    assert (tmp_path / "nfrc_dlft.h5").read_bytes() == dlft
    assert load_branch(tmp_path / "nfrc_rl.h5").complete and art.verify(tmp_path / "nfrc_rl.h5") is None


@TWO_CORES
def test_treatments_at_once_give_the_nfrcs_of_one_after_the_other(coarse_nfrc, tmp_path):
    """The stage's default (one process per treatment) against workers=1 (this process, one
    after the other): the same points to round-off (each process limits BLAS to one thread)."""
    from pipelines.progress import Progress
    from pipelines.runner import expected_inputs
    from pipelines.stages import REGISTRY
    from pipelines.stages.base import Context
    from pipelines.stages.hbm import _compute

    scene = clone(coarse_nfrc[1], tmp_path)
    for name in ("nfrc_dlft.h5", "nfrc_rl.h5"):
        (tmp_path / name).unlink()
    sc = load_scene(scene)
    outputs = REGISTRY["hbm"].outputs(sc)
    expected = expected_inputs(sc, ("hbm",))
    ctx = Context(sc, tmp_path, Progress(quiet=True))
    for o in outputs:
        ctx.inputs[o.file], ctx.hashes[o.file] = expected[o.file]
    _compute(ctx, outputs, workers=1)
    for o in outputs:
        serial = load_branch(tmp_path / o.file)
        concurrent = load_branch(coarse_nfrc[1] / o.file)  # made by `bladerub run` with its default
        assert serial.complete and concurrent.complete
        assert serial.branch.omega.shape == concurrent.branch.omega.shape and len(serial.branch.omega) > 10
        scale = np.abs(concurrent.branch.x).max()
        assert np.abs(serial.branch.x - concurrent.branch.x).max() <= 1e-9 * scale
        assert np.allclose(serial.branch.omega, concurrent.branch.omega, rtol=1e-10, atol=0)


# --- one run per folder ------------------------------------------------------------------
def test_a_second_run_is_refused_naming_the_first(coarse_run, tmp_path, capsys):
    scene = clone(coarse_run[1], tmp_path)
    with folder.hold(tmp_path, "bladerub run other.toml --out here"):
        assert run(scene, tmp_path, "--until", "rom") == 2
    line = one_line(capsys.readouterr().err)
    assert line.startswith(f"bladerub: error: {tmp_path} is in use by another run: pid {os.getpid()} on ")
    assert "(`bladerub run other.toml --out here`, started 20" in line
    assert run(scene, tmp_path, "--until", "rom") == 0  # the lock went with its holder


def test_two_concurrent_runs_compute_once(coarse_run, tmp_path):
    scene = clone(coarse_run[1], tmp_path)
    scene.write_text(scene.read_text().replace('methods = ["dlft", "rl"]', 'methods = ["dlft"]'))
    cmd = [sys.executable, "-m", "pipelines.cli", "run", str(scene), "--out", str(tmp_path), "--until", "hbm"]
    procs = [subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                              env=shell_env()) for _ in range(2)]
    results = [(p.pid, *p.communicate(timeout=300)) for p in procs]
    results = [(pid, p.returncode, out, err) for p, (pid, out, err) in zip(procs, results)]
    computed = [r for r in results if "[hbm] done" in r[2]]
    assert len(computed) == 1, results
    winner, (other,) = computed[0], [r for r in results if r is not computed[0]]
    assert winner[1] == 0
    # the other was refused while the first ran, naming it, or came after it and found the work done
    if other[1] == 2:
        assert f"is in use by another run: pid {winner[0]} on " in one_line(other[3])
    else:
        assert other[1] == 0 and "[hbm] up to date" in other[2]
    assert art.verify(tmp_path / "nfrc_dlft.h5") is None and load_branch(tmp_path / "nfrc_dlft.h5").complete
    assert not temps(tmp_path) and not (tmp_path / "nfrc_dlft.partial.h5").exists()


def test_temp_file_of_a_run_killed_while_writing_is_removed(coarse_run, tmp_path, capsys):
    """kill -9 between the datasets and the rename of rom.h5: the next run in the folder
    removes the orphan and keeps the previous rom.h5 until its own is complete."""
    scene = with_rom_damping(clone(coarse_run[1], tmp_path, copy=("rom.h5",)), "6e-3")
    before = (tmp_path / "rom.h5").read_bytes()
    die = ("import os, signal, sys; import pipelines.artifacts as art; "
           "art.add_checksums = lambda path: os.kill(os.getpid(), signal.SIGKILL); "
           "from pipelines.cli import main; main(sys.argv[1:])")
    r = subprocess.run([sys.executable, "-c", die, "run", str(scene), "--out", str(tmp_path), "--until", "rom"],
                       cwd=ROOT, capture_output=True, text=True, timeout=300, env=shell_env())
    assert r.returncode == -signal.SIGKILL
    orphans = temps(tmp_path)
    assert len(orphans) == 1 and orphans[0].startswith(".rom.h5.tmp")
    assert (tmp_path / "rom.h5").read_bytes() == before
    assert run(scene, tmp_path, "--until", "rom") == 0
    assert f"[folder] removed 1 temporary file(s) left by a run that was killed: {orphans[0]} (11." in \
        capsys.readouterr().out
    assert not temps(tmp_path) and art.verify(tmp_path / "rom.h5") is None


# --- unusable output folders: one line, before computing, nothing lost -----------------
def test_out_that_is_a_file(coarse_run, tmp_path, capsys):
    target = tmp_path / "results"
    target.write_text("not a folder")
    assert run(coarse_run[0], target) == 2
    assert one_line(capsys.readouterr().err) == (f"bladerub: error: --out {target} is a file, not a folder: give a "
                                                 "folder (it is created if missing)")
    assert target.read_text() == "not a folder"


def _mount(*args) -> str | None:
    r = subprocess.run(["mount", *args], capture_output=True, text=True)
    return None if r.returncode == 0 else (r.stderr.strip() or f"mount exit {r.returncode}")


def test_read_only_folder(coarse_run, tmp_path, capsys):
    """A read-only bind mount of a folder with work to do: refused before computing. (Tests
    run as root, which ignores permission bits: only a read-only mount makes this real.)"""
    src = tmp_path / "src"
    scene = with_rom_damping(clone(coarse_run[1], src, copy=("rom.h5",)), "6e-3")
    ro = tmp_path / "ro"
    ro.mkdir()
    why = _mount("--bind", str(src), str(ro))
    if why:
        pytest.skip(f"cannot bind-mount a folder here: {why}")
    try:
        why = _mount("-o", "remount,ro,bind", str(ro))
        if why:
            pytest.skip(f"cannot make a read-only bind mount here: {why}")
        before = {p.name: p.read_bytes() for p in ro.iterdir() if p.is_file()}
        assert run(ro / scene.name, ro, "--until", "rom") == 2
        captured = capsys.readouterr()
        assert one_line(captured.err) == (f"bladerub: error: cannot write in the output folder {ro}: "
                                          "Read-only file system")
        assert "running" not in captured.out
        assert {p.name: p.read_bytes() for p in ro.iterdir() if p.is_file()} == before and not temps(ro)
    finally:
        subprocess.run(["umount", str(ro)], check=False)


def test_full_file_system(coarse_run, tmp_path, capsys):
    """rom.h5 (11.3 MB) to rewrite on a 14 MB tmpfs that already holds the old one: refused
    before computing; with --yes the write fails on the full disk: one line, exit 1, no temp
    file left, the old rom.h5 intact."""
    small = tmp_path / "small"
    small.mkdir()
    why = _mount("-t", "tmpfs", "-o", "size=14m", "tmpfs", str(small))
    if why:
        pytest.skip(f"cannot mount a small tmpfs here: {why}")
    try:
        scene = with_rom_damping(clone(coarse_run[1], small, copy=("rom.h5",)), "6e-3")
        shutil.rmtree(small / "figures")  # the mode pictures are current: nothing else to write
        before = (small / "rom.h5").read_bytes()
        assert run(scene, small, "--until", "rom") == 2
        captured = capsys.readouterr()
        line = one_line(captured.err)
        assert line.startswith(f"bladerub: error: not enough free space in {small}: this run writes ~11.3 MB "
                               "(stage rom: ~11.3 MB), ")
        assert "[rom] running" not in captured.out
        assert run(scene, small, "--until", "rom", "--yes") == 1
        assert one_line(capsys.readouterr().err) == ("bladerub: error: stage rom failed: No space left on device; "
                                                     "kept: mesh.h5, fem.h5")
        assert not temps(small) and (small / "rom.h5").read_bytes() == before
    finally:
        subprocess.run(["umount", str(small)], check=False)


def test_render_before_fem_names_the_command_to_run(coarse_run, tmp_path, capsys):
    scene = clone(coarse_run[1], tmp_path)
    for name in ("fem.h5", "rom.h5"):
        (tmp_path / name).unlink()
    assert main(["render", str(scene), "--out", str(tmp_path)]) == 2
    assert one_line(capsys.readouterr().err) == (
        f"bladerub: error: {tmp_path / 'fem.h5'} is missing: run `bladerub run {scene} --out {tmp_path} --until fem` "
        "first")
    scene.write_text(scene.read_text().replace("E = 108e9", "E = 110e9"))  # fem.h5 there, but not this scene's
    (tmp_path / "fem.h5").symlink_to(coarse_run[1] / "fem.h5")
    assert main(["render", str(scene), "--out", str(tmp_path)]) == 2
    assert "fem.h5 is not usable for this scene (inputs changed: material.E 1.08e+11 -> 1.1e+11): run `bladerub run" in \
        one_line(capsys.readouterr().err)


def test_a_folder_copied_with_hard_links_gets_its_own_lock(tmp_path, capsys):
    """`cp -al` shares the lock file between the folders: while the original's run holds it
    the copy's is refused (which run holds a shared file is not known), then the copy's run
    makes the lock its own, and from then on each folder is locked alone."""
    a, b = tmp_path / "a", tmp_path / "b"
    a.mkdir()
    b.mkdir()
    with folder.hold(a, "run in a"):
        os.link(a / folder.LOCK, b / folder.LOCK)
        with pytest.raises(FolderBusy, match="shared by hard links with another folder.*run in a"):
            with folder.hold(b, "run in b"):
                pass
    with folder.hold(b, "run in b"):
        assert os.stat(b / folder.LOCK).st_ino != os.stat(a / folder.LOCK).st_ino
        assert os.stat(a / folder.LOCK).st_nlink == os.stat(b / folder.LOCK).st_nlink == 1
        with folder.hold(a, "run in a again"):  # both at once: one lock each
            assert "run in b" in (b / folder.LOCK).read_text() and "run in a again" in (a / folder.LOCK).read_text()
    assert not [p for p in b.iterdir() if p.name != folder.LOCK]  # no temporary file left
