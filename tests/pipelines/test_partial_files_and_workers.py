"""Partial files that are symbolic links (pipelines.artifacts.open_in_place), final artifacts
written over one (atomic_output), and the line of a run whose pool worker was killed
(pipelines.runner._execute): what was kept and how to go on, as after Ctrl-C."""
from __future__ import annotations

import concurrent.futures
import multiprocessing
import signal
from dataclasses import dataclass, field

import h5py
import numpy as np

from hbm.processes import reported_deaths
from pipelines import artifacts as art
from pipelines.branch_store import BranchStore, load_branch, partial_path
from test_branch_store import extras_of, two_run_folders
from test_runner_stage_faults import mesh_stage, one_line, scene  # noqa: F401 - scene: a fixture


def test_a_partial_file_that_is_a_symbolic_link_is_resumed_from_a_copy_and_its_target_left_as_it_was(tmp_path):
    # before: the resume in b appended its points to a's file through the link (`cp -as`, or
    # a link made by hand to another run's partial file)
    a, b, pts = two_run_folders(tmp_path)
    target = partial_path(a / "nfrc.h5")
    partial_path(b / "nfrc.h5").symlink_to(target)
    original = target.read_bytes()

    store = BranchStore.reopen(b / "nfrc.h5", keep=2)  # "r+": resumes from the target's points
    for p in pts[2:]:
        store.append(p, extras_of(p))
    store.finalize("reached omega_max")
    np.testing.assert_array_equal(load_branch(b / "nfrc.h5").branch.omega, [p.omega for p in pts])
    assert target.read_bytes() == original
    assert len(load_branch(a / "nfrc.h5", allow_partial=True).branch) == 3

    # "a" (the sweep's and the isola search's partial files): the link becomes a file of its own
    link = b / "ti.partial.h5"
    link.symlink_to(target)
    with art.open_in_place(link, "a") as h5:
        h5.attrs["n_speeds"] = 7
    assert not link.is_symlink() and target.read_bytes() == original
    with h5py.File(link, "r") as h5:
        assert h5.attrs["n_speeds"] == 7 and h5.attrs["n_points"] == 3  # the target's content, and the new

    # a broken link: "a" creates the file here, not at the link's target (outside the folder)
    dangling = b / "isolas.partial.h5"
    dangling.symlink_to(a / "absent.h5")
    with art.open_in_place(dangling, "a") as h5:
        h5.attrs["n_branches"] = 1
    assert not (a / "absent.h5").exists() and not dangling.is_symlink()


@dataclass(frozen=True)
class _Result:
    x: np.ndarray = field(metadata={"unit": "m"})


def test_a_final_artifact_written_over_a_symbolic_link_replaces_the_link(tmp_path):
    elsewhere = tmp_path / "other" / "rom.h5"
    elsewhere.parent.mkdir()
    elsewhere.write_bytes(b"another run's rom.h5")
    link = tmp_path / "rom.h5"
    link.symlink_to(elsewhere)
    art.write_artifact(link, _Result(np.arange(3.0)), stage="rom")
    assert not link.is_symlink() and art.verify(link) is None
    assert elsewhere.read_bytes() == b"another run's rom.h5"


def _killed_worker(ctx, outputs):
    """A stage that keeps 2 speeds in its partial file, then loses a pool worker to SIGKILL
    (as the OOM killer would end it) while it marches 2000 rad/s."""
    with h5py.File(ctx.out / "mesh.partial.h5", "w") as h5:
        h5.attrs["n_speeds"], h5.attrs["inputs_hash"] = 2, ctx.hashes["mesh.h5"]
    context = multiprocessing.get_context("fork")
    with concurrent.futures.ProcessPoolExecutor(1, mp_context=context) as pool, \
            reported_deaths("the time-integration sweep", lambda: "speeds being marched: 2000 rad/s"):
        pool.submit(signal.raise_signal, signal.SIGKILL).result()


def test_a_killed_pool_worker_says_what_was_kept_and_how_to_go_on(scene, tmp_path, monkeypatch, capsys):
    # before: "bladerub: error: a worker process of the time-integration sweep ended without an
    # answer (killed, perhaps for lack of memory); speeds being marched: 2000 rad/s" alone
    from pipelines.cli import main

    mesh_stage(monkeypatch, compute=_killed_worker)
    assert main(["run", str(scene), "--out", str(tmp_path), "--until", "mesh", "--quiet"]) == 1
    assert one_line(capsys.readouterr().err) == (
        "bladerub: error: stage mesh failed: a worker process of the time-integration sweep ended without an "
        "answer (killed, perhaps for lack of memory); speeds being marched: 2000 rad/s; kept: 2 speeds of "
        f"mesh.partial.h5; run `bladerub run {scene} --out {tmp_path} --until mesh` again to go on from there")
