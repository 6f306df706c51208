"""Shared pipeline fixtures.

`coarse_run`: the coarse rotor 67 scene taken once through mesh -> fem -> rom (about 20 s)
for the whole session. Tests must not modify its folder (tests are order-independent):
a test that changes or adds artifacts works on `support.fresh_copy(...)` of it.
"""
import pytest

from pipelines.cli import main
from support import coarse_text


@pytest.fixture(scope="session")
def coarse_run(tmp_path_factory):
    """(scene path, output folder) of the coarse scene run --until rom. Read-only."""
    out = tmp_path_factory.mktemp("coarse")
    scene = out / "scene.toml"
    scene.write_text(coarse_text())
    assert main(["run", str(scene), "--out", str(out), "--until", "rom"]) == 0
    return scene, out
