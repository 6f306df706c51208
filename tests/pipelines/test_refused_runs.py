"""A run refused before computing (the size guard, a bad scene) leaves the file system as it
found it: no folder it made for itself, an existing folder's files byte for byte, no lock file
where there was none, and exit code 2."""
from __future__ import annotations

from pathlib import Path

import pytest

import pipelines.runner
from coarse_runs import coarse_scene_text
from pipelines import folder, guard
from pipelines.cli import main

#: Far beyond any machine's memory: the size guard refuses it (~1.6e+08 GB for the sweep).
TOO_LARGE = "ti.n_omega=1000000000000"


@pytest.fixture
def nothing_computes(monkeypatch):
    """The run's stages replaced by a record (a run the guard let through computes nothing,
    and the test says so), on the reference machine's memory."""
    ran = []
    monkeypatch.setattr(pipelines.runner, "_execute", lambda *args, **kwargs: ran.append(args))
    monkeypatch.setattr(guard, "machine_memory", lambda: 24e9)
    return ran


@pytest.fixture
def scene(tmp_path) -> Path:
    path = tmp_path / "scene.toml"
    path.write_text(coarse_scene_text())
    return path


def tree(root: Path) -> dict:
    """{relative path: content (bytes) or None for a folder} of everything under root."""
    return {str(p.relative_to(root)): None if p.is_dir() else p.read_bytes() for p in sorted(root.rglob("*"))}


def refused(scene: Path, out: Path, capsys, *sets: str) -> str:
    """Run the scene into out, expect exit 2; returns the one error line."""
    args = ["run", str(scene), "--out", str(out), "--until", "ti"]
    code = main(args + [w for s in sets for w in ("--set", s)])
    err = capsys.readouterr().err
    lines = [x for x in err.splitlines() if x.strip()]
    assert code == 2, err
    assert len(lines) == 1 and lines[0].startswith("bladerub: error: "), err
    return lines[0]


def test_a_run_refused_by_the_size_guard_leaves_no_folder(tmp_path, scene, capsys, nothing_computes):
    """--out three folders deep, none of them there: none is left (each used to stay, the
    deepest holding only the lock file)."""
    line = refused(scene, tmp_path / "a" / "b" / "out", capsys, TOO_LARGE)
    assert "lower [ti] n_omega" in line
    assert not nothing_computes
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scene.toml"]


@pytest.mark.parametrize("lock", [None, b'{"pid": 1, "host": "h", "command": "the last run"}'],
                         ids=["no lock file", "the last run's lock file"])
def test_a_run_refused_by_the_size_guard_leaves_an_existing_folder_as_it_was(tmp_path, scene, capsys,
                                                                             nothing_computes, lock):
    out = tmp_path / "out"
    (out / "notes").mkdir(parents=True)
    (out / "notes" / "todo.txt").write_text("the user's")
    if lock is not None:
        (out / folder.LOCK).write_bytes(lock)
    before = tree(out)
    refused(scene, out, capsys, TOO_LARGE)
    assert not nothing_computes
    assert tree(out) == before  # no lock file added, the last run's record not overwritten


@pytest.mark.parametrize("problem, sets", [
    ("unknown key", ["ti.nokey=1"]),
    ("not valid TOML", []),
    ("scene file not found", []),
])
def test_a_scene_error_leaves_no_folder(tmp_path, scene, capsys, nothing_computes, problem, sets):
    if problem == "not valid TOML":
        scene.write_text("[ti\n")
    elif problem == "scene file not found":
        scene.unlink()
    line = refused(scene, tmp_path / "a" / "out", capsys, *sets)
    assert problem in line
    assert not (tmp_path / "a").exists()


def test_a_failed_run_keeps_a_folder_that_holds_something(tmp_path):
    """The folders made for a run stay once anything is written in them (another run's
    files, or what a stage kept): only empty ones are removed."""
    out = tmp_path / "a" / "out"
    with pytest.raises(RuntimeError):
        with folder.removed_if_unused(out):
            folder.prepare(out)
            (out / "mesh.h5").write_bytes(b"kept")
            raise RuntimeError("a stage failed")
    assert (out / "mesh.h5").read_bytes() == b"kept"
