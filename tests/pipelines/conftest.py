"""Shared pipeline fixtures.

`coarse_run`: the coarse rotor 67 scene taken once through mesh -> fem -> rom (about 20 s)
for the whole session. `coarse_nfrc`: a clone of it plus both NFRCs of a short, cheap
continuation (coarse_runs.SHORT: N_h = 5, N_t = 64, Omega in [1900, 2000] rad/s). Tests
must not modify their folders (tests are order-independent): a test that changes or adds
artifacts works on `support.fresh_copy(...)` or `coarse_runs.clone(...)` of one.
"""
import pytest

from coarse_runs import clone
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


@pytest.fixture(scope="session")
def coarse_nfrc(coarse_run, tmp_path_factory):
    """(scene path, output folder): a clone of `coarse_run` with nfrc_dlft.h5 and nfrc_rl.h5
    of the SHORT continuation. Read-only."""
    out = tmp_path_factory.mktemp("coarse_nfrc")
    scene = clone(coarse_run[1], out)
    assert main(["run", str(scene), "--out", str(out), "--until", "hbm", "--quiet"]) == 0
    return scene, out
