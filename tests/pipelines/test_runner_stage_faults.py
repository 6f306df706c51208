"""Faults of a stage that the runner reports (pipelines.runner._execute, _kept): a stage's child
process that ends without a word, a figure whose drawing raises a ValueError, a partial file
left for other inputs. Each is one line naming the stage (or figure) and what was kept, exit 1.

The stages are the coarse scene's mesh stage with its compute (or figures) replaced: nothing is
meshed, a run takes well under a second (a spawned child: about one more).
"""
from __future__ import annotations

import dataclasses
import json
import os
import sys

import h5py
import pytest

from pipelines.artifacts import ArtifactError
from pipelines.child import call_in_child
from pipelines.cli import main
from pipelines.runner import expected_inputs
from pipelines.scene import load_scene
from pipelines.stages import REGISTRY
from pipelines.stages.base import Figure
from support import coarse_text


def one_line(err: str) -> str:
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


@pytest.fixture
def scene(tmp_path):
    path = tmp_path / "scene.toml"
    path.write_text(coarse_text())
    return path


def mesh_stage(monkeypatch, compute=None, figures=None):
    s = REGISTRY["mesh"]
    changes = {"compute": compute} if compute is not None else {}
    if figures is not None:
        changes["figures"] = figures
    monkeypatch.setitem(REGISTRY, "mesh", dataclasses.replace(s, **changes))


def run(scene, out):
    return main(["run", str(scene), "--out", str(out), "--until", "mesh", "--quiet"])


@pytest.mark.parametrize("child, said", [
    ((os._exit, 3), "_exit ended without an answer (exit code 3)"),  # killed or crashed: no answer
    ((sys.exit, 3), "a process of it exited (code 3) without an answer"),  # re-raised by call_in_child
])
def test_a_stage_child_that_exits_without_a_word_is_one_line_naming_the_stage(child, said, scene, tmp_path,
                                                                               monkeypatch, capsys):
    # before: "bladerub: error: _exit ended without an answer (exit code 3)" (no stage, nothing
    # said kept), and for sys.exit(3) no line at all and the child's code as the run's (sys.exit(0): 0)
    mesh_stage(monkeypatch, compute=lambda ctx, outputs: call_in_child(*child))
    assert run(scene, tmp_path) == 1
    # and, as for a killed pool worker, how to go on (the line said only what was kept)
    assert one_line(capsys.readouterr().err) == (f"bladerub: error: stage mesh failed: {said}; kept: nothing new; "
                                                 f"run `bladerub run {scene} --out {tmp_path} --until mesh` again to go on from there")


def test_a_stage_raising_system_exit_0_is_not_a_run_done(scene, tmp_path, monkeypatch, capsys):
    mesh_stage(monkeypatch, compute=lambda ctx, outputs: sys.exit(0))
    assert run(scene, tmp_path) == 1
    assert one_line(capsys.readouterr().err) == ("bladerub: error: stage mesh failed: a process of it exited (code 0) "
                                                 f"without an answer; kept: nothing new; run `bladerub run {scene} --out {tmp_path} --until mesh` "
                                                 "again to go on from there")


def test_a_figure_raising_a_value_error_fails_the_run_with_exit_1_naming_the_figure(scene, tmp_path, monkeypatch,
                                                                                    capsys):
    # before: exit 2 ("nothing was computed") with the bare "bladerub: error: x and y must ..."
    def draw(ctx):
        raise ValueError("x and y must have same first dimension, but have shapes (3,) and (4,)")

    fig = Figure("bad", lambda s: ("bad.png",), (), lambda s: ("scene.toml",), draw)
    mesh_stage(monkeypatch, compute=lambda ctx, outputs: None, figures=(fig,))
    assert run(scene, tmp_path) == 1
    assert one_line(capsys.readouterr().err) == (
        "bladerub: error: figure bad failed: x and y must have same first dimension, but have shapes (3,) and (4,); "
        "kept: mesh.h5")


def test_the_figures_after_a_failed_one_are_drawn_and_every_failure_named(scene, tmp_path, monkeypatch, capsys):
    """A figure that fails does not keep the later ones from being drawn (a run used to stop
    at the first): here the second of four is drawn and recorded, and the line names the
    three failures in the order met."""
    def bad(message, kind=ValueError):
        def draw(ctx):
            raise kind(message)
        return draw

    def good(ctx):
        (ctx.out / "figures").mkdir(exist_ok=True)
        (ctx.out / "figures" / "good.png").write_bytes(b"drawn")

    figs = (Figure("first", lambda s: ("first.png",), (), lambda s: ("scene.toml",), bad("no data to plot")),
            Figure("good", lambda s: ("good.png",), (), lambda s: ("scene.toml",), good),
            # an input the figure finds unusable (a ROM without its recovery matrix): it used to
            # end the run at once with exit 2, the figures after it undrawn
            Figure("third", lambda s: ("third.png",), (), lambda s: ("scene.toml",),
                   bad("rom.h5 has no recovery matrix", ArtifactError)),
            Figure("fourth", lambda s: ("fourth.png",), (), lambda s: ("scene.toml",), bad("shapes (3,) and (4,)")))
    mesh_stage(monkeypatch, compute=lambda ctx, outputs: None, figures=figs)
    assert run(scene, tmp_path) == 1
    assert one_line(capsys.readouterr().err) == ("bladerub: error: figure first failed: no data to plot; "
                                                 "figure third failed: rom.h5 has no recovery matrix; "
                                                 "figure fourth failed: shapes (3,) and (4,); kept: mesh.h5")
    assert (tmp_path / "figures" / "good.png").read_bytes() == b"drawn"
    manifest = json.loads((tmp_path / "figures" / "manifest.json").read_text())
    assert set(manifest) == {"good"}  # the failed ones are drawn again by the next run


def test_a_failed_figure_names_the_files_its_last_drawing_left(scene, tmp_path, monkeypatch, capsys):
    """A figure that fails keeps its last drawing's files (a failed run overwrites nothing),
    which now stand for other inputs: after a run at mu = 0.25, figures/hbm_dlft.pvd still
    held the mu = 0.15 point, and nothing said so. The line names them."""
    def good(ctx):
        (ctx.out / "figures" / "sub").mkdir(parents=True, exist_ok=True)
        (ctx.out / "figures" / "pic.png").write_bytes(b"drawn")
        (ctx.out / "figures" / "sub" / "pic.vtu").write_bytes(b"drawn")

    def bad(ctx):
        raise ValueError("the NFRC has no converged point to write")

    def figure(draw):
        return (Figure("pic", lambda s: ("pic.png", "sub/pic.vtu", "gone.vtu"), (), lambda s: ("scene.toml",), draw),)

    mesh_stage(monkeypatch, compute=lambda ctx, outputs: None, figures=figure(good))
    assert run(scene, tmp_path) == 0
    path = tmp_path / "figures" / "manifest.json"
    manifest = json.loads(path.read_text())
    manifest["pic"]["inputs"] = "the hash of other inputs"
    path.write_text(json.dumps(manifest))
    mesh_stage(monkeypatch, compute=lambda ctx, outputs: None, figures=figure(bad))
    assert run(scene, tmp_path) == 1
    assert one_line(capsys.readouterr().err) == (
        "bladerub: error: figure pic failed: the NFRC has no converged point to write (its last drawing stays, "
        "from other inputs: figures/pic.png, figures/sub/pic.vtu); kept: mesh.h5")
    assert (tmp_path / "figures" / "pic.png").read_bytes() == b"drawn"


def test_a_partial_file_of_other_inputs_is_not_said_kept(scene, tmp_path, monkeypatch, capsys):
    # rank 0's partial file left by a run of other inputs (the stage starts over from it), rank 1's
    # of these inputs; before: "kept: 17 points of mesh.partial.h5, mesh.r1.partial.h5"
    h = expected_inputs(load_scene(scene), ("mesh",))["mesh.h5"][1]
    for name, n, inputs_hash in (("mesh.partial.h5", 12, "other inputs"), ("mesh.r1.partial.h5", 5, h)):
        with h5py.File(tmp_path / name, "w") as f:
            f.attrs["n_points"], f.attrs["inputs_hash"] = n, inputs_hash

    def full(ctx, outputs):
        raise OSError(28, "No space left on device")

    mesh_stage(monkeypatch, compute=full)
    assert run(scene, tmp_path) == 1
    assert one_line(capsys.readouterr().err) == ("bladerub: error: stage mesh failed: No space left on device; "
                                                 "kept: 5 points of mesh.r1.partial.h5")


def test_a_value_error_after_a_file_was_written_is_a_stage_failure_and_before_it_nothing_computed(
        scene, tmp_path, monkeypatch, capsys):
    # before: exit 2, "nothing was computed", also once the stage had written its file
    def compute(ctx, outputs, write):
        if write:
            (tmp_path / "mesh.h5").write_bytes(b"")
        raise ValueError("dR_dx has NaN or inf entries")

    mesh_stage(monkeypatch, compute=lambda ctx, outputs: compute(ctx, outputs, False))
    assert run(scene, tmp_path) == 2
    assert one_line(capsys.readouterr().err) == "bladerub: error: dR_dx has NaN or inf entries"
    mesh_stage(monkeypatch, compute=lambda ctx, outputs: compute(ctx, outputs, True))
    assert run(scene, tmp_path) == 1
    assert one_line(capsys.readouterr().err) == ("bladerub: error: stage mesh failed: dR_dx has NaN or inf entries; "
                                                 "kept: nothing new")


def test_the_command_to_go_on_keeps_the_runs_settings(scene, tmp_path, monkeypatch, capsys):
    """The line of a failed run says the command that goes on from what was kept: the same
    --set items (quoted as a shell needs them), so that the next run reads the same scene and
    finds the kept artifacts current; without them it would compute another scene."""
    mesh_stage(monkeypatch, compute=lambda ctx, outputs: call_in_child(os._exit, 3))
    argv = ["run", str(scene), "--out", str(tmp_path), "--until", "mesh", "--quiet",
            "--set", "mesh.element_size=0.009", "--set", "name=two words"]
    assert main(argv) == 1
    line = one_line(capsys.readouterr().err)
    assert line.endswith(f"run `bladerub run {scene} --out {tmp_path} --set mesh.element_size=0.009 "
                         f"--set 'name=two words' --until mesh` again to go on from there"), line
