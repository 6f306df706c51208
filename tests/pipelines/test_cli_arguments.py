"""The command line as a first-time user meets it: each wrong argument is one line naming
it and exit 2 ("nothing was computed", README *Commands*), never a traceback, a silent
exit 0, or a run in a folder the user did not name; nothing on disk changes."""
import os
import subprocess
import sys
from pathlib import Path

import pytest

from pipelines.cli import main
from support import mpirun_command, needs_mpirun

ROOT = Path(__file__).resolve().parents[2]
COARSE = ROOT / "scenes" / "rotor67_coarse.toml"


def _snapshot(folder: Path) -> dict:
    return {p.relative_to(folder): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _one_line(capsys) -> str:
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1, lines
    return lines[0]


def _argparse_refusal(argv, capsys) -> str:
    """An argument refused by the parser: exit 2, its error line (after the usage lines)."""
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    return capsys.readouterr().err.strip().splitlines()[-1]


@pytest.mark.parametrize("command", ["run", "show", "render"])
def test_a_scene_path_that_is_a_folder_is_called_a_folder(command, tmp_path, capsys):
    """It was `scene file not found: DIR`, of a folder that is there."""
    out = tmp_path / "out"
    argv = [command, str(tmp_path)] + ([] if command == "show" else ["--out", str(out)])
    assert main(argv) == 2
    line = _one_line(capsys)
    assert line.startswith("bladerub: error: ") and "is a folder, not a scene file" in line, line
    assert not out.exists()


@pytest.mark.parametrize("command", ["run", "show", "render"])
def test_an_unreadable_scene_is_a_bad_scene_exit_2(command, tmp_path, capsys, monkeypatch):
    """A scene file that cannot be read (permissions: root reads any, so the read is made to
    fail) was `bladerub: error: Permission denied PATH` with exit 1, "a stage failed while
    computing", for a run that computed nothing."""
    scene = tmp_path / "s.toml"
    scene.write_text("[contact]\nmu = 0.1\n")
    read_bytes = Path.read_bytes

    def denied(self):
        if self == scene:
            raise PermissionError(13, "Permission denied", str(self))
        return read_bytes(self)

    monkeypatch.setattr(Path, "read_bytes", denied)
    out = tmp_path / "out"
    assert main([command, str(scene)] + ([] if command == "show" else ["--out", str(out)])) == 2
    line = _one_line(capsys)
    assert line == f"bladerub: error: cannot read the scene file {scene}: Permission denied", line
    assert not out.exists()


@pytest.mark.skipif(os.geteuid() == 0, reason="root reads a file whatever its permission bits; the test above "
                    "denies the read itself and runs as root too")
def test_a_scene_without_read_permission_is_exit_2(tmp_path, capsys):
    scene = tmp_path / "s.toml"
    scene.write_text("[contact]\nmu = 0.1\n")
    scene.chmod(0)
    assert main(["show", str(scene)]) == 2
    assert "cannot read the scene file" in _one_line(capsys)


@pytest.mark.parametrize("argv, named", [
    (["run", str(COARSE), "--out", "", "--until", "mesh"], "argument --out: empty"),
    (["render", str(COARSE), "--out", ""], "argument --out: empty"),
    (["run", "", "--out", "OUT"], "argument scene: empty"),
    (["show", ""], "argument scene: empty"),
])
def test_an_empty_path_is_refused_not_taken_as_the_current_folder(argv, named, tmp_path, capsys, monkeypatch):
    """`--out "$DIR"` with DIR unset was Path("") = the current folder: the run wrote its
    artifacts and lock there (render's refusal read `--out .`); an empty scene path was
    `scene file not found: .`."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "mine.txt").write_text("a user's file")
    before = _snapshot(tmp_path)
    assert named in _argparse_refusal(argv, capsys)
    assert _snapshot(tmp_path) == before


@pytest.mark.parametrize("modes", ["0", "-1"])
def test_render_with_no_modes_to_draw_is_refused(modes, tmp_path, capsys):
    """`--modes 0` and `--modes -1` ended with exit 0 having drawn and said nothing."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "fem.h5").write_bytes(b"not looked at")
    before = _snapshot(out)
    line = _argparse_refusal(["render", str(COARSE), "--out", str(out), "--modes", modes], capsys)
    assert f"argument --modes: {modes}: give at least 1" in line, line
    assert _snapshot(out) == before


def test_render_with_more_modes_than_computed_is_refused_naming_the_count(tmp_path, capsys):
    """`--modes 13` (or 1000) with 12 modes in fem.h5 drew the 12 and said nothing of the
    others; it is refused before the folder is looked at, naming [fem] n_modes."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "keep.txt").write_text("kept")
    before = _snapshot(out)
    assert main(["render", str(COARSE), "--out", str(out), "--modes", "13"]) == 2
    line = _one_line(capsys)
    assert line.startswith("bladerub: error: --modes 13: ") and "[fem] n_modes = 12" in line, line
    assert _snapshot(out) == before
    # raising [fem] n_modes makes the count acceptable (then the missing artifacts are named)
    assert main(["render", str(COARSE), "--out", str(out), "--modes", "13", "--set", "fem.n_modes=13"]) == 2
    assert "is missing: run `bladerub run" in _one_line(capsys)
    assert _snapshot(out) == before


def test_a_key_set_twice_says_which_value_is_used(capsys):
    """The last of two --set of one key won without a word."""
    argv = ["show", str(COARSE), "--set", "contact.mu=0.1", "--set", "hbm.n_harmonics=5", "--set", "contact.mu=0.2"]
    assert main(argv) == 0
    captured = capsys.readouterr()
    warnings = captured.err.strip().splitlines()
    assert warnings == ["bladerub: warning: [contact] mu is set 2 times on the command line "
                        "(--set contact.mu=0.1, --set contact.mu=0.2): the last, --set contact.mu=0.2, is used"]
    assert "\nmu = 0.2\n" in captured.out


def test_a_run_warns_of_a_key_set_twice_before_anything_else(tmp_path, capsys):
    """The warning comes with the run too (here one the size guard refuses: nothing made)."""
    out = tmp_path / "out"
    argv = ["run", str(COARSE), "--out", str(out), "--quiet", "--set", "name=a", "--set", "name=b",
            "--set", "mesh.element_size=1e-6"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert ("bladerub: warning: name is set 2 times on the command line (--set name=a, --set name=b): "
            "the last, --set name=b, is used") in err
    assert "[mesh]" in err.strip().splitlines()[-1]
    assert not out.exists()


@needs_mpirun
def test_under_mpirun_a_key_set_twice_is_said_once(tmp_path):
    """Rank 0 does the talking: the warning comes once, not once per rank."""
    words, env = mpirun_command(ROOT)
    out = tmp_path / "out"
    proc = subprocess.run([*words, sys.executable, "-m", "pipelines.cli", "run", str(COARSE), "--out", str(out),
                           "--until", "mesh", "--quiet", "--set", "contact.mu=0.1", "--set", "contact.mu=0.2",
                           "--set", "mesh.edge_layers=100000"],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=120)
    assert proc.stderr.count("bladerub: warning: [contact] mu is set 2 times") == 1, proc.stderr
    assert proc.stderr.count("bladerub: error: [mesh] ") == 1, proc.stderr
    assert not out.exists()


@pytest.mark.parametrize("item, expected", [("hbm.methods=[dlft]", ["dlft"]), ("hbm.methods=[dlft,rl]", ["dlft", "rl"]),
                                            ("hbm.methods=[ rl , dlft ]", ["rl", "dlft"]),
                                            ("isolas.harmonics=[1,2,3]", [1, 2, 3])])
def test_a_list_in_brackets_without_quotes_is_that_list(item, expected):
    """hbm.methods=[dlft] is not TOML (dlft unquoted): it was read as the text "[dlft]" and
    refused as "unknown HBM method '[dlft]'", blaming the method for the brackets."""
    from pipelines.scene import parse_override

    assert parse_override(item)[2] == expected


def test_out_as_a_dangling_link_is_named_as_such(tmp_path, capsys):
    """mkdir on a link to nothing said 'File exists', of a path that does not exist."""
    scene = Path(__file__).resolve().parents[2] / "scenes" / "rotor67_coarse.toml"
    link = tmp_path / "run"
    link.symlink_to(tmp_path / "elsewhere" / "run")
    assert main(["run", str(scene), "--out", str(link), "--until", "mesh"]) == 2
    err = capsys.readouterr().err
    assert f"--out {link} is a link to {tmp_path / 'elsewhere' / 'run'}, which does not exist" in err, err
    assert link.is_symlink() and not (tmp_path / "elsewhere").exists()
