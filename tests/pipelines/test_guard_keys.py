"""The size guard names the scene key that makes a run too large: absurd values of keys that
drive memory (the sweep's speeds, the AFT's samples, the isola search's workers, the contact
nodes) are refused before anything is computed, in one line naming [section] key, exit 2."""
from __future__ import annotations

import pytest

import pipelines.runner
from coarse_runs import coarse_scene_text
from pipelines import guard
from pipelines.cli import main


@pytest.fixture
def nothing_computes(monkeypatch):
    """The run's stages replaced by a record: a plan that passes the guard computes nothing
    here (and the test says so), where it would otherwise mesh and go on."""
    ran = []
    monkeypatch.setattr(pipelines.runner, "_execute", lambda *args, **kwargs: ran.append(args))
    monkeypatch.setattr(guard, "machine_memory", lambda: 24e9)  # the reference machine's
    return ran


@pytest.mark.parametrize("until, key, value, named", [
    # np.linspace of the grid failed in the estimate: IndexError (2**63 - 1), MemoryError (1e12)
    ("ti", "ti.n_omega", "9223372036854775807", "lower [ti] n_omega"),
    ("ti", "ti.n_omega", "1000000000000", "lower [ti] n_omega"),
    # refused, but the advice named the seeds' keys, which do not change the memory
    ("isolas", "isolas.workers", "100000", "lower [isolas] workers (now 100000"),
    # the AFT's samples were not in the estimate: the guard let it through
    ("hbm", "hbm.n_time", "100000000000", "lower [hbm] n_time (now 100000000000"),
    # failed in the mesher's child process: "Maximum allowed size exceeded", naming no key
    ("mesh", "mesh.n_boundary", "100000000000000000000", "lower [mesh] n_boundary (now 100000000000000000000"),
])
def test_an_absurd_value_is_refused_naming_its_key(tmp_path, capsys, nothing_computes, until, key, value, named):
    scene = tmp_path / "scene.toml"
    scene.write_text(coarse_scene_text())
    out = tmp_path / "out"
    code = main(["run", str(scene), "--out", str(out), "--until", until, "--set", f"{key}={value}"])
    captured = capsys.readouterr()
    assert not nothing_computes, f"the guard let it through:\n{captured.out}"
    assert code == 2
    lines = [x for x in captured.err.splitlines() if x.strip()]
    assert len(lines) == 1 and "Traceback" not in captured.err, captured.err
    section = key.split(".")[0]
    assert lines[0].startswith(f"bladerub: error: [{section}] "), lines[0]
    assert named in lines[0], lines[0]
    assert not list(out.glob("*.h5")) and not list(out.glob("*.partial.h5"))
